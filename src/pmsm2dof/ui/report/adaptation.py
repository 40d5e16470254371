"""The report's section on gain scheduling by the identified inertia (not in the paper).

Drawn from :func:`pmsm2dof.studies.adaptation.run_adaptation`: for each ratio of the plant's J
to the design's, the response of the fixed design, of the design adapted by the online estimator
(``estimator.adapt_gains``) and of the design for the true J.
"""

from collections.abc import Mapping
from typing import Any

from matplotlib.figure import Figure

from ...sim.simulate import Result
from ...studies.adaptation import J_RATIOS, MODES, PRESET, STEP_INDEX, adaptation_figures
from .figures import FigureData, _figure, _finish, _tag, _trace

_STYLE: dict[str, dict[str, Any]] = {
    "fixed": {"color": "C3", "lw": 1.2},
    "adapted": {"color": "C0", "lw": 1.2},
    "matched": {"color": "k", "lw": 1.0, "ls": ":"},
}

CAPTION = (
    "Gain scheduling by the identified J: speed of the paper's condition 1 with the plant's J at each ratio to the "
    "design's 0.4 kg m^2, the fixed design (red), the design adapted by the online estimator (blue) and the design "
    "for the true J (dotted)."
)


def fig_adaptation(runs: Mapping[tuple[float, str], Result | str]) -> tuple[Figure, FigureData]:
    """Speed of each design, one panel per J ratio."""
    fig, axes = _figure(len(J_RATIOS), 1, height=1.9, width=8.0)
    data = FigureData()
    for (ax,), ratio in zip(axes, J_RATIOS):
        tag = f"{_tag(f'j ratio {ratio}')}_"
        for mode in MODES:
            result = runs[ratio, mode]
            if isinstance(result, str):
                continue
            _trace(data, ax, result, "speed_rpm", f"{tag}{mode}_speed_rpm", tag, label=mode, **_STYLE[mode])
        ax.set_title(f"plant J = {ratio:g} x the design's", fontsize="small", loc="left")
        _finish(ax, "speed [rpm]")
    axes[0, 0].legend(fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("Fixed design, adapted by the estimated J, and designed for the true J")
    return fig, data


def adaptation_blocks(runs: Mapping[tuple[float, str], Result | str] | None) -> list[tuple[Any, ...]]:
    """The section's blocks (none without runs)."""
    if runs is None:
        return []
    header = (
        "J plant / design",
        "J estimated [kg m^2]",
        "gains for J [kg m^2]",
        "IAE fixed [rpm s]",
        "IAE adapted [rpm s]",
        "IAE matched [rpm s]",
        "peak from matched, fixed [rpm]",
        "peak from matched, adapted [rpm]",
    )
    rows = []
    for ratio in J_RATIOS:
        f = adaptation_figures(runs, ratio)
        if not f:
            rows.append((f"{ratio:g}", "did not run", "", "", "", "", "", ""))
            continue
        rows.append(
            (
                f"{ratio:g}",
                f"{f['J_est_kgm2']:.4g}",
                f"{f['J_gains_kgm2']:.4g}",
                f"{f['fixed_iae_rpm_s']:.4g}",
                f"{f['adapted_iae_rpm_s']:.4g}",
                f"{f['matched_iae_rpm_s']:.4g}",
                f"{f['fixed_deviation_rpm']:.3g}",
                f"{f['adapted_deviation_rpm']:.3g}",
            )
        )
    return [
        ("h2", "Gain scheduling by the identified inertia (not in the paper)"),
        (
            "p",
            f"The speed PI of eq 9 is designed for J. Here `{PRESET}` runs with the plant's J at 0.5 to 2 times the "
            "design's, three ways: the fixed design; the design adapted by the online estimator of the C library "
            "(`pmsm2dof/inertia.h`, scenario keys `estimator.enabled` and `estimator.adapt_gains`), which "
            "re-designs the speed controller for its estimate through the bumpless `p2d_speed_set_config` at the "
            "first quiet sample (reference constant, output inside the current limit, error within "
            "`estimator.adapt_error_rpm`); and the design for the true J. Figures over the reference step "
            f"{STEP_INDEX} (from its time to the end of the run): the IAE of each design and its peak distance "
            "from the matched response. Where the drive never becomes quiet before that step (the smaller "
            "inertias, on this slow loop), the gains stay those of the design. The runs have no load: the "
            "estimate of the load follows a step with the time constant `estimator.load_memory_s`, and a large "
            "load step during a speed transient is meanwhile taken partly for a change of J (see docs/your-motor.md).",
        ),
        ("figure", "adaptation", CAPTION),
        ("table", header, rows),
    ]
