"""`pmsm2dof drive commission` and `drive identify` on the PC's virtual drive and on QEMU, against a hidden motor.

The drive is a build of the small servo (20 kHz current, 2 kHz speed loop) whose motor the host
never reads: its inertia is 1.3 times the one the speed controller is designed for, and it has
viscous and Coulomb friction the controllers know nothing of; before the commissioning, the
drive's controllers are given motor data 20 to 40 % off (`drive set`, as a wrong datasheet would),
from which the host derives the routine's settings. The commands see the link and the A2L file
only.

Truth from outside the code under test: the scenario that built the drive (its motor's values),
the engine's run of the same C routine (:func:`pmsm2dof.sim.commission.commission`, its own RK4
plant and inverter) against that motor with the settings the drive used, and a hand-derived
correction for the one modelling difference between the two plants: the virtual board holds each
period's voltage in the rotor frame at the period's starting angle (board_virtual.c, the engine's
drive loop), where the engine's commissioning run holds the stationary-frame vector as an inverter
does; in the flux test, at the electrical speed w_e with the current i_d on the rotor's d axis,
the voltage the routine assumes is then rotated by w_e Ts / 2 against the one applied, which
shifts the active flux along d by -(w_e Ts / 2) Rs i_d / w_e = -Ts Rs i_d / 2 (a relative
-Ts Rs i_spin / (2 psi_f), -0.5 % here). The link-drop tests cut a TCP relay mid-step (as
tests/test_drive_cli.py) and read the drive's state over a fresh link.
"""

import json
import shutil
import time

import numpy as np
import pytest
from test_drive_cli import Relay

from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_host, serve_qemu
from pmsm2dof.drive.session import read_variable
from pmsm2dof.sim.commission import TARGETS, commission
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.drive_commission import STATES
from pmsm2dof.studies.firmware import build_firmware
from pmsm2dof.ui.cli import main

pytest.importorskip("pyxcp")
_MISSING = [t for t in ("cmake", "cc", "arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]

#: Slow (firmware builds, QEMU): the full suite.
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]

#: The hidden motor: the small servo without its load, heavier than its controller's design, with friction.
HIDDEN = {"load": [], "motor.J_kgm2": 1.3e-4, "speed_controller.J_kgm2": 1e-4, "motor.B_Nms": 2e-5,
          "motor.T_coulomb_Nm": 0.004}  # fmt: skip
#: What the drive's controllers are told of the motor before the commissioning (a wrong datasheet).
DATASHEET = ["current_loop.Rs_ohm=0.7", "current_loop.Ld_H=0.0006", "current_loop.Lq_H=0.0007",
             "current_loop.psi_f_Wb=0.012"]  # fmt: skip
#: The link watchdog of the drives [ms]: the tests share two cores, a master starved of them must not trip a drive.
TIMEOUT_MS = 1000
#: The watchdog of the drives whose link is cut [ms]: the PC's drive without a master runs a control period per
#: millisecond of the wall clock, so the trip comes 10 s of the wall clock per 0.5 s of its time (and a master that
#: connects before it would feed the watchdog again).
CUT_TIMEOUT_MS = 200
#: Wall time left to a drive whose link was cut before its state is read [s]: the timeout, the guard's ramp and hold.
CUT_WAIT_S = 15.0
DRIVES = ["host", "qemu"]


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    """The hidden motor's scenario and its firmware built for the PC and QEMU."""
    scenario = load_scenario("examples/firmware/small-servo-20k.toml").with_overrides(HIDDEN)
    return scenario, build_firmware(scenario, tmp_path_factory.mktemp("hidden") / "fw").folder


def serve(kind, folder, **arguments):
    arguments.setdefault("timeout_ms", TIMEOUT_MS)
    if kind == "host":
        return serve_host(folder / "virtual_drive_host", realtime=False, **arguments)
    return serve_qemu(folder / "virtual_drive.elf", serial="tcp", **arguments)


def link_args(kind, folder, url):
    a2l = folder / ("virtual_drive_host.a2l" if kind == "host" else "virtual_drive.a2l")
    return ["--link", url.replace("socket://", "tcp://"), "--a2l", str(a2l)]


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("kind", DRIVES)
def test_commission_over_the_link_finds_what_the_engine_finds(hidden, kind, tmp_path, capsys):
    scenario, folder = hidden
    out = tmp_path / "commissioned"
    with serve(kind, folder) as url:
        link = link_args(kind, folder, url)
        assert run(["drive", "set", *DATASHEET, *link], capsys)[0] == 0
        start = time.perf_counter()
        code, text, err = run(["drive", "commission", "--out", str(out), *link], capsys)
        wall_s = time.perf_counter() - start
    assert code == 0, text + err
    # every step printed as the drive entered it, in order
    steps = [line.split()[-1] for line in text.splitlines() if line.startswith("  ") and line.strip()[0].isdigit()]
    assert steps == ["probe", "align", "rs_low", "rs_high", "ld", "lq", "ramp_up", "spin", "ramp_down", "done"], text
    result = json.loads((out / "result.json").read_text())
    drive = result["estimates"]
    motor = scenario.motor
    # the engine's run of the routine with the settings the drive used, against the same motor at rest at angle 0
    drive_only = ("Ts_s", "voltage_delay_samples")
    settings = {f"commissioning.{k}": v for k, v in result["config"].items() if k not in drive_only}
    engine = commission(scenario.with_overrides({**settings, "commissioning.theta0_rad": 0.0})).estimates
    Ts = scenario.current_loop.Ts_s
    psi_shift = -Ts * motor.Rs_ohm * result["config"]["i_spin_A"] / 2.0
    print(f"\n  {kind}: {wall_s:.1f} s wall")
    for key in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb"):
        print(f"  {key}: drive {drive[key]:.7g}, engine {engine[key]:.7g}, true {getattr(motor, key):.7g}, "
              f"drive/true - 1 = {drive[key] / getattr(motor, key) - 1:+.2e}")  # fmt: skip
        assert abs(drive[key] / getattr(motor, key) - 1.0) <= TARGETS[key]
    for key in ("Rs_ohm", "Ld_H", "Lq_H"):
        assert drive[key] == pytest.approx(engine[key], rel=1e-4)
    assert drive["psi_f_Wb"] == pytest.approx(engine["psi_f_Wb"] + psi_shift, rel=1e-3)
    # the motor file holds what the drive found, not the datasheet the drive was given
    text = (out / "motor.toml").read_text()
    assert f"Rs_ohm = {drive['Rs_ohm']!r}" in text and "pole_pairs = 4" in text
    assert {"log.csv", "plot.png"} <= {p.name for p in out.iterdir()}


@pytest.mark.parametrize("kind", DRIVES)
def test_identify_over_the_link_finds_the_hidden_inertia(hidden, kind, tmp_path, capsys):
    scenario, folder = hidden
    out = tmp_path / "identified"
    with serve(kind, folder) as url:
        start = time.perf_counter()
        code, text, err = run(["drive", "identify", "--out", str(out), *link_args(kind, folder, url)], capsys)
        wall_s = time.perf_counter() - start
    assert code == 0, text + err
    found = json.loads((out / "identify.json").read_text())
    motor = scenario.motor
    print(f"\n  {kind}: {wall_s:.1f} s wall; " + ", ".join(
        f"{k} {found[k]:.6g} (true {getattr(motor, k):.6g})" for k in ("J_kgm2", "B_Nms", "T_coulomb_Nm")))  # fmt: skip
    assert found["J_kgm2"] == pytest.approx(motor.J_kgm2, rel=0.02)
    # the controller's design inertia is not what was found
    assert abs(found["J_kgm2"] / scenario.data["speed_controller"]["J_kgm2"] - 1) > 0.2
    identified = load_scenario(str(out / "identified.toml"))
    assert identified.data["speed_controller"]["J_kgm2"] == found["J_kgm2"]
    capture = np.genfromtxt(out / "capture.csv", delimiter=",", names=True)
    plan = load_scenario(str(out / "plan.toml"))
    Ts_speed = scenario.data["speed_controller"]["Ts_s"]
    # a row per speed sample of the plan, the speed within the plan's largest step
    assert len(capture) == int(np.ceil(plan.data["simulation"]["t_end_s"] / Ts_speed))
    np.testing.assert_allclose(np.diff(capture["time_s"]), Ts_speed)
    w_max = max(abs(e["speed_rpm"]) for e in plan.data["reference"]) * np.pi / 30
    assert np.max(np.abs(capture["speed_radps"])) <= 1.1 * w_max
    # the run leaves the motor at rest (its last step is to zero)
    assert abs(capture["speed_radps"][-1]) < 0.01 * w_max


def cut_when(monkeypatch, relay, condition):
    """Cut the relay at the first poll of the link's status that meets ``condition(link)``; returns what it saw."""
    status = Link.status
    seen = {}

    def status_then_cut(link):
        st = status(link)
        if not seen and condition(link, st):
            seen.update(st)
            relay.cut()
        return st

    monkeypatch.setattr(Link, "status", status_then_cut)
    return seen


def test_a_link_that_drops_mid_commissioning_leaves_the_drive_off(hidden, tmp_path, capsys, monkeypatch):
    """The relay cuts the link as soon as the routine runs: one line, exit status 2, no output folder; the drive's
    watchdog ends the routine (state tripped, power stage off) long before its end, read over a fresh link."""
    scenario, folder = hidden
    Ts = scenario.current_loop.Ts_s
    with serve("host", folder, timeout_ms=CUT_TIMEOUT_MS) as url:
        port = int(url.rpartition(":")[2])
        relay = Relay(port)

        def running(link, st):
            return STATES[read_variable(link, "commission_now")["state"]] == "running" and st["periods"] > 0

        seen = cut_when(monkeypatch, relay, running)
        a2l = str(folder / "virtual_drive_host.a2l")
        try:
            code, text, err = run(["drive", "commission", "--out", str(tmp_path / "c"), "--link",
                                   f"tcp://127.0.0.1:{relay.port}", "--a2l", a2l], capsys)  # fmt: skip
        finally:
            relay.close()
            monkeypatch.undo()
        assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert "dropped" in err and "watchdog" in err and "power stage off" in err
        assert seen and not (tmp_path / "c").exists()
        time.sleep(CUT_WAIT_S)
        with Link(url, a2l) as link:
            now = read_variable(link, "commission_now")
            status = link.status()
    assert STATES[now["state"]] == "tripped" and status["power_on"] == 0, (now, status)
    # ended within the watchdog's timeout (and a poll) of the cut, far from the routine's 3.3 s
    assert now["sample"] * Ts < 1.0 + CUT_TIMEOUT_MS * 1e-3, now


def test_a_link_that_drops_mid_identification_leaves_the_drive_off(hidden, tmp_path, capsys, monkeypatch):
    """The relay cuts the link 200 samples into the plan's run: one line, exit status 2, no output folder; the
    watchdog ramps the reference to zero and switches the power stage off (state tripped)."""
    scenario, folder = hidden
    with serve("host", folder, timeout_ms=CUT_TIMEOUT_MS) as url:
        relay = Relay(int(url.rpartition(":")[2]))
        seen = cut_when(monkeypatch, relay, lambda link, st: st["state"] == "running" and st["sample"] > 200)
        a2l = str(folder / "virtual_drive_host.a2l")
        try:
            code, text, err = run(["drive", "identify", "--out", str(tmp_path / "i"), "--link",
                                   f"tcp://127.0.0.1:{relay.port}", "--a2l", a2l], capsys)  # fmt: skip
        finally:
            relay.close()
            monkeypatch.undo()
        assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert "dropped" in err and "watchdog" in err and "power stage off" in err
        assert seen and not (tmp_path / "i").exists()
        time.sleep(CUT_WAIT_S)
        with Link(url, a2l) as link:
            status = link.status()
    assert status["state"] == "tripped" and status["power_on"] == 0 and status["w_ref_radps"] == 0.0, status
    assert status["trip_sample"] >= seen["sample"] + CUT_TIMEOUT_MS * 1e-3 / scenario.data["speed_controller"]["Ts_s"]
