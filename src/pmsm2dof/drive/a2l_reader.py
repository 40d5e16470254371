"""Reading the A2L file of a build back: what a master needs to talk to the drive.

The ASAP2 blocks :func:`pmsm2dof.drive.a2l.write_a2l` writes, read by their positional fields
(ASAM MCD-2 MC 1.7): the memory segments, the MEASUREMENTs and CHARACTERISTICs with their types,
limits, units and descriptions, the DAQ events and the protocol layer's packet limits.
"""

import dataclasses
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .elf import Scalar, Variable

#: Largest A2L file read [bytes] (a build's is some 30 kB; a large ECU's some MB).
A2L_BYTES_MAX = 64 * 1024**2

#: The encoding and size of an ASAP2 data type (a UBYTE with a verbal table is an enum).
ENCODINGS = {
    "FLOAT32_IEEE": ("float", 4),
    "FLOAT64_IEEE": ("float", 8),
    "UBYTE": ("unsigned", 1),
    "UWORD": ("unsigned", 2),
    "ULONG": ("unsigned", 4),
    "A_UINT64": ("unsigned", 8),
    "SBYTE": ("signed", 1),
    "SWORD": ("signed", 2),
    "SLONG": ("signed", 4),
    "A_INT64": ("signed", 8),
}

_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|/\*.*?\*/|//[^\n]*|[^\s"]+', re.S)


@dataclasses.dataclass(frozen=True)
class Entry:
    """A MEASUREMENT or CHARACTERISTIC of an A2L file.

    Attributes
    ----------
    scalar : Scalar
        Its address, type and element count (``struct`` is empty: the A2L does not name C types).
    lower, upper : float
        The limits the A2L gives (the C comment's range narrowed to the type's).
    unit : str
        The unit of its COMPU_METHOD.
    text : str
        Its description (the C comment).
    writable : bool
        A CHARACTERISTIC (calibration), not a MEASUREMENT.
    """

    scalar: Scalar
    lower: float
    upper: float
    unit: str
    text: str
    writable: bool


@dataclasses.dataclass(frozen=True)
class A2l:
    """The facts of an A2L file a master uses: segments, variables, limits, events, protocol limits.

    Attributes
    ----------
    path : Path
        The file read.
    module : str
        The MODULE's name (GET_ID type 1 of the firmware answers the same).
    byte_order : str
        ``"little"`` or ``"big"``.
    segments : dict
        ``{name: (address, size)}`` of the MEMORY_SEGMENTs: the only memory the master touches.
    entries : dict
        ``{name: Entry}`` of the MEASUREMENTs and CHARACTERISTICs.
    events : dict
        ``{name: (channel, period_s)}`` of the DAQ events.
    max_cto, max_dto : int
        The protocol layer's packet limits [bytes].
    """

    path: Path
    module: str
    byte_order: str
    segments: dict[str, tuple[int, int]]
    entries: dict[str, Entry]
    events: dict[str, tuple[int, float]]
    max_cto: int
    max_dto: int

    def variables(self) -> dict[str, Variable]:
        """The segments as :class:`~pmsm2dof.drive.elf.Variable` with the entries inside each as its scalars."""
        out = {}
        for name, (address, size) in self.segments.items():
            scalars = tuple(
                e.scalar
                for e in self.entries.values()
                if address <= e.scalar.address and e.scalar.address + e.scalar.size * e.scalar.count <= address + size
            )
            out[name] = Variable(name, address, size, "", scalars)
        return out


def _blocks(tokens: list[str], path: Path) -> list[Any]:
    """The tokens as nested lists: ``[kind, arg, ..., [kind, ...]]`` for each /begin ... /end block."""
    stack: list[list[Any]] = [[""]]
    i = 0
    while i < len(tokens):
        t = tokens[i]
        if t == "/begin" and i + 1 < len(tokens):
            block: list[Any] = [tokens[i + 1]]
            stack[-1].append(block)
            stack.append(block)
            i += 2
            continue
        if t == "/end" and i + 1 < len(tokens):
            if len(stack) == 1 or stack[-1][0] != tokens[i + 1]:
                raise ConfigError("a2l", str(path), f"an A2L file whose blocks nest (/end {tokens[i + 1]} unopened)")
            stack.pop()
            i += 2
            continue
        stack[-1].append(t)
        i += 1
    if len(stack) != 1:
        raise ConfigError("a2l", str(path), f"an A2L file whose blocks close (/begin {stack[-1][0]} not ended)")
    return stack[0]


def _walk(block: list[Any], kind: str) -> Iterator[list[Any]]:
    for item in block[1:]:
        if isinstance(item, list):
            if item[0] == kind:
                yield item
            yield from _walk(item, kind)


def _text(token: str) -> str:
    return token[1:-1].replace("\\\\", "\\") if token.startswith('"') else token


def _after(block: list[Any], keyword: str) -> str | None:
    words = [t for t in block if isinstance(t, str)]
    return words[words.index(keyword) + 1] if keyword in words and words.index(keyword) + 1 < len(words) else None


def read_a2l(path: Path | str) -> A2l:
    """Read the A2L file of a build (:func:`write_a2l`): segments, variables, limits, events.

    The ASAP2 blocks read are MODULE, MOD_COMMON (BYTE_ORDER), MOD_PAR (MEMORY_SEGMENT), IF_DATA
    XCP (PROTOCOL_LAYER, DAQ EVENT), MEASUREMENT, CHARACTERISTIC (VALUE, VAL_BLK), RECORD_LAYOUT,
    COMPU_METHOD and COMPU_VTAB, by their positional fields (ASAM MCD-2 MC 1.7). A reader of its
    own because a general one (pya2ldb, which the tests hold this one against) builds a database
    of the file in seconds where a command needs milliseconds.

    Raises
    ------
    ConfigError
        The file is missing, too large, or not an A2L file with these blocks.
    """
    from ..inputs import check_file

    path = Path(path)
    check_file(path, "a2l", A2L_BYTES_MAX)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
        tokens = [t for t in _TOKEN.findall(text) if not t.startswith(("/*", "//"))]
        root = _blocks(tokens, path)
        modules = list(_walk(root, "MODULE"))
        if not modules:
            raise ConfigError("a2l", str(path), "an A2L file with a MODULE")
        module = modules[0]
        order = _after(next(_walk(module, "MOD_COMMON"), ["MOD_COMMON"]), "BYTE_ORDER") or "MSB_LAST"
        layouts = {b[1]: b[4] for b in _walk(module, "RECORD_LAYOUT")}
        units, tables = {}, {}
        for b in _walk(module, "COMPU_METHOD"):
            units[b[1]] = _text(b[5])
            ref = _after(b, "COMPU_TAB_REF")
            if ref is not None:
                tables[b[1]] = ref
        vtabs = {
            b[1]: tuple((int(float(b[i])), _text(b[i + 1])) for i in range(5, 5 + 2 * int(b[4]), 2))
            for b in _walk(module, "COMPU_VTAB")
        }
        entries: dict[str, Entry] = {}
        for kind in ("MEASUREMENT", "CHARACTERISTIC"):
            for b in _walk(module, kind):
                name = b[1]
                if kind == "MEASUREMENT":
                    datatype, conv, lower, upper = b[3], b[4], b[7], b[8]
                    address = int(_after(b, "ECU_ADDRESS") or "-1", 0)
                else:
                    datatype, conv, lower, upper = layouts[b[5]], b[7], b[8], b[9]
                    address = int(b[4], 0)
                encoding, size = ENCODINGS[datatype]
                enumerators = vtabs.get(tables.get(conv, ""), ())
                scalar = Scalar(
                    name=name,
                    struct="",
                    field=name.partition(".")[2],
                    address=address,
                    encoding="enum" if enumerators else encoding,
                    size=size,
                    count=int(_after(b, "MATRIX_DIM") or "1"),
                    enumerators=enumerators,
                )
                entries[name] = Entry(scalar, float(lower), float(upper), units.get(conv, ""), _text(b[2]),
                                      kind == "CHARACTERISTIC")  # fmt: skip
        segments = {b[1]: (int(b[6], 0), int(b[7], 0)) for b in _walk(module, "MEMORY_SEGMENT")}
        events = {}
        for b in _walk(module, "EVENT"):
            events[_text(b[1])] = (int(b[3], 0), int(b[6]) * 10.0 ** int(b[7]) * 1e-9)
        layer = next(_walk(module, "PROTOCOL_LAYER"), None)
        max_cto, max_dto = (int(layer[9], 0), int(layer[10], 0)) if layer else (8, 8)
    except (IndexError, KeyError, ValueError, StopIteration) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(
            "a2l", str(path), f"an A2L file as ASAP2 1.7 lays it out ({type(exc).__name__}: {exc})"
        ) from None
    return A2l(path, module[1], "little" if order == "MSB_LAST" else "big", segments, entries, events, max_cto, max_dto)
