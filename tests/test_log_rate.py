"""``simulation.log_rate = "current"``: a row per current period, the controllers unchanged.

Truth from outside the code under test:

- the controllers do not know the log's rate: the rows of a run at the current rate that fall on
  the speed controller's samples are, bit for bit, the rows of the same run logged at the speed
  rate (every column, the voltage-limit share included);
- between those samples, the logged currents obey eq 1 over each current period: integrated here
  by SciPy (``solve_ivp``, DOP853) from the logged currents at the start of the period, with the
  logged dq voltage held over it and the logged speed interpolated linearly, they reach the logged
  currents at its end within a bound derived below from the run's scales;
- the bound on the log's memory, the speed-loop figures of the metrics (counted in speed samples)
  and the electrical identification of eq 1 on the small servo's log with its 2 kHz speed loop.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from oracles import small_servo
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.logs import read_log
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import log_rows, simulate, simulate_many
from pmsm2dof.studies.electrical import PARAMETERS, identify_electrical
from pmsm2dof.studies.identify import IdentificationError
from pmsm2dof.ui.cli import main

CURRENT = {"simulation.log_rate": "current"}
PER_SPEED = round(small_servo.TS_SPEED_S / small_servo.TS_CURRENT_S)


def servo(**overrides):
    """The small servo (20 kHz / 2 kHz), events close together and between the loops' instants: a
    load of 0.1 Nm at 0.10003 s (inside a current period), removed at 0.2 s, a reversal at 0.21 s."""
    base = small_servo.scenario(
        reference=((0.0, 3000.0), (0.21, -3000.0)), load=((0.10003, 0.1), (0.2, 0.0)), t_end_s=0.3
    )
    return base.with_overrides(overrides)


def speed_rows(rows, log_every):
    """Indices of the current-rate rows at the speed samples, and of those samples in the speed-rate log."""
    periods = np.arange(rows) * log_every
    at = np.flatnonzero(periods % PER_SPEED == 0)
    return at, periods[at] // PER_SPEED


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {"inverter.computation_delay": True},
        {"current_loop.model": "first_order"},
        {"speed_controller.alpha_radps": 3000.0},  # a sampled loop that chatters between the limits
        {"speed_sensor.model": "encoder", "speed_sensor.counts_per_rev": 2048, "current_measurement.noise_A_rms": 0.05},
        {"mechanics.model": "two_mass", "mechanics.J_load_kgm2": 1e-4, "mechanics.stiffness_Nm_per_rad": 50.0},
        {"simulation.log_every": 5},
        {"simulation.log_every": 3},
        {"speed_controller.arithmetic": "q31"},  # the fixed-point controller's columns
        {"speed_controller.arithmetic": "q15"},
    ],
)
def test_rows_at_the_speed_samples_are_the_speed_rate_log_bit_for_bit(overrides):
    log_every = overrides.pop("simulation.log_every", 1)
    speed = simulate(servo(**overrides))
    current = simulate(servo(**overrides, **CURRENT, **{"simulation.log_every": log_every}))
    at, samples = speed_rows(len(current.t_s), log_every)
    assert len(current.t_s) == (len(speed.t_s) - 1) * PER_SPEED // log_every + 1  # to t_end_s, no further
    for name in speed.signals:
        assert getattr(current, name)[at].tobytes() == getattr(speed, name)[samples].tobytes(), name
    np.testing.assert_allclose(np.diff(current.t_s), log_every * small_servo.TS_CURRENT_S, rtol=1e-9)
    # the speed controller's outputs hold over the rows of its sample
    _, first, sample = np.unique(np.arange(len(current.t_s)) * log_every // PER_SPEED, True, True)
    for name in ("iq_ref_A", "torque_ref_Nm", "x_i_Nm", "speed_meas_rpm", "voltage_limited"):
        assert np.array_equal(getattr(current, name), getattr(current, name)[first][sample]), name


def test_lockstep_runs_log_the_lone_runs_at_the_current_rate():
    scenarios = [servo(**CURRENT, **{"motor.J_kgm2": small_servo.J_KGM2 * k}) for k in (0.5, 1.0, 2.0)]
    for many, scenario in zip(simulate_many(scenarios), scenarios):
        lone = simulate(scenario)
        for name in lone.signals:
            assert getattr(many, name).tobytes() == getattr(lone, name).tobytes(), name


def eq1_bound(result, substeps):
    """The largest error of the currents at the end of each period that the comparison below allows [A].

    Two errors, bounded from the run's scales (largest |i|, |u|, |w_e| of the log), the change of the currents
    over the period and the motor:

    - the speed inside a period, taken linear between the logged ends: off by at most ``h^2/8 max|w''|``,
      ``w'' = Te'/J``, ``|Te'| <= 1.5 p (psi_f + 2 |Ld - Lq| i) max|i'|``; over a period eq 1 is linear with a
      held input, ``i' = exp(A t) i'(0)``, so ``|i'| <= e^(a h) / (2 - e^(a h)) |delta i| / h`` with ``a``
      the largest rate of eq 1 (``Rs / L + w_e L_max / L_min``); in a period that holds a load step ``dT``
      the speed has a kink instead, off by ``h/4 |dT|/J``. Either moves the currents by
      ``h p dw (L_max i + psi_f) / L_min`` at most;
    - the engine's RK4 step ``dt = h / substeps`` of eq 1: its local error is the series beyond the fourth
      power, ``(dt a)^5 / 5!`` of the state's scale ``i + u / (a L_min)``, ``substeps`` times.

    Twice their sum, plus the SciPy integration's own tolerance.
    """
    d = result.scenario.data
    m = d["motor"]
    h = d["current_loop"]["Ts_s"]
    p, Rs, psi, J = m["pole_pairs"], m["Rs_ohm"], m["psi_f_Wb"], m["J_kgm2"]
    L_min, L_max = min(m["Ld_H"], m["Lq_H"]), max(m["Ld_H"], m["Lq_H"])
    i = float(np.max(np.hypot(result.id_A, result.iq_A)))
    u = float(np.max(np.hypot(result.ud_V, result.uq_V)))
    w_e = p * float(np.max(np.abs(result.w_m_radps)))
    a = Rs / L_min + w_e * L_max / L_min
    assert math.exp(a * h) < 2.0
    step = np.hypot(np.diff(result.id_A), np.diff(result.iq_A))
    di = math.exp(a * h) / (2.0 - math.exp(a * h)) * step / h
    w2 = 1.5 * p * (psi + 2 * abs(m["Ld_H"] - m["Lq_H"]) * i) * di / J
    dw = h**2 / 8 * w2
    before = 0.0
    for e in d["load"]:
        k = int(np.searchsorted(result.t_s, e["t_s"], side="right")) - 1
        dw[k] = max(dw[k], h / 4 * abs(e["torque_Nm"] - before) / J)
        before = e["torque_Nm"]
    speed_error = h * p * dw * (L_max * i + psi) / L_min
    rk4_error = substeps * (h / substeps * a) ** 5 / math.factorial(5) * (i + u / (a * L_min))
    return 2.0 * (speed_error + rk4_error) + 1e-9


def eq1_end_of_period(result, shift=0):
    """The currents at the end of every current period by eq 1 (SciPy), from the logged currents at its
    start, with the logged voltage of the row ``shift`` rows later held over it (0: its own)."""
    d = result.scenario.data
    m = d["motor"]
    h = d["current_loop"]["Ts_s"]
    p, Rs, Ld, Lq, psi = m["pole_pairs"], m["Rs_ohm"], m["Ld_H"], m["Lq_H"], m["psi_f_Wb"]
    k = np.arange(max(0, -shift), len(result.t_s) - 1 - max(0, shift))
    ud, uq = result.ud_V[k + shift], result.uq_V[k + shift]
    w0, w1 = p * result.w_m_radps[k], p * result.w_m_radps[k + 1]

    def eq1(t, x):
        i_d, i_q = x[: len(k)], x[len(k) :]
        w_e = w0 + (w1 - w0) * (t / h)
        return np.concatenate([(ud - Rs * i_d + w_e * Lq * i_q) / Ld, (uq - Rs * i_q - w_e * (Ld * i_d + psi)) / Lq])

    x0 = np.concatenate([result.id_A[k], result.iq_A[k]])
    sol = solve_ivp(eq1, (0.0, h), x0, method="DOP853", rtol=1e-12, atol=1e-12)
    x1 = sol.y[:, -1]
    return k, x1[: len(k)], x1[len(k) :]


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {"inverter.computation_delay": True},
        # salient, into field weakening on 12 V: id moves and the voltage sits at its range
        {
            "motor.Lq_H": 4.6e-4,
            "limits.u_dc_V": 12.0,
            "field_weakening.enabled": True,
            "field_weakening.Ki_A_per_Vs": 3.0,
            "simulation.dt_s": 1e-5,
        },
    ],
)
def test_currents_between_the_speed_samples_follow_eq1(overrides):
    result = simulate(servo(**CURRENT, **overrides))
    d = result.scenario.data
    substeps = math.ceil(d["current_loop"]["Ts_s"] / d["simulation"]["dt_s"] * (1 - 1e-9))
    bound = eq1_bound(result, substeps)
    k, i_d, i_q = eq1_end_of_period(result)
    error = np.maximum(np.abs(i_d - result.id_A[k + 1]), np.abs(i_q - result.iq_A[k + 1]))
    assert np.all(error <= bound[k])
    # the check sees a voltage paired with the wrong period: beyond the bound wherever the voltage moves
    k, i_d, i_q = eq1_end_of_period(result, shift=1)
    error = np.maximum(np.abs(i_d - result.id_A[k + 1]), np.abs(i_q - result.iq_A[k + 1]))
    assert np.mean(error > bound[k]) > 0.5 and np.max(error / bound[k]) > 100


def test_the_log_bound_counts_the_rows_of_the_current_rate():
    # 1500 s at the speed rate: 1.5e6 rows (275 MiB); at the current rate ten times that
    scenario = load_scenario("paper-condition-2").with_overrides({"simulation.t_end_s": 1500.0})
    with pytest.raises(ConfigError) as err:
        simulate(scenario.with_overrides(CURRENT))
    # 1500001 speed samples of 10 current periods, 24 columns of 8 bytes: 2.88e9 bytes, below 2 GiB from log_every 2
    rows = 1500001 * 10
    assert rows * 24 * 8 > 2 * 1024**3 > rows / 2 * 24 * 8
    text = str(err.value)
    assert f"simulation.log_every = 1 is invalid: valid range is >= 2: the log of {rows} rows" in text
    assert f"a row every 1 of the {rows} current periods, 10 per speed sample) would exceed 2 GiB" in text
    assert log_rows(scenario) == (1500001, 1500001)


def test_steady_state_figures_count_speed_samples_not_rows():
    """A load removed 2 ms after it was applied: the window's last 10 % (0.2 ms) holds no speed sample of
    the 2 kHz loop, but four current periods; a steady state is not told from within one speed period."""
    scenario = small_servo.scenario(reference=((0.0, 1000.0),), load=((0.1, 0.1), (0.102, 0.0)), t_end_s=0.2)
    for rate in ("speed", "current"):
        metrics = compute_metrics(simulate(scenario.with_overrides({"simulation.log_rate": rate})))
        step = metrics["load_steps"][0]
        assert step["steady_state_error_rpm"]["value"] is None
        assert "logged speed-controller samples in its last 10 %" in step["steady_state_error_rpm"]["reason"]
        assert step["speed_dip_rpm"]["value"] > 0


def test_chatter_is_counted_at_the_speed_samples():
    chattering = servo(**{"speed_controller.alpha_radps": 3000.0})
    at_speed = compute_metrics(simulate(chattering))["run"]["chatter_share"]["value"]
    assert at_speed > 0.01
    for log_every in (1, 2, 5):
        run = simulate(chattering.with_overrides({**CURRENT, "simulation.log_every": log_every}))
        assert compute_metrics(run)["run"]["chatter_share"]["value"] == at_speed
    run = simulate(chattering.with_overrides({**CURRENT, "simulation.log_every": 3}))
    figure = compute_metrics(run)["run"]["chatter_share"]
    assert figure["value"] is None and "does not divide the speed-controller period" in figure["reason"]


SALIENT_SERVO = "examples/commissioning/servo-salient.toml"
MOTOR = {"Rs_ohm": 0.8, "Ld_H": 4e-3, "Lq_H": 8e-3, "psi_f_Wb": 0.05}


def salient_trace(tmp_path, suffix, **overrides):
    """The salient servo (10 kHz current loop, its own 1 kHz speed loop) into field weakening on 24 V."""
    scenario = load_scenario(SALIENT_SERVO).with_overrides(
        {
            "simulation.t_end_s": 0.4,
            "limits.u_dc_V": 24.0,
            "field_weakening.enabled": True,
            "field_weakening.Ki_A_per_Vs": 3.0,
            "current_measurement.noise_A_rms": 0.02,
            **{f"motor.{k}": v for k, v in MOTOR.items()},
            **overrides,
        }
    )
    path = tmp_path / f"trace{suffix}"
    simulate(scenario).save(path)
    return read_log(path)


def test_electrical_fit_of_a_current_rate_trace(tmp_path):
    log = salient_trace(tmp_path, ".npz", **CURRENT)
    assert log.current_period_s == 1e-4 and log.dt_s == pytest.approx(1e-4)
    fit = identify_electrical(log, 4)
    for name in PARAMETERS:
        assert abs(getattr(fit, name) / MOTOR[name] - 1) < 0.01, name
    assert not any("iq_ref_A changes" in note for note in fit.notes)


def test_electrical_fit_refuses_a_speed_rate_trace(tmp_path):
    with pytest.raises(IdentificationError, match=r"rows are 0.001 s apart, 10 periods of its current loop"):
        identify_electrical(salient_trace(tmp_path, ".npz"), 4)
    # a CSV says nothing of the current loop: the command changing from row to row tells the speed rate
    fit = identify_electrical(salient_trace(tmp_path, ".csv"), 4)
    assert any("the rows look like the speed controller's samples" in note for note in fit.notes)
    assert not any("iq_ref_A" in n for n in identify_electrical(salient_trace(tmp_path, ".csv", **CURRENT), 4).notes)


def test_cli_simulate_logs_at_the_current_rate(tmp_path, capsys):
    path = tmp_path / "servo.toml"
    path.write_text(servo().to_toml())
    assert main(["simulate", str(path), "--set", "simulation.log_rate=current", "--out", str(tmp_path / "c")]) == 0
    assert main(["simulate", str(path), "--out", str(tmp_path / "s")]) == 0
    capsys.readouterr()
    import pandas as pd

    current, speed = (pd.read_csv(tmp_path / d / "trace.csv") for d in ("c", "s"))
    assert len(current) == (len(speed) - 1) * PER_SPEED + 1
    assert current.iloc[::PER_SPEED].reset_index(drop=True).equals(speed)
    assert (tmp_path / "c" / "plot.png").stat().st_size > 0
    code = main(["simulate", str(path), "--set", "simulation.log_rate=fast", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.splitlines()
    assert (
        code == 2
        and len(err) == 1
        and "simulation.log_rate = 'fast' is invalid: valid range is one of 'speed', 'current'" in err[0]
    )
    assert not (tmp_path / "x").exists()


def test_the_firmware_refuses_and_the_tuner_drops_the_current_rate():
    from pmsm2dof.studies.virtual_drive import check_virtual_drive
    from pmsm2dof.ui.tuner.experiment import Tuner

    with pytest.raises(ConfigError, match=r"simulation.log_rate = 'current' is invalid.*a row per speed sample"):
        check_virtual_drive(servo(**CURRENT))
    logged = Tuner.logged(servo(**CURRENT, **{"simulation.log_every": 3})).data["simulation"]
    assert logged["log_rate"] == "speed" and logged["log_every"] == 1
