"""Running a sweep: its points on the engine, a results table, an output folder that resumes.

The points of a :class:`~pmsm2dof.studies.sweep.Sweep` run on the engine of
:mod:`pmsm2dof.studies.engine`; each finished batch is stored in ``out/parts``, so that an
interrupted sweep computes only its missing points when run again. The rows of the results are
those of :mod:`pmsm2dof.studies.sweep` (:func:`~pmsm2dof.studies.sweep.metric_columns`).
"""

import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from ..errors import ConfigError
from .engine import Outcome, PartStore, Run, check_options, connect, run_many
from .sweep import Sweep, describe_point, flatten_metrics, metric_columns

if TYPE_CHECKING:
    import pandas as pd


def _row(sweep: Sweep, point: int, outcome: Outcome) -> dict[str, Any]:
    """The results row of one point: ``point``, the axis values, ``status`` (``"ok"`` or
    ``"error"``), ``error`` (the SimulationError message or ""), ``wall_time_s`` of the
    simulation, every metric column and ``notes`` (why a metric is missing). A run that diverges
    is a row with status ``"error"`` and no metrics, never NaN."""
    row = {"point": point, **sweep.points[point]}
    if outcome.metrics is None:
        row.update(status="error", error=outcome.error, wall_time_s=None)
        row.update(dict.fromkeys(metric_columns(sweep.base)))
        row["notes"] = ""
    else:
        figures, notes = flatten_metrics(outcome.metrics)
        row.update(status="ok", error="", wall_time_s=outcome.wall_time_s, **figures, notes=notes)
    return row


def _frame(rows: list[dict[str, Any]], sweep: Sweep) -> "pd.DataFrame":
    """Rows as a DataFrame with fixed column order and nullable float metrics."""
    import pandas as pd

    columns = ["point", *sweep.keys, "status", "error", "wall_time_s", *metric_columns(sweep.base), "notes"]
    frame = pd.DataFrame(rows, columns=columns)
    for col in ["wall_time_s", *metric_columns(sweep.base)]:
        frame[col] = frame[col].astype("Float64")
    return frame


MANIFEST = "sweep.json"
PARTS = "parts"
#: What a sweep keeps in its folder between runs, besides the outputs of its manifest.
OWN = (MANIFEST, "base.toml", *(f"{PARTS}/{p}" for p in PartStore.PATTERNS))
#: Largest sweep.json read [bytes] (it holds a name, a digest, a count and the keys).
MANIFEST_BYTES_MAX = 1024**2


def _prepare_out(out: Path, sweep: Sweep, force: bool) -> None:
    """Create ``out`` with the sweep's manifest, or check that it holds the same sweep.

    With ``force``, a folder of another sweep, or of a sweep whose manifest is damaged, is
    cleared of what the sweep wrote there (other files stay) and the sweep starts afresh.
    """
    from ..outputs import atomic_write, check_out, remove_outputs

    check_out(out, "sweep", force, own=OWN)
    digest = sweep.digest()
    if (out / MANIFEST).exists() or (out / PARTS).exists():
        problem = _manifest_problem(out, digest)
        if problem is None:
            return
        if not force:
            raise ConfigError(
                "out",
                str(out),
                f"a new folder, or the folder of an earlier run of this same sweep ({problem}); force=True "
                "starts this sweep there afresh",
            )
        remove_outputs(out, "sweep", own=OWN)
    try:
        (out / PARTS).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("out", str(out), f"a writable folder ({exc.strerror})") from None
    atomic_write(out / "base.toml", sweep.base.to_toml())
    content = {"name": sweep.name, "digest": digest, "points": len(sweep.points), "keys": list(sweep.keys)}
    atomic_write(out / MANIFEST, json.dumps({**content, "checksum": _checksum(content)}, indent=2) + "\n")


def _checksum(content: Mapping[str, Any]) -> str:
    """SHA-256 of the manifest's content (its JSON with sorted keys)."""
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


def _manifest_problem(out: Path, digest: str) -> str | None:
    """What keeps the sweep folder ``out`` from resuming the sweep of ``digest``; None if nothing."""
    from ..inputs import parse_json, read_bytes

    where = f"{MANIFEST} of {out}"
    if not (out / MANIFEST).exists():
        return f"it has {PARTS}/ but no {MANIFEST}, which says which sweep they belong to"
    try:
        data = parse_json(read_bytes(out / MANIFEST, MANIFEST, MANIFEST_BYTES_MAX), MANIFEST, str(out / MANIFEST))
    except ConfigError as exc:
        return f"its {MANIFEST} is damaged: {exc.valid}"
    if not isinstance(data, dict) or "checksum" not in data:
        return f"its {MANIFEST} is damaged: not a JSON object with a checksum"
    content = {k: v for k, v in data.items() if k != "checksum"}
    if data["checksum"] != _checksum(content):
        return f"its {MANIFEST} is damaged: its content does not match its checksum"
    if content.get("digest") != digest:
        return f"{where} is that of a different sweep ({content.get('name')!r})"
    return None


def _parts(out: Path, sweep: Sweep) -> PartStore:
    """The store of the finished points' rows of ``sweep`` in ``out/parts``."""
    return PartStore(out / PARTS, lambda rows: _frame(rows, sweep), "point", len(sweep.points))


def _save_part(out: Path, sweep: Sweep, rows: list[dict[str, Any]]) -> None:
    """Store the rows of one finished batch of points (``parts/part-<first point>.parquet``)."""
    _parts(out, sweep).save(rows)


@dataclass(frozen=True)
class SweepRun:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per point (see :func:`run_sweep`), sorted by point.
    out : Path
        The output folder.
    resumed : int
        Points found finished in ``out`` and not run again.
    computed : int
        Points simulated by this call.
    files : tuple of Path
        The results and figures written.
    """

    table: "pd.DataFrame"
    out: Path
    resumed: int
    computed: int
    files: tuple[Path, ...]


#: Draws the figures of a finished sweep: ``figures(sweep, table, folder)`` returns their paths.
FigureWriter = Callable[[Sweep, "pd.DataFrame", Path], Sequence[Path]]


def run_sweep(
    sweep: Sweep,
    out: Path | str,
    workers: int | None = None,
    scheduler: str | None = None,
    batch_size: int | None = None,
    progress: bool = True,
    figures: FigureWriter | None = None,
    force: bool = False,
) -> SweepRun:
    """Run every point of ``sweep`` not yet finished in ``out``, then write results and figures.

    The points run on the engine of :mod:`pmsm2dof.studies.engine`. Each finished batch of
    points is stored at once as ``out/parts/part-*.parquet``, so an interrupted sweep keeps its
    finished points and a second call with the same ``out`` computes only the missing ones; a
    stored part that cannot be used (its content no longer matches the checksum written with it,
    :class:`~pmsm2dof.studies.engine.PartStore`) is deleted and its points computed again, with a
    :class:`~pmsm2dof.studies.engine.PartWarning` naming it. When all points are done, ``out``
    receives ``results.parquet`` and ``results.csv`` (one row per point, see
    :func:`~pmsm2dof.studies.sweep.metric_columns`), ``base.toml`` (the frozen base scenario), ``sweep.json`` and, with
    ``figures``, the figures under ``figures/``, each written whole or not at all.

    Parameters
    ----------
    sweep : Sweep
    out : str or Path
        Output folder: new, empty, or holding an earlier run of the same sweep (checked by the
        ``sweep.json`` it wrote there, whose checksum tells a damaged one).
    workers : int, optional
        Local threads (default: the cores available). The compiled engine releases the GIL for
        the whole simulation, so threads run on all cores. Not used with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask distributed scheduler (``tcp://host:port``): the batches run
        on its workers, which must have pmsm2dof installed.
    batch_size : int, optional
        Points per task (default: the remaining points spread over about 4 tasks per worker,
        at most 50 points per task).
    progress : bool
        Show a progress bar on stderr.
    figures : callable, optional
        ``figures(sweep, table, folder)`` draws the figures into ``folder`` and returns their
        paths (:func:`pmsm2dof.ui.plots.sweep.draw_figures`, as ``pmsm2dof sweep`` does); None
        writes the results table only.
    force : bool
        Use ``out`` even if it holds other files (they are kept), or the folder of another sweep
        or one whose ``sweep.json`` is damaged (what that sweep wrote is removed first).

    Returns
    -------
    SweepRun

    Raises
    ------
    ConfigError
        ``out``, ``workers``, ``scheduler`` or ``batch_size`` invalid (naming the parameter), or a
        point's value that only the C controllers or the engine reject (naming the point).
    """
    out = Path(out)
    check_options(workers, scheduler, batch_size)
    with connect(scheduler) as client:
        _prepare_out(out, sweep, force)
        parts = _parts(out, sweep)
        finished = parts.read()
        done = set() if finished is None else set(int(i) for i in finished["point"])
        todo = [
            Run(i, "base", sweep.points[i], f"point {i} ({describe_point(sweep.points[i])})")
            for i in range(len(sweep.points))
            if i not in done
        ]
        run_many(
            {"base": sweep.base},
            todo,
            workers=workers,
            client=client,
            batch_size=batch_size,
            progress=progress,
            description=sweep.name,
            # the runs are keyed by point index
            on_batch=lambda outcomes: _save_part(out, sweep, [_row(sweep, cast(int, o.key), o) for o in outcomes]),
        )
    table = parts.read().drop_duplicates("point").sort_values("point", ignore_index=True)
    if len(table) != len(sweep.points):
        raise RuntimeError(f"{len(sweep.points) - len(table)} points of the sweep have no stored result")
    files = _write_results(out, sweep, table, figures, force)
    return SweepRun(table, out, len(done), len(todo), files)


def _write_results(
    out: Path, sweep: Sweep, table: "pd.DataFrame", figures: FigureWriter | None, force: bool
) -> tuple[Path, ...]:
    """results.parquet, results.csv and the figures, moved into ``out`` together when all are written
    (those of an earlier run that this one does not write again are removed)."""
    from ..outputs import staged_dir

    drawn: Sequence[Path] = []
    with staged_dir(out, "sweep", force, own=OWN) as tmp:
        table.to_parquet(tmp / "results.parquet", index=False)
        table.to_csv(tmp / "results.csv", index=False)
        if figures:
            drawn = figures(sweep, table, tmp / "figures")
    names = ["results.parquet", "results.csv", *(f"figures/{p.name}" for p in drawn)]
    return tuple(out / n for n in names)
