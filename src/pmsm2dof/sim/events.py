"""The events of a scenario and the window in which the response to each one is measured.

For every entry of the scenario's ``reference`` and ``load`` schedules, the response is measured
in its *window*: from the entry's time ``t_s`` to the last logged sample before the next *event*
(or to the end of the trace). The events are the entries of either schedule that change the
reference or the load, in any order and at any spacing, and the starts of the faults. A sample
at the time of the next event (within the engine's time tolerance, ``csrc/sim/drive.c``) already
shows it: its reference is the new one, so that a load step removed 50 ms before a speed
reversal would otherwise count the reversal as its dip. An entry that repeats the value before
it changes no input of the loop, so the response of the event before goes on through it: it is
no boundary. A fault's window ends at the next schedule entry or fault after the fault's end (a
sensor_spike lasts one speed-controller period). The figures measured in the windows are those
of :mod:`pmsm2dof.sim.event_figures`.
"""

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from .scenario import Scenario

_Vector = npt.NDArray[np.float64]


def _schedule(entries: Sequence[tuple[float, float]]) -> list[tuple[float, float, float]]:
    """(t_s, value before, value after) of each entry ``(t_s, value)``; the value is 0 before the first entry."""
    before = 0.0
    events = []
    for t_s, value in entries:
        events.append((t_s, before, value))
        before = value
    return events


def reference_events(scenario: "Scenario") -> list[tuple[float, float, float]]:
    """:func:`_schedule` of the speed reference [rpm]."""
    return _schedule([(e.t_s, e.speed_rpm) for e in scenario.reference])


def load_events(scenario: "Scenario") -> list[tuple[float, float, float]]:
    """:func:`_schedule` of the load torque [Nm]."""
    return _schedule([(e.t_s, e.torque_Nm) for e in scenario.load])


def event_times(scenario: "Scenario") -> list[float]:
    """The events of a scenario, sorted: the entries of ``reference`` and ``load`` that change the value
    before them (0 before the first), and the start of each fault."""
    times = {f.t_s for f in scenario.fault}
    for events in (reference_events(scenario), load_events(scenario)):
        times.update(t0 for t0, before, after in events if after != before)
    return sorted(times)


def fault_ends(scenario: "Scenario") -> list[float]:
    """The end of each fault: a sensor_spike lasts one speed-controller period."""
    Ts_speed = scenario.speed_controller.Ts_s
    return [f.t_s + (Ts_speed if f.duration_s is None else f.duration_s) for f in scenario.fault]


def next_event(times: Sequence[float], t0: float, tol: float) -> float | None:
    later = [x for x in times if x > t0 + tol]
    return later[0] if later else None


def time_tolerance_s(scenario: "Scenario") -> float:
    """The engine's time tolerance: times closer than it are equal, so an entry within it of a sample
    acts at that sample (``P2D_SIM_T_TOL`` of ``csrc/sim/drive.c`` times the integration step)."""
    Ts_current = float(scenario.current_loop.Ts_s)
    step = Ts_current / max(1, math.ceil(Ts_current / scenario.simulation.dt_s * (1.0 - 1e-9)))
    return float(1e-6 * step)


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


@dataclasses.dataclass(frozen=True)
class EventWindow:
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
    def of(cls, t: _Vector, t0: float, t_next: float | None, tol: float) -> "EventWindow":
        """The window of the event at ``t0`` in the increasing sample times ``t``."""
        first = int(np.searchsorted(t, t0 + tol, side="right"))  # the first sample after t0
        end = t.size if t_next is None else int(np.searchsorted(t, t_next - tol, side="left"))
        return cls(t0, t_next, float(t[end - 1]) if end > first else None, tol)

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
        """The window's sample times after ``t0`` (``t0`` itself first, the signals interpolated there) and the
        signals at them."""
        assert self.t_end is not None
        first = int(np.searchsorted(t, self.t0 + self.tol, side="right"))
        end = int(np.searchsorted(t, self.t_end, side="right"))
        tw = np.concatenate(([self.t0], t[first:end]))
        return tw, [np.concatenate(([np.interp(self.t0, t, s)], s[first:end])) for s in signals]
