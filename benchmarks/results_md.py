"""What every benchmark shares: the sections of ``benchmarks/results.md`` and where they were measured.

Each benchmark writes its own sections (``## Title`` up to the next ``## ``) with
:func:`write_section`, which keeps the other sections as they are, and opens each with
:func:`measured_by`: the date, the command and the machine (:func:`machine_line`).
"""

import datetime
import os
import platform
import re
import subprocess
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results.md"


def cpu_model():
    """The ``Model name`` of lscpu (``model name`` of ``/proc/cpuinfo`` if lscpu is absent)."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        found = re.search(r"^Model name:\s*(.+)$", out, re.M)
        if found:
            return found.group(1).strip()
    except (OSError, subprocess.CalledProcessError):
        pass
    text = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    found = re.search(r"^model name\s*:\s*(.+)$", text, re.M)
    return found.group(1).strip() if found else "unknown CPU"


def machine_line():
    """``host (machine, CPU model, N cores)`` for the results."""
    return f"{platform.node() or 'host'} ({platform.machine()}, {cpu_model()}, {os.cpu_count()} cores)"


def measured_by(command):
    """``Measured <date> by `command` on <machine>``: the opening of a section's provenance sentence."""
    return f"Measured {datetime.date.today().isoformat()} by `{command}` on {machine_line()}"


def write_section(section, text):
    """Replace (or append) the section titled ``section`` of results.md, keeping the others.

    The file is replaced at once (written aside, then renamed), never left half-written.
    """
    old = RESULTS.read_text() if RESULTS.exists() else "# Benchmark results\n"
    start = old.find(section + "\n")
    if start < 0:
        new = old.rstrip("\n") + "\n\n" + text
    else:
        nxt = old.find("\n## ", start + len(section))
        new = old[:start] + text + (old[nxt:] if nxt >= 0 else "")
    tmp = RESULTS.with_suffix(".md.tmp")
    tmp.write_text(new)
    tmp.replace(RESULTS)
