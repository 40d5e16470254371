"""The tuner's suggest action: ``POST /api/suggest`` autotunes the experiment of the controls.

Bounded like the other endpoints: JSON only (415), the Host and Origin checks of the server (421,
403), bad input named (422) before any work, the work of one suggestion bounded (422 naming
``simulation.t_end_s``), one suggestion at a time (429). The suggestion itself is checked by
simulating it again outside the tuner, at both ends of the inertia range.
"""

import math
import warnings

import httpx
import pytest

with warnings.catch_warnings():
    # starlette's TestClient prefers httpx2 and warns on import when it runs on httpx, which it supports
    warnings.filterwarnings("ignore", message="Using `httpx` with `starlette.testclient`")
    from starlette.testclient import TestClient

from pmsm2dof import Scenario, compute_metrics, load_scenario, simulate
from pmsm2dof.ui.tuner import create_app, serving_in_thread
from pmsm2dof.ui.tuner.experiment import SUGGEST_STEPS_MAX

#: A small servo (0.6 Nm at 10 A, J = 1e-4 kg m^2): 2000 rpm, 0.3 Nm load, 1000 rpm in 0.45 s.
SERVO = {
    "name": "tuner servo",
    "motor": {"pole_pairs": 4, "Rs_ohm": 0.5, "Ld_H": 5e-4, "Lq_H": 5e-4, "psi_f_Wb": 0.01, "J_kgm2": 1e-4},
    "limits": {"i_max_A": 10.0, "u_dc_V": 48.0},
    "current_loop": {"model": "dq_pi", "tau_i_s": 1e-3, "Ts_s": 1e-4},
    "speed_controller": {"alpha_radps": 100.0, "zeta": 0.707, "Ts_s": 1e-4},
    "simulation": {"t_end_s": 0.45},
    "reference": [{"t_s": 0.0, "speed_rpm": 2000.0}, {"t_s": 0.3, "speed_rpm": 1000.0}],
    "load": [{"t_s": 0.15, "torque_Nm": 0.3}],
}


@pytest.fixture(scope="module")
def paper_app():
    return create_app(load_scenario("paper-condition-2"))


@pytest.fixture(scope="module")
def client(paper_app):
    with TestClient(paper_app) as c:
        yield c


@pytest.mark.parametrize(
    ("content_type", "content"),
    [("text/plain", b'{"values": {}}'), ("application/x-www-form-urlencoded", b"spec=1"), (None, b"{}")],
)
def test_a_suggestion_not_sent_as_json_answers_415(client, content_type, content):
    headers = {} if content_type is None else {"Content-Type": content_type}
    assert client.post("/api/suggest", content=content, headers=headers).status_code == 415


@pytest.mark.parametrize(
    ("body", "param"),
    [
        ({"value": {}}, "value"),
        ({"values": [1]}, "values"),
        ({"spec": {"bogus": 1}}, "spec.bogus"),
        ({"spec": {"J_range": [2.0, 1.0]}}, "spec.J_range"),
        ({"spec": {"max_overshoot_pct": -1}}, "spec.max_overshoot_pct"),
        ({"spec": {"feedforwards": ["none"]}}, "spec.feedforwards"),
        ({"values": {"speed_controller.zeta": -1}}, "speed_controller.zeta"),
        ({"values": {"load.0.torque_Nm": 0.0}}, "scenario"),  # no load step: nothing to reject
        ({"values": {"simulation.t_end_s": 100.0}}, "simulation.t_end_s"),  # beyond the bound of the work
    ],
)
def test_bad_input_answers_422_naming_it_before_any_work(client, body, param):
    response = client.post("/api/suggest", json=body)
    assert response.status_code == 422, response.text
    assert response.json()["param"] == param


def test_the_bound_is_the_autotuners_runs_times_the_steps_of_one_run(client):
    """paper-condition-2 (dt = 100 us) may be simulated 1656 times (runs_bound, J range 0.5 to 2):
    the experiment may last at most SUGGEST_STEPS_MAX / 1656 steps."""
    err = client.post("/api/suggest", json={"values": {"simulation.t_end_s": 100.0}, "spec": {"J_range": [0.5, 2]}})
    bound_s = SUGGEST_STEPS_MAX / 1656 * 1e-4
    assert f"<= {bound_s:.3g} s" in err.json()["error"]


def test_one_suggestion_at_a_time_answers_429(client, paper_app):
    assert paper_app.state.suggesting.acquire(blocking=False)
    try:
        response = client.post("/api/suggest", json={})
    finally:
        paper_app.state.suggesting.release()
    assert response.status_code == 429 and "one at a time" in response.json()["error"]


def test_suggest_answers_only_its_own_host_and_origin(paper_app):
    with serving_in_thread(paper_app) as url:
        port = int(url.rsplit(":", 1)[1].strip("/"))
        refused_host = httpx.post(url + "api/suggest", json={}, headers={"Host": f"evil.example:{port}"}, timeout=30)
        assert refused_host.status_code == 421
        refused_origin = httpx.post(url + "api/suggest", json={}, headers={"Origin": "http://evil.example"}, timeout=30)
        assert refused_origin.status_code == 403


@pytest.mark.slow
def test_the_suggestion_meets_its_spec_when_simulated_again():
    spec = {"max_overshoot_pct": 5.0, "J_range": [0.5, 2.0]}
    with TestClient(create_app(Scenario.from_dict(SERVO))) as c:
        response = c.post("/api/suggest", json={"values": {"tuner.J_ratio": 1.0}, "spec": spec})
        assert response.status_code == 200, response.text
        s = response.json()
        assert s["feasible"] and not s["violations"]
        assert set(s["values"]) == {
            f"speed_controller.{k}" for k in ("alpha_radps", "zeta", "m", "Ka", "feedforward", "anti_windup")
        }
        # the page applies the values as controls: the tuner runs them
        assert c.post("/api/run", json=s["values"]).status_code == 200
    for J_ratio in (0.5, 2.0):
        scenario = Scenario.from_dict(SERVO).with_overrides(
            s["values"] | {"motor.J_kgm2": J_ratio * 1e-4, "speed_controller.J_kgm2": 1e-4}
        )
        metrics = compute_metrics(simulate(scenario))
        overshoot = max(step["overshoot_pct"]["value"] for step in metrics["reference_steps"])
        assert overshoot <= 5.0
        dip = metrics["load_steps"][0]["speed_dip_rpm"]["value"] / 0.3
        assert dip <= s["worst_case"]["load_dip_rpm_per_Nm"] * (1.0 + 1e-9)
        assert math.isfinite(dip)
