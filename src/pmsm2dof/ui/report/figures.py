"""The figures of the reproduction report, each with the numbers it draws.

Fig. 7 (Bode of Gx), Fig. 8 to 10 (simulation conditions 1 and 2), Fig. 12 to 14 (the
experimental conditions, simulated), the sensitivity figures, the discretization study and the
fault scenarios, drawn on matplotlib's Agg canvas from the studies of
:mod:`pmsm2dof.studies.paper` and :mod:`pmsm2dof.studies.faults`. Beside each figure, a
:class:`FigureData` records the numbers it draws, written as CSV.
"""

import csv
import io
import itertools
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...core.bindings import AntiWindup
from ...sim.simulate import Result
from ...studies import paper as st
from ...studies import paper_runs as pr
from ...studies.claims import FIG7_M
from ...studies.configuration import scenario_design
from ...studies.faults import FAULT_PRESETS, fault_figures
from ..plots.design import bode_gx_sweep

#: Most points per line in the time plots (the traces are thinned evenly beyond it).
PLOT_POINTS = 2500


class FigureData:
    """The numbers a report figure draws, as named columns: written beside it as CSV.

    Every line of a figure is drawn from the values :meth:`__call__` records, so the CSV holds
    exactly what the figure shows. Names end with the unit, as the traces and the metrics spell
    them (``speed_rpm``, ``iq_ref_A``, ``overshoot_pct``), after a tag of the run or series
    (``1dof_none_speed_rpm``). A name shared by several lines (their time axis) must hold the
    same values each time. Columns may differ in length: a shorter one ends in empty cells, and
    NaN (a figure that could not be computed) is an empty cell.
    """

    def __init__(self) -> None:
        self.columns: dict[str, npt.NDArray[np.float64]] = {}

    def __call__(self, name: str, values: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Record column ``name``; return its values (a float array) to draw."""
        array = np.atleast_1d(np.asarray(values, dtype=float))
        known = self.columns.get(name)
        if known is not None and not np.array_equal(known, array, equal_nan=True):
            raise ValueError(f"figure data column {name!r} recorded with two different sets of values")
        self.columns[name] = array
        return array

    def to_csv(self) -> str:
        """The columns as CSV text: a header row, then numbers in their shortest exact form."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(self.columns)
        for row in itertools.zip_longest(*self.columns.values()):
            writer.writerow(["" if v is None or not math.isfinite(v) else repr(float(v)) for v in row])
        return buf.getvalue()


def _tag(label: str) -> str:
    """A series label as a column-name prefix: ``"2DOF eq 15, no AW"`` -> ``"2dof_eq_15_no_aw"``."""
    return re.sub(r"[^a-z0-9]+", "_", label.lower()).strip("_")


def _figure(rows: int, cols: int = 1, height: float = 2.6, width: float = 8.0) -> tuple[Figure, npt.NDArray[Any]]:
    """A figure on the Agg canvas and its (rows, cols) array of Axes."""
    fig = Figure(figsize=(width, height * rows + 0.7), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False)
    return fig, axes


def _thin(
    result: Result, name: str, t0: float | None = None, t1: float | None = None
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Time and signal ``name`` of ``result`` over [t0, t1), at most :data:`PLOT_POINTS` points."""
    t = result.t_s
    keep = np.ones(t.shape, bool) if t0 is None or t1 is None else (t >= t0) & (t < t1)
    idx = np.nonzero(keep)[0]
    idx = idx[:: max(1, math.ceil(idx.size / PLOT_POINTS))]
    return t[idx], getattr(result, name)[idx]


def _trace(
    data: FigureData,
    ax: Axes,
    result: Result,
    name: str,
    column: str,
    prefix: str = "",
    t0: float | None = None,
    t1: float | None = None,
    **style: Any,
) -> None:
    """Draw signal ``name`` of ``result`` against time on ``ax``, recorded as ``column`` and its time axis."""
    t, y = _thin(result, name, t0, t1)
    ax.plot(data(f"{prefix}t_s", t), data(column, y), **style)


_AW_STYLE: dict[str, dict[str, Any]] = {
    "none": {"color": "C3"},
    "back_calculation": {"color": "C0"},
    "clamping": {"color": "C2", "ls": "--"},
}
_DOF_STYLE: dict[str, dict[str, Any]] = {"1dof": {"color": "C3"}, "2dof": {"color": "C0"}}
#: Two responses equal to the bit: the first wide and pale under the second, dashed.
_SAME_STYLE: dict[str, dict[str, Any]] = {
    "1dof": {"color": "C3", "lw": 3.0, "alpha": 0.5},
    "2dof": {"color": "C0", "lw": 1.2, "ls": "--"},
}


def _finish(ax: Axes, ylabel: str, xlabel: str | None = None) -> None:
    ax.set_ylabel(ylabel)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="best")


def _current_limit(ax: Axes, result: Result, signs: Sequence[int] = (1, -1)) -> None:
    """Dotted horizontal lines at the current limit (``+i_max`` and ``-i_max`` by default)."""
    i_max = result.scenario.limits.i_max_A
    for sign in signs:
        ax.axhline(sign * i_max, color="grey", lw=0.8, ls=":")


def _load_steps(axes: Sequence[Axes], result: Result) -> None:
    """Dashed vertical lines at the load steps of ``result``, labelled on the first axes."""
    for entry in result.scenario.load:
        for ax in axes:
            ax.axvline(entry.t_s, color="C4", lw=0.8, ls="--")
        axes[0].annotate(
            f"load {entry.torque_Nm:g} Nm",
            (entry.t_s, axes[0].get_ylim()[0]),
            fontsize="small",
            color="C4",
            xytext=(3, 3),
            textcoords="offset points",
        )


def fig_aw(studies: st.Studies, cond: str, signal: str) -> tuple[Figure, FigureData]:
    """Fig. 8 (speed) or 9 (current command) of condition ``cond``: each AW mode, 1DOF and 2DOF."""
    fig, axes = _figure(2)
    data = FigureData()
    for ax, (dof, label) in zip(axes[:, 0], (("1dof", pr.ONE_DOF), ("2dof", pr.TWO_DOF))):
        first = studies.results[f"{cond}-{dof}-none"]
        if signal == "speed_rpm":
            _trace(data, ax, first, "speed_ref_rpm", "speed_ref_rpm", color="k", ls=":", lw=1.0, label="reference")
        else:
            _current_limit(ax, first)
        for aw, aw_label in pr.AW_LABELS.items():
            _trace(
                data,
                ax,
                studies.results[f"{cond}-{dof}-{aw}"],
                signal,
                f"{dof}_{aw}_{signal}",
                lw=1.3,
                label=aw_label,
                **_AW_STYLE[aw],
            )
        ax.set_title(label)
        _finish(ax, "speed [rpm]" if signal == "speed_rpm" else "iq command [A]")
    axes[-1, 0].set_xlabel("time [s]")
    number, what = (8, "speed") if signal == "speed_rpm" else (9, "current command iq_cmd")
    fig.suptitle(f"Fig. {number}: simulation condition 1, {what} without and with AW")
    return fig, data


def fig_2dof(studies: st.Studies, cond: str) -> tuple[Figure, FigureData]:
    """Fig. 10: condition 2, speed and current command of the 1DOF PI and of the 2DOF controller."""
    fig, axes = _figure(2)
    data = FigureData()
    ax_w, ax_i = axes[:, 0]
    r1 = studies.results[f"{cond}-1dof"]
    _trace(data, ax_w, r1, "speed_ref_rpm", "speed_ref_rpm", color="k", ls=":", lw=1.0, label="reference")
    for dof, label in (("1dof", pr.ONE_DOF), ("2dof", pr.TWO_DOF)):
        r = studies.results[f"{cond}-{dof}"]
        _trace(data, ax_w, r, "speed_rpm", f"{dof}_speed_rpm", lw=1.3, label=label, **_DOF_STYLE[dof])
        _trace(data, ax_i, r, "iq_ref_A", f"{dof}_iq_ref_A", lw=1.3, label=label, **_DOF_STYLE[dof])
    _load_steps((ax_w, ax_i), r1)
    _finish(ax_w, "speed [rpm]")
    _finish(ax_i, "iq command [A]", "time [s]")
    fig.suptitle("Fig. 10: simulation condition 2, 1DOF PI against the 2DOF controller")
    return fig, data


def fig_exp1(studies: st.Studies) -> tuple[Figure, FigureData]:
    """Fig. 12: experiment 1, the 500 rpm step with and without AW."""
    fig, axes = _figure(1, height=3.2)
    data = FigureData()
    ax = axes[0, 0]
    _trace(
        data,
        ax,
        studies.results["e1-1dof-none"],
        "speed_ref_rpm",
        "speed_ref_rpm",
        color="k",
        ls=":",
        lw=1.0,
        label="reference",
    )
    for dof, label in (("1dof", pr.ONE_DOF), ("2dof", pr.TWO_DOF)):
        for aw in ("none", "back_calculation"):
            style = dict(_DOF_STYLE[dof], ls="-" if aw == "back_calculation" else "--")
            _trace(
                data,
                ax,
                studies.results[f"e1-{dof}-{aw}"],
                "speed_rpm",
                f"{dof}_{aw}_speed_rpm",
                lw=1.3,
                label=f"{label}, {pr.AW_LABELS[aw]}",
                **style,
            )
    _finish(ax, "speed [rpm]", "time [s]")
    fig.suptitle("Fig. 12 (experiment 1, simulated): speed responses with and without AW")
    return fig, data


def fig_exp2(studies: st.Studies) -> tuple[Figure, FigureData]:
    """Fig. 13: experiment 2, (a) step up and (b) step down, 1DOF PI against 2DOF."""
    r1 = studies.results["e2-1dof"]
    steps = studies.metrics["e2-1dof"]["reference_steps"]
    fig, axes = _figure(2)
    data = FigureData()
    for ax, step, (prefix, title) in zip(axes[:, 0], steps, (("up_", "(a) step up"), ("down_", "(b) step down"))):
        t0, t1 = step["t_s"] - 0.5, step["window_end_s"]
        _trace(
            data,
            ax,
            r1,
            "speed_ref_rpm",
            f"{prefix}speed_ref_rpm",
            prefix,
            t0,
            t1,
            color="k",
            ls=":",
            lw=1.0,
            label="reference",
        )
        for dof, label in (("1dof", pr.ONE_DOF), ("2dof", pr.TWO_DOF)):
            _trace(
                data,
                ax,
                studies.results[f"e2-{dof}"],
                "speed_rpm",
                f"{prefix}{dof}_speed_rpm",
                prefix,
                t0,
                t1,
                lw=1.3,
                label=label,
                **_DOF_STYLE[dof],
            )
        ax.set_title(title)
        _finish(ax, "speed [rpm]")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("Fig. 13 (experiment 2, simulated): speed-reference tracking")
    return fig, data


def fig_exp3(studies: st.Studies) -> tuple[Figure, FigureData]:
    """Fig. 14: experiment 3, the load step at a steady speed: speed and current command."""
    fig, axes = _figure(2)
    data = FigureData()
    ax_w, ax_i = axes[:, 0]
    r1 = studies.results["e3-1dof"]
    for dof, label in (("1dof", pr.ONE_DOF), ("2dof", pr.TWO_DOF)):
        r = studies.results[f"e3-{dof}"]
        _trace(data, ax_w, r, "speed_rpm", f"{dof}_speed_rpm", label=label, **_SAME_STYLE[dof])
        _trace(data, ax_i, r, "iq_ref_A", f"{dof}_iq_ref_A", label=label, **_SAME_STYLE[dof])
    _current_limit(ax_i, r1, signs=(1,))
    _load_steps((ax_w, ax_i), r1)
    _finish(ax_w, "speed [rpm]")
    _finish(ax_i, "iq command [A]", "time [s]")
    fig.suptitle("Fig. 14 (experiment 3, simulated): load-torque rejection")
    return fig, data


def _bode_data(fig: Figure) -> FigureData:
    """The curves of the Bode figure of Fig. 7 (:func:`pmsm2dof.ui.plots.design.bode_gx_sweep`), recorded as drawn."""
    data = FigureData()
    magnitude, phase = fig.axes[:2]
    for m, line_mag, line_phase in zip(FIG7_M, magnitude.lines, phase.lines):
        data("w_radps", line_mag.get_xdata())
        data("w_radps", line_phase.get_xdata())
        data(f"m{m:g}_Gx_magnitude_dB", line_mag.get_ydata())
        data(f"m{m:g}_Gx_phase_deg", line_phase.get_ydata())
    return data


_STEP_PANELS = (("overshoot_pct", "overshoot [%]"), ("settling_time_s", "2 % settling time [s]"))
_LOAD_PANELS = (("speed_dip_rpm", "load-step dip [rpm]"), ("recovery_time_s", "load recovery (2 % of dip) [s]"))


def fig_sweep(studies: st.Studies, sweep: pr.Sweep) -> tuple[Figure, FigureData]:
    """A sensitivity figure: overshoot and settling of the step (and dip and recovery of the load step)."""
    has_load = any(s.kind == "load" for s in sweep.series)
    fig, axes = _figure(2 if has_load else 1, 2, height=3.0, width=9.0)
    data = FigureData()
    panels = [("step", f, label) for f, label in _STEP_PANELS]
    if has_load:
        panels += [("load", f, label) for f, label in _LOAD_PANELS]
    for ax, (kind, figure, label) in zip(axes.flat, panels):
        for k, series in enumerate(s for s in sweep.series if s.kind == kind):
            ls = "--" if kind == "load" and k > 0 else "-"
            ax.plot(
                data(sweep.x_column, sweep.x),
                data(f"{_tag(series.label)}_{figure}", studies.series_values(series, figure)),
                marker="o",
                ms=3.5,
                ls=ls,
                color=f"C{k}",
                label=series.label,
            )
        labels = [s.label for s in sweep.series if s.kind == kind]
        for ref_label, run in sweep.references if kind == "step" else ():
            k = next(k for k, label in enumerate(labels) if ref_label.startswith(label))
            value = data(f"{_tag(ref_label)}_{figure}", studies.figure(run.name, "step", figure))[0]
            ax.axhline(
                value,
                color=f"C{k}",
                lw=1.0,
                ls=":" if ref_label.endswith(pr.AW_LABELS["none"]) else "-.",
                label=ref_label,
            )
        for x, mark in sweep.marks:
            ax.axvline(x, color="grey", lw=0.8, ls="--", label=mark)
        for j, (lo, hi, band) in enumerate(sweep.bands):
            ax.axvspan(lo, hi, color=("C0", "C7")[j % 2], alpha=0.08, label=band)
        if sweep.log_x:
            ax.set_xscale("log")
        ax.set_ylim(bottom=0.0)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_ylabel(label)
        ax.set_xlabel(sweep.x_label)
        ax.grid(True, which="both", alpha=0.3)
    axes.flat[0].legend(fontsize="x-small", loc="best")
    if has_load:
        axes.flat[2].legend(fontsize="x-small", loc="best")
    fig.suptitle(f"Sensitivity to the {sweep.title}")
    return fig, data


def fig_discretization(studies: st.Studies) -> tuple[Figure, FigureData]:
    """Discretization study: overshoot, margins and controller error against the sampling period."""
    fig, axes = _figure(2, 2, height=3.0, width=9.0)
    data = FigureData()
    names = {"forward_euler": "forward Euler", "backward_euler": "backward Euler", "tustin": "Tustin"}
    panels = (
        ("overshoot_pct", "step overshoot [%]"),
        ("phase_margin_deg", "phase margin [deg]"),
        ("gain_margin_dB", "gain margin [dB]"),
        ("controller_error", "|F(z)/F(s) - 1| at crossover"),
    )
    for ax, (field, label) in zip(axes.flat, panels):
        for k, method in enumerate(names):
            for controller, ls in ((pr.ONE_DOF, "-"), (pr.TWO_DOF, "--")):
                if controller == pr.TWO_DOF and field != "overshoot_pct":
                    continue  # the feedforward is outside the loop: same margins and PI
                pts = [p for p in studies.discretization if p.controller == controller and p.method == method]
                ax.plot(
                    data("Ts_s", [p.Ts_s for p in pts]),
                    data(f"{_tag(controller)}_{method}_{field}", [getattr(p, field) for p in pts]),
                    ls=ls,
                    marker="o",
                    ms=3,
                    color=f"C{k}",
                    label=names[method] if controller == pr.ONE_DOF else None,
                )
            if field == "overshoot_pct":
                engine = [studies.figure(f"disc-{method}-{Ts:g}", "step", "overshoot_pct") for Ts in pr.TS_ENGINE_S]
                ax.plot(
                    data("engine_Ts_s", pr.TS_ENGINE_S),
                    data(f"engine_{_tag(pr.ONE_DOF)}_{method}_overshoot_pct", engine),
                    ls="none",
                    marker="x",
                    ms=8,
                    color=f"C{k}",
                    label="engine" if k == 0 else None,
                )
        if field == "overshoot_pct":
            for controller, ls in ((pr.ONE_DOF, "-"), (pr.TWO_DOF, "--")):
                value = data(f"continuous_{_tag(controller)}_overshoot_pct", studies.continuous[controller][0])[0]
                ax.axhline(value, color="k", lw=0.8, ls=ls, alpha=0.5)
        elif field == "phase_margin_deg":
            value = data(
                f"continuous_{_tag(pr.ONE_DOF)}_phase_margin_deg", studies.continuous[pr.ONE_DOF][1].phase_margin_deg
            )[0]
            ax.axhline(value, color="k", lw=0.8, alpha=0.5, label="continuous")
        ax.axvline(studies.fine_Ts_s, color="grey", lw=0.8, ls="-.")
        ax.set_xscale("log")
        if field == "controller_error":
            ax.set_yscale("log")
        ax.set_xlabel("speed-loop sampling period Ts [s]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="xx-small", loc="best")
    fig.suptitle(
        "Discretization (Table 1): ZOH loop of the design; black: continuous; dash-dot: largest recommended Ts",
        fontsize="medium",
    )
    return fig, data


def fig_faults(runs: Mapping[tuple[str, AntiWindup], Result | str | None]) -> tuple[Figure, FigureData]:
    """Speed and speed integrator of each fault preset, one line per anti-windup mode."""
    fig, axes = _figure(len(FAULT_PRESETS), 2, height=2.2, width=10.0)
    data = FigureData()
    for (ax_w, ax_x), preset in zip(axes, FAULT_PRESETS):
        results = {aw: run for aw in pr.AW_LABELS if isinstance(run := runs[preset, aw], Result)}
        if not results:
            ax_w.set_title(f"{preset}: did not run", fontsize="small")
            continue
        first = next(iter(results.values()))
        t0 = fault_figures(first)["t_s"] - 0.5
        t1 = first.t_s[-1]
        tag = f"{_tag(preset)}_"
        _trace(
            data,
            ax_w,
            first,
            "speed_ref_rpm",
            f"{tag}speed_ref_rpm",
            tag,
            t0,
            t1,
            color="k",
            ls=":",
            lw=1.0,
            label="reference",
        )
        for aw, result in results.items():
            style = dict(lw=1.2, label=pr.AW_LABELS[aw], **_AW_STYLE[aw])
            _trace(data, ax_w, result, "speed_rpm", f"{tag}{aw}_speed_rpm", tag, t0, t1, **style)
            _trace(data, ax_x, result, "x_i_Nm", f"{tag}{aw}_x_i_Nm", tag, t0, t1, **style)
        ax_w.set_title(first.scenario.description, fontsize="small", loc="left")
        _finish(ax_w, "speed [rpm]")
        _finish(ax_x, "integrator x_i [Nm]")
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    fig.suptitle("Fault scenarios (not in the paper): each anti-windup mode of the 2DOF controller")
    return fig, data


def figures(studies: st.Studies) -> dict[str, tuple[Figure, FigureData, str]]:
    """Every figure of the report: ``{stem: (Figure, FigureData, caption)}`` in report order."""
    sc = studies.speed_controller()
    d = scenario_design(studies.bases[pr.STEP_BASE])
    Kp, Ki = d.Kp, d.Ki
    bode = bode_gx_sweep(
        sc.alpha_radps,
        FIG7_M,
        J_kgm2=sc.J_kgm2,
        zeta=sc.zeta,
        tau_i_s=sc.tau_i_s,
        feedforward="full",
    )
    out = {
        "fig07_bode_gx": (
            bode,
            _bode_data(bode),
            f"Fig. 7: Bode diagram of the tracking response Gx (eq 6 with the feedforward of eq 11), alpha = "
            f"{sc.alpha_radps:g} rad/s, m from {FIG7_M[0]:g} to {FIG7_M[-1]:g}.",
        ),
        "fig08_speed_aw": (
            *fig_aw(studies, "c1", "speed_rpm"),
            "Fig. 8: simulation condition 1 (500 rpm at 0 s, 200 rpm at 5 s, no load), speed without AW, with "
            "back-calculation AW (Ka = 1/Kp) and with clamping; top: 1DOF PI, bottom: 2DOF with the eq 15 "
            "feedforward (the presets' controller).",
        ),
        "fig09_current_aw": (
            *fig_aw(studies, "c1", "iq_ref_A"),
            "Fig. 9: simulation condition 1, the current command iq_cmd of the runs of Fig. 8; dotted: the 7.6 A "
            "limit.",
        ),
        "fig10_2dof": (
            *fig_2dof(studies, "c2"),
            f"Fig. 10: simulation condition 2 (500 rpm at 0 s, 8 Nm at 7 s, 200 rpm at 10 s), 1DOF PI (Kp = "
            f"{Kp:.3g}, Ki = {Ki:.3g}) against the 2DOF "
            "controller with the eq 15 feedforward, both with back-calculation AW.",
        ),
        "fig12_exp1_aw": (
            *fig_exp1(studies),
            "Fig. 12 (experiment 1, simulated): 500 rpm step at 0.5 s, with and without AW.",
        ),
        "fig13_exp2_tracking": (
            *fig_exp2(studies),
            "Fig. 13 (experiment 2, simulated): tracking of (a) the step up 0 -> 500 rpm and (b) the step down "
            "500 -> 200 rpm, 1DOF PI against 2DOF eq 15.",
        ),
        "fig14_exp3_load": (
            *fig_exp3(studies),
            "Fig. 14 (experiment 3, simulated): 8 Nm load step at a steady 500 rpm, speed (top) and current command "
            "iq_cmd (bottom) of the 1DOF PI (wide) and the 2DOF controller (dashed), which coincide: the feedforward "
            "acts on the reference only; dotted: the 7.6 A limit.",
        ),
    }
    captions = {
        "ka": (
            f"Sensitivity to Ka (1DOF PI and 2DOF eq 15, back-calculation AW, 500 rpm step from rest). Shaded: "
            f"1/(3Kp) .. 3/Kp, the range used, and the literal Kp/3 .. 3Kp of the paper's text (Kp = {Kp:.3g}); "
            "dotted: the same step without AW and with clamping."
        ),
        "m": (
            "Sensitivity to m with the feedforward of eq 11: the 500 rpm step with and without AW, and the 8 Nm "
            "load step at 500 rpm, which does not depend on m."
        ),
        "zeta": "Sensitivity to zeta (eq 9): 500 rpm step and 8 Nm load step, 1DOF PI and 2DOF eq 15.",
        "inertia": (
            "Sensitivity to an inertia error: the plant's J from 0.5 to 2 times the J the controller is "
            "designed for (eq 9, 11), 1DOF PI and 2DOF eq 15."
        ),
        "torque_limit": (
            "Sensitivity to the torque the 7.6 A limit allows, 1.5 p psi_f i_max (swept through "
            "psi_f; the paper gives no torque constant): 1DOF PI, 500 rpm step, each AW mode."
        ),
    }
    for sweep in studies.sweeps:
        out[f"sens_{sweep.name}"] = (*fig_sweep(studies, sweep), captions[sweep.name])
    out["discretization"] = (
        *fig_discretization(studies),
        "Discretization study: the design's discrete loop (ZOH plant, python-control) for forward Euler, backward "
        f"Euler and Tustin as Ts grows; overshoot: solid 1DOF PI, dashed 2DOF eq 15, crosses the engine's overshoot "
        f"of a {pr.SMALL_STEP_RPM:g} rpm step with the 1DOF PI. The margins and the PI are the same for both "
        "controllers (the feedforward is outside the loop). Missing points: the discrete loop is unstable.",
    )
    return out
