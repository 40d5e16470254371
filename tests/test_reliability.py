"""No bad input gets through, nothing crashes, nothing returns silent garbage (scenario side).

Properties over scenario inputs, drawn by hypothesis around a short (50 ms) run of the paper's
drive so that each example simulates in about a millisecond:

- any overrides, however wild (NaN, inf, huge, negative, zero, wrong types, unknown choices,
  broken schedule and fault entries), either simulate with finite results within the limits, or
  raise a ConfigError whose message names a scenario key with the value that key really holds,
  or stop with a SimulationError giving the time and the reason (runaway, non-finite state);
- plausible drives, schedules and faults always simulate, with finite results, the current
  command within i_max, the voltage within the inverter's range and the reading as the fault says;
- any byte-level corruption of a scenario file loads or raises ConfigError, nothing else.

The time keys (periods, step, t_end) are drawn from values that are either rejected or keep a run
short; every other key takes any value.
"""

import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pmsm2dof.core import FAULT_KINDS
from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim.scenario import ARRAYS, SCHEMA, _Placeholder, load_scenario
from pmsm2dof.sim.simulate import simulate

BASE = load_scenario("paper-condition-1").with_overrides(
    {
        "simulation.t_end_s": 0.05,
        "reference": [{"t_s": 0.0, "speed_rpm": 500.0}, {"t_s": 0.02, "speed_rpm": 200.0}],
        "load": [{"t_s": 0.03, "torque_Nm": 4.0}],
    }
)
FIELDS = {f.key: f for f in SCHEMA}
SCALARS = [f for f in SCHEMA if "[]" not in f.key]

#: Values that are wrong for a number key in some way.
WILD = [
    0,
    0.0,
    -0.0,
    -1.0,
    -1,
    1e-300,
    5e-324,
    1e-12,
    1e12,
    1e300,
    1.7976931348623157e308,
    10**30,
    -(10**30),
    math.nan,
    math.inf,
    -math.inf,
    3.5e38,
    2,
    1.0,
]
#: Values of the wrong type for most keys.
WRONG_TYPES = ["nan", "inf", "1.0", "", "fast", True, False, [], [1.0], {}, {"x": 1}]
#: Time keys: rejected values, or plausible ones that keep a run short.
TIME_VALUES = {
    "current_loop.Ts_s": [5e-5, 1e-4, 2e-4, 1e-3],
    "speed_controller.Ts_s": [1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 1.05e-3],
    "simulation.t_end_s": [1e-300, 1e-3, 0.01, 0.05, 1e300, 36000.5],
    "simulation.dt_s": [1e-5, 5e-5, 1e-4, 1e-3],
}
TIME_WILD = [0, 0.0, -1e-3, math.nan, math.inf, -math.inf, 1e300, 1e-300, "1e-3", True]


def base_value(key):
    node = BASE.data
    for part in key.split("."):
        node = node[part]
    return node


def value_for(field):
    """Any value for a scalar key: plausible for its kind, wild, or of another type."""
    if field.key in TIME_VALUES:
        return st.sampled_from(TIME_VALUES[field.key] + TIME_WILD)
    if field.kind is float:
        start = base_value(field.key)
        scale = abs(start) if isinstance(start, float) and start else 1.0
        plausible = st.floats(-3, 3).map(lambda x: scale * 10.0**x)
    elif field.kind is int:
        plausible = st.integers(-5, 2000)
    elif field.kind is bool:
        plausible = st.booleans()
    elif field.choices:
        plausible = st.sampled_from(list(field.choices) + ["bogus", field.choices[0].upper()])
    else:
        plausible = st.text(max_size=8)
    # mostly plausible, so that many examples reach the engine
    return st.one_of(plausible, plausible, plausible, st.sampled_from(WILD), st.sampled_from(WRONG_TYPES))


def entry(name):
    """One entry of the array ``name``: the keys it needs (a fault's by its kind) with plausible or wild
    values, sometimes one key less or one more."""
    values = {
        "t_s": st.floats(0.0, 0.06) | st.sampled_from([-1.0, math.nan, math.inf, 1e300, "0"]),
        "ramp_s": st.floats(0.0, 0.02) | st.sampled_from([-0.01, math.nan]),
        "duration_s": st.floats(1e-4, 0.03) | st.sampled_from([0.0, -0.01, math.inf]),
        "speed_rpm": st.floats(-3000.0, 3000.0) | st.sampled_from(WILD + ["500"]),
        "torque_Nm": st.floats(-20.0, 20.0) | st.sampled_from(WILD),
        "u_dc_factor": st.floats(0.0, 1.0) | st.sampled_from([1.5, -0.1, math.nan]),
        "stray": st.just(1.0),
    }
    needs = {
        "reference": ["t_s", "speed_rpm", "ramp_s"],
        "load": ["t_s", "torque_Nm", "ramp_s"],
        "dc_link_sag": ["t_s", "duration_s", "u_dc_factor"],
        "sensor_hold": ["t_s", "duration_s"],
        "sensor_zero": ["t_s", "duration_s"],
        "sensor_spike": ["t_s", "speed_rpm"],
        "encoder_loss": ["t_s"],
    }

    @st.composite
    def one(draw):
        kind = draw(st.sampled_from(list(FAULT_KINDS) + ["encoder_loss"])) if name == "fault" else None
        keys = list(needs[kind or name])
        change = draw(st.sampled_from(["none", "none", "none", "drop", "add"]))
        if change == "drop":
            keys.remove(draw(st.sampled_from(keys)))
        elif change == "add":
            extra = draw(st.sampled_from(["stray", "duration_s", "speed_rpm", "u_dc_factor"]))
            keys += [] if extra in keys else [extra]
        e = {k: draw(values[k]) for k in keys}
        return e if kind is None else {"kind": kind, **e}

    return one()


@st.composite
def wild_overrides(draw):
    """Up to two scalar keys and, now and then, a schedule or the fault list."""
    keys = draw(st.lists(st.sampled_from(SCALARS), unique_by=lambda f: f.key, max_size=2))
    overrides = {f.key: draw(value_for(f)) for f in keys}
    for name in draw(st.sampled_from([[], [], ["reference"], ["load"], ["fault"], ["fault", "load"]])):
        overrides[name] = draw(st.lists(entry(name), max_size=3) | st.sampled_from([[], {}, 1.0, "x"]))
    return overrides


def normalized(key):
    """The schema key of a dotted key: ``reference.1.t_s`` -> ``reference[].t_s``."""
    return re.sub(r"\.\d+(?=\.|$)", "[]", key)


def value_at(data, key):
    node = data
    for part in key.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def same(shown, held):
    """The value a message shows is the one held (a number key shows an integer as its float)."""
    if isinstance(shown, float) and isinstance(held, int) and not isinstance(held, bool):
        held = float(held)
    return (
        shown is held
        or shown == held
        or (isinstance(shown, float) and isinstance(held, float) and math.isnan(shown) and math.isnan(held))
    )


def check_message(exc):
    """One line: '<key> = <value> is invalid: valid range is <range>', the key one of the schema."""
    text = str(exc)
    assert "\n" not in text and text == f"{exc.param} = {exc.value!r} is invalid: valid range is {exc.valid}"
    assert exc.valid
    known = set(FIELDS) | set(ARRAYS) | {f"{name}[]" for name in ARRAYS} | {"scenario"}
    # an unknown key is named as written, with the valid keys
    assert normalized(exc.param) in known or "not a key of" in exc.valid, exc.param


def check_result(result):
    d = result.scenario.data
    for name in result.signals:
        assert np.all(np.isfinite(getattr(result, name))), name
    assert np.all(np.hypot(result.id_ref_A, result.iq_ref_A) <= d["limits"]["i_max_A"] * (1 + 1e-6))
    if d["current_loop"]["model"] == "dq_pi":
        assert np.all(np.hypot(result.ud_V, result.uq_V) <= result.u_dc_V / math.sqrt(3) * (1 + 1e-9))
    assert result.t_s[0] == 0.0 and np.all(np.diff(result.t_s) > 0)


def simulate_or_explain(scenario):
    """Simulate a scenario the schema accepted: a result passes :func:`check_result`, a refusal of
    the engine names the key with the value the scenario holds there, a stop says when and why."""
    try:
        result = simulate(scenario)
    except ConfigError as exc:
        check_message(exc)
        # the engine names the key and shows the value the scenario holds there
        held = value_at(scenario.data, exc.param)
        if exc.param == "speed_controller.Ka" and held is None:
            assert str(exc.value).startswith("None (default 1/Kp = ")
        else:
            assert same(exc.value, held), (exc.param, exc.value, held)
        event(f"rejected by the engine: {exc.param}")
        return
    except SimulationError as exc:
        assert re.fullmatch(r"simulation of .* stopped at t = \S+ s: .+", str(exc), flags=re.S), str(exc)
        assert "\n" not in str(exc)
        event(f"stopped: {str(exc).split(': ', 1)[1][:40]}")
        return
    check_result(result)
    event("simulated")


@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(overrides=wild_overrides())
def test_any_scenario_simulates_or_fails_naming_the_key(overrides):
    try:
        scenario = BASE.with_overrides(overrides)
    except ConfigError as exc:
        check_message(exc)
        if exc.param in overrides and not isinstance(exc.value, _Placeholder):
            assert same(exc.value, overrides[exc.param]), (exc.value, overrides[exc.param])
        event(f"rejected by the schema: {normalized(exc.param)}")
        return
    simulate_or_explain(scenario)


#: Number keys of the drive and the controller that take any magnitude the schema allows.
MAGNITUDE_KEYS = [
    f.key for f in SCALARS if f.kind is float and f.key not in TIME_VALUES and f.key != "simulation.speed0_rpm"
]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.dictionaries(
        st.sampled_from(MAGNITUDE_KEYS), st.floats(-40.0, 40.0).map(lambda x: 10.0**x), min_size=1, max_size=3
    )
)
@pytest.mark.slow
def test_extreme_magnitudes_simulate_or_are_named(values):
    """Values the schema accepts, from 1e-40 to 1e40: the float32 controllers and the engine either
    run them, name the key they refuse with the value it holds, or stop with the time and reason."""
    values = {k: (v if FIELDS[k].le is None else min(v, FIELDS[k].le)) for k, v in values.items()}
    try:
        scenario = BASE.with_overrides(values)
    except ConfigError as exc:
        check_message(exc)  # a relation between keys (tau_i >= Ts, m = 1 with lowpass ...)
        event(f"rejected by the schema: {normalized(exc.param)}")
        return
    simulate_or_explain(scenario)


@st.composite
def plausible_scenarios(draw):
    """Drives a user could mean, within what the drive can do: loads within 90 % of the torque limit,
    speeds within half the no-load speed, current loops at least 5 samples slow, faults in order,
    and an inertia that the largest torque within the current limit plus the load cannot spin
    past the no-load speed within the run (a lighter drive that loses its speed reading runs away: a
    legitimate stop)."""
    p = draw(st.integers(1, 8))
    psi = draw(st.floats(0.02, 0.5))
    Ld = draw(st.floats(1e-4, 0.05))
    Lq = draw(st.sampled_from([Ld, Ld * draw(st.floats(1.0, 3.0))]))
    i_max = draw(st.floats(1.0, 50.0))
    u_dc = draw(st.floats(24.0, 800.0))
    Ts_current = draw(st.sampled_from([5e-5, 1e-4, 2e-4]))
    Ts_speed = Ts_current * draw(st.integers(1, 20))
    model = draw(st.sampled_from(["dq_pi", "first_order"]))
    tau_i = Ts_current * draw(st.floats(5.0, 200.0))
    alpha = draw(st.floats(0.1, 0.1 / Ts_speed))
    t_end = 0.05
    T_max = 1.5 * p * psi * i_max  # of a surface motor
    # any torque within the current limit: |id iq| <= i_max^2 / 2
    T_most = 1.5 * p * (psi * i_max + abs(Ld - Lq) * i_max**2 / 2)
    w_no_load_rpm = u_dc / math.sqrt(3) / (p * psi) * 30 / math.pi
    J_least = (T_most + 0.9 * T_max) * t_end / (0.5 * w_no_load_rpm * math.pi / 30)
    J = max(draw(st.floats(1e-4, 1.0)), J_least * draw(st.floats(1.0, 10.0)))
    speed = st.floats(-0.5, 0.5).map(lambda x: x * w_no_load_rpm)
    times = sorted(draw(st.lists(st.floats(0.0, 0.045), min_size=1, max_size=3, unique=True)))
    faults = []
    t = draw(st.floats(0.0, 0.01))
    for kind in draw(st.lists(st.sampled_from(FAULT_KINDS), max_size=3)):
        if kind == "dc_link_sag" and (model != "dq_pi" or any(f["kind"] == kind for f in faults)):
            continue
        if kind != "dc_link_sag" and any(f["kind"] != "dc_link_sag" for f in faults):
            continue
        f = {"kind": kind, "t_s": t}
        if kind == "sensor_spike":
            f["speed_rpm"] = draw(speed)
        else:
            f["duration_s"] = draw(st.floats(1e-3, 0.02))
        if kind == "dc_link_sag":
            f["u_dc_factor"] = draw(st.floats(0.0, 1.0))
        faults.append(f)
    return BASE.with_overrides(
        {
            "motor.pole_pairs": p,
            "motor.psi_f_Wb": psi,
            "motor.Ld_H": Ld,
            "motor.Lq_H": Lq,
            "motor.Rs_ohm": draw(st.floats(0.01, 5.0)),
            "motor.J_kgm2": J,
            "motor.B_Nms": draw(st.floats(0.0, 0.1)),
            "motor.T_coulomb_Nm": draw(st.floats(0.0, 0.2)) * T_max,
            "limits.i_max_A": i_max,
            "limits.u_dc_V": u_dc,
            "inverter.computation_delay": draw(st.booleans()),
            "current_loop.model": model,
            "current_loop.tau_i_s": tau_i,
            "current_loop.Ts_s": Ts_current,
            "speed_controller.Ts_s": Ts_speed,
            "speed_controller.alpha_radps": alpha,
            "speed_controller.zeta": draw(st.floats(0.3, 2.0)),
            "speed_controller.anti_windup": draw(st.sampled_from(["none", "back_calculation", "clamping"])),
            "speed_controller.feedforward": draw(st.sampled_from(["none", "lowpass", "full"])),
            "speed_controller.method": draw(st.sampled_from(["forward_euler", "backward_euler", "tustin"])),
            "simulation.t_end_s": t_end,
            "simulation.speed0_rpm": draw(speed),
            "reference": [{"t_s": t, "speed_rpm": draw(speed)} for t in times],
            "load": [{"t_s": t, "torque_Nm": draw(st.floats(-0.9, 0.9)) * T_max} for t in times[:2]],
            "fault": faults,
        }
    )


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=plausible_scenarios())
def test_plausible_scenarios_simulate_with_finite_results(scenario):
    try:
        result = simulate(scenario)
    except ConfigError as exc:
        # designs the float32 controller refuses (Ki Ka Ts >= 2 and the like) are named, not run
        check_message(exc)
        event(f"rejected: {exc.param}")
        return
    check_result(result)
    check_sensor_readings(scenario, result)
    event("simulated")


def check_sensor_readings(scenario, result):
    """Outside its sensor faults the speed controller reads the true speed; a spike reads its value."""
    d = scenario.data
    spikes = [f for f in d["fault"] if f["kind"] == "sensor_spike"]
    quiet = np.ones(len(result.t_s), dtype=bool)
    Ts = d["speed_controller"]["Ts_s"]
    # the engine takes times closer than 1e-6 of its integration step as equal (drive.h, t_tol_s)
    Ts_current = d["current_loop"]["Ts_s"]
    t_tol = 1e-6 * Ts_current / math.ceil(Ts_current / d["simulation"]["dt_s"] * (1.0 - 1e-9))
    for f in d["fault"]:
        if f["kind"] != "dc_link_sag":
            end = f["t_s"] + (Ts if f["kind"] == "sensor_spike" else f["duration_s"])
            quiet &= ~((result.t_s >= f["t_s"] - t_tol) & (result.t_s < end - t_tol))
    assert np.array_equal(result.speed_meas_rpm[quiet], result.speed_rpm[quiet])
    for f in spikes:
        k = np.searchsorted(result.t_s, f["t_s"] - t_tol)
        if k < len(result.t_s):
            assert math.isclose(result.speed_meas_rpm[k], f["speed_rpm"], rel_tol=1e-12, abs_tol=1e-9)


def test_a_sensor_fault_window_off_the_sample_grid_is_read_as_the_engine_times_it():
    """A hold from 1e-9 s for 10 ms covers the sample at 10 ms: [1e-9, 0.01 + 1e-9) holds it.

    Found by the property above, which had compared sample times with 1e-9 s instead of the
    engine's tolerance of 1e-6 of an integration step (5e-11 s here).
    """
    scenario = load_scenario("paper-condition-1").with_overrides(
        {
            "current_loop.tau_i_s": 0.00025,
            "current_loop.Ts_s": 5e-05,
            "speed_controller.Ts_s": 5e-05,
            "simulation.t_end_s": 0.05,
            "simulation.speed0_rpm": 0.0,
            "reference": [{"t_s": 0.0, "speed_rpm": -5.0}],
            "fault": [{"kind": "sensor_hold", "t_s": 1e-9, "duration_s": 0.01}],
        }
    )
    result = simulate(scenario)
    k = int(np.searchsorted(result.t_s, 0.01 - 1e-12))
    assert result.t_s[k] == pytest.approx(0.01) and result.speed_rpm[k] != 0.0
    assert result.speed_meas_rpm[k] == result.speed_meas_rpm[0]
    check_sensor_readings(scenario, result)


PRESET_TEXT = (
    Path(__file__).parents[1] / "src" / "pmsm2dof" / "sim" / "presets" / "fault-sensor-spike.toml"
).read_bytes()


@settings(max_examples=300, deadline=None)
@given(
    cuts=st.lists(
        st.tuples(st.integers(0, len(PRESET_TEXT) - 1), st.integers(0, 8), st.binary(max_size=8)),
        min_size=1,
        max_size=4,
    )
)
@pytest.mark.slow
def test_corrupted_scenario_file_loads_or_names_the_problem(cuts):
    text = bytearray(PRESET_TEXT)
    for at, length, insert in cuts:
        text[at : at + length] = insert
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "corrupt.toml"
        path.write_bytes(bytes(text))
        try:
            load_scenario(path)
        except ConfigError as exc:
            check_message(exc)
            event(f"rejected: {normalized(exc.param)}")
        else:
            event("loaded")
