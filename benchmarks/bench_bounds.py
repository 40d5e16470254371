"""What the bounds on the work an input asks for are derived from (RELIABILITY.md, "Bounded work").

Usage::

    python3 benchmarks/bench_bounds.py [--repeats 3] [--no-write]

Measured side by side in one run (medians of ``--repeats`` repetitions, each in a fresh
subprocess so that imports and caches are the same every time):

- the sampled analysis of ``pmsm2dof design`` against the sensor delay in speed-loop periods
  (0 to 256; the bound is :data:`pmsm2dof.analysis.sensor.DELAY_PERIODS_MAX`): the wall and CPU
  time of :meth:`pmsm2dof.analysis.design.Design.discretize` and the peak resident memory of the
  process;
- the validation of one sweep point (:meth:`pmsm2dof.sim.scenario.Scenario.with_overrides` on a
  frozen base, as :func:`pmsm2dof.studies.sweep.parse_sweep` does for every point) and one run
  of the paper's drive, from which :data:`pmsm2dof.studies.sweep.POINTS_MAX` follows;
- the peak resident memory of writing the CSV trace of 600,000 rows: streamed
  (:meth:`pmsm2dof.sim.simulate.Result.save`, :data:`~pmsm2dof.sim.simulate.CSV_ROWS_PER_CHUNK`
  rows at a time) against the same text held whole (the writer in one chunk), above the process
  that holds the log.

Writes the section "Bounds on the work an input asks for" of ``benchmarks/results.md`` and
prints it.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time

from results_md import measured_by, write_section

from pmsm2dof.sim.simulate import CSV_ROWS_PER_CHUNK

DELAYS = (0, 64, 128, 256, 512)

DESIGN = textwrap.dedent(
    """
    import json, resource, sys, time
    import control  # imported before the timing (the analysis loads it on first use, pmsm2dof.lazy)
    import pmsm2dof.analysis.sensor as sensor
    from pmsm2dof.analysis.design import design
    from pmsm2dof.analysis.sensor import SensorChain

    sensor.DELAY_PERIODS_MAX = 10**6  # measured beyond the bound too
    n = int(sys.argv[1])
    d = design(0.4, 0.5, 0.3, sensor=SensorChain(delay_s=n * 1e-3))
    wall, cpu = time.perf_counter(), time.process_time()
    d.discretize(1e-3, "tustin")
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    rss_MiB = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "rss_MiB": rss_MiB}))
    """
)

POINT = textwrap.dedent(
    """
    import json, time
    from pmsm2dof.sim.scenario import Scenario, load_scenario
    from pmsm2dof.sim.simulate import simulate

    base = Scenario.from_dict(load_scenario("paper-condition-2").data)
    n = 300
    start = time.perf_counter()
    for i in range(n):
        base.with_overrides({"motor.J_kgm2": 0.2 + 1e-3 * i, "speed_controller.alpha_radps": 0.5})
    check = (time.perf_counter() - start) / n
    start = time.perf_counter()
    for _ in range(10):
        simulate(base)
    print(json.dumps({"check_ms": 1e3 * check, "run_ms": 1e3 * (time.perf_counter() - start) / 10}))
    """
)

CSV = textwrap.dedent(
    """
    import json, resource, sys
    import numpy as np
    import pmsm2dof.sim.simulate
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate

    result = simulate(load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": 1.0}))
    for name in result.signals:  # the log of a long run: the rows repeated
        object.__setattr__(result, name, np.resize(getattr(result, name), 600_000))
    if sys.argv[1] == "whole":
        pmsm2dof.sim.simulate.CSV_ROWS_PER_CHUNK = 600_000
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    result.save(sys.argv[2])
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    log = sum(getattr(result, n).nbytes for n in result.signals)
    print(json.dumps({"log_MiB": log / 2**20, "extra_MiB": (after - before) / 1024}))
    """
)


def run(script, *args):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def median(rows, key):
    return statistics.median(r[key] for r in rows)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    design = {n: [] for n in DELAYS}
    points, csv = [], {"streamed": [], "whole": []}
    for _ in range(args.repeats):
        for n in DELAYS:
            design[n].append(run(DESIGN, str(n)))
        points.append(run(POINT))
        with tempfile.TemporaryDirectory() as folder:
            for how in csv:
                csv[how].append(run(CSV, how, os.path.join(folder, "trace.csv")))
    load_after = os.getloadavg()[0]

    lines = [
        "## Bounds on the work an input asks for",
        "",
        f"{measured_by('python3 benchmarks/bench_bounds.py')}. Medians of {args.repeats} repetitions, each in a "
        f"fresh subprocess with one BLAS thread, measured side by side in one run; 1-minute load average "
        f"{load_before:.2f} before and {load_after:.2f} after (other work on the machine slows the times down).",
        "",
        "The sampled analysis of `pmsm2dof design` (`Design.discretize`, Tustin, Ts = 1 ms, the paper's J, "
        "alpha 0.5 rad/s, zeta 0.3) against the sensor delay: the loop has a state per period of delay, and the "
        "bound is 256 periods.",
        "",
        "| delay [periods] | wall time (s) | CPU time (s) | peak RSS of the process (MiB) |",
        "|---:|---:|---:|---:|",
    ]
    for n in DELAYS:
        rows = design[n]
        lines.append(
            f"| {n} | {median(rows, 'wall_s'):.3g} | {median(rows, 'cpu_s'):.3g} | {median(rows, 'rss_MiB'):.0f} |"
        )
    check, one_run = median(points, "check_ms"), median(points, "run_ms")
    lines += [
        "",
        f"A sweep point is validated in {check:.2g} ms (`with_overrides` on the frozen base) and the paper's drive "
        f"(`paper-condition-2`, 15 s) simulated in {one_run:.3g} ms: the bound of 100,000 points is "
        f"{100_000 * check / 60e3:.1f} minutes of checks and {100_000 * one_run / 3600e3:.2g} hours of runs on one "
        "core.",
        "",
        "Writing the CSV trace of 600,000 rows (above the process that holds the log):",
        "",
        "| writer | log held (MiB) | peak RSS added while writing (MiB) |",
        "|---|---:|---:|",
    ]
    for how, label in (
        ("streamed", f"streamed, {CSV_ROWS_PER_CHUNK:,} rows at a time (`Result.save`)"),
        ("whole", "the same text held whole (one chunk of 600,000 rows)"),
    ):
        lines.append(f"| {label} | {median(csv[how], 'log_MiB'):.0f} | {median(csv[how], 'extra_MiB'):.0f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        write_section("## Bounds on the work an input asks for", text)


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"({time.perf_counter() - start:.0f} s)")
