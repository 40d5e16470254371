"""One default feedforward everywhere: the paper's lowpass of eq 13, discretized as eq 15.

Truth: the default the documentation promises, checked in every entry point that has one
(design(), SpeedController, the scenario schema, `pmsm2dof design` and `pmsm2dof bode`).
"""

import json
import tomllib

import pytest

from pmsm2dof import SpeedController, design, load_scenario
from pmsm2dof.sim.scenario import Scenario
from pmsm2dof.ui.cli import main
from pmsm2dof.ui.plots.design import bode_gx_sweep

MOTOR = dict(Ts_s=1e-3, i_max_A=7.6, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01, pole_pairs=4)
DEFAULT = "lowpass"


def test_design_function_default():
    assert design(0.4, 0.5, 0.2887).feedforward == DEFAULT


def test_speed_controller_default():
    assert SpeedController(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, **MOTOR).config["feedforward"] == DEFAULT


def test_scenario_default():
    tree = tomllib.loads(load_scenario("paper-condition-1").to_toml())
    del tree["speed_controller"]["feedforward"]
    assert Scenario.from_dict(tree).data["speed_controller"]["feedforward"] == DEFAULT


def test_cli_design_default(capsys):
    assert (
        main(["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--Ts-s", "1e-3", "--json"]) == 0
    )
    assert json.loads(capsys.readouterr().out)["feedforward"] == DEFAULT


@pytest.mark.slow
def test_bode_default_draws_the_lowpass(tmp_path, capsys):
    assert main(["bode", "--alpha-radps", "0.5", "--out", str(tmp_path / "gx.png")]) == 0
    title = bode_gx_sweep(0.5, [1.0]).axes[0].get_title()
    assert f"feedforward {DEFAULT}" in title


def test_m_other_than_1_without_a_feedforward_says_to_choose_no_tau_or_full(capsys):
    for make in (
        lambda: design(0.4, 0.5, 0.2887, m=2.0),
        lambda: SpeedController(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, m=2.0, **MOTOR),
        lambda: bode_gx_sweep(0.5, [0.5, 1.0]),
    ):
        with pytest.raises(ValueError, match=r"^m = (2|0\.5)\b.*no_tau'? or '?full") as exc:
            make()
        assert "lowpass" in str(exc.value)
    assert (
        main(["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--Ts-s", "1e-3", "--m", "2"])
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no_tau' or 'full" in err
