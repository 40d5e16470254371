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
import threading
import time
import tomllib
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import numpy as np
import pandas as pd
import pytest

with warnings.catch_warnings():
    # starlette's TestClient prefers httpx2 and warns on import when it runs on httpx, which it supports
    warnings.filterwarnings("ignore", message="Using `httpx` with `starlette.testclient`")
    from starlette.testclient import TestClient

from pmsm2dof.analysis.design import design
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Simulation
from pmsm2dof.ui.tuner import create_app, serving_in_thread
from pmsm2dof.ui.tuner.app import CLIENT_HEADER
from pmsm2dof.ui.tuner.controls import page_controls
from pmsm2dof.ui.tuner.experiment import (
    DECIMATION_BUCKETS,
    LOG_ROWS_MAX,
    SPANS_MAX,
    STEPS_MAX,
    Tuner,
    bode_data,
    limit_spans,
    minmax_indices,
)
from pmsm2dof.ui.tuner.server import HostCheck

PRESET = "paper-condition-2"
RADPS_PER_RPM = 2.0 * math.pi / 60.0
POST_PATHS = ("/api/run", "/api/download/scenario.toml", "/api/download/header.h", "/api/download/trace.csv")


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
        chunk = y[start : start + width]
        kept = y[keep[(keep >= start) & (keep < start + width)]]
        assert kept.max() == chunk.max() and kept.min() == chunk.min()


def test_minmax_leaves_short_traces_whole():
    assert np.array_equal(minmax_indices(np.arange(50.0), buckets=100), np.arange(50))


def test_limit_spans_hold_each_flag_until_the_next_sample_and_merge_across_the_shortest_gaps():
    t = np.arange(12.0)
    flags = np.array([0, 1, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1], dtype=bool)
    # the flag of sample k holds over [t[k], t[k+1]); the last sample has no interval
    assert limit_spans(t, flags) == [[1, 3], [6, 7], [8, 9]]
    # two spans at most: the gap of 1 s between 7 and 8 closes, the gap of 3 s stays
    assert limit_spans(t, flags, most=2) == [[1, 3], [6, 9]]
    chatter = np.arange(10_000) % 2 == 0  # a flag set every other sample
    spans = limit_spans(np.arange(10_000.0), chatter)
    assert len(spans) == SPANS_MAX and spans[0][0] == 0 and spans[-1][1] == 9_999


# ---- transfer functions of the Bode plot -----------------------------------------------


def eq8_GN(s, J, tau, Kp, Ki):
    """Paper eq (8), load torque to speed, written out."""
    return -(tau * s**2 + s) / (J * tau * s**3 + J * s**2 + Kp * s + Ki)


@pytest.mark.parametrize("J_ratio", [1.0, 0.5, 2.5])
def test_load_response_is_eq8_with_the_true_inertia(J_ratio):
    d = design(0.4, 0.5, 0.2887, m=1.0, tau_i_s=0.05, feedforward="lowpass")
    _, GN = d.on_plant(J_ratio * 0.4)
    w = np.logspace(-3, 3, 50)
    got = np.asarray(GN(1j * w)).reshape(-1)
    want = eq8_GN(1j * w, J_ratio * 0.4, 0.05, d.Kp, d.Ki)
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_full_feedforward_tracks_as_eq10_on_the_design_inertia():
    d = design(0.4, 0.5, 0.2887, m=1.7, tau_i_s=0.05, feedforward="full")
    Gx, _ = d.on_plant(0.4)
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
    assert set(specs) == set(Tuner(base).keys)
    assert specs["speed_controller.alpha_radps"]["value"] == data["speed_controller"]["alpha_radps"]
    assert specs["speed_controller.Ka"]["value"] is None
    for name, value_key in (("reference", "speed_rpm"), ("load", "torque_Nm")):
        for i, entry in enumerate(data[name]):
            assert specs[f"{name}.{i}.{value_key}"]["value"] == entry[value_key]
            assert specs[f"{name}.{i}.t_s"]["value"] == entry["t_s"]
    assert specs["tuner.J_ratio"]["value"] == 1.0
    for spec in specs.values():
        if spec["kind"] == "slider":
            assert spec["min"] < spec["max"]
        else:
            assert spec["value"] in spec["choices"]


def test_inertia_ratio_changes_the_plant_not_the_design(base):
    scenario = Tuner(base).scenario({"tuner.J_ratio": 2.0, "speed_controller.alpha_radps": 0.8})
    data = scenario.data
    assert data["motor"]["J_kgm2"] == pytest.approx(2.0 * base.data["motor"]["J_kgm2"])
    assert data["speed_controller"]["J_kgm2"] == base.data["motor"]["J_kgm2"]
    assert data["speed_controller"]["alpha_radps"] == 0.8
    assert data["reference"] == base.data["reference"]
    assert data["load"] == base.data["load"]


def test_every_reference_and_load_entry_is_a_control():
    """Paper condition 1 has two reference entries and no load: both entries are controls, and
    the tuner runs them as they are, adding none."""
    base = load_scenario("paper-condition-1")
    tuner = Tuner(base)
    specs = {c["key"]: c for g in page_controls(base)["groups"] for c in g["controls"]}
    entries = [specs[f"reference.{i}.{k}"]["value"] for i in (0, 1) for k in ("t_s", "speed_rpm")]
    assert entries == [0.0, 500.0, 5.0, 200.0]
    assert not [key for key in specs if key.startswith("load.")]
    data = tuner.scenario({"reference.1.speed_rpm": 300.0}).data
    assert [(e["t_s"], e["speed_rpm"]) for e in data["reference"]] == [(0.0, 500.0), (5.0, 300.0)]
    assert data["load"] == []


# ---- /api/run --------------------------------------------------------------------------


def test_run_returns_decimated_traces_that_keep_the_peaks(client):
    out = run(client, speed_controller__feedforward="none", speed_controller__anti_windup="none")
    for trace in out["traces"].values():
        assert len(trace["t"]) == len(trace["y"]) <= 2 * DECIMATION_BUCKETS + 2
        assert np.all(np.diff(trace["t"]) > 0)
    # the plotted overshoot is the table's: decimation kept the peak before the load step
    speed = out["traces"]["speed_rpm"]
    t, y = np.asarray(speed["t"]), np.asarray(speed["y"])
    plotted_pct = 100.0 * (y[t < out["detail"]["t_s"]].max() - 500.0) / 500.0
    table = {m["key"]: m for m in out["metrics"]}
    assert table["reference_steps.0.overshoot_pct"]["value"] == pytest.approx(plotted_pct, abs=0.05)
    assert table["load_steps.0.speed_dip_rpm"]["value"] > 0
    assert out["design"]["Kp"] == pytest.approx(0.4 * 0.5)
    assert out["server_ms"] > 0


def test_saturated_start_accelerates_at_the_torque_limit_over_the_true_inertia(client, base):
    motor = base.data["motor"]
    T_max_Nm = 1.5 * motor["pole_pairs"] * motor["psi_f_Wb"] * base.data["limits"]["i_max_A"]
    for J_ratio in (1.0, 2.0):
        out = run(
            client, tuner__J_ratio=J_ratio, speed_controller__feedforward="none", speed_controller__anti_windup="none"
        )
        t, y = np.asarray(out["traces"]["speed_rpm"]["t"]), np.asarray(out["traces"]["speed_rpm"]["y"])
        # 0.4 s .. 1.0 s: the 1DOF PI commands the limit (its proportional part alone asks for
        # Kp * 52 rad/s = 10.5 Nm > T_max) and the current loop (tau_i = 0.05 s) has settled there
        window = (t > 0.4) & (t < 1.0)
        a = np.polyfit(t[window], y[window] * RADPS_PER_RPM, 1)[0]
        assert a == pytest.approx(T_max_Nm / (J_ratio * motor["J_kgm2"]), rel=0.02)


def test_settled_load_is_carried_by_the_q_current(client, base):
    motor = base.data["motor"]
    out = run(
        client,
        simulation__t_end_s=40.0,
        load__0__torque_Nm=5.0,
        load__0__t_s=10.0,
        reference__1__speed_rpm=500.0,
        speed_controller__alpha_radps=1.0,
    )
    iq = out["traces"]["iq_ref_A"]["y"][-1]
    assert iq == pytest.approx(5.0 / (1.5 * motor["pole_pairs"] * motor["psi_f_Wb"]), rel=0.01)
    assert out["traces"]["speed_rpm"]["y"][-1] == pytest.approx(500.0, abs=1.0)


def test_anti_windup_lowers_the_overshoot_of_a_saturated_step(client):
    """Paper section 4.1: without anti-windup the 1DOF PI overshoots far more (Fig. 8)."""

    def overshoot(mode):
        rows = run(client, speed_controller__anti_windup=mode, speed_controller__feedforward="none")["metrics"]
        return {m["key"]: m["value"] for m in rows}["reference_steps.0.overshoot_pct"]

    assert overshoot("none") > 1.5 * overshoot("back_calculation") > 0


def test_both_reference_steps_of_paper_condition_1_run_and_are_measured():
    """Condition 1 steps the reference to 500 rpm at 0 s and to 200 rpm at 5 s: both run.

    Truth, eq 10: the 2DOF lowpass design (m = 1) tracks the 300 rpm step down as
    m alpha / (s + m alpha), from the speed w5 it has at 5 s (still approaching 500 rpm): rise time
    10-90 % ln(9) / (m alpha) = 4.39 s, and at 10 s the speed is (w5 - 200 rpm) exp(-2.5) above
    200 rpm, never below it (the current loop, tau_i = 0.05 s, lags by a little). The torque it
    asks for, J m alpha 300 rpm = 6.3 Nm, stays below the current limit 1.5 p psi_f i_max =
    9.12 Nm, so the loop is linear.
    """
    with TestClient(create_app(load_scenario("paper-condition-1"))) as c:
        out = run(c)
    ref = out["traces"]["speed_ref_rpm"]
    t, r = np.asarray(ref["t"]), np.asarray(ref["y"])
    assert np.all(r[(t > 0.01) & (t < 4.99)] == 500.0) and np.all(r[t > 5.01] == 200.0)
    t_w, w = np.asarray(out["traces"]["speed_rpm"]["t"]), np.asarray(out["traces"]["speed_rpm"]["y"])
    w5 = np.interp(5.0, t_w, w)
    assert np.interp(9.99, t_w, w) == pytest.approx(200.0 + (w5 - 200.0) * math.exp(-0.5 * 4.99), abs=2.0)
    assert w[t_w > 5.0].min() > 200.0
    table = {m["key"]: m for m in out["metrics"]}
    groups = [m["group"] for m in out["metrics"]]
    assert "speed reference at 5 s: 500 \u2192 200 rpm" in groups
    assert out["detail"]["title"] == "Reference step: 500 \u2192 200 rpm at 5 s"
    assert table["reference_steps.1.rise_time_s"]["value"] == pytest.approx(math.log(9) / 0.5, rel=0.02)
    assert "did not reach the reference" in table["reference_steps.1.overshoot_pct"]["reason"]
    assert table["reference_steps.1.current_limit_time_s"]["value"] == 0.0
    assert table["reference_steps.0.current_limit_time_s"]["value"] > 0.0  # the 500 rpm start does saturate


def test_the_voltage_limit_is_plotted_timed_and_warned_about():
    """At u_dc = 60 V the inverter's range u_dc / sqrt(3) = 34.6 V is below the back-EMF of the
    500 rpm reference, p w_m psi_f = 41.9 V: by eq 1 in steady state (id = 0) the range caps the
    speed at u_dc / (sqrt(3) p psi_f) = 413.5 rpm, and the drive runs at its voltage limit."""
    base = load_scenario(PRESET).with_overrides({"limits.u_dc_V": 60.0})
    motor = base.data["motor"]
    u_max_V = 60.0 / math.sqrt(3.0)
    w_cap_rpm = u_max_V / (motor["pole_pairs"] * motor["psi_f_Wb"]) / RADPS_PER_RPM
    with TestClient(create_app(base)) as c:
        out = run(c)
    traces = out["traces"]
    np.testing.assert_allclose(traces["u_max_V"]["y"], u_max_V, rtol=1e-12)
    assert max(traces["u_dq_V"]["y"]) <= u_max_V * (1 + 1e-6)
    peak_rpm = max(y for t, y in zip(traces["speed_rpm"]["t"], traces["speed_rpm"]["y"]) if t < 7.0)
    assert 0.9 * w_cap_rpm < peak_rpm <= w_cap_rpm
    table = {m["key"]: m for m in out["metrics"]}
    limited_s = table["run.voltage_limit_time_s"]["value"]
    assert limited_s > 3.0
    assert sum(b - a for a, b in out["spans"]["voltage"]) >= limited_s
    (warning,) = out["warnings"]
    assert warning.startswith("Voltage limit") and f"{limited_s:.4g} s" in warning


def test_a_drive_within_its_voltage_range_has_no_voltage_warning(client):
    out = run(client)
    assert {m["key"]: m["value"] for m in out["metrics"]}["run.voltage_limit_time_s"] == 0.0
    assert out["spans"]["voltage"] == [] and out["warnings"] == []
    assert max(out["traces"]["u_dq_V"]["y"]) < 540.0 / math.sqrt(3.0)


# ---- the work one request may ask for --------------------------------------------------


def test_a_run_beyond_the_work_bound_answers_422_naming_the_key_and_the_bound(client, base):
    """10000 s at the 100 us current loop would be 1e8 integration steps; the bound is 1e7 (1000 s)."""
    assert STEPS_MAX * base.data["current_loop"]["Ts_s"] == pytest.approx(1000.0)
    for path in ("/api/run", "/api/download/trace.csv", "/api/download/header.h"):
        response = client.post(path, json={"simulation.t_end_s": 10000.0})
        assert response.status_code == 422, path
        err = response.json()
        assert err["param"] == "simulation.t_end_s"
        assert "simulation.t_end_s = 10000.0 is invalid" in err["error"] and "<= 1000 s" in err["error"]


@pytest.mark.slow
def test_a_run_at_the_bound_logs_at_most_log_rows_max_rows(client):
    """1000 s of 1 ms samples: 1000001 samples, logged every 201st (ceil(1000001 / 5000))."""
    out = run(client, simulation__t_end_s=1000.0)
    assert out["log"] == {"every": 201, "period_s": pytest.approx(0.201), "rows": 4976}
    assert out["log"]["rows"] <= LOG_ROWS_MAX
    assert out["traces"]["speed_rpm"]["t"][-1] == pytest.approx(4975 * 0.201)


BAD_VALUES = [
    ("speed_controller.alpha_radps", -1.0),
    ("speed_controller.alpha_radps", "fast"),
    ("speed_controller.zeta", 0),
    ("speed_controller.m", 2.0),  # lowpass feedforward is eq (13): m = 1
    ("speed_controller.Ka", -0.5),
    ("speed_controller.feedforward", "bogus"),
    ("speed_controller.anti_windup", True),
    ("speed_controller.method", "zoh"),
    ("speed_controller.Ts_s", 1.5e-4),  # not an integer multiple of the 1e-4 s current loop
    ("simulation.t_end_s", 1e9),
    ("tuner.J_ratio", 0.0),
    ("reference.0.speed_rpm", None),
    ("reference.1.t_s", 0.0),  # not after reference.0.t_s
    ("load.0.torque_Nm", "8 Nm"),
    ("load.0.t_s", 20.0),  # after the end of the 15 s run
    ("motor.J_kgm2", 1.0),  # not a control of the tuner
    ("reference.2.speed_rpm", 300.0),  # the tuner keeps the preset's entries, it adds none
]


@pytest.mark.parametrize("key, value", BAD_VALUES)
def test_bad_value_answers_422_naming_the_key(client, key, value):
    for path in POST_PATHS:
        response = client.post(path, json={key: value})
        assert response.status_code == 422, (path, response.text)
        err = response.json()
        assert err["param"] == key
        assert key in err["error"] and "valid" in err["error"]


def test_a_run_that_stops_answers_422_with_the_reason(client, base):
    """A load of -1000 Nm drives the motor past the engine's overspeed bound (twice the no-load
    speed u_dc / (sqrt(3) p psi_f)): the engine stops and the page gets the reason, not a trace."""
    motor = base.data["motor"]
    bound_rpm = (
        2 * base.data["limits"]["u_dc_V"] / (math.sqrt(3) * motor["pole_pairs"] * motor["psi_f_Wb"]) / (RADPS_PER_RPM)
    )
    response = client.post("/api/run", json={"load.0.torque_Nm": -1000.0})
    assert response.status_code == 422
    err = response.json()
    assert err["param"] is None
    assert "stopped at t =" in err["error"] and f"{bound_rpm:.6g} rpm" in err["error"]


def test_non_finite_json_number_is_rejected(client):
    response = client.post(
        "/api/run", content=b'{"speed_controller.alpha_radps": NaN}', headers={"Content-Type": "application/json"}
    )
    assert response.status_code == 422
    assert response.json()["param"] == "speed_controller.alpha_radps"


@pytest.mark.parametrize("body", [b"not json", b"[1, 2]", b'"alpha"'])
def test_body_that_is_not_an_object_answers_422(client, body):
    response = client.post("/api/run", content=body, headers={"Content-Type": "application/json"})
    assert response.status_code == 422
    assert response.json()["param"] == "body"


# ---- what the server answers to ----------------------------------------------------------


@pytest.mark.parametrize("path", POST_PATHS)
@pytest.mark.parametrize(
    "content_type, content",
    [
        ("text/plain", b'{"simulation.t_end_s": 20.0}'),  # a cross-site fetch without preflight
        ("application/x-www-form-urlencoded", b"speed_controller.alpha_radps=0.6"),  # a cross-site form
        ("multipart/form-data; boundary=x", b"--x--\r\n"),
        (None, b"{}"),
    ],
)
def test_a_body_not_sent_as_json_answers_415(client, path, content_type, content):
    headers = {} if content_type is None else {"Content-Type": content_type}
    response = client.post(path, content=content, headers=headers)
    assert response.status_code == 415
    err = response.json()
    assert err["param"] == "Content-Type" and "application/json" in err["error"]


def test_json_with_a_charset_is_json(client):
    response = client.post("/api/run", content=b"{}", headers={"Content-Type": "application/json; charset=utf-8"})
    assert response.status_code == 200


@pytest.fixture(scope="module")
def served(base):
    """The tuner on a real uvicorn server on loopback: (url, port, app)."""
    app = create_app(base)
    with serving_in_thread(app) as url:
        yield url, int(url.rsplit(":", 1)[1].strip("/")), app


REFUSED_HOSTS = [
    "evil.example:{port}",
    "evil.example",
    "127.0.0.1.nip.io:{port}",  # names that resolve to 127.0.0.1: what DNS rebinding makes of a site
    "7f000001.c0a80001.rbndr.us:{port}",
    "localtest.me:{port}",
    "127.0.0.1:{other}",  # right address, port of another service
    "localhost:{other}",
    "127.0.0.1",  # no port: port 80
    "user@127.0.0.1:{port}",
]


@pytest.mark.parametrize("host", REFUSED_HOSTS)
def test_a_request_for_another_host_answers_421(served, host):
    url, port, _ = served
    host = host.format(port=port, other=port + 1)
    for method, path in (("GET", ""), ("GET", "api/controls"), ("POST", "api/run")):
        response = httpx.request(
            method, url + path, headers={"Host": host}, json={} if method == "POST" else None, timeout=30
        )
        assert response.status_code == 421, (host, path)
        assert repr(host) in response.text and f"127.0.0.1:{port}" in response.text


@pytest.mark.parametrize("host", ["127.0.0.1:{port}", "localhost:{port}", "LocalHost:{port}"])
def test_a_request_for_this_server_is_answered(served, host):
    url, port, _ = served
    response = httpx.get(url + "api/controls", headers={"Host": host.format(port=port)}, timeout=30)
    assert response.status_code == 200 and response.json()["name"] == "paper condition 2"


@pytest.mark.parametrize(
    "origin, status",
    [
        ("http://evil.example", 403),
        ("null", 403),  # a sandboxed page or a file
        ("http://127.0.0.1:{other}", 403),
        ("https://127.0.0.1:{port}", 403),
        ("http://127.0.0.1:{port}", 200),
        ("http://localhost:{port}", 200),
    ],
)
def test_a_post_from_another_origin_answers_403(served, origin, status):
    url, port, _ = served
    origin = origin.format(port=port, other=port + 1)
    response = httpx.post(url + "api/download/scenario.toml", json={}, headers={"Origin": origin}, timeout=30)
    assert response.status_code == status, origin
    if status == 403:
        assert repr(origin) in response.text


def test_a_server_on_all_interfaces_also_answers_its_addresses_but_no_name():
    check = HostCheck(None, {"127.0.0.1", "localhost", "0.0.0.0"}, 8765, any_address=True)
    assert check.accepts("192.168.1.20:8765") and check.accepts("[fe80::1]:8765")
    assert not check.accepts("192.168.1.20:8766")
    assert not check.accepts("attacker.example:8765")


class EngineWatch:
    """Counts the engine's C calls (``Simulation.advance``) that run at the same time, and the
    samples each run advanced."""

    def __init__(self, advance):
        self._advance = advance
        self._lock = threading.Lock()
        self.running = 0
        self.peak = 0
        self.runs = {}  # engine run -> samples advanced

    def advance(self, run, n):
        with self._lock:
            self.running += 1
            self.peak = max(self.peak, self.running)
            self.runs.setdefault(run, 0)
        try:
            return self._advance(run, n)
        finally:
            with self._lock:
                self.running -= 1
                self.runs[run] += n


@pytest.fixture
def watch(monkeypatch):
    watch = EngineWatch(Simulation.advance)
    monkeypatch.setattr(Simulation, "advance", lambda run, n: watch.advance(run, n))
    return watch


def post_run(url, values, client_id):
    return httpx.post(url + "api/run", json=values, headers={CLIENT_HEADER: client_id}, timeout=120)


def wait_until(condition, timeout_s=60.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.002)


def test_a_newer_run_of_a_client_supersedes_its_older_one(served, watch):
    """The older run stops between two C calls (it does not run to its end) and answers 409."""
    url, _, app = served
    with ThreadPoolExecutor(1) as pool:
        older = pool.submit(
            post_run, url, {"simulation.t_end_s": 1000.0, "speed_controller.alpha_radps": 0.51}, "tab-1"
        )
        wait_until(lambda: watch.runs)  # the older run is simulating
        newer = post_run(url, {"speed_controller.alpha_radps": 0.52}, "tab-1")
        older = older.result()
    assert newer.status_code == 200
    assert older.status_code == 409 and "superseded" in older.json()["error"]
    long_run = next(run for run in watch.runs if run.n_samples == 1_000_001)
    assert watch.runs[long_run] < long_run.n_samples
    assert watch.peak == 1
    assert app.state.slots.clients() == 0  # nothing kept for the client once answered


@pytest.mark.slow
def test_concurrent_runs_of_one_client_simulate_one_at_a_time(served, watch):
    """A run, then three more sent together while it simulates: the first is superseded, at
    least the last to arrive is answered, and no two of them simulate at once."""
    url, _, _ = served

    def send(k):
        return post_run(url, {"simulation.t_end_s": 600.0, "speed_controller.alpha_radps": 0.53 + 0.01 * k}, "tab-2")

    with ThreadPoolExecutor(4) as pool:
        first = pool.submit(send, 0)
        wait_until(lambda: watch.runs)
        others = [pool.submit(send, k) for k in (1, 2, 3)]
        codes = [f.result().status_code for f in others]
        assert first.result().status_code == 409
    assert watch.peak == 1
    assert set(codes) <= {200, 409} and 200 in codes


@pytest.mark.slow
def test_two_clients_simulate_side_by_side(served, watch):
    url, _, _ = served
    with ThreadPoolExecutor(2) as pool:
        first = pool.submit(post_run, url, {"simulation.t_end_s": 800.0, "speed_controller.alpha_radps": 0.61}, "tab-a")
        wait_until(lambda: watch.runs)
        second = pool.submit(
            post_run, url, {"simulation.t_end_s": 800.0, "speed_controller.alpha_radps": 0.62}, "tab-b"
        )
        assert first.result().status_code == 200 and second.result().status_code == 200
    assert watch.peak == 2


@pytest.mark.slow
def test_a_download_waits_for_the_run_of_its_client_and_is_not_superseded(served, watch):
    url, _, _ = served
    headers = {CLIENT_HEADER: "tab-3"}
    with ThreadPoolExecutor(1) as pool:
        download = pool.submit(
            httpx.post,
            url + "api/download/trace.csv",
            timeout=120,
            headers=headers,
            json={"simulation.t_end_s": 800.0, "speed_controller.alpha_radps": 0.71},
        )
        wait_until(lambda: watch.runs)
        run_answer = post_run(url, {"speed_controller.alpha_radps": 0.72}, "tab-3")
        download = download.result()
    assert download.status_code == 200 and run_answer.status_code == 200
    assert len(download.text.splitlines()) == 4969 + 1  # 800001 samples logged every 161st, and the header
    assert watch.peak == 1


def process_memory_kib(pid):
    fields = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
    return {key: int(fields[key].split()[0]) for key in ("VmRSS", "VmHWM")}


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the memory of the server in /proc")
def test_three_runs_at_the_bound_keep_the_server_memory_small():
    """Three clients each ask for the longest run the tuner allows, at the same time: the server
    grows by less than 100 MiB at its peak and keeps less than 30 MiB after (a log of every 1 ms
    sample of 1000 s alone is 150 MB)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "pmsm2dof", "tune", PRESET, "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        url = re.search(r"http://\S+/", proc.stdout.readline()).group(0)
        with ThreadPoolExecutor(3) as pool:  # warm-up: imports, worker threads, first runs
            assert all(
                f.result().status_code == 200
                for f in [pool.submit(post_run, url, {"simulation.t_end_s": 20.0 + k}, f"warm-{k}") for k in range(3)]
            )
            before = process_memory_kib(proc.pid)
            answers = [pool.submit(post_run, url, {"simulation.t_end_s": 1000.0 - k}, f"client-{k}") for k in range(3)]
            assert all(f.result().status_code == 200 for f in answers)
        after = process_memory_kib(proc.pid)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    assert after["VmHWM"] - before["VmRSS"] < 100 * 1024
    assert after["VmRSS"] - before["VmRSS"] < 30 * 1024


# ---- downloads -------------------------------------------------------------------------


def test_scenario_download_loads_back_to_the_run_scenario(client, base, tmp_path):
    values = {
        "speed_controller.alpha_radps": 0.7,
        "speed_controller.anti_windup": "clamping",
        "tuner.J_ratio": 1.5,
        "load.0.torque_Nm": -3.0,
    }
    response = client.post("/api/download/scenario.toml", json=values)
    assert response.status_code == 200
    assert 'filename="paper-condition-2-tuned.toml"' in response.headers["content-disposition"]
    tree = tomllib.loads(response.text)
    assert tree["speed_controller"]["alpha_radps"] == 0.7
    assert tree["load"] == [{"t_s": 7.0, "torque_Nm": -3.0}]
    path = tmp_path / "tuned.toml"
    path.write_text(response.text)
    assert load_scenario(path) == Tuner(base).scenario(values)


def test_header_download_holds_the_posted_design(client):
    response = client.post(
        "/api/download/header.h",
        json={"speed_controller.alpha_radps": 0.75, "speed_controller.method": "backward_euler"},
    )
    assert response.status_code == 200
    text = response.text
    assert re.search(r"\.alpha_radps = 0\.75f,", text)
    assert ".method = P2D_BACKWARD_EULER," in text
    assert '#include "pmsm2dof/speed.h"' in text


@pytest.mark.slow
@pytest.mark.parametrize("feedforward", ["lowpass", "none"])
def test_header_download_of_the_paper_design_sampled_at_100_us(client, feedforward):
    """The paper's design (alpha = 0.5 rad/s) at Ts = 1e-4 s: slow against the sampling, but stable."""
    response = client.post(
        "/api/download/header.h", json={"speed_controller.Ts_s": 1e-4, "speed_controller.feedforward": feedforward}
    )
    assert response.status_code == 200, response.text
    assert "Ts_s        = 0.0001 s" in response.text


def test_trace_download_is_the_logged_run(client, base):
    """The trace is the run the page draws: 12001 speed samples of 1 ms logged every 3rd (LOG_ROWS_MAX = 5000)."""
    response = client.post("/api/download/trace.csv", json={"simulation.t_end_s": 12.0})
    assert response.status_code == 200
    frame = pd.read_csv(io.StringIO(response.text))
    Ts = base.data["speed_controller"]["Ts_s"]
    assert LOG_ROWS_MAX == 5000
    assert {"t_s", "speed_rpm", "speed_ref_rpm", "iq_ref_A", "voltage_limited"} <= set(frame.columns)
    assert len(frame) == 4001
    assert frame["t_s"].iloc[-1] == pytest.approx(12.0, abs=Ts / 2)
    np.testing.assert_allclose(np.diff(frame["t_s"]), 3 * Ts, rtol=1e-6)


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


@pytest.mark.slow
def test_tune_serves_on_loopback_and_stops(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-m", "pmsm2dof", "tune", PRESET, "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        url = re.search(r"http://\S+/", line).group(0)
        assert url.startswith("http://127.0.0.1:")
        assert httpx.get(url + "api/controls", timeout=30).json()["name"] == "paper condition 2"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.mark.parametrize(
    "args, param",
    [
        (["--port", "70000"], "port"),
        (["--host", "no-such-host.invalid"], "host"),
        (["no-such-preset"], "scenario"),
    ],
)
@pytest.mark.slow
def test_tune_bad_arguments_exit_2_with_one_line(args, param):
    proc = subprocess.run(
        [sys.executable, "-m", "pmsm2dof", "tune", "--no-browser", *args], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pmsm2dof: error: {param} = ")


@pytest.mark.slow
def test_tune_on_a_busy_port_exits_2():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        proc = subprocess.run(
            [sys.executable, "-m", "pmsm2dof", "tune", "--no-browser", "--port", str(port)],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"pmsm2dof: error: port = {port} is invalid")


@pytest.mark.parametrize(
    ("args", "param"),
    [
        (["--link", "socket://127.0.0.1:1"], "--a2l"),  # a drive of its own needs its firmware's A2L file
        (["--link", "virtual", "--a2l", __file__], "--a2l"),  # the virtual drive is built here
        (["--link", "socket://127.0.0.1:1", "--a2l", __file__], "--a2l"),  # not an A2L file
        (["--link", "socket://127.0.0.1:1", "--a2l", "no-such.a2l"], "--a2l"),
        (["--link", "virtual", "--host", "0.0.0.0"], "host"),  # drive mode on loopback only
    ],
)
def test_tune_link_bad_arguments_exit_2_with_one_line_before_any_build(args, param, capsys):
    from pmsm2dof.ui.cli import main

    servo = Path(__file__).resolve().parents[1] / "examples" / "firmware" / "small-servo-20k.toml"
    code = main(["tune", "--no-browser", str(servo), *args])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pmsm2dof: error: {param} = "), err
