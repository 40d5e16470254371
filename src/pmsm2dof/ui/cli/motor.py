"""``pmsm2dof motor``: the per-phase model of a motor given in datasheet units (pmsm2dof.core.motor)."""

import math
from typing import Any

import click

from .options import json_option


def _motor_help() -> str:
    """The help of `pmsm2dof motor`: what it prints and every key of [motor.datasheet]."""
    import textwrap

    from ...core.motor import DATASHEET_KEYS

    keys = "\n".join(
        textwrap.fill(f"{key}: {doc}", width=76, initial_indent="  ", subsequent_indent="      ")
        for key, (_, doc) in DATASHEET_KEYS.items()
    )
    return (
        "Print the model parameters of eq 1 of a motor given in datasheet units, with their source.\n\n"
        "FILE is a TOML file (a scenario, one with only [motor], or an identified motor.toml) whose "
        "[motor.datasheet] table gives the datasheet's values; without it the model keys of [motor] are shown "
        "as given. Kt and Ke (or Kv), when both are given, are checked against each other. With [limits] "
        "u_dc_V in the file, the no-load speed the DC link allows is shown too.\n\n"
        "\b\nKeys of [motor.datasheet] (pmsm2dof.core.motor):\n" + keys
    )


class _MotorCommand(click.Command):
    """`pmsm2dof motor`, its help written when shown (the datasheet keys are core's: numpy and the extension)."""

    def format_help_text(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        self.help = _motor_help()
        super().format_help_text(ctx, formatter)


@click.command(cls=_MotorCommand, short_help="The per-phase model of a motor given in datasheet units.")
@click.argument("file", type=click.Path(dir_okay=False))
@json_option()
def motor(file: str, as_json: bool) -> None:
    import json

    from ...core.motor import MOTOR_KEYS, RATING_KEYS, load_motor, no_load_speed_radps
    from ...errors import require_positive
    from ...inputs import read_toml

    m = load_motor(file)
    keys = [*MOTOR_KEYS, "kt_Nm_per_A"] + [key for key in RATING_KEYS if getattr(m, key) is not None]
    sources = {**m.sources, "kt_Nm_per_A": "1.5 p psi_f (amplitude-invariant dq, eq 1)"}
    limits = read_toml(file, "motor file").get("limits")
    u_dc = limits.get("u_dc_V") if isinstance(limits, dict) else None
    extra: dict[str, float] = {}
    notes = list(m.notes)
    if u_dc is not None:
        u_dc = require_positive("limits.u_dc_V", u_dc)
        extra["no_load_rpm"] = no_load_speed_radps(u_dc, m.pole_pairs, m.psi_f_Wb) * 30.0 / math.pi
        sources["no_load_rpm"] = f"u_dc / (sqrt(3) p psi_f) at limits.u_dc_V = {u_dc:g} V (space-vector modulation)"
        if m.commutation == "block":
            # block: the mean DC-side back-EMF kM w_m meets u_dc, kM = (3 sqrt(3)/pi) p psi_f (pmsm2dof.core.motor)
            notes.append(
                f"block commutation reaches u_dc / kM = {extra['no_load_rpm'] * math.pi / 3.0:.5g} rpm at no load, "
                "pi/3 times more (the datasheet's no-load speed is this, less the drop of the no-load current)"
            )
    if as_json:
        out: dict[str, Any] = {key: getattr(m, key) for key in keys} | extra
        out["sources"] = {key: sources[key] for key in (*keys, *extra)}
        out["notes"] = notes
        click.echo(json.dumps(out, indent=2))
        return
    values = {key: getattr(m, key) for key in keys} | extra
    for key, value in values.items():
        click.echo(f"{key:<12} = {value:<12.6g}  from {sources.get(key, '')}")
    for note in notes:
        click.echo(f"note: {note}")
