"""Autotuning: the anti-windup 2DOF design that rejects loads best within a specification.

:func:`autotune` searches the speed-controller keys of a scenario (``alpha_radps``, ``zeta``,
``m``, ``Ka``, and the ``feedforward`` and ``anti_windup`` forms the :class:`Spec` allows) for
the smallest worst-case integral of the absolute speed error per Nm of load (IAE) on the
scenario's own load steps, such that every constraint of the :class:`Spec` holds at every
inertia of the range ``J_range`` (the ratio of the true inertia to the design inertia). The IAE
holds the depth of the dip and the time the speed takes to recover: the dip alone rewards a
large ``Kp`` and leaves the integral action free, so that zeta would run to the top of its range
with a slow recovery (for a response that does not overshoot, the IAE is ``dT / Ki``, with
``Ki = J (alpha / (2 zeta))^2`` of eq 9). ``max_recovery_s`` bounds the recovery itself.

1. linear constraints first: the gain and phase margins of the C controller's discrete loop on
   the true plant at each inertia ratio (:func:`pmsm2dof.analysis.sampled_loop.margins_on_plants`,
   eq 2, 3, 9, 14); a candidate that is unstable or misses a margin anywhere is not simulated;
2. then the saturated ones: the candidates left are simulated (the scenario's speed and load
   steps, with the current limit where the scenario drives the drive to it) at the ends and the
   geometric middle of the range, in batches on threads or the workers of a Dask cluster
   (:func:`pmsm2dof.studies.engine.run_many`): first at the largest inertia, where the worst
   cases mostly lie, and at the two others only while the candidate could still be the best
   one; its figures at the ratios simulated bound those over all three (a worst case only
   grows), so that the search takes the steps it would take with every candidate simulated
   everywhere, and chooses the same design (``"partial"`` evaluations: the others);
3. for each zeta, the margins give the edge: the largest ``alpha`` whose loop meets them at
   every inertia ratio (bisection; at most the stability bound ``alpha < 4 zeta^2 / tau_i`` of
   eq 8 and the sampling bound of :data:`~pmsm2dof.analysis.discretize.MAX_W_TS`); the search
   runs in the coordinates (zeta, alpha as a fraction of the edge, ``Ka Kp``, m): a coarse grid
   first, then a pattern search around the best point with shrinking steps, which follows the
   edge where it bends;
4. the best design is simulated again at :data:`N_J_CHECK` inertia ratios spread over the range;
   one that fails there is rejected and the next best checked.

A candidate whose current command chatters in a simulation (``chatter_share`` above
:data:`pmsm2dof.sim.metrics.CHATTER_SHARE_MAX`: a limit cycle, whatever its figures) is rejected.
When the chosen design lies on a bound of the search (:data:`ZETA_RANGE`, :data:`KA_KP_RANGE`,
:data:`M_RANGE`, or the stability and sampling bound of alpha), :attr:`AutotuneResult.on_bounds`
says so: the best design may lie beyond it. The scenario's own design is checked as
``pmsm2dof design`` checks it (:func:`pmsm2dof.studies.loopcheck.sampled_loop`), and a warning
given when its sampled loop is unstable.

When no candidate meets the specification the result says so (``feasible`` False): the design
returned is the one that misses it least, and :attr:`AutotuneResult.binding` names the
constraint it misses most and by how much.

The worst-case figures are those of :func:`pmsm2dof.sim.metrics.compute_metrics` (rpm), taken
over the reference steps (overshoot, settling time, tracking IAE), the load steps (speed dip
and IAE divided by the load change, recovery time) and both (longest time at the current limit
in one step window), and the run (chatter).
"""

import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..analysis.design import design as make_design
from ..analysis.discretize import MAX_W_TS
from ..analysis.margins import Margins
from ..analysis.sampled_loop import c_coefficients, margins_on_plants
from ..core import ANTI_WINDUPS, FEEDFORWARDS
from ..core.bindings import AntiWindup, Feedforward
from ..errors import ConfigError
from ..sim.metrics import CHATTER_SHARE_MAX
from ..sim.scenario import Scenario
from .engine import Outcome, Run, check_options, connect, run_many
from .loopcheck import sampled_loop

#: Inertia ratios at which the margins are checked, and the best design is simulated again.
N_J_CHECK = 9
#: Relative damping of the coarse grid (eq 9).
ZETA_GRID = (0.3, 0.45, 0.67, 1.0, 1.4, 2.0)
#: Bandwidths of the coarse grid as fractions of the edge (the largest alpha the margins allow).
ALPHA_FRACTIONS = (1.0, 0.7, 0.4, 0.15)
#: Decades below the stability and sampling bound where the edge is sought (and the grid's
#: bandwidths lie when no bandwidth meets the margins: then log-spaced, :data:`N_ALPHA`).
ALPHA_DECADES = 2.5
N_ALPHA = 7
#: Bisection steps of the edge (a precision of ``ALPHA_DECADES / 2**EDGE_STEPS`` decades).
EDGE_STEPS = 10
#: Factor by which the edge steps down where it misses a margin between the ends of the range.
EDGE_BACKOFF = 0.97
#: First step of the pattern search (a factor on zeta, the fraction of the edge, Ka Kp and m).
STEP_FIRST = 1.25
#: Back-calculation gain of the coarse grid, ``Ka Kp`` (1 is the paper's Ka = 1/Kp, section 3.3).
KA_KP_GRID = (0.5, 1.0, 2.0, 4.0)
#: Tracking pole factors of the coarse grid for the feedforwards of eq 11 (``no_tau``, ``full``).
M_GRID = (0.5, 1.0, 2.0)
#: Bounds of the search: zeta, ``Ka Kp`` and m (alpha: :meth:`_Search.alpha_max_radps`).
ZETA_RANGE = (0.3, 2.0)
KA_KP_RANGE = (0.1, 10.0)
M_RANGE = (0.25, 4.0)
#: Most rounds of the pattern search around the best point, and its smallest step (a factor).
REFINE_ROUNDS = 12
REFINE_STEP_MIN = 1.01
#: Most "partial" candidates :meth:`_Search.best` simulates at the other inertia ratios at a time, those of
#: best bound first: enough for the engine's threads, few enough that the best of them raises the bar
#: for the rest.
COMPLETE_BATCH = 4
#: Largest number of best designs simulated again over the inertia range.
CHECK_MAX = 20
#: Widest inertia range, hi / lo.
J_RANGE_SPAN_MAX = 100.0

#: Constraints: Spec field -> (worst-case figure, "max" or "min", unit).
CONSTRAINTS = {
    "max_overshoot_pct": ("overshoot_pct", "max", "%"),
    "min_phase_margin_deg": ("phase_margin_deg", "min", "deg"),
    "min_gain_margin_dB": ("gain_margin_dB", "min", "dB"),
    "max_settling_s": ("settling_time_s", "max", "s"),
    "max_load_dip_rpm_per_Nm": ("load_dip_rpm_per_Nm", "max", "rpm/Nm"),
    "max_recovery_s": ("load_recovery_s", "max", "s"),
    "max_current_limit_time_s": ("current_limit_time_s", "max", "s"),
}
#: Worst-case figures of a design over the inertia range; "min" ones are worst at their smallest.
FIGURES = {
    "phase_margin_deg": "min",
    "gain_margin_dB": "min",
    "overshoot_pct": "max",
    "settling_time_s": "max",
    "load_dip_rpm_per_Nm": "max",
    "load_iae_rpm_s_per_Nm": "max",
    "load_recovery_s": "max",
    "current_limit_time_s": "max",
    "tracking_iae_rpm_s": "max",
    "chatter_share": "max",
}
#: The figure the search minimises (worst case over the inertia range).
OBJECTIVE = "load_iae_rpm_s_per_Nm"
MARGIN_FIGURES = ("phase_margin_deg", "gain_margin_dB")


@dataclasses.dataclass(frozen=True)
class Spec:
    """What the autotuned design must meet, at every inertia of ``J_range``.

    Every field is optional; a constraint that is None is not checked. The margins default to
    the classical 45 deg and 6 dB, because the objective alone drives the bandwidth to the
    edge of stability (set them to 0 to leave them out).

    Attributes
    ----------
    max_overshoot_pct : float, optional
        Largest overshoot of any reference step [%], >= 0.
    min_phase_margin_deg : float, optional
        Smallest phase margin of the discrete loop [deg], in [0, 180).
    min_gain_margin_dB : float, optional
        Smallest gain margin of the discrete loop [dB], >= 0.
    max_settling_s : float, optional
        Longest settling time (2 % band) of any reference step [s], > 0.
    max_load_dip_rpm_per_Nm : float, optional
        Largest speed dip of any load step per Nm of load change [rpm/Nm], > 0.
    max_recovery_s : float, optional
        Longest recovery time (2 % of the dip) of any load step [s], > 0.
    max_current_limit_time_s : float, optional
        Longest time at the current limit within one step window [s], >= 0.
    J_range : (float, float)
        Ratio of the true inertia to the design inertia ``speed_controller.J_kgm2``, (lo, hi)
        with ``0 < lo <= hi`` and ``hi / lo <=`` :data:`J_RANGE_SPAN_MAX`; default (1, 1).
    feedforwards : tuple of str, optional
        The feedforward forms the search may choose (:data:`FEEDFORWARDS`); default the
        scenario's own.
    anti_windups : tuple of str, optional
        The anti-windup modes the search may choose (:data:`ANTI_WINDUPS`); default the
        scenario's own.

    Raises
    ------
    ConfigError
        Naming the field, its value and the valid range.
    """

    max_overshoot_pct: float | None = None
    min_phase_margin_deg: float | None = 45.0
    min_gain_margin_dB: float | None = 6.0
    max_settling_s: float | None = None
    max_load_dip_rpm_per_Nm: float | None = None
    max_recovery_s: float | None = None
    max_current_limit_time_s: float | None = None
    J_range: tuple[float, float] = (1.0, 1.0)
    feedforwards: tuple[Feedforward, ...] | None = None
    anti_windups: tuple[AntiWindup, ...] | None = None

    def __post_init__(self) -> None:
        bounds: dict[str, tuple[str, Callable[[float], bool]]] = {
            "max_overshoot_pct": ("a finite number >= 0", lambda v: v >= 0.0),
            "min_phase_margin_deg": ("a finite number >= 0 and < 180", lambda v: 0.0 <= v < 180.0),
            "min_gain_margin_dB": ("a finite number >= 0", lambda v: v >= 0.0),
            "max_settling_s": ("a finite number > 0", lambda v: v > 0.0),
            "max_load_dip_rpm_per_Nm": ("a finite number > 0", lambda v: v > 0.0),
            "max_recovery_s": ("a finite number > 0", lambda v: v > 0.0),
            "max_current_limit_time_s": ("a finite number >= 0", lambda v: v >= 0.0),
        }
        for name, (valid, ok) in bounds.items():
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(name, value, valid + " or None (not checked)")
            if not ok(value):
                raise ConfigError(name, value, valid + " or None (not checked)")
            object.__setattr__(self, name, float(value))
        valid_range = f"(lo, hi) with 0 < lo <= hi and hi / lo <= {J_RANGE_SPAN_MAX:g}, finite"
        J_range = self.J_range
        if (
            not isinstance(J_range, (tuple, list))
            or len(J_range) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in J_range)
        ):
            raise ConfigError("J_range", J_range, valid_range)
        lo, hi = float(J_range[0]), float(J_range[1])
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi and hi <= J_RANGE_SPAN_MAX * lo):
            raise ConfigError("J_range", J_range, valid_range)
        object.__setattr__(self, "J_range", (lo, hi))
        for name, choices in (("feedforwards", FEEDFORWARDS), ("anti_windups", ANTI_WINDUPS)):
            value = getattr(self, name)
            if value is None:
                continue
            valid = "a non-empty list of " + ", ".join(repr(c) for c in choices) + ", or None (the scenario's own)"
            if isinstance(value, str) or not isinstance(value, (tuple, list)) or not value:
                raise ConfigError(name, value, valid)
            for item in value:
                if item not in choices:
                    raise ConfigError(name, value, valid)
            object.__setattr__(self, name, tuple(dict.fromkeys(value)))

    def constraints(self) -> dict[str, float]:
        """The constraints that are checked: ``{Spec field: limit}``."""
        return {name: getattr(self, name) for name in CONSTRAINTS if getattr(self, name) is not None}

    def as_dict(self) -> dict[str, Any]:
        """The specification as JSON-ready data."""
        data = dataclasses.asdict(self)
        data["J_range"] = list(self.J_range)
        for name in ("feedforwards", "anti_windups"):
            data[name] = None if data[name] is None else list(data[name])
        return data


@dataclasses.dataclass(frozen=True, order=True)
class Candidate:
    """One speed-controller design: the scenario's ``speed_controller`` keys of the search.

    Attributes
    ----------
    alpha_radps : float
        Bandwidth of the P loop [rad/s] (eq 9).
    zeta : float
        Relative damping of the PI loop [-] (eq 9).
    m : float
        Tracking pole factor [-] (eq 10); 1 with the ``lowpass`` and ``none`` feedforwards.
    Ka : float
        Back-calculation gain [(rad/s)/Nm] (Fig. 5); without effect unless ``back_calculation``.
    feedforward : str
        One of :data:`FEEDFORWARDS`.
    anti_windup : str
        One of :data:`ANTI_WINDUPS`.
    """

    alpha_radps: float
    zeta: float
    m: float
    Ka: float
    feedforward: Feedforward
    anti_windup: AntiWindup

    def speed_controller(self) -> dict[str, float | str]:
        """``{key: value}`` of the scenario's ``speed_controller`` table."""
        return dataclasses.asdict(self)

    def overrides(self) -> dict[str, float | str]:
        """``{"speed_controller.KEY": value}`` (:meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`)."""
        return {f"speed_controller.{key}": value for key, value in self.speed_controller().items()}


@dataclasses.dataclass(frozen=True)
class Violation:
    """A constraint a candidate misses.

    Attributes
    ----------
    constraint : str
        The :class:`Spec` field.
    limit : float
        Its value in the specification.
    value : float
        The candidate's worst case over the inertia ratios checked (``inf``: never settled).
    miss : float
        How far it misses, in the constraint's unit (> 0).
    J_ratio : float
        The inertia ratio of that worst case.
    """

    constraint: str
    limit: float
    value: float
    miss: float
    J_ratio: float

    def normalized(self) -> float:
        """The miss relative to the limit (to the unit for a zero limit); ``inf`` for a step never settled."""
        return self.miss / (abs(self.limit) if self.limit != 0.0 else 1.0)

    def describe(self) -> str:
        """One line: the constraint, the worst case, the limit and the miss."""
        figure, sense, unit = CONSTRAINTS[self.constraint]
        return (
            f"{self.constraint} = {self.limit:g} {unit}: worst {figure} {self.value:.4g} {unit} at J ratio "
            f"{self.J_ratio:.4g}, misses by {self.miss:.4g} {unit}"
        )


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """What the search knows of one candidate.

    Attributes
    ----------
    candidate : Candidate
    stage : str
        ``"margins"``: rejected by the analytic margins, never simulated; ``"engine"``: simulated at
        every inertia ratio of the search (or rejected for good: a simulation stopped, or the
        current command chattered); ``"partial"``: simulated at some of them only, where it
        already misses a constraint or ranks below the chosen design (:meth:`_Search.best`), so
        that the others were not needed.
    worst : dict
        Worst case of each figure of :data:`FIGURES` known at this stage, over the inertia ratios
        checked (the margins at all :data:`N_J_CHECK`, the simulated ones at those simulated).
    worst_J_ratio : dict
        The inertia ratio of each worst case.
    J_ratios_simulated : tuple of float
        The inertia ratios it was simulated at.
    violations : tuple of Violation
        The constraints it misses.
    error : str
        Why it could not be evaluated (unstable loop, a controller the C code refuses, a
        simulation that stopped); empty otherwise.
    """

    candidate: Candidate
    stage: str
    worst: dict[str, float]
    worst_J_ratio: dict[str, float]
    J_ratios_simulated: tuple[float, ...]
    violations: tuple[Violation, ...]
    error: str

    @property
    def feasible(self) -> bool:
        """Simulated over the search's inertia ratios and meeting every constraint."""
        return self.stage == "engine" and not self.error and not self.violations

    @property
    def may_be_feasible(self) -> bool:
        """Feasible, or simulated at some ratios only and meeting every constraint there."""
        return self.stage in ("engine", "partial") and not self.error and not self.violations

    def total_miss(self) -> tuple[float, float]:
        """How far it misses the specification: (the number of infinite misses, the sum of the finite
        normalized ones, :meth:`Violation.normalized`); ``(inf, inf)`` when it could not be evaluated."""
        if self.error:
            return (math.inf, math.inf)
        misses = [v.normalized() for v in self.violations]
        return (float(sum(math.isinf(x) for x in misses)), sum(x for x in misses if math.isfinite(x)))


@dataclasses.dataclass(frozen=True)
class RunRecord:
    """One simulation of the search.

    Attributes
    ----------
    candidate : Candidate
    J_ratio : float
        True over design inertia of the run.
    figures : dict
        The figures of :data:`FIGURES` but the margins, for this run; empty when it stopped.
    error : str
        The SimulationError that stopped it; empty when it completed.
    wall_time_s : float or None
        Wall time of the simulation [s].
    """

    candidate: Candidate
    J_ratio: float
    figures: dict[str, float]
    error: str
    wall_time_s: float | None


@dataclasses.dataclass(frozen=True)
class AutotuneResult:
    """The outcome of :func:`autotune`.

    Attributes
    ----------
    scenario : Scenario
        The scenario tuned (its speed and load steps, its design inertia).
    spec : Spec
    feasible : bool
        True when the chosen design meets the whole specification over the inertia range.
    chosen : Evaluation
        The best design: the smallest worst case of :data:`OBJECTIVE` among the feasible ones; when
        none is feasible, the one with the smallest :meth:`Evaluation.total_miss`.
    binding : Violation or None
        When no design is feasible: the constraint the chosen design misses most (normalized).
    evaluations : tuple of Evaluation
        Every candidate of the search, in the order they were generated.
    pareto : tuple of Evaluation
        The feasible candidates (all simulated ones when none is) no other one beats on tracking
        (worst ``tracking_iae_rpm_s``), rejection (worst :data:`OBJECTIVE`) and robustness
        (worst ``phase_margin_deg``): :func:`pareto_front`.
    runs : tuple of RunRecord
        Every simulation, in the order they ran.
    J_ratios_checked : tuple of float
        The inertia ratios of the margins and of the final check of the chosen design.
    wall_time_s : float
        Wall time of the search [s].
    on_bounds : tuple of str
        One sentence per bound of the search the chosen design lies on (:func:`bounds_reached`).
    scenario_loop : dict
        :func:`pmsm2dof.studies.loopcheck.sampled_loop` of the scenario's own design.
    """

    scenario: Scenario
    spec: Spec
    feasible: bool
    chosen: Evaluation
    binding: Violation | None
    evaluations: tuple[Evaluation, ...]
    pareto: tuple[Evaluation, ...]
    runs: tuple[RunRecord, ...]
    J_ratios_checked: tuple[float, ...]
    wall_time_s: float
    on_bounds: tuple[str, ...] = ()
    scenario_loop: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def speed_controller(self) -> dict[str, float | str]:
        """The chosen ``speed_controller`` keys: ``--set speed_controller.KEY=VALUE`` reproduces it."""
        return self.chosen.candidate.speed_controller()

    @property
    def rejected(self) -> tuple[Evaluation, ...]:
        """The candidates that miss a constraint, could not be evaluated, or rank below the chosen design at
        the inertia ratios they were simulated at (``"partial"``)."""
        return tuple(e for e in self.evaluations if not e.feasible)

    def tuned_scenario(self) -> Scenario:
        """The scenario with the chosen design."""
        return self.scenario.with_overrides(self.chosen.candidate.overrides())

    def write_c_header(self, path: Any, prefix: str = "p2d_config") -> Any:
        """Write the C configuration of the tuned scenario; return the path.

        See :func:`pmsm2dof.studies.configuration.configuration` (the header every command writes).
        """
        from .configuration import configuration

        return configuration(self.tuned_scenario(), source="pmsm2dof autotune").write_header(path, prefix)

    def pareto_rows(self) -> list[dict[str, Any]]:
        """One row per design of the Pareto front: its keys, worst-case figures and whether it is feasible."""
        return [_keys_and_worst(e) | {"feasible": e.feasible} for e in self.pareto]

    def runs_rows(self) -> list[dict[str, Any]]:
        """One row per simulation: the candidate's keys, the inertia ratio, its figures or the error."""
        return [
            r.candidate.speed_controller()
            | {"J_ratio": r.J_ratio}
            | {name: r.figures.get(name) for name in FIGURES if name not in MARGIN_FIGURES}
            | {"error": r.error, "wall_time_s": r.wall_time_s}
            for r in self.runs
        ]

    def rejected_rows(self) -> list[dict[str, Any]]:
        """One row per constraint a candidate misses (or per candidate that could not be evaluated)."""
        rows: list[dict[str, Any]] = []
        blank = {"constraint": "", "limit": None, "value": None, "miss": None, "J_ratio": None}
        for e in self.rejected:
            keys: dict[str, Any] = e.candidate.speed_controller() | {"stage": e.stage}
            if e.error:
                rows.append(keys | blank | {"error": e.error})
            elif not e.violations:
                ratios = ", ".join(f"{r:.4g}" for r in e.J_ratios_simulated)
                below = f"its {OBJECTIVE} at J ratio {ratios} already ranks it below the chosen design"
                rows.append(keys | blank | {"error": below})
            rows += [keys | dataclasses.asdict(v) | {"error": ""} for v in e.violations]
        return rows

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the chosen keys, worst case, binding constraint, Pareto front and counts."""
        simulated = [e for e in self.evaluations if e.stage == "engine"]
        return {
            "scenario": self.scenario.name,
            "feasible": self.feasible,
            "speed_controller": self.speed_controller,
            "worst_case": _finite(self.chosen.worst),
            "worst_J_ratio": dict(self.chosen.worst_J_ratio),
            "violations": [dataclasses.asdict(v) | {"value": _number(v.value)} for v in self.chosen.violations],
            "binding": None
            if self.binding is None
            else dataclasses.asdict(self.binding) | {"value": _number(self.binding.value)},
            "spec": self.spec.as_dict(),
            "J_ratios_checked": list(self.J_ratios_checked),
            "J_ratios_simulated": list(self.chosen.J_ratios_simulated),
            "counts": {
                "candidates": len(self.evaluations),
                "rejected_by_margins": sum(e.stage == "margins" for e in self.evaluations),
                "simulated": len(simulated),
                "simulated_in_part": sum(e.stage == "partial" for e in self.evaluations),
                "feasible": sum(e.feasible for e in self.evaluations),
                "runs": len(self.runs),
            },
            "pareto": [_keys_and_worst(e) | {"feasible": e.feasible} for e in self.pareto],
            "objective": OBJECTIVE,
            "on_bounds": list(self.on_bounds),
            "scenario_sampled_loop": self.scenario_loop,
            "wall_time_s": self.wall_time_s,
        }


def _keys_and_worst(e: Evaluation) -> dict[str, Any]:
    return e.candidate.speed_controller() | {f"worst_{name}": v for name, v in _finite(e.worst).items()}


def _number(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _finite(figures: Mapping[str, float]) -> dict[str, float | None]:
    """Figures as JSON numbers: infinite ones (a margin without crossing, a step never settled) are None."""
    return {name: _number(v) for name, v in figures.items()}


def _sig(x: float) -> float:
    """``x`` to 4 significant digits, so that the chosen keys read and reproduce exactly."""
    return float(f"{x:.4g}")


def _sig_down(x: float) -> float:
    """``x > 0`` rounded down to 4 significant digits (a bandwidth at the edge stays inside it)."""
    unit = 10.0 ** (math.floor(math.log10(x)) - 3)
    return float(f"{math.floor(x / unit * (1.0 + 1e-12)) * unit:.4g}")


def step_figures(metrics: Mapping[str, Any]) -> dict[str, float]:
    """The figures of one simulated run that the specification bounds and the search minimises.

    From :func:`pmsm2dof.sim.metrics.compute_metrics`: over the reference steps that change the
    reference, the largest ``overshoot_pct`` (0 when the speed has not reached the reference in
    the window: no overshoot), the longest ``settling_time_s`` (``inf`` when it does not settle
    in the window) and the sum of their ``iae_rpm_s`` (``tracking_iae_rpm_s``); over the load
    steps that change the load, the largest ``speed_dip_rpm`` and ``iae_rpm_s`` divided by the
    change (``load_dip_rpm_per_Nm``, ``load_iae_rpm_s_per_Nm``) and the longest
    ``recovery_time_s`` (``load_recovery_s``), each ``inf`` when it is missing (the speed did not
    recover in the window, or was still following a reference step when the load stepped); over
    both, the longest ``current_limit_time_s``; the run's ``chatter_share`` (``inf`` when the log
    cannot tell it).
    """
    figures = {
        "overshoot_pct": 0.0,
        "settling_time_s": 0.0,
        "load_dip_rpm_per_Nm": 0.0,
        "load_iae_rpm_s_per_Nm": 0.0,
        "load_recovery_s": 0.0,
        "current_limit_time_s": 0.0,
        "tracking_iae_rpm_s": 0.0,
    }
    for step in itertools.chain(metrics["reference_steps"], metrics["load_steps"]):
        limited = step["current_limit_time_s"]["value"]
        figures["current_limit_time_s"] = max(figures["current_limit_time_s"], limited or 0.0)
    for step in metrics["reference_steps"]:
        change = step["to_rpm"] - step["from_rpm"]
        at_step = step.get("speed_at_step_rpm")
        if change == 0.0 or at_step is None or abs(step["to_rpm"] - at_step) <= 1e-3 * abs(change):
            continue
        overshoot, settling = step["overshoot_pct"]["value"], step["settling_time_s"]["value"]
        figures["overshoot_pct"] = max(figures["overshoot_pct"], overshoot or 0.0)
        figures["settling_time_s"] = max(figures["settling_time_s"], math.inf if settling is None else settling)
        figures["tracking_iae_rpm_s"] += step["iae_rpm_s"]["value"]
    for step in metrics["load_steps"]:
        change = abs(step["to_Nm"] - step["from_Nm"])
        if change == 0.0:
            continue
        for name, key, per_Nm in (
            ("load_dip_rpm_per_Nm", "speed_dip_rpm", True),
            ("load_iae_rpm_s_per_Nm", "iae_rpm_s", True),
            ("load_recovery_s", "recovery_time_s", False),
        ):
            value = step[key]["value"]
            value = math.inf if value is None else (value / change if per_Nm else value)
            figures[name] = max(figures[name], value)
    chatter = metrics["run"]["chatter_share"]["value"]
    figures["chatter_share"] = math.inf if chatter is None else chatter
    return figures


def J_ratios(J_range: tuple[float, float], n: int) -> tuple[float, ...]:
    """``n`` inertia ratios log-spaced over ``J_range``, both ends included (one for a point range)."""
    lo, hi = J_range
    if lo == hi:
        return (lo,)
    return tuple(float(r) for r in np.geomspace(lo, hi, n))


def runs_bound(scenario: Scenario, spec: Spec) -> int:
    """The most simulations :func:`autotune` can make for ``scenario`` and ``spec``: a bound on its work.

    The coarse grid, :data:`REFINE_ROUNDS` rounds of at most 81 neighbours, each at the 3 inertia
    ratios of the search, and at most :data:`CHECK_MAX` final checks at :data:`N_J_CHECK` ratios.
    """
    sc = scenario.speed_controller
    forms = list(itertools.product(spec.feedforwards or (sc.feedforward,), spec.anti_windups or (sc.anti_windup,)))
    grid = 0
    neighbours = 0
    for ff, aw in forms:
        n_m = len(M_GRID) if ff in ("no_tau", "full") else 1
        n_ka = len(KA_KP_GRID) if aw == "back_calculation" else 1
        grid += len(ZETA_GRID) * max(len(ALPHA_FRACTIONS), N_ALPHA) * n_m * n_ka
        neighbours = max(neighbours, 9 * (3 if n_m > 1 else 1) * (3 if n_ka > 1 else 1))
    n_search = len(J_ratios(spec.J_range, 3))
    return (grid + REFINE_ROUNDS * neighbours) * n_search + CHECK_MAX * len(J_ratios(spec.J_range, N_J_CHECK))


class _Search:
    """The state of one autotuning: what is known of each candidate, and the runs made."""

    def __init__(self, scenario: Scenario, spec: Spec, workers: int | None, client: Any, progress: bool) -> None:
        self.scenario = scenario
        self.spec = spec
        self.workers = workers
        self.client = client
        self.progress = progress
        sc = scenario.speed_controller
        self.J_design_kgm2 = sc.J_kgm2
        self.tau_i_design_s = sc.tau_i_s
        self.tau_i_plant_s = scenario.current_loop.tau_i_s
        self.Ts_s = sc.Ts_s
        self.method = sc.method
        self.feedforwards = spec.feedforwards or (sc.feedforward,)
        self.anti_windups = spec.anti_windups or (sc.anti_windup,)
        self.J_ratios_checked = J_ratios(spec.J_range, N_J_CHECK)
        self.J_ratios_search = J_ratios(spec.J_range, 3)
        self.bases = {"scenario": scenario}
        self.margins: dict[tuple[float, float], dict[float, Margins | None]] = {}
        self.edges: dict[tuple[float, float], float | None] = {}
        self.known: dict[Candidate, tuple[int, Evaluation]] = {}
        self.refused: dict[Candidate, str] = {}
        self.figures: dict[tuple[Candidate, float], RunRecord] = {}
        self.simulated_at: dict[Candidate, list[float]] = {}
        self.order: dict[Candidate, None] = {}
        self.runs: list[RunRecord] = []

    # -- the search space --------------------------------------------------------------------

    def alpha_max_radps(self, zeta: float, m: float) -> float:
        """The largest bandwidth searched: stable (Routh on eq 8: alpha < 4 zeta^2 / tau_i) and
        sampled finely enough (``max(alpha, alpha/(2 zeta), m alpha) Ts <= MAX_W_TS``)."""
        return float(min(4.0 * zeta**2 / self.tau_i_plant_s, MAX_W_TS / (self.Ts_s * max(1.0, 1.0 / (2.0 * zeta), m))))

    def edge_radps(self, zeta: float, m: float) -> float | None:
        """The largest bandwidth (at most :meth:`alpha_max_radps`) whose loop meets the margin constraints
        (stable without them) at every inertia ratio; None when even ``alpha_max 10**-ALPHA_DECADES``
        misses them.

        The margins fall as alpha grows (the current loop's lag takes a larger share of the phase
        at the crossover), and over the inertia range they are smallest at its ends (the crossover
        moves towards the current loop's pole or towards the PI's zero): a bisection on a log scale
        with the two ends, then the edge checked at every ratio, stepping down where it fails.
        """
        top = self.alpha_max_radps(zeta, m)
        key = (zeta, top)
        if key not in self.edges:
            ends = (self.J_ratios_checked[0], self.J_ratios_checked[-1])
            lo, hi = top * 10.0**-ALPHA_DECADES, top
            edge: float | None = None
            if self.margins_hold(hi, zeta, ends):
                edge = hi
            elif self.margins_hold(lo, zeta, ends):
                for _ in range(EDGE_STEPS):
                    mid = math.sqrt(lo * hi)
                    lo, hi = (mid, hi) if self.margins_hold(mid, zeta, ends) else (lo, mid)
                edge = lo
            while edge is not None and not self.margins_hold(edge, zeta, self.J_ratios_checked):
                edge = edge * EDGE_BACKOFF if edge * EDGE_BACKOFF >= top * 10.0**-ALPHA_DECADES else None
            self.edges[key] = edge
        return self.edges[key]

    def scale_radps(self, zeta: float, m: float) -> float:
        """The bandwidth that the fraction coordinate of the search multiplies: the edge, else the bound."""
        return self.edge_radps(zeta, m) or self.alpha_max_radps(zeta, m)

    def candidate(
        self, alpha_radps: float, zeta: float, m: float, Ka_Kp: float, ff: Feedforward, aw: AntiWindup
    ) -> Candidate:
        """The candidate of these values, rounded to 4 digits (alpha down); Ka from ``Ka Kp``."""
        alpha_radps, zeta = _sig_down(alpha_radps), _sig(zeta)
        m = _sig(m) if ff in ("no_tau", "full") else 1.0
        Kp = self.J_design_kgm2 * alpha_radps
        Ka = _sig(Ka_Kp / Kp if aw == "back_calculation" else 1.0 / Kp)
        return Candidate(alpha_radps, zeta, m, Ka, ff, aw)

    def in_space(self, c: Candidate) -> bool:
        """Whether ``c`` lies in the searched box (:data:`ZETA_RANGE`, :data:`KA_KP_RANGE`, :data:`M_RANGE`, alpha)."""
        Ka_Kp = c.Ka * self.J_design_kgm2 * c.alpha_radps
        return (
            c.alpha_radps <= self.alpha_max_radps(c.zeta, c.m) * (1.0 + 1e-9)
            and ZETA_RANGE[0] <= c.zeta <= ZETA_RANGE[1]
            and M_RANGE[0] <= c.m <= M_RANGE[1]
            and (c.anti_windup != "back_calculation" or KA_KP_RANGE[0] * 0.999 <= Ka_Kp <= KA_KP_RANGE[1] * 1.001)
        )

    def grid(self) -> list[Candidate]:
        """The coarse grid: zeta, alpha as fractions of the edge, ``Ka Kp``, m, the forms allowed."""
        out = []
        for ff, aw in itertools.product(self.feedforwards, self.anti_windups):
            ms = M_GRID if ff in ("no_tau", "full") else (1.0,)
            kas = KA_KP_GRID if aw == "back_calculation" else (1.0,)
            for zeta, m, Ka_Kp in itertools.product(ZETA_GRID, ms, kas):
                edge = self.edge_radps(zeta, m)
                if edge is None:
                    alphas = self.alpha_max_radps(zeta, m) * np.logspace(-ALPHA_DECADES, 0.0, N_ALPHA)
                else:
                    alphas = edge * np.array(ALPHA_FRACTIONS)
                out += [self.candidate(float(alpha), zeta, m, Ka_Kp, ff, aw) for alpha in alphas]
        return [c for c in dict.fromkeys(out) if self.in_space(c)]

    def neighbours(self, c: Candidate, step: float) -> list[Candidate]:
        """The candidates one log step ``step`` (a factor > 1) away in zeta, the fraction of the edge,
        Ka Kp and m: a step in zeta moves alpha with the edge."""
        f = (1.0 / step, 1.0, step)
        Ka_Kp = c.Ka * self.J_design_kgm2 * c.alpha_radps
        fraction = c.alpha_radps / self.scale_radps(c.zeta, c.m)
        ms = f if c.feedforward in ("no_tau", "full") else (1.0,)
        kas = f if c.anti_windup == "back_calculation" else (1.0,)
        out = []
        for z, mm, a, k in itertools.product(f, ms, f, kas):
            zeta, m = _sig(c.zeta * z), c.m * mm
            if not ZETA_RANGE[0] <= zeta <= ZETA_RANGE[1]:
                continue
            alpha = min(fraction * a, 1.0) * self.scale_radps(zeta, m)
            out.append(self.candidate(alpha, zeta, m, Ka_Kp * k, c.feedforward, c.anti_windup))
        return [n for n in dict.fromkeys(out) if n != c and self.in_space(n)]

    # -- evaluation --------------------------------------------------------------------------

    def margins_of(self, alpha_radps: float, zeta: float, J_ratio: float) -> Margins | None:
        """The margins of the PI (alpha, zeta) on the plant of inertia ratio ``J_ratio`` (one of
        :attr:`J_ratios_checked`, all computed together); None: unstable."""
        key = (alpha_radps, zeta)
        if key not in self.margins:
            d = make_design(self.J_design_kgm2, alpha_radps, zeta, tau_i_s=self.tau_i_design_s)
            J_plants = [r * self.J_design_kgm2 for r in self.J_ratios_checked]
            margins = margins_on_plants(d, self.Ts_s, self.method, J_plants, self.tau_i_plant_s)
            self.margins[key] = dict(zip(self.J_ratios_checked, margins))
        return self.margins[key][J_ratio]

    def refusal(self, c: Candidate) -> str:
        """Why the C controller refuses ``c`` at the scenario's sampling period; empty when it does not."""
        if c not in self.refused:
            try:
                d = make_design(
                    self.J_design_kgm2,
                    c.alpha_radps,
                    c.zeta,
                    c.m,
                    self.tau_i_design_s,
                    c.feedforward,
                    c.anti_windup,
                    c.Ka,
                )
                c_coefficients(d, self.Ts_s, self.method)
            except ConfigError as exc:
                self.refused[c] = f"the C controller refuses it: {exc}"
            else:
                self.refused[c] = ""
        return self.refused[c]

    def margins_hold(self, alpha_radps: float, zeta: float, J_ratios: Sequence[float]) -> bool:
        """Whether the PI (alpha, zeta) is stable and meets the margin constraints at ``J_ratios``."""
        limits = self.spec.constraints()
        for r in J_ratios:
            margins = self.margins_of(alpha_radps, zeta, r)
            if margins is None:
                return False
            if margins.phase_margin_deg < limits.get("min_phase_margin_deg", -math.inf):
                return False
            if margins.gain_margin_dB < limits.get("min_gain_margin_dB", -math.inf):
                return False
        return True

    def margin_figures(self, c: Candidate) -> tuple[dict[str, float], dict[str, float], str]:
        """Worst margins of ``c`` over the checked inertia ratios, the ratio of each, and why they are
        missing (the loop is unstable at a ratio) or empty."""
        worst = {"phase_margin_deg": math.inf, "gain_margin_dB": math.inf}
        at = {"phase_margin_deg": self.J_ratios_checked[0], "gain_margin_dB": self.J_ratios_checked[0]}
        for r in self.J_ratios_checked:
            margins = self.margins_of(c.alpha_radps, c.zeta, r)
            if margins is None:
                return worst, at, f"the discrete loop is unstable at J ratio {r:.4g}"
            for name in MARGIN_FIGURES:
                value = getattr(margins, name)
                if value < worst[name]:
                    worst[name], at[name] = value, r
        return worst, at, ""

    def passes_margins(self, c: Candidate) -> bool:
        """Whether ``c`` is worth simulating: the C controller takes it and its margins hold."""
        worst, at, error = self.margin_figures(c)
        if error or self.refusal(c):
            return False
        return not any(
            v.constraint in ("min_phase_margin_deg", "min_gain_margin_dB") for v in self.violations(worst, at)
        )

    def violations(self, worst: Mapping[str, float], at: Mapping[str, float]) -> tuple[Violation, ...]:
        """The constraints of the spec that the worst-case figures known miss."""
        out = []
        for name, limit in self.spec.constraints().items():
            figure, sense, _unit = CONSTRAINTS[name]
            if figure not in worst:
                continue
            value = worst[figure]
            miss = value - limit if sense == "max" else limit - value
            if miss > 0.0:
                out.append(Violation(name, limit, value, miss, at[figure]))
        return tuple(out)

    def simulate(self, pairs: Sequence[tuple[Candidate, float]]) -> None:
        """Simulate each (candidate, J ratio) not simulated yet, in batches on the engine's threads."""
        todo = list(dict.fromkeys(p for p in pairs if p not in self.figures))
        if not todo:
            return
        runs = [
            Run(
                key=i,
                base="scenario",
                overrides=c.overrides()
                # every speed sample logged, no more: a chattering command shows from one sample to the next
                | {"motor.J_kgm2": r * self.J_design_kgm2, "speed_controller.J_kgm2": self.J_design_kgm2}
                | {"simulation.log_every": 1, "simulation.log_rate": "speed"},
                label=f"autotune candidate {c.speed_controller()} at J ratio {r:.4g}",
            )
            for i, (c, r) in enumerate(todo)
        ]
        outcomes: list[Outcome] = run_many(
            self.bases, runs, workers=self.workers, client=self.client, progress=self.progress, description="autotune"
        )
        for (c, r), outcome in zip(todo, outcomes):
            figures = step_figures(outcome.metrics) if outcome.metrics is not None else {}
            record = RunRecord(c, r, figures, outcome.error, outcome.wall_time_s)
            self.figures[(c, r)] = record
            self.simulated_at.setdefault(c, []).append(r)
            self.runs.append(record)

    def evaluate(self, candidates: Iterable[Candidate], J_ratios_sim: Sequence[float] | None = None) -> None:
        """Check the margins of ``candidates``, then simulate those that pass at ``J_ratios_sim``; by default at
        the largest inertia ratio of the search, where the worst cases mostly lie (:meth:`best` simulates the
        others where they matter)."""
        ratios = self.J_ratios_search[-1:] if J_ratios_sim is None else J_ratios_sim
        candidates = list(candidates)
        self.order.update(dict.fromkeys(candidates))
        self.simulate([(c, r) for c in candidates if self.passes_margins(c) for r in ratios])

    def evaluation(self, c: Candidate) -> Evaluation:
        """What is known of ``c`` (computed again only when it has been simulated at more ratios)."""
        n_simulated = len(self.simulated_at.get(c, ()))
        if c not in self.known or self.known[c][0] != n_simulated:
            self.known[c] = (n_simulated, self._evaluation(c))
        return self.known[c][1]

    def _evaluation(self, c: Candidate) -> Evaluation:
        worst, at, error = self.margin_figures(c)
        error = error or self.refusal(c)
        simulated = sorted(self.simulated_at.get(c, []))
        if error or not simulated:
            return Evaluation(c, "margins", worst, at, (), self.violations(worst, at) if not error else (), error)
        stage = "engine" if set(self.J_ratios_search) <= set(simulated) else "partial"
        for r in simulated:
            record = self.figures[(c, r)]
            if record.error:
                stopped = f"the simulation at J ratio {r:.4g} stopped: {record.error}"
                return Evaluation(c, "engine", worst, at, tuple(simulated), (), stopped)
            for name, value in record.figures.items():
                if name not in worst or value > worst[name]:
                    worst[name], at[name] = value, r
        if worst["chatter_share"] > CHATTER_SHARE_MAX:
            chatters = (
                f"the current command chatters at J ratio {at['chatter_share']:.4g} "
                f"({100 * worst['chatter_share']:.3g} % of the samples, more than {100 * CHATTER_SHARE_MAX:g} %): "
                "a limit cycle"
            )
            return Evaluation(c, "engine", worst, at, tuple(simulated), (), chatters)
        return Evaluation(c, stage, worst, at, tuple(simulated), self.violations(worst, at), "")

    def evaluations(self) -> list[Evaluation]:
        return [self.evaluation(c) for c in self.order]

    @staticmethod
    def rank(e: Evaluation) -> tuple[float, float, float]:
        """Feasible first, by the worst case of :data:`OBJECTIVE`; then by :meth:`Evaluation.total_miss`.

        For a ``"partial"`` evaluation, a bound: its rank over the ratios simulated, which more ratios
        can only raise (a worst case only grows; a finite miss that becomes infinite moves the rank up).
        """
        if e.may_be_feasible:
            return (0.0, 0.0, e.worst[OBJECTIVE])
        return (1.0, *e.total_miss())

    def best(self) -> Evaluation:
        """The best simulated candidate (:meth:`rank`); the best of all when none was simulated.

        The same as if every candidate had been simulated at every inertia ratio of the search: a
        ``"partial"`` candidate whose bound ranks it before the best complete one is simulated at
        the other ratios (:data:`COMPLETE_BATCH` at a time, best bound first), until the best is complete.
        """
        while True:
            pool = self.evaluations()
            simulated = [e for e in pool if e.stage in ("engine", "partial")]
            best = min(simulated or pool, key=self.rank)
            if best.stage != "partial":
                return best
            complete = [self.rank(e) for e in simulated if e.stage == "engine"]
            bar = min(complete) if complete else None
            todo = sorted(
                (e for e in simulated if e.stage == "partial" and (bar is None or self.rank(e) < bar)), key=self.rank
            )
            self.simulate([(e.candidate, r) for e in todo[:COMPLETE_BATCH] for r in self.J_ratios_search])


def bounds_reached(search: "_Search", c: Candidate) -> tuple[str, ...]:
    """The bounds of the search that the candidate ``c`` lies on, one sentence each.

    ``zeta`` at an end of :data:`ZETA_RANGE`; ``alpha`` at :meth:`_Search.alpha_max_radps`, the
    stability and sampling bound (the margins' edge below it is a constraint, not a bound);
    ``m`` at an end of :data:`M_RANGE` (feedforwards ``no_tau``, ``full``); ``Ka Kp`` at an end of
    :data:`KA_KP_RANGE` (back calculation). Within the rounding of the keys to 4 digits.
    """

    def at(value: float, lo: float, hi: float) -> str:
        return "lower" if value <= lo * 1.001 else "upper" if value >= hi * 0.999 else ""

    out = []
    checks = [("zeta", c.zeta, ZETA_RANGE)]
    if c.feedforward in ("no_tau", "full"):
        checks.append(("m", c.m, M_RANGE))
    if c.anti_windup == "back_calculation":
        checks.append(("Ka Kp", c.Ka * search.J_design_kgm2 * c.alpha_radps, KA_KP_RANGE))
    for name, value, (lo, hi) in checks:
        side = at(value, lo, hi)
        if side:
            out.append(
                f"{name} = {value:.4g} is at the {side} bound of the search ({lo:g} to {hi:g}): the best design "
                "may lie beyond it"
            )
    alpha_max = search.alpha_max_radps(c.zeta, c.m)
    if c.alpha_radps >= alpha_max * 0.999:
        out.append(
            f"alpha_radps = {c.alpha_radps:.4g} is at the bound of the search, {alpha_max:.4g} rad/s "
            "(stability alpha < 4 zeta^2 / tau_i, or sampling max(alpha, alpha/(2 zeta), m alpha) Ts <= "
            f"{MAX_W_TS:g})"
        )
    return tuple(out)


def pareto_front(evaluations: Sequence[Evaluation]) -> tuple[Evaluation, ...]:
    """The designs that no other one beats on all of tracking, rejection and robustness.

    Among the feasible evaluations (all the simulated, completed ones when none is feasible):
    worst ``tracking_iae_rpm_s`` (smaller), worst :data:`OBJECTIVE` (smaller), worst
    ``phase_margin_deg`` (larger). Sorted by the objective.
    """
    points = [e for e in evaluations if e.feasible] or [e for e in evaluations if e.stage == "engine" and not e.error]

    def objectives(e: Evaluation) -> tuple[float, float, float]:
        return (e.worst["tracking_iae_rpm_s"], e.worst[OBJECTIVE], -e.worst["phase_margin_deg"])

    values = [objectives(e) for e in points]
    front = []
    for i, a in enumerate(values):
        dominated = any(all(x <= y for x, y in zip(b, a)) and b != a for j, b in enumerate(values) if j != i)
        if not dominated:
            front.append(points[i])
    return tuple(sorted(front, key=lambda e: e.worst[OBJECTIVE]))


def autotune(
    scenario: Scenario,
    spec: Spec | None = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> AutotuneResult:
    """The anti-windup 2DOF design of smallest worst-case load IAE per Nm that meets ``spec`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The drive and the test: its speed and load steps are those the design is measured on;
        it needs at least one load step that changes the load (the objective).
        ``speed_controller.J_kgm2`` is the design inertia, ``current_loop.tau_i_s`` the plant's.
    spec : Spec, optional
        The constraints and the inertia range; default :class:`Spec` () (margins 45 deg and
        6 dB at the design inertia).
    workers : int, optional
        Local threads of the engine, >= 1 (default: all available cores). Not with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask distributed scheduler (``tcp://host:port``): the simulations
        run on its workers, which need pmsm2dof installed (:func:`pmsm2dof.studies.engine.connect`).
    progress : bool
        Show a progress bar (stderr) over each batch of simulations.

    Returns
    -------
    AutotuneResult
        Also when no design meets ``spec``: ``feasible`` is then False and ``binding`` says
        which constraint binds and by how much the best design misses it.

    Raises
    ------
    ConfigError
        ``scenario`` not a Scenario or without a load step, ``spec`` not a Spec, ``workers``
        out of range, ``scheduler`` not the address of a running scheduler.
    """
    start = time.perf_counter()
    if not isinstance(scenario, Scenario):
        raise ConfigError("scenario", type(scenario).__name__, "a pmsm2dof Scenario (load_scenario)")
    if spec is None:
        spec = Spec()
    if not isinstance(spec, Spec):
        raise ConfigError("spec", type(spec).__name__, "a pmsm2dof Spec")
    check_options(workers, scheduler)
    loads = [entry.torque_Nm for entry in scenario.load]
    if not any(b != a for b, a in zip([0.0] + loads, loads)):
        raise ConfigError(
            "scenario",
            scenario.name,
            "a scenario with a load step that changes the load torque (the objective is its speed dip per Nm)",
        )
    with connect(scheduler) as client:
        search = _Search(scenario, spec, workers, client, progress)
        search.evaluate(search.grid())
        center = search.best().candidate
        step = STEP_FIRST
        for _ in range(REFINE_ROUNDS):
            search.evaluate(search.neighbours(center, step))
            new = search.best().candidate
            if new == center:
                step = math.sqrt(step)
                if step < REFINE_STEP_MIN:
                    break
            center = new
        # the best design again over the whole range, until the best one has been checked there
        checked: set[Candidate] = set()
        for _ in range(CHECK_MAX):
            best = search.best()
            if best.candidate in checked or not best.feasible:
                break
            search.evaluate([best.candidate], search.J_ratios_checked)
            checked.add(best.candidate)
        held = [e for e in map(search.evaluation, checked) if e.feasible]
        chosen = min(held, key=_Search.rank) if held else search.best()
    evaluations = search.evaluations()
    binding = None
    if not chosen.feasible and chosen.violations:
        binding = max(chosen.violations, key=Violation.normalized)  # an infinite miss binds first
    return AutotuneResult(
        scenario=scenario,
        spec=spec,
        feasible=chosen.feasible,
        chosen=chosen,
        binding=binding,
        evaluations=tuple(evaluations),
        pareto=pareto_front(evaluations),
        runs=tuple(search.runs),
        J_ratios_checked=search.J_ratios_checked,
        wall_time_s=time.perf_counter() - start,
        on_bounds=bounds_reached(search, chosen.candidate),
        scenario_loop=sampled_loop(scenario),
    )
