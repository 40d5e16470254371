"""The tuner's web application (Starlette): the page, its assets and the JSON endpoints.

Endpoints
---------
``GET /``                          the page (``static/index.html``)
``GET /static/*``                  its script and style sheet
``GET /vendor/plotly.min.js``      plotly.js, served from the installed ``plotly`` package (offline)
``GET /api/controls``              the controls: groups, ranges, choices, values of the base scenario
``POST /api/run``                  run the tuner's experiment for the posted control values
``POST /api/download/{kind}``      ``scenario.toml``, ``header.h`` or ``trace.csv`` of those values
``POST /api/suggest``              autotune the experiment of those values for a specification

In drive mode (:mod:`pmsm2dof.ui.tuner.drive`, ``create_app(scenario, drive=session)``), also:

``GET /api/drive``                 the drive's link, arming, run state and speed controller read back
``POST /api/drive/arm``            ``{"armed": true}`` arms the drive for this page, ``false`` disarms
``POST /api/drive/heartbeat``      the arming page is there (at least every ``heartbeat_timeout_s``)
``POST /api/drive/write``          validate the control values and write their speed controller
``POST /api/drive/run``            run the experiment of the control values on the drive and in its twin

A write or a run by a page that has not armed the drive answers 409 and writes nothing; a failed
link or a drive that refused or stopped answers 502 with the sentence the terminal prints too.

A POST body is a JSON object, sent as ``Content-Type: application/json`` (anything else answers
415: a form of another site cannot post to the tuner without a CORS preflight, which it does
not grant), mapping control keys (the scenario's dotted keys, e.g. ``speed_controller.alpha_radps``,
and ``tuner.J_ratio``) to values. A body longer than :data:`BODY_BYTES_MAX` answers 413 before
it is read whole. Bad input (ConfigError: a body that is no JSON object, nested deeper than
:data:`~pmsm2dof.inputs.NESTING_MAX`, with an integer of thousands of digits, a bad key or
value) or numerical trouble (SimulationError, or a result that is not finite) answers HTTP 422
with ``{"error": message, "param": key}``, both short (a long value is shown by its beginning
and its length) and valid UTF-8; the page shows the message next to the control.

A client (the peer address and the page's ``X-Pmsm2dof-Client`` header) runs one simulation at
a time: a newer run request cancels the older one, which answers 409
(:mod:`pmsm2dof.ui.tuner.slots`). A suggestion (``{"values": ..., "spec": ...}``,
:meth:`~pmsm2dof.ui.tuner.experiment.Tuner.suggest`) runs many simulations on every core: the
server computes one at a time and answers 429 to another asked meanwhile; its work is bounded
by :data:`~pmsm2dof.ui.tuner.experiment.SUGGEST_STEPS_MAX`. The Host and Origin checks are the server's
(:mod:`pmsm2dof.ui.tuner.server`), which knows the address it is bound to.
"""

import threading
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ...errors import PARAM_CHARS_MAX, ConfigError, SimulationError, ToolError, cut_text
from ...inputs import parse_json
from ...sim.scenario import Scenario
from ...studies.bench import DriveSession, NotArmed
from .controls import page_controls
from .drive import DriveMode
from .experiment import Tuner
from .slots import ClientSlots, Superseded

STATIC_DIR = Path(__file__).parent / "static"
#: Header with which the page names itself, so that its runs supersede each other only.
CLIENT_HEADER = "X-Pmsm2dof-Client"
#: Longest request body [bytes]: the page posts some hundred bytes of control values.
BODY_BYTES_MAX = 64 * 1024


def plotly_js_path() -> Path:
    """Path of ``plotly.min.js`` inside the installed ``plotly`` Python package."""
    path = resources.files("plotly") / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise FileNotFoundError(f"plotly.min.js is missing from the plotly package at {path}")
    return Path(str(path))


class _NotJSON(Exception):
    """The request's body is not declared as JSON."""


class _TooLarge(Exception):
    """The request's body is longer than :data:`BODY_BYTES_MAX`."""

    def __init__(self, size: str) -> None:
        super().__init__(f"the body ({size}) is longer than {BODY_BYTES_MAX} bytes: the tuner takes control values")


class _Busy(Exception):
    """A suggestion is being computed: the server computes one at a time."""

    def __init__(self) -> None:
        super().__init__(
            "a suggestion is being computed (it uses every core): one at a time, ask again when it is done"
        )


def _error(exc: Exception) -> JSONResponse:
    if isinstance(exc, _NotJSON):
        return _answer({"error": str(exc), "param": "Content-Type"}, 415)
    if isinstance(exc, _TooLarge):
        return _answer({"error": str(exc), "param": None}, 413)
    if isinstance(exc, Superseded):
        return _answer({"error": str(exc), "param": None}, 409)
    if isinstance(exc, _Busy):
        return _answer({"error": str(exc), "param": None}, 429)
    if isinstance(exc, NotArmed):
        return _answer({"error": str(exc), "param": None}, 409)
    if isinstance(exc, ToolError):
        return _answer({"error": str(exc), "param": None}, 502)
    param = exc.param if isinstance(exc, ConfigError) else None
    return _answer({"error": str(exc), "param": param}, 422)


def _answer(error: dict[str, str | None], status: int) -> JSONResponse:
    """An error answer whose texts are short and valid UTF-8 (a lone surrogate of the request
    escaped), whatever the request held."""

    def safe(text: str | None, limit: int) -> str | None:
        if text is None:
            return None
        return cut_text(text, limit).encode("utf-8", "backslashreplace").decode("utf-8")

    return JSONResponse(
        {"error": safe(error["error"], 4 * PARAM_CHARS_MAX + 1000), "param": safe(error["param"], PARAM_CHARS_MAX)},
        status_code=status,
    )


def _json(data: Any) -> JSONResponse:
    """``data`` as a JSON answer; a non-finite number in it (the analysis of values beyond what
    it can compute) is numerical trouble, answered 422 like a SimulationError."""
    try:
        return JSONResponse(data)
    except ValueError:
        return _error(
            SimulationError("the result holds numbers that are not finite: the values are beyond what can be computed")
        )


async def _body(request: Request) -> dict[str, Any]:
    media_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media_type != "application/json":
        raise _NotJSON(
            f"Content-Type = {media_type or '(none)'!r} is refused: the tuner takes a JSON object "
            "of control values, sent as application/json"
        )
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > BODY_BYTES_MAX:
        raise _TooLarge(f"{int(declared)} bytes")
    data = bytearray()
    async for chunk in request.stream():  # a body sent without its length is read up to the bound
        data += chunk
        if len(data) > BODY_BYTES_MAX:
            raise _TooLarge(f"more than {BODY_BYTES_MAX} bytes")
    body = parse_json(bytes(data), "body", "(the request's body)")
    if not isinstance(body, dict):
        raise ConfigError("body", body, "a JSON object of control values")
    return body


def _client(request: Request) -> tuple[str, str]:
    peer = request.client.host if request.client else ""
    return peer, request.headers.get(CLIENT_HEADER, "")


def create_app(scenario: Scenario, drive: DriveSession | None = None) -> Starlette:
    """The tuner application for a base scenario, in drive mode with a session on a drive.

    Parameters
    ----------
    scenario : pmsm2dof.sim.scenario.Scenario
        Base scenario: motor, limits, current loop, schedules and the initial controller settings.
    drive : pmsm2dof.studies.bench.DriveSession, optional
        A session on the drive built for ``scenario``: the drive mode's endpoints.

    Returns
    -------
    starlette.applications.Starlette
        Its ``state.tuner`` is the :class:`~pmsm2dof.ui.tuner.experiment.Tuner`, its
        ``state.slots`` the :class:`~pmsm2dof.ui.tuner.slots.ClientSlots` of its clients, its
        ``state.suggesting`` the lock held while a suggestion is computed, ``state.drive`` the
        :class:`~pmsm2dof.ui.tuner.drive.DriveMode` or None.
    """
    tuner = Tuner(scenario)
    mode = DriveMode(tuner, drive) if drive is not None else None
    slots = ClientSlots()
    suggesting = threading.Lock()
    plotly_js = plotly_js_path()

    async def index(request: Request) -> Response:
        return FileResponse(STATIC_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    async def vendor_plotly(request: Request) -> Response:
        return FileResponse(plotly_js, media_type="text/javascript")

    async def controls(request: Request) -> Response:
        description = page_controls(tuner.base)
        description["drive"] = mode.describe() if mode is not None else None
        return JSONResponse(description)

    async def run(request: Request) -> Response:
        try:
            body = await _body(request)
            with slots.request(_client(request), supersede=True) as ticket:
                return _json(await run_in_threadpool(tuner.run, body, ticket))
        except (_NotJSON, _TooLarge, Superseded, ConfigError, SimulationError) as exc:
            return _error(exc)

    async def download(request: Request) -> Response:
        kind = request.path_params["kind"]
        try:
            body = await _body(request)
            with slots.request(_client(request), supersede=False) as ticket:
                filename, media_type, text = await run_in_threadpool(tuner.download, kind, body, ticket)
        except (_NotJSON, _TooLarge, ConfigError, SimulationError) as exc:
            return _error(exc)
        return Response(
            text, media_type=media_type, headers={"Content-Disposition": f'attachment; filename="{filename}"'}
        )

    async def suggest(request: Request) -> Response:
        try:
            body = await _body(request)
            if not suggesting.acquire(blocking=False):
                raise _Busy()
            try:
                return _json(await run_in_threadpool(tuner.suggest, body))
            finally:
                suggesting.release()
        except (_NotJSON, _TooLarge, _Busy, ConfigError, SimulationError) as exc:
            return _error(exc)

    async def drive_status(request: Request) -> Response:
        assert mode is not None
        try:
            return _json(await run_in_threadpool(mode.session.status))
        except ToolError as exc:
            return _error(exc)

    async def drive_arm(request: Request) -> Response:
        assert mode is not None
        try:
            body = await _body(request)
            armed = body.get("armed")
            if set(body) != {"armed"} or not isinstance(armed, bool):
                raise ConfigError("armed", body.get("armed", body), "true (arm the drive for this page) or false")
            owner = _client(request)
            await run_in_threadpool(mode.session.arm if armed else mode.session.disarm, owner)
            return _json(await run_in_threadpool(mode.session.status))
        except (_NotJSON, _TooLarge, ConfigError, NotArmed, ToolError) as exc:
            return _error(exc)

    async def drive_heartbeat(request: Request) -> Response:
        assert mode is not None
        try:
            await _body(request)
        except (_NotJSON, _TooLarge, ConfigError) as exc:
            return _error(exc)
        session = mode.session
        return _json(
            {
                "armed": session.heartbeat(_client(request)),
                "running": session.running,
                "lost": session.lost,
                "messages": session.recent(),
            }
        )

    async def drive_write(request: Request) -> Response:
        assert mode is not None
        try:
            body = await _body(request)
            return _json(await run_in_threadpool(mode.write, body, _client(request)))
        except (_NotJSON, _TooLarge, ConfigError, NotArmed, SimulationError, ToolError) as exc:
            return _error(exc)

    async def drive_run(request: Request) -> Response:
        assert mode is not None
        try:
            body = await _body(request)
            return _json(await run_in_threadpool(mode.run, body, _client(request)))
        except (_NotJSON, _TooLarge, ConfigError, NotArmed, SimulationError, ToolError) as exc:
            return _error(exc)

    drive_routes = [
        Route("/api/drive", drive_status),
        Route("/api/drive/arm", drive_arm, methods=["POST"]),
        Route("/api/drive/heartbeat", drive_heartbeat, methods=["POST"]),
        Route("/api/drive/write", drive_write, methods=["POST"]),
        Route("/api/drive/run", drive_run, methods=["POST"]),
    ]
    routes = [
        *(drive_routes if mode is not None else []),
        Route("/", index),
        Route("/vendor/plotly.min.js", vendor_plotly),
        Route("/api/controls", controls),
        Route("/api/run", run, methods=["POST"]),
        Route("/api/download/{kind}", download, methods=["POST"]),
        Route("/api/suggest", suggest, methods=["POST"]),
        Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"),
    ]
    app = Starlette(routes=routes)
    app.state.tuner = tuner
    app.state.slots = slots
    app.state.suggesting = suggesting
    app.state.drive = mode
    return app
