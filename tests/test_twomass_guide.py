"""The manual's two-mass guide (docs/sensing.md) runs as written and shows what it says."""

import numpy as np
import pandas as pd
import pytest
from test_readme_commands import readme_commands

from pmsm2dof.ui.cli import main


def test_twomass_commands_show_the_notch_stabilizing_the_load_side_loop(capsys):
    commands = [a for a in readme_commands("pmsm2dof") if a[0] == "twomass"]
    assert len(commands) == 2
    outputs = []
    for args in commands:
        assert main(args) == 0
        outputs.append(capsys.readouterr().out)
    assert "UNSTABLE" in outputs[0] and "resonance                  30 Hz" in outputs[0]
    assert "(load side)  stable" in outputs[1]


@pytest.mark.slow
def test_two_mass_simulation_runs_as_written(tmp_path, monkeypatch):
    (args,) = [a for a in readme_commands("pmsm2dof") if a[0] == "simulate" and "mechanics.model=two_mass" in a]
    monkeypatch.chdir(tmp_path)
    assert main(args) == 0
    trace = pd.read_csv(tmp_path / args[args.index("--out") + 1] / "trace.csv")
    # the load side's torque balance over the last second: T_s = T_load + J_L dw_L/dt
    last = trace[trace["t_s"] > 14.0]
    w_L = last["load_speed_rpm"].to_numpy() * np.pi / 30.0
    accel = np.gradient(w_L, last["t_s"].to_numpy())
    balance = last["load_Nm"].to_numpy() + 0.3 * accel
    assert np.max(np.abs(last["shaft_torque_Nm"].to_numpy() - balance)[1:-1]) < 1e-3
    assert last["load_Nm"].iloc[-1] == 8.0
