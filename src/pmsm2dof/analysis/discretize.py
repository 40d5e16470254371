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

Near z = 1 (a sampling period much shorter than the loop's time constants) the roots and
values of transfer functions multiplied out in z are lost to rounding: the coefficients of
``(z - 1)^2 (z - a) + ...`` no longer carry the poles' distance to 1, and a stable loop
shows a pole at 1.00005. The loop's figures are therefore computed from forms that keep
that distance:

- stability, poles and margins in the w plane, ``z = (1 + w Ts/2) / (1 - w Ts/2)``, where
  the realized PI is exactly ``Kp' + Ki / w`` (``Kp' = b_e0 - Ki Ts / 2``) and the ZOH plant
  ``(1 - w Ts/2)(1 + kappa w) / (J w (1 + rho w))`` (derived in :func:`plant_w`); the
  characteristic polynomial has continuous-like coefficients, so the Routh-Hurwitz test
  (``Re w < 0`` is ``|z| < 1``) is decided without root finding, and python-control finds the
  margins of ``L(w)`` as for a continuous loop (gain and phase are those of ``L(z)``; the
  frequency maps back as ``w_z = (2/Ts) atan(w_w Ts/2)``);
- the tracking step response from the realized difference equations in increment form
  (:class:`~pmsm2dof.analysis.stepresponse.StepResponse`).

With a sensor chain (:class:`~pmsm2dof.analysis.sensor.SensorChain`: encoder estimator,
filters, delay) the controller reads the measured speed of
:func:`~pmsm2dof.analysis.sensor.sampled_plant_blocks`, the plant sampled exactly at fractions of
a period; the loop is assembled in z by python-control (``interconnect``), its poles are the
eigenvalues of the closed loop and its margins are found on the frequency response of
``F(z)`` times the plant-to-reading chain on the unit circle
(:func:`~pmsm2dof.analysis.margins.frequency_margins`). This is meant for sensor chains of
practical drives; the w-plane forms above, which keep a loop with ``alpha Ts`` of 1e-6 exact,
serve the ideal sensor.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..core import METHODS, SpeedController
from ..core.bindings import AntiWindup, Feedforward, Method
from ..core.gains import default_Ka_error
from ..errors import ConfigError, Pmsm2dofWarning, require_choice, require_positive
from ..lazy import lazy_module
from .margins import Margins, frequency_margins, pick_margins, polynomial_crossings
from .sensor import delay_periods, sampled_plant_blocks
from .stepresponse import StepResponse

if TYPE_CHECKING:
    import control
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

if TYPE_CHECKING:
    from .design import Design

#: Motor data given to the C controller whose coefficients a discretization reads: the PI and
#: feedforward coefficients do not depend on them (they fill the torque-to-current part only).
NEUTRAL_MOTOR: dict[str, Any] = {"i_max_A": 1.0, "psi_f_Wb": 1.0, "Ld_H": 1.0, "Lq_H": 1.0, "pole_pairs": 1}
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


def _sample(tf_s: control.TransferFunction, Ts_s: float, method: str) -> control.TransferFunction:
    """``control.sample_system(tf_s, Ts_s, method)`` computed on unit-scaled coefficients (the ZOH plant).

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


def c_coefficients(
    design: Design,
    Ts_s: float,
    method: Method,
    feedforward: Feedforward | None = None,
    anti_windup: AntiWindup | None = None,
) -> dict[str, float | bool]:
    """The coefficients ``p2d_speed_init`` computes for ``design`` at ``Ts_s`` with ``method``.

    ``feedforward`` and ``anti_windup`` default to the design's. The C controller validates the
    configuration: a feedforward pole on or outside the unit circle, ``Ki Ka Ts >= 2`` with back
    calculation or a float32 overflow raise its ConfigError (naming ``Ts_s``, ``Ka``, ...).

    Returns
    -------
    dict
        :attr:`pmsm2dof.core.SpeedController.coefficients` (float32 values).
    """
    d = design
    try:
        ctl = SpeedController(
            J_kgm2=d.J_kgm2,
            alpha_radps=d.alpha_radps,
            zeta=d.zeta,
            m=d.m,
            tau_i_s=d.tau_i_s,
            Ka=d.Ka,
            Ts_s=Ts_s,
            method=method,
            feedforward=feedforward or d.feedforward,
            anti_windup=anti_windup or d.anti_windup,
            **NEUTRAL_MOTOR,
        )
    except ConfigError as exc:
        if exc.param == "Ka" and d.Ka_default and d.alpha_radps * Ts_s / (4.0 * d.zeta**2) >= 2.0 * (1.0 - 1e-6):
            # the default 1/Kp made Ki Ka Ts >= 2: name what the caller set
            names = {name: name for name in ("alpha_radps", "zeta", "Ts_s", "Ka")}
            raise default_Ka_error(d.J_kgm2, d.alpha_radps, d.zeta, Ts_s, names) from None
        raise
    return ctl.coefficients


def _pi_z(b_e0: float, Ki_Ts: float, Ts_s: float) -> control.TransferFunction:
    """The realized PI ``(b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1)`` (eq 14 for Tustin)."""
    return control.tf([b_e0, Ki_Ts - b_e0], [1.0, -1.0], Ts_s)


def _feedforward_z(
    ff_Fr0: float, ff_b_dr: float, ff_a1: float, ff_Kd_per_Ts: float, Ts_s: float
) -> control.TransferFunction:
    """The realized feedforward ``ff_Fr0 + ff_b_dr (1 - z^-1)/(1 + ff_a1 z^-1) + ff_Kd_per_Ts (1 - z^-1)``."""
    static = control.tf([ff_Fr0], [1.0], Ts_s)
    transient = control.tf([ff_b_dr, -ff_b_dr], [1.0, ff_a1], Ts_s)
    derivative = control.tf([ff_Kd_per_Ts, -ff_Kd_per_Ts], [1.0, 0.0], Ts_s)
    return static + transient + derivative if ff_Kd_per_Ts != 0.0 else static + transient


def plant_w(J_kgm2: float, tau_i_s: float, Ts_s: float) -> tuple[_Vector, _Vector]:
    """The ZOH plant in the w plane, ``z = (1 + w Ts/2) / (1 - w Ts/2)``: (numerator, denominator).

    The ZOH equivalent of ``1 / (J s (tau s + 1))`` is (step invariance)
    ``G(z) = (n1 z + n0) / (J (z - 1)(z - a))``, ``a = exp(-Ts/tau)``, ``n1 = Ts - tau (1 - a)``,
    ``n0 = tau (1 - a) - a Ts``. With ``z - 1 = w Ts / (1 - w Ts/2)`` and
    ``z - a = ((1 - a) + w Ts (1 + a)/2) / (1 - w Ts/2)`` it becomes::

        G(w) = (1 - w Ts/2)(1 + kappa w) / (J w (1 + rho w)),
        rho = (Ts/2) coth(Ts / (2 tau)),  kappa = rho - tau

    and ``(1 - w Ts/2) / (J w)`` for tau = 0 (the limit, ``rho = kappa = Ts/2``).
    ``kappa = tau ((x/2) coth(x/2) - 1)``, ``x = Ts/tau``, is taken from its series
    ``tau x^2 / 12 (1 - x^2/60)`` for x < 1e-3, where the difference would round away.
    """
    hold = np.array([-0.5 * Ts_s, 1.0])
    if tau_i_s == 0.0:
        return hold, np.array([J_kgm2, 0.0])
    x = Ts_s / tau_i_s
    rho = 0.5 * Ts_s / math.tanh(0.5 * x)
    kappa = tau_i_s * x * x / 12.0 * (1.0 - x * x / 60.0) if x < 1e-3 else rho - tau_i_s
    return np.polymul(hold, [kappa, 1.0]), J_kgm2 * np.array([rho, 1.0, 0.0])


def _loop_w(design: Design, Ts_s: float, b_e0: float, Ki_Ts: float) -> tuple[_Poly, _Poly]:
    """Numerator and denominator of the loop gain ``L(w) = F(w) G(w)``.

    The realized PI is exactly ``F(w) = Kp' + Ki / w``, ``Kp' = b_e0 - Ki Ts / 2``:
    ``Ki Ts / (z - 1) = Ki Ts (1 - w Ts/2) / (w Ts) = Ki / w - Ki Ts / 2``. (Products by
    convolution: every factor's leading coefficient is nonzero, so that numpy.polymul would
    trim nothing.)
    """
    G_num, G_den = plant_w(design.J_kgm2, design.tau_i_s, Ts_s)
    return np.convolve([b_e0 - 0.5 * Ki_Ts, Ki_Ts / Ts_s], G_num), np.convolve([1.0, 0.0], G_den)


def _hurwitz(char: _Poly) -> bool:
    """True when every root of the polynomial ``char`` (degree 2 or 3) has ``Re w < 0`` (Routh-Hurwitz)."""
    if not np.all(char > 0.0):
        return False
    return len(char) == 3 or bool(char[1] * char[2] > char[0] * char[3])


def _stable(design: Design, Ts_s: float, method: Method) -> bool:
    """Whether the discrete feedback loop is stable at ``Ts_s`` (Routh-Hurwitz in the w plane)."""
    pi = c_coefficients(design, Ts_s, method, feedforward="none", anti_windup="none")
    L_num, L_den = _loop_w(design, Ts_s, pi["b_e0"], pi["Ki_Ts"])
    return _hurwitz(np.polyadd(L_den, L_num))


def _unstable_loop_error(design: Design, Ts_s: float, method: Method, z_max: float) -> ConfigError:
    """The ConfigError of a discrete loop that is unstable at ``Ts_s``, naming the range that is stable."""
    d = design
    if not d.Kp > d.tau_i_s * d.Ki:
        # Routh on J tau s^3 + J s^2 + Kp s + Ki: no sampling period helps
        return ConfigError(
            "alpha_radps",
            d.alpha_radps,
            f"< 4 zeta^2 / tau_i_s = {4.0 * d.zeta**2 / d.tau_i_s:.6g} rad/s with zeta = {d.zeta:g} and tau_i_s = "
            f"{d.tau_i_s:g} s: beyond it the continuous loop J tau_i s^3 + J s^2 + Kp s + Ki is unstable (Routh: "
            "Kp > tau_i Ki), at any Ts_s",
        )
    # the largest period below which every period of a fine log grid is stable, then bisection
    grid = Ts_s * np.logspace(-9.0, 0.0, 181)
    stable = [_stable(d, Ts, method) for Ts in grid]
    first_bad = stable.index(False)
    if first_bad == 0:
        return ConfigError(
            "Ts_s",
            Ts_s,
            f"a period that makes the discrete loop stable (none found from {grid[0]:.3g} s "
            f"to {Ts_s:g} s with {method} and a ZOH plant)",
        )
    lo, hi = grid[first_bad - 1], grid[first_bad]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _stable(d, mid, method) else (lo, mid)
    return ConfigError(
        "Ts_s",
        Ts_s,
        f"< {lo:.4g} s, where the discrete loop is stable ({method}, ZOH plant; at Ts_s = {Ts_s:g} s its "
        f"largest closed-loop pole has |z| = {z_max:.6g})",
    )


def _margins(design: Design, Ts_s: float, b_e0: float, Ki_Ts: float) -> Margins:
    """Margins of ``F(z) G(z)``, found on ``L(w)`` as for a continuous loop (same gain and phase) by the
    polynomial method of python-control (:func:`~pmsm2dof.analysis.margins.polynomial_crossings`).

    A frequency ``w_w`` of the w plane is ``w_z = (2/Ts) atan(w_w Ts / 2)``; the Nyquist
    frequency ``pi/Ts``, ``z = -1``, is ``w = infinity``, where ``L`` is the ratio of the
    leading coefficients (numerator and denominator have the same degree).
    """
    return _loop_margins(*_loop_w(design, Ts_s, b_e0, Ki_Ts), Ts_s)[0]


def _loop_margins(num: _Poly, den: _Poly, Ts_s: float, scales: Sequence[float] = (1.0,)) -> list[Margins]:
    """:func:`_margins` of the loop gains ``L(w) = num(w) / (c den(w))`` (:func:`_loop_w`), one per scale ``c``."""

    def to_z(w: npt.ArrayLike) -> _Vector:
        return 2.0 / Ts_s * np.arctan(0.5 * Ts_s * np.asarray(w, dtype=float))

    out = []
    for c, (gms, pms, w_pcs, w_gcs) in zip(scales, polynomial_crossings(num, den, scales)):
        L_nyquist = num[0] / (c * den[0])
        extra = [(1.0 / abs(L_nyquist), math.pi / Ts_s)] if L_nyquist < 0.0 else []
        out.append(pick_margins(gms, pms, to_z(w_pcs), to_z(w_gcs), extra))
    return out


def margins_on_plant(
    design: Design, Ts_s: float, method: Method, J_plant_kgm2: float, tau_i_plant_s: float
) -> Margins | None:
    """Margins of the C controller of ``design`` on a plant it was not designed for; None if unstable there.

    The PI is realized for ``design`` at ``Ts_s`` with ``method`` (:func:`c_coefficients`); the
    plant is the ZOH equivalent of ``1 / (J_plant s (tau_i_plant s + 1))`` (eq 2, 3;
    :func:`plant_w`), such as the true inertia of a drive known only to a range.

    Parameters
    ----------
    design : Design
        The continuous design the controller is configured with.
    Ts_s : float
        Sampling period [s], > 0.
    method : str
        One of :data:`METHODS`.
    J_plant_kgm2, tau_i_plant_s : float
        Inertia [kg m^2] and current-loop time constant [s] of the plant.

    Returns
    -------
    Margins or None
        The margins of ``F(z) G(z)``; None when the discrete feedback loop is unstable
        (Routh-Hurwitz in the w plane), where margins have no meaning.
    """
    return margins_on_plants(design, Ts_s, method, [J_plant_kgm2], tau_i_plant_s)[0]


def margins_on_plants(
    design: Design, Ts_s: float, method: Method, J_plants_kgm2: Sequence[float], tau_i_plant_s: float
) -> list[Margins | None]:
    """:func:`margins_on_plant` at each inertia of ``J_plants_kgm2``, computed together.

    The loop gain is inversely proportional to the plant's inertia: its -180 deg crossings are
    found once (:func:`~pmsm2dof.analysis.margins.polynomial_crossings`), and only the unit-gain
    crossings once per inertia.
    """
    pi = c_coefficients(design, Ts_s, method, feedforward="none", anti_windup="none")
    unit = replace(design, J_kgm2=1.0, tau_i_s=float(tau_i_plant_s))
    L_num, L_den = _loop_w(unit, Ts_s, pi["b_e0"], pi["Ki_Ts"])
    J = [float(J_plant) for J_plant in J_plants_kgm2]
    stable = [_hurwitz(np.polyadd(J_plant * L_den, L_num)) for J_plant in J]
    margins = _loop_margins(L_num, L_den, Ts_s, [J_plant for J_plant, ok in zip(J, stable) if ok])
    return [margins.pop(0) if ok else None for ok in stable]


def sampled_loop_poles(
    design: Design, Ts_s: float, method: Method, J_plant_kgm2: float, tau_i_plant_s: float
) -> tuple[tuple[complex, ...], bool]:
    """Poles of the sampled feedback loop of the C controller of ``design`` on a plant, and whether it is stable.

    The check :func:`discretize` makes before it accepts a design (the controller realized at
    ``Ts_s`` with ``method``, :func:`c_coefficients`; the ZOH plant of eq 2, 3,
    ``1 / (J_plant s (tau_i_plant s + 1))``; the design's sensor chain), here on any plant and
    without refusing: the plant of the design itself, or the scenario's true one. Stable is
    decided as :func:`discretize` decides it (Routh-Hurwitz in the w plane, exact near ``z = 1``;
    with a sensor chain, the eigenvalues of the closed loop inside the unit circle).

    Returns
    -------
    (tuple of complex, bool)
        The closed-loop poles in z, and whether every one lies inside the unit circle.
    """
    pi = c_coefficients(design, Ts_s, method, feedforward="none", anti_windup="none")
    plant = replace(design, J_kgm2=float(J_plant_kgm2), tau_i_s=float(tau_i_plant_s))
    if design.sensor.is_ideal:
        L_num, L_den = _loop_w(plant, Ts_s, pi["b_e0"], pi["Ki_Ts"])
        char_w = np.polyadd(L_den, L_num)
        poles_w = np.roots(char_w)
        poles = (1.0 + 0.5 * Ts_s * poles_w) / (1.0 - 0.5 * Ts_s * poles_w)
        return tuple(complex(p) for p in poles), _hurwitz(char_w)
    F_z = _pi_z(pi["b_e0"], pi["Ki_Ts"], Ts_s)
    _reading, closed = _closed_loop_with_sensor(plant, Ts_s, F_z, control.tf([0.0], [1.0], Ts_s))
    poles = np.linalg.eigvals(closed.A)
    return tuple(complex(p) for p in poles), bool(np.max(np.abs(poles)) < 1.0)


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
    F_z = _pi_z(b_e0, Ki_Ts, Ts_s)
    if d.feedforward == "none":
        Fr_z = control.tf([0.0], [1.0], Ts_s)
    else:
        Fr_z = _feedforward_z(c["ff_Fr0"], c["ff_b_dr"], c["ff_a1"], c["ff_Kd_per_Ts"], Ts_s)
    if not d.sensor.is_ideal:
        return _loop_with_sensor(d, Ts_s, method, c, F_z, Fr_z)

    # feedback loop in the w plane: 1 + F(w) G(w) = 0, stable when Re w < 0
    L_num, L_den = _loop_w(d, Ts_s, b_e0, Ki_Ts)
    char_w = np.polyadd(L_den, L_num)
    poles_w = np.roots(char_w)
    poles = (1.0 + 0.5 * Ts_s * poles_w) / (1.0 - 0.5 * Ts_s * poles_w)
    if not _hurwitz(char_w):
        raise _unstable_loop_error(d, Ts_s, method, float(np.max(np.abs(poles))))
    E, f, out = _tracking_increments(d, Ts_s, **{k: v for k, v in c.items() if k != "Ki_Ka_Ts"})
    overshoot, reason = StepResponse(E, f, out, dt_s=Ts_s).overshoot_pct()
    margins = _margins(d, Ts_s, b_e0, Ki_Ts)
    G_z = _sample(d.G, Ts_s, "zoh")  # the plant held over each period, not the controller
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


def _closed_loop_with_sensor(
    design: Design, Ts_s: float, F_z: control.TransferFunction, Fr_z: control.TransferFunction
) -> tuple[list[Any], control.StateSpace]:
    """The sampled plant-to-reading blocks of ``design`` (its J, tau_i and sensor chain) and the closed
    loop from ``r`` to ``w`` with the PI ``F_z`` and the feedforward ``Fr_z``."""
    plant = sampled_plant_blocks(design.J_kgm2, design.tau_i_s, Ts_s, design.sensor)
    blocks = plant + [
        control.ss(F_z, inputs="e", outputs="u_fb"),
        control.ss(Fr_z, inputs="r", outputs="u_ff"),
        control.summing_junction(["u_fb", "u_ff"], "u"),
        control.summing_junction(["r", "-y"], "e"),
    ]
    return plant, control.interconnect(blocks, inplist=["r"], outlist=["w"], dt=Ts_s)


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
    plant, closed = _closed_loop_with_sensor(d, Ts_s, F_z, Fr_z)
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
    G_z = _sample(d.G, Ts_s, "zoh")
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
