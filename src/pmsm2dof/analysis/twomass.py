"""The eq 9 design on a two-mass drive train: resonance, loop, margins, poles and torque filters.

The paper designs on a rigid inertia and notes in its conclusion that a multibody load needs a
higher-order model. Here the load is the two-mass train of the engine (csrc/sim/drive.h): the
motor side J_M and the load side J_L coupled by a shaft of stiffness K and damping D. From the
torque T to the motor speed w_m and to the load speed w_L::

    w_m / T = (J_L s^2 + D s + K) / (s (J_M J_L s^2 + D (J_M + J_L) s + K (J_M + J_L)))
    w_L / T = (D s + K)           / (s (J_M J_L s^2 + D (J_M + J_L) s + K (J_M + J_L)))

with the resonance ``w_r = sqrt(K (J_M + J_L) / (J_M J_L))`` (poles), the anti-resonance
``w_a = sqrt(K / J_L)`` (zeros of w_m / T) and ``w_r / w_a = sqrt(1 + J_L / J_M)``; as K grows,
both tend to the rigid ``1 / ((J_M + J_L) s)`` of eq 2. The PI of eq 9 is designed on the total
inertia ``J_M + J_L``. The loop is analysed sampled, as the controller runs: the ZOH equivalent
of ``Gci Gm`` (eq 3 and the above), the PI as the C controller realizes it
(:func:`pmsm2dof.analysis.sampled_loop.c_coefficients`) and the torque filters of
``csrc/include/pmsm2dof/filter.h`` (Tustin prewarped at their frequency) inside the loop.
The reference feedforward Fr is outside the loop (eq 6): the closed-loop poles, and so the
stable region, are the same for every feedforward form; Fr adds only its own pole.

The transfer functions are formed in state space: multiplied out in z, the polynomials of the
loop lose the distance of its poles to z = 1 (see :mod:`.discretize`).
"""

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import control
import numpy as np
import numpy.typing as npt
from scipy import signal

from ..core import FEEDBACKS
from ..core.bindings import Method
from ..errors import ConfigError, require_choice, require_nonnegative, require_positive
from .design import Design, design
from .sampled_loop import c_coefficients


@dataclass(frozen=True)
class TwoMass:
    """A two-mass drive train: motor inertia, load inertia and the shaft between them.

    Build it with :func:`two_mass`. Attributes carry their units in their names.
    """

    J_motor_kgm2: float
    J_load_kgm2: float
    stiffness_Nm_per_rad: float
    damping_Nms_per_rad: float

    @property
    def J_total_kgm2(self) -> float:
        """J_M + J_L, the inertia of the eq 9 design [kg m^2]."""
        return self.J_motor_kgm2 + self.J_load_kgm2

    @property
    def inertia_ratio(self) -> float:
        """J_L / J_M [-]."""
        return self.J_load_kgm2 / self.J_motor_kgm2

    @property
    def resonance_radps(self) -> float:
        """w_r = sqrt(K (J_M + J_L) / (J_M J_L)), the free oscillation of the shaft [rad/s]."""
        return math.sqrt(self.stiffness_Nm_per_rad * self.J_total_kgm2 / (self.J_motor_kgm2 * self.J_load_kgm2))

    @property
    def antiresonance_radps(self) -> float:
        """w_a = sqrt(K / J_L): the load alone on the shaft, a zero of w_m / T [rad/s]."""
        return math.sqrt(self.stiffness_Nm_per_rad / self.J_load_kgm2)

    @property
    def resonance_damping(self) -> float:
        """Damping ratio of the resonance, D (J_M + J_L) / (2 J_M J_L w_r) [-]."""
        J_ML = self.J_motor_kgm2 * self.J_load_kgm2
        return self.damping_Nms_per_rad * self.J_total_kgm2 / (2.0 * J_ML * self.resonance_radps)

    def Gm(self, feedback: str = "motor") -> control.TransferFunction:
        """Speed of the motor or load side per torque [rad/s / Nm] (module docstring)."""
        require_choice("feedback", feedback, FEEDBACKS)
        JM, JL, K, D = self.J_motor_kgm2, self.J_load_kgm2, self.stiffness_Nm_per_rad, self.damping_Nms_per_rad
        num = [JL, D, K] if feedback == "motor" else [D, K]
        return control.tf(num, np.polymul([1.0, 0.0], [JM * JL, D * (JM + JL), K * (JM + JL)]))


def two_mass(
    J_motor_kgm2: float, J_load_kgm2: float, stiffness_Nm_per_rad: float, damping_Nms_per_rad: float = 0.0
) -> TwoMass:
    """A validated :class:`TwoMass` (ConfigError naming the parameter out of range)."""
    return TwoMass(
        require_positive("J_motor_kgm2", J_motor_kgm2),
        require_positive("J_load_kgm2", J_load_kgm2),
        require_positive("stiffness_Nm_per_rad", stiffness_Nm_per_rad),
        require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad),
    )


def filter_tf(
    Ts_s: float,
    notch_freq_Hz: float = 0.0,
    notch_width_Hz: float = 0.0,
    notch_depth: float = 0.0,
    lowpass_freq_Hz: float = 0.0,
    lowpass_zeta: float = 0.0,
) -> control.TransferFunction:
    """The torque filters of ``filter.h`` as designed, sampled at ``Ts_s``: notch then low-pass.

    Notch ``(s^2 + d B s + w0^2) / (s^2 + B s + w0^2)`` and low-pass
    ``w0^2 / (s^2 + 2 zeta w0 s + w0^2)``, each discretized by Tustin prewarped at its frequency
    (``scipy.signal.bilinear`` at the sampling rate ``w0 / (2 tan(w0 Ts / 2))``). The notch's B is
    the one whose discrete -3 dB width is ``notch_width_Hz``: ``B = B_v w0 / g`` with
    ``g = tan(pi f0 Ts)`` and ``B_v = (1 + g^2) tan(pi W Ts) / sqrt(1 - 2 d^2)`` (filter.h).
    A frequency of 0 leaves its section out; both 0 give 1.
    """
    Ts_s = require_positive("Ts_s", Ts_s)
    nyquist = 0.5 / Ts_s
    H = control.tf([1.0], [1.0], Ts_s)
    if notch_freq_Hz:
        f0 = _in_band("notch_freq_Hz", notch_freq_Hz, nyquist)
        W = _in_band("notch_width_Hz", notch_width_Hz, nyquist)
        d = require_nonnegative("notch_depth", notch_depth)
        if not d < math.sqrt(0.5):
            raise ConfigError("notch_depth", notch_depth, ">= 0 and < 1/sqrt(2)")
        g = math.tan(math.pi * f0 * Ts_s)
        w0 = 2.0 * math.pi * f0
        B = (1.0 + g * g) * math.tan(math.pi * W * Ts_s) / math.sqrt(1.0 - 2.0 * d * d) * w0 / g
        H = H * _prewarped([1.0, d * B, w0 * w0], [1.0, B, w0 * w0], w0, g, Ts_s)
    if lowpass_freq_Hz:
        f0 = _in_band("lowpass_freq_Hz", lowpass_freq_Hz, nyquist)
        zeta = require_positive("lowpass_zeta", lowpass_zeta)
        w0 = 2.0 * math.pi * f0
        g = math.tan(math.pi * f0 * Ts_s)
        H = H * _prewarped([w0 * w0], [1.0, 2.0 * zeta * w0, w0 * w0], w0, g, Ts_s)
    return H


def _in_band(param: str, value: float, nyquist_Hz: float) -> float:
    v = require_positive(param, value)
    if not v < nyquist_Hz:
        raise ConfigError(param, value, f"> 0 and < 1/(2 Ts_s) = {nyquist_Hz:g} Hz")
    return v


def _prewarped(b: list[float], a: list[float], w0: float, g: float, Ts_s: float) -> control.TransferFunction:
    bz, az = signal.bilinear(b, a, fs=w0 / (2.0 * g))
    return control.tf(bz, az, Ts_s)


@dataclass(frozen=True)
class TwoMassLoop:
    """The sampled speed loop of an eq 9 design on a two-mass train.

    Attributes
    ----------
    mechanics : TwoMass
    feedback : str
        The side the controller reads, ``"motor"`` or ``"load"``.
    L : control.StateSpace
        Loop gain ``C(z) H(z) P(z)`` (discrete, sampling period ``Ts_s``).
    poles : numpy.ndarray
        Closed-loop poles in z (the feedforward's own pole excluded: it is outside the loop).
    stable : bool
        Every closed-loop pole inside the unit circle.
    """

    mechanics: TwoMass
    feedback: str
    Ts_s: float
    L: control.StateSpace
    poles: npt.NDArray[np.complex128]
    stable: bool

    @property
    def poles_s(self) -> npt.NDArray[np.complex128]:
        """The closed-loop poles mapped to s, ``ln(z) / Ts`` [1/s]."""
        return np.asarray(np.log(self.poles.astype(complex)) / self.Ts_s, dtype=np.complex128)

    def margins(self) -> tuple[float, float]:
        """(gain margin [dB], phase margin [deg]) of the loop gain (python-control); inf when there is no crossing."""
        with warnings.catch_warnings():  # its note that it evaluates the frequency response instead
            warnings.simplefilter("ignore", UserWarning)
            gm, pm, _sm, _wpc, _wgc, _wms = control.stability_margins(self.L)
        return (20.0 * math.log10(gm) if gm > 0 and math.isfinite(gm) else math.inf, float(pm))


def sampled_loop(
    d: Design,
    mechanics: TwoMass,
    Ts_s: float,
    method: Method = "tustin",
    feedback: str = "motor",
    filters: Mapping[str, float] | None = None,
) -> TwoMassLoop:
    """The sampled loop of the design ``d`` (:func:`pmsm2dof.analysis.design.design`) on ``mechanics``.

    The plant is the ZOH equivalent of ``1 / (tau_i s + 1)`` (eq 3, ``design.tau_i_s``) times
    :meth:`TwoMass.Gm` of the side read; the PI is the C controller's (``method``, ``Ts_s``) and
    the torque filters ``filters`` (the keywords of :func:`filter_tf`; None: no filter) run inside the loop.
    """
    require_choice("feedback", feedback, FEEDBACKS)
    Ts_s = require_positive("Ts_s", Ts_s)
    c = c_coefficients(d, Ts_s, method, anti_windup="none")  # the linear loop: no limit acts
    C = control.ss(control.tf([c["b_e0"], c["Ki_Ts"] - c["b_e0"]], [1.0, -1.0], Ts_s))
    Gci = control.tf([1.0], [d.tau_i_s, 1.0])
    P = control.c2d(control.ss(Gci * mechanics.Gm(feedback)), Ts_s, "zoh")
    H = control.ss(filter_tf(Ts_s, **(filters or {})))
    L = C * H * P
    poles = np.asarray(control.feedback(L, 1).poles(), dtype=np.complex128)
    return TwoMassLoop(mechanics, feedback, Ts_s, L, poles, bool(np.all(np.abs(poles) < 1.0)))


def largest_stable_alpha(
    mechanics: TwoMass,
    zeta: float,
    tau_i_s: float,
    Ts_s: float,
    alpha_min_radps: float = 0.1,
    alpha_max_radps: float = 1000.0,
    feedback: str = "motor",
    filters: Mapping[str, float] | None = None,
    rtol: float = 0.01,
) -> float:
    """The alpha [rad/s] where the sampled loop (:func:`sampled_loop`, eq 9 on the total inertia)
    first loses stability, scanning up from ``alpha_min_radps`` by factors of 2, then bisected
    (geometrically) to ``rtol``.

    ``alpha_max_radps`` if every alpha scanned is stable, NaN if ``alpha_min_radps`` is not. An
    unstable band narrower than a factor of 2 can be stepped over. The stable region does not depend
    on the feedforward form (module docstring).
    """

    def stable(alpha: float) -> bool:
        d = design(mechanics.J_total_kgm2, alpha, zeta, tau_i_s=tau_i_s)
        return sampled_loop(d, mechanics, Ts_s, feedback=feedback, filters=filters).stable

    lo = require_positive("alpha_min_radps", alpha_min_radps)
    if not stable(lo):
        return math.nan
    while True:
        hi = min(2.0 * lo, alpha_max_radps)
        if not stable(hi):
            break
        if hi >= alpha_max_radps:
            return alpha_max_radps
        lo = hi
    while hi / lo > 1.0 + rtol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
