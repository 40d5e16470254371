"""Scenarios: the drive, the controller and the test sequence of one simulation, as TOML.

A scenario file describes the motor (paper eq 1), the limits, the current loop (eq 3 or the
dq current controllers of Fig. 1), the speed controller (eq 9-15, Fig. 5 and 6), and the speed
reference and load torque schedules of a run (section 4.1)::

    name = "paper condition 2"
    [motor]
    pole_pairs = 4
    Rs_ohm = 0.5
    ...
    [[reference]]
    t_s = 0.0
    speed_rpm = 500.0

The motor may be given in datasheet units instead, as a ``[motor.datasheet]`` table (Kt, Ke or Kv,
line-to-line R and L, poles, sinusoidal or block commutation: see :mod:`pmsm2dof.core.motor`); it
provides ``pole_pairs``, ``Rs_ohm``, ``Ld_H``, ``Lq_H`` and ``psi_f_Wb`` (and the ratings it gives,
``i_rated_A``, ``i_peak_A``, ``J_rotor_kgm2``), which :meth:`Scenario.to_toml` writes as converted.

An optional ``[mechanics]`` table makes the load a two-mass drive train (the paper's conclusion:
motor and load inertia coupled by an elastic shaft), and ``[speed_filter]`` puts a notch and a
low-pass on the speed controller's torque command; both absent, the drive is the paper's.

Optional ``[[fault]]`` entries make the simulator play a fault: a DC-link sag over a window, or a
speed-sensor reading held, zero or wrong for one sample (see :data:`pmsm2dof.core.FAULT_KINDS`).

Every key, its type, valid range, default and meaning is declared once, as a field of the typed
table it belongs to (:mod:`pmsm2dof.sim.scenario_tables`), read into :data:`SCHEMA`
(:mod:`pmsm2dof.sim.scenario_schema`); that drives validation (:mod:`pmsm2dof.sim.scenario_validate`),
the defaults, :meth:`Scenario.to_toml` and :func:`schema_reference`. A :class:`Scenario` holds its
tables typed, built once after validation: ``scenario.speed_controller.alpha_radps``. A bad file raises
:class:`~pmsm2dof.errors.ConfigError` naming the dotted key (``motor.J_kgm2``, ``reference.1.t_s``) and
its valid range.

The paper's eq (1) writes ``Te = p0 (psi_f iq + ...)`` and calls p0 the number of poles while
using it as pole pairs; here ``motor.pole_pairs`` is the number of pole pairs and the torque is
amplitude invariant, ``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``.
"""

import copy
import importlib.resources
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..inputs import parse_toml, read_toml
from .scenario_keys import (
    REQUIRED,
    SENSOR_DELAY_MAX_PERIODS,
    STRING_CHARS_MAX,
    T_END_MAX_S,
    TS_MULTIPLE_RTOL,
    Field,
    SameAs,
    Tree,
    _Placeholder,
)
from .scenario_schema import FIELDS_OF, RENAMED_KEYS, SCHEMA, schema_reference, toml_value
from .scenario_tables import (
    ARRAYS,
    ENTRIES,
    TABLES,
    CommissioningTable,
    CurrentLoopTable,
    CurrentMeasurementTable,
    EstimatorTable,
    FaultEntry,
    FieldWeakeningTable,
    InverterTable,
    LimitsTable,
    LoadEntry,
    MechanicsTable,
    MotorTable,
    ReferenceEntry,
    SimulationTable,
    SpeedControllerTable,
    SpeedFilterTable,
    SpeedSensorTable,
)
from .scenario_validate import FULL_SCALE_KEYS, build, short, validate

__all__ = [
    "ARRAYS",
    "FULL_SCALE_KEYS",
    "REQUIRED",
    "RENAMED_KEYS",
    "SCHEMA",
    "SENSOR_DELAY_MAX_PERIODS",
    "STRING_CHARS_MAX",
    "TS_MULTIPLE_RTOL",
    "T_END_MAX_S",
    "Field",
    "SameAs",
    "Scenario",
    "Tree",
    "_Placeholder",
    "list_presets",
    "load_scenario",
    "schema_reference",
]

#: The names of the fields of each typed table: its keys.
_LEAVES = {cls: tuple(f.leaf for f in FIELDS_OF[name]) for name, cls in TABLES.items()} | {
    cls: tuple(f.leaf for f in FIELDS_OF[f"{name}[]"]) for name, cls in ENTRIES.items()
}
#: The attributes of a scenario: its top-level keys, its tables, its arrays of tables.
_PARTS = (*(f.leaf for f in FIELDS_OF[""]), *TABLES, *ARRAYS)


def _table_dict(table: object) -> Tree:
    """A typed table as ``{key: value}``."""
    return {leaf: getattr(table, leaf) for leaf in _LEAVES[type(table)]}


class Scenario:
    """One validated, immutable scenario, its tables typed.

    Build it with :func:`load_scenario` (a preset or a TOML file) or :meth:`from_dict`; change it
    with :meth:`with_overrides`. Each table is an attribute holding every key resolved (defaults
    filled; ``None`` for an optional key not given, such as ``speed_controller.Ka``, meaning 1/Kp):
    ``scenario.speed_controller.alpha_radps``, ``scenario.reference[0].t_s``. :attr:`data` is the same
    as a plain nested dict, for the code that walks the keys by name.
    """

    __slots__ = ("_given", *_PARTS)
    _given: Tree  # the keys given, validated
    name: str
    description: str
    motor: MotorTable
    limits: LimitsTable
    inverter: InverterTable
    current_loop: CurrentLoopTable
    speed_controller: SpeedControllerTable
    mechanics: MechanicsTable
    speed_filter: SpeedFilterTable
    simulation: SimulationTable
    commissioning: CommissioningTable
    speed_sensor: SpeedSensorTable
    current_measurement: CurrentMeasurementTable
    field_weakening: FieldWeakeningTable
    estimator: EstimatorTable
    reference: tuple[ReferenceEntry, ...]
    load: tuple[LoadEntry, ...]
    fault: tuple[FaultEntry, ...]

    def __init__(self, given: Tree, tables: Mapping[str, Any]) -> None:
        """Use :func:`load_scenario`, :meth:`from_dict` or :meth:`with_overrides`: ``given`` and ``tables``
        are those of :func:`~pmsm2dof.sim.scenario_validate.validate` and
        :func:`~pmsm2dof.sim.scenario_validate.build`."""
        object.__setattr__(self, "_given", given)
        for part in _PARTS:
            object.__setattr__(self, part, tables[part])

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("a Scenario is immutable: use with_overrides()")

    def __reduce__(self) -> tuple[type["Scenario"], tuple[Tree, dict[str, Any]]]:
        # pickled by its parts (threads and Dask workers of pmsm2dof.studies.engine), not by setattr
        return Scenario, (self._given, {part: getattr(self, part) for part in _PARTS})

    @classmethod
    def from_dict(cls, tree: Mapping[str, Any]) -> "Scenario":
        """Validate a nested dict (as read from TOML; ``None`` means absent) into a Scenario."""
        given = validate(copy.deepcopy(tree))
        return cls(given, build(given))

    @property
    def data(self) -> Tree:
        """All keys as a plain nested dict, defaults filled (a new dict at each read: the scenario never
        changes), for the code that walks keys by name (TOML, JSON); read the typed tables otherwise."""
        tree: Tree = {leaf: getattr(self, leaf) for leaf in _PARTS if leaf not in TABLES and leaf not in ARRAYS}
        tree |= {name: _table_dict(getattr(self, name)) for name in TABLES}
        tree |= {name: [_table_dict(e) for e in getattr(self, name)] for name in ARRAYS}
        return tree

    def with_overrides(self, overrides: Mapping[str, Any]) -> "Scenario":
        """A new scenario with changes applied, validated again; this one is unchanged.

        The tables and arrays that no override touches are neither copied nor checked again; the
        relations between keys are.

        Parameters
        ----------
        overrides : mapping
            ``{"dotted.key": value}``. Keys address tables by name and arrays by index:
            ``"speed_controller.anti_windup"``, ``"reference.0.speed_rpm"``; the index one past
            the end appends an entry. A whole table or array may be replaced
            (``{"load": [{"t_s": 1.0, "torque_Nm": 2.0}]}``). ``None`` removes a key, so that its
            default (for a derived default such as ``speed_controller.J_kgm2``, its source key) applies again.

        Returns
        -------
        Scenario

        Raises
        ------
        ConfigError
            Naming the dotted key that is unknown, of the wrong type or out of range.
        """
        if not isinstance(overrides, Mapping):
            raise ConfigError("overrides", short(overrides), "a mapping of dotted keys to values")
        tree = dict(self._given)
        touched = set()
        for key, value in overrides.items():
            touched.add(_set_dotted(tree, key, copy.deepcopy(value)))
        given = validate(tree, self._given, touched)
        return Scenario(given, build(given, {part: getattr(self, part) for part in TABLES}, touched))

    def to_toml(self) -> str:
        """The scenario as TOML text: the keys given, then the defaults as comments.

        ``load_scenario`` of the text gives back an equal scenario.
        """
        data = self.data
        lines: list[str] = []
        lines += _toml_fields(FIELDS_OF[""], self._given, data)
        for table in TABLES:
            lines += ["", f"[{table}]"] + _toml_fields(FIELDS_OF[table], self._given.get(table, {}), data[table])
        for name, (_, what) in ARRAYS.items():
            fields = FIELDS_OF[f"{name}[]"]
            entries = self._given.get(name, [])
            if not entries:
                lines += ["", f"# [[{name}]]: none ({what})"]
            for given, values in zip(entries, data[name]):
                lines += ["", f"[[{name}]]"] + _toml_fields(fields, given, values)
        return "\n".join(lines) + "\n"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scenario):
            return NotImplemented
        return all(getattr(self, part) == getattr(other, part) for part in _PARTS)

    __hash__ = None  # type: ignore[assignment]  # scenarios compare by value, like the dicts they are read from

    def __repr__(self) -> str:
        return f"Scenario({self.name!r})"


def _toml_fields(fields: tuple[Field, ...], given: Tree, data: Tree) -> list[str]:
    lines = []
    for f in fields:
        if f.leaf in given:
            lines.append(f"{f.leaf} = {toml_value(given[f.leaf])}")
        elif isinstance(f.default, SameAs):
            lines.append(f"# {f.leaf} = {toml_value(data[f.leaf])}  (default: {f.default.key})")
        elif f.default is None:
            lines.append(f"# {f.leaf} =  (optional: {f.doc})")
        else:
            lines.append(f"# {f.leaf} = {toml_value(f.default)}  (default)")
    return lines


def _set_dotted(tree: Tree, key: object, value: object) -> str:
    """Set ``tree[a][b]...`` for the dotted ``key``, creating tables and appending array entries; return
    its first part (the table, array or top-level key it changes).

    The tables and entries on the way are copied before they change (the others stay shared).
    """
    parts = key.split(".") if isinstance(key, str) else []
    if not parts or any(not p.strip() for p in parts):
        raise ConfigError("override key", key, "a dotted key such as 'motor.J_kgm2' or 'reference.0.speed_rpm'")
    node: Any = tree
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = ".".join(parts[: depth + 1])
        if isinstance(node, list):
            if not part.isdigit() or int(part) > len(node):
                raise ConfigError(
                    here, value, f"an index 0..{len(node)} of {'.'.join(parts[:depth])} ({len(node)} appends an entry)"
                )
            index = int(part)
            if index == len(node):
                node.append({})
            if last:
                node[index] = value
            else:
                node[index] = _copied(node[index])
                node = node[index]
            continue
        if not isinstance(node, dict):
            raise ConfigError(here, value, f"a key inside a table, but {'.'.join(parts[:depth])} is a value")
        if last:
            if value is None:
                node.pop(part, None)
            else:
                node[part] = value
        else:
            child = node.get(part)
            if child is None:
                child = [] if part in ARRAYS and depth == 0 else {}
            node[part] = child = _copied(child)
            node = child
    return parts[0]


def _copied(node: object) -> object:
    """A shallow copy of a table or array on the path of an override (a value as it is)."""
    if isinstance(node, dict):
        return dict(node)
    if isinstance(node, list):
        return list(node)
    return node


def _presets_dir() -> importlib.resources.abc.Traversable:
    return importlib.resources.files("pmsm2dof.sim") / "presets"


def list_presets() -> list[str]:
    """Names of the scenarios shipped with the package (``pmsm2dof/sim/presets/*.toml``), sorted."""
    return sorted(p.name[: -len(".toml")] for p in _presets_dir().iterdir() if p.name.endswith(".toml"))


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load and validate a scenario from a preset name or a TOML file.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        An existing file is read as TOML; any other name must be one of :func:`list_presets`.

    Returns
    -------
    Scenario

    Raises
    ------
    ConfigError
        For an unknown name, an unreadable or invalid TOML file, or a schema violation (naming
        the dotted key, its value and its valid range).
    """
    path = Path(os.fspath(name_or_path))
    if path.exists():
        return Scenario.from_dict(read_toml(path, "scenario"))
    name = str(name_or_path)
    if name in list_presets():
        text = (_presets_dir() / f"{name}.toml").read_text(encoding="utf-8")
        return Scenario.from_dict(parse_toml(text, "scenario", name))
    raise ConfigError("scenario", name, "an existing TOML file or a preset: " + ", ".join(list_presets()))
