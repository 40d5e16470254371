"""Python objects over the C speed estimators of an encoder and the field weakening (no logic here).

:class:`Encoder` wraps ``p2d_encoder_t`` (csrc/include/pmsm2dof/encoder.h): the speed from the
readings of an encoder's hardware counter, by count differencing or a type-2 tracking loop
(PLL), with an optional first-order low-pass. :class:`FieldWeakening` wraps
``p2d_field_weakening_t`` (field_weakening.h): a PI on the margin between the inverter's voltage
range and the current controller's voltage command that drives the d-axis current negative
above base speed (Kim, Sul, IEEE Trans. Ind. Appl. 33(1), 1997). The speed controller takes
that current through :meth:`pmsm2dof.core.SpeedController.step_fw`.

Both compute in float32, as on the MCU; every number is the C library's.
"""

import dataclasses
import numbers
from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError
from .bindings import AntiWindup, Method, ffi, lib, struct_fields
from .fields import _finite, _get_fields, _raise_status, _struct_dict, set_fields

_ENCODER_CONFIG_FIELDS = struct_fields("p2d_encoder_config_t")
_ENCODER_PARAMS = tuple(_ENCODER_CONFIG_FIELDS)
_ENCODER_OUTPUT_FIELDS = struct_fields("p2d_encoder_output_t")
_FW_CONFIG_FIELDS = struct_fields("p2d_field_weakening_config_t")
_FW_PARAMS = tuple(_FW_CONFIG_FIELDS)
_FW_OUTPUT_FIELDS = struct_fields("p2d_field_weakening_output_t")


def _count(name: str, value: object) -> int:
    """A counter reading as the C ``uint32_t``: any integer, taken modulo 2**32."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ConfigError(name, value, "an integer (the counter reading)")
    return int(value) & 0xFFFFFFFF


@dataclasses.dataclass(frozen=True)
class EncoderOutput:
    """One speed period of the encoder (the C ``p2d_encoder_output_t``).

    Attributes
    ----------
    dn_counts : counted increment of this period [count], wrapped to the counter's signed range
    w_raw_radps : estimate before the low-pass [rad/s]
    w_m_radps : measured speed after the low-pass, what a speed controller reads [rad/s]
    fault : the non-finite policy engaged (an overflow): the outputs hold the last measured speed
    """

    dn_counts: int
    w_raw_radps: float
    w_m_radps: float
    fault: bool


class Encoder:
    """The speed of an incremental encoder from its counter readings, in C (``p2d_encoder_t``).

    Parameters
    ----------
    counts_per_rev : int
        Counts per mechanical revolution (4 x the lines of a quadrature encoder), >= 1.
    counter_bits : int
        Width of the hardware counter [bit], 2..32: it wraps at ``2**counter_bits``.
    Ts_s : float
        Speed period, the time between two readings [s], > 0.
    estimator : {"difference", "pll"}
        ``"difference"``: ``w = 2 pi dn / (counts_per_rev Ts)``, an integer multiple of the
        resolution; ``"pll"``: a critically damped type-2 tracking loop whose double pole is the
        bilinear image of ``s = -bandwidth_radps``, so that the estimate is
        ``(1 - p)^2 / (1 - p z^-1)^2`` times the difference estimate,
        ``p = (2 - bandwidth Ts) / (2 + bandwidth Ts)``.
    bandwidth_radps : float, default 200.0
        PLL pole [rad/s], ``1e-3 <= bandwidth_radps Ts_s <= 2`` (pll only).
    lowpass_radps : float, default 0.0
        First-order low-pass on the estimate [rad/s]: 0 (none) or ``1e-3 <= lowpass_radps Ts_s <= 2``.

    Raises
    ------
    ConfigError
        A parameter out of range (the message names it, the value and the valid range).
    """

    def __init__(
        self,
        *,
        counts_per_rev: int,
        counter_bits: int = 32,
        Ts_s: float,
        estimator: str,
        bandwidth_radps: float = 200.0,
        lowpass_radps: float = 0.0,
    ) -> None:
        self._enc = ffi.new("p2d_encoder_t *")
        params = dict(
            counts_per_rev=counts_per_rev, counter_bits=counter_bits, Ts_s=Ts_s, estimator=estimator,
            bandwidth_radps=bandwidth_radps, lowpass_radps=lowpass_radps,
        )  # fmt: skip
        status = lib.p2d_encoder_init(self._enc, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    @staticmethod
    def _c_config(params: Mapping[str, Any]) -> Any:
        cfg = ffi.new("p2d_encoder_config_t *")
        set_fields(cfg, _ENCODER_CONFIG_FIELDS, params)
        return cfg

    def set_config(self, **changes: Any) -> None:
        """Change parameters atomically, keeping the state (the C shadow-set swap)."""
        unknown = sorted(set(changes) - set(_ENCODER_PARAMS))
        if unknown:
            raise ConfigError(unknown[0], changes[unknown[0]], "a parameter of Encoder: " + ", ".join(_ENCODER_PARAMS))
        params = {**self._params, **changes}
        status = lib.p2d_encoder_set_config(self._enc, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    def reset(self, count: int, w_m_radps: float = 0.0) -> None:
        """Start from the reading ``count`` with the estimate at ``w_m_radps`` [rad/s]."""
        lib.p2d_encoder_reset(self._enc, _count("count", count), _finite("w_m_radps", w_m_radps))

    def step(self, count: int) -> EncoderOutput:
        """One speed period with the counter reading ``count`` (bits above ``counter_bits`` ignored)."""
        out = ffi.new("p2d_encoder_output_t *")
        lib.p2d_encoder_step(self._enc, _count("count", count), out)
        return EncoderOutput(**{name: getattr(out, name) for name in _ENCODER_OUTPUT_FIELDS})

    @property
    def resolution_radps(self) -> float:
        """Speed of one count per period, ``2 pi / (counts_per_rev Ts_s)`` [rad/s] (float32)."""
        return float(self._coef.w_res_radps)

    @property
    def coefficients(self) -> dict[str, Any]:
        """The active coefficients (the C ``p2d_encoder_coef_t``) as a dict."""
        return _struct_dict(self._coef, "p2d_encoder_coef_t")

    @property
    def config(self) -> dict[str, Any]:
        """The active configuration; ``Encoder(**enc.config)`` rebuilds it."""
        return _get_fields(self._enc.config, _ENCODER_CONFIG_FIELDS)

    @property
    def state(self) -> dict[str, float]:
        """``count_prev``, ``theta_err_counts`` (PLL angle residual), ``v_pll_counts``, ``w_lowpass_radps``."""
        e = self._enc
        return {
            "count_prev": e.count_prev,
            "theta_err_counts": e.theta_err_counts,
            "v_pll_counts": e.v_pll_counts,
            "w_lowpass_radps": e.w_lowpass_radps,
        }

    @property
    def fault_count(self) -> int:
        """Steps and resets refused so far by the non-finite policy."""
        return int(self._enc.fault_count)

    @property
    def _coef(self) -> Any:
        return self._enc.coef[self._enc.active]

    def __repr__(self) -> str:
        return "Encoder(" + ", ".join(f"{k}={v!r}" for k, v in self.config.items()) + ")"


@dataclasses.dataclass(frozen=True)
class FieldWeakeningOutput:
    """One sample of the field weakening (the C ``p2d_field_weakening_output_t``), float32 values.

    Attributes
    ----------
    u_ref_V : the voltage held, ``voltage_ratio max(u_dc, 0) / sqrt(3)`` [V]
    e_V : margin ``u_ref - ||u_dq||`` [V]
    id_unsat_A : PI output before the limit [A]
    id_ref_A : d-axis current command in ``[id_min_A, 0]`` [A]
    active : ``id_ref_A < 0``: the field is weakened
    at_id_min : ``id_ref_A == id_min_A``: no weakening left
    fault : the non-finite policy engaged: ``id_ref_A`` holds the integrator's current
    """

    u_ref_V: float
    e_V: float
    id_unsat_A: float
    id_ref_A: float
    active: bool
    at_id_min: bool
    fault: bool


class FieldWeakening:
    """Voltage-feedback field weakening, in C (``p2d_field_weakening_t``).

    A PI on the margin ``e = voltage_ratio u_dc / sqrt(3) - ||u_dq||`` between the inverter's
    range and the current controller's voltage command (before its limit) drives the d-axis
    current into ``[id_min_A, 0]``, with the anti-windup of the PI at both limits (Fig. 5).

    Parameters
    ----------
    Kp_A_per_V : float
        Proportional gain [A/V], >= 0.
    Ki_A_per_Vs : float
        Integral gain [A/(V s)], > 0. Near the operating point ``d||u||/d id`` is about
        ``w_e Ld``: the loop crosses over near ``Ki w_e Ld`` [rad/s].
    Ka_V_per_A : float
        Back-calculation gain [V/A], >= 0, ``Ki Ka Ts < 2``.
    Ts_s : float
        Sampling period [s], > 0.
    voltage_ratio : float
        Share of ``u_dc / sqrt(3)`` held, in (0, 1].
    id_min_A : float
        Most negative d-axis current [A], < 0.
    method : {"forward_euler", "backward_euler", "tustin"}, default "tustin"
    anti_windup : {"none", "back_calculation", "clamping"}, default "back_calculation"

    Raises
    ------
    ConfigError
        A parameter out of range (the message names it, the value and the valid range).
    """

    def __init__(
        self,
        *,
        Kp_A_per_V: float,
        Ki_A_per_Vs: float,
        Ka_V_per_A: float,
        Ts_s: float,
        voltage_ratio: float,
        id_min_A: float,
        method: Method = "tustin",
        anti_windup: AntiWindup = "back_calculation",
    ) -> None:
        self._fw = ffi.new("p2d_field_weakening_t *")
        params = dict(
            Kp_A_per_V=Kp_A_per_V, Ki_A_per_Vs=Ki_A_per_Vs, Ka_V_per_A=Ka_V_per_A, Ts_s=Ts_s,
            voltage_ratio=voltage_ratio, id_min_A=id_min_A, method=method, anti_windup=anti_windup,
        )  # fmt: skip
        status = lib.p2d_field_weakening_init(self._fw, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    @staticmethod
    def _c_config(params: Mapping[str, Any]) -> Any:
        cfg = ffi.new("p2d_field_weakening_config_t *")
        set_fields(cfg, _FW_CONFIG_FIELDS, params)
        return cfg

    def set_config(self, **changes: Any) -> None:
        """Change parameters atomically, keeping the integrator (the C shadow-set swap)."""
        unknown = sorted(set(changes) - set(_FW_PARAMS))
        if unknown:
            raise ConfigError(
                unknown[0], changes[unknown[0]], "a parameter of FieldWeakening: " + ", ".join(_FW_PARAMS)
            )
        params = {**self._params, **changes}
        status = lib.p2d_field_weakening_set_config(self._fw, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    def reset(self, id_A: float = 0.0) -> None:
        """Bumpless start at the d current ``id_A`` [A], clamped to ``[id_min_A, 0]``."""
        lib.p2d_field_weakening_reset(self._fw, _finite("id_A", id_A))

    def step(self, ud_V: float, uq_V: float, u_dc_V: float) -> FieldWeakeningOutput:
        """One sample: the current controller's voltage command [V] and the measured DC link [V]."""
        out = ffi.new("p2d_field_weakening_output_t *")
        lib.p2d_field_weakening_step(self._fw, float(ud_V), float(uq_V), float(u_dc_V), out)
        return FieldWeakeningOutput(**{name: getattr(out, name) for name in _FW_OUTPUT_FIELDS})

    @property
    def config(self) -> dict[str, Any]:
        """The active configuration; ``FieldWeakening(**fw.config)`` rebuilds it."""
        return _get_fields(self._fw.config, _FW_CONFIG_FIELDS)

    @property
    def x_A(self) -> float:
        """The integrator x[k-1] [A]."""
        return float(self._fw.x_A)

    @property
    def fault_count(self) -> int:
        """Samples rejected so far by the non-finite policy."""
        return int(self._fw.fault_count)

    def __repr__(self) -> str:
        return "FieldWeakening(" + ", ".join(f"{k}={v!r}" for k, v in self.config.items()) + ")"
