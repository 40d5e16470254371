"""`pmsm2dof simulate` and `pmsm2dof presets`: outputs, and bad input handled cleanly.

Bad input must end with exit status 2, one line on stderr naming the problem, no traceback, and
no output folder (nor a temporary one) left behind. The real run checks its files against the
physics they must satisfy (amplitude-invariant torque of the surface PMSM, rpm = rad/s * 30/pi)
and against the paper's schedule of condition 2.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pmsm2dof.errors import SimulationError
from pmsm2dof.sim.scenario import list_presets, load_scenario
from pmsm2dof.ui.cli import main

BAD = Path(__file__).parent / "bad_scenarios"
REQUIRED_COLUMNS = ["t_s", "speed_ref_rpm", "speed_rpm", "id_ref_A", "iq_ref_A", "id_A", "iq_A", "torque_Nm", "load_Nm"]


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean_failure(code, err, tmp_path, must_mention):
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("pmsm2dof: error: ")
    assert must_mention in lines[0]
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.glob(".out.*")), "a temporary folder was left behind"


@pytest.mark.parametrize(
    "args, must_mention",
    [
        ([str(BAD / "missing_motor_J.toml")], "motor.J_kgm2"),
        ([str(BAD / "unknown_key_case.toml")], "did you mean 'motor.Rs_ohm'"),
        ([str(BAD / "wrong_type_pole_pairs_string.toml")], "motor.pole_pairs"),
        ([str(BAD / "not_toml.toml")], "valid TOML"),
        (["paper-condition-2", "--set", "motor.J_kgm2=0"], "motor.J_kgm2"),
        (["paper-condition-2", "--set", "motor.J_kgm2=-0.4"], "motor.J_kgm2"),
        (["paper-condition-2", "--set", "limits.i_max_A=true"], "limits.i_max_A"),
        (["paper-condition-2", "--set", "motor.J_kgm2=nan"], "motor.J_kgm2"),
        (["paper-condition-2", "--set", 'motor.J_kgm2="nan"'], "motor.J_kgm2"),
        (["paper-condition-2", "--set", "motor.J_kgm2=inf"], "motor.J_kgm2"),
        (["paper-condition-2", "--set", "simulation.t_end_s=1e9"], "simulation.t_end_s"),
        (["paper-condition-2", "--set", "speed_controller.Ts_s=1.05e-3"], "speed_controller.Ts_s"),
        (["paper-condition-2", "--set", "reference.1.t_s=99"], "reference.1.t_s"),
        (["paper-condition-2", "--set", "speed_controller.m=2"], "no_tau"),
        (["paper-condition-2", "--set", "motor.J=0.4"], "motor.J"),
        (["paper-condition-2", "--set", "motor.J_kgm2"], "--set"),
        (["paper-condition-2", "--set", "speed_controller.Ka=1e9"], "speed_controller.Ka"),
        (["paper-condition-9"], "paper-condition-2"),
        (["no/such/file.toml"], "no/such/file.toml"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, must_mention):
    code, out, err = run(["simulate", *args, "--out", str(tmp_path / "out")], capsys)
    assert_clean_failure(code, err, tmp_path, must_mention)


def test_missing_out_option(tmp_path, capsys):
    code, out, err = run(["simulate", "paper-condition-2"], capsys)
    assert_clean_failure(code, err, tmp_path, "--out")


@pytest.mark.parametrize("where", ["below_a_file", "proc"])
def test_unwritable_out(tmp_path, capsys, where):
    """A folder that cannot be created (below a regular file, or in /proc) is refused up front."""
    if where == "below_a_file":
        blocker = tmp_path / "file"
        blocker.write_text("x")
        out = blocker / "out"
    else:
        out = Path("/proc/pmsm2dof-out")
    code, _, err = run(["simulate", "paper-condition-2", "--out", str(out)], capsys)
    assert_clean_failure(code, err, tmp_path, "out =")
    assert not out.exists()


def test_out_is_an_existing_file(tmp_path, capsys):
    target = tmp_path / "out"
    target.write_text("keep me")
    code, _, err = run(["simulate", "paper-condition-2", "--out", str(target)], capsys)
    assert code == 2 and len(err.splitlines()) == 1 and "out =" in err
    assert target.read_text() == "keep me"


def test_failure_during_the_run_leaves_the_old_output_untouched(tmp_path, capsys, monkeypatch):
    """An error after the trace is written (here: in the plot) leaves the earlier run's outputs as they
    were, and no new file behind."""
    import pmsm2dof.ui.plots.trace

    out = tmp_path / "out"
    argv = ["simulate", "paper-experiment-1", "--set", "simulation.t_end_s=1", "--out", str(out)]
    assert run(argv, capsys)[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def failing_plot(result, path):
        raise SimulationError("plot failed on purpose")

    monkeypatch.setattr(pmsm2dof.ui.plots.trace, "plot_trace", failing_plot)
    code, _, err = run([*argv, "--set", "reference.0.speed_rpm=100"], capsys)
    assert code == 2 and "plot failed on purpose" in err and len(err.splitlines()) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert not list(tmp_path.glob(".out.*"))


@pytest.mark.slow
def test_simulate_paper_condition_2(tmp_path):
    """The real command, as a user runs it: files, columns, physics and the paper's schedule."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "pmsm2dof", "simulate", "paper-condition-2", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "paper condition 2" in proc.stdout and "load step at 7 s" in proc.stdout
    assert sorted(p.name for p in out.iterdir()) == [
        ".pmsm2dof-outputs.json",
        "metrics.json",
        "plot.png",
        "scenario.toml",
        "trace.csv",
    ]

    trace = pd.read_csv(out / "trace.csv")
    assert set(REQUIRED_COLUMNS) <= set(trace.columns)
    assert np.all(np.isfinite(trace.to_numpy()))
    t = trace["t_s"].to_numpy()
    assert t[0] == 0.0 and t[-1] == pytest.approx(15.0) and np.allclose(np.diff(t), 1e-3)
    # the schedule of section 4.1, condition 2, as seen in the trace
    ref, load = trace["speed_ref_rpm"].to_numpy(), trace["load_Nm"].to_numpy()
    assert np.all(ref[(t >= 0) & (t < 10 - 1e-9)] == 500.0) and np.all(ref[t >= 10] == 200.0)
    assert np.all(load[t < 7 - 1e-9] == 0.0) and np.allclose(load[t >= 7], 8.0)
    # amplitude-invariant torque of the surface PMSM of the preset: Te = 1.5 p psi_f iq
    assert np.allclose(trace["torque_Nm"], 1.5 * 4 * 0.2 * trace["iq_A"], rtol=1e-9, atol=1e-12)
    assert np.allclose(trace["speed_rpm"], trace["w_m_radps"] * 30 / math.pi, rtol=1e-12)
    # the current-vector limit of the paper holds for the commands
    assert np.all(np.hypot(trace["id_ref_A"], trace["iq_ref_A"]) <= 7.6 * (1 + 1e-6))

    metrics = json.loads((out / "metrics.json").read_text())
    assert [s["t_s"] for s in metrics["reference_steps"]] == [0.0, 10.0]
    assert [(s["t_s"], s["to_Nm"]) for s in metrics["load_steps"]] == [(7.0, 8.0)]
    for step in metrics["reference_steps"] + metrics["load_steps"]:
        for name, figure in step.items():
            if isinstance(figure, dict):
                assert (figure["value"] is None) == ("reason" in figure), name
    assert (out / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert load_scenario(out / "scenario.toml") == load_scenario("paper-condition-2")


@pytest.mark.slow
def test_simulate_with_overrides(tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, err = run(
        [
            "simulate",
            "paper-experiment-1",
            "--set",
            "simulation.t_end_s=1.5",
            "--set",
            "speed_controller.anti_windup=none",
            "--set",
            "current_loop.model=first_order",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    s = load_scenario(out / "scenario.toml")
    assert s.data["simulation"]["t_end_s"] == 1.5
    assert s.data["speed_controller"]["anti_windup"] == "none"
    assert s.data["current_loop"]["model"] == "first_order"
    trace = pd.read_csv(out / "trace.csv")
    assert trace["t_s"].iloc[-1] == pytest.approx(1.5)


def test_presets_lists_names_and_descriptions(capsys):
    code, out, err = run(["presets"], capsys)
    assert code == 0
    lines = out.splitlines()
    assert [line.split()[0] for line in lines] == list_presets()
    for line, name in zip(lines, list_presets()):
        assert load_scenario(name).description in line


def test_presets_keys(capsys):
    code, out, _ = run(["presets", "--keys"], capsys)
    assert code == 0
    assert "speed_controller.feedforward" in out and "reference[].ramp_s" in out
