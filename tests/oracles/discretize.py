"""The speed controller's coefficients derived in Python, in double precision (Table 1, eq 9-15).

An oracle for the C controller, which computes them in float32 (``p2d_speed_init``): every
dynamic part of the design is discretized with python-control ``sample_system`` (SciPy
``cont2discrete``), and the coefficients are read off the discrete transfer functions in the
form the C core realizes them (csrc/include/pmsm2dof/speed.h):

- PI: ``(b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1)``;
- feedforward: ``Fr = Kd s + D + c / (s + m alpha)`` by polynomial division; the proper part
  sampled as ``(b0 + b1 z^-1) / (1 + ff_a1 z^-1)`` and written around its static gain,
  ``ff_Fr0 + ff_b_dr (1 - z^-1) / (1 + ff_a1 z^-1)``; ``Kd s`` as ``Kd (1 - z^-1) / Ts``.
"""

import control
import numpy as np

from pmsm2dof.core import pi_gains

#: The methods as named by SciPy ``cont2discrete`` / python-control ``sample_system``.
SAMPLE_SYSTEM_METHODS = {"forward_euler": "euler", "backward_euler": "backward_diff", "tustin": "bilinear"}


def sample(tf_s, Ts_s, method):
    """``control.sample_system`` on unit-scaled coefficients (SciPy trims leading numerator
    coefficients below an absolute 1e-14: the system is sampled in normalized time, period 1,
    with numerator and denominator scaled to a largest coefficient of 1)."""
    num = np.atleast_1d(np.squeeze(tf_s.num[0][0])).astype(float)
    den = np.atleast_1d(np.squeeze(tf_s.den[0][0])).astype(float)
    n = len(den) - 1
    num = num * Ts_s ** (n - np.arange(len(num) - 1, -1, -1))
    den = den * Ts_s ** (n - np.arange(n, -1, -1))
    num_scale, den_scale = np.max(np.abs(num)), np.max(np.abs(den))
    if num_scale == 0.0:
        return control.tf([0.0], [1.0], Ts_s)
    unit = control.sample_system(control.tf(num / num_scale, den / den_scale), 1.0, method=method)
    return control.tf(unit.num[0][0] * (num_scale / den_scale), unit.den[0][0], Ts_s)


def _first_order_z(tf):
    """Numerator and denominator of a discrete first-order ``tf`` in powers of z^-1, den[0] = 1."""
    num = np.atleast_1d(np.squeeze(tf.num[0][0]))
    den = np.atleast_1d(np.squeeze(tf.den[0][0]))
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    return num / den[0], den / den[0]


def coefficients(
    J_kgm2, alpha_radps, zeta, m, tau_i_s, Ts_s, method, feedforward, Ka=None, anti_windup="back_calculation"
):
    """The fields of ``p2d_speed_coef_t`` a discretization determines, in double precision."""
    Kp, Ki = pi_gains(J_kgm2, alpha_radps, zeta)  # eq 9
    Ka = 1.0 / Kp if Ka is None else Ka
    # the integral part Ki/s sampled alone, (i0 + i1 z^-1) / (1 - z^-1): Ki Ts = i0 + i1
    (i0, i1), _ = _first_order_z(sample(control.tf([Ki], [1.0, 0.0]), Ts_s, SAMPLE_SYSTEM_METHODS[method]))
    out = {"b_e0": Kp + float(i0), "Ki_Ts": float(i0 + i1)}
    out["Ki_Ka_Ts"] = out["Ki_Ts"] * Ka if anti_windup == "back_calculation" else 0.0
    if feedforward == "none":
        return out | dict.fromkeys(("ff_Fr0", "ff_b_dr", "ff_a1", "ff_Kd_per_Ts"), 0.0)
    # eq 11 (full), tau = 0 (no_tau), m = 1 and tau = 0 (lowpass, eq 13)
    m = 1.0 if feedforward == "lowpass" else m
    tau = tau_i_s if feedforward == "full" else 0.0
    fr_num = Kp * np.array([m * tau, m - 1.0, -alpha_radps / (4.0 * zeta**2)])
    fr_den = np.array([1.0, m * alpha_radps])
    (Kd, D), c = np.polydiv(fr_num, fr_den)
    P_z = sample(control.tf(np.polyadd(D * fr_den, c), fr_den), Ts_s, SAMPLE_SYSTEM_METHODS[method])
    (b0, _), (_, a1) = _first_order_z(P_z)
    Fr0 = fr_num[-1] / fr_den[-1]
    return out | {
        "ff_Fr0": float(Fr0),
        "ff_b_dr": float(b0 - Fr0),
        "ff_a1": float(a1),
        "ff_Kd_per_Ts": float(Kd / Ts_s),
    }
