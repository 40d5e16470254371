"""The Python objects over the encoder speed estimators and the field weakening (csrc/src).

Truth from outside the code under test: the counts of an angle trajectory counted here, the
PLL's and the low-pass's designed discrete transfer functions run by SciPy (``lfilter``), and
the steady-state voltage equations of the dq model (paper eq 1) solved for the d current.
"""

import math

import numpy as np
import pytest
from scipy import signal

from pmsm2dof.core import ESTIMATORS, Encoder, FieldWeakening, SpeedController
from pmsm2dof.core.bindings import lib
from pmsm2dof.errors import ConfigError

TS = 1e-3
CPR = 10000


def counts_of(theta_rad, cpr=CPR, bits=16, offset=0):
    """The readings of a ``bits``-bit counter of ``cpr`` counts/rev at the angles ``theta_rad``."""
    n = np.floor(np.asarray(theta_rad) * cpr / (2 * math.pi)).astype(np.int64)
    return (n + offset) % 2**bits, n


def trajectory(n=3000):
    """Angles of a drive accelerating to 150 rad/s, cruising, then reversing to -100 rad/s."""
    t = np.arange(1, n + 1) * TS
    w = np.interp(t, [0.0, 0.5, 1.5, 2.5, 3.0], [0.0, 150.0, 150.0, -100.0, -100.0])
    return np.concatenate(([0.0], np.cumsum(w) * TS))[1:], w


def test_estimator_names_are_the_c_enum():
    assert ESTIMATORS == ("difference", "pll")
    assert (lib.P2D_ESTIMATOR_DIFFERENCE, lib.P2D_ESTIMATOR_PLL) == (0, 1)


def test_difference_is_an_integer_multiple_of_the_resolution_through_the_wrap():
    theta, _ = trajectory()
    readings, n = counts_of(theta, offset=65000)
    enc = Encoder(counts_per_rev=CPR, counter_bits=16, Ts_s=TS, estimator="difference")
    enc.reset(int(counts_of(0.0, offset=65000)[0]))
    res = 2 * math.pi / (CPR * TS)
    assert enc.resolution_radps == pytest.approx(res, rel=1e-7)
    dn_expected = np.diff(np.concatenate(([0], n)))
    outs = [enc.step(int(r)) for r in readings]
    assert [o.dn_counts for o in outs] == dn_expected.tolist()
    w = np.array([o.w_m_radps for o in outs])
    multiples = w / enc.resolution_radps
    assert np.max(np.abs(multiples - np.round(multiples))) < 1e-4
    assert np.array_equal(np.round(multiples), dn_expected)


def test_pll_and_lowpass_follow_their_designed_transfer_functions():
    """W / (w_res DN) = (1 - p)^2 / (1 - p z^-1)^2 and Y / W = (1 - q) / (1 - q z^-1), p and q bilinear."""
    theta, _ = trajectory()
    readings, n = counts_of(theta)
    enc = Encoder(counts_per_rev=CPR, counter_bits=16, Ts_s=TS, estimator="pll", bandwidth_radps=300.0,
                  lowpass_radps=500.0)  # fmt: skip
    enc.reset(0)
    outs = [enc.step(int(r)) for r in readings]
    dn = np.diff(np.concatenate(([0], n))).astype(float)
    res = 2 * math.pi / (CPR * TS)
    p = (2 - 300 * TS) / (2 + 300 * TS)
    q = (2 - 500 * TS) / (2 + 500 * TS)
    w_pll = signal.lfilter([(1 - p) ** 2], np.polymul([1, -p], [1, -p]), res * dn)
    w_lp = signal.lfilter([1 - q], [1, -q], w_pll)
    assert np.max(np.abs(np.array([o.w_raw_radps for o in outs]) - w_pll)) < 2e-3
    assert np.max(np.abs(np.array([o.w_m_radps for o in outs]) - w_lp)) < 2e-3


def test_pll_settles_within_one_count_per_period():
    w_true = 123.456
    readings, _ = counts_of(0.3 + w_true * TS * np.arange(1, 2001), bits=32)
    enc = Encoder(counts_per_rev=CPR, Ts_s=TS, estimator="pll", bandwidth_radps=200.0)
    enc.reset(int(counts_of(0.3, bits=32)[0]))
    w = np.array([enc.step(int(r)).w_m_radps for r in readings])
    assert np.max(np.abs(w[200:] - w_true)) < enc.resolution_radps
    # the difference estimator alternates between neighbouring multiples instead
    enc = Encoder(counts_per_rev=CPR, Ts_s=TS, estimator="difference")
    enc.reset(int(counts_of(0.3, bits=32)[0]))
    w_diff = np.array([enc.step(int(r)).w_m_radps for r in readings])
    assert np.max(np.abs(w_diff[200:] - w_true)) > 0.3 * enc.resolution_radps


@pytest.mark.parametrize(
    "changes, name",
    [
        ({"counts_per_rev": 0}, "counts_per_rev"),
        ({"counter_bits": 1}, "counter_bits"),
        ({"counter_bits": 33}, "counter_bits"),
        ({"estimator": "kalman"}, "estimator"),
        ({"bandwidth_radps": 2500.0}, "bandwidth_radps"),
        ({"bandwidth_radps": 0.5}, "bandwidth_radps"),
        ({"lowpass_radps": -1.0}, "lowpass_radps"),
        ({"Ts_s": 0.0}, "Ts_s"),
        ({"counts_per_rev": 2.5}, "counts_per_rev"),
    ],
)
def test_encoder_rejects_a_bad_parameter_by_name(changes, name):
    params = dict(counts_per_rev=CPR, counter_bits=16, Ts_s=TS, estimator="pll", bandwidth_radps=200.0)
    with pytest.raises(ConfigError) as err:
        Encoder(**{**params, **changes})
    assert err.value.param == name
    assert repr(next(iter(changes.values()))) in str(err.value)
    # set_config: refused, the old configuration stays
    enc = Encoder(**params)
    with pytest.raises(ConfigError):
        enc.set_config(**changes)
    assert enc.config == Encoder(**params).config


def test_encoder_set_config_keeps_the_state_and_reset_takes_the_reading():
    enc = Encoder(counts_per_rev=CPR, Ts_s=TS, estimator="pll", bandwidth_radps=200.0)
    enc.reset(1000, 50.0)
    assert enc.state["count_prev"] == 1000 and enc.state["w_lowpass_radps"] == 50.0
    for k in range(1, 100):
        enc.step(1000 + 80 * k)
    before = enc.state
    enc.set_config(bandwidth_radps=50.0, lowpass_radps=100.0)
    assert enc.state == before and Encoder(**enc.config).config == enc.config
    with pytest.raises(ConfigError) as err:
        enc.set_config(poles=3)
    assert err.value.param == "poles"
    with pytest.raises(ConfigError):
        enc.reset(0, math.nan)
    with pytest.raises(ConfigError):
        enc.step(1.5)


def fw_params(**changes):
    return dict(Kp_A_per_V=0.02, Ki_A_per_Vs=100.0, Ka_V_per_A=50.0, Ts_s=1e-4, voltage_ratio=0.95,
                id_min_A=-15.0) | changes  # fmt: skip


def test_field_weakening_settles_on_the_steady_state_voltage_equations():
    """An ideal current loop at 2000 rad/s electrical: ||u(id, iq)|| = 0.95 u_dc/sqrt(3) at the settled id."""
    Rs, L, psi, w_e, iq, u_dc = 0.2, 1e-3, 0.02, 2000.0, 5.0, 48.0
    U = 0.95 * u_dc / math.sqrt(3)
    fw = FieldWeakening(**fw_params())
    id_ = 0.0
    for _ in range(20000):
        out = fw.step(Rs * id_ - w_e * L * iq, Rs * iq + w_e * (L * id_ + psi), u_dc)
        id_ = out.id_ref_A
    # (Rs id - w L iq)^2 + (Rs iq + w (L id + psi))^2 = U^2, the root nearer 0
    a = Rs**2 + (w_e * L) ** 2
    b = 2 * (-Rs * w_e * L * iq + (Rs * iq + w_e * psi) * w_e * L)
    c = (w_e * L * iq) ** 2 + (Rs * iq + w_e * psi) ** 2 - U**2
    id_expected = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert out.active and not out.at_id_min and not out.fault
    assert id_ == pytest.approx(id_expected, rel=1e-4)


@pytest.mark.parametrize(
    "changes, name",
    [
        ({"Kp_A_per_V": -1.0}, "Kp_A_per_V"),
        ({"Ki_A_per_Vs": 0.0}, "Ki_A_per_Vs"),
        ({"Ka_V_per_A": 1e6}, "Ka_V_per_A"),
        ({"voltage_ratio": 1.5}, "voltage_ratio"),
        ({"id_min_A": 1.0}, "id_min_A"),
        ({"method": "rk4"}, "method"),
    ],
)
def test_field_weakening_rejects_a_bad_parameter_by_name(changes, name):
    with pytest.raises(ConfigError) as err:
        FieldWeakening(**fw_params(**changes))
    assert err.value.param == name


def test_field_weakening_holds_its_current_on_a_nan_voltage():
    fw = FieldWeakening(**fw_params())
    fw.reset(-3.0)
    out = fw.step(math.nan, 1.0, 48.0)
    assert out.fault and out.id_ref_A == -3.0 and fw.x_A == -3.0 and fw.fault_count == 1


def test_speed_step_fw_limits_the_torque_to_the_q_current_that_remains():
    speed = dict(J_kgm2=0.02, alpha_radps=200.0, zeta=1.0, Ts_s=1e-4, i_max_A=10.0, psi_f_Wb=0.05, Ld_H=2e-3,
                 Lq_H=2e-3, pole_pairs=4)  # fmt: skip
    a, b = SpeedController(**speed), SpeedController(**speed)
    for k in range(50):
        assert a.step(10.0, 0.1 * k) == b.step_fw(10.0, 0.1 * k, 0.0)
    c = SpeedController(**speed)
    out = c.compute_fw(100.0, 0.0, -6.0)
    kt = 1.5 * 4 * 0.05
    assert out.saturated and out.id_ref_A == -6.0
    assert out.T_ref_Nm == pytest.approx(kt * 8.0, rel=1e-6) and out.iq_ref_A == pytest.approx(8.0, rel=1e-6)
