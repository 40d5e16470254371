"""The scaling check of the fixed-point speed controller (pmsm2dof.analysis.fixedpoint).

Truth: the dead zone's edges from the header's rounding rule applied to the exact gain, quantised
by the oracle (tests/oracles/fixed_point.py), and the C controllers' own behaviour at those edges
(the integrator moves one LSB beyond them, not at them); the headroom bound against the states
the C controller reaches after a reference step; the stuck feedforward transient against a run;
the proposals against the check of the changed drive.
"""

import math

import pytest

from oracles.fixed_point import exact_gains, quantise
from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.fixedpoint import scaling_check
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.core.fixedpoint import FixedPointSpeedController
from pmsm2dof.errors import ConfigError

RPM = math.pi / 30.0
ZETA = 1.0 / (2.0 * math.sqrt(3.0))
PAPER = design(0.4, 0.5, ZETA, tau_i_s=0.05)  # Kp = 0.2, Ki = 0.3 (section 4.1)
T_MAX = 1.5 * 4 * 0.2 * 7.6  # 9.12 Nm
SCALES = dict(speed_full_scale_radps=1000.0 * RPM, torque_full_scale_Nm=10.0)


def paper_check(fmt, **kw):
    return scaling_check(PAPER, 1e-4, fmt=fmt, **{**SCALES, "T_max_Nm": T_MAX, **kw})


def controller(fmt, Ts_s=1e-4, torque_full_scale_Nm=10.0):
    return FixedPointSpeedController(
        fmt, J_kgm2=0.4, alpha_radps=0.5, zeta=ZETA, tau_i_s=0.05, Ts_s=Ts_s, i_max_A=7.6, psi_f_Wb=0.2,
        Ld_H=0.01, Lq_H=0.01, pole_pairs=4, speed_full_scale_radps=SCALES["speed_full_scale_radps"],
        torque_full_scale_Nm=torque_full_scale_Nm, current_full_scale_A=10.0,
    )  # fmt: skip


def test_the_paper_design_in_q15_is_flagged_with_its_dead_zone():
    """Ki Ts = 0.3 * 1e-4 = 3e-5 Nm per rad/s per sample, half a torque LSB (10 Nm / 2^16 = 1.5e-4 Nm)
    at an error of 5.09 rad/s (48.6 rpm): the dead zone, from the quantised gain and the rule."""
    report = paper_check("q15", amplitude_radps=1.0 * RPM)
    assert report.flagged and report.exceeds
    drive = dict(
        J_kgm2=0.4, alpha_radps=0.5, zeta=ZETA, Ka=1.0, Ts_s=1e-4, torque_full_scale_Nm=10.0,
        speed_full_scale_radps=SCALES["speed_full_scale_radps"], current_full_scale_A=10.0, method="tustin",
        feedforward="none", anti_windup="none", m=1.0, tau_i_s=0.0, pole_pairs=4, psi_f_Wb=0.2, i_max_A=7.6,
    )  # fmt: skip
    m, s, _ = quantise(exact_gains(drive)["Ki_Ts"], 15)
    # R(m e, s) = 0 for -2^(s-1) <= m e < 2^(s-1)
    assert report.dead_zone.high_lsb == math.ceil(2 ** (s - 1) / m) - 1
    assert report.dead_zone.low_lsb == -math.floor(2 ** (s - 1) / m)
    edge_radps = 0.5 * (10.0 / 2**15) / (0.3 * 1e-4)
    assert report.dead_zone.width_radps == pytest.approx(edge_radps, abs=report.speed_lsb_radps)
    assert report.dead_zone.width_radps / RPM == pytest.approx(48.55, abs=0.01)
    # a series-form Q15 PI would store Ki Ts W_fs / T_fs = 3.1e-4 as 10 counts, 2.9 % low
    ki = next(g for g in report.gains if g.name == "Ki_Ts")
    assert ki.plain_counts == 10 and ki.plain_relative_error == pytest.approx(10 / 2**15 / ki.exact - 1)
    assert abs(ki.relative_error) < 2**-14
    text = report.text()
    print("\n" + text)
    Ts = next(p.value for p in report.proposals if p.change == "Ts_s")
    for fragment in ("Q15", "FLAGGED", "-48.55 to 48.55 rpm", "-1591 to 1591 LSB", "exceeded", f"Ts_s = {Ts:.4g}"):
        assert fragment in text, fragment


def test_q31_has_no_dead_zone_and_passes_with_room_for_the_paper_steps():
    report = paper_check("q31", torque_full_scale_Nm=32.0, max_reference_step_radps=500.0 * RPM)
    assert report.dead_zone.removed and not report.proposals
    assert all(h.bits > 0 for h in report.headroom if h.signal in ("x", "y_ff"))
    assert not report.flagged
    assert "none (one LSB of speed error moves the integrator)" in report.text()


@pytest.mark.parametrize("fmt, Ts_s, T_fs", [("q15", 1e-4, 10.0), ("q15", 1e-3, 40.0), ("q31", 1e-4, 10.0)])
def test_the_c_integrator_moves_just_beyond_the_dead_zone(fmt, Ts_s, T_fs):
    """At rest at a reference, one sample of constant error e: x stays for e at the edges, moves beyond."""
    report = scaling_check(PAPER, Ts_s, fmt=fmt, speed_full_scale_radps=SCALES["speed_full_scale_radps"],
                           torque_full_scale_Nm=T_fs, T_max_Nm=T_MAX)  # fmt: skip
    dz = report.dead_zone

    def moved(e):
        ctl = controller(fmt, Ts_s, T_fs)
        ctl.reset(w_ref=1000)
        ctl.step(1000, 1000 - int(e))
        return ctl.state["x"] != 0

    if dz.removed:
        assert moved(1) and moved(-1)
    else:
        assert not moved(dz.high_lsb) and moved(dz.high_lsb + 1)
        assert not moved(dz.low_lsb) and moved(dz.low_lsb - 1)


def test_the_headroom_bound_separates_saturating_and_safe_scalings():
    """A 500 rpm reference step from rest: with 10 Nm full scale the bound says the states saturate, and the
    C controller clamps x at two full scales; at the torque full scale the check asks for, nothing clamps."""
    step = 500.0 * RPM
    report = paper_check("q15", max_reference_step_radps=step)
    rows = {h.signal: h for h in report.headroom}
    assert rows["x"].bits < 0 and rows["y_ff"].bits < 0
    T_fs_safe = max(rows["x"].torque_full_scale_min_Nm, rows["y_ff"].torque_full_scale_min_Nm) * 1.01
    safe = paper_check("q15", torque_full_scale_Nm=T_fs_safe, max_reference_step_radps=step)
    assert all(h.bits > 0 for h in safe.headroom if h.signal in ("x", "y_ff"))
    for T_fs, clamps in ((10.0, True), (T_fs_safe, False)):
        ctl = controller("q15", torque_full_scale_Nm=T_fs)
        ctl.reset(T_init=ctl.torque_to_q(T_MAX))  # at rest at the torque limit
        out = ctl.step(ctl.speed_to_q(step), 0)
        held = max(abs(ctl.state["x"]), abs(out.y_ff))
        assert (held == 2**16 - 1) == clamps, (T_fs, ctl.state, out)


def test_the_stuck_feedforward_transient_is_where_a_run_stops():
    """After a reference step, at zero error, the transient y decays until rounding holds it, at the bound
    (the speed loop at Ts = 1 ms, as the paper presets, for a short run)."""
    report = scaling_check(PAPER, 1e-3, fmt="q15", speed_full_scale_radps=SCALES["speed_full_scale_radps"],
                           torque_full_scale_Nm=40.0, T_max_Nm=T_MAX)  # fmt: skip
    ctl = controller("q15", Ts_s=1e-3, torque_full_scale_Nm=40.0)
    w = ctl.speed_to_q(200.0 * RPM)
    c, out = ctl._ctl, ffi.new("p2d_speed_q15_output_t *")
    for _ in range(40_000):  # 40 s: 20 time constants of the lowpass (1 / alpha = 2 s)
        lib.p2d_speed_q15_step(c, w, w, out)
    stuck_lsb = round(report.feedforward_stuck_Nm / report.torque_lsb_Nm)
    assert stuck_lsb > 500  # the pole 1 - m alpha Ts = 0.9995: a dead band of about 1 / (2 * 5e-4) LSB
    assert out.y_ff_q15 == stuck_lsb


def test_the_proposals_bring_the_dead_zone_within_the_amplitude():
    amplitude = 1.0 * RPM
    report = paper_check("q15", amplitude_radps=amplitude)
    by = {p.change: p for p in report.proposals}
    # the sampling period: checked again by the scaling check at that period
    Ts = by["Ts_s"].value
    assert by["Ts_s"].feasible and isinstance(Ts, float)
    again = scaling_check(PAPER, Ts, fmt="q15", **SCALES, T_max_Nm=T_MAX, amplitude_radps=amplitude)
    assert again.dead_zone.width_radps <= amplitude and not again.exceeds
    # a torque full scale small enough would not hold the 9.12 Nm limit; Q31 removes the dead zone
    assert not by["torque_full_scale_Nm"].feasible and by["torque_full_scale_Nm"].value < T_MAX
    assert by["fmt"].feasible and by["fmt"].value == "q31" and by["fmt"].dead_zone_radps == 0.0
    # without an amplitude the target is one speed LSB: a period 1590 times longer, too coarse for the design
    exact = paper_check("q15")
    assert not {p.change: p for p in exact.proposals}["Ts_s"].feasible


@pytest.mark.parametrize(
    "kw, param",
    [
        (dict(fmt="q16"), "fmt"),
        (dict(Ts_s=0.0), "Ts_s"),
        (dict(speed_full_scale_radps=-1.0), "speed_full_scale_radps"),
        (dict(torque_full_scale_Nm=5.0), "torque_full_scale_Nm"),  # below T_max_Nm = 9.12
        (dict(amplitude_radps=math.nan), "amplitude_radps"),
        (dict(max_reference_step_radps=0.0), "max_reference_step_radps"),
    ],
)
def test_bad_input_names_the_parameter(kw, param):
    args = dict(fmt="q15", Ts_s=1e-4, **SCALES, T_max_Nm=T_MAX)
    args.update(kw)
    Ts_s = args.pop("Ts_s")
    with pytest.raises(ConfigError, match=param):
        scaling_check(PAPER, Ts_s, **args)
