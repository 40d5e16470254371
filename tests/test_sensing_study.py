"""The sensor-chain study, its CLI command, and the manual's guide to speed sensing (docs/sensing.md) run verbatim.

Truth from outside the study: the margins of the ideal chain are those of the paper's loop
without a sensor (python-control on F G built here from eq 2, 3 and 9, sampled by
``control.sample_system``), a direct simulation of each experiment, and the ordering that a
lag (PLL, low-pass, delay) costs phase.
"""

import csv
import json
import os
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import control
import numpy as np
import pytest

from pmsm2dof.analysis.sensor import SensorChain
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.configuration import sensor_chain
from pmsm2dof.studies.sensing import SensorRow, offset_ripple_Nm, offset_study, sensor_study, verdict
from pmsm2dof.ui.report.render import render_markdown
from pmsm2dof.ui.report.sensing import sensing_blocks

ROOT = Path(__file__).resolve().parents[1]
CHAINS = {
    "ideal": {},
    "encoder 1024, PLL 5 rad/s": {
        "speed_sensor.model": "encoder",
        "speed_sensor.counts_per_rev": 1024,
        "speed_sensor.estimator": "pll",
        "speed_sensor.bandwidth_radps": 5.0,
    },
}


@pytest.fixture(scope="module")
def rows():
    return sensor_study(chains=CHAINS)


def test_ideal_row_is_the_plain_simulation_and_the_plain_sampled_loop(rows):
    ideal = rows[0]
    e1 = load_scenario("paper-experiment-1").with_overrides(
        {"speed_controller.feedforward": "none", "speed_controller.anti_windup": "none"}
    )
    direct = compute_metrics(simulate(e1))["reference_steps"][0]["overshoot_pct"]["value"]
    assert ideal.overshoot_no_aw_pct == direct
    # the paper's loop F G sampled with ZOH at 1 ms (python-control), no sensor
    sc = e1.data["speed_controller"]
    J, a, z, tau = sc["J_kgm2"], sc["alpha_radps"], sc["zeta"], sc["tau_i_s"]
    Kp, Ki = J * a, J * (a / (2 * z)) ** 2
    G = control.sample_system(control.tf([1], [tau, 1]) * control.tf([1], [J, 0]), sc["Ts_s"], "zoh")
    # the PI discretized by Tustin: Kp + Ki Ts/2 (z + 1)/(z - 1)
    Ts = sc["Ts_s"]
    F = control.tf([Kp + Ki * Ts / 2, -Kp + Ki * Ts / 2], [1, -1], Ts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control falls back to its frequency-response method
        _gm, pm, *_ = control.stability_margins(F * G)
    assert ideal.phase_margin_deg == pytest.approx(pm, abs=0.05)


def test_sensor_chain_of_a_scenario_table():
    chain = sensor_chain(load_scenario("paper-experiment-3").with_overrides(CHAINS["encoder 1024, PLL 5 rad/s"]))
    assert chain == SensorChain(model="encoder", estimator="pll", bandwidth_radps=5.0)
    assert sensor_chain(load_scenario("paper-experiment-3")).is_ideal


def test_a_lag_in_the_reading_costs_phase_and_raises_the_overshoot(rows):
    ideal, pll = rows
    assert pll.phase_margin_deg < ideal.phase_margin_deg - 10
    assert pll.overshoot_no_aw_pct > ideal.overshoot_no_aw_pct
    assert pll.dip_rpm > ideal.dip_rpm
    assert pll.sensor.estimator == "pll" and ideal.sensor.model == "ideal"


def test_verdict_follows_the_numbers(rows):
    assert verdict(rows).startswith("No sensor chain of the study explains")

    def row(label, no_aw, aw):
        return SensorRow(label, {}, no_aw, aw, None, None, None, abs(no_aw - 35) + abs(aw - 15))

    closer = [row("ideal", 68.0, 34.0), row("slow", 40.0, 18.0)]
    assert verdict(closer).startswith("'slow' explains the measured 35 % -> 15 % better")


def test_report_section_holds_the_table_and_the_verdict(rows):
    text = render_markdown(sensing_blocks(rows))
    assert text.startswith("## Speed measurement (not in the paper)")
    assert "| paper, measured (section 4.2) | 35 | 15 |" in text
    assert "| encoder 1024, PLL 5 rad/s |" in text and verdict(rows) in text
    assert text.count("\n| ") == 2 + len(rows)  # header, paper and one row per chain
    assert sensing_blocks([]) == []


def test_offset_ripple_follows_the_linear_current_loop():
    """The simulated ripple against the dq loop with the measured-current decoupling, written out here:
    i_err = E (-T + j w_e L G_d) at s = -j w_e, T = 1/(tau s + 1), G_d = tau s / ((L s + R)(tau s + 1))."""
    d = load_scenario("paper-experiment-3").data
    m, tau = d["motor"], d["current_loop"]["tau_i_s"]
    kt = 1.5 * m["pole_pairs"] * m["psi_f_Wb"]
    offsets = offset_study()
    for o in offsets:
        w_e = m["pole_pairs"] * o.speed_rpm * np.pi / 30
        s = -1j * w_e
        T = 1 / (tau * s + 1)
        G_d = tau * s / ((m["Ld_H"] * s + m["Rs_ohm"]) * (tau * s + 1))
        expected = kt * 2 * o.offset_a_A / np.sqrt(3) * abs(-T + 1j * w_e * m["Ld_H"] * G_d)
        assert o.predicted_Nm == pytest.approx(expected, rel=1e-12)
        assert o.torque_ripple_Nm == pytest.approx(expected, rel=0.01)
    assert offset_ripple_Nm(0.0, 100.0, kt, 0.01, 0.5, tau) == 0.0
    text = render_markdown(sensing_blocks([SensorRow("ideal", {}, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)], offsets))
    assert "| 500 | 0.38 |" in text


def run_cli(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "pmsm2dof", *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


@pytest.mark.slow  # a fresh interpreter per CLI call
def test_cli_sensors_refuses_a_bad_key_in_one_line_and_writes_nothing(tmp_path):
    proc = run_cli("sensors", "--set", "speed_sensor.counts_per_rev=0", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "speed_sensor.counts_per_rev" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow  # a fresh interpreter per CLI call
@pytest.mark.parametrize(
    "setting, key",
    [
        ("speed_sensor.model=magnetic", "speed_sensor.model"),
        ("field_weakening.enabled=true", "field_weakening.Ki_A_per_Vs"),
        ("current_measurement.noise_A_rms=-1", "current_measurement.noise_A_rms"),
    ],
)
def test_cli_simulate_refuses_a_bad_sensing_key_in_one_line_and_writes_nothing(tmp_path, setting, key):
    proc = run_cli("simulate", "paper-experiment-3", "--set", setting, "--out", "out", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and key in proc.stderr and "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


def readme_section():
    text = (ROOT / "docs" / "sensing.md").read_text()
    start = text.index("## Speed sensing, current sensors and field weakening")
    end = text.index("\n## ", start + 1)
    return text[start:end]


@pytest.mark.slow
def test_readme_guide_runs_verbatim(tmp_path):
    blocks = re.findall(r"^```sh\n(.*?)^```$", readme_section(), flags=re.M | re.S)
    assert blocks
    installed = shutil.which("pmsm2dof") or str(Path(sys.executable).parent / "pmsm2dof")
    env = dict(os.environ, PATH=f"{Path(installed).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    for block in blocks:
        proc = subprocess.run(
            ["sh", "-e", "-c", block], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600
        )
        assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "encoder-run" / "trace.csv") as f:
        header = next(csv.reader(f))
    assert "speed_meas_rpm" in header and "speed_rpm" in header
    fw = json.loads((tmp_path / "fw-run" / "metrics.json").read_text())
    assert abs(fw["reference_steps"][0]["steady_state_error_rpm"]["value"]) < 1.0
    assert "paper, measured" in (tmp_path / "sensors" / "sensors.md").read_text()
    with open(tmp_path / "sensors" / "sensors.csv") as f:
        table = list(csv.DictReader(f))
    assert table[0]["label"] == "ideal" and np.isfinite(float(table[0]["overshoot_no_aw_pct"]))
