"""Scaling check of the fixed-point speed controller: what Q15 or Q31 does to a design.

A design (eq 9-13) sampled at ``Ts_s`` runs in the fixed-point C controller
(csrc/include/pmsm2dof/speed_fixed.h, :class:`~pmsm2dof.core.fixedpoint.FixedPointSpeedController`)
with speeds and torques scaled to full scales ``W_fs`` and ``T_fs``. :func:`scaling_check` reads
the coefficients that controller quantised and reports, from the header's arithmetic rules:

- each coefficient's quantisation error (the mantissa-and-shift form the controller uses, and the
  plain Q15/Q31 number a series-form PI would store, which rounds a small ``Ki Ts`` to a few counts);
- the dead zone of the integrator: the speed errors ``e`` for which the increment
  ``R(Ki Ts e)``, rounded to the integrator's LSB, is 0. A load's steady-state error anywhere in
  it is never removed. Its edge is about ``T_fs 2^-(N+1) / (Ki Ts)`` in Q15 (the torque LSB over
  twice ``Ki Ts``), whatever ``W_fs``; Q31 keeps 31 more fractional bits and has none;
- the transient of the feedforward that rounding leaves stuck (the dead band of a rounded
  first-order section, ``|y| <= 1 / (2 (1 - |pole|))`` LSBs: a torque offset the integrator must
  take up);
- the amplitude of the limit cycles quantisation allows: the dead zone, plus the swing of the speed
  error while the output toggles between two adjacent torque LSBs (``max(speed LSB, torque LSB /
  b_e0)`` and the drift ``Ts T_LSB / J`` of one sample), against an amplitude the drive must meet;
  and, for comparison, the dead zone of the float32 controller at the torque limit, where an
  increment below half a float32 ulp of the integrator is lost (``ulp(T_max) / (2 Ki Ts)``);
- the headroom of every signal the controller holds within two full scales (speed_fixed.h): the
  largest magnitude it reaches after a reference step (the lowpass feedforward's ``Fr(0) = -Ki /
  alpha`` moves the integrator state by ``Fr(0)`` times the step, often many times the torque
  limit), in bits, and the torque full scale that would hold it;
- proposals that bring the dead zone within the amplitude (or below one speed LSB): a sampling
  period, a torque full scale, the Q31 format, each checked by the C controller and said feasible
  or not (the period within ``MAX_W_TS`` of the design, the full scale above the torque limit and
  the headroom).

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller"; the dead band of a rounded first-order recursion: L. B. Jackson, "An
analysis of limit cycles due to multiplication rounding in recursive digital (sub)filters",
Proc. 7th Allerton Conf., 1969.
"""

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..core.bindings import Method
from ..core.fixedpoint import FORMATS, FRACTIONAL_BITS, GAINS, INTEGRATOR_EXTRA_BITS, FixedPointSpeedController, Format
from ..errors import ConfigError, require_choice, require_positive
from .discretize import MAX_W_TS
from .scaling_report import (
    SIGNAL_LIMIT_PU,
    STATES,
    DeadZone,
    Headroom,
    Proposal,
    QuantisedGain,
    ScalingReport,
)

if TYPE_CHECKING:
    from .design import Design


def _controller(
    design: "Design", Ts_s: float, method: Method, fmt: Format, W_fs: float, T_fs: float, T_max: float
) -> FixedPointSpeedController:
    """The C controller of the design: a surface PMSM whose torque limit is ``T_max`` (i_max 1 A, one
    pole pair, so ``kt = T_max``); the current part does not enter the check. psi_f is the float32 number
    at or below ``T_max / 1.5``, so that the limit the controller computes never exceeds ``T_max`` (a
    torque full scale equal to it stays valid)."""
    psi_f = float(np.float32(T_max / 1.5))
    if 1.5 * psi_f > T_max:
        psi_f = float(np.nextafter(np.float32(psi_f), np.float32(0.0)))
    return FixedPointSpeedController(
        fmt,
        J_kgm2=design.J_kgm2,
        alpha_radps=design.alpha_radps,
        zeta=design.zeta,
        m=design.m,
        tau_i_s=design.tau_i_s,
        Ka=design.Ka,
        Ts_s=Ts_s,
        i_max_A=1.0,
        psi_f_Wb=psi_f,
        Ld_H=1.0,
        Lq_H=1.0,
        pole_pairs=1,
        method=method,
        feedforward=design.feedforward,
        anti_windup=design.anti_windup,
        speed_full_scale_radps=W_fs,
        torque_full_scale_Nm=T_fs,
        current_full_scale_A=1.0,
    )


def _dead_zone(ctl: FixedPointSpeedController, speed_lsb_radps: float) -> DeadZone:
    """The errors e (LSBs) with R(m e, s - F) = 0 (speed_fixed.h): -2^(s'-1) <= m e < 2^(s'-1), s' = s - F."""
    m, s = ctl.coefficients["Ki_Ts"]
    s_x = s - INTEGRATOR_EXTRA_BITS[ctl.fmt]
    if m == 0:
        return DeadZone(-math.inf, math.inf, speed_lsb_radps)
    if s_x <= 0:
        return DeadZone(0, 0, speed_lsb_radps)
    half = 2 ** (s_x - 1)
    # m > 0 (Ki Ts > 0): m e < half for e <= ceil(half / m) - 1, m e >= -half for e >= -floor(half / m)
    return DeadZone(-(half // m), -(-half // m) - 1, speed_lsb_radps)


def _stuck_transient(ctl: FixedPointSpeedController) -> int:
    """The largest |y| (LSBs) that the rounded feedforward section at rest, y <- y - R((1 + a1) y), does not shrink."""
    m, s = ctl.coefficients["ff_one_plus_a1"]
    if m == 0:
        return 0
    m, s = int(m), int(s)

    def moved(y: int) -> int:
        return y - ((m * y + (1 << (s - 1))) >> s)  # y - R(m y, s)

    pole = 1.0 - math.ldexp(m, -s)
    y = int(0.5 / (1.0 - abs(pole))) + 2
    while y > 0 and abs(moved(y)) < y and abs(moved(-y)) < y:
        y -= 1
    return y


def _headroom(
    gains: dict[str, float], T_max_pu: float, step_pu: float, anti_windup: str, T_fs: float
) -> tuple[Headroom, ...]:
    """The largest magnitudes [full scales] of the held signals after a reference step ``step_pu`` from rest
    at the torque limit (speeds within one full scale, errors within two)."""
    pole = 1.0 - gains["ff_one_plus_a1"]
    # y = b_dr (r[k] - (1 - p) sum p^(j-1) r[k-j]): one step for p >= 0; alternating references for p < 0
    # (no feedforward, b_dr = 0: y stays 0 though the section's pole, 1 + a1 = 0, is 1)
    if gains["ff_b_dr"] == 0.0:
        y = 0.0
    elif pole < 1.0:
        y = abs(gains["ff_b_dr"]) * step_pu * (1.0 + abs(1.0 - pole) / (1.0 - abs(pole))) / 2.0
    else:
        y = math.inf
    x = T_max_pu + abs(gains["ff_Fr0"]) * step_pu if anti_windup != "none" else math.inf
    T_ff = abs(gains["ff_Fr0"]) + y + abs(gains["ff_Kd_per_Ts"]) * step_pu
    u = 2.0 * abs(gains["b_e0"]) + x + abs(gains["ff_Fr0"]) * step_pu + abs(gains["ff_Kd_per_Ts"]) * step_pu + y
    rows = []
    for signal, bound in (("y_ff", y), ("x", x), ("T_ff", T_ff), ("u", u)):
        bits = math.log2(SIGNAL_LIMIT_PU / bound) if 0.0 < bound < math.inf else (math.inf if bound == 0 else -math.inf)
        rows.append(Headroom(signal, bound, bits, bound * T_fs / SIGNAL_LIMIT_PU))
    return tuple(rows)


def _ripple(ctl: FixedPointSpeedController, design: "Design", Ts_s: float) -> float:
    """The swing of the speed error [rad/s] while the output toggles between two adjacent torque LSBs:
    max(speed LSB, T LSB / b_e0), and the drift Ts T_LSB / J over the sample the toggle waits for."""
    W_fs, T_fs = float(ctl.config["speed_full_scale_radps"]), float(ctl.config["torque_full_scale_Nm"])
    speed_lsb, torque_lsb = math.ldexp(W_fs, -ctl.bits), math.ldexp(T_fs, -ctl.bits)
    b_e0_phys = ctl.gains["b_e0"] * T_fs / W_fs
    return max(speed_lsb, torque_lsb / b_e0_phys) + Ts_s * torque_lsb / design.J_kgm2


@dataclass(frozen=True)
class _Figures:
    """The dead zone and the limit-cycle amplitude [rad/s] of one candidate drive."""

    dead_zone_radps: float
    limit_cycle_radps: float


def _figures_with(
    design: "Design", Ts_s: float, method: Method, fmt: Format, W_fs: float, T_fs: float, T_max: float
) -> _Figures | None:
    """The figures of the C controller with these values, None if it refuses them."""
    try:
        ctl = _controller(design, Ts_s, method, fmt, W_fs, T_fs, T_max)
    except ConfigError:
        return None
    dead_zone = _dead_zone(ctl, math.ldexp(W_fs, -FRACTIONAL_BITS[fmt])).width_radps
    return _Figures(dead_zone, dead_zone + _ripple(ctl, design, Ts_s))


def _proposals(
    design: "Design",
    Ts_s: float,
    method: Method,
    fmt: Format,
    W_fs: float,
    T_fs: float,
    T_max: float,
    amplitude: float | None,
    T_fs_headroom: float,
) -> tuple[Proposal, ...]:
    """A period, a torque full scale and, in Q15, the Q31 format, that bring the limit cycles within
    ``amplitude`` (without one: the dead zone within one speed LSB).

    The dead zone's edge is about ``T_fs 2^-(N+1) / (Ki Ts)``, proportional to T_fs / Ts: each
    candidate starts there and is moved by steps of 2^-8 until the C controller meets the target.
    """
    N = FRACTIONAL_BITS[fmt]
    speed_lsb = math.ldexp(W_fs, -N)
    edge = math.ldexp(T_fs, -(N + 1)) / (design.Ki * Ts_s)

    def meets(f: _Figures | None) -> bool:
        if f is None:
            return False
        return f.dead_zone_radps <= speed_lsb if amplitude is None else f.limit_cycle_radps <= amplitude

    # the dead zone to aim at: the amplitude less the ripple of the present drive
    current = _figures_with(design, Ts_s, method, fmt, W_fs, T_fs, T_max)
    ripple = 0.0 if current is None else current.limit_cycle_radps - current.dead_zone_radps
    aim = speed_lsb if amplitude is None else max(amplitude - ripple, 0.5 * amplitude)
    proposals = []

    Ts_new = Ts_s * edge / aim
    figures = _figures_with(design, Ts_new, method, fmt, W_fs, T_fs, T_max)
    for _ in range(200):
        if meets(figures):
            break
        Ts_new *= 1.0 + 2.0**-8
        figures = _figures_with(design, Ts_new, method, fmt, W_fs, T_fs, T_max)
    w_design = max(design.alpha_radps, design.alpha_radps / (2.0 * design.zeta), design.m * design.alpha_radps)
    coarse = w_design * Ts_new > MAX_W_TS
    proposals.append(
        _proposal(
            "Ts_s",
            Ts_new,
            figures,
            not coarse and meets(figures),
            f"max(alpha, alpha/(2 zeta), m alpha) Ts = {w_design * Ts_new:.3g}"
            + (f" > {MAX_W_TS}: too coarse for the design" if coarse else f" <= {MAX_W_TS}"),
        )
    )

    T_fs_new = T_fs * aim / edge
    figures = _figures_with(design, Ts_s, method, fmt, W_fs, T_fs_new, T_max)
    for _ in range(200):
        if meets(figures) or T_fs_new < T_max:
            break
        T_fs_new *= 1.0 - 2.0**-8
        figures = _figures_with(design, Ts_s, method, fmt, W_fs, T_fs_new, T_max)
    floor_Nm = max(T_max, T_fs_headroom)
    if figures is None:  # the C controller refuses a full scale below the limit: the edge's proportionality
        figures = _Figures(edge * T_fs_new / T_fs, edge * T_fs_new / T_fs + ripple * T_fs_new / T_fs)
    proposals.append(
        _proposal(
            "torque_full_scale_Nm",
            T_fs_new,
            figures,
            T_fs_new >= floor_Nm and meets(figures),
            f"it must hold the torque limit {T_max:.4g} Nm and the states' headroom, >= {floor_Nm:.4g} Nm",
        )
    )
    if fmt == "q15":
        figures = _figures_with(design, Ts_s, method, "q31", W_fs, T_fs, T_max)
        proposals.append(
            _proposal(
                "fmt",
                "q31",
                figures,
                meets(figures) or amplitude is None and figures is not None,
                "31 more fractional bits in the integrator: int64 arithmetic (Cortex-M3)",
            )
        )
    return tuple(proposals)


def _proposal(change: str, value: float | str, figures: _Figures | None, feasible: bool, reason: str) -> Proposal:
    f = figures or _Figures(math.inf, math.inf)
    return Proposal(change, value, f.dead_zone_radps, f.limit_cycle_radps, feasible, reason)


def scaling_check(
    design: "Design",
    Ts_s: float,
    *,
    fmt: Format,
    speed_full_scale_radps: float,
    torque_full_scale_Nm: float,
    method: Method = "tustin",
    T_max_Nm: float | None = None,
    max_reference_step_radps: float | None = None,
    amplitude_radps: float | None = None,
) -> ScalingReport:
    """Check the fixed-point scaling of ``design`` sampled at ``Ts_s`` (module docstring).

    Parameters
    ----------
    design : Design
        The continuous design (:func:`~pmsm2dof.analysis.design.design`).
    Ts_s : float
        Sampling period [s], > 0.
    fmt : {"q15", "q31"}
        The fixed-point format.
    speed_full_scale_radps : float
        Speed of the integer 2^N [rad/s], > 0.
    torque_full_scale_Nm : float
        Torque of the integer 2^N [Nm], >= the torque limit.
    method : {"forward_euler", "backward_euler", "tustin"}, default "tustin"
        Discretization (Table 1).
    T_max_Nm : float, optional
        The torque limit of the current-vector limit, ``1.5 p psi_f i_max`` [Nm], > 0; default the
        torque full scale.
    max_reference_step_radps : float, optional
        The largest step of the reference [rad/s], > 0, for the headroom; default two full scales
        (from one end of the speed range to the other).
    amplitude_radps : float, optional
        The speed-error amplitude the drive must meet [rad/s], > 0; the limit cycles are compared with it
        and the proposals aim at it (without it, at one speed LSB).

    Returns
    -------
    ScalingReport

    Raises
    ------
    ConfigError
        A parameter out of range, or a scaling the C controller refuses (naming it).
    """
    Ts_s = require_positive("Ts_s", Ts_s)
    fmt = require_choice("fmt", fmt, FORMATS)
    W_fs = require_positive("speed_full_scale_radps", speed_full_scale_radps)
    T_fs = require_positive("torque_full_scale_Nm", torque_full_scale_Nm)
    T_max = T_fs if T_max_Nm is None else require_positive("T_max_Nm", T_max_Nm)
    step = (
        2.0 * W_fs
        if max_reference_step_radps is None
        else require_positive("max_reference_step_radps", max_reference_step_radps)
    )
    amplitude = None if amplitude_radps is None else require_positive("amplitude_radps", amplitude_radps)
    ctl = _controller(design, Ts_s, method, fmt, W_fs, T_fs, T_max)
    N = FRACTIONAL_BITS[fmt]
    exact, coef = ctl.gains, ctl.coefficients
    gains = tuple(_quantised(name, exact[name], coef[name], N) for name in GAINS if name != "iq_per_T")
    speed_lsb, torque_lsb = math.ldexp(W_fs, -N), math.ldexp(T_fs, -N)
    dead_zone = _dead_zone(ctl, speed_lsb)
    headroom = _headroom(exact, T_max / T_fs, step / W_fs, design.anti_windup, T_fs)
    ripple = _ripple(ctl, design, Ts_s)
    T_fs_headroom = max(h.torque_full_scale_min_Nm for h in headroom if h.signal in STATES)
    needs = dead_zone.width_radps > speed_lsb if amplitude is None else dead_zone.width_radps + ripple > amplitude
    return ScalingReport(
        fmt=fmt,
        Ts_s=Ts_s,
        method=method,
        speed_full_scale_radps=W_fs,
        torque_full_scale_Nm=T_fs,
        T_max_Nm=T_max,
        max_reference_step_radps=step,
        gains=gains,
        dead_zone=dead_zone,
        feedforward_stuck_Nm=_stuck_transient(ctl) * torque_lsb,
        ripple_radps=ripple,
        float32_dead_zone_radps=0.5 * _ulp_float32(T_max) / (design.Ki * Ts_s),
        amplitude_radps=amplitude,
        headroom=headroom,
        proposals=(_proposals(design, Ts_s, method, fmt, W_fs, T_fs, T_max, amplitude, T_fs_headroom) if needs else ()),
    )


def _ulp_float32(x: float) -> float:
    """The spacing of float32 numbers at |x| (normal range)."""
    return math.ldexp(1.0, math.frexp(abs(x))[1] - 24)


def _quantised(name: str, exact: float, stored_gain: tuple[int, int], bits: int) -> QuantisedGain:
    mantissa, shift = stored_gain
    stored = math.ldexp(mantissa, -shift)
    plain = round(math.ldexp(exact, bits))
    return QuantisedGain(
        name=name,
        exact=exact,
        mantissa=mantissa,
        shift=shift,
        relative_error=(stored - exact) / exact if exact != 0 else 0.0,
        plain_counts=plain if abs(plain) < 2**bits else None,
        plain_relative_error=(math.ldexp(plain, -bits) - exact) / exact if exact != 0 and abs(plain) < 2**bits else 0.0,
    )
