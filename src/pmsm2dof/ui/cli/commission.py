"""``pmsm2dof commission``: the C commissioning routine against a scenario's motor (pmsm2dof.sim.commission)."""

import math
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    from ...sim.commission import Commissioning

from .options import json_option, out_option, parse_override, set_option


@click.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@set_option("change a scenario key, e.g. --set commissioning.dead_time_V=1.5 (repeatable; values are TOML literals)")
@json_option()
@out_option(
    "folder for result.json, log.csv, plot.png, motor.toml (the identified motor, for design --motor) and "
    "p2d_config.h (the scenario's controllers for the identified motor)"
)
def commission(scenario: str, overrides: tuple[str, ...], as_json: bool, out: str | None, force: bool) -> None:
    """Run the C commissioning routine (commission.h) against a scenario's simulated motor.

    The routine identifies Rs, Ld, Lq and psi_f as on the drive; the table compares them with
    the scenario's true values and gives the simulated time of each step. The routine's settings
    and the simulated inverter's dead time and current noise are the scenario's [commissioning]
    keys (`pmsm2dof presets --keys`). A failed run names the step and why, and exits with 1.
    """
    import json

    from ...outputs import check_out, staged_dir
    from ...sim.commission import commission as run_commissioning
    from ...sim.scenario import load_scenario

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    if out is not None:
        check_out(out, "commission", force)
    result = run_commissioning(chosen)
    summary = result.to_dict()
    if out is not None:
        with staged_dir(out, "commission", force) as tmp:
            write_commission(result, chosen.motor.pole_pairs, tmp)
            if result.phase == "done":
                _commissioned_header(chosen, result, tmp / "p2d_config.h")
    if as_json:
        click.echo(json.dumps(summary, allow_nan=False))
    else:
        click.echo(_commission_table(result))
        if out is not None:
            written = "result.json, log.csv, plot.png" + (
                ", motor.toml and p2d_config.h" if result.phase == "done" else ""
            )
            click.echo(f"wrote {written} to {out}")
    if result.phase != "done":
        raise click.exceptions.Exit(1)


def write_commission(result: "Commissioning", pole_pairs: int, folder: Any) -> None:
    """The report of a commissioning into ``folder``: result.json, log.csv, plot.png and, when it ended done,
    motor.toml (the identified motor)."""
    import json

    from ...outputs import atomic_write
    from ..plots.commission import plot_commission

    atomic_write(folder / "result.json", json.dumps(result.to_dict(), indent=2, allow_nan=False) + "\n")
    atomic_write(folder / "log.csv", result.log_csv())
    plot_commission(result, folder / "plot.png")
    if result.phase == "done":
        atomic_write(folder / "motor.toml", result.motor_toml(pole_pairs))


def _commissioned_header(scenario: Any, result: "Commissioning", path: Any) -> None:
    """The scenario's controllers configured with the identified motor (studies.configuration)."""
    from ...studies.configuration import configuration

    identified = scenario.with_overrides({f"motor.{key}": value for key, value in result.estimates.items()})
    notes = ("The motor's Rs, Ld, Lq and psi_f are those the commissioning identified.",)
    configuration(identified, source=f"pmsm2dof commission {scenario.name!r}", notes=notes).write_header(path)


def _commission_table(result: "Commissioning") -> str:
    from ...sim.commission import TARGETS

    units = {"Rs_ohm": "ohm", "Ld_H": "H", "Lq_H": "H", "psi_f_Wb": "Wb"}
    lines = [f"{result.scenario}: commissioning {result.phase}"]
    if result.phase != "done":
        lines.append(f"  failed in {result.failed_phase}: {result.reason} ({result.reason_text})")
    lines.append(f"  {'':<9}{'identified':>13}{'true':>13}{'error':>10}{'target':>9}")
    for key, error in result.errors.items():
        lines.append(
            f"  {key:<9}{result.estimates[key]:>13.6g}{result.truth[key]:>13.6g}"
            f"{_percent(error):>10}{TARGETS[key] * 100:>8g}%  [{units[key]}]"
        )
    lines.append("  step        time [s]")
    for phase, t in result.phase_time_s.items():
        lines.append(f"  {phase:<12}{t:>8.4g}")
    lines.append(f"  {'total':<12}{sum(result.phase_time_s.values()):>8.4g}")
    return "\n".join(lines)


def _percent(x: float) -> str:
    return f"{x * 100:.3f}%" if math.isfinite(x) else "n/a"
