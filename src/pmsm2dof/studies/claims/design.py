"""The claims of the paper's section 3 and of the discretization, checked on the design and the runs
(:mod:`pmsm2dof.studies.claims`)."""

import math
from collections.abc import Callable, Mapping

import numpy as np

from ...core.bindings import Method
from .. import paper as st
from .. import paper_runs as pr
from ..configuration import scenario_design
from .common import (
    C1_SECOND_STEP_S,
    FIG7_M,
    FIRST_ORDER_RTOL,
    NO_OVERSHOOT_PCT,
    SAME_RTOL,
    Claim,
    _along,
    _claim,
    _over_text,
    _overshoot,
    _reference,
    _series,
    _value,
    _verdict,
    _window,
    fmt,
)


def _claim_gains(studies: st.Studies) -> Claim:
    sc = studies.speed_controller()
    d = scenario_design(studies.bases[pr.STEP_BASE])
    ok = math.isclose(d.Kp, 0.2, rel_tol=1e-6) and math.isclose(d.Ki, 0.3, rel_tol=1e-6)
    return _claim(
        section="4.1 (eq 9)",
        claim="the PI gains Kp = 0.2 and Ki = 0.3 correspond to alpha = 0.5 (eq 9, J = 0.4 kg m^2)",
        paper="Kp = 0.2, Ki = 0.3, alpha = 0.5 rad/s",
        measured=(
            f"eq 9 with J = {sc.J_kgm2:g} kg m^2, alpha = {sc.alpha_radps:g} rad/s, zeta = "
            f"{sc.zeta:.4g}: Kp = {d.Kp:.4g} Nm/(rad/s), Ki = {d.Ki:.4g} Nm/rad"
        ),
        values={"Kp": d.Kp, "Ki": d.Ki, "zeta": sc.zeta},
        verdict=_verdict(ok),
        reason=(
            "Kp = J alpha holds; the paper does not state zeta, and Ki = 0.3 gives zeta = alpha/2 sqrt(J/Ki) "
            "= 0.289 (the presets' value); their load rejection is checked with condition 2 of section 4.1"
            if ok
            else "the overrides change J, alpha or zeta away from the paper's values"
        ),
        source="design",
        evidence="design of the presets (eq 9)",
    )


def _claim_separate(studies: st.Studies) -> Claim:
    sweep = studies.sweep("m")
    step = _series(sweep, "2DOF eq 11, back-calculation AW", "step")
    load = _series(sweep, "2DOF eq 11, back-calculation AW", "load")
    rise = studies.series_values(step, "rise_time_s")
    dip = studies.series_values(load, "speed_dip_rpm")
    spread = float(np.nanmax(dip) - np.nanmin(dip))
    ratio = float(np.nanmax(rise) / np.nanmin(rise))
    ok = spread <= SAME_RTOL * np.nanmax(dip) and ratio > 2.0
    return _claim(
        section="3.1 (eq 5, 6), 4.2",
        claim="with Fr, Gx depends on F and Fr but GN on F only: tracking and load rejection are adjusted separately",
        paper="qualitative",
        measured=(
            f"m from {sweep.x[0]:g} to {sweep.x[-1]:g}: 10-90 % rise time of the 500 rpm step "
            f"{np.nanmax(rise):.2f} .. {np.nanmin(rise):.2f} s, while the dip after the 8 Nm load step "
            f"stays {np.nanmin(dip):.2f} .. {np.nanmax(dip):.2f} rpm (spread {spread:.3g} rpm)"
        ),
        values={"rise_time_s": rise.tolist(), "speed_dip_rpm": dip.tolist()},
        verdict=_verdict(ok),
        reason=""
        if ok
        else (
            f"the load dip changes by {spread:.3g} rpm (> {100 * SAME_RTOL:g} % of the dip) "
            f"or the rise time by less than a factor 2 ({ratio:.3g})"
        ),
        source="simulation",
        evidence="sensitivity to m (sens_m)",
    )


def _claim_first_order(studies: st.Studies) -> Claim:
    sc = studies.speed_controller()
    d = scenario_design(studies.bases[pr.STEP_BASE], m=1.0, feedforward="full")
    overshoot_lin = d.overshoot_pct()
    bandwidth = d.bandwidth_radps()
    pole = sc.alpha_radps
    small = studies.step("lin-full")
    rise, rise_eq10 = _value(small["rise_time_s"]), math.log(9.0) / pole
    over_small = _value(small["overshoot_pct"])
    big, note = _overshoot(studies, "e1-2dof-full")
    limit_time = _value(studies.step("e1-2dof-full")["current_limit_time_s"])
    sweep = studies.sweep("m")
    over_m = _along(studies, sweep, "2DOF eq 11, back-calculation AW", "step", "overshoot_pct")
    ok = (
        overshoot_lin < NO_OVERSHOOT_PCT
        and math.isclose(bandwidth, pole, rel_tol=FIRST_ORDER_RTOL)
        and over_small is not None
        and over_small < NO_OVERSHOOT_PCT
        and rise is not None
        and math.isclose(rise, rise_eq10, rel_tol=FIRST_ORDER_RTOL)
    )
    return _claim(
        section="3.3 (eq 10, 11)",
        claim="with the feedforward of eq 11 the tracking is first order, Gx = m alpha / (s + m alpha), "
        "without the overshoot of the 1DOF PI",
        paper="Gx = m alpha / (s + m alpha)",
        measured=(
            f"m = 1: linear Gx (eq 6 with eq 11) overshoot {overshoot_lin:.2g} %, -3 dB bandwidth "
            f"{bandwidth:.4g} rad/s (m alpha = {pole:.4g}); simulated {pr.SMALL_STEP_RPM:g} rpm step: overshoot "
            f"{fmt(over_small, 2, '%')}, 10-90 % rise {fmt(rise, 4, 's')} (eq 10: ln 9/(m alpha) = "
            f"{rise_eq10:.4g} s); 500 rpm step from rest (at the current limit for {limit_time:.2f} s): "
            f"{_over_text(big, note)}; the larger m of the sweep saturate longer and overshoot up to "
            f"{np.nanmax(over_m):.1f} % (m = {sweep.x[int(np.nanargmax(over_m))]:g})"
        ),
        values={
            "overshoot_linear_pct": overshoot_lin,
            "bandwidth_radps": bandwidth,
            "overshoot_small_step_pct": over_small,
            "rise_time_small_step_s": rise,
            "overshoot_500rpm_pct": big,
            "overshoot_m_sweep_pct": over_m.tolist(),
        },
        verdict=_verdict(ok),
        reason=(
            "first order while the current stays below its limit; the paper does not discuss saturated "
            "tracking with a fast feedforward (large m)"
        )
        if ok
        else "the linear or simulated tracking response is not first order (overshoot or rise time off eq 10)",
        source="design+simulation",
        evidence="design (eq 6, 11), runs lin-full, e1-2dof-full, sens_m",
    )


def _claim_fig7(studies: st.Studies) -> Claim:
    bandwidths = [
        scenario_design(studies.bases[pr.STEP_BASE], m=m, feedforward="full").bandwidth_radps() for m in FIG7_M
    ]
    sweep = studies.sweep("m")
    rise = _along(studies, sweep, "2DOF eq 11, back-calculation AW", "step", "rise_time_s")
    bw_up = all(b > a for a, b in zip(bandwidths, bandwidths[1:]))
    rise_down = all(b <= a * 1.001 for a, b in zip(rise, rise[1:]))
    return _claim(
        section="3.3 (Fig. 7)",
        claim="the bandwidth of Gx increases with m (alpha = 0.5, m from 0.2 to 2)",
        paper="increases with m",
        measured=(
            f"-3 dB bandwidth of Gx for m = {', '.join(f'{m:g}' for m in FIG7_M)}: "
            f"{', '.join(f'{b:.3g}' for b in bandwidths)} rad/s; simulated rise time of the 500 rpm step "
            f"falls from {rise[0]:.2f} s (m = {sweep.x[0]:g}) to {rise[-1]:.2f} s (m = {sweep.x[-1]:g})"
        ),
        values={"bandwidth_radps": bandwidths, "rise_time_s": rise.tolist()},
        verdict=_verdict(bw_up and rise_down, bw_up or rise_down),
        reason="" if bw_up and rise_down else "the bandwidth or the simulated rise time is not monotonic in m",
        source="design+simulation",
        evidence="fig07_bode_gx, sens_m",
    )


def _claim_lowpass(studies: st.Studies) -> Claim:
    sc = studies.speed_controller()
    low = scenario_design(studies.bases[pr.STEP_BASE], m=1.0, feedforward="lowpass")
    small = studies.step("lin-lowpass")
    rise, rise_eq10 = _value(small["rise_time_s"]), math.log(9.0) / sc.alpha_radps
    over_small = _value(small["overshoot_pct"])
    a, b = studies.results["lin-lowpass"], studies.results["lin-full"]
    diff = float(np.max(np.abs(a.speed_rpm - b.speed_rpm)))
    alpha_tau = sc.alpha_radps * sc.tau_i_s
    ok = (
        low.overshoot_pct() < NO_OVERSHOOT_PCT
        and math.isclose(low.bandwidth_radps(), sc.alpha_radps, rel_tol=FIRST_ORDER_RTOL)
        and over_small is not None
        and over_small < NO_OVERSHOOT_PCT
        and rise is not None
        and math.isclose(rise, rise_eq10, rel_tol=FIRST_ORDER_RTOL)
    )
    return _claim(
        section="3.3 (eq 12, 13)",
        claim="when tau_i is very small the feedforward simplifies to the first-order low-pass of eq 13",
        paper=f"tau_i 'very small' (here alpha tau_i = {alpha_tau:.3g})",
        measured=(
            f"linear Gx with eq 13: overshoot {low.overshoot_pct():.2g} %, bandwidth "
            f"{low.bandwidth_radps():.4g} rad/s (eq 12: {sc.alpha_radps:g}); simulated {pr.SMALL_STEP_RPM:g} rpm "
            f"step with eq 13: overshoot {fmt(over_small, 2, '%')}, rise {fmt(rise, 4, 's')} (eq 10: "
            f"{rise_eq10:.4g} s); it differs from the step with eq 12 by at most "
            f"{100 * diff / pr.SMALL_STEP_RPM:.2g} % of the step"
        ),
        values={
            "overshoot_lowpass_pct": low.overshoot_pct(),
            "bandwidth_lowpass_radps": low.bandwidth_radps(),
            "overshoot_small_step_pct": over_small,
            "rise_time_small_step_s": rise,
            "max_speed_difference_fraction": diff / pr.SMALL_STEP_RPM,
        },
        verdict=_verdict(ok),
        reason=(
            f"eq 13 keeps the tracking first order without overshoot; neglecting tau_i changes the "
            f"response by the order of alpha tau_i = {100 * alpha_tau:.2g} % of a step"
        )
        if ok
        else (
            f"with alpha tau_i = {alpha_tau:.3g} the low-pass feedforward no longer gives first-order tracking "
            f"(overshoot, or bandwidth or rise time more than {100 * FIRST_ORDER_RTOL:g} % off eq 10)"
        ),
        source="design+simulation",
        evidence="runs lin-lowpass, lin-full",
    )


def _claim_ka_range(studies: st.Studies) -> Claim:
    sweep = studies.sweep("ka")
    Kp = scenario_design(studies.bases[pr.STEP_BASE]).Kp
    x = np.array(sweep.x)
    used = (x >= 1.0 / (3.0 * Kp) * (1 - 1e-9)) & (x <= 3.0 / Kp * (1 + 1e-9))
    literal = (x >= Kp / 3.0 * (1 - 1e-9)) & (x <= 3.0 * Kp * (1 + 1e-9)) & ~used
    series = _series(sweep, pr.ONE_DOF, "step")
    over = studies.series_values(series, "overshoot_pct")
    settle = studies.series_values(series, "settling_time_s")
    no_aw = studies.figure(_reference(sweep, f"{pr.ONE_DOF}, no AW").name, "step", "overshoot_pct")
    ok = bool(np.all(np.isfinite(over[used])) and np.all(over[used] < no_aw))
    literal_text = (
        f"; over the literal Kp/3 .. 3 Kp = {Kp / 3:.3g} .. {3 * Kp:.3g} it is "
        f"{np.nanmin(over[literal]):.1f} .. {np.nanmax(over[literal]):.1f} %"
        if literal.any()
        else ""
    )
    return _claim(
        section="3.2",
        claim="Ka = 1/Kp generally; it can vary in the range 'Kp/3 ~ 3Kp'",
        paper=f"Ka = 1/Kp = {1 / Kp:.3g}; range read as 1/(3Kp) .. 3/Kp = {1 / (3 * Kp):.3g} .. {3 / Kp:.3g}",
        measured=(
            f"1DOF PI, 500 rpm step, Ka from 1/(3Kp) to 3/Kp: overshoot {over[used][0]:.1f} to "
            f"{over[used][-1]:.1f} %, 2 % settling {settle[used][0]:.1f} to {settle[used][-1]:.1f} s, against "
            f"{no_aw:.1f} % without AW{literal_text}"
        ),
        values={
            "overshoot_pct": over[used].tolist(),
            "settling_time_s": settle[used].tolist(),
            "overshoot_no_aw_pct": no_aw,
        },
        verdict=_verdict(ok),
        reason=(
            "Ka multiplies the torque u* and adds to the speed error, so it has the unit of 1/Kp; 'Kp/3 ~ 3Kp' "
            f"does not contain the default 1/Kp (= {1 / Kp:.3g} with Kp = {Kp:.3g}), and is read as "
            "1/(3Kp) .. 3/Kp, the default's factor-3 neighbourhood (figure sens_ka)"
        )
        if ok
        else "some Ka of the range does not reduce the overshoot below that without AW",
        source="simulation",
        evidence="sensitivity to Ka (sens_ka)",
    )


def _claim_unwind(studies: st.Studies) -> Claim:
    runs = {aw: studies.results[f"c1-1dof-{aw}"] for aw in pr.AW_LABELS}
    limit_time = {aw: _value(studies.step(f"c1-1dof-{aw}", 0)["current_limit_time_s"]) for aw in runs}
    x_peak = {aw: float(np.max(r.x_i_Nm[_window(r, 0.0, C1_SECOND_STEP_S)])) for aw, r in runs.items()}
    ok = limit_time["back_calculation"] < limit_time["none"]
    return _claim(
        section="3.3, 4.1",
        claim="with AW the signal u* is soon reduced to zero: the integrator quickly comes out of saturation",
        paper="qualitative",
        measured=(
            f"condition 1, 1DOF PI, first step: at the current limit for {limit_time['none']:.2f} s without "
            f"AW, {limit_time['back_calculation']:.2f} s with back-calculation, {limit_time['clamping']:.2f} s "
            "with clamping; "
            f"integrator peak {x_peak['none']:.2f} / {x_peak['back_calculation']:.2f} / "
            f"{x_peak['clamping']:.2f} Nm"
        ),
        values={"current_limit_time_s": limit_time, "integrator_peak_Nm": x_peak},
        verdict=_verdict(ok),
        reason="" if ok else "back calculation does not shorten the time at the current limit",
        source="simulation",
        evidence="runs c1-1dof-*, fig08_speed_aw, fig09_current_aw",
    )


def _claim_tustin(studies: st.Studies) -> Claim:
    Ts = studies.fine_Ts_s
    points = [p for p in studies.discretization if p.Ts_s == Ts]
    one = {p.method: p for p in points if p.controller == pr.ONE_DOF}
    cont = studies.continuous[pr.ONE_DOF][0]
    error = {m: p.controller_error for m, p in one.items()}
    deviation = {m: abs(p.overshoot_pct - cont) for m, p in one.items()}
    pm = {m: p.phase_margin_deg for m, p in one.items()}
    engine = {}
    for method in one:
        name = f"disc-{method}-{Ts:g}"
        if name in studies.metrics:
            engine[method] = studies.figure(name, "step", "overshoot_pct")
    best_error = min(error, key=error.__getitem__) == "tustin"
    closest = min(deviation, key=deviation.__getitem__)
    best_loop = closest == "tustin"
    Ts0 = min(p.Ts_s for p in studies.discretization)
    at_Ts0 = [p.overshoot_pct for p in studies.discretization if p.Ts_s == Ts0 and p.controller == pr.ONE_DOF]
    spread0 = max(at_Ts0) - min(at_Ts0)
    names = {"forward_euler": "FE", "backward_euler": "BE", "tustin": "Tustin"}
    reason = ""
    if not (best_error and best_loop):
        reason = f"Tustin is {'' if best_error else 'not '}the most faithful discrete PI"
        if not best_loop:
            reason += (
                f", but the sampled loop also delays by the ZOH (about Ts/2): in closed loop {names[closest]} "
                f"stays closest to the continuous design and {names[max(pm, key=pm.__getitem__)]} keeps the most "
                "phase margin"
            )
            if closest == "backward_euler":
                reason += (
                    "; the backward-Euler integrator takes the newest error, half a sample ahead of Tustin's "
                    "average, which offsets part of that delay"
                )
        reason += f"; at Ts = {Ts0:g} s the three overshoots differ by {spread0:.2g} pp (figure discretization)"

    def listing(d: Mapping[Method, float], fmt: Callable[[float], str]) -> str:
        return ", ".join(f"{names[m]} {fmt(v)}" for m, v in d.items())

    return _claim(
        section="3.4 (Table 1)",
        claim="among the discretization methods, Tustin (trapezoidal) usually has better performance",
        paper="Tustin best",
        measured=(
            f"at Ts = {Ts:g} s (largest of the study with max(alpha, alpha/2zeta, m alpha) Ts <= 0.1): error of "
            f"the discrete PI at the crossover {listing(error, lambda v: f'{100 * v:.2g} %')}; 1DOF step "
            f"overshoot off the continuous {cont:.1f} % by {listing(deviation, lambda v: f'{v:.2f} pp')}"
            + (f" (engine: {listing(engine, lambda v: f'{v:.2f} %')})" if engine else "")
            + f"; phase margin {listing(pm, lambda v: f'{v:.1f} deg')}"
        ),
        values={
            "controller_error": error,
            "overshoot_deviation_pp": deviation,
            "phase_margin_deg": pm,
            "engine_overshoot_pct": engine,
        },
        verdict=_verdict(best_error and best_loop, best_error or best_loop),
        reason=reason,
        source="design+simulation",
        evidence="discretization study (discretization), runs disc-*",
    )
