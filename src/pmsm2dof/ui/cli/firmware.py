"""``pmsm2dof header`` and ``pmsm2dof firmware``: the C configuration and the firmware (pmsm2dof.studies.firmware)."""

import click

from ...errors import ConfigError
from .options import chosen_scenario, out_option, set_option, warnings_as_lines


@click.command()
@click.argument("scenario", metavar="PRESET_OR_FILE")
@set_option("change a scenario key (repeatable)")
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
    from ...outputs import atomic_write, check_file
    from ...studies.configuration import configuration
    from ...studies.virtual_drive import virtual_drive_header

    options = {out: "--out"} if virtual_drive is None else {out: "--out", virtual_drive: "--virtual-drive"}
    for path, option in options.items():
        check_file(path, option)
    chosen, named = chosen_scenario(scenario, overrides)
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


@click.command(short_help="Build the firmware for a scenario, or run it on QEMU against the engine.")
@click.argument("args", nargs=-1, metavar="PRESET_OR_FILE | run DIR")
@set_option("build: change a scenario key (repeatable)")
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
    from ...studies.firmware import build_firmware

    chosen, named = chosen_scenario(args[0], overrides)
    with warnings_as_lines():
        build = build_firmware(chosen, out, source=f"pmsm2dof firmware {named}", force=force)
    for name, size in build.sizes.items():
        click.echo(f"  {name:<18} flash {size['text'] + size['data']:>7} B, RAM {size['data'] + size['bss']:>6} B")
    click.echo(f"{chosen.name}: wrote scenario.toml, p2d_config.h, p2d_virtual_drive.h, the ELF and map files to {out}")


def _firmware_run(folder: str, out: str, force: bool, samples: int | None) -> None:
    """``pmsm2dof firmware run DIR --out RUN``."""
    import json

    from ...outputs import atomic_write, check_out, csv_text, staged_dir
    from ...sim.metrics import compute_metrics
    from ...studies.firmware import run_firmware
    from ..plots.firmware import plot_firmware

    check_out(out, "firmware-run", force)
    run = run_firmware(folder, samples=samples)
    comparison, cost = run.comparison(), run.cost()
    metrics = {"firmware": compute_metrics(run.firmware), "comparison": comparison, "interrupts": cost}
    with staged_dir(out, "firmware-run", force) as tmp:
        run.firmware.save(tmp / "trace.csv")
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=2, allow_nan=False) + "\n")
        plot_firmware(run, tmp / "plot.png")
        rows = [{"instructions": int(n), "speed_sample": int(s)} for n, s in zip(run.instructions, run.speed_sample)]
        atomic_write(tmp / "interrupts.csv", csv_text(rows))
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
