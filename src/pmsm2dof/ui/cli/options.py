"""What the commands share: the options written once, the parsing of --set and --column, the errors
and warnings as one line.

An option that sets a quantity with a unit is spelled as the scenario key or the library argument
it sets, ``_`` written ``-``: its SI unit suffix included (``--alpha-radps``, ``--Ts-s``,
``--Ld-H``; docs/conventions.md, "Units"). A spelling renamed by this rule is refused with one line
that names the new one (:data:`RENAMED`, :class:`Group`).
"""

import contextlib
import sys
import tomllib
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, TextIO

import click

from ...errors import ConfigError, Pmsm2dofWarning

Decorator = Callable[[Callable[..., Any]], Callable[..., Any]]

#: Old spellings of options -> the spelling with the unit suffix of the scenario key.
RENAMED = {
    "--J": "--J-kgm2",
    "--alpha": "--alpha-radps",
    "--Ts": "--Ts-s",
    "--tau-i": "--tau-i-s",
    "--i-max": "--i-max-A",
    "--psi-f": "--psi-f-Wb",
    "--Ld": "--Ld-H",
    "--Lq": "--Lq-H",
    "--Rs": "--Rs-ohm",
    "--Ts-current": "--Ts-current-s",
    "--sensor-bandwidth": "--sensor-bandwidth-radps",
    "--sensor-lowpass": "--sensor-lowpass-radps",
    "--sensor-delay": "--sensor-delay-s",
    "--phase-margin": "--phase-margin-deg",
    "--current-bandwidth": "--current-bandwidth-radps",
    "--J-motor": "--J-motor-kgm2",
    "--J-load": "--J-load-kgm2",
    "--stiffness": "--stiffness-Nm-per-rad",
    "--damping": "--damping-Nms-per-rad",
    "--notch-freq": "--notch-freq-Hz",
    "--notch-width": "--notch-width-Hz",
    "--lowpass-freq": "--lowpass-freq-Hz",
    "--duration": "--duration-s",
}
#: Options replaced by another of a different meaning -> (the new option, why).
REPLACED = {"--elf": ("--a2l", "the drive is described by its A2L file, as in `pmsm2dof drive`")}


class Group(click.Group):
    """A command group whose commands refuse the old spelling of a renamed option in one line.

    ``pmsm2dof design --alpha 30`` ends with "--alpha is spelled --alpha-radps now", exit status 2,
    where click would only say that it knows no such option.
    """

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name, command, rest = super().resolve_command(ctx, args)
        if command is not None and not isinstance(command, click.Group):
            known = {opt for param in command.params for opt in param.opts}
            for arg in rest:
                if arg == "--":
                    break
                old = arg.split("=", 1)[0]
                if old in RENAMED and old not in known and RENAMED[old] in known:
                    raise click.UsageError(
                        f"{old} is spelled {RENAMED[old]} now (an option carries the unit of its scenario key)"
                    )
                if old in REPLACED and old not in known and REPLACED[old][0] in known:
                    raise click.UsageError(f"{old} is replaced by {REPLACED[old][0]}: {REPLACED[old][1]}")
        return name, command, rest


def option_name(param: str) -> str:
    """The option of the library argument or scenario key ``param`` (``alpha_radps`` -> ``--alpha-radps``)."""
    return "--" + param.replace("_", "-")


class _FieldOption(click.Option):
    """An option whose help is the comment of a field in a C header (meaning, unit, range), read when shown.

    The comments load with the C library (:func:`pmsm2dof.core.bindings.field_comment`), which
    ``pmsm2dof --help`` does not import.
    """

    def __init__(self, *args: Any, ctype: str, field: str, note: str = "", **kwargs: Any) -> None:
        self._comment = (ctype, field, note)
        super().__init__(*args, **kwargs)

    @property
    def help(self) -> str:
        from ...core.bindings import field_comment

        ctype, field, note = self._comment
        return "; ".join(filter(None, (field_comment(ctype, field), note)))

    @help.setter
    def help(self, value: str | None) -> None:
        """click sets the help it was given (None): the header's is read instead."""


def speed_option(field: str, note: str = "", **kwargs: Any) -> Decorator:
    """The option of a field of the C speed controller's configuration (``p2d_speed_config_t``).

    Its meaning, unit and range are the header's comment of the field (speed.h), written once;
    ``note`` is added to it.
    """
    kwargs.setdefault("type", float)
    return click.option(
        option_name(field), field, cls=_FieldOption, ctype="p2d_speed_config_t", field=field, note=note, **kwargs
    )


#: The motor data options: argument -> (type, help).
MOTOR_OPTIONS: dict[str, tuple[type, str]] = {
    "i_max_A": (float, "current-vector limit [A]"),
    "pole_pairs": (int, "pole pairs p"),
    "psi_f_Wb": (float, "magnet flux linkage [Wb]"),
    "Ld_H": (float, "d-axis inductance [H]"),
    "Lq_H": (float, "q-axis inductance [H]"),
    "Rs_ohm": (float, "stator resistance per phase [ohm]"),
    "Ts_current_s": (float, "current-loop sampling period [s]"),
}


def motor_option(param: str, note: str = "") -> Decorator:
    """The option of one motor quantity of :data:`MOTOR_OPTIONS`, ``note`` added to its help."""
    kind, help_text = MOTOR_OPTIONS[param]
    return click.option(option_name(param), param, type=kind, default=None, help=f"{help_text} {note}".strip())


def json_option(instead_of: str = "the table") -> Decorator:
    """``--json``: print one JSON object instead of ``instead_of``."""
    return click.option("--json", "as_json", is_flag=True, help=f"print one JSON object instead of {instead_of}")


def set_option(help_text: str = "change a scenario key (repeatable; values are TOML literals)") -> Decorator:
    """``--set KEY=VALUE`` (repeatable): change a scenario key, the value a TOML literal (:func:`parse_override`)."""
    return click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", help=help_text)


def workers_option() -> Decorator:
    """``--workers``: the local threads of a study."""
    return click.option("--workers", type=int, default=None, help="local threads [default: all available cores]")


def scheduler_option(command: str) -> Decorator:
    """``--scheduler ADDRESS``: run ``command``'s simulations on a Dask cluster (the extra ``dask``)."""

    def needs_dask(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
        if value is not None:
            require_extra("distributed", "dask", f"pmsm2dof {command} --scheduler")
        return value

    return click.option(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        callback=needs_dask,
        help="run the simulations on an existing Dask cluster, e.g. tcp://host:8786 (its workers need pmsm2dof; "
        "the extra 'dask')",
    )


def require_extra(module: str, extra: str, what: str) -> None:
    """Raise a one-line error naming the extra and its pip command when ``module`` is not installed."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise click.UsageError(
            f"{what} needs the optional dependencies '{extra}': python3 -m pip install 'pmsm2dof[{extra}]'"
        )


def one_line(text: object) -> str:
    return " ".join(str(text).split())


def as_option(exc: ConfigError, options: Mapping[str, str]) -> ConfigError:
    """``exc`` with its parameter named by its command-line option, when it has one in ``options``."""
    if exc.param in options:
        return ConfigError(options[exc.param], exc.value, exc.valid)
    return exc


#: The library's arguments of a drive's link -> the options the drive commands, ``tune`` and ``reproduce`` take.
LINK_OPTIONS = {"link": "--link", "a2l": "--a2l", "allow_remote": "--allow-remote"}


@contextlib.contextmanager
def options_named(options: Mapping[str, str]) -> Iterator[None]:
    """Raise a ConfigError of the block with its parameter named by its option (:func:`as_option`)."""
    try:
        yield
    except ConfigError as exc:
        raise as_option(exc, options) from None


class DriveGroup(Group):
    """A group of commands on a drive: an error of its link or A2L file names ``--link`` or ``--a2l``."""

    def invoke(self, ctx: click.Context) -> Any:
        with options_named(LINK_OPTIONS):
            return super().invoke(ctx)


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


def as_cli_error(exc: ConfigError) -> ConfigError:
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


@contextlib.contextmanager
def held_warnings() -> Iterator[None]:
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

        def show_as_line(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            if not issubclass(category, Pmsm2dofWarning):
                show(message, category, filename, lineno, file, line)
            elif (text := one_line(message)) not in shown:
                shown.add(text)
                print(f"pmsm2dof: warning: {text}", file=sys.stderr)

        warnings.filterwarnings("always", category=Pmsm2dofWarning)
        warnings.showwarning = show_as_line
        yield


def parse_column(text: str) -> tuple[str, str]:
    """Parse one ``--column signal=name`` into ``(signal, name)`` for :func:`pmsm2dof.sim.logs.read_log`."""
    signal, sep, name = text.partition("=")
    if not sep or not signal.strip() or not name.strip():
        raise ConfigError("--column", text, "signal=name, e.g. speed=enc_speed_rpm")
    return signal.strip(), name.strip()


def chosen_scenario(scenario: str, overrides: Sequence[str]) -> tuple[Any, str]:
    """The scenario of PRESET_OR_FILE with the --set changes, and the command line that names it."""
    from ...sim.scenario import load_scenario

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    return chosen, " ".join([scenario, *(f"--set {text}" for text in overrides)])
