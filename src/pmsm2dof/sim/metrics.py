"""Figures of merit of a simulated run: each reference step and each load step.

For every entry of the scenario's ``reference`` and ``load`` schedules, the response is measured
in its *window*: from the entry's time ``t_s`` to the last logged sample before the next *event*
(or to the end of the trace). The events are the entries of either schedule that change the
reference or the load, in any order and at any spacing, and the starts of the faults. A sample
at the time of the next event (within the engine's time tolerance, ``csrc/sim/drive.c``) already
shows it: its reference is the new one, so that a load step removed 50 ms before a speed
reversal would otherwise count the reversal as its dip. An entry that repeats the value before
it changes no input of the loop, so the response of the event before goes on through it: it is
no boundary (its own figures are missing, "does not change"). The figures are taken relative to
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
- ``current_limit_time_s``: time at the current limit (:func:`at_current_limit`; the state of a
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

Whole run: ``iae_rpm_s`` and ``current_limit_time_s`` as above, ``voltage_limit_time_s``, the time
at the inverter's range ``u_dc / sqrt(3)`` (:func:`at_voltage_limit`; missing for a trace without
the ``voltage_limited`` signal), and ``chatter_share``, the share of the samples at which the
current command chatters (:func:`chatter`). A drive at its voltage limit no longer follows its
current commands: the speed loop's design (eq 3, 9) does not hold there. A run whose
``chatter_share`` exceeds :data:`CHATTER_SHARE_MAX` is a limit cycle, not a response: its
``warnings`` say so, first.

Fault (each ``[[fault]]`` entry; a sensor_spike lasts one speed-controller period), from its
start ``t_s`` over a window that ends at the next schedule entry or fault after the fault's end:

- ``speed_deviation_rpm`` and ``deviation_time_s``: the peak of ``|e|`` and when it occurs after
  ``t_s``;
- ``recovery_time_s``: from the fault's end until ``|e|`` stays within 2 % of that peak (the same
  rule);
- ``current_limit_time_s`` as above.

A log at the current rate (``simulation.log_rate = "current"``) is measured on all its rows (the
speed between the speed controller's samples too: a dip or a crossing between two samples is
seen where it happens); what is counted in the speed controller's samples is counted in the rows
at its sampling instants: the samples that tell a steady state (:data:`STEADY_SAMPLES_MIN`) and
the chatter of its command, which holds between them.

A figure that cannot be computed (no change at the step, the speed did not reach or did not
settle before the window ends) is ``{"value": None, "reason": "..."}``, never NaN; a computed one
is ``{"value": x}``. Speeds are in rpm, as in the scenario and the trace.
"""

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError, SimulationError
from .logs import Log

if TYPE_CHECKING:
    from .scenario import Scenario
    from .scenario_tables import FaultEntry
    from .simulate import Result

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
#: Figures of the whole run.
RUN_FIGURES = ("iae_rpm_s", "current_limit_time_s", "voltage_limit_time_s", "chatter_share")
#: Fewest samples in the last :data:`STEADY_FRACTION` of a window for a settling, recovery or
#: steady-state figure: two samples give a spread of one difference, which cannot tell a constant
#: from a ramp or an oscillation; three show a change of direction.
STEADY_SAMPLES_MIN = 3
#: Second difference of the current command, relative to the current limit, at and above which a
#: sample chatters (:func:`chatter`).
CHATTER_D2 = 0.1
#: Largest share of chattering samples of a run that does not chatter (:func:`chatter`).
CHATTER_SHARE_MAX = 0.01
#: Largest spread of the speed over that part, relative to the step (reference) or dip (load).
STEADY_SPREAD = 0.002
#: A command within this fraction of its limit is at the limit (:func:`at_current_limit`, :func:`at_voltage_limit`).
LIMIT_RTOL = 0.01


def _value(x: float) -> _Figure:
    return {"value": float(x)}


def _missing(reason: str) -> _Figure:
    return {"value": None, "reason": reason}


def _trace(result: "Result", name: str) -> _Vector:
    values = np.asarray(getattr(result, name), dtype=float)
    if values.shape != np.shape(result.t_s) or not np.all(np.isfinite(values)):
        raise SimulationError(f"result.{name} must be finite and as long as result.t_s")
    return values


def _schedule(entries: Sequence[tuple[float, float]]) -> list[tuple[float, float, float]]:
    """(t_s, value before, value after) of each entry ``(t_s, value)``; the value is 0 before the first entry."""
    before = 0.0
    events = []
    for t_s, value in entries:
        events.append((t_s, before, value))
        before = value
    return events


def _references(scenario: "Scenario") -> list[tuple[float, float, float]]:
    """:func:`_schedule` of the speed reference [rpm]."""
    return _schedule([(e.t_s, e.speed_rpm) for e in scenario.reference])


def _loads(scenario: "Scenario") -> list[tuple[float, float, float]]:
    """:func:`_schedule` of the load torque [Nm]."""
    return _schedule([(e.t_s, e.torque_Nm) for e in scenario.load])


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


def at_current_limit(result: "Result") -> npt.NDArray[np.bool_]:
    """Whether the drive is at its current limit, sample by sample.

    A sample is at the limit when the speed controller's ``saturated`` flag is set or the
    magnitude of the current command ``(id_ref_A, iq_ref_A)`` is at least
    ``(1 - LIMIT_RTOL) i_max``. The limit bounds the torque (``Te = 1.5 p psi_f iq`` for a
    surface PMSM), so within 1 % of it the drive accelerates at 99 % or more of what the limit
    allows, which no speed trace tells from the limit itself.

    The flag alone undercounts. With clamping anti-windup (the integrator held while the limit is
    active and the error pushes into it) the unlimited command falls by ``Kp dw/dt Ts`` in one
    sample, a fraction ``(J_design / J) alpha Ts`` of the limit (0.05 % in paper condition 1);
    the integrator then pushes it back over, and the flag toggles every sample while the command
    stays at the limit (condition 1, 1DOF PI with clamping: flagged for 0.95 s of the first 1.65 s,
    over which the command never falls 0.05 % below the limit). Dips deeper than 1 % (alpha Ts
    above 0.01) count as off the limit for the samples they last, as the torque then is.

    Parameters
    ----------
    result : Result
        Arrays ``saturated``, ``id_ref_A``, ``iq_ref_A`` and the ``scenario`` (``limits.i_max_A``).

    Returns
    -------
    numpy.ndarray of bool
    """
    saturated = np.asarray(result.saturated, dtype=bool)
    if saturated.shape != np.shape(result.t_s):
        raise SimulationError("result.saturated must be as long as result.t_s")
    i_max = result.scenario.limits.i_max_A
    command = np.hypot(_trace(result, "id_ref_A"), _trace(result, "iq_ref_A"))
    at_limit: npt.NDArray[np.bool_] = saturated | (command >= (1.0 - LIMIT_RTOL) * i_max)
    return at_limit


def at_voltage_limit(result: "Result") -> _Vector:
    """The share of each sample at the inverter's voltage limit, counted as :func:`at_current_limit` counts.

    A sample is at the limit for its whole interval when the applied voltage ``||(ud_V, uq_V)||``
    is at least ``(1 - LIMIT_RTOL) u_dc / sqrt(3)``; otherwise for the share of its current periods
    whose voltage the range cut (the engine's ``voltage_limited``). Within 1 % of its range the
    inverter has next to no voltage left to drive the currents to their commands, which the speed
    loop's design assumes it has (eq 3, 9); and a current controller whose limit acts on some
    current periods of a sample and not on others while the voltage holds at the range is at
    the limit for all of them, as the speed controller's chattering flag is for the current.

    Parameters
    ----------
    result : Result
        Arrays ``voltage_limited``, ``ud_V``, ``uq_V`` and ``u_dc_V``.

    Returns
    -------
    numpy.ndarray of float
        In [0, 1], one per sample.
    """
    share = _trace(result, "voltage_limited")
    if np.any((share < 0.0) | (share > 1.0)):
        raise SimulationError("result.voltage_limited must be a share in [0, 1]")
    u_max = _trace(result, "u_dc_V") / math.sqrt(3.0)
    at_range = np.hypot(_trace(result, "ud_V"), _trace(result, "uq_V")) >= (1.0 - LIMIT_RTOL) * u_max
    return np.where(at_range, 1.0, share)


def _time_where(t: _Vector, mask: npt.NDArray[np.bool_] | _Vector, t0: float, t1: float) -> float:
    """Time in [t0, t1] where ``mask`` holds; the value of sample k holds over [t[k], t[k+1]).

    ``mask`` may also be a share in [0, 1] of each sample's interval (``voltage_limited``).
    """
    starts = np.clip(t[:-1], t0, t1)
    ends = np.clip(t[1:], t0, t1)
    return float(np.sum((ends - starts) * mask[:-1]))


def _window(t: _Vector, t0: float, t1: float, *signals: _Vector) -> tuple[_Vector, list[_Vector]]:
    """Sample times in [t0, t1] with both ends included, and the signals interpolated on them."""
    tw = np.concatenate(([t0], t[(t > t0) & (t < t1)], [t1]))
    return tw, [np.interp(tw, t, s) for s in signals]


@dataclasses.dataclass(frozen=True)
class _Span:
    """The window of one event: from its time ``t0`` to the last sample ``t_end`` before the next event.

    ``t_next`` is the time of the next event (None: none before the end of the trace); ``t_end``
    is None when no sample lies between ``t0`` and ``t_next``; ``tol`` is the time within which a
    sample is at an event (the engine's tolerance).
    """

    t0: float
    t_next: float | None
    t_end: float | None
    tol: float

    @classmethod
    def of(cls, t: _Vector, t0: float, t_next: float | None, tol: float) -> "_Span":
        inside = t > t0 + tol
        if t_next is not None:
            inside &= t < t_next - tol
        return cls(t0, t_next, float(t[inside][-1]) if np.any(inside) else None, tol)

    def limit_end(self, t: _Vector) -> float:
        """The end of the time counted at the current limit: the next event, or the end of the trace."""
        return float(t[-1]) if self.t_next is None else min(self.t_next, float(t[-1]))

    def empty_reason(self, t: _Vector, what: str) -> str:
        if self.t0 >= t[-1]:
            return f"the trace ends at {t[-1]:g} s, before the {what}"
        return (
            f"no logged sample between the {what} at {self.t0:g} s and the next event at {self.t_next:g} s: "
            "the window is empty"
        )

    def samples(self, t: _Vector, *signals: _Vector) -> tuple[_Vector, list[_Vector]]:
        """The window's sample times after ``t0`` (``t0`` itself first, the signals interpolated there)."""
        assert self.t_end is not None
        tw = np.concatenate(([self.t0], t[(t > self.t0 + self.tol) & (t <= self.t_end)]))
        return tw, [np.interp(tw, t, s) for s in signals]


def _too_short(tw: _Vector, t_samples: _Vector) -> str:
    """Why the window ``tw`` is too short to tell a steady state, or empty (:data:`STEADY_SAMPLES_MIN`).

    ``t_samples`` are the times of the rows at the speed controller's samples (:func:`speed_sample_rows`):
    its samples are what a steady state of the speed loop is told from.
    """
    inside = t_samples[(t_samples > tw[0]) & (t_samples <= tw[-1])]
    n = int(np.count_nonzero(inside >= tw[-1] - STEADY_FRACTION * (tw[-1] - tw[0])))
    if n >= STEADY_SAMPLES_MIN:
        return ""
    return (
        f"the window to the next event ({tw[0]:g} to {tw[-1]:g} s) is too short: {n} logged speed-controller "
        f"samples in its last {100 * STEADY_FRACTION:g} %, at least {STEADY_SAMPLES_MIN} needed to tell a steady state"
    )


def speed_sample_rows(scenario: "Scenario", rows: int) -> npt.NDArray[np.bool_]:
    """Which of the ``rows`` rows of a run's log are at the speed controller's sampling instants.

    Every row at the speed rate; at the current rate (``simulation.log_rate = "current"``) row ``r``
    starts the current period ``r log_every``, a speed sample when ``current_per_speed`` divides it.
    """
    if scenario.simulation.log_rate == "speed":
        return np.ones(rows, bool)
    per_speed = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    mask: npt.NDArray[np.bool_] = (np.arange(rows, dtype=np.int64) * scenario.simulation.log_every) % per_speed == 0
    return mask


def _reference_step(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    span: _Span,
    before: float,
    after: float,
) -> dict[str, Any]:
    t0 = span.t0
    out: dict[str, Any] = {"t_s": t0, "from_rpm": before, "to_rpm": after, "window_end_s": span.t_end or t0}
    names = REFERENCE_FIGURES
    if span.t_end is None:
        return out | {n: _missing(span.empty_reason(t, "step")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    step = after - w[0]
    result: dict[str, _Figure] = {}
    short = _too_short(tw, t_samples)
    if after == before or abs(step) <= 1e-3 * abs(after - before):
        reason = (
            "the reference does not change"
            if after == before
            else f"the speed is already at the new reference ({w[0]:g} rpm)"
        )
        result.update({n: _missing(reason) for n in names[:4]})
    else:
        z = (w - w[0]) / step
        t10, t90 = _first_crossing(tw, z, 0.1), _first_crossing(tw, z, 0.9)
        t_settle = None if short else _entry_into_band(tw, z - 1.0, BAND)
        if np.max(z) >= 1.0 or t_settle is not None:
            result["overshoot_pct"] = _value(100.0 * max(0.0, np.max(z) - 1.0))
        else:
            result["overshoot_pct"] = _missing(f"the speed did not reach the reference before {t1:g} s")
        result["rise_time_s"] = (
            _value(t90 - t10)
            if t90 is not None and t10 is not None
            else _missing(f"the speed did not reach 90 % of the step before {t1:g} s")
        )
        if short:
            result["settling_time_s"] = _missing(short)
        elif t_settle is None:
            result["settling_time_s"] = _missing(
                f"the speed did not settle within 2 % of the step (and stay there over the last "
                f"{100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
            )
        else:
            result["settling_time_s"] = _value(t_settle - t0)
        result["steady_state_error_rpm"] = (
            _missing(short) if short else _steady_state_error(tw, w, after, STEADY_SPREAD * abs(step))
        )
    result["iae_rpm_s"] = _value(float(np.trapezoid(np.abs(r - w), tw)))
    result["current_limit_time_s"] = _value(_time_where(t, limited, t0, span.limit_end(t)))
    return out | {"speed_at_step_rpm": float(w[0])} | {n: result[n] for n in names}


def _load_step(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    span: _Span,
    before: float,
    after: float,
) -> dict[str, Any]:
    t0 = span.t0
    out: dict[str, Any] = {"t_s": t0, "from_Nm": before, "to_Nm": after, "window_end_s": span.t_end or t0}
    names = LOAD_FIGURES
    if span.t_end is None:
        return out | {n: _missing(span.empty_reason(t, "step")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    e = r - w
    result: dict[str, _Figure] = {}
    short = _too_short(tw, t_samples)
    if after == before:
        result.update({n: _missing("the load torque does not change") for n in names[:4]})
    else:
        d = math.copysign(1.0, after - before) * e
        k = int(np.argmax(d))
        dip = float(d[k])
        deviation = max(dip, abs(float(e[0])))
        if deviation <= 0.0:
            result.update({n: _missing("the speed did not give way to the load") for n in names[:4]})
        else:
            if dip > 0.0 and k == 0:
                reason = (
                    f"the speed error in the direction of the load is largest at the step itself ({dip:.4g} rpm, the "
                    "response to what came before): the load adds no dip of its own"
                )
                result.update({n: _missing(reason) for n in names[:2]})
            elif dip > 0.0:
                result["speed_dip_rpm"] = _value(dip)
                result["dip_time_s"] = _value(tw[k] - t0)
            else:
                result.update({n: _missing("the speed did not give way to the load") for n in names[:2]})
            t_rec = None if short else _entry_into_band(tw, e, BAND * deviation)
            if short:
                result["recovery_time_s"] = _missing(short)
            elif t_rec is None:
                result["recovery_time_s"] = _missing(
                    f"the speed did not recover to within 2 % of the {'dip' if dip >= deviation else 'error'}"
                    f" (and stay there over the last {100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
                )
            else:
                result["recovery_time_s"] = _value(t_rec - t0)
            result["steady_state_error_rpm"] = (
                _missing(short) if short else _steady_state_error(tw, w, r[-1], STEADY_SPREAD * deviation)
            )
    result["iae_rpm_s"] = _value(float(np.trapezoid(np.abs(e), tw)))
    result["current_limit_time_s"] = _value(_time_where(t, limited, t0, span.limit_end(t)))
    return out | {n: result[n] for n in names}


def _fault(
    t: _Vector,
    t_samples: _Vector,
    speed: _Vector,
    ref: _Vector,
    limited: npt.NDArray[np.bool_],
    fault: "FaultEntry",
    t_end_fault: float,
    after: _Span,
) -> dict[str, Any]:
    """Figures of a fault from its start ``t_s`` to ``after.t_end``, the last sample before the event that
    follows its end (``after`` is the window from the fault's end)."""
    t0 = fault.t_s
    span = _Span(t0, after.t_next, after.t_end, after.tol)
    out: dict[str, Any] = {"kind": fault.kind, "t_s": t0, "end_s": t_end_fault, "window_end_s": span.t_end or t0}
    names = FAULT_FIGURES
    if span.t_end is None:
        return out | {n: _missing(span.empty_reason(t, "fault")) for n in names}
    tw, (w, r) = span.samples(t, speed, ref)
    t1 = span.t_end
    e = np.abs(r - w)
    k = int(np.argmax(e))
    result = {"current_limit_time_s": _value(_time_where(t, limited, t0, span.limit_end(t)))}
    if e[k] <= 0.0:
        result.update({n: _missing("the speed did not deviate from its reference") for n in names[:3]})
    elif t_end_fault >= t1:
        result.update(
            {
                "speed_deviation_rpm": _value(e[k]),
                "deviation_time_s": _value(tw[k] - t0),
                "recovery_time_s": _missing(f"the fault lasts to the end of the window ({t1:g} s)"),
            }
        )
    else:
        result.update({"speed_deviation_rpm": _value(e[k]), "deviation_time_s": _value(tw[k] - t0)})
        tr, (wr, rr) = after.samples(t, speed, ref)
        short = _too_short(tr, t_samples)
        t_rec = None if short else _entry_into_band(tr, rr - wr, BAND * e[k])
        if short:
            result["recovery_time_s"] = _missing(short)
        elif t_rec is None:
            result["recovery_time_s"] = _missing(
                f"the speed did not recover to within 2 % of its deviation (and stay there over the last "
                f"{100 * STEADY_FRACTION:g} % of the window) before {t1:g} s"
            )
        else:
            result["recovery_time_s"] = _value(t_rec - t_end_fault)
    return out | {n: result[n] for n in names}


def _steady_state_error(tw: _Vector, w: _Vector, target: float, spread_max: float) -> _Figure:
    """``target`` minus the mean of ``w`` over the last part of the window, if ``w`` is steady there."""
    tf, (final,) = _window(tw, tw[-1] - STEADY_FRACTION * (tw[-1] - tw[0]), tw[-1], w)
    spread = float(np.ptp(final))
    if spread > spread_max:
        return _missing(
            f"the speed is still changing at {tw[-1]:g} s (spread {spread:.3g} rpm over the last "
            f"{100 * STEADY_FRACTION:g} % of the window, more than {spread_max:.3g} rpm)"
        )
    return _value(target - np.trapezoid(final, tf) / (tf[-1] - tf[0]))


def event_times(scenario: "Scenario") -> list[float]:
    """The events of a scenario, sorted: the entries of ``reference`` and ``load`` that change the value
    before them (0 before the first), and the start of each fault."""
    times = {f.t_s for f in scenario.fault}
    for events in (_references(scenario), _loads(scenario)):
        times.update(t0 for t0, before, after in events if after != before)
    return sorted(times)


def _fault_ends(scenario: "Scenario") -> list[float]:
    """The end of each fault: a sensor_spike lasts one speed-controller period."""
    Ts_speed = scenario.speed_controller.Ts_s
    return [f.t_s + (Ts_speed if f.duration_s is None else f.duration_s) for f in scenario.fault]


def _next_event(times: Sequence[float], t0: float, tol: float) -> float | None:
    later = [x for x in times if x > t0 + tol]
    return later[0] if later else None


def time_tolerance_s(scenario: "Scenario") -> float:
    """The engine's time tolerance: times closer than it are equal, so an entry within it of a sample
    acts at that sample (``P2D_SIM_T_TOL`` of ``csrc/sim/drive.c`` times the integration step)."""
    Ts_current = float(scenario.current_loop.Ts_s)
    step = Ts_current / max(1, math.ceil(Ts_current / scenario.simulation.dt_s * (1.0 - 1e-9)))
    return float(1e-6 * step)


def chatter(command: _Vector, limit: float, quiet: npt.NDArray[np.bool_] | None = None) -> float:
    """The share of the samples at which a command chatters: ``|c[k+1] - 2 c[k] + c[k-1]| >= CHATTER_D2 limit``.

    The second difference is the change of the command's slope from one sample to the next. A
    command that oscillates at the angular frequency ``w`` with amplitude ``A`` has
    ``|second difference| <= 4 sin^2(w Ts / 2) A``, at most ``(w Ts)^2 A``: within the band the
    design keeps to (``w Ts <= 0.1``, the sampling check of
    :func:`pmsm2dof.analysis.discretize.discretize`) and at the full amplitude ``A = limit``,
    ``0.01 limit``, ten times below :data:`CHATTER_D2`. A sample beyond it is a reversal at a
    frequency the design does not have: a limit cycle between or short of the limits, an unstable
    sampled loop held by the limit, or noise amplified to a tenth of the limit. A step of the
    reference steps the command on purpose; the caller marks those samples ``quiet``.

    Parameters
    ----------
    command : numpy.ndarray
        The command, one value per speed-controller sample (every sample: a decimated log
        cannot show a reversal from one sample to the next).
    limit : float
        Its limit, > 0 (``i_max_A`` for the q current command).
    quiet : numpy.ndarray of bool, optional
        Samples whose second difference is not counted (their stencil ``k-1, k, k+1`` holds a
        step of the reference, the load or a fault).

    Returns
    -------
    float
        In [0, 1]; 0 for fewer than three samples.
    """
    c = np.asarray(command, dtype=float) / limit
    if c.size < 3:
        return 0.0
    d2 = np.abs(c[2:] - 2.0 * c[1:-1] + c[:-2])
    counted = np.ones(d2.shape, bool) if quiet is None else ~np.asarray(quiet, bool)[1:-1]
    n = int(np.count_nonzero(counted))
    return float(np.count_nonzero((d2 >= CHATTER_D2) & counted) / n) if n else 0.0


def _chatter_figure(t: _Vector, iq_ref: _Vector, scenario: "Scenario", times: Sequence[float], tol: float) -> _Figure:
    """``chatter_share`` of a run: :func:`chatter` of the q current command at the speed controller's samples
    (the rows of :func:`speed_sample_rows`, ``t`` and ``iq_ref`` already those), quiet at the events."""
    log_every = scenario.simulation.log_every
    per_speed = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    if scenario.simulation.log_rate == "speed" and log_every > 1:
        return _missing(
            f"the trace logs every {log_every}th speed-controller sample: a reversal from one sample to the "
            "next needs every sample (simulation.log_every = 1)"
        )
    if scenario.simulation.log_rate == "current" and per_speed % log_every != 0:
        return _missing(
            f"the trace logs every {log_every}th current period, which does not divide the speed-controller "
            "period: a reversal from one sample to the next needs every sample (a simulation.log_every that "
            "divides speed_controller.Ts_s / current_loop.Ts_s)"
        )
    # the two samples from each event on, and the one before, step on purpose
    quiet = np.zeros(t.shape, bool)
    for x in times:
        k = int(np.searchsorted(t, x - tol))
        quiet[max(k - 1, 0) : k + 2] = True
    return _value(chatter(iq_ref, scenario.limits.i_max_A, quiet))


def _chatter_warning(figure: _Figure) -> list[str]:
    share = figure["value"]
    if share is None or share <= CHATTER_SHARE_MAX:
        return []
    return [
        f"CHATTER: the current command reverses by {100 * CHATTER_D2:g} % of the limit or more from one sample to "
        f"the next at {100 * share:.3g} % of the samples (more than {100 * CHATTER_SHARE_MAX:g} %): a limit cycle "
        "or an unstable sampled loop held by the limit, not a response the figures describe"
    ]


def compute_metrics(result: "Result | Log", i_max_A: float | None = None) -> dict[str, Any]:
    """Figures of merit of every reference step and load step of a simulated run or a measured log.

    Parameters
    ----------
    result : Result or Log
        A run of :func:`pmsm2dof.simulate`: arrays ``t_s``, ``speed_rpm``, ``speed_ref_rpm``,
        ``saturated``, ``id_ref_A``, ``iq_ref_A`` and the ``scenario`` whose ``reference`` and
        ``load`` schedules are measured. Or a measured :class:`~pmsm2dof.sim.logs.Log` with
        ``speed_ref_rpm``: each change of the logged reference by more than 1 % of its range is a
        reference step, and so is its first row when the speed there is that far from the
        reference (a log does not know its loads; a ramp counts as its steps); the time at
        the current limit counts the samples whose ``||(id_A, iq_A)||`` (``iq_ref_A`` when logged)
        is within 1 % of ``i_max_A``, and is missing without it; no voltage figure.
    i_max_A : float, optional
        Log only: the drive's current limit [A].

    Returns
    -------
    dict
        JSON-serialisable: ``{"scenario", "reference_steps": [...], "load_steps": [...], "faults": [...],
        "run", "warnings"}``;
        each figure is ``{"value": x}`` or ``{"value": None, "reason": "..."}`` (see the module
        docstring for the definitions); ``warnings`` holds sentences on a run that the figures
        do not describe (a chattering command), empty for a run they do.
    """
    if isinstance(result, Log):
        return _log_metrics(result, i_max_A)
    t = np.asarray(result.t_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise SimulationError("result.t_s must hold at least two finite, increasing times")
    speed = _trace(result, "speed_rpm")
    ref = _trace(result, "speed_ref_rpm")
    limited = at_current_limit(result)
    scenario = result.scenario
    at_samples = speed_sample_rows(scenario, t.size)
    t_samples = t[at_samples]
    ref_events = _references(scenario)
    load_events = _loads(scenario)
    times = event_times(scenario)
    tol = time_tolerance_s(scenario)

    def span(t0: float) -> _Span:
        return _Span.of(t, t0, _next_event(times, t0, tol), tol)

    chatter_share = _chatter_figure(
        t_samples,
        _trace(result, "iq_ref_A")[at_samples],
        scenario,
        [*times, *_fault_ends(scenario)],
        tol,
    )
    return {
        "scenario": scenario.name,
        "reference_steps": [
            _reference_step(t, t_samples, speed, ref, limited, span(t0), b, a) for t0, b, a in ref_events
        ],
        "load_steps": [_load_step(t, t_samples, speed, ref, limited, span(t0), b, a) for t0, b, a in load_events],
        "faults": [
            _fault(t, t_samples, speed, ref, limited, f, end, span(end))
            for f, end in zip(scenario.fault, _fault_ends(scenario))
        ],
        "run": {
            "t_end_s": float(t[-1]),
            "iae_rpm_s": _value(float(np.trapezoid(np.abs(ref - speed), t))),
            "current_limit_time_s": _value(_time_where(t, limited, t[0], t[-1])),
            "voltage_limit_time_s": _voltage_limit_time(result, t),
            "chatter_share": chatter_share,
        },
        "warnings": _chatter_warning(chatter_share),
    }


def _log_metrics(log: Log, i_max_A: float | None) -> dict[str, Any]:
    """:func:`compute_metrics` of a measured log: its steps from the logged reference."""
    if log.speed_ref_rpm is None:
        raise ConfigError("log", log.source, "a log with speed_ref_rpm to measure its reference steps")
    t, speed, ref = log.t_s, log.speed_rpm, log.speed_ref_rpm
    tol = 0.01 * max(float(np.ptp(ref)), float(np.max(np.abs(ref))), 1e-12)
    jumps = np.flatnonzero(np.abs(np.diff(ref)) > tol) + 1
    ref_events = [(float(t[k]), float(ref[k - 1]), float(ref[k])) for k in jumps]
    if abs(ref[0] - speed[0]) > tol:
        # a log that starts with the reference away from the speed: a step at its first row
        ref_events.insert(0, (float(t[0]), float(speed[0]), float(ref[0])))
    if i_max_A is None:
        limited = np.zeros(t.shape, bool)
    else:
        iq = log.iq_ref_A if log.iq_ref_A is not None else log.iq_A
        if iq is None:
            raise ConfigError("log", log.source, "a log with iq_A or iq_ref_A to count the time at the current limit")
        i_d = log.id_A if log.id_A is not None else np.zeros_like(iq)
        limited = np.hypot(i_d, iq) >= (1.0 - LIMIT_RTOL) * i_max_A
    # a logged step is at its row: the window of the one before ends at the row before
    times = [e[0] for e in ref_events]

    def span(t0: float) -> _Span:
        return _Span.of(t, t0, _next_event(times, t0, 0.0), 0.0)

    limit_time = _value(_time_where(t, limited, t[0], t[-1])) if i_max_A is not None else _missing("no i_max_A")
    chatter_share = _missing("a log's rows need not be the speed controller's samples")
    return {
        "scenario": log.source,
        "reference_steps": [_reference_step(t, t, speed, ref, limited, span(t0), b, a) for t0, b, a in ref_events],
        "load_steps": [],
        "faults": [],
        "run": {
            "t_end_s": float(t[-1]),
            "iae_rpm_s": _value(np.trapezoid(np.abs(ref - speed), t)),
            "current_limit_time_s": limit_time,
            "voltage_limit_time_s": _missing("a log has no voltage_limited signal"),
            "chatter_share": chatter_share,
        },
        "warnings": [],
    }


def _voltage_limit_time(result: "Result", t: _Vector) -> _Figure:
    if getattr(result, "voltage_limited", None) is None:
        return _missing("the trace has no voltage_limited signal")
    return _value(_time_where(t, at_voltage_limit(result), t[0], t[-1]))


def _fmt(figure: Mapping[str, Any], unit: str) -> str:
    return "n/a" if figure["value"] is None else f"{figure['value']:.4g} {unit}".rstrip()


def summary_lines(metrics: Mapping[str, Any]) -> list[str]:
    """A few lines of text summarising :func:`compute_metrics` (missing figures shown as n/a).

    The ``warnings`` come first (a chattering run, an unstable sampled loop when the caller
    added it), so that no run they name reads as a good one.
    """
    lines = list(metrics.get("warnings", []))
    for s in metrics["reference_steps"]:
        lines.append(
            f"reference step at {s['t_s']:g} s to {s['to_rpm']:g} rpm: overshoot {_fmt(s['overshoot_pct'], '%')}, "
            f"rise {_fmt(s['rise_time_s'], 's')}, settling {_fmt(s['settling_time_s'], 's')}, "
            f"steady-state error {_fmt(s['steady_state_error_rpm'], 'rpm')}, "
            f"at the current limit {_fmt(s['current_limit_time_s'], 's')}"
        )
    for s in metrics["faults"]:
        lines.append(
            f"fault {s['kind']} at {s['t_s']:g} s to {s['end_s']:g} s: speed deviation "
            f"{_fmt(s['speed_deviation_rpm'], 'rpm')} after {_fmt(s['deviation_time_s'], 's')}, recovery "
            f"{_fmt(s['recovery_time_s'], 's')} after its end, at the current limit "
            f"{_fmt(s['current_limit_time_s'], 's')}"
        )
    for s in metrics["load_steps"]:
        lines.append(
            f"load step at {s['t_s']:g} s, {s['from_Nm']:g} -> {s['to_Nm']:g} Nm: dip "
            f"{_fmt(s['speed_dip_rpm'], 'rpm')} after {_fmt(s['dip_time_s'], 's')}, "
            f"recovery {_fmt(s['recovery_time_s'], 's')}, "
            f"steady-state error {_fmt(s['steady_state_error_rpm'], 'rpm')}"
        )
    run = metrics["run"]
    voltage = run["voltage_limit_time_s"]["value"]
    if voltage:
        share = 100.0 * voltage / run["t_end_s"]
        lines.append(
            f"VOLTAGE LIMIT: at the inverter's range u_dc/sqrt(3) for {voltage:.4g} s "
            f"({share:.3g} % of the run): the currents do not follow their commands there"
        )
    return lines
