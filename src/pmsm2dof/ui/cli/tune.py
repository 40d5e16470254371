"""``pmsm2dof tune``: the tuner in the browser (pmsm2dof.ui.tuner)."""

import click

from .options import LINK_OPTIONS, options_named, require_extra


@click.command()
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
@click.option(
    "--a2l",
    type=click.Path(dir_okay=False),
    default=None,
    help="the A2L file of the drive's firmware (written beside its ELF by pmsm2dof firmware)",
)
def tune(scenario: str | None, port: int, host: str, no_browser: bool, link: str | None, a2l: str | None) -> None:
    """Tune the speed controller in the browser: responses redrawn as the sliders move.

    Starts from PRESET_OR_FILE (default: paper-condition-2) and serves a local page with
    sliders for alpha, zeta, m, Ka, the feedforward, anti-windup, discretization and Ts,
    the inertia error and the speed and load steps; downloads the scenario (TOML), the
    C header of the design and the trace (CSV). With --link the page, once armed, writes each
    change to the drive and runs the experiment on it beside its simulation (docs/tuning.md).
    """
    for module in ("starlette", "uvicorn"):
        require_extra(module, "tuner", "pmsm2dof tune")
    from ...sim.plausibility import warn_implausible
    from ...sim.scenario import load_scenario
    from ..tuner import DEFAULT_PRESET, run_tuner

    chosen = load_scenario(scenario or DEFAULT_PRESET)
    warn_implausible(chosen)
    with options_named(LINK_OPTIONS):
        run_tuner(chosen, host=host, port=port, open_browser=not no_browser, link=link, a2l=a2l)
