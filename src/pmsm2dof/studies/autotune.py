"""What autotuning is asked and what it answers: the specification, the candidate designs, the result.

A :class:`Spec` bounds the figures of :data:`FIGURES` (:data:`CONSTRAINTS`) over a range of inertias; the
search (:func:`pmsm2dof.studies.autotune_search.autotune`) tries :class:`Candidate` designs, knows each one as an
:class:`Evaluation` and each simulation as a :class:`RunRecord`, and answers an :class:`AutotuneResult`.
The figures of a simulation are :func:`step_figures` of :func:`pmsm2dof.sim.metrics.compute_metrics`
(rpm), taken over the reference steps (overshoot, settling time, tracking IAE), the load steps (speed dip
and IAE divided by the load change, recovery time) and both (longest time at the current limit in one step
window), and the run (chatter); their worst cases over the inertias are those of :data:`FIGURES`. The
search computes only the figures that :func:`step_figures` reads (:func:`run_figures`).
"""

import dataclasses
import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from ..core import ANTI_WINDUPS, FEEDFORWARDS
from ..core.bindings import AntiWindup, Feedforward
from ..errors import ConfigError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario

if TYPE_CHECKING:
    from ..sim.simulate import Result

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
        already misses a constraint or ranks below the chosen design
        (:func:`~pmsm2dof.studies.autotune_search.autotune`), so that the others were not needed.
    worst : dict
        Worst case of each figure of :data:`FIGURES` known at this stage, over the inertia ratios
        checked (the margins at all :data:`~pmsm2dof.studies.autotune_space.N_J_CHECK`, the simulated ones at
        those simulated).
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
    """The outcome of :func:`~pmsm2dof.studies.autotune_search.autotune`.

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
        One sentence per bound of the search the chosen design lies on
        (:func:`~pmsm2dof.studies.autotune_search.bounds_reached`).
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


#: The figures of :func:`pmsm2dof.sim.metrics.compute_metrics` that :func:`step_figures` reads, by part.
STEP_METRICS = {
    "reference_steps": ("overshoot_pct", "settling_time_s", "iae_rpm_s", "current_limit_time_s"),
    "load_steps": ("speed_dip_rpm", "recovery_time_s", "iae_rpm_s", "current_limit_time_s"),
    "run": ("chatter_share",),
}


def run_figures(result: "Result") -> dict[str, float]:
    """:func:`step_figures` of a simulated run, from the figures it reads alone (:data:`STEP_METRICS`):
    the measure of each simulation of the search (:func:`pmsm2dof.studies.engine.run_many`)."""
    return step_figures(compute_metrics(result, figures=STEP_METRICS))


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
