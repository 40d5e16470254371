"""C header holding a designed speed-controller configuration.

The firmware includes the header and passes its ``static const`` configuration
to ``p2d_speed_init`` (and, when the motor resistance and the current-loop
sampling period are given, a second one to ``p2d_current_init``); the C core
computes the coefficients from it, exactly as in the simulations. A comment
block records every design input and the derived values, so that the numbers
on the MCU can be traced back to the design.

Every configuration is first given to the C core itself (through
:mod:`pmsm2dof.core`), so a header is only written when its
configuration initializes without error.
"""

import re
from collections.abc import Iterable, Mapping, Sequence
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from ..core import ANTI_WINDUPS, FEEDFORWARDS, METHODS, CurrentController, SpeedController
from ..core.bindings import AntiWindup, Method
from ..errors import ConfigError, require_choice, require_positive
from ..outputs import atomic_write

if TYPE_CHECKING:
    from .discretize import DiscreteDesign

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

# field: (unit, meaning) of p2d_speed_config_t, in declaration order
_SPEED_FIELDS = {
    "J_kgm2": ("kg m^2", "design inertia (eq 2, 9)"),
    "alpha_radps": ("rad/s", "bandwidth of the P loop (eq 9)"),
    "zeta": ("-", "relative damping of the PI loop (eq 9)"),
    "m": ("-", "tracking pole factor, Gx = m alpha / (s + m alpha) (eq 10)"),
    "tau_i_s": ("s", "current-loop time constant (eq 3)"),
    "Ka": ("(rad/s)/Nm", "back-calculation gain (Fig. 5)"),
    "Ts_s": ("s", "sampling period"),
    "i_max_A": ("A", "current-vector limit ||i_dq|| <= i_max_A"),
    "psi_f_Wb": ("Wb", "permanent-magnet flux linkage"),
    "Ld_H": ("H", "d-axis inductance"),
    "Lq_H": ("H", "q-axis inductance"),
    "pole_pairs": ("-", "pole pairs p, Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)"),
    "method": ("", "discretization (Table 1)"),
    "feedforward": ("", "2DOF feedforward form"),
    "anti_windup": ("", "integrator anti-windup"),
}
# field: (unit, meaning) of p2d_current_config_t, in declaration order
_CURRENT_FIELDS = {
    "Rs_ohm": ("ohm", "stator resistance"),
    "Ld_H": ("H", "d-axis inductance"),
    "Lq_H": ("H", "q-axis inductance"),
    "psi_f_Wb": ("Wb", "permanent-magnet flux linkage"),
    "tau_i_s": ("s", "closed current-loop time constant (eq 3): Kp = L/tau_i, Ki = Rs/tau_i"),
    "Ts_s": ("s", "current-loop sampling period"),
    "method": ("", "discretization (Table 1)"),
    "anti_windup": ("", "anti-windup per axis, Ka = 1/Kp"),
    "decouple": ("", "back-EMF and cross-coupling feedforward (eq 1)"),
}
# field: (unit, meaning) of p2d_filter_config_t, in declaration order (csrc/include/pmsm2dof/filter.h)
_FILTER_FIELDS = {
    "notch_freq_Hz": ("Hz", "notch frequency f0; 0: no notch"),
    "notch_width_Hz": ("Hz", "-3 dB width of the notch"),
    "notch_depth": ("-", "gain of the notch at f0"),
    "lowpass_freq_Hz": ("Hz", "low-pass natural frequency; 0: no low-pass"),
    "lowpass_zeta": ("-", "low-pass damping"),
}
# C enumerator prefix of each choice field
_ENUMS = {
    "method": ("P2D_", METHODS),
    "feedforward": ("P2D_FF_", FEEDFORWARDS),
    "anti_windup": ("P2D_AW_", ANTI_WINDUPS),
}


def c_float(x: float) -> str:
    """A C float literal (``f`` suffix) with the shortest digits that round-trip ``float32(x)``."""
    if not abs(float(x)) <= float(np.finfo(np.float32).max):
        raise ConfigError("value", x, "finite in float32 (|x| <= 3.4e38)")
    f = np.float32(x)
    if f == 0.0 or 1e-4 <= abs(f) < 1e7:
        return np.format_float_positional(f, unique=True, trim="0") + "f"
    return np.format_float_scientific(f, unique=True, trim="0") + "f"


def _c_value(name: str, value: Any) -> str:
    """The C initializer of one configuration field."""
    if name in _ENUMS:
        prefix, _ = _ENUMS[name]
        return prefix + str(value).upper()
    if name == "pole_pairs":
        return f"{value}u"
    if name == "decouple":
        return "true" if value else "false"
    return c_float(value)


def _initializer(
    ctype: str, identifier: str, config: Mapping[str, Any], fields: Mapping[str, tuple[str, str]]
) -> list[str]:
    lines = [f"static const {ctype} {identifier} = {{"]
    for name, (unit, meaning) in fields.items():
        assignment = f"    .{name} = {_c_value(name, config[name])},"
        comment = f"{meaning} [{unit}]" if unit else meaning
        lines.append(f"{assignment:<44}/* {comment} */")
    lines.append("};")
    return lines


def speed_config(
    discrete: "DiscreteDesign", *, i_max_A: float, pole_pairs: int, psi_f_Wb: float, Ld_H: float, Lq_H: float
) -> dict[str, Any]:
    """Keyword arguments of :class:`~pmsm2dof.core.controllers.SpeedController` for a discrete design.

    They hold the same values as the ``p2d_speed_config_t`` of the header.
    """
    d = discrete.design
    return dict(
        J_kgm2=d.J_kgm2,
        alpha_radps=d.alpha_radps,
        zeta=d.zeta,
        m=d.m,
        tau_i_s=d.tau_i_s,
        Ka=d.Ka,
        Ts_s=discrete.Ts_s,
        i_max_A=i_max_A,
        psi_f_Wb=psi_f_Wb,
        Ld_H=Ld_H,
        Lq_H=Lq_H,
        pole_pairs=pole_pairs,
        method=discrete.method,
        feedforward=d.feedforward,
        anti_windup=d.anti_windup,
    )


def c_header(
    discrete: "DiscreteDesign",
    *,
    i_max_A: float,
    pole_pairs: int,
    psi_f_Wb: float,
    Ld_H: float,
    Lq_H: float,
    Rs_ohm: float | None = None,
    Ts_current_s: float | None = None,
    current_method: Method | None = None,
    current_anti_windup: AntiWindup = "back_calculation",
    decouple: bool = True,
    prefix: str = "p2d_design",
    motor_sources: Mapping[str, str] | None = None,
    speed_filter: Mapping[str, float] | None = None,
) -> str:
    """The text of a C header configuring the controllers with ``discrete``.

    Parameters
    ----------
    discrete : DiscreteDesign
        The design discretized for the speed-loop sampling period and method.
    i_max_A : float
        Current-vector limit ``||i_dq|| <= i_max_A`` [A], > 0.
    pole_pairs : int
        Pole pairs p [-], >= 1. The torque is ``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``
        (amplitude-invariant Park); the paper's eq (1) omits the 1.5 and calls p0
        the number of poles while using it as pole pairs.
    psi_f_Wb : float
        Permanent-magnet flux linkage [Wb], > 0.
    Ld_H, Lq_H : float
        dq inductances [H], > 0; equal for a surface PMSM (id = 0), else MTPA.
    Rs_ohm : float, optional
        Stator resistance [ohm]. With ``Ts_current_s`` it adds a ``p2d_current_config_t``
        whose loop time constant is the design's ``tau_i_s`` (eq 3).
    Ts_current_s : float, optional
        Current-loop sampling period [s], > 0, <= ``tau_i_s``.
    current_method : str, optional
        Discretization of the current PIs; default the speed-loop method.
    current_anti_windup : str, optional
        Anti-windup of the current PIs.
    decouple : bool, optional
        Back-EMF and cross-coupling feedforward in the current loop.
    prefix : str, optional
        C identifier prefix: the header defines ``<prefix>_speed_config``
        (and ``<prefix>_current_config``) and the guard ``<PREFIX>_H``.
    motor_sources : dict, optional
        Where motor values came from, ``{keyword: text}`` (for example a placeholder drive);
        recorded next to each value in the header's comment.
    speed_filter : dict, optional
        Torque filters of the speed controller, the fields of ``p2d_filter_config_t``
        (``notch_freq_Hz``, ``notch_width_Hz``, ``notch_depth``, ``lowpass_freq_Hz``,
        ``lowpass_zeta``; absent ones 0). Adds ``<prefix>_speed_filter`` for
        ``p2d_speed_set_filter()``, validated by the C core with the speed configuration.

    Returns
    -------
    str

    Raises
    ------
    ConfigError
        An invalid prefix or motor value, or a configuration the C core rejects.
    """
    if not isinstance(prefix, str) or not _IDENTIFIER.match(prefix):
        raise ConfigError("prefix", prefix, "a C identifier: a letter or '_' then letters, digits or '_'")
    speed = speed_config(discrete, i_max_A=i_max_A, pole_pairs=pole_pairs, psi_f_Wb=psi_f_Wb, Ld_H=Ld_H, Lq_H=Lq_H)
    filters: dict[str, float] | None = None
    if speed_filter:
        unknown = sorted(set(speed_filter) - set(_FILTER_FIELDS))
        if unknown:
            raise ConfigError(
                unknown[0], speed_filter[unknown[0]], "a field of p2d_filter_config_t: " + ", ".join(_FILTER_FIELDS)
            )
        filters = {name: speed_filter.get(name, 0.0) for name in _FILTER_FIELDS}
    speed_ctl = SpeedController(**speed, **cast(dict[str, Any], filters or {}))
    current: dict[str, Any] | None = None
    if Rs_ohm is not None or Ts_current_s is not None:
        if Rs_ohm is None:
            raise ConfigError("Rs_ohm", Rs_ohm, "finite and > 0 when Ts_current_s is given")
        if Ts_current_s is None:
            raise ConfigError("Ts_current_s", Ts_current_s, "finite and > 0 when Rs_ohm is given")
        current_method = discrete.method if current_method is None else current_method
        require_choice("current_method", current_method, METHODS)
        require_choice("current_anti_windup", current_anti_windup, ANTI_WINDUPS)
        current = dict(
            Rs_ohm=require_positive("Rs_ohm", Rs_ohm),
            Ld_H=Ld_H,
            Lq_H=Lq_H,
            psi_f_Wb=psi_f_Wb,
            tau_i_s=discrete.design.tau_i_s,
            Ts_s=require_positive("Ts_current_s", Ts_current_s),
            method=current_method,
            anti_windup=current_anti_windup,
            decouple=decouple,
        )
        CurrentController(**current)

    lines = ["/*", f" * {prefix}.h: controller configuration designed with pmsm2dof {version('pmsm2dof')}.", " *"]
    record = _record(discrete, speed, speed_ctl, current, motor_sources or {})
    lines += [" * " + line if line else " *" for line in record]
    lines += [
        " */",
        f"#ifndef {prefix.upper()}_H",
        f"#define {prefix.upper()}_H",
        "",
        "#include <stdbool.h>",
        "",
        '#include "pmsm2dof/speed.h"',
    ]
    if current is not None:
        lines.append('#include "pmsm2dof/current.h"')
    lines += ["", "/* Pass to p2d_speed_init(); the C core computes the coefficients listed above. */"]
    lines += _initializer("p2d_speed_config_t", f"{prefix}_speed_config", speed, _SPEED_FIELDS)
    if filters is not None:
        lines += ["", "/* Pass to p2d_speed_set_filter() after p2d_speed_init(): the torque filters (filter.h). */"]
        lines += _initializer("p2d_filter_config_t", f"{prefix}_speed_filter", filters, _FILTER_FIELDS)
    if current is not None:
        lines += ["", "/* Pass to p2d_current_init(). */"]
        lines += _initializer("p2d_current_config_t", f"{prefix}_current_config", current, _CURRENT_FIELDS)
    lines += ["", f"#endif /* {prefix.upper()}_H */", ""]
    return "\n".join(lines)


def _record(
    discrete: "DiscreteDesign",
    speed: Mapping[str, Any],
    speed_ctl: SpeedController,
    current: Mapping[str, Any] | None,
    motor_sources: Mapping[str, str],
) -> list[str]:
    """Comment lines recording the design inputs and the derived values."""
    d = discrete.design
    dm = d.margins()
    zm = discrete.margins
    coef = speed_ctl.coefficients
    out = [
        'Anti-windup 2DOF PI speed controller of Wang, Lin, Yang, Fang, "Anti-Windup and',
        '2DOF Design for Permanent-Magnet Synchronous Motor Speed Controller" (Fig. 5, 6).',
        "",
        "Design inputs:",
        f"  J_kgm2      = {d.J_kgm2:.9g} kg m^2",
        f"  alpha_radps = {d.alpha_radps:.9g} rad/s",
        f"  zeta        = {d.zeta:.9g}",
        f"  m           = {d.m:.9g}",
        f"  tau_i_s     = {d.tau_i_s:.9g} s",
        f"  feedforward = {d.feedforward}",
        f"  anti_windup = {d.anti_windup}",
        f"  Ka          = {d.Ka:.9g} (rad/s)/Nm",
        f"  Ts_s        = {discrete.Ts_s:.9g} s",
        f"  method      = {discrete.method}",
        f"  i_max_A     = {speed['i_max_A']:.9g} A" + _source(motor_sources, "i_max_A"),
        f"  pole_pairs  = {speed['pole_pairs']}" + _source(motor_sources, "pole_pairs"),
        f"  psi_f_Wb    = {speed['psi_f_Wb']:.9g} Wb" + _source(motor_sources, "psi_f_Wb"),
        f"  Ld_H        = {speed['Ld_H']:.9g} H" + _source(motor_sources, "Ld_H"),
        f"  Lq_H        = {speed['Lq_H']:.9g} H" + _source(motor_sources, "Lq_H"),
    ]
    if current is not None:
        out += [
            f"  Rs_ohm      = {current['Rs_ohm']:.9g} ohm" + _source(motor_sources, "Rs_ohm"),
            f"  current loop: Ts_s = {current['Ts_s']:.9g} s, method = {current['method']},",
            f"                anti_windup = {current['anti_windup']}, decouple = {current['decouple']}",
        ]
    out += [
        "",
        "Derived, continuous (double precision):",
        f"  Kp = J alpha               = {d.Kp:.9g} Nm/(rad/s) (eq 9)",
        f"  Ki = J (alpha / (2 zeta))^2 = {d.Ki:.9g} Nm/rad (eq 9)",
        f"  Fr(s) = ({_poly_s(d.fr_polynomials()[0])}) / ({_poly_s(d.fr_polynomials()[1])})",
        f"  loop poles: {_complex_list(d.closed_loop_poles())} rad/s",
        f"  tracking bandwidth (-3 dB of Gx) = {d.bandwidth_radps():.6g} rad/s,"
        f" step overshoot = {_overshoot_text(d.overshoot_pct(), d.missing())}",
        f"  margins of F G: gain {dm.gain_margin_dB:.4g} dB, phase {dm.phase_margin_deg:.4g} deg"
        f" at {dm.w_gain_crossover_radps:.4g} rad/s",
        "",
        f"Derived, discrete ({discrete.method}, Ts_s = {discrete.Ts_s:.9g} s; ZOH plant):",
        f"  loop poles: {_complex_list(discrete.poles)}",
        f"  tracking step overshoot = {_overshoot_text(discrete.overshoot_pct, discrete.missing)}",
        f"  margins of F(z) G(z): gain {zm.gain_margin_dB:.4g} dB, phase {zm.phase_margin_deg:.4g} deg",
        "",
        "Coefficients computed by p2d_speed_init from this configuration (float32):",
    ]
    for name in ("Kp", "Ki", "b_e0", "Ki_Ts", "Ki_Ka_Ts", "ff_Fr0", "ff_b_dr", "ff_a1", "ff_Kd_per_Ts", "T_max_Nm"):
        out.append(f"  {name:<12} = {coef[name]:.9g}")
    return out


def _source(motor_sources: Mapping[str, str], name: str) -> str:
    return f" ({motor_sources[name]})" if name in motor_sources else ""


def _overshoot_text(value: float, missing: Mapping[str, str]) -> str:
    return f"{value:.3g} %" if "overshoot_pct" not in missing else f"n/a ({missing['overshoot_pct']})"


def _complex_list(values: Iterable[complex]) -> str:
    return ", ".join(f"{complex(v).real:.6g}" if complex(v).imag == 0 else f"{complex(v):.6g}" for v in values)


def _poly_s(coefficients: Sequence[float] | npt.NDArray[np.float64]) -> str:
    """A polynomial in s, highest power first, as text."""
    terms = []
    for power, c in zip(range(len(coefficients) - 1, -1, -1), coefficients):
        if c != 0.0 or len(coefficients) == 1:
            s_power = {0: "", 1: "s"}.get(power, f"s^{power}")
            terms.append(s_power if c == 1.0 and s_power else f"{c:.6g} {s_power}".rstrip())
    return " + ".join(terms).replace("+ -", "- ") if terms else "0"


def write_c_header(path: Path | str, discrete: "DiscreteDesign", **options: Any) -> Path | str:
    """Write :func:`c_header` of ``discrete`` to ``path`` atomically; return the path.

    ``options`` are the keywords of :func:`c_header`.
    """
    atomic_write(path, c_header(discrete, **options))
    return path
