"""Property tests (hypothesis) of the C controllers through their Python objects.

Per anti-windup mode: the current command never exceeds the limit and stays
finite for finite input; under a sustained saturating error the integrator
stays bounded with back calculation (it contracts onto the fixed point of
Fig. 5's loop) and with clamping, and grows without bound with none. Invalid
parameters raise ConfigError naming the parameter; non-finite inputs raise the
fault flag with a zero, finite output and leave the state intact.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pmsm2dof.core import ANTI_WINDUPS, FEEDFORWARDS, METHODS, CurrentController, SpeedController
from pmsm2dof.errors import ConfigError

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def f32(x):
    return float(np.float32(x))


@st.composite
def speed_configs(draw, anti_windup=None, feedforward=None):
    """Valid speed-controller configurations over wide ranges.

    alpha Ts <= 0.5, zeta >= 0.3 and m <= 3 keep the forward-Euler feedforward
    pole (m alpha Ts < 2) and the default back-calculation loop
    (Ki Ka Ts = alpha Ts / (4 zeta^2) < 2) stable, as init requires.
    """
    Ts = draw(st.floats(1e-5, 1e-3))
    Ld = draw(st.floats(1e-4, 1e-2))
    salient = draw(st.booleans())
    ff = feedforward or draw(st.sampled_from(FEEDFORWARDS))
    return dict(
        J_kgm2=draw(st.floats(1e-4, 10.0)),
        alpha_radps=draw(st.floats(1.0, 0.5 / Ts)),
        zeta=draw(st.floats(0.3, 3.0)),
        m=1.0 if ff == "lowpass" else draw(st.floats(0.2, 3.0)),
        tau_i_s=draw(st.floats(0.0, 0.05)),
        Ts_s=Ts,
        i_max_A=draw(st.floats(0.1, 500.0)),
        psi_f_Wb=draw(st.floats(0.005, 1.0)),
        Ld_H=Ld,
        Lq_H=draw(st.floats(1e-4, 1e-2)) if salient else Ld,
        pole_pairs=draw(st.integers(1, 12)),
        method=draw(st.sampled_from(METHODS)),
        feedforward=ff,
        anti_windup=anti_windup or draw(st.sampled_from(ANTI_WINDUPS)),
    )


speeds = st.lists(st.floats(-1e4, 1e4, width=32), min_size=1, max_size=300)


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
@SETTINGS
@given(data=st.data())
def test_command_within_limit_and_finite(anti_windup, data):
    cfg = data.draw(speed_configs(anti_windup=anti_windup))
    w_ref = np.array(data.draw(speeds))
    w_m = np.array(data.draw(st.lists(st.floats(-1e4, 1e4, width=32), min_size=len(w_ref), max_size=len(w_ref))))
    ctl = SpeedController(**cfg)
    out = ctl.run(w_ref, w_m)
    i_norm = np.hypot(out["id_ref_A"].astype(float), out["iq_ref_A"].astype(float))
    assert np.all(i_norm <= f32(cfg["i_max_A"]) * (1 + 4e-7 * 4)), "||i_dq|| <= i_max (float32 slack)"
    T_max = ctl.coefficients["T_max_Nm"]
    assert np.all(np.abs(out["T_ref_Nm"]) <= T_max)
    for name, values in out.items():
        assert np.all(np.isfinite(values)), name
    assert not out["fault"].any()


@pytest.mark.parametrize("anti_windup", ["back_calculation", "clamping", "none"])
@SETTINGS
@given(cfg=speed_configs(feedforward="none"), e_over=st.floats(1.5, 100.0), sign=st.sampled_from([-1.0, 1.0]))
def test_integrator_under_sustained_saturation(anti_windup, cfg, e_over, sign):
    """A constant error that saturates from the first sample: b_e0 e = e_over * T_max."""
    cfg["anti_windup"] = anti_windup
    ctl = SpeedController(**cfg)
    c = ctl.coefficients
    e = sign * e_over * c["T_max_Nm"] / c["b_e0"]
    assume(math.isfinite(e) and abs(e) < 1e6)
    n = 2000
    out = ctl.run(np.full(n, e), 0.0)
    x = out["x_i_Nm"].astype(float)
    assert out["saturated"].all()
    if anti_windup == "back_calculation":
        # fixed point of x = x + Ki Ts e + Ki Ka Ts (T_sat - b_e0 e - x), with |1 - Ki Ka Ts| < 1 a contraction
        x_star = sign * c["T_max_Nm"] - c["b_e0"] * e + e * c["Ki_Ts"] / c["Ki_Ka_Ts"]
        assert np.all(np.abs(x - x_star) <= abs(x_star) * (1 + 1e-5) + 1e-6), "bounded by the start distance"
    elif anti_windup == "clamping":
        assert np.all(x == 0.0), "held from the first sample"
    else:
        # the plain integrator winds up: x[k] = (k + 1) Ki Ts e
        assert abs(x[-1]) == pytest.approx(n * c["Ki_Ts"] * abs(e), rel=1e-3)


# --- invalid parameters -----------------------------------------------------------------------

SPEED_BASE = dict(
    J_kgm2=0.01, alpha_radps=100.0, zeta=0.8, Ts_s=1e-4, i_max_A=10.0, psi_f_Wb=0.05, Ld_H=1e-3, Lq_H=2e-3, pole_pairs=4
)
BAD_NUMBERS = [math.nan, math.inf, -math.inf]
SPEED_BAD = {
    "J_kgm2": [0.0, -1.0, 1e-60] + BAD_NUMBERS,
    "alpha_radps": [0.0, -3.0] + BAD_NUMBERS,
    "zeta": [0.0, -0.1] + BAD_NUMBERS,
    "m": [0.0, -1.0] + BAD_NUMBERS,
    "Ts_s": [0.0, -1e-4, 1e300] + BAD_NUMBERS,
    "i_max_A": [0.0, -5.0] + BAD_NUMBERS,
    "Ka": [-0.1] + BAD_NUMBERS,
    "tau_i_s": [-1e-3] + BAD_NUMBERS,
    "psi_f_Wb": [0.0, -0.1] + BAD_NUMBERS,
    "Ld_H": [0.0, -1e-3] + BAD_NUMBERS,
    "Lq_H": [0.0] + BAD_NUMBERS,
    "pole_pairs": [0, -2, 2.5, "4", True],
    "method": ["rk4", "Tustin", "", 2, None],
    "feedforward": ["eq13", 1, None],
    "anti_windup": ["back-calculation", 0, None],
}


@SETTINGS
@given(st.sampled_from([(p, v) for p, values in SPEED_BAD.items() for v in values]), st.data())
def test_invalid_speed_parameter_is_named(bad, data):
    param, value = bad
    cfg = dict(SPEED_BASE)
    if param == "m":
        cfg["feedforward"] = "no_tau"
    cfg[param] = value
    with pytest.raises(ConfigError) as info:
        SpeedController(**cfg)
    assert info.value.param == param
    assert param in str(info.value) and "valid range" in str(info.value)
    # the same value through set_config: rejected, old configuration kept
    ctl = SpeedController(**SPEED_BASE)
    before = (ctl.config, ctl.coefficients)
    with pytest.raises(ConfigError) as info:
        ctl.set_config(**{param: value, **({"feedforward": "no_tau"} if param == "m" else {})})
    assert info.value.param == param
    assert (ctl.config, ctl.coefficients) == before


@pytest.mark.parametrize("value", [0.0, -1.0, "fast", math.nan])
def test_string_and_number_errors_name_the_value(value):
    with pytest.raises(ConfigError, match=r"zeta = ") as info:
        SpeedController(**{**SPEED_BASE, "zeta": value})
    assert repr(value) in str(info.value)


def test_lowpass_requires_m_one():
    with pytest.raises(ConfigError, match="eq 13") as info:
        SpeedController(**SPEED_BASE, m=2.0, feedforward="lowpass")
    assert info.value.param == "m"


CURRENT_BASE = dict(Rs_ohm=0.5, Ld_H=1e-3, Lq_H=2e-3, psi_f_Wb=0.05, tau_i_s=1e-3, Ts_s=1e-4)
CURRENT_BAD = {
    "Rs_ohm": [0.0, -1.0] + BAD_NUMBERS,
    "Ld_H": [0.0] + BAD_NUMBERS,
    "Lq_H": [-1e-3] + BAD_NUMBERS,
    "psi_f_Wb": [-0.01] + BAD_NUMBERS,
    "tau_i_s": [0.0, 1e-5] + BAD_NUMBERS,
    "Ts_s": [0.0, -1.0] + BAD_NUMBERS,
    "method": ["zoh"],
    "anti_windup": ["clamp"],
    "decouple": ["yes", 1, None],
}


@SETTINGS
@given(st.sampled_from([(p, v) for p, values in CURRENT_BAD.items() for v in values]))
def test_invalid_current_parameter_is_named(bad):
    param, value = bad
    with pytest.raises(ConfigError) as info:
        CurrentController(**{**CURRENT_BASE, param: value})
    assert info.value.param == param
    ctl = CurrentController(**CURRENT_BASE)
    before = ctl.coefficients
    with pytest.raises(ConfigError):
        ctl.set_config(**{param: value})
    assert ctl.coefficients == before


# --- non-finite inputs ------------------------------------------------------------------------


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
@SETTINGS
@given(data=st.data(), bad=st.sampled_from(BAD_NUMBERS), where=st.sampled_from(["w_ref", "w_m", "both"]))
def test_non_finite_speed_input_faults_and_keeps_state(anti_windup, data, bad, where):
    cfg = data.draw(speed_configs(anti_windup=anti_windup))
    ctl = SpeedController(**cfg)
    warmup = np.array(data.draw(speeds))
    ctl.run(warmup, warmup[::-1])
    state, faults = ctl.state, ctl.fault_count
    w_ref = bad if where in ("w_ref", "both") else 10.0
    w_m = bad if where in ("w_m", "both") else 0.0
    out = ctl.step(w_ref, w_m)
    assert out.fault
    assert out.T_ref_Nm == 0.0 and out.id_ref_A == 0.0 and out.iq_ref_A == 0.0
    assert ctl.state == state
    assert ctl.fault_count == faults + 1
    # and in a bulk run, only that sample is flagged
    run = ctl.run([1.0, w_ref, 1.0], [0.0, w_m, 0.0])
    assert run["fault"].tolist() == [False, True, False]
    assert np.all(np.isfinite(run["T_ref_Nm"])) and np.all(np.isfinite(run["iq_ref_A"]))


@SETTINGS
@given(bad=st.sampled_from(BAD_NUMBERS), index=st.integers(0, 5), anti_windup=st.sampled_from(ANTI_WINDUPS))
def test_non_finite_current_input_faults_and_keeps_state(bad, index, anti_windup):
    ctl = CurrentController(**CURRENT_BASE, anti_windup=anti_windup)
    ctl.run([1.0] * 10, 2.0, 0.0, 0.5, 300.0, 100.0)
    state, faults = ctl.state, ctl.fault_count
    inputs = [1.0, 2.0, 0.0, 0.5, 300.0, 100.0]
    inputs[index] = bad
    out = ctl.step(*inputs)
    assert out.fault and out.ud_ref_V == 0.0 and out.uq_ref_V == 0.0
    assert ctl.state == state and ctl.fault_count == faults + 1


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
@SETTINGS
@given(
    id_ref=st.floats(-1e3, 1e3),
    iq_ref=st.floats(-1e3, 1e3),
    w_e=st.floats(-1e4, 1e4),
    u_dc=st.floats(0.0, 1e3),
    n=st.integers(1, 200),
)
def test_voltage_within_limit(anti_windup, id_ref, iq_ref, w_e, u_dc, n):
    ctl = CurrentController(**CURRENT_BASE, anti_windup=anti_windup)
    out = ctl.run(id_ref, iq_ref, 0.0, 0.0, w_e, np.full(n, u_dc))
    norm = np.hypot(out["ud_ref_V"].astype(float), out["uq_ref_V"].astype(float))
    assert np.all(norm <= f32(u_dc) / math.sqrt(3) * (1 + 1e-6) + 1e-30)
    assert np.all(np.isfinite(norm)) and not out["fault"].any()
