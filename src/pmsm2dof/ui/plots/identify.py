"""The figures of a measured log: the identification's fit (rows, residual) and the comparison with a simulation."""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...sim.logs import Log
from ...sim.simulate import Result
from ...studies.electrical import Electrical
from ...studies.identify import Mechanics
from .canvas import save_figure


def plot_fit(mech: Mechanics, path: Path) -> None:
    """Draw the rows of :func:`~pmsm2dof.studies.identify.identify_mechanics` against time to ``path``.

    Top: the mean torque of each row (``y``, the torque integral over the row) and the model's
    ``J x_J + B x_B + Tc x_C``; rows excluded as outliers marked. Bottom: the residual [Nm].
    """
    fig = Figure(figsize=(9, 6), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True)
    rows = mech.rows
    t, y, fit, kept = rows["t_s"], rows["y"], rows["fit"], rows["kept"]
    top.plot(t, y, ".", ms=3, label="mean torque of the row (log)")
    top.plot(t, fit, "-", lw=1, label="J dw/dt + B w + Tc sign(w) (fit)")
    top.plot(t[~kept], y[~kept], "x", color="tab:red", label="excluded (outlier)")
    top.set_ylabel("torque [Nm]")
    top.set_title(
        f"J = {mech.J_kgm2:.5g} kg m^2, B = {mech.B_Nms:.4g} Nm s/rad, Tc = {mech.T_coulomb_Nm:.4g} Nm "
        f"({mech.n_rows} rows of {mech.window_s:.3g} s)"
    )
    top.legend(loc="best", fontsize="small")
    bottom.plot(t[kept], (y - fit)[kept], ".", ms=3)
    bottom.plot(t[~kept], (y - fit)[~kept], "x", color="tab:red")
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_ylabel("residual [Nm]")
    bottom.set_xlabel("time [s]")
    lim = 4 * float(np.std((y - fit)[kept])) or 1.0
    bottom.set_ylim(-lim, lim)
    save_figure(fig, path)


def plot_electrical_fit(fit: Electrical, path: Path) -> None:
    """Draw the window-mean voltages of :func:`~pmsm2dof.studies.electrical.identify_electrical`, log vs eq 1.

    Left: ud, uq (measured and the model with the parameters found) and the residuals [V]. With a fit per
    current range, right: Ld and Lq of each range with their 95 % intervals against ``|i_dq|`` [A].
    """
    fig = Figure(figsize=(13 if fit.ranges else 9, 7), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 2 if fit.ranges else 1, width_ratios=[2, 1] if fit.ranges else [1])
    ax_d = fig.add_subplot(grid[0, 0])
    ax_q = fig.add_subplot(grid[1, 0], sharex=ax_d)
    ax_e = fig.add_subplot(grid[2, 0], sharex=ax_d)
    rows = fit.rows
    t = rows["t_s"]
    for ax, axis in ((ax_d, "d"), (ax_q, "q")):
        ax.plot(t, rows[f"u{axis}_V"], ".", ms=3, label=f"u{axis} window mean (log)")
        ax.plot(t, rows[f"u{axis}_fit_V"], "-", lw=1, label=f"u{axis} of eq 1 (fit)")
        ax.set_ylabel(f"u{axis} [V]")
        ax.legend(loc="best", fontsize="small")
        ax_e.plot(t, rows[f"u{axis}_V"] - rows[f"u{axis}_fit_V"], ".", ms=3, label=f"u{axis}")
    ax_d.set_title(
        f"Rs = {fit.Rs_ohm:.4g} ohm, Ld = {fit.Ld_H:.4g} H, Lq = {fit.Lq_H:.4g} H, psi_f = {fit.psi_f_Wb:.4g} Wb "
        f"({fit.n_windows} windows)"
    )
    ax_e.axhline(0.0, color="k", lw=0.5)
    ax_e.set_ylabel("residual [V]")
    ax_e.set_xlabel("time [s]")
    ax_e.legend(loc="best", fontsize="small")
    if fit.ranges:
        ax_l = fig.add_subplot(grid[:, 1])
        for name, axis, whole in (("Ld_H", "Ld", fit.Ld_H), ("Lq_H", "Lq", fit.Lq_H)):
            found = [r for r in fit.ranges if getattr(r, name) is not None]
            mid = np.array([0.5 * (r.i_low_A + r.i_high_A) for r in found])
            value = np.array([getattr(r, name) for r in found]) * 1e3
            lo = value - np.array([r.ci[name][0] for r in found]) * 1e3
            hi = np.array([r.ci[name][1] for r in found]) * 1e3 - value
            width = np.array([[0.5 * (r.i_high_A - r.i_low_A)] * 2 for r in found]).T.reshape(2, -1)
            line = ax_l.errorbar(mid, value, xerr=width, yerr=[lo, hi], fmt="o", capsize=3, label=f"{axis} per range")
            ax_l.axhline(whole * 1e3, color=line[0].get_color(), ls=":", lw=1, label=f"{axis} whole log")
        ax_l.set_xlabel("window-mean |i_dq| [A]")
        ax_l.set_ylabel("inductance [mH]")
        ax_l.set_title("per current range (95 % intervals)")
        ax_l.legend(loc="best", fontsize="small")
        ax_l.grid(True, alpha=0.3)
    save_figure(fig, path)


def plot_compare(log: Log, result: Result, path: Path) -> None:
    """Overlay a measured log and the simulation of the same reference: speed, iq and the speed error."""
    fig = Figure(figsize=(9, 7), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True)
    axes[0].plot(log.t_s, log.speed_rpm, lw=1.2, label=f"log ({Path(log.source).name})")
    axes[0].plot(result.t_s, result.speed_rpm, lw=1.0, ls="--", label=f"simulation ({result.scenario.name})")
    if log.speed_ref_rpm is not None:
        axes[0].plot(log.t_s, log.speed_ref_rpm, color="k", lw=0.8, ls=":", label="reference (log)")
    axes[0].set_ylabel("speed [rpm]")
    axes[0].legend(loc="best", fontsize="small")
    if log.iq_A is not None:
        axes[1].plot(log.t_s, log.iq_A, lw=1.2, label="log")
    axes[1].plot(result.t_s, result.iq_A, lw=1.0, ls="--", label="simulation")
    axes[1].set_ylabel("iq [A]")
    error = log.speed_rpm - np.interp(log.t_s, result.t_s, result.speed_rpm)
    axes[2].plot(log.t_s, error, lw=1.0)
    axes[2].set_ylabel("log - simulation [rpm]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    save_figure(fig, path)
