"""The keys of a scenario: what one key is (:class:`Field`), its declaration in a table (:func:`key`).

The tables of :mod:`pmsm2dof.sim.scenario_tables` declare every key of a scenario with :func:`key`
(meaning, default, valid range); :mod:`pmsm2dof.sim.scenario_schema` reads them into the
:class:`Field` of each dotted key, which checks a value and words its valid range.
"""

import dataclasses
import functools
import math
from typing import Any

from ..errors import ConfigError, is_integer, is_real

#: Longest simulated time of one scenario [s] (ten hours).
T_END_MAX_S = 36000.0

#: Longest delay of the speed reading in current periods (the engine's P2D_SIM_HISTORY - 2).
SENSOR_DELAY_MAX_PERIODS = 2046

#: Relative tolerance of "speed_controller.Ts_s is an integer multiple of current_loop.Ts_s".
TS_MULTIPLE_RTOL = 1e-9

#: A scenario as nested tables: ``{key: value, table: {key: value}, array: [{key: value}]}``.
Tree = dict[str, Any]


class _Placeholder:
    """A value shown in error messages by its name, such as ``<missing>``."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


#: Marks a key without a default (and a missing value in error messages).
REQUIRED = _Placeholder("<missing>")
#: A table or an array of tables as shown in error messages.
TABLE_VALUE = _Placeholder("<table>")
ARRAY_VALUE = _Placeholder("<array>")


@dataclasses.dataclass(frozen=True)
class SameAs:
    """A default taken from another key of the same scenario (``"motor.J_kgm2"``)."""

    key: str


@dataclasses.dataclass(frozen=True)
class Field:
    """One key of the scenario schema.

    ``key`` is the dotted path; keys of the entries of an array of tables are written
    ``"reference[].t_s"``. ``kind`` is ``float``, ``int``, ``bool`` or ``str``. ``default`` is
    :data:`REQUIRED`, a value, ``None`` (optional, no value: see ``doc``) or a :class:`SameAs`.
    Numbers are bounded by ``gt``/``ge``/``lt``/``le`` and must be finite; strings may be
    restricted to ``choices``.
    """

    key: str
    kind: type
    doc: str
    default: object = REQUIRED
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] = ()

    @functools.cached_property
    def leaf(self) -> str:
        return self.key.rsplit(".", 1)[-1]

    @functools.cached_property
    def parent(self) -> str:
        return self.key.rsplit(".", 1)[0] if "." in self.key else ""

    def valid_range(self) -> str:
        """The valid range in words, as shown in error messages."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            return f"a string of at most {STRING_CHARS_MAX} characters"
        limits = ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le))
        bounds = [f"{op} {v:g}" if isinstance(v, float) else f"{op} {v}" for op, v in limits if v is not None]
        noun = "an integer" if self.kind is int else "a finite number"
        return " ".join([noun, " and ".join(bounds)]) if bounds else noun

    def check(self, dotted: str, value: Any) -> Any:
        """Return ``value`` converted to the field's type, or raise ConfigError naming ``dotted``."""
        # numpy scalars (np.float32(0.4), np.int64(4)) are numbers too, stored as Python's
        if self.kind is float:
            if not is_real(value):
                raise ConfigError(dotted, value, self.valid_range())
            try:
                value = float(value)
            except OverflowError:
                raise ConfigError(dotted, value, self.valid_range()) from None
            if not math.isfinite(value):
                raise ConfigError(dotted, value, self.valid_range())
        elif self.kind is int:
            if not is_integer(value):
                raise ConfigError(dotted, value, self.valid_range())
            value = int(value)
        elif self.kind is bool:
            if not isinstance(value, bool):
                raise ConfigError(dotted, value, self.valid_range())
        elif not isinstance(value, str) or len(value) > STRING_CHARS_MAX or not _is_unicode(value):
            raise ConfigError(dotted, value, self.valid_range())
        if self.choices and value not in self.choices:
            raise ConfigError(dotted, value, self.valid_range())
        if (
            (self.gt is not None and not value > self.gt)
            or (self.ge is not None and not value >= self.ge)
            or (self.lt is not None and not value < self.lt)
            or (self.le is not None and not value <= self.le)
        ):
            raise ConfigError(dotted, value, self.valid_range())
        return value


def _is_unicode(text: str) -> bool:
    """True if ``text`` can be written as UTF-8 (no lone surrogates)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


#: Longest string value of a scenario (a name, a description) [characters]: a name is drawn in
#: the titles of figures, whose rasteriser fails on a line of some hundred thousand characters.
STRING_CHARS_MAX = 500


@dataclasses.dataclass(frozen=True)
class FromC:
    """The meaning of a key is the comment beside the C field it fills (meaning, [unit], range, equation: the
    one source of that fact), followed by ``extra``, what only the scenario says (its default when absent)."""

    extra: str = ""


def from_c(extra: str = "") -> FromC:
    """The doc of a key that a controller's C field holds: that field's comment, then ``extra`` (see :class:`FromC`)."""
    return FromC(extra)


@dataclasses.dataclass(frozen=True)
class Spec:
    """What :func:`key` declares of one key: all of :class:`Field` but its dotted name and its type."""

    doc: str | FromC
    default: object = REQUIRED
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] = ()


def key(
    doc: str | FromC,
    default: object = REQUIRED,
    *,
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    choices: tuple[str, ...] = (),
) -> Any:
    """Declare a key of a scenario table as a field of its dataclass: meaning, default and valid range.

    ``doc`` is the meaning in words, or :func:`from_c` for a key that a controller's C field holds.

    ``default`` is :data:`REQUIRED`, a value, ``None`` (optional, no value: see ``doc``) or a
    :class:`SameAs`. The dataclass field itself has no default: a table is built with every key resolved.
    """
    return dataclasses.field(metadata={"key": Spec(doc, default, gt, ge, lt, le, choices)})
