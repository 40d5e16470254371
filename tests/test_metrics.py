"""Metrics on synthetic traces whose figures are known analytically.

Truth: closed-form step responses (first order, second order, difference of exponentials)
and root finding (scipy.optimize.brentq) on the closed forms, never the sampled algorithm.
"""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import brentq

from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim.event_figures import time_where
from pmsm2dof.sim.metrics import compute_metrics, summary_lines
from pmsm2dof.sim.scenario import load_scenario

DT = 1e-3


def fake_result(t, speed, ref, reference, load=(), saturated=None, iq_ref=None):
    """A Result honouring the contract, with the given traces and schedules (id_ref = 0, iq_ref = 0 unless given)."""
    scenario = load_scenario("paper-condition-2").with_overrides(
        {
            "simulation.t_end_s": float(t[-1] + DT),
            "reference": [{"t_s": float(a), "speed_rpm": float(b)} for a, b in reference],
            "load": [{"t_s": float(a), "torque_Nm": float(b)} for a, b in load],
        }
    )
    if saturated is None:
        saturated = np.zeros(t.shape, dtype=bool)
    if iq_ref is None:
        iq_ref = np.zeros_like(t)
    return SimpleNamespace(
        t_s=t,
        speed_rpm=speed,
        speed_ref_rpm=ref,
        saturated=saturated,
        id_ref_A=np.zeros_like(t),
        iq_ref_A=iq_ref,
        scenario=scenario,
    )


def step_ref(t, steps):
    """The reference of a list of (t_s, speed_rpm) steps, 0 before the first."""
    r = np.zeros_like(t)
    for t0, value in steps:
        r[t >= t0] = value
    return r


def first_order(t, t0, y0, y1, tau):
    return np.where(t < t0, y0, y1 + (y0 - y1) * np.exp(-np.clip(t - t0, 0, None) / tau))


def second_order_unit(t, zeta, wn):
    wd = wn * math.sqrt(1 - zeta**2)
    return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))


@pytest.mark.parametrize("y0, y1", [(0.0, 500.0), (500.0, 200.0)])
def test_first_order_step(y0, y1):
    """Rise time ln(9) tau, 2 % settling ln(50) tau, no overshoot, IAE |D| tau (1 - exp(-T/tau))."""
    tau, t0, T = 0.8, 1.0, 9.0
    t = np.arange(0.0, t0 + T + DT / 2, DT)
    steps = [(0.0, y0), (t0, y1)]
    speed = first_order(t, t0, y0, y1, tau)
    m = compute_metrics(fake_result(t, speed, step_ref(t, steps), steps))
    s = m["reference_steps"][1]
    assert s["t_s"] == t0 and s["from_rpm"] == y0 and s["to_rpm"] == y1
    assert s["rise_time_s"]["value"] == pytest.approx(math.log(9) * tau, abs=1e-5)
    assert s["settling_time_s"]["value"] == pytest.approx(math.log(50) * tau, abs=1e-5)
    assert s["overshoot_pct"]["value"] == 0.0
    D = abs(y1 - y0)
    assert s["iae_rpm_s"]["value"] == pytest.approx(D * tau * (1 - math.exp(-T / tau)), rel=1e-5)
    # mean of the error over the last 10 % of the window, in closed form
    a, b = 0.9 * T, T
    mean_err = (y1 - y0) * tau / (b - a) * (math.exp(-a / tau) - math.exp(-b / tau))
    assert s["steady_state_error_rpm"]["value"] == pytest.approx(mean_err, rel=1e-4)
    # the first entry (0 -> y0 at t = 0) is a step only if y0 != 0 and the speed starts elsewhere
    first = m["reference_steps"][0]
    assert first["window_end_s"] == t[t < t0][-1]  # the last sample before the next step
    if y0 == 0.0:
        assert first["rise_time_s"] == {"value": None, "reason": "the reference does not change"}
    else:
        assert "already at the new reference" in first["rise_time_s"]["reason"]


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7])
def test_second_order_step(zeta):
    """Overshoot exp(-pi zeta / sqrt(1 - zeta^2)); rise and settling from the closed form by brentq."""
    wn, A, t0 = 3.0, 300.0, 0.5
    t = np.arange(0.0, 12.0, DT)
    steps = [(t0, A)]
    speed = A * np.where(t < t0, 0.0, second_order_unit(np.clip(t - t0, 0, None), zeta, wn))
    s = compute_metrics(fake_result(t, speed, step_ref(t, steps), steps))["reference_steps"][0]

    overshoot = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    assert s["overshoot_pct"]["value"] == pytest.approx(overshoot, rel=1e-5)

    wd = wn * math.sqrt(1 - zeta**2)
    y = lambda x: second_order_unit(x, zeta, wn)  # noqa: E731
    t_peak = math.pi / wd
    rise = brentq(lambda x: y(x) - 0.9, 0, t_peak) - brentq(lambda x: y(x) - 0.1, 0, t_peak)
    assert s["rise_time_s"]["value"] == pytest.approx(rise, abs=1e-5)

    # |y - 1| has its extrema exp(-zeta wn k pi / wd) at k pi / wd: the last one above 2 % bounds
    # the final band crossing, found by brentq on the closed form.
    k = math.floor(math.log(1 / 0.02) * wd / (zeta * wn * math.pi))
    lo, hi = k * math.pi / wd, (k + 1) * math.pi / wd
    settle = brentq(lambda x: abs(y(x) - 1) - 0.02, lo, hi)
    assert s["settling_time_s"]["value"] == pytest.approx(settle, abs=1e-5)


def test_load_step_difference_of_exponentials():
    """Speed error D (exp(-t/t1) - exp(-t/t2)): peak at ln(t1/t2) t1 t2 / (t1 - t2), recovery by brentq."""
    r, D, t1, t2, t0 = 500.0, 40.0, 1.5, 0.3, 2.0
    t = np.arange(0.0, 14.0, DT)
    x = np.clip(t - t0, 0, None)
    err = D * (np.exp(-x / t1) - np.exp(-x / t2))
    res = fake_result(t, r - err, np.full_like(t, r), [(0.0, r)], load=[(t0, 8.0)])
    s = compute_metrics(res)["load_steps"][0]
    assert s["from_Nm"] == 0.0 and s["to_Nm"] == 8.0

    t_peak = math.log(t1 / t2) * t1 * t2 / (t1 - t2)
    e = lambda x: D * (math.exp(-x / t1) - math.exp(-x / t2))  # noqa: E731
    assert s["dip_time_s"]["value"] == pytest.approx(t_peak, abs=DT)
    assert s["speed_dip_rpm"]["value"] == pytest.approx(e(t_peak), rel=1e-6)
    recovery = brentq(lambda x: e(x) - 0.02 * e(t_peak), t_peak, 100.0)
    assert s["recovery_time_s"]["value"] == pytest.approx(recovery, abs=1e-4)
    T = t[-1] - t0
    iae = D * (t1 * (1 - math.exp(-T / t1)) - t2 * (1 - math.exp(-T / t2)))
    assert s["iae_rpm_s"]["value"] == pytest.approx(iae, rel=1e-5)


def test_load_decrease_counts_the_speed_rise_as_the_dip():
    """A load removed pushes the speed up: the dip is measured in that direction."""
    r, D, tau, t0 = 300.0, 25.0, 0.5, 1.0
    t = np.arange(0.0, 8.0, DT)
    x = np.clip(t - t0, 0, None)
    rise = D * x / tau * np.exp(1 - x / tau)  # peak D at x = tau
    res = fake_result(t, r + rise, np.full_like(t, r), [(0.0, r)], load=[(0.2, 5.0), (t0, 1.0)])
    s = compute_metrics(res)["load_steps"][1]
    assert s["speed_dip_rpm"]["value"] == pytest.approx(D, rel=1e-6)
    assert s["dip_time_s"]["value"] == pytest.approx(tau, abs=DT)


def test_current_limit_time_split_by_windows():
    """The flag holds from its sample to the next: 1.0 s before the load step at 2 s, 0.5 s after."""
    t = np.arange(0.0, 5.0, DT)
    sat = (t >= 1.0 - DT / 2) & (t < 2.5 - DT / 2)
    res = fake_result(
        t, np.full_like(t, 100.0), np.full_like(t, 100.0), [(0.0, 100.0)], load=[(2.0, 1.0)], saturated=sat
    )
    m = compute_metrics(res)
    assert m["reference_steps"][0]["current_limit_time_s"]["value"] == pytest.approx(1.0, abs=1e-9)
    assert m["load_steps"][0]["current_limit_time_s"]["value"] == pytest.approx(0.5, abs=1e-9)
    assert m["run"]["current_limit_time_s"]["value"] == pytest.approx(1.5, abs=1e-9)


def test_current_limit_time_follows_the_command_through_a_chattering_flag():
    """From 1 s to 3 s the command holds within 0.05 % of i_max while the flag toggles every sample, except
    for one sample at 2 s where it dips 5 % below: 2 s at the limit minus that one sample."""
    t = np.arange(0.0, 5.0, DT)
    res = fake_result(t, np.full_like(t, 100.0), np.full_like(t, 100.0), [(0.0, 100.0)])
    i_max = res.scenario.data["limits"]["i_max_A"]
    k = np.arange(t.size)
    holding = (t >= 1.0 - DT / 2) & (t < 3.0 - DT / 2)
    res.saturated = holding & (k % 2 == 0)
    res.iq_ref_A = np.where(holding, np.where(res.saturated, i_max, (1 - 5e-4) * i_max), 0.5 * i_max)
    dip = int(np.argmin(np.abs(t - 2.0))) | 1  # an odd sample: not flagged
    res.iq_ref_A[dip] = 0.95 * i_max
    m = compute_metrics(res)
    assert np.sum(res.saturated) * DT == pytest.approx(1.0, abs=1e-9)  # the flag alone says half of it
    assert m["run"]["current_limit_time_s"]["value"] == pytest.approx(2.0 - DT, abs=1e-9)
    # the command's direction does not matter: a braking (negative) command at the limit counts the same
    res.iq_ref_A = -res.iq_ref_A
    assert compute_metrics(res)["run"]["current_limit_time_s"]["value"] == pytest.approx(2.0 - DT, abs=1e-9)


def test_voltage_limit_time_counts_a_sample_whose_voltage_holds_at_the_range():
    """From 1 s to 3 s the applied voltage holds within 0.5 % of u_dc/sqrt(3) while the range cuts only some
    current periods of each sample (share 1 or 0.3), except one sample at 2 s whose voltage is 10 % below it
    (share 0); at 4 s one sample with 40 % of its periods cut before the voltage fell: 2 s - DT + 0.4 DT."""
    t = np.arange(0.0, 5.0, DT)
    res = fake_result(t, np.full_like(t, 100.0), np.full_like(t, 100.0), [(0.0, 100.0)])
    res.u_dc_V = np.full_like(t, 540.0)
    u_max = 540.0 / math.sqrt(3.0)
    holding = (t >= 1.0 - DT / 2) & (t < 3.0 - DT / 2)
    u = np.where(holding, 0.995 * u_max, 0.5 * u_max)
    share = np.where(holding, np.where(np.arange(t.size) % 2 == 0, 1.0, 0.3), 0.0)
    dip = int(np.argmin(np.abs(t - 2.0)))
    u[dip], share[dip] = 0.9 * u_max, 0.0
    share[int(np.argmin(np.abs(t - 4.0)))] = 0.4
    res.ud_V, res.uq_V, res.voltage_limited = -0.6 * u, 0.8 * u, share
    m = compute_metrics(res)
    assert np.sum(share[:-1]) * DT < 1.4  # the cut periods alone say 1.3 s of the 2 s
    assert m["run"]["voltage_limit_time_s"]["value"] == pytest.approx(2.0 - DT + 0.4 * DT, abs=1e-9)


def test_figures_that_cannot_be_computed_are_missing_with_a_reason():
    t = np.arange(0.0, 10.0, DT)
    # a sustained oscillation around the reference never settles
    steps = [(0.0, 100.0)]
    ringing = 100.0 * (1 - np.cos(3.0 * t))
    m = compute_metrics(fake_result(t, ringing, step_ref(t, steps), steps))
    s = m["reference_steps"][0]
    assert s["settling_time_s"]["value"] is None and "did not settle" in s["settling_time_s"]["reason"]
    assert s["steady_state_error_rpm"]["value"] is None and "still changing" in s["steady_state_error_rpm"]["reason"]
    assert s["overshoot_pct"]["value"] == pytest.approx(100.0, rel=1e-4)

    # a response inside the 2 % band but still converging has settled, yet has no steady state
    steps = [(0.0, 500.0)]
    converging = first_order(t, 0.0, 0.0, 500.0, 2.0)  # 500 exp(-10 / 2) = 3.4 rpm left at the end
    s = compute_metrics(fake_result(t, converging, step_ref(t, steps), steps))["reference_steps"][0]
    assert s["settling_time_s"]["value"] == pytest.approx(2.0 * math.log(50), abs=1e-5)
    assert s["steady_state_error_rpm"]["value"] is None
    assert "still changing" in s["steady_state_error_rpm"]["reason"]

    # a response that enters the band only in the last 10 % of its window has not shown it settled
    steps = [(0.0, 500.0)]
    late = first_order(t, 0.0, 0.0, 500.0, 0.95 * t[-1] / math.log(50))
    s = compute_metrics(fake_result(t, late, step_ref(t, steps), steps))["reference_steps"][0]
    assert s["settling_time_s"]["value"] is None and "last 10 %" in s["settling_time_s"]["reason"]
    assert s["rise_time_s"]["value"] is not None

    # a slow response cut short by the next step never reaches 90 % nor the reference
    steps = [(0.0, 100.0), (1.0, 50.0)]
    slow = first_order(t, 0.0, 0.0, 100.0, 5.0)
    s = compute_metrics(fake_result(t, slow, step_ref(t, steps), steps))["reference_steps"][0]
    assert s["window_end_s"] == t[t < 1.0][-1]
    for name in ("rise_time_s", "settling_time_s", "overshoot_pct"):
        assert s[name]["value"] is None and "before 0.999 s" in s[name]["reason"]

    # a load entry that does not change the torque
    res = fake_result(t, np.full_like(t, 10.0), np.full_like(t, 10.0), [(0.0, 10.0)], load=[(1.0, 0.0)])
    s = compute_metrics(res)["load_steps"][0]
    assert s["speed_dip_rpm"] == {"value": None, "reason": "the load torque does not change"}
    assert s["iae_rpm_s"]["value"] == 0.0


def test_json_serialisable_without_nan():
    t = np.arange(0.0, 6.0, DT)
    steps = [(0.0, 100.0), (3.0, 100.0)]
    speed = first_order(t, 0.0, 0.0, 100.0, 2.0)
    m = compute_metrics(fake_result(t, speed, step_ref(t, steps), steps, load=[(2.0, 3.0)]))
    text = json.dumps(m, allow_nan=False)
    assert json.loads(text) == m
    assert len(summary_lines(m)) == 3
    assert "n/a" in summary_lines(m)[1]


def test_non_finite_trace_is_an_error():
    t = np.arange(0.0, 1.0, DT)
    speed = np.zeros_like(t)
    speed[10] = np.nan
    with pytest.raises(SimulationError, match="speed_rpm"):
        compute_metrics(fake_result(t, speed, np.zeros_like(t), [(0.0, 1.0)]))


def test_time_where_is_the_overlap_of_each_sample_interval_with_the_window():
    """Sample k holds over [t[k], t[k+1]): the time is the sum of each interval's overlap with [t0, t1]
    times its mask (a flag or a share), summed here interval by interval; windows beyond the trace's
    ends, on its samples, empty and reversed included."""
    rng = np.random.default_rng(7)
    for case in range(300):
        n = int(rng.integers(2, 400))
        t = np.cumsum(rng.uniform(1e-4, 2e-3, n)) - 0.1
        mask = rng.random(n) < 0.5 if case % 2 else rng.random(n)
        ends = [t[0] - 1.0, t[0], t[int(rng.integers(n))], float(rng.uniform(t[0], t[-1])), t[-1], t[-1] + 1.0]
        t0, t1 = ends[int(rng.integers(6))], ends[int(rng.integers(6))]
        overlap = [max(0.0, min(t[k + 1], t1) - max(t[k], t0)) * float(mask[k]) for k in range(n - 1)]
        assert time_where(t, mask, t0, t1) == pytest.approx(math.fsum(overlap), rel=1e-12, abs=1e-15)


def test_a_subset_of_the_figures_is_each_the_same_number_as_in_the_full_metrics():
    """``figures`` computes the figures asked for alone, each equal to the full computation's (bit for bit)."""
    t = np.arange(0.0, 9.0, DT)
    steps = [(0.0, 500.0), (6.0, 200.0)]
    speed = first_order(t, 0.0, 0.0, 500.0, 0.4) - 8.0 * np.clip(t - 3.0, 0, None) * np.exp(-np.clip(t - 3.0, 0, None))
    speed = np.where(t >= 6.0, first_order(t, 6.0, speed[int(6.0 / DT) - 1], 200.0, 0.3), speed)
    iq = np.where(t < 0.5, 1.0, 0.2) * 100.0
    res = fake_result(t, speed, step_ref(t, steps), steps, load=[(3.0, 4.0)], iq_ref=iq)
    full = compute_metrics(res)
    subsets = [
        {"reference_steps": ("settling_time_s", "iae_rpm_s"), "run": ("chatter_share",)},
        {"load_steps": ("recovery_time_s", "current_limit_time_s"), "faults": ()},
        {"reference_steps": ("rise_time_s", "steady_state_error_rpm", "overshoot_pct")},
        {"run": ("voltage_limit_time_s", "iae_rpm_s")},
        {},
    ]
    for asked in subsets:
        part = compute_metrics(res, figures=asked)
        for name in ("reference_steps", "load_steps"):
            for got, want in zip(part[name], full[name], strict=True):
                figures = set(asked.get(name, ()))
                assert {k for k, v in got.items() if isinstance(v, dict)} == figures
                assert got == {k: v for k, v in want.items() if not isinstance(v, dict) or k in figures}
        assert set(part["run"]) == {"t_end_s", *asked.get("run", ())}
        assert part["run"] == {k: v for k, v in full["run"].items() if k in part["run"]}


@pytest.mark.parametrize(
    "figures",
    [{"steps": ("iae_rpm_s",)}, {"reference_steps": ("speed_dip_rpm",)}, {"run": "chatter_share"}, ["run"]],
)
def test_a_subset_of_figures_that_does_not_exist_is_refused_naming_it(figures):
    t = np.arange(0.0, 1.0, DT)
    with pytest.raises(ConfigError, match="figures"):
        compute_metrics(fake_result(t, np.zeros_like(t), np.zeros_like(t), [(0.0, 1.0)]), figures=figures)
