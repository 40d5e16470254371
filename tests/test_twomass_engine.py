"""The engine's two-mass drive train and torque filters against truths from outside the engine.

- an independent SciPy integration (DOP853, rtol 1e-11) of the two-mass plant written here,
  replaying the engine's logged current commands sample-and-hold;
- the analytic free oscillation of the twist: frequency sqrt(K (J_M + J_L) / (J_M J_L)) and
  damping D (J_M + J_L) / (2 J_M J_L w_r), from a least-squares fit of the shaft torque;
- the sampled closed loop built here with python-control: the ZOH equivalent of the continuous
  two-mass plant, the C controller's realized PI and feedforward, and the torque filters designed
  with SciPy (bilinear, prewarped) from their continuous prototypes;
- the rigid default: a stiff shaft tends to the rigid drive, and a notch damps a resonance that the
  loop excites without it;
- an encoder counts the angle of the side fed back: the readings of a difference estimator sum to
  the angle integrated here from the logged speed of that side (and not of the other).
"""

import math

import control
import numpy as np
import pytest
from scipy import optimize
from scipy.integrate import solve_ivp
from test_torque_filter import designed_lowpass, designed_notch

from pmsm2dof.core import SpeedController
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import Scenario
from pmsm2dof.sim.simulate import simulate

RADPS_PER_RPM = math.pi / 30.0
J_M, J_L = 0.1, 0.3  # motor and load side [kg m^2]: the paper's 0.4 in total
F_R_HZ = 30.0  # resonance
K = (2 * math.pi * F_R_HZ) ** 2 * J_M * J_L / (J_M + J_L)  # stiffness giving F_R_HZ [Nm/rad]
ZETA_R = 0.02
D = 2 * ZETA_R * (2 * math.pi * F_R_HZ) * J_M * J_L / (J_M + J_L)  # damping giving ZETA_R [Nm s/rad]


def tree(**sections):
    """The paper's motor on a two-mass train (first-order current loop), with sections replaced."""
    t = {
        "name": "two-mass test drive",
        "motor": {"pole_pairs": 4, "Rs_ohm": 0.5, "Ld_H": 0.01, "Lq_H": 0.01, "psi_f_Wb": 0.2, "J_kgm2": J_M},
        "limits": {"i_max_A": 7.6, "u_dc_V": 540.0},
        "current_loop": {"model": "first_order", "tau_i_s": 2e-3, "Ts_s": 1e-4},
        "speed_controller": {"alpha_radps": 20.0, "zeta": 0.7, "Ts_s": 1e-3},
        "mechanics": {
            "model": "two_mass",
            "J_load_kgm2": J_L,
            "stiffness_Nm_per_rad": K,
            "damping_Nms_per_rad": D,
        },
        "simulation": {"t_end_s": 0.5, "speed0_rpm": 100.0},
        "reference": [{"t_s": 0.0, "speed_rpm": 100.0}],
    }
    t.update(sections)
    return t


def replay(result, backlash_rad=0.0):
    """SciPy integration of the first-order current loop and the two-mass train through the rows,
    holding each row's iq_ref; returns (w_m, w_L, T_s) at the row times."""
    data = result.scenario.data
    mech, motor = data["mechanics"], data["motor"]
    kt = 1.5 * motor["pole_pairs"] * motor["psi_f_Wb"]
    tau_i, JM, JL = data["current_loop"]["tau_i_s"], motor["J_kgm2"], mech["J_load_kgm2"]
    Kk, Dd, half = mech["stiffness_Nm_per_rad"], mech["damping_Nms_per_rad"], 0.5 * backlash_rad
    load = {e["t_s"]: e["torque_Nm"] for e in data["load"]}

    def shaft(theta, dw):
        return 0.0 if abs(theta) < half else Kk * (theta - math.copysign(half, theta)) + Dd * dw

    def rhs(t, x, iq_ref, T_load):
        iq, w_m, theta, w_l = x
        T_s = shaft(theta, w_m - w_l)
        return [(iq_ref - iq) / tau_i, (kt * iq - T_s) / JM, w_m - w_l, (T_s - T_load) / JL]

    def contact(sign):
        event = lambda t, x, *args: x[2] - sign * half  # noqa: E731
        event.terminal = True
        return event

    events = [contact(1.0), contact(-1.0)] if half > 0 else []
    x = np.array([result.iq_A[0], result.w_m_radps[0], 0.0, result.w_m_radps[0]])
    out = [x]
    t, T_load = result.t_s, 0.0
    for k in range(len(t) - 1):
        T_load = load.get(round(t[k], 9), T_load)
        ta = t[k]
        while True:  # restart at each contact change, so that DOP853 never steps over a kink
            sol = solve_ivp(
                rhs, (ta, t[k + 1]), x, method="DOP853", rtol=1e-11, atol=1e-13, args=(result.iq_ref_A[k], T_load),
                events=events,
            )  # fmt: skip
            x = sol.y[:, -1]
            if sol.status != 1:
                break
            ta = sol.t[-1]
            x[2] = math.copysign(half, x[2]) if abs(abs(x[2]) - half) < 1e-15 else x[2]
            sol_next = rhs(ta, x, result.iq_ref_A[k], T_load)
            x[2] += 1e-14 * math.copysign(1.0, sol_next[2])  # step off the event surface
        out.append(x)
    x = np.array(out)
    return x[:, 1], x[:, 3], np.array([shaft(th, dw) for th, dw in zip(x[:, 2], x[:, 1] - x[:, 3])])


def open_loop(**mechanics):
    """A load step on the load side with (practically) no control: eq 9 gains for alpha = 1e-6 rad/s."""
    return Scenario.from_dict(
        tree(
            speed_controller={
                "alpha_radps": 1e-6,
                "zeta": 1.0,
                "Ts_s": 1e-4,
                "feedforward": "none",
                "anti_windup": "none",
            },
            mechanics={"model": "two_mass", "J_load_kgm2": J_L, "stiffness_Nm_per_rad": K, **mechanics},
            load=[{"t_s": 0.01, "torque_Nm": 2.0}],
        )
    )


def test_open_loop_oscillation_frequency_and_damping_are_the_analytic_ones():
    result = simulate(open_loop(damping_Nms_per_rad=D))
    after = result.t_s >= 0.01
    t, T_s = result.t_s[after] - 0.01, result.shaft_torque_Nm[after]

    def model(t, c, A, sigma, w_d, phi):
        return c + A * np.exp(-sigma * t) * np.cos(w_d * t + phi)

    w_r = 2 * math.pi * F_R_HZ
    p0 = (2.0 * J_M / (J_M + J_L), -2.0 * J_M / (J_M + J_L), ZETA_R * w_r, w_r, 0.0)
    (c, A, sigma, w_d, phi), _ = optimize.curve_fit(model, t, T_s, p0=p0)
    w_fit = math.hypot(w_d, sigma)
    assert w_fit == pytest.approx(math.sqrt(K * (J_M + J_L) / (J_M * J_L)), rel=1e-2)
    assert sigma / w_fit == pytest.approx(D * (J_M + J_L) / (2 * J_M * J_L * w_r), rel=1e-2)
    # the fit describes the trace: the residual is far below the oscillation
    assert np.max(np.abs(model(t, c, A, sigma, w_d, phi) - T_s)) < 1e-3 * abs(A)
    # the mean shaft torque accelerates the motor side like the load side: T_L J_M / (J_M + J_L)
    assert c == pytest.approx(2.0 * J_M / (J_M + J_L), rel=1e-3)


@pytest.mark.parametrize(
    "backlash_rad, dt_s, tol, tol_T_Nm", [(0.0, 1e-4, 1e-9, 1e-7), (2e-3, 1e-4, 1e-4, 0.05), (2e-3, 1e-5, 2e-6, 5e-4)]
)
def test_two_mass_trace_matches_scipy_integration(backlash_rad, dt_s, tol, tol_T_Nm):
    """Without play to 1e-9 of the speed; with play RK4 steps over the contact kinks (measured: 3.6e-5
    of the speed and 0.023 Nm at one step per current period, 1e-6 and 2e-4 Nm at a tenth of it)."""
    result = simulate(
        open_loop(damping_Nms_per_rad=D, backlash_rad=backlash_rad).with_overrides({"simulation.dt_s": dt_s})
    )
    w_m, w_l, T_s = replay(result, backlash_rad)
    scale = np.max(np.abs(result.w_m_radps))
    assert np.max(np.abs(w_m - result.w_m_radps)) < tol * scale
    assert np.max(np.abs(w_l - result.load_speed_rpm * RADPS_PER_RPM)) < tol * scale
    assert np.max(np.abs(T_s - result.shaft_torque_Nm)) < tol_T_Nm
    if backlash_rad:
        # the play is crossed: the shaft carries nothing for a while, then the torque again
        assert np.any(result.shaft_torque_Nm[result.t_s > 0.01] == 0.0)


def test_load_feedback_reads_the_load_side():
    result = simulate(
        Scenario.from_dict(
            tree(
                mechanics={
                    "model": "two_mass",
                    "J_load_kgm2": J_L,
                    "stiffness_Nm_per_rad": K,
                    "damping_Nms_per_rad": D,
                    "feedback": "load",
                },
                load=[{"t_s": 0.1, "torque_Nm": 1.0}],
            )
        )
    )
    assert np.array_equal(result.speed_meas_rpm, result.load_speed_rpm)
    assert not np.array_equal(result.speed_meas_rpm, result.speed_rpm)


def realized_controller(data):
    """C(z) and Fr(z) of the C speed controller of the scenario, from its realized coefficients
    (discretize.py's form: the PI (b_e0 + (Ki Ts - b_e0) z^-1)/(1 - z^-1), the feedforward
    Fr0 + b_dr (1 - z^-1)/(1 + a1 z^-1))."""
    sc, motor = data["speed_controller"], data["motor"]
    ctl = SpeedController(
        J_kgm2=sc["J_kgm2"],
        alpha_radps=sc["alpha_radps"],
        zeta=sc["zeta"],
        Ts_s=sc["Ts_s"],
        i_max_A=data["limits"]["i_max_A"],
        psi_f_Wb=motor["psi_f_Wb"],
        Ld_H=motor["Ld_H"],
        Lq_H=motor["Lq_H"],
        pole_pairs=motor["pole_pairs"],
    )
    c, Ts = ctl.coefficients, sc["Ts_s"]
    C = control.tf([c["b_e0"], c["Ki_Ts"] - c["b_e0"]], [1.0, -1.0], Ts)
    Fr = control.tf([c["ff_Fr0"]], [1.0], Ts) + control.tf([c["ff_b_dr"], -c["ff_b_dr"]], [1.0, c["ff_a1"]], Ts)
    return C, Fr


def analytic_step(data, n, H=None):
    """Motor-side speed at the samples for a unit reference step: P H (Fr + C) / (1 + P H C), with P the
    ZOH equivalent of kt/(tau_i s + 1) * the two-mass w_m / T and H the torque filters (None: 1)."""
    JM, mech = data["motor"]["J_kgm2"], data["mechanics"]
    JL, Kk, Dd = mech["J_load_kgm2"], mech["stiffness_Nm_per_rad"], mech["damping_Nms_per_rad"]
    Ts, tau = data["speed_controller"]["Ts_s"], data["current_loop"]["tau_i_s"]
    # w_m / T = (J_L s^2 + D s + K) / (s (J_M J_L s^2 + D (J_M + J_L) s + K (J_M + J_L)))
    Gm = control.tf([JL, Dd, Kk], np.polymul([1.0, 0.0], [JM * JL, Dd * (JM + JL), Kk * (JM + JL)]))
    # in state space: the polynomials of the loop multiplied out in z lose the poles near z = 1
    P = control.c2d(control.ss(control.tf([1.0], [tau, 1.0]) * Gm), Ts, "zoh")
    C, Fr = (control.ss(G) for G in realized_controller(data))
    if H is not None:
        P = P * control.ss(H)
    T = control.feedback(P, C) * (Fr + C)
    return control.forced_response(T, T=np.arange(n) * Ts, U=np.ones(n)).outputs


@pytest.mark.parametrize("with_filters", [False, True])
def test_closed_loop_small_signal_response_is_the_analytic_one(with_filters):
    """A 1 rpm step (no saturation): the sampled motor speed equals the two-mass loop's within 1e-3 of the step."""
    filters = {"notch_freq_Hz": 30.0, "notch_width_Hz": 20.0, "notch_depth": 0.05} if with_filters else {}
    if with_filters:
        filters.update(lowpass_freq_Hz=150.0, lowpass_zeta=0.7)
    scenario = Scenario.from_dict(
        tree(
            speed_filter=filters,
            simulation={"t_end_s": 0.6, "speed0_rpm": 100.0},
            reference=[{"t_s": 0.0, "speed_rpm": 100.0}, {"t_s": 0.1, "speed_rpm": 101.0}],
        )
    )
    result = simulate(scenario)
    data = scenario.data
    assert data["speed_controller"]["J_kgm2"] == J_M + J_L  # eq 9 on the total inertia
    assert not result.saturated.any()
    H = None
    if with_filters:
        Ts = data["speed_controller"]["Ts_s"]
        H = control.tf(*designed_notch(30.0, 20.0, 0.05, Ts), Ts) * control.tf(*designed_lowpass(150.0, 0.7, Ts), Ts)
    after = result.t_s >= 0.1 - 1e-9
    step = RADPS_PER_RPM
    measured = (result.w_m_radps[after] - 100 * RADPS_PER_RPM) / step
    expected = analytic_step(data, int(after.sum()), H)
    assert np.max(np.abs(measured - expected)) < 1e-3
    assert np.max(np.abs(expected - 1.0)) > 0.5  # the comparison covers the transient


def test_stiff_shaft_tends_to_the_rigid_drive():
    rigid = simulate(
        Scenario.from_dict(
            tree(
                motor={**tree()["motor"], "J_kgm2": J_M + J_L},
                mechanics={"model": "rigid"},
                reference=[{"t_s": 0.0, "speed_rpm": 100.0}, {"t_s": 0.05, "speed_rpm": 101.0}],
            )
        )
    )
    stiff = simulate(
        Scenario.from_dict(
            tree(
                mechanics={
                    "model": "two_mass",
                    "J_load_kgm2": J_L,
                    "stiffness_Nm_per_rad": 1e6,
                    "damping_Nms_per_rad": 50.0,
                },
                reference=[{"t_s": 0.0, "speed_rpm": 100.0}, {"t_s": 0.05, "speed_rpm": 101.0}],
            )
        )
    )
    # a 580 Hz shaft: the compliance costs 0.3 % of the 1 rpm step
    assert np.max(np.abs(stiff.speed_rpm - rigid.speed_rpm)) < 5e-3
    assert np.array_equal(rigid.load_speed_rpm, rigid.speed_rpm)
    assert np.array_equal(rigid.shaft_torque_Nm, rigid.load_Nm)


def resonant_scenario(**speed_filter):
    """Feedback from the load side, the shaft at 30 Hz (zeta_r = 0.02) and the eq 9 design with
    alpha = 20 rad/s on the total inertia: the loop's gain peaks above 1 at the resonance, a closed-loop
    pole at |z| = 1.005 (pmsm2dof.analysis.twomass); with the notch its largest pole is at |z| = 0.996."""
    return Scenario.from_dict(
        tree(
            mechanics={
                "model": "two_mass",
                "J_load_kgm2": J_L,
                "stiffness_Nm_per_rad": K,
                "damping_Nms_per_rad": D,
                "feedback": "load",
            },
            speed_filter=speed_filter,
            simulation={"t_end_s": 3.0, "speed0_rpm": 100.0},
            reference=[{"t_s": 0.0, "speed_rpm": 100.0}, {"t_s": 0.1, "speed_rpm": 100.5}],
        )
    )


def test_notch_damps_the_resonance_the_loop_excites():
    plain = simulate(resonant_scenario())
    notched = simulate(resonant_scenario(notch_freq_Hz=F_R_HZ, notch_width_Hz=20.0, notch_depth=0.05))
    late = plain.t_s > 2.5
    # without the notch the resonance grows until the current limit holds it: a limit cycle
    assert plain.saturated[late].any() and np.ptp(plain.shaft_torque_Nm[late]) > 100.0
    # with it the half-rpm step settles: no saturation, the shaft torque still within 0.1 Nm
    assert not notched.saturated.any() and np.ptp(notched.shaft_torque_Nm[late]) < 1e-3


@pytest.mark.parametrize(
    "sections, key",
    [
        ({"mechanics": {"model": "two_mass", "stiffness_Nm_per_rad": 1.0}}, "mechanics.J_load_kgm2"),
        ({"mechanics": {"model": "rigid", "J_load_kgm2": 0.1}}, "mechanics.J_load_kgm2"),
        (
            {"mechanics": {"model": "two_mass", "J_load_kgm2": 0.1, "stiffness_Nm_per_rad": -1.0}},
            "mechanics.stiffness_Nm_per_rad",
        ),
        ({"speed_filter": {"notch_freq_Hz": 600.0, "notch_width_Hz": 10.0}}, "speed_filter.notch_freq_Hz"),
        ({"speed_filter": {"notch_freq_Hz": 60.0}}, "speed_filter.notch_width_Hz"),
        ({"speed_filter": {"lowpass_freq_Hz": 60.0}}, "speed_filter.lowpass_zeta"),
    ],
)
def test_bad_mechanics_and_filters_name_their_key(sections, key):
    with pytest.raises(ConfigError) as err:
        simulate(Scenario.from_dict(tree(**sections)))
    assert err.value.param == key


@pytest.mark.slow
@pytest.mark.parametrize("feedforward, m", [("none", 1.0), ("lowpass", 1.0), ("no_tau", 2.0), ("full", 2.0)])
def test_stability_does_not_depend_on_the_feedforward_form(feedforward, m):
    """Fr lies outside the loop (eq 6): every form leaves the resonance unstable without the notch and
    stable with it (the stable region of pmsm2dof.analysis.twomass holds for each form)."""
    form = {"speed_controller.feedforward": feedforward, "speed_controller.m": m}
    plain = simulate(resonant_scenario().with_overrides(form))
    notched = simulate(
        resonant_scenario(notch_freq_Hz=F_R_HZ, notch_width_Hz=20.0, notch_depth=0.05).with_overrides(form)
    )
    late = plain.t_s > 2.5
    assert np.ptp(plain.shaft_torque_Nm[late]) > 100.0
    assert np.ptp(notched.shaft_torque_Nm[late]) < 1e-3


@pytest.mark.parametrize(
    ("feedback", "delay_s"), [("load", 0.0), ("motor", 0.0), ("load", 2.5e-4)], ids=["load", "motor", "load-delayed"]
)
def test_encoder_counts_the_angle_of_the_fed_back_side(feedback, delay_s):
    # A difference estimator's readings telescope: Ts sum_{k=1..j} w_meas[k] is the count of the
    # angle at t_j - delay from the one at -delay, within one count. The angle of each side is integrated here from the
    # logged speeds (trapezoids, interpolated to t - delay); a load step twists the shaft by
    # T_load / K, 250 counts at 2^20 counts/rev, so only the fed-back side's angle fits.
    counts_per_rev, T_load_Nm = 2**20, 4.0
    result = simulate(
        Scenario.from_dict(
            tree(
                speed_controller={"alpha_radps": 5.0, "zeta": 0.7, "Ts_s": 1e-3},
                mechanics={
                    "model": "two_mass",
                    "J_load_kgm2": J_L,
                    "stiffness_Nm_per_rad": K,
                    "damping_Nms_per_rad": D,
                    "feedback": feedback,
                },
                speed_sensor={
                    "model": "encoder",
                    "counts_per_rev": counts_per_rev,
                    "estimator": "difference",
                    "delay_s": delay_s,
                },
                load=[{"t_s": 0.1, "torque_Nm": T_load_Nm}],
            )
        )
    )
    t, Ts = result.t_s, 1e-3
    assert np.allclose(np.diff(t), Ts)
    counted = Ts * np.cumsum(result.speed_meas_rpm[1:] * RADPS_PER_RPM)

    def angle(speed_rpm):
        w = speed_rpm * RADPS_PER_RPM
        theta = np.concatenate([[0.0], np.cumsum(0.5 * Ts * (w[:-1] + w[1:]))])
        # from theta(-delay) = -w(0) delay: before t = 0 the drive turns at its initial speed
        return np.interp(t[1:] - delay_s, t, theta) + w[0] * delay_s

    own, other = (result.load_speed_rpm, result.speed_rpm)[:: 1 if feedback == "load" else -1]
    twist = T_load_Nm / K
    late = t[1:] > 0.4
    one_count = 2 * math.pi / counts_per_rev
    assert np.max(np.abs(counted - angle(own))) < one_count + 0.02 * twist
    assert np.min(np.abs(counted - angle(other))[late]) > 0.8 * twist
