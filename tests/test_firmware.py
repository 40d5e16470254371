"""The firmware of examples/firmware runs closed loop on the emulated MCU and equals the engine.

foc.c on the virtual board (board_virtual.c: the engine's plant, csrc/sim/plant.c, compiled for the
Cortex-M4F) runs on QEMU (mps2-an386, -icount) for a scenario; its trace must equal the engine's
simulation of the same scenario within 1e-4 of the step on the speed and the currents (the truth is
the engine, an independent loop: it hands its controllers the dq currents, where the firmware
samples phase currents and turns them with float32 transforms, and takes their dq voltage, where the
firmware writes duty cycles). Checked for the paper's experiments 1 and 3, for a small servo at
20 kHz / 2 kHz, for every loop ratio from 1 to 20, for the header every command writes, and for the
same firmware built for the PC. A configuration the firmware rejects, or an inconsistent loop ratio,
is reported (a build error naming the values, or the diagnostic line and exit status 1), never a
silent hang. The instructions per interrupt the firmware counts equal those of QEMU's instruction
trace (benchmarks/footprint.py's method).

One cross build (CMake) serves every case: the headers in its configuration folder are rewritten
and only the firmware's own files recompile.
"""

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.analysis.design import design
from pmsm2dof.errors import SimulationError, ToolError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Result, simulate
from pmsm2dof.studies.configuration import configuration, design_scenario
from pmsm2dof.studies.firmware import QEMU, read_trace, run_firmware
from pmsm2dof.studies.virtual_drive import virtual_drive_header
from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "examples" / "firmware"
TOOLCHAIN = ROOT / "csrc" / "cmake" / "arm-none-eabi-cortex-m4f.cmake"
SERVO = FIRMWARE / "small-servo-20k.toml"
EVERY_PART = FIRMWARE / "small-servo-every-part.toml"
#: A short run of a scenario: 50 ms from a step to 2000 rpm.
RUN = {"simulation.t_end_s": 0.05, "reference": [{"t_s": 0.0, "speed_rpm": 2000.0}], "load": []}
BUILD_TIMEOUT_S = 600

_MISSING = [t for t in ("cmake", "arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]


def needs_tools(test):
    """Slow (cross builds and QEMU runs: the full suite), and skipped without the tools."""
    missing = pytest.mark.skipif(
        bool(_MISSING),
        reason=f"{', '.join(_MISSING)} not installed (Debian: cmake gcc-arm-none-eabi libnewlib-arm-none-eabi "
        "qemu-system-arm; scripts/install.sh installs them)",
    )
    return pytest.mark.slow(missing(test))


def run(cmd, timeout=BUILD_TIMEOUT_S, **kwargs):
    done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done


class Bench:
    """One CMake build of examples/firmware whose headers are rewritten for each case."""

    def __init__(self, root, toolchain=TOOLCHAIN):
        self.root = root
        self.config = root / "config"
        self.build_dir = root / "build"
        self.config.mkdir(parents=True)
        self.write(configuration(load_scenario(str(SERVO))))
        args = [f"-DCMAKE_TOOLCHAIN_FILE={toolchain}"] if toolchain else []
        run(["cmake", "-S", FIRMWARE, "-B", self.build_dir, *args, f"-DP2D_CONFIG_DIR={self.config}"])
        self.cases = 0

    def write(self, config, header_text=None):
        """The headers of ``config`` (or the header text given) into the configuration folder."""
        (self.config / "p2d_config.h").write_text(header_text if header_text is not None else config.c_header())
        (self.config / "p2d_virtual_drive.h").write_text(virtual_drive_header(config))

    def build(self, config, header_text=None):
        """A folder as `pmsm2dof firmware` writes it, for ``config`` (run_firmware runs it)."""
        self.write(config, header_text)
        run(["cmake", "--build", self.build_dir, "--target", "virtual_drive", "-j2"])
        self.cases += 1
        folder = self.root / f"case{self.cases}"
        folder.mkdir()
        elf = "virtual_drive.elf" if (self.build_dir / "virtual_drive.elf").exists() else "virtual_drive"
        shutil.copy2(self.build_dir / elf, folder / elf)
        (folder / "scenario.toml").write_text(config.scenario.to_toml())
        return folder


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    if _MISSING:
        pytest.skip(f"{', '.join(_MISSING)} not installed")
    return Bench(tmp_path_factory.mktemp("firmware"))


def firmware_equals_engine(folder, **kwargs):
    """Run the firmware of ``folder``; assert it equals the engine within 1e-4 of the step; return the run."""
    result = run_firmware(folder, **kwargs)
    c = result.comparison()
    print(
        f"\n{result.scenario.name}: speed {c['speed']['max_abs_difference']:.3g} rad/s "
        f"({c['speed']['relative_to_step']:.3g} of {c['speed']['step']:.4g}), currents "
        f"{c['currents']['max_abs_difference']:.3g} A ({c['currents']['relative_to_step']:.3g} of "
        f"{c['currents']['step']:.4g}), QEMU {result.wall_time_s:.2f} s"
    )
    assert c["speed"]["relative_to_step"] <= 1e-4 and c["currents"]["relative_to_step"] <= 1e-4, c
    assert c["agrees"]
    np.testing.assert_array_equal(result.firmware.t_s, result.engine.t_s)
    return result


@needs_tools
def test_paper_experiment_1(bench):
    """The 500 rpm step at 0.5 s, 0.3 s of it: the current limit and the anti-windup at work."""
    scenario = load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": 0.8})
    result = firmware_equals_engine(bench.build(configuration(scenario)))
    # standing still at zero currents before the step, both are zero to the bit
    signals = result.comparison()["signals"]
    for name in ("w_m_radps", "id_A", "iq_A", "ud_V"):
        assert signals[name]["first_difference_t_s"] >= 0.5, (name, signals[name])
    assert result.engine.saturated[result.engine.t_s > 0.5].all()


@needs_tools
def test_paper_experiment_3(bench):
    """Steady at 500 rpm, the 8 Nm load step at 0.5 s, 0.3 s of the dip."""
    scenario = load_scenario("paper-experiment-3").with_overrides({"simulation.t_end_s": 0.8})
    result = firmware_equals_engine(bench.build(configuration(scenario)))
    assert result.engine.speed_rpm[-1] < 480.0  # the dip is under way


@needs_tools
def test_small_servo_20_kHz_2_kHz(bench):
    """The servo's whole run: limited acceleration, a load step, a step down, at 20 kHz / 2 kHz."""
    result = firmware_equals_engine(bench.build(configuration(load_scenario(str(SERVO)))))
    assert result.engine.saturated.any() and not result.engine.saturated.all()
    ratio = 10
    assert np.array_equal(result.speed_sample, np.arange(len(result.speed_sample)) % ratio == 0)
    assert len(result.speed_sample) == ratio * len(result.firmware.t_s)


@needs_tools
def test_every_part_of_the_configuration(bench):
    """A salient servo (MTPA), an encoder read by the PLL with a low-pass, a notch, field weakening, the
    inertia estimator re-designing the gains: the whole 0.2 s."""
    result = firmware_equals_engine(bench.build(configuration(load_scenario(str(EVERY_PART)))))
    engine = result.engine
    assert (engine.id_ref_A < -0.1).any()  # MTPA and field weakening drive id
    assert engine.J_valid.any() and len(np.unique(engine.J_gains_kgm2)) > 1  # the gains were re-designed
    np.testing.assert_array_equal(result.firmware.J_gains_kgm2 > 0, True)
    assert np.max(np.abs(result.firmware.J_est_kgm2 - engine.J_est_kgm2)) <= 1e-3 * np.max(engine.J_est_kgm2)


@needs_tools
def test_the_drive_train_and_the_sensors_of_the_plant(bench):
    """A two-mass train read on the load side, Coulomb friction, a computation delay, current sensors with
    gain errors, offsets and noise (the same seeded noise as the engine's)."""
    scenario = load_scenario(str(SERVO)).with_overrides(
        {
            **RUN,
            "mechanics.model": "two_mass",
            "mechanics.J_load_kgm2": 5e-5,
            "mechanics.stiffness_Nm_per_rad": 50.0,
            "mechanics.damping_Nms_per_rad": 1e-3,
            "mechanics.feedback": "load",
            "motor.J_kgm2": 5e-5,
            "motor.T_coulomb_Nm": 0.01,
            "inverter.computation_delay": True,
            "current_measurement.gain_error_a": 0.01,
            "current_measurement.offset_b_A": 0.05,
            "current_measurement.noise_A_rms": 0.02,
            "current_measurement.seed": 7,
        }
    )
    result = firmware_equals_engine(bench.build(configuration(scenario)))
    assert not np.array_equal(result.engine.load_speed_rpm, result.engine.speed_rpm)


@needs_tools
@pytest.mark.parametrize("ratio", range(1, 21))
def test_every_loop_ratio_runs(bench, ratio):
    """The servo at 20 kHz with its speed loop every `ratio`-th period: 10 ms from a step to 2000 rpm."""
    scenario = load_scenario(str(SERVO)).with_overrides(
        {"speed_controller.Ts_s": ratio * 5e-5, "simulation.t_end_s": 0.01, "load": [], "reference": RUN["reference"]}
    )
    result = firmware_equals_engine(bench.build(configuration(scenario)))
    n = len(result.speed_sample)
    assert n == ratio * len(result.firmware.t_s)
    assert np.array_equal(result.speed_sample, np.arange(n) % ratio == 0)


@needs_tools
def test_a_rejected_configuration_reports_its_diagnostic(bench):
    config = configuration(load_scenario(str(SERVO)).with_overrides({**RUN, "simulation.t_end_s": 0.001}))
    text = config.c_header()
    bad = text.replace(".alpha_radps = 150.0f,", ".alpha_radps = -1.0f,")
    assert bad != text
    with pytest.raises(ToolError) as exc:
        run_firmware(bench.build(config, bad))
    message = str(exc.value)
    assert "(exit status 1)" in message
    assert "configuration rejected: speed controller (p2d_config_speed): alpha_radps must be" in message
    assert re.search(r"\(p2d_status_t \d+\)", message), message


@needs_tools
def test_the_porting_stub_reports_a_rejected_configuration_on_its_uart(bench):
    """firmware.elf (board_stub.c) writes the diagnostic to the MPS2's UART0, then halts with PWM off."""
    config = configuration(load_scenario(str(SERVO)))
    bench.write(config, config.c_header().replace(".alpha_radps = 150.0f,", ".alpha_radps = -1.0f,"))
    run(["cmake", "--build", bench.build_dir, "--target", "firmware"])
    qemu = subprocess.Popen(
        ["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-kernel", str(bench.build_dir / "firmware.elf")],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        out, _ = qemu.communicate(timeout=5)  # board_halt sleeps for good: QEMU does not end by itself
    except subprocess.TimeoutExpired:
        qemu.kill()
        out, _ = qemu.communicate()
    assert "configuration rejected: speed controller (p2d_config_speed): alpha_radps must be" in out, out


@needs_tools
def test_a_loop_ratio_off_the_periods_is_reported(bench):
    """The speed controller's period edited by hand: the run stops with the loop-rate diagnostic."""
    config = configuration(load_scenario(str(SERVO)).with_overrides({**RUN, "simulation.t_end_s": 0.001}))
    text = config.c_header()
    speed = text.index("p2d_config_speed = {")
    bad = text[:speed] + text[speed:].replace(".Ts_s = 0.0005f,", ".Ts_s = 0.0006f,", 1)
    with pytest.raises(ToolError) as exc:
        run_firmware(bench.build(config, bad))
    assert "loop rates (P2D_CONFIG_CURRENT_PER_SPEED): Ts_s of p2d_config_speed" in str(exc.value)


@needs_tools
@pytest.mark.parametrize(
    "old, new, message",
    [
        (
            "#define P2D_CONFIG_CURRENT_PER_SPEED 10u",
            "#define P2D_CONFIG_CURRENT_PER_SPEED 12u",
            "P2D_CONFIG_TS_SPEED_S = 0.0005f is not P2D_CONFIG_CURRENT_PER_SPEED = 12u times "
            "P2D_CONFIG_TS_CURRENT_S = 5.0e-05f",
        ),
        (
            "#define P2D_CONFIG_CURRENT_PER_SPEED 10u",
            "#define P2D_CONFIG_CURRENT_PER_SPEED 0u",
            "P2D_CONFIG_CURRENT_PER_SPEED = 0u: the speed loop runs every 1 to 1000u current periods",
        ),
    ],
)
def test_an_inconsistent_configuration_fails_the_build_naming_the_values(bench, old, new, message):
    config = configuration(load_scenario(str(SERVO)))
    bench.write(config, config.c_header().replace(old, new))
    done = subprocess.run(
        ["cmake", "--build", bench.build_dir, "--target", "virtual_drive"], capture_output=True, text=True, timeout=600
    )
    assert done.returncode != 0
    assert message in done.stdout + done.stderr, (done.stdout + done.stderr)[-3000:]


@needs_tools
def test_an_interrupt_longer_than_its_period_is_reported(bench):
    """At 1 MHz the control interrupt (hundreds of instructions) cannot fit 1 us of a 113 MIPS core."""
    scenario = load_scenario(str(SERVO)).with_overrides(
        {**RUN, "current_loop.Ts_s": 1e-6, "speed_controller.Ts_s": 1e-5, "simulation.t_end_s": 1e-4}
    )
    with pytest.raises(ToolError) as exc:
        run_firmware(bench.build(configuration(scenario)))
    assert "virtual drive: the control interrupt overran its period Ts_current at t = 0 us" in str(exc.value)


@needs_tools
def test_the_engines_stops_stop_the_firmwares_run(bench):
    """A load of -3 Nm drives the servo past twice its no-load speed: the engine stops there, and so does
    the virtual board, with the engine's reason."""
    scenario = load_scenario(str(SERVO)).with_overrides(
        {**RUN, "load": [{"t_s": 0.0, "torque_Nm": -3.0}], "simulation.t_end_s": 0.1}
    )
    with pytest.raises(SimulationError) as engine:
        simulate(scenario)
    with pytest.raises(SimulationError) as firmware:
        run_firmware(bench.build(configuration(scenario)))
    assert "exceeds twice the no-load speed" in str(engine.value)
    assert "stopped: the speed exceeds twice the no-load speed of the DC link at t = " in str(firmware.value)
    t_engine = float(re.search(r"stopped at t = (\S+) s", str(engine.value)).group(1))
    t_firmware = float(re.search(r"at t = (\d+) us", str(firmware.value)).group(1)) * 1e-6
    assert t_firmware == pytest.approx(t_engine, abs=1e-6)


# ----------------------------------------------------------------------------------------------------
# the header of every command builds into the firmware and runs
# ----------------------------------------------------------------------------------------------------


@needs_tools
def test_the_header_of_pmsm2dof_header_builds_and_runs(bench, tmp_path, capsys):
    header = tmp_path / "p2d_config.h"
    assert main(["header", str(SERVO), "--out", str(header)]) == 0
    config = configuration(load_scenario(str(SERVO)).with_overrides(RUN))
    firmware_equals_engine(bench.build(config, header.read_text()))


@needs_tools
def test_the_header_of_design_builds_and_runs(bench, tmp_path, capsys):
    """design --emit-c-header: the same controllers as the design's scenario, whose engine it equals."""
    header = tmp_path / "p2d_config.h"
    argv = [
        "design",
        "--J-kgm2",
        "1e-4",
        "--alpha-radps",
        "150",
        "--zeta",
        "0.707",
        "--tau-i-s",
        "5e-4",
        "--Ts-s",
        "5e-4",
    ]
    motor = ["--i-max-A", "10", "--pole-pairs", "4", "--psi-f-Wb", "0.01", "--Ld-H", "5e-4", "--Rs-ohm", "0.5"]
    assert main([*argv, *motor, "--Ts-current-s", "5e-5", "--emit-c-header", str(header)]) == 0
    dd = design(1e-4, 150.0, 0.707, tau_i_s=5e-4).discretize(5e-4, "tustin")
    scenario = design_scenario(
        dd, i_max_A=10.0, pole_pairs=4, psi_f_Wb=0.01, Ld_H=5e-4, Lq_H=5e-4, Rs_ohm=0.5, Ts_current_s=5e-5
    ).with_overrides({**RUN, "limits.u_dc_V": 48.0})
    firmware_equals_engine(bench.build(configuration(scenario), header.read_text()))


@needs_tools
def test_the_header_of_autotune_builds_and_runs(bench, tmp_path):
    """autotune --emit-c-header (AutotuneResult.write_c_header): the tuned scenario's controllers."""
    from pmsm2dof.studies.autotune import Spec
    from pmsm2dof.studies.autotune_search import autotune

    base = load_scenario(str(SERVO)).with_overrides({**RUN, "load": [{"t_s": 0.03, "torque_Nm": 0.3}]})
    result = autotune(base, Spec(max_overshoot_pct=10.0, feedforwards=("lowpass",), anti_windups=("back_calculation",)))
    header = result.write_c_header(tmp_path / "p2d_config.h")
    firmware_equals_engine(bench.build(configuration(result.tuned_scenario()), header.read_text()))


@needs_tools
def test_the_header_of_the_tuner_builds_and_runs(bench):
    from pmsm2dof.ui.tuner.experiment import Tuner

    tuner = Tuner(load_scenario(str(SERVO)))
    values = {"speed_controller.alpha_radps": 120.0, "speed_controller.zeta": 0.8}
    name, media_type, text = tuner.download("header.h", values)
    assert (name, media_type) == ("p2d_config.h", "text/x-c")
    scenario = tuner.scenario(values).with_overrides(RUN)
    firmware_equals_engine(bench.build(configuration(scenario), text))


@needs_tools
def test_the_header_of_commission_builds_and_runs(bench, tmp_path, capsys):
    """commission --out: the scenario's controllers for the motor the routine identified."""
    out = tmp_path / "commissioned"
    assert main(["commission", str(SERVO), "--out", str(out)]) == 0
    estimates = json.loads((out / "result.json").read_text())["estimates"]
    identified = load_scenario(str(SERVO)).with_overrides({f"motor.{k}": v for k, v in estimates.items()})
    firmware_equals_engine(
        bench.build(configuration(identified.with_overrides(RUN)), (out / "p2d_config.h").read_text())
    )


# ----------------------------------------------------------------------------------------------------
# the same firmware on the PC; the instructions per interrupt
# ----------------------------------------------------------------------------------------------------


@needs_tools
def test_the_firmware_built_for_the_pc_runs_the_same_loop(bench, tmp_path):
    """virtual_target_host.c: the same foc.c and virtual board compiled by the PC's compiler.

    The float32 controllers and the double plant compute the same bits on both machines (IEEE 754
    +, -, *, /, sqrt; no fused multiply-add); the traces part where newlib and glibc round a sine
    or cosine differently, and stay within float32 rounding of each other after.
    """
    scenario = load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": 0.8})
    config = configuration(scenario)
    qemu = run_firmware(bench.build(config))
    pc = Bench(tmp_path / "pc", toolchain=None)
    folder = pc.build(config)
    run([folder / "virtual_drive"], cwd=folder, timeout=120)
    host = read_trace((folder / "trace.bin").read_bytes())
    current_step = max(np.ptp(qemu.firmware.id_A), np.ptp(qemu.firmware.iq_A))
    for name, step in (("w_m_radps", np.ptp(qemu.firmware.w_m_radps)), ("id_A", current_step), ("iq_A", current_step)):
        mcu = getattr(qemu.firmware, name)
        differ = np.flatnonzero(host[name] != mcu)
        print(f"\n{name}: bit-equal until t = {qemu.firmware.t_s[differ[0]] if len(differ) else None}")
        assert len(differ) == 0 or qemu.firmware.t_s[differ[0]] > 0.5  # the step; before it all is zero
        assert np.max(np.abs(host[name] - mcu)) <= 1e-6 * step
    # the speed controller sees the same speed to the bit for a while after the step
    np.testing.assert_array_equal(host["x_i_Nm"][:550], qemu.firmware.x_i_Nm[:550])


@needs_tools
def test_the_instructions_counted_equal_the_instruction_trace(bench, tmp_path):
    """The firmware's counts against QEMU's log of every executed instruction (-singlestep -d exec)."""
    folder = bench.build(configuration(load_scenario(str(SERVO))))
    elf = folder / "virtual_drive.elf"
    nm = run(["arm-none-eabi-nm", "-S", "--defined-only", elf]).stdout
    funcs = {p[3]: (int(p[0], 16) & ~1, int(p[1], 16)) for p in map(str.split, nm.splitlines()) if len(p) == 4}
    calls, return_site, current, previous = {}, None, None, None
    for line in run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf]).stdout.splitlines():
        head = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if head:
            current = head.group(1)
            calls[current] = set()
            continue
        m = re.match(r"^\s*([0-9a-f]+):\s+(\S+)(.*)$", line)
        if m and current is not None:
            target = re.search(r"<([^>+]+)>", m.group(3))
            if target and m.group(2).startswith(("b", "cb")) and target.group(1) != current:
                calls[current].add(target.group(1))
            # measured_call calls link_isr through a pointer: the instruction after its blx is the return site
            if previous == (current, "blx") and current == "measured_call":
                return_site = int(m.group(1), 16)
            previous = (current, m.group(2))
    # the control interrupt (link_isr: the slave's sections, then foc_isr) and the callbacks the slave calls
    # through pointers (its clock, lock, commit)
    reachable, todo = set(), ["link_isr", "link_clock", "link_lock", "link_unlock", "link_commit"]
    while todo:
        f = todo.pop()
        if f not in reachable:
            reachable.add(f)
            todo.extend(calls.get(f, ()))
    ranges = [f"{funcs[f][0]:#x}+{funcs[f][1]:#x}" for f in sorted(reachable) if funcs.get(f, (0, 0))[1] > 0]
    log = tmp_path / "exec.log"
    args = "enable=on,target=native,arg=virtual_drive,arg=samples=3"
    run(
        [*QEMU, "-singlestep", "-d", "exec,nochain", "-dfilter", ",".join([*ranges, f"{return_site:#x}+2"]), "-D", log]
        + ["-semihosting-config", args, "-kernel", elf.resolve()],
        cwd=tmp_path,
        timeout=300,
    )
    pcs = [
        int(m.group(1), 16) for m in map(re.compile(r"^Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/").match, log.open()) if m
    ]
    traced, i = [], 0
    while funcs["link_isr"][0] in pcs[i:]:
        start = pcs.index(funcs["link_isr"][0], i)
        i = pcs.index(return_site, start)
        traced.append(i - start)
    counted = np.fromfile(tmp_path / "cost.bin", dtype="<u4") & 0x7FFFFFFF
    print(f"\ninstructions per interrupt (speed sample first): {counted.tolist()}")
    assert len(traced) == 30
    # the first interrupt starts the run: board_run_begin initialises the plant with the clock held (the motor
    # takes no firmware time), which the count leaves out and the trace does not
    assert counted[0] < traced[0]
    np.testing.assert_array_equal(counted[1:], traced[1:])


# ----------------------------------------------------------------------------------------------------
# the commands
# ----------------------------------------------------------------------------------------------------


@needs_tools
def test_the_commands_build_run_and_write_the_engines_format(tmp_path, capsys):
    fw, out = tmp_path / "fw", tmp_path / "run"
    argv = ["firmware", str(SERVO), "--set", "simulation.t_end_s=0.05", "--set", "load=[]", "--out", str(fw)]
    argv += ["--set", "reference=[{t_s = 0.0, speed_rpm = 2000.0}]"]
    assert main(argv) == 0, capsys.readouterr().err
    assert {p.name for p in fw.iterdir()} == {
        ".pmsm2dof-outputs.json",
        "scenario.toml",
        "p2d_config.h",
        "p2d_virtual_drive.h",
        "virtual_drive.elf",
        "virtual_drive.map",
        "firmware.elf",
        "firmware.map",
        "firmware.a2l",
        "virtual_drive.a2l",
        "virtual_drive_host",
        "virtual_drive_host.a2l",
    }
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["firmware", "run", str(fw), "--out", str(out), "--force"]) == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "of the step" in printed and "instructions" in printed and "CPU load" in printed
    written = {"trace.csv", "metrics.json", "plot.png", "interrupts.csv"}
    assert {p.name for p in out.iterdir()} == {".pmsm2dof-outputs.json", "notes.txt", *written}
    assert (out / "notes.txt").read_text() == "mine"  # --force writes beside the user's file, and keeps it
    assert set(json.loads((out / ".pmsm2dof-outputs.json").read_text())["files"]) == written
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["comparison"]["agrees"] is True
    assert metrics["interrupts"]["speed"]["interrupts"] == 101
    assert metrics["interrupts"]["current"]["interrupts"] == 909
    header = (out / "trace.csv").read_text().splitlines()[0]
    assert header == ",".join(Result.signals)
    assert (out / "plot.png").read_bytes().startswith(b"\x89PNG")


def test_without_the_tools_the_commands_name_the_debian_package(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    assert main(["firmware", str(SERVO), "--out", str(tmp_path / "fw")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cmake is not installed: install the Debian package cmake" in err
    assert not (tmp_path / "fw").exists()
    fw = tmp_path / "built"
    fw.mkdir()
    (fw / "virtual_drive.elf").write_bytes(b"")
    (fw / "scenario.toml").write_text(load_scenario(str(SERVO)).to_toml())
    assert main(["firmware", "run", str(fw), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1 and "qemu-system-arm is not installed: install the Debian package qemu-system-arm" in err
    )
    assert not (tmp_path / "run").exists()


def test_the_firmware_folders_are_outputs_refused_over_other_files(tmp_path, capsys):
    """Both folders of `pmsm2dof firmware` are command outputs: a folder holding a file of the user's
    is refused before any build or run, naming the file, and left as it was."""
    fw = tmp_path / "built"
    fw.mkdir()
    (fw / "virtual_drive.elf").write_bytes(b"")
    (fw / "scenario.toml").write_text(load_scenario(str(SERVO)).to_toml())
    for argv, folder in (
        (["firmware", str(SERVO), "--out", str(fw)], fw),  # a folder not written by pmsm2dof firmware
        (["firmware", "run", str(fw), "--out", str(tmp_path / "run")], tmp_path / "run"),
    ):
        folder.mkdir(exist_ok=True)
        (folder / "notes.txt").write_text("mine")
        before = sorted(p.name for p in folder.iterdir())
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--out" in err and "notes.txt" in err and "--force" in err, err
        assert sorted(p.name for p in folder.iterdir()) == before
        assert (folder / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["built", "run"]  # no staging folder left


@needs_tools
def test_the_readme_firmware_commands_run_as_written(tmp_path, monkeypatch, capsys):
    from test_readme_commands import readme_commands

    commands = [a for a in readme_commands("pmsm2dof") if a[0] == "firmware"]
    assert [a[1] for a in commands] == ["paper-experiment-1", "run"]
    monkeypatch.chdir(tmp_path)
    for args in commands:
        assert main(args) == 0, capsys.readouterr().err
    out = tmp_path / commands[1][commands[1].index("--out") + 1]
    assert json.loads((out / "metrics.json").read_text())["comparison"]["agrees"] is True
