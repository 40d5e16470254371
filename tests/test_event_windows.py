"""Event windows: each figure is measured from its event to the last sample before the next one.

A small servo that is no preset (tests/oracles/small_servo.py: 20 kHz current loop, 2 kHz speed
loop) with two events close together, in every order: a load put on or taken off, and a
reference step or reversal. Truth comes from the trace itself, read here independently of
pmsm2dof.sim.metrics: the window is the samples from the event to the last one before the other
event (the engine applies an entry at the first sample at or after its time), the load dip the
largest speed error there in the direction the load pushes, relative to the reference the
trace shows in that window.
"""

import itertools

import numpy as np
import pytest

from oracles import small_servo
from pmsm2dof.sim.metrics import compute_metrics, summary_lines
from pmsm2dof.sim.simulate import simulate

T_FIRST = 0.15  # s: the load put on at 0 has been rejected by then
LOAD_NM = 0.1
EPS = 1e-9  # s: far below a sample period (5e-4 s), far above the rounding of sample times

LOADS = {"on": ((), LOAD_NM), "off": (((0.0, LOAD_NM),), 0.0)}
REFERENCES = {"step": 2000.0, "reversal": -3000.0}


def run(load_kind, ref_kind, load_first, gap_s):
    earlier, to_Nm = LOADS[load_kind]
    t_load, t_ref = (T_FIRST, T_FIRST + gap_s) if load_first else (T_FIRST + gap_s, T_FIRST)
    scenario = small_servo.scenario(
        reference=((0.0, 3000.0), (t_ref, REFERENCES[ref_kind])),
        load=(*earlier, (t_load, to_Nm)),
        t_end_s=T_FIRST + gap_s + 0.2,
        speed0_rpm=3000.0,
    )
    result = simulate(scenario)
    return result, compute_metrics(result), t_load, t_ref


def window(t, t0, t_next):
    """Indices of the samples of the window of an event at t0 whose next event is at t_next (None: none)."""
    inside = t >= t0 - EPS
    if t_next is not None:
        inside &= t < t_next - EPS
    return np.flatnonzero(inside)


@pytest.mark.parametrize(
    "load_kind, ref_kind, load_first, gap_s",
    list(itertools.product(("on", "off"), ("step", "reversal"), (True, False), (0.05, 0.005))),
)
def test_load_and_reference_events_in_any_order(load_kind, ref_kind, load_first, gap_s):
    result, m, t_load, t_ref = run(load_kind, ref_kind, load_first, gap_s)
    t, w, r = result.t_s, result.speed_rpm, result.speed_ref_rpm
    load = m["load_steps"][-1]
    ref = m["reference_steps"][-1]
    assert (load["t_s"], ref["t_s"]) == (t_load, t_ref)

    # each window ends at the last sample before the other event, or at the end of the trace
    k_load = window(t, t_load, t_ref if load_first else None)
    k_ref = window(t, t_ref, None if load_first else t_load)
    assert load["window_end_s"] == t[k_load[-1]]
    assert ref["window_end_s"] == t[k_ref[-1]]
    # inside a window the reference is what was commanded there (one value), never the next event's
    assert np.ptp(r[k_load]) == 0.0 and np.ptp(r[k_ref[1:]]) == 0.0

    # the load dip: the largest error in the direction the load pushes, over its window; none when
    # that error is largest at the step itself (a load taken off while a reversal is under way)
    sign = 1.0 if load["to_Nm"] > load["from_Nm"] else -1.0
    d = sign * (r[k_load] - w[k_load])
    if np.argmax(d) > 0:
        assert load["speed_dip_rpm"]["value"] == pytest.approx(np.max(d), rel=1e-9)
        assert load["dip_time_s"]["value"] == pytest.approx(t[k_load[np.argmax(d)]] - t_load, abs=EPS)
        # a tenth of the peak torque gives way by tens of rpm (more with a step's overshoot), never thousands
        assert 5.0 < load["speed_dip_rpm"]["value"] < (100.0 if load_first else 200.0)
    else:
        assert load["speed_dip_rpm"]["value"] is None
        assert "largest at the step itself" in load["speed_dip_rpm"]["reason"]

    # the reference step: overshoot from the speed at the step, over its window
    w0 = np.interp(t_ref, t, w)
    z = (w[k_ref] - w0) / (REFERENCES[ref_kind] - w0)
    if np.max(z) >= 1.0:
        assert ref["overshoot_pct"]["value"] == pytest.approx(100.0 * (np.max(z) - 1.0), rel=1e-6, abs=1e-9)
    else:
        assert ref["overshoot_pct"]["value"] is None

    # a window of 5 ms holds 10 samples, one in its last 10 %: no steady state can be told there
    short = load if load_first else ref
    if gap_s == 0.005:
        figure = short["recovery_time_s" if load_first else "settling_time_s"]
        assert figure["value"] is None and "too short" in figure["reason"]
    text = "\n".join(summary_lines(m))
    assert "6000 rpm" not in text and "-6000" not in text


def test_load_removed_just_before_a_reversal_reports_its_own_dip():
    """The reported case: a load removed 50 ms before a reversal was summarised as a 6000 rpm dip."""
    result, m, t_load, t_ref = run("off", "reversal", True, 0.05)
    t, w, r = result.t_s, result.speed_rpm, result.speed_ref_rpm
    k = window(t, t_load, t_ref)
    overspeed = np.max(w[k] - r[k])  # the load taken off: the speed rises above its reference
    load = m["load_steps"][-1]
    assert load["speed_dip_rpm"]["value"] == pytest.approx(overspeed, rel=1e-9)
    assert load["speed_dip_rpm"]["value"] < 100.0
    assert load["steady_state_error_rpm"]["value"] is None or abs(load["steady_state_error_rpm"]["value"]) < 1.0


def test_events_closer_than_a_sample_leave_an_empty_window():
    """Two events 0.2 ms apart at a 0.5 ms speed loop: no sample lies between them."""
    scenario = small_servo.scenario(
        reference=((0.0, 3000.0), (0.1502, 2000.0)), load=((0.15, LOAD_NM),), t_end_s=0.3, speed0_rpm=3000.0
    )
    load = compute_metrics(simulate(scenario))["load_steps"][0]
    for name in ("speed_dip_rpm", "recovery_time_s", "iae_rpm_s"):
        assert load[name]["value"] is None and "the window is empty" in load[name]["reason"]


def test_an_entry_that_changes_nothing_is_no_boundary():
    """A reference entry repeating the value before it leaves the load step's window running through it."""
    base = dict(load=((0.15, LOAD_NM),), t_end_s=0.4, speed0_rpm=3000.0)
    plain = compute_metrics(simulate(small_servo.scenario(reference=((0.0, 3000.0),), **base)))
    repeated = compute_metrics(simulate(small_servo.scenario(reference=((0.0, 3000.0), (0.16, 3000.0)), **base)))
    assert repeated["load_steps"][0]["window_end_s"] == plain["load_steps"][0]["window_end_s"]
    assert repeated["load_steps"][0]["recovery_time_s"] == plain["load_steps"][0]["recovery_time_s"]
    assert repeated["reference_steps"][1]["overshoot_pct"]["reason"] == "the reference does not change"


def test_tuner_zoom_ends_before_the_next_event():
    """The tuner's load-step zoom spans the load step's window: not the reversal 50 ms later."""
    from pmsm2dof.ui.tuner.experiment import Tuner

    scenario = small_servo.scenario(
        reference=((0.0, 3000.0), (0.3, -3000.0)), load=((0.25, LOAD_NM),), t_end_s=0.5, speed0_rpm=3000.0
    )
    page = Tuner(scenario).run({})
    detail = page["detail"]
    assert max(detail["t"]) < 0.3
    assert np.allclose(detail["speed_ref_rpm"], 3000.0, rtol=1e-12)
    # the dip the zoom shows is the one the table gives
    dip = max(np.asarray(detail["speed_ref_rpm"]) - np.asarray(detail["speed_rpm"]))
    row = next(r for r in page["metrics"] if r["key"] == "load_steps.0.speed_dip_rpm")
    assert row["value"] == pytest.approx(dip, rel=1e-9)
