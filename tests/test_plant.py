"""The drive's plant as a virtual motor (csrc/sim/plant.h), through the interface a board uses.

Truth from outside the code under test: SciPy integrations (DOP853) of eq 1, the mechanics and
the stator-frame voltage of the duty cycles, written here; the amplitude-invariant phase
currents and the encoder counts computed here from the state; the sample statistics of the
sensor noise.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from pmsm2dof.core.bindings import c_string, ffi, lib

TS = 1e-4
#: A salient motor with both frictions.
MOTOR = {
    "pole_pairs": 3,
    "Rs_ohm": 0.4,
    "Ld_H": 0.006,
    "Lq_H": 0.012,
    "psi_f_Wb": 0.15,
    "J_kgm2": 0.002,
    "B_Nms": 0.001,
    "T_coulomb_Nm": 0.05,
}


def plant(**fields):
    """An initialized plant (cffi) of MOTOR at 300 V, TS, 2 RK4 steps per period, and ``fields``."""
    cfg = ffi.new("p2d_plant_config_t *")
    for key, value in MOTOR.items():
        setattr(cfg.motor, key, value)
    cfg.u_dc_V = 300.0
    cfg.Ts_s = TS
    cfg.substeps = 2
    cfg.w_m0_radps = 50.0
    for key, value in fields.items():
        target, name = (cfg, key) if "." not in key else (getattr(cfg, key.split(".")[0]), key.split(".")[1])
        setattr(target, name, value)
    p = ffi.new("p2d_plant_t *")
    status = lib.p2d_plant_init(p, cfg)
    assert status == lib.P2D_PLANT_OK, c_string(lib.p2d_plant_status_param(status))
    return p


def eq1_rhs(u_dq, T_load_Nm):
    """d(id, iq, w_m, theta_m)/dt of eq 1 and the rigid mechanics; u_dq(t, x) gives (ud, uq)."""
    m = MOTOR
    p, Rs, Ld, Lq, psi = m["pole_pairs"], m["Rs_ohm"], m["Ld_H"], m["Lq_H"], m["psi_f_Wb"]
    w_c = max(0.01, 10 * TS * m["T_coulomb_Nm"] / m["J_kgm2"])

    def rhs(t, x):
        i_d, i_q, w, _ = x
        ud, uq = u_dq(t, x)
        Te = 1.5 * p * (psi * i_q + (Ld - Lq) * i_d * i_q)
        friction = m["B_Nms"] * w + m["T_coulomb_Nm"] * math.tanh(w / w_c)
        return [
            (ud - Rs * i_d + p * w * Lq * i_q) / Ld,
            (uq - Rs * i_q - p * w * (Ld * i_d + psi)) / Lq,
            (Te - T_load_Nm - friction) / m["J_kgm2"],
            w,
        ]

    return rhs


def state(p):
    return np.array([p.id_A, p.iq_A, p.w_m_radps, p.theta_m_rad])


def test_step_integrates_eq1_with_the_voltage_held():
    p = plant(id0_A=-1.0, iq0_A=2.0)
    x = state(p)
    commands = [(12.0, 30.0), (-5.0, 60.0), (0.0, 45.0)] * 20
    for k, (ud, uq) in enumerate(commands):
        lib.p2d_plant_step(p, ud, uq, 0.3, ffi.NULL)
        rhs = eq1_rhs(lambda t, x, ud=ud, uq=uq: (ud, uq), 0.3)
        x = solve_ivp(rhs, (k * TS, (k + 1) * TS), x, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        # RK4 with two steps per period: its error per period is far below these (the currents are ~5 A)
        assert state(p)[:2] == pytest.approx(x[:2], abs=1e-8)
        assert state(p)[2:] == pytest.approx(x[2:], rel=1e-10)


def test_step_is_command_then_substeps_of_advance():
    a, b = plant(computation_delay=True), plant(computation_delay=True)
    for ud, uq in [(10.0, 40.0), (400.0, 0.0), (-20.0, 30.0)]:
        out_a, out_b = ffi.new("p2d_inverter_output_t *"), ffi.new("p2d_inverter_output_t *")
        lib.p2d_plant_step(a, ud, uq, 0.1, out_a)
        lib.p2d_plant_command(b, ud, uq, out_b)
        for _ in range(2):
            lib.p2d_plant_advance(b, TS / 2, 0.1, 0.0)
        assert np.array_equal(state(a), state(b))
        assert (out_a.ud_V, out_a.uq_V, out_a.limited) == (out_b.ud_V, out_b.uq_V, out_b.limited)


def test_inverter_limits_to_the_dc_link_and_delays_one_period():
    p = plant(computation_delay=True)
    ud0, uq0 = ffi.new("double *"), ffi.new("double *")
    lib.p2d_plant_steady_voltage(p, ud0, uq0)
    out = ffi.new("p2d_inverter_output_t *")
    lib.p2d_plant_command(p, 300.0, 300.0, out)
    ud, uq = ffi.new("double *"), ffi.new("double *")
    lib.p2d_plant_applied_voltage(p, ud, uq)
    # the first period applies the steady state of the initial state, the command comes next, cut to u_dc/sqrt(3)
    assert (ud[0], uq[0]) == (ud0[0], uq0[0])
    assert out.limited and math.hypot(out.ud_V, out.uq_V) == pytest.approx(300.0 / math.sqrt(3), rel=1e-15)
    assert out.ud_V == pytest.approx(out.uq_V, rel=1e-15)
    lib.p2d_plant_set_dc_link(p, 150.0)
    lib.p2d_plant_command(p, 0.0, 0.0, out)
    lib.p2d_plant_applied_voltage(p, ud, uq)
    # the delayed command is cut again by the range of the period it is applied in
    assert math.hypot(ud[0], uq[0]) == pytest.approx(150.0 / math.sqrt(3), rel=1e-15) and out.applied_limited
    assert lib.p2d_plant_dc_link_V(p) == 150.0


def test_duties_apply_the_mean_of_the_stator_vector_in_the_rotor_frame():
    """The voltage applied over the step is the mean over the period of the stationary vector of the
    duties seen from the rotor turning at its speed, computed here by quadrature."""
    p = plant(w_m0_radps=150.0, id0_A=1.0, iq0_A=3.0)
    for _ in range(7):
        lib.p2d_plant_step(p, 5.0, 40.0, 0.0, ffi.NULL)
    da, db, dc = 0.8, 0.3, 0.45
    u_dc = 300.0
    ua, ub, uc = (d * u_dc for d in (da, db, dc))
    u_alpha, u_beta = (2 * ua - ub - uc) / 3, (ub - uc) / math.sqrt(3)
    th0, w_e = MOTOR["pole_pairs"] * p.theta_m_rad, MOTOR["pole_pairs"] * p.w_m_radps

    def rotor(t, part):
        th = th0 + w_e * t
        ud, uq = math.cos(th) * u_alpha + math.sin(th) * u_beta, -math.sin(th) * u_alpha + math.cos(th) * u_beta
        return ud if part == 0 else uq

    mean = [quad(rotor, 0.0, TS, args=(k,), epsabs=1e-13)[0] / TS for k in (0, 1)]
    lib.p2d_plant_step_duties(p, da, db, dc, 0.0)
    ud, uq = ffi.new("double *"), ffi.new("double *")
    lib.p2d_plant_applied_voltage(p, ud, uq)
    assert (ud[0], uq[0]) == pytest.approx(mean, abs=1e-10 * u_dc)


def test_duties_drive_the_motor_as_a_stator_frame_voltage():
    """Against eq 1 with the true stator-frame voltage (rotating in the rotor frame): the period mean
    of the plant differs from it by less than |u| w_e Ts / (4 Rs) in the currents, the first-order
    bound of holding a vector whose deviation from its mean is at most |u| w_e Ts / 2 over a period,
    summed with the decay of the currents, L / Rs."""
    p = plant(w_m0_radps=150.0)
    x = state(p)
    da, db, dc, u_dc = 0.55, 0.48, 0.47, 300.0
    u_alpha, u_beta = u_dc * (2 * da - db - dc) / 3, u_dc * (db - dc) / math.sqrt(3)

    def u_dq(t, x):
        th = MOTOR["pole_pairs"] * x[3]
        return math.cos(th) * u_alpha + math.sin(th) * u_beta, -math.sin(th) * u_alpha + math.cos(th) * u_beta

    rhs = eq1_rhs(u_dq, 0.0)
    truth = solve_ivp(rhs, (0.0, 200 * TS), x, method="DOP853", rtol=1e-11, atol=1e-11, t_eval=TS * np.arange(201))
    mine = [state(p)]
    for _ in range(200):
        lib.p2d_plant_step_duties(p, da, db, dc, 0.0)
        mine.append(state(p))
    mine = np.array(mine)
    bound = math.hypot(u_alpha, u_beta) * MOTOR["pole_pairs"] * 150.0 * TS / (4 * MOTOR["Rs_ohm"])
    error = np.max(np.abs(mine[:, :2] - truth.y[:2].T))
    assert error < bound
    assert np.max(np.abs(truth.y[:2])) > 20 * error  # the currents move far more than the error


def test_phase_currents_are_the_amplitude_invariant_transform():
    p = plant(w_m0_radps=300.0, id0_A=-2.0, iq0_A=5.0)
    for _ in range(13):
        lib.p2d_plant_step(p, -30.0, 120.0, 0.0, ffi.NULL)
    ia, ib, ic = (ffi.new("double *") for _ in range(3))
    lib.p2d_plant_phase_currents(p, ia, ib, ic)
    th = MOTOR["pole_pairs"] * p.theta_m_rad
    i = (p.id_A + 1j * p.iq_A) * np.exp(1j * th)  # the stator-frame vector
    expected = [np.real(i * np.exp(-1j * k * 2 * math.pi / 3)) for k in range(3)]
    assert (ia[0], ib[0], ic[0]) == pytest.approx(expected, abs=1e-12)


def test_current_sensors_read_gain_offset_and_seeded_noise():
    sensor = {"gain_error_a": 0.02, "gain_error_b": -0.01, "offset_a_A": 0.1, "offset_b_A": -0.05}
    p = plant(id0_A=1.0, iq0_A=4.0, **{f"current_sensor.{k}": v for k, v in sensor.items()})
    ia, ib, ic, ra, rb = (ffi.new("double *") for _ in range(5))
    lib.p2d_plant_phase_currents(p, ia, ib, ic)
    lib.p2d_plant_sense_currents(p, ra, rb)
    assert ra[0] == pytest.approx(1.02 * ia[0] + 0.1, rel=1e-15)
    assert rb[0] == pytest.approx(0.99 * ib[0] - 0.05, rel=1e-15)
    noise = {"current_sensor.noise_rms_A": 0.2, "current_sensor.seed": 7}
    noisy = [plant(id0_A=1.0, iq0_A=4.0, **noise) for _ in range(2)]
    reads = []
    for q in noisy:
        draws = []
        for _ in range(20000):
            lib.p2d_plant_sense_currents(q, ra, rb)
            draws.append((ra[0] - ia[0], rb[0] - ib[0]))
        reads.append(np.array(draws))
    assert np.array_equal(reads[0], reads[1])  # one stream per seed
    # 40000 normal draws: the sample rms within 3 % of 0.2 A (its relative standard error is 0.35 %)
    assert np.std(reads[0]) == pytest.approx(0.2, rel=0.03) and abs(np.mean(reads[0])) < 0.01


@pytest.mark.parametrize("feedback", ["motor", "load"])
def test_encoder_counts_the_sensed_side(feedback):
    fields = {"counts_per_rev": 4096, "mechanics.feedback": lib.P2D_FEEDBACK_LOAD if feedback == "load" else 0}
    fields |= {"mechanics.model": lib.P2D_MECHANICS_TWO_MASS, "mechanics.J_load_kgm2": 0.004}
    fields |= {"mechanics.stiffness_Nm_per_rad": 50.0, "mechanics.damping_Nms_per_rad": 0.01}
    p = plant(w_m0_radps=-40.0, iq0_A=5.0, **fields)
    for _ in range(500):
        lib.p2d_plant_step(p, 0.0, 50.0, 0.5, ffi.NULL)
    theta = p.theta_m_rad - (p.theta_rad if feedback == "load" else 0.0)
    assert lib.p2d_plant_encoder_count(p) == math.floor(theta * 4096 / (2 * math.pi)) % 2**32
    assert p.theta_rad != 0.0  # the shaft is twisted: the two sides count differently


@pytest.mark.parametrize(
    "field, value, param",
    [
        ("motor.pole_pairs", 0, "motor.pole_pairs"),
        ("motor.Ld_H", float("nan"), "motor.Ld_H"),
        ("motor.T_coulomb_Nm", -1.0, "motor.T_coulomb_Nm"),
        ("u_dc_V", 0.0, "u_dc_V"),
        ("Ts_s", float("inf"), "Ts_s"),
        ("substeps", 0, "substeps"),
        ("tau_i_s", -0.01, "tau_i_s"),
        ("w_m0_radps", float("nan"), "w_m0_radps"),
        ("mechanics.model", 2, "mechanics.model"),
        ("current_sensor.gain_error_a", -1.0, "current_sensor"),
    ],
)
def test_init_names_the_field_out_of_range(field, value, param):
    with pytest.raises(AssertionError, match=param.replace(".", r"\.")):
        plant(**{field: value})
