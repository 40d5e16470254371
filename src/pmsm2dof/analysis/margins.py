"""Stability margins of a loop gain, continuous or discrete.

The gain margin is the factor by which the loop gain can grow before the loop goes unstable,
the phase margin the phase it can lose; both are found by python-control
(``stability_margins``) on the crossings of the loop gain.
"""

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import control
import numpy as np
import numpy.typing as npt

#: Numbers at the crossings: a sequence or a 1-D array (python-control returns arrays).
_Floats = Sequence[float] | npt.NDArray[np.float64]


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


def loop_margins(L: control.TransferFunction) -> Margins:
    """Gain and phase margins of the stable continuous loop gain ``L(s)`` (see :func:`pick_margins`)."""
    gms, pms, _sms, w_pcs, w_gcs, _w_sms = control.stability_margins(L, returnall=True)
    return pick_margins(gms, pms, w_pcs, w_gcs)
