"""The figures of a measured log: the identification's fit (rows, residual) and the comparison with a simulation."""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...sim.logs import Log
from ...sim.simulate import Result
from ...studies.electrical import Electrical
from ...studies.identify import Mechanics
from .design import save_figure


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

    Top: ud, middle: uq (measured and the model with the parameters found), bottom: residuals [V].
    """
    fig = Figure(figsize=(9, 7), layout="constrained")
    FigureCanvasAgg(fig)
    ax_d, ax_q, ax_e = fig.subplots(3, 1, sharex=True)
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
