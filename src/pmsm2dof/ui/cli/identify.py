"""``pmsm2dof identify mechanics | electrical | plan``: a drive from its logs (pmsm2dof.studies.identify_log,
on studies.identify and studies.electrical)."""

import math
from typing import Any

import click

from ...errors import ConfigError
from .options import Group, as_option, json_option, motor_option, out_option, parse_column

#: The modes of the former single command (a flag each) -> the sub-command now.
_FORMER_FLAGS = {"--plan": "plan", "--electrical": "electrical"}


class _Identify(Group):
    """``identify``: a sub-command first; the former ``identify LOG [--electrical | --plan]`` names it."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if args and args[0] not in self.commands and args[0] not in ctx.help_option_names:
            mode = next((name for flag, name in _FORMER_FLAGS.items() if flag in args), "mechanics")
            rest = " ".join(arg for arg in args if arg not in _FORMER_FLAGS)
            raise click.UsageError(f"identify takes a sub-command: use `pmsm2dof identify {mode} {rest}`".strip())
        return super().parse_args(ctx, args)


def _column_option(f: Any) -> Any:
    return click.option(
        "--column",
        "column_maps",
        multiple=True,
        metavar="SIGNAL=NAME",
        help="read a signal from another column, e.g. --column speed=enc_speed_rpm (the suffix gives the unit)",
    )(f)


@click.group(cls=_Identify)
def identify() -> None:
    """Identify a drive from logged runs: its mechanics, its electrical parameters, or the run to log."""


@identify.command(short_help="The inertia J, viscous and Coulomb friction (and tau_i) of a logged run.")
@click.argument("log", type=click.Path(dir_okay=False))
@_column_option
@click.option("--motor", "motor_file", type=click.Path(dir_okay=False), help="motor TOML (scenario or datasheet)")
@motor_option("pole_pairs", "(torque from the currents)")
@motor_option("psi_f_Wb")
@motor_option("Ld_H", "(default: Lq)")
@motor_option("Lq_H", "(default: Ld)")
@click.option(
    "--speed-period-mean",
    is_flag=True,
    help="the logged speed is the mean over each sampling period (encoder counts differenced)",
)
@click.option("--window-s", type=float, default=None, help="distance of the blocks of a regression row [s]")
@json_option()
@out_option("folder for fit.png, rows.csv, identified.toml")
@click.option(
    "--design", "design_text", default=None, metavar="ALPHA,ZETA", help="print the eq 9 gains for the J found"
)
def mechanics(
    log: str,
    column_maps: tuple[str, ...],
    motor_file: str | None,
    pole_pairs: int | None,
    psi_f_Wb: float | None,
    Ld_H: float | None,
    Lq_H: float | None,
    speed_period_mean: bool,
    window_s: float | None,
    as_json: bool,
    out: str | None,
    force: bool,
    design_text: str | None,
) -> None:
    """Identify the inertia J, viscous friction B and Coulomb friction of a logged run.

    LOG is a CSV, Parquet, NPZ or MAT file with time_s and speed_rpm (or speed_radps) and the
    torque: torque_Nm, or iq_A (and id_A) with the motor data (--motor FILE or --pole-pairs and
    --psi-f-Wb). With iq_ref_A in the log, the current loop's tau_i (eq 3) is identified too.
    Prints each value with its 95 % interval; --out DIR writes fit.png, rows.csv and
    identified.toml (the --motor scenario with the values found, or a [motor] table).
    """
    import json

    from ...studies.identify_log import mechanics_from_log
    from ..plots.identify import plot_fit

    design = None
    if design_text is not None:
        parts = design_text.split(",")
        try:
            alpha_radps, zeta = (float(p) for p in parts)
        except ValueError:
            raise ConfigError("--design", design_text, "ALPHA,ZETA: two numbers, e.g. 30,0.7") from None
        if not (alpha_radps > 0 and zeta > 0 and math.isfinite(alpha_radps) and math.isfinite(zeta)):
            raise ConfigError("--design", design_text, "ALPHA,ZETA both finite and > 0")
        design = (alpha_radps, zeta)
    if out is not None:
        from ...outputs import check_out

        check_out(out, "identify", force)
    motor = None
    if motor_file is not None:
        for option, value in (
            ("--pole-pairs", pole_pairs),
            ("--psi-f-Wb", psi_f_Wb),
            ("--Ld-H", Ld_H),
            ("--Lq-H", Lq_H),
        ):
            if value is not None:
                raise ConfigError(option, value, "absent when --motor gives the motor")
    elif pole_pairs is not None or psi_f_Wb is not None:
        if pole_pairs is None or psi_f_Wb is None:
            missing = "--pole-pairs" if pole_pairs is None else "--psi-f-Wb"
            raise ConfigError(missing, "<missing>", "given with the other motor options (or --motor FILE)")
        if pole_pairs < 1 or not (math.isfinite(psi_f_Wb) and psi_f_Wb > 0):
            bad = ("--pole-pairs", pole_pairs) if pole_pairs < 1 else ("--psi-f-Wb", psi_f_Wb)
            raise ConfigError(bad[0], bad[1], "> 0")
        Ld = Ld_H if Ld_H is not None else (Lq_H if Lq_H is not None else 0.0)
        motor = (pole_pairs, psi_f_Wb, Ld, Lq_H if Lq_H is not None else Ld)
    try:
        found = mechanics_from_log(
            log,
            dict(parse_column(text) for text in column_maps),
            motor_file=motor_file,
            motor=motor,
            window_s=window_s,
            speed_is_period_mean=speed_period_mean,
            design=design,
            out=out,
            force=force,
            figure=plot_fit,
        )
    except ConfigError as exc:
        raise as_option(exc, {"window_s": "--window-s"}) from None
    if as_json:
        click.echo(json.dumps(found.report, indent=2, allow_nan=False))
        return
    for line in found.lines():
        click.echo(line)


@identify.command(short_help="Rs, Ld, Lq and psi_f (eq 1) from the logged currents and voltages.")
@click.argument("log", type=click.Path(dir_okay=False))
@_column_option
@motor_option("pole_pairs", "(required)")
@click.option(
    "--voltage-delay-samples",
    type=int,
    default=0,
    help="the logged voltage applies this many samples after its row",
)
@click.option(
    "--angle-lead-samples",
    type=float,
    default=None,
    metavar="X",
    help="the drive holds the stator-frame voltage over a period, turned at the row's angle plus "
    "X w_e Ts (0.5: mid-period; 1.5 with --voltage-delay-samples 1: delay compensation); default: the logged "
    "voltage is the rotor-frame voltage over its period",
)
@click.option(
    "--dead-time",
    is_flag=True,
    help="fit the inverter's dead-time voltage per phase dead_time_V [V] with Rs (needs two current levels)",
)
@click.option(
    "--u-dc-V",
    "u_dc_V",
    type=float,
    default=None,
    help="DC-link voltage [V]; windows where the voltage magnitude reaches u_dc/sqrt(3) are left out "
    "(default: the log's u_dc_V column; a voltage_limited column is always used)",
)
@click.option(
    "--current-ranges",
    type=int,
    default=None,
    help="Ld and Lq per range of the current magnitude (1: none; default: 3 when the log's currents span "
    "more than a factor 2, else 1)",
)
@json_option()
@out_option("folder for fit.png, residuals.csv, motor.toml, identify.json (and ranges.csv)")
def electrical(
    log: str,
    column_maps: tuple[str, ...],
    pole_pairs: int | None,
    voltage_delay_samples: int,
    angle_lead_samples: float | None,
    dead_time: bool,
    u_dc_V: float | None,
    current_ranges: int | None,
    as_json: bool,
    out: str | None,
    force: bool,
) -> None:
    """Rs, Ld, Lq and psi_f (per phase, amplitude-invariant dq, eq 1) of a logged run.

    From id_A, iq_A, ud_V, uq_V and the speed, each with its 95 % interval; --out DIR writes
    fit.png (measured vs model voltages), residuals.csv, motor.toml (for design --motor) and
    identify.json (and ranges.csv with the fit per current range). When the log holds the
    controller's references (--voltage-delay-samples >= 1, --angle-lead-samples or --u-dc-V), windows
    at the inverter's voltage limit (a voltage_limited column, or a voltage magnitude at u_dc/sqrt(3)
    from --u-dc-V or a u_dc_V column) are left out; a log of applied voltages keeps them.
    """
    import json

    from ...studies.identify_log import electrical_from_log
    from ..plots.identify import plot_electrical_fit

    if pole_pairs is None or pole_pairs < 1:
        raise ConfigError("--pole-pairs", "<missing>" if pole_pairs is None else pole_pairs, "an integer >= 1")
    if out is not None:
        from ...outputs import check_out

        check_out(out, "identify-electrical", force)
    options = ("--voltage-delay-samples", "--angle-lead-samples", "--dead-time", "--u-dc-V", "--current-ranges")
    try:
        found = electrical_from_log(
            log,
            dict(parse_column(text) for text in column_maps),
            pole_pairs,
            voltage_delay_samples=voltage_delay_samples,
            angle_lead_samples=angle_lead_samples,
            dead_time=dead_time,
            u_dc_V=u_dc_V,
            current_ranges=current_ranges,
            out=out,
            force=force,
            figure=plot_electrical_fit,
        )
    except ConfigError as exc:
        # the library names its arguments; the user typed options
        raise as_option(exc, {name[2:].replace("-", "_"): name for name in options}) from None
    if as_json:
        click.echo(json.dumps(found.report, indent=2, allow_nan=False))
        return
    for line in found.lines():
        click.echo(line)


@identify.command(short_help="The run to play on the drive and log: speed steps for a scenario's J guess.")
@click.option("--motor", "motor_file", type=click.Path(dir_okay=False), help="the drive's scenario (its J guess)")
@click.option("--speed-max-rpm", type=float, default=None, help="largest speed of the steps [rpm]")
@motor_option("i_max_A", "(default: the scenario's)")
@out_option("folder for plan.toml, trace.csv and plot.png")
def plan(
    motor_file: str | None, speed_max_rpm: float | None, i_max_A: float | None, out: str | None, force: bool
) -> None:
    """Write the run to play on the drive and log for identify mechanics.

    Speed steps within --speed-max-rpm and the current limit for the --motor scenario's J guess:
    plan.toml (the scenario), its simulation trace.csv and plot.png, written to --out.
    """
    from ...studies.identify_log import plan_run
    from ..plots.trace import plot_trace

    if motor_file is None or speed_max_rpm is None or out is None:
        missing = "--motor" if motor_file is None else "--speed-max-rpm" if speed_max_rpm is None else "--out"
        raise ConfigError(missing, "<missing>", "given to identify plan")
    try:
        planned = plan_run(motor_file, speed_max_rpm, i_max_A, out, force, plot_trace)
    except ConfigError as exc:
        raise as_option(exc, {"speed_max_rpm": "--speed-max-rpm", "limits.i_max_A": "--i-max-A"}) from None
    for line in planned.lines():
        click.echo(line)
