"""simulate() and Result: sampling and logging, schedules, initial state, files, and errors."""

import math
import tomllib

import numpy as np
import pandas as pd
import pytest
import scipy.io

import pmsm2dof
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import Scenario, load_scenario
from pmsm2dof.sim.scenario_tables import ARRAYS, TABLES, ReferenceEntry
from pmsm2dof.sim.simulate import Result, Simulation, simulate

RPM_PER_RADPS = 30.0 / math.pi


def paper2(**overrides):
    return load_scenario("paper-condition-2").with_overrides(overrides)


@pytest.fixture(scope="module")
def short_run():
    return simulate(paper2(**{"simulation.t_end_s": 10.2, "load": [{"t_s": 7.0, "torque_Nm": 8.0}]}))


def test_result_holds_every_signal_at_the_speed_sampling_instants(short_run):
    r = short_run
    assert pmsm2dof.simulate is simulate and isinstance(r, Result)
    n = 10201  # samples at 0, 1 ms, ..., 10.2 s
    for name in Result.signals:
        a = getattr(r, name)
        assert a.shape == (n,), name
        assert np.all(np.isfinite(a)), name
    assert r.saturated.dtype == bool
    np.testing.assert_allclose(r.t_s, np.arange(n) * 1e-3, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.speed_rpm, r.w_m_radps * RPM_PER_RADPS, rtol=1e-15)
    assert r.speed_ref_rpm[0] == pytest.approx(500.0, rel=1e-12)
    assert r.speed_ref_rpm[-1] == pytest.approx(200.0, rel=1e-12)
    assert r.wall_time_s > 0
    assert list(r.to_dataframe().columns) == list(Result.signals)


def test_log_every_decimates_the_same_trace(short_run):
    decimated = simulate(short_run.scenario.with_overrides({"simulation.log_every": 7}))
    for name in Result.signals:
        np.testing.assert_array_equal(getattr(decimated, name), getattr(short_run, name)[::7], err_msg=name)


def test_progress_runs_in_chunks_with_the_same_result(short_run, capsys):
    chunked = simulate(short_run.scenario, progress=True)
    for name in Result.signals:
        np.testing.assert_array_equal(getattr(chunked, name), getattr(short_run, name), err_msg=name)
    # the bar appears only for runs longer than a second
    assert capsys.readouterr().err == ""


def test_plant_step_is_the_largest_whole_fraction_of_the_current_period():
    base = paper2(**{"simulation.t_end_s": 1.0, "reference": [{"t_s": 0.0, "speed_rpm": 500.0}], "load": []})
    a = simulate(base.with_overrides({"simulation.dt_s": 3e-5}))  # -> 4 steps of 25 us
    b = simulate(base.with_overrides({"simulation.dt_s": 2.5e-5}))
    np.testing.assert_array_equal(a.w_m_radps, b.w_m_radps)


def schedule_value(entries, key, t):
    """The contract's piecewise-linear schedule: 0 before the first entry; each entry moves from
    the value reached at its t_s to its value, in a step or linearly over ramp_s."""
    t0 = v0 = v1 = ramp = 0.0

    def segment(t):
        if ramp > 0.0 and t < t0 + ramp:
            return v0 + (v1 - v0) * (t - t0) / ramp
        return v1

    for e in entries:
        if e["t_s"] > t:
            break
        v0, t0, v1, ramp = segment(e["t_s"]), e["t_s"], e[key], e.get("ramp_s", 0.0)
    return segment(t)


def test_reference_is_sampled_and_load_follows_the_schedules():
    reference = [
        {"t_s": 0.2, "speed_rpm": 300.0, "ramp_s": 0.5},
        {"t_s": 1.0, "speed_rpm": -100.0},
        {"t_s": 1.5, "speed_rpm": 50.0, "ramp_s": 0.25},
    ]
    load = [
        {"t_s": 0.1, "torque_Nm": 2.0, "ramp_s": 0.3},
        {"t_s": 0.9, "torque_Nm": -1.0},
        {"t_s": 1.2, "torque_Nm": 0.5, "ramp_s": 0.6},
    ]
    r = simulate(paper2(**{"reference": reference, "load": load, "simulation.t_end_s": 2.0}))
    expected_ref = [schedule_value(reference, "speed_rpm", t) for t in r.t_s]
    expected_load = [schedule_value(load, "torque_Nm", t) for t in r.t_s]
    np.testing.assert_allclose(r.speed_ref_rpm, expected_ref, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(r.load_Nm, expected_load, rtol=1e-12, atol=1e-12)
    assert r.speed_ref_rpm[r.t_s < 0.2].max() == 0.0  # 0 before the first entry


@pytest.mark.parametrize("model", ["dq_pi", "first_order"])
@pytest.mark.parametrize("delay", [False, True])
def test_starts_in_steady_state_at_speed0(model, delay):
    """Salient motor with friction at 400 rpm, the reference equal to it: nothing moves."""
    r = simulate(
        paper2(
            **{
                "current_loop.model": model,
                "inverter.computation_delay": delay,
                "motor.Ld_H": 0.008,
                "motor.Lq_H": 0.014,
                "motor.B_Nms": 0.01,
                "motor.T_coulomb_Nm": 0.4,
                "simulation.speed0_rpm": 400.0,
                "reference": [{"t_s": 0.0, "speed_rpm": 400.0}],
                "load": [],
                "simulation.t_end_s": 1.0,
            }
        )
    )
    w0 = 400.0 / RPM_PER_RADPS
    hold_Nm = 0.01 * w0 + 0.4
    assert np.max(np.abs(r.w_m_radps - w0)) < 1e-6 * w0
    assert np.max(np.abs(r.torque_Nm - hold_Nm)) < 1e-5 * hold_Nm
    assert r.id_A[0] < 0  # MTPA of the salient motor
    assert np.ptp(r.iq_A) < 1e-5 * abs(r.iq_A[0])


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".mat"])
def test_save_writes_every_signal(short_run, tmp_path, suffix):
    path = tmp_path / f"trace{suffix}"
    short_run.save(path)
    if suffix == ".csv":
        frame = pd.read_csv(path)
        assert list(frame.columns) == list(Result.signals)
        loaded = {name: frame[name].to_numpy() for name in Result.signals}
        assert set(np.unique(loaded["saturated"])) == {0, 1}
    elif suffix == ".npz":
        with np.load(path) as z:
            loaded = {name: z[name] for name in Result.signals}
            toml = str(z["scenario_toml"])
    else:
        mat = scipy.io.loadmat(path)
        loaded = {name: mat[name][:, 0] for name in Result.signals}
        toml = str(mat["scenario_toml"][0])
    for name in Result.signals:
        np.testing.assert_array_equal(loaded[name], getattr(short_run, name).astype(loaded[name].dtype), err_msg=name)
    if suffix != ".csv":
        assert Scenario.from_dict(tomllib.loads(toml)) == short_run.scenario
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left behind


def test_save_rejects_an_unknown_format(short_run, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a short path: a message cuts a long value to its beginning
    with pytest.raises(ConfigError, match=r"path = .*trace\.txt.*\.csv, \.npz or \.mat"):
        short_run.save("trace.txt")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "overrides, key, valid",
    [
        # Ki Ka Ts = 0.3 * 1e4 * 1e-3 = 3 > 2: the discrete back-calculation loop is unstable
        ({"speed_controller.Ka": 1e4}, "speed_controller.Ka", r"Ka < 6666\.67 \(Ki = 0\.3 by eq 9\)"),
        # forward Euler: the feedforward pole 1 - m alpha Ts leaves the unit circle at m alpha Ts >= 2
        (
            {
                "speed_controller.method": "forward_euler",
                "speed_controller.alpha_radps": 2500.0,
                "speed_controller.anti_windup": "clamping",
            },
            "speed_controller.Ts_s",
            r"m\*alpha\*Ts_s < 2",
        ),
        # a value float32 cannot hold
        ({"speed_controller.J_kgm2": 1e-50}, "speed_controller.J_kgm2", "float32"),
        # 3.6e7 rows of 24 doubles (6.9 GB): every 4th row fits in 2 GiB
        ({"simulation.t_end_s": 36000.0}, "simulation.log_every", r">= 4: the log"),
        ({"simulation.dt_s": 1e-12}, "simulation.dt_s", r">= current_loop.Ts_s / 1e\+06"),
        (
            {"speed_controller.Ts_s": 1000.0, "simulation.t_end_s": 2000.0},
            "speed_controller.Ts_s",
            r"<= 1e\+06 current_loop.Ts_s = 100 s",
        ),
    ],
)
def test_rejected_values_name_the_scenario_key(overrides, key, valid):
    with pytest.raises(ConfigError, match=valid) as err:
        simulate(paper2(**overrides))
    assert err.value.param == key


def test_engine_validates_what_it_is_given():
    """The C engine checks its configuration itself (here an unsorted reference, which a Scenario
    never holds) and the error names the scenario key."""
    valid = paper2()
    tables = {name: getattr(valid, name) for name in ("name", "description", *TABLES, *ARRAYS)}
    tables["reference"] = (
        ReferenceEntry(t_s=2.0, speed_rpm=100.0, ramp_s=0.0),
        ReferenceEntry(t_s=1.0, speed_rpm=0.0, ramp_s=0.0),
    )
    with pytest.raises(ConfigError, match=r"nondecreasing") as err:
        Simulation(Scenario(valid.data, tables))
    assert err.value.param == "reference"


def test_simulate_wants_a_scenario():
    with pytest.raises(ConfigError, match=r"scenario = 'dict'"):
        simulate(paper2().data)
