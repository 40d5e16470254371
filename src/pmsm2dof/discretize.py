"""Discretization of the speed controller (paper section 3.4, Table 1, eq 14, 15).

Every dynamic part is discretized with python-control ``sample_system`` (SciPy
``cont2discrete``): forward Euler ``s = (z - 1)/Ts`` ('euler'), backward Euler
``s = (z - 1)/(z Ts)`` ('backward_diff') and Tustin ``s = 2(z - 1)/(Ts (z + 1))``
('bilinear'). The coefficients are read off the discrete transfer functions in
the form the C core realizes them (csrc/include/pmsm2dof/speed.h):

- PI (eq 14 for Tustin): ``u[k] = b_e0 e[k] + x[k-1]``, ``x[k] = x[k-1] + Ki Ts e[k]``,
  whose transfer function is ``(b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1)``.
- Feedforward (eq 11-13, 15): ``Fr`` is split by polynomial division into
  ``Kd s + D + c / (s + m alpha)``; the proper part ``D + c/(s + m alpha)`` becomes
  ``(b0 + b1 z^-1) / (1 + ff_a1 z^-1)``, realized around its static gain
  ``ff_Fr0 = Fr(0)`` (kept by every method) as
  ``ff_Fr0 + ff_b_dr (1 - z^-1) / (1 + ff_a1 z^-1)``, ``ff_b_dr = b0 - ff_Fr0``, so that
  the steady-state torque ``Fr(0) r`` does not depend on the rounding of a pole near
  z = 1; the derivative ``Kd s`` is always the backward difference ``Kd (1 - z^-1) / Ts``.

The discrete closed loop uses the zero-order-hold equivalent of the plant
``G = Gci Gm``: the torque command is held over each sampling period.
"""

import math
import warnings
from dataclasses import asdict, dataclass, field

import control
import numpy as np

from .controllers import METHODS
from .design import Design, Margins, loop_margins, step_overshoot_pct, tracking_tf
from .errors import ConfigError, require_choice, require_positive

#: The same methods as named by SciPy ``cont2discrete`` / python-control ``sample_system``.
SAMPLE_SYSTEM_METHODS = {"forward_euler": "euler", "backward_euler": "backward_diff", "tustin": "bilinear"}
#: Largest design frequency times Ts [rad] above which the discretization is too coarse.
MAX_W_TS = 0.1
#: The coefficients of ``p2d_speed_coef_t`` a discretization determines.
COEFFICIENTS = ("b_e0", "Ki_Ts", "Ki_Ka_Ts", "ff_Fr0", "ff_b_dr", "ff_a1", "ff_Kd_per_Ts")


class SamplingWarning(UserWarning):
    """The sampling period is long for the designed bandwidth: expect discretization effects."""


@dataclass(frozen=True)
class DiscreteDesign:
    """A design discretized for one sampling period and method.

    The coefficient attributes carry the names and meaning of the fields of
    ``p2d_speed_coef_t`` in the C core (computed here in double precision).

    Attributes
    ----------
    design : Design
        The continuous design.
    Ts_s : float
        Sampling period [s].
    method : str
        One of :data:`METHODS`.
    b_e0 : float
        PI output gain on ``e[k]`` [Nm/(rad/s)].
    Ki_Ts : float
        Integrator increment per unit error [Nm/(rad/s)].
    Ki_Ka_Ts : float
        Integrator increment per Nm of ``u*`` [-]; 0 unless back calculation.
    ff_Fr0 : float
        Static gain ``Fr(0)`` of the feedforward, weight of ``r[k]`` [Nm/(rad/s)].
    ff_b_dr : float
        Transient section, weight of ``r[k] - r[k-1]`` [Nm/(rad/s)].
    ff_a1 : float
        Transient section, weight of ``-y[k-1]`` [-].
    ff_Kd_per_Ts : float
        Derivative term of the ``full`` feedforward, ``J alpha m tau_i / Ts`` [Nm/(rad/s)].
    poles : tuple of complex
        Poles of the discrete feedback loop with the ZOH plant.
    overshoot_pct : float
        Overshoot [%] of the discrete tracking step response ``Gx_z``.
    margins : Margins
        Margins of the discrete loop gain ``L_z``.
    F_z, Fr_z, G_z, L_z, Gx_z : control.TransferFunction
        Discrete PI, feedforward, ZOH plant, loop gain and tracking response.
    """

    design: Design
    Ts_s: float
    method: str
    b_e0: float
    Ki_Ts: float
    Ki_Ka_Ts: float
    ff_Fr0: float
    ff_b_dr: float
    ff_a1: float
    ff_Kd_per_Ts: float
    poles: tuple
    overshoot_pct: float
    margins: Margins
    F_z: control.TransferFunction = field(compare=False, repr=False)
    Fr_z: control.TransferFunction = field(compare=False, repr=False)
    G_z: control.TransferFunction = field(compare=False, repr=False)
    L_z: control.TransferFunction = field(compare=False, repr=False)
    Gx_z: control.TransferFunction = field(compare=False, repr=False)

    def as_dict(self):
        """Inputs, continuous and discrete results as plain numbers (JSON-ready).

        Complex poles are ``[re, im]`` pairs; infinite or undefined margins are ``None``.
        """
        d = self.design
        return {
            "J_kgm2": d.J_kgm2, "alpha_radps": d.alpha_radps, "zeta": d.zeta, "m": d.m, "tau_i_s": d.tau_i_s,
            "feedforward": d.feedforward, "anti_windup": d.anti_windup, "Ts_s": self.Ts_s, "method": self.method,
            "Kp": d.Kp, "Ki": d.Ki, "Ka": d.Ka,
            "continuous": {
                "poles_radps": _pairs(d.closed_loop_poles()),
                "bandwidth_radps": d.bandwidth_radps(),
                "overshoot_pct": d.overshoot_pct(),
                "margins": _finite_dict(asdict(d.margins())),
            },
            "discrete": {
                "poles_z": _pairs(self.poles),
                "overshoot_pct": self.overshoot_pct,
                "margins": _finite_dict(asdict(self.margins)),
                "coefficients": {name: getattr(self, name) for name in COEFFICIENTS},
            },
        }


def _pairs(values):
    return [[complex(v).real, complex(v).imag] for v in values]


def _finite_dict(values):
    return {k: (v if math.isfinite(v) else None) for k, v in values.items()}


def _sample(tf_s, Ts_s, method):
    """``control.sample_system(tf_s, Ts_s, method)`` computed on unit-scaled coefficients.

    SciPy trims leading numerator coefficients below an absolute 1e-14, which drops
    significant ones of a design with a tiny inertia, bandwidth or sampling period.
    The system is therefore sampled in normalized time (``s = s' / Ts_s``, period 1)
    with its numerator and denominator scaled to a largest coefficient of 1, and the
    gain is restored afterwards; the result is the same transfer function.
    """
    num = np.atleast_1d(np.squeeze(tf_s.num[0][0])).astype(float)
    den = np.atleast_1d(np.squeeze(tf_s.den[0][0])).astype(float)
    n = len(den) - 1
    # H(s'/Ts) multiplied above and below by Ts^n: the coefficient of s^k gets Ts^(n - k)
    num = num * Ts_s ** (n - np.arange(len(num) - 1, -1, -1))
    den = den * Ts_s ** (n - np.arange(n, -1, -1))
    num_scale, den_scale = np.max(np.abs(num)), np.max(np.abs(den))
    if num_scale == 0.0:
        return control.tf([0.0], [1.0], Ts_s)
    unit = control.sample_system(control.tf(num / num_scale, den / den_scale), 1.0, method=method)
    return control.tf(unit.num[0][0] * (num_scale / den_scale), unit.den[0][0], Ts_s)


def _coefficients_z(tf):
    """Numerator and denominator of a discrete first-order ``tf`` in powers of z^-1, den[0] = 1."""
    num = np.atleast_1d(np.squeeze(tf.num[0][0]))
    den = np.atleast_1d(np.squeeze(tf.den[0][0]))
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    return num / den[0], den / den[0]


def discretize(design, Ts_s, method):
    """Discretize ``design`` for the sampling period ``Ts_s`` with ``method`` (Table 1).

    Parameters
    ----------
    design : Design
        The continuous design.
    Ts_s : float
        Sampling period [s], > 0.
    method : {'forward_euler', 'backward_euler', 'tustin'}
        Discretization of the PI and of the proper part of the feedforward.

    Returns
    -------
    DiscreteDesign

    Warns
    -----
    SamplingWarning
        When the largest design frequency, ``max(alpha, alpha/(2 zeta), m alpha)``,
        times ``Ts_s`` exceeds :data:`MAX_W_TS`.

    Raises
    ------
    ConfigError
        ``Ts_s`` or ``method`` out of range, the feedforward filter or the discrete
        feedback loop unstable at this ``Ts_s``, or ``Ka`` too large for the discrete
        back-calculation loop ``x[k] = (1 - Ki Ka Ts) x[k-1] + ...``.
    """
    Ts_s = require_positive("Ts_s", Ts_s)
    require_choice("method", method, METHODS)
    d = design
    w_design_radps = max(d.alpha_radps, d.alpha_radps / (2.0 * d.zeta), d.m * d.alpha_radps)
    if w_design_radps * Ts_s > MAX_W_TS:
        warnings.warn(
            f"Ts_s = {Ts_s:g} s is long for the design: max(alpha, alpha/(2 zeta), m alpha) * Ts_s = "
            f"{w_design_radps * Ts_s:.3g} > {MAX_W_TS}; the discrete loop departs from the continuous design",
            SamplingWarning,
            stacklevel=3,
        )
    c2d_method = SAMPLE_SYSTEM_METHODS[method]

    # PI: F(z) = (b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1), eq 14 for Tustin
    F_z = _sample(d.F, Ts_s, c2d_method)
    num, _ = _coefficients_z(F_z)
    b_e0 = float(num[0])
    Ki_Ts = float(num[0] + num[1])
    Ki_Ka_Ts = Ki_Ts * d.Ka if d.anti_windup == "back_calculation" else 0.0
    if Ki_Ka_Ts >= 2.0:
        raise ConfigError(
            "Ka", d.Ka,
            f"finite, >= 0 and < 2 / (Ki Ts_s) = {2.0 / Ki_Ts:.6g} with back_calculation at Ts_s = {Ts_s:g} s "
            "(stability of the discrete anti-windup loop)")

    # feedforward: Fr = Kd s + D + c / (s + m alpha) = Kd s + P(s)
    if d.feedforward == "none":
        ff_Fr0 = ff_b_dr = ff_a1 = ff_Kd_per_Ts = 0.0
        Fr_z = control.tf([0.0], [1.0], Ts_s)
    else:
        fr_num, fr_den = d.fr_polynomials()
        (Kd, D), c = np.polydiv(fr_num, fr_den)
        P_z = _sample(control.tf(np.polyadd(D * fr_den, c), fr_den), Ts_s, c2d_method)
        (b0, _), (_, ff_a1) = _coefficients_z(P_z)
        # P(z) = Fr(0) + (b0 - Fr(0)) (1 - z^-1) / (1 + a1 z^-1), as b0 + b1 = Fr(0) (1 + a1)
        ff_Fr0 = fr_num[-1] / fr_den[-1]
        ff_b_dr = b0 - ff_Fr0
        if abs(ff_a1) >= 1.0:
            raise ConfigError(
                "Ts_s", Ts_s,
                f"small enough that the feedforward pole stays inside the unit circle "
                f"(m*alpha*Ts_s = {fr_den[1] * Ts_s:.4g}, must be < 2 with {method})")
        # Kd s -> Kd (1 - z^-1) / Ts
        ff_Kd_per_Ts = Kd / Ts_s
        Fr_z = P_z + control.tf([ff_Kd_per_Ts, -ff_Kd_per_Ts], [1.0, 0.0], Ts_s) if Kd != 0.0 else P_z

    G_z = _sample(d.G, Ts_s, "zoh")
    L_z = F_z * G_z
    poles = control.poles(control.feedback(L_z, 1))
    r_max = float(np.max(np.abs(poles)))
    if not r_max < 1.0:
        raise ConfigError(
            "Ts_s", Ts_s,
            f"small enough that the discrete loop is stable (with {method} and a ZOH plant the largest "
            f"closed-loop pole has |z| = {r_max:.6g} >= 1)")
    Gx_z = tracking_tf(F_z, Fr_z, G_z)
    return DiscreteDesign(
        design=d, Ts_s=Ts_s, method=method,
        b_e0=b_e0, Ki_Ts=Ki_Ts, Ki_Ka_Ts=Ki_Ka_Ts,
        ff_Fr0=float(ff_Fr0), ff_b_dr=float(ff_b_dr), ff_a1=float(ff_a1), ff_Kd_per_Ts=float(ff_Kd_per_Ts),
        poles=tuple(complex(p) for p in poles),
        overshoot_pct=step_overshoot_pct(Gx_z),
        margins=loop_margins(L_z),
        F_z=F_z, Fr_z=Fr_z, G_z=G_z, L_z=L_z, Gx_z=Gx_z,
    )
