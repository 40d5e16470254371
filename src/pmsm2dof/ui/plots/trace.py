"""The plot of one simulated run: speed, currents, torques, load and voltage against time.

Drawn like the paper's Fig. 8 to 10 and 12 to 14 (speed and current responses), from a
:class:`~pmsm2dof.sim.simulate.Result`. Intervals where the current-vector limit is active (the
saturation that the anti-windup of Fig. 5 acts on, :func:`~pmsm2dof.sim.metrics.at_current_limit`) are
shaded in every panel; the voltage panel shows ``||u_dq||`` against the inverter's range
``u_dc / sqrt(3)`` and shades, in another colour, the intervals at the voltage limit
(:func:`~pmsm2dof.sim.metrics.at_voltage_limit`).
"""

from pathlib import Path

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ...sim.metrics import at_current_limit, at_voltage_limit
from ...sim.simulate import Result
from .canvas import DPI, decimate_lines, save_figure


def saturated_intervals(
    t: npt.NDArray[np.float64], saturated: npt.ArrayLike, min_gap_s: float = 0.0
) -> list[tuple[float, float]]:
    """(start, end) of each run of set flags; the flag of sample k holds over [t[k], t[k+1]).

    Runs separated by less than ``min_gap_s`` are one (a gap narrower than a pixel is not drawn).
    """
    flags = np.concatenate(([False], np.asarray(saturated, dtype=bool)[:-1], [False]))
    edges = np.flatnonzero(np.diff(flags.astype(np.int8)))
    starts, ends = t[edges[::2]], t[edges[1::2]]
    if starts.size:
        join = np.concatenate(([False], starts[1:] - ends[:-1] < min_gap_s))
        starts, ends = starts[~join], ends[np.concatenate((~join[1:], [True]))]
    return list(zip(starts.tolist(), ends.tolist()))


def trace_figure(result: Result) -> Figure:
    """A four-panel figure of a run: speed [rpm], dq currents [A], torques and load [Nm], voltage [V].

    Parameters
    ----------
    result : Result
        A run of :func:`pmsm2dof.simulate`.

    Returns
    -------
    matplotlib.figure.Figure
        On the Agg canvas. The current panel shows the limit ``+-limits.i_max_A``; shaded spans
        mark the samples where the current-vector limit is active. The torque panel is scaled to
        the torques applied (limited command, ``Te``, load): a controller output beyond them is
        clipped, its range in the legend. The voltage panel shows
        ``||u_dq||`` and the range ``u_dc / sqrt(3)``, with the samples at the voltage limit shaded.
        A trace longer than the image is wide is drawn from the points that matter per pixel column
        (:func:`~pmsm2dof.ui.plots.canvas.decimate`: peaks kept).
    """
    t = result.t_s
    i_max = result.scenario.limits.i_max_A
    # fixed margins: a layout engine measures every text once more for each figure (half of savefig)
    fig = Figure(figsize=(8.0, 9.5))
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.055, top=0.95, hspace=0.1)
    FigureCanvasAgg(fig)
    ax_w, ax_i, ax_T, ax_u = fig.subplots(4, 1, sharex=True, height_ratios=(1.0, 1.0, 1.0, 0.7))
    fig.suptitle(result.scenario.name)

    ax_w.plot(t, result.speed_ref_rpm, "k--", lw=1.0, label="reference")
    two_mass = result.scenario.mechanics.model == "two_mass"
    ax_w.plot(t, result.speed_rpm, lw=1.4, label="motor speed" if two_mass else "speed")
    if two_mass:
        ax_w.plot(t, result.load_speed_rpm, lw=1.0, color="C2", label="load speed")
    ax_w.set_ylabel("speed [rpm]")

    ax_i.plot(t, result.iq_ref_A, "--", lw=1.0, color="C0", label="iq command")
    ax_i.plot(t, result.iq_A, lw=1.4, color="C0", label="iq")
    ax_i.plot(t, result.id_ref_A, "--", lw=1.0, color="C1", label="id command")
    ax_i.plot(t, result.id_A, lw=1.4, color="C1", label="id")
    for sign in (1, -1):
        ax_i.axhline(sign * i_max, color="grey", lw=0.8, ls=":")
    ax_i.set_ylabel("current [A]")

    (u_line,) = ax_T.plot(t, result.torque_unsat_Nm, ":", lw=1.0, color="C3", label="controller output u")
    ax_T.plot(t, result.torque_ref_Nm, "--", lw=1.0, color="C2", label="limited command u_sat")
    ax_T.plot(t, result.torque_Nm, lw=1.4, color="C0", label="electromagnetic Te")
    ax_T.plot(t, result.load_Nm, lw=1.4, color="C4", label="load")
    applied = [result.torque_ref_Nm, result.torque_Nm, result.load_Nm]
    if two_mass:
        ax_T.plot(t, result.shaft_torque_Nm, lw=1.0, color="C5", label="shaft")
        applied.append(result.shaft_torque_Nm)
    _clip_to_applied(ax_T, u_line, np.asarray(result.torque_unsat_Nm), applied)
    ax_T.set_ylabel("torque [Nm]")

    ax_u.plot(t, np.hypot(result.ud_V, result.uq_V), lw=1.4, color="C0", label="||u_dq||")
    ax_u.plot(t, result.u_dc_V / np.sqrt(3.0), ":", lw=1.0, color="grey", label="range u_dc/sqrt(3)")
    ax_u.set_ylabel("voltage [V]")
    ax_u.set_xlabel("time [s]")
    voltage_limited = at_voltage_limit(result) > 0.0
    pixel_s = (t[-1] - t[0]) / (fig.get_figwidth() * DPI)
    for a, b in saturated_intervals(t, voltage_limited, pixel_s):
        ax_u.axvspan(a, b, color="purple", alpha=0.15, lw=0)

    spans = saturated_intervals(t, at_current_limit(result), pixel_s)
    for ax in (ax_w, ax_i, ax_T, ax_u):
        for a, b in spans:
            ax.axvspan(a, b, color="orange", alpha=0.15, lw=0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    if spans:
        ax_w.axvspan(np.nan, np.nan, color="orange", alpha=0.15, label="current limit active")
        ax_w.legend(fontsize="small", loc="best")
    if np.any(voltage_limited):
        ax_u.axvspan(np.nan, np.nan, color="purple", alpha=0.15, label="voltage limit active")
        ax_u.legend(fontsize="small", loc="best")
    ax_u.set_xlim(t[0], t[-1])
    decimate_lines(fig)
    return fig


def _clip_to_applied(
    ax: Axes, u_line: Line2D, u: npt.NDArray[np.float64], applied: list[npt.NDArray[np.float64]]
) -> None:
    """Scale the torque panel to the torques the drive applies (limited command, Te, load), 10 % beyond.

    The controller output before the limit may be orders of magnitude larger (a windup, a gain
    designed for the wrong inertia): drawn to its own scale it would flatten ``Te`` and the load
    to a line. It is then clipped at the panel's edge, its range given in its legend entry.
    """
    values = np.concatenate([np.asarray(a, dtype=float) for a in applied])
    lo, hi = float(np.min(values)), float(np.max(values))
    pad = 0.1 * (hi - lo) if hi > lo else 0.1 * max(abs(hi), 1e-9)
    lo, hi = lo - pad, hi + pad
    if np.min(u) < lo or np.max(u) > hi:
        ax.set_ylim(lo, hi)
        u_line.set_label(f"controller output u (clipped; {np.min(u):.3g} to {np.max(u):.3g} Nm)")


def plot_trace(result: Result, path: Path | str) -> Path:
    """Draw :func:`trace_figure` of ``result`` into ``path`` (.png or .svg) atomically; return the path."""
    return save_figure(trace_figure(result), path)
