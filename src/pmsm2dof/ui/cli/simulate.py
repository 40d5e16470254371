"""``pmsm2dof simulate``, ``presets`` and ``compare``: one scenario run by the engine (pmsm2dof.sim)."""

from typing import Any

import click

from ...errors import ConfigError
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
    import json

    import numpy as np

    from ...outputs import atomic_write, staged_dir
    from ...sim.logs import read_log
    from ...sim.metrics import compute_metrics
    from ...sim.plausibility import warn_implausible
    from ...sim.scenario import load_scenario
    from ...sim.simulate import simulate as run_simulation
    from ..plots.identify import plot_compare

    columns = dict(parse_column(text) for text in column_maps)
    measured = read_log(log, columns)
    chosen = load_scenario(scenario)
    inside = (measured.t_s >= 0.0) & (measured.t_s <= chosen.simulation.t_end_s)
    if np.count_nonzero(inside) < 2:
        raise ConfigError("LOG", log, f"a log whose time overlaps the scenario's 0 to {chosen.simulation.t_end_s:g} s")
    with staged_dir(out, "compare", force) as tmp:
        result = run_simulation(chosen)
        error = measured.speed_rpm[inside] - np.interp(measured.t_s[inside], result.t_s, result.speed_rpm)
        i_max = chosen.limits.i_max_A
        table: dict[str, Any] = {
            "log": str(log),
            "scenario": chosen.name,
            "speed_error_rms_rpm": float(np.sqrt(np.mean(error**2))),
            "speed_error_max_rpm": float(np.max(np.abs(error))),
            "log_metrics": compute_metrics(measured, i_max_A=i_max) if measured.speed_ref_rpm is not None else None,
            "simulation_metrics": compute_metrics(result),
        }
        plot_compare(measured, result, tmp / "compare.png")
        atomic_write(tmp / "compare.json", json.dumps(table, indent=2, allow_nan=False) + "\n")
        result.save(tmp / "simulation.csv")
    warn_implausible(chosen)
    click.echo(
        f"{chosen.name} against {log}: speed difference {table['speed_error_rms_rpm']:.4g} rpm rms, "
        f"{table['speed_error_max_rpm']:.4g} rpm at most"
    )
    for note in measured.notes:
        click.echo(f"note: {note}")
    if table["log_metrics"] is not None:
        dt = measured.dt_s
        for mine in table["log_metrics"]["reference_steps"]:
            same = [s for s in table["simulation_metrics"]["reference_steps"] if abs(s["t_s"] - mine["t_s"]) <= dt]
            missing = {"value": None}
            sim = same[0] if same else dict.fromkeys(("overshoot_pct", "rise_time_s", "settling_time_s"), missing)
            cells = []
            for key in ("overshoot_pct", "rise_time_s", "settling_time_s"):
                a, b = mine[key]["value"], sim[key]["value"]
                cells.append(f"{key} {'n/a' if a is None else f'{a:.4g}'} / {'n/a' if b is None else f'{b:.4g}'}")
            click.echo(f"  step at {mine['t_s']:g} s (log / simulation): " + ", ".join(cells))
    click.echo(f"wrote compare.png, compare.json and simulation.csv to {out}")
