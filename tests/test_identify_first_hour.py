"""Identification of the maxon EC 45 flat of examples/ec45-flat, as a new user runs it.

Truths: the steady state of eq 1 at the current limit on the voltage circle (solved here by brentq),
the load the example scenario applies (examples/your-motor: 1.5 Nm from 0.9 s to 1.1 s), and an
encoder's resolution 60 / (counts dt) written here.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from pmsm2dof.core.motor import load_motor
from pmsm2dof.sim.logs import read_log
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.identify import identify_mechanics, plan_experiment, torque_from_currents
from pmsm2dof.ui.cli import main

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
EC45 = EXAMPLES / "ec45-flat" / "drive.toml"
YOUR_MOTOR = EXAMPLES / "your-motor" / "drive.toml"


def fit(scenario, motor_file, folder):
    """Identify the mechanics of the scenario's simulated run as logged, the torque from its currents."""
    simulate(scenario).save(folder / "trace.csv")
    log = read_log(folder / "trace.csv")
    m = load_motor(motor_file)
    return identify_mechanics(log, torque_from_currents(log, m.pole_pairs, m.psi_f_Wb, m.Ld_H, m.Lq_H))


def test_the_plan_stays_inside_the_voltage_limit():
    """At 5000 rpm the voltage at the 10 A limit exceeds 24 V / sqrt(3): the plan lowers its speeds."""
    from pmsm2dof.studies.identify import PLAN_VOLTAGE_SHARE, PlanWarning

    drive = load_scenario(EC45)
    m, limits = drive.data["motor"], drive.data["limits"]
    u = PLAN_VOLTAGE_SHARE * limits["u_dc_V"] / math.sqrt(3)
    i = limits["i_max_A"]

    def excess(w_m):  # surface PMSM at id = 0: ud = -w_e Lq i, uq = Rs i + w_e psi_f
        w_e = m["pole_pairs"] * w_m
        return math.hypot(w_e * m["Lq_H"] * i, m["Rs_ohm"] * i + w_e * m["psi_f_Wb"]) - u

    top_rpm = brentq(excess, 0.0, 1e4) * 30 / math.pi
    with pytest.warns(PlanWarning, match=f"largest speed is {top_rpm:.5g} rpm, not speed_max_rpm = 5000 rpm"):
        plan = plan_experiment(drive, 5000.0)
    speeds = [abs(e["speed_rpm"]) for e in plan.data["reference"]]
    assert max(speeds) == pytest.approx(top_rpm, rel=1e-9)
    run = simulate(plan)
    assert np.all(run.voltage_limited == 0.0)
    assert np.max(np.abs(run.iq_A)) == pytest.approx(i, rel=1e-3)  # the accelerations at the current limit
    # a plan that fits is not changed
    with_room = plan_experiment(drive, 0.5 * top_rpm)
    assert max(abs(e["speed_rpm"]) for e in with_room.data["reference"]) == 0.5 * top_rpm


def test_rows_excluded_without_a_load_are_not_called_one(tmp_path):
    """The plan's run has no load: rows the 2 kHz log does not resolve are excluded, not called a load."""
    plan = plan_experiment(load_scenario(EC45), 3400.0)
    mech = fit(plan, EC45, tmp_path)
    assert mech.J_kgm2 == pytest.approx(7.24e-5, rel=1e-3)
    assert not any("unannounced" in note for note in mech.notes), mech.notes


def test_an_unannounced_load_is_named_with_its_torque_and_time(tmp_path):
    mech = fit(load_scenario(YOUR_MOTOR), YOUR_MOTOR, tmp_path)
    (note,) = [n for n in mech.notes if "excluded as outliers" in n]
    load, window = note.split("an unannounced load, about ")[1].split(" Nm in ")
    start, end = (float(x) for x in window.removesuffix(" s").split("-"))
    assert float(load) == pytest.approx(1.5, rel=0.02)  # load.0.torque_Nm of the example
    assert 0.85 < start and end < 1.15  # the load acts from 0.9 s to 1.1 s


def test_a_coarse_encoder_is_noted_in_the_log_and_the_scenario(tmp_path, capsys):
    """2048 counts differenced at 2 kHz: 60 / (2048 * 0.5 ms) = 58.59 rpm per count."""
    args = ["--set", "speed_sensor.model=encoder", "--set", "speed_sensor.counts_per_rev=2048"]
    assert main(["simulate", str(EC45), *args, "--out", str(tmp_path / "run")]) == 0
    (warning,) = capsys.readouterr().err.splitlines()
    assert "speed_sensor.counts_per_rev = 2048" in warning and f"resolves {60 / (2048 * 5e-4):.4g} rpm" in warning
    # the measured speed as a drive logs it
    trace = np.genfromtxt(tmp_path / "run" / "trace.csv", delimiter=",", names=True)
    names = [n for n in trace.dtype.names if n not in ("speed_rpm", "w_m_radps")]
    header = ",".join("speed_rpm" if n == "speed_meas_rpm" else n for n in names)
    np.savetxt(
        tmp_path / "log.csv", np.column_stack([trace[n] for n in names]), delimiter=",", header=header, comments=""
    )
    log = read_log(tmp_path / "log.csv")
    (note,) = log.notes
    assert f"steps of {60 / (2048 * 5e-4):.4g} rpm" in note and "about 2048 counts per revolution" in note
    # the true speed is not quantized
    assert read_log(tmp_path / "run" / "trace.csv").notes == ()
