"""The tuner's controls: the scenario keys the page sets, their ranges and initial values.

The tuner's experiment is the base scenario: every entry of its ``reference`` and ``load``
schedules, and its faults. The controls are

- scenario keys, applied as overrides of the base scenario (``speed_controller.alpha_radps``,
  ``zeta``, ``m``, ``Ka``, ``feedforward``, ``anti_windup``, ``method``, ``Ts_s``,
  ``simulation.t_end_s``, and ``reference.<i>.t_s``, ``reference.<i>.speed_rpm``,
  ``load.<i>.t_s``, ``load.<i>.torque_Nm`` of the first :data:`ENTRY_CONTROLS_MAX` entries of
  each schedule; later entries run as the scenario has them), and
- ``tuner.J_ratio`` (true inertia / design inertia: the design inertia stays that of the base
  scenario and ``motor.J_kgm2`` follows the ratio).
"""

from collections.abc import Iterable
from typing import Any

from ...core import ANTI_WINDUPS, FEEDFORWARDS, METHODS
from ...sim.scenario import Scenario

#: Entries of each schedule (reference, load) of the base scenario that get controls.
ENTRY_CONTROLS_MAX = 6
#: The keys of the speed controller that are controls.
SPEED_CONTROLLER_CONTROLS = ("alpha_radps", "zeta", "m", "Ka", "feedforward", "anti_windup", "method", "Ts_s")
#: Schedules of the experiment: (name, value key, label, unit).
SCHEDULES = (("reference", "speed_rpm", "reference", "rpm"), ("load", "torque_Nm", "load", "Nm"))


def initial_values(scenario: Scenario) -> dict[str, Any]:
    """The control values of ``scenario``: ``{control key: value}``, in the page's order."""
    sc, sim = scenario.speed_controller, scenario.simulation
    values = {f"speed_controller.{k}": getattr(sc, k) for k in SPEED_CONTROLLER_CONTROLS}
    values["tuner.J_ratio"] = scenario.motor.J_kgm2 / scenario.speed_controller.J_kgm2
    for name, value_key, _, _ in SCHEDULES:
        for i, entry in enumerate(getattr(scenario, name)[:ENTRY_CONTROLS_MAX]):
            values[f"{name}.{i}.t_s"] = entry.t_s
            values[f"{name}.{i}.{value_key}"] = getattr(entry, value_key)
    values["simulation.t_end_s"] = sim.t_end_s
    return values


def page_controls(base: Scenario) -> dict[str, Any]:
    """Description of the page's controls: groups of specs with ranges and initial values.

    A spec has ``key``, ``label``, ``unit``, ``kind`` ('slider' or 'select'), ``value``;
    sliders have ``min``, ``max``, ``scale`` ('lin' or 'log') and optionally ``quantum``
    (values are integer multiples of it) and ``nullable`` (a checkbox sends null);
    ``enabled_when = [key, [choices]]`` disables a control unless another has one of the
    choices (``value_when_disabled`` is then sent). Ranges are only those of the sliders:
    any value can be typed, and the server validates it. A group may carry a ``note``.
    """
    v = initial_values(base)
    J_design_kgm2 = base.speed_controller.J_kgm2
    motor, limits = base.motor, base.limits
    alpha = v["speed_controller.alpha_radps"]
    Kp = J_design_kgm2 * alpha
    Ts_cl = base.current_loop.Ts_s
    torque_max_Nm = 1.5 * motor.pole_pairs * motor.psi_f_Wb * limits.i_max_A
    t_end = v["simulation.t_end_s"]

    def slider(
        key: str, label: str, unit: str, lo: float, hi: float, scale: str = "lin", **extra: Any
    ) -> dict[str, Any]:
        return dict(key=key, label=label, unit=unit, kind="slider", min=lo, max=hi, scale=scale, value=v[key], **extra)

    def select(key: str, label: str, choices: Iterable[str], **extra: Any) -> dict[str, Any]:
        return dict(key=key, label=label, unit="", kind="select", choices=list(choices), value=v[key], **extra)

    experiment = [
        slider(
            "tuner.J_ratio",
            "true J / design J",
            "",
            0.25,
            4.0,
            "log",
            help=f"design inertia {J_design_kgm2:g} kg m^2 stays; the plant's changes",
        )
    ]
    notes: list[str] = []
    for name, value_key, label, unit in SCHEDULES:
        entries = getattr(base, name)
        values = [getattr(e, value_key) for e in entries]
        if name == "reference":  # the scenario has at least one reference entry
            top = 3 * (max(abs(x) for x in values) or 500.0)
            lo, hi = (-top if min(values) < 0 else 0.0), top
        else:
            lo, hi = -torque_max_Nm, torque_max_Nm
        for i in range(min(len(entries), ENTRY_CONTROLS_MAX)):
            experiment.append(
                slider(f"{name}.{i}.{value_key}", f"{label} {i + 1}", unit, lo, hi, help=f"{name}.{i}.{value_key}")
            )
            experiment.append(slider(f"{name}.{i}.t_s", f"{label} {i + 1} at", "s", 0.0, t_end, help=f"{name}.{i}.t_s"))
        if len(entries) > ENTRY_CONTROLS_MAX:
            notes.append(f"{name} entries {ENTRY_CONTROLS_MAX + 1} to {len(entries)} run as the scenario has them")
    t_last = max(v[key] for key in v if key.endswith(".t_s"))
    t_end_min = 1.05 * t_last if t_end / 10 < 1.05 * t_last < t_end else t_end / 10
    experiment.append(slider("simulation.t_end_s", "simulated time", "s", t_end_min, t_end * 10, "log"))

    groups = [
        {
            "legend": "PI design (eq 9, 10)",
            "controls": [
                slider("speed_controller.alpha_radps", "\u03b1 bandwidth", "rad/s", alpha / 10, alpha * 10, "log"),
                slider("speed_controller.zeta", "\u03b6 damping", "", 0.1, 2.0, "log"),
                slider(
                    "speed_controller.m",
                    "m tracking pole",
                    "",
                    0.1,
                    10.0,
                    "log",
                    enabled_when=["speed_controller.feedforward", ["no_tau", "full"]],
                    value_when_disabled=1.0,
                    help="Gx = m alpha / (s + m alpha) (eq 10); lowpass is m = 1 (eq 13)",
                ),
                select(
                    "speed_controller.feedforward",
                    "feedforward Fr",
                    FEEDFORWARDS,
                    help="none: 1DOF PI; lowpass: eq 13/15; no_tau: eq 11 with tau_i = 0; full: eq 11",
                ),
            ],
        },
        {
            "legend": "Anti-windup (Fig. 5)",
            "controls": [
                select("speed_controller.anti_windup", "anti-windup", ANTI_WINDUPS),
                slider(
                    "speed_controller.Ka",
                    "Ka",
                    "(rad/s)/Nm",
                    0.03 / Kp,
                    30.0 / Kp,
                    "log",
                    nullable=True,
                    null_label="1/Kp (paper default)",
                    default_position=1.0 / Kp,
                    enabled_when=["speed_controller.anti_windup", ["back_calculation"]],
                    value_when_disabled=None,
                ),
            ],
        },
        {
            "legend": "Digital implementation (Table 1)",
            "controls": [
                select("speed_controller.method", "discretization", METHODS),
                slider(
                    "speed_controller.Ts_s",
                    "Ts speed loop",
                    "s",
                    Ts_cl,
                    max(1000 * Ts_cl, 10 * v["speed_controller.Ts_s"]),
                    "log",
                    quantum=Ts_cl,
                    help=f"an integer multiple of the current-loop period {Ts_cl:g} s",
                ),
            ],
        },
        {"legend": "Experiment", "controls": experiment, "note": "; ".join(notes)},
    ]
    return {"name": base.name, "groups": groups}
