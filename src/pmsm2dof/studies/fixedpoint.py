"""The paper's conditions with the fixed-point speed controllers (Q31, Q15) against float32.

Not in the paper: an MCU without an FPU runs the speed controller in integers
(csrc/include/pmsm2dof/speed_fixed.h, ``speed_controller.arithmetic``). :func:`run_arithmetic`
runs the conditions of :data:`PRESETS` in each arithmetic of :data:`ARITHMETICS`, at the full
scales the engine derives from the drive (twice the no-load speed; the torque that holds the limit
and the feedforward's state), and the trap of the issue the paper's design walks into: condition 3
at Ts = 1e-4 s in Q15 at 1000 rpm and 10 Nm (:data:`DEAD_ZONE_RUN`), where the integrator's dead
zone keeps a steady-state error after the 8 Nm load. Each row holds the largest speed deviation
from the float32 run, the error at the end and the dead zone :func:`~pmsm2dof.analysis.fixedpoint.
scaling_check` predicts for the run's scalings.

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller", section 4 (the conditions).
"""

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..analysis.design import design
from ..analysis.fixedpoint import scaling_check
from ..errors import ConfigError
from ..sim.scenario import Scenario, load_scenario
from ..sim.simulate import Result, Simulation
from .engine import Run, run_many

RPM_PER_RADPS = 30.0 / math.pi
#: The arithmetics of the speed controller, in the order of the report (``speed_controller.arithmetic``).
ARITHMETICS = ("float32", "q31", "q15")
#: The paper's conditions compared (their presets, as shipped but for the study's overrides).
PRESETS = ("paper-condition-1", "paper-condition-2", "paper-experiment-3")
#: The Q15 dead zone of the paper's design: condition 3 sampled at 1e-4 s, the 1DOF PI (the
#: reference is constant), 1000 rpm and 10 Nm full scale, run long enough to come to rest.
DEAD_ZONE_PRESET = "paper-experiment-3"
DEAD_ZONE_RUN: dict[str, Any] = {
    "speed_controller.Ts_s": 1e-4,
    "speed_controller.feedforward": "none",
    "simulation.t_end_s": 40.0,
    "simulation.log_every": 100,
}
#: Its full scales (the fixed-point runs).
DEAD_ZONE_SCALES: dict[str, Any] = {
    "speed_controller.speed_full_scale_rpm": 1000.0,
    "speed_controller.torque_full_scale_Nm": 10.0,
}
#: The name of the dead-zone condition in the rows.
DEAD_ZONE_NAME = "paper-experiment-3 at Ts 1e-4 s, 1DOF, 1000 rpm / 10 Nm"


@dataclasses.dataclass(frozen=True)
class ArithmeticRow:
    """One condition in one arithmetic.

    Attributes
    ----------
    condition : the preset (or :data:`DEAD_ZONE_NAME`)
    arithmetic : ``float32``, ``q31`` or ``q15``
    speed_full_scale_rpm, torque_full_scale_Nm : the full scales run (None for float32)
    deviation_rpm : largest absolute difference of the speed from the float32 run's [rpm] (0 for float32)
    final_error_rpm : reference - speed at the end of the run [rpm]
    dead_zone_rpm : the largest error the integrator ignores, as the scaling check predicts [rpm]
        (None for float32)
    error : why the run did not complete ("" when it did)
    """

    condition: str
    arithmetic: str
    speed_full_scale_rpm: float | None
    torque_full_scale_Nm: float | None
    deviation_rpm: float | None
    final_error_rpm: float | None
    dead_zone_rpm: float | None
    error: str = ""


@dataclasses.dataclass(frozen=True)
class ArithmeticStudy:
    """The rows and the traces of :func:`run_arithmetic`: ``results[condition, arithmetic]``."""

    rows: tuple[ArithmeticRow, ...]
    results: dict[tuple[str, str], Result]


def _dead_zone_rpm(scenario: Scenario, full_scales: Mapping[str, float]) -> float:
    """The dead zone of the scenario's design at its full scales (scaling_check) [rpm]."""
    sc, motor = scenario.speed_controller, scenario.motor
    d = design(
        sc.J_kgm2,
        sc.alpha_radps,
        sc.zeta,
        m=sc.m,
        tau_i_s=sc.tau_i_s,
        feedforward=sc.feedforward,
        anti_windup=sc.anti_windup,
        Ka=sc.Ka,
    )
    report = scaling_check(
        d,
        sc.Ts_s,
        fmt="q15" if sc.arithmetic == "q15" else "q31",
        speed_full_scale_radps=full_scales["speed_full_scale_radps"],
        torque_full_scale_Nm=full_scales["torque_full_scale_Nm"],
        method=sc.method,
        T_max_Nm=1.5 * motor.pole_pairs * motor.psi_f_Wb * scenario.limits.i_max_A,
    )
    return report.dead_zone.width_radps * RPM_PER_RADPS


def run_arithmetic(overrides: Mapping[str, Any] | None = None, workers: int | None = None) -> ArithmeticStudy:
    """Simulate each condition of :data:`PRESETS` and the dead-zone run in every arithmetic.

    A condition that the overrides do not apply to, or whose run stops, gets rows with the reason.
    """
    conditions: dict[str, Scenario | str] = {}
    for name, preset, extra in [(p, p, {}) for p in PRESETS] + [(DEAD_ZONE_NAME, DEAD_ZONE_PRESET, DEAD_ZONE_RUN)]:
        try:
            conditions[name] = load_scenario(preset).with_overrides({**dict(overrides or {}), **extra})
        except ConfigError as exc:
            conditions[name] = str(exc)
    bases: dict[str, Scenario] = {}
    todo: list[Run] = []
    scales: dict[tuple[str, str], dict[str, float]] = {}
    failed: dict[tuple[str, str], str] = {}
    for name, scenario in conditions.items():
        for arithmetic in ARITHMETICS:
            if isinstance(scenario, str):
                failed[name, arithmetic] = scenario
                continue
            fixed = {"speed_controller.arithmetic": arithmetic}
            if name == DEAD_ZONE_NAME and arithmetic != "float32":
                fixed |= DEAD_ZONE_SCALES
            try:
                changed = scenario.with_overrides(fixed)
                scales[name, arithmetic] = Simulation(changed).full_scales
            except ConfigError as exc:
                failed[name, arithmetic] = str(exc)
                continue
            key = f"{name} {arithmetic}"
            bases[key] = changed
            todo.append(Run((name, arithmetic), key, {}, key))
    outcomes = run_many(bases, todo, keep=[r.key for r in todo], workers=workers)
    results: dict[tuple[str, str], Result] = {}
    for o in outcomes:
        if o.result is not None:
            results[o.key] = o.result  # type: ignore[index]
        else:
            failed[o.key] = o.error  # type: ignore[index]
    rows = []
    for name in conditions:
        reference = results.get((name, "float32"))
        for arithmetic in ARITHMETICS:
            run = results.get((name, arithmetic))
            if run is None:
                rows.append(ArithmeticRow(name, arithmetic, None, None, None, None, None, failed[name, arithmetic]))
                continue
            fs = scales[name, arithmetic]
            fixed_point = arithmetic != "float32"
            rows.append(
                ArithmeticRow(
                    condition=name,
                    arithmetic=arithmetic,
                    speed_full_scale_rpm=fs["speed_full_scale_radps"] * RPM_PER_RADPS if fixed_point else None,
                    torque_full_scale_Nm=fs["torque_full_scale_Nm"] if fixed_point else None,
                    deviation_rpm=(
                        None if reference is None else float(np.max(np.abs(run.speed_rpm - reference.speed_rpm)))
                    ),
                    final_error_rpm=float(run.speed_ref_rpm[-1] - run.speed_rpm[-1]),
                    dead_zone_rpm=_dead_zone_rpm(run.scenario, fs) if fixed_point else None,
                )
            )
    return ArithmeticStudy(tuple(rows), results)
