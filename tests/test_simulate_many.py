"""Lockstep runs of the engine (simulate_many, p2d_sim_run_many) against lone runs (simulate).

The truth is the lone run of each scenario: every signal of every trace must be equal to the
bit, whatever the group a scenario runs in (full groups, a partial one, drives that stop, loads
whose breakpoints fall inside a period of one drive only, every drive-train and current-loop
model, the sensors, the computation delay, the voltage limit).
"""

import numpy as np
import pytest

from pmsm2dof import simulate, simulate_many
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim import simulate as simulate_module
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Simulation


def short(**overrides):
    """paper-condition-2 over 1.5 s (reference steps at 0 and 1 s, a load step at 0.7 s) with overrides."""
    base = load_scenario("paper-condition-2").with_overrides(
        {
            "simulation.t_end_s": 1.5,
            "reference": [{"t_s": 0.0, "speed_rpm": 500.0}, {"t_s": 1.0, "speed_rpm": 200.0}],
            "load": [{"t_s": 0.7, "torque_Nm": 8.0}],
        }
    )
    return base.with_overrides(overrides)


def alone(scenario):
    """The Result of a lone run, or the SimulationError that stopped it."""
    try:
        return simulate(scenario)
    except SimulationError as exc:
        return exc


def assert_same(many, lone):
    assert len(many) == len(lone)
    for a, b in zip(many, lone):
        assert type(a) is type(b)
        if isinstance(b, SimulationError):
            assert str(a) == str(b)
            continue
        for name in b.signals:
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), name


TWO_MASS = {
    "mechanics.model": "two_mass",
    "motor.J_kgm2": 0.1,
    "mechanics.J_load_kgm2": 0.3,
    "mechanics.stiffness_Nm_per_rad": 3000.0,
    "mechanics.damping_Nms_per_rad": 0.5,
}
SENSORS = {
    "speed_sensor.model": "encoder",
    "speed_sensor.counts_per_rev": 4096,
    "speed_sensor.estimator": "pll",
    "speed_sensor.bandwidth_radps": 300.0,
    "speed_sensor.delay_s": 2.5e-4,
    "speed_sensor.noise_rpm_rms": 0.5,
    "current_measurement.offset_a_A": 0.05,
    "current_measurement.noise_A_rms": 0.02,
}


@pytest.mark.parametrize(
    "common",
    [
        {},
        {"inverter.computation_delay": True},
        {"current_loop.model": "first_order"},
        {"motor.T_coulomb_Nm": 0.3, "motor.B_Nms": 0.01, "simulation.dt_s": 5e-5},
        {"motor.Ld_H": 0.006, "motor.Lq_H": 0.012},
        {"limits.u_dc_V": 60.0, "inverter.computation_delay": True},
        TWO_MASS | {"mechanics.backlash_rad": 0.002, "mechanics.feedback": "load"},
        SENSORS,
    ],
    ids=["dq_pi", "delay", "first_order", "friction-substeps", "salient", "voltage-limit", "two-mass", "sensors"],
)
def test_lockstep_traces_equal_lone_runs_to_the_bit(common):
    """Six drives of one shape: a full group and a partial one; inertia, gains and load differ."""
    scenarios = [
        short(**common | {"motor.J_kgm2": common.get("motor.J_kgm2", 0.4) * (0.5 + 0.3 * i)})
        .with_overrides({"speed_controller.alpha_radps": 0.3 + 0.2 * i})
        .with_overrides({"load": [{"t_s": 0.7 + 0.01 * i, "torque_Nm": 4.0 + i}]})
        for i in range(6)
    ]
    assert_same(simulate_many(scenarios), [alone(s) for s in scenarios])


def test_drives_that_stop_leave_the_group_and_the_others_run_on():
    """An overspeed and an overcurrent inside one group, a load ramp whose corners fall inside the periods of one
    drive only (its periods split there), in the order given."""
    scenarios = [
        short(),
        short(load=[{"t_s": 0.1, "torque_Nm": 40.0}], **{"motor.J_kgm2": 0.01}),  # runs away backwards
        short(load=[{"t_s": 0.31234, "torque_Nm": 5.0, "ramp_s": 0.200017}]),
        short(**{"limits.i_max_A": 500.0, "speed_controller.alpha_radps": 50.0}),
        short(**{"speed_controller.alpha_radps": 2.0}),
    ]
    many = simulate_many(scenarios)
    lone = [alone(s) for s in scenarios]
    assert_same(many, lone)
    stops = [str(r) for r in many if isinstance(r, SimulationError)]
    assert any("twice the no-load speed" in s for s in stops), stops


def test_scenarios_of_different_shapes_group_among_themselves():
    scenarios = [
        short(),
        short(**{"current_loop.Ts_s": 5e-5}),
        short(**{"simulation.t_end_s": 1.2}),
        short(**{"motor.J_kgm2": 0.3}),
        short(**{"current_loop.model": "first_order"}),
        short(**{"simulation.log_every": 3}),
    ]
    assert_same(simulate_many(scenarios), [alone(s) for s in scenarios])
    assert simulate_many([]) == []


def test_rejects_what_is_no_scenario_and_bounds_the_logs(monkeypatch):
    with pytest.raises(ConfigError, match="scenarios"):
        simulate_many([short(), short().data])
    monkeypatch.setattr(simulate_module, "LOG_BYTES_MAX", 2 * 1501 * lib.P2D_LOG_COUNT * 8 - 1)
    with pytest.raises(ConfigError, match="smaller groups"):
        simulate_many([short(), short()])


def test_run_many_checks_shapes_and_log_room_before_running():
    runs = [Simulation(short()), Simulation(short())]
    other = Simulation(short(**{"simulation.dt_s": 5e-5}))
    assert lib.p2d_sim_lockstep(runs[0].sim, runs[1].sim) and not lib.p2d_sim_lockstep(runs[0].sim, other.sim)
    group = runs + [other]
    sims = ffi.new("p2d_sim_t *[]", [r.sim for r in group])
    logs = ffi.new("double *[]", [r._log_ptr for r in group])
    rows = ffi.new("uint64_t[]", [r.log.shape[1] for r in group])
    assert lib.p2d_sim_run_many(sims, 3, runs[0].n_samples, logs, rows) == lib.P2D_SIM_ERR_LOCKSTEP
    rows[1] -= 1
    assert lib.p2d_sim_run_many(sims, 2, runs[0].n_samples, logs, rows) == lib.P2D_SIM_ERR_LOG_FULL
    assert all(r.sim.n_speed == 0 and r.sim.n_rows == 0 for r in group)  # nothing ran
    rows[1] += 1
    assert lib.p2d_sim_run_many(sims, 2, runs[0].n_samples, logs, rows) == lib.P2D_SIM_OK
    assert np.array_equal(runs[0].log, runs[1].log) and runs[0].sim.n_rows == rows[0]


def baseline_isa_logs(scenarios):
    """The logs of ``scenarios`` through the engine's baseline copy of its loop (p2d_sim_t.fma false): each
    alone (p2d_sim_run), then all in lockstep groups (p2d_sim_run_many)."""
    lone, grouped = [], [Simulation(s) for s in scenarios]
    for scenario, run in zip(scenarios, grouped):
        single = Simulation(scenario)
        single.sim.fma = run.sim.fma = False
        status = lib.p2d_sim_run(single.sim, single.n_samples, single._log_ptr, single.log.shape[1])
        lone.append((status, single.log[:, : single.sim.n_rows].copy()))
    for start in range(0, len(grouped), lib.P2D_SIM_LANES):
        group = grouped[start : start + lib.P2D_SIM_LANES]
        sims = ffi.new("p2d_sim_t *[]", [r.sim for r in group])
        logs = ffi.new("double *[]", [r._log_ptr for r in group])
        rows = ffi.new("uint64_t[]", [r.log.shape[1] for r in group])
        assert lib.p2d_sim_run_many(sims, len(group), group[0].n_samples, logs, rows) == lib.P2D_SIM_OK
    return lone, [(r.sim.status, r.log[:, : r.sim.n_rows].copy()) for r in grouped]


@pytest.mark.parametrize(
    "common",
    [
        {},
        {"inverter.computation_delay": True},
        {"current_loop.model": "first_order"},
        {"motor.T_coulomb_Nm": 0.3, "motor.B_Nms": 0.01, "simulation.dt_s": 5e-5},
        {"motor.Ld_H": 0.006, "motor.Lq_H": 0.012},
        {"limits.u_dc_V": 60.0, "inverter.computation_delay": True},
        TWO_MASS | {"mechanics.backlash_rad": 0.002, "mechanics.feedback": "load"},
        SENSORS,
    ],
    ids=["dq_pi", "delay", "first_order", "friction-substeps", "salient", "voltage-limit", "two-mass", "sensors"],
)
def test_baseline_copy_of_the_loop_equals_the_fma_copy_to_the_bit(common):
    """On an x86-64 CPU with FMA the engine runs a copy of its loop compiled for it (the controllers' fmaf as
    one instruction, the plant in AVX form); the copy for the baseline ISA, which a CPU without FMA runs (and
    fmaf through libm), gives the same logs to the bit, alone and in lockstep, stops included."""
    scenarios = [
        short(**common | {"motor.J_kgm2": common.get("motor.J_kgm2", 0.4) * (0.5 + 0.3 * i)}).with_overrides(
            {"speed_controller.alpha_radps": 0.3 + 0.2 * i}
        )
        for i in range(5)
    ]
    reference = []
    for scenario in scenarios:
        run = Simulation(scenario)
        status = lib.p2d_sim_run(run.sim, run.n_samples, run._log_ptr, run.log.shape[1])
        reference.append((status, run.log[:, : run.sim.n_rows].copy()))
    for logs in baseline_isa_logs(scenarios):
        for (status, log), (status_ref, log_ref) in zip(logs, reference):
            assert status == status_ref and log.tobytes() == log_ref.tobytes()
