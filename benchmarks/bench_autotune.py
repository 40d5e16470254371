"""Wall and CPU time of the autotuner, side by side with another package, and the designs it chooses.

Usage::

    python3 benchmarks/bench_autotune.py [--repeats 3] [--workers 2] [--baseline SRC] [--instructions] [--no-write]

For each drive, :func:`pmsm2dof.autotune` with an inertia known to 0.5x to 2x of the design
value, on ``--workers`` local threads, ``--repeats`` times (medians); the search is
deterministic, so every repetition chooses the same design:

- ``paper-condition-2`` (J = 0.4 kg m^2, tau_i = 50 ms, dq current loop, 15 s): overshoot
  at most 5 %, margins 45 deg and 6 dB;
- ``benchmarks/small-servo.toml`` (J = 1e-4 kg m^2, tau_i = 1 ms, 0.45 s): overshoot at most
  5 %, settling within 0.1 s, margins 45 deg and 6 dB.

Each repetition runs in a fresh subprocess with its package first on ``PYTHONPATH``: this checkout's
``src`` and, with ``--baseline SRC``, another ``src`` (an earlier revision with its extension built);
the repetitions alternate between the sides (and which one goes first). Per repetition: the wall time
of the call, the CPU time of the process over it (all its threads, user and system), the simulations
and the chosen design with its worst case, which must be the same on both sides.

With ``--instructions``, each side's autotuning of each drive runs once more under callgrind
(``valgrind --tool=callgrind``, which runs the threads one at a time): the instructions of the call (those
of the process less those of a process that imports the same modules and loads the scenario, and stops
there), and of them those of the engine's C run (``p2d_sim_run_many``, inclusive): counts that other load
on the machine does not change.

Writes the section "Autotune" of ``benchmarks/results.md`` (other sections are kept) and prints it.
"""

import argparse
import math
import os
import pickle
import platform
import re
import statistics
import subprocess
import sys
import tempfile
from importlib.metadata import version
from pathlib import Path

from results_md import measured_by, write_section

HERE = Path(__file__).resolve().parent
SECTION = "## Autotune"
J_RANGE = (0.5, 2.0)
#: A constraint whose worst case is this close to its limit (relative) is reported as active.
ACTIVE_RTOL = 0.02
#: The drives tuned: label -> scenario argument.
DRIVES = {"paper drive": "paper-condition-2", "small servo": "benchmarks/small-servo.toml"}


def case(label):
    """(scenario, Spec) of the drive ``label``."""
    from pmsm2dof import Spec, load_scenario

    if label == "paper drive":
        return load_scenario("paper-condition-2"), Spec(max_overshoot_pct=5.0, J_range=J_RANGE)
    spec = Spec(max_overshoot_pct=5.0, max_settling_s=0.1, J_range=J_RANGE)
    return load_scenario(str(HERE / "small-servo.toml")), spec


def worker(label, workers, path, load_only=False):
    """One autotuning in this process: its times and the result (pickled to ``path``); with ``load_only``, the
    imports and the scenario alone."""
    import resource
    import time

    import tqdm  # noqa: F401

    import pmsm2dof.studies.autotune_search  # noqa: F401 (the modules an autotuning imports)
    from pmsm2dof import autotune

    scenario, spec = case(label)
    if load_only:
        return
    usage = resource.getrusage(resource.RUSAGE_SELF)
    start, start_cpu = time.perf_counter(), usage.ru_utime + usage.ru_stime
    result = autotune(scenario, spec, workers=workers)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    times = {"wall": time.perf_counter() - start, "cpu": usage.ru_utime + usage.ru_stime - start_cpu}
    Path(path).write_bytes(pickle.dumps((times, result)))


def instructions(src, label, workers):
    """``(instructions of the autotuning, of them in p2d_sim_run_many)`` under callgrind, ``src`` first on the path."""
    counts = []
    with tempfile.TemporaryDirectory() as tmp:
        for tune in (True, False):
            out = Path(tmp) / f"callgrind.{tune}.out"
            args = [sys.executable, __file__, "--worker", label, str(workers), str(Path(tmp) / "result.pickle")]
            subprocess.run(
                ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *args, *([] if tune else ["--load"])],
                env={**os.environ, "PYTHONPATH": str(src)},
                check=True,
                cwd=HERE,
                capture_output=True,
            )
            text = subprocess.run(
                ["callgrind_annotate", "--inclusive=yes", str(out)], check=True, capture_output=True, text=True
            ).stdout
            total = int(re.search(r"^\s*([\d,]+) \(100\.0%\)\s+PROGRAM TOTALS", text, re.M).group(1).replace(",", ""))
            engine = re.search(r"^\s*([\d,]+) \([\d.]+%\)\s+\S*drive\.c:p2d_sim_run_many ", text, re.M)
            counts.append((total, int(engine.group(1).replace(",", "")) if engine else 0))
    return counts[0][0] - counts[1][0], counts[0][1]


def run_side(src, label, workers):
    """``(times, result)`` of one autotuning in a subprocess with ``src`` first on the path."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "result.pickle"
        env = {**os.environ, "PYTHONPATH": str(src)}
        subprocess.run(
            [sys.executable, __file__, "--worker", label, str(workers), str(path)], env=env, check=True, cwd=HERE
        )
        return pickle.loads(path.read_bytes())


def measure(repeats, workers, sides):
    """``{side: {label: [(times, result) per repetition]}}``, the sides alternating."""
    out = {name: {label: [] for label in DRIVES} for name in sides}
    names = list(sides)
    for r in range(repeats):
        for label in DRIVES:
            for name in names if r % 2 == 0 else reversed(names):
                out[name][label].append(run_side(sides[name], label, workers))
    return out


def same_choice(a, b):
    """Whether two results chose the same design with the same worst case and made the same simulations."""
    return (
        a.speed_controller == b.speed_controller
        and a.chosen.worst == b.chosen.worst
        and a.chosen.worst_J_ratio == b.chosen.worst_J_ratio
        and [(r.candidate, r.J_ratio, r.figures, r.error) for r in a.runs]
        == [(r.candidate, r.J_ratio, r.figures, r.error) for r in b.runs]
    )


def _figure(value, unit):
    return "inf" if value is None or not math.isfinite(value) else f"{value:.4g} {unit}"


def report(measured, repeats, workers, load, baseline, counted):
    from pmsm2dof.studies.autotune import CONSTRAINTS

    command = f"python3 benchmarks/bench_autotune.py --repeats {repeats} --workers {workers}"
    if baseline is not None:
        command += " --baseline SRC"
    if counted is not None:
        command += " --instructions"
    head = (
        measured_by(command)
        + f"; Python {platform.python_version()}, pmsm2dof {version('pmsm2dof')}. Medians of {repeats} "
        f"repetitions on {workers} threads, each in a fresh process; 1-minute load average {load[0]:.2f} before and "
        f"{load[1]:.2f} after (other work on the machine slows the wall times down; the CPU time of the process, "
        "all its threads, less so)."
    )
    if baseline is not None:
        head += f" SRC: {baseline}."
    mine = measured["this checkout"]
    lines = [
        SECTION,
        "",
        head,
        "",
        f"`pmsm2dof.autotune` with the inertia known to {J_RANGE[0]:g}x to {J_RANGE[1]:g}x of the design "
        "value: the margins of the discrete loop at 9 inertia ratios prune first, the engine simulates "
        "the rest at the ends and the middle of the range, and the chosen design is simulated again at "
        "the 9 ratios. Target (issue 31): the paper drive in under 3 s on 2 cores.",
        "",
        "| drive | side | wall time, median (s) | repetitions (s) | CPU time, median (s) | designs | simulations "
        "| same choice and runs as this checkout |",
        "|---|---|---:|---|---:|---:|---:|---|",
    ]
    for label, argument in DRIVES.items():
        for name, drives in measured.items():
            rows = drives[label]
            walls = [times["wall"] for times, _ in rows]
            cpus = [times["cpu"] for times, _ in rows]
            result = rows[-1][1]
            counts = result.as_dict()["counts"]
            same = all(same_choice(r, mine[label][-1][1]) for _, r in rows)
            lines.append(
                f"| {label} (`{argument}`) | {name} | {statistics.median(walls):.3g} | "
                + ", ".join(f"{w:.3g}" for w in walls)
                + f" | {statistics.median(cpus):.3g} | {counts['candidates']} | {counts['runs']} | "
                f"{'yes' if same else 'NO'} |"
            )
    if counted is not None:
        lines += [
            "",
            "Instructions of one autotuning (callgrind; the engine: `p2d_sim_run_many` inclusive):",
            "",
            "| drive | side | instructions (G) | of them the engine's C run (G) | "
            "the rest: Python, NumPy, analysis (G) |",
            "|---|---|---:|---:|---:|",
        ]
        for label in DRIVES:
            for name, drives in counted.items():
                total, engine = drives[label]
                lines.append(
                    f"| {label} | {name} | {total / 1e9:.3g} | {engine / 1e9:.3g} | {(total - engine) / 1e9:.3g} |"
                )
    results = [(label, drives[-1][1]) for label, drives in mine.items()]
    lines += ["", "Specifications:", ""]
    for label, r in results:
        spec = ", ".join(f"{name} {limit:g}" for name, limit in r.spec.constraints().items())
        lines.append(f"- {label}: {spec}")
    lines += ["", "Chosen designs and their worst case over the inertia range (J ratio where it occurs):", ""]
    names = list(results[0][1].chosen.worst)
    units = {
        "phase_margin_deg": "deg",
        "gain_margin_dB": "dB",
        "overshoot_pct": "%",
        "settling_time_s": "s",
        "load_dip_rpm_per_Nm": "rpm/Nm",
        "load_iae_rpm_s_per_Nm": "rpm s/Nm",
        "load_recovery_s": "s",
        "current_limit_time_s": "s",
        "tracking_iae_rpm_s": "rpm s",
        "chatter_share": "",
    }
    lines += [
        "| | " + " | ".join(label for label, _ in results) + " |",
        "|---|" + "---:|" * len(results),
        "| meets the specification | " + " | ".join("yes" if r.feasible else "no" for _, r in results) + " |",
    ]
    for key in results[0][1].speed_controller:
        lines.append(
            f"| `speed_controller.{key}` | " + " | ".join(str(r.speed_controller[key]) for _, r in results) + " |"
        )
    for name in names:
        cells = [
            f"{_figure(r.chosen.worst[name], units[name]).rstrip()} ({r.chosen.worst_J_ratio[name]:.3g})"
            for _, r in results
        ]
        lines.append(f"| worst {name} | " + " | ".join(cells) + " |")
    cells = []
    for _, r in results:
        active = [
            name
            for name, limit in r.spec.constraints().items()
            if abs(r.chosen.worst[CONSTRAINTS[name][0]] - limit) <= ACTIVE_RTOL * max(abs(limit), 1.0)
        ]
        cells.append(", ".join(active) or "none")
    lines.append("| constraints at their limit (within 2 %) | " + " | ".join(cells) + " |")
    lines.append(
        "| on a bound of the search | "
        + " | ".join("; ".join(n.split(" is at ")[0] for n in r.on_bounds) or "none" for _, r in results)
        + " |"
    )
    lines += [
        "",
        "Reproduce a design with `pmsm2dof simulate SCENARIO --set speed_controller.KEY=VALUE ...` (the keys above).",
        "",
    ]
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--baseline", type=Path, default=None, help="the src folder of the other side")
    parser.add_argument("--instructions", action="store_true", help="count instructions under callgrind too")
    parser.add_argument("--no-write", action="store_true", help="print the section, do not write results.md")
    parser.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--load", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        label, workers, path = args.worker
        worker(label, int(workers), path, args.load)
        return
    sides = {"this checkout": HERE.parent / "src"}
    if args.baseline is not None:
        sides = {"baseline": args.baseline.resolve(), **sides}
    load_before = os.getloadavg()[0]
    measured = measure(args.repeats, args.workers, sides)
    counted = None
    if args.instructions:
        counted = {
            name: {label: instructions(src, label, args.workers) for label in DRIVES} for name, src in sides.items()
        }
    text = report(measured, args.repeats, args.workers, (load_before, os.getloadavg()[0]), args.baseline, counted)
    print(text)
    if not args.no_write:
        write_section(SECTION, text)


if __name__ == "__main__":
    main()
