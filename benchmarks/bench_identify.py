"""Accuracy and cost of ``pmsm2dof identify`` on logs with known mechanics.

Usage::

    python3 benchmarks/bench_identify.py [--drives 200] [--no-write]

Each drive is simulated by the engine with random J, B, Coulomb friction and an unannounced load
(the drive of tests/test_identify.py: kt = 1.2 Nm/A, 7.6 A, the closed current loop of eq 3,
speed steps of up to 1200 rpm in both directions), its log degraded as a real one (the speed from
encoder counts differenced over 1 ms, 1024 to 16384 counts per turn; white torque noise up to
0.1 Nm), then identified with ``speed_is_period_mean``. Reported: the relative errors of J, B and
the Coulomb friction (median, 95th percentile, largest), how often the 95 % intervals hold the
truth, and the CPU time of one identification (a 2.8 s log of 2801 rows). Also the log of
another simulator (tests/data/motulator_identification.npz). Writes the section "Identification
accuracy" of benchmarks/results.md.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from results_md import measured_by, write_section  # noqa: E402
from test_identify import drive_scenario, measured_log  # noqa: E402

from pmsm2dof.sim.logs import read_log  # noqa: E402
from pmsm2dof.sim.simulate import simulate  # noqa: E402
from pmsm2dof.studies.identify import identify_mechanics, torque_from_currents  # noqa: E402

SECTION = "## Identification accuracy (`benchmarks/bench_identify.py`)"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drives", type=int, default=200)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args()
    rng = np.random.default_rng(13)
    errors, hits, cpu = [], np.zeros(3), []
    for i in range(args.drives):
        J = float(np.exp(rng.uniform(np.log(0.004), np.log(0.04))))
        B = float(rng.uniform(0.0005, 0.01))
        Tc = float(rng.uniform(0.05, 0.5))
        t_load = float(rng.uniform(0.1, 2.4))
        load = [{"t_s": t_load, "torque_Nm": float(rng.uniform(-2, 2))}, {"t_s": t_load + 0.2, "torque_Nm": 0.0}]
        cpr = int(rng.choice([1024, 4096, 16384]))
        log = measured_log(simulate(drive_scenario(J, B, Tc, load)), cpr, float(rng.uniform(0.0, 0.1)), seed=i)
        start = time.process_time()
        m = identify_mechanics(log, speed_is_period_mean=True)
        cpu.append(time.process_time() - start)
        truth = (J, B, Tc)
        found = (m.J_kgm2, m.B_Nms, m.T_coulomb_Nm)
        cis = (m.J_kgm2_ci, m.B_Nms_ci, m.T_coulomb_Nm_ci)
        errors.append([abs(f / t - 1) for f, t in zip(found, truth)])
        hits += [lo <= t <= hi for t, (lo, hi) in zip(truth, cis)]
    errors = np.array(errors) * 100
    path = ROOT / "tests" / "data" / "motulator_identification.npz"
    log = read_log(path)
    data = np.load(path)
    mot = identify_mechanics(log, torque_Nm=torque_from_currents(log, 4, 0.2, 0.01, 0.01))
    mot_err = [
        100 * abs(mot.J_kgm2 / float(data["true_J_kgm2"]) - 1),
        100 * abs(mot.B_Nms / float(data["true_B_Nms"]) - 1),
        100 * abs(mot.T_coulomb_Nm / float(data["true_T_coulomb_Nm"]) - 1),
    ]
    rows = []
    for k, (name, target) in enumerate((("J", 2), ("B", 35), ("Coulomb friction", 15))):
        e = errors[:, k]
        rows.append(
            f"| {name} | {np.median(e):.2f} | {np.percentile(e, 95):.2f} | {e.max():.2f} | {target} | "
            f"{100 * hits[k] / args.drives:.0f} | {mot_err[k]:.2f} |"
        )
    text = "\n".join(
        [
            SECTION,
            "",
            f"{measured_by('python3 benchmarks/bench_identify.py')}; load average "
            f"{open('/proc/loadavg').read().split()[0]}. {args.drives} engine drives with random J (0.004 to "
            "0.04 kg m^2), B (0.0005 to 0.01 Nm s/rad), Coulomb friction (0.05 to 0.5 Nm), an unannounced "
            "load of up to 2 Nm for 0.2 s, the speed from 1024 to 16384 encoder counts per turn differenced "
            "over 1 ms and torque noise up to 0.1 Nm; and the log made by motulator "
            "(tests/data/make_motulator_logs.py). Relative errors in %:",
            "",
            "| parameter | median | 95th percentile | largest | target | 95 % interval holds the truth [%] "
            "| motulator log |",
            "|---|---|---|---|---|---|---|",
            *rows,
            "",
            "The largest errors of B and of the Coulomb friction come from the slowest drives, which never "
            "reach a steady speed between the steps (B and the Coulomb friction are told apart by the "
            "speeds held); their intervals are wide accordingly. CPU time of one identification of a "
            f"2801-row log: median {1e3 * np.median(cpu):.1f} ms.",
            "",
        ]
    )
    print(text)
    if not args.no_write:
        write_section(SECTION, text)


if __name__ == "__main__":
    main()
