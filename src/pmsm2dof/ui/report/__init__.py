"""The paper reproduction: figures, the claims table and the report of ``pmsm2dof reproduce``.

:func:`reproduce` runs the studies of :mod:`pmsm2dof.studies.paper` (the paper's simulation and
experimental conditions, the sensitivity sweeps and the discretization study) and the fault
scenarios of :mod:`pmsm2dof.studies.faults`, checks every claim of the paper (sections 3, 4.1,
4.2 and 5) against what they measured (:mod:`.claims`), draws the figures (:mod:`.figures`)
and writes, all or nothing (:func:`pmsm2dof.outputs.staged_dir`), the report
(:mod:`.render`):

- ``figures/*.png`` and ``figures/*.svg``: Fig. 7 (Bode of Gx), Fig. 8 to 10 (simulation
  conditions 1 and 2), Fig. 12 to 14 (the experimental conditions, simulated), the sensitivity
  figures, the discretization study and the fault scenarios; beside each, ``figures/*.csv`` with
  the numbers it draws (:class:`~pmsm2dof.ui.report.figures.FigureData`);
- ``report.md`` and ``report.html`` (self-contained: the figures embedded as base64 PNG);
- ``claims.json``: one row per claim, with the paper's value, the measured one, a verdict
  (``reproduced``, ``partly``, ``not reproduced``) and the reason where they differ;
- with ``--link``, ``drive.json``: the experiments' runs on the drive, their figures and their
  agreement with the engine (:mod:`.drive`), and the claims of section 4.2 checked on them;
- ``metrics.json`` (figures of merit of the paper runs), ``sensitivity.csv`` and
  ``discretization.csv`` (the data of the study figures);
- a section on fault scenarios the paper does not treat (the ``fault-*`` presets: a stall, a
  DC-link sag, speed-sensor hold, zero and spike) run with each anti-windup mode;
- a section on self-commissioning (:mod:`.commissioning`): the C routine identifies the paper's
  drive and a salient servo, identified against true values and the time of each step;
- a section on the speed measurement (:mod:`pmsm2dof.studies.sensing`): encoder resolution,
  estimator, filter and delay against overshoot, load dip and margins, and whether a sensor
  chain explains the experiment's 35 % -> 15 % better than the exact reading;
- a section on gain scheduling by the inertia the online estimator identifies (J of the plant
  0.5 to 2 times the design's: fixed, adapted and matched designs, :mod:`.adaptation`);
- a section beyond the rigid load (:mod:`.twomass`): the paper's condition 2 on two-mass drive
  trains, with and without a notch, and the stable region of alpha;
- a section without an FPU (:mod:`.fixedpoint`): the paper's conditions with the speed controller
  in Q31 and Q15 against float32, and the Q15 dead zone of the paper's design at Ts = 1e-4 s.

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller" (equation, figure and section numbers are the paper's).
"""

import dataclasses
import io
import json
import sys
import time
from collections.abc import Iterable, Mapping
from importlib.metadata import version
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from ...outputs import atomic_write, check_out, staged_dir
from ...studies import paper as st
from ...studies import paper_runs as pr
from ...studies.adaptation import run_adaptation
from ...studies.claims import VERDICTS, Claim, compute_claims
from ...studies.faults import run_faults
from ...studies.fixedpoint import run_arithmetic
from ...studies.paper_drive import DriveStudies, check_link, run_on_drives
from ...studies.sensing import offset_study, sensor_study
from ...studies.twomass import paper_region_study
from .adaptation import CAPTION as ADAPTATION_CAPTION
from .adaptation import fig_adaptation
from .commissioning import run_commissioning
from .figures import FigureData, fig_faults, figures
from .fixedpoint import CAPTION as FIXED_POINT_CAPTION
from .fixedpoint import fig_fixed_point
from .render import csv_text, json_value, render_html, render_markdown, report_blocks, sensitivity_rows
from .twomass import fig_stable_region

__all__ = ["VERDICTS", "Claim", "Report", "compute_claims", "reproduce", "write_report"]


@dataclasses.dataclass(frozen=True)
class Report:
    """What :func:`reproduce` wrote.

    Attributes
    ----------
    out : pathlib.Path
        The output folder.
    claims : list of Claim
    studies : Studies
    files : list of str
        The files written, relative to ``out``.
    wall_time_s : float
        Wall-clock time of the whole reproduction [s].
    """

    out: Path
    claims: list[Claim]
    studies: st.Studies
    files: list[str]
    wall_time_s: float


def write_report(
    studies: st.Studies,
    out: Path | str,
    progress: bool = False,
    force: bool = False,
    drive: DriveStudies | None = None,
) -> tuple[list[Claim], list[str], float]:
    """Check the claims on ``studies`` and write the report into ``out``, all or nothing.

    Parameters
    ----------
    studies : Studies
        Of :func:`pmsm2dof.studies.paper.run_studies`.
    out : str or os.PathLike
        Output folder: new, empty, or holding only an earlier report, which is replaced
        (:func:`pmsm2dof.outputs.staged_dir`).
    progress : bool
        Show a progress bar over the figures.
    force : bool
        Write into ``out`` even if it holds other files (they are kept).
    drive : DriveStudies, optional
        The experiments played on a drive (:func:`pmsm2dof.studies.paper_drive.run_on_drives`): the
        claims are checked on them too, and ``drive.json`` holds their figures and their agreement
        with the engine.

    Returns
    -------
    (list of Claim, list of str, float)
        The claims, the files written (relative to ``out``) and the wall-clock time of the
        studies and the report [s].
    """
    start = time.perf_counter()
    claims = compute_claims(studies, drive)
    made = figures(studies)
    fault_runs = run_faults(studies.overrides)
    sensor_rows = sensor_study(studies.overrides)
    offset_rows = offset_study(studies.overrides)
    made["faults"] = (
        *fig_faults(fault_runs),
        "Fault scenarios: speed (left) and speed integrator (right) with each anti-windup mode; dotted: the reference.",
    )
    adaptation_runs = run_adaptation(studies.overrides)
    made["adaptation"] = (*fig_adaptation(adaptation_runs), ADAPTATION_CAPTION)
    two_mass = paper_region_study(studies.overrides)
    arithmetic = run_arithmetic(studies.overrides)
    made["fixed_point"] = (*fig_fixed_point(arithmetic), FIXED_POINT_CAPTION)
    made["two_mass_region"] = (
        *fig_stable_region(two_mass),
        "Largest alpha of a stable sampled loop on two-mass trains of the paper's inertia, against the shaft's "
        "resonance; dashed: with a notch at the resonance; dotted: the paper's alpha.",
    )
    files: list[str] = []
    with staged_dir(out, "reproduce", force) as tmp:
        images: dict[str, bytes] = {}
        items: Iterable[tuple[str, tuple[Figure, FigureData, str]]] = made.items()
        if progress:
            from tqdm import tqdm

            items = tqdm(items, desc="figures", unit="figure")
        for stem, (fig, data, _caption) in items:
            for fmt in ("png", "svg"):
                buf = io.BytesIO()
                fig.savefig(buf, format=fmt, dpi=110)
                atomic_write(tmp / "figures" / f"{stem}.{fmt}", buf.getvalue())
                files.append(f"figures/{stem}.{fmt}")
                if fmt == "png":
                    images[stem] = buf.getvalue()
            atomic_write(tmp / "figures" / f"{stem}.csv", data.to_csv())
            files.append(f"figures/{stem}.csv")
        captions = {stem: caption for stem, (_fig, _data, caption) in made.items()}
        claims_json = {
            "paper": "Wang, Lin, Yang, Fang, Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous Motor "
            "Speed Controller",
            "pmsm2dof_version": version("pmsm2dof"),
            "overrides": json_value(studies.overrides),
            "verdict_counts": {v: sum(c.verdict == v for c in claims) for v in VERDICTS},
            "claims": [json_value(_claim_json(c)) for c in claims],
        }
        atomic_write(tmp / "claims.json", json.dumps(claims_json, indent=2, allow_nan=False) + "\n")
        atomic_write(
            tmp / "metrics.json",
            json.dumps({name: studies.metrics[name] for name in studies.results}, indent=2, allow_nan=False) + "\n",
        )
        atomic_write(tmp / "sensitivity.csv", csv_text(sensitivity_rows(studies)))
        atomic_write(
            tmp / "discretization.csv", csv_text([json_value(dataclasses.asdict(p)) for p in studies.discretization])
        )
        if drive is not None:
            drive_json = {
                "link": drive.link,
                "runs": {
                    n: {
                        "metrics": drive.metrics[n],
                        "comparison": drive.comparisons[n],
                        "pre_roll_s": drive.pre_roll_s.get(n, 0.0),
                        "capture": drive.captures.get(n, ""),
                    }
                    for n in drive.results
                },
            }
            atomic_write(tmp / "drive.json", json.dumps(json_value(drive_json), indent=2, allow_nan=False) + "\n")
            files.append("drive.json")
        wall_time_s = studies.wall_time_s + time.perf_counter() - start
        blocks = report_blocks(
            studies,
            claims,
            captions,
            wall_time_s,
            fault_runs,
            commissioning_runs=run_commissioning(),
            sensor_rows=sensor_rows,
            offset_rows=offset_rows,
            adaptation_runs=adaptation_runs,
            two_mass=two_mass,
            arithmetic=arithmetic,
            drive=drive,
        )
        atomic_write(tmp / "report.md", render_markdown(blocks))
        atomic_write(tmp / "report.html", render_html(blocks, images))
        files += ["claims.json", "metrics.json", "sensitivity.csv", "discretization.csv", "report.md", "report.html"]
    return claims, files, studies.wall_time_s + time.perf_counter() - start


def _claim_json(claim: Claim) -> dict[str, Any]:
    """A claim as claims.json holds it: ``on_drive`` only where the claim was checked on a drive."""
    row = dataclasses.asdict(claim)
    if row["on_drive"] is None:
        del row["on_drive"]
    return row


def reproduce(
    out: Path | str = "pmsm2dof-report",
    overrides: Mapping[str, Any] | None = None,
    points: int = pr.POINTS,
    progress: bool = False,
    force: bool = False,
    link: str | None = None,
    a2l: Path | str | None = None,
    allow_remote: bool = False,
) -> Report:
    """Run the paper reproduction and write the report into ``out``, all or nothing.

    Parameters
    ----------
    out : str or os.PathLike
        Output folder: new, empty, or holding only an earlier report, which is replaced as a
        whole (:func:`pmsm2dof.outputs.staged_dir`).
    overrides : mapping, optional
        ``{"dotted.key": value}`` applied to every preset (see :func:`pmsm2dof.studies.paper.run_studies`).
    points : int
        Values per sensitivity sweep; the full study uses :data:`pmsm2dof.studies.paper_runs.POINTS`.
    progress : bool
        Show progress bars over the runs, the discrete designs and the figures.
    force : bool
        Write into ``out`` even if it holds other files (they are kept).
    link : str, optional
        Also play the experiments on drives (:func:`pmsm2dof.studies.paper_drive.run_on_drives`;
        ``"virtual"``: the PC's virtual drives, built here; or the link URL of one drive).
    a2l : path, optional
        The A2L file of the drive at a ``link`` URL.
    allow_remote : bool
        A ``tcp://`` link to another machine.

    Returns
    -------
    Report

    Raises
    ------
    ConfigError
        Invalid overrides or points (naming the parameter or scenario key), or ``out`` not a
        writable folder or holding other files (without ``force``).
    SimulationError
        A run of the paper's conditions stopped, or a run on a drive did not end as done (or was not steady
        after its pre-roll).
    ToolError
        The link to a drive dropped (its watchdog stops the run), or a drive's build failed.
    """
    check_out(out, "reproduce", force)
    if link is not None:
        check_link(link, a2l, allow_remote)
    studies = st.run_studies(overrides, points=points, progress=progress)
    drive = None
    if link is not None:
        say = (lambda text: print(f"  drive: {text}", file=sys.stderr, flush=True)) if progress else None
        drive = run_on_drives(studies.bases, link, report=say, a2l=a2l, allow_remote=allow_remote)
    claims, files, wall_time_s = write_report(studies, out, progress=progress, force=force, drive=drive)
    return Report(out=Path(out), claims=claims, studies=studies, files=files, wall_time_s=wall_time_s)
