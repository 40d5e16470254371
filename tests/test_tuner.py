"""The tuner's computations and JSON endpoints (Starlette TestClient), and `pmsm2dof tune`.

Truth comes from outside the tuner: eq (8) and eq (10) of the paper written out here, the
torque balance of the mechanics (a saturated start accelerates at T_max / J, a settled
load is carried by iq = T_load / (1.5 p psi_f)), and a brute-force decimation check.
"""

import io
import math
import re
import socket
import subprocess
import sys
import tomllib
import warnings

import httpx
import numpy as np
import pandas as pd
import pytest

with warnings.catch_warnings():
    # starlette's TestClient prefers httpx2 and warns on import when it runs on httpx, which it supports
    warnings.filterwarnings("ignore", message="Using `httpx` with `starlette.testclient`")
    from starlette.testclient import TestClient

from pmsm2dof.design import design
from pmsm2dof.scenario import load_scenario
from pmsm2dof.tuner import create_app
from pmsm2dof.tuner.experiment import (
    CONTROLS,
    DECIMATION_BUCKETS,
    Tuner,
    bode_data,
    loop_on_plant,
    minmax_indices,
)

PRESET = "paper-condition-2"
RADPS_PER_RPM = 2.0 * math.pi / 60.0


@pytest.fixture(scope="module")
def base():
    return load_scenario(PRESET)


@pytest.fixture(scope="module")
def client(base):
    with TestClient(create_app(base)) as c:
        yield c


def run(client, **values):
    body = {k.replace("__", "."): v for k, v in values.items()}
    response = client.post("/api/run", json=body)
    assert response.status_code == 200, response.text
    return response.json()


# ---- decimation ------------------------------------------------------------------------


def test_minmax_keeps_every_bucket_extreme_and_the_ends():
    rng = np.random.default_rng(7)
    y = np.cumsum(rng.normal(size=20011))
    keep = minmax_indices(y, buckets=100)
    assert len(keep) <= 2 * 100 + 2
    assert keep[0] == 0 and keep[-1] == len(y) - 1
    assert np.all(np.diff(keep) > 0)
    width = math.ceil(len(y) / 100)
    for start in range(0, len(y), width):  # brute force, bucket by bucket
        chunk = y[start:start + width]
        kept = y[keep[(keep >= start) & (keep < start + width)]]
        assert kept.max() == chunk.max() and kept.min() == chunk.min()


def test_minmax_leaves_short_traces_whole():
    assert np.array_equal(minmax_indices(np.arange(50.0), buckets=100), np.arange(50))


# ---- transfer functions of the Bode plot -----------------------------------------------


def eq8_GN(s, J, tau, Kp, Ki):
    """Paper eq (8), load torque to speed, written out."""
    return -(tau * s**2 + s) / (J * tau * s**3 + J * s**2 + Kp * s + Ki)


@pytest.mark.parametrize("J_ratio", [1.0, 0.5, 2.5])
def test_load_response_is_eq8_with_the_true_inertia(J_ratio):
    d = design(0.4, 0.5, 0.2887, m=1.0, tau_i_s=0.05, feedforward="lowpass")
    _, GN = loop_on_plant(d, J_ratio * 0.4)
    w = np.logspace(-3, 3, 50)
    got = np.asarray(GN(1j * w)).reshape(-1)
    want = eq8_GN(1j * w, J_ratio * 0.4, 0.05, d.Kp, d.Ki)
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_full_feedforward_tracks_as_eq10_on_the_design_inertia():
    d = design(0.4, 0.5, 0.2887, m=1.7, tau_i_s=0.05, feedforward="full")
    Gx, _ = loop_on_plant(d, 0.4)
    w = np.logspace(-3, 3, 50)
    m_alpha = 1.7 * 0.5
    np.testing.assert_allclose(np.asarray(Gx(1j * w)).reshape(-1), m_alpha / (1j * w + m_alpha), rtol=1e-7)
    bode = bode_data(Gx, Gx, 0.5, 1e-3)
    w_b = np.asarray(bode["w_radps"])
    np.testing.assert_allclose(bode["Gx_dB"], 20 * np.log10(m_alpha / np.abs(1j * w_b + m_alpha)), atol=1e-6)
    np.testing.assert_allclose(bode["Gx_deg"], -np.degrees(np.arctan(w_b / m_alpha)), atol=1e-6)


# ---- controls -> scenario --------------------------------------------------------------


def test_initial_controls_are_the_preset(client, base):
    data = base.data
    description = client.get("/api/controls").json()
    assert description["name"] == data["name"]
    specs = {c["key"]: c for g in description["groups"] for c in g["controls"]}
    assert set(specs) == set(CONTROLS)
    assert specs["speed_controller.alpha"]["value"] == data["speed_controller"]["alpha"]
    assert specs["speed_controller.Ka"]["value"] is None
    assert specs["tuner.speed_step_rpm"]["value"] == data["reference"][0]["speed_rpm"]
    assert specs["tuner.load_step_Nm"]["value"] == data["load"][0]["torque_Nm"]
    assert specs["tuner.t_load_s"]["value"] == data["load"][0]["t_s"]
    assert specs["tuner.J_ratio"]["value"] == 1.0
    for spec in specs.values():
        if spec["kind"] == "slider":
            assert spec["min"] < spec["max"]
        else:
            assert spec["value"] in spec["choices"]


def test_inertia_ratio_changes_the_plant_not_the_design(base):
    scenario = Tuner(base).scenario({"tuner.J_ratio": 2.0, "speed_controller.alpha": 0.8})
    data = scenario.data
    assert data["motor"]["J_kgm2"] == pytest.approx(2.0 * base.data["motor"]["J_kgm2"])
    assert data["speed_controller"]["J_design_kgm2"] == base.data["motor"]["J_kgm2"]
    assert data["speed_controller"]["alpha"] == 0.8
    assert data["reference"] == [{"t_s": 0.0, "speed_rpm": 500.0, "ramp_s": 0.0}]
    assert data["load"] == [{"t_s": 7.0, "torque_Nm": 8.0, "ramp_s": 0.0}]


# ---- /api/run --------------------------------------------------------------------------


def test_run_returns_decimated_traces_that_keep_the_peaks(client):
    out = run(client, speed_controller__feedforward="none", speed_controller__anti_windup="none")
    for trace in out["traces"].values():
        assert len(trace["t"]) == len(trace["y"]) <= 2 * DECIMATION_BUCKETS + 2
        assert np.all(np.diff(trace["t"]) > 0)
    # the plotted overshoot is the table's: decimation kept the peak before the load step
    speed = out["traces"]["speed_rpm"]
    t, y = np.asarray(speed["t"]), np.asarray(speed["y"])
    plotted_pct = 100.0 * (y[t < out["t_load_s"]].max() - 500.0) / 500.0
    table = {m["key"]: m for m in out["metrics"]}
    assert table["step.overshoot_pct"]["value"] == pytest.approx(plotted_pct, abs=0.05)
    assert table["load.speed_dip_rpm"]["value"] > 0
    assert out["design"]["Kp"] == pytest.approx(0.4 * 0.5)
    assert out["server_ms"] > 0


def test_saturated_start_accelerates_at_the_torque_limit_over_the_true_inertia(client, base):
    motor = base.data["motor"]
    T_max_Nm = 1.5 * motor["pole_pairs"] * motor["psi_f_Wb"] * base.data["limits"]["i_max_A"]
    for J_ratio in (1.0, 2.0):
        out = run(client, tuner__J_ratio=J_ratio, speed_controller__feedforward="none",
                  speed_controller__anti_windup="none")
        t, y = np.asarray(out["traces"]["speed_rpm"]["t"]), np.asarray(out["traces"]["speed_rpm"]["y"])
        # 0.4 s .. 1.0 s: the 1DOF PI commands the limit (its proportional part alone asks for
        # Kp * 52 rad/s = 10.5 Nm > T_max) and the current loop (tau_i = 0.05 s) has settled there
        window = (t > 0.4) & (t < 1.0)
        a = np.polyfit(t[window], y[window] * RADPS_PER_RPM, 1)[0]
        assert a == pytest.approx(T_max_Nm / (J_ratio * motor["J_kgm2"]), rel=0.02)


def test_settled_load_is_carried_by_the_q_current(client, base):
    motor = base.data["motor"]
    out = run(client, simulation__t_end_s=40.0, tuner__load_step_Nm=5.0, tuner__t_load_s=10.0,
              speed_controller__alpha=1.0)
    iq = out["traces"]["iq_ref_A"]["y"][-1]
    assert iq == pytest.approx(5.0 / (1.5 * motor["pole_pairs"] * motor["psi_f_Wb"]), rel=0.01)
    assert out["traces"]["speed_rpm"]["y"][-1] == pytest.approx(500.0, abs=1.0)


def test_anti_windup_lowers_the_overshoot_of_a_saturated_step(client):
    """Paper section 4.1: without anti-windup the 1DOF PI overshoots far more (Fig. 8)."""

    def overshoot(mode):
        rows = run(client, speed_controller__anti_windup=mode, speed_controller__feedforward="none")["metrics"]
        return {m["key"]: m["value"] for m in rows}["step.overshoot_pct"]

    assert overshoot("none") > 1.5 * overshoot("back_calculation") > 0


BAD_VALUES = [
    ("speed_controller.alpha", -1.0),
    ("speed_controller.alpha", "fast"),
    ("speed_controller.zeta", 0),
    ("speed_controller.m", 2.0),  # lowpass feedforward is eq (13): m = 1
    ("speed_controller.Ka", -0.5),
    ("speed_controller.feedforward", "bogus"),
    ("speed_controller.anti_windup", True),
    ("speed_controller.discretization", "zoh"),
    ("speed_controller.Ts_s", 1.5e-4),  # not an integer multiple of the 1e-4 s current loop
    ("simulation.t_end_s", 1e9),
    ("tuner.J_ratio", 0.0),
    ("tuner.speed_step_rpm", None),
    ("tuner.load_step_Nm", "8 Nm"),
    ("tuner.t_load_s", 20.0),  # after the end of the 15 s run
    ("motor.J_kgm2", 1.0),  # not a control of the tuner
]


@pytest.mark.parametrize("key, value", BAD_VALUES)
def test_bad_value_answers_422_naming_the_key(client, key, value):
    for path in ("/api/run", "/api/download/scenario.toml", "/api/download/header.h", "/api/download/trace.csv"):
        response = client.post(path, json={key: value})
        assert response.status_code == 422, (path, response.text)
        err = response.json()
        assert err["param"] == key
        assert key in err["error"] and "valid" in err["error"]


def test_a_run_that_stops_answers_422_with_the_reason(client, base):
    """A load of -1000 Nm drives the motor past the engine's overspeed bound (twice the no-load
    speed u_dc / (sqrt(3) p psi_f)): the engine stops and the page gets the reason, not a trace."""
    motor = base.data["motor"]
    bound_rpm = 2 * base.data["limits"]["u_dc_V"] / (math.sqrt(3) * motor["pole_pairs"] * motor["psi_f_Wb"]) / (
        RADPS_PER_RPM)
    response = client.post("/api/run", json={"tuner.load_step_Nm": -1000.0})
    assert response.status_code == 422
    err = response.json()
    assert err["param"] is None
    assert "stopped at t =" in err["error"] and f"{bound_rpm:.6g} rpm" in err["error"]


def test_non_finite_json_number_is_rejected(client):
    response = client.post("/api/run", content=b'{"speed_controller.alpha": NaN}',
                           headers={"Content-Type": "application/json"})
    assert response.status_code == 422
    assert response.json()["param"] == "speed_controller.alpha"


@pytest.mark.parametrize("body", [b"not json", b"[1, 2]", b'"alpha"'])
def test_body_that_is_not_an_object_answers_422(client, body):
    response = client.post("/api/run", content=body, headers={"Content-Type": "application/json"})
    assert response.status_code == 422
    assert response.json()["param"] == "body"


# ---- downloads -------------------------------------------------------------------------


def test_scenario_download_loads_back_to_the_run_scenario(client, base, tmp_path):
    values = {"speed_controller.alpha": 0.7, "speed_controller.anti_windup": "clamping", "tuner.J_ratio": 1.5,
              "tuner.load_step_Nm": -3.0}
    response = client.post("/api/download/scenario.toml", json=values)
    assert response.status_code == 200
    assert 'filename="paper-condition-2-tuned.toml"' in response.headers["content-disposition"]
    tree = tomllib.loads(response.text)
    assert tree["speed_controller"]["alpha"] == 0.7
    assert tree["load"] == [{"t_s": 7.0, "torque_Nm": -3.0}]
    path = tmp_path / "tuned.toml"
    path.write_text(response.text)
    assert load_scenario(path) == Tuner(base).scenario(values)


def test_header_download_holds_the_posted_design(client):
    response = client.post("/api/download/header.h", json={"speed_controller.alpha": 0.75,
                                                           "speed_controller.discretization": "backward_euler"})
    assert response.status_code == 200
    text = response.text
    assert re.search(r"\.alpha_radps = 0\.75f,", text)
    assert ".method = P2D_BACKWARD_EULER," in text
    assert '#include "pmsm2dof/speed.h"' in text


def test_trace_download_is_the_full_rate_run(client, base):
    response = client.post("/api/download/trace.csv", json={"simulation.t_end_s": 9.0})
    assert response.status_code == 200
    frame = pd.read_csv(io.StringIO(response.text))
    Ts = base.data["speed_controller"]["Ts_s"]
    assert {"t_s", "speed_rpm", "speed_ref_rpm", "iq_ref_A"} <= set(frame.columns)
    assert frame["t_s"].iloc[-1] == pytest.approx(9.0, abs=2 * Ts)
    assert np.diff(frame["t_s"]).max() == pytest.approx(Ts, rel=1e-6)


def test_unknown_download_answers_422(client):
    response = client.post("/api/download/firmware.bin", json={})
    assert response.status_code == 422
    assert response.json()["param"] == "download"


# ---- the page and its assets -----------------------------------------------------------


def test_page_and_assets_are_served_locally(client):
    page = client.get("/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    sources = re.findall(r'(?:src|href)="([^"]+)"', page.text)
    assert not [s for s in sources if "//" in s], "the page must not load anything from another host"
    for src in sources:
        if not src.startswith("data:"):
            assert client.get("/" + src).status_code == 200, src
    plotly = client.get("/vendor/plotly.min.js")
    assert "javascript" in plotly.headers["content-type"] and len(plotly.content) > 1_000_000


# ---- the command -----------------------------------------------------------------------


def test_tune_serves_on_loopback_and_stops(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "pmsm2dof", "tune", PRESET, "--port", "0", "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        url = re.search(r"http://\S+/", line).group(0)
        assert url.startswith("http://127.0.0.1:")
        assert httpx.get(url + "api/controls", timeout=30).json()["name"] == "paper condition 2"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.mark.parametrize("args, param", [
    (["--port", "70000"], "port"),
    (["--host", "no-such-host.invalid"], "host"),
    (["no-such-preset"], "scenario"),
])
def test_tune_bad_arguments_exit_2_with_one_line(args, param):
    proc = subprocess.run([sys.executable, "-m", "pmsm2dof", "tune", "--no-browser", *args],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pmsm2dof: error: {param} = ")


def test_tune_on_a_busy_port_exits_2():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "pmsm2dof", "tune", "--no-browser", "--port", str(port)],
                              capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"pmsm2dof: error: port = {port} is invalid")
