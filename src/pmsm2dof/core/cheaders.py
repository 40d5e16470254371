"""The comments beside the fields of C structs, read from the C text: meaning, [unit], range.

One parser for every reader: ``ffibuild.py`` compiles the comments of the library's configuration
structs into the extension with it (:func:`pmsm2dof.core.bindings.field_comment` reads them back),
and the A2L file of a firmware build (:mod:`pmsm2dof.drive.a2l`) takes the comments of the
firmware's variables from its headers with it. :func:`comment_bounds` reads a comment's range, the
one text of a field's bounds that the scenario schema (:mod:`pmsm2dof.sim.scenario_schema`) and the
A2L's limits both check. Pure Python, importing nothing of the package, so that the build script can
load this file before the extension exists.
"""

import dataclasses
import re
from collections.abc import Iterable

#: ``typedef struct { fields } name;`` (no nested braces): its body and its name.
STRUCT = re.compile(r"typedef struct\s*\{([^{}]*?)\}\s*(\w+)\s*;", re.S)
#: A field declaration followed by the start of its comment.
FIELD = re.compile(r"^\s*[\w ]*?\s\**(\w+)(?:\[[^\]]*\])?\s*;\s*/\*(.*)$")
#: The unit in a comment: the text of its first square brackets, ``[unit]``.
UNIT = re.compile(r"\[([^\]]*)\]")


def field_comments(texts: Iterable[str], struct_names: str = r"\w+") -> dict[str, str]:
    """The comments of the fields of the typedef'd structs in the C texts, by ``"<struct>.<field>"``.

    Parameters
    ----------
    texts : iterable of str
        C source or header texts.
    struct_names : str
        A regular expression the struct's name must match whole (e.g. ``r"\\w+_(?:config|params)_t"``).
    """
    wanted = re.compile(struct_names)
    comments: dict[str, str] = {}
    for text in texts:
        for body, struct in STRUCT.findall(text):
            if wanted.fullmatch(struct) is None:
                continue
            lines = body.splitlines()
            for i, line in enumerate(lines):
                m = FIELD.match(line)
                if m is None:
                    continue
                parts = [m.group(2)]
                while "*/" not in parts[-1] and i + 1 < len(lines):
                    i += 1
                    parts.append(lines[i])
                joined = " ".join(p.strip() for p in parts)
                comments[f"{struct}.{m.group(1)}"] = " ".join(joined[: joined.index("*/")].split())
    return comments


def comment_unit(comment: str) -> str:
    """The unit of a field comment, the text of its first square brackets ("" when none, "-" for dimensionless)."""
    m = UNIT.search(comment)
    return m.group(1).strip() if m else ""


#: A plain number in a range text.
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
#: The end of a plain-number bound: not ``>= 10 Ts_s`` or ``<= 2^15 - 1`` (they bound other quantities).
_ALONE = r"(?!\.?\d|\s*(?!and\b|or\b)[\w/^*])"
#: A bound of the field: ``>= a``, ``> a``, ``<= b``, ``< b`` opening a clause (after ``]``, a comma or ``and``).
_BOUND = re.compile(rf"(?:^|[],]|\band)\s*(>=|>|<=|<)\s*({_NUMBER}){_ALONE}")
#: The field's interval ``a..b``.
_DOTS = re.compile(rf"({_NUMBER})\s*\.\.\s*({_NUMBER})")
#: The field's interval ``in (a, b]`` opening a clause (after a comma or ``and``), not scaled (``in [2, 4] Ts_s``);
#: an end that is not a number alone (``J0_kgm2``, ``2 pi``) bounds through another quantity.
_INTERVAL = re.compile(r"(?:^|,|\band)\s*in\s*([(\[])([^,()\[\]]*),([^,()\[\]]*)([)\]])(?!\s*[\w/^*])")


@dataclasses.dataclass(frozen=True)
class Bounds:
    """A field's range: ``value > gt``, ``>= ge``, ``< lt``, ``<= le`` (None: no such bound)."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None


def _plain(text: str) -> float | None:
    """``text`` as a number when it is a number alone, else None."""
    return float(text) if re.fullmatch(rf"\s*{_NUMBER}\s*", text) else None


def comment_bounds(comment: str) -> Bounds:
    """The range a field comment gives the field itself, in plain numbers: ``>= a``, ``> a``, ``<= b``,
    ``< b`` opening a clause (after ``]``, a comma or ``and``), ``a..b`` or ``in (a, b]``.

    A bound that is not a number alone bounds another quantity and is left to the C init: ``>= 10 Ts_s``,
    ``1e-3 <= bandwidth_radps Ts_s <= 2``, ``|m| <= 2^15 - 1``, the ``J0_kgm2`` of ``in (0, J0_kgm2]``.
    """
    m = _DOTS.search(comment)
    if m:
        return Bounds(ge=float(m.group(1)), le=float(m.group(2)))
    m = _INTERVAL.search(comment)
    if m:
        opening, lower, upper, closing = m.groups()
        lo, hi = _plain(lower), _plain(upper)
        return Bounds(
            gt=lo if opening == "(" else None,
            ge=lo if opening == "[" else None,
            lt=hi if closing == ")" else None,
            le=hi if closing == "]" else None,
        )
    found: dict[str, float] = {}
    for op, value in _BOUND.findall(comment):
        found.setdefault({">": "gt", ">=": "ge", "<": "lt", "<=": "le"}[op], float(value))
    return Bounds(**found)
