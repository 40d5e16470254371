"""The virtual board's header: the engine's plant of a scenario, its schedules and its run, as C data.

``examples/firmware/board_virtual.c`` runs the firmware against the engine's plant
(``csrc/sim/plant.c``); :func:`virtual_drive_header` writes what it needs of a scenario
(``p2d_virtual_drive.h``), after :func:`check_virtual_drive` has refused what the virtual board
does not model.
"""

from ..analysis.codegen import c_double, config_header
from ..core.bindings import ffi
from ..errors import ConfigError
from ..sim.scenario import Scenario
from ..sim.simulate import RPM_PER_RADPS
from .configuration import Configuration

#: The prefix of the virtual board's header (examples/firmware/board_virtual.c includes p2d_virtual_drive.h).
VIRTUAL_DRIVE_PREFIX = "p2d_vd"
#: The virtual core of virtual_target_mps2.c: a 170 MHz Cortex-M4 at 1.5 cycles per instruction.
CORE_CLOCK_HZ = 170e6
CYCLES_PER_INSTRUCTION = 1.5
#: Longest current period the virtual board's SysTick holds: 2^24 ticks of 40 ns at 3.2 ticks per instruction [s].
TS_CURRENT_MAX_S = 2**24 / 3.2 * CYCLES_PER_INSTRUCTION / CORE_CLOCK_HZ


def check_virtual_drive(scenario: Scenario) -> None:
    """Raise ConfigError for what the virtual board does not model (the engine does).

    The virtual board runs the firmware's dq current controllers against eq 1, reads the speed as
    the plant has it (or its encoder's counter) and plays no fault.
    """
    if scenario.current_loop.model != "dq_pi":
        raise ConfigError(
            "current_loop.model",
            scenario.current_loop.model,
            "'dq_pi' for the firmware: it runs the dq current controllers against the motor of eq 1",
        )
    if scenario.fault:
        raise ConfigError("fault", f"<{len(scenario.fault)} entries>", "none: the virtual board plays no fault")
    if scenario.simulation.log_rate != "speed":
        raise ConfigError(
            "simulation.log_rate",
            scenario.simulation.log_rate,
            "'speed' for the firmware: its trace holds a row per speed sample",
        )
    ss = scenario.speed_sensor
    for key, value in (("delay_s", ss.delay_s), ("noise_rpm_rms", ss.noise_rpm_rms)):
        if value != 0.0:
            raise ConfigError(f"speed_sensor.{key}", value, "0: the virtual board has no delay or noise on the speed")
    if scenario.current_loop.Ts_s > TS_CURRENT_MAX_S:
        raise ConfigError(
            "current_loop.Ts_s",
            scenario.current_loop.Ts_s,
            f"<= {TS_CURRENT_MAX_S:.4g} s on the virtual board (the 24-bit SysTick at its instruction clock)",
        )


def virtual_drive_header(config: Configuration) -> str:
    """The text of ``p2d_virtual_drive.h``: the virtual board's plant, schedules and run.

    Defines ``p2d_vd_plant`` (``p2d_plant_config_t``: the engine's plant of the scenario; its
    initial currents are set when the firmware starts), the reference [rad/s] and load [Nm]
    schedules as arrays ``p2d_vd_reference_*``, ``p2d_vd_load_*``, and the macros
    ``P2D_VD_CURRENT_PER_SPEED``, ``P2D_VD_SPEED_SAMPLES`` (the engine's samples of the run),
    ``P2D_VD_LOG_EVERY``, ``P2D_VD_I_MAX_A``, ``P2D_VD_REFERENCE_N``, ``P2D_VD_LOAD_N`` and
    ``P2D_VD_CURRENT_SENSOR_ERRORS``.

    Raises
    ------
    ConfigError
        The scenario needs what the virtual board does not model (:func:`check_virtual_drive`).
    """
    scenario = config.scenario
    check_virtual_drive(scenario)
    cfg = config.engine.cfg
    # the plant the engine builds from its configuration (csrc/sim/drive.c, plant_config)
    plant = ffi.new("p2d_plant_config_t *")[0]
    plant.motor = cfg.motor
    plant.mechanics = cfg.mechanics
    plant.u_dc_V = cfg.u_dc_V
    plant.computation_delay = cfg.computation_delay
    plant.Ts_s = cfg.Ts_current_s
    plant.substeps = cfg.substeps
    plant.w_m0_radps = cfg.w_m0_radps
    plant.current_sensor = cfg.sensing.current_sensor
    encoder = scenario.speed_sensor.model == "encoder"
    plant.counts_per_rev = cfg.sensing.speed_sensor.encoder.counts_per_rev if encoder else 0
    cm = scenario.current_measurement
    errors = any(e != 0.0 for e in (cm.gain_error_a, cm.gain_error_b, cm.offset_a_A, cm.offset_b_A, cm.noise_A_rms))
    reference = scenario.reference
    load = scenario.load
    macros = [
        ("CURRENT_PER_SPEED", f"{config.current_per_speed}u", "current periods per speed period [-]"),
        ("SPEED_SAMPLES", f"{config.engine.n_samples}u", "speed samples of the run (t_end) [-]"),
        ("LOG_EVERY", f"{scenario.simulation.log_every}u", "a trace row every LOG_EVERY-th speed sample [-]"),
        ("I_MAX_A", c_double(float(cfg.speed.i_max_A)), "current limit of the speed controller [A]"),
        ("REFERENCE_N", f"{len(reference)}u", "entries of the speed reference [-]"),
        ("LOAD_N", f"{len(load)}u", "entries of the load torque [-]"),
        ("CURRENT_SENSOR_ERRORS", str(int(errors)), "1: the current sensors have gain errors, offsets or noise"),
    ]
    # the values as the engine's schedules hold them (pmsm2dof.sim.simulate._schedule)
    arrays = [
        ("reference_t_s", [e.t_s for e in reference], "entry times of the speed reference [s]"),
        (
            "reference_radps",
            [e.speed_rpm * (1.0 / RPM_PER_RADPS) for e in reference],
            "speed reference entries [rad/s]",
        ),
        ("reference_ramp_s", [e.ramp_s for e in reference], "ramp of each speed reference entry [s]"),
        ("load_t_s", [e.t_s for e in load], "entry times of the load torque [s]"),
        ("load_Nm", [e.torque_Nm for e in load], "load torque entries [Nm]"),
        ("load_ramp_s", [e.ramp_s for e in load], "ramp of each load torque entry [s]"),
    ]
    return config_header(
        prefix=VIRTUAL_DRIVE_PREFIX,
        title=f'p2d_virtual_drive.h: the virtual board of "{scenario.name}" (examples/firmware/board_virtual.c)',
        record=[
            "The engine's plant of the scenario (csrc/sim/plant.h), its reference and load schedules and",
            "the length of its run; the controllers are in p2d_config.h.",
        ],
        includes=["plant.h"],
        macros=macros,
        blocks=[("p2d_plant_config_t", "plant", plant, "The virtual motor, inverter and sensors (p2d_plant_init).")],
        arrays=arrays,
    )
