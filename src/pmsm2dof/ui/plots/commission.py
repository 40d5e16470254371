"""The plot of a commissioning run: currents, voltages and speeds against time, one band per step.

From the log of a :class:`~pmsm2dof.sim.commission.Commissioning`: the currents and the voltage
command in the routine's frame, the frame's and the rotor's electrical speed, and the rotor's
angle off the frame; each step of the routine (probe, align, rs_low ... ramp_down) is a band
named at its start, so that a failure shows where it happened.
"""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...sim.commission import PHASES, Commissioning
from .canvas import save_figure

__all__ = ["commission_figure", "plot_commission"]


def commission_figure(result: Commissioning) -> Figure:
    """A four-panel figure of the run (on the Agg canvas)."""
    log = result.log
    t = log["t_s"]
    fig = Figure(figsize=(10, 9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(4, 1, sharex=True)
    axes[0].plot(t, log["id_A"], label="id")
    axes[0].plot(t, log["iq_A"], label="iq")
    axes[0].set_ylabel("current [A]")
    axes[1].plot(t, log["ud_V"], label="ud")
    axes[1].plot(t, log["uq_V"], label="uq")
    axes[1].set_ylabel("voltage command [V]")
    axes[2].plot(t, log["w_e_frame_radps"], label="frame")
    axes[2].plot(t, log["w_e_radps"], "--", label="rotor")
    axes[2].set_ylabel("electrical speed [rad/s]")
    axes[3].plot(t, np.degrees(log["theta_err_rad"]), label="rotor - frame")
    axes[3].set_ylabel("angle [deg]")
    axes[3].set_xlabel("time [s]")
    phase = log["phase"].astype(int)
    starts = np.flatnonzero(np.diff(phase, prepend=-1))
    for n, k in enumerate(starts):
        end = t[starts[n + 1]] if n + 1 < len(starts) else t[-1]
        for ax in axes:
            if n % 2 == 0:
                ax.axvspan(t[k], end, color="0.92", lw=0)
        axes[0].annotate(
            PHASES[phase[k]], (t[k], 1.0), xycoords=("data", "axes fraction"), fontsize=7, rotation=90, va="top"
        )
    for ax in axes:
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(True, lw=0.3)
    title = f"{result.scenario}: commissioning {result.phase}"
    if result.phase != "done":
        title += f" (failed in {result.failed_phase}: {result.reason})"
    fig.suptitle(title)
    return fig


def plot_commission(result: Commissioning, path: str | Path) -> Path:
    """Draw :func:`commission_figure` into ``path`` (.png or .svg), atomically."""
    return save_figure(commission_figure(result), path)
