"""The A2L file (ASAM MCD-2 MC, ASAP2 1.71) of a firmware build, for CANape, INCA or pyxcp.

Written from the ELF (:mod:`pmsm2dof.drive.elf`: addresses, sizes, C types) and the comments of
the C declarations (:mod:`pmsm2dof.core.cheaders`: meaning, [unit], range), so that a master
opens the drive without pmsm2dof: MOD_COMMON (byte order, alignments), MOD_PAR (a memory segment
per variable the slave exposes), IF_DATA XCP (protocol layer, dynamic DAQ with the events
"current" and "speed", XCP on TCP/IP and on SxI), a MEASUREMENT per field of the measurement
variables and a CHARACTERISTIC (VALUE, or VAL_BLK for an array) per field of the calibration
variables, each with a COMPU_METHOD of its unit (enums: a verbal table) and a RECORD_LAYOUT of its
type. The XCP interface is described by a reduced A2ML written here from the ASAM XCP 1.x
definition of the blocks used.
"""

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from ..core.cheaders import comment_bounds, comment_unit
from ..outputs import atomic_write
from .elf import Scalar, Variable

#: ASAP2 data type of an encoding and size.
DATATYPES = {
    ("float", 4): "FLOAT32_IEEE",
    ("float", 8): "FLOAT64_IEEE",
    ("unsigned", 1): "UBYTE",
    ("unsigned", 2): "UWORD",
    ("unsigned", 4): "ULONG",
    ("unsigned", 8): "A_UINT64",
    ("signed", 1): "SBYTE",
    ("signed", 2): "SWORD",
    ("signed", 4): "SLONG",
    ("signed", 8): "A_INT64",
    ("bool", 1): "UBYTE",
    ("enum", 1): "UBYTE",
    ("enum", 2): "UWORD",
    ("enum", 4): "ULONG",
}

#: The XCP part of the A2ML: the blocks and fields this file uses, as ASAM XCP 1.x defines them.
A2ML = """/begin A2ML
  block "IF_DATA" taggedunion if_data {
    "XCP" struct {
      taggedstruct {
        block "PROTOCOL_LAYER" struct {
          uint; uint; uint; uint; uint; uint; uint; uint; uchar; uint;
          enum { "BYTE_ORDER_MSB_LAST" = 0, "BYTE_ORDER_MSB_FIRST" = 1 };
          enum { "ADDRESS_GRANULARITY_BYTE" = 1, "ADDRESS_GRANULARITY_WORD" = 2, "ADDRESS_GRANULARITY_DWORD" = 4 };
          taggedstruct {
            ("OPTIONAL_CMD" enum {
              "GET_COMM_MODE_INFO" = 251, "GET_ID" = 250, "GET_SEED" = 248, "UNLOCK" = 247, "SET_MTA" = 246,
              "UPLOAD" = 245, "SHORT_UPLOAD" = 244, "DOWNLOAD" = 240, "GET_DAQ_CLOCK" = 220,
              "GET_DAQ_PROCESSOR_INFO" = 218, "GET_DAQ_RESOLUTION_INFO" = 217, "GET_DAQ_EVENT_INFO" = 215,
              "FREE_DAQ" = 214, "ALLOC_DAQ" = 213, "ALLOC_ODT" = 212, "ALLOC_ODT_ENTRY" = 211,
              "SET_DAQ_PTR" = 226, "WRITE_DAQ" = 225, "SET_DAQ_LIST_MODE" = 224, "START_STOP_DAQ_LIST" = 222,
              "START_STOP_SYNCH" = 221
            })*;
            "COMMUNICATION_MODE_SUPPORTED" taggedunion { "BLOCK" taggedstruct { "SLAVE"; }; };
            "SEED_AND_KEY_EXTERNAL_FUNCTION" char[256];
          };
        };
        block "DAQ" struct {
          enum { "STATIC" = 0, "DYNAMIC" = 1 };
          uint; uint; uchar;
          enum { "OPTIMISATION_TYPE_DEFAULT" = 0 };
          enum { "ADDRESS_EXTENSION_FREE" = 0, "ADDRESS_EXTENSION_ODT" = 1, "ADDRESS_EXTENSION_DAQ" = 3 };
          enum { "IDENTIFICATION_FIELD_TYPE_ABSOLUTE" = 0, "IDENTIFICATION_FIELD_TYPE_RELATIVE_BYTE" = 1,
                 "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD" = 2,
                 "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD_ALIGNED" = 3 };
          enum { "GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE" = 1, "GRANULARITY_ODT_ENTRY_SIZE_DAQ_WORD" = 2,
                 "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DWORD" = 4, "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DLONG" = 8 };
          uchar;
          enum { "NO_OVERLOAD_INDICATION" = 0, "OVERLOAD_INDICATION_PID" = 1, "OVERLOAD_INDICATION_EVENT" = 2 };
          taggedstruct {
            "PRESCALER_SUPPORTED";
            block "TIMESTAMP_SUPPORTED" struct {
              uint;
              enum { "NO_TIME_STAMP" = 0, "SIZE_BYTE" = 1, "SIZE_WORD" = 2, "SIZE_DWORD" = 4 };
              enum { "UNIT_1NS" = 0, "UNIT_10NS" = 1, "UNIT_100NS" = 2, "UNIT_1US" = 3, "UNIT_10US" = 4,
                     "UNIT_100US" = 5, "UNIT_1MS" = 6, "UNIT_10MS" = 7, "UNIT_100MS" = 8, "UNIT_1S" = 9 };
              taggedstruct { "TIMESTAMP_FIXED"; };
            };
            (block "EVENT" struct {
              char[101]; char[9]; uint;
              enum { "DAQ" = 1, "STIM" = 2, "DAQ_STIM" = 3 };
              uchar; uchar; uchar; uchar;
            })*;
          };
        };
        block "XCP_ON_SxI" struct {
          uint; ulong;
          taggedstruct { "ASYNCH_FULL_DUPLEX_MODE" struct {
            enum { "PARITY_NONE" = 0, "PARITY_ODD" = 1, "PARITY_EVEN" = 2 };
            enum { "ONE_STOP_BIT" = 1, "TWO_STOP_BITS" = 2 }; }; };
          enum { "HEADER_LEN_BYTE" = 0, "HEADER_LEN_CTR_BYTE" = 1, "HEADER_LEN_WORD" = 2, "HEADER_LEN_CTR_WORD" = 3 };
          enum { "NO_CHECKSUM" = 0, "CHECKSUM_BYTE" = 1, "CHECKSUM_WORD" = 2 };
        };
        block "XCP_ON_TCP_IP" struct {
          uint; uint;
          taggedunion { "HOST_NAME" char[256]; "ADDRESS" char[15]; };
        };
      };
    };
  };
/end A2ML"""

#: Units that the names of the trace's columns end with (the engine's log: ``w_m_radps``, ``id_A``).
SUFFIX_UNITS = {"radps": "rad/s", "rpm": "rpm", "A": "A", "V": "V", "Nm": "Nm", "s": "s", "kgm2": "kg m^2"}


def limits(comment: str, scalar: Scalar) -> tuple[float, float]:
    """The range of a field: its type's, narrowed by its comment's bounds
    (:func:`~pmsm2dof.core.cheaders.comment_bounds`, the range the scenario checks too)."""
    if scalar.encoding == "float":
        lo, hi = (-3.4e38, 3.4e38) if scalar.size == 4 else (-1.7e308, 1.7e308)
    elif scalar.encoding in ("unsigned", "bool", "enum"):
        lo, hi = 0.0, float(2 ** (8 * scalar.size) - 1)
    else:
        lo, hi = -float(2 ** (8 * scalar.size - 1)), float(2 ** (8 * scalar.size - 1) - 1)
    if scalar.encoding == "bool":
        return 0.0, 1.0
    if scalar.encoding == "enum" and scalar.enumerators:
        return float(min(v for v, _ in scalar.enumerators)), float(max(v for v, _ in scalar.enumerators))
    b = comment_bounds(comment)
    for bound in (b.gt, b.ge):
        if bound is not None:
            lo = max(lo, bound)
    for bound in (b.lt, b.le):
        if bound is not None:
            hi = min(hi, bound)
    return lo, hi


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', "'") + '"'


def _ident(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.\[\]]", "_", text)


def _number(x: float) -> str:
    return repr(float(x)) if not math.isinf(x) else ("3.4e38" if x > 0 else "-3.4e38")


def write_a2l(
    path: Path | str,
    *,
    module: str,
    variables: Mapping[str, Variable],
    measurements: Sequence[str],
    calibrations: Sequence[str],
    comments: Mapping[str, str],
    events: Sequence[tuple[str, float]],
    timestamp_s: float,
    byte_order: str,
    tcp_port: int,
    sxi_baud: int | None,
    max_cto: int = 255,
    max_dto: int = 255,
) -> Path:
    """Write the A2L file of a build.

    Parameters
    ----------
    path : path
        The file written (atomically).
    module : str
        The MODULE's name (the firmware's; GET_ID type 1 answers it).
    variables : mapping
        :func:`pmsm2dof.drive.elf.read_variables` of the ELF.
    measurements, calibrations : sequence of str
        The variables the slave exposes for reading, and for writing through its commits.
    comments : mapping
        ``{"<struct>.<field>": comment}`` (:func:`pmsm2dof.core.cheaders.field_comments`).
    events : sequence of (str, float)
        The slave's events in their order: name and period [s].
    timestamp_s : float
        One tick of the DAQ timestamps [s].
    byte_order : str
        ``"little"`` or ``"big"`` (the ELF's).
    tcp_port : int
        The TCP port the A2L names for XCP on TCP/IP (the one a master connects to by default).
    sxi_baud : int or None
        The UART's bit rate for XCP on SxI; None: no SxI transport (the PC's drive).
    """
    msb = "MSB_LAST" if byte_order == "little" else "MSB_FIRST"
    compu: dict[str, str] = {}
    layouts: set[str] = set()
    body: list[str] = []

    def conversion(scalar: Scalar, unit: str) -> str:
        if scalar.encoding == "enum" and scalar.enumerators:
            name = f"CM_{_ident(scalar.struct or scalar.name)}_{_ident(scalar.field)}"
            if name not in compu:
                pairs = " ".join(f"{v} {_quote(n)}" for v, n in scalar.enumerators)
                compu[name] = (
                    f'  /begin COMPU_METHOD {name} "" TAB_VERB "%.0" "" COMPU_TAB_REF VT_{name[3:]} /end COMPU_METHOD\n'
                    f"  /begin COMPU_VTAB VT_{name[3:]} {_quote(scalar.field)} TAB_VERB {len(scalar.enumerators)} "
                    f"{pairs} /end COMPU_VTAB"
                )
            return name
        fmt = "%12.9" if scalar.encoding == "float" else "%12.0"
        name = "CM_" + (re.sub(r"[^A-Za-z0-9]", "_", unit) or "none") + ("_f" if scalar.encoding == "float" else "_i")
        if name not in compu:
            compu[name] = f'  /begin COMPU_METHOD {name} "" IDENTICAL "{fmt}" {_quote(unit)} /end COMPU_METHOD'
        return name

    for var_name in [*measurements, *calibrations]:
        var = variables[var_name]
        writable = var_name in calibrations
        for scalar in var.scalars:
            datatype = DATATYPES[(scalar.encoding, scalar.size)]
            comment = comments.get(f"{scalar.struct}.{scalar.field}", "") if scalar.struct else ""
            # a field's unit is its comment's; a column of the trace row carries it in its name (w_m_radps)
            unit = comment_unit(comment) if comment else SUFFIX_UNITS.get(scalar.field.rsplit("_", 1)[-1], "-")
            cm = conversion(scalar, unit)
            lo, hi = limits(comment, scalar)
            text = _quote(comment or scalar.name)
            if not writable:
                matrix = f" MATRIX_DIM {scalar.count}" if scalar.count > 1 else ""
                body.append(
                    f"  /begin MEASUREMENT {_ident(scalar.name)} {text} {datatype} {cm} 0 0 {_number(lo)} {_number(hi)}"
                    f"{matrix} ECU_ADDRESS 0x{scalar.address:08X} /end MEASUREMENT"
                )
            else:
                layout = f"RL_{datatype}"
                layouts.add(datatype)
                kind, matrix = ("VAL_BLK", f" MATRIX_DIM {scalar.count}") if scalar.count > 1 else ("VALUE", "")
                body.append(
                    f"  /begin CHARACTERISTIC {_ident(scalar.name)} {text} {kind} 0x{scalar.address:08X} {layout} 0 "
                    f"{cm} {_number(lo)} {_number(hi)}{matrix} /end CHARACTERISTIC"
                )

    kinds = {**dict.fromkeys(measurements, "measurement"), **dict.fromkeys(calibrations, "calibration")}
    segments = "\n".join(
        f"    /begin MEMORY_SEGMENT {_ident(n)} {_quote(kinds[n] + ': ' + n)}"
        f" DATA RAM INTERN 0x{variables[n].address:08X} 0x{variables[n].size:X} -1 -1 -1 -1 -1 /end MEMORY_SEGMENT"
        for n in [*measurements, *calibrations]
    )
    ts_unit, ts_ticks = _xcp_time(timestamp_s, 65535)
    event_lines = []
    for i, (name, period_s) in enumerate(events):
        power, cycle = _xcp_time(period_s, 255)
        event_lines.append(f'      /begin EVENT "{name}" "{name[:8]}" {i} DAQ 255 {cycle} {power} {2 - i} /end EVENT')
    optional = (
        "GET_COMM_MODE_INFO GET_ID SET_MTA UPLOAD SHORT_UPLOAD DOWNLOAD GET_DAQ_CLOCK GET_DAQ_PROCESSOR_INFO "
        "GET_DAQ_RESOLUTION_INFO GET_DAQ_EVENT_INFO FREE_DAQ ALLOC_DAQ ALLOC_ODT ALLOC_ODT_ENTRY SET_DAQ_PTR "
        "WRITE_DAQ SET_DAQ_LIST_MODE START_STOP_DAQ_LIST START_STOP_SYNCH"
    ).split()
    sxi = (
        f"    /begin XCP_ON_SxI 0x0100 {sxi_baud} ASYNCH_FULL_DUPLEX_MODE PARITY_NONE ONE_STOP_BIT "
        "HEADER_LEN_CTR_WORD NO_CHECKSUM /end XCP_ON_SxI\n"
        if sxi_baud
        else ""
    )
    if_data = (
        "  /begin IF_DATA XCP\n"
        f"    /begin PROTOCOL_LAYER 0x0100 2000 2000 2000 2000 2000 2000 2000 {max_cto} {max_dto} "
        f"BYTE_ORDER_{msb} ADDRESS_GRANULARITY_BYTE\n"
        + "".join(f"      OPTIONAL_CMD {c}\n" for c in optional)
        + "      COMMUNICATION_MODE_SUPPORTED BLOCK SLAVE\n    /end PROTOCOL_LAYER\n"
        f"    /begin DAQ DYNAMIC 0 {len(events)} 0 OPTIMISATION_TYPE_DEFAULT ADDRESS_EXTENSION_FREE "
        f"IDENTIFICATION_FIELD_TYPE_ABSOLUTE GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE {min(max_dto - 1, 255)} "
        "NO_OVERLOAD_INDICATION PRESCALER_SUPPORTED\n"
        f"      /begin TIMESTAMP_SUPPORTED {ts_ticks} SIZE_DWORD UNIT_{_UNITS[ts_unit]} /end TIMESTAMP_SUPPORTED\n"
        + "\n".join(event_lines)
        + "\n    /end DAQ\n"
        + sxi
        + f'    /begin XCP_ON_TCP_IP 0x0100 {tcp_port} ADDRESS "127.0.0.1" /end XCP_ON_TCP_IP\n'
        "  /end IF_DATA"
    )
    record_layouts = "\n".join(
        f"  /begin RECORD_LAYOUT RL_{d} FNC_VALUES 1 {d} ROW_DIR DIRECT /end RECORD_LAYOUT" for d in sorted(layouts)
    )
    text = "\n".join(
        [
            "ASAP2_VERSION 1 71",
            f'/begin PROJECT pmsm2dof "pmsm2dof firmware: {module}"',
            '  /begin HEADER "written by pmsm2dof from the ELF and the C declarations" /end HEADER',
            f'  /begin MODULE {_ident(module)} ""',
            A2ML,
            f'  /begin MOD_COMMON "" BYTE_ORDER {msb} ALIGNMENT_BYTE 1 ALIGNMENT_WORD 2 ALIGNMENT_LONG 4 '
            "ALIGNMENT_FLOAT32_IEEE 4 ALIGNMENT_FLOAT64_IEEE 8 /end MOD_COMMON",
            f'  /begin MOD_PAR ""\n{segments}\n  /end MOD_PAR',
            if_data,
            *compu.values(),
            record_layouts,
            *body,
            "  /end MODULE",
            "/end PROJECT",
            "",
        ]
    )
    atomic_write(Path(path), text)
    return Path(path)


#: XCP time units (unit 10^k ns) as the A2L names them.
_UNITS = ("1NS", "10NS", "100NS", "1US", "10US", "100US", "1MS", "10MS", "100MS", "1S")


def _xcp_time(seconds: float, most: int) -> tuple[int, int]:
    """A duration as (unit k: 10^k ns, count <= most), the largest exact unit (as the firmware's link.c)."""
    ns = round(seconds * 1e9)
    unit = 0
    while unit < 9 and ns >= 10 and (ns > most or ns % 10 == 0):
        ns //= 10
        unit += 1
    return unit, ns if ns <= most else 0


def write_firmware_a2l(
    elf: Path | str,
    path: Path | str,
    *,
    sources: Sequence[Path],
    virtual: bool,
    Ts_current_s: float,
    current_per_speed: int,
    tcp_port: int,
    sxi_baud: int | None,
) -> Path:
    """The A2L file of a build of examples/firmware (its variables: :mod:`pmsm2dof.drive.link`).

    ``sources``: the C files whose struct comments describe the variables (the firmware's headers,
    board_virtual.c, the library's headers).
    """
    from elftools.elf.elffile import ELFFile

    from ..core.cheaders import field_comments
    from .link import CALIBRATIONS, MEASUREMENTS, VIRTUAL_CALIBRATIONS, VIRTUAL_MEASUREMENTS, firmware_variables

    variables = firmware_variables(elf, virtual)
    with open(elf, "rb") as f:
        byte_order = "little" if ELFFile(f).little_endian else "big"
    comments = field_comments(p.read_text() for p in sources)
    Ts_speed_s = Ts_current_s * current_per_speed
    return write_a2l(
        path,
        module=Path(elf).stem,
        variables=variables,
        measurements=[*MEASUREMENTS, *(VIRTUAL_MEASUREMENTS if virtual else ())],
        calibrations=[*CALIBRATIONS, *(VIRTUAL_CALIBRATIONS if virtual else ())],
        comments=comments,
        events=[("current", Ts_current_s), ("speed", Ts_speed_s)],
        timestamp_s=Ts_current_s,
        byte_order=byte_order,
        tcp_port=tcp_port,
        sxi_baud=sxi_baud,
    )
