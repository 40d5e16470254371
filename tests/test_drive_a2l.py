"""The A2L files a firmware build writes, read back by pya2ldb (an A2L parser nobody here wrote) and held
against the ELFs as binutils' nm lists them, and against the host compiler's layout of the library's
structs (cffi's offsetof): every variable's memory segment, every field's address and type, the units
and ranges of the C comments, the XCP interface (parsed by the file's own A2ML)."""

import re
import shutil
import subprocess

import pytest

from pmsm2dof.core.bindings import enum_names, ffi, field_comment, struct_fields

pya2l = pytest.importorskip("pya2l")
from pya2l import model  # noqa: E402

_MISSING = [t for t in ("cmake", "cc", "nm", "arm-none-eabi-gcc", "arm-none-eabi-nm") if shutil.which(t) is None]

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed (scripts/install.sh)"),
]

#: (ELF, its A2L, nm, the virtual board's variables are in it, XCP on SxI)
BUILDS = [
    ("virtual_drive.elf", "virtual_drive.a2l", "arm-none-eabi-nm", True, True),
    ("firmware.elf", "firmware.a2l", "arm-none-eabi-nm", False, True),
    ("virtual_drive_host", "virtual_drive_host.a2l", "nm", True, False),
]
#: The firmware's variables of each kind (examples/firmware/link.h, capture.h, commission_task.h, board_virtual.c).
MEASUREMENTS = ["foc_now", "link_status_now", "capture_status_now", "capture_buffer", "commission_now", "identify_now"]
CALIBRATIONS = ["link_speed_config", "link_current_config", "link_command", "link_reference", "capture_config",
                "commission_config", "commission_command", "identify_config", "identify_command"]  # fmt: skip
#: Struct type of the library's calibration variables.
LIBRARY = {"link_speed_config": "p2d_speed_config_t", "link_current_config": "p2d_current_config_t"}


@pytest.fixture(scope="module")
def folder(servo_firmware):
    return servo_firmware[1]


def nm_symbols(nm, elf):
    """{name: (address, size)} of the data symbols, from binutils' nm -S."""
    out = subprocess.run([nm, "-S", str(elf)], capture_output=True, text=True, check=True).stdout
    symbols = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "bBdDgGsS":
            symbols[parts[3]] = (int(parts[0], 16), int(parts[1], 16))
    return symbols


def read_a2l(path):
    session = pya2l.import_a2l(str(path), in_memory=True, progress_bar=False, loglevel="ERROR")
    session.setup_ifdata_parser("ERROR")
    return session


@pytest.mark.parametrize(("elf", "a2l", "nm", "virtual", "sxi"), BUILDS)
def test_every_address_and_size_is_the_elfs(folder, elf, a2l, nm, virtual, sxi):
    symbols = nm_symbols(nm, folder / elf)
    s = read_a2l(folder / a2l)
    variables = MEASUREMENTS + CALIBRATIONS + (["vd_trace", "vd_load"] if virtual else [])
    segments = {m.name: (m.address, m.size) for m in s.query(model.MemorySegment).all()}
    assert segments == {v: symbols[v] for v in variables}
    measurements = {m.name: m for m in s.query(model.Measurement).all()}
    characteristics = {c.name: c for c in s.query(model.Characteristic).all()}
    assert measurements and characteristics
    offsets = {}
    sizes = {
        "FLOAT32_IEEE": 4,
        "FLOAT64_IEEE": 8,
        "UBYTE": 1,
        "UWORD": 2,
        "ULONG": 4,
        "SLONG": 4,
        "SWORD": 2,
        "A_UINT64": 8,
    }
    for name, m in measurements.items():
        var = name.split(".")[0]
        assert var in MEASUREMENTS + ["vd_trace"], name
        start, size = symbols[var]
        n = (m.matrix_dim.numbers[0] if m.matrix_dim else 1) * sizes[m.datatype]
        assert start <= m.ecu_address.address and m.ecu_address.address + n <= start + size, name
    for name, c in characteristics.items():
        var = name.split(".")[0]
        assert var in CALIBRATIONS + ["vd_load"], name
        start, size = symbols[var]
        dtype = str(c.deposit)[len("RL_") :]
        n = (c.matrix_dim.numbers[0] if c.matrix_dim else 1) * sizes[dtype]
        assert start <= c.address and c.address + n <= start + size, name
        if var in LIBRARY:
            offsets.setdefault(var, {})[name.split(".")[1]] = (c.address - start, sizes[dtype])
    for var, fields in offsets.items():
        if nm == "nm":
            # the PC's drive: the offsets the host compiler gave the library's struct in the extension (cffi)
            assert fields == {f: (ffi.offsetof(LIBRARY[var], f), n) for f, (_, n) in fields.items()}
        else:
            # the MCU: C's layout rules over the fields in their declaration order, each at the next multiple
            # of its size (the Arm EABI of bare-metal GCC gives an enum the smallest integer that holds it)
            expected, at = {}, 0
            for f in struct_fields(LIBRARY[var]):
                n = fields[f][1]
                at = -(-at // n) * n
                expected[f] = (at, n)
                at += n
            assert fields == expected
    # the fields of a variable do not overlap and cover it up to its padding
    for var in variables:
        fields = sorted(
            [(m.ecu_address.address, m) for n, m in measurements.items() if n.split(".")[0] == var]
            + [(c.address, c) for n, c in characteristics.items() if n.split(".")[0] == var],
            key=lambda t: t[0],
        )
        assert len({a for a, _ in fields}) == len(fields), var
    if virtual:
        assert len([n for n in measurements if n.startswith("vd_trace.")]) == 24


def test_units_ranges_and_enums_come_from_the_c_declarations(folder):
    s = read_a2l(folder / "virtual_drive.a2l")
    alpha = s.query(model.Characteristic).filter(model.Characteristic.name == "link_speed_config.alpha_radps").one()
    assert alpha.longIdentifier == field_comment("p2d_speed_config_t", "alpha_radps")
    cm = s.query(model.CompuMethod).filter(model.CompuMethod.name == alpha.conversion).one()
    assert cm.unit == "rad/s" and cm.conversionType == "IDENTICAL"
    assert alpha.lowerLimit == 0.0  # "> 0"
    command = s.query(model.Characteristic).filter(model.Characteristic.name == "link_command.command").one()
    assert (command.lowerLimit, command.upperLimit) == (0.0, 2.0)  # "0..2"
    # a bound of another quantity is none of the field's: "[s], >= 10 Ts_s", "[rad/s], > 0, w_e_spin_radps Ts_s <= 0.1"
    tau = s.query(model.Characteristic).filter(model.Characteristic.name == "commission_config.tau_i_s").one()
    assert (tau.lowerLimit, tau.upperLimit) == (-3.4e38, 3.4e38)
    spin = s.query(model.Characteristic).filter(model.Characteristic.name == "commission_config.w_e_spin_radps").one()
    assert (spin.lowerLimit, spin.upperLimit) == (0.0, 3.4e38)
    trip = s.query(model.Characteristic).filter(model.Characteristic.name == "commission_config.i_trip_A").one()
    assert trip.lowerLimit == -3.4e38  # ">= 1.5 max(i_test_A, i_spin_A)": not 1.5, nor 1
    w_m = s.query(model.Measurement).filter(model.Measurement.name == "vd_trace.w_m_radps").one()
    assert s.query(model.CompuMethod).filter(model.CompuMethod.name == w_m.conversion).one().unit == "rad/s"
    method = s.query(model.Characteristic).filter(model.Characteristic.name == "link_speed_config.method").one()
    table = s.query(model.CompuVtab).filter(model.CompuVtab.name == "VT_" + method.conversion[3:]).one()
    names = [p.outVal for p in table.pairs]
    assert [n.lower().removeprefix("p2d_") for n in names] == list(enum_names("p2d_method_t", "P2D_"))


@pytest.mark.parametrize(("elf", "a2l", "nm", "virtual", "sxi"), BUILDS)
def test_the_xcp_interface(folder, elf, a2l, nm, virtual, sxi):
    """IF_DATA XCP as the file's A2ML parses it: limits, events at the loop periods, timestamps, transports."""
    s = read_a2l(folder / a2l)
    module = s.query(model.Module).first()
    (xcp,) = s.parse_ifdata(module.if_data)
    (xcp,) = xcp["XCP"]
    protocol = xcp["PROTOCOL_LAYER"]
    assert protocol[8:12] == [255, 255, "BYTE_ORDER_MSB_LAST", "ADDRESS_GRANULARITY_BYTE"]
    daq = xcp["DAQ"]
    assert daq[0] == "DYNAMIC" and daq[2] == 2
    # 50 us = 5 x 10^4 ns, 0.5 ms = 5 x 10^5 ns; timestamps in ticks of the current period
    assert daq[-1]["EVENT"] == [
        ["current", "current", 0, "DAQ", 255, 5, 4, 2],
        ["speed", "speed", 1, "DAQ", 255, 5, 5, 1],
    ]
    assert daq[-1]["TIMESTAMP_SUPPORTED"] == [5, "SIZE_DWORD", "UNIT_10US"]
    assert ("XCP_ON_SxI" in xcp) == sxi
    if sxi:
        assert xcp["XCP_ON_SxI"][3:] == ["HEADER_LEN_CTR_WORD", "NO_CHECKSUM"]
    assert xcp["XCP_ON_TCP_IP"][2] == {"ADDRESS": "127.0.0.1"}
    mod_common = s.query(model.ModCommon).first()
    assert mod_common.byte_order.byteOrder == "MSB_LAST"
    assert re.search(r"ASAP2_VERSION 1 71", (folder / a2l).read_text())


@pytest.mark.parametrize(("elf", "a2l", "nm", "virtual", "sxi"), BUILDS)
def test_the_drive_commands_reader_agrees_with_pya2ldb(folder, elf, a2l, nm, virtual, sxi):
    """pmsm2dof.drive.a2l_reader.read_a2l (what `pmsm2dof drive` reads) against pya2ldb: every segment, every
    MEASUREMENT's and CHARACTERISTIC's address, type, element count, limits, unit and text, the events."""
    from pmsm2dof.drive.a2l_reader import read_a2l as drive_a2l

    mine = drive_a2l(folder / a2l)
    s = read_a2l(folder / a2l)
    assert mine.segments == {m.name: (m.address, m.size) for m in s.query(model.MemorySegment).all()}
    units = {c.name: c.unit for c in s.query(model.CompuMethod).all()}
    sizes = {
        "FLOAT32_IEEE": 4,
        "FLOAT64_IEEE": 8,
        "UBYTE": 1,
        "UWORD": 2,
        "ULONG": 4,
        "SLONG": 4,
        "SWORD": 2,
        "A_UINT64": 8,
    }
    theirs = {}
    for m in s.query(model.Measurement).all():
        theirs[m.name] = (m.ecu_address.address, sizes[m.datatype], m.matrix_dim.numbers[0] if m.matrix_dim else 1,
                          m.lowerLimit, m.upperLimit, units[m.conversion], m.longIdentifier, False)  # fmt: skip
    for c in s.query(model.Characteristic).all():
        size = sizes[str(c.deposit)[len("RL_") :]]
        theirs[c.name] = (c.address, size, c.matrix_dim.numbers[0] if c.matrix_dim else 1, c.lowerLimit,
                          c.upperLimit, units[c.conversion], c.longIdentifier, True)  # fmt: skip
    assert {
        n: (e.scalar.address, e.scalar.size, e.scalar.count, e.lower, e.upper, e.unit, e.text, e.writable)
        for n, e in mine.entries.items()
    } == theirs
    module = s.query(model.Module).first()
    (xcp,) = s.parse_ifdata(module.if_data)
    events = xcp["XCP"][0]["DAQ"][-1]["EVENT"]
    assert mine.events == {e[0]: (e[2], pytest.approx(e[5] * 10.0 ** e[6] * 1e-9, rel=1e-12)) for e in events}
    assert mine.module == module.name and mine.byte_order == "little"
