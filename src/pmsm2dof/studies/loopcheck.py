"""The sampled-loop stability check of a scenario's speed controller, reported with a run's figures.

``pmsm2dof design`` refuses a design whose sampled loop is unstable
(:func:`pmsm2dof.analysis.discretize.discretize`). A simulation, a sweep, an autotuning, the
tuner and the paper's reproduction run such a design all the same, because a user may want to
see it; the current limit then holds the growing oscillation in a limit cycle, whose figures
(overshoot, settling) can look excellent. :func:`measure` therefore adds to the figures of
:func:`pmsm2dof.sim.metrics.compute_metrics` the same check on the scenario's design, and a
warning when it fails:

- on the design's own plant (``speed_controller.J_kgm2``, ``speed_controller.tau_i_s``): what
  ``pmsm2dof design`` checks;
- on the scenario's plant (``motor.J_kgm2``, with ``mechanics.J_load_kgm2`` for a two-mass train
  taken as one body, and ``current_loop.tau_i_s``), when it differs: an inertia typed in the
  wrong unit for the design makes a loop that is stable on paper and unstable on the drive.

Both with the design's speed-sensor chain (``[speed_sensor]``, :class:`~pmsm2dof.analysis.sensor.SensorChain`)
and the controller the C code realizes (:func:`pmsm2dof.analysis.sampled_loop.sampled_loop_poles`).

A scenario the engine runs may lie beyond what the analysis takes: a sensor delay longer than
:data:`~pmsm2dof.analysis.sensor.DELAY_PERIODS_MAX` speed-loop periods (the scenario allows
2046 current-loop periods; the analysis has a state per speed period, and its work is bounded), or
one too short for its Pade approximant (:func:`pmsm2dof.analysis.design.design`). The check is then
not made, and its warning says so and why, naming the scenario key.
"""

from typing import TYPE_CHECKING, Any

from ..analysis.sampled_loop import sampled_loop_poles
from ..errors import ConfigError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario
from .configuration import scenario_design

if TYPE_CHECKING:
    from ..sim.simulate import Result


def plant_inertia_kgm2(scenario: Scenario) -> float:
    """The inertia the speed loop drives: ``motor.J_kgm2``, plus ``mechanics.J_load_kgm2`` for a two-mass train."""
    J = scenario.motor.J_kgm2
    J_load = scenario.mechanics.J_load_kgm2
    return J + J_load if scenario.mechanics.model == "two_mass" and J_load is not None else J


def sampled_loop(scenario: Scenario) -> dict[str, Any]:
    """The sampled-loop stability check of ``scenario``'s speed controller (see the module docstring).

    Returns
    -------
    dict
        JSON-ready: ``stable`` (both loops), ``design`` and ``plant`` (each ``J_kgm2``,
        ``tau_i_s``, ``z_max``: the largest pole magnitude, ``stable``; ``plant`` is None when
        it is the design's), and ``warning`` (one sentence; empty when stable). When the
        analysis does not take the scenario (see the module docstring), ``stable``, ``design``
        and ``plant`` are None and the warning gives the reason.
    """
    sc = scenario.speed_controller
    try:
        d = scenario_design(scenario)

        def check(J_kgm2: float, tau_i_s: float) -> dict[str, Any]:
            poles, stable = sampled_loop_poles(d, sc.Ts_s, sc.method, J_kgm2, tau_i_s)
            return {"J_kgm2": J_kgm2, "tau_i_s": tau_i_s, "z_max": max(abs(p) for p in poles), "stable": stable}

        own = check(d.J_kgm2, d.tau_i_s)
        J_plant, tau_plant = plant_inertia_kgm2(scenario), scenario.current_loop.tau_i_s
        plant = None if (J_plant, tau_plant) == (d.J_kgm2, d.tau_i_s) else check(J_plant, tau_plant)
    except ConfigError as exc:
        key = _SCENARIO_KEYS.get(exc.param, exc.param)
        refused = ConfigError(key, exc.value, exc.valid)
        warning = f"the sampled-loop stability check was not made: the analysis does not take {refused}"
        return {"stable": None, "design": None, "plant": None, "warning": warning}
    where = f"alpha_radps = {d.alpha_radps:g} rad/s, zeta = {d.zeta:g}, Ts_s = {sc.Ts_s:g} s, {sc.method}"
    warning = ""
    if not own["stable"]:
        warning = (
            f"UNSTABLE SAMPLED LOOP: the speed controller's design ({where}, J_kgm2 = {d.J_kgm2:g}, tau_i_s = "
            f"{d.tau_i_s:g} s) has its largest closed-loop pole at |z| = {own['z_max']:.6g}, as `pmsm2dof design` "
            "says when it refuses it; what the run shows is held by the current limit"
        )
    elif plant is not None and not plant["stable"]:
        warning = (
            f"UNSTABLE SAMPLED LOOP: the speed controller designed for J_kgm2 = {d.J_kgm2:g} ({where}) has its "
            f"largest closed-loop pole at |z| = {plant['z_max']:.6g} on the scenario's plant (J = {J_plant:g} "
            f"kg m^2, {J_plant / d.J_kgm2:.3g} times the design's; tau_i_s = {tau_plant:g} s); what the run shows "
            "is held by the current limit"
        )
    return {"stable": own["stable"] and (plant is None or plant["stable"]), "design": own, "plant": plant} | {
        "warning": warning
    }


#: The scenario keys of the analysis' parameters, for the reason a check was not made.
_SCENARIO_KEYS = {
    **{name: f"speed_sensor.{name}" for name in ("delay_s", "lowpass_radps", "bandwidth_radps")},
    **{name: f"speed_controller.{name}" for name in ("J_kgm2", "alpha_radps", "zeta", "m", "tau_i_s", "Ka", "Ts_s")},
}


def measure(result: "Result") -> dict[str, Any]:
    """:func:`pmsm2dof.sim.metrics.compute_metrics` of a run, with its ``sampled_loop`` check
    (:func:`sampled_loop`) and that check's warning first among the ``warnings``."""
    metrics = compute_metrics(result)
    check = sampled_loop(result.scenario)
    metrics["sampled_loop"] = check
    if check["warning"]:
        metrics["warnings"] = [check["warning"], *metrics["warnings"]]
    return metrics
