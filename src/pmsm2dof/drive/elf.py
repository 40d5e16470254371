"""The firmware's variables as its ELF file describes them: addresses, sizes and C types.

The symbol table gives each variable's address and size; the DWARF debug information (the
firmware is built with ``-g``) gives the layout of its type: every field's offset, its base type
(float, unsigned, signed, bool, enum with its enumerators) and array dimensions. Read with
pyelftools (the ``drive`` extra). The A2L file (:mod:`pmsm2dof.drive.a2l`) is written from this.
"""

import dataclasses
from pathlib import Path
from typing import Any

from ..errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Scalar:
    """One scalar (or array of scalars) of a variable: a field, or the variable itself.

    Attributes
    ----------
    name : str
        ``variable.field`` (``variable`` for a scalar variable).
    struct : str
        The typedef name of the struct holding the field ("" for a variable).
    field : str
        The field's name ("" for a variable).
    address : int
        Address of its first byte.
    encoding : str
        ``"float"``, ``"unsigned"``, ``"signed"``, ``"bool"`` or ``"enum"``.
    size : int
        Bytes of one element.
    count : int
        Elements (1: a scalar, else a one-dimensional array).
    enumerators : tuple of (int, str)
        The values and names of an enum type.
    """

    name: str
    struct: str
    field: str
    address: int
    encoding: str
    size: int
    count: int
    enumerators: tuple[tuple[int, str], ...] = ()


@dataclasses.dataclass(frozen=True)
class Variable:
    """A variable of the ELF: its symbol, its struct type's name and its scalars."""

    name: str
    address: int
    size: int
    type_name: str
    scalars: tuple[Scalar, ...]


def _strip(die: Any) -> tuple[Any, str]:
    """The DIE of a type under its typedefs and qualifiers, and the first typedef name met."""
    name = ""
    while die.tag in ("DW_TAG_typedef", "DW_TAG_const_type", "DW_TAG_volatile_type"):
        if die.tag == "DW_TAG_typedef" and not name:
            name = die.attributes["DW_AT_name"].value.decode()
        die = die.get_DIE_from_attribute("DW_AT_type")
    return die, name


def _member_offset(die: Any) -> int:
    value = die.attributes["DW_AT_data_member_location"].value
    if isinstance(value, int):
        return value
    # DW_OP_plus_uconst <offset> (DWARF 2 location expression)
    return int(value[1]) if value and value[0] == 0x23 else 0


def _leaf(name: str, struct: str, field: str, address: int, die: Any) -> Scalar:
    """The Scalar of a base, enum or one-dimensional array type."""
    die, _ = _strip(die)
    count = 1
    if die.tag == "DW_TAG_array_type":
        count = 1
        for sub in die.iter_children():
            if sub.tag == "DW_TAG_subrange_type":
                if "DW_AT_count" in sub.attributes:
                    count *= sub.attributes["DW_AT_count"].value
                else:
                    count *= sub.attributes["DW_AT_upper_bound"].value + 1
        die, _ = _strip(die.get_DIE_from_attribute("DW_AT_type"))
    size = die.attributes["DW_AT_byte_size"].value
    if die.tag == "DW_TAG_enumeration_type":
        values = tuple(
            (int(e.attributes["DW_AT_const_value"].value), e.attributes["DW_AT_name"].value.decode())
            for e in die.iter_children()
            if e.tag == "DW_TAG_enumerator"
        )
        return Scalar(name, struct, field, address, "enum", size, count, values)
    if die.tag != "DW_TAG_base_type":
        raise ConfigError(name, die.tag, "a number, an enum or an array of them (the A2L writer's types)")
    encoding = {0x04: "float", 0x02: "bool", 0x05: "signed", 0x06: "signed", 0x07: "unsigned", 0x08: "unsigned"}
    return Scalar(name, struct, field, address, encoding[die.attributes["DW_AT_encoding"].value], size, count)


def read_variables(elf: Path | str, names: list[str]) -> dict[str, Variable]:
    """The variables ``names`` of the ELF file: address and size (symbol table), layout (DWARF).

    Raises
    ------
    ConfigError
        Not an ELF file, unreadable, or a variable not in its symbol table or debug information (built
        without -g).
    """
    from elftools.common.exceptions import DWARFError, ELFError

    try:
        return _read_variables(elf, names)
    except (ELFError, DWARFError) as exc:
        raise ConfigError("elf", str(elf), f"an ELF file of the firmware ({exc})") from None
    except OSError as exc:
        raise ConfigError("elf", str(elf), f"a readable ELF file ({exc.strerror or exc})") from None


def _read_variables(elf: Path | str, names: list[str]) -> dict[str, Variable]:
    """:func:`read_variables`, its parser's errors left to the caller."""
    from elftools.elf.elffile import ELFFile
    from elftools.elf.sections import SymbolTableSection

    out: dict[str, Variable] = {}
    with open(elf, "rb") as f:
        e = ELFFile(f)
        table = e.get_section_by_name(".symtab")
        if not isinstance(table, SymbolTableSection):
            raise ConfigError("elf", str(elf), "an ELF file with its symbol table (not stripped)")
        symbols = {s.name: s for s in table.iter_symbols() if s.name in names and s["st_info"]["type"] == "STT_OBJECT"}
        types: dict[str, Any] = {}
        for cu in e.get_dwarf_info().iter_CUs():
            for die in cu.iter_DIEs():
                if die.tag != "DW_TAG_variable" or "DW_AT_name" not in die.attributes:
                    continue
                name = die.attributes["DW_AT_name"].value.decode()
                if name in names and name not in types and "DW_AT_type" in die.attributes:
                    types[name] = die.get_DIE_from_attribute("DW_AT_type")
        for name in names:
            if name not in symbols or name not in types:
                raise ConfigError("elf", str(elf), f"a firmware built with -g that defines {name}")
            sym = symbols[name]
            base, type_name = _strip(types[name])
            scalars: list[Scalar] = []
            if base.tag == "DW_TAG_structure_type":
                for member in base.iter_children():
                    if member.tag != "DW_TAG_member":
                        continue
                    field = member.attributes["DW_AT_name"].value.decode()
                    scalars.append(
                        _leaf(
                            f"{name}.{field}",
                            type_name,
                            field,
                            sym["st_value"] + _member_offset(member),
                            member.get_DIE_from_attribute("DW_AT_type"),
                        )
                    )
            else:
                scalars.append(_leaf(name, "", "", sym["st_value"], types[name]))
            out[name] = Variable(name, sym["st_value"], sym["st_size"], type_name, tuple(scalars))
    return out
