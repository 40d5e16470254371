"""``pmsm2dof sweep`` and ``pmsm2dof autotune``: many runs (pmsm2dof.studies.sweep_run, studies.autotune_search)."""

import sys
from typing import TYPE_CHECKING, Any

import click

from ...errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from ...core.bindings import AntiWindup, Feedforward

from .options import (
    as_option,
    json_option,
    one_line,
    out_option,
    parse_override,
    scheduler_option,
    set_option,
    workers_option,
)


@click.command()
@click.argument("file", type=click.Path(dir_okay=False))
@out_option("output folder; rerun with the same folder to resume an interrupted sweep", required=True)
@workers_option()
@scheduler_option("sweep")
@click.option(
    "--batch-size",
    type=int,
    default=None,
    help="points per task [default: about 4 tasks per worker, at most 50 points]",
)
@click.option("--no-figures", is_flag=True, help="write the results table only")
def sweep(
    file: str,
    out: str,
    force: bool,
    workers: int | None,
    scheduler: str | None,
    batch_size: int | None,
    no_figures: bool,
) -> None:
    """Run a sweep (grid or Monte Carlo) of a scenario: one row of metrics per point, and figures.

    FILE is a sweep TOML: a base scenario and axes (lists, ranges or random distributions of
    dotted scenario keys); see `pmsm2dof.studies.sweep` for the format. Writes OUT/results.parquet,
    OUT/results.csv and OUT/figures/*.png once every point is done; finished points are kept
    under OUT/parts, so an interrupted sweep resumes where it stopped (a part damaged since, which
    its checksum shows, is deleted with a warning and its points run again). With --force, a
    folder of another sweep is started again from nothing, and other files in it are kept.
    """
    import warnings

    from ...sim.plausibility import warn_implausible
    from ...studies.engine import PartWarning
    from ...studies.sweep import load_sweep
    from ...studies.sweep_run import run_sweep
    from ..plots.sweep import draw_figures

    chosen = load_sweep(file)
    warn_implausible(chosen.base)
    with warnings.catch_warnings():
        show = warnings.showwarning

        def show_as_line(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
            if issubclass(category, PartWarning):
                print(f"pmsm2dof: warning: {one_line(message)}", file=sys.stderr)
            else:
                show(message, category, *args, **kwargs)

        warnings.simplefilter("always", PartWarning)
        warnings.showwarning = show_as_line
        try:
            run = run_sweep(
                chosen,
                out,
                workers=workers,
                scheduler=scheduler,
                batch_size=batch_size,
                figures=None if no_figures else draw_figures,
                force=force,
            )
        except ConfigError as exc:
            raise as_option(
                exc, {"workers": "--workers", "scheduler": "--scheduler", "batch_size": "--batch-size"}
            ) from None
    table = run.table
    stopped = table[table["status"] != "ok"]
    click.echo(
        f"{chosen.name}: {len(table)} points ({run.computed} simulated, {run.resumed} already done), "
        f"{len(stopped)} stopped by a SimulationError"
    )
    for _, row in stopped.head(5).iterrows():
        click.echo(f"  point {row['point']}: {row['error']}")
    _sweep_warnings(table)
    ranked = table[table[chosen.rank_by].notna()].sort_values(chosen.rank_by, ascending=False)
    for _, row in ranked.head(chosen.worst).iterrows():
        values = ", ".join(f"{key}={row[key]}" for key in chosen.keys)
        click.echo(f"  worst {chosen.rank_by} = {row[chosen.rank_by]:.4g} at point {row['point']}: {values}")
    click.echo(f"wrote results.parquet, results.csv and {len(run.files) - 2} figures to {out}")


def _sweep_warnings(table: "pd.DataFrame") -> None:
    """Name the points whose sampled loop is unstable or whose current command chatters (the first five)."""
    import pandas as pd

    from ...sim.metrics import CHATTER_SHARE_MAX

    unstable = table["sampled_loop_z_max"] >= 1.0
    chatter = table["run_chatter_share"] > CHATTER_SHARE_MAX
    flagged = table[(unstable | chatter).fillna(False)]
    if flagged.empty:
        return
    click.echo(
        f"  WARNING: {int(unstable.fillna(False).sum())} points with an unstable sampled loop (|z| >= 1), "
        f"{int(chatter.fillna(False).sum())} whose current command chatters: their figures describe a limit cycle"
    )
    for _, row in flagged.head(5).iterrows():
        z_max = row["sampled_loop_z_max"]
        pole = "not computed (see the notes)" if pd.isna(z_max) else f"{z_max:.4g}"
        click.echo(
            f"  point {row['point']}: largest closed-loop pole |z| = {pole}, "
            f"chatter share {row['run_chatter_share']:.3g}"
        )


#: Spec field or argument of autotune -> its option.
_AUTOTUNE_OPTIONS = {
    "max_overshoot_pct": "--max-overshoot-pct",
    "min_phase_margin_deg": "--min-phase-margin-deg",
    "min_gain_margin_dB": "--min-gain-margin-dB",
    "max_settling_s": "--max-settling-s",
    "max_load_dip_rpm_per_Nm": "--max-load-dip-rpm-per-Nm",
    "max_recovery_s": "--max-recovery-s",
    "max_current_limit_time_s": "--max-current-limit-time-s",
    "J_range": "--J-range",
    "feedforwards": "--feedforward",
    "anti_windups": "--anti-windup",
    "workers": "--workers",
    "scheduler": "--scheduler",
    "header": "--emit-c-header",
    "path": "--emit-c-header",
}


def _J_range(text: str) -> tuple[float, float]:
    """``LO,HI`` of --J-range as two floats (the Spec checks their range)."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return (float(parts[0]), float(parts[1]))
    except ValueError:
        raise ConfigError("--J-range", text, "LO,HI: two numbers, true over design inertia, e.g. 0.5,2") from None


@click.command(short_help="Find the anti-windup 2DOF design that rejects loads best within a specification.")
@click.argument("scenario", metavar="PRESET_OR_FILE")
@set_option("change a scenario key first (repeatable)")
@click.option("--max-overshoot-pct", type=float, default=None, help="largest overshoot of a reference step [%]")
@click.option("--min-phase-margin-deg", type=float, default=45.0, show_default=True, help="smallest phase margin [deg]")
@click.option(
    "--min-gain-margin-dB",
    "min_gain_margin_dB",
    type=float,
    default=6.0,
    show_default=True,
    help="smallest gain margin [dB]",
)
@click.option("--max-settling-s", type=float, default=None, help="longest settling time (2 %) of a reference step [s]")
@click.option(
    "--max-recovery-s", type=float, default=None, help="longest recovery time (2 % of the dip) of a load step [s]"
)
@click.option(
    "--max-load-dip-rpm-per-Nm",
    "max_load_dip_rpm_per_Nm",
    type=float,
    default=None,
    help="largest speed dip of a load step per Nm of load change [rpm/Nm]",
)
@click.option(
    "--max-current-limit-time-s", type=float, default=None, help="longest time at the current limit in one step [s]"
)
@click.option(
    "--J-range",
    "J_range",
    default="1,1",
    show_default=True,
    metavar="LO,HI",
    help="true inertia over the design inertia speed_controller.J_kgm2: the range the spec must hold over",
)
@click.option(
    "--feedforward",
    "feedforwards",
    multiple=True,
    help="a feedforward form the search may choose: lowpass, none, no_tau, full (repeatable) [default: the scenario's]",
)
@click.option(
    "--anti-windup",
    "anti_windups",
    multiple=True,
    help="an anti-windup the search may choose: none, back_calculation, clamping (repeatable) "
    "[default: the scenario's]",
)
@workers_option()
@scheduler_option("autotune")
@json_option("the summary")
@out_option(
    "folder for scenario.toml (the tuned scenario), autotune.json, pareto.csv, pareto.png, runs.csv, rejected.csv",
    default=None,
)
@click.option(
    "--emit-c-header",
    "header",
    type=click.Path(dir_okay=False),
    default=None,
    help="write a C header with the p2d_speed_config_t of the chosen design and the scenario's motor",
)
def autotune(
    scenario: str,
    overrides: tuple[str, ...],
    max_overshoot_pct: float | None,
    min_phase_margin_deg: float | None,
    min_gain_margin_dB: float | None,
    max_settling_s: float | None,
    max_recovery_s: float | None,
    max_load_dip_rpm_per_Nm: float | None,
    max_current_limit_time_s: float | None,
    J_range: str,
    feedforwards: tuple["Feedforward", ...],  # any strings from the command line: the Spec validates them
    anti_windups: tuple["AntiWindup", ...],
    workers: int | None,
    scheduler: str | None,
    as_json: bool,
    out: str | None,
    force: bool,
    header: str | None,
) -> None:
    """Autotune the speed controller of a scenario: the smallest worst-case load IAE per Nm (the
    dip and the recovery from it) that meets the specification at every inertia of --J-range, on
    the scenario's own steps.

    Searches alpha, zeta, m, Ka (and the feedforward and anti-windup forms given) with the
    analytic margins first, then the simulation engine (current limit and anti-windup included).
    Prints the chosen speed_controller keys (`--set speed_controller.KEY=VALUE` reproduces
    them) and their worst case. A candidate whose current command chatters is rejected; the
    summary says when the chosen design lies on a bound of the search, and when the scenario's
    own design has an unstable sampled loop. Exit status 0 when the design meets the
    specification, 1 when none does (the summary names the binding constraint and the miss), 2
    for bad input.
    """
    import json

    from ...sim.plausibility import warn_implausible
    from ...sim.scenario import load_scenario
    from ...studies.autotune import Spec
    from ...studies.autotune_outputs import run_autotune, summary
    from ..plots.autotune import plot_pareto

    try:
        spec = Spec(
            max_overshoot_pct=max_overshoot_pct,
            min_phase_margin_deg=min_phase_margin_deg,
            min_gain_margin_dB=min_gain_margin_dB,
            max_settling_s=max_settling_s,
            max_load_dip_rpm_per_Nm=max_load_dip_rpm_per_Nm,
            max_recovery_s=max_recovery_s,
            max_current_limit_time_s=max_current_limit_time_s,
            J_range=_J_range(J_range),
            feedforwards=feedforwards or None,
            anti_windups=anti_windups or None,
        )
        chosen = load_scenario(scenario)
        changes = dict(parse_override(text) for text in overrides)
        if changes:
            chosen = chosen.with_overrides(changes)
        warn_implausible(chosen)
        result = run_autotune(
            chosen,
            spec,
            out=out,
            force=force,
            header=header,
            figure=plot_pareto,
            workers=workers,
            scheduler=scheduler,
            progress=True,
        )
    except ConfigError as exc:
        raise as_option(exc, _AUTOTUNE_OPTIONS) from None
    click.echo(json.dumps(result.as_dict(), allow_nan=False) if as_json else summary(result, scenario, out, header))
    if not result.feasible:
        raise click.exceptions.Exit(1)
