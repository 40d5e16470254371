"""`pmsm2dof drive identify --electrical` on the PC's virtual drive and on QEMU, against a hidden salient motor.

The drive is a build of the small servo (20 kHz current, 2 kHz speed loop) whose motor the host
never reads: salient (Lq 1.5 Ld), its values 10 to 20 % off the servo's, heavier than its speed
controller's design, with friction and a load torque from t = 0 in its scenario. Before the
identification its controllers are told other motor data (`drive set`, a wrong datasheet), from
which the host plans the current steps. The command sees the link and the A2L file only.

Truth from outside the code under test: the scenario that built the drive (its motor's values), and
the engine's run of the same plan: the engine's plant (csrc/sim/plant.h, the motor of eq 1 by RK4)
under the library's current controller configured as the drive's, the plan's steps played by this
file's own reading of identify_task.h (a step ends after its time or at its speed), logged at every
current period without the capture's windows and fitted by the same ``identify_electrical``: the
accuracy the fit reaches with this plan. The drive must reach it (within a margin for its windows:
the plays' seams leave out GAP_SAMPLES periods each) and the targets of ``identify electrical``.
"""

import dataclasses
import json
import shutil
import socket
import time

import numpy as np
import pandas as pd
import pytest
from test_drive_bench import CUT_TIMEOUT_MS, CUT_WAIT_S, link_args, run, serve
from test_drive_cli import Relay
from test_identify_electrical import TARGETS

from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.drive.link import Link
from pmsm2dof.drive.session import read_variable
from pmsm2dof.sim.commission import commissioning_config
from pmsm2dof.sim.logs import read_log
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies import drive_electrical
from pmsm2dof.studies.configuration import configuration
from pmsm2dof.studies.drive_commission import STATES as COMMISSION_STATES
from pmsm2dof.studies.drive_commission import drive_scenario
from pmsm2dof.studies.drive_electrical import STATES, plan_electrical
from pmsm2dof.studies.electrical import PARAMETERS, identify_electrical
from pmsm2dof.studies.firmware import build_firmware

pytest.importorskip("pyxcp")
_MISSING = [t for t in ("cmake", "cc", "arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]

#: Slow (firmware builds, QEMU): the full suite.
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]

#: The hidden motor: salient, off the servo's values, heavier than the design, with friction, loaded from t = 0.
HIDDEN = {"motor.Rs_ohm": 0.45, "motor.Ld_H": 4.5e-4, "motor.Lq_H": 6.75e-4, "motor.psi_f_Wb": 0.011,
          "motor.J_kgm2": 1.3e-4, "speed_controller.J_kgm2": 1e-4, "motor.B_Nms": 2e-5, "motor.T_coulomb_Nm": 0.004,
          "load": [{"t_s": 0.0, "torque_Nm": 0.05}]}  # fmt: skip
#: What the drive's controllers are told of the motor before the identification (a wrong datasheet).
DATASHEET = {"Rs_ohm": 0.7, "Ld_H": 6e-4, "Lq_H": 7e-4, "psi_f_Wb": 0.012}
#: The drive's relative error may exceed the engine's by this much (its log is windows of separate plays).
MARGIN = 2e-3


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    """The hidden motor's scenario and its firmware for the PC and QEMU."""
    scenario = load_scenario("examples/firmware/small-servo-20k.toml").with_overrides(HIDDEN)
    return scenario, build_firmware(scenario, tmp_path_factory.mktemp("hidden") / "fw").folder


def engine_fit(scenario, plan, path):
    """The engine's run of ``plan`` (module docstring) against the scenario's motor, at rest, without load,
    the current controller configured with DATASHEET; its log at every current period, fitted."""
    told = configuration(scenario.with_overrides({f"motor.{k}": v for k, v in DATASHEET.items()}))
    cfg = configuration(scenario).engine.cfg
    plant_cfg = ffi.new("p2d_plant_config_t *")
    plant_cfg.motor, plant_cfg.mechanics, plant_cfg.u_dc_V = cfg.motor, cfg.mechanics, cfg.u_dc_V
    plant_cfg.Ts_s, plant_cfg.substeps = cfg.Ts_current_s, cfg.substeps
    plant = ffi.new("p2d_plant_t *")
    ctl = ffi.new("p2d_current_t *")
    assert lib.p2d_plant_init(plant, plant_cfg) == 0
    assert lib.p2d_current_init(ctl, ffi.addressof(told.engine.cfg, "current")) == 0
    out, io = ffi.new("p2d_current_output_t *"), ffi.new("p2d_inverter_output_t *")
    p, Ts, u_dc = cfg.motor.pole_pairs, plan.Ts_s, cfg.u_dc_V
    rows, k, start, n = [], 0, 0, 0
    while True:
        w = plant.w_m_radps
        s = plan.steps[k]
        if n - start >= round(s.t_s / Ts) or (s.iq_A > 0 and w >= s.w_end_radps) or (s.iq_A < 0 and w <= s.w_end_radps):
            k, start = k + 1, n
            if k == len(plan.steps):
                break
            s = plan.steps[k]
        lib.p2d_current_compute(ctl, s.id_A, s.iq_A, plant.id_A, plant.iq_A, p * w, u_dc, out)
        lib.p2d_current_update(ctl, out, out.ud_ref_V, out.uq_ref_V)
        rows.append((n * Ts, w, plant.id_A, plant.iq_A, out.ud_ref_V, out.uq_ref_V))
        lib.p2d_plant_step(plant, out.ud_ref_V, out.uq_ref_V, 0.0, io)
        n += 1
    columns = ["time_s", "speed_radps", "id_A", "iq_A", "ud_V", "uq_V"]
    pd.DataFrame(rows, columns=columns).to_csv(path, index=False)
    return identify_electrical(read_log(path), p, u_dc_V=u_dc)


@pytest.mark.parametrize("kind", ["host", "qemu"])
def test_electrical_over_the_link_reaches_the_engines_accuracy(hidden, kind, tmp_path, capsys):
    scenario, folder = hidden
    out = tmp_path / "identified"
    with serve(kind, folder) as url:
        link = link_args(kind, folder, url)
        told = [f"current_loop.{k}={v}" for k, v in DATASHEET.items()]
        assert run(["drive", "set", *told, *link], capsys)[0] == 0
        with Link(url, link[3]) as session:
            plan = plan_electrical(drive_scenario(session))
        start = time.perf_counter()
        code, text, err = run(["drive", "identify", "--electrical", "--out", str(out), *link], capsys)
        wall_s = time.perf_counter() - start
    assert code == 0, text + err
    assert {p.name for p in out.iterdir()} >= {"capture.csv", "plan.json", "fit.png", "residuals.csv", "motor.toml",
                                               "identify.json"}  # fmt: skip
    # the plan the command played is the one planned from the drive's configuration here
    assert json.loads((out / "plan.json").read_text())["steps"] == [s.to_json() for s in plan.steps]
    drive = json.loads((out / "identify.json").read_text())
    engine = engine_fit(scenario, plan, tmp_path / "engine.csv")
    motor = scenario.motor
    print(f"\n  {kind}: {wall_s:.1f} s wall")
    for key in PARAMETERS:
        true = getattr(motor, key)
        e_drive, e_engine = drive[key] / true - 1.0, getattr(engine, key) / true - 1.0
        print(f"  {key}: drive {drive[key]:.7g} ({e_drive:+.2e}), engine {getattr(engine, key):.7g} "
              f"({e_engine:+.2e}), true {true:.7g}")  # fmt: skip
        assert abs(e_drive) <= min(TARGETS[key], abs(e_engine) + MARGIN), key
    # the board's load is off between runs: the rotor stands under the d-axis steps (iq = 0; the scenario's load
    # of 0.05 Nm would turn it at 0.05 / 1.3e-4 = 385 rad/s^2, 15 rad/s after them)
    capture = pd.read_csv(out / "capture.csv")
    at_rest = capture["time_s"] < 4 * plan.steps[0].t_s
    assert capture["speed_radps"][at_rest].abs().max() < 1e-3
    assert np.ptp(capture["id_A"][at_rest]) > 1.9 * plan.i_A
    text = (out / "motor.toml").read_text()
    assert f"Ld_H = {drive['Ld_H']!r}" in text and "pole_pairs = 4" in text


def test_a_link_that_drops_mid_identification_leaves_the_drive_off(hidden, tmp_path, capsys, monkeypatch):
    """The relay cuts the link when the current steps run: one line, exit status 2, no output folder; the drive's
    watchdog ends the routine (state tripped, power stage off), read over a fresh link."""
    scenario, folder = hidden
    with serve("host", folder, timeout_ms=CUT_TIMEOUT_MS) as url:
        relay = Relay(int(url.rpartition(":")[2]))
        capture_status = Link._capture_status
        seen = {}

        def capture_status_then_cut(link):
            # the command polls the capture buffer's status while the steps run: cut 400 periods into a play
            st = capture_status(link)
            now = read_variable(link, "identify_now")
            if not seen and STATES[now["state"]] == "running" and now["sample"] > 400:
                seen.update(now)
                relay.cut()
            return st

        monkeypatch.setattr(Link, "_capture_status", capture_status_then_cut)
        a2l = str(folder / "virtual_drive_host.a2l")
        try:
            code, text, err = run(["drive", "identify", "--electrical", "--out", str(tmp_path / "e"), "--link",
                                   f"tcp://127.0.0.1:{relay.port}", "--a2l", a2l], capsys)  # fmt: skip
        finally:
            relay.close()
            monkeypatch.undo()
        assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
        assert "dropped" in err and "watchdog" in err and "power stage off" in err
        assert seen and not (tmp_path / "e").exists()
        time.sleep(CUT_WAIT_S)
        with Link(url, a2l) as link:
            now = read_variable(link, "identify_now")
            status = link.status()
    assert STATES[now["state"]] == "tripped" and status["power_on"] == 0, (now, status)


def _start_identification(link):
    """A plan of one long d-axis step (5 s at 1 A) started by this master."""
    link.write({"identify_config.n": 1, "identify_config.i_trip_A": 5.0, "identify_config.w_trip_radps": 100.0,
                "identify_config.id_A": [1.0], "identify_config.iq_A": [0.0], "identify_config.t_s": [5.0],
                "identify_config.w_end_radps": [0.0]})  # fmt: skip
    link.write({"identify_command.command": 1})
    return "identify_now", STATES


def _start_commissioning(link):
    """The commissioning (some 3 s of the drive's time) started by this master."""
    config = commissioning_config(drive_scenario(link))
    config.pop("voltage_delay_samples")
    link.write({f"commission_config.{k}": v for k, v in config.items()})
    link.write({"commission_command.command": 1})
    return "commission_now", COMMISSION_STATES


@pytest.mark.parametrize("routine", [_start_identification, _start_commissioning], ids=["identify", "commission"])
def test_only_the_master_of_a_routine_feeds_its_watchdog(hidden, routine):
    """The master that started a routine is cut off (its socket shut, no DISCONNECT); a second master connects at
    once and reads all along: the routine still trips, about the link timeout after the first master's last
    command (a second master cannot keep alive a routine it did not start)."""
    scenario, folder = hidden
    Ts = scenario.current_loop.Ts_s
    with serve("host", folder, timeout_ms=CUT_TIMEOUT_MS) as url:
        a2l = folder / "virtual_drive_host.a2l"
        first = Link(url, a2l).__enter__()
        variable, states = routine(first)
        deadline = time.monotonic() + 30.0
        while states[(last := read_variable(first, variable))["state"]] != "running":
            assert time.monotonic() < deadline
        first.master.transport.sock.shutdown(socket.SHUT_RDWR)
        first._master = None  # abandoned, as by a master that crashed
        with Link(url, a2l) as second:
            deadline = time.monotonic() + 60.0
            while states[(now := read_variable(second, variable))["state"]] == "running":
                assert time.monotonic() < deadline
                time.sleep(0.005)
            status = second.status()
    assert states[now["state"]] == "tripped" and status["power_on"] == 0, now
    # the trip came the timeout after the first master's last read (and the drive's run-on until the cut reached
    # it: a few hundred periods), far from the routine's end (5 s; the commissioning's 3 s)
    assert CUT_TIMEOUT_MS * 1e-3 / Ts <= now["sample"] - last["sample"] <= CUT_TIMEOUT_MS * 1e-3 / Ts + 4000, now


def test_a_trip_of_the_routine_is_reported_in_one_line_nothing_written(hidden, tmp_path, capsys, monkeypatch):
    """A plan whose speed trip lies below its top speed: the routine ends failed at the trip, power off; the command
    says so in one line naming the reason, exit status 2, no output folder."""
    planned = drive_electrical.plan_electrical

    def tripping(drive, speed_max_rpm=None):
        plan = planned(drive, speed_max_rpm)
        return dataclasses.replace(plan, w_trip_radps=0.5 * plan.w_high_radps)

    monkeypatch.setattr(drive_electrical, "plan_electrical", tripping)
    scenario, folder = hidden
    with serve("host", folder) as url:
        link = link_args("host", folder, url)
        code, text, err = run(["drive", "identify", "--electrical", "--out", str(tmp_path / "e"), *link], capsys)
        with Link(url, link[3]) as session:
            now = read_variable(session, "identify_now")
            status = session.status()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert "ended failed (the speed exceeded w_trip_radps)" in err and "power stage is off" in err, err
    assert not (tmp_path / "e").exists()
    assert STATES[now["state"]] == "failed" and now["reason"] == 2 and status["power_on"] == 0
