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
integral is a sum over whole periods); a log that records the voltage computed at a sample and
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
sqrt(3)`` within :data:`VOLTAGE_MARGIN` (the DC link from ``u_dc_V`` or the log's ``u_dc_V``
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

Identifiability: a parameter whose relative standard deviation exceeds :data:`REL_SD_MAX` is not
reported: :class:`~pmsm2dof.studies.identify.IdentificationError` names it and the experiment that
would fix it (id never moved: Ld; no speed: psi_f ...).
"""

import dataclasses
import math
from typing import Any

import numpy as np
import scipy.stats

from ..errors import ConfigError
from ..sim.logs import Log
from .identify import LEVEL, IdentificationError, _block_means, _cumtrapz

#: The identified parameters of eq 1, in the order of the regressors.
PARAMETERS = ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")

#: The dead-time voltage per phase [V], the fifth regressor with ``dead_time = True``.
DEAD_TIME = "dead_time_V"

#: A parameter is reported when its standard deviation is below this share of its value.
REL_SD_MAX = 0.05

#: Fewest windows of a fit (and of a current range).
WINDOWS_MIN = 12

#: A period is at the voltage limit when its ``|u_dq|`` reaches u_dc / sqrt(3) times (1 - this).
VOLTAGE_MARGIN = 0.02

#: Without a limit source: ``|u_dq|`` within this share of its largest value at STUCK_SAMPLES samples or more
#: is the signature of a reference logged after the drive's own limit.
STUCK_TOLERANCE = 1e-3
STUCK_SAMPLES = 20

#: Default current ranges: AUTO_RANGES when the windows' ``|i_dq|`` (5th to 95th percentile) span more than AUTO_SPAN.
AUTO_RANGES = 3
AUTO_SPAN = 2.0

#: The per-range note needs the lowest- and highest-current ranges this far apart (relative), beyond their intervals.
SATURATION_MIN = 0.05

#: The dead-time term needs the windows' ``|i_dq|`` (10th to 90th percentile) to span at least this factor.
DEAD_TIME_SPAN = 1.5

#: Most current ranges.
RANGES_MAX = 10

#: Largest ``|angle_lead_samples|``.
ANGLE_LEAD_MAX = 10.0

#: What each parameter needs from the log, for the message when it is not identifiable.
_NEEDS = {
    "Rs_ohm": "a current held while the speed is low (a DC current at standstill, or a slow run under load)",
    "Ld_H": "id moved (a d-axis current step at standstill, or a run into field weakening); "
    "with id at zero Ld only multiplies zero",
    "Lq_H": "iq moved (torque or speed steps)",
    "psi_f_Wb": "the rotor turned (a run at speed)",
}


@dataclasses.dataclass(frozen=True, eq=False)
class CurrentRange:
    """Ld and Lq fitted over the windows whose mean ``|i_dq|`` lies in one range.

    Attributes
    ----------
    i_low_A, i_high_A : float
        The range's edges: the window-mean ``|i_dq|`` it holds [A].
    n_windows : int
        Windows in the range.
    Ld_H, Lq_H : float or None
        The range's inductances [H], None where the range does not determine them (relative standard
        deviation beyond :data:`REL_SD_MAX`).
    ci : dict
        ``Ld_H``/``Lq_H`` -> 95 % interval, for those determined.
    """

    i_low_A: float
    i_high_A: float
    n_windows: int
    Ld_H: float | None
    Lq_H: float | None
    ci: dict[str, tuple[float, float]]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"i_low_A": self.i_low_A, "i_high_A": self.i_high_A, "n_windows": self.n_windows}
        for name in ("Ld_H", "Lq_H"):
            out[name] = getattr(self, name)
            out[f"{name}_ci"] = list(self.ci[name]) if name in self.ci else None
        return out


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

    def motor_toml(self, pole_pairs: int, source: str) -> str:
        """The identified motor as a ``[motor]`` table for ``pmsm2dof design --motor`` (as ``commission --out``)."""
        lines = [
            f"# identified from {source} by pmsm2dof identify electrical",
            "# per phase, amplitude-invariant dq (eq 1)",
        ]
        if self.dead_time_V is not None:
            lo, hi = self.ci[DEAD_TIME]
            lines.append(f"# inverter dead-time voltage per phase: {self.dead_time_V:.4g} V [{lo:.4g}, {hi:.4g}]")
        for r in self.ranges:
            found = ", ".join(
                f"{name} = {value:.4g}" for name in ("Ld_H", "Lq_H") if (value := getattr(r, name)) is not None
            )
            lines.append(f"# |i_dq| {r.i_low_A:.3g} to {r.i_high_A:.3g} A: {found or 'not determined'}")
        lines += ["[motor]", f"pole_pairs = {pole_pairs}"]
        lines += [f"{name} = {getattr(self, name)!r}" for name in PARAMETERS]
        lines += [f"{name}_ci = [{lo!r}, {hi!r}]" for name, (lo, hi) in self.ci.items() if name in PARAMETERS]
        return "\n".join(lines) + "\n"


@dataclasses.dataclass(frozen=True)
class _Rows:
    """The windows of one segment: regressors of the d and q rows, window-mean voltages, instruments."""

    X_d: np.ndarray
    y_d: np.ndarray
    X_q: np.ndarray
    y_q: np.ndarray
    Z_d: np.ndarray
    Z_q: np.ndarray
    t0_s: np.ndarray
    i_mean_A: np.ndarray


def _turning_integral(t: np.ndarray, theta: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The running integral of ``exp(j theta) x`` from ``t[0]``, ``theta`` and ``x`` linear within each period.

    Over a period of length ``h`` in which the angle turns by ``phi``:
    ``h exp(j theta_k) (x_k (A0 - A1) + x_(k+1) A1)``, ``A0 = int_0^1 exp(j phi s) ds``,
    ``A1 = int_0^1 s exp(j phi s) ds`` (their Taylor series where ``|phi|`` is small).
    """
    h = np.diff(t)
    phi = np.diff(theta)
    small = np.abs(phi) < 1e-2
    jp = 1j * np.where(small, 1.0, phi)
    ep = np.exp(jp)
    a0 = (ep - 1.0) / jp
    a1 = ep / jp - (ep - 1.0) / jp**2
    js = 1j * phi
    a0 = np.where(small, 1.0 + js / 2.0 + js**2 / 6.0 + js**3 / 24.0, a0)
    a1 = np.where(small, 0.5 + js / 3.0 + js**2 / 8.0 + js**3 / 30.0, a1)
    period = h * np.exp(1j * theta[:-1]) * (x[:-1] * (a0 - a1) + x[1:] * a1)
    out: np.ndarray = np.concatenate(([0.0], np.cumsum(period)))
    return out


def _bend(
    t: np.ndarray,
    theta: np.ndarray,
    i_dq: np.ndarray,
    u_s: np.ndarray,
    inductances: tuple[float, float],
    stator_hold: bool,
) -> np.ndarray:
    """The running integral of ``exp(j theta)`` times the part of ``i_dq`` that bends within a period (module
    docstring): ``-(h^3 / 12) exp(j theta_mid) L^-1 psi_dq''`` a period, ``psi_dq'' = -j w_e (psi_dq' + u_r)`` under
    a stator-frame hold, ``-j w_e psi_dq'`` under a rotor-frame one, with the period's mean flux slope ``psi_dq' =
    (Ld did + j Lq diq) / h`` and rotor-frame voltage ``u_r``."""
    Ld_H, Lq_H = inductances
    h = np.diff(t)
    turned = np.diff(theta)
    w_e = turned / h
    mid = np.exp(1j * (theta[:-1] + 0.5 * turned))
    slope = (Ld_H * np.diff(i_dq.real) + 1j * Lq_H * np.diff(i_dq.imag)) / h
    if stator_hold:
        slope = slope + np.conj(mid) * u_s[:-1] / h
    bend = -1j * w_e * slope
    period = -(h**3) / 12.0 * mid * (bend.real / Ld_H + 1j * bend.imag / Lq_H)
    out: np.ndarray = np.concatenate(([0.0], np.cumsum(period)))
    return out


def _regressors(
    t: np.ndarray,
    theta: np.ndarray,
    i_d: np.ndarray,
    i_q: np.ndarray,
    u_s: np.ndarray,
    a: np.ndarray,
    n: int,
    m: int,
    dead_time: bool,
    inductances: tuple[float, float] | None,
    stator_hold: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Regressors and window-mean voltages of the windows starting at ``a``: (X_d, y_d, X_q, y_q).

    ``theta`` is the electrical angle at the samples [rad], ``u_s`` the stator-frame voltage integral over
    each period [V s] (:func:`_held_voltage`). Each pair of instants ``a + j``, ``b + j`` gives the
    stator-frame relation turned to the angle of ``a + j`` (module docstring), averaged over ``j``.
    """
    b = a + n
    turn = np.exp(1j * theta)
    back = np.conj(turn[:-n])

    def pair(F: np.ndarray) -> np.ndarray:
        # mean over j of exp(-j theta(a+j)) (F(b+j) - F(a+j))
        out: np.ndarray = _block_means(back * (F[n:] - F[:-n]), a, m)
        return out

    i_dq = i_d + 1j * i_q
    span = _block_means(t, b, m) - _block_means(t, a, m)
    # the held voltage: int_a^b u_s dt, a sum of whole periods
    y = pair(np.concatenate(([0.0], np.cumsum(u_s[:-1])))) / span
    # Rs int i_s dt + exp(j theta) (Ld id + j Lq iq + psi_f) between a and b
    current = _turning_integral(t, theta, i_dq)
    if inductances is not None:
        current += _bend(t, theta, i_dq, u_s, inductances, stator_hold)
    cols = [pair(current), pair(turn * i_d), pair(1j * turn * i_q), pair(turn)]
    if dead_time:
        # the fundamental of the per-phase dead-time error: (4/pi) dead_time_V i_dq / |i_dq|
        magnitude = np.abs(i_dq)
        inverse = np.divide(1.0, magnitude, out=np.zeros_like(magnitude), where=magnitude > 0)
        cols.append(4.0 / math.pi * pair(_turning_integral(t, theta, i_dq * inverse)))
    X = np.column_stack(cols) / span[:, None]
    return X.real, y.real, X.imag, y.imag


def _keep(x: np.ndarray, parity: int) -> np.ndarray:
    """The samples of one parity, the others replaced by the mean of their two neighbours (of that parity)."""
    out = x.copy()
    other = np.arange(1 - parity, len(x), 2)
    inner = other[(other > 0) & (other < len(x) - 1)]
    out[inner] = 0.5 * (x[inner - 1] + x[inner + 1])
    edge = other[(other == 0) | (other == len(x) - 1)]
    out[edge] = x[np.where(edge == 0, 1, len(x) - 2)]
    return out


def _held_voltage(
    t: np.ndarray,
    theta: np.ndarray,
    u_dq: np.ndarray,
    theta_u: np.ndarray,
    w_u: np.ndarray,
    Ts_s: float,
    lead: float | None,
) -> np.ndarray:
    """The stator-frame voltage integral over each period [V s] (module docstring); the last is zero.

    ``u_dq`` is the logged voltage that applies over the period from ``t[k]``, ``theta`` the angle at ``t``,
    ``theta_u`` and ``w_u`` the angle and electrical speed at the row that logged ``u_dq``. With ``lead = X`` the
    stator-frame vector ``u_dq exp(j (theta_u + X w_u Ts))`` is held; with None the rotor-frame ``u_dq`` is held,
    ``int exp(j theta) dt = Ts exp(j theta_k) exp(j w Ts / 2) sinc(w Ts / 2)`` at the period's mean speed ``w``.
    """
    dt = np.diff(t)
    if lead is None:
        turned = np.diff(theta)
        # numpy's sinc is sin(pi x) / (pi x)
        u_s = u_dq[:-1] * np.exp(1j * (theta[:-1] + 0.5 * turned)) * np.sinc(0.5 * turned / math.pi) * dt
    else:
        u_s = u_dq[:-1] * np.exp(1j * (theta_u[:-1] + lead * w_u[:-1] * Ts_s)) * dt
    # the last sample's voltage applies beyond the log
    out: np.ndarray = np.append(u_s, 0.0)
    return out


@dataclasses.dataclass
class _Windows:
    """The windows of a log's segments and what the voltage-limit handling counted."""

    blocks: list[_Rows] = dataclasses.field(default_factory=list)
    n_used: int = 0
    n_flagged: int = 0
    n_dropped: int = 0
    stuck: int = 0
    has_limit_source: bool = False


def _windows(
    log: Log,
    pole_pairs: int,
    d: int,
    angle_lead_samples: float | None,
    dead_time: bool,
    u_dc_V: float | None,
    logged_reference: bool,
    n: int,
    m: int,
    inductances: tuple[float, float] | None,
) -> _Windows:
    """The regression rows of every segment of the log (module docstring), windows at the voltage limit left out
    where the log holds references (``logged_reference``)."""
    assert log.id_A is not None and log.iq_A is not None and log.ud_V is not None and log.uq_V is not None
    out = _Windows()
    for seg in log.segments():
        idx = np.arange(seg.start, seg.stop)
        if idx.size <= d + n + m:
            continue
        # the voltage applied over the period that starts at row k was logged at row k - d
        rows_u = idx[: idx.size - d]
        rows_x = idx[d:]
        t = log.t_s[rows_x]
        w_seg = pole_pairs * log.w_m_radps[idx]
        # only angle differences within a window matter: the angle from the logged speed by trapezoids
        theta_seg = _cumtrapz(log.t_s[idx], w_seg)
        theta = theta_seg[d:]
        i_d, i_q = log.id_A[rows_x], log.iq_A[rows_x]
        u_d, u_q = log.ud_V[rows_u], log.uq_V[rows_u]
        flags = _limited(log, rows_u, u_d, u_q, u_dc_V)
        u_s = _held_voltage(
            t, theta, u_d + 1j * u_q, theta_seg[: idx.size - d], w_seg[: idx.size - d], log.dt_s, angle_lead_samples
        )
        a = np.arange(0, len(t) - n - m + 1, n)
        if flags is None:
            magnitude = np.hypot(log.ud_V[rows_u], log.uq_V[rows_u])
            out.stuck += int(np.count_nonzero(magnitude >= (1.0 - STUCK_TOLERANCE) * np.max(magnitude)))
        else:
            out.has_limit_source = True
            out.n_flagged += int(np.count_nonzero(flags))
            if logged_reference:
                # a window integrates the voltages of its samples a .. b + m - 2
                count = np.concatenate(([0], np.cumsum(flags)))
                keep = count[a + n + m - 1] - count[a] == 0
                out.n_dropped += int(np.count_nonzero(~keep))
                a = a[keep]
        if a.size == 0:
            continue
        out.n_used += rows_x.size
        magnitude_sum = np.concatenate(([0.0], np.cumsum(np.hypot(i_d, i_q))))
        # split-sample instruments: regressors from the even samples' currents, instruments from the odd ones'
        hold = (inductances, angle_lead_samples is not None)
        X_d, y_d, X_q, y_q = _regressors(t, theta, _keep(i_d, 0), _keep(i_q, 0), u_s, a, n, m, dead_time, *hold)
        Z_d, _, Z_q, _ = _regressors(t, theta, _keep(i_d, 1), _keep(i_q, 1), u_s, a, n, m, dead_time, *hold)
        i_mean = (magnitude_sum[a + n + m] - magnitude_sum[a]) / (n + m)
        out.blocks.append(_Rows(X_d, y_d, X_q, y_q, Z_d, Z_q, t[a], i_mean))
    return out


def _limited(log: Log, rows_u: np.ndarray, u_d: np.ndarray, u_q: np.ndarray, u_dc_V: float | None) -> np.ndarray | None:
    """Which logged voltages are at the inverter's limit, or None when the log gives no source."""
    flags: np.ndarray | None = None
    if log.voltage_limited is not None:
        flags = log.voltage_limited[rows_u] > 0
    u_dc = None if u_dc_V is None else np.full(rows_u.size, u_dc_V)
    if u_dc is None and log.u_dc_V is not None:
        u_dc = log.u_dc_V[rows_u]
    if u_dc is not None:
        at_limit = np.hypot(u_d, u_q) >= u_dc / math.sqrt(3.0) * (1.0 - VOLTAGE_MARGIN)
        flags = at_limit if flags is None else flags | at_limit
    return flags


def _iv_fit(
    rows: _Rows, X_d: np.ndarray, X_q: np.ndarray, Z_d: np.ndarray, Z_q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Instrumental-variable fit of the d and q rows with Newey-West intervals over the windows.

    Returns
    -------
    theta, sd, residuals, t quantile of the 95 % interval. A column the rows do not excite (the
    largest component of the direction of the smallest singular value, dropped until the rest is
    well conditioned) gets NaN and an infinite standard deviation.
    """
    k, p = X_d.shape
    X = np.vstack([X_d, X_q])
    y = np.concatenate([rows.y_d, rows.y_q])
    Z = np.vstack([Z_d, Z_q])
    # column scales: the rank test does not depend on units
    scale = np.sqrt(np.sum(X**2, axis=0))
    scale[scale == 0] = 1.0
    kept = list(range(p))
    while True:
        _, singular, vt = np.linalg.svd(X[:, kept] / scale[kept], full_matrices=False)
        if singular[-1] > 1e-9 * singular[0] or len(kept) == 1:
            break
        del kept[int(np.argmax(np.abs(vt[-1])))]
    theta = np.full(p, np.nan)
    sd = np.full(p, np.inf)
    ZX = Z[:, kept].T @ X[:, kept]
    theta[kept] = np.linalg.solve(ZX, Z[:, kept].T @ y)
    e = y - X[:, kept] @ theta[kept]
    # Newey-West over the windows: the score of a window is its d row's plus its q row's
    scores = Z_d[:, kept] * e[:k, None] + Z_q[:, kept] * e[k:, None]
    lags = max(2, math.ceil(4.0 * (k / 100.0) ** (2.0 / 9.0)))
    S = scores.T @ scores
    for lag in range(1, min(lags, k - 1) + 1):
        G = scores[lag:].T @ scores[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    dof = 2 * k - len(kept)
    inv = np.linalg.inv(ZX)
    cov = inv @ S @ inv.T * (2 * k) / dof
    sd[kept] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return theta, sd, e, float(scipy.stats.t.ppf(0.5 + LEVEL / 2.0, dof))


def _determined(value: float, sd: float) -> bool:
    return bool(np.isfinite(sd) and sd < REL_SD_MAX * abs(value))


def _range_edges(i_mean_A: np.ndarray, n_ranges: int) -> np.ndarray:
    """The edges of the current ranges: ``n_ranges`` of equal width from the smallest to the largest
    window-mean ``|i_dq|``, each range with fewer than :data:`WINDOWS_MIN` windows merged into its
    neighbour with fewer windows until every range holds enough (one range left: no split)."""
    edges = list(np.linspace(float(i_mean_A.min()), float(i_mean_A.max()), n_ranges + 1))
    while len(edges) > 2:
        counts = np.bincount(np.searchsorted(edges[1:-1], i_mean_A, side="right"), minlength=len(edges) - 1)
        r = int(np.argmin(counts))
        if counts[r] >= WINDOWS_MIN:
            break
        # drop the inner edge between range r and its neighbour with fewer windows
        left = r > 0 and (r == len(counts) - 1 or counts[r - 1] <= counts[r + 1])
        del edges[r if left else r + 1]
    return np.array(edges)


def _fit_ranges(rows: _Rows, edges: np.ndarray, n_common: int) -> tuple[CurrentRange, ...]:
    """Ld and Lq per range of the window-mean |i_dq| (:func:`_range_edges`), the other parameters common."""
    n_ranges = len(edges) - 1
    index = np.searchsorted(edges[1:-1], rows.i_mean_A, side="right")
    member = index[:, None] == np.arange(n_ranges)[None, :]
    common = [0, 3, *range(4, n_common)]

    def split(M: np.ndarray) -> np.ndarray:
        return np.column_stack([M[:, common], M[:, [1]] * member, M[:, [2]] * member])

    theta, sd, _, q = _iv_fit(rows, split(rows.X_d), split(rows.X_q), split(rows.Z_d), split(rows.Z_q))
    out = []
    base = len(common)
    for r in range(n_ranges):
        values: dict[str, float | None] = {}
        ci: dict[str, tuple[float, float]] = {}
        for name, col in (("Ld_H", base + r), ("Lq_H", base + n_ranges + r)):
            if _determined(theta[col], sd[col]):
                values[name] = float(theta[col])
                ci[name] = (float(theta[col] - q * sd[col]), float(theta[col] + q * sd[col]))
            else:
                values[name] = None
        out.append(
            CurrentRange(
                i_low_A=float(edges[r]),
                i_high_A=float(edges[r + 1]),
                n_windows=int(np.count_nonzero(index == r)),
                Ld_H=values["Ld_H"],
                Lq_H=values["Lq_H"],
                ci=ci,
            )
        )
    return tuple(out)


def _saturation_notes(ranges: tuple[CurrentRange, ...]) -> list[str]:
    """A note per inductance whose lowest- and highest-current ranges differ beyond their intervals and by
    more than :data:`SATURATION_MIN`."""
    notes = []
    for name, axis in (("Ld_H", "Ld"), ("Lq_H", "Lq")):
        found = [r for r in ranges if getattr(r, name) is not None]
        if len(found) < 2:
            continue
        low, high = found[0], found[-1]
        (lo_a, hi_a), (lo_b, hi_b) = low.ci[name], high.ci[name]
        a, b = getattr(low, name), getattr(high, name)
        if (hi_b < lo_a or hi_a < lo_b) and abs(b / a - 1.0) > SATURATION_MIN:
            change = f"{axis} {'falls' if b < a else 'rises'} from {a * 1e3:.4g} to {b * 1e3:.4g} mH over |i_dq| "
            change += f"{low.i_low_A:.3g} to {high.i_high_A:.3g} A"
            notes.append(
                f"the machine saturates: {change}"
                if b < a
                else f"{change}: not saturation, check the log's conventions"
            )
    return notes


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
    notes = []
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
