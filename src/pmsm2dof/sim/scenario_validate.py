"""Validation of a scenario tree against the schema, and its typed tables built once from the keys given.

:func:`validate` checks the keys of each table of a nested dict (as read from TOML) against
:data:`~pmsm2dof.sim.scenario_schema.SCHEMA` and returns the keys given, converted; it can check
only the tables a change touched, the others taken as already checked. :func:`build` resolves the
defaults, builds the typed tables (:mod:`pmsm2dof.sim.scenario_tables`) and checks the relations
between keys, which involve more than one table. A bad value raises
:class:`~pmsm2dof.errors.ConfigError` naming the dotted key (``motor.J_kgm2``, ``reference.1.t_s``),
its value and its valid range.
"""

import dataclasses
import difflib
import math
from collections.abc import Collection, Mapping
from typing import Any

from ..core.motor import motor_from_table
from ..errors import ConfigError
from .scenario_keys import (
    ARRAY_VALUE,
    REQUIRED,
    SENSOR_DELAY_MAX_PERIODS,
    TABLE_VALUE,
    TS_MULTIPLE_RTOL,
    SameAs,
    Tree,
)
from .scenario_schema import FIELDS, FIELDS_OF, RENAMED_KEYS, SCHEMA
from .scenario_tables import (
    ARRAYS,
    ENTRIES,
    TABLES,
    CurrentLoopTable,
    FaultEntry,
    FieldWeakeningTable,
    MechanicsTable,
    SpeedControllerTable,
    SpeedFilterTable,
)

#: The full scales of the fixed-point speed controllers (speed_controller.*).
FULL_SCALE_KEYS = ("speed_full_scale_rpm", "torque_full_scale_Nm", "current_full_scale_A")

#: The keys whose default is another key's value: (table, leaf, source table, source leaf).
_SAME_AS = tuple((f.parent, f.leaf, *f.default.key.split(".")) for f in SCHEMA if isinstance(f.default, SameAs))


#: The defaults of each table's keys: (leaf, default) in file order.
_DEFAULTS = {name: tuple((f.leaf, f.default) for f in FIELDS_OF[name]) for name in TABLES}

#: The tables each table takes a default from: the SameAs defaults, and the design inertia of a two-mass
#: train (``speed_controller.J_kgm2``: motor and load, :func:`build`).
_SOURCES: dict[str, set[str]] = {name: set() for name in TABLES}
for _parent, _, _source, _ in _SAME_AS:
    _SOURCES[_parent].add(_source)
_SOURCES["speed_controller"] |= {"motor", "mechanics"}


def _affected(touched: Collection[str]) -> set[str]:
    """The tables whose values change with those named in ``touched``: they, and those that take a default
    from one of them, again and again."""
    affected = {name for name in touched if name in TABLES}
    while True:
        more = {name for name, sources in _SOURCES.items() if sources & affected} - affected
        if not more:
            return affected
        affected |= more


def short(value: object) -> object:
    """The value as shown in an error message (tables and arrays are not spelled out)."""
    if isinstance(value, dict):
        return TABLE_VALUE
    if isinstance(value, list):
        return ARRAY_VALUE
    return value


def _unknown_key(dotted: str, value: object, parent: str, valid: list[str]) -> None:
    """ConfigError for an unknown key, suggesting the closest valid one."""
    renamed = RENAMED_KEYS.get(f"{parent}.{dotted.rsplit('.', 1)[-1]}" if parent else dotted)
    if renamed is not None:
        raise ConfigError(dotted, short(value), f"a key renamed to '{renamed}' (same meaning and unit)")
    leaf = dotted.rsplit(".", 1)[-1]
    where = f"[{parent}]" if parent else "the top level"
    prefix = f"{parent}." if parent else ""
    same_case = [v for v in valid if v.lower() == leaf.lower()]
    elsewhere = [f"'{f.key.replace('[]', '.0')}'" for f in SCHEMA if f.leaf.lower() == leaf.lower()]
    close = difflib.get_close_matches(leaf, valid, n=1, cutoff=0.6)
    if same_case:
        hint = f"did you mean '{prefix}{same_case[0]}'?"
    elif elsewhere:
        hint = f"did you mean {' or '.join(elsewhere)}?"
    elif close:
        hint = f"did you mean '{prefix}{close[0]}'?"
    else:
        hint = "valid keys: " + ", ".join(valid)
    raise ConfigError(dotted, short(value), f"not a key of {where} ({hint})")


#: The names that may appear at the top level besides its keys: the tables and the arrays.
_SUB = [*TABLES, *ARRAYS]


def _validate_table(table: Tree, parent: str, prefix: str) -> Tree:
    """Check the keys of one table against the schema; return {leaf: value} of the keys given.

    ``parent`` is the schema parent (``"motor"``, ``"reference[]"``), ``prefix`` the dotted
    name used in messages (``"motor"``, ``"reference.2"``).
    """
    fields = FIELDS_OF[parent]
    sub = _SUB if parent == "" else []
    valid = [f.leaf for f in fields] + sub
    given: Tree = {}
    for key, value in table.items():
        dotted = f"{prefix}.{key}" if prefix else key
        if key not in valid:
            _unknown_key(dotted, value, prefix, valid)
        if key in sub:
            continue
        if value is not None:
            given[key] = FIELDS[f"{parent}.{key}" if parent else key].check(dotted, value)
    for f in fields:
        if f.default is REQUIRED and f.leaf not in given:
            raise ConfigError(
                f"{prefix}.{f.leaf}" if prefix else f.leaf, REQUIRED, f"required: {f.valid_range()} ({f.doc})"
            )
    return given


def _as_table(value: object, dotted: str) -> Tree:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(dotted, short(value), "a table of keys")
    return value


def validate(tree: object, checked: Tree | None = None, touched: Collection[str] = ()) -> Tree:
    """Validate a scenario tree; return the keys given, converted to their types (absent tables left out).

    Parameters
    ----------
    tree : object
        The scenario as nested tables (a dict; ``None`` means absent). It is not changed.
    checked : dict, optional
        The keys given of a validated scenario from which ``tree`` differs only in the tables and arrays
        named in ``touched`` (and in its top-level keys): the other tables are taken from it unchecked.
    touched : collection of str
        With ``checked``: the tables and arrays that changed.
    """
    table = _as_table(tree, "scenario")
    motor = table.get("motor")
    if (checked is None or "motor" in touched) and isinstance(motor, dict) and "datasheet" in motor:
        # [motor.datasheet]: the model keys converted from datasheet units (pmsm2dof.core.motor)
        converted = motor_from_table(motor).motor_table()
        table = {**table, "motor": {**{k: v for k, v in motor.items() if k != "datasheet"}, **converted}}
    given = _validate_table(table, "", "")
    for name in TABLES:
        if checked is not None and name not in touched:
            if name in checked:
                given[name] = checked[name]
            continue
        values = _validate_table(_as_table(table.get(name), name), name, name)
        if values:
            given[name] = values
    for name, (required, what) in ARRAYS.items():
        if checked is not None and name not in touched:
            if name in checked:
                given[name] = checked[name]
            continue
        entries = table.get(name)
        if entries is None and not required:
            continue
        valid = f"an array of tables [[{name}]]{' with at least one entry' if required else ''} ({what})"
        if not isinstance(entries, list) or (required and not entries):
            raise ConfigError(name, REQUIRED if entries is None else short(entries), valid)
        for i, e in enumerate(entries):
            if not isinstance(e, dict):
                raise ConfigError(f"{name}.{i}", e, f"a table, one entry of {valid}")
        given[name] = [_validate_table(e, f"{name}[]", f"{name}.{i}") for i, e in enumerate(entries)]
    return given


def build(given: Tree, previous: Mapping[str, Any] | None = None, touched: Collection[str] = ()) -> dict[str, Any]:
    """The typed tables of the validated keys ``given`` (:func:`validate`), by name, defaults resolved, after
    the checks of the relations between keys: ``{"name": ..., "motor": MotorTable, ..., "reference": (...)}``.

    With ``previous``, the tables of a scenario from which ``given`` differs only in the tables named in
    ``touched``: the tables that neither changed nor take a default from one that did are taken from it.
    """
    rebuilt = set(TABLES) if previous is None else _affected(touched)
    needed = set(rebuilt)  # and the tables they take a SameAs default from (before a two-mass design)
    for parent, _, source, _ in reversed(_SAME_AS):
        if parent in needed:
            needed.add(source)
    values: dict[str, Tree] = {}
    for name in needed:
        table = given.get(name, {})
        values[name] = {leaf: table.get(leaf, default) for leaf, default in _DEFAULTS[name]}
    for parent, leaf, source, source_leaf in _SAME_AS:
        if parent in needed and leaf not in given.get(parent, {}):
            values[parent][leaf] = values[source][source_leaf]
    tables: dict[str, Any] = {f.leaf: given.get(f.leaf, f.default) for f in FIELDS_OF[""]}
    for name, cls in TABLES.items():
        tables[name] = cls(**values[name]) if name in rebuilt or previous is None else previous[name]
    _check_mechanics(tables["mechanics"], tables["speed_filter"])
    mech: MechanicsTable = tables["mechanics"]
    if "speed_controller" in rebuilt and mech.model == "two_mass" and "J_kgm2" not in given.get("speed_controller", {}):
        # the eq 9 design on the total inertia of the drive train
        assert mech.J_load_kgm2 is not None  # required by two_mass (_check_mechanics)
        J_total = tables["motor"].J_kgm2 + mech.J_load_kgm2
        tables["speed_controller"] = dataclasses.replace(tables["speed_controller"], J_kgm2=J_total)
    for name, entry in ENTRIES.items():
        fields = FIELDS_OF[f"{name}[]"]
        tables[name] = tuple(entry(**{f.leaf: e.get(f.leaf, f.default) for f in fields}) for e in given.get(name, []))
    _check_relations(tables)
    return tables


def _check_mechanics(mech: MechanicsTable, filt: SpeedFilterTable) -> None:
    """A two-mass train has its load inertia and stiffness; a rigid one none of the two-mass keys;
    each torque filter has its width/depth or damping when it is on."""
    two_mass_keys = ("J_load_kgm2", "stiffness_Nm_per_rad")
    for leaf in two_mass_keys:
        field = FIELDS[f"mechanics.{leaf}"]
        if mech.model == "two_mass" and getattr(mech, leaf) is None:
            raise ConfigError(
                f"mechanics.{leaf}", REQUIRED, f"required by model 'two_mass': {field.valid_range()} ({field.doc})"
            )
    if mech.model == "rigid":
        for leaf in (*two_mass_keys, "damping_Nms_per_rad", "backlash_rad"):
            if getattr(mech, leaf) not in (None, 0.0):
                raise ConfigError(f"mechanics.{leaf}", getattr(mech, leaf), "absent: model 'rigid' does not use it")
    for on, leaves in (("notch_freq_Hz", ("notch_width_Hz",)), ("lowpass_freq_Hz", ("lowpass_zeta",))):
        for leaf in leaves:
            if getattr(filt, on) > 0 and not getattr(filt, leaf) > 0:
                raise ConfigError(f"speed_filter.{leaf}", getattr(filt, leaf), f"> 0 with speed_filter.{on} > 0")


def _check_relations(tables: dict[str, Any]) -> None:
    """The checks that involve more than one key."""
    sc: SpeedControllerTable = tables["speed_controller"]
    cl: CurrentLoopTable = tables["current_loop"]
    t_end_s: float = tables["simulation"].t_end_s
    ratio = sc.Ts_s / cl.Ts_s
    n = round(ratio) if math.isfinite(ratio) else 0
    if n < 1 or abs(sc.Ts_s - n * cl.Ts_s) > TS_MULTIPLE_RTOL * sc.Ts_s:
        raise ConfigError(
            "speed_controller.Ts_s", sc.Ts_s, f"an integer multiple (1, 2, 3, ...) of current_loop.Ts_s = {cl.Ts_s!r}"
        )
    if sc.feedforward == "lowpass" and sc.m != 1.0:
        raise ConfigError(
            "speed_controller.m",
            sc.m,
            "exactly 1 with feedforward 'lowpass' (eq 13 is eq 11 with m = 1 and tau_i = 0); "
            "for m != 1 use feedforward 'no_tau' (eq 11 with tau_i = 0) or 'full'",
        )
    if cl.model == "dq_pi" and cl.tau_i_s < cl.Ts_s:
        raise ConfigError(
            "current_loop.tau_i_s",
            cl.tau_i_s,
            f">= current_loop.Ts_s = {cl.Ts_s!r} (the dq current PIs cannot be faster than their sampling)",
        )
    for name in ("reference", "load"):
        entries = tables[name]
        for i, e in enumerate(entries):
            if e.t_s >= t_end_s:
                raise ConfigError(f"{name}.{i}.t_s", e.t_s, f">= 0 and < simulation.t_end_s = {t_end_s!r}")
            if i > 0:
                prev = entries[i - 1]
                earliest = prev.t_s + prev.ramp_s
                if not (e.t_s > prev.t_s and e.t_s >= earliest):
                    raise ConfigError(
                        f"{name}.{i}.t_s",
                        e.t_s,
                        f"> {name}.{i - 1}.t_s = {prev.t_s!r} and >= the end of its ramp "
                        f"({earliest!r}): entries sorted by time, ramps not overlapping",
                    )
    _check_faults(tables["fault"], t_end_s, sc.Ts_s, cl.model)
    _check_sensing(tables)
    _check_arithmetic(tables)


def _check_arithmetic(tables: dict[str, Any]) -> None:
    """The full scales only with a fixed-point speed controller, which needs a surface PMSM and takes no
    torque filters, field weakening or gain scheduling (speed_fixed.h)."""
    sc: SpeedControllerTable = tables["speed_controller"]
    if sc.arithmetic == "float32":
        for leaf in FULL_SCALE_KEYS:
            if getattr(sc, leaf) is not None:
                raise ConfigError(
                    f"speed_controller.{leaf}", getattr(sc, leaf), "absent: arithmetic 'float32' has no full scales"
                )
        return
    fixed = f"with speed_controller.arithmetic {sc.arithmetic!r} (the fixed-point speed controllers have none)"
    for leaf in ("notch_freq_Hz", "lowpass_freq_Hz"):
        if getattr(tables["speed_filter"], leaf) != 0.0:
            raise ConfigError(
                f"speed_filter.{leaf}", getattr(tables["speed_filter"], leaf), f"0 (no torque filter) {fixed}"
            )
    if tables["field_weakening"].enabled:
        raise ConfigError("field_weakening.enabled", True, f"false {fixed}")
    if tables["estimator"].enabled and tables["estimator"].adapt_gains:
        raise ConfigError("estimator.adapt_gains", True, f"false (no gain scheduling) {fixed}")
    motor = tables["motor"]
    if motor.Lq_H != motor.Ld_H:
        raise ConfigError(
            "motor.Lq_H",
            motor.Lq_H,
            f"equal to motor.Ld_H = {motor.Ld_H!r} with speed_controller.arithmetic {sc.arithmetic!r} (the "
            "fixed-point speed controllers drive a surface PMSM: id = 0, no MTPA)",
        )


def _check_sensing(tables: dict[str, Any]) -> None:
    """The speed sensor, current measurement and field weakening against the other tables."""
    ss = tables["speed_sensor"]
    cl: CurrentLoopTable = tables["current_loop"]
    fw: FieldWeakeningTable = tables["field_weakening"]
    if ss.model == "ideal" and ss.estimator == "pll":
        raise ConfigError("speed_sensor.estimator", "pll", "'difference' with model 'ideal' (a PLL reads counts)")
    if ss.model == "encoder" and ss.estimator == "pll" and ss.bandwidth_radps is None:
        raise ConfigError(
            "speed_sensor.bandwidth_radps", REQUIRED, "required by estimator 'pll': the PLL's double pole [rad/s], > 0"
        )
    if ss.bandwidth_radps is not None and not (ss.model == "encoder" and ss.estimator == "pll"):
        raise ConfigError(
            "speed_sensor.bandwidth_radps",
            ss.bandwidth_radps,
            "absent: only model 'encoder' with estimator 'pll' uses it",
        )
    if ss.delay_s > SENSOR_DELAY_MAX_PERIODS * cl.Ts_s * (1.0 + TS_MULTIPLE_RTOL):
        raise ConfigError(
            "speed_sensor.delay_s",
            ss.delay_s,
            f"<= {SENSOR_DELAY_MAX_PERIODS} current_loop.Ts_s = {SENSOR_DELAY_MAX_PERIODS * cl.Ts_s:g} s",
        )
    cm = tables["current_measurement"]
    errors = (cm.gain_error_a, cm.gain_error_b, cm.offset_a_A, cm.offset_b_A, cm.noise_A_rms)
    if any(e != 0.0 for e in errors) and cl.model != "dq_pi":
        raise ConfigError(
            "current_loop.model", cl.model, "'dq_pi' with a [current_measurement] error (eq 3 measures nothing)"
        )
    if fw.enabled:
        if cl.model != "dq_pi":
            raise ConfigError(
                "current_loop.model", cl.model, "'dq_pi' with field_weakening.enabled (eq 3 has no voltage)"
            )
        if fw.Ki_A_per_Vs is None:
            field = FIELDS["field_weakening.Ki_A_per_Vs"]
            raise ConfigError("field_weakening.Ki_A_per_Vs", REQUIRED, f"required when enabled: {field.valid_range()}")


def _check_faults(faults: tuple[FaultEntry, ...], t_end_s: float, Ts_speed: float, current_model: str) -> None:
    """Each fault has the keys its kind uses, acts before t_end and, within its group (DC link or
    speed sensor), does not overlap another; a sensor_spike takes one speed period."""
    windows: dict[str, list[tuple[int, tuple[float, float]]]] = {"dc_link": [], "sensor": []}
    for i, f in enumerate(faults):
        kind = f.kind
        if f.t_s >= t_end_s:
            raise ConfigError(f"fault.{i}.t_s", f.t_s, f">= 0 and < simulation.t_end_s = {t_end_s!r}")
        uses = {
            "duration_s": kind != "sensor_spike",
            "u_dc_factor": kind == "dc_link_sag",
            "speed_rpm": kind == "sensor_spike",
        }
        for leaf, used in uses.items():
            if used and getattr(f, leaf) is None:
                field = FIELDS[f"fault[].{leaf}"]
                raise ConfigError(
                    f"fault.{i}.{leaf}", REQUIRED, f"required by kind {kind!r}: {field.valid_range()} ({field.doc})"
                )
            if not used and getattr(f, leaf) is not None:
                raise ConfigError(f"fault.{i}.{leaf}", getattr(f, leaf), f"absent: kind {kind!r} does not use it")
        if kind == "dc_link_sag" and current_model != "dq_pi":
            raise ConfigError(
                f"fault.{i}.kind",
                kind,
                "a sensor fault with current_loop.model 'first_order' "
                "(eq 3 has no inverter and no DC link): use 'dq_pi' for a DC-link sag",
            )
        group = "dc_link" if kind == "dc_link_sag" else "sensor"
        start = f.t_s
        if kind == "sensor_spike":
            end = start + Ts_speed
        else:
            assert f.duration_s is not None  # used by every other kind (checked above)
            end = start + f.duration_s
        tol = TS_MULTIPLE_RTOL * Ts_speed
        for j, (s0, s1) in windows[group]:
            if start < s1 - tol and s0 < end - tol:
                raise ConfigError(
                    f"fault.{i}.t_s",
                    start,
                    f"outside [{s0!r}, {s1!r}) s, the window of fault.{j}: faults of the "
                    f"{'DC link' if group == 'dc_link' else 'speed sensor'} do not overlap "
                    "(a sensor_spike takes one speed_controller.Ts_s)",
                )
        windows[group].append((i, (start, end)))
