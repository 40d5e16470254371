"""The report's section on the fixed-point speed controllers (not in the paper).

Drawn from :func:`pmsm2dof.studies.fixedpoint.run_arithmetic`: the paper's conditions in Q31 and
Q15 against float32, and the Q15 dead zone of the paper's design at Ts = 1e-4 s.
"""

from typing import Any

from matplotlib.figure import Figure

from ...studies.fixedpoint import ARITHMETICS, DEAD_ZONE_NAME, ArithmeticStudy
from .figures import FigureData, _figure, _finish, _tag, _trace

#: float32 wide and pale under Q31 (equal to the eye), Q15 apart.
_STYLE: dict[str, dict[str, Any]] = {
    "float32": {"color": "C0", "lw": 3.0, "alpha": 0.4},
    "q31": {"color": "k", "lw": 1.0, "ls": "--"},
    "q15": {"color": "C3", "lw": 1.2},
}

CAPTION = (
    "The paper's conditions with the speed controller in float32 (wide, pale), Q31 (dashed) and Q15 (red): speed. "
    "Last panel: condition 3 at Ts = 1e-4 s (1DOF PI, 1000 rpm and 10 Nm full scale), where the Q15 integrator's "
    "dead zone keeps an error after the 8 Nm load."
)


def fig_fixed_point(study: ArithmeticStudy) -> tuple[Figure, FigureData]:
    """Speed of each condition in each arithmetic, one panel per condition."""
    conditions = list(dict.fromkeys(row.condition for row in study.rows))
    fig, axes = _figure(len(conditions), 1, height=1.9, width=8.0)
    data = FigureData()
    for (ax,), condition in zip(axes, conditions):
        tag = f"{_tag(condition)}_"
        for arithmetic in ARITHMETICS:
            run = study.results.get((condition, arithmetic))
            if run is not None:
                column = f"{tag}{arithmetic}_speed_rpm"
                _trace(data, ax, run, "speed_rpm", column, tag, label=arithmetic, **_STYLE[arithmetic])
        ax.set_title(condition, fontsize="small", loc="left")
        _finish(ax, "speed [rpm]")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("The speed controller in float32, Q31 and Q15")
    return fig, data


def _number(value: float | None, fmt: str) -> str:
    return "" if value is None else format(value, fmt)


def fixed_point_blocks(study: ArithmeticStudy | None) -> list[tuple[Any, ...]]:
    """The section's blocks (none without a study)."""
    if study is None:
        return []
    header = (
        "condition",
        "arithmetic",
        "speed full scale [rpm]",
        "torque full scale [Nm]",
        "largest deviation from float32 [rpm]",
        "error at the end [rpm]",
        "dead zone predicted [rpm]",
    )
    rows = []
    for r in study.rows:
        if r.error:
            rows.append((r.condition, r.arithmetic, f"did not run: {r.error}", "", "", "", ""))
            continue
        rows.append(
            (
                r.condition,
                r.arithmetic,
                _number(r.speed_full_scale_rpm, ".5g"),
                _number(r.torque_full_scale_Nm, ".4g"),
                _number(r.deviation_rpm, ".3g"),
                _number(r.final_error_rpm, ".4g"),
                _number(r.dead_zone_rpm, ".4g"),
            )
        )
    q31 = [r.deviation_rpm for r in study.rows if r.arithmetic == "q31" and r.deviation_rpm is not None]
    trap = {r.arithmetic: r for r in study.rows if r.condition == DEAD_ZONE_NAME and not r.error}
    findings = []
    if q31:
        findings.append(f"Q31 follows float32 to within {max(q31):.2g} rpm on every condition.")
    q15, q31_trap = trap.get("q15"), trap.get("q31")
    if q15 is not None and q31_trap is not None:
        dead_zone, error = q15.dead_zone_rpm or 0.0, q15.final_error_rpm or 0.0
        findings.append(
            f"At Ts = 1e-4 s the Q15 controller keeps an error of {error:.4g} rpm 40 s after the 8 Nm load, "
            f"{'inside' if abs(error) <= dead_zone else 'OUTSIDE'} the dead zone of +-{dead_zone:.4g} rpm that "
            f"`pmsm2dof design --fixed-point q15` predicts; Q31 ends at {q31_trap.final_error_rpm or 0.0:.2g} rpm."
        )
    return [
        ("h2", "Without an FPU: the paper's conditions in Q31 and Q15 (not in the paper)"),
        (
            "p",
            "The speed controller in integers, as an MCU without an FPU runs it (`speed_fixed.h`, scenario key "
            "`speed_controller.arithmetic`): Q31 (int32 data, int64 arithmetic, an integrator with 31 more "
            "fractional bits) and Q15 (int16 data, int32 arithmetic). The full scales are the engine's defaults "
            "(twice the no-load speed; 1.25 times the torque that holds the limit, the low-pass feedforward's "
            "state Fr(0) r, which is many times the limit at 500 rpm, and the command at the reference step), but "
            "for the last condition, the paper's "
            "design at Ts = 1e-4 s at 1000 rpm and 10 Nm. There one torque LSB (10 Nm / 2^15) is more than twice "
            "what the integrator adds per sample, Ki Ts e, for any error below tens of rpm: the integrator's dead "
            "zone, in which a load's steady-state error is never removed. " + " ".join(findings),
        ),
        ("figure", "fixed_point", CAPTION),
        ("table", header, rows),
    ]
