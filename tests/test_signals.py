"""SIGTERM and SIGHUP end a command as SIGINT does: exit 143 or 129, "terminated", nothing half-written.

Each command runs in a real subprocess in which every file write takes a while (so that the
signal arrives while the outputs are being written: the staging folder holds some of them); the
test waits for that, sends the signal and inspects the folder: no staging folder, the output
folder absent (a first run) or as the earlier run left it. A sweep keeps its finished parts,
each sound, and resumes. The tuner stops on both signals.
"""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from pmsm2dof.studies.engine import _PART_NAME

ROOT = Path(__file__).resolve().parents[1]

#: Runs the command with every file of pmsm2dof.outputs written slowly (SLOW_WRITE_S after each).
SLOW_MAIN = textwrap.dedent(
    """
    import contextlib, os, sys, time
    import pmsm2dof.outputs as outputs

    real = outputs.atomic_file

    @contextlib.contextmanager
    def slow(path, mode="w"):
        with real(path, mode) as f:
            yield f
        time.sleep(float(os.environ.get("SLOW_WRITE_S", "0")))

    outputs.atomic_file = slow
    from pmsm2dof.ui.cli import main

    sys.exit(main(sys.argv[1:]))
    """
)


def start(argv, cwd, slow_write_s=1.0):
    env = dict(os.environ, SLOW_WRITE_S=str(slow_write_s), OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen(
        [sys.executable, "-c", SLOW_MAIN, *argv], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )


def wait_for(condition, proc, timeout_s):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert proc.poll() is None, f"ended before the signal: {proc.communicate()}"
        assert time.monotonic() < deadline, "the condition was not reached in time"
        time.sleep(0.05)


def staging(parent, out_name):
    """The files in the hidden staging folders of ``out_name`` (and its temporary files)."""
    return [p for p in parent.glob(f".{out_name}.*") for p in ([p] if p.is_file() else p.rglob("*")) if p.is_file()]


def terminate(proc, signum):
    proc.send_signal(signum)
    _out, err = proc.communicate(timeout=120)
    return proc.returncode, err.decode()


def assert_terminated(code, err, signum):
    assert code == 128 + signum, err
    assert err.rstrip().splitlines()[-1] == "pmsm2dof: terminated" and "Traceback" not in err


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_simulate_killed_while_writing_leaves_nothing(tmp_path, signum):
    proc = start(["simulate", "paper-condition-2", "--out", "out"], tmp_path)
    wait_for(lambda: staging(tmp_path, "out"), proc, 120)
    assert_terminated(*terminate(proc, signum), signum)
    assert list(tmp_path.iterdir()) == []


def test_simulate_killed_while_replacing_keeps_the_earlier_run(tmp_path):
    short = ["simulate", "paper-experiment-1", "--set", "simulation.t_end_s=1", "--out", "out"]
    assert subprocess.run([sys.executable, "-m", "pmsm2dof", *short], cwd=tmp_path).returncode == 0
    before = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    proc = start([*short, "--set", "reference.0.speed_rpm=100"], tmp_path)
    wait_for(lambda: staging(tmp_path, "out"), proc, 120)
    assert_terminated(*terminate(proc, signal.SIGTERM), signal.SIGTERM)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()} == before


def test_sweep_killed_keeps_sound_parts_and_resumes(tmp_path):
    (tmp_path / "sweep.toml").write_text(
        textwrap.dedent(
            """
            base = "paper-condition-2"
            worst = 0
            [axes]
            "speed_controller.alpha_radps" = { start = 0.3, stop = 0.9, num = 200 }
            """
        )
    )
    argv = ["sweep", "sweep.toml", "--out", "out", "--workers", "1", "--batch-size", "1", "--no-figures"]
    proc = start(argv, tmp_path, slow_write_s=0.1)
    wait_for(lambda: len(list((tmp_path / "out" / "parts").glob("part-*"))) >= 2, proc, 120)
    assert_terminated(*terminate(proc, signal.SIGTERM), signal.SIGTERM)
    parts = list((tmp_path / "out" / "parts").iterdir())
    assert 2 <= len(parts) < 200 and all(_PART_NAME.fullmatch(p.name) for p in parts)
    assert not (tmp_path / "out" / "results.csv").exists() and not staging(tmp_path, "out")
    run = subprocess.run([sys.executable, "-m", "pmsm2dof", *argv], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0 and "warning" not in run.stderr and "Traceback" not in run.stderr, run.stderr
    assert f"({200 - len(parts)} simulated, {len(parts)} already done)" in run.stdout


@pytest.mark.slow
def test_autotune_killed_while_writing_leaves_nothing(tmp_path):
    proc = start(["autotune", "paper-condition-2", "--out", "out", "--workers", "2"], tmp_path)
    wait_for(lambda: staging(tmp_path, "out"), proc, 600)
    assert_terminated(*terminate(proc, signal.SIGTERM), signal.SIGTERM)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_reproduce_killed_while_writing_its_figures_leaves_nothing(tmp_path):
    proc = start(["reproduce", "--out", "report"], tmp_path, slow_write_s=0.2)
    wait_for(lambda: len(staging(tmp_path, "report")) >= 3, proc, 900)
    assert_terminated(*terminate(proc, signal.SIGTERM), signal.SIGTERM)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_the_tuner_stops_on_the_signal(tmp_path, signum):
    proc = subprocess.Popen(
        [sys.executable, "-m", "pmsm2dof", "tune", "--port", "0", "--no-browser"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline()
    assert "pmsm2dof tuner for" in line, proc.stderr.read() if proc.poll() is not None else line
    proc.send_signal(signum)
    _out, err = proc.communicate(timeout=60)
    assert_terminated(proc.returncode, err, signum)
