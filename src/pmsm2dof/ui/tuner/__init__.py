"""The interactive tuner: ``pmsm2dof tune`` serves a page that redraws the responses as the
controls move (a Starlette app on uvicorn, plotted with the plotly.js shipped in the
``plotly`` package, so it works offline).

See :mod:`pmsm2dof.ui.tuner.experiment` for what is computed, :mod:`pmsm2dof.ui.tuner.app` for
the endpoints, :mod:`pmsm2dof.ui.tuner.drive` for the drive mode and
:mod:`pmsm2dof.ui.tuner.server` for serving.
"""

import contextlib
import sys
import webbrowser
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ...errors import ConfigError, ToolError
from ...sim.scenario import Scenario
from .app import create_app
from .server import bind_socket, is_loopback, serve, serving_in_thread, url_of

if TYPE_CHECKING:
    from ...studies.bench import DriveSession

#: Scenario the tuner starts from when none is given: a speed step then a load step.
DEFAULT_PRESET = "paper-condition-2"

__all__ = ["DEFAULT_PRESET", "VIRTUAL_LINK", "create_app", "drive_session", "run_tuner", "serving_in_thread"]


#: The ``link`` that builds the PC's virtual drive of the scenario and links to it.
VIRTUAL_LINK = "virtual"


@contextlib.contextmanager
def drive_session(scenario: Scenario, link: str, elf: Path | str | None) -> "Iterator[DriveSession]":
    """A :class:`~pmsm2dof.studies.bench.DriveSession` on the drive at ``link`` (its firmware's ``elf``).

    ``link`` is ``socket://HOST:PORT``, a serial device, or :data:`VIRTUAL_LINK`: the PC's virtual
    drive of ``scenario`` built and started here (on the wall clock) for the session's length.
    Events of the session are printed on stderr.
    """
    from ...drive.link import Link
    from ...studies.bench import DriveSession
    from ...studies.firmware import serve_scenario

    def say(text: str) -> None:
        print(f"pmsm2dof tune: drive: {text}", file=sys.stderr, flush=True)

    with contextlib.ExitStack() as stack:
        if link == VIRTUAL_LINK:
            if elf is not None:
                raise ConfigError("elf", str(elf), f"none with link = {VIRTUAL_LINK} (the drive is built here)")
            url, folder = stack.enter_context(serve_scenario(scenario))
            elf = folder / "virtual_drive_host"
        else:
            if elf is None:
                raise ConfigError("elf", None, f"the ELF file of the firmware the drive at {link} runs")
            url = link
        try:
            try:
                session_link = Link(url, elf, virtual=True)
            except ConfigError:  # no virtual board: a drive of its own
                session_link = Link(url, elf, virtual=False)
        except ConfigError:
            raise
        except Exception as exc:  # not a file, or not an ELF file (pyelftools' ELFError)
            raise ConfigError("elf", str(elf), f"the firmware's ELF file ({str(exc).strip()})") from None
        try:
            session_link.open()
        except Exception as exc:
            raise ToolError(f"cannot connect to the drive at {url}: {str(exc).strip() or type(exc).__name__}") from None
        session = DriveSession(session_link, scenario, report=say)
        stack.callback(session.close)
        yield session


def run_tuner(
    scenario: Scenario,
    host: str = "127.0.0.1",
    port: int | None = None,
    open_browser: bool = True,
    link: str | None = None,
    elf: Path | str | None = None,
) -> None:
    """Serve the tuner for ``scenario`` until interrupted.

    Parameters
    ----------
    scenario : pmsm2dof.sim.scenario.Scenario
        Base scenario.
    host : str
        Interface to listen on; the loopback address unless another is asked for explicitly.
    port : int or None
        TCP port; 0 for any free port; None for :data:`~pmsm2dof.ui.tuner.server.DEFAULT_PORT`
        or a free one when it is busy.
    open_browser : bool
        Open the page in the default browser.
    link : str, optional
        The drive mode: the link of a drive built for ``scenario`` (:func:`drive_session`).
    elf : path, optional
        The ELF file of the drive's firmware (its variables' addresses).
    """
    if link is not None and not is_loopback(host):
        raise ConfigError("host", host, "a loopback address (127.0.0.1, localhost) when the tuner drives a drive")
    with contextlib.ExitStack() as stack:
        session = stack.enter_context(drive_session(scenario, link, elf)) if link is not None else None
        _serve(create_app(scenario, drive=session), scenario, host, port, open_browser)


def _serve(app: Any, scenario: Scenario, host: str, port: int | None, open_browser: bool) -> None:
    sock = bind_socket(host, port)
    url = url_of(sock)
    if not is_loopback(host):
        print(
            f"pmsm2dof tune: warning: listening on {host}: reachable from the network, without authentication",
            file=sys.stderr,
        )
    print(f"pmsm2dof tuner for '{scenario.name}' at {url} (Ctrl-C to stop)", flush=True)
    if open_browser:
        webbrowser.open(url)
    serve(app, sock, host)
