"""The engine's C configuration (``p2d_sim_config_t``, csrc/sim/drive.h) of a scenario.

:func:`engine_config` walks the configuration's fields from its C declaration and fills each through
the generic field setter of :mod:`pmsm2dof.core` (:func:`~pmsm2dof.core.fields.set_fields`) with the
value of its scenario key (:data:`pmsm2dof.sim.engine_keys.KEYS`) unless the value is derived
(:func:`derived_values`), so that a new C field needs no hand-written line; the fixed-point speed
controller's full scales, given or derived from the filled rest (:data:`FULL_SCALES`), are filled last.
The same map gives the scenario key an error of a C init names (:data:`SPEED_KEYS` ...), and
:func:`raise_config_error` the error itself.
"""

import math
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

import numpy as np
import numpy.typing as npt

from ..core import FAULT_KINDS, pi_gains
from ..core.bindings import c_string, ffi, lib
from ..core.fields import float32_note, set_fields
from ..core.gains import default_Ka_error
from ..core.motor import no_load_speed_radps
from ..errors import ConfigError
from .engine_keys import CONFIG_PARTS, KEYS, RPM_PER_RADPS
from .scenario import SCHEMA, SameAs, Scenario
from .scenario_tables import FaultEntry


def engine_config(scenario: Scenario, current_per_speed: int, substeps: int) -> tuple[Any, list[Any]]:
    """The C configuration of ``scenario`` (a cffi ``p2d_sim_config_t *``), and the arrays its
    schedules and faults point into (keep them while the engine runs).

    ``current_per_speed`` and ``substeps`` are the integer period ratios the caller checked.
    """
    cfg = ffi.new("p2d_sim_config_t *")
    arrays = [
        _schedule(cfg.reference, [(e.t_s, e.speed_rpm * (1.0 / RPM_PER_RADPS), e.ramp_s) for e in scenario.reference]),
        _schedule(cfg.load, [(e.t_s, e.torque_Nm, e.ramp_s) for e in scenario.load]),
        _faults(cfg, scenario.fault),
    ]
    _fill(cfg, scenario, derived_values(scenario, current_per_speed, substeps))
    _arithmetic(cfg, scenario)  # after the fill: the derived full scales read the speed controller's fields
    return cfg, arrays


#: The full scales of the fixed-point speed controller in the engine's configuration (``p2d_sim_config_t``):
#: given or derived by :func:`_arithmetic`, not by the generic fill (their keys may be absent, None).
FULL_SCALES = ("speed_full_scale_radps", "torque_full_scale_Nm", "current_full_scale_A")
#: Default speed full scale of the fixed-point controllers in no-load speeds: the engine's overspeed bound
#: (``P2D_SIM_OVERSPEED_FACTOR``), so that every speed a run reaches is within the input's range.
FULL_SCALE_NO_LOAD_SPEEDS = 2.0
#: Margin of the default torque full scale over the smallest that holds the states [-].
FULL_SCALE_MARGIN = 1.25


def _names(part: str) -> dict[str, str]:
    """``{field: scenario key}`` of the fields of ``part`` that a C init can reject."""
    return {name: key for name in CONFIG_PARTS[part][1] if (key := KEYS[f"{part}.{name}"]) is not None}


#: Scenario key of each field that the C speed controller init can reject (p2d_status_param): the
#: fixed-point one's full scales too.
SPEED_KEYS = (
    _names("speed") | _names("speed_filter") | {name: key for name in FULL_SCALES if (key := KEYS[name]) is not None}
)
#: Scenario key of each field that the C current controller init can reject.
CURRENT_KEYS = _names("current")
#: Scenario key of each field that the C encoder (speed_sensor) or field weakening init can reject.
SENSING_KEYS = _names("sensing.speed_sensor.encoder") | _names("sensing.field_weakening.config")
#: Scenario key of each field that p2d_sim_init can reject (p2d_sim_status_param): a field, or a table.
SIM_KEYS = {path: key for path, key in KEYS.items() if key is not None} | {
    "reference": "reference",
    "load": "load",
    "faults": "fault",
    "speed_sensor": "speed_sensor",
    "current_sensor": "current_measurement",
    "field_weakening": "field_weakening",
}
#: Scenario key of each field that the C inertia estimator init can reject (the estimator block).
ESTIMATOR_KEYS = _names("adapt.config")


def _schedule(target: Any, entries: Sequence[tuple[float, float, float]]) -> list[npt.NDArray[np.float64]]:
    """Fill the C schedule ``target`` from the scenario's entries ``(t_s, value in SI units, ramp_s)``; return
    the arrays it points into."""
    arrays = [np.array(column, dtype=np.float64) for column in zip(*entries)] if entries else [np.zeros(0)] * 3
    target.n = len(entries)
    if entries:
        target.t_s, target.value, target.ramp_s = (ffi.cast("double *", ffi.from_buffer(a)) for a in arrays)
    return arrays


def _faults(cfg: Any, entries: Sequence[FaultEntry]) -> Any:
    """Fill ``cfg.faults`` from the scenario's ``fault`` entries; return the C array it points to."""
    faults = ffi.new("p2d_fault_t[]", max(1, len(entries)))
    for f, e in zip(faults, entries):
        f.kind = FAULT_KINDS.index(e.kind)
        f.t_s = e.t_s
        f.duration_s = 0.0 if e.duration_s is None else e.duration_s
        if e.kind == "dc_link_sag":
            f.value = e.u_dc_factor
        elif e.kind == "sensor_spike":
            assert e.speed_rpm is not None  # required by sensor_spike (the scenario's validation)
            f.value = e.speed_rpm / RPM_PER_RADPS
    cfg.faults = faults
    cfg.n_faults = len(entries)
    return faults


def _fill(cfg: Any, scenario: Scenario, derived: Mapping[str, Any]) -> None:
    """Fill every field of the C configuration ``cfg`` (:data:`CONFIG_PARTS`) but the scenario's entries
    and the full scales (:func:`_arithmetic`): from its scenario key (:data:`KEYS`) or ``derived``, through
    the generic field setter."""
    for part, (_, fields) in CONFIG_PARTS.items():
        paths = {name: f"{part}.{name}" if part else name for name in fields}
        filled = {
            name: ctype
            for name, ctype in fields.items()
            if paths[name] not in FULL_SCALES and not _left_zero(scenario, paths[name])
        }
        values = {name: _scenario_value(scenario, paths[name], derived) for name in filled}
        target = cfg
        for name in filter(None, part.split(".")):
            target = getattr(target, name)
        set_fields(target, filled, values, {name: KEYS[paths[name]] or paths[name] for name in filled})


def _left_zero(scenario: Scenario, path: str) -> bool:
    """Whether the configuration field ``path`` stays 0 (unused): the estimator when it is off, the field
    weakening's regulator when it is off, the two-mass train's parameters of a rigid one."""
    if path.startswith("adapt.") and path != "adapt.enabled":
        return not scenario.estimator.enabled
    if path.startswith("sensing.field_weakening.config."):
        return not scenario.field_weakening.enabled
    if path.startswith("mechanics.") and path not in ("mechanics.model", "mechanics.feedback"):
        return scenario.mechanics.model != "two_mass"
    return False


def _scenario_value(scenario: Scenario, path: str, derived: Mapping[str, Any]) -> Any:
    """The value of the configuration field ``path``: derived (:func:`derived_values`), else the scenario's, in
    rad/s for a key in rpm."""
    if path in derived:
        return derived[path]
    key = KEYS[path]
    assert key is not None, path
    value = _value(scenario, key)
    return value / RPM_PER_RADPS if "_rpm" in key else value


def derived_values(scenario: Scenario, current_per_speed: int, substeps: int) -> dict[str, Any]:
    """The configuration fields the scenario does not give, by path: the periods' ratios, the defaults of
    absent keys (``speed_controller.Ka``, the estimator's limits, the field weakening's), fixed choices."""
    sc, motor, est, fw = scenario.speed_controller, scenario.motor, scenario.estimator, scenario.field_weakening
    derived: dict[str, Any] = {
        "current_per_speed": current_per_speed,
        "substeps": substeps,
        "adapt.Ka_follows_J": sc.Ka is None,
        "sensing.field_weakening.config.method": "tustin",
        "sensing.field_weakening.config.anti_windup": "back_calculation",
    }
    if sc.Ka is None:
        # section 3.3: Ka = 1/Kp = 1/(J alpha), computed in float32 by the C library
        derived["speed.Ka"] = lib.p2d_speed_Ka_default(sc.J_kgm2, sc.alpha_radps)
    if scenario.speed_sensor.bandwidth_radps is None:
        derived["sensing.speed_sensor.encoder.bandwidth_radps"] = 0.0
    if est.enabled:
        T_peak_Nm = 1.5 * motor.pole_pairs * motor.psi_f_Wb * scenario.limits.i_max_A
        J0 = est.J0_kgm2
        defaults = {
            "J_min_kgm2": (est.J_min_kgm2, J0 / 10.0),
            "J_max_kgm2": (est.J_max_kgm2, 10.0 * J0),
            "B_max_Nms": (est.B_max_Nms, T_peak_Nm / 100.0),
            "T_load_max_Nm": (est.T_load_max_Nm, T_peak_Nm),
            "sigma_T_Nm": (est.sigma_T_Nm, 0.01 * T_peak_Nm),
            "load_memory_s": (est.load_memory_s, 1.0 / sc.alpha_radps),
            "w_f_radps": (est.w_f_radps, 0.2 / sc.Ts_s),
        }
        derived |= {f"adapt.config.{k}": v for k, (given, v) in defaults.items() if given is None}
    if fw.enabled:
        if fw.Ka_V_per_A is None:
            # absent: Ki Ka Ts = 1, the back-calculation's own time constant one sample
            assert fw.Ki_A_per_Vs is not None  # required when enabled (the scenario's validation)
            derived["sensing.field_weakening.config.Ka_V_per_A"] = 1.0 / (fw.Ki_A_per_Vs * sc.Ts_s)
        if fw.id_min_A is None:
            derived["sensing.field_weakening.config.id_min_A"] = -scenario.limits.i_max_A
    return derived


#: Keys whose absent value the engine takes from another key: key -> (that key, how). An error of the
#: engine names the key the user set: the SameAs defaults of the schema and the derived defaults of
#: [estimator] and [field_weakening] (``speed_controller.Ka``, 1/Kp, is named by what makes it fail:
#: :func:`pmsm2dof.core.gains.default_Ka_error`).
_SAME_AS = {f.key: f.default.key for f in SCHEMA if isinstance(f.default, SameAs)}
_SOURCES = {key: (source, source) for key, source in _SAME_AS.items()} | {
    "estimator.J_min_kgm2": ("estimator.J0_kgm2", "J0_kgm2 / 10"),
    "estimator.J_max_kgm2": ("estimator.J0_kgm2", "10 J0_kgm2"),
    "estimator.B_max_Nms": ("limits.i_max_A", "the peak torque 1.5 p psi_f i_max_A per 100 rad/s"),
    "estimator.T_load_max_Nm": ("limits.i_max_A", "the peak torque 1.5 p psi_f i_max_A"),
    "estimator.sigma_T_Nm": ("limits.i_max_A", "1 % of the peak torque 1.5 p psi_f i_max_A"),
    "estimator.load_memory_s": ("speed_controller.alpha_radps", "1 / alpha_radps"),
    "estimator.w_f_radps": ("speed_controller.Ts_s", "0.2 / Ts_s"),
    "field_weakening.Ka_V_per_A": ("field_weakening.Ki_A_per_Vs", "1 / (Ki_A_per_Vs speed_controller.Ts_s)"),
    "field_weakening.id_min_A": ("limits.i_max_A", "-i_max_A"),
    "speed_controller.speed_full_scale_rpm": ("limits.u_dc_V", "twice the no-load speed u_dc_V / (sqrt(3) p psi_f)"),
    "speed_controller.torque_full_scale_Nm": (
        "limits.i_max_A",
        "1.25 times the smallest that holds the torque limit 1.5 p psi_f i_max_A, the feedforward's state and "
        "transient at the references and the command at the largest reference step",
    ),
    "speed_controller.current_full_scale_A": (
        "speed_controller.torque_full_scale_Nm",
        "torque_full_scale_Nm / (1.5 p psi_f)",
    ),
}


def _value(scenario: Scenario, key: str) -> Any:
    """The value of the scenario key ``key`` (``"<table>.<key>"``), or of a whole table or array (``"reference"``)
    as plain data, as an error shows it."""
    if "." not in key:
        return scenario.data[key]
    table, name = key.split(".")
    return getattr(getattr(scenario, table), name)


def raise_config_error(status: int, sim: Any, cfg: Any, scenario: Scenario) -> NoReturn:
    """Raise the ConfigError of the ``p2d_sim_init`` status ``status`` of the engine ``sim`` built from
    ``cfg`` and ``scenario``, naming the scenario key the user set."""
    if status in (lib.P2D_SIM_ERR_SPEED_SENSOR, lib.P2D_SIM_ERR_FIELD_WEAKENING) and sim.controller_status:
        ctl = sim.controller_status
        field = c_string(lib.p2d_status_param(ctl))
        key = SENSING_KEYS[field]
        derived = getattr(cfg.sensing.field_weakening.config, field, None)
        raise _blame(scenario, key, c_string(lib.p2d_status_range(ctl)), derived)
    if status in (lib.P2D_SIM_ERR_SPEED_CONTROLLER, lib.P2D_SIM_ERR_CURRENT_CONTROLLER, lib.P2D_SIM_ERR_ESTIMATOR):
        ctl = sim.controller_status
        field = c_string(lib.p2d_status_param(ctl))
        valid = c_string(lib.p2d_status_range(ctl))
        keys = {
            lib.P2D_SIM_ERR_SPEED_CONTROLLER: SPEED_KEYS,
            lib.P2D_SIM_ERR_CURRENT_CONTROLLER: CURRENT_KEYS,
            lib.P2D_SIM_ERR_ESTIMATOR: ESTIMATOR_KEYS,
        }[status]
        key = keys[field]
        derived = getattr(cfg.adapt.config, field, None) if status == lib.P2D_SIM_ERR_ESTIMATOR else None
        scales = full_scales(cfg) if status == lib.P2D_SIM_ERR_SPEED_CONTROLLER else {}
        if field in scales:
            # a full scale of the fixed-point controller, in the key's unit (rpm for the speed)
            derived = scales[field] * (RPM_PER_RADPS if field == "speed_full_scale_radps" else 1.0)
            if field == "speed_full_scale_radps":
                valid += f" (speed_full_scale_radps = speed_full_scale_rpm pi/30 = {scales[field]:.6g})"
        value = _value(scenario, key)
        note = float32_note(derived if value is None else value)
        s = cfg.speed
        if status == lib.P2D_SIM_ERR_SPEED_CONTROLLER and field == "J_kgm2" and not note:
            # a gain of eq 9 overflowed float32: name the factor farthest from 1
            factors = {"J_kgm2": s.J_kgm2, "alpha_radps": s.alpha_radps, "zeta": 1.0 / s.zeta}
            field = max(factors, key=lambda k: abs(math.log(factors[k])))
            key = SPEED_KEYS[field]
            Kp, Ki = pi_gains(s.J_kgm2, s.alpha_radps, s.zeta)
            valid = (
                f"a value that keeps the gains of eq 9 finite in float32 (Kp = J alpha = {Kp:.4g}, "
                f"Ki = J (alpha / (2 zeta))^2 = {Ki:.4g} with J_kgm2 = {s.J_kgm2:g}, alpha_radps = "
                f"{s.alpha_radps:g}, zeta = {s.zeta:g})"
            )
        elif status == lib.P2D_SIM_ERR_SPEED_CONTROLLER and field == "Ts_s" and not note:
            # the speed controller's refusal of a sound period: its float32 coefficients overflowed
            valid += (
                f" (it is: the controller's float32 coefficients overflow with J_kgm2 = {s.J_kgm2:g}, "
                f"alpha_radps = {s.alpha_radps:g} and i_max_A = {s.i_max_A:g})"
            )
        else:
            valid += note
        if key != "speed_controller.Ka":
            raise _blame(scenario, key, valid, derived)
        sc = scenario.speed_controller
        if sc.Ka is not None:
            _, Ki = pi_gains(s.J_kgm2, s.alpha_radps, s.zeta)
            valid = (
                f"finite, >= 0 and, with back_calculation, Ki Ka Ts_s < 2, i.e. Ka < "
                f"{2.0 / (Ki * s.Ts_s):.6g} (Ki = {Ki:.6g} by eq 9)"
            )
            raise ConfigError(key, sc.Ka, valid)
        if s.alpha_radps * s.Ts_s / (4.0 * s.zeta**2) >= 2.0 * (1.0 - 1e-6):
            # the default 1/Kp made Ki Ka Ts >= 2: name what the user set
            names = {name: f"speed_controller.{name}" for name in ("alpha_radps", "zeta", "Ts_s", "Ka")}
            raise default_Ka_error(sc.J_kgm2, sc.alpha_radps, sc.zeta, sc.Ts_s, names)
        # the filters the user set made the loop unstable: name the first of their frequencies given
        filters = scenario.speed_filter
        raise ConfigError(
            "speed_filter.lowpass_freq_Hz" if filters.lowpass_freq_Hz > 0.0 else "speed_filter.notch_freq_Hz",
            filters.lowpass_freq_Hz if filters.lowpass_freq_Hz > 0.0 else filters.notch_freq_Hz,
            f"a filter through which the back-calculation loop with the default Ka = 1/Kp = {s.Ka:.6g} "
            "(speed_controller.Ka absent) is stable; or give speed_controller.Ka smaller",
        )
    field = c_string(lib.p2d_sim_status_param(status))
    valid = c_string(lib.p2d_sim_status_text(status))
    raise _blame(scenario, SIM_KEYS[field], valid)


def _blame(scenario: Scenario, key: str, valid: str, derived: float | None = None) -> ConfigError:
    """The ConfigError of ``key``, or, when ``key`` was absent and took its value from another key
    (:data:`_SOURCES`: the defaults the engine derives), of that key: the input the user set.

    ``derived`` is the value the engine derived for a key absent from the scenario (None in it).
    """
    value = _value(scenario, key)
    source = _SOURCES.get(key)
    if source is not None:
        origin, how = source
        is_default = value is None if key not in _SAME_AS else value == _value(scenario, origin)
        if is_default:
            shown = value if value is not None else derived
            return ConfigError(
                origin,
                _value(scenario, origin),
                f"a value that makes {key} (when not given, {how} = {shown:.6g}) valid: {valid}",
            )
    return ConfigError(key, value, valid)


def full_scales(cfg: Any) -> dict[str, float]:
    """The full scales of the fixed-point speed controller of the C configuration ``cfg`` by C field name
    ({} for float32)."""
    if cfg.arithmetic == lib.P2D_ARITHMETIC_FLOAT32:
        return {}
    return {name: float(getattr(cfg, name)) for name in FULL_SCALES}


def _float32_up(x: float) -> float:
    """The float32 number nearest ``x`` at or above it: a full scale that still holds ``x`` once stored."""
    x32 = np.float32(x)
    return float(x32) if float(x32) >= x else float(np.nextafter(x32, np.float32(np.inf)))


def _arithmetic(cfg: Any, scenario: Scenario) -> None:
    """Fill the full scales of the fixed-point speed controller (Q15 or Q31) of ``cfg``, given or derived (see
    :data:`~pmsm2dof.sim.scenario.SCHEMA`), once the rest of ``cfg`` is filled.

    The derived torque full scale keeps within the two full scales the format holds (speed_fixed.h)
    the integrator state ``x = x_i + Fr(0) r`` up to ``T_max + |Fr(0)| r_max``, the feedforward
    transient ``y`` up to ``|b_dr| dr_max`` after the largest reference step ``dr_max``, and the command
    ``u`` at that step, ``T_max + (b_e0 + |Fr(0) + b_dr|) dr_max`` (so that the back calculation sees
    the ``u* = u_sat - u`` the float32 controller sees); the gains are the C controller's
    (``p2d_speed_q15_gains``).
    """
    sc, motor = scenario.speed_controller, scenario.motor
    if sc.arithmetic == "float32":
        return
    s = cfg.speed
    kt = 1.5 * s.pole_pairs * s.psi_f_Wb
    T_max = kt * s.i_max_A
    W_fs = (
        FULL_SCALE_NO_LOAD_SPEEDS * no_load_speed_radps(scenario.limits.u_dc_V, motor.pole_pairs, motor.psi_f_Wb)
        if sc.speed_full_scale_rpm is None
        else sc.speed_full_scale_rpm / RPM_PER_RADPS
    )
    cfg.speed_full_scale_radps = W_fs
    T_fs = sc.torque_full_scale_Nm
    if T_fs is None:
        T_fs = T_max
        # the feedforward's gains in physical units, from the C controller at provisional full scales
        cfg.torque_full_scale_Nm = _float32_up(T_max)
        cfg.current_full_scale_A = _float32_up(s.i_max_A)
        fixed = ffi.new(
            "p2d_speed_fixed_config_t *",
            [cfg.speed, cfg.speed_full_scale_radps, cfg.torque_full_scale_Nm, cfg.current_full_scale_A],
        )
        gains = ffi.new("p2d_speed_fixed_gains_t *")
        if getattr(lib, f"p2d_speed_{sc.arithmetic}_gains")(fixed, gains) == lib.P2D_OK:
            per_unit = cfg.torque_full_scale_Nm / cfg.speed_full_scale_radps
            Fr0, b_dr = abs(gains.ff_Fr0) * per_unit, abs(gains.ff_b_dr) * per_unit
            # u at a reference step dr from rest: b_e0 dr + x + (Fr0 + b_dr) dr (the derivative kick of the
            # full feedforward left out: it saturates the command anyway)
            u_per_dr = (gains.b_e0 + abs(gains.ff_Fr0 + gains.ff_b_dr)) * per_unit
            # the references in the order the controller sees them: w_m0, 0 until the first entry, the entries
            w_m0 = scenario.simulation.speed0_rpm / RPM_PER_RADPS
            refs = [w_m0] + ([0.0] if scenario.reference[0].t_s > 0.0 else [])
            refs += [e.speed_rpm / RPM_PER_RADPS for e in scenario.reference]
            r_max = max(abs(r) for r in refs)
            dr_max = max(abs(b - a) for a, b in zip(refs, refs[1:]))
            held = max(T_max + Fr0 * r_max, b_dr * dr_max, T_max + u_per_dr * dr_max) / 2.0
            T_fs = max(T_max, FULL_SCALE_MARGIN * held)
        cfg.torque_full_scale_Nm = _float32_up(T_fs)
    else:
        cfg.torque_full_scale_Nm = T_fs
    I_fs = sc.current_full_scale_A
    cfg.current_full_scale_A = _float32_up(max(s.i_max_A, T_fs / kt)) if I_fs is None else I_fs
