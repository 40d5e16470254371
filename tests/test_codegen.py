"""C header export of a design (pmsm2dof.studies.configuration.design_scenario and
configuration): it compiles against csrc/ with the project's -Werror flags, and the C
controllers initialized from it produce the same outputs, bit for bit, as the controllers
configured from Python with the design values written out here.
"""

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pmsm2dof import CurrentController, SpeedController
from pmsm2dof.analysis.codegen import c_float
from pmsm2dof.analysis.design import design
from pmsm2dof.studies.configuration import configuration, design_scenario

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
GCC = shutil.which("gcc")
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wdouble-promotion", "-Werror"]
N_STEPS = 60

CASES = {
    "paper_tustin_full": dict(
        design=dict(
            J_kgm2=0.4,
            alpha_radps=0.5,
            zeta=0.2887,
            m=1.0,
            tau_i_s=0.05,
            feedforward="full",
            anti_windup="back_calculation",
        ),
        Ts_s=1e-3,
        method="tustin",
        motor=dict(i_max_A=7.6, pole_pairs=4, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01),
        current=dict(Rs_ohm=0.5, Ts_current_s=1e-4),
    ),
    "salient_forward_lowpass_clamping": dict(
        design=dict(
            J_kgm2=0.02, alpha_radps=30.0, zeta=0.7, m=1.0, tau_i_s=0.002, feedforward="lowpass", anti_windup="clamping"
        ),
        Ts_s=2e-4,
        method="forward_euler",
        motor=dict(i_max_A=12.0, pole_pairs=3, psi_f_Wb=0.05, Ld_H=0.008, Lq_H=0.02),
        current=dict(Rs_ohm=0.8, Ts_current_s=1e-4),
    ),
    "backward_no_tau_explicit_Ka": dict(
        design=dict(
            J_kgm2=1.5,
            alpha_radps=4.0,
            zeta=1.0,
            m=1.6,
            tau_i_s=0.01,
            feedforward="no_tau",
            anti_windup="back_calculation",
            Ka=0.3,
        ),
        Ts_s=5e-4,
        method="backward_euler",
        motor=dict(i_max_A=20.0, pole_pairs=5, psi_f_Wb=0.3, Ld_H=0.004, Lq_H=0.004),
        current=dict(Rs_ohm=0.2, Ts_current_s=5e-5),
    ),
}


def inputs(n):
    """A reference step and a measured speed that lags it, in float32: saturates, then recovers."""
    k = np.arange(n)
    w_ref = np.where(k < 5, 0.0, np.where(k < 40, 60.0, 20.0)).astype(np.float32)
    w_m = (25.0 * np.sin(0.07 * k) + 0.5 * k).astype(np.float32)
    return w_ref, w_m


def current_inputs(n):
    k = np.arange(n)
    return [
        a.astype(np.float32)
        for a in (
            np.where(k < 10, 0.0, -1.0),
            np.where(k < 5, 0.0, 8.0),
            0.1 * np.cos(0.3 * k),
            0.15 * k,
            300.0 + 2.0 * k,
            np.full(n, 48.0),
        )
    ]


def c_array(name, values):
    items = ", ".join(f"{float(v):.9e}f" for v in values)
    return f"static const float {name}[{len(values)}] = {{{items}}};"


PROGRAM = """\
#include <stdio.h>

#include "{header}"

{arrays}

int count_configs(void);

int main(void)
{{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_status_t status = p2d_speed_init(&ctl, &{prefix}_speed);
    int k;
    if (status != P2D_OK) {{
        printf("init %d\\n", (int)status);
        return 1;
    }}
    printf("config %.9g %.9g %.9g %.9g %.9g %.9g %.9g\\n", (double){prefix}_speed.J_kgm2,
           (double){prefix}_speed.alpha_radps, (double){prefix}_speed.zeta,
           (double){prefix}_speed.m, (double){prefix}_speed.tau_i_s,
           (double){prefix}_speed.Ka, (double){prefix}_speed.Ts_s);
    for (k = 0; k < {n}; ++k) {{
        p2d_speed_step(&ctl, w_ref[k], w_m[k], &out);
        printf("speed %.9g %.9g %.9g %.9g %.9g %d\\n", (double)out.T_ff_Nm, (double)out.T_unsat_Nm,
               (double)out.T_ref_Nm, (double)out.id_ref_A, (double)out.iq_ref_A, (int)out.saturated);
    }}
{current}
    return count_configs() == {n_configs} ? 0 : 2;
}}
"""

CURRENT = """\
    {{
        p2d_current_t cc;
        p2d_current_output_t co;
        if (p2d_current_init(&cc, &{prefix}_current) != P2D_OK) return 1;
        for (k = 0; k < {n}; ++k) {{
            p2d_current_step(&cc, id_ref[k], iq_ref[k], id[k], iq[k], w_e[k], u_dc[k], &co);
            printf("current %.9g %.9g %d\\n", (double)co.ud_ref_V, (double)co.uq_ref_V, (int)co.saturated);
        }}
    }}
"""

# a second translation unit including the same header: no clash (it uses every constant, as a firmware does)
SECOND_UNIT = """\
#include "{header}"

int count_configs(void)
{{
    return (int)(sizeof {prefix}_speed / sizeof(p2d_speed_config_t) + sizeof {prefix}_speed_filter /
                 sizeof(p2d_filter_config_t) + sizeof {prefix}_encoder / sizeof(p2d_encoder_config_t) +
                 sizeof {prefix}_field_weakening / sizeof(p2d_field_weakening_config_t) +
                 sizeof {prefix}_inertia / sizeof(p2d_inertia_config_t)){plus_current};
}}
"""


def build_and_run(tmp_path, header_text, prefix, with_current=True):
    (tmp_path / f"{prefix}.h").write_text(header_text)
    w_ref, w_m = inputs(N_STEPS)
    arrays = [c_array("w_ref", w_ref), c_array("w_m", w_m)]
    current = ""
    if with_current:
        names = ("id_ref", "iq_ref", "id", "iq", "w_e", "u_dc")
        arrays += [c_array(name, a) for name, a in zip(names, current_inputs(N_STEPS))]
        current = CURRENT.format(prefix=prefix, n=N_STEPS)
    (tmp_path / "main.c").write_text(
        PROGRAM.format(
            header=f"{prefix}.h",
            arrays="\n".join(arrays),
            prefix=prefix,
            n=N_STEPS,
            current=current,
            n_configs=6 if with_current else 5,
        )
    )
    plus = f" + (int)sizeof({prefix}_current) / (int)sizeof(p2d_current_config_t)" if with_current else ""
    (tmp_path / "second.c").write_text(SECOND_UNIT.format(header=f"{prefix}.h", prefix=prefix, plus_current=plus))
    exe = tmp_path / "run"
    sources = [str(tmp_path / "main.c"), str(tmp_path / "second.c")] + sorted(
        str(p) for p in (CSRC / "src").glob("*.c")
    )
    subprocess.run(
        [GCC, *CFLAGS, f"-I{CSRC / 'include'}", f"-I{tmp_path}", *sources, "-o", str(exe), "-lm"],
        check=True,
        capture_output=True,
        text=True,
    )
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stdout + run.stderr
    rows = {"config": [], "speed": [], "current": []}
    for line in run.stdout.splitlines():
        tag, *values = line.split()
        rows[tag].append([float(v) for v in values])
    return {tag: np.array(v) for tag, v in rows.items()}


def header_of(case, prefix):
    """The header text of a CASES entry: its design and motor through design_scenario and configuration."""
    dd = design(**case["design"]).discretize(case["Ts_s"], case["method"])
    return configuration(design_scenario(dd, **case["motor"], **case["current"])).c_header(prefix)


@pytest.mark.slow
@pytest.mark.skipif(GCC is None, reason="gcc is not installed")
@pytest.mark.parametrize("name", list(CASES))
def test_header_compiles_and_matches_python_configured_controller(tmp_path, name):
    case = CASES[name]
    prefix = name + "_cfg"
    result = build_and_run(tmp_path, header_of(case, prefix), prefix)

    # the configuration literals round-trip to the float32 of every design value
    inp = case["design"]
    Ka = inp.get("Ka", 1.0 / (inp["J_kgm2"] * inp["alpha_radps"]))
    expected = [inp["J_kgm2"], inp["alpha_radps"], inp["zeta"], inp["m"], inp["tau_i_s"], Ka, case["Ts_s"]]
    np.testing.assert_array_equal(result["config"][0].astype(np.float32), np.float32(expected))

    # the same controller configured from Python, from the values written out above
    ctl = SpeedController(
        **{k: v for k, v in inp.items() if k != "Ka"}, Ka=Ka, Ts_s=case["Ts_s"], method=case["method"], **case["motor"]
    )
    w_ref, w_m = inputs(N_STEPS)
    py = ctl.run(w_ref, w_m)
    c = result["speed"]
    for column, field in enumerate(("T_ff_Nm", "T_unsat_Nm", "T_ref_Nm", "id_ref_A", "iq_ref_A")):
        np.testing.assert_array_equal(c[:, column].astype(np.float32), py[field], err_msg=field)
    np.testing.assert_array_equal(c[:, 5].astype(bool), py["saturated"])
    assert py["saturated"].any() and not py["saturated"].all()  # the sequence exercises the limit

    cc = CurrentController(
        Rs_ohm=case["current"]["Rs_ohm"],
        Ld_H=case["motor"]["Ld_H"],
        Lq_H=case["motor"]["Lq_H"],
        psi_f_Wb=case["motor"]["psi_f_Wb"],
        tau_i_s=inp["tau_i_s"],
        Ts_s=case["current"]["Ts_current_s"],
        method=case["method"],
        anti_windup="back_calculation",
        decouple=True,
    )
    py_c = cc.run(*current_inputs(N_STEPS))
    np.testing.assert_array_equal(result["current"][:, 0].astype(np.float32), py_c["ud_ref_V"])
    np.testing.assert_array_equal(result["current"][:, 1].astype(np.float32), py_c["uq_ref_V"])


def test_header_records_every_design_input():
    case = CASES["backward_no_tau_explicit_Ka"]
    text = header_of(case, "p2d_config")
    recorded = dict(re.findall(r"^ \*   (\w+)\s+= (\S+)", text, flags=re.M))
    for name, value in {**case["design"], "Ts_s": case["Ts_s"], "method": case["method"]}.items():
        if isinstance(value, str):
            assert recorded[name] == value, name
        else:
            assert float(recorded[name]) == pytest.approx(value, rel=1e-9), name
    # the motor and the current loop, exact, in the initializers
    initialized = dict(re.findall(r"^    \.(\w+) = ([^,]+),", text, flags=re.M))
    for name in ("i_max_A", "psi_f_Wb", "Ld_H", "Rs_ohm"):
        assert np.float32(initialized[name].rstrip("f")) == np.float32({**case["motor"], **case["current"]}[name])
    assert initialized["pole_pairs"] == "5u"
    assert "Loop rates: current loop 20000 Hz (Ts 5e-05 s), speed loop every 10th interrupt (2000 Hz)" in text


C_FLOAT = re.compile(r"-?(\d+\.\d*|\.\d+)(e[+-]?\d+)?f\Z")


@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
def test_float_literals_round_trip_float32(x):
    literal = c_float(x)
    assert C_FLOAT.match(literal), literal
    assert np.float32(float(literal[:-1])) == np.float32(x)


def test_non_finite_literal_is_refused():
    with pytest.raises(ValueError):
        c_float(math.inf)
    with pytest.raises(ValueError):
        c_float(1e39)  # overflows float32


@pytest.mark.parametrize(
    "param, options",
    [
        ("prefix", {"prefix": "2fast"}),
        ("prefix", {"prefix": "my-design"}),
        ("motor.pole_pairs", {"pole_pairs": 0}),
        ("motor.pole_pairs", {"pole_pairs": 2.5}),
        ("limits.i_max_A", {"i_max_A": -1.0}),
        ("motor.psi_f_Wb", {"psi_f_Wb": 0.0}),
        ("motor.Ld_H", {"Ld_H": math.nan}),
        ("motor.Rs_ohm", {"Rs_ohm": -0.5}),
        ("current_loop.Ts_s", {"Ts_current_s": 0.0}),
        ("speed_controller.Ts_s", {"Ts_current_s": 3e-4}),  # Ts = 1e-3 is no multiple of it
        ("current_loop.anti_windup", {"current_anti_windup": "bogus"}),
        ("current_loop.method", {"current_method": "euler"}),
    ],
)
def test_invalid_header_options_leave_no_file(tmp_path, param, options):
    dd = design(0.4, 0.5, 0.2887, tau_i_s=0.05).discretize(1e-3, "tustin")
    motor = {"i_max_A": 7.6, "pole_pairs": 4, "psi_f_Wb": 0.2, "Ld_H": 0.01, "Lq_H": 0.01, "Rs_ohm": 0.5}
    motor |= {"Ts_current_s": 1e-4}
    prefix = options.pop("prefix", "p2d_config")
    path = tmp_path / "out" / "design.h"
    with pytest.raises(ValueError) as exc:
        configuration(design_scenario(dd, **{**motor, **options})).write_header(path, prefix)
    assert str(exc.value).startswith(param + " = ")
    assert not path.exists()
    assert not any(path.parent.glob("*")) if path.parent.exists() else True


@pytest.mark.slow
@pytest.mark.parametrize("feedforward", ["lowpass", "none"])
def test_header_of_a_finely_sampled_design_from_the_tuner(feedforward):
    """The paper's design with the speed loop at Ts = 1e-4 (alpha Ts = 5e-5): the tuner's
    header download once failed on a figure of merit of this stable design."""
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.ui.tuner.experiment import Tuner

    values = {"speed_controller.Ts_s": 1e-4, "speed_controller.feedforward": feedforward}
    name, media_type, text = Tuner(load_scenario("paper-condition-2")).download("header.h", values)
    assert media_type == "text/x-c"
    assert ".Ts_s = 0.0001f" in text and f".feedforward = P2D_FF_{feedforward.upper()}" in text
    overshoot = float(re.search(r"discrete .*\n.*\n \*   tracking step overshoot = (\S+) %", text).group(1))
    assert overshoot == pytest.approx(49.5 if feedforward == "none" else 0.026, abs=0.01)
