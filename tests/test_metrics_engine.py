"""Metrics of real engine runs in the linear regime against the paper's transfer functions.

With the first-order current loop (eq 3) and the full feedforward (eq 11), the tracking response
is Gx = m alpha / (s + m alpha) (eq 10): rise time ln(9) / (m alpha), 2 % settling time
ln(50) / (m alpha), no overshoot. The load response is GN of eq 8 for every feedforward; its
peak and its 2 % recovery are found here on the closed-form step response (partial fractions
of GN(s)/s by scipy.signal.residue, roots by brentq). The steps are small so that nothing
saturates. The tolerances allow for the 1 ms sampling of the speed loop (a delay of about
Ts/2 against the continuous design) and the float32 controller.
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.signal import residue

from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate

RPM_PER_RADPS = 30 / math.pi


def linear_scenario(**overrides):
    base = load_scenario("paper-condition-2").with_overrides(
        {"current_loop.model": "first_order", "speed_controller.feedforward": "full", "load": []}
    )
    return base.with_overrides(overrides)


@pytest.mark.parametrize("m", [1.0, 2.0])
def test_reference_step_follows_eq_10(m):
    alpha = 0.5
    s = linear_scenario(
        **{"speed_controller.m": m, "simulation.t_end_s": 20.0, "reference": [{"t_s": 0.5, "speed_rpm": 1.0}]}
    )
    result = simulate(s)
    assert not result.saturated.any()
    step = compute_metrics(result)["reference_steps"][0]
    p = m * alpha
    # within five speed-controller samples (Ts = 1 ms): what sampling the continuous design explains
    assert step["rise_time_s"]["value"] == pytest.approx(math.log(9) / p, abs=5e-3)
    assert step["settling_time_s"]["value"] == pytest.approx(math.log(50) / p, abs=5e-3)
    assert step["overshoot_pct"]["value"] < 0.1
    assert abs(step["steady_state_error_rpm"]["value"]) < 1e-3
    # IAE of a first-order response to a unit step: 1 / p (times the step, window long enough)
    assert step["iae_rpm_s"]["value"] == pytest.approx(1.0 / p, rel=2e-3)


def gn_step(J, tau_i, Kp, Ki, dT):
    """Speed response [rad/s] to a load step dT, eq 8: -(tau s^2 + s) / (J tau s^3 + J s^2 + Kp s + Ki) / s."""
    r, p, _ = residue([-tau_i * dT, -dT], [J * tau_i, J, Kp, Ki])  # GN(s)/s = -(tau s + 1) dT / (...)
    return lambda t: np.real(np.exp(np.multiply.outer(t, p)) @ r)


@pytest.mark.parametrize("feedforward", ["none", "lowpass", "full"])
def test_load_step_follows_eq_8(feedforward):
    J, alpha, zeta, tau_i, dT, t_load = 0.4, 0.5, 1 / (2 * math.sqrt(3)), 0.05, 1.0, 1.0
    Kp, Ki = J * alpha, J * (alpha / (2 * zeta)) ** 2  # eq 9
    s = linear_scenario(
        **{
            "speed_controller.feedforward": feedforward,
            "simulation.t_end_s": 45.0,
            "simulation.speed0_rpm": 100.0,
            "reference": [{"t_s": 0.0, "speed_rpm": 100.0}],
            "load": [{"t_s": t_load, "torque_Nm": dT}],
        }
    )
    result = simulate(s)
    assert not result.saturated.any()
    step = compute_metrics(result)["load_steps"][0]

    w = gn_step(J, tau_i, Kp, Ki, dT)
    grid = np.linspace(0.0, 44.0, 440001)
    deviation_radps = -w(grid)
    k = int(np.argmax(deviation_radps))
    t_peak = brentq(lambda x: w(x + 1e-6) - w(x - 1e-6), grid[k - 1], grid[k + 1])
    dip = -w(t_peak) * RPM_PER_RADPS
    band = 0.02 * dip / RPM_PER_RADPS
    last_out = np.nonzero(np.abs(deviation_radps) > band)[0][-1]
    recovery = brentq(lambda x: abs(w(x)) - band, grid[last_out], grid[last_out + 1])

    assert step["speed_dip_rpm"]["value"] == pytest.approx(dip, rel=1e-3)
    assert step["dip_time_s"]["value"] == pytest.approx(t_peak, abs=1e-3)
    assert step["recovery_time_s"]["value"] == pytest.approx(recovery, abs=5e-3)
    assert abs(step["steady_state_error_rpm"]["value"]) < 0.002 * dip
