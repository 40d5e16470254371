"""``pmsm2dof simulate``, ``presets`` and ``compare``: one scenario run by the engine (pmsm2dof.sim)."""

import click

from .options import out_option, parse_column, parse_override, set_option


@click.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@set_option(
    "change a scenario key, e.g. --set speed_controller.anti_windup=none or "
    "--set reference.0.speed_rpm=300 (repeatable; values are TOML literals)"
)
@out_option("folder for trace.csv, metrics.json, plot.png and scenario.toml", required=True)
def simulate(scenario: str, overrides: tuple[str, ...], out: str, force: bool) -> None:
    """Simulate a scenario (see `pmsm2dof presets`) and write its trace, metrics and plot.

    Writes DIR/trace.csv (one column per signal), DIR/metrics.json (the step and load-step
    figures; a figure that cannot be computed is null with its reason), DIR/plot.png and
    DIR/scenario.toml (the scenario as run), all or nothing. A design whose sampled loop is
    unstable (the check `pmsm2dof design` refuses it by) and a current command that chatters
    are run all the same, and named first in the summary and in metrics.json's warnings.
    """
    import json

    from ...outputs import atomic_write, staged_dir
    from ...sim.metrics import summary_lines
    from ...sim.plausibility import warn_implausible
    from ...sim.scenario import load_scenario
    from ...sim.simulate import simulate as run_simulation
    from ...studies.loopcheck import measure
    from ..plots import trace

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    with staged_dir(out, "simulate", force) as tmp:
        result = run_simulation(chosen, progress=True)
        metrics = measure(result)
        result.save(tmp / "trace.csv")
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        trace.plot_trace(result, tmp / "plot.png")
        atomic_write(tmp / "scenario.toml", chosen.to_toml())
    # after the run: an input the engine refuses, or a run that stops, is one line (its error) alone
    warn_implausible(chosen)
    click.echo(f"{chosen.name}: {result.t_s[-1]:g} s simulated in {result.wall_time_s:.3g} s")
    for line in summary_lines(metrics):
        click.echo(f"  {line}")
    click.echo(f"wrote trace.csv, metrics.json, plot.png and scenario.toml to {out}")


@click.command()
@click.option("--keys", is_flag=True, help="list every scenario key (type, range, default, meaning) instead")
def presets(keys: bool) -> None:
    """List the scenarios shipped with pmsm2dof, by name, for `pmsm2dof simulate NAME`."""
    from ...sim.scenario import list_presets, load_scenario, schema_reference

    if keys:
        click.echo(schema_reference())
        return
    names = list_presets()
    width = max(len(name) for name in names)
    for name in names:
        click.echo(f"{name:<{width}}  {load_scenario(name).description}")


@click.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option(
    "--column",
    "column_maps",
    multiple=True,
    metavar="SIGNAL=NAME",
    help="read a signal from another column, e.g. --column speed=enc_speed_rpm",
)
@out_option("folder for the figure and the table", required=True)
def compare(log: str, scenario: str, column_maps: tuple[str, ...], out: str, force: bool) -> None:
    """Overlay a measured LOG and the simulation of SCENARIO (the same reference and load).

    Writes DIR/compare.png (speed, iq and their difference), DIR/compare.json (RMS and largest
    speed difference, and the figures of merit of each reference step of the log and of the
    simulation, pmsm2dof.sim.metrics) and DIR/simulation.csv, all or nothing.
    """
    from ...studies.compare import compare_log
    from ..plots.identify import plot_compare

    columns = dict(parse_column(text) for text in column_maps)
    for line in compare_log(log, columns, scenario, out, force, plot_compare).lines():
        click.echo(line)
