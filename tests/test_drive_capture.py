"""The drive's triggered capture buffer (examples/firmware/capture.h) and the capture's choice of DAQ or buffer.

Truth from outside the buffer: the engine's current-rate log of the same run (simulation.log_rate =
"current", the same plant and controllers simulated here), a DAQ capture of the same run streamed
at the same time (the PC's drive waits for the link, so DAQ loses nothing there), and the drive's
period counter captured beside the signals (continuous, the trigger where asked).
"""

import shutil

import numpy as np
import pytest

from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_host, serve_qemu
from pmsm2dof.drive.session import plan_capture
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.simulate import RPM_PER_RADPS, Simulation
from pmsm2dof.ui.cli import main

pytest.importorskip("pyxcp")
_MISSING = [t for t in ("cmake", "cc", "arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]

CURRENTS = ["foc_now.id_A", "foc_now.iq_A", "foc_now.ud_ref_V", "foc_now.uq_ref_V"]


def schedules(scenario):
    reference = [(e.t_s, e.speed_rpm / RPM_PER_RADPS, e.ramp_s) for e in scenario.reference]
    return reference, [(e.t_s, e.torque_Nm, e.ramp_s) for e in scenario.load]


def drive(folder, kind="host"):
    """The PC's drive as fast as the link allows, or QEMU's with its UART on a pty (XCP on SxI); and its A2L."""
    if kind == "host":
        return serve_host(folder / "virtual_drive_host", realtime=False, timeout_ms=2000)
    return serve_qemu(folder / "virtual_drive.elf", serial="pty", timeout_ms=2000)


def a2l(folder, kind="host"):
    return folder / ("virtual_drive_host.a2l" if kind == "host" else "virtual_drive.a2l")


@pytest.mark.parametrize("kind", ["host", "qemu-pty"])
def test_a_buffered_capture_of_a_run_equals_the_engines_current_rate_log(servo_firmware, kind):
    """The currents of a run's first 0.05 s (1000 control periods, the load step at 0.06 s not yet) recorded at
    every control interrupt from the run's start: the engine's current-rate log row by row, to float32 round-off."""
    scenario, folder = servo_firmware
    names = ["foc_now.id_A", "foc_now.iq_A", "link_status_now.periods"]
    with drive(folder, kind) as url, Link(url, a2l(folder, kind)) as link:
        link.set_schedules(*schedules(scenario))
        cap = link.capture_buffered(names, samples=1000, trigger="run", armed=lambda link: link.start(200))
    sim = Simulation(scenario.with_overrides({"simulation.log_rate": "current"}))
    sim.advance(200)
    engine = sim.result(scenario, 0.0)
    # no sample lost, none twice: the drive's clock steps by one period, the trigger at the run's first
    periods = cap.signals["link_status_now.periods"]
    assert np.all(np.diff(periods.astype(np.int64)) == 1)
    assert cap.timestamps[0] == cap.trigger_ns == int(periods[0]) * 50_000
    # the scale of both currents: the peak of iq (id stays near zero)
    peak = np.max(np.abs(np.asarray(engine.iq_A)[:1000]))
    assert peak > 1.0
    for column, name in (("id_A", "foc_now.id_A"), ("iq_A", "foc_now.iq_A")):
        expected = np.asarray(getattr(engine, column))[:1000]
        got = cap.signals[name].astype(np.float64)
        ulps = np.max(np.abs(got - expected)) / np.spacing(np.float32(peak))
        print(f"\n  {column}: largest difference {ulps:.1f} float32 steps of the peak {peak:.4g} A")
        assert ulps <= 8.0


def test_the_buffer_holds_the_same_bits_as_daq_and_the_trigger_where_asked(servo_firmware):
    """One run streamed by DAQ at the current event and recorded in the buffer at once, triggered by iq crossing
    5 A upwards with 0.5 ms before it: the buffer's samples are the DAQ's of the same periods, bit for bit, and
    the trigger's sample is the first at or above 5 A with the one before below."""
    scenario, folder = servo_firmware
    names = [*CURRENTS, "link_status_now.periods"]
    out = {}
    with drive(folder) as url, Link(url, folder / "virtual_drive_host.a2l") as link:
        link.set_schedules(*schedules(scenario))

        def until(link):
            if not out:
                out["buffer"] = link.capture_buffered(
                    names,
                    samples=400,
                    trigger="rising",
                    trigger_signal="foc_now.iq_A",
                    level=5.0,
                    pre_samples=10,
                    armed=lambda link: link.start(100),
                )
            return link.status()["state"] == "done"

        daq = link.capture(names, event="current", until=until)
    buf = out["buffer"]
    assert daq.dtos_lost == 0
    k = buf.signals["link_status_now.periods"]
    assert np.all(np.diff(k.astype(np.int64)) == 1)
    rows = np.searchsorted(daq.signals["link_status_now.periods"], k)
    assert np.array_equal(daq.signals["link_status_now.periods"][rows], k)
    for n in CURRENTS:
        assert np.array_equal(np.asarray(daq.signals[n][rows], dtype=np.float32).view(np.uint32),
                              buf.signals[n].view(np.uint32)), n  # fmt: skip
    iq = buf.signals["foc_now.iq_A"]
    assert iq[10] >= 5.0 and iq[9] < 5.0 and buf.trigger_ns == int(k[10]) * 50_000
    # the first crossing since the capture was armed: none among the pre-trigger samples
    assert np.all(iq[:10] < 5.0)


def test_the_capture_takes_the_buffer_when_the_link_is_too_slow(servo_firmware, tmp_path, capsys):
    scenario, folder = servo_firmware
    a2l = folder / "virtual_drive_host.a2l"
    with drive(folder) as url, Link(url, a2l) as link:
        out = tmp_path / "c.csv"
        fast = plan_capture(link, CURRENTS, "current", 0.05, out)
        slow = plan_capture(link, CURRENTS, "current", 0.05, out, link_bytes_per_s=11520.0)
        # 4 float32 + 9 bytes a sample at 20 kHz: 500 kB/s, within half of TCP's stated 1 MB/s, not of a UART's
        assert (fast.way, slow.way) == ("daq", "buffer") and fast.need_bytes_per_s == pytest.approx(25 * 20000)
        assert slow.samples == 1001
        # 16384 bytes hold 1024 samples of 16 bytes: 1023 periods of 50 us
        with pytest.raises(ConfigError) as caught:
            plan_capture(link, CURRENTS, "current", 0.06, out, link_bytes_per_s=11520.0)
        assert caught.value.param == "duration_s" and "0.05115 s" in str(caught.value)
    with drive(folder) as url:
        link = ["--link", url.replace("socket://", "tcp://"), "--a2l", str(a2l), "--link-bytes-per-s", "11520"]

        def argv(duration_s):
            return ["drive", "capture", *CURRENTS, "--event", "current", "--duration-s", duration_s, "--out", str(out),
                    *link]  # fmt: skip

        code = main(argv("0.06"))
        err = capsys.readouterr().err
        assert code == 2 and "--duration-s = 0.06" in err and "at most 0.05115 s" in err and len(err.splitlines()) == 1
        assert not out.exists()
        code = main(argv("0.02"))
        text = capsys.readouterr().out
        assert code == 0 and "in the drive's buffer" in text, text
    import pandas as pd

    frame = pd.read_csv(out)
    assert len(frame) == 401 and np.allclose(np.diff(frame["t_s"]), 5e-5)
