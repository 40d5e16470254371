"""The figures show what matters: the torque panel at the drive's torques, the Pareto axes with ticks.

Truth: the torques the drive can apply, ``1.5 p psi_f i_max`` (0.354 Nm for the small servo of
tests/oracles/small_servo.py), against a controller output of thousands of Nm when the design
inertia is typed in the wrong unit (181 for 181 g cm^2); and the tick labels matplotlib draws.
"""

import math

import numpy as np

from oracles import small_servo
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.autotune import AutotuneResult, Candidate, Evaluation, Spec, pareto_front
from pmsm2dof.ui.plots.autotune import pareto_figure
from pmsm2dof.ui.plots.trace import trace_figure

T_MAX_NM = 1.5 * 8 * 3.075e-3 * small_servo.I_MAX_A


def torque_axes(fig):
    return next(ax for ax in fig.axes if ax.get_ylabel() == "torque [Nm]")


def test_torque_panel_is_scaled_to_the_limits_not_to_the_unsaturated_output():
    result = simulate(small_servo.scenario(load=((0.1, 0.1),), J_kgm2=181.0))
    assert np.max(np.abs(result.torque_unsat_Nm)) > 1000 * T_MAX_NM  # the output the panel must not follow
    ax = torque_axes(trace_figure(result))
    lo, hi = ax.get_ylim()
    assert -1.3 * T_MAX_NM <= lo < -T_MAX_NM and T_MAX_NM < hi <= 1.3 * T_MAX_NM
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert any(label.startswith("controller output u (clipped") for label in labels)


def test_torque_panel_keeps_the_output_when_it_stays_within_the_applied_torques():
    """A load step at speed, below the limit: the output is the applied torque, drawn whole."""
    scenario = small_servo.scenario(reference=((0.0, 3000.0),), load=((0.1, 0.1),), t_end_s=0.3, speed0_rpm=3000.0)
    result = simulate(scenario)
    ax = torque_axes(trace_figure(result))
    lo, hi = ax.get_ylim()
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert "controller output u" in labels
    assert lo <= np.min(result.torque_unsat_Nm) and np.max(result.torque_unsat_Nm) <= hi


def _evaluation(i, load_iae, tracking_iae, pm, feasible=True):
    worst = {"tracking_iae_rpm_s": tracking_iae, "load_iae_rpm_s_per_Nm": load_iae, "phase_margin_deg": pm}
    candidate = Candidate(100.0 + i, 1.0, 1.0, 0.01, "lowpass", "back_calculation")
    return Evaluation(candidate, "engine", worst, {}, (1.0,), (), "")


def visible_tick_labels(ax, axis):
    ax.figure.canvas.draw()
    lo, hi = sorted(ax.get_xlim() if axis == "x" else ax.get_ylim())
    ticks = ax.get_xticklabels(which="both") if axis == "x" else ax.get_yticklabels(which="both")
    return [t.get_text() for t in ticks if t.get_text() and lo <= (t.get_position()[0 if axis == "x" else 1]) <= hi]


def test_pareto_axes_carry_tick_labels_over_less_than_a_decade():
    """Tracking IAE from 87 to 95 rpm s holds no 1, 2 or 5 of a decade: a log axis would have no label."""
    evaluations = [_evaluation(i, 5.0 + 0.3 * i, 87.0 + i, 45.0 + i) for i in range(8)]
    result = AutotuneResult(
        scenario=small_servo.scenario(load=((0.1, 0.1),)),
        spec=Spec(),
        feasible=True,
        chosen=evaluations[0],
        binding=None,
        evaluations=tuple(evaluations),
        pareto=pareto_front(evaluations),
        runs=(),
        J_ratios_checked=(1.0,),
        wall_time_s=0.0,
    )
    ax = pareto_figure(result).axes[0]
    for axis in ("x", "y"):
        assert len(visible_tick_labels(ax, axis)) >= 2, axis
    # values spread over decades keep the log scale, still labelled
    wide = [_evaluation(i, 10.0 ** (i / 2), 10.0 ** (i / 3), 50.0) for i in range(8)]
    result = AutotuneResult(**{**result.__dict__, "evaluations": tuple(wide), "chosen": wide[0]})
    ax = pareto_figure(result).axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    for axis in ("x", "y"):
        assert len(visible_tick_labels(ax, axis)) >= 2, axis
    assert math.isfinite(ax.get_ylim()[1])
