"""Figures of merit of one event of a run: a reference step, a load step, a fault.

Each is measured in the event's window (:mod:`pmsm2dof.sim.events`). The figures are taken relative to
what is commanded in the window (the reference there, for a load step). A window that holds no
sample after its event has every figure missing; one whose last :data:`STEADY_FRACTION` holds
fewer than :data:`STEADY_SAMPLES_MIN` samples has no settling, recovery or steady-state figure
(a steady state cannot be told from fewer); each says why. The figures are those used to
compare the controllers in the paper's section 4
(overshoot of Fig. 8, 12, tracking of Fig. 10, 13, load rejection of Fig. 14):

Reference step, from the speed ``w0`` at ``t_s`` to the new reference ``r`` (step ``D = r - w0``):

- ``overshoot_pct``: ``100 max(0, max((w - r) / D))``;
- ``rise_time_s``: from 10 % to 90 % of ``D`` (first crossings, linear interpolation);
- ``settling_time_s``: from ``t_s`` until ``|w - r|`` stays within 2 % of ``|D|``; the speed must
  be inside that band over at least the last 10 % of the window, else the figure is missing (a
  speed that has just entered the band may leave it again);
- ``steady_state_error_rpm``: ``r`` minus the mean speed over the last 10 % of the window, when
  the speed is steady there: it spreads by at most 0.2 % of ``|D|`` (a speed still converging
  inside the settling band is not a steady state);
- ``iae_rpm_s``: integral of ``|speed_ref - speed|`` over the window;
- ``current_limit_time_s``: time at the current limit (:func:`~pmsm2dof.sim.metrics.at_current_limit`; the state of a
  logged sample holds until the next sample).

Load step, from the load torque before to the new one (change ``dT``), with the speed error
``e = speed_ref - speed`` taken in the direction the load pushes (``sign(dT) e``):

- ``speed_dip_rpm`` and ``dip_time_s``: the peak of that error and when it occurs after ``t_s``;
  missing when that error is largest at ``t_s`` itself (a load taken off during a reversal:
  the error is the reversal's, and the load adds nothing to it);
- ``recovery_time_s``: from ``t_s`` until ``|e|`` stays within 2 % of the deviation (the same
  rule): the dip, or ``|e|`` at ``t_s`` when that is larger (a load that falls while the speed is
  still far from its reference, as when an overload that stalled the drive is released);
- ``steady_state_error_rpm``, ``iae_rpm_s``, ``current_limit_time_s`` as above (the spread test
  uses 0.2 % of the deviation).

Fault (each ``[[fault]]`` entry; a sensor_spike lasts one speed-controller period), from its
start ``t_s`` over a window that ends at the next schedule entry or fault after the fault's end:

- ``speed_deviation_rpm`` and ``deviation_time_s``: the peak of ``|e|`` and when it occurs after
  ``t_s``;
- ``recovery_time_s``: from the fault's end until ``|e|`` stays within 2 % of that peak (the same
  rule);
- ``current_limit_time_s`` as above.

A figure that cannot be computed is ``{"value": None, "reason": "..."}``, never NaN; a computed one is
``{"value": x}``.
"""

import math
from collections.abc import Collection
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .events import EventWindow

if TYPE_CHECKING:
    from .scenario_tables import FaultEntry

_Vector = npt.NDArray[np.float64]
#: A figure of merit: ``{"value": x}`` or ``{"value": None, "reason": "..."}``.
_Figure = dict[str, Any]

#: Settling band, relative to the step (reference) or to the dip (load).
BAND = 0.02
#: Final part of a window over which the steady state is measured.
STEADY_FRACTION = 0.1
#: Figures of each reference step, in output order.
REFERENCE_FIGURES = (
    "overshoot_pct",
    "rise_time_s",
    "settling_time_s",
    "steady_state_error_rpm",
    "iae_rpm_s",
    "current_limit_time_s",
)
#: Figures of each load step, in output order.
LOAD_FIGURES = (
    "speed_dip_rpm",
    "dip_time_s",
    "recovery_time_s",
    "steady_state_error_rpm",
    "iae_rpm_s",
    "current_limit_time_s",
)
#: Figures of each fault, in output order.
FAULT_FIGURES = ("speed_deviation_rpm", "deviation_time_s", "recovery_time_s", "current_limit_time_s")
#: Fewest samples in the last :data:`STEADY_FRACTION` of a window for a settling, recovery or
#: steady-state figure: two samples give a spread of one difference, which cannot tell a constant
#: from a ramp or an oscillation; three show a change of direction.
STEADY_SAMPLES_MIN = 3
#: Largest spread of the speed over that part, relative to the step (reference) or dip (load).
STEADY_SPREAD = 0.002


def figure(x: float) -> _Figure:
    """A computed figure: ``{"value": x}``."""
    return {"value": float(x)}


def missing(reason: str) -> _Figure:
    """A figure that cannot be computed, and why: ``{"value": None, "reason": reason}``."""
    return {"value": None, "reason": reason}


def time_where(t: _Vector, mask: npt.NDArray[np.bool_] | _Vector, t0: float, t1: float) -> float:
    """Time in [t0, t1] where ``mask`` holds; the value of sample k holds over [t[k], t[k+1]).

    ``mask`` may also be a share in [0, 1] of each sample's interval (``voltage_limited``).
    The sum runs over every interval of the trace, those outside [t0, t1] zero (``clip(t[k+1]) -
    clip(t[k])``), so that its rounding does not depend on where the window lies; only the
    intervals that meet the window are computed.
    """
    # the intervals [t[k], t[k+1]) that meet [t0, t1]: t[k+1] > t0 and t[k] < t1
    a = int(np.searchsorted(t[1:], t0, side="right"))
    b = int(np.searchsorted(t[:-1], t1, side="left"))
    inside = np.zeros(t.size - 1)
    if a < b:
        inside[a:b] = (np.clip(t[a + 1 : b + 1], t0, t1) - np.clip(t[a:b], t0, t1)) * mask[a:b]
    return float(np.sum(inside))


def _window(t: _Vector, t0: float, t1: float, *signals: _Vector) -> tuple[_Vector, list[_Vector]]:
    """Sample times in [t0, t1] with both ends included, and the signals interpolated on them."""
    tw = np.concatenate(([t0], t[(t > t0) & (t < t1)], [t1]))
    return tw, [np.interp(tw, t, s) for s in signals]


def _first_crossing(t: _Vector, z: _Vector, level: float) -> float | None:
    """First time z rises to ``level`` (z[0] < level), linearly interpolated, or None."""
    above = np.nonzero(z >= level)[0]
    if above.size == 0:
        return None
    k = above[0]
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (level - z[k - 1]) / (z[k] - z[k - 1]) * (t[k] - t[k - 1]))


def _entry_into_band(t: _Vector, dev: _Vector, band: float) -> float | None:
    """Time after which ``|dev| <= band`` to the end (interpolated), or None.

    None when ``dev`` is not inside the band over the whole final part of the window
    (:data:`STEADY_FRACTION`): a trace that has just entered the band may leave it again.
    """
    outside = np.nonzero(np.abs(dev) > band)[0]
    if outside.size == 0:
        return float(t[0])
    k = outside[-1]
    if k == len(t) - 1:
        return None
    level = band if dev[k] > band else -band
    t_in = float(t[k] + (level - dev[k]) / (dev[k + 1] - dev[k]) * (t[k + 1] - t[k]))
    return t_in if t_in <= t[-1] - STEADY_FRACTION * (t[-1] - t[0]) else None


def _too_short(tw: _Vector, t_samples: _Vector) -> str:
    """Why the window ``tw`` is too short to tell a steady state, or empty (:data:`STEADY_SAMPLES_MIN`).

    ``t_samples`` are the times of the rows at the speed controller's samples
    (:func:`~pmsm2dof.sim.events.speed_sample_rows`): its samples are what a steady state of the speed loop is
    told from.
    """
    # the samples in (tw[0], tw[-1]] at or after the start of its last part (t_samples increase)
    first = max(
        int(np.searchsorted(t_samples, tw[0], side="right")),
        int(np.searchsorted(t_samples, tw[-1] - STEADY_FRACTION * (tw[-1] - tw[0]), side="left")),
    )
    n = max(0, int(np.searchsorted(t_samples, tw[-1], side="right")) - first)
    if n >= STEADY_SAMPLES_MIN:
        return ""
    return (
        f"the window to the next event ({tw[0]:g} to {tw[-1]:g} s) is too short: {n} logged speed-controller "
        f"samples in its last {100 * STEADY_FRACTION:g} %, at least {STEADY_SAMPLES_MIN} needed to tell a steady state"
    )


def _steady_state_error(tw: _Vector, w: _Vector, target: float, spread_max: float) -> _Figure:
    """``target`` minus the mean of ``w`` over the last part of the window, if ``w`` is steady there."""
    tf, (final,) = _window(tw, tw[-1] - STEADY_FRACTION * (tw[-1] - tw[0]), tw[-1], w)
    spread = float(np.ptp(final))
    if spread > spread_max:
        return missing(
            f"the speed is still changing at {tw[-1]:g} s (spread {spread:.3g} rpm over the last "
            f"{100 * STEADY_FRACTION:g} % of the window, more than {spread_max:.3g} rpm)"
        )
    return figure(target - np.trapezoid(final, tf) / (tf[-1] - tf[0]))


def reference_step(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    span: EventWindow,
    before: float,
    after: float,
    names: Collection[str] = REFERENCE_FIGURES,
) -> dict[str, Any]:
    """Figures of the reference step from ``before`` to ``after`` [rpm] in the window ``span`` (module docstring).

    ``t`` and the traces ``speed``, ``ref`` [rpm] and ``limited`` (at the current limit) are the run's rows;
    ``t_samples`` the times of its speed-controller samples. Only the figures ``names`` (of
    :data:`REFERENCE_FIGURES`) are computed and returned, in the order of :data:`REFERENCE_FIGURES`.
    """
    t0 = span.t0
    out: dict[str, Any] = {"t_s": t0, "from_rpm": before, "to_rpm": after, "window_end_s": span.t_end or t0}
    names = [n for n in REFERENCE_FIGURES if n in names]
    if span.t_end is None:
        return out | {n: missing(span.empty_reason(t, "step")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    step = after - w[0]
    result: dict[str, _Figure] = {}
    if after == before or abs(step) <= 1e-3 * abs(after - before):
        reason = (
            "the reference does not change"
            if after == before
            else f"the speed is already at the new reference ({w[0]:g} rpm)"
        )
        result.update({n: missing(reason) for n in REFERENCE_FIGURES[:4]})
    else:
        z = (w - w[0]) / step
        short = _too_short(tw, t_samples)
        if "overshoot_pct" in names or "settling_time_s" in names:
            t_settle = None if short else _entry_into_band(tw, z - 1.0, BAND)
            if np.max(z) >= 1.0 or t_settle is not None:
                result["overshoot_pct"] = figure(100.0 * max(0.0, np.max(z) - 1.0))
            else:
                result["overshoot_pct"] = missing(f"the speed did not reach the reference before {t1:g} s")
            if short:
                result["settling_time_s"] = missing(short)
            elif t_settle is None:
                result["settling_time_s"] = missing(
                    f"the speed did not settle within 2 % of the step (and stay there over the last "
                    f"{100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
                )
            else:
                result["settling_time_s"] = figure(t_settle - t0)
        if "rise_time_s" in names:
            t10, t90 = _first_crossing(tw, z, 0.1), _first_crossing(tw, z, 0.9)
            result["rise_time_s"] = (
                figure(t90 - t10)
                if t90 is not None and t10 is not None
                else missing(f"the speed did not reach 90 % of the step before {t1:g} s")
            )
        if "steady_state_error_rpm" in names:
            result["steady_state_error_rpm"] = (
                missing(short) if short else _steady_state_error(tw, w, after, STEADY_SPREAD * abs(step))
            )
    if "iae_rpm_s" in names:
        result["iae_rpm_s"] = figure(float(np.trapezoid(np.abs(r - w), tw)))
    if "current_limit_time_s" in names:
        result["current_limit_time_s"] = figure(time_where(t, limited, t0, span.limit_end(t)))
    return out | {"speed_at_step_rpm": float(w[0])} | {n: result[n] for n in names}


def load_step(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    span: EventWindow,
    before: float,
    after: float,
    names: Collection[str] = LOAD_FIGURES,
) -> dict[str, Any]:
    """Figures of the load step from ``before`` to ``after`` [Nm] in the window ``span``, as :func:`reference_step`
    (``names`` of :data:`LOAD_FIGURES`)."""
    t0 = span.t0
    out: dict[str, Any] = {"t_s": t0, "from_Nm": before, "to_Nm": after, "window_end_s": span.t_end or t0}
    names = [n for n in LOAD_FIGURES if n in names]
    if span.t_end is None:
        return out | {n: missing(span.empty_reason(t, "step")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    e = r - w
    result: dict[str, _Figure] = {}
    if after == before:
        result.update({n: missing("the load torque does not change") for n in LOAD_FIGURES[:4]})
    else:
        d = math.copysign(1.0, after - before) * e
        k = int(np.argmax(d))
        dip = float(d[k])
        deviation = max(dip, abs(float(e[0])))
        if deviation <= 0.0:
            result.update({n: missing("the speed did not give way to the load") for n in LOAD_FIGURES[:4]})
        else:
            if dip > 0.0 and k == 0:
                reason = (
                    f"the speed error in the direction of the load is largest at the step itself ({dip:.4g} rpm, the "
                    "response to what came before): the load adds no dip of its own"
                )
                result.update({n: missing(reason) for n in LOAD_FIGURES[:2]})
            elif dip > 0.0:
                result["speed_dip_rpm"] = figure(dip)
                result["dip_time_s"] = figure(tw[k] - t0)
            else:
                result.update({n: missing("the speed did not give way to the load") for n in LOAD_FIGURES[:2]})
            short = _too_short(tw, t_samples)
            if "recovery_time_s" in names:
                t_rec = None if short else _entry_into_band(tw, e, BAND * deviation)
                if short:
                    result["recovery_time_s"] = missing(short)
                elif t_rec is None:
                    result["recovery_time_s"] = missing(
                        f"the speed did not recover to within 2 % of the {'dip' if dip >= deviation else 'error'}"
                        f" (and stay there over the last {100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
                    )
                else:
                    result["recovery_time_s"] = figure(t_rec - t0)
            if "steady_state_error_rpm" in names:
                result["steady_state_error_rpm"] = (
                    missing(short) if short else _steady_state_error(tw, w, r[-1], STEADY_SPREAD * deviation)
                )
    if "iae_rpm_s" in names:
        result["iae_rpm_s"] = figure(float(np.trapezoid(np.abs(e), tw)))
    if "current_limit_time_s" in names:
        result["current_limit_time_s"] = figure(time_where(t, limited, t0, span.limit_end(t)))
    return out | {n: result[n] for n in names}


def fault_figures(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    fault: "FaultEntry",
    t_end_fault: float,
    after: EventWindow,
    names: Collection[str] = FAULT_FIGURES,
) -> dict[str, Any]:
    """Figures of a fault from its start ``t_s`` to ``after.t_end``, the last sample before the event that
    follows its end (``after`` is the window from the fault's end); ``names`` of :data:`FAULT_FIGURES`, as
    :func:`reference_step`."""
    t0 = fault.t_s
    span = EventWindow(t0, after.t_next, after.t_end, after.tol)
    out: dict[str, Any] = {"kind": fault.kind, "t_s": t0, "end_s": t_end_fault, "window_end_s": span.t_end or t0}
    names = [n for n in FAULT_FIGURES if n in names]
    if span.t_end is None or not names:
        return out | {n: missing(span.empty_reason(t, "fault")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    e = np.abs(r - w)
    k = int(np.argmax(e))
    result: dict[str, _Figure] = {}
    if "current_limit_time_s" in names:
        result["current_limit_time_s"] = figure(time_where(t, limited, t0, span.limit_end(t)))
    if e[k] <= 0.0:
        result.update({n: missing("the speed did not deviate from its reference") for n in FAULT_FIGURES[:3]})
    elif t_end_fault >= t1:
        result.update(
            {
                "speed_deviation_rpm": figure(e[k]),
                "deviation_time_s": figure(tw[k] - t0),
                "recovery_time_s": missing(f"the fault lasts to the end of the window ({t1:g} s)"),
            }
        )
    else:
        result.update({"speed_deviation_rpm": figure(e[k]), "deviation_time_s": figure(tw[k] - t0)})
        tr, (wr, rr) = after.samples(t, speed, ref)
        short = _too_short(tr, t_samples)
        t_rec = None if short else _entry_into_band(tr, rr - wr, BAND * e[k])
        if short:
            result["recovery_time_s"] = missing(short)
        elif t_rec is None:
            result["recovery_time_s"] = missing(
                f"the speed did not recover to within 2 % of its deviation (and stay there over the last "
                f"{100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
            )
        else:
            result["recovery_time_s"] = figure(t_rec - t_end_fault)
    return out | {n: result[n] for n in names}
