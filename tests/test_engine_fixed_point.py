"""The engine running the fixed-point speed controllers (``speed_controller.arithmetic``).

Truths from outside the engine:

- the dead zone of the Q15 integrator from the scaling check (the quantised ``Ki Ts`` and the
  header's rounding rule, :mod:`pmsm2dof.analysis.fixedpoint`), against the samples of an engine
  run at which the integrator moved: it must stand still exactly on the predicted errors;
- a rounding analysis of the float32 and Q31 controllers propagated through the difference
  equations of the closed loop (the engine's RK4 map of eq 3 and the rotor, written out here):
  the bound the two runs' speeds must agree to;
- the defaults of the full scales from their documented formulas (eq 11 at s = 0 for Fr(0));
- lockstep runs against lone ones, and refusals naming the key, its value and its valid range.
"""

import math

import numpy as np
import pytest

from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.fixedpoint import scaling_check
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Simulation, simulate, simulate_many

RPM = math.pi / 30.0
J, ALPHA, ZETA, TAU_I = 0.4, 0.5, 1.0 / (2.0 * math.sqrt(3.0)), 0.05
KT = 1.5 * 4 * 0.2  # Nm/A
T_MAX = KT * 7.6  # 9.12 Nm
W0 = 500.0 * RPM
#: The scalings of the paper's Q15 example (docs/mcu.md): 1000 rpm and 10 Nm full scale.
SCALES = {"speed_controller.speed_full_scale_rpm": 1000.0, "speed_controller.torque_full_scale_Nm": 10.0}


def experiment3(arithmetic, **overrides):
    """The paper's experimental condition 3 (steady 500 rpm, 8 Nm load step at 0.5 s) in ``arithmetic``."""
    return load_scenario("paper-experiment-3").with_overrides({"speed_controller.arithmetic": arithmetic, **overrides})


def error_lsb(result, full_scale_radps, bits):
    """The speed error of each logged sample as the controller's integer: the engine rounds the reference
    and the reading to the nearest LSB, half up (csrc/sim/drive.h), the same double arithmetic here."""
    per = math.ldexp(1.0, bits) / float(np.float32(full_scale_radps))
    w_ref = np.floor(result.speed_ref_rpm * RPM * per + 0.5)
    w_meas = np.floor(result.speed_meas_rpm * RPM * per + 0.5)
    return w_ref - w_meas


# ---- the Q15 dead zone --------------------------------------------------------------------------


def q15_check():
    """The scaling check of the paper's design at Ts = 1e-4 s in Q15 with the scalings above."""
    return scaling_check(
        design(J, ALPHA, ZETA, tau_i_s=TAU_I),
        1e-4,
        fmt="q15",
        speed_full_scale_radps=1000.0 * RPM,
        torque_full_scale_Nm=10.0,
        T_max_Nm=T_MAX,
    )


@pytest.mark.parametrize("load_Nm", [8.0, -8.0])
def test_the_q15_integrator_in_the_engine_stands_still_exactly_on_the_predicted_dead_zone(load_Nm):
    """Paper condition 3 at Ts = 1e-4 s (the 1DOF PI: the reference is constant, so the feedforward
    would only add its static part to the state), Q15 at 1000 rpm and 10 Nm: over the 12 s after the
    8 Nm step, the integrator moves at every unsaturated sample whose error is outside the predicted
    [low, high] and at none inside it. The dead zone is the engine's, to the LSB: the load's sign
    decides which edge the error's last excursions reach (one LSB more or less on that edge fails)."""
    dz = q15_check().dead_zone
    assert dz.width_radps / RPM == pytest.approx(48.55, abs=0.01)
    run = simulate(
        experiment3(
            "q15",
            **SCALES,
            **{"speed_controller.Ts_s": 1e-4, "speed_controller.feedforward": "none"},
            **{"simulation.t_end_s": 12.0, "load.0.torque_Nm": load_Nm},
        )  # fmt: skip
    )
    e = error_lsb(run, 1000.0 * RPM, 15)
    moved = np.diff(run.x_i_Nm) != 0.0
    e_k, free = e[1:], ~run.saturated[1:]
    outside = (e_k < dz.low_lsb) | (e_k > dz.high_lsb)
    print(
        f"\nQ15 dead zone {dz.low_lsb:.0f} to {dz.high_lsb:.0f} LSB ({dz.width_radps / RPM:.2f} rpm): "
        f"{int(np.sum(moved & free))} moves, all outside; {int(np.sum(~outside & free))} samples inside, none moved"
    )
    assert np.sum(moved & free) > 1000 and np.sum(~outside & free) > 1000
    assert np.array_equal(moved[free], outside[free])


def test_q15_leaves_its_dead_zone_after_the_load_step_and_q31_removes_it():
    """After the 8 Nm step the Q15 error comes to rest inside the predicted zone (where the decaying
    oscillation last entered it: not at its edge, the current loop's lag carries it on) with the
    integrator still; float32 and Q31 remove the error to far below it."""
    dz = q15_check().dead_zone
    runs = {
        a: simulate(
            experiment3(
                a,
                **(SCALES if a != "float32" else {}),
                **{"speed_controller.Ts_s": 1e-4, "speed_controller.feedforward": "none"},
                **{"simulation.t_end_s": 60.0, "simulation.log_every": 100},
            )  # fmt: skip
        )
        for a in ("float32", "q31", "q15")
    }
    q15 = runs["q15"]
    e15 = error_lsb(q15, 1000.0 * RPM, 15)
    tail = q15.t_s >= 40.0
    assert np.ptp(q15.x_i_Nm[tail]) == 0.0 and np.ptp(e15[tail]) <= 1, "Q15 has not come to rest"
    assert dz.low_lsb <= e15[-1] <= dz.high_lsb
    e_rest = e15[-1] * dz.speed_lsb_radps
    errors = {a: abs(r.speed_ref_rpm[-1] - r.speed_rpm[-1]) * RPM for a, r in runs.items()}
    print(
        f"\nsteady-state error 60 s after the 8 Nm step: Q15 {e_rest / RPM:.3f} rpm (dead zone "
        f"+-{dz.width_radps / RPM:.2f} rpm), Q31 {errors['q31'] / RPM:.2e} rpm, "
        f"float32 {errors['float32'] / RPM:.2e} rpm"
    )
    assert abs(e_rest) > 0.25 * dz.width_radps
    # the loop's slowest mode decays as exp(-zeta w_n t) = exp(-t / 4 s): 15 time constants at 60 s
    assert errors["q31"] < 1e-3 < abs(e_rest)


# ---- float32 against Q31: a derived bound -------------------------------------------------------
#
# Both controllers compute the same discrete controller (eq 14, 15) up to rounding; on a constant
# reference the feedforward transient is exactly 0 in both (y = 0, dr = 0). Write each run as the
# exact equations on its own signals plus residuals n (per speed sample k):
#   u = b (r - w) + x + n_u,   T = Sat(u) at its limit L,   iq_cmd = (T + n_i) / kt
#   x' = x + Ki Ts (r - w) + Ki Ka Ts (T - u) + n_x
#   [w, iq]' = Phi [w, iq] + Gamma iq_cmd + (the load, the same in both runs) + n_w
# with b = Kp + Ki Ts / 2 (Tustin), and Phi, Gamma the engine's plant over one speed sample: eq 3
# (iq -> iq_cmd with tau_i) and J dw/dt = kt iq - T_load, integrated by current_per_speed RK4 steps
# of h = Ts_current, each x <- R(hA) x + h S(hA) B u for this linear system (R, S the RK4
# polynomials). The saturation is monotone and 1-Lipschitz: at the exact limit T_max,
# Sat(u_f) - Sat(u_q) = theta (u_f - u_q) with theta in [0, 1] (read from the two runs' u), and the
# two limits differ from T_max by lambda. The differences d = (d_w, d_iq, d_x) of the two runs then
# follow a linear time-varying system from d = 0 (both start at rest at 500 rpm):
#   du = -b d_w + d_x + n_u,   dT = theta du + lambda
#   d_x' = d_x - Ki Ts d_w + Ki Ka Ts ((theta - 1) du + lambda) + n_x
#   [d_w, d_iq]' = Phi [d_w, d_iq] + Gamma / kt (dT + n_i) + n_w
# so |d_w[n]| <= sum_k sum_j |(C Phi(n, k+1) B_k)_j| (|n_j,f[k]| + |n_j,q[k]|), the sensitivities
# taken backwards from each checked sample n. The residuals, per sample (U = 2^-24):
# - float32: r, w rounded to float32 and e = r - w rounded: |eta_e| <= U (|r| + |w| + |e|); each
#   coefficient from at most 7 float32 roundings of the design: relative error <= 8 U; u =
#   fmaf(b_e0, e, x): n_u <= 8 U b |e| + b eta_e + U |u|; x' = x + fl(Ki Ts e) (+ fmaf(Ki Ka Ts, u*, .)
#   limited): n_x <= U (|Ki Ts e| + 2 |Ki Ka Ts u*| + |x| + |x'|) (1 + 8 U) + 8 U (|Ki Ts e| +
#   |Ki Ka Ts u*|) + Ki Ts eta_e; iq = T / kt in float32 with kt rounded: n_i <= 9 U |T|; the limit
#   T_max from kt and i_max in float32: |lambda| <= 8 U T_max;
# - Q31: r and w rounded to the nearest speed LSB: |eta_e| <= 1 LSB; gains of 31-bit mantissas:
#   relative error <= 2^-31 (1 + 2^-14); u = R(b e) + R(x_q62, 31): 1 torque LSB; x rounds its
#   products to 2^-31 of a torque LSB; iq = R(iq_per_T T): one current LSB times kt, and its gain's
#   2^-31; the limit floored: one torque LSB;
# - the plant: double, the same code for both; <= 2^8 operations per speed sample, each rounding by
#   2^-53 of a value at most |w| + |iq|: n_w <= 2^-45 (|w| + |iq|) per run.
# |x| <= |u| + b |e| + 1e-5 Nm (the unsaturated equation for u, with room for its roundings).

U32 = 2.0**-24


def rk4_sample_map(Ts_current, n_periods):
    """(Phi, Gamma) of the plant [w, iq] over one speed sample of ``n_periods`` RK4 steps of ``Ts_current``:
    the input iq_cmd held, the load left out (it is the same in both runs)."""
    A = np.array([[0.0, KT / J], [0.0, -1.0 / TAU_I]])
    B = np.array([0.0, 1.0 / TAU_I])
    Z = Ts_current * A
    I2 = np.eye(2)
    R = I2 + Z + Z @ Z / 2.0 + Z @ Z @ Z / 6.0 + Z @ Z @ Z @ Z / 24.0
    S = I2 + Z / 2.0 + Z @ Z / 6.0 + Z @ Z @ Z / 24.0
    g = Ts_current * S @ B
    Phi, Gamma = I2, np.zeros(2)
    for _ in range(n_periods):
        Phi, Gamma = R @ Phi, R @ Gamma + g
    return Phi, Gamma


def residuals(f, q, fs, Ts, b, Ki_Ts, Ki_Ka_Ts):
    """(n_u, lambda, n_x, n_i, n_w): the bounds of both runs' residuals summed, per sample [SI]."""
    r = W0
    W_lsb, T_lsb, I_lsb = (math.ldexp(fs[k], -31) for k in ("speed_full_scale_radps", "torque_full_scale_Nm",
                                                           "current_full_scale_A"))  # fmt: skip
    c32, c31 = 8.0 * U32, 2.0**-31 * (1.0 + 2.0**-14)
    bounds = []
    for run, fmt in ((f, "float32"), (q, "q31")):
        w, u, T = run.w_m_radps, run.torque_unsat_Nm, run.torque_ref_Nm
        e = np.abs(r - w)
        ustar = np.abs(T - u)
        x = np.abs(u) + b * e + 1e-5
        x_new = x + Ki_Ts * e + Ki_Ka_Ts * ustar
        if fmt == "float32":
            eta_e = U32 * (abs(r) + np.abs(w) + e) * (1.0 + 4.0 * U32)
            n_u = c32 * b * e + b * eta_e + U32 * np.abs(u)
            n_x = (
                (1.0 + c32) * U32 * (Ki_Ts * e + 2.0 * Ki_Ka_Ts * ustar + x + x_new)
                + c32 * (Ki_Ts * e + Ki_Ka_Ts * ustar)
                + Ki_Ts * eta_e
            )
            n_i = 9.0 * U32 * (1.0 + U32) * np.abs(T)
            lam = 8.0 * U32 * T_MAX
        else:
            eta_e = W_lsb * (1.0 + 2.0**-30)
            n_u = c31 * b * e + b * eta_e + T_lsb * (1.0 + 2.0**-30)
            n_x = c31 * (Ki_Ts * e + Ki_Ka_Ts * ustar) + Ki_Ts * eta_e + 2.0**-31 * T_lsb
            n_i = KT * (I_lsb + c31 * np.abs(T) / KT) * (1.0 + 2.0**-30)
            lam = T_lsb * (1.0 + 2.0**-30)
        n_w = 2.0**-45 * (np.abs(w) + np.abs(run.iq_A))
        bounds.append((n_u, lam, n_x, n_i, n_w))
    return tuple(a + c for a, c in zip(*bounds))


def ltv_bound(theta, res, Phi, Gamma, checks, b, Ki_Ts, Ki_Ka_Ts):
    """The bound of |d_w[n]| at each sample n of ``checks``: the sensitivities backwards from n."""
    n_u, lam, n_x, n_i, n_w = res
    G = Gamma / KT
    n_of = np.asarray(checks)
    p = np.zeros((len(checks), 3))
    acc = np.zeros(len(checks))
    for k in range(max(checks) - 1, -1, -1):
        p[n_of == k + 1] = (1.0, 0.0, 0.0)
        th = theta[k]
        a = Ki_Ka_Ts * (th - 1.0)
        pG = p[:, 0] * G[0] + p[:, 1] * G[1]
        acc += (
            np.abs(pG * th + p[:, 2] * a) * n_u[k]
            + np.abs(pG + p[:, 2] * Ki_Ka_Ts) * lam
            + np.abs(p[:, 2]) * n_x[k]
            + np.abs(pG) * n_i[k]
            + np.abs(p[:, 0]) * n_w[k]
        )
        # p <- p A_k, A_k the matrix of d' = A_k d (columns d_w, d_iq, d_x)
        p = np.stack(
            (
                p[:, 0] * Phi[0, 0] + p[:, 1] * Phi[1, 0] - pG * th * b + p[:, 2] * (-Ki_Ts - a * b),
                p[:, 0] * Phi[0, 1] + p[:, 1] * Phi[1, 1],
                pG * th + p[:, 2] * (1.0 + a),
            ),
            axis=1,
        )
    return acc


@pytest.mark.parametrize("Ts_s", [1e-3, pytest.param(1e-4, marks=pytest.mark.slow)])
def test_float32_and_q31_runs_of_the_paper_condition_agree_within_the_derived_bound(Ts_s):
    """Paper condition 3 (the 2DOF controller of the preset, back calculation, 8 Nm load step, which
    drives the command into the current limit) with the paper's eq 3 current loop, float32 against
    Q31 at its derived full scales: the speeds agree within the bound derived above at every check."""
    overrides = {
        "current_loop.model": "first_order", "speed_controller.Ts_s": Ts_s, "simulation.t_end_s": 15.0,
    }  # fmt: skip
    f = simulate(experiment3("float32", **overrides))
    q_scenario = experiment3("q31", **overrides)
    q = simulate(q_scenario)
    fs = Simulation(q_scenario).full_scales
    T_lsb = math.ldexp(fs["torque_full_scale_Nm"], -31)
    # within the ranges the analysis assumes: u inside two full scales (not clamped by the format)
    assert np.max(np.abs(q.torque_unsat_Nm)) < (2**32 - 1) * T_lsb
    assert np.sum(f.saturated) > 10, "the load step should drive the command into the current limit"
    Kp, Ki = J * ALPHA, J * (ALPHA / (2.0 * ZETA)) ** 2
    b, Ki_Ts, Ki_Ka_Ts = Kp + Ki * Ts_s / 2.0, Ki * Ts_s, Ki * Ts_s / Kp
    u_f, u_q = f.torque_unsat_Nm, q.torque_unsat_Nm
    du = u_f - u_q
    with np.errstate(invalid="ignore", divide="ignore"):
        sat = np.clip(u_f, -T_MAX, T_MAX) - np.clip(u_q, -T_MAX, T_MAX)
        theta = np.where(du != 0.0, sat / du, (np.abs(u_f) < T_MAX).astype(float))
    assert np.all((theta >= 0.0) & (theta <= 1.0 + 1e-12))
    n = len(f.t_s)
    checks = list(range(n // 60, n, n // 60))
    Phi, Gamma = rk4_sample_map(1e-4, round(Ts_s / 1e-4))
    bound = ltv_bound(theta, residuals(f, q, fs, Ts_s, b, Ki_Ts, Ki_Ka_Ts), Phi, Gamma, checks, b, Ki_Ts, Ki_Ka_Ts)
    diff = np.abs(f.w_m_radps - q.w_m_radps)[checks]
    worst = int(np.argmax(diff / bound))
    print(
        f"\nTs = {Ts_s:g} s: float32 - Q31 speed, largest {diff.max() / RPM:.3g} rpm; bound {bound.min() / RPM:.3g} "
        f"to {bound.max() / RPM:.3g} rpm; closest to it at {f.t_s[checks[worst]]:.2f} s: {diff[worst] / RPM:.3g} "
        f"of {bound[worst] / RPM:.3g} rpm"
    )
    assert np.all(diff <= bound)
    assert diff.max() > 0.0  # two arithmetics, two traces: the comparison is not vacuous


# ---- defaults, lockstep, refusals ---------------------------------------------------------------


def test_the_derived_full_scales_follow_their_documented_formulas_and_hold_the_states():
    """Paper condition 2 (2DOF lowpass: x = x_i + Fr(0) r with Fr(0) = -J alpha / (4 zeta^2 m), eq 11 at
    s = 0): speed twice the no-load speed, torque 1.25 max(T_max + |Fr0| r_max, |b_dr| dr_max) / 2."""
    scenario = load_scenario("paper-condition-2").with_overrides({"speed_controller.arithmetic": "q31"})
    fs = Simulation(scenario).full_scales
    no_load = 540.0 / (math.sqrt(3.0) * 4 * 0.2)
    assert fs["speed_full_scale_radps"] == pytest.approx(2.0 * no_load, rel=1e-7)
    Fr0 = J * ALPHA / (4.0 * ZETA**2)  # 0.6 Nm per rad/s
    # references 0 -> 500 -> 200 rpm: x holds T_max + |Fr0| 500 rpm; y the transient of the 500 rpm step,
    # b_dr = Fr0 (1 - alpha Ts / 2) / (1 + alpha Ts / 2) by Tustin (smaller than x's here)
    assert fs["torque_full_scale_Nm"] == pytest.approx(1.25 * (T_MAX + Fr0 * W0) / 2.0, rel=1e-6)
    assert fs["current_full_scale_A"] == pytest.approx(fs["torque_full_scale_Nm"] / KT, rel=1e-6)
    run = simulate(scenario)
    # x = x_i + Fr0 r stays inside the two full scales the format holds
    x = run.x_i_Nm - Fr0 * run.speed_ref_rpm * RPM
    assert np.max(np.abs(x)) < 2.0 * fs["torque_full_scale_Nm"]
    # the small servo (2 kHz speed loop, 2000 rpm step from rest, 0.6 Nm limit): the command at the step decides,
    # b_e0 = Kp + Ki Ts / 2 (Tustin, eq 14), b_dr = -Fr0 / (1 + m alpha Ts / 2) (eq 15 by Tustin)
    servo = load_scenario("examples/firmware/small-servo-20k.toml").with_overrides(
        {"speed_controller.arithmetic": "q31"}
    )
    J_s, a_s, z_s, Ts_s, step = 1e-4, 150.0, 0.707, 5e-4, 2000.0 * RPM
    Fr0_s = -J_s * a_s / (4.0 * z_s**2)
    b_e0 = J_s * a_s + J_s * (a_s / (2.0 * z_s)) ** 2 * Ts_s / 2.0
    b_dr = -Fr0_s / (1.0 + a_s * Ts_s / 2.0)
    T_max_s = 1.5 * 4 * 0.01 * 10.0
    expected = 1.25 * (T_max_s + (b_e0 + abs(Fr0_s + b_dr)) * step) / 2.0
    assert Simulation(servo).full_scales["torque_full_scale_Nm"] == pytest.approx(expected, rel=1e-5)
    one_dof = load_scenario("paper-condition-2").with_overrides(
        {"speed_controller.arithmetic": "q15", "speed_controller.feedforward": "none"}
    )
    # the 1DOF PI holds no feedforward state: the command at the 500 rpm step, b_e0 = Kp + Ki Ts / 2
    b_e0_paper = J * ALPHA + J * (ALPHA / (2.0 * ZETA)) ** 2 * 1e-3 / 2.0
    expected = 1.25 * (T_MAX + b_e0_paper * W0) / 2.0
    assert Simulation(one_dof).full_scales["torque_full_scale_Nm"] == pytest.approx(expected, rel=1e-6)


def test_lockstep_runs_of_the_three_arithmetics_equal_lone_runs():
    scenarios = [
        load_scenario("paper-condition-1").with_overrides({"speed_controller.arithmetic": a, "simulation.t_end_s": 6.0})
        for a in ("float32", "q15", "q31", "q15")
    ]
    many = simulate_many(scenarios)
    for scenario, lockstep in zip(scenarios, many):
        lone = simulate(scenario)
        for name in ("speed_rpm", "torque_ref_Nm", "x_i_Nm", "iq_ref_A"):
            assert np.array_equal(getattr(lone, name), getattr(lockstep, name)), name
    assert not np.array_equal(many[0].speed_rpm, many[1].speed_rpm)


@pytest.mark.parametrize(
    "overrides, key, fragment",
    [
        ({"speed_controller.arithmetic": "q16"}, "speed_controller.arithmetic", "'float32', 'q15', 'q31'"),
        ({"speed_controller.torque_full_scale_Nm": 10.0}, "speed_controller.torque_full_scale_Nm", "'float32'"),
        (
            {
                "speed_controller.arithmetic": "q15",
                "speed_filter.notch_freq_Hz": 50.0,
                "speed_filter.notch_width_Hz": 5.0,
            },
            "speed_filter.notch_freq_Hz",
            "0 (no torque filter)",
        ),
        (
            {"speed_controller.arithmetic": "q31", "estimator.enabled": True, "estimator.adapt_gains": True},
            "estimator.adapt_gains",
            "no gain scheduling",
        ),
        ({"speed_controller.arithmetic": "q15", "motor.Lq_H": 0.02}, "motor.Lq_H", "equal to motor.Ld_H = 0.01"),
        (
            {"speed_controller.arithmetic": "q15", "speed_controller.torque_full_scale_Nm": 5.0},
            "speed_controller.torque_full_scale_Nm",
            ">= the torque limit",
        ),
        (
            {"speed_controller.arithmetic": "q15", "speed_controller.current_full_scale_A": 5.0},
            "speed_controller.current_full_scale_A",
            ">= i_max_A",
        ),
        (
            {"speed_controller.arithmetic": "q31", "speed_controller.speed_full_scale_rpm": 1e9},
            "speed_controller.speed_full_scale_rpm",
            "below 2^13",
        ),
        (
            {"speed_controller.arithmetic": "q15", "speed_controller.torque_full_scale_Nm": -1.0},
            "speed_controller.torque_full_scale_Nm",
            "> 0",
        ),
    ],
)
def test_what_the_fixed_point_controllers_do_not_support_is_refused_naming_the_key(overrides, key, fragment):
    with pytest.raises(ConfigError) as info:
        simulate(load_scenario("paper-condition-1").with_overrides(overrides))
    assert info.value.param == key and fragment in str(info.value), str(info.value)


def test_the_engine_refuses_an_arithmetic_it_does_not_know_and_fixed_point_with_a_torque_filter():
    cfg = Simulation(load_scenario("paper-condition-1")).cfg
    sim = ffi.new("p2d_sim_t *")
    cfg.arithmetic = 3
    assert lib.p2d_sim_init(sim, cfg) == lib.P2D_SIM_ERR_ARITHMETIC
    cfg.arithmetic = lib.P2D_ARITHMETIC_Q15
    cfg.speed_full_scale_radps, cfg.torque_full_scale_Nm, cfg.current_full_scale_A = 200.0, 10.0, 10.0
    assert lib.p2d_sim_init(sim, cfg) == lib.P2D_SIM_OK
    cfg.speed_filter.lowpass_freq_Hz, cfg.speed_filter.lowpass_zeta = 50.0, 0.7
    assert lib.p2d_sim_init(sim, cfg) == lib.P2D_SIM_ERR_ARITHMETIC
    assert ffi.string(lib.p2d_sim_status_param(lib.P2D_SIM_ERR_ARITHMETIC)) == b"arithmetic"


def test_the_firmware_configuration_refuses_a_fixed_point_scenario():
    """The header configures the float32 controller the firmware runs: a Q15 scenario is not silently shipped
    as float32."""
    from pmsm2dof.studies.configuration import configuration

    with pytest.raises(ConfigError) as info:
        configuration(load_scenario("paper-condition-1").with_overrides({"speed_controller.arithmetic": "q15"}))
    assert info.value.param == "speed_controller.arithmetic" and "speed_fixed.h" in str(info.value)
