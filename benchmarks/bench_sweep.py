"""Throughput of single runs and sweeps, parallel efficiency, and the memory of a long run.

Usage::

    python3 benchmarks/bench_sweep.py [--sweep FILE] [--repeats 3] [--runs 21] [--no-write]

Measured side by side in one run (medians of ``--repeats`` repetitions):

- single-run throughput (simulated s per wall s) of the preset ``paper-condition-2`` with
  ``current_loop.model = "dq_pi"``, timed around :func:`pmsm2dof.simulate`;
- sweep throughput (runs per second) of the 1,000-point grid
  ``examples/sweeps/alpha-inertia-grid.toml`` (alpha x plant inertia of paper-condition-2) on
  1 and on 2 local workers (threads), without the figures, and the parallel efficiency
  ``rate(2) / (2 rate(1))``;
- peak resident memory of a 60 s simulation logged at every current-controller sample
  (``speed_controller.Ts_s = current_loop.Ts_s``, ``log_every = 1``), measured by
  ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` in a fresh subprocess, against the same
  subprocess that only imports pmsm2dof and loads the scenario.

Writes the sections "Simulation and sweep throughput" and "Memory of a long run" of
``benchmarks/results.md`` (other sections are kept) and prints them.
"""

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

from results_md import measured_by, write_section

HERE = Path(__file__).resolve().parent
GRID = HERE.parent / "examples" / "sweeps" / "alpha-inertia-grid.toml"
SECTION_SPEED = "## Simulation and sweep throughput"
SECTION_MEMORY = "## Memory of a long run"


def single_run(repeats, runs):
    """Simulated s per wall s of paper-condition-2 (dq_pi): the median of ``runs`` timed runs, per repeat."""
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate

    scenario = load_scenario("paper-condition-2").with_overrides({"current_loop.model": "dq_pi"})
    t_end = scenario.data["simulation"]["t_end_s"]
    simulate(scenario)  # warm-up
    rates = []
    for _ in range(repeats):
        walls = []
        for _ in range(runs):
            start = time.perf_counter()
            simulate(scenario)
            walls.append(time.perf_counter() - start)
        rates.append(t_end / statistics.median(walls))
    return scenario, rates


def _cpu_s():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def sweep_rates(path, repeats):
    """The sweep at ``path`` on 1 and on 2 threads (no figures), repetitions interleaved.

    Returns the sweep, ``{workers: [(runs per wall s, CPU s per run, share of the wall time
    inside the engine's C call) per repetition]}``, the time to write the results and figures
    of a finished sweep, and the number of figures.
    """
    from pmsm2dof.studies.sweep import load_sweep
    from pmsm2dof.studies.sweep_run import run_sweep
    from pmsm2dof.ui.plots.sweep import draw_figures

    sweep = load_sweep(path)
    n = len(sweep.points)
    rates = {1: [], 2: []}
    with tempfile.TemporaryDirectory(prefix="p2d-bench-sweep-") as tmp:
        for k in range(repeats):
            for workers in rates:
                out = Path(tmp) / f"w{workers}-{k}"
                start, cpu = time.perf_counter(), _cpu_s()
                run = run_sweep(sweep, out, workers=workers, progress=False, figures=None)
                wall, cpu = time.perf_counter() - start, _cpu_s() - cpu
                engine = float(run.table["wall_time_s"].sum())
                rates[workers].append((n / wall, cpu / n, engine / (workers * wall)))
        start = time.perf_counter()
        run = run_sweep(sweep, out, progress=False, figures=draw_figures)
        outputs_s = time.perf_counter() - start
    return sweep, rates, outputs_s, len(run.files) - 2


MEMORY_PROBE = r"""
import json, resource, sys, time
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
base = load_scenario("paper-condition-2")
Ts = base.data["current_loop"]["Ts_s"]
scenario = base.with_overrides({"simulation.t_end_s": 60.0, "speed_controller.Ts_s": Ts,
                                "simulation.log_every": 1})
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if sys.argv[1] == "run":
    start = time.perf_counter()
    result = simulate(scenario)
    wall = time.perf_counter() - start
    rows, signals = len(result.t_s), len(result.signals)
else:
    wall, rows, signals = 0.0, 0, 0
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
with open("/proc/self/status") as f:
    hwm = int(next(line.split()[1] for line in f if line.startswith("VmHWM:")))
print(json.dumps({"before_kB": before, "peak_kB": after, "hwm_kB": hwm, "rows": rows, "signals": signals,
                  "wall_s": wall}))
"""


def memory(repeats):
    """Peak RSS [kB] of a fresh process that runs the 60 s simulation, and of one that only loads it.

    Linux carries ``ru_maxrss`` over fork and exec, so a child starts from the parent's peak:
    this runs before the benchmark has grown, and ``VmHWM`` (reset by exec) cross-checks it.
    """

    def probe(mode):
        proc = subprocess.run([sys.executable, "-c", MEMORY_PROBE, mode], check=True, capture_output=True, text=True)
        return json.loads(proc.stdout)

    runs = [probe("run") for _ in range(repeats)]
    idle = [probe("idle") for _ in range(repeats)]
    return runs, idle


def report(single, sweeps, mem, repeats, runs, load):
    scenario, single_rates = single
    sweep, rates, outputs_s, n_figures = sweeps
    rates1, rates2 = ([r[0] for r in rates[w]] for w in (1, 2))
    r1, r2 = statistics.median(rates1), statistics.median(rates2)
    cpu1, cpu2 = (statistics.median(r[1] for r in rates[w]) for w in (1, 2))
    engine1 = statistics.median(r[2] for r in rates[1])
    amdahl = 1.0 / ((1.0 - engine1) + engine1 / 2.0)
    mem_runs, mem_idle = mem
    peak = statistics.median(m["peak_kB"] for m in mem_runs) / 1024
    idle = statistics.median(m["peak_kB"] for m in mem_idle) / 1024
    hwm = statistics.median(m["hwm_kB"] for m in mem_runs) / 1024
    hwm_idle = statistics.median(m["hwm_kB"] for m in mem_idle) / 1024
    rows, signals = mem_runs[0]["rows"], mem_runs[0]["signals"]
    d = scenario.data
    head = (
        measured_by("python3 benchmarks/bench_sweep.py")
        + f"; Python {platform.python_version()}, pmsm2dof {version('pmsm2dof')}. "
        f"Medians of {repeats} repetitions, measured side by side in one run; 1-minute load average "
        f"{load[0]:.2f} before and {load[1]:.2f} after (other work on the machine slows the numbers down)."
    )
    lines = [
        SECTION_SPEED,
        "",
        head,
        "",
        "| measurement | median | repetitions |",
        "|---|---:|---|",
        f"| single run, `paper-condition-2` ({d['simulation']['t_end_s']:g} s, `dq_pi`, current "
        f"{d['current_loop']['Ts_s'] * 1e6:g} us, speed {d['speed_controller']['Ts_s'] * 1e3:g} ms): "
        f"simulated s per wall s (median of {runs} runs each) | {statistics.median(single_rates):.4g} | "
        + ", ".join(f"{r:.4g}" for r in single_rates)
        + " |",
        f"| sweep `{sweep.name}` ({len(sweep.points)} runs of paper-condition-2), 1 worker: runs/s | "
        f"{r1:.4g} | " + ", ".join(f"{r:.4g}" for r in rates1) + " |",
        f"| same sweep, 2 workers: runs/s | {r2:.4g} | " + ", ".join(f"{r:.4g}" for r in rates2) + " |",
        f"| speed-up 2 workers / 1 worker | {r2 / r1:.3g} | |",
        f"| parallel efficiency rate(2) / (2 rate(1)) | {100 * r2 / (2 * r1):.0f} % | |",
        f"| CPU time per run, 1 worker / 2 workers (ms) | {1e3 * cpu1:.3g} / {1e3 * cpu2:.3g} | |",
        f"| share of a 1-worker run inside the engine's C call (GIL released) | {100 * engine1:.0f} % | |",
        f"| speed-up for 2 threads if only that share ran in parallel (Amdahl) | {amdahl:.3g} | |",
        "",
        "The sweep rates cover simulating every point (the sweep file is loaded once), measuring its "
        "metrics and storing the Parquet parts, 1- and 2-worker repetitions interleaved; writing "
        f"results.parquet, results.csv and the {n_figures} figures (heatmaps and worst-case traces) "
        f"afterwards took {outputs_s:.3g} s more. Local workers are threads: the engine releases the GIL "
        "for the whole simulation (one C call), the rest of each point (scenario validation, metrics) "
        "holds it, except inside numpy and the Parquet writer, which release it too (so the measured "
        "speed-up can exceed the Amdahl figure of the engine share alone). Equal CPU time per run on 1 "
        "and 2 workers means the threads add no work; a speed-up far below that figure then comes from "
        "cores taken by other work (see the load average).",
        "",
        SECTION_MEMORY,
        "",
        head,
        "",
        f"A 60 s run of `paper-condition-2` with the speed controller at the current period "
        f"({d['current_loop']['Ts_s'] * 1e6:g} us) and `log_every = 1`, i.e. logged at every current "
        f"sample: {rows} rows x {signals} signals; the float64 log alone is "
        f"{rows * signals * 8 / 2**20:.1f} MiB.",
        "",
        "| process | peak RSS, ru_maxrss (MiB) | VmHWM (MiB) |",
        "|---|---:|---:|",
        f"| imports pmsm2dof and loads the scenario | {idle:.1f} | {hwm_idle:.1f} |",
        f"| ... and simulates it (`simulate`, Result held) | {peak:.1f} | {hwm:.1f} |",
        f"| difference: the run | {peak - idle:.1f} | {hwm - hwm_idle:.1f} |",
        "",
        "Peak RSS is `resource.getrusage(RUSAGE_SELF).ru_maxrss` at the end of a fresh subprocess "
        "(median of the repetitions), measured first so that the small parent's peak, which Linux carries "
        "into the child, stays below the child's; `VmHWM` of /proc/self/status (reset by exec) agrees.",
    ]
    return "\n".join(lines[: lines.index(SECTION_MEMORY) - 1]) + "\n", "\n".join(
        lines[lines.index(SECTION_MEMORY) :]
    ) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", type=Path, default=GRID, help="sweep file timed on 1 and 2 workers")
    parser.add_argument("--repeats", type=int, default=3, help="repetitions of every measurement")
    parser.add_argument("--runs", type=int, default=21, help="timed single runs per repetition")
    parser.add_argument("--no-write", action="store_true", help="print only, leave results.md alone")
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]
    mem = memory(args.repeats)
    single = single_run(args.repeats, args.runs)
    sweeps = sweep_rates(args.sweep, args.repeats)
    load = (load_before, os.getloadavg()[0])
    speed_text, memory_text = report(single, sweeps, mem, args.repeats, args.runs, load)
    if not args.no_write:
        write_section(SECTION_SPEED, speed_text)
        write_section(SECTION_MEMORY, memory_text)
    print(speed_text + "\n" + memory_text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
