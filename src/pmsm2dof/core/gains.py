"""The gains of the speed controller's PI from the inertia and the bandwidth (paper eq 9).

This is the one place eq 9 is written in Python, in double precision, for the designs, the
studies and the messages that need Kp or Ki; the C controller computes the same gains in
float32 when it is configured (``csrc/src/speed.c``).

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller", eq (9), after the analytical PI design of its reference [4].
"""


def pi_gains(J_kgm2: float, alpha_radps: float, zeta: float) -> tuple[float, float]:
    """``(Kp, Ki)`` of eq 9: ``Kp = J alpha`` [Nm/(rad/s)], ``Ki = J (alpha / (2 zeta))**2`` [Nm/rad].

    With them the loop ``J s^2 + Kp s + Ki`` (ideal current loop) has the natural frequency
    ``alpha / (2 zeta)`` and the damping ``zeta``. The inputs are not validated here
    (:func:`pmsm2dof.analysis.design.design` and the C controller do that).
    """
    Kp = J_kgm2 * alpha_radps
    Ki = J_kgm2 * (alpha_radps / (2.0 * zeta)) ** 2
    return Kp, Ki
