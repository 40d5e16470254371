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
import struct
import subprocess
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import ConfigError, ToolError

#: QEMU for the virtual drive: the MPS2 AN386 board (Cortex-M4F), no monitor, and instruction counting
#: (128 ns of QEMU's clock per instruction: the firmware counts instructions with SysTick) with WFI jumping
#: to the next interrupt (sleep=off: see examples/firmware/virtual_target_mps2.c on time and the link).
QEMU_MACHINE = ("qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none", "-icount", "shift=7,sleep=off")

#: Bits of a CAN frame beside its data (11-bit identifier, control, CRC, stuffing, interframe space), about.
CAN_FRAME_BITS = 64

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


@contextlib.contextmanager
def serve_can(program: Path | str, can_link: str, *, realtime: bool = True, timeout_ms: int = 200,
              **extra: int) -> Iterator[str]:  # fmt: skip
    """Run the PC's virtual drive on a CAN bus of python-can; yields the link URL ``can://...`` for the master.

    The drive runs with packets of a CAN frame (``max_packet=8``, 64 with ``fd=1``) and a bridge here
    is its CAN controller: each frame on the bus with the master's identifier goes to the drive as one
    packet, each packet of the drive goes on the bus as one frame with the slave's identifier, padded
    to a CAN (FD) data length by the C library's ``p2d_xcp_can_pad``, at the bus's pace (the URL's
    bitrate, :data:`CAN_FRAME_BITS` and 8 bits a data byte a frame; the drive waits while it is
    busy, as for TCP: nothing is lost, and a master on a bus that drops datagrams keeps up). Between
    processes the bus is python-can's ``udp_multicast`` interface
    (``can://udp_multicast/239.74.163.2?fd=1``: no root, no kernel module); a socketcan ``vcan``
    works the same where one exists.
    """
    import can

    from ..core.bindings import ffi, lib
    from .transport import can_url

    c = can_url(can_link)
    fd = bool(c["fd"])
    extended = [bool(c[k] & 0x80000000) for k in ("master", "slave")]
    master_id, slave_id = (c[k] & 0x1FFFFFFF for k in ("master", "slave"))
    with serve_host(program, realtime=realtime, timeout_ms=timeout_ms, max_packet=64 if fd else 8, **extra) as url:
        host, _, port = url.partition("://")[2].rpartition(":")
        drive = socket.create_connection((host, int(port)))
        drive.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        bus: Any = can.Bus(interface=c["interface"], channel=c["channel"], fd=fd, bitrate=c["bitrate"])
        done = threading.Event()

        def to_drive() -> None:
            counter = 0
            while not done.is_set():
                msg = bus.recv(0.05)
                if msg is None or msg.arbitration_id != master_id or msg.is_extended_id != extended[0]:
                    continue
                # XCP on SxI/TCP: LEN CTR (little endian) and the packet
                drive.sendall(struct.pack("<HH", len(msg.data), counter & 0xFFFF) + bytes(msg.data))
                counter += 1

        def to_bus() -> None:
            frame = ffi.new("uint8_t[64]")
            data = b""
            free_at = time.monotonic()  # when the bus takes the next frame
            while not done.is_set():
                try:
                    chunk = drive.recv(65536)
                except OSError:
                    return
                if not chunk:
                    return
                data += chunk
                while len(data) >= 4 and len(data) >= 4 + struct.unpack_from("<H", data)[0]:
                    n = struct.unpack_from("<H", data)[0]
                    packet, data = data[4 : 4 + n], data[4 + n :]
                    ffi.memmove(frame, packet, n)
                    length = lib.p2d_xcp_can_pad(frame, n, 0, 0)
                    free_at = max(free_at, time.monotonic()) + (CAN_FRAME_BITS + 8 * length) / c["bitrate"]
                    if free_at - time.monotonic() > 2e-3:
                        time.sleep(free_at - time.monotonic())
                    bus.send(can.Message(arbitration_id=slave_id, is_extended_id=extended[1], is_fd=fd,
                                         data=bytes(ffi.buffer(frame, length))))  # fmt: skip

        threads = [threading.Thread(target=f, daemon=True) for f in (to_drive, to_bus)]
        for t in threads:
            t.start()
        try:
            yield can_link
        finally:
            done.set()
            drive.shutdown(socket.SHUT_RDWR)
            drive.close()
            for t in threads:
                t.join(timeout=5)
            bus.shutdown()


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
