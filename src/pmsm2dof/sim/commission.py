"""Self-commissioning in simulation: the C routine of ``commission.h`` run against a scenario's motor.

The firmware routine ``p2d_commission`` (float32, once per current sample) aligns the rotor,
measures Rs from two DC current levels, Ld and Lq by square-wave injection at standstill and
psi_f from the back-EMF while an I-f frame turns the rotor. :func:`commission` runs that very
code, compiled, against the motor of a scenario simulated by the engine
(``csrc/sim/commission_run.c``: the dq model of eq 1 with the rotor's angle, an inverter with an
optional computation delay and dead-time error, noisy phase-current sensing), and compares the
estimates with the scenario's true values, so the routine is tested before it meets a motor.

The parameters are per phase in the amplitude-invariant dq frame, the convention of eq 1 and
the engine (``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``). The routine's settings are the
scenario's ``[commissioning]`` table; :func:`commissioning_config` derives the absent ones.
"""

import dataclasses
import math
from typing import Any

import numpy as np

from ..core.bindings import c_string, enum_names, ffi, lib
from ..core.motor import Motor
from ..errors import ConfigError, SimulationError
from .scenario import Scenario

__all__ = ["PHASES", "REASONS", "Commissioning", "commission", "commissioning_config", "ESTIMATES"]

#: Phases of the routine (``p2d_commission_phase_t``), in order.
PHASES = tuple(c_string(lib.p2d_commission_phase_name(i)) for i in range(lib.P2D_PHASE_COUNT))
#: Failure reasons (``p2d_commission_reason_t``).
REASONS = enum_names("p2d_commission_reason_t", "P2D_REASON_")
#: The identified quantities, as named in the scenario's ``[motor]`` table and the C routine.
ESTIMATES = ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")
#: Accuracy targets of the identification (issue 20): ``|estimate / truth - 1|`` at most this.
TARGETS = {"Rs_ohm": 0.05, "Ld_H": 0.10, "Lq_H": 0.05, "psi_f_Wb": 0.02}

#: Longest simulated commissioning [s]; a run that does not end within it stops.
T_MAX_S = 3600.0
#: Log rows are kept for one current sample in this many.
LOG_EVERY = 10
#: The scenario key behind each field of ``p2d_commission_config_t`` (for error messages).
_KEY_OF_FIELD = {"Ts_s": "current_loop.Ts_s", "voltage_delay_samples": "inverter.computation_delay"}
#: Peak torque of the I-f ramp as a share of the torque i_spin_A gives.
_RAMP_TORQUE_SHARE = 0.4
#: Alignment time in periods of the rotor held by i_test_A: the routine damps the swing, and a
#: rotor still creeping into place fails the Rs levels (4 periods left a third of the random machines
#: of pmsm2dof.studies.commissioning creeping)
_ALIGN_PERIODS = 12.0
#: Largest test current, by default, as a share of psi_f / (Lq - Ld): a d current on the frame's d
#: axis holds the rotor with the stiffness 1.5 p^2 i_d (psi_f - (Lq - Ld) i_d) [Nm/rad], which the
#: reluctance torque of a salient rotor turns negative above psi_f / (Lq - Ld): the rotor then
#: rests off the frame, where a change of the current moves it
_RELUCTANCE_SHARE = 0.5
#: Alignment time in time constants of the damped rotor's creep into place, psi_f / (Rs i_test_A):
#: the damping of the routine is the machine's own short circuit, which overdamps a machine whose
#: psi_f^2 / Rs is large against sqrt(stiffness J); its rotor then creeps, without swinging, at a
#: speed that falls by e over that time
_ALIGN_CREEP_TIMES = 8.0
#: Length of each Rs level in time constants Ld / Rs: the mean d voltage of a half-window holds
#: Ld (id_end - id_start) / t, the current noise's change over it, against Rs times the step of
#: i_test_A / 2; a window short against Ld / Rs lets it pass the 2 % of the rs_spread check
_LEVEL_TIME_CONSTANTS = 5.0
#: Back-EMF of the flux test as a share of the voltage range u_dc / sqrt(3).
_SPIN_EMF_SHARE = 0.2


def commissioning_config(scenario: Scenario) -> dict[str, float | int]:
    """The routine's configuration (fields of ``p2d_commission_config_t``) for a scenario.

    Given keys of ``[commissioning]`` are taken as they are; absent ones are derived from the
    scenario as a commissioning engineer would from the motor's rough data:

    - ``i_test_A = 0.4 i_max_A``, on a salient rotor at most ``0.5 psi_f / (Lq - Ld)`` (beyond
      ``psi_f / (Lq - Ld)`` the d-axis alignment is unstable: the reluctance torque wins);
      ``i_spin_A = i_test_A``, ``i_trip_A = 2 max(i_test_A, i_spin_A)``;
    - ``tau_i_s = 20 Ts_s`` (the routine's loop is designed from the inductance it measures first);
    - ``t_align_s``: the longest of twelve periods of the rotor held by i_test_A on d, whose
      stiffness is ``1.5 p^2 i_test_A (psi_f - (Lq - Ld) i_test_A)`` [Nm/rad] (at least half the
      magnet's), eight time constants ``psi_f / (Rs i_test_A)`` of the overdamped creep, and
      ``20 tau_i_s``;
    - ``t_level_s = max(50 tau_i_s, 0.05 s, 5 Ld / Rs)``;
    - ``w_e_spin_radps``: the speed whose back-EMF ``w_e psi_f`` is 0.2 of ``u_dc / sqrt(3)``
      (at most ``0.1 / Ts_s``);
    - ``t_ramp_s``: the S ramp to that speed whose peak acceleration needs 0.4 of the torque
      ``1.5 p psi_f i_spin_A`` (peak acceleration of the S ramp: ``2 w_m / t_ramp_s``), at
      least ``t_align_s``;
    - ``t_spin_s = max(t_align_s, 0.5 s, 20 tau_i_s)``;
    - ``voltage_delay_samples`` is 1 with ``inverter.computation_delay``, else 0.
    """
    motor, cm = scenario.motor, scenario.commissioning
    Ts = scenario.current_loop.Ts_s
    p, psi_f, J = motor.pole_pairs, motor.psi_f_Wb, motor.J_kgm2
    dL = motor.Lq_H - motor.Ld_H
    i_test = cm.i_test_A
    if i_test is None:
        i_test = 0.4 * scenario.limits.i_max_A
        if dL > 0.0:
            i_test = min(i_test, _RELUCTANCE_SHARE * psi_f / dL)
    i_spin = cm.i_spin_A if cm.i_spin_A is not None else i_test
    i_trip = cm.i_trip_A if cm.i_trip_A is not None else 2.0 * max(i_test, i_spin)
    tau_i = cm.tau_i_s if cm.tau_i_s is not None else 20.0 * Ts
    w_hold = math.sqrt(1.5 * p * p * i_test * max(psi_f - dL * i_test, 0.5 * psi_f) / J)
    t_creep = psi_f / (motor.Rs_ohm * i_test)
    t_align = (
        cm.t_align_s
        if cm.t_align_s is not None
        else max(_ALIGN_PERIODS * 2.0 * math.pi / w_hold, _ALIGN_CREEP_TIMES * t_creep, 20.0 * tau_i)
    )
    t_level = (
        cm.t_level_s
        if cm.t_level_s is not None
        else max(50.0 * tau_i, 0.05, _LEVEL_TIME_CONSTANTS * motor.Ld_H / motor.Rs_ohm)
    )
    if cm.w_e_spin_radps is not None:
        w_e_spin = cm.w_e_spin_radps
    else:
        w_e_spin = min(_SPIN_EMF_SHARE * scenario.limits.u_dc_V / math.sqrt(3.0) / psi_f, 0.1 / Ts)
    if cm.t_ramp_s is not None:
        t_ramp = cm.t_ramp_s
    else:
        torque = _RAMP_TORQUE_SHARE * 1.5 * p * psi_f * i_spin
        t_ramp = max(2.0 * J * (w_e_spin / p) / torque, t_align)
    t_spin = cm.t_spin_s if cm.t_spin_s is not None else max(t_align, 0.5, 20.0 * tau_i)
    return {
        "Ts_s": Ts,
        "i_test_A": i_test,
        "i_spin_A": i_spin,
        "i_trip_A": i_trip,
        "tau_i_s": tau_i,
        "t_align_s": t_align,
        "t_level_s": t_level,
        "t_inductance_s": cm.t_inductance_s,
        "t_ramp_s": t_ramp,
        "t_spin_s": t_spin,
        "w_e_spin_radps": w_e_spin,
        "voltage_delay_samples": 1 if scenario.inverter.computation_delay else 0,
    }


@dataclasses.dataclass(frozen=True)
class Commissioning:
    """The outcome of a simulated commissioning run.

    ``phase`` is ``"done"`` or ``"failed"``; after a failure ``failed_phase`` and ``reason``
    name the step and why, and ``reason_text`` says what to change. ``estimates`` holds the
    routine's Rs_ohm, Ld_H, Lq_H, psi_f_Wb (those of the finished steps after a failure, else
    NaN), ``truth`` the scenario's, ``phase_time_s`` the simulated time each step took,
    ``config`` the routine's configuration and ``log`` the signals of every ``LOG_EVERY``-th
    current sample (``t_s``, ``phase``, the measured currents and the voltage command in the
    routine's frame, the frame's and the rotor's electrical speed, the rotor's angle off the frame).
    """

    scenario: str
    phase: str
    failed_phase: str | None
    reason: str | None
    reason_text: str
    estimates: dict[str, float]
    truth: dict[str, float]
    phase_time_s: dict[str, float]
    config: dict[str, float | int]
    checks: dict[str, float]
    log: dict[str, np.ndarray] = dataclasses.field(repr=False)

    @property
    def errors(self) -> dict[str, float]:
        """Relative error estimate / truth - 1 of each estimate (NaN when not estimated)."""
        return {k: self.estimates[k] / self.truth[k] - 1.0 for k in ESTIMATES}

    @property
    def within_targets(self) -> bool:
        """True if the run ended DONE and every estimate is within :data:`TARGETS`."""
        return self.phase == "done" and all(abs(e) <= TARGETS[k] for k, e in self.errors.items())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no log): identified vs true values, errors, time per step."""
        return {
            "scenario": self.scenario,
            "phase": self.phase,
            "failed_phase": self.failed_phase,
            "reason": self.reason,
            "reason_text": self.reason_text,
            "estimates": {k: _json_float(v) for k, v in self.estimates.items()},
            "truth": {k: _json_float(v) for k, v in self.truth.items()},
            "relative_errors": {k: _json_float(v) for k, v in self.errors.items()},
            "targets": TARGETS,
            "within_targets": self.within_targets,
            "phase_time_s": self.phase_time_s,
            "total_time_s": sum(self.phase_time_s.values()),
            "checks": {k: _json_float(v) for k, v in self.checks.items()},
            "config": self.config,
        }

    def motor_toml(self, pole_pairs: int) -> str:
        """The identified motor as a motor file (``[motor]`` table) for ``pmsm2dof design --motor``.

        Raises
        ------
        SimulationError
            The run did not end DONE: there is no identified motor to write.
        """
        if self.phase != "done":
            raise SimulationError(f"commissioning failed in {self.failed_phase} ({self.reason}): no motor to write")
        e = self.estimates
        motor = Motor(pole_pairs, Rs_ohm=e["Rs_ohm"], Ld_H=e["Ld_H"], Lq_H=e["Lq_H"], psi_f_Wb=e["psi_f_Wb"])
        return motor.motor_file(
            [
                f"identified by the commissioning routine (commission.h) on scenario {self.scenario!r}",
                "per phase, amplitude-invariant dq (eq 1)",
            ]
        )

    def log_csv(self) -> str:
        """The log as CSV text, one column per signal (``phase`` as its index in :data:`PHASES`)."""
        names = list(self.log)
        rows = np.column_stack([self.log[n] for n in names])
        lines = [",".join(names)]
        lines += [",".join(repr(float(v)) for v in row) for row in rows]
        return "\n".join(lines) + "\n"


def _json_float(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _raise_run_status(status: int, run: Any, cfg: Any) -> None:
    """Raise the ConfigError or SimulationError of a p2d_commission_run* status."""
    param = c_string(lib.p2d_crun_status_param(status))
    text = c_string(lib.p2d_crun_status_text(status))
    if status == lib.P2D_CRUN_ERR_COMMISSIONING:
        field = c_string(lib.p2d_status_param(run.commission_status))
        value = getattr(cfg.commissioning, field) if field else None
        key = _KEY_OF_FIELD.get(field, f"commissioning.{field}")
        raise ConfigError(key, value, c_string(lib.p2d_status_range(run.commission_status)))
    if status >= lib.P2D_CRUN_STOP_NONFINITE:
        raise SimulationError(f"commissioning run stopped: {text}")
    raise ConfigError(param, None, text)


def commission(scenario: Scenario, log_every: int = LOG_EVERY) -> Commissioning:
    """Run the C commissioning routine against the scenario's motor; compare with the truth.

    Parameters
    ----------
    scenario : Scenario
        The motor (``[motor]``), DC link (``limits.u_dc_V``), current sampling
        (``current_loop.Ts_s``), computation delay (``inverter``) and the ``[commissioning]``
        table (the routine's settings, and the simulated rotor's angle and load, dead time and
        current noise).
    log_every : int
        Keep one log row for this many current samples (>= 1).

    Returns
    -------
    Commissioning
        Estimates vs truth, the step that failed if any, the time of each step.

    Raises
    ------
    ConfigError
        A setting the routine rejects (named as its scenario key) or a bad ``log_every``.
    SimulationError
        The simulated plant went non-finite, or the routine did not end within ``T_MAX_S``.
    """
    if isinstance(log_every, bool) or not isinstance(log_every, int) or log_every < 1:
        raise ConfigError("log_every", log_every, "an integer >= 1")
    motor, cm = scenario.motor, scenario.commissioning
    routine = commissioning_config(scenario)
    cfg = ffi.new("p2d_crun_config_t *")
    cfg.motor.pole_pairs = motor.pole_pairs
    for key in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb", "J_kgm2", "B_Nms", "T_coulomb_Nm"):
        setattr(cfg.motor, key, getattr(motor, key))
    cfg.u_dc_V = scenario.limits.u_dc_V
    cfg.computation_delay = scenario.inverter.computation_delay
    cfg.substeps = max(1, math.ceil(scenario.current_loop.Ts_s / scenario.simulation.dt_s * (1.0 - 1e-9)))
    cfg.log_every = log_every
    for key in ("dead_time_V", "noise_A", "seed", "theta0_rad", "T_load_Nm"):
        setattr(cfg, key, getattr(cm, key))
    for key, value in routine.items():
        setattr(cfg.commissioning, key, value)
    run = ffi.new("p2d_crun_t *")
    status = lib.p2d_commission_run_init(run, cfg)
    if status != lib.P2D_CRUN_OK:
        _raise_run_status(status, run, cfg)

    Ts = float(cfg.commissioning.Ts_s)
    max_samples = math.ceil(T_MAX_S / Ts)
    rows = -(-max_samples // log_every)
    # the log grows with the run: start with the nominal length and rerun into a larger buffer if needed
    nominal = (routine["t_align_s"] + 2 * routine["t_level_s"] + 2 * routine["t_ramp_s"] + routine["t_spin_s"]) / Ts
    rows = min(rows, -(-int(2 * nominal + 100_000) // log_every))
    while True:
        buffer = np.empty((lib.P2D_CLOG_COUNT, rows))
        status = lib.p2d_commission_run(run, max_samples, ffi.cast("double *", buffer.ctypes.data), rows)
        if status != lib.P2D_CRUN_ERR_LOG_FULL:
            break
        rows *= 4
        status = lib.p2d_commission_run_init(run, cfg)
    if status == lib.P2D_CRUN_STOP_TIMEOUT:
        raise SimulationError(f"commissioning did not end within {T_MAX_S:g} s of simulated time")
    if status != lib.P2D_CRUN_OK:
        _raise_run_status(status, run, cfg)

    r = run.routine
    n_rows = int(run.n_rows)
    log = {c_string(lib.p2d_crun_log_name(i)): buffer[i, :n_rows].copy() for i in range(lib.P2D_CLOG_COUNT)}
    starts = [int(s) for s in run.phase_start]
    end = int(run.n)
    phase_time_s = {}
    for i in range(lib.P2D_PHASE_DONE):
        if starts[i] == 2**64 - 1:
            continue
        later = [s for s in starts[i + 1 : lib.P2D_PHASE_DONE] if s != 2**64 - 1]
        phase_time_s[PHASES[i]] = ((min(later) if later else end) - starts[i]) * Ts
    done = r.phase == lib.P2D_PHASE_DONE
    estimates = {k: float(getattr(r, k)) for k in ESTIMATES}
    if not done:
        # a failed run keeps the estimates of its finished steps only
        finished = {"Rs_ohm": lib.P2D_PHASE_LD, "Ld_H": lib.P2D_PHASE_RAMP_UP, "Lq_H": lib.P2D_PHASE_RAMP_UP}
        for k in ESTIMATES:
            if r.failed_phase < finished.get(k, lib.P2D_PHASE_DONE):
                estimates[k] = math.nan
    checks = {
        k: float(getattr(r, k))
        for k in ("u_err_V", "rs_spread", "uq_ratio", "asymmetry", "coherence", "psi_spread", "slip", "L_probe_H")
    }
    return Commissioning(
        scenario=scenario.name,
        phase=PHASES[r.phase],
        failed_phase=None if done else PHASES[r.failed_phase],
        reason=None if done else REASONS[r.reason],
        reason_text=c_string(lib.p2d_commission_reason_text(r.reason)),
        estimates=estimates,
        truth={k: float(getattr(motor, k)) for k in ESTIMATES},
        phase_time_s=phase_time_s,
        config=routine,
        checks=checks,
        log=log,
    )
