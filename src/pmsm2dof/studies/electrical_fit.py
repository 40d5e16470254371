"""The rows, the windows and the instrumental-variable fit of the electrical identification.

The machinery of :func:`pmsm2dof.studies.electrical.identify_electrical` (its module docstring
derives the rows of eq 1 this fits), with the thresholds it applies.
"""

import dataclasses
import math
from typing import Any

import numpy as np
import scipy.stats

from ..sim.logs import Log
from .identify import LEVEL, _block_means, _cumtrapz

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

#: The per-range note needs the lowest- and highest-current ranges this far apart (relative), beyond their intervals.
SATURATION_MIN = 0.05


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
