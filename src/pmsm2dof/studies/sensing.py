"""How the speed measurement changes the paper's drive: overshoot, load dip and margins per sensor chain.

The paper's experiment 1 (section 4.2, Fig. 12) reports that anti-windup cuts the overshoot of
the 500 rpm step from 35 % to 15 %, where the simulated drive with an exact speed reading gives
about 68 % and 34 %. A real drive reads an encoder through an estimator, a filter and a delay;
this study runs experiment 1 (1DOF PI, without and with back-calculation AW) and experiment 3
(the 8 Nm load step, 2DOF eq 15) for each chain of :data:`SENSOR_CHAINS`, with the chain's phase
and gain margins of the sampled loop (:meth:`pmsm2dof.analysis.design.Design.discretize` with the
:class:`~pmsm2dof.analysis.sensor.SensorChain`), so that one can see whether a plausible chain
brings the simulation closer to the measured 35 % -> 15 % than the exact reading does.

:func:`offset_study` shows what a phase-current sensor's offset does to the same drive: a torque
ripple at the electrical frequency, measured in the simulation and predicted by the linear current
loop (:func:`offset_ripple_Nm`).
"""

import dataclasses
import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import Pmsm2dofError, SimulationError
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario, load_scenario
from ..sim.scenario_tables import SpeedSensorTable
from ..sim.simulate import simulate
from .configuration import scenario_design

#: The paper's measured overshoots of experiment 1 without and with AW [%] (section 4.2).
PAPER_OVERSHOOT_PCT = {"none": 35.0, "back_calculation": 15.0}

#: A chain explains the measurement better when it removes this share of the ideal reading's distance.
EXPLAINS_FRACTION = 0.25

_E = "speed_sensor."
_ENCODER = {_E + "model": "encoder", _E + "counts_per_rev": 1024}

#: Sensor chains compared, by label: the ``[speed_sensor]`` keys of each (absent keys: defaults).
SENSOR_CHAINS: dict[str, dict[str, Any]] = {
    "ideal": {},
    "encoder 1024, difference": _ENCODER,
    "encoder 256, difference": _ENCODER | {_E + "counts_per_rev": 256},
    "encoder 1024, low-pass 20 rad/s": _ENCODER | {_E + "lowpass_radps": 20.0},
    "encoder 1024, low-pass 5 rad/s": _ENCODER | {_E + "lowpass_radps": 5.0},
    "encoder 1024, PLL 20 rad/s": _ENCODER | {_E + "estimator": "pll", _E + "bandwidth_radps": 20.0},
    "encoder 1024, PLL 5 rad/s": _ENCODER | {_E + "estimator": "pll", _E + "bandwidth_radps": 5.0},
    "ideal, delay 20 ms": {_E + "delay_s": 0.02},
    "ideal, noise 10 rpm rms": {_E + "noise_rpm_rms": 10.0},
}


@dataclasses.dataclass(frozen=True)
class SensorRow:
    """The figures of one sensor chain (None where a figure cannot be computed).

    Attributes
    ----------
    label : str
        Name of the chain in :data:`SENSOR_CHAINS`.
    sensor : SpeedSensorTable
        Its ``[speed_sensor]`` table as run.
    overshoot_no_aw_pct, overshoot_aw_pct : float or None
        Experiment 1, 1DOF PI, without and with back-calculation AW [%].
    dip_rpm : float or None
        Experiment 3, 2DOF eq 15: speed dip of the 8 Nm load step [rpm].
    phase_margin_deg, gain_margin_dB : float or None
        Of the sampled 1DOF loop with the chain (speed_controller.Ts_s, Tustin).
    distance_pct : float or None
        ``|overshoot_no_aw - 35| + |overshoot_aw - 15|``: how far from the paper's measurement.
    """

    label: str
    sensor: SpeedSensorTable
    overshoot_no_aw_pct: float | None
    overshoot_aw_pct: float | None
    dip_rpm: float | None
    phase_margin_deg: float | None
    gain_margin_dB: float | None
    distance_pct: float | None


def _figure(metrics: dict[str, Any], group: str, name: str) -> float | None:
    value = metrics[group][0][name]["value"]
    return None if value is None else float(value)


def _run_figure(scenario: Scenario, group: str, name: str) -> float | None:
    """A figure of the first step of a run; None when the engine stops the run (a chain that destabilizes it)."""
    try:
        return _figure(compute_metrics(simulate(scenario)), group, name)
    except SimulationError:
        return None


def _margins(scenario: Scenario) -> tuple[float | None, float | None]:
    """Phase and gain margin of the sampled 1DOF loop with the scenario's sensor chain."""
    sc = scenario.speed_controller
    loop = scenario_design(scenario, feedforward="none")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            margins = loop.discretize(sc.Ts_s, sc.method).margins
    except Pmsm2dofError:
        return None, None
    pm, gm = margins.phase_margin_deg, margins.gain_margin_dB
    return (pm if math.isfinite(pm) else None), (gm if math.isfinite(gm) else None)


def sensor_study(
    overrides: Mapping[str, Any] | None = None, chains: Mapping[str, Mapping[str, Any]] | None = None
) -> list[SensorRow]:
    """Run experiments 1 and 3 of the paper for each sensor chain.

    Parameters
    ----------
    overrides : mapping, optional
        Scenario keys changed in both presets first (``{"motor.J_kgm2": 0.5}``).
    chains : mapping, optional
        ``{label: {"speed_sensor.key": value}}``; default :data:`SENSOR_CHAINS`.

    Returns
    -------
    list of SensorRow
        One per chain, in order.

    Raises
    ------
    ConfigError
        An override or a chain key that the scenario refuses, by name.
    """
    chains = SENSOR_CHAINS if chains is None else chains
    base = dict(overrides or {})
    e1 = load_scenario("paper-experiment-1").with_overrides(base | {"speed_controller.feedforward": "none"})
    e3 = load_scenario("paper-experiment-3").with_overrides(base | {"speed_controller.feedforward": "lowpass"})
    rows = []
    for label, chain in chains.items():
        overshoot: dict[str, float | None] = {}
        for aw in PAPER_OVERSHOOT_PCT:
            run = e1.with_overrides(dict(chain) | {"speed_controller.anti_windup": aw})
            overshoot[aw] = _run_figure(run, "reference_steps", "overshoot_pct")
        loaded = e3.with_overrides(dict(chain))
        dip = _run_figure(loaded, "load_steps", "speed_dip_rpm")
        pm, gm = _margins(loaded)
        measured = [(v, PAPER_OVERSHOOT_PCT[aw]) for aw, v in overshoot.items() if v is not None]
        distance = sum(abs(v - paper) for v, paper in measured) if len(measured) == len(overshoot) else None
        rows.append(
            SensorRow(
                label=label,
                sensor=loaded.speed_sensor,
                overshoot_no_aw_pct=overshoot["none"],
                overshoot_aw_pct=overshoot["back_calculation"],
                dip_rpm=dip,
                phase_margin_deg=pm,
                gain_margin_dB=gm,
                distance_pct=distance,
            )
        )
    return rows


def _cell(value: float | None, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def verdict(rows: Sequence[SensorRow]) -> str:
    """One sentence: does any chain come closer to the paper's 35 % -> 15 % than the ideal reading?"""
    scored = [r for r in rows if r.distance_pct is not None]
    ideal = next((r for r in scored if r.label == "ideal"), None)
    others = [r for r in scored if r is not ideal]
    if ideal is None or not others:
        return "The study needs the ideal reading and at least one other chain with both overshoots."
    best = min(others, key=lambda r: r.distance_pct or 0.0)

    def pair(r: SensorRow) -> str:
        return f"{_cell(r.overshoot_no_aw_pct)} % -> {_cell(r.overshoot_aw_pct)} %"

    gain = (ideal.distance_pct or 0.0) - (best.distance_pct or 0.0)
    if gain > EXPLAINS_FRACTION * (ideal.distance_pct or 0.0):
        return (
            f"'{best.label}' explains the measured 35 % -> 15 % better ({pair(best)}) than the exact "
            f"reading ({pair(ideal)}): distance {_cell(best.distance_pct)} against {_cell(ideal.distance_pct)} "
            "% points."
        )
    return (
        f"No sensor chain of the study explains the measured 35 % -> 15 % better than the exact reading "
        f"({pair(ideal)}, distance {_cell(ideal.distance_pct)} % points): the closest, '{best.label}' "
        f"({pair(best)}), is {_cell(best.distance_pct)} % points away."
    )


#: Speeds [rpm] and phase-a offsets [A] (1 % and 5 % of the paper's 7.6 A) of :func:`offset_study`.
OFFSET_SPEEDS_RPM = (100.0, 500.0)
OFFSET_CURRENTS_A = (0.076, 0.38)
#: Simulated time of an offset run, and the start of the window its ripple is measured over [s].
OFFSET_T_END_S = 4.0
OFFSET_WINDOW_S = 2.0


@dataclasses.dataclass(frozen=True)
class OffsetRow:
    """The torque and speed ripple of one phase-a current-sensor offset at one speed.

    Attributes
    ----------
    speed_rpm, offset_a_A : float
        Operating speed [rpm] and offset of phase a's sensor [A].
    torque_ripple_Nm, speed_ripple_rpm : float
        Amplitudes at the electrical frequency in the simulation (least-squares fit) [Nm], [rpm].
    predicted_Nm : float
        :func:`offset_ripple_Nm` for the drive.
    """

    speed_rpm: float
    offset_a_A: float
    torque_ripple_Nm: float
    speed_ripple_rpm: float
    predicted_Nm: float


def offset_ripple_Nm(
    offset_a_A: float, w_e_radps: float, kt_Nm_per_A: float, L_H: float, Rs_ohm: float, tau_i_s: float
) -> float:
    """Torque ripple of a phase-a offset on a surface PMSM under the decoupled dq current PI.

    The offset ``I0`` reads as the stator-fixed vector ``2 I0 / sqrt(3)`` (two sensors, c = -a - b),
    in dq ``E exp(-j w_e t)``. With the PI ``C = (L s + Rs) / (tau_i s)`` and the decoupling, which
    uses the measured currents, the dq current error is ``E H(-j w_e)`` with
    ``H(s) = -1 / (tau_i s + 1) + j w_e L tau_i s / ((L s + Rs) (tau_i s + 1))``: the loop follows the
    reading, and the decoupling adds ``j w_e L`` times the error as a voltage the loop rejects.
    Returns ``kt 2 I0 / sqrt(3) |H(-j w_e)|`` [Nm].
    """
    s = -1j * w_e_radps
    H = -1.0 / (tau_i_s * s + 1.0) + 1j * w_e_radps * L_H * tau_i_s * s / ((L_H * s + Rs_ohm) * (tau_i_s * s + 1.0))
    return kt_Nm_per_A * 2.0 * abs(offset_a_A) / math.sqrt(3.0) * abs(H)


def _amplitude(t: np.ndarray, y: np.ndarray, w_radps: float) -> float:
    """Amplitude of the component of y at w (least squares of a + b cos(w t) + c sin(w t))."""
    basis = np.column_stack([np.ones_like(t), np.cos(w_radps * t), np.sin(w_radps * t)])
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    return float(math.hypot(coef[1], coef[2]))


def offset_study(overrides: Mapping[str, Any] | None = None) -> list[OffsetRow]:
    """Experiment 3's drive (2DOF eq 15) at constant speed with a phase-a current-sensor offset.

    Parameters
    ----------
    overrides : mapping, optional
        Scenario keys changed first. The prediction needs a surface PMSM (``Ld = Lq``).

    Returns
    -------
    list of OffsetRow
        For each of :data:`OFFSET_SPEEDS_RPM` and :data:`OFFSET_CURRENTS_A`.
    """
    base = load_scenario("paper-experiment-3").with_overrides(dict(overrides or {}))
    motor, cl = base.motor, base.current_loop
    kt = 1.5 * motor.pole_pairs * motor.psi_f_Wb
    rows = []
    for rpm in OFFSET_SPEEDS_RPM:
        for I0 in OFFSET_CURRENTS_A:
            run = base.with_overrides(
                {
                    "simulation.t_end_s": OFFSET_T_END_S,
                    "simulation.speed0_rpm": rpm,
                    "reference": [{"t_s": 0.0, "speed_rpm": rpm}],
                    "load": [],
                    "current_measurement.offset_a_A": I0,
                }
            )
            r = simulate(run)
            w_e = motor.pole_pairs * rpm * math.pi / 30.0
            late = r.t_s >= OFFSET_WINDOW_S
            rows.append(
                OffsetRow(
                    speed_rpm=rpm,
                    offset_a_A=I0,
                    torque_ripple_Nm=_amplitude(r.t_s[late], r.torque_Nm[late], w_e),
                    speed_ripple_rpm=_amplitude(r.t_s[late], r.speed_rpm[late], w_e),
                    predicted_Nm=offset_ripple_Nm(I0, w_e, kt, motor.Ld_H, motor.Rs_ohm, cl.tau_i_s),
                )
            )
    return rows
