"""A session with the firmware's XCP slave over its link, by the names of its variables.

The master is pyxcp (the ``drive`` extra); the names, addresses and types are the ELF's
(:func:`pmsm2dof.drive.elf.read_variables`), the facts the build's A2L file lists. The link is
XCP on TCP, on SxI (a UART) or on CAN (:mod:`pmsm2dof.drive.transport`).

The firmware's run control (examples/firmware/link.h): :meth:`Link.play` writes a reference
schedule (and, on the virtual board, a load schedule), starts a run of so many speed samples,
captures named signals by DAQ at the speed event while it keeps the link alive, and returns them
sample by sample; :meth:`Link.capture_buffered` reads the firmware's triggered capture buffer.
"""

import dataclasses
import struct
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core import LOG_COLUMNS
from ..errors import ConfigError, SimulationError, ToolError
from .a2l_reader import A2l, read_a2l
from .elf import Scalar, Variable, read_variables
from .transport import link_url, pyxcp_master, use_default_application

#: The variables of the firmware example that the slave exposes (examples/firmware/link.h, capture.h,
#: commission_task.h, identify_task.h).
MEASUREMENTS = ("foc_now", "link_status_now", "capture_status_now", "capture_buffer", "commission_now", "identify_now")
CALIBRATIONS = (
    "link_speed_config",
    "link_current_config",
    "link_command",
    "link_reference",
    "capture_config",
    "commission_config",
    "commission_command",
    "identify_config",
    "identify_command",
)
#: The virtual board's own (board_virtual.c).
VIRTUAL_MEASUREMENTS = ("vd_trace",)
VIRTUAL_CALIBRATIONS = ("vd_load",)
#: Entries of a schedule (LINK_SCHEDULE_MAX, VB_LOAD_MAX).
SCHEDULE_MAX = 32
#: The run states of link_status_now.state.
STATES = ("idle", "running", "done", "tripped", "stopped")
#: Events of the slave, by name.
EVENTS = {"current": 0, "speed": 1}
#: The capture buffer's triggers (examples/firmware/capture.h), by name.
TRIGGERS = {"immediate": 0, "rising": 1, "falling": 2, "run": 3}
#: Most signals of one buffered capture (CAPTURE_SIGNALS_MAX).
CAPTURE_SIGNALS_MAX = 16

_FORMATS = {("float", 4): "f", ("float", 8): "d", ("unsigned", 1): "B", ("unsigned", 2): "H", ("unsigned", 4): "I",
            ("signed", 1): "b", ("signed", 2): "h", ("signed", 4): "i", ("bool", 1): "B", ("enum", 1): "B",
            ("enum", 2): "H", ("enum", 4): "I", ("unsigned", 8): "Q", ("signed", 8): "q"}  # fmt: skip
_DAQ_TYPES = {"f": "F32", "d": "F64", "B": "U8", "H": "U16", "I": "U32", "b": "S8", "h": "S16", "i": "S32",
              "Q": "U64", "q": "S64"}  # fmt: skip


def firmware_variables(elf: Path | str, virtual: bool) -> dict[str, Variable]:
    """The firmware's exposed variables in ``elf`` (with the virtual board's when ``virtual``).

    The virtual board's trace row ``vd_trace`` (double[24]) is split into its columns, named as the
    engine's log columns (:data:`pmsm2dof.core.LOG_COLUMNS`): ``vd_trace.w_m_radps``, ...
    """
    names = [*MEASUREMENTS, *CALIBRATIONS]
    if virtual:
        names += [*VIRTUAL_MEASUREMENTS, *VIRTUAL_CALIBRATIONS]
    variables = read_variables(elf, names)
    if virtual:
        row = variables["vd_trace"]
        (whole,) = row.scalars
        if whole.count != len(LOG_COLUMNS):
            raise ConfigError("vd_trace", f"<{whole.count} columns>", f"the engine's {len(LOG_COLUMNS)} log columns")
        columns = tuple(
            dataclasses.replace(whole, name=f"vd_trace.{c}", field=c, address=whole.address + i * whole.size, count=1)
            for i, c in enumerate(LOG_COLUMNS)
        )
        variables["vd_trace"] = dataclasses.replace(row, scalars=columns)
    return variables


@dataclasses.dataclass(frozen=True)
class Capture:
    """Samples of a DAQ capture: one array per signal, the DAQ timestamps [ticks] and the lost-sample count."""

    signals: dict[str, npt.NDArray[Any]]
    timestamps: npt.NDArray[np.int64]
    dtos_lost: int
    #: The drive's time of the trigger [ns] of a buffered capture (t = 0 there); None: a DAQ capture (t = 0 at its
    #: first sample).
    trigger_ns: int | None = None


class _Collect:
    """A pyxcp DAQ policy that keeps every sample of the one list (made on first use: pyxcp is optional)."""

    @staticmethod
    def make(daq_lists: list[Any]) -> Any:
        from pyxcp.daq_stim import DaqOnlinePolicy

        class Collect(DaqOnlinePolicy):
            def __init__(self) -> None:
                super().__init__(daq_lists)
                self.rows: list[tuple[int, dict[str, Any]]] = []
                self.lock = threading.Lock()

            def initialize(self) -> None:
                pass

            def finalize(self) -> None:
                pass

            def on_daq_list(self, daq_list: int, timestamp0: int, timestamp1: int, payload: list[Any]) -> None:
                # pyxcp lays the measurements out in its own order: its headers name the payload's
                names = [h[0] for h in self.daq_lists[daq_list].headers]
                with self.lock:
                    self.rows.append((timestamp1, dict(zip(names, payload))))

        return Collect()


class Link:
    """An XCP session with the firmware over ``url``, its variables read from ``elf``.

    Parameters
    ----------
    url : str
        ``socket://127.0.0.1:PORT`` or a serial device (``/dev/pts/N``, ``COM3``).
    elf : path
        The firmware's ELF (``virtual_drive.elf``, ``virtual_drive_host``, ``firmware.elf``).
        Or the build's A2L file (``virtual_drive_host.a2l``, ...): its memory segments, variables and limits.
    virtual : bool
        The firmware runs on the virtual board (its load schedule and trace row); read from an A2L file.
    timeout_s : float
        pyxcp's response timeout [s].
    allow_remote : bool
        Connect to a TCP host other than this machine (:func:`~pmsm2dof.drive.transport.link_url`).

    Notes
    -----
    The link reads and writes only inside the variables (:meth:`read_bytes`, :meth:`write_bytes`).
    """

    def __init__(
        self, url: str, elf: Path | str, *, virtual: bool = True, timeout_s: float = 2.0, allow_remote: bool = False
    ) -> None:
        self.url = link_url(url, allow_remote)
        self.timeout_s = timeout_s
        self.a2l: A2l | None = None
        if Path(elf).suffix.lower() == ".a2l":
            self.a2l = read_a2l(elf)
            self.variables = self.a2l.variables()
        else:
            self.variables = firmware_variables(elf, virtual)
        self.scalars: dict[str, Scalar] = {s.name: s for v in self.variables.values() for s in v.scalars}
        self._master: Any = None
        self.max_cto = 8

    # ---- session --------------------------------------------------------
    def __enter__(self) -> "Link":
        if self._master is None:
            self.open()
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    def open(self, policy: Any = None) -> None:
        """Connect (CONNECT) with a new master; ``policy``: a pyxcp DAQ policy."""
        self.close()
        self._master = pyxcp_master(self.url, self.timeout_s, policy)
        self._master.__enter__()
        self.max_cto = self._master.connect().maxCto

    def close(self) -> None:
        """Disconnect and close the transport."""
        if self._master is not None:
            try:
                self._master.disconnect()
            except Exception:
                pass
            self._master.__exit__(None, None, None)
            self._master = None

    @property
    def master(self) -> Any:
        """The pyxcp Master of the session (for what this class does not wrap)."""
        if self._master is None:
            raise ToolError("the XCP link is not open")
        return self._master

    # ---- memory ---------------------------------------------------------
    def scalar(self, name: str) -> Scalar:
        """The variable or field ``name`` (``link_speed_config.alpha_radps``), or ConfigError listing some."""
        if name not in self.scalars:
            raise ConfigError(
                "name", name, "a variable of the firmware: " + ", ".join(sorted(self.scalars)[:12]) + ", ..."
            )
        return self.scalars[name]

    def read(self, name: str) -> Any:
        """The value of a field (a number, or a tuple for an array), read with SHORT_UPLOAD/UPLOAD."""
        s = self.scalar(name)
        data = self.read_bytes(s.address, s.size * s.count)
        values = struct.unpack(f"<{s.count}{_FORMATS[(s.encoding, s.size)]}", data)
        return values[0] if s.count == 1 else values

    def _inside(self, address: int, n: int) -> None:
        """Raise ConfigError unless [address, address + n) lies inside one variable of the firmware."""
        for var in self.variables.values():
            if var.address <= address and address + n <= var.address + var.size:
                return
        raise ConfigError(
            "address", f"0x{address:X} + {n} bytes", "inside one of the variables: " + ", ".join(self.variables)
        )

    def read_bytes(self, address: int, n: int) -> bytes:
        """n bytes at an XCP address inside a variable (UPLOADs of at most 255 bytes, in the slave's block mode)."""
        self._inside(address, n)
        self.master.setMta(address)
        return b"".join(bytes(self.master.upload(min(255, n - i))) for i in range(0, n, 255))

    def write_bytes(self, address: int, data: bytes) -> None:
        """Write bytes inside a variable with SET_MTA and DOWNLOADs of at most MAX_CTO - 2 bytes (each one taken
        into force whole)."""
        self._inside(address, len(data))
        step = self.max_cto - 2
        self.master.setMta(address)
        for i in range(0, len(data), step):
            self.master.download(data[i : i + step])

    def write(self, values: Mapping[str, Any]) -> None:
        """Write fields; the fields of one variable in one DOWNLOAD when they fit, so that they take effect at once.

        An array takes a sequence of at most its length (the first elements). Raises pyxcp's
        XcpResponseError (ERR_OUT_OF_RANGE) when the drive rejects the new page.
        """
        by_variable: dict[str, list[Scalar]] = {}
        for name in values:
            s = self.scalar(name)
            by_variable.setdefault(name.split(".")[0], []).append(s)
        for var_name, scalars in by_variable.items():
            var = self.variables[var_name]
            start = min(s.address for s in scalars)
            end = max(s.address + s.size * s.count for s in scalars)
            page = bytearray(self.read_bytes(start, end - start))
            for s in scalars:
                value = values[s.name]
                items = list(value) if s.count > 1 else [value]
                if len(items) > s.count:
                    raise ConfigError(s.name, f"<{len(items)} values>", f"at most {s.count} values")
                fmt = f"<{len(items)}{_FORMATS[(s.encoding, s.size)]}"
                struct.pack_into(fmt, page, s.address - start, *items)
            del var
            self.write_bytes(start, bytes(page))

    # ---- run control ------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """link_status_now as a dict of its fields (``state`` as its name)."""
        var = self.variables["link_status_now"]
        data = self.read_bytes(var.address, var.size)
        out: dict[str, Any] = {}
        for s in var.scalars:
            out[s.field] = struct.unpack_from(f"<{_FORMATS[(s.encoding, s.size)]}", data, s.address - var.address)[0]
        out["state"] = STATES[out["state"]] if out["state"] < len(STATES) else out["state"]
        return out

    def set_schedules(
        self, reference: Sequence[tuple[float, float, float]], load: Sequence[tuple[float, float, float]] | None = None
    ) -> None:
        """Write the speed reference (t_s, w_radps, ramp_s) entries and the virtual board's load (t_s, Nm, ramp_s)."""
        for var, fields, entries in (
            ("link_reference", ("t_s", "w_radps", "ramp_s"), reference),
            ("vd_load", ("t_s", "torque_Nm", "ramp_s"), load),
        ):
            if entries is None:
                continue
            if len(entries) > SCHEDULE_MAX:
                raise ConfigError(var, f"<{len(entries)} entries>", f"at most {SCHEDULE_MAX} entries")
            for j, field in enumerate(fields):
                if entries:
                    self.write({f"{var}.{field}": [float(e[j]) for e in entries]})
            self.write({f"{var}.n": len(entries)})

    def start(self, samples: int) -> None:
        """Start a run of ``samples`` speed samples at the next speed sample (ERR_OUT_OF_RANGE: refused)."""
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples < 2**32:
            raise ConfigError("samples", samples, "an integer in [1, 2^32 - 1]")
        self.write({"link_command.command": 1, "link_command.samples": samples})

    def stop(self) -> None:
        """Stop the run (power stage off) at the next speed sample."""
        self.write({"link_command.command": 2})

    def wait(self, states: Sequence[str], timeout_s: float, poll_s: float = 0.02) -> dict[str, Any]:
        """Poll the status (which also keeps the link alive) until its state is one of ``states``."""
        end = time.monotonic() + timeout_s
        while True:
            st = self.status()
            if st["state"] in states:
                return st
            if time.monotonic() > end:
                raise ToolError(
                    f"the drive did not reach {'/'.join(states)} within {timeout_s:g} s (state {st['state']})"
                )
            time.sleep(poll_s)

    # ---- DAQ ---------------------------------------------------------------
    def _daq_list(self, names: Sequence[str], event: str, prescaler: int) -> Any:
        from pyxcp.daq_stim import DaqList

        measurements = []
        for name in names:
            s = self.scalar(name)
            if s.count != 1:
                raise ConfigError("signal", name, "a scalar (one element of an array has a name of its own)")
            measurements.append((name, s.address, 0, _DAQ_TYPES[_FORMATS[(s.encoding, s.size)]]))
        if event not in EVENTS:
            raise ConfigError("event", event, "speed or current")
        return DaqList(
            name="capture",
            event_num=EVENTS[event],
            stim=False,
            enable_timestamps=True,
            measurements=measurements,
            priority=0,
            prescaler=prescaler,
        )

    def capture(
        self,
        names: Sequence[str],
        *,
        event: str = "speed",
        prescaler: int = 1,
        until: Any = None,
        duration_s: float = 1.0,
        stall_s: float = 10.0,
    ) -> Capture:
        """Capture signals by DAQ at an event; ``until(link)`` (polled every 20 ms) or ``duration_s`` ends it.

        ``duration_s`` is of the drive's time, by the DAQ timestamps: the capture ends once its samples
        span it, however fast or slow the drive runs against the wall clock (QEMU's at a few percent
        of it while a list streams). The session is re-opened with the DAQ policy (a CONNECT: the
        drive takes it for a new master, whose commands do not feed the watchdog of a run started
        before; start a run from ``until``, as :meth:`play` does). The status is polled throughout,
        which keeps the link's watchdog fed. Raises ToolError when no sample arrives for ``stall_s``
        of the wall clock.
        """
        use_default_application()
        policy = _Collect.make([self._daq_list(names, event, prescaler)])
        self.open(policy)
        policy.setup()
        policy.start()
        span_ns = duration_s * 1e9
        heard = (time.monotonic(), 0)

        def covered() -> bool:
            nonlocal heard
            with policy.lock:
                n = len(policy.rows)
                span = policy.rows[-1][0] - policy.rows[0][0] if n else -1
            now = time.monotonic()
            if n != heard[1]:
                heard = (now, n)
            elif now - heard[0] > stall_s:
                raise ToolError(f"the drive sent no DAQ sample at the {event} event for {stall_s:g} s")
            return bool(span >= span_ns)

        try:
            while not (until(self) if until is not None else covered()):
                self.status()
                time.sleep(0.02)
        finally:
            policy.stop()
        lost = int(self.status()["dtos_lost"])
        with policy.lock:
            rows = list(policy.rows)
        self.open()
        return Capture(
            signals={n: np.array([r[1][n] for r in rows]) for n in names},
            timestamps=np.array([r[0] for r in rows], dtype=np.int64),
            dtos_lost=lost,
        )

    # ---- the capture buffer ------------------------------------------------
    def capture_buffered(
        self,
        names: Sequence[str],
        *,
        event: str = "current",
        samples: int,
        trigger: str = "immediate",
        level: float = 0.0,
        trigger_signal: str | None = None,
        pre_samples: int = 0,
        armed: Callable[["Link"], None] | None = None,
        during: Callable[["Link"], None] | None = None,
        timeout_s: float = 60.0,
    ) -> Capture:
        """Capture signals into the drive's buffer (examples/firmware/capture.h) and read them out by UPLOAD.

        ``samples`` records at the event, ``pre_samples`` of them before the trigger's: ``immediate``,
        ``rising``/``falling`` (``trigger_signal``, a float32 of ``names``, crossing ``level``) or ``run``
        (a run's first control interrupt). ``armed(link)`` is called once the drive holds the
        pre-trigger records (to start the run a ``run`` trigger waits for, say); ``during(link)`` at every
        poll after it (it may raise: a trigger that will not come, say). The status is polled
        until the capture is done (which keeps the watchdog fed). Timestamps: the drive's clock [ns].
        Raises ConfigError for a capture the buffer cannot hold, ToolError when it does not end in
        ``timeout_s``.
        """
        scalars = [self.scalar(n) for n in names]
        if not 1 <= len(scalars) <= CAPTURE_SIGNALS_MAX:
            raise ConfigError("signals", f"<{len(scalars)} signals>", f"1 to {CAPTURE_SIGNALS_MAX} signals")
        for s in scalars:
            if s.count != 1:
                raise ConfigError("signal", s.name, "a scalar")
        if event not in EVENTS or trigger not in TRIGGERS:
            raise ConfigError("event" if event not in EVENTS else "trigger", event if event not in EVENTS else trigger,
                              " or ".join(EVENTS if event not in EVENTS else TRIGGERS))  # fmt: skip
        index = 0
        if trigger in ("rising", "falling"):
            if trigger_signal is None or trigger_signal not in names:
                raise ConfigError("trigger_signal", trigger_signal, "a float32 signal among the captured ones")
            index = list(names).index(trigger_signal)
            if (scalars[index].encoding, scalars[index].size) != ("float", 4):
                raise ConfigError("trigger_signal", trigger_signal, "a float32 signal among the captured ones")
        record = sum(s.size for s in scalars)
        capacity = self.variables["capture_buffer"].size // record
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= capacity:
            raise ConfigError("samples", samples, f"an integer in [1, {capacity}] (the buffer's {record}-byte records)")
        if isinstance(pre_samples, bool) or not isinstance(pre_samples, int) or not 0 <= pre_samples < samples:
            raise ConfigError("pre_samples", pre_samples, f"an integer in [0, {samples - 1}]")
        arms = int(self.read("capture_status_now.arms"))
        # the page in parts as small as the link's packets (6 bytes on classic CAN), each taken on its own: the
        # command 0 (none) first, the fields, then the command 1 (arm) that the drive checks with the whole page
        self.write({"capture_config.command": 0})
        self.write({
            "capture_config.event": EVENTS[event], "capture_config.n": len(scalars),
            "capture_config.samples": samples, "capture_config.pre_samples": pre_samples,
            "capture_config.trigger": TRIGGERS[trigger], "capture_config.trigger_signal": index,
            "capture_config.level": level, "capture_config.address": [s.address for s in scalars],
            "capture_config.size": [s.size for s in scalars],
        })  # fmt: skip
        self.write({"capture_config.command": 1})
        end = time.monotonic() + timeout_s
        told = armed is None
        while True:
            st = self._capture_status()
            if st["arms"] == arms + 1 and st["state"] == 3:
                break
            if not told and st["arms"] == arms + 1 and st["written"] > pre_samples:
                assert armed is not None
                armed(self)
                told = True
            elif told and during is not None:
                during(self)
            if time.monotonic() > end:
                state = ("idle", "armed: no trigger came", "triggered", "done")[min(st["state"], 3)]
                raise ToolError(f"the drive's capture did not end within {timeout_s:g} s ({state})")
            time.sleep(0.01)
        var = self.variables["capture_buffer"]
        data = self.read_bytes(var.address, samples * record)
        first = st["first"]
        data = data[first * record :] + data[: first * record]
        fmt = "<" + "".join(_FORMATS[(s.encoding, s.size)] for s in scalars)
        rows = np.array(list(struct.iter_unpack(fmt, data)), dtype=object)
        stride = 1 if event == "current" else self._current_per_speed()
        Ts_ns = self._Ts_current_ns()
        periods = st["trigger_period"] + (np.arange(samples, dtype=np.int64) - pre_samples) * stride
        signals = {}
        for j, (n, s) in enumerate(zip(names, scalars)):
            dtype = np.float32 if (s.encoding, s.size) == ("float", 4) else None
            signals[n] = np.array(list(rows[:, j]), dtype=dtype)
        return Capture(signals, periods * Ts_ns, 0, trigger_ns=int(st["trigger_period"]) * Ts_ns)

    def _capture_status(self) -> dict[str, int]:
        var = self.variables["capture_status_now"]
        data = self.read_bytes(var.address, var.size)
        return {s.field: struct.unpack_from("<I", data, s.address - var.address)[0] for s in var.scalars}

    def _Ts_current_ns(self) -> int:
        """The control period [ns] of the drive: its A2L's current event."""
        if self.a2l is None:
            raise ToolError("the control period of the drive comes from its A2L file")
        return round(self.a2l.events["current"][1] * 1e9)

    def _current_per_speed(self) -> int:
        assert self.a2l is not None
        return round(self.a2l.events["speed"][1] / self.a2l.events["current"][1])

    def play(
        self,
        samples: int,
        reference: Sequence[tuple[float, float, float]],
        load: Sequence[tuple[float, float, float]] | None,
        columns: Sequence[str],
        *,
        timeout_s: float,
        during: Callable[["Link", dict[str, Any]], None] | None = None,
    ) -> dict[str, npt.NDArray[np.float64]]:
        """Run the drive through a schedule and return the virtual board's trace rows of every speed sample.

        Writes the schedules, starts DAQ at the speed event on ``vd_trace.<column>`` (the engine's log
        columns) with the run's sample counter, starts a run of ``samples`` samples, polls until it
        ends, and returns the rows 0 .. samples-1: the row of sample k is complete at sample k+1,
        where it is captured. ``during(link, status)`` is called at every poll of the running drive
        (a live calibration, say). Raises SimulationError when the run does not end as done, or a
        sample is missing.
        """
        self.set_schedules(reference, load)
        runs = int(self.read("link_status_now.runs"))
        names = ["link_status_now.runs", "link_status_now.sample", *(f"vd_trace.{c}" for c in columns)]
        state: dict[str, Any] = {}

        def ended(link: "Link") -> bool:
            if not state:
                link.start(samples)
                state["started"] = time.monotonic()
            st = link.status()
            state.update(st)
            if during is not None and st["state"] == "running":
                during(link, st)
            if time.monotonic() - state["started"] > timeout_s:
                raise ToolError(f"the run of {samples} samples did not end within {timeout_s:g} s")
            return bool(st["state"] != "running" and st["runs"] == runs + 1)

        cap = self.capture(names, until=ended)
        if state.get("state") != "done":
            raise SimulationError(f"the run over the link ended {state.get('state')}, not done (status {state})")
        if cap.dtos_lost:
            raise SimulationError(f"the DAQ lost {cap.dtos_lost} samples of the run")
        run = cap.signals["link_status_now.runs"] == runs + 1
        k = cap.signals["link_status_now.sample"][run]
        keep = (k >= 1) & (k <= samples)
        k, first = np.unique(k[keep], return_index=True)
        if len(k) != samples:
            raise SimulationError(f"the capture holds {len(k)} of the run's {samples} samples")
        return {c: cap.signals[f"vd_trace.{c}"][run][keep][first].astype(np.float64) for c in columns}
