"""The one engine of many runs (pmsm2dof.studies.engine): what it returns, in which order.

Truth: the same runs simulated and measured one by one with pmsm2dof.simulate and
measure (compute_metrics and the sampled-loop check), outside the engine.
"""

import pickle
import threading

import pytest

from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.engine import Run, check_options, local_threads, run_many
from pmsm2dof.studies.loopcheck import measure

SHORT = {"simulation.t_end_s": 12.0}
RUNS = [
    Run("a", "c2", {**SHORT, "speed_controller.zeta": 0.5}),
    Run("b", "e1", SHORT),
    Run("stall", "c2", {**SHORT, "load": [{"t_s": 0.1, "torque_Nm": -3000.0}]}),  # overspeed: stops
    Run("c", "c2", {**SHORT, "speed_controller.feedforward": "none"}),
]


@pytest.fixture(scope="module")
def bases():
    return {"c2": load_scenario("paper-condition-2"), "e1": load_scenario("paper-experiment-1")}


@pytest.mark.parametrize("workers, batch_size", [(1, None), (2, 1)])
def test_outcomes_in_the_order_of_the_runs_equal_single_runs(bases, workers, batch_size):
    batches = []
    outcomes = run_many(
        bases,
        RUNS,
        keep=["b"],
        workers=workers,
        batch_size=batch_size,
        on_batch=batches.append,
    )
    assert [o.key for o in outcomes] == [r.key for r in RUNS]
    assert sorted(o.key for batch in batches for o in batch) == sorted(r.key for r in RUNS)
    for run, outcome in zip(RUNS, outcomes):
        scenario = bases[run.base].with_overrides(run.overrides)
        if run.key == "stall":
            with pytest.raises(SimulationError) as stop:
                simulate(scenario)
            assert outcome.metrics is None and outcome.error == str(stop.value) and outcome.wall_time_s is None
            continue
        assert outcome.error == "" and outcome.metrics == measure(simulate(scenario))
        assert (outcome.result is not None) == (run.key == "b")
    assert outcomes[1].result.scenario == bases["e1"].with_overrides(SHORT)


def _iae(result):
    """A study's own measure: the run's speed IAE alone (a module-level function, as Dask needs)."""
    return {"iae_rpm_s": compute_metrics(result, figures={"run": ("iae_rpm_s",)})["run"]["iae_rpm_s"]["value"]}


def test_a_pool_kept_over_many_calls_and_a_study_measure_give_what_single_runs_give(bases):
    """run_many on the threads of one local_threads pool, three times, measuring with the study's function:
    each outcome is that function of the run simulated alone; the pool's threads are the same every call."""
    threads = []

    def named(result):
        threads.append(threading.current_thread())
        return _iae(result)

    runs = [r for r in RUNS if r.key != "stall"]
    with local_threads(2) as pool:
        for _ in range(3):
            outcomes = run_many(bases, runs, measure=named, workers=2, pool=pool, batch_size=1)
            for run, outcome in zip(runs, outcomes, strict=True):
                assert outcome.metrics == _iae(simulate(bases[run.base].with_overrides(run.overrides)))
    assert len(set(threads)) <= 2 and len(threads) == 3 * len(runs)


def test_a_value_only_the_c_code_rejects_names_the_run(bases):
    bad = Run("too-fast", "c2", {**SHORT, "speed_controller.alpha_radps": 1e39}, "run too-fast")
    with pytest.raises(ConfigError) as info:
        run_many({"c2": bases["c2"]}, [bad], workers=1)
    assert info.value.param == "run too-fast: speed_controller.alpha_radps"


@pytest.mark.parametrize(
    "options, param",
    [
        (dict(workers=0), "workers"),
        (dict(workers=2, scheduler="tcp://127.0.0.1:9"), "workers"),
        (dict(scheduler="127.0.0.1:9"), "scheduler"),
        (dict(batch_size=0), "batch_size"),
    ],
)
def test_bad_options_name_the_parameter(options, param):
    with pytest.raises(ConfigError) as info:
        check_options(**options)
    assert info.value.param == param


def test_a_scenario_travels_to_a_worker_by_pickle(bases):
    scenario = bases["c2"].with_overrides({"speed_controller.Ka": 2.0})
    copy = pickle.loads(pickle.dumps(scenario))
    assert copy == scenario and copy.to_toml() == scenario.to_toml()
