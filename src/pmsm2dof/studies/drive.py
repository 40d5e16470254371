"""A scenario on the drive and in the engine: the run played over the link beside the simulation of the same scenario.

The drive is a build of the scenario (:func:`pmsm2dof.studies.firmware.build_firmware`): the
PC's virtual drive or the firmware on QEMU's virtual board. Before a run its controllers'
configuration is read over the link and held against the scenario's, field by field in float32:
a drive that runs another design (a ``drive set`` since its build) would not be the engine's run.
"""

import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..drive.link import Link
from ..drive.session import CONTROLLERS, link_errors
from ..errors import ConfigError, SimulationError, ToolError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario
from ..sim.simulate import Result, Simulation
from .autotune import CONSTRAINTS, MARGIN_FIGURES, Spec, step_figures
from .firmware import compare, play_scenario, serve_scenario

#: Longest run played over the link, of the drive's time [s] (the virtual board's schedules and the host's memory).
RUN_MAX_S = 600.0
#: Longest serve of a drive with a set duration [s] (a day; without one it serves until interrupted).
SERVE_MAX_S = 86400.0
#: Wall-clock time allowed per second of the drive's time, on top of a fixed minute [s] (QEMU runs slower).
WALL_S_PER_DRIVE_S = 60.0
#: The constraints of autotune's specification that a trace shows (the margins are the analytic loop's).
TRACE_CONSTRAINTS = tuple(name for name, (figure, _, _) in CONSTRAINTS.items() if figure not in MARGIN_FIGURES)


@dataclasses.dataclass(frozen=True, eq=False)
class DriveRun:
    """A scenario played on the drive and simulated by the engine over the same samples.

    Attributes
    ----------
    scenario : Scenario
    drive : Result
        The drive's trace in the engine's log format.
    engine : Result
        The engine's simulation of the scenario.
    url : str
        The link the run was played over.
    """

    scenario: Scenario
    drive: Result
    engine: Result
    url: str

    def comparison(self) -> dict[str, Any]:
        """:func:`pmsm2dof.studies.firmware.compare` of the drive's trace with the engine's."""
        return compare(self.drive, self.engine)


def judge(trace: Result, limits: dict[str, float]) -> dict[str, Any]:
    """Hold a run's trace against a specification: autotune's constraints (:data:`TRACE_CONSTRAINTS`) on its figures.

    ``limits`` maps Spec fields to their limits; the figures are
    :func:`pmsm2dof.studies.autotune.step_figures` of the trace's metrics, as autotune holds each
    simulated run. Returns ``{"limits", "figures", "misses", "met"}``: ``misses`` lists
    ``{"constraint", "limit", "value", "miss", "unit"}`` of the constraints missed, the largest miss
    relative to its limit (the binding one) first.

    Raises
    ------
    ConfigError
        A limit outside its valid range, or a constraint a trace does not show (naming it).
    """
    check_limits(limits)
    figures = step_figures(compute_metrics(trace))
    misses: list[dict[str, Any]] = []
    for name, limit in limits.items():
        figure, sense, unit = CONSTRAINTS[name]
        value = figures[figure]
        miss = value - limit if sense == "max" else limit - value
        if miss > 0.0:
            misses.append({"constraint": name, "limit": limit, "value": value, "miss": miss, "unit": unit})
    misses.sort(key=lambda m: -m["miss"] / (abs(m["limit"]) or 1.0))
    shown = {CONSTRAINTS[name][0]: _finite(figures[CONSTRAINTS[name][0]]) for name in limits}
    return {"limits": dict(limits), "figures": shown, "misses": _json_misses(misses), "met": not misses}


def check_limits(limits: dict[str, float]) -> None:
    """Raise ConfigError unless ``limits`` are valid constraints of :data:`TRACE_CONSTRAINTS` (as the Spec checks)."""
    for name, limit in limits.items():
        if name not in TRACE_CONSTRAINTS:
            raise ConfigError(name, limit, "one of " + ", ".join(TRACE_CONSTRAINTS) + " (what a trace shows)")
    checked: dict[str, Any] = dict(limits)
    Spec(min_phase_margin_deg=None, min_gain_margin_dB=None, **checked)


def _finite(x: float) -> float | None:
    """A figure for JSON: None for a step that never settled or recovered (inf)."""
    return x if math.isfinite(x) else None


def _json_misses(misses: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**m, "value": _finite(m["value"]), "miss": _finite(m["miss"])} for m in misses]


def check_drive_runs(link: Link, scenario: Scenario) -> None:
    """Raise ConfigError unless the drive's controllers run the scenario's configuration (float32, field by field).

    The drive must also be a virtual drive (its trace row ``vd_trace``): on a real drive the
    engine's plant is not the motor.
    """
    if "vd_trace" not in link.variables:
        raise ConfigError(
            "link", link.url, "a virtual drive (its A2L lists vd_trace): a run is held against the engine"
        )
    sim = Simulation(scenario).sim
    engine_cfg = {"link_speed_config": sim.speed.config, "link_current_config": sim.current.config}
    with link_errors(link, "reading the configuration"):
        for var, (ctype, _, _) in CONTROLLERS.items():
            if var not in link.variables:
                continue
            for s in link.variables[var].scalars:
                drive = link.read(s.name)
                mine = getattr(engine_cfg[var], s.field)
                if np.float32(drive) != np.float32(mine):
                    raise ConfigError(
                        "SCENARIO",
                        scenario.name,
                        f"the scenario the drive runs: its {s.name} is {drive!r}, the scenario's {float(mine)!r} "
                        f"({ctype}; rebuild the drive or set it back)",
                    )


def run_on_drive(link: Link, scenario: Scenario) -> DriveRun:
    """Play ``scenario``'s reference (and load, on the virtual board) on the drive and simulate it with the engine.

    Raises
    ------
    ConfigError
        The drive runs another configuration, or the scenario is longer than :data:`RUN_MAX_S`.
    SimulationError
        The run did not end as done, or a sample was lost.
    ToolError
        The link dropped (the drive's watchdog stops the run).
    """
    t_end = scenario.simulation.t_end_s
    if t_end > RUN_MAX_S:
        raise ConfigError("simulation.t_end_s", t_end, f"at most {RUN_MAX_S:g} s for a run over the link")
    check_drive_runs(link, scenario)
    with link_errors(link, "the run"):
        before = link.status()
        if before["state"] == "running":
            raise ToolError(
                f"the drive at {link.url} is running (sample {before['sample']}): wait for its end or stop it"
            )
        drive = play_scenario(link, scenario, timeout_s=60.0 + WALL_S_PER_DRIVE_S * t_end)
        after = link.status()
    if after["trip_sample"]:
        raise SimulationError(
            f"the link watchdog tripped the run at sample {after['trip_sample']} (the master was silent for longer "
            "than the drive's link timeout): the run is not the scenario's"
        )
    sim = Simulation(scenario)
    start = time.perf_counter()
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, time.perf_counter() - start)
    return DriveRun(scenario=scenario, drive=drive, engine=engine, url=link.url)


def serve_drive(
    scenario: Scenario,
    out: Path | str,
    *,
    port: int,
    realtime: bool,
    timeout_ms: int,
    force: bool,
    duration_s: float | None,
    ready: Callable[[str, str], None],
) -> None:
    """Build the PC's virtual drive of ``scenario`` into ``out`` and serve it on 127.0.0.1:``port``.

    ``ready(url, a2l)`` is called once it listens (its link URL ``tcp://127.0.0.1:PORT`` and its A2L
    file); it serves for ``duration_s`` [s] or, when None, until interrupted
    (:func:`pmsm2dof.studies.firmware.serve_scenario`).
    """
    if duration_s is not None and not (math.isfinite(duration_s) and 0 < duration_s <= SERVE_MAX_S):
        raise ConfigError("duration_s", duration_s, f"(0, {SERVE_MAX_S:g}] s, or none: until interrupted")
    with serve_scenario(scenario, port=port, realtime=realtime, timeout_ms=timeout_ms, out=out, force=force) as (
        url,
        folder,
    ):
        ready("tcp://" + url.removeprefix("socket://"), str(folder / "virtual_drive_host.a2l"))
        end = time.monotonic() + (duration_s if duration_s is not None else math.inf)
        while time.monotonic() < end:
            time.sleep(min(0.1, max(0.0, end - time.monotonic())))
