"""The paper's experimental conditions 1 to 3 (section 4.2) played on a drive, beside their simulation.

:func:`run_on_drives` plays the runs of the experiments that the claims of section 4.2 measure
(:data:`DRIVE_RUNS`) on drives and returns their measured runs in the engine's log format, with
the same figures of merit the simulated runs have (:func:`pmsm2dof.sim.metrics.compute_metrics` of
the drive's speed reading), so that the claims can be checked on what the drive did
(:func:`pmsm2dof.studies.claims.compute_claims`). Each run is captured from the firmware's own
signals (:func:`pmsm2dof.studies.drive.capture_run`), so any drive with the firmware's variables
plays them. Between the runs only the speed controller changes: it is written over XCP
(:func:`pmsm2dof.studies.bench.write_speed_controller`) and held against the run's scenario before
the run (:func:`pmsm2dof.studies.drive.check_drive_runs`).

Two kinds of drive:

- :data:`VIRTUAL_LINK`: the PC's virtual drive of each experiment, a build of its preset
  (:func:`pmsm2dof.studies.firmware.serve_scenario`; the firmware's foc.c and link.c with the C
  controllers, the engine's plant of the preset as the motor, its load played by the virtual
  board), run as fast as the link allows. Each run must agree with the engine's simulation
  (:func:`pmsm2dof.studies.firmware.compare`).
- a link URL and its A2L file: the one drive there plays the three conditions. Its controllers'
  motor, limits and loop periods must be the paper's (:func:`check_paper_drive`). Experimental
  condition 3 starts at a steady 500 rpm: on a drive that starts its runs at rest the run begins
  with a pre-roll (:func:`pre_roll`) that ramps the reference to the condition's initial speed and
  holds it until the engine's twin has settled; the drive's own speed must then be steady (within
  :data:`STEADY_SHARE` of that speed over the last :data:`STEADY_WINDOW_PER_ALPHA` / alpha) or the
  run is refused; the recorded part is the rest, its time from 0. Condition 3's load is what the
  bench applies (a virtual drive's board plays the scenario's).
"""

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..drive.link import Link
from ..drive.session import link_errors, open_link
from ..drive.transport import link_url
from ..errors import ConfigError, SimulationError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario
from ..sim.simulate import Result, Simulation
from .bench import DRIVE_FIELDS, speed_config, write_speed_controller
from .drive import (
    WALL_S_PER_DRIVE_S,
    DriveRun,
    capture_run,
    check_drive_runs,
    plan_run,
    run_on_drive,
    sample_times,
)
from .firmware import serve_scenario
from .paper_runs import RunSpec, paper_runs

#: The link of ``reproduce --link``: the PC's virtual drive of each experiment, built here.
VIRTUAL_LINK = "virtual"
#: The runs of experimental conditions 1 to 3 whose figures the claims of section 4.2 use.
DRIVE_RUNS = ("e1-1dof-none", "e1-1dof-back_calculation", "e2-1dof", "e2-2dof", "e3-1dof", "e3-2dof")
#: The virtual drives' link watchdog [ms of the drive's time]: the host polls far more often.
TIMEOUT_MS = 2000
#: The pre-roll's acceleration, a share of the acceleration at the current limit (1.5 p psi_f i_max / J).
PRE_ROLL_ACCELERATION_SHARE = 0.5
#: Steady: the speed within this share of the initial speed...
STEADY_SHARE = 1e-3
#: ... over this many times 1 / alpha of the speed controller (the time constant of its slowest mode, 2 / alpha
#: for zeta < 1, eq 8: the window spans one) [-].
STEADY_WINDOW_PER_ALPHA = 2.0
#: Longest pre-roll [s of the drive's time].
PRE_ROLL_MAX_S = 120.0


@dataclasses.dataclass(frozen=True, eq=False)
class DriveStudies:
    """The experimental runs played on drives.

    Attributes
    ----------
    link : str
        Where they ran (:data:`VIRTUAL_LINK`, or the drive's link URL).
    results : dict
        Run name -> the drive's trace (:class:`pmsm2dof.sim.simulate.Result`).
    metrics : dict
        Run name -> :func:`pmsm2dof.sim.metrics.compute_metrics` of the drive's trace.
    comparisons : dict
        Run name -> :func:`pmsm2dof.studies.firmware.compare` of the drive's trace with the engine's.
    wall_time_s : float
        Wall-clock time of the builds and the runs [s].
    pre_roll_s : dict
        Run name -> the pre-roll before its recorded part [s] (0: none).
    captures : dict
        Run name -> how it was captured (:attr:`pmsm2dof.studies.drive.RunPlan.why`).
    """

    link: str
    results: dict[str, Result]
    metrics: dict[str, dict[str, Any]]
    comparisons: dict[str, dict[str, Any]]
    wall_time_s: float
    pre_roll_s: dict[str, float] = dataclasses.field(default_factory=dict)
    captures: dict[str, str] = dataclasses.field(default_factory=dict)


def check_link(link: str, a2l: Path | str | None = None, allow_remote: bool = False) -> None:
    """Raise ConfigError unless :func:`run_on_drives` plays on ``link``: :data:`VIRTUAL_LINK`, or a URL with an A2L."""
    if link == VIRTUAL_LINK:
        if a2l is not None:
            raise ConfigError("a2l", str(a2l), f"none with the link '{VIRTUAL_LINK}' (its drives are built here)")
        return
    link_url(link, allow_remote)
    if a2l is None:
        raise ConfigError("a2l", "<missing>", f"the A2L file of the drive at {link} (its firmware's build writes it)")


def check_paper_drive(link: Link, base: Scenario) -> None:
    """Raise ConfigError unless the drive's controllers hold the paper's motor, limits and loop periods.

    The fields of :data:`pmsm2dof.studies.bench.DRIVE_FIELDS` of ``link_speed_config`` against those of a
    build of ``base`` (an experiment's preset, :func:`pmsm2dof.studies.bench.speed_config`), in float32:
    the claims of section 4.2 are about that drive. The first that differs is named.
    """
    paper = speed_config(base)
    with link_errors(link, "reading the drive's configuration"):
        for f in DRIVE_FIELDS:
            drive = link.read(f"link_speed_config.{f}")
            if np.float32(drive) != np.float32(paper[f]):
                raise ConfigError(
                    f"link_speed_config.{f}",
                    drive,
                    f"{paper[f]!r}, the paper's drive of section 4.2 (the experiments' presets): the claims are "
                    "about that motor and its limits, so another drive's runs are refused",
                )


def pre_roll(scenario: Scenario) -> tuple[Scenario, int]:
    """``scenario`` as a run from rest on a drive: a pre-roll to its initial speed, then its schedules; its samples.

    For ``simulation.speed0_rpm`` w0 = 0 the scenario itself and 0. Else the reference ramps from
    0 to w0 at :data:`PRE_ROLL_ACCELERATION_SHARE` of the acceleration at the current limit and
    holds it; the pre-roll lasts until the engine's twin of it (no load) has its speed within
    :data:`STEADY_SHARE` of w0 for good, plus :data:`STEADY_WINDOW_PER_ALPHA` / alpha, in whole speed
    samples n_pre. The scenario's reference and load follow, shifted by n_pre Ts_speed. Returns the
    run's scenario (at rest at t = 0) and n_pre.

    Raises
    ------
    ConfigError
        A pre-roll longer than :data:`PRE_ROLL_MAX_S`.
    """
    w0_rpm = scenario.simulation.speed0_rpm
    if w0_rpm == 0.0:
        return scenario, 0
    m, sc, Ts_s = scenario.motor, scenario.speed_controller, scenario.speed_controller.Ts_s
    a_radps2 = PRE_ROLL_ACCELERATION_SHARE * 1.5 * m.pole_pairs * m.psi_f_Wb * scenario.limits.i_max_A / sc.J_kgm2
    t_ramp_s = abs(w0_rpm) * math.pi / 30.0 / a_radps2
    window_s = STEADY_WINDOW_PER_ALPHA / sc.alpha_radps
    twin = scenario.with_overrides(
        {
            "simulation.speed0_rpm": 0.0,
            "reference": [{"t_s": 0.0, "speed_rpm": w0_rpm, "ramp_s": t_ramp_s}],
            "load": [],
            "simulation.t_end_s": PRE_ROLL_MAX_S,
            "simulation.log_every": 1,
        }
    )
    sim = Simulation(twin)
    sim.advance(sim.n_samples)
    r = sim.result(twin, 0.0)
    away = np.flatnonzero(np.abs(r.speed_meas_rpm - w0_rpm) > STEADY_SHARE * abs(w0_rpm))
    settled_s = float(r.t_s[away[-1] + 1]) if len(away) and away[-1] + 1 < len(r.t_s) else math.inf
    if not settled_s + window_s <= PRE_ROLL_MAX_S:
        raise ConfigError(
            "simulation.speed0_rpm",
            w0_rpm,
            f"an initial speed the drive settles at within {PRE_ROLL_MAX_S:g} s of a pre-roll from rest (the engine's "
            f"twin is not within {STEADY_SHARE:g} of it for good by then)",
        )
    n_pre = math.ceil((settled_s + window_s) / Ts_s - 1e-9)
    t_pre_s = n_pre * Ts_s
    played = scenario.with_overrides(
        {
            "simulation.speed0_rpm": 0.0,
            "reference": [
                {"t_s": 0.0, "speed_rpm": w0_rpm, "ramp_s": t_ramp_s},
                *({"t_s": e.t_s + t_pre_s, "speed_rpm": e.speed_rpm, "ramp_s": e.ramp_s} for e in scenario.reference),
            ],
            "load": [{"t_s": e.t_s + t_pre_s, "torque_Nm": e.torque_Nm, "ramp_s": e.ramp_s} for e in scenario.load],
            "simulation.t_end_s": t_pre_s + scenario.simulation.t_end_s,
        }
    )
    return played, n_pre


def run_pre_rolled(link: Link, scenario: Scenario) -> tuple[DriveRun, float]:
    """Play ``scenario`` on a drive that starts at rest: its :func:`pre_roll`, then the recorded part.

    Returns the recorded part (from the end of the pre-roll, its time from 0, as a run of
    ``scenario`` beside the engine's simulation of ``scenario``) and the pre-roll's length [s].

    Raises
    ------
    SimulationError
        The drive's speed reading was not steady at the end of the pre-roll (within
        :data:`STEADY_SHARE` of the initial speed over the last :data:`STEADY_WINDOW_PER_ALPHA` / alpha).
    """
    played, n_pre = pre_roll(scenario)
    check_drive_runs(link, played)
    Ts_s = scenario.speed_controller.Ts_s
    n_rec = math.floor(scenario.simulation.t_end_s / Ts_s + 1e-9) + 1
    with link_errors(link, "the run"):
        plan = plan_run(link, n_pre + n_rec)
        start = time.perf_counter()
        measured = capture_run(link, played, plan, timeout_s=60.0 + WALL_S_PER_DRIVE_S * played.simulation.t_end_s)
        wall_s = time.perf_counter() - start
    w0_rpm = scenario.simulation.speed0_rpm
    if n_pre:
        window = max(1, math.ceil(STEADY_WINDOW_PER_ALPHA / scenario.speed_controller.alpha_radps / Ts_s))
        off = float(np.max(np.abs(measured.speed_rpm[max(0, n_pre - window) : n_pre] - w0_rpm)))
        if off > STEADY_SHARE * abs(w0_rpm):
            raise SimulationError(
                f"the drive at {link.url} was not steady at {w0_rpm:g} rpm after a pre-roll of {n_pre * Ts_s:g} s: its "
                f"speed was up to {off:.3g} rpm away over the last {min(window, n_pre) * Ts_s:g} s (at most "
                f"{STEADY_SHARE * abs(w0_rpm):.3g}): the recorded part would not start from the condition"
            )
    part = {name: getattr(measured, name)[n_pre:] for name in Result.signals if name != "t_s"}
    sim = Simulation(scenario)
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, 0.0)
    drive = Result(scenario=scenario, wall_time_s=wall_s, t_s=sample_times(scenario, n_rec), **part)
    return DriveRun(scenario=scenario, drive=drive, engine=engine, url=link.url, plan=plan), n_pre * Ts_s


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
    *,
    a2l: Path | str | None = None,
    allow_remote: bool = False,
) -> DriveStudies:
    """Play ``runs`` (names of :func:`pmsm2dof.studies.paper_runs.paper_runs`) on drives (module docstring).

    Parameters
    ----------
    bases : mapping
        Preset name -> scenario as the studies run it (:attr:`pmsm2dof.studies.paper.Studies.bases`).
    link : str
        :data:`VIRTUAL_LINK`: the PC's virtual drive of each preset, built and served here; or the
        link URL of one drive (:func:`pmsm2dof.drive.transport.link_url`), with ``a2l``.
    runs : tuple of str
        The runs to play (default :data:`DRIVE_RUNS`).
    report : callable, optional
        Called with a line per run played (progress).
    a2l : path, optional
        The A2L file of the drive at ``link`` (not with :data:`VIRTUAL_LINK`).
    allow_remote : bool
        A ``tcp://`` link to another machine (:func:`pmsm2dof.drive.transport.link_url`).

    Raises
    ------
    ConfigError
        A link or A2L file it cannot play on, an unknown run, or a drive whose motor, limits or loop
        periods are not the paper's (naming the field, :func:`check_paper_drive`).
    SimulationError
        A run did not end as done, lost a sample, was tripped by the link watchdog, was not steady
        after its pre-roll, or (on a virtual drive) differs from the engine's.
    ToolError
        The link dropped (the drive's watchdog stops the run), or a build failed.
    """
    check_link(link, a2l, allow_remote)
    known = {spec.name: spec for spec in paper_runs()}
    for name in runs:
        if name not in known:
            raise ConfigError("runs", name, "runs of the paper's conditions: " + ", ".join(DRIVE_RUNS))
    start = time.perf_counter()
    by_preset: dict[str, list[RunSpec]] = {}
    for name in runs:
        by_preset.setdefault(known[name].preset, []).append(known[name])
    out = DriveStudies(link=link, results={}, metrics={}, comparisons={}, wall_time_s=0.0)
    if link == VIRTUAL_LINK:
        for preset, specs in by_preset.items():
            with _virtual_drive(bases[preset]) as drive:
                for spec in specs:
                    _play(drive, bases[preset].with_overrides(spec.overrides), spec.name, out, report, agree=True)
    else:
        assert a2l is not None
        with open_link(link, a2l, allow_remote=allow_remote) as drive:
            for preset in by_preset:
                check_paper_drive(drive, bases[preset])
            for preset, specs in by_preset.items():
                for spec in specs:
                    _play(drive, bases[preset].with_overrides(spec.overrides), spec.name, out, report, agree=False)
    return dataclasses.replace(out, wall_time_s=time.perf_counter() - start)


def _play(
    drive: Link,
    scenario: Scenario,
    name: str,
    out: DriveStudies,
    report: Callable[[str], None] | None,
    *,
    agree: bool,
) -> None:
    """Play one run on ``drive`` into ``out``; ``agree``: it must agree with the engine (a virtual drive)."""
    with link_errors(drive, f"writing the speed controller of run {name}"):
        write_speed_controller(drive, scenario)
    if scenario.simulation.speed0_rpm == 0.0 or agree:
        played, pre_s = run_on_drive(drive, scenario), 0.0
    else:
        played, pre_s = run_pre_rolled(drive, scenario)
    comparison = played.comparison()
    if agree and not comparison["agrees"]:
        raise SimulationError(
            f"run {name} on the drive at {drive.url}: its speed or currents differ from the "
            f"engine's by more than {comparison['agreement']:g} of their step (speed "
            f"{comparison['speed']['relative_to_step']:.3g}, currents "
            f"{comparison['currents']['relative_to_step']:.3g}): the drive is not the preset's build"
        )
    out.results[name] = played.drive
    out.metrics[name] = compute_metrics(played.drive)
    out.comparisons[name] = comparison
    out.pre_roll_s[name] = pre_s
    out.captures[name] = played.plan.why
    if report is not None:
        pre = f" after a pre-roll of {pre_s:g} s" if pre_s else ""
        report(
            f"{name}: {played.drive.t_s[-1]:g} s on the drive{pre}, {played.plan.why}; speed within "
            f"{comparison['speed']['relative_to_step']:.2g} of the step of the engine's"
        )
