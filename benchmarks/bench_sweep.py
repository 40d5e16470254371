"""Throughput of single runs and sweeps, parallel efficiency, and the memory of a long run.

Usage::

    python3 benchmarks/bench_sweep.py [--points 1000] [--repeats 3] [--no-write]

Measured side by side in one run (medians of ``--repeats`` repetitions):

- single-run throughput (simulated s per wall s) of the preset ``paper-condition-2`` with
  ``current_loop.model = "dq_pi"``, timed around :func:`pmsm2dof.simulate`;
- sweep throughput (runs per second) of a grid of ``--points`` points (alpha x plant inertia
  around paper-condition-2) on 1 and on 2 local workers, and the parallel efficiency
  ``rate(2) / (2 rate(1))``;
- peak resident memory of a 60 s simulation logged at every current-controller sample
  (``speed_controller.Ts_s = current_loop.Ts_s``, ``log_every = 1``), measured by
  ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` in a fresh subprocess, against the same
  subprocess that only imports pmsm2dof and loads the scenario.

Writes the sections "Simulation and sweep throughput" and "Memory of a long run" of
``benchmarks/results.md`` (other sections are kept) and prints them.
"""

import os
import platform
import re
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results.md"


def machine_line():
    """``host (machine, CPU model, N cores)`` for the results."""
    cpu = "unknown CPU"
    if Path("/proc/cpuinfo").exists():
        found = re.search(r"^model name\s*:\s*(.+)$", Path("/proc/cpuinfo").read_text(), re.M)
        cpu = found.group(1) if found else cpu
    return f"{platform.node() or 'host'} ({platform.machine()}, {cpu}, {os.cpu_count()} cores)"


def write_section(section, text):
    """Replace (or append) the section titled ``section`` of results.md, keeping the others."""
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
