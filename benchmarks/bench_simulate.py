"""Throughput of the drive simulation engine: simulated seconds per wall-clock second.

Usage::

    python3 benchmarks/bench_simulate.py [--runs 5] [--no-write]

Runs the preset ``paper-condition-2`` (15 s: speed step, 8 Nm load step, speed step) with the
``dq_pi`` current loop at Ts_current = 100 us, and the same with the ``first_order`` current loop,
``--runs`` times each after one warm-up run, on one core (the engine is single-threaded), and
reports the median of

- the whole :func:`pmsm2dof.simulate` call (scenario to C configuration, the run, the Result);
- the same call in the process's CPU time (``time.process_time``), robust to other load;
- the C run alone (``Result.wall_time_s``), also as nanoseconds per current-controller period.

It also measures the accuracy of the plant step the run uses (the default, one RK4 step per
current period): the largest change of the speed trace when the step is halved, relative to the
largest speed. Writes the section "Simulation engine throughput" of ``benchmarks/results.md``
(other sections are kept) and prints it. The target is at least 1000 simulated seconds per wall
second for ``dq_pi``.
"""

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from results_md import RESULTS, measured_by, write_section

from pmsm2dof import load_scenario, simulate

SECTION = "## Simulation engine throughput"
TARGET_SIM_S_PER_WALL_S = 1000.0


def git_commit():
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parent,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def measure(scenario, runs):
    """Whole-call wall and CPU times and C-run wall times [s] of ``runs`` runs after one warm-up."""
    simulate(scenario)
    calls, cpu, engine = [], [], []
    for _ in range(runs):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = simulate(scenario)
        calls.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        engine.append(result.wall_time_s)
    return calls, cpu, engine


def halving_change(scenario):
    """max |w(dt) - w(dt/2)| / max |w(dt/2)| of the speed traces."""
    dt = scenario.data["simulation"]["dt_s"]
    a = simulate(scenario)
    b = simulate(scenario.with_overrides({"simulation.dt_s": dt / 2}))
    return float(np.max(np.abs(a.w_m_radps - b.w_m_radps)) / np.max(np.abs(b.w_m_radps)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs per case (median reported)")
    parser.add_argument("--no-write", action="store_true", help="print the section, do not write results.md")
    args = parser.parse_args(argv)

    base = load_scenario("paper-condition-2")
    data = base.data
    assert data["current_loop"]["model"] == "dq_pi" and data["current_loop"]["Ts_s"] == 1e-4
    t_end_s = data["simulation"]["t_end_s"]
    Ts_current_s = data["current_loop"]["Ts_s"]
    load_before = os.getloadavg()[0]

    rows = []
    for label, scenario in (
        ("dq_pi", base),
        ("first_order", base.with_overrides({"current_loop.model": "first_order"})),
    ):
        calls, cpu, engine = measure(scenario, args.runs)
        call_s, engine_s = statistics.median(calls), statistics.median(engine)
        rows.append(
            (
                label,
                t_end_s / call_s,
                t_end_s / max(calls),
                t_end_s / min(calls),
                t_end_s / statistics.median(cpu),
                t_end_s / engine_s,
                engine_s / (t_end_s / Ts_current_s) * 1e9,
            )
        )
    change = halving_change(base)
    load_after = os.getloadavg()[0]

    dq_pi_rate = rows[0][1]
    verdict = "met" if dq_pi_rate >= TARGET_SIM_S_PER_WALL_S else "NOT met"
    lines = [
        SECTION,
        "",
        measured_by(f"python3 benchmarks/bench_simulate.py --runs {args.runs}")
        + f" at commit {git_commit()}, Python {platform.python_version()}; "
        f"1-minute load average {load_before:.2f} before and {load_after:.2f} after (the machine is shared "
        "with other work, which lowers these figures).",
        "",
        f"Preset `paper-condition-2` ({t_end_s:g} s simulated), current controller at "
        f"Ts_current = {Ts_current_s * 1e6:g} us, speed controller at "
        f"{data['speed_controller']['Ts_s'] * 1e3:g} ms, plant by RK4 with dt = "
        f"{data['simulation']['dt_s'] * 1e6:g} us "
        f"(the default, one step per current period), logged every speed sample. Median of {args.runs} runs "
        "after a warm-up run, one core.",
        "",
        "| current loop | simulated s / wall s, whole `simulate()` call (slowest-fastest run) "
        "| simulated s / CPU s, whole call | simulated s / wall s, C run only | ns per current period (C run) |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {label} | {call:.0f} ({low:.0f}-{high:.0f}) | {per_cpu:.0f} | {engine:.0f} | {ns:.0f} |"
        for label, call, low, high, per_cpu, engine, ns in rows
    ]
    lines += [
        "",
        f"Target: >= {TARGET_SIM_S_PER_WALL_S:g} simulated s per wall s for dq_pi (whole call, median): {verdict}. "
        "The CPU-time column is the same work measured in the process's own CPU time, which other load on "
        "the machine does not inflate.",
        f"Accuracy of the plant step: halving dt changes the speed trace by {change:.1e} of the largest speed "
        "(requirement < 1e-4; tests/test_engine.py checks it).",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if not args.no_write:
        write_section(SECTION, text)
        print(f"wrote the section to {RESULTS}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
