"""Unstable and chattering runs are named, not summarised as good (and not refused).

Truth from outside the code under test:

- the closed-loop poles of the sampled speed loop from the characteristic polynomial derived
  here by hand: the Tustin PI ``(b0 z + (Ki Ts - b0)) / (z - 1)``, ``b0 = Kp + Ki Ts / 2``
  (eq 9, 14), on the ZOH equivalent of ``1 / (J s (tau s + 1))``,
  ``(n1 z + n0) / (J (z - 1)(z - a))``, ``a = exp(-Ts/tau)``, ``n1 = Ts - tau (1 - a)``,
  ``n0 = tau (1 - a) - a Ts`` (step invariance), so that
  ``J (z - 1)^2 (z - a) + (b0 z + Ki Ts - b0)(n1 z + n0) = 0``, solved by numpy.roots;
- a command that bangs between the current limits, seen in the trace as the sign flips of the
  q current command from one limit to the other; the second difference of a sinusoid in closed
  form, ``4 sin^2(w Ts / 2) A``.
"""

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from oracles import small_servo
from pmsm2dof.sim.metrics import CHATTER_D2, CHATTER_SHARE_MAX, chatter, summary_lines
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.loopcheck import measure, sampled_loop
from pmsm2dof.ui.cli import cli

TAU_I_S = 5e-4  # small_servo's current loop


def analytic_poles(J_design, alpha, zeta, J_plant, tau_s, Ts):
    Kp, Ki = J_design * alpha, J_design * (alpha / (2 * zeta)) ** 2  # eq 9
    b0 = Kp + Ki * Ts / 2  # Tustin, eq 14
    a = math.exp(-Ts / tau_s)
    n1, n0 = Ts - tau_s * (1 - a), tau_s * (1 - a) - a * Ts
    char = J_plant * np.polymul(np.polymul([1, -1], [1, -1]), [1, -a]) + np.polyadd(
        np.zeros(4), np.polymul([b0, Ki * Ts - b0], [n1, n0])
    )
    return np.roots(char)


def scenario(**speed_controller):
    return small_servo.scenario(
        reference=((0.0, 3000.0), (0.3, -3000.0)), load=((0.1, 0.1), (0.25, 0.0)), **speed_controller
    )


@pytest.mark.parametrize("alpha", [300.0, 1500.0, 2500.0, 3000.0, 4000.0])
def test_stability_check_against_analytic_poles(alpha):
    check = sampled_loop(scenario(alpha_radps=alpha))
    z = np.max(np.abs(analytic_poles(small_servo.J_KGM2, alpha, 1.0, small_servo.J_KGM2, TAU_I_S, 5e-4)))
    assert check["design"]["z_max"] == pytest.approx(z, rel=1e-5)  # float32 coefficients in the C controller
    assert check["stable"] == (z < 1.0)
    assert check["plant"] is None  # the design's plant is the scenario's
    assert bool(check["warning"]) == (z >= 1.0)
    if z >= 1.0:
        assert f"|z| = {check['design']['z_max']:.6g}" in check["warning"]


def test_inertia_typed_in_the_wrong_unit_is_unstable_on_the_plant():
    """J = 181 (g cm^2 typed as kg m^2) for the design: stable on paper, unstable on the 7.24e-5 kg m^2 rotor."""
    check = sampled_loop(scenario(J_kgm2=181.0))
    own = np.max(np.abs(analytic_poles(181.0, 300.0, 1.0, 181.0, TAU_I_S, 5e-4)))
    on_plant = np.max(np.abs(analytic_poles(181.0, 300.0, 1.0, small_servo.J_KGM2, TAU_I_S, 5e-4)))
    assert own < 1.0 < on_plant
    assert check["design"]["stable"] and check["design"]["z_max"] == pytest.approx(own, rel=1e-5)
    assert not check["plant"]["stable"] and check["plant"]["z_max"] == pytest.approx(on_plant, rel=1e-4)
    assert not check["stable"] and "on the scenario's plant" in check["warning"]


def test_simulate_warns_and_does_not_refuse(tmp_path):
    path = tmp_path / "servo.toml"
    path.write_text(scenario().to_toml())
    out = tmp_path / "run"
    r = CliRunner().invoke(
        cli, ["simulate", str(path), "--set", "speed_controller.alpha_radps=3000", "--out", str(out)]
    )
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert "UNSTABLE SAMPLED LOOP" in lines[1] and "CHATTER" in lines[2]  # before any figure
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["sampled_loop"]["stable"] is False
    assert metrics["warnings"][0].startswith("UNSTABLE SAMPLED LOOP")
    assert metrics["run"]["chatter_share"]["value"] > CHATTER_SHARE_MAX


@pytest.mark.parametrize(
    "changes, words",
    [
        # 300 speed periods with the current loop at the speed loop's rate: within the scenario's
        # 2046 current periods, beyond the analysis' 256 speed periods
        ({"current_loop.Ts_s": 5e-4, "speed_sensor.delay_s": 0.15}, "speed_sensor.delay_s = 0.15 is invalid"),
        # shorter than its Pade approximant takes; the engine runs it
        ({"speed_sensor.delay_s": 1e-13}, "speed_sensor.delay_s = 1e-13 is invalid"),
    ],
)
def test_a_run_the_analysis_does_not_take_says_the_check_was_not_made(tmp_path, changes, words):
    """The engine runs such a scenario; the check that would exceed the analysis' bounds is not made
    (instead of failing the run after it), and the warning names the key and the bound."""
    from pmsm2dof.studies.sweep import flatten_metrics

    chosen = scenario().with_overrides(changes)
    check = sampled_loop(chosen)
    assert check["stable"] is None and check["design"] is None and check["plant"] is None
    assert check["warning"].startswith("the sampled-loop stability check was not made") and words in check["warning"]
    metrics = measure(simulate(chosen))
    assert metrics["warnings"][0] == check["warning"]
    row, notes = flatten_metrics(metrics)
    assert row["sampled_loop_z_max"] is None and f"sampled_loop_z_max: {check['warning']}" in notes
    path = tmp_path / "servo.toml"
    path.write_text(chosen.to_toml())
    r = CliRunner().invoke(cli, ["simulate", str(path), "--out", str(tmp_path / "run")])
    assert r.exit_code == 0, r.output
    assert "the sampled-loop stability check was not made" in r.output.splitlines()[1]


def test_the_sweep_summary_names_a_point_whose_check_was_not_made(capsys):
    import pandas as pd

    from pmsm2dof.ui.cli.sweep import _sweep_warnings

    table = pd.DataFrame(
        {
            "point": [0, 1, 2],
            "sampled_loop_z_max": pd.array([None, 1.2, 0.5], dtype="Float64"),
            "run_chatter_share": [0.9, 0.0, 0.0],
        }
    )
    _sweep_warnings(table)
    lines = capsys.readouterr().out.splitlines()
    assert "1 points with an unstable sampled loop" in lines[0] and "1 whose current command chatters" in lines[0]
    assert lines[1:] == [
        "  point 0: largest closed-loop pole |z| = not computed (see the notes), chatter share 0.9",
        "  point 1: largest closed-loop pole |z| = 1.2, chatter share 0",
    ]


def flips_between_limits(iq_ref, i_max):
    """The share of samples at which the command jumps from one current limit to the other."""
    at = np.where(iq_ref >= 0.99 * i_max, 1, np.where(iq_ref <= -0.99 * i_max, -1, 0))
    return np.mean((at[1:] * at[:-1]) == -1)


@pytest.mark.parametrize("overrides", [{"J_kgm2": 181.0}, {"alpha_radps": 3000.0}])
def test_chatter_names_a_run_that_bangs_between_the_limits(overrides):
    result = simulate(scenario(**overrides))
    m = measure(result)
    share = m["run"]["chatter_share"]["value"]
    assert share > CHATTER_SHARE_MAX
    if "J_kgm2" in overrides:
        # the command jumps from one limit to the other at a fifth of the samples or more
        assert flips_between_limits(result.iq_ref_A, small_servo.I_MAX_A) > 0.2
    text = summary_lines(m)
    assert text[0].startswith("UNSTABLE SAMPLED LOOP") and text[1].startswith("CHATTER")


@pytest.mark.parametrize("name", ["small servo", "paper-condition-1", "paper-condition-2", "fault-sensor-spike"])
def test_no_chatter_on_a_run_that_does_not(name):
    s = scenario() if name == "small servo" else load_scenario(name)
    result = simulate(s)
    m = measure(result)
    assert flips_between_limits(result.iq_ref_A, s.data["limits"]["i_max_A"]) == 0.0
    assert m["run"]["chatter_share"]["value"] <= CHATTER_SHARE_MAX
    assert m["warnings"] == [] and m["sampled_loop"]["stable"]


@pytest.mark.parametrize("w_Ts", [0.1, 0.3, 1.0, math.pi / 2, math.pi])
def test_chatter_of_a_sinusoid_in_closed_form(w_Ts):
    """A full-amplitude sinusoid: |second difference| = 4 sin^2(w Ts / 2) |sin(w Ts k + phase)|."""
    k = np.arange(4000)
    command = 10.0 * np.sin(w_Ts * k + 0.3)
    d2 = 4 * math.sin(w_Ts / 2) ** 2 * np.abs(np.sin(w_Ts * k[1:-1] + 0.3))  # relative to the limit 10
    assert chatter(command, 10.0) == pytest.approx(np.mean(d2 >= CHATTER_D2), abs=1e-3)
    if w_Ts <= 0.1:  # the band a design keeps to: never chatter, even at the full amplitude
        assert chatter(command, 10.0) == 0.0


def test_the_tuner_shows_the_warnings():
    from pmsm2dof.ui.tuner.experiment import Tuner

    page = Tuner(scenario()).run({"speed_controller.alpha_radps": 3000.0})
    assert page["warnings"][0].startswith("UNSTABLE SAMPLED LOOP") and page["warnings"][1].startswith("CHATTER")
    assert Tuner(scenario()).run({})["warnings"] == []
