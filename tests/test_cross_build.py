"""The deployable controller builds for a Cortex-M4F and uses nothing but float math; so does
the drive's plant, in double, for the firmware's virtual motor.

Compiles every csrc/src/*.c with arm-none-eabi-gcc and the project's warning
flags (-Werror), prints `arm-none-eabi-size` of the objects (so CI logs show
the flash cost of the speed controller), and checks that the objects hold no
mutable global state (.data/.bss empty) and call nothing but <math.h> and our
own functions. The source check (only <math.h>, <stdint.h>, <stdbool.h>, our
public headers and the internal headers beside the sources are included) needs
no cross compiler.

The plant of the simulation engine (csrc/sim/plant.c and plant.h) is compiled the same way: the
firmware example runs it on the target as a virtual motor, from the same source as the engine
(double precision, soft-float there). It may include <string.h> besides, and call the double
<math.h> functions, memset and memcpy.
"""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

CSRC = Path(__file__).resolve().parents[1] / "csrc"
SOURCES = sorted((CSRC / "src").glob("*.c"))
HEADERS = sorted((CSRC / "include" / "pmsm2dof").glob("*.h"))
INTERNAL_HEADERS = sorted((CSRC / "src").glob("*.h"))
FLAGS = [
    "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wdouble-promotion", "-Werror",
    "-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-O2",
]  # fmt: skip
ALLOWED_SYSTEM_HEADERS = {"math.h", "stdint.h", "stdbool.h"}
PLANT_SOURCES = [CSRC / "sim" / "plant.c", CSRC / "sim" / "plant.h", CSRC / "sim" / "plant_inline.h"]
# the double <math.h> functions and the <string.h> copies the plant may call
PLANT_FUNCTIONS = {
    "sqrt", "fabs", "fmax", "fmin", "copysign", "hypot", "exp", "log", "sin", "cos", "tanh", "floor", "fmod",
    "memset", "memcpy",
}  # fmt: skip
# <math.h> float functions the controller may call (the FPU or libm provides them)
MATH_FUNCTIONS = {
    "sqrtf",
    "fabsf",
    "fminf",
    "fmaxf",
    "copysignf",
    "hypotf",
    "expf",
    "sinf",
    "cosf",
    "atan2f",
    "nextafterf",
}


def test_sources_include_only_math_stdint_stdbool_and_our_headers():
    assert SOURCES and HEADERS
    for path in SOURCES + HEADERS + INTERNAL_HEADERS:
        for line in path.read_text().splitlines():
            m = re.match(r"\s*#\s*include\s*([<\"])([^>\"]+)[>\"]", line)
            if not m:
                continue
            kind, name = m.groups()
            if kind == "<":
                assert name in ALLOWED_SYSTEM_HEADERS, f"{path.name} includes <{name}>"
            else:
                public = name.startswith("pmsm2dof/") and (CSRC / "include" / name).is_file()
                internal = path.parent == CSRC / "src" and "/" not in name and (CSRC / "src" / name).is_file()
                assert public or internal, f'{path.name} includes "{name}"'


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
def test_cortex_m4f_build(tmp_path, capsys):
    objects = []
    for source in SOURCES:
        obj = tmp_path / (source.stem + ".o")
        cc = subprocess.run(
            ["arm-none-eabi-gcc", *FLAGS, "-I", str(CSRC / "include"), "-c", str(source), "-o", str(obj)],
            capture_output=True, text=True,
        )  # fmt: skip
        assert cc.returncode == 0, cc.stderr
        objects.append(obj)

    size = subprocess.run(["arm-none-eabi-size", *map(str, objects)], capture_output=True, text=True, cwd=tmp_path)
    assert size.returncode == 0, size.stderr
    table = size.stdout.replace(str(tmp_path) + "/", "")
    with capsys.disabled():
        print("\narm-none-eabi-size (Cortex-M4F, -O2):\n" + table)

    rows = {}
    for line in table.splitlines()[1:]:
        text, data, bss, *_, name = line.split()
        rows[name] = (int(text), int(data), int(bss))
    assert rows["speed.o"][0] > 0
    for name, (_, data, bss) in rows.items():
        assert data == 0 and bss == 0, f"{name} has mutable global state (.data {data} B, .bss {bss} B)"

    nm = subprocess.run(["arm-none-eabi-nm", "-u", *map(str, objects)], capture_output=True, text=True)
    assert nm.returncode == 0, nm.stderr
    undefined = set(re.findall(r"^\s+U (\S+)$", nm.stdout, flags=re.M))
    foreign = {s for s in undefined if s not in MATH_FUNCTIONS and not s.startswith(("p2d_", "__aeabi_"))}
    assert not foreign, f"the controller calls outside <math.h>: {sorted(foreign)}"


def test_plant_sources_include_only_math_stdint_stdbool_string_and_its_headers():
    allowed = {f"<{h}>" for h in ALLOWED_SYSTEM_HEADERS | {"string.h"}} | {'"plant.h"', '"plant_inline.h"'}
    for path in PLANT_SOURCES:
        for line in path.read_text().splitlines():
            m = re.match(r"\s*#\s*include\s*([<\"][^>\"]+[>\"])", line)
            if m:
                assert m.group(1) in allowed, f"{path.name} includes {m.group(1)}"


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="arm-none-eabi-gcc is not installed")
def test_plant_cortex_m4f_build(tmp_path, capsys):
    """plant.c with -std=c99 and the warnings of the controller (-Wconversion -Wdouble-promotion -Werror)."""
    obj = tmp_path / "plant.o"
    cc = subprocess.run(
        ["arm-none-eabi-gcc", *FLAGS, "-c", str(CSRC / "sim" / "plant.c"), "-o", str(obj)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert cc.returncode == 0, cc.stderr
    size = subprocess.run(["arm-none-eabi-size", str(obj)], capture_output=True, text=True, cwd=tmp_path)
    assert size.returncode == 0, size.stderr
    with capsys.disabled():
        print("\narm-none-eabi-size of the plant (Cortex-M4F, -O2):\n" + size.stdout.replace(str(tmp_path) + "/", ""))
    text, data, bss, *_ = size.stdout.splitlines()[1].split()
    assert int(text) > 0
    assert int(data) == 0 and int(bss) == 0, f"the plant has mutable global state (.data {data} B, .bss {bss} B)"
    nm = subprocess.run(["arm-none-eabi-nm", "-u", str(obj)], capture_output=True, text=True)
    assert nm.returncode == 0, nm.stderr
    undefined = set(re.findall(r"^\s+U (\S+)$", nm.stdout, flags=re.M))
    assert {"sin", "cos", "hypot"} <= undefined  # the check sees the calls (the duties' rotation, the inverter)
    foreign = {s for s in undefined if s not in PLANT_FUNCTIONS and not s.startswith(("p2d_", "__aeabi_"))}
    assert not foreign, f"the plant calls outside <math.h> and <string.h>: {sorted(foreign)}"
