"""The dq current loop designed from an identified motor, and the speed loop's sensitivity to it.

A :class:`~pmsm2dof.core.motor.Motor` is the machine per phase in the amplitude-invariant dq frame
of eq 1, with the 95 % intervals of the estimates where known (a motor file of ``pmsm2dof commission
--out`` or ``identify electrical --out``, read by :func:`pmsm2dof.core.motor.load_motor`).

:func:`design_current_loop` places the closed current loop of each axis at the bandwidth
``alpha_c``: the PI ``Kp = L alpha_c``, ``Ki = Rs alpha_c`` cancels the pole ``-Rs/L`` of the
decoupled axis, so that ``i / i_ref = alpha_c / (s + alpha_c)``, the first-order lag of eq 3 with
``tau_i = 1 / alpha_c`` (the C controller's ``Kp = L / tau_i``, ``Ki = Rs / tau_i``), and the
decoupling feedforward ``ud += -w_e Lq iq``, ``uq += w_e (Ld id + psi_f)``.

:func:`speed_margin_sensitivity` gives the speed loop's margins when the true machine sits at
the corners of the estimates' intervals while the current PIs and the torque constant keep the
estimates: the q-axis loop ``alpha_c (Lq' s + Rs') / (Lq s^2 + (Rs + alpha_c Lq') s + alpha_c
Rs')`` (primes: estimates) no longer reduces to eq 3, and a wrong psi_f scales the torque by
``psi_f / psi_f'`` (surface machine at id = 0, Te = 1.5 p psi_f iq).
"""

import itertools
import warnings
from dataclasses import dataclass

import control

from ..core.motor import Motor
from ..errors import require_positive
from .discretize import SamplingWarning
from .margins import Margins, loop_margins

__all__ = ["CurrentLoopDesign", "design_current_loop", "speed_margin_sensitivity"]


@dataclass(frozen=True)
class CurrentLoopDesign:
    """dq current PIs placed at ``alpha_c`` [rad/s] from an identified motor.

    ``Kp_d_V_per_A = Ld alpha_c``, ``Kp_q_V_per_A = Lq alpha_c``, ``Ki_V_per_As = Rs alpha_c``
    (both axes), ``tau_i_s = 1 / alpha_c`` (eq 3, for the speed loop's eq 11), and the
    decoupling coefficients ``Ld_H``, ``Lq_H``, ``psi_f_Wb`` of the feedforward.
    """

    motor: Motor
    alpha_c_radps: float
    Kp_d_V_per_A: float
    Kp_q_V_per_A: float
    Ki_V_per_As: float
    tau_i_s: float

    def as_dict(self) -> dict[str, object]:
        """JSON-ready summary."""
        return {
            "alpha_c_radps": self.alpha_c_radps,
            "Kp_d_V_per_A": self.Kp_d_V_per_A,
            "Kp_q_V_per_A": self.Kp_q_V_per_A,
            "Ki_V_per_As": self.Ki_V_per_As,
            "tau_i_s": self.tau_i_s,
            "decoupling": {
                "ud_V": "-w_e Lq_H iq_A",
                "uq_V": "w_e (Ld_H id_A + psi_f_Wb)",
                "Ld_H": self.motor.Ld_H,
                "Lq_H": self.motor.Lq_H,
                "psi_f_Wb": self.motor.psi_f_Wb,
            },
        }


def design_current_loop(motor: Motor, alpha_c_radps: float, Ts_s: float | None = None) -> CurrentLoopDesign:
    """Current PIs of bandwidth ``alpha_c_radps`` for ``motor`` (pole-zero cancellation, eq 3).

    Parameters
    ----------
    motor : Motor
        The identified machine.
    alpha_c_radps : float
        Closed current-loop bandwidth [rad/s], > 0.
    Ts_s : float, optional
        Current sampling period [s], > 0. Above ``alpha_c Ts = 0.2`` a warning says that the
        sampled loop (about 1.5 Ts of delay with PWM) departs from the first-order response.

    Raises
    ------
    ConfigError
        Naming ``current_bandwidth`` (the option) or ``Ts_current``.
    """
    alpha_c = require_positive("current_bandwidth", alpha_c_radps)
    if Ts_s is not None:
        Ts_s = require_positive("Ts_current", Ts_s)
        if alpha_c * Ts_s > 0.2:
            warnings.warn(
                f"current bandwidth {alpha_c:g} rad/s is above 0.2 / Ts_current = {0.2 / Ts_s:g} rad/s: "
                "the sampled current loop is slower and less damped than eq 3 assumes",
                SamplingWarning,
                stacklevel=2,
            )
    return CurrentLoopDesign(
        motor=motor,
        alpha_c_radps=alpha_c,
        Kp_d_V_per_A=motor.Ld_H * alpha_c,
        Kp_q_V_per_A=motor.Lq_H * alpha_c,
        Ki_V_per_As=motor.Rs_ohm * alpha_c,
        tau_i_s=1.0 / alpha_c,
    )


def current_closed_loop(loop: CurrentLoopDesign, Rs_ohm: float, Lq_H: float) -> control.TransferFunction:
    """q-axis ``iq / iq_ref`` of the decoupled loop on a true machine ``(Rs_ohm, Lq_H)``.

    The PI ``Kp + Ki / s`` of the estimates on ``1 / (Lq s + Rs)``:
    ``alpha_c (Lq' s + Rs') / (Lq s^2 + (Rs + alpha_c Lq') s + alpha_c Rs')``; on the
    estimated machine itself it is ``alpha_c / (s + alpha_c)``.
    """
    a, m = loop.alpha_c_radps, loop.motor
    return control.tf([a * m.Lq_H, a * m.Rs_ohm], [Lq_H, Rs_ohm + a * m.Lq_H, a * m.Rs_ohm])


def speed_margin_sensitivity(loop: CurrentLoopDesign, Kp: float, Ki: float, J_kgm2: float) -> list[dict[str, object]]:
    """Speed-loop margins at every corner of the motor's intervals (and at the estimates).

    The speed PI ``Kp + Ki / s`` (eq 9) drives the q current loop of :func:`current_closed_loop`
    through the torque ratio ``psi_f / psi_f'`` and ``1 / (J s)``. Parameters without an
    interval stay at their estimate. Returns one entry per machine: its parameters and margins
    (``gain_margin_dB``, ``phase_margin_deg``, ``w_gain_crossover_radps``; ``None`` if infinite).
    """
    m = loop.motor
    F = control.tf([Kp, Ki], [1.0, 0.0])
    Gm = control.tf([1.0], [J_kgm2, 0.0])
    varied = [k for k in ("Rs_ohm", "Lq_H", "psi_f_Wb") if k in m.intervals]
    corners = [dict(zip(varied, values)) for values in itertools.product(*(m.intervals[k] for k in varied))]
    rows = []
    for corner in [{}, *corners] if varied else [{}]:
        truth = {k: corner.get(k, getattr(m, k)) for k in ("Rs_ohm", "Lq_H", "psi_f_Wb")}
        L = F * (truth["psi_f_Wb"] / m.psi_f_Wb) * current_closed_loop(loop, truth["Rs_ohm"], truth["Lq_H"]) * Gm
        margins: Margins = loop_margins(L)
        values, _reasons = margins.values_and_reasons()
        rows.append({"machine": "estimates" if not corner else "interval corner", **truth, **values})
    return rows
