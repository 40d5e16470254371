"""Throughput of the drive simulation engine, side by side with the engine of an earlier revision.

Usage::

    python3 benchmarks/bench_simulate.py [--baseline REV] [--rounds 5] [--runs 5] [--instructions]
                                         [--no-write]

Every measurement runs in a fresh subprocess on an engine built for the purpose: this checkout's
``csrc/`` compiled by its ``ffibuild.py`` into a temporary directory and put under a copy of this
checkout's Python package. With ``--baseline REV`` the engine of the git revision REV (its
``csrc/`` and ``ffibuild.py``, so its compiler flags too) is built the same way under another copy
of the same Python package: the two sides differ in the engine only. The rounds alternate between
the two sides (and which one goes first), and every figure is the median over all rounds.

Per engine:

- the preset ``paper-condition-2`` (15 s: speed step, 8 Nm load step, speed step) with the
  ``dq_pi`` current loop at Ts_current = 100 us, and with the ``first_order`` current loop:
  ``--runs`` timed :func:`pmsm2dof.simulate` calls per round after a warm-up, in wall time and
  in the CPU time of the calling thread, which runs the engine too (``time.thread_time``: other
  load on the machine does not inflate it, nor do other threads, such as the BLAS threads that
  numpy's first matrix operations leave spinning for a while), and the C run alone
  (``Result.wall_time_s``), also as nanoseconds per current period;
- a sweep of 200 points of paper-condition-2 (plant inertia 0.5 to 2 times the design inertia,
  20 values, x alpha from 0.2 to 2 rad/s, 10 values) on 1 and on 2 threads, without figures: runs
  per second and CPU time per run (all threads of the process: simulation, metrics and the
  Parquet parts);
- with ``--instructions``: instructions executed in the C run per current period of one
  paper-condition-2 run (valgrind's callgrind, counted from ``p2d_sim_run`` down), a figure that
  other load on the machine does not change.

Then, with a baseline: whether the two engines log the same bits on every preset (as shipped,
with the computation delay, with the first-order current loop) and on paper-condition-2 with
friction and three RK4 steps per current period, and with a DC link low enough to reach the
voltage limit. Last, the accuracy of the plant step of this checkout: the largest change of the
speed trace when the step is halved, relative to the largest speed.

Writes the section "Simulation engine throughput" of ``benchmarks/results.md`` (other sections are
kept) and prints it.
"""

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SECTION = "## Simulation engine throughput"
MODELS = ("dq_pi", "first_order")
WORKERS = (1, 2)
SWEEP_TOML = """\
name = "inertia-alpha-200"
base = "paper-condition-2"

[axes]
"motor.J_kgm2" = { start = 0.2, stop = 0.8, num = 20 }
"speed_controller.alpha_radps" = { start = 0.2, stop = 2.0, num = 10, scale = "log" }
"""


# ---- worker: runs in the subprocess, on the package given by PYTHONPATH ---------------------------


def _scenario(model):
    from pmsm2dof import load_scenario

    return load_scenario("paper-condition-2").with_overrides({"current_loop.model": model})


def worker_single(model, runs):
    """Whole-call wall and CPU times and C-run wall times [s] of ``runs`` runs after a warm-up."""
    from pmsm2dof import simulate

    scenario = _scenario(model)
    simulate(scenario)
    call, cpu, engine = [], [], []
    for _ in range(runs):
        start, start_cpu = time.perf_counter(), time.thread_time()
        result = simulate(scenario)
        call.append(time.perf_counter() - start)
        cpu.append(time.thread_time() - start_cpu)
        engine.append(result.wall_time_s)
    return {"call": call, "cpu": cpu, "engine": engine}


def worker_sweep(workers):
    """Wall and CPU time [s] of the 200-point sweep on ``workers`` threads, without figures.

    A 2-point sweep runs first, so that the timed one pays no imports (pandas, the Parquet writer).
    """
    import resource

    from pmsm2dof.studies.sweep import load_sweep, run_sweep

    with tempfile.TemporaryDirectory(prefix="p2d-bench-engine-") as tmp:
        path = Path(tmp) / "sweep.toml"
        path.write_text(SWEEP_TOML.replace("num = 20", "num = 2").replace("num = 10", "num = 1"))
        run_sweep(load_sweep(path), Path(tmp) / "warm-up", workers=workers, progress=False)
        path.write_text(SWEEP_TOML)
        sweep = load_sweep(path)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        start, start_cpu = time.perf_counter(), usage.ru_utime + usage.ru_stime
        run_sweep(sweep, Path(tmp) / "out", workers=workers, progress=False)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return {
            "points": len(sweep.points),
            "wall": time.perf_counter() - start,
            "cpu": usage.ru_utime + usage.ru_stime - start_cpu,
        }


def identity_cases():
    """(name, scenario) of the runs whose logs the two engines must agree on to the bit."""
    from pmsm2dof import list_presets, load_scenario

    for name in list_presets():
        scenario = load_scenario(name)
        yield name, scenario
        yield name + " (computation delay)", scenario.with_overrides({"inverter.computation_delay": True})
        if not any(f["kind"] == "dc_link_sag" for f in scenario.data["fault"]):
            yield name + " (first_order)", scenario.with_overrides({"current_loop.model": "first_order"})
    base = load_scenario("paper-condition-2")
    Ts_s = base.data["current_loop"]["Ts_s"]
    friction = {"motor.T_coulomb_Nm": 0.5, "motor.B_Nms": 0.01, "simulation.dt_s": Ts_s / 3}
    yield "paper-condition-2 (friction, 3 RK4 steps per period)", base.with_overrides(friction)
    yield (
        "paper-condition-2 (first_order, friction, 3 RK4 steps per period)",
        base.with_overrides({**friction, "current_loop.model": "first_order"}),
    )
    yield (
        "paper-condition-2 (u_dc 60 V: voltage limit)",
        base.with_overrides({"limits.u_dc_V": 60.0, "inverter.computation_delay": True}),
    )


def worker_logs(path):
    """Save every signal of every identity case to the .npz ``path``."""
    import numpy as np

    from pmsm2dof import simulate

    arrays = {}
    for name, scenario in identity_cases():
        result = simulate(scenario)
        for signal in result.signals:
            arrays[f"{name}|{signal}"] = getattr(result, signal)
    np.savez(path, **arrays)
    return {"cases": len(arrays) // len(result.signals)}


def worker_halving():
    """max |w(dt) - w(dt/2)| / max |w(dt/2)| of the speed traces of paper-condition-2 (dq_pi)."""
    import numpy as np

    from pmsm2dof import simulate

    scenario = _scenario("dq_pi")
    a = simulate(scenario)
    b = simulate(scenario.with_overrides({"simulation.dt_s": scenario.data["simulation"]["dt_s"] / 2}))
    return {"change": float(np.max(np.abs(a.w_m_radps - b.w_m_radps)) / np.max(np.abs(b.w_m_radps)))}


def worker_once(model):
    """One run (for callgrind); the number of current periods it simulates."""
    from pmsm2dof import simulate

    scenario = _scenario(model)
    simulate(scenario)
    d = scenario.data
    return {"periods": round(d["simulation"]["t_end_s"] / d["current_loop"]["Ts_s"])}


def worker(kind, arg):
    """Run the worker ``kind``; its result, with the package directory it ran on."""
    import pmsm2dof

    if kind == "single":
        model, runs = arg.split(",")
        got = worker_single(model, int(runs))
    elif kind == "sweep":
        got = worker_sweep(int(arg))
    elif kind == "logs":
        got = worker_logs(arg)
    elif kind == "halving":
        got = worker_halving()
    elif kind == "once":
        got = worker_once(arg)
    else:
        raise ValueError(kind)
    return {**got, "package": str(Path(pmsm2dof.__file__).resolve().parent)}


# ---- parent: builds the engines and runs the workers ---------------------------------------------


def git(*args):
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True, cwd=ROOT).stdout.strip()


def describe(rev):
    """Short commit of ``rev``; for the working tree, HEAD with ``+changes`` if the engine differs from it."""
    if rev is not None:
        return git("rev-parse", "--short", rev)
    dirty = git("status", "--porcelain", "--", "csrc", "ffibuild.py")
    return git("rev-parse", "--short", "HEAD") + (" + uncommitted changes" if dirty else "")


def build_engine(rev, dest):
    """Build the engine of ``rev`` (None: the working tree) and put it under a copy of the package.

    Returns the directory to put on PYTHONPATH.
    """
    import pmsm2dof

    src = dest / "build"
    src.mkdir(parents=True)
    if rev is None:
        shutil.copytree(ROOT / "csrc", src / "csrc")
        shutil.copy2(ROOT / "ffibuild.py", src / "ffibuild.py")
    else:
        archive = subprocess.run(
            ["git", "archive", rev, "csrc", "ffibuild.py"], capture_output=True, check=True, cwd=ROOT
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    code = "import runpy; runpy.run_path('ffibuild.py')['ffibuilder'].compile()"
    subprocess.run([sys.executable, "-c", code], cwd=src, check=True, capture_output=True)
    package = Path(pmsm2dof.__file__).resolve().parent
    site = dest / "site"
    shutil.copytree(
        package, site / package.name, ignore=shutil.ignore_patterns("_core.*.so", "_core.*.pyd", "__pycache__")
    )
    for built in (src / package.name).rglob("_core.*"):
        if built.suffix in (".so", ".pyd"):
            target = site / built.relative_to(src)
            shutil.copy2(built, target)
    return site


def run_worker(site, kind, arg="", valgrind=None):
    env = dict(os.environ, PYTHONPATH=str(site))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", kind, arg]
    if valgrind:
        cmd = ["valgrind", "--tool=callgrind", "--toggle-collect=p2d_sim_run", f"--callgrind-out-file={valgrind}", *cmd]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=tempfile.gettempdir())
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    if not Path(got.pop("package")).is_relative_to(site):
        raise RuntimeError(f"the worker did not run on the package under {site}: is PYTHONPATH overridden?")
    return got


def instructions(site, model, tmp):
    """Instructions per current period of the C run of one paper-condition-2 run (callgrind)."""
    out = Path(tmp) / f"callgrind-{site.parent.name}-{model}.out"
    periods = run_worker(site, "once", model, valgrind=out)["periods"]
    summary = next(line for line in out.read_text().splitlines() if line.startswith("summary:"))
    return int(summary.split()[1]) / periods


def measure(sides, rounds, runs):
    """{side: {"model": {...lists}, "sweep": {workers: [...]}}} over ``rounds`` alternating rounds."""
    data = {
        side: {**{m: {"call": [], "cpu": [], "engine": []} for m in MODELS}, "sweep": {w: [] for w in WORKERS}}
        for side in sides
    }
    for k in range(rounds):
        order = list(sides) if k % 2 == 0 else list(reversed(list(sides)))
        for side in order:
            site = sides[side]
            for model in MODELS:
                got = run_worker(site, "single", f"{model},{runs}")
                for key in got:
                    data[side][model][key] += got[key]
            for w in WORKERS:
                data[side]["sweep"][w].append(run_worker(site, "sweep", str(w)))
    return data


def identical(sides, tmp):
    """(cases, differing case names) of the logs of the two engines."""
    import numpy as np

    files = {side: Path(tmp) / f"logs-{side}.npz" for side in sides}
    for side, site in sides.items():
        run_worker(site, "logs", str(files[side]))
    before, after = (np.load(files[side]) for side in sides)
    differ = sorted(
        {
            key.split("|")[0]
            for key in after.files
            if key not in before.files or not np.array_equal(before[key], after[key], equal_nan=True)
        }
    )
    return len({key.split("|")[0] for key in after.files}), differ


def report(args, labels, data, instr, identity, change, load):
    from results_md import measured_by

    from pmsm2dof import load_scenario

    d = load_scenario("paper-condition-2").data
    t_end, Ts = d["simulation"]["t_end_s"], d["current_loop"]["Ts_s"]
    periods = t_end / Ts
    sides = list(labels)
    command = (
        "python3 benchmarks/bench_simulate.py"
        + (f" --baseline {args.baseline}" if args.baseline else "")
        + (f" --rounds {args.rounds} --runs {args.runs}")
        + (" --instructions" if args.instructions else "")
    )
    lines = [
        SECTION,
        "",
        measured_by(command) + f", Python {platform.python_version()}; 1-minute load average {load[0]:.2f} before "
        f"and {load[1]:.2f} after (the machine is shared with other work, which lowers the wall-time figures; "
        "the CPU-time figures and the instruction counts are not inflated by it).",
        "",
        "Engines: " + "; ".join(f"{side} = {label}" for side, label in labels.items()) + ". Each is built from its "
        "revision's csrc/ and ffibuild.py (its compiler flags) under the same copy of this checkout's Python "
        "package, so that the sides differ in the engine only; rounds alternate between them. "
        f"Preset `paper-condition-2` ({t_end:g} s simulated), current controller at Ts_current = {Ts * 1e6:g} us, "
        f"speed controller at {d['speed_controller']['Ts_s'] * 1e3:g} ms, plant by RK4 with "
        f"dt = {d['simulation']['dt_s'] * 1e6:g} us (one step per current period), logged every speed sample. "
        f"Medians of {args.rounds} rounds x {args.runs} runs after a warm-up run, one core.",
        "",
        "| current loop | engine | simulated s / wall s, whole `simulate()` call (slowest-fastest) | simulated s "
        "/ CPU s of the calling thread, whole call | simulated s / wall s, C run only | ns per current period (C run) |"
        + (" instructions per current period (C run, callgrind) |" if instr else ""),
        "|---|---|---:|---:|---:|---:|" + ("---:|" if instr else ""),
    ]
    rate = {}
    for model in MODELS:
        for side in sides:
            m = data[side][model]
            call, cpu, engine = (statistics.median(m[key]) for key in ("call", "cpu", "engine"))
            rate[side, model] = (t_end / call, t_end / cpu, t_end / engine)
            row = (
                f"| {model} | {side} | {t_end / call:.0f} ({t_end / max(m['call']):.0f}-{t_end / min(m['call']):.0f})"
                f" | {t_end / cpu:.0f} | {t_end / engine:.0f} | {engine / periods * 1e9:.0f} |"
            )
            if instr:
                row += f" {instr[side, model]:.0f} |"
            lines.append(row)
        if len(sides) == 2:
            b, a = sides
            ratio = [rate[a, model][i] / rate[b, model][i] for i in range(3)]
            row = f"| {model} | speed-up, {a} vs {b} | {ratio[0]:.2f} | {ratio[1]:.2f} | {ratio[2]:.2f} | |"
            if instr:
                row += f" {instr[b, model] / instr[a, model]:.2f} |"
            lines.append(row)
    lines += [
        "",
        "Sweep of 200 points of paper-condition-2 (plant inertia 0.5 to 2 times the design inertia, 20 values, x "
        "alpha 0.2 to 2 rad/s, 10 values; `dq_pi`), local threads, without figures: simulation, metrics and the "
        "Parquet parts of every point.",
        "",
        "| threads | engine | runs / s (slowest-fastest) | CPU ms per run |",
        "|---|---|---:|---:|",
    ]
    sweep_rate = {}
    for w in WORKERS:
        for side in sides:
            reps = data[side]["sweep"][w]
            rates = [r["points"] / r["wall"] for r in reps]
            sweep_rate[side, w] = statistics.median(rates)
            cpu_ms = statistics.median(1e3 * r["cpu"] / r["points"] for r in reps)
            lines.append(
                f"| {w} | {side} | {sweep_rate[side, w]:.1f} ({min(rates):.1f}-{max(rates):.1f}) | {cpu_ms:.2f} |"
            )
        if len(sides) == 2:
            b, a = sides
            lines.append(f"| {w} | speed-up, {a} vs {b} | {sweep_rate[a, w] / sweep_rate[b, w]:.2f} | |")
    lines.append("")
    if identity is not None:
        cases, differ = identity
        lines.append(
            f"Logs of the two engines: bit-identical in {cases - len(differ)} of {cases} runs (every "
            "preset as shipped, with the computation delay and with the first-order current loop; "
            "paper-condition-2 with friction and 3 RK4 steps per current period, and at the voltage limit)"
            + (": differ in " + ", ".join(differ) if differ else "")
            + "."
        )
    lines += [
        f"Accuracy of the plant step ({labels[sides[-1]]}): halving dt changes the speed trace by {change:.1e} of "
        "the largest speed (requirement < 1e-4; tests/test_engine.py checks it).",
        "",
    ]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", metavar="REV", help="git revision whose engine to measure side by side")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds (medians over all)")
    parser.add_argument("--runs", type=int, default=5, help="timed single runs per round and current loop")
    parser.add_argument("--instructions", action="store_true", help="count instructions with valgrind's callgrind")
    parser.add_argument("--no-write", action="store_true", help="print the section, do not write results.md")
    parser.add_argument("--worker", nargs=2, metavar=("KIND", "ARG"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(*args.worker)))
        return 0
    if args.instructions and shutil.which("valgrind") is None:
        parser.error("--instructions needs valgrind on PATH")

    from results_md import RESULTS, write_section

    labels = {}
    if args.baseline:
        labels["before"] = describe(args.baseline)
    labels["after" if args.baseline else "this checkout"] = describe(None)
    with tempfile.TemporaryDirectory(prefix="p2d-bench-engines-") as tmp:
        sides = {
            side: build_engine(args.baseline if side == "before" else None, Path(tmp) / side.replace(" ", "-"))
            for side in labels
        }
        load_before = os.getloadavg()[0]
        data = measure(sides, args.rounds, args.runs)
        load_after = os.getloadavg()[0]
        instr = (
            {(side, model): instructions(site, model, tmp) for side, site in sides.items() for model in MODELS}
            if args.instructions
            else None
        )
        identity = identical(sides, tmp) if len(sides) == 2 else None
        change = run_worker(sides[list(sides)[-1]], "halving")["change"]
    text = report(args, labels, data, instr, identity, change, (load_before, load_after))
    print(text)
    if not args.no_write:
        write_section(SECTION, text)
        print(f"wrote the section to {RESULTS}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
