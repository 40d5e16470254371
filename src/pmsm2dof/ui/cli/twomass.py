"""``pmsm2dof twomass``: the eq 9 design on a two-mass drive train (pmsm2dof.analysis.twomass)."""

from collections.abc import Mapping
from typing import TYPE_CHECKING

import click

from ...errors import ConfigError

if TYPE_CHECKING:
    from ...analysis.design import Design
    from ...analysis.twomass import TwoMass

from .options import as_option, option_name, speed_option


@click.command()
@click.option("--J-motor-kgm2", "J_motor_kgm2", type=float, required=True, help="motor-side inertia J_M [kg m^2], > 0")
@click.option("--J-load-kgm2", "J_load_kgm2", type=float, required=True, help="load-side inertia J_L [kg m^2], > 0")
@click.option(
    "--stiffness-Nm-per-rad", "stiffness_Nm_per_rad", type=float, required=True, help="shaft stiffness K [Nm/rad], > 0"
)
@click.option(
    "--damping-Nms-per-rad",
    "damping_Nms_per_rad",
    type=float,
    default=0.0,
    show_default=True,
    help="shaft damping [Nm s/rad]",
)
@speed_option("alpha_radps", required=True)
@speed_option("zeta", default=0.7, show_default=True)
@speed_option("tau_i_s", default=0.0, show_default=True)
@speed_option("Ts_s", required=True)
@click.option("--feedback", default="motor", show_default=True, help="the speed the controller reads: motor or load")
@click.option("--notch-freq-Hz", "notch_freq_Hz", type=float, default=0.0, help="notch frequency [Hz] (0: none)")
@click.option("--notch-width-Hz", "notch_width_Hz", type=float, default=0.0, help="notch -3 dB width [Hz]")
@click.option("--notch-depth", "notch_depth", type=float, default=0.0, help="notch gain at its frequency [-]")
@click.option("--lowpass-freq-Hz", "lowpass_freq_Hz", type=float, default=0.0, help="low-pass frequency [Hz] (0: none)")
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
    from ...analysis.design import design
    from ...analysis.twomass import sampled_loop, two_mass

    options = {name: option_name(name) for name in ("J_motor_kgm2", "J_load_kgm2", "alpha_radps", "zeta", "tau_i_s")}
    options |= {name: option_name(name) for name in ("stiffness_Nm_per_rad", "damping_Nms_per_rad", "Ts_s", *filters)}
    options |= {"J_kgm2": "--J-motor-kgm2", "feedback": "--feedback", "region": "--region"}
    try:
        train = two_mass(J_motor_kgm2, J_load_kgm2, stiffness_Nm_per_rad, damping_Nms_per_rad)
        d = design(train.J_total_kgm2, alpha_radps, zeta, tau_i_s=tau_i_s)
        loop = sampled_loop(d, train, Ts_s, feedback=feedback, filters=filters)
        if region is not None and not region.lower().endswith((".png", ".svg")):
            raise ConfigError("region", region, "a file name ending in .png or .svg")
    except ConfigError as exc:
        raise as_option(exc, options) from None
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

    from ...outputs import atomic_write
    from ...studies.twomass import region_around
    from ..report.twomass import fig_stable_region

    fig, _data = fig_stable_region(region_around(train, d.alpha_radps, d.zeta, d.tau_i_s, Ts_s, filters))
    buf = io.BytesIO()
    fig.savefig(buf, format=path.rsplit(".", 1)[-1].lower(), dpi=110)
    atomic_write(path, buf.getvalue())
