"""The C sources follow .clang-format (the check of .ci/run, so that ``python3 -m pytest`` runs it too).

Needs clang-format 14 (scripts/install.sh installs the Debian package); without it
the tests fail and say so rather than skip.
"""

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MISSING = "clang-format is not installed: run scripts/install.sh (Debian package clang-format)"


@pytest.fixture(scope="module")
def clang_format():
    path = shutil.which("clang-format")
    if path is None:
        pytest.fail(MISSING)
    return path


def test_c_sources_are_formatted(clang_format):
    done = subprocess.run(
        ["bash", str(ROOT / "scripts" / "clang-format.sh")], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, (
        "C sources differ from .clang-format (fix: bash scripts/clang-format.sh --fix):\n" + done.stderr[-5000:]
    )


def test_the_check_catches_a_misformatted_source(clang_format):
    # two-space indent, brace on the function line, no spaces around operators
    source = "float p2d_twice(float x) {\n  return 2.0f*x;\n}\n"
    done = subprocess.run(
        [clang_format, "--dry-run", "-Werror", "--style=file", "--assume-filename", str(ROOT / "csrc/src/twice.c")],
        input=source, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode != 0 and "clang-format-violations" in done.stderr, done.stderr
