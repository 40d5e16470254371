"""Scenarios: the drive, the controller and the test sequence of one simulation, as TOML.

A scenario file describes the motor (paper eq 1), the limits, the current loop (eq 3 or the
dq current controllers of Fig. 1), the speed controller (eq 9-15, Fig. 5 and 6), and the speed
reference and load torque schedules of a run (section 4.1)::

    name = "paper condition 2"
    [motor]
    pole_pairs = 4
    Rs_ohm = 0.5
    ...
    [[reference]]
    t_s = 0.0
    speed_rpm = 500.0

The motor may be given in datasheet units instead, as a ``[motor.datasheet]`` table (Kt, Ke or Kv,
line-to-line R and L, poles, sinusoidal or block commutation: see :mod:`pmsm2dof.core.motor`); it
provides ``pole_pairs``, ``Rs_ohm``, ``Ld_H``, ``Lq_H`` and ``psi_f_Wb`` (and the ratings it gives,
``i_rated_A``, ``i_peak_A``, ``J_rotor_kgm2``), which :meth:`Scenario.to_toml` writes as converted.

An optional ``[mechanics]`` table makes the load a two-mass drive train (the paper's conclusion:
motor and load inertia coupled by an elastic shaft), and ``[speed_filter]`` puts a notch and a
low-pass on the speed controller's torque command; both absent, the drive is the paper's.

Optional ``[[fault]]`` entries make the simulator play a fault: a DC-link sag over a window, or a
speed-sensor reading held, zero or wrong for one sample (see :data:`pmsm2dof.core.FAULT_KINDS`).

Every key, its type, valid range, default and meaning is declared once, in :data:`SCHEMA`; that
table drives validation, the defaults filled into :attr:`Scenario.data`, :meth:`Scenario.to_toml`
and :func:`schema_reference`. A bad file raises :class:`~pmsm2dof.errors.ConfigError` naming the
dotted key (``motor.J_kgm2``, ``reference.1.t_s``) and its valid range.

The paper's eq (1) writes ``Te = p0 (psi_f iq + ...)`` and calls p0 the number of poles while
using it as pole pairs; here ``motor.pole_pairs`` is the number of pole pairs and the torque is
amplitude invariant, ``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``.
"""

import copy
import dataclasses
import difflib
import importlib.resources
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..core import (
    ANTI_WINDUPS,
    ARITHMETICS,
    CURRENT_LOOP_MODELS,
    ESTIMATORS,
    FAULT_KINDS,
    FEEDBACKS,
    FEEDFORWARDS,
    LOG_RATES,
    MECHANICS_MODELS,
    METHODS,
    SPEED_SENSOR_MODELS,
)
from ..core.motor import DATASHEET_KEYS, motor_from_table
from ..errors import ConfigError, is_integer, is_real
from ..inputs import parse_toml, read_toml

#: Longest simulated time of one scenario [s] (ten hours).
T_END_MAX_S = 36000.0

#: Longest delay of the speed reading in current periods (the engine's P2D_SIM_HISTORY - 2).
SENSOR_DELAY_MAX_PERIODS = 2046

#: Relative tolerance of "speed_controller.Ts_s is an integer multiple of current_loop.Ts_s".
TS_MULTIPLE_RTOL = 1e-9

#: A scenario as nested tables: ``{key: value, table: {key: value}, array: [{key: value}]}``.
Tree = dict[str, Any]


class _Placeholder:
    """A value shown in error messages by its name, such as ``<missing>``."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


#: Marks a key without a default (and a missing value in error messages).
REQUIRED = _Placeholder("<missing>")
_TABLE = _Placeholder("<table>")
_ARRAY = _Placeholder("<array>")


@dataclasses.dataclass(frozen=True)
class SameAs:
    """A default taken from another key of the same scenario (``"motor.J_kgm2"``)."""

    key: str


@dataclasses.dataclass(frozen=True)
class Field:
    """One key of the scenario schema.

    ``key`` is the dotted path; keys of the entries of an array of tables are written
    ``"reference[].t_s"``. ``kind`` is ``float``, ``int``, ``bool`` or ``str``. ``default`` is
    :data:`REQUIRED`, a value, ``None`` (optional, no value: see ``doc``) or a :class:`SameAs`.
    Numbers are bounded by ``gt``/``ge``/``lt``/``le`` and must be finite; strings may be
    restricted to ``choices``.
    """

    key: str
    kind: type
    doc: str
    default: object = REQUIRED
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] = ()

    @property
    def leaf(self) -> str:
        return self.key.rsplit(".", 1)[-1]

    @property
    def parent(self) -> str:
        return self.key.rsplit(".", 1)[0] if "." in self.key else ""

    def valid_range(self) -> str:
        """The valid range in words, as shown in error messages."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            return f"a string of at most {STRING_CHARS_MAX} characters"
        limits = ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le))
        bounds = [f"{op} {v:g}" if isinstance(v, float) else f"{op} {v}" for op, v in limits if v is not None]
        noun = "an integer" if self.kind is int else "a finite number"
        return " ".join([noun, " and ".join(bounds)]) if bounds else noun

    def check(self, dotted: str, value: Any) -> Any:
        """Return ``value`` converted to the field's type, or raise ConfigError naming ``dotted``."""
        # numpy scalars (np.float32(0.4), np.int64(4)) are numbers too, stored as Python's
        if self.kind is float:
            if not is_real(value):
                raise ConfigError(dotted, value, self.valid_range())
            try:
                value = float(value)
            except OverflowError:
                raise ConfigError(dotted, value, self.valid_range()) from None
            if not math.isfinite(value):
                raise ConfigError(dotted, value, self.valid_range())
        elif self.kind is int:
            if not is_integer(value):
                raise ConfigError(dotted, value, self.valid_range())
            value = int(value)
        elif self.kind is bool:
            if not isinstance(value, bool):
                raise ConfigError(dotted, value, self.valid_range())
        elif not isinstance(value, str) or len(value) > STRING_CHARS_MAX or not _is_unicode(value):
            raise ConfigError(dotted, value, self.valid_range())
        if self.choices and value not in self.choices:
            raise ConfigError(dotted, value, self.valid_range())
        if (
            (self.gt is not None and not value > self.gt)
            or (self.ge is not None and not value >= self.ge)
            or (self.lt is not None and not value < self.lt)
            or (self.le is not None and not value <= self.le)
        ):
            raise ConfigError(dotted, value, self.valid_range())
        return value


def _is_unicode(text: str) -> bool:
    """True if ``text`` can be written as UTF-8 (no lone surrogates)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


#: Longest string value of a scenario (a name, a description) [characters]: a name is drawn in
#: the titles of figures, whose rasteriser fails on a line of some hundred thousand characters.
STRING_CHARS_MAX = 500

#: The scenario schema: every key, in file order. Units are in the key names.
SCHEMA = (
    Field("name", str, "name of the scenario, shown in summaries and plots"),
    Field("description", str, "one line on what the scenario shows, listed by `pmsm2dof presets`", default=""),
    Field(
        "motor.pole_pairs",
        int,
        "pole pairs p (the paper's p0 of eq 1, which it calls the number of poles)",
        ge=1,
        le=1000,
    ),
    Field("motor.Rs_ohm", float, "stator resistance Rs [ohm] (eq 1)", gt=0),
    Field("motor.Ld_H", float, "d-axis inductance Ld [H] (eq 1)", gt=0),
    Field("motor.Lq_H", float, "q-axis inductance Lq [H] (eq 1); Lq != Ld makes a salient motor (MTPA)", gt=0),
    Field("motor.psi_f_Wb", float, "permanent-magnet flux linkage psi_f [Wb] (eq 1)", gt=0),
    Field("motor.J_kgm2", float, "true inertia of motor and load J [kg m^2] (eq 1, 2)", gt=0),
    Field("motor.B_Nms", float, "viscous friction B [Nm s/rad]", default=0.0, ge=0),
    Field("motor.T_coulomb_Nm", float, "Coulomb friction torque [Nm]", default=0.0, ge=0),
    Field(
        "motor.i_rated_A",
        float,
        "rated (continuous) current as a dq magnitude, the peak of the phase current [A]; "
        "only the plausibility checks read it",
        default=None,
        gt=0,
    ),
    Field(
        "motor.i_peak_A",
        float,
        "largest current the motor may carry, as a dq magnitude [A]; only the plausibility checks read it",
        default=None,
        gt=0,
    ),
    Field(
        "motor.J_rotor_kgm2",
        float,
        "the motor's own rotor inertia [kg m^2] (part of J_kgm2); only the plausibility checks read it",
        default=None,
        gt=0,
    ),
    Field("limits.i_max_A", float, "current-vector limit ||i_dq|| <= i_max_A [A] (Sat of Fig. 1 and 2)", gt=0),
    Field("limits.u_dc_V", float, "DC-link voltage [V]; the voltage vector is limited to u_dc/sqrt(3)", gt=0),
    Field(
        "inverter.computation_delay",
        bool,
        "true: the voltage command is applied one current-controller sample later",
        default=False,
    ),
    Field(
        "current_loop.model",
        str,
        "dq_pi: the C dq current controllers and the electrical model of eq 1; "
        "first_order: the closed current loop as eq 3",
        choices=CURRENT_LOOP_MODELS,
    ),
    Field("current_loop.tau_i_s", float, "time constant of the closed current loop tau_i [s] (eq 3)", gt=0),
    Field("current_loop.Ts_s", float, "sampling period of the current controller [s]", gt=0),
    Field("current_loop.decouple", bool, "add the back-EMF and cross-coupling feedforward (dq_pi)", default=True),
    Field(
        "current_loop.anti_windup",
        str,
        "anti-windup of the current PIs (dq_pi)",
        default="back_calculation",
        choices=ANTI_WINDUPS,
    ),
    Field(
        "current_loop.method",
        str,
        "discretization of the current PIs (Table 1)",
        default="tustin",
        choices=METHODS,
    ),
    Field("speed_controller.alpha_radps", float, "bandwidth alpha [rad/s] of the P loop (eq 9)", gt=0),
    Field("speed_controller.zeta", float, "relative damping zeta of the PI loop (eq 9)", gt=0),
    Field("speed_controller.m", float, "tracking pole factor, Gx = m alpha / (s + m alpha) (eq 10)", default=1.0, gt=0),
    Field(
        "speed_controller.feedforward",
        str,
        "2DOF feedforward Fr: none (1DOF PI), lowpass (eq 13, 15), no_tau (eq 11 with tau_i = 0), full (eq 11)",
        default="lowpass",
        choices=FEEDFORWARDS,
    ),
    Field(
        "speed_controller.anti_windup",
        str,
        "anti-windup of the speed PI (section 3.2, Fig. 5)",
        default="back_calculation",
        choices=ANTI_WINDUPS,
    ),
    Field(
        "speed_controller.Ka",
        float,
        "back-calculation gain Ka [(rad/s)/Nm] (Fig. 5); absent: 1/Kp (section 3.3)",
        default=None,
        ge=0,
    ),
    Field(
        "speed_controller.method",
        str,
        "discretization of the PI and Fr (Table 1, eq 14, 15)",
        default="tustin",
        choices=METHODS,
    ),
    Field(
        "speed_controller.Ts_s",
        float,
        "sampling period of the speed controller [s], an integer multiple of current_loop.Ts_s",
        gt=0,
    ),
    Field(
        "speed_controller.J_kgm2",
        float,
        "inertia the gains are designed for [kg m^2] (eq 9, 11)",
        default=SameAs("motor.J_kgm2"),
        gt=0,
    ),
    Field(
        "speed_controller.tau_i_s",
        float,
        "current-loop time constant the full feedforward is designed for [s] (eq 11)",
        default=SameAs("current_loop.tau_i_s"),
        ge=0,
    ),
    Field(
        "speed_controller.arithmetic",
        str,
        "arithmetic of the speed controller: float32 (speed.h), or the fixed-point q15 or q31 (speed_fixed.h: an MCU "
        "without an FPU; a surface PMSM, no speed_filter, field weakening or estimator.adapt_gains)",
        default="float32",
        choices=ARITHMETICS,
    ),
    Field(
        "speed_controller.speed_full_scale_rpm",
        float,
        "q15, q31: the speed of the integer 2^N [rpm]; absent: twice the no-load speed u_dc_V / (sqrt(3) p psi_f), "
        "the engine's overspeed bound",
        default=None,
        gt=0,
    ),
    Field(
        "speed_controller.torque_full_scale_Nm",
        float,
        "q15, q31: the torque of the integer 2^N [Nm], >= the torque limit 1.5 p psi_f i_max_A; absent: 1.25 times "
        "the smallest that holds, within two full scales, the torque limit with the feedforward's state and "
        "transient at the references and the command at the largest reference step",
        default=None,
        gt=0,
    ),
    Field(
        "speed_controller.current_full_scale_A",
        float,
        "q15, q31: the current of the integer 2^N [A], >= limits.i_max_A; absent: the current of the torque full "
        "scale, torque_full_scale_Nm / (1.5 p psi_f)",
        default=None,
        gt=0,
    ),
    # the drive train beyond the rigid load, and the speed controller's torque filters (drive.h, filter.h)
    Field(
        "mechanics.model",
        str,
        "rigid: one inertia motor.J_kgm2; two_mass: motor.J_kgm2 is the motor side alone, coupled to "
        "J_load_kgm2 by an elastic shaft; the load torque acts on the load side",
        default="rigid",
        choices=MECHANICS_MODELS,
    ),
    Field("mechanics.J_load_kgm2", float, "load inertia J_L [kg m^2] (two_mass)", default=None, gt=0),
    Field("mechanics.stiffness_Nm_per_rad", float, "shaft stiffness K [Nm/rad] (two_mass)", default=None, gt=0),
    Field("mechanics.damping_Nms_per_rad", float, "shaft damping D [Nm s/rad] (two_mass)", default=0.0, ge=0),
    Field(
        "mechanics.backlash_rad",
        float,
        "total play b of the shaft, a dead zone of +-b/2 of the twist [rad] (two_mass)",
        default=0.0,
        ge=0,
    ),
    Field(
        "mechanics.feedback",
        str,
        "the side the speed sensor reads for the speed controller: motor or load (load side, two_mass)",
        default="motor",
        choices=FEEDBACKS,
    ),
    Field(
        "speed_filter.notch_freq_Hz",
        float,
        "notch on the torque command, inside the anti-windup loop: frequency f0 [Hz]; 0: no notch, "
        "else < 1/(2 speed_controller.Ts_s)",
        default=0.0,
        ge=0,
    ),
    Field("speed_filter.notch_width_Hz", float, "-3 dB width of the notch [Hz] (notch only)", default=0.0, ge=0),
    Field(
        "speed_filter.notch_depth",
        float,
        "gain of the notch at f0 [-], < 1/sqrt(2) (0.1: -20 dB; notch only)",
        default=0.0,
        ge=0,
        lt=1 / math.sqrt(2),
    ),
    Field(
        "speed_filter.lowpass_freq_Hz",
        float,
        "second-order low-pass on the torque command: natural frequency [Hz]; 0: no low-pass",
        default=0.0,
        ge=0,
    ),
    Field(
        "speed_filter.lowpass_zeta",
        float,
        "damping of the low-pass [-] (1/sqrt(2): -3 dB at its frequency; low-pass only)",
        default=0.0,
        ge=0,
    ),
    Field("simulation.t_end_s", float, "simulated time [s]", gt=0, le=T_END_MAX_S),
    Field(
        "simulation.dt_s",
        float,
        "largest plant integration step [s] (RK4; the default, one step per "
        "current period, is accurate to better than 1e-4 of the speed: see pmsm2dof.sim.simulate)",
        default=SameAs("current_loop.Ts_s"),
        gt=0,
    ),
    Field(
        "simulation.log_every",
        int,
        "log every n-th row of simulation.log_rate: speed-controller sample (speed) or current period (current) [-]",
        default=1,
        ge=1,
        le=10**9,
    ),
    Field(
        "simulation.log_rate",
        str,
        "rate of the log's rows: speed (a row per speed_controller.Ts_s) or current (a row per current_loop.Ts_s, "
        "to see the currents and voltages within a speed period; the controllers and the run are the same at "
        "either rate)",
        default="speed",
        choices=LOG_RATES,
    ),
    Field("simulation.speed0_rpm", float, "initial speed [rpm]", default=0.0),
    # commissioning: `pmsm2dof commission` runs the C routine of commission.h against this motor; absent
    # values are derived from the scenario (pmsm2dof.sim.commission.commissioning_config); no other run reads them
    Field(
        "commissioning.i_test_A",
        float,
        "test current of alignment, Rs and inductance tests [A]; "
        "absent: 0.4 limits.i_max_A, at most 0.5 psi_f / (Lq - Ld)",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.i_spin_A",
        float,
        "current of the I-f flux test [A]; absent: commissioning.i_test_A",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.i_trip_A",
        float,
        "current that ends the routine [A]; absent: twice the larger test current",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.tau_i_s",
        float,
        "time constant of the routine's own current loop [s]; absent: 20 current_loop.Ts_s",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.t_align_s",
        float,
        "alignment [s]; absent: 12 periods of the rotor held by i_test_A, >= 8 psi_f / (Rs i_test_A) and 20 tau_i_s",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.t_level_s",
        float,
        "each Rs level [s]; absent: max(50 tau_i_s, 0.05 s, 5 Ld / Rs)",
        default=None,
        gt=0,
    ),
    Field("commissioning.t_inductance_s", float, "averaging of each injection test [s]", default=0.05, gt=0),
    Field(
        "commissioning.t_ramp_s",
        float,
        "I-f speed ramp [s]; absent: peak torque 0.4 of what i_spin_A gives, >= t_align_s",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.t_spin_s",
        float,
        "flux test at speed [s]; absent: max(t_align_s, 0.5 s, 20 tau_i_s)",
        default=None,
        gt=0,
    ),
    Field(
        "commissioning.w_e_spin_radps",
        float,
        "electrical speed of the flux test [rad/s]; absent: a back-EMF of 0.2 u_dc/sqrt(3)",
        default=None,
        gt=0,
    ),
    Field("commissioning.theta0_rad", float, "initial electrical angle of the simulated rotor [rad]", default=1.0),
    Field("commissioning.T_load_Nm", float, "constant load torque on the simulated rotor [Nm]", default=0.0),
    Field(
        "commissioning.dead_time_V",
        float,
        "dead-time voltage error per phase of the simulated inverter [V]",
        default=0.0,
        ge=0,
    ),
    Field("commissioning.noise_A", float, "standard deviation of each measured phase current [A]", default=0.0, ge=0),
    Field("commissioning.seed", int, "seed of the current-measurement noise", default=1, ge=0, le=2**63),
    # ---- the drive as it is measured, and field weakening (speed_sensor, current_measurement, field_weakening)
    Field(
        "speed_sensor.model",
        str,
        "what the speed controller reads: ideal (the true speed) or encoder (counts read by the C estimator)",
        default="ideal",
        choices=SPEED_SENSOR_MODELS,
    ),
    Field(
        "speed_sensor.counts_per_rev", int, "encoder counts per revolution (4 x lines)", default=4096, ge=1, le=2**24
    ),
    Field("speed_sensor.counter_bits", int, "width of the encoder's hardware counter [bit]", default=32, ge=2, le=32),
    Field(
        "speed_sensor.estimator",
        str,
        "encoder speed estimator: difference (counts over one speed period) or pll (type-2 tracking loop)",
        default="difference",
        choices=ESTIMATORS,
    ),
    Field(
        "speed_sensor.bandwidth_radps",
        float,
        "PLL double pole w_pll [rad/s], 1e-3 <= w_pll speed_controller.Ts_s <= 2 (estimator pll)",
        default=None,
        gt=0,
    ),
    Field(
        "speed_sensor.lowpass_radps",
        float,
        "first-order low-pass on the estimate [rad/s], 0: none, else 1e-3 <= it speed_controller.Ts_s <= 2",
        default=0.0,
        ge=0,
    ),
    Field(
        "speed_sensor.delay_s",
        float,
        f"transport delay of the reading [s], at most {SENSOR_DELAY_MAX_PERIODS} current_loop.Ts_s",
        default=0.0,
        ge=0,
    ),
    Field(
        "speed_sensor.noise_rpm_rms",
        float,
        "white Gaussian noise added to the reading, after the estimator and the low-pass [rpm rms]",
        default=0.0,
        ge=0,
    ),
    Field("speed_sensor.seed", int, "seed of the speed noise", default=0, ge=0, lt=2**64),
    Field(
        "current_measurement.gain_error_a",
        float,
        "relative gain error of the phase-a current sensor [-] (measured = (1 + gain_error) i + offset + noise)",
        default=0.0,
        gt=-1,
    ),
    Field(
        "current_measurement.gain_error_b", float, "relative gain error of the phase-b sensor [-]", default=0.0, gt=-1
    ),
    Field("current_measurement.offset_a_A", float, "offset of the phase-a current sensor [A]", default=0.0),
    Field("current_measurement.offset_b_A", float, "offset of the phase-b current sensor [A]", default=0.0),
    Field(
        "current_measurement.noise_A_rms",
        float,
        "white Gaussian noise of each phase current sensor [A rms]",
        default=0.0,
        ge=0,
    ),
    Field("current_measurement.seed", int, "seed of the current noise", default=0, ge=0, lt=2**64),
    Field(
        "field_weakening.enabled",
        bool,
        "voltage-feedback field weakening in the current reference path (dq_pi)",
        default=False,
    ),
    Field(
        "field_weakening.Ki_A_per_Vs",
        float,
        "integral gain of the PI on the voltage margin [A/(V s)]; crossover about Ki w_e Ld (required when enabled)",
        default=None,
        gt=0,
    ),
    Field("field_weakening.Kp_A_per_V", float, "proportional gain of that PI [A/V]", default=0.0, ge=0),
    Field(
        "field_weakening.Ka_V_per_A",
        float,
        "back-calculation gain [V/A]; absent: 1 / (Ki speed_controller.Ts_s)",
        default=None,
        ge=0,
    ),
    Field(
        "field_weakening.voltage_ratio",
        float,
        "the voltage command is held at voltage_ratio u_dc/sqrt(3) [-]",
        default=0.95,
        gt=0,
        le=1,
    ),
    Field(
        "field_weakening.id_min_A",
        float,
        "most negative d-axis current [A]; absent: -limits.i_max_A",
        default=None,
        lt=0,
    ),
    Field(
        "estimator.enabled",
        bool,
        "run the online inertia estimator of the C library (pmsm2dof/inertia.h) beside the speed controller",
        default=False,
    ),
    Field(
        "estimator.adapt_gains",
        bool,
        "gain scheduling: re-design the speed controller (eq 9) for the estimated J once it is valid",
        default=False,
    ),
    Field(
        "estimator.adapt_rel_change",
        float,
        "re-design when the estimate has moved by more than this fraction of the J of the present gains",
        default=0.05,
        ge=0,
    ),
    Field(
        "estimator.adapt_error_rpm",
        float,
        "re-design only at a quiet sample: reference constant, output inside the current limit and "
        "|speed error| <= this [rpm] (a re-design in a transient disturbs the integrator)",
        default=5.0,
        ge=0,
    ),
    Field(
        "estimator.J0_kgm2",
        float,
        "initial estimate and prior standard deviation of J [kg m^2]",
        default=SameAs("speed_controller.J_kgm2"),
        gt=0,
    ),
    Field("estimator.J_min_kgm2", float, "smallest plausible J [kg m^2]; absent: J0_kgm2 / 10", default=None, gt=0),
    Field("estimator.J_max_kgm2", float, "largest plausible J [kg m^2]; absent: 10 J0_kgm2", default=None, gt=0),
    Field(
        "estimator.B_max_Nms",
        float,
        "largest plausible viscous friction [Nm s/rad]; absent: the peak torque 1.5 p psi_f i_max_A per 100 rad/s",
        default=None,
        gt=0,
    ),
    Field(
        "estimator.T_load_max_Nm",
        float,
        "largest plausible |load torque| [Nm]; absent: the peak torque 1.5 p psi_f i_max_A",
        default=None,
        gt=0,
    ),
    Field(
        "estimator.sigma_T_Nm",
        float,
        "standard deviation of the torque input's noise [Nm]; absent: 1 % of the peak torque",
        default=None,
        gt=0,
    ),
    Field("estimator.J_memory_s", float, "memory of the estimates of J and B [s]", default=10.0, gt=0),
    Field(
        "estimator.load_memory_s",
        float,
        "time constant of the load estimate after a load step [s]; absent: 1 / speed_controller.alpha_radps",
        default=None,
        gt=0,
    ),
    Field(
        "estimator.w_f_radps",
        float,
        "bandwidth of the prefilter of speed and torque [rad/s]; absent: 0.2 / speed_controller.Ts_s",
        default=None,
        gt=0,
    ),
    Field(
        "estimator.J_rel_sd_max",
        float,
        "J is valid (and used by adapt_gains) once its standard deviation is below this fraction",
        default=0.05,
        gt=0,
        lt=1,
    ),
    Field(
        "estimator.speed_is_period_mean",
        bool,
        "the speed reading is the mean over the speed period (encoder counts differenced)",
        default=False,
    ),
    Field("reference[].t_s", float, "time of the reference change [s], 0 <= t_s < simulation.t_end_s", ge=0),
    Field("reference[].speed_rpm", float, "new speed reference [rpm]"),
    Field(
        "reference[].ramp_s",
        float,
        "0: a step; > 0: a linear ramp from the previous value over ramp_s [s]",
        default=0.0,
        ge=0,
    ),
    Field("load[].t_s", float, "time of the load change [s], 0 <= t_s < simulation.t_end_s", ge=0),
    Field("load[].torque_Nm", float, "new load torque [Nm]"),
    Field(
        "load[].ramp_s",
        float,
        "0: a step; > 0: a linear ramp from the previous value over ramp_s [s]",
        default=0.0,
        ge=0,
    ),
    Field(
        "fault[].kind",
        str,
        "what fails: dc_link_sag (the DC link drops to u_dc_factor u_dc_V over the "
        "window, dq_pi only), sensor_hold (the speed controller reads its last reading before the window), "
        "sensor_zero (it reads 0), sensor_spike (its first sample at or after t_s reads speed_rpm)",
        choices=FAULT_KINDS,
    ),
    Field("fault[].t_s", float, "start of the fault [s], 0 <= t_s < simulation.t_end_s", ge=0),
    Field(
        "fault[].duration_s",
        float,
        "length of the fault window [s]; every kind but sensor_spike (one sample)",
        default=None,
        gt=0,
    ),
    Field(
        "fault[].u_dc_factor",
        float,
        "dc_link_sag only: the DC link over the window as a fraction of limits.u_dc_V",
        default=None,
        ge=0,
        le=1,
    ),
    Field("fault[].speed_rpm", float, "sensor_spike only: the wrong speed reading [rpm]", default=None),
)

#: Arrays of tables: name -> (required, what its entries are).
ARRAYS = {
    "reference": (True, "speed reference schedule; the reference is 0 before the first entry"),
    "load": (False, "load torque schedule; the load is 0 before the first entry"),
    "fault": (False, "faults the simulation plays: DC-link sag, speed-sensor hold, zero or spike"),
}

_FIELDS = {f.key: f for f in SCHEMA}
_TABLES = tuple(dict.fromkeys(f.parent for f in SCHEMA if f.parent and not f.parent.endswith("[]")))


def _fields_of(parent: str) -> list[Field]:
    return [f for f in SCHEMA if f.parent == parent]


def _short(value: object) -> object:
    """The value as shown in an error message (tables and arrays are not spelled out)."""
    if isinstance(value, dict):
        return _TABLE
    if isinstance(value, list):
        return _ARRAY
    return value


#: Keys renamed so that scenario keys and API arguments share one spelling (docs/conventions.md):
#: the old key of a file is refused with its new name.
RENAMED_KEYS = {
    "speed_controller.alpha": "speed_controller.alpha_radps",
    "speed_controller.discretization": "speed_controller.method",
    "speed_controller.J_design_kgm2": "speed_controller.J_kgm2",
    "speed_controller.tau_i_design_s": "speed_controller.tau_i_s",
    "current_loop.discretization": "current_loop.method",
}


def _unknown_key(dotted: str, value: object, parent: str, valid: list[str]) -> None:
    """ConfigError for an unknown key, suggesting the closest valid one."""
    renamed = RENAMED_KEYS.get(f"{parent}.{dotted.rsplit('.', 1)[-1]}" if parent else dotted)
    if renamed is not None:
        raise ConfigError(dotted, _short(value), f"a key renamed to '{renamed}' (same meaning and unit)")
    leaf = dotted.rsplit(".", 1)[-1]
    where = f"[{parent}]" if parent else "the top level"
    prefix = f"{parent}." if parent else ""
    same_case = [v for v in valid if v.lower() == leaf.lower()]
    elsewhere = [f"'{f.key.replace('[]', '.0')}'" for f in SCHEMA if f.leaf.lower() == leaf.lower()]
    close = difflib.get_close_matches(leaf, valid, n=1, cutoff=0.6)
    if same_case:
        hint = f"did you mean '{prefix}{same_case[0]}'?"
    elif elsewhere:
        hint = f"did you mean {' or '.join(elsewhere)}?"
    elif close:
        hint = f"did you mean '{prefix}{close[0]}'?"
    else:
        hint = "valid keys: " + ", ".join(valid)
    raise ConfigError(dotted, _short(value), f"not a key of {where} ({hint})")


def _validate_table(table: Tree, parent: str, prefix: str) -> Tree:
    """Check the keys of one table against the schema; return {leaf: value} of the keys given.

    ``parent`` is the schema parent (``"motor"``, ``"reference[]"``), ``prefix`` the dotted
    name used in messages (``"motor"``, ``"reference.2"``).
    """
    fields = _fields_of(parent)
    sub = [t for t in _TABLES if "." not in t] + list(ARRAYS) if parent == "" else []
    valid = [f.leaf for f in fields] + sub
    given: Tree = {}
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else key
        if key not in valid:
            _unknown_key(dotted, value, prefix, valid)
        if key in sub:
            continue
        if value is not None:
            given[key] = _FIELDS[f"{parent}.{key}" if parent else key].check(dotted, value)
    for f in fields:
        if f.default is REQUIRED and f.leaf not in given:
            raise ConfigError(
                f"{prefix}.{f.leaf}" if prefix else f.leaf, REQUIRED, f"required: {f.valid_range()} ({f.doc})"
            )
    return given


def _as_table(value: object, dotted: str) -> Tree:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(dotted, _short(value), "a table of keys")
    return value


def _validate(tree: object) -> tuple[Tree, Tree]:
    """Validate a scenario tree; return (given, data): the keys given and all keys resolved."""
    table = _as_table(tree, "scenario")
    motor = table.get("motor")
    if isinstance(motor, dict) and "datasheet" in motor:
        # [motor.datasheet]: the model keys converted from datasheet units (pmsm2dof.core.motor)
        converted = motor_from_table(motor).motor_table()
        table["motor"] = {**{k: v for k, v in motor.items() if k != "datasheet"}, **converted}
    given = _validate_table(table, "", "")
    for name in _TABLES:
        values = _validate_table(_as_table(table.get(name), name), name, name)
        if values:
            given[name] = values
    for name, (required, what) in ARRAYS.items():
        entries = table.get(name)
        if entries is None and not required:
            continue
        valid = f"an array of tables [[{name}]]{' with at least one entry' if required else ''} ({what})"
        if not isinstance(entries, list) or (required and not entries):
            raise ConfigError(name, REQUIRED if entries is None else _short(entries), valid)
        for i, e in enumerate(entries):
            if not isinstance(e, dict):
                raise ConfigError(f"{name}.{i}", e, f"a table, one entry of {valid}")
        given[name] = [_validate_table(e, f"{name}[]", f"{name}.{i}") for i, e in enumerate(entries)]

    data: Tree = {}
    for f in SCHEMA:
        if "[]" in f.key:
            continue
        node = data
        for part in f.key.split(".")[:-1]:
            node = node.setdefault(part, {})
        source = given.get(f.parent, {}) if f.parent else given
        node[f.leaf] = source.get(f.leaf, f.default)
    for f in SCHEMA:
        if isinstance(f.default, SameAs) and f.leaf not in given.get(f.parent, {}):
            source_table, source_leaf = f.default.key.split(".")
            data[f.parent][f.leaf] = data[source_table][source_leaf]
    _check_mechanics(data)
    if data["mechanics"]["model"] == "two_mass" and "J_kgm2" not in given.get("speed_controller", {}):
        # the eq 9 design on the total inertia of the drive train
        data["speed_controller"]["J_kgm2"] = data["motor"]["J_kgm2"] + data["mechanics"]["J_load_kgm2"]
    for name in ARRAYS:
        data[name] = [{f.leaf: e.get(f.leaf, f.default) for f in _fields_of(f"{name}[]")} for e in given.get(name, [])]
    _check_relations(data)
    return given, data


def _check_mechanics(data: Tree) -> None:
    """A two-mass train has its load inertia and stiffness; a rigid one none of the two-mass keys;
    each torque filter has its width/depth or damping when it is on."""
    mech = data["mechanics"]
    two_mass_keys = ("J_load_kgm2", "stiffness_Nm_per_rad")
    for leaf in two_mass_keys:
        field = _FIELDS[f"mechanics.{leaf}"]
        if mech["model"] == "two_mass" and mech[leaf] is None:
            raise ConfigError(
                f"mechanics.{leaf}", REQUIRED, f"required by model 'two_mass': {field.valid_range()} ({field.doc})"
            )
    if mech["model"] == "rigid":
        for leaf in (*two_mass_keys, "damping_Nms_per_rad", "backlash_rad"):
            if mech[leaf] not in (None, 0.0):
                raise ConfigError(f"mechanics.{leaf}", mech[leaf], "absent: model 'rigid' does not use it")
    filt = data["speed_filter"]
    for on, leaves in (("notch_freq_Hz", ("notch_width_Hz",)), ("lowpass_freq_Hz", ("lowpass_zeta",))):
        for leaf in leaves:
            if filt[on] > 0 and not filt[leaf] > 0:
                raise ConfigError(f"speed_filter.{leaf}", filt[leaf], f"> 0 with speed_filter.{on} > 0")


def _check_relations(data: Tree) -> None:
    """The checks that involve more than one key."""
    sc, cl, sim = data["speed_controller"], data["current_loop"], data["simulation"]
    ratio = sc["Ts_s"] / cl["Ts_s"]
    n = round(ratio) if math.isfinite(ratio) else 0
    if n < 1 or abs(sc["Ts_s"] - n * cl["Ts_s"]) > TS_MULTIPLE_RTOL * sc["Ts_s"]:
        raise ConfigError(
            "speed_controller.Ts_s",
            sc["Ts_s"],
            f"an integer multiple (1, 2, 3, ...) of current_loop.Ts_s = {cl['Ts_s']!r}",
        )
    if sc["feedforward"] == "lowpass" and sc["m"] != 1.0:
        raise ConfigError(
            "speed_controller.m",
            sc["m"],
            "exactly 1 with feedforward 'lowpass' (eq 13 is eq 11 with m = 1 and tau_i = 0); "
            "for m != 1 use feedforward 'no_tau' (eq 11 with tau_i = 0) or 'full'",
        )
    if cl["model"] == "dq_pi" and cl["tau_i_s"] < cl["Ts_s"]:
        raise ConfigError(
            "current_loop.tau_i_s",
            cl["tau_i_s"],
            f">= current_loop.Ts_s = {cl['Ts_s']!r} (the dq current PIs cannot be faster than their sampling)",
        )
    for name in ("reference", "load"):
        entries = data[name]
        for i, e in enumerate(entries):
            if e["t_s"] >= sim["t_end_s"]:
                raise ConfigError(f"{name}.{i}.t_s", e["t_s"], f">= 0 and < simulation.t_end_s = {sim['t_end_s']!r}")
            if i > 0:
                prev = entries[i - 1]
                earliest = prev["t_s"] + prev["ramp_s"]
                if not (e["t_s"] > prev["t_s"] and e["t_s"] >= earliest):
                    raise ConfigError(
                        f"{name}.{i}.t_s",
                        e["t_s"],
                        f"> {name}.{i - 1}.t_s = {prev['t_s']!r} and >= the end of its ramp "
                        f"({earliest!r}): entries sorted by time, ramps not overlapping",
                    )
    _check_faults(data)
    _check_sensing(data)
    _check_arithmetic(data)


#: The full scales of the fixed-point speed controllers (speed_controller.*).
FULL_SCALE_KEYS = ("speed_full_scale_rpm", "torque_full_scale_Nm", "current_full_scale_A")


def _check_arithmetic(data: Tree) -> None:
    """The full scales only with a fixed-point speed controller, which needs a surface PMSM and takes no
    torque filters, field weakening or gain scheduling (speed_fixed.h)."""
    sc = data["speed_controller"]
    if sc["arithmetic"] == "float32":
        for leaf in FULL_SCALE_KEYS:
            if sc[leaf] is not None:
                raise ConfigError(
                    f"speed_controller.{leaf}", sc[leaf], "absent: arithmetic 'float32' has no full scales"
                )
        return
    fixed = f"with speed_controller.arithmetic {sc['arithmetic']!r} (the fixed-point speed controllers have none)"
    for leaf in ("notch_freq_Hz", "lowpass_freq_Hz"):
        if data["speed_filter"][leaf] != 0.0:
            raise ConfigError(f"speed_filter.{leaf}", data["speed_filter"][leaf], f"0 (no torque filter) {fixed}")
    if data["field_weakening"]["enabled"]:
        raise ConfigError("field_weakening.enabled", True, f"false {fixed}")
    if data["estimator"]["enabled"] and data["estimator"]["adapt_gains"]:
        raise ConfigError("estimator.adapt_gains", True, f"false (no gain scheduling) {fixed}")
    motor = data["motor"]
    if motor["Lq_H"] != motor["Ld_H"]:
        raise ConfigError(
            "motor.Lq_H",
            motor["Lq_H"],
            f"equal to motor.Ld_H = {motor['Ld_H']!r} with speed_controller.arithmetic {sc['arithmetic']!r} (the "
            "fixed-point speed controllers drive a surface PMSM: id = 0, no MTPA)",
        )


def _check_sensing(data: Tree) -> None:
    """The speed sensor, current measurement and field weakening against the other tables."""
    ss, cl, fw = data["speed_sensor"], data["current_loop"], data["field_weakening"]
    if ss["model"] == "ideal" and ss["estimator"] == "pll":
        raise ConfigError("speed_sensor.estimator", "pll", "'difference' with model 'ideal' (a PLL reads counts)")
    if ss["model"] == "encoder" and ss["estimator"] == "pll" and ss["bandwidth_radps"] is None:
        raise ConfigError(
            "speed_sensor.bandwidth_radps", REQUIRED, "required by estimator 'pll': the PLL's double pole [rad/s], > 0"
        )
    if ss["bandwidth_radps"] is not None and not (ss["model"] == "encoder" and ss["estimator"] == "pll"):
        raise ConfigError(
            "speed_sensor.bandwidth_radps",
            ss["bandwidth_radps"],
            "absent: only model 'encoder' with estimator 'pll' uses it",
        )
    if ss["delay_s"] > SENSOR_DELAY_MAX_PERIODS * cl["Ts_s"] * (1.0 + TS_MULTIPLE_RTOL):
        raise ConfigError(
            "speed_sensor.delay_s",
            ss["delay_s"],
            f"<= {SENSOR_DELAY_MAX_PERIODS} current_loop.Ts_s = {SENSOR_DELAY_MAX_PERIODS * cl['Ts_s']:g} s",
        )
    cm = data["current_measurement"]
    measured = any(cm[k] != 0.0 for k in ("gain_error_a", "gain_error_b", "offset_a_A", "offset_b_A", "noise_A_rms"))
    if measured and cl["model"] != "dq_pi":
        raise ConfigError(
            "current_loop.model", cl["model"], "'dq_pi' with a [current_measurement] error (eq 3 measures nothing)"
        )
    if fw["enabled"]:
        if cl["model"] != "dq_pi":
            raise ConfigError(
                "current_loop.model", cl["model"], "'dq_pi' with field_weakening.enabled (eq 3 has no voltage)"
            )
        if fw["Ki_A_per_Vs"] is None:
            field = _FIELDS["field_weakening.Ki_A_per_Vs"]
            raise ConfigError("field_weakening.Ki_A_per_Vs", REQUIRED, f"required when enabled: {field.valid_range()}")


def _check_faults(data: Tree) -> None:
    """Each fault has the keys its kind uses, acts before t_end and, within its group (DC link or
    speed sensor), does not overlap another; a sensor_spike takes one speed period."""
    sim, Ts_speed = data["simulation"], data["speed_controller"]["Ts_s"]
    windows: dict[str, list[tuple[int, tuple[float, float]]]] = {"dc_link": [], "sensor": []}
    for i, f in enumerate(data["fault"]):
        kind = f["kind"]
        if f["t_s"] >= sim["t_end_s"]:
            raise ConfigError(f"fault.{i}.t_s", f["t_s"], f">= 0 and < simulation.t_end_s = {sim['t_end_s']!r}")
        uses = {
            "duration_s": kind != "sensor_spike",
            "u_dc_factor": kind == "dc_link_sag",
            "speed_rpm": kind == "sensor_spike",
        }
        for leaf, used in uses.items():
            if used and f[leaf] is None:
                field = _FIELDS[f"fault[].{leaf}"]
                raise ConfigError(
                    f"fault.{i}.{leaf}", REQUIRED, f"required by kind {kind!r}: {field.valid_range()} ({field.doc})"
                )
            if not used and f[leaf] is not None:
                raise ConfigError(f"fault.{i}.{leaf}", f[leaf], f"absent: kind {kind!r} does not use it")
        if kind == "dc_link_sag" and data["current_loop"]["model"] != "dq_pi":
            raise ConfigError(
                f"fault.{i}.kind",
                kind,
                "a sensor fault with current_loop.model 'first_order' "
                "(eq 3 has no inverter and no DC link): use 'dq_pi' for a DC-link sag",
            )
        group = "dc_link" if kind == "dc_link_sag" else "sensor"
        start, end = f["t_s"], f["t_s"] + (Ts_speed if kind == "sensor_spike" else f["duration_s"])
        tol = TS_MULTIPLE_RTOL * Ts_speed
        for j, (s0, s1) in windows[group]:
            if start < s1 - tol and s0 < end - tol:
                raise ConfigError(
                    f"fault.{i}.t_s",
                    start,
                    f"outside [{s0!r}, {s1!r}) s, the window of fault.{j}: faults of the "
                    f"{'DC link' if group == 'dc_link' else 'speed sensor'} do not overlap "
                    "(a sensor_spike takes one speed_controller.Ts_s)",
                )
        windows[group].append((i, (start, end)))


class Scenario:
    """One validated, immutable scenario.

    Build it with :func:`load_scenario` (a preset or a TOML file) or :meth:`from_dict`.
    :attr:`data` is a plain nested dict holding every key of :data:`SCHEMA` (defaults filled;
    ``speed_controller.Ka`` is ``None`` when absent, meaning 1/Kp).
    """

    __slots__ = ("_given", "_data")
    _given: Tree  # the keys given, validated
    _data: Tree  # every key, defaults filled

    def __init__(self, given: Tree, data: Tree) -> None:
        object.__setattr__(self, "_given", given)
        object.__setattr__(self, "_data", data)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("a Scenario is immutable: use with_overrides()")

    def __reduce__(self) -> tuple[type["Scenario"], tuple[Tree, Tree]]:
        # pickled by its parts (threads and Dask workers of pmsm2dof.studies.engine), not by setattr
        return Scenario, (self._given, self._data)

    @classmethod
    def from_dict(cls, tree: Mapping[str, Any]) -> "Scenario":
        """Validate a nested dict (as read from TOML; ``None`` means absent) into a Scenario."""
        given, data = _validate(copy.deepcopy(tree))
        return cls(given, data)

    @property
    def data(self) -> Tree:
        """All keys, validated and with defaults filled (a copy: the scenario never changes)."""
        return copy.deepcopy(self._data)

    @property
    def name(self) -> str:
        """The scenario's ``name``."""
        name: str = self._data["name"]
        return name

    @property
    def description(self) -> str:
        """The scenario's ``description``."""
        description: str = self._data["description"]
        return description

    def with_overrides(self, overrides: Mapping[str, Any]) -> "Scenario":
        """A new scenario with changes applied, validated again; this one is unchanged.

        Parameters
        ----------
        overrides : mapping
            ``{"dotted.key": value}``. Keys address tables by name and arrays by index:
            ``"speed_controller.anti_windup"``, ``"reference.0.speed_rpm"``; the index one past
            the end appends an entry. A whole table or array may be replaced
            (``{"load": [{"t_s": 1.0, "torque_Nm": 2.0}]}``). ``None`` removes a key, so that its
            default (for a derived default such as ``speed_controller.J_kgm2``, its source key) applies again.

        Returns
        -------
        Scenario

        Raises
        ------
        ConfigError
            Naming the dotted key that is unknown, of the wrong type or out of range.
        """
        if not isinstance(overrides, Mapping):
            raise ConfigError("overrides", _short(overrides), "a mapping of dotted keys to values")
        tree = copy.deepcopy(self._given)
        for key, value in overrides.items():
            _set_dotted(tree, key, copy.deepcopy(value))
        return Scenario.from_dict(tree)

    def to_toml(self) -> str:
        """The scenario as TOML text: the keys given, then the defaults as comments.

        ``load_scenario`` of the text gives back an equal scenario.
        """
        lines: list[str] = []
        lines += _toml_fields(_fields_of(""), self._given, self._data)
        for table in _TABLES:
            lines += ["", f"[{table}]"] + _toml_fields(_fields_of(table), self._given.get(table, {}), self._data[table])
        for name, (_, what) in ARRAYS.items():
            fields = _fields_of(f"{name}[]")
            entries = self._given.get(name, [])
            if not entries:
                lines += ["", f"# [[{name}]]: none ({what})"]
            for given, data in zip(entries, self._data[name]):
                lines += ["", f"[[{name}]]"] + _toml_fields(fields, given, data)
        return "\n".join(lines) + "\n"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scenario):
            return NotImplemented
        equal: bool = self._data == other._data
        return equal

    __hash__ = None  # type: ignore[assignment]  # equal scenarios compare by data, which is mutable

    def __repr__(self) -> str:
        return f"Scenario({self.name!r})"


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    # a TOML basic string is a JSON string in which DEL must be escaped as well
    return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")


def _toml_fields(fields: list[Field], given: Tree, data: Tree) -> list[str]:
    lines = []
    for f in fields:
        if f.leaf in given:
            lines.append(f"{f.leaf} = {_toml_value(given[f.leaf])}")
        elif isinstance(f.default, SameAs):
            lines.append(f"# {f.leaf} = {_toml_value(data[f.leaf])}  (default: {f.default.key})")
        elif f.default is None:
            lines.append(f"# {f.leaf} =  (optional: {f.doc})")
        else:
            lines.append(f"# {f.leaf} = {_toml_value(f.default)}  (default)")
    return lines


def _set_dotted(tree: Tree, key: object, value: object) -> None:
    """Set ``tree[a][b]...`` for the dotted ``key``, creating tables and appending array entries."""
    parts = key.split(".") if isinstance(key, str) else []
    if not parts or any(not p.strip() for p in parts):
        raise ConfigError("override key", key, "a dotted key such as 'motor.J_kgm2' or 'reference.0.speed_rpm'")
    node: Any = tree
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = ".".join(parts[: depth + 1])
        if isinstance(node, list):
            if not part.isdigit() or int(part) > len(node):
                raise ConfigError(
                    here, value, f"an index 0..{len(node)} of {'.'.join(parts[:depth])} ({len(node)} appends an entry)"
                )
            index = int(part)
            if index == len(node):
                node.append({})
            if last:
                node[index] = value
            else:
                node = node[index]
            continue
        if not isinstance(node, dict):
            raise ConfigError(here, value, f"a key inside a table, but {'.'.join(parts[:depth])} is a value")
        if last:
            if value is None:
                node.pop(part, None)
            else:
                node[part] = value
        else:
            child = node.get(part)
            if child is None:
                child = [] if part in ARRAYS and depth == 0 else {}
                node[part] = child
            node = child


def _presets_dir() -> importlib.resources.abc.Traversable:
    return importlib.resources.files("pmsm2dof.sim") / "presets"


def list_presets() -> list[str]:
    """Names of the scenarios shipped with the package (``pmsm2dof/sim/presets/*.toml``), sorted."""
    return sorted(p.name[: -len(".toml")] for p in _presets_dir().iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load and validate a scenario from a preset name or a TOML file.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        An existing file is read as TOML; any other name must be one of :func:`list_presets`.

    Returns
    -------
    Scenario

    Raises
    ------
    ConfigError
        For an unknown name, an unreadable or invalid TOML file, or a schema violation (naming
        the dotted key, its value and its valid range).
    """
    path = Path(os.fspath(name_or_path))
    if path.exists():
        return Scenario.from_dict(read_toml(path, "scenario"))
    name = str(name_or_path)
    if name in list_presets():
        text = (_presets_dir() / f"{name}.toml").read_text(encoding="utf-8")
        return Scenario.from_dict(parse_toml(text, "scenario", name))
    raise ConfigError("scenario", name, "an existing TOML file or a preset: " + ", ".join(list_presets()))


def schema_reference() -> str:
    """Every scenario key with its type, valid range, default and meaning, as plain text."""
    lines = []
    for f in SCHEMA:
        if f.default is REQUIRED:
            default = "required"
        elif isinstance(f.default, SameAs):
            default = f"default {f.default.key}"
        elif f.default is None:
            default = "optional"
        else:
            default = f"default {_toml_value(f.default)}"
        lines.append(f"{f.key:36s} {f.valid_range()}; {default}. {f.doc}")
    for name, (required, what) in ARRAYS.items():
        lines.append(
            f"{name + '[]':36s} {'required, at least one entry' if required else 'optional'}: {what}; "
            "entries sorted by t_s, ramps not overlapping"
        )
    lines.append("")
    lines.append(
        "[motor.datasheet] instead of motor.pole_pairs, Rs_ohm, Ld_H, Lq_H, psi_f_Wb (and i_rated_A, i_peak_A, "
        "J_rotor_kgm2): the motor in datasheet units (pmsm2dof.core.motor; `pmsm2dof motor FILE` shows the "
        "conversion)"
    )
    lines += [f"{'motor.datasheet.' + key:36s} {doc}" for key, (_, doc) in DATASHEET_KEYS.items()]
    return "\n".join(lines)
