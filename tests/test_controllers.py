"""The Python objects over the C controllers: API behaviour, bulk runs, reset, parameter updates."""

import dataclasses
import math
import typing

import numpy as np
import pytest

from pmsm2dof.core import (
    ANTI_WINDUPS,
    FEEDFORWARDS,
    METHODS,
    CurrentController,
    CurrentOutput,
    SpeedController,
    SpeedOutput,
    bindings,
)
from pmsm2dof.core.bindings import lib
from pmsm2dof.errors import ConfigError

SPEED = dict(
    J_kgm2=0.01,
    alpha_radps=150.0,
    zeta=0.7,
    Ts_s=1e-4,
    i_max_A=8.0,
    psi_f_Wb=0.06,
    Ld_H=1e-3,
    Lq_H=2.5e-3,
    pole_pairs=4,
)
CURRENT = dict(Rs_ohm=0.5, Ld_H=1e-3, Lq_H=2e-3, psi_f_Wb=0.05, tau_i_s=1e-3, Ts_s=1e-4)


def f32(x):
    return float(np.float32(x))


def test_choice_tuples_are_the_c_enum_values():
    assert [getattr(lib, n) for n in ("P2D_FORWARD_EULER", "P2D_BACKWARD_EULER", "P2D_TUSTIN")] == [
        METHODS.index(m) for m in METHODS
    ]
    assert [getattr(lib, n) for n in ("P2D_FF_NONE", "P2D_FF_LOWPASS", "P2D_FF_NO_TAU", "P2D_FF_FULL")] == [0, 1, 2, 3]
    assert FEEDFORWARDS == ("none", "lowpass", "no_tau", "full")
    assert [getattr(lib, n) for n in ("P2D_AW_NONE", "P2D_AW_BACK_CALCULATION", "P2D_AW_CLAMPING")] == [
        ANTI_WINDUPS.index(a) for a in ANTI_WINDUPS
    ]


def test_literal_types_name_the_choices_read_from_c():
    # the annotations' Literal types are written by hand; the tuples are read from the C enums
    assert typing.get_args(bindings.Method) == METHODS
    assert typing.get_args(bindings.Feedforward) == FEEDFORWARDS
    assert typing.get_args(bindings.AntiWindup) == ANTI_WINDUPS


def test_every_status_code_names_a_parameter_of_the_bindings():
    import inspect

    from pmsm2dof.core import Encoder, FieldWeakening
    from pmsm2dof.core.bindings import ffi
    from pmsm2dof.core.fixedpoint import FixedPointSpeedController
    from pmsm2dof.sim.commission import commissioning_config
    from pmsm2dof.sim.scenario import load_scenario

    names = set()
    for binding in (SpeedController, CurrentController, Encoder, FieldWeakening, FixedPointSpeedController):
        names |= set(inspect.signature(binding).parameters)
    # the commissioning routine's settings (commission.h): the fields of a scenario's [commissioning]
    names |= set(commissioning_config(load_scenario("paper-condition-2")))
    # the inertia estimator (inertia.h) has no Python binding of its own: its codes name fields of its C config
    names |= {name for name, _ in ffi.typeof("p2d_inertia_config_t").fields}
    for status in range(2, lib.P2D_STATUS_COUNT):  # after P2D_OK and P2D_ERR_NULL
        assert ffi.string(lib.p2d_status_param(status)).decode() in names


def test_gains_and_default_Ka():
    ctl = SpeedController(**SPEED)
    J, a, z = f32(SPEED["J_kgm2"]), f32(SPEED["alpha_radps"]), f32(SPEED["zeta"])
    assert ctl.Kp == pytest.approx(J * a, rel=1e-6)  # eq 9
    assert ctl.Ki == pytest.approx(J * (a / (2 * z)) ** 2, rel=1e-6)
    assert ctl.Ka == pytest.approx(1 / ctl.Kp, rel=1e-6)  # section 3.3
    assert ctl.config["Ka"] is None
    # the default follows J and alpha; an explicit Ka is kept
    ctl.set_config(J_kgm2=0.04)
    assert ctl.Ka == pytest.approx(1 / ctl.Kp, rel=1e-6) and ctl.Kp == pytest.approx(0.04 * a, rel=1e-6)
    ctl.set_config(Ka=0.5)
    ctl.set_config(alpha_radps=100.0)
    assert ctl.Ka == 0.5 and ctl.config["Ka"] == 0.5


def test_values_are_float32():
    ctl = SpeedController(**SPEED)
    assert ctl.config["Ts_s"] == f32(1e-4) != 1e-4
    out = ctl.run([1.0, 2.0], 0.0)
    assert all(v.dtype == np.float32 for k, v in out.items() if k not in ("saturated", "fault"))
    assert out["saturated"].dtype == np.bool_


def test_config_round_trip():
    ctl = SpeedController(**SPEED, m=1.4, tau_i_s=2e-3, feedforward="full", method="backward_euler")
    again = SpeedController(**ctl.config)
    assert again.config == ctl.config and again.coefficients == ctl.coefficients
    assert "feedforward='full'" in repr(ctl)
    cur = CurrentController(**CURRENT, decouple=False, anti_windup="clamping")
    assert CurrentController(**cur.config).coefficients == cur.coefficients


@pytest.mark.parametrize("feedforward", FEEDFORWARDS)
def test_run_equals_steps_and_compute_update(feedforward):
    kwargs = dict(SPEED, feedforward=feedforward, m=1.0 if feedforward == "lowpass" else 1.5, tau_i_s=1e-3)
    rng = np.random.default_rng(5)
    w_ref = np.float32(np.repeat(rng.uniform(-200, 200, 12), 25))
    w_m = np.float32(rng.uniform(-200, 200, w_ref.size))
    bulk = SpeedController(**kwargs).run(w_ref, w_m)
    stepped, split = SpeedController(**kwargs), SpeedController(**kwargs)
    for k, (r, w) in enumerate(zip(w_ref, w_m)):
        a = stepped.step(r, w)
        b = split.compute(r, w)
        split.update(b, b.T_ref_Nm)
        assert a == b
        for field in dataclasses.fields(SpeedOutput):
            assert getattr(a, field.name) == bulk[field.name][k]
        assert stepped.x_i_Nm == bulk["x_i_Nm"][k]
    assert bulk["saturated"].any() and not bulk["saturated"].all()


def test_run_state_carries_over_and_broadcasts():
    w_ref = np.linspace(0, 50, 40)
    whole = SpeedController(**SPEED, feedforward="lowpass").run(w_ref, 3.0)
    parts = SpeedController(**SPEED, feedforward="lowpass")
    first, second = parts.run(w_ref[:15], 3.0), parts.run(w_ref[15:], np.full(25, 3.0))
    for name in whole:
        assert np.array_equal(whole[name], np.concatenate([first[name], second[name]]))
    assert SpeedController(**SPEED).run([], [])["T_ref_Nm"].shape == (0,)
    assert SpeedController(**SPEED).run(5.0, 0.0)["T_ref_Nm"].shape == (1,)


def test_run_rejects_bad_shapes():
    ctl = SpeedController(**SPEED)
    with pytest.raises(ConfigError, match="w_m_radps"):
        ctl.run(np.zeros(3), np.zeros(4))
    with pytest.raises(ConfigError, match="w_ref_radps"):
        ctl.run(np.zeros((2, 2)), 0.0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("feedforward, m", [("none", 1.0), ("lowpass", 1.0), ("no_tau", 0.5), ("full", 2.0)])
def test_reset_is_bumpless(method, feedforward, m):
    """After reset(w, T) the output at zero error and constant reference w is T, and stays T.

    The feedforward section is at its steady state, up to float32 rounding of
    that state (its slow pole 1 - p Ts turns rounding of the size of the
    feedforward torque, here ~90 Nm, into a drift of a few 1e-6 of it).
    """
    ctl = SpeedController(**SPEED, method=method, feedforward=feedforward, m=m, tau_i_s=5e-3)
    ctl.reset(120.0, 0.75)
    out = ctl.run(np.full(500, 120.0), 120.0)
    T_ff = np.max(np.abs(out["T_ff_Nm"]))
    np.testing.assert_allclose(out["T_ref_Nm"], 0.75, rtol=0, atol=1e-6 + 2e-5 * T_ff)
    ctl.reset()
    assert ctl.state == {"x_Nm": 0.0, "r_prev_radps": 0.0, "y_ff_prev_Nm": 0.0}
    with pytest.raises(ConfigError, match="T_init_Nm"):
        ctl.reset(0.0, math.nan)


def test_set_config_keeps_state_and_rejects_unknown_names():
    ctl = SpeedController(**SPEED)
    ctl.run(np.full(30, 10.0), 0.0)
    state = ctl.state
    ctl.set_config(zeta=1.2, anti_windup="clamping")
    assert ctl.state == state and ctl.config["anti_windup"] == "clamping"
    with pytest.raises(ConfigError, match="zeta_typo"):
        ctl.set_config(zeta_typo=1.0)
    with pytest.raises(ConfigError) as info:
        ctl.set_config(Ts_s=-1.0, zeta=5.0)
    assert info.value.param == "Ts_s" and ctl.config["zeta"] == f32(1.2)


def test_ka_default_error_shows_its_value():
    # Ki Ka Ts = alpha Ts / (4 zeta^2) = 1000 * 1e-3 / 0.04 >= 2 with the default Ka
    with pytest.raises(ConfigError, match=r"Ka = 'None \(default 1/Kp = ") as info:
        SpeedController(**{**SPEED, "alpha_radps": 1000.0, "zeta": 0.1, "Ts_s": 1e-3})
    assert info.value.param == "Ka"


def test_outputs_are_frozen():
    out = SpeedController(**SPEED).step(1.0, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.T_ref_Nm = 0.0


def test_current_controller_api():
    ctl = CurrentController(**CURRENT)
    c = ctl.coefficients
    assert c["d"]["Kp"] == pytest.approx(1e-3 / 1e-3) and c["q"]["Kp"] == pytest.approx(2.0)  # eq 3: L / tau_i
    assert c["d"]["Ki"] == pytest.approx(500.0, rel=1e-6)  # Rs / tau_i
    n = 60
    args = (np.full(n, 1.0), np.full(n, 3.0), np.zeros(n), np.linspace(0, 2, n), 400.0, 48.0)
    bulk = CurrentController(**CURRENT).run(*args)
    split = CurrentController(**CURRENT)
    for k in range(n):
        out = split.compute(*(a[k] if np.ndim(a) else a for a in args))
        split.update(out, out.ud_ref_V, out.uq_ref_V)
        for field in dataclasses.fields(CurrentOutput):
            assert getattr(out, field.name) == bulk[field.name][k]
        assert split.state == {"x_d_V": bulk["x_d_V"][k], "x_q_V": bulk["x_q_V"][k]}
    assert bulk["saturated"].any()
    split.set_config(decouple=False)
    assert split.coefficients["Lq_H"] == 0.0 and split.state["x_q_V"] == bulk["x_q_V"][-1]
    split.reset()
    assert split.state == {"x_d_V": 0.0, "x_q_V": 0.0}
    assert split.fault_count == 0
