"""Writing outputs all at once or not at all.

A command that fails half-way must not leave a half-written file or folder behind:
everything is written into a temporary sibling and moved into place at the end.
"""

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import ConfigError


def _stage(out: Path | str) -> Path:
    """Create and return the temporary sibling folder of ``out``, or raise ConfigError."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("out", str(out), "a folder path (it is an existing file)")
    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    except OSError as exc:
        raise ConfigError("out", str(out), f"a writable folder ({exc.strerror})") from None


def require_writable_dir(out: Path | str) -> None:
    """Raise ConfigError now, before any long work, if ``out`` cannot be written as a folder."""
    _stage(out).rmdir()


@contextlib.contextmanager
def staged_dir(out: Path | str) -> Iterator[Path]:
    """Yield a temporary folder whose files replace those in ``out`` on success.

    On an exception the temporary folder is removed and ``out`` is untouched.
    """
    out = Path(out)
    tmp = _stage(out)
    try:
        yield tmp
        out.mkdir(exist_ok=True)
        for item in tmp.iterdir():
            target = out / item.name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            os.replace(item, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def atomic_write(path: Path | str, data: bytes | str) -> None:
    """Write ``data`` (bytes or str) to ``path`` through a temporary file and a rename."""
    path = Path(path)
    mode = "wb" if isinstance(data, bytes) else "w"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as exc:
        raise ConfigError("path", str(path), f"a writable location ({exc.strerror})") from None
    try:
        # mkstemp creates the file 0600; give it the mode an ordinary open() would
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, mode) as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
