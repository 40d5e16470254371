"""The ``pmsm2dof`` command.

Each sub-command lives next to the module it drives and is registered here.
Every error the user can cause ends as one line on stderr and exit status 2.
"""

import contextlib
import math
import sys
import tomllib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TextIO

import click

from ..errors import ConfigError, Pmsm2dofError, Pmsm2dofWarning, Terminated, signals_raise_terminated

if TYPE_CHECKING:
    import pandas as pd

    from ..analysis.current_loop import CurrentLoopDesign
    from ..analysis.design import Design
    from ..analysis.discretize import DiscreteDesign
    from ..analysis.margins import Margins
    from ..analysis.sensor import DelayModel
    from ..analysis.twomass import TwoMass
    from ..core.bindings import AntiWindup, Feedforward, Method
    from ..core.motor import Motor
    from ..sim.commission import Commissioning
    from ..studies.autotune import AutotuneResult
    from ..studies.identify import Mechanics


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="pmsm2dof")
def cli() -> None:
    """Design, simulate and deploy the anti-windup 2DOF PI speed controller of a PMSM."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _as_option(exc: ConfigError, options: Mapping[str, str]) -> ConfigError:
    """``exc`` with its parameter named by its command-line option, when it has one in ``options``."""
    if exc.param in options:
        return ConfigError(options[exc.param], exc.value, exc.valid)
    return exc


def parse_override(text: str) -> tuple[str, Any]:
    """Parse one ``--set key=value`` of the command line.

    Parameters
    ----------
    text : str
        ``key=value``; the value is read as a TOML literal (``0.5``, ``true``, ``"x"``,
        ``nan``, ``[{t_s = 1.0, torque_Nm = 2.0}]``) and, when it is not one, taken as a plain
        string (``feedforward=none``).

    Returns
    -------
    tuple
        ``(key, value)`` for :meth:`pmsm2dof.sim.scenario.Scenario.with_overrides`, which
        validates the value.
    """
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError("--set", text, "key=value, e.g. speed_controller.alpha_radps=0.5")
    raw = raw.strip()
    try:
        parsed = tomllib.loads(f"v = {raw}")
    except tomllib.TOMLDecodeError:
        return key, raw
    return (key, parsed["v"]) if list(parsed) == ["v"] else (key, raw)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script: run the CLI, map user errors to exit status 2.

    The warnings of pmsm2dof are shown once each, as one line on stderr (:func:`warnings_as_lines`).

    A command ends with another status by raising ``click.exceptions.Exit`` (``autotune``: 1
    when no design meets the specification). SIGINT ends it with 130, SIGTERM with 143 and
    SIGHUP with 129 (128 + the signal), after the same cleanup: no staging folder is left.
    """
    try:
        with signals_raise_terminated(), warnings_as_lines():
            status = cli.main(args=argv, prog_name="pmsm2dof", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except click.exceptions.Abort:
        print("pmsm2dof: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print("pmsm2dof: terminated", file=sys.stderr)
        return 128 + exc.signum
    except click.ClickException as exc:
        print(f"pmsm2dof: error: {_one_line(exc.format_message())}", file=sys.stderr)
        return 2
    except ConfigError as exc:
        print(f"pmsm2dof: error: {_one_line(_as_cli_error(exc))}", file=sys.stderr)
        return 2
    except (Pmsm2dofError, ValueError, OSError) as exc:
        print(f"pmsm2dof: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    return status if isinstance(status, int) else 0


def _as_cli_error(exc: ConfigError) -> ConfigError:
    """``exc`` of an output folder in the words of the command line (``--out``, ``--force``)."""
    if exc.param not in ("out", "--out"):
        return exc
    return ConfigError("--out", exc.value, exc.valid.replace("force=True", "--force"))


def out_option(what: str, **kwargs: Any) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The ``--out`` folder of a command (``what`` it receives) and ``--force``.

    The folder must be new, empty or hold only the outputs of an earlier run of the same command,
    which are replaced as a whole (:func:`pmsm2dof.outputs.staged_dir`); ``--force`` writes into
    a folder holding other files too, and keeps them.
    """
    kwargs.setdefault("type", click.Path())
    help_text = (
        f"{what}; an existing folder must hold only the outputs of an earlier run of this command, which are replaced"
    )

    def decorate(f: Callable[..., Any]) -> Callable[..., Any]:
        f = click.option("--force", is_flag=True, help="write into --out even if it holds other files (they are kept)")(
            f
        )
        return click.option("--out", help=help_text, **kwargs)(f)

    return decorate


# ---------------------------------------------------------------------------------------------
# design and bode (pmsm2dof.analysis, ui.plots.design)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.option("--J", "J_kgm2", type=float, required=True, help="inertia [kg m^2], > 0")
@click.option("--alpha", "alpha_radps", type=float, required=True, help="bandwidth of the P loop [rad/s], > 0 (eq 9)")
@click.option("--zeta", type=float, required=True, help="relative damping of the PI loop, > 0 (eq 9)")
@click.option(
    "--m", type=float, default=1.0, show_default=True, help="tracking pole factor, Gx = m alpha/(s + m alpha) (eq 10)"
)
@click.option(
    "--tau-i", "tau_i_s", type=float, default=0.0, show_default=True, help="current-loop time constant [s] (eq 3)"
)
@click.option("--Ts", "Ts_s", type=float, required=True, help="speed-loop sampling period [s], > 0")
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
@click.option("--Ka", "Ka", type=float, default=None, help="back-calculation gain [(rad/s)/Nm], >= 0 [default: 1/Kp]")
@click.option(
    "--sensor",
    "sensor_model",
    default="ideal",
    show_default=True,
    help="speed sensor: ideal (the speed, sampled) or encoder (counted angle increments)",
)
@click.option("--estimator", default="difference", show_default=True, help="encoder speed estimator: difference or pll")
@click.option(
    "--sensor-bandwidth", "sensor_bandwidth_radps", type=float, default=0.0, help="PLL double pole [rad/s] (pll)"
)
@click.option(
    "--sensor-lowpass",
    "sensor_lowpass_radps",
    type=float,
    default=0.0,
    show_default=True,
    help="first-order low-pass on the measured speed [rad/s]; 0: none",
)
@click.option(
    "--sensor-delay", "sensor_delay_s", type=float, default=0.0, show_default=True, help="delay of the reading [s]"
)
@click.option(
    "--delay",
    "delay_model",
    default="exact",
    show_default=True,
    help="the delay in the continuous margins: exact (exp(-sT)) or pade (its approximant, as in poles and steps)",
)
@click.option(
    "--phase-margin",
    "phase_margin_deg",
    type=float,
    default=None,
    help="also report the largest alpha that keeps this phase margin [deg] with the sensor chain",
)
@click.option("--json", "as_json", is_flag=True, help="print one JSON object instead of the table")
@click.option(
    "--emit-c-header",
    "header",
    type=click.Path(dir_okay=False),
    default=None,
    help="write the C configuration of this design and its motor (as pmsm2dof header: the firmware's p2d_config.h)",
)
@click.option("--prefix", default="p2d_config", show_default=True, help="C identifier prefix in the header")
@click.option("--i-max", "i_max_A", type=float, default=None, help="header: current-vector limit [A]")
@click.option(
    "--pole-pairs",
    type=int,
    default=None,
    help="header: pole pairs p, Te = 1.5 p psi_f iq (the paper's p0, called there the number of poles)",
)
@click.option("--psi-f", "psi_f_Wb", type=float, default=None, help="header: magnet flux linkage [Wb]")
@click.option("--Ld", "Ld_H", type=float, default=None, help="header: d-axis inductance [H]")
@click.option(
    "--Lq", "Lq_H", type=float, default=None, help="header: q-axis inductance [H] [default: Ld, surface PMSM]"
)
@click.option(
    "--Rs",
    "Rs_ohm",
    type=float,
    default=None,
    help="header: stator resistance [ohm] (the current controller)",
)
@click.option(
    "--Ts-current", "Ts_current_s", type=float, default=None, help="header: current-loop sampling period [s], Ts / N"
)
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
    "--electrical --out): the header's motor data not given, and the rotor inertia and currents --J and --i-max "
    "are checked against",
)
@click.option(
    "--current-bandwidth",
    "alpha_c_radps",
    type=float,
    default=None,
    help="with --motor: current loop Kp = L alpha_c, Ki = Rs alpha_c [rad/s]; tau_i = 1/alpha_c (replaces --tau-i)",
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
    --sensor-bandwidth, --sensor-lowpass, --sensor-delay): the loop gain becomes F G H, and
    the margins, poles, overshoot and the discrete loop include it; --phase-margin reports the
    largest alpha that keeps that margin with it.

    With --emit-c-header the header (the whole configuration, as `pmsm2dof header` writes it)
    needs the motor data and the current loop: --i-max, --pole-pairs, --psi-f, --Ld (--Lq for a
    salient motor), --Rs and --Ts-current (Ts an integer multiple of it), or --paper-drive to
    take what is not given from the paper's drive. The summary says where each value came from.

    --fixed-point q15|q31 with --speed-full-scale-rpm and --torque-full-scale-Nm adds the scaling check
    of the fixed-point controller (docs/mcu.md, "No FPU"): each coefficient's quantisation error, the
    integrator's dead zone, the headroom of the states and the scalings or Ts that remove a dead zone.
    """
    import json
    import warnings

    from ..analysis.design import design as make_design
    from ..analysis.sensor import SensorChain
    from ..sim.plausibility import PlausibilityWarning, current_findings, inertia_findings
    from .fixedpoint import design_scaling_check, report_dict

    with _held_warnings():
        file_motor = None if motor_file is None else _load_motor(motor_file)
        loop = _identified_current_loop(file_motor, alpha_c_radps, tau_i_s, Ts_current_s)
        from_file: set[str] = set()
        if file_motor is not None:
            given = dict(pole_pairs=pole_pairs, psi_f_Wb=psi_f_Wb, Ld_H=Ld_H, Lq_H=Lq_H, Rs_ohm=Rs_ohm)
            from_file = {name for name, value in given.items() if value is None}
            pole_pairs = pole_pairs if pole_pairs is not None else file_motor.pole_pairs
            psi_f_Wb, Ld_H, Lq_H, Rs_ohm = (
                getattr(file_motor, k) if k in from_file else v for k, v in given.items() if k != "pole_pairs"
            )
            findings = inertia_findings("--J", J_kgm2, file_motor.J_rotor_kgm2)
            if i_max_A is not None:
                findings += current_findings("--i-max", i_max_A, file_motor.i_rated_A, file_motor.i_peak_A)
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
                paper_drive,
            )
            sources |= {name: f"motor file {motor_file}" for name in from_file if name in sources}
        options = {
            "J_kgm2": "--J",
            "alpha_radps": "--alpha",
            "zeta": "--zeta",
            "m": "--m",
            "tau_i_s": "--tau-i",
            "Ts_s": "--Ts",
            "Ka": "--Ka",
            "method": "--method",
            "feedforward": "--feedforward",
            "anti_windup": "--anti-windup",
            "model": "--sensor",
            "estimator": "--estimator",
            "bandwidth_radps": "--sensor-bandwidth",
            "lowpass_radps": "--sensor-lowpass",
            "delay_s": "--sensor-delay",
            "delay": "--delay",
            "phase_margin_deg": "--phase-margin",
        }
        try:
            sensor = SensorChain(
                model=sensor_model,
                estimator=estimator,
                bandwidth_radps=sensor_bandwidth_radps,
                lowpass_radps=sensor_lowpass_radps,
                delay_s=sensor_delay_s,
            )
            d = make_design(
                J_kgm2,
                alpha_radps,
                zeta,
                m=m,
                tau_i_s=tau_i_s,
                feedforward=feedforward,
                anti_windup=anti_windup,
                Ka=Ka,
                sensor=sensor,
            )
            dd = d.discretize(Ts_s, method)  # first: it bounds the work of the sensor's delay
            margins = d.margins(delay_model)
            alpha_max = (
                None if phase_margin_deg is None else d.max_alpha_for_phase_margin(phase_margin_deg, delay_model)
            )
        except ConfigError as exc:
            raise _as_option(exc, options) from None
        scaling = design_scaling_check(
            d, Ts_s, method, fixed_point, speed_full_scale_rpm, torque_full_scale_Nm, i_max_A, pole_pairs, psi_f_Wb
        )
    sensitivity = None
    if loop is not None:
        from ..analysis.current_loop import speed_margin_sensitivity

        sensitivity = speed_margin_sensitivity(loop, dd.design.Kp, dd.design.Ki, J_kgm2)
    if header is not None:
        from ..studies.configuration import configuration, design_scenario

        notes = ("Motor data and current loop given to design:",) + tuple(
            f"  {name:<12} = {motor[name]:g} {_HEADER_MOTOR[name][1]} ({source})" for name, source in sources.items()
        )
        try:
            config = configuration(design_scenario(dd, **motor), source="pmsm2dof design", notes=notes)
            config.write_header(header, prefix)
        except ConfigError as exc:
            raise _as_option(exc, _HEADER_KEYS) from None
    if as_json:
        data = dd.as_dict()
        data["continuous"]["margins"], _ = margins.values_and_reasons()
        data["delay"] = delay_model
        if phase_margin_deg is not None:
            data["max_alpha_radps"] = {"phase_margin_deg": phase_margin_deg, "alpha_radps": alpha_max}
        if header is not None:
            data["header"] = {
                "path": header,
                "motor": {name: {"value": motor[name], "source": sources[name]} for name in sources},
            }
        if loop is not None:
            data["current_loop"] = loop.as_dict()
            data["speed_margin_sensitivity"] = sensitivity
        if scaling is not None:
            data["fixed_point"] = report_dict(scaling)
        click.echo(json.dumps(data))
        return
    click.echo(_design_table(dd, margins, delay_model))
    if phase_margin_deg is not None:
        click.echo(
            f"\nLargest alpha keeping a phase margin of {phase_margin_deg:g} deg (zeta, tau_i and sensor kept): "
            f"{alpha_max:.6g} rad/s"
        )
    if loop is not None:
        click.echo(_current_loop_table(loop, motor_file, sensitivity))
    if scaling is not None:
        click.echo("\n" + scaling.text())
    if header is not None:
        click.echo(f"\nC header written to {header}, with the motor data")
        width = max(len(name) for name in sources)
        for name, source in sources.items():
            click.echo(f"  {name:<{width}} = {motor[name]:<8g} {_HEADER_MOTOR[name][1]:<4} {source}")


def _load_motor(motor_file: str) -> "Motor":
    """The motor of --motor: a scenario, a datasheet motor file or an identified motor.toml."""
    from ..core.motor import load_motor

    try:
        return load_motor(motor_file)
    except ConfigError as exc:
        raise _as_option(exc, {"motor file": "--motor"}) from None


def _identified_current_loop(
    motor: "Motor | None", alpha_c_radps: float | None, tau_i_s: float, Ts_current_s: float | None
) -> "CurrentLoopDesign | None":
    """The current loop of --motor and --current-bandwidth, or None without --current-bandwidth."""
    if alpha_c_radps is None:
        return None
    if motor is None:
        raise click.UsageError("--current-bandwidth needs --motor FILE (the identified motor)")
    if tau_i_s != 0.0:
        raise click.UsageError("--current-bandwidth sets tau_i = 1/alpha_c: give it or --tau-i, not both")
    from ..analysis.current_loop import design_current_loop

    try:
        return design_current_loop(motor, alpha_c_radps, Ts_current_s)
    except ConfigError as exc:
        raise _as_option(exc, {"current_bandwidth": "--current-bandwidth", "Ts_current": "--Ts-current"}) from None


def _current_loop_table(
    loop: "CurrentLoopDesign", motor_file: str | None, sensitivity: list[dict[str, Any]] | None
) -> str:
    m = loop.motor
    lines = [
        f"\nCurrent loop from {motor_file} (alpha_c = {loop.alpha_c_radps:g} rad/s)",
        f"  Kp_d = Ld alpha_c          {loop.Kp_d_V_per_A:.6g} V/A",
        f"  Kp_q = Lq alpha_c          {loop.Kp_q_V_per_A:.6g} V/A",
        f"  Ki = Rs alpha_c            {loop.Ki_V_per_As:.6g} V/(A s)",
        f"  tau_i = 1/alpha_c (eq 3)   {loop.tau_i_s:.6g} s",
        f"  decoupling                 ud += -w_e {m.Lq_H:.6g} iq, uq += w_e ({m.Ld_H:.6g} id + {m.psi_f_Wb:.6g})",
        "Speed-loop margins if the machine is at the corners of the estimates' intervals",
        f"  {'Rs_ohm':>10} {'Lq_H':>10} {'psi_f_Wb':>10} {'gain [dB]':>10} {'phase [deg]':>12}",
    ]
    for row in sensitivity or []:
        gm = "inf" if row["gain_margin_dB"] is None else f"{row['gain_margin_dB']:.4g}"
        pm = "inf" if row["phase_margin_deg"] is None else f"{row['phase_margin_deg']:.4g}"
        lines.append(f"  {row['Rs_ohm']:>10.4g} {row['Lq_H']:>10.4g} {row['psi_f_Wb']:>10.4g} {gm:>10} {pm:>12}")
    if not m.intervals:
        lines.append(f"  (no intervals in {motor_file}: the estimates only)")
    return "\n".join(lines)


#: The shipped scenario whose motor and current limit --paper-drive fills in.
PAPER_DRIVE_PRESET = "paper-condition-1"
#: Motor data and current loop of the header: keyword -> (option, unit, scenario key).
_HEADER_MOTOR = {
    "i_max_A": ("--i-max", "A", "limits.i_max_A"),
    "pole_pairs": ("--pole-pairs", "", "motor.pole_pairs"),
    "psi_f_Wb": ("--psi-f", "Wb", "motor.psi_f_Wb"),
    "Ld_H": ("--Ld", "H", "motor.Ld_H"),
    "Lq_H": ("--Lq", "H", "motor.Lq_H"),
    "Rs_ohm": ("--Rs", "ohm", "motor.Rs_ohm"),
    "Ts_current_s": ("--Ts-current", "s", "current_loop.Ts_s"),
}
#: Scenario key of the design's header -> its option (studies.configuration.design_scenario).
_HEADER_KEYS = {key: option for option, _, key in _HEADER_MOTOR.values()} | {
    "current_loop.tau_i_s": "--tau-i",
    "speed_controller.tau_i_s": "--tau-i",
    "speed_controller.Ts_s": "--Ts",
}


def _header_motor(given: Mapping[str, float | None], paper_drive: bool) -> tuple[dict[str, Any], dict[str, str]]:
    """The motor data and current-loop period of the C header and where each value came from.

    Every value is either given, or, with ``paper_drive``, taken from the paper's drive
    (:data:`PAPER_DRIVE_PRESET`); ``Lq_H`` not given is ``Ld_H`` (surface PMSM) when ``Ld_H``
    is given.

    Raises
    ------
    click.UsageError
        Naming the missing options when a value is neither given nor taken from the paper drive.
    """
    needed = list(_HEADER_MOTOR)
    motor: dict[str, Any] = {}
    sources: dict[str, str] = {}
    if given["Lq_H"] is None and given["Ld_H"] is not None:
        given = {**given, "Lq_H": given["Ld_H"]}
        sources["Lq_H"] = "= Ld_H: surface PMSM, --Lq not given"
    missing = [name for name in needed if given[name] is None]
    if missing and not paper_drive:
        options = ", ".join(_HEADER_MOTOR[name][0] for name in missing if name != "Lq_H")
        raise click.UsageError(
            f"--emit-c-header needs the motor data and the current loop: {options} missing; give them, or "
            "--paper-drive for the paper's drive (placeholders, not your motor)"
        )
    if missing:
        from ..sim.scenario import load_scenario

        data = load_scenario(PAPER_DRIVE_PRESET).data
    for name in needed:
        if given[name] is not None:
            motor[name] = given[name]
            sources.setdefault(name, "given: " + _HEADER_MOTOR[name][0])
        else:
            table, key = _HEADER_MOTOR[name][2].split(".")
            motor[name] = data[table][key]
            sources[name] = f"paper drive, preset {PAPER_DRIVE_PRESET}: a placeholder, not your motor"
    return motor, {name: sources[name] for name in needed}


def _poles_text(poles: Iterable[complex], unit: str) -> str:
    """Poles with conjugate pairs shown once as re ± im j."""
    parts = []
    for p in sorted(poles, key=lambda p: (p.real, -p.imag)):
        if p.imag > 0:
            parts.append(f"{p.real:.6g} ± {p.imag:.6g}j")
        elif p.imag == 0:
            parts.append(f"{p.real:.6g}")
    return ", ".join(parts) + f" {unit}"


def _margins_text(margins: "Margins", unit: str) -> str:
    return (
        f"gain {margins.gain_margin_dB:.4g} dB, phase {margins.phase_margin_deg:.4g} deg"
        f" (crossover {margins.w_gain_crossover_radps:.4g} {unit})"
    )


def _overshoot_text(value: float, missing: Mapping[str, str]) -> str:
    return f"{value:.3g} %" if "overshoot_pct" not in missing else f"n/a ({missing['overshoot_pct']})"


def _design_table(dd: "DiscreteDesign", margins: "Margins", delay_model: str) -> str:
    d = dd.design
    sensor = d.sensor.describe() + (f" ({delay_model} delay in the margins)" if d.sensor.delay_s else "")
    rows = [
        ("Design inputs", None),
        ("J", f"{d.J_kgm2:.6g} kg m^2"),
        ("alpha", f"{d.alpha_radps:.6g} rad/s"),
        ("zeta", f"{d.zeta:.6g}"),
        ("m", f"{d.m:.6g}"),
        ("tau_i", f"{d.tau_i_s:.6g} s"),
        ("feedforward", d.feedforward),
        ("anti-windup", d.anti_windup),
        ("speed sensor", sensor),
        ("Gains (eq 9)", None),
        ("Kp = J alpha", f"{d.Kp:.6g} Nm/(rad/s)"),
        ("Ki = J (alpha/(2 zeta))^2", f"{d.Ki:.6g} Nm/rad"),
        ("Ka", f"{d.Ka:.6g} (rad/s)/Nm" + (" (1/Kp)" if d.Ka == 1.0 / d.Kp else "")),
        ("Continuous loop (F G, eq 2, 3, 6, 8)" if d.sensor.is_ideal else "Continuous loop (F G H)", None),
        ("loop poles", _poles_text(d.closed_loop_poles(), "rad/s")),
        ("feedforward pole", "none" if d.feedforward == "none" else f"{-d.fr_polynomials()[1][1]:.6g} rad/s"),
        ("bandwidth (-3 dB of Gx)", f"{d.bandwidth_radps():.6g} rad/s"),
        ("step overshoot", _overshoot_text(d.overshoot_pct(), d.missing())),
        ("margins", _margins_text(margins, "rad/s")),
        (f"Discrete loop ({dd.method}, Ts = {dd.Ts_s:g} s, ZOH plant)", None),
        ("loop poles", _poles_text(dd.poles, "(z)")),
        ("largest |z|", f"{max(abs(p) for p in dd.poles):.9g}"),
        ("step overshoot", _overshoot_text(dd.overshoot_pct, dd.missing)),
        ("margins", _margins_text(dd.margins, "rad/s")),
        ("Coefficients (p2d_speed_coef_t)", None),
        ("b_e0", f"{dd.b_e0:.9g} Nm/(rad/s)"),
        ("Ki_Ts", f"{dd.Ki_Ts:.9g} Nm/(rad/s)"),
        ("Ki_Ka_Ts", f"{dd.Ki_Ka_Ts:.9g}"),
        ("ff_Fr0", f"{dd.ff_Fr0:.9g} Nm/(rad/s)"),
        ("ff_b_dr", f"{dd.ff_b_dr:.9g} Nm/(rad/s)"),
        ("ff_a1", f"{dd.ff_a1:.9g}"),
        ("ff_Kd_per_Ts", f"{dd.ff_Kd_per_Ts:.9g} Nm/(rad/s)"),
    ]
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


@cli.command()
@click.option("--alpha", "alpha_radps", type=float, required=True, help="bandwidth of the P loop [rad/s], > 0")
@click.option(
    "--m",
    "m_list",
    default="1",
    show_default=True,
    help="comma-separated values of m (eq 10), at most 20; other than 1 with --feedforward no_tau or full",
)
@click.option("--J", "J_kgm2", type=float, default=0.4, show_default=True, help="inertia [kg m^2] (paper section 4)")
@click.option("--zeta", type=float, default=0.2887, show_default=True, help="relative damping (paper: Ki = 0.3)")
@click.option("--tau-i", "tau_i_s", type=float, default=0.05, show_default=True, help="current-loop time constant [s]")
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
    from .plots.canvas import save_figure
    from .plots.design import bode_gx_sweep

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


# ---------------------------------------------------------------------------------------------
# reproduce (pmsm2dof.studies.paper, ui.report)
# ---------------------------------------------------------------------------------------------


@cli.command(short_help="Reproduce the paper: figures 7-14, sensitivity studies and the claims table.")
@out_option(
    "folder for report.md, report.html, claims.json, the figures and their data",
    default="pmsm2dof-report",
    show_default=True,
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="change a scenario key in every preset, e.g. --set motor.psi_f_Wb=0.1 (repeatable)",
)
def reproduce(out: str, force: bool, overrides: tuple[str, ...]) -> None:
    """Reproduce the paper: Fig. 7-14 as simulations, sensitivity and discretization studies, claims table.

    Runs the paper's conditions on the presets (the float32 C controller in the compiled
    engine) and writes OUT/report.md, OUT/report.html (self-contained), OUT/claims.json (each
    claim of the paper with the measured value and a verdict), OUT/figures/*.png and *.svg,
    and beside each figure its data (OUT/figures/*.csv), all or nothing.
    """
    import time

    from .report import VERDICTS
    from .report import reproduce as run_reproduction

    start = time.perf_counter()
    changes = dict(parse_override(text) for text in overrides)
    report = run_reproduction(out, overrides=changes, progress=True, force=force)
    for claim in report.claims:
        click.echo(f"  {claim.id:>4}  {claim.verdict:<15} {claim.claim}")
    for name, metrics in report.studies.metrics.items():
        for warning in metrics["warnings"]:
            click.echo(f"  WARNING: run {name}: {warning}")
    counts = ", ".join(f"{sum(c.verdict == v for c in report.claims)} {v}" for v in VERDICTS)
    click.echo(f"{len(report.claims)} claims: {counts}")
    click.echo(
        f"{report.studies.n_runs} simulations; wrote report.md, report.html, claims.json and "
        f"{sum(f.startswith('figures/') for f in report.files)} figure files to {out} "
        f"in {time.perf_counter() - start:.1f} s"
    )


# ---------------------------------------------------------------------------------------------
# simulate and presets (pmsm2dof.sim, ui.plots.trace)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="change a scenario key, e.g. --set speed_controller.anti_windup=none or "
    "--set reference.0.speed_rpm=300 (repeatable; values are TOML literals)",
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

    from ..outputs import atomic_write, staged_dir
    from ..sim.metrics import summary_lines
    from ..sim.plausibility import warn_implausible
    from ..sim.scenario import load_scenario
    from ..sim.simulate import simulate as run_simulation
    from ..studies.loopcheck import measure
    from .plots import trace

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


@cli.command()
@click.option("--keys", is_flag=True, help="list every scenario key (type, range, default, meaning) instead")
def presets(keys: bool) -> None:
    """List the scenarios shipped with pmsm2dof, by name, for `pmsm2dof simulate NAME`."""
    from ..sim.scenario import list_presets, load_scenario, schema_reference

    if keys:
        click.echo(schema_reference())
        return
    names = list_presets()
    width = max(len(name) for name in names)
    for name in names:
        click.echo(f"{name:<{width}}  {load_scenario(name).description}")


# ---------------------------------------------------------------------------------------------
# sweep (pmsm2dof.studies.sweep, ui.plots.sweep)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.argument("file", type=click.Path(dir_okay=False))
@out_option("output folder; rerun with the same folder to resume an interrupted sweep", required=True)
@click.option("--workers", type=int, default=None, help="local threads [default: all available cores]")
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="run on an existing Dask cluster, e.g. tcp://host:8786 (its workers need pmsm2dof)",
)
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

    from ..sim.plausibility import warn_implausible
    from ..studies.engine import PartWarning
    from ..studies.sweep import load_sweep, run_sweep
    from .plots.sweep import draw_figures

    chosen = load_sweep(file)
    warn_implausible(chosen.base)
    with warnings.catch_warnings():
        show = warnings.showwarning

        def one_line(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
            if issubclass(category, PartWarning):
                print(f"pmsm2dof: warning: {_one_line(message)}", file=sys.stderr)
            else:
                show(message, category, *args, **kwargs)

        warnings.simplefilter("always", PartWarning)
        warnings.showwarning = one_line
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
            raise _as_option(
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

    from ..sim.metrics import CHATTER_SHARE_MAX

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


# ---------------------------------------------------------------------------------------------
# tune (pmsm2dof.ui.tuner)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario", required=False, metavar="[PRESET_OR_FILE]")
@click.option(
    "--port", type=int, default=None, help="TCP port; 0 for any free port [default: 8765, or a free one if busy]"
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="interface to listen on; anything but loopback exposes the tuner to the network",
)
@click.option("--no-browser", is_flag=True, help="do not open the page in a browser")
@click.option(
    "--link",
    metavar="URL",
    default=None,
    help="drive mode: the XCP link of a drive built for the scenario (socket://HOST:PORT or a serial device), "
    "or 'virtual' for the PC's virtual drive built here",
)
@click.option("--elf", type=click.Path(dir_okay=False), default=None, help="the ELF file of the drive's firmware")
def tune(scenario: str | None, port: int, host: str, no_browser: bool, link: str | None, elf: str | None) -> None:
    """Tune the speed controller in the browser: responses redrawn as the sliders move.

    Starts from PRESET_OR_FILE (default: paper-condition-2) and serves a local page with
    sliders for alpha, zeta, m, Ka, the feedforward, anti-windup, discretization and Ts,
    the inertia error and the speed and load steps; downloads the scenario (TOML), the
    C header of the design and the trace (CSV). With --link the page, once armed, writes each
    change to the drive and runs the experiment on it beside its simulation (docs/tuning.md).
    """
    from ..sim.plausibility import warn_implausible
    from ..sim.scenario import load_scenario
    from .tuner import DEFAULT_PRESET, run_tuner

    chosen = load_scenario(scenario or DEFAULT_PRESET)
    warn_implausible(chosen)
    run_tuner(chosen, host=host, port=port, open_browser=not no_browser, link=link, elf=elf)


# ---------------------------------------------------------------------------------------------
# autotune (pmsm2dof.studies.autotune, ui.plots.autotune)
# ---------------------------------------------------------------------------------------------

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


def _require_writable_file(path: str, option: str = "--emit-c-header") -> None:
    """Raise ConfigError naming ``option``, before any long work, if ``path`` cannot be written."""
    import os
    from pathlib import Path

    folder = Path(path).resolve().parent
    if Path(path).is_dir():
        raise ConfigError(option, path, "a file path (it is an existing folder)")
    if os.path.lexists(path) and not (Path(path).is_file() or Path(path).is_symlink()):
        raise ConfigError(option, path, "a file path (it is a device, a FIFO or a socket)")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ConfigError(option, path, "a file in an existing, writable folder")


def _csv_text(rows: Sequence[Mapping[str, Any]]) -> str:
    """``rows`` (dicts with the same keys) as CSV text; None is an empty cell."""
    import csv
    import io

    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return buf.getvalue()


@cli.command(short_help="Find the anti-windup 2DOF design that rejects loads best within a specification.")
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", help="change a scenario key first (repeatable)")
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
@click.option("--workers", type=int, default=None, help="local threads [default: all available cores]")
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="run the simulations on an existing Dask cluster, e.g. tcp://host:8786 (its workers need pmsm2dof)",
)
@click.option("--json", "as_json", is_flag=True, help="print one JSON object instead of the summary")
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

    from ..outputs import atomic_write, check_out, staged_dir
    from ..sim.plausibility import warn_implausible
    from ..sim.scenario import load_scenario
    from ..studies.autotune import Spec
    from ..studies.autotune import autotune as run_autotune

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
        if out is not None:
            check_out(out, "autotune", force)
        if header is not None:
            _require_writable_file(header)
        result = run_autotune(chosen, spec, workers=workers, scheduler=scheduler, progress=True)
        if out is not None:
            from .plots.autotune import plot_pareto

            with staged_dir(out, "autotune", force) as tmp:
                atomic_write(tmp / "scenario.toml", result.tuned_scenario().to_toml())
                atomic_write(tmp / "autotune.json", json.dumps(result.as_dict(), indent=2, allow_nan=False) + "\n")
                atomic_write(tmp / "pareto.csv", _csv_text(result.pareto_rows()))
                atomic_write(tmp / "runs.csv", _csv_text(result.runs_rows()))
                atomic_write(tmp / "rejected.csv", _csv_text(result.rejected_rows()))
                plot_pareto(result, tmp / "pareto.png")
                if header is not None:
                    result.write_c_header(header)
        elif header is not None:
            result.write_c_header(header)
    except ConfigError as exc:
        raise _as_option(exc, _AUTOTUNE_OPTIONS) from None
    if as_json:
        click.echo(json.dumps(result.as_dict(), allow_nan=False))
    else:
        click.echo(_autotune_summary(result, scenario))
        written = [f"{out}/" if out is not None else "", header or ""]
        if any(written):
            click.echo("wrote " + " and ".join(w for w in written if w))
    if not result.feasible:
        raise click.exceptions.Exit(1)


def _autotune_summary(result: "AutotuneResult", scenario: str) -> str:
    """The summary of an autotuning: outcome, chosen keys, worst case, how to reproduce it."""
    from ..studies.autotune import CONSTRAINTS

    data = result.as_dict()
    lo, hi = result.spec.J_range
    counts = data["counts"]
    lines = [
        f"{result.scenario.name}: {counts['candidates']} designs ({counts['rejected_by_margins']} rejected by the "
        f"margins alone), {counts['runs']} simulations over J ratio {lo:g} to {hi:g}, in {result.wall_time_s:.3g} s",
    ]
    if result.scenario_loop["warning"]:
        lines.append(f"WARNING: the scenario as given: {result.scenario_loop['warning']}")
    if result.feasible:
        lines.append(f"the design below meets the specification ({counts['feasible']} designs did)")
    else:
        lines.append("NO design meets the specification; the one below misses it least:")
        lines += [f"  misses {v.describe()}" for v in result.chosen.violations]
        if result.chosen.error:
            lines.append(f"  {result.chosen.error}")
        if result.binding is not None:
            lines.append(f"binding constraint: {result.binding.constraint}, missed by {result.binding.miss:.4g}")
    for key, value in result.speed_controller.items():
        lines.append(f"  speed_controller.{key} = {value}")
    lines.append("worst case over the inertia range (J ratio where it occurs):")
    units = {figure: unit for figure, _sense, unit in CONSTRAINTS.values()} | {
        "tracking_iae_rpm_s": "rpm s",
        "load_iae_rpm_s_per_Nm": "rpm s/Nm",
        "chatter_share": "",
    }
    for name, value in data["worst_case"].items():
        shown = "inf (never settles in its window)" if value is None and name == "settling_time_s" else value
        if isinstance(shown, float):
            shown = f"{shown:.4g} {units[name]}".rstrip()
        shown = "inf" if shown is None else shown
        lines.append(f"  {name:<22} {shown}  ({data['worst_J_ratio'][name]:.4g})")
    lines += [f"NOTE: {sentence}" for sentence in result.on_bounds]
    sets = " ".join(f"--set speed_controller.{k}={v}" for k, v in result.speed_controller.items())
    lines.append(f"reproduce: pmsm2dof simulate {scenario} {sets} --out DIR")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# commission (pmsm2dof.sim.commission): the C commissioning routine against a scenario's motor
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="change a scenario key, e.g. --set commissioning.dead_time_V=1.5 (repeatable; values are TOML literals)",
)
@click.option("--json", "as_json", is_flag=True, help="print one JSON object instead of the table")
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

    from ..outputs import atomic_write, check_out, staged_dir
    from ..sim.commission import commission as run_commissioning
    from ..sim.scenario import load_scenario
    from .plots.commission import plot_commission

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
            atomic_write(tmp / "result.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
            atomic_write(tmp / "log.csv", result.log_csv())
            plot_commission(result, tmp / "plot.png")
            if result.phase == "done":
                atomic_write(tmp / "motor.toml", result.motor_toml(chosen.data["motor"]["pole_pairs"]))
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


def _commissioned_header(scenario: Any, result: "Commissioning", path: Any) -> None:
    """The scenario's controllers configured with the identified motor (studies.configuration)."""
    from ..studies.configuration import configuration

    identified = scenario.with_overrides({f"motor.{key}": value for key, value in result.estimates.items()})
    notes = ("The motor's Rs, Ld, Lq and psi_f are those the commissioning identified.",)
    configuration(identified, source=f"pmsm2dof commission {scenario.name!r}", notes=notes).write_header(path)


def _commission_table(result: "Commissioning") -> str:
    from ..sim.commission import TARGETS

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


# ---------------------------------------------------------------------------------------------
# motor and identify (pmsm2dof.core.motor, sim.logs, studies.identify)
# ---------------------------------------------------------------------------------------------


def _motor_help() -> str:
    """The help of `pmsm2dof motor`: what it prints and every key of [motor.datasheet]."""
    import textwrap

    from ..core.motor import DATASHEET_KEYS

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


@cli.command(help=_motor_help(), short_help="The per-phase model of a motor given in datasheet units.")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="print one JSON object instead of the table")
def motor(file: str, as_json: bool) -> None:
    import json

    from ..core.motor import MOTOR_KEYS, RATING_KEYS, load_motor, no_load_speed_radps
    from ..errors import require_positive
    from ..inputs import read_toml

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


@contextlib.contextmanager
def _held_warnings() -> Iterator[None]:
    """Hold the warnings raised inside the block; give them again only when it ends without an error."""
    import warnings

    with warnings.catch_warnings(record=True) as held:
        warnings.simplefilter("always")
        yield
    for w in held:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


@contextlib.contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Show each warning of pmsm2dof raised inside the block once, as one line on stderr.

    A :class:`~pmsm2dof.errors.Pmsm2dofWarning` whose text was shown already (a scenario converted
    again for every run of a study, say) is not repeated; other warnings are shown as Python shows them.
    """
    import warnings

    shown: set[str] = set()
    with warnings.catch_warnings():
        show = warnings.showwarning

        def one_line(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            if not issubclass(category, Pmsm2dofWarning):
                show(message, category, filename, lineno, file, line)
            elif (text := _one_line(message)) not in shown:
                shown.add(text)
                print(f"pmsm2dof: warning: {text}", file=sys.stderr)

        warnings.filterwarnings("always", category=Pmsm2dofWarning)
        warnings.showwarning = one_line
        yield


@cli.command()
@click.argument("log", type=click.Path(dir_okay=False), required=False)
@click.option(
    "--column",
    "column_maps",
    multiple=True,
    metavar="SIGNAL=NAME",
    help="read a signal from another column, e.g. --column speed=enc_speed_rpm (the suffix gives the unit)",
)
@click.option("--motor", "motor_file", type=click.Path(dir_okay=False), help="motor TOML (scenario or datasheet)")
@click.option("--pole-pairs", type=int, default=None, help="pole pairs p (torque from the currents)")
@click.option("--psi-f-Wb", "psi_f_Wb", type=float, default=None, help="magnet flux linkage [Wb]")
@click.option("--Ld-H", "Ld_H", type=float, default=None, help="d-axis inductance [H] (default: Lq)")
@click.option("--Lq-H", "Lq_H", type=float, default=None, help="q-axis inductance [H] (default: Ld)")
@click.option(
    "--speed-period-mean",
    is_flag=True,
    help="the logged speed is the mean over each sampling period (encoder counts differenced)",
)
@click.option("--window-s", type=float, default=None, help="distance of the blocks of a regression row [s]")
@click.option("--json", "as_json", is_flag=True, help="print one JSON object instead of the table")
@out_option("folder for fit.png, rows.csv, identified.toml")
@click.option(
    "--design", "design_text", default=None, metavar="ALPHA,ZETA", help="print the eq 9 gains for the J found"
)
@click.option(
    "--electrical",
    is_flag=True,
    help="instead: Rs, Ld, Lq, psi_f (eq 1) from id_A, iq_A, ud_V, uq_V (needs --pole-pairs)",
)
@click.option(
    "--voltage-delay-samples",
    type=int,
    default=0,
    help="--electrical: the logged voltage applies this many samples after its row",
)
@click.option(
    "--angle-lead-samples",
    type=float,
    default=None,
    metavar="X",
    help="--electrical: the drive holds the stator-frame voltage over a period, turned at the row's angle plus "
    "X w_e Ts (0.5: mid-period; 1.5 with --voltage-delay-samples 1: delay compensation); default: the logged "
    "voltage is the rotor-frame voltage over its period",
)
@click.option(
    "--dead-time",
    is_flag=True,
    help="--electrical: fit the inverter's dead-time voltage per phase dead_time_V [V] with Rs "
    "(needs two current levels)",
)
@click.option(
    "--u-dc-V",
    "u_dc_V",
    type=float,
    default=None,
    help="--electrical: DC-link voltage [V]; windows where the voltage magnitude reaches u_dc/sqrt(3) are left out "
    "(default: the log's u_dc_V column; a voltage_limited column is always used)",
)
@click.option(
    "--current-ranges",
    type=int,
    default=None,
    help="--electrical: Ld and Lq per range of the current magnitude (1: none; default: 3 when the log's currents span "
    "more than a factor 2, else 1)",
)
@click.option("--plan", is_flag=True, help="instead: write the run to log (speed steps) for --motor SCENARIO to --out")
@click.option("--speed-max-rpm", type=float, default=None, help="--plan: largest speed of the steps [rpm]")
@click.option(
    "--i-max-A", "i_max_A", type=float, default=None, help="--plan: current limit [A] (default: the scenario's)"
)
def identify(
    log: str | None,
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
    electrical: bool,
    voltage_delay_samples: int,
    angle_lead_samples: float | None,
    dead_time: bool,
    u_dc_V: float | None,
    current_ranges: int | None,
    plan: bool,
    speed_max_rpm: float | None,
    i_max_A: float | None,
) -> None:
    """Identify the inertia J, viscous friction B and Coulomb friction of a logged run.

    LOG is a CSV, Parquet, NPZ or MAT file with time_s and speed_rpm (or speed_radps) and the
    torque: torque_Nm, or iq_A (and id_A) with the motor data (--motor FILE or --pole-pairs and
    --psi-f-Wb). With iq_ref_A in the log, the current loop's tau_i (eq 3) is identified too.
    Prints each value with its 95 % interval; --out DIR writes fit.png, rows.csv and
    identified.toml (the --motor scenario with the values found, or a [motor] table).

    With --plan (no LOG): writes to --out the run to play on the drive and log, speed steps
    within --speed-max-rpm and the current limit for the --motor scenario's J guess: plan.toml
    (the scenario), its simulation trace.csv and plot.png.

    With --electrical --pole-pairs P: Rs, Ld, Lq and psi_f (per phase, amplitude-invariant dq,
    eq 1) from id_A, iq_A, ud_V, uq_V and the speed, each with its 95 % interval; --out DIR
    writes fit.png (measured vs model voltages), residuals.csv, motor.toml (for design --motor)
    and identify.json (and ranges.csv with the fit per current range). When the log holds the
    controller's references (--voltage-delay-samples >= 1, --angle-lead-samples or --u-dc-V), windows
    at the inverter's voltage limit (a voltage_limited column, or a voltage magnitude at u_dc/sqrt(3)
    from --u-dc-V or a u_dc_V column) are left out; a log of applied voltages keeps them.
    """
    import json

    from ..core.gains import pi_gains
    from ..core.motor import load_motor
    from ..outputs import atomic_write, staged_dir
    from ..sim.logs import read_log
    from ..studies.identify import IdentificationError, identify_mechanics, identify_tau_i, torque_from_currents

    if plan:
        _identify_plan(log, motor_file, speed_max_rpm, i_max_A, out, force)
        return
    if log is None:
        raise ConfigError("LOG", "<missing>", "a log file (CSV, Parquet, NPZ or MAT), or --plan")
    options = {
        "--voltage-delay-samples": voltage_delay_samples or None,
        "--angle-lead-samples": angle_lead_samples,
        "--dead-time": dead_time or None,
        "--u-dc-V": u_dc_V,
        "--current-ranges": current_ranges,
    }
    if electrical:
        _identify_electrical(log, column_maps, pole_pairs, options, as_json, out, force)
        return
    for option, value in options.items():
        if value is not None:
            raise ConfigError(option, value, "given only with --electrical")
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
        from ..outputs import check_out

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
        raise _as_option(exc, {"window_s": "--window-s"}) from None
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
        import numpy as np

        from ..sim.scenario import Scenario, load_scenario
        from .plots.identify import plot_fit

        values = {"motor.J_kgm2": mech.J_kgm2, "motor.B_Nms": max(mech.B_Nms, 0.0)}
        values["motor.T_coulomb_Nm"] = max(mech.T_coulomb_Nm, 0.0)
        if current is not None:
            values["current_loop.tau_i_s"] = current.tau_i_s
        scenario: Scenario | None = None
        if motor_file is not None:
            try:
                scenario = load_scenario(motor_file)
            except ConfigError:
                scenario = None
        if scenario is not None:
            # the drive with the values found, its speed controller designed for the J found (eq 9)
            text = scenario.with_overrides({**values, "speed_controller.J_kgm2": mech.J_kgm2}).to_toml()
        else:
            lines = [f"# identified from {log} by pmsm2dof identify", "[motor]"]
            lines += [f"{k.split('.')[1]} = {v!r}" for k, v in values.items() if k.startswith("motor.")]
            if current is not None:
                lines += ["", "[current_loop]", f"tau_i_s = {current.tau_i_s!r}"]
            text = "\n".join(lines) + "\n"
        with staged_dir(out, "identify", force) as tmp:
            plot_fit(mech, tmp / "fit.png")
            rows = mech.rows
            table = np.column_stack([rows["t_s"], rows["y"], rows["fit"], rows["y"] - rows["fit"], rows["kept"]])
            body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
            atomic_write(tmp / "rows.csv", "t_s,torque_mean_Nm,fit_Nm,residual_Nm,kept\n" + body + "\n")
            atomic_write(tmp / "identified.toml", text)
            atomic_write(tmp / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")
    if as_json:
        click.echo(json.dumps(report, indent=2, allow_nan=False))
        return
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
    if gains is not None:
        click.echo(
            f"eq 9 with alpha = {alpha_radps:g} rad/s, zeta = {zeta:g}: Kp = {gains[0]:.6g}, Ki = {gains[1]:.6g}"
        )
    if out is not None:
        click.echo(f"wrote fit.png, rows.csv, identified.toml and identify.json to {out}")


def _identify_electrical(
    log: str,
    column_maps: tuple[str, ...],
    pole_pairs: int | None,
    options: dict[str, Any],
    as_json: bool,
    out: str | None,
    force: bool,
) -> None:
    """``identify --electrical``: Rs, Ld, Lq, psi_f of eq 1 (pmsm2dof.studies.electrical)."""
    import json

    import numpy as np

    from ..outputs import atomic_write, staged_dir
    from ..sim.logs import read_log
    from ..studies.electrical import DEAD_TIME, PARAMETERS, identify_electrical

    if pole_pairs is None or pole_pairs < 1:
        raise ConfigError("--pole-pairs", "<missing>" if pole_pairs is None else pole_pairs, "an integer >= 1")
    if out is not None:
        from ..outputs import check_out

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
        raise _as_option(exc, {name[2:].replace("-", "_"): name for name in options}) from None
    report = fit.to_json()
    range_names = ["i_low_A", "i_high_A", "n_windows", "Ld_H", "Ld_H_low", "Ld_H_high", "Lq_H", "Lq_H_low", "Lq_H_high"]

    def range_row(r: dict[str, Any]) -> list[float]:
        row = [r["i_low_A"], r["i_high_A"], r["n_windows"]]
        for name in ("Ld_H", "Lq_H"):
            row += [math.nan, math.nan, math.nan] if r[name] is None else [r[name], *r[f"{name}_ci"]]
        return row

    if out is not None:
        from .plots.identify import plot_electrical_fit

        rows = fit.rows
        names = ["t_s", "ud_V", "ud_fit_V", "uq_V", "uq_fit_V"]
        table = np.column_stack([rows[n] for n in names])
        body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
        ranges = "".join(",".join(f"{v:.9g}" for v in range_row(r)) + "\n" for r in report["ranges"])
        with staged_dir(out, "identify-electrical", force) as tmp:
            plot_electrical_fit(fit, tmp / "fit.png")
            atomic_write(tmp / "residuals.csv", ",".join(names) + "\n" + body + "\n")
            if fit.ranges:
                atomic_write(tmp / "ranges.csv", ",".join(range_names) + "\n" + ranges)
            atomic_write(tmp / "motor.toml", fit.motor_toml(pole_pairs, log))
            atomic_write(tmp / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")
    if as_json:
        click.echo(json.dumps(report, indent=2, allow_nan=False))
        return
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
    if out is not None:
        written = "fit.png, residuals.csv, " + ("ranges.csv, " if fit.ranges else "")
        click.echo(f"wrote {written}motor.toml and identify.json to {out}")


@cli.command()
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

    from ..outputs import atomic_write, staged_dir
    from ..sim.logs import read_log
    from ..sim.metrics import compute_metrics
    from ..sim.plausibility import warn_implausible
    from ..sim.scenario import load_scenario
    from ..sim.simulate import simulate as run_simulation
    from .plots.identify import plot_compare

    columns = dict(parse_column(text) for text in column_maps)
    measured = read_log(log, columns)
    chosen = load_scenario(scenario)
    inside = (measured.t_s >= 0.0) & (measured.t_s <= chosen.data["simulation"]["t_end_s"])
    if np.count_nonzero(inside) < 2:
        raise ConfigError(
            "LOG", log, f"a log whose time overlaps the scenario's 0 to {chosen.data['simulation']['t_end_s']:g} s"
        )
    with staged_dir(out, "compare", force) as tmp:
        result = run_simulation(chosen)
        error = measured.speed_rpm[inside] - np.interp(measured.t_s[inside], result.t_s, result.speed_rpm)
        i_max = chosen.data["limits"]["i_max_A"]
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


def _identify_plan(
    log: str | None,
    motor_file: str | None,
    speed_max_rpm: float | None,
    i_max_A: float | None,
    out: str | None,
    force: bool,
) -> None:
    """``identify --plan``: the experiment as a scenario and its simulation."""
    from ..outputs import atomic_write, staged_dir
    from ..sim.scenario import load_scenario
    from ..sim.simulate import simulate as run_simulation
    from ..studies.identify import plan_experiment
    from .plots import trace

    if log is not None:
        raise ConfigError("LOG", log, "absent with --plan (the plan is what to log)")
    if motor_file is None or speed_max_rpm is None or out is None:
        missing = "--motor" if motor_file is None else "--speed-max-rpm" if speed_max_rpm is None else "--out"
        raise ConfigError(missing, "<missing>", "given with --plan")
    try:
        chosen = plan_experiment(load_scenario(motor_file), speed_max_rpm, i_max_A)
    except ConfigError as exc:
        raise _as_option(exc, {"speed_max_rpm": "--speed-max-rpm", "limits.i_max_A": "--i-max-A"}) from None
    with staged_dir(out, "identify-plan", force) as tmp:
        result = run_simulation(chosen)
        result.save(tmp / "trace.csv")
        trace.plot_trace(result, tmp / "plot.png")
        atomic_write(tmp / "plan.toml", chosen.to_toml())
    for entry in chosen.data["reference"]:
        click.echo(f"  t = {entry['t_s']:8.4g} s: speed reference {entry['speed_rpm']:8.5g} rpm")
    i_limit = chosen.data["limits"]["i_max_A"]
    click.echo(
        f"simulated with J = {chosen.data['speed_controller']['J_kgm2']:g} kg m^2: |speed| <= "
        f"{abs(result.speed_rpm).max():.5g} rpm, |iq| <= {abs(result.iq_A).max():.4g} A (limit {i_limit:g} A), "
        f"at the voltage limit {100 * float(result.voltage_limited.mean()):.3g} % of the time, {result.t_s[-1]:g} s"
    )
    click.echo(f"wrote plan.toml, trace.csv and plot.png to {out}: play plan.toml's reference on the drive, log it")


def parse_column(text: str) -> tuple[str, str]:
    """Parse one ``--column signal=name`` into ``(signal, name)`` for :func:`pmsm2dof.sim.logs.read_log`."""
    signal, sep, name = text.partition("=")
    if not sep or not signal.strip() or not name.strip():
        raise ConfigError("--column", text, "signal=name, e.g. speed=enc_speed_rpm")
    return signal.strip(), name.strip()


def dataclasses_replace_notes(mech: "Mechanics", note: str) -> "Mechanics":
    """``mech`` with one more note."""
    import dataclasses

    return dataclasses.replace(mech, notes=(*mech.notes, note))


# ---------------------------------------------------------------------------------------------
# sensors (pmsm2dof.studies.sensing)
# ---------------------------------------------------------------------------------------------


@cli.command(short_help="Sensor chains against the paper's experiments: overshoot, load dip, margins.")
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="change a scenario key of both experiments first, e.g. --set motor.J_kgm2=0.5 (repeatable)",
)
@out_option("folder for sensors.md and sensors.csv")
def sensors(overrides: tuple[str, ...], out: str | None, force: bool) -> None:
    """How encoder resolution, estimator, filter, delay and noise change the paper's drive.

    Runs experiment 1 (500 rpm step, 1DOF PI without and with AW) and experiment 3 (8 Nm load
    step, 2DOF) for each sensor chain, prints overshoots, load dip and the sampled loop's margins
    beside the paper's measured 35 % -> 15 %, whether a chain explains that measurement better
    than the exact reading, and the torque ripple of a current-sensor offset (the report's
    section). With --out, writes sensors.md and sensors.csv (the chains), all or nothing.
    """
    import csv
    import dataclasses
    import io

    from ..outputs import atomic_write, check_out, staged_dir
    from ..studies.sensing import offset_study, sensor_study
    from .report.render import render_markdown
    from .report.sensing import sensing_blocks

    changes = dict(parse_override(text) for text in overrides)
    if out is not None:
        check_out(out, "sensors", force)
    rows = sensor_study(changes)
    text = render_markdown(sensing_blocks(rows, offset_study(changes)))
    click.echo(text)
    if out is None:
        return
    with staged_dir(out, "sensors", force) as tmp:
        atomic_write(tmp / "sensors.md", text)
        buf = io.StringIO()
        names = [f.name for f in dataclasses.fields(rows[0]) if f.name != "sensor"]
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(names)
        for r in rows:
            writer.writerow(["" if getattr(r, n) is None else getattr(r, n) for n in names])
        atomic_write(tmp / "sensors.csv", buf.getvalue())
    click.echo(f"wrote sensors.md and sensors.csv to {out}")


# ---------------------------------------------------------------------------------------------
# twomass (pmsm2dof.analysis.twomass)
# ---------------------------------------------------------------------------------------------


@cli.command()
@click.option("--J-motor", "J_motor_kgm2", type=float, required=True, help="motor-side inertia J_M [kg m^2], > 0")
@click.option("--J-load", "J_load_kgm2", type=float, required=True, help="load-side inertia J_L [kg m^2], > 0")
@click.option("--stiffness", "stiffness_Nm_per_rad", type=float, required=True, help="shaft stiffness K [Nm/rad], > 0")
@click.option(
    "--damping", "damping_Nms_per_rad", type=float, default=0.0, show_default=True, help="shaft damping [Nm s/rad]"
)
@click.option("--alpha", "alpha_radps", type=float, required=True, help="bandwidth of the P loop [rad/s] (eq 9)")
@click.option("--zeta", type=float, default=0.7, show_default=True, help="relative damping of the PI loop (eq 9)")
@click.option("--tau-i", "tau_i_s", type=float, default=0.0, show_default=True, help="current-loop time constant [s]")
@click.option("--Ts", "Ts_s", type=float, required=True, help="speed-loop sampling period [s]")
@click.option("--feedback", default="motor", show_default=True, help="the speed the controller reads: motor or load")
@click.option("--notch-freq", "notch_freq_Hz", type=float, default=0.0, help="notch frequency [Hz] (0: none)")
@click.option("--notch-width", "notch_width_Hz", type=float, default=0.0, help="notch -3 dB width [Hz]")
@click.option("--notch-depth", "notch_depth", type=float, default=0.0, help="notch gain at its frequency [-]")
@click.option("--lowpass-freq", "lowpass_freq_Hz", type=float, default=0.0, help="low-pass frequency [Hz] (0: none)")
@click.option("--lowpass-zeta", "lowpass_zeta", type=float, default=0.0, help="low-pass damping [-]")
@click.option(
    "--region",
    type=click.Path(dir_okay=False),
    default=None,
    help="also draw the stable region (.png or .svg): the largest stable alpha against the resonance, "
    "resonance/10 .. 10x, for inertia ratios around J_L/J_M, with and without a notch at the resonance "
    "(the --notch-* width share and depth, else half the resonance wide and 0.05 deep); takes tens of seconds",
)
def twomass(
    J_motor_kgm2: float,
    J_load_kgm2: float,
    stiffness_Nm_per_rad: float,
    damping_Nms_per_rad: float,
    alpha_radps: float,
    zeta: float,
    tau_i_s: float,
    Ts_s: float,
    feedback: str,
    region: str | None,
    **filters: float,
) -> None:
    """The eq 9 design on the total inertia of a two-mass drive train: resonance, margins, poles.

    Prints the resonance and anti-resonance of the train, and for the sampled loop (the C
    controller's PI, the ZOH plant, the torque filters given) its stability, margins and the
    closed-loop poles nearest the unit circle.
    """
    from ..analysis.design import design
    from ..analysis.twomass import sampled_loop, two_mass

    options = {
        "J_motor_kgm2": "--J-motor",
        "J_load_kgm2": "--J-load",
        "stiffness_Nm_per_rad": "--stiffness",
        "damping_Nms_per_rad": "--damping",
        "alpha_radps": "--alpha",
        "J_kgm2": "--J-motor",
        "zeta": "--zeta",
        "tau_i_s": "--tau-i",
        "Ts_s": "--Ts",
        "feedback": "--feedback",
        **{name: "--" + name.rsplit("_", 1)[0].replace("_", "-") for name in filters},
        "notch_depth": "--notch-depth",
        "lowpass_zeta": "--lowpass-zeta",
        "region": "--region",
    }
    try:
        train = two_mass(J_motor_kgm2, J_load_kgm2, stiffness_Nm_per_rad, damping_Nms_per_rad)
        d = design(train.J_total_kgm2, alpha_radps, zeta, tau_i_s=tau_i_s)
        loop = sampled_loop(d, train, Ts_s, feedback=feedback, filters=filters)
        if region is not None and not region.lower().endswith((".png", ".svg")):
            raise ConfigError("region", region, "a file name ending in .png or .svg")
    except ConfigError as exc:
        raise _as_option(exc, options) from None
    two_pi = 2.0 * 3.141592653589793
    click.echo(
        f"inertia ratio J_L/J_M      {train.inertia_ratio:.4g} (design on J_M + J_L = {train.J_total_kgm2:.4g} kg m^2)"
    )
    click.echo(
        f"resonance                  {train.resonance_radps / two_pi:.4g} Hz (damping {train.resonance_damping:.3g})"
    )
    click.echo(f"anti-resonance             {train.antiresonance_radps / two_pi:.4g} Hz")
    click.echo(f"sampled loop ({feedback} side)  {'stable' if loop.stable else 'UNSTABLE'}")
    if loop.stable:
        gm, pm = loop.margins()
        click.echo(f"margins                    {gm:.3g} dB, {pm:.3g} deg")
    worst = sorted(loop.poles, key=abs)[-2:]
    click.echo("poles nearest |z| = 1      " + ", ".join(f"{p:.6g} (|z| = {abs(p):.6f})" for p in worst))
    if region is not None:
        _write_region(region, train, d, Ts_s, filters)
        click.echo(f"wrote the stable region to {region}")


def _write_region(path: str, train: "TwoMass", d: "Design", Ts_s: float, filters: Mapping[str, float]) -> None:
    """The stable-region figure of ``pmsm2dof twomass --region`` (written whole or not at all)."""
    import io

    import numpy as np

    from ..core import FEEDBACKS
    from ..outputs import atomic_write
    from ..studies.twomass import stable_region
    from .report.twomass import TwoMassStudy, fig_stable_region

    f_r = train.resonance_radps / (2.0 * np.pi)
    ratios = tuple(sorted({train.inertia_ratio, train.inertia_ratio / 3.0, 3.0 * train.inertia_ratio}))
    resonances = tuple(float(f) for f in np.geomspace(f_r / 10.0, 10.0 * f_r, 9))
    notch = filters["notch_freq_Hz"] > 0.0
    shape = dict(
        J_total_kgm2=train.J_total_kgm2,
        resonance_damping=train.resonance_damping,
        notch_width_share=filters["notch_width_Hz"] / filters["notch_freq_Hz"] if notch else 0.5,
        notch_depth=filters["notch_depth"] if notch else 0.05,
    )
    regions = {
        (fb, with_notch): stable_region(
            ratios if fb == "motor" else ratios[:1],
            resonances,
            zeta=d.zeta,
            tau_i_s=d.tau_i_s,
            Ts_s=Ts_s,
            feedback=fb,
            notch=with_notch,
            **shape,
        )
        for fb in FEEDBACKS
        for with_notch in (False, True)
    }
    study = TwoMassStudy([], regions, d.alpha_radps, d.zeta, d.tau_i_s, Ts_s, ratios, resonances)
    fig, _data = fig_stable_region(study)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.rsplit(".", 1)[-1].lower(), dpi=110)
    atomic_write(path, buf.getvalue())


# ---------------------------------------------------------------------------------------------
# header and firmware (pmsm2dof.studies.configuration, studies.firmware, ui.plots.firmware)
# ---------------------------------------------------------------------------------------------


def _chosen(scenario: str, overrides: Sequence[str]) -> tuple[Any, str]:
    """The scenario of PRESET_OR_FILE with the --set changes, and the command line that names it."""
    from ..sim.scenario import load_scenario

    chosen = load_scenario(scenario)
    changes = dict(parse_override(text) for text in overrides)
    if changes:
        chosen = chosen.with_overrides(changes)
    return chosen, " ".join([scenario, *(f"--set {text}" for text in overrides)])


@cli.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", help="change a scenario key (repeatable)")
@click.option(
    "--out", type=click.Path(dir_okay=False), required=True, help="the header to write (the firmware's p2d_config.h)"
)
@click.option("--prefix", default="p2d_config", show_default=True, help="C identifier prefix of the header")
@click.option(
    "--virtual-drive",
    type=click.Path(dir_okay=False),
    default=None,
    help="also write the virtual board's header (p2d_virtual_drive.h: the scenario's plant and schedules)",
)
def header(scenario: str, overrides: tuple[str, ...], out: str, prefix: str, virtual_drive: str | None) -> None:
    """Write the C configuration of a scenario's controllers: the header the firmware includes.

    Speed controller, torque filters, current controller, speed-sensor estimator, field weakening,
    inertia estimator and the loop rates, as the engine runs them on the scenario (the same shape
    as design --emit-c-header, autotune --emit-c-header, commission --out and the tuner write).
    """
    from ..outputs import atomic_write
    from ..studies.configuration import configuration
    from ..studies.firmware import virtual_drive_header

    options = {out: "--out"} if virtual_drive is None else {out: "--out", virtual_drive: "--virtual-drive"}
    for path, option in options.items():
        _require_writable_file(path, option)
    chosen, named = _chosen(scenario, overrides)
    with warnings_as_lines():
        config = configuration(chosen, source=f"pmsm2dof header {named}")
        texts = {out: config.c_header(prefix)}
    if virtual_drive is not None:
        texts[virtual_drive] = virtual_drive_header(config)
    for path, text in texts.items():
        try:
            atomic_write(path, text)
        except ConfigError as exc:  # a full disk
            raise ConfigError(options[path], exc.value, exc.valid) from None
    click.echo(
        f"{chosen.name}: wrote {' and '.join(texts)} (current loop every {config.engine.cfg.Ts_current_s:g} s, "
        f"speed loop every {config.current_per_speed} current periods)"
    )


@cli.command(short_help="Build the firmware for a scenario, or run it on QEMU against the engine.")
@click.argument("args", nargs=-1, metavar="PRESET_OR_FILE | run DIR")
@click.option(
    "--set", "overrides", multiple=True, metavar="KEY=VALUE", help="build: change a scenario key (repeatable)"
)
@out_option(
    "build: the firmware's folder; run: the folder for trace.csv, metrics.json, plot.png, interrupts.csv",
    type=click.Path(file_okay=False),
    required=True,
)
@click.option("--samples", type=int, default=None, help="run: speed samples to run [default: the scenario's t_end]")
def firmware(args: tuple[str, ...], overrides: tuple[str, ...], out: str, force: bool, samples: int | None) -> None:
    """Build the FOC firmware of examples/firmware for a scenario, or run it closed loop on QEMU.

    `pmsm2dof firmware PRESET_OR_FILE --out DIR` writes DIR/scenario.toml, DIR/p2d_config.h (the
    controllers), DIR/p2d_virtual_drive.h (the virtual board: the engine's plant, the scenario's
    reference and load) and cross-builds DIR/virtual_drive.elf and DIR/firmware.elf (the porting stub)
    for the Cortex-M4F (CMake, arm-none-eabi-gcc).

    `pmsm2dof firmware run DIR --out RUN` runs DIR/virtual_drive.elf on QEMU (mps2-an386), simulates
    the scenario with the engine and writes RUN/trace.csv (the firmware's trace in the engine's
    format), RUN/metrics.json (the figures of merit, the agreement with the engine, the instructions
    per interrupt), RUN/plot.png (the firmware over the engine) and RUN/interrupts.csv. Exit status 1
    when the firmware's speed or currents differ from the engine's by more than 1e-4 of their step.
    """
    if len(args) == 2 and args[0] == "run":
        if overrides:
            raise click.UsageError("--set changes a scenario before the build: pmsm2dof firmware SCENARIO --set ...")
        _firmware_run(args[1], out, force, samples)
        return
    if len(args) != 1:
        raise click.UsageError("give a scenario (pmsm2dof firmware SCENARIO --out DIR) or run DIR (--out RUN)")
    if samples is not None:
        raise click.UsageError("--samples is an option of `pmsm2dof firmware run DIR`")
    from ..studies.firmware import build_firmware

    chosen, named = _chosen(args[0], overrides)
    with warnings_as_lines():
        build = build_firmware(chosen, out, source=f"pmsm2dof firmware {named}", force=force)
    for name, size in build.sizes.items():
        click.echo(f"  {name:<18} flash {size['text'] + size['data']:>7} B, RAM {size['data'] + size['bss']:>6} B")
    click.echo(f"{chosen.name}: wrote scenario.toml, p2d_config.h, p2d_virtual_drive.h, the ELF and map files to {out}")


def _firmware_run(folder: str, out: str, force: bool, samples: int | None) -> None:
    """``pmsm2dof firmware run DIR --out RUN``."""
    import json

    from ..outputs import atomic_write, check_out, staged_dir
    from ..sim.metrics import compute_metrics
    from ..studies.firmware import run_firmware
    from .plots.firmware import plot_firmware

    check_out(out, "firmware-run", force)
    run = run_firmware(folder, samples=samples)
    comparison, cost = run.comparison(), run.cost()
    metrics = {"firmware": compute_metrics(run.firmware), "comparison": comparison, "interrupts": cost}
    with staged_dir(out, "firmware-run", force) as tmp:
        run.firmware.save(tmp / "trace.csv")
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        plot_firmware(run, tmp / "plot.png")
        rows = [{"instructions": int(n), "speed_sample": int(s)} for n, s in zip(run.instructions, run.speed_sample)]
        atomic_write(tmp / "interrupts.csv", _csv_text(rows))
    t_end = run.firmware.t_s[-1]
    click.echo(f"{run.scenario.name}: {t_end:g} s on QEMU in {run.wall_time_s:.3g} s of wall time")
    for group in ("speed", "currents"):
        c = comparison[group]
        click.echo(
            f"  {group:<8} firmware - engine: {c['max_abs_difference']:.3g} at most, "
            f"{c['relative_to_step']:.3g} of the step {c['step']:.4g}"
        )
    for kind in ("current", "speed"):
        k = cost[kind]
        if k["interrupts"]:
            click.echo(f"  {kind:<8} interrupts: {k['interrupts']}, {k['min']} to {k['max']} instructions")
    click.echo(
        f"  CPU load on a {cost['core_clock_Hz'] / 1e6:g} MHz Cortex-M4 at {cost['cycles_per_instruction']:g} cycles "
        f"per instruction: {100 * cost['mean_load']:.3g} % mean, {100 * cost['peak_share_of_period']:.3g} % of a "
        "period at most"
    )
    click.echo(f"wrote trace.csv, metrics.json, plot.png and interrupts.csv to {out}")
    if not comparison["agrees"]:
        click.echo(
            f"the firmware's trace differs from the engine's by more than {comparison['agreement']:g} of the step"
        )
        raise click.exceptions.Exit(1)
