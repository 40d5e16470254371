"""The scenario key of each field of the engine's C configuration (``p2d_sim_config_t``, csrc/sim/drive.h).

The fields are read from the C declaration (:data:`CONFIG_PARTS`); the field ``f`` of a part is the key
``<table>.f`` of the part's scenario table (:data:`TABLES`) unless :data:`FIELD_KEYS` names another
key. :mod:`pmsm2dof.sim.engine_config` fills the configuration and names the key of an error of a C
init with these maps; :mod:`pmsm2dof.sim.scenario_schema` takes the meaning, unit and range of a key
that a controller's field holds from that field's comment in the C header (:func:`c_field`), and the
valid range of every key that fields of the configuration hold from their comments and C types
(:func:`c_bounds`): the range the C inits check, checked by the scenario before any engine exists.
"""

import math

from ..core.bindings import ffi, field_comment
from ..core.cheaders import Bounds, comment_bounds, comment_unit

#: rpm per rad/s: a scenario key in rpm fills a field in rad/s.
RPM_PER_RADPS = 30.0 / math.pi

#: The scenario table of each part of the engine's configuration (``p2d_sim_config_t``, csrc/sim/drive.h):
#: the field ``f`` of a part is the key ``<table>.f`` unless :data:`FIELD_KEYS` names another.
TABLES = {
    "motor": "motor",
    "speed": "speed_controller",
    "speed_filter": "speed_filter",
    "current": "current_loop",
    "mechanics": "mechanics",
    "sensing.speed_sensor": "speed_sensor",
    "sensing.speed_sensor.encoder": "speed_sensor",
    "sensing.current_sensor": "current_measurement",
    "sensing.field_weakening": "field_weakening",
    "sensing.field_weakening.config": "field_weakening",
    "adapt": "estimator",
    "adapt.config": "estimator",
}

#: The scenario key of each field of the engine's configuration that its table does not give; a
#: key in rpm fills a field in rad/s. None: a value the engine's caller derives
#: (:func:`pmsm2dof.sim.engine_config.derived_values`).
FIELD_KEYS: dict[str, str | None] = {
    "u_dc_V": "limits.u_dc_V",
    "computation_delay": "inverter.computation_delay",
    "current_model": "current_loop.model",
    "tau_i_s": "current_loop.tau_i_s",
    "Ts_current_s": "current_loop.Ts_s",
    "current_per_speed": "speed_controller.Ts_s",
    "substeps": "simulation.dt_s",
    "log_every": "simulation.log_every",
    "log_rate": "simulation.log_rate",
    "w_m0_radps": "simulation.speed0_rpm",
    "arithmetic": "speed_controller.arithmetic",
    "speed_full_scale_radps": "speed_controller.speed_full_scale_rpm",
    "torque_full_scale_Nm": "speed_controller.torque_full_scale_Nm",
    "current_full_scale_A": "speed_controller.current_full_scale_A",
    "speed.i_max_A": "limits.i_max_A",
    "speed.pole_pairs": "motor.pole_pairs",
    "current.Rs_ohm": "motor.Rs_ohm",
    **{f"{part}.{name}": f"motor.{name}" for part in ("speed", "current") for name in ("psi_f_Wb", "Ld_H", "Lq_H")},
    "sensing.speed_sensor.encoder.Ts_s": "speed_controller.Ts_s",
    "sensing.speed_sensor.noise_rms_radps": "speed_sensor.noise_rpm_rms",
    "sensing.current_sensor.noise_rms_A": "current_measurement.noise_A_rms",
    "sensing.field_weakening.config.Ts_s": "speed_controller.Ts_s",
    "sensing.field_weakening.config.method": None,
    "sensing.field_weakening.config.anti_windup": None,
    "adapt.Ka_follows_J": "speed_controller.Ka",
    "adapt.e_quiet_radps": "estimator.adapt_error_rpm",
    "adapt.config.Ts_s": "speed_controller.Ts_s",
}

#: The parts of the configuration filled from the scenario's entries (the schedules and faults).
_ENTRIES = ("reference", "load", "faults", "n_faults")


def _parts(ctype: str, path: str = "") -> dict[str, tuple[str, dict[str, str]]]:
    """The structs of the C configuration ``ctype`` by path, each with its C type and its fields of
    one value (``{field: C type}``), the nested structs and the scenario's entries left out."""
    parts: dict[str, tuple[str, dict[str, str]]] = {path: (ctype, {})}
    for name, field in ffi.typeof(ctype).fields:
        dotted = f"{path}.{name}" if path else name
        if field.type.kind == "struct" and dotted not in _ENTRIES:
            parts |= _parts(field.type.cname, dotted)
        elif field.type.kind in ("primitive", "enum") and dotted not in _ENTRIES:
            parts[path][1][name] = field.type.cname
    return parts


#: The parts of ``p2d_sim_config_t`` read from its declaration: a new field needs no line here.
CONFIG_PARTS = _parts("p2d_sim_config_t")


def scenario_key(path: str) -> str | None:
    """The scenario key of the configuration field ``path`` (None: derived)."""
    if path in FIELD_KEYS:
        return FIELD_KEYS[path]
    part, _, name = path.rpartition(".")
    if part not in TABLES:
        raise RuntimeError(f"p2d_sim_config_t.{path} has no scenario key: name it in FIELD_KEYS or TABLES")
    return f"{TABLES[part]}.{name}"


#: The scenario key of every field of the engine's configuration, by path (checked when imported).
KEYS = {
    path: scenario_key(path)
    for path in (f"{part}.{name}" if part else name for part, (_, fields) in CONFIG_PARTS.items() for name in fields)
}


def c_field(key: str) -> tuple[str, str] | None:
    """The C struct and field that the scenario key ``key`` (``"<table>.<name>"``) fills under its own name:
    ``("p2d_speed_config_t", "alpha_radps")`` for ``speed_controller.alpha_radps`` (the first part of the
    configuration that its table gives and that has the field); None when no field has its name."""
    table, _, name = key.partition(".")
    for part, part_table in TABLES.items():
        ctype, fields = CONFIG_PARTS[part]
        if part_table == table and name in fields:
            return ctype, name
    return None


#: Fields the engine's caller computes from their key rather than holding its value (the ratios of
#: the periods): the key's range is not theirs.
_COMPUTED = ("current_per_speed", "substeps")

#: The range of the C integer types of the configuration: ``[0, 2^bits)``.
_INTEGER_BITS = {"uint32_t": 32, "uint64_t": 64}


def c_bounds(key: str) -> Bounds | None:
    """The valid range of the numeric scenario key ``key`` that fields of the engine's configuration hold:
    the tightest of the bounds their comments give (:func:`~pmsm2dof.core.cheaders.comment_bounds`) and of
    their C integer types, in the key's unit (rpm for a field in rad/s). None when no numeric field holds it.
    """
    lower: list[tuple[float, bool]] = []  # (bound, strict)
    upper: list[tuple[float, bool]] = []
    held = False
    for path, path_key in KEYS.items():
        part, _, name = path.rpartition(".")
        ctype, fields = CONFIG_PARTS[part]
        kind = fields[name]
        if path_key != key or name in _COMPUTED or kind not in ("float", "double", *_INTEGER_BITS):
            continue
        held = True
        comment = field_comment(ctype, name)
        scale = 1.0
        if "_rpm" in key:
            if comment_unit(comment) != "rad/s":
                raise RuntimeError(f"{key} in rpm fills {ctype}.{name}, whose comment gives no unit rad/s")
            scale = RPM_PER_RADPS
        b = comment_bounds(comment)
        lower += [(v * scale, strict) for v, strict in ((b.gt, True), (b.ge, False)) if v is not None]
        upper += [(v * scale, strict) for v, strict in ((b.lt, True), (b.le, False)) if v is not None]
        if kind in _INTEGER_BITS:
            lower.append((0, False))
            upper.append((2 ** _INTEGER_BITS[kind], True))
    if not held:
        return None
    # the tightest bound; of two equal ones the strict
    lo = max(lower, default=None)
    hi = min(upper, key=lambda b: (b[0], not b[1]), default=None)
    return Bounds(
        gt=lo[0] if lo and lo[1] else None,
        ge=lo[0] if lo and not lo[1] else None,
        lt=hi[0] if hi and hi[1] else None,
        le=hi[0] if hi and not hi[1] else None,
    )
