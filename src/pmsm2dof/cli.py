"""The ``pmsm2dof`` command.

Each sub-command lives next to the module it drives and is registered here.
Every error the user can cause ends as one line on stderr and exit status 2.
"""

import sys

import click

from .errors import Pmsm2dofError


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pmsm2dof")
def cli():
    """Design, simulate and deploy the anti-windup 2DOF PI speed controller of a PMSM."""


def _one_line(text):
    return " ".join(str(text).split())


def main(argv=None):
    """Entry point of the console script: run the CLI, map user errors to exit status 2."""
    try:
        cli.main(args=argv, prog_name="pmsm2dof", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        print("pmsm2dof: interrupted", file=sys.stderr)
        return 130
    except click.ClickException as exc:
        print(f"pmsm2dof: error: {_one_line(exc.format_message())}", file=sys.stderr)
        return 2
    except (Pmsm2dofError, ValueError, OSError) as exc:
        print(f"pmsm2dof: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    return 0
