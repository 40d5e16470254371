"""The report of the fixed-point scaling check (:func:`pmsm2dof.analysis.fixedpoint.scaling_check`).

What Q15 or Q31 does to a design, as numbers: each coefficient's quantisation
(:class:`QuantisedGain`), the integrator's dead zone (:class:`DeadZone`), the headroom of each
signal (:class:`Headroom`), the changes that would bring the dead zone within the amplitude
(:class:`Proposal`), and the whole (:class:`ScalingReport`, with its text).
"""

import math
from dataclasses import dataclass

from ..core.bindings import Method
from ..core.fixedpoint import FRACTIONAL_BITS, Format

RPM_PER_RADPS = 30.0 / math.pi
#: Headroom of a signal: the format holds +-(2^(N+1) - 1) LSBs, two full scales.
SIGNAL_LIMIT_PU = 2.0
#: The signals whose saturation changes the controller's response (states and the feedforward).
STATES = ("y_ff", "x")


@dataclass(frozen=True)
class QuantisedGain:
    """One coefficient of the controller, per unit of the scalings (a speed-to-torque gain ``G`` is
    ``G W_fs / T_fs``).

    Attributes
    ----------
    name : the coefficient of ``p2d_speed_q15_coef_t`` (``b_e0``, ``Ki_Ts``, ...)
    exact : the value before quantisation (double, ``p2d_speed_fixed_gains_t``)
    mantissa, shift : the stored gain, ``mantissa 2^-shift``
    relative_error : (stored - exact) / exact, 0 for an exact 0
    plain_counts : ``round(exact 2^N)``, the gain as a plain Q15 or Q31 number without a shift; None
        where it does not fit (``|gain| >= 1``)
    plain_relative_error : its relative error (-1 when it rounds to 0)
    """

    name: str
    exact: float
    mantissa: int
    shift: int
    relative_error: float
    plain_counts: int | None
    plain_relative_error: float

    @property
    def stored(self) -> float:
        """The stored gain ``mantissa 2^-shift``."""
        return math.ldexp(self.mantissa, -self.shift)


@dataclass(frozen=True)
class DeadZone:
    """The speed errors whose integrator increment rounds to 0, ``low_lsb <= e <= high_lsb`` (speed LSBs).

    ``low_lsb == high_lsb == 0``: one LSB of error moves the integrator. Unbounded (``math.inf``)
    when ``Ki Ts`` itself rounds to 0.
    """

    low_lsb: float
    high_lsb: float
    speed_lsb_radps: float

    @property
    def low_radps(self) -> float:
        return self.low_lsb * self.speed_lsb_radps

    @property
    def high_radps(self) -> float:
        return self.high_lsb * self.speed_lsb_radps

    @property
    def width_radps(self) -> float:
        """The largest error the integrator ignores [rad/s]."""
        return max(abs(self.low_radps), abs(self.high_radps))

    @property
    def removed(self) -> bool:
        """One LSB of speed error moves the integrator."""
        return self.low_lsb == self.high_lsb == 0


@dataclass(frozen=True)
class Headroom:
    """The largest magnitude of one signal against what the format holds.

    Attributes
    ----------
    signal : ``y_ff`` (feedforward transient), ``x`` (integrator plus static feedforward),
        ``T_ff`` (feedforward torque), ``u`` (command before the limit)
    bound_pu : largest magnitude [full scales] after a reference step of the given size from rest
        at the torque limit, speeds within the full scale; inf where the integrator winds up
    bits : log2(2 / bound_pu): negative where the signal saturates
    torque_full_scale_min_Nm : the torque full scale at which it fits
    """

    signal: str
    bound_pu: float
    bits: float
    torque_full_scale_min_Nm: float


@dataclass(frozen=True)
class Proposal:
    """A change that brings the limit cycles within the amplitude (without one, the dead zone within one
    speed LSB), checked by the C controller.

    Attributes
    ----------
    change : ``Ts_s``, ``torque_full_scale_Nm`` or ``fmt``
    value : the new value
    dead_zone_radps : the largest error the integrator ignores with it [rad/s]
    limit_cycle_radps : the amplitude of the limit cycles it allows [rad/s]
    feasible : whether the drive can use it
    reason : why, or why not
    """

    change: str
    value: float | str
    dead_zone_radps: float
    limit_cycle_radps: float
    feasible: bool
    reason: str


@dataclass(frozen=True)
class ScalingReport:
    """The scaling check of one design in one format: see :func:`~pmsm2dof.analysis.fixedpoint.scaling_check`.

    ``flagged`` is true when the dead zone is wider than one speed LSB, when the limit cycles exceed
    the given amplitude, or when a state can saturate.
    """

    fmt: Format
    Ts_s: float
    method: Method
    speed_full_scale_radps: float
    torque_full_scale_Nm: float
    T_max_Nm: float
    max_reference_step_radps: float
    gains: tuple[QuantisedGain, ...]
    dead_zone: DeadZone
    feedforward_stuck_Nm: float
    ripple_radps: float
    float32_dead_zone_radps: float
    amplitude_radps: float | None
    headroom: tuple[Headroom, ...]
    proposals: tuple[Proposal, ...]

    @property
    def bits(self) -> int:
        return FRACTIONAL_BITS[self.fmt]

    @property
    def speed_lsb_radps(self) -> float:
        return math.ldexp(self.speed_full_scale_radps, -self.bits)

    @property
    def torque_lsb_Nm(self) -> float:
        return math.ldexp(self.torque_full_scale_Nm, -self.bits)

    @property
    def limit_cycle_radps(self) -> float:
        """The amplitude of the speed error quantisation lets persist: the dead zone plus the output's ripple."""
        return self.dead_zone.width_radps + self.ripple_radps

    @property
    def exceeds(self) -> bool | None:
        """The limit cycles exceed the given amplitude (None without one)."""
        return None if self.amplitude_radps is None else self.limit_cycle_radps > self.amplitude_radps

    @property
    def flagged(self) -> bool:
        saturates = any(h.bits < 0 for h in self.headroom if h.signal in STATES)
        return self.dead_zone.width_radps > self.speed_lsb_radps or saturates or bool(self.exceeds)

    def text(self) -> str:
        """The report as lines of text, with every number in SI units and in rpm where it is a speed."""
        N, fmt = self.bits, self.fmt.upper()
        dz = self.dead_zone
        lines = [
            f"Fixed-point scaling check: {fmt}, Ts = {self.Ts_s:g} s, {self.method}"
            + (" -- FLAGGED" if self.flagged else " -- ok"),
            f"  speed: 2^{N} = {self.speed_full_scale_radps:.6g} rad/s "
            f"({self.speed_full_scale_radps * RPM_PER_RADPS:.6g} rpm), LSB {self.speed_lsb_radps:.4g} rad/s "
            f"({self.speed_lsb_radps * RPM_PER_RADPS:.4g} rpm)",
            f"  torque: 2^{N} = {self.torque_full_scale_Nm:.6g} Nm, LSB {self.torque_lsb_Nm:.4g} Nm; "
            f"limit {self.T_max_Nm:.6g} Nm",
            "  coefficients (per unit; stored as mantissa * 2^-shift):",
            f"    {'name':<15}{'exact':>14}{'mantissa':>13}{'shift':>6}{'error':>11}   plain {fmt}: counts (error)",
        ]
        for g in self.gains:
            lines.append(
                f"    {g.name:<15}{g.exact:>14.7g}{g.mantissa:>13d}{g.shift:>6d}{g.relative_error:>11.2e}"
                + (
                    f"   {g.plain_counts} ({g.plain_relative_error:+.2e})"
                    if g.plain_counts is not None
                    else "   does not fit"
                )
            )
        if math.isinf(dz.high_lsb):
            lines.append("  integrator dead zone: Ki Ts rounds to 0, no integral action")
        elif dz.removed:
            lines.append("  integrator dead zone: none (one LSB of speed error moves the integrator)")
        else:
            lines.append(
                f"  integrator dead zone: errors from {dz.low_radps:.4g} to {dz.high_radps:.4g} rad/s "
                f"({dz.low_radps * RPM_PER_RADPS:.4g} to {dz.high_radps * RPM_PER_RADPS:.4g} rpm, "
                f"{dz.low_lsb:.0f} to {dz.high_lsb:.0f} LSB) leave the integrator at rest: a load's steady-state "
                f"error up to {dz.width_radps * RPM_PER_RADPS:.4g} rpm is never removed"
            )
        lines.append(
            f"  for comparison, float32 at the torque limit: dead zone about {self.float32_dead_zone_radps:.3g} rad/s "
            f"({self.float32_dead_zone_radps * RPM_PER_RADPS:.3g} rpm)"
        )
        lines.append(
            f"  feedforward transient: rounding leaves up to {self.feedforward_stuck_Nm:.4g} Nm of it "
            f"({self.feedforward_stuck_Nm / self.T_max_Nm:.1%} of the limit) for the integrator to take up"
        )
        amplitude = (
            ""
            if self.amplitude_radps is None
            else f"; given amplitude {self.amplitude_radps:.4g} rad/s ({self.amplitude_radps * RPM_PER_RADPS:.4g} "
            f"rpm): {'exceeded' if self.exceeds else 'met'}"
        )
        lines.append(
            f"  limit cycles: quantisation lets a speed error of {self.limit_cycle_radps:.4g} rad/s "
            f"({self.limit_cycle_radps * RPM_PER_RADPS:.4g} rpm) persist (dead zone + output ripple "
            f"{self.ripple_radps:.3g} rad/s){amplitude}"
        )
        step = self.max_reference_step_radps
        lines.append(
            f"  headroom after a reference step of {step:.6g} rad/s ({step * RPM_PER_RADPS:.6g} rpm), "
            f"the format holds {SIGNAL_LIMIT_PU:g} full scales:"
        )
        lines.append("    e, dr    exact: a difference of two inputs fits two full scales")
        for h in self.headroom:
            if math.isinf(h.bound_pu):
                lines.append(f"    {h.signal:<8} winds up (no anti-windup): held at the format's limit")
                continue
            verdict = "ok" if h.bits >= 0 else f"SATURATES; torque_full_scale_Nm >= {h.torque_full_scale_min_Nm:.4g}"
            note = "" if h.signal in STATES or h.bits >= 0 else " (output only)" if h.signal == "T_ff" else ""
            lines.append(f"    {h.signal:<8} {h.bound_pu:8.3g} full scales, {h.bits:+6.2f} bits: {verdict}{note}")
        if self.proposals:
            goal = (
                f"the dead zone within one speed LSB ({self.speed_lsb_radps:.4g} rad/s)"
                if self.amplitude_radps is None
                else f"the limit cycles within {self.amplitude_radps:.4g} rad/s"
            )
            lines.append(f"  to bring {goal}:")
            for p in self.proposals:
                value = p.value if isinstance(p.value, str) else f"{p.value:.4g}"
                lines.append(
                    f"    {p.change} = {value}: dead zone {p.dead_zone_radps:.4g} rad/s "
                    f"({p.dead_zone_radps * RPM_PER_RADPS:.4g} rpm), limit cycles {p.limit_cycle_radps:.4g} rad/s; "
                    + ("feasible" if p.feasible else "not feasible")
                    + f" ({p.reason})"
                )
        return "\n".join(lines)
