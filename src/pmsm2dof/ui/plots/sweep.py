"""Figures of a sweep: heatmaps of 2-D grids, scatter plots and histograms, worst-case traces.

Drawn by :func:`draw_figures`, which ``pmsm2dof sweep`` gives to
:func:`pmsm2dof.studies.sweep_run.run_sweep`, into ``<out>/figures`` with matplotlib's Agg backend
(no display needed):

- a grid with exactly two axes of more than one value and no distribution axes:
  ``heatmap_<metric>.png`` for every metric column with at least one value, the first
  axis along the rows and the second along the columns;
- any other sweep: ``scatter_<metric>.png`` of the ranking metric (``rank_by``) against
  every numeric axis, one colour per cell of the grid axes when there are at most 10; with
  distribution axes also ``histograms.png`` of every metric column;
- always ``worst_traces.png``: speed and torque reference against time of the ``worst``
  points with the largest ``rank_by``, simulated again (the engine is deterministic).

Points whose simulation stopped (status "error") are marked with a cross (heatmaps) or
listed in the figure title; they are never drawn as values.
"""

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ...sim.simulate import simulate
from ...studies.sweep import Axis, Sweep, metric_columns

if TYPE_CHECKING:
    import pandas as pd


def _pyplot() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _is_numeric(values: Iterable[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def draw_figures(sweep: Sweep, table: "pd.DataFrame", folder: Path) -> list[Path]:
    """Draw the figures of ``sweep`` from its results ``table`` into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    plt = _pyplot()
    columns = [c for c in metric_columns(sweep.base) if table[c].notna().any()]
    grid = [a for a in sweep.grid_axes if len(a.values or ()) > 1]
    paths: list[Path] = []
    if len(grid) == 2 and not sweep.random_axes:
        paths += [_heatmap(plt, sweep, grid, table, col, folder) for col in columns]
    else:
        numeric = [a.key for a in sweep.axes if _is_numeric(table[a.key].tolist())]
        if numeric and sweep.rank_by in columns:
            paths.append(_scatter(plt, sweep, table, sweep.rank_by, numeric, folder))
        if sweep.random_axes and columns:
            paths.append(_histograms(plt, table, columns, folder))
    if sweep.worst > 0:
        paths.append(_worst_traces(plt, sweep, table, folder))
    return paths


def _heatmap(
    plt: ModuleType, sweep: Sweep, grid: Sequence[Axis], table: "pd.DataFrame", col: str, folder: Path
) -> Path:
    rows_axis, cols_axis = grid
    row_values, col_values = rows_axis.values or (), cols_axis.values or ()
    n_r, n_c = len(row_values), len(col_values)
    # points run with the first axis slowest (axes of one value do not count): point = i * n_c + j
    values = table[col].to_numpy(dtype=float, na_value=np.nan).reshape(n_r, n_c)
    failed = (table["status"] != "ok").to_numpy().reshape(n_r, n_c)
    fig, ax = plt.subplots(figsize=(1.2 + 0.55 * max(n_c, 6), 1.2 + 0.45 * max(n_r, 5)))
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")  # cells without a value: light gray
    image = ax.imshow(np.ma.masked_invalid(values), origin="lower", aspect="auto", cmap=cmap)
    fig.colorbar(image, ax=ax, label=col)
    ax.set_xticks(
        range(n_c),
        [f"{v:.3g}" if _is_numeric([v]) else str(v) for v in col_values],
        rotation=45 if n_c > 8 else 0,
    )
    ax.set_yticks(range(n_r), [f"{v:.3g}" if _is_numeric([v]) else str(v) for v in row_values])
    ax.set_xlabel(cols_axis.key)
    ax.set_ylabel(rows_axis.key)
    for i, j in zip(*np.nonzero(failed)):
        ax.text(j, i, "x", ha="center", va="center", color="red", fontsize=12)
    if n_r * n_c <= 144:
        for i in range(n_r):
            for j in range(n_c):
                if np.isfinite(values[i, j]):
                    ax.text(j, i, f"{values[i, j]:.3g}", ha="center", va="center", fontsize=7, color="w")
    missing = int(np.sum(~np.isfinite(values) & ~failed))
    ax.set_title(f"{sweep.name}: {col}" + (f" ({missing} cells without a value)" if missing else ""), fontsize=9)
    fig.tight_layout()
    path = folder / f"heatmap_{col}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _scatter(plt: ModuleType, sweep: Sweep, table: "pd.DataFrame", col: str, keys: Sequence[str], folder: Path) -> Path:
    ok = table[table[col].notna()]
    # one colour per cell of the grid axes (with more than one value), when there are few
    multi = [a for a in sweep.grid_axes if len(a.values or ()) > 1]
    grid = [a.key for a in multi]
    n_cells = math.prod(len(a.values or ()) for a in multi)
    groups = list(ok.groupby(grid, sort=False)) if grid and n_cells <= 10 else [(None, ok)]
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.6), squeeze=False)
    for ax, key in zip(axes[0], keys):
        x_all = ok[key].astype(float)
        for cell, part in groups:
            label = (
                None
                if cell is None
                else ", ".join(
                    f"{k.split('.')[-1]}={v}" for k, v in zip(grid, cell if isinstance(cell, tuple) else (cell,))
                )
            )
            ax.scatter(part[key].astype(float), part[col].astype(float), s=10, alpha=0.6, label=label)
        ax.set_xlabel(key)
        ax.set_ylabel(col)
        if (x_all > 0).all() and x_all.max() > 20 * x_all.min():
            ax.set_xscale("log")
        ax.grid(True, alpha=0.3)
        if groups[0][0] is not None:
            ax.legend(fontsize=7)
    n_failed = int((table["status"] != "ok").sum())
    fig.suptitle(
        f"{sweep.name}: {col}, {len(ok)} of {len(table)} points" + (f" ({n_failed} stopped)" if n_failed else ""),
        fontsize=9,
    )
    fig.tight_layout()
    path = folder / f"scatter_{col}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _histograms(plt: ModuleType, table: "pd.DataFrame", columns: Sequence[str], folder: Path) -> Path:
    n = len(columns)
    n_cols = min(4, n)
    n_rows = -(-n // n_cols)
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(3.6 * n_cols, 2.8 * n_rows), squeeze=False)
    for ax, col in zip(axes.flat, columns):
        values = table[col].dropna().astype(float)
        ax.hist(values, bins=min(40, max(5, int(np.sqrt(len(values))))))
        ax.set_title(f"{col} ({len(values)} values)", fontsize=8)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    path = folder / "histograms.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _worst_traces(plt: ModuleType, sweep: Sweep, table: "pd.DataFrame", folder: Path) -> Path:
    ranked = table[table[sweep.rank_by].notna()].sort_values(sweep.rank_by, ascending=False)
    worst = ranked.head(sweep.worst)
    fig, (ax_w, ax_t) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for _, row in worst.iterrows():
        point = int(row["point"])
        result = simulate(sweep.scenario(point))
        label = f"#{point}: " + ", ".join(
            f"{k.split('.')[-1]}={row[k]:.4g}" if _is_numeric([row[k]]) else f"{k.split('.')[-1]}={row[k]}"
            for k in sweep.keys
        )
        (line,) = ax_w.plot(result.t_s, result.speed_rpm, label=f"{label} ({sweep.rank_by} {row[sweep.rank_by]:.4g})")
        ax_w.plot(result.t_s, result.speed_ref_rpm, "--", color=line.get_color(), linewidth=0.8)
        ax_t.plot(result.t_s, result.torque_ref_Nm, color=line.get_color())
    ax_w.set_ylabel("speed [rpm] (dashed: reference)")
    ax_t.set_ylabel("torque reference [Nm]")
    ax_t.set_xlabel("t [s]")
    for ax in (ax_w, ax_t):
        ax.grid(True, alpha=0.3)
    if len(worst):
        ax_w.legend(fontsize=7)
    failed = table.loc[table["status"] != "ok", "point"].tolist()
    title = f"{sweep.name}: the {len(worst)} points with the largest {sweep.rank_by}"
    if failed:
        title += f"; stopped: points {', '.join(str(p) for p in failed[:10])}" + (" ..." if len(failed) > 10 else "")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = folder / "worst_traces.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
