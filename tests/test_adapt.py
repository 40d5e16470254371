"""The engine runs the C inertia estimator beside the speed controller, and schedules the gains by its J.

Truth: the plant's motor.J_kgm2 of the scenario; the estimator is passive unless adapt_gains is
set (every other signal bit-identical); a re-designed controller responds as one designed for the
true J from the start (eq 9 with the true J is the reference response).
"""

import numpy as np
import pytest
from test_identify import drive_scenario

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Result, simulate

ESTIMATOR_SIGNALS = ("J_est_kgm2", "J_valid", "T_load_est_Nm", "J_gains_kgm2")


@pytest.mark.parametrize(("preset", "excited"), [("paper-condition-2", True), ("fault-sensor-spike", False)])
def test_the_estimator_alone_changes_no_other_signal(preset, excited):
    base = load_scenario(preset)
    off = simulate(base)
    on = simulate(base.with_overrides({"estimator.enabled": True}))
    for name in Result.signals:
        if name not in ESTIMATOR_SIGNALS:
            np.testing.assert_array_equal(getattr(on, name), getattr(off, name), err_msg=name)
    assert np.all(off.J_est_kgm2 == 0.0) and not np.any(off.J_valid)
    assert np.all(off.J_gains_kgm2 == np.float32(base.data["speed_controller"]["J_kgm2"]))
    assert np.any(on.J_valid) == excited  # a run at constant speed never makes J valid


@pytest.mark.parametrize("ratio", [0.5, 2.0])
def test_the_estimate_converges_to_the_plant_inertia(ratio):
    J = 0.01
    run = simulate(
        drive_scenario(J, 0.003, 0.3).with_overrides({"speed_controller.J_kgm2": J / ratio, "estimator.enabled": True})
    )
    assert run.J_est_kgm2[0] == pytest.approx(J / ratio)
    late = run.t_s > 1.0
    assert np.all(run.J_valid[late])
    assert np.max(np.abs(run.J_est_kgm2[late] / J - 1)) < 0.02
    # without adapt_gains the controller keeps its design
    assert np.all(run.J_gains_kgm2 == np.float32(J / ratio))


@pytest.mark.parametrize("ratio", [0.5, 2.0])
def test_adapted_gains_respond_as_the_design_for_the_true_inertia(ratio):
    J = 0.01
    base = drive_scenario(J, 0.003, 0.3)
    matched = simulate(base)
    fixed = simulate(base.with_overrides({"speed_controller.J_kgm2": J / ratio}))
    adapted = simulate(
        base.with_overrides(
            {"speed_controller.J_kgm2": J / ratio, "estimator.enabled": True, "estimator.adapt_gains": True}
        )
    )
    assert adapted.J_gains_kgm2[-1] == pytest.approx(J, rel=0.05)
    changes = np.flatnonzero(np.diff(adapted.J_gains_kgm2)) + 1
    assert changes.size >= 1
    # re-designs only at quiet samples: reference constant, last output inside the limit, error within 5 rpm
    error_rpm = adapted.speed_ref_rpm[changes] - adapted.speed_meas_rpm[changes]
    assert np.all(np.abs(error_rpm) <= 5.0 * (1 + 1e-6))
    assert not np.any(adapted.saturated[changes - 1])
    assert np.all(adapted.speed_ref_rpm[changes] == adapted.speed_ref_rpm[changes - 1])
    # the last speed step (2.3 s on): the adapted drive follows the matched one far closer than the fixed one
    last = matched.t_s >= 2.3
    err_fixed = np.max(np.abs(fixed.speed_rpm[last] - matched.speed_rpm[last]))
    err_adapted = np.max(np.abs(adapted.speed_rpm[last] - matched.speed_rpm[last]))
    assert err_adapted < 0.25 * err_fixed, (err_adapted, err_fixed)


def test_a_bad_estimator_key_is_named():
    base = load_scenario("paper-condition-2").with_overrides({"estimator.enabled": True})
    with pytest.raises(ConfigError, match="estimator.J_min_kgm2 = 1.0 is invalid: valid range is finite, > 0 and <="):
        simulate(base.with_overrides({"estimator.J_min_kgm2": 1.0}))
    with pytest.raises(ConfigError, match="estimator.J_rel_sd_max"):
        base.with_overrides({"estimator.J_rel_sd_max": 1.5})


def test_the_report_section_on_gain_scheduling():
    from pmsm2dof.studies.adaptation import J_RATIOS, adaptation_figures, run_adaptation
    from pmsm2dof.ui.report.adaptation import adaptation_blocks, fig_adaptation

    runs = run_adaptation()
    for ratio in J_RATIOS:
        f = adaptation_figures(runs, ratio)
        assert f["J_est_kgm2"] == pytest.approx(0.4 * ratio, rel=0.02)
        assert f["matched_deviation_rpm"] == 0.0
        # adapting never makes the response worse than keeping the design
        assert f["adapted_iae_rpm_s"] <= f["fixed_iae_rpm_s"] * (1 + 1e-9)
    big = adaptation_figures(runs, 2.0)
    assert big["J_gains_kgm2"] == pytest.approx(0.8, rel=0.05)
    assert big["adapted_deviation_rpm"] < 0.5 * big["fixed_deviation_rpm"]
    blocks = adaptation_blocks(runs)
    assert blocks[0] == ("h2", "Gain scheduling by the identified inertia (not in the paper)")
    header, rows = blocks[-1][1], blocks[-1][2]
    assert len(rows) == len(J_RATIOS) and len(header) == len(rows[0])
    _fig, data = fig_adaptation(runs)
    assert "j_ratio_2_0_adapted_speed_rpm" in data.to_csv().splitlines()[0]
    assert adaptation_blocks(None) == []
