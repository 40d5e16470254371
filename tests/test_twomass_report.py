"""The report's section beyond the rigid load (pmsm2dof.studies.twomass, pmsm2dof.ui.report.twomass).

- the load-side stable region does not depend on the inertia ratio: w_L / T depends on the
  resonance, its damping and the total inertia only (physics of the two-mass train);
- the stable region and the simulations agree: where the sampled loop is unstable the run keeps
  oscillating, where it is stable the oscillation dies out;
- the section renders its table, one row per run.
"""

import numpy as np
import pytest

from pmsm2dof.studies import twomass as tm
from pmsm2dof.studies.twomass import REGION_RESONANCES_HZ
from pmsm2dof.studies.twomass import paper_region_study as run_two_mass_study
from pmsm2dof.ui.report.render import render_markdown
from pmsm2dof.ui.report.twomass import two_mass_blocks

PAPER = dict(zeta=0.28867513459481287, tau_i_s=0.05, Ts_s=1e-3)


def test_load_side_region_does_not_depend_on_the_inertia_ratio():
    region = tm.stable_region([0.5, 10.0], [2.0, 20.0], feedback="load", **PAPER)
    assert np.allclose(region[0], region[1], rtol=0.011)  # bisected to 1 %
    # and the motor side does: the anti-resonance moves with the ratio
    motor = tm.stable_region([0.5, 10.0], [1.0], feedback="motor", notch=True, **PAPER)
    assert abs(motor[0, 0] / motor[1, 0] - 1.0) > 0.05


def test_train_overrides_keep_the_total_inertia_and_set_the_resonance():
    from pmsm2dof.analysis.twomass import two_mass

    o = tm.train_overrides(7.0, "load", notch=True, ratio=4.0)
    train = two_mass(
        o["motor.J_kgm2"],
        o["mechanics.J_load_kgm2"],
        o["mechanics.stiffness_Nm_per_rad"],
        o["mechanics.damping_Nms_per_rad"],
    )
    assert train.J_total_kgm2 == pytest.approx(0.4, rel=1e-15)
    assert train.inertia_ratio == pytest.approx(4.0, rel=1e-14)
    assert train.resonance_radps == pytest.approx(2 * np.pi * 7.0, rel=1e-14)
    assert train.resonance_damping == pytest.approx(tm.RESONANCE_DAMPING, rel=1e-14)
    assert o["speed_filter.notch_freq_Hz"] == 7.0


@pytest.mark.slow
def test_section_agrees_with_the_stable_region():
    study = run_two_mass_study()
    rows = {(r["resonance_Hz"], r["feedback"], r["alpha_factor"], r["notch"]): r for r in study.rows}
    assert len(rows) == len(study.rows) == 2 + len(tm.RESONANCES_HZ) * 2 * 2 * 2
    for a in tm.ALPHA_FACTORS:  # the rigid drive against itself
        assert rows[None, "rigid", a, False]["off_rigid_rpm"] == 0.0 == rows[None, "rigid", a, False]["twist_rpm"]
    load = dict(zip(REGION_RESONANCES_HZ, study.regions["load", False][0]))
    fast = tm.ALPHA_FACTORS[-1] * study.alpha_radps
    assert load[2.0] < fast < load[20.0]
    # unstable by the analysis: the oscillation grows to the current limit; stable: it dies out
    assert rows[2.0, "load", tm.ALPHA_FACTORS[-1], False]["twist_rpm"] > 100.0
    assert rows[20.0, "load", tm.ALPHA_FACTORS[-1], False]["twist_rpm"] < 0.1
    text = render_markdown(two_mass_blocks(study, {"two_mass_region": "region"}))
    assert "## Beyond the rigid load" in text
    assert text.count("\n| 2 | load |") == 4
