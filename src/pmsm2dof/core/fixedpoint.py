"""The fixed-point speed controllers (Q15 and Q31) of the C library, for MCUs without an FPU.

:class:`FixedPointSpeedController` wraps ``p2d_speed_q15_t`` and ``p2d_speed_q31_t``
(csrc/include/pmsm2dof/speed_fixed.h): the controller of :class:`~.controllers.SpeedController`
(paper Fig. 5 and 6, eq 9-15) whose step computes in integers only. Speeds, torques and currents
are integers in units of their full scale: ``w_q = w 2^N / speed_full_scale_radps`` with ``N = 15``
(Q15: int16 inputs and outputs, int32 arithmetic) or ``N = 31`` (Q31: int32 inputs and outputs,
int64 arithmetic, an integrator with 31 more fractional bits). Every number is computed by the C
code, the same that is cross-compiled for the Cortex-M0 and M3; the coefficients, quantised at
init, are read back (:attr:`~FixedPointSpeedController.coefficients`) beside the values they
approximate (:attr:`~FixedPointSpeedController.gains`).

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller".
"""

import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any, Literal

from ..errors import ConfigError, require_choice
from .bindings import AntiWindup, Feedforward, Method, ffi, lib, struct_fields
from .controllers import SpeedController, _given_speed
from .fields import _float_param, _get_fields, _raise_status

#: The fixed-point formats: Q15 (int16 data, int32 arithmetic) and Q31 (int32 data, int64 arithmetic).
Format = Literal["q15", "q31"]
FORMATS: tuple[Format, ...] = ("q15", "q31")
#: Fractional bits N of each format: a full scale is the integer 2^N.
FRACTIONAL_BITS = {"q15": 15, "q31": 31}
#: Fractional bits of the integrator beyond the torque's (x_q62 of the Q31 controller, speed_fixed.h).
INTEGRATOR_EXTRA_BITS = {"q15": 0, "q31": 31}
#: The quantised gains of the coefficient sets (``p2d_speed_q15_coef_t``), in declaration order.
GAINS = ("b_e0", "Ki_Ts", "Ki_Ka_Ts", "ff_Fr0", "ff_b_dr", "ff_one_plus_a1", "ff_Kd_per_Ts", "iq_per_T")
#: The scalings of a fixed-point controller, the fields of ``p2d_speed_fixed_config_t`` after the design.
SCALINGS = ("speed_full_scale_radps", "torque_full_scale_Nm", "current_full_scale_A")

_SPEED_CONFIG_FIELDS = struct_fields("p2d_speed_config_t")
_PARAMS = tuple(_SPEED_CONFIG_FIELDS) + SCALINGS
_GAIN_FIELDS = struct_fields("p2d_speed_fixed_gains_t")


@dataclasses.dataclass(frozen=True)
class FixedPointOutput:
    """One sample of a fixed-point speed controller (``p2d_speed_q15_output_t`` or ``_q31_``).

    Integers in LSBs of the format (the C fields carry its suffix, ``T_ref_q15``): speeds of
    ``speed_full_scale_radps / 2^N``, torques of ``torque_full_scale_Nm / 2^N``, currents of
    ``current_full_scale_A / 2^N``.

    Attributes
    ----------
    w_ref : reference used this sample
    e : speed error w_ref - w_m
    T_ff : feedforward torque Fr(z) w_ref (eq 11-13, 15)
    y_ff : transient y[k] of the feedforward
    T_unsat : u, feedback plus feedforward before the limit
    T_ref : u_sat, torque of the limited current vector
    iq_ref : q-axis current command (id = 0, surface PMSM), within i_max_A in magnitude
    saturated : the current-vector limit is active
    """

    w_ref: int
    e: int
    T_ff: int
    y_ff: int
    T_unsat: int
    T_ref: int
    iq_ref: int
    saturated: bool


class FixedPointSpeedController:
    """The 2DOF PI speed controller with anti-windup of the paper in Q15 or Q31, in C.

    The design and drive parameters are those of :class:`~.controllers.SpeedController` (without
    torque filters; a surface PMSM, ``Ld_H == Lq_H``), validated by the same C rules; the
    scalings set the units of the integers.

    Parameters
    ----------
    fmt : {"q15", "q31"}
        Q15 (int16 inputs and outputs, int32 arithmetic, what a Cortex-M0 multiplies in one
        instruction) or Q31 (int32 inputs and outputs, int64 arithmetic).
    speed_full_scale_radps : float
        Speed of the integer 2^N [rad/s], > 0.
    torque_full_scale_Nm : float
        Torque of the integer 2^N [Nm], at least the torque limit ``1.5 p psi_f i_max_A``.
    current_full_scale_A : float
        Current of the integer 2^N [A], at least ``i_max_A``.
    J_kgm2, alpha_radps, zeta, m, tau_i_s, Ka, Ts_s, i_max_A, psi_f_Wb, Ld_H, Lq_H, pole_pairs, method, \
feedforward, anti_windup
        As :class:`~.controllers.SpeedController`.

    Raises
    ------
    ConfigError
        A parameter has the wrong type or is out of range (the message names the parameter,
        the value given and the valid range), the scalings included: every gain that
        multiplies a speed below 2^13 per unit, and in Q31 one LSB of speed error must move
        the integrator.
    """

    def __init__(
        self,
        fmt: Format,
        *,
        J_kgm2: float,
        alpha_radps: float,
        zeta: float,
        m: float = 1.0,
        tau_i_s: float = 0.0,
        Ka: float | None = None,
        Ts_s: float,
        i_max_A: float,
        psi_f_Wb: float,
        Ld_H: float,
        Lq_H: float,
        pole_pairs: int,
        method: Method = "tustin",
        feedforward: Feedforward = "lowpass",
        anti_windup: AntiWindup = "back_calculation",
        speed_full_scale_radps: float,
        torque_full_scale_Nm: float,
        current_full_scale_A: float,
    ) -> None:
        self._fmt: Format = require_choice("fmt", fmt, FORMATS)
        self._ctl = ffi.new(f"p2d_speed_{fmt}_t *")  # cffi ``p2d_speed_q15_t *`` or ``_q31_``
        params: dict[str, Any] = dict(
            J_kgm2=J_kgm2, alpha_radps=alpha_radps, zeta=zeta, m=m, tau_i_s=tau_i_s, Ka=Ka, Ts_s=Ts_s,
            i_max_A=i_max_A, psi_f_Wb=psi_f_Wb, Ld_H=Ld_H, Lq_H=Lq_H, pole_pairs=pole_pairs,
            method=method, feedforward=feedforward, anti_windup=anti_windup,
            speed_full_scale_radps=speed_full_scale_radps, torque_full_scale_Nm=torque_full_scale_Nm,
            current_full_scale_A=current_full_scale_A,
        )  # fmt: skip
        cfg = self._c_config(params)
        status = self._call("init", cfg)
        if status != lib.P2D_OK:
            _raise_status(status, _given_speed(params, cfg.speed))
        self._params = params

    @property
    def fmt(self) -> Format:
        """The format, ``"q15"`` or ``"q31"``."""
        return self._fmt

    @property
    def bits(self) -> int:
        """Fractional bits N of the format: a full scale is the integer 2^N."""
        return FRACTIONAL_BITS[self._fmt]

    def _call(self, name: str, *args: Any) -> Any:
        """``p2d_speed_<fmt>_<name>(ctl, *args)``."""
        return getattr(lib, f"p2d_speed_{self._fmt}_{name}")(self._ctl, *args)

    @staticmethod
    def _c_config(params: Mapping[str, Any]) -> Any:
        """The C ``p2d_speed_fixed_config_t *`` of ``params``; type errors raise ConfigError."""
        cfg = ffi.new("p2d_speed_fixed_config_t *")
        cfg.speed = SpeedController._c_config(params)[0]
        for name in SCALINGS:
            setattr(cfg, name, _float_param(name, params[name]))
        return cfg

    def set_config(self, **changes: Any) -> None:
        """Change design parameters atomically, keeping the state (bumpless at a constant reference).

        The scalings stay as they are (the state is held in their LSBs). Invalid parameters
        raise :class:`ConfigError` and leave the old configuration active.
        """
        unknown = sorted(set(changes) - set(_PARAMS))
        if unknown:
            raise ConfigError(
                unknown[0], changes[unknown[0]], "a parameter of FixedPointSpeedController: " + ", ".join(_PARAMS)
            )
        params = {**self._params, **changes}
        cfg = self._c_config(params)
        status = self._call("set_config", cfg)
        if status != lib.P2D_OK:
            _raise_status(status, _given_speed(params, cfg.speed))
        self._params = params

    def _integer(self, name: str, value: object, bits: int) -> int:
        """``value`` as a signed integer of ``bits`` bits, else ConfigError naming ``name``."""
        lo, hi = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= int(value) <= hi:
            raise ConfigError(name, value, f"an integer from {lo} to {hi} ({self._fmt})")
        return int(value)

    def _input(self, name: str, value: object) -> int:
        """An input of the format: an integer of N + 1 bits."""
        return self._integer(name, value, self.bits + 1)

    def reset(self, w_ref: int = 0, T_init: int = 0) -> None:
        """Bumpless reset: the feedforward at rest at the reference ``w_ref``, the output ``T_init`` at zero error."""
        self._call("reset", self._input("w_ref", w_ref), self._input("T_init", T_init))

    def compute(self, w_ref: int, w_m: int) -> FixedPointOutput:
        """The command for this sample (speeds in LSBs of the format); the state is not changed."""
        out = ffi.new(f"p2d_speed_{self._fmt}_output_t *")
        self._call("compute", self._input("w_ref", w_ref), self._input("w_m", w_m), out)
        return self._output(out)

    def update(self, output: FixedPointOutput, T_applied: int) -> None:
        """Update the state with the torque actually applied after every limit (LSBs of the format)."""
        out = ffi.new(f"p2d_speed_{self._fmt}_output_t *")
        suffix = f"_{self._fmt}"
        for field in dataclasses.fields(output):
            name = field.name if field.name == "saturated" else field.name + suffix
            setattr(out, name, getattr(output, field.name))
        self._call("update", out, self._input("T_applied", T_applied))

    def step(self, w_ref: int, w_m: int) -> FixedPointOutput:
        """:meth:`compute` and :meth:`update` with the controller's own limited torque."""
        out = ffi.new(f"p2d_speed_{self._fmt}_output_t *")
        self._call("step", self._input("w_ref", w_ref), self._input("w_m", w_m), out)
        return self._output(out)

    def _output(self, out: Any) -> FixedPointOutput:
        suffix = f"_{self._fmt}"
        values = {f.name: getattr(out, f.name if f.name == "saturated" else f.name + suffix) for f in _OUTPUT_FIELDS}
        return FixedPointOutput(**values)

    @property
    def config(self) -> dict[str, Any]:
        """The active configuration (float32 values); ``Ka`` is None when it is the default 1/Kp.

        ``FixedPointSpeedController(ctl.fmt, **ctl.config)`` builds an equal controller.
        """
        cfg = _get_fields(self._ctl.config.speed, _SPEED_CONFIG_FIELDS)
        cfg.update((name, getattr(self._ctl.config, name)) for name in SCALINGS)
        if self._params["Ka"] is None:
            cfg["Ka"] = None
        return cfg

    @property
    def coefficients(self) -> dict[str, Any]:
        """The active quantised coefficients: each gain of :data:`GAINS` as ``(mantissa, shift)``
        (the gain is ``mantissa 2^-shift``), ``T_max`` and ``iq_max`` (LSBs) and ``clamping``."""
        c = self._ctl.coef[self._ctl.active]
        coef: dict[str, Any] = {name: (int(getattr(c, name).mantissa), int(getattr(c, name).shift)) for name in GAINS}
        coef["T_max"] = int(getattr(c, f"T_max_{self._fmt}"))
        coef["iq_max"] = int(getattr(c, f"iq_max_{self._fmt}"))
        coef["clamping"] = bool(c.clamping)
        return coef

    @property
    def gains(self) -> dict[str, float]:
        """The active coefficients before quantisation, per unit of the scalings (``p2d_speed_fixed_gains_t``)."""
        gains = ffi.new("p2d_speed_fixed_gains_t *")
        status = getattr(lib, f"p2d_speed_{self._fmt}_gains")(ffi.addressof(self._ctl.config), gains)
        if status != lib.P2D_OK:  # the active configuration was validated by the same function
            raise RuntimeError(f"p2d_speed_{self._fmt}_gains refused the active configuration ({status})")
        return {name: float(getattr(gains, name)) for name in _GAIN_FIELDS}

    @property
    def state(self) -> dict[str, int]:
        """The state: ``x`` (integrator plus static feedforward, in LSBs of ``2^-(N + F)`` full scales,
        F = :data:`INTEGRATOR_EXTRA_BITS`), ``y_ff_prev`` and ``r_prev`` (LSBs of the format)."""
        c, fmt = self._ctl, self._fmt
        x = c.x_q15 if fmt == "q15" else c.x_q62
        return {
            "x": int(x),
            "y_ff_prev": int(getattr(c, f"y_ff_prev_{fmt}")),
            "r_prev": int(getattr(c, f"r_prev_{fmt}")),
        }

    def speed_to_q(self, w_radps: float) -> int:
        """The speed ``w_radps`` [rad/s] as the nearest integer of the format, saturated to its range."""
        return self._to_q(w_radps, float(self._ctl.config.speed_full_scale_radps))

    def torque_to_q(self, T_Nm: float) -> int:
        """The torque ``T_Nm`` [Nm] as the nearest integer of the format, saturated to its range."""
        return self._to_q(T_Nm, float(self._ctl.config.torque_full_scale_Nm))

    def _to_q(self, value: float, full_scale: float) -> int:
        top = 1 << self.bits
        return max(-top, min(top - 1, round(math.ldexp(float(value) / full_scale, self.bits))))

    def speed_from_q(self, w_q: int) -> float:
        """The speed [rad/s] of the integer ``w_q``."""
        return math.ldexp(float(w_q) * float(self._ctl.config.speed_full_scale_radps), -self.bits)

    def torque_from_q(self, T_q: int) -> float:
        """The torque [Nm] of the integer ``T_q``."""
        return math.ldexp(float(T_q) * float(self._ctl.config.torque_full_scale_Nm), -self.bits)

    def current_from_q(self, i_q: int) -> float:
        """The current [A] of the integer ``i_q``."""
        return math.ldexp(float(i_q) * float(self._ctl.config.current_full_scale_A), -self.bits)

    def __repr__(self) -> str:
        return (
            f"FixedPointSpeedController({self._fmt!r}, " + ", ".join(f"{k}={v!r}" for k, v in self.config.items()) + ")"
        )


_OUTPUT_FIELDS = dataclasses.fields(FixedPointOutput)
