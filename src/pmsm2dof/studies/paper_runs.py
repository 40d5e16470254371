"""The runs of the paper reproduction: the paper's conditions, the linear runs, the sensitivity sweeps.

Each is a :class:`RunSpec`, a preset changed by overrides, which :func:`pmsm2dof.studies.paper.run_studies`
simulates with the study's common overrides:

Paper runs (:func:`paper_runs`)
    Simulation conditions 1 and 2 of section 4.1 (Fig. 8 to 10) and experimental conditions 1 to 3
    of section 4.2 (Fig. 12 to 14) as simulations, each with the 1DOF PI (feedforward ``none``)
    and the 2DOF controller of the presets (the low-pass feedforward of eq 13, discretized as
    eq 15), and in conditions 1 and experiment 1 with each anti-windup mode.

Linear runs (:func:`linear_runs`)
    A small step from rest, which leaves the current far from its limit, with the
    feedforward of eq 12 and of eq 13: the linear tracking the design promises (eq 10).

Sensitivity sweeps (:func:`sweeps`)
    One 500 rpm step from rest (``paper-experiment-1``, run for :data:`STEP_T_END_S` so that
    slow designs settle) and one 8 Nm load step at a steady 500 rpm (``paper-experiment-3``),
    against the back-calculation gain Ka (Fig. 5), the tracking pole factor m (eq 10), the
    damping zeta (eq 9), the inertia error (true J against the design J of eq 9, 11) and the
    torque the current limit allows (the paper gives the 7.6 A limit but not the torque constant).

Engine runs of the discretization study (:func:`discretization_runs`)
    A small, unsaturated step at a few speed-loop periods, a check of the discrete design's prediction.
"""

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..core import METHODS, pi_gains
from ..core.bindings import AntiWindup, Feedforward
from ..errors import ConfigError
from ..sim.scenario import Scenario

#: The presets every study starts from.
PRESETS = ("paper-condition-1", "paper-condition-2", "paper-experiment-1", "paper-experiment-2", "paper-experiment-3")
#: Preset of the step sweeps: no load, one 500 rpm step from rest at 0.5 s.
STEP_BASE = "paper-experiment-1"
#: Preset of the load sweeps: steady 500 rpm, an 8 Nm load step at 0.5 s.
LOAD_BASE = "paper-experiment-3"
#: Simulated time of the step sweeps [s]: m = 0.2 puts the tracking pole at 0.1 rad/s (2 % in 39 s).
STEP_T_END_S = 60.0
#: Points per sensitivity sweep in the full study.
POINTS = 9
#: Periods of the discretization study also run in the engine [s].
TS_ENGINE_S = (1e-3, 0.1, 0.3, 0.5)
#: Small speed step of the linear runs [rpm]: even the derivative kick of eq 11 (J alpha m tau_i / Ts per
#: rad/s of step) stays below the current limit.
SMALL_STEP_RPM = 2.0

ONE_DOF = "1DOF PI"
TWO_DOF = "2DOF eq 15"
#: Feedforward of each controller compared in the paper (section 4.1): eq 13 discretized as eq 15.
FEEDFORWARD: dict[str, Feedforward] = {ONE_DOF: "none", TWO_DOF: "lowpass"}
#: Anti-windup modes, as the scenario names them, and as the report labels them.
AW_LABELS: dict[AntiWindup, str] = {"none": "no AW", "back_calculation": "back-calculation AW", "clamping": "clamping"}


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One simulation: a preset, changed by ``overrides`` (after the study's common overrides)."""

    name: str
    preset: str
    overrides: dict[str, Any]


def _controller(label: str, anti_windup: AntiWindup = "back_calculation") -> dict[str, Any]:
    return {"speed_controller.feedforward": FEEDFORWARD[label], "speed_controller.anti_windup": anti_windup}


def paper_runs() -> list[RunSpec]:
    """The runs of the paper's simulation and experimental conditions (section 4), by name.

    ``c1``, ``c2``: simulation conditions 1 and 2; ``e1`` to ``e3``: experimental conditions 1 to 3;
    ``1dof`` / ``2dof``: feedforward none / lowpass; the last part is the anti-windup mode.
    """
    runs: list[RunSpec] = []
    for cond, preset in (("c1", "paper-condition-1"), ("e1", "paper-experiment-1")):
        for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF)):
            for aw in AW_LABELS:
                runs.append(RunSpec(f"{cond}-{dof}-{aw}", preset, _controller(label, aw)))
    runs.append(RunSpec("e1-2dof-full", "paper-experiment-1", {"speed_controller.feedforward": "full"}))
    for cond, preset in (("c2", "paper-condition-2"), ("e2", "paper-experiment-2"), ("e3", "paper-experiment-3")):
        for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF)):
            runs.append(RunSpec(f"{cond}-{dof}", preset, _controller(label)))
    return runs


@dataclasses.dataclass(frozen=True)
class Series:
    """One line of a sweep: a run per x value; ``kind`` is ``"step"`` or ``"load"``."""

    label: str
    kind: str
    runs: tuple[RunSpec, ...]


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A sensitivity study: the same figures measured along one parameter.

    Attributes
    ----------
    name : str
        Short name, used in file names (``ka``, ``m``, ``zeta``, ``inertia``, ``torque_limit``).
    title : str
        What varies, in words.
    x_label : str
        Axis label of the varied parameter, with its unit.
    x_column : str
        Name of the varied parameter in data files, ending with its unit (none: dimensionless).
    x : tuple of float
        The values.
    series : tuple of Series
        The lines, each a run per value.
    references : tuple of (str, RunSpec)
        Runs that do not depend on x, drawn as horizontal lines (label, run).
    marks : tuple of (float, str)
        Vertical lines: the presets' value.
    bands : tuple of (float, float, str)
        Shaded x ranges.
    log_x : bool
        Logarithmic x axis.
    """

    name: str
    title: str
    x_label: str
    x_column: str
    x: tuple[float, ...]
    series: tuple[Series, ...]
    references: tuple[tuple[str, RunSpec], ...] = ()
    marks: tuple[tuple[float, str], ...] = ()
    bands: tuple[tuple[float, float, str], ...] = ()
    log_x: bool = False

    def runs(self) -> list[RunSpec]:
        """Every run of the sweep."""
        return [r for s in self.series for r in s.runs] + [r for _, r in self.references]


def _unique(values: Iterable[float]) -> tuple[float, ...]:
    """``values`` sorted, those equal to 12 significant digits taken once (the last of them)."""
    return tuple(sorted({float(f"{v:.12g}"): float(v) for v in values}.values()))


def _geom(lo: float, hi: float, n: int, *include: float) -> tuple[float, ...]:
    """``n`` log-spaced values from ``lo`` to ``hi``, with the values ``include`` added (exactly), sorted."""
    return _unique([*np.geomspace(lo, hi, n), *include])


def _step(label: str, name: str, overrides: dict[str, Any], anti_windup: AntiWindup = "back_calculation") -> RunSpec:
    return RunSpec(name, STEP_BASE, {"simulation.t_end_s": STEP_T_END_S} | _controller(label, anti_windup) | overrides)


def _load(label: str, name: str, overrides: dict[str, Any]) -> RunSpec:
    return RunSpec(name, LOAD_BASE, _controller(label) | overrides)


def sweeps(bases: Mapping[str, Scenario], points: int = POINTS) -> list[Sweep]:
    """The sensitivity sweeps around the presets ``bases`` (preset name -> Scenario).

    Parameters
    ----------
    bases : dict
        The presets of :data:`PRESETS` as run (with the study's common overrides).
    points : int
        Values per sweep, >= 2 (odd values put the preset's value at the centre of the
        log-spaced sweeps).

    Returns
    -------
    list of Sweep
    """
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise ConfigError("points", points, "an integer >= 2")
    step_data = bases[STEP_BASE]
    sc = step_data.speed_controller
    J_design = sc.J_kgm2
    Kp, _ = pi_gains(J_design, sc.alpha_radps, sc.zeta)  # eq 9
    out = []

    # Ka (Fig. 5): the range the paper gives, read as 1/(3 Kp) .. 3/Kp, and its literal Kp/3 .. 3 Kp
    used = _geom(1.0 / (3.0 * Kp), 3.0 / Kp, points, 1.0 / Kp)
    literal = _geom(Kp / 3.0, 3.0 * Kp, max(2, points // 2 + 1))
    ka = _unique(literal + used)
    out.append(
        Sweep(
            "ka",
            "back-calculation gain Ka",
            "Ka [(rad/s)/Nm]",
            "Ka_radps_per_Nm",
            ka,
            tuple(
                Series(
                    label,
                    "step",
                    tuple(_step(label, f"ka-{dof}-{i}", {"speed_controller.Ka": v}) for i, v in enumerate(ka)),
                )
                for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF))
            ),
            references=tuple(
                (f"{label}, {AW_LABELS[aw]}", _step(label, f"ka-{dof}-{aw}", {}, aw))
                for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF))
                for aw in ("none", "clamping")
            ),
            marks=((1.0 / Kp, "1/Kp (preset)"),),
            bands=(
                (1.0 / (3.0 * Kp), 3.0 / Kp, "1/(3Kp) .. 3/Kp (used)"),
                (Kp / 3.0, 3.0 * Kp, "Kp/3 .. 3Kp (literal)"),
            ),
            log_x=True,
        )
    )

    # m (eq 10, 11): the full feedforward, whose Gx is m alpha / (s + m alpha)
    m_values = tuple(float(v) for v in np.linspace(0.2, 2.0, points + 1))
    full = {"speed_controller.feedforward": "full"}
    out.append(
        Sweep(
            "m",
            "tracking pole factor m (feedforward eq 11)",
            "m [-]",
            "m",
            m_values,
            (
                Series(
                    "2DOF eq 11, back-calculation AW",
                    "step",
                    tuple(
                        RunSpec(
                            f"m-bc-{i}",
                            STEP_BASE,
                            {"simulation.t_end_s": STEP_T_END_S, **full, "speed_controller.m": m},
                        )
                        for i, m in enumerate(m_values)
                    ),
                ),
                Series(
                    "2DOF eq 11, no AW",
                    "step",
                    tuple(
                        RunSpec(
                            f"m-none-{i}",
                            STEP_BASE,
                            {
                                "simulation.t_end_s": STEP_T_END_S,
                                **full,
                                "speed_controller.m": m,
                                "speed_controller.anti_windup": "none",
                            },
                        )
                        for i, m in enumerate(m_values)
                    ),
                ),
                Series(
                    "2DOF eq 11, back-calculation AW",
                    "load",
                    tuple(
                        RunSpec(f"m-load-{i}", LOAD_BASE, {**full, "speed_controller.m": m})
                        for i, m in enumerate(m_values)
                    ),
                ),
            ),
            marks=((sc.m, "preset"),),
        )
    )

    # zeta (eq 9)
    zeta = _geom(0.2, 1.0, points, sc.zeta)
    out.append(
        Sweep(
            "zeta",
            "relative damping zeta (eq 9)",
            "zeta [-]",
            "zeta",
            zeta,
            _both_controllers("zeta", zeta, "speed_controller.zeta"),
            marks=((sc.zeta, "preset"),),
            log_x=True,
        )
    )

    # inertia error: the plant's J from 0.5 to 2 times the J the controller is designed for
    ratios = _geom(0.5, 2.0, points, 1.0)
    series = []
    for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF)):
        for kind, make in (("step", _step), ("load", _load)):
            series.append(
                Series(
                    label,
                    kind,
                    tuple(
                        make(
                            label,
                            f"inertia-{kind}-{dof}-{i}",
                            {"motor.J_kgm2": r * J_design, "speed_controller.J_kgm2": J_design},
                        )
                        for i, r in enumerate(ratios)
                    ),
                )
            )
    out.append(
        Sweep(
            "inertia",
            "inertia error (true J / design J)",
            "true J / design J [-]",
            "J_over_J_design",
            ratios,
            tuple(series),
            marks=((1.0, "J = design J"),),
            log_x=True,
        )
    )

    # torque limit: the torque constant 1.5 p psi_f that turns the 7.6 A limit into torque is not in the paper
    motor, limits = step_data.motor, step_data.limits
    psi_f = _geom(0.4 * motor.psi_f_Wb, 2.5 * motor.psi_f_Wb, points, motor.psi_f_Wb)
    torque_limit = tuple(1.5 * motor.pole_pairs * v * limits.i_max_A for v in psi_f)
    out.append(
        Sweep(
            "torque_limit",
            "torque the current limit allows, 1.5 p psi_f i_max (1DOF PI)",
            "torque limit [Nm]",
            "torque_limit_Nm",
            torque_limit,
            tuple(
                Series(
                    f"{ONE_DOF}, {AW_LABELS[aw]}",
                    "step",
                    tuple(_step(ONE_DOF, f"torque-{aw}-{i}", {"motor.psi_f_Wb": v}, aw) for i, v in enumerate(psi_f)),
                )
                for aw in AW_LABELS
            ),
            marks=((1.5 * motor.pole_pairs * motor.psi_f_Wb * limits.i_max_A, "preset"),),
            log_x=True,
        )
    )
    return out


def _both_controllers(name: str, values: Sequence[float], key: str) -> tuple[Series, ...]:
    series = []
    for dof, label in (("1dof", ONE_DOF), ("2dof", TWO_DOF)):
        for kind, make in (("step", _step), ("load", _load)):
            series.append(
                Series(
                    label, kind, tuple(make(label, f"{name}-{kind}-{dof}-{i}", {key: v}) for i, v in enumerate(values))
                )
            )
    return tuple(series)


def _small_step(name: str, overrides: dict[str, Any]) -> RunSpec:
    """A step of :data:`SMALL_STEP_RPM` from rest at 0.5 s, no load: the current stays below its limit.

    From rest rather than at speed, so that the float32 resolution of a large speed reference
    (about 1e-7 of it per operation) stays far below the step.
    """
    return RunSpec(
        name,
        STEP_BASE,
        {"simulation.t_end_s": 20.0, "reference": [{"t_s": 0.5, "speed_rpm": SMALL_STEP_RPM}]} | overrides,
    )


def linear_runs() -> list[RunSpec]:
    """Runs of the 2DOF controller in the linear range (a small step): eq 13 against eq 12 (m = 1).

    Named ``lin-lowpass`` and ``lin-full``; their traces are kept.
    """
    return [
        _small_step(f"lin-{ff}", {"speed_controller.feedforward": ff, "speed_controller.m": 1.0})
        for ff in ("lowpass", "full")
    ]


def discretization_runs(Ts_engine: Sequence[float] = TS_ENGINE_S) -> list[RunSpec]:
    """Engine runs of the 1DOF PI at a few speed-loop periods: a small step from rest.

    The step of :data:`SMALL_STEP_RPM` leaves the current far from its limit, so the loop stays
    linear and its overshoot can be compared with that of the discrete design.
    """
    return [
        _small_step(
            f"disc-{method}-{Ts:g}",
            {
                "speed_controller.feedforward": "none",
                "speed_controller.method": method,
                "speed_controller.Ts_s": Ts,
            },
        )
        for method in METHODS
        for Ts in Ts_engine
    ]
