"""The firmware's capture buffer (examples/firmware/capture.h): footprint and instructions per control interrupt.

footprint
    capture.c in firmware.elf (the porting stub's firmware, Cortex-M4F, ``-O2``) from the linker's
    map: its code and its RAM (the buffer of CAPTURE_BYTES and the configuration, status and state).
instructions
    The virtual drive of the small servo (20 kHz current, 2 kHz speed loop) on QEMU with
    ``cost=1`` (SysTick counts instructions): runs of 0.1 s with the buffer idle, then armed at
    the current event on 4 float32 signals with a trigger that never fires (a rising crossing of
    iq at 1e9 A: every interrupt records and checks the trigger, the most the buffer costs), and
    armed on 16 signals the same way. Medians of the interrupts that run the current loop alone
    and of those that also run the speed loop.

Writes its section of benchmarks/results.md.
"""

import argparse
import tempfile
from pathlib import Path

from drive_link import SERVO, code_version, costs, footprint, run_with_daq, tool_version
from results_md import measured_by, write_section

from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_qemu
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.firmware import build_firmware

SECTION = "## Capture buffer of the firmware (Cortex-M4F, QEMU)"
CURRENTS = ["foc_now.id_A", "foc_now.iq_A", "foc_now.ud_ref_V", "foc_now.uq_ref_V"]
SIXTEEN = CURRENTS + ["foc_now." + n for n in ("w_ref_radps", "w_meas_radps", "T_unsat_Nm", "T_ref_Nm", "x_i_Nm",
                                                 "id_fw_A", "J_est_kgm2", "T_load_est_Nm", "J_gains_kgm2")] + [
    "link_status_now.periods", "link_status_now.sample", "link_status_now.state"]  # fmt: skip


def arm_never_firing(link, names):
    """Arm the buffer at the current event on ``names``, waiting for iq to cross 1e9 A (it never does)."""
    scalars = [link.scalar(n) for n in names]
    link.write({"capture_config.command": 0})
    link.write({
        "capture_config.event": 0, "capture_config.n": len(names), "capture_config.samples": 16,
        "capture_config.pre_samples": 0, "capture_config.trigger": 1,
        "capture_config.trigger_signal": names.index("foc_now.iq_A"), "capture_config.level": 1e9,
        "capture_config.address": [s.address for s in scalars], "capture_config.size": [s.size for s in scalars],
    })  # fmt: skip
    link.write({"capture_config.command": 1})
    assert link.read("capture_status_now.state") == 1


def main():
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = build_firmware(load_scenario(str(SERVO)), Path(tmp) / "fw").folder
        (flash, ram) = footprint(folder / "firmware.map", {"capture.c.obj": ""})["capture.c.obj"]
        qelf = folder / "virtual_drive.elf"
        rows = []
        for name, names in (("idle", []), ("armed, 4 float32", CURRENTS), ("armed, 16 signals", SIXTEEN)):
            work = Path(tmp) / f"cost-{len(rows)}"
            work.mkdir()
            with (
                serve_qemu(qelf, serial="tcp", folder=work, cost=1) as url,
                Link(url, folder / "virtual_drive.a2l") as link,
            ):
                if names:
                    arm_never_firing(link, names)
                run_with_daq(link, [], "speed")
            rows.append((name, *costs(work)))
    base_c, base_s = rows[0][1], rows[0][2]
    lines = [
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/capture_buffer.py')}; {tool_version('arm-none-eabi-gcc')}; "
        f"{tool_version('qemu-system-arm')}; code: {code_version()}.",
        "",
        f"capture.c in firmware.elf (`-O2`, Cortex-M4F, the default 16 KiB buffer): {flash} B of flash, {ram} B of "
        f"RAM (the buffer and {ram - 16384} B of configuration, status and state).",
        "",
        "Instructions per control interrupt of the small servo's virtual drive on QEMU (link_isr with foc_isr, "
        "0.1 s runs), the buffer armed at the current event with a trigger that never fires (every interrupt "
        "records and checks it):",
        "",
        "| buffer | current loop alone: median | with the speed loop: median | the buffer: current / speed interrupt |",
        "|---|---:|---:|---:|",
        *(f"| {n} | {c:.0f} | {s:.0f} | {c - base_c:+.0f} / {s - base_s:+.0f} |" for n, c, s in rows),
        "",
        f"At about one instruction a cycle, the 4 signals' {rows[1][1] - base_c:.0f} instructions are "
        f"{(rows[1][1] - base_c) / 180e6 * 1e6:.2f} us on a 180 MHz M4F: "
        f"{(rows[1][1] - base_c) / 180e6 / 50e-6 * 100:.1f} % of the 50 us period.",
        "",
    ]
    write_section(SECTION, "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
