"""The drive simulation engine against truths from outside it.

- an independent SciPy integration (DOP853, rtol 1e-10) of the continuous plant of eq (1),
  written here, replaying the engine's logged voltages or current commands sample-and-hold;
- the closed-loop transfer functions of the paper: the tracking response of eq (10) and the
  load response GN of eq (8) (python-control);
- the dq current loop tuned to tau_i against the first-order model of eq (3);
- the torque balance at steady state;
- convergence in the integration step;
- stops on runaway and non-finite states.
"""

import math
import re

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsm2dof.core import CurrentController, SpeedController
from pmsm2dof.core.bindings import lib
from pmsm2dof.errors import SimulationError
from pmsm2dof.sim.scenario import Scenario, load_scenario
from pmsm2dof.sim.simulate import Simulation, simulate

RADPS_PER_RPM = math.pi / 30.0


def paper2(**overrides):
    """paper-condition-2 with dotted-key overrides."""
    return load_scenario("paper-condition-2").with_overrides(overrides)


def load_torque(entries, t):
    """Piecewise-linear load of the scenario contract: 0 before the first entry; each entry moves
    from the value reached at its t_s to torque_Nm, in a step or linearly over ramp_s."""
    t0 = v0 = v1 = ramp = 0.0

    def segment(t):
        if ramp > 0.0 and t < t0 + ramp:
            return v0 + (v1 - v0) * max(t - t0, 0.0) / ramp
        return v1

    for e in entries:
        if e["t_s"] > t:
            break
        v0, t0, v1, ramp = segment(e["t_s"]), e["t_s"], e["torque_Nm"], e["ramp_s"]
    return segment(t)


def plant_rhs(data):
    """Right-hand side f(t, x, a, b) of the continuous plant, x = (id, iq, w_m).

    dq_pi: a, b are the applied voltages ud, uq and the currents follow eq (1);
    first_order: a, b are the current commands and the currents follow eq (3).
    Mechanics: J dw/dt = 1.5 p (psi_f iq + (Ld - Lq) id iq) - T_load - B w - T_c tanh(w / w_c),
    with the smoothing band w_c = max(0.01, 10 Ts_current T_c / J) documented in drive.h.
    """
    m = data["motor"]
    p, Rs, Ld, Lq, psi = m["pole_pairs"], m["Rs_ohm"], m["Ld_H"], m["Lq_H"], m["psi_f_Wb"]
    J, B, Tc = m["J_kgm2"], m["B_Nms"], m["T_coulomb_Nm"]
    w_c = max(0.01, 10.0 * data["current_loop"]["Ts_s"] * Tc / J)
    tau_i = data["current_loop"]["tau_i_s"]
    dq_pi = data["current_loop"]["model"] == "dq_pi"

    def rhs(t, x, a, b):
        i_d, i_q, w = x
        w_e = p * w
        if dq_pi:
            did = (a - Rs * i_d + w_e * Lq * i_q) / Ld
            diq = (b - Rs * i_q - w_e * (Ld * i_d + psi)) / Lq
        else:
            did = (a - i_d) / tau_i
            diq = (b - i_q) / tau_i
        Te = 1.5 * p * (psi * i_q + (Ld - Lq) * i_d * i_q)
        dw = (Te - load_torque(data["load"], t) - B * w - Tc * np.tanh(w / w_c)) / J
        return [did, diq, dw]

    return rhs


def replay(result, inputs):
    """Integrate the plant with SciPy through the logged rows, holding ``inputs[k]`` over row k.

    Starts from the engine's state in row 0; returns the states at the row times. Intervals are
    split at the load's breakpoints so that the integrator never steps over a jump.
    """
    data = result.scenario.data
    rhs = plant_rhs(data)
    breaks = sorted({e["t_s"] for e in data["load"]} | {e["t_s"] + e["ramp_s"] for e in data["load"]})
    scale = np.array([data["limits"]["i_max_A"], data["limits"]["i_max_A"], np.max(np.abs(result.w_m_radps))])
    x = np.array([result.id_A[0], result.iq_A[0], result.w_m_radps[0]])
    states = [x]
    t = result.t_s
    for k in range(len(t) - 1):
        points = [t[k]] + [b for b in breaks if t[k] < b < t[k + 1]] + [t[k + 1]]
        for ta, tb in zip(points[:-1], points[1:]):
            sol = solve_ivp(
                rhs, (ta, tb), x, method="DOP853", rtol=1e-10, atol=1e-12 * scale, args=(inputs[0][k], inputs[1][k])
            )
            x = sol.y[:, -1]
        states.append(x)
    return np.array(states)


def drive_tree(**sections):
    """A salient motor with both frictions, a fast speed loop, and the given sections replaced."""
    tree = {
        "name": "engine test drive",
        "motor": {
            "pole_pairs": 3,
            "Rs_ohm": 0.4,
            "Ld_H": 0.006,
            "Lq_H": 0.012,
            "psi_f_Wb": 0.15,
            "J_kgm2": 0.02,
            "B_Nms": 0.002,
            "T_coulomb_Nm": 0.3,
        },
        "limits": {"i_max_A": 10.0, "u_dc_V": 300.0},
        "inverter": {"computation_delay": True},
        "current_loop": {"model": "dq_pi", "tau_i_s": 0.002, "Ts_s": 1e-4},
        "speed_controller": {"alpha_radps": 20.0, "zeta": 0.7, "Ts_s": 1e-4, "feedforward": "full", "m": 2.0},
        "simulation": {"t_end_s": 0.15, "speed0_rpm": 300.0},
        "reference": [{"t_s": 0.0, "speed_rpm": 700.0}],
        # a step between samples, then a ramp whose ends fall between samples too
        "load": [{"t_s": 0.05123, "torque_Nm": 1.5}, {"t_s": 0.08, "torque_Nm": -1.0, "ramp_s": 0.0301}],
    }
    tree.update(sections)
    return tree


def test_dq_pi_matches_scipy_integration():
    """Electrical model, inverter limit, delay, saliency, frictions, off-grid load steps and ramps."""
    result = simulate(Scenario.from_dict(drive_tree()))
    assert result.saturated.any() and (~result.saturated).any()  # the current limit is exercised
    assert np.all(result.w_m_radps > 1.0)  # no zero crossing here: see the next test
    x = replay(result, (result.ud_V, result.uq_V))
    i_max = 10.0
    assert np.max(np.abs(x[:, 0] - result.id_A)) < 1e-7 * i_max
    assert np.max(np.abs(x[:, 1] - result.iq_A)) < 1e-7 * i_max
    assert np.max(np.abs(x[:, 2] - result.w_m_radps)) < 1e-7 * np.max(np.abs(result.w_m_radps))


def test_speed_reversal_through_coulomb_friction_matches_scipy():
    """Crossing zero speed, the friction changes by 2 T_c within less than one RK4 step; the
    engine's error is bounded by the friction impulse of one step, T_c dt / J."""
    tree = drive_tree(reference=[{"t_s": 0.0, "speed_rpm": -200.0}])
    result = simulate(Scenario.from_dict(tree))
    assert result.w_m_radps[0] > 0 > result.w_m_radps[-1]
    x = replay(result, (result.ud_V, result.uq_V))
    motor = tree["motor"]
    bound = motor["T_coulomb_Nm"] * tree["current_loop"]["Ts_s"] / motor["J_kgm2"]
    assert np.max(np.abs(x[:, 2] - result.w_m_radps)) < bound
    # before the crossing the agreement is as tight as without friction
    before = result.t_s < 0.07
    assert np.max(np.abs(x[before, 2] - result.w_m_radps[before])) < 1e-7 * np.max(np.abs(result.w_m_radps))


@pytest.mark.parametrize("T_coulomb_Nm", [0.0, 0.3])
@pytest.mark.parametrize("model", ["dq_pi", "first_order"])
def test_load_breakpoints_inside_a_period_match_scipy(model, T_coulomb_Nm):
    """Steps and ramp ends between the RK4 steps, two of them inside one step, a whole ramp inside
    one current period, a ramp ending on a period boundary; three RK4 steps per current period.
    Every breakpoint must split the step it falls in: a step integrated across a jump of the load
    errs by about the jump times the rest of the step over J, 1e3 times the tolerance."""
    Ts_s = 1e-4
    current_loop = {"model": model, "tau_i_s": 0.002, "Ts_s": Ts_s}
    tree = drive_tree(
        motor={**drive_tree()["motor"], "T_coulomb_Nm": T_coulomb_Nm},
        current_loop=current_loop,
        simulation={"t_end_s": 0.1, "speed0_rpm": 300.0, "dt_s": Ts_s / 3},
        load=[
            {"t_s": 0.01002, "torque_Nm": 1.5},
            {"t_s": 0.010045, "torque_Nm": -0.5, "ramp_s": 0.00003},
            {"t_s": 0.02, "torque_Nm": 1.0, "ramp_s": 0.03001},
            {"t_s": 0.060031, "torque_Nm": -1.0},
            {"t_s": 0.060042, "torque_Nm": 0.5},
            {"t_s": 0.07, "torque_Nm": 0.0, "ramp_s": 0.01},
        ],
    )
    result = simulate(Scenario.from_dict(tree))
    inputs = (result.ud_V, result.uq_V) if model == "dq_pi" else (result.id_ref_A, result.iq_ref_A)
    x = replay(result, inputs)
    assert np.max(np.abs(x[:, 0] - result.id_A)) < 1e-7 * 10.0
    assert np.max(np.abs(x[:, 1] - result.iq_A)) < 1e-7 * 10.0
    assert np.max(np.abs(x[:, 2] - result.w_m_radps)) < 1e-7 * np.max(np.abs(result.w_m_radps))


def test_voltage_range_decided_as_hypot():
    """The share of periods beyond the inverter's range is hypot(ud, uq) > u_dc / sqrt(3) exactly,
    also for vectors within a few ulp of the range (where the engine's shortcut through the sum of
    squares must hand over to hypot). The first_order drive does not depend on u_dc, so u_dc is
    set so that chosen rows sit 0, 1 and 2 ulp on either side of the range."""
    inv_sqrt3 = 0.57735026918962576  # the engine's 1/sqrt(3)
    current_loop = {"model": "first_order", "tau_i_s": 0.002, "Ts_s": 1e-4}
    tree = drive_tree(current_loop=current_loop, simulation={"t_end_s": 0.1, "speed0_rpm": 300.0})
    first = simulate(Scenario.from_dict(tree))
    norms = np.hypot(first.ud_V, first.uq_V)
    rows = [int(np.argmax(norms)), int(np.argmin(norms)), len(norms) // 2]
    for k in rows:
        u_dc = norms[k] / inv_sqrt3
        for step in (-2, -1, 0, 1, 2):
            u_dc_k = u_dc + step * np.spacing(u_dc)
            r = simulate(Scenario.from_dict({**tree, "limits": {"i_max_A": 10.0, "u_dc_V": u_dc_k}}))
            np.testing.assert_array_equal(r.ud_V, first.ud_V)
            beyond = np.hypot(r.ud_V, r.uq_V) > u_dc_k * inv_sqrt3
            np.testing.assert_array_equal(r.voltage_limited, beyond.astype(float))
        # the steps straddle the range at row k
        assert np.hypot(first.ud_V[k], first.uq_V[k]) > (u_dc - 2 * np.spacing(u_dc)) * inv_sqrt3
        assert np.hypot(first.ud_V[k], first.uq_V[k]) <= (u_dc + 2 * np.spacing(u_dc)) * inv_sqrt3


@pytest.mark.parametrize("delay", [False, True])
def test_loop_feeds_the_controllers_the_sampled_state(delay):
    """The controllers, stepped here by hand from the logged states (speed and current at the same
    period, 100 us), give the logged commands; the inverter applies the current controller's
    command in the same period, or with the computation delay one period later (0 V first, the
    steady state at rest). u_dc = 60 V puts the voltage limit in play."""
    tree = drive_tree(
        inverter={"computation_delay": delay},
        limits={"i_max_A": 10.0, "u_dc_V": 60.0},
        simulation={"t_end_s": 0.1, "speed0_rpm": 0.0},
    )
    r = simulate(Scenario.from_dict(tree))
    m = tree["motor"]
    speed = SpeedController(
        J_kgm2=m["J_kgm2"],
        alpha_radps=20.0,
        zeta=0.7,
        m=2.0,
        tau_i_s=0.002,
        Ts_s=1e-4,
        i_max_A=10.0,
        psi_f_Wb=m["psi_f_Wb"],
        Ld_H=m["Ld_H"],
        Lq_H=m["Lq_H"],
        pole_pairs=m["pole_pairs"],
        feedforward="full",
    )
    current = CurrentController(
        Rs_ohm=m["Rs_ohm"], Ld_H=m["Ld_H"], Lq_H=m["Lq_H"], psi_f_Wb=m["psi_f_Wb"], tau_i_s=0.002, Ts_s=1e-4
    )
    u_max = 60.0 / math.sqrt(3)
    applied = np.zeros((len(r.t_s), 2))
    previous = (0.0, 0.0)
    for k in range(len(r.t_s)):
        so = speed.step(r.speed_ref_rpm[k] * RADPS_PER_RPM, r.w_m_radps[k])
        assert (so.id_ref_A, so.iq_ref_A, so.T_ref_Nm, so.T_unsat_Nm) == (
            r.id_ref_A[k],
            r.iq_ref_A[k],
            r.torque_ref_Nm[k],
            r.torque_unsat_Nm[k],
        )
        assert speed.x_i_Nm == r.x_i_Nm[k]
        assert so.saturated == r.saturated[k]
        co = current.step(so.id_ref_A, so.iq_ref_A, r.id_A[k], r.iq_A[k], m["pole_pairs"] * r.w_m_radps[k], 60.0)
        command = (co.ud_ref_V, co.uq_ref_V)
        applied[k] = previous if delay else command
        previous = command
    # the engine's inverter limits the float32 command again in double: equal to float32 rounding
    np.testing.assert_allclose(np.c_[r.ud_V, r.uq_V], applied, rtol=0, atol=1e-6 * u_max)
    assert np.any(np.hypot(r.ud_V, r.uq_V) > (1 - 1e-6) * u_max)  # the voltage limit was reached
    assert np.all(np.hypot(r.ud_V, r.uq_V) <= u_max * (1 + 1e-12))


def test_first_order_multirate_matches_scipy_integration():
    """Eq (3) current loop, speed controller at 10 current periods, current commands replayed."""
    tree = drive_tree(
        current_loop={"model": "first_order", "tau_i_s": 0.002, "Ts_s": 1e-4},
        speed_controller={"alpha_radps": 20.0, "zeta": 0.7, "Ts_s": 1e-3, "feedforward": "lowpass"},
        simulation={"t_end_s": 0.3, "speed0_rpm": 300.0},
    )
    result = simulate(Scenario.from_dict(tree))
    assert result.saturated.any()
    x = replay(result, (result.id_ref_A, result.iq_ref_A))
    assert np.max(np.abs(x[:, :2] - np.c_[result.id_A, result.iq_A])) < 1e-7 * 10.0
    assert np.max(np.abs(x[:, 2] - result.w_m_radps)) < 1e-7 * np.max(np.abs(result.w_m_radps))
    # the logged voltage is what eq (1) needs for the current slopes of eq (3)
    m, tau = tree["motor"], 0.002
    w_e = m["pole_pairs"] * result.w_m_radps
    ud = m["Rs_ohm"] * result.id_A + m["Ld_H"] * (result.id_ref_A - result.id_A) / tau - w_e * m["Lq_H"] * result.iq_A
    uq = (
        m["Rs_ohm"] * result.iq_A
        + m["Lq_H"] * (result.iq_ref_A - result.iq_A) / tau
        + w_e * (m["Ld_H"] * result.id_A + m["psi_f_Wb"])
    )
    np.testing.assert_allclose(result.ud_V, ud, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(result.uq_V, uq, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("m", [0.5, 1.0, 2.0])
def test_linear_tracking_follows_eq10(m):
    """Small step, first_order loop, full feedforward (eq 11): w = w_step (1 - exp(-m alpha t)).

    The only departure is the sampling of the speed controller, a half-sample delay of the
    torque: |error| <~ m alpha Ts / 2 of the step; allowed m alpha Ts.
    """
    Ts, alpha = 1e-3, 0.5
    result = simulate(
        paper2(
            **{
                "current_loop.model": "first_order",
                "speed_controller.feedforward": "full",
                "speed_controller.m": m,
                "reference": [{"t_s": 0.0, "speed_rpm": 1.0}],
                "load": [],
                "simulation.t_end_s": 12.0,
            }
        )
    )
    assert not result.saturated.any()
    w_step = 1.0 * RADPS_PER_RPM
    ideal = w_step * (1.0 - np.exp(-m * alpha * result.t_s))
    assert np.max(np.abs(result.w_m_radps - ideal)) < m * alpha * Ts * w_step


def test_load_step_independent_of_feedforward_and_matches_GN():
    """Eq (5)-(8): the load response depends on F only. From steady state at 300 rpm, a small load
    step gives the same speed dip for every feedforward, and the dip is GN(s) of eq (8) driven by
    the load: GN = -(tau s^2 + s) / (J tau s^3 + J s^2 + Kp s + Ki)."""
    J, tau, alpha, zeta = 0.4, 0.05, 0.5, 0.28867513459481287
    Kp, Ki = J * alpha, J * (alpha / (2 * zeta)) ** 2  # eq 9
    w0 = 300.0 * RADPS_PER_RPM
    runs = {}
    for ff in ("none", "lowpass", "full"):
        runs[ff] = simulate(
            paper2(
                **{
                    "current_loop.model": "first_order",
                    "speed_controller.feedforward": ff,
                    "simulation.speed0_rpm": 300.0,
                    "reference": [{"t_s": 0.0, "speed_rpm": 300.0}],
                    "load": [{"t_s": 1.0, "torque_Nm": 0.5}],
                    "simulation.t_end_s": 20.0,
                }
            )
        )
        assert not runs[ff].saturated.any()
    dw = runs["none"].w_m_radps - w0
    dip = np.max(np.abs(dw))
    assert dip > 0.5  # a visible dip [rad/s]
    # equal up to the float32 rounding of the controller's integrator, which holds the
    # feedforward's DC part (-Ki/alpha w0 = -19 Nm for lowpass) and so rounds the increments
    for ff in ("lowpass", "full"):
        assert np.max(np.abs(runs[ff].w_m_radps - runs["none"].w_m_radps)) < 2e-3 * dip
    GN = control.tf([-tau, -1.0, 0.0], [J * tau, J, Kp, Ki])
    response = control.forced_response(GN, T=runs["none"].t_s, U=runs["none"].load_Nm)
    assert np.max(np.abs(response.outputs - dw)) < 5e-3 * dip


def test_dq_pi_tuned_to_tau_i_agrees_with_first_order():
    """The dq PIs (Kp = L/tau_i, Ki = Rs/tau_i, decoupled) close the current loop as eq (3); the
    sampled loop lags the continuous one by about Ts/2, i.e. Ts/(2 tau_i) = 1e-3 of a current step."""
    dq = simulate(paper2())
    fo = simulate(paper2(**{"current_loop.model": "first_order"}))
    assert dq.saturated.any()  # through the saturated start, the load step and the step down
    assert np.max(np.abs(dq.w_m_radps - fo.w_m_radps)) < 1e-4 * np.max(np.abs(fo.w_m_radps))
    Ts, tau_i, i_max = 1e-4, 0.05, 7.6
    assert np.max(np.abs(dq.iq_A - fo.iq_A)) < 2 * Ts / tau_i * i_max
    assert np.max(np.abs(dq.id_A)) < 2 * Ts / tau_i * i_max


@pytest.mark.parametrize("model", ["dq_pi", "first_order"])
def test_steady_state_torque_balances_load_and_friction(model):
    """At constant speed J dw/dt = 0: Te = T_load + B w + T_c (eq 1 with friction).

    1DOF (feedforward none) so that the float32 integrator holds only the load torque; with the
    lowpass feedforward it also holds Ki/alpha w_ref (188 Nm here), whose float32 spacing leaves a
    dead band of ~1e-4 rad/s in the integral action, a property of the deployable controller.
    """
    B, Tc, load = 0.02, 0.5, 3.0
    result = simulate(
        paper2(
            **{
                "current_loop.model": model,
                "motor.B_Nms": B,
                "motor.T_coulomb_Nm": Tc,
                "speed_controller.feedforward": "none",
                "speed_controller.alpha_radps": 5.0,
                "speed_controller.zeta": 0.7,
                "simulation.speed0_rpm": 300.0,
                "reference": [{"t_s": 0.0, "speed_rpm": 300.0}],
                "load": [{"t_s": 0.5, "torque_Nm": load}],
                "simulation.t_end_s": 8.0,
            }
        )
    )
    w = result.w_m_radps[-1]
    assert w == pytest.approx(300.0 * RADPS_PER_RPM, rel=1e-5)
    assert np.ptp(result.w_m_radps[-1000:]) < 1e-6 * w  # settled: constant speed over the last second
    # far outside the friction band, tanh(w / w_c) = 1
    assert result.torque_Nm[-1] == pytest.approx(load + B * w + Tc, rel=1e-5)
    # and the torque is 1.5 p psi_f iq of the surface motor
    assert result.torque_Nm[-1] == pytest.approx(1.5 * 4 * 0.2 * result.iq_A[-1], rel=1e-12)


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {
            "inverter.computation_delay": True,
            "motor.Ld_H": 0.008,
            "motor.Lq_H": 0.012,
            "load": [{"t_s": 7.00037, "torque_Nm": 8.0, "ramp_s": 0.5}],
        },
    ],
)
def test_halving_the_step_changes_the_speed_by_less_than_1e_4(overrides):
    base = paper2(**overrides)
    dt = base.data["simulation"]["dt_s"]
    assert dt == base.data["current_loop"]["Ts_s"]  # the default: one RK4 step per current period
    a = simulate(base)
    b = simulate(base.with_overrides({"simulation.dt_s": dt / 2}))
    assert np.max(np.abs(a.w_m_radps - b.w_m_radps)) < 1e-4 * np.max(np.abs(b.w_m_radps))


def test_runaway_under_overhauling_load_stops_with_the_time():
    """A load beyond the torque limit drives the motor up to twice its no-load speed."""
    scenario = paper2(
        **{
            "motor.J_kgm2": 0.05,
            "load": [{"t_s": 0.5, "torque_Nm": -60.0}],
            "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
            "simulation.t_end_s": 5.0,
        }
    )
    no_load_rpm = 540.0 / math.sqrt(3) / (4 * 0.2) / RADPS_PER_RPM
    # said as the load above the peak torque 1.5 p psi_f i_max = 1.5 * 4 * 0.2 * 7.6 = 9.12 Nm that it is
    match = r"stopped at t = [0-9.]+ s: the load load.0.torque_Nm = -60 Nm is above the peak torque 9.12 Nm .*twice"
    with pytest.raises(SimulationError, match=match) as err:
        simulate(scenario)
    t_stop = float(str(err.value).split("t = ")[1].split(" s")[0])
    # after the load step, and no sooner than the load plus the whole torque limit
    # (1.2 Nm/A * 7.6 A) could accelerate J from the reference to the bound
    w_bound = 2 * no_load_rpm * RADPS_PER_RPM
    assert 0.5 + (w_bound - 500 * RADPS_PER_RPM) * 0.05 / (60 + 1.2 * 7.6) < t_stop < 5.0
    assert f"{2 * no_load_rpm:.6g} rpm" in str(err.value)


@pytest.mark.parametrize(
    ("t_load_s", "t_stop"),
    [
        ("0.5", "0.5001"),  # the first period of a speed sample
        ("0.50037", "0.5004"),  # inside one: the stop ends the period the load enters in, not the sample
    ],
)
def test_non_finite_state_stops(t_load_s, t_stop):
    with pytest.raises(SimulationError, match=rf"t = {re.escape(t_stop)} s: the plant state became non-finite"):
        simulate(
            paper2(
                **{
                    "load": [{"t_s": float(t_load_s), "torque_Nm": 1e308}],
                    "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
                    "simulation.t_end_s": 1.0,
                }
            )
        )


def test_overcurrent_stops():
    """A current controller tuned for 1000 times the plant's inductance: with the computation
    delay the loop is unstable and the voltage bangs between the limits, driving currents far
    beyond ten times the short-circuit current of this low-flux plant."""
    run = Simulation(
        paper2(
            **{
                "inverter.computation_delay": True,
                "simulation.t_end_s": 0.1,
                "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
                "load": [],
            }
        )
    )
    run.cfg.motor.Ld_H = run.cfg.motor.Lq_H = 1e-5
    run.cfg.motor.psi_f_Wb = 1e-4
    assert lib.p2d_sim_init(run.sim, run.cfg) == lib.P2D_SIM_OK
    with pytest.raises(SimulationError, match=r"the current exceeds ten times .*: \|\|i_dq\|\| = [0-9.e+]+ A > 100 A"):
        run.advance(run.n_samples)
