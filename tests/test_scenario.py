"""Scenario schema, presets, overrides and the TOML round trip.

Truth: the paper's text (section 4.1/4.2 values and schedules, eq 9), the physics the preset
files claim (torque and voltage balances computed here), and the corpus of broken files in
tests/bad_scenarios, each naming in its first line the key the error must name.
"""

import math
import re
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import SCHEMA, Scenario, list_presets, load_scenario, schema_reference
from pmsm2dof.ui.cli import parse_override

BAD = sorted((Path(__file__).parent / "bad_scenarios").glob("*.toml"))
PAPER_PRESETS = [
    "paper-condition-1",
    "paper-condition-2",
    "paper-experiment-1",
    "paper-experiment-2",
    "paper-experiment-3",
]


def rpm_to_radps(rpm):
    return rpm * 2 * math.pi / 60


# --- presets ---------------------------------------------------------------------------------


def test_the_paper_presets_are_shipped():
    assert set(PAPER_PRESETS) <= set(list_presets())


@pytest.mark.parametrize("name", PAPER_PRESETS)
def test_preset_holds_the_papers_values(name):
    """Section 4.1/4.2: J = 0.4, tau_i = 0.05, 7.6 A; Kp = 0.2 and Ki = 0.3 by eq 9 with alpha = 0.5."""
    d = load_scenario(name).data
    assert d["motor"]["J_kgm2"] == 0.4
    assert d["current_loop"]["tau_i_s"] == 0.05
    assert d["limits"]["i_max_A"] == 7.6
    sc = d["speed_controller"]
    assert sc["alpha_radps"] == 0.5
    Kp = sc["J_kgm2"] * sc["alpha_radps"]
    Ki = sc["J_kgm2"] * (sc["alpha_radps"] / (2 * sc["zeta"])) ** 2
    assert Kp == pytest.approx(0.2, rel=1e-12)
    assert Ki == pytest.approx(0.3, rel=1e-12)
    assert sc["Ka"] is None  # the paper's default 1/Kp (section 3.3)


@pytest.mark.parametrize("name", PAPER_PRESETS)
def test_preset_motor_can_do_what_the_paper_asks(name):
    """The chosen motor holds every load within the current limit and every speed within u_dc."""
    d = load_scenario(name).data
    m, lim = d["motor"], d["limits"]
    kt = 1.5 * m["pole_pairs"] * m["psi_f_Wb"]  # amplitude-invariant Park, surface PMSM
    assert m["Ld_H"] == m["Lq_H"]
    for entry in d["load"]:
        assert abs(entry["torque_Nm"]) / kt < lim["i_max_A"]
    w_max = rpm_to_radps(max(abs(e["speed_rpm"]) for e in d["reference"]))
    w_e = m["pole_pairs"] * w_max
    # steady state at the highest speed with the largest load: |u_dq| within the linear range
    iq = max([abs(e["torque_Nm"]) for e in d["load"]] + [0.0]) / kt
    ud = -w_e * m["Lq_H"] * iq
    uq = m["Rs_ohm"] * iq + w_e * m["psi_f_Wb"]
    assert math.hypot(ud, uq) < lim["u_dc_V"] / math.sqrt(3)


def schedule(data, name, key):
    return [(e["t_s"], e[key]) for e in data[name]]


def test_preset_schedules_follow_the_paper():
    """Section 4.1 conditions 1 and 2, section 4.2 experiments 1 to 3."""
    d = load_scenario("paper-condition-1").data
    assert schedule(d, "reference", "speed_rpm") == [(0.0, 500.0), (5.0, 200.0)] and d["load"] == []
    d = load_scenario("paper-condition-2").data
    assert schedule(d, "reference", "speed_rpm") == [(0.0, 500.0), (10.0, 200.0)]
    assert schedule(d, "load", "torque_Nm") == [(7.0, 8.0)]
    assert d["speed_controller"]["feedforward"] == "lowpass"  # Fig. 10: the 2DOF of eq 15
    d = load_scenario("paper-experiment-1").data
    assert schedule(d, "reference", "speed_rpm") == [(0.5, 500.0)] and d["load"] == []
    d = load_scenario("paper-experiment-2").data
    assert [v for _, v in schedule(d, "reference", "speed_rpm")] == [500.0, 200.0] and d["load"] == []
    d = load_scenario("paper-experiment-3").data
    assert d["simulation"]["speed0_rpm"] == 500.0
    assert schedule(d, "reference", "speed_rpm") == [(0.0, 500.0)]
    assert schedule(d, "load", "torque_Nm") == [(0.5, 8.0)]


@pytest.mark.parametrize("name", list_presets())
def test_preset_data_is_complete_and_round_trips(name):
    s = load_scenario(name)
    d = s.data
    for f in SCHEMA:
        if "[]" in f.key:
            for entry in d[f.key.split("[]")[0]]:
                assert f.leaf in entry
        else:
            node = d
            for part in f.key.split("."):
                node = node[part]
    assert s.name == d["name"] and s.description
    assert load_scenario_text(s.to_toml()) == s
    assert Scenario.from_dict(d) == s


def load_scenario_text(text):
    return Scenario.from_dict(tomllib.loads(text))


def test_load_scenario_from_a_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(load_scenario("paper-condition-1").with_overrides({"name": "mine"}).to_toml())
    s = load_scenario(path)
    assert s.name == "mine"
    assert load_scenario(str(path)) == s


def test_round_trip_through_a_file_keeps_defaults_and_derived_values(tmp_path):
    s = load_scenario("paper-condition-2").with_overrides({"speed_controller.Ka": 2.5, "motor.J_kgm2": 0.5})
    path = tmp_path / "s.toml"
    path.write_text(s.to_toml())
    back = load_scenario(path)
    assert back == s
    assert back.data["speed_controller"]["J_kgm2"] == 0.5
    assert back.data["speed_controller"]["Ka"] == 2.5


def test_unknown_preset_lists_the_presets():
    with pytest.raises(ConfigError) as exc:
        load_scenario("paper-condition-9")
    assert exc.value.param == "scenario"
    for name in PAPER_PRESETS:
        assert name in str(exc.value)


def test_defaults_are_filled():
    text = """
name = "minimal"
[motor]
pole_pairs = 2
Rs_ohm = 1
Ld_H = 0.002
Lq_H = 0.003
psi_f_Wb = 0.1
J_kgm2 = 0.01
[limits]
i_max_A = 10
u_dc_V = 48
[current_loop]
model = "first_order"
tau_i_s = 0.001
Ts_s = 0.0001
[speed_controller]
alpha_radps = 20
zeta = 0.7
Ts_s = 0.0005
[simulation]
t_end_s = 1
[[reference]]
t_s = 0
speed_rpm = 100
"""
    d = load_scenario_text(text).data
    assert d["motor"]["Rs_ohm"] == 1.0 and isinstance(d["motor"]["Rs_ohm"], float)
    assert d["motor"]["B_Nms"] == 0.0 and d["motor"]["T_coulomb_Nm"] == 0.0
    assert d["inverter"] == {"computation_delay": False}
    assert d["current_loop"]["decouple"] is True
    assert d["current_loop"]["anti_windup"] == "back_calculation"
    assert d["current_loop"]["method"] == "tustin"
    sc = d["speed_controller"]
    assert (sc["m"], sc["feedforward"], sc["anti_windup"], sc["method"]) == (
        1.0,
        "lowpass",
        "back_calculation",
        "tustin",
    )
    assert sc["Ka"] is None
    assert sc["J_kgm2"] == 0.01 and sc["tau_i_s"] == 0.001
    assert d["simulation"]["log_every"] == 1 and d["simulation"]["speed0_rpm"] == 0.0
    assert d["simulation"]["dt_s"] > 0
    assert d["load"] == []
    assert d["reference"] == [{"t_s": 0.0, "speed_rpm": 100.0, "ramp_s": 0.0}]
    assert d["description"] == ""


@pytest.mark.parametrize("ts_speed", [1e-3, 3e-4, 1e-4, 0.7e-3])
def test_ts_speed_integer_multiples_are_accepted(ts_speed):
    """0.001 / 0.0001 is 10.000000000000002 in binary floating point: within the 1e-9 tolerance."""
    s = load_scenario("paper-condition-2").with_overrides({"speed_controller.Ts_s": ts_speed})
    assert s.data["speed_controller"]["Ts_s"] == ts_speed


# --- the corpus of broken files --------------------------------------------------------------


def test_corpus_is_not_empty():
    assert len(BAD) >= 30


@pytest.mark.parametrize("path", BAD, ids=[p.stem for p in BAD])
def test_bad_scenario_names_the_key(path):
    key = re.match(r"# must name: (\S+)", path.read_text()).group(1)
    with pytest.raises(ConfigError) as exc:
        load_scenario(path)
    message = str(exc.value)
    assert exc.value.param == key
    assert message.startswith(f"{key} = ")
    assert "valid range is" in message and "\n" not in message


@pytest.mark.parametrize(
    "stem, hint",
    [
        ("unknown_key_case", "did you mean 'motor.Rs_ohm'"),
        ("unknown_key_wrong_table", "did you mean 'limits.i_max_A'"),
        ("unknown_table", "did you mean 'simulation'"),
        ("unknown_key_top_level", "did you mean 'current_loop.Ts_s' or 'speed_controller.Ts_s'"),
        ("unknown_key_in_entry", "did you mean 'load.0.torque_Nm'"),
        ("lowpass_m_not_1", "no_tau"),
        ("ts_not_multiple", "integer multiple"),
        ("missing_motor_J", "required"),
        ("wrong_type_bool_number", "finite number"),
        ("huge_t_end", "<= 36000"),
    ],
)
def test_bad_scenario_message_helps(stem, hint):
    with pytest.raises(ConfigError, match=re.escape(hint)):
        load_scenario(Path(__file__).parent / "bad_scenarios" / f"{stem}.toml")


# --- overrides -------------------------------------------------------------------------------


def test_overrides_by_dotted_key_and_index():
    base = load_scenario("paper-condition-2")
    s = base.with_overrides(
        {"speed_controller.anti_windup": "none", "reference.0.speed_rpm": 300, "load.0.ramp_s": 0.5}
    )
    d = s.data
    assert d["speed_controller"]["anti_windup"] == "none"
    assert d["reference"][0]["speed_rpm"] == 300.0
    assert d["load"][0] == {"t_s": 7.0, "torque_Nm": 8.0, "ramp_s": 0.5}
    # the original is untouched
    assert base.data["speed_controller"]["anti_windup"] == "back_calculation"
    assert base.data["reference"][0]["speed_rpm"] == 500.0


def test_overrides_append_replace_and_reset():
    base = load_scenario("paper-condition-1")
    s = base.with_overrides({"load.0.t_s": 2.0, "load.0.torque_Nm": 3.0})
    assert s.data["load"] == [{"t_s": 2.0, "torque_Nm": 3.0, "ramp_s": 0.0}]
    s = base.with_overrides({"reference": [{"t_s": 1.0, "speed_rpm": -100.0, "ramp_s": 2.0}]})
    assert s.data["reference"] == [{"t_s": 1.0, "speed_rpm": -100.0, "ramp_s": 2.0}]
    s = base.with_overrides({"speed_controller.Ka": 3.0}).with_overrides({"speed_controller.Ka": None})
    assert s.data["speed_controller"]["Ka"] is None
    assert s == base


def test_derived_defaults_follow_their_source_unless_given():
    base = load_scenario("paper-condition-2")
    s = base.with_overrides({"motor.J_kgm2": 0.6, "current_loop.tau_i_s": 0.02})
    assert s.data["speed_controller"]["J_kgm2"] == 0.6
    assert s.data["speed_controller"]["tau_i_s"] == 0.02
    s = base.with_overrides({"speed_controller.J_kgm2": 0.4, "motor.J_kgm2": 0.8})
    assert s.data["speed_controller"]["J_kgm2"] == 0.4
    assert s.data["motor"]["J_kgm2"] == 0.8


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"motor.J_kgm": 1.0}, "motor.J_kgm"),
        ({"motor.J_kgm2": 0}, "motor.J_kgm2"),
        ({"motor.J_kgm2": float("nan")}, "motor.J_kgm2"),
        ({"reference.5.speed_rpm": 1.0}, "reference.5"),
        ({"reference.x.speed_rpm": 1.0}, "reference.x"),
        ({"motor.J_kgm2.x": 1.0}, "motor.J_kgm2.x"),
        ({"reference.0.speed_rpm": "fast"}, "reference.0.speed_rpm"),
        ({"simulation.t_end_s": 5.0}, "reference.1.t_s"),
        ({"current_loop.Ts_s": 3e-4}, "speed_controller.Ts_s"),
        ({"speed_controller.m": 0.5}, "speed_controller.m"),
        ({"": 1}, "override key"),
        ({"motor.J_kgm2": 10**400}, "motor.J_kgm2"),
        ({"speed_controller.Ts_s": 1e300, "current_loop.Ts_s": 1e-300}, "speed_controller.Ts_s"),
    ],
)
def test_bad_overrides_name_the_key(overrides, key):
    with pytest.raises(ConfigError) as exc:
        load_scenario("paper-condition-2").with_overrides(overrides)
    assert exc.value.param == key


def test_m_other_than_1_is_accepted_with_the_general_feedforward():
    s = load_scenario("paper-condition-2").with_overrides(
        {"speed_controller.m": 2.0, "speed_controller.feedforward": "no_tau"}
    )
    assert s.data["speed_controller"]["m"] == 2.0


def test_scenario_is_immutable():
    s = load_scenario("paper-condition-2")
    with pytest.raises(AttributeError):
        s.name = "x"
    d = s.data
    d["motor"]["J_kgm2"] = 99.0
    assert s.data["motor"]["J_kgm2"] == 0.4


@pytest.mark.parametrize(
    "text, expected",
    [
        ("speed_controller.alpha_radps=0.7", ("speed_controller.alpha_radps", 0.7)),
        ("simulation.log_every = 10", ("simulation.log_every", 10)),
        ("inverter.computation_delay=true", ("inverter.computation_delay", True)),
        ("speed_controller.feedforward=none", ("speed_controller.feedforward", "none")),
        ('name="a b"', ("name", "a b")),
        ("name=a = b", ("name", "a = b")),
        ("load=[{t_s = 1.0, torque_Nm = 2.0}]", ("load", [{"t_s": 1.0, "torque_Nm": 2.0}])),
        ("reference.0.speed_rpm=-300", ("reference.0.speed_rpm", -300)),
        ("motor.J_kgm2=1\nx = 2", ("motor.J_kgm2", "1\nx = 2")),
    ],
)
def test_parse_override(text, expected):
    assert parse_override(text) == expected


def test_parse_override_nan_is_rejected_when_applied():
    key, value = parse_override("motor.J_kgm2=nan")
    assert math.isnan(value)
    with pytest.raises(ConfigError, match="motor.J_kgm2"):
        load_scenario("paper-condition-2").with_overrides({key: value})


@pytest.mark.parametrize("text", ["motor.J_kgm2", "=1", " = 1"])
def test_parse_override_needs_key_and_value(text):
    with pytest.raises(ConfigError, match="--set"):
        parse_override(text)


positive = st.floats(min_value=1e-6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    J=positive,
    Rs=positive,
    alpha=positive,
    speed=st.floats(-1e4, 1e4),
    Ka=st.none() | positive,
    name=st.text(max_size=20),
    n=st.integers(1, 50),
    delay=st.booleans(),
)
def test_round_trip_property(J, Rs, alpha, speed, Ka, name, n, delay):
    """load(to_toml(s)) == s for any valid values, including awkward floats and strings."""
    s = load_scenario("paper-condition-2").with_overrides(
        {
            "motor.J_kgm2": J,
            "motor.Rs_ohm": Rs,
            "speed_controller.alpha_radps": alpha,
            "reference.1.speed_rpm": speed,
            "speed_controller.Ka": Ka,
            "name": name,
            "speed_controller.Ts_s": n * 1e-4,
            "inverter.computation_delay": delay,
        }
    )
    assert load_scenario_text(s.to_toml()) == s


@pytest.mark.parametrize(
    "name", ["tab\there", 'quote " and \\ backslash', "line\nbreak", "del \x7f", "nul \x00", "Grüße, 速度"]
)
def test_round_trip_of_awkward_strings(name):
    s = load_scenario("paper-condition-2").with_overrides({"name": name, "description": name})
    assert load_scenario_text(s.to_toml()) == s


def test_strings_must_be_unicode():
    with pytest.raises(ConfigError, match="name"):
        load_scenario("paper-condition-2").with_overrides({"name": "lone \ud800 surrogate"})


def test_schema_reference_documents_every_key():
    text = schema_reference()
    for f in SCHEMA:
        assert f.key in text


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("speed_controller.alpha", "speed_controller.alpha_radps"),
        ("speed_controller.discretization", "speed_controller.method"),
        ("speed_controller.J_design_kgm2", "speed_controller.J_kgm2"),
        ("speed_controller.tau_i_design_s", "speed_controller.tau_i_s"),
        ("current_loop.discretization", "current_loop.method"),
    ],
)
def test_a_renamed_key_is_refused_with_its_new_name(tmp_path, old, new):
    """docs/conventions.md: scenario keys are the API's argument names; an old file says what to write."""
    table, leaf = old.split(".")
    text = load_scenario("paper-condition-1").to_toml()
    value = '"tustin"' if leaf == "discretization" else "0.5"
    text = text.replace(f"[{table}]\n", f"[{table}]\n{leaf} = {value}\n", 1)
    (tmp_path / "old.toml").write_text(text)
    with pytest.raises(ConfigError) as err:
        load_scenario(tmp_path / "old.toml")
    assert err.value.param == old
    assert f"renamed to '{new}'" in str(err.value)


def test_conventions_page_lists_every_renamed_key():
    from pmsm2dof.sim.scenario import RENAMED_KEYS

    page = (Path(__file__).parents[1] / "docs" / "conventions.md").read_text()
    for old, new in RENAMED_KEYS.items():
        assert f"| `{old}` | `{new}` |" in page
