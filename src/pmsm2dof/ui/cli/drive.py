"""``pmsm2dof drive``: the drive over XCP (pyxcp, the ``drive`` extra) by its A2L file.

Each command parses its options and calls one function of :mod:`pmsm2dof.drive.session` or
:mod:`pmsm2dof.studies.drive`; the link is one option, ``--link URL`` (:func:`link_option`).
"""

from collections.abc import Callable
from typing import Any

import click

from ...errors import ConfigError
from .options import Group, as_option, chosen_scenario, out_option, set_option, warnings_as_lines

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


@click.group(cls=Group, short_help="Talk to a drive over XCP: info, get, set, capture, run, serve.")
def drive() -> None:
    """Talk to a drive (the firmware of examples/firmware, on an MCU, on QEMU or the PC's virtual drive) over
    XCP, by the names of its A2L file: read and write its variables, capture signals by DAQ, play a
    scenario on it beside the engine's simulation, or serve the PC's virtual drive of a scenario.
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
@click.argument("assignments", nargs=-1, required=True, metavar="NAME=VALUE...")
@link_option
def set_(assignments: tuple[str, ...], url: str, a2l: str, allow_remote: bool) -> None:
    """Write calibration variables, checked first against the A2L's limits and the controller's own validation;
    the fields of one variable take effect together at the drive's next speed sample."""
    from ...drive.session import set_values

    with _open(url, a2l, allow_remote) as link:
        for name, value, unit in set_values(link, assignments):
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


@drive.command()
@click.argument("scenario")
@set_option()
@out_option("the folder for trace.csv, metrics.json and plot.png", type=click.Path(file_okay=False), required=True)
@link_option
def run(scenario: str, overrides: tuple[str, ...], out: str, force: bool, url: str, a2l: str,
        allow_remote: bool) -> None:  # fmt: skip
    """Play a scenario's reference and load on the drive (a build of it) and hold the trace against the engine.

    Writes OUT/trace.csv (the drive's trace in the engine's log format), OUT/metrics.json (the figures
    of merit, the agreement) and OUT/plot.png (the drive over the engine). Exit status 1 when the
    speed or the currents differ from the engine's by more than 1e-4 of their step.
    """
    import json

    from ...outputs import atomic_write, check_out, staged_dir
    from ...sim.metrics import compute_metrics
    from ...studies.drive import run_on_drive
    from ..plots.firmware import plot_drive_run

    chosen, _ = chosen_scenario(scenario, overrides)
    check_out(out, "drive-run", force)
    with _open(url, a2l, allow_remote) as link, warnings_as_lines():
        result = run_on_drive(link, chosen)
    c = result.comparison()
    with staged_dir(out, "drive-run", force) as tmp:
        result.drive.save(tmp / "trace.csv")
        metrics = {"drive": compute_metrics(result.drive), "engine": compute_metrics(result.engine), "comparison": c}
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        plot_drive_run(result, tmp / "plot.png")
    click.echo(f"{chosen.name}: {result.drive.t_s[-1]:g} s on the drive at {result.url}")
    for group in ("speed", "currents"):
        g = c[group]
        click.echo(f"  {group:<8} drive - engine: {g['max_abs_difference']:.3g} at most, "
                   f"{g['relative_to_step']:.3g} of the step {g['step']:.4g}")  # fmt: skip
    click.echo(f"wrote trace.csv, metrics.json and plot.png to {out}")
    if not c["agrees"]:
        click.echo(f"the drive's trace differs from the engine's by more than {c['agreement']:g} of the step")
        raise click.exceptions.Exit(1)


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
