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

from ...errors import ConfigError
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
def drive_session(scenario: Scenario, link: str, a2l: Path | str | None) -> "Iterator[DriveSession]":
    """A :class:`~pmsm2dof.studies.bench.DriveSession` on the drive at ``link`` (its firmware's A2L file ``a2l``).

    ``link`` is ``socket://HOST:PORT``, a serial device, or :data:`VIRTUAL_LINK`: the PC's virtual
    drive of ``scenario`` built and started here (on the wall clock) for the session's length.
    Events of the session are printed on stderr.
    """
    from ...drive.session import open_link
    from ...studies.bench import DriveSession
    from ...studies.firmware import serve_scenario

    def say(text: str) -> None:
        print(f"pmsm2dof tune: drive: {text}", file=sys.stderr, flush=True)

    with contextlib.ExitStack() as stack:
        if link == VIRTUAL_LINK:
            if a2l is not None:
                raise ConfigError("a2l", str(a2l), f"none with link = {VIRTUAL_LINK} (the drive is built here)")
            url, folder = stack.enter_context(serve_scenario(scenario))
            a2l = folder / "virtual_drive_host.a2l"
        else:
            if a2l is None:
                raise ConfigError("a2l", None, f"the A2L file of the firmware the drive at {link} runs")
            url = link
        session_link = stack.enter_context(open_link(url, a2l))
        session = DriveSession(session_link, scenario, report=say)
        stack.callback(session.close)
        yield session


def run_tuner(
    scenario: Scenario,
    host: str = "127.0.0.1",
    port: int | None = None,
    open_browser: bool = True,
    link: str | None = None,
    a2l: Path | str | None = None,
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
    a2l : path, optional
        The A2L file of the drive's firmware (its variables' addresses, types and limits).
    """
    if link is not None and not is_loopback(host):
        raise ConfigError("host", host, "a loopback address (127.0.0.1, localhost) when the tuner drives a drive")
    with contextlib.ExitStack() as stack:
        session = stack.enter_context(drive_session(scenario, link, a2l)) if link is not None else None
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
