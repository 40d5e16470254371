"""Step-response overshoot at any time scale (pmsm2dof.analysis.stepresponse).

Truth: the closed-form overshoot of the second-order system, the closed-form response of a
system with poles six decades apart (partial fractions by SciPy, peak by root finding), and
a sample-by-sample simulation.
"""

import math

import numpy as np
import pytest
from scipy import optimize, signal

from pmsm2dof.analysis.stepresponse import StepResponse


def second_order(wn, zeta):
    """x'' + 2 zeta wn x' + wn^2 x = wn^2 u: (A, b, c) with states (x, x'/wn)."""
    return np.array([[0.0, wn], [-wn, -2.0 * zeta * wn]]), np.array([0.0, wn]), np.array([1.0, 0.0])


@pytest.mark.slow
@pytest.mark.parametrize("wn", [1e-4, 1.0, 3e4])
@pytest.mark.parametrize("zeta", [0.02, 0.3, 0.7, 0.95])
def test_continuous_second_order_overshoot_is_the_closed_form(wn, zeta):
    over, reason = StepResponse.continuous(*second_order(wn, zeta)).overshoot_pct()
    assert reason == ""
    assert over == pytest.approx(100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2)), rel=1e-9)


@pytest.mark.parametrize("zeta", [1.0, 3.0])
def test_no_overshoot_without_oscillation(zeta):
    assert StepResponse.continuous(*second_order(2.0, zeta)).overshoot_pct() == (0.0, "")


def test_poles_six_decades_apart():
    # (s + z) p1 p2 / (z (s + p1)(s + p2)): the fast pole makes the peak, the slow one the tail
    z, p1, p2 = 0.5, 1.0, 1e6
    num, den = np.array([1.0, z]) * p1 * p2 / z, np.polymul([1.0, p1], [1.0, p2])
    # states: the two partial-fraction modes of G(s) = r1 / (s + p1) + r2 / (s + p2)
    residues, poles, _ = signal.residue(num, den)
    r1, r2 = residues[np.argsort(np.abs(poles))].real
    response = StepResponse.continuous(np.diag([-p1, -p2]), np.array([r1, r2]), np.array([1.0, 1.0]))
    # y(t) = r1 (1 - e^-p1 t) / p1 + r2 (1 - e^-p2 t) / p2, peak where y'(t) = 0
    t_peak = optimize.brentq(lambda t: r1 * math.exp(-p1 * t) + r2 * math.exp(-p2 * t), 1e-9, 1e-3, xtol=1e-20)
    y_peak = r1 * (1 - math.exp(-p1 * t_peak)) / p1 + r2 * (1 - math.exp(-p2 * t_peak)) / p2
    over, reason = response.overshoot_pct()
    assert reason == ""
    assert over == pytest.approx(100.0 * (y_peak - 1.0), rel=1e-9)


def test_late_peak_after_a_fast_pole_has_died():
    # the mean of a slow second-order response (peak after ~1000 s) and a first order at 1e3 rad/s
    zeta = 0.3
    slow_A, slow_b, slow_c = second_order(1e-3, zeta)
    A, b = np.zeros((3, 3)), np.append(slow_b, 1e3)
    A[:2, :2], A[2, 2] = slow_A, -1e3
    over, reason = StepResponse.continuous(A, b, np.append(slow_c, 1.0) / 2.0).overshoot_pct()
    assert reason == ""
    assert over == pytest.approx(50.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2)), rel=1e-9)


def test_discrete_overshoot_is_the_largest_sample():
    # a sampled lightly damped pair and a slow real pole: x[k+1] = A x[k] + b
    A = np.array([[0.95, 0.2, 0.0], [-0.2, 0.95, 0.0], [0.0, 0.0, 0.999]])
    b = np.array([0.05, 0.1, 0.001])
    c = np.array([1.0, 0.0, 0.2])
    x, y = np.zeros(3), []
    for _ in range(60000):
        y.append(c @ x)
        x = A @ x + b
    final = c @ np.linalg.solve(np.eye(3) - A, b)
    assert max(y) > 1.1 * final
    over, reason = StepResponse(A - np.eye(3), b, c).overshoot_pct()
    assert reason == ""
    assert over == pytest.approx(100.0 * (max(y) - final) / final, rel=1e-9)


def test_discrete_sampling_a_million_times_faster_than_the_loop_tends_to_the_continuous_form():
    zeta, wn, Ts = 0.3, 1.0, 1e-6
    A, b, c = second_order(wn, zeta)
    # forward-Euler increments of one period: E = A Ts, f = b Ts (first order in Ts)
    over, reason = StepResponse(A * Ts, b * Ts, c, dt_s=Ts).overshoot_pct()
    assert reason == ""
    assert over == pytest.approx(100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2)), abs=1e-3)


def test_unstable_loop_has_no_overshoot_and_says_why():
    over, reason = StepResponse.continuous(*second_order(1.0, -0.1)).overshoot_pct()
    assert math.isnan(over) and "not stable" in reason


def test_too_many_evaluations_is_reported_missing():
    # a mode at 1e3 rad/s damped by 1e-7 next to a pole at 1e-3 rad/s
    fast_A, fast_b, fast_c = second_order(1e3, 1e-7)
    A = np.zeros((3, 3))
    A[:2, :2], A[2, 2] = fast_A, -1e-3
    over, reason = StepResponse.continuous(A, np.append(fast_b, 1e-3), np.append(fast_c, 1.0)).overshoot_pct()
    assert math.isnan(over) and "evaluations" in reason
