"""Python objects over the deployable C controllers (no controller logic here).

:class:`SpeedController` wraps ``p2d_speed_t`` (paper Fig. 5 and 6: the 2DOF PI
speed controller with anti-windup, eq 9-15) and :class:`CurrentController` wraps
``p2d_current_t`` (the dq current regulators of Fig. 1 with the loop of eq 3).
Every number is computed by the C code in ``csrc/src``, the same code that is
cross-compiled for the MCU; ``run`` methods drive it over whole arrays in one C
call (``csrc/sim/batch.c``).

The controllers compute in float32 (C ``float``): Python floats given to them
are rounded to the nearest float32, and the values read back (outputs,
coefficients, configuration, state) are those float32 numbers.

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for
Permanent-Magnet Synchronous Motor Speed Controller".
"""

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ConfigError
from .bindings import (
    AntiWindup,
    Feedforward,
    Method,
    ffi,
    lib,
    struct_fields,
)
from .fields import (
    _as_inputs,
    _finite,
    _float_param,
    _float_ptr,
    _get_fields,
    _raise_status,
    _struct_dict,
    _structured_dtype,
    set_fields,
)

# ---------------------------------------------------------------------------------------------
# Speed controller
# ---------------------------------------------------------------------------------------------

_SPEED_OUTPUT_FIELDS = struct_fields("p2d_speed_output_t")
_SPEED_OUTPUT_DTYPE = _structured_dtype("p2d_speed_output_t", _SPEED_OUTPUT_FIELDS)
#: The parameters of SpeedController: the fields of p2d_speed_config_t, with their C types.
_SPEED_CONFIG_FIELDS = struct_fields("p2d_speed_config_t")
#: The torque filters' parameters (p2d_filter_config_t, csrc/include/pmsm2dof/filter.h); all 0: no filter.
_FILTER_CONFIG_FIELDS = struct_fields("p2d_filter_config_t")
_SPEED_PARAMS = tuple(_SPEED_CONFIG_FIELDS) + tuple(_FILTER_CONFIG_FIELDS)


@dataclasses.dataclass(frozen=True)
class SpeedOutput:
    """One sample of the speed controller (the C ``p2d_speed_output_t``), float32 values.

    Attributes
    ----------
    w_ref_radps : reference used this sample [rad/s]
    e_radps : speed error w_ref - w_m [rad/s]
    T_ff_Nm : feedforward torque Fr(z) w_ref [Nm] (eq 11-13, 15)
    y_ff_Nm : transient of the feedforward, T_ff without Fr(0) w_ref and the derivative part [Nm]
    T_unsat_Nm : u, feedback plus feedforward before the limit [Nm]
    T_ref_Nm : u_sat, torque of the limited current vector [Nm]
    id_ref_A, iq_ref_A : current command [A], ||i_dq|| <= i_max_A
    saturated : the current-vector limit is active
    fault : the non-finite policy engaged (outputs are zero, state untouched)
    """

    w_ref_radps: float
    e_radps: float
    T_ff_Nm: float
    y_ff_Nm: float
    T_unsat_Nm: float
    T_ref_Nm: float
    id_ref_A: float
    iq_ref_A: float
    saturated: bool
    fault: bool


class SpeedController:
    """The 2DOF PI speed controller with anti-windup of the paper (Fig. 5 and 6), in C.

    Gains from eq 9: ``Kp = J alpha``, ``Ki = J (alpha / (2 zeta))**2``. The PI
    feedback is discretized as in eq 14 and the reference feedforward as in
    eq 11, 13 and 15 (``feedforward``: ``"none"`` 1DOF, ``"lowpass"`` eq 13 with
    m = 1, ``"no_tau"`` eq 11 with tau_i = 0, ``"full"`` eq 11 with the derivative
    part realized by a backward difference of the reference). The torque
    reference is turned into a current vector (id = 0 for Ld == Lq, MTPA
    otherwise) limited to ``||i_dq|| <= i_max_A``; the torque the limit removes,
    ``u* = u_sat - u``, drives the anti-windup (``dx_i/dt = Ki (e + Ka u*)`` for
    back calculation, Fig. 5).

    Parameters
    ----------
    J_kgm2 : float
        Design inertia [kg m^2], > 0.
    alpha_radps : float
        Bandwidth of the P loop [rad/s], > 0 (eq 9).
    zeta : float
        Relative damping of the PI loop, > 0 (eq 9).
    m : float, default 1.0
        Tracking pole factor, Gx = m alpha / (s + m alpha) (eq 10), > 0; must be 1
        with ``feedforward="lowpass"``, the default.
    tau_i_s : float, default 0.0
        Current-loop time constant [s], >= 0 (eq 3); used by ``feedforward="full"``.
    Ka : float or None, default None
        Back-calculation gain [(rad/s)/Nm], >= 0. None selects the paper's
        ``Ka = 1/Kp`` (section 3.3), which then follows J and alpha in
        :meth:`set_config`.
    Ts_s : float
        Sampling period [s], > 0.
    i_max_A : float
        Current-vector limit [A], > 0.
    psi_f_Wb, Ld_H, Lq_H : float
        Flux linkage [Wb] and dq inductances [H] of the motor, > 0.
    pole_pairs : int
        Pole pairs, >= 1. The torque is ``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``
        (amplitude-invariant Park; the paper's eq 1 omits the 1.5 and calls p0
        the number of poles while using it as pole pairs).
    method : {"forward_euler", "backward_euler", "tustin"}, default "tustin"
        Discretization of every dynamic part (Table 1).
    feedforward : {"lowpass", "none", "no_tau", "full"}, default "lowpass"
        ``"lowpass"``: eq 13 discretized as eq 15, the paper's 2DOF controller (section 4),
        which requires m = 1; ``"none"``: the 1DOF PI; ``"no_tau"`` or ``"full"``: eq 11,
        for any m.
    anti_windup : {"none", "back_calculation", "clamping"}, default "back_calculation"
    notch_freq_Hz, notch_width_Hz, notch_depth : float, default 0.0
        Notch on the torque command (csrc/include/pmsm2dof/filter.h): frequency f0 [Hz] (0: no
        notch, else < 1/(2 Ts_s)), -3 dB width [Hz] and gain at f0, ``0 <= depth < 1/sqrt(2)``.
        Tustin prewarped at f0: the discrete notch has exactly the depth at f0 and the width.
    lowpass_freq_Hz, lowpass_zeta : float, default 0.0
        Second-order low-pass on the torque command: natural frequency [Hz] (0: none) and damping.
        The filters run inside the anti-windup loop: the limit acts on the filtered command and
        ``u* = u_sat - u_f`` drives the back calculation (``T_unsat_Nm`` is then ``u_f``).

    Raises
    ------
    ConfigError
        A parameter has the wrong type or is out of range (the message names the
        parameter, the value given and the valid range).

    Notes
    -----
    Computation is float32 (C ``float``); Python floats are rounded to float32.
    """

    def __init__(
        self,
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
        notch_freq_Hz: float = 0.0,
        notch_width_Hz: float = 0.0,
        notch_depth: float = 0.0,
        lowpass_freq_Hz: float = 0.0,
        lowpass_zeta: float = 0.0,
    ) -> None:
        self._ctl = ffi.new("p2d_speed_t *")  # cffi ``p2d_speed_t *``
        params: dict[str, Any] = dict(
            J_kgm2=J_kgm2, alpha_radps=alpha_radps, zeta=zeta, m=m, tau_i_s=tau_i_s, Ka=Ka, Ts_s=Ts_s,
            i_max_A=i_max_A, psi_f_Wb=psi_f_Wb, Ld_H=Ld_H, Lq_H=Lq_H, pole_pairs=pole_pairs,
            method=method, feedforward=feedforward, anti_windup=anti_windup,
            notch_freq_Hz=notch_freq_Hz, notch_width_Hz=notch_width_Hz, notch_depth=notch_depth,
            lowpass_freq_Hz=lowpass_freq_Hz, lowpass_zeta=lowpass_zeta,
        )  # fmt: skip
        cfg = self._c_config(params)
        filt = self._c_filter(params)
        status = lib.p2d_speed_init(self._ctl, cfg)
        if status == lib.P2D_OK and (filt.notch_freq_Hz != 0 or filt.lowpass_freq_Hz != 0):
            status = lib.p2d_speed_set_filter(self._ctl, filt)
        if status != lib.P2D_OK:
            _raise_status(status, _given_speed(params, cfg))
        self._params = params

    @staticmethod
    def _c_config(params: Mapping[str, Any]) -> Any:
        """The C configuration of ``params`` (a cffi ``p2d_speed_config_t *``); type errors raise ConfigError."""
        cfg = ffi.new("p2d_speed_config_t *")
        set_fields(cfg, {name: t for name, t in _SPEED_CONFIG_FIELDS.items() if name != "Ka"}, params)
        if params["Ka"] is None:
            # section 3.3: Ka = 1/Kp, computed in float32 by the C library
            cfg.Ka = lib.p2d_speed_Ka_default(cfg.J_kgm2, cfg.alpha_radps)
        else:
            cfg.Ka = _float_param("Ka", params["Ka"])
        return cfg

    @staticmethod
    def _c_filter(params: dict[str, Any]) -> Any:
        """The C torque-filter configuration of ``params`` (cffi ``p2d_filter_config_t *``); type
        errors raise ConfigError."""
        filt = ffi.new("p2d_filter_config_t *")
        set_fields(filt, _FILTER_CONFIG_FIELDS, params)
        return filt

    def set_config(self, **changes: Any) -> None:
        """Change parameters atomically, keeping the controller state.

        The new configuration is validated and its coefficients computed into the
        C controller's shadow set, which is then made active; if any parameter is
        invalid, :class:`ConfigError` is raised and the old configuration stays.
        """
        unknown = sorted(set(changes) - set(_SPEED_PARAMS))
        if unknown:
            raise ConfigError(
                unknown[0], changes[unknown[0]], "a parameter of SpeedController: " + ", ".join(_SPEED_PARAMS)
            )
        params = {**self._params, **changes}
        cfg = self._c_config(params)
        filt = self._c_filter(params)
        # both changes on a copy first, so that a rejected filter leaves the old configuration
        for ctl in (ffi.new("p2d_speed_t *", self._ctl[0]), self._ctl):
            status = lib.p2d_speed_set_config(ctl, cfg)
            if status == lib.P2D_OK:
                status = lib.p2d_speed_set_filter(ctl, filt)
            if status != lib.P2D_OK:
                _raise_status(status, _given_speed(params, cfg))
        self._params = params

    def reset(self, w_ref_radps: float = 0.0, T_init_Nm: float = 0.0) -> None:
        """Bumpless reset: feedforward at steady state for a constant ``w_ref_radps``,
        integrator such that the output is ``T_init_Nm`` at zero error."""
        lib.p2d_speed_reset(self._ctl, _finite("w_ref_radps", w_ref_radps), _finite("T_init_Nm", T_init_Nm))

    def compute(self, w_ref_radps: float, w_m_radps: float) -> SpeedOutput:
        """The command for this sample [rad/s in]; the state is not changed."""
        out = ffi.new("p2d_speed_output_t *")
        lib.p2d_speed_compute(self._ctl, float(w_ref_radps), float(w_m_radps), out)
        return _speed_output(out)

    def update(self, output: SpeedOutput, T_applied_Nm: float) -> None:
        """Update the state with the torque actually applied after every limit [Nm]."""
        out = ffi.new("p2d_speed_output_t *", dataclasses.asdict(output))
        lib.p2d_speed_update(self._ctl, out, float(T_applied_Nm))

    def step(self, w_ref_radps: float, w_m_radps: float) -> SpeedOutput:
        """:meth:`compute` and :meth:`update` with the controller's own limited torque."""
        out = ffi.new("p2d_speed_output_t *")
        lib.p2d_speed_step(self._ctl, float(w_ref_radps), float(w_m_radps), out)
        return _speed_output(out)

    def compute_fw(self, w_ref_radps: float, w_m_radps: float, id_fw_A: float) -> SpeedOutput:
        """:meth:`compute` with the d-axis current bound ``id_fw_A`` [A] of a field weakening.

        The torque limit follows the q-axis current that remains, ``sqrt(i_max^2 - id^2)``
        (``p2d_speed_compute_fw``, csrc/include/pmsm2dof/speed.h); the state is not changed.
        """
        out = ffi.new("p2d_speed_output_t *")
        lib.p2d_speed_compute_fw(self._ctl, float(w_ref_radps), float(w_m_radps), float(id_fw_A), out)
        return _speed_output(out)

    def step_fw(self, w_ref_radps: float, w_m_radps: float, id_fw_A: float) -> SpeedOutput:
        """:meth:`compute_fw` and :meth:`update` with the controller's own limited torque."""
        out = ffi.new("p2d_speed_output_t *")
        lib.p2d_speed_step_fw(self._ctl, float(w_ref_radps), float(w_m_radps), float(id_fw_A), out)
        return _speed_output(out)

    def run(self, w_ref_radps: npt.ArrayLike, w_m_radps: npt.ArrayLike) -> dict[str, npt.NDArray[Any]]:
        """Run :meth:`step` over whole arrays in one C call (``p2d_speed_run``).

        Parameters
        ----------
        w_ref_radps, w_m_radps : array_like
            Reference and measured mechanical speed [rad/s], 1-D of one length
            (or scalars, broadcast).

        Returns
        -------
        dict of numpy.ndarray
            One array per field of :class:`SpeedOutput` (float32, bool for
            ``saturated`` and ``fault``) plus ``x_i_Nm``, the integral of the PI
            after each sample. The state carries over to the next call. Samples
            with non-finite input are flagged in ``fault``.
        """
        w_ref, w_m = _as_inputs(("w_ref_radps", "w_m_radps"), (w_ref_radps, w_m_radps))
        n = w_ref.size
        out = np.zeros(n, dtype=_SPEED_OUTPUT_DTYPE)
        x_i = np.zeros(n, dtype=np.float32)
        lib.p2d_speed_run(
            self._ctl, n, _float_ptr(w_ref), _float_ptr(w_m),
            ffi.cast("p2d_speed_output_t *", ffi.from_buffer(out)), _float_ptr(x_i),
        )  # fmt: skip
        result = {name: np.ascontiguousarray(out[name]) for name in _SPEED_OUTPUT_FIELDS}
        result["x_i_Nm"] = x_i
        return result

    @property
    def Kp(self) -> float:
        """Proportional gain J alpha [Nm/(rad/s)] (eq 9)."""
        return float(self._coef.pi.Kp)

    @property
    def Ki(self) -> float:
        """Integral gain J (alpha / (2 zeta))**2 [Nm/rad] (eq 9)."""
        return float(self._coef.pi.Ki)

    @property
    def Ka(self) -> float:
        """Back-calculation gain in use [(rad/s)/Nm] (1/Kp unless given)."""
        return float(self._ctl.config.Ka)

    @property
    def coefficients(self) -> dict[str, float | bool]:
        """The active precomputed coefficients (the C ``p2d_speed_coef_t``, its PI ``pi`` flattened) as a dict."""
        c = self._coef
        coef = _struct_dict(c.pi, "p2d_pi_coef_t")
        coef.update((name, value) for name, value in _struct_dict(c, "p2d_speed_coef_t").items() if name != "pi")
        return coef

    @property
    def config(self) -> dict[str, Any]:
        """The active configuration as float32 values; ``Ka`` is None when it is the default 1/Kp.

        ``SpeedController(**ctl.config)`` builds an equal controller.
        """
        cfg = _get_fields(self._ctl.config, _SPEED_CONFIG_FIELDS)
        cfg.update(_get_fields(self._ctl.filter_config, _FILTER_CONFIG_FIELDS))
        if self._params["Ka"] is None:
            cfg["Ka"] = None
        return cfg

    @property
    def state(self) -> dict[str, float]:
        """Controller state: ``x_Nm``, ``r_prev_radps`` and ``y_ff_prev_Nm``.

        ``x_Nm`` is the integrator plus the static feedforward, x = x_i + Fr(0) r[k-1]
        (csrc/include/pmsm2dof/speed.h); :attr:`x_i_Nm` is the integral alone.
        """
        c = self._ctl
        return {"x_Nm": c.x_Nm, "r_prev_radps": c.r_prev_radps, "y_ff_prev_Nm": c.y_ff_prev_Nm}

    @property
    def x_i_Nm(self) -> float:
        """Integral of the PI, x_i = x - Fr(0) r[k-1] [Nm] (``p2d_speed_integrator_Nm``)."""
        return float(lib.p2d_speed_integrator_Nm(self._ctl))

    @property
    def fault_count(self) -> int:
        """Samples rejected so far by the non-finite policy (not cleared by :meth:`reset`)."""
        return int(self._ctl.fault_count)

    @property
    def _coef(self) -> Any:  # cffi ``p2d_speed_coef_t``
        return self._ctl.coef[self._ctl.active]

    def __repr__(self) -> str:
        return "SpeedController(" + ", ".join(f"{k}={v!r}" for k, v in self.config.items()) + ")"


def _given_speed(params: Mapping[str, Any], cfg: Any) -> dict[str, Any]:
    """The parameters as the user gave them, for error messages; a default Ka shows its value."""
    if params["Ka"] is None:
        return {**params, "Ka": f"None (default 1/Kp = {cfg.Ka:.6g})"}
    return dict(params)


def _speed_output(out: Any) -> SpeedOutput:
    return SpeedOutput(**{name: getattr(out, name) for name in _SPEED_OUTPUT_FIELDS})


# ---------------------------------------------------------------------------------------------
# Current controller
# ---------------------------------------------------------------------------------------------

_CURRENT_OUTPUT_FIELDS = struct_fields("p2d_current_output_t")
_CURRENT_OUTPUT_DTYPE = _structured_dtype("p2d_current_output_t", _CURRENT_OUTPUT_FIELDS)
#: The parameters of CurrentController: the fields of p2d_current_config_t, with their C types.
_CURRENT_CONFIG_FIELDS = struct_fields("p2d_current_config_t")
_CURRENT_PARAMS = tuple(_CURRENT_CONFIG_FIELDS)
_CURRENT_INPUTS = ("id_ref_A", "iq_ref_A", "id_A", "iq_A", "w_e_radps", "u_dc_V")


@dataclasses.dataclass(frozen=True)
class CurrentOutput:
    """One sample of the current controllers (the C ``p2d_current_output_t``), float32 values.

    Attributes
    ----------
    ed_A, eq_A : current errors [A]
    ud_unsat_V, uq_unsat_V : voltage before the limit [V]
    ud_ref_V, uq_ref_V : voltage command, ||u_dq|| <= u_dc / sqrt(3) [V]
    saturated : the voltage-vector limit is active
    fault : the non-finite policy engaged (outputs are zero, state untouched)
    """

    ed_A: float
    eq_A: float
    ud_unsat_V: float
    uq_unsat_V: float
    ud_ref_V: float
    uq_ref_V: float
    saturated: bool
    fault: bool


class CurrentController:
    """The d- and q-axis PI current regulators (paper Fig. 1), in C.

    Gains from the desired loop time constant (eq 3): ``Kp = L / tau_i``,
    ``Ki = Rs / tau_i``, so that the decoupled, unsaturated loop is
    ``1 / (tau_i s + 1)``. With ``decouple`` the back-EMF and cross-coupling
    terms of the dq model (eq 1) are fed forward. The voltage vector is limited
    to the linear range of space-vector modulation, ``||u_dq|| <= u_dc / sqrt(3)``,
    with d-axis priority (``ud`` limited to the range, ``uq`` to what it leaves; see
    ``csrc/include/pmsm2dof/current.h``) and per-axis anti-windup (``Ka = 1/Kp`` for back
    calculation).

    Parameters
    ----------
    Rs_ohm : float
        Stator resistance [ohm], > 0.
    Ld_H, Lq_H : float
        dq inductances [H], > 0.
    psi_f_Wb : float
        Flux linkage [Wb], >= 0.
    tau_i_s : float
        Desired current-loop time constant [s], >= Ts_s (eq 3).
    Ts_s : float
        Sampling period [s], > 0.
    method : {"forward_euler", "backward_euler", "tustin"}
    anti_windup : {"none", "back_calculation", "clamping"}
    decouple : bool, default True

    Raises
    ------
    ConfigError
        A parameter has the wrong type or is out of range.

    Notes
    -----
    Computation is float32 (C ``float``); Python floats are rounded to float32.
    """

    def __init__(
        self,
        *,
        Rs_ohm: float,
        Ld_H: float,
        Lq_H: float,
        psi_f_Wb: float,
        tau_i_s: float,
        Ts_s: float,
        method: Method = "tustin",
        anti_windup: AntiWindup = "back_calculation",
        decouple: bool = True,
    ) -> None:
        self._ctl = ffi.new("p2d_current_t *")  # cffi ``p2d_current_t *``
        params: dict[str, Any] = dict(
            Rs_ohm=Rs_ohm, Ld_H=Ld_H, Lq_H=Lq_H, psi_f_Wb=psi_f_Wb, tau_i_s=tau_i_s, Ts_s=Ts_s,
            method=method, anti_windup=anti_windup, decouple=decouple,
        )  # fmt: skip
        status = lib.p2d_current_init(self._ctl, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    @staticmethod
    def _c_config(params: Mapping[str, Any]) -> Any:  # cffi ``p2d_current_config_t *``
        cfg = ffi.new("p2d_current_config_t *")
        set_fields(cfg, _CURRENT_CONFIG_FIELDS, params)
        return cfg

    def set_config(self, **changes: Any) -> None:
        """Change parameters atomically, keeping the integrator states.

        Invalid parameters raise :class:`ConfigError` and leave the old configuration active.
        """
        unknown = sorted(set(changes) - set(_CURRENT_PARAMS))
        if unknown:
            raise ConfigError(
                unknown[0], changes[unknown[0]], "a parameter of CurrentController: " + ", ".join(_CURRENT_PARAMS)
            )
        params = {**self._params, **changes}
        status = lib.p2d_current_set_config(self._ctl, self._c_config(params))
        if status != lib.P2D_OK:
            _raise_status(status, params)
        self._params = params

    def reset(self) -> None:
        """Clear both integrators."""
        lib.p2d_current_reset(self._ctl)

    def compute(
        self, id_ref_A: float, iq_ref_A: float, id_A: float, iq_A: float, w_e_radps: float, u_dc_V: float
    ) -> CurrentOutput:
        """The voltage command for this sample; the state is not changed.

        ``w_e_radps`` is the electrical speed, ``u_dc_V`` the measured DC-link voltage.
        """
        out = ffi.new("p2d_current_output_t *")
        lib.p2d_current_compute(
            self._ctl, float(id_ref_A), float(iq_ref_A), float(id_A), float(iq_A), float(w_e_radps), float(u_dc_V), out
        )
        return _current_output(out)

    def update(self, output: CurrentOutput, ud_applied_V: float, uq_applied_V: float) -> None:
        """Update the integrators with the voltage actually applied [V]."""
        out = ffi.new("p2d_current_output_t *", dataclasses.asdict(output))
        lib.p2d_current_update(self._ctl, out, float(ud_applied_V), float(uq_applied_V))

    def step(
        self, id_ref_A: float, iq_ref_A: float, id_A: float, iq_A: float, w_e_radps: float, u_dc_V: float
    ) -> CurrentOutput:
        """:meth:`compute` and :meth:`update` with the controller's own limited voltage."""
        out = ffi.new("p2d_current_output_t *")
        lib.p2d_current_step(
            self._ctl, float(id_ref_A), float(iq_ref_A), float(id_A), float(iq_A), float(w_e_radps), float(u_dc_V), out
        )
        return _current_output(out)

    def run(
        self,
        id_ref_A: npt.ArrayLike,
        iq_ref_A: npt.ArrayLike,
        id_A: npt.ArrayLike,
        iq_A: npt.ArrayLike,
        w_e_radps: npt.ArrayLike,
        u_dc_V: npt.ArrayLike,
    ) -> dict[str, npt.NDArray[Any]]:
        """Run :meth:`step` over whole arrays in one C call (``p2d_current_run``).

        All inputs are 1-D arrays of one length or scalars (broadcast). Returns a
        dict of numpy arrays: one per field of :class:`CurrentOutput` plus
        ``x_d_V`` and ``x_q_V``, the integrator states after each sample.
        """
        inputs = _as_inputs(_CURRENT_INPUTS, (id_ref_A, iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V))
        n = inputs[0].size
        out = np.zeros(n, dtype=_CURRENT_OUTPUT_DTYPE)
        x_d = np.zeros(n, dtype=np.float32)
        x_q = np.zeros(n, dtype=np.float32)
        lib.p2d_current_run(
            self._ctl, n, *(_float_ptr(a) for a in inputs),
            ffi.cast("p2d_current_output_t *", ffi.from_buffer(out)), _float_ptr(x_d), _float_ptr(x_q),
        )  # fmt: skip
        result = {name: np.ascontiguousarray(out[name]) for name in _CURRENT_OUTPUT_FIELDS}
        result["x_d_V"] = x_d
        result["x_q_V"] = x_q
        return result

    @property
    def coefficients(self) -> dict[str, Any]:
        """The active coefficients: ``d`` and ``q`` PI dicts, decoupling terms, ``clamping``."""
        c = self._ctl.coef[self._ctl.active]
        coef = _struct_dict(c, "p2d_current_coef_t")
        coef["d"] = _struct_dict(c.d, "p2d_pi_coef_t")
        coef["q"] = _struct_dict(c.q, "p2d_pi_coef_t")
        return coef

    @property
    def config(self) -> dict[str, Any]:
        """The active configuration (float32 values); ``CurrentController(**ctl.config)`` rebuilds it."""
        return _get_fields(self._ctl.config, _CURRENT_CONFIG_FIELDS)

    @property
    def state(self) -> dict[str, float]:
        """Integrator states ``x_d_V`` and ``x_q_V`` [V]."""
        return {"x_d_V": self._ctl.x_d_V, "x_q_V": self._ctl.x_q_V}

    @property
    def fault_count(self) -> int:
        """Samples rejected so far by the non-finite policy."""
        return int(self._ctl.fault_count)

    def __repr__(self) -> str:
        return "CurrentController(" + ", ".join(f"{k}={v!r}" for k, v in self.config.items()) + ")"


def _current_output(out: Any) -> CurrentOutput:
    return CurrentOutput(**{name: getattr(out, name) for name in _CURRENT_OUTPUT_FIELDS})
