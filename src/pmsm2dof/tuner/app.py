"""The tuner's web application (Starlette): the page, its assets and the JSON endpoints.

Endpoints
---------
``GET /``                          the page (``static/index.html``)
``GET /static/*``                  its script and style sheet
``GET /vendor/plotly.min.js``      plotly.js, served from the installed ``plotly`` package (offline)
``GET /api/controls``              the controls: groups, ranges, choices, values of the base scenario
``POST /api/run``                  run the tuner's experiment for the posted control values
``POST /api/download/{kind}``      ``scenario.toml``, ``header.h`` or ``trace.csv`` of those values

A POST body is a JSON object mapping control keys (the scenario's dotted keys, e.g.
``speed_controller.alpha``, and the experiment's ``tuner.*`` keys) to values. Bad input
(ConfigError) or numerical trouble (SimulationError) answers HTTP 422 with
``{"error": message, "param": key}``; the page shows the message next to the control.
"""

import json
from importlib import resources
from pathlib import Path

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ..errors import ConfigError, SimulationError
from .experiment import Tuner

STATIC_DIR = Path(__file__).parent / "static"


def plotly_js_path():
    """Path of ``plotly.min.js`` inside the installed ``plotly`` Python package."""
    path = resources.files("plotly") / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise FileNotFoundError(f"plotly.min.js is missing from the plotly package at {path}")
    return Path(str(path))


def _error(exc):
    param = exc.param if isinstance(exc, ConfigError) else None
    return JSONResponse({"error": str(exc), "param": param}, status_code=422)


async def _body(request):
    try:
        body = await request.json()
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise ConfigError("body", "(not JSON)", "a JSON object of control values") from None
    if not isinstance(body, dict):
        raise ConfigError("body", body, "a JSON object of control values")
    return body


def create_app(scenario):
    """The tuner application for a base scenario.

    Parameters
    ----------
    scenario : pmsm2dof.scenario.Scenario
        Base scenario: motor, limits, current loop and the initial controller settings.
    """
    tuner = Tuner(scenario)
    plotly_js = plotly_js_path()

    async def index(request):
        return FileResponse(STATIC_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    async def vendor_plotly(request):
        return FileResponse(plotly_js, media_type="text/javascript")

    async def controls(request):
        return JSONResponse(tuner.controls())

    async def run(request):
        try:
            body = await _body(request)
            return JSONResponse(await run_in_threadpool(tuner.run, body))
        except (ConfigError, SimulationError) as exc:
            return _error(exc)

    async def download(request):
        kind = request.path_params["kind"]
        try:
            body = await _body(request)
            filename, media_type, text = await run_in_threadpool(tuner.download, kind, body)
        except (ConfigError, SimulationError) as exc:
            return _error(exc)
        return Response(text, media_type=media_type,
                        headers={"Content-Disposition": f'attachment; filename="{filename}"'})

    routes = [
        Route("/", index),
        Route("/vendor/plotly.min.js", vendor_plotly),
        Route("/api/controls", controls),
        Route("/api/run", run, methods=["POST"]),
        Route("/api/download/{kind}", download, methods=["POST"]),
        Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"),
    ]
    return Starlette(routes=routes)
