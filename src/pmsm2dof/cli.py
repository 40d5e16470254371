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


# ---------------------------------------------------------------------------------------------
# simulate and presets (pmsm2dof.scenario, simulate, metrics, traceplot)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="change a scenario key, e.g. --set speed_controller.anti_windup=none or "
                   "--set reference.0.speed_rpm=300 (repeatable; values are TOML literals)")
@click.option("--out", type=click.Path(), required=True,
              help="folder for trace.csv, metrics.json, plot.png and scenario.toml")
def simulate(scenario, overrides, out):
    """Simulate a scenario (see `pmsm2dof presets`) and write its trace, metrics and plot.

    Writes DIR/trace.csv (one column per signal), DIR/metrics.json (the step and load-step
    figures; a figure that cannot be computed is null with its reason), DIR/plot.png and
    DIR/scenario.toml (the scenario as run), all or nothing.
    """
    import json

    from .metrics import compute_metrics, summary_lines
    from .outputs import atomic_write, staged_dir
    from .scenario import load_scenario, parse_override
    from .simulate import simulate as run_simulation
    from .traceplot import plot_trace

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    with staged_dir(out) as tmp:
        result = run_simulation(chosen, progress=True)
        metrics = compute_metrics(result)
        result.save(tmp / "trace.csv")
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        plot_trace(result, tmp / "plot.png")
        atomic_write(tmp / "scenario.toml", chosen.to_toml())
    click.echo(f"{chosen.name}: {result.t_s[-1]:g} s simulated in {result.wall_time_s:.3g} s")
    for line in summary_lines(metrics):
        click.echo(f"  {line}")
    click.echo(f"wrote trace.csv, metrics.json, plot.png and scenario.toml to {out}")


@cli.command()
@click.option("--keys", is_flag=True, help="list every scenario key (type, range, default, meaning) instead")
def presets(keys):
    """List the scenarios shipped with pmsm2dof, by name, for `pmsm2dof simulate NAME`."""
    from .scenario import list_presets, load_scenario, schema_reference

    if keys:
        click.echo(schema_reference())
        return
    names = list_presets()
    width = max(len(name) for name in names)
    for name in names:
        click.echo(f"{name:<{width}}  {load_scenario(name).description}")
