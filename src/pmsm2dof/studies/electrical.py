"""Identification of the machine from a logged run: Rs, Ld, Lq and psi_f (eq 1).

Model: the dq voltage equations of eq 1 (per phase, amplitude-invariant dq), with the electrical
speed ``w_e = p w_m``::

    ud = Rs id + Ld did/dt - w_e Lq iq
    uq = Rs iq + Lq diq/dt + w_e (Ld id + psi_f)

Integral form, in the stator frame: with the flux linkage ``psi_dq = Ld id + j Lq iq + psi_f`` and
its stator-frame vector ``psi_s = exp(j theta) psi_dq`` (``theta`` the electrical angle), eq 1 is
``d psi_s/dt = u_s - Rs i_s``. Integrated between two instants ``a`` and ``b`` and turned to the
angle at ``a``::

    exp(-j theta_a) int_a^b u_s dt = Rs exp(-j theta_a) int_a^b exp(j theta) i_dq dt
                                     + Ld (id(b) R - id(a)) + j Lq (iq(b) R - iq(a)) + psi_f (R - 1),

``R = exp(j (theta_b - theta_a))``: linear in Rs, Ld, Lq and psi_f, its real and imaginary parts
the d and q rows. The derivatives became current differences, so no current is differenced over
one sample (whose noise would bias L towards zero); at standstill (``R = 1``) it is the rotor-frame
integral of eq 1. Only angle differences within a window enter: ``theta`` is the logged electrical
speed ``w_e = p w_m`` integrated by trapezoids.

As in the mechanical fit (:mod:`pmsm2dof.studies.identify`), each regression row averages this
relation over the ``M`` pairs of instants ``a + j``, ``b + j`` of two blocks ``N`` samples apart
(each pair turned to the angle of its own start), so the current noise in the differences shrinks by
``sqrt(M)`` (the errors-in-variables bias of Ld and Lq stays small).

Voltage: held over the sample period that starts at its time (a zero-order hold: the voltage
integral is a sum over whole periods), so the log needs a row per period of the voltage, the
current loop's. A log whose rows are further apart (the speed controller's samples, while the
current controller changes the voltage several times between them) breaks that hold: the engine's
log of the servo at 10 current periods per speed sample gives Lq 3 % high and Ld 2 % low, with no
sign in the residuals. Such a log is refused when the file gives the current loop's period
(:attr:`~pmsm2dof.sim.logs.Log.current_period_s`, a pmsm2dof trace saved with its scenario), and
noted when its speed controller's command ``iq_ref_A`` changes from row to row, as it does at the
speed controller's rate and never at a faster one, where it holds over the current periods of a
speed sample (:data:`COMMAND_CHANGES_MAX`); pmsm2dof's engine logs every current
period with ``simulation.log_rate = "current"``. A log that records the voltage computed at a sample and
applied ``d`` periods later (``voltage_delay_samples``) is shifted by ``d`` samples first.
pmsm2dof's own engine logs the dq voltage applied over the period that starts at the row, after its
computation delay (``inverter.computation_delay``): its logs take ``voltage_delay_samples = 0``
(given 1, the fit pairs each voltage with the currents one period late: +2.7 % on Lq of a surface
servo). Two holds, each integrated exactly over a period ``[t_k, t_k + h)``:

- a stator-frame hold (``angle_lead_samples = X``): a drive turns the logged rotor-frame reference
  ``u`` of row ``k - d`` into the stator frame with the angle of that row plus ``X w_e Ts`` and the
  inverter holds that vector over its period, while the rotor turns on (the rotor-frame voltage
  turns by ``-w_e tau`` within the period). The stator-frame integral is ``h u exp(j (theta_(k-d) +
  X w_(k-d) Ts))``. ``X = d + 1/2`` points it at the rotor's mean angle over the period;
- a rotor-frame hold (None, pmsm2dof's engine): ``u`` of row ``k - d`` is the rotor-frame voltage
  over the period, ``int exp(j theta) dt u = h exp(j theta_k) exp(j phi/2) sinc(phi/2) u``,
  ``sinc(x) = sin x / x``, ``phi`` the angle turned in the period.

One form serves both: on the engine's logs it gives the rotor-frame integral's fit (the seeded
coverage test: 377 of 388 intervals cover the truth against 379 with the rotor-frame form, four
machines flipping either way, the errors within half a standard deviation of each other). On a
stator-frame hold it is exact where the rotor-frame form with the period's mean voltage was not:
the currents sampled at the period ends are not the period's means when the flux moves along an arc
within it (motulator's log at ``w_e Ts`` = 0.24 rad: +0.036 V d and -0.71 V q mean residual with
the true parameters at 4500 rpm, against 0.001 V and 0.003 V).

Current: the resistive term integrates ``exp(j theta) i_dq`` over each period with ``theta`` and
``i_dq`` linear within it (closed form, :func:`_turning_integral`), plus the bend of ``i_dq``
within the period. With ``psi_dq' = u_r - Rs i_dq - j w_e psi_dq`` (eq 1) and ``Rs i_dq'``
neglected, ``psi_dq'' = -j w_e (psi_dq' + u_r)`` under a stator-frame hold (``u_r' = -j w_e u_r``)
and ``-j w_e psi_dq'`` under a rotor-frame one; a parabola's integral over ``h`` falls short of its
chord's by ``h^3/12`` times its second derivative, so each period's integral gains ``-(h^3/12)
exp(j theta_mid) L^-1 psi_dq''`` (``L^-1 x = Re x / Ld + j Im x / Lq``, ``psi_dq'`` the period's
mean ``(Ld did + j Lq diq) / h``, ``u_r`` its mean rotor-frame voltage). It needs the inductances:
a first fit without it gives them, a second fit uses them. Under a stator-frame hold the bend
carries the magnet's arc, ``(w_e h)^2/12 psi_f / Ld`` of current along d: left out, the d row's
``Rs`` term biases Lq (+0.06 % at ``w_e Ts`` = 0.25 rad on the oracle log, beyond its 0.04 % interval;
-0.01 % with it).

Dead time (``dead_time = True``): each phase applies its reference minus ``dead_time_V
sign(i_phase)``. The fundamental of that square wave, in amplitude-invariant dq, is the current's
direction times ``4/pi dead_time_V`` (the six-step wave's first harmonic, e.g. J.-W. Choi and
S.-K. Sul, "Inverter output voltage synthesis using novel dead time compensation", IEEE Trans.
Power Electron. 11(2), 1996), so the logged reference is eq 1 plus::

    u_dq = ... + (4/pi) dead_time_V i_dq / |i_dq|

a fifth regressor, integrated in the stator frame as the resistive term (without the bend); the
hexagon's sixth harmonic averages out where the current turns, and at a fixed angle the error lies
between 9 % below and 5 % above the fundamental. It separates from ``Rs i`` only where ``|i_dq|``
takes different values (``Rs |i| + 4/pi dead_time_V`` is one line): a log whose windows' ``|i_dq|``
span less than :data:`DEAD_TIME_SPAN` is refused naming ``dead_time_V``.

Voltage limit: where the inverter cut the reference to its range, a logged reference is not the
applied voltage. The logged voltage is a reference when the log says it applies later or turns in
the stator frame (``voltage_delay_samples > 0`` or ``angle_lead_samples`` given) or when
``u_dc_V`` is given; then the windows that touch a period at the limit are left out: the periods
flagged by the log's ``voltage_limited`` column, and those whose ``|u_dq|`` reaches ``u_dc /
sqrt(3)`` within :data:`~.electrical_fit.VOLTAGE_MARGIN` (the DC link from ``u_dc_V`` or the log's ``u_dc_V``
column). Otherwise the logged voltage is the one applied (the default convention, and pmsm2dof's
engine logs): periods at the limit are counted and kept, since they are what the machine saw (and,
in field weakening, where ``id`` moves). Without a limit source, a reference that a drive logged
after its own limit shows as ``|u_dq|`` stuck at its largest value in many samples: the result then
carries a note.

Fit: the d and q rows of all windows together, by instrumental variables: the logged currents'
noise enters the regressors (errors in variables: least squares would be biased by it, and its
intervals would miss the truth), so the regressors are built from the even samples' currents (the
odd ones replaced by the mean of their neighbours) and the instruments from the odd samples',
whose noise is independent of the regressors' (J. Durbin, "Errors in variables", Rev. Int.
Statistical Institute 22, 1954: instruments from a second, independent measurement). Intervals: 95 % intervals from
the Newey-West covariance (Newey and West, Econometrica 55(3), 1987) of the per-window scores
(the d and q rows of one window share their noise, neighbouring windows share a block), so
that correlated residuals do not give intervals too narrow.

Current ranges: a saturating machine's inductances fall with the current, and one fit averages
them. A second fit, with the same instruments and covariance, keeps Rs, psi_f (and dead_time_V)
common and gives Ld and Lq one column per range of the windows' mean ``|i_dq|``: ranges of equal
width in current, a range with fewer than :data:`WINDOWS_MIN` windows merged into a neighbour (so
that no range is a sliver of windows piled at one current, such as the current limit; a note says
when fewer ranges than asked remain). Its estimates lie between the incremental inductance (which
the current differences see) and the apparent one (which the speed terms see) of the range. By default the log
gets :data:`AUTO_RANGES` ranges when its windows' current magnitudes (5th to 95th percentile)
span more than a factor :data:`AUTO_SPAN`, else one (no range table).

Identifiability: a parameter whose relative standard deviation exceeds :data:`~.electrical_fit.REL_SD_MAX` is not
reported: :class:`~pmsm2dof.studies.identify.IdentificationError` names it and the experiment that
would fix it (id never moved: Ld; no speed: psi_f ...).
"""

import dataclasses
import math
from typing import Any

import numpy as np

from ..core.motor import Motor
from ..errors import ConfigError
from ..sim.logs import Log
from .electrical_fit import (
    STUCK_SAMPLES,
    WINDOWS_MIN,
    CurrentRange,
    _determined,
    _fit_ranges,
    _iv_fit,
    _range_edges,
    _Rows,
    _saturation_notes,
    _windows,
)
from .identify import IdentificationError

#: The identified parameters of eq 1, in the order of the regressors.
PARAMETERS = ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")

#: The dead-time voltage per phase [V], the fifth regressor with ``dead_time = True``.
DEAD_TIME = "dead_time_V"


#: Default current ranges: AUTO_RANGES when the windows' ``|i_dq|`` (5th to 95th percentile) span more than AUTO_SPAN.
AUTO_RANGES = 3
AUTO_SPAN = 2.0


#: The dead-time term needs the windows' ``|i_dq|`` (10th to 90th percentile) to span at least this factor.
DEAD_TIME_SPAN = 1.5

#: Most current ranges.
RANGES_MAX = 10

#: Largest ``|angle_lead_samples|``.
ANGLE_LEAD_MAX = 10.0

#: A logged ``iq_ref_A`` whose changes are followed by another at the next row more often than this share changes
#: at every speed-controller sample: the rows are those samples (at a faster rate the command holds over the rows
#: of a sample, and no change follows another).
COMMAND_CHANGES_MAX = 0.5

#: Rows further apart than this many current periods (:attr:`~pmsm2dof.sim.logs.Log.current_period_s`) are too
#: coarse for the voltage's hold.
PERIODS_PER_ROW_MAX = 1.01

#: What each parameter needs from the log, for the message when it is not identifiable.
_NEEDS = {
    "Rs_ohm": "a current held while the speed is low (a DC current at standstill, or a slow run under load)",
    "Ld_H": "id moved (a d-axis current step at standstill, or a run into field weakening); "
    "with id at zero Ld only multiplies zero",
    "Lq_H": "iq moved (torque or speed steps)",
    "psi_f_Wb": "the rotor turned (a run at speed)",
}


@dataclasses.dataclass(frozen=True, eq=False)
class Electrical:
    """Rs, Ld, Lq and psi_f of eq 1 found in a log, with their 95 % intervals.

    Attributes
    ----------
    Rs_ohm, Ld_H, Lq_H, psi_f_Wb : float
        Per-phase resistance [ohm], dq inductances [H], magnet flux linkage [Wb] (amplitude-invariant dq).
    dead_time_V : float or None
        Per-phase dead-time voltage [V] (``dead_time = True``), else None.
    ci : dict
        Parameter -> its 95 % interval.
    residual_rms_V : float
        Rms residual of the rows (window-mean voltages) [V].
    n_samples : int
        Log samples the windows span.
    n_windows : int
        Windows (each gives a d and a q row).
    n_samples_voltage_limited : int or None
        Voltage samples at the inverter's limit (None: the log gives no limit source).
    n_windows_voltage_limited : int
        Windows left out because they touch such a sample (none where the logged voltage is the applied one).
    ranges : tuple of CurrentRange
        The fit per current range (empty with one range).
    notes : tuple of str
        What the fit found about the log, one line each.
    rows : dict
        Per row ``t_s``, measured and model window-mean voltages ``ud_V``, ``ud_fit_V``, ``uq_V``, ``uq_fit_V``.
    """

    Rs_ohm: float
    Ld_H: float
    Lq_H: float
    psi_f_Wb: float
    dead_time_V: float | None
    ci: dict[str, tuple[float, float]]
    residual_rms_V: float
    n_samples: int
    n_windows: int
    n_samples_voltage_limited: int | None
    n_windows_voltage_limited: int
    ranges: tuple[CurrentRange, ...]
    notes: tuple[str, ...]
    rows: dict[str, np.ndarray]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name in (*PARAMETERS, DEAD_TIME):
            if name in self.ci:
                out[name] = getattr(self, name)
                out[f"{name}_ci"] = list(self.ci[name])
        out.update(
            residual_V=self.residual_rms_V,
            n_samples=self.n_samples,
            n_windows=self.n_windows,
            n_samples_voltage_limited=self.n_samples_voltage_limited,
            n_windows_voltage_limited=self.n_windows_voltage_limited,
            ranges=[r.to_json() for r in self.ranges],
            notes=list(self.notes),
        )
        return out

    def motor(self, pole_pairs: int) -> Motor:
        """The identified motor: the estimates of eq 1 with their 95 % intervals, ``pole_pairs`` given."""
        return Motor(
            pole_pairs=pole_pairs,
            Rs_ohm=self.Rs_ohm,
            Ld_H=self.Ld_H,
            Lq_H=self.Lq_H,
            psi_f_Wb=self.psi_f_Wb,
            intervals={name: ci for name, ci in self.ci.items() if name in PARAMETERS},
        )

    def motor_toml(self, pole_pairs: int, source: str) -> str:
        """The identified motor as a ``[motor]`` table for ``pmsm2dof design --motor`` (as ``commission --out``)."""
        lines = [
            f"identified from {source} by pmsm2dof identify electrical",
            "per phase, amplitude-invariant dq (eq 1)",
        ]
        if self.dead_time_V is not None:
            lo, hi = self.ci[DEAD_TIME]
            lines.append(f"inverter dead-time voltage per phase: {self.dead_time_V:.4g} V [{lo:.4g}, {hi:.4g}]")
        for r in self.ranges:
            found = ", ".join(
                f"{name} = {value:.4g}" for name in ("Ld_H", "Lq_H") if (value := getattr(r, name)) is not None
            )
            lines.append(f"|i_dq| {r.i_low_A:.3g} to {r.i_high_A:.3g} A: {found or 'not determined'}")
        return self.motor(pole_pairs).motor_file(lines)


def _rate_check(log: Log) -> str:
    """Refuse a log whose rows are further apart than its drive's current period (when the file gives it); the
    note of a log whose ``iq_ref_A`` changes at most rows (the speed controller's rate), else ""."""
    dt = log.dt_s
    if log.current_period_s is not None and dt > PERIODS_PER_ROW_MAX * log.current_period_s:
        raise IdentificationError(
            f"the log's rows are {dt:.4g} s apart, {dt / log.current_period_s:.3g} periods of its current loop "
            f"(current_loop.Ts_s = {log.current_period_s:.4g} s), which changes the voltage at each: the fit holds "
            "a row's voltage until the next row, so it needs a row per current period (simulate with "
            "simulation.log_rate = 'current' and simulation.log_every = 1)"
        )
    if log.current_period_s is not None or log.iq_ref_A is None or len(log.t_s) < 3:
        return ""
    changes = np.diff(log.iq_ref_A) != 0.0
    n_changes = int(np.count_nonzero(changes[:-1]))
    share = float(np.count_nonzero(changes[:-1] & changes[1:]) / n_changes) if n_changes else 0.0
    if share <= COMMAND_CHANGES_MAX:
        return ""
    return (
        f"iq_ref_A changes again at the next row after {100 * share:.3g} % of its changes (rows {dt:.4g} s apart): "
        "the rows look like the speed "
        "controller's samples; the fit holds a row's voltage until the next row, so if the current loop runs "
        "faster, its voltage changed between the rows and the estimates are biased (a few %): log every current "
        "period (pmsm2dof: simulation.log_rate = 'current')"
    )


def identify_electrical(
    log: Log,
    pole_pairs: int,
    voltage_delay_samples: int = 0,
    *,
    angle_lead_samples: float | None = None,
    dead_time: bool = False,
    u_dc_V: float | None = None,
    current_ranges: int | None = None,
    window_samples: int | None = None,
) -> Electrical:
    """Rs, Ld, Lq and psi_f of eq 1 from a log with id_A, iq_A, ud_V, uq_V and the speed.

    Parameters
    ----------
    log : Log
        The run (:func:`pmsm2dof.sim.logs.read_log`).
    pole_pairs : int
        Pole pairs p (w_e = p w_m).
    voltage_delay_samples : int
        The logged voltage applies this many samples after its row (0: over the period that starts at it).
    angle_lead_samples : float or None
        X: the drive turns the logged reference into the stator frame at the row's angle plus ``X w_e Ts`` and
        the inverter holds that vector over its period (module docstring); None: the logged voltage is the
        rotor-frame voltage over its period.
    dead_time : bool
        Fit the inverter's dead-time voltage per phase ``dead_time_V`` [V] with Rs (needs two current levels).
    u_dc_V : float or None
        DC-link voltage [V]: periods with ``|u_dq| >= u_dc / sqrt(3) (1 - VOLTAGE_MARGIN)`` are at the limit
        (default: the log's ``u_dc_V`` column, if any).
    current_ranges : int or None
        Ranges of the window-mean ``|i_dq|`` for the per-range Ld and Lq (1: none; None: automatic, module
        docstring); a range too sparse is merged into a neighbour, so that fewer may result.
    window_samples : int or None
        Distance N of the two blocks of a row [samples] (default: rows / 960, at least 8); blocks N/2 long.

    Raises
    ------
    ConfigError
        A missing column or a bad argument.
    IdentificationError
        A parameter the log does not determine: the message names it and what experiment would.
    """
    for name in ("id_A", "iq_A", "ud_V", "uq_V"):
        if getattr(log, name) is None:
            raise ConfigError("log", log.source, f"a log with {name} for --electrical (and id_A, iq_A, ud_V, uq_V)")
    if pole_pairs < 1:
        raise ConfigError("pole_pairs", pole_pairs, "an integer >= 1")
    if voltage_delay_samples < 0 or voltage_delay_samples > 100:
        raise ConfigError("voltage_delay_samples", voltage_delay_samples, "an integer in [0, 100]")
    if angle_lead_samples is not None and not abs(angle_lead_samples) <= ANGLE_LEAD_MAX:
        raise ConfigError(
            "angle_lead_samples", angle_lead_samples, f"a number in [-{ANGLE_LEAD_MAX:g}, {ANGLE_LEAD_MAX:g}]"
        )
    if u_dc_V is not None and not (math.isfinite(u_dc_V) and u_dc_V > 0):
        raise ConfigError("u_dc_V", u_dc_V, "a finite voltage > 0 [V]")
    if current_ranges is not None and not 1 <= current_ranges <= RANGES_MAX:
        raise ConfigError("current_ranges", current_ranges, f"an integer in [1, {RANGES_MAX}]")
    rate_note = _rate_check(log)
    n_total = len(log.t_s)
    if window_samples is None:
        window_samples = max(8, n_total // 960)
    if window_samples < 2:
        raise ConfigError("window_samples", window_samples, "an integer >= 2")
    n, m = window_samples, max(1, window_samples // 2)
    d = voltage_delay_samples
    assert log.id_A is not None and log.iq_A is not None
    # a logged reference is not the applied voltage where the inverter cut it (module docstring)
    logged_reference = d > 0 or angle_lead_samples is not None or u_dc_V is not None
    found = _windows(log, pole_pairs, d, angle_lead_samples, dead_time, u_dc_V, logged_reference, n, m, None)
    blocks, n_used, n_flagged, n_dropped = found.blocks, found.n_used, found.n_flagged, found.n_dropped
    stuck, has_limit_source = found.stuck, found.has_limit_source
    if not blocks and not n_dropped:
        raise IdentificationError(f"the log is too short for windows of {n + m} samples ({n_total} rows)")
    k = sum(len(blk.y_d) for blk in blocks)
    if k < WINDOWS_MIN:
        limited = f" ({n_dropped} windows touch the {n_flagged} samples at the voltage limit)" if n_dropped else ""
        raise IdentificationError(
            f"{k} windows of {n + m} samples{limited}, at least {WINDOWS_MIN} needed: "
            + (
                "a run that stays within the inverter's voltage range (lower speed or current)"
                if n_dropped
                else "a longer log"
            )
        )
    rows = _Rows(*(np.concatenate([getattr(blk, f.name) for blk in blocks]) for f in dataclasses.fields(_Rows)))
    i_low, i_high = np.percentile(rows.i_mean_A, [10, 90])
    if dead_time and not i_high >= DEAD_TIME_SPAN * i_low:
        raise IdentificationError(
            f"{DEAD_TIME} is not identifiable with Rs from this log (window |i_dq| {i_low:.3g} to {i_high:.3g} A, "
            f"10th to 90th percentile, less than a factor {DEAD_TIME_SPAN:g}): Rs |i| and the dead-time voltage "
            "separate only where |i_dq| takes different values; it needs a log with two current levels (e.g. DC "
            "currents at a third of and at the rated current), or a fit without the dead-time term"
        )
    theta, sd, e, q = _iv_fit(rows, rows.X_d, rows.X_q, rows.Z_d, rows.Z_q)
    if theta[1] > 0 and theta[2] > 0:
        # the current's bend within a period, from the first fit's inductances (module docstring): a second fit
        inductances = (float(theta[1]), float(theta[2]))
        found = _windows(log, pole_pairs, d, angle_lead_samples, dead_time, u_dc_V, logged_reference, n, m, inductances)
        rows = _Rows(
            *(np.concatenate([getattr(blk, f.name) for blk in found.blocks]) for f in dataclasses.fields(_Rows))
        )
        theta, sd, e, q = _iv_fit(rows, rows.X_d, rows.X_q, rows.Z_d, rows.Z_q)
    names = (*PARAMETERS, DEAD_TIME) if dead_time else PARAMETERS
    if dead_time and not (_determined(theta[0], sd[0]) and np.isfinite(sd[4])):
        raise IdentificationError(
            f"{DEAD_TIME} is not identifiable with Rs from this log: Rs {theta[0]:.4g} +- {sd[0]:.3g} ohm, "
            f"{DEAD_TIME} {theta[4]:.4g} +- {sd[4]:.3g} V; it needs a log with two current levels held long "
            "enough (e.g. DC currents at a third of and at the rated current), or a fit without the dead-time term"
        )
    for name, value, s in zip(PARAMETERS, theta, sd, strict=False):
        if not _determined(value, s):
            spread = {"Ld_H": ("id", log.id_A), "Lq_H": ("iq", log.iq_A)}
            moved = ""
            if name in spread:
                sig, x = spread[name]
                moved = f" ({sig} spans {np.ptp(x):.3g} A)"
            left_out = f" ({n_dropped} windows at the voltage limit left out)" if n_dropped else ""
            if has_limit_source and not logged_reference and n_flagged:
                left_out = (
                    f" ({n_flagged} samples at the voltage limit kept as applied voltages: if the log holds the "
                    "controller's reference, give voltage_delay_samples, angle_lead_samples or u_dc_V)"
                )
            raise IdentificationError(
                f"{name} is not identifiable from this log{moved}{left_out}: estimate {value:.4g}, standard "
                f"deviation {s:.3g}; it needs a log where {_NEEDS[name]}"
            )
    ci = {name: (float(v - q * s), float(v + q * s)) for name, v, s in zip(names, theta, sd, strict=True)}
    notes = [rate_note] if rate_note else []
    if not has_limit_source and stuck >= STUCK_SAMPLES:
        notes.append(
            f"|u_dq| sits at its largest value in {stuck} samples: if the drive logged its reference "
            "after its own voltage limit, those windows are not its applied voltage; give the DC-link voltage "
            "(u_dc_V) or a voltage_limited column to leave them out"
        )
    if has_limit_source and not logged_reference and n_flagged:
        notes.append(
            f"{n_flagged} samples at the voltage limit kept: the logged voltage is taken as the voltage applied "
            "over its period (voltage_delay_samples 0, no angle_lead_samples, no u_dc_V); if the log holds the "
            "controller's reference, give one of them to leave those windows out"
        )
    asked = current_ranges is not None
    if current_ranges is None:
        lo, hi = np.percentile(rows.i_mean_A, [5, 95])
        current_ranges = AUTO_RANGES if hi > AUTO_SPAN * lo and k >= AUTO_RANGES * WINDOWS_MIN else 1
    edges = _range_edges(rows.i_mean_A, current_ranges)
    if asked and len(edges) - 1 < current_ranges:
        notes.append(
            f"{len(edges) - 1} current range{'s' if len(edges) > 2 else ''} instead of the {current_ranges} asked: "
            f"a range with fewer than {WINDOWS_MIN} windows is merged into its neighbour (window |i_dq| "
            f"{edges[0]:.3g} to {edges[-1]:.3g} A; a longer log, or currents spread wider, gives more)"
        )
    ranges = _fit_ranges(rows, edges, len(names)) if len(edges) > 2 else ()
    notes += _saturation_notes(ranges)
    fitted = {"ud_fit_V": rows.X_d @ theta, "uq_fit_V": rows.X_q @ theta}
    return Electrical(
        Rs_ohm=float(theta[0]),
        Ld_H=float(theta[1]),
        Lq_H=float(theta[2]),
        psi_f_Wb=float(theta[3]),
        dead_time_V=float(theta[4]) if dead_time else None,
        ci=ci,
        residual_rms_V=float(np.sqrt(np.mean(e**2))),
        n_samples=n_used,
        n_windows=k,
        n_samples_voltage_limited=n_flagged if has_limit_source else None,
        n_windows_voltage_limited=n_dropped,
        ranges=ranges,
        notes=tuple(notes),
        rows={"t_s": rows.t0_s, "ud_V": rows.y_d, "uq_V": rows.y_q, **fitted},
    )
