"""The XCP slave of the C library (csrc/src/xcp.c) driven by pyxcp, a master nobody here wrote.

csrc/tests/xcp_tcp_slave.c runs the slave over TCP on 127.0.0.1 the way the firmware runs it: a
thread plays the interrupts (the "current" event every 0.5 ms; every 4th, the speed sample: the
calibration commit, the link watchdog and its guard, a first-order stand-in drive, the "speed"
event), the main thread the transport. Its memory map (the file's comment) is restated here:
truth about values comes from what the tests wrote, from counters that step by one per sample,
and from the guard's ramp equation (xcp.h) evaluated here.
"""

import contextlib
import shutil
import struct
import subprocess
import time
from pathlib import Path

import pytest
from pyxcp import Master
from pyxcp.config import create_application_from_config, reset_application, set_application
from pyxcp.daq_stim import DaqList, DaqOnlinePolicy, DaqRecorder
from pyxcp.recorder import XcpLogFileDecoder
from pyxcp.types import XcpResponseError, XcpTimeoutError

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

CSRC = Path(__file__).resolve().parents[1] / "csrc"
MEAS = 0x00010000  # drive_meas_t
CAL = 0x00020000  # drive_cal_t
LOST = 0x00030000  # the slave's count of lost DAQ samples
#: drive_meas_t: sample, current_count, w_ref_radps, w_m_radps, command_sample, trip_sample, stop_sample,
#: silent_samples, power_on, guard_state, commits_rejected
MEAS_FORMAT = "<IIffIIIIBBH"
CAL_FORMAT = "<fff"  # w_cmd_radps, tau_s, limit_radps
TS_S = 2e-3  # speed sample: 4 x 0.5 ms


@pytest.fixture(scope="module")
def slave_program(tmp_path_factory):
    """xcp_tcp_slave built from the sources with the host's C compiler."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (Debian: build-essential)")
    binary = tmp_path_factory.mktemp("xcp") / "xcp_tcp_slave"
    build = subprocess.run(
        [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pthread", "-I", str(CSRC / "include")]
        + [str(CSRC / "tests" / "xcp_tcp_slave.c"), str(CSRC / "src" / "xcp.c"), "-lm", "-o", str(binary)],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    return binary


@pytest.fixture(scope="module", autouse=True)
def pyxcp_application():
    """pyxcp's DAQ policies read the global application's configuration, which pyxcp would otherwise make from
    sys.argv (pytest's arguments): a default one for this module."""
    set_application(create_application_from_config({}, log_level=50))
    yield
    reset_application()


@contextlib.contextmanager
def running_slave(program, *options):
    """The slave listening on an ephemeral port of 127.0.0.1; yields the port, ends the process after."""
    process = subprocess.Popen(
        [str(program), "--lifetime-s", "120", *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line = process.stdout.readline()
        assert line.startswith("port "), line + process.stderr.read()
        yield int(line.split()[1])
    finally:
        process.terminate()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def master(port, policy=None, key=None, timeout_s=2.0):
    """A pyxcp master on TCP to 127.0.0.1:port, raising XcpResponseError on an error packet."""
    general = {"disable_error_handling": True}
    if key is not None:
        general["seed_n_key_function"] = key
    config = {
        "Transport": {"timeout": timeout_s, "Eth": {"host": "127.0.0.1", "port": port, "protocol": "TCP"}},
        "General": general,
    }
    return Master("eth", config=create_application_from_config(config, log_level=50), policy=policy)


def meas(x):
    names = "sample current_count w_ref w_m command_sample trip_sample stop_sample silent_samples power_on guard_state"
    return dict(zip([*names.split(), "rejected"], struct.unpack(MEAS_FORMAT, x.shortUpload(36, MEAS))))


def cal(x):
    return struct.unpack(CAL_FORMAT, x.shortUpload(12, CAL))


def write(x, address, data):
    x.setMta(address)
    x.download(data)


def error_code(call):
    with pytest.raises(XcpResponseError) as caught:
        call()
    return str(caught.value.get_error_code())


def key_of(resource, seed):
    """The key xcp_tcp_slave.c expects: each seed byte xor 0xA5, then the seed reversed."""
    return bytes(b ^ 0xA5 for b in seed) + bytes(reversed(seed))


def test_connect_identify_and_status(slave_program):
    with running_slave(slave_program) as port, master(port) as x:
        connected = x.connect()
        assert (connected.maxCto, connected.maxDto) == (255, 1024)
        assert connected.resource.daq and connected.resource.calpag and not connected.resource.pgm
        assert connected.commModeBasic.byteOrder == "INTEL" and connected.commModeBasic.addressGranularity == "BYTE"
        assert x.identifier(0) == "pmsm2dof xcp_tcp_slave"
        assert x.identifier(1) == "xcp_tcp_slave"
        status = x.getStatus()
        assert not status.sessionStatus.daqRunning and not any(x.getCurrentProtectionStatus().values())
        assert x.getCommModeInfo().commModeOptional.masterBlockMode is False
        assert error_code(lambda: x.buildChecksum(4)) == "ERR_CMD_UNKNOWN"
        x.disconnect()


def test_upload_download_and_short_upload(slave_program):
    with running_slave(slave_program) as port, master(port) as x:
        x.connect()
        x.setMta(CAL)
        assert struct.unpack(CAL_FORMAT, x.upload(12)) == pytest.approx((0.0, 0.05, 500.0))
        write(x, CAL, struct.pack("<f", 123.5))
        assert cal(x)[0] == 123.5
        # the drive applies it from the next speed sample on: the guard passes the master's reference
        time.sleep(0.05)
        m = meas(x)
        assert m["w_ref"] == 123.5 and m["power_on"] == 1 and 0 < m["w_m"] <= 123.5
        # the MTA moves on after an UPLOAD: two parts read what one reads
        x.setMta(CAL)
        assert x.upload(4) + x.upload(8) == x.shortUpload(12, CAL)
        x.disconnect()


def test_access_outside_the_segments_is_denied(slave_program):
    with running_slave(slave_program) as port, master(port) as x:
        x.connect()
        assert error_code(lambda: x.shortUpload(1, MEAS - 1)) == "ERR_ACCESS_DENIED"
        assert error_code(lambda: x.shortUpload(2, MEAS + 35)) == "ERR_ACCESS_DENIED"  # across the end
        assert error_code(lambda: x.shortUpload(4, 0)) == "ERR_ACCESS_DENIED"
        assert error_code(lambda: x.shortUpload(4, LOST + 1)) == "ERR_ACCESS_DENIED"
        assert error_code(lambda: write(x, MEAS, b"\x00\x00\x00\x00")) == "ERR_WRITE_PROTECTED"
        assert error_code(lambda: write(x, CAL + 10, b"\x00\x00\x00\x00")) == "ERR_ACCESS_DENIED"
        assert error_code(lambda: write(x, 0x7FFF0000, b"\x00")) == "ERR_ACCESS_DENIED"
        assert cal(x) == pytest.approx((0.0, 0.05, 500.0))
        x.disconnect()


def test_a_rejected_calibration_leaves_the_drive_unchanged(slave_program):
    with running_slave(slave_program) as port, master(port) as x:
        x.connect()
        write(x, CAL, struct.pack("<f", 200.0))
        before_cal, before = cal(x), meas(x)
        # a reference above the limit, then a limit the drive refuses: both answered with an error
        assert error_code(lambda: write(x, CAL, struct.pack("<f", 600.0))) == "ERR_OUT_OF_RANGE"
        assert error_code(lambda: write(x, CAL + 8, struct.pack("<f", -1.0))) == "ERR_OUT_OF_RANGE"
        time.sleep(0.02)
        after = meas(x)
        assert cal(x) == before_cal and after["w_ref"] == before["w_ref"] == 200.0
        assert after["rejected"] == 2
        # the same reference with a new limit, in one DOWNLOAD: accepted, the two values at once
        write(x, CAL, struct.pack(CAL_FORMAT, 600.0, 0.05, 700.0))
        assert cal(x) == pytest.approx((600.0, 0.05, 700.0))
        x.disconnect()


def test_seed_and_key(slave_program):
    with running_slave(slave_program, "--protect") as port:
        with master(port, key=key_of) as x:
            x.connect()
            assert x.getCurrentProtectionStatus()["calpag"] and x.getCurrentProtectionStatus()["daq"]
            assert error_code(lambda: write(x, CAL, struct.pack("<f", 1.0))) == "ERR_ACCESS_LOCKED"
            assert error_code(lambda: x.getDaqProcessorInfo()) == "ERR_ACCESS_LOCKED"
            x.cond_unlock()
            assert not any(x.getCurrentProtectionStatus().values())
            write(x, CAL, struct.pack("<f", 1.0))
            assert cal(x)[0] == 1.0
            x.disconnect()
        with master(port, key=lambda resource, seed: bytes(len(seed) * 2), timeout_s=0.3) as x:
            x.connect()
            assert error_code(lambda: x.cond_unlock("calpag")) == "ERR_ACCESS_LOCKED"
            with pytest.raises(XcpTimeoutError):  # a wrong key ends the session: the slave answers nothing
                x.getStatus()
            x.connect()
            assert x.getStatus().resourceProtectionStatus.calpag


class Collect(DaqOnlinePolicy):
    """The samples of every DAQ list, by name, as dicts of the measurement names."""

    def __init__(self, daq_lists):
        super().__init__(daq_lists)
        self.samples = {d.name: [] for d in daq_lists}

    def initialize(self):
        pass

    def finalize(self):
        pass

    def on_daq_list(self, daq_list, timestamp0, timestamp1, payload):
        d = self.daq_lists[daq_list]
        row = dict(zip([h[0] for h in d.headers], payload))
        self.samples[d.name].append({"t_ns": timestamp1, **row})


def speed_and_current_lists(timestamps=True):
    return [
        DaqList(
            name="speed",
            event_num=1,
            stim=False,
            enable_timestamps=timestamps,
            measurements=[
                ("sample", MEAS, 0, "U32"),
                ("w_ref", MEAS + 8, 0, "F32"),
                ("w_m", MEAS + 12, 0, "F32"),
                ("power_on", MEAS + 32, 0, "U8"),
            ],
            priority=0,
            prescaler=1,
        ),
        DaqList(
            name="current",
            event_num=0,
            stim=False,
            enable_timestamps=False,
            measurements=[("current_count", MEAS + 4, 0, "U32")],
            priority=0,
            prescaler=2,
        ),
    ]


def assert_continuous(samples, key, step):
    values = [s[key] for s in samples]
    assert len(values) > 10
    assert {b - a for a, b in zip(values, values[1:])} == {step}, values[:20]


def test_daq_capture_loses_no_sample(slave_program):
    with running_slave(slave_program) as port:
        policy = Collect(speed_and_current_lists())
        with master(port, policy=policy) as x:
            x.connect()
            write(x, CAL, struct.pack("<f", 50.0))
            policy.setup()
            policy.start()
            time.sleep(1.5)
            policy.stop()
            lost = struct.unpack("<I", x.shortUpload(4, LOST))[0]
            x.disconnect()
        speed, current = policy.samples["speed"], policy.samples["current"]
        assert_continuous(speed, "sample", 1)
        assert_continuous(current, "current_count", 2)  # prescaler 2
        assert lost == 0
        # about 1.5 s of samples, and timestamps (1 us ticks) one speed period apart on average
        assert 0.7 * 1.5 / TS_S < len(speed) < 1.3 * 1.5 / TS_S
        period_s = (speed[-1]["t_ns"] - speed[0]["t_ns"]) * 1e-9 / (len(speed) - 1)
        assert period_s == pytest.approx(TS_S, rel=0.05)
        assert all(s["w_ref"] == 50.0 and s["power_on"] == 1 for s in speed)

        # the same through pyxcp's recorder, to a file read back by its decoder
        recording = Path(str(slave_program) + "-run")
        recorder = DaqRecorder(speed_and_current_lists(), str(recording), 8)
        with master(port, policy=recorder) as x:
            x.connect()
            recorder.setup()
            recorder.start()
            time.sleep(0.5)
            recorder.stop()
            x.disconnect()
        decoded = Decoded(str(recording) + ".xmraw")
        decoded.run()
        assert_continuous(decoded.samples["speed"], "sample", 1)
        assert_continuous(decoded.samples["current"], "current_count", 2)


class Decoded(XcpLogFileDecoder):
    """The samples of a pyxcp recording, by DAQ list name."""

    def __init__(self, file_name):
        super().__init__(file_name)
        self.samples = {}

    def initialize(self):
        pass

    def finalize(self):
        pass

    def on_daq_list(self, daq_list, timestamp0, timestamp1, payload):
        d = self.daq_lists[daq_list]
        self.samples.setdefault(d.name, []).append(dict(zip([h[0] for h in d.headers], payload)))


def test_can_sized_packets(slave_program):
    """MAX_CTO 8 and MAX_DTO 8, as on classic CAN: an UPLOAD in slave block mode, DAQ lists of several ODTs."""
    with running_slave(slave_program, "--max-cto", "8", "--max-dto", "8") as port:
        policy = Collect(speed_and_current_lists(timestamps=False))
        with master(port, policy=policy) as x:
            assert x.connect().maxCto == 8
            write(x, CAL, struct.pack("<f", -20.0))
            x.setMta(CAL)
            assert struct.unpack(CAL_FORMAT, x.upload(12)) == pytest.approx((-20.0, 0.05, 500.0))
            policy.setup()
            policy.start()
            time.sleep(0.5)
            policy.stop()
            x.disconnect()
        assert_continuous(policy.samples["speed"], "sample", 1)
        assert_continuous(policy.samples["current"], "current_count", 2)
        assert all(s["w_ref"] == -20.0 for s in policy.samples["speed"])


def test_watchdog_trips_on_a_silent_master(slave_program):
    """A master that starts a run and goes silent: after the link timeout the guard ramps the reference to zero
    at 1000 rad/s^2, holds it 50 ms with the power on, then disables the power stage, latched (xcp.h)."""
    timeout_s, ramp, hold_s = 0.2, 1000.0, 0.05
    options = ["--link-timeout-ms", "200", "--ramp-radps-per-s", "1000", "--hold-s", "0.05"]
    with running_slave(slave_program, *options) as port:
        policy = Collect(speed_and_current_lists()[:1])
        with master(port, policy=policy) as x:
            x.connect()
            write(x, CAL, struct.pack("<f", 100.0))
            policy.setup()
            policy.start()  # the last command before the silence
            time.sleep(timeout_s + 100.0 / ramp + hold_s + 0.3)
            policy.stop()  # the master is back: the drive stays stopped
            time.sleep(0.02)
            m = meas(x)
            x.disconnect()
        assert m["guard_state"] == 3 and m["power_on"] == 0 and m["w_ref"] == 0.0
        silent_samples = m["silent_samples"]
        print(f"\nwatchdog: tripped after {silent_samples} samples ({silent_samples * TS_S * 1e3:.0f} ms) of silence")
        assert timeout_s / TS_S <= silent_samples <= timeout_s / TS_S + 25
        # the trace, sample by sample: w_ref[k] = w_ref[k-1] - ramp Ts down to 0, then the hold, then power off
        speed = policy.samples["speed"]
        assert_continuous(speed, "sample", 1)
        trip = next(i for i, s in enumerate(speed) if s["sample"] == m["trip_sample"])
        assert all(s["w_ref"] == 100.0 and s["power_on"] == 1 for s in speed[:trip])
        ramp_samples = round(100.0 / (ramp * TS_S))
        expected = [max(100.0 - ramp * TS_S * k, 0.0) for k in range(1, ramp_samples + 1)]
        assert [s["w_ref"] for s in speed[trip : trip + ramp_samples]] == pytest.approx(expected, abs=1e-4)
        hold = round(hold_s / TS_S)
        after = speed[trip + ramp_samples : trip + ramp_samples + hold + 5]
        assert [s["power_on"] for s in after] == [1] * hold + [0] * 5
        assert all(s["w_ref"] == 0.0 for s in after)
        assert m["stop_sample"] - m["trip_sample"] == ramp_samples + hold
