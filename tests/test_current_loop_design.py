"""The current loop designed from an identified motor (pmsm2dof.analysis.current_loop, design --motor).

Truths: the shipped C current controller's own coefficients for tau_i = 1/alpha_c; the step
response of the q axis closed by the PI on an RL branch, integrated by SciPy; the phase margin
of the speed loop found by a root finder on the hand-written loop gain.
"""

import cmath
import json
import math

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from pmsm2dof.analysis.current_loop import (
    current_closed_loop,
    design_current_loop,
    speed_margin_sensitivity,
)
from pmsm2dof.core import CurrentController
from pmsm2dof.core.motor import load_motor
from pmsm2dof.errors import ConfigError
from pmsm2dof.ui.cli import main

SERVO = "[motor]\npole_pairs = 4\nRs_ohm = 0.8\nLd_H = 0.004\nLq_H = 0.008\npsi_f_Wb = 0.05\n"
INTERVALS = "Rs_ohm_ci = [0.76, 0.84]\nLq_H_ci = [0.0076, 0.0084]\npsi_f_Wb_ci = [0.045, 0.055]\n"


def estimate(path):
    """The identified motor of a motor file, as design --motor reads it."""
    return load_motor(path)


@pytest.fixture
def motor_file(tmp_path):
    path = tmp_path / "motor.toml"
    path.write_text(SERVO + INTERVALS)
    return path


def test_gains_are_those_of_the_shipped_controller(motor_file):
    loop = design_current_loop(estimate(motor_file), 2000.0)
    ctl = CurrentController(Rs_ohm=0.8, Ld_H=0.004, Lq_H=0.008, psi_f_Wb=0.05, tau_i_s=loop.tau_i_s, Ts_s=1e-4)
    coef = ctl.coefficients
    assert loop.Kp_d_V_per_A == pytest.approx(coef["d"]["Kp"], rel=1e-6) == 0.004 * 2000.0
    assert loop.Kp_q_V_per_A == pytest.approx(coef["q"]["Kp"], rel=1e-6)
    assert loop.Ki_V_per_As == pytest.approx(coef["q"]["Ki"], rel=1e-6) == 0.8 * 2000.0
    assert loop.tau_i_s == 1.0 / 2000.0


@pytest.mark.parametrize(("Rs_ohm", "Lq_H"), [(0.8, 0.008), (0.6, 0.010)])
def test_closed_current_loop_against_an_integrated_rl_branch(motor_file, Rs_ohm, Lq_H):
    """PI of the estimates on Lq di/dt = u - Rs i (decoupled), unit step, integrated by SciPy."""
    loop = design_current_loop(estimate(motor_file), 2000.0)
    Kp, Ki = loop.Kp_q_V_per_A, loop.Ki_V_per_As

    def rhs(_t, x):
        i, integral = x
        e = 1.0 - i
        return [(Kp * e + Ki * integral - Rs_ohm * i) / Lq_H, e]

    t = np.linspace(0.0, 5e-3, 201)
    ref = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12).y[0]
    tf = current_closed_loop(loop, Rs_ohm, Lq_H)
    _, y = control.step_response(tf, t)
    assert np.max(np.abs(y - ref)) < 1e-6
    if (Rs_ohm, Lq_H) == (0.8, 0.008):  # on the estimated machine: eq 3, 1 - exp(-t / tau_i)
        assert np.max(np.abs(ref - (1.0 - np.exp(-t / loop.tau_i_s)))) < 1e-6


def test_speed_margin_sensitivity_against_a_root_finder(motor_file):
    """Phase margin at each corner: |L(jw)| = 1 found by brentq on the hand-written loop gain."""
    loop = design_current_loop(estimate(motor_file), 300.0)
    J, Kp, Ki = 2e-4, 2e-4 * 50.0, 2e-4 * (50.0 / 1.4) ** 2  # eq 9, alpha 50 rad/s, zeta 0.7
    rows = speed_margin_sensitivity(loop, Kp, Ki, J)
    assert len(rows) == 1 + 8 and rows[0]["machine"] == "estimates"
    for row in rows:
        k = row["psi_f_Wb"] / 0.05

        def L(w, row=row, k=k):
            s = 1j * w
            current = 300.0 * (0.008 * s + 0.8) / (row["Lq_H"] * s**2 + (row["Rs_ohm"] + 300.0 * 0.008) * s + 240.0)
            return (Kp + Ki / s) * k * current / (J * s)

        w_c = brentq(lambda w: abs(L(w)) - 1.0, 1.0, 1e4)
        pm = 180.0 + math.degrees(cmath.phase(L(w_c)))
        assert row["phase_margin_deg"] == pytest.approx(pm, abs=0.01)
        assert row["w_gain_crossover_radps"] == pytest.approx(w_c, rel=1e-4)
    # a stronger magnet raises the crossover: the margin moves with psi_f
    pms = {row["psi_f_Wb"]: row["phase_margin_deg"] for row in rows[1:]}
    assert pms[0.045] != pms[0.055]


@pytest.mark.parametrize(
    ("text", "param"),
    [
        (SERVO.replace("Ld_H = 0.004\n", ""), "motor.Ld_H"),
        (SERVO.replace("pole_pairs = 4", "pole_pairs = 0"), "motor.pole_pairs"),
        (SERVO + "Rs_ohm_ci = [0.9, 1.0]\n", "motor.Rs_ohm_ci"),
        (SERVO + "Rs = 1.0\n", "motor.Rs"),
        ("[motor\n", "motor file"),
    ],
)
def test_bad_motor_file_names_the_key(tmp_path, text, param):
    path = tmp_path / "m.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_motor(path)
    assert err.value.param == param


DESIGN = ["design", "--J-kgm2", "2e-4", "--alpha-radps", "50", "--zeta", "0.7", "--Ts-s", "1e-3"]


@pytest.mark.slow
def test_design_command_with_an_identified_motor(motor_file, capsys):
    assert main([*DESIGN, "--motor", str(motor_file), "--current-bandwidth-radps", "2000", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["current_loop"]["Kp_q_V_per_A"] == pytest.approx(16.0)
    assert data["tau_i_s"] == pytest.approx(5e-4)  # eq 11's tau_i is 1 / alpha_c
    assert len(data["speed_margin_sensitivity"]) == 9
    assert main([*DESIGN, "--motor", str(motor_file), "--current-bandwidth-radps", "2000"]) == 0
    out = capsys.readouterr().out
    assert "Kp_q = Lq alpha_c" in out and "interval" in out


@pytest.mark.parametrize(
    ("extra", "mention"),
    [
        (["--current-bandwidth-radps", "-1"], "--current-bandwidth-radps = -1.0"),
        (["--current-bandwidth-radps", "2000", "--tau-i-s", "0.01"], "not both"),
        (["--current-bandwidth-radps", "2000", "--motor", "missing.toml"], "--motor = 'missing.toml'"),
    ],
)
def test_design_bad_input_one_line_exit_2(motor_file, capsys, extra, mention):
    assert main([*DESIGN, "--motor", str(motor_file), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and mention in err and "Traceback" not in err
