"""Analytical design of the 2DOF PI speed controller (paper section 3).

The plant seen by the speed controller is the current loop in series with the
mechanics (eq 2, 3)::

    G(s) = Gci(s) Gm(s),  Gci = 1 / (tau_i s + 1),  Gm = 1 / (J s)

The PI feedback ``F(s) = Kp + Ki/s`` is tuned by eq (9)::

    Kp = J alpha,  Ki = J (alpha / (2 zeta))^2

so that the loop ``J s^2 + Kp s + Ki`` (tau_i = 0) has natural frequency
``alpha / (2 zeta)`` and damping ``zeta``. The reference feedforward ``Fr(s)``
(eq 7, 10, 11) makes the tracking response first order,
``Gx = m alpha / (s + m alpha)``, while the load rejection ``GN`` (eq 5, 8)
stays that of the PI alone.

The speed the controller reads passes through a sensor chain ``H(s)`` (estimator, filter,
delay; :mod:`pmsm2dof.analysis.sensor`), which closes the loop as ``1 + F G H``: the loop gain
is ``L = F G H``, the tracking ``Gx = (Fr + F) G / (1 + F G H)`` and the load rejection
``GN = -Gm / (1 + F Gci Gm H)``. With the default ideal sensor ``H = 1``, the paper's loop.

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for
Permanent-Magnet Synchronous Motor Speed Controller"; eq (9) follows the
analytical PI design of its reference [4].
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..core import ANTI_WINDUPS, FEEDFORWARDS, pi_gains
from ..core.bindings import AntiWindup, Feedforward, Method
from ..errors import (
    FLOAT32_MAX,
    FLOAT32_MIN,
    ConfigError,
    require_choice,
    require_float32,
    require_nonnegative,
    require_positive,
)
from ..lazy import lazy_module
from .discretize import DiscreteDesign, discretize
from .margins import Margins, frequency_margins, loop_margins
from .sensor import DELAY_MODELS, DelayModel, SensorChain
from .stepresponse import StepResponse

if TYPE_CHECKING:
    import control
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

#: The -3 dB (half-power) gain drop that defines the bandwidth [dB].
HALF_POWER_DB = 20.0 * math.log10(1.0 / math.sqrt(2.0))


def tracking_tf(
    F: control.TransferFunction, Fr: control.TransferFunction, G: control.TransferFunction
) -> control.TransferFunction:
    """Reference-to-output transfer function of the 2DOF loop (eq 6), multiplied through.

    With ``F = Fn/Fd``, ``Fr = Rn/Rd``, ``G = Gn/Gd``::

        Gx = (Fr + F) G / (1 + F G) = (Rn Fd + Fn Rd) Gn / (Rd (Fd Gd + Fn Gn))

    Forming it from the polynomials keeps the integrator of ``F`` from appearing in both
    numerator and denominator.
    """
    Fn, Fd = F.num[0][0], F.den[0][0]
    Rn, Rd = Fr.num[0][0], Fr.den[0][0]
    Gn, Gd = G.num[0][0], G.den[0][0]
    num = np.polymul(np.polyadd(np.polymul(Rn, Fd), np.polymul(Fn, Rd)), Gn)
    den = np.polymul(Rd, np.polyadd(np.polymul(Fd, Gd), np.polymul(Fn, Gn)))
    return control.tf(num, den, F.dt)


@functools.lru_cache(maxsize=64)
def _overshoot(design: Design) -> tuple[float, str]:
    return design.tracking_step().overshoot_pct()


@dataclass(frozen=True)
class Design:
    """A designed speed controller: inputs, gains (eq 9) and transfer functions.

    Create it with :func:`design`. Transfer functions are python-control
    ``TransferFunction`` objects built afresh on every access, so the design
    itself never changes.

    Attributes
    ----------
    J_kgm2 : float
        Design inertia [kg m^2].
    alpha_radps : float
        Bandwidth of the P loop [rad/s] (eq 9).
    zeta : float
        Relative damping of the PI loop [-] (eq 9).
    m : float
        Tracking pole factor: ``Gx = m alpha / (s + m alpha)`` (eq 10) [-].
    tau_i_s : float
        Current-loop time constant [s] (eq 3), 0 for an ideal current loop.
    feedforward : str
        One of :data:`FEEDFORWARDS`.
    anti_windup : str
        One of :data:`ANTI_WINDUPS`.
    Ka : float
        Back-calculation gain [(rad/s)/Nm] (Fig. 5).
    Kp : float
        Proportional gain ``J alpha`` [Nm/(rad/s)] (eq 9).
    Ki : float
        Integral gain ``J (alpha / (2 zeta))^2`` [Nm/rad] (eq 9).
    sensor : SensorChain
        The speed measurement in the loop (ideal by default).
    Ka_default : bool
        ``Ka`` is the default ``1 / Kp`` (not given): an error it causes names the input it came from.
    """

    J_kgm2: float
    alpha_radps: float
    zeta: float
    m: float
    tau_i_s: float
    feedforward: Feedforward
    anti_windup: AntiWindup
    Ka: float
    Kp: float
    Ki: float
    sensor: SensorChain = SensorChain()
    Ka_default: bool = False

    @property
    def F(self) -> control.TransferFunction:
        """PI feedback ``F(s) = Kp + Ki / s = (Kp s + Ki) / s``."""
        return control.tf([self.Kp, self.Ki], [1.0, 0.0])

    @property
    def Gci(self) -> control.TransferFunction:
        """Closed current loop ``1 / (tau_i s + 1)`` (eq 3)."""
        return control.tf([1.0], [self.tau_i_s, 1.0])

    @property
    def Gm(self) -> control.TransferFunction:
        """Mechanics ``1 / (J s)`` from torque [Nm] to speed [rad/s] (eq 2)."""
        return control.tf([1.0], [self.J_kgm2, 0.0])

    @property
    def G(self) -> control.TransferFunction:
        """Plant seen by the speed controller, ``Gci Gm`` (eq 2, 3)."""
        return self.Gci * self.Gm

    def fr_polynomials(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Numerator and denominator of ``Fr(s)`` in powers of s, highest first.

        eq (11): ``Fr = J alpha (m tau s^2 + (m - 1) s - alpha / (4 zeta^2)) / (s + m alpha)``,
        with ``tau = 0`` for ``no_tau``, ``m = 1, tau = 0`` for ``lowpass`` (eq 13),
        and ``Fr = 0`` for ``none``. The numerator always has three coefficients.
        """
        if self.feedforward == "none":
            return np.zeros(3), np.array([1.0])
        m = 1.0 if self.feedforward == "lowpass" else self.m
        tau_s = self.tau_i_s if self.feedforward == "full" else 0.0
        num = self.Kp * np.array([m * tau_s, m - 1.0, -self.alpha_radps / (4.0 * self.zeta**2)])
        return num, np.array([1.0, m * self.alpha_radps])

    @property
    def Fr(self) -> control.TransferFunction:
        """Reference feedforward ``Fr(s)`` (eq 11, 12, 13; 0 for the 1DOF PI).

        Improper for ``full`` with ``tau_i > 0`` (a derivative term).
        """
        num, den = self.fr_polynomials()
        return control.tf(num, den)

    @property
    def H(self) -> control.TransferFunction:
        """Sensor chain ``H(s)`` from the true to the measured speed, its delay as a Pade approximant."""
        return self.sensor.H()

    @property
    def L(self) -> control.TransferFunction:
        """Loop gain ``F G H`` (``F G`` with the ideal sensor), the delay as a Pade approximant."""
        if self.sensor.is_ideal:
            return self.F * self.G
        return self.F * self.G * self.H

    @property
    def Gx(self) -> control.TransferFunction:
        """Reference tracking ``(Fr + F) G / (1 + F G)`` (eq 6), pole-zero cancelled."""
        return self.on_plant(self.J_kgm2)[0]

    @property
    def GN(self) -> control.TransferFunction:
        """Load rejection, from load torque [Nm] to speed [rad/s] (eq 5, 8).

        The load acts on the mechanics, between ``Gci`` and ``Gm`` (Fig. 6), so eq (5)
        reads ``-Gm / (1 + F Gci Gm)``, which is eq (8):
        ``-(tau_i s^2 + s) / (J tau_i s^3 + J s^2 + Kp s + Ki)``. It does not
        depend on ``Fr``: 1DOF and 2DOF reject loads identically.
        """
        return self.on_plant(self.J_kgm2)[1]

    def on_plant(self, J_plant_kgm2: float) -> tuple[control.TransferFunction, control.TransferFunction]:
        """``(Gx, GN)`` of this controller on a plant of inertia ``J_plant_kgm2`` [kg m^2].

        The controller (``F``, ``Fr``) stays designed for :attr:`J_kgm2`; the plant is
        ``Gm = 1 / (J_plant s)``, ``G = Gci Gm`` (eq 2, 3). ``Gx = (Fr + F) G / (1 + F G)`` (eq 6,
        by :func:`tracking_tf`, pole-zero cancelled) and ``GN = -Gm / (1 + F Gci Gm)`` (eq 5
        with the load at the mechanics, eq 8). With ``J_plant_kgm2 == J_kgm2`` these are
        :attr:`Gx` and :attr:`GN`. With a sensor chain the feedback reads ``H`` times the speed:
        ``Gx = (Fr + F) G / (1 + F G H)``, ``GN = -Gm / (1 + F Gci Gm H)``.

        Raises
        ------
        ConfigError
            ``J_plant_kgm2`` not a normal float32 number > 0 (as the design's inertia).
        """
        J_plant_kgm2 = require_float32("J_plant_kgm2", J_plant_kgm2)
        Gm = control.tf([1.0], [J_plant_kgm2, 0.0])
        if self.sensor.is_ideal:
            return tracking_tf(self.F, self.Fr, self.Gci * Gm).minreal(), -control.feedback(Gm, self.F * self.Gci)
        G = self.Gci * Gm
        Gx = ((self.Fr + self.F) * control.feedback(G, self.F * self.H)).minreal()
        return Gx, -control.feedback(Gm, self.F * self.Gci * self.H)

    def closed_loop_poles(self) -> npt.NDArray[np.complex128]:
        """Poles of the feedback loop, roots of ``J tau_i s^3 + J s^2 + Kp s + Ki``.

        The feedforward adds its own pole ``-m alpha`` on the reference path only.
        """
        poles: npt.NDArray[np.complex128] = control.poles(control.feedback(self.L, 1))
        return poles

    def bandwidth_radps(self) -> float:
        """Tracking bandwidth [rad/s]: where ``|Gx|`` first falls 3 dB (half power) below DC."""
        return float(control.bandwidth(self.Gx, dbdrop=HALF_POWER_DB))

    def margins(self, delay: DelayModel = "exact") -> Margins:
        """Gain and phase margins of the loop gain ``F G H``.

        ``delay``: ``"exact"`` evaluates the sensor's delay as ``exp(-j w T)`` in the frequency
        response (:func:`~pmsm2dof.analysis.margins.frequency_margins`); ``"pade"`` uses its Pade
        approximant (:data:`~pmsm2dof.analysis.sensor.PADE_ORDER`), as :attr:`L` does.
        """
        require_choice("delay", delay, DELAY_MODELS)
        if self.sensor.delay_s == 0.0 or delay == "pade":
            return loop_margins(self.L)
        F, G = self.F, self.G

        def L_of_w(w: npt.NDArray[np.float64]) -> npt.NDArray[np.complex128]:
            s = 1j * w
            return np.asarray(
                np.polyval(F.num[0][0], s) / np.polyval(F.den[0][0], s)
                * np.polyval(G.num[0][0], s) / np.polyval(G.den[0][0], s)
                * self.sensor.frequency_response(w)
            )  # fmt: skip

        w_scale = self._frequencies()
        return frequency_margins(L_of_w, 1e-3 * min(w_scale), 1e3 * max(w_scale))

    def phase_margin_deg(self, delay: DelayModel = "exact") -> float:
        """The phase margin [deg] of ``F G H`` alone, faster than :meth:`margins` with an exact delay.

        A delay leaves ``|L|`` as it is: at each gain crossover ``w_c`` of the rational part it
        takes ``w_c T`` of phase, so the margin is the smallest ``PM_i - w_c,i T`` over them.
        """
        require_choice("delay", delay, DELAY_MODELS)
        if self.sensor.delay_s == 0.0 or delay == "pade":
            return self.margins(delay).phase_margin_deg
        rational = self.F * self.G * self.sensor.H(pade_order=0)
        _gms, pms, _sms, _w_pcs, w_gcs, _w_sms = control.stability_margins(rational, returnall=True)
        if not len(pms):
            return math.inf
        return float(min(pm - math.degrees(w * self.sensor.delay_s) for pm, w in zip(pms, w_gcs)))

    def _frequencies(self) -> list[float]:
        """The characteristic frequencies of the loop [rad/s]: design, current loop, sensor."""
        w = [self.alpha_radps, self.alpha_radps / (2.0 * self.zeta)]
        w += [1.0 / self.tau_i_s] if self.tau_i_s > 0.0 else []
        w += [self.sensor.bandwidth_radps] if self.sensor.pll else []
        w += [self.sensor.lowpass_radps] if self.sensor.lowpass_radps > 0.0 else []
        w += [1.0 / self.sensor.delay_s] if self.sensor.delay_s > 0.0 else []
        return w

    def max_alpha_for_phase_margin(self, phase_margin_deg: float, delay: DelayModel = "exact") -> float:
        """The largest ``alpha`` [rad/s] whose loop keeps ``phase_margin_deg`` with this sensor chain.

        With ``zeta``, ``tau_i`` and the sensor kept, the phase margin of ``F G H`` depends on
        ``alpha`` alone (not on J: ``F`` scales with J, ``G`` with 1/J). Without lag in the loop
        it is the margin of ``zeta`` at every alpha; each lag (current loop, filter, PLL, delay)
        takes phase at the crossover, more as alpha grows. The largest alpha is found by
        bisection on ``log alpha``.

        Raises
        ------
        ConfigError
            ``phase_margin_deg`` out of (0, 180), or above what ``zeta`` allows at any alpha
            (the margin of the lag-free loop).
        """
        target = require_positive("phase_margin_deg", phase_margin_deg)
        if not target < 180.0:
            raise ConfigError("phase_margin_deg", phase_margin_deg, "finite, > 0 and < 180")

        def pm(alpha: float) -> float:
            d = design(self.J_kgm2, alpha, self.zeta, tau_i_s=self.tau_i_s, feedforward="none", sensor=self.sensor)
            return d.phase_margin_deg(delay)

        # the lag-free loop: the margin of zeta, the most any alpha can reach
        lag_free = design(self.J_kgm2, 1.0, self.zeta, feedforward="none").margins().phase_margin_deg
        if not target < lag_free:
            raise ConfigError(
                "phase_margin_deg",
                phase_margin_deg,
                f"< {lag_free:.4g} deg, the margin of the loop without lag at zeta = {self.zeta:g} (raise zeta)",
            )
        lo = 1e-6 * min(self._frequencies()[2:] or [self.alpha_radps])
        hi = 1e3 * max(self._frequencies())
        if pm(lo) < target:
            lo = hi  # the margin is reached nowhere below; keep shrinking
            while pm(lo) < target:
                lo *= 1e-3
        for _ in range(80):
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if pm(mid) >= target else (lo, mid)
            if hi / lo < 1.0 + 1e-9:
                break
        return lo

    def tracking_step(self) -> StepResponse:
        """The unit reference step of the loop (eq 6) as a :class:`~pmsm2dof.analysis.stepresponse.StepResponse`.

        With a sensor chain, :meth:`_tracking_step_with_sensor`.

        States: the torque ``T`` after the current loop (eq 3, absent when tau_i = 0), the
        momentum ``p = J w`` (eq 2), the PI integral ``q`` and the feedforward state ``v``,
        with ``Fr = Kd s + D + c / (s + m alpha)`` split by polynomial division::

            u = q + Kp (r - w) + D r + v + Kd dr/dt
            tau_i T' = u - T,  p' = T,  q' = Ki (r - w),  v' = -m alpha v + c r

        The derivative of the step reaches the current loop as an impulse: ``T(0+) = Kd / tau_i``.
        """
        if not self.sensor.is_ideal:
            return self._tracking_step_with_sensor()
        fr_num, fr_den = self.fr_polynomials()
        has_ff = self.feedforward != "none"
        (Kd, D), c = np.polydiv(fr_num, fr_den) if has_ff else ((0.0, 0.0), np.zeros(1))
        lag = self.tau_i_s > 0.0
        iT, ip = (0, 1) if lag else (None, 0)
        iq = ip + 1
        iv = iq + 1
        n = iv + 1 if has_ff else iv
        A, b, x0 = np.zeros((n, n)), np.zeros(n), np.zeros(n)
        # the row of u: q + Kp (r - p/J) + D r + v
        u_row, u_r = np.zeros(n), self.Kp + D
        u_row[iq], u_row[ip] = 1.0, -self.Kp / self.J_kgm2
        if has_ff:
            u_row[iv] = 1.0
            A[iv, iv], b[iv] = -fr_den[1], c[-1]
        if lag:
            A[iT], b[iT] = u_row / self.tau_i_s, u_r / self.tau_i_s
            A[iT, iT] -= 1.0 / self.tau_i_s
            A[ip, iT] = 1.0
            x0[iT] = Kd / self.tau_i_s
        else:
            A[ip], b[ip] = u_row, u_r
        A[iq, ip], b[iq] = -self.Ki / self.J_kgm2, self.Ki
        out = np.zeros(n)
        out[ip] = 1.0 / self.J_kgm2
        return StepResponse.continuous(A, b, out, x0)

    def _tracking_step_with_sensor(self) -> StepResponse:
        """The unit reference step of the loop that reads ``H`` times the speed (delay: Pade).

        The blocks (python-control ``interconnect``): ``u = F (r - y) + Fr' r + u_d``, the current
        loop, the mechanics and ``y = H w``, with ``Fr = Kd s + Fr'`` (``Fr'`` proper); the
        derivative of the step enters as the impulse ``Kd`` on ``u_d``, the initial state ``Kd b_d``.
        """
        fr_num, fr_den = self.fr_polynomials()
        (Kd, D), c = np.polydiv(fr_num, fr_den) if self.feedforward != "none" else ((0.0, 0.0), np.zeros(1))
        Fr_proper = control.tf([D, D * fr_den[-1] + c[-1]], fr_den) if self.feedforward != "none" else 0.0 * self.F
        blocks = [
            control.ss(self.F, inputs="e", outputs="u_fb"),
            control.ss(Fr_proper, inputs="r", outputs="u_ff"),
            control.summing_junction(["u_fb", "u_ff", "u_d"], "u"),
            control.ss(self.G, inputs="u", outputs="w"),
            control.ss(self.H, inputs="w", outputs="y"),
            control.summing_junction(["r", "-y"], "e"),
        ]
        loop = control.interconnect(blocks, inplist=["r", "u_d"], outlist=["w"])
        A, B, C = loop.A, loop.B, loop.C
        return StepResponse.continuous(A, B[:, 0], C[0], Kd * B[:, 1])

    def overshoot_pct(self) -> float:
        """Overshoot [%] of the linear unit-step tracking response (eq 6).

        NaN when it cannot be computed; :meth:`missing` says why.
        """
        return _overshoot(self)[0]

    def missing(self) -> dict[str, str]:
        """``{figure: reason}`` for each figure of the continuous design that is NaN or infinite."""
        _margins, missing = self.margins().values_and_reasons()
        reason = _overshoot(self)[1]
        return ({"overshoot_pct": reason} if reason else {}) | missing

    def discretize(self, Ts_s: float, method: Method) -> DiscreteDesign:
        """Discrete controller for sampling period ``Ts_s`` [s] (Table 1, eq 14, 15).

        See :func:`pmsm2dof.analysis.discretize.discretize`.
        """
        return discretize(self, Ts_s, method)


#: Shortest sensor delay, relative to the loop's shortest time constant: below about 1e-15
#: the Pade approximant's coefficients overflow when multiplied with the loop's.
DELAY_SHARE_MIN = 1e-9


def _require_float32_gain(gain: str, value: float, factors: dict[str, float]) -> None:
    """Raise ConfigError, naming the factor farthest from 1, if the gain ``value`` of eq 9 is not a
    normal float32 number (it overflowed, or came out 0 or subnormal)."""
    if FLOAT32_MIN <= value <= FLOAT32_MAX:
        return
    name = max(factors, key=lambda k: abs(math.log(factors[k])))
    raise ConfigError(
        name,
        factors[name],
        f"a value that makes {gain} (eq 9) a normal float32 number, {FLOAT32_MIN:.4g} to {FLOAT32_MAX:.4g} "
        f"(it is {value:.4g} with {', '.join(f'{k} = {v:.4g}' for k, v in factors.items())})",
    )


def design(
    J_kgm2: float,
    alpha_radps: float,
    zeta: float,
    m: float = 1.0,
    tau_i_s: float = 0.0,
    feedforward: Feedforward = "lowpass",
    anti_windup: AntiWindup = "back_calculation",
    Ka: float | None = None,
    sensor: SensorChain | None = None,
) -> Design:
    """Design the anti-windup 2DOF PI speed controller (paper section 3.3).

    Parameters
    ----------
    J_kgm2 : float
        Inertia [kg m^2], > 0.
    alpha_radps : float
        Bandwidth of the P loop [rad/s], > 0 (eq 9).
    zeta : float
        Relative damping of the PI loop [-], > 0 (eq 9).
    m : float, optional
        Tracking pole factor [-], > 0 (eq 10); exactly 1 with ``lowpass``, the default
        feedforward.
    tau_i_s : float, optional
        Current-loop time constant [s], >= 0 (eq 3).
    feedforward : {'lowpass', 'none', 'no_tau', 'full'}, optional
        ``lowpass`` (default): eq (13), discretized as eq (15), the paper's 2DOF controller of
        section 4, requires ``m == 1``; ``none``: 1DOF PI; ``no_tau``: eq (11) with
        ``tau_i = 0``; ``full``: eq (11). For ``m != 1`` choose ``no_tau`` or ``full``.
    anti_windup : {'none', 'back_calculation', 'clamping'}, optional
        Integrator anti-windup (section 3.2).
    Ka : float, optional
        Back-calculation gain [(rad/s)/Nm], >= 0; default ``1 / Kp`` (section 3.3).
    sensor : SensorChain, optional
        The speed measurement (estimator, filter, delay) in the loop; default the ideal sensor.

    Returns
    -------
    Design

    Raises
    ------
    ConfigError
        For any input out of range, naming the parameter, its value and the valid range. The
        numbers (``tau_i_s`` when not 0) and the gains ``Kp`` and ``Ki`` of eq 9 must be normal
        float32 numbers (:func:`~pmsm2dof.errors.require_float32`), the range of the C controller
        that runs the design: no gain comes out infinite, 0 or subnormal.
    """
    J_kgm2, alpha_radps, zeta, m = (
        require_float32(name, value)
        for name, value in (("J_kgm2", J_kgm2), ("alpha_radps", alpha_radps), ("zeta", zeta), ("m", m))
    )
    tau_i_s = require_float32("tau_i_s", tau_i_s, zero=True)
    require_choice("feedforward", feedforward, FEEDFORWARDS)
    require_choice("anti_windup", anti_windup, ANTI_WINDUPS)
    if feedforward == "lowpass" and m != 1.0:
        raise ConfigError(
            "m",
            m,
            "exactly 1 with feedforward 'lowpass' (eq 13, the default); for m != 1 choose "
            "feedforward 'no_tau' or 'full' (eq 11)",
        )
    Kp, Ki = pi_gains(J_kgm2, alpha_radps, zeta)  # eq 9
    _require_float32_gain("Kp = J alpha", Kp, {"J_kgm2": J_kgm2, "alpha_radps": alpha_radps})
    _require_float32_gain(
        "Ki = J (alpha / (2 zeta))^2", Ki, {"J_kgm2": J_kgm2, "alpha_radps": alpha_radps, "zeta": zeta}
    )
    Ka_default = Ka is None
    Ka = 1.0 / Kp if Ka is None else require_nonnegative("Ka", Ka)
    if sensor is None:
        sensor = SensorChain()
    elif not isinstance(sensor, SensorChain):
        raise ConfigError("sensor", sensor, "a SensorChain")
    w_fastest_radps = max(alpha_radps, alpha_radps / (2.0 * zeta), m * alpha_radps)
    if 0.0 < sensor.delay_s < DELAY_SHARE_MIN / w_fastest_radps:
        raise ConfigError(
            "delay_s",
            sensor.delay_s,
            f"0, or >= {DELAY_SHARE_MIN / w_fastest_radps:.3g} s: {DELAY_SHARE_MIN:g} of the loop's shortest time "
            "constant 1/max(alpha, alpha/(2 zeta), m alpha) (a shorter delay changes nothing in this loop, and its "
            "Pade approximant's coefficients overflow)",
        )
    return Design(J_kgm2, alpha_radps, zeta, m, tau_i_s, feedforward, anti_windup, Ka, Kp, Ki, sensor, Ka_default)
