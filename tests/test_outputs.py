"""Output folders never destroy what pmsm2dof did not write (pmsm2dof.outputs, and every command with --out).

A folder holding a file of the user's is refused before any work (naming the file) unless
--force, which keeps the file; an earlier run's outputs of the same command are replaced whole,
stale ones included; an empty --out and a symbolic-link loop are refused in one line; a full disk
is named with the room there was. Truth: the files on disk, byte for byte.
"""

import errno
import os
import re
from pathlib import Path

import pytest

import pmsm2dof.outputs as outputs
from pmsm2dof.errors import ConfigError
from pmsm2dof.outputs import MANIFEST, atomic_file, atomic_write, check_out, staged_dir
from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
SERVO = str(ROOT / "examples" / "commissioning" / "servo-salient.toml")
#: A short simulation, for the commands' folders.
SHORT = ["simulate", "paper-experiment-1", "--set", "simulation.t_end_s=0.2", "--set", "reference.0.t_s=0.05"]


def snapshot(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def one_error_line(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pmsm2dof: error: ") and "Traceback" not in err, err
    return err


def test_reproduce_into_a_folder_holding_a_users_file_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """The issue's probe: `mkdir -p proj/figures; echo notes > proj/figures/notes.txt; pmsm2dof
    reproduce --out proj` deleted notes.txt (exit 0)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "proj" / "figures").mkdir(parents=True)
    (tmp_path / "proj" / "figures" / "notes.txt").write_text("notes\n")
    assert main(["reproduce", "--out", "proj"]) == 2
    err = one_error_line(capsys)
    assert "--out = 'proj'" in err and "'figures/notes.txt'" in err and "--force" in err
    assert snapshot(tmp_path) == {"proj/figures/notes.txt": b"notes\n"}


def test_force_writes_beside_the_users_file_and_keeps_it(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("notes\n")
    (out / "trace.csv").write_text("my own trace\n")  # a name the command writes: --force replaces it
    assert main([*SHORT, "--out", str(out)]) == 2
    assert "'notes.txt'" in one_error_line(capsys)
    assert main([*SHORT, "--out", str(out), "--force"]) == 0
    files = snapshot(out)
    assert files["notes.txt"] == b"notes\n"
    assert files["trace.csv"].startswith(b"t_s,")
    assert set(files) == {"notes.txt", MANIFEST, "trace.csv", "metrics.json", "plot.png", "scenario.toml"}
    # the manifest lists what the command wrote, not the user's file: without --force it is refused again
    assert main([*SHORT, "--out", str(out)]) == 2
    assert "'notes.txt'" in one_error_line(capsys)


def test_a_second_run_replaces_the_first_and_a_changed_output_is_the_users(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*SHORT, "--out", str(out)]) == 0
    first = snapshot(out)
    assert main([*SHORT, "--set", "reference.0.speed_rpm=200", "--out", str(out)]) == 0
    second = snapshot(out)
    assert set(second) == set(first) and second["trace.csv"] != first["trace.csv"]
    with open(out / "scenario.toml", "a") as f:  # the user edits an output
        f.write("# my change\n")
    capsys.readouterr()
    assert main([*SHORT, "--out", str(out)]) == 2
    assert "'scenario.toml' (changed since pmsm2dof simulate wrote it)" in one_error_line(capsys)
    assert (out / "scenario.toml").read_text().endswith("# my change\n")


def test_a_folder_of_another_command_is_not_replaced(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*SHORT, "--out", str(out)]) == 0
    before = snapshot(out)
    capsys.readouterr()
    assert main(["commission", SERVO, "--out", str(out)]) == 2
    err = one_error_line(capsys)
    assert "an earlier commission" in err and "'metrics.json' (written by pmsm2dof simulate)" in err
    assert snapshot(out) == before


def test_a_failed_commissioning_over_a_successful_one_leaves_no_old_motor(tmp_path, capsys):
    """The stale motor.toml of the earlier run would be read by design --motor as if just identified."""
    out = tmp_path / "c"
    assert main(["commission", SERVO, "--out", str(out)]) == 0
    assert (out / "motor.toml").exists()
    assert main(["commission", SERVO, "--set", "limits.u_dc_V=4", "--out", str(out)]) == 1
    assert set(snapshot(out)) == {MANIFEST, "result.json", "log.csv", "plot.png"}
    assert '"phase": "failed"' in (out / "result.json").read_text()


@pytest.mark.parametrize("out", ["", " "])
def test_an_empty_out_is_refused(out, tmp_path, capsys, monkeypatch):
    """`--out ""` wrote into the current folder, replacing its trace.csv and the rest."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "trace.csv").write_text("mine\n")
    assert main([*SHORT, "--out", out]) == 2
    assert "--out = " in one_error_line(capsys)
    assert snapshot(tmp_path) == {"trace.csv": b"mine\n"}


@pytest.mark.parametrize("below", ["", "/inner"])
def test_a_symbolic_link_loop_is_refused_in_one_line(below, tmp_path, capsys):
    (tmp_path / "loop").symlink_to("loop")
    assert main([*SHORT, "--out", str(tmp_path / "loop") + below]) == 2
    assert "can be resolved" in one_error_line(capsys)


def test_earlier_outputs_are_replaced_whole_stale_ones_removed(tmp_path):
    out = tmp_path / "out"
    with staged_dir(out, "study") as tmp:
        atomic_write(tmp / "a.txt", "1")
        atomic_write(tmp / "figures" / "f1.png", "1")
        atomic_write(tmp / "figures" / "f2.png", "1")
    (out / "mine").mkdir()  # an empty folder of the user's: no file, kept
    with staged_dir(out, "study") as tmp:
        atomic_write(tmp / "a.txt", "2")
        atomic_write(tmp / "b.txt", "2")
    assert snapshot(out) == {"a.txt": b"2", "b.txt": b"2", MANIFEST: (out / MANIFEST).read_bytes()}
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["mine"]  # figures/ emptied and removed


def test_a_new_folder_gets_the_mode_mkdir_gives(tmp_path):
    with staged_dir(tmp_path / "out", "study") as tmp:
        atomic_write(tmp / "a.txt", "1")
    umask = os.umask(0)
    os.umask(umask)
    assert (tmp_path / "out").stat().st_mode & 0o777 == 0o777 & ~umask
    assert ((tmp_path / "out" / "a.txt").stat().st_mode & 0o777) == 0o666 & ~umask


def test_a_failure_inside_leaves_the_folder_and_no_staging(tmp_path):
    out = tmp_path / "out"
    with staged_dir(out, "study") as tmp:
        atomic_write(tmp / "a.txt", "1")
    before = snapshot(out)
    with pytest.raises(KeyboardInterrupt), staged_dir(out, "study") as tmp:
        atomic_write(tmp / "a.txt", "2")
        raise KeyboardInterrupt
    assert snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_full_disk_names_the_output_and_the_room(tmp_path, monkeypatch):
    """`[Errno 28] No space left on device` named nothing; now the file, what was written and the room."""
    real_fdopen = os.fdopen

    class FullDisk:
        def __init__(self, f):
            self.f = f
            self.written = 0

        def write(self, data):
            if self.written + len(data) > 1000:
                raise OSError(errno.ENOSPC, "No space left on device")
            self.written += len(data)
            return self.f.write(data)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    monkeypatch.setattr(outputs.os, "fdopen", lambda *a, **k: FullDisk(real_fdopen(*a, **k)))
    out = tmp_path / "out"
    with pytest.raises(ConfigError) as info, staged_dir(out, "study") as tmp:
        with atomic_file(tmp / "trace.csv") as f:
            for _ in range(100):
                f.write("0123456789" * 5)
    assert info.value.param == "out" and info.value.value == str(out / "trace.csv")
    assert re.search(r"the disk filled up after \d+ B of it \(.* free once that was removed\)", info.value.valid)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_check_out_refuses_before_any_work(tmp_path):
    (tmp_path / "file").write_text("x")
    for bad, words in [
        ("", "not empty"),
        (tmp_path / "file", "an existing file"),
        (tmp_path / "file" / "below", "writable folder"),
    ]:
        with pytest.raises(ConfigError, match=words):
            check_out(bad, "study")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_a_failed_run_leaves_no_folder_it_created_above_out(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*SHORT, "--set", "speed_controller.Ka=1e9", "--out", "a/b/out"]) == 2
    assert "speed_controller.Ka" in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []
    check_out("c/d/out", "study")  # the check alone creates nothing either
    assert list(tmp_path.iterdir()) == []


def test_a_device_or_fifo_is_never_replaced_by_a_file(tmp_path):
    """As root, the rename of a header written to /dev/null would put a file in its place; a FIFO
    stands for the device here."""
    os.mkfifo(tmp_path / "fifo.h")
    for path in (tmp_path / "fifo.h", tmp_path):
        with pytest.raises(ConfigError, match="a device, a FIFO"):
            atomic_write(path, "x")
    assert (tmp_path / "fifo.h").is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["fifo.h"]
    code = main(
        [
            "design",
            "--J-kgm2",
            "0.4",
            "--alpha-radps",
            "0.5",
            "--zeta",
            "0.3",
            "--Ts-s",
            "1e-3",
            "--paper-drive",
            "--emit-c-header",
            str(tmp_path / "fifo.h"),
        ]
    )
    assert code == 2 and (tmp_path / "fifo.h").is_fifo()
