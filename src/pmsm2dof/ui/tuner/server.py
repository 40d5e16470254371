"""Serving the tuner: bind a socket, run uvicorn on it, in the foreground or in a thread.

The socket is bound here (not by uvicorn) so that the port is known before the server
starts, bad hosts and busy ports become a ConfigError, and ``port=0`` asks the system for
a free port.

The server answers only requests addressed to it (:class:`HostCheck`): a page of another site
can make its own name resolve to 127.0.0.1 (DNS rebinding) and reach a local server as if it
were its own; the browser still sends that name in the ``Host`` header, which is refused.
"""

import contextlib
import errno
import ipaddress
import signal
import socket
import threading
import time
from collections.abc import Iterable, Iterator
from urllib.parse import urlsplit

import uvicorn
from starlette.types import ASGIApp, Receive, Scope, Send

from ...errors import ConfigError, is_integer

DEFAULT_PORT = 8765
"""Port tried first when none is given; a free one is chosen if it is busy."""


def is_loopback(host: str) -> bool:
    """True if ``host`` is an address or name of this machine's loopback interface."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind_socket(host: str = "127.0.0.1", port: int | None = None) -> socket.socket:
    """Return a listening TCP socket on ``host``.

    Parameters
    ----------
    host : str
        Interface address or name.
    port : int or None
        TCP port; 0 lets the system choose a free one; None tries :data:`DEFAULT_PORT`
        and falls back to a free port when it is busy.
    """
    if port is not None and (not is_integer(port) or not 0 <= port <= 65535):
        raise ConfigError("port", port, "an integer in [0, 65535]")
    port = None if port is None else int(port)
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        raise ConfigError("host", host, "an address or name of an interface of this machine") from None
    family, _, _, _, sockaddr = infos[0]
    for candidate in [DEFAULT_PORT, 0] if port is None else [port]:
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((sockaddr[0], candidate, *sockaddr[2:]))
        except OSError as exc:
            sock.close()
            if exc.errno == errno.EADDRINUSE and candidate != 0 and port is None:
                continue
            if exc.errno == errno.EADDRINUSE:
                raise ConfigError("port", port, "a free TCP port (this one is in use)") from None
            raise ConfigError("host", host, f"an address of an interface of this machine ({exc.strerror})") from None
        sock.listen(128)
        sock.setblocking(False)
        return sock
    raise AssertionError("unreachable: port 0 always binds")


def url_of(sock: socket.socket) -> str:
    """The http URL that reaches the server listening on ``sock`` from this machine."""
    host, port = sock.getsockname()[:2]
    if ipaddress.ip_address(host).is_unspecified:  # all interfaces: loopback is one of them
        host = "127.0.0.1" if sock.family == socket.AF_INET else "::1"
    if ":" in host:
        host = f"[{host}]"
    return f"http://{host}:{port}/"


class HostCheck:
    """ASGI middleware: answer only requests addressed to this server, and posts of its own pages.

    A request's ``Host`` must name the bound port and one of ``names`` (for a server bound to
    all interfaces, any IP address as well: an address cannot be rebound); otherwise it answers
    421. A request with an ``Origin`` header (a browser's post or cross-site fetch) must come from
    such an http origin; otherwise it answers 403.

    Parameters
    ----------
    app : ASGI application
    names : iterable of str
        Host names and addresses accepted, lower case, IPv6 without brackets.
    port : int
        The bound port.
    any_address : bool
        Accept any IP address as the host too.
    """

    def __init__(self, app: ASGIApp, names: Iterable[str], port: int, any_address: bool = False) -> None:
        self.app = app
        self.names = frozenset(names)
        self.port = port
        self.any_address = any_address

    def accepts(self, authority: str, scheme: str = "http") -> bool:
        """True if ``scheme://authority`` names this server."""
        try:
            parts = urlsplit(f"{scheme}://{authority}")
            port = parts.port or (80 if scheme == "http" else None)
        except ValueError:
            return False
        name = parts.hostname or ""
        if scheme != "http" or port != self.port or parts.username is not None or parts.path:
            return False
        return name in self.names or (self.any_address and _is_address(name))

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope["headers"]}
            host = headers.get("host", "")
            origin = headers.get("origin")
            if not self.accepts(host):
                shown = ", ".join(f"{n}:{self.port}" for n in sorted(self.names))
                return await _refuse(
                    send,
                    421,
                    f"pmsm2dof tuner: Host {host[:100]!r} is not this server "
                    f"(it answers to {shown}); open http://127.0.0.1:{self.port}/ "
                    "if it listens on loopback",
                )
            if origin is not None:
                scheme, _, authority = origin.partition("://")
                if not self.accepts(authority, scheme):
                    return await _refuse(
                        send,
                        403,
                        f"pmsm2dof tuner: requests from the page of {origin[:100]!r} "
                        "are refused: only the tuner's own page may use it",
                    )
        await self.app(scope, receive, send)


def _is_address(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


async def _refuse(send: Send, status: int, text: str) -> None:
    body = (text + "\n").encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [(b"content-type", b"text/plain; charset=utf-8"), (b"content-length", str(len(body)).encode())],
        }
    )
    await send({"type": "http.response.body", "body": body})


def host_check(app: ASGIApp, sock: socket.socket, host: str) -> HostCheck:
    """:class:`HostCheck` of ``app`` served on ``sock``, bound for the ``host`` asked for.

    Accepted: 127.0.0.1, localhost, the bound address and ``host`` as given (a name of this
    machine's interface), with the bound port; any IP address too when bound to all interfaces.
    """
    address, port = sock.getsockname()[:2]
    names = {"127.0.0.1", "localhost", address.lower(), host.lower().strip("[]")}
    return HostCheck(app, names, port, any_address=ipaddress.ip_address(address).is_unspecified)


def make_server(app: ASGIApp, sock: socket.socket, host: str) -> uvicorn.Server:
    """A uvicorn server for ``app`` behind :func:`host_check` on the bound socket ``sock``, quiet
    except for errors."""
    address, port = sock.getsockname()[:2]
    config = uvicorn.Config(
        host_check(app, sock, host), host=address, port=port, log_level="warning", access_log=False, lifespan="off"
    )
    return uvicorn.Server(config)


def serve(app: ASGIApp, sock: socket.socket, host: str) -> None:
    """Serve ``app`` on ``sock``, bound for ``host``, until interrupted (Ctrl-C) or terminated.

    SIGINT and SIGTERM stop the server gracefully (uvicorn), SIGHUP too; the signal is then
    raised again, so that the caller ends as it does on that signal (``pmsm2dof tune``: exit
    status 130, 143 or 129).
    """
    server = make_server(app, sock, host)
    hangups: list[int] = []
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread and hasattr(signal, "SIGHUP"):

        def hang_up(signum: int, frame: object) -> None:
            hangups.append(signum)
            server.should_exit = True

        before = signal.signal(signal.SIGHUP, hang_up)
    try:
        server.run(sockets=[sock])
    finally:
        if main_thread and hasattr(signal, "SIGHUP"):
            signal.signal(signal.SIGHUP, before)
    for signum in hangups[:1]:
        signal.raise_signal(signum)


@contextlib.contextmanager
def serving_in_thread(
    app: ASGIApp, host: str = "127.0.0.1", port: int | None = 0, timeout_s: float = 10.0
) -> Iterator[str]:
    """Run ``app`` in a background thread; yield its URL; stop it on exit.

    Used by the browser test and the benchmark.
    """
    sock = bind_socket(host, port)
    server = make_server(app, sock, host)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + timeout_s
        while not server.started:
            if time.monotonic() > deadline or not thread.is_alive():
                raise RuntimeError(f"the tuner server did not start within {timeout_s} s")
            time.sleep(0.01)
        yield url_of(sock)
    finally:
        server.should_exit = True
        thread.join(timeout_s)
        sock.close()
