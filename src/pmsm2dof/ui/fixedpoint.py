"""The fixed-point scaling check of ``pmsm2dof design --fixed-point q15|q31``.

The command line's edge of :func:`pmsm2dof.analysis.fixedpoint.scaling_check`: the full scales in
the units of the options (the speed in rpm), the torque limit from the header's motor options when
they are given, and the library's errors named by their options.
"""

import math
from typing import TYPE_CHECKING, Any, cast

import click

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..analysis.design import Design
    from ..analysis.scaling_report import ScalingReport
    from ..core.fixedpoint import Format

RPM_PER_RADPS = 30.0 / math.pi
#: The option of each parameter of scaling_check that the command line sets.
_OPTIONS = {
    "fmt": "--fixed-point",
    "speed_full_scale_radps": "--speed-full-scale-rpm",
    "torque_full_scale_Nm": "--torque-full-scale-Nm",
    "T_max_Nm": "--i-max-A",
    "Ts_s": "--Ts-s",
}


def design_scaling_check(
    design: "Design",
    Ts_s: float,
    method: Any,
    fmt: str | None,
    speed_full_scale_rpm: float | None,
    torque_full_scale_Nm: float | None,
    i_max_A: float | None,
    pole_pairs: int | None,
    psi_f_Wb: float | None,
) -> "ScalingReport | None":
    """The scaling check of ``design`` at ``Ts_s`` in ``fmt``, or None without ``--fixed-point``.

    The torque limit is ``1.5 p psi_f i_max`` when --i-max-A, --pole-pairs and --psi-f-Wb (or --motor)
    give it, else the torque full scale (the check's default).

    Raises
    ------
    click.UsageError
        A full scale without --fixed-point, or --fixed-point without both full scales.
    ConfigError
        A value out of range, named by its option (the speed in rpm).
    """
    scales = {"--speed-full-scale-rpm": speed_full_scale_rpm, "--torque-full-scale-Nm": torque_full_scale_Nm}
    if fmt is None:
        given = [option for option, value in scales.items() if value is not None]
        if given:
            raise click.UsageError(f"{' and '.join(given)} need --fixed-point q15 or q31")
        return None
    if speed_full_scale_rpm is None or torque_full_scale_Nm is None:
        missing = " and ".join(option for option, value in scales.items() if value is None)
        raise click.UsageError(f"--fixed-point needs {missing} (the speed and torque of the integer 2^N)")
    from ..analysis.fixedpoint import scaling_check

    T_max_Nm = None
    if i_max_A is not None and pole_pairs is not None and psi_f_Wb is not None:
        T_max_Nm = 1.5 * pole_pairs * psi_f_Wb * i_max_A
    try:
        return scaling_check(
            design,
            Ts_s,
            fmt=cast("Format", fmt),  # any string from the command line: the check validates it
            speed_full_scale_radps=speed_full_scale_rpm / RPM_PER_RADPS,
            torque_full_scale_Nm=torque_full_scale_Nm,
            method=method,
            T_max_Nm=T_max_Nm,
        )
    except ConfigError as exc:
        if exc.param == "speed_full_scale_radps":
            raise ConfigError("--speed-full-scale-rpm", speed_full_scale_rpm, _rpm_range(exc.valid)) from None
        if exc.param in _OPTIONS:
            raise ConfigError(_OPTIONS[exc.param], exc.value, exc.valid) from None
        raise


def _rpm_range(valid: str) -> str:
    """The valid range of speed_full_scale_radps said for the option in rpm."""
    return f"{valid} (speed_full_scale_radps = --speed-full-scale-rpm * pi/30)"


def report_dict(report: "ScalingReport") -> dict[str, Any]:
    """The report as JSON-ready data: speeds in rad/s and rpm, infinite values as None."""

    def finite(x: float) -> float | None:
        return x if math.isfinite(x) else None

    dz = report.dead_zone
    return {
        "fmt": report.fmt,
        "flagged": report.flagged,
        "speed_full_scale_radps": report.speed_full_scale_radps,
        "torque_full_scale_Nm": report.torque_full_scale_Nm,
        "T_max_Nm": report.T_max_Nm,
        "coefficients": [
            {
                "name": g.name,
                "exact": g.exact,
                "mantissa": g.mantissa,
                "shift": g.shift,
                "relative_error": g.relative_error,
                "plain_counts": g.plain_counts,
                "plain_relative_error": g.plain_relative_error,
            }
            for g in report.gains
        ],
        "dead_zone": {
            "low_radps": finite(dz.low_radps),
            "high_radps": finite(dz.high_radps),
            "width_rpm": finite(dz.width_radps * RPM_PER_RADPS),
            "removed": dz.removed,
        },
        "limit_cycle_radps": finite(report.limit_cycle_radps),
        "headroom": [
            {"signal": h.signal, "bound_pu": finite(h.bound_pu), "bits": finite(h.bits)} for h in report.headroom
        ],
        "proposals": [
            {
                "change": p.change,
                "value": p.value,
                "dead_zone_radps": finite(p.dead_zone_radps),
                "feasible": p.feasible,
                "reason": p.reason,
            }
            for p in report.proposals
        ],
    }
