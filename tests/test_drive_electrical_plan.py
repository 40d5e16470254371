"""The plan of `drive identify --electrical` (pmsm2dof.studies.drive_electrical.plan_electrical) and its refusals.

Truth by hand: the steady voltage of eq 1 at the plan's top speed and current (ud = -w_e Lq iq,
uq = Rs iq + w_e psi_f at id = 0) against the drive's limit 0.9 u_dc / sqrt(3), for the configured
motor and for one whose flux is twice the configured one; J dw/dt = 1.5 p psi_f iq for the steps'
longest times.
"""

import math

import pytest

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.drive_electrical import STEPS_MAX, plan_electrical
from pmsm2dof.ui.cli import main

SERVO = "examples/firmware/small-servo-20k.toml"


def voltage_V(motor, i_A, w_m_radps, psi_factor=1.0):
    """|u_dq| of eq 1 in steady state at id = 0, iq = i_A and the mechanical speed w_m_radps."""
    w_e = motor.pole_pairs * w_m_radps
    return math.hypot(w_e * motor.Lq_H * i_A, motor.Rs_ohm * i_A + w_e * psi_factor * motor.psi_f_Wb)


@pytest.mark.parametrize("overrides", [{}, {"motor.Lq_H": 1e-3, "limits.u_dc_V": 24.0, "limits.i_max_A": 6.0}])
def test_the_plan_stays_inside_the_drives_limits(overrides):
    drive = load_scenario(SERVO).with_overrides(overrides)
    plan = plan_electrical(drive)
    motor, limits = drive.motor, drive.limits
    u_limit = 0.9 * limits.u_dc_V / math.sqrt(3.0)
    assert len(plan.steps) <= STEPS_MAX
    assert plan.i_A == 0.5 * limits.i_max_A and plan.i_trip_A < limits.i_max_A
    assert all(math.hypot(s.id_A, s.iq_A) <= plan.i_A for s in plan.steps)
    # at the top speed, the configured motor and one with twice its flux stay inside 0.9 u_dc / sqrt(3)
    assert voltage_V(motor, plan.i_A, plan.w_high_radps) <= u_limit
    assert voltage_V(motor, plan.i_A, plan.w_high_radps, psi_factor=2.0) <= u_limit
    assert plan.w_trip_radps > plan.w_high_radps
    # d-axis steps at standstill (no q current: no torque), then q-axis steps at speed ending at rest
    d_steps = [s for s in plan.steps if s.id_A != 0.0]
    assert len(d_steps) == 4 and all(s.iq_A == 0.0 for s in d_steps) and max(s.id_A for s in d_steps) == plan.i_A
    q_steps = [s for s in plan.steps if s.iq_A != 0.0]
    assert [s.w_end_radps for s in q_steps] == pytest.approx(
        [plan.w_high_radps, plan.w_high_radps / 2] * 2 + [plan.w_high_radps, 0.0]
    )
    # a q step lasts at most three times what the configured inertia needs at I (J dw/dt = 1.5 p psi_f iq)
    acc = 1.5 * motor.pole_pairs * motor.psi_f_Wb * plan.i_A / drive.speed_controller.J_kgm2
    assert q_steps[0].t_s == pytest.approx(3.0 * plan.w_high_radps / acc)


def test_a_lower_top_speed_is_taken_a_higher_one_refused():
    drive = load_scenario(SERVO)
    top_rpm = plan_electrical(drive).w_high_radps * 30 / math.pi
    assert plan_electrical(drive, 0.5 * top_rpm).w_high_radps == pytest.approx(0.5 * top_rpm * math.pi / 30)
    for bad in (2.0 * top_rpm, 0.0, -100.0, math.nan):
        with pytest.raises(ConfigError, match="speed_max_rpm"):
            plan_electrical(drive, bad)


def test_motor_with_electrical_is_refused_in_one_line_before_any_link(tmp_path, capsys):
    out = tmp_path / "e"
    argv = ["drive", "identify", "--electrical", "--motor", "m.toml", "--out", str(out), "--link",
            "tcp://127.0.0.1:1", "--a2l", "x.a2l"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--motor" in err and "--electrical" in err
    assert not out.exists()
