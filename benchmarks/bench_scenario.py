"""Cost of a scenario change, and the autotuner that makes one per candidate, side by side with another package.

Usage::

    python3 benchmarks/bench_scenario.py [--baseline SRC] [--rounds 5] [--calls 300] [--autotune 3]

Each side runs in a fresh subprocess with its package directory first on ``PYTHONPATH``: this
checkout's ``src`` and, with ``--baseline SRC``, another ``src`` (a copy of an earlier revision with
its extension built). The rounds alternate between the sides (and which one goes first). Per side:

- :meth:`pmsm2dof.sim.scenario.Scenario.with_overrides` on ``paper-condition-2`` with the overrides
  of one autotuner candidate at one inertia (alpha, zeta, m, Ka, feedforward, anti-windup of
  ``[speed_controller]`` and ``motor.J_kgm2``): microseconds per call, the median over the rounds of
  ``--calls`` calls each;
- with ``--autotune N``: :func:`pmsm2dof.autotune` of the paper's drive (inertia known to 0.5x to 2x,
  overshoot at most 5 %) on 2 threads, N times per side: wall and CPU time of the process (all its
  threads), medians.

Prints a Markdown table; the section "Autotune" of ``benchmarks/results.md`` quotes it.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
OVERRIDES = {
    "speed_controller.alpha_radps": 9.5,
    "speed_controller.zeta": 1.1,
    "speed_controller.m": 1.0,
    "speed_controller.Ka": 0.5,
    "speed_controller.feedforward": "lowpass",
    "speed_controller.anti_windup": "back_calculation",
    "motor.J_kgm2": 0.8,
}


def worker(kind, arg):
    """Run one measurement in this process; its figures as a dict."""
    import resource
    import time

    from pmsm2dof import Spec, autotune, load_scenario

    base = load_scenario("paper-condition-2")
    if kind == "overrides":
        calls = int(arg)
        base.with_overrides(OVERRIDES)
        start = time.perf_counter()
        for _ in range(calls):
            base.with_overrides(OVERRIDES)
        return {"us_per_call": 1e6 * (time.perf_counter() - start) / calls}
    spec = Spec(max_overshoot_pct=5.0, J_range=(0.5, 2.0))
    usage = resource.getrusage(resource.RUSAGE_SELF)
    start, start_cpu = time.perf_counter(), usage.ru_utime + usage.ru_stime
    result = autotune(base, spec, workers=2)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return {
        "wall": time.perf_counter() - start,
        "cpu": usage.ru_utime + usage.ru_stime - start_cpu,
        "runs": result.as_dict()["counts"]["runs"],
        "chosen": result.as_dict()["speed_controller"],
    }


def run_side(src, kind, arg):
    env = {**os.environ, "PYTHONPATH": str(src)}
    out = subprocess.run(
        [sys.executable, __file__, "--worker", kind, str(arg)], env=env, capture_output=True, text=True, check=True
    ).stdout
    return json.loads(out.splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, default=None, help="the src folder of the other side")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--autotune", type=int, default=0)
    parser.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(*args.worker), default=str))
        return
    sides = {"this checkout": HERE.parent / "src"}
    if args.baseline is not None:
        sides = {"baseline": args.baseline, **sides}
    names = list(sides)
    figures = {name: {"overrides": [], "autotune": []} for name in names}
    for r in range(max(args.rounds, args.autotune)):
        for name in names if r % 2 == 0 else reversed(names):
            if r < args.rounds:
                figures[name]["overrides"].append(run_side(sides[name], "overrides", args.calls)["us_per_call"])
            if r < args.autotune:
                figures[name]["autotune"].append(run_side(sides[name], "autotune", 0))
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    print(
        "| side | with_overrides (us per call), median (rounds) | autotune wall (s), median (runs) | "
        "autotune CPU (s), median | simulations |"
    )
    print("|---|---:|---:|---:|---:|")
    for name in names:
        ov = figures[name]["overrides"]
        at = figures[name]["autotune"]
        row = f"| {name} | {statistics.median(ov):.0f} ({', '.join(f'{v:.0f}' for v in ov)}) |"
        if at:
            walls = [a["wall"] for a in at]
            row += (
                f" {statistics.median(walls):.3g} ({', '.join(f'{w:.3g}' for w in walls)}) |"
                f" {statistics.median(a['cpu'] for a in at):.3g} | {at[-1]['runs']} |"
            )
        else:
            row += " | | |"
        print(row)
        if at:
            print(f"  chosen ({name}): {at[-1]['chosen']}")


if __name__ == "__main__":
    main()
