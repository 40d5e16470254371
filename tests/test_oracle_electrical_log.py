"""The reference simulator of the electrical drive (tests/oracles/electrical_log.py) checked from outside.

Truth here: the exact discrete map of the linear machine over a period (``scipy.linalg.expm`` of
eq 1 augmented with the rotating rotor-frame voltage, no ODE solver), the period mean of a voltage
held in the stator frame (derived by hand below), the phasor equations of eq 1, the power balance,
the hexagon of the dead-time error vector, and the saturation law differentiated numerically.

The mean over a period of the rotor-frame voltage ``U0 exp(-j w_e tau)``, tau in [0, Ts), is

    (1 / Ts) int_0^Ts U0 exp(-j w_e tau) d tau = U0 exp(-j w_e Ts / 2) sinc(w_e Ts / 2),

with sinc(x) = sin(x) / x. The reference of sample k, turned at theta_k + X w_e Ts and applied from
theta_{k+d} = theta_k + d w_e Ts on, starts its period at U0 = u_ref exp(j (X - d) w_e Ts), so

    mean(u_dq over its period) = u_ref sinc(w_e Ts / 2) exp(j (X - d - 1/2) w_e Ts).

X = d + 1/2 (0.5 with d = 0, 1.5 with d = 1) leaves only the sinc: the logged reference is the
mean applied voltage divided by sinc(w_e Ts / 2).
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from oracles.electrical_log import Machine, simulate_log, write_csv

RADPS_PER_RPM = 2.0 * math.pi / 60.0

#: A salient machine at a speed where the rotor turns 0.42 rad in a period of 100 us.
SALIENT = Machine(Rs_ohm=1.0, Ld_H=1.0e-3, Lq_H=2.5e-3, psi_f_Wb=0.05, pole_pairs=4)
TS = 1e-4
SPEED_RPM = 10_000.0
W_E = SALIENT.pole_pairs * RADPS_PER_RPM * SPEED_RPM


def run(machine=SALIENT, *, t_end_s=0.1, speed=SPEED_RPM, i_ref=(-3.0, 8.0), u_dc_V=1200.0, **kwargs):
    return simulate_log(
        machine,
        Ts_s=TS,
        t_end_s=t_end_s,
        speed_rpm=speed if callable(speed) else (lambda t: speed),
        i_ref_A=i_ref if callable(i_ref) else (lambda t: i_ref),
        u_dc_V=u_dc_V,
        **kwargs,
    )


def period_map(machine, w_e, Ts, stator_hold=True):
    """The exact map over one period of z = [psi_d, psi_q, u_d, u_q, 1] for a linear machine at a
    constant speed: eq 1 with the rotor-frame voltage of a held stator-frame vector, du/dt = -j w_e u
    (``stator_hold``), or of a held rotor-frame vector, du/dt = 0."""
    w_u = w_e if stator_hold else 0.0
    Rs, Ld, Lq, psi_f = machine.Rs_ohm, machine.Ld_H, machine.Lq_H, machine.psi_f_Wb
    A = np.array(
        [
            [-Rs / Ld, w_e, 1.0, 0.0, Rs * psi_f / Ld],  # d psi_d = u_d - Rs (psi_d - psi_f) / Ld + w_e psi_q
            [-w_e, -Rs / Lq, 0.0, 1.0, 0.0],  # d psi_q = u_q - Rs psi_q / Lq - w_e psi_d
            [0.0, 0.0, 0.0, w_u, 0.0],
            [0.0, 0.0, -w_u, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 0.0],
        ]
    )
    return expm(A * Ts)


def complex_of(log, d_key, q_key):
    return log[d_key] + 1j * log[q_key]


@pytest.mark.parametrize("lead, delay", [(0.0, 0), (0.5, 0), (1.5, 1), (None, 0), (None, 1)])
def test_steady_state_is_the_periodic_solution_of_eq1(lead, delay):
    log = run(angle_lead_samples=lead, voltage_delay_samples=delay)
    id_ref, iq_ref = -3.0, 8.0
    assert log["id_true_A"][-1] == pytest.approx(id_ref, abs=1e-9)
    assert log["iq_true_A"][-1] == pytest.approx(iq_ref, abs=1e-9)
    # the rotor-frame voltage U0 at the start of the period that makes the sampled currents periodic
    m = SALIENT
    Phi = period_map(m, W_E, TS, stator_hold=lead is not None)
    psi0 = np.array([m.Ld_H * id_ref + m.psi_f_Wb, m.Lq_H * iq_ref])
    U0 = np.linalg.solve(Phi[:2, 2:4], psi0 - Phi[:2, :2] @ psi0 - Phi[:2, 4])
    # a stator-frame hold starts the period at u_ref exp(j (X - d) w_e Ts); a rotor-frame hold at u_ref
    u_ref = complex(*U0) * (1.0 if lead is None else np.exp(-1j * (lead - delay) * W_E * TS))
    assert log["ud_V"][-1] == pytest.approx(u_ref.real, rel=1e-8)
    assert log["uq_V"][-1] == pytest.approx(u_ref.imag, rel=1e-8)


@pytest.mark.parametrize("lead, delay", [(0.0, 0), (0.5, 0), (1.5, 1), (2.0, 1), (None, 0), (None, 1)])
def test_mean_applied_voltage_is_the_reference_times_sinc_and_rotation(lead, delay):
    log = run(t_end_s=0.02, angle_lead_samples=lead, voltage_delay_samples=delay, i_ref=lambda t: (-3.0, 8.0 + 40 * t))
    assert not log["voltage_limited"].any()
    x = W_E * TS
    factor = 1.0 if lead is None else math.sin(x / 2) / (x / 2) * np.exp(1j * (lead - delay - 0.5) * x)
    u_ref = complex_of(log, "ud_V", "uq_V")
    u_mean = complex_of(log, "ud_mean_V", "uq_mean_V")
    # every period, the transient included (the reference of row k applies over period k + d)
    n = len(u_ref)
    np.testing.assert_allclose(u_mean[delay:], u_ref[: n - delay] * factor, rtol=1e-9, atol=1e-9)
    if delay:
        assert u_mean[0] == 0.0
    if lead == delay + 0.5:
        np.testing.assert_allclose(u_ref[: n - delay], u_mean[delay:] / (math.sin(x / 2) / (x / 2)), rtol=1e-9)


def test_phasor_equations_of_eq1_hold_for_the_period_means():
    # X = 0.5, d = 0: the logged reference times sinc(w_e Ts / 2) is the mean voltage of eq 1's phasors
    log = run(angle_lead_samples=0.5)
    m, x = SALIENT, W_E * TS
    u = complex_of(log, "ud_V", "uq_V")[-1] * math.sin(x / 2) / (x / 2)
    i_d, i_q = log["id_mean_A"][-1], log["iq_mean_A"][-1]
    assert u.real == pytest.approx(m.Rs_ohm * i_d - W_E * m.Lq_H * i_q, rel=1e-8)
    assert u.imag == pytest.approx(m.Rs_ohm * i_q + W_E * (m.Ld_H * i_d + m.psi_f_Wb), rel=1e-8)
    # the sampled currents differ from the means by the ripple the turning voltage drives
    assert abs(log["iq_true_A"][-1] - i_q) > 1e-3


@pytest.mark.parametrize("lead, delay", [(0.5, 0), (1.5, 1), (None, 1)])
def test_transient_follows_the_exact_period_map(lead, delay):
    """Every sampled current of a run with current steps against the expm map, period by period."""
    m = SALIENT
    log = run(
        t_end_s=0.01,
        angle_lead_samples=lead,
        voltage_delay_samples=delay,
        i_ref=lambda t: (-3.0 if t > 0.004 else 0.0, 8.0 if t > 0.001 else 2.0),
        theta_e0_rad=0.7,
    )
    Phi = period_map(m, W_E, TS, stator_hold=lead is not None)
    n = len(log["time_s"])
    theta = 0.7 + W_E * TS * np.arange(n)
    # the held vector of each reference, in the frame it is held in
    u_held = complex_of(log, "ud_V", "uq_V")
    if lead is not None:
        u_held = u_held * np.exp(1j * (theta + lead * W_E * TS))
    psi = np.array([m.psi_f_Wb, 0.0])
    for k in range(n):
        i_d, i_q = (psi[0] - m.psi_f_Wb) / m.Ld_H, psi[1] / m.Lq_H
        assert log["id_true_A"][k] == pytest.approx(i_d, abs=1e-7)
        assert log["iq_true_A"][k] == pytest.approx(i_q, abs=1e-7)
        if k < delay:
            u0 = 0.0
        else:
            u0 = u_held[k - delay] * (1.0 if lead is None else np.exp(-1j * theta[k]))
        psi = (Phi @ np.array([psi[0], psi[1], u0.real, u0.imag, 1.0]))[:2]


@pytest.mark.parametrize("machine", [SALIENT, Machine(1.0, 1.0e-3, 2.5e-3, 0.05, 4, sat_q=0.8, psi_q_sat_Wb=0.02)])
def test_energy_balance(machine):
    """(3/2) int u.i = copper losses + (3/2) int w_e (psi_d i_q - psi_q i_d) + change of magnetic energy,
    with dead time, the clip and a speed ramp on (the balance holds whatever the voltage)."""
    log = run(
        machine,
        t_end_s=0.02,
        speed=lambda t: SPEED_RPM * t / 0.02,
        i_ref=lambda t: (-3.0, 30.0 if 0.005 < t < 0.012 else 5.0),
        u_dc_V=300.0,
        dead_time_V=2.0,
        voltage_delay_samples=1,
        angle_lead_samples=1.5,
    )
    assert log["voltage_limited"].any()
    m = machine

    def magnetic_energy(psi_d, psi_q):
        # (3/2) (int i_d d psi_d + int i_q d psi_q): the q co-law integrated by hand
        a = m.sat_q / m.psi_q_sat_Wb**2
        w_q = psi_q**2 / (2 * m.Lq_H) + a * psi_q**4 / (4 * m.Lq_H)
        return 1.5 * ((psi_d - m.psi_f_Wb) ** 2 / (2 * m.Ld_H) + w_q)

    W = magnetic_energy(log["psi_d_Wb"], log["psi_q_Wb"])
    E_in, E_cu, E_mech = log["energy_in_J"], log["energy_copper_J"], log["energy_mech_J"]
    balance = E_in - (E_cu + E_mech + W - W[0])
    assert np.max(np.abs(balance)) < 1e-8 * np.max(np.abs(E_in))
    assert E_cu[-1] > 0.0 and np.max(np.abs(W - W[0])) > 1e-3 * E_in[-1]


@pytest.mark.parametrize(
    "theta0, current_angle, error_angle",
    [
        (0.0, 0.0, 0.0),  # phases a, b, c carry +, -, -: the error is the a-axis vector
        (0.0, math.pi / 4, math.pi / 3),  # +, +, -: the vector between a and -c, at 60 deg in the stator frame
        (1.0, 0.0, math.pi / 3 - 1.0),  # stator current angle 1 rad: +, +, -, seen from the rotor frame
    ],
)
def test_dead_time_error_is_the_hexagon_vector(theta0, current_angle, error_angle):
    """At standstill, a DC current: the steady reference is Rs i plus the dead-time error vector,
    4/3 dead_time_V at the sector's vector (amplitude-invariant Clarke of -V sign(i_abc))."""
    dead_time_V, i_abs = 1.5, 6.0
    i_ref = (i_abs * math.cos(current_angle), i_abs * math.sin(current_angle))
    log = run(t_end_s=0.05, speed=0.0, i_ref=i_ref, dead_time_V=dead_time_V, theta_e0_rad=theta0)
    u_ref = complex_of(log, "ud_V", "uq_V")[-1]
    rs_i = SALIENT.Rs_ohm * complex(*i_ref)
    expected = rs_i + 4.0 / 3.0 * dead_time_V * np.exp(1j * error_angle)
    assert u_ref.real == pytest.approx(expected.real, abs=1e-9)
    assert u_ref.imag == pytest.approx(expected.imag, abs=1e-9)
    # what the machine sees is Rs i alone
    assert complex_of(log, "ud_mean_V", "uq_mean_V")[-1] == pytest.approx(rs_i, abs=1e-9)


def test_clip_flags_exactly_the_periods_beyond_the_linear_range():
    u_dc = 400.0
    # a q-current step the back-EMF leaves too little voltage for
    log = run(t_end_s=0.05, u_dc_V=u_dc, i_ref=lambda t: (-3.0, 60.0 if 0.005 < t < 0.008 else 8.0))
    u_ref = complex_of(log, "ud_V", "uq_V")
    beyond = np.abs(u_ref) > u_dc / math.sqrt(3.0)
    assert 0 < beyond.sum() < len(beyond) // 2
    np.testing.assert_array_equal(log["voltage_limited"], beyond.astype(float))
    np.testing.assert_array_equal(log["udc_V"], u_dc)
    # the inverter applied the circle's radius on those periods (X = 0.5, d = 0: mean = vector sinc)
    x = W_E * TS
    u_mean = np.abs(complex_of(log, "ud_mean_V", "uq_mean_V"))
    applied = np.where(beyond, u_dc / math.sqrt(3.0), np.abs(u_ref))
    np.testing.assert_allclose(u_mean, applied * math.sin(x / 2) / (x / 2), rtol=1e-9)
    # the anti-windup lets the current settle back without a windup overshoot
    assert log["iq_true_A"][-1] == pytest.approx(8.0, abs=1e-6)
    after = log["time_s"] > 0.008
    assert np.max(log["iq_true_A"][after]) < 1.02 * 8.0


def test_saturation_inductances_against_numerical_differentiation():
    m = Machine(1.0, 1.0e-3, 2.5e-3, 0.05, 4, sat_q=0.8, psi_q_sat_Wb=0.02)

    def iq_of(psi_q):  # the law of the brief, written out here
        return psi_q / 2.5e-3 * (1.0 + 0.8 * (psi_q / 0.02) ** 2)

    for psi_q in (-0.03, -0.004, 0.001, 0.02, 0.05):
        iq = iq_of(psi_q)
        h = 1e-7
        assert m.Lq_apparent_H(iq) == pytest.approx(psi_q / iq, rel=1e-12)
        assert m.Lq_incremental_H(iq) == pytest.approx(2 * h / (iq_of(psi_q + h) - iq_of(psi_q - h)), rel=1e-8)
        assert m.Lq_incremental_H(iq) < m.Lq_apparent_H(iq) < m.Lq_H
    linear = Machine(0.3, 1.0e-3, 2.5e-3, 0.05, 4)
    for iq in (-20.0, 0.0, 3.0):
        assert linear.Lq_apparent_H(iq) == linear.Lq_H == linear.Lq_incremental_H(iq)
    assert m.Lq_apparent_H(0.0) == m.Lq_incremental_H(0.0) == m.Lq_H


def test_saturating_machine_holds_the_flux_its_voltages_integrate():
    """At standstill the q flux is the integral of u_q - Rs i_q (eq 1, no rotation term): it must
    match the law's flux at the final current."""
    m = Machine(1.0, 1.0e-3, 2.5e-3, 0.05, 4, sat_q=0.8, psi_q_sat_Wb=0.02)
    log = run(m, speed=0.0, i_ref=(0.0, 25.0))
    psi_q = np.sum(log["uq_mean_V"] - m.Rs_ohm * log["iq_mean_A"]) * TS
    iq_end = log["iq_true_A"][-1]
    roots = np.roots([0.8 / 0.02**2 / 2.5e-3, 0.0, 1 / 2.5e-3, -iq_end])  # i_q(psi_q) = iq_end
    psi_law = roots[np.abs(roots.imag) < 1e-9].real[0]
    assert iq_end == pytest.approx(25.0, abs=1e-6)
    assert psi_q == pytest.approx(psi_law, rel=1e-7)
    assert psi_law < 0.8 * m.Lq_H * iq_end  # saturated: well below the linear flux


def test_noise_is_seeded_and_of_the_rms_asked():
    a = run(t_end_s=0.05, noise_A=0.2, seed=3)
    b = run(t_end_s=0.05, noise_A=0.2, seed=3)
    c = run(t_end_s=0.05, noise_A=0.2, seed=4)
    np.testing.assert_array_equal(a["id_A"], b["id_A"])
    assert not np.array_equal(a["id_A"], c["id_A"])
    noise = np.concatenate([a["id_A"] - a["id_true_A"], a["iq_A"] - a["iq_true_A"]])
    assert np.std(noise) == pytest.approx(0.2, rel=0.05)  # 1000 samples: 2.2 % standard error


def test_csv_is_what_read_log_reads(tmp_path):
    from pmsm2dof.sim.logs import read_log

    log = run(t_end_s=0.01, noise_A=0.05)
    path = tmp_path / "drive.csv"
    write_csv(log, path)
    read = read_log(path)
    np.testing.assert_array_equal(read.t_s, log["time_s"])
    for name in ("speed_rpm", "id_A", "iq_A", "ud_V", "uq_V"):
        np.testing.assert_array_equal(getattr(read, name), log[name])
    np.testing.assert_array_equal(read.u_dc_V, log["udc_V"])
    assert read.notes == ()
    header = path.read_text().splitlines()[0]
    assert header == "time_s,speed_rpm,id_A,iq_A,ud_V,uq_V,u_dc_V,voltage_limited"


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"Ts_s": 0.0}, "Ts_s"),
        ({"voltage_delay_samples": 2}, "voltage_delay_samples"),
        ({"dead_time_V": -1.0}, "dead_time_V"),
        ({"u_dc_V": float("nan")}, "u_dc_V"),
        ({"alpha_c_radps": -5.0}, "alpha_c_radps"),
    ],
)
def test_bad_arguments_are_named(kwargs, name):
    args = {"Ts_s": TS, "t_end_s": 0.01, "speed_rpm": lambda t: 0.0, "i_ref_A": lambda t: (0.0, 0.0), "u_dc_V": 300.0}
    with pytest.raises(ValueError, match=name):
        simulate_log(SALIENT, **(args | kwargs))
    with pytest.raises(ValueError, match="Lq_H"):
        Machine(0.3, 1e-3, -1e-3, 0.05, 4)


def test_angle_is_the_integral_of_a_piecewise_linear_speed():
    """theta_e = theta_0 + p 2 pi / 60 int speed_rpm dt, integrated by hand for a ramp then a hold."""
    t_ramp, top_rpm = 0.004, 6000.0
    log = run(t_end_s=0.01, speed=lambda t: top_rpm * min(t, t_ramp) / t_ramp, theta_e0_rad=0.3)
    t = log["time_s"]
    turns = np.where(t < t_ramp, top_rpm * t**2 / (2 * t_ramp), top_rpm * (t - t_ramp / 2))
    theta = 0.3 + SALIENT.pole_pairs * RADPS_PER_RPM * turns
    np.testing.assert_allclose(np.exp(1j * log["theta_e_rad"]), np.exp(1j * theta), atol=1e-9)
    assert np.all((0.0 <= log["theta_e_rad"]) & (log["theta_e_rad"] < 2 * math.pi))
    np.testing.assert_array_equal(log["speed_rpm"], top_rpm * np.minimum(t, t_ramp) / t_ramp)


@pytest.mark.parametrize("delay", [0, 1])
def test_rotor_frame_hold_agrees_with_the_fitter_checked_on_engine_logs(tmp_path, delay):
    """Cross-check of conventions (amplitude-invariant dq, signs, the delay of the logged voltage):
    in the engine's convention (angle_lead_samples=None) the oracle's log gives the fitter, which
    tests/test_identify_electrical.py checks on the engine's logs, the machine within issue 20's targets."""
    from pmsm2dof.sim.logs import read_log
    from pmsm2dof.studies.electrical import identify_electrical

    m = Machine(Rs_ohm=0.8, Ld_H=4e-3, Lq_H=8e-3, psi_f_Wb=0.05, pole_pairs=4)

    def speed(t):  # a ramp to 1500 rpm, a hold, a ramp down
        return 1500.0 * min(t / 0.1, 1.0) - 600.0 * max(0.0, t - 0.25) / 0.15

    def i_ref(t):  # id steps of 1 and 2 A, iq steps and a 13 Hz sine
        k = int(t / 0.02)
        return -2.0 * (k % 3 == 1) - 1.0 * (k % 3 == 2), 2.0 + (k % 2) + 1.5 * math.sin(2 * math.pi * 13 * t)

    log = simulate_log(
        m,
        Ts_s=TS,
        t_end_s=0.4,
        speed_rpm=speed,
        i_ref_A=i_ref,
        u_dc_V=100.0,
        voltage_delay_samples=delay,
        angle_lead_samples=None,
        noise_A=0.02,
        seed=1,
    )
    write_csv(log, tmp_path / "log.csv")
    fit = identify_electrical(read_log(tmp_path / "log.csv"), m.pole_pairs, voltage_delay_samples=delay)
    for name, target in {"Rs_ohm": 0.05, "Ld_H": 0.10, "Lq_H": 0.05, "psi_f_Wb": 0.02}.items():
        assert getattr(fit, name) == pytest.approx(getattr(m, name), rel=target), name


def test_the_oracle_does_not_import_pmsm2dof():
    import ast

    import oracles.electrical_log

    tree = ast.parse(Path(oracles.electrical_log.__file__).read_text())
    imported = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    imported += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert imported and not [name for name in imported if name.split(".")[0] == "pmsm2dof"]
