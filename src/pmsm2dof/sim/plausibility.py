"""Plausibility of a drive: valid values that are probably a mistake, each said with its reason.

A scenario can be valid and still describe a drive that cannot exist or cannot do what is asked of
it: an inertia in g cm^2 typed as kg m^2, a current limit of a different motor, a speed beyond the
DC link. :func:`implausible` lists such findings as sentences that name the key, its value, what it
was compared with and why it matters; :func:`warn_implausible` gives each as a
:class:`PlausibilityWarning`. None of them stops a run: a user may mean it.

The checks, with ``p``, ``psi_f``, ``Ld``, ``Lq`` of ``[motor]``:

- inertia: ``speed_controller.J_kgm2`` or ``motor.J_kgm2`` below the rotor inertia
  ``motor.J_rotor_kgm2`` (the drive's inertia includes the rotor), or above
  :data:`J_ROTOR_RATIO_MAX` times it (a load that large is rare, a unit slip such as g cm^2 read as
  kg m^2 gives 1e7); the design inertia more than :data:`J_DESIGN_RATIO_MAX` times above or below the
  inertia of the drive train (the gains of eq 9 scale with it);
- current: ``limits.i_max_A`` above ``motor.i_peak_A`` (beyond :data:`I_PEAK_RTOL`: the magnets
  may demagnetize), or, when only the rated current is known, above :data:`I_RATED_RATIO_MAX` times
  ``motor.i_rated_A`` (servo motors allow peaks of 3 to 4 times their rated current);
- speed: a reference or initial speed above the no-load speed ``u_dc / (sqrt(3) p psi_f)``
  (:func:`pmsm2dof.core.motor.no_load_speed_radps`), which the drive cannot reach without field
  weakening (skipped when ``field_weakening.enabled``);
- load: a load torque above the peak torque the current limit gives, the largest torque of eq 1 at
  ``||i_dq|| = limits.i_max_A`` (:func:`peak_torque_Nm`): the drive cannot hold it, it stalls and
  the load turns it backwards;
- speed sensor: an encoder read by the difference estimator resolves ``60 / (counts Ts)`` rpm;
  coarser than :data:`~pmsm2dof.sim.event_figures.STEADY_SPREAD` of the smallest reference step,
  the speed dithers by about that and the step figures finer than it read n/a.
"""

import math

from ..core.motor import no_load_speed_radps
from ..errors import Pmsm2dofWarning
from .event_figures import STEADY_SPREAD
from .scenario import Scenario
from .scenario_tables import MotorTable

#: Largest plausible ratio of the drive's inertia to the rotor's own [-].
J_ROTOR_RATIO_MAX = 1000.0
#: Largest plausible ratio (either way) of the design inertia to the inertia of the drive train [-].
J_DESIGN_RATIO_MAX = 10.0
#: Largest plausible ratio of the current limit to the rated current, without a peak current [-].
I_RATED_RATIO_MAX = 5.0
#: Relative margin of the current limit over the motor's peak current before it is reported [-].
I_PEAK_RTOL = 0.1

RPM_PER_RADPS = 30.0 / math.pi


class PlausibilityWarning(Pmsm2dofWarning):
    """A valid value that is probably a mistake (see :mod:`pmsm2dof.sim.plausibility`)."""


def mtpa_id_A(i_A: float, psi_f_Wb: float, Ld_H: float, Lq_H: float) -> float:
    """The d current of the largest torque of eq 1 on the circle ``||i_dq|| = i_A`` (MTPA) [A].

    ``Te = 1.5 p iq (psi_f + (Ld - Lq) id)``; on the circle (``id = I cos beta``) it is largest where
    ``dTe/dbeta = 0``, ``2 dL I^2 cos^2 beta + psi_f I cos beta - dL I^2 = 0`` with ``dL = Ld - Lq``,
    so ``id = 2 dL I^2 / (psi_f + sqrt(psi_f^2 + 8 dL^2 I^2))``: 0 for a surface PMSM.
    """
    dL = Ld_H - Lq_H
    return 2.0 * dL * i_A * i_A / (psi_f_Wb + math.sqrt(psi_f_Wb**2 + 8.0 * dL * dL * i_A * i_A))


def peak_torque_Nm(i_max_A: float, pole_pairs: int, psi_f_Wb: float, Ld_H: float, Lq_H: float) -> float:
    """The largest torque of eq 1 with ``||i_dq|| = i_max_A`` [Nm], at the MTPA point (:func:`mtpa_id_A`).

    ``1.5 p psi_f i_max`` for a surface PMSM; the C speed controller's torque limit ``T_max`` is the same.
    """
    id_A = mtpa_id_A(i_max_A, psi_f_Wb, Ld_H, Lq_H)
    iq_A = math.sqrt(max(i_max_A * i_max_A - id_A * id_A, 0.0))
    return 1.5 * pole_pairs * iq_A * (psi_f_Wb + (Ld_H - Lq_H) * id_A)


def voltage_limited_speed_radps(u_V: float, i_A: float, motor: MotorTable) -> float:
    """The mechanical speed at which the steady-state voltage of eq 1 at the current ``i_A`` reaches ``u_V`` [rad/s].

    At the MTPA point ``(id, iq)`` of ``||i_dq|| = i_A``, eq 1 with d/dt = 0 gives
    ``ud = Rs id - w_e Lq iq``, ``uq = Rs iq + w_e (Ld id + psi_f)``; ``||u_dq|| = u`` is the quadratic
    ``A w_e^2 + 2 B w_e + C = 0`` with ``A = (Lq iq)^2 + (Ld id + psi_f)^2``,
    ``B = Rs iq (Ld id + psi_f) - Rs id Lq iq``, ``C = Rs^2 i^2 - u^2``, whose positive root is taken;
    ``i_A = 0`` gives the no-load speed ``u / (p psi_f)``. 0 when ``Rs i_A >= u`` (no speed is left).
    ``motor`` is a scenario's ``[motor]``.
    """
    Rs, Ld, Lq, psi = motor.Rs_ohm, motor.Ld_H, motor.Lq_H, motor.psi_f_Wb
    id_A = mtpa_id_A(i_A, psi, Ld, Lq)
    iq_A = math.sqrt(max(i_A * i_A - id_A * id_A, 0.0))
    flux_d = Ld * id_A + psi
    A = (Lq * iq_A) ** 2 + flux_d**2
    B = Rs * iq_A * flux_d - Rs * id_A * Lq * iq_A
    C = Rs * Rs * i_A * i_A - u_V * u_V
    if C >= 0.0:
        return 0.0
    w_e = (-B + math.sqrt(B * B - A * C)) / A
    return float(w_e / motor.pole_pairs)


def inertia_findings(key: str, J_kgm2: float, J_rotor_kgm2: float | None) -> list[str]:
    """The findings on an inertia ``key`` = ``J_kgm2`` against the motor's rotor inertia."""
    if J_rotor_kgm2 is None:
        return []
    ratio = J_kgm2 / J_rotor_kgm2
    if ratio < 1.0:
        return [
            f"{key} = {J_kgm2:.6g} kg m^2 is below the motor's rotor inertia motor.J_rotor_kgm2 = "
            f"{J_rotor_kgm2:.6g} kg m^2 ({ratio:.3g} times it): the drive's inertia includes the rotor "
            "(check the unit: 1 g cm^2 = 1e-7 kg m^2, 1 kg cm^2 = 1e-4 kg m^2)"
        ]
    if ratio > J_ROTOR_RATIO_MAX:
        return [
            f"{key} = {J_kgm2:.6g} kg m^2 is {ratio:.3g} times the motor's rotor inertia motor.J_rotor_kgm2 = "
            f"{J_rotor_kgm2:.6g} kg m^2 (more than {J_ROTOR_RATIO_MAX:g}): check the unit "
            "(1 g cm^2 = 1e-7 kg m^2, 1 kg cm^2 = 1e-4 kg m^2)"
        ]
    return []


def current_findings(key: str, i_max_A: float, i_rated_A: float | None, i_peak_A: float | None) -> list[str]:
    """The findings on a current limit ``key`` = ``i_max_A`` against the motor's rated and peak current."""
    if i_peak_A is not None:
        if i_max_A > (1.0 + I_PEAK_RTOL) * i_peak_A:
            return [
                f"{key} = {i_max_A:.6g} A is {i_max_A / i_peak_A:.3g} times the motor's peak current "
                f"motor.i_peak_A = {i_peak_A:.6g} A (dq magnitude): the motor is not made for it "
                "(the magnets may demagnetize, the winding overheat)"
            ]
        return []
    if i_rated_A is not None and i_max_A > I_RATED_RATIO_MAX * i_rated_A:
        return [
            f"{key} = {i_max_A:.6g} A is {i_max_A / i_rated_A:.3g} times the motor's rated current "
            f"motor.i_rated_A = {i_rated_A:.6g} A (dq magnitude; more than {I_RATED_RATIO_MAX:g}): servo motors "
            "allow peaks of 3 to 4 times their rated current"
        ]
    return []


def implausible(scenario: Scenario) -> list[str]:
    """The plausibility findings of ``scenario``, one sentence each (see the module docstring).

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        Empty when nothing is implausible.
    """
    motor, limits, sc = scenario.motor, scenario.limits, scenario.speed_controller
    found: list[str] = []
    two_mass = scenario.mechanics.model == "two_mass"
    J_load = scenario.mechanics.J_load_kgm2
    J_train = motor.J_kgm2 + (J_load if two_mass and J_load is not None else 0.0)
    found += inertia_findings("speed_controller.J_kgm2", sc.J_kgm2, motor.J_rotor_kgm2)
    found += inertia_findings("motor.J_kgm2", motor.J_kgm2, motor.J_rotor_kgm2)
    ratio = sc.J_kgm2 / J_train
    if not 1.0 / J_DESIGN_RATIO_MAX <= ratio <= J_DESIGN_RATIO_MAX:
        found.append(
            f"speed_controller.J_kgm2 = {sc.J_kgm2:.6g} kg m^2 is {ratio:.3g} times the inertia of the drive "
            f"train, {J_train:.6g} kg m^2 (motor.J_kgm2{' + mechanics.J_load_kgm2' if two_mass else ''}): "
            "the gains of eq 9 scale with the design inertia"
        )
    found += current_findings("limits.i_max_A", limits.i_max_A, motor.i_rated_A, motor.i_peak_A)
    if not scenario.field_weakening.enabled:
        w_max_rpm = no_load_speed_radps(limits.u_dc_V, motor.pole_pairs, motor.psi_f_Wb) * RPM_PER_RADPS
        speeds = [("simulation.speed0_rpm", scenario.simulation.speed0_rpm)]
        speeds += [(f"reference.{i}.speed_rpm", e.speed_rpm) for i, e in enumerate(scenario.reference)]
        for key, rpm in speeds:
            if abs(rpm) > w_max_rpm:
                found.append(
                    f"{key} = {rpm:.6g} rpm is above the no-load speed {w_max_rpm:.5g} rpm that limits.u_dc_V = "
                    f"{limits.u_dc_V:g} V reaches (u_dc / (sqrt(3) p psi_f)): the drive runs at its voltage "
                    "limit and cannot follow it (field weakening is off)"
                )
    found += _sensor_findings(scenario)
    T_peak = peak_torque_Nm(limits.i_max_A, motor.pole_pairs, motor.psi_f_Wb, motor.Ld_H, motor.Lq_H)
    for i, e in enumerate(scenario.load):
        if abs(e.torque_Nm) > T_peak:
            found.append(
                f"load.{i}.torque_Nm = {e.torque_Nm:.6g} Nm is above the peak torque {T_peak:.4g} Nm that "
                f"limits.i_max_A = {limits.i_max_A:g} A gives: the drive cannot hold it, it stalls and the load "
                "turns it backwards"
            )
    return found


def _sensor_findings(scenario: "Scenario") -> list[str]:
    """An encoder read by the difference estimator whose resolution is coarser than the step figures need."""
    ss, sc = scenario.speed_sensor, scenario.speed_controller
    if ss.model != "encoder" or ss.estimator != "difference":
        return []
    resolution_rpm = 60.0 / (ss.counts_per_rev * sc.Ts_s)
    previous, steps = scenario.simulation.speed0_rpm, []
    for e in scenario.reference:
        if e.speed_rpm != previous:
            steps.append(abs(e.speed_rpm - previous))
        previous = e.speed_rpm
    if not steps or resolution_rpm <= STEADY_SPREAD * min(steps):
        return []
    return [
        f"speed_sensor.counts_per_rev = {ss.counts_per_rev} counted over speed_controller.Ts_s = {sc.Ts_s:g} s "
        f"resolves {resolution_rpm:.4g} rpm (60 / (counts Ts), estimator 'difference'), "
        f"{100 * resolution_rpm / min(steps):.2g} % of the smallest reference step, {min(steps):g} rpm: the speed "
        f"dithers by about that, and the step figures finer than it (a steady state needs a spread below "
        f"{100 * STEADY_SPREAD:g} % of the step) read n/a; more counts, a PLL or a low-pass resolve finer"
    ]


def warn_implausible(scenario: Scenario) -> list[str]:
    """Give each finding of :func:`implausible` as a :class:`PlausibilityWarning`; return them."""
    import warnings

    found = implausible(scenario)
    for text in found:
        warnings.warn(text, PlausibilityWarning, stacklevel=2)
    return found
