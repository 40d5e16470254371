"""Continuous design (paper section 3): gains, feedforward forms, Gx, GN, poles, margins.

Truth: the paper's equations (9)-(13) and (8) written out here, and frequency and
time responses evaluated from explicit formulas with numpy/scipy.
"""

import dataclasses
import math

import control
import numpy as np
import pytest
from scipy import optimize, signal

import pmsm2dof
from pmsm2dof.analysis.design import Design, design
from pmsm2dof.core import FEEDFORWARDS

# (J_kgm2, alpha_radps, zeta, m, tau_i_s): the paper's values and others far from them
PARAMETER_SETS = [
    (0.4, 0.5, 0.2887, 1.0, 0.05),
    (0.4, 0.5, 0.2887, 0.2, 0.05),
    (0.01, 100.0, 0.7, 0.3, 0.002),
    (2.0, 5.0, 1.2, 2.5, 0.0),
    (0.05, 20.0, 0.5, 0.5, 0.01),
]


def poly_eval(coefficients, s):
    return np.polyval(coefficients, s)


def tf_eval(tf, s):
    return poly_eval(tf.num[0][0], s) / poly_eval(tf.den[0][0], s)


def same_tf(a, b, rtol=1e-9):
    """Equal transfer functions: equal responses at points spread over the s plane."""
    points = np.array([0.013 + 0.0j, 0.7j, 1.0 + 2.0j, -0.31 + 5.0j, 40.0 + 1.0j, 300.0j, -7.0 - 0.5j])
    np.testing.assert_allclose(tf_eval(a, points), tf_eval(b, points), rtol=rtol)


def test_paper_gains():
    # section 4.1: Kp = 0.2 and Ki = 0.3 with J = 0.4, alpha = 0.5; eq 9 gives zeta = 0.25 / sqrt(0.75)
    d = design(0.4, 0.5, 0.25 / math.sqrt(0.75))
    assert d.Kp == pytest.approx(0.2, rel=1e-12)
    assert d.Ki == pytest.approx(0.3, rel=1e-12)
    assert d.Ka == pytest.approx(1.0 / 0.2, rel=1e-12)


def test_package_exports_design():
    assert pmsm2dof.design is design
    assert isinstance(pmsm2dof.design(0.4, 0.5, 0.2887), pmsm2dof.Design)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_gains_eq9(J, alpha, zeta, m, tau):
    d = design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="full")
    assert d.Kp == pytest.approx(J * alpha, rel=1e-14)
    assert d.Ki == pytest.approx(J * alpha**2 / (4.0 * zeta**2), rel=1e-14)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_full_feedforward_makes_tracking_first_order(J, alpha, zeta, m, tau):
    d = design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="full")
    target = control.tf([m * alpha], [1.0, m * alpha])  # eq 10
    # eq 6 formed here from the design's parts, then reduced
    F, Fr, G = d.F, d.Fr, d.G
    eq6 = ((Fr + F) * G * control.feedback(1, F * G)).minreal()
    for Gx in (d.Gx, eq6):
        assert len(control.poles(Gx)) == 1
        same_tf(Gx, target, rtol=1e-6)
    # the -3 dB (half-power) bandwidth of m alpha / (s + m alpha) is m alpha
    assert d.bandwidth_radps() == pytest.approx(m * alpha, rel=1e-6)
    assert d.overshoot_pct() == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_fr_eq11_and_special_cases(J, alpha, zeta, m, tau):
    eq11 = control.tf(J * alpha * np.array([m * tau, m - 1.0, -alpha / (4 * zeta**2)]), [1.0, m * alpha])
    same_tf(design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="full").Fr, eq11)
    no_tau = control.tf(J * alpha * np.array([m - 1.0, -alpha / (4 * zeta**2)]), [1.0, m * alpha])
    same_tf(design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="no_tau").Fr, no_tau)
    # eq 12: m = 1
    eq12 = control.tf(J * alpha * np.array([tau, 0.0, -alpha / (4 * zeta**2)]), [1.0, alpha])
    same_tf(design(J, alpha, zeta, m=1.0, tau_i_s=tau, feedforward="full").Fr, eq12)
    # eq 13: m = 1 and tau_i = 0, also the 'lowpass' form whatever tau_i
    eq13 = control.tf([-J * (alpha / (2 * zeta)) ** 2], [1.0, alpha])
    same_tf(design(J, alpha, zeta, m=1.0, tau_i_s=0.0, feedforward="full").Fr, eq13)
    same_tf(design(J, alpha, zeta, m=1.0, tau_i_s=tau, feedforward="lowpass").Fr, eq13)
    assert np.all(tf_eval(design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="none").Fr, np.array([1j, 3.0])) == 0)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_gn_is_eq8_for_every_feedforward(J, alpha, zeta, m, tau):
    Kp, Ki = J * alpha, J * alpha**2 / (4 * zeta**2)
    eq8 = control.tf([-tau, -1.0, 0.0], [J * tau, J, Kp, Ki])
    for ff in FEEDFORWARDS:
        d = design(J, alpha, zeta, m=1.0 if ff == "lowpass" else m, tau_i_s=tau, feedforward=ff)
        same_tf(d.GN, eq8)
        # the same polynomials, not only the same response
        num, den = np.trim_zeros(d.GN.num[0][0], "f"), np.trim_zeros(d.GN.den[0][0], "f")
        num8, den8 = np.trim_zeros(eq8.num[0][0], "f"), np.trim_zeros(eq8.den[0][0], "f")
        np.testing.assert_allclose(den / den[0], den8 / den8[0], rtol=1e-12)
        np.testing.assert_allclose(num / den[0], num8 / den8[0], rtol=1e-12)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_closed_loop_poles_are_roots_of_eq8_denominator(J, alpha, zeta, m, tau):
    d = design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="full")
    char = [J * tau, J, J * alpha, J * alpha**2 / (4 * zeta**2)]
    expected = np.sort_complex(np.roots(np.trim_zeros(char, "f")))
    np.testing.assert_allclose(np.sort_complex(d.closed_loop_poles()), expected, rtol=1e-9)


@pytest.mark.slow
def test_one_dof_bandwidth_and_overshoot_from_explicit_response():
    J, alpha, zeta = 0.4, 0.5, 0.2887
    Kp, Ki = J * alpha, J * alpha**2 / (4 * zeta**2)
    d = design(J, alpha, zeta, tau_i_s=0.0, feedforward="none")

    def gx(w):  # (Kp s + Ki) / (J s^2 + Kp s + Ki)
        s = 1j * w
        return (Kp * s + Ki) / (J * s * s + Kp * s + Ki)

    # the 1DOF loop peaks above 1 before it falls: the -3 dB point lies beyond the peak
    w_peak = optimize.minimize_scalar(lambda w: -abs(gx(w)), bounds=(0.01, 5.0), method="bounded").x
    w_bw = optimize.brentq(lambda w: abs(gx(w)) - 1 / math.sqrt(2), w_peak, 100.0)
    assert d.bandwidth_radps() == pytest.approx(w_bw, rel=1e-4)
    t = np.linspace(0.0, 60.0, 200001)
    _, y = signal.step(([Kp, Ki], [J, Kp, Ki]), T=t)
    assert d.overshoot_pct() == pytest.approx(100.0 * (y.max() - 1.0), abs=0.05)


@pytest.mark.parametrize("J, alpha, zeta, m, tau", PARAMETER_SETS)
def test_phase_margin_from_explicit_loop(J, alpha, zeta, m, tau):
    Kp, Ki = J * alpha, J * alpha**2 / (4 * zeta**2)

    def loop(w):  # F G = (Kp s + Ki) / (J s^2 (tau s + 1))
        s = 1j * w
        return (Kp * s + Ki) / (J * s * s * (tau * s + 1.0))

    w_c = optimize.brentq(lambda w: abs(loop(w)) - 1.0, 1e-6 * alpha, 1e6 * alpha)
    margins = design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward="full").margins()
    assert margins.w_gain_crossover_radps == pytest.approx(w_c, rel=1e-6)
    assert margins.phase_margin_deg == pytest.approx(180.0 + math.degrees(np.angle(loop(w_c))), abs=1e-6)
    # Routh on J tau s^3 + J s^2 + k Kp s + k Ki: stable for every gain k when Kp > tau Ki
    assert Kp > tau * Ki
    assert margins.gain_margin_dB == math.inf


def test_design_is_immutable_and_transfer_functions_are_fresh():
    d = design(0.4, 0.5, 0.2887, tau_i_s=0.05)
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.Kp = 1.0
    assert d.F is not d.F
    assert d == design(0.4, 0.5, 0.2887, tau_i_s=0.05)
    assert isinstance(d, Design)


def test_explicit_Ka_is_kept():
    assert design(0.4, 0.5, 0.2887, Ka=2.5).Ka == 2.5
    assert design(0.4, 0.5, 0.2887, Ka=0).Ka == 0.0


@pytest.mark.parametrize(
    "param, kwargs",
    [
        ("J_kgm2", {"J_kgm2": 0.0}),
        ("J_kgm2", {"J_kgm2": -0.4}),
        ("J_kgm2", {"J_kgm2": math.nan}),
        ("J_kgm2", {"J_kgm2": "heavy"}),
        ("alpha_radps", {"alpha_radps": 0.0}),
        ("alpha_radps", {"alpha_radps": math.inf}),
        ("zeta", {"zeta": -1.0}),
        ("zeta", {"zeta": math.nan}),
        ("m", {"m": 0.0}),
        ("m", {"m": -math.inf}),
        ("m", {"m": 0.5, "feedforward": "lowpass"}),
        ("tau_i_s", {"tau_i_s": -0.01}),
        ("tau_i_s", {"tau_i_s": math.inf}),
        ("Ka", {"Ka": -1.0}),
        ("Ka", {"Ka": math.nan}),
        ("Ka", {"Ka": True}),
        ("feedforward", {"feedforward": "2dof"}),
        ("anti_windup", {"anti_windup": "backcalc"}),
    ],
)
def test_invalid_inputs_name_the_parameter(param, kwargs):
    args = {"J_kgm2": 0.4, "alpha_radps": 0.5, "zeta": 0.2887, **kwargs}
    with pytest.raises(ValueError) as exc:
        design(**args)
    assert str(exc.value).startswith(param + " = ")
    assert "valid range" in str(exc.value)
