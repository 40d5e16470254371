"""Build the C library and its unit tests with CMake and run them with ctest.

The C tests (csrc/tests/test_*.c) check the controllers against hand-derived
values; each prints a closing line "N passed, M failed".
"""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

CSRC = Path(__file__).resolve().parents[1] / "csrc"


def _run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600)


@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("ctest") is None, reason="cmake/ctest not installed")
def test_ctest_passes(tmp_path):
    build = tmp_path / "build"
    configure = _run(["cmake", "-S", str(CSRC), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release"])
    assert configure.returncode == 0, configure.stdout + configure.stderr
    compiled = _run(["cmake", "--build", str(build), "-j", "2"])
    assert compiled.returncode == 0, compiled.stdout + compiled.stderr
    ctest = _run(["ctest", "--test-dir", str(build), "--output-on-failure", "-V"])
    print(ctest.stdout)
    assert ctest.returncode == 0, ctest.stdout + ctest.stderr

    sources = sorted(p.stem for p in (CSRC / "tests").glob("test_*.c"))
    assert {"test_speed", "test_current", "test_transforms"} <= set(sources)
    summaries = re.findall(r"(\d+) passed, (\d+) failed", ctest.stdout)
    assert len(summaries) == len(sources), ctest.stdout
    for passed, failed in summaries:
        assert int(failed) == 0 and int(passed) > 0
