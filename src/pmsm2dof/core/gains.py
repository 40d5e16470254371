"""The gains of the speed controller's PI from the inertia and the bandwidth (paper eq 9).

This is the one place eq 9 is written in Python, in double precision, for the designs, the
studies and the messages that need Kp or Ki; the C controller computes the same gains in
float32 when it is configured (``csrc/src/speed.c``).

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller", eq (9), after the analytical PI design of its reference [4].
"""

import math
from collections.abc import Mapping

from ..errors import ConfigError


def pi_gains(J_kgm2: float, alpha_radps: float, zeta: float) -> tuple[float, float]:
    """``(Kp, Ki)`` of eq 9: ``Kp = J alpha`` [Nm/(rad/s)], ``Ki = J (alpha / (2 zeta))**2`` [Nm/rad].

    With them the loop ``J s^2 + Kp s + Ki`` (ideal current loop) has the natural frequency
    ``alpha / (2 zeta)`` and the damping ``zeta``. The inputs are not validated here
    (:func:`pmsm2dof.analysis.design.design` and the C controller do that).
    """
    Kp = J_kgm2 * alpha_radps
    Ki = J_kgm2 * (alpha_radps / (2.0 * zeta)) ** 2
    return Kp, Ki


#: The damping below which a back-calculation loop too fast for the default Ka is blamed on zeta
#: rather than on alpha [-]: with zeta >= 0.5 it needs alpha Ts > 2, a bandwidth beyond the sampling.
ZETA_LOW = 0.5


def default_Ka_error(
    J_kgm2: float, alpha_radps: float, zeta: float, Ts_s: float, names: Mapping[str, str]
) -> ConfigError:
    """The error of a back calculation that the default ``Ka = 1/Kp`` makes unstable, naming the input at fault.

    With ``Ka = 1/Kp`` (section 3.3) and eq 9 the discrete back-calculation loop
    ``x[k] = (1 - Ki Ka Ts) x[k-1] + ...`` has the gain ``Ki Ka Ts = alpha Ts / (4 zeta^2)``, which
    the C controller requires below 2: ``zeta > sqrt(alpha Ts / 8)``, or ``alpha < 8 zeta^2 / Ts``.
    Ka was not given, so the error names the input the user set: ``zeta`` when it is below
    :data:`ZETA_LOW`, else ``alpha``; the text gives the other bound and the Ka that would do.

    Parameters
    ----------
    J_kgm2, alpha_radps, zeta, Ts_s : float
        The design's inertia, bandwidth, damping and sampling period.
    names : mapping
        The names of ``alpha_radps``, ``zeta``, ``Ts_s`` and ``Ka`` in the message (scenario keys
        or API arguments).
    """
    g = alpha_radps * Ts_s / (4.0 * zeta * zeta)
    _, Ki = pi_gains(J_kgm2, alpha_radps, zeta)
    why = (
        f"{names['Ka']} is absent, and its default 1/Kp (section 3.3) makes the back-calculation gain "
        f"Ki Ka Ts = alpha Ts / (4 zeta^2) = {g:.4g}, which must be < 2 for a stable loop "
        f"(or give {names['Ka']} < 2 / (Ki Ts) = {2.0 / (Ki * Ts_s):.4g} (rad/s)/Nm)"
    )
    if zeta < ZETA_LOW:
        bound = math.sqrt(alpha_radps * Ts_s / 8.0)
        return ConfigError(
            names["zeta"],
            zeta,
            f"> sqrt(alpha Ts / 8) = {bound:.4g} with {names['alpha_radps']} = {alpha_radps:g} and "
            f"{names['Ts_s']} = {Ts_s:g}: {why}",
        )
    bound = 8.0 * zeta * zeta / Ts_s
    return ConfigError(
        names["alpha_radps"],
        alpha_radps,
        f"< 8 zeta^2 / Ts = {bound:.6g} rad/s with {names['zeta']} = {zeta:g} and {names['Ts_s']} = {Ts_s:g}: {why}",
    )
