"""``pmsm2dof reproduce --link``: the claims of the experiments checked on the runs played on a drive.

The claims' drive column must come from the drive's traces and not from the simulation: a drive
trace changed by hand moves the drive column to the overshoot computed here from that trace, and
leaves the simulated column. On the PC's virtual drive (the firmware's controllers over XCP, the
engine's plant), the experiments' runs agree with the engine and the claims read the same.
"""

import dataclasses
import shutil

import numpy as np
import pytest

from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.claims import compute_claims
from pmsm2dof.studies.paper import run_studies
from pmsm2dof.studies.paper_drive import DRIVE_RUNS, DriveStudies, run_on_drives
from pmsm2dof.ui.cli import main

REDUCED = {"points": 3, "Ts_grid": (1e-3, 0.1, 0.3)}


@pytest.fixture(scope="module")
def studies():
    return run_studies({}, **REDUCED)


def _by_evidence(claims, run):
    return next(c for c in claims if run in c.evidence)


def test_the_drive_column_comes_from_the_drive_traces(studies):
    # a "drive" whose run without AW overshoots more than the simulation: its speed 5 % above it
    results = {n: studies.results[n] for n in DRIVE_RUNS}
    sim = results["e1-1dof-none"]
    changed = dataclasses.replace(sim, speed_rpm=1.05 * sim.speed_rpm)
    results["e1-1dof-none"] = changed
    drive = DriveStudies(
        link="test",
        results=results,
        metrics={n: compute_metrics(r) for n, r in results.items()},
        comparisons={n: {"speed": {"relative_to_step": 0.0}} for n in results},
        wall_time_s=0.0,
    )
    plain = _by_evidence(compute_claims(studies), "e1-1dof")
    claim = _by_evidence(compute_claims(studies, drive), "e1-1dof")
    # the overshoot of the changed trace, by hand: the 500 rpm step from rest at t = 0
    step_rpm = sim.scenario.reference[0].speed_rpm
    expected = 100.0 * (np.max(changed.speed_rpm) - step_rpm) / step_rpm
    assert claim.on_drive is not None and plain.on_drive is None
    assert claim.on_drive.values["overshoot_no_aw_pct"] == pytest.approx(expected, rel=1e-9)
    assert claim.on_drive.values["overshoot_aw_pct"] == pytest.approx(plain.values["overshoot_aw_pct"], rel=1e-12)
    assert claim.values == plain.values  # the simulated column is the simulation's
    assert abs(claim.on_drive.values["overshoot_no_aw_pct"] - plain.values["overshoot_no_aw_pct"]) > 3.0
    # only the experiments' claims carry a drive column
    assert sum(c.on_drive is not None for c in compute_claims(studies, drive)) == 3


def test_reproduce_refuses_a_link_it_cannot_play_on(tmp_path, capsys):
    out = tmp_path / "report"
    # a drive at a URL is known by its A2L file: without one, refused before any study runs
    assert main(["reproduce", "--link", "tcp://127.0.0.1:5555", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pmsm2dof: error: --a2l") and "tcp://127.0.0.1:5555" in err[0]
    assert not out.exists()
    assert main(["reproduce", "--link", "ftp://127.0.0.1", "--a2l", "d.a2l", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pmsm2dof: error: --link = 'ftp://127.0.0.1'")
    assert not out.exists()


_MISSING = [t for t in ("cmake", "cc") if shutil.which(t) is None]


@pytest.mark.slow
@pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)")
def test_experiment_1_on_the_virtual_drive_reads_as_simulated():
    pytest.importorskip("pyxcp")
    bases = {"paper-experiment-1": load_scenario("paper-experiment-1")}
    runs = ("e1-1dof-none", "e1-1dof-back_calculation")
    lines = []
    drive = run_on_drives(bases, "virtual", runs=runs, report=lines.append)
    assert len(lines) == 2
    step = bases["paper-experiment-1"].reference[0]
    for name in runs:
        played = drive.results[name]
        # the drive played the preset's step (500 rpm from rest at 0.5 s), and the engine agrees with it
        after = played.t_s >= step.t_s + 1e-3
        assert np.all(played.speed_ref_rpm[after] == pytest.approx(step.speed_rpm, rel=1e-6))
        assert np.all(played.speed_ref_rpm[played.t_s < step.t_s] == 0.0)
        assert drive.comparisons[name]["agrees"]
        assert drive.comparisons[name]["speed"]["relative_to_step"] < 1e-6
        # the figure the claim reads is the overshoot of the drive's own trace
        overshoot = drive.metrics[name]["reference_steps"][0]["overshoot_pct"]["value"]
        by_hand = 100.0 * (np.max(played.speed_rpm) - step.speed_rpm) / step.speed_rpm
        assert overshoot == pytest.approx(by_hand, rel=1e-9)
    # back-calculation AW overshoots less on the drive, as claim 16 says
    o = {n: drive.metrics[n]["reference_steps"][0]["overshoot_pct"]["value"] for n in runs}
    assert o["e1-1dof-back_calculation"] < o["e1-1dof-none"]
