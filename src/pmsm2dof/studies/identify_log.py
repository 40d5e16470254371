"""A drive identified from its logged runs, as ``pmsm2dof identify mechanics | electrical | plan`` tell it.

:func:`mechanics_from_log` and :func:`electrical_from_log` read a log, fit it
(:func:`~pmsm2dof.studies.identify.identify_mechanics`, :func:`~pmsm2dof.studies.electrical.identify_electrical`),
write the output folder and return the report whose ``lines`` the command prints; :func:`plan_run` chooses
the run to log (:func:`~pmsm2dof.studies.identify.plan_experiment`), simulates and writes it. The figures are
drawn by the caller's ``figure`` function (the plots belong to the user interface).
"""

import dataclasses
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..core.gains import pi_gains
from ..core.motor import load_motor
from ..errors import ConfigError
from ..outputs import atomic_write, staged_dir
from ..sim.logs import read_log
from ..sim.scenario import Scenario, load_scenario
from ..sim.simulate import Result, simulate
from .electrical import DEAD_TIME, PARAMETERS, Electrical, identify_electrical
from .identify import (
    CurrentLoop,
    IdentificationError,
    Mechanics,
    identified_toml,
    identify_mechanics,
    identify_tau_i,
    plan_experiment,
    torque_from_currents,
)

#: The columns of an identify electrical ranges.csv.
RANGE_COLUMNS = ("i_low_A", "i_high_A", "n_windows", "Ld_H", "Ld_H_low", "Ld_H_high", "Lq_H", "Lq_H_low", "Lq_H_high")
#: The columns of an identify electrical residuals.csv.
RESIDUAL_COLUMNS = ("t_s", "ud_V", "ud_fit_V", "uq_V", "uq_fit_V")
#: The units of the electrical parameters as printed.
ELECTRICAL_UNITS = {"Rs_ohm": "ohm", "Ld_H": "H", "Lq_H": "H", "psi_f_Wb": "Wb", DEAD_TIME: "V per phase"}


def _interval_line(name: str, width: int, value: float, ci: tuple[float, float] | list[float], unit: str) -> str:
    lo, hi = ci
    return f"{name:<{width}} = {value:<11.5g} 95 % interval [{lo:.5g}, {hi:.5g}] {unit}"


@dataclasses.dataclass(frozen=True)
class MechanicsReport:
    """What identify mechanics found: the fit, the current loop's tau_i (None without iq_ref_A), the eq 9
    gains for the J found (``(alpha_radps, zeta, Kp, Ki)``, None when not asked), the JSON report, and
    the output folder (None: nothing written)."""

    mech: Mechanics
    current: CurrentLoop | None
    design: tuple[float, float, float, float] | None
    report: dict[str, Any]
    out: str | None

    def lines(self) -> list[str]:
        """Each value with its 95 % interval, the fit, its notes, the gains, what was written."""
        mech, report = self.mech, self.report
        lines = [
            _interval_line(name, 13, report[name], report[f"{name}_ci"], unit)
            for name, unit in (("J_kgm2", "kg m^2"), ("B_Nms", "Nm s/rad"), ("T_coulomb_Nm", "Nm"))
        ]
        if self.current is not None:
            lines.append(_interval_line("tau_i_s", 13, self.current.tau_i_s, self.current.tau_i_s_ci, "s"))
        lines.append(
            f"fit: {mech.n_rows} rows of {mech.window_s:.3g} s ({mech.n_samples} samples), "
            f"residual {mech.residual_rms_Nm:.3g} Nm rms, {mech.n_rows_excluded} rows excluded"
        )
        lines += [f"note: {note}" for note in mech.notes]
        if self.design is not None:
            alpha_radps, zeta, Kp, Ki = self.design
            lines.append(f"eq 9 with alpha = {alpha_radps:g} rad/s, zeta = {zeta:g}: Kp = {Kp:.6g}, Ki = {Ki:.6g}")
        if self.out is not None:
            lines.append(f"wrote fit.png, rows.csv, identified.toml and identify.json to {self.out}")
        return lines


def mechanics_from_log(
    log: str,
    columns: Mapping[str, str],
    *,
    motor_file: str | None,
    motor: tuple[int, float, float, float] | None,
    window_s: float | None,
    speed_is_period_mean: bool,
    design: tuple[float, float] | None,
    out: str | None,
    force: bool,
    figure: Callable[[Mechanics, Path], object],
) -> MechanicsReport:
    """Identify J, B, the Coulomb friction (and tau_i) of the log ``log``; write ``out``.

    Parameters
    ----------
    log, columns
        The log file and its column map (:func:`~pmsm2dof.sim.logs.read_log`).
    motor_file, motor
        The torque from the currents: the motor of a file (:func:`~pmsm2dof.core.motor.load_motor`), or
        ``(pole_pairs, psi_f_Wb, Ld_H, Lq_H)``; both None: the log's torque_Nm.
    window_s, speed_is_period_mean
        As :func:`~pmsm2dof.studies.identify.identify_mechanics`.
    design
        ``(alpha_radps, zeta)``: the eq 9 gains for the J found too.
    out, force, figure
        The output folder (None: none), whether it may hold other files, and the function drawing the fit.

    Raises
    ------
    ConfigError
        A log, motor file or argument out of range, naming it.
    IdentificationError
        J not identifiable from the log.
    """
    measured = read_log(log, columns)
    torque = None
    if motor_file is not None:
        m = load_motor(motor_file)
        torque = torque_from_currents(measured, m.pole_pairs, m.psi_f_Wb, m.Ld_H, m.Lq_H)
    elif motor is not None:
        torque = torque_from_currents(measured, *motor)
    mech = identify_mechanics(measured, torque_Nm=torque, window_s=window_s, speed_is_period_mean=speed_is_period_mean)
    current = None
    if measured.iq_ref_A is not None and measured.iq_A is not None:
        try:
            current = identify_tau_i(measured)
        except IdentificationError as exc:
            mech = dataclasses.replace(mech, notes=(*mech.notes, f"tau_i: {exc}"))
    report = mech.to_json()
    if current is not None:
        report.update(tau_i_s=current.tau_i_s, tau_i_s_ci=list(current.tau_i_s_ci), tau_i_n_rows=current.n_rows)
    gains = None
    if design is not None:
        alpha_radps, zeta = design
        Kp, Ki = pi_gains(mech.J_kgm2, alpha_radps, zeta)
        gains = (alpha_radps, zeta, Kp, Ki)
        report["design"] = {"alpha_radps": alpha_radps, "zeta": zeta, "Kp": Kp, "Ki": Ki}
    if out is not None:
        scenario: Scenario | None = None
        if motor_file is not None:
            try:
                scenario = load_scenario(motor_file)
            except ConfigError:  # a datasheet or identified motor file: a [motor] table only
                scenario = None
        text = identified_toml(mech, current, scenario, f"{log} by pmsm2dof identify mechanics")
        with staged_dir(out, "identify", force) as tmp:
            write_mechanics(tmp, mech, text, report, figure)
    return MechanicsReport(mech, current, gains, report, out)


def write_mechanics(
    folder: Path,
    mech: Mechanics,
    identified: str,
    report: Mapping[str, Any],
    figure: Callable[[Mechanics, Path], object],
) -> None:
    """The outputs of a mechanics fit into ``folder``: fit.png (drawn by ``figure``), rows.csv, identified.toml
    (the text ``identified``, :func:`~pmsm2dof.studies.identify.identified_toml`) and identify.json (``report``)."""
    figure(mech, folder / "fit.png")
    rows = mech.rows
    table = np.column_stack([rows["t_s"], rows["y"], rows["fit"], rows["y"] - rows["fit"], rows["kept"]])
    atomic_write(folder / "rows.csv", "t_s,torque_mean_Nm,fit_Nm,residual_Nm,kept\n" + _csv_body(table) + "\n")
    atomic_write(folder / "identified.toml", identified)
    atomic_write(folder / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")


@dataclasses.dataclass(frozen=True)
class ElectricalReport:
    """What identify electrical found: the fit, its JSON report and the output folder (None: nothing written)."""

    fit: Electrical
    report: dict[str, Any]
    out: str | None

    def lines(self) -> list[str]:
        """Each parameter with its 95 % interval, the fit, the voltage limit, the current ranges, the notes."""
        fit, report = self.fit, self.report
        lines = [
            _interval_line(name, 11, report[name], fit.ci[name], ELECTRICAL_UNITS[name])
            for name in (*PARAMETERS, DEAD_TIME)
            if name in fit.ci
        ]
        lines.append(
            f"fit: {fit.n_windows} windows ({fit.n_samples} samples), residual {fit.residual_rms_V:.3g} V rms "
            "(per phase, amplitude-invariant dq, eq 1)"
        )
        if fit.n_samples_voltage_limited is not None:
            lines.append(
                f"voltage limit: {fit.n_samples_voltage_limited} samples at the limit, "
                f"{fit.n_windows_voltage_limited} windows that touch them left out"
            )
        if fit.ranges:
            lines.append("per current range (Rs, psi_f common):")
            lines.append(f"  {'|i_dq| [A]':<15} {'Ld [mH]':<24} {'Lq [mH]':<24} windows")
            for r in report["ranges"]:
                span = f"{r['i_low_A']:.3g} to {r['i_high_A']:.3g}"
                lines.append(f"  {span:<15} {_range_cell(r, 'Ld_H'):<24} {_range_cell(r, 'Lq_H'):<24} {r['n_windows']}")
        lines += [f"note: {note}" for note in fit.notes]
        if self.out is not None:
            written = "fit.png, residuals.csv, " + ("ranges.csv, " if fit.ranges else "")
            lines.append(f"wrote {written}motor.toml and identify.json to {self.out}")
        return lines


def _range_cell(r: Mapping[str, Any], name: str) -> str:
    """An inductance of a current range in mH with its interval, or "not determined"."""
    if r[name] is None:
        return "not determined"
    lo, hi = r[f"{name}_ci"]
    return f"{r[name] * 1e3:.4g} [{lo * 1e3:.4g}, {hi * 1e3:.4g}]"


def _csv_body(table: np.ndarray) -> str:
    """The rows of ``table`` as CSV lines of 9 significant digits."""
    return "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)


def electrical_from_log(
    log: str,
    columns: Mapping[str, str],
    pole_pairs: int,
    *,
    voltage_delay_samples: int,
    angle_lead_samples: float | None,
    dead_time: bool,
    u_dc_V: float | None,
    current_ranges: int | None,
    out: str | None,
    force: bool,
    figure: Callable[[Electrical, Path], object],
) -> ElectricalReport:
    """Identify Rs, Ld, Lq and psi_f (eq 1) of the log ``log``; write ``out``.

    The arguments are those of :func:`~pmsm2dof.studies.electrical.identify_electrical` (the log read with
    ``columns``), then the output folder (None: none), whether it may hold other files, and the function
    drawing the fit. Raises ConfigError naming a log or an argument out of range, or IdentificationError.
    """
    measured = read_log(log, columns)
    fit = identify_electrical(
        measured,
        pole_pairs,
        voltage_delay_samples=voltage_delay_samples,
        angle_lead_samples=angle_lead_samples,
        dead_time=dead_time,
        u_dc_V=u_dc_V,
        current_ranges=current_ranges,
    )
    if out is not None:
        with staged_dir(out, "identify-electrical", force) as tmp:
            write_electrical(tmp, fit, pole_pairs, log, figure)
    return ElectricalReport(fit, fit.to_json(), out)


def write_electrical(
    folder: Path, fit: Electrical, pole_pairs: int, source: str, figure: Callable[[Electrical, Path], object]
) -> None:
    """Write what identify electrical found into ``folder``: fit.png (drawn by ``figure``), residuals.csv,
    ranges.csv (with current ranges), motor.toml (``source`` names where the data came from), identify.json."""
    report = fit.to_json()
    table = np.column_stack([fit.rows[n] for n in RESIDUAL_COLUMNS])
    ranges = "".join(",".join(f"{v:.9g}" for v in _range_row(r)) + "\n" for r in report["ranges"])
    figure(fit, folder / "fit.png")
    atomic_write(folder / "residuals.csv", ",".join(RESIDUAL_COLUMNS) + "\n" + _csv_body(table) + "\n")
    if fit.ranges:
        atomic_write(folder / "ranges.csv", ",".join(RANGE_COLUMNS) + "\n" + ranges)
    atomic_write(folder / "motor.toml", fit.motor_toml(pole_pairs, source))
    atomic_write(folder / "identify.json", json.dumps(report, indent=2, allow_nan=False) + "\n")


def _range_row(r: Mapping[str, Any]) -> list[float]:
    """A row of ranges.csv (:data:`RANGE_COLUMNS`): an inductance not determined is NaN."""
    row = [r["i_low_A"], r["i_high_A"], r["n_windows"]]
    for name in ("Ld_H", "Lq_H"):
        row += [math.nan, math.nan, math.nan] if r[name] is None else [r[name], *r[f"{name}_ci"]]
    return row


@dataclasses.dataclass(frozen=True)
class PlanReport:
    """The run identify plan chose (a scenario), its simulation, and the output folder."""

    plan: Scenario
    result: Result
    out: str

    def lines(self) -> list[str]:
        """The reference's steps, what the simulation of the run reached, what was written."""
        plan, result = self.plan, self.result
        lines = [f"  t = {e.t_s:8.4g} s: speed reference {e.speed_rpm:8.5g} rpm" for e in plan.reference]
        lines.append(
            f"simulated with J = {plan.speed_controller.J_kgm2:g} kg m^2: |speed| <= "
            f"{abs(result.speed_rpm).max():.5g} rpm, |iq| <= {abs(result.iq_A).max():.4g} A "
            f"(limit {plan.limits.i_max_A:g} A), at the voltage limit "
            f"{100 * float(result.voltage_limited.mean()):.3g} % of the time, {result.t_s[-1]:g} s"
        )
        lines.append(
            f"wrote plan.toml, trace.csv and plot.png to {self.out}: play plan.toml's reference on the drive, log it"
        )
        return lines


def plan_run(
    motor_file: str,
    speed_max_rpm: float,
    i_max_A: float | None,
    out: str,
    force: bool,
    figure: Callable[[Result, Path], object],
) -> PlanReport:
    """The run to log for identify mechanics (:func:`~pmsm2dof.studies.identify.plan_experiment` of the
    scenario ``motor_file``), simulated; ``out`` gets plan.toml, trace.csv and the ``figure`` plot.png.

    Raises ConfigError naming the scenario, ``speed_max_rpm``, ``limits.i_max_A`` or ``out``.
    """
    plan = plan_experiment(load_scenario(motor_file), speed_max_rpm, i_max_A)
    with staged_dir(out, "identify-plan", force) as tmp:
        result = simulate(plan)
        result.save(tmp / "trace.csv")
        figure(result, tmp / "plot.png")
        atomic_write(tmp / "plan.toml", plan.to_toml())
    return PlanReport(plan, result, out)
