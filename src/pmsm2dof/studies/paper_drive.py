"""The paper's experimental conditions 1 to 3 (section 4.2) played on a drive, beside their simulation.

:func:`run_on_drives` plays the runs of the experiments that the claims of section 4.2 measure
(:data:`DRIVE_RUNS`) on drives and returns their traces in the engine's log format, with the same
figures of merit the simulated runs have (:func:`pmsm2dof.sim.metrics.compute_metrics`), so that
the claims can be checked on what the drive did (:func:`pmsm2dof.studies.claims.compute_claims`).

The drives are the PC's virtual drives (:data:`VIRTUAL_LINK`): for each experiment, a build of its
preset (:func:`pmsm2dof.studies.firmware.serve_scenario`; the firmware's foc.c and link.c with the
C controllers, the engine's plant of the preset as the motor, its load played by the virtual
board), run as fast as the link allows. Between the runs of one experiment only the speed
controller changes: it is written over XCP (:func:`pmsm2dof.studies.bench.write_speed_controller`)
and held against the run's scenario before the run (:func:`pmsm2dof.studies.drive.check_drive_runs`).
Each run is also simulated by the engine, and how far the two differ is kept
(:func:`pmsm2dof.studies.firmware.compare`).
"""

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from ..drive.link import Link
from ..drive.session import link_errors, open_link
from ..errors import ConfigError, SimulationError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario
from ..sim.simulate import Result
from .bench import write_speed_controller
from .drive import run_on_drive
from .firmware import serve_scenario
from .paper_runs import RunSpec, paper_runs

#: The link of ``reproduce --link``: the PC's virtual drive of each experiment, built here.
VIRTUAL_LINK = "virtual"
#: The runs of experimental conditions 1 to 3 whose figures the claims of section 4.2 use.
DRIVE_RUNS = ("e1-1dof-none", "e1-1dof-back_calculation", "e2-1dof", "e2-2dof", "e3-1dof", "e3-2dof")
#: The virtual drives' link watchdog [ms of the drive's time]: the host polls far more often.
TIMEOUT_MS = 2000


@dataclasses.dataclass(frozen=True, eq=False)
class DriveStudies:
    """The experimental runs played on drives.

    Attributes
    ----------
    link : str
        Where they ran (:data:`VIRTUAL_LINK`).
    results : dict
        Run name -> the drive's trace (:class:`pmsm2dof.sim.simulate.Result`).
    metrics : dict
        Run name -> :func:`pmsm2dof.sim.metrics.compute_metrics` of the drive's trace.
    comparisons : dict
        Run name -> :func:`pmsm2dof.studies.firmware.compare` of the drive's trace with the engine's.
    wall_time_s : float
        Wall-clock time of the builds and the runs [s].
    """

    link: str
    results: dict[str, Result]
    metrics: dict[str, dict[str, Any]]
    comparisons: dict[str, dict[str, Any]]
    wall_time_s: float


def check_link(link: str) -> None:
    """Raise ConfigError unless ``link`` is one :func:`run_on_drives` plays on."""
    if link != VIRTUAL_LINK:
        raise ConfigError(
            "link",
            link,
            f"'{VIRTUAL_LINK}': the PC's virtual drive of each experiment, built here (a drive's run is "
            "held against the engine, so each experiment needs a build of its preset)",
        )


@contextlib.contextmanager
def _virtual_drive(scenario: Scenario) -> Iterator[Link]:
    with serve_scenario(scenario, realtime=False, timeout_ms=TIMEOUT_MS) as (url, folder):
        with open_link(url, folder / "virtual_drive_host.a2l") as link:
            yield link


def run_on_drives(
    bases: Mapping[str, Scenario],
    link: str = VIRTUAL_LINK,
    runs: tuple[str, ...] = DRIVE_RUNS,
    report: Callable[[str], None] | None = None,
) -> DriveStudies:
    """Play ``runs`` (names of :func:`pmsm2dof.studies.paper_runs.paper_runs`) on drives of their presets.

    Parameters
    ----------
    bases : mapping
        Preset name -> scenario as the studies run it (:attr:`pmsm2dof.studies.paper.Studies.bases`).
    link : str
        :data:`VIRTUAL_LINK`: the PC's virtual drive of each preset, built and served here.
    runs : tuple of str
        The runs to play (default :data:`DRIVE_RUNS`).
    report : callable, optional
        Called with a line per run played (progress).

    Raises
    ------
    ConfigError
        Another link than :data:`VIRTUAL_LINK`, or an unknown run.
    SimulationError
        A run did not end as done, lost a sample, or was tripped by the link watchdog.
    ToolError
        The link dropped (the drive's watchdog stops the run), or a build failed.
    """
    check_link(link)
    known = {spec.name: spec for spec in paper_runs()}
    for name in runs:
        if name not in known:
            raise ConfigError("runs", name, "runs of the paper's conditions: " + ", ".join(DRIVE_RUNS))
    start = time.perf_counter()
    by_preset: dict[str, list[RunSpec]] = {}
    for name in runs:
        by_preset.setdefault(known[name].preset, []).append(known[name])
    results: dict[str, Result] = {}
    metrics: dict[str, dict[str, Any]] = {}
    comparisons: dict[str, dict[str, Any]] = {}
    for preset, specs in by_preset.items():
        with _virtual_drive(bases[preset]) as drive:
            for spec in specs:
                scenario = bases[preset].with_overrides(spec.overrides)
                with link_errors(drive, f"writing the speed controller of run {spec.name}"):
                    write_speed_controller(drive, scenario)
                played = run_on_drive(drive, scenario)
                comparison = played.comparison()
                if not comparison["agrees"]:
                    raise SimulationError(
                        f"run {spec.name} on the drive at {drive.url}: its speed or currents differ from the "
                        f"engine's by more than {comparison['agreement']:g} of their step (speed "
                        f"{comparison['speed']['relative_to_step']:.3g}, currents "
                        f"{comparison['currents']['relative_to_step']:.3g}): the drive is not the preset's build"
                    )
                results[spec.name] = played.drive
                metrics[spec.name] = compute_metrics(played.drive)
                comparisons[spec.name] = comparison
                if report is not None:
                    report(
                        f"{spec.name}: {played.drive.t_s[-1]:g} s on the drive, speed within "
                        f"{comparison['speed']['relative_to_step']:.2g} of the step of the engine's"
                    )
    return DriveStudies(
        link=link, results=results, metrics=metrics, comparisons=comparisons, wall_time_s=time.perf_counter() - start
    )
