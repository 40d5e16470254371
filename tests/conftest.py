"""The fast and the full suite, and the Hypothesis profiles.

``python3 -m pytest`` runs the fast subset, for development (well under 30 s on two cores): the
tests marked ``slow`` (cross builds, QEMU, fuzzing, sanitizers, the browser, the reproduction,
long engine runs and fresh interpreters; ``--durations=50`` finds new ones) are deselected, not
skipped. ``python3 -m pytest --full`` runs every test; CI runs it (``.ci/run``).

Hypothesis profiles: random exploration on a workstation, the same examples every run in CI.

``HYPOTHESIS_PROFILE=ci`` (set by ``.ci/run``) selects the ``ci`` profile; without it the
property tests run with Hypothesis' defaults, drawing new examples on every run and replaying
the failures it stored in ``.hypothesis/``.

The ``ci`` profile makes a run a function of the code alone, so a result can be reproduced
from the commit:

- ``derandomize``: the examples are seeded by a hash of each test, the same on every run;
- ``database=None``: no examples replayed from, or written to, a local database;
- ``deadline=None`` and no ``too_slow`` health check: both measure wall time, which on a shared
  CI machine depends on its load, not on the code. The health checks that do not time anything
  (filtering too much, data too large) stay on.

A test's own ``@settings`` (its number of examples, say) still applies on top of the profile.

Builds that several test files need are session fixtures here, made once per run; under
pytest-xdist (``-n``) the first worker that asks makes it, in the folder the workers share, and
the others wait for it (:func:`made_once`).
"""

import fcntl
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parents[1]


def pytest_addoption(parser):
    parser.addoption("--full", action="store_true", help="run the slow tests too (the full suite CI runs)")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: a test of the full suite only (python3 -m pytest --full)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--full"):
        return
    slow = [item for item in items if item.get_closest_marker("slow")]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if not item.get_closest_marker("slow")]


settings.register_profile(
    "ci", derandomize=True, database=None, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def made_once(request, tmp_path_factory, name, make):
    """The folder ``name`` filled by ``make(folder)`` once per test run, shared by the xdist workers.

    Without xdist a new temporary folder. Under xdist a folder of the run's temporary root, which
    all workers share: the first worker holding its lock makes it, the others wait and reuse it; a
    ``make`` that failed leaves no mark, and the next worker tries again (and fails the same way).
    """
    if not hasattr(request.config, "workerinput"):
        folder = tmp_path_factory.mktemp(name)
        make(folder)
        return folder
    root = tmp_path_factory.getbasetemp().parent
    folder, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            folder.mkdir(exist_ok=True)
            make(folder)
            done.touch()
    return folder


@pytest.fixture(scope="session")
def servo_firmware(request, tmp_path_factory):
    """examples/firmware/small-servo-20k.toml (20 kHz current, 2 kHz speed loop) built by ``build_firmware``
    for QEMU and the PC: ``(scenario, folder)``. The tests read the folder and never write into it."""
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.studies.firmware import build_firmware

    scenario = load_scenario(str(ROOT / "examples" / "firmware" / "small-servo-20k.toml"))
    folder = made_once(request, tmp_path_factory, "small-servo-20k", lambda f: build_firmware(scenario, f / "fw"))
    return scenario, folder / "fw"
