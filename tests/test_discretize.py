"""Discretization (paper section 3.4, Table 1, eq 14, 15) and the discrete closed loop.

The coefficients are the C controller's (float32): they are checked against the substitutions
of Table 1 at float32 precision and against the double-precision derivation of
tests/oracles/discretize.py, whose coefficients also feed the analysis where its accuracy near
z = 1 is checked against exact values (below float32's resolution of the coefficients).

Truth: the substitutions of Table 1 applied here to the continuous transfer
functions written out from eq (9)-(11), eq (14) and (15) by hand, the
zero-order-hold equivalent of 1/(J s (tau s + 1)) derived by hand, a
sample-by-sample simulation of the difference equations on SciPy's ZOH plant,
the continuous step response from SciPy's partial fractions, 50-digit roots
(mpmath), and root loci.
"""

import itertools
import math
import warnings

import control
import mpmath
import numpy as np
import pytest
from scipy import optimize, signal

from oracles.discretize import coefficients as oracle_coefficients
from pmsm2dof import SamplingWarning, SpeedController
from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.discretize import discrete_loop
from pmsm2dof.core import FEEDFORWARDS, METHODS

J, ALPHA, ZETA, TAU = 0.4, 0.5, 0.2887, 0.05
CASES = [  # (J, alpha, zeta, m, tau_i, Ts)
    (J, ALPHA, ZETA, 1.0, TAU, 1e-3),
    (J, ALPHA, ZETA, 1.6, TAU, 0.02),
    (0.01, 100.0, 0.7, 0.5, 0.002, 1e-4),
    (2.0, 5.0, 1.2, 2.5, 0.0, 5e-3),
]
#: Relative precision of a coefficient computed in float32 (a few ulps of 6e-8).
F32 = 1e-6
# points of the z plane away from the poles
Z_POINTS = np.array([1.3 + 0.0j, np.exp(0.2j), 0.4 - 0.9j, -0.7 + 0.2j, 2.0 - 1.0j])


def s_of_z(method, z, Ts):
    """Table 1."""
    return {
        "forward_euler": (z - 1.0) / Ts,
        "backward_euler": (z - 1.0) / (z * Ts),
        "tustin": 2.0 * (z - 1.0) / (Ts * (z + 1.0)),
    }[method]


def fr_continuous(ff, J, alpha, zeta, m, tau, s):
    """eq 11 (full), eq 11 with tau = 0 (no_tau), eq 13 (lowpass), 0 (none)."""
    if ff == "none":
        return 0.0 * s
    if ff == "lowpass":
        return -J * (alpha / (2 * zeta)) ** 2 / (s + alpha)
    tau = tau if ff == "full" else 0.0
    return J * alpha * (m * tau * s**2 + (m - 1) * s - alpha / (4 * zeta**2)) / (s + m * alpha)


def kd(ff, J, alpha, m, tau):
    """The derivative part of Fr: its s^2 coefficient over the leading 1 of s + m alpha."""
    return J * alpha * m * tau if ff == "full" else 0.0


def zoh_plant(J, tau, Ts):
    """Numerator and denominator in z of the ZOH equivalent of 1/(J s (tau s + 1)), derived from the
    step-invariance (1 - z^-1) Z{G(s)/s}."""
    if tau == 0.0:
        return np.array([Ts / J]), np.array([1.0, -1.0])
    a = math.exp(-Ts / tau)
    return np.array([Ts - tau * (1 - a), tau * (1 - a) - a * Ts]) / J, np.polymul([1.0, -1.0], [1.0, -a])


def g_zoh(J, tau, Ts, z):
    """The ZOH plant of :func:`zoh_plant` at the points ``z``."""
    num, den = zoh_plant(J, tau, Ts)
    return np.polyval(num, z) / np.polyval(den, z)


def discretized(J, alpha, zeta, m, tau, Ts, ff, method, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)
        return design(J, alpha, zeta, m=m, tau_i_s=tau, feedforward=ff, **kw).discretize(Ts, method)


def simulated_overshoot_pct(dd):
    """Sample-by-sample simulation: the controller's difference equations and SciPy's ZOH plant."""
    d, Ts = dd.design, dd.Ts_s
    tau = d.tau_i_s
    # states (T, w): tau T' = u - T, J w' = T; without the current loop the plant is J w' = u
    if tau > 0.0:
        A, B, C = [[-1 / tau, 0.0], [1 / d.J_kgm2, 0.0]], [[1 / tau], [0.0]], [[0.0, 1.0]]
    else:
        A, B, C = [[0.0, 0.0], [1.0, 0.0]], [[0.0], [1 / d.J_kgm2]], [[0.0, 1.0]]
    Ad, Bd, _, _, _ = signal.cont2discrete((np.array(A), np.array(B), np.array(C), np.zeros((1, 1))), Ts, "zoh")
    (a11, a12), (a21, a22) = Ad.tolist()
    (b1,), (b2,) = Bd.tolist()
    slowest = min(np.min(-d.closed_loop_poles().real), d.m * d.alpha_radps)
    T = w = q = r_prev = y_prev = 0.0
    out = np.empty(int(40.0 / (slowest * Ts)))
    for k in range(len(out)):
        r = 1.0
        out[k] = w
        e = r - w
        y = dd.ff_b_dr * (r - r_prev) - dd.ff_a1 * y_prev
        u = dd.b_e0 * e + q + dd.ff_Fr0 * r + y + dd.ff_Kd_per_Ts * (r - r_prev)
        q += dd.Ki_Ts * e
        r_prev, y_prev = r, y
        T, w = a11 * T + a12 * w + b1 * u, a21 * T + a22 * w + b2 * u
    assert out[-1] == pytest.approx(1.0, abs=1e-9)
    return 100.0 * max(out.max() - 1.0, 0.0)


@pytest.mark.parametrize("case, method, ff", list(itertools.product(CASES, METHODS, FEEDFORWARDS)))
def test_coefficients_realize_table1_substitution(case, method, ff):
    Jc, alpha, zeta, m, tau, Ts = case
    m = 1.0 if ff == "lowpass" else m
    dd = discretized(Jc, alpha, zeta, m, tau, Ts, ff, method)
    z = Z_POINTS
    zi = 1.0 / z
    Kp, Ki = Jc * alpha, Jc * alpha**2 / (4 * zeta**2)
    s = s_of_z(method, z, Ts)
    # PI realization u = b_e0 e + x[k-1], x[k] = x[k-1] + Ki Ts e  ->  F(z)
    F_realized = (dd.b_e0 + (dd.Ki_Ts - dd.b_e0) * zi) / (1.0 - zi)
    np.testing.assert_allclose(F_realized, Kp + Ki / s, rtol=F32)
    assert dd.Ki_Ts == pytest.approx(Ki * Ts, rel=F32)
    # feedforward realization: static gain, transient section b_dr (1 - z^-1)/(1 + a1 z^-1), Kd (1 - z^-1)/Ts
    Fr_realized = dd.ff_Fr0 + dd.ff_b_dr * (1.0 - zi) / (1.0 + dd.ff_a1 * zi) + dd.ff_Kd_per_Ts * (1.0 - zi)
    # the static gain is Fr(0) of eq 11 / 13, -J alpha / (4 zeta^2 m) (0 for none)
    assert dd.ff_Fr0 == pytest.approx(fr_continuous(ff, Jc, alpha, zeta, m, tau, 0.0), rel=F32)
    Kd = kd(ff, Jc, alpha, m, tau)
    # proper part by the method, derivative Kd s by the backward difference
    expected = fr_continuous(ff, Jc, alpha, zeta, m, tau, s) - Kd * s + Kd * s_of_z("backward_euler", z, Ts)
    np.testing.assert_allclose(Fr_realized, expected, rtol=F32, atol=F32 * Kp)
    # the discrete transfer functions returned agree with the realization
    np.testing.assert_allclose(dd.F_z(z), F_realized, rtol=1e-9)
    np.testing.assert_allclose(dd.Fr_z(z), Fr_realized, rtol=1e-8, atol=1e-12 * Kp)
    assert dd.Ki_Ka_Ts == pytest.approx(Ki * Ts / Kp, rel=F32)  # back calculation, Ka = 1/Kp


def test_tustin_pi_is_eq14():
    d = design(J, ALPHA, ZETA, tau_i_s=TAU)
    Ts = 1e-3
    dd = d.discretize(Ts, "tustin")
    # eq 14: F(z) = Kp + Ki Ts/2 (1 + z^-1)/(1 - z^-1) = ((Kp + Ki Ts/2) + (Ki Ts/2 - Kp) z^-1) / (1 - z^-1)
    Kp, Ki = J * ALPHA, J * ALPHA**2 / (4 * ZETA**2)
    assert dd.b_e0 == pytest.approx(Kp + Ki * Ts / 2, rel=F32)
    assert dd.Ki_Ts - dd.b_e0 == pytest.approx(Ki * Ts / 2 - Kp, rel=F32)
    zi = 1.0 / Z_POINTS
    np.testing.assert_allclose(dd.F_z(Z_POINTS), Kp + Ki * Ts / 2 * (1 + zi) / (1 - zi), rtol=F32)


@pytest.mark.parametrize("Ts", [1e-3, 0.05, 0.2])
def test_tustin_lowpass_is_eq15(Ts):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)
        dd = design(J, ALPHA, ZETA, feedforward="lowpass", tau_i_s=TAU).discretize(Ts, "tustin")
    # eq 15: -J (alpha/(2 zeta))^2 / ((2/Ts)(1 - z^-1)/(1 + z^-1) + alpha)
    #      = -Ki Ts (1 + z^-1) / ((2 + alpha Ts) - (2 - alpha Ts) z^-1)
    # around the static gain Fr(0) = -Ki / alpha:
    #      = -Ki / alpha + b_dr (1 - z^-1) / (1 + a1 z^-1),  b_dr = b0 + Ki / alpha = 2 Ki / (alpha (2 + alpha Ts))
    Ki = J * (ALPHA / (2 * ZETA)) ** 2
    assert dd.ff_Fr0 == pytest.approx(-Ki / ALPHA, rel=F32)
    assert dd.ff_b_dr == pytest.approx(2 * Ki / (ALPHA * (2 + ALPHA * Ts)), rel=F32)
    assert dd.ff_a1 == pytest.approx(-(2 - ALPHA * Ts) / (2 + ALPHA * Ts), rel=F32)
    assert dd.ff_Kd_per_Ts == 0.0
    zi = 1.0 / Z_POINTS
    eq15 = -Ki / (2 / Ts * (1 - zi) / (1 + zi) + ALPHA)
    np.testing.assert_allclose(dd.Fr_z(Z_POINTS), eq15, rtol=F32, atol=F32 * Ki / ALPHA)


@pytest.mark.parametrize("J_tiny", [1e-15, 1e-9])
def test_tiny_inertia_keeps_every_coefficient(J_tiny):
    # every coefficient of eq 9, 11 and 14 is proportional to J (ff_a1 does not depend on it),
    # so a tiny inertia must give the paper-drive coefficients scaled by J_tiny / J
    paper = design(J, ALPHA, ZETA, tau_i_s=TAU, feedforward="full").discretize(1e-3, "tustin")
    tiny = design(J_tiny, ALPHA, ZETA, tau_i_s=TAU, feedforward="full").discretize(1e-3, "tustin")
    for name in ("b_e0", "Ki_Ts", "ff_Fr0", "ff_b_dr", "ff_Kd_per_Ts"):
        assert getattr(tiny, name) == pytest.approx(getattr(paper, name) * J_tiny / J, rel=F32), name
    assert tiny.ff_a1 == pytest.approx(paper.ff_a1, rel=1e-12)
    assert tiny.Ki_Ka_Ts == pytest.approx(paper.Ki_Ka_Ts, rel=F32)


@pytest.mark.parametrize("case, method, ff", list(itertools.product(CASES, METHODS, FEEDFORWARDS)))
def test_coefficients_are_those_of_the_c_core_and_of_the_python_oracle(case, method, ff):
    Jc, alpha, zeta, m, tau, Ts = case
    m = 1.0 if ff == "lowpass" else m
    dd = discretized(Jc, alpha, zeta, m, tau, Ts, ff, method)
    ctl = SpeedController(
        J_kgm2=Jc,
        alpha_radps=alpha,
        zeta=zeta,
        m=m,
        tau_i_s=tau,
        Ts_s=Ts,
        i_max_A=7.6,
        psi_f_Wb=0.2,
        Ld_H=0.01,
        Lq_H=0.01,
        pole_pairs=4,
        method=method,
        feedforward=ff,
    )
    c = ctl.coefficients
    oracle = oracle_coefficients(Jc, alpha, zeta, m, tau, Ts, method, ff)
    for name in ("b_e0", "Ki_Ts", "Ki_Ka_Ts", "ff_Fr0", "ff_b_dr", "ff_a1", "ff_Kd_per_Ts"):
        assert getattr(dd, name) == c[name], name  # read from the C controller, not computed again
        # float32 C arithmetic against double: a few float32 ulps of the largest term involved
        assert oracle[name] == pytest.approx(c[name], rel=2e-6, abs=2e-7 * max(abs(c[name]), Jc * alpha)), name


@pytest.mark.parametrize("case, method", list(itertools.product(CASES, METHODS)))
def test_discrete_poles_are_roots_of_the_zoh_characteristic_polynomial(case, method):
    Jc, alpha, zeta, m, tau, Ts = case
    dd = discretized(Jc, alpha, zeta, m, tau, Ts, "full", method)
    # 1 + F(z) G(z) = 0 with F = (b_e0 z + Ki Ts - b_e0)/(z - 1) and the hand-derived ZOH plant
    Kp, Ki = Jc * alpha, Jc * alpha**2 / (4 * zeta**2)
    b_e0 = {"forward_euler": Kp, "backward_euler": Kp + Ki * Ts, "tustin": Kp + Ki * Ts / 2}[method]
    Fn, Fd = np.array([b_e0, Ki * Ts - b_e0]), np.array([1.0, -1.0])
    Gn, Gd = zoh_plant(Jc, tau, Ts)
    char = np.polyadd(np.polymul(Fd, Gd), np.polymul(Fn, Gn))
    np.testing.assert_allclose(np.sort_complex(np.array(dd.poles)), np.sort_complex(np.roots(char)), atol=1e-9)
    np.testing.assert_allclose(dd.G_z(Z_POINTS), g_zoh(Jc, tau, Ts, Z_POINTS), rtol=1e-9)


@pytest.mark.parametrize("case, method", list(itertools.product(CASES, METHODS)))
def test_discrete_gain_margin_from_root_locus(case, method):
    Jc, alpha, zeta, m, tau, Ts = case
    dd = discretized(Jc, alpha, zeta, m, tau, Ts, "full", method)
    Fn, Fd = dd.F_z.num[0][0], dd.F_z.den[0][0]
    Gn, Gd = zoh_plant(Jc, tau, Ts)  # the ZOH plant, by hand, as polynomials

    def radius(k):
        return np.max(np.abs(np.roots(np.polyadd(np.polymul(Fd, Gd), k * np.polymul(Fn, Gn)))))

    assert radius(1.0) < 1.0
    gm = 10.0 ** (dd.margins.gain_margin_dB / 20.0)
    assert math.isfinite(gm)
    # the loop is stable for every gain up to the margin and unstable just beyond
    for k in np.linspace(1.0, 0.999 * gm, 60):
        assert radius(k) < 1.0
    assert radius(1.001 * gm) > 1.0


@pytest.mark.parametrize("method", METHODS)
def test_phase_margin_from_explicit_discrete_loop(method):
    Ts = 0.02
    dd = discretized(J, ALPHA, ZETA, 1.0, TAU, Ts, "full", method)
    Kp, Ki = J * ALPHA, J * ALPHA**2 / (4 * ZETA**2)
    w = np.linspace(0.05, 5.0, 200001)
    z = np.exp(1j * w * Ts)
    loop = (Kp + Ki / s_of_z(method, z, Ts)) * g_zoh(J, TAU, Ts, z)
    k = np.argmin(np.abs(np.abs(loop) - 1.0))
    assert dd.margins.w_gain_crossover_radps == pytest.approx(w[k], abs=1e-3)
    assert dd.margins.phase_margin_deg == pytest.approx(180.0 + np.degrees(np.angle(loop[k])), abs=1e-2)


@pytest.mark.parametrize("ff, Ts", [("none", 0.05), ("full", 0.05), ("lowpass", 0.3)])
def test_overshoot_from_sample_by_sample_simulation(ff, Ts):
    """Simulate the controller's difference equations with the exact sampled mechanics (tau_i = 0)."""
    dd = discretized(J, ALPHA, ZETA, 1.0, 0.0, Ts, ff, "tustin")
    assert dd.overshoot_pct == pytest.approx(simulated_overshoot_pct(dd), abs=1e-3)


def test_sampling_warning_when_alpha_ts_is_large():
    d = design(J, ALPHA, 1.0, tau_i_s=TAU)  # m = 1, zeta = 1: the largest design frequency is alpha
    with pytest.warns(SamplingWarning, match="Ts_s"):
        d.discretize(0.25, "tustin")  # alpha Ts = 0.125
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d.discretize(0.19, "tustin")  # alpha Ts = 0.095


def test_unstable_discrete_loop_is_refused():
    Ts = 12.0
    d = design(J, ALPHA, ZETA, anti_windup="none")
    # by hand: Tustin PI and ZOH integrator, F(-1) G(-1) = -Kp Ts / (2 J) = -3: a pole beyond z = -1
    Kp, Ki = J * ALPHA, J * ALPHA**2 / (4 * ZETA**2)
    b_e0 = Kp + Ki * Ts / 2
    char = np.polyadd(np.polymul([1.0, -1.0], [1.0, -1.0]), np.array([b_e0, Ki * Ts - b_e0]) * Ts / J)
    assert np.max(np.abs(np.roots(char))) > 1.0
    with pytest.warns(SamplingWarning), pytest.raises(ValueError, match=r"^Ts_s = 12\.0 .*discrete loop is stable"):
        d.discretize(Ts, "tustin")


def test_forward_euler_feedforward_pole_outside_unit_circle_is_refused():
    d = design(J, ALPHA, 1.0, m=2.0, feedforward="full")
    # m alpha Ts = 2.2 > 2: pole 1 - m alpha Ts = -1.2; the C core refuses it too
    with pytest.warns(SamplingWarning), pytest.raises(ValueError, match="^Ts_s = "):
        d.discretize(2.2, "forward_euler")
    with pytest.raises(ValueError, match="^Ts_s = "):
        SpeedController(
            J_kgm2=J,
            alpha_radps=ALPHA,
            zeta=1.0,
            m=2.0,
            Ts_s=2.2,
            i_max_A=7.6,
            psi_f_Wb=0.2,
            Ld_H=0.01,
            Lq_H=0.01,
            pole_pairs=4,
            method="forward_euler",
            feedforward="full",
        )


def test_back_calculation_gain_too_large_is_refused():
    Ki = J * ALPHA**2 / (4 * ZETA**2)
    d = design(J, ALPHA, ZETA, Ka=2.5 / (Ki * 1e-3))  # Ki Ka Ts = 2.5 >= 2
    with pytest.raises(ValueError, match="^Ka = "):
        d.discretize(1e-3, "tustin")
    # without back calculation Ka does not enter the discrete loop
    design(J, ALPHA, ZETA, Ka=2.5 / (Ki * 1e-3), anti_windup="clamping").discretize(1e-3, "tustin")


@pytest.mark.parametrize(
    "param, Ts, method",
    [
        ("Ts_s", 0.0, "tustin"),
        ("Ts_s", -1e-3, "tustin"),
        ("Ts_s", math.nan, "tustin"),
        ("Ts_s", math.inf, "tustin"),
        ("Ts_s", "1ms", "tustin"),
        ("method", 1e-3, "bilinear"),
        ("method", 1e-3, "zoh"),
    ],
)
def test_invalid_discretization_inputs(param, Ts, method):
    with pytest.raises(ValueError) as exc:
        design(J, ALPHA, ZETA).discretize(Ts, method)
    assert str(exc.value).startswith(param + " = ")


def test_as_dict_is_plain_numbers():
    import json

    dd = design(J, ALPHA, ZETA, tau_i_s=TAU).discretize(1e-3, "tustin")
    data = json.loads(json.dumps(dd.as_dict(), allow_nan=False))
    assert data["Kp"] == dd.design.Kp and data["Ki"] == dd.design.Ki and data["Ka"] == dd.design.Ka
    assert data["continuous"]["margins"]["gain_margin_dB"] is None  # infinite
    assert data["continuous"]["missing"]["gain_margin_dB"].startswith("infinite")
    assert data["discrete"]["coefficients"]["b_e0"] == dd.b_e0


# ---- fine and coarse sampling: the figures of every stable design --------------------------

ALPHA_TS_GRID = np.logspace(-6.0, -1.0, 6)
ANCHOR_ALPHA_TS = 1e-3  # finest alpha Ts that a sample-by-sample simulation covers in a moment


def gx_continuous(ff, J, alpha, zeta, m, tau):
    """eq 6 with eq 11 / 13 multiplied through by hand:
    (Rn s + (Kp s + Ki) Rd) / (Rd (J tau s^3 + J s^2 + Kp s + Ki))."""
    Kp, Ki = J * alpha, J * alpha**2 / (4 * zeta**2)
    if ff == "none":
        Rn, Rd = np.zeros(1), np.ones(1)
    elif ff == "lowpass":
        Rn, Rd = np.array([-Ki]), np.array([1.0, alpha])
    else:
        t = tau if ff == "full" else 0.0
        Rn, Rd = J * alpha * np.array([m * t, m - 1.0, -alpha / (4 * zeta**2)]), np.array([1.0, m * alpha])
    num = np.polyadd(np.polymul(Rn, [1.0, 0.0]), np.polymul([Kp, Ki], Rd))
    return num, np.polymul(Rd, [J * tau, J, Kp, Ki])


def continuous_overshoot_pct(ff, J, alpha, zeta, m, tau):
    """Peak of the step response of :func:`gx_continuous` from its partial fractions (SciPy),
    ``y(t) = sum r_i (exp(p_i t) - 1) / p_i``, on a dense grid refined by a bounded search."""
    residues, poles, direct = signal.residue(*gx_continuous(ff, J, alpha, zeta, m, tau))
    assert not np.any(direct)

    def y(t):
        return np.real(np.sum(residues[:, None] / poles[:, None] * np.expm1(np.outer(poles, np.atleast_1d(t))), 0))

    t = np.linspace(0.0, 40.0 / np.min(-poles.real), 200001)
    k = int(np.argmax(y(t)))
    lo, hi = t[max(k - 1, 0)], t[min(k + 1, len(t) - 1)]
    peak = -optimize.minimize_scalar(
        lambda x: -y(x)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
    ).fun
    assert y(t[-1])[0] == pytest.approx(1.0, abs=1e-12)
    return 100.0 * max(peak - 1.0, 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("tau", [0.0, TAU])
@pytest.mark.parametrize("ff", FEEDFORWARDS)
@pytest.mark.parametrize("method", METHODS)
def test_every_stable_design_has_its_figures_from_alpha_ts_1e_6_to_0_1(tau, ff, method):
    """Never refused, never garbage: the discrete overshoot is the simulated one where a simulation
    is quick, and tends to the continuous one at first order in Ts below (anchored on the simulation)."""
    m = 1.0 if ff in ("none", "lowpass") else 0.5
    continuous = continuous_overshoot_pct(ff, J, ALPHA, ZETA, m, tau)
    d = design(J, ALPHA, ZETA, m=m, tau_i_s=tau, feedforward=ff)
    assert d.overshoot_pct() == pytest.approx(continuous, abs=1e-6)
    anchor = simulated_overshoot_pct(discretized(J, ALPHA, ZETA, m, tau, ANCHOR_ALPHA_TS / ALPHA, ff, method))
    for alpha_Ts in ALPHA_TS_GRID:
        dd = discretized(J, ALPHA, ZETA, m, tau, alpha_Ts / ALPHA, ff, method)
        assert max(abs(p) for p in dd.poles) < 1.0
        assert "overshoot_pct" not in dd.missing
        assert math.isfinite(dd.margins.gain_margin_dB) and math.isfinite(dd.margins.phase_margin_deg)
        if alpha_Ts >= ANCHOR_ALPHA_TS:
            truth = anchor if alpha_Ts == ANCHOR_ALPHA_TS else simulated_overshoot_pct(dd)
            assert dd.overshoot_pct == pytest.approx(truth, abs=1e-7), alpha_Ts
        else:
            # below the anchor the float32 rounding of the C coefficients (1e-7 against alpha Ts) can
            # outweigh the discretization: the analysis is checked on the double-precision coefficients
            ideal = discrete_loop(
                d, alpha_Ts / ALPHA, method, oracle_coefficients(J, ALPHA, ZETA, m, tau, alpha_Ts / ALPHA, method, ff)
            )
            expected = continuous + (anchor - continuous) * alpha_Ts / ANCHOR_ALPHA_TS
            tolerance = 0.03 * abs(anchor - continuous) * alpha_Ts / ANCHOR_ALPHA_TS + 2e-5
            assert ideal.overshoot_pct == pytest.approx(expected, abs=tolerance), alpha_Ts


@pytest.mark.parametrize("ff", FEEDFORWARDS)
def test_poles_near_z_1_are_those_of_a_50_digit_root_finding(ff):
    """The paper's design at Ts = 1e-4 (alpha Ts = 5e-5): multiplied out in double precision,
    its tracking transfer function shows a pole at |z| = 1.00005; the loop is stable."""
    Ts = 1e-4
    # the double-precision coefficients of the oracle: the C's float32 ones move the poles by ~1e-12
    coefficients = oracle_coefficients(J, ALPHA, ZETA, 1.0, TAU, Ts, "tustin", ff)
    dd = discrete_loop(design(J, ALPHA, ZETA, m=1.0, tau_i_s=TAU, feedforward=ff), Ts, "tustin", coefficients)
    mpmath.mp.dps = 50
    # 1 + F(z) G(z) = 0 by hand (eq 14, ZOH of 1 / (J s (tau s + 1))), in 50 digits
    Ts_mp, tau, J_mp = mpmath.mpf(Ts), mpmath.mpf(TAU), mpmath.mpf(J)
    Kp, Ki = J_mp * mpmath.mpf(ALPHA), J_mp * mpmath.mpf(ALPHA) ** 2 / (4 * mpmath.mpf(ZETA) ** 2)
    a = mpmath.exp(-Ts_mp / tau)
    b_e0 = Kp + Ki * Ts_mp / 2
    Fn, Fd = [b_e0, Ki * Ts_mp - b_e0], [1, -1]
    Gn = [(Ts_mp - tau * (1 - a)) / J_mp, (tau * (1 - a) - a * Ts_mp) / J_mp]
    Gd = [1, -(1 + a), a]
    FdGd = [sum(Fd[i] * Gd[k - i] for i in range(2) if 0 <= k - i < 3) for k in range(4)]
    FnGn = [0] + [sum(Fn[i] * Gn[k - i] for i in range(2) if 0 <= k - i < 2) for k in range(3)]
    exact = sorted(
        mpmath.polyroots([x + y for x, y in zip(FdGd, FnGn)], maxsteps=200, extraprec=200),
        key=lambda p: (float(mpmath.re(p)), float(mpmath.im(p))),
    )
    assert all(abs(p) < 1 for p in exact)
    np.testing.assert_allclose(
        sorted(dd.poles, key=lambda p: (p.real, p.imag)), [complex(p) for p in exact], rtol=0.0, atol=1e-13
    )
    # the tracking response adds the feedforward pole -ff_a1 and the pole at 0 of r[k-1]
    assert np.max(np.abs(control.poles(dd.Gx_z))) < 1.0


def test_unstable_discrete_loop_names_the_stable_range_of_Ts():
    d = design(J, ALPHA, ZETA, tau_i_s=TAU, feedforward="none", anti_windup="none")
    with pytest.warns(SamplingWarning), pytest.raises(ValueError, match=r"^Ts_s = 12\.0 .* < ") as exc:
        d.discretize(12.0, "tustin")
    bound = float(str(exc.value).split("< ")[1].split(" s")[0])
    Kp, Ki = J * ALPHA, J * ALPHA**2 / (4 * ZETA**2)

    def radius(Ts):  # 1 + F(z) G(z) = 0 with the Tustin PI (eq 14) and the hand-derived ZOH plant
        b_e0 = Kp + Ki * Ts / 2
        Gn, Gd = zoh_plant(J, TAU, Ts)
        return np.max(np.abs(np.roots(np.polyadd(np.polymul([1.0, -1.0], Gd), np.polymul([b_e0, Ki * Ts - b_e0], Gn)))))

    assert all(radius(Ts) < 1.0 for Ts in np.linspace(1e-3, 0.999 * bound, 200))
    assert radius(1.001 * bound) > 1.0


def test_continuously_unstable_design_names_alpha():
    # Routh on J tau s^3 + J s^2 + Kp s + Ki: unstable when Kp < tau Ki, i.e. alpha tau > 4 zeta^2
    alpha = 10.0
    assert np.max(np.roots([J * TAU, J, J * alpha, J * alpha**2 / (4 * ZETA**2)]).real) > 0.0
    with pytest.raises(ValueError, match=r"^alpha_radps = 10\.0 .*< 4 zeta\^2 / tau_i_s = 6\.667"):
        design(J, alpha, ZETA, tau_i_s=TAU).discretize(1e-4, "tustin")
