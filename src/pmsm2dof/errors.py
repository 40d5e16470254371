"""Exceptions of pmsm2dof.

Every public entry point raises :class:`ConfigError` (a ``ValueError``) for bad input,
with a message that names the parameter, its value and the valid range,
:class:`SimulationError` when the numbers go wrong (non-finite or physically absurd state), and
:class:`ToolError` when an external program is missing or fails.
The CLI turns each into one line on stderr and exit status 2. Valid but doubtful input gives a
:class:`Pmsm2dofWarning`.
"""

import math
from collections.abc import Callable, Collection
from typing import Any, TypeVar

_T = TypeVar("_T")


class Pmsm2dofError(Exception):
    """Base class of the errors pmsm2dof raises on purpose."""


class ConfigError(Pmsm2dofError, ValueError):
    """An input parameter is missing, of the wrong type or out of its valid range."""

    def __init__(self, param: str, value: object, valid: str) -> None:
        self.param = param
        self.value = value
        self.valid = valid
        super().__init__(f"{param} = {value!r} is invalid: valid range is {valid}")


class SimulationError(Pmsm2dofError, RuntimeError):
    """The simulation or a numerical computation produced non-finite or absurd values."""


class Pmsm2dofWarning(UserWarning):
    """Base class of the warnings pmsm2dof gives: a valid input whose result deserves a second look.

    The command line shows each one once per command, as one line on stderr.
    """


class ToolError(Pmsm2dofError, RuntimeError):
    """An external program (cross compiler, CMake, emulator) is missing or failed; the message says what to do."""


def require_positive(param: str, value: Any) -> float:
    """Return ``float(value)`` if it is a finite number > 0, else raise ConfigError."""
    return _require(param, value, lambda v: v > 0, "finite and > 0")


def require_nonnegative(param: str, value: Any) -> float:
    """Return ``float(value)`` if it is a finite number >= 0, else raise ConfigError."""
    return _require(param, value, lambda v: v >= 0, "finite and >= 0")


def require_choice(param: str, value: _T, choices: Collection[_T]) -> _T:
    """Return ``value`` if it is one of ``choices``, else raise ConfigError."""
    if value not in choices:
        raise ConfigError(param, value, "one of " + ", ".join(repr(c) for c in choices))
    return value


def _require(param: str, value: Any, ok: Callable[[float], bool], valid: str) -> float:
    if isinstance(value, bool):
        raise ConfigError(param, value, valid)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(param, value, valid) from None
    if not math.isfinite(v) or not ok(v):
        raise ConfigError(param, value, valid)
    return v
