"""Motor data in datasheet units, converted to the per-phase, amplitude-invariant model of eq 1.

Datasheets give the torque constant Kt in Nm per ampere rms (or peak) of the phase current, the
back-EMF constant Ke in volts per 1000 rpm between two lines (rms or peak), or the speed constant
Kv in rpm per volt, the resistance and inductance measured between two terminals, and the number
of poles. The model of eq 1 uses the pole pairs p, the per-phase Rs, Ld, Lq and the magnet flux
linkage psi_f, with dq quantities in the amplitude-invariant transform (the dq current magnitude
is the peak phase current) and ``Te = 1.5 p psi_f iq`` for a non-salient motor.

Sinusoidal commutation (``commutation = "sinusoidal"``, the default), for a star-connected,
sinusoidal machine (R. Krishnan, *Permanent Magnet Synchronous and Brushless DC Motor Drives*,
CRC Press 2010, sections 3.2-3.4; a delta winding has the equivalent star values and is converted
the same way from its terminal data):

- back-EMF: the phase voltage has the peak ``e = p psi_f w_m``; between lines it is sqrt(3)
  times larger, and an rms value is the peak over sqrt(2). With ``w_krpm = 1000 * 2 pi / 60``
  rad/s, ``psi_f = Ke_phase_peak / (p w_krpm)``, ``Ke_phase_peak = Ke_line_rms sqrt(2/3)
  = Ke_line_peak / sqrt(3) = Ke_phase_rms sqrt(2)``; a speed constant is ``Kv = 1000 / Ke``
  (rpm per volt of the same voltage);
- torque: ``Te = 1.5 p psi_f i_peak``, so ``psi_f = Kt_peak / (1.5 p) = sqrt(2) Kt_rms / (3 p)``;
- currents: ``i_peak = sqrt(2) i_rms``.

Block commutation (``commutation = "block"``: trapezoidal, 120-degree conduction; maxon quotes
its EC motors' kM, kn and currents so, as do many hobby-motor sheets). In each 60-degree sector
two phases carry the DC-link current I in series, chosen so that their line-to-line back-EMF
``e_ll = sqrt(3) p psi_f w_m cos(phi)`` is within 30 degrees of its peak (``|phi| <= pi/6``).
Over a sector, ``mean(cos phi) = sin(pi/6) / (pi/6) = 3/pi``, so

- the DC-side back-EMF is ``(3 sqrt(3)/pi) p psi_f w_m`` on average, and by the power balance
  ``Te w_m = e_ll I`` the mean torque is ``(3 sqrt(3)/pi) p psi_f I``: the torque constant and
  the back-EMF constant in SI units are both ``kM = (3 sqrt(3)/pi) p psi_f = 1.654 p psi_f``
  (maxon's ``kM kn = 30000/pi`` with kM in mNm/A and kn in rpm/V), hence
  ``psi_f = pi kM / (3 sqrt(3) p)``, and from ``kn``: ``psi_f = pi / (3 sqrt(3) p kn)`` with kn
  in rad/s per volt;
- the model's torque constant is ``1.5 p psi_f = (pi / (2 sqrt(3))) kM = 0.907 kM`` per A of dq
  current (the peak of a sinusoidal phase current);
- a rated (continuous, thermal) current I flows in each phase for two thirds of the period, an rms
  of ``sqrt(2/3) I``: the sinusoidal current of the same rms, hence the same copper losses, has the
  peak ``i = (2/sqrt(3)) I`` (at equal losses, sinusoidal commutation then gives
  ``(2/sqrt(3)) (pi/(2 sqrt(3))) = pi/3``, 4.7 % more torque). A peak current is the phase
  current's peak in both: ``i = I``.

Both conventions: resistance and inductance between two terminals are two phases in series,
``Rs = R_line_to_line / 2``, ``L = L_line_to_line / 2`` (``Ld = Lq = L`` unless ``Ld_H`` and
``Lq_H`` are given).

In SI units the two constants of one machine are tied (sinusoidal: ``Kt_rms [Nm/A] = sqrt(3)
Ke_line_rms [V s/rad]``; block: ``kM = kn^-1``). When both are given, psi_f comes from Ke or Kv
(measured at no load, free of the saturation that lowers Kt at high current) and their
disagreement beyond :data:`KT_KE_RTOL` is reported as a :class:`DatasheetWarning` and in
:attr:`Motor.notes`.

In a scenario, the table ``[motor.datasheet]`` replaces the keys ``motor.pole_pairs``,
``motor.Rs_ohm``, ``motor.Ld_H``, ``motor.Lq_H`` and ``motor.psi_f_Wb``, and, when it gives them,
``motor.i_rated_A``, ``motor.i_peak_A`` and ``motor.J_rotor_kgm2`` (used by the plausibility
checks of :mod:`pmsm2dof.sim.plausibility`).
"""

import dataclasses
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..errors import ConfigError, Pmsm2dofWarning, is_integer, is_real
from ..inputs import read_toml

#: Mechanical speed of 1000 rpm [rad/s].
W_KRPM_RADPS = 1000.0 * 2.0 * math.pi / 60.0

#: Relative disagreement of psi_f from Kt and from Ke beyond which a warning is given.
KT_KE_RTOL = 0.10

#: Block commutation: the torque and back-EMF constant per unit of p psi_f, 3 sqrt(3) / pi [-].
BLOCK_K = 3.0 * math.sqrt(3.0) / math.pi

#: Keys of ``[motor.datasheet]``: name -> (kind, meaning). Units are in the names.
DATASHEET_KEYS: dict[str, tuple[type, str]] = {
    "commutation": (
        str,
        "'sinusoidal' (default: the *_current and *_voltage keys give the conventions) or 'block': Kt, Ke or Kv "
        "and the currents of block (trapezoidal) commutation, per A of DC-link current and volt of the mean "
        "DC-side back-EMF, as maxon quotes kM, kn and its currents",
    ),
    "poles": (int, "number of poles 2p (even); or pole_pairs"),
    "pole_pairs": (int, "number of pole pairs p; or poles"),
    "Kt_Nm_per_A": (float, "torque constant [Nm/A], per ampere as Kt_current says (block: maxon's kM)"),
    "Kt_current": (str, "current of Kt: 'rms' (default) or 'peak' phase current (sinusoidal only)"),
    "Ke_V_per_krpm": (float, "back-EMF constant [V per 1000 rpm], as Ke_voltage says; or Kv_rpm_per_V"),
    "Kv_rpm_per_V": (
        float,
        "speed constant [rpm/V] = 1000 / Ke_V_per_krpm, per volt as Ke_voltage says (block: maxon's kn; a "
        "hobby motor's Kv is usually line_peak); or Ke_V_per_krpm",
    ),
    "Ke_voltage": (
        str,
        "voltage of Ke or Kv: 'line_rms' (default), 'line_peak', 'phase_rms' or 'phase_peak' (sinusoidal only)",
    ),
    "R_ohm": (float, "winding resistance [ohm], measured as R_between says"),
    "R_between": (str, "'line_to_line' (default: between two terminals, maxon's phase to phase) or 'phase'"),
    "L_H": (float, "winding inductance [H] (non-salient), measured as L_between says; or Ld_H and Lq_H"),
    "Ld_H": (float, "d-axis inductance [H], measured as L_between says"),
    "Lq_H": (float, "q-axis inductance [H], measured as L_between says"),
    "L_between": (str, "'line_to_line' (default) or 'phase'"),
    "I_rated_A": (float, "rated (continuous) current [A], as I_rated_current says (optional)"),
    "I_rated_current": (str, "'rms' (default) or 'peak' (sinusoidal only)"),
    "I_peak_A": (float, "largest current the motor may carry [A], as I_peak_current says (optional)"),
    "I_peak_current": (str, "'rms' (default) or 'peak' (sinusoidal only)"),
    "J_rotor_gcm2": (float, "rotor inertia [g cm^2] as catalogues give it, 1 g cm^2 = 1e-7 kg m^2 (optional)"),
}

_CHOICES = {
    "commutation": ("sinusoidal", "block"),
    "Kt_current": ("rms", "peak"),
    "Ke_voltage": ("line_rms", "line_peak", "phase_rms", "phase_peak"),
    "R_between": ("line_to_line", "phase"),
    "L_between": ("line_to_line", "phase"),
    "I_rated_current": ("rms", "peak"),
    "I_peak_current": ("rms", "peak"),
}

#: The keys that name a convention of sinusoidal commutation (absent with commutation 'block').
_SINUSOIDAL_ONLY = ("Kt_current", "Ke_voltage", "I_rated_current", "I_peak_current")

#: Per-phase peak back-EMF per unit of the given Ke.
_KE_TO_PHASE_PEAK = {
    "line_rms": math.sqrt(2.0 / 3.0),
    "line_peak": 1.0 / math.sqrt(3.0),
    "phase_rms": math.sqrt(2.0),
    "phase_peak": 1.0,
}

#: Scenario keys of [motor] that [motor.datasheet] provides: the model of eq 1.
MOTOR_KEYS = ("pole_pairs", "Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")

#: Scenario keys of [motor] that [motor.datasheet] provides when it gives them: the ratings.
RATING_KEYS = ("i_rated_A", "i_peak_A", "J_rotor_kgm2")

#: The model parameters an identified motor file may give 95 % intervals of, as ``<key>_ci``.
INTERVAL_KEYS = ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")

#: The mechanical keys of a scenario's [motor] (read by :func:`load_motor` when a file gives them).
MECHANICAL_KEYS = ("J_kgm2", "B_Nms", "T_coulomb_Nm")


def no_load_speed_radps(u_dc_V: float, pole_pairs: int, psi_f_Wb: float) -> float:
    """The largest speed at no load within the voltage ``u_dc / sqrt(3)`` of space-vector modulation [rad/s].

    ``u_dc / (sqrt(3) p psi_f)``: the back-EMF ``p psi_f w_m`` of eq 1 reaches the linear range of
    the modulation, to which the drive's current controller limits ``||u_dq||``.
    """
    return u_dc_V / (math.sqrt(3.0) * pole_pairs * psi_f_Wb)


class DatasheetWarning(Pmsm2dofWarning):
    """The datasheet values disagree with each other (Kt and Ke of one machine)."""


@dataclasses.dataclass(frozen=True)
class Motor:
    """The motor of eq 1: per-phase, amplitude-invariant parameters, named as the scenario's ``[motor]`` keys.

    The one motor type of simulation, analysis and identification: read from a datasheet, a
    scenario or an identified motor file by :func:`load_motor`, built by identification
    (:meth:`pmsm2dof.studies.electrical.Electrical.motor`), designed for by
    :func:`pmsm2dof.analysis.current_loop.design_current_loop`.

    Attributes
    ----------
    pole_pairs, Rs_ohm, Ld_H, Lq_H, psi_f_Wb
        Pole pairs p [-], phase resistance [ohm], dq inductances [H], magnet flux linkage [Wb].
    i_rated_A, i_peak_A
        Rated and peak current as a dq current magnitude (peak phase current) [A], or None.
    J_rotor_kgm2
        Rotor inertia [kg m^2], or None.
    J_kgm2, B_Nms, T_coulomb_Nm
        The drive's inertia [kg m^2], viscous [Nm s/rad] and Coulomb [Nm] friction, when the file
        gives them (a scenario's mechanical keys of ``[motor]``), or None.
    sources
        For each parameter, the formula and datasheet value or the key it comes from.
    notes
        Findings of the consistency check (Kt against Ke).
    intervals
        95 % intervals ``(low, high)`` of identified parameters (``<key>_ci`` of a motor file).
    commutation
        The convention of the datasheet's constants: ``"sinusoidal"`` or ``"block"``.
    """

    pole_pairs: int
    Rs_ohm: float
    Ld_H: float
    Lq_H: float
    psi_f_Wb: float
    i_rated_A: float | None = None
    i_peak_A: float | None = None
    J_rotor_kgm2: float | None = None
    J_kgm2: float | None = None
    B_Nms: float | None = None
    T_coulomb_Nm: float | None = None
    sources: dict[str, str] = dataclasses.field(default_factory=dict)
    notes: tuple[str, ...] = ()
    intervals: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    commutation: str = "sinusoidal"

    @property
    def kt_Nm_per_A(self) -> float:
        """Torque constant of the model, ``1.5 p psi_f`` [Nm per A of dq current] (eq 1, id = 0)."""
        return 1.5 * self.pole_pairs * self.psi_f_Wb

    def motor_table(self) -> dict[str, Any]:
        """The scenario keys of ``[motor]`` this datasheet provides (the ratings it gives)."""
        table = {key: getattr(self, key) for key in MOTOR_KEYS}
        table |= {key: getattr(self, key) for key in RATING_KEYS if getattr(self, key) is not None}
        return table

    def motor_file(self, comments: Sequence[str] = ()) -> str:
        """The motor as a motor file that :func:`load_motor` reads back: the ``comments`` (one ``#`` line
        each), ``[motor]`` with the model keys, the ratings and mechanical keys given, and the intervals
        as ``<key>_ci = [low, high]``."""
        lines = [f"# {text}" for text in comments] + ["[motor]", f"pole_pairs = {self.pole_pairs}"]
        given = (*MOTOR_KEYS[1:], *RATING_KEYS, *MECHANICAL_KEYS)
        lines += [f"{key} = {value!r}" for key in given if (value := getattr(self, key)) is not None]
        lines += [f"{key}_ci = [{low!r}, {high!r}]" for key, (low, high) in self.intervals.items()]
        return "\n".join(lines) + "\n"


def _check(sheet: Mapping[str, Any], key: str, prefix: str) -> Any:
    kind, doc = DATASHEET_KEYS[key]
    value = sheet[key]
    dotted = f"{prefix}.{key}"
    if key in _CHOICES:
        if value not in _CHOICES[key]:
            raise ConfigError(dotted, value, "one of " + ", ".join(repr(c) for c in _CHOICES[key]))
        return value
    if kind is int:
        if not is_integer(value) or not 1 <= value <= 2000:
            raise ConfigError(dotted, value, f"an integer in [1, 2000] ({doc})")
        if key == "poles" and value % 2:
            raise ConfigError(dotted, value, "an even integer in [2, 2000] (the number of poles is 2 p)")
        return int(value)
    number = _as_float(value)
    if not (math.isfinite(number) and number > 0):
        raise ConfigError(dotted, value, f"a finite number > 0 ({doc})")
    return number


def convert_datasheet(sheet: Mapping[str, Any], prefix: str = "motor.datasheet") -> Motor:
    """Convert datasheet values to the per-phase, amplitude-invariant parameters of eq 1.

    Parameters
    ----------
    sheet : mapping
        The keys of :data:`DATASHEET_KEYS`: ``poles`` or ``pole_pairs``; ``Kt_Nm_per_A`` or one of
        ``Ke_V_per_krpm`` and ``Kv_rpm_per_V`` (or Kt and one of them, then checked against each
        other); ``R_ohm``; ``L_H`` or ``Ld_H`` and ``Lq_H``; optionally ``I_rated_A``, ``I_peak_A``
        and ``J_rotor_gcm2``; the conventions of ``commutation`` (default sinusoidal) and, for
        sinusoidal commutation, of the ``*_current``, ``*_voltage`` and ``*_between`` keys
        (defaults rms, line_rms, line_to_line). See the module docstring for the formulas.
    prefix : str
        Dotted name of the table in error messages.

    Returns
    -------
    Motor

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
    block = v.get("commutation", "sinusoidal") == "block"
    if block:
        for key in _SINUSOIDAL_ONLY:
            if key in v:
                raise ConfigError(
                    f"{prefix}.{key}", v[key], "absent with commutation 'block' (DC-link current, mean DC-side voltage)"
                )

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

    if "Ke_V_per_krpm" in v and "Kv_rpm_per_V" in v:
        raise ConfigError(f"{prefix}.Kv_rpm_per_V", v["Kv_rpm_per_V"], "absent with Ke_V_per_krpm (Kv = 1000 / Ke)")
    if "Kt_Nm_per_A" not in v and "Ke_V_per_krpm" not in v and "Kv_rpm_per_V" not in v:
        raise ConfigError(
            f"{prefix}.Kt_Nm_per_A",
            "<missing>",
            "Kt_Nm_per_A, Ke_V_per_krpm or Kv_rpm_per_V (Kt and one of the others)",
        )
    kt_kind = "block" if block else v.get("Kt_current", "rms")
    ke_kind = "block" if block else v.get("Ke_voltage", "line_rms")
    psi_kt = psi_ke = None
    kt_text = ke_text = ""
    if "Kt_Nm_per_A" in v:
        kt = v["Kt_Nm_per_A"]
        if block:
            psi_kt = kt / (BLOCK_K * p)
            kt_text = f"Kt {kt:g} Nm/A block -> pi Kt / (3 sqrt(3) p)"
        else:
            psi_kt = kt / (math.sqrt(2.0) if kt_kind == "rms" else 1.0) / (1.5 * p)
            kt_text = f"Kt {kt:g} Nm/A {kt_kind} -> peak / (1.5 p)"
    if "Ke_V_per_krpm" in v or "Kv_rpm_per_V" in v:
        if "Kv_rpm_per_V" in v:
            ke = 1000.0 / v["Kv_rpm_per_V"]
            given = f"Kv {v['Kv_rpm_per_V']:g} rpm/V {ke_kind} (Ke = 1000 / Kv = {ke:.6g} V/krpm)"
        else:
            ke = v["Ke_V_per_krpm"]
            given = f"Ke {ke:g} V/krpm {ke_kind}"
        if block:
            psi_ke = ke / (BLOCK_K * p * W_KRPM_RADPS)
            ke_text = f"{given} -> pi Ke / (3 sqrt(3) p * 104.72 rad/s)"
        else:
            psi_ke = ke * _KE_TO_PHASE_PEAK[ke_kind] / (p * W_KRPM_RADPS)
            ke_text = f"{given} -> phase peak / (p * 104.72 rad/s)"
    notes: list[str] = []
    if psi_ke is not None:
        psi_f = psi_ke
        sources["psi_f_Wb"] = ke_text
        if psi_kt is not None:
            diff = psi_kt / psi_ke - 1.0
            text = (
                f"Kt {v['Kt_Nm_per_A']:g} Nm/A {kt_kind} gives psi_f = {psi_kt:.6g} Wb, "
                f"{100 * diff:+.1f} % from the {psi_ke:.6g} Wb of {'Kv' if 'Kv_rpm_per_V' in v else 'Ke'}"
            )
            if abs(diff) > KT_KE_RTOL:
                text += (
                    f": they disagree by more than {100 * KT_KE_RTOL:g} % (check the commutation and the "
                    "rms/peak and line/phase conventions of both; psi_f is taken from "
                    f"{'Kv' if 'Kv_rpm_per_V' in v else 'Ke'})"
                )
                warnings.warn(text, DatasheetWarning, stacklevel=2)
            else:
                text += ": consistent"
            notes.append(text)
    else:
        assert psi_kt is not None
        psi_f = psi_kt
        sources["psi_f_Wb"] = kt_text

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
    currents: dict[str, float | None] = {}
    for key, name, thermal in (("I_rated_A", "i_rated_A", True), ("I_peak_A", "i_peak_A", False)):
        currents[name] = None
        if key not in v:
            continue
        label = key[: -len("_A")]
        if block and thermal:
            # the sinusoidal current of the same rms: (2/sqrt(3)) I
            currents[name] = v[key] * 2.0 / math.sqrt(3.0)
            sources[name] = f"{label} {v[key]:g} A block * 2/sqrt(3) (same rms, same copper losses)"
        elif block:
            currents[name] = v[key]
            sources[name] = f"{label} {v[key]:g} A block (the phase current's peak)"
        else:
            rms = v.get(f"{label}_current", "rms") == "rms"
            currents[name] = v[key] * (math.sqrt(2.0) if rms else 1.0)
            sources[name] = f"{label} {v[key]:g} A {'rms * sqrt(2)' if rms else 'peak'}"
    J_rotor = None
    if "J_rotor_gcm2" in v:
        J_rotor = v["J_rotor_gcm2"] * 1e-7
        sources["J_rotor_kgm2"] = f"J_rotor {v['J_rotor_gcm2']:g} g cm^2 * 1e-7"
    return Motor(
        pole_pairs=p,
        Rs_ohm=Rs,
        Ld_H=Ld,
        Lq_H=Lq,
        psi_f_Wb=psi_f,
        i_rated_A=currents["i_rated_A"],
        i_peak_A=currents["i_peak_A"],
        J_rotor_kgm2=J_rotor,
        sources=sources,
        notes=tuple(notes),
        commutation="block" if block else "sinusoidal",
    )


def load_motor(path: str | os.PathLike[str]) -> Motor:
    """Read the motor of a TOML file: a ``[motor.datasheet]`` table, or the model keys of ``[motor]``.

    Parameters
    ----------
    path : str or os.PathLike
        A scenario file, a file with only ``[motor]`` (and ``[motor.datasheet]``), or an identified
        motor file (``motor.toml`` of ``pmsm2dof commission --out`` or ``identify electrical
        --out``: the model keys and, optionally, ``<key>_ci = [low, high]``, the 95 % interval of
        an estimate, for the keys of :data:`INTERVAL_KEYS`).

    Returns
    -------
    Motor
        With sources ``"motor.<key>"`` for the keys given directly.

    Raises
    ------
    ConfigError
        An unreadable file, a motor table with neither a datasheet nor the model keys, an unknown
        key of ``[motor]``, or a value out of its range.
    """
    file = Path(os.fspath(path))
    tree = read_toml(file, "motor file")
    motor = tree.get("motor")
    if not isinstance(motor, dict):
        raise ConfigError("motor", "<missing>", f"a [motor] table in {file}")
    known = (*MOTOR_KEYS, *RATING_KEYS, *MECHANICAL_KEYS, *(f"{k}_ci" for k in INTERVAL_KEYS), "datasheet")
    for key in motor:
        if key not in known:
            raise ConfigError(f"motor.{key}", motor[key], "a key of [motor]: " + ", ".join(known))
    if "datasheet" in motor:
        converted = motor_from_table(motor)
        ratings: dict[str, Any] = {k: _positive(motor, k) for k in RATING_KEYS if k in motor} | _mechanics(motor)
        ratings["sources"] = {**converted.sources, **{k: f"motor.{k}" for k in ratings}}
        return dataclasses.replace(converted, **ratings)
    missing = [k for k in MOTOR_KEYS if k not in motor]
    if missing:
        raise ConfigError(f"motor.{missing[0]}", "<missing>", "a [motor.datasheet] table or every model key of [motor]")
    p = motor["pole_pairs"]
    if not is_integer(p) or not 1 <= p <= 1000:
        raise ConfigError("motor.pole_pairs", p, "an integer >= 1 and <= 1000")
    p = int(p)
    values: dict[str, Any] = {key: _positive(motor, key) for key in MOTOR_KEYS[1:]}
    values |= {key: _positive(motor, key) for key in RATING_KEYS if key in motor} | _mechanics(motor)
    intervals = {}
    for key in INTERVAL_KEYS:
        ci = motor.get(f"{key}_ci")
        if ci is None:
            continue
        valid = f"[low, high] with 0 < low <= motor.{key} <= high, finite"
        if not isinstance(ci, list) or len(ci) != 2:
            raise ConfigError(f"motor.{key}_ci", ci, valid)
        low, high = _as_float(ci[0]), _as_float(ci[1])
        if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= values[key] <= high):
            raise ConfigError(f"motor.{key}_ci", ci, valid)
        intervals[key] = (low, high)
    return Motor(
        pole_pairs=p,
        **values,
        sources={key: f"motor.{key}" for key in (*MOTOR_KEYS, *RATING_KEYS, *MECHANICAL_KEYS) if key in motor},
        intervals=intervals,
    )


def _mechanics(motor: Mapping[str, Any]) -> dict[str, float]:
    """The mechanical keys ``motor`` gives: ``J_kgm2`` > 0, ``B_Nms`` and ``T_coulomb_Nm`` >= 0, finite."""
    values = {}
    for key in MECHANICAL_KEYS:
        if key in motor:
            number = _as_float(motor[key])
            if not (math.isfinite(number) and (number > 0 if key == "J_kgm2" else number >= 0)):
                raise ConfigError(
                    f"motor.{key}", motor[key], "a finite number " + ("> 0" if key == "J_kgm2" else ">= 0")
                )
            values[key] = number
    return values


def _positive(motor: Mapping[str, Any], key: str) -> float:
    """``motor[key]`` as a finite float > 0, or ConfigError naming ``motor.<key>``."""
    value = motor[key]
    number = _as_float(value)
    if not (math.isfinite(number) and number > 0):
        raise ConfigError(f"motor.{key}", value, "a finite number > 0")
    return number


def _as_float(value: Any) -> float:
    """``value`` as a float; NaN for what is no real number (a bool, a string) and for an integer
    beyond float's range (a TOML integer may have hundreds of digits)."""
    if not is_real(value):
        return math.nan
    try:
        return float(value)
    except OverflowError:
        return math.nan


def motor_from_table(motor: Mapping[str, Any]) -> Motor:
    """Convert the ``[motor.datasheet]`` of a ``[motor]`` table; no key it provides may be given beside it."""
    converted = convert_datasheet(motor["datasheet"])
    for key in (*MOTOR_KEYS, *converted.motor_table()):
        if key in motor:
            raise ConfigError(f"motor.{key}", motor[key], "absent when [motor.datasheet] is given (it provides it)")
    return converted
