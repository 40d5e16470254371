"""Runs over the link captured from the firmware's own signals: any drive with the firmware's variables plays them.

The drives are the PC's virtual drive of a scenario (the firmware's foc.c and link.c over the
engine's plant) and the firmware on QEMU's virtual board. Each is known to the tool by an A2L file
that lists the firmware's variables only (written here from the ELF with ``virtual=False``, as for
a board of one's own): no ``vd_trace``, no ``vd_load``, so the run can only come from ``foc_now``.

Truth from outside the code under test:

- the virtual board's trace of the plant's true speed (``vd_trace``, read over the full A2L of the
  same drive, whose runs are deterministic): the drive's measured speed differs from it by the
  encoder's resolution and the difference estimator's averaging alone. With ``counts_per_rev`` N and
  the speed period Ts, the estimate is a whole number of counts per period, w_res = 2 pi / (N Ts)
  (encoder.h), and the mean speed over the last period, which is within a_max Ts / 2 of the speed
  at its end; a_max = (1.5 p psi_f i_max + |T_load|) / J bounds the acceleration (eq 1, 2).
- the engine's simulation of the same scenario, and its sensor's reading (``speed_meas_rpm``).
- the paper's experiment 3 simulated from its steady state, for the pre-roll of ``reproduce --link URL``.
"""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.drive.a2l import write_firmware_a2l
from pmsm2dof.drive.serve import serve_host, serve_qemu
from pmsm2dof.drive.session import open_link
from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import RPM_PER_RADPS, Simulation, simulate
from pmsm2dof.studies import paper_drive
from pmsm2dof.studies.drive import plan_run, run_on_drive
from pmsm2dof.studies.firmware import AGREEMENT, build_firmware, play_scenario
from pmsm2dof.studies.paper_drive import DRIVE_RUNS, STEADY_SHARE, pre_roll, run_on_drives
from pmsm2dof.ui.cli import main
from pmsm2dof.ui.report.drive import drive_blocks

pytest.importorskip("pyxcp")
ROOT = Path(__file__).resolve().parents[1]
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"
#: The small servo with an incremental encoder and the difference estimator: a reading coarse enough to tell apart.
COUNTS_PER_REV = 10000
ENCODER = {"speed_sensor.model": "encoder", "speed_sensor.counts_per_rev": COUNTS_PER_REV}
_MISSING = [t for t in ("cmake", "cc") if shutil.which(t) is None]
_MISSING_MCU = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]
needs_build = pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)")
#: The drives' link watchdog [ms]: a master starved of the CPU by other work must not trip it.
TIMEOUT_MS = 2000


def firmware_only_a2l(folder, scenario, elf="virtual_drive_host", baud=None):
    """An A2L of the build's ELF listing the firmware's variables only (a board's, not the virtual board's)."""
    firmware = ROOT / "examples" / "firmware"
    sources = [*sorted(firmware.glob("*.h")), *sorted((ROOT / "csrc" / "include" / "pmsm2dof").glob("*.h"))]
    path = Path(folder) / f"{Path(elf).stem}-board.a2l"
    per_speed = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    write_firmware_a2l(Path(folder) / elf, path, sources=sources, virtual=False,
                       Ts_current_s=scenario.current_loop.Ts_s, current_per_speed=per_speed, tcp_port=5555,
                       sxi_baud=baud)  # fmt: skip
    return path


@pytest.fixture(scope="module")
def encoder_drive(tmp_path_factory):
    """The small servo with an encoder, its PC virtual drive built and served for the module."""
    if _MISSING:
        pytest.skip("cmake or cc not installed")
    scenario = load_scenario(str(SERVO)).with_overrides(ENCODER)
    folder = build_firmware(scenario, tmp_path_factory.mktemp("enc") / "fw", mcu=False).folder
    with serve_host(folder / "virtual_drive_host", realtime=False, timeout_ms=TIMEOUT_MS) as url:
        yield scenario, folder, url, firmware_only_a2l(folder, scenario)


@needs_build
def test_a_drive_without_the_virtual_board_runs_and_its_figures_are_of_its_measured_speed(encoder_drive):
    scenario, folder, url, board_a2l = encoder_drive
    with open_link(url, board_a2l) as link:
        assert "vd_trace" not in link.variables and "vd_load" not in link.variables
        daq = run_on_drive(link, scenario)
        buffered = run_on_drive(link, scenario, way="buffer")
    with open_link(url, folder / "virtual_drive_host.a2l") as link:
        truth = play_scenario(link, scenario)  # the plant's true state, by the virtual board's trace
    assert daq.plan.way == "daq" and buffered.plan.way == "buffer"
    # the two ways capture the same samples of the same (deterministic) run
    for name in ("speed_rpm", "speed_ref_rpm", "id_A", "iq_A", "iq_ref_A", "saturated"):
        assert np.array_equal(getattr(daq.drive, name), getattr(buffered.drive, name)), name
    # the speed is the encoder's reading: a whole number of counts per period, which the true speed is not
    Ts = scenario.speed_controller.Ts_s
    w_res = 2.0 * math.pi / (COUNTS_PER_REV * Ts)
    counts = daq.drive.w_m_radps / w_res
    assert np.max(np.abs(counts - np.round(counts))) < 1e-4
    true_counts = truth.w_m_radps / w_res
    assert np.median(np.abs(true_counts - np.round(true_counts))) > 0.1
    # ... within the sensor's resolution and half a period of the largest acceleration of the true speed
    m, load = scenario.motor, max(abs(e.torque_Nm) for e in scenario.load)
    a_max = (1.5 * m.pole_pairs * m.psi_f_Wb * scenario.limits.i_max_A + load) / m.J_kgm2
    bound = w_res + a_max * Ts / 2.0
    difference = np.abs(daq.drive.w_m_radps - truth.w_m_radps)
    assert np.max(difference) <= bound
    assert np.max(difference) > 0.25 * bound  # the bound is not loose by orders of magnitude
    # reading against reading, the drive is the engine's run (its sensor the same estimator, in float32)
    c = daq.comparison()
    assert c["agrees"] and c["speed"]["relative_to_step"] <= AGREEMENT
    assert c["signals"]["ud_V"]["max_abs_difference"] is None  # not measured, not compared
    # the figures are those of the measured speed: the overshoot of the first step by hand from the reading
    step = scenario.reference[0].speed_rpm
    first = daq.drive.t_s < scenario.reference[1].t_s
    overshoot = compute_metrics(daq.drive)["reference_steps"][0]["overshoot_pct"]["value"]
    assert overshoot == pytest.approx(100.0 * (np.max(daq.drive.speed_rpm[first]) - step) / step, rel=1e-12)


@needs_build
def test_drive_run_on_a_board_a2l_and_a_run_the_link_cannot_carry(encoder_drive, tmp_path, capsys):
    scenario, folder, url, board_a2l = encoder_drive
    sets = ["--set", "speed_sensor.model=encoder", "--set", f"speed_sensor.counts_per_rev={COUNTS_PER_REV}"]
    link = ["--link", url.replace("socket://", "tcp://"), "--a2l", str(board_a2l)]
    assert main(["drive", "run", str(SERVO), *sets, "--out", str(tmp_path / "run"), *link]) == 0
    out, err = capsys.readouterr()
    assert (tmp_path / "run" / "trace.csv").is_file(), err
    # a run longer than the buffer holds, on a link as slow as a UART: refused before it starts, naming the key
    with open_link(url, board_a2l) as drive:
        plan = plan_run(drive, 10, link_bytes_per_s=11520.0)
        assert plan.way == "buffer" and "DAQ would need" in plan.why
        with pytest.raises(ConfigError) as refused:
            plan_run(drive, plan.buffer_samples + 1, link_bytes_per_s=11520.0)
        assert refused.value.param == "simulation.t_end_s"


@needs_build
def test_the_tuners_drive_mode_runs_a_drive_known_by_its_board_a2l(encoder_drive):
    """The tuner's run (its session, its computations; the page is tests/test_tuner_drive.py's) on a board's A2L."""
    pytest.importorskip("starlette")
    from pmsm2dof.ui.tuner import drive_session
    from pmsm2dof.ui.tuner.controls import initial_values
    from pmsm2dof.ui.tuner.drive import DriveMode
    from pmsm2dof.ui.tuner.experiment import Tuner

    scenario, folder, url, board_a2l = encoder_drive
    with drive_session(scenario, url, board_a2l) as session:
        mode = DriveMode(Tuner(scenario), session)
        assert mode.describe()["virtual"] is False
        session.arm("page")
        shown = mode.run(initial_values(scenario), "page")
    assert "streamed by DAQ" in shown["capture"]
    # the drive's reading against the twin's sensor: the same encoder and estimator in float32
    assert shown["comparison"]["agrees"], shown["comparison"]
    dip = {r["key"]: r for r in shown["metrics"]}
    rows = [r for r in dip.values() if r["drive"] is not None and r["twin"] is not None]
    assert rows and all(r["drive"] == pytest.approx(r["twin"], rel=1e-3, abs=1e-6) for r in rows), rows


@pytest.mark.parametrize(
    "argv, option",
    [
        (["drive", "info", "--link", "tcp://192.0.2.1:5555", "--a2l", "x.a2l"], "--link"),
        (["drive", "get", "speed_controller.zeta", "--link", "tcp://127.0.0.1:0", "--a2l", "x.a2l"], "--link"),
        (["drive", "set", "speed_controller.zeta=1", "--link", "tcp://127.0.0.1:99999", "--a2l", "x.a2l"], "--link"),
        (
            [
                "drive",
                "capture",
                "foc_now.iq_A",
                "--duration-s",
                "1",
                "--out",
                "c.csv",
                "--link",
                "tcp://127.0.0.1:5555",
                "--a2l",
                "x.txt",
            ],
            "--a2l",
        ),  # fmt: skip
        (
            ["drive", "run", "paper-experiment-1", "--out", "r", "--link", "tcp://127.0.0.1:5555", "--a2l", "x.txt"],
            "--a2l",
        ),  # fmt: skip
        (["drive", "commission", "--out", "c", "--link", "tcp://127.0.0.1:5555", "--a2l", "x.txt"], "--a2l"),
        (["drive", "identify", "--out", "i", "--link", "tcp://192.0.2.1:5555", "--a2l", "x.a2l"], "--link"),
        (["reproduce", "--out", "rep", "--link", "tcp://127.0.0.1:5555"], "--a2l"),
        (["reproduce", "--out", "rep", "--link", "virtual", "--a2l", "x.a2l"], "--a2l"),
        (["reproduce", "--out", "rep", "--link", "tcp://192.0.2.1:5555", "--a2l", "x.a2l"], "--link"),
    ],
)
def test_errors_of_the_link_name_the_options_the_user_typed(argv, option, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"pmsm2dof: error: {option} "), err
    assert not any(tmp_path.iterdir())


def test_the_pre_roll_brings_experiment_3_to_its_steady_start():
    e3 = load_scenario("paper-experiment-3")
    played, n_pre = pre_roll(e3)
    Ts = e3.speed_controller.Ts_s
    assert played.simulation.speed0_rpm == 0.0 and n_pre > 0
    assert [e.t_s for e in played.load] == [pytest.approx(e.t_s + n_pre * Ts, abs=1e-12) for e in e3.load]
    # the engine from rest through the pre-roll: at its end within STEADY_SHARE of 500 rpm, and the recorded
    # part's load dip that of the run started steady (a linear loop: the residue adds at most its size)
    sim = Simulation(played)
    sim.advance(sim.n_samples)
    r = sim.result(played, 0.0)
    w0 = e3.simulation.speed0_rpm
    assert abs(r.speed_rpm[n_pre] - w0) <= STEADY_SHARE * w0
    steady = Simulation(e3)
    steady.advance(steady.n_samples)
    s = steady.result(e3, 0.0)
    assert len(r.t_s) - n_pre == len(s.t_s)
    assert np.max(np.abs(r.speed_rpm[n_pre:] - s.speed_rpm)) <= STEADY_SHARE * w0
    # a condition at rest needs none
    assert pre_roll(load_scenario("paper-experiment-1"))[1] == 0


@pytest.fixture(scope="module")
def paper_drive_served(tmp_path_factory):
    """One PC virtual drive of the paper's motor (experiment 1's build), known by a board's A2L."""
    if _MISSING:
        pytest.skip("cmake or cc not installed")
    base = load_scenario("paper-experiment-1")
    folder = build_firmware(base, tmp_path_factory.mktemp("paper") / "fw", mcu=False).folder
    with serve_host(folder / "virtual_drive_host", realtime=False, timeout_ms=TIMEOUT_MS) as url:
        yield url.replace("socket://", "tcp://"), folder


@pytest.mark.slow
@needs_build
def test_the_experiments_on_one_drive_at_a_url(paper_drive_served, monkeypatch):
    url, folder = paper_drive_served
    bases = {p: load_scenario(p) for p in ("paper-experiment-1", "paper-experiment-2", "paper-experiment-3")}
    lines = []
    drive = run_on_drives(bases, url, report=lines.append, a2l=folder / "virtual_drive_host.a2l")
    assert len(lines) == len(DRIVE_RUNS)
    for name in DRIVE_RUNS:
        pre = drive.pre_roll_s[name]
        assert (pre > 0.0) == name.startswith("e3"), (name, pre)
        played = drive.results[name]
        scenario = played.scenario
        sim = Simulation(scenario)
        sim.advance(sim.n_samples)
        engine = sim.result(scenario, 0.0)
        w_step = max(np.ptp(engine.speed_rpm), np.ptp(engine.speed_ref_rpm), abs(scenario.simulation.speed0_rpm))
        # from rest: the engine's run to float32; after a pre-roll: within its steady tolerance of the steady start
        tolerance = STEADY_SHARE * scenario.simulation.speed0_rpm if pre else AGREEMENT * w_step
        assert np.max(np.abs(played.speed_rpm - engine.speed_rpm)) <= tolerance, name
        ours, theirs = drive.metrics[name], compute_metrics(engine)
        if theirs["reference_steps"][0]["overshoot_pct"]["value"] is not None:
            o = ours["reference_steps"][0]["overshoot_pct"]["value"]
            assert o == pytest.approx(theirs["reference_steps"][0]["overshoot_pct"]["value"], rel=1e-4), name
        for mine, engine_step in zip(ours["load_steps"], theirs["load_steps"]):
            assert abs(mine["speed_dip_rpm"]["value"] - engine_step["speed_dip_rpm"]["value"]) <= tolerance, name
    assert drive.pre_roll_s["e3-1dof"] > 10.0  # the paper's slow loop (alpha = 0.5 rad/s) takes its time to settle
    # the report's table holds each run's pre-roll, and names the drive at its URL
    engine_metrics = {n: compute_metrics(simulate(drive.results[n].scenario)) for n in DRIVE_RUNS}
    (_, title), (_, text), (_, header, rows) = drive_blocks(drive, engine_metrics)
    column = header.index("pre-roll [s]")
    assert {r[0]: float(r[column]) for r in rows} == pytest.approx(drive.pre_roll_s)
    assert url in text and "pre-roll" in text
    # a recorded part that would start before the drive is steady (here: during the pre-roll's ramp) is refused
    whole = paper_drive.pre_roll
    monkeypatch.setattr(paper_drive, "pre_roll", lambda scenario: (whole(scenario)[0], whole(scenario)[1] // 8))
    with pytest.raises(SimulationError, match="not steady at 500 rpm"):
        run_on_drives(bases, url, runs=("e3-2dof",), a2l=folder / "virtual_drive_host.a2l")


@needs_build
def test_a_drive_that_is_not_the_papers_is_refused_naming_the_field(encoder_drive):
    scenario, folder, url, board_a2l = encoder_drive
    bases = {p: load_scenario(p) for p in ("paper-experiment-1", "paper-experiment-3")}
    with pytest.raises(ConfigError) as refused:
        run_on_drives(bases, url.replace("socket://", "tcp://"), runs=("e3-1dof",), a2l=board_a2l)
    assert refused.value.param == "link_speed_config.J_kgm2"
    assert refused.value.value == pytest.approx(scenario.motor.J_kgm2, rel=1e-6)


@pytest.mark.slow
@pytest.mark.skipif(bool(_MISSING_MCU), reason=f"{', '.join(_MISSING_MCU)} not installed")
def test_a_run_on_qemu_by_its_board_a2l_over_a_uart(tmp_path):
    """The firmware on QEMU, a serial link (a UART's rate: the run goes to the drive's capture buffer)."""
    scenario = load_scenario(str(SERVO)).with_overrides({"simulation.t_end_s": 0.15})
    folder = build_firmware(scenario, tmp_path / "fw").folder
    a2l = firmware_only_a2l(folder, scenario, "virtual_drive.elf", baud=115200)
    with serve_qemu(folder / "virtual_drive.elf", serial="pty", timeout_ms=TIMEOUT_MS) as device:
        with open_link(f"serial:{device}", a2l) as link:
            played = run_on_drive(link, scenario)
    assert played.plan.way == "buffer"
    c = played.comparison()
    assert c["agrees"], c
    sim = Simulation(scenario)
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, 0.0)
    step = max(np.ptp(engine.w_m_radps), np.ptp(engine.speed_ref_rpm) / RPM_PER_RADPS)
    assert np.max(np.abs(played.drive.w_m_radps - engine.w_m_radps)) <= AGREEMENT * step
