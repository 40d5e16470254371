"""The FOC firmware closed loop on the emulated Cortex-M4F: instructions per interrupt, CPU load, agreement.

Builds ``examples/firmware`` for a few scenarios (``pmsm2dof.studies.firmware.build_firmware``: the
scenario's ``p2d_config.h`` and the virtual board on the engine's plant), runs each on QEMU
(``-M mps2-an386``, ``-icount shift=7``) and the engine on the same scenario
(``run_firmware``), and writes the section "FOC firmware on the Cortex-M4F (virtual board, QEMU)"
of ``benchmarks/results.md``:

instructions per interrupt
    Counted by the firmware at every control interrupt of the whole run: ``link_isr`` (the XCP
    link's clock, events and, at a speed sample, its commit check, watchdog, guard and reference
    schedule) and ``foc_isr`` with every callee (the board's reads and writes, the transforms,
    ``sinf``/``cosf``, the controllers), from
    SysTick read around the call at 128 ns of QEMU's clock per instruction (3.2 ticks: exact; the
    count equals QEMU's instruction trace, tests/test_firmware.py). Interrupts that run the speed
    loop and those that run the current loop alone are counted apart.
CPU load
    The cycles are the instructions times an assumed 1.5 cycles per instruction (on the Cortex-M4
    most integer and FPU instructions take 1 cycle, loads 2 (1 when pipelined), taken branches 2 to
    4, ``vdiv.f32``/``vsqrt.f32`` 14: Cortex-M4 Technical Reference Manual, instruction timings;
    flash wait states add more on a part without a cache hit). Mean load: the run's mean interrupt;
    worst: the longest interrupt's share of its period. At 20 kHz on a 170 MHz part (an STM32G4
    class MCU) and at 10 kHz on a 72 MHz one (an STM32F3 class MCU); the load scales with the
    cycles per instruction assumed.
agreement
    The firmware's largest difference from the engine on the speed and the currents, relative to
    their step (tests/test_firmware.py requires 1e-4).

Usage: ``python3 benchmarks/firmware_cost.py`` (a few minutes: builds and QEMU runs).
"""

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from results_md import measured_by, write_section

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from pmsm2dof.sim.scenario import load_scenario  # noqa: E402
from pmsm2dof.studies.firmware import build_firmware, run_firmware  # noqa: E402
from pmsm2dof.studies.virtual_drive import CYCLES_PER_INSTRUCTION  # noqa: E402

SECTION = "## FOC firmware on the Cortex-M4F (virtual board, QEMU)"
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"
#: (core clock [Hz], control-interrupt rate [Hz]) of the two parts of the load table
PARTS = ((170e6, 20e3), (72e6, 10e3))

#: The runs: name, scenario, what it exercises.
RUNS = (
    (
        "paper experiment 1 (10 kHz / 1 kHz)",
        lambda: load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": 0.8}),
        "0.8 s: at rest, then the 500 rpm step at 0.5 s at the current limit",
    ),
    (
        "small servo (20 kHz / 2 kHz)",
        lambda: load_scenario(str(SERVO)),
        "its whole 0.2 s: limited acceleration, a load step, a step down",
    ),
    (
        "small servo, every part (20 kHz / 2 kHz)",
        lambda: load_scenario(str(SERVO.parent / "small-servo-every-part.toml")),
        "salient (MTPA), encoder with PLL and low-pass, notch, field weakening, inertia estimator with gain scheduling",
    ),
)


def tool_version(cmd):
    return subprocess.run([cmd, "--version"], capture_output=True, text=True).stdout.splitlines()[0]


def code_version():
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True, cwd=ROOT).stdout
    return head.stdout.strip() + ("+" if dirty.strip() else "")


def measure(workdir):
    rows = []
    for name, make, what in RUNS:
        folder = workdir / name.split(" (")[0].replace(" ", "-").replace(",", "")
        build = build_firmware(make(), folder)
        run = run_firmware(folder)
        cost, comparison = run.cost(), run.comparison()
        rows.append(dict(name=name, what=what, cost=cost, comparison=comparison, run=run, sizes=build.sizes))
        print(name, cost, comparison["speed"], comparison["currents"], flush=True)
    return rows


def report(rows):
    lines = [
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/firmware_cost.py')}; {tool_version('arm-none-eabi-gcc')}; "
        f"{tool_version('qemu-system-arm')}; code: {code_version()}.",
        "",
        "`examples/firmware` (foc.c) on the virtual board (board_virtual.c: the engine's plant), built by "
        "`pmsm2dof firmware` with the flags users ship with (`-O2 -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 "
        "-mfloat-abi=hard -ffp-contract=off`) and run on QEMU by `pmsm2dof firmware run`. Every control "
        "interrupt of the run is counted: `link_isr` (the XCP link's clock and events with no DAQ list, and at "
        "a speed sample its commit check, watchdog, guard and reference schedule, in double) and `foc_isr` with "
        "its callees (the board's register reads and duty writes, Clarke and Park, newlib's `sinf` and `cosf`, "
        "the controllers), as the firmware counts it "
        "with SysTick at 128 ns of QEMU's clock per instruction (exact: the counts equal QEMU's instruction "
        "trace, `tests/test_firmware.py`). The count varies with the angle (the range reduction of `sinf` "
        "and `cosf`) and the controllers' paths (the current limit, the voltage limit).",
        "",
        "### Instructions per control interrupt (whole run)",
        "",
        "| run | what it exercises | current loop alone: min / median / max | with the speed loop: min / median "
        "/ max | flash / RAM of the firmware |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        c, s = r["cost"]["current"], r["cost"]["speed"]
        size = r["sizes"]["virtual_drive.elf"]
        lines.append(
            f"| {r['name']} | {r['what']} | {c['min']} / {c['median']:g} / {c['max']} | {s['min']} / "
            f"{s['median']:g} / {s['max']} | {size['text'] + size['data']} B / {size['data'] + size['bss']} B "
            "(virtual board and plant included) |"
        )
    lines += [
        "",
        f"### CPU load ({CYCLES_PER_INSTRUCTION:g} cycles per instruction assumed)",
        "",
        "Mean: the run's mean interrupt (the speed loop's share spread over its current periods); worst: the "
        "longest interrupt of the run against its period. Cycles = instructions x "
        f"{CYCLES_PER_INSTRUCTION:g} (Cortex-M4: most instructions 1 cycle, loads 2, taken branches 2 to 4, "
        "`vdiv.f32`/`vsqrt.f32` 14 (Technical Reference Manual, instruction timings); flash wait states add "
        "more); the load scales with that assumption. The firmware's own run on QEMU takes its time on the "
        "first part's core (170 MHz at 1.5 cycles per instruction): an interrupt longer than its period "
        "stops the run as an overrun.",
        "",
        "| run | " + " | ".join(f"{f / 1e6:g} MHz at {r / 1e3:g} kHz: mean / worst" for f, r in PARTS) + " |",
        "|---|" + "---|" * len(PARTS),
    ]
    notes = []
    for r in rows:
        n = r["run"].instructions.astype(float)
        cells = []
        for f_cpu, f_isr in PARTS:
            mean = np.mean(n) * CYCLES_PER_INSTRUCTION * f_isr / f_cpu
            worst = np.max(n) * CYCLES_PER_INSTRUCTION * f_isr / f_cpu
            cells.append(f"{100 * mean:.1f} % / {100 * worst:.1f} %")
        lines.append(f"| {r['name']} | " + " | ".join(cells) + " |")
        # the speed samples where the gain scheduling re-designed the controller (p2d_speed_set_config)
        run = r["run"]
        redesigns = np.flatnonzero(np.diff(run.firmware.J_gains_kgm2) != 0) + 1
        if len(redesigns):
            speed = run.instructions[run.speed_sample]
            others = np.delete(speed, redesigns)
            notes.append(
                f"In {r['name']} the longest interrupts ({', '.join(str(int(speed[k])) for k in redesigns)} "
                f"instructions) are the {len(redesigns)} re-designs of the gain scheduling (`p2d_speed_set_config` "
                f"in the speed interrupt, as in the engine; a drive can run it from the background loop); the "
                f"other speed interrupts take at most {int(others.max())}."
            )
    lines += ["", *notes] if notes else []
    lines += [
        "",
        "### Agreement with the engine (the same scenario)",
        "",
        "Largest difference of the firmware's trace from the engine's, relative to the step (the larger "
        "excursion of the speed or its reference; of the dq currents or their references).",
        "",
        "| run | speed | currents | QEMU wall time |",
        "|---|---|---|---|",
    ]
    for r in rows:
        c = r["comparison"]
        lines.append(
            f"| {r['name']} | {c['speed']['relative_to_step']:.2g} of {c['speed']['step']:.4g} rad/s | "
            f"{c['currents']['relative_to_step']:.2g} of {c['currents']['step']:.4g} A | "
            f"{r['run'].wall_time_s:.2f} s |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="pmsm2dof-firmware-cost-") as tmp:
        text = report(measure(Path(tmp)))
    write_section(SECTION, text)
    print(text)


if __name__ == "__main__":
    main()
