"""`drive run`'s specification (pmsm2dof.studies.drive.judge) and `drive set --scenario`'s input, without a drive.

Truth from outside the metrics: the overshoot of the bench servo's first step read off its trace
by hand (the largest speed before the next reference change, over the step's size); the binding
miss is the one furthest from its limit relative to the limit. The command-line checks happen
before a link is opened (the link is a closed port) and leave no output folder.
"""

import socket

import numpy as np
import pytest

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.drive import check_limits, judge
from pmsm2dof.ui.cli import main

DATASHEET = "examples/bench/datasheet.toml"


@pytest.fixture(scope="module")
def trace():
    return simulate(load_scenario(DATASHEET))


def hand_overshoot_pct(trace):
    """The first step's (0 -> 2000 rpm, until the next change at 0.12 s) overshoot, from the trace."""
    window = trace.t_s < 0.12
    return (np.max(trace.speed_rpm[window]) - 2000.0) / 2000.0 * 100.0


def test_met_and_missed_by_the_figure_of_the_trace(trace):
    overshoot = hand_overshoot_pct(trace)
    assert overshoot > 0.5  # the datasheet design overshoots: the test can tell the two limits apart
    met = judge(trace, {"max_overshoot_pct": overshoot * 1.01})
    assert met["met"] is True and met["misses"] == []
    assert met["figures"]["overshoot_pct"] == pytest.approx(overshoot, rel=1e-3)
    missed = judge(trace, {"max_overshoot_pct": overshoot * 0.9})
    assert missed["met"] is False
    (miss,) = missed["misses"]
    assert miss["constraint"] == "max_overshoot_pct" and miss["unit"] == "%"
    assert miss["miss"] == pytest.approx(overshoot * 0.1, rel=1e-2)


def test_the_binding_miss_is_the_furthest_relative_to_its_limit(trace):
    overshoot = hand_overshoot_pct(trace)
    dip = judge(trace, {"max_load_dip_rpm_per_Nm": 1e6})["figures"]["load_dip_rpm_per_Nm"]
    assert dip > 0.0
    limits = {"max_overshoot_pct": overshoot / 3.0, "max_load_dip_rpm_per_Nm": dip / 1.5}
    misses = judge(trace, limits)["misses"]
    assert [m["constraint"] for m in misses] == ["max_overshoot_pct", "max_load_dip_rpm_per_Nm"]
    limits = {"max_overshoot_pct": overshoot / 1.5, "max_load_dip_rpm_per_Nm": dip / 3.0}
    assert judge(trace, limits)["misses"][0]["constraint"] == "max_load_dip_rpm_per_Nm"


def test_a_load_step_never_recovered_misses_any_recovery_limit(trace):
    verdict = judge(trace, {"max_recovery_s": 1.0})
    assert verdict["figures"]["load_recovery_s"] is None  # the datasheet design: not recovered in its window
    assert verdict["met"] is False and verdict["misses"][0]["value"] is None


@pytest.mark.parametrize(
    "limits, name",
    [({"max_overshoot_pct": -1.0}, "max_overshoot_pct"), ({"max_settling_s": 0.0}, "max_settling_s"),
     ({"min_phase_margin_deg": 45.0}, "min_phase_margin_deg"), ({"J_range": 1.0}, "J_range")],
)  # fmt: skip
def test_limits_are_checked(limits, name):
    with pytest.raises(ConfigError) as err:
        check_limits(limits)
    assert err.value.param == name


def closed_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(
    "argv, words",
    [(["drive", "set"], "NAME=VALUE"),
     (["drive", "set", "speed_controller.zeta=1", "--scenario", DATASHEET], "one of the two"),
     (["drive", "run", DATASHEET, "--max-overshoot-pct", "-1"], "--max-overshoot-pct"),
     (["drive", "run", DATASHEET, "--max-recovery-s", "nan"], "--max-recovery-s")],
)  # fmt: skip
def test_bad_input_is_one_line_before_the_link(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    extra = ["--out", str(out)] if argv[1] == "run" else []
    link = ["--link", f"tcp://127.0.0.1:{closed_port()}", "--a2l", str(tmp_path / "none.a2l")]
    code = main([*argv, *extra, *link])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and words in err and "Traceback" not in err, err
    assert not out.exists()
