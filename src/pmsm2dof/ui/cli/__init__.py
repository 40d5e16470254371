"""The ``pmsm2dof`` command: the group, its entry point, and the registration of every command.

Each command group lives in a module of this package (design, simulate, sweep, identify, ...); a
command parses its options, calls one function of a lower layer and prints. What the commands
share (the ``--out``/``--force``, ``--json`` and ``--set`` options, the parsing of ``--set`` and
``--column``, errors and warnings as one line) is in :mod:`pmsm2dof.ui.cli.options`. Every error
the user can cause ends as one line on stderr and exit status 2.
"""

import sys

import click

from ...errors import ConfigError, Pmsm2dofError, Terminated, signals_raise_terminated
from . import commission, design, drive, firmware, identify, motor, report, simulate, sweep, tune, twomass
from .options import Group, as_cli_error, one_line, parse_override, warnings_as_lines

__all__ = ["cli", "main", "parse_override"]


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pmsm2dof")
def cli() -> None:
    """Design, simulate and deploy the anti-windup 2DOF PI speed controller of a PMSM."""


for _command in (
    design.design,
    design.bode,
    report.reproduce,
    simulate.simulate,
    simulate.presets,
    sweep.sweep,
    tune.tune,
    sweep.autotune,
    commission.commission,
    motor.motor,
    identify.identify,
    simulate.compare,
    report.sensors,
    twomass.twomass,
    firmware.header,
    firmware.firmware,
):
    cli.add_command(_command)
cli.add_command(drive.drive)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script: run the CLI, map user errors to exit status 2.

    The warnings of pmsm2dof are shown once each, as one line on stderr (:func:`warnings_as_lines`).

    A command ends with another status by raising ``click.exceptions.Exit`` (``autotune``: 1
    when no design meets the specification). SIGINT ends it with 130, SIGTERM with 143 and
    SIGHUP with 129 (128 + the signal), after the same cleanup: no staging folder is left.
    """
    try:
        with signals_raise_terminated(), warnings_as_lines():
            status = cli.main(args=argv, prog_name="pmsm2dof", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except click.exceptions.Abort:
        print("pmsm2dof: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print("pmsm2dof: terminated", file=sys.stderr)
        return 128 + exc.signum
    except click.ClickException as exc:
        print(f"pmsm2dof: error: {one_line(exc.format_message())}", file=sys.stderr)
        return 2
    except ConfigError as exc:
        print(f"pmsm2dof: error: {one_line(as_cli_error(exc))}", file=sys.stderr)
        return 2
    except (Pmsm2dofError, ValueError, OSError) as exc:
        print(f"pmsm2dof: error: {one_line(exc)}", file=sys.stderr)
        return 2
    return status if isinstance(status, int) else 0
