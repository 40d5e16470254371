"""What the tuner computes: from control values to a scenario, a run, plot data and downloads.

The tuner's experiment is the base scenario, changed by the page's controls
(:mod:`pmsm2dof.ui.tuner.controls`).

Every request is validated by :meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`, exactly like
a scenario file; errors name the control key.

The work of one run is bounded: at most :data:`STEPS_MAX` plant integration steps (a longer
``simulation.t_end_s`` answers a ConfigError naming the bound), and ``simulation.log_every`` is
raised so that the run logs at most :data:`LOG_ROWS_MAX` rows (the plots draw a thousand points a
trace; the metrics and the trace download are those of the logged rows). A run is simulated in
chunks of about :data:`CHUNK_STEPS` steps and stops between two of them when a newer request of
the same client supersedes it (:mod:`pmsm2dof.ui.tuner.slots`).
"""

import collections
import functools
import json
import math
import threading
import time
from collections.abc import Mapping
from typing import Any

import control
import numpy as np
import numpy.typing as npt

from ...analysis.design import Design, design
from ...errors import ConfigError, require_positive
from ...sim.metrics import at_current_limit, at_voltage_limit
from ...sim.scenario import Scenario
from ...sim.simulate import Result, Simulation
from ...studies.configuration import configuration, scenario_design
from ...studies.loopcheck import measure
from ..plots.trace import saturated_intervals
from .controls import initial_values
from .slots import Ticket

#: Buckets of the min-max decimation of the traces sent to the page: each bucket keeps its
#: minimum and its maximum, so peaks (the overshoot, the load dip) survive exactly.
DECIMATION_BUCKETS = 500
#: Points of the Bode plot.
BODE_POINTS = 240
#: Bode plot range around the design bandwidth alpha [decades below, decades above].
BODE_DECADES = (2.0, 2.5)
#: Runs kept for the downloads that follow a run with the same control values.
CACHED_RUNS = 8
#: Most rows a run logs (simulation.log_every grows to keep below it).
LOG_ROWS_MAX = 5000
#: Most plant integration steps (RK4) one run may take: about half a second of the engine.
STEPS_MAX = 10**7
#: Integration steps per C call: a superseded run stops within one call (a few ms).
CHUNK_STEPS = 50_000
#: Most shaded spans a limit gets on the page: beyond, the spans closest together merge.
SPANS_MAX = 40
#: Most plant integration steps one suggestion may take over all the simulations the autotuner
#: can make (:func:`pmsm2dof.studies.autotune_space.runs_bound` times the steps of one run).
SUGGEST_STEPS_MAX = 5 * 10**8
#: The specification a suggestion takes (:class:`pmsm2dof.studies.autotune.Spec` fields; the forms
#: searched are the experiment's feedforward and anti-windup).
SUGGEST_SPEC_KEYS = (
    "max_overshoot_pct",
    "min_phase_margin_deg",
    "min_gain_margin_dB",
    "max_settling_s",
    "max_load_dip_rpm_per_Nm",
    "max_recovery_s",
    "max_current_limit_time_s",
    "J_range",
)

#: Rows of the metrics table, per part of compute_metrics: (figure key, label, unit).
TABLE_METRICS = {
    "reference_steps": (
        ("overshoot_pct", "overshoot", "%"),
        ("rise_time_s", "rise time 10-90 %", "s"),
        ("settling_time_s", "settling time 2 %", "s"),
        ("current_limit_time_s", "time at the current limit", "s"),
    ),
    "load_steps": (
        ("speed_dip_rpm", "load dip", "rpm"),
        ("recovery_time_s", "recovery time 2 %", "s"),
    ),
    "faults": (
        ("speed_deviation_rpm", "speed deviation", "rpm"),
        ("recovery_time_s", "recovery time 2 % after the fault", "s"),
    ),
    "run": (
        ("current_limit_time_s", "time at the current limit", "s"),
        ("voltage_limit_time_s", "time at the voltage limit", "s"),
        ("chatter_share", "share of samples where the current command chatters", ""),
    ),
}


def minmax_indices(y: npt.ArrayLike, buckets: int = DECIMATION_BUCKETS) -> npt.NDArray[np.intp]:
    """Indices of the samples of ``y`` that min-max decimation keeps, sorted.

    The samples are split into ``buckets`` consecutive runs of equal length; of each run the
    samples holding the minimum and the maximum are kept, plus the first and the last sample,
    so at most ``2 * buckets + 2`` remain and the extremes of the whole trace (the overshoot,
    the load dip) are kept exactly. Short traces are kept whole.
    """
    values = np.asarray(y, dtype=float)
    n = len(values)
    if n <= 2 * buckets + 2:
        return np.arange(n)
    width = -(-n // buckets)  # ceil(n / buckets)
    padded = np.concatenate([values, np.full(width * buckets - n, values[-1])]).reshape(buckets, width)
    offsets = np.arange(buckets) * width
    i_min = np.minimum(offsets + np.argmin(padded, axis=1), n - 1)
    i_max = np.minimum(offsets + np.argmax(padded, axis=1), n - 1)
    return np.unique(np.concatenate([[0, n - 1], i_min, i_max]))


def _trace(t: npt.ArrayLike, y: npt.ArrayLike) -> dict[str, list[float]]:
    keep = minmax_indices(y)
    return {"t": np.asarray(t)[keep].tolist(), "y": np.asarray(y)[keep].tolist()}


def limit_spans(t: npt.ArrayLike, flags: npt.ArrayLike, most: int = SPANS_MAX) -> list[list[float]]:
    """``[start, end]`` of each run of set ``flags`` (the flag of sample k holds over [t[k], t[k+1])).

    When there are more than ``most`` runs, those separated by the shortest gaps are merged, so
    that a flag that chatters (clamping at the limit every other sample) shades one span and
    the page draws at most ``most`` of them.
    """
    spans = np.asarray(saturated_intervals(np.asarray(t), flags), dtype=float).reshape(-1, 2)
    if len(spans) > most:
        gaps = spans[1:, 0] - spans[:-1, 1]
        cuts = np.sort(np.argsort(gaps, kind="stable")[len(gaps) - (most - 1) :])  # the widest gaps stay
        spans = np.column_stack(
            (np.concatenate(([spans[0, 0]], spans[cuts + 1, 0])), np.concatenate((spans[cuts, 1], [spans[-1, 1]])))
        )
    return spans.tolist()


def bode_data(
    Gx: control.TransferFunction, GN: control.TransferFunction, alpha_radps: float, Ts_s: float
) -> dict[str, Any]:
    """Magnitude [dB] and unwrapped phase [deg] of ``Gx`` and ``GN`` around ``alpha_radps``.

    ``w_nyquist_radps = pi / Ts_s`` marks where the sampled controller stops following the
    continuous design.
    """
    below, above = BODE_DECADES
    w = np.logspace(math.log10(alpha_radps) - below, math.log10(alpha_radps) + above, BODE_POINTS)
    out: dict[str, Any] = {"w_radps": w.tolist(), "w_nyquist_radps": math.pi / Ts_s}
    for name, sys in (("Gx", Gx), ("GN", GN)):
        h = np.asarray(control.frequency_response(sys, w).complex).reshape(-1)
        # a zero of the response on the grid would be -inf dB, which JSON cannot carry
        out[f"{name}_dB"] = (20.0 * np.log10(np.maximum(np.abs(h), 1e-300))).tolist()
        out[f"{name}_deg"] = np.degrees(np.unwrap(np.angle(h))).tolist()
    return out


def design_of(scenario: Scenario) -> Design:
    """The :class:`~pmsm2dof.analysis.design.Design` of a scenario's speed controller (eq 9-13)."""
    return scenario_design(scenario, sensor=None)


class Tuner:
    """The tuner's computations for one base scenario.

    Parameters
    ----------
    base : pmsm2dof.sim.scenario.Scenario
        Motor, limits, current loop, initial controller settings, schedules, faults and timing.
    """

    def __init__(self, base: Scenario) -> None:
        self.base = base
        self._J_design_kgm2 = base.speed_controller.J_kgm2
        self._initial = initial_values(base)
        self._cache: collections.OrderedDict[str, tuple[Scenario, Result]] = collections.OrderedDict()
        self._cache_lock = threading.Lock()
        self._bode_cached = functools.lru_cache(maxsize=CACHED_RUNS)(self._bode_uncached)

    @property
    def keys(self) -> tuple[str, ...]:
        """The control keys a request may set, in the page's order."""
        return tuple(self._initial)

    # ---- request -> scenario ---------------------------------------------------------

    def scenario(self, values: Mapping[str, Any]) -> Scenario:
        """The validated scenario of the control ``values`` (missing keys keep their initial value).

        Raises
        ------
        ConfigError
            Naming the control key, its value and the valid range.
        """
        for key, value in values.items():
            if key not in self._initial:
                raise ConfigError(key, value, "one of the tuner's controls: " + ", ".join(self._initial))
        v = dict(self._initial, **values)
        J_ratio = require_positive("tuner.J_ratio", v.pop("tuner.J_ratio"))
        v.update({"motor.J_kgm2": J_ratio * self._J_design_kgm2, "speed_controller.J_kgm2": self._J_design_kgm2})
        return self.base.with_overrides(v)

    @staticmethod
    def logged(scenario: Scenario) -> Scenario:
        """The scenario as the tuner simulates it: at the speed rate (``simulation.log_rate``), its
        ``simulation.log_every`` raised to log at most :data:`LOG_ROWS_MAX` rows.

        Raises
        ------
        ConfigError
            Naming ``simulation.t_end_s`` when the run would take more than :data:`STEPS_MAX`
            plant integration steps.
        """
        sim, Ts_cl = scenario.simulation, scenario.current_loop.Ts_s
        # the engine's integration step: current_loop.Ts_s / ceil(current_loop.Ts_s / dt_s) (pmsm2dof.sim.simulate)
        h_s = Ts_cl / max(1, math.ceil(Ts_cl / sim.dt_s * (1.0 - 1e-9)))
        if sim.t_end_s > STEPS_MAX * h_s:
            raise ConfigError(
                "simulation.t_end_s",
                sim.t_end_s,
                f"<= {STEPS_MAX * h_s:g} s in the tuner: at most {STEPS_MAX:.0e} plant integration "
                f"steps of {h_s:g} s per run (pmsm2dof simulate runs longer ones)",
            )
        n_samples = math.floor(sim.t_end_s / scenario.speed_controller.Ts_s + 1e-9) + 1
        # the tuner's figures and metrics are the speed loop's: a row per speed sample at most
        log_every = max(sim.log_every if sim.log_rate == "speed" else 1, -(-n_samples // LOG_ROWS_MAX))
        return scenario.with_overrides({"simulation.log_every": log_every, "simulation.log_rate": "speed"})

    # ---- runs ------------------------------------------------------------------------

    def _evaluate(self, values: Mapping[str, Any], ticket: Ticket | None = None) -> tuple[Scenario, Result]:
        """(scenario, result) of the control values, from a small cache keyed by the values.

        ``result.scenario`` is :meth:`logged` of ``scenario``. On a cache miss the simulation
        runs under ``ticket`` (its client's slot; a slot of its own when None).
        """
        key = json.dumps(values, sort_keys=True)
        with self._cache_lock:
            if key in self._cache:
                self._cache.move_to_end(key)
                return self._cache[key]
        scenario = self.scenario(values)
        result = self._simulate(self.logged(scenario), ticket or Ticket())
        with self._cache_lock:
            self._cache[key] = scenario, result
            while len(self._cache) > CACHED_RUNS:
                self._cache.popitem(last=False)
        return scenario, result

    @staticmethod
    def _simulate(scenario: Scenario, ticket: Ticket) -> Result:
        """:func:`pmsm2dof.simulate` in chunks of about :data:`CHUNK_STEPS` steps, stopping with
        :class:`~pmsm2dof.ui.tuner.slots.Superseded` between two when ``ticket`` is cancelled."""
        run = Simulation(scenario)
        chunk = max(1, CHUNK_STEPS // (run.cfg.current_per_speed * run.cfg.substeps))
        with ticket.simulation():
            start = time.perf_counter()
            done = 0
            while done < run.n_samples:
                ticket.check()
                n = min(chunk, run.n_samples - done)
                run.advance(n)
                done += n
            wall_time_s = time.perf_counter() - start
        return run.result(scenario, wall_time_s)

    def run(self, values: Mapping[str, Any], ticket: Ticket | None = None) -> dict[str, Any]:
        """Run the experiment; return what the page draws (JSON-ready dict).

        Keys: ``traces`` (decimated ``{"t", "y"}`` of speed_ref_rpm, speed_rpm, iq_ref_A,
        id_ref_A, u_dq_V = ||u_dq|| and u_max_V = u_dc / sqrt(3)), ``spans`` (``current`` and
        ``voltage``: the ``[start, end]`` intervals at the current-vector limit and at the
        inverter's voltage range, by :func:`pmsm2dof.sim.metrics.at_current_limit` and
        :func:`~pmsm2dof.sim.metrics.at_voltage_limit`, as plot.png shades them), ``detail`` (speed
        and reference around the first load step,
        or without one the last reference step, to the last sample of its window (before the next
        event), decimated on their own so that the dip keeps its full resolution; its ``t_s`` and
        ``title``), ``bode``, ``metrics`` (list of ``{key, group, label, unit, value, reason}``, key
        the path in :func:`pmsm2dof.sim.metrics.compute_metrics`), ``warnings`` (sentences: the
        sampled loop unstable, the current command chattering, the voltage limit cut in;
        :func:`pmsm2dof.studies.loopcheck.measure`), ``design`` (Kp, Ki, Ka), ``log`` (every,
        period_s, rows), ``i_max_A``,
        ``t_end_s``, ``label`` and ``server_ms``.

        Raises
        ------
        ConfigError, SimulationError
            Bad control values, a run over the bound, a run that stopped.
        pmsm2dof.ui.tuner.slots.Superseded
            ``ticket`` was cancelled by a newer request of its client.
        """
        t0 = time.perf_counter()
        scenario, result = self._evaluate(values, ticket)
        dsg = design_of(scenario)
        t = np.asarray(result.t_s)
        u_dq_V = np.hypot(result.ud_V, result.uq_V)
        traces = {
            name: _trace(t, getattr(result, name)) for name in ("speed_ref_rpm", "speed_rpm", "iq_ref_A", "id_ref_A")
        }
        traces["u_dq_V"] = _trace(t, u_dq_V)
        traces["u_max_V"] = _trace(t, np.asarray(result.u_dc_V) / math.sqrt(3.0))
        figures = measure(result)
        if figures["load_steps"]:
            event = figures["load_steps"][0]
            title = f"Load step: {event['from_Nm']:g} \u2192 {event['to_Nm']:g} Nm at {event['t_s']:g} s"
        else:
            event = figures["reference_steps"][-1]
            title = f"Reference step: {event['from_rpm']:g} \u2192 {event['to_rpm']:g} rpm at {event['t_s']:g} s"
        t0_s, t1_s = event["t_s"], event["window_end_s"]
        window = np.flatnonzero((t >= t0_s - 0.1 * (t1_s - t0_s)) & (t <= t1_s))
        speed_w = np.asarray(result.speed_rpm)[window]
        ref_w = np.asarray(result.speed_ref_rpm)[window]
        keep = window[np.union1d(minmax_indices(speed_w), minmax_indices(ref_w))]
        detail = {
            "t": t[keep].tolist(),
            "speed_rpm": np.asarray(result.speed_rpm)[keep].tolist(),
            "speed_ref_rpm": np.asarray(result.speed_ref_rpm)[keep].tolist(),
            "t_s": t0_s,
            "title": title,
        }
        # everything the Bode plot depends on: computed, and redrawn by the page, when it changes
        bode_key = json.dumps(
            [
                dsg.J_kgm2,
                dsg.alpha_radps,
                dsg.zeta,
                dsg.m,
                dsg.tau_i_s,
                dsg.feedforward,
                result.scenario.motor.J_kgm2,
                result.scenario.speed_controller.Ts_s,
            ]
        )
        log_every = result.scenario.simulation.log_every
        out: dict[str, Any] = {
            "label": _label(result.scenario),
            "traces": traces,
            "spans": {
                "current": limit_spans(t, at_current_limit(result)),
                "voltage": limit_spans(t, at_voltage_limit(result) > 0.0),
            },
            "detail": detail,
            "bode": self._bode_cached(bode_key),
            "metrics": _metric_rows(figures),
            "warnings": _warnings(figures, result.scenario),
            "design": {"Kp": dsg.Kp, "Ki": dsg.Ki, "Ka": dsg.Ka},
            "log": {"every": log_every, "period_s": log_every * result.scenario.speed_controller.Ts_s, "rows": len(t)},
            "i_max_A": result.scenario.limits.i_max_A,
            "t_end_s": result.scenario.simulation.t_end_s,
        }
        out["server_ms"] = 1e3 * (time.perf_counter() - t0)
        return out

    @staticmethod
    def _bode_uncached(key: str) -> dict[str, Any]:
        J_design_kgm2, alpha_radps, zeta, m, tau_i_s, feedforward, J_true_kgm2, Ts_s = json.loads(key)
        dsg = design(J_design_kgm2, alpha_radps, zeta, m=m, tau_i_s=tau_i_s, feedforward=feedforward)
        Gx, GN = dsg.on_plant(J_true_kgm2)
        return bode_data(Gx, GN, alpha_radps, Ts_s) | {"key": key}

    # ---- suggest ---------------------------------------------------------------------

    def suggest(self, body: Mapping[str, Any]) -> dict[str, Any]:
        """Autotune the experiment of the posted control values; return the suggestion (JSON-ready dict).

        ``body`` is ``{"values": {control key: value}, "spec": {field: value}}``, the spec's fields
        those of :data:`SUGGEST_SPEC_KEYS` (``J_range`` as ``[lo, hi]``); the experiment is the
        scenario of the values (:meth:`scenario`) and its design inertia the base scenario's. Keys:
        ``feasible``, ``values`` (the chosen ``speed_controller.*`` control values), ``worst_case``
        and ``worst_J_ratio``, ``violations`` (sentences; empty when feasible), ``binding``,
        ``on_bounds`` (sentences: the bounds of the search the design lies on), ``counts`` and
        ``wall_time_s`` (:meth:`pmsm2dof.studies.autotune.AutotuneResult.as_dict`).

        Raises
        ------
        ConfigError
            Naming ``spec.<field>`` or the control key, or ``simulation.t_end_s`` when the search
            could take more than :data:`SUGGEST_STEPS_MAX` integration steps.
        """
        from ...studies.autotune import Spec
        from ...studies.autotune_search import autotune
        from ...studies.autotune_space import runs_bound

        for key in body:
            if key not in ("values", "spec"):
                raise ConfigError(key, body[key], "'values' (the control values) or 'spec' (the specification)")
        values, fields = body.get("values", {}), body.get("spec", {})
        for name, given in (("values", values), ("spec", fields)):
            if not isinstance(given, dict):
                raise ConfigError(name, given, "a JSON object")
        for key in fields:
            if key not in SUGGEST_SPEC_KEYS:
                raise ConfigError(f"spec.{key}", fields[key], "one of " + ", ".join(SUGGEST_SPEC_KEYS))
        try:
            spec = Spec(**fields)
        except ConfigError as exc:
            raise ConfigError(f"spec.{exc.param}", exc.value, exc.valid) from None
        scenario = self.scenario(values)
        sim, Ts_cl = scenario.simulation, scenario.current_loop.Ts_s
        h_s = Ts_cl / max(1, math.ceil(Ts_cl / sim.dt_s * (1.0 - 1e-9)))
        runs = runs_bound(scenario, spec)
        if sim.t_end_s / h_s * runs > SUGGEST_STEPS_MAX:
            raise ConfigError(
                "simulation.t_end_s",
                sim.t_end_s,
                f"<= {SUGGEST_STEPS_MAX / runs * h_s:.3g} s for a suggestion: the search may simulate the "
                f"experiment {runs} times, at most {SUGGEST_STEPS_MAX:.0e} integration steps of {h_s:g} s in "
                "all (pmsm2dof autotune runs longer ones)",
            )
        start = time.perf_counter()
        result = autotune(scenario, spec)
        out = result.as_dict()
        return {
            "feasible": result.feasible,
            "values": {f"speed_controller.{k}": v for k, v in result.speed_controller.items()},
            "worst_case": out["worst_case"],
            "worst_J_ratio": out["worst_J_ratio"],
            "violations": [v.describe() for v in result.chosen.violations]
            + ([result.chosen.error] if result.chosen.error else []),
            "binding": out["binding"],
            "on_bounds": out["on_bounds"],
            "counts": out["counts"],
            "wall_time_s": out["wall_time_s"],
            "server_ms": 1e3 * (time.perf_counter() - start),
        }

    # ---- downloads -------------------------------------------------------------------

    def download(self, kind: str, values: Mapping[str, Any], ticket: Ticket | None = None) -> tuple[str, str, str]:
        """``(filename, media type, text)`` of a download: scenario.toml, header.h or trace.csv.

        The trace is the run the page draws: the rows it logs (:meth:`logged`).
        """
        if kind == "scenario.toml":
            scenario = self.scenario(values)
            return f"{_slug(scenario.name)}-tuned.toml", "application/toml", scenario.to_toml()
        if kind == "header.h":
            scenario = self.scenario(values)
            # the engine's init runs the C controllers' init, which names the scenario key of any
            # value they reject; nothing is simulated
            return "p2d_config.h", "text/x-c", self._c_header(self.logged(scenario))
        if kind == "trace.csv":
            scenario, result = self._evaluate(values, ticket)
            return f"{_slug(scenario.name)}-trace.csv", "text/csv", result.to_dataframe().to_csv(index=False)
        raise ConfigError("download", kind, "one of 'scenario.toml', 'header.h', 'trace.csv'")

    @staticmethod
    def _c_header(scenario: Scenario) -> str:
        """The C configuration of the scenario's controllers (pmsm2dof.studies.configuration)."""
        return configuration(scenario, source="pmsm2dof tune (the tuner's download)").c_header()


def _metric_rows(figures: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The metrics table: the figures of every reference step, load step and fault in time order,
    then the whole run's; a figure that cannot be computed has ``value`` None and a ``reason``."""
    parts: list[tuple[float, str, int | None, str]] = []
    for part in ("reference_steps", "load_steps", "faults"):
        for k, event in enumerate(figures[part]):
            parts.append((event["t_s"], part, k, _event_title(part, event)))
    parts.sort(key=lambda p: p[0])  # stable: at equal times references, then loads, then faults
    run = figures["run"]
    parts.append((math.inf, "run", None, f"whole run (0 to {run['t_end_s']:g} s)"))
    rows = []
    for _, part, i, group in parts:
        event = figures[part] if i is None else figures[part][i]
        prefix = part if i is None else f"{part}.{i}"
        for key, label, unit in TABLE_METRICS[part]:
            figure = event[key]
            rows.append(
                {
                    "key": f"{prefix}.{key}",
                    "group": group,
                    "label": label,
                    "unit": unit,
                    "value": figure["value"],
                    "reason": figure.get("reason", ""),
                }
            )
    return rows


def _event_title(part: str, event: Mapping[str, Any]) -> str:
    if part == "reference_steps":
        return f"speed reference at {event['t_s']:g} s: {event['from_rpm']:g} \u2192 {event['to_rpm']:g} rpm"
    if part == "load_steps":
        return f"load at {event['t_s']:g} s: {event['from_Nm']:g} \u2192 {event['to_Nm']:g} Nm"
    return f"fault {event['kind']} at {event['t_s']:g} s to {event['end_s']:g} s"


def _warnings(figures: Mapping[str, Any], scenario: Scenario) -> list[str]:
    """Sentences the page shows above the metrics: the run left the design's assumptions (those of
    :func:`pmsm2dof.studies.loopcheck.measure` first)."""
    run = figures["run"]
    voltage_s = run["voltage_limit_time_s"]["value"]
    if not voltage_s:
        return list(figures["warnings"])
    u_max_V = scenario.limits.u_dc_V / math.sqrt(3.0)
    return [
        *figures["warnings"],
        f"Voltage limit: the inverter's range u_dc/\u221a3 = {u_max_V:.4g} V cut the voltage for "
        f"{voltage_s:.4g} s ({100.0 * voltage_s / run['t_end_s']:.3g} % of the run). There the currents do "
        "not follow their commands and the design (eq 3, 9) does not hold.",
    ]


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in name.lower()).strip("-") or "scenario"


def _label(scenario: Scenario) -> str:
    sc = scenario.speed_controller
    ka = "1/Kp" if sc.Ka is None else f"{sc.Ka:.4g}"
    J_ratio = scenario.motor.J_kgm2 / sc.J_kgm2
    return (
        f"\u03b1={sc.alpha_radps:.4g} \u03b6={sc.zeta:.4g} m={sc.m:.4g} Fr {sc.feedforward}, "
        f"AW {sc.anti_windup} Ka={ka}, {sc.method} Ts={sc.Ts_s:.4g} s, J/Jd={J_ratio:.3g}"
    )
