"""Gain scheduling by the identified inertia, not in the paper: a fixed design against an adapted one.

The paper designs the speed PI for the inertia J (eq 9). When the drive's J differs from the J of
the design, the loop's bandwidth and damping move with the ratio. :func:`run_adaptation` runs
``paper-condition-1`` (500 rpm, then 200 rpm at 5 s) with the plant's J at each ratio of
:data:`J_RATIOS` to the design's 0.4 kg m^2 three ways: the fixed design, the design adapted by
the online estimator of the C library (``estimator.adapt_gains``: the speed controller is
re-designed for the estimate through ``p2d_speed_set_config`` once the estimate is valid) and the
design for the true J (the reference). :func:`adaptation_figures` compares the responses to the
second step, which the adapted controller meets with its new gains.
"""

from collections.abc import Mapping

import numpy as np

from ..errors import ConfigError
from ..sim.scenario import load_scenario
from ..sim.simulate import Result
from .engine import Run, run_many

#: Plant J over the design's J.
J_RATIOS = (0.5, 0.71, 1.0, 1.41, 2.0)

#: The three designs of each ratio.
MODES = ("fixed", "adapted", "matched")

#: The base scenario and the step measured (its second reference step).
PRESET = "paper-condition-1"
STEP_INDEX = 1


def _overrides(ratio: float, mode: str, J_design_kgm2: float) -> dict[str, object]:
    J = J_design_kgm2 * ratio
    overrides: dict[str, object] = {"motor.J_kgm2": J, "speed_controller.J_kgm2": J_design_kgm2}
    if mode == "adapted":
        overrides |= {"estimator.enabled": True, "estimator.adapt_gains": True}
    elif mode == "matched":
        overrides["speed_controller.J_kgm2"] = J
    return overrides


def run_adaptation(
    overrides: dict[str, object] | None = None, workers: int | None = None
) -> dict[tuple[float, str], Result | str]:
    """Simulate every ratio of :data:`J_RATIOS` with each design of :data:`MODES`.

    Returns ``{(ratio, mode): Result}``, or the reason instead of a Result when the overrides do
    not apply or the run stopped.
    """
    base = load_scenario(PRESET)
    if overrides:
        try:
            base = base.with_overrides(overrides)
        except ConfigError as exc:
            return {(ratio, mode): str(exc) for ratio in J_RATIOS for mode in MODES}
    J_design = base.speed_controller.J_kgm2
    bases, todo = {}, []
    for ratio in J_RATIOS:
        for mode in MODES:
            key = f"{ratio}-{mode}"
            bases[key] = base.with_overrides(_overrides(ratio, mode, J_design))
            todo.append(Run(key, key, {}, key))
    outcomes = {o.key: o for o in run_many(bases, todo, keep=[r.key for r in todo], workers=workers)}
    runs: dict[tuple[float, str], Result | str] = {}
    for ratio in J_RATIOS:
        for mode in MODES:
            o = outcomes[f"{ratio}-{mode}"]
            runs[ratio, mode] = o.result if o.metrics is not None and o.result is not None else o.error
    return runs


def adaptation_figures(runs: Mapping[tuple[float, str], Result | str], ratio: float) -> dict[str, float | None]:
    """Figures of one ratio: the step's IAE of each design, their peak deviation from the matched
    response over the step, the final estimate of J and when it first became valid."""
    out: dict[str, float | None] = {}
    results: dict[str, Result] = {}
    for mode in MODES:
        run = runs[ratio, mode]
        if isinstance(run, str):
            return out
        results[mode] = run
    matched = results["matched"]
    t0 = matched.scenario.reference[STEP_INDEX].t_s
    step = matched.t_s >= t0
    for mode, r in results.items():
        err = np.abs(r.speed_ref_rpm[step] - r.speed_rpm[step])
        out[f"{mode}_iae_rpm_s"] = float(np.trapezoid(err, r.t_s[step]))
        out[f"{mode}_deviation_rpm"] = float(np.max(np.abs(r.speed_rpm[step] - matched.speed_rpm[step])))
    adapted = results["adapted"]
    valid = np.flatnonzero(adapted.J_valid)
    out["J_est_kgm2"] = float(adapted.J_est_kgm2[-1])
    out["J_gains_kgm2"] = float(adapted.J_gains_kgm2[-1])
    out["J_valid_after_s"] = float(adapted.t_s[valid[0]]) if valid.size else None
    return out
