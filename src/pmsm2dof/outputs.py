"""Writing outputs all at once or not at all, and never over what pmsm2dof did not write.

A command that fails half-way must not leave a half-written file or folder behind:
everything is written into a temporary sibling and moved into place at the end
(:func:`staged_dir`, :func:`atomic_file`). A command that succeeds must not destroy what it
did not write:

- an output folder records what was written into it, in :data:`MANIFEST` (the command and each
  file with its size and modification time);
- :func:`check_out` refuses, before any work, an empty path, a path that is a file, a symbolic-link
  loop, an unwritable place, and a folder that holds anything else than what the same command
  wrote there earlier (naming the first such file) unless ``force`` is given; with ``force`` the
  other files stay where they are and the outputs are written beside them;
- :func:`staged_dir` replaces the earlier outputs of the same command as a whole: the new files
  are moved in, and those of the earlier run that this one did not write again (a ``motor.toml``
  of a commissioning that succeeded, under the ``result.json`` of one that failed) are removed.

A file that runs out of room on its disk is reported naming the output, with how much of it was
written and the room left; a path that is a device, a FIFO or a folder is never replaced by a file.
"""

import contextlib
import errno
import fnmatch
import json
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from .errors import ConfigError, format_bytes

#: The file of an output folder that lists what a command wrote there.
MANIFEST = ".pmsm2dof-outputs.json"
#: Largest manifest read [bytes] (some hundred bytes per file listed).
MANIFEST_BYTES_MAX = 16 * 1024**2


# ---------------------------------------------------------------------------------------------
# The output folder: checked before any work, replaced as a whole
# ---------------------------------------------------------------------------------------------


def check_out(out: Path | str, command: str, force: bool = False, own: Iterable[str] = ()) -> Path:
    """Raise ConfigError, before any work, unless ``out`` can receive the outputs of ``command``.

    Parameters
    ----------
    out : str or Path
        The output folder: new, empty, or holding only what ``command`` wrote there earlier.
    command : str
        The kind of output (``"simulate"``, ``"sweep"``...): only an earlier run of the same
        kind may be replaced.
    force : bool
        Accept a folder that holds other files too (they are kept).
    own : iterable of str
        Patterns (``fnmatch``, of the path relative to ``out``, ``*`` within one folder) of files
        the command keeps there between runs and checks itself (a sweep's parts).

    Returns
    -------
    Path
        ``out``.
    """
    if not isinstance(out, (str, os.PathLike)) or not os.fspath(out).strip():
        raise ConfigError("out", out, "a folder path (not empty)")
    out = Path(out)
    try:
        out.resolve(strict=False)
        exists = out.exists()
    except (OSError, RuntimeError) as exc:  # a symbolic-link loop, a name too long
        raise ConfigError("out", str(out), f"a folder path that can be resolved ({_reason(exc)})") from None
    if out.is_symlink() and not exists:
        raise ConfigError("out", str(out), "a folder path (it is a broken symbolic link)")
    if exists and not out.is_dir():
        raise ConfigError("out", str(out), "a folder path (it is an existing file)")
    if exists and not force:
        foreign = first_foreign(out, command, own)
        if foreign is not None:
            raise ConfigError(
                "out",
                str(out),
                f"a new or empty folder, or one holding only the outputs of an earlier {command} (it holds "
                f"{foreign}); force=True keeps the other files and writes beside them",
            )
    tmp, created = _stage(out)
    tmp.rmdir()
    _remove_created(created)
    return out


def first_foreign(out: Path, command: str, own: Iterable[str] = ()) -> str | None:
    """The first file in ``out`` (sorted, depth first) that no earlier ``command`` wrote there,
    described (``'notes.txt'``, ``'plot.png' (changed since pmsm2dof simulate wrote it)``,
    ``'trace.csv' (written by pmsm2dof simulate)``); None if none."""
    manifest = _manifest(out)
    writer, listed = manifest if manifest is not None else (None, {})
    patterns = tuple(own)
    for folder, dirs, files in os.walk(out):
        dirs.sort()
        for name in sorted(files) + [d for d in dirs if os.path.islink(os.path.join(folder, d))]:
            path = Path(folder, name)
            rel = path.relative_to(out).as_posix()
            if (rel == MANIFEST and manifest is not None) or _matches(rel, patterns):
                continue
            if rel not in listed:
                return repr(rel)
            if writer != command:
                return f"{rel!r} (written by pmsm2dof {writer})"
            if _stamp(path) != listed[rel]:
                return f"{rel!r} (changed since pmsm2dof {command} wrote it)"
    return None


@contextlib.contextmanager
def staged_dir(out: Path | str, command: str, force: bool = False, own: Iterable[str] = ()) -> Iterator[Path]:
    """Yield a temporary folder whose files become the outputs of ``command`` in ``out`` on success.

    ``out`` is checked first (:func:`check_out`). On success the files move into ``out`` (a new
    ``out`` is the temporary folder renamed, in one step), the files of the earlier run of
    ``command`` that this one did not write are removed, and the manifest lists the new files.
    On an exception the temporary folder is removed and ``out`` is untouched.
    """
    out = check_out(out, command, force, own)
    tmp, created = _stage(out)
    done = False
    try:
        try:
            yield tmp
        except ConfigError as exc:
            # a file of the temporary folder is named by its place in out
            inside = exc.param == "path" and Path(str(exc.value)).is_relative_to(tmp)
            if not inside:
                raise
            raise ConfigError("out", str(out / Path(str(exc.value)).relative_to(tmp)), exc.valid) from None
        with _signals_deferred():
            check_out(out, command, force, own)  # a file may have appeared during a long run
            _commit(tmp, out, command, force)
        done = True
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if not done:
            _remove_created(created)


def remove_outputs(out: Path | str, command: str, own: Iterable[str] = ()) -> None:
    """Remove what ``command`` wrote in ``out`` (the files of its manifest unchanged since, and the
    files matching ``own``), then the folders left empty; other files stay."""
    out = Path(out)
    listed = _own_files(out, command) or {}
    patterns = tuple(own)
    for folder, _dirs, files in os.walk(out):
        for name in files:
            path = Path(folder, name)
            rel = path.relative_to(out).as_posix()
            mine = rel in listed and _stamp(path) == listed[rel]
            if mine or rel == MANIFEST or _matches(rel, patterns):
                _unlink(path, out)


def _own_files(out: Path, command: str) -> dict[str, list[int]] | None:
    """``{relative path: [size, mtime_ns]}`` that the manifest of ``out`` lists for ``command``;
    None when it has no manifest of ``command`` (or a damaged one)."""
    manifest = _manifest(out)
    return manifest[1] if manifest is not None and manifest[0] == command else None


def _manifest(out: Path) -> tuple[str, dict[str, list[int]]] | None:
    """The command and the files (``{relative path: [size, mtime_ns]}``) of the manifest of
    ``out``; None when it has none, or a damaged one."""
    path = out / MANIFEST
    try:
        if not path.is_file() or path.stat().st_size > MANIFEST_BYTES_MAX:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if (
        not isinstance(data, dict)
        or not isinstance(data.get("command"), str)
        or not isinstance(data.get("files"), dict)
    ):
        return None
    files = {k: v for k, v in data["files"].items() if isinstance(k, str) and isinstance(v, list)}
    return data["command"], files


def _matches(rel: str, patterns: tuple[str, ...]) -> bool:
    """True if the relative path ``rel`` matches a pattern of ``patterns`` at the same depth."""
    return any(rel.count("/") == p.count("/") and fnmatch.fnmatchcase(rel, p) for p in patterns)


def _stamp(path: Path) -> list[int]:
    info = path.lstat()
    return [info.st_size, info.st_mtime_ns]


def _tree(folder: Path) -> list[str]:
    """The files below ``folder``, relative, sorted."""
    return sorted(
        Path(d, f).relative_to(folder).as_posix() for d, _dirs, files in os.walk(folder) for f in files if f != MANIFEST
    )


def _commit(tmp: Path, out: Path, command: str, force: bool) -> None:
    """Move the files of ``tmp`` into ``out`` and remove the earlier outputs of ``command`` there."""
    new = _tree(tmp)
    if not out.exists():
        _write_manifest(tmp, command, {rel: _stamp(tmp / rel) for rel in new})
        os.rename(tmp, out)
        return
    old = _own_files(out, command) or {}
    stamps = {rel: _stamp(tmp / rel) for rel in new}
    # first a manifest listing both runs' files: an interrupt below leaves no file unaccounted
    _write_manifest(out, command, {**old, **stamps})
    for rel in new:
        target = out / rel
        _make_parents(target, out)
        if target.is_dir() and not target.is_symlink():
            raise ConfigError("out", str(out), f"a folder where {rel!r} can be written (a folder has that name)")
        os.replace(tmp / rel, target)
    for rel, stamp in old.items():
        path = out / rel
        if rel not in stamps and path.is_file() and _stamp(path) == stamp:
            _unlink(path, out)
    _write_manifest(out, command, stamps)


def _make_parents(target: Path, out: Path) -> None:
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        rel = target.parent.relative_to(out).as_posix()
        raise ConfigError("out", str(out), f"a folder where {rel!r} can be a folder (a file has that name)") from None


def _write_manifest(folder: Path, command: str, files: dict[str, list[int]]) -> None:
    text = json.dumps({"command": command, "files": files}, indent=1, sort_keys=True) + "\n"
    atomic_write(folder / MANIFEST, text)


def _unlink(path: Path, out: Path) -> None:
    """Remove the file ``path`` of ``out``, then its folders that this left empty (not ``out``)."""
    try:
        path.unlink()
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise ConfigError("out", str(out), f"a folder whose old outputs can be removed ({_reason(exc)})") from None
    folder = path.parent
    while folder != out and out in folder.parents:
        try:
            folder.rmdir()
        except OSError:  # not empty
            return
        folder = folder.parent


def _stage(out: Path) -> tuple[Path, list[Path]]:
    """Create the temporary sibling folder of ``out`` (and the missing folders above it), or raise
    ConfigError; return it and the folders above it that this created, deepest first."""
    parent = out.absolute().parent
    created = [p for p in [parent, *parent.parents] if not p.exists()]
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
        # mkdtemp creates the folder 0700; renamed into place, it gets the mode mkdir would give
        tmp.chmod(0o777 & ~_umask())
        return tmp, created
    except (OSError, RuntimeError) as exc:
        _remove_created(created)
        raise ConfigError("out", str(out), f"a writable folder ({_reason(exc)})") from None


def _remove_created(folders: list[Path]) -> None:
    """Remove the ``folders`` created for an output that was not written, deepest first, if empty."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP during the block and deliver them after it (main thread only):
    the moves into an output folder are not cut in two."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    names = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    before = {sig: signal.signal(sig, lambda sig, frame: held.append(sig)) for sig in names}
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
        for signum in held[:1]:
            signal.raise_signal(signum)


# ---------------------------------------------------------------------------------------------
# Files: written whole or not at all
# ---------------------------------------------------------------------------------------------


@contextlib.contextmanager
def atomic_file(path: Path | str, mode: str = "w") -> Iterator[IO[Any]]:
    """Yield a file opened in ``mode`` (``"w"`` or ``"wb"``) whose content replaces ``path`` on success.

    The content goes to a temporary sibling that is renamed over ``path`` at the end, so that a
    failure or an interrupt leaves ``path`` as it was; a ``path`` that is a folder, a device (the
    rename would replace ``/dev/null``), a FIFO or a socket is refused. Written in pieces, a large output (the log
    of a long run) is never held in memory whole. A full disk raises ConfigError naming ``path``
    with the room there was.
    """
    path = Path(path)
    if os.path.lexists(path) and not (path.is_file() or path.is_symlink()):
        # the rename would put a file in the place of a device (/dev/null), a FIFO or a folder
        raise ConfigError("path", str(path), "a file path (it is a folder, a device, a FIFO or a socket)")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except (OSError, RuntimeError) as exc:
        raise ConfigError("path", str(path), f"a writable location ({_reason(exc)})") from None
    try:
        # mkstemp creates the file 0600; give it the mode an ordinary open() would
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8") as f:
            yield f
        os.replace(tmp, path)
    except OSError as exc:
        written = 0
        with contextlib.suppress(OSError):
            written = os.stat(tmp).st_size
            os.unlink(tmp)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise ConfigError(
                "path",
                str(path),
                f"a place with room for it: the disk filled up after {format_bytes(written)} of it "
                f"({free_space(path.parent)} free once that was removed)",
            ) from None
        raise
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def check_file(path: Path | str, param: str) -> None:
    """Raise ConfigError naming ``param``, before any long work, if the file ``path`` cannot be written."""
    folder = Path(path).resolve().parent
    if Path(path).is_dir():
        raise ConfigError(param, path, "a file path (it is an existing folder)")
    if os.path.lexists(path) and not (Path(path).is_file() or Path(path).is_symlink()):
        raise ConfigError(param, path, "a file path (it is a device, a FIFO or a socket)")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ConfigError(param, path, "a file in an existing, writable folder")


def atomic_write(path: Path | str, data: bytes | str) -> None:
    """Write ``data`` (bytes or str) to ``path`` through a temporary file and a rename."""
    with atomic_file(path, "wb" if isinstance(data, bytes) else "w") as f:
        f.write(data)


def csv_text(rows: Sequence[Mapping[str, Any]]) -> str:
    """``rows`` (dicts with the same keys) as CSV text; None is an empty cell."""
    import csv
    import io

    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return buf.getvalue()


def free_space(folder: Path | str) -> str:
    """The room left on the disk of ``folder``, for messages (``'1.2 GiB'``, or ``'unknown'``)."""
    try:
        return format_bytes(shutil.disk_usage(folder).free)
    except OSError:
        return "unknown"


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__
