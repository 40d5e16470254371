"""The engine's configuration is filled from the scenario through the generic field setter.

Every field of ``p2d_sim_config_t`` (walked here from its C declaration) holds, after
:class:`~pmsm2dof.sim.simulate.Simulation` built it, the value of the scenario key that names it
(rpm converted to rad/s, float32 fields rounded), so that a new C field needs no hand-written line.
"""

import math

import numpy as np
import pytest

from pmsm2dof.core.bindings import ENUM_CHOICES, ffi
from pmsm2dof.sim import engine_config as engine
from pmsm2dof.sim import engine_keys
from pmsm2dof.sim.scenario import SCHEMA, load_scenario
from pmsm2dof.sim.simulate import Simulation

#: Every part switched on, every value distinct from its default.
CHANGES = {
    "estimator.enabled": True,
    "estimator.adapt_gains": True,
    "estimator.J_memory_s": 5.0,
    "speed_sensor.model": "encoder",
    "speed_sensor.estimator": "pll",
    "speed_sensor.bandwidth_radps": 300.0,
    "speed_sensor.noise_rpm_rms": 2.0,
    "speed_sensor.delay_s": 0.0002,
    "speed_sensor.seed": 7,
    "current_measurement.noise_A_rms": 0.01,
    "current_measurement.gain_error_a": 0.02,
    "current_measurement.seed": 3,
    "mechanics.model": "two_mass",
    "mechanics.J_load_kgm2": 0.2,
    "mechanics.stiffness_Nm_per_rad": 500.0,
    "mechanics.damping_Nms_per_rad": 0.5,
    "mechanics.feedback": "load",
    "speed_filter.lowpass_freq_Hz": 200.0,
    "speed_filter.lowpass_zeta": 0.7,
}


#: The fields whose scenario key has another name than the field (units of the scenario: rpm), written
#: here from csrc/sim/drive.h and the scenario schema; every other field ``f`` is ``<its table>.f``.
RENAMED = {
    "current_model": "current_loop.model",
    "Ts_current_s": "current_loop.Ts_s",
    "w_m0_radps": "simulation.speed0_rpm",
    "sensing.speed_sensor.noise_rms_radps": "speed_sensor.noise_rpm_rms",
    "sensing.current_sensor.noise_rms_A": "current_measurement.noise_A_rms",
    "adapt.e_quiet_radps": "estimator.adapt_error_rpm",
}


def _leaves(obj, ctype, path=""):
    for name, field in ffi.typeof(ctype).fields:
        dotted = f"{path}{name}"
        if field.type.kind == "struct":
            yield from _leaves(getattr(obj, name), field.type.cname, dotted + ".")
        elif field.type.kind != "pointer":
            yield dotted, field.type.cname, getattr(obj, name)


def test_every_field_holds_its_scenario_key():
    scenario = load_scenario("field-weakening").with_overrides(CHANGES)
    data = scenario.data
    run = Simulation(scenario)
    keys = {f.key for f in SCHEMA}
    checked = 0
    for path, ctype, value in _leaves(run.cfg, "p2d_sim_config_t"):
        if path in ("reference.n", "load.n", "n_faults"):
            continue
        key = engine_keys.KEYS[path]
        if key is None or path in engine.derived_values(scenario, run.current_per_speed, 1):
            continue
        if path in engine.FULL_SCALES:  # given or derived for Q15 and Q31: tests/test_engine_fixed_point.py
            continue
        assert key in keys, (path, key)
        assert key == RENAMED.get(path, key.split(".")[0] + "." + path.rpartition(".")[2]), path
        table, name = key.split(".")
        given = data[table][name]
        if ctype in ENUM_CHOICES:
            assert ENUM_CHOICES[ctype][value] == given, path
        elif ctype == "_Bool":
            assert value is given, path
        else:
            expected = given / (30.0 / math.pi) if "_rpm" in name else given
            if ctype == "float":
                expected = float(np.float32(expected))
            assert value == pytest.approx(expected, rel=1e-15, abs=0.0), path
        checked += 1
    assert checked >= 75


def test_a_field_without_a_key_is_refused_when_imported():
    with pytest.raises(RuntimeError, match="no scenario key"):
        engine_keys.scenario_key("p2d_new_part.new_field_s")
