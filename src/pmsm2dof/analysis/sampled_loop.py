"""The sampled speed loop: the C controller's coefficients, and the loop's stability and margins.

:func:`c_coefficients` reads the coefficients ``p2d_speed_init`` computes (float32, the code that
runs on the MCU) from a :class:`~pmsm2dof.core.SpeedController` configured with a design; the
realized PI and feedforward as transfer functions in z (:func:`pi_z`, :func:`feedforward_z`); the
ZOH plant of eq 2, 3 (:func:`plant_w`, :func:`sample_system`). :func:`margins_on_plants` and
:func:`sampled_loop_poles` analyse the loop on any plant (a design's own, or a drive's true one);
:func:`pmsm2dof.analysis.discretize.discretize` uses the same functions before it accepts a design.

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
  frequency maps back as ``w_z = (2/Ts) atan(w_w Ts/2)``).

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
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..core import SpeedController
from ..core.bindings import AntiWindup, Feedforward, Method
from ..core.gains import default_Ka_error
from ..errors import ConfigError
from ..lazy import lazy_module
from .margins import Margins, pick_margins, polynomial_crossings
from .sensor import sampled_plant_blocks

if TYPE_CHECKING:
    import control

    from .design import Design
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

#: Motor data given to the C controller whose coefficients a discretization reads: the PI and
#: feedforward coefficients do not depend on them (they fill the torque-to-current part only).
NEUTRAL_MOTOR: dict[str, Any] = {"i_max_A": 1.0, "psi_f_Wb": 1.0, "Ld_H": 1.0, "Lq_H": 1.0, "pole_pairs": 1}

_Vector = npt.NDArray[np.float64]
#: Coefficients of a polynomial, highest power first (what numpy.polymul returns).
_Poly = npt.NDArray[np.floating[Any]]


def sample_system(tf_s: control.TransferFunction, Ts_s: float, method: str) -> control.TransferFunction:
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


def pi_z(b_e0: float, Ki_Ts: float, Ts_s: float) -> control.TransferFunction:
    """The realized PI ``(b_e0 + (Ki Ts - b_e0) z^-1) / (1 - z^-1)`` (eq 14 for Tustin)."""
    return control.tf([b_e0, Ki_Ts - b_e0], [1.0, -1.0], Ts_s)


def feedforward_z(
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


def loop_w(design: Design, Ts_s: float, b_e0: float, Ki_Ts: float) -> tuple[_Poly, _Poly]:
    """Numerator and denominator of the loop gain ``L(w) = F(w) G(w)``.

    The realized PI is exactly ``F(w) = Kp' + Ki / w``, ``Kp' = b_e0 - Ki Ts / 2``:
    ``Ki Ts / (z - 1) = Ki Ts (1 - w Ts/2) / (w Ts) = Ki / w - Ki Ts / 2``. (Products by
    convolution: every factor's leading coefficient is nonzero, so that numpy.polymul would
    trim nothing.)
    """
    G_num, G_den = plant_w(design.J_kgm2, design.tau_i_s, Ts_s)
    return np.convolve([b_e0 - 0.5 * Ki_Ts, Ki_Ts / Ts_s], G_num), np.convolve([1.0, 0.0], G_den)


def hurwitz(char: _Poly) -> bool:
    """True when every root of the polynomial ``char`` (degree 2 or 3) has ``Re w < 0`` (Routh-Hurwitz)."""
    if not np.all(char > 0.0):
        return False
    return len(char) == 3 or bool(char[1] * char[2] > char[0] * char[3])


def loop_stable(design: Design, Ts_s: float, method: Method) -> bool:
    """Whether the discrete feedback loop is stable at ``Ts_s`` (Routh-Hurwitz in the w plane)."""
    pi = c_coefficients(design, Ts_s, method, feedforward="none", anti_windup="none")
    L_num, L_den = loop_w(design, Ts_s, pi["b_e0"], pi["Ki_Ts"])
    return hurwitz(np.polyadd(L_den, L_num))


def unstable_loop_error(design: Design, Ts_s: float, method: Method, z_max: float) -> ConfigError:
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
    stable = [loop_stable(d, Ts, method) for Ts in grid]
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
        lo, hi = (mid, hi) if loop_stable(d, mid, method) else (lo, mid)
    return ConfigError(
        "Ts_s",
        Ts_s,
        f"< {lo:.4g} s, where the discrete loop is stable ({method}, ZOH plant; at Ts_s = {Ts_s:g} s its "
        f"largest closed-loop pole has |z| = {z_max:.6g})",
    )


def margins_w(design: Design, Ts_s: float, b_e0: float, Ki_Ts: float) -> Margins:
    """Margins of ``F(z) G(z)``, found on ``L(w)`` as for a continuous loop (same gain and phase) by the
    polynomial method of python-control (:func:`~pmsm2dof.analysis.margins.polynomial_crossings`).

    A frequency ``w_w`` of the w plane is ``w_z = (2/Ts) atan(w_w Ts / 2)``; the Nyquist
    frequency ``pi/Ts``, ``z = -1``, is ``w = infinity``, where ``L`` is the ratio of the
    leading coefficients (numerator and denominator have the same degree).
    """
    return margins_w_scaled(*loop_w(design, Ts_s, b_e0, Ki_Ts), Ts_s)[0]


def margins_w_scaled(num: _Poly, den: _Poly, Ts_s: float, scales: Sequence[float] = (1.0,)) -> list[Margins]:
    """:func:`margins_w` of the loop gains ``L(w) = num(w) / (c den(w))`` (:func:`loop_w`), one per scale ``c``."""

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
    L_num, L_den = loop_w(unit, Ts_s, pi["b_e0"], pi["Ki_Ts"])
    J = [float(J_plant) for J_plant in J_plants_kgm2]
    stable = [hurwitz(np.polyadd(J_plant * L_den, L_num)) for J_plant in J]
    margins = margins_w_scaled(L_num, L_den, Ts_s, [J_plant for J_plant, ok in zip(J, stable) if ok])
    return [margins.pop(0) if ok else None for ok in stable]


def sampled_loop_poles(
    design: Design, Ts_s: float, method: Method, J_plant_kgm2: float, tau_i_plant_s: float
) -> tuple[tuple[complex, ...], bool]:
    """Poles of the sampled feedback loop of the C controller of ``design`` on a plant, and whether it is stable.

    The check :func:`~pmsm2dof.analysis.discretize.discretize` makes before it accepts a design
    (the controller realized at ``Ts_s`` with ``method``, :func:`c_coefficients`; the ZOH plant of
    eq 2, 3, ``1 / (J_plant s (tau_i_plant s + 1))``; the design's sensor chain), here on any plant
    and without refusing: the plant of the design itself, or the scenario's true one. Stable is
    decided as ``discretize`` decides it (Routh-Hurwitz in the w plane, exact near ``z = 1``; with
    a sensor chain, the eigenvalues of the closed loop inside the unit circle).

    Returns
    -------
    (tuple of complex, bool)
        The closed-loop poles in z, and whether every one lies inside the unit circle.
    """
    pi = c_coefficients(design, Ts_s, method, feedforward="none", anti_windup="none")
    plant = replace(design, J_kgm2=float(J_plant_kgm2), tau_i_s=float(tau_i_plant_s))
    if design.sensor.is_ideal:
        L_num, L_den = loop_w(plant, Ts_s, pi["b_e0"], pi["Ki_Ts"])
        char_w = np.polyadd(L_den, L_num)
        poles_w = np.roots(char_w)
        poles = (1.0 + 0.5 * Ts_s * poles_w) / (1.0 - 0.5 * Ts_s * poles_w)
        return tuple(complex(p) for p in poles), hurwitz(char_w)
    F_z = pi_z(pi["b_e0"], pi["Ki_Ts"], Ts_s)
    _reading, closed = closed_loop_with_sensor(plant, Ts_s, F_z, control.tf([0.0], [1.0], Ts_s))
    poles = np.linalg.eigvals(closed.A)
    return tuple(complex(p) for p in poles), bool(np.max(np.abs(poles)) < 1.0)


def closed_loop_with_sensor(
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
