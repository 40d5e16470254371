"""The scenario keys and Python API of the drive train and the torque filters.

- the rigid default leaves every existing key as it was, and a two-mass train designs eq 9 on
  the total inertia unless speed_controller.J_kgm2 is given;
- a scenario with [mechanics] and [speed_filter] survives to_toml and load_scenario;
- SpeedController's filter parameters are the C library's p2d_speed_set_filter, and set_config
  with a rejected filter changes nothing (the old configuration and state stay).
"""

import numpy as np
import pytest

from pmsm2dof.core import SpeedController
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario

TRAIN = {
    "motor.J_kgm2": 0.1,
    "mechanics.model": "two_mass",
    "mechanics.J_load_kgm2": 0.3,
    "mechanics.stiffness_Nm_per_rad": 1000.0,
}
FILTERS = dict(notch_freq_Hz=40.0, notch_width_Hz=15.0, notch_depth=0.05, lowpass_freq_Hz=200.0, lowpass_zeta=0.7)
MOTOR = dict(i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01, pole_pairs=4)


def test_rigid_default_and_the_design_inertia():
    base = load_scenario("paper-condition-2")
    data = base.data
    assert data["mechanics"] == {
        "model": "rigid",
        "J_load_kgm2": None,
        "stiffness_Nm_per_rad": None,
        "damping_Nms_per_rad": 0.0,
        "backlash_rad": 0.0,
        "feedback": "motor",
    }
    assert all(v == 0.0 for v in data["speed_filter"].values())
    train = base.with_overrides(TRAIN).data
    assert train["speed_controller"]["J_kgm2"] == pytest.approx(0.4, rel=1e-15)
    given = base.with_overrides({**TRAIN, "speed_controller.J_kgm2": 0.25}).data
    assert given["speed_controller"]["J_kgm2"] == 0.25


def test_two_mass_scenario_round_trips_through_toml(tmp_path):
    chosen = load_scenario("paper-condition-2").with_overrides(
        {**TRAIN, "mechanics.backlash_rad": 1e-3, "mechanics.feedback": "load"}
        | {f"speed_filter.{k}": v for k, v in FILTERS.items()}
    )
    path = tmp_path / "two-mass.toml"
    path.write_text(chosen.to_toml())
    assert load_scenario(str(path)) == chosen


def test_speed_controller_filters_are_the_c_set_filter():
    w_ref = np.repeat([0.0, 3.0, -2.0, 1.0], 50)
    w_m = 0.8 * w_ref + 0.3 * np.sin(0.25 * np.arange(w_ref.size))
    wrapped = SpeedController(J_kgm2=0.4, alpha_radps=20.0, zeta=0.7, Ts_s=1e-3, **MOTOR, **FILTERS).run(w_ref, w_m)
    plain = SpeedController(J_kgm2=0.4, alpha_radps=20.0, zeta=0.7, Ts_s=1e-3, **MOTOR)
    cfg = ffi.new("p2d_filter_config_t *", FILTERS)
    assert lib.p2d_speed_set_filter(plain._ctl, cfg) == lib.P2D_OK
    direct = plain.run(w_ref, w_m)
    for name in ("T_unsat_Nm", "T_ref_Nm", "iq_ref_A", "x_i_Nm"):
        np.testing.assert_array_equal(wrapped[name], direct[name], err_msg=name)


def test_rejected_filter_in_set_config_changes_nothing():
    ctl = SpeedController(J_kgm2=0.4, alpha_radps=20.0, zeta=0.7, Ts_s=1e-3, **MOTOR, **FILTERS)
    ctl.step(2.0, 1.0)
    before = (ctl.config, ctl.state, ctl.coefficients)
    with pytest.raises(ConfigError) as err:
        ctl.set_config(alpha_radps=30.0, notch_freq_Hz=600.0)  # above 1/(2 Ts)
    assert err.value.param == "notch_freq_Hz"
    assert (ctl.config, ctl.state, ctl.coefficients) == before
    ctl.set_config(lowpass_freq_Hz=0.0)
    assert ctl.config["lowpass_freq_Hz"] == 0.0 and ctl.config["notch_freq_Hz"] == 40.0
    assert SpeedController(**ctl.config).config == ctl.config
