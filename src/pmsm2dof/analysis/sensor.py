"""The speed measurement in the loop: encoder estimator, low-pass and delay, continuous and sampled.

The speed controller does not see the speed: it sees an encoder's counts differenced or tracked
by a PLL, filtered and delayed. For the linear analysis the chain from the true speed ``w`` to
the measured speed ``w_meas`` is (the C estimators of csrc/include/pmsm2dof/encoder.h)::

    continuous:  H(s) = w_pll^2 / (s + w_pll)^2  *  w_lp / (s + w_lp)  *  exp(-s T_d)
    sampled:     w_meas[k] = Hf(z) y[k],  Hf(z) = (1 - p)^2 / (1 - p z^-1)^2 * (1 - q) / (1 - q z^-1)

with ``p`` and ``q`` the bilinear images of ``-w_pll`` and ``-w_lp`` (a factor is absent when its
bandwidth is 0), and ``y[k]`` the speed sampled at ``t_k - T_d`` (``ideal``) or the mean speed over
the period ending there, ``(theta(t_k - T_d) - theta(t_k - T_d - Ts)) / Ts`` (``encoder``, whose
count increments the estimators read). The sampled chain is exact for the linear loop (the
plant, held torque, is integrated exactly over fractions of a period); the quantization of the
counts, a nonlinearity, is left to the simulation. In the continuous design the delay enters as
``exp(-s T_d)`` in the frequency response, or as a Pade approximant (:data:`PADE_ORDER`) where a
rational transfer function is needed (poles, step response); the encoder's averaging over a
period, ``Ts/2`` of delay at low frequencies, appears in the sampled loop only, as the
continuous design has no period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from ..core import ESTIMATORS, SPEED_SENSOR_MODELS, Encoder
from ..errors import ConfigError, require_choice, require_float32
from ..lazy import lazy_module

if TYPE_CHECKING:
    import control
else:
    control = lazy_module("control")  # python-control loads on first use (pmsm2dof.lazy)

#: Speed-sensor models: the true speed sampled, or an encoder's counts (the engine's, read from C).
SENSOR_MODELS = SPEED_SENSOR_MODELS
#: How a delay enters the frequency response: exactly, or as its Pade approximant.
DelayModel = Literal["exact", "pade"]
DELAY_MODELS: tuple[DelayModel, ...] = ("exact", "pade")
#: A real matrix.
_Matrix = npt.NDArray[np.float64]
#: Order of the Pade approximant of the delay in rational transfer functions.
PADE_ORDER = 4
#: Counts per revolution given to the C estimator whose filter coefficients are read (they do not depend on it).
_NEUTRAL_COUNTS = 4096


@dataclass(frozen=True)
class SensorChain:
    """The speed measurement seen by the speed controller (the ``[speed_sensor]`` of a scenario).

    Attributes
    ----------
    model : str
        ``"ideal"``: the true speed, sampled; ``"encoder"``: counted angle increments.
    estimator : str
        ``"difference"`` or ``"pll"`` (encoder only).
    bandwidth_radps : float
        PLL double pole ``w_pll`` [rad/s] (``estimator="pll"``).
    lowpass_radps : float
        First-order low-pass on the estimate [rad/s]; 0: none.
    delay_s : float
        Transport delay of the reading [s], >= 0.
    """

    model: str = "ideal"
    estimator: str = "difference"
    bandwidth_radps: float = 0.0
    lowpass_radps: float = 0.0
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        require_choice("model", self.model, SENSOR_MODELS)
        require_choice("estimator", self.estimator, ESTIMATORS)
        for name in ("bandwidth_radps", "lowpass_radps", "delay_s"):
            object.__setattr__(self, name, require_float32(name, getattr(self, name), zero=True))
        if self.pll and not self.bandwidth_radps > 0.0:
            raise ConfigError("bandwidth_radps", self.bandwidth_radps, "finite and > 0 with estimator 'pll'")
        if self.model == "ideal" and self.estimator == "pll":
            raise ConfigError("estimator", self.estimator, "'difference' with model 'ideal' (a PLL reads counts)")

    @property
    def pll(self) -> bool:
        """The encoder's speed comes from the tracking loop."""
        return self.model == "encoder" and self.estimator == "pll"

    @property
    def is_ideal(self) -> bool:
        """The true speed, sampled without filter or delay: the loop of the paper."""
        return self.model == "ideal" and self.lowpass_radps == 0.0 and self.delay_s == 0.0

    def _filter_factors(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """``(numerator, denominator)`` of the rational part of H(s): PLL and low-pass."""
        num, den = np.array([1.0]), np.array([1.0])
        if self.pll:
            w = self.bandwidth_radps
            num, den = num * w * w, np.polymul(den, [1.0, 2.0 * w, w * w])
        if self.lowpass_radps > 0.0:
            num, den = num * self.lowpass_radps, np.polymul(den, [1.0, self.lowpass_radps])
        return num, den

    def H(self, pade_order: int = PADE_ORDER) -> control.TransferFunction:
        """``H(s)`` from the true to the measured speed, the delay by its Pade approximant of ``pade_order``.

        ``pade_order=0`` leaves the delay out: the rational part (PLL and low-pass) alone.
        """
        num, den = self._filter_factors()
        H = control.tf(num, den)
        if self.delay_s > 0.0 and pade_order > 0:
            H = H * control.tf(*control.pade(self.delay_s, pade_order))
        return H

    def frequency_response(self, w_radps: npt.ArrayLike) -> npt.NDArray[np.complex128]:
        """``H(j w)`` with the exact delay ``exp(-j w T_d)``."""
        s = 1j * np.asarray(w_radps, dtype=float)
        num, den = self._filter_factors()
        return np.asarray(np.polyval(num, s) / np.polyval(den, s) * np.exp(-s * self.delay_s), dtype=np.complex128)

    def filter_poles(self, Ts_s: float) -> tuple[float, float]:
        """``(p, q)``: the PLL's and the low-pass's discrete poles at ``Ts_s`` as the C estimator computes them.

        0 for an absent factor. Raises the C estimator's ConfigError (``bandwidth_radps``,
        ``lowpass_radps``) when a pole is out of its range at this period.
        """
        if not self.pll and self.lowpass_radps == 0.0:
            return 0.0, 0.0
        enc = Encoder(
            counts_per_rev=_NEUTRAL_COUNTS,
            Ts_s=Ts_s,
            estimator="pll" if self.pll else "difference",
            bandwidth_radps=self.bandwidth_radps if self.pll else 200.0,
            lowpass_radps=self.lowpass_radps,
        )
        c = enc.coefficients
        return float(c["pll_pole"]), float(c["lowpass_pole"])

    def filter_z(self, Ts_s: float) -> control.TransferFunction:
        """The sampled filters ``Hf(z)`` (PLL and low-pass) at ``Ts_s``, with the C estimator's poles."""
        p, q = self.filter_poles(Ts_s)
        H = control.tf([1.0], [1.0], Ts_s)
        if self.pll:
            H = H * control.tf([(1.0 - p) ** 2, 0.0, 0.0], np.polymul([1.0, -p], [1.0, -p]), Ts_s)
        if self.lowpass_radps > 0.0:
            H = H * control.tf([1.0 - q, 0.0], [1.0, -q], Ts_s)
        return H

    def filter_frequency_response(self, Ts_s: float, w_radps: npt.ArrayLike) -> npt.NDArray[np.complex128]:
        """``Hf(exp(j w Ts))`` of the sampled filters."""
        p, q = self.filter_poles(Ts_s)
        z_inv = np.exp(-1j * np.asarray(w_radps, dtype=float) * Ts_s)
        H = np.ones_like(z_inv)
        if self.pll:
            H = H * ((1.0 - p) / (1.0 - p * z_inv)) ** 2
        if self.lowpass_radps > 0.0:
            H = H * (1.0 - q) / (1.0 - q * z_inv)
        return H

    def describe(self) -> str:
        """A one-line description, e.g. ``encoder, PLL 200 rad/s, low-pass 500 rad/s, delay 1 ms``."""
        parts = [self.model]
        if self.model == "encoder":
            parts.append(f"PLL {self.bandwidth_radps:g} rad/s" if self.pll else "difference")
        if self.lowpass_radps > 0.0:
            parts.append(f"low-pass {self.lowpass_radps:g} rad/s")
        if self.delay_s > 0.0:
            parts.append(f"delay {self.delay_s * 1e3:g} ms")
        return ", ".join(parts)


#: Longest delay of the sampled loop's analysis [periods]: the loop has a state per period of
#: delay and its step response costs the cube of its order (256 periods: 1.8 s, 512: 15 s on
#: one core of the development machine, benchmarks/results.md). It covers the engine's 2046
#: current-loop periods (the scenario's bound) wherever the speed loop runs at least 8 of them.
DELAY_PERIODS_MAX = 256


def sampled_plant_blocks(J_kgm2: float, tau_i_s: float, Ts_s: float, chain: SensorChain) -> list[Any]:
    """The sampled plant and sensor chain as python-control blocks from ``u`` to ``w`` and ``y``.

    ``u`` is the torque command held over each period, ``w`` the true speed at ``t_k`` and ``y``
    the measured speed the controller reads at ``t_k`` (filters included). The plant
    ``x' = A x + B u`` (torque lag of eq 3 when ``tau_i > 0``, then the speed) is sampled
    exactly, ``x[k+1] = Phi x[k] + Gamma u[k]``, and so are the integrals of the speed over a
    fraction ``a`` of a period, ``int_0^a w dt = M_a x[k] + N_a u[k]`` (SciPy ``expm`` of the
    plant augmented with the angle). With the delay ``T_d = (n + lam) Ts``, ``0 <= lam < 1``,
    and ``a = (1 - lam) Ts``, the reading before the ``n`` further periods of delay is

    - ``ideal``: ``w(t_k - lam Ts) = v[k]``, ``v[k+1] = C Phi_a x[k] + C Gamma_a u[k]`` (``v = w[k]``
      when ``lam = 0``);
    - ``encoder``: the mean speed over the period ending at ``t_k - lam Ts``,
      ``(h[k] + t[k-1]) / Ts``, with the head ``h[k+1] = M_a x[k] + N_a u[k]`` and the tail
      ``t[k+1] = (M_Ts - M_a) x[k] + (N_Ts - N_a) u[k]`` of each period.

    Every added state forgets itself after one or two samples (eigenvalues 0): the loop has no
    mode of the angle, which the readings difference away. Returns the blocks for
    ``control.interconnect``.
    """
    n_lag = 1 if tau_i_s > 0.0 else 0
    n = n_lag + 1
    # x = (T, w) or (w): tau_i T' = u - T, J w' = T (or u); the angle theta' = w is the augmented state
    A, B = np.zeros((n + 1, n + 1)), np.zeros((n + 1, 1))
    if n_lag:
        A[0, 0], B[0, 0] = -1.0 / tau_i_s, 1.0 / tau_i_s
        A[1, 0] = 1.0 / J_kgm2
    else:
        B[0, 0] = 1.0 / J_kgm2
    A[n, n - 1] = 1.0

    def over(t_s: float) -> tuple[_Matrix, _Matrix, _Matrix, _Matrix]:
        """``(Phi, Gamma, M, N)`` of the plant over ``t_s`` and the speed's integral over it."""
        E, G = _zoh(A, B, t_s)
        return E[:n, :n], G[:n], E[n:, :n], G[n:]

    n_delay, lam = delay_periods(chain.delay_s, Ts_s)
    Phi, Gamma, M_T, N_T = over(Ts_s)
    C_w = np.zeros((1, n))
    C_w[0, n - 1] = 1.0
    if chain.model == "ideal" and lam == 0.0:
        Ad, Bd = Phi, Gamma
        C_y = C_w
    elif chain.model == "ideal":
        Phi_a, Gamma_a, _M, _N = over((1.0 - lam) * Ts_s)
        # states (x, v): v[k+1] = C Phi_a x[k] + C Gamma_a u[k], y = v
        Ad = np.block([[Phi, np.zeros((n, 1))], [C_w @ Phi_a, np.zeros((1, 1))]])
        Bd = np.vstack([Gamma, C_w @ Gamma_a])
        C_y = np.hstack([np.zeros((1, n)), [[1.0]]])
    elif lam == 0.0:
        # states (x, s): s[k+1] = M_Ts x[k] + N_Ts u[k], the angle over the period; y = s / Ts
        Ad = np.block([[Phi, np.zeros((n, 1))], [M_T, np.zeros((1, 1))]])
        Bd = np.vstack([Gamma, N_T])
        C_y = np.hstack([np.zeros((1, n)), [[1.0 / Ts_s]]])
    else:
        _P, _G, M_a, N_a = over((1.0 - lam) * Ts_s)
        # states (x, h, t, t_prev): head and tail of each period, y = (h + t_prev) / Ts
        Z = np.zeros((1, 3))
        Ad = np.block(
            [
                [Phi, np.zeros((n, 3))],
                [M_a, Z],
                [M_T - M_a, Z],
                [np.zeros((1, n)), np.array([[0.0, 1.0, 0.0]])],
            ]
        )
        Bd = np.vstack([Gamma, N_a, N_T - N_a, [[0.0]]])
        C_y = np.hstack([np.zeros((1, n)), [[1.0 / Ts_s, 0.0, 1.0 / Ts_s]]])
    C_wy = np.vstack([np.hstack([C_w, np.zeros((1, len(Ad) - n))]), C_y])
    plant = control.ss(Ad, Bd, C_wy, np.zeros((2, 1)), Ts_s, inputs="u", outputs=["w", "y_0"])
    # the whole periods of delay and the filters, in series: y_0 -> y
    reading = chain.filter_z(Ts_s)
    if n_delay:
        reading = control.tf([1.0], [1.0] + [0.0] * n_delay, Ts_s) * reading
    return [plant, control.ss(reading, inputs="y_0", outputs="y")]


def delay_periods(delay_s: float, Ts_s: float) -> tuple[int, float]:
    """The delay as ``(n, lam)``: ``delay_s = (n + lam) Ts_s``, ``n`` whole periods and ``0 <= lam < 1``.

    Raises
    ------
    ConfigError
        Naming ``delay_s`` when it exceeds :data:`DELAY_PERIODS_MAX` periods.
    """
    periods = delay_s / Ts_s
    if not periods <= DELAY_PERIODS_MAX:
        raise ConfigError(
            "delay_s",
            delay_s,
            f"<= {DELAY_PERIODS_MAX} Ts_s = {DELAY_PERIODS_MAX * Ts_s:g} s in the sampled loop's analysis (it has "
            "one state per period of delay)",
        )
    n_delay = math.floor(periods + 1e-9)
    return n_delay, periods - n_delay if periods - n_delay > 1e-9 else 0.0


def _zoh(A: _Matrix, B: _Matrix, t_s: float) -> tuple[_Matrix, _Matrix]:
    """``(expm(A t), int_0^t expm(A s) ds B)`` (SciPy ``expm`` of the block matrix)."""
    n, m = B.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = A * t_s, B * t_s
    import scipy.linalg  # loaded here: a stability check alone never needs it

    E = scipy.linalg.expm(block)
    return E[:n, :n], E[:n, n:]
