"""The simulations behind the paper reproduction: the paper's runs, sensitivity sweeps, discretization.

Everything runs on the shipped presets (:func:`pmsm2dof.sim.scenario.list_presets`), optionally all
changed by the same overrides, in the compiled engine, many at a time
(:func:`pmsm2dof.studies.engine.run_many`). The runs are those of :mod:`pmsm2dof.studies.paper_runs`:
the paper runs and the linear runs are kept whole (for the figures and the claims), of the sensitivity
sweeps only their metrics are kept.

Discretization study
    The discrete loops of :func:`pmsm2dof.analysis.discretize.discretize` (ZOH plant) for forward Euler,
    backward Euler and Tustin (Table 1) as the speed-loop sampling period grows, and engine runs
    of a small, unsaturated step at a few of those periods as a check of the design's prediction
    (:func:`~pmsm2dof.studies.paper_runs.discretization_runs`).
"""

import dataclasses
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..analysis.design import Design, design
from ..analysis.discretize import MAX_W_TS, SamplingWarning
from ..analysis.margins import Margins, loop_margins
from ..core import METHODS
from ..core.bindings import Method
from ..errors import ConfigError, SimulationError
from ..sim.scenario import Scenario, load_scenario
from ..sim.scenario_tables import SpeedControllerTable
from ..sim.simulate import Result
from .engine import Run, run_many
from .paper_runs import (
    FEEDFORWARD,
    POINTS,
    PRESETS,
    STEP_BASE,
    Series,
    Sweep,
    discretization_runs,
    linear_runs,
    paper_runs,
    sweeps,
)

#: Speed-loop sampling periods of the discretization study [s] (multiples of the 100 us current period).
TS_GRID_S = (1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)


@dataclasses.dataclass(frozen=True)
class DiscretePoint:
    """The discrete loop of one controller, method and sampling period (design level).

    ``stable`` False when :func:`~pmsm2dof.analysis.discretize.discretize` rejects the period (the
    discrete loop or the feedforward filter is unstable); the figures are then NaN and
    ``reason`` says why. ``controller_error`` is ``|F(z)/F(s) - 1|`` of the PI at the continuous
    gain crossover (z = exp(j w Ts)): how far the discrete controller is from the designed one.
    """

    controller: str
    method: Method
    Ts_s: float
    stable: bool
    overshoot_pct: float
    gain_margin_dB: float
    phase_margin_deg: float
    controller_error: float
    reason: str = ""


def discretization_points(
    base: Scenario, Ts_grid: Sequence[float] = TS_GRID_S, progress: bool = False
) -> tuple[list[DiscretePoint], dict[str, tuple[float, Margins, float]]]:
    """The discretization study on the design of scenario ``base`` (Table 1, eq 14, 15).

    Parameters
    ----------
    base : Scenario
        Its speed controller is designed (eq 9, 11) and discretized at each period.
    Ts_grid : sequence of float
        Speed-loop sampling periods [s], multiples of ``current_loop.Ts_s``.
    progress : bool
        Show a progress bar (tqdm) over the discrete designs.

    Returns
    -------
    (list of DiscretePoint, dict)
        The points, and the continuous reference: ``{controller: (overshoot_pct, Margins, w_gc)}``.
    """
    sc, cl = base.speed_controller, base.current_loop
    for Ts in Ts_grid:
        if not math.isclose(Ts / cl.Ts_s, round(Ts / cl.Ts_s), rel_tol=1e-9):
            raise ConfigError("Ts_s", Ts, f"a multiple of current_loop.Ts_s = {cl.Ts_s:g} s")
    designs: dict[str, Design] = {}
    continuous: dict[str, tuple[float, Margins, float]] = {}
    for label, ff in FEEDFORWARD.items():
        d = design(
            sc.J_kgm2,
            sc.alpha_radps,
            sc.zeta,
            m=sc.m,
            tau_i_s=sc.tau_i_s,
            feedforward=ff,
            anti_windup=sc.anti_windup,
            Ka=sc.Ka,
        )
        margins = loop_margins(d.L)
        designs[label] = d
        continuous[label] = (d.overshoot_pct(), margins, margins.w_gain_crossover_radps)
    cases = [(label, method, Ts) for label in FEEDFORWARD for method in METHODS for Ts in Ts_grid]
    if progress:
        from tqdm import tqdm

        cases = tqdm(cases, desc="discretization", unit="design")
    points: list[DiscretePoint] = []
    for label, method, Ts in cases:
        d, w_gc = designs[label], continuous[label][2]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SamplingWarning)
                dd = d.discretize(Ts, method)
        except ConfigError as exc:
            points.append(DiscretePoint(label, method, Ts, False, math.nan, math.nan, math.nan, math.nan, str(exc)))
            continue
        error = abs(complex(dd.F_z(np.exp(1j * w_gc * Ts))) / complex(d.F(1j * w_gc)) - 1.0)
        points.append(
            DiscretePoint(
                label, method, Ts, True, dd.overshoot_pct, dd.margins.gain_margin_dB, dd.margins.phase_margin_deg, error
            )
        )
    return points, continuous


def largest_fine_Ts(base: Scenario, Ts_grid: Sequence[float] = TS_GRID_S) -> float:
    """The largest period of ``Ts_grid`` that :mod:`pmsm2dof.analysis.discretize` deems fine for the design.

    That is ``max(alpha, alpha/(2 zeta), m alpha) Ts <= MAX_W_TS`` (beyond it discretize warns).
    """
    sc = base.speed_controller
    w = max(sc.alpha_radps, sc.alpha_radps / (2.0 * sc.zeta), sc.m * sc.alpha_radps)
    fine = [Ts for Ts in Ts_grid if w * Ts <= MAX_W_TS]
    return max(fine) if fine else min(Ts_grid)


@dataclasses.dataclass
class Studies:
    """Everything the reproduction simulated and computed.

    Attributes
    ----------
    bases : dict
        Preset name -> Scenario as run (with the common overrides).
    overrides : dict
        The common overrides applied to every preset.
    results : dict
        Run name -> Result of the paper runs (:func:`~pmsm2dof.studies.paper_runs.paper_runs`) and the linear
        runs (:func:`~pmsm2dof.studies.paper_runs.linear_runs`).
    metrics : dict
        Run name -> :func:`pmsm2dof.compute_metrics` of every run that completed.
    failures : dict
        Run name -> SimulationError message, for sweep and check runs that stopped.
    sweeps : list of Sweep
    discretization : list of DiscretePoint
    continuous : dict
        Controller label -> (overshoot_pct, Margins, gain crossover [rad/s]) of the continuous design.
    fine_Ts_s : float
        Largest period of the discretization grid that the design deems fine.
    n_runs : int
        Simulations run.
    wall_time_s : float
        Wall-clock time of all the runs and design computations [s].
    """

    bases: dict[str, Scenario]
    overrides: dict[str, Any]
    results: dict[str, Result]
    metrics: dict[str, dict[str, Any]]
    failures: dict[str, str]
    sweeps: list[Sweep]
    discretization: list[DiscretePoint]
    continuous: dict[str, tuple[float, Margins, float]]
    fine_Ts_s: float
    n_runs: int
    wall_time_s: float

    def speed_controller(self) -> SpeedControllerTable:
        """The ``speed_controller`` table of the sensitivity base, as run
        (:data:`~pmsm2dof.studies.paper_runs.STEP_BASE`)."""
        return self.bases[STEP_BASE].speed_controller

    def step(self, name: str, index: int = 0) -> dict[str, Any]:
        """Figures of reference step ``index`` of run ``name`` (see :mod:`pmsm2dof.sim.metrics`)."""
        figures: dict[str, Any] = self.metrics[name]["reference_steps"][index]
        return figures

    def load(self, name: str, index: int = 0) -> dict[str, Any]:
        """Figures of load step ``index`` of run ``name``."""
        figures: dict[str, Any] = self.metrics[name]["load_steps"][index]
        return figures

    def sweep(self, name: str) -> Sweep:
        """The sweep called ``name``."""
        return next(s for s in self.sweeps if s.name == name)

    def figure(self, run_name: str, kind: str, figure: str) -> float:
        """The value of ``figure`` of the step (kind ``"step"``) or load step (``"load"``) of a sweep run.

        NaN when the run stopped or the figure could not be computed (its reason is in
        :attr:`metrics` or :attr:`failures`).
        """
        if run_name not in self.metrics:
            return math.nan
        steps = self.metrics[run_name]["reference_steps" if kind == "step" else "load_steps"]
        step = steps[-1] if kind == "step" else steps[0]
        value = step[figure]["value"]
        return math.nan if value is None else value

    def series_values(self, series: Series, figure: str) -> npt.NDArray[np.float64]:
        """``figure`` along a series, as a float array (NaN where missing)."""
        return np.array([self.figure(r.name, series.kind, figure) for r in series.runs], dtype=float)


def run_studies(
    overrides: Mapping[str, Any] | None = None,
    points: int = POINTS,
    Ts_grid: Sequence[float] = TS_GRID_S,
    workers: int | None = None,
    progress: bool = False,
) -> Studies:
    """Run every simulation and design computation of the reproduction.

    Parameters
    ----------
    overrides : mapping, optional
        ``{"dotted.key": value}`` applied to every preset first (see
        :meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`), e.g. ``{"motor.J_kgm2": 0.5}``.
    points : int
        Values per sensitivity sweep (:data:`~pmsm2dof.studies.paper_runs.POINTS` in the full study).
    Ts_grid : sequence of float
        Speed-loop sampling periods of the discretization study [s] (:data:`TS_GRID_S`).
    workers : int, optional
        Local threads of the engine (:func:`pmsm2dof.studies.engine.run_many`; default: the
        cores available).
    progress : bool
        Show progress bars (tqdm, on stderr) over the list of runs and the discrete designs.

    Returns
    -------
    Studies

    Raises
    ------
    ConfigError
        An override or a derived run is invalid (naming the scenario key).
    SimulationError
        A run of the paper's conditions or a linear run stopped; stopped sweep and discretization
        runs are kept in ``failures``.
    """
    overrides = dict(overrides or {})
    start = time.perf_counter()
    bases = {name: load_scenario(name).with_overrides(overrides) for name in PRESETS}
    paper = paper_runs()
    study_sweeps = sweeps(bases, points)
    kept = paper + linear_runs()
    specs = kept + [r for s in study_sweeps for r in s.runs()] + discretization_runs()
    for spec in specs:  # every run valid before any runs
        bases[spec.preset].with_overrides(spec.overrides)
    keep = {spec.name for spec in kept}
    outcomes = run_many(
        bases,
        [Run(spec.name, spec.preset, spec.overrides, spec.name) for spec in specs],
        keep=keep,
        workers=workers,
        progress=progress,
        description="pmsm2dof reproduce",
    )

    results: dict[str, Result] = {}
    metrics: dict[str, dict[str, Any]] = {}
    failures: dict[str, str] = {}
    for outcome in outcomes:
        name = str(outcome.key)  # the runs are keyed by their names
        if outcome.metrics is None:
            if name in keep:
                raise SimulationError(outcome.error)
            failures[name] = outcome.error
            continue
        metrics[name] = outcome.metrics
        if name in keep and outcome.result is not None:  # a kept run that completed has its result
            results[name] = outcome.result

    discretization, continuous = discretization_points(bases[STEP_BASE], Ts_grid, progress=progress)
    return Studies(
        bases=bases,
        overrides=overrides,
        results=results,
        metrics=metrics,
        failures=failures,
        sweeps=study_sweeps,
        discretization=discretization,
        continuous=continuous,
        fine_Ts_s=largest_fine_Ts(bases[STEP_BASE], Ts_grid),
        n_runs=len(specs),
        wall_time_s=time.perf_counter() - start,
    )
