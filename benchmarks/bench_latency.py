"""Latency of the command line: CPU seconds of one ``pmsm2dof`` process, side by side with an earlier revision.

Usage::

    python3 benchmarks/bench_latency.py [--baseline REV] [--rounds 5] [--no-write]

Each side is a whole package: the working tree's ``src/`` and ``csrc/``, and those of the git
revision REV (default ``main``), each with its C engine compiled by its own ``ffibuild.py`` in a
temporary folder. Every measurement is one fresh process, ``python3 -m pmsm2dof ARGS``, with the
side's package first on ``PYTHONPATH`` and bytecode caching on (a warm-up run per side and command
writes the caches, as an installed package has them); its CPU time is the user plus system time
of the child (``resource.getrusage(RUSAGE_CHILDREN)`` around it), which other load on the machine
inflates less than wall time. The rounds alternate the sides (and which one goes first); each
figure is the median over the rounds.

Commands: ``pmsm2dof --help``; ``pmsm2dof simulate paper-condition-2 --out DIR`` (15 001 samples:
the trace, the metrics, the figure and the CSV); the same with ``speed_controller.Ts_s = 1e-4``
(150 001 samples). For this checkout it also lists the heavy modules ``--help`` loads (none of
python-control, SciPy, matplotlib, pandas, numpy should be), and times the steps of the simulate
command in one process (imports, simulation, CSV, figure, ``savefig``; median over the rounds).

Writes the section "Command latency (CPU seconds of the process)" of ``benchmarks/results.md``
(other sections are kept) and prints it.
"""

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_md import measured_by, write_section

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SECTION = "## Command latency (CPU seconds of the process)"
HEAVY = ("control", "scipy", "matplotlib", "pandas", "numpy")
COMMANDS = {
    "pmsm2dof --help": ["--help"],
    "simulate paper-condition-2 --out DIR (15 001 samples)": ["simulate", "paper-condition-2", "--out", "{out}"],
    "the same, speed_controller.Ts_s = 1e-4 (150 001 samples)": [
        "simulate",
        "paper-condition-2",
        "--set",
        "speed_controller.Ts_s=1e-4",
        "--out",
        "{out}",
    ],
}


def build_side(rev, dest):
    """The package of ``rev`` (None: the working tree) with its engine compiled; returns its ``src`` folder."""
    dest.mkdir(parents=True)
    if rev is None:
        for name in ("src", "csrc"):
            shutil.copytree(ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__", "_core.*"))
        shutil.copy2(ROOT / "ffibuild.py", dest / "ffibuild.py")
    else:
        archive = subprocess.run(
            ["git", "archive", rev, "src", "csrc", "ffibuild.py"], capture_output=True, check=True, cwd=ROOT
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
        for stale in (dest / "src").rglob("_core.*"):
            stale.unlink()
    code = "import runpy; runpy.run_path('ffibuild.py')['ffibuilder'].compile()"
    subprocess.run([sys.executable, "-c", code], cwd=dest, check=True, capture_output=True)
    for built in (dest / "pmsm2dof").glob("_core.*"):
        if built.suffix in (".so", ".pyd"):
            shutil.copy2(built, dest / "src" / "pmsm2dof" / built.name)
    return dest / "src"


def environment(site):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = str(site)
    return env


def cpu_seconds(site, args, out):
    """User + system CPU seconds of one ``python3 -m pmsm2dof ARGS`` process on the package under ``site``."""
    if out.exists():
        shutil.rmtree(out)
    argv = [a.format(out=out) for a in args]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(
        [sys.executable, "-m", "pmsm2dof", *argv],
        env=environment(site),
        check=True,
        capture_output=True,
        cwd=out.parent,
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def heavy_modules_of_help(site):
    """The modules of :data:`HEAVY` that ``pmsm2dof --help`` has loaded when it exits."""
    code = (
        "import sys, json, pmsm2dof.ui.cli as c\n"
        "c.main(['--help'])\n"
        f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], env=environment(site), check=True, capture_output=True, text=True
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def worker_steps(out):
    """The steps of ``simulate paper-condition-2 --out`` in this process, CPU seconds each (JSON on stdout)."""
    start = time.process_time()
    marks = {}

    def mark(name):
        marks[name] = time.process_time()

    import pmsm2dof.ui.cli  # noqa: F401  (the command line itself)

    mark("the command line (click, pmsm2dof.ui.cli)")
    from pmsm2dof.sim.metrics import compute_metrics
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate

    mark("numpy and the engine (pmsm2dof.sim)")
    from pmsm2dof.ui.plots import trace

    mark("matplotlib (pmsm2dof.ui.plots.trace)")
    result = simulate(load_scenario("paper-condition-2"), progress=True)
    mark("simulation")
    compute_metrics(result)
    mark("metrics")
    result.save(Path(out) / "trace.csv")
    mark("trace.csv")
    fig = trace.trace_figure(result)
    mark("figure")
    from pmsm2dof.ui.plots.canvas import save_figure

    save_figure(fig, Path(out) / "plot.png")
    mark("savefig (PNG)")
    previous, steps = start, {}
    for name, t in marks.items():
        steps[name] = t - previous
        previous = t
    print(json.dumps(steps))


def steps_of(site, out):
    out.mkdir(exist_ok=True)
    proc = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--worker-steps", str(out)],
        env=environment(site),
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default="main", help="git revision of the before side [main]")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--no-write", action="store_true", help="print the section only")
    parser.add_argument("--worker-steps", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker_steps:
        worker_steps(args.worker_steps)
        return
    baseline = subprocess.run(
        ["git", "rev-parse", "--short", args.baseline], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout.strip()
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout
    dirty = subprocess.run(["git", "status", "--porcelain", "src", "csrc"], capture_output=True, text=True, cwd=ROOT)
    this = head.strip() + (" with local changes" if dirty.stdout.strip() else "")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        sides = {"before": build_side(args.baseline, tmp / "before"), "after": build_side(None, tmp / "after")}
        times = {(side, name): [] for side in sides for name in COMMANDS}
        for side, site in sides.items():  # warm-up: bytecode caches and the font cache
            for argv in COMMANDS.values():
                cpu_seconds(site, argv, tmp / f"out-{side}")
        for r in range(args.rounds):
            order = list(sides) if r % 2 == 0 else list(reversed(sides))
            for name, argv in COMMANDS.items():
                for side in order:
                    times[side, name].append(cpu_seconds(sides[side], argv, tmp / f"out-{side}"))
        heavy = {side: heavy_modules_of_help(site) for side, site in sides.items()}
        steps = [steps_of(sides["after"], tmp / "steps") for _ in range(args.rounds)]
    lines = [
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/bench_latency.py')}: before = {args.baseline} ({baseline}), "
        f"after = {this}; CPU seconds (user + system) of one `python3 -m pmsm2dof ...` process, median of "
        f"{args.rounds} alternating rounds after a warm-up, bytecode cached. Load average at the end: "
        f"{', '.join(f'{x:.1f}' for x in os.getloadavg())} (CPU time grows too when the cores are shared).",
        "",
        "| command | before [s] | after [s] | after / before |",
        "|---|---:|---:|---:|",
    ]
    for name in COMMANDS:
        b, a = (statistics.median(times[side, name]) for side in ("before", "after"))
        lines.append(f"| `{name}` | {b:.3f} | {a:.3f} | {a / b:.2f} |")
    lines += [
        "",
        "Heavy modules loaded by `pmsm2dof --help`: before "
        + (", ".join(heavy["before"]) or "none")
        + "; after "
        + (", ".join(heavy["after"]) or "none")
        + ".",
        "",
        "Where the after side's `simulate paper-condition-2 --out` spends its CPU (one process, median):",
        "",
        "| step | CPU [s] |",
        "|---|---:|",
    ]
    for name in steps[0]:
        lines.append(f"| {name} | {statistics.median(s[name] for s in steps):.3f} |")
    lines.append("")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        write_section(SECTION, text)


if __name__ == "__main__":
    main()
