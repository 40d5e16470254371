"""Fault scenarios, not in the paper: each anti-windup mode when something fails.

The ``fault-*`` presets (a stall, a DC-link sag, a speed sensor held, zero or wrong for one
sample) run with each anti-windup mode of the speed controller (:func:`run_faults`), and
:func:`fault_figures` measures what the fault did to the drive.
"""

from collections.abc import Mapping
from typing import Any, TypedDict

import numpy as np

from ..core.bindings import AntiWindup
from ..errors import ConfigError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario, load_scenario
from ..sim.simulate import Result
from .engine import Run, run_many
from .paper_runs import AW_LABELS

#: The fault presets of the report, in report order.
FAULT_PRESETS = ("fault-stall", "fault-dc-link-sag", "fault-sensor-hold", "fault-sensor-zero", "fault-sensor-spike")


def run_faults(
    overrides: Mapping[str, Any] | None = None, workers: int | None = None
) -> dict[tuple[str, AntiWindup], Result | str | None]:
    """Simulate every fault preset with each anti-windup mode (:func:`pmsm2dof.studies.engine.run_many`).

    Returns ``{(preset, anti_windup): Result}`` in the order of :data:`FAULT_PRESETS` and
    :data:`~pmsm2dof.studies.paper_runs.AW_LABELS`, or the reason instead of a Result when the
    overrides do not apply to the preset or the run stopped. ``workers``: local threads of the
    engine (default: the cores available).
    """
    runs: dict[tuple[str, AntiWindup], Result | str | None] = {}
    bases: dict[str, Scenario] = {}
    todo: list[Run] = []
    for preset in FAULT_PRESETS:
        for aw in AW_LABELS:
            key = f"{preset}-{aw}"
            try:
                scenario = load_scenario(preset).with_overrides(
                    {**(overrides or {}), "speed_controller.anti_windup": aw}
                )
            except ConfigError as exc:
                runs[preset, aw] = str(exc)
                continue
            bases[key] = scenario
            todo.append(Run(key, key, {}, key))
            runs[preset, aw] = None
    outcomes = {o.key: o for o in run_many(bases, todo, keep=[r.key for r in todo], workers=workers)}
    for preset, aw in runs:
        outcome = outcomes.get(f"{preset}-{aw}")
        if outcome is not None:
            runs[preset, aw] = outcome.result if outcome.metrics is not None else outcome.error
    return runs


class FaultFigures(TypedDict):
    """What a fault did to the drive (:func:`fault_figures`); None where the metrics have no value."""

    t_s: float
    deviation_rpm: float
    x_i_excursion_Nm: float
    i_peak_A: float
    current_limit_time_s: float | None
    recovery_time_s: float | None


def fault_figures(result: Result) -> FaultFigures:
    """What a fault did to the drive, from its start (the jam of the stall) to the end of the run.

    ``deviation_rpm``: peak of ``|speed_ref - speed|``; ``x_i_excursion_Nm``: peak change of the
    speed integrator from its value before the fault; ``i_peak_A``: peak ``||i_dq||`` (the limit
    bounds the command, not a current the inverter lacks the voltage to oppose);
    ``current_limit_time_s`` and ``recovery_time_s`` from :func:`pmsm2dof.sim.metrics.compute_metrics`:
    the fault's own figures, or for the stall those of the jam and of its release.
    """
    m = compute_metrics(result)
    if m["faults"]:
        fault = m["faults"][0]
        t0, recovery, limit_time = fault["t_s"], fault["recovery_time_s"], fault["current_limit_time_s"]["value"]
    else:
        jam, release = m["load_steps"][:2]
        t0, recovery = jam["t_s"], release["recovery_time_s"]
        limit_time = jam["current_limit_time_s"]["value"] + release["current_limit_time_s"]["value"]
    k0 = int(np.searchsorted(result.t_s, t0 - 1e-9))
    after = slice(k0, None)
    return {
        "t_s": t0,
        "deviation_rpm": float(np.max(np.abs(result.speed_ref_rpm[after] - result.speed_rpm[after]))),
        "x_i_excursion_Nm": float(np.max(np.abs(result.x_i_Nm[after] - result.x_i_Nm[max(k0 - 1, 0)]))),
        "i_peak_A": float(np.max(np.hypot(result.id_A[after], result.iq_A[after]))),
        "current_limit_time_s": limit_time,
        "recovery_time_s": recovery["value"],
    }
