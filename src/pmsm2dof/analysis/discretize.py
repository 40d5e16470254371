"""Discretization of the speed controller (paper section 3.4, Table 1, eq 14, 15).

The coefficients are those the C controller computes (``p2d_speed_init``, float32, the code
that runs on the MCU), read from a :class:`~pmsm2dof.core.SpeedController` configured with the
design: forward Euler ``s = (z - 1)/Ts``, backward Euler ``s = (z - 1)/(z Ts)`` and Tustin
``s = 2(z - 1)/(Ts (z + 1))`` applied to every dynamic part, in the form the C core realizes
them (csrc/include/pmsm2dof/speed.h):

- PI (eq 14 for Tustin): ``u[k] = b_e0 e[k] + x[k-1]``, ``x[k] = x[k-1] + Ki Ts e[k]``,
  whose transfer function is ``(b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1)``.
- Feedforward (eq 11-13, 15): ``Fr`` split into ``Kd s + D + c / (s + m alpha)``; the proper
  part ``(b0 + b1 z^-1) / (1 + ff_a1 z^-1)`` realized around its static gain
  ``ff_Fr0 = Fr(0)`` (kept by every method) as
  ``ff_Fr0 + ff_b_dr (1 - z^-1) / (1 + ff_a1 z^-1)``, so that the steady-state torque
  ``Fr(0) r`` does not depend on the rounding of a pole near z = 1; the derivative ``Kd s``
  is always the backward difference ``Kd (1 - z^-1) / Ts``.

The rules that refuse a configuration (the feedforward pole on or outside the unit circle,
``Ki Ka Ts >= 2`` with back calculation, float32 overflow) are the C controller's too; this
module adds the analysis of the sampled loop. Nothing of the controller's maths is written
here a second time (tests/oracles/ derives the coefficients independently and checks them).

The discrete closed loop uses the zero-order-hold equivalent of the plant
``G = Gci Gm``: the torque command is held over each sampling period.

The loop's figures (stability, poles, margins; with a sensor chain, the loop assembled in z) are
those of :mod:`pmsm2dof.analysis.sampled_loop`; the tracking step response comes from the
realized difference equations in increment form
(:class:`~pmsm2dof.analysis.stepresponse.StepResponse`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..core import METHODS
from ..core.bindings import Method
from ..errors import ConfigError, Pmsm2dofWarning, require_choice, require_positive
from ..lazy import lazy_module
from .margins import Margins, frequency_margins
from .sampled_loop import (
    c_coefficients,
    closed_loop_with_sensor,
    feedforward_z,
    hurwitz,
    loop_w,
    margins_w,
    pi_z,
    sample_system,
    unstable_loop_error,
)
from .sensor import delay_periods
from .stepresponse import StepResponse

if TYPE_CHECKING:
    import control
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

if TYPE_CHECKING:
    from .design import Design

#: Largest design frequency times Ts [rad] above which the discretization is too coarse.
MAX_W_TS = 0.1
#: The coefficients of ``p2d_speed_coef_t`` a discretization determines.
COEFFICIENTS = ("b_e0", "Ki_Ts", "Ki_Ka_Ts", "ff_Fr0", "ff_b_dr", "ff_a1", "ff_Kd_per_Ts")

_Vector = npt.NDArray[np.float64]
#: Coefficients of a polynomial, highest power first (what numpy.polymul returns).
_Poly = npt.NDArray[np.floating[Any]]


class SamplingWarning(Pmsm2dofWarning):
    """The sampling period is long for the designed bandwidth: expect discretization effects."""


@dataclass(frozen=True)
class DiscreteDesign:
    """A design discretized for one sampling period and method.

    The coefficient attributes are the fields of ``p2d_speed_coef_t`` as the C core computes
    them (float32 values, as on the MCU), and the figures are those of the loop they realize.

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
        Poles of the discrete feedback loop with the ZOH plant, in z.
    overshoot_pct : float
        Overshoot [%] of the discrete tracking step response (NaN when it cannot be
        computed; ``missing`` says why).
    margins : Margins
        Margins of the discrete loop gain ``F(z) G(z)``.
    missing : dict
        ``{figure: reason}`` for each discrete figure that is NaN or infinite.
    F_z, Fr_z, G_z, L_z : control.TransferFunction
        Discrete PI, feedforward, ZOH plant and loop gain.
    Gx_z : control.StateSpace
        Tracking response, realized from the difference equations (states: plant, PI
        integral, feedforward ``y[k-1]`` and ``r[k-1]``).
    """

    design: Design
    Ts_s: float
    method: Method
    b_e0: float
    Ki_Ts: float
    Ki_Ka_Ts: float
    ff_Fr0: float
    ff_b_dr: float
    ff_a1: float
    ff_Kd_per_Ts: float
    poles: tuple[complex, ...]
    overshoot_pct: float
    margins: Margins
    missing: dict[str, str]
    F_z: control.TransferFunction = field(compare=False, repr=False)
    Fr_z: control.TransferFunction = field(compare=False, repr=False)
    G_z: control.TransferFunction = field(compare=False, repr=False)
    L_z: control.TransferFunction = field(compare=False, repr=False)
    Gx_z: control.StateSpace = field(compare=False, repr=False)

    def as_dict(self) -> dict[str, Any]:
        """Inputs, continuous and discrete results as plain numbers (JSON-ready).

        Complex poles are ``[re, im]`` pairs. A figure that is infinite or cannot be computed
        is ``None``, with the reason under ``missing``.
        """
        d = self.design
        margins, _ = d.margins().values_and_reasons()
        discrete_margins, _ = self.margins.values_and_reasons()
        overshoot = d.overshoot_pct()
        return {
            "J_kgm2": d.J_kgm2,
            "alpha_radps": d.alpha_radps,
            "zeta": d.zeta,
            "m": d.m,
            "tau_i_s": d.tau_i_s,
            "feedforward": d.feedforward,
            "anti_windup": d.anti_windup,
            "sensor": asdict(d.sensor),
            "Ts_s": self.Ts_s,
            "method": self.method,
            "Kp": d.Kp,
            "Ki": d.Ki,
            "Ka": d.Ka,
            "continuous": {
                "poles_radps": _pairs(d.closed_loop_poles()),
                "bandwidth_radps": d.bandwidth_radps(),
                "overshoot_pct": overshoot if math.isfinite(overshoot) else None,
                "margins": margins,
                "missing": d.missing(),
            },
            "discrete": {
                "poles_z": _pairs(self.poles),
                "overshoot_pct": self.overshoot_pct if math.isfinite(self.overshoot_pct) else None,
                "margins": discrete_margins,
                "missing": self.missing,
                "coefficients": {name: getattr(self, name) for name in COEFFICIENTS},
            },
        }


def _pairs(values: Iterable[complex]) -> list[list[float]]:
    return [[complex(v).real, complex(v).imag] for v in values]


def _plant_increments(J_kgm2: float, tau_i_s: float, Ts_s: float) -> tuple[_Vector, _Vector, _Vector]:
    """The ZOH plant over one period in increment form: ``(E_p, g_p, c_p)``.

    States: the torque ``T`` after the current loop (absent when tau_i = 0) and the momentum
    ``p = J w``; with ``u`` held over the period and ``a = exp(-Ts/tau)``::

        T[k+1] - T[k] = (1 - a)(u - T[k])
        p[k+1] - p[k] = tau (1 - a) T[k] + (Ts - tau (1 - a)) u,   w = p / J

    ``1 - a = -expm1(-x)`` and ``Ts - tau (1 - a) = tau (x + expm1(-x))``, ``x = Ts/tau``.
    """
    if tau_i_s == 0.0:
        return np.zeros((1, 1)), np.array([Ts_s]), np.array([1.0 / J_kgm2])
    x = Ts_s / tau_i_s
    one_minus_a = -math.expm1(-x)
    E_p = np.array([[-one_minus_a, 0.0], [tau_i_s * one_minus_a, 0.0]])
    return E_p, np.array([one_minus_a, tau_i_s * (x + math.expm1(-x))]), np.array([0.0, 1.0 / J_kgm2])


def _tracking_increments(
    design: Design,
    Ts_s: float,
    b_e0: float,
    Ki_Ts: float,
    ff_Fr0: float,
    ff_b_dr: float,
    ff_a1: float,
    ff_Kd_per_Ts: float,
) -> tuple[_Vector, _Vector, _Vector]:
    """The tracking loop over one period in increment form: ``(E, f, c)`` of a unit reference step.

    States: the plant (:func:`_plant_increments`), the PI integral ``q = x[k-1]``, and with a
    feedforward its transient ``v = y[k-1]`` and ``s = r[k-1]``; the realized difference
    equations (see the module docstring)::

        y[k] = -ff_a1 v + ff_b_dr (r - s)
        u[k] = q + b_e0 (r - w) + ff_Fr0 r + y[k] + ff_Kd_per_Ts (r - s)
        q[k+1] - q = Ki_Ts (r - w),  v[k+1] - v = y[k] - v,  s[k+1] - s = r - s
    """
    E_p, g_p, c_p = _plant_increments(design.J_kgm2, design.tau_i_s, Ts_s)
    n_p = len(g_p)
    has_ff = design.feedforward != "none"
    n = n_p + (3 if has_ff else 1)
    iq, iv, i_s = n_p, n_p + 1, n_p + 2
    # u = u_row x + u_r r
    u_row, u_r = np.zeros(n), b_e0
    u_row[:n_p], u_row[iq] = -b_e0 * c_p, 1.0
    E, f = np.zeros((n, n)), np.zeros(n)
    if has_ff:
        u_row[iv], u_row[i_s] = -ff_a1, -(ff_b_dr + ff_Kd_per_Ts)
        u_r += ff_Fr0 + ff_b_dr + ff_Kd_per_Ts
        # v[k+1] - v = -(1 + a1) v + b_dr (r - s),  s[k+1] - s = r - s
        E[iv, iv], E[iv, i_s], f[iv] = -(1.0 + ff_a1), -ff_b_dr, ff_b_dr
        E[i_s, i_s], f[i_s] = -1.0, 1.0
    E[:n_p] = np.outer(g_p, u_row)
    E[:n_p, :n_p] += E_p
    f[:n_p] = g_p * u_r
    E[iq, :n_p], f[iq] = -Ki_Ts * c_p, Ki_Ts
    c = np.zeros(n)
    c[:n_p] = c_p
    return E, f, c


def discretize(design: Design, Ts_s: float, method: Method) -> DiscreteDesign:
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
        ``Ts_s`` or ``method`` out of range; the feedforward filter or the discrete
        feedback loop unstable at this ``Ts_s`` (the message gives the periods that are
        stable); ``alpha_radps`` when the continuous loop itself is unstable
        (``alpha tau_i >= 4 zeta^2``, Routh on eq 8's denominator); or ``Ka`` too large for
        the discrete back-calculation loop ``x[k] = (1 - Ki Ka Ts) x[k-1] + ...``; the
        sensor's ``delay_s`` beyond :data:`~pmsm2dof.analysis.sensor.DELAY_PERIODS_MAX` periods.
        A stable design is never refused for a figure of merit: one that cannot be
        computed is NaN, with its reason in ``DiscreteDesign.missing``.
    """
    Ts_s = require_positive("Ts_s", Ts_s)
    require_choice("method", method, METHODS)
    d = design
    delay_periods(d.sensor.delay_s, Ts_s)  # bounded before any work
    w_design_radps = max(d.alpha_radps, d.alpha_radps / (2.0 * d.zeta), d.m * d.alpha_radps)
    if w_design_radps * Ts_s > MAX_W_TS:
        warnings.warn(
            f"Ts_s = {Ts_s:g} s is long for the design: max(alpha, alpha/(2 zeta), m alpha) * Ts_s = "
            f"{w_design_radps * Ts_s:.3g} > {MAX_W_TS}; the discrete loop departs from the continuous design",
            SamplingWarning,
            stacklevel=3,
        )
    return discrete_loop(d, Ts_s, method, c_coefficients(d, Ts_s, method))


def discrete_loop(design: Design, Ts_s: float, method: Method, coefficients: Mapping[str, float]) -> DiscreteDesign:
    """The discrete loop of ``design`` realized with the controller ``coefficients`` at ``Ts_s``.

    :func:`discretize` gives it the coefficients of the C controller; any other set in the same
    realization (a fixed-point port, the double-precision values of a test) is analysed alike.

    Parameters
    ----------
    design : Design
        The continuous design (the plant: J, tau_i; the feedforward form).
    Ts_s : float
        Sampling period [s], > 0.
    method : str
        The discretization the coefficients come from (recorded, not used).
    coefficients : mapping
        ``b_e0``, ``Ki_Ts``, ``Ki_Ka_Ts``, ``ff_Fr0``, ``ff_b_dr``, ``ff_a1``, ``ff_Kd_per_Ts``: the
        fields of ``p2d_speed_coef_t`` (its PI flattened).

    Returns
    -------
    DiscreteDesign

    Raises
    ------
    ConfigError
        The discrete feedback loop is unstable (naming the periods that are stable).
    """
    d = design
    c = {name: float(coefficients[name]) for name in COEFFICIENTS}
    b_e0, Ki_Ts = c["b_e0"], c["Ki_Ts"]
    F_z = pi_z(b_e0, Ki_Ts, Ts_s)
    if d.feedforward == "none":
        Fr_z = control.tf([0.0], [1.0], Ts_s)
    else:
        Fr_z = feedforward_z(c["ff_Fr0"], c["ff_b_dr"], c["ff_a1"], c["ff_Kd_per_Ts"], Ts_s)
    if not d.sensor.is_ideal:
        return _loop_with_sensor(d, Ts_s, method, c, F_z, Fr_z)

    # feedback loop in the w plane: 1 + F(w) G(w) = 0, stable when Re w < 0
    L_num, L_den = loop_w(d, Ts_s, b_e0, Ki_Ts)
    char_w = np.polyadd(L_den, L_num)
    poles_w = np.roots(char_w)
    poles = (1.0 + 0.5 * Ts_s * poles_w) / (1.0 - 0.5 * Ts_s * poles_w)
    if not hurwitz(char_w):
        raise unstable_loop_error(d, Ts_s, method, float(np.max(np.abs(poles))))
    E, f, out = _tracking_increments(d, Ts_s, **{k: v for k, v in c.items() if k != "Ki_Ka_Ts"})
    overshoot, reason = StepResponse(E, f, out, dt_s=Ts_s).overshoot_pct()
    margins = margins_w(d, Ts_s, b_e0, Ki_Ts)
    G_z = sample_system(d.G, Ts_s, "zoh")  # the plant held over each period, not the controller
    return DiscreteDesign(
        design=d,
        Ts_s=Ts_s,
        method=method,
        **c,
        poles=tuple(complex(p) for p in poles),
        overshoot_pct=overshoot,
        margins=margins,
        missing=({"overshoot_pct": reason} if reason else {}) | margins.values_and_reasons()[1],
        F_z=F_z,
        Fr_z=Fr_z,
        G_z=G_z,
        L_z=F_z * G_z,
        Gx_z=control.ss(np.eye(len(f)) + E, f[:, None], out[None, :], 0.0, Ts_s),
    )


def _loop_with_sensor(
    design: Design,
    Ts_s: float,
    method: Method,
    c: Mapping[str, float],
    F_z: control.TransferFunction,
    Fr_z: control.TransferFunction,
) -> DiscreteDesign:
    """:func:`discrete_loop` for a design whose controller reads a sensor chain (see the module docstring)."""
    d = design
    plant, closed = closed_loop_with_sensor(d, Ts_s, F_z, Fr_z)
    poles = np.linalg.eigvals(closed.A)
    z_max = float(np.max(np.abs(poles)))
    if not z_max < 1.0:
        raise ConfigError(
            "Ts_s",
            Ts_s,
            f"a period at which the discrete loop reading the sensor chain ({d.sensor.describe()}) is stable: at "
            f"Ts_s = {Ts_s:g} s its largest closed-loop pole has |z| = {z_max:.6g} (see the continuous margins, "
            "and Design.max_alpha_for_phase_margin)",
        )
    reading = control.interconnect(plant, inplist=["u"], outlist=["y"], ignore_outputs=["w"], dt=Ts_s)
    # the plant to y_0 (a few states), then the filters and z^-n of the whole periods of delay
    y_0 = plant[0][1, 0]
    A, B, C, D = y_0.A, y_0.B, y_0.C, y_0.D
    n_delay, _lam = delay_periods(d.sensor.delay_s, Ts_s)
    b_e0, Ki_Ts = c["b_e0"], c["Ki_Ts"]

    def L_of_w(w: npt.NDArray[np.float64]) -> npt.NDArray[np.complex128]:
        z = np.exp(1j * np.asarray(w, dtype=float) * Ts_s)
        M = z[:, None, None] * np.eye(len(A)) - A
        P = (C @ np.linalg.solve(M, np.broadcast_to(B, (len(z),) + B.shape)))[:, 0, 0] + D[0, 0]
        P = P * d.sensor.filter_frequency_response(Ts_s, w) * z**-n_delay
        return np.asarray((b_e0 + (Ki_Ts - b_e0) / z) / (1.0 - 1.0 / z) * P, dtype=np.complex128)

    L_nyquist = L_of_w(np.array([math.pi / Ts_s]))[0].real
    extra = [(1.0 / abs(L_nyquist), math.pi / Ts_s)] if L_nyquist < 0.0 else []
    w_lo = 1e-3 * min(d._frequencies())
    margins = frequency_margins(L_of_w, w_lo, (1.0 - 1e-9) * math.pi / Ts_s, extra) if w_lo < math.pi / Ts_s else None
    if margins is None:
        margins = Margins(math.nan, math.nan, math.nan, math.nan)
    overshoot, reason = StepResponse(
        closed.A - np.eye(len(closed.A)), closed.B[:, 0], closed.C[0], dt_s=Ts_s
    ).overshoot_pct()
    G_z = sample_system(d.G, Ts_s, "zoh")
    return DiscreteDesign(
        design=d,
        Ts_s=Ts_s,
        method=method,
        **c,
        poles=tuple(complex(p) for p in poles),
        overshoot_pct=overshoot,
        margins=margins,
        missing=({"overshoot_pct": reason} if reason else {}) | margins.values_and_reasons()[1],
        F_z=F_z,
        Fr_z=Fr_z,
        G_z=G_z,
        L_z=control.tf(F_z * control.ss(reading)),
        Gx_z=closed,
    )
