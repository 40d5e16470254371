"""XCP on CAN: the link URL, the frame packing of the C library, and the PC's drive on a python-can bus.

The bus between processes is python-can's ``udp_multicast`` interface (UDP multicast on the
loopback: no root, no kernel module; socketcan's vcan needs both, and python-can's ``virtual``
interface reaches one process only). The master is pyxcp's CAN transport over python-can; the
drive is the PC's virtual drive behind :func:`pmsm2dof.drive.serve.serve_can`, its CAN controller.
Truth: python-can's own DLC tables for the packing, the scenario that built the drive for what is
read, the drive's period counter for what is captured.
"""

import os
import shutil

import numpy as np
import pytest

from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.drive.link import Link
from pmsm2dof.drive.transport import link_url
from pmsm2dof.errors import ConfigError

can = pytest.importorskip("can")
pytest.importorskip("pyxcp")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("can://udp_multicast/239.74.163.2", "can://udp_multicast/239.74.163.2?master=0x7E0&slave=0x7E1&fd=0&bitrate=500000"),
        ("can://socketcan/can0?fd=1&master=0x100&slave=0x101", "can://socketcan/can0?master=0x100&slave=0x101&fd=1&bitrate=500000"),
        ("can://pcan/PCAN_USBBUS1?bitrate=1000000&master=0x80012345", "can://pcan/PCAN_USBBUS1?master=0x80012345&slave=0x7E1&fd=0&bitrate=1000000"),
    ],
)  # fmt: skip
def test_a_can_url_is_read_in_one_form(text, expected):
    assert link_url(text) == expected


@pytest.mark.parametrize(
    ("text", "param", "words"),
    [
        ("can://nosuchbus/can0", "link", "INTERFACE one of"),
        ("can://socketcan", "link", "a channel"),
        ("can://socketcan/can0?master=0x800", "link master", "0..0x7FF"),
        ("can://socketcan/can0?slave=0x7E0", "link slave", "another identifier"),
        ("can://socketcan/can0?fd=2", "link fd", "0 or 1"),
        ("can://socketcan/can0?bitrate=fast", "link bitrate", "bit/s"),
        ("can://socketcan/can0?baud=500000", "link", "options master=, slave=, fd=, bitrate="),
    ],
)
def test_a_wrong_can_url_is_refused_naming_the_part(text, param, words):
    with pytest.raises(ConfigError) as caught:
        link_url(text)
    assert caught.value.param == param and words in str(caught.value)


def test_the_c_librarys_can_packing_agrees_with_python_can():
    """p2d_xcp_can_length/pad/dlc against python-can's len2dlc/dlc2len for every packet of 1..64 bytes."""
    frame = ffi.new("uint8_t[64]")
    for n in range(1, 65):
        want = can.util.dlc2len(can.util.len2dlc(n))
        assert lib.p2d_xcp_can_length(n, 0) == want
        assert lib.p2d_xcp_can_length(n, 8) == max(want, 8)
        assert lib.p2d_xcp_can_dlc(want) == can.util.len2dlc(want)
        ffi.memmove(frame, bytes(range(1, n + 1)) + bytes(64 - n), 64)
        assert lib.p2d_xcp_can_pad(frame, n, 0, 0xAA) == want
        assert bytes(ffi.buffer(frame, want)) == bytes(range(1, n + 1)) + b"\xaa" * (want - n)
    assert lib.p2d_xcp_can_length(0, 0) == 0 and lib.p2d_xcp_can_length(65, 0) == 0
    assert lib.p2d_xcp_can_dlc(13) == 0xFF


_MISSING = [t for t in ("cmake", "cc", "arm-none-eabi-gcc") if shutil.which(t) is None]


def group():
    """A multicast group of this process: test runs side by side on one machine do not share a bus."""
    return f"239.74.{os.getpid() >> 8 & 0xFF}.{os.getpid() & 0xFF}"


@pytest.mark.slow
@pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)")
@pytest.mark.parametrize("fd", [1, 0])
def test_the_pcs_drive_speaks_xcp_on_can(servo_firmware, fd, tmp_path):
    """On CAN FD: read, a checked write, a DAQ capture at the speed rate with no lost sample. On classic CAN
    (8-byte frames): read and write, and `drive capture` takes the drive's buffer (DAQ cannot carry a float32
    beside the PID and the timestamp in 8 bytes)."""
    from pmsm2dof.drive.serve import serve_can
    from pmsm2dof.drive.session import capture, plan_capture

    scenario, folder = servo_firmware
    url = f"can://udp_multicast/{group()}?fd={fd}"
    program = folder / "virtual_drive_host"
    with serve_can(program, url, realtime=False, timeout_ms=2000) as link_text:
        with Link(link_text, folder / "virtual_drive_host.a2l") as link:
            assert link.max_cto == (64 if fd else 8)
            alpha = link.read("link_speed_config.alpha_radps")
            assert alpha == pytest.approx(scenario.data["speed_controller"]["alpha_radps"], rel=1e-7)
            link.write({"link_speed_config.alpha_radps": 120.0})
            assert link.read("link_speed_config.alpha_radps") == 120.0
            names = ["link_status_now.periods", "foc_now.iq_A"]
            plan = plan_capture(link, names, "speed", 0.05, tmp_path / "c.csv")
            # 17 bytes at 2 kHz: more than half of CAN's stated 30 kB/s, and classic CAN has no room for DAQ
            assert plan.way == "buffer"
            if fd:
                plan = plan_capture(link, names, "speed", 0.05, tmp_path / "c.csv", way="daq")
            cap = capture(link, plan)
    periods = cap.signals["link_status_now.periods"].astype(np.int64)
    assert cap.dtos_lost == 0 and len(periods) == 101 and np.all(np.diff(periods) == 10)


@pytest.mark.slow
@pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)")
def test_a_can_interface_that_cannot_open_is_one_line(servo_firmware, capsys):
    """A CAN channel this machine does not have (no socketcan here, or no such device): exit status 2, one line
    on stderr naming the link, no traceback."""
    from pmsm2dof.ui.cli import main

    _, folder = servo_firmware
    code = main(
        ["drive", "info", "--link", "can://socketcan/p2dnone0", "--a2l", str(folder / "virtual_drive_host.a2l")]
    )
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "can://socketcan/p2dnone0" in err and "Traceback" not in err
