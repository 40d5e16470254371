"""The one scenario -> design -> C configuration of the firmware, for every command that writes a header.

:func:`scenario_design` is the design (eq 9-13) of a scenario's speed controller, for every caller
that analyses a scenario's loop (the claims, the report, the loop checks, the header's record).
:func:`configuration` turns a scenario into the complete configuration of the controllers the
firmware runs (``examples/firmware/foc.c``), as the engine would run them on that scenario: the
speed controller and its torque filters, the dq current controllers, the speed sensor's estimator
(an encoder's, or the low-pass of the speed as measured), the field weakening, the inertia
estimator and its gain scheduling when enabled, and the loop rates. Its values are read from the
engine's own C configuration of the scenario (:class:`pmsm2dof.sim.simulate.Simulation`), so a
default derived in C (``Ka = 1/Kp``, the estimator's bounds) is the engine's float to the bit, and
a value the C inits reject is a :class:`~pmsm2dof.errors.ConfigError` naming the scenario key.

:meth:`Configuration.c_header` writes it as one C header of one shape, whatever the command:
``pmsm2dof header``, ``firmware``, ``design --emit-c-header``, ``autotune --emit-c-header``,
``commission --out`` and the tuner's download. The other results reach it as scenarios:
:func:`design_scenario` (a design and its motor), ``AutotuneResult.tuned_scenario()``, a
commissioning's identified motor set into its scenario, the tuner's scenario.

The header defines, with ``prefix`` ``p2d_config`` (the firmware's):

- ``P2D_CONFIG_TS_CURRENT_S``, ``P2D_CONFIG_TS_SPEED_S`` [s] and ``P2D_CONFIG_CURRENT_PER_SPEED``,
  the integer loop ratio the firmware's interrupt counts;
- ``P2D_CONFIG_ENCODER``, ``P2D_CONFIG_FIELD_WEAKENING``, ``P2D_CONFIG_INERTIA`` (0 or 1), and the
  gain scheduling's ``P2D_CONFIG_ADAPT_GAINS``, ``P2D_CONFIG_KA_FOLLOWS_J``,
  ``P2D_CONFIG_ADAPT_REL_CHANGE``, ``P2D_CONFIG_ADAPT_ERROR_RADPS``;
- ``p2d_config_speed`` (``p2d_speed_config_t``), ``p2d_config_speed_filter``
  (``p2d_filter_config_t``, zero: none), ``p2d_config_current`` (``p2d_current_config_t``),
  ``p2d_config_encoder`` (``p2d_encoder_config_t``; with the speed as measured, only its low-pass
  counts, as in the engine), ``p2d_config_field_weakening`` and ``p2d_config_inertia`` (zero when off).
"""

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..analysis.codegen import c_float, check_prefix, config_header, design_record
from ..analysis.design import Design, design
from ..analysis.discretize import DiscreteDesign
from ..analysis.sensor import SensorChain
from ..core import ANTI_WINDUPS, FEEDFORWARDS, METHODS, SpeedController
from ..core.bindings import ffi
from ..core.motor import Motor
from ..errors import ConfigError
from ..outputs import atomic_write
from ..sim.scenario import Scenario, load_scenario
from ..sim.scenario_schema import FIELDS
from ..sim.scenario_tables import SpeedFilterTable
from ..sim.simulate import RPM_PER_RADPS, Simulation

#: The identifier prefix of the firmware's configuration (examples/firmware/foc.c includes p2d_config.h).
DEFAULT_PREFIX = "p2d_config"

#: The preset whose drive fills what a design does not define (the DC link, friction, the test
#: sequence): none of it reaches the configuration.
DESIGN_TEMPLATE = "paper-condition-1"

#: The C headers the configuration's structs come from.
INCLUDES = (
    "pmsm2dof/current.h",
    "pmsm2dof/encoder.h",
    "pmsm2dof/field_weakening.h",
    "pmsm2dof/filter.h",
    "pmsm2dof/inertia.h",
    "pmsm2dof/speed.h",
)

#: The largest log_every of a scenario: the configuration's engine logs a row or a few.
_LOG_EVERY_ONE_ROW = FIELDS["simulation.log_every"].le


@dataclasses.dataclass(frozen=True, eq=False)
class Configuration:
    """The complete C configuration of the firmware's controllers for one scenario.

    Attributes
    ----------
    scenario : Scenario
        The scenario it was made from.
    source : str
        What made it (a command line), recorded in the header.
    notes : tuple of str
        Further lines for the header's record (where placeholder values came from).
    engine : Simulation
        The engine set up on the scenario (not run): its C configuration holds every value.
    """

    scenario: Scenario
    source: str
    notes: tuple[str, ...]
    engine: Simulation

    @property
    def current_per_speed(self) -> int:
        """Current periods per speed period [-] (the firmware's loop ratio)."""
        return int(self.engine.cfg.current_per_speed)

    @property
    def encoder(self) -> Any:
        """The ``p2d_encoder_config_t`` the firmware runs (cffi), as the engine's sensing runs it."""
        cfg = self.engine.cfg
        enc = ffi.new("p2d_encoder_config_t *", cfg.sensing.speed_sensor.encoder)[0]
        enc.Ts_s = cfg.speed.Ts_s
        if self.scenario.speed_sensor.model == "ideal":
            # the speed as measured: only the estimator's low-pass acts (csrc/sim/sensing.c)
            enc.counts_per_rev, enc.counter_bits, enc.estimator, enc.bandwidth_radps = 1, 32, 0, 0.0
        return enc

    @property
    def switches(self) -> dict[str, bool]:
        """Which optional parts run: encoder, field weakening, inertia estimator, gain scheduling."""
        scenario = self.scenario
        return dict(
            ENCODER=scenario.speed_sensor.model == "encoder",
            FIELD_WEAKENING=scenario.field_weakening.enabled,
            INERTIA=scenario.estimator.enabled,
            ADAPT_GAINS=scenario.estimator.enabled and scenario.estimator.adapt_gains,
            KA_FOLLOWS_J=scenario.speed_controller.Ka is None,
        )

    def c_header(self, prefix: str = DEFAULT_PREFIX) -> str:
        """The text of the C header (see the module's docstring for what it defines)."""
        check_prefix(prefix)
        cfg = self.engine.cfg
        on = self.switches
        est = self.scenario.estimator
        off = "zero: off (not used by the firmware)"
        macros = [
            ("TS_CURRENT_S", c_float(cfg.current.Ts_s), "current-loop (PWM, control interrupt) period [s]"),
            ("TS_SPEED_S", c_float(cfg.speed.Ts_s), "speed-loop period [s]"),
            (
                "CURRENT_PER_SPEED",
                f"{self.current_per_speed}u",
                "the speed loop runs every CURRENT_PER_SPEED-th control interrupt: Ts_speed / Ts_current [-]",
            ),
            ("ENCODER", str(int(on["ENCODER"])), "1: the speed from an encoder's counter (p2d_encoder_step)"),
            ("FIELD_WEAKENING", str(int(on["FIELD_WEAKENING"])), "1: field weakening (p2d_field_weakening_step)"),
            ("INERTIA", str(int(on["INERTIA"])), "1: the online inertia estimator (p2d_inertia_step)"),
            ("ADAPT_GAINS", str(int(on["ADAPT_GAINS"])), "1: re-design the speed controller for the valid J"),
            ("KA_FOLLOWS_J", str(int(on["KA_FOLLOWS_J"])), "1: gain scheduling sets Ka = 1 / (J alpha)"),
            ("ADAPT_REL_CHANGE", c_float(est.adapt_rel_change), "re-design when J moved by this share [-]"),
            (
                "ADAPT_ERROR_RADPS",
                c_float(est.adapt_error_rpm / RPM_PER_RADPS),
                "re-design only while |w_ref - w_meas| <= this [rad/s]",
            ),
        ]
        zero_fw = ffi.new("p2d_field_weakening_config_t *")[0]
        zero_inertia = ffi.new("p2d_inertia_config_t *")[0]
        blocks = [
            ("p2d_speed_config_t", "speed", cfg.speed, "Pass to p2d_speed_init()."),
            (
                "p2d_filter_config_t",
                "speed_filter",
                cfg.speed_filter,
                "Torque filters: pass to p2d_speed_set_filter() after p2d_speed_init() (zero: none).",
            ),
            ("p2d_current_config_t", "current", cfg.current, "Pass to p2d_current_init()."),
            (
                "p2d_encoder_config_t",
                "encoder",
                self.encoder,
                "Pass to p2d_encoder_init() (ENCODER 0: only its low-pass acts, on the speed as measured).",
            ),
            (
                "p2d_field_weakening_config_t",
                "field_weakening",
                cfg.sensing.field_weakening.config if on["FIELD_WEAKENING"] else zero_fw,
                "Pass to p2d_field_weakening_init() (FIELD_WEAKENING 1)." if on["FIELD_WEAKENING"] else off,
            ),
            (
                "p2d_inertia_config_t",
                "inertia",
                cfg.adapt.config if on["INERTIA"] else zero_inertia,
                "Pass to p2d_inertia_init() (INERTIA 1)." if on["INERTIA"] else off,
            ),
        ]
        return config_header(
            prefix=prefix,
            title=f'{prefix}.h: the controller configuration of "{self.scenario.name}"',
            record=self.record(),
            includes=INCLUDES,
            macros=macros,
            blocks=blocks,
        )

    def write_header(self, path: Path | str, prefix: str = DEFAULT_PREFIX) -> Path:
        """Write :meth:`c_header` to ``path`` (whole or not at all); return the path."""
        text = self.c_header(prefix)
        atomic_write(path, text)
        return Path(path)

    def record(self) -> list[str]:
        """The header's record: where it came from, the design and what it gives, the other parts."""
        scenario = self.scenario
        cfg = self.engine.cfg
        sc, cl, ss = scenario.speed_controller, scenario.current_loop, scenario.speed_sensor
        speed = _speed_controller(cfg.speed)
        # Ka absent: the default 1/Kp as the C library computes it; the record's margins are the ideal sensor's
        Ka = float(cfg.speed.Ka) if sc.Ka is None else sc.Ka
        discrete = scenario_design(self.scenario, Ka=Ka, sensor=None).discretize(sc.Ts_s, sc.method)
        Ts_c, Ts_s = float(cfg.current.Ts_s), float(cfg.speed.Ts_s)
        lines = [f"From: {self.source}" if self.source else f"From the scenario {self.scenario.name!r}.", *self.notes]
        lines += ["", *design_record(discrete, speed.coefficients), ""]
        lines += [
            f"Loop rates: current loop {1.0 / Ts_c:.6g} Hz (Ts {Ts_c:.6g} s), speed loop every "
            f"{self.current_per_speed}th interrupt ({1.0 / Ts_s:.6g} Hz)",
            f"Motor: p = {scenario.motor.pole_pairs}, Rs = {cfg.current.Rs_ohm:.6g} ohm, "
            f"Ld = {cfg.current.Ld_H:.6g} H, Lq = {cfg.current.Lq_H:.6g} H, psi_f = {cfg.current.psi_f_Wb:.6g} Wb, "
            f"i_max = {cfg.speed.i_max_A:.6g} A",
            f"Current loop: tau_i = {cl.tau_i_s:g} s, {cl.method}, anti-windup {cl.anti_windup}, "
            f"decoupling {'on' if cl.decouple else 'off'}",
            "Speed sensor: "
            + (
                f"encoder, {ss.counts_per_rev} counts/rev, {ss.counter_bits}-bit counter, {ss.estimator}"
                if ss.model == "encoder"
                else "the speed as measured"
            )
            + (f", low-pass {ss.lowpass_radps:g} rad/s" if ss.lowpass_radps else ""),
            f"Torque filters: {_filters_text(scenario.speed_filter)}",
            f"Field weakening: {'on' if scenario.field_weakening.enabled else 'off'}; inertia estimator: "
            + (
                ("on, with gain scheduling" if scenario.estimator.adapt_gains else "on")
                if scenario.estimator.enabled
                else "off"
            ),
        ]
        if cl.model == "first_order":
            lines.append("The scenario simulates eq 3 (first_order); the firmware runs these dq current controllers.")
        return lines


def sensor_chain(scenario: Scenario) -> SensorChain:
    """The speed sensor chain of ``scenario``'s ``[speed_sensor]`` in the linear loop.

    The counts per revolution, the counter and the noise act in the simulation only (the linear
    loop has no quantization and no noise).
    """
    ss = scenario.speed_sensor
    return SensorChain(
        model=ss.model,
        estimator=ss.estimator,
        bandwidth_radps=ss.bandwidth_radps or 0.0,
        lowpass_radps=ss.lowpass_radps,
        delay_s=ss.delay_s,
    )


def scenario_design(scenario: Scenario, **changes: Any) -> Design:
    """The design (eq 9-13, section 3.3) of the speed controller of ``scenario``.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario: the design takes its ``speed_controller`` J, alpha, zeta, m, tau_i,
        feedforward, anti-windup and Ka (absent: 1/Kp) and the sensor chain of its ``[speed_sensor]``
        (:func:`sensor_chain`).
    **changes
        Arguments of :func:`pmsm2dof.analysis.design.design` that replace the scenario's, e.g.
        ``feedforward="none"``.

    Raises
    ------
    ConfigError
        A change out of its range, named as the argument.
    """
    sc = scenario.speed_controller
    arguments: dict[str, Any] = {
        "J_kgm2": sc.J_kgm2,
        "alpha_radps": sc.alpha_radps,
        "zeta": sc.zeta,
        "m": sc.m,
        "tau_i_s": sc.tau_i_s,
        "feedforward": sc.feedforward,
        "anti_windup": sc.anti_windup,
        "Ka": sc.Ka,
        "sensor": sensor_chain(scenario),
    }
    unknown = sorted(set(changes) - set(arguments))
    if unknown:
        raise ConfigError(unknown[0], changes[unknown[0]], "an argument of design: " + ", ".join(arguments))
    return design(**(arguments | changes))


def configuration(scenario: Scenario, *, source: str = "", notes: tuple[str, ...] = ()) -> Configuration:
    """The complete C configuration of the firmware's controllers for ``scenario``.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario. Its controllers are what the engine runs on it; with the current
        loop of eq 3 (``current_loop.model = "first_order"``) the dq current controllers of its
        ``[current_loop]`` and ``[motor]`` (which the firmware runs) are configured.
    source : str, optional
        What made it (a command line), recorded in the header.
    notes : tuple of str, optional
        Further lines for the header's record (placeholder values and where they came from).

    Raises
    ------
    ConfigError
        A value the C controllers or the engine reject, naming the scenario key; a fixed-point speed
        controller (``speed_controller.arithmetic``), which the firmware's float32 configuration
        does not hold.
    """
    if not isinstance(scenario, Scenario):
        raise ConfigError("scenario", type(scenario).__name__, "a pmsm2dof Scenario (load_scenario)")
    arithmetic = scenario.speed_controller.arithmetic
    if arithmetic != "float32":
        raise ConfigError(
            "speed_controller.arithmetic",
            arithmetic,
            "'float32': the firmware's configuration is that of the float32 speed controller (speed.h); a "
            "fixed-point one is configured by p2d_speed_fixed_config_t (speed_fixed.h)",
        )
    engine = scenario.with_overrides(
        {"current_loop.model": "dq_pi", "simulation.log_every": _LOG_EVERY_ONE_ROW, "simulation.log_rate": "speed"}
    )
    return Configuration(scenario=scenario, source=source, notes=tuple(notes), engine=Simulation(engine))


def design_scenario(
    discrete: DiscreteDesign,
    *,
    i_max_A: float,
    pole_pairs: int,
    psi_f_Wb: float,
    Ld_H: float,
    Lq_H: float,
    Rs_ohm: float,
    Ts_current_s: float,
    current_method: str | None = None,
    current_anti_windup: str = "back_calculation",
    decouple: bool = True,
    speed_filter: Mapping[str, float] | None = None,
) -> Scenario:
    """A scenario holding a discretized design and its motor, for :func:`configuration`.

    The speed controller is the design (its J, alpha, zeta, m, tau_i, feedforward, anti-windup,
    Ka, Ts and method); the current loop has the design's tau_i (eq 3) at ``Ts_current_s`` with
    ``current_method`` (default: the design's method); the speed sensor is the design's sensor
    chain (an encoder's counts and counter are the scenario defaults); ``speed_filter`` holds the
    fields of ``p2d_filter_config_t`` given. What a design does not define (the DC link, the
    friction, the test sequence) comes from the preset :data:`DESIGN_TEMPLATE`; none of it reaches
    the configuration.

    Raises
    ------
    ConfigError
        A value out of its range, naming the scenario key.
    """
    d = discrete.design
    sensor = d.sensor
    changes: dict[str, Any] = {
        "name": "design",
        "description": "a design of pmsm2dof.analysis.design and its motor",
        "motor.pole_pairs": pole_pairs,
        "motor.Rs_ohm": Rs_ohm,
        "motor.Ld_H": Ld_H,
        "motor.Lq_H": Lq_H,
        "motor.psi_f_Wb": psi_f_Wb,
        "motor.J_kgm2": d.J_kgm2,
        "limits.i_max_A": i_max_A,
        "current_loop.model": "dq_pi",
        "current_loop.tau_i_s": d.tau_i_s,
        "current_loop.Ts_s": Ts_current_s,
        "current_loop.method": discrete.method if current_method is None else current_method,
        "current_loop.anti_windup": current_anti_windup,
        "current_loop.decouple": decouple,
        "speed_controller.J_kgm2": d.J_kgm2,
        "speed_controller.alpha_radps": d.alpha_radps,
        "speed_controller.zeta": d.zeta,
        "speed_controller.m": d.m,
        "speed_controller.tau_i_s": d.tau_i_s,
        "speed_controller.feedforward": d.feedforward,
        "speed_controller.anti_windup": d.anti_windup,
        "speed_controller.Ka": d.Ka,
        "speed_controller.Ts_s": discrete.Ts_s,
        "speed_controller.method": discrete.method,
        "speed_sensor.model": sensor.model,
        "speed_sensor.estimator": sensor.estimator,
        "speed_sensor.lowpass_radps": sensor.lowpass_radps,
        "speed_sensor.delay_s": sensor.delay_s,
        # the design alone, none of the template's test sequence (a zero reference over one speed period)
        "reference": [{"t_s": 0.0, "speed_rpm": 0.0}],
        "load": [],
        "fault": [],
        "simulation.t_end_s": discrete.Ts_s,
        "simulation.speed0_rpm": 0.0,
    }
    if sensor.pll:
        changes["speed_sensor.bandwidth_radps"] = sensor.bandwidth_radps
    for key, value in (speed_filter or {}).items():
        changes[f"speed_filter.{key}"] = value
    return load_scenario(DESIGN_TEMPLATE).with_overrides(changes)


#: The motor data and current loop of a design's configuration (:func:`design_scenario`'s arguments):
#: argument -> (unit, scenario key).
DESIGN_MOTOR = {
    "i_max_A": ("A", "limits.i_max_A"),
    "pole_pairs": ("", "motor.pole_pairs"),
    "psi_f_Wb": ("Wb", "motor.psi_f_Wb"),
    "Ld_H": ("H", "motor.Ld_H"),
    "Lq_H": ("H", "motor.Lq_H"),
    "Rs_ohm": ("ohm", "motor.Rs_ohm"),
    "Ts_current_s": ("s", "current_loop.Ts_s"),
}
#: The source of a value of :func:`design_motor` given by the caller.
GIVEN = "given"


def design_motor(
    given: Mapping[str, float | None],
    *,
    motor: Motor | None = None,
    motor_source: str = "",
    paper_drive: bool = False,
) -> tuple[dict[str, Any], dict[str, str]]:
    """The motor data and current-loop period of a design's configuration, and where each came from.

    Each value of :data:`DESIGN_MOTOR` is the one ``given`` (source :data:`GIVEN`), else the one of
    ``motor`` (a motor file's, source ``motor_source``), else, with ``paper_drive``, the paper's
    drive (the preset :data:`DESIGN_TEMPLATE`, a placeholder); ``Lq_H`` not given is ``Ld_H``
    (surface PMSM) when ``Ld_H`` is given.

    Returns
    -------
    tuple
        ``(values, sources)``: the keyword arguments of :func:`design_scenario` and, for each,
        its source, in the order of :data:`DESIGN_MOTOR`.

    Raises
    ------
    ConfigError
        Naming every missing value (its parameter: their names, comma-separated) when one is
        neither given, in ``motor`` nor taken from the paper's drive.
    """
    values: dict[str, Any] = {}
    sources: dict[str, str] = {}
    for name in DESIGN_MOTOR:
        if given.get(name) is not None:
            values[name], sources[name] = given[name], GIVEN
        elif motor is not None and hasattr(motor, name):
            values[name], sources[name] = getattr(motor, name), motor_source
    if "Lq_H" not in values and sources.get("Ld_H") == GIVEN:
        values["Lq_H"], sources["Lq_H"] = values["Ld_H"], "= Ld_H: surface PMSM, Lq_H not given"
    missing = [name for name in DESIGN_MOTOR if name not in values]
    if missing and not paper_drive:
        raise ConfigError(
            ", ".join(missing),
            "<missing>",
            f"the motor data and the current loop of the configuration: {', '.join(missing)} missing; give "
            "them, or take them from the paper's drive (placeholders, not your motor)",
        )
    if missing:
        template = load_scenario(DESIGN_TEMPLATE)
        for name in missing:
            table, key = DESIGN_MOTOR[name][1].split(".")
            values[name] = getattr(getattr(template, table), key)
            sources[name] = f"paper drive, preset {DESIGN_TEMPLATE}: a placeholder, not your motor"
    return {name: values[name] for name in DESIGN_MOTOR}, {name: sources[name] for name in DESIGN_MOTOR}


def _speed_controller(speed: Any) -> SpeedController:
    """The :class:`SpeedController` of a cffi ``p2d_speed_config_t``."""
    names = {"method": METHODS, "feedforward": FEEDFORWARDS, "anti_windup": ANTI_WINDUPS}
    params = {name: getattr(speed, name) for name, _ in ffi.typeof("p2d_speed_config_t").fields}
    params.update({name: choices[params[name]] for name, choices in names.items()})
    return SpeedController(**params)


def _filters_text(table: SpeedFilterTable) -> str:
    """The torque filters of a ``[speed_filter]`` table, in words."""
    parts = []
    if table.notch_freq_Hz:
        parts.append(
            f"notch at {table.notch_freq_Hz:g} Hz, {table.notch_width_Hz:g} Hz wide, depth {table.notch_depth:g}"
        )
    if table.lowpass_freq_Hz:
        parts.append(f"low-pass at {table.lowpass_freq_Hz:g} Hz, zeta {table.lowpass_zeta:g}")
    return "; ".join(parts) if parts else "none"
