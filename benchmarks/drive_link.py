"""The firmware's XCP link: footprint, instructions per interrupt, throughput and calibration latency.

Builds ``examples/firmware`` for the small servo (20 kHz current, 2 kHz speed loop) and writes the
section "XCP link of the firmware (Cortex-M4F, QEMU, and the PC's drive)" of
``benchmarks/results.md``:

footprint
    Flash (.text, .rodata, .data) and RAM (.data, .bss) of the link's objects in ``firmware.elf``
    (the porting stub's firmware: no virtual board), from the linker's map: the slave
    (csrc/src/xcp.c), the firmware's link (link.c: segments, buffers, run control), the schedule
    player (schedule.c) and the UART driver (csrc/target/cmsdk_uart.c).
instructions per interrupt
    The virtual drive on QEMU counts the instructions of each control interrupt (``link_isr``: the
    slave's calibration commit, watchdog and guard, ``foc_isr``, the DAQ events) with SysTick at
    128 ns of QEMU's clock per instruction (``cost=1``). A run of 0.1 s without DAQ, then with DAQ
    lists of 8 float signals at the speed event, at the current event, and of the 26 double and
    integer columns of the trace row at the speed event: the medians of the interrupts with and
    without the speed loop, and their difference from the run without DAQ (the slave's sampling).
throughput
    Runs of 0.1 s captured by DAQ with no lost sample (the virtual board waits for the link:
    ``board_virtual.c``): the DAQ payload per second of the wall clock and the drive's time per wall
    time, on QEMU's pty and TCP and on the PC's drive; then the PC's drive on the wall clock (it
    cannot wait) with DAQ lists at the current rate (20 kHz) of growing size: the lost samples.
latency
    Wall time of a calibration write of alpha (SET_MTA + DOWNLOAD of 4 bytes, answered once the
    firmware committed it at its next speed sample) and of a GET_STATUS, medians of 20, with the drive
    idle and running.
pmsm2dof drive
    ``drive capture`` on the PC's drive on the wall clock at the current event (20 kHz, 1 s): the
    samples, the lost ones, and the time to write them as CSV, Parquet and MDF4 with the file sizes;
    ``drive set`` of alpha: the checked write (A2L limits, the controller's validation on the
    configuration read back, one DOWNLOAD, the value read back; medians of 20) beside the bare
    write, on the PC's drive and QEMU's TCP link, and the whole command (a new process) on the PC.

Usage: ``python3 benchmarks/drive_link.py`` (a few minutes: builds and QEMU runs).
"""

import argparse
import re
import statistics
import struct
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np
from results_md import measured_by, write_section

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from pmsm2dof.drive.link import Link  # noqa: E402
from pmsm2dof.drive.serve import serve_host, serve_qemu  # noqa: E402
from pmsm2dof.sim.scenario import load_scenario  # noqa: E402
from pmsm2dof.studies.firmware import SPEED_SAMPLE_BIT, build_firmware  # noqa: E402

SECTION = "## XCP link of the firmware (Cortex-M4F, QEMU, and the PC's drive)"
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"
SAMPLES = 200  # speed samples of a run (0.1 s at 2 kHz)
OBJECTS = {
    "xcp.c.obj": "XCP slave (csrc/src/xcp.c)",
    "link.c.obj": "firmware link (link.c)",
    "schedule.c.obj": "schedule player (schedule.c)",
    "cmsdk_uart.c.obj": "UART driver (cmsdk_uart.c)",
}
FLOATS = ["foc_now." + n for n in ("w_ref_radps", "w_meas_radps", "T_unsat_Nm", "T_ref_Nm", "id_A", "iq_A",
                                   "x_i_Nm", "ud_ref_V")]  # fmt: skip
TRACE = ["link_status_now.runs", "link_status_now.sample"] + [
    "vd_trace." + c
    for c in "t_s w_ref_radps w_m_radps id_ref_A iq_ref_A id_A iq_A ud_V uq_V torque_Nm torque_ref_Nm torque_unsat_Nm "
    "load_Nm saturated x_i_Nm w_meas_radps u_dc_V voltage_limited J_est_kgm2 J_valid T_load_est_Nm J_gains_kgm2 "
    "w_load_radps shaft_torque_Nm".split()
]


def tool_version(cmd):
    return subprocess.run([cmd, "--version"], capture_output=True, text=True).stdout.splitlines()[0]


def code_version():
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True, cwd=ROOT).stdout
    return head.stdout.strip() + ("+" if dirty.strip() else "")


def footprint(map_file, objects=OBJECTS):
    """{object: [flash, ram]} of the link's objects, from the linker map's placed input sections."""
    sizes = {o: [0, 0] for o in objects}
    text = map_file.read_text()
    body = text[text.index("Linker script and memory map") :]
    section = ""
    for line in body.splitlines():
        head = re.match(r"^ (\.\w+)(\.\S*)?\s*(0x[0-9a-f]+\s+0x[0-9a-f]+\s+(\S+))?$", line)
        if head:
            section = head.group(1)
            rest = head.group(3)
        else:
            m = re.match(r"^\s+(0x[0-9a-f]+\s+0x[0-9a-f]+\s+(\S+))$", line)
            rest = m.group(1) if m else None
        if not rest:
            continue
        address, size, path = rest.split()
        name = path.split("(")[-1].rstrip(")").split("/")[-1]
        if name in sizes and int(address, 16) != 0:
            n = int(size, 16)
            if section in (".text", ".rodata", ".data"):
                sizes[name][0] += n
            if section in (".data", ".bss"):
                sizes[name][1] += n
    return sizes


def run_with_daq(link, names, event, samples=SAMPLES):
    """A run of ``samples`` speed samples with a DAQ list (or none): (wall s, DAQ samples of the run, lost)."""
    if not names:
        link.start(samples)
        start = time.perf_counter()
        link.wait(["done"], 300)
        return time.perf_counter() - start, 0, 0
    state = {}

    def until(link):
        if not state:
            link.start(samples)
            state["t"] = time.perf_counter()
        return link.status()["state"] == "done"

    cap = link.capture([*names, "link_status_now.power_on"], event=event, until=until)
    wall = time.perf_counter() - state["t"]
    return wall, int(np.sum(cap.signals["link_status_now.power_on"] == 1)), cap.dtos_lost


def costs(folder):
    words = np.fromfile(folder / "cost.bin", dtype="<u4")
    speed = (words & np.uint32(SPEED_SAMPLE_BIT)) != 0
    n = words & ~np.uint32(SPEED_SAMPLE_BIT)
    return float(np.median(n[~speed])), float(np.median(n[speed]))


def latency(link, running):
    """Medians of 20 [ms]: a calibration write of alpha, a GET_STATUS."""
    x = link.master
    address = link.scalar("link_speed_config.alpha_radps").address
    alpha = link.read("link_speed_config.alpha_radps")
    if running:
        link.start(10**6)
    writes, polls = [], []
    for _ in range(20):
        t = time.perf_counter()
        x.setMta(address)
        x.download(struct.pack("<f", alpha))
        writes.append(time.perf_counter() - t)
        t = time.perf_counter()
        x.getStatus()
        polls.append(time.perf_counter() - t)
    if running:
        link.stop()
    return statistics.median(writes) * 1e3, statistics.median(polls) * 1e3


def payload_bytes(link, names):
    return sum(link.scalar(n).size for n in names)


def main():
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    scenario = load_scenario(str(SERVO))
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = build_firmware(scenario, Path(tmp) / "fw").folder
        fp = footprint(folder / "firmware.map")
        qelf = folder / "virtual_drive.elf"
        cases = [("none", [], "speed"), ("8 floats at the speed event", FLOATS, "speed"),
                 ("8 floats at the current event", FLOATS, "current"),
                 ("trace row (26 columns) at the speed event", TRACE, "speed")]  # fmt: skip
        cost_rows = []
        for name, names, event in cases:
            work = Path(tmp) / f"cost-{len(cost_rows)}"
            work.mkdir()
            with serve_qemu(qelf, serial="tcp", folder=work, cost=1) as url, Link(url, qelf) as link:
                run_with_daq(link, names, event)
            cost_rows.append((name, *costs(work)))
        throughput = []
        for kind in ("qemu-pty", "qemu-tcp", "host"):
            ctx = (
                serve_host(folder / "virtual_drive_host", realtime=False)
                if kind == "host"
                else serve_qemu(qelf, serial=kind.split("-")[1])
            )
            program = folder / "virtual_drive_host" if kind == "host" else qelf
            with ctx as url, Link(url, program) as link:
                for name, names, event in cases[1:]:
                    wall, n, lost = run_with_daq(link, names, event)
                    dto = payload_bytes(link, names) + 1 + 4  # PID, timestamp
                    throughput.append((kind, name, n, lost, n * dto / wall / 1e3, SAMPLES * 5e-4 / wall))
                rows[kind] = (latency(link, False), latency(link, True))
        lossy = []
        with (
            serve_host(folder / "virtual_drive_host", realtime=True) as url,
            Link(url, folder / "virtual_drive_host") as link,
        ):
            for count in (4, 8, 16, 26):
                names = (FLOATS + TRACE)[:count] if count <= 8 else TRACE[:count]
                wall, n, lost = run_with_daq(link, names, "current", samples=400)
                lossy.append((count, payload_bytes(link, names), n, lost))
            rows["host-realtime"] = (latency(link, False), latency(link, True))

        captures, checked = drive_commands(folder, qelf)

    base_current, base_speed = cost_rows[0][1], cost_rows[0][2]
    lines = [  # the samples counted are those of the run (power on)
        SECTION,
        "",
        f"{measured_by('python3 benchmarks/drive_link.py')}; {tool_version('arm-none-eabi-gcc')}; "
        f"{tool_version('qemu-system-arm')}; pyxcp {version('pyxcp')}; code: {code_version()}.",
        "",
        "The firmware of `examples/firmware` with its XCP link (link.c on csrc/src/xcp.c) for the small servo "
        "(20 kHz current loop, 2 kHz speed loop), built by `pmsm2dof firmware` (`-O2`, Cortex-M4F).",
        "",
        "### Footprint in firmware.elf (the porting stub's firmware), from the linker map",
        "",
        "| part | flash | RAM |",
        "|---|---:|---:|",
        *(f"| {OBJECTS[o]} | {f} B | {r} B |" for o, (f, r) in fp.items()),
        f"| all of the link | {sum(v[0] for v in fp.values())} B | {sum(v[1] for v in fp.values())} B |",
        "",
        "The link's RAM is mostly its buffers: the DTO queue (4096 B), the DAQ tables (1536 B), the shadow page "
        "(the largest calibration segment, the reference schedule: 776 B), the slave's state (`p2d_xcp_t`) and "
        "the byte link's receiver and frame being sent.",
        "",
        "### Instructions per control interrupt (link_isr with foc_isr; virtual drive on QEMU, 0.1 s runs)",
        "",
        "| DAQ | current loop alone: median | with the speed loop: median | slave's DAQ: current / speed interrupt |",
        "|---|---:|---:|---:|",
        *(
            f"| {name} | {c:.0f} | {s:.0f} | {c - base_current:+.0f} / {s - base_speed:+.0f} |"
            for name, c, s in cost_rows
        ),
        "",
        "Without DAQ the link costs its clock, the idle events and, at a speed sample, the commit check, the "
        "watchdog, the guard and the schedule's reference (in double: soft-float on the M4F).",
        "",
        "### Throughput with no lost sample (the virtual drive waits for the link)",
        "",
        "| drive | DAQ | samples | lost | payload kB/s (wall) | drive time / wall time |",
        "|---|---|---:|---:|---:|---:|",
        *(f"| {k} | {n} | {s} | {lo} | {kb:.1f} | {r:.2f} |" for k, n, s, lo, kb, r in throughput),
        "",
        "On QEMU the link sets the pace: its UART model sends one byte per write to the pty or socket and hands "
        "the firmware one received byte per poll, so the drive's time runs at a few percent of the wall's while a "
        "DAQ list streams (0.2 to 0.3 without DAQ: the virtual motor's soft-float physics). The PC's drive runs "
        "its 0.1 s faster than the master's 20 ms polls resolve: its rate here is the run's, not the link's.",
        "",
        "The PC's drive on the wall clock cannot wait: DAQ at the current rate (20 kHz) over a run of 0.2 s (4000 "
        "samples):",
        "",
        "| signals | payload per sample | samples | lost |",
        "|---:|---:|---:|---:|",
        *(f"| {c} | {b} B | {n} | {lo} |" for c, b, n, lo in lossy),
        "",
        "### Latency (medians of 20, wall clock)",
        "",
        "| drive | calibration write idle | GET_STATUS idle | calibration write running | GET_STATUS running |",
        "|---|---:|---:|---:|---:|",
        *(
            f"| {k} | {w0:.2f} ms | {p0:.2f} ms | {w1:.2f} ms | {p1:.2f} ms |"
            for k, ((w0, p0), (w1, p1)) in rows.items()
        ),
        "",
        "A calibration write is answered after the firmware's next speed sample committed it (0.5 ms of the "
        "drive's time here). QEMU's UART hands the firmware one received byte per poll of its background loop "
        "(one per control period while the virtual motor's physics runs); its transmitter is not paced.",
        "",
        "### pmsm2dof drive: capture to a file, checked set",
        "",
        "`drive capture` on the PC's drive on the wall clock, at the current event (20 kHz) for 1 s of the drive's "
        "time (the samples/s are those of the wall time the whole capture took, set-up and stop included); the "
        "writes of the same samples to each format:",
        "",
        "| signals | samples | lost | samples/s (wall) | CSV | Parquet | MDF4 |",
        "|---:|---:|---:|---:|---:|---:|---:|",
        *(
            f"| {c} | {n} | {lo} | {rate:.0f} | "
            + " | ".join(f"{t * 1e3:.0f} ms, {b / 1e3:.0f} kB" for t, b in w)
            + " |"
            for c, n, lo, rate, w in captures
        ),
        "",
        "`drive set speed_controller.alpha_radps=...` (medians of 20): the checked write reads the controller's "
        "configuration back (15 fields), validates it with the C library's init, writes in one DOWNLOAD and "
        "reads the value back; the bare write is one SET_MTA + DOWNLOAD.",
        "",
        "| drive | checked set | bare write | the command (new process) |",
        "|---|---:|---:|---:|",
        *(
            f"| {k} | {a * 1e3:.2f} ms | {b * 1e3:.2f} ms | " + (f"{c:.2f} s |" if c else "- |")
            for k, (a, b, c) in checked.items()
        ),
        "",
        "The command's time is Python's start and the imports (pyxcp, numpy, the extension) far more than the link.",
    ]
    write_section(SECTION, "\n".join(lines))


def drive_commands(folder, qelf):
    """`drive capture` throughput and the file writes; `drive set` latency (checked, bare, whole command)."""
    import os

    from pmsm2dof.drive.session import capture, open_link, plan_capture, write_capture

    captures = []
    checked = {}
    a2l = folder / "virtual_drive_host.a2l"
    with serve_host(folder / "virtual_drive_host", realtime=True) as url, tempfile.TemporaryDirectory() as tmp:
        with open_link(url, a2l) as link:
            for count in (2, 8, 24):
                names = TRACE[:count] if count > 8 else (FLOATS + TRACE)[:count]
                start = time.perf_counter()
                cap = capture(link, plan_capture(link, names, "current", 1.0, Path(tmp) / "c.csv", force=True))
                wall = time.perf_counter() - start
                writes = []
                for suffix in (".csv", ".parquet", ".mf4"):
                    path = Path(tmp) / f"c{suffix}"
                    t0 = time.perf_counter()
                    write_capture(link, cap, path)
                    writes.append((time.perf_counter() - t0, path.stat().st_size))
                n = len(cap.timestamps)
                captures.append((count, n, cap.dtos_lost, n / wall, writes))
            checked["host (wall clock)"] = set_latency(link)
        # a new master once this one has gone (the drive takes one at a time)
        checked["host (wall clock)"] += (cli_latency(url, a2l, os.environ),)
    with serve_qemu(qelf, serial="tcp") as url, open_link(url, folder / "virtual_drive.a2l") as link:
        checked["qemu-tcp"] = set_latency(link) + (None,)
    return captures, checked


def set_latency(link):
    from pmsm2dof.drive.session import set_values

    alpha = link.read("link_speed_config.alpha_radps")
    checked, bare = [], []
    for i in range(20):
        t0 = time.perf_counter()
        set_values(link, [f"speed_controller.alpha_radps={alpha + 1 + i % 2}"])
        checked.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        link.write({"link_speed_config.alpha_radps": alpha + i % 2})
        bare.append(time.perf_counter() - t0)
    link.write({"link_speed_config.alpha_radps": alpha})
    return statistics.median(checked), statistics.median(bare)


def cli_latency(url, a2l, env):
    walls = []
    for i in range(3):
        t0 = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "pmsm2dof", "drive", "set", f"speed_controller.alpha_radps={150 + i}", "--link",
             url, "--a2l", str(a2l)],
            capture_output=True, text=True, env={**env, "PYTHONPATH": str(ROOT / "src")},
        )  # fmt: skip
        walls.append(time.perf_counter() - t0)
        if done.returncode != 0:
            raise RuntimeError(f"pmsm2dof drive set failed: {done.stderr}")
    return statistics.median(walls)


if __name__ == "__main__":
    main()
