"""Figures of merit of a simulated run or a measured log: each reference step, load step and fault, and the run.

The figures of each event, measured in its window, are those of :mod:`pmsm2dof.sim.event_figures` (the events and
their windows: :mod:`pmsm2dof.sim.events`); they are those used to compare the controllers in the paper's section 4
(overshoot of Fig. 8, 12, tracking of Fig. 10, 13, load rejection of Fig. 14).

Whole run: ``iae_rpm_s`` and ``current_limit_time_s`` as for a step, ``voltage_limit_time_s``, the time
at the inverter's range ``u_dc / sqrt(3)`` (:func:`at_voltage_limit`; missing for a trace without
the ``voltage_limited`` signal), and ``chatter_share``, the share of the samples at which the
current command chatters (:func:`chatter`). A drive at its voltage limit no longer follows its
current commands: the speed loop's design (eq 3, 9) does not hold there. A run whose
``chatter_share`` exceeds :data:`CHATTER_SHARE_MAX` is a limit cycle, not a response: its
``warnings`` say so, first.

A log at the current rate (``simulation.log_rate = "current"``) is measured on all its rows (the
speed between the speed controller's samples too: a dip or a crossing between two samples is
seen where it happens); what is counted in the speed controller's samples is counted in the rows
at its sampling instants: the samples that tell a steady state
(:data:`~pmsm2dof.sim.event_figures.STEADY_SAMPLES_MIN`) and
the chatter of its command, which holds between them.

A figure that cannot be computed (no change at the step, the speed did not reach or did not
settle before the window ends) is ``{"value": None, "reason": "..."}``, never NaN; a computed one
is ``{"value": x}``. Speeds are in rpm, as in the scenario and the trace.
"""

import math
from collections.abc import Collection, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError, SimulationError
from .event_figures import (
    FAULT_FIGURES,
    LOAD_FIGURES,
    REFERENCE_FIGURES,
    fault_figures,
    figure,
    load_step,
    missing,
    reference_step,
    time_where,
)
from .events import (
    EventWindow,
    event_times,
    fault_ends,
    load_events,
    next_event,
    reference_events,
    speed_sample_rows,
    time_tolerance_s,
)
from .logs import Log

if TYPE_CHECKING:
    from .scenario import Scenario
    from .simulate import Result

_Vector = npt.NDArray[np.float64]
#: A figure of merit: ``{"value": x}`` or ``{"value": None, "reason": "..."}``.
_Figure = dict[str, Any]

#: Figures of the whole run.
RUN_FIGURES = ("iae_rpm_s", "current_limit_time_s", "voltage_limit_time_s", "chatter_share")
#: Second difference of the current command, relative to the current limit, at and above which a
#: sample chatters (:func:`chatter`).
CHATTER_D2 = 0.1
#: Largest share of chattering samples of a run that does not chatter (:func:`chatter`).
CHATTER_SHARE_MAX = 0.01
#: A command within this fraction of its limit is at the limit (:func:`at_current_limit`, :func:`at_voltage_limit`).
LIMIT_RTOL = 0.01


def _trace(result: "Result", name: str) -> _Vector:
    values = np.asarray(getattr(result, name), dtype=float)
    if values.shape != np.shape(result.t_s) or not np.all(np.isfinite(values)):
        raise SimulationError(f"result.{name} must be finite and as long as result.t_s")
    return values


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
        Arrays ``voltage_limited``, ``ud_V``, ``uq_V`` and ``u_dc_V`` (the last three all NaN in a
        drive's measured run, which has its firmware's flag alone: then the flag).

    Returns
    -------
    numpy.ndarray of float
        In [0, 1], one per sample.
    """
    share = _trace(result, "voltage_limited")
    if np.any((share < 0.0) | (share > 1.0)):
        raise SimulationError("result.voltage_limited must be a share in [0, 1]")
    if all(np.all(np.isnan(getattr(result, name))) for name in ("ud_V", "uq_V", "u_dc_V")):
        return share  # a drive's measured run: the firmware's flag alone (pmsm2dof.studies.drive.NOT_MEASURED)
    u_max = _trace(result, "u_dc_V") / math.sqrt(3.0)
    at_range = np.hypot(_trace(result, "ud_V"), _trace(result, "uq_V")) >= (1.0 - LIMIT_RTOL) * u_max
    return np.where(at_range, 1.0, share)


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
        return missing(
            f"the trace logs every {log_every}th speed-controller sample: a reversal from one sample to the "
            "next needs every sample (simulation.log_every = 1)"
        )
    if scenario.simulation.log_rate == "current" and per_speed % log_every != 0:
        return missing(
            f"the trace logs every {log_every}th current period, which does not divide the speed-controller "
            "period: a reversal from one sample to the next needs every sample (a simulation.log_every that "
            "divides speed_controller.Ts_s / current_loop.Ts_s)"
        )
    # the two samples from each event on, and the one before, step on purpose
    quiet = np.zeros(t.shape, bool)
    for x in times:
        k = int(np.searchsorted(t, x - tol))
        quiet[max(k - 1, 0) : k + 2] = True
    return figure(chatter(iq_ref, scenario.limits.i_max_A, quiet))


def _chatter_warning(figure: _Figure) -> list[str]:
    share = figure["value"]
    if share is None or share <= CHATTER_SHARE_MAX:
        return []
    return [
        f"CHATTER: the current command reverses by {100 * CHATTER_D2:g} % of the limit or more from one sample to "
        f"the next at {100 * share:.3g} % of the samples (more than {100 * CHATTER_SHARE_MAX:g} %): a limit cycle "
        "or an unstable sampled loop held by the limit, not a response the figures describe"
    ]


#: The figures of each part of :func:`compute_metrics`, in output order.
PART_FIGURES = {
    "reference_steps": REFERENCE_FIGURES,
    "load_steps": LOAD_FIGURES,
    "faults": FAULT_FIGURES,
    "run": RUN_FIGURES,
}


def compute_metrics(
    result: "Result | Log", i_max_A: float | None = None, figures: Mapping[str, Collection[str]] | None = None
) -> dict[str, Any]:
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
    figures : mapping, optional
        The figures to compute, by part: ``{part: names}`` with the parts and names of
        :data:`PART_FIGURES`; a part left out has none (its events keep their times and values).
        Default: every figure. A study that reads a few figures of many runs computes only those;
        each is the same number as in the full metrics.

    Returns
    -------
    dict
        JSON-serialisable: ``{"scenario", "reference_steps": [...], "load_steps": [...], "faults": [...],
        "run", "warnings"}``;
        each figure is ``{"value": x}`` or ``{"value": None, "reason": "..."}`` (see the module
        docstring for the definitions); ``warnings`` holds sentences on a run that the figures
        do not describe (a chattering command, when ``chatter_share`` is computed), empty for a run they do.

    Raises
    ------
    ConfigError
        ``figures`` names a part or a figure that :data:`PART_FIGURES` does not hold.
    """
    wanted = _wanted(figures)
    if isinstance(result, Log):
        return _log_metrics(result, i_max_A, wanted)
    t = np.asarray(result.t_s, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise SimulationError("result.t_s must hold at least two finite, increasing times")
    speed = _trace(result, "speed_rpm")
    ref = _trace(result, "speed_ref_rpm")
    limited = at_current_limit(result)
    scenario = result.scenario
    at_samples = speed_sample_rows(scenario, t.size)
    t_samples = t[at_samples]
    ref_events = reference_events(scenario)
    loads = load_events(scenario)
    times = event_times(scenario)
    tol = time_tolerance_s(scenario)

    def span(t0: float) -> EventWindow:
        return EventWindow.of(t, t0, next_event(times, t0, tol), tol)

    run_figures = wanted["run"]
    run: dict[str, Any] = {"t_end_s": float(t[-1])}
    if "iae_rpm_s" in run_figures:
        run["iae_rpm_s"] = figure(float(np.trapezoid(np.abs(ref - speed), t)))
    if "current_limit_time_s" in run_figures:
        run["current_limit_time_s"] = figure(time_where(t, limited, t[0], t[-1]))
    if "voltage_limit_time_s" in run_figures:
        run["voltage_limit_time_s"] = _voltage_limit_time(result, t)
    if "chatter_share" in run_figures:
        run["chatter_share"] = _chatter_figure(
            t_samples,
            _trace(result, "iq_ref_A")[at_samples],
            scenario,
            [*times, *fault_ends(scenario)],
            tol,
        )
    return {
        "scenario": scenario.name,
        "reference_steps": [
            reference_step(t, t_samples, speed, ref, limited, span(t0), b, a, wanted["reference_steps"])
            for t0, b, a in ref_events
        ],
        "load_steps": [
            load_step(t, t_samples, speed, ref, limited, span(t0), b, a, wanted["load_steps"]) for t0, b, a in loads
        ],
        "faults": [
            fault_figures(t, t_samples, speed, ref, limited, f, end, span(end), wanted["faults"])
            for f, end in zip(scenario.fault, fault_ends(scenario))
        ],
        "run": run,
        "warnings": _chatter_warning(run["chatter_share"]) if "chatter_share" in run else [],
    }


def _wanted(figures: Mapping[str, Collection[str]] | None) -> dict[str, Collection[str]]:
    """The figures of each part that ``compute_metrics(figures=...)`` asks for (every one by default)."""
    if figures is None:
        return dict(PART_FIGURES)
    valid = "; ".join(f"{part}: {', '.join(names)}" for part, names in PART_FIGURES.items())
    if not isinstance(figures, Mapping) or any(
        part not in PART_FIGURES or isinstance(names, str) or not set(names) <= set(PART_FIGURES[part])
        for part, names in figures.items()
    ):
        raise ConfigError("figures", figures, f"a mapping of parts to some of their figures ({valid})")
    return {part: figures.get(part, ()) for part in PART_FIGURES}


def _log_metrics(log: Log, i_max_A: float | None, wanted: Mapping[str, Collection[str]]) -> dict[str, Any]:
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

    def span(t0: float) -> EventWindow:
        return EventWindow.of(t, t0, next_event(times, t0, 0.0), 0.0)

    limit_time = figure(time_where(t, limited, t[0], t[-1])) if i_max_A is not None else missing("no i_max_A")
    run = {
        "t_end_s": float(t[-1]),
        "iae_rpm_s": figure(np.trapezoid(np.abs(ref - speed), t)),
        "current_limit_time_s": limit_time,
        "voltage_limit_time_s": missing("a log has no voltage_limited signal"),
        "chatter_share": missing("a log's rows need not be the speed controller's samples"),
    }
    return {
        "scenario": log.source,
        "reference_steps": [
            reference_step(t, t, speed, ref, limited, span(t0), b, a, wanted["reference_steps"])
            for t0, b, a in ref_events
        ],
        "load_steps": [],
        "faults": [],
        "run": {name: value for name, value in run.items() if name == "t_end_s" or name in wanted["run"]},
        "warnings": [],
    }


def _voltage_limit_time(result: "Result", t: _Vector) -> _Figure:
    if getattr(result, "voltage_limited", None) is None:
        return missing("the trace has no voltage_limited signal")
    return figure(time_where(t, at_voltage_limit(result), t[0], t[-1]))


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
