"""Step-response figures of a stable linear loop at any time scale.

The overshoot of a designed loop must be computable for a sampling period a million times
shorter than its slowest time constant (alpha Ts = 1e-6) and for a loop whose poles are decades
apart (zeta >> 1). A simulation of fixed length does neither, and the poles of a transfer
function multiplied out in z do not survive rounding there: near z = 1 the coefficients of a
product of polynomials lose the roots' distance to 1 (a stable loop shows a pole at 1.00005).

The loop is therefore kept as the increment of one step,
``x[k+1] = x[k] + E x[k] + f`` (``E = A - I`` never rounded against the identity, ``f`` the
increment of a unit step input), with output ``y[k] = c x[k]`` and initial state ``x0``:

- the map ``T: x -> x + E x + f`` is composed with itself in that form
  (``T_a T_b: E = E_a + E_b + E_a E_b``), so the state at any sample ``k`` costs O(log k)
  products and loses nothing to the identity;
- the response is evaluated on a grid that follows its modes: with ``nu_i = log(1 + eig(E)_i)``
  per step, the grid advances at most :data:`THETA` radians or nepers of every mode that is
  still alive (above ``exp(-DECAY)`` of its amplitude): one sample at a time while fast modes
  last, far apart once only slow ones remain;
- the largest grid values are refined over the samples between their grid neighbours (over
  continuous time for a continuous loop).

A continuous loop ``x' = A x + b`` is handled as the same map over a step ``dt_s``, sampled
exactly: ``E = A Gamma(dt)``, ``f = Gamma(dt) b``, ``Gamma(t) = int_0^t exp(A s) ds``
(SciPy ``expm`` of the block matrix ``[[A, I], [0, 0]] t``).
"""

import bisect
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

#: Largest advance of any live mode between two grid points [rad or neper].
THETA = 0.05
#: A mode is followed until it has decayed by this many nepers (exp(-40) = 4e-18).
DECAY = 40.0
#: Samples always evaluated one by one from the start.
DENSE = 64
#: Most grid points one response may take; beyond, the overshoot is reported missing.
MAX_POINTS = 2_000_000
#: Relative overshoot below which the peak is the final value seen through rounding.
ROUNDING = 1e-11
_CHUNK = 1 << 15

_Vector = npt.NDArray[np.float64]
_Matrix = npt.NDArray[np.float64]
#: A map ``x -> x + E x + f`` as its ``(E, f)``.
_Map = tuple[_Matrix, _Vector]
#: Samples ``start, start + h, ... < stop`` of the grid.
_Segment = tuple[int, int, int]


def _compose(t1: _Map, t2: _Map) -> _Map:
    """The map ``t1(t2(x))`` of two maps ``x -> x + E x + f`` given as ``(E, f)``."""
    E1, f1 = t1
    E2, f2 = t2
    return E1 + E2 + E1 @ E2, f1 + f2 + E1 @ f2


def _power(t: _Map, k: int) -> _Map:
    """``t`` applied ``k`` times (k >= 0, a Python int of any size)."""
    n = len(t[1])
    result: _Map = (np.zeros((n, n)), np.zeros(n))
    while k:
        if k & 1:
            result = _compose(t, result)
        k >>= 1
        if k:
            t = _compose(t, t)
    return result


def _apply(t: _Map, X: _Matrix) -> _Matrix:
    """``t`` applied to the columns of ``X``."""
    E, f = t
    return X + E @ X + f[:, None]


def _orbit(t: _Map, x: _Vector, n: int) -> _Matrix:
    """Columns ``t^j(x)``, j = 0 .. n - 1, by doubling."""
    X = x[:, None]
    while X.shape[1] < n:
        X = np.hstack([X, _apply(t, X)])
        t = _compose(t, t)
    return X[:, :n]


def _log1p(e: npt.ArrayLike) -> npt.NDArray[np.complex128]:
    """``log(1 + e)`` of complex ``e`` without the rounding of ``1 + e``."""
    z = np.asarray(e, dtype=complex)
    real = 0.5 * np.log1p(2.0 * z.real + np.abs(z) ** 2)
    log: npt.NDArray[np.complex128] = real + 1j * np.arctan2(z.imag, 1.0 + z.real)
    return log


def _gamma(A: _Matrix, t: float) -> _Matrix:
    """``int_0^t exp(A s) ds`` (SciPy ``expm`` of ``[[A, I], [0, 0]] t``)."""
    n = A.shape[0]
    block = np.zeros((2 * n, 2 * n))
    block[:n, :n] = A * t
    block[:n, n:] = np.eye(n) * t
    import scipy.linalg  # loaded here: a stability check alone never needs it

    exp_block: _Matrix = scipy.linalg.expm(block)
    return exp_block[:n, n:]


class StepResponse:
    """The response ``y[k] = c x[k]`` of ``x[k+1] = x[k] + E x[k] + f`` from ``x[0] = x0``.

    Parameters
    ----------
    E : (n, n) array
        Increment matrix of one step, ``A_d - I``.
    f : (n,) array
        Increment of one step due to the unit step input.
    c : (n,) array
        Output row.
    x0 : (n,) array, optional
        State at k = 0 (zero by default).
    dt_s : float, optional
        Duration of one step [s].
    """

    def __init__(
        self, E: npt.ArrayLike, f: npt.ArrayLike, c: npt.ArrayLike, x0: npt.ArrayLike | None = None, dt_s: float = 1.0
    ) -> None:
        self.step = (np.asarray(E, dtype=float), np.asarray(f, dtype=float))
        self.c = np.asarray(c, dtype=float)
        self.x0 = np.zeros(len(self.c)) if x0 is None else np.asarray(x0, dtype=float)
        self.dt_s = float(dt_s)
        # the continuous loop x' = A x + b that the steps sample, if any (:meth:`continuous`)
        self._A: _Matrix | None = None
        self._b: _Vector | None = None

    @classmethod
    def continuous(
        cls, A: npt.ArrayLike, b: npt.ArrayLike, c: npt.ArrayLike, x0: npt.ArrayLike | None = None
    ) -> "StepResponse":
        """The loop ``x' = A x + b`` (unit step input), ``y = c x``, sampled exactly.

        The step is :data:`THETA` over the fastest rate of ``A``; :meth:`overshoot_pct` then
        refines the peak over continuous time.
        """
        A_ = np.asarray(A, dtype=float)
        fastest = float(np.max(np.abs(np.linalg.eigvals(A_)))) if A_.size else 0.0
        dt_s = THETA / fastest if fastest > 0.0 else 1.0
        G = _gamma(A_, dt_s)
        response = cls(A_ @ G, G @ np.asarray(b, dtype=float), c, x0, dt_s)
        response._A, response._b = A_, np.asarray(b, dtype=float)
        return response

    def rates(self) -> npt.NDArray[np.complex128]:
        """Complex rate of each mode per step, ``log(1 + eig(E))`` (``-inf`` for a pole at z = 0)."""
        with np.errstate(divide="ignore"):
            return _log1p(np.linalg.eigvals(self.step[0]))

    def output(self, k: int) -> float:
        """``y[k]``, k a Python int >= 0."""
        E, f = _power(self.step, k)
        return float(self.c @ (self.x0 + E @ self.x0 + f))

    def _grid(self, nu: npt.NDArray[np.complex128]) -> list[_Segment]:
        """Segments ``(start, stop, h)``: samples start, start + h, ... < stop cover the response."""
        sigma = -nu.real
        with np.errstate(divide="ignore", invalid="ignore"):
            life = np.where(sigma > 0.0, DECAY / sigma, math.inf)
        speed = np.abs(nu)
        order = np.argsort(life)
        segments = [(0, DENSE, 1)]
        start = DENSE
        for j, i in enumerate(order):
            stop = math.ceil(life[i]) + 1
            if stop <= start:
                continue
            fastest = float(np.max(speed[order[j:]]))
            h = max(1, math.floor(THETA / fastest))
            segments.append((start, stop, h))
            start = stop
        return segments

    def overshoot_pct(self) -> tuple[float, str]:
        """Overshoot [%] of the step response over its final value, or NaN and the reason.

        Returns
        -------
        (float, str)
            ``100 max(0, (max y - y_end) / (y_end - y[0]))`` and ``""``, or ``nan`` and the
            reason it cannot be computed.
        """
        nu = self.rates()
        if np.any(nu.real >= 0.0):
            worst = nu[np.argmax(nu.real)] / self.dt_s
            return math.nan, (
                f"the loop is not stable (a mode grows or stays at the rate {complex(worst):.4g} "
                "1/s), so its step response has no final value"
            )
        segments = self._grid(nu)
        points: int = sum(-(-(stop - start) // h) for start, stop, h in segments)
        if points > MAX_POINTS:
            slowest = float(np.min(-nu.real)) / self.dt_s
            return math.nan, (
                f"the step response needs {points:.3g} evaluations (> {MAX_POINTS:g}) to follow "
                f"its modes, from lightly damped ones to the slowest ({slowest:.3g} 1/s)"
            )
        k_of, y = self._evaluate(segments)
        y0, y_end = float(self.c @ self.x0), float(y[-1])
        step = y_end - y0
        if not step > 0.0:
            return math.nan, "the step response does not rise from its initial value"
        if (y.max() - y_end) / step <= ROUNDING:
            return 0.0, ""
        # local maxima of the grid, those that may be the peak refined between their grid neighbours
        is_max = np.ones(len(y), dtype=bool)
        is_max[1:] &= y[1:] >= y[:-1]
        is_max[:-1] &= y[:-1] >= y[1:]
        index = np.flatnonzero(is_max)
        index = index[y[index] >= y.max() - 1e-3 * step]
        top = index[np.argsort(y[index])[-8:]]
        peak = max(self._refine(k_of(max(i - 1, 0)), k_of(min(i + 1, len(y) - 1))) for i in top)
        over = (peak - y_end) / step
        # below ROUNDING of the step, the peak is the final value seen through rounding
        return (100.0 * over if over > ROUNDING else 0.0), ""

    def _evaluate(self, segments: list[_Segment]) -> tuple[Callable[[int], int], _Vector]:
        """The outputs on the grid of ``segments``, and the sample ``k`` (a Python int) of an index."""
        x, k_now = self.x0, 0
        ys: list[_Vector] = []
        firsts: list[_Segment] = []  # firsts: (index of the first point, its sample, spacing) of each segment
        for start, stop, h in segments:
            x = _apply(_power(self.step, start - k_now), x[:, None])[:, 0]
            t_h = _power(self.step, h)
            n = -(-(stop - start) // h)
            firsts.append((sum(len(v) for v in ys), start, h))
            for first in range(0, n, _CHUNK):
                X = _orbit(t_h, x, min(_CHUNK, n - first))
                ys.append(self.c @ X)
                x = _apply(t_h, X[:, -1:])[:, 0]
            # back to the last grid point, which lies before the next segment's start
            x, k_now = X[:, -1], start + h * (n - 1)
        offsets = [i for i, _, _ in firsts]

        def k_of(i: int) -> int:
            i0, start, h = firsts[bisect.bisect_right(offsets, i) - 1]
            return start + h * (i - i0)

        return k_of, np.concatenate(ys)

    def _refine(self, lo: int, hi: int) -> float:
        """The largest output from sample ``lo`` to ``hi``, grid neighbours of a grid maximum.

        Between grid neighbours every live mode turns by at most 2 THETA, so the output is
        unimodal there: golden-section search over the integers, then over time for a
        continuous loop.
        """
        ratio = (math.sqrt(5.0) - 1.0) / 2.0
        m1, m2 = hi - round(ratio * (hi - lo)), lo + round(ratio * (hi - lo))
        y1, y2 = self.output(m1), self.output(m2)
        while hi - lo > 8:
            if y1 < y2:
                lo, m1, y1 = m1, m2, y2
                m2 = lo + round(ratio * (hi - lo))
                y2 = self.output(m2)
            else:
                hi, m2, y2 = m2, m1, y1
                m1 = hi - round(ratio * (hi - lo))
                y1 = self.output(m1)
            if m1 > m2:  # rounding to integers can swap the inner points
                m1, m2, y1, y2 = m2, m1, y2, y1
        k_best = max(range(lo, hi + 1), key=self.output)
        y_best = self.output(k_best)
        if self._A is None or self._b is None:
            return y_best
        A, b = self._A, self._b
        E, f = _power(self.step, max(k_best - 1, 0))
        x = self.x0 + E @ self.x0 + f

        def minus_y(t_s: float) -> float:
            G = _gamma(A, t_s)
            return -float(self.c @ (x + A @ G @ x + G @ b))

        span = (2.0 if k_best > 0 else 1.0) * self.dt_s
        from scipy import optimize  # loaded here: a stability check alone never needs it

        found = optimize.minimize_scalar(minus_y, bounds=(0.0, span), method="bounded", options={"xatol": 1e-10 * span})
        return max(y_best, -float(found.fun))
