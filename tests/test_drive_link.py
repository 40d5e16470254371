"""The firmware's XCP link with pyxcp as the master, on the PC's virtual drive and on QEMU (pty and TCP).

The same firmware sources (examples/firmware: foc.c, link.c, board_virtual.c) built for the PC
(the link on TCP) and for the Cortex-M4F of QEMU -M mps2-an386 (UART0 on a pty, or on a TCP port).
Truth comes from outside the link: the engine's simulation of the same scenario (for a live
calibration: the engine run to the sample the drive reports, then given the same configuration by
the C library's p2d_speed_set_config, the bumpless update the firmware calls), counters that step
by one per sample, the guard's ramp equation (xcp.h) evaluated here, and the addresses of the A2L
file read by pya2ldb (tests/test_drive_a2l.py checks those against the ELF).
"""

import shutil
import struct
import time

import numpy as np
import pytest

from pmsm2dof.core import LOG_COLUMNS
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_host, serve_qemu
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Result, Simulation
from pmsm2dof.studies.firmware import build_firmware, compare, play_scenario

pyxcp = pytest.importorskip("pyxcp")
from pyxcp.types import XcpResponseError  # noqa: E402

_MISSING = [t for t in ("cmake", "cc", "arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]

#: Slow (cross builds and emulators: the full suite); skipped without the tools.
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]

#: The drives: the PC's (as fast as the link allows) and QEMU's UART on a pty and on TCP.
DRIVES = ["host", "qemu-pty", "qemu-tcp"]


@pytest.fixture(scope="module")
def servo(servo_firmware):
    """The small servo (20 kHz current, 2 kHz speed loop) built for QEMU and the PC (tests/conftest.py)."""
    return servo_firmware


def serve(kind, folder, realtime=False, **arguments):
    """The drive of a build; the PC's as fast as the link allows unless ``realtime`` (QEMU's as fast as it runs).

    The link's watchdog waits 1 s unless a test sets ``timeout_ms``: the tests share the cores with other
    tests, and a master starved of CPU for the default 200 ms would trip a drive that a test expects to run.
    """
    arguments.setdefault("timeout_ms", 1000)
    if kind == "host":
        return serve_host(folder / "virtual_drive_host", realtime=realtime, **arguments)
    return serve_qemu(folder / "virtual_drive.elf", serial=kind.split("-")[1], **arguments)


def elf(kind, folder):
    return folder / ("virtual_drive_host" if kind == "host" else "virtual_drive.elf")


def a2l_addresses(path):
    """{name: (address, datatype)} of the MEASUREMENTs and CHARACTERISTICs of an A2L file, read by pya2ldb."""
    import pya2l
    from pya2l import model

    session = pya2l.import_a2l(str(path), in_memory=True, progress_bar=False, loglevel="ERROR")
    out = {m.name: (m.ecu_address.address, m.datatype) for m in session.query(model.Measurement).all()}
    for c in session.query(model.Characteristic).all():
        out[c.name] = (c.address, str(c.deposit))
    return out


def assert_agrees(drive: Result, engine: Result):
    """The drive's run equals the engine's within 1e-4 of the step (speed and currents), sample by sample."""
    np.testing.assert_array_equal(drive.t_s, engine.t_s)
    c = compare(drive, engine)
    print(
        f"\n  speed {c['speed']['relative_to_step']:.2e}, currents {c['currents']['relative_to_step']:.2e} of the step"
    )
    assert c["agrees"], c


@pytest.mark.parametrize("kind", DRIVES)
def test_read_and_write_by_the_a2l_address(servo, kind):
    """A master that knows only the A2L file: SHORT_UPLOAD and DOWNLOAD at its addresses."""
    scenario, folder = servo
    a2l = a2l_addresses(folder / ("virtual_drive_host.a2l" if kind == "host" else "virtual_drive.a2l"))
    with serve(kind, folder) as url, Link(url, elf(kind, folder)) as link:
        x = link.master
        assert x.identifier(1) == "firmware"
        address, datatype = a2l["link_speed_config.alpha_radps"]
        assert datatype == "RL_FLOAT32_IEEE"
        alpha = struct.unpack("<f", x.shortUpload(4, address))[0]
        assert alpha == pytest.approx(scenario.data["speed_controller"]["alpha_radps"], rel=1e-7)
        x.setMta(address)
        x.download(struct.pack("<f", 120.0))
        assert struct.unpack("<f", x.shortUpload(4, address))[0] == 120.0
        # the controller took it: the firmware's copy of its configuration, another variable, says so
        address, datatype = a2l["link_status_now.commits_applied"]
        assert datatype == "ULONG" and struct.unpack("<I", x.shortUpload(4, address))[0] == 1
        # a measurement is read-only
        with pytest.raises(XcpResponseError) as caught:
            x.setMta(a2l["foc_now.w_ref_radps"][0])
            x.download(struct.pack("<f", 1.0))
        assert str(caught.value.get_error_code()) == "ERR_WRITE_PROTECTED"


@pytest.mark.parametrize("kind", DRIVES)
def test_daq_at_the_speed_rate_loses_no_sample(servo, kind):
    """A run of 0.1 s captured at every speed sample: counters continuous, timestamps one speed period apart."""
    scenario, folder = servo
    ratio = 10
    with serve(kind, folder) as url, Link(url, elf(kind, folder)) as link:
        started = {}

        def done(link):
            if not started:
                link.start(200)
                started["yes"] = True
            return link.status()["state"] == "done"

        names = ["link_status_now.sample", "link_status_now.periods", "foc_now.w_meas_radps", "foc_now.iq_A",
                 "foc_now.T_ref_Nm", "foc_now.x_i_Nm", "vd_trace.w_m_radps", "vd_trace.iq_A"]  # fmt: skip
        cap = link.capture(names, until=done)
    k = cap.signals["link_status_now.sample"]
    running = (k >= 1) & (k < 200)
    assert cap.dtos_lost == 0
    assert np.all(np.diff(k[running]) == 1) and running.sum() == 199
    # one DAQ sample per speed sample: the periods counter steps by the ratio, the timestamps (pyxcp turns the
    # ticks into ns by the slave's GET_DAQ_RESOLUTION_INFO) by the speed period of the drive's time, 0.5 ms
    assert np.all(np.diff(cap.signals["link_status_now.periods"]) == ratio)
    assert np.all(np.diff(cap.timestamps) == 500_000)
    print(f"\n  {len(k)} samples of {len(names)} signals, none lost")


@pytest.mark.parametrize("kind", DRIVES)
def test_a_live_write_of_alpha_takes_effect_at_the_next_speed_sample(servo, kind):
    """alpha written during the run (before the second step): the run equals the engine's run switched to the
    new design at the sample the drive reports, through the same bumpless p2d_speed_set_config."""
    scenario, folder = servo
    alpha_new = 100.0

    def play_with_a_write():
        """The run on the PC's drive on the wall clock (its 0.2 s), alpha written once it passed sample 100."""
        written = {}

        def write_alpha(link, status):
            if not written and status["sample"] >= 100:
                link.write({"link_speed_config.alpha_radps": alpha_new})
                written["status"] = link.status()

        with serve(kind, folder, realtime=True) as url, Link(url, elf(kind, folder)) as link:
            return play_scenario(link, scenario, during=write_alpha), written.get("status")

    # a machine too busy for the write to land before the second step's response is over plays the run again
    for _ in range(3):
        drive, status = play_with_a_write()
        if status is not None and status["commit_run"] == status["runs"] and status["commit_sample"] < 300:
            break
    assert status is not None and status["commit_run"] == status["runs"] and status["commits_applied"] >= 1, status
    k = status["commit_sample"]
    assert 100 <= k < 300, k  # after the first step, before the response to the second (at sample 240) is over
    sim = Simulation(scenario)
    sim.advance(k)
    cfg = ffi.new("p2d_speed_config_t *", sim.sim.speed.config)
    cfg.alpha_radps = alpha_new
    assert lib.p2d_speed_set_config(ffi.addressof(sim.sim, "speed"), cfg) == lib.P2D_OK
    sim.advance(sim.n_samples - k)
    engine = sim.result(scenario, 0.0)
    assert_agrees(drive, engine)
    # and the new design made a difference the comparison can see: the old one's run differs after k
    old = Simulation(scenario)
    old.advance(old.n_samples)
    old_speed = old.result(scenario, 0.0).w_m_radps
    assert np.max(np.abs(old_speed - drive.w_m_radps)) > 1e-2 * np.ptp(old_speed)


@pytest.mark.parametrize("kind", DRIVES)
def test_a_rejected_configuration_leaves_the_drive_unchanged(servo, kind):
    scenario, folder = servo
    with serve(kind, folder) as url, Link(url, elf(kind, folder)) as link:
        before = link.read("link_speed_config.alpha_radps")
        with pytest.raises(XcpResponseError) as caught:
            link.write({"link_speed_config.alpha_radps": -5.0})
        assert str(caught.value.get_error_code()) == "ERR_OUT_OF_RANGE"
        # another loop period than the firmware's: refused by the firmware before the controller
        with pytest.raises(XcpResponseError):
            link.write({"link_speed_config.Ts_s": 1e-3})
        status = link.status()
        assert link.read("link_speed_config.alpha_radps") == before
        assert status["commits_rejected"] == 2 and status["commit_status"] == lib.P2D_ERR_TS
        drive = play_scenario(link, scenario, samples=200)
    sim = Simulation(scenario)
    sim.advance(200)
    assert_agrees(drive, sim.result(scenario, 0.0))


@pytest.mark.parametrize("kind", DRIVES)
def test_a_silent_master_trips_the_watchdog(servo, kind):
    """The master starts a run at 2000 rpm and falls silent (its DAQ keeps streaming): after the link timeout
    the reference ramps to zero at the guard's rate, holds 20 ms with the power on, then the power goes off."""
    scenario, folder = servo
    timeout_ms, ramp, hold_ms, Ts = 50, 20000, 20, 5e-4
    names = ["link_status_now.sample", "link_status_now.w_ref_radps", "link_status_now.guard_state",
             "link_status_now.power_on", "vd_trace.w_m_radps"]  # fmt: skip
    args = {"timeout_ms": timeout_ms, "ramp_radps_per_s": ramp, "hold_ms": hold_ms}
    with serve(kind, folder, **args) as url, Link(url, elf(kind, folder)) as link:
        link.set_schedules([(0.0, 200.0, 0.0)], [])
        silent = {}

        def silence(link):
            if not silent:
                link.start(4000)
                silent["started"] = True
                return False
            # the last command; then none at all until the drive must have stopped (QEMU's time runs slower
            # than the wall's)
            silent["last"] = link.status()
            time.sleep(0.5 if kind == "host" else 3.0)
            return True

        cap = link.capture(names, until=silence)
        status = link.status()
    assert status["state"] == "tripped" and status["power_on"] == 0
    k = cap.signals["link_status_now.sample"]
    w_ref = cap.signals["link_status_now.w_ref_radps"]
    power = cap.signals["link_status_now.power_on"]
    trip, last = status["trip_sample"], silent["last"]["sample"]
    # tripped at the first speed sample after the timeout of the drive's time since the last command
    assert last > 0 and timeout_ms * 1e-3 / Ts <= trip - last <= timeout_ms * 1e-3 / Ts + 2
    i = int(np.flatnonzero(k == trip)[0])
    assert np.all(w_ref[:i][k[:i] >= 1] == 200.0)
    # w_ref[k] = max(w_ref[k-1] - ramp Ts, 0), in float32 as the guard computes it
    n_ramp = int(np.ceil(200.0 / (ramp * Ts)))
    expected = np.maximum(200.0 - ramp * Ts * np.arange(1, n_ramp + 1), 0.0)
    np.testing.assert_allclose(w_ref[i : i + n_ramp], expected, atol=1e-3)
    hold = round(hold_ms * 1e-3 / Ts)
    assert list(power[i + n_ramp : i + n_ramp + hold]) == [1] * hold
    assert status["stop_sample"] == trip + n_ramp + hold and power[i + n_ramp + hold] == 0


@pytest.fixture(scope="module")
def experiment_1(tmp_path_factory):
    """The paper's experiment 1 built for QEMU and the PC (the run's length is the master's: any t_end builds it)."""
    return build_firmware(load_scenario("paper-experiment-1"), tmp_path_factory.mktemp("exp1") / "fw").folder


@pytest.mark.parametrize("kind", DRIVES)
def test_paper_experiment_1_over_the_link_equals_the_engine(experiment_1, kind):
    """The paper's experiment 1 played over the link (reference schedule written, run started, trace captured
    by DAQ): the whole 10 s on the PC's drive, the first 0.8 s (the step at 0.5 s) on QEMU."""
    t_end = 10.0 if kind == "host" else 0.8
    scenario = load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": t_end})
    folder = experiment_1
    with serve(kind, folder) as url, Link(url, elf(kind, folder)) as link:
        drive = play_scenario(link, scenario)
    sim = Simulation(scenario)
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, 0.0)
    assert list(LOG_COLUMNS)[:3] == ["t_s", "w_ref_radps", "w_m_radps"]
    assert_agrees(drive, engine)


@pytest.mark.parametrize("how", ["cut", "disconnect"])
@pytest.mark.parametrize("kind", ["host", "qemu-tcp"])
def test_only_the_master_of_a_run_feeds_its_watchdog(servo, kind, how):
    """The master that started a run is cut off (its socket shut, no DISCONNECT) or leaves (DISCONNECT); a second
    master connects at once and talks all along: the run still trips, the link timeout after the first master's
    last command, as if nobody talked (a second master cannot keep alive a run it did not start)."""
    scenario, folder = servo
    timeout_ms, Ts = 50, 5e-4
    with serve(kind, folder, timeout_ms=timeout_ms) as url:
        first = Link(url, elf(kind, folder)).__enter__()
        first.set_schedules([(0.0, 100.0, 0.0)], [])
        first.start(40000)
        last = first.wait(["running"], timeout_s=10.0)
        if how == "cut":
            import socket

            first.master.transport.sock.shutdown(socket.SHUT_RDWR)
            first._master = None  # abandoned, as by a master that crashed
        else:
            first.close()
        end = time.monotonic() + 60.0
        while True:
            try:
                second = Link(url, elf(kind, folder)).__enter__()
                break
            except Exception:
                if time.monotonic() > end:
                    raise
                time.sleep(0.1)
        with second:
            status = second.wait(["tripped", "done", "stopped"], timeout_s=60.0, poll_s=0.005)
    assert status["state"] == "tripped" and status["power_on"] == 0, status
    # the first master's last command came at or after `last` (its status read); the guard left armed the link
    # timeout of the drive's time later, at the first speed sample after it (the second master notwithstanding).
    # Between that read and the master's last command (its DISCONNECT, or the cut) the drive runs on as fast as
    # the link allows: on a loaded host that is up to a few hundred samples, far fewer than the 40000 of the run
    # that a second master feeding the guard would let finish.
    assert timeout_ms * 1e-3 / Ts <= status["trip_sample"] - last["sample"] <= timeout_ms * 1e-3 / Ts + 400, status
