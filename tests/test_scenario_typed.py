"""The typed scenario: its tables hold every key, and a change checks no less than a whole validation.

:meth:`Scenario.with_overrides` validates only the tables an override touches (the others are
shared with the scenario it changes) and the relations between keys. Its truth here is the
validation of the whole changed tree by :meth:`Scenario.from_dict`, the tree built by a dotted-key
setter written in this file: for any overrides, both give equal scenarios (the same TOML) or the same
error.
"""

import copy
import dataclasses
import math
import pickle
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import SCHEMA, Scenario, list_presets, load_scenario
from pmsm2dof.sim.scenario_tables import ARRAYS, ENTRIES, TABLES

#: Bases that exercise the derived defaults: the estimator's J0 (speed_controller.J_kgm2, itself
#: motor.J_kgm2's), a two-mass design inertia, faults and sensor keys.
BASES = {
    "estimator": load_scenario("paper-condition-2").with_overrides(
        {"estimator.enabled": True, "speed_sensor.model": "encoder"}
    ),
    "two-mass": load_scenario("paper-condition-2").with_overrides(
        {"mechanics.model": "two_mass", "mechanics.J_load_kgm2": 0.2, "mechanics.stiffness_Nm_per_rad": 400.0}
    ),
    "fault": load_scenario("fault-sensor-spike"),
}

SCALAR_KEYS = [f.key for f in SCHEMA if "[]" not in f.key]
ENTRY_KEYS = ["reference.0.speed_rpm", "reference.1.t_s", "reference.2.t_s", "load.0.torque_Nm", "fault.0.kind"]
#: Values valid somewhere and wrong elsewhere: types, signs, choices, None (removes the key).
VALUES = [
    None,
    0,
    0.0,
    -1.0,
    1e-4,
    0.05,
    0.4,
    1.0,
    2,
    3.5,
    1e9,
    math.nan,
    True,
    False,
    "pll",
    "two_mass",
    "encoder",
    "q15",
    "full",
    "none",
    "x",
    [],
    {},
    [{"t_s": 0.5, "torque_Nm": 2.0}],
    {"t_s": 1.0},
]
TABLE_KEYS = [*TABLES, *ARRAYS, "name", "nonsense", "motor.nonsense", "reference.9.t_s", "motor.J_kgm2.x", ""]


def raw_tree(scenario):
    """The scenario's keys as given, read back from its TOML (independent of its own tree)."""
    return tomllib.loads(scenario.to_toml())


def set_dotted(tree, key, value):
    """Set the dotted ``key`` of ``tree`` (tables by name, arrays by index, one past the end appends),
    ``None`` removing it; raise KeyError where the path does not exist as such."""
    parts = key.split(".")
    if not all(parts):
        raise KeyError(key)
    node = tree
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        if isinstance(node, list):
            index = int(part)
            if index == len(node):
                node.append({})
            if last:
                node[index] = value
            else:
                node = node[index]
        elif last:
            if value is None:
                node.pop(part, None)
            else:
                node[part] = value
        else:
            node = node.setdefault(part, [] if part in ARRAYS and depth == 0 else {})


def outcome(make):
    """("ok", scenario) or ("error", str(ConfigError))."""
    try:
        return "ok", make()
    except ConfigError as exc:
        return "error", str(exc)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    base=st.sampled_from(sorted(BASES)),
    overrides=st.dictionaries(
        st.sampled_from(SCALAR_KEYS + ENTRY_KEYS + TABLE_KEYS), st.sampled_from(VALUES), min_size=1, max_size=3
    ),
)
def test_a_change_is_checked_as_the_whole_tree_is(base, overrides):
    scenario = BASES[base]
    tree = raw_tree(scenario)
    try:
        for key, value in overrides.items():
            set_dotted(tree, key, copy.deepcopy(value))
    except (KeyError, ValueError, IndexError, TypeError, AttributeError):
        # a path the tree does not have: the override is refused, naming its key
        kind, got = outcome(lambda: scenario.with_overrides(overrides))
        assert kind == "error", overrides
        return
    changed = outcome(lambda: scenario.with_overrides(overrides))
    whole = outcome(lambda: Scenario.from_dict(tree))
    assert changed[0] == whole[0], (overrides, changed, whole)
    if changed[0] == "error":
        assert changed[1] == whole[1]
    else:
        assert changed[1] == whole[1]
        assert changed[1].to_toml() == whole[1].to_toml()
        assert changed[1].data == whole[1].data


def test_a_change_shares_the_tables_it_does_not_touch():
    base = BASES["estimator"]
    alpha = base.with_overrides({"speed_controller.alpha_radps": 2.0})
    assert alpha.speed_controller.alpha_radps == 2.0 and base.speed_controller.alpha_radps != 2.0
    for name in TABLES:
        if name not in ("speed_controller", "estimator"):
            assert getattr(alpha, name) is getattr(base, name), name
    assert alpha._given["motor"] is base._given["motor"]
    # motor.J_kgm2 is the default of speed_controller.J_kgm2, which is estimator.J0_kgm2's
    heavy = base.with_overrides({"motor.J_kgm2": 0.9})
    assert heavy.speed_controller.J_kgm2 == 0.9 and heavy.estimator.J0_kgm2 == 0.9
    assert heavy.limits is base.limits


def test_the_design_inertia_of_a_two_mass_train_is_the_total_and_the_estimator_starts_at_the_motor():
    base = BASES["two-mass"]
    assert base.speed_controller.J_kgm2 == pytest.approx(0.4 + 0.2)
    assert base.estimator.J0_kgm2 == 0.4  # the SameAs default taken before the two-mass design
    lighter = base.with_overrides({"mechanics.J_load_kgm2": 0.1})
    assert lighter.speed_controller.J_kgm2 == pytest.approx(0.5)
    assert lighter == Scenario.from_dict(raw_tree(lighter))


@pytest.mark.parametrize("name", list_presets())
def test_the_tables_hold_every_key_of_the_data(name):
    scenario = load_scenario(name)
    data = scenario.data
    for f in SCHEMA:
        if "[]" in f.key:
            array, leaf = f.key.split("[].")
            assert [getattr(e, leaf) for e in getattr(scenario, array)] == [e[leaf] for e in data[array]], f.key
        elif "." in f.key:
            table, leaf = f.key.split(".")
            value = getattr(getattr(scenario, table), leaf)
            assert value == data[table][leaf] and type(value) is type(data[table][leaf]), f.key
            assert value is None or isinstance(value, f.kind), f.key
        else:
            assert getattr(scenario, f.key) == data[f.key]


def test_each_table_declares_its_keys_in_file_order():
    declared = [f"{name}.{field.name}" for name, table in TABLES.items() for field in dataclasses.fields(table)]
    declared += [f"{name}[].{field.name}" for name, entry in ENTRIES.items() for field in dataclasses.fields(entry)]
    assert declared == [f.key for f in SCHEMA if "." in f.key]
    scenario = load_scenario("paper-condition-2")
    with pytest.raises(dataclasses.FrozenInstanceError):
        scenario.speed_controller.alpha_radps = 1.0
    with pytest.raises(AttributeError, match="immutable"):
        scenario.motor = scenario.motor


def test_a_scenario_pickles_and_compares_by_value():
    scenario = BASES["fault"].with_overrides({"speed_controller.Ka": 2.0})
    back = pickle.loads(pickle.dumps(scenario))
    assert back == scenario and back.to_toml() == scenario.to_toml()
    assert back.fault == scenario.fault and back.speed_controller.Ka == 2.0
    assert back.with_overrides({"speed_controller.Ka": 3.0}) != scenario
    assert back.with_overrides({"speed_controller.Ka": 2.0}) == scenario


def test_a_controller_key_is_described_by_its_c_field_comment():
    """One source per fact: the meaning, unit and range of a key that a C field holds under its name are that
    field's comment in the C header (compiled into the extension from csrc/), read here from the header text."""
    from pathlib import Path

    from pmsm2dof.core.cheaders import field_comments
    from pmsm2dof.sim.engine_keys import c_field
    from pmsm2dof.sim.scenario_keys import FromC
    from pmsm2dof.sim.scenario_schema import FIELDS

    root = Path(__file__).resolve().parents[1] / "csrc"
    headers = field_comments(p.read_text() for p in sorted(root.glob("**/*.h")))
    speed_h = (root / "include/pmsm2dof/speed.h").read_text()
    assert "bandwidth of the P loop [rad/s], > 0 (eq 9)" in speed_h
    assert FIELDS["speed_controller.alpha_radps"].doc == "bandwidth of the P loop [rad/s], > 0 (eq 9)"
    from_c = 0
    for name, table in TABLES.items():
        for field in dataclasses.fields(table):
            key = f"{name}.{field.name}"
            where = c_field(key)
            if isinstance(field.metadata["key"].doc, FromC):
                assert where is not None, key
                assert FIELDS[key].doc.startswith(headers[f"{where[0]}.{where[1]}"]), key
                from_c += 1
            elif where is not None:
                # a choice or a switch: its words say what each choice does, the C comment only names them
                assert FIELDS[key].choices or FIELDS[key].kind is bool, key
    assert from_c >= 50


def test_a_key_declared_from_c_without_a_c_field_is_refused():
    from pmsm2dof.sim.scenario_keys import from_c
    from pmsm2dof.sim.scenario_schema import _c_doc

    with pytest.raises(RuntimeError, match="fills no commented field"):
        _c_doc("limits.u_dc_V", from_c())
