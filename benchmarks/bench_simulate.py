"""Throughput of the drive simulation engine, side by side with the engine of an earlier revision.

Usage::

    python3 benchmarks/bench_simulate.py [--baseline REV] [--rounds 5] [--runs 5] [--instructions]
                                         [--autotune 3] [--motulator 3] [--no-write]

Every measurement runs in a fresh subprocess on a package built for the purpose: this checkout's
``csrc/`` compiled by its ``ffibuild.py`` into a temporary directory and put under a copy of this
checkout's Python package. With ``--baseline REV`` the revision REV is built the same way from
its own ``csrc/``, ``ffibuild.py`` (so its compiler flags too) and Python package (the study
engine of a revision calls the engine its own way: lone runs, or lockstep groups). The rounds
alternate between the two sides (and which one goes first), and every figure is the median over
all rounds.

Per side:

- the preset ``paper-condition-2`` (15 s: speed step, 8 Nm load step, speed step) with the
  ``dq_pi`` current loop at Ts_current = 100 us, and with the ``first_order`` current loop:
  ``--runs`` timed :func:`pmsm2dof.simulate` calls per round after a warm-up, in wall time and
  in the CPU time of the calling thread, which runs the engine too (``time.thread_time``: other
  load on the machine does not inflate it, nor do other threads, such as the BLAS threads that
  numpy's first matrix operations leave spinning for a while), and the C run alone
  (``Result.wall_time_s``), also as nanoseconds per current period;
- where the side has it, the same scenario with 8 plant inertias (0.5 to 2 times) in one
  :func:`pmsm2dof.simulate_many` call (lockstep groups): CPU time of the calling thread per run;
- a sweep of 200 points of paper-condition-2 (plant inertia 0.5 to 2 times the design inertia,
  20 values, x alpha from 0.2 to 2 rad/s, 10 values) on 1 and on 2 threads, without figures: runs
  per second and CPU time per run (all threads of the process: simulation, metrics and the
  Parquet parts);
- with ``--instructions``: instructions executed in the C run per current period of one
  paper-condition-2 run (valgrind's callgrind, counted from ``p2d_sim_run`` down), and per
  current period and drive of the 8 inertias in lockstep (from ``p2d_sim_run_many`` down), a
  figure that other load on the machine does not change;
- with ``--autotune N``: the wall time of :func:`pmsm2dof.autotune` for the paper's drive
  (paper-condition-2, inertia 0.5 to 2 times, overshoot at most 5 %) on 2 threads, N times;
- with ``--motulator N``: the throughput on the situation of ``benchmarks/bench_motulator.py``
  (motulator run N times once, in its Python 3.12 venv; each side timed on the same
  situation), as the ratio pmsm2dof / motulator.

Then, with a baseline: how the two sides' logs compare on every preset (as shipped, with the
computation delay, with the first-order current loop), on paper-condition-2 with friction and
three RK4 steps per current period, at the voltage limit with and without the delay, with the
two-mass train (rigid and load-side feedback, play, friction, first order) and with the sensors
(encoder through the PLL, delay, noise, phase-current errors; with the delay; with the two-mass
train), and on a salient drive with load steps and ramps between samples: bit-identical, or the
largest difference of each quantity relative to its scale in the run (the largest current,
voltage, torque or speed of that run). Last, on this checkout: the accuracy of the plant step
(the largest change of the speed trace when the step is halved, relative to the largest speed),
and whether every lockstep trace of those runs equals the lone run's to the bit.

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
#: Plant inertias of the lockstep measurement, in design inertias.
MANY_J = tuple(0.5 + 1.5 * i / 7 for i in range(8))
SWEEP_TOML = """\
name = "inertia-alpha-200"
base = "paper-condition-2"

[axes]
"motor.J_kgm2" = { start = 0.2, stop = 0.8, num = 20 }
"speed_controller.alpha_radps" = { start = 0.2, stop = 2.0, num = 10, scale = "log" }
"""
#: Quantities whose logged signals are compared relative to the largest of them in the run.
QUANTITIES = {
    "currents": ("id_A", "iq_A", "id_ref_A", "iq_ref_A"),
    "voltages": ("ud_V", "uq_V"),
    "torques": ("torque_Nm", "torque_ref_Nm", "torque_unsat_Nm", "x_i_Nm", "shaft_torque_Nm", "T_load_est_Nm"),
    "speeds": ("speed_rpm", "speed_ref_rpm", "speed_meas_rpm", "load_speed_rpm"),
}
#: The bound of the restated RK4 step (see report): 2^-20 of each quantity's scale.
BOUND = 2.0**-20


# ---- worker: runs in the subprocess, on the package given by PYTHONPATH ---------------------------


def _scenario(model):
    from pmsm2dof import load_scenario

    return load_scenario("paper-condition-2").with_overrides({"current_loop.model": model})


def _inertias():
    base = _scenario("dq_pi")
    J = base.data["speed_controller"]["J_kgm2"]
    return [base.with_overrides({"motor.J_kgm2": r * J}) for r in MANY_J]


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


def worker_many(runs):
    """CPU time per run [s] of the 8 inertias in one simulate_many call, ``runs`` calls; {} without it."""
    import pmsm2dof

    if not hasattr(pmsm2dof, "simulate_many"):
        return {"cpu": []}
    scenarios = _inertias()
    pmsm2dof.simulate_many(scenarios)
    cpu = []
    for _ in range(runs):
        start = time.thread_time()
        pmsm2dof.simulate_many(scenarios)
        cpu.append((time.thread_time() - start) / len(scenarios))
    return {"cpu": cpu}


def worker_sweep(workers):
    """Wall and CPU time [s] of the 200-point sweep on ``workers`` threads, without figures.

    A 2-point sweep runs first, so that the timed one pays no imports (pandas, the Parquet writer).
    """
    import resource

    from pmsm2dof.studies.sweep import load_sweep
    from pmsm2dof.studies.sweep_run import run_sweep

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


def worker_autotune(repeats):
    """Wall and CPU times [s] of autotune for the paper's drive on 2 threads, ``repeats`` times."""
    import resource

    from pmsm2dof import Spec, autotune, load_scenario

    scenario, spec = load_scenario("paper-condition-2"), Spec(max_overshoot_pct=5.0, J_range=(0.5, 2.0))
    walls, cpus, runs = [], [], 0
    for _ in range(repeats):
        usage = resource.getrusage(resource.RUSAGE_SELF)
        start, start_cpu = time.perf_counter(), usage.ru_utime + usage.ru_stime
        result = autotune(scenario, spec, workers=2)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        walls.append(time.perf_counter() - start)
        cpus.append(usage.ru_utime + usage.ru_stime - start_cpu)
        runs = result.as_dict()["counts"]["runs"]
    return {"wall": walls, "cpu": cpus, "runs": runs}


def worker_motulator(runs):
    """Wall and CPU times [s] of ``runs`` runs of bench_motulator's situation, after a warm-up."""
    sys.path.insert(0, str(HERE))
    from bench_motulator import matched_scenario

    from pmsm2dof import simulate

    scenario = matched_scenario("paper-condition-2")
    simulate(scenario)
    walls, cpus = [], []
    for _ in range(runs):
        start, start_cpu = time.perf_counter(), time.process_time()
        simulate(scenario)
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - start_cpu)
    return {"wall": walls, "cpu": cpus, "t_end": scenario.data["simulation"]["t_end_s"]}


def identity_cases():
    """(name, scenario) of the runs whose logs the two sides are compared on."""
    from pmsm2dof import list_presets, load_scenario
    from pmsm2dof.sim.scenario import Scenario

    for name in list_presets():
        scenario = load_scenario(name)
        yield name, scenario
        yield name + " (computation delay)", scenario.with_overrides({"inverter.computation_delay": True})
        data = scenario.data
        if not any(f["kind"] == "dc_link_sag" for f in data["fault"]) and not data["field_weakening"]["enabled"]:
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
        "paper-condition-2 (u_dc 60 V: voltage limit, delay)",
        base.with_overrides({"limits.u_dc_V": 60.0, "inverter.computation_delay": True}),
    )
    yield "paper-condition-2 (u_dc 60 V: voltage limit)", base.with_overrides({"limits.u_dc_V": 60.0})
    two_mass = {
        "mechanics.model": "two_mass",
        "motor.J_kgm2": 0.1,
        "mechanics.J_load_kgm2": 0.3,
        "mechanics.stiffness_Nm_per_rad": 3000.0,
        "mechanics.damping_Nms_per_rad": 0.5,
        "speed_filter.notch_freq_Hz": 30.0,
        "speed_filter.notch_width_Hz": 10.0,
    }
    yield "paper-condition-2 (two-mass, notch)", base.with_overrides(two_mass)
    yield (
        "paper-condition-2 (two-mass, load feedback, play, friction)",
        base.with_overrides(
            {**two_mass, "mechanics.feedback": "load", "mechanics.backlash_rad": 0.002, "motor.T_coulomb_Nm": 0.3}
        ),
    )
    yield (
        "paper-condition-2 (two-mass, first_order)",
        base.with_overrides({**two_mass, "current_loop.model": "first_order"}),
    )
    sensors = {
        "speed_sensor.model": "encoder",
        "speed_sensor.counts_per_rev": 4096,
        "speed_sensor.estimator": "pll",
        "speed_sensor.bandwidth_radps": 300.0,
        "speed_sensor.delay_s": 2.5e-4,
        "speed_sensor.noise_rpm_rms": 0.5,
        "current_measurement.offset_a_A": 0.05,
        "current_measurement.gain_error_b": 0.01,
        "current_measurement.noise_A_rms": 0.02,
    }
    yield "paper-condition-2 (sensors)", base.with_overrides(sensors)
    yield "paper-condition-2 (sensors, delay)", base.with_overrides({**sensors, "inverter.computation_delay": True})
    yield (
        "paper-condition-2 (sensors, two-mass, load feedback)",
        base.with_overrides({**sensors, **two_mass, "mechanics.feedback": "load"}),
    )
    salient = {
        "name": "salient drive",
        "motor": {
            "pole_pairs": 3,
            "Rs_ohm": 0.4,
            "Ld_H": 0.006,
            "Lq_H": 0.012,
            "psi_f_Wb": 0.15,
            "J_kgm2": 0.02,
            "B_Nms": 0.002,
            "T_coulomb_Nm": 0.3,
        },
        "limits": {"i_max_A": 10.0, "u_dc_V": 300.0},
        "inverter": {"computation_delay": True},
        "current_loop": {"model": "dq_pi", "tau_i_s": 0.002, "Ts_s": 1e-4},
        "speed_controller": {"alpha_radps": 20.0, "zeta": 0.7, "Ts_s": 1e-4, "feedforward": "full", "m": 2.0},
        "simulation": {"t_end_s": 0.15, "speed0_rpm": 300.0},
        "reference": [{"t_s": 0.0, "speed_rpm": 700.0}],
        "load": [{"t_s": 0.05123, "torque_Nm": 1.5}, {"t_s": 0.08, "torque_Nm": -1.0, "ramp_s": 0.0301}],
    }
    yield "salient drive (load steps and ramps between samples)", Scenario.from_dict(salient)
    yield (
        "salient drive (first_order)",
        Scenario.from_dict(salient).with_overrides({"current_loop.model": "first_order"}),
    )


def worker_logs(path):
    """Save every signal of every identity case to the .npz ``path`` (a stop as its message)."""
    import numpy as np

    from pmsm2dof import simulate
    from pmsm2dof.errors import SimulationError

    arrays = {}
    for name, scenario in identity_cases():
        try:
            result = simulate(scenario)
        except SimulationError as exc:
            arrays[f"{name}|stop"] = np.array(str(exc))
            continue
        for signal in result.signals:
            arrays[f"{name}|{signal}"] = getattr(result, signal)
    np.savez(path, **arrays)
    return {"cases": len({key.split("|")[0] for key in arrays})}


def worker_lockstep():
    """Whether simulate_many's traces of the identity cases (and the 8 inertias) equal simulate's to the bit."""
    from pmsm2dof import simulate, simulate_many
    from pmsm2dof.errors import SimulationError

    scenarios = [s for _, s in identity_cases()] + _inertias()
    many = simulate_many(scenarios)
    equal = 0
    for scenario, a in zip(scenarios, many):
        try:
            b = simulate(scenario)
        except SimulationError as exc:
            equal += isinstance(a, SimulationError) and str(a) == str(exc)
            continue
        equal += not isinstance(a, SimulationError) and all(
            getattr(a, n).tobytes() == getattr(b, n).tobytes() for n in b.signals
        )
    return {"runs": len(scenarios), "equal": equal}


def worker_halving():
    """max |w(dt) - w(dt/2)| / max |w(dt/2)| of the speed traces of paper-condition-2 (dq_pi)."""
    import numpy as np

    from pmsm2dof import simulate

    scenario = _scenario("dq_pi")
    a = simulate(scenario)
    b = simulate(scenario.with_overrides({"simulation.dt_s": scenario.data["simulation"]["dt_s"] / 2}))
    return {"change": float(np.max(np.abs(a.w_m_radps - b.w_m_radps)) / np.max(np.abs(b.w_m_radps)))}


def worker_once(kind):
    """One run (for callgrind): paper-condition-2 with the model ``kind``, or ``many``: the 8 inertias in
    lockstep ({} without simulate_many); the number of current periods per drive and of drives."""
    import pmsm2dof

    if kind == "many":
        if not hasattr(pmsm2dof, "simulate_many"):
            return {}
        scenarios = _inertias()
        pmsm2dof.simulate_many(scenarios)
    else:
        scenarios = [_scenario(kind)]
        pmsm2dof.simulate(scenarios[0])
    d = scenarios[0].data
    return {"periods": round(d["simulation"]["t_end_s"] / d["current_loop"]["Ts_s"]), "drives": len(scenarios)}


def worker(kind, arg):
    """Run the worker ``kind``; its result, with the package directory it ran on."""
    import pmsm2dof

    workers = {
        "single": lambda: worker_single(arg.split(",")[0], int(arg.split(",")[1])),
        "many": lambda: worker_many(int(arg)),
        "sweep": lambda: worker_sweep(int(arg)),
        "autotune": lambda: worker_autotune(int(arg)),
        "motulator": lambda: worker_motulator(int(arg)),
        "logs": lambda: worker_logs(arg),
        "lockstep": worker_lockstep,
        "halving": worker_halving,
        "once": lambda: worker_once(arg),
    }
    got = workers[kind]()
    return {**got, "package": str(Path(pmsm2dof.__file__).resolve().parent)}


# ---- parent: builds the packages and runs the workers --------------------------------------------


def git(*args):
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True, cwd=ROOT).stdout.strip()


def describe(rev):
    """Short commit of ``rev``; for the working tree, HEAD with ``+changes`` if it differs from it."""
    if rev is not None:
        return git("rev-parse", "--short", rev)
    dirty = git("status", "--porcelain", "--", "csrc", "ffibuild.py", "src")
    return git("rev-parse", "--short", "HEAD") + (" + uncommitted changes" if dirty else "")


def build(rev, dest):
    """Build the package of ``rev`` (None: the working tree) with its own engine; the directory for PYTHONPATH."""
    src = dest / "build"
    src.mkdir(parents=True)
    if rev is None:
        shutil.copytree(ROOT / "csrc", src / "csrc")
        shutil.copytree(ROOT / "src", src / "src", ignore=shutil.ignore_patterns("_core.*", "__pycache__"))
        shutil.copy2(ROOT / "ffibuild.py", src / "ffibuild.py")
    else:
        archive = subprocess.run(
            ["git", "archive", rev, "csrc", "src", "ffibuild.py"], capture_output=True, check=True, cwd=ROOT
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    code = "import runpy; runpy.run_path('ffibuild.py')['ffibuilder'].compile()"
    subprocess.run([sys.executable, "-c", code], cwd=src, check=True, capture_output=True)
    site = dest / "site"
    shutil.copytree(src / "src" / "pmsm2dof", site / "pmsm2dof", ignore=shutil.ignore_patterns("__pycache__"))
    for built in (src / "pmsm2dof").glob("_core.*"):
        if built.suffix in (".so", ".pyd"):
            shutil.copy2(built, site / "pmsm2dof" / built.name)
    return site


def run_worker(site, kind, arg="", valgrind=None):
    env = dict(os.environ, PYTHONPATH=str(site))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", kind, arg]
    if valgrind:
        toggle = "p2d_sim_run_many" if arg == "many" else "p2d_sim_run"
        cmd = ["valgrind", "--tool=callgrind", f"--toggle-collect={toggle}", f"--callgrind-out-file={valgrind}", *cmd]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=tempfile.gettempdir())
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    if not Path(got.pop("package")).is_relative_to(site):
        raise RuntimeError(f"the worker did not run on the package under {site}: is PYTHONPATH overridden?")
    return got


def instructions(site, kind, tmp):
    """Instructions per current period (and drive) of the C run of ``kind`` (callgrind); None if the side lacks it."""
    out = Path(tmp) / f"callgrind-{site.parent.name}-{kind}.out"
    got = run_worker(site, "once", kind, valgrind=out)
    if not got:
        return None
    summary = next(line for line in out.read_text().splitlines() if line.startswith("summary:"))
    return int(summary.split()[1]) / (got["periods"] * got["drives"])


def measure(sides, rounds, runs):
    """{side: {model: {...lists}, "many": [...], "sweep": {workers: [...]}}} over ``rounds`` alternating rounds."""
    data = {
        side: {
            **{m: {"call": [], "cpu": [], "engine": []} for m in MODELS},
            "many": [],
            "sweep": {w: [] for w in WORKERS},
        }
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
            data[side]["many"] += run_worker(site, "many", str(runs))["cpu"]
            for w in WORKERS:
                data[side]["sweep"][w].append(run_worker(site, "sweep", str(w)))
    return data


def compare_logs(sides, tmp):
    """{case: None (bit-identical), the stop messages, or {quantity: largest difference / its scale}}."""
    import numpy as np

    files = {side: Path(tmp) / f"logs-{side.replace(' ', '-')}.npz" for side in sides}
    for side, site in sides.items():
        run_worker(site, "logs", str(files[side]))
    before, after = (np.load(files[side]) for side in sides)
    cases = {}
    for case in dict.fromkeys(key.split("|")[0] for key in after.files):
        keys = [k for k in after.files if k.startswith(case + "|")]
        if f"{case}|stop" in keys or f"{case}|stop" in before.files:
            cases[case] = ("stops", str(before.get(f"{case}|stop", "")) == str(after.get(f"{case}|stop", "")))
            continue
        if all(np.array_equal(before[k], after[k]) and before[k].tobytes() == after[k].tobytes() for k in keys):
            cases[case] = None
            continue
        worst = {}
        for quantity, names in QUANTITIES.items():
            present = [f"{case}|{n}" for n in names if f"{case}|{n}" in after.files]
            scale = max(float(np.max(np.abs(before[k]))) for k in present) or 1.0
            worst[quantity] = max(float(np.max(np.abs(after[k] - before[k]))) for k in present) / scale
        flags = sum(
            int(np.sum(before[f"{case}|{n}"] != after[f"{case}|{n}"])) for n in ("saturated", "voltage_limited")
        )
        worst["flags"] = flags
        cases[case] = worst
    return cases


def motulator(runs):
    """motulator's timing of bench_motulator's situation (its venv, ``runs`` runs)."""
    sys.path.insert(0, str(HERE))
    from bench_motulator import matched_scenario, motulator_python, motulator_spec, run_motulator

    spec = motulator_spec(matched_scenario("paper-condition-2"), runs)
    info, _, _ = run_motulator(motulator_python(), spec)
    return info


def report(args, labels, data, extra, load):
    from results_md import measured_by

    from pmsm2dof import load_scenario

    d = load_scenario("paper-condition-2").data
    t_end, Ts = d["simulation"]["t_end_s"], d["current_loop"]["Ts_s"]
    periods = t_end / Ts
    sides = list(labels)
    pair = len(sides) == 2
    command = (
        "python3 benchmarks/bench_simulate.py"
        + (f" --baseline {args.baseline}" if args.baseline else "")
        + f" --rounds {args.rounds} --runs {args.runs}"
        + (" --instructions" if args.instructions else "")
        + (f" --autotune {args.autotune}" if args.autotune else "")
        + (f" --motulator {args.motulator}" if args.motulator else "")
    )
    lines = [
        SECTION,
        "",
        measured_by(command) + f", Python {platform.python_version()}; 1-minute load average {load[0]:.2f} before "
        f"and {load[1]:.2f} after (the machine is shared with other work, which lowers the wall-time figures; "
        "the CPU-time figures and the instruction counts are not inflated by it).",
        "",
        "Sides: " + "; ".join(f"{side} = {label}" for side, label in labels.items()) + ", each built from its "
        "revision's csrc/, ffibuild.py (its compiler flags) and Python package; rounds alternate between them. "
        f"Preset `paper-condition-2` ({t_end:g} s simulated), current controller at Ts_current = {Ts * 1e6:g} us, "
        f"speed controller at {d['speed_controller']['Ts_s'] * 1e3:g} ms, plant by RK4 with "
        f"dt = {d['simulation']['dt_s'] * 1e6:g} us (one step per current period), logged every speed sample. "
        f"Medians of {args.rounds} rounds x {args.runs} runs after a warm-up run, one core.",
        "",
    ]
    instr = extra.get("instructions")
    if instr:
        lines += [
            "Instructions per current period (callgrind, a count that other load does not change):",
            "",
            "| run | " + " | ".join(sides) + (" | after / before |" if pair else " |"),
            "|---|" + "---:|" * len(sides) + ("---:|" if pair else ""),
        ]
        rows = [("dq_pi, `simulate` (p2d_sim_run)", "dq_pi"), ("first_order, `simulate` (p2d_sim_run)", "first_order")]
        rows.append(("dq_pi, 8 inertias in lockstep, per drive (`simulate_many`, p2d_sim_run_many)", "many"))
        for title, kind in rows:
            values = [instr.get((side, kind)) for side in sides]
            cells = ["n/a" if v is None else f"{v:.0f}" for v in values]
            row = f"| {title} | " + " | ".join(cells) + " |"
            if pair:
                base = instr.get((sides[0], "dq_pi" if kind == "many" else kind))
                row += f" {values[1] / base:.2f} |" if values[1] is not None and base else " |"
            lines.append(row)
        lines += [
            "",
            "(For the lockstep row the ratio is against the lone run of the side before: the work a sweep of "
            "lone runs did.)",
            "",
        ]
    lines += [
        "| current loop | side | simulated s / wall s, whole `simulate()` call (slowest-fastest) | simulated s "
        "/ CPU s of the calling thread, whole call | simulated s / wall s, C run only "
        "| ns per current period (C run) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    rate = {}
    for model in MODELS:
        for side in sides:
            m = data[side][model]
            call, cpu, engine = (statistics.median(m[key]) for key in ("call", "cpu", "engine"))
            rate[side, model] = (t_end / call, t_end / cpu, t_end / engine)
            lines.append(
                f"| {model} | {side} | {t_end / call:.0f} ({t_end / max(m['call']):.0f}-{t_end / min(m['call']):.0f})"
                f" | {t_end / cpu:.0f} | {t_end / engine:.0f} | {engine / periods * 1e9:.0f} |"
            )
        if pair:
            b, a = sides
            ratio = [rate[a, model][i] / rate[b, model][i] for i in range(3)]
            lines.append(f"| {model} | speed-up, {a} vs {b} | {ratio[0]:.2f} | {ratio[1]:.2f} | {ratio[2]:.2f} | |")
    for side in sides:
        many = data[side]["many"]
        if many:
            cpu = statistics.median(many)
            lines.append(
                f"| dq_pi, 8 inertias in lockstep (`simulate_many`) | {side} | | {t_end / cpu:.0f} "
                f"({t_end / rate[sides[0], 'dq_pi'][1] / cpu:.2f} x the lone runs of {sides[0]}) | | |"
            )
    lines += [
        "",
        "Sweep of 200 points of paper-condition-2 (plant inertia 0.5 to 2 times the design inertia, 20 values, x "
        "alpha 0.2 to 2 rad/s, 10 values; `dq_pi`), local threads, without figures: simulation, metrics and the "
        "Parquet parts of every point.",
        "",
        "| threads | side | runs / s (slowest-fastest) | CPU ms per run |",
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
        if pair:
            b, a = sides
            lines.append(f"| {w} | speed-up, {a} vs {b} | {sweep_rate[a, w] / sweep_rate[b, w]:.2f} | |")
    if "autotune" in extra:
        lines += [
            "",
            f"`pmsm2dof.autotune` for the paper's drive (paper-condition-2, inertia known to 0.5x to 2x, overshoot "
            f"at most 5 %) on 2 threads, {args.autotune} repetitions per side (target: under 3 s):",
            "",
            "| side | wall time, median (s) (repetitions) | CPU time, median (s) | simulations |",
            "|---|---:|---:|---:|",
        ]
        for side in sides:
            at = extra["autotune"][side]
            lines.append(
                f"| {side} | {statistics.median(at['wall']):.3g} ("
                + ", ".join(f"{w:.3g}" for w in at["wall"])
                + f") | {statistics.median(at['cpu']):.3g} | {at['runs']} |"
            )
    if "motulator" in extra:
        info, ours = extra["motulator"]
        theirs = statistics.median(info["wall_s"])
        theirs_cpu = statistics.median(info["cpu_s"])
        lines += [
            "",
            f"Ratio to motulator {info['motulator_version']} ({info['python']}, its own venv) on the situation of "
            f"`benchmarks/bench_motulator.py` (paper-condition-2, 1DOF PI, both loops at {Ts * 1e6:g} us, one "
            f"period of delay; motulator's median of {len(info['wall_s'])} runs: {theirs:.3g} s wall, "
            f"{theirs_cpu:.3g} s CPU):",
            "",
            "| side | pmsm2dof median wall (s) | ratio in wall time | ratio in CPU time |",
            "|---|---:|---:|---:|",
        ]
        for side in sides:
            wall, cpu = statistics.median(ours[side]["wall"]), statistics.median(ours[side]["cpu"])
            lines.append(f"| {side} | {wall:.4g} | {theirs / wall:.0f}x | {theirs_cpu / cpu:.0f}x |")
    lines.append("")
    logs = extra.get("logs")
    if logs is not None:
        same = [c for c, v in logs.items() if v is None]
        stops = [c for c, v in logs.items() if isinstance(v, tuple)]
        differ = {c: v for c, v in logs.items() if isinstance(v, dict)}
        lines.append(
            f"Logs of the two sides on {len(logs)} runs (every preset as shipped, with the computation delay and with "
            "the first-order current loop; paper-condition-2 with friction and 3 RK4 steps per period, at the voltage "
            "limit with and without the delay, with the two-mass train and with the sensors; a salient drive with "
            f"load steps and ramps between samples): bit-identical in {len(same)}"
            + (f", stopping alike in {sum(logs[c][1] for c in stops)} of {len(stops)}" if stops else "")
            + (f", different in {len(differ)}" if differ else "")
            + "."
        )
        if differ:
            worst = {q: max(v[q] for v in differ.values()) for q in QUANTITIES}
            flags = sum(v["flags"] for v in differ.values())
            lines += [
                "",
                "| quantity | largest difference / its scale in the run | bound |",
                "|---|---:|---:|",
            ]
            lines += [f"| {q} | {worst[q]:.2g} | {BOUND:.2g} |" for q in QUANTITIES]
            lines += [
                "",
                f"Flags (saturated, voltage_limited) that differ: {flags}. The sides differ by the RK4 step, restated "
                "with precomputed ratios (Rs/Ld, p Lq/Ld, 1.5 p psi_f/J, ...) and leaving out terms that are zero: the "
                "same method and step, different rounding, a few units in the last place of a double (about 1e-15) "
                "per step. The float32 controllers see the plant through its rounding to float (2^-24); a value that "
                "lies within 1e-15 of a float rounding boundary reads one float unit differently, and the closed loop "
                "carries that unit to every signal and damps it: the stated bound is 2^-20 of each quantity's scale "
                "(16 float units), the measured differences are the table's.",
            ]
    if "lockstep" in extra:
        ls = extra["lockstep"]
        lines.append(
            f"Lockstep (`simulate_many`) against lone runs (`simulate`) of {labels[sides[-1]]}: bit-identical in "
            f"{ls['equal']} of {ls['runs']} runs (the runs above and the 8 inertias)."
        )
    lines += [
        f"Accuracy of the plant step ({labels[sides[-1]]}): halving dt changes the speed trace by "
        f"{extra['halving']:.1e} of the largest speed (requirement < 1e-4; tests/test_engine.py checks it).",
        "",
    ]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", metavar="REV", help="git revision to measure side by side")
    parser.add_argument("--rounds", type=int, default=5, help="alternating rounds (medians over all)")
    parser.add_argument("--runs", type=int, default=5, help="timed single runs per round and current loop")
    parser.add_argument("--instructions", action="store_true", help="count instructions with valgrind's callgrind")
    parser.add_argument("--autotune", type=int, default=0, metavar="N", help="time autotune N times per side")
    parser.add_argument("--motulator", type=int, default=0, metavar="N", help="ratio to N motulator runs")
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
    extra = {}
    with tempfile.TemporaryDirectory(prefix="p2d-bench-engines-") as tmp:
        sides = {
            side: build(args.baseline if side == "before" else None, Path(tmp) / side.replace(" ", "-"))
            for side in labels
        }
        load_before = os.getloadavg()[0]
        data = measure(sides, args.rounds, args.runs)
        if args.autotune:
            extra["autotune"] = {side: run_worker(site, "autotune", str(args.autotune)) for side, site in sides.items()}
        if args.motulator:
            ours = {side: run_worker(site, "motulator", "21") for side, site in sides.items()}
            extra["motulator"] = (motulator(args.motulator), ours)
        load_after = os.getloadavg()[0]
        if args.instructions:
            extra["instructions"] = {
                (side, kind): instructions(site, kind, tmp)
                for side, site in sides.items()
                for kind in (*MODELS, "many")
            }
        if len(sides) == 2:
            extra["logs"] = compare_logs(sides, tmp)
        last = sides[list(sides)[-1]]
        extra["lockstep"] = run_worker(last, "lockstep")
        extra["halving"] = run_worker(last, "halving")["change"]
    text = report(args, labels, data, extra, (load_before, load_after))
    print(text)
    if not args.no_write:
        write_section(SECTION, text)
        print(f"wrote the section to {RESULTS}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
