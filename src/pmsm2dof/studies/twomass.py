"""Beyond the rigid load (the paper's conclusion): its design on two-mass trains of the same inertia.

The paper's condition 2 (``paper-condition-2``: 500 rpm, an 8 Nm load at 7 s, 200 rpm at 10 s,
the 2DOF controller with back-calculation) runs on two-mass trains of the paper's total inertia
0.4 kg m^2, split into a motor side of 0.1 and a load side of 0.3 kg m^2 (:func:`run_two_mass`):
for each shaft resonance of :data:`RESONANCES_HZ`, the speed read on the motor or the load side,
the paper's alpha and ten times it, with and without a notch at the resonance. :func:`two_mass_rows`
measures each run against the rigid drive; :func:`stable_region` gives the largest alpha of a
stable sampled loop over inertia ratio and resonance (:mod:`pmsm2dof.analysis.twomass`).
"""

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..analysis.twomass import TwoMass, largest_stable_alpha, two_mass
from ..core import FEEDBACKS
from ..errors import ConfigError
from ..sim.metrics import compute_metrics
from ..sim.scenario import load_scenario
from ..sim.simulate import Result
from .engine import Run, run_many

#: The preset of the study.
PRESET = "paper-condition-2"
#: Motor and load side of the paper's 0.4 kg m^2 [kg m^2].
J_MOTOR_KGM2, J_LOAD_KGM2 = 0.1, 0.3
#: Resonances of the shafts of the study [Hz].
RESONANCES_HZ = (2.0, 5.0, 20.0)
#: Damping ratio of the shaft's resonance [-] (a steel coupling: a few per cent).
RESONANCE_DAMPING = 0.02
#: The alphas of the study, as factors of the preset's [-].
ALPHA_FACTORS = (1.0, 10.0)
#: A run of the study: (resonance [Hz] or None for the rigid drive, the side read or "rigid",
#: the factor of the preset's alpha, with the notch).
Case = tuple[float | None, str, float, bool]
#: The end of a run over which the remaining shaft oscillation is measured [s].
LATE_S = 2.0
#: The notch at the resonance: -3 dB width as a share of its frequency, and its depth [-].
NOTCH_WIDTH_SHARE, NOTCH_DEPTH = 0.5, 0.05
#: Inertia ratios J_L/J_M and resonances [Hz] of the report's stable-region figure.
REGION_RATIOS = (1.0, 3.0, 10.0)
REGION_RESONANCES_HZ = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)
#: A stable region: (the side read, with the notch) -> largest stable alpha [rad/s] over (ratio, resonance).
Regions = dict[tuple[str, bool], np.ndarray]


@dataclasses.dataclass(frozen=True)
class TwoMassStudy:
    """The runs, their rows and the stable regions of two-mass trains around one design.

    ``regions[(feedback, notch)]``: the largest stable alpha [rad/s] over ``ratios`` (rows; the load
    side: the first ratio alone, it does not depend on it) and ``resonances_Hz`` (columns).
    """

    rows: list[dict[str, Any]]
    regions: Regions
    alpha_radps: float
    zeta: float
    tau_i_s: float
    Ts_s: float
    ratios: tuple[float, ...] = REGION_RATIOS
    resonances_Hz: tuple[float, ...] = REGION_RESONANCES_HZ


def train_overrides(
    f_r_Hz: float,
    feedback: str,
    notch: bool,
    ratio: float = J_LOAD_KGM2 / J_MOTOR_KGM2,
    J_total_kgm2: float = J_MOTOR_KGM2 + J_LOAD_KGM2,
    resonance_damping: float = RESONANCE_DAMPING,
    notch_width_share: float = NOTCH_WIDTH_SHARE,
    notch_depth: float = NOTCH_DEPTH,
) -> dict[str, Any]:
    """Scenario overrides: a two-mass train of ``J_total_kgm2`` with load/motor inertia ``ratio`` and
    its resonance at ``f_r_Hz`` (damping ratio ``resonance_damping``), read on ``feedback``; with
    ``notch`` a notch at the resonance, ``notch_width_share`` of it wide and ``notch_depth`` deep. The
    speed controller stays designed for the total inertia."""
    J_total = J_total_kgm2
    J_M, J_L = J_total / (1.0 + ratio), J_total * ratio / (1.0 + ratio)
    w_r = 2.0 * math.pi * f_r_Hz
    K = w_r**2 * J_M * J_L / J_total
    D = 2.0 * resonance_damping * w_r * J_M * J_L / J_total
    overrides: dict[str, Any] = {
        "motor.J_kgm2": J_M,
        "mechanics.model": "two_mass",
        "mechanics.J_load_kgm2": J_L,
        "mechanics.stiffness_Nm_per_rad": K,
        "mechanics.damping_Nms_per_rad": D,
        "mechanics.feedback": feedback,
    }
    if notch:
        overrides |= {
            "speed_filter.notch_freq_Hz": f_r_Hz,
            "speed_filter.notch_width_Hz": notch_width_share * f_r_Hz,
            "speed_filter.notch_depth": notch_depth,
        }
    return overrides


def run_two_mass(overrides: Mapping[str, Any] | None = None, workers: int | None = None) -> dict[Case, Result | str]:
    """Simulate the study (module docstring) and the rigid drive at each alpha.

    Returns ``{(f_r_Hz, feedback, alpha_factor, notch): Result}``, with ``(None, "rigid",
    alpha_factor, False)`` for the rigid drive, or the reason instead of a Result when the
    overrides do not apply or the run stopped.
    """
    base = load_scenario(PRESET).with_overrides(dict(overrides or {}))
    alpha = base.speed_controller.alpha_radps
    cases: list[Case] = [(None, "rigid", a, False) for a in ALPHA_FACTORS]
    cases += [
        (f_r, fb, a, notch)
        for f_r in RESONANCES_HZ
        for fb in FEEDBACKS
        for a in ALPHA_FACTORS
        for notch in (False, True)
    ]
    runs: dict[Case, Result | str] = {}
    bases, todo = {}, []
    for i, (f_r, fb, a, notch) in enumerate(cases):
        change: dict[str, Any] = {"speed_controller.alpha_radps": a * alpha}
        if f_r is not None:
            change |= train_overrides(f_r, fb, notch)
        try:
            bases[str(i)] = base.with_overrides(change)
        except ConfigError as exc:
            runs[f_r, fb, a, notch] = str(exc)
            continue
        todo.append(Run(i, str(i), {}, f"two-mass {i}"))
    outcomes = {o.key: o for o in run_many(bases, todo, keep=[r.key for r in todo], workers=workers)}
    for i, case in enumerate(cases):
        if i in outcomes:
            o = outcomes[i]
            runs[case] = o.result if o.metrics is not None and o.result is not None else o.error
    return runs


def two_mass_rows(runs: Mapping[Case, Result | str]) -> list[dict[str, Any]]:
    """One row per run of :func:`run_two_mass`: the figures the report's table shows.

    ``overshoot_pct`` of the 500 rpm step and ``load_dip_rpm`` of the 8 Nm step
    (:func:`pmsm2dof.sim.metrics.compute_metrics`); ``off_rigid_rpm``: the largest difference of
    the motor speed from the rigid drive's at the same alpha; ``twist_rpm``: the largest speed
    difference across the shaft, ``|w_m - w_L|``, over the last :data:`LATE_S` seconds, where the
    steps have settled (an oscillation the loop does not damp); ``stopped``: the reason when the run
    did not complete.
    """
    rows = []
    for (f_r, fb, a, notch), result in runs.items():
        row: dict[str, Any] = {"resonance_Hz": f_r, "feedback": fb, "alpha_factor": a, "notch": notch}
        if isinstance(result, str):
            rows.append(row | {"stopped": result})
            continue
        m = compute_metrics(result)
        rigid = runs.get((None, "rigid", a, False))
        late = result.t_s > result.t_s[-1] - LATE_S
        row |= {
            "overshoot_pct": m["reference_steps"][0]["overshoot_pct"]["value"],
            "load_dip_rpm": m["load_steps"][0]["speed_dip_rpm"]["value"] if m["load_steps"] else None,
            "off_rigid_rpm": (
                float(np.max(np.abs(result.speed_rpm - rigid.speed_rpm))) if isinstance(rigid, Result) else None
            ),
            "twist_rpm": float(np.max(np.abs(result.speed_rpm[late] - result.load_speed_rpm[late]))),
            "stopped": "",
        }
        rows.append(row)
    return rows


def stable_region(
    ratios: Sequence[float],
    resonances_Hz: Sequence[float],
    *,
    zeta: float,
    tau_i_s: float,
    Ts_s: float,
    feedback: str,
    notch: bool = False,
    alpha_min_radps: float = 0.1,
    alpha_max_radps: float = 1000.0,
    **shape: float,
) -> np.ndarray:
    """Largest stable alpha [rad/s] over ``ratios`` (J_L/J_M, rows) and ``resonances_Hz`` (columns).

    The trains are those of :func:`train_overrides` (``shape``: its keywords ``J_total_kgm2``,
    ``resonance_damping``, ``notch_width_share``, ``notch_depth``; default the paper's total inertia);
    the eq 9 design is on the total inertia; ``notch`` puts the notch at each resonance. Each value is
    :func:`pmsm2dof.analysis.twomass.largest_stable_alpha` between ``alpha_min_radps`` and
    ``alpha_max_radps``, to 1 %.
    """
    region = np.full((len(ratios), len(resonances_Hz)), math.nan)
    for i, ratio in enumerate(ratios):
        for j, f_r in enumerate(resonances_Hz):
            o = train_overrides(f_r, feedback, notch, ratio, **shape)
            train = two_mass(
                o["motor.J_kgm2"],
                o["mechanics.J_load_kgm2"],
                o["mechanics.stiffness_Nm_per_rad"],
                o["mechanics.damping_Nms_per_rad"],
            )
            filters = {k.split(".")[1]: v for k, v in o.items() if k.startswith("speed_filter.")}
            region[i, j] = largest_stable_alpha(
                train, zeta, tau_i_s, Ts_s, alpha_min_radps, alpha_max_radps, feedback, filters
            )
    return region


def stable_regions(
    ratios: Sequence[float], resonances_Hz: Sequence[float], *, zeta: float, tau_i_s: float, Ts_s: float, **shape: float
) -> Regions:
    """:func:`stable_region` read on either side (the load side: the first ratio alone), without and with a notch."""
    return {
        (fb, notch): stable_region(
            ratios if fb == "motor" else ratios[:1],
            resonances_Hz,
            zeta=zeta,
            tau_i_s=tau_i_s,
            Ts_s=Ts_s,
            feedback=fb,
            notch=notch,
            **shape,
        )
        for fb in FEEDBACKS
        for notch in (False, True)
    }


def paper_region_study(overrides: Mapping[str, Any] | None = None) -> TwoMassStudy:
    """The study's runs and the stable regions of :data:`REGION_RATIOS` x :data:`REGION_RESONANCES_HZ` on
    the preset's design (with ``overrides``)."""
    base = load_scenario(PRESET).with_overrides(dict(overrides or {}))
    sc, tau_i_s = base.speed_controller, base.current_loop.tau_i_s
    rows = two_mass_rows(run_two_mass(overrides))
    regions = stable_regions(REGION_RATIOS, REGION_RESONANCES_HZ, zeta=sc.zeta, tau_i_s=tau_i_s, Ts_s=sc.Ts_s)
    return TwoMassStudy(rows, regions, sc.alpha_radps, sc.zeta, tau_i_s, sc.Ts_s)


def region_around(
    train: TwoMass, alpha_radps: float, zeta: float, tau_i_s: float, Ts_s: float, filters: Mapping[str, float]
) -> TwoMassStudy:
    """The stable regions around one train: resonances from a tenth to ten times its own (9, log-spaced),
    inertia ratios a third, one and three times its own, with the notch of ``filters`` (the fields of
    ``p2d_filter_config_t``; without a notch: :data:`NOTCH_WIDTH_SHARE` and :data:`NOTCH_DEPTH`)."""
    f_r = train.resonance_radps / (2.0 * np.pi)
    ratios = tuple(sorted({train.inertia_ratio, train.inertia_ratio / 3.0, 3.0 * train.inertia_ratio}))
    resonances = tuple(float(f) for f in np.geomspace(f_r / 10.0, 10.0 * f_r, 9))
    notch = filters.get("notch_freq_Hz", 0.0) > 0.0
    regions = stable_regions(
        ratios,
        resonances,
        zeta=zeta,
        tau_i_s=tau_i_s,
        Ts_s=Ts_s,
        J_total_kgm2=train.J_total_kgm2,
        resonance_damping=train.resonance_damping,
        notch_width_share=filters["notch_width_Hz"] / filters["notch_freq_Hz"] if notch else NOTCH_WIDTH_SHARE,
        notch_depth=filters["notch_depth"] if notch else NOTCH_DEPTH,
    )
    return TwoMassStudy([], regions, alpha_radps, zeta, tau_i_s, Ts_s, ratios, resonances)
