"""One configuration for every header (pmsm2dof.studies.configuration).

The header of a scenario, compiled by the PC's C compiler, holds to the bit the configuration the
engine runs on that scenario (read back from the engine's own C structs through cffi, the truth);
every command writes the same shape; what the C library or the virtual board cannot take is
refused naming the scenario key.
"""

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.core.bindings import ffi
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.studies.configuration import configuration
from pmsm2dof.studies.virtual_drive import check_virtual_drive
from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
GCC = shutil.which("gcc")
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"

SCENARIOS = {
    "paper-experiment-1": lambda: load_scenario("paper-experiment-1"),
    "field-weakening": lambda: load_scenario("field-weakening"),
    "servo, every part": lambda: load_scenario(str(SERVO.parent / "small-servo-every-part.toml")),
    "paper condition 2, Ka given": lambda: load_scenario("paper-condition-2").with_overrides(
        {"speed_controller.Ka": 3.0}
    ),
}

DUMP = """\
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "p2d_config.h"

static void word(const char *name, const void *p, size_t n)
{{
    uint64_t w = 0;
    memcpy(&w, p, n);
    printf("%s %" PRIx64 "\\n", name, w);
}}

int main(void)
{{
{lines}
    printf("CURRENT_PER_SPEED %u\\n", (unsigned)P2D_CONFIG_CURRENT_PER_SPEED);
    printf("switches %d %d %d %d %d\\n", P2D_CONFIG_ENCODER, P2D_CONFIG_FIELD_WEAKENING, P2D_CONFIG_INERTIA,
           P2D_CONFIG_ADAPT_GAINS, P2D_CONFIG_KA_FOLLOWS_J);
    return 0;
}}
"""

#: block of the header -> its C type
BLOCKS = {
    "speed": "p2d_speed_config_t",
    "speed_filter": "p2d_filter_config_t",
    "current": "p2d_current_config_t",
    "encoder": "p2d_encoder_config_t",
    "field_weakening": "p2d_field_weakening_config_t",
    "inertia": "p2d_inertia_config_t",
}


def words_of(ctype, value):
    """{field: the bits of its value as an unsigned integer} of a cffi struct value."""
    out = {}
    for name, field in ffi.typeof(ctype).fields:
        raw = bytes(ffi.buffer(ffi.addressof(value, name), ffi.sizeof(field.type)))
        out[name] = int.from_bytes(raw, "little")
    return out


def engine_blocks(config):
    """The configuration the engine runs: its own C structs (the encoder and the disabled parts as the engine's
    sensing and estimator take them)."""
    cfg = config.engine.cfg
    zero = {ctype: ffi.new(f"{ctype} *")[0] for ctype in BLOCKS.values()}
    on = config.switches
    return {
        "speed": cfg.speed,
        "speed_filter": cfg.speed_filter,
        "current": cfg.current,
        "encoder": config.encoder,
        "field_weakening": cfg.sensing.field_weakening.config
        if on["FIELD_WEAKENING"]
        else zero[BLOCKS["field_weakening"]],
        "inertia": cfg.adapt.config if on["INERTIA"] else zero[BLOCKS["inertia"]],
    }


@pytest.mark.skipif(GCC is None, reason="gcc is not installed")
@pytest.mark.parametrize("name", list(SCENARIOS))
def test_the_compiled_header_holds_the_engines_configuration_to_the_bit(tmp_path, name):
    config = configuration(SCENARIOS[name]())
    (tmp_path / "p2d_config.h").write_text(config.c_header())
    lines = []
    for block, ctype in BLOCKS.items():
        for field, _ in ffi.typeof(ctype).fields:
            lines.append(
                f'    word("{block}.{field}", &p2d_config_{block}.{field}, sizeof p2d_config_{block}.{field});'
            )
    (tmp_path / "dump.c").write_text(DUMP.format(lines="\n".join(lines)))
    flags = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wdouble-promotion", "-Werror"]
    exe = tmp_path / "dump"
    subprocess.run(
        [GCC, *flags, f"-I{ROOT / 'csrc' / 'include'}", f"-I{tmp_path}", str(tmp_path / "dump.c"), "-o", str(exe)],
        check=True,
        capture_output=True,
        text=True,
    )
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.splitlines()
    compiled = dict(line.split(" ", 1) for line in out)
    expected = {}
    for block, value in engine_blocks(config).items():
        for field, bits in words_of(BLOCKS[block], value).items():
            expected[f"{block}.{field}"] = f"{bits:x}"
    assert {k: v for k, v in compiled.items() if "." in k} == expected
    assert compiled["CURRENT_PER_SPEED"] == str(config.current_per_speed)
    on = config.switches
    flags = [on[k] for k in ("ENCODER", "FIELD_WEAKENING", "INERTIA", "ADAPT_GAINS", "KA_FOLLOWS_J")]
    assert compiled["switches"] == " ".join(str(int(f)) for f in flags)


def test_every_part_is_on_in_the_drive_that_uses_every_part():
    config = configuration(SCENARIOS["servo, every part"]())
    assert config.switches == dict(
        ENCODER=True, FIELD_WEAKENING=True, INERTIA=True, ADAPT_GAINS=True, KA_FOLLOWS_J=True
    )
    assert config.engine.cfg.speed_filter.notch_freq_Hz == 300.0
    assert config.encoder.estimator == 1 and config.encoder.Ts_s == np.float32(5e-4)
    # the derived defaults are the engine's: the estimator's bounds around J0
    assert config.engine.cfg.adapt.config.J_max_kgm2 == np.float32(1.2e-3)


def shape(text):
    """The macros and constants a header defines, in order."""
    return re.findall(r"^(?:#define (\w+) |static const (\w+) (\w+) = )", text, flags=re.M)


def test_every_command_writes_the_same_shape(tmp_path, capsys):
    from pmsm2dof.ui.tuner.experiment import Tuner

    assert main(["header", "paper-condition-2", "--out", str(tmp_path / "header.h")]) == 0
    design = [
        "design",
        "--J-kgm2",
        "0.4",
        "--alpha-radps",
        "0.5",
        "--zeta",
        "0.2887",
        "--tau-i-s",
        "0.05",
        "--Ts-s",
        "1e-3",
    ]
    assert main([*design, "--paper-drive", "--emit-c-header", str(tmp_path / "design.h")]) == 0
    _, _, tuner = Tuner(load_scenario("paper-condition-2")).download("header.h", {})
    expected = shape((tmp_path / "header.h").read_text())
    assert len(expected) == 16
    assert shape((tmp_path / "design.h").read_text()) == expected
    assert shape(tuner) == expected


def test_header_refuses_a_path_it_must_not_replace_before_any_work(tmp_path, capsys):
    """`header` writes files the user names: a FIFO (standing for a device such as /dev/null, which the
    rename of an atomic write would replace) or a folder is refused naming the option, and nothing is written."""
    os.mkfifo(tmp_path / "fifo.h")
    (tmp_path / "folder.h").mkdir()
    cases = [
        (["--out", str(tmp_path / "fifo.h")], "--out"),
        (["--out", str(tmp_path / "ok.h"), "--virtual-drive", str(tmp_path / "folder.h")], "--virtual-drive"),
        (["--out", str(tmp_path / "ok.h"), "--virtual-drive", str(tmp_path / "fifo.h")], "--virtual-drive"),
        (["--out", str(tmp_path / "missing" / "ok.h")], "--out"),
    ]
    for args, option in cases:
        assert main(["header", "paper-condition-2", *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("pmsm2dof: error: ") and option in err, err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo.h", "folder.h"]
    assert (tmp_path / "fifo.h").is_fifo()


@pytest.mark.parametrize(
    "changes, key",
    [
        ({"speed_controller.Ka": 1e6}, "speed_controller.Ka"),
        ({"speed_sensor.model": "encoder", "speed_sensor.counts_per_rev": 0}, "speed_sensor.counts_per_rev"),
        ({"field_weakening.enabled": True, "field_weakening.Ki_A_per_Vs": -1.0}, "field_weakening.Ki_A_per_Vs"),
    ],
)
def test_a_value_the_c_library_rejects_is_named_by_its_scenario_key(changes, key):
    with pytest.raises(ConfigError) as exc:
        configuration(load_scenario("paper-condition-2").with_overrides(changes))
    assert exc.value.param == key


@pytest.mark.parametrize(
    "changes, key",
    [
        ({"current_loop.model": "first_order"}, "current_loop.model"),
        ({"fault": [{"kind": "sensor_zero", "t_s": 1.0, "duration_s": 0.1}]}, "fault"),
        ({"speed_sensor.delay_s": 1e-3}, "speed_sensor.delay_s"),
        ({"speed_sensor.noise_rpm_rms": 1.0}, "speed_sensor.noise_rpm_rms"),
        (
            {"current_loop.Ts_s": 0.05, "speed_controller.Ts_s": 0.05, "motor.Ld_H": 0.1, "motor.Lq_H": 0.1},
            "current_loop.Ts_s",
        ),
    ],
)
def test_what_the_virtual_board_does_not_model_is_refused(changes, key):
    scenario = load_scenario("paper-condition-2").with_overrides(changes)
    with pytest.raises(ConfigError) as exc:
        check_virtual_drive(scenario)
    assert exc.value.param == key
    # the header alone is fine: the firmware's controllers do not depend on it
    assert "p2d_config_speed" in configuration(scenario).c_header()


# ---------------------------------------------------------------------------------------------
# scenario_design: the one scenario -> design
# ---------------------------------------------------------------------------------------------


def test_scenario_design_is_the_design_of_the_scenario_keys():
    """eq 9 from the scenario's own J, alpha, zeta; its feedforward, m and tau_i; changes replace them."""
    from pmsm2dof.studies.configuration import scenario_design

    scenario = load_scenario(str(SERVO))
    sc = scenario.data["speed_controller"]
    d = scenario_design(scenario)
    assert d.Kp == pytest.approx(sc["J_kgm2"] * sc["alpha_radps"], rel=1e-12)
    assert d.Ki == pytest.approx(sc["J_kgm2"] * (sc["alpha_radps"] / (2.0 * sc["zeta"])) ** 2, rel=1e-12)
    assert (d.m, d.tau_i_s, d.feedforward, d.anti_windup) == (
        sc["m"],
        sc["tau_i_s"],
        sc["feedforward"],
        sc["anti_windup"],
    )
    full = scenario_design(scenario, m=1.0, feedforward="full")
    assert (full.feedforward, full.m, full.Kp) == ("full", 1.0, d.Kp)
    with pytest.raises(ConfigError, match="alpha = 3"):
        scenario_design(scenario, alpha=3)


def test_scenario_design_holds_the_scenario_sensor():
    """A measurement delay in [speed_sensor] costs phase margin: the design's loop holds the sensor."""
    from pmsm2dof.studies.configuration import scenario_design

    base = load_scenario("paper-experiment-1")
    delay_s = 0.2
    delayed = base.with_overrides({"speed_sensor.delay_s": delay_s})
    ideal, slow = scenario_design(base).margins(), scenario_design(delayed).margins()
    w_c = ideal.w_gain_crossover_radps
    # a pure delay leaves the gain crossover and removes w_c * delay of phase there
    assert slow.w_gain_crossover_radps == pytest.approx(w_c, rel=1e-6)
    assert ideal.phase_margin_deg - slow.phase_margin_deg == pytest.approx(np.degrees(w_c * delay_s), rel=1e-3)
