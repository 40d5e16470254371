"""Identification of the machine from a logged run: Rs, Ld, Lq and psi_f (eq 1).

Model: the dq voltage equations of eq 1 (per phase, amplitude-invariant dq), with the electrical
speed ``w_e = p w_m``::

    ud = Rs id + Ld did/dt - w_e Lq iq
    uq = Rs iq + Lq diq/dt + w_e (Ld id + psi_f)

Integral form: integrated between two instants ``a`` and ``b`` the derivatives become current
differences, so no current is differenced over one sample (whose noise would bias L towards
zero)::

    int ud = Rs int id + Ld (id(b) - id(a)) - Lq int w_e iq
    int uq = Rs int iq + Lq (iq(b) - iq(a)) + Ld int w_e id + psi_f int w_e

As in the mechanical fit (:mod:`pmsm2dof.studies.identify`), each regression row averages this
relation over the ``M`` instants ``a + j`` and ``b + j`` of two blocks ``N`` samples apart, so
the current noise in the differences shrinks by ``sqrt(M)`` (the errors-in-variables bias of Ld
and Lq stays small). The voltage is held over the sample period that starts at its time (a
zero-order hold: its running integral is a sum of rectangles); a log that records the voltage
computed at a sample and applied ``d`` periods later (``voltage_delay_samples``) is shifted by
``d`` samples first. Currents and speed are integrated by trapezoids.

Fit: the d and q rows of all windows together, by instrumental variables: the logged currents'
noise enters the regressors (errors in variables: least squares would be biased by it, and its
intervals would miss the truth), so the regressors are built from the even samples' currents (the
odd ones replaced by the mean of their neighbours) and the instruments from the odd samples',
whose noise is independent of the regressors' (J. Durbin, "Errors in variables", Rev. Int.
Statistical Institute 22, 1954: instruments from a second, independent measurement). Intervals: 95 % intervals from
the Newey-West covariance (Newey and West, Econometrica 55(3), 1987) of the per-window scores
(the d and q rows of one window share their noise, neighbouring windows share a block), so
that correlated residuals do not give intervals too narrow.

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

#: The identified parameters, in the order of the regressors.
PARAMETERS = ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")

#: A parameter is reported when its standard deviation is below this share of its value.
REL_SD_MAX = 0.05

#: Fewest windows of a fit.
WINDOWS_MIN = 12

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
    ci : dict
        Parameter -> its 95 % interval.
    residual_rms_V : float
        Rms residual of the rows (window-mean voltages) [V].
    n_samples : int
        Log samples the windows span.
    n_windows : int
        Windows (each gives a d and a q row).
    rows : dict
        Per row ``t_s``, measured and model window-mean voltages ``ud_V``, ``ud_fit_V``, ``uq_V``, ``uq_fit_V``.
    """

    Rs_ohm: float
    Ld_H: float
    Lq_H: float
    psi_f_Wb: float
    ci: dict[str, tuple[float, float]]
    residual_rms_V: float
    n_samples: int
    n_windows: int
    rows: dict[str, np.ndarray]

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name in PARAMETERS:
            out[name] = getattr(self, name)
            out[f"{name}_ci"] = list(self.ci[name])
        out.update(residual_V=self.residual_rms_V, n_samples=self.n_samples, n_windows=self.n_windows)
        return out

    def motor_toml(self, pole_pairs: int, source: str) -> str:
        """The identified motor as a ``[motor]`` table for ``pmsm2dof design --motor`` (as ``commission --out``)."""
        lines = [
            f"# identified from {source} by pmsm2dof identify --electrical",
            "# per phase, amplitude-invariant dq (eq 1)",
        ]
        lines += ["[motor]", f"pole_pairs = {pole_pairs}"]
        lines += [f"{name} = {getattr(self, name)!r}" for name in PARAMETERS]
        lines += [f"{name}_ci = [{lo!r}, {hi!r}]" for name, (lo, hi) in self.ci.items()]
        return "\n".join(lines) + "\n"


def _window_rows(
    t: np.ndarray, i_d: np.ndarray, i_q: np.ndarray, u_d: np.ndarray, u_q: np.ndarray, w_e: np.ndarray, n: int, m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Regressors and window-mean voltages of one segment: (X_d, y_d, X_q, y_q, t0)."""
    starts = np.arange(0, len(t) - n - m + 1, n)
    dt = np.diff(t)
    # zero-order hold: u[k] applies over [t[k], t[k+1])
    F_ud = np.concatenate(([0.0], np.cumsum(u_d[:-1] * dt)))
    F_uq = np.concatenate(([0.0], np.cumsum(u_q[:-1] * dt)))
    F = {
        "id": _cumtrapz(t, i_d),
        "iq": _cumtrapz(t, i_q),
        "wid": _cumtrapz(t, w_e * i_d),
        "wiq": _cumtrapz(t, w_e * i_q),
        "w": _cumtrapz(t, w_e),
    }
    a, b = starts, starts + n

    def diff(x: np.ndarray) -> np.ndarray:
        out: np.ndarray = _block_means(x, b, m) - _block_means(x, a, m)
        return out

    span = diff(t)
    zero = np.zeros_like(span)
    X_d = np.column_stack([diff(F["id"]), diff(i_d), -diff(F["wiq"]), zero]) / span[:, None]
    X_q = np.column_stack([diff(F["iq"]), diff(F["wid"]), diff(i_q), diff(F["w"])]) / span[:, None]
    return X_d, diff(F_ud) / span, X_q, diff(F_uq) / span, t[a]


def _keep(x: np.ndarray, parity: int) -> np.ndarray:
    """The samples of one parity, the others replaced by the mean of their two neighbours (of that parity)."""
    out = x.copy()
    other = np.arange(1 - parity, len(x), 2)
    inner = other[(other > 0) & (other < len(x) - 1)]
    out[inner] = 0.5 * (x[inner - 1] + x[inner + 1])
    edge = other[(other == 0) | (other == len(x) - 1)]
    out[edge] = x[np.where(edge == 0, 1, len(x) - 2)]
    return out


def identify_electrical(
    log: Log, pole_pairs: int, voltage_delay_samples: int = 0, window_samples: int | None = None
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
    n_total = len(log.t_s)
    if window_samples is None:
        window_samples = max(8, n_total // 960)
    if window_samples < 2:
        raise ConfigError("window_samples", window_samples, "an integer >= 2")
    n, m = window_samples, max(1, window_samples // 2)
    d = voltage_delay_samples
    assert log.id_A is not None and log.iq_A is not None and log.ud_V is not None and log.uq_V is not None
    blocks: list[tuple[np.ndarray, ...]] = []
    n_used = 0
    for seg in log.segments():
        idx = np.arange(seg.start, seg.stop)
        if idx.size <= d + n + m:
            continue
        # the voltage applied over the period that starts at row k was logged at row k - d
        rows_u = idx[: idx.size - d]
        rows_x = idx[d:]
        n_used += rows_x.size
        t = log.t_s[rows_x]
        w_e = pole_pairs * log.w_m_radps[rows_x]
        i_d, i_q = log.id_A[rows_x], log.iq_A[rows_x]
        u_d, u_q = log.ud_V[rows_u], log.uq_V[rows_u]
        # split-sample instruments: regressors from the even samples' currents, instruments from the odd ones'
        even = _window_rows(t, _keep(i_d, 0), _keep(i_q, 0), u_d, u_q, w_e, n, m)
        odd = _window_rows(t, _keep(i_d, 1), _keep(i_q, 1), u_d, u_q, w_e, n, m)
        blocks.append((*even, odd[0], odd[2]))
    if not blocks:
        raise IdentificationError(f"the log is too short for windows of {n + m} samples ({n_total} rows)")
    X_d, y_d, X_q, y_q, t0, Z_d, Z_q = (np.concatenate([blk[i] for blk in blocks]) for i in range(7))
    k = len(y_d)
    if k < WINDOWS_MIN:
        raise IdentificationError(f"{k} windows of {n + m} samples, at least {WINDOWS_MIN} needed: a longer log")
    X = np.vstack([X_d, X_q])
    y = np.concatenate([y_d, y_q])
    # column scales: the rank test does not depend on units
    scale = np.sqrt(np.sum(X**2, axis=0))
    scale[scale == 0] = 1.0
    Z = np.vstack([Z_d, Z_q])
    ZX = Z.T @ X
    theta = np.linalg.lstsq(ZX, Z.T @ y, rcond=None)[0]
    e = y - X @ theta
    # Newey-West over the windows: the score of a window is its d row's plus its q row's
    scores = Z_d * e[:k, None] + Z_q * e[k:, None]
    lags = max(2, math.ceil(4.0 * (k / 100.0) ** (2.0 / 9.0)))
    S = scores.T @ scores
    for lag in range(1, min(lags, k - 1) + 1):
        G = scores[lag:].T @ scores[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    _, singular, vt = np.linalg.svd(X / scale, full_matrices=False)
    if singular[-1] <= 1e-9 * singular[0]:
        # the direction the log does not excite: its largest component is the parameter to blame
        sd = np.zeros(4)
        sd[int(np.argmax(np.abs(vt[-1])))] = np.inf
    else:
        inv = np.linalg.inv(ZX)
        cov = inv @ S @ inv.T * (2 * k) / (2 * k - 4)
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    for name, value, s in zip(PARAMETERS, theta, sd, strict=True):
        if not (np.isfinite(s) and s < REL_SD_MAX * abs(value)):
            spread = {"Ld_H": ("id", log.id_A), "Lq_H": ("iq", log.iq_A)}
            moved = ""
            if name in spread:
                sig, x = spread[name]
                moved = f" ({sig} spans {np.ptp(x):.3g} A)"
            raise IdentificationError(
                f"{name} is not identifiable from this log{moved}: estimate {value:.4g}, standard deviation "
                f"{s:.3g}; it needs a log where {_NEEDS[name]}"
            )
    q = float(scipy.stats.t.ppf(0.5 + LEVEL / 2.0, 2 * k - 4))
    ci = {name: (float(v - q * s), float(v + q * s)) for name, v, s in zip(PARAMETERS, theta, sd, strict=True)}
    rows = {"t_s": t0, "ud_V": y_d, "ud_fit_V": X_d @ theta, "uq_V": y_q, "uq_fit_V": X_q @ theta}
    return Electrical(
        Rs_ohm=float(theta[0]),
        Ld_H=float(theta[1]),
        Lq_H=float(theta[2]),
        psi_f_Wb=float(theta[3]),
        ci=ci,
        residual_rms_V=float(np.sqrt(np.mean(e**2))),
        n_samples=n_used,
        n_windows=k,
        rows=rows,
    )
