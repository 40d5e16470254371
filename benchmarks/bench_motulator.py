"""pmsm2dof side by side with motulator: the same drive situation, both throughputs and the traces.

Usage::

    python3 benchmarks/bench_motulator.py [--scenario paper-condition-2] [--runs 3] [--no-write]

What it does, in one run:

1. Creates (once) a virtual environment with Python 3.12 from pyenv under the cache folder
   ``$PMSM2DOF_BENCH_CACHE`` (default ``~/.cache/pmsm2dof-bench``), outside the repository, and
   installs the newest motulator that installs there (``pip install --upgrade motulator``).
   motulator is not a dependency of pmsm2dof.
2. Derives from the pmsm2dof scenario the situation both tools can simulate (see
   :data:`MATCHED`): a PMSM speed step and load step with a PI speed loop whose integrator is
   driven by the realized torque (back calculation with Ka = 1/Kp, paper Fig. 5, forward Euler)
   and dq current control, speed and current sampled at the same control period, one period of
   computational delay.
3. Times ``pmsm2dof.simulate`` (median of many runs) and motulator (median of ``--runs`` runs
   in the venv, ``benchmarks/motulator/run_motulator.py``); throughput is simulated seconds per
   wall-clock second, each run timed from building the models to the finished trace, and also
   per CPU second of the process (robust to other load on the machine).
4. Interpolates both speed traces on a 1 ms grid and reports their largest and RMS difference.
5. Writes the section "Side by side with motulator" of ``benchmarks/results.md``.

To make the situation the same, motulator's current controller is given pmsm2dof's
decoupling feedforward and PI gains through two small subclasses (``run_motulator.py``,
``controller_classes``); without them its complex-vector PI leaves a current error that grows
with the acceleration at the paper's slow current loop, and the speed traces differ by tens
of rpm. Differences that remain (documented in the results section): motulator measures the
speed through its sensored observer (poles 2 pi 400 rad/s) and tracks the current reference
with a first-order law (2 pi 100 rad/s), pmsm2dof samples the exact speed and applies the
reference at once; motulator's PI integrates by forward Euler, pmsm2dof's current PIs by
Tustin; motulator integrates the plant with RK45 (rtol 1e-3) between samples, pmsm2dof with
fixed-step RK4; pmsm2dof's controllers compute in float32 (the MCU code).
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
from results_md import measured_by, write_section

from pmsm2dof.analysis.design import design
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import RPM_PER_RADPS, simulate

HERE = Path(__file__).resolve().parent
RUNNER = HERE / "motulator" / "run_motulator.py"
SECTION = "## Side by side with motulator"
TARGET_RATIO = 1000.0
PMSM2DOF_RUNS = 21
GRID_STEP_S = 1e-3

#: Overrides that make a pmsm2dof scenario the situation motulator simulates too.
MATCHED = {
    "speed_controller.feedforward": "none",
    "speed_controller.anti_windup": "back_calculation",
    "speed_controller.Ka": None,
    "speed_controller.method": "forward_euler",
    "inverter.computation_delay": True,
    "current_loop.model": "dq_pi",
    "current_loop.decouple": True,
    "motor.T_coulomb_Nm": 0.0,
}


def cache_dir():
    return Path(os.environ.get("PMSM2DOF_BENCH_CACHE", Path.home() / ".cache" / "pmsm2dof-bench"))


def python312():
    """The newest Python 3.12 that pyenv holds."""
    try:
        root = Path(subprocess.run(["pyenv", "root"], check=True, capture_output=True, text=True).stdout.strip())
    except (OSError, subprocess.CalledProcessError) as exc:
        sys.exit(f"bench_motulator: pyenv, which provides the venv's Python 3.12, does not run ({exc})")
    found = sorted(
        root.glob("versions/3.12.*/bin/python3.12"),
        key=lambda p: tuple(int(x) for x in p.parent.parent.name.split(".") if x.isdigit()),
    )
    if not found:
        sys.exit(f"bench_motulator: no Python 3.12 under {root}/versions (pyenv install 3.12)")
    return found[-1]


def motulator_python():
    """The venv's Python, after creating the venv and installing or upgrading motulator."""
    venv = cache_dir() / "venv-motulator"
    python = venv / "bin" / "python"
    if not python.exists():
        venv.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([str(python312()), "-m", "venv", str(venv)], check=True)
    pip = subprocess.run(
        [str(python), "-m", "pip", "install", "-q", "--upgrade", "motulator"], capture_output=True, text=True
    )
    if pip.returncode != 0:
        print("bench_motulator: could not upgrade motulator, using the installed one:\n" + pip.stderr, file=sys.stderr)
    return python


def matched_scenario(name):
    """The pmsm2dof scenario of the comparison: ``name`` with :data:`MATCHED` and equal periods."""
    base = load_scenario(name)
    Ts_s = base.data["current_loop"]["Ts_s"]
    return base.with_overrides({**MATCHED, "speed_controller.Ts_s": Ts_s})


def motulator_spec(scenario, runs):
    """The situation of ``scenario`` in motulator's terms (SI units, mechanical rad/s)."""
    d = scenario.data
    motor, sc = d["motor"], d["speed_controller"]
    gains = design(sc["J_kgm2"], sc["alpha_radps"], sc["zeta"], feedforward="none")
    return {
        "n_p": motor["pole_pairs"],
        "R_s": motor["Rs_ohm"],
        "L_d": motor["Ld_H"],
        "L_q": motor["Lq_H"],
        "psi_f": motor["psi_f_Wb"],
        "J": motor["J_kgm2"],
        "B": motor["B_Nms"],
        "i_s_max": d["limits"]["i_max_A"],
        "u_dc": d["limits"]["u_dc_V"],
        "T_s": d["current_loop"]["Ts_s"],
        "alpha_c": 1.0 / d["current_loop"]["tau_i_s"],
        "alpha_i": motor["Rs_ohm"] / motor["Ld_H"],  # stator pole R_s/L (one L: exact for a surface PMSM)
        "k_p": gains.Kp,
        "k_i": gains.Ki,
        "t_end": d["simulation"]["t_end_s"],
        "w_M0": d["simulation"]["speed0_rpm"] / RPM_PER_RADPS,
        "reference": [[e["t_s"], e["speed_rpm"] / RPM_PER_RADPS, e["ramp_s"]] for e in d["reference"]],
        "load": [[e["t_s"], e["torque_Nm"], e["ramp_s"]] for e in d["load"]],
        "runs": runs,
    }


def time_pmsm2dof(scenario, runs):
    """Wall and CPU times [s] of ``runs`` simulations, and the last result."""
    walls, cpus = [], []
    for _ in range(runs):
        start, cpu = time.perf_counter(), time.process_time()
        result = simulate(scenario)
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return walls, cpus, result


def run_motulator(python, spec):
    with tempfile.TemporaryDirectory(prefix="p2d-motulator-") as tmp:
        spec_path, out_path = Path(tmp) / "spec.json", Path(tmp) / "trace.npz"
        spec_path.write_text(json.dumps(spec))
        proc = subprocess.run([str(python), str(RUNNER), str(spec_path), str(out_path)], capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit("bench_motulator: motulator run failed:\n" + proc.stderr)
        info = json.loads(proc.stdout.strip().splitlines()[-1])
        with np.load(out_path) as trace:
            t_s, w_M = trace["t_s"], trace["w_M_radps"]
    info["python"] = subprocess.run([str(python), "--version"], capture_output=True, text=True).stdout.strip()
    return info, t_s, w_M


def trace_difference(result, t_mot_s, w_mot_radps):
    """Largest and RMS speed difference [rpm] on a common grid, and the largest speed [rpm]."""
    t_end = float(result.t_s[-1])
    grid = np.arange(0.0, t_end + 0.5 * GRID_STEP_S, GRID_STEP_S)
    t_mot_s, first = np.unique(t_mot_s, return_index=True)
    ours = np.interp(grid, result.t_s, result.w_m_radps) * RPM_PER_RADPS
    theirs = np.interp(grid, t_mot_s, w_mot_radps[first]) * RPM_PER_RADPS
    diff = ours - theirs
    return float(np.max(np.abs(diff))), float(np.sqrt(np.mean(diff**2))), float(np.max(np.abs(ours)))


def report(name, scenario, spec, ours_times, info, diff, load):
    """The markdown section of the results."""
    ours_walls, ours_cpus = ours_times
    theirs_walls, theirs_cpus = info["wall_s"], info["cpu_s"]
    t_end = spec["t_end"]
    ours = t_end / statistics.median(ours_walls)
    theirs = t_end / statistics.median(theirs_walls)
    ratio = ours / theirs
    ours_cpu = t_end / statistics.median(ours_cpus)
    theirs_cpu = t_end / statistics.median(theirs_cpus)
    max_diff, rms_diff, peak = diff
    lines = [
        SECTION,
        "",
        measured_by("python3 benchmarks/bench_motulator.py")
        + f"; pmsm2dof {version('pmsm2dof')} on Python {platform.python_version()}, "
        f"motulator {info['motulator_version']} on {info['python']} (separate venv); 1-minute load "
        f"average {load[0]:.2f} before and {load[1]:.2f} after.",
        "",
        f"Situation: preset `{name}` ({t_end:g} s: "
        + ", ".join(f"{e['speed_rpm']:g} rpm at {e['t_s']:g} s" for e in scenario.data["reference"])
        + ", load "
        + ", ".join(f"{e['torque_Nm']:g} Nm at {e['t_s']:g} s" for e in scenario.data["load"])
        + "), with "
        + ", ".join(f"`{k} = {json.dumps(v)}`" for k, v in MATCHED.items())
        + f" and `speed_controller.Ts_s = {spec['T_s']:g}` (the current period): 1DOF PI speed loop with "
        f"Kp = {spec['k_p']:.4g} Nm s/rad, Ki = {spec['k_i']:.4g} Nm/rad (eq 9), Ka = 1/Kp, "
        f"current limit {spec['i_s_max']:g} A, dq current control with tau_i = {1 / spec['alpha_c']:g} s, "
        f"both loops at {spec['T_s'] * 1e6:g} us, one period of computational delay.",
        "",
        "| simulator | runs | median wall time (s) | throughput (simulated s / wall s) "
        "| throughput (simulated s / CPU s) |",
        "|---|---:|---:|---:|---:|",
        f"| pmsm2dof | {len(ours_walls)} | {statistics.median(ours_walls):.4g} | {ours:.4g} | {ours_cpu:.4g} |",
        f"| motulator | {len(theirs_walls)} | {statistics.median(theirs_walls):.4g} | {theirs:.4g} "
        f"| {theirs_cpu:.4g} |",
        "",
        f"Ratio pmsm2dof / motulator: **{ratio:.0f}x** in wall time (target >= {TARGET_RATIO:.0f}x: "
        + ("met" if ratio >= TARGET_RATIO else "missed")
        + f"), {ours_cpu / theirs_cpu:.0f}x in CPU time "
        "(the process's own CPU seconds, which other load on the machine does not inflate).",
        "",
        f"Speed traces on a {GRID_STEP_S * 1e3:g} ms grid: largest difference {max_diff:.3g} rpm, "
        f"RMS {rms_diff:.3g} rpm ({100 * max_diff / peak:.2g} % and {100 * rms_diff / peak:.2g} % of the "
        f"{peak:.4g} rpm peak speed).",
        "",
        "Same situation: motulator's current controller is given pmsm2dof's decoupling feedforward "
        "j w_m psi_s(i) and dq PI gains (Kp = L/tau_i, Ki = Rs/tau_i) by two small subclasses in "
        "`benchmarks/motulator/run_motulator.py`; with its own complex-vector PI the slow current loop "
        "lags by a current error that grows with the acceleration. Remaining differences: motulator "
        "feeds the speed controller from its sensored speed observer (poles 2 pi 400 rad/s) and tracks "
        "the current reference at 2 pi 100 rad/s, pmsm2dof samples the exact speed and applies the "
        "reference at once; current PI by forward Euler (motulator) or Tustin (pmsm2dof); plant by "
        "RK45 with rtol 1e-3 between samples, in Python (motulator), or fixed-step RK4 in C "
        "(pmsm2dof); pmsm2dof's controllers compute in float32 (the MCU code).",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper-condition-2", help="pmsm2dof preset or scenario file")
    parser.add_argument("--runs", type=int, default=3, help="timed motulator runs (median)")
    parser.add_argument("--no-write", action="store_true", help="print only, leave results.md alone")
    args = parser.parse_args(argv)

    python = motulator_python()
    load_before = os.getloadavg()[0]
    scenario = matched_scenario(args.scenario)
    spec = motulator_spec(scenario, args.runs)
    simulate(scenario)  # warm-up: page in the extension and numpy
    ours_walls, ours_cpus, result = time_pmsm2dof(scenario, PMSM2DOF_RUNS)
    info, t_mot, w_mot = run_motulator(python, spec)
    diff = trace_difference(result, t_mot, w_mot)
    load = (load_before, os.getloadavg()[0])
    text = report(args.scenario, scenario, spec, (ours_walls, ours_cpus), info, diff, load)
    if not args.no_write:
        write_section(SECTION, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
