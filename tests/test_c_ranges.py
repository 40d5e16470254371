"""One range per parameter: a scenario key that fields of the C configuration hold is checked against the
range of those fields' comments in the C headers, and the C init refuses what the scenario refuses.

The truth of a range is the header's text (read here from csrc/, not from the extension) and the C init
itself: for every such key, the scenario refuses a value just outside each bound of the comments and
accepts one just inside, and ``p2d_sim_init`` (or the binding of a C integer type) refuses the same
outside value written into the engine's configuration of a valid scenario that uses the field.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.core.cheaders import Bounds, comment_bounds, field_comments
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.engine_keys import CONFIG_PARTS, KEYS
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.scenario_schema import FIELDS
from pmsm2dof.sim.simulate import Simulation

HEADERS = field_comments(p.read_text() for p in sorted((Path(__file__).resolve().parents[1] / "csrc").glob("**/*.h")))
RPM_PER_RADPS = 30.0 / math.pi  # a key in rpm fills a field in rad/s
NUMERIC = ("float", "double", "uint32_t", "uint64_t")
INTEGER_TOP = {"uint32_t": 2**32, "uint64_t": 2**64}
COMPUTED = ("current_per_speed", "substeps")  # the periods' ratios, computed from their keys


def held_fields(key: str) -> list[tuple[str, str, str]]:
    """(path, C struct, C type) of each numeric field of the engine's configuration that holds ``key``."""
    held = []
    for path, k in KEYS.items():
        part, _, name = path.rpartition(".")
        ctype, fields = CONFIG_PARTS[part]
        if k == key and fields[name] in NUMERIC and name not in COMPUTED:
            held.append((path, ctype, fields[name]))
    return held


C_KEYS = sorted({k for k in KEYS.values() if k is not None and held_fields(k)})


def key_bounds(key: str) -> list[tuple[str, float]]:
    """Every bound of ``key`` (``("gt", 0.0)`` ...) that the header comments and C integer types give, in the
    key's unit."""
    bounds = []
    for path, ctype, kind in held_fields(key):
        b = comment_bounds(HEADERS[f"{ctype}.{path.rpartition('.')[2]}"])
        scale = RPM_PER_RADPS if "_rpm" in key else 1.0
        bounds += [(op, v * scale) for op, v in vars(b).items() if v is not None]
        if kind in INTEGER_TOP:
            bounds += [("ge", 0), ("lt", INTEGER_TOP[kind])]
    return bounds


def outside_inside(key: str, op: str, bound: float) -> tuple[list[float], float]:
    """Values just outside the bound (the bound itself too when strict and exact in float32: the C fields are
    float32) and one just inside it; integers for an integer key."""
    if FIELDS[key].kind is int:
        bound = int(bound)
        below, above = (bound - 1, bound + 1) if op in ("ge", "le") else (bound, bound)
        return ([below] if op in ("gt", "ge") else [above]), (bound + 1 if op in ("gt", "ge") else bound - 1)
    step = max(abs(bound), 1.0) * 1e-6  # above the float32 resolution
    exact = float(np.float32(bound)) == bound
    if op in ("gt", "ge"):
        return ([bound - step] + ([bound] if op == "gt" and exact else [])), bound + step
    return ([bound + step] + ([bound] if op == "lt" and exact else [])), bound - step


BASE = load_scenario("paper-condition-1")
#: Every part of the engine in use, each optional key given (so that a refusal names it, not its default's origin).
IN_USE = BASE.with_overrides(
    {
        "mechanics.model": "two_mass",
        "mechanics.J_load_kgm2": BASE.motor.J_kgm2,
        "mechanics.stiffness_Nm_per_rad": 1000.0,
        "speed_filter.notch_freq_Hz": 200.0,
        "speed_filter.notch_width_Hz": 50.0,
        "speed_filter.notch_depth": 0.1,
        "speed_filter.lowpass_freq_Hz": 300.0,
        "speed_filter.lowpass_zeta": 0.7,
        "speed_sensor.model": "encoder",
        "speed_sensor.estimator": "pll",
        "speed_sensor.bandwidth_radps": 500.0,
        "speed_sensor.lowpass_radps": 2000.0,
        "field_weakening.enabled": True,
        "field_weakening.Ki_A_per_Vs": 10.0,
        "field_weakening.Ka_V_per_A": 0.01,
        "field_weakening.id_min_A": -BASE.limits.i_max_A,
        "estimator.enabled": True,
        "estimator.J_min_kgm2": BASE.motor.J_kgm2 / 10,
        "estimator.J_max_kgm2": BASE.motor.J_kgm2 * 10,
        "estimator.B_max_Nms": 0.1,
        "estimator.T_load_max_Nm": 10.0,
        "estimator.sigma_T_Nm": 0.1,
        "estimator.load_memory_s": 0.1,
        "estimator.w_f_radps": 200.0,
    }
)
#: The fixed-point speed controller (a surface PMSM without the torque filters and field weakening).
FIXED = BASE.with_overrides(
    {
        "speed_controller.arithmetic": "q15",
        "speed_controller.speed_full_scale_rpm": 5000.0,
        "speed_controller.torque_full_scale_Nm": 50.0,
        "speed_controller.current_full_scale_A": 50.0,
    }
)


def c_init_refuses(key: str, value: float) -> bool:
    """Whether the C init (or the binding of a C integer type) refuses ``value`` of ``key`` written into every
    field that holds it, in the engine's configuration of a valid scenario that uses it."""
    scenario = FIXED if "full_scale" in key else IN_USE
    cfg = Simulation(scenario).cfg  # initialised: the scenario is valid
    for path, _, kind in held_fields(key):
        part, _, name = path.rpartition(".")
        target = cfg
        for step in filter(None, part.split(".")):
            target = getattr(target, step)
        c_value = value / RPM_PER_RADPS if "_rpm" in key else value
        try:
            setattr(target, name, int(c_value) if kind in INTEGER_TOP else c_value)
        except OverflowError:  # outside the C integer type
            return True
    return lib.p2d_sim_init(ffi.new("p2d_sim_t *"), cfg) != lib.P2D_SIM_OK


@pytest.mark.parametrize("key", C_KEYS)
def test_the_scenario_and_the_c_init_refuse_just_outside_the_c_comments_range(key):
    bounds = key_bounds(key)
    for op, bound in bounds:
        outside, inside = outside_inside(key, op, bound)
        for value in outside:
            with pytest.raises(ConfigError) as err:
                IN_USE.with_overrides({key: value})
            assert err.value.param == key
            assert c_init_refuses(key, value), (key, value)
        if all(
            {"gt": inside > b, "ge": inside >= b, "lt": inside < b, "le": inside <= b}[o] for o, b in bounds
        ):  # inside every bound of the key, not only this one (the relations between keys are not ranges)
            assert FIELDS[key].check(key, inside) == inside
    # the schema holds no other bound than the comments' and the types'
    f = FIELDS[key]
    declared = {op: v for op, v in (("gt", f.gt), ("ge", f.ge), ("lt", f.lt), ("le", f.le)) if v is not None}
    for op, v in declared.items():
        assert (op, v) in bounds, (key, op, v)


def test_every_c_key_is_checked_and_most_have_a_bound():
    assert len(C_KEYS) >= 60
    assert sum(1 for k in C_KEYS if key_bounds(k)) >= 55
    assert "speed_controller.alpha_radps" in C_KEYS and "speed_sensor.noise_rpm_rms" in C_KEYS


def test_the_range_words_of_a_c_key_are_unchanged():
    with pytest.raises(ConfigError, match=r"speed_controller.alpha_radps = 0.0 is invalid: valid range is a finite"):
        BASE.with_overrides({"speed_controller.alpha_radps": 0.0})
    assert FIELDS["speed_controller.alpha_radps"].valid_range() == "a finite number > 0"
    assert FIELDS["speed_filter.notch_depth"].valid_range() == "a finite number >= 0 and < 0.707107"
    assert FIELDS["speed_sensor.seed"].valid_range() == "an integer >= 0 and < 18446744073709551616"
    assert FIELDS["motor.pole_pairs"].valid_range() == "an integer >= 1 and < 4294967296"


@pytest.mark.parametrize(
    ("comment", "bounds"),
    [
        ("DC-link voltage [V], > 0", Bounds(gt=0.0)),
        ("viscous friction [Nm s/rad], >= 0", Bounds(ge=0.0)),
        ("width of the hardware counter [bit], 2..32: it wraps at 2^counter_bits", Bounds(ge=2.0, le=32.0)),
        ("||u_dq|| held at voltage_ratio u_dc / sqrt(3) [-], in (0, 1]", Bounds(gt=0.0, le=1.0)),
        ("J_valid once sd(J) <= J_rel_sd_max J [-], in (0, 1)", Bounds(gt=0.0, lt=1.0)),
        ("smallest plausible J [kg m^2], in (0, J0_kgm2]", Bounds(gt=0.0)),
        ("angle [rad], in [0, 2 pi)", Bounds(ge=0.0)),
        ("window [s], in [2, 4] Ts_s", Bounds()),
        ("DC_LINK_SAG: factor of u_dc [-] in [0, 1]; SENSOR_SPIKE: the reading [rad/s]", Bounds()),
        ("back-calculation gain [V/A], >= 0, Ki Ka Ts < 2 (1/Kp is usual)", Bounds(ge=0.0)),
        ("PLL pole [rad/s], > 0, 1e-3 <= bandwidth_radps Ts_s <= 2; pll only", Bounds(gt=0.0)),
        ("delay [s], >= 0, <= (P2D_SIM_HISTORY - 2) Ts_current", Bounds(ge=0.0)),
        ("gain [-], >= 0 and < 0.7071067811865476 = 1/sqrt(2) (0.1: -20 dB)", Bounds(ge=0.0, lt=0.7071067811865476)),
        ("notch frequency f0 [Hz], >= 0: 0 for no notch, else < 1/(2 Ts_s)", Bounds(ge=0.0)),
        ("test time [s], >= 10 Ts_s", Bounds()),
        ("|m| <= 2^15 - 1 [-]", Bounds()),
        ("relative gain error [-], > -1", Bounds(gt=-1.0)),
        ("offset [A], finite", Bounds()),
    ],
)
def test_comment_bounds_reads_the_fields_own_plain_bounds(comment, bounds):
    assert comment_bounds(comment) == bounds


def test_a_c_key_that_declares_its_own_range_is_refused():
    from pmsm2dof.sim.scenario_keys import Spec, from_c
    from pmsm2dof.sim.scenario_schema import _c_range

    with pytest.raises(TypeError, match="speed_controller.alpha_radps declares a range"):
        _c_range("speed_controller.alpha_radps", float, Spec(from_c(), gt=0))
    assert _c_range("simulation.dt_s", float, Spec("step", gt=0)) == Bounds(gt=0)  # held by no C field
