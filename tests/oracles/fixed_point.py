"""An independent model of the fixed-point speed controllers (csrc/include/pmsm2dof/speed_fixed.h).

Written from the header's rules with Python integers, which neither overflow nor round: a
product is exact, ``R(p, s) = floor(p / 2^s + 1/2)`` is ``(p + 2^(s-1)) >> s`` (Python's ``>>``
floors), saturation is ``min``/``max``. The gains (mantissa, shift) are an input of the model;
:func:`exact_gains` derives the values they approximate with exact rational arithmetic, from the
float32 configuration, and :func:`quantise` the mantissa and shift the header's rule gives them.
"""

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

#: Fractional bits N and the integrator's extra bits F of each format.
BITS = {"q15": (15, 0), "q31": (31, 31)}
INT64_MAX = 2**63 - 1


def R(p, s):
    """floor(p / 2^s + 1/2)."""
    return p if s == 0 else (p + (1 << (s - 1))) >> s


def clamp(v, limit):
    return max(-limit, min(limit, v))


def sat64(v):
    """v limited to [-(2^63 - 1), 2^63 - 1]."""
    return clamp(v, INT64_MAX)


@dataclass
class State:
    x: int  # integrator plus static feedforward, in LSBs of 2^-(N + F) full scales
    y: int  # feedforward transient y[k-1]
    r: int  # reference of the previous sample


class Model:
    """The controller of one format with the quantised coefficients ``coef`` (mantissa, shift pairs)."""

    def __init__(self, fmt, coef):
        self.N, self.F = BITS[fmt]
        self.L = 2 ** (self.N + 1) - 1  # every signal within two full scales
        self.c = coef
        self.state = State(0, 0, 0)

    def mul(self, name, v):
        """R(g v) in the LSB of the result."""
        m, s = self.c[name]
        return R(m * v, s)

    def mul_x(self, name, v):
        """R(g v) in the LSB of the integrator (2^-F of the result's); Q31: limited to the int64 range."""
        m, s = self.c[name]
        if self.F == 0:
            return R(m * v, s)
        return R(m * v, s - self.F) if s >= self.F else sat64(m * v * 2 ** (self.F - s))

    def reset(self, w_ref, T_init):
        self.state = State(T_init * 2**self.F, 0, w_ref)

    def compute(self, w_ref, w_m):
        c, st, L = self.c, self.state, self.L
        e = w_ref - w_m
        dr = w_ref - st.r
        T_d = self.mul("ff_Kd_per_Ts", dr)
        x = R(st.x, self.F)
        # y[k] = b_dr dr[k] - a1 y[k-1], with the stored 1 + a1
        y = clamp(self.mul("ff_b_dr", dr) + st.y - self.mul("ff_one_plus_a1", st.y), L)
        u = clamp(self.mul("b_e0", e) + x + self.mul("ff_Fr0", dr) + T_d + y, L)
        T = clamp(u, c["T_max"])
        return dict(
            w_ref=w_ref,
            e=e,
            T_ff=clamp(self.mul("ff_Fr0", w_ref) + T_d + y, L),
            y_ff=y,
            T_unsat=u,
            T_ref=T,
            iq_ref=clamp(self.mul("iq_per_T", T), c["iq_max"]),
            saturated=T != u,
        )

    def update(self, out, T_applied):
        st = self.state
        dr = out["w_ref"] - st.r
        u_star = clamp(T_applied - out["T_unsat"], self.L)
        e = out["e"]
        if self.F == 0:
            dx = self.mul_x("Ki_Ts", e) + self.mul_x("Ki_Ka_Ts", u_star)
            if self.c["clamping"] and u_star * e < 0:
                dx = 0
            x = clamp(st.x + dx + self.mul_x("ff_Fr0", dr), self.L)
        else:
            # Q31: each addition saturates to the int64 range, in the header's order
            dx = sat64(self.mul_x("Ki_Ts", e) + self.mul_x("Ki_Ka_Ts", u_star))
            if self.c["clamping"] and u_star * e < 0:
                dx = 0
            x = sat64(sat64(st.x + dx) + self.mul_x("ff_Fr0", dr))
        self.state = State(x, out["y_ff"], out["w_ref"])


def f32(x):
    """The float32 value of x as an exact Fraction."""
    return Fraction(float(np.float32(x)))


def exact_gains(cfg):
    """The gains of speed_fixed.h per unit (p2d_speed_fixed_gains_t) as exact Fractions of the float32 config.

    Kp = J alpha, Ki = J (alpha / (2 zeta))^2 (eq 9); b_e0 by method (eq 14, Table 1); the
    feedforward Fr = J alpha (m tau s^2 + (m - 1) s - alpha / (4 zeta^2)) / (s + m alpha) (eq 11,
    lowpass: m = 1, tau = 0; no_tau: tau = 0) split as Kd s + D + c / (s + p), p = m alpha, whose
    proper part c / (s + p) is discretised by the method and realised around its static gain:
    b_dr is the weight of r[k] - r[k-1], a1 of -y[k-1] (stored as 1 + a1).
    """
    J, alpha, zeta = f32(cfg["J_kgm2"]), f32(cfg["alpha_radps"]), f32(cfg["zeta"])
    Ts, Ka = f32(cfg["Ts_s"]), f32(cfg["Ka"])
    W, T_fs, I_fs = (
        f32(cfg["speed_full_scale_radps"]),
        f32(cfg["torque_full_scale_Nm"]),
        f32(cfg["current_full_scale_A"]),
    )
    per_unit = W / T_fs
    Kp = J * alpha
    Ki = J * (alpha / (2 * zeta)) ** 2
    method, ff = cfg["method"], cfg["feedforward"]
    b_e0 = {"forward_euler": Kp, "backward_euler": Kp + Ki * Ts, "tustin": Kp + Ki * Ts / 2}[method]
    g = dict(
        b_e0=b_e0 * per_unit,
        Ki_Ts=Ki * Ts * per_unit,
        Ki_Ka_Ts=Ki * Ka * Ts if cfg["anti_windup"] == "back_calculation" else Fraction(0),
    )
    if ff == "none":
        g.update(ff_Fr0=Fraction(0), ff_b_dr=Fraction(0), ff_one_plus_a1=Fraction(0), ff_Kd_per_Ts=Fraction(0))
    else:
        m = Fraction(1) if ff == "lowpass" else f32(cfg["m"])
        tau = f32(cfg["tau_i_s"]) if ff == "full" else Fraction(0)
        p = m * alpha
        Kd = Kp * m * tau  # the s^2 coefficient over s
        D = Kp * ((m - 1) - m * tau * p)  # the constant of the division
        c = Kp * (-alpha / (4 * zeta**2)) - D * p  # the remainder over (s + p)
        if method == "forward_euler":  # c Ts z^-1 / (1 - (1 - p Ts) z^-1)
            b0, a1 = Fraction(0), p * Ts - 1
        elif method == "backward_euler":  # c Ts / ((1 + p Ts) - z^-1)
            b0, a1 = c * Ts / (1 + p * Ts), -1 / (1 + p * Ts)
        else:  # c Ts (1 + z^-1) / ((2 + p Ts) - (2 - p Ts) z^-1)
            b0, a1 = c * Ts / (2 + p * Ts), -(2 - p * Ts) / (2 + p * Ts)
        # around the static gain c / p: b0 + b1 z^-1 = (c/p)(1 + a1 z^-1) + b_dr (1 - z^-1)
        g.update(
            ff_Fr0=(D + c / p) * per_unit,
            ff_b_dr=(b0 - c / p) * per_unit,
            ff_one_plus_a1=1 + a1,
            ff_Kd_per_Ts=Kd / Ts * per_unit,
        )
    kt = Fraction(3, 2) * cfg["pole_pairs"] * f32(cfg["psi_f_Wb"])
    g.update(iq_per_T=T_fs / (kt * I_fs), T_max=kt * f32(cfg["i_max_A"]) / T_fs, iq_max=f32(cfg["i_max_A"]) / I_fs)
    return g


def quantise(g, bits):
    """(mantissa, shift) of the exact gain g by the rule of speed_fixed.h, and g 2^shift (unrounded)."""
    top, max_shift = 2**bits, 2 * bits + 1
    s = 0
    while s < max_shift and abs(g) * 2 ** (s + 1) < top:
        s += 1
    scaled = abs(g) * 2**s
    m = int(scaled + Fraction(1, 2))  # ties away from zero
    if m >= top:
        s, scaled = s - 1, scaled / 2
        m = int(scaled + Fraction(1, 2))
    return (m if g >= 0 else -m), s, (scaled if g >= 0 else -scaled)
