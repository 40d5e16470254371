"""One speed-controller design, as ``pmsm2dof design`` reports it: gains, poles, margins, coefficients.

:func:`speed_design` designs the speed controller (eq 9-13) with its speed sensor chain, discretizes it
(Table 1, eq 14, 15), computes the margins of its loop and, when asked, the largest bandwidth that keeps
a phase margin; with a current loop designed for an identified motor, the speed loop's margins at the
corners of the motor's intervals. The :class:`SpeedDesign` it returns holds the figures as data
(:meth:`SpeedDesign.as_dict`) and as the rows of the command's tables (:meth:`SpeedDesign.design_rows`,
:meth:`SpeedDesign.current_loop_rows`).
"""

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any

from ..analysis.current_loop import CurrentLoopDesign, speed_margin_sensitivity
from ..analysis.design import Design, design
from ..analysis.discretize import DiscreteDesign
from ..analysis.margins import Margins
from ..analysis.sensor import DelayModel, SensorChain
from ..core.bindings import AntiWindup, Feedforward, Method


@dataclasses.dataclass(frozen=True)
class SpeedDesign:
    """The outcome of :func:`speed_design`.

    Attributes
    ----------
    design : Design
        The continuous design (eq 9-13) with its sensor chain.
    discrete : DiscreteDesign
        The design discretized at the speed loop's period (Table 1, eq 14, 15).
    margins : Margins
        The continuous loop's margins, with the sensor's delay as ``delay_model`` models it.
    delay_model : str
        ``"exact"`` or ``"pade"``.
    phase_margin_deg : float or None
        The phase margin asked for; None: not asked.
    alpha_max_radps : float or None
        The largest bandwidth that keeps ``phase_margin_deg`` (zeta, tau_i and the sensor kept).
    current_loop : CurrentLoopDesign or None
        The current loop of an identified motor, when designed.
    sensitivity : list of dict or None
        :func:`pmsm2dof.analysis.current_loop.speed_margin_sensitivity` of the design on that loop.
    """

    design: Design
    discrete: DiscreteDesign
    margins: Margins
    delay_model: DelayModel
    phase_margin_deg: float | None
    alpha_max_radps: float | None
    current_loop: CurrentLoopDesign | None
    sensitivity: list[dict[str, Any]] | None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the discrete design (:meth:`~pmsm2dof.analysis.discretize.DiscreteDesign.as_dict`) with
        the continuous margins, the delay model and the largest bandwidth asked for."""
        data = self.discrete.as_dict()
        data["continuous"]["margins"], _ = self.margins.values_and_reasons()
        data["delay"] = self.delay_model
        if self.phase_margin_deg is not None:
            data["max_alpha_radps"] = {"phase_margin_deg": self.phase_margin_deg, "alpha_radps": self.alpha_max_radps}
        return data

    def current_loop_dict(self) -> dict[str, Any]:
        """JSON-ready: ``current_loop`` and ``speed_margin_sensitivity``; empty without a current loop."""
        if self.current_loop is None:
            return {}
        return {"current_loop": self.current_loop.as_dict(), "speed_margin_sensitivity": self.sensitivity}

    def design_rows(self) -> list[tuple[str, str | None]]:
        """The design's figures, ``(name, value)`` in the order of the table; a heading has the value None."""
        d, dd = self.design, self.discrete
        sensor = d.sensor.describe() + (f" ({self.delay_model} delay in the margins)" if d.sensor.delay_s else "")
        return [
            ("Design inputs", None),
            ("J", f"{d.J_kgm2:.6g} kg m^2"),
            ("alpha", f"{d.alpha_radps:.6g} rad/s"),
            ("zeta", f"{d.zeta:.6g}"),
            ("m", f"{d.m:.6g}"),
            ("tau_i", f"{d.tau_i_s:.6g} s"),
            ("feedforward", d.feedforward),
            ("anti-windup", d.anti_windup),
            ("speed sensor", sensor),
            ("Gains (eq 9)", None),
            ("Kp = J alpha", f"{d.Kp:.6g} Nm/(rad/s)"),
            ("Ki = J (alpha/(2 zeta))^2", f"{d.Ki:.6g} Nm/rad"),
            ("Ka", f"{d.Ka:.6g} (rad/s)/Nm" + (" (1/Kp)" if d.Ka == 1.0 / d.Kp else "")),
            ("Continuous loop (F G, eq 2, 3, 6, 8)" if d.sensor.is_ideal else "Continuous loop (F G H)", None),
            ("loop poles", _poles_text(d.closed_loop_poles(), "rad/s")),
            ("feedforward pole", "none" if d.feedforward == "none" else f"{-d.fr_polynomials()[1][1]:.6g} rad/s"),
            ("bandwidth (-3 dB of Gx)", f"{d.bandwidth_radps():.6g} rad/s"),
            ("step overshoot", _overshoot_text(d.overshoot_pct(), d.missing())),
            ("margins", _margins_text(self.margins, "rad/s")),
            (f"Discrete loop ({dd.method}, Ts = {dd.Ts_s:g} s, ZOH plant)", None),
            ("loop poles", _poles_text(dd.poles, "(z)")),
            ("largest |z|", f"{max(abs(p) for p in dd.poles):.9g}"),
            ("step overshoot", _overshoot_text(dd.overshoot_pct, dd.missing)),
            ("margins", _margins_text(dd.margins, "rad/s")),
            ("Coefficients (p2d_speed_coef_t)", None),
            ("b_e0", f"{dd.b_e0:.9g} Nm/(rad/s)"),
            ("Ki_Ts", f"{dd.Ki_Ts:.9g} Nm/(rad/s)"),
            ("Ki_Ka_Ts", f"{dd.Ki_Ka_Ts:.9g}"),
            ("ff_Fr0", f"{dd.ff_Fr0:.9g} Nm/(rad/s)"),
            ("ff_b_dr", f"{dd.ff_b_dr:.9g} Nm/(rad/s)"),
            ("ff_a1", f"{dd.ff_a1:.9g}"),
            ("ff_Kd_per_Ts", f"{dd.ff_Kd_per_Ts:.9g} Nm/(rad/s)"),
        ]

    def current_loop_rows(self) -> list[tuple[str, str]]:
        """The current loop's gains (eq 3) and decoupling, ``(name, value)``; empty without a current loop."""
        loop = self.current_loop
        if loop is None:
            return []
        m = loop.motor
        return [
            ("Kp_d = Ld alpha_c", f"{loop.Kp_d_V_per_A:.6g} V/A"),
            ("Kp_q = Lq alpha_c", f"{loop.Kp_q_V_per_A:.6g} V/A"),
            ("Ki = Rs alpha_c", f"{loop.Ki_V_per_As:.6g} V/(A s)"),
            ("tau_i = 1/alpha_c (eq 3)", f"{loop.tau_i_s:.6g} s"),
            ("decoupling", f"ud += -w_e {m.Lq_H:.6g} iq, uq += w_e ({m.Ld_H:.6g} id + {m.psi_f_Wb:.6g})"),
        ]


def speed_design(
    J_kgm2: float,
    alpha_radps: float,
    zeta: float,
    *,
    m: float,
    tau_i_s: float,
    Ts_s: float,
    method: Method,
    feedforward: Feedforward,
    anti_windup: AntiWindup,
    Ka: float | None,
    sensor: Mapping[str, Any],
    delay_model: DelayModel,
    phase_margin_deg: float | None,
    current_loop: CurrentLoopDesign | None = None,
) -> SpeedDesign:
    """Design, discretize and check the speed controller (module docstring).

    Parameters
    ----------
    J_kgm2, alpha_radps, zeta, m, tau_i_s, feedforward, anti_windup, Ka
        As :func:`pmsm2dof.analysis.design.design` (eq 9-13); ``tau_i_s`` that of ``current_loop`` when given.
    Ts_s, method
        The speed loop's sampling period [s] and discretization (Table 1).
    sensor : dict
        The arguments of :class:`~pmsm2dof.analysis.sensor.SensorChain`.
    delay_model : str
        How the margins model the sensor's delay: ``"exact"`` or ``"pade"``.
    phase_margin_deg : float or None
        Also find the largest bandwidth that keeps this phase margin [deg].
    current_loop : CurrentLoopDesign, optional
        The current loop of an identified motor: the margins at the corners of its intervals.

    Returns
    -------
    SpeedDesign

    Raises
    ------
    ConfigError
        Naming the parameter of the design, the sensor chain or the discretization, its value and the valid range.
    """
    d = design(
        J_kgm2,
        alpha_radps,
        zeta,
        m=m,
        tau_i_s=tau_i_s,
        feedforward=feedforward,
        anti_windup=anti_windup,
        Ka=Ka,
        sensor=SensorChain(**sensor),
    )
    dd = d.discretize(Ts_s, method)  # first: it bounds the work of the sensor's delay
    margins = d.margins(delay_model)
    alpha_max = None if phase_margin_deg is None else d.max_alpha_for_phase_margin(phase_margin_deg, delay_model)
    sensitivity = (
        None if current_loop is None else speed_margin_sensitivity(current_loop, dd.design.Kp, dd.design.Ki, J_kgm2)
    )
    return SpeedDesign(d, dd, margins, delay_model, phase_margin_deg, alpha_max, current_loop, sensitivity)


def _poles_text(poles: Iterable[complex], unit: str) -> str:
    """Poles with conjugate pairs shown once as re ± im j."""
    parts = []
    for p in sorted(poles, key=lambda p: (p.real, -p.imag)):
        if p.imag > 0:
            parts.append(f"{p.real:.6g} ± {p.imag:.6g}j")
        elif p.imag == 0:
            parts.append(f"{p.real:.6g}")
    return ", ".join(parts) + f" {unit}"


def _margins_text(margins: Margins, unit: str) -> str:
    return (
        f"gain {margins.gain_margin_dB:.4g} dB, phase {margins.phase_margin_deg:.4g} deg"
        f" (crossover {margins.w_gain_crossover_radps:.4g} {unit})"
    )


def _overshoot_text(value: float, missing: Mapping[str, str]) -> str:
    return f"{value:.3g} %" if "overshoot_pct" not in missing else f"n/a ({missing['overshoot_pct']})"
