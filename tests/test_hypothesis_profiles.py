"""The property tests are deterministic in CI and explore on a workstation.

A small property test, run in a fresh pytest process next to a copy of ``tests/conftest.py``,
records the examples Hypothesis draws, and a second one fails: with ``HYPOTHESIS_PROFILE=ci`` two
runs draw the same examples and store no failure in an example database; without it two runs draw
different ones and the failure is stored (to be replayed first next time). And ``.ci/run``, the
CI entry point, selects that profile for the README's full test command.
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

#: Slow (each check runs pytest twice in a fresh process): run by the full suite.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]

DRAWS = """
import os

from hypothesis import given, settings, strategies as st


@settings(max_examples=30)
@given(st.integers(), st.floats(allow_nan=False))
def test_draw(n, x):
    with open(os.environ["DRAWS_FILE"], "a") as f:
        f.write(f"{n!r} {x!r}\\n")


@given(st.integers())
def test_fails(n):
    assert n < 1000
"""


def draws(folder, run, profile):
    """The examples one pytest run of the small property test draws, with ``profile`` (None: unset)."""
    env = {k: v for k, v in os.environ.items() if k != "HYPOTHESIS_PROFILE"}
    env["DRAWS_FILE"] = str(folder / f"draws-{run}.txt")
    if profile is not None:
        env["HYPOTHESIS_PROFILE"] = profile
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_draws.py"],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1 and "1 failed, 1 passed" in proc.stdout, proc.stdout + proc.stderr
    return Path(env["DRAWS_FILE"]).read_text().splitlines()


def project(tmp_path):
    shutil.copy(ROOT / "tests" / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_draws.py").write_text(DRAWS)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    return tmp_path


def test_ci_profile_draws_the_same_examples_every_run_and_stores_no_failure(tmp_path):
    folder = project(tmp_path)
    first, second = draws(folder, 1, "ci"), draws(folder, 2, "ci")
    assert len(first) == 30 and first == second
    assert not (folder / ".hypothesis" / "examples").exists()


def test_default_profile_explores_new_examples_every_run_and_stores_the_failure(tmp_path):
    folder = project(tmp_path)
    first, second = draws(folder, 1, None), draws(folder, 2, None)
    # 30 random draws of an integer and a float: two runs never draw the same list
    assert len(first) == len(second) == 30 and first != second
    assert any((folder / ".hypothesis" / "examples").iterdir())


def test_ci_entry_point_runs_the_readme_test_command_with_the_ci_profile():
    script = (ROOT / ".ci" / "run").read_text()
    readme = (ROOT / "README.md").read_text()
    readme_command = re.search(r"```sh\n(python3 -m pytest --full[^\n]*)\n```", readme).group(1)
    commands = [line.strip() for line in script.splitlines() if line.strip() and not line.startswith("#")]
    assert commands[-1] == readme_command
    assert "export HYPOTHESIS_PROFILE=ci" in commands[:-1]
