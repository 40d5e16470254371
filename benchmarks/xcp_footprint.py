"""Code size and RAM of the XCP slave (csrc/src/xcp.c) on the Cortex-M4F.

Compiles xcp.c alone with arm-none-eabi-gcc at -Os and at -O2 (the flags of the
library's cross build otherwise) and writes its section of benchmarks/results.md:
flash of the module and of its largest functions, and the sizes of the structs the
integrator allocates (read from the symbol sizes of a probe object).

    python3 benchmarks/xcp_footprint.py
"""

import re
import subprocess
import sys
import tempfile
from pathlib import Path

from results_md import measured_by, write_section

SECTION = "## XCP slave on the Cortex-M4F"
ROOT = Path(__file__).resolve().parents[1]
CC = "arm-none-eabi-gcc"
TARGET = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-ffp-contract=off", "-std=c99"]
PROBE = """#include "pmsm2dof/xcp.h"
const char sizeof_p2d_xcp_t[sizeof(p2d_xcp_t)] = {0};
const char sizeof_p2d_xcp_frame_t[sizeof(p2d_xcp_frame_t)] = {0};
const char sizeof_p2d_xcp_guard_t[sizeof(p2d_xcp_guard_t)] = {0};
const char sizeof_p2d_xcp_config_t[sizeof(p2d_xcp_config_t)] = {0};
"""


def compile_object(source, out, optimisation):
    subprocess.run(
        [CC, *TARGET, optimisation, "-I", str(ROOT / "csrc" / "include"), "-c", str(source), "-o", str(out)], check=True
    )


def sizes(obj):
    """text, data, bss of an object [bytes]."""
    line = subprocess.run(["arm-none-eabi-size", str(obj)], capture_output=True, text=True, check=True).stdout
    text, data, bss = line.splitlines()[1].split()[:3]
    return int(text), int(data), int(bss)


def string_bytes(obj):
    """Bytes of the object's string literals (the status texts) [bytes]."""
    listing = subprocess.run(["arm-none-eabi-size", "-A", str(obj)], capture_output=True, text=True, check=True).stdout
    return sum(int(m.group(1)) for m in re.finditer(r"^\.rodata\.str\S*\s+(\d+)", listing, re.M))


def symbols(obj):
    """(name, size) of the object's symbols, largest first."""
    command = ["arm-none-eabi-nm", "--size-sort", "--reverse-sort", "-S", str(obj)]
    listing = subprocess.run(command, capture_output=True, text=True, check=True).stdout
    return [(m.group(2), int(m.group(1), 16)) for m in re.finditer(r"^\S+ (\S+) \w (\S+)$", listing, re.M)]


def main():
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows, functions = [], None
        for optimisation in ("-Os", "-O2"):
            obj = tmp / f"xcp{optimisation}.o"
            compile_object(ROOT / "csrc" / "src" / "xcp.c", obj, optimisation)
            rows.append((optimisation, *sizes(obj), string_bytes(obj)))
            if functions is None:
                functions = symbols(obj)
        probe = tmp / "probe.c"
        probe.write_text(PROBE)
        compile_object(probe, tmp / "probe.o", "-Os")
        structs = {name.removeprefix("sizeof_"): size for name, size in symbols(tmp / "probe.o")}
    version = subprocess.run([CC, "--version"], capture_output=True, text=True, check=True).stdout.splitlines()[0]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    lines = [
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/xcp_footprint.py')}; {version}; code: commit {commit.stdout.strip()}.",
        f"Flags `{' '.join(TARGET)}` and the optimisation below.",
        "",
        "| optimisation | text (flash) | of which status texts | data | bss |",
        "|---|---:|---:|---:|---:|",
        *(f"| {o} | {text} | {strings} | {data} | {bss} |" for o, text, data, bss, strings in rows),
        "",
        "Largest symbols at -Os (bytes):",
        "",
        "| symbol | size |",
        "|---|---:|",
        *(f"| {name} | {size} |" for name, size in functions[:12]),
        "",
        "RAM the integrator allocates (bytes):",
        "",
        "| struct | size |",
        "|---|---:|",
        *(f"| {name} | {size} |" for name, size in structs.items()),
        "",
        "The slave keeps no .data or .bss: its state is the integrator's `p2d_xcp_t` (of which 256 bytes are the",
        "response buffer), plus the buffers it hands over: the DAQ memory (per dynamic DAQ list 20 bytes, per ODT",
        "12, per ODT entry 8 on the Cortex-M4F), the DTO queue (each DTO its length + 2 bytes) and the shadow page",
        "(the largest calibration segment). `p2d_xcp_frame_t` is the byte-stream receiver (a 255-byte packet",
        "buffer). Instructions per event and link throughput are measured once the firmware runs the slave.",
        "",
    ]
    write_section(SECTION, "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
