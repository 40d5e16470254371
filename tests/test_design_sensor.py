"""The design with the speed sensor in the loop: margins, the largest alpha, the sampled loop.

Truth from outside the code under test: python-control on loop gains built here from the
formulas (``F G H`` with ``H = w^2 / (s + w)^2``), the delay's phase ``w_c T`` at the gain
crossover (a delay leaves ``|L|`` unchanged), and a sample-by-sample simulation of the sampled
loop whose plant SciPy integrates (``solve_ivp``, dense output for the delayed readings).
"""

import json
import math
import subprocess
import sys
import warnings

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsm2dof import design
from pmsm2dof.analysis.sensor import SensorChain
from pmsm2dof.errors import ConfigError

# the paper's drive (section 4) and a faster servo
PAPER = dict(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, tau_i_s=0.05)
SERVO = dict(J_kgm2=0.4, alpha_radps=20.0, zeta=0.7, tau_i_s=0.005)


def loop(params, H=None):
    """F G (H) built here from eq 2, 3 and 9."""
    J, a, z, tau = params["J_kgm2"], params["alpha_radps"], params["zeta"], params["tau_i_s"]
    Kp, Ki = J * a, J * (a / (2 * z)) ** 2
    L = control.tf([Kp, Ki], [1, 0]) * control.tf([1], [tau, 1]) * control.tf([1], [J, 0])
    return L if H is None else L * H


@pytest.mark.parametrize("delay_s", [0.01, 0.1, 0.3])
def test_exact_delay_takes_w_c_T_of_phase_at_the_crossover(delay_s):
    d = design(**PAPER, feedforward="none", sensor=SensorChain(delay_s=delay_s))
    gm, pm, _sm, w_pc, w_gc, _w_sm = control.stability_margins(loop(PAPER))
    m = d.margins()
    assert m.w_gain_crossover_radps == pytest.approx(w_gc, rel=1e-9)
    assert m.phase_margin_deg == pytest.approx(pm - math.degrees(w_gc * delay_s), abs=1e-6)
    # the gain margin: |L| at the first frequency where the phase, delay included, reaches -180 deg
    w = m.w_phase_crossover_radps
    L = control.evalfr(loop(PAPER), 1j * w) * np.exp(-1j * w * delay_s)
    assert math.degrees(np.angle(L)) == pytest.approx(-180.0, abs=1e-6) or math.degrees(np.angle(L)) == pytest.approx(
        180.0, abs=1e-6
    )
    assert m.gain_margin_dB == pytest.approx(-20 * math.log10(abs(L)), abs=1e-6)
    # the Pade approximant agrees for a delay short against the loop
    if delay_s <= 0.1:
        assert d.margins("pade").phase_margin_deg == pytest.approx(m.phase_margin_deg, abs=0.01)


def test_pll_chain_margins_are_those_of_F_G_H():
    w = 5.0
    d = design(**PAPER, feedforward="none", sensor=SensorChain(model="encoder", estimator="pll", bandwidth_radps=w))
    gm, pm, _sm, _w_pc, w_gc, _w_sm = control.stability_margins(loop(PAPER, control.tf([w * w], [1, 2 * w, w * w])))
    assert d.margins().phase_margin_deg == pytest.approx(pm, abs=1e-6)
    assert d.margins().gain_margin_dB == pytest.approx(20 * math.log10(gm), abs=1e-6)
    # the lag costs phase: the ideal sensor's margin is larger
    assert design(**PAPER, feedforward="none").margins().phase_margin_deg > pm + 5


def test_ideal_sensor_is_the_paper_loop():
    plain = design(**PAPER)
    assert plain.sensor == SensorChain() and plain.sensor.is_ideal
    assert plain.margins() == design(**PAPER, sensor=SensorChain()).margins()


@pytest.mark.parametrize(
    "sensor",
    [
        SensorChain(delay_s=0.05),
        SensorChain(model="encoder", estimator="pll", bandwidth_radps=10.0, lowpass_radps=20.0),
    ],
)
def test_largest_alpha_keeps_the_phase_margin(sensor):
    d = design(**PAPER, sensor=sensor)
    alpha = d.max_alpha_for_phase_margin(25.0)
    at = design(**(PAPER | {"alpha_radps": alpha}), feedforward="none", sensor=sensor)
    beyond = design(**(PAPER | {"alpha_radps": 1.01 * alpha}), feedforward="none", sensor=sensor)
    assert at.margins().phase_margin_deg == pytest.approx(25.0, abs=1e-4)
    assert beyond.margins().phase_margin_deg < 25.0


def test_largest_alpha_refuses_a_margin_zeta_cannot_give():
    with pytest.raises(ConfigError) as err:
        design(**PAPER).max_alpha_for_phase_margin(45.0)
    assert err.value.param == "phase_margin_deg" and "raise zeta" in str(err.value)


def simulate_sampled_loop(params, sensor, Ts_s, n_samples):
    """The 1DOF PI loop sampled at ``Ts_s``, plant integrated by SciPy, the reading of ``sensor`` at t_k - T_d.

    PI (eq 14, Tustin): u[k] = (Kp + Ki Ts/2) e[k] + x[k-1], x[k] = x[k-1] + Ki Ts e[k], e = 1 - y[k].
    Plant: tau_i T' = u - T, J w' = T, theta' = w. The encoder reads (theta(t) - theta(t - Ts)) / Ts,
    the ideal sensor w(t), at t = t_k - T_d; then the PLL and low-pass with the bilinear poles.
    """
    J, a, z, tau = params["J_kgm2"], params["alpha_radps"], params["zeta"], params["tau_i_s"]
    Kp, Ki = J * a, J * (a / (2 * z)) ** 2
    b_e0, Ki_Ts = Kp + Ki * Ts_s / 2, Ki * Ts_s
    p = (2 - sensor.bandwidth_radps * Ts_s) / (2 + sensor.bandwidth_radps * Ts_s) if sensor.pll else None
    q = (2 - sensor.lowpass_radps * Ts_s) / (2 + sensor.lowpass_radps * Ts_s) if sensor.lowpass_radps else None
    segments = []  # dense solutions of the periods, oldest first

    def state_at(t):
        if t <= 0.0:
            return np.zeros(3)
        k = min(int(t / Ts_s + 1e-9), len(segments) - 1)
        if t > (k + 1) * Ts_s + 1e-12:
            k = len(segments) - 1
        return segments[k](t)

    x, xi, y1, y2, yl = np.zeros(3), 0.0, 0.0, 0.0, 0.0
    w_out = []
    for k in range(n_samples):
        t_k = k * Ts_s
        t_read = t_k - sensor.delay_s
        if sensor.model == "encoder":
            raw = (state_at(t_read)[2] - state_at(t_read - Ts_s)[2]) / Ts_s
        else:
            raw = state_at(t_read)[1]
        if p is not None:
            y1 = p * y1 + (1 - p) * raw
            y2 = p * y2 + (1 - p) * y1
            raw = y2
        if q is not None:
            yl = q * yl + (1 - q) * raw
            raw = yl
        e = 1.0 - raw
        u = b_e0 * e + xi
        xi += Ki_Ts * e
        w_out.append(x[1])

        def rhs(_t, s, u=u):
            return [(u - s[0]) / tau, s[0] / J, s[1]]

        sol = solve_ivp(rhs, (t_k, t_k + Ts_s), x, method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)
        segments.append(sol.sol)
        x = sol.y[:, -1]
    return np.array(w_out)


@pytest.mark.parametrize(
    "sensor",
    [
        SensorChain(model="encoder"),
        SensorChain(delay_s=2.6e-3),
        SensorChain(model="encoder", estimator="pll", bandwidth_radps=300.0, delay_s=1.3e-3),
        SensorChain(model="encoder", lowpass_radps=200.0, delay_s=0.4e-3),
    ],
)
def test_sampled_loop_with_sensor_matches_a_sample_by_sample_simulation(sensor):
    Ts = 1e-3
    d = design(**SERVO, feedforward="none", sensor=sensor)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dd = d.discretize(Ts, "tustin")
    w = simulate_sampled_loop(SERVO, sensor, Ts, 600)
    overshoot = 100 * (w.max() - 1.0)
    assert dd.overshoot_pct == pytest.approx(overshoot, abs=1e-5)
    # the step response itself, sample by sample
    response = control.step_response(dd.Gx_z, T=np.arange(600) * Ts).outputs
    assert np.max(np.abs(response - w)) < 1e-7
    # the margins on the unit circle against python-control on the loop's transfer function
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control falls back to its frequency-response method
        gm, pm, _sm, _w_pc, w_gc, _w_sm = control.stability_margins(dd.L_z)
    assert dd.margins.phase_margin_deg == pytest.approx(pm, abs=1e-4)
    assert dd.margins.w_gain_crossover_radps == pytest.approx(w_gc, rel=1e-5)


def test_the_sampled_loop_refuses_an_unstable_sensor_chain():
    d = design(**SERVO, feedforward="none", sensor=SensorChain(delay_s=0.05))
    with pytest.raises(ConfigError) as err:
        d.discretize(1e-3, "tustin")
    assert err.value.param == "Ts_s" and "sensor chain" in str(err.value)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(model="hall"), "model"),
        (dict(estimator="pll"), "estimator"),  # a PLL reads counts: encoder only
        (dict(model="encoder", estimator="pll"), "bandwidth_radps"),
        (dict(lowpass_radps=-1.0), "lowpass_radps"),
        (dict(delay_s=math.inf), "delay_s"),
    ],
)
def test_sensor_chain_rejects_bad_input_by_name(kwargs, name):
    with pytest.raises(ConfigError) as err:
        SensorChain(**kwargs)
    assert err.value.param == name


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "pmsm2dof", *args], capture_output=True, text=True, timeout=300)


@pytest.mark.slow  # a fresh interpreter per CLI call
def test_cli_design_reports_the_sensor_chain_and_the_largest_alpha():
    done = run_cli(
        "design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--tau-i-s", "0.05", "--Ts-s", "1e-3",
        "--sensor", "encoder", "--estimator", "pll", "--sensor-bandwidth-radps", "20", "--sensor-delay-s", "0.02",
        "--phase-margin-deg", "20", "--json",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    data = json.loads(done.stdout)
    sensor = SensorChain(model="encoder", estimator="pll", bandwidth_radps=20.0, delay_s=0.02)
    d = design(**PAPER, sensor=sensor)
    assert data["sensor"] == dict(model="encoder", estimator="pll", bandwidth_radps=20.0, lowpass_radps=0.0,
                                  delay_s=0.02)  # fmt: skip
    assert data["continuous"]["margins"]["phase_margin_deg"] == pytest.approx(d.margins().phase_margin_deg)
    assert data["max_alpha_radps"]["alpha_radps"] == pytest.approx(d.max_alpha_for_phase_margin(20.0), rel=1e-6)
    table = run_cli("design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--Ts-s", "1e-3",
                    "--sensor-delay-s", "0.02")  # fmt: skip
    assert table.returncode == 0 and "ideal, delay 20 ms (exact delay in the margins)" in table.stdout


@pytest.mark.slow  # a fresh interpreter per CLI call
def test_cli_design_bad_sensor_input_is_one_line_and_status_2():
    done = run_cli("design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--Ts-s", "1e-3",
                   "--sensor-lowpass-radps", "-3")  # fmt: skip
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and "--sensor-lowpass-radps = -3.0 is invalid" in done.stderr
