"""Log import: the four formats, unit suffixes, column mapping, NaN rows, gaps, non-uniform sampling."""

import math

import numpy as np
import pandas as pd
import pytest
import scipy.io

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.logs import read_log


def _frame(n=200):
    t = np.arange(n) * 1e-3
    return pd.DataFrame(
        {
            "time_s": t,
            "speed_rpm": 300.0 * np.sin(7 * t),
            "iq_A": np.cos(5 * t),
            "id_A": np.zeros(n),
            "torque_Nm": 1.2 * np.cos(5 * t),
        }
    )


def _write(frame, path):
    if path.suffix == ".csv":
        frame.to_csv(path, index=False)
    elif path.suffix == ".parquet":
        frame.to_parquet(path)
    elif path.suffix == ".npz":
        np.savez(path, **{c: frame[c].to_numpy() for c in frame.columns})
    else:
        scipy.io.savemat(path, {c: frame[c].to_numpy() for c in frame.columns}, oned_as="column")


@pytest.mark.parametrize("ext", [".csv", ".parquet", ".npz", ".mat"])
def test_every_format_gives_the_same_arrays_in_si(tmp_path, ext):
    frame = _frame()
    path = tmp_path / f"log{ext}"
    _write(frame, path)
    log = read_log(path)
    np.testing.assert_array_equal(log.t_s, frame["time_s"])
    np.testing.assert_allclose(log.w_m_radps, frame["speed_rpm"] * math.pi / 30, rtol=1e-15, atol=0)
    np.testing.assert_allclose(log.speed_rpm, frame["speed_rpm"], rtol=1e-14)
    np.testing.assert_array_equal(log.iq_A, frame["iq_A"])
    assert log.iq_ref_A is None and log.u_dc_V is None
    assert log.notes == () and log.rows_dropped == 0 and len(log.segments()) == 1


def test_a_mapped_column_takes_its_unit_from_its_suffix(tmp_path):
    frame = _frame().rename(columns={"time_s": "stamp_ms", "speed_rpm": "enc_speed_radps", "iq_A": "Iq_meas_mA"})
    frame["stamp_ms"] *= 1e3
    frame["Iq_meas_mA"] *= 1e3
    path = tmp_path / "log.csv"
    _write(frame, path)
    log = read_log(path, {"time": "stamp_ms", "speed": "enc_speed_radps", "iq": "Iq_meas_mA"})
    np.testing.assert_allclose(log.t_s, _frame()["time_s"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(log.w_m_radps, _frame()["speed_rpm"])
    np.testing.assert_allclose(log.iq_A, _frame()["iq_A"], rtol=1e-12)
    assert log.columns["speed"] == "enc_speed_radps"


def test_nan_rows_gaps_and_nonuniform_sampling_are_handled_and_reported(tmp_path):
    frame = _frame(300)
    frame.loc[[10, 11, 50], "iq_A"] = np.nan
    frame.loc[200:, "time_s"] += 0.5  # a gap of 0.5 s
    frame.loc[100:150, "time_s"] += np.linspace(0, 0.0005, 51)  # steps up to 1.01 ms
    path = tmp_path / "log.csv"
    _write(frame, path)
    log = read_log(path)
    assert log.rows_dropped == 3 and len(log.t_s) == 297
    assert not np.any(np.isnan(log.iq_A))
    assert log.gaps == (pytest.approx((0.199, 0.7)),)
    segments = log.segments()
    assert [(s.start, s.stop) for s in segments] == [(0, 197), (197, 297)]
    text = " ".join(log.notes)
    assert "3 rows" in text and "1 gaps" in text and "non-uniform" in text


@pytest.mark.parametrize(
    ("change", "columns", "match"),
    [
        (lambda f: f.drop(columns="speed_rpm"), None, "column speed = '<missing>'.*speed_rpm, speed_radps"),
        (lambda f: f.assign(speed_radps=1.0), None, "one column for speed"),
        (lambda f: f.rename(columns={"speed_rpm": "enc"}), {"speed": "enc"}, "column speed = 'enc'.*_rpm, _radps"),
        (lambda f: f, {"sped": "speed_rpm"}, "column = 'sped'"),
        (lambda f: f.assign(time_s=f["time_s"].where(f.index != 7, 0.0)), None, "time_s at row 7 = 0.0"),
        (lambda f: f.assign(iq_A="x"), None, "column iq_A"),
    ],
)
def test_bad_logs_name_the_column(tmp_path, change, columns, match):
    path = tmp_path / "log.csv"
    _write(change(_frame()), path)
    with pytest.raises(ConfigError, match=match):
        read_log(path, columns)


def test_unreadable_files_are_config_errors(tmp_path):
    (tmp_path / "a.parquet").write_bytes(b"not parquet")
    (tmp_path / "a.txt").write_text("time_s,speed_rpm\n0,1\n")
    for name in ("a.parquet", "a.txt", "missing.csv"):
        with pytest.raises(ConfigError, match="log = "):
            read_log(tmp_path / name)


def test_compute_metrics_of_a_log_equals_that_of_the_run_it_records(tmp_path):
    from pmsm2dof.sim.metrics import compute_metrics
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate

    result = simulate(load_scenario("paper-condition-1"))
    result.save(tmp_path / "run.csv")
    log = read_log(tmp_path / "run.csv")
    of_log = compute_metrics(log, i_max_A=7.6)
    of_run = compute_metrics(result)
    assert len(of_log["reference_steps"]) == len(of_run["reference_steps"]) == 2
    for mine, theirs in zip(of_log["reference_steps"], of_run["reference_steps"]):
        assert mine["t_s"] == theirs["t_s"]
        for key, figure in theirs.items():
            if isinstance(figure, dict):
                assert (mine[key]["value"] is None) == (figure["value"] is None), key
                if figure["value"] is not None:
                    assert mine[key]["value"] == pytest.approx(figure["value"], rel=1e-9, abs=1e-9), key
    assert of_log["run"]["iae_rpm_s"]["value"] == pytest.approx(of_run["run"]["iae_rpm_s"]["value"])
    assert of_log["load_steps"] == [] and of_log["run"]["voltage_limit_time_s"]["value"] is None
    # the time at the current limit counts the same samples as the run's (no clamping chatter here)
    limit = of_run["run"]["current_limit_time_s"]["value"]
    assert of_log["run"]["current_limit_time_s"]["value"] == pytest.approx(limit, abs=2e-3)


@pytest.mark.slow
def test_cli_compare_overlays_a_log_and_its_simulation(tmp_path, capsys):
    import json

    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate
    from pmsm2dof.ui.cli import main

    scenario = load_scenario("paper-condition-1")
    heavier = simulate(scenario.with_overrides({"motor.J_kgm2": 0.5, "speed_controller.J_kgm2": 0.4}))
    heavier.save(tmp_path / "run.csv")
    out = tmp_path / "cmp"
    assert main(["compare", str(tmp_path / "run.csv"), "paper-condition-1", "--out", str(out)]) == 0
    table = json.loads((out / "compare.json").read_text())
    # the log's drive is 25 % heavier: its speed lags the simulation's on the steps
    assert table["speed_error_max_rpm"] > 10.0
    assert sorted(p.name for p in out.iterdir()) == [
        ".pmsm2dof-outputs.json",
        "compare.json",
        "compare.png",
        "simulation.csv",
    ]
    same = tmp_path / "same"
    simulate(scenario).save(tmp_path / "same.csv")
    assert main(["compare", str(tmp_path / "same.csv"), "paper-condition-1", "--out", str(same)]) == 0
    assert json.loads((same / "compare.json").read_text())["speed_error_max_rpm"] < 1e-9
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "run.csv"), "no-such-preset", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no-such-preset" in err and not (tmp_path / "bad").exists()
