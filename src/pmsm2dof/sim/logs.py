"""Measured drive logs: CSV, Parquet, NPZ, MAT or MDF4 files read into named arrays in SI units.

A log has one column per signal, found by its unit-suffixed name (the suffix gives the unit):

===========  =============================================  =======================
signal       accepted column names                          attribute of the Log
===========  =============================================  =======================
time         ``time_s``, ``t_s``, ``time_ms``, ``time_us``  ``t_s`` [s]
speed        ``speed_rpm``, ``speed_radps``                 ``speed_rpm``, ``w_m_radps``
speed_ref    ``speed_ref_rpm``, ``speed_ref_radps``         ``speed_ref_rpm``
id, iq       ``id_A``, ``iq_A`` (or ``_mA``)                ``id_A``, ``iq_A``
iq_ref       ``iq_ref_A`` (or ``_mA``)                      ``iq_ref_A``
torque       ``torque_Nm``                                  ``torque_Nm``
ud, uq       ``ud_V``, ``uq_V``                             ``ud_V``, ``uq_V``
u_dc         ``u_dc_V``                                     ``u_dc_V``
voltage      ``voltage_limited`` (no unit: a share [0, 1]   ``voltage_limited``
limited      of the row's periods whose voltage the
             inverter cut, or 0/1, as the engine logs it)
===========  =============================================  =======================

Time and speed are required, the others optional (absent: ``None``). Another column name is
mapped to a signal by ``columns={"speed": "enc_speed_rpm"}`` (``--column speed=enc_speed_rpm``);
its suffix must still name the unit. Currents and voltages are dq quantities in the
amplitude-invariant transform of the model (eq 1).

What real logs have is handled and reported in :attr:`Log.notes`: rows where a used signal is
NaN or empty are dropped; a time step longer than :data:`GAP_FACTOR` times the median step is a
gap, which splits the log into :meth:`Log.segments` (nothing is differenced or integrated across
it); a non-uniform sampling is kept as it is (the consumers use the time column) and its spread
reported; a speed quantized coarser than the step figures need (:func:`speed_resolution_rpm`, an
encoder's counts differenced over the sampling period) is reported with its resolution. Times must
increase.

A trace that pmsm2dof wrote with its scenario (``Result.save`` to NPZ or MAT: ``scenario_toml``)
gives the period of its drive's current loop, :attr:`Log.current_period_s`: the period over which
its voltage holds, which :mod:`pmsm2dof.studies.electrical` compares with the rows' spacing.
"""

import dataclasses
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, format_bytes
from ..inputs import check_file, parse_toml
from .event_figures import STEADY_SPREAD
from .scenario import Scenario
from .simulate import RPM_PER_RADPS

#: A time step longer than this many median steps is a gap in the log.
GAP_FACTOR = 3.0

#: Fewest row-to-row changes of the speed that show it quantized.
QUANTIZED_CHANGES_MIN = 20

#: Signals of a log: name -> ({unit suffix: factor to SI}, required).
SIGNALS: dict[str, tuple[dict[str, float], bool]] = {
    "time": ({"s": 1.0, "ms": 1e-3, "us": 1e-6}, True),
    "speed": ({"rpm": 1.0 / RPM_PER_RADPS, "radps": 1.0}, True),
    "speed_ref": ({"rpm": 1.0 / RPM_PER_RADPS, "radps": 1.0}, False),
    "id": ({"A": 1.0, "mA": 1e-3}, False),
    "iq": ({"A": 1.0, "mA": 1e-3}, False),
    "iq_ref": ({"A": 1.0, "mA": 1e-3}, False),
    "torque": ({"Nm": 1.0}, False),
    "ud": ({"V": 1.0}, False),
    "uq": ({"V": 1.0}, False),
    "u_dc": ({"V": 1.0}, False),
    "voltage_limited": ({"": 1.0}, False),
}

#: Default column base names of the signals (the unit suffix follows): time is also ``t``.
_BASES = {"time": ("time", "t")}

#: Most rows of a log (memory bound: 14 float64 arrays).
ROWS_MAX = 50_000_000
#: Largest log file, and largest content of a compressed one (NPZ, MAT, Parquet) [bytes]: what
#: the readers hold in memory while they parse it.
LOG_BYTES_MAX = 2 * 1024**3

FORMATS = (".csv", ".parquet", ".npz", ".mat", ".mf4")


@dataclasses.dataclass(frozen=True, eq=False)
class Log:
    """A measured run: arrays of equal length in SI units, speeds also in rpm.

    Attributes
    ----------
    source : str
        The file it was read from.
    t_s : time [s], increasing
    w_m_radps, speed_rpm : mechanical speed [rad/s], [rpm]
    speed_ref_rpm, id_A, iq_A, iq_ref_A, torque_Nm, ud_V, uq_V, u_dc_V : the optional signals, or None
    columns : dict
        Signal -> the file's column it was read from.
    rows_dropped : int
        Rows dropped for a NaN or empty value of a used signal.
    gaps : tuple
        ``(t_before_s, t_after_s)`` of each gap.
    notes : tuple of str
        What was found and done, one line each.
    voltage_limited : ndarray or None
        Share of the row's periods whose voltage the inverter cut to its range [-] (0 or 1 in a
        log that flags each period), or None.
    current_period_s : float or None
        The current loop's period of the drive that logged it [s] (``current_loop.Ts_s`` of a
        pmsm2dof trace's scenario), or None when the file does not say.
    """

    source: str
    t_s: np.ndarray
    w_m_radps: np.ndarray
    speed_rpm: np.ndarray
    speed_ref_rpm: np.ndarray | None
    id_A: np.ndarray | None
    iq_A: np.ndarray | None
    iq_ref_A: np.ndarray | None
    torque_Nm: np.ndarray | None
    ud_V: np.ndarray | None
    uq_V: np.ndarray | None
    u_dc_V: np.ndarray | None
    columns: dict[str, str]
    rows_dropped: int
    gaps: tuple[tuple[float, float], ...]
    notes: tuple[str, ...]
    voltage_limited: np.ndarray | None = None
    current_period_s: float | None = None

    @property
    def dt_s(self) -> float:
        """The median sampling step [s]."""
        return float(np.median(np.diff(self.t_s)))

    def segments(self) -> list[slice]:
        """The row ranges between gaps, in order (one slice when the log has no gap)."""
        steps = np.diff(self.t_s)
        cuts = np.flatnonzero(steps > GAP_FACTOR * np.median(steps)) + 1
        bounds = [0, *cuts.tolist(), len(self.t_s)]
        return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    def __repr__(self) -> str:
        return f"Log({self.source!r}, {len(self.t_s)} rows, t = {self.t_s[0]:g}..{self.t_s[-1]:g} s)"


def _read_table(path: Path) -> dict[str, np.ndarray]:
    """The columns of a file as 1-d arrays, by name."""
    suffix = path.suffix.lower()
    try:
        content = _content_bytes(path, suffix)
        if content > LOG_BYTES_MAX:
            raise ConfigError(
                "log", str(path), f"a log of at most {format_bytes(LOG_BYTES_MAX)} (it holds {format_bytes(content)})"
            )
        if suffix in (".csv", ".parquet"):
            import pandas as pd

            frame = pd.read_csv(path) if suffix == ".csv" else pd.read_parquet(path)
            return {str(name): frame[name].to_numpy() for name in frame.columns}
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as npz:
                return {name: npz[name] for name in npz.files}
        if suffix == ".mat":
            import scipy.io

            mat = scipy.io.loadmat(path, squeeze_me=True)
            return {name: value for name, value in mat.items() if not name.startswith("__")}
        if suffix == ".mf4":
            return _read_mdf(path)
    except ConfigError:
        raise
    except (OSError, ValueError, UnicodeDecodeError, ImportError) as exc:
        raise ConfigError("log", str(path), f"a readable {suffix[1:].upper()} log ({exc})") from None
    except Exception as exc:  # the readers' own parse errors (pandas, pyarrow, zipfile, scipy.io)
        raise ConfigError(
            "log", str(path), f"a readable {suffix[1:].upper()} log ({type(exc).__name__}: {exc})"
        ) from None
    raise ConfigError("log", str(path), "a file ending in " + ", ".join(FORMATS))


def _read_mdf(path: Path) -> dict[str, np.ndarray]:
    """The channels of an MDF4 file (ASAM MDF 4, as CANape, INCA and ``pmsm2dof drive capture`` write it) by
    name, read with asammdf; the master channel (time [s]) as ``t_s``. The channels must share one time base
    (one channel group, or groups sampled together): a log is one table."""
    from asammdf import MDF

    table: dict[str, np.ndarray] = {}
    with MDF(path) as mdf:
        for index, group in enumerate(mdf.groups):
            channels: list[Any] = group.channels  # type: ignore[attr-defined]
            master = np.asarray(mdf.get_master(index), dtype=float)
            if "t_s" in table and not np.array_equal(table["t_s"], master):
                raise ConfigError("log", str(path), "an MDF4 log whose channel groups share one time base")
            table["t_s"] = master
            master_index = mdf.masters_db.get(index)
            for i, channel in enumerate(channels):
                if i != master_index:
                    table[channel.name] = np.asarray(mdf.get(channel.name, group=index, index=i).samples)
    return table


def _content_bytes(path: Path, suffix: str) -> int:
    """The bytes of the arrays in a log file, read from its headers before the arrays (a compressed
    file may hold far more than its size)."""
    if suffix == ".npz":
        import zipfile

        with zipfile.ZipFile(path) as z:
            return sum(info.file_size for info in z.infolist())
    if suffix == ".mat":
        import scipy.io

        return sum(8 * math.prod(shape) for _name, shape, _kind in scipy.io.whosmat(path))
    if suffix == ".parquet":
        import pyarrow.parquet as pq

        meta = pq.ParquetFile(path).metadata
        return 8 * int(meta.num_rows) * int(meta.num_columns)
    if suffix == ".mf4":
        from asammdf import MDF

        with MDF(path) as mdf:
            return sum(8 * int(g.channel_group.cycles_nr) * len(g.channels) for g in mdf.groups)
    return path.stat().st_size


def _unit_factor(signal: str, column: str) -> float:
    units, _ = SIGNALS[signal]
    for unit, factor in units.items():
        if not unit or column.endswith("_" + unit):
            return factor
    raise ConfigError(
        f"column {signal}",
        column,
        "a column name ending in the unit: " + ", ".join("_" + u for u in units),
    )


def _find_columns(names: list[str], columns: Mapping[str, str]) -> dict[str, str]:
    for signal in columns:
        if signal not in SIGNALS:
            raise ConfigError("column", signal, "a signal of the log: " + ", ".join(SIGNALS))
    found: dict[str, str] = {}
    for signal, (units, required) in SIGNALS.items():
        if signal in columns:
            if columns[signal] not in names:
                raise ConfigError(f"column {signal}", columns[signal], "a column of the log: " + ", ".join(names))
            found[signal] = columns[signal]
            continue
        candidates = [f"{base}_{unit}".rstrip("_") for base in _BASES.get(signal, (signal,)) for unit in units]
        hits = [c for c in candidates if c in names]
        if len(hits) > 1:
            raise ConfigError(f"column {signal}", hits, f"one column for {signal} (map one with --column)")
        if hits:
            found[signal] = hits[0]
        elif required:
            raise ConfigError(
                f"column {signal}",
                "<missing>",
                f"one of the columns {', '.join(candidates)} (or map another: --column {signal}=NAME); "
                f"the log has {', '.join(names)}",
            )
    return found


def speed_resolution_rpm(speed_rpm: np.ndarray) -> float | None:
    """The step of a quantized speed [rpm], or None when the speed is not quantized.

    A speed from encoder counts differenced over the sampling period ``dt`` takes the values
    ``k 60 / (counts dt)``: its changes from row to row are whole multiples of that step. The step
    is the smallest change; the speed is quantized when at least :data:`QUANTIZED_CHANGES_MIN`
    changes are all within 1e-3 of whole multiples of it.
    """
    change = np.abs(np.diff(speed_rpm))
    moving = change[change > 1e-9 * float(np.max(np.abs(speed_rpm), initial=0.0))]
    if moving.size < QUANTIZED_CHANGES_MIN:
        return None
    step = float(np.min(moving))
    multiple = moving / step
    if np.max(np.abs(multiple - np.round(multiple))) > 1e-3:
        return None
    return step


def read_log(path: str | os.PathLike[str], columns: Mapping[str, str] | None = None) -> Log:
    """Read a drive log (CSV, Parquet, NPZ, MAT or MDF4 ``.mf4`` with asammdf, the ``drive`` extra) into a Log.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension gives the format.
    columns : mapping, optional
        Signal -> column name, for columns not named as the module docstring says
        (``{"speed": "enc_speed_rpm"}``).

    Returns
    -------
    Log

    Raises
    ------
    ConfigError
        An unreadable file, a missing or ambiguous column, a column without its unit, non-numeric
        values, times that do not increase, or fewer than 3 usable rows.
    """
    file = Path(os.fspath(path))
    if file.suffix.lower() not in FORMATS:
        raise ConfigError("log", str(file), "an existing file ending in " + ", ".join(FORMATS))
    check_file(file, "log", LOG_BYTES_MAX)
    table = _read_table(file)
    found = _find_columns(list(table), columns or {})
    raw: dict[str, np.ndarray] = {}
    n = None
    for signal, name in found.items():
        try:
            values = np.asarray(table[name], dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ConfigError(
                f"column {name}", "non-numeric values", "numbers (NaN or empty for a missing value)"
            ) from None
        if n is not None and values.size != n:
            raise ConfigError(f"column {name}", f"{values.size} rows", f"{n} rows, as the other columns")
        n = values.size
        raw[signal] = values * _unit_factor(signal, name)
    assert n is not None
    if n > ROWS_MAX:
        raise ConfigError("log", f"{n} rows", f"at most {ROWS_MAX} rows")
    notes = []
    finite = np.all([np.isfinite(v) for v in raw.values()], axis=0)
    dropped = int(n - np.count_nonzero(finite))
    if dropped:
        notes.append(f"{dropped} rows with a missing or non-finite value dropped")
        raw = {k: v[finite] for k, v in raw.items()}
    t = raw["time"]
    if t.size < 3:
        raise ConfigError("log", str(file), f"at least 3 rows with every used signal finite (it has {t.size})")
    steps = np.diff(t)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise ConfigError(f"{found['time']} at row {i}", float(t[i]), f"> the time of the row before ({t[i - 1]!r})")
    dt = float(np.median(steps))
    gap_at = np.flatnonzero(steps > GAP_FACTOR * dt)
    gaps = tuple((float(t[i]), float(t[i + 1])) for i in gap_at)
    if gaps:
        longest = max(b - a for a, b in gaps)
        notes.append(f"{len(gaps)} gaps longer than {GAP_FACTOR:g} steps (longest {longest:.4g} s): log split there")
    inside = np.delete(steps, gap_at)
    spread = float(np.max(np.abs(inside - dt)) / dt) if inside.size else 0.0
    if spread > 0.01:
        notes.append(f"non-uniform sampling: steps {inside.min():.4g} to {inside.max():.4g} s (median {dt:.4g} s)")
    w = raw["speed"]
    ref = raw.get("speed_ref")
    step_rpm = speed_resolution_rpm(w * RPM_PER_RADPS)
    if step_rpm is not None and step_rpm > STEADY_SPREAD * float(np.max(np.abs(w))) * RPM_PER_RADPS:
        counts = 60.0 / (step_rpm * dt)
        share = 100 * step_rpm / (float(np.max(np.abs(w))) * RPM_PER_RADPS)
        notes.append(
            f"the speed moves in steps of {step_rpm:.4g} rpm, {share:.2g} % of its largest value: an encoder of "
            f"about {counts:.4g} counts per revolution read over the {dt:.4g} s sampling period (60 / (counts dt)); "
            f"figures finer than that (steady-state errors, which need a spread below {100 * STEADY_SPREAD:g} % "
            "of the step, small dips) are not resolved and read n/a: log a filtered speed estimate, or count over "
            "a longer period"
        )
    return Log(
        source=str(file),
        t_s=t,
        w_m_radps=w,
        speed_rpm=w * RPM_PER_RADPS,
        speed_ref_rpm=None if ref is None else ref * RPM_PER_RADPS,
        id_A=raw.get("id"),
        iq_A=raw.get("iq"),
        iq_ref_A=raw.get("iq_ref"),
        torque_Nm=raw.get("torque"),
        ud_V=raw.get("ud"),
        uq_V=raw.get("uq"),
        u_dc_V=raw.get("u_dc"),
        columns=found,
        rows_dropped=dropped,
        gaps=gaps,
        notes=tuple(notes),
        voltage_limited=raw.get("voltage_limited"),
        current_period_s=_current_period_s(table, file),
    )


def _current_period_s(table: Mapping[str, np.ndarray], file: Path) -> float | None:
    """``current_loop.Ts_s`` of the scenario a pmsm2dof trace carries (``scenario_toml``), or None."""
    if "scenario_toml" not in table:
        return None
    text = str(np.asarray(table["scenario_toml"]).reshape(-1)[0])
    try:
        return float(Scenario.from_dict(parse_toml(text, "log", str(file))).current_loop.Ts_s)
    except ConfigError:
        return None
