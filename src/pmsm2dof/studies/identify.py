"""Identification of the mechanics from a logged run: inertia J, viscous B and Coulomb friction.

Model (rigid shaft, the engine's and eq 1's): ``J dw/dt = Te - B w - Tc sign(w) - T_load``, with
T_load zero except for loads the log does not announce. Integrated between two instants ``a`` and
``b`` it is exact whatever happens in between::

    J (w(b) - w(a)) = int_a^b Te dt - B int_a^b w dt - Tc int_a^b sign(w) dt - int_a^b T_load dt

Regression rows (:func:`identify_mechanics`): each row averages this relation over the ``M``
instants ``a + j`` and ``b + j`` (j = 0..M-1) of two blocks ``N`` samples apart, so that the
speed enters as the difference of two block means (noise of a differenced encoder, whose
block mean errs by about one count over the block, shrinks by M: the errors-in-variables bias of
J, ``var(noise) / var(dw)``, stays below a few 1e-4), and the integrals, by cumulative trapezoids
of the samples, as the mean of ``F(b + j) - F(a + j)``. Dividing by ``N dt`` gives rows in Nm::

    y  = mean_j(FT(b+j) - FT(a+j)) / (N dt)          x_J = (mean_j w(b+j) - mean_j w(a+j)) / (N dt)
    x_B = mean_j(Fw(b+j) - Fw(a+j)) / (N dt)         x_C = mean_j(Fs(b+j) - Fs(a+j)) / (N dt)

with ``FT``, ``Fw``, ``Fs`` the running integrals of Te, w and sign(w). Rows follow each other
(stride N, each block shared by two rows) within one segment of the log (never across a gap) and
are used only where the speed stays away from zero (sign(w) defined; no stiction).

Fit: ordinary least squares, then a Huber regression (``scipy.optimize.least_squares``,
``loss="huber"``) scaled by the median absolute deviation of the residuals; rows whose robust
residual exceeds :data:`OUTLIER_SIGMAS` robust standard deviations (an unannounced load, a
stall, a transient the log's sampling does not resolve) are excluded and reported as time
windows, and the parameters are the least squares of the rows kept. The note calls them an
unannounced load only when their residuals say so: consecutive rows with one constant residual,
the load's torque (:func:`_constant_runs`). This removes loads acting on less than half the rows and several times the
noise; a smaller load biases the fit by at most its share of the rows times its size.

Intervals: 95 % intervals ``theta_i +- t(0.975, n - 3) sd_i`` from the Newey-West covariance
(W. K. Newey and K. D. West, "A simple, positive semi-definite, heteroskedasticity and
autocorrelation consistent covariance matrix", Econometrica 55(3), 1987) of the kept rows, with
Bartlett weights over ``L = ceil(4 (n / 100)^(2/9))`` lags at least 2: rows that share a block,
and the closed loop's correlated torque noise, make the residuals correlated, and an interval
from the white-noise formula would be too narrow.

Identifiability: J is reported only when its relative standard deviation is below
:data:`J_REL_SD_MAX`; otherwise :class:`IdentificationError` says why and what experiment
would do (speed steps or torque pulses: ``pmsm2dof identify plan``).

The time constant of the current loop (eq 3) comes from the logged iq steps when ``iq_ref_A``
is in the log (:func:`identify_tau_i`).
"""

import dataclasses
import math
import warnings
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats

from ..errors import ConfigError, Pmsm2dofError, Pmsm2dofWarning
from ..sim.logs import Log
from ..sim.plausibility import voltage_limited_speed_radps
from ..sim.scenario import Scenario

#: Rows with a robust residual above this many robust standard deviations are excluded.
OUTLIER_SIGMAS = 3.5

#: J is reported when sd(J) / J is below this.
J_REL_SD_MAX = 0.05

#: Fewest regression rows of a fit.
ROWS_MIN = 12

#: The default window: block means whose speed noise variance is at most this share of the
#: mean square speed change of the rows (the bias of J it causes is about as large) ...
NOISE_SHARE_MAX = 1e-3

#: ... with at least this many rows in the log.
ROWS_AUTO = 60

#: Confidence level of the intervals.
LEVEL = 0.95

#: Excluded rows are said to be an unannounced load when at least this many consecutive ones ...
LOAD_ROWS_MIN = 4

#: ... have residuals of one sign within this share of their median (a constant torque).
LOAD_SPREAD = 0.05


class IdentificationError(Pmsm2dofError):
    """The log does not determine the parameters asked for; the message says what would."""


@dataclasses.dataclass(frozen=True)
class Mechanics:
    """Identified mechanics of a log, with 95 % intervals.

    Attributes
    ----------
    J_kgm2, B_Nms, T_coulomb_Nm : float
        Inertia [kg m^2], viscous friction [Nm s/rad], Coulomb friction [Nm].
    J_kgm2_ci, B_Nms_ci, T_coulomb_Nm_ci : tuple of float
        Their 95 % intervals.
    residual_rms_Nm : float
        RMS of the residual of the rows kept [Nm].
    n_samples : int
        Log rows that enter the rows kept.
    n_rows, n_rows_excluded : int
        Regression rows kept, and excluded as outliers.
    excluded_s : tuple of (float, float)
        Time windows of the excluded rows (merged) [s].
    window_s : float
        Distance of the two blocks of a row, N dt [s].
    notes : tuple of str
        Findings, one line each.
    """

    J_kgm2: float
    B_Nms: float
    T_coulomb_Nm: float
    J_kgm2_ci: tuple[float, float]
    B_Nms_ci: tuple[float, float]
    T_coulomb_Nm_ci: tuple[float, float]
    residual_rms_Nm: float
    n_samples: int
    n_rows: int
    n_rows_excluded: int
    excluded_s: tuple[tuple[float, float], ...]
    window_s: float
    notes: tuple[str, ...]
    rows: dict[str, np.ndarray] = dataclasses.field(repr=False, compare=False)

    def to_json(self) -> dict[str, Any]:
        """The figures as a JSON-serialisable dict (the fit's rows left out)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "rows"}
        for key in ("J_kgm2_ci", "B_Nms_ci", "T_coulomb_Nm_ci"):
            out[key] = list(out[key])
        out["excluded_s"] = [list(w) for w in self.excluded_s]
        out["notes"] = list(self.notes)
        return out


def torque_from_currents(log: Log, pole_pairs: int, psi_f_Wb: float, Ld_H: float, Lq_H: float) -> np.ndarray:
    """Electromagnetic torque of eq 1, ``1.5 p (psi_f iq + (Ld - Lq) id iq)`` [Nm], from the logged currents."""
    if log.iq_A is None:
        raise ConfigError("log", log.source, "a log with iq_A (or torque_Nm) to compute the torque from")
    iq = log.iq_A
    id_ = log.id_A if log.id_A is not None else np.zeros_like(iq)
    torque: np.ndarray = 1.5 * pole_pairs * (psi_f_Wb * iq + (Ld_H - Lq_H) * id_ * iq)
    return torque


def _cumtrapz(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.zeros_like(x)
    out[1:] = np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))
    return out


def _block_means(x: np.ndarray, starts: np.ndarray, m: int) -> np.ndarray:
    c = np.concatenate(([0.0], np.cumsum(x)))
    means: np.ndarray = (c[starts + m] - c[starts]) / m
    return means


def _rows(t: np.ndarray, w: np.ndarray, T: np.ndarray, n: int, m: int, w_zero: float) -> dict[str, np.ndarray]:
    """Regression rows of one segment (see the module docstring)."""
    starts = np.arange(0, len(t) - n - m + 1, n)
    if starts.size == 0:
        return {k: np.empty(0) for k in ("y", "x_J", "x_B", "x_C", "t0", "t1", "samples")}
    sgn = np.sign(w)
    F = {name: _cumtrapz(t, x) for name, x in (("T", T), ("w", w), ("s", sgn))}
    a, b = starts, starts + n
    span = _block_means(t, b, m) - _block_means(t, a, m)
    rows = {
        "y": (_block_means(F["T"], b, m) - _block_means(F["T"], a, m)) / span,
        "x_J": (_block_means(w, b, m) - _block_means(w, a, m)) / span,
        "x_B": (_block_means(F["w"], b, m) - _block_means(F["w"], a, m)) / span,
        "x_C": (_block_means(F["s"], b, m) - _block_means(F["s"], a, m)) / span,
        "t0": t[a],
        "t1": t[b + m - 1],
    }
    # |w| over each row's samples a .. b + m - 1 stays above w_zero
    small = np.abs(w) <= w_zero
    c = np.concatenate(([0], np.cumsum(small)))
    keep = (c[b + m] - c[a]) == 0
    out = {k: v[keep] for k, v in rows.items()}
    out["samples"] = np.full(int(np.count_nonzero(keep)), n + m, dtype=float)
    return out


def _newey_west(X: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Newey-West covariance of the least-squares estimate (Bartlett weights)."""
    n = len(e)
    lags = max(2, math.ceil(4.0 * (n / 100.0) ** (2.0 / 9.0)))
    Xe = X * e[:, None]
    S = Xe.T @ Xe
    for lag in range(1, min(lags, n - 1) + 1):
        G = Xe[lag:].T @ Xe[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    inv = np.linalg.inv(X.T @ X)
    cov: np.ndarray = inv @ S @ inv * n / (n - X.shape[1])
    return cov


def _merge(windows: list[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    merged: list[list[float]] = []
    for t0, t1 in sorted(windows):
        if merged and t0 <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], t1)
        else:
            merged.append([t0, t1])
    return tuple((a, b) for a, b in merged)


def _constant_runs(residual: np.ndarray, excluded: np.ndarray, t0: np.ndarray) -> list[tuple[float, float, float]]:
    """The runs of excluded rows that an unannounced load explains: ``(start, end, load)`` [s, s, Nm].

    A load torque T_L adds ``+T_L`` to the residual of every row it covers whole (the rows average
    ``J dw/dt + B w + Tc sign(w) + T_L``): a run of consecutive excluded rows with at least
    :data:`LOAD_ROWS_MIN` residuals of one sign within :data:`LOAD_SPREAD` of their median is one,
    of about that median. Transients the rows do not resolve give residuals that change in size or
    sign instead.
    """
    runs: list[tuple[float, float, float]] = []
    idx = np.flatnonzero(excluded)
    if idx.size == 0:
        return runs
    # consecutive rows of one segment: neighbouring indices whose start times increase by one stride
    breaks = np.flatnonzero((np.diff(idx) != 1) | (np.diff(t0[idx]) <= 0)) + 1
    for run in np.split(idx, breaks):
        r = residual[run]
        median = float(np.median(r))
        near = np.abs(r - median) <= LOAD_SPREAD * abs(median)
        if np.count_nonzero(near) >= LOAD_ROWS_MIN and (np.all(r[near] > 0) or np.all(r[near] < 0)):
            runs.append((float(t0[run[0]]), float(t0[run[-1]]), median))
    return runs


def identify_mechanics(
    log: Log,
    torque_Nm: np.ndarray | None = None,
    window_s: float | None = None,
    speed_is_period_mean: bool = False,
) -> Mechanics:
    """Identify J, B and the Coulomb friction from the speed and torque of a log.

    Parameters
    ----------
    log : Log
        A measured (or simulated) run: ``t_s``, ``w_m_radps`` and, unless ``torque_Nm`` is given,
        ``torque_Nm``.
    torque_Nm : array, optional
        The electromagnetic torque per log row [Nm], e.g. :func:`torque_from_currents`.
    speed_is_period_mean : bool
        The logged speed is the mean over the sampling period that ends at its row (encoder
        counts differenced over the period): it lags the torque samples by half a period, so the
        torque is taken as the mean of its row and the row before (the trapezoid over that period).
    window_s : float, optional
        Distance of the two blocks of a row [s] (blocks of half of it); default: the shortest
        of 8, 16, 32, ... samples whose block means carry a speed noise variance below
        :data:`NOISE_SHARE_MAX` of the mean square speed change of a row, within 1.5 windows per
        8th of the longest segment and :data:`ROWS_AUTO` windows in the log.

    Returns
    -------
    Mechanics

    Raises
    ------
    IdentificationError
        Too few usable rows, or J not determined (too little acceleration): the message says
        what experiment would determine it.
    ConfigError
        No torque, a torque array of the wrong length, or a bad ``window_s``.
    """
    T = log.torque_Nm if torque_Nm is None else np.asarray(torque_Nm, dtype=float)
    if T is None:
        raise ConfigError(
            "torque", "<missing>", "a torque_Nm column, or the currents with the motor data (--motor or --psi-f-Wb ...)"
        )
    if T.shape != log.t_s.shape or not np.all(np.isfinite(T)):
        raise ConfigError("torque_Nm", f"{T.shape} values", f"{log.t_s.shape[0]} finite values, one per log row")
    dt = log.dt_s
    segments = log.segments()
    if speed_is_period_mean:
        T = T.copy()
        for s in segments:
            T[s.start + 1 : s.stop] = 0.5 * (T[s.start + 1 : s.stop] + T[s.start : s.stop - 1])
    longest = max(s.stop - s.start for s in segments)
    w = log.w_m_radps
    # speed noise, from the second difference (a smooth speed has almost none): var(d2) = 6 var(noise)
    d2 = np.concatenate([np.diff(w[s], 2) for s in segments if s.stop - s.start > 2])
    sigma_w = float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0)) if d2.size else 0.0
    w_zero = max(4.0 * sigma_w, 0.01 * float(np.max(np.abs(w))))
    if window_s is not None:
        if not (isinstance(window_s, (int, float)) and math.isfinite(window_s) and window_s >= 2 * dt):
            raise ConfigError("window_s", window_s, f"a time >= 2 log steps ({2 * dt:.4g} s)")
        candidates = [max(2, round(window_s / dt))]
    else:
        total = sum(s.stop - s.start for s in segments)
        candidates = [2**k for k in range(3, 40) if 2**k * 1.5 <= longest / 8 and 2**k * ROWS_AUTO <= total]
        candidates = candidates or [max(2, min(longest // 12, total // ROWS_AUTO))]
    rows: dict[str, np.ndarray] = {}
    n = candidates[0]
    for n in candidates:
        m = max(1, n // 2)
        parts = [_rows(log.t_s[s], w[s], T[s], n, m, w_zero) for s in segments]
        rows = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        if rows["y"].size < ROWS_MIN:
            break
        spread = float(np.mean(rows["x_J"] ** 2)) * (n * dt) ** 2
        if spread > 0 and 2.0 * sigma_w**2 / m <= NOISE_SHARE_MAX * spread:
            break
    if rows["y"].size < ROWS_MIN:
        raise IdentificationError(
            f"{log.source}: only {rows['y'].size} usable rows of {n * dt:.3g} s (at least {ROWS_MIN}) with the speed "
            f"away from zero (|w| > {w_zero:.3g} rad/s): log a longer run with speed steps or torque pulses "
            "(pmsm2dof identify plan)"
        )
    X = np.column_stack([rows["x_J"], rows["x_B"], rows["x_C"]])
    y = rows["y"]
    theta0, *_ = np.linalg.lstsq(X, y, rcond=None)
    r0 = y - X @ theta0
    scale = 1.4826 * float(np.median(np.abs(r0 - np.median(r0)))) or float(np.std(r0)) or 1.0
    fit = scipy.optimize.least_squares(lambda th: X @ th - y, theta0, loss="huber", f_scale=1.345 * scale)
    r = y - X @ fit.x
    s_robust = 1.4826 * float(np.median(np.abs(r)))
    keep = np.abs(r) <= OUTLIER_SIGMAS * s_robust if s_robust > 0 else np.ones(r.size, bool)
    Xk, yk = X[keep], y[keep]
    if yk.size < ROWS_MIN:
        raise IdentificationError(f"{log.source}: only {yk.size} rows fit one model (at least {ROWS_MIN})")
    theta, *_ = np.linalg.lstsq(Xk, yk, rcond=None)
    e = yk - Xk @ theta
    cov = _newey_west(Xk, e)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    q = float(scipy.stats.t.ppf(0.5 + LEVEL / 2, yk.size - 3))
    J, B, Tc = (float(v) for v in theta)
    notes = list(log.notes)
    if not (J > 0 and sd[0] <= J_REL_SD_MAX * J):
        accel = float(np.max(np.abs(rows["x_J"])))
        raise IdentificationError(
            f"{log.source}: J is not identifiable from this log (J = {J:.4g} +- {sd[0]:.2g} kg m^2; the largest "
            f"mean acceleration over {n * dt:.3g} s is {accel:.3g} rad/s^2, too little against the torque noise): "
            "log speed steps or torque pulses that accelerate the drive near its current limit, in both directions "
            "(pmsm2dof identify plan writes such a run)"
        )
    excluded = _merge([(float(a), float(b)) for a, b in zip(rows["t0"][~keep], rows["t1"][~keep])])
    if excluded:
        where = ", ".join(f"{a:.4g}-{b:.4g} s" for a, b in excluded[:5]) + (" ..." if len(excluded) > 5 else "")
        loads = _constant_runs(r, ~keep, rows["t0"])
        if loads:
            found = "; ".join(f"about {load:.3g} Nm in {a:.4g}-{b:.4g} s" for a, b, load in loads[:3])
            notes.append(
                f"{int(np.count_nonzero(~keep))} rows excluded as outliers in {where}: an unannounced load, {found}"
            )
        else:
            notes.append(
                f"{int(np.count_nonzero(~keep))} rows excluded as outliers in {where}: their residuals change in size "
                "or sign from row to row, a transient the model or the log's sampling does not follow, not a load"
            )
    for name, value, s in (("B", B, sd[1]), ("Coulomb friction", Tc, sd[2])):
        if abs(value) < 2 * s:
            notes.append(f"{name} is not distinguished from zero ({value:.3g} +- {q * s:.2g})")
    if np.all(rows["x_C"] > 0) or np.all(rows["x_C"] < 0):
        notes.append(
            "the speed keeps one sign: a constant load torque is counted in the Coulomb friction "
            "(run both directions to separate them)"
        )
    return Mechanics(
        J_kgm2=J,
        B_Nms=B,
        T_coulomb_Nm=Tc,
        J_kgm2_ci=(J - q * sd[0], J + q * sd[0]),
        B_Nms_ci=(B - q * sd[1], B + q * sd[1]),
        T_coulomb_Nm_ci=(Tc - q * sd[2], Tc + q * sd[2]),
        residual_rms_Nm=float(np.sqrt(np.mean(e**2))),
        n_samples=int(np.sum(rows["samples"][keep])),
        n_rows=int(yk.size),
        n_rows_excluded=int(np.count_nonzero(~keep)),
        excluded_s=excluded,
        window_s=n * dt,
        notes=tuple(notes),
        rows={"t_s": 0.5 * (rows["t0"] + rows["t1"]), "y": y, "fit": X @ theta, "kept": keep},
    )


@dataclasses.dataclass(frozen=True)
class CurrentLoop:
    """The time constant of the closed current loop (eq 3) identified from a log.

    Attributes
    ----------
    tau_i_s : float
        Time constant [s].
    tau_i_s_ci : tuple of float
        Its 95 % interval [s].
    n_rows : int
        Log steps used.
    """

    tau_i_s: float
    tau_i_s_ci: tuple[float, float]
    n_rows: int

    def to_json(self) -> dict[str, Any]:
        return {"tau_i_s": self.tau_i_s, "tau_i_s_ci": list(self.tau_i_s_ci), "n_rows": self.n_rows}


def identify_tau_i(log: Log) -> CurrentLoop:
    """Identify tau_i of eq 3, ``tau_i diq/dt = iq_ref - iq``, from the logged iq and iq_ref.

    Each log step ``k -> k + 1`` with the command held at ``iq_ref[k]`` (the speed controller's
    output of row k, applied until the next row) obeys, for eq 3 exactly,
    ``iq[k+1] - iq_ref[k] = exp(-dt_k / tau_i) (iq[k] - iq_ref[k])``; tau_i is the least-squares
    fit of that relation over the steps where the command is away from the current (the steps
    after a change of iq_ref), with a Newey-West interval as :func:`identify_mechanics`.

    Raises
    ------
    ConfigError
        The log has no ``iq_ref_A`` or ``iq_A``.
    IdentificationError
        Too few steps where iq_ref moves away from iq, or a time constant the log's sampling does
        not resolve (below a tenth of a step: log faster, or log the current loop's own samples).
    """
    if log.iq_A is None or log.iq_ref_A is None:
        raise ConfigError("log", log.source, "a log with iq_A and iq_ref_A to identify tau_i from")
    parts = []
    for s in log.segments():
        t, iq, ref = log.t_s[s], log.iq_A[s], log.iq_ref_A[s]
        parts.append((np.diff(t), iq[:-1] - ref[:-1], iq[1:] - ref[:-1]))
    dt, x, y = (np.concatenate(p) for p in zip(*parts))
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    use = np.abs(x) > 0.05 * scale
    dt, x, y = dt[use], x[use], y[use]
    if x.size < ROWS_MIN:
        raise IdentificationError(
            f"{log.source}: only {x.size} log steps with iq_ref away from iq (at least {ROWS_MIN}): "
            "log a run with iq steps (torque pulses or speed steps)"
        )
    # a = y / x per step, exp(-dt / tau): fit the ratio's log-linear model
    ratio = float(np.sum(x * y) / np.sum(x * x))
    dt_med = float(np.median(dt))
    if not 0.0 < ratio < 1.0 or ratio < math.exp(-10.0):
        raise IdentificationError(
            f"{log.source}: tau_i is not resolved by the log's sampling ({dt_med:.3g} s; iq follows iq_ref within "
            "one step): log the current loop at its own rate"
        )
    tau0 = -dt_med / math.log(ratio)

    def residual(p: np.ndarray) -> np.ndarray:
        r: np.ndarray = y - np.exp(-dt / p[0]) * x
        return r

    fit = scipy.optimize.least_squares(residual, [tau0], x_scale=[tau0], bounds=([tau0 * 1e-3], [tau0 * 1e3]))
    jac = fit.jac
    cov = _newey_west(jac, fit.fun)
    sd = math.sqrt(max(float(cov[0, 0]), 0.0)) * math.sqrt((x.size - 3) / (x.size - 1))
    q = float(scipy.stats.t.ppf(0.5 + LEVEL / 2, x.size - 1))
    tau = float(fit.x[0])
    return CurrentLoop(tau_i_s=tau, tau_i_s_ci=(tau - q * sd, tau + q * sd), n_rows=int(x.size))


#: Speed levels of a plan, as fractions of the largest speed: both directions, several speeds
#: (B against the Coulomb friction), large changes (J).
PLAN_LEVELS = (1.0, -0.8, 0.6, -1.0, 0.3)

#: A plan's largest speed keeps the voltage of eq 1 at the current limit within this share of u_dc / sqrt(3).
PLAN_VOLTAGE_SHARE = 0.9


def identified_toml(mech: Mechanics, current: CurrentLoop | None, scenario: Scenario | None, source: str) -> str:
    """The values identified from a log as a TOML file for the next commands (simulate, design --motor).

    With the drive's ``scenario``: the scenario with them, its speed controller designed for the J
    found (eq 9); without one, a ``[motor]`` table (and ``[current_loop]`` with tau_i), headed by
    ``source``. Friction coefficients below zero (a fit within its noise) are written as zero.
    """
    values = {"motor.J_kgm2": mech.J_kgm2, "motor.B_Nms": max(mech.B_Nms, 0.0)}
    values["motor.T_coulomb_Nm"] = max(mech.T_coulomb_Nm, 0.0)
    if current is not None:
        values["current_loop.tau_i_s"] = current.tau_i_s
    if scenario is not None:
        return scenario.with_overrides({**values, "speed_controller.J_kgm2": mech.J_kgm2}).to_toml()
    lines = [f"# identified from {source}", "[motor]"]
    lines += [f"{k.split('.')[1]} = {v!r}" for k, v in values.items() if k.startswith("motor.")]
    if current is not None:
        lines += ["", "[current_loop]", f"tau_i_s = {current.tau_i_s!r}"]
    return "\n".join(lines) + "\n"


class PlanWarning(Pmsm2dofWarning):
    """The plan departs from what was asked (its speeds lowered to stay inside the voltage limit)."""


def plan_experiment(scenario: Scenario, speed_max_rpm: float, i_max_A: float | None = None) -> Scenario:
    """A run that identifies the mechanics: speed steps within the limits, as a scenario to simulate and to play.

    The reference visits ``PLAN_LEVELS`` times ``speed_max_rpm`` (both directions, five speeds,
    changes of up to twice the largest speed: J from the accelerations at the current limit, B and
    the Coulomb friction from the steady speeds). Each level is held for ``2 t_acc + 8 / alpha``:
    ``t_acc = J |dw| / T_max`` is the time of the change at the torque of the current limit for the
    inertia the controller is designed for (the guess), ``8 / alpha`` lets the speed loop settle.
    The load schedule is removed (a load the drive has stays in the log and is found by the fit).

    The plan stays inside the voltage limit, where the current follows its command and the torque
    is the current limit's: when the steady-state voltage of eq 1 at the current limit would exceed
    :data:`PLAN_VOLTAGE_SHARE` of ``u_dc / sqrt(3)`` at ``speed_max_rpm``
    (:func:`pmsm2dof.sim.plausibility.voltage_limited_speed_radps`), the largest speed is lowered
    to where it does not, with a :class:`PlanWarning`.

    Parameters
    ----------
    scenario : Scenario
        The drive with the present guess of J (``speed_controller.J_kgm2``).
    speed_max_rpm : float
        Largest speed of the plan [rpm], > 0.
    i_max_A : float, optional
        Current limit for the experiment [A], > 0 (default: ``limits.i_max_A``).

    Returns
    -------
    Scenario
        With the reference schedule, no load, ``simulation.t_end_s`` one hold after the last step.
    """
    if isinstance(speed_max_rpm, bool) or not (isinstance(speed_max_rpm, (int, float)) and speed_max_rpm > 0):
        raise ConfigError("speed_max_rpm", speed_max_rpm, "a finite number > 0 [rpm]")
    if not math.isfinite(speed_max_rpm):
        raise ConfigError("speed_max_rpm", speed_max_rpm, "a finite number > 0 [rpm]")
    if i_max_A is not None:
        scenario = scenario.with_overrides({"limits.i_max_A": i_max_A})
    motor, sc, limits = scenario.motor, scenario.speed_controller, scenario.limits
    T_max_Nm = 1.5 * motor.pole_pairs * motor.psi_f_Wb * limits.i_max_A
    u_plan_V = PLAN_VOLTAGE_SHARE * limits.u_dc_V / math.sqrt(3.0)
    w_voltage_rpm = voltage_limited_speed_radps(u_plan_V, limits.i_max_A, motor) * 30.0 / math.pi
    if speed_max_rpm > w_voltage_rpm:
        warnings.warn(
            f"the plan's largest speed is {w_voltage_rpm:.5g} rpm, not speed_max_rpm = {speed_max_rpm:g} rpm: above "
            f"it the voltage of eq 1 at the current limit {limits.i_max_A:g} A exceeds {PLAN_VOLTAGE_SHARE:g} "
            f"u_dc / sqrt(3) = {u_plan_V:.4g} V, the current no longer follows its command and the acceleration "
            "is not the current limit's",
            PlanWarning,
            stacklevel=2,
        )
        speed_max_rpm = w_voltage_rpm
    levels = [level * speed_max_rpm for level in PLAN_LEVELS]
    t, previous, reference = 0.05, 0.0, []
    for rpm in levels:
        reference.append({"t_s": round(t, 6), "speed_rpm": rpm})
        t_acc = sc.J_kgm2 * abs(rpm - previous) * math.pi / 30.0 / T_max_Nm
        t += 2.0 * t_acc + 8.0 / sc.alpha_radps
        previous = rpm
    return scenario.with_overrides(
        {
            "name": f"{scenario.name}: identification plan",
            "description": f"speed steps within +-{speed_max_rpm:g} rpm for pmsm2dof identify mechanics",
            "reference": reference,
            "load": [],
            "fault": [],
            "simulation.t_end_s": round(t, 6),
            "simulation.speed0_rpm": 0.0,
        }
    )
