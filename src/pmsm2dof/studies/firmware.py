"""The firmware on the emulated MCU: built for a scenario, run closed loop on QEMU, held against the engine.

``examples/firmware`` is a FOC firmware (``foc.c``) over a board interface (``board.h``). With the
virtual board (``board_virtual.c``) its motor, inverter, sensors and load are the engine's plant
(``csrc/sim/plant.c``, compiled for the Cortex-M4F in double precision, soft-float), driven by the
scenario's reference and load schedules. :func:`build_firmware` writes the two headers of a
scenario (``p2d_config.h``, :func:`pmsm2dof.studies.configuration.configuration`; and
``p2d_virtual_drive.h``, :func:`~pmsm2dof.studies.virtual_drive.virtual_drive_header`) and cross-builds it with CMake;
:func:`run_firmware` runs it on QEMU (``-M mps2-an386``, ``-icount``: deterministic, the control
interrupt every Ts_current of virtual time), reads its trace into the engine's log format,
simulates the same scenario with the engine and compares the two, and counts the instructions of
each control interrupt by tracing a short run (QEMU's ``-d exec`` log of every executed instruction,
as ``benchmarks/footprint.py`` does).

The firmware's trace and the engine's differ by what the firmware does that the engine does not:
it reads the phase currents and turns them to dq with float32 Clarke and Park transforms at the
angle it reads (``sinf``, ``cosf`` of newlib), and writes duty cycles that the virtual inverter
turns back into the dq voltage (in double, with newlib's ``sin``, ``cos``); the engine hands its
controllers the dq currents and takes their dq voltages. The controllers are the same float32
code, the plant the same double code (Arm's soft-float double is IEEE 754 correctly rounded, as
the PC's). See :func:`compare` for the measure.
"""

import contextlib
import dataclasses
import math
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core import LOG_COLUMNS
from ..drive.a2l import write_firmware_a2l
from ..drive.link import Link
from ..drive.serve import QEMU_MACHINE, serve_host
from ..errors import ConfigError, SimulationError, ToolError
from ..outputs import atomic_write
from ..sim.scenario import Scenario, load_scenario
from ..sim.simulate import RPM_PER_RADPS, Result, Simulation, log_signals
from .configuration import configuration
from .virtual_drive import CORE_CLOCK_HZ, CYCLES_PER_INSTRUCTION, virtual_drive_header

#: Debian package of each program the commands need.
DEBIAN_PACKAGES = {
    "cmake": "cmake",
    "arm-none-eabi-gcc": "gcc-arm-none-eabi libnewlib-arm-none-eabi",
    "qemu-system-arm": "qemu-system-arm",
}


#: QEMU for a run of the virtual drive without a link: the machine of :data:`pmsm2dof.drive.serve.QEMU_MACHINE`
#: with no serial port (semihosting writes the trace to the working folder).
QEMU = (*QEMU_MACHINE, "-serial", "none")

#: The link's UART rate the A2L file names for XCP on SxI (QEMU does not pace the bytes) [bit/s].
UART_BAUD = 115200

#: The TCP port the A2L files name for XCP on TCP/IP (a master connects where the drive listens).
TCP_PORT = 5555


def require_tool(program: str) -> str:
    """The path of ``program``, or ToolError naming the Debian package that installs it."""
    path = shutil.which(program)
    if path is None:
        raise ToolError(
            f"{program} is not installed: install the Debian package {DEBIAN_PACKAGES[program]} "
            "(sudo apt-get install ...; scripts/install.sh installs every package pmsm2dof uses)"
        )
    return path


#: Most control interrupts of one run on QEMU (about an hour of the machine's time).
PERIODS_MAX = 10**7

#: Wall-clock time allowed per control interrupt on QEMU, on top of a fixed minute [s] (runs take ~0.3 ms).
WALL_S_PER_PERIOD = 5e-3

#: Bit of a cost word that marks an interrupt that ran the speed loop (board_virtual.c).
SPEED_SAMPLE_BIT = 0x80000000

#: The relative agreement the firmware's trace must reach with the engine's (speed and currents).
AGREEMENT = 1e-4


def sources_root() -> Path:
    """The folder holding ``examples/firmware`` and ``csrc`` (the checkout pmsm2dof runs from).

    Raises
    ------
    ToolError
        pmsm2dof runs from an installed wheel, which carries no C sources.
    """
    root = Path(__file__).resolve().parents[3]
    if not (root / "examples" / "firmware" / "CMakeLists.txt").is_file() or not (root / "csrc" / "src").is_dir():
        raise ToolError(
            f"the firmware's sources (examples/firmware, csrc) are not beside this pmsm2dof ({root}): "
            "run pmsm2dof from a checkout of its repository (pip install -e .)"
        )
    return root


def _run(cmd: Sequence[str | Path], what: str, timeout_s: float, **kwargs: Any) -> "subprocess.CompletedProcess[str]":
    """Run an external program; ToolError with the end of its output when it fails."""
    try:
        done = subprocess.run(
            [str(c) for c in cmd], capture_output=True, text=True, timeout=timeout_s, stdin=subprocess.DEVNULL, **kwargs
        )
    except subprocess.TimeoutExpired:
        raise ToolError(f"{what} did not end within {timeout_s:g} s") from None
    if done.returncode != 0:
        tail = " ".join((done.stdout + done.stderr).split()[-60:])
        raise ToolError(f"{what} failed (exit status {done.returncode}): {tail}")
    return done


@dataclasses.dataclass(frozen=True)
class FirmwareBuild:
    """The firmware built for a scenario: the folder ``pmsm2dof firmware`` writes.

    Attributes
    ----------
    folder : Path
        Holds ``scenario.toml``, ``p2d_config.h``, ``p2d_virtual_drive.h``, ``virtual_drive.elf`` (foc.c on the
        virtual board, for QEMU), ``firmware.elf`` (foc.c on the porting stub) and their ``.map`` files,
        ``virtual_drive_host`` (the virtual drive for the PC, its link on TCP), and the A2L file of each
        (``virtual_drive.a2l``, ``firmware.a2l``, ``virtual_drive_host.a2l``).
    sizes : dict
        ``{elf name: {"text": bytes, "data": bytes, "bss": bytes}}`` (arm-none-eabi-size) of the Cortex-M4F's ELFs.
    """

    folder: Path
    sizes: dict[str, dict[str, int]]


def build_firmware(
    scenario: Scenario, out: Path | str, *, source: str = "", mcu: bool = True, force: bool = False
) -> FirmwareBuild:
    """Write the scenario's headers and build the firmware into the folder ``out`` (all or nothing).

    ``out`` is an output folder of the kind ``"firmware"`` (:func:`pmsm2dof.outputs.staged_dir`):
    new, empty, or holding only an earlier build, which is replaced as a whole; ``force`` writes
    beside other files and keeps them.

    Parameters
    ----------
    scenario : Scenario
        The scenario of the controllers (``p2d_config.h``) and of the virtual board.
    out : path
        The folder written (:class:`FirmwareBuild`).
    source : str
        Where the scenario came from, for the header's record.
    mcu : bool
        Cross-build for the Cortex-M4F too (``virtual_drive.elf``, ``firmware.elf``); False: the PC's
        virtual drive alone (``virtual_drive_host``: CMake and the host's C compiler suffice).
    force : bool
        Write into an output folder that holds other files (they are kept).

    Raises
    ------
    ConfigError
        A value the controllers or the engine reject, or what the virtual board does not model;
        ``out`` holds other files (without ``force``) or cannot be written.
    ToolError
        CMake or the cross toolchain is missing (naming the Debian package), or the build fails.
    """
    from ..outputs import check_out, staged_dir

    check_out(out, "firmware", force)
    config = configuration(scenario, source=source)
    board = virtual_drive_header(config)
    root = sources_root()
    require_tool("cmake")
    if mcu:
        require_tool("arm-none-eabi-gcc")
        specs = _run(["arm-none-eabi-gcc", "-print-file-name=nano.specs"], "arm-none-eabi-gcc", 60).stdout.strip()
        if not Path(specs).is_file():
            raise ToolError(
                "newlib for arm-none-eabi is not installed: install the Debian package libnewlib-arm-none-eabi "
                "(scripts/install.sh installs every package pmsm2dof uses)"
            )
    firmware = root / "examples" / "firmware"
    sizes = {}
    with staged_dir(out, "firmware", force) as tmp:
        atomic_write(tmp / "scenario.toml", scenario.to_toml())
        config.write_header(tmp / "p2d_config.h")
        atomic_write(tmp / "p2d_virtual_drive.h", board)
        if mcu:
            build = tmp / "build"
            toolchain = f"-DCMAKE_TOOLCHAIN_FILE={root / 'csrc' / 'cmake' / 'arm-none-eabi-cortex-m4f.cmake'}"
            _run(["cmake", "-S", firmware, "-B", build, toolchain, f"-DP2D_CONFIG_DIR={tmp}"], "cmake (configure)", 600)
            _run(["cmake", "--build", build, "-j2"], "cmake --build", 1200)
            for name in ("virtual_drive", "firmware"):
                for suffix in (".elf", ".map"):
                    shutil.copy2(build / f"{name}{suffix}", tmp / f"{name}{suffix}")
                text, data, bss = (
                    _run(["arm-none-eabi-size", tmp / f"{name}.elf"], "arm-none-eabi-size", 60)
                    .stdout.split("\n")[1]
                    .split()[:3]
                )
                sizes[f"{name}.elf"] = {"text": int(text), "data": int(data), "bss": int(bss)}
            shutil.rmtree(build)
        # the same sources for the PC: the virtual drive with its link on TCP
        host = tmp / "build-host"
        _run(["cmake", "-S", firmware, "-B", host, f"-DP2D_CONFIG_DIR={tmp}"], "cmake (configure, PC)", 600)
        _run(["cmake", "--build", host, "-j2", "--target", "virtual_drive"], "cmake --build (PC)", 1200)
        shutil.copy2(host / "virtual_drive", tmp / "virtual_drive_host")
        shutil.rmtree(host)
        sources = [
            *sorted(firmware.glob("*.h")),
            firmware / "board_virtual.c",
            *sorted((root / "csrc" / "include" / "pmsm2dof").glob("*.h")),
        ]
        builds: list[tuple[str, str, bool, int | None]] = [("virtual_drive_host", "virtual_drive_host.a2l", True, None)]
        if mcu:
            builds += [
                ("virtual_drive.elf", "virtual_drive.a2l", True, UART_BAUD),
                ("firmware.elf", "firmware.a2l", False, UART_BAUD),
            ]
        for elf, a2l, virtual, baud in builds:
            write_firmware_a2l(
                tmp / elf,
                tmp / a2l,
                sources=sources,
                virtual=virtual,
                Ts_current_s=scenario.current_loop.Ts_s,
                current_per_speed=config.current_per_speed,
                tcp_port=TCP_PORT,
                sxi_baud=baud,
            )
    return FirmwareBuild(folder=Path(out), sizes=sizes)


@contextlib.contextmanager
def serve_scenario(
    scenario: Scenario,
    *,
    port: int = 0,
    realtime: bool = True,
    timeout_ms: int = 200,
    out: Path | str | None = None,
    force: bool = False,
) -> Iterator[tuple[str, Path]]:
    """Build the PC's virtual drive of a scenario and run it; yields its link URL and its folder.

    The engine's plant of the scenario under the firmware (foc.c, link.c), its XCP slave on TCP on
    127.0.0.1:``port`` (0: a free port), on the wall clock (``realtime``) or as fast as the link
    allows; ``timeout_ms``: the link watchdog [ms of the drive's time], 0: off
    (:func:`pmsm2dof.drive.serve.serve_host`). The folder holds its A2L file
    ``virtual_drive_host.a2l`` for CANape, INCA, pyxcp or ``pmsm2dof drive``: ``out`` (an output
    folder of the kind ``"firmware"``, kept; ``force`` as :func:`build_firmware`), or by default a
    temporary one removed at the end.
    """
    with tempfile.TemporaryDirectory(prefix="pmsm2dof-serve-") as tmp:
        folder = build_firmware(
            scenario, out if out is not None else Path(tmp) / "drive", mcu=False, force=force
        ).folder
        with serve_host(folder / "virtual_drive_host", realtime=realtime, timeout_ms=timeout_ms, port=port) as url:
            yield url, folder


@dataclasses.dataclass(frozen=True, eq=False)
class FirmwareRun:
    """One run of the firmware on QEMU and the engine's simulation of the same scenario.

    Attributes
    ----------
    scenario : Scenario
        The scenario the firmware was built for.
    firmware : Result
        The firmware's trace in the engine's format (:class:`pmsm2dof.sim.simulate.Result`).
    engine : Result
        The engine's simulation of the scenario over the same samples.
    instructions : numpy.ndarray
        The instructions of each control interrupt (link_isr and foc_isr), callees included (uint32).
    speed_sample : numpy.ndarray
        Whether each interrupt ran the speed loop (bool).
    report : tuple of str
        The firmware's diagnostic lines.
    wall_time_s : float
        Wall-clock time of the QEMU run [s].
    """

    scenario: Scenario
    firmware: Result
    engine: Result
    instructions: npt.NDArray[np.uint32]
    speed_sample: npt.NDArray[np.bool_]
    report: tuple[str, ...]
    wall_time_s: float

    def comparison(self) -> dict[str, Any]:
        """:func:`compare` of the firmware's trace with the engine's."""
        return compare(self.firmware, self.engine)

    def cost(self) -> dict[str, Any]:
        """:func:`interrupt_cost` of the run."""
        Ts_s = self.scenario.current_loop.Ts_s
        return interrupt_cost(self.instructions, self.speed_sample, Ts_s)


def read_trace(data: bytes) -> dict[str, npt.NDArray[np.float64]]:
    """The columns of a virtual board's trace (``pmsm2dof-trace 1 <n> <names> ...``, then rows of doubles)."""
    end = data.find(b"\n")
    head = data[:end].decode("ascii", "replace").split() if end > 0 else []
    if len(head) < 3 or head[:2] != ["pmsm2dof-trace", "1"] or not head[2].isdigit() or len(head) != 3 + int(head[2]):
        raise SimulationError("the firmware's trace has no valid header line (pmsm2dof-trace 1 <columns> <names>)")
    names = head[3:]
    body = data[end + 1 :]
    if len(body) % (8 * len(names)) != 0:
        raise SimulationError(f"the firmware's trace ends inside a row ({len(body)} bytes of {len(names)} doubles)")
    rows = np.frombuffer(body, dtype="<f8").reshape(-1, len(names))
    return {name: rows[:, i].copy() for i, name in enumerate(names)}


def run_firmware(folder: Path | str, *, samples: int | None = None) -> FirmwareRun:
    """Run the virtual drive of ``folder`` (:func:`build_firmware`) on QEMU and the engine on its scenario.

    Parameters
    ----------
    folder : path
        A folder :func:`build_firmware` wrote.
    samples : int, optional
        Speed samples to run (default: the scenario's, to ``simulation.t_end_s``); the engine runs as many.

    Raises
    ------
    ConfigError
        ``folder`` is not a built firmware, or ``samples`` is out of range.
    ToolError
        QEMU is missing (naming the Debian package) or the firmware failed (its diagnostic in the message).
    SimulationError
        The engine stopped on the scenario.
    """
    folder = Path(folder)
    elf = folder / "virtual_drive.elf"
    if not elf.is_file() or not (folder / "scenario.toml").is_file():
        raise ConfigError("DIR", str(folder), "a folder written by `pmsm2dof firmware SCENARIO --out DIR`")
    scenario = load_scenario(str(folder / "scenario.toml"))
    ratio = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    n_samples = math.floor(scenario.simulation.t_end_s / scenario.speed_controller.Ts_s + 1e-9) + 1
    if samples is not None:
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= n_samples:
            raise ConfigError("samples", samples, f"an integer in [1, {n_samples}] (the scenario's speed samples)")
        n_samples = samples
    if n_samples * ratio > PERIODS_MAX:
        raise ConfigError(
            "simulation.t_end_s",
            scenario.simulation.t_end_s,
            f"at most {PERIODS_MAX:g} current periods on QEMU "
            f"({PERIODS_MAX / ratio * scenario.speed_controller.Ts_s:g} s)",
        )
    require_tool("qemu-system-arm")
    timeout_s = 60.0 + WALL_S_PER_PERIOD * n_samples * ratio
    with tempfile.TemporaryDirectory(prefix="pmsm2dof-qemu-") as tmp:
        start = time.perf_counter()
        args = f"enable=on,target=native,arg=virtual_drive,arg=samples={n_samples}"
        try:
            done = subprocess.run(
                [*QEMU, "-semihosting-config", args, "-kernel", str(elf.resolve())],
                cwd=tmp,
                capture_output=True,
                text=True,
                timeout=timeout_s,
                stdin=subprocess.DEVNULL,
            )
        except subprocess.TimeoutExpired:
            raise ToolError(f"the virtual drive did not end within {timeout_s:g} s on QEMU") from None
        wall_s = time.perf_counter() - start
        # semihosting output arrives on stderr
        report = tuple(line for line in done.stderr.splitlines() if line.strip())
        if done.returncode != 0:
            stopped = [line for line in report if line.startswith("virtual drive: stopped:")]
            if stopped:
                # the engine's stops: the scenario's physics, not the tools
                raise SimulationError(
                    f"the firmware's run of {scenario.name!r} {stopped[-1][len('virtual drive: ') :]}"
                )
            raise ToolError(
                f"the virtual drive failed on QEMU (exit status {done.returncode}): " + " ".join(report[-3:])
            )
        columns = read_trace((Path(tmp) / "trace.bin").read_bytes())
        words = np.fromfile(Path(tmp) / "cost.bin", dtype="<u4")
    if list(columns) != list(LOG_COLUMNS):
        raise SimulationError(
            f"the firmware's trace has the columns {list(columns)}, not the engine's {list(LOG_COLUMNS)}"
        )
    firmware = Result(scenario=scenario, wall_time_s=wall_s, **log_signals(np.array(list(columns.values()))))
    # the engine over the same speed samples
    sim = Simulation(scenario)
    start = time.perf_counter()
    sim.advance(n_samples)
    engine = sim.result(scenario, time.perf_counter() - start)
    return FirmwareRun(
        scenario=scenario,
        firmware=firmware,
        engine=engine,
        instructions=(words & ~np.uint32(SPEED_SAMPLE_BIT)).astype(np.uint32),
        speed_sample=(words & np.uint32(SPEED_SAMPLE_BIT)) != 0,
        report=report,
        wall_time_s=wall_s,
    )


def compare(firmware: Result, engine: Result) -> dict[str, Any]:
    """How far the firmware's trace is from the engine's, on the speed and on the currents.

    For each signal: the largest difference, the share of samples where both are equal to the bit
    and the first time they differ. The speed (``w_m_radps``) is judged against its step, the
    larger of the excursions (largest minus smallest) of the engine's speed and speed reference;
    the currents (``id_A``, ``iq_A``) against theirs, the largest excursion of the engine's dq
    currents and their references. ``agrees`` is True when both stay within :data:`AGREEMENT` of
    their step.
    """
    if len(firmware.t_s) != len(engine.t_s) or not np.array_equal(firmware.t_s, engine.t_s):
        raise SimulationError(
            f"the firmware's trace has {len(firmware.t_s)} rows, the engine's {len(engine.t_s)}: not the same samples"
        )

    steps = {
        "speed": max(float(np.ptp(engine.w_m_radps)), float(np.ptp(engine.speed_ref_rpm)) / RPM_PER_RADPS),
        "currents": max(float(np.ptp(getattr(engine, n))) for n in ("id_A", "iq_A", "id_ref_A", "iq_ref_A")),
    }
    signals: dict[str, Any] = {}
    for name in ("w_m_radps", "id_A", "iq_A", "id_ref_A", "iq_ref_A", "torque_Nm", "ud_V", "uq_V", "x_i_Nm"):
        a, b = getattr(firmware, name), getattr(engine, name)
        if np.all(np.isnan(a)):  # a column the drive does not measure (pmsm2dof.studies.drive.NOT_MEASURED)
            signals[name] = {"max_abs_difference": None, "bit_equal_share": None, "first_difference_t_s": None}
            continue
        equal = a == b
        differ = np.flatnonzero(~equal)
        signals[name] = {
            "max_abs_difference": float(np.max(np.abs(a - b))) if len(a) else 0.0,
            "bit_equal_share": float(np.mean(equal)) if len(a) else 1.0,
            "first_difference_t_s": float(firmware.t_s[differ[0]]) if len(differ) else None,
        }
    out: dict[str, Any] = {"agreement": AGREEMENT, "signals": signals}
    agrees = True
    for group, names in (("speed", ("w_m_radps",)), ("currents", ("id_A", "iq_A"))):
        worst = max(signals[n]["max_abs_difference"] for n in names)
        ratio = worst / steps[group] if steps[group] > 0.0 else (0.0 if worst == 0.0 else math.inf)
        out[group] = {"step": steps[group], "max_abs_difference": worst, "relative_to_step": ratio}
        agrees = agrees and ratio <= AGREEMENT
    out["agrees"] = agrees
    return out


def interrupt_cost(
    instructions: npt.NDArray[np.uint32], speed_sample: npt.NDArray[np.bool_], Ts_s: float
) -> dict[str, Any]:
    """The instructions per control interrupt and the CPU load they mean.

    For the interrupts that ran the speed loop and those that did not: their number and the
    smallest, median and largest instruction count. The load of the run's mean interrupt and the
    share of the period its largest one takes, at the run's rate on the virtual core
    (:data:`~pmsm2dof.studies.virtual_drive.CORE_CLOCK_HZ`,
    :data:`~pmsm2dof.studies.virtual_drive.CYCLES_PER_INSTRUCTION`).
    """
    out: dict[str, Any] = {"core_clock_Hz": CORE_CLOCK_HZ, "cycles_per_instruction": CYCLES_PER_INSTRUCTION}
    for name, mask in (("current", ~speed_sample), ("speed", speed_sample)):
        n = instructions[mask].astype(np.int64)
        out[name] = {
            "interrupts": int(len(n)),
            "min": int(n.min()) if len(n) else None,
            "median": float(np.median(n)) if len(n) else None,
            "max": int(n.max()) if len(n) else None,
        }
    if len(instructions):
        seconds_per_instruction = CYCLES_PER_INSTRUCTION / CORE_CLOCK_HZ
        out["mean_load"] = float(np.mean(instructions)) * seconds_per_instruction / Ts_s
        out["peak_share_of_period"] = float(np.max(instructions)) * seconds_per_instruction / Ts_s
    return out


def play_scenario(
    link: Link, scenario: Scenario, *, samples: int | None = None, timeout_s: float = 600.0,
    during: Callable[[Link, dict[str, Any]], None] | None = None,
) -> Result:  # fmt: skip
    """Play a scenario's reference and load on the virtual drive over its XCP link; its trace as the engine's log.

    The drive must be a build of the scenario (:func:`build_firmware`): its plant, initial state and
    loops are the scenario's; the schedules go over the link (:meth:`pmsm2dof.drive.link.Link.play`).

    Parameters
    ----------
    link : Link
        An open link to the drive.
    scenario : Scenario
        The scenario the drive was built for.
    samples : int, optional
        Speed samples to run (default: the scenario's, to ``simulation.t_end_s``).
    timeout_s : float
        Longest run of the wall clock [s].
    during : callable, optional
        Called with the link and the drive's status at every poll of the run.

    Raises
    ------
    ConfigError
        ``samples`` out of range, or a schedule longer than the drive holds.
    SimulationError
        The run did not end as done, or the capture lost a sample.
    """
    n_samples = math.floor(scenario.simulation.t_end_s / scenario.speed_controller.Ts_s + 1e-9) + 1
    if samples is not None:
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= n_samples:
            raise ConfigError("samples", samples, f"an integer in [1, {n_samples}] (the scenario's speed samples)")
        n_samples = samples
    # the values as the engine's schedules hold them (pmsm2dof.sim.simulate._schedule)
    reference = [(e.t_s, e.speed_rpm * (1.0 / RPM_PER_RADPS), e.ramp_s) for e in scenario.reference]
    load = [(e.t_s, e.torque_Nm, e.ramp_s) for e in scenario.load]
    start = time.perf_counter()
    rows = link.play(n_samples, reference, load, LOG_COLUMNS, timeout_s=timeout_s, during=during)
    log = np.array([rows[c] for c in LOG_COLUMNS])
    return Result(scenario=scenario, wall_time_s=time.perf_counter() - start, **log_signals(log))
