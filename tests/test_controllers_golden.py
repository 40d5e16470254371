"""Golden tests: the C controllers against sequences computed here, in float64.

The expected sequences come from difference equations derived by hand in this
file from the paper's equations (eq 9 gains, eq 11/13 feedforward, eq 14/15
and Table 1 discretizations, Fig. 5 back calculation), cross-checked against
python-control's ``sample_system``; the current loop against the analytic
first-order response of eq 3 with the dq model (eq 1) integrated exactly.
The C code computes in float32, so comparisons use a float32 tolerance scaled
by the size of the signal.
"""

import math

import control
import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from scipy.optimize import minimize_scalar

from pmsm2dof.core import ANTI_WINDUPS, METHODS, CurrentController, SpeedController
from pmsm2dof.core.bindings import ffi, lib


def f32(x):
    """The float32 number the C code works with, as a Python float."""
    return float(np.float32(x))


SURFACE = dict(psi_f_Wb=0.05, Ld_H=2e-3, Lq_H=2e-3, pole_pairs=4)
SALIENT = dict(psi_f_Wb=0.05, Ld_H=1e-3, Lq_H=4e-3, pole_pairs=4)
DESIGN = dict(J_kgm2=0.02, alpha_radps=200.0, zeta=0.8, Ts_s=1e-4, i_max_A=12.0)


def gains(J_kgm2, alpha_radps, zeta):
    """Eq 9: Kp = J alpha, Ki = J (alpha / (2 zeta))^2, from the float32 inputs."""
    J, a, z = f32(J_kgm2), f32(alpha_radps), f32(zeta)
    return J * a, J * (a / (2 * z)) ** 2


def torque_Nm(id_A, iq_A, psi_f_Wb, Ld_H, Lq_H, pole_pairs):
    """Amplitude-invariant torque 1.5 p (psi_f iq + (Ld - Lq) id iq) (eq 1 with the 3/2 restored)."""
    return 1.5 * pole_pairs * (psi_f_Wb * iq_A + (Ld_H - Lq_H) * id_A * iq_A)


def max_torque_Nm(i_A, motor):
    """Largest torque of a current vector of length i_A, by a bounded search over its angle."""
    res = minimize_scalar(
        lambda ang: -torque_Nm(i_A * math.cos(ang), i_A * math.sin(ang), **motor),
        bounds=(math.pi / 2, math.pi) if motor["Ld_H"] < motor["Lq_H"] else (0.0, math.pi / 2),
        method="bounded",
        options={"xatol": 1e-10},
    )
    return -res.fun


def feedforward_polynomials(form, J_kgm2, alpha_radps, zeta, m, tau_i_s):
    """Fr(s) = num(s) / (s + p) of eq 11 (full, no_tau: tau_i = 0) and eq 13 (lowpass)."""
    J, a, z, m, tau = f32(J_kgm2), f32(alpha_radps), f32(zeta), f32(m), f32(tau_i_s)
    if form == "lowpass":
        return [-J * (a / (2 * z)) ** 2], a
    tau = tau if form == "full" else 0.0
    return [J * a * m * tau, J * a * (m - 1), -J * a * a / (4 * z * z)], m * a


def first_order_section(n1, n0, p, Ts, method):
    """(n1 s + n0) / (s + p) discretized by Table 1: y[k] + a1 y[k-1] = b0 r[k] + b1 r[k-1].

    Substituting s, with q = z^-1:
      forward Euler  s = (1 - q) / (Ts q):   (n1 + (n0 Ts - n1) q) / (1 + (p Ts - 1) q)
      backward Euler s = (1 - q) / Ts:       ((n1 + n0 Ts) - n1 q) / ((1 + p Ts) - q)
      Tustin         s = 2 (1 - q) / (Ts (1 + q)):
                     ((2 n1 + n0 Ts) + (n0 Ts - 2 n1) q) / ((2 + p Ts) + (p Ts - 2) q)
    """
    if method == "forward_euler":
        return n1, n0 * Ts - n1, p * Ts - 1
    if method == "backward_euler":
        d = 1 + p * Ts
        return (n1 + n0 * Ts) / d, -n1 / d, -1 / d
    d = 2 + p * Ts
    return (2 * n1 + n0 * Ts) / d, (n0 * Ts - 2 * n1) / d, (p * Ts - 2) / d


def feedforward_sequence(r, form, method, J_kgm2, alpha_radps, zeta, m, tau_i_s, Ts_s):
    """T_ff[k] for the reference r[k] (r[-1] = 0, rest).

    Fr = Kd s + (n1 s + n0) / (s + p) with Kd = num[0], n1 = num[1] - Kd p,
    n0 = num[2] (division of num(s) by s + p); the proper part by the method,
    the derivative by the backward difference Kd (r[k] - r[k-1]) / Ts.
    """
    if form == "none":
        return np.zeros_like(r)
    num, p = feedforward_polynomials(form, J_kgm2, alpha_radps, zeta, m, tau_i_s)
    num = [0.0] * (3 - len(num)) + num
    Kd, n1, n0 = num[0], num[1] - num[0] * p, num[2]
    Ts = f32(Ts_s)
    b0, b1, a1 = first_order_section(n1, n0, p, Ts, method)
    y = np.empty_like(r)
    y_prev = r_prev = 0.0
    for k, rk in enumerate(r):
        y[k] = b0 * rk + b1 * r_prev - a1 * y_prev
        y_prev = y[k]
        r_prev = rk
    return y + Kd * np.diff(r, prepend=0.0) / Ts


def speed_reference(
    w_ref, w_m, T_ff, method, anti_windup, Ka, T_max_Nm, J_kgm2, alpha_radps, zeta, Ts_s, ties=None, **_
):
    """u[k] and u_sat[k] of the PI with anti-windup, by hand, for given sequences.

    Integral part of F (eq 14 and Table 1), e[-1] = 0:
      forward Euler  I[k] = I[k-1] + Ki Ts e[k-1]
      backward Euler I[k] = I[k-1] + Ki Ts e[k]
      Tustin         I[k] = I[k-1] + Ki Ts (e[k] + e[k-1]) / 2
    u[k] = Kp e[k] + I[k] + T_ff[k], u_sat = Sat(u), u* = u_sat - u.
    Back calculation (Fig. 5, dI/dt = Ki (e + Ka u*)): the u* known after the
    output enters one sample later, + Ki Ka Ts u*[k-1].
    Clamping (conditional integration): sample k-1 is held if the limit was
    active and u[k-1] e[k-1] > 0 (the error drives further into it); its error
    is then taken out of the integral, - Ki Ts e[k-1].

    ``w_m`` may be a callable ``w_m(k, u_sat_history)`` that closes the loop.
    ``ties`` (the controller's saturated flags) settles only the samples where
    |u| is within float32 rounding of the limit, where either answer is right
    and float64 and float32 may differ (clamping keeps u near the limit).
    """
    Kp, Ki = gains(J_kgm2, alpha_radps, zeta)
    Ts = f32(Ts_s)
    n = len(w_ref)
    u = np.empty(n)
    u_sat = np.empty(n)
    w = np.empty(n)
    I_prev = e_prev = u_star_prev = 0.0
    held_prev = False
    for k in range(n):
        w[k] = w_m(k, u_sat[:k]) if callable(w_m) else w_m[k]
        e = w_ref[k] - w[k]
        dI = {
            "forward_euler": Ki * Ts * e_prev,
            "backward_euler": Ki * Ts * e,
            "tustin": Ki * Ts * (e + e_prev) / 2,
        }[method]
        if anti_windup == "back_calculation":
            dI += Ki * Ka * Ts * u_star_prev
        if held_prev:
            dI -= Ki * Ts * e_prev
        I = I_prev + dI
        u[k] = Kp * e + I + T_ff[k]
        saturated = abs(u[k]) > T_max_Nm
        if ties is not None and abs(abs(u[k]) - T_max_Nm) <= 1e-5 * max(abs(I), abs(T_ff[k]), T_max_Nm):
            saturated = bool(ties[k])
        u_sat[k] = math.copysign(T_max_Nm, u[k]) if saturated else u[k]
        u_star_prev = u_sat[k] - u[k]
        held_prev = anti_windup == "clamping" and saturated and u[k] * e > 0
        I_prev, e_prev = I, e
    return u, u_sat, w


def closed_loop_speed(J_kgm2, Ts_s):
    """w_m for speed_reference: the rigid shaft J dw/dt = T, sampled exactly (float32 values)."""
    step = f32(Ts_s) / J_kgm2

    def w_m(k, u_sat):
        return 0.0 if k == 0 else f32(w_m.prev + step * u_sat[-1])

    def tracked(k, u_sat):
        w_m.prev = w_m(k, u_sat)
        return w_m.prev

    return tracked


def assert_float32_close(actual, expected, what, scale=None, rel=2e-5):
    """|actual - expected| <= rel * scale, scale = max|expected| unless given (float32 rounding)."""
    scale = max(float(np.max(np.abs(expected))) if scale is None else scale, 1e-30)
    err = float(np.max(np.abs(np.asarray(actual, dtype=float) - expected)))
    assert err <= rel * scale, f"{what}: max error {err:.3g} > {rel:g} * {scale:.3g}"


def speed_steps(n=4000):
    """Reference: rest, a step to 20 rad/s, a reversal to -10 rad/s (float32 values)."""
    k = np.arange(n)
    w_ref = np.where(k < 20, 0.0, 20.0)
    w_ref = np.where(k >= 2000, -10.0, w_ref)
    return np.float32(w_ref).astype(float)


def make_speed(method, feedforward, anti_windup, motor=SURFACE, m=1.0, tau_i_s=0.0, Ka=None):
    return SpeedController(
        **DESIGN, **motor, m=m, tau_i_s=tau_i_s, Ka=Ka, method=method, feedforward=feedforward, anti_windup=anti_windup
    )


@pytest.mark.parametrize("method", METHODS)
def test_unsaturated_pi_is_F_of_z(method):
    """Eq 14 / Table 1: with no limit active the error path is F(z), the method's c2d of Kp + Ki/s."""
    ctl = make_speed(method, "none", "none")
    Kp, Ki = gains(DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"])
    Fz = control.sample_system(
        control.tf([Kp, Ki], [1, 0]),
        f32(DESIGN["Ts_s"]),
        method={"forward_euler": "euler", "backward_euler": "backward_diff", "tustin": "tustin"}[method],
    )
    rng = np.random.default_rng(7)
    e = np.float32(rng.uniform(-0.5, 0.5, 400)).astype(float)
    out = ctl.run(e, 0.0)
    expected = scipy.signal.lfilter(Fz.num[0][0], Fz.den[0][0], e)
    assert not out["saturated"].any()
    assert_float32_close(out["T_unsat_Nm"], expected, "u")
    assert_float32_close(out["T_ref_Nm"], expected, "u_sat")


def test_tustin_lowpass_feedforward_eq15():
    """Eq 15 written out: (2/Ts (1 - q) + alpha (1 + q)) y = -Ki (1 + q) r, with q = z^-1."""
    ctl = make_speed("tustin", "lowpass", "back_calculation")
    Kp, Ki = gains(DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"])
    a, Ts = f32(DESIGN["alpha_radps"]), f32(DESIGN["Ts_s"])
    r = np.float32(np.r_[np.zeros(5), np.full(200, 80.0), np.linspace(80, -50, 300)]).astype(float)
    y = np.empty_like(r)
    y_prev = r_prev = 0.0
    for k in range(len(r)):
        y[k] = ((2 / Ts - a) * y_prev - Ki * (r[k] + r_prev)) / (2 / Ts + a)
        y_prev, r_prev = y[k], r[k]
    out = ctl.run(r, r)
    assert_float32_close(out["T_ff_Nm"], y, "T_ff")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("form", ["lowpass", "no_tau", "full"])
def test_hand_derived_feedforward_matches_python_control(method, form):
    """The hand substitutions of first_order_section equal python-control's sample_system."""
    num, p = feedforward_polynomials(form, DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"], 1.6, 2e-3)
    num = [0.0] * (3 - len(num)) + num
    n1, n0 = num[1] - num[0] * p, num[2]
    Ts = 1e-3
    b0, b1, a1 = first_order_section(n1, n0, p, Ts, method)
    Gz = control.sample_system(
        control.tf([n1, n0], [1, p]),
        Ts,
        method={"forward_euler": "euler", "backward_euler": "backward_diff", "tustin": "tustin"}[method],
    )
    num_z, den_z = np.atleast_1d(Gz.num[0][0]), np.atleast_1d(Gz.den[0][0])
    num_z = np.r_[np.zeros(2 - len(num_z)), num_z] / den_z[0]
    np.testing.assert_allclose(
        [b0, b1, a1], [num_z[0], num_z[1], den_z[1] / den_z[0]], rtol=1e-12, atol=1e-12 * abs(n0)
    )


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("form, m, tau_i_s", [("lowpass", 1.0, 0.0), ("no_tau", 1.6, 0.0), ("full", 0.7, 2e-3)])
def test_feedforward_settles_on_its_static_gain(method, form, m, tau_i_s):
    """After a reference step T_ff settles on Fr(0) r to float32 rounding (eq 11 at s = 0; eq 13: -Ki/alpha).

    The feedforward pole is near z = 1 here (m alpha Ts = 0.014 to 0.032); a section on r with that pole
    amplifies float32 rounding by about 1 / (m alpha Ts) and settled 6e-5 to 3e-4 Nm off on these 46 to 105 Nm.
    """
    ctl = SpeedController(
        **{**DESIGN, "i_max_A": 1e4},
        **SURFACE,
        m=m,
        tau_i_s=tau_i_s,
        method=method,
        feedforward=form,
        anti_windup="none",
    )
    num, p = feedforward_polynomials(form, DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"], m, tau_i_s)
    r = 47.0
    expected = num[-1] / p * r
    n = int(40 / (f32(m) * f32(DESIGN["alpha_radps"]) * f32(DESIGN["Ts_s"])))  # 40 time constants
    out = ctl.run(np.full(n, r), r)
    assert not out["saturated"].any()
    ulp = float(np.spacing(np.float32(abs(expected))))
    assert abs(float(out["T_ff_Nm"][-1]) - expected) <= 4 * ulp, (float(out["T_ff_Nm"][-1]), expected)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    "form, m, tau_i_s", [("none", 1.0, 0.0), ("lowpass", 1.0, 0.0), ("no_tau", 1.6, 0.0), ("full", 0.7, 2e-3)]
)
@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
def test_speed_controller_golden(method, form, m, tau_i_s, anti_windup):
    """Whole runs with saturated stretches: C output against the hand-derived sequences.

    The speed sequence is made by closing the hand-derived controller around a
    rigid shaft (so that the run saturates and recovers as a drive does); the C
    controller then gets the same reference and speed sequences.
    """
    ctl = make_speed(method, form, anti_windup, m=m, tau_i_s=tau_i_s)
    w_ref = speed_steps()
    T_ff = feedforward_sequence(
        w_ref, form, method, DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"], m, tau_i_s, DESIGN["Ts_s"]
    )
    Kp, _ = gains(DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"])
    T_max = 1.5 * SURFACE["pole_pairs"] * f32(SURFACE["psi_f_Wb"]) * f32(DESIGN["i_max_A"])
    w_m = closed_loop_speed(DESIGN["J_kgm2"], DESIGN["Ts_s"])
    u, u_sat, w = speed_reference(w_ref, w_m, T_ff, method, anti_windup, 1 / Kp, T_max, **DESIGN)
    out = ctl.run(w_ref, w)
    if anti_windup == "clamping":
        u, u_sat, _ = speed_reference(
            w_ref, w, T_ff, method, anti_windup, 1 / Kp, T_max, **DESIGN, ties=out["saturated"]
        )

    saturated = np.abs(u) > T_max
    assert saturated.sum() > 1000, "the run must saturate"
    if anti_windup != "none":  # without anti-windup the run stays wound up: F(z) is tested unsaturated above
        assert (~saturated).sum() > 1000, "the run must recover"
    # float32 rounding of the largest terms summed into u (integral and feedforward)
    scale = max(np.max(np.abs(u)), np.max(np.abs(T_ff)), np.max(np.abs(u - T_ff)))
    assert_float32_close(out["T_ff_Nm"], T_ff, "T_ff")
    assert_float32_close(out["T_unsat_Nm"], u, "u", scale=scale)
    assert_float32_close(out["T_ref_Nm"], u_sat, "u_sat", scale=scale)
    # surface PMSM: id = 0, iq = T / (1.5 p psi_f)
    assert np.all(out["id_ref_A"] == 0)
    kt = 1.5 * SURFACE["pole_pairs"] * f32(SURFACE["psi_f_Wb"])
    assert_float32_close(out["iq_ref_A"], u_sat / kt, "iq", scale=scale / kt)
    assert not out["fault"].any()


@pytest.mark.parametrize("anti_windup", ["back_calculation", "clamping"])
def test_applied_torque_drives_the_anti_windup(anti_windup):
    """compute/update with a tighter limit downstream: u* = T_applied - u, as in Fig. 5."""
    ctl = make_speed("tustin", "lowpass", anti_windup)
    w_ref = speed_steps(2000)
    T_ff = feedforward_sequence(
        w_ref, "lowpass", "tustin", DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"], 1.0, 0.0, DESIGN["Ts_s"]
    )
    Kp, _ = gains(DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"])
    T_applied_max = 2.0
    w_m = closed_loop_speed(DESIGN["J_kgm2"], DESIGN["Ts_s"])
    u, u_sat, w = speed_reference(w_ref, w_m, T_ff, "tustin", anti_windup, 1 / Kp, T_applied_max, **DESIGN)
    got, ties = [], []
    for r, wk in zip(w_ref, w):
        out = ctl.compute(r, wk)
        T_applied = min(max(out.T_ref_Nm, -T_applied_max), T_applied_max)
        ctl.update(out, T_applied)
        got.append(out.T_unsat_Nm)
        ties.append(T_applied != out.T_unsat_Nm)
    u, _, _ = speed_reference(w_ref, w, T_ff, "tustin", anti_windup, 1 / Kp, T_applied_max, **DESIGN, ties=ties)
    assert_float32_close(got, u, "u", scale=np.max(np.abs(T_ff)))


def test_salient_saturation_uses_the_mtpa_torque_limit():
    """Salient PMSM: the torque limit is the MTPA torque at ||i|| = i_max, found here by search."""
    ctl = make_speed("tustin", "lowpass", "back_calculation", motor=SALIENT)
    motor32 = {k: (f32(v) if isinstance(v, float) else v) for k, v in SALIENT.items()}
    T_max = max_torque_Nm(f32(DESIGN["i_max_A"]), motor32)
    w_ref = speed_steps()
    T_ff = feedforward_sequence(
        w_ref, "lowpass", "tustin", DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"], 1.0, 0.0, DESIGN["Ts_s"]
    )
    Kp, _ = gains(DESIGN["J_kgm2"], DESIGN["alpha_radps"], DESIGN["zeta"])
    w_m = closed_loop_speed(DESIGN["J_kgm2"], DESIGN["Ts_s"])
    u, u_sat, w = speed_reference(w_ref, w_m, T_ff, "tustin", "back_calculation", 1 / Kp, T_max, **DESIGN)
    out = ctl.run(w_ref, w)
    scale = max(np.max(np.abs(u)), np.max(np.abs(T_ff)))
    assert_float32_close(out["T_ref_Nm"], u_sat, "u_sat", scale=scale)
    Te = torque_Nm(out["id_ref_A"].astype(float), out["iq_ref_A"].astype(float), **motor32)
    assert_float32_close(Te, out["T_ref_Nm"], "torque of the current command", rel=1e-5)
    norm = np.hypot(out["id_ref_A"].astype(float), out["iq_ref_A"].astype(float))
    assert np.all(norm <= f32(DESIGN["i_max_A"]) * (1 + 1e-6))
    assert np.max(norm) > 0.999 * DESIGN["i_max_A"]


@pytest.mark.parametrize(
    "motor",
    [
        SALIENT,
        dict(psi_f_Wb=0.01, Ld_H=1e-3, Lq_H=10e-3, pole_pairs=3),
        dict(psi_f_Wb=0.1, Ld_H=3e-3, Lq_H=1e-3, pole_pairs=2),
    ],
)
def test_mtpa_current_gives_the_torque_at_least_current(motor):
    """MTPA: the current command produces the commanded torque, and no shorter current vector can."""
    ctl = SpeedController(**DESIGN, **motor, anti_windup="none")
    motor32 = {k: (f32(v) if isinstance(v, float) else v) for k, v in motor.items()}
    T_max = ctl.coefficients["T_max_Nm"]
    assert T_max == pytest.approx(max_torque_Nm(f32(DESIGN["i_max_A"]), motor32), rel=1e-5)
    for T in np.linspace(-T_max, T_max, 25):
        ctl.reset(0.0, T)
        out = ctl.compute(0.0, 0.0)
        Te = torque_Nm(out.id_ref_A, out.iq_ref_A, **motor32)
        assert Te == pytest.approx(out.T_ref_Nm, rel=1e-5, abs=1e-6 * T_max)
        i = math.hypot(out.id_ref_A, out.iq_ref_A)
        assert i <= f32(DESIGN["i_max_A"]) * (1 + 1e-6)
        # the largest torque of a vector of this length is the command: it is the MTPA point
        assert max_torque_Nm(i, motor32) == pytest.approx(abs(Te), rel=1e-5, abs=1e-6 * T_max)


# ---------------------------------------------------------------------------------------------
# Current controller
# ---------------------------------------------------------------------------------------------

RL = dict(Rs_ohm=0.4, Ld_H=2e-3, Lq_H=3e-3, psi_f_Wb=0.05)


def dq_model_step(Ts, Rs_ohm, Ld_H, Lq_H, psi_f_Wb, w_e_radps):
    """Exact sampling (ZOH) of the dq model of eq 1 at constant speed: x[k+1] = Ad x + Bd (u, 1)."""
    A = np.array([[-Rs_ohm / Ld_H, w_e_radps * Lq_H / Ld_H], [-w_e_radps * Ld_H / Lq_H, -Rs_ohm / Lq_H]])
    B = np.array([[1 / Ld_H, 0, 0], [0, 1 / Lq_H, -w_e_radps * psi_f_Wb / Lq_H]])
    M = np.zeros((5, 5))
    M[:2, :2] = A
    M[:2, 2:] = B
    E = scipy.linalg.expm(M * Ts)
    return E[:2, :2], E[:2, 2:]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("w_e_radps", [0.0, 800.0])
def test_current_loop_is_first_order(method, w_e_radps):
    """Decoupled PI with Kp = L/tau_i, Ki = Rs/tau_i on the dq model: i = i_ref (1 - exp(-t/tau_i)) (eq 3)."""
    tau_i, Ts = 2e-3, 2e-5
    ctl = CurrentController(**RL, tau_i_s=tau_i, Ts_s=Ts, method=method)
    Ad, Bd = dq_model_step(f32(Ts), **RL, w_e_radps=w_e_radps)
    x = np.zeros(2)
    n = 1000
    i = np.empty((n, 2))
    id_ref, iq_ref = -1.0, 2.0
    for k in range(n):
        i[k] = x
        out = ctl.step(id_ref, iq_ref, x[0], x[1], w_e_radps, 400.0)
        assert not out.saturated
        x = Ad @ x + Bd @ np.array([out.ud_ref_V, out.uq_ref_V, 1.0])
    t = np.arange(n) * f32(Ts)
    # a sampled loop with a hold lags the continuous one by about half a sample: Ts / (2 tau_i) = 0.5 %
    np.testing.assert_allclose(i[:, 0], id_ref * (1 - np.exp(-t / tau_i)), atol=0.015 * abs(id_ref))
    np.testing.assert_allclose(i[:, 1], iq_ref * (1 - np.exp(-t / tau_i)), atol=0.015 * abs(iq_ref))


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
def test_voltage_limit_holds(anti_windup):
    """||u_dq|| <= u_dc / sqrt(3) in a run with large steps on the dq model, with d-axis priority.

    The limit, written here: ud_sat = Sat(ud) within +-u_max, uq_sat = Sat(uq) within
    +-sqrt(u_max^2 - ud_sat^2).
    """
    tau_i, Ts, u_dc = 1e-3, 1e-4, 60.0
    ctl = CurrentController(**RL, tau_i_s=tau_i, Ts_s=Ts, anti_windup=anti_windup)
    Ad, Bd = dq_model_step(f32(Ts), **RL, w_e_radps=300.0)
    x = np.zeros(2)
    refs = [(0.0, 40.0)] * 100 + [(-20.0, -30.0)] * 100 + [(0.0, 1.0)] * 100 + [(60.0, 5.0)] * 100
    u_max = f32(u_dc) * f32(1 / math.sqrt(3))
    cut = {"d": 0, "q": 0}
    for id_ref, iq_ref in refs:
        out = ctl.step(id_ref, iq_ref, x[0], x[1], 300.0, u_dc)
        norm = math.hypot(out.ud_ref_V, out.uq_ref_V)
        assert norm <= u_max * (1 + 1e-6)
        ud_sat = min(max(out.ud_unsat_V, -u_max), u_max)
        room = math.sqrt(max(u_max**2 - ud_sat**2, 0.0))
        uq_sat = min(max(out.uq_unsat_V, -room), room)
        assert out.ud_ref_V == pytest.approx(ud_sat, rel=1e-6, abs=1e-6 * u_max)
        assert out.uq_ref_V == pytest.approx(uq_sat, rel=1e-6, abs=1e-6 * u_max)
        assert out.saturated == (abs(out.ud_unsat_V) > u_max or abs(out.uq_unsat_V) > room * (1 + 1e-6))
        cut["d"] += abs(out.ud_unsat_V) > u_max
        cut["q"] += abs(out.uq_unsat_V) > room
        x = Ad @ x + Bd @ np.array([out.ud_ref_V, out.uq_ref_V, 1.0])
    assert cut["q"] > 20 and cut["d"] > 5


@pytest.mark.parametrize("method", METHODS)
def test_current_pi_sequence(method):
    """Per-axis PI of the same form as eq 14 plus the decoupling of eq 1, over given sequences."""
    tau_i, Ts = 1e-3, 1e-4
    ctl = CurrentController(**RL, tau_i_s=tau_i, Ts_s=Ts, method=method, anti_windup="none")
    rng = np.random.default_rng(3)
    n = 300
    ed, eq = (np.float32(rng.uniform(-1, 1, n)).astype(float) for _ in range(2))
    id_, iq = (np.float32(rng.uniform(-5, 5, n)).astype(float) for _ in range(2))
    w_e = np.float32(rng.uniform(-500, 500, n)).astype(float)
    out = ctl.run(id_ + ed, iq + eq, id_, iq, w_e, 1e4)
    c2d = {"forward_euler": "euler", "backward_euler": "backward_diff", "tustin": "tustin"}[method]
    Rs, Ld, Lq, psi = (f32(RL[k]) for k in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb"))
    tau, Ts = f32(tau_i), f32(Ts)
    Fd = control.sample_system(control.tf([Ld / tau, Rs / tau], [1, 0]), Ts, method=c2d)
    Fq = control.sample_system(control.tf([Lq / tau, Rs / tau], [1, 0]), Ts, method=c2d)
    ud = scipy.signal.lfilter(Fd.num[0][0], Fd.den[0][0], ed) - w_e * Lq * iq
    uq = scipy.signal.lfilter(Fq.num[0][0], Fq.den[0][0], eq) + w_e * (Ld * id_ + psi)
    assert_float32_close(out["ud_ref_V"], ud, "ud")
    assert_float32_close(out["uq_ref_V"], uq, "uq")


# ---------------------------------------------------------------------------------------------
# Transforms
# ---------------------------------------------------------------------------------------------


def _clarke(a, b, c):
    p = ffi.new("float[2]")
    lib.p2d_clarke(a, b, c, p, p + 1)
    return p[0], p[1]


def _park(x_alpha, x_beta, th):
    p = ffi.new("float[2]")
    lib.p2d_park(x_alpha, x_beta, math.sin(th), math.cos(th), p, p + 1)
    return p[0], p[1]


def test_balanced_three_phase_set_gives_constant_dq():
    """i_a = I cos(th + phi), i_b, i_c shifted by -+120 deg, seen at angle th: (I cos phi, I sin phi)."""
    I, phi = 5.0, -0.4
    for th in np.linspace(0, 4 * math.pi, 50):
        abc = [I * math.cos(th + phi - k * 2 * math.pi / 3) for k in range(3)]
        d, q = _park(*_clarke(*abc), th)
        assert d == pytest.approx(I * math.cos(phi), abs=1e-5 * I)
        assert q == pytest.approx(I * math.sin(phi), abs=1e-5 * I)


def test_clarke_park_round_trips():
    rng = np.random.default_rng(11)
    for a, b, th in rng.uniform(-10, 10, (50, 3)):
        c = -a - b
        x_alpha, x_beta = _clarke(a, b, c)
        abc = ffi.new("float[3]")
        lib.p2d_inv_clarke(x_alpha, x_beta, abc, abc + 1, abc + 2)
        np.testing.assert_allclose(list(abc), [a, b, c], atol=1e-5 * 20)
        d, q = _park(x_alpha, x_beta, th)
        ab = ffi.new("float[2]")
        lib.p2d_inv_park(d, q, math.sin(th), math.cos(th), ab, ab + 1)
        np.testing.assert_allclose(list(ab), [x_alpha, x_beta], atol=1e-5 * 20)
