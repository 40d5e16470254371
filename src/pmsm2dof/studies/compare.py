"""A measured log against the simulation of its scenario, as ``pmsm2dof compare`` tells it.

:func:`compare_log` simulates the scenario (the same reference and load as the log's run), measures the
speed difference over the time both cover and the figures of merit of each reference step of both
(:func:`pmsm2dof.sim.metrics.compute_metrics`), and writes the output folder; the figure is drawn by the
caller's ``figure`` function (the plots belong to the user interface).
"""

import dataclasses
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..outputs import atomic_write, staged_dir
from ..sim.logs import Log, read_log
from ..sim.metrics import compute_metrics
from ..sim.plausibility import warn_implausible
from ..sim.scenario import load_scenario
from ..sim.simulate import Result, simulate

#: The figures of merit of a reference step compared, log against simulation.
STEP_FIGURES = ("overshoot_pct", "rise_time_s", "settling_time_s")


@dataclasses.dataclass(frozen=True)
class Comparison:
    """A log against its simulation: the log, the table written to compare.json, and the output folder."""

    log: Log
    table: dict[str, Any]
    out: str

    def lines(self) -> list[str]:
        """The speed difference, the log's notes, each reference step's figures (log / simulation), what was
        written."""
        table = self.table
        lines = [
            f"{table['scenario']} against {table['log']}: speed difference {table['speed_error_rms_rpm']:.4g} rpm "
            f"rms, {table['speed_error_max_rpm']:.4g} rpm at most"
        ]
        lines += [f"note: {note}" for note in self.log.notes]
        if table["log_metrics"] is not None:
            dt = self.log.dt_s
            for mine in table["log_metrics"]["reference_steps"]:
                same = [s for s in table["simulation_metrics"]["reference_steps"] if abs(s["t_s"] - mine["t_s"]) <= dt]
                sim = same[0] if same else dict.fromkeys(STEP_FIGURES, {"value": None})
                cells = []
                for key in STEP_FIGURES:
                    a, b = mine[key]["value"], sim[key]["value"]
                    cells.append(f"{key} {'n/a' if a is None else f'{a:.4g}'} / {'n/a' if b is None else f'{b:.4g}'}")
                lines.append(f"  step at {mine['t_s']:g} s (log / simulation): " + ", ".join(cells))
        lines.append(f"wrote compare.png, compare.json and simulation.csv to {self.out}")
        return lines


def compare_log(
    log: str,
    columns: Mapping[str, str],
    scenario: str,
    out: str,
    force: bool,
    figure: Callable[[Log, Result, Path], object],
) -> Comparison:
    """Compare the log ``log`` (read with ``columns``) with the simulation of ``scenario`` (a preset or a file);
    write compare.png (drawn by ``figure``), compare.json and simulation.csv to ``out``, all or nothing.

    Raises
    ------
    ConfigError
        The log, the scenario or ``out`` invalid, or a log whose time does not overlap the scenario's.
    """
    measured = read_log(log, columns)
    chosen = load_scenario(scenario)
    inside = (measured.t_s >= 0.0) & (measured.t_s <= chosen.simulation.t_end_s)
    if np.count_nonzero(inside) < 2:
        raise ConfigError("LOG", log, f"a log whose time overlaps the scenario's 0 to {chosen.simulation.t_end_s:g} s")
    with staged_dir(out, "compare", force) as tmp:
        result = simulate(chosen)
        error = measured.speed_rpm[inside] - np.interp(measured.t_s[inside], result.t_s, result.speed_rpm)
        i_max = chosen.limits.i_max_A
        table: dict[str, Any] = {
            "log": str(log),
            "scenario": chosen.name,
            "speed_error_rms_rpm": float(np.sqrt(np.mean(error**2))),
            "speed_error_max_rpm": float(np.max(np.abs(error))),
            "log_metrics": compute_metrics(measured, i_max_A=i_max) if measured.speed_ref_rpm is not None else None,
            "simulation_metrics": compute_metrics(result),
        }
        figure(measured, result, tmp / "compare.png")
        atomic_write(tmp / "compare.json", json.dumps(table, indent=2, allow_nan=False) + "\n")
        result.save(tmp / "simulation.csv")
    warn_implausible(chosen)
    return Comparison(measured, table, out)
