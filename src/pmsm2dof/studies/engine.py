"""The one engine for many simulations: batches on local threads or a Dask cluster, progress, parts.

A study is a list of :class:`Run`: a base scenario, named in a mapping of bases, changed by
overrides. :func:`run_many` simulates them and measures each one
(:func:`pmsm2dof.studies.loopcheck.measure`: the figures of
:func:`pmsm2dof.sim.metrics.compute_metrics` and the sampled-loop stability check; or the
study's own measure, which computes only the figures it reads), in batches:

- on local threads (:func:`default_workers` by default): the compiled engine releases the GIL
  for the whole simulation, so the threads run on all cores;
- or on the workers of a running Dask distributed scheduler (:func:`connect`), which need
  pmsm2dof installed: the batches travel pickled (their base scenarios and overrides).

Every run is one :class:`Outcome` (its metrics, or the message of the SimulationError that
stopped it; its :class:`~pmsm2dof.sim.simulate.Result` when asked to keep it), returned in the
order of the runs, whatever the order in which the batches finish. A caller that stores what
finished (a sweep's parts) does so in ``on_batch``, called in the calling thread as each batch
finishes, also for those that finished before an error or an interrupt, which is then raised.

:class:`PartStore` keeps the rows of finished batches as Parquet files, so that an interrupted
study resumes where it stopped (the sweeps of :mod:`pmsm2dof.studies.sweep`).
"""

import contextlib
import dataclasses
import hashlib
import io
import math
import os
import re
import warnings
from collections.abc import Callable, Hashable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigError, Pmsm2dofWarning, SimulationError, is_integer
from ..inputs import read_bytes
from ..outputs import atomic_write
from ..sim.scenario import Scenario
from ..sim.simulate import Result, Simulation, simulate_many
from . import loopcheck

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

#: What a study computes from each run that completed: :attr:`Outcome.metrics`.
Measure = Callable[[Result], dict[str, Any]]

#: Most runs per batch when the batch size is automatic.
BATCH_SIZE_MAX = 50
#: Batches per worker when the batch size is automatic (so that the last ones balance the load).
BATCHES_PER_WORKER = 4
#: Runs a worker simulates in one simulate_many call (a few lockstep groups: few traces in memory at a time).
SIMULATE_MANY_RUNS = 8


@dataclasses.dataclass(frozen=True)
class Run:
    """One simulation of a study: the base scenario ``base`` changed by ``overrides``.

    Attributes
    ----------
    key : hashable
        What the run is called: a name (the paper's runs) or an index (a sweep's points).
    base : str
        The key of its base scenario in the ``bases`` of :func:`run_many`.
    overrides : dict
        ``{dotted key: value}`` (:meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`).
    label : str
        Names the run in a ConfigError that only the C controllers or the engine raise (a value
        beyond float32): ``"<label>: <key>"``; empty, the key alone.
    """

    key: Hashable
    base: str
    overrides: dict[str, Any]
    label: str = ""


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What one run gave.

    Attributes
    ----------
    key : hashable
        The :attr:`Run.key`.
    metrics : dict or None
        The measure of the run (:func:`~pmsm2dof.studies.loopcheck.measure` unless the study gave its own);
        None when it stopped.
    error : str
        The message of the SimulationError that stopped the run; empty when it completed.
    wall_time_s : float or None
        Wall-clock time of the simulation [s]; None when it stopped.
    result : Result or None
        The trace, for the runs asked to be kept; None otherwise.
    """

    key: Hashable
    metrics: dict[str, Any] | None
    error: str
    wall_time_s: float | None
    result: Result | None = None


def default_workers() -> int:
    """The number of cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def simulate_batch(
    bases: Mapping[str, Scenario],
    runs: Sequence[Run],
    keep: frozenset[Hashable] = frozenset(),
    measure: Measure = loopcheck.measure,
) -> list[Outcome]:
    """Simulate and measure ``runs`` (in a worker thread or on a Dask worker), the engine's lockstep
    groups (:func:`~pmsm2dof.sim.simulate.simulate_many`) a few runs at a time.

    Parameters
    ----------
    bases : mapping
        Base name -> its scenario (pickled to a Dask worker).
    runs : sequence of Run
    keep : frozenset
        Keys of the runs whose Result is kept in their Outcome.
    measure : callable
        ``measure(result)``: the :attr:`Outcome.metrics` of a run that completed (a module-level
        function, pickled to a Dask worker by its name).

    Raises
    ------
    ConfigError
        A value that only the C controllers or the engine check, naming the run
        (:attr:`Run.label`) and the scenario key.
    """
    outcomes = []
    # lockstep groups of the engine (simulate_many), measured as they finish: a few traces in memory at a time
    for start in range(0, len(runs), SIMULATE_MANY_RUNS):
        chunk = runs[start : start + SIMULATE_MANY_RUNS]
        scenarios = []
        for run in chunk:
            with _named(run):
                scenarios.append(bases[run.base].with_overrides(run.overrides))
        try:
            results = simulate_many(scenarios)
        except ConfigError:
            # a value that only the C controllers or the engine check: the run whose engine rejects it names it
            for run, scenario in zip(chunk, scenarios):
                with _named(run):
                    Simulation(scenario)
            raise
        for run, result in zip(chunk, results):
            if isinstance(result, SimulationError):
                outcomes.append(Outcome(run.key, None, str(result), None))
            else:
                kept = result if run.key in keep else None
                outcomes.append(Outcome(run.key, measure(result), "", result.wall_time_s, kept))
    return outcomes


@contextlib.contextmanager
def _named(run: Run) -> Iterator[None]:
    """A ConfigError raised inside names the run (:attr:`Run.label`)."""
    try:
        yield
    except ConfigError as exc:
        if not run.label:
            raise
        raise ConfigError(f"{run.label}: {exc.param}", exc.value, exc.valid) from None


def check_options(workers: int | None = None, scheduler: str | None = None, batch_size: int | None = None) -> None:
    """Raise ConfigError, naming the parameter, for options :func:`run_many` cannot use.

    ``workers``: local threads, an integer >= 1, absent with a ``scheduler``; ``scheduler``: the
    address of a Dask scheduler (``tcp://host:port``); ``batch_size``: an integer >= 1.
    """
    if scheduler is not None and workers is not None:
        raise ConfigError("workers", workers, "absent when a scheduler is given (the cluster's workers run the runs)")
    if scheduler is not None and (not isinstance(scheduler, str) or "://" not in scheduler):
        raise ConfigError("scheduler", scheduler, "the address of a Dask scheduler, e.g. tcp://10.0.0.5:8786")
    if workers is not None and (not is_integer(workers) or workers < 1):
        raise ConfigError("workers", workers, "an integer >= 1")
    if batch_size is not None and (not is_integer(batch_size) or batch_size < 1):
        raise ConfigError("batch_size", batch_size, "an integer >= 1")


@contextlib.contextmanager
def local_threads(workers: int | None = None) -> Iterator["ThreadPoolExecutor"]:
    """``workers`` local threads (default :func:`default_workers`) for :func:`run_many`, shut down on exit."""
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(max_workers=workers or default_workers(), thread_name_prefix="pmsm2dof-study")
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def connect(scheduler: str | None) -> Iterator[Any]:
    """A Dask distributed client of the scheduler at ``scheduler``, closed on exit; None for None.

    Raises
    ------
    ConfigError
        Naming ``scheduler`` when no scheduler answers there.
    """
    if scheduler is None:
        yield None
        return
    from dask.distributed import Client

    try:
        client = Client(scheduler, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(
            "scheduler", scheduler, f"the address of a running Dask scheduler ({one_line(exc)})"
        ) from None
    with client:
        yield client


def run_many(
    bases: Mapping[str, Scenario],
    runs: Sequence[Run],
    *,
    keep: Iterable[Hashable] = (),
    measure: Measure = loopcheck.measure,
    workers: int | None = None,
    pool: "ThreadPoolExecutor | None" = None,
    client: Any = None,
    batch_size: int | None = None,
    progress: bool = False,
    description: str = "runs",
    on_batch: Callable[[list[Outcome]], None] | None = None,
) -> list[Outcome]:
    """Simulate and measure every run, in batches, on local threads or a Dask cluster.

    Parameters
    ----------
    bases : mapping
        Base name -> its scenario.
    runs : sequence of Run
        Their overrides are validated by the caller (a ConfigError raised here stops the study).
    keep : iterable
        Keys of the runs whose Result is kept (local threads: no copy is made).
    measure : callable
        ``measure(result)``, the :attr:`Outcome.metrics` of each run that completed; default
        :func:`~pmsm2dof.studies.loopcheck.measure`. A module-level function (a Dask worker runs it).
    workers : int, optional
        Local threads, >= 1 (default: :func:`default_workers`). Not used with ``client``.
    pool : ThreadPoolExecutor, optional
        The local threads of :func:`local_threads` (``workers`` of them), kept from one call to the
        next by a study that calls this many times; default: new threads for this call.
    client : dask.distributed.Client, optional
        A client of a running Dask scheduler (:func:`connect`): the batches run on its workers,
        which need pmsm2dof installed.
    batch_size : int, optional
        Runs per batch, >= 1 (default: the runs spread over :data:`BATCHES_PER_WORKER` batches
        per worker, at most :data:`BATCH_SIZE_MAX` runs per batch).
    progress : bool
        Show a progress bar (tqdm, on stderr) over the runs.
    description : str
        Label of the progress bar.
    on_batch : callable, optional
        Called with the outcomes of each batch as it finishes, in the calling thread; on an
        error or an interrupt, also with those of the batches that had finished.

    Returns
    -------
    list of Outcome
        One per run, in the order of ``runs``.

    Raises
    ------
    ConfigError
        ``workers`` or ``batch_size`` invalid (:func:`check_options`), or a run's value beyond
        what the C controllers or the engine take (naming the run).
    """
    check_options(workers, None, batch_size)
    if not runs:
        return []
    keep = frozenset(keep)
    bases = {name: bases[name] for name in dict.fromkeys(run.base for run in runs)}
    from tqdm import tqdm

    done: dict[Hashable, Outcome] = {}
    with tqdm(total=len(runs), unit="run", desc=description, disable=not progress, leave=False) as bar:

        def finished(outcomes: list[Outcome]) -> None:
            done.update((o.key, o) for o in outcomes)
            if on_batch is not None:
                on_batch(outcomes)
            bar.update(len(outcomes))

        if client is None:
            n_workers = workers or default_workers()
            batches = _batches(runs, batch_size or _auto_batch_size(len(runs), n_workers))
            _run_local(bases, batches, keep, measure, n_workers, pool, finished)
        else:
            threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
            batches = _batches(runs, batch_size or _auto_batch_size(len(runs), max(1, threads)))
            _run_dask(client, bases, batches, keep, measure, finished)
    return [done[run.key] for run in runs]


def _auto_batch_size(n_runs: int, n_workers: int) -> int:
    return max(1, min(BATCH_SIZE_MAX, math.ceil(n_runs / (BATCHES_PER_WORKER * n_workers))))


def _batches(runs: Sequence[Run], size: int) -> list[list[Run]]:
    return [list(runs[i : i + size]) for i in range(0, len(runs), size)]


def _run_local(
    bases: Mapping[str, Scenario],
    batches: Sequence[list[Run]],
    keep: frozenset[Hashable],
    measure: Measure,
    workers: int,
    pool: "ThreadPoolExecutor | None",
    finished: Callable[[list[Outcome]], None],
) -> None:
    """Batches on a thread pool (``pool``, else new threads); on any exception or interrupt, pass on what
    finished and re-raise."""
    from concurrent.futures import Future, as_completed, wait

    with contextlib.ExitStack() as stack:
        if pool is None:
            pool = stack.enter_context(local_threads(workers))
        futures = [pool.submit(simulate_batch, bases, batch, keep, measure) for batch in batches]
        passed: set[Future[list[Outcome]]] = set()
        try:
            for fut in as_completed(futures):
                finished(fut.result())
                passed.add(fut)
        except BaseException:
            for fut in futures:
                fut.cancel()
            wait(futures)
            for fut in futures:
                if fut not in passed and fut.done() and not fut.cancelled() and fut.exception() is None:
                    finished(fut.result())
            raise


def _run_dask(
    client: Any,  # a dask.distributed.Client
    bases: Mapping[str, Scenario],
    batches: Sequence[list[Run]],
    keep: frozenset[Hashable],
    measure: Measure,
    finished: Callable[[list[Outcome]], None],
) -> None:
    """Batches as tasks on a Dask distributed cluster; on any exception or interrupt, pass on what finished."""
    from dask.distributed import as_completed

    futures = [client.submit(simulate_batch, bases, batch, keep, measure, pure=False) for batch in batches]
    passed: set[str] = set()
    try:
        for fut in as_completed(futures, loop=client.loop):
            finished(fut.result())
            passed.add(fut.key)
    except BaseException:
        client.cancel([f for f in futures if not f.done()])
        for fut in futures:
            if fut.key not in passed and fut.status == "finished":
                finished(fut.result())
        raise


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line."""
    return " ".join(str(exc).split())


# ---------------------------------------------------------------------------------------------
# Parts: the rows of finished batches, stored as they finish
# ---------------------------------------------------------------------------------------------


class PartWarning(Pmsm2dofWarning):
    """A stored part of an earlier run cannot be used: it is deleted and its rows computed again."""


class PartStore:
    """The rows of finished batches, one Parquet file per batch, in ``folder``.

    Each part is written whole or not at all (:func:`pmsm2dof.outputs.atomic_write`), so an
    interrupted study keeps what finished and a second run reads it back instead of computing it
    again. Its name carries the SHA-256 of its content, written with it
    (``part-<first key>.<sha256>.parquet``): a part changed since, by a single byte, no longer
    matches and is never read.

    Parameters
    ----------
    folder : Path
        Where the parts are stored (created).
    frame : callable
        ``frame(rows)``: the rows (dicts) as a pandas DataFrame with the study's columns, in order.
    key_column : str
        The column that holds the key of a row: an integer index.
    n_keys : int
        The keys run from 0 to ``n_keys - 1``.
    """

    #: File names of the parts, and of the temporary files they are written through.
    PATTERNS = ("part-*.parquet", ".part-*")
    #: Largest part read [bytes] (a row takes some hundred bytes).
    BYTES_MAX = 1024**3

    def __init__(
        self, folder: Path, frame: Callable[[list[dict[str, Any]]], Any], key_column: str, n_keys: int
    ) -> None:
        self.folder = Path(folder)
        self.frame = frame
        self.key_column = key_column
        self.n_keys = n_keys

    def save(self, rows: list[dict[str, Any]]) -> None:
        """Store the rows of one finished batch as ``part-<first key>.<sha256 of the file>.parquet``."""
        buf = io.BytesIO()
        self.frame(rows).to_parquet(buf, index=False)
        data = buf.getvalue()
        name = f"part-{rows[0][self.key_column]:08d}.{hashlib.sha256(data).hexdigest()}.parquet"
        atomic_write(self.folder / name, data)

    def read(self) -> Any:
        """The rows of every stored part as one DataFrame, or None when there is none.

        A part can be damaged after it was written (a full disk, a copy cut short, another
        program). One whose content does not match the checksum in its name, that cannot be read,
        or that does not hold the columns and keys of this study, is deleted with a
        :class:`PartWarning` that names it: its rows are then missing and computed again.

        Raises
        ------
        ConfigError
            A damaged part cannot be deleted (naming the folder as ``out``).
        """
        import pandas as pd

        for path in self.folder.glob(".part-*"):  # the temporary file of a write cut short
            path.unlink(missing_ok=True)
        frames = []
        for path in sorted(self.folder.glob("part-*.parquet")):
            frame, problem = self._read_part(path)
            if frame is not None:
                frames.append(frame)
                continue
            where = f"{self.folder.name}/{path.name}"
            try:
                path.unlink()
            except OSError as exc:
                raise ConfigError(
                    "out",
                    str(self.folder.parent),
                    f"a folder where the damaged {where} can be deleted ({exc.strerror})",
                ) from None
            warnings.warn(
                f"{where} of the earlier run in {self.folder.parent} {problem}: deleted, its "
                f"{self.key_column}s run again",
                PartWarning,
                stacklevel=3,
            )
        return pd.concat(frames, ignore_index=True) if frames else None

    def _read_part(self, path: Path) -> tuple[Any, str]:
        """``(frame, "")`` of a sound part, ``(None, what is wrong)`` of another."""
        import pandas as pd
        import pyarrow

        name = _PART_NAME.fullmatch(path.name)
        if name is None:
            return None, "has no checksum in its name (renamed, or written by an older pmsm2dof)"
        try:
            data = read_bytes(path, "part", self.BYTES_MAX)
        except ConfigError as exc:
            return None, f"cannot be read ({exc.valid})"
        if hashlib.sha256(data).hexdigest() != name.group(2):
            return None, "does not match its checksum (it was changed after it was written)"
        try:
            frame = pd.read_parquet(io.BytesIO(data))
        except (OSError, ValueError, pyarrow.ArrowException) as exc:
            return None, f"cannot be read ({one_line(exc)})"
        if list(frame.columns) != list(self.frame([]).columns):
            return None, "does not hold the columns of this study"
        keys = frame[self.key_column]
        if not len(keys) or not keys.between(0, self.n_keys - 1).all() or int(keys.iloc[0]) != int(name.group(1)):
            return None, f"holds {self.key_column}s this study does not have"
        return frame, ""


#: ``part-<first key, 8 digits>.<SHA-256, 64 hex digits>.parquet``.
_PART_NAME = re.compile(r"part-(\d{8,})\.([0-9a-f]{64})\.parquet")
