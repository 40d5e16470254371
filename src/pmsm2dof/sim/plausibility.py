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
  (:func:`pmsm2dof.sim.datasheet.no_load_speed_radps`), which the drive cannot reach without field
  weakening (skipped when ``field_weakening.enabled``);
- load: a load torque above the peak torque the current limit gives, the largest torque of eq 1 at
  ``||i_dq|| = limits.i_max_A`` (:func:`peak_torque_Nm`): the drive cannot hold it, it stalls and
  the load turns it backwards.
"""

import math
from typing import Any

from ..errors import Pmsm2dofWarning
from .datasheet import no_load_speed_radps
from .scenario import Scenario

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


def peak_torque_Nm(i_max_A: float, pole_pairs: int, psi_f_Wb: float, Ld_H: float, Lq_H: float) -> float:
    """The largest torque of eq 1 with ``||i_dq|| = i_max_A`` [Nm]: the MTPA point of the current limit.

    ``Te = 1.5 p iq (psi_f + (Ld - Lq) id)``; on the circle ``||i_dq|| = I`` it is largest where
    ``dTe/dbeta = 0`` (``id = I cos beta``), ``2 dL I^2 cos^2 beta + psi_f I cos beta - dL I^2 = 0``
    with ``dL = Ld - Lq``, so ``id = 2 dL I^2 / (psi_f + sqrt(psi_f^2 + 8 dL^2 I^2))`` (0 for a
    surface PMSM, where the peak torque is ``1.5 p psi_f I``).
    """
    dL = Ld_H - Lq_H
    I = i_max_A
    id_A = 2.0 * dL * I * I / (psi_f_Wb + math.sqrt(psi_f_Wb**2 + 8.0 * dL * dL * I * I))
    iq_A = math.sqrt(max(I * I - id_A * id_A, 0.0))
    return 1.5 * pole_pairs * iq_A * (psi_f_Wb + dL * id_A)


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
    data: dict[str, Any] = scenario.data
    motor, limits, sc = data["motor"], data["limits"], data["speed_controller"]
    found: list[str] = []
    two_mass = data["mechanics"]["model"] == "two_mass"
    J_train = motor["J_kgm2"] + (data["mechanics"]["J_load_kgm2"] if two_mass else 0.0)
    found += inertia_findings("speed_controller.J_kgm2", sc["J_kgm2"], motor["J_rotor_kgm2"])
    found += inertia_findings("motor.J_kgm2", motor["J_kgm2"], motor["J_rotor_kgm2"])
    ratio = sc["J_kgm2"] / J_train
    if not 1.0 / J_DESIGN_RATIO_MAX <= ratio <= J_DESIGN_RATIO_MAX:
        found.append(
            f"speed_controller.J_kgm2 = {sc['J_kgm2']:.6g} kg m^2 is {ratio:.3g} times the inertia of the drive "
            f"train, {J_train:.6g} kg m^2 (motor.J_kgm2{' + mechanics.J_load_kgm2' if two_mass else ''}): "
            "the gains of eq 9 scale with the design inertia"
        )
    found += current_findings("limits.i_max_A", limits["i_max_A"], motor["i_rated_A"], motor["i_peak_A"])
    if not data["field_weakening"]["enabled"]:
        w_max_rpm = no_load_speed_radps(limits["u_dc_V"], motor["pole_pairs"], motor["psi_f_Wb"]) * RPM_PER_RADPS
        speeds = [("simulation.speed0_rpm", data["simulation"]["speed0_rpm"])]
        speeds += [(f"reference.{i}.speed_rpm", e["speed_rpm"]) for i, e in enumerate(data["reference"])]
        for key, rpm in speeds:
            if abs(rpm) > w_max_rpm:
                found.append(
                    f"{key} = {rpm:.6g} rpm is above the no-load speed {w_max_rpm:.5g} rpm that limits.u_dc_V = "
                    f"{limits['u_dc_V']:g} V reaches (u_dc / (sqrt(3) p psi_f)): the drive runs at its voltage "
                    "limit and cannot follow it (field weakening is off)"
                )
    T_peak = peak_torque_Nm(limits["i_max_A"], motor["pole_pairs"], motor["psi_f_Wb"], motor["Ld_H"], motor["Lq_H"])
    for i, e in enumerate(data["load"]):
        if abs(e["torque_Nm"]) > T_peak:
            found.append(
                f"load.{i}.torque_Nm = {e['torque_Nm']:.6g} Nm is above the peak torque {T_peak:.4g} Nm that "
                f"limits.i_max_A = {limits['i_max_A']:g} A gives: the drive cannot hold it, it stalls and the load "
                "turns it backwards"
            )
    return found


def warn_implausible(scenario: Scenario) -> list[str]:
    """Give each finding of :func:`implausible` as a :class:`PlausibilityWarning`; return them."""
    import warnings

    found = implausible(scenario)
    for text in found:
        warnings.warn(text, PlausibilityWarning, stacklevel=2)
    return found
