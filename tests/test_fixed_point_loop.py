"""The fixed-point speed controllers in closed loop: the dead zone the scaling check predicts is
the steady-state error Q15 leaves, Q31 removes it, and float32 and Q31 agree within a derived bound.

The drive: the paper's (J = 0.4 kg m^2, alpha = 0.5 rad/s, zeta = 1/(2 sqrt 3): Kp = 0.2, Ki = 0.3,
Ka = 1/Kp; Tustin, lowpass feedforward, back calculation; surface PMSM, kt = 1.2 Nm/A, 7.6 A:
9.12 Nm) sampled at Ts = 1e-4 s, where ``Ki Ts = 3e-5`` Nm per rad/s of error per sample. The
plant, written here: a rigid rotor ``J dw/dt = T - T_load`` with the torque held over each sample
(an ideal current loop), integrated exactly in double: ``w[k+1] = w[k] + Ts/J (T[k] - T_load)``.
The controllers read ``w`` rounded to their format (float32, or the nearest Q15/Q31 integer) and
start at rest at 500 rpm (``reset``); the paper's 8 Nm load (condition 2) is applied at 0.5 s.
Scalings: 1000 rpm and 10 Nm full scale.

Truth: the scaling check's dead zone comes from the quantised coefficients and the header's
rounding rule, not from running the loop; the float32-Q31 bound from a rounding analysis of
each controller (below), propagated through the loop's difference equations.
"""

import math

import numpy as np
import pytest

from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.fixedpoint import scaling_check
from pmsm2dof.core import SpeedController
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.core.fixedpoint import FixedPointSpeedController

#: Slow (seconds of closed loop at 10 kHz in Python): run by the full suite.
pytestmark = pytest.mark.slow

J, ALPHA, ZETA, TAU_I = 0.4, 0.5, 1.0 / (2.0 * math.sqrt(3.0)), 0.05
TS = 1e-4
RPM = math.pi / 30.0
W0 = 500.0 * RPM
T_LOAD, T_LOAD_AT = 8.0, 0.5
DRIVE = dict(
    J_kgm2=J, alpha_radps=ALPHA, zeta=ZETA, tau_i_s=TAU_I, Ts_s=TS, i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01,
    Lq_H=0.01, pole_pairs=4, method="tustin", feedforward="lowpass", anti_windup="back_calculation",
)  # fmt: skip
SCALES = dict(speed_full_scale_radps=1000.0 * RPM, torque_full_scale_Nm=10.0, current_full_scale_A=10.0)
T_MAX = 1.5 * 4 * 0.2 * 7.6


def check(fmt):
    return scaling_check(
        design(J, ALPHA, ZETA, tau_i_s=TAU_I),
        TS,
        fmt=fmt,
        speed_full_scale_radps=SCALES["speed_full_scale_radps"],
        torque_full_scale_Nm=SCALES["torque_full_scale_Nm"],
        T_max_Nm=T_MAX,
    )


def load(t):
    """The load torque [Nm] at t: the 8 Nm step."""
    return T_LOAD if t >= T_LOAD_AT else 0.0


def fixed_loop(fmt, n, load_of_t=load, record=False):
    """The fixed-point controller in closed loop for n samples: (final error [LSB], records or None).

    Records per sample: the plant speed before the sample [rad/s], the error [LSB], u and T_ref
    [LSB], and the integrator state after it [its LSB]."""
    ctl = FixedPointSpeedController(fmt, **DRIVE, **SCALES)
    r = ctl.speed_to_q(W0)
    ctl.reset(r, 0)
    c, out = ctl._ctl, ffi.new(f"p2d_speed_{fmt}_output_t *")
    step = getattr(lib, f"p2d_speed_{fmt}_step")
    per_w = 2**ctl.bits / SCALES["speed_full_scale_radps"]
    T_per_lsb = SCALES["torque_full_scale_Nm"] / 2**ctl.bits
    x_name = "x_q15" if fmt == "q15" else "x_q62"
    e_name, u_name, T_name = f"e_{fmt}", f"T_unsat_{fmt}", f"T_ref_{fmt}"
    w = W0
    rows = []
    for k in range(n):
        step(c, r, round(w * per_w), out)
        if record:
            rows.append((w, getattr(out, e_name), getattr(out, u_name), getattr(out, T_name), getattr(c, x_name)))
        w += TS / J * (getattr(out, T_name) * T_per_lsb - load_of_t(k * TS))
    return ctl, getattr(out, e_name), (np.array(rows, dtype=np.float64) if record else None), rows


def float_loop(n):
    """The float32 controller in the same loop: records (w, e, u, T_ref, x) per sample [SI]."""
    ctl = SpeedController(**DRIVE)
    ctl.reset(W0, 0.0)
    c, out = ctl._ctl, ffi.new("p2d_speed_output_t *")
    w = W0
    rows = []
    for k in range(n):
        lib.p2d_speed_step(c, W0, w, out)
        rows.append((w, out.e_radps, out.T_unsat_Nm, out.T_ref_Nm, c.x_Nm))
        w += TS / J * (out.T_ref_Nm - load(k * TS))
    return np.array(rows, dtype=np.float64)


def test_q15_dead_zone_is_the_steady_state_error_of_a_slowly_applied_load():
    """The dead zone is the largest error the Q15 integrator leaves: the paper's 8 Nm load applied
    slowly (over 100 s), which the error follows along the zone's edge, ends on the edge, to the LSB."""
    report = check("q15")
    dz = report.dead_zone
    assert report.flagged and dz.high_lsb > 1000  # 48.6 rpm of 1000: tens of rpm, as the trap says

    def ramp(t):
        return T_LOAD * min(max(t - T_LOAD_AT, 0.0) / 100.0, 1.0)

    _, e_final, _, _ = fixed_loop("q15", 1_200_000, ramp)
    print(
        f"\nQ15 dead zone predicted: {dz.high_radps / RPM:.4f} rpm ({dz.high_lsb:.0f} LSB); steady-state error "
        f"after the slow 8 Nm load: {e_final * dz.speed_lsb_radps / RPM:.4f} rpm ({e_final} LSB)"
    )
    assert dz.high_lsb - 1 <= e_final <= dz.high_lsb


def test_q15_keeps_an_error_inside_the_dead_zone_after_the_load_step_and_q31_removes_it():
    """After the paper's 8 Nm load step the Q15 error stops inside the predicted zone, where the
    integrator no longer moves (wherever the decaying oscillation last enters it); Q31's error decays
    to its limit cycle, within the amplitude its check allows."""
    q15, q31 = check("q15"), check("q31")
    _, e15, _, rows15 = fixed_loop("q15", 300_000, record=True)
    tail15 = [row[1] for row in rows15[-50_000:]]
    assert min(tail15) == max(tail15) == e15, "Q15 has not settled"
    assert q15.dead_zone.low_lsb <= e15 <= q15.dead_zone.high_lsb
    assert abs(e15) * q15.dead_zone.speed_lsb_radps <= q15.limit_cycle_radps
    # the integrator is at rest there: its increment rounds to 0 (speed_fixed.h)
    m, s = FixedPointSpeedController("q15", **DRIVE, **SCALES).coefficients["Ki_Ts"]
    assert (m * e15 + (1 << (s - 1))) >> s == 0

    ctl31, _, _, rows31 = fixed_loop("q31", 1_000_000, record=True)
    lsb31 = q31.dead_zone.speed_lsb_radps
    at_60_s = rows31[600_000][1] * lsb31
    tail31 = [abs(row[1]) * lsb31 for row in rows31[-50_000:]]
    print(
        f"\nafter the 8 Nm load step: Q15 error {e15 * q15.dead_zone.speed_lsb_radps / RPM:.3f} rpm (its dead zone "
        f"{q15.dead_zone.high_radps / RPM:.3f} rpm); Q31 error at 60 s {at_60_s / RPM:.2e} rpm, over 95-100 s "
        f"at most {max(tail31) / RPM:.2e} rpm (its limit-cycle bound {q31.limit_cycle_radps / RPM:.2e} rpm)"
    )
    assert q31.dead_zone.removed
    # the loop's slowest mode decays as exp(-zeta w_n t) = exp(-t / 4 s): 15 time constants at 60 s
    assert abs(at_60_s) < 1e-3 < abs(e15) * q15.dead_zone.speed_lsb_radps
    assert max(tail31) <= q31.limit_cycle_radps


# ---------------------------------------------------------------------------------------------
# float32 against Q31: a derived bound
# ---------------------------------------------------------------------------------------------
#
# Both controllers compute the same discrete controller (eq 14, 15; constant reference: the
# feedforward transient is exactly 0 in both) up to rounding. Write each run i as the exact
# equations on its own signals plus a residual:
#   u_i = b (r - w_i) + x_i + n_u,i,   T_i = Sat(u_i) at its limit L_i,
#   x_i' = x_i + Ki Ts (r - w_i) + Ki Ka Ts (T_i - u_i) + n_x,i,   w_i' = w_i + Ts/J (T_i - T_load) + n_w,i
# with b = Kp + Ki Ts / 2, the exact coefficients. The saturation is monotone and 1-Lipschitz: at
# the exact limit L, Sat(u_f) - Sat(u_q) = theta_k (u_f - u_q) with theta_k in [0, 1] (read from
# the two runs), and the limits differ by lambda_k, |lambda| <= |L_f - L| + |L_q - L|. The
# differences d_w = w_f - w_q, d_x = x_f - x_q then follow the linear time-varying system
#   d_w' = (1 - Ts/J theta b) d_w + Ts/J theta d_x + Ts/J theta n_u + Ts/J lambda + n_w
#   d_x' = -(Ki Ts + Ki Ka Ts (theta - 1) b) d_w + (1 + Ki Ka Ts (theta - 1)) d_x
#          + Ki Ka Ts (theta - 1) n_u + Ki Ka Ts lambda + n_x
# from d = 0 (both start at rest at 500 rpm), with n = n_f - n_q, so that
#   |d_w[n]| <= sum_k sum_j |(C Phi(n, k+1) B_k)_j| (|n_j,f[k]| + |n_j,q[k]|)
# (C = [1 0], Phi the transition matrices), the impulse responses taken backwards from each
# checked sample. The residual bounds, per sample, from each format's rounding (U = 2^-24):
# - float32: the inputs r and w rounded to float32 and e = r - w rounded: |eta_e| <= U (|r| + |w| + |e|);
#   each coefficient from at most 7 float32 roundings of the design (Kp, Ki Ts, b_e0, Ki Ka Ts with
#   Ka = 1/(J alpha)): relative error <= 8 U; u = fmaf(b_e0, e, x) rounded once: U |u|; the limit
#   T_max from kt = 1.5 p psi_f, the MTPA norm and the ulps speed.c lowers it by: <= 8 U T_max;
#   the integrator x + fl(Ki Ts e) (+ fmaf(Ki Ka Ts, fl(T - u), .) when limited): a rounding of each
#   product and sum, U (|Ki Ts e| + 2 |Ki Ka Ts u*| + |dx| + |x'|) with 8 U on each coefficient;
# - Q31: w and r rounded to the nearest LSB: |eta_e| <= 1 speed LSB; coefficients normalised to
#   31-bit mantissas: relative error <= 2^-31 (and the double they come from, 2^-45 more);
#   u = R(b e) + R(x_q62, 31): 1 torque LSB; T_max floored: 1 torque LSB; the integrator rounds
#   two products to 2^-31 of a torque LSB: 2^-31 LSB;
# - the plant (double, the same code for both): 2^-52 (|w'| + Ts/J |T - T_load|) and, for Q31,
#   Ts/J 2^-53 |T| for the torque's conversion to Nm.
# The bound holds while the integrator and u stay within the formats' ranges (checked).

U32 = 2.0**-24


def residual_bounds(f, q, r_exact, b, Ki_Ts, Ki_Ka_Ts):
    """(W_u, W_lambda, W_x, W_w): the bounds of the residuals of both runs, per sample [SI]."""
    w_f, e_f, u_f, T_f, x_f = f.T
    W_lsb = SCALES["speed_full_scale_radps"] * 2.0**-31
    T_lsb = SCALES["torque_full_scale_Nm"] * 2.0**-31
    w_q, e_q, u_q, T_q = q[:, 0], q[:, 1] * W_lsb, q[:, 2] * T_lsb, q[:, 3] * T_lsb
    c32, c31 = 8.0 * U32, 2.0**-31 * (1.0 + 2.0**-14)
    # float32
    eta_e_f = U32 * (abs(r_exact) + np.abs(w_f) + np.abs(e_f)) * (1.0 + 4.0 * U32)
    n_u_f = c32 * b * np.abs(e_f) + b * eta_e_f + U32 * np.abs(u_f)
    ustar_f = np.abs(T_f - u_f)
    n_x_f = (
        (1.0 + c32) * (U32 * Ki_Ts * np.abs(e_f) + 2.0 * U32 * Ki_Ka_Ts * ustar_f)
        + c32 * (Ki_Ts * np.abs(e_f) + Ki_Ka_Ts * ustar_f)
        + Ki_Ts * eta_e_f
        + U32 * (Ki_Ts * np.abs(e_f) + Ki_Ka_Ts * ustar_f)
        + U32 * (np.abs(x_f) + Ki_Ts * np.abs(e_f) + Ki_Ka_Ts * ustar_f)
    )
    # Q31
    eta_e_q = W_lsb * (1.0 + 2.0**-30)
    n_u_q = c31 * b * np.abs(e_q) + b * eta_e_q + T_lsb * (1.0 + 2.0**-30)
    n_x_q = c31 * (Ki_Ts * np.abs(e_q) + Ki_Ka_Ts * np.abs(T_q - u_q)) + Ki_Ts * eta_e_q + 2.0**-31 * T_lsb
    # the plant
    n_w = 2.0**-52 * (
        np.abs(w_f) + np.abs(w_q) + 2.0 * TS / J * (np.abs(T_f) + np.abs(T_q) + T_LOAD)
    ) + TS / J * 2.0**-53 * np.abs(T_q)
    W_lambda = 8.0 * U32 * T_MAX + T_lsb * (1.0 + 2.0**-30)
    return n_u_f + n_u_q, W_lambda, n_x_f + n_x_q, n_w


def ltv_bound(theta, W_u, W_lambda, W_x, W_w, checks, b, Ki_Ts, Ki_Ka_Ts):
    """The bound of |d_w[n]| at each sample n of ``checks``: the impulse responses backwards from n."""
    g = TS / J
    n_of = np.asarray(checks)
    p = np.zeros((len(checks), 2))
    acc = np.zeros(len(checks))
    for k in range(max(checks) - 1, -1, -1):
        p[n_of == k + 1] = (1.0, 0.0)
        th = theta[k]
        a = Ki_Ka_Ts * (th - 1.0)
        col_u = p[:, 0] * (g * th) + p[:, 1] * a
        col_l = p[:, 0] * g + p[:, 1] * Ki_Ka_Ts
        acc += np.abs(col_u) * W_u[k] + np.abs(col_l) * W_lambda + np.abs(p[:, 1]) * W_x[k] + np.abs(p[:, 0]) * W_w[k]
        p = np.stack(
            (p[:, 0] * (1.0 - g * th * b) + p[:, 1] * (-Ki_Ts - a * b), p[:, 0] * g * th + p[:, 1] * (1.0 + a)), axis=1
        )
    return acc


def test_float32_and_q31_agree_within_the_derived_bound():
    n = 150_000  # 15 s: the load step, the saturation of the current limit (11.7 Nm wanted, 9.12 held), recovery
    f = float_loop(n)
    _, _, q, _ = fixed_loop("q31", n, record=True)
    T_lsb = SCALES["torque_full_scale_Nm"] * 2.0**-31
    u_f, u_q = f[:, 2], q[:, 2] * T_lsb
    # within the ranges the analysis assumes: u and x inside two full scales, no clamping of either
    assert np.max(np.abs(q[:, 2])) < 2**32 - 1 and np.max(np.abs(q[:, 4])) < 2**63 - 2**40
    saturated = np.abs(f[:, 3]) >= 0.999 * T_MAX
    assert saturated.sum() > 1000, "the load step should drive the command into the current limit"

    Kp, Ki = J * ALPHA, J * (ALPHA / (2.0 * ZETA)) ** 2
    b, Ki_Ts, Ki_Ka_Ts = Kp + Ki * TS / 2.0, Ki * TS, Ki * TS / Kp
    sat_f, sat_q = np.clip(u_f, -T_MAX, T_MAX), np.clip(u_q, -T_MAX, T_MAX)
    du = u_f - u_q
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.where(du != 0.0, (sat_f - sat_q) / du, (np.abs(u_f) < T_MAX).astype(float))
    assert np.all((theta >= 0.0) & (theta <= 1.0 + 1e-12))
    checks = list(range(2_500, n, 2_500))
    bound = ltv_bound(theta, *residual_bounds(f, q, W0, b, Ki_Ts, Ki_Ka_Ts), checks, b, Ki_Ts, Ki_Ka_Ts)
    # w after sample n - 1 is the speed read at sample n
    w_f = np.append(f[1:, 0], np.nan)
    w_q = np.append(q[1:, 0], np.nan)
    diff = np.abs(w_f - w_q)[np.array(checks) - 1]
    worst = int(np.argmax(diff / bound))
    print(
        f"\nfloat32 - Q31 speed over 15 s: largest {diff.max():.3g} rad/s ({diff.max() / RPM:.3g} rpm), bound "
        f"{bound.min():.3g} to {bound.max():.3g} rad/s; closest to its bound at {checks[worst] * TS:.2f} s: "
        f"{diff[worst]:.3g} of {bound[worst]:.3g} rad/s"
    )
    assert np.all(diff <= bound)
