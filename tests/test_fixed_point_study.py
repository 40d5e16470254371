"""The report's section without an FPU (pmsm2dof.studies.fixedpoint, ui.report.fixedpoint).

Truth: the deviations and errors measured here on the traces with plain numpy; the Q15 dead zone
of the paper's design from its formula (half a torque LSB over Ki Ts, Ki = 0.3 by eq 9) to within a
speed LSB; the derived full scales from their formulas (twice the no-load speed; T_fs >= T_max).
"""

import math

import numpy as np
import pytest

from pmsm2dof.studies.fixedpoint import DEAD_ZONE_NAME, PRESETS, run_arithmetic
from pmsm2dof.ui.report.fixedpoint import fig_fixed_point, fixed_point_blocks
from pmsm2dof.ui.report.render import render_markdown

RPM = math.pi / 30.0


@pytest.fixture(scope="module")
def study():
    return run_arithmetic()


def test_every_condition_runs_in_every_arithmetic_and_the_rows_are_the_traces(study):
    rows = {(r.condition, r.arithmetic): r for r in study.rows}
    assert set(rows) == {(c, a) for c in (*PRESETS, DEAD_ZONE_NAME) for a in ("float32", "q31", "q15")}
    for (condition, arithmetic), row in rows.items():
        assert not row.error, row
        run, reference = study.results[condition, arithmetic], study.results[condition, "float32"]
        assert row.deviation_rpm == np.max(np.abs(run.speed_rpm - reference.speed_rpm))
        assert row.final_error_rpm == run.speed_ref_rpm[-1] - run.speed_rpm[-1]
        if arithmetic == "float32":
            assert row.speed_full_scale_rpm is None and row.dead_zone_rpm is None
        elif condition != DEAD_ZONE_NAME:
            # twice the no-load speed u_dc / (sqrt(3) p psi_f) of the paper's drive
            assert row.speed_full_scale_rpm == pytest.approx(2 * 540 / (math.sqrt(3) * 0.8) / RPM, rel=1e-6)
            assert row.torque_full_scale_Nm >= 1.5 * 4 * 0.2 * 7.6
    # Q31 follows float32 closely on every condition; Q15 does not
    for condition in (*PRESETS, DEAD_ZONE_NAME):
        assert rows[condition, "q31"].dead_zone_rpm == 0.0
        assert rows[condition, "q31"].deviation_rpm < 0.2 < rows[condition, "q15"].deviation_rpm


def test_the_q15_trap_rests_inside_the_dead_zone_of_its_formula(study):
    trap = {r.arithmetic: r for r in study.rows if r.condition == DEAD_ZONE_NAME}
    edge_rpm = 0.5 * (10.0 / 2**15) / (0.3 * 1e-4) / RPM
    assert trap["q15"].dead_zone_rpm == pytest.approx(edge_rpm, abs=1000.0 / 2**15)
    assert 0.25 * edge_rpm < abs(trap["q15"].final_error_rpm) <= trap["q15"].dead_zone_rpm
    assert abs(trap["q31"].final_error_rpm) < 0.05 and abs(trap["float32"].final_error_rpm) < 0.2


def test_the_section_renders_its_figure_and_table(study):
    blocks = fixed_point_blocks(study)
    text = render_markdown(blocks)
    assert "Without an FPU" in text and "inside the dead zone of +-48.55 rpm" in text
    table = next(b for b in blocks if b[0] == "table")
    assert len(table[2]) == len(study.rows)
    fig, data = fig_fixed_point(study)
    assert len(fig.axes) == len(PRESETS) + 1
    assert len([c for c in data.columns if c.endswith("_speed_rpm")]) == 3 * (len(PRESETS) + 1)
    assert fixed_point_blocks(None) == []
