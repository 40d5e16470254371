"""A small servo that is no preset: a maxon EC 45 flat class motor (70 W, 24 V), 3x flywheel, 20 kHz / 2 kHz.

Entered as a user reads a catalogue page, in per-phase values for the amplitude-invariant model:

- 8 pole pairs; terminal resistance and inductance phase to phase about 0.608 ohm and 0.46 mH, so
  per phase (star) ``Rs = 0.304 ohm`` and ``L = 0.23 mH``;
- torque constant about 36.9 mNm/A: ``psi_f = kt / (1.5 p) = 3.075e-3 Wb``;
- rotor inertia 181 g cm^2 = 1.81e-5 kg m^2, with a flywheel of three times the rotor:
  ``J = 4 * 1.81e-5 = 7.24e-5 kg m^2``;
- current limit 9.6 A (``1.5 p psi_f i_max = 0.354 Nm``), 24 V DC link;
- current loop at 20 kHz (``Ts = 5e-5 s``, ``tau_i = 0.5 ms``), speed loop at 2 kHz (10 periods).

:func:`scenario` builds it with a schedule of reference and load entries.
"""

import copy
from collections.abc import Sequence

from pmsm2dof.sim.scenario import Scenario

J_ROTOR_KGM2 = 181e-7
J_KGM2 = 4 * J_ROTOR_KGM2
I_MAX_A = 9.6
TS_CURRENT_S = 5e-5
TS_SPEED_S = 10 * TS_CURRENT_S

BASE = {
    "name": "small servo (EC 45 flat class)",
    "motor": {
        "pole_pairs": 8,
        "Rs_ohm": 0.304,
        "Ld_H": 2.3e-4,
        "Lq_H": 2.3e-4,
        "psi_f_Wb": 3.075e-3,
        "J_kgm2": J_KGM2,
    },
    "limits": {"i_max_A": I_MAX_A, "u_dc_V": 24.0},
    "current_loop": {"model": "dq_pi", "tau_i_s": 5e-4, "Ts_s": TS_CURRENT_S},
    "speed_controller": {"alpha_radps": 300.0, "zeta": 1.0, "Ts_s": TS_SPEED_S},
    "simulation": {"t_end_s": 0.6},
    "reference": [{"t_s": 0.0, "speed_rpm": 3000.0}],
}


def scenario(
    reference: Sequence[tuple[float, float]] = ((0.0, 3000.0),),
    load: Sequence[tuple[float, float]] = (),
    t_end_s: float = 0.6,
    speed0_rpm: float = 0.0,
    **speed_controller: float,
) -> Scenario:
    """The small servo with ``reference`` and ``load`` entries ``(t_s, value)`` and speed-controller keys."""
    data = copy.deepcopy(BASE)
    data["reference"] = [{"t_s": t, "speed_rpm": v} for t, v in reference]
    data["load"] = [{"t_s": t, "torque_Nm": v} for t, v in load]
    data["simulation"] = {"t_end_s": t_end_s, "speed0_rpm": speed0_rpm}
    data["speed_controller"].update(speed_controller)
    return Scenario.from_dict(data)
