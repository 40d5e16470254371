"""Commissioning and identification on a drive over XCP: wall times and what each finds against the truth.

Builds ``examples/firmware`` for the small servo (20 kHz current, 2 kHz speed loop) without its
load, with a motor the host never reads (J 1.3e-4 kg m^2 where the speed controller is designed for
1e-4, B 2e-5 Nm s/rad, Coulomb 0.004 Nm), and writes the section "Commissioning and identification
on the drive" of ``benchmarks/results.md``: the wall time of ``pmsm2dof drive commission`` and
``drive identify`` (in-process, the link opened and closed by each; medians of 3 on the PC's drive
run as fast as the link allows, one run on QEMU's TCP link) beside the engine's run of the same
routine (``pmsm2dof.sim.commission.commission``) and the drive's time each covers; and each
estimate against the hidden truth.

Usage: ``python3 benchmarks/drive_bench.py`` (some three minutes: builds and QEMU runs).
"""

import contextlib
import io
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from results_md import measured_by, write_section

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from pmsm2dof.drive.serve import serve_host, serve_qemu  # noqa: E402
from pmsm2dof.sim.commission import commission  # noqa: E402
from pmsm2dof.sim.scenario import load_scenario  # noqa: E402
from pmsm2dof.studies.firmware import build_firmware  # noqa: E402
from pmsm2dof.ui.cli import main  # noqa: E402

SECTION = "## Commissioning and identification on the drive (PC's virtual drive, QEMU)"
HIDDEN = {"load": [], "motor.J_kgm2": 1.3e-4, "speed_controller.J_kgm2": 1e-4, "motor.B_Nms": 2e-5,
          "motor.T_coulomb_Nm": 0.004}  # fmt: skip
REPEATS = 3


def timed(argv):
    """Wall time of ``pmsm2dof ARGV`` in this process [s] (its output kept from the terminal)."""
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    wall = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"pmsm2dof {' '.join(argv)} exited with {code}")
    return wall


def on_drive(kind, folder, tmp, n):
    """Walls of ``drive commission`` and ``drive identify`` (n runs each) and their last outputs."""
    serve = (
        serve_host(folder / "virtual_drive_host", realtime=False, timeout_ms=1000)
        if kind == "host"
        else serve_qemu(folder / "virtual_drive.elf", serial="tcp", timeout_ms=1000)
    )
    a2l = folder / ("virtual_drive_host.a2l" if kind == "host" else "virtual_drive.a2l")
    walls = {"commission": [], "identify": []}
    with serve as url:
        link = ["--link", url.replace("socket://", "tcp://"), "--a2l", str(a2l)]
        for i in range(n):
            for command in walls:
                out = tmp / f"{kind}-{command}-{i}"
                walls[command].append(timed(["drive", command, "--out", str(out), *link]))
    last = n - 1
    result = json.loads((tmp / f"{kind}-commission-{last}" / "result.json").read_text())
    found = json.loads((tmp / f"{kind}-identify-{last}" / "identify.json").read_text())
    found["t_plan_s"] = load_scenario(str(tmp / f"{kind}-identify-{last}" / "plan.toml")).data["simulation"]["t_end_s"]
    return walls, result, found


def main_():
    scenario = load_scenario(str(ROOT / "examples" / "firmware" / "small-servo-20k.toml")).with_overrides(HIDDEN)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        folder = build_firmware(scenario, tmp / "fw").folder
        host_walls, result, found = on_drive("host", folder, tmp, REPEATS)
        qemu_walls, q_result, q_found = on_drive("qemu", folder, tmp, 1)
    drive_only = ("Ts_s", "voltage_delay_samples")
    settings = {f"commissioning.{k}": v for k, v in result["config"].items() if k not in drive_only}
    engine_walls = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        engine = commission(scenario.with_overrides({**settings, "commissioning.theta0_rad": 0.0}))
        engine_walls.append(time.perf_counter() - start)
    motor = scenario.data["motor"]
    t_routine = result["total_time_s"]
    qemu = subprocess.run(["qemu-system-arm", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    med = statistics.median
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    lines = [
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/drive_bench.py')}; {qemu}; code: {commit.stdout.strip()}.",
        "",
        "The small servo (20 kHz current, 2 kHz speed loop) without its load, its motor hidden from the host "
        "(J = 1.3e-4 kg m^2 where the speed controller is designed for 1e-4; B = 2e-5 Nm s/rad, Coulomb 0.004 Nm). "
        "Wall times of the commands in one process (the link opened and closed by each, the output folder "
        f"written); the PC's drive as fast as the link allows (median of {REPEATS}), QEMU's TCP link (one run).",
        "",
        "| step | drive's time | PC's drive: wall | QEMU: wall | engine: wall |",
        "|---|---:|---:|---:|---:|",
        f"| `drive commission` (the whole routine) | {t_routine:.3g} s | {med(host_walls['commission']):.3g} s | "
        f"{qemu_walls['commission'][0]:.3g} s | {med(engine_walls):.3g} s (`pmsm2dof commission`'s run) |",
        f"| `drive identify` (the plan: 5 speed steps, then to rest) | {found['t_plan_s']:.3g} s | "
        f"{med(host_walls['identify']):.3g} s | {qemu_walls['identify'][0]:.3g} s | |",
        "",
        "| estimate | truth | PC's drive | QEMU | engine (same routine settings) |",
        "|---|---:|---:|---:|---:|",
    ]
    for key in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb"):
        d, q, e = result["estimates"][key], q_result["estimates"][key], engine.estimates[key]
        t = motor[key]
        lines.append(f"| {key} | {t:.6g} | {d:.7g} ({d / t - 1:+.2e}) | {q:.7g} ({q / t - 1:+.2e}) | "
                     f"{e:.7g} ({e / t - 1:+.2e}) |")  # fmt: skip
    for key in ("J_kgm2", "B_Nms", "T_coulomb_Nm"):
        d, q, t = found[key], q_found[key], motor[key]
        lines.append(f"| {key} | {t:.6g} | {d:.6g} ({d / t - 1:+.2e}) | {q:.6g} ({q / t - 1:+.2e}) | |")
    lines += [
        "",
        "psi_f on the virtual drive is 0.5 % low against the engine's run: the virtual board holds each period's "
        "voltage in the rotor frame at the period's starting angle (its inverter turns with the rotor), the "
        "engine's commissioning run holds the stator vector as an inverter does; the shift of the active flux, "
        "-Ts Rs i_spin / 2, is what tests/test_drive_bench.py checks. QEMU's time runs slower than the wall "
        "clock while the virtual motor's soft-float physics runs, and the link (DAQ at every speed sample) paces it.",
        "",
    ]
    write_section(SECTION, "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main_()
