"""The command line on a corpus of bad inputs: exit status 2, exactly one line on stderr naming the
problem, no traceback, and no output left behind (no new file or folder, no temporary one, an
existing output folder untouched).

The corpus: every broken scenario file of tests/bad_scenarios (each names in its first line the
key its error must name), bad --set overrides, unknown presets and commands, runs that stop, output
folders that cannot be written, and bad options of design and bode.
"""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm2dof.ui.cli import main

BAD_FILES = sorted((Path(__file__).parent / "bad_scenarios").glob("*.toml"))


def must_name(path):
    return re.match(r"# must name: (\S+)", path.read_text()).group(1)


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """An empty working folder with an existing output folder holding one old file."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("keep")
    return tmp_path


def snapshot(folder):
    return sorted((str(p.relative_to(folder)), p.read_bytes() if p.is_file() else None) for p in folder.rglob("*"))


def assert_clean_failure(argv, workdir, capsys, mention):
    before = snapshot(workdir)
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 2, captured.err
    assert captured.err.count("\n") == 1, captured.err
    line = captured.err.rstrip("\n")
    assert line.startswith("pmsm2dof: error: ") and "Traceback" not in line
    assert mention in line, line
    assert snapshot(workdir) == before, "output left behind or changed"
    return line


@pytest.mark.parametrize("path", BAD_FILES, ids=[p.stem for p in BAD_FILES])
def test_every_bad_scenario_file(path, workdir, capsys):
    key = must_name(path)
    line = assert_clean_failure(["simulate", str(path), "--out", "out"], workdir, capsys, f"error: {key} = ")
    assert "valid range is" in line


PAPER = "paper-condition-2"

SIMULATE_BAD = [
    # bad --set syntax
    (["--set", "motor.J_kgm2"], "--set"),
    (["--set", "=1"], "--set"),
    (["--set", " = 1"], "--set"),
    (["--set", "motor..J_kgm2=1"], "override key"),
    (["--set", "reference.x.t_s=1"], "reference.x"),
    (["--set", "reference.9.t_s=1"], "reference.9"),
    (["--set", "motor.J_kgm2.x=1"], "motor.J_kgm2.x"),
    (["--set", "motor.J=0.4"], "not a key of [motor]"),
    (["--set", "load=[{t_s = 1.0}]"], "load.0.torque_Nm"),
    (["--set", "fault.0.kind=sensor_zero"], "fault.0.t_s"),
    (["--set", 'fault=[{kind = "sensor_zero", t_s = 1.0}]'], "fault.0.duration_s"),
    (["--set", 'fault=[{kind = "sensor_spike", t_s = 1.0, speed_rpm = "fast"}]'], "fault.0.speed_rpm"),
    # missing, wrong types, zero and negative, NaN strings, huge and tiny values
    (["--set", "motor.J_kgm2="], "motor.J_kgm2 = ''"),
    (["--set", "motor.Rs_ohm=0"], "motor.Rs_ohm"),
    (["--set", "motor.pole_pairs=4.5"], "motor.pole_pairs"),
    (["--set", "limits.i_max_A=true"], "limits.i_max_A"),
    (["--set", "limits.i_max_A=-7.6"], "limits.i_max_A"),
    (["--set", "limits.u_dc_V=0"], "limits.u_dc_V"),
    (["--set", 'motor.J_kgm2="nan"'], "motor.J_kgm2"),
    (["--set", "motor.J_kgm2=nan"], "motor.J_kgm2"),
    (["--set", "motor.J_kgm2=-inf"], "motor.J_kgm2"),
    (["--set", "simulation.t_end_s=1e9"], "simulation.t_end_s"),
    (["--set", "simulation.log_every=0"], "simulation.log_every"),
    (["--set", "simulation.dt_s=1e-12"], "simulation.dt_s"),
    (["--set", "speed_controller.anti_windup=windup"], "speed_controller.anti_windup"),
    (["--set", "speed_controller.Ts_s=1.05e-3"], "speed_controller.Ts_s"),
    (["--set", "speed_controller.Ts_s=1e-5"], "speed_controller.Ts_s"),
    (["--set", "current_loop.Ts_s=3e-4"], "speed_controller.Ts_s"),
    # rejected by the controllers or the engine, named by the scenario key
    (["--set", "speed_controller.Ka=1e9"], "speed_controller.Ka"),
    (["--set", "simulation.speed0_rpm=1e6"], "simulation.speed0_rpm"),
    (["--set", "motor.J_kgm2=1e-300"], "speed_controller.J_kgm2"),
    # a run that stops: an overhauling load beyond the torque limit drives the motor to overspeed
    (["--set", "load.0.torque_Nm=-1000"], "stopped at t ="),
]


@pytest.mark.parametrize("extra, mention", SIMULATE_BAD, ids=[" ".join(a) for a, _ in SIMULATE_BAD])
def test_bad_simulate_arguments(extra, mention, workdir, capsys):
    # --force: the folder holds a file of the user's, which a failed run must leave as it is too
    assert_clean_failure(["simulate", PAPER, *extra, "--out", "out", "--force"], workdir, capsys, mention)


@pytest.mark.parametrize(
    "preset, extra, mention",
    [
        ("fault-dc-link-sag", ["--set", "current_loop.model=first_order"], "fault.0.kind"),
        ("fault-sensor-spike", ["--set", "fault.0.duration_s=0.1"], "fault.0.duration_s"),
        (
            "fault-sensor-hold",
            ["--set", "fault.1.kind=sensor_spike", "--set", "fault.1.t_s=1.2", "--set", "fault.1.speed_rpm=0"],
            "fault.1.t_s",
        ),
        ("fault-stall", ["--set", "load.1.t_s=0.5"], "load.1.t_s"),
    ],
)
def test_bad_fault_overrides(preset, extra, mention, workdir, capsys):
    assert_clean_failure(["simulate", preset, *extra, "--out", "out", "--force"], workdir, capsys, mention)


@pytest.mark.parametrize(
    "argv, mention",
    [
        (["simulate", "paper-condition-9", "--out", "out"], "fault-stall"),
        (["simulate", "no/such/file.toml", "--out", "out"], "no/such/file.toml"),
        (["simulate", ".", "--out", "out"], "scenario = '.'"),
        (["simulate", PAPER], "--out"),
        (["simulate", "--out", "out"], "PRESET_OR_FILE"),
        (["simulate", PAPER, "--out", "out", "--bogus"], "--bogus"),
        (["simulat", PAPER], "Did you mean 'simulate'"),
        (["presets", "--bogus"], "--bogus"),
    ],
)
def test_bad_names_and_options(argv, mention, workdir, capsys):
    assert_clean_failure(argv, workdir, capsys, mention)


@pytest.mark.parametrize("where", ["below_a_file", "in_proc", "an_existing_file", "below_dev_null"])
def test_unwritable_output_folder(where, workdir, capsys):
    (workdir / "file").write_text("x")
    out = {
        "below_a_file": "file/out",
        "in_proc": "/proc/pmsm2dof-out",
        "an_existing_file": "file",
        "below_dev_null": "/dev/null/out",
    }[where]
    assert_clean_failure(["simulate", PAPER, "--out", out], workdir, capsys, "out = ")
    assert (workdir / "file").read_text() == "x"


DESIGN = ["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"]

DESIGN_BAD = [
    (["--feedforward", "bogus"], "feedforward = 'bogus'"),
    (["--anti-windup", "bogus"], "--anti-windup = 'bogus'"),
    (["--method", "zoh"], "method = 'zoh'"),
    (["--method"], "--method"),
    (["--Ts-s", "0"], "--Ts-s = 0.0"),
    (["--Ts-s", "-1e-3"], "--Ts-s = -0.001"),
    (["--Ts-s", "1e300"], "--Ts-s = "),  # the C controller: not a float32
    (["--zeta", "-0.5"], "zeta = -0.5"),
    (["--alpha-radps", "inf"], "--alpha-radps = inf"),
    (["--J-kgm2", "nan"], "--J-kgm2 = nan"),
    (["--J-kgm2", "0.4kg"], "--J-kgm2"),
    (["--m", "0"], "m = 0.0"),
    (["--Ka", "nan"], "Ka = nan"),
    (["--tau-i-s", "nan"], "--tau-i-s = nan"),
    (["--emit-c-header", "h.h"], "--i-max-A, --pole-pairs, --psi-f-Wb, --Ld-H, --Rs-ohm, --Ts-current-s missing"),
    (
        ["--emit-c-header", "h.h", "--i-max-A", "7.6", "--Ld-H", "0.01"],
        "--pole-pairs, --psi-f-Wb, --Rs-ohm, --Ts-current-s missing",
    ),
    (["--emit-c-header", "h.h", "--paper-drive", "--i-max-A", "-1"], "--i-max-A = -1.0"),
    (["--emit-c-header", "h.h", "--paper-drive", "--pole-pairs", "0"], "--pole-pairs = 0"),
    (["--emit-c-header", "h.h", "--paper-drive", "--tau-i-s", "0.05", "--prefix", "1bad"], "prefix = '1bad'"),
    (["--emit-c-header", "h.h", "--paper-drive", "--Ld-H", "0"], "--Ld-H = 0.0"),
    (["--emit-c-header", "h.h", "--paper-drive", "--psi-f-Wb", "nan"], "--psi-f-Wb = nan"),
    (["--emit-c-header", "h.h", "--paper-drive", "--tau-i-s", "0.05", "--Ts-current-s", "3e-4"], "--Ts-s = 0.001"),
    (["--emit-c-header", "h.h", "--paper-drive", "--tau-i-s", "0.05", "--Rs-ohm", "-1"], "--Rs-ohm = -1.0"),
    (["--emit-c-header", "h.h", "--paper-drive"], "--tau-i-s = 0.0"),
    (["--emit-c-header", "/proc/pmsm2dof/h.h", "--paper-drive", "--tau-i-s", "0.05"], "/proc/pmsm2dof/h.h"),
    (["--emit-c-header", "file/h.h", "--paper-drive", "--tau-i-s", "0.05"], "file/h.h"),
]


@pytest.mark.parametrize("extra, mention", DESIGN_BAD, ids=[" ".join(a) for a, _ in DESIGN_BAD])
def test_bad_design_options(extra, mention, workdir, capsys):
    (workdir / "file").write_text("x")
    assert_clean_failure([*DESIGN, *extra], workdir, capsys, mention)


@pytest.mark.parametrize(
    "extra, mention",
    [
        (["--m", ""], "m = ''"),
        (["--m", "0"], "m = 0.0"),
        (["--m", "-1,2"], "m = -1.0"),
        (["--alpha-radps", "nan"], "alpha_radps = nan"),
        (["--J-kgm2", "0"], "J_kgm2 = 0.0"),
        (["--feedforward", "bogus"], "feedforward = 'bogus'"),
        (["--out", "fig"], "out = 'fig'"),
        (["--out", "/proc/pmsm2dof.png"], "/proc/pmsm2dof.png"),
    ],
)
def test_bad_bode_options(extra, mention, workdir, capsys):
    argv = ["bode", "--alpha-radps", "0.5", "--out", "fig.png"]
    for i in range(0, len(extra), 2):
        if extra[i] in argv:
            argv[argv.index(extra[i]) + 1] = extra[i + 1]
        else:
            argv += extra[i : i + 2]
    assert_clean_failure(argv, workdir, capsys, mention)


@pytest.mark.slow
def test_bad_input_in_a_fresh_process(tmp_path):
    """The console entry point, as a user runs it: the same single line, no traceback."""
    path = Path(__file__).parent / "bad_scenarios" / "fault_sensor_overlap.toml"
    run = subprocess.run(
        [sys.executable, "-m", "pmsm2dof", "simulate", str(path), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and run.stderr.startswith("pmsm2dof: error: fault.1.t_s = ")
    assert not any(tmp_path.iterdir())
