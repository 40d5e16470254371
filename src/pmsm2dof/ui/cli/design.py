"""``pmsm2dof design`` and ``pmsm2dof bode``: the speed controller of eq 9-15 (pmsm2dof.analysis)."""

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import click

from ...errors import ConfigError

if TYPE_CHECKING:
    from ...analysis.current_loop import CurrentLoopDesign
    from ...analysis.sensor import DelayModel
    from ...core.bindings import AntiWindup, Feedforward, Method
    from ...core.motor import Motor
    from ...studies.speed_design import SpeedDesign

from .options import as_option, held_warnings, json_option, motor_option, option_name, speed_option


@click.command()
@speed_option("J_kgm2", required=True)
@speed_option("alpha_radps", required=True)
@speed_option("zeta", required=True)
@speed_option("m", default=1.0, show_default=True)
@speed_option("tau_i_s", default=0.0, show_default=True)
@speed_option("Ts_s", required=True)
@click.option(
    "--method",
    default="tustin",
    show_default=True,
    help="discretization (Table 1): forward_euler, backward_euler or tustin",
)
@click.option(
    "--feedforward",
    default="lowpass",
    show_default=True,
    help="lowpass (eq 13/15, the paper's 2DOF controller; needs m = 1), none (1DOF PI), "
    "no_tau (eq 11 with tau_i = 0) or full (eq 11); for m != 1 choose no_tau or full",
)
@click.option("--anti-windup", default="back_calculation", show_default=True, help="none, back_calculation or clamping")
@speed_option("Ka", default=None)
@click.option(
    "--sensor",
    "sensor_model",
    default="ideal",
    show_default=True,
    help="speed sensor: ideal (the speed, sampled) or encoder (counted angle increments)",
)
@click.option("--estimator", default="difference", show_default=True, help="encoder speed estimator: difference or pll")
@click.option("--sensor-bandwidth-radps", type=float, default=0.0, help="PLL double pole [rad/s] (pll)")
@click.option(
    "--sensor-lowpass-radps",
    type=float,
    default=0.0,
    show_default=True,
    help="first-order low-pass on the measured speed [rad/s]; 0: none",
)
@click.option("--sensor-delay-s", type=float, default=0.0, show_default=True, help="delay of the reading [s]")
@click.option(
    "--delay",
    "delay_model",
    default="exact",
    show_default=True,
    help="the delay in the continuous margins: exact (exp(-sT)) or pade (its approximant, as in poles and steps)",
)
@click.option(
    "--phase-margin-deg",
    type=float,
    default=None,
    help="also report the largest alpha that keeps this phase margin [deg] with the sensor chain",
)
@json_option()
@click.option(
    "--emit-c-header",
    "header",
    type=click.Path(dir_okay=False),
    default=None,
    help="write the C configuration of this design and its motor (as pmsm2dof header: the firmware's p2d_config.h)",
)
@click.option("--prefix", default="p2d_config", show_default=True, help="C identifier prefix in the header")
@motor_option("i_max_A", "(header)")
@motor_option("pole_pairs", "(header), Te = 1.5 p psi_f iq (the paper's p0, called there the number of poles)")
@motor_option("psi_f_Wb", "(header)")
@motor_option("Ld_H", "(header)")
@motor_option("Lq_H", "(header) [default: Ld, surface PMSM]")
@motor_option("Rs_ohm", "(header: the current controller)")
@motor_option("Ts_current_s", "(header), Ts / N")
@click.option(
    "--paper-drive",
    is_flag=True,
    help="header: take the motor data not given from the paper's drive (the preset "
    "paper-condition-1), placeholders rather than your motor's",
)
@click.option(
    "--motor",
    "motor_file",
    type=click.Path(dir_okay=False),
    default=None,
    help="motor file: a scenario, a [motor.datasheet] file or an identified motor.toml (commission --out, identify "
    "electrical --out): the header's motor data not given, and the rotor inertia and currents --J-kgm2 and "
    "--i-max-A are checked against",
)
@click.option(
    "--current-bandwidth-radps",
    "alpha_c_radps",
    type=float,
    default=None,
    help="with --motor: current loop Kp = L alpha_c, Ki = Rs alpha_c [rad/s]; tau_i = 1/alpha_c (replaces --tau-i-s)",
)
@click.option(
    "--fixed-point",
    "fixed_point",
    default=None,
    help="also check the design in the fixed-point controller: q15 (Cortex-M0) or q31 (Cortex-M3); needs the "
    "two full scales",
)
@click.option(
    "--speed-full-scale-rpm", type=float, default=None, help="--fixed-point: speed of the integer 2^N [rpm], > 0"
)
@click.option(
    "--torque-full-scale-Nm",
    "torque_full_scale_Nm",
    type=float,
    default=None,
    help="--fixed-point: torque of the integer 2^N [Nm], >= the torque limit",
)
def design(
    J_kgm2: float,
    alpha_radps: float,
    zeta: float,
    m: float,
    tau_i_s: float,
    Ts_s: float,
    method: "Method",  # any string from the command line: the library validates the choices
    feedforward: "Feedforward",
    anti_windup: "AntiWindup",
    Ka: float | None,
    sensor_model: str,
    estimator: str,
    sensor_bandwidth_radps: float,
    sensor_lowpass_radps: float,
    sensor_delay_s: float,
    delay_model: "DelayModel",
    phase_margin_deg: float | None,
    as_json: bool,
    header: str | None,
    prefix: str,
    i_max_A: float | None,
    pole_pairs: int | None,
    psi_f_Wb: float | None,
    Ld_H: float | None,
    Lq_H: float | None,
    Rs_ohm: float | None,
    Ts_current_s: float | None,
    paper_drive: bool,
    motor_file: str | None,
    alpha_c_radps: float | None,
    fixed_point: str | None,
    speed_full_scale_rpm: float | None,
    torque_full_scale_Nm: float | None,
) -> None:
    """Design the speed controller (eq 9-15): gains, poles, margins, bandwidth, coefficients.

    The speed the controller reads may pass through a sensor chain (--sensor, --estimator,
    --sensor-bandwidth-radps, --sensor-lowpass-radps, --sensor-delay-s): the loop gain becomes F G H, and
    the margins, poles, overshoot and the discrete loop include it; --phase-margin-deg reports the
    largest alpha that keeps that margin with it.

    With --emit-c-header the header (the whole configuration, as `pmsm2dof header` writes it)
    needs the motor data and the current loop: --i-max-A, --pole-pairs, --psi-f-Wb, --Ld-H (--Lq-H for a
    salient motor), --Rs-ohm and --Ts-current-s (Ts an integer multiple of it), or --paper-drive to
    take what is not given from the paper's drive. The summary says where each value came from.

    --fixed-point q15|q31 with --speed-full-scale-rpm and --torque-full-scale-Nm adds the scaling check
    of the fixed-point controller (docs/mcu.md, "No FPU"): each coefficient's quantisation error, the
    integrator's dead zone, the headroom of the states and the scalings or Ts that remove a dead zone.
    """
    import json
    import warnings

    from ...sim.plausibility import PlausibilityWarning, current_findings, inertia_findings
    from ...studies.speed_design import speed_design
    from ..fixedpoint import design_scaling_check, report_dict

    with held_warnings():
        file_motor = None if motor_file is None else _load_motor(motor_file)
        loop = _identified_current_loop(file_motor, alpha_c_radps, tau_i_s, Ts_current_s)
        if file_motor is not None:
            findings = inertia_findings("--J-kgm2", J_kgm2, file_motor.J_rotor_kgm2)
            if i_max_A is not None:
                findings += current_findings("--i-max-A", i_max_A, file_motor.i_rated_A, file_motor.i_peak_A)
            for text in findings:
                warnings.warn(f"{text} (motor file {motor_file})", PlausibilityWarning, stacklevel=1)
        if loop is not None:
            tau_i_s = loop.tau_i_s
        if header is not None:
            motor, sources = _header_motor(
                dict(
                    i_max_A=i_max_A,
                    pole_pairs=pole_pairs,
                    psi_f_Wb=psi_f_Wb,
                    Ld_H=Ld_H,
                    Lq_H=Lq_H,
                    Rs_ohm=Rs_ohm,
                    Ts_current_s=Ts_current_s,
                ),
                file_motor,
                motor_file,
                paper_drive,
            )
        options = {name: option_name(name) for name in ("J_kgm2", "alpha_radps", "zeta", "m", "tau_i_s", "Ts_s", "Ka")}
        options |= {"method": "--method", "feedforward": "--feedforward", "anti_windup": "--anti-windup"}
        options |= {"model": "--sensor", "estimator": "--estimator", "delay": "--delay"}
        options |= {name: option_name("sensor_" + name) for name in ("bandwidth_radps", "lowpass_radps", "delay_s")}
        options["phase_margin_deg"] = "--phase-margin-deg"
        try:
            result = speed_design(
                J_kgm2,
                alpha_radps,
                zeta,
                m=m,
                tau_i_s=tau_i_s,
                Ts_s=Ts_s,
                method=method,
                feedforward=feedforward,
                anti_windup=anti_windup,
                Ka=Ka,
                sensor=dict(
                    model=sensor_model,
                    estimator=estimator,
                    bandwidth_radps=sensor_bandwidth_radps,
                    lowpass_radps=sensor_lowpass_radps,
                    delay_s=sensor_delay_s,
                ),
                delay_model=delay_model,
                phase_margin_deg=phase_margin_deg,
                current_loop=loop,
            )
        except ConfigError as exc:
            raise as_option(exc, options) from None
        scaling = design_scaling_check(
            result.design,
            Ts_s,
            method,
            fixed_point,
            speed_full_scale_rpm,
            torque_full_scale_Nm,
            i_max_A,
            pole_pairs,
            psi_f_Wb,
        )
    if header is not None:
        from ...studies.configuration import DESIGN_MOTOR, configuration, design_scenario

        notes = ("Motor data and current loop given to design:",) + tuple(
            f"  {name:<12} = {motor[name]:g} {DESIGN_MOTOR[name][0]} ({source})" for name, source in sources.items()
        )
        try:
            config = configuration(design_scenario(result.discrete, **motor), source="pmsm2dof design", notes=notes)
            config.write_header(header, prefix)
        except ConfigError as exc:
            raise as_option(exc, _header_keys()) from None
    if as_json:
        data = result.as_dict()
        if header is not None:
            data["header"] = {
                "path": header,
                "motor": {name: {"value": motor[name], "source": sources[name]} for name in sources},
            }
        data |= result.current_loop_dict()
        if scaling is not None:
            data["fixed_point"] = report_dict(scaling)
        click.echo(json.dumps(data))
        return
    click.echo(_table(result.design_rows()))
    if phase_margin_deg is not None:
        click.echo(
            f"\nLargest alpha keeping a phase margin of {phase_margin_deg:g} deg (zeta, tau_i and sensor kept): "
            f"{result.alpha_max_radps:.6g} rad/s"
        )
    if loop is not None:
        click.echo(_current_loop_table(result, loop, motor_file))
    if scaling is not None:
        click.echo("\n" + scaling.text())
    if header is not None:
        click.echo(f"\nC header written to {header}, with the motor data")
        width = max(len(name) for name in sources)
        for name, source in sources.items():
            click.echo(f"  {name:<{width}} = {motor[name]:<8g} {DESIGN_MOTOR[name][0]:<4} {source}")


def _load_motor(motor_file: str) -> "Motor":
    """The motor of --motor: a scenario, a datasheet motor file or an identified motor.toml."""
    from ...core.motor import load_motor

    try:
        return load_motor(motor_file)
    except ConfigError as exc:
        raise as_option(exc, {"motor file": "--motor"}) from None


def _identified_current_loop(
    motor: "Motor | None", alpha_c_radps: float | None, tau_i_s: float, Ts_current_s: float | None
) -> "CurrentLoopDesign | None":
    """The current loop of --motor and --current-bandwidth-radps, or None without --current-bandwidth-radps."""
    if alpha_c_radps is None:
        return None
    if motor is None:
        raise click.UsageError("--current-bandwidth-radps needs --motor FILE (the identified motor)")
    if tau_i_s != 0.0:
        raise click.UsageError("--current-bandwidth-radps sets tau_i = 1/alpha_c: give it or --tau-i-s, not both")
    from ...analysis.current_loop import design_current_loop

    try:
        return design_current_loop(motor, alpha_c_radps, Ts_current_s)
    except ConfigError as exc:
        raise as_option(
            exc, {"current_bandwidth": "--current-bandwidth-radps", "Ts_current": "--Ts-current-s"}
        ) from None


def _current_loop_table(result: "SpeedDesign", loop: "CurrentLoopDesign", motor_file: str | None) -> str:
    lines = [f"\nCurrent loop from {motor_file} (alpha_c = {loop.alpha_c_radps:g} rad/s)"]
    lines += [f"  {name:<27}{value}" for name, value in result.current_loop_rows()]
    lines += [
        "Speed-loop margins if the machine is at the corners of the estimates' intervals",
        f"  {'Rs_ohm':>10} {'Lq_H':>10} {'psi_f_Wb':>10} {'gain [dB]':>10} {'phase [deg]':>12}",
    ]
    for row in result.sensitivity or []:
        gm = "inf" if row["gain_margin_dB"] is None else f"{row['gain_margin_dB']:.4g}"
        pm = "inf" if row["phase_margin_deg"] is None else f"{row['phase_margin_deg']:.4g}"
        lines.append(f"  {row['Rs_ohm']:>10.4g} {row['Lq_H']:>10.4g} {row['psi_f_Wb']:>10.4g} {gm:>10} {pm:>12}")
    if not loop.motor.intervals:
        lines.append(f"  (no intervals in {motor_file}: the estimates only)")
    return "\n".join(lines)


def _header_keys() -> dict[str, str]:
    """Scenario key of the design's header -> its option (studies.configuration.design_scenario)."""
    from ...studies.configuration import DESIGN_MOTOR

    return {key: option_name(name) for name, (_, key) in DESIGN_MOTOR.items()} | {
        "current_loop.tau_i_s": "--tau-i-s",
        "speed_controller.tau_i_s": "--tau-i-s",
        "speed_controller.Ts_s": "--Ts-s",
    }


def _header_motor(
    given: Mapping[str, float | None], file_motor: "Motor | None", motor_file: str | None, paper_drive: bool
) -> tuple[dict[str, Any], dict[str, str]]:
    """The motor data of --emit-c-header and their sources, in the words of the command line."""
    from ...studies.configuration import GIVEN, design_motor

    try:
        motor, sources = design_motor(
            given, motor=file_motor, motor_source=f"motor file {motor_file}", paper_drive=paper_drive
        )
    except ConfigError as exc:
        missing = ", ".join(option_name(name) for name in exc.param.split(", ") if name != "Lq_H")
        raise click.UsageError(
            f"--emit-c-header needs the motor data and the current loop: {missing} missing; give them, or "
            "--paper-drive for the paper's drive (placeholders, not your motor)"
        ) from None
    return motor, {name: f"given: {option_name(name)}" if s == GIVEN else s for name, s in sources.items()}


def _table(rows: "list[tuple[str, str | None]]") -> str:
    """Rows ``(name, value)`` as a table under their headings (the rows whose value is None)."""
    width = max(len(name) for name, value in rows if value is not None) + 2
    lines: list[str] = []
    for name, value in rows:
        if value is None:
            lines.append(("\n" if lines else "") + name)
        else:
            lines.append(f"  {name:<{width}}{value}")
    return "\n".join(lines)


#: Most curves of ``pmsm2dof bode`` (values of --m): each takes about 0.1 s, and a figure with
#: more is no longer read.
BODE_CURVES_MAX = 20


@click.command()
@speed_option("alpha_radps", required=True)
@click.option(
    "--m",
    "m_list",
    default="1",
    show_default=True,
    help="comma-separated values of m (eq 10), at most 20; other than 1 with --feedforward no_tau or full",
)
@speed_option("J_kgm2", "paper section 4", default=0.4, show_default=True)
@speed_option("zeta", "paper: Ki = 0.3", default=0.2887, show_default=True)
@speed_option("tau_i_s", default=0.05, show_default=True)
@click.option(
    "--feedforward",
    default="lowpass",
    show_default=True,
    help="lowpass (eq 13, m = 1), none, no_tau or full (eq 11); Fig. 7 is full with m = 0.2,0.5,1,2",
)
@click.option("--out", type=click.Path(dir_okay=False), required=True, help="figure file, .png or .svg")
def bode(
    alpha_radps: float,
    m_list: str,
    J_kgm2: float,
    zeta: float,
    tau_i_s: float,
    feedforward: "Feedforward",  # any string from the command line: the library validates it
    out: str,
) -> None:
    """Bode diagram of the tracking response Gx for several m (paper Fig. 7).

    Fig. 7 of the paper: --feedforward full --m 0.2,0.5,1,2.
    """
    from ..plots.canvas import save_figure
    from ..plots.design import bode_gx_sweep

    if m_list.count(",") >= BODE_CURVES_MAX:
        raise ConfigError("m", m_list, f"at most {BODE_CURVES_MAX} comma-separated numbers > 0 (one curve each)")
    try:
        m_values = [float(v) for v in m_list.split(",")]
    except ValueError:
        raise ConfigError("m", m_list, "comma-separated numbers > 0, e.g. 0.2,0.5,1,2") from None
    save_figure(
        bode_gx_sweep(alpha_radps, m_values, J_kgm2=J_kgm2, zeta=zeta, tau_i_s=tau_i_s, feedforward=feedforward), out
    )
    click.echo(
        f"wrote {out}: Bode diagram of Gx, feedforward {feedforward}, m = {', '.join(f'{m:g}' for m in m_values)}"
    )
