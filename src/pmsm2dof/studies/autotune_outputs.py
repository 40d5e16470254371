"""What ``pmsm2dof autotune`` prints and writes: an autotuning with its outputs, and its summary.

:func:`run_autotune` checks the output folder before the search, runs
:func:`pmsm2dof.studies.autotune_search.autotune` and writes, all or nothing
(:func:`pmsm2dof.outputs.staged_dir`), the folder of :data:`FILES` and the C header of the chosen
design; :func:`summary` is the text the command prints.
"""

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..outputs import atomic_write, check_file, check_out, csv_text, staged_dir
from ..sim.scenario import Scenario
from .autotune import CONSTRAINTS, AutotuneResult, Spec
from .autotune_search import autotune

#: The files of an autotuning's output folder (``pareto.png`` when a figure writer is given).
FILES = ("scenario.toml", "autotune.json", "pareto.csv", "pareto.png", "runs.csv", "rejected.csv")
#: Draws the Pareto figure of a result into a file (:func:`pmsm2dof.ui.plots.autotune.plot_pareto`).
FigureWriter = Callable[[AutotuneResult, Path], Any]


def run_autotune(
    scenario: Scenario,
    spec: Spec | None = None,
    *,
    out: Path | str | None = None,
    force: bool = False,
    header: Path | str | None = None,
    figure: FigureWriter | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> AutotuneResult:
    """Autotune ``scenario`` to ``spec`` and write the outputs asked for.

    Parameters
    ----------
    scenario, spec, workers, scheduler, progress
        As :func:`pmsm2dof.studies.autotune_search.autotune`.
    out : path, optional
        Output folder of the kind ``"autotune"`` (:func:`pmsm2dof.outputs.check_out`, checked before
        the search): ``scenario.toml`` (the tuned scenario), ``autotune.json``
        (:meth:`AutotuneResult.as_dict`), ``pareto.csv``, ``runs.csv``, ``rejected.csv`` (the rows of
        :meth:`AutotuneResult.pareto_rows`, :meth:`~AutotuneResult.runs_rows`,
        :meth:`~AutotuneResult.rejected_rows`) and ``pareto.png`` (drawn by ``figure``).
    force : bool
        Write into an output folder that holds other files (they are kept).
    header : path, optional
        The C header of the chosen design (:meth:`AutotuneResult.write_c_header`; checked before the
        search); written with the folder, when there is one.
    figure : callable, optional
        ``figure(result, path)`` draws ``pareto.png``; None: no figure.

    Returns
    -------
    AutotuneResult

    Raises
    ------
    ConfigError
        As :func:`~pmsm2dof.studies.autotune_search.autotune`; ``out`` not a folder this command
        may write, ``header`` not a file that can be written (both before the search).
    """
    if out is not None:
        check_out(out, "autotune", force)
    if header is not None:
        check_file(header, "header")
    result = autotune(scenario, spec, workers=workers, scheduler=scheduler, progress=progress)
    if out is None:
        if header is not None:
            result.write_c_header(header)
        return result
    with staged_dir(out, "autotune", force) as tmp:
        atomic_write(tmp / "scenario.toml", result.tuned_scenario().to_toml())
        atomic_write(tmp / "autotune.json", json.dumps(result.as_dict(), indent=2, allow_nan=False) + "\n")
        atomic_write(tmp / "pareto.csv", csv_text(result.pareto_rows()))
        atomic_write(tmp / "runs.csv", csv_text(result.runs_rows()))
        atomic_write(tmp / "rejected.csv", csv_text(result.rejected_rows()))
        if figure is not None:
            figure(result, tmp / "pareto.png")
        if header is not None:
            result.write_c_header(header)
    return result


def summary(
    result: AutotuneResult, scenario: str, out: Path | str | None = None, header: Path | str | None = None
) -> str:
    """The summary of an autotuning: outcome, chosen keys, worst case, how to reproduce it.

    ``scenario`` is the preset or file as the user named it (for the command that reproduces the
    design); ``out`` and ``header`` those :func:`run_autotune` wrote, named in a last line.
    """
    data = result.as_dict()
    lo, hi = result.spec.J_range
    counts = data["counts"]
    lines = [
        f"{result.scenario.name}: {counts['candidates']} designs ({counts['rejected_by_margins']} rejected by the "
        f"margins alone), {counts['runs']} simulations over J ratio {lo:g} to {hi:g}, in {result.wall_time_s:.3g} s",
    ]
    if result.scenario_loop["warning"]:
        lines.append(f"WARNING: the scenario as given: {result.scenario_loop['warning']}")
    if result.feasible:
        lines.append(f"the design below meets the specification ({counts['feasible']} designs did)")
    else:
        lines.append("NO design meets the specification; the one below misses it least:")
        lines += [f"  misses {v.describe()}" for v in result.chosen.violations]
        if result.chosen.error:
            lines.append(f"  {result.chosen.error}")
        if result.binding is not None:
            lines.append(f"binding constraint: {result.binding.constraint}, missed by {result.binding.miss:.4g}")
    for key, value in result.speed_controller.items():
        lines.append(f"  speed_controller.{key} = {value}")
    lines.append("worst case over the inertia range (J ratio where it occurs):")
    units = {figure: unit for figure, _sense, unit in CONSTRAINTS.values()} | {
        "tracking_iae_rpm_s": "rpm s",
        "load_iae_rpm_s_per_Nm": "rpm s/Nm",
        "chatter_share": "",
    }
    for name, value in data["worst_case"].items():
        shown = "inf (never settles in its window)" if value is None and name == "settling_time_s" else value
        if isinstance(shown, float):
            shown = f"{shown:.4g} {units[name]}".rstrip()
        shown = "inf" if shown is None else shown
        lines.append(f"  {name:<22} {shown}  ({data['worst_J_ratio'][name]:.4g})")
    lines += [f"NOTE: {sentence}" for sentence in result.on_bounds]
    sets = " ".join(f"--set speed_controller.{k}={v}" for k, v in result.speed_controller.items())
    lines.append(f"reproduce: pmsm2dof simulate {scenario} {sets} --out DIR")
    written = [f"{out}/" if out is not None else "", str(header or "")]
    if any(written):
        lines.append("wrote " + " and ".join(w for w in written if w))
    return "\n".join(lines)
