"""The firmware's run on the emulated MCU, or a run played over the link, over the engine's simulation of the same
scenario.

From a :class:`~pmsm2dof.studies.firmware.FirmwareRun` or a :class:`~pmsm2dof.studies.drive.DriveRun`: the
speed and the dq currents of the firmware's trace (foc.c on the virtual board, QEMU) drawn over the engine's, and
their differences, firmware minus engine, on a scale of their own (they are float32 roundings, far below the signals).
"""

from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...sim.simulate import Result
from ...studies.drive import DriveRun
from ...studies.firmware import FirmwareRun
from .canvas import save_figure


def firmware_figure(run: FirmwareRun) -> Figure:
    """Three panels: speed [rpm], dq currents [A], and the differences firmware - engine."""
    return _traces_figure(
        f"{run.scenario.name}: firmware on QEMU (mps2-an386) over the engine", run.firmware, run.engine
    )


def _traces_figure(title: str, fw: Result, eng: Result) -> Figure:
    t = fw.t_s
    fig = Figure(figsize=(8.0, 8.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_w, ax_i, ax_d = fig.subplots(3, 1, sharex=True)
    fig.suptitle(title)
    ax_w.plot(t, eng.speed_ref_rpm, "k--", lw=1.0, label="reference")
    ax_w.plot(t, eng.speed_rpm, lw=3.0, color="0.75", label="engine")
    ax_w.plot(t, fw.speed_rpm, lw=1.0, color="C0", label="firmware")
    ax_w.set_ylabel("speed [rpm]")
    for name, color in (("iq_A", "C0"), ("id_A", "C1")):
        ax_i.plot(t, getattr(eng, name), lw=3.0, color="0.75")
        ax_i.plot(t, getattr(fw, name), lw=1.0, color=color, label=f"{name.split('_')[0]} firmware (grey: engine)")
    ax_i.set_ylabel("current [A]")
    ax_d.plot(t, fw.speed_rpm - eng.speed_rpm, lw=1.0, color="C0", label="speed [rpm]")
    ax_d.plot(t, fw.iq_A - eng.iq_A, lw=1.0, color="C2", label="iq [A]")
    ax_d.plot(t, fw.id_A - eng.id_A, lw=1.0, color="C1", label="id [A]")
    ax_d.set_ylabel("firmware - engine")
    ax_d.set_xlabel("time [s]")
    for ax in (ax_w, ax_i, ax_d):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    return fig


def plot_firmware(run: FirmwareRun, path: Path | str) -> None:
    """Save :func:`firmware_figure` of ``run`` to ``path`` (.png or .svg), whole or not at all."""
    save_figure(firmware_figure(run), path)


def plot_drive_run(run: DriveRun, path: Path | str) -> None:
    """Save the drive's trace over the engine's (the panels of :func:`firmware_figure`) to ``path``."""
    save_figure(_traces_figure(f"{run.scenario.name}: the drive at {run.url} over the engine", run.drive, run.engine),
                path)  # fmt: skip
