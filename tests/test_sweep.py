"""Sweeps: expansion of the axes, validation, local and Dask runs, resume after an interruption.

Truth: ranges and draws are checked against values computed here by hand (the linspace and
geomspace formulas, sample statistics of the named distributions); the rows of a sweep
against individual ``simulate`` + ``compute_metrics`` runs of scenarios built here; the Dask
run against the local run, point for point.
"""

import hashlib
import importlib
import io
import json
import math
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.engine import PartWarning
from pmsm2dof.studies.sweep import load_sweep, metric_columns, parse_sweep
from pmsm2dof.studies.sweep_run import run_sweep
from pmsm2dof.ui.cli import main
from pmsm2dof.ui.plots.sweep import draw_figures

# the modules (the package exports functions of the same names)
# the simulate that the engine calls (the tests count the simulations)
simulate_module = importlib.import_module("pmsm2dof.studies.engine")
sweep_run_module = importlib.import_module("pmsm2dof.studies.sweep_run")

# A small drive that settles within 0.3 s: a speed step at 0 s and a load step at 0.3 s.
BASE_TOML = """
name = "sweep test"

[motor]
pole_pairs = 4
Rs_ohm = 0.5
Ld_H = 0.01
Lq_H = 0.01
psi_f_Wb = 0.2
J_kgm2 = 0.01

[limits]
i_max_A = 7.6
u_dc_V = 540.0

[current_loop]
model = "dq_pi"
tau_i_s = 0.002
Ts_s = 1e-4

[speed_controller]
alpha_radps = 50.0
zeta = 1.0
Ts_s = 1e-3
J_kgm2 = 0.01
tau_i_s = 0.002

[simulation]
t_end_s = 0.6

[[reference]]
t_s = 0.0
speed_rpm = 200.0

[[load]]
t_s = 0.3
torque_Nm = 2.0
"""

GRID_AXES = """
[axes]
"speed_controller.alpha_radps" = [25.0, 50.0, 100.0]
"motor.J_kgm2" = { start = 0.005, stop = 0.02, num = 3, scale = "log" }
"""


@pytest.fixture
def base_file(tmp_path):
    path = tmp_path / "base.toml"
    path.write_text(BASE_TOML)
    return path


def write_sweep(tmp_path, text, name="sweep.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def sweep_of(base_file, axes_text, **top):
    """A parsed sweep of the test base with the given [axes] text and top-level keys."""
    import tomllib

    data = tomllib.loads(axes_text)
    data.update(base=base_file.name, **top)
    return parse_sweep(data, base_dir=base_file.parent)


# ---------------------------------------------------------------------------------------------
# expansion
# ---------------------------------------------------------------------------------------------


def test_grid_is_the_product_with_the_first_axis_slowest(base_file):
    sw = sweep_of(base_file, GRID_AXES)
    alphas = [25.0, 50.0, 100.0]
    # geometric range by hand: start (stop/start)^(k/(num-1))
    inertias = [0.005 * (0.02 / 0.005) ** (k / 2) for k in range(3)]
    expected = [(a, j) for a in alphas for j in inertias]
    got = [(p["speed_controller.alpha_radps"], p["motor.J_kgm2"]) for p in sw.points]
    assert len(got) == 9
    for (a, j), (ga, gj) in zip(expected, got):
        assert ga == a
        assert gj == pytest.approx(j, rel=1e-12)
    assert sw.rank_by == "run_iae_rpm_s"


def test_linear_range_by_hand(base_file):
    sw = sweep_of(base_file, '[axes]\n"speed_controller.zeta" = { start = 0.5, stop = 2.0, num = 4 }\n')
    assert [p["speed_controller.zeta"] for p in sw.points] == pytest.approx([0.5, 1.0, 1.5, 2.0], rel=1e-15)


@pytest.mark.slow
def test_draws_are_reproducible_independent_per_key_and_follow_their_distribution(base_file):
    axes = """
    [axes]
    "motor.J_kgm2" = { distribution = "log_normal", median = 0.01, sigma = 0.3 }
    "speed_controller.Ka" = { distribution = "uniform", low = 0.01, high = 0.2 }
    "speed_controller.zeta" = { distribution = "normal", mean = 1.0, std = 0.05 }
    """
    n = 2000
    sw = sweep_of(base_file, textwrap.dedent(axes), draws=n, seed=11)
    again = sweep_of(base_file, textwrap.dedent(axes), draws=n, seed=11)
    assert sw.points == again.points
    other_seed = sweep_of(base_file, textwrap.dedent(axes), draws=n, seed=12)
    assert sw.points != other_seed.points

    J = np.array([p["motor.J_kgm2"] for p in sw.points])
    Ka = np.array([p["speed_controller.Ka"] for p in sw.points])
    zeta = np.array([p["speed_controller.zeta"] for p in sw.points])
    # sample statistics within 5 standard errors of the named distributions
    assert np.mean(np.log(J)) == pytest.approx(math.log(0.01), abs=5 * 0.3 / math.sqrt(n))
    assert np.std(np.log(J)) == pytest.approx(0.3, rel=0.05)
    assert Ka.min() >= 0.01 and Ka.max() <= 0.2
    assert np.mean(Ka) == pytest.approx(0.105, abs=5 * (0.19 / math.sqrt(12)) / math.sqrt(n))
    assert np.mean(zeta) == pytest.approx(1.0, abs=5 * 0.05 / math.sqrt(n))
    assert np.std(zeta) == pytest.approx(0.05, rel=0.05)
    # independent streams: weak correlation, and one axis alone draws the same values
    assert abs(np.corrcoef(np.log(J), Ka)[0, 1]) < 0.1
    alone = sweep_of(
        base_file,
        '[axes]\n"motor.J_kgm2" = { distribution = "log_normal", median = 0.01, sigma = 0.3 }\n',
        draws=n,
        seed=11,
    )
    assert [p["motor.J_kgm2"] for p in alone.points] == list(J)


def test_grid_times_draws_uses_the_same_draws_in_every_cell(base_file):
    axes = """
    [axes]
    "speed_controller.alpha_radps" = [25.0, 50.0]
    "motor.J_kgm2" = { distribution = "uniform", low = 0.008, high = 0.012 }
    """
    sw = sweep_of(base_file, textwrap.dedent(axes), draws=5, seed=1)
    assert len(sw.points) == 10
    first = [p["motor.J_kgm2"] for p in sw.points[:5]]
    second = [p["motor.J_kgm2"] for p in sw.points[5:]]
    assert first == second
    assert [p["speed_controller.alpha_radps"] for p in sw.points] == [25.0] * 5 + [50.0] * 5


def test_plant_inertia_axis_keeps_the_design_inertia_of_the_base(tmp_path):
    # paper-condition-2 does not give J_design_kgm2 (its default is motor.J_kgm2 = 0.4)
    sw = parse_sweep({"base": "paper-condition-2", "axes": {"motor.J_kgm2": [0.2, 0.8]}})
    for i, J in enumerate((0.2, 0.8)):
        data = sw.scenario(i).data
        assert data["motor"]["J_kgm2"] == J
        assert data["speed_controller"]["J_kgm2"] == 0.4


# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------

BAD = [
    ({"colour": 1}, "colour"),
    ({"base": None}, "base"),
    ({"base": "no-such-preset"}, "scenario"),
    ({"axes": {}}, "axes"),
    ({"axes": {"motor.J": [1.0]}}, "axes"),
    ({"axes": {"motor": [1.0]}}, "axes"),
    ({"axes": {"motor.J_kgm2": []}}, "axes.motor.J_kgm2"),
    ({"axes": {"motor.J_kgm2": 0.3}}, "axes.motor.J_kgm2"),
    ({"axes": {"motor.J_kgm2": {"start": 0.1, "stop": 0.2, "num": 0}}}, "axes.motor.J_kgm2.num"),
    ({"axes": {"motor.J_kgm2": {"start": 0.1, "stop": 0.2}}}, "axes.motor.J_kgm2.num"),
    ({"axes": {"motor.J_kgm2": {"start": 0.0, "stop": 0.2, "num": 3, "scale": "log"}}}, "axes.motor.J_kgm2.start"),
    ({"axes": {"motor.J_kgm2": {"start": 0.1, "stop": 0.2, "num": 3, "scale": "cubic"}}}, "axes.motor.J_kgm2.scale"),
    ({"axes": {"motor.J_kgm2": {"start": 0.1, "stop": 0.2, "num": 3, "step": 1}}}, "axes.motor.J_kgm2.step"),
    ({"axes": {"motor.J_kgm2": {"distribution": "cauchy"}}, "draws": 3, "seed": 1}, "axes.motor.J_kgm2.distribution"),
    (
        {"axes": {"motor.J_kgm2": {"distribution": "uniform", "low": 0.2, "high": 0.1}}, "draws": 3, "seed": 1},
        "axes.motor.J_kgm2.high",
    ),
    (
        {"axes": {"motor.J_kgm2": {"distribution": "normal", "mean": 0.2, "std": -1.0}}, "draws": 3, "seed": 1},
        "axes.motor.J_kgm2.std",
    ),
    (
        {"axes": {"motor.J_kgm2": {"distribution": "log_normal", "median": -0.2, "sigma": 0.1}}, "draws": 3, "seed": 1},
        "axes.motor.J_kgm2.median",
    ),
    ({"axes": {"motor.J_kgm2": {"distribution": "uniform", "low": 0.1, "high": 0.2}}, "seed": 1}, "draws"),
    ({"axes": {"motor.J_kgm2": {"distribution": "uniform", "low": 0.1, "high": 0.2}}, "draws": 3}, "seed"),
    ({"axes": {"motor.J_kgm2": {"distribution": "uniform", "low": 0.1, "high": 0.2}}, "draws": 0, "seed": 1}, "draws"),
    ({"draws": 10}, "draws"),
    ({"rank_by": "overshoot"}, "rank_by"),
    ({"worst": -1}, "worst"),
    ({"axes": {"motor.J_kgm2": [0.01, -0.01]}}, "motor.J_kgm2"),
    ({"axes": {"speed_controller.method": ["tustin", "zoh"]}}, "speed_controller.method"),
]


@pytest.mark.parametrize("change, param", BAD, ids=[p for _, p in BAD])
def test_invalid_sweeps_name_the_key(base_file, change, param):
    data = {"base": base_file.name, "axes": {"speed_controller.alpha_radps": [25.0]}}
    data.update(change)
    with pytest.raises(ConfigError) as info:
        parse_sweep(data, base_dir=base_file.parent)
    assert param in info.value.param
    assert "valid range is" in str(info.value)


def test_an_invalid_point_is_named_with_its_values(base_file):
    with pytest.raises(ConfigError) as info:
        parse_sweep({"base": base_file.name, "axes": {"motor.J_kgm2": [0.01, -0.01]}}, base_dir=base_file.parent)
    assert info.value.param.startswith("point 1 (motor.J_kgm2=-0.01)")


def test_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match="sweep file"):
        load_sweep(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="valid TOML"):
        load_sweep(write_sweep(tmp_path, "base = \n"))


# ---------------------------------------------------------------------------------------------
# running
# ---------------------------------------------------------------------------------------------


def expected_row(base_file, point):
    """Metrics of one point from a scenario built here and the single-run path."""
    result = simulate(load_scenario(base_file).with_overrides(point))
    metrics = compute_metrics(result)
    row = {}
    for i, step in enumerate(metrics["reference_steps"]):
        row.update({f"ref{i}_{k}": v["value"] for k, v in step.items() if isinstance(v, dict)})
    for j, step in enumerate(metrics["load_steps"]):
        row.update({f"load{j}_{k}": v["value"] for k, v in step.items() if isinstance(v, dict)})
    row.update({f"run_{k}": v["value"] for k, v in metrics["run"].items() if isinstance(v, dict)})
    return row


@pytest.mark.slow
def test_local_run_equals_single_runs_and_writes_every_output(tmp_path, base_file):
    path = write_sweep(tmp_path, f'base = "base.toml"\nworst = 2\n{GRID_AXES}')
    sw = load_sweep(path)
    out = tmp_path / "out"
    run = run_sweep(sw, out, workers=2, batch_size=2, progress=False, figures=draw_figures)
    table = run.table
    assert list(table["point"]) == list(range(9))
    assert (table["status"] == "ok").all()
    assert run.computed == 9 and run.resumed == 0
    columns = metric_columns(sw.base)
    assert set(columns) <= set(table.columns)
    for index in (0, 4, 8):
        point = sw.points[index]
        row = table.iloc[index]
        for key, value in point.items():
            assert row[key] == value
        for col, value in expected_row(tmp_path / "base.toml", point).items():
            if value is None:
                assert pd.isna(row[col]), col
            else:
                assert row[col] == value, col
    # the axes reach the simulation: a larger plant inertia dips less under the load step
    dips = table.set_index(["speed_controller.alpha_radps", "motor.J_kgm2"])["load0_speed_dip_rpm"]
    for alpha in (25.0, 50.0, 100.0):
        assert dips.loc[alpha].is_monotonic_decreasing

    stored = pd.read_parquet(out / "results.parquet")
    pd.testing.assert_frame_equal(stored, table)
    csv = pd.read_csv(out / "results.csv")
    assert list(csv["point"]) == list(range(9))
    assert np.allclose(csv["run_iae_rpm_s"], table["run_iae_rpm_s"].astype(float), rtol=1e-12)
    names = sorted(p.name for p in (out / "figures").iterdir())
    assert "heatmap_run_iae_rpm_s.png" in names and "worst_traces.png" in names
    assert all((out / "figures" / n).stat().st_size > 1000 for n in names)
    assert json.loads((out / "sweep.json").read_text())["digest"] == sw.digest()

    one = run_sweep(sw, tmp_path / "one", workers=1, progress=False, figures=draw_figures).table
    pd.testing.assert_frame_equal(one.drop(columns="wall_time_s"), table.drop(columns="wall_time_s"))


def test_a_diverging_point_is_a_row_with_its_error_and_no_metrics(tmp_path, base_file):
    # a driving load far beyond the current limit: the shaft overspeeds, the engine stops
    sw = sweep_of(base_file, '[axes]\n"load.0.torque_Nm" = [2.0, -2000.0]\n', worst=0)
    table = run_sweep(sw, tmp_path / "out", workers=1, progress=False, figures=draw_figures).table
    assert list(table["status"]) == ["ok", "error"]
    assert table.loc[0, "error"] == ""
    assert "speed" in table.loc[1, "error"]
    assert table.loc[1, metric_columns(sw.base)].isna().all()
    with pytest.raises(Exception) as info:
        simulate(load_scenario(base_file).with_overrides({"load.0.torque_Nm": -2000.0}))
    assert str(info.value) == table.loc[1, "error"]


def test_a_value_only_the_engine_rejects_stops_the_sweep_naming_the_point(tmp_path, base_file):
    # finite and > 0 for the schema, but not a float32 for the C controller
    sw = sweep_of(base_file, '[axes]\n"speed_controller.alpha_radps" = [50.0, 1e39]\n', worst=0)
    out = tmp_path / "out"
    with pytest.raises(ConfigError) as info:
        run_sweep(sw, out, workers=1, batch_size=1, progress=False, figures=draw_figures)
    assert info.value.param == "point 1 (speed_controller.alpha_radps=1e+39): speed_controller.alpha_radps"
    assert [p.name[:14] for p in (out / "parts").iterdir()] == ["part-00000000."]
    assert not (out / "results.parquet").exists()


@pytest.mark.slow
def test_interrupted_sweep_resumes_without_recomputing(tmp_path, base_file, monkeypatch):
    sw = sweep_of(base_file, GRID_AXES, worst=0)
    out = tmp_path / "out"
    real_save = sweep_run_module._save_part
    saved = []

    def save_then_interrupt(out_, sweep_, rows):
        real_save(out_, sweep_, rows)
        saved.extend(r["point"] for r in rows)
        if len(saved) >= 4:
            raise KeyboardInterrupt

    monkeypatch.setattr(sweep_run_module, "_save_part", save_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(sw, out, workers=1, batch_size=2, progress=False, figures=draw_figures)
    monkeypatch.setattr(sweep_run_module, "_save_part", real_save)
    assert not (out / "results.parquet").exists() and not (out / "results.csv").exists()
    finished = set(saved)
    assert 4 <= len(finished) < 9

    simulated = []
    real_simulate_many = simulate_module.simulate_many

    def counting_simulate_many(scenarios):
        simulated.extend(scenarios)
        return real_simulate_many(scenarios)

    monkeypatch.setattr(simulate_module, "simulate_many", counting_simulate_many)
    run = run_sweep(sw, out, workers=1, batch_size=2, progress=False, figures=draw_figures)
    assert run.resumed == len(finished) and run.computed == 9 - len(finished)
    missing = [sw.scenario(i) for i in range(9) if i not in finished]
    assert len(simulated) == len(missing)
    assert all(any(s == m for m in missing) for s in simulated)

    monkeypatch.setattr(simulate_module, "simulate_many", real_simulate_many)
    fresh = run_sweep(sw, tmp_path / "fresh", workers=1, progress=False, figures=draw_figures).table
    pd.testing.assert_frame_equal(run.table.drop(columns="wall_time_s"), fresh.drop(columns="wall_time_s"))


def damage(part, how):
    """Cut ``part`` to half its bytes, fill it with bytes that are no Parquet, or rename a column
    (as an earlier version wrote it: a sound file, under the checksum of its content)."""
    data = part.read_bytes()
    if how == "truncated":
        part.write_bytes(data[: len(data) // 2])
    elif how == "garbage":
        part.write_bytes(b"not a parquet file\n" * 20)
    else:  # the time at the current limit under its old name
        frame = pd.read_parquet(part)
        buf = io.BytesIO()
        frame.rename(columns={"run_current_limit_time_s": "run_saturation_time_s"}).to_parquet(buf)
        part.unlink()
        (part.parent / f"{part.name[:13]}.{hashlib.sha256(buf.getvalue()).hexdigest()}.parquet").write_bytes(
            buf.getvalue()
        )


def test_resume_recomputes_the_points_of_damaged_parts_naming_each(tmp_path, base_file, monkeypatch):
    sw = sweep_of(base_file, GRID_AXES, worst=0)
    out = tmp_path / "out"
    first = run_sweep(sw, out, workers=1, batch_size=2, progress=False, figures=None).table
    parts = sorted((out / "parts").iterdir())
    assert len(parts) == 5
    damaged = {parts[0].name: "truncated", parts[2].name: "garbage", parts[4].name: "columns"}
    for name, how in damaged.items():
        damage(out / "parts" / name, how)
    lost = {p for name in damaged for p in range(int(name[5:13]), min(int(name[5:13]) + 2, 9))}

    simulated = []
    real_simulate_many = simulate_module.simulate_many

    def counting_simulate_many(scenarios):
        simulated.extend(scenarios)
        return real_simulate_many(scenarios)

    monkeypatch.setattr(simulate_module, "simulate_many", counting_simulate_many)
    with pytest.warns(PartWarning) as caught:
        run = run_sweep(sw, out, workers=1, batch_size=2, progress=False, figures=None)
    messages = [str(w.message) for w in caught]
    assert len(messages) == 3
    for name, how in damaged.items():
        (message,) = [m for m in messages if f"parts/{name[:13]}" in m]
        assert ("does not match its checksum" if how != "columns" else "columns") in message
        assert message.endswith("deleted, its points run again")
    assert run.computed == len(lost) == len(simulated) and run.resumed == 9 - len(lost)
    assert all(any(s == sw.scenario(i) for i in lost) for s in simulated)
    pd.testing.assert_frame_equal(run.table.drop(columns="wall_time_s"), first.drop(columns="wall_time_s"))
    # the damaged files are gone; the parts now read without a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", PartWarning)
        assert run_sweep(sw, out, workers=1, progress=False, figures=None).computed == 0


def test_cli_resume_with_a_damaged_part_warns_in_one_line(tmp_path, base_file, capsys):
    path = write_sweep(
        tmp_path, 'base = "base.toml"\nworst = 0\n[axes]\n"speed_controller.alpha_radps" = [25.0, 50.0]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--workers", "1", "--batch-size", "1", "--no-figures"]) == 0
    capsys.readouterr()
    (part,) = (out / "parts").glob("part-00000001.*.parquet")
    damage(part, "truncated")
    assert main(["sweep", str(path), "--out", str(out), "--no-figures"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith(f"pmsm2dof: warning: parts/{part.name} of the earlier run in ")
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert "2 points (1 simulated, 1 already done)" in captured.out


def test_out_folder_of_another_sweep_is_refused(tmp_path, base_file):
    out = tmp_path / "out"
    run_sweep(
        sweep_of(base_file, '[axes]\n"speed_controller.alpha_radps" = [25.0]\n', worst=0),
        out,
        progress=False,
        figures=draw_figures,
    )
    with pytest.raises(ConfigError, match="different sweep"):
        run_sweep(
            sweep_of(base_file, '[axes]\n"speed_controller.alpha_radps" = [30.0]\n', worst=0),
            out,
            progress=False,
            figures=draw_figures,
        )


@pytest.mark.slow
def test_dask_cluster_on_loopback_equals_the_local_run(tmp_path, base_file):
    distributed = pytest.importorskip("dask.distributed")
    axes = """
    [axes]
    "speed_controller.alpha_radps" = [25.0, 100.0]
    "motor.J_kgm2" = { distribution = "log_normal", median = 0.01, sigma = 0.2 }
    """
    sw = sweep_of(base_file, textwrap.dedent(axes), draws=4, seed=5, worst=1)
    local = run_sweep(sw, tmp_path / "local", workers=2, progress=False, figures=draw_figures).table
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        remote = run_sweep(
            sw,
            tmp_path / "dask",
            scheduler=cluster.scheduler_address,
            batch_size=3,
            progress=False,
            figures=draw_figures,
        ).table
    pd.testing.assert_frame_equal(remote.drop(columns="wall_time_s"), local.drop(columns="wall_time_s"))
    names = {p.name for p in (tmp_path / "dask" / "figures").iterdir()}
    assert {"scatter_run_iae_rpm_s.png", "histograms.png", "worst_traces.png"} <= names


# ---------------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_cli_runs_a_sweep_and_resumes(tmp_path, base_file, capsys):
    path = write_sweep(
        tmp_path, 'base = "base.toml"\nworst = 1\n[axes]\n"speed_controller.alpha_radps" = [25.0, 50.0]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--workers", "2"]) == 0
    text = capsys.readouterr().out
    assert "2 points (2 simulated, 0 already done)" in text
    assert (out / "results.parquet").exists() and (out / "results.csv").exists()
    assert main(["sweep", str(path), "--out", str(out)]) == 0
    assert "2 points (0 simulated, 2 already done)" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["--workers", "0"], "--workers = 0"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "--workers"),
        (["--scheduler", "127.0.0.1:9"], "--scheduler"),
    ],
)
def test_cli_bad_options_exit_2_with_one_line_and_no_output(tmp_path, base_file, capsys, args, message):
    path = write_sweep(tmp_path, 'base = "base.toml"\n[axes]\n"speed_controller.alpha_radps" = [25.0]\n')
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not out.exists()


def test_cli_bad_sweep_file_exits_2_without_output(tmp_path, base_file, capsys):
    path = write_sweep(tmp_path, 'base = "base.toml"\n[axes]\n"motor.J_kgm2" = { start = 0.1, stop = 0.2, num = -3 }\n')
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "axes.motor.J_kgm2.num = -3" in err and err.count("\n") == 1
    assert not out.exists()


EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples" / "sweeps").glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_sweeps_are_valid(path):
    sw = load_sweep(path)
    assert sw.points and sw.name == path.stem
