"""Exceptions of pmsm2dof.

Every public entry point raises :class:`ConfigError` (a ``ValueError``) for bad input,
with a message that names the parameter, its value and the valid range,
:class:`SimulationError` when the numbers go wrong (non-finite or physically absurd state), and
:class:`ToolError` when an external program is missing or fails.
The CLI turns each into one line on stderr and exit status 2. Valid but doubtful input gives a
:class:`Pmsm2dofWarning`.

A message stays short whatever the input: a long value (a 5 MB string, a 5000-digit integer)
is shown by its beginning and its length (:func:`shorten`).
"""

import contextlib
import math
import numbers
import reprlib
import signal
from collections.abc import Callable, Collection, Iterator
from typing import Any, TypeVar

_T = TypeVar("_T")

#: Longest text of a value in a message [characters]; a longer one is cut (:func:`shorten`).
VALUE_CHARS_MAX = 80
#: Longest parameter name and valid range in a message [characters].
PARAM_CHARS_MAX = 200
VALID_CHARS_MAX = 1000


class Pmsm2dofError(Exception):
    """Base class of the errors pmsm2dof raises on purpose."""


class ConfigError(Pmsm2dofError, ValueError):
    """An input parameter is missing, of the wrong type or out of its valid range.

    The message is ``"<param> = <value> is invalid: valid range is <valid>"``, each part cut to
    a few lines (:func:`shorten`); the attributes keep them whole.
    """

    def __init__(self, param: str, value: object, valid: str) -> None:
        self.param = param
        self.value = value
        self.valid = valid
        super().__init__(
            f"{cut_text(str(param), PARAM_CHARS_MAX)} = {shorten(value)} is invalid: "
            f"valid range is {cut_text(str(valid), VALID_CHARS_MAX)}"
        )


class SimulationError(Pmsm2dofError, RuntimeError):
    """The simulation or a numerical computation produced non-finite or absurd values."""


class Pmsm2dofWarning(UserWarning):
    """Base class of the warnings pmsm2dof gives: a valid input whose result deserves a second look.

    The command line shows each one once per command, as one line on stderr.
    """


class ToolError(Pmsm2dofError, RuntimeError):
    """An external program (cross compiler, CMake, emulator) is missing or failed; the message says what to do."""


def shorten(value: object, limit: int = VALUE_CHARS_MAX) -> str:
    """``repr(value)``, or its beginning and its length when it is longer than ``limit`` characters.

    Never fails: an integer too long to print in full (Python refuses beyond 4300 digits) is
    shown by its number of digits, a container by its type and length when its repr fails.
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 3 * limit:
        return f"<an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits>"
    if isinstance(value, (str, bytes)):
        return cut_text(repr(value), limit)
    try:
        # reprlib: a container is shown by its first items, to a few levels, however large
        text = _SHORT_REPR.repr(value)
    except (ValueError, RecursionError):
        size = f" of length {len(value)}" if isinstance(value, Collection) else ""
        return f"<a {type(value).__name__}{size}>"
    return cut_text(text, limit)


_SHORT_REPR = reprlib.Repr()
_SHORT_REPR.maxlevel = 3
_SHORT_REPR.maxstring = _SHORT_REPR.maxother = _SHORT_REPR.maxlong = VALUE_CHARS_MAX


def cut_text(text: str, limit: int) -> str:
    """``text``, or its beginning and its length when it is longer than ``limit`` characters."""
    if len(text) <= limit:
        return text
    return f"{text[: limit - 20]}... ({len(text)} characters)"


def format_bytes(n_bytes: float) -> str:
    """``n_bytes`` in B, KiB, MiB or GiB, for messages (``format_bytes(3.2e9)`` is ``'2.98 GiB'``)."""
    value = float(n_bytes)
    for unit in ("B", "KiB", "MiB"):
        if value < 1024:
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.3g} {unit}"
        value /= 1024
    return f"{value:.3g} GiB"


def is_real(value: object) -> bool:
    """True for a real number: a Python or numpy int or float (``np.float32(0.4)``), not a bool
    (numpy's ``bool_`` is no ``numbers.Real``)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value: object) -> bool:
    """True for an integer: a Python or numpy int (``np.int64(4)``), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def require_positive(param: str, value: Any) -> float:
    """Return ``float(value)`` if it is a finite number > 0, else raise ConfigError."""
    return _require(param, value, lambda v: v > 0, "finite and > 0")


def require_nonnegative(param: str, value: Any) -> float:
    """Return ``float(value)`` if it is a finite number >= 0, else raise ConfigError."""
    return _require(param, value, lambda v: v >= 0, "finite and >= 0")


def require_choice(param: str, value: _T, choices: Collection[_T]) -> _T:
    """Return ``value`` if it is one of ``choices``, else raise ConfigError."""
    try:
        known = value in choices
    except TypeError:  # an unhashable value
        known = False
    if not known:
        raise ConfigError(param, value, "one of " + ", ".join(repr(c) for c in choices))
    return value


#: The normal float32 numbers: the range of the C controllers' parameters and gains.
FLOAT32_MIN = 1.1754943508222875e-38
FLOAT32_MAX = 3.4028234663852886e38


def require_float32(param: str, value: Any, zero: bool = False) -> float:
    """Return ``float(value)`` if it is a normal float32 number > 0 (or 0 with ``zero``), else
    raise ConfigError: the range in which the C controllers, and the analyses of their loops,
    compute without overflow or underflow."""
    v = require_nonnegative(param, value) if zero else require_positive(param, value)
    if not (FLOAT32_MIN <= v <= FLOAT32_MAX or (zero and v == 0.0)):
        span = f"a number from {FLOAT32_MIN:.4g} to {FLOAT32_MAX:.4g} (a normal float32, as the C controllers compute)"
        raise ConfigError(param, value, f"0, or {span}" if zero else span)
    return v


def _require(param: str, value: Any, ok: Callable[[float], bool], valid: str) -> float:
    if not is_real(value):
        raise ConfigError(param, value, valid)
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(param, value, valid) from None
    if not math.isfinite(v) or not ok(v):
        raise ConfigError(param, value, valid)
    return v


class Terminated(BaseException):
    """The process was asked to end by a signal (SIGTERM, SIGHUP): raised like KeyboardInterrupt,
    so that every ``finally`` and context manager cleans up on the way out (staging folders)."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(f"terminated by signal {signum}")


#: The signals that end a run cleanly with :class:`Terminated` (SIGINT stays KeyboardInterrupt).
TERMINATING_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def signals_raise_terminated() -> Iterator[None]:
    """Turn SIGTERM and SIGHUP into :class:`Terminated` in the main thread during the block.

    After the first, further such signals and SIGINT are ignored while the exception unwinds,
    so that the cleanup it triggers is not cut short; the handlers before the block are restored
    at its end.
    """

    def raise_terminated(signum: int, frame: object) -> None:
        for sig in (*TERMINATING_SIGNALS, signal.SIGINT):
            signal.signal(sig, signal.SIG_IGN)
        raise Terminated(signum)

    before = {sig: signal.signal(sig, raise_terminated) for sig in TERMINATING_SIGNALS}
    sigint = signal.getsignal(signal.SIGINT)
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
        signal.signal(signal.SIGINT, sigint)
