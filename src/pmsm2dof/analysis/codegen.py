"""C text of a controller configuration: ``static const`` initializers, macros and a record.

The firmware includes the header and passes its ``static const`` configurations to the inits of
the C library (``p2d_speed_init``, ``p2d_current_init``, ...); the C core computes the
coefficients from them, exactly as in the simulations. :func:`config_header` assembles the text;
:func:`pmsm2dof.studies.configuration.configuration` decides what goes in it (the one scenario ->
configuration of every command that writes a header).

Every initializer is written from the C struct itself (a cffi value of the compiled library):
field by field in declaration order, each value exact (float32 and double literals that round-trip,
enumerators by name), each with the comment its C header gives the field (meaning, unit, range;
:func:`pmsm2dof.core.bindings.field_comment`).
"""

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..core.bindings import ffi, field_comment
from ..errors import ConfigError

if TYPE_CHECKING:
    from .discretize import DiscreteDesign

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

#: Column of the comment beside an initialized field.
_COMMENT_COLUMN = 48


def c_float(x: float) -> str:
    """A C float literal (``f`` suffix) with the shortest digits that round-trip ``float32(x)``."""
    if not abs(float(x)) <= float(np.finfo(np.float32).max):
        raise ConfigError("value", x, "finite in float32 (|x| <= 3.4e38)")
    f = np.float32(x)
    if f == 0.0 or 1e-4 <= abs(f) < 1e7:
        return np.format_float_positional(f, unique=True, trim="0") + "f"
    return np.format_float_scientific(f, unique=True, trim="0") + "f"


def c_double(x: float) -> str:
    """A C double literal with the shortest digits that round-trip ``x`` (C compilers round correctly)."""
    if not math.isfinite(x):
        raise ConfigError("value", x, "finite")
    text = repr(float(x))
    return text if any(c in text for c in ".en") else text + ".0"


def check_prefix(prefix: str) -> str:
    """``prefix`` if it is a C identifier, else ConfigError."""
    if not isinstance(prefix, str) or not _IDENTIFIER.match(prefix):
        raise ConfigError("prefix", prefix, "a C identifier: a letter or '_' then letters, digits or '_'")
    return prefix


def _c_value(ctype: Any, value: Any) -> str:
    """The C initializer of one scalar of the cffi type ``ctype``."""
    if ctype.kind == "enum":
        return str(ctype.elements[int(value)])
    name = ctype.cname
    if name == "float":
        return c_float(value)
    if name == "double":
        return c_double(value)
    if name == "_Bool":
        return "true" if value else "false"
    if name == "uint64_t":
        return f"UINT64_C({int(value)})"
    if name.startswith(("uint", "unsigned")):
        return f"{int(value)}u"
    return str(int(value))


def c_fields(ctype: str, value: Any, indent: str = "    ") -> list[str]:
    """The designated initializers of every field of the C struct ``ctype`` held in the cffi ``value``.

    Nested structs are written as nested braces; each line carries the field's comment from its
    C header.
    """
    lines = []
    for name, field in ffi.typeof(ctype).fields:
        comment = field_comment(ctype, name)
        if field.type.kind == "struct":
            head = f"{indent}.{name} = {{"
            lines.append(f"{head:<{_COMMENT_COLUMN}}/* {comment} */" if comment else head)
            lines += c_fields(field.type.cname, getattr(value, name), indent + "    ")
            lines.append(f"{indent}}},")
            continue
        assignment = f"{indent}.{name} = {_c_value(field.type, getattr(value, name))},"
        lines.append(f"{assignment:<{_COMMENT_COLUMN}}/* {comment} */" if comment else assignment)
    return lines


def config_header(
    *,
    prefix: str,
    title: str,
    record: Sequence[str],
    includes: Sequence[str],
    macros: Sequence[tuple[str, str, str]],
    blocks: Sequence[tuple[str, str, Any, str]],
    arrays: Sequence[tuple[str, Sequence[float], str]] = (),
) -> str:
    """The text of a C header of ``static const`` configurations.

    Parameters
    ----------
    prefix : str
        C identifier prefix: the header defines ``<PREFIX>_<name>`` macros and ``<prefix>_<name>``
        constants, and the guard ``<PREFIX>_H``.
    title : str
        First line of the opening comment.
    record : sequence of str
        Further lines of the opening comment (where the values came from, what they give).
    includes : sequence of str
        Headers to include (``"pmsm2dof/speed.h"``), in order.
    macros : sequence of (name, value, comment)
        ``#define <PREFIX>_<name> <value>`` with the comment.
    blocks : sequence of (ctype, name, value, comment)
        ``static const <ctype> <prefix>_<name>`` initialized from the cffi struct ``value``.
    arrays : sequence of (name, values, comment)
        ``static const double <prefix>_<name>[]`` (one element at least: a 0 stands for an empty one).
    """
    from importlib.metadata import version  # read only when a header is written

    check_prefix(prefix)
    upper = prefix.upper()
    lines = ["/*", f" * {title}", f" * Written by pmsm2dof {version('pmsm2dof')}.", " *"]
    lines += [" * " + line if line else " *" for line in record]
    lines += [" */", f"#ifndef {upper}_H", f"#define {upper}_H", "", "#include <stdbool.h>", "#include <stdint.h>", ""]
    lines += [f'#include "{name}"' for name in includes]
    for name, value, comment in macros:
        lines += ["", f"/* {comment} */", f"#define {upper}_{name} {value}"]
    for ctype, name, value, comment in blocks:
        lines += ["", f"/* {comment} */", f"static const {ctype} {prefix}_{name} = {{"]
        lines += c_fields(ctype, value)
        lines.append("};")
    for name, values, comment in arrays:
        items = ", ".join(c_double(v) for v in values) if len(values) else "0.0"
        lines += ["", f"/* {comment} */", f"static const double {prefix}_{name}[] = {{{items}}};"]
    lines += ["", f"#endif /* {upper}_H */", ""]
    return "\n".join(lines)


def design_record(discrete: "DiscreteDesign", coefficients: Mapping[str, Any]) -> list[str]:
    """Comment lines recording a speed-controller design: inputs, derived values, the C coefficients.

    ``coefficients`` are those ``p2d_speed_init`` computes
    (:attr:`pmsm2dof.core.controllers.SpeedController.coefficients`).
    """
    d = discrete.design
    dm = d.margins()
    zm = discrete.margins
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
        out.append(f"  {name:<12} = {coefficients[name]:.9g}")
    return out


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
