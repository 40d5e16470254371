"""Stability margins of a loop gain, continuous or discrete.

The gain margin is the factor by which the loop gain can grow before the loop goes unstable,
the phase margin the phase it can lose; both are found by python-control
(``stability_margins``) on the crossings of the loop gain, or, for a loop gain that is not a
rational function (an exact delay ``exp(-s T)``, a sampled loop evaluated factor by factor), on
the crossings of its frequency response (:func:`frequency_margins`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..lazy import lazy_module

if TYPE_CHECKING:
    import control
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

#: Numbers at the crossings: a sequence or a 1-D array (python-control returns arrays).
_Floats = Sequence[float] | npt.NDArray[np.float64]
_Vector = npt.NDArray[np.float64]
_Matrix = npt.NDArray[np.float64]
#: Points per decade of the grid on which :func:`frequency_margins` looks for crossings.
GRID_PER_DECADE = 400


@dataclass(frozen=True)
class Margins:
    """Stability margins of a loop gain (python-control ``stability_margins``).

    Attributes
    ----------
    gain_margin_dB : float
        Gain margin [dB] (``inf`` when the phase never crosses -180 deg where ``|L| < 1``).
    phase_margin_deg : float
        Phase margin [deg] (``inf`` when ``|L|`` never crosses 1).
    w_gain_crossover_radps : float
        Frequency where ``|L| = 1`` [rad/s] (``nan`` when there is none).
    w_phase_crossover_radps : float
        Frequency of the gain margin's -180 deg crossing [rad/s] (``nan`` when there is none).
    """

    gain_margin_dB: float
    phase_margin_deg: float
    w_gain_crossover_radps: float
    w_phase_crossover_radps: float

    def values_and_reasons(self) -> tuple[dict[str, float | None], dict[str, str]]:
        """The margins as JSON-ready numbers, and the reason of each one that is ``None``.

        Returns
        -------
        (dict, dict)
            ``{name: value or None}`` (infinite and undefined values are ``None``) and
            ``{name: reason}`` for the ``None`` ones.
        """
        no_phase_crossing = "infinite: the phase of the loop gain never crosses -180 deg where |L| < 1"
        no_gain_crossing = "infinite: |L| never crosses 1"
        reasons = {
            "gain_margin_dB": no_phase_crossing,
            "phase_margin_deg": no_gain_crossing,
            "w_gain_crossover_radps": "undefined: |L| never crosses 1",
            "w_phase_crossover_radps": "undefined: the phase of the loop gain never crosses -180 deg where |L| < 1",
        }
        values = asdict(self)
        missing = {name: reasons[name] for name, v in values.items() if not math.isfinite(v)}
        return {name: (v if math.isfinite(v) else None) for name, v in values.items()}, missing


def pick_margins(
    gains: _Floats,
    phases_deg: _Floats,
    w_phase_radps: _Floats,
    w_gain_radps: _Floats,
    extra_crossings: Sequence[tuple[float, float]] = (),
) -> Margins:
    """The :class:`Margins` of a loop gain from all its -180 deg and unit-gain crossings.

    The gain margin is the factor by which the loop gain can grow before the loop goes
    unstable: the smallest ``1/|L|`` over the -180 deg crossings with ``|L| < 1``. Crossings
    with ``|L| > 1`` are left out: this type-2 loop (PI and integrating plant) has its phase
    at -180 deg at DC, and lowering its gain does not destabilize it. The phase margin is the
    smallest over the gain crossovers.

    Parameters
    ----------
    gains, w_phase_radps : sequence of float
        ``1/|L|`` [-] and frequency [rad/s] at each -180 deg crossing.
    phases_deg, w_gain_radps : sequence of float
        Phase margin [deg] and frequency [rad/s] at each crossing of ``|L| = 1``.
    extra_crossings : sequence of (float, float)
        Further ``(1/|L|, frequency)`` -180 deg crossings (the Nyquist frequency of a
        discrete loop).
    """
    crossings = [(float(gm), float(w)) for gm, w in zip(gains, w_phase_radps) if gm > 1.0]
    crossings += [(float(gm), float(w)) for gm, w in extra_crossings if gm > 1.0]
    gm, w_pc = min(crossings) if crossings else (math.inf, math.nan)
    pm, w_gc = min(zip(phases_deg, w_gain_radps)) if len(phases_deg) else (math.inf, math.nan)
    return Margins(20.0 * math.log10(gm), float(pm), float(w_gc), w_pc)


def polynomial_crossings(
    num: npt.ArrayLike, den: npt.ArrayLike, scales: Sequence[float] = (1.0,)
) -> list[tuple[_Vector, _Vector, _Vector, _Vector]]:
    """All -180 deg and unit-gain crossings of the continuous loop gains ``L(s) = num(s) / (c den(s))``.

    The crossings python-control's ``stability_margins`` finds by its polynomial method (its
    ``returnall`` result, the test oracle), without building a transfer function, for each gain
    scale ``c > 0`` of ``scales`` (a plant's inertia, say). With ``s = j w`` and ``x = w^2`` a
    real polynomial splits into its even and odd parts, ``P(jw) = Pe(x) + j w Po(x)``; then
    ``Im(num(jw) conj(den(jw))) = w (No De - Ne Do)(x)`` and
    ``|num(jw)|^2 - c^2 |den(jw)|^2 = (Ne^2 + x No^2 - c^2 (De^2 + x Do^2))(x)``. The -180 deg
    crossings, ``w = 0`` and the roots ``x > 0`` of the first where ``Re L(jw) <= 0``, do not
    depend on ``c`` (``1/|L|`` grows with it); the unit-gain crossings are the roots ``x > 0``
    of the second, where the phase does not depend on ``c`` either.

    Parameters
    ----------
    num, den : array_like
        Coefficients, highest power first.
    scales : sequence of float
        The factors ``c`` of the denominator, > 0.

    Returns
    -------
    list of (gains, phases_deg, w_phase_radps, w_gain_radps)
        Per scale: ``1/|L|`` at each -180 deg crossing, the phase margin at each unit-gain
        crossing, and their frequencies, as :func:`pick_margins` takes them.
    """
    num = np.asarray(num, dtype=float)
    den = np.asarray(den, dtype=float)

    def parts(p: _Vector) -> tuple[_Vector, _Vector]:
        # P(jw) = sum p_k (jw)^k: the even powers k = 2i give (-x)^i, the odd ones k = 2i + 1 give j w (-x)^i
        c = p[::-1]
        signs = (-1.0) ** np.arange((len(c) + 1) // 2)
        return (c[0::2] * signs[: len(c[0::2])])[::-1], (c[1::2] * signs[: len(c[1::2])])[::-1]

    def sqrt_of_roots(polys: _Matrix) -> list[_Vector]:
        # per row, sqrt(x) of the real roots x > 0, as numpy.roots finds them: the eigenvalues of the
        # companion matrix, of all rows in one call where their leading and trailing zeros agree
        nonzero = polys != 0.0
        if len(polys) == 0:
            return []
        if not np.all(nonzero == nonzero[0]):
            return [r for poly in polys for r in sqrt_of_roots(poly[np.newaxis, :])]
        where = np.flatnonzero(nonzero[0])
        if len(where) < 2:
            return [np.empty(0) for _ in polys]
        polys = polys[:, where[0] : where[-1] + 1]  # leading zeros, and roots at 0 (x > 0 is kept)
        n = polys.shape[1] - 1
        companion = np.zeros((len(polys), n, n))
        companion[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        companion[:, 0, :] = -polys[:, 1:] / polys[:, :1]
        out = []
        for roots in np.linalg.eigvals(companion):
            x = np.real(roots[np.isreal(roots)])
            out.append(np.sort(np.sqrt(x[x > 0.0])))
        return out

    def L(w: _Vector) -> npt.NDArray[np.complex128]:
        # with c = 1; den = 0 at w = 0 (integrators): L infinite there, left out below
        with np.errstate(all="ignore"):
            return np.polyval(num, 1j * w) / np.polyval(den, 1j * w)

    (ne, no), (de, do) = parts(num), parts(den)
    phase_poly = np.asarray(np.polysub(np.convolve(no, de), np.convolve(ne, do)), dtype=float)
    w_180: _Vector = np.concatenate((np.zeros(1), sqrt_of_roots(phase_poly[np.newaxis])[0]))
    L_180 = L(w_180)
    negative = L_180.real <= 0.0
    w_180, abs_L_180 = w_180[negative], np.abs(L_180[negative])
    num2 = np.polyadd(np.convolve(ne, ne), np.convolve(np.convolve(no, no), [1.0, 0.0]))
    den2 = np.polyadd(np.convolve(de, de), np.convolve(np.convolve(do, do), [1.0, 0.0]))
    c = np.asarray(scales, dtype=float)
    width = max(len(num2), len(den2))
    gain_polys = np.zeros((len(c), width))
    gain_polys[:, width - len(num2) :] += num2
    gain_polys[:, width - len(den2) :] -= np.outer(c * c, den2)
    w_cs = sqrt_of_roots(gain_polys)
    phases_all = np.remainder(np.angle(L(np.concatenate([np.empty(0), *w_cs])), deg=True), 360.0) - 180.0
    out = []
    start = 0
    for scale, w_c in zip(c, w_cs):
        with np.errstate(divide="ignore"):
            gains = scale / abs_L_180
        out.append((gains, phases_all[start : start + len(w_c)], w_180, w_c))
        start += len(w_c)
    return out


def loop_margins(L: control.TransferFunction) -> Margins:
    """Gain and phase margins of the stable continuous loop gain ``L(s)`` (see :func:`pick_margins`)."""
    gms, pms, _sms, w_pcs, w_gcs, _w_sms = control.stability_margins(L, returnall=True)
    return pick_margins(gms, pms, w_pcs, w_gcs)


def frequency_margins(
    L_of_w: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.complex128]],
    w_lo_radps: float,
    w_hi_radps: float,
    extra_crossings: Sequence[tuple[float, float]] = (),
) -> Margins:
    """Margins of a loop gain given by its frequency response ``L_of_w(w)`` (complex, vectorized).

    The crossings of ``|L| = 1`` and of the phase ``-180 deg (mod 360)`` are bracketed on a
    logarithmic grid from ``w_lo_radps`` to ``w_hi_radps`` (:data:`GRID_PER_DECADE` points per
    decade, the phase unwrapped along it) and refined by Brent's method; the margins are then
    picked as :func:`pick_margins` does. The grid must span the crossings (a delay adds a
    phase crossing every ``2 pi / T`` rad/s: all below ``w_hi_radps`` are found).
    """
    n = max(int(GRID_PER_DECADE * math.log10(w_hi_radps / w_lo_radps)), 2)
    w = np.geomspace(w_lo_radps, w_hi_radps, n)
    L = L_of_w(w)
    mag_db = 20.0 * np.log10(np.abs(L))
    phase = np.unwrap(np.angle(L))

    def phase_at(x: float) -> float:
        # the phase at x, unwrapped continuously from the nearest grid point
        i = min(int(np.searchsorted(w, x)), len(w) - 1)
        return float(phase[i] + np.angle(L_of_w(np.array([x]))[0] / L[i]))

    from scipy import optimize  # loaded here: a stability check alone never needs it

    gains: list[float] = []
    w_phase: list[float] = []
    phases: list[float] = []
    w_gain: list[float] = []
    for i in np.flatnonzero(np.diff(np.sign(mag_db)) != 0):
        wc = optimize.brentq(lambda x: 20.0 * np.log10(abs(L_of_w(np.array([x]))[0])), w[i], w[i + 1])
        phases.append(math.degrees(phase_at(wc)) % 360.0 - 180.0)
        w_gain.append(wc)
    # the phase crossings: phase + 180 deg through a multiple of 360 deg
    turns = (phase + math.pi) / (2.0 * math.pi)
    for i in np.flatnonzero(np.floor(turns[1:]) != np.floor(turns[:-1])):
        k = max(math.floor(turns[i]), math.floor(turns[i + 1]))
        wp = optimize.brentq(lambda x, k=k: (phase_at(x) + math.pi) / (2.0 * math.pi) - k, w[i], w[i + 1])
        gains.append(1.0 / abs(L_of_w(np.array([wp]))[0]))
        w_phase.append(wp)
    return pick_margins(gains, phases, w_phase, w_gain, extra_crossings)
