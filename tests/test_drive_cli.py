"""`pmsm2dof drive`: info, get, set, capture, run and serve on the PC's virtual drive and on QEMU.

The drives are builds of scenarios (the PC's served by `pmsm2dof drive serve` itself, in a
subprocess; QEMU's by :func:`pmsm2dof.drive.serve.serve_qemu`). Truth comes from outside the
commands: the scenario that built the drive (what `get` reads), the C library's validation and the
drive's own commit counters (what `set` writes or refuses), the scenario's loop periods and the
drive's period counter (what `capture` records), asammdf and pandas reading the files back, the
engine's simulation of the same scenario (what `run` plays), and a TCP relay written here that cuts
the link mid-command (what the drive does then: its status read over a fresh link).
"""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_qemu
from pmsm2dof.sim.logs import read_log
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import RPM_PER_RADPS, Simulation
from pmsm2dof.studies.firmware import AGREEMENT, build_firmware
from pmsm2dof.ui.cli import main

pytest.importorskip("pyxcp")
asammdf = pytest.importorskip("asammdf")

ROOT = Path(__file__).resolve().parents[1]
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"
_MISSING = [t for t in ("cmake", "cc") if shutil.which(t) is None]
_MISSING_MCU = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]
needs_qemu = pytest.mark.skipif(bool(_MISSING_MCU), reason=f"{', '.join(_MISSING_MCU)} not installed")


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Served:
    """`pmsm2dof drive serve SCENARIO --fast` in a subprocess, until the end of the test module."""

    def __init__(self, scenario, out, *extra):
        self.port = free_port()
        env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
        argv = [sys.executable, "-m", "pmsm2dof", "drive", "serve", str(scenario), "--port", str(self.port),
                "--out", str(out), "--fast", "--duration-s", "900", *extra]  # fmt: skip
        self.process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        self.line = self.process.stdout.readline()
        if "serving" not in self.line:
            self.process.kill()
            raise AssertionError(f"drive serve did not start: {self.line} {self.process.stderr.read()}")
        self.url = f"tcp://127.0.0.1:{self.port}"
        self.a2l = Path(out) / "virtual_drive_host.a2l"
        self.link = ["--link", self.url, "--a2l", str(self.a2l)]

    def stop(self):
        self.process.send_signal(signal.SIGTERM)
        code = self.process.wait(timeout=30)
        return code, self.process.stdout.read(), self.process.stderr.read()


@pytest.fixture(scope="module")
def servo(tmp_path_factory):
    """The small servo (20 kHz current, 2 kHz speed loop) served on the PC by `pmsm2dof drive serve`."""
    served = Served(SERVO, tmp_path_factory.mktemp("servo") / "drive")
    yield load_scenario(str(SERVO)), served
    code, out, err = served.stop()
    assert code == 128 + signal.SIGTERM and "Traceback" not in err, (code, out, err)


@pytest.fixture(scope="module")
def experiment_1(tmp_path_factory):
    # a watchdog of 2 s: a master starved of the CPU by other work on the machine must not trip it
    served = Served("paper-experiment-1", tmp_path_factory.mktemp("exp1") / "drive", "--timeout-ms", "2000")
    yield load_scenario("paper-experiment-1"), served
    served.stop()


def test_serve_writes_the_a2l_and_listens_on_loopback_only(servo):
    scenario, served = servo
    assert served.line.startswith(f"{scenario.name}: serving --link {served.url} --a2l {served.a2l}")
    assert served.a2l.is_file() and (served.a2l.parent / "scenario.toml").is_file()
    # the drive answers on 127.0.0.1 only
    addresses = {a[4][0] for a in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)} - {"127.0.0.1"}
    for address in sorted(addresses)[:1]:
        with pytest.raises(OSError), socket.create_connection((address, served.port), timeout=1):
            pass


def test_get_reads_the_configuration_the_scenario_built(servo, capsys):
    scenario, served = servo
    keys = ["speed_controller.alpha_radps", "speed_controller.zeta", "speed_controller.J_kgm2",
            "speed_controller.Ts_s", "current_loop.Ts_s"]  # fmt: skip
    code, out, err = run(["drive", "get", *keys, *served.link], capsys)
    assert code == 0, err
    lines = dict(line.split(" = ") for line in out.splitlines())
    for key in keys:
        section, field = key.split(".")
        value = float(lines[key].split()[0])
        assert np.float32(value) == np.float32(scenario.data[section][field]), key
    assert lines["speed_controller.alpha_radps"].endswith(" rad/s")
    code, out, err = run(["drive", "info", *served.link], capsys)
    assert code == 0 and out.startswith("firmware at ") and "speed every 500 us" in out and "current every 50 us" in out


def test_set_is_checked_before_anything_is_written(servo, capsys):
    """Refused on the host (the A2L's limit, the controller's check, the firmware's fixed period): one line
    naming the variable, the value and the range; the drive's commit counters show that nothing reached it."""
    scenario, served = servo
    with Link(served.url, served.a2l) as link:
        before = link.status()
        alpha = link.read("link_speed_config.alpha_radps")
    cases = {
        "speed_controller.alpha_radps=-5": ("link_speed_config.alpha_radps", "'-5'", "[0, 3.4e+38] rad/s"),
        "speed_controller.alpha_radps=0": ("link_speed_config.alpha_radps", "0.0", "> 0"),
        "speed_controller.Ts_s=0.001": ("link_speed_config.Ts_s", "0.001", "fixed"),
        "speed_controller.method=simpson": ("link_speed_config.method", "'simpson'", "P2D_TUSTIN"),
        "foc_now.iq_A=1": ("foc_now.iq_A", "'1'", "read-only"),
        "link_speed_config.pole_pairs=2.5": ("link_speed_config.pole_pairs", "'2.5'", "an integer"),
    }
    for assignment, (name, value, valid) in cases.items():
        code, out, err = run(["drive", "set", assignment, *served.link], capsys)
        assert code == 2 and out == "" and len(err.splitlines()) == 1, (assignment, err)
        assert err.startswith(f"pmsm2dof: error: {name} = {value} is invalid") and valid in err, err
    with Link(served.url, served.a2l) as link:
        after = link.status()
        assert link.read("link_speed_config.alpha_radps") == alpha
    assert after["commits_rejected"] == before["commits_rejected"]
    assert after["commits_applied"] == before["commits_applied"]
    # two fields of one variable: one commit, both in force, the rest as the scenario built it
    code, out, err = run(["drive", "set", "speed_controller.alpha_radps=120", "speed_controller.method=backward_euler",
                          *served.link], capsys)  # fmt: skip
    assert code == 0, err
    assert out.splitlines() == ["link_speed_config.alpha_radps = 120 rad/s",
                                "link_speed_config.method = P2D_BACKWARD_EULER"]  # fmt: skip
    with Link(served.url, served.a2l) as link:
        status = link.status()
        assert status["commits_applied"] == before["commits_applied"] + 1
        assert link.read("link_speed_config.zeta") == np.float32(scenario.data["speed_controller"]["zeta"])
        link.write({"link_speed_config.alpha_radps": alpha, "link_speed_config.method": 2})


def periods_and_time(t_s, periods, scenario):
    """The capture's time steps by the speed period and the drive's period counter by the loop ratio, every sample."""
    Ts = scenario.data["speed_controller"]["Ts_s"]
    ratio = round(Ts / scenario.data["current_loop"]["Ts_s"])
    np.testing.assert_allclose(np.diff(t_s), Ts, rtol=1e-9)
    assert np.all(np.diff(periods) == ratio)


@pytest.mark.parametrize("suffix", [".mf4", ".csv", ".parquet"])
def test_capture_records_every_speed_sample(servo, tmp_path, capsys, suffix):
    scenario, served = servo
    out = tmp_path / f"capture{suffix}"
    signals = ["link_status_now.periods", "foc_now.w_meas_radps", "foc_now.iq_A"]
    code, text, err = run(
        ["drive", "capture", *signals, "--duration-s", "0.3", "--out", str(out), *served.link], capsys
    )
    assert code == 0, err
    n = int(text.split()[0])
    # 0.3 s of the drive's time at the speed period, every sample from the first
    assert n == round(0.3 / scenario.data["speed_controller"]["Ts_s"]) + 1 and ", 0 lost: wrote" in text
    if suffix == ".mf4":
        # read back by asammdf: an MDF 4.10 file, one channel group, the A2L's units
        with asammdf.MDF(out) as mdf:
            assert mdf.version == "4.10"
            periods = mdf.get("link_status_now.periods")
            assert mdf.get("foc_now.iq_A").unit == "A" and len(periods.samples) == n
            periods_and_time(periods.timestamps, periods.samples, scenario)
    else:
        table = pd.read_csv(out) if suffix == ".csv" else pd.read_parquet(out)
        assert list(table.columns) == ["t_s", *signals] and len(table) == n
        periods_and_time(table["t_s"].to_numpy(), table["link_status_now.periods"].to_numpy(), scenario)
    log = read_log(out, {"speed": "foc_now.w_meas_radps", "iq": "foc_now.iq_A"})
    assert len(log.t_s) == n and log.t_s[0] == 0.0


def test_one_capture_reads_back_the_same_from_each_format(servo, tmp_path):
    """The same samples written as CSV, Parquet and MDF4, read back by read_log (and asammdf): equal to the bit."""
    from pmsm2dof.drive.session import capture, open_link, plan_capture, write_capture

    scenario, served = servo
    signals = ["foc_now.w_meas_radps", "foc_now.iq_A", "link_status_now.periods"]
    with open_link(served.url, served.a2l) as link:
        cap = capture(link, plan_capture(link, signals, "speed", 0.2, tmp_path / "c.csv"))
        for suffix in (".csv", ".parquet", ".mf4"):
            write_capture(link, cap, tmp_path / f"c{suffix}")
    logs = [read_log(tmp_path / f"c{s}", {"speed": signals[0], "iq": signals[1]}) for s in (".csv", ".parquet", ".mf4")]
    for log in logs[1:]:
        np.testing.assert_array_equal(log.t_s, logs[0].t_s)
        np.testing.assert_array_equal(log.w_m_radps, logs[0].w_m_radps)
        np.testing.assert_array_equal(log.iq_A, logs[0].iq_A)
    np.testing.assert_array_equal(logs[2].iq_A, cap.signals["foc_now.iq_A"])


def test_capture_bounds_are_checked_before_it_starts(servo, tmp_path, capsys):
    scenario, served = servo
    (tmp_path / "mine.csv").write_text("not the tool's\n")
    cases = [
        (["foc_now.iq_A", "--duration-s", "1e9", "--out", str(tmp_path / "a.csv")], "--duration-s = 1000000000.0"),
        (["foc_now.iq_A", "--duration-s", "0.1", "--out", str(tmp_path / "a.txt")], ".mf4"),
        (
            ["foc_now.iq_A", "--duration-s", "0.1", "--event", "slow", "--out", str(tmp_path / "a.csv")],
            "event = 'slow'",
        ),
        (["foc_now.iq_A", "--duration-s", "0.1", "--out", str(tmp_path / "mine.csv")], "--force replaces it"),
        ([*(["foc_now.iq_A"] * 65), "--duration-s", "0.1", "--out", str(tmp_path / "a.csv")], "1 to 64 names"),
        (["link_reference.t_s", "--duration-s", "0.1", "--out", str(tmp_path / "a.csv")], "a scalar"),
    ]
    for argv, words in cases:
        start = time.perf_counter()
        code, out, err = run(["drive", "capture", *argv, *served.link], capsys)
        assert code == 2 and len(err.splitlines()) == 1 and words in err, err
        assert time.perf_counter() - start < 20
    assert (tmp_path / "mine.csv").read_text() == "not the tool's\n" and not (tmp_path / "a.csv").exists()


def test_a_remote_host_is_refused_unless_allowed(servo, capsys):
    scenario, served = servo
    code, out, err = run(["drive", "info", "--link", "tcp://192.0.2.1:5555", "--a2l", str(served.a2l)], capsys)
    assert code == 2 and "tcp://192.0.2.1:5555" in err and "this machine" in err


class Relay:
    """A TCP relay to the drive whose connections :meth:`cut` shuts (the master's and the drive's sockets)."""

    def __init__(self, port):
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port, self.drive_port = self.server.getsockname()[1], port
        self.open = []
        threading.Thread(target=self.serve, daemon=True).start()

    @staticmethod
    def pipe(a, b):
        try:
            while data := a.recv(65536):
                b.sendall(data)
            b.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def serve(self):
        while True:
            try:
                master, _ = self.server.accept()
            except OSError:
                return
            drive = socket.create_connection(("127.0.0.1", self.drive_port))
            self.open += [master, drive]
            threading.Thread(target=self.pipe, args=(master, drive), daemon=True).start()
            threading.Thread(target=self.pipe, args=(drive, master), daemon=True).start()

    def cut(self):
        for s in self.open:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()

    def close(self):
        self.server.close()
        self.cut()


def test_a_link_that_drops_mid_run_leaves_the_drive_stopped(servo, tmp_path, capsys, monkeypatch):
    """The relay cuts the link 50 samples into a 2 s run of the servo: one line, exit status 2, no output folder.
    Left alone, the drive's watchdog trips 200 ms of its time after the last command, ramps the reference to
    zero and switches the power stage off (its status read over a fresh link once that time has passed: the PC's
    drive without a master runs a control period per millisecond of the wall clock)."""
    scenario, served = servo
    relay = Relay(served.port)
    status = Link.status
    cut = {}

    def status_then_cut(link):
        st = status(link)
        if st["state"] == "running" and st["sample"] > 50 and not cut:
            cut.update(st)
            relay.cut()
        return st

    monkeypatch.setattr(Link, "status", status_then_cut)
    try:
        link = ["--link", f"tcp://127.0.0.1:{relay.port}", "--a2l", str(served.a2l)]
        code, out, err = run(["drive", "run", str(SERVO), "--set", "simulation.t_end_s=2", "--out",
                              str(tmp_path / "run"), *link], capsys)  # fmt: skip
    finally:
        relay.close()
        monkeypatch.undo()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "dropped" in err and "watchdog" in err and "power stage off" in err
    assert not (tmp_path / "run").exists()
    time.sleep(15.0)
    with Link(served.url, served.a2l) as link:
        status = link.status()
    assert status["state"] == "tripped" and status["power_on"] == 0 and status["w_ref_radps"] == 0.0, status
    # 200 ms of the drive's time (400 speed samples) after the last command the master sent
    assert status["trip_sample"] >= cut["sample"] + 400, (status, cut)


def test_run_of_paper_experiment_1_agrees_with_the_engine(experiment_1, tmp_path, capsys):
    """`drive run` of the paper's experiment 1 (10 s) against the engine's simulation run here."""
    scenario, served = experiment_1
    out = tmp_path / "run"
    code, text, err = run(["drive", "run", "paper-experiment-1", "--out", str(out), *served.link], capsys)
    assert code == 0, text + err
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["metrics.json", "plot.png",
                                                                                   "trace.csv"]  # fmt: skip
    trace = pd.read_csv(out / "trace.csv")
    sim = Simulation(scenario)
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, 0.0)
    np.testing.assert_array_equal(trace["t_s"].to_numpy(), engine.t_s)
    step = max(np.ptp(engine.w_m_radps), np.ptp(engine.speed_ref_rpm) / RPM_PER_RADPS)
    speed = trace["speed_rpm"].to_numpy() / RPM_PER_RADPS
    assert np.max(np.abs(speed - engine.w_m_radps)) <= AGREEMENT * step
    i_step = max(np.ptp(getattr(engine, n)) for n in ("id_A", "iq_A", "id_ref_A", "iq_ref_A"))
    for name in ("id_A", "iq_A"):
        assert np.max(np.abs(trace[name].to_numpy() - getattr(engine, name))) <= AGREEMENT * i_step
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["comparison"]["agrees"] is True
    # a drive set to another design is not the scenario's: refused before it runs
    code, text, err = run(["drive", "set", "speed_controller.alpha_radps=0.6", *served.link], capsys)
    assert code == 0, err
    try:
        code, text, err = run(["drive", "run", "paper-experiment-1", "--out", str(tmp_path / "r2"), *served.link],
                              capsys)  # fmt: skip
        assert code == 2 and "link_speed_config.alpha_radps is 0.6" in err and not (tmp_path / "r2").exists()
    finally:
        run(["drive", "set", f"speed_controller.alpha_radps={scenario.data['speed_controller']['alpha_radps']}",
             *served.link], capsys)  # fmt: skip


# ---- on QEMU: one test per command family -------------------------------------------------------


@pytest.fixture(scope="module")
def servo_mcu(tmp_path_factory):
    if _MISSING_MCU:
        pytest.skip(f"{', '.join(_MISSING_MCU)} not installed")
    return build_firmware(load_scenario(str(SERVO)), tmp_path_factory.mktemp("mcu") / "fw").folder


@needs_qemu
def test_qemu_pty_info_get_set(servo_mcu, capsys):
    scenario = load_scenario(str(SERVO))
    with serve_qemu(servo_mcu / "virtual_drive.elf", serial="pty") as device:
        link = ["--link", f"serial:{device}", "--a2l", str(servo_mcu / "virtual_drive.a2l")]
        code, out, err = run(["drive", "get", "speed_controller.alpha_radps", *link], capsys)
        assert code == 0 and float(out.split()[2]) == scenario.data["speed_controller"]["alpha_radps"], err
        code, out, err = run(["drive", "set", "speed_controller.alpha_radps=-1", *link], capsys)
        assert code == 2 and "link_speed_config.alpha_radps = '-1'" in err
        code, out, err = run(["drive", "set", "speed_controller.zeta=0.9", *link], capsys)
        assert code == 0 and out == "link_speed_config.zeta = 0.9\n", err
        code, out, err = run(["drive", "info", *link], capsys)
        assert code == 0 and "commits 1 applied / 0 rejected" in out and "zeta = 0.9," in out


@needs_qemu
def test_qemu_tcp_capture_to_mdf4(servo_mcu, tmp_path, capsys):
    scenario = load_scenario(str(SERVO))
    out = tmp_path / "c.mf4"
    with serve_qemu(servo_mcu / "virtual_drive.elf", serial="tcp") as url:
        link = ["--link", url.replace("socket://", "tcp://"), "--a2l", str(servo_mcu / "virtual_drive.a2l")]
        code, text, err = run(["drive", "capture", "link_status_now.periods", "foc_now.iq_A", "--duration-s", "1",
                               "--out", str(out), *link], capsys)  # fmt: skip
    assert code == 0 and ", 0 lost" in text, err
    with asammdf.MDF(out) as mdf:
        periods = mdf.get("link_status_now.periods")
    assert len(periods.samples) > 20
    periods_and_time(periods.timestamps, periods.samples, scenario)


@needs_qemu
def test_qemu_run_agrees_with_the_engine(servo_mcu, tmp_path, capsys):
    with serve_qemu(servo_mcu / "virtual_drive.elf", serial="tcp") as url:
        link = ["--link", url.replace("socket://", "tcp://"), "--a2l", str(servo_mcu / "virtual_drive.a2l")]
        code, text, err = run(["drive", "run", str(SERVO), "--set", "simulation.t_end_s=0.15",
                               "--out", str(tmp_path / "run"), *link], capsys)  # fmt: skip
    assert code == 0, err
    scenario = load_scenario(str(SERVO)).with_overrides({"simulation.t_end_s": 0.15})
    sim = Simulation(scenario)
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, 0.0)
    trace = pd.read_csv(tmp_path / "run" / "trace.csv")
    step = max(np.ptp(engine.w_m_radps), np.ptp(engine.speed_ref_rpm) / RPM_PER_RADPS)
    assert np.max(np.abs(trace["speed_rpm"].to_numpy() / RPM_PER_RADPS - engine.w_m_radps)) <= AGREEMENT * step
