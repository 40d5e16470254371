"""docs/your-motor.md, "No datasheet: identify the machine": its commands run as written and do what it says."""

import json
import shutil
from pathlib import Path

import pytest
from test_readme_commands import readme_commands

from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]


def guide_commands():
    # design --motor reads the motor the guide's commission writes (identify --motor, of the guide
    # "Your motor", and design --motor of its datasheet keys read a file of examples/ instead)
    return [
        a
        for a in readme_commands("pmsm2dof")
        if a[0] == "commission"
        or (a[0] == "design" and "--motor" in a and not a[a.index("--motor") + 1].startswith("examples/"))
    ]


def test_the_guide_has_its_three_commands():
    assert [a[0] for a in guide_commands()] == ["commission", "commission", "design"]


@pytest.mark.slow
def test_commands_run_as_written(tmp_path, monkeypatch, capsys):
    shutil.copytree(ROOT / "examples" / "commissioning", tmp_path / "examples" / "commissioning")
    monkeypatch.chdir(tmp_path)
    first, second, design = guide_commands()
    assert main(first) == 0
    assert "salient servo: commissioning done" in capsys.readouterr().out
    written = {p.name for p in (tmp_path / "servo-id").iterdir()}
    assert written == {".pmsm2dof-outputs.json", "result.json", "log.csv", "plot.png", "motor.toml", "p2d_config.h"}
    # the paper's drive with a real inverter (dead time, noise, delay): within the targets
    assert main(second) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["phase"] == "done" and summary["within_targets"]
    # design from the identified motor: the header carries the identified machine
    assert main(design) == 0
    out = capsys.readouterr().out
    assert "Kp_q = Lq alpha_c" in out and "servo_config.h" in out
    header = (tmp_path / "servo_config.h").read_text()
    assert ".tau_i_s = 0.0005f" in header


def test_a_failed_run_as_the_guide_says(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    servo = str(ROOT / "examples" / "commissioning" / "servo-salient.toml")
    assert main(["commission", servo, "--set", "limits.u_dc_V=4"]) == 1
    assert "current_not_reached" in capsys.readouterr().out


@pytest.mark.parametrize("block", ["p2d_commission_step(&cm, id_A, iq_A, u_dc_V, &out)"])
def test_the_c_snippet_uses_the_real_signature(block):
    header = (ROOT / "csrc" / "include" / "pmsm2dof" / "commission.h").read_text()
    assert "void p2d_commission_step(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V," in header
    assert block in (ROOT / "docs" / "your-motor.md").read_text()
