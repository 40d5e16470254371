"""Sweeps: many simulations of one base scenario, on local cores or a Dask cluster.

A sweep file (TOML) names a base scenario and the axes along which it varies::

    name = "alpha-vs-inertia"        # optional; default: the file name without .toml
    base = "paper-condition-2"       # a preset name, or a scenario file (relative to this file)
    draws = 500                      # Monte Carlo draws; required when an axis is a distribution
    seed = 7                         # seed of the draws; required when an axis is a distribution
    rank_by = "load0_speed_dip_rpm"  # metric column whose largest values are the worst cases
    worst = 3                        # number of worst-case traces drawn (default 3)

    [axes]                           # each key is a dotted scenario key
    "speed_controller.alpha_radps" = [0.25, 0.5, 1.0]                          # a list
    "motor.J_kgm2" = { start = 0.2, stop = 1.6, num = 8, scale = "log" } # a range
    "speed_controller.Ka" = { distribution = "log_normal", median = 5.0, sigma = 0.5 }

The list and range axes span a grid (their Cartesian product, in file order, the
first axis varying slowest). Distribution axes are drawn ``draws`` times; with
distribution axes every grid cell is simulated with the same ``draws`` draws
(common random numbers), so a pure Monte Carlo study has only distribution axes.
A list may hold any values the key accepts (``["none", "lowpass"]``); list entries of
the schedules are addressed by index (``"reference.0.speed_rpm"``, ``"load.0.torque_Nm"``).

Ranges: ``scale = "linear"`` (default) gives ``num`` evenly spaced values from
``start`` to ``stop`` inclusive, ``"log"`` evenly spaced logarithms (start, stop > 0).

Distributions (each axis draws from its own stream, seeded by ``seed`` and the
axis key, so adding or reordering axes does not change the other axes' draws):

- ``uniform``: ``low`` < ``high``;
- ``normal``: ``mean``, ``std`` >= 0;
- ``log_normal``: ``median`` > 0, ``sigma`` >= 0: ``median * exp(sigma * N(0, 1))``.

The base scenario is frozen with its defaults filled in, so that an axis changes its
own key only: sweeping the plant inertia ``motor.J_kgm2`` keeps the design inertia
``speed_controller.J_kgm2`` (and ``tau_i_design_s``) of the base, the
robustness question of the design of eq 9 and 11 against the true plant. An absent
``speed_controller.Ka`` stays the paper's 1/Kp of each point's design (section 3.3).

Every point is validated before anything runs (:func:`parse_sweep`). The results of a sweep
(:func:`pmsm2dof.studies.sweep_run.run_sweep`) have one row per point: ``point`` (its index), the
axis values (one column per dotted key), ``status`` ("ok", or "error" when the engine stopped with a
SimulationError, whose message is in ``error``), ``wall_time_s`` of the simulation, every metric of
:func:`pmsm2dof.sim.metrics.compute_metrics` as the columns of :func:`metric_columns` (empty when a
figure cannot be computed, with the reason in ``notes``: :func:`flatten_metrics`), and
``sampled_loop_z_max``, the largest closed-loop pole magnitude of the point's design on its
own plant and on the scenario's (:func:`pmsm2dof.studies.loopcheck.sampled_loop`; 1 or more:
unstable, and its warning in ``notes`` as the warnings of a chattering run).
"""

import hashlib
import itertools
import json
import math
import numbers
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..sim.scenario import Scenario, Tree

#: One point of a sweep: ``{dotted key: value}``.
Point = dict[str, Any]

#: Distribution names and their parameters, in the order of the docstring.
DISTRIBUTIONS = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "log_normal": ("median", "sigma"),
}
SCALES = ("linear", "log")
#: Default ranking metric of the worst cases: the integral of ``|speed reference - speed|`` over the run.
DEFAULT_RANK_BY = "run_iae_rpm_s"
_TOP_KEYS = ("name", "base", "draws", "seed", "rank_by", "worst", "axes")
#: Most points of a sweep (grid cells times draws), checked before any is made: validating one
#: takes about 2 ms and simulating the paper's drive about 10 ms (one core of the development
#: machine, benchmarks/results.md), so this many take about 3 minutes to check and 16 minutes to run.
POINTS_MAX = 100_000
#: Most worst-case traces drawn.
WORST_MAX = 20


@dataclass(frozen=True)
class Axis:
    """One swept scenario key.

    Attributes
    ----------
    key : str
        Dotted scenario key, e.g. ``"motor.J_kgm2"``.
    values : tuple or None
        The values of a list or range axis; None for a distribution axis.
    distribution : str or None
        ``"uniform"``, ``"normal"`` or ``"log_normal"`` for a distribution axis.
    params : dict or None
        Parameters of the distribution; None for list and range axes.
    """

    key: str
    values: tuple[Any, ...] | None
    distribution: str | None = None
    params: dict[str, float] | None = None

    @property
    def is_random(self) -> bool:
        """True for a distribution axis."""
        return self.distribution is not None

    def draw(self, draws: int, seed: int) -> tuple[float, ...]:
        """The ``draws`` values of a distribution axis, reproducible from ``seed`` and the key."""
        rng = np.random.default_rng(np.random.SeedSequence([seed, zlib.crc32(self.key.encode())]))
        p = self.params
        if p is None:
            raise ValueError(f"{self.key} is a list or range axis, not a distribution")
        x: npt.NDArray[np.float64]
        if self.distribution == "uniform":
            x = rng.uniform(p["low"], p["high"], draws)
        elif self.distribution == "normal":
            x = rng.normal(p["mean"], p["std"], draws)
        else:
            x = p["median"] * np.exp(p["sigma"] * rng.standard_normal(draws))
        return tuple(float(v) for v in x)


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the base scenario, the axes and every point.

    Attributes
    ----------
    name : str
    base : pmsm2dof.sim.scenario.Scenario
    axes : tuple of Axis
    draws : int or None
    seed : int or None
    rank_by : str
        Metric whose largest values are the worst cases.
    worst : int
        Number of worst-case traces to draw.
    points : tuple of dict
        One ``{dotted key: value}`` per point, in point-index order.
    """

    name: str
    base: "Scenario"
    axes: tuple[Axis, ...]
    draws: int | None
    seed: int | None
    rank_by: str
    worst: int
    points: tuple[Point, ...]

    @property
    def grid_axes(self) -> tuple[Axis, ...]:
        """The list and range axes."""
        return tuple(a for a in self.axes if not a.is_random)

    @property
    def random_axes(self) -> tuple[Axis, ...]:
        """The distribution axes."""
        return tuple(a for a in self.axes if a.is_random)

    @property
    def keys(self) -> tuple[str, ...]:
        """The dotted keys of the axes, in file order."""
        return tuple(a.key for a in self.axes)

    def digest(self) -> str:
        """SHA-256 of the base scenario and the points: equal digests mean the same runs."""
        text = json.dumps({"base": self.base.data, "points": self.points}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def scenario(self, index: int) -> "Scenario":
        """The scenario of point ``index`` (the base with the point's values)."""
        return self.base.with_overrides(self.points[index])


def load_sweep(path: Path | str) -> Sweep:
    """Read and validate a sweep file.

    Parameters
    ----------
    path : str or Path
        The sweep TOML file.

    Returns
    -------
    Sweep

    Raises
    ------
    ConfigError
        If the file is missing or malformed, or any key, axis or point is invalid.
    """
    from ..inputs import read_toml

    path = Path(path)
    data = read_toml(path, "sweep file")
    data.setdefault("name", path.stem)
    return parse_sweep(data, base_dir=path.parent)


def parse_sweep(data: Mapping[str, Any], base_dir: Path | str = ".") -> Sweep:
    """Validate a sweep description given as a dict (the parsed TOML).

    Parameters
    ----------
    data : dict
        Keys as in the module docstring.
    base_dir : str or Path
        Folder against which a relative ``base`` scenario path is resolved.

    Returns
    -------
    Sweep
    """
    from ..sim.scenario import Scenario, load_scenario

    if not isinstance(data, dict):
        raise ConfigError("sweep", data, "a table of sweep keys")
    for key in data:
        if key not in _TOP_KEYS:
            raise ConfigError(key, data[key], "not a sweep key; the keys are " + ", ".join(_TOP_KEYS))
    name = data.get("name", "sweep")
    if not isinstance(name, str) or not name.strip():
        raise ConfigError("name", name, "a non-empty string")
    base = _load_base(load_scenario, data.get("base"), Path(base_dir))
    # Freeze the defaults: an axis then changes its own key only (motor.J_kgm2 leaves the
    # design inertia speed_controller.J_kgm2 of the base as it was).
    base = Scenario.from_dict(base.data)

    raw_axes = data.get("axes")
    if not isinstance(raw_axes, dict) or not raw_axes:
        raise ConfigError("axes", raw_axes, "a table with at least one 'dotted.key = values' entry")
    axes = tuple(_parse_axis(key, spec, base.data) for key, spec in raw_axes.items())

    has_random = any(a.is_random for a in axes)
    draws = data.get("draws")
    seed = data.get("seed")
    if has_random:
        draws = _require_int(
            "draws", draws, 1, f"an integer >= 1 and <= {POINTS_MAX} (required with distribution axes)", POINTS_MAX
        )
        seed = _require_int("seed", seed, 0, "an integer >= 0 and < 2**64 (required with distribution axes)", 2**64 - 1)
    else:
        for key, value in (("draws", draws), ("seed", seed)):
            if value is not None:
                raise ConfigError(key, value, "absent: only distribution axes are drawn")

    rank_by = data.get("rank_by", DEFAULT_RANK_BY)
    columns = metric_columns(base)
    if rank_by not in columns:
        raise ConfigError("rank_by", rank_by, "a metric column of the base scenario: " + ", ".join(columns))
    worst = _require_int("worst", data.get("worst", 3), 0, f"an integer >= 0 and <= {WORST_MAX}", WORST_MAX)

    n_points = math.prod(len(a.values or ()) for a in axes if not a.is_random) * (draws or 1)
    if n_points > POINTS_MAX:
        sizes = " x ".join(
            [str(len(a.values or ())) for a in axes if not a.is_random] + ([f"{draws} draws"] if has_random else [])
        )
        raise ConfigError("axes", f"{sizes} = {n_points} points", f"at most {POINTS_MAX} points")
    points = _expand(axes, draws, seed)
    for index, point in enumerate(points):
        try:
            base.with_overrides(point)
        except ConfigError as exc:
            raise ConfigError(f"point {index} ({describe_point(point)}): {exc.param}", exc.value, exc.valid) from None
    return Sweep(name.strip(), base, axes, draws, seed, rank_by, worst, tuple(points))


def _load_base(load_scenario: Callable[[str], "Scenario"], base: object, base_dir: Path) -> "Scenario":
    if not isinstance(base, str) or not base.strip():
        raise ConfigError("base", base, "a preset name or the path of a scenario TOML file")
    candidate = base_dir / base
    if base.endswith(".toml") or "/" in base or "\\" in base:
        return load_scenario(str(candidate))
    return load_scenario(base)


def _parse_axis(key: str, spec: object, base_data: "Tree") -> Axis:
    _check_key(key, base_data)
    where = f"axes.{key}"
    if isinstance(spec, list):
        if not spec:
            raise ConfigError(where, spec, "a non-empty list of values")
        return Axis(key, tuple(spec))
    if not isinstance(spec, dict):
        raise ConfigError(where, spec, "a list, a range {start, stop, num, scale} or a distribution")
    if "distribution" in spec:
        return _parse_distribution(key, where, spec)
    if "start" in spec or "stop" in spec or "num" in spec:
        return _parse_range(key, where, spec)
    raise ConfigError(where, spec, "a list, a range {start, stop, num, scale} or a distribution")


def _parse_range(key: str, where: str, spec: Mapping[str, Any]) -> Axis:
    allowed = ("start", "stop", "num", "scale")
    _no_extra_keys(where, spec, allowed)
    start = _require_finite(f"{where}.start", spec.get("start"))
    stop = _require_finite(f"{where}.stop", spec.get("stop"))
    num = _require_int(f"{where}.num", spec.get("num"), 1, f"an integer >= 1 and <= {POINTS_MAX}", POINTS_MAX)
    scale = spec.get("scale", "linear")
    if scale not in SCALES:
        raise ConfigError(f"{where}.scale", scale, "one of " + ", ".join(repr(s) for s in SCALES))
    if scale == "log":
        for name, v in (("start", start), ("stop", stop)):
            if v <= 0:
                raise ConfigError(f"{where}.{name}", v, "> 0 for scale = 'log'")
        values = np.geomspace(start, stop, num)
    else:
        values = np.linspace(start, stop, num)
    return Axis(key, tuple(float(v) for v in values))


def _parse_distribution(key: str, where: str, spec: Mapping[str, Any]) -> Axis:
    kind = spec["distribution"]
    if kind not in DISTRIBUTIONS:
        raise ConfigError(f"{where}.distribution", kind, "one of " + ", ".join(repr(d) for d in DISTRIBUTIONS))
    names = DISTRIBUTIONS[kind]
    _no_extra_keys(where, spec, ("distribution", *names))
    params = {n: _require_finite(f"{where}.{n}", spec.get(n)) for n in names}
    if kind == "uniform" and not params["low"] < params["high"]:
        raise ConfigError(f"{where}.high", params["high"], f"> low = {params['low']!r}")
    if kind == "normal" and params["std"] < 0:
        raise ConfigError(f"{where}.std", params["std"], ">= 0")
    if kind == "log_normal":
        if params["median"] <= 0:
            raise ConfigError(f"{where}.median", params["median"], "> 0")
        if params["sigma"] < 0:
            raise ConfigError(f"{where}.sigma", params["sigma"], ">= 0")
    return Axis(key, None, kind, params)


def _check_key(key: str, base_data: "Tree") -> None:
    """The dotted key must name a value of the scenario (a list element by its index)."""
    node: Any = base_data
    for i, part in enumerate(key.split(".")):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            raise ConfigError(
                "axes",
                key,
                "dotted keys of the base scenario, e.g. 'motor.J_kgm2' "
                "or 'reference.0.speed_rpm'" + (f" (no '{part}' here)" if i else ""),
            )
    if isinstance(node, (dict, list)):
        raise ConfigError("axes", key, "a key holding one value, not a table or list")


def _expand(axes: Sequence[Axis], draws: int | None, seed: int | None) -> list[Point]:
    """Every point: the grid of list/range axes times the draws of the distribution axes."""
    grid = [a for a in axes if not a.is_random]
    random = [a for a in axes if a.is_random]
    drawn = {a.key: a.draw(cast(int, draws), cast(int, seed)) for a in random}  # given with random axes
    n_draws = cast(int, draws) if random else 1
    points: list[Point] = []
    for cell in itertools.product(*(a.values or () for a in grid)):
        for d in range(n_draws):
            values = dict(zip((a.key for a in grid), cell))
            values.update({a.key: drawn[a.key][d] for a in random})
            points.append({a.key: values[a.key] for a in axes})
    return points


def describe_point(point: Mapping[str, Any]) -> str:
    """A point as ``key=value, ...``, to name it in a message."""
    return ", ".join(f"{k}={v!r}" for k, v in point.items())


def _no_extra_keys(where: str, spec: Mapping[str, Any], allowed: Iterable[str]) -> None:
    for k in spec:
        if k not in allowed:
            raise ConfigError(f"{where}.{k}", spec[k], "not a key here; the keys are " + ", ".join(allowed))


def _require_finite(param: str, value: object) -> float:
    if not isinstance(value, numbers.Real) or isinstance(value, bool) or not math.isfinite(value):
        raise ConfigError(param, value, "a finite number")
    return float(value)


def _require_int(param: str, value: object, minimum: int, valid: str, maximum: int | None = None) -> int:
    if not isinstance(value, numbers.Integral) or isinstance(value, bool):
        raise ConfigError(param, value, valid)
    if int(value) < minimum or (maximum is not None and int(value) > maximum):
        raise ConfigError(param, value, valid)
    return int(value)


# ---------------------------------------------------------------------------------------------
# Result columns
# ---------------------------------------------------------------------------------------------


def metric_columns(scenario: "Scenario") -> list[str]:
    """Names of the metric columns for ``scenario``, in table order.

    ``ref{i}_<figure>`` for the i-th entry of ``reference``, ``load{j}_<figure>`` for the j-th
    entry of ``load`` and ``run_<figure>`` for the whole run (figures of
    :func:`pmsm2dof.sim.metrics.compute_metrics`).
    """
    from ..sim.event_figures import LOAD_FIGURES, REFERENCE_FIGURES
    from ..sim.metrics import RUN_FIGURES

    columns = [f"ref{i}_{f}" for i in range(len(scenario.reference)) for f in REFERENCE_FIGURES]
    columns += [f"load{j}_{f}" for j in range(len(scenario.load)) for f in LOAD_FIGURES]
    columns += [f"run_{f}" for f in RUN_FIGURES]
    return columns + ["sampled_loop_z_max"]


def flatten_metrics(metrics: Mapping[str, Any]) -> tuple[dict[str, Any], str]:
    """The figures of ``compute_metrics`` as ``{column: value or None}`` and the reasons of the None."""
    from ..sim.event_figures import LOAD_FIGURES, REFERENCE_FIGURES
    from ..sim.metrics import RUN_FIGURES

    figures: dict[str, dict[str, Any]] = {}
    for prefix, steps, names in (
        ("ref", metrics["reference_steps"], REFERENCE_FIGURES),
        ("load", metrics["load_steps"], LOAD_FIGURES),
    ):
        for i, step in enumerate(steps):
            figures.update({f"{prefix}{i}_{name}": step[name] for name in names})
    figures.update({f"run_{name}": metrics["run"][name] for name in RUN_FIGURES})
    loop = metrics["sampled_loop"]
    checked = [p["z_max"] for p in (loop["design"], loop["plant"]) if p]
    figures["sampled_loop_z_max"] = {"value": max(checked)} if checked else {"value": None, "reason": loop["warning"]}
    notes = "; ".join(
        [*metrics["warnings"], *(f"{col}: {fig['reason']}" for col, fig in figures.items() if fig["value"] is None)]
    )
    return {col: fig["value"] for col, fig in figures.items()}, notes
