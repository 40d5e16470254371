"""At most one simulation per client: a newer request of a client supersedes its older one.

The page asks for a run whenever a control moves; a script or a second tab may ask for many at
once. Each request holds a :class:`Ticket`; a client's simulations run one at a time under its
slot, and a newer run request cancels the ticket of the older one, whose simulation stops at the
next chunk boundary (:meth:`pmsm2dof.ui.tuner.experiment.Tuner.run` checks between C calls) and
answers HTTP 409.
"""

import contextlib
import threading
from collections.abc import Hashable, Iterator

#: How often a request waiting for its client's slot checks whether it was superseded [s].
SLOT_POLL_S = 0.02


class Superseded(Exception):
    """A newer request of the same client took over: this one's simulation stopped or never started."""

    def __init__(self) -> None:
        super().__init__("superseded by a newer request of the same client")


class Ticket:
    """One request's claim on its client's simulation slot.

    Parameters
    ----------
    slot : threading.Lock or None
        The client's slot; None for a slot of its own (a caller outside the server).
    """

    def __init__(self, slot: "threading.Lock | None" = None) -> None:
        self._slot = threading.Lock() if slot is None else slot
        self._cancelled = threading.Event()

    def cancel(self) -> None:
        """Mark the request superseded; its simulation stops at the next :meth:`check`."""
        self._cancelled.set()

    def check(self) -> None:
        """Raise :class:`Superseded` if a newer request of the client took over."""
        if self._cancelled.is_set():
            raise Superseded()

    @contextlib.contextmanager
    def simulation(self) -> Iterator["Ticket"]:
        """Hold the client's slot while simulating; give up waiting for it when superseded."""
        while not self._slot.acquire(timeout=SLOT_POLL_S):
            self.check()
        try:
            self.check()
            yield self
        finally:
            self._slot.release()


class _Client:
    __slots__ = ("slot", "latest", "requests")

    def __init__(self) -> None:
        self.slot = threading.Lock()
        self.latest: Ticket | None = None
        self.requests = 0


class ClientSlots:
    """The simulation slots of the server's clients; a client is any hashable key."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._clients: dict[Hashable, _Client] = {}

    @contextlib.contextmanager
    def request(self, client: Hashable, supersede: bool) -> Iterator[Ticket]:
        """A :class:`Ticket` for one request of ``client``, released on exit.

        Parameters
        ----------
        client : hashable
            Who asks (the server uses the peer address and the page's client id).
        supersede : bool
            True for a run of the page: the client's previous run request is cancelled. False
            for a download: it waits for the slot and neither cancels nor is cancelled.
        """
        with self._lock:
            entry = self._clients.setdefault(client, _Client())
            entry.requests += 1
            ticket = Ticket(entry.slot)
            if supersede:
                if entry.latest is not None:
                    entry.latest.cancel()
                entry.latest = ticket
        try:
            yield ticket
        finally:
            with self._lock:
                entry.requests -= 1
                if entry.latest is ticket:
                    entry.latest = None
                if entry.requests == 0:
                    del self._clients[client]

    def clients(self) -> int:
        """Number of clients with a request being answered."""
        with self._lock:
            return len(self._clients)
