"""The report's self-commissioning section: identified against the scenarios' true values."""

import pytest

from pmsm2dof.sim.commission import ESTIMATES, TARGETS
from pmsm2dof.ui.report.commissioning import commissioning_blocks, run_commissioning
from pmsm2dof.ui.report.render import render_markdown


@pytest.mark.slow
def test_section_tabulates_the_runs_within_the_targets():
    runs = run_commissioning()
    assert list(runs) == [
        ("paper drive", "ideal"),
        ("paper drive", "real"),
        ("salient servo", "ideal"),
        ("salient servo", "real"),
    ]
    for r in runs.values():
        assert r.phase == "done" and r.within_targets
    blocks = commissioning_blocks(runs)
    assert blocks[0] == ("h2", "Self-commissioning (not in the paper)")
    table = blocks[2]
    assert table[1][3:7] == tuple(f"{k} error" for k in ESTIMATES)
    for row, r in zip(table[2], runs.values()):
        for cell, key in zip(row[3:7], ESTIMATES):
            # the table shows the error of the run, in percent, within the target
            assert float(cell.split()[0]) == pytest.approx(100 * r.errors[key], abs=0.006)
            assert abs(float(cell.split()[0])) <= 100 * TARGETS[key]
    assert "| align |" in render_markdown(blocks)


def test_no_runs_no_section():
    assert commissioning_blocks(None) == []
