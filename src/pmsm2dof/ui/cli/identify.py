"""``pmsm2dof identify mechanics | electrical | plan``: a drive from its logs (pmsm2dof.studies.identify,
studies.electrical)."""

import math
from typing import TYPE_CHECKING, Any

import click

from ...errors import ConfigError

if TYPE_CHECKING:
    from pathlib import Path

    from ...studies.electrical import Electrical
    from ...studies.identify import CurrentLoop, Mechanics

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

    from ...core.gains import pi_gains
    from ...core.motor import load_motor
    from ...outputs import staged_dir
    from ...sim.logs import read_log
    from ...studies.identify import (
        IdentificationError,
        identified_toml,
        identify_mechanics,
        identify_tau_i,
        torque_from_currents,
    )

    gains = None
    if design_text is not None:
        parts = design_text.split(",")
        try:
            alpha_radps, zeta = (float(p) for p in parts)
        except ValueError:
            raise ConfigError("--design", design_text, "ALPHA,ZETA: two numbers, e.g. 30,0.7") from None
        if not (alpha_radps > 0 and zeta > 0 and math.isfinite(alpha_radps) and math.isfinite(zeta)):
            raise ConfigError("--design", design_text, "ALPHA,ZETA both finite and > 0")
    if out is not None:
        from ...outputs import check_out

        check_out(out, "identify", force)
    if motor_file is not None:
        for option, value in (
            ("--pole-pairs", pole_pairs),
            ("--psi-f-Wb", psi_f_Wb),
            ("--Ld-H", Ld_H),
            ("--Lq-H", Lq_H),
        ):
            if value is not None:
                raise ConfigError(option, value, "absent when --motor gives the motor")
    columns = dict(parse_column(text) for text in column_maps)
    measured = read_log(log, columns)
    motor_data = None
    if motor_file is not None:
        motor_data = load_motor(motor_file)
    torque = None
    if motor_data is not None or pole_pairs is not None or psi_f_Wb is not None:
        if motor_data is None:
            if pole_pairs is None or psi_f_Wb is None:
                missing = "--pole-pairs" if pole_pairs is None else "--psi-f-Wb"
                raise ConfigError(missing, "<missing>", "given with the other motor options (or --motor FILE)")
            if pole_pairs < 1 or not (math.isfinite(psi_f_Wb) and psi_f_Wb > 0):
                bad = ("--pole-pairs", pole_pairs) if pole_pairs < 1 else ("--psi-f-Wb", psi_f_Wb)
                raise ConfigError(bad[0], bad[1], "> 0")
            Ld = Ld_H if Ld_H is not None else (Lq_H if Lq_H is not None else 0.0)
            Lq = Lq_H if Lq_H is not None else Ld
            torque = torque_from_currents(measured, pole_pairs, psi_f_Wb, Ld, Lq)
        else:
            m = motor_data
            torque = torque_from_currents(measured, m.pole_pairs, m.psi_f_Wb, m.Ld_H, m.Lq_H)
    try:
        mech = identify_mechanics(measured, torque_Nm=torque, window_s=window_s, speed_is_period_mean=speed_period_mean)
    except ConfigError as exc:
        raise as_option(exc, {"window_s": "--window-s"}) from None
    current = None
    if measured.iq_ref_A is not None and measured.iq_A is not None:
        try:
            current = identify_tau_i(measured)
        except IdentificationError as exc:
            mech = dataclasses_replace_notes(mech, f"tau_i: {exc}")
    if design_text is not None:
        gains = pi_gains(mech.J_kgm2, alpha_radps, zeta)
    report = mech.to_json()
    if current is not None:
        report.update(tau_i_s=current.tau_i_s, tau_i_s_ci=list(current.tau_i_s_ci), tau_i_n_rows=current.n_rows)
    if gains is not None:
        report["design"] = {"alpha_radps": alpha_radps, "zeta": zeta, "Kp": gains[0], "Ki": gains[1]}
    if out is not None:
        from ...sim.scenario import Scenario, load_scenario

        scenario: Scenario | None = None
        if motor_file is not None:
            try:
                scenario = load_scenario(motor_file)
            except ConfigError:
                scenario = None
        text = identified_toml(mech, current, scenario, f"{log} by pmsm2dof identify mechanics")
        with staged_dir(out, "identify", force) as tmp:
            write_mechanics(tmp, mech, text, report)
    if as_json:
        click.echo(json.dumps(report, indent=2, allow_nan=False))
        return
    echo_mechanics(mech, current, report)
    if gains is not None:
        click.echo(
            f"eq 9 with alpha = {alpha_radps:g} rad/s, zeta = {zeta:g}: Kp = {gains[0]:.6g}, Ki = {gains[1]:.6g}"
        )
    if out is not None:
        click.echo(f"wrote fit.png, rows.csv, identified.toml and identify.json to {out}")


def write_mechanics(folder: Any, mech: "Mechanics", identified: str, report: dict[str, Any]) -> None:
    """The outputs of identify mechanics into ``folder``: fit.png, rows.csv, identified.toml, identify.json."""
    import json

    import numpy as np

    from ...outputs import atomic_write
    from ..plots.identify import plot_fit

    plot_fit(mech, folder / "fit.png")
    rows = mech.rows
    table = np.column_stack([rows["t_s"], rows["y"], rows["fit"], rows["y"] - rows["fit"], rows["kept"]])
    body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
    atomic_write(folder / "rows.csv", "t_s,torque_mean_Nm,fit_Nm,residual_Nm,kept\n" + body + "\n")
    atomic_write(folder / "identified.toml", identified)
    atomic_write(folder / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")


def echo_mechanics(mech: "Mechanics", current: "CurrentLoop | None", report: dict[str, Any]) -> None:
    """Print what identify mechanics found: each value with its 95 % interval, the fit, its notes."""
    for name, unit in (("J_kgm2", "kg m^2"), ("B_Nms", "Nm s/rad"), ("T_coulomb_Nm", "Nm")):
        lo, hi = report[f"{name}_ci"]
        click.echo(f"{name:<13} = {report[name]:<11.5g} 95 % interval [{lo:.5g}, {hi:.5g}] {unit}")
    if current is not None:
        lo, hi = current.tau_i_s_ci
        click.echo(f"{'tau_i_s':<13} = {current.tau_i_s:<11.5g} 95 % interval [{lo:.5g}, {hi:.5g}] s")
    click.echo(
        f"fit: {mech.n_rows} rows of {mech.window_s:.3g} s ({mech.n_samples} samples), "
        f"residual {mech.residual_rms_Nm:.3g} Nm rms, {mech.n_rows_excluded} rows excluded"
    )
    for note in mech.notes:
        click.echo(f"note: {note}")


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

    from ...sim.logs import read_log
    from ...studies.electrical import identify_electrical

    options: dict[str, Any] = {
        "--voltage-delay-samples": voltage_delay_samples or None,
        "--angle-lead-samples": angle_lead_samples,
        "--dead-time": dead_time or None,
        "--u-dc-V": u_dc_V,
        "--current-ranges": current_ranges,
    }
    if pole_pairs is None or pole_pairs < 1:
        raise ConfigError("--pole-pairs", "<missing>" if pole_pairs is None else pole_pairs, "an integer >= 1")
    if out is not None:
        from ...outputs import check_out

        check_out(out, "identify-electrical", force)
    columns = dict(parse_column(text) for text in column_maps)
    measured = read_log(log, columns)
    try:
        fit = identify_electrical(
            measured,
            pole_pairs,
            voltage_delay_samples=options["--voltage-delay-samples"] or 0,
            angle_lead_samples=options["--angle-lead-samples"],
            dead_time=bool(options["--dead-time"]),
            u_dc_V=options["--u-dc-V"],
            current_ranges=options["--current-ranges"],
        )
    except ConfigError as exc:
        # the library names its arguments; the user typed options
        raise as_option(exc, {name[2:].replace("-", "_"): name for name in options}) from None
    report = fit.to_json()
    if out is not None:
        from ...outputs import staged_dir

        with staged_dir(out, "identify-electrical", force) as tmp:
            write_electrical(tmp, fit, pole_pairs, log)
    if as_json:
        click.echo(json.dumps(report, indent=2, allow_nan=False))
        return
    echo_electrical(fit)
    if out is not None:
        written = "fit.png, residuals.csv, " + ("ranges.csv, " if fit.ranges else "")
        click.echo(f"wrote {written}motor.toml and identify.json to {out}")


def write_electrical(folder: "Path", fit: "Electrical", pole_pairs: int, source: str) -> None:
    """What identify electrical writes into ``folder``: fit.png (measured vs model voltages), residuals.csv,
    motor.toml (for design --motor; ``source`` names the log), identify.json and, with current ranges, ranges.csv."""
    import json

    import numpy as np

    from ...outputs import atomic_write
    from ..plots.identify import plot_electrical_fit

    report = fit.to_json()
    range_names = ["i_low_A", "i_high_A", "n_windows", "Ld_H", "Ld_H_low", "Ld_H_high", "Lq_H", "Lq_H_low", "Lq_H_high"]

    def range_row(r: dict[str, Any]) -> list[float]:
        row = [r["i_low_A"], r["i_high_A"], r["n_windows"]]
        for name in ("Ld_H", "Lq_H"):
            row += [math.nan, math.nan, math.nan] if r[name] is None else [r[name], *r[f"{name}_ci"]]
        return row

    rows = fit.rows
    names = ["t_s", "ud_V", "ud_fit_V", "uq_V", "uq_fit_V"]
    table = np.column_stack([rows[n] for n in names])
    body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
    ranges = "".join(",".join(f"{v:.9g}" for v in range_row(r)) + "\n" for r in report["ranges"])
    plot_electrical_fit(fit, folder / "fit.png")
    atomic_write(folder / "residuals.csv", ",".join(names) + "\n" + body + "\n")
    if fit.ranges:
        atomic_write(folder / "ranges.csv", ",".join(range_names) + "\n" + ranges)
    atomic_write(folder / "motor.toml", fit.motor_toml(pole_pairs, source))
    atomic_write(folder / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")


def echo_electrical(fit: "Electrical") -> None:
    """Print what identify electrical found: each value with its 95 % interval, the fit, its ranges, its notes."""
    from ...studies.electrical import DEAD_TIME, PARAMETERS

    report = fit.to_json()
    units = {"Rs_ohm": "ohm", "Ld_H": "H", "Lq_H": "H", "psi_f_Wb": "Wb", DEAD_TIME: "V per phase"}
    for name in (*PARAMETERS, DEAD_TIME):
        if name in fit.ci:
            lo, hi = fit.ci[name]
            click.echo(f"{name:<11} = {report[name]:<11.5g} 95 % interval [{lo:.5g}, {hi:.5g}] {units[name]}")
    click.echo(
        f"fit: {fit.n_windows} windows ({fit.n_samples} samples), residual {fit.residual_rms_V:.3g} V rms "
        "(per phase, amplitude-invariant dq, eq 1)"
    )
    if fit.n_samples_voltage_limited is not None:
        click.echo(
            f"voltage limit: {fit.n_samples_voltage_limited} samples at the limit, "
            f"{fit.n_windows_voltage_limited} windows that touch them left out"
        )
    if fit.ranges:
        click.echo("per current range (Rs, psi_f common):")
        click.echo(f"  {'|i_dq| [A]':<15} {'Ld [mH]':<24} {'Lq [mH]':<24} windows")

        def cell(r: dict[str, Any], name: str) -> str:
            if r[name] is None:
                return "not determined"
            lo, hi = r[f"{name}_ci"]
            return f"{r[name] * 1e3:.4g} [{lo * 1e3:.4g}, {hi * 1e3:.4g}]"

        for r in report["ranges"]:
            span = f"{r['i_low_A']:.3g} to {r['i_high_A']:.3g}"
            click.echo(f"  {span:<15} {cell(r, 'Ld_H'):<24} {cell(r, 'Lq_H'):<24} {r['n_windows']}")
    for note in fit.notes:
        click.echo(f"note: {note}")


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
    from ...outputs import atomic_write, staged_dir
    from ...sim.scenario import load_scenario
    from ...sim.simulate import simulate as run_simulation
    from ...studies.identify import plan_experiment
    from ..plots import trace

    if motor_file is None or speed_max_rpm is None or out is None:
        missing = "--motor" if motor_file is None else "--speed-max-rpm" if speed_max_rpm is None else "--out"
        raise ConfigError(missing, "<missing>", "given to identify plan")
    try:
        chosen = plan_experiment(load_scenario(motor_file), speed_max_rpm, i_max_A)
    except ConfigError as exc:
        raise as_option(exc, {"speed_max_rpm": "--speed-max-rpm", "limits.i_max_A": "--i-max-A"}) from None
    with staged_dir(out, "identify-plan", force) as tmp:
        result = run_simulation(chosen)
        result.save(tmp / "trace.csv")
        trace.plot_trace(result, tmp / "plot.png")
        atomic_write(tmp / "plan.toml", chosen.to_toml())
    for entry in chosen.reference:
        click.echo(f"  t = {entry.t_s:8.4g} s: speed reference {entry.speed_rpm:8.5g} rpm")
    i_limit = chosen.limits.i_max_A
    click.echo(
        f"simulated with J = {chosen.speed_controller.J_kgm2:g} kg m^2: |speed| <= "
        f"{abs(result.speed_rpm).max():.5g} rpm, |iq| <= {abs(result.iq_A).max():.4g} A (limit {i_limit:g} A), "
        f"at the voltage limit {100 * float(result.voltage_limited.mean()):.3g} % of the time, {result.t_s[-1]:g} s"
    )
    click.echo(f"wrote plan.toml, trace.csv and plot.png to {out}: play plan.toml's reference on the drive, log it")


def dataclasses_replace_notes(mech: "Mechanics", note: str) -> "Mechanics":
    """``mech`` with one more note."""
    import dataclasses

    return dataclasses.replace(mech, notes=(*mech.notes, note))
