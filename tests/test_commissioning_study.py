"""The commissioning routine's promise over seeded random machines (pmsm2dof.studies.commissioning).

An estimate is returned only when the measurement checked out: every run ends DONE with every
parameter within the identification's targets, or FAILED naming the step and the reason. The truth
is each machine's scenario.
"""

import math
from pathlib import Path

import pytest

from pmsm2dof.sim.commission import REASONS, TARGETS, commission
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.commissioning import (
    SERVO,
    accuracy_study,
    random_machines,
    real_drive,
    servo_scenario,
    summary_table,
)


def motional_q_bias(scenario):
    """The q injection's error predicted by the rotor's motion: at w0 = pi / (2 Ts) the rotor's
    inertia adds -1.5 p^2 psi_f^2 / (J w0) to the q reactance w0 Lq (a light rotor with a strong
    magnet swings with the injected torque): the relative bias of Lq."""
    m = scenario.data["motor"]
    w0 = math.pi / (2.0 * scenario.data["current_loop"]["Ts_s"])
    return 1.5 * m["pole_pairs"] ** 2 * m["psi_f_Wb"] ** 2 / (m["J_kgm2"] * w0**2 * m["Lq_H"])


def test_the_servo_of_the_study_is_the_guide_s():
    example = load_scenario(str(Path(__file__).resolve().parents[1] / "examples/commissioning/servo-salient.toml")).data
    for key, value in SERVO.items():
        if key != "name":
            table, leaf = key.split(".")
            assert example[table][leaf] == value == servo_scenario().data[table][leaf]


def test_random_machines_are_seeded():
    a, b = random_machines(3, 7), random_machines(3, 7)
    assert [s.data["motor"] for s in a] == [s.data["motor"] for s in b]
    assert a[0].data["motor"] != random_machines(1, 8)[0].data["motor"]


@pytest.fixture(scope="module")
def study():
    return accuracy_study(n_random=100, seed=20)


@pytest.mark.slow
def test_done_within_targets_or_failed_with_a_reason(study):
    machines = {s.name: s for s in random_machines(100, 20)}
    done = 0
    for row in study:
        r = row.result
        if r.phase == "failed":
            assert r.reason in REASONS[1:] and r.failed_phase and r.reason_text
            continue
        done += 1
        for key, error in r.errors.items():
            bound = TARGETS[key]
            if key == "Lq_H" and row.machine in machines:
                bound += motional_q_bias(machines[row.machine])  # the open finding of RELIABILITY.md
            assert abs(error) <= bound, (row.machine, row.drive, key, error)
    # the paper's drive and the servo end DONE on both drives; most random machines do
    assert all(r.result.phase == "done" for r in study[:4])
    assert done >= 100
    assert "100 random machines | real" in summary_table(study)


def _tripped(r):
    """The check behind a failure's reason really tripped (those the run reports)."""
    c = r.checks
    if r.reason == "rotor_moved":
        return c["rs_spread"] > 0.02 or c["uq_ratio"] > 0.02 or c["asymmetry"] > 0.05
    if r.reason == "speed_not_reached":
        return c["coherence"] < 0.9 or c["psi_spread"] > 0.02 or c["slip"] > 0.02 or r.failed_phase == "spin"
    return bool(r.reason_text)


@pytest.fixture
def runs(request, drive):
    """(scenario, commissioning) of the 100 seeded random machines on ``drive``: in the full suite the
    study's runs (the same calls, made once: the log's density changes no result), else runs of their own."""
    machines = random_machines(100, 20)
    if request.config.getoption("--full"):
        results = {(row.machine, row.drive): row.result for row in request.getfixturevalue("study")}
        return [(s, results[s.name, drive]) for s in machines]
    return [(s, commission(real_drive(s) if drive == "real" else s, log_every=1000)) for s in machines]


@pytest.mark.parametrize(
    ("drive", "min_done"),
    [("ideal", 90), pytest.param("real", 85, marks=pytest.mark.slow)],  # measured: 97 and 89 of 100
)
def test_most_random_machines_end_done(runs, drive, min_done):
    """A routine run on an unknown motor succeeds whenever machine and drive allow: seeded machines."""
    done = 0
    for scenario, r in runs:
        if r.phase == "failed":
            assert r.reason in REASONS[1:] and _tripped(r), (scenario.name, r.failed_phase, r.reason, r.checks)
            continue
        done += 1
        for key, error in r.errors.items():
            bound = TARGETS[key] + (motional_q_bias(scenario) if key == "Lq_H" else 0.0)
            assert abs(error) <= bound, (scenario.name, drive, key, error)
    assert done >= min_done
