"""The compiled C library and the names it defines, read from its headers.

``ffi`` and ``lib`` are those of the cffi extension ``pmsm2dof._core``, built from the public
headers of ``csrc/include/pmsm2dof`` and ``csrc/sim`` (see ``ffibuild.py``). Every name that
Python shares with the C code is read here from those declarations instead of being written a
second time: the choices of the enums (:func:`enum_names`), the fields of the C structs
(:func:`struct_fields`), the comment beside each field of the configuration structs
(:func:`field_comment`) and the columns of the engine's log (:data:`LOG_COLUMNS`). This is the
only module that imports the extension.
"""

from typing import Literal, cast

# the extension has no type information: ``ffi`` (cffi.FFI) and ``lib`` (its compiled library)
# are typed Any, as are the C objects they return
from .._core import ffi, lib

__all__ = [
    "ANTI_WINDUPS",
    "ARITHMETICS",
    "AntiWindup",
    "CURRENT_LOOP_MODELS",
    "ENUM_CHOICES",
    "ESTIMATORS",
    "FAULT_KINDS",
    "FEEDBACKS",
    "FEEDFORWARDS",
    "Feedforward",
    "LOG_COLUMNS",
    "LOG_RATES",
    "MECHANICS_MODELS",
    "METHODS",
    "Method",
    "SPEED_SENSOR_MODELS",
    "c_string",
    "enum_names",
    "ffi",
    "field_comment",
    "lib",
    "struct_fields",
]


def c_string(pointer: object) -> str:
    """The C string ``pointer`` (``const char *``) as a Python str."""
    text: bytes = ffi.string(pointer)
    return text.decode()


def enum_names(ctype: str, prefix: str) -> tuple[str, ...]:
    """The enumerators of the C enum ``ctype`` as lower-case names, indexed by their value.

    ``enum_names("p2d_method_t", "P2D_")`` is ``("forward_euler", "backward_euler", "tustin")``:
    each enumerator loses ``prefix`` and is lowered. The values must be 0, 1, 2, ... so that a
    name's index is its C value.
    """
    elements = ffi.typeof(ctype).elements
    if sorted(elements) != list(range(len(elements))):
        raise RuntimeError(f"{ctype}: values {sorted(elements)} are not 0..{len(elements) - 1}")
    names: list[str] = []
    for value in range(len(elements)):
        name = elements[value]
        if not name.startswith(prefix):
            raise RuntimeError(f"{ctype}: {name} does not start with {prefix}")
        names.append(name[len(prefix) :].lower())
    return tuple(names)


def struct_fields(ctype: str) -> dict[str, str]:
    """The fields of the C struct ``ctype`` in declaration order: ``{name: C type name}``."""
    return {name: field.type.cname for name, field in ffi.typeof(ctype).fields}


def _field_comments() -> dict[str, str]:
    """{"<struct>.<field>": comment} compiled into the extension from the headers (ffibuild.py)."""
    comments: dict[str, str] = {}
    i = 0
    while (name := lib.p2d_field_comment(2 * i)) != ffi.NULL:
        comments[c_string(name)] = c_string(lib.p2d_field_comment(2 * i + 1))
        i += 1
    return comments


_FIELD_COMMENTS = _field_comments()


def field_comment(ctype: str, field: str) -> str:
    """The comment beside ``field`` in the declaration of the C struct ``ctype``: meaning, [unit], range.

    Only the configuration structs (``*_config_t``, ``*_params_t``) carry their comments; "" for
    any other field.
    """
    return _FIELD_COMMENTS.get(f"{ctype}.{field}", "")


# The choices of the enums of the API's arguments as types for the annotations: the names of the
# tuples below, which are read from C (tests/test_controllers.py checks that both agree, so that
# the tuples can carry these types).
Method = Literal["forward_euler", "backward_euler", "tustin"]
Feedforward = Literal["none", "lowpass", "no_tau", "full"]
AntiWindup = Literal["none", "back_calculation", "clamping"]

#: Discretization methods (paper Table 1); the index is the C ``p2d_method_t`` value.
METHODS = cast(tuple[Method, ...], enum_names("p2d_method_t", "P2D_"))
#: 2DOF feedforward forms; the index is the C ``p2d_feedforward_t`` value.
FEEDFORWARDS = cast(tuple[Feedforward, ...], enum_names("p2d_feedforward_t", "P2D_FF_"))
#: Anti-windup modes (paper section 3.2); the index is the C ``p2d_anti_windup_t`` value.
ANTI_WINDUPS = cast(tuple[AntiWindup, ...], enum_names("p2d_anti_windup_t", "P2D_AW_"))
#: Speed estimators of an encoder (``p2d_estimator_t``): count differencing or a tracking PLL.
ESTIMATORS = enum_names("p2d_estimator_t", "P2D_ESTIMATOR_")
#: Speed-sensor models of the engine (``p2d_speed_sensor_model_t``): the true speed, or an encoder's counts.
SPEED_SENSOR_MODELS = enum_names("p2d_speed_sensor_model_t", "P2D_SPEED_SENSOR_")
#: Current-loop models of the engine (``p2d_current_model_t``): the C dq current controllers
#: driving the electrical model, or the closed loop of eq 3.
CURRENT_LOOP_MODELS = enum_names("p2d_current_model_t", "P2D_CURRENT_")
#: Fault kinds the engine plays (``p2d_fault_kind_t``).
FAULT_KINDS = enum_names("p2d_fault_kind_t", "P2D_FAULT_")
#: Drive-train models of the engine (``p2d_mechanics_model_t``): one inertia, or motor and load
#: coupled by an elastic shaft.
MECHANICS_MODELS = enum_names("p2d_mechanics_model_t", "P2D_MECHANICS_")
#: The speed the simulated speed controller reads (``p2d_feedback_t``): motor or load side.
FEEDBACKS = enum_names("p2d_feedback_t", "P2D_FEEDBACK_")
#: Arithmetic of the engine's speed controller (``p2d_arithmetic_t``): the float32 controller, or the
#: fixed-point Q15 or Q31 one (speed_fixed.h).
ARITHMETICS = enum_names("p2d_arithmetic_t", "P2D_ARITHMETIC_")
#: Rates of the engine's log rows (``p2d_log_rate_t``): a row per speed sample, or per current period.
LOG_RATES = enum_names("p2d_log_rate_t", "P2D_LOG_RATE_")
#: Names of the columns of the engine's log, with their units (``p2d_sim_log_name``).
LOG_COLUMNS = tuple(c_string(lib.p2d_sim_log_name(i)) for i in range(lib.P2D_LOG_COUNT))

#: The choices of every enum type of the C configurations, indexed by their C value: what a field of
#: that type takes (:func:`pmsm2dof.core.fields.set_fields`).
ENUM_CHOICES: dict[str, tuple[str, ...]] = {
    "p2d_method_t": METHODS,
    "p2d_feedforward_t": FEEDFORWARDS,
    "p2d_anti_windup_t": ANTI_WINDUPS,
    "p2d_estimator_t": ESTIMATORS,
    "p2d_speed_sensor_model_t": SPEED_SENSOR_MODELS,
    "p2d_current_model_t": CURRENT_LOOP_MODELS,
    "p2d_fault_kind_t": FAULT_KINDS,
    "p2d_mechanics_model_t": MECHANICS_MODELS,
    "p2d_feedback_t": FEEDBACKS,
    "p2d_arithmetic_t": ARITHMETICS,
    "p2d_log_rate_t": LOG_RATES,
}
