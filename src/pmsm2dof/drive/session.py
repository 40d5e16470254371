"""What ``pmsm2dof drive`` does on a link: identity, reads and checked writes by name, DAQ captures to files.

The drive is described by its A2L file (:func:`pmsm2dof.drive.a2l_reader.read_a2l`): the names, types,
units and limits of its variables, its DAQ events. A write is checked on the host before anything
is sent: the A2L's type and limits, then the controller's own validation (the C library's
``p2d_speed_init`` / ``p2d_current_init`` on the configuration the drive would hold), and again by
the drive when it commits it. A link that drops mid-command is reported in one line: the drive
falls back to its safe state by itself (a write is taken whole or not at all; a run is stopped by
the link watchdog, examples/firmware/link.h).
"""

import contextlib
import dataclasses
import io
import math
import os
import shutil
import struct
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.bindings import c_string, ffi, lib
from ..errors import ConfigError, ToolError, format_bytes
from ..outputs import atomic_file, atomic_write
from .a2l_reader import Entry
from .link import _FORMATS, Capture, Link

#: The scenario's sections whose keys the drive's configuration variables carry (same field names).
SCENARIO_SECTIONS = {"speed_controller": "link_speed_config", "current_loop": "link_current_config"}
#: The controllers' configuration variables: the C type of each and its validating init.
CONTROLLERS = {
    "link_speed_config": ("p2d_speed_config_t", "p2d_speed_t", "p2d_speed_init"),
    "link_current_config": ("p2d_current_config_t", "p2d_current_t", "p2d_current_init"),
}
#: The variable whose Ts_s the firmware fixes (it refuses another loop period).
FIXED_FIELDS = ("Ts_s",)

#: Most names of one get, set or capture.
NAMES_MAX = 64
#: Longest capture [s].
DURATION_MAX_S = 3600.0
#: Most values (samples x columns) of one capture: what the host holds while it runs (some 100 bytes each).
CAPTURE_VALUES_MAX = 20_000_000
#: Bytes a value takes in the largest output format (CSV text), for the room check before a capture.
BYTES_PER_VALUE = 24
#: What each kind of link streams, stated [bytes/s] (a capture measured otherwise gives --link-bytes-per-s): a
#: UART at 115200 baud (10 bits a byte), a CAN bus at 500 kbit/s (8 data bytes in some 130 bits a frame), TCP.
LINK_BYTES_PER_S = {"serial": 11_520.0, "can": 30_000.0, "tcp": 1_000_000.0}
#: Share of the link's rate a DAQ capture may take (the rest: the master's polls, the framing's jitter).
DAQ_SHARE = 0.5
#: Bytes a DAQ sample adds to its payload: the SxI/TCP header (4), the PID (1) and the timestamp (4).
DAQ_OVERHEAD_BYTES = 9
#: Ways of a capture: chosen by the rate, streamed by DAQ, or recorded in the drive's buffer.
CAPTURE_WAYS = ("auto", "daq", "buffer")
#: Formats of a capture file.
CAPTURE_FORMATS = (".csv", ".parquet", ".mf4")

#: What the drive does when the link drops (examples/firmware/link.h): one line for the user.
SAFE_STATE = (
    "the drive falls back to its safe state by itself: a write is taken whole or not at all, and a run "
    "is stopped by the link watchdog (speed ramped to zero, then the power stage off)"
)


#: What the drive does when the link drops during its commissioning (examples/firmware/commission_task.h).
SAFE_STATE_COMMISSIONING = (
    "the drive falls back to its safe state by itself: its link watchdog ends the commissioning routine, zero "
    "voltage and the power stage off"
)


@contextlib.contextmanager
def link_errors(link: Link, what: str, safe_state: str = SAFE_STATE) -> Iterator[None]:
    """Turn pyxcp's timeouts and the transport's errors during ``what`` into one ToolError line.

    An error packet of the drive (pyxcp's XcpResponseError) becomes a ToolError naming its code;
    a dropped link one that says what the drive does then (``safe_state``).
    """
    from can import CanError
    from pyxcp.types import XcpResponseError, XcpTimeoutError

    try:
        yield
    except XcpResponseError as exc:
        code = exc.get_error_code()  # type: ignore[no-untyped-call]
        raise ToolError(f"the drive at {link.url} refused {what}: {code}") from None
    except (XcpTimeoutError, OSError, EOFError, CanError) as exc:
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ToolError(f"the link to {link.url} dropped during {what} ({reason}); {safe_state}") from None


def open_link(url: str, a2l: Path | str, *, allow_remote: bool = False, timeout_s: float = 2.0) -> Link:
    """An open :class:`Link` to the drive at ``url`` described by the A2L file ``a2l``.

    ``url`` in the forms of :func:`~pmsm2dof.drive.transport.link_url`.
    """
    from can import CanError
    from pyxcp.types import XcpTimeoutError

    if Path(a2l).suffix.lower() != ".a2l":
        raise ConfigError("a2l", str(a2l), "an A2L file (*.a2l), written beside the firmware's ELF by its build")
    link = Link(url, a2l, allow_remote=allow_remote, timeout_s=timeout_s)
    try:
        link.open()
    except (XcpTimeoutError, OSError, EOFError, CanError) as exc:
        link.close()
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ToolError(
            f"the drive at {link.url} does not answer ({reason}; a drive takes one master at a time)"
        ) from None
    except BaseException:
        link.close()
        raise
    return link


def entry(link: Link, name: str) -> Entry:
    """The A2L entry of ``name``: a variable's field (``link_speed_config.alpha_radps``) or a scenario key that
    names one (``speed_controller.alpha_radps``)."""
    assert link.a2l is not None
    section, _, field = name.partition(".")
    full = f"{SCENARIO_SECTIONS[section]}.{field}" if section in SCENARIO_SECTIONS else name
    if full not in link.a2l.entries:
        listed = ", ".join(sorted(link.a2l.entries)[:8])
        raise ConfigError("name", name, f"a variable of the A2L file {link.a2l.path.name} ({listed}, ...)")
    return link.a2l.entries[full]


def _check_names(names: Sequence[str]) -> None:
    if not 1 <= len(names) <= NAMES_MAX:
        raise ConfigError("names", f"<{len(names)} names>", f"1 to {NAMES_MAX} names")


def info(link: Link) -> dict[str, Any]:
    """The drive's identity, protocol limits, events, run status and the configuration it runs."""
    assert link.a2l is not None
    with link_errors(link, "info"):
        master = link.master
        ident = master.identifier(1)
        props = master.slaveProperties
        daq = master.getDaqProcessorInfo()
        status = link.status()
        config = {
            var: {
                e.scalar.field: value(link, e) for e in link.a2l.entries.values() if e.scalar.name.startswith(var + ".")
            }
            for var in CONTROLLERS
            if var in link.variables
        }
    return {
        "url": link.url,
        "id": ident,
        "a2l_module": link.a2l.module,
        "byte_order": str(props.byteOrder),
        "max_cto": int(props.maxCto),
        "max_dto": int(props.maxDto),
        "protocol_version": int(props.protocolLayerVersion),
        "daq_lists_max": int(daq.maxDaq),
        "events": {name: period for name, (_, period) in link.a2l.events.items()},
        "status": status,
        "config": config,
    }


def read_variable(link: Link, name: str) -> dict[str, Any]:
    """Every field of the variable ``name`` (a struct of the firmware), read in one upload: ``{field: value}``."""
    if name not in link.variables:
        raise ConfigError("link", link.url, f"a drive whose firmware has {name} (its A2L lists it)")
    var = link.variables[name]
    data = link.read_bytes(var.address, var.size)
    out: dict[str, Any] = {}
    for s in var.scalars:
        fmt = f"<{s.count}{_FORMATS[(s.encoding, s.size)]}"
        values = struct.unpack_from(fmt, data, s.address - var.address)
        out[s.field] = values[0] if s.count == 1 else values
    return out


def value(link: Link, e: Entry) -> Any:
    """The value of an entry: a number, an enumerator's name, or a tuple for an array."""
    raw = link.read(e.scalar.name)
    names = dict(e.scalar.enumerators)
    if names and not isinstance(raw, tuple):
        return names.get(int(raw), int(raw))
    if e.scalar.encoding == "float" and e.scalar.size == 4:
        # the shortest decimal that is the float32 (0.0001, not 9.999999747378752e-05)
        return tuple(float(str(np.float32(v))) for v in raw) if isinstance(raw, tuple) else float(str(np.float32(raw)))
    return raw


def get(link: Link, names: Sequence[str]) -> list[tuple[str, Any, str]]:
    """``(name, value, unit)`` of each name (:func:`entry`), read from the drive."""
    _check_names(names)
    entries = [entry(link, n) for n in names]
    with link_errors(link, "get"):
        return [(n, value(link, e), e.unit) for n, e in zip(names, entries)]


def _parse(e: Entry, text: str) -> float | int:
    """The number ``text`` gives for an entry (an enum's value may be given by its name), checked against the
    A2L's type and limits."""
    s = e.scalar
    name = s.name
    if s.count != 1:
        raise ConfigError(name, text, "a scalar: the schedules are written by `pmsm2dof drive run`")
    if s.enumerators:
        # the enumerator's name, or its end after the type's prefix (P2D_AW_BACK_CALCULATION: back_calculation)
        t = text.strip().lower()
        hits = [c for c, label in s.enumerators if label.lower() == t or label.lower().endswith("_" + t)]
        if len(hits) == 1:
            return hits[0]
    try:
        number = float(text)
    except ValueError:
        number = math.nan
    valid = f"[{e.lower:g}, {e.upper:g}]" + (f" {e.unit}" if e.unit not in ("", "-") else "")
    if s.enumerators:
        valid = ", ".join(label for _, label in s.enumerators)
    if not math.isfinite(number) or not e.lower <= number <= e.upper:
        raise ConfigError(name, text, f"{valid} ({e.text})")
    if s.encoding != "float":
        if number != round(number):
            raise ConfigError(name, text, f"an integer in {valid}")
        return int(number)
    return number


def _controller_check(link: Link, var: str, changes: Mapping[str, float | int]) -> None:
    """Raise ConfigError unless the controller accepts the configuration the drive would hold after the changes:
    the C library's validating init on the host, and the firmware's fixed loop period."""
    assert link.a2l is not None
    ctype, state_type, init = CONTROLLERS[var]
    cfg = ffi.new(f"{ctype} *")
    current: dict[str, Any] = {}
    for e in link.a2l.entries.values():
        if e.scalar.name.startswith(var + "."):
            current[e.scalar.field] = link.read(e.scalar.name)
    for field in FIXED_FIELDS:
        name = f"{var}.{field}"
        if name in changes and field in current and np.float32(changes[name]) != np.float32(current[field]):
            raise ConfigError(name, changes[name], f"{current[field]!r}: the firmware's loop period is fixed at build")
    for field, v in current.items():
        setattr(cfg, field, changes.get(f"{var}.{field}", v))
    status = getattr(lib, init)(ffi.new(f"{state_type} *"), cfg)
    if status != lib.P2D_OK:
        param = c_string(lib.p2d_status_param(status))
        name = f"{var}.{param}"
        given = changes.get(name, current.get(param))
        raise ConfigError(name, given, c_string(lib.p2d_status_range(status)) + " (the controller's check)")


def set_values(link: Link, assignments: Sequence[str]) -> list[tuple[str, Any, str]]:
    """Write ``NAME=VALUE`` assignments, checked first (A2L type and limits, the controller's validation).

    The fields of one variable go in one DOWNLOAD, taken by the drive at once at its next speed
    sample. Returns ``(name, value, unit)`` read back from the drive.

    Raises
    ------
    ConfigError
        A malformed assignment, an unknown name, a value outside the A2L's range or refused by the
        controller's check (naming the variable, the value and the valid range); nothing is written.
    ToolError
        The drive refused the write (its check) or the link dropped.
    """
    _check_names(assignments)
    changes: dict[str, float | int] = {}
    for text in assignments:
        name, sep, raw = text.partition("=")
        if not sep or not name.strip():
            raise ConfigError("assignment", text, "NAME=VALUE, e.g. speed_controller.alpha_radps=120")
        e = entry(link, name.strip())
        if not e.writable:
            raise ConfigError(name.strip(), raw, "a calibration variable (this one is a measurement: read-only)")
        changes[e.scalar.name] = _parse(e, raw)
    with link_errors(link, "set"):
        for var in {n.split(".")[0] for n in changes} & set(CONTROLLERS):
            _controller_check(link, var, changes)
        link.write(changes)
        return [(n, value(link, entry(link, n)), entry(link, n).unit) for n in changes]


@dataclasses.dataclass(frozen=True)
class CapturePlan:
    """A capture checked before it starts: its signals, event, period and size."""

    signals: tuple[str, ...]
    event: str
    period_s: float
    duration_s: float
    samples: int
    #: "daq" (streamed) or "buffer" (recorded in the drive, read out after)
    way: str = "daq"
    #: the payload the DAQ would stream and what the link streams [bytes/s]
    need_bytes_per_s: float = 0.0
    link_bytes_per_s: float = 0.0
    #: the buffer's trigger, its signal and level, and the samples before it
    trigger: str = "immediate"
    trigger_signal: str | None = None
    level: float = 0.0
    pre_samples: int = 0


def link_kind(url: str) -> str:
    """The kind of a link URL: ``tcp``, ``can`` or ``serial``."""
    return "tcp" if url.startswith(("tcp://", "socket://")) else "can" if url.startswith("can://") else "serial"


def parse_trigger(text: str) -> tuple[str, str | None, float]:
    """``immediate``, ``SIGNAL>LEVEL`` (rising) or ``SIGNAL<LEVEL`` (falling) -> (kind, signal, level).

    (The start of a run, the buffer's fourth trigger, is for a master that starts the run itself:
    :meth:`pmsm2dof.drive.link.Link.capture_buffered`.)
    """
    if text == "immediate":
        return text, None, 0.0
    for op, kind in ((">", "rising"), ("<", "falling")):
        name, sep, level = text.partition(op)
        if sep and name.strip():
            try:
                value = float(level)
            except ValueError:
                break
            if math.isfinite(value):
                return kind, name.strip(), value
    raise ConfigError("trigger", text, "immediate, SIGNAL>LEVEL (rising) or SIGNAL<LEVEL (falling)")


def plan_capture(
    link: Link,
    signals: Sequence[str],
    event: str,
    duration_s: float,
    out: Path | str,
    force: bool = False,
    *,
    way: str = "auto",
    link_bytes_per_s: float | None = None,
    trigger: str = "immediate",
    pre_s: float = 0.0,
) -> CapturePlan:
    """Check a capture before any work: names, event, duration, the samples it holds and the room for its file.

    The way: DAQ when its payload (signals x bytes + 9 bytes a sample, x the event's rate) takes at
    most half of what the link streams (``link_bytes_per_s``, else :data:`LINK_BYTES_PER_S` of its
    kind), else the drive's capture buffer (examples/firmware/capture.h), which must hold the
    duration; ``way`` forces one. A trigger (:func:`parse_trigger`; ``pre_s`` before it) needs the
    buffer. ``out`` must be a new file unless ``force`` (an existing file is replaced only when
    asked). Raises ConfigError naming what is out of range.
    """
    if way not in CAPTURE_WAYS:
        raise ConfigError("way", way, " or ".join(CAPTURE_WAYS))
    if link_bytes_per_s is not None and not (math.isfinite(link_bytes_per_s) and 1.0 <= link_bytes_per_s <= 1e10):
        raise ConfigError("link_bytes_per_s", link_bytes_per_s, "[1, 1e10] bytes/s")
    kind, trigger_signal, level = parse_trigger(trigger)
    assert link.a2l is not None
    _check_names(signals)
    names = tuple(entry(link, s).scalar.name for s in signals)
    if len(set(names)) != len(names):
        raise ConfigError("signals", ", ".join(signals), "each signal once")
    for n in names:
        if link.scalars[n].count != 1:
            raise ConfigError("signal", n, "a scalar (an array's elements are not DAQ signals here)")
    if event not in link.a2l.events:
        raise ConfigError("event", event, " or ".join(link.a2l.events) + " (the A2L's DAQ events)")
    if not (isinstance(duration_s, float | int) and math.isfinite(duration_s) and 0 < duration_s <= DURATION_MAX_S):
        raise ConfigError("duration_s", duration_s, f"(0, {DURATION_MAX_S:g}] s")
    suffix = Path(out).suffix.lower()
    if suffix not in CAPTURE_FORMATS:
        raise ConfigError("out", str(out), "a file ending in " + ", ".join(CAPTURE_FORMATS))
    if Path(out).is_dir() or (os.path.lexists(out) and not Path(out).is_file()):
        raise ConfigError("out", str(out), "a file path (it is a folder, a device, a FIFO or a socket)")
    if os.path.lexists(out) and not force:
        raise ConfigError("out", str(out), "a new file (it exists; force=True replaces it)")
    if not Path(out).resolve().parent.is_dir():
        raise ConfigError("out", str(out), "a file in an existing folder")
    period_s = link.a2l.events[event][1]
    samples = math.ceil(duration_s / period_s) + 1
    values = samples * (len(names) + 1)
    if values > CAPTURE_VALUES_MAX:
        raise ConfigError(
            "duration_s",
            duration_s,
            f"at most {CAPTURE_VALUES_MAX / (len(names) + 1) * period_s:.4g} s of {len(names)} signals at the "
            f"{event} event ({period_s:g} s): {CAPTURE_VALUES_MAX:g} values",
        )
    folder = Path(out).resolve().parent
    if folder.is_dir():
        free = shutil.disk_usage(folder).free
        if values * BYTES_PER_VALUE > free:
            raise ConfigError(
                "out",
                str(out),
                f"a disk with room for {format_bytes(values * BYTES_PER_VALUE)} (it has {format_bytes(free)})",
            )
    rate = link_bytes_per_s if link_bytes_per_s is not None else LINK_BYTES_PER_S[link_kind(link.url)]
    record = sum(link.scalars[n].size for n in names)
    need = (record + DAQ_OVERHEAD_BYTES) / period_s
    # classic CAN: 8-byte packets leave 3 bytes beside the PID and the timestamp, too few for most signals
    classic_can = link.url.startswith("can://") and "&fd=0" in link.url
    streams = need <= DAQ_SHARE * rate and not classic_can
    chosen = way if way != "auto" else "daq" if streams and kind == "immediate" else "buffer"
    if chosen == "daq" and kind != "immediate":
        raise ConfigError("trigger", trigger, "immediate for a DAQ capture (a trigger needs the drive's buffer)")
    if chosen == "daq" and classic_can:
        raise ConfigError("way", way, "buffer or auto on classic CAN (fd=0): a DAQ packet of 8 bytes holds no signal")
    pre_samples = 0
    if chosen == "buffer":
        if "capture_buffer" not in link.variables:
            raise ConfigError("way", way, "daq: this drive has no capture buffer")
        capacity = link.variables["capture_buffer"].size // record
        samples = round(duration_s / period_s) + 1
        if samples > capacity:
            raise ConfigError(
                "duration_s",
                duration_s,
                f"at most {(capacity - 1) * period_s:.6g} s of these {len(names)} signals ({record} bytes a sample) "
                f"at the {event} event in the drive's capture buffer of {link.variables['capture_buffer'].size} "
                f"bytes: the link streams {rate:.6g} bytes/s, DAQ would need {need:.6g}",
            )
        if not (math.isfinite(pre_s) and 0.0 <= pre_s <= (samples - 1) * period_s):
            raise ConfigError("pre_s", pre_s, f"[0, {(samples - 1) * period_s:g}] s (the capture's duration)")
        pre_samples = round(pre_s / period_s)
        if trigger_signal is not None:
            trigger_signal = entry(link, trigger_signal).scalar.name
            if trigger_signal not in names:
                raise ConfigError("trigger", trigger, "a crossing of one of the captured signals")
    return CapturePlan(names, event, period_s, float(duration_s), samples, chosen, need, rate, kind,
                       trigger_signal, level, pre_samples)  # fmt: skip


def capture(link: Link, plan: CapturePlan) -> Capture:
    """Run a planned DAQ capture: the samples of its duration from the first one, by the drive's timestamps (the
    status polled all along: the watchdog stays fed)."""
    if plan.way == "buffer":
        with link_errors(link, "capture"):
            return link.capture_buffered(
                list(plan.signals), event=plan.event, samples=plan.samples, trigger=plan.trigger,
                level=plan.level, trigger_signal=plan.trigger_signal, pre_samples=plan.pre_samples,
                timeout_s=max(60.0, 1000 * plan.duration_s),
            )  # fmt: skip
    with link_errors(link, "capture"):
        cap = link.capture(list(plan.signals), event=plan.event, duration_s=plan.duration_s)
    # the DAQ list streams from its start until its stop reaches the drive: keep the duration's samples
    t_s = (cap.timestamps - (cap.timestamps[0] if len(cap.timestamps) else 0)) * 1e-9
    keep = t_s <= plan.duration_s * (1.0 + 1e-12)
    return Capture({n: v[keep] for n, v in cap.signals.items()}, cap.timestamps[keep], cap.dtos_lost)


def capture_columns(link: Link, cap: Capture) -> dict[str, npt.NDArray[Any]]:
    """The columns of a capture: ``t_s`` (from the first sample's DAQ timestamp, or from the trigger of a buffered
    capture) and each signal."""
    t0 = cap.trigger_ns if cap.trigger_ns is not None else cap.timestamps[0] if len(cap.timestamps) else 0
    t_s = (cap.timestamps - t0) * 1e-9
    return {"t_s": t_s, **cap.signals}


def write_capture(link: Link, cap: Capture, path: Path | str) -> None:
    """Write a capture to ``path`` (whole or not at all): CSV, Parquet or MDF4 (ASAM MDF 4.10 by asammdf, the
    format CANape and INCA write: one channel group, the DAQ time as master, each signal with its A2L unit
    and description)."""
    assert link.a2l is not None
    columns = capture_columns(link, cap)
    suffix = Path(path).suffix.lower()
    if suffix in (".csv", ".parquet"):
        import pandas as pd

        frame = pd.DataFrame(columns)
        with atomic_file(path, "w" if suffix == ".csv" else "wb") as f:
            if suffix == ".csv":
                # each float as the shortest text that reads back to its double: float32 values widened first, so
                # that the CSV reads back to the same numbers as the binary formats
                frame = frame.astype({c: np.float64 for c in frame.columns if frame[c].dtype.kind == "f"})
                frame.to_csv(f, index=False)
            else:
                frame.to_parquet(f, index=False)
        return
    if suffix != ".mf4":
        raise ConfigError("out", str(path), "a file ending in " + ", ".join(CAPTURE_FORMATS))
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    t = np.asarray(columns["t_s"], dtype=np.float64)
    signals = []
    for name, samples in cap.signals.items():
        e = link.a2l.entries[name]
        signals.append(Signal(samples=np.asarray(samples), timestamps=t, name=name, unit=e.unit, comment=e.text))
    mdf.append(signals, comment=f"pmsm2dof drive capture of {link.a2l.module} at {link.url}")
    data = io.BytesIO()
    mdf.save(data, overwrite=True)
    mdf.close()
    atomic_write(path, data.getvalue())
