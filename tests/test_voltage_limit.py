"""The inverter's voltage range u_dc / sqrt(3) in the engine, the trace and the metrics.

Truth: the steady-state dq voltage equations of the surface PMSM (eq 1 with d/dt = 0, id = 0),
``ud = -w_e Lq iq``, ``uq = Rs iq + w_e psi_f``, against the range ``u_dc / sqrt(3)``.
"""

import math

import numpy as np
import pytest

from pmsm2dof.sim.metrics import compute_metrics, summary_lines
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import RPM_PER_RADPS, simulate
from pmsm2dof.ui.cli import main

SQRT3 = math.sqrt(3.0)


def servo(u_dc_V, speed_rpm, model="dq_pi", delay=False, load_Nm=0.0):
    """A small surface servo (p = 4, psi_f = 0.022 Wb) holding speed_rpm against load_Nm."""
    return load_scenario("paper-condition-1").with_overrides(
        {
            "motor.J_kgm2": 2e-4,
            "motor.Rs_ohm": 0.3,
            "motor.Ld_H": 5e-4,
            "motor.Lq_H": 5e-4,
            "motor.psi_f_Wb": 0.022,
            "limits.i_max_A": 20.0,
            "limits.u_dc_V": u_dc_V,
            "inverter.computation_delay": delay,
            "current_loop.model": model,
            "current_loop.tau_i_s": 1e-3,
            "speed_controller.alpha_radps": 100.0,
            "speed_controller.zeta": 0.7071,
            "simulation.speed0_rpm": speed_rpm,
            "simulation.t_end_s": 0.2,
            "reference": [{"t_s": 0.0, "speed_rpm": speed_rpm}],
            "load": [{"t_s": 0.0, "torque_Nm": load_Nm}],
        }
    )


def steady_voltage_V(s, speed_rpm, load_Nm):
    """||u_dq|| of eq 1 in steady state, id = 0."""
    m = s.data["motor"]
    w_e = m["pole_pairs"] * speed_rpm / RPM_PER_RADPS
    iq = load_Nm / (1.5 * m["pole_pairs"] * m["psi_f_Wb"])
    return math.hypot(-w_e * m["Lq_H"] * iq, m["Rs_ohm"] * iq + w_e * m["psi_f_Wb"])


@pytest.mark.parametrize("delay", [False, True])
def test_a_drive_within_its_range_is_never_voltage_limited(delay):
    s = servo(48.0, 2000.0, delay=delay, load_Nm=0.5)
    assert steady_voltage_V(s, 2000.0, 0.5) < 0.9 * 48.0 / SQRT3
    r = simulate(s)
    assert np.all(r.voltage_limited == 0.0)
    m = compute_metrics(r)
    assert m["run"]["voltage_limit_time_s"]["value"] == 0.0
    assert not any("VOLTAGE LIMIT" in line for line in summary_lines(m))


@pytest.mark.parametrize("delay", [False, True])
def test_a_drive_beyond_its_range_is_voltage_limited_and_applies_the_whole_range(delay):
    s = servo(48.0, 3000.0, delay=delay, load_Nm=1.5)
    u_max = 48.0 / SQRT3
    assert steady_voltage_V(s, 3000.0, 1.5) > 1.1 * u_max
    r = simulate(s)
    full = r.voltage_limited == 1.0
    # the load step at t = 0 asks for a current that the range cannot drive at this speed: once
    # the current has risen, the voltage stays cut
    assert full[len(full) // 4 :].all()
    # the rows whose periods were all cut apply exactly the range
    assert np.allclose(
        np.hypot(r.ud_V[full], r.uq_V[full]), u_max, rtol=1e-6
    )  # cut to the float32 range of the controller
    # and the drive slows down: the speed it can reach is below the one asked for
    assert r.speed_rpm[-1] < 3000.0 - 100.0
    m = compute_metrics(r)
    assert m["run"]["voltage_limit_time_s"]["value"] > 0.75 * r.t_s[-1]
    assert any("VOLTAGE LIMIT" in line for line in summary_lines(m))


def test_rows_below_the_range_are_not_flagged():
    s = servo(48.0, 1000.0, load_Nm=0.5).with_overrides(
        {"reference": [{"t_s": 0.0, "speed_rpm": 1000.0}, {"t_s": 0.05, "speed_rpm": 3000.0}]}
    )
    r = simulate(s)
    u = np.hypot(r.ud_V, r.uq_V)
    u_max = 48.0 / SQRT3
    assert np.all(u[r.voltage_limited == 0.0] <= u_max * (1 + 1e-12))
    assert np.any(r.voltage_limited > 0.0) and np.any(r.voltage_limited == 0.0)


def test_first_order_model_flags_the_voltage_eq_1_needs_beyond_the_range():
    low = simulate(servo(48.0, 2000.0, model="first_order", load_Nm=0.5))
    high = simulate(servo(48.0, 3000.0, model="first_order", load_Nm=1.5))
    assert np.all(low.voltage_limited == 0.0)
    # eq 3 ignores the range: the speed is held, but the voltage it needs is beyond the range
    assert abs(high.speed_rpm[-1] - 3000.0) < 1.0
    late = high.t_s > 0.1
    assert np.all(high.voltage_limited[late] == 1.0)
    assert np.all(np.hypot(high.ud_V, high.uq_V)[late] > 48.0 / SQRT3)


def test_a_zero_range_applies_exactly_zero_volts():
    """A DC link at 0 V cuts any command to exactly 0 V, a subnormal one included.

    With a speed of 1e-310 rpm the steady-state voltage of the first period is subnormal: its
    squared norm underflows to 0, which a comparison of squares let through unscaled.
    """
    s = servo(48.0, 1e-310, delay=True).with_overrides(
        {"fault": [{"kind": "dc_link_sag", "t_s": 0.0, "duration_s": 0.01, "u_dc_factor": 0.0}]}
    )
    r = simulate(s)
    window = r.t_s < 0.01
    assert np.all(r.u_dc_V[window] == 0.0)
    assert np.all(r.ud_V[window] == 0.0) and np.all(r.uq_V[window] == 0.0)


@pytest.mark.slow
def test_simulate_cli_names_the_voltage_limit(tmp_path, capsys):
    (tmp_path / "servo.toml").write_text(servo(48.0, 3000.0, load_Nm=1.5).to_toml())
    main(["simulate", str(tmp_path / "servo.toml"), "--out", str(tmp_path / "out")])
    assert "VOLTAGE LIMIT" in capsys.readouterr().out


def test_the_trace_plot_shows_the_voltage_and_its_range():
    from pmsm2dof.ui.plots.trace import trace_figure

    r = simulate(servo(48.0, 3000.0, load_Nm=1.5))
    ax_u = trace_figure(r).axes[3]
    lines = {line.get_label(): line for line in ax_u.get_lines()}
    assert np.array_equal(lines["||u_dq||"].get_ydata(), np.hypot(r.ud_V, r.uq_V))
    assert np.allclose(lines["range u_dc/sqrt(3)"].get_ydata(), 48.0 / SQRT3)
    assert "voltage limit active" in [t.get_text() for t in ax_u.get_legend().get_texts()]


def test_at_the_voltage_limit_id_stays_at_its_reference_and_the_speed_is_where_the_circle_says():
    """The maxon EC 45 flat of examples/ec45-flat asked for 6000 rpm on 24 V (above its 5409 rpm).

    d-axis priority: the d current stays at 0, so the speed settles where the steady state of eq 1
    with id = 0 reaches the range: ``(w_e Lq iq)^2 + (Rs iq + w_e psi_f)^2 = (u_dc / sqrt(3))^2``
    with the torque balance ``1.5 p psi_f iq = B w_m + T_load`` (solved here by brentq). Scaling
    the whole vector instead let id drift to +0.8 A and the speed stop 180 rpm lower.
    """
    from pathlib import Path

    from scipy.optimize import brentq

    path = Path(__file__).resolve().parents[1] / "examples" / "ec45-flat" / "drive.toml"
    s = load_scenario(path).with_overrides(
        {
            "reference": [{"t_s": 0.0, "speed_rpm": 6000.0}],
            "load": [{"t_s": 0.0, "torque_Nm": 0.1}],
            "simulation.t_end_s": 0.6,
        }
    )
    r = simulate(s)
    m, u_max = s.data["motor"], s.data["limits"]["u_dc_V"] / SQRT3
    p, psi_f, Rs, Lq, B = m["pole_pairs"], m["psi_f_Wb"], m["Rs_ohm"], m["Lq_H"], m["B_Nms"]

    def iq_of(w_m):
        return (0.1 + B * w_m) / (1.5 * p * psi_f)

    def excess(w_m):
        w_e = p * w_m
        return math.hypot(w_e * Lq * iq_of(w_m), Rs * iq_of(w_m) + w_e * psi_f) - u_max

    w_m = brentq(excess, 1.0, u_max / (p * psi_f))
    late = r.t_s > 0.4
    assert np.all(r.voltage_limited[late] == 1.0)
    assert np.max(np.abs(r.id_A[late])) < 2e-3
    assert r.speed_rpm[-1] == pytest.approx(w_m * RPM_PER_RADPS, rel=1e-3)
    assert r.iq_A[-1] == pytest.approx(iq_of(w_m), rel=1e-3)
