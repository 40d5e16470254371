"""Start the firmware's virtual drive with its XCP link: on the PC (TCP) or on QEMU (UART on a pty or TCP).

Both are the same sources (examples/firmware: foc.c, link.c, board_virtual.c) built by
:func:`pmsm2dof.studies.firmware.build_firmware`: ``virtual_drive_host`` for the PC,
``virtual_drive.elf`` for the Cortex-M4F of QEMU -M mps2-an386. Started with ``link=1`` they idle
until a master starts a run. The processes end with the context: the PC's drive when its standard
input closes, QEMU when it is terminated.
"""

import contextlib
import os
import re
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from ..errors import ConfigError, ToolError

#: QEMU for the virtual drive: the MPS2 AN386 board (Cortex-M4F), no monitor, and instruction counting
#: (128 ns of QEMU's clock per instruction: the firmware counts instructions with SysTick) with WFI jumping
#: to the next interrupt (sleep=off: see examples/firmware/virtual_target_mps2.c on time and the link).
QEMU_MACHINE = ("qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none", "-icount", "shift=7,sleep=off")

#: Longest wait for a drive to come up [s].
START_TIMEOUT_S = 30.0


def _arguments(timeout_ms: int, extra: dict[str, int]) -> list[str]:
    if isinstance(timeout_ms, bool) or not isinstance(timeout_ms, int) or not 0 <= timeout_ms <= 3_600_000:
        raise ConfigError("timeout_ms", timeout_ms, "an integer in [0, 3600000] ms (0: no link watchdog)")
    return ["link=1", f"timeout_ms={timeout_ms}", *(f"{k}={v}" for k, v in extra.items())]


@contextlib.contextmanager
def serve_host(program: Path | str, *, realtime: bool = True, timeout_ms: int = 200, port: int = 0,
               **extra: int) -> Iterator[str]:  # fmt: skip
    """Run the PC's virtual drive; yields its link URL ``socket://127.0.0.1:PORT``.

    Parameters
    ----------
    program : path
        ``virtual_drive_host`` of a firmware build.
    realtime : bool
        The control interrupt on the wall clock; False: as fast as the link and the master allow.
    timeout_ms : int
        The link watchdog's timeout, of the drive's time [ms]; 0: off.
    port : int
        TCP port on 127.0.0.1 (0: a free one).
    extra : int
        Further arguments of the virtual board (``ramp_radps_per_s``, ``hold_ms``).
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigError("port", port, "an integer in [0, 65535] (0: a free port)")
    args = _arguments(timeout_ms, {"realtime": int(realtime), "port": port, **extra})
    with tempfile.TemporaryDirectory(prefix="pmsm2dof-drive-") as tmp:
        process = subprocess.Popen(
            [str(Path(program).resolve())],
            cwd=tmp,
            env={**os.environ, "P2D_VIRTUAL_DRIVE_ARGS": " ".join(args)},
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            line = process.stdout.readline() if process.stdout else ""
            if not line.startswith("port "):
                err = process.stderr.read() if process.stderr else ""
                raise ToolError(f"the virtual drive did not start: {line.strip()} {err.strip()}")
            yield f"socket://127.0.0.1:{int(line.split()[1])}"
        finally:
            _end(process)


def _end(process: "subprocess.Popen[str]") -> None:
    """End a drive started here: its stdin closed (the PC's drive exits), then terminate, then kill."""
    if process.stdin:
        process.stdin.close()
    try:
        process.wait(timeout=2)
    except subprocess.TimeoutExpired:
        process.terminate()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@contextlib.contextmanager
def serve_qemu(
    elf: Path | str, *, serial: str = "pty", timeout_ms: int = 200, folder: Path | str | None = None, **extra: int
) -> Iterator[str]:
    """Run the virtual drive on QEMU; yields its link URL: the pty's device, or ``socket://127.0.0.1:PORT``.

    Parameters
    ----------
    elf : path
        ``virtual_drive.elf`` of a firmware build.
    serial : str
        ``"pty"`` (QEMU's UART0 on a pseudo-terminal: XCP on SxI) or ``"tcp"`` (on a TCP port of
        127.0.0.1 that QEMU listens on: the same framing, XCP on TCP for the master).
    folder : path, optional
        QEMU's working folder, where the firmware writes its files (``cost.bin`` with ``cost=1``);
        default: a temporary one.
    extra : int
        Further arguments of the virtual board (``ramp_radps_per_s``, ``hold_ms``, ``cost``).
    """
    if serial not in ("pty", "tcp"):
        raise ConfigError("serial", serial, "pty or tcp")
    port = _free_port() if serial == "tcp" else 0
    # nodelay: every byte the UART sends leaves at once (Nagle's algorithm would hold a response ~40 ms)
    device = "pty" if serial == "pty" else f"tcp:127.0.0.1:{port},server=on,wait=off,nodelay=on"
    args = ",".join(f"arg={a}" for a in ["virtual_drive", *_arguments(timeout_ms, extra)])
    with tempfile.TemporaryDirectory(prefix="pmsm2dof-qemu-") as scratch:
        tmp = str(folder) if folder is not None else scratch
        process = subprocess.Popen(
            [*QEMU_MACHINE, "-serial", device, "-semihosting-config", f"enable=on,target=native,{args}",
             "-kernel", str(Path(elf).resolve())],
            cwd=tmp, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
        try:
            if serial == "pty":
                line = process.stdout.readline() if process.stdout else ""
                m = re.search(r"(/dev/pts/\d+)", line)
                if m is None:
                    raise ToolError(f"QEMU gave no pty: {line.strip()}")
                url = m.group(1)
            else:
                url = f"socket://127.0.0.1:{port}"
                end = time.monotonic() + START_TIMEOUT_S
                while True:
                    try:
                        socket.create_connection(("127.0.0.1", port), timeout=1).close()
                        break
                    except OSError:
                        if time.monotonic() > end or process.poll() is not None:
                            raise ToolError("QEMU's serial port did not open") from None
                        time.sleep(0.05)
            yield url
        finally:
            process.terminate()
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
