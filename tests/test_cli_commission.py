"""`pmsm2dof commission`: the table, the JSON, the output folder, a failed run and bad input."""

import json
import tomllib
from pathlib import Path

import pytest

from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
SERVO = str(ROOT / "examples" / "commissioning" / "servo-salient.toml")


def snapshot(folder):
    return sorted((str(p.relative_to(folder)), p.read_bytes() if p.is_file() else None) for p in folder.rglob("*"))


def test_table_compares_with_the_truth(capsys):
    assert main(["commission", SERVO]) == 0
    out = capsys.readouterr().out
    assert "salient servo: commissioning done" in out
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:6]}
    assert list(rows) == ["Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb"]
    assert float(rows["Lq_H"][2]) == 0.008 and float(rows["Ld_H"][2]) == 0.004  # the scenario's truth
    assert "ramp_down" in out and "total" in out


def test_json_and_output_folder(tmp_path, capsys):
    out = tmp_path / "servo"
    assert main(["commission", SERVO, "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["phase"] == "done" and summary["within_targets"]
    assert summary == json.loads((out / "result.json").read_text())
    assert summary["total_time_s"] == pytest.approx(sum(summary["phase_time_s"].values()))
    motor = tomllib.loads((out / "motor.toml").read_text())["motor"]
    assert motor["pole_pairs"] == 4
    assert motor["Lq_H"] == pytest.approx(0.008, rel=0.005) and motor["Ld_H"] == pytest.approx(0.004, rel=0.005)
    assert (out / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    header = (out / "log.csv").read_text().splitlines()[0]
    assert header.split(",")[:3] == ["t_s", "phase", "id_A"]


def test_a_failed_run_exits_1_and_writes_no_motor(tmp_path, capsys):
    out = tmp_path / "low"
    assert main(["commission", SERVO, "--set", "limits.u_dc_V=4", "--out", str(out)]) == 1
    text = capsys.readouterr().out
    assert "failed in probe: current_not_reached" in text
    assert sorted(p.name for p in out.iterdir()) == [".pmsm2dof-outputs.json", "log.csv", "plot.png", "result.json"]


def test_bad_setting_one_line_exit_2_nothing_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code = main(["commission", SERVO, "--set", "commissioning.i_trip_A=2.5", "--out", "out"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("pmsm2dof: error: commissioning.i_trip_A = 2.5 is invalid")
    assert "Traceback" not in err
    assert snapshot(tmp_path) == before
