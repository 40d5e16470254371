"""The figure of an autotuning: tracking against rejection against robustness.

:func:`plot_pareto` draws every simulated design of :func:`pmsm2dof.studies.autotune_search.autotune`
by its worst-case load IAE per Nm (rejection, the search's objective) and tracking IAE
(tracking) over the inertia range, coloured by its worst-case phase margin (robustness); the
Pareto front is outlined and the chosen design starred. An axis is logarithmic when its values
span more than a decade, else linear, so that it always carries tick labels. Matplotlib's Agg
backend, no display needed.
"""

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ...studies.autotune import OBJECTIVE, AutotuneResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_pareto(result: AutotuneResult, path: Path | str) -> Path:
    """Draw :func:`pareto_figure` of ``result`` into ``path`` (.png or .svg); return the path."""
    fig = pareto_figure(result)
    fig.savefig(path)
    return Path(path)


def pareto_figure(result: AutotuneResult) -> "Figure":
    """The designs of ``result`` (see the module docstring), on the Agg canvas."""
    from matplotlib import ticker
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    simulated = [e for e in result.evaluations if e.stage == "engine" and not e.error]
    fig = Figure(figsize=(7.5, 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()

    def xy(evaluations: Any) -> tuple[list[float], list[float]]:
        return [e.worst[OBJECTIVE] for e in evaluations], [e.worst["tracking_iae_rpm_s"] for e in evaluations]

    pm = [e.worst["phase_margin_deg"] for e in simulated]
    pm = [v if math.isfinite(v) else 90.0 for v in pm]
    x, y = xy(simulated)
    marker = ["o" if e.feasible else "x" for e in simulated]
    for m in ("o", "x"):
        keep = [i for i, k in enumerate(marker) if k == m]
        points = ax.scatter(
            [x[i] for i in keep],
            [y[i] for i in keep],
            c=[pm[i] for i in keep],
            cmap="viridis",
            vmin=min(pm, default=0.0),
            vmax=max(pm, default=90.0),
            marker=m,
            s=18,
            label="meets the spec" if m == "o" else "misses the spec",
        )
    fig.colorbar(points, ax=ax, label="worst-case phase margin [deg]")
    fx, fy = xy(result.pareto)
    ax.scatter(fx, fy, facecolors="none", edgecolors="tab:red", s=70, label="Pareto front")
    cx, cy = xy([result.chosen])
    ax.scatter(cx, cy, marker="*", s=250, color="tab:red", edgecolors="black", label="chosen", zorder=5)
    for axis, values, set_scale in ((ax.xaxis, x, ax.set_xscale), (ax.yaxis, y, ax.set_yscale)):
        finite = [v for v in values if math.isfinite(v) and v > 0.0]
        if finite and max(finite) > 10.0 * min(finite):
            set_scale("log")  # plain numbers at 1, 2 and 5 of each decade, never overlapping
            axis.set_major_formatter(ticker.FuncFormatter(lambda v, _pos: f"{v:g}"))
            axis.set_minor_formatter(ticker.FuncFormatter(lambda v, _pos: f"{v:g}" if f"{v:.0e}"[0] in "25" else ""))
    ax.set_xlabel("worst-case load IAE per Nm of load [rpm s/Nm]")
    ax.set_ylabel("worst-case tracking IAE [rpm s]")
    lo, hi = result.spec.J_range
    ax.set_title(f"{result.scenario.name}: autotune over J ratio {lo:g} to {hi:g}")
    ax.legend(loc="best", fontsize="small")
    ax.grid(True, which="both", alpha=0.3)
    return fig
