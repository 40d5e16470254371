"""Identification of J, B and Coulomb friction from logs simulated by the engine with known values.

Truth comes from the scenario that made the log (motor.J_kgm2, motor.B_Nms, motor.T_coulomb_Nm),
not from the fitter; the log is degraded as a real one is: the speed from an encoder's counts
differenced over the sampling period, white noise on the torque, and a load the fitter is not told of.
"""

import numpy as np
import pytest

from pmsm2dof.sim.logs import Log
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.studies.identify import IdentificationError, identify_mechanics

REFERENCE = [
    {"t_s": 0.05, "speed_rpm": 1000.0},
    {"t_s": 0.6, "speed_rpm": -800.0},
    {"t_s": 1.2, "speed_rpm": 600.0},
    {"t_s": 1.7, "speed_rpm": -1200.0},
    {"t_s": 2.3, "speed_rpm": 300.0},
]


def drive_scenario(J, B, Tc, load=(), reference=REFERENCE, t_end_s=2.8):
    """A fast drive (kt = 1.2 Nm/A, 9.1 Nm peak) with the closed current loop of eq 3, tau_i = 1 ms."""
    return load_scenario("paper-condition-2").with_overrides(
        {
            "motor.J_kgm2": J,
            "motor.B_Nms": B,
            "motor.T_coulomb_Nm": Tc,
            "limits.u_dc_V": 2000.0,
            "current_loop.model": "first_order",
            "current_loop.tau_i_s": 1e-3,
            "current_loop.Ts_s": 1e-4,
            "speed_controller.Ts_s": 1e-3,
            "speed_controller.alpha_radps": 30.0,
            "speed_controller.zeta": 0.7,
            "simulation.t_end_s": t_end_s,
            "reference": list(reference),
            "load": list(load),
        }
    )


def measured_log(result, counts_per_rev=None, torque_noise_Nm=0.0, seed=0):
    """The log a drive would record: speed from encoder counts differenced over each period, noisy torque."""
    rng = np.random.default_rng(seed)
    t, w = result.t_s, result.w_m_radps.copy()
    if counts_per_rev:
        angle = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))))
        step = 2 * np.pi / counts_per_rev
        counts = np.floor(angle / step + rng.uniform())
        w[1:] = np.diff(counts) * step / np.diff(t)
    torque = result.torque_Nm + torque_noise_Nm * rng.standard_normal(t.size)
    none = dict.fromkeys(("speed_ref_rpm", "id_A", "iq_A", "iq_ref_A", "ud_V", "uq_V", "u_dc_V"))
    return Log(
        source="engine",
        t_s=t,
        w_m_radps=w,
        speed_rpm=w * 30 / np.pi,
        torque_Nm=torque,
        columns={},
        rows_dropped=0,
        gaps=(),
        notes=(),
        **none,
    )


def test_an_exact_log_gives_the_parameters_of_the_engine():
    J, B, Tc = 0.01, 0.003, 0.3
    m = identify_mechanics(measured_log(simulate(drive_scenario(J, B, Tc))))
    assert m.J_kgm2 == pytest.approx(J, rel=2e-3)
    assert m.B_Nms == pytest.approx(B, rel=0.05)
    assert m.T_coulomb_Nm == pytest.approx(Tc, rel=0.02)


def test_encoder_noise_and_an_unannounced_load_stay_within_the_targets():
    J, B, Tc = 0.01, 0.003, 0.3
    load = [{"t_s": 0.9, "torque_Nm": 1.5}, {"t_s": 1.1, "torque_Nm": 0.0}]
    log = measured_log(simulate(drive_scenario(J, B, Tc, load)), counts_per_rev=1024, torque_noise_Nm=0.05, seed=3)
    m = identify_mechanics(log, speed_is_period_mean=True)
    assert m.J_kgm2 == pytest.approx(J, rel=0.02)
    assert m.T_coulomb_Nm == pytest.approx(Tc, rel=0.15)
    assert m.B_Nms == pytest.approx(B, rel=0.35)
    # the load window is found and excluded
    assert any(a <= 0.95 and b >= 1.05 for a, b in m.excluded_s)
    assert "outliers" in " ".join(m.notes)
    # without the exclusion, the load would bias the fit: the load-free run agrees within the intervals
    free = identify_mechanics(
        measured_log(simulate(drive_scenario(J, B, Tc)), counts_per_rev=1024, torque_noise_Nm=0.05, seed=3),
        speed_is_period_mean=True,
    )
    assert free.J_kgm2_ci[0] < m.J_kgm2 < free.J_kgm2_ci[1]


@pytest.mark.slow
def test_the_intervals_cover_the_truth_in_90_percent_of_100_random_drives():
    rng = np.random.default_rng(2026)
    hits = np.zeros(3)
    worst = np.zeros(3)
    for i in range(100):
        J = float(np.exp(rng.uniform(np.log(0.004), np.log(0.04))))
        B = float(rng.uniform(0.0005, 0.01))
        Tc = float(rng.uniform(0.05, 0.5))
        t_load = float(rng.uniform(0.1, 2.4))
        load = [{"t_s": t_load, "torque_Nm": float(rng.uniform(-2, 2))}, {"t_s": t_load + 0.2, "torque_Nm": 0.0}]
        cpr = int(rng.choice([1024, 4096, 16384]))
        log = measured_log(
            simulate(drive_scenario(J, B, Tc, load)),
            counts_per_rev=cpr,
            torque_noise_Nm=float(rng.uniform(0.0, 0.1)),
            seed=i,
        )
        m = identify_mechanics(log, speed_is_period_mean=True)
        for k, (value, (lo, hi), est) in enumerate(
            ((J, m.J_kgm2_ci, m.J_kgm2), (B, m.B_Nms_ci, m.B_Nms), (Tc, m.T_coulomb_Nm_ci, m.T_coulomb_Nm))
        ):
            hits[k] += lo <= value <= hi
            worst[k] = max(worst[k], abs(est / value - 1))
    assert np.all(hits >= 90), (hits, worst)
    # J within 2 % on every drive; B and the Coulomb friction are the weakly excited ones (the
    # slowest drives never reach a steady speed) and are held to their intervals only
    assert worst[0] < 0.02, worst


def test_a_log_without_acceleration_says_what_experiment_would_identify_j():
    steady = [{"t_s": 0.0, "speed_rpm": 500.0}]
    scenario = drive_scenario(0.01, 0.003, 0.3, reference=steady).with_overrides({"simulation.speed0_rpm": 500.0})
    log = measured_log(simulate(scenario), counts_per_rev=4096, torque_noise_Nm=0.05)
    with pytest.raises(IdentificationError, match="not identifiable.*speed steps or torque pulses.*identify plan"):
        identify_mechanics(log, speed_is_period_mean=True)


def test_identify_tau_i_of_eq_3_from_the_logged_iq_steps():
    from pmsm2dof.studies.identify import identify_tau_i

    for tau_i in (1e-3, 5e-3):
        result = simulate(drive_scenario(0.01, 0.003, 0.3).with_overrides({"current_loop.tau_i_s": tau_i}))
        log = measured_log(result)
        log = Log(**{**log.__dict__, "iq_A": result.iq_A, "iq_ref_A": result.iq_ref_A})
        assert identify_tau_i(log).tau_i_s == pytest.approx(tau_i, rel=1e-4)


def _csv_log(tmp_path, J=0.01, B=0.003, Tc=0.3):
    """A log as a drive writes it: currents, no torque column, speed in a column of its own name."""
    scenario = drive_scenario(J, B, Tc)
    result = simulate(scenario)
    frame = result.to_dataframe()[["t_s", "speed_rpm", "id_A", "iq_A", "iq_ref_A", "speed_ref_rpm"]]
    frame = frame.rename(columns={"t_s": "time_s", "speed_rpm": "enc_speed_rpm"})
    path = tmp_path / "run.csv"
    frame.to_csv(path, index=False)
    motor = tmp_path / "drive.toml"
    motor.write_text(scenario.to_toml())
    return path, motor


@pytest.mark.slow
def test_cli_identify_from_the_currents_writes_the_fit_and_an_identified_scenario(tmp_path, capsys):
    import json

    from pmsm2dof.core.gains import pi_gains
    from pmsm2dof.ui.cli import main

    path, motor = _csv_log(tmp_path)
    out = tmp_path / "out"
    argv = ["identify", "mechanics", str(path), "--column", "speed=enc_speed_rpm", "--motor", str(motor), "--json"]
    assert main([*argv, "--out", str(out), "--design", "30,0.7"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["J_kgm2"] == pytest.approx(0.01, rel=0.02)
    assert report["J_kgm2_ci"][0] < report["J_kgm2"] < report["J_kgm2_ci"][1]
    assert report["T_coulomb_Nm"] == pytest.approx(0.3, rel=0.15)
    assert report["tau_i_s"] == pytest.approx(1e-3, rel=1e-3)
    assert report["n_samples"] > 1000 and report["residual_rms_Nm"] > 0
    assert report["design"]["Kp"] == pytest.approx(pi_gains(report["J_kgm2"], 30.0, 0.7)[0], rel=1e-12)
    assert sorted(p.name for p in out.iterdir()) == [
        ".pmsm2dof-outputs.json",
        "fit.png",
        "identified.toml",
        "identify.json",
        "rows.csv",
    ]
    identified = load_scenario(out / "identified.toml")
    assert identified.data["motor"]["J_kgm2"] == report["J_kgm2"]
    assert identified.data["speed_controller"]["J_kgm2"] == report["J_kgm2"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--design", "30"], "--design = '30'"),
        (["--pole-pairs", "4"], "--pole-pairs = 4 is invalid: valid range is absent when --motor"),
        (["--window-s", "0.0001"], "--window-s = 0.0001"),
        (["--column", "speed"], "--column = 'speed'"),
    ],
)
def test_cli_identify_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, extra, message):
    from pmsm2dof.ui.cli import main

    path, motor = _csv_log(tmp_path)
    out = tmp_path / "out"
    argv = [
        "identify",
        "mechanics",
        str(path),
        "--column",
        "speed=enc_speed_rpm",
        "--motor",
        str(motor),
        "--out",
        str(out),
    ]
    assert main(argv + extra) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and message in captured.err
    assert "Traceback" not in captured.err
    assert not out.exists()


def test_a_log_made_by_motulator_gives_its_mechanics():
    """A log of another simulator (tests/data/make_motulator_logs.py): its controller, its machine
    model and friction function, a load it does not record; the torque from the logged currents."""
    from pathlib import Path

    from pmsm2dof.sim.logs import read_log
    from pmsm2dof.studies.identify import torque_from_currents

    path = Path(__file__).with_name("data") / "motulator_identification.npz"
    log = read_log(path)
    truth = np.load(path)
    m = identify_mechanics(log, torque_Nm=torque_from_currents(log, 4, 0.2, 0.01, 0.01))
    J, B, Tc = (float(truth[k]) for k in ("true_J_kgm2", "true_B_Nms", "true_T_coulomb_Nm"))
    assert m.J_kgm2 == pytest.approx(J, rel=0.02)
    assert m.T_coulomb_Nm == pytest.approx(Tc, rel=0.15)
    assert m.B_Nms == pytest.approx(B, rel=0.35)
    for value, (lo, hi) in ((J, m.J_kgm2_ci), (B, m.B_Nms_ci), (Tc, m.T_coulomb_Nm_ci)):
        assert lo <= value <= hi
    assert any(a <= 1.55 and b >= 1.75 for a, b in m.excluded_s)  # the load of 1.5 to 1.8 s


@pytest.mark.slow
def test_cli_plan_writes_a_run_within_the_limits_that_identifies_the_drive(tmp_path, capsys):
    from pathlib import Path

    from pmsm2dof.sim.logs import read_log
    from pmsm2dof.ui.cli import main

    drive = Path(__file__).resolve().parents[1] / "examples" / "your-motor" / "drive.toml"
    out = tmp_path / "plan"
    argv = ["identify", "plan", "--motor", str(drive), "--speed-max-rpm", "1000", "--i-max-A", "6", "--out"]
    assert main([*argv, str(out)]) == 0
    plan = load_scenario(out / "plan.toml")
    speeds = [e["speed_rpm"] for e in plan.data["reference"]]
    assert max(abs(s) for s in speeds) == 1000.0 and min(speeds) < 0 < max(speeds)
    assert plan.data["limits"]["i_max_A"] == 6.0 and plan.data["load"] == []
    log = read_log(out / "trace.csv")
    assert np.max(np.hypot(log.id_A, log.iq_A)) <= 6.0 * (1 + 1e-6)
    truth = plan.data["motor"]["J_kgm2"]
    assert identify_mechanics(log).J_kgm2 == pytest.approx(truth, rel=0.02)
    capsys.readouterr()
    assert main([*argv, str(tmp_path / "bad"), "--speed-max-rpm", "-5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--speed-max-rpm = -5.0" in err
    assert not (tmp_path / "bad").exists()


def test_a_log_with_gaps_and_missing_rows_is_identified_across_its_segments(tmp_path):
    """Rows removed (a gap of 0.1 s, scattered NaN rows): nothing is differenced across a hole."""
    from pmsm2dof.sim.logs import read_log

    J, B, Tc = 0.01, 0.003, 0.3
    result = simulate(drive_scenario(J, B, Tc))
    frame = result.to_dataframe()[["t_s", "speed_rpm", "torque_Nm"]]
    frame = frame[(frame["t_s"] < 1.0) | (frame["t_s"] > 1.1)].copy()
    frame.loc[frame.index[::97], "torque_Nm"] = np.nan
    frame.to_csv(tmp_path / "holes.csv", index=False)
    log = read_log(tmp_path / "holes.csv")
    assert len(log.segments()) == 2 and log.rows_dropped > 20
    m = identify_mechanics(log)
    assert m.J_kgm2 == pytest.approx(J, rel=0.02)
    assert m.T_coulomb_Nm == pytest.approx(Tc, rel=0.15)
    assert m.B_Nms == pytest.approx(B, rel=0.35)
