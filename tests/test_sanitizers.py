"""The C unit tests and the simulation engine under AddressSanitizer and UndefinedBehaviorSanitizer.

csrc is configured with the CMake option P2D_SANITIZE (ASan + UBSan on every
target, -fno-sanitize-recover=all: the first report aborts) in a temporary
build folder, and ctest runs whatever csrc/tests/test_*.c exist plus
`sanitize_drive` (csrc/fuzz/sanitize_drive.c), which drives the simulation
engine csrc/sim/drive.c on short scenarios with log buffers of exactly the
size they need. The compiler is clang when installed, else the default one.
"""

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
CSRC = ROOT / "csrc"
SANITIZE = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all"]


def _compiler(tmp_path):
    """A C compiler that links ASan + UBSan programs, or None."""
    probe = tmp_path / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    for cc in ("clang", "cc"):
        if shutil.which(cc) is None:
            continue
        if (
            subprocess.run([cc, *SANITIZE, str(probe), "-o", str(tmp_path / "probe")], capture_output=True).returncode
            == 0
        ):
            return cc
    return None


@pytest.fixture(scope="module")
def sanitize_build(tmp_path_factory):
    """A P2D_SANITIZE build of csrc in a temporary folder."""
    if shutil.which("cmake") is None:
        pytest.skip("cmake is not installed")
    cc = _compiler(tmp_path_factory.mktemp("probe"))
    if cc is None:
        pytest.skip(
            "no C compiler here links AddressSanitizer and UndefinedBehaviorSanitizer "
            "(Debian: clang libclang-rt-14-dev)"
        )
    build = tmp_path_factory.mktemp("sanitize-build")
    for command in (
        ["cmake", "-S", str(CSRC), "-B", str(build), f"-DCMAKE_C_COMPILER={cc}", "-DP2D_SANITIZE=ON"],
        ["cmake", "--build", str(build), "-j", "2"],
    ):
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return build


def _ctest_names(build):
    listing = subprocess.run(["ctest", "-N"], cwd=build, capture_output=True, text=True, check=True).stdout
    return re.findall(r"Test\s+#\d+: (\S+)", listing)


def test_every_ctest_is_instrumented(sanitize_build):
    names = _ctest_names(sanitize_build)
    assert "sanitize_drive" in names
    assert any(name.startswith("test_") for name in names), names
    for name in names:
        symbols = subprocess.run(["nm", str(sanitize_build / name)], capture_output=True, text=True, check=True).stdout
        assert "__asan_report" in symbols and "__ubsan_handle" in symbols, f"{name} is not instrumented"


def test_ctest_under_sanitizers(sanitize_build):
    env = dict(
        os.environ,
        ASAN_OPTIONS="detect_leaks=1:abort_on_error=0:halt_on_error=1",
        UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1",
    )
    result = subprocess.run(
        ["ctest", "--output-on-failure"], cwd=sanitize_build, env=env, capture_output=True, text=True, timeout=600
    )
    summary = re.search(r"(\d+)% tests passed, (\d+) tests failed out of (\d+)", result.stdout)
    assert result.returncode == 0 and summary, result.stdout[-6000:] + result.stderr[-3000:]
    names = _ctest_names(sanitize_build)
    print(f"\nctest under ASan+UBSan: {summary.group(3)} tests passed ({', '.join(names)})")
    assert int(summary.group(2)) == 0 and int(summary.group(3)) == len(names)
