"""``pmsm2dof reproduce`` and ``pmsm2dof sensors``: the paper's studies (pmsm2dof.studies, ui.report)."""

import click

from .options import LINK_OPTIONS, options_named, out_option, parse_override, require_extra, set_option


@click.command(short_help="Reproduce the paper: figures 7-14, sensitivity studies and the claims table.")
@out_option(
    "folder for report.md, report.html, claims.json, the figures and their data",
    default="pmsm2dof-report",
    show_default=True,
)
@set_option("change a scenario key in every preset, e.g. --set motor.psi_f_Wb=0.1 (repeatable)")
@click.option(
    "--link",
    metavar="virtual|URL",
    default=None,
    help="also play experimental conditions 1 to 3 on a drive and check their claims on it: 'virtual', the "
    "PC's virtual drive of each experiment built here (needs cmake and a C compiler), or the link of one drive "
    "whose motor and limits are the paper's (tcp://HOST:PORT, a serial device, can://...; with --a2l); "
    "needs the extra 'drive'",
)
@click.option(
    "--a2l",
    type=click.Path(dir_okay=False),
    default=None,
    help="the A2L file of the drive at --link URL (written beside its firmware's ELF)",
)
@click.option("--allow-remote", is_flag=True, help="connect to a drive on another machine (tcp://HOST)")
def reproduce(
    out: str, force: bool, overrides: tuple[str, ...], link: str | None, a2l: str | None, allow_remote: bool
) -> None:
    """Reproduce the paper: Fig. 7-14 as simulations, sensitivity and discretization studies, claims table.

    Runs the paper's conditions on the presets (the float32 C controller in the compiled
    engine) and writes OUT/report.md, OUT/report.html (self-contained), OUT/claims.json (each
    claim of the paper with the measured value and a verdict), OUT/figures/*.png and *.svg,
    and beside each figure its data (OUT/figures/*.csv), all or nothing. With --link, the
    experiments also run on a drive, captured from the firmware's own signals (its measured speed):
    OUT/drive.json, and the claims of section 4.2 checked on them. On one drive at a URL, condition
    3 (steady at 500 rpm) starts with a pre-roll from rest, checked steady before the recorded part.
    """
    import time

    from ..report import VERDICTS
    from ..report import reproduce as run_reproduction

    start = time.perf_counter()
    if link is not None:
        require_extra("pyxcp", "drive", "pmsm2dof reproduce --link")
    changes = dict(parse_override(text) for text in overrides)
    with options_named(LINK_OPTIONS):
        report = run_reproduction(
            out, overrides=changes, progress=True, force=force, link=link, a2l=a2l, allow_remote=allow_remote
        )
    for claim in report.claims:
        on_drive = f"  (on the drive: {claim.on_drive.verdict})" if claim.on_drive is not None else ""
        click.echo(f"  {claim.id:>4}  {claim.verdict:<15} {claim.claim}{on_drive}")
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


@click.command(short_help="Sensor chains against the paper's experiments: overshoot, load dip, margins.")
@set_option("change a scenario key of both experiments first, e.g. --set motor.J_kgm2=0.5 (repeatable)")
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

    from ...outputs import atomic_write, check_out, staged_dir
    from ...studies.sensing import offset_study, sensor_study
    from ..report.render import render_markdown
    from ..report.sensing import sensing_blocks

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
