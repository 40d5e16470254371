"""Reading what a user gives, within bounds: files, TOML and JSON.

Every file a user names (a scenario, a sweep, a motor file, a log, a sweep folder's manifest)
is opened here, or checked here before a library reads it:

- only a regular file (not a folder, a device such as ``/dev/zero``, a FIFO or a socket), found
  without a symbolic-link loop;
- of at most a given size, checked before it is read (:data:`TOML_BYTES_MAX` for the TOML
  files, the log reader's own bound for logs), and read no further than that size even if it
  grows meanwhile;
- TOML and JSON nested at most :data:`NESTING_MAX` levels deep (arrays and tables), and with
  integers of at most :data:`INTEGER_DIGITS_MAX` digits: a deeper or longer value would exhaust
  the parsers' recursion or Python's integer conversion, and no input of pmsm2dof needs one.

Each refusal is a :class:`~pmsm2dof.errors.ConfigError` naming the parameter, the file and
the bound.
"""

import json
import os
import stat
import tomllib
from typing import Any

from .errors import ConfigError, format_bytes

#: Largest TOML input file (scenario, sweep, motor) [bytes]: a scenario is a few kB, a sweep
#: with long lists of values some hundred kB; tomllib parses about 4 MiB/s (pure Python).
TOML_BYTES_MAX = 4 * 1024**2
#: Deepest nesting of arrays and tables in a TOML or JSON input (a scenario has 3 levels).
NESTING_MAX = 32
#: Most digits of an integer in a TOML or JSON input (float64 holds about 309).
INTEGER_DIGITS_MAX = 400


def check_file(path: str | os.PathLike[str], param: str, max_bytes: int) -> int:
    """Raise ConfigError unless ``path`` is a regular file of at most ``max_bytes``; return its size.

    Parameters
    ----------
    path : str or os.PathLike
    param : str
        The parameter the file was given as, named in the error.
    max_bytes : int
        Largest size accepted [bytes].
    """
    shown = os.fspath(path)
    try:
        info = os.stat(path)
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ConfigError(param, shown, f"an existing, readable file ({reason})") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a device, FIFO or socket"
        raise ConfigError(param, shown, f"a regular file (it is {kind})")
    if info.st_size > max_bytes:
        raise ConfigError(
            param, shown, f"a file of at most {format_bytes(max_bytes)} (it has {format_bytes(info.st_size)})"
        )
    return info.st_size


def read_bytes(path: str | os.PathLike[str], param: str, max_bytes: int) -> bytes:
    """The content of the regular file ``path``, of at most ``max_bytes`` (:func:`check_file`)."""
    check_file(path, param, max_bytes)
    try:
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise ConfigError(param, os.fspath(path), f"a readable file ({exc.strerror})") from None
    if len(data) > max_bytes:  # it grew since it was checked
        raise ConfigError(param, os.fspath(path), f"a file of at most {format_bytes(max_bytes)}")
    return data


def read_toml(path: str | os.PathLike[str], param: str, max_bytes: int = TOML_BYTES_MAX) -> dict[str, Any]:
    """The TOML file ``path`` parsed (:func:`read_bytes`, :func:`parse_toml`)."""
    data = read_bytes(path, param, max_bytes)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(param, os.fspath(path), f"a UTF-8 text file ({exc.reason} at byte {exc.start})") from None
    return parse_toml(text, param, os.fspath(path))


def parse_toml(text: str, param: str, source: str) -> dict[str, Any]:
    """``text`` parsed as TOML, nested at most :data:`NESTING_MAX` deep; ConfigError names ``source``."""
    try:
        tree = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(param, source, f"valid TOML ({exc})") from None
    except (ValueError, RecursionError, MemoryError) as exc:  # an integer too long, nesting
        raise ConfigError(param, source, f"valid TOML within pmsm2dof's bounds ({type(exc).__name__})") from None
    check_nesting(tree, param, source)
    return tree


def parse_json(data: bytes | str, param: str, source: str = "(JSON)") -> Any:
    """``data`` parsed as JSON, nested at most :data:`NESTING_MAX` deep, with integers of at most
    :data:`INTEGER_DIGITS_MAX` digits; ConfigError names ``param`` with ``source``. ``NaN`` and
    ``Infinity`` are read as floats, for the validation of the value to name its key."""
    try:
        text = data.decode("utf-8") if isinstance(data, bytes) else data
    except UnicodeDecodeError as exc:
        raise ConfigError(param, source, f"UTF-8 JSON ({exc.reason} at byte {exc.start})") from None

    def integer(digits: str) -> int:
        if len(digits.lstrip("-")) > INTEGER_DIGITS_MAX:
            raise ConfigError(param, source, f"JSON whose integers have at most {INTEGER_DIGITS_MAX} digits")
        return int(digits)

    try:
        value = json.loads(text, parse_int=integer)
    except json.JSONDecodeError as exc:
        raise ConfigError(param, source, f"valid JSON ({exc.msg} at character {exc.pos})") from None
    except RecursionError:
        raise ConfigError(param, source, f"JSON nested at most {NESTING_MAX} levels deep") from None
    check_nesting(value, param, source)
    return value


def check_nesting(value: Any, param: str, source: str) -> None:
    """Raise ConfigError if lists and dicts in ``value`` nest deeper than :data:`NESTING_MAX`."""
    level = [value]
    for _ in range(NESTING_MAX + 1):
        level = [
            child
            for node in level
            if isinstance(node, (dict, list))
            for child in (node.values() if isinstance(node, dict) else node)
        ]
        if not level:
            return
    raise ConfigError(param, source, f"tables and arrays nested at most {NESTING_MAX} levels deep")
