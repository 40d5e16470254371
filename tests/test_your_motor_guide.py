"""The manual's guide "Your motor" (docs/your-motor.md) runs as written and finds the drive's inertia.

The commands are read from the guide's section of docs/your-motor.md; the truth is the example drive's
motor.J_kgm2 (the plant of the simulated log), not anything the commands print.
"""

import json
import re
import shlex
import shutil
from pathlib import Path

import pytest

from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
HEADING = "## Your motor: datasheet, log, identify, design, header"


def guide_commands():
    text = (ROOT / "docs" / "your-motor.md").read_text()
    section = text[text.index(HEADING) :]
    section = section[: section.index("\n## ", 1)]
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", section, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            args = shlex.split(line, comments=True)
            if args and args[0] == "pmsm2dof":
                commands.append(args[1:])
    return commands


@pytest.mark.slow
def test_the_guide_runs_as_written_and_identifies_the_drive(tmp_path, monkeypatch, capsys):
    for example in ("your-motor", "ec45-flat"):
        shutil.copytree(ROOT / "examples" / example, tmp_path / "examples" / example)
    monkeypatch.chdir(tmp_path)
    commands = guide_commands()
    # the chain on the example drive, then a catalogue motor in maxon's convention
    chain = ["motor", "identify", "simulate", "identify", "design", "simulate", "motor", "design", "simulate"]
    assert [c[0] for c in commands] == chain
    for args in commands:
        assert main(args) == 0, args
    out = capsys.readouterr().out
    assert "consistent" in out  # Kt and Ke of the example agree
    truth = load_scenario(tmp_path / "examples" / "your-motor" / "drive.toml").data["motor"]
    report = json.loads((tmp_path / "ident" / "identify.json").read_text())
    assert report["J_kgm2"] == pytest.approx(truth["J_kgm2"], rel=0.02)
    assert report["T_coulomb_Nm"] == pytest.approx(truth["T_coulomb_Nm"], rel=0.15)
    assert report["B_Nms"] == pytest.approx(truth["B_Nms"], rel=0.35)
    # the design's J is the identified one, rounded as the guide writes it
    assert load_scenario(tmp_path / "plan" / "plan.toml").data["reference"]
    design_J = float(commands[4][commands[4].index("--J-kgm2") + 1])
    assert design_J == pytest.approx(report["J_kgm2"], rel=0.01)
    assert "p2d_speed_config_t" in (tmp_path / "speed_config.h").read_text()
    identified = load_scenario(tmp_path / "ident" / "identified.toml")
    assert identified.data["speed_controller"]["J_kgm2"] == report["J_kgm2"]
    import pandas as pd

    adapted = pd.read_csv(tmp_path / "run-adapted" / "trace.csv")
    assert adapted["J_gains_kgm2"].iloc[-1] == pytest.approx(truth["J_kgm2"], rel=0.05)
    # the catalogue motor's run is summarised from its own trace
    assert (tmp_path / "ec45" / "trace.csv").is_file()
