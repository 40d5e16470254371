"""The interactive tuner: ``pmsm2dof tune`` serves a page that redraws the responses as the
controls move (a Starlette app on uvicorn, plotted with the plotly.js shipped in the
``plotly`` package, so it works offline).

See :mod:`pmsm2dof.ui.tuner.experiment` for what is computed, :mod:`pmsm2dof.ui.tuner.app` for
the endpoints and :mod:`pmsm2dof.ui.tuner.server` for serving.
"""

import sys
import webbrowser

from ...sim.scenario import Scenario
from .app import create_app
from .server import bind_socket, is_loopback, serve, serving_in_thread, url_of

#: Scenario the tuner starts from when none is given: a speed step then a load step.
DEFAULT_PRESET = "paper-condition-2"

__all__ = ["DEFAULT_PRESET", "create_app", "run_tuner", "serving_in_thread"]


def run_tuner(scenario: Scenario, host: str = "127.0.0.1", port: int | None = None, open_browser: bool = True) -> None:
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
    """
    app = create_app(scenario)
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
