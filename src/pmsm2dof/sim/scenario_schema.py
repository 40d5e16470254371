"""The scenario schema: every key, its type, valid range, default and meaning, in file order.

:data:`SCHEMA` is read from the declarations of the typed tables (:mod:`pmsm2dof.sim.scenario_tables`)
and, for a key that fields of the engine's C configuration hold, its range from those fields' comments
and types (:func:`~pmsm2dof.sim.engine_keys.c_bounds`: the range their C inits check):
the two top-level keys, then each table's keys, then those of the entries of each array of tables
(written ``"reference[].t_s"``). It drives the validation (:mod:`pmsm2dof.sim.scenario_validate`),
the defaults, :meth:`pmsm2dof.sim.scenario.Scenario.to_toml` and :func:`schema_reference`.
"""

import dataclasses
import json
import types
import typing

from ..core.bindings import field_comment
from ..core.cheaders import Bounds
from ..core.motor import DATASHEET_KEYS
from .engine_keys import c_bounds, c_field
from .scenario_keys import REQUIRED, Field, FromC, SameAs, Spec
from .scenario_tables import ARRAYS, ENTRIES, TABLES

#: The keys of the top level of a scenario file.
TOP_FIELDS = (
    Field("name", str, "name of the scenario, shown in summaries and plots"),
    Field("description", str, "one line on what the scenario shows, listed by `pmsm2dof presets`", default=""),
)


def _table_fields(parent: str, table: type) -> tuple[Field, ...]:
    """The :class:`Field` of each key declared in the dataclass ``table`` (``parent``: its dotted name)."""
    fields = []
    for f in dataclasses.fields(table):
        spec: Spec = f.metadata["key"]
        kind = f.type
        if isinstance(kind, types.UnionType):  # ``float | None``: an optional key
            (kind,) = (t for t in kind.__args__ if t is not type(None))
        if typing.get_origin(kind) is typing.Literal:  # the choices of a C enum (Method ...): a string
            kind = str
        if not isinstance(kind, type):
            raise TypeError(f"{parent}.{f.name}: annotated {f.type!r}, not float, int, bool or str")
        key = f"{parent}.{f.name}"
        doc = spec.doc if isinstance(spec.doc, str) else _c_doc(key, spec.doc)
        bounds = _c_range(key, kind, spec)
        fields.append(Field(key, kind, doc, spec.default, bounds.gt, bounds.ge, bounds.lt, bounds.le, spec.choices))
    return tuple(fields)


def _c_range(key: str, kind: type, spec: Spec) -> Bounds:
    """The range of ``key``: the C configuration's (:func:`~pmsm2dof.sim.engine_keys.c_bounds`, the range its
    C init checks) when fields of it hold the key, else the one its table declares."""
    declared = Bounds(spec.gt, spec.ge, spec.lt, spec.le)
    bounds = c_bounds(key)
    if bounds is None:
        return declared
    if declared != Bounds():
        raise TypeError(f"{key} declares a range; its C field's comment gives it (delete the one in the table)")
    if kind is int:  # 1, not 1.0, in the messages of an integer key
        return Bounds(*(None if v is None else int(v) for v in (bounds.gt, bounds.ge, bounds.lt, bounds.le)))
    return bounds


def _c_doc(key: str, doc: FromC) -> str:
    """The doc of ``key`` from the comment of the C field it fills (:func:`~pmsm2dof.sim.engine_keys.c_field`)."""
    where = c_field(key)
    comment = field_comment(*where) if where is not None else ""
    if not comment:
        raise RuntimeError(f"{key} is declared from_c() but fills no commented field of a C configuration struct")
    return f"{comment}; {doc.extra}" if doc.extra else comment


#: Each table's keys by parent: ``""`` (the top level), ``"motor"``, ..., ``"reference[]"``.
FIELDS_OF: dict[str, tuple[Field, ...]] = {
    "": TOP_FIELDS,
    **{name: _table_fields(name, table) for name, table in TABLES.items()},
    **{f"{name}[]": _table_fields(f"{name}[]", entry) for name, entry in ENTRIES.items()},
}

#: The scenario schema: every key, in file order. Units are in the key names.
SCHEMA = tuple(f for fields in FIELDS_OF.values() for f in fields)

#: Every key by its dotted name.
FIELDS = {f.key: f for f in SCHEMA}

#: Keys renamed so that scenario keys and API arguments share one spelling (docs/conventions.md):
#: the old key of a file is refused with its new name.
RENAMED_KEYS = {
    "speed_controller.alpha": "speed_controller.alpha_radps",
    "speed_controller.discretization": "speed_controller.method",
    "speed_controller.J_design_kgm2": "speed_controller.J_kgm2",
    "speed_controller.tau_i_design_s": "speed_controller.tau_i_s",
    "current_loop.discretization": "current_loop.method",
}


def toml_value(value: object) -> str:
    """``value`` (bool, number or string) written as TOML."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    # a TOML basic string is a JSON string in which DEL must be escaped as well
    return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")


def schema_reference() -> str:
    """Every scenario key with its type, valid range, default and meaning, as plain text."""
    lines = []
    for f in SCHEMA:
        if f.default is REQUIRED:
            default = "required"
        elif isinstance(f.default, SameAs):
            default = f"default {f.default.key}"
        elif f.default is None:
            default = "optional"
        else:
            default = f"default {toml_value(f.default)}"
        lines.append(f"{f.key:36s} {f.valid_range()}; {default}. {f.doc}")
    for name, (required, what) in ARRAYS.items():
        lines.append(
            f"{name + '[]':36s} {'required, at least one entry' if required else 'optional'}: {what}; "
            "entries sorted by t_s, ramps not overlapping"
        )
    lines.append("")
    lines.append(
        "[motor.datasheet] instead of motor.pole_pairs, Rs_ohm, Ld_H, Lq_H, psi_f_Wb (and i_rated_A, i_peak_A, "
        "J_rotor_kgm2): the motor in datasheet units (pmsm2dof.core.motor; `pmsm2dof motor FILE` shows the "
        "conversion)"
    )
    lines += [f"{'motor.datasheet.' + key:36s} {doc}" for key, (_, doc) in DATASHEET_KEYS.items()]
    return "\n".join(lines)
