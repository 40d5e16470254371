"""The report's section on the speed measurement (not in the paper): :mod:`pmsm2dof.studies.sensing`."""

from collections.abc import Sequence
from typing import Any

from ...studies.sensing import PAPER_OVERSHOOT_PCT, OffsetRow, SensorRow, verdict

_HEADER = (
    "sensor chain",
    "overshoot no AW [%]",
    "overshoot AW [%]",
    "load dip [rpm]",
    "phase margin [deg]",
    "gain margin [dB]",
    "distance to 35/15 [% points]",
)


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def sensing_blocks(rows: Sequence[SensorRow] | None, offsets: Sequence[OffsetRow] = ()) -> list[tuple[Any, ...]]:
    """Blocks of the section (see :func:`pmsm2dof.ui.report.render.report_blocks`); none without rows.

    ``offsets`` (of :func:`pmsm2dof.studies.sensing.offset_study`) adds the current-sensor offsets.
    """
    if not rows:
        return []
    table = [
        (
            "paper, measured (section 4.2)",
            f"{PAPER_OVERSHOOT_PCT['none']:.0f}",
            f"{PAPER_OVERSHOOT_PCT['back_calculation']:.0f}",
            "-",
            "-",
            "-",
            "0",
        )
    ]
    for r in rows:
        table.append(
            (
                r.label,
                _cell(r.overshoot_no_aw_pct),
                _cell(r.overshoot_aw_pct),
                _cell(r.dip_rpm),
                _cell(r.phase_margin_deg),
                _cell(r.gain_margin_dB),
                _cell(r.distance_pct),
            )
        )
    return [
        ("h2", "Speed measurement (not in the paper)"),
        (
            "p",
            "The paper's experiment 1 overshoots 35 % without and 15 % with AW, where the simulated drive with an "
            "exact speed reading overshoots about twice as much. A real drive reads an encoder through an "
            "estimator, a filter and a delay (`[speed_sensor]` of a scenario). Each chain below runs experiment 1 "
            "(1DOF PI, without and with back-calculation AW) and experiment 3 (8 Nm load step, 2DOF eq 15); the "
            "margins are those of the sampled 1DOF loop with the chain (`Design.discretize`). Encoders of 1024 "
            "and 256 counts per revolution, the C difference and PLL estimators, a first-order low-pass, a "
            "transport delay and noise; run `pmsm2dof sensors` for the same table.",
        ),
        ("table", _HEADER, table),
        ("p", verdict(rows)),
        *_offset_blocks(offsets),
    ]


def _offset_blocks(offsets: Sequence[OffsetRow]) -> list[tuple[Any, ...]]:
    if not offsets:
        return []
    header = ("speed [rpm]", "phase-a offset [A]", "torque ripple [Nm]", "predicted [Nm]", "speed ripple [rpm]")
    rows = [
        (
            f"{o.speed_rpm:g}",
            f"{o.offset_a_A:g}",
            f"{o.torque_ripple_Nm:.3g}",
            f"{o.predicted_Nm:.3g}",
            f"{o.speed_ripple_rpm:.3g}",
        )
        for o in offsets
    ]
    return [
        (
            "p",
            "A current sensor's offset (`[current_measurement]`), on experiment 3's drive at constant speed: the "
            "offset I0 of phase a reads as a stator-fixed vector 2 I0 / sqrt(3), a torque ripple at the electrical "
            "frequency. Predicted: the linear dq current loop, whose decoupling uses the measured currents "
            "(`pmsm2dof.studies.sensing.offset_ripple_Nm`); with the paper's slow current loop (tau_i = 0.05 s) "
            "the decoupling's share dominates at speed.",
        ),
        ("table", header, rows),
    ]
