"""The fixed-point speed controllers (Q15, Q31) equal an independent integer model to the bit.

Truth: tests/oracles/fixed_point.py, the arithmetic rules of csrc/include/pmsm2dof/speed_fixed.h
written out with Python integers (exact products, ``floor(p / 2^s + 1/2)``, saturation by
``min``/``max``), never the C code. Every output and every state word of the C controllers
(through :class:`~pmsm2dof.core.fixedpoint.FixedPointSpeedController`) must equal the model's
after every sample, over random configurations of every method, feedforward form and anti-windup
mode, and over random and adversarial input sequences: the extremes of the integer range,
reversals from one extreme to the other, applied torques other than the controller's own,
parameter updates (bumpless: the output at a constant reference does not move) and resets.
The quantised coefficients are checked on their own against the exact rational values of the
design (eq 9, 11, 14, 15) and the header's quantisation rule.
"""

import math
from fractions import Fraction

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from oracles.fixed_point import BITS, Model, exact_gains, quantise
from pmsm2dof.core import ANTI_WINDUPS, FEEDFORWARDS, METHODS
from pmsm2dof.core.fixedpoint import FORMATS, GAINS, FixedPointSpeedController
from pmsm2dof.errors import ConfigError

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SAMPLES = 50


@st.composite
def configs(draw, fmt=None):
    """A valid configuration: a surface PMSM at any method, feedforward and anti-windup, and scalings
    from generous to tight (the largest speed-to-torque gain from 2^-6 to 2^11 per unit)."""
    fmt = fmt or draw(st.sampled_from(FORMATS))
    Ts = draw(st.floats(1e-5, 1e-2))
    ff = draw(st.sampled_from(FEEDFORWARDS))
    J = draw(st.floats(1e-4, 1.0))
    alpha = draw(st.floats(0.5, 0.3 / Ts))
    zeta = draw(st.floats(0.3, 2.0))
    psi_f, pole_pairs, i_max = draw(st.floats(0.01, 0.5)), draw(st.integers(1, 8)), draw(st.floats(0.5, 50.0))
    T_max = 1.5 * pole_pairs * psi_f * i_max
    T_fs = T_max * draw(st.floats(1.01, 16.0))
    # the proportional gain per unit: Kp W_fs / T_fs
    W_fs = T_fs / (J * alpha) * 2.0 ** draw(st.floats(-6.0, 6.0))
    cfg = dict(
        J_kgm2=J,
        alpha_radps=alpha,
        zeta=zeta,
        m=1.0 if ff == "lowpass" else draw(st.floats(0.3, 3.0)),
        tau_i_s=draw(st.floats(0.0, 20 * Ts)),
        Ka=draw(st.floats(0.2, 3.0)) / (J * alpha),
        Ts_s=Ts,
        i_max_A=i_max,
        psi_f_Wb=psi_f,
        Ld_H=2e-3,
        Lq_H=2e-3,
        pole_pairs=pole_pairs,
        method=draw(st.sampled_from(METHODS)),
        feedforward=ff,
        anti_windup=draw(st.sampled_from(ANTI_WINDUPS)),
        speed_full_scale_radps=W_fs,
        torque_full_scale_Nm=T_fs,
        current_full_scale_A=i_max * draw(st.floats(1.0, 4.0)),
    )
    try:
        ctl = FixedPointSpeedController(fmt, **cfg)
    except ConfigError:
        assume(False)  # a rare combination beyond the scaling bounds (gains of FULL with large tau_i)
    return fmt, cfg, ctl


def extremes(bits):
    """Adversarial values of an input of the format: the ends of the range, 0, +-1, mid-scale."""
    top = 2**bits
    return [-top, top - 1, 0, 1, -1, -top + 1, top // 2, -top // 2]


@st.composite
def sequences(draw, fmt):
    """(op, a, b) per sample: "step" (w_ref, w_m), "split" (w_ref, w_m, then an applied torque), "set"
    (a new design, bumpless), "reset" (w_ref, T_init); inputs random or at the extremes."""
    bits = BITS[fmt][0]
    value = st.one_of(st.integers(-(2**bits), 2**bits - 1), st.sampled_from(extremes(bits)))
    ops = st.tuples(
        st.sampled_from(["step"] * 6 + ["split"] * 3 + ["set", "reset"]), value, value, value, st.floats(0.3, 3.0)
    )
    return draw(st.lists(ops, min_size=SAMPLES, max_size=SAMPLES))


def c_row(ctl):
    return dict(ctl.state)


def model_row(model):
    s = model.state
    return dict(x=s.x, y_ff_prev=s.y, r_prev=s.r)


def as_dict(out):
    return {name: getattr(out, name) for name in out.__dataclass_fields__}


def run_against_model(fmt, cfg, ctl, ops):
    model = Model(fmt, ctl.coefficients)
    for k, (op, a, b, c, factor) in enumerate(ops):
        if op == "reset":
            ctl.reset(a, b)
            model.reset(a, b)
        elif op == "set":
            # a new bandwidth and back-calculation gain (the scalings stay)
            try:
                ctl.set_config(alpha_radps=cfg["alpha_radps"] * factor, Ka=cfg["Ka"] / factor)
            except ConfigError:
                continue
            before = model.compute(model.state.r, model.state.r)
            model.c = ctl.coefficients
            after = ctl.compute(model.state.r, model.state.r)
            assert as_dict(after) == model.compute(model.state.r, model.state.r)
            if model.state.y == 0:
                # bumpless: at rest at a constant reference, zero error, the command does not move
                assert after.T_unsat == before["T_unsat"]
        elif op == "step":
            out = ctl.step(a, b)
            expected = model.compute(a, b)
            model.update(expected, expected["T_ref"])
            assert as_dict(out) == expected, (k, op, cfg)
        else:
            out = ctl.compute(a, b)
            expected = model.compute(a, b)
            assert as_dict(out) == expected, (k, op, cfg)
            ctl.update(out, c)
            model.update(expected, c)
        assert c_row(ctl) == model_row(model), (k, op, cfg)


@pytest.mark.parametrize("fmt", FORMATS)
@SETTINGS
@given(data=st.data())
def test_outputs_and_states_equal_the_integer_model(fmt, data):
    _, cfg, ctl = data.draw(configs(fmt))
    run_against_model(fmt, cfg, ctl, data.draw(sequences(fmt)))


@pytest.mark.parametrize("fmt", FORMATS)
@SETTINGS
@given(data=st.data())
def test_saturating_sequences_equal_the_integer_model(fmt, data):
    """Inputs only at the extremes, reversing: every signal and state at its bound, every saturation path."""
    _, cfg, ctl = data.draw(configs(fmt))
    bits = BITS[fmt][0]
    ends = st.sampled_from([-(2**bits), 2**bits - 1])
    ops = data.draw(
        st.lists(
            st.tuples(st.sampled_from(["step", "split"]), ends, ends, ends, st.just(1.0)), min_size=40, max_size=40
        )
    )
    run_against_model(fmt, cfg, ctl, ops)


@pytest.mark.parametrize("fmt", FORMATS)
@SETTINGS
@given(data=st.data())
def test_coefficients_are_the_quantised_design(fmt, data):
    """Each mantissa and shift is the header's rule applied to the exact gain, within half a mantissa LSB
    (the C computes in double: a gain within 2^-20 LSB of a rounding tie may round either way)."""
    _, cfg, ctl = data.draw(configs(fmt))
    bits = BITS[fmt][0]
    ka = ctl.config["Ka"]
    exact = exact_gains({**cfg, "Ka": ka if ka is not None else cfg["Ka"]})
    coef = ctl.coefficients
    for name in GAINS:
        m, s = coef[name]
        m_rule, s_rule, scaled = quantise(exact[name], bits)
        assert abs(m) <= 2**bits - 1
        assert s == s_rule, (name, coef[name], m_rule, s_rule)
        assert abs(Fraction(m) - scaled) <= Fraction(1, 2) + Fraction(1, 2**20), (name, m, float(scaled))
        # and the double values the C reports before quantisation are the exact ones to double precision
        assert ctl.gains[name] == pytest.approx(float(exact[name]), rel=1e-12, abs=1e-300)
    top = 2**bits
    for name in ("T_max", "iq_max"):
        floor_exact = math.floor(exact[name] * top)
        assert min(floor_exact, top - 1) - 1 <= coef[name] <= min(floor_exact, top - 1)
    assert coef["clamping"] == (cfg["anti_windup"] == "clamping")


def test_q31_one_lsb_of_error_moves_the_integrator():
    """Q31 refuses a configuration whose integrator ignores one LSB of error; Q15 accepts it (its dead zone)."""
    cfg = dict(
        J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, Ts_s=1e-4, i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01,
        pole_pairs=4, speed_full_scale_radps=1e-7, torque_full_scale_Nm=10.0, current_full_scale_A=10.0,
    )  # fmt: skip
    # Ki Ts W_fs / T_fs = 3e-5 * 1e-7 / 10 = 3e-13 < 2^-32
    with pytest.raises(ConfigError, match="speed_full_scale_radps"):
        FixedPointSpeedController("q31", **cfg)
    ctl = FixedPointSpeedController("q15", **cfg)
    ctl.reset(w_ref=100)  # at rest at the reference: the step below moves the integrator alone
    ctl.step(100, 0)
    assert ctl.state["x"] == 0
    cfg["speed_full_scale_radps"] = 1e-4  # 3e-10 >= 2^-32: one LSB of error moves the Q62 integrator
    ctl = FixedPointSpeedController("q31", **cfg)
    ctl.reset(w_ref=1)
    ctl.step(1, 0)
    assert ctl.state["x"] >= 1


@pytest.mark.parametrize(
    "change, param",
    [
        (dict(Lq_H=0.02), "Lq_H"),
        (dict(torque_full_scale_Nm=9.0), "torque_full_scale_Nm"),  # below the limit 9.12 Nm
        (dict(current_full_scale_A=7.0), "current_full_scale_A"),  # below i_max_A
        (dict(speed_full_scale_radps=1e6), "speed_full_scale_radps"),  # Fr(0) W_fs / T_fs = 6e4 >= 2^13
        (dict(speed_full_scale_radps=math.inf), "speed_full_scale_radps"),
        (dict(zeta=-1.0), "zeta"),  # the float controller's rules
    ],
)
def test_invalid_configurations_name_the_parameter(change, param):
    cfg = dict(
        J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, Ts_s=1e-4, i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01,
        pole_pairs=4, speed_full_scale_radps=104.7, torque_full_scale_Nm=10.0, current_full_scale_A=10.0,
    )  # fmt: skip
    for fmt in FORMATS:
        with pytest.raises(ConfigError, match=param):
            FixedPointSpeedController(fmt, **{**cfg, **change})
        ctl = FixedPointSpeedController(fmt, **cfg)
        before = (ctl.coefficients, ctl.config)
        with pytest.raises(ConfigError, match=param):
            ctl.set_config(**change)
        assert (ctl.coefficients, ctl.config) == before


def test_inputs_outside_the_format_are_refused():
    cfg = dict(
        J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, Ts_s=1e-4, i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01,
        pole_pairs=4, speed_full_scale_radps=104.7, torque_full_scale_Nm=10.0, current_full_scale_A=10.0,
    )  # fmt: skip
    ctl = FixedPointSpeedController("q15", **cfg)
    with pytest.raises(ConfigError, match="w_m"):
        ctl.step(0, 32768)
    with pytest.raises(ConfigError, match="w_ref"):
        ctl.compute(1.5, 0)
    with pytest.raises(ConfigError, match="fmt"):
        FixedPointSpeedController("q7", **cfg)
