"""The report's section on self-commissioning (not in the paper): the C routine identifies the drive.

:func:`run_commissioning` runs the C commissioning routine (``commission.h``) through the engine on
the paper's drive and on a salient servo, each on an ideal and on a real drive
(:func:`pmsm2dof.studies.commissioning.real_drive`); :func:`commissioning_blocks` tabulates the
identified against the true Rs, Ld, Lq, psi_f and the time each step took.
"""

import math
from collections.abc import Mapping
from typing import Any

from ...sim.commission import ESTIMATES, TARGETS, Commissioning, commission
from ...sim.scenario import load_scenario
from ...studies.commissioning import real_drive, servo_scenario

__all__ = ["commissioning_blocks", "run_commissioning"]


def run_commissioning() -> dict[tuple[str, str], Commissioning]:
    """``{(machine, drive): Commissioning}`` for the paper's drive and the salient servo, ideal and real."""
    runs = {}
    for machine, scenario in (("paper drive", load_scenario("paper-condition-2")), ("salient servo", servo_scenario())):
        runs[machine, "ideal"] = commission(scenario)
        runs[machine, "real"] = commission(real_drive(scenario))
    return runs


def _pct(x: float) -> str:
    return f"{x * 100:+.2f} %" if math.isfinite(x) else "-"


def commissioning_blocks(runs: Mapping[tuple[str, str], Commissioning] | None) -> list[tuple[Any, ...]]:
    """The report blocks of the section (none without runs)."""
    if runs is None:
        return []
    header = ("machine", "drive", "outcome", *(f"{k} error" for k in ESTIMATES), "time [s]")
    rows = []
    for (machine, drive), r in runs.items():
        outcome = r.phase if r.phase == "done" else f"failed in {r.failed_phase}: {r.reason}"
        rows.append(
            (machine, drive, outcome, *(_pct(r.errors[k]) for k in ESTIMATES), f"{sum(r.phase_time_s.values()):.3g}")
        )
    phases = list(next(iter(runs.values())).phase_time_s)
    step_rows = [(phase, *(f"{r.phase_time_s.get(phase, math.nan):.3g}" for r in runs.values())) for phase in phases]
    step_header = ("step", *(f"{machine}, {drive}" for machine, drive in runs))
    targets = ", ".join(f"{k} {v * 100:g} %" for k, v in TARGETS.items())
    return [
        ("h2", "Self-commissioning (not in the paper)"),
        (
            "p",
            "The speed loop of the paper sits on a current loop designed from Rs and L, and its torque constant "
            "comes from psi_f. The C library's commissioning routine (`commission.h`, float32, once per current "
            "sample) measures them on the drive: rotor alignment, Rs from two DC levels (the inverter's error "
            "cancels), Ld and Lq by square-wave injection at standstill, psi_f from the back-EMF under I-f "
            "control. Here the engine runs it against the scenario's motor (`pmsm2dof commission`); errors are "
            f"identified / true - 1, targets {targets}. Real drive: a dead-time error of 1 % of u_dc per phase, "
            "current noise of 1 % of the test current, one period of computation delay. The routine's settings "
            "are derived from the motor (`pmsm2dof.sim.commission.commissioning_config`); the overrides of the "
            "reproduction do not apply here.",
        ),
        ("table", header, rows),
        ("p", "Simulated time of each step [s]:"),
        ("table", step_header, step_rows),
    ]
