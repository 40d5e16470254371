"""The command line loads only what a command uses, and a long trace is drawn at the image's resolution.

No timing is asserted (benchmarks/bench_latency.py measures it): the import graph of a fresh
process is checked instead, and the decimated trace against the per-pixel-column extremes of the
raw samples, computed here.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.ui.plots.canvas import DPI, decimate
from pmsm2dof.ui.plots.trace import trace_figure

HEAVY = ("control", "scipy", "matplotlib", "pandas", "numpy")


def modules_after(argv, tmp_path):
    """The modules of HEAVY loaded once ``pmsm2dof ARGV`` has run in a fresh interpreter.

    A module of pmsm2dof.lazy that nobody used was never imported: it is not in ``sys.modules``
    (a module of another lazy type there would not count as loaded either).
    """
    code = (
        "import sys, json, types\n"
        "from pmsm2dof.ui.cli import main\n"
        f"status = main({argv!r})\n"
        f"loaded = [m for m in {HEAVY!r} if type(sys.modules.get(m)) is types.ModuleType]\n"
        "print(json.dumps([status, sorted(loaded)]))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    status, loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert status == 0, proc.stderr
    return set(loaded)


@pytest.mark.slow
def test_help_loads_none_of_the_heavy_libraries(tmp_path):
    assert modules_after(["--help"], tmp_path) == set()
    assert modules_after(["simulate", "--help"], tmp_path) == set()


@pytest.mark.slow
def test_simulate_loads_neither_python_control_nor_scipy_nor_pandas(tmp_path):
    assert modules_after(["simulate", "paper-condition-1", "--out", "run"], tmp_path) == {"numpy", "matplotlib"}
    written = {p.name for p in (tmp_path / "run").iterdir()}
    assert written == {".pmsm2dof-outputs.json", "trace.csv", "metrics.json", "plot.png", "scenario.toml"}


def column_extremes(x, y, x_lo, x_hi, columns):
    """Per pixel column over [x_lo, x_hi]: (min, max) of the samples that fall in it."""
    col = np.clip(((x - x_lo) * (columns / (x_hi - x_lo))).astype(int), 0, columns - 1)
    return {c: (y[col == c].min(), y[col == c].max()) for c in np.unique(col)}


def test_decimation_keeps_every_column_extreme_and_the_ends():
    rng = np.random.default_rng(7)
    x = np.sort(rng.uniform(0.0, 10.0, 150_000))
    y = np.cumsum(rng.standard_normal(x.size)) + 50.0 * (np.abs(x - 6.3) < 1e-3)  # a spike a few samples wide
    xd, yd = decimate(x, y, 0.0, 10.0, 960)
    assert xd.size <= 4 * 960 and np.all(np.diff(xd) > 0)
    assert (xd[0], xd[-1]) == (x[0], x[-1])
    assert column_extremes(xd, yd, 0.0, 10.0, 960) == column_extremes(x, y, 0.0, 10.0, 960)
    assert yd.max() == y.max()  # the spike is drawn
    # a short line is kept whole
    assert decimate(x[:100], y[:100], 0.0, 10.0, 960)[0].size == 100


def test_a_trace_of_150_000_samples_is_drawn_from_a_few_thousand_points():
    scenario = load_scenario("paper-condition-2").with_overrides({"speed_controller.Ts_s": 1e-4})
    result = simulate(scenario)
    assert result.t_s.size == 150_001
    fig = trace_figure(result)
    columns = int(np.ceil(fig.get_figwidth() * DPI))
    ax_speed = fig.axes[0]
    lines = [line for ax in fig.axes for line in ax.get_lines() if len(line.get_xdata()) > 2]
    assert lines and all(len(line.get_xdata()) <= 4 * columns for line in lines)
    # the speed as drawn has the peaks of the speed as simulated, column by column
    speed = next(line for line in ax_speed.get_lines() if line.get_label() == "speed")
    x_lo, x_hi = ax_speed.get_xlim()
    drawn = column_extremes(np.asarray(speed.get_xdata()), np.asarray(speed.get_ydata()), x_lo, x_hi, columns)
    assert drawn == column_extremes(result.t_s, result.speed_rpm, x_lo, x_hi, columns)


@pytest.mark.parametrize("rows_per_chunk", [None, 999])
def test_the_csv_trace_is_pandas_own_text(tmp_path, monkeypatch, rows_per_chunk):
    """The trace is written without pandas, as pandas writes it (the oracle): every column, every digit;
    streamed in chunks too (999 rows: 10 whole chunks of the 10001 rows and a last one of 11)."""
    import pandas as pd

    import pmsm2dof.sim.simulate

    if rows_per_chunk is not None:
        monkeypatch.setattr(pmsm2dof.sim.simulate, "CSV_ROWS_PER_CHUNK", rows_per_chunk)
    result = simulate(load_scenario("paper-condition-1"))
    assert len(result.t_s) == 10001
    result.save(tmp_path / "trace.csv")
    frame = result.to_dataframe()
    for flag in ("saturated", "J_valid"):
        frame[flag] = frame[flag].astype(np.int8)
    assert (tmp_path / "trace.csv").read_text() == frame.to_csv(index=False)
    back = pd.read_csv(tmp_path / "trace.csv")
    np.testing.assert_array_equal(back["speed_rpm"].to_numpy(), result.speed_rpm)
