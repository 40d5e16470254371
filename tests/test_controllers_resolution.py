"""Float32 resolution of the speed integrator under the 2DOF feedforward.

At a constant reference the feedforward outputs Fr(0) r (eq 11-13 at s = 0), so
the integral of the PI holds the load torque minus Fr(0) r: 39.4 Nm for the 8 Nm
load of the paper's drive at 500 rpm. A float32 state of that size loses every
increment Ki Ts e under half its ulp, and the speed error stalls in a dead band
that grows with the speed. The controller keeps the integrator plus the static
feedforward as its state (csrc/include/pmsm2dof/speed.h), which holds the load
torque alone, so its dead band is that of the 1DOF PI:

    |e| < ulp(T_load) / (2 Ki Ts)

with ulp taken at the load torque (the state settles there).
"""

import numpy as np
import pytest

import pmsm2dof

RPM_PER_RADPS = 60.0 / (2.0 * np.pi)
TS_SPEED_S = 1e-4
T_END_S = 60.0
MEAN_FROM_S = 50.0


@pytest.mark.parametrize("feedforward", ["none", "lowpass"])
def test_steady_speed_error_within_the_load_torque_dead_band(feedforward):
    scenario = pmsm2dof.load_scenario("paper-experiment-3").with_overrides(
        {
            "speed_controller.Ts_s": TS_SPEED_S,
            "simulation.t_end_s": T_END_S,
            "speed_controller.feedforward": feedforward,
        }
    )
    d = scenario.data
    sc = d["speed_controller"]
    J, alpha, zeta = sc["J_kgm2"], sc["alpha_radps"], sc["zeta"]
    T_load_Nm = d["load"][-1]["torque_Nm"]
    # eq 9: Ki = J (alpha / (2 zeta))^2
    Ki = J * (alpha / (2.0 * zeta)) ** 2
    dead_band_rpm = float(np.spacing(np.float32(T_load_Nm))) / (2.0 * Ki * TS_SPEED_S) * RPM_PER_RADPS

    r = pmsm2dof.simulate(scenario)
    last = r.t_s >= MEAN_FROM_S
    error_rpm = np.mean(r.speed_ref_rpm[last] - r.speed_rpm[last])
    # the loop has settled: the state is the load torque (physical balance, B = 0)
    assert np.mean(r.torque_Nm[last]) == pytest.approx(T_load_Nm, abs=1e-3)
    # the 2DOF feedforward's static part Fr(0) r = -31.4 Nm would widen it to 0.6 rpm
    assert abs(error_rpm) < dead_band_rpm, (error_rpm, dead_band_rpm)
