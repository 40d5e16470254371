"""The typed tables of a scenario: a frozen dataclass per table, each field a key of the scenario.

The field names are the scenario's keys (``scenario.speed_controller.alpha_radps`` is the key
``speed_controller.alpha_radps``) and each field declares with :func:`~pmsm2dof.sim.scenario_keys.key`
the key's meaning, default and valid range: the one declaration that the schema
(:mod:`pmsm2dof.sim.scenario_schema`), the validation, the TOML writer and ``pmsm2dof presets --keys``
read. A key that a field of the C configuration holds under its name is described by that field's comment in
the C header (:func:`~pmsm2dof.sim.scenario_keys.from_c`): the header is the one text of its meaning, unit
and range. A key that fields of the engine's C configuration hold declares no range: the schema takes it
from their comments and C types (:func:`~pmsm2dof.sim.engine_keys.c_bounds`, the range their C inits check).
A table holds every key resolved (defaults filled; ``None`` for an optional key not given); a
:class:`~pmsm2dof.sim.scenario.Scenario` builds its tables once, after validation.
"""

import dataclasses

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
from ..core.bindings import AntiWindup, Feedforward, Method
from .scenario_keys import T_END_MAX_S, SameAs, from_c, key


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MotorTable:
    """``[motor]``."""

    pole_pairs: int = key(from_c("the paper's p0 of eq 1, which it calls the number of poles"))
    Rs_ohm: float = key(from_c("eq 1"))
    Ld_H: float = key(from_c("eq 1"))
    Lq_H: float = key(from_c("eq 1; Lq != Ld makes a salient motor (MTPA)"))
    psi_f_Wb: float = key(from_c("eq 1"))
    J_kgm2: float = key(from_c("the plant's (eq 1, 2)"))
    B_Nms: float = key(from_c(), default=0.0)
    T_coulomb_Nm: float = key(from_c(), default=0.0)
    i_rated_A: float | None = key(
        "rated (continuous) current as a dq magnitude, the peak of the phase current [A]; "
        "only the plausibility checks read it",
        default=None,
        gt=0,
    )
    i_peak_A: float | None = key(
        "largest current the motor may carry, as a dq magnitude [A]; only the plausibility checks read it",
        default=None,
        gt=0,
    )
    J_rotor_kgm2: float | None = key(
        "the motor's own rotor inertia [kg m^2] (part of J_kgm2); only the plausibility checks read it",
        default=None,
        gt=0,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LimitsTable:
    """``[limits]``."""

    i_max_A: float = key("current-vector limit ||i_dq|| <= i_max_A [A] (Sat of Fig. 1 and 2)")
    u_dc_V: float = key("DC-link voltage [V]; the voltage vector is limited to u_dc/sqrt(3)")


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class InverterTable:
    """``[inverter]``."""

    computation_delay: bool = key(
        "true: the voltage command is applied one current-controller sample later",
        default=False,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class CurrentLoopTable:
    """``[current_loop]``."""

    model: str = key(
        "dq_pi: the C dq current controllers and the electrical model of eq 1; "
        "first_order: the closed current loop as eq 3",
        choices=CURRENT_LOOP_MODELS,
    )
    tau_i_s: float = key(from_c("tau_i of the closed current loop (eq 3): first_order's, or the dq PIs' design"))
    Ts_s: float = key(from_c("of the current controller and the PWM"))
    decouple: bool = key(from_c("dq_pi"), default=True)
    anti_windup: AntiWindup = key(
        "anti-windup of the current PIs (dq_pi)", default="back_calculation", choices=ANTI_WINDUPS
    )
    method: Method = key("discretization of the current PIs (Table 1)", default="tustin", choices=METHODS)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SpeedControllerTable:
    """``[speed_controller]``."""

    alpha_radps: float = key(from_c())
    zeta: float = key(from_c())
    m: float = key(from_c(), default=1.0)
    feedforward: Feedforward = key(
        "2DOF feedforward Fr: none (1DOF PI), lowpass (eq 13, 15), no_tau (eq 11 with tau_i = 0), full (eq 11)",
        default="lowpass",
        choices=FEEDFORWARDS,
    )
    anti_windup: AntiWindup = key(
        "anti-windup of the speed PI (section 3.2, Fig. 5)",
        default="back_calculation",
        choices=ANTI_WINDUPS,
    )
    Ka: float | None = key(
        from_c("absent means that default (section 3.3)"),
        default=None,
    )
    method: Method = key("discretization of the PI and Fr (Table 1, eq 14, 15)", default="tustin", choices=METHODS)
    Ts_s: float = key(from_c("of the speed controller, an integer multiple of current_loop.Ts_s"))
    J_kgm2: float = key(
        from_c("the gains of eq 9 and the feedforward of eq 11 are designed for it"),
        default=SameAs("motor.J_kgm2"),
    )
    tau_i_s: float = key(
        from_c("the full feedforward of eq 11 is designed for it"),
        default=SameAs("current_loop.tau_i_s"),
    )
    arithmetic: str = key(
        "arithmetic of the speed controller: float32 (speed.h), or the fixed-point q15 or q31 (speed_fixed.h: an MCU "
        "without an FPU; a surface PMSM, no speed_filter, field weakening or estimator.adapt_gains)",
        default="float32",
        choices=ARITHMETICS,
    )
    speed_full_scale_rpm: float | None = key(
        "q15, q31: the speed of the integer 2^N [rpm]; absent: twice the no-load speed u_dc_V / (sqrt(3) p psi_f), "
        "the engine's overspeed bound",
        default=None,
    )
    torque_full_scale_Nm: float | None = key(
        "q15, q31: the torque of the integer 2^N [Nm], >= the torque limit 1.5 p psi_f i_max_A; absent: 1.25 times "
        "the smallest that holds, within two full scales, the torque limit with the feedforward's state and "
        "transient at the references and the command at the largest reference step",
        default=None,
    )
    current_full_scale_A: float | None = key(
        "q15, q31: the current of the integer 2^N [A], >= limits.i_max_A; absent: the current of the torque full "
        "scale, torque_full_scale_Nm / (1.5 p psi_f)",
        default=None,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class MechanicsTable:
    """``[mechanics]``."""

    model: str = key(
        "rigid: one inertia motor.J_kgm2; two_mass: motor.J_kgm2 is the motor side alone, coupled to "
        "J_load_kgm2 by an elastic shaft; the load torque acts on the load side",
        default="rigid",
        choices=MECHANICS_MODELS,
    )
    J_load_kgm2: float | None = key(from_c("two_mass"), default=None)
    stiffness_Nm_per_rad: float | None = key(from_c("two_mass"), default=None)
    damping_Nms_per_rad: float = key(from_c("two_mass"), default=0.0)
    backlash_rad: float = key(
        from_c("a dead zone of +-b/2 of the twist (two_mass)"),
        default=0.0,
    )
    feedback: str = key(
        "the side the speed sensor reads for the speed controller: motor or load (load side, two_mass)",
        default="motor",
        choices=FEEDBACKS,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SpeedFilterTable:
    """``[speed_filter]``."""

    notch_freq_Hz: float = key(
        from_c("on the torque command, inside the anti-windup loop; Ts_s is speed_controller.Ts_s"),
        default=0.0,
    )
    notch_width_Hz: float = key(from_c(), default=0.0)
    notch_depth: float = key(
        from_c(),
        default=0.0,
    )
    lowpass_freq_Hz: float = key(
        from_c("second order, on the torque command"),
        default=0.0,
    )
    lowpass_zeta: float = key(
        from_c(),
        default=0.0,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SimulationTable:
    """``[simulation]``."""

    t_end_s: float = key("simulated time [s]", gt=0, le=T_END_MAX_S)
    dt_s: float = key(
        "largest plant integration step [s] (RK4; the default, one step per "
        "current period, is accurate to better than 1e-4 of the speed: see pmsm2dof.sim.simulate)",
        default=SameAs("current_loop.Ts_s"),
        gt=0,
    )
    log_every: int = key(
        "log every n-th row of simulation.log_rate: speed-controller sample (speed) or current period (current) [-]",
        default=1,
    )
    log_rate: str = key(
        "rate of the log's rows: speed (a row per speed_controller.Ts_s) or current (a row per current_loop.Ts_s, "
        "to see the currents and voltages within a speed period; the controllers and the run are the same at "
        "either rate)",
        default="speed",
        choices=LOG_RATES,
    )
    speed0_rpm: float = key("initial speed [rpm]", default=0.0)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class CommissioningTable:
    """``[commissioning]``."""

    i_test_A: float | None = key(
        "test current of alignment, Rs and inductance tests [A]; "
        "absent: 0.4 limits.i_max_A, at most 0.5 psi_f / (Lq - Ld)",
        default=None,
        gt=0,
    )
    i_spin_A: float | None = key("current of the I-f flux test [A]; absent: commissioning.i_test_A", default=None, gt=0)
    i_trip_A: float | None = key(
        "current that ends the routine [A]; absent: twice the larger test current",
        default=None,
        gt=0,
    )
    tau_i_s: float | None = key(
        "time constant of the routine's own current loop [s]; absent: 20 current_loop.Ts_s",
        default=None,
        gt=0,
    )
    t_align_s: float | None = key(
        "alignment [s]; absent: 12 periods of the rotor held by i_test_A, >= 8 psi_f / (Rs i_test_A) and 20 tau_i_s",
        default=None,
        gt=0,
    )
    t_level_s: float | None = key("each Rs level [s]; absent: max(50 tau_i_s, 0.05 s, 5 Ld / Rs)", default=None, gt=0)
    t_inductance_s: float = key("averaging of each injection test [s]", default=0.05, gt=0)
    t_ramp_s: float | None = key(
        "I-f speed ramp [s]; absent: peak torque 0.4 of what i_spin_A gives, >= t_align_s",
        default=None,
        gt=0,
    )
    t_spin_s: float | None = key(
        "flux test at speed [s]; absent: max(t_align_s, 0.5 s, 20 tau_i_s)",
        default=None,
        gt=0,
    )
    w_e_spin_radps: float | None = key(
        "electrical speed of the flux test [rad/s]; absent: a back-EMF of 0.2 u_dc/sqrt(3)",
        default=None,
        gt=0,
    )
    theta0_rad: float = key("initial electrical angle of the simulated rotor [rad]", default=1.0)
    T_load_Nm: float = key("constant load torque on the simulated rotor [Nm]", default=0.0)
    dead_time_V: float = key("dead-time voltage error per phase of the simulated inverter [V]", default=0.0, ge=0)
    noise_A: float = key("standard deviation of each measured phase current [A]", default=0.0, ge=0)
    seed: int = key("seed of the current-measurement noise", default=1, ge=0, le=2**63)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class SpeedSensorTable:
    """``[speed_sensor]``."""

    model: str = key(
        "what the speed controller reads: ideal (the true speed) or encoder (counts read by the C estimator)",
        default="ideal",
        choices=SPEED_SENSOR_MODELS,
    )
    counts_per_rev: int = key(from_c("4 x lines"), default=4096)
    counter_bits: int = key(from_c(), default=32)
    estimator: str = key(
        "encoder speed estimator: difference (counts over one speed period) or pll (type-2 tracking loop)",
        default="difference",
        choices=ESTIMATORS,
    )
    bandwidth_radps: float | None = key(
        from_c("Ts_s is speed_controller.Ts_s"),
        default=None,
    )
    lowpass_radps: float = key(
        from_c("first order; Ts_s is speed_controller.Ts_s"),
        default=0.0,
    )
    delay_s: float = key(
        from_c("Ts_current is current_loop.Ts_s"),
        default=0.0,
    )
    noise_rpm_rms: float = key(
        "white Gaussian noise added to the reading, after the estimator and the low-pass [rpm rms]",
        default=0.0,
    )
    seed: int = key(from_c("the speed noise"), default=0)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class CurrentMeasurementTable:
    """``[current_measurement]``."""

    gain_error_a: float = key(
        from_c("measured = (1 + gain_error) i + offset + noise"),
        default=0.0,
    )
    gain_error_b: float = key(from_c(), default=0.0)
    offset_a_A: float = key(from_c(), default=0.0)
    offset_b_A: float = key(from_c(), default=0.0)
    noise_A_rms: float = key("white Gaussian noise of each phase current sensor [A rms]", default=0.0)
    seed: int = key(from_c("the current noise"), default=0)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class FieldWeakeningTable:
    """``[field_weakening]``."""

    enabled: bool = key("voltage-feedback field weakening in the current reference path (dq_pi)", default=False)
    Ki_A_per_Vs: float | None = key(
        from_c("of the PI on the voltage margin, crossover about Ki w_e Ld; required when enabled"),
        default=None,
    )
    Kp_A_per_V: float = key(from_c(), default=0.0)
    Ka_V_per_A: float | None = key(
        from_c("absent: 1 / (Ki speed_controller.Ts_s)"),
        default=None,
    )
    voltage_ratio: float = key(
        from_c(),
        default=0.95,
    )
    id_min_A: float | None = key(from_c("absent: -limits.i_max_A"), default=None)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class EstimatorTable:
    """``[estimator]``."""

    enabled: bool = key(
        "run the online inertia estimator of the C library (pmsm2dof/inertia.h) beside the speed controller",
        default=False,
    )
    adapt_gains: bool = key(
        "gain scheduling: re-design the speed controller (eq 9) for the estimated J once it is valid",
        default=False,
    )
    adapt_rel_change: float = key(
        from_c(),
        default=0.05,
    )
    adapt_error_rpm: float = key(
        "re-design only at a quiet sample: reference constant, output inside the current limit and "
        "|speed error| <= this [rpm] (a re-design in a transient disturbs the integrator)",
        default=5.0,
    )
    J0_kgm2: float = key(
        from_c(),
        default=SameAs("speed_controller.J_kgm2"),
    )
    J_min_kgm2: float | None = key(from_c("absent: J0_kgm2 / 10"), default=None)
    J_max_kgm2: float | None = key(from_c("absent: 10 J0_kgm2"), default=None)
    B_max_Nms: float | None = key(
        from_c("absent: the peak torque 1.5 p psi_f i_max_A per 100 rad/s"),
        default=None,
    )
    T_load_max_Nm: float | None = key(
        from_c("absent: the peak torque 1.5 p psi_f i_max_A"),
        default=None,
    )
    sigma_T_Nm: float | None = key(
        from_c("absent: 1 % of the peak torque"),
        default=None,
    )
    J_memory_s: float = key(from_c(), default=10.0)
    load_memory_s: float | None = key(
        from_c("absent: 1 / speed_controller.alpha_radps"),
        default=None,
    )
    w_f_radps: float | None = key(
        from_c("absent: 0.2 / speed_controller.Ts_s"),
        default=None,
    )
    J_rel_sd_max: float = key(
        from_c("J_valid: the estimate is used by adapt_gains"),
        default=0.05,
    )
    speed_is_period_mean: bool = key(
        from_c(),
        default=False,
    )


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class ReferenceEntry:
    """One entry of ``[[reference]]``."""

    t_s: float = key("time of the reference change [s], 0 <= t_s < simulation.t_end_s", ge=0)
    speed_rpm: float = key("new speed reference [rpm]")
    ramp_s: float = key("0: a step; > 0: a linear ramp from the previous value over ramp_s [s]", default=0.0, ge=0)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class LoadEntry:
    """One entry of ``[[load]]``."""

    t_s: float = key("time of the load change [s], 0 <= t_s < simulation.t_end_s", ge=0)
    torque_Nm: float = key("new load torque [Nm]")
    ramp_s: float = key("0: a step; > 0: a linear ramp from the previous value over ramp_s [s]", default=0.0, ge=0)


@dataclasses.dataclass(frozen=True, slots=True, kw_only=True)
class FaultEntry:
    """One entry of ``[[fault]]``."""

    kind: str = key(
        "what fails: dc_link_sag (the DC link drops to u_dc_factor u_dc_V over the "
        "window, dq_pi only), sensor_hold (the speed controller reads its last reading before the window), "
        "sensor_zero (it reads 0), sensor_spike (its first sample at or after t_s reads speed_rpm)",
        choices=FAULT_KINDS,
    )
    t_s: float = key("start of the fault [s], 0 <= t_s < simulation.t_end_s", ge=0)
    duration_s: float | None = key(
        "length of the fault window [s]; every kind but sensor_spike (one sample)",
        default=None,
        gt=0,
    )
    u_dc_factor: float | None = key(
        "dc_link_sag only: the DC link over the window as a fraction of limits.u_dc_V",
        default=None,
        ge=0,
        le=1,
    )
    speed_rpm: float | None = key("sensor_spike only: the wrong speed reading [rpm]", default=None)


#: The tables of a scenario by name, in file order.
TABLES: dict[str, type] = {
    "motor": MotorTable,
    "limits": LimitsTable,
    "inverter": InverterTable,
    "current_loop": CurrentLoopTable,
    "speed_controller": SpeedControllerTable,
    "mechanics": MechanicsTable,
    "speed_filter": SpeedFilterTable,
    "simulation": SimulationTable,
    "commissioning": CommissioningTable,
    "speed_sensor": SpeedSensorTable,
    "current_measurement": CurrentMeasurementTable,
    "field_weakening": FieldWeakeningTable,
    "estimator": EstimatorTable,
}

#: The arrays of tables by name: the type of an entry.
ENTRIES: dict[str, type] = {"reference": ReferenceEntry, "load": LoadEntry, "fault": FaultEntry}

#: The arrays of tables by name: (required, what its entries are).
ARRAYS = {
    "reference": (True, "speed reference schedule; the reference is 0 before the first entry"),
    "load": (False, "load torque schedule; the load is 0 before the first entry"),
    "fault": (False, "faults the simulation plays: DC-link sag, speed-sensor hold, zero or spike"),
}
