"""
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
4. the best design is simulated again at ``N_J_CHECK`` inertia ratios spread over the range;
   one that fails there is rejected and the next best checked.

A candidate whose current command chatters in a simulation (``chatter_share`` above
:data:`pmsm2dof.sim.metrics.CHATTER_SHARE_MAX`: a limit cycle, whatever its figures) is rejected.
When the chosen design lies on a bound of the search (``ZETA_RANGE``, ``KA_KP_RANGE``,
``M_RANGE``, or the stability and sampling bound of alpha), :attr:`AutotuneResult.on_bounds`
says so: the best design may lie beyond it. The scenario's own design is checked as
``pmsm2dof design`` checks it (:func:`pmsm2dof.studies.loopcheck.sampled_loop`), and a warning
given when its sampled loop is unstable.

When no candidate meets the specification the result says so (``feasible`` False): the design
returned is the one that misses it least, and :attr:`AutotuneResult.binding` names the
constraint it misses most and by how much.

The specification, the candidates and the result are those of :mod:`pmsm2dof.studies.autotune`; the grids
and bounds of the search (``ZETA_RANGE``, ``N_J_CHECK``, ...) those of :mod:`pmsm2dof.studies.autotune_space`.
"""

import contextlib
import itertools
import math
import time
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis.design import design as make_design
from ..analysis.discretize import MAX_W_TS
from ..analysis.margins import Margins
from ..analysis.sampled_loop import c_coefficients, margins_on_plants
from ..core.bindings import AntiWindup, Feedforward
from ..errors import ConfigError
from ..sim.metrics import CHATTER_SHARE_MAX
from ..sim.scenario import Scenario
from .autotune import (
    CONSTRAINTS,
    MARGIN_FIGURES,
    OBJECTIVE,
    AutotuneResult,
    Candidate,
    Evaluation,
    RunRecord,
    Spec,
    Violation,
    pareto_front,
    run_figures,
)
from .autotune_space import (
    ALPHA_DECADES,
    ALPHA_FRACTIONS,
    CHECK_MAX,
    COMPLETE_BATCH,
    EDGE_BACKOFF,
    EDGE_STEPS,
    KA_KP_GRID,
    KA_KP_RANGE,
    M_GRID,
    M_RANGE,
    N_ALPHA,
    N_J_CHECK,
    REFINE_ROUNDS,
    REFINE_STEP_MIN,
    STEP_FIRST,
    ZETA_GRID,
    ZETA_RANGE,
    J_ratios,
)
from .engine import Outcome, Run, check_options, connect, local_threads, run_many
from .loopcheck import sampled_loop

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor


def _sig(x: float) -> float:
    """``x`` to 4 significant digits, so that the chosen keys read and reproduce exactly."""
    return float(f"{x:.4g}")


def _sig_down(x: float) -> float:
    """``x > 0`` rounded down to 4 significant digits (a bandwidth at the edge stays inside it)."""
    unit = 10.0 ** (math.floor(math.log10(x)) - 3)
    return float(f"{math.floor(x / unit * (1.0 + 1e-12)) * unit:.4g}")


class _Search:
    """The state of one autotuning: what is known of each candidate, and the runs made."""

    def __init__(
        self,
        scenario: Scenario,
        spec: Spec,
        workers: int | None,
        client: Any,
        progress: bool,
        pool: "ThreadPoolExecutor | None" = None,
    ) -> None:
        self.scenario = scenario
        self.spec = spec
        self.workers = workers
        self.client = client
        self.pool = pool
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
        # every run: the design inertia, every speed sample logged, no more (a chattering command shows from
        # one sample to the next); set once here, so that a run changes the candidate's keys and the inertia
        self.bases = {
            "scenario": scenario.with_overrides(
                {"speed_controller.J_kgm2": sc.J_kgm2, "simulation.log_every": 1, "simulation.log_rate": "speed"}
            )
        }
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
        """Whether ``c`` lies in the searched box (``ZETA_RANGE``, ``KA_KP_RANGE``, ``M_RANGE``, alpha)."""
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
                overrides=c.overrides() | {"motor.J_kgm2": r * self.J_design_kgm2},
                label=f"autotune candidate {c.speed_controller()} at J ratio {r:.4g}",
            )
            for i, (c, r) in enumerate(todo)
        ]
        outcomes: list[Outcome] = run_many(
            self.bases,
            runs,
            measure=run_figures,
            workers=self.workers,
            pool=self.pool,
            client=self.client,
            progress=self.progress,
            description="autotune",
        )
        for (c, r), outcome in zip(todo, outcomes):
            figures = outcome.metrics if outcome.metrics is not None else {}
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
        the other ratios (``COMPLETE_BATCH`` at a time, best bound first), until the best is complete.
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

    ``zeta`` at an end of ``ZETA_RANGE``; ``alpha`` at :meth:`_Search.alpha_max_radps`, the
    stability and sampling bound (the margins' edge below it is a constraint, not a bound);
    ``m`` at an end of ``M_RANGE`` (feedforwards ``no_tau``, ``full``); ``Ka Kp`` at an end of
    ``KA_KP_RANGE`` (back calculation). Within the rounding of the keys to 4 digits.
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
    with contextlib.ExitStack() as stack:
        client = stack.enter_context(connect(scheduler))
        # the engine's threads for the whole search (not started again for each batch of simulations)
        pool = None if client is not None else stack.enter_context(local_threads(workers))
        search = _Search(scenario, spec, workers, client, progress, pool)
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
