"""The drive as it is measured in the engine: encoder, PLL, delay, noise, current sensors, field weakening.

Truth from outside the code under test: the encoder's resolution 60 / (counts_per_rev Ts) rpm,
the linear sampled loop of :meth:`pmsm2dof.analysis.design.Design.discretize` with the sensor chain
(python-control's step response of its closed loop), the engine's own true-speed trace read
at the delayed instants, the statistics of the seeded noise, the closed current loop's gain at the
electrical frequency for a sensor offset, and the steady-state voltage equations of eq 1 solved
by SciPy for the field weakening's operating point.
"""

import math
import warnings

import control
import numpy as np
import pytest
from scipy.optimize import fsolve

from pmsm2dof import design
from pmsm2dof.analysis.sensor import SensorChain
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate

RPM = 30.0 / math.pi
BASE = load_scenario("paper-condition-2")
#: a faster drive: the paper's motor with a light load inertia and a fast current loop
SERVO = {
    "motor.J_kgm2": 0.01,
    "speed_controller.alpha_radps": 20.0,
    "speed_controller.zeta": 0.7,
    "current_loop.tau_i_s": 2e-3,
    "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
    "load": [],
}


def constant_speed(rpm, t_end_s=0.5, **sensor):
    overrides = {
        "simulation.t_end_s": t_end_s,
        "simulation.speed0_rpm": rpm,
        "reference": [{"t_s": 0.0, "speed_rpm": rpm}],
        "load": [],
    }
    overrides |= {f"speed_sensor.{k}": v for k, v in sensor.items()}
    return simulate(BASE.with_overrides(SERVO | overrides))


def test_defaults_are_the_ideal_sensor_and_keep_every_trace():
    d = BASE.data
    assert d["speed_sensor"]["model"] == "ideal" and not d["field_weakening"]["enabled"]
    plain = simulate(BASE)
    # the same scenario with the sensing tables written out at their defaults
    explicit = simulate(
        BASE.with_overrides(
            {
                "speed_sensor.model": "ideal",
                "speed_sensor.delay_s": 0.0,
                "speed_sensor.noise_rpm_rms": 0.0,
                "current_measurement.offset_a_A": 0.0,
                "field_weakening.enabled": False,
            }
        )
    )
    for name in plain.signals:
        assert np.array_equal(getattr(plain, name), getattr(explicit, name)), name
    assert np.array_equal(plain.speed_meas_rpm, plain.speed_rpm)


@pytest.mark.parametrize("counts_per_rev, counter_bits", [(4096, 32), (1000, 16), (500, 8)])
def test_difference_estimate_is_a_whole_number_of_counts_per_period(counts_per_rev, counter_bits):
    """Every reading is an integer multiple of 60 / (counts_per_rev Ts) rpm, through the counter's wrap."""
    r = simulate(
        BASE.with_overrides(
            SERVO
            | {
                "simulation.t_end_s": 1.0,
                "speed_sensor.model": "encoder",
                "speed_sensor.counts_per_rev": counts_per_rev,
                "speed_sensor.counter_bits": counter_bits,
            }
        )
    )
    resolution_rpm = 60.0 / (counts_per_rev * BASE.data["speed_controller"]["Ts_s"])
    n = r.speed_meas_rpm / resolution_rpm
    assert np.max(np.abs(n - np.round(n))) < 1e-4 * max(1.0, np.max(np.abs(n)))
    assert len(np.unique(np.round(n))) >= 5
    # the mean speed over the period, within one count of the speed at its end once the speed settles
    settled = r.t_s > 0.6
    assert np.max(np.abs(r.speed_meas_rpm[settled] - r.speed_rpm[settled])) < resolution_rpm * 1.01


def test_pll_settles_within_one_count_per_period_at_constant_speed():
    counts, Ts = 1024, BASE.data["speed_controller"]["Ts_s"]
    resolution_rpm = 60.0 / (counts * Ts)
    # 1234.5 rpm is 21.07 counts per period: the difference estimate jumps between 21 and 22 counts
    r = constant_speed(1234.5, model="encoder", estimator="pll", bandwidth_radps=100.0, counts_per_rev=counts)
    late = r.t_s > 0.3
    assert np.max(np.abs(r.speed_meas_rpm[late] - r.speed_rpm[late])) < resolution_rpm
    d = constant_speed(1234.5, model="encoder", counts_per_rev=counts)
    assert np.max(np.abs(d.speed_meas_rpm[late] - d.speed_rpm[late])) > 0.5 * resolution_rpm


@pytest.mark.slow
@pytest.mark.parametrize(
    "sensor",
    [
        SensorChain(model="encoder"),
        SensorChain(model="encoder", estimator="pll", bandwidth_radps=300.0, delay_s=1.3e-3),
        SensorChain(model="encoder", lowpass_radps=200.0, delay_s=0.4e-3),
        SensorChain(delay_s=2.0e-3, lowpass_radps=150.0),
    ],
)
def test_small_signal_step_matches_the_designed_sampled_loop(sensor):
    """Engine (first-order current loop, 1DOF PI, 2^24 counts) against Design.discretize with the chain."""
    J, alpha, zeta, tau_i, Ts = 0.4, 20.0, 0.7, 0.005, 1e-3
    step_rpm = 100.0
    overrides = {
        "motor.J_kgm2": J,
        "limits.i_max_A": 1000.0,
        "current_loop.model": "first_order",
        "current_loop.tau_i_s": tau_i,
        "speed_controller.alpha_radps": alpha,
        "speed_controller.zeta": zeta,
        "speed_controller.feedforward": "none",
        "simulation.t_end_s": 0.6,
        "reference": [{"t_s": 0.0, "speed_rpm": step_rpm}],
        "load": [],
        "speed_sensor.model": sensor.model,
        "speed_sensor.counts_per_rev": 2**24,
        "speed_sensor.estimator": sensor.estimator,
        "speed_sensor.bandwidth_radps": sensor.bandwidth_radps or None,
        "speed_sensor.lowpass_radps": sensor.lowpass_radps,
        "speed_sensor.delay_s": sensor.delay_s,
    }
    r = simulate(BASE.with_overrides(overrides))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dd = design(
            J_kgm2=J, alpha_radps=alpha, zeta=zeta, tau_i_s=tau_i, feedforward="none", sensor=sensor
        ).discretize(Ts, "tustin")
    expected = step_rpm * control.step_response(dd.Gx_z, T=r.t_s).outputs
    # quantization 60 / (2^24 Ts) = 0.0036 rpm, float32 controller, RK4 at 1e-4 s
    assert np.max(np.abs(r.speed_rpm - expected)) < 2e-3 * step_rpm
    assert 100 * (r.speed_rpm.max() / step_rpm - 1) == pytest.approx(dd.overshoot_pct, abs=0.2)


def test_delay_of_whole_speed_periods_reads_the_true_speed_that_many_samples_back():
    r = simulate(BASE.with_overrides(SERVO | {"simulation.t_end_s": 0.3, "speed_sensor.delay_s": 3e-3}))
    assert np.array_equal(r.speed_meas_rpm[3:], r.speed_rpm[:-3])
    assert np.all(r.speed_meas_rpm[:3] == BASE.data["simulation"]["speed0_rpm"])


def test_fractional_delay_interpolates_between_the_true_speeds():
    r = simulate(BASE.with_overrides(SERVO | {"simulation.t_end_s": 0.3, "speed_sensor.delay_s": 2.5e-3}))
    # w(t_k - 2.5 Ts) against the mean of the speeds 2 and 3 samples back (a smooth trace)
    mid = 0.5 * (r.speed_rpm[1:-2] + r.speed_rpm[:-3])
    span = np.ptp(r.speed_rpm)
    assert np.max(np.abs(r.speed_meas_rpm[3:] - mid)) < 2e-3 * span


def test_speed_noise_has_its_rms_and_is_reproduced_by_its_seed():
    a = constant_speed(600.0, t_end_s=2.0, noise_rpm_rms=4.0, seed=7)
    b = constant_speed(600.0, t_end_s=2.0, noise_rpm_rms=4.0, seed=7)
    c = constant_speed(600.0, t_end_s=2.0, noise_rpm_rms=4.0, seed=8)
    assert np.array_equal(a.speed_meas_rpm, b.speed_meas_rpm)
    assert not np.array_equal(a.speed_meas_rpm, c.speed_meas_rpm)
    e = a.speed_meas_rpm - a.speed_rpm
    n = len(e)
    # sample standard deviation within 4 of its standard errors (chi-square, 2001 samples)
    assert np.std(e) == pytest.approx(4.0, abs=4 * 4.0 / math.sqrt(2 * n))
    assert abs(np.mean(e)) < 4 * 4.0 / math.sqrt(n)


def test_current_offset_gives_a_torque_ripple_at_the_electrical_frequency():
    """An offset I0 on phase a reads as 2 I0 / sqrt(3) fixed in the stator: the closed current loop
    1 / (tau_i s + 1) turns it into a q current ripple of 2 I0 / sqrt(3) / |1 + j w_e tau_i|.

    At a low speed, so that the decoupling's share (w_e L times the error, rejected by the PI) and
    the speed loop's answer (alpha / w_e) stay below 1 %, with a large inertia, so that the speed
    ripple (ripple torque / (J w_e)) leaves w_e constant."""
    I0, rpm, tau_i = 0.3, 30.0, 2e-3
    d = BASE.data
    r = simulate(
        BASE.with_overrides(
            SERVO
            | {
                "motor.J_kgm2": 10.0,
                "speed_controller.alpha_radps": 0.05,
                "simulation.t_end_s": 2.0,
                "simulation.speed0_rpm": rpm,
                "reference": [{"t_s": 0.0, "speed_rpm": rpm}],
                "load": [],
                "current_measurement.offset_a_A": I0,
            }
        )
    )
    w_e = d["motor"]["pole_pairs"] * rpm / RPM
    kt = 1.5 * d["motor"]["pole_pairs"] * d["motor"]["psi_f_Wb"]
    late = r.t_s > 1.0
    t, T = r.t_s[late], r.torque_Nm[late]
    # least squares fit of T = a + b cos(w_e t) + c sin(w_e t)
    A = np.column_stack([np.ones_like(t), np.cos(w_e * t), np.sin(w_e * t)])
    coef, *_ = np.linalg.lstsq(A, T, rcond=None)
    amplitude = math.hypot(coef[1], coef[2])
    expected = kt * 2 * I0 / math.sqrt(3) / abs(1 + 1j * w_e * tau_i)
    assert amplitude == pytest.approx(expected, rel=0.02)
    # the exact sensors give no ripple
    clean = simulate(
        BASE.with_overrides(
            SERVO
            | {
                "simulation.t_end_s": 2.0,
                "simulation.speed0_rpm": rpm,
                "reference": [{"t_s": 0.0, "speed_rpm": rpm}],
            }
        )
    )
    assert np.ptp(clean.torque_Nm[late]) < 0.01 * expected


FW_DRIVE = SERVO | {
    "simulation.t_end_s": 3.0,
    "simulation.speed0_rpm": 3000.0,
    "reference": [{"t_s": 0.0, "speed_rpm": 4500.0}],
    "load": [{"t_s": 0.0, "torque_Nm": 2.0}],
}
FW_ON = {"field_weakening.enabled": True, "field_weakening.Ki_A_per_Vs": 3.0}


def test_field_weakening_reaches_a_speed_beyond_base_speed_within_voltage_and_current():
    d = BASE.data
    u_max = d["limits"]["u_dc_V"] / math.sqrt(3)
    i_max = d["limits"]["i_max_A"]
    without = simulate(BASE.with_overrides(FW_DRIVE))
    with_fw = simulate(BASE.with_overrides(FW_DRIVE | FW_ON))
    assert without.speed_rpm[-1] < 3700.0 and np.mean(without.voltage_limited[-100:]) == 1.0
    assert with_fw.speed_rpm[-1] == pytest.approx(4500.0, abs=0.5)
    assert np.max(np.hypot(with_fw.ud_V, with_fw.uq_V)) <= u_max * (1 + 1e-12)
    # the commands within i_max (float32), the currents within the current loop's tracking of them
    assert np.max(np.hypot(with_fw.id_ref_A, with_fw.iq_ref_A)) <= i_max * (1 + 1e-6)
    assert np.max(np.hypot(with_fw.id_A, with_fw.iq_A)) <= i_max * 1.01
    # no wind-up: the torque command stays within the torque the remaining q current allows
    kt = 1.5 * d["motor"]["pole_pairs"] * d["motor"]["psi_f_Wb"]
    T_lim = kt * np.sqrt(np.maximum(i_max**2 - with_fw.id_ref_A**2, 0.0))
    assert np.all(np.abs(with_fw.torque_ref_Nm) <= T_lim * (1 + 1e-5) + 1e-6)
    assert np.max(with_fw.speed_rpm) < 4500.0 * 1.02


@pytest.mark.parametrize("Ld_H, Lq_H", [(0.01, 0.01), (0.008, 0.012)])
def test_field_weakening_settles_at_the_operating_point_of_the_voltage_equations(Ld_H, Lq_H):
    """Steady state at 4500 rpm and 2 Nm: Te = 1.5 p (psi_f + (Ld - Lq) id) iq and ||u_dq|| of eq 1 at
    the regulator's 0.95 u_dc / sqrt(3), solved by SciPy; surface and salient PMSM."""
    d = BASE.data
    m = d["motor"] | {"Ld_H": Ld_H, "Lq_H": Lq_H}
    r = simulate(BASE.with_overrides(FW_DRIVE | FW_ON | {"motor.Ld_H": Ld_H, "motor.Lq_H": Lq_H}))
    w_e = m["pole_pairs"] * 4500.0 / RPM
    u_ref = 0.95 * d["limits"]["u_dc_V"] / math.sqrt(3)

    def equations(x):
        id_A, iq_A = x
        ud = m["Rs_ohm"] * id_A - w_e * m["Lq_H"] * iq_A
        uq = m["Rs_ohm"] * iq_A + w_e * (m["Ld_H"] * id_A + m["psi_f_Wb"])
        torque = 1.5 * m["pole_pairs"] * (m["psi_f_Wb"] + (m["Ld_H"] - m["Lq_H"]) * id_A) * iq_A
        return [torque - 2.0, math.hypot(ud, uq) - u_ref]

    (id_expected, iq_expected), info, ok, msg = fsolve(equations, [-3.0, 1.5], full_output=True, xtol=1e-12)
    assert ok == 1, msg
    assert -d["limits"]["i_max_A"] < id_expected < 0
    assert r.id_A[-1] == pytest.approx(id_expected, rel=0.01)
    assert r.iq_A[-1] == pytest.approx(iq_expected, rel=0.01)
    assert r.speed_rpm[-1] == pytest.approx(4500.0, abs=0.5)


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"speed_sensor.model": "encoder", "speed_sensor.estimator": "pll"}, "speed_sensor.bandwidth_radps"),
        ({"speed_sensor.estimator": "pll", "speed_sensor.bandwidth_radps": 10.0}, "speed_sensor.estimator"),
        ({"speed_sensor.delay_s": 1.0}, "speed_sensor.delay_s"),
        ({"speed_sensor.model": "encoder", "speed_sensor.bandwidth_radps": 10.0}, "speed_sensor.bandwidth_radps"),
        ({"speed_sensor.counter_bits": 33}, "speed_sensor.counter_bits"),
        ({"speed_sensor.model": "encoder", "speed_sensor.lowpass_radps": 1e6}, "speed_sensor.lowpass_radps"),
        ({"field_weakening.enabled": True}, "field_weakening.Ki_A_per_Vs"),
        (
            {"field_weakening.enabled": True, "field_weakening.Ki_A_per_Vs": 1.0, "field_weakening.Ka_V_per_A": 1e9},
            "field_weakening.Ka_V_per_A",
        ),
        ({"current_measurement.gain_error_a": -1.0}, "current_measurement.gain_error_a"),
        ({"current_loop.model": "first_order", "current_measurement.offset_b_A": 0.1}, "current_loop.model"),
    ],
)
def test_bad_sensing_keys_are_refused_by_name(overrides, key):
    with pytest.raises(ConfigError) as err:
        simulate(BASE.with_overrides(overrides))
    assert err.value.param == key
