"""The report's section on the experiments played on a drive (``pmsm2dof reproduce --link``).

:func:`drive_blocks` tabulates, for each run of experimental conditions 1 to 3 played on a drive
(:func:`pmsm2dof.studies.paper_drive.run_on_drives`), its figures of merit on the drive (of its
measured speed) beside the engine's, and how far the drive's speed reading and currents differ from
the engine's (the claims checked
on the drive, :attr:`pmsm2dof.studies.claims.Claim.on_drive`, are columns of the claims table).
"""

from collections.abc import Mapping
from typing import Any

from ...studies.paper_drive import VIRTUAL_LINK, DriveStudies

__all__ = ["drive_blocks"]


def _figure(metrics: Mapping[str, Any], kind: str, figure: str) -> str:
    steps = metrics[kind]
    if not steps or steps[0][figure]["value"] is None:
        return "n/a"
    return f"{steps[0][figure]['value']:.4g}"


def drive_blocks(drive: DriveStudies | None, engine_metrics: Mapping[str, Mapping[str, Any]]) -> list[tuple[Any, ...]]:
    """The report blocks of the section (none without a drive)."""
    if drive is None:
        return []
    where = (
        "the PC's virtual drives built for each experiment (the firmware example's foc.c and link.c with the C "
        "controllers, the engine's plant of the preset as the motor, its load played by the virtual board)"
        if drive.link == VIRTUAL_LINK
        else f"the drive at {drive.link} (one drive whose motor, limits and loop periods are the paper's; condition "
        "3's load applied by its bench)"
    )
    header = (
        "run",
        "overshoot on the drive [%]",
        "overshoot simulated [%]",
        "load dip on the drive [rpm]",
        "load dip simulated [rpm]",
        "pre-roll [s]",
        "speed: drive - engine, of the step",
        "currents: drive - engine, of the step",
    )
    rows = []
    for name, metrics in drive.metrics.items():
        c = drive.comparisons[name]
        rows.append(
            (
                name,
                _figure(metrics, "reference_steps", "overshoot_pct"),
                _figure(engine_metrics[name], "reference_steps", "overshoot_pct"),
                _figure(metrics, "load_steps", "speed_dip_rpm"),
                _figure(engine_metrics[name], "load_steps", "speed_dip_rpm"),
                f"{drive.pre_roll_s.get(name, 0.0):g}",
                f"{c['speed']['relative_to_step']:.2g}",
                f"{c['currents']['relative_to_step']:.2g}",
            )
        )
    return [
        ("h2", "The experiments on a drive"),
        (
            "p",
            f"`pmsm2dof reproduce --link {drive.link}` played the runs of experimental conditions 1 to 3 on "
            f"{where}, over XCP: for each run the speed controller was written to the drive and read back, the "
            "reference (and on a virtual drive the load) schedule played, and the firmware's own signals captured "
            "at every speed sample (its speed reading, references, dq currents); the claims of section 4.2 are "
            "checked on those runs, of the drive's measured speed, by the same rules "
            f"({drive.wall_time_s:.1f} s for the builds and the runs); the claims table's last columns hold them. "
            "A run that starts at speed (condition 3) on a drive that starts its runs at rest begins with a "
            "pre-roll from rest to that speed, held until the drive is steady; its recorded part follows.",
        ),
        ("table", header, rows),
    ]
