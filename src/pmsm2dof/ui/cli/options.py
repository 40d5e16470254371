"""What the commands share: the options written once, the parsing of --set and --column, the errors
and warnings as one line."""

import contextlib
import sys
import tomllib
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TextIO

import click

from ...errors import ConfigError, Pmsm2dofWarning

if TYPE_CHECKING:
    pass


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _as_option(exc: ConfigError, options: Mapping[str, str]) -> ConfigError:
    """``exc`` with its parameter named by its command-line option, when it has one in ``options``."""
    if exc.param in options:
        return ConfigError(options[exc.param], exc.value, exc.valid)
    return exc


def parse_override(text: str) -> tuple[str, Any]:
    """Parse one ``--set key=value`` of the command line.

    Parameters
    ----------
    text : str
        ``key=value``; the value is read as a TOML literal (``0.5``, ``true``, ``"x"``,
        ``nan``, ``[{t_s = 1.0, torque_Nm = 2.0}]``) and, when it is not one, taken as a plain
        string (``feedforward=none``).

    Returns
    -------
    tuple
        ``(key, value)`` for :meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`, which
        validates the value.
    """
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError("--set", text, "key=value, e.g. speed_controller.alpha_radps=0.5")
    raw = raw.strip()
    try:
        parsed = tomllib.loads(f"v = {raw}")
    except tomllib.TOMLDecodeError:
        return key, raw
    return (key, parsed["v"]) if list(parsed) == ["v"] else (key, raw)


def _as_cli_error(exc: ConfigError) -> ConfigError:
    """``exc`` of an output folder in the words of the command line (``--out``, ``--force``)."""
    if exc.param not in ("out", "--out"):
        return exc
    return ConfigError("--out", exc.value, exc.valid.replace("force=True", "--force"))


def out_option(what: str, **kwargs: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The ``--out`` folder of a command (``what`` it receives) and ``--force``.

    The folder must be new, empty or hold only the outputs of an earlier run of the same command,
    which are replaced as a whole (:func:`pmsm2dof.outputs.staged_dir`); ``--force`` writes into
    a folder holding other files too, and keeps them.
    """
    kwargs.setdefault("type", click.Path())
    help_text = (
        f"{what}; an existing folder must hold only the outputs of an earlier run of this command, which are replaced"
    )

    def decorate(f: Callable[..., Any]) -> Callable[..., Any]:
        f = click.option("--force", is_flag=True, help="write into --out even if it holds other files (they are kept)")(
            f
        )
        return click.option("--out", help=help_text, **kwargs)(f)

    return decorate


def _require_writable_file(path: str, option: str = "--emit-c-header") -> None:
    """Raise ConfigError naming ``option``, before any long work, if ``path`` cannot be written."""
    import os
    from pathlib import Path

    folder = Path(path).resolve().parent
    if Path(path).is_dir():
        raise ConfigError(option, path, "a file path (it is an existing folder)")
    if os.path.lexists(path) and not (Path(path).is_file() or Path(path).is_symlink()):
        raise ConfigError(option, path, "a file path (it is a device, a FIFO or a socket)")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ConfigError(option, path, "a file in an existing, writable folder")


def _csv_text(rows: Sequence[Mapping[str, Any]]) -> str:
    """``rows`` (dicts with the same keys) as CSV text; None is an empty cell."""
    import csv
    import io

    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return buf.getvalue()


@contextlib.contextmanager
def _held_warnings() -> Iterator[None]:
    """Hold the warnings raised inside the block; give them again only when it ends without an error."""
    import warnings

    with warnings.catch_warnings(record=True) as held:
        warnings.simplefilter("always")
        yield
    for w in held:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


@contextlib.contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Show each warning of pmsm2dof raised inside the block once, as one line on stderr.

    A :class:`~pmsm2dof.errors.Pmsm2dofWarning` whose text was shown already (a scenario converted
    again for every run of a study, say) is not repeated; other warnings are shown as Python shows them.
    """
    import warnings

    shown: set[str] = set()
    with warnings.catch_warnings():
        show = warnings.showwarning

        def one_line(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            if not issubclass(category, Pmsm2dofWarning):
                show(message, category, filename, lineno, file, line)
            elif (text := _one_line(message)) not in shown:
                shown.add(text)
                print(f"pmsm2dof: warning: {text}", file=sys.stderr)

        warnings.filterwarnings("always", category=Pmsm2dofWarning)
        warnings.showwarning = one_line
        yield


def parse_column(text: str) -> tuple[str, str]:
    """Parse one ``--column signal=name`` into ``(signal, name)`` for :func:`pmsm2dof.sim.logs.read_log`."""
    signal, sep, name = text.partition("=")
    if not sep or not signal.strip() or not name.strip():
        raise ConfigError("--column", text, "signal=name, e.g. speed=enc_speed_rpm")
    return signal.strip(), name.strip()


def _chosen(scenario: str, overrides: Sequence[str]) -> tuple[Any, str]:
    """The scenario of PRESET_OR_FILE with the --set changes, and the command line that names it."""
    from ...sim.scenario import load_scenario

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    return chosen, " ".join([scenario, *(f"--set {text}" for text in overrides)])
