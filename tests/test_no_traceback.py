"""No input gives a traceback, and every refusal names the parameter, its value (shortened) and the
valid range.

- A property test feeds random bytes, and TOML nested at random depths with random values, to
  every command that reads a file (scenario, sweep, motor and log files): exit status 2 and one
  line on stderr, never a traceback.
- The probes the issue found: a TOML value nested 5000 deep, --alpha-radps 1e300 (eq 9 overflowed in
  design, bode, twomass), the design equations at 5e-324, a 5 MB scenario name, the tuner's JSON
  edge cases (answered 500 before), and the messages that named no parameter.
- The Python API: numpy scalars are numbers, a plant inertia must be finite and > 0, and a gain
  is never infinite.
"""

import contextlib
import io
import json
import math
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmsm2dof.analysis.design import design
from pmsm2dof.errors import ConfigError, shorten
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.ui.cli import main

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message="Using `httpx` with `starlette.testclient`")
    from starlette.testclient import TestClient

ROOT = Path(__file__).resolve().parents[1]
MESSAGE = re.compile(r"^pmsm2dof: error: .+ = .+ is invalid: valid range is .+$")
DESIGN = ["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"]
LOG_TEXT = "time_s,speed_rpm\n" + "".join(f"{i * 0.01},{10.0 * i}\n" for i in range(300))

#: Every command that reads a file, by the kind of file: argv with FILE where the file goes.
TOML_COMMANDS = {
    "simulate": ["simulate", "FILE", "--out", "out"],
    "motor": ["motor", "FILE"],
    "sweep": ["sweep", "FILE", "--out", "out"],
    "commission": ["commission", "FILE"],
    "autotune": ["autotune", "FILE"],
    "tune": ["tune", "FILE", "--port", "70000", "--no-browser"],
    "design --motor": [*DESIGN, "--motor", "FILE", "--current-bandwidth-radps", "100"],
    "identify plan": ["identify", "plan", "--motor", "FILE", "--speed-max-rpm", "100", "--out", "out"],
    "compare (scenario)": ["compare", "log.csv", "FILE", "--out", "out"],
    "header": ["header", "FILE", "--out", "p2d_config.h"],
}
#: Commands that read a file but would start a long build on a sound one: probed with refused files only.
BUILD_COMMANDS = {"firmware": ["firmware", "FILE", "--out", "out"]}
LOG_COMMANDS = {
    "identify mechanics": ["identify", "mechanics", "FILE", "--pole-pairs", "4", "--psi-f-Wb", "0.1"],
    "identify electrical": ["identify", "electrical", "FILE", "--pole-pairs", "4"],
    "compare (log)": ["compare", "FILE", "paper-condition-2", "--out", "out"],
}
LOG_SUFFIXES = (".csv", ".parquet", ".npz", ".mat")


def run_in(folder, argv):
    """``main(argv)`` in ``folder``: (exit status, stderr); an exception escaping main fails the test."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), contextlib.chdir(folder):
        code = main(argv)
    return code, err.getvalue()


def assert_one_error_line(code, err):
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("pmsm2dof: error: ") and "Traceback" not in err, err


# ---- random files -------------------------------------------------------------------------

leaves = st.one_of(
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from(["9" * 5000, "9" * 400, "1e308", "-1e400", "nan", "inf", "5e-324", "true", '"\\ud800"', '""']),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.text(max_size=20).map(json.dumps),
).map(str)


def nested(depth, leaf, kind):
    """A TOML value: ``leaf`` inside ``depth`` arrays or inline tables (``kind``)."""
    if kind == "array":
        return "[" * depth + leaf + "]" * depth
    return "{a = " * depth + leaf + "}" * depth


@st.composite
def toml_files(draw):
    """TOML text: a table the commands know ([motor], [speed_controller], axes...) or another, with
    keys holding values nested from 0 to 3000 levels deep; sometimes broken by a cut."""
    lines = []
    if draw(st.booleans()):
        lines.append("base = " + draw(st.sampled_from(['"paper-condition-2"', '"x.toml"', "1", "[[]]"])))
    for _ in range(draw(st.integers(1, 4))):
        table = draw(st.sampled_from(["motor", "motor.datasheet", "speed_controller", "axes", "simulation", "x"]))
        key = draw(st.sampled_from(["J_kgm2", "pole_pairs", "name", '"motor.J_kgm2"', "Kt_Nm_per_A", "t_end_s"]))
        depth = draw(st.one_of(st.integers(0, 40), st.sampled_from([100, 999, 1000, 3000])))
        value = nested(depth, draw(leaves), draw(st.sampled_from(["array", "table"])))
        lines += [f"[{table}]", f"{key} = {value}"]
    text = "\n".join(lines) + "\n"
    if draw(st.booleans()):
        cut = draw(st.integers(0, len(text)))
        text = text[:cut]
    return text.encode("utf-8", "surrogatepass")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(
    command=st.sampled_from(sorted(TOML_COMMANDS)),
    content=st.one_of(st.binary(max_size=3000), toml_files()),
)
def test_any_toml_input_file_exits_2_with_one_line(command, content):
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "input.toml").write_bytes(content)
        (Path(folder) / "log.csv").write_text(LOG_TEXT)
        argv = [a if a != "FILE" else "input.toml" for a in TOML_COMMANDS[command]]
        assert_one_error_line(*run_in(folder, argv))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    command=st.sampled_from(sorted(LOG_COMMANDS)),
    suffix=st.sampled_from(LOG_SUFFIXES),
    content=st.one_of(
        st.binary(max_size=3000),
        st.builds(lambda cut, junk: (LOG_TEXT[:cut] + junk).encode(), st.integers(0, 200), st.text(max_size=50)),
    ),
)
def test_any_log_file_is_read_or_exits_2_with_one_line(command, suffix, content):
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / f"log{suffix}").write_bytes(content)
        argv = [a if a != "FILE" else f"log{suffix}" for a in LOG_COMMANDS[command]]
        code, err = run_in(folder, argv)
        lines = [line for line in err.splitlines() if not line.startswith("pmsm2dof: warning: ")]
        if code == 0:  # a cut of the sound log can be a sound log
            assert lines == [], err
        else:
            assert code == 2 and len(lines) == 1 and lines[0].startswith("pmsm2dof: error: "), err


# ---- the probes of the issue ----------------------------------------------------------------


@pytest.mark.parametrize("command", sorted(TOML_COMMANDS | BUILD_COMMANDS))
def test_a_value_nested_5000_deep_is_refused_in_one_line(tmp_path, command):
    """RecursionError in simulate, motor, sweep, commission and tune."""
    (tmp_path / "input.toml").write_text("[motor]\nJ_kgm2 = " + "[" * 5000 + "]" * 5000 + "\n")
    (tmp_path / "log.csv").write_text(LOG_TEXT)
    argv = (TOML_COMMANDS | BUILD_COMMANDS)[command]
    code, err = run_in(tmp_path, [a if a != "FILE" else "input.toml" for a in argv])
    assert_one_error_line(code, err)
    assert "nested" in err or "within pmsm2dof's bounds" in err


MOTOR_MODEL = "[motor]\npole_pairs = 4\nRs_ohm = 0.8\nLd_H = 0.004\nLq_H = 0.004\npsi_f_Wb = 0.05\n"


@pytest.mark.parametrize(
    "text, key",
    [
        (MOTOR_MODEL.replace("psi_f_Wb = 0.05", "psi_f_Wb = " + "9" * 400), "motor.psi_f_Wb"),
        (MOTOR_MODEL + "Rs_ohm_ci = [0.5, " + "9" * 400 + "]\n", "motor.Rs_ohm_ci"),
        (MOTOR_MODEL + "[limits]\nu_dc_V = " + "9" * 400 + "\n", "limits.u_dc_V"),
        ("[motor.datasheet]\npoles = 8\nKt_Nm_per_A = " + "9" * 400 + "\n", "motor.datasheet.Kt_Nm_per_A"),
    ],
)
def test_an_integer_beyond_float_in_a_motor_file_names_its_key(tmp_path, text, key):
    """A TOML integer of 400 digits passed the type checks of the motor file and overflowed in
    math.isfinite (OverflowError, a traceback)."""
    (tmp_path / "motor.toml").write_text(text)
    code, err = run_in(tmp_path, ["motor", "motor.toml"])
    assert_one_error_line(code, err)
    assert MESSAGE.match(err.rstrip("\n")) and f"{key} = " in err, err


@pytest.mark.parametrize(
    "argv, words",
    [
        ([*DESIGN, "--alpha-radps", "1e300"], "--alpha-radps = 1e+300"),
        (["bode", "--alpha-radps", "1e300", "--out", "f.png"], "alpha_radps = 1e+300"),
        (
            [
                "twomass",
                "--J-motor-kgm2",
                "0.4",
                "--J-load-kgm2",
                "0.1",
                "--stiffness-Nm-per-rad",
                "100",
                "--alpha-radps",
                "1e300",
                "--Ts-s",
                "1e-3",
            ],
            "--alpha-radps = 1e+300",
        ),
        ([*DESIGN, "--J-kgm2", "1e300"], "--J-kgm2 = 1e+300"),  # "Array must not contain infs or NaNs"
        ([*DESIGN, "--J-kgm2", "5e-324"], "--J-kgm2 = 5e-324"),  # ZeroDivisionError
        ([*DESIGN, "--alpha-radps", "5e-324"], "--alpha-radps = 5e-324"),
        ([*DESIGN, "--zeta", "1e-300"], "--zeta = 1e-300"),  # OverflowError
        ([*DESIGN, "--zeta", "5e-324"], "--zeta = 5e-324"),
        ([*DESIGN, "--tau-i-s", "1e-300"], "--tau-i-s = 1e-300"),
        ([*DESIGN, "--tau-i-s", "1e300"], "--tau-i-s = 1e+300"),
        ([*DESIGN, "--sensor-delay-s", "1e-300"], "--sensor-delay-s = 1e-300"),  # ZeroDivisionError in pade
        ([*DESIGN, "--sensor-delay-s", "1e-20"], "--sensor-delay-s = 1e-20"),
        ([*DESIGN, "--sensor-lowpass-radps", "1e-300"], "--sensor-lowpass-radps = 1e-300"),
        ([*DESIGN, "--sensor-delay-s", "10"], "--sensor-delay-s = 10.0"),  # over 5 minutes
        (
            [*DESIGN, "--J-kgm2", "3e38", "--alpha-radps", "3e38"],
            "a value that makes Kp = J alpha (eq 9) a normal float32",
        ),
        (["bode", "--alpha-radps", "0.5", "--m", ",".join(["1"] * 2000), "--out", "f.png"], "at most 20"),
    ],
)
def test_the_design_probes_name_the_parameter(tmp_path, argv, words):
    code, err = run_in(tmp_path, argv)
    assert_one_error_line(code, err)
    assert MESSAGE.match(err.rstrip("\n")) and words in err, err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    "option", ["--J-kgm2", "--alpha-radps", "--zeta", "--m", "--tau-i-s", "--Ts-s", "--Ka", "--sensor-delay-s"]
)
@pytest.mark.parametrize("value", ["5e-324", "1e-300", "1e-40", "1e-20", "1e20", "1e40", "1e300"])
def test_design_at_any_magnitude_runs_or_names_the_parameter(tmp_path, option, value):
    argv = [*DESIGN, option, value] + (["--feedforward", "full"] if option == "--m" else [])
    code, err = run_in(tmp_path, argv)
    assert (code == 0 and not err) or (code == 2 and MESSAGE.match(err.rstrip("\n"))), err


def test_a_huge_scenario_name_is_refused_naming_the_key(tmp_path):
    """A 5 MB name reached the font rasteriser; a name is at most 500 characters, and one that long is drawn."""
    preset = (ROOT / "src" / "pmsm2dof" / "sim" / "presets" / "paper-experiment-1.toml").read_text()
    name_line = next(line for line in preset.splitlines() if line.startswith("name ="))
    (tmp_path / "big.toml").write_text(preset.replace(name_line, f'name = "{"x" * 1_000_000}"'))
    code, err = run_in(tmp_path, ["simulate", "big.toml", "--out", "out"])
    assert_one_error_line(code, err)
    assert "name = 'xxxx" in err and "(1000002 characters)" in err and "at most 500 characters" in err
    assert len(err) < 400
    (tmp_path / "long.toml").write_text(preset.replace(name_line, f'name = "{"x" * 500}"'))
    argv = ["simulate", "long.toml", "--set", "simulation.t_end_s=0.2", "--set", "reference.0.t_s=0.05"]
    assert run_in(tmp_path, [*argv, "--out", "out"])[0] == 0


def test_a_message_shows_a_long_value_by_its_beginning_and_length():
    assert str(ConfigError("x", "a" * 5_000_000, "y")).startswith("x = 'aaaa")
    assert len(str(ConfigError("x" * 10**6, [1.5] * 10**6, "y" * 10**6))) < 1500
    assert shorten(10**5000) == "<an integer of about 5001 digits>"
    deep: list = []
    for _ in range(10**5):
        deep = [deep]
    assert shorten(deep) == "[[[[...]]]]"


# ---- the tuner ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tuner():
    from pmsm2dof.ui.tuner import create_app

    with TestClient(create_app(load_scenario("paper-condition-2")), raise_server_exceptions=False) as client:
        yield client


TUNER_BODIES = [
    (b"[" * 5000 + b"]" * 5000, "nested at most 32"),
    (b'{"a": ' * 100 + b"1" + b"}" * 100, "nested at most 32"),
    (b'{"speed_controller.alpha_radps": ' + b"9" * 5000 + b"}", "at most 400 digits"),
    (b'{"\\ud800": 1}', r"\ud800 = 1 is invalid"),
    (b'{"speed_controller.alpha_radps": "\\ud800"}', r"speed_controller.alpha_radps = '\ud800'"),
    (b'{"tuner.J_ratio": 1e308}', "J_plant_kgm2 = 4.0000000000000004e+307 is invalid"),
    (b'{"speed_controller.alpha_radps": 1e308}', "speed_controller.alpha_radps = 1e+308"),
    (b'{"reference.0.speed_rpm": 1e308}', "stopped at t ="),
    (b'{"x": "' + b"a" * 60_000 + b'"}', "(60002 characters)"),
    (b'{"speed_controller.alpha_radps": NaN}', "speed_controller.alpha_radps = nan"),
    (b"\xff\xfe", "UTF-8"),
]


@pytest.mark.parametrize("body, words", TUNER_BODIES, ids=range(len(TUNER_BODIES)))
def test_the_tuner_answers_422_with_a_short_message(tuner, body, words):
    """The issue's bodies answered 500 (a nested body, a 5000-digit integer, a lone surrogate key,
    1e308), and a long value was echoed whole."""
    response = tuner.post("/api/run", content=body, headers={"Content-Type": "application/json"})
    assert response.status_code == 422 and len(response.content) < 2000, response.text[:300]
    assert words in response.json()["error"], response.json()
    header = tuner.post("/api/download/header.h", content=body, headers={"Content-Type": "application/json"})
    assert header.status_code in (200, 422), header.text[:300]  # a header needs no run: it may not use the value
    if b"speed_controller" not in body and b"tuner" not in body:  # a suggestion of sound values would take seconds
        suggestion = tuner.post("/api/suggest", content=body, headers={"Content-Type": "application/json"})
        assert suggestion.status_code == 422 and len(suggestion.content) < 2000, suggestion.text[:300]


# ---- the Python API -------------------------------------------------------------------------


def test_numpy_scalars_are_numbers():
    s = load_scenario("paper-condition-2").with_overrides(
        {"motor.pole_pairs": np.int64(4), "speed_controller.zeta": np.float32(0.4), "motor.J_kgm2": np.float64(0.5)}
    )
    assert type(s.data["motor"]["pole_pairs"]) is int and s.data["motor"]["pole_pairs"] == 4
    assert type(s.data["speed_controller"]["zeta"]) is float and s.data["speed_controller"]["zeta"] == float(
        np.float32(0.4)
    )
    assert "pole_pairs = 4\n" in s.to_toml()
    d = design(np.float32(0.4), np.int64(2), np.float32(0.5))
    J = float(np.float32(0.4))
    assert (d.Kp, d.Ki) == (J * 2.0, J * (2.0 / (2.0 * 0.5)) ** 2)  # eq 9
    with pytest.raises(ConfigError, match="motor.pole_pairs"):
        load_scenario("paper-condition-2").with_overrides({"motor.pole_pairs": np.bool_(True)})


@pytest.mark.parametrize("J", [-1.0, 0.0, math.nan, math.inf, 5e-324, 1e300])
def test_a_plant_inertia_must_be_finite_and_positive(J):
    """`on_plant(-1.0)` built a plant with negative inertia."""
    with pytest.raises(ConfigError, match="J_plant_kgm2"):
        design(0.4, 0.5, 0.3).on_plant(J)


@settings(max_examples=300, deadline=None)
@given(
    J=st.floats(5e-324, 1e308),
    alpha=st.floats(5e-324, 1e308),
    zeta=st.floats(5e-324, 1e308),
)
def test_a_gain_is_never_infinite_nor_zero(J, alpha, zeta):
    """`design(zeta=5e-324)` returned Ki = inf; J = 5e-324 raised ZeroDivisionError."""
    try:
        d = design(J, alpha, zeta)
    except ConfigError as exc:
        assert exc.param in ("J_kgm2", "alpha_radps", "zeta")
        return
    for gain in (d.Kp, d.Ki, d.Ka):
        assert math.isfinite(gain) and gain > 0
