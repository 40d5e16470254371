"""Motor data in datasheet units, converted to the per-phase, amplitude-invariant model of eq 1.

Datasheets give the torque constant Kt in Nm per ampere rms (or peak) of the phase current, the
back-EMF constant Ke in volts per 1000 rpm between two lines (rms or peak), the resistance and
inductance measured between two terminals, and the number of poles. The model of eq 1 uses the
pole pairs p, the per-phase Rs, Ld, Lq and the magnet flux linkage psi_f, with dq quantities in
the amplitude-invariant transform (the dq current magnitude is the peak phase current) and
``Te = 1.5 p psi_f iq`` for a non-salient motor.

The conversion, for a star-connected, sinusoidal machine (R. Krishnan, *Permanent Magnet
Synchronous and Brushless DC Motor Drives*, CRC Press 2010, sections 3.2-3.4; a delta winding
has the equivalent star values and is converted the same way from its terminal data):

- back-EMF: the phase voltage has the peak ``e = p psi_f w_m``; between lines it is sqrt(3)
  times larger, and an rms value is the peak over sqrt(2). With ``w_krpm = 1000 * 2 pi / 60``
  rad/s, ``psi_f = Ke_phase_peak / (p w_krpm)``, ``Ke_phase_peak = Ke_line_rms sqrt(2/3)
  = Ke_line_peak / sqrt(3) = Ke_phase_rms sqrt(2)``;
- torque: ``Te = 1.5 p psi_f i_peak``, so ``psi_f = Kt_peak / (1.5 p) = sqrt(2) Kt_rms / (3 p)``;
- resistance and inductance between two terminals are two phases in series:
  ``Rs = R_line_to_line / 2``, ``L = L_line_to_line / 2`` (``Ld = Lq = L`` unless ``Ld_H`` and
  ``Lq_H`` are given);
- currents: ``i_peak = sqrt(2) i_rms``.

In SI units the two constants of one machine are tied: ``Kt_rms [Nm/A] = sqrt(3) Ke_line_rms
[V s/rad]``. When both are given, psi_f comes from Ke (measured at no load, free of the
saturation that lowers Kt at high current) and their disagreement beyond
:data:`KT_KE_RTOL` is reported as a :class:`DatasheetWarning` and in
:attr:`MotorParameters.notes`.

In a scenario, the table ``[motor.datasheet]`` replaces the keys ``motor.pole_pairs``,
``motor.Rs_ohm``, ``motor.Ld_H``, ``motor.Lq_H`` and ``motor.psi_f_Wb``.
"""

import dataclasses
import math
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..inputs import read_toml

#: Mechanical speed of 1000 rpm [rad/s].
W_KRPM_RADPS = 1000.0 * 2.0 * math.pi / 60.0

#: Relative disagreement of psi_f from Kt and from Ke beyond which a warning is given.
KT_KE_RTOL = 0.10

#: Keys of ``[motor.datasheet]``: name -> (kind, meaning). Units are in the names.
DATASHEET_KEYS: dict[str, tuple[type, str]] = {
    "poles": (int, "number of poles 2p (even); or pole_pairs"),
    "pole_pairs": (int, "number of pole pairs p; or poles"),
    "Kt_Nm_per_A": (float, "torque constant [Nm/A], per ampere as Kt_current says"),
    "Kt_current": (str, "current of Kt: 'rms' (default) or 'peak' phase current"),
    "Ke_V_per_krpm": (float, "back-EMF constant [V per 1000 rpm], as Ke_voltage says"),
    "Ke_voltage": (str, "voltage of Ke: 'line_rms' (default), 'line_peak', 'phase_rms' or 'phase_peak'"),
    "R_ohm": (float, "winding resistance [ohm], measured as R_between says"),
    "R_between": (str, "'line_to_line' (default: between two terminals) or 'phase'"),
    "L_H": (float, "winding inductance [H] (non-salient), measured as L_between says; or Ld_H and Lq_H"),
    "Ld_H": (float, "d-axis inductance [H], measured as L_between says"),
    "Lq_H": (float, "q-axis inductance [H], measured as L_between says"),
    "L_between": (str, "'line_to_line' (default) or 'phase'"),
    "I_rated_A": (float, "rated current [A], as I_rated_current says (optional)"),
    "I_rated_current": (str, "'rms' (default) or 'peak'"),
}

_CHOICES = {
    "Kt_current": ("rms", "peak"),
    "Ke_voltage": ("line_rms", "line_peak", "phase_rms", "phase_peak"),
    "R_between": ("line_to_line", "phase"),
    "L_between": ("line_to_line", "phase"),
    "I_rated_current": ("rms", "peak"),
}

#: Per-phase peak back-EMF per unit of the given Ke.
_KE_TO_PHASE_PEAK = {
    "line_rms": math.sqrt(2.0 / 3.0),
    "line_peak": 1.0 / math.sqrt(3.0),
    "phase_rms": math.sqrt(2.0),
    "phase_peak": 1.0,
}

#: Scenario keys of [motor] that [motor.datasheet] provides.
MOTOR_KEYS = ("pole_pairs", "Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")


class DatasheetWarning(UserWarning):
    """The datasheet values disagree with each other (Kt and Ke of one machine)."""


@dataclasses.dataclass(frozen=True)
class MotorParameters:
    """The model parameters of eq 1 converted from a datasheet, each with its source.

    Attributes
    ----------
    pole_pairs, Rs_ohm, Ld_H, Lq_H, psi_f_Wb
        Per-phase, amplitude-invariant parameters (scenario keys of ``[motor]``).
    i_rated_A
        Rated current as a dq current magnitude (peak phase current) [A], or None.
    kt_Nm_per_A
        Torque constant of the model, ``1.5 p psi_f`` [Nm per A of dq current].
    sources
        For each parameter, the formula and datasheet value it comes from.
    notes
        Findings of the consistency check (Kt against Ke).
    """

    pole_pairs: int
    Rs_ohm: float
    Ld_H: float
    Lq_H: float
    psi_f_Wb: float
    i_rated_A: float | None
    kt_Nm_per_A: float
    sources: dict[str, str]
    notes: tuple[str, ...]

    def motor_table(self) -> dict[str, Any]:
        """The scenario keys of ``[motor]`` this datasheet provides."""
        return {key: getattr(self, key) for key in MOTOR_KEYS}


def _check(sheet: Mapping[str, Any], key: str, prefix: str) -> Any:
    kind, doc = DATASHEET_KEYS[key]
    value = sheet[key]
    dotted = f"{prefix}.{key}"
    if key in _CHOICES:
        if value not in _CHOICES[key]:
            raise ConfigError(dotted, value, "one of " + ", ".join(repr(c) for c in _CHOICES[key]))
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 2000:
            raise ConfigError(dotted, value, f"an integer in [1, 2000] ({doc})")
        if key == "poles" and value % 2:
            raise ConfigError(dotted, value, "an even integer in [2, 2000] (the number of poles is 2 p)")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not value > 0:
        raise ConfigError(dotted, value, f"a finite number > 0 ({doc})")
    return float(value)


def convert_datasheet(sheet: Mapping[str, Any], prefix: str = "motor.datasheet") -> MotorParameters:
    """Convert datasheet values to the per-phase, amplitude-invariant parameters of eq 1.

    Parameters
    ----------
    sheet : mapping
        The keys of :data:`DATASHEET_KEYS`: ``poles`` or ``pole_pairs``; ``Kt_Nm_per_A`` or
        ``Ke_V_per_krpm`` (or both, then checked against each other); ``R_ohm``; ``L_H`` or
        ``Ld_H`` and ``Lq_H``; optionally ``I_rated_A``, with the conventions of the ``*_current``,
        ``*_voltage`` and ``*_between`` keys (defaults rms, line_rms, line_to_line).
    prefix : str
        Dotted name of the table in error messages.

    Returns
    -------
    MotorParameters

    Raises
    ------
    ConfigError
        An unknown, missing, contradictory or out-of-range key, named ``prefix.key``.
    """
    if not isinstance(sheet, Mapping):
        raise ConfigError(prefix, type(sheet).__name__, "a table of datasheet keys")
    for key in sheet:
        if key not in DATASHEET_KEYS:
            raise ConfigError(f"{prefix}.{key}", sheet[key], "a datasheet key: " + ", ".join(DATASHEET_KEYS))
    v = {key: _check(sheet, key, prefix) for key in sheet}

    def one_of(a: str, b: str, what: str) -> str:
        if (a in v) == (b in v):
            given = v.get(a, v.get(b, "<missing>"))
            raise ConfigError(f"{prefix}.{a}", given, f"exactly one of {a} and {b} ({what})")
        return a if a in v else b

    sources: dict[str, str] = {}
    if one_of("poles", "pole_pairs", "the number of poles or of pole pairs") == "poles":
        p = v["poles"] // 2
        sources["pole_pairs"] = f"poles {v['poles']} / 2"
    else:
        p = v["pole_pairs"]
        sources["pole_pairs"] = "pole_pairs"

    kt_kind = v.get("Kt_current", "rms")
    ke_kind = v.get("Ke_voltage", "line_rms")
    if "Kt_Nm_per_A" not in v and "Ke_V_per_krpm" not in v:
        raise ConfigError(f"{prefix}.Kt_Nm_per_A", "<missing>", "Kt_Nm_per_A or Ke_V_per_krpm (or both)")
    psi_kt = psi_ke = None
    if "Kt_Nm_per_A" in v:
        kt_peak = v["Kt_Nm_per_A"] / (math.sqrt(2.0) if kt_kind == "rms" else 1.0)
        psi_kt = kt_peak / (1.5 * p)
    if "Ke_V_per_krpm" in v:
        psi_ke = v["Ke_V_per_krpm"] * _KE_TO_PHASE_PEAK[ke_kind] / (p * W_KRPM_RADPS)
    notes: list[str] = []
    if psi_ke is not None:
        psi_f = psi_ke
        sources["psi_f_Wb"] = f"Ke {v['Ke_V_per_krpm']:g} V/krpm {ke_kind} -> phase peak / (p * 104.72 rad/s)"
        if psi_kt is not None:
            diff = psi_kt / psi_ke - 1.0
            text = (
                f"Kt {v['Kt_Nm_per_A']:g} Nm/A {kt_kind} gives psi_f = {psi_kt:.6g} Wb, "
                f"{100 * diff:+.1f} % from Ke's {psi_ke:.6g} Wb"
            )
            if abs(diff) > KT_KE_RTOL:
                text += (
                    f": they disagree by more than {100 * KT_KE_RTOL:g} % (check the rms/peak and line/phase "
                    "conventions of both; psi_f is taken from Ke)"
                )
                warnings.warn(text, DatasheetWarning, stacklevel=2)
            else:
                text += ": consistent"
            notes.append(text)
    else:
        assert psi_kt is not None
        psi_f = psi_kt
        sources["psi_f_Wb"] = f"Kt {v['Kt_Nm_per_A']:g} Nm/A {kt_kind} -> peak / (1.5 p)"

    r_div = 2.0 if v.get("R_between", "line_to_line") == "line_to_line" else 1.0
    if "R_ohm" not in v:
        raise ConfigError(f"{prefix}.R_ohm", "<missing>", "a finite number > 0 (the winding resistance)")
    Rs = v["R_ohm"] / r_div
    sources["Rs_ohm"] = f"R {v['R_ohm']:g} ohm {v.get('R_between', 'line_to_line')}" + (" / 2" if r_div == 2 else "")
    l_between = v.get("L_between", "line_to_line")
    l_div = 2.0 if l_between == "line_to_line" else 1.0
    if "L_H" in v:
        if "Ld_H" in v or "Lq_H" in v:
            raise ConfigError(f"{prefix}.L_H", v["L_H"], "absent when Ld_H and Lq_H are given")
        Ld = Lq = v["L_H"] / l_div
        sources["Ld_H"] = sources["Lq_H"] = f"L {v['L_H']:g} H {l_between}" + (" / 2" if l_div == 2 else "")
    else:
        for key in ("Ld_H", "Lq_H"):
            if key not in v:
                raise ConfigError(f"{prefix}.{key}", "<missing>", "a finite number > 0, or L_H alone (non-salient)")
            sources[key] = f"{key} {v[key]:g} H {l_between}" + (" / 2" if l_div == 2 else "")
        Ld, Lq = v["Ld_H"] / l_div, v["Lq_H"] / l_div
    i_rated = None
    if "I_rated_A" in v:
        rms = v.get("I_rated_current", "rms") == "rms"
        i_rated = v["I_rated_A"] * (math.sqrt(2.0) if rms else 1.0)
        sources["i_rated_A"] = f"I_rated {v['I_rated_A']:g} A {'rms * sqrt(2)' if rms else 'peak'}"
    return MotorParameters(
        pole_pairs=p,
        Rs_ohm=Rs,
        Ld_H=Ld,
        Lq_H=Lq,
        psi_f_Wb=psi_f,
        i_rated_A=i_rated,
        kt_Nm_per_A=1.5 * p * psi_f,
        sources=sources,
        notes=tuple(notes),
    )


def load_motor(path: str | os.PathLike[str]) -> MotorParameters:
    """Read the motor of a TOML file: a ``[motor.datasheet]`` table, or the model keys of ``[motor]``.

    Parameters
    ----------
    path : str or os.PathLike
        A scenario file, or a file with only ``[motor]`` (and ``[motor.datasheet]``).

    Returns
    -------
    MotorParameters
        With sources ``"motor.<key>"`` for the keys given directly.

    Raises
    ------
    ConfigError
        An unreadable file, or a motor table with neither a datasheet nor the model keys.
    """
    file = Path(os.fspath(path))
    tree = read_toml(file, "motor file")
    motor = tree.get("motor")
    if not isinstance(motor, dict):
        raise ConfigError("motor", "<missing>", f"a [motor] table in {file}")
    if "datasheet" in motor:
        return motor_from_table(motor)
    missing = [k for k in MOTOR_KEYS if k not in motor]
    if missing:
        raise ConfigError(f"motor.{missing[0]}", "<missing>", "a [motor.datasheet] table or every model key of [motor]")
    values = {key: motor[key] for key in MOTOR_KEYS}
    p = values["pole_pairs"]
    if isinstance(p, bool) or not isinstance(p, int) or not 1 <= p <= 1000:
        raise ConfigError("motor.pole_pairs", p, "an integer >= 1 and <= 1000")
    for key in MOTOR_KEYS[1:]:
        v = values[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            raise ConfigError(f"motor.{key}", v, "a finite number > 0")
        values[key] = float(v)
    return MotorParameters(
        **values,
        i_rated_A=None,
        kt_Nm_per_A=1.5 * values["pole_pairs"] * values["psi_f_Wb"],
        sources={key: f"motor.{key}" for key in MOTOR_KEYS},
        notes=(),
    )


def motor_from_table(motor: dict[str, Any]) -> MotorParameters:
    """Convert the ``[motor.datasheet]`` of a ``[motor]`` table; no model key may be given beside it."""
    for key in MOTOR_KEYS:
        if key in motor:
            raise ConfigError(f"motor.{key}", motor[key], "absent when [motor.datasheet] is given (it provides it)")
    return convert_datasheet(motor["datasheet"])
