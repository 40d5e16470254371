"""The fields of the C configuration structs from Python values and back, read from their declarations.

:func:`set_fields` writes Python values into a C struct field by field as each field's C type asks
(:func:`~pmsm2dof.core.bindings.struct_fields`): the one generic setter of the controllers' wrappers
and of the engine's configuration (:mod:`pmsm2dof.sim.engine_config`). Only the type is checked here;
the C inits check the ranges and :func:`_raise_status` reports their verdict with the value given.
"""

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError
from .bindings import ENUM_CHOICES, c_string, ffi, lib


def _float_param(name: str, value: object) -> float:
    """``value`` as a Python float, for a float32 field of a C configuration.

    Only the type is checked here; the C init checks the range (it knows it)
    and :func:`_raise_status` reports its verdict with the value given.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(name, value, "a real number")
    return float(value)


def _finite(name: str, value: object) -> float:
    """``value`` as a finite Python float, else ConfigError naming ``name``."""
    v = _float_param(name, value)
    if not math.isfinite(v):
        raise ConfigError(name, value, "a finite number")
    return v


def _choice_param(name: str, value: object, choices: Sequence[str]) -> int:
    """Index of the string ``value`` in ``choices`` (the C enum value)."""
    if not isinstance(value, str) or value not in choices:
        raise ConfigError(name, value, "one of " + ", ".join(repr(c) for c in choices))
    return choices.index(value)


def set_fields(
    cfg: Any, fields: Mapping[str, str], params: Mapping[str, Any], names: Mapping[str, str] | None = None
) -> None:
    """Write ``params`` into the C configuration ``cfg``, field by field as its C type asks.

    ``fields`` maps a field to its C type (:func:`~pmsm2dof.core.bindings.struct_fields`):
    ``float`` and ``double`` take a real number, ``uint32_t`` and ``uint64_t`` an integer, an enum
    one of its names (:data:`~pmsm2dof.core.bindings.ENUM_CHOICES`), ``_Bool`` True or False. Only
    the type is checked here: the C init checks the range. An error names ``names[field]`` (the
    user's name of the field, e.g. a scenario key), else the field.
    """
    for field, ctype in fields.items():
        value, name = params[field], (names or {}).get(field, field)
        if ctype in ("float", "double"):
            setattr(cfg, field, _float_param(name, value))
        elif ctype in ("uint32_t", "uint64_t"):
            top = 0xFFFFFFFF if ctype == "uint32_t" else 0xFFFFFFFFFFFFFFFF
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not 0 <= int(value) <= top:
                raise ConfigError(
                    name, value, "an integer >= 1" if ctype == "uint32_t" else f"an integer in [0, {top}]"
                )
            setattr(cfg, field, int(value))
        elif ctype in ENUM_CHOICES:
            setattr(cfg, field, _choice_param(name, value, ENUM_CHOICES[ctype]))
        elif ctype == "_Bool":
            if not isinstance(value, (bool, np.bool_)):
                raise ConfigError(name, value, "True or False")
            setattr(cfg, field, bool(value))
        else:
            raise TypeError(f"set_fields: field {field} has the C type {ctype}, which it does not convert")


def _get_fields(cfg: Any, fields: Mapping[str, str]) -> dict[str, Any]:
    """The C configuration ``cfg`` as a dict of Python values: floats, ints, enum names, bools."""
    values: dict[str, Any] = {}
    for name, ctype in fields.items():
        value = getattr(cfg, name)
        if ctype in ENUM_CHOICES:
            value = ENUM_CHOICES[ctype][value]
        elif ctype == "_Bool":
            value = bool(value)
        values[name] = value
    return values


def _raise_status(status: int, given: Mapping[str, Any]) -> None:
    """Raise the ConfigError of a non-zero C status, with the value the user gave.

    A value that float32 cannot hold (it overflows to inf or rounds to 0) is
    rejected by C as inf or 0; the message says so.
    """
    param = c_string(lib.p2d_status_param(status))
    value = given.get(param)
    raise ConfigError(param, value, c_string(lib.p2d_status_range(status)) + float32_note(value))


def float32_note(value: object) -> str:
    """Why a C controller refuses a finite ``value`` its range admits: `` (computed in float32, where
    <value> becomes inf)`` when float32 cannot hold it (it overflows or rounds to 0), else ``""``."""
    if isinstance(value, numbers.Real) and math.isfinite(value) and value != 0:
        with np.errstate(over="ignore"):  # the overflow to inf is what the message reports
            as_float32 = float(np.float32(value))
        if as_float32 == 0 or math.isinf(as_float32):
            return f" (computed in float32, where {value!r} becomes {as_float32!r})"
    return ""


def _structured_dtype(ctype: str, fields: Mapping[str, str]) -> np.dtype[np.void]:
    """A numpy dtype with the memory layout of the C struct ``ctype``."""
    return np.dtype(
        {
            "names": list(fields),
            "formats": [np.bool_ if kind == "_Bool" else np.float32 for kind in fields.values()],
            "offsets": [ffi.offsetof(ctype, name) for name in fields],
            "itemsize": ffi.sizeof(ctype),
        }
    )


def _as_inputs(names: Sequence[str], values: Sequence[npt.ArrayLike]) -> list[npt.NDArray[np.float32]]:
    """Broadcast the inputs of a ``run`` to contiguous 1-D float32 arrays of one length."""
    arrays: list[npt.NDArray[np.float64]] = []
    for name, value in zip(names, values):
        a = np.asarray(value, dtype=np.float64)
        if a.ndim > 1:
            raise ConfigError(name, f"array of shape {a.shape}", "a scalar or a 1-D array")
        arrays.append(a)
    try:
        broadcast = np.broadcast_arrays(*arrays)
    except ValueError:
        shapes = ", ".join(f"{n}: {a.shape}" for n, a in zip(names, arrays))
        raise ConfigError(names[1], shapes, "arrays of equal length (or scalars)") from None
    return [np.ascontiguousarray(np.atleast_1d(a), dtype=np.float32) for a in broadcast]


def _float_ptr(array: npt.NDArray[np.float32]) -> Any:  # a cffi ``float *``
    return ffi.cast("float *", ffi.from_buffer(array))


def _struct_dict(cdata: Any, ctype: str) -> dict[str, Any]:
    """The fields of a flat C struct of numbers and bools as a dict."""
    return {name: getattr(cdata, name) for name, _ in ffi.typeof(ctype).fields}
