"""``pmsm2dof drive``: the drive over XCP (pyxcp, the ``drive`` extra) by its A2L file.

Each command parses its options and calls one function of :mod:`pmsm2dof.drive.session` or
:mod:`pmsm2dof.studies.drive`; the link is one option, ``--link URL`` (:func:`link_option`).
"""

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import click

from ...errors import ConfigError
from .options import DriveGroup, as_option, chosen_scenario, out_option, set_option, warnings_as_lines

if TYPE_CHECKING:
    from ...sim.scenario_tables import MotorTable

LINK_HELP = (
    "the drive's link: tcp://HOST:PORT (XCP on TCP: the PC's drive, QEMU's -serial tcp), serial:DEVICE or a "
    "device (/dev/pts/3, /dev/ttyUSB0, COM3: XCP on SxI), can://INTERFACE/CHANNEL?master=ID&slave=ID&fd=0|1 "
    "(XCP on CAN by python-can); HOST must be this machine unless --allow-remote"
)

#: The library's argument of the duration -> its option.
DURATION = {"duration_s": "--duration-s", "pre_s": "--pre-s", "link_bytes_per_s": "--link-bytes-per-s"}


def link_option(f: Callable[..., Any]) -> Callable[..., Any]:
    """``--link URL``, ``--a2l FILE`` and ``--allow-remote``: where the drive is and what it holds."""
    f = click.option("--allow-remote", is_flag=True, help="connect to a drive on another machine (tcp://HOST)")(f)
    f = click.option(
        "--a2l", "a2l", type=click.Path(dir_okay=False), required=True,
        help="the drive's A2L file (pmsm2dof firmware writes one beside each ELF): its variables, limits, events",
    )(f)  # fmt: skip
    return click.option("--link", "url", required=True, metavar="URL", help=LINK_HELP)(f)


def _open(url: str, a2l: str, allow_remote: bool) -> Any:
    from ...drive.session import open_link

    return open_link(url, a2l, allow_remote=allow_remote)


def _show(value: Any) -> str:
    return (
        ", ".join(f"{v:.9g}" for v in value)
        if isinstance(value, tuple)
        else f"{value:.9g}"
        if isinstance(value, float)
        else str(value)
    )


@click.group(
    cls=DriveGroup, short_help="Talk to a drive over XCP: info, get, set, capture, run, serve, commission, identify."
)
def drive() -> None:
    """Talk to a drive (the firmware of examples/firmware, on an MCU, on QEMU or the PC's virtual drive) over
    XCP, by the names of its A2L file: read and write its variables, capture signals by DAQ, play a
    scenario on it beside the engine's simulation, serve the PC's virtual drive of a scenario, commission
    its motor or identify its mechanics or its motor's electrical values.
    """


@drive.command()
@link_option
def info(url: str, a2l: str, allow_remote: bool) -> None:
    """The drive's identity, protocol limits, events, run status and the controllers' configuration."""
    from ...drive.session import info as drive_info

    with _open(url, a2l, allow_remote) as link:
        i = drive_info(link)
    click.echo(f"{i['id']} at {i['url']} (A2L module {i['a2l_module']}), XCP protocol layer {i['protocol_version']}")
    click.echo(f"  byte order {i['byte_order']}, MAX_CTO {i['max_cto']} B, MAX_DTO {i['max_dto']} B, "
               f"{i['daq_lists_max']} DAQ lists")  # fmt: skip
    click.echo("  events: " + ", ".join(f"{n} every {p * 1e6:g} us" for n, p in i["events"].items()))
    st = i["status"]
    power = "on" if st["power_on"] else "off"
    commits = f"commits {st['commits_applied']} applied / {st['commits_rejected']} rejected"
    click.echo(f"  state {st['state']}, run {st['runs']}, sample {st['sample']}, power {power}, {commits}, "
               f"DAQ lost {st['dtos_lost']}")  # fmt: skip
    for var, fields in i["config"].items():
        click.echo(f"  {var}: " + ", ".join(f"{k} = {_show(v)}" for k, v in fields.items()))


@drive.command()
@click.argument("names", nargs=-1, required=True, metavar="NAME...")
@link_option
def get(names: tuple[str, ...], url: str, a2l: str, allow_remote: bool) -> None:
    """Read variables by the A2L's names (link_speed_config.alpha_radps) or the scenario's keys
    (speed_controller.alpha_radps)."""
    from ...drive.session import get as drive_get

    with _open(url, a2l, allow_remote) as link:
        for name, value, unit in drive_get(link, names):
            click.echo(f"{name} = {_show(value)}" + (f" {unit}" if unit not in ("", "-") else ""))


@drive.command(name="set")
@click.argument("assignments", nargs=-1, metavar="[NAME=VALUE...]")
@click.option(
    "--scenario", "scenario_file", type=click.Path(dir_okay=False), default=None,
    help="write this scenario's speed controller and its design inertia J_kgm2 (the scenario.toml of autotune "
         "of drive identify's identified.toml) instead of NAME=VALUE",
)  # fmt: skip
@link_option
def set_(assignments: tuple[str, ...], scenario_file: str | None, url: str, a2l: str, allow_remote: bool) -> None:
    """Write calibration variables, checked first against the A2L's limits and the controller's own validation;
    the fields of one variable take effect together at the drive's next speed sample.

    With --scenario FILE: the speed controller of FILE (alpha, zeta, m, Ka, method, feedforward,
    anti_windup) and the inertia it is designed for (speed_controller.J_kgm2), in one write; the
    motor, limits and loop periods of FILE must be the drive's (a tuned scenario of this drive).
    """
    from ...drive.session import link_errors, set_values
    from ...studies.bench import TUNED_FIELDS, write_tuned

    if (scenario_file is None) == (not assignments):
        raise ConfigError(
            "NAME=VALUE", " ".join(assignments) or "none", "assignments or --scenario FILE, one of the two"
        )
    chosen = chosen_scenario(scenario_file, ())[0] if scenario_file is not None else None
    with _open(url, a2l, allow_remote) as link:
        if chosen is None:
            written = set_values(link, assignments)
        else:
            with link_errors(link, "set"):
                values = write_tuned(link, chosen)
            written = [(f"link_speed_config.{f}", values[f], "") for f in TUNED_FIELDS]
        for name, value, unit in written:
            click.echo(f"{name} = {_show(value)}" + (f" {unit}" if unit not in ("", "-") else ""))


@drive.command()
@click.argument("signals", nargs=-1, required=True, metavar="SIGNAL...")
@click.option(
    "--event", default="speed", show_default=True, help="the DAQ event: speed (every speed sample) or current"
)
@click.option("--duration-s", "duration_s", type=float, required=True, help="how long to capture [s], (0, 3600]")
@click.option("--out", required=True, type=click.Path(), help="the file: .csv, .parquet or .mf4 (ASAM MDF 4.10)")
@click.option("--force", is_flag=True, help="replace --out if it exists")
@click.option(
    "--way",
    type=click.Choice(["auto", "daq", "buffer"]),
    default="auto",
    show_default=True,
    help="stream by DAQ, record in the drive's capture buffer and read it after, or choose by the rate",
)
@click.option(
    "--link-bytes-per-s",
    "link_bytes_per_s",
    type=float,
    default=None,
    help="what the link streams [bytes/s] [default: 11520 serial (115200 baud), 30000 CAN, 1e6 TCP]",
)
@click.option(
    "--trigger",
    default="immediate",
    show_default=True,
    help="the buffer's trigger: immediate, SIGNAL>LEVEL (rising) or SIGNAL<LEVEL (falling)",
)
@click.option("--pre-s", "pre_s", type=float, default=0.0, show_default=True, help="captured before the trigger [s]")
@link_option
def capture(signals: tuple[str, ...], event: str, duration_s: float, out: str, force: bool, way: str,
            link_bytes_per_s: float | None, trigger: str, pre_s: float, url: str, a2l: str,
            allow_remote: bool) -> None:  # fmt: skip
    """Capture signals at an event (every sample, timestamped by the drive) into a file: streamed by DAQ when the
    link carries them with room to spare, else recorded in the drive's capture buffer and read out after (a
    duration longer than the buffer holds is refused). t_s from the first sample (DAQ) or from the trigger
    (buffer). Exit status 1 when the drive lost samples (its DAQ queue overflowed)."""
    from ...drive.session import capture as drive_capture
    from ...drive.session import plan_capture, write_capture

    with _open(url, a2l, allow_remote) as link:
        try:
            plan = plan_capture(link, signals, event, duration_s, out, force, way=way,
                                link_bytes_per_s=link_bytes_per_s, trigger=trigger, pre_s=pre_s)  # fmt: skip
        except ConfigError as exc:
            raise as_option(exc, DURATION) from None
        cap = drive_capture(link, plan)
        write_capture(link, cap, out)
    n = len(cap.timestamps)
    how = ("by DAQ" if plan.way == "daq" else "in the drive's buffer") + (
        f" (payload {plan.need_bytes_per_s:.4g} B/s, the link {plan.link_bytes_per_s:.4g} B/s)"
    )
    click.echo(f"{n} samples of {len(signals)} signals at the {event} event over {duration_s:g} s {how}, "
               f"{cap.dtos_lost} lost: wrote {out}")  # fmt: skip
    if cap.dtos_lost:
        raise click.exceptions.Exit(1)


#: Spec field -> its option of drive run (autotune's names).
SPEC_OPTIONS = {
    "max_overshoot_pct": "--max-overshoot-pct",
    "max_settling_s": "--max-settling-s",
    "max_load_dip_rpm_per_Nm": "--max-load-dip-rpm-per-Nm",
    "max_recovery_s": "--max-recovery-s",
    "max_current_limit_time_s": "--max-current-limit-time-s",
}


def spec_options(f: Callable[..., Any]) -> Callable[..., Any]:
    """The constraints of autotune's specification that a trace shows, by autotune's option names."""
    helps = {
        "max_overshoot_pct": "largest overshoot of a reference step [%]",
        "max_settling_s": "longest settling time (2 %) of a reference step [s]",
        "max_load_dip_rpm_per_Nm": "largest speed dip of a load step per Nm of load change [rpm/Nm]",
        "max_recovery_s": "longest recovery time (2 % of the dip) of a load step [s]",
        "max_current_limit_time_s": "longest time at the current limit in one step [s]",
    }
    for name, option in reversed(SPEC_OPTIONS.items()):
        f = click.option(option, name, type=float, default=None, help="the spec: " + helps[name])(f)
    return f


@drive.command()
@click.argument("scenario")
@set_option()
@spec_options
@out_option("the folder for trace.csv, metrics.json and plot.png", type=click.Path(file_okay=False), required=True)
@link_option
def run(scenario: str, overrides: tuple[str, ...], out: str, force: bool, url: str, a2l: str,
        allow_remote: bool, **limits: float | None) -> None:  # fmt: skip
    """Play a scenario's reference and load on the drive (a build of it) and hold the trace against the engine,
    or against a specification.

    The run is captured from the firmware's own signals (foc_now at every speed sample: by DAQ when the
    link carries it, else in the drive's capture buffer), so any drive with the firmware's variables
    plays it. Writes OUT/trace.csv (the drive's measured run in the engine's log columns that a drive
    measures: its speed is the drive's speed reading), OUT/metrics.json (the figures
    of merit, the agreement, the specification's verdict) and OUT/plot.png (the drive over the engine).
    Without a specification, exit status 1 when the speed or the currents differ from the engine's by
    more than 1e-4 of their step. With one (--max-overshoot-pct ... as autotune takes them: a drive
    whose motor is not the scenario's), the trace's figures are held against it as autotune holds its
    runs: exit status 1 when one is missed (the binding miss is printed); the agreement with the
    engine is printed for information.
    """
    import json

    from ...outputs import atomic_write, check_out, staged_dir
    from ...sim.metrics import compute_metrics
    from ...studies.drive import check_limits, judge, run_on_drive, save_run
    from ..plots.firmware import plot_drive_run

    spec = {name: value for name, value in limits.items() if value is not None}
    try:
        check_limits(spec)
    except ConfigError as exc:
        raise as_option(exc, SPEC_OPTIONS) from None
    chosen, _ = chosen_scenario(scenario, overrides)
    check_out(out, "drive-run", force)
    with _open(url, a2l, allow_remote) as link, warnings_as_lines():
        result = run_on_drive(link, chosen)
    c = result.comparison()
    verdict = judge(result.drive, spec) if spec else None
    with staged_dir(out, "drive-run", force) as tmp:
        save_run(result.drive, tmp / "trace.csv")
        metrics = {"drive": compute_metrics(result.drive), "engine": compute_metrics(result.engine), "comparison": c}
        if verdict is not None:
            metrics["spec"] = verdict
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        plot_drive_run(result, tmp / "plot.png")
    click.echo(f"{chosen.name}: {result.drive.t_s[-1]:g} s on the drive at {result.url}, {result.plan.why}")
    for group in ("speed", "currents"):
        g = c[group]
        click.echo(f"  {group:<8} drive - engine: {g['max_abs_difference']:.3g} at most, "
                   f"{g['relative_to_step']:.3g} of the step {g['step']:.4g}")  # fmt: skip
    if verdict is not None:
        _echo_verdict(verdict)
    click.echo(f"wrote trace.csv, metrics.json and plot.png to {out}")
    if verdict is not None:
        if not verdict["met"]:
            raise click.exceptions.Exit(1)
    elif not c["agrees"]:
        click.echo(f"the drive's trace differs from the engine's by more than {c['agreement']:g} of the step")
        raise click.exceptions.Exit(1)


def _echo_verdict(verdict: dict[str, Any]) -> None:
    """The drive's figures against the specification, and the binding miss."""
    from ...studies.autotune import CONSTRAINTS

    for name, limit in verdict["limits"].items():
        figure, sense, unit = CONSTRAINTS[name]
        value = verdict["figures"][figure]
        shown = "never reached" if value is None else f"{value:.4g} {unit}"
        click.echo(f"  {figure:<22} {shown:>14}  ({sense} {limit:g} {unit})")
    if verdict["met"]:
        click.echo("the drive meets the specification")
    else:
        m = verdict["misses"][0]
        value = "inf" if m["value"] is None else f"{m['value']:.4g}"
        click.echo(f"the drive misses the specification: binding {m['constraint']} = {m['limit']:g} {m['unit']}, "
                   f"the drive's {value} {m['unit']}")  # fmt: skip


@drive.command()
@click.argument("scenario")
@set_option()
@click.option("--port", type=int, default=5555, show_default=True, help="TCP port on 127.0.0.1 (0: a free one)")
@out_option("the drive's build folder (its A2L file virtual_drive_host.a2l)", type=click.Path(file_okay=False),
            required=True)  # fmt: skip
@click.option("--realtime/--fast", default=True, show_default=True,
              help="the control interrupt on the wall clock, or as fast as the link allows")  # fmt: skip
@click.option("--timeout-ms", type=int, default=200, show_default=True, help="the link watchdog [ms], 0: off")
@click.option(
    "--duration-s", "duration_s", type=float, default=None, help="serve this long [s] [default: until Ctrl-C]"
)
def serve(scenario: str, overrides: tuple[str, ...], port: int, out: str, force: bool, realtime: bool,
          timeout_ms: int, duration_s: float | None) -> None:  # fmt: skip
    """Build the PC's virtual drive of a scenario (the firmware over the engine's plant) into OUT and serve it on
    TCP at 127.0.0.1:PORT until Ctrl-C (or --duration-s); OUT holds its A2L file for the other commands."""
    from ...studies.drive import serve_drive

    chosen, _ = chosen_scenario(scenario, overrides)

    def ready(url: str, a2l: str) -> None:
        click.echo(f"{chosen.name}: serving --link {url} --a2l {a2l} (Ctrl-C ends it)")

    try:
        serve_drive(chosen, out, port=port, realtime=realtime, timeout_ms=timeout_ms, force=force,
                    duration_s=duration_s, ready=ready)  # fmt: skip
    except ConfigError as exc:
        raise as_option(exc, DURATION) from None
    click.echo("the drive stopped")


@drive.command()
@out_option("the folder for result.json, log.csv, plot.png and motor.toml (the identified motor)",
            type=click.Path(file_okay=False), required=True)  # fmt: skip
@link_option
def commission(out: str, force: bool, url: str, a2l: str, allow_remote: bool) -> None:
    """Run the commissioning routine (commission.h) on the drive: Rs, Ld, Lq and psi_f of its motor.

    The routine's settings follow from the motor data the drive's controllers hold and the DC link it
    measures; each step is printed as the drive enters it. Writes the report of `pmsm2dof commission`:
    OUT/result.json, log.csv (the routine's signals at the speed event), plot.png and, when it ends
    done, motor.toml. A failed routine names the step and why, and exits with 1; a link that drops
    leaves the drive's watchdog to end the routine (power stage off), exit status 2.
    """
    from ...outputs import check_out, staged_dir
    from ...studies.drive_commission import commission_on_drive, drive_scenario
    from .commission import write_commission

    check_out(out, "drive-commission", force)

    def progress(step: str, t_s: float) -> None:
        click.echo(f"  {t_s:8.4f} s  {step}")

    with _open(url, a2l, allow_remote) as link:
        configured = drive_scenario(link).motor
        click.echo(f"commissioning the drive at {link.url}")
        result = commission_on_drive(link, progress=progress)
    with staged_dir(out, "drive-commission", force) as tmp:
        write_commission(result, configured.pole_pairs, tmp)
    click.echo(_commission_table(result, configured))
    written = "result.json, log.csv, plot.png" + (", motor.toml" if result.phase == "done" else "")
    click.echo(f"wrote {written} to {out}")
    if result.phase != "done":
        raise click.exceptions.Exit(1)


def _commission_table(result: Any, configured: "MotorTable") -> str:
    """The estimates beside the values the drive's controllers hold, and the time of each step."""
    units = {"Rs_ohm": "ohm", "Ld_H": "H", "Lq_H": "H", "psi_f_Wb": "Wb"}
    lines = [f"commissioning {result.phase}"]
    if result.phase != "done":
        lines.append(f"  failed in {result.failed_phase}: {result.reason} ({result.reason_text})")
    lines.append(f"  {'':<9}{'identified':>13}{'configured':>13}")
    for key, unit in units.items():
        lines.append(f"  {key:<9}{result.estimates[key]:>13.6g}{getattr(configured, key):>13.6g}  [{unit}]")
    lines.append("  step        time [s]")
    for phase, t in result.phase_time_s.items():
        lines.append(f"  {phase:<12}{t:>8.4g}")
    lines.append(f"  {'total':<12}{sum(result.phase_time_s.values()):>8.4g}")
    return "\n".join(lines)


@drive.command()
@click.option("--electrical", is_flag=True,
              help="identify Rs, Ld, Lq and psi_f from current steps captured at the current period, in place of "
                   "the mechanics")  # fmt: skip
@click.option("--speed-max-rpm", type=float, default=None,
              help="largest speed of the plan [rpm] (default: where the voltage at the current limit reaches "
                   "0.9 u_dc / sqrt(3); --electrical: half the speed where it does at half the current "
                   "limit)")  # fmt: skip
@click.option("--motor", "motor_file", type=click.Path(dir_okay=False), default=None,
              help="the motor's data for the torque from the currents (the motor.toml of drive commission); "
                   "default: the drive's configuration (not with --electrical)")  # fmt: skip
@out_option("the folder for capture.csv, plan.toml and what identify mechanics writes (fit.png, rows.csv, "
            "identified.toml, identify.json); --electrical: capture.csv, plan.json and what identify electrical "
            "writes (fit.png, residuals.csv, motor.toml, identify.json)",
            type=click.Path(file_okay=False), required=True)  # fmt: skip
@link_option
def identify(electrical: bool, speed_max_rpm: float | None, motor_file: str | None, out: str, force: bool, url: str,
             a2l: str, allow_remote: bool) -> None:  # fmt: skip
    """Play the identification plan on the drive, capture it, and identify the inertia J and the friction, or
    with --electrical the motor's Rs, Ld, Lq and psi_f.

    The plan (pmsm2dof identify plan: speed steps at the current limit, both directions) is made for the
    drive's own configuration: its current limit, DC link and the inertia its speed controller is designed
    for. The speed reading and the dq currents are captured at every speed sample (OUT/capture.csv) and
    fitted as `pmsm2dof identify mechanics capture.csv --motor MOTOR` would; OUT/identified.toml is the
    drive's configuration with the values found (its speed controller designed for the J found).

    --electrical: the drive's identification routine plays dq current steps (d-axis steps at standstill,
    q-axis steps between two speeds), made for its current limit and DC link; the dq currents, voltages
    and the speed are captured at every current period in the drive's capture buffer, one window a play
    (OUT/capture.csv), and fitted as `pmsm2dof identify electrical capture.csv --u-dc-V U_DC` would, with
    its outputs (motor.toml: the motor found). A link that drops leaves the drive's watchdog to stop the
    motor, power stage off (exit status 2).
    """
    if electrical:
        if motor_file is not None:
            raise ConfigError("--motor", motor_file, "not given with --electrical (the fit needs no motor data)")
        _identify_electrical(speed_max_rpm, out, force, url, a2l, allow_remote)
        return
    from ...core.motor import load_motor
    from ...outputs import atomic_write, check_out, staged_dir
    from ...sim.logs import read_log
    from ...studies.drive_commission import drive_scenario
    from ...studies.drive_identify import capture_plan, plan_on_drive
    from ...studies.identify import (
        identified_toml,
        identify_mechanics,
        torque_from_currents,
    )
    from ...studies.identify_log import MechanicsReport, write_mechanics
    from ..plots.identify import plot_fit

    check_out(out, "drive-identify", force)
    motor = load_motor(motor_file) if motor_file is not None else None
    with staged_dir(out, "drive-identify", force) as tmp:
        with _open(url, a2l, allow_remote) as link, warnings_as_lines():
            drive = drive_scenario(link)
            try:
                plan = plan_on_drive(link, speed_max_rpm)
            except ConfigError as exc:
                raise as_option(exc, {"speed_max_rpm": "--speed-max-rpm"}) from None
            for entry in plan.reference:
                click.echo(f"  t = {entry.t_s:8.4g} s: speed reference {entry.speed_rpm:8.5g} rpm")
            t_start = time.perf_counter()
            samples = capture_plan(link, plan, tmp / "capture.csv")
            wall_s = time.perf_counter() - t_start
        click.echo(f"captured {samples} speed samples ({plan.simulation.t_end_s:g} s of the drive) in "
                   f"{wall_s:.3g} s")  # fmt: skip
        atomic_write(tmp / "plan.toml", plan.to_toml())
        measured = read_log(tmp / "capture.csv")
        # the torque from the currents with the motor's data: the given file's, or what the drive holds
        d = drive.motor if motor is None else motor
        p, psi, Ld, Lq = d.pole_pairs, d.psi_f_Wb, d.Ld_H, d.Lq_H
        mech = identify_mechanics(measured, torque_Nm=torque_from_currents(measured, p, psi, Ld, Lq))
        report = mech.to_json()
        text = identified_toml(mech, None, drive, f"the drive at {url} by pmsm2dof drive identify")
        write_mechanics(tmp, mech, text, report, plot_fit)
    for line in MechanicsReport(mech, None, None, report, None).lines():
        click.echo(line)
    click.echo(f"wrote capture.csv, plan.toml, fit.png, rows.csv, identified.toml and identify.json to {out}")


def _identify_electrical(speed_max_rpm: float | None, out: str, force: bool, url: str, a2l: str,
                         allow_remote: bool) -> None:  # fmt: skip
    """drive identify --electrical: the plan played and captured, the fit and the outputs of identify electrical."""
    import json

    from ...outputs import atomic_write, check_out, staged_dir
    from ...studies.drive_electrical import identify_on_drive
    from ...studies.identify_log import ElectricalReport, write_electrical
    from ..plots.identify import plot_electrical_fit

    check_out(out, "drive-identify-electrical", force)

    def progress(window: int, t_s: float) -> None:
        click.echo(f"  window {window:3d}: {t_s:8.4f} s of the plan captured")

    with staged_dir(out, "drive-identify-electrical", force) as tmp:
        with _open(url, a2l, allow_remote) as link:
            click.echo(f"identifying the motor of the drive at {link.url}")
            t_start = time.perf_counter()
            try:
                plan, fit, drive = identify_on_drive(link, tmp / "capture.csv", speed_max_rpm=speed_max_rpm,
                                                     progress=progress)  # fmt: skip
            except ConfigError as exc:
                raise as_option(exc, {"speed_max_rpm": "--speed-max-rpm"}) from None
            wall_s = time.perf_counter() - t_start
        click.echo(f"plan: current steps of {plan.i_A:.4g} A, d axis at standstill, q axis up to "
                   f"{plan.w_high_radps * 30 / math.pi:.5g} rpm; {fit.n_samples} current periods "
                   f"captured in {wall_s:.3g} s")  # fmt: skip
        atomic_write(tmp / "plan.json", json.dumps(plan.to_json(), indent=2) + "\n")
        source = f"the capture of the drive at {url} (drive identify --electrical)"
        write_electrical(tmp, fit, drive.motor.pole_pairs, source, plot_electrical_fit)
    for line in ElectricalReport(fit, fit.to_json(), None).lines():
        click.echo(line)
    written = "capture.csv, plan.json, fit.png, residuals.csv, " + ("ranges.csv, " if fit.ranges else "")
    click.echo(f"wrote {written}motor.toml and identify.json to {out}")
