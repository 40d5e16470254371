"""What the tuner computes: from control values to a scenario, a run, plot data and downloads.

The tuner's experiment is the paper's simulation condition 2 reduced to its two events
(section 4.1): a speed reference step at ``reference.0.t_s`` of the base scenario, then a load
torque step at ``tuner.t_load_s``. The controls are

- scenario keys, applied as overrides of the base scenario (``speed_controller.alpha``,
  ``zeta``, ``m``, ``Ka``, ``feedforward``, ``anti_windup``, ``discretization``, ``Ts_s``,
  ``simulation.t_end_s``), and
- the experiment's own keys: ``tuner.J_ratio`` (true inertia / design inertia: the design
  inertia stays that of the base scenario and ``motor.J_kgm2`` follows the ratio),
  ``tuner.speed_step_rpm``, ``tuner.load_step_Nm`` and ``tuner.t_load_s``.

Every request is validated by :meth:`pmsm2dof.scenario.Scenario.with_overrides`, exactly like
a scenario file, after the experiment's keys are checked here; errors name the control key.

The work of one run is bounded: at most :data:`STEPS_MAX` plant integration steps (a longer
``simulation.t_end_s`` answers a ConfigError naming the bound), and ``simulation.log_every`` is
raised so that the run logs at most :data:`LOG_ROWS_MAX` rows (the plots draw a thousand points a
trace; the metrics and the trace download are those of the logged rows). A run is simulated in
chunks of about :data:`CHUNK_STEPS` steps and stops between two of them when a newer request of
the same client supersedes it (:mod:`pmsm2dof.tuner.slots`).
"""

import collections
import functools
import json
import math
import threading
import time

import control
import numpy as np

from ..codegen import c_header
from ..controllers import ANTI_WINDUPS, FEEDFORWARDS, METHODS
from ..design import design
from ..errors import ConfigError, require_nonnegative, require_positive
from ..metrics import compute_metrics
from ..simulate import Result, _EngineRun
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

SCENARIO_CONTROLS = (
    "speed_controller.alpha",
    "speed_controller.zeta",
    "speed_controller.m",
    "speed_controller.Ka",
    "speed_controller.feedforward",
    "speed_controller.anti_windup",
    "speed_controller.discretization",
    "speed_controller.Ts_s",
    "simulation.t_end_s",
)
TUNER_CONTROLS = ("tuner.J_ratio", "tuner.speed_step_rpm", "tuner.load_step_Nm", "tuner.t_load_s")
CONTROLS = SCENARIO_CONTROLS + TUNER_CONTROLS
#: Rows of the metrics table: (step, key of pmsm2dof.metrics, label, unit).
TABLE_METRICS = (
    ("step", "overshoot_pct", "overshoot", "%"),
    ("step", "rise_time_s", "rise time 10-90 %", "s"),
    ("step", "settling_time_s", "settling time 2 %", "s"),
    ("step", "current_limit_time_s", "time at the current limit", "s"),
    ("load", "speed_dip_rpm", "load dip", "rpm"),
    ("load", "recovery_time_s", "recovery time 2 %", "s"),
)


def minmax_indices(y, buckets=DECIMATION_BUCKETS):
    """Indices of the samples of ``y`` that min-max decimation keeps, sorted.

    The samples are split into ``buckets`` consecutive runs of equal length; of each run the
    samples holding the minimum and the maximum are kept, plus the first and the last sample,
    so at most ``2 * buckets + 2`` remain and the extremes of the whole trace (the overshoot,
    the load dip) are kept exactly. Short traces are kept whole.
    """
    y = np.asarray(y, dtype=float)
    n = len(y)
    if n <= 2 * buckets + 2:
        return np.arange(n)
    width = -(-n // buckets)  # ceil(n / buckets)
    padded = np.concatenate([y, np.full(width * buckets - n, y[-1])]).reshape(buckets, width)
    offsets = np.arange(buckets) * width
    i_min = np.minimum(offsets + np.argmin(padded, axis=1), n - 1)
    i_max = np.minimum(offsets + np.argmax(padded, axis=1), n - 1)
    return np.unique(np.concatenate([[0, n - 1], i_min, i_max]))


def _trace(t, y):
    keep = minmax_indices(y)
    return {"t": np.asarray(t)[keep].tolist(), "y": np.asarray(y)[keep].tolist()}


def loop_on_plant(dsg, J_true_kgm2):
    """Tracking and load transfer functions of the designed controller on the true inertia.

    The controller (``F``, ``Fr``) is designed for ``dsg.J_kgm2``; the plant has the inertia
    ``J_true_kgm2``: ``Gm = 1 / (J_true s)``, ``G = Gci Gm`` (eq 2, 3). Then
    ``Gx = (Fr + F) G / (1 + F G)`` (eq 6) and ``GN = -Gm / (1 + F Gci Gm)`` (eq 5 with the
    load entering at the mechanics, Fig. 6, which is eq 8). For ``J_true == dsg.J_kgm2``
    these are ``dsg.Gx`` and ``dsg.GN``.

    Returns
    -------
    Gx, GN : control.TransferFunction
        Speed over reference [-] and speed [rad/s] over load torque [Nm].
    """
    Gm = control.tf([1.0], [J_true_kgm2, 0.0])
    G = dsg.Gci * Gm
    Gx = ((dsg.Fr + dsg.F) * control.feedback(G, dsg.F)).minreal()
    GN = -control.feedback(Gm, dsg.F * dsg.Gci)
    return Gx, GN


def bode_data(Gx, GN, alpha_radps, Ts_s):
    """Magnitude [dB] and unwrapped phase [deg] of ``Gx`` and ``GN`` around ``alpha_radps``.

    ``w_nyquist_radps = pi / Ts_s`` marks where the sampled controller stops following the
    continuous design.
    """
    below, above = BODE_DECADES
    w = np.logspace(math.log10(alpha_radps) - below, math.log10(alpha_radps) + above, BODE_POINTS)
    out = {"w_radps": w.tolist(), "w_nyquist_radps": math.pi / Ts_s}
    for name, sys in (("Gx", Gx), ("GN", GN)):
        h = np.asarray(control.frequency_response(sys, w).complex).reshape(-1)
        # a zero of the response on the grid would be -inf dB, which JSON cannot carry
        out[f"{name}_dB"] = (20.0 * np.log10(np.maximum(np.abs(h), 1e-300))).tolist()
        out[f"{name}_deg"] = np.degrees(np.unwrap(np.angle(h))).tolist()
    return out


def design_of(scenario):
    """The :class:`~pmsm2dof.design.Design` of a scenario's speed controller (eq 9-13)."""
    sc = scenario.data["speed_controller"]
    return design(sc["J_design_kgm2"], sc["alpha"], sc["zeta"], m=sc["m"], tau_i_s=sc["tau_i_design_s"],
                  feedforward=sc["feedforward"], anti_windup=sc["anti_windup"], Ka=sc["Ka"])


class Tuner:
    """The tuner's computations for one base scenario.

    Parameters
    ----------
    base : pmsm2dof.scenario.Scenario
        Motor, limits, current loop, initial controller settings and timing.
    """

    def __init__(self, base):
        self.base = base
        data = base.data
        self._J_design_kgm2 = data["speed_controller"]["J_design_kgm2"]
        self._t_ref_s = data["reference"][0]["t_s"]
        self._initial = self._initial_values(data)
        self._cache = collections.OrderedDict()
        self._cache_lock = threading.Lock()
        self._bode_cached = functools.lru_cache(maxsize=CACHED_RUNS)(self._bode_uncached)

    # ---- controls -------------------------------------------------------------------

    def _initial_values(self, data):
        sc, sim = data["speed_controller"], data["simulation"]
        steps = [r["speed_rpm"] for r in data["reference"] if r["speed_rpm"] != 0.0]
        loads = [entry for entry in data["load"] if entry["torque_Nm"] != 0.0]
        values = {f"speed_controller.{k}": sc[k] for k in
                  ("alpha", "zeta", "m", "Ka", "feedforward", "anti_windup", "discretization", "Ts_s")}
        values.update({
            "simulation.t_end_s": sim["t_end_s"],
            "tuner.J_ratio": data["motor"]["J_kgm2"] / self._J_design_kgm2,
            "tuner.speed_step_rpm": steps[0] if steps else 0.0,
            "tuner.load_step_Nm": loads[0]["torque_Nm"] if loads else 0.0,
            "tuner.t_load_s": loads[0]["t_s"] if loads else self._t_ref_s + 0.6 * (sim["t_end_s"] - self._t_ref_s),
        })
        return values

    def controls(self):
        """Description of the page's controls: groups of specs with ranges and initial values.

        A spec has ``key``, ``label``, ``unit``, ``kind`` ('slider' or 'select'), ``value``;
        sliders have ``min``, ``max``, ``scale`` ('lin' or 'log') and optionally ``quantum``
        (values are integer multiples of it) and ``nullable`` (a checkbox sends null);
        ``enabled_when = [key, [choices]]`` disables a control unless another has one of the
        choices (``value_when_disabled`` is then sent). Ranges are only those of the sliders:
        any value can be typed, and the server validates it.
        """
        v = self._initial
        data = self.base.data
        motor, limits = data["motor"], data["limits"]
        alpha = v["speed_controller.alpha"]
        Kp = self._J_design_kgm2 * alpha
        Ts_cl = data["current_loop"]["Ts_s"]
        torque_max_Nm = 1.5 * motor["pole_pairs"] * motor["psi_f_Wb"] * limits["i_max_A"]
        step = abs(v["tuner.speed_step_rpm"]) or 500.0
        t_end = v["simulation.t_end_s"]

        def slider(key, label, unit, lo, hi, scale="lin", **extra):
            return dict(key=key, label=label, unit=unit, kind="slider", min=lo, max=hi, scale=scale,
                        value=v[key], **extra)

        def select(key, label, choices, **extra):
            return dict(key=key, label=label, unit="", kind="select", choices=list(choices), value=v[key], **extra)

        groups = [
            {"legend": "PI design (eq 9, 10)", "controls": [
                slider("speed_controller.alpha", "\u03b1 bandwidth", "rad/s", alpha / 10, alpha * 10, "log"),
                slider("speed_controller.zeta", "\u03b6 damping", "", 0.1, 2.0, "log"),
                slider("speed_controller.m", "m tracking pole", "", 0.1, 10.0, "log",
                       enabled_when=["speed_controller.feedforward", ["no_tau", "full"]],
                       value_when_disabled=1.0,
                       help="Gx = m alpha / (s + m alpha) (eq 10); lowpass is m = 1 (eq 13)"),
                select("speed_controller.feedforward", "feedforward Fr", FEEDFORWARDS,
                       help="none: 1DOF PI; lowpass: eq 13/15; no_tau: eq 11 with tau_i = 0; full: eq 11"),
            ]},
            {"legend": "Anti-windup (Fig. 5)", "controls": [
                select("speed_controller.anti_windup", "anti-windup", ANTI_WINDUPS),
                slider("speed_controller.Ka", "Ka", "(rad/s)/Nm", 0.03 / Kp, 30.0 / Kp, "log",
                       nullable=True, null_label="1/Kp (paper default)", default_position=1.0 / Kp,
                       enabled_when=["speed_controller.anti_windup", ["back_calculation"]],
                       value_when_disabled=None),
            ]},
            {"legend": "Digital implementation (Table 1)", "controls": [
                select("speed_controller.discretization", "discretization", METHODS),
                slider("speed_controller.Ts_s", "Ts speed loop", "s", Ts_cl,
                       max(1000 * Ts_cl, 10 * v["speed_controller.Ts_s"]), "log", quantum=Ts_cl,
                       help=f"an integer multiple of the current-loop period {Ts_cl:g} s"),
            ]},
            {"legend": "Experiment", "controls": [
                slider("tuner.J_ratio", "true J / design J", "", 0.25, 4.0, "log",
                       help=f"design inertia {self._J_design_kgm2:g} kg m^2 stays; the plant's changes"),
                slider("tuner.speed_step_rpm", "speed step", "rpm", 0.0, 3 * step,
                       help=f"reference step at t = {self._t_ref_s:g} s"),
                slider("tuner.load_step_Nm", "load step", "Nm", -torque_max_Nm, torque_max_Nm),
                slider("tuner.t_load_s", "load step at", "s", 0.0, t_end),
                slider("simulation.t_end_s", "simulated time", "s", t_end / 10, t_end * 10, "log"),
            ]},
        ]
        return {"name": self.base.name, "groups": groups}

    # ---- request -> scenario ---------------------------------------------------------

    def scenario(self, values):
        """The validated scenario of the control ``values`` (missing keys keep their initial value).

        Raises
        ------
        ConfigError
            Naming the control key, its value and the valid range.
        """
        for key, value in values.items():
            if key not in CONTROLS:
                raise ConfigError(key, value, "one of the tuner's controls: " + ", ".join(CONTROLS))
        v = dict(self._initial, **values)
        J_ratio = require_positive("tuner.J_ratio", v["tuner.J_ratio"])
        step_rpm = _require_finite("tuner.speed_step_rpm", v["tuner.speed_step_rpm"])
        load_Nm = _require_finite("tuner.load_step_Nm", v["tuner.load_step_Nm"])
        t_load_s = require_nonnegative("tuner.t_load_s", v["tuner.t_load_s"])
        overrides = {key: v[key] for key in SCENARIO_CONTROLS}
        t_end_s = overrides["simulation.t_end_s"]
        if isinstance(t_end_s, (int, float)) and not isinstance(t_end_s, bool) and t_load_s >= t_end_s:
            raise ConfigError("tuner.t_load_s", t_load_s, f">= 0 and < simulation.t_end_s = {t_end_s!r}")
        overrides.update({
            "motor.J_kgm2": J_ratio * self._J_design_kgm2,
            "speed_controller.J_design_kgm2": self._J_design_kgm2,
            "reference": [{"t_s": self._t_ref_s, "speed_rpm": step_rpm}],
            "load": [{"t_s": t_load_s, "torque_Nm": load_Nm}],
        })
        return self.base.with_overrides(overrides)

    @staticmethod
    def logged(scenario):
        """The scenario as the tuner simulates it: ``simulation.log_every`` raised to log at most
        :data:`LOG_ROWS_MAX` rows.

        Raises
        ------
        ConfigError
            Naming ``simulation.t_end_s`` when the run would take more than :data:`STEPS_MAX`
            plant integration steps.
        """
        data = scenario.data
        sim, Ts_cl = data["simulation"], data["current_loop"]["Ts_s"]
        # the engine's integration step: current_loop.Ts_s / ceil(current_loop.Ts_s / dt_s) (pmsm2dof.simulate)
        h_s = Ts_cl / max(1, math.ceil(Ts_cl / sim["dt_s"] * (1.0 - 1e-9)))
        if sim["t_end_s"] > STEPS_MAX * h_s:
            raise ConfigError("simulation.t_end_s", sim["t_end_s"],
                              f"<= {STEPS_MAX * h_s:g} s in the tuner: at most {STEPS_MAX:.0e} plant integration "
                              f"steps of {h_s:g} s per run (pmsm2dof simulate runs longer ones)")
        n_samples = math.floor(sim["t_end_s"] / data["speed_controller"]["Ts_s"] + 1e-9) + 1
        log_every = max(sim["log_every"], -(-n_samples // LOG_ROWS_MAX))
        return scenario.with_overrides({"simulation.log_every": log_every})

    # ---- runs ------------------------------------------------------------------------

    def _evaluate(self, values, ticket=None):
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
    def _simulate(scenario, ticket):
        """:func:`pmsm2dof.simulate` in chunks of about :data:`CHUNK_STEPS` steps, stopping with
        :class:`~pmsm2dof.tuner.slots.Superseded` between two when ``ticket`` is cancelled."""
        run = _EngineRun(scenario.data)
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
        return Result(scenario=scenario, wall_time_s=wall_time_s, **run.signals())

    def run(self, values, ticket=None):
        """Run the experiment; return what the page draws (JSON-ready dict).

        Keys: ``traces`` (decimated ``{"t", "y"}`` of speed_ref_rpm, speed_rpm, iq_ref_A,
        id_ref_A), ``load_detail`` (speed and reference from shortly before the load step,
        decimated on their own so that the dip keeps its full resolution), ``bode``,
        ``metrics`` (list of ``{key, label, unit, value}``), ``design`` (Kp, Ki, Ka),
        ``log`` (every, period_s, rows), ``i_max_A``, ``t_load_s``, ``load_step_Nm``, ``label``
        and ``server_ms``.

        Raises
        ------
        ConfigError, SimulationError
            Bad control values, a run over the bound, a run that stopped.
        pmsm2dof.tuner.slots.Superseded
            ``ticket`` was cancelled by a newer request of its client.
        """
        t0 = time.perf_counter()
        scenario, result = self._evaluate(values, ticket)
        data = result.scenario.data
        dsg = design_of(scenario)
        t = np.asarray(result.t_s)
        t_load_s = data["load"][0]["t_s"]
        t_end_s = data["simulation"]["t_end_s"]
        traces = {name: _trace(t, getattr(result, name))
                  for name in ("speed_ref_rpm", "speed_rpm", "iq_ref_A", "id_ref_A")}
        pre_s = 0.1 * (t_end_s - t_load_s)
        window = np.flatnonzero(t >= t_load_s - pre_s)
        speed_w = np.asarray(result.speed_rpm)[window]
        ref_w = np.asarray(result.speed_ref_rpm)[window]
        keep = window[np.union1d(minmax_indices(speed_w), minmax_indices(ref_w))]
        load_detail = {"t": t[keep].tolist(), "speed_rpm": np.asarray(result.speed_rpm)[keep].tolist(),
                       "speed_ref_rpm": np.asarray(result.speed_ref_rpm)[keep].tolist()}
        # everything the Bode plot depends on: computed, and redrawn by the page, when it changes
        bode_key = json.dumps([dsg.J_kgm2, dsg.alpha_radps, dsg.zeta, dsg.m, dsg.tau_i_s, dsg.feedforward,
                               data["motor"]["J_kgm2"], data["speed_controller"]["Ts_s"]])
        log_every = data["simulation"]["log_every"]
        out = {
            "label": _label(data),
            "traces": traces,
            "load_detail": load_detail,
            "bode": self._bode_cached(bode_key),
            "metrics": self._metrics(result),
            "design": {"Kp": dsg.Kp, "Ki": dsg.Ki, "Ka": dsg.Ka},
            "log": {"every": log_every, "period_s": log_every * data["speed_controller"]["Ts_s"], "rows": len(t)},
            "i_max_A": data["limits"]["i_max_A"],
            "t_load_s": t_load_s,
            "load_step_Nm": data["load"][0]["torque_Nm"],
        }
        out["server_ms"] = 1e3 * (time.perf_counter() - t0)
        return out

    @staticmethod
    def _bode_uncached(key):
        J_design_kgm2, alpha_radps, zeta, m, tau_i_s, feedforward, J_true_kgm2, Ts_s = json.loads(key)
        dsg = design(J_design_kgm2, alpha_radps, zeta, m=m, tau_i_s=tau_i_s, feedforward=feedforward)
        Gx, GN = loop_on_plant(dsg, J_true_kgm2)
        return bode_data(Gx, GN, alpha_radps, Ts_s) | {"key": key}

    @staticmethod
    def _metrics(result):
        """The metrics table: the speed step's and the load step's figures (pmsm2dof.metrics).

        A figure that cannot be computed has ``value`` None and a ``reason``.
        """
        figures = compute_metrics(result)
        step, load = figures["reference_steps"][0], figures["load_steps"][0]
        rows = []
        for source, key, label, unit in TABLE_METRICS:
            figure = (step if source == "step" else load)[key]
            rows.append({"key": f"{source}.{key}", "label": label, "unit": unit, "value": figure["value"],
                         "reason": figure.get("reason", "")})
        return rows

    # ---- downloads -------------------------------------------------------------------

    def download(self, kind, values, ticket=None):
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
            _EngineRun(self.logged(scenario).data)
            return "pmsm2dof_speed_config.h", "text/x-c", self._c_header(scenario)
        if kind == "trace.csv":
            scenario, result = self._evaluate(values, ticket)
            return f"{_slug(scenario.name)}-trace.csv", "text/csv", result.to_dataframe().to_csv(index=False)
        raise ConfigError("download", kind, "one of 'scenario.toml', 'header.h', 'trace.csv'")

    @staticmethod
    def _c_header(scenario):
        """C header of the scenario's speed and current controllers (pmsm2dof.codegen)."""
        data = scenario.data
        motor, sc, cl = data["motor"], data["speed_controller"], data["current_loop"]
        discrete = design_of(scenario).discretize(sc["Ts_s"], sc["discretization"])
        return c_header(discrete, i_max_A=data["limits"]["i_max_A"], pole_pairs=motor["pole_pairs"],
                        psi_f_Wb=motor["psi_f_Wb"], Ld_H=motor["Ld_H"], Lq_H=motor["Lq_H"], Rs_ohm=motor["Rs_ohm"],
                        Ts_current_s=cl["Ts_s"], current_method=cl["discretization"],
                        current_anti_windup=cl["anti_windup"], decouple=cl["decouple"])


def _require_finite(param, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(param, value, "a finite number")
    return float(value)


def _slug(name):
    return "".join(c if c.isalnum() else "-" for c in name.lower()).strip("-") or "scenario"


def _label(data):
    sc = data["speed_controller"]
    ka = "1/Kp" if sc["Ka"] is None else f"{sc['Ka']:.4g}"
    J_ratio = data["motor"]["J_kgm2"] / sc["J_design_kgm2"]
    return (f"\u03b1={sc['alpha']:.4g} \u03b6={sc['zeta']:.4g} m={sc['m']:.4g} Fr {sc['feedforward']}, "
            f"AW {sc['anti_windup']} Ka={ka}, {sc['discretization']} Ts={sc['Ts_s']:.4g} s, J/Jd={J_ratio:.3g}")
