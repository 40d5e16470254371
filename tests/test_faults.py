"""Fault scenarios: a stall, a DC-link sag and speed-sensor faults, with each anti-windup mode.

Truth from outside the engine and the controller:

- the mechanics of eq (1)-(2): with the current vector at its limit the shaft accelerates at
  (T_max - T_load) / J, T_max = 1.5 p psi_f i_max (amplitude-invariant torque, surface PMSM);
- the speed PI's integrator of eq (14) and Fig. 5, written out per sample by hand: without
  anti-windup x[k] = x[k-1] + Ki Ts e[k]; clamping holds x while the limit is active and e pushes
  into it; back-calculation with Ka = 1/Kp moves x[k] = (1 - c) x[k-1] + c x* with c = Ki Ka Ts
  toward x* = u_sat - T_ff - e Ki Ts / 2 (Tustin, b_e0 = Kp + Ki Ts / 2);
- the lowpass feedforward of eq (13) at a constant reference: its DC gain, T_ff = -Ki / alpha w_ref;
- the fault windows of the scenario for the readings and the DC link, and the inverter's range
  u_dc / sqrt(3) (space-vector modulation).
"""

import json
import math

import numpy as np
import pytest

from pmsm2dof.core import ANTI_WINDUPS
from pmsm2dof.core.bindings import lib
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.metrics import compute_metrics
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Simulation, simulate
from pmsm2dof.studies.faults import FAULT_PRESETS, fault_figures, run_faults
from pmsm2dof.ui.cli import main
from pmsm2dof.ui.report.render import _fault_blocks

RADPS_PER_RPM = math.pi / 30.0
PRESETS = ["fault-stall", "fault-dc-link-sag", "fault-sensor-hold", "fault-sensor-zero", "fault-sensor-spike"]
_RUNS = {}


def run(preset, anti_windup, **overrides):
    """The preset with that anti-windup mode (and dotted-key overrides), simulated once per module."""
    key = (preset, anti_windup, repr(sorted(overrides.items(), key=str)))
    if key not in _RUNS:
        scenario = load_scenario(preset).with_overrides({"speed_controller.anti_windup": anti_windup, **overrides})
        _RUNS[key] = simulate(scenario)
    return _RUNS[key]


def drive(result):
    """Design figures of the run's scenario by eq (9), (13), (14) and the torque limit."""
    d = result.scenario.data
    m, sc = d["motor"], d["speed_controller"]
    Kp = sc["J_kgm2"] * sc["alpha_radps"]
    Ki = sc["J_kgm2"] * (sc["alpha_radps"] / (2 * sc["zeta"])) ** 2
    Ts = sc["Ts_s"]
    return {
        "Kp": Kp,
        "Ki": Ki,
        "Ts": Ts,
        "Ka": 1.0 / Kp,
        "b_e0": Kp + Ki * Ts / 2,
        "J": m["J_kgm2"],
        "alpha": sc["alpha_radps"],
        "i_max": d["limits"]["i_max_A"],
        "T_max": 1.5 * m["pole_pairs"] * m["psi_f_Wb"] * d["limits"]["i_max_A"],
        "w_ref": d["reference"][0]["speed_rpm"] * RADPS_PER_RPM,
    }


def error_radps(result):
    """The error the speed controller saw: reference minus reading [rad/s]."""
    return (result.speed_ref_rpm - result.speed_meas_rpm) * RADPS_PER_RPM


def rows(result, t0, t1):
    return (result.t_s >= t0 - 1e-9) & (result.t_s < t1 - 1e-9)


# --- every fault, every mode: finite, within the limits ----------------------------------------


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
@pytest.mark.parametrize("preset", PRESETS)
def test_fault_runs_are_finite_and_respect_the_limits(preset, anti_windup):
    r = run(preset, anti_windup)
    for name in r.signals:
        assert np.all(np.isfinite(getattr(r, name))), name
    d = drive(r)
    assert np.all(np.hypot(r.id_ref_A, r.iq_ref_A) <= d["i_max"] * (1 + 1e-6))
    assert np.all(np.abs(r.torque_ref_Nm) <= d["T_max"] * (1 + 1e-6))
    # the inverter's range at the DC link of each period, sagged or not
    assert np.all(np.hypot(r.ud_V, r.uq_V) <= r.u_dc_V / math.sqrt(3) * (1 + 1e-9))
    assert r.t_s[-1] == pytest.approx(r.scenario.data["simulation"]["t_end_s"])


# --- stall: a load above the current limit -----------------------------------------------------


def stall_times(r):
    jam, release = r.scenario.data["load"]
    return jam["t_s"], jam["torque_Nm"], release["t_s"]


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
def test_stall_speed_falls_at_the_rate_the_current_limit_allows(anti_windup):
    r = run("fault-stall", anti_windup)
    d = drive(r)
    t_jam, T_jam, t_release = stall_times(r)
    assert T_jam > d["T_max"]
    # saturated from some time after the jam until the release, at the full current vector
    first = np.argmax(r.saturated & (r.t_s >= t_jam))
    t_sat = r.t_s[first]
    assert t_jam < t_sat < t_release
    window = rows(r, t_sat, t_release)
    assert np.all(r.saturated[window])
    assert np.allclose(np.hypot(r.id_ref_A, r.iq_ref_A)[window], d["i_max"], rtol=1e-6)
    # once the current loop has settled (10 tau_i), J dw/dt = T_max - T_load
    settled = rows(r, t_sat + 10 * r.scenario.data["current_loop"]["tau_i_s"], t_release)
    slope = np.polyfit(r.t_s[settled], r.w_m_radps[settled], 1)[0]
    assert slope == pytest.approx((d["T_max"] - T_jam) / d["J"], rel=1e-3)
    # the jam brings the drive to about standstill
    assert abs(r.speed_rpm[np.searchsorted(r.t_s, t_release)]) < 0.1 * r.speed_ref_rpm[0]


def test_stall_integrator_stays_bounded_with_anti_windup_and_winds_up_without():
    """Bound shared by back-calculation and clamping: while unsaturated x <= T_max - T_ff - b_e0 e,
    while saturated x moves toward (back-calculation) or holds below (clamping) T_max - T_ff, so
    x <= T_max + Ki/alpha w_ref + b_e0 max|e| at every sample (T_ff = -Ki/alpha w_ref, eq 13)."""
    base = run("fault-stall", "back_calculation")
    d = drive(base)
    peaks = {}
    for aw in ANTI_WINDUPS:
        r = run("fault-stall", aw)
        bound = d["T_max"] + d["Ki"] / d["alpha"] * d["w_ref"] + d["b_e0"] * np.max(np.abs(error_radps(r)))
        peaks[aw] = (np.max(r.x_i_Nm), bound)
    for aw in ("back_calculation", "clamping"):
        assert peaks[aw][0] <= peaks[aw][1] + 1e-4
    assert peaks["none"][0] > peaks["none"][1] + 10.0


def test_stall_back_calculation_holds_the_integrator_at_its_fixed_point():
    """Saturated, x contracts toward x* = T_max - T_ff - e Ki Ts / 2 by (1 - c) per sample (u* then
    just cancels e); x* itself drifts by Ki Ts / 2 de/dt, a few mNm over the time constant 1/c."""
    r = run("fault-stall", "back_calculation")
    d = drive(r)
    t_jam, _, t_release = stall_times(r)
    first = np.argmax(r.saturated & (r.t_s >= t_jam))
    last = np.nonzero(r.saturated & (r.t_s > t_release))[0][-1]
    assert np.all(r.saturated[first : last + 1])
    c = d["Ki"] * d["Ka"] * d["Ts"]
    n = last - first
    assert n * c > 5  # saturated for more than five time constants of the contraction
    x_star = d["T_max"] + d["Ki"] / d["alpha"] * d["w_ref"] - error_radps(r) * d["Ki"] * d["Ts"] / 2
    start = abs(x_star[first] - r.x_i_Nm[first - 1])
    assert start > 1.0
    assert abs(r.x_i_Nm[last] - x_star[last]) <= (1 - c) ** n * start + 5e-3


def test_stall_clamping_holds_and_none_integrates_every_error():
    d = drive(run("fault-stall", "none"))
    r = run("fault-stall", "clamping")
    e = error_radps(r)
    pushing = r.saturated[1:] & (e[1:] > 0) & (r.torque_unsat_Nm[1:] > d["T_max"])
    assert pushing.sum() > 1000
    assert np.all(np.diff(r.x_i_Nm)[pushing] == 0.0)
    r = run("fault-stall", "none")
    # x[k] - x[k-1] = Ki Ts e[k], to the float32 rounding of an integrator near 100 Nm
    assert np.allclose(np.diff(r.x_i_Nm), d["Ki"] * d["Ts"] * error_radps(r)[1:], rtol=0, atol=2e-5)


def test_stall_recovery_is_reported_and_anti_windup_recovers_sooner():
    """Recovery after the release (metrics, load step at the release): no faster than the full
    torque can bring the shaft back, T_max / J; without anti-windup the wound-up integrator
    overshoots several times further and takes longer, if it settles at all in the run."""
    figures = {}
    for aw in ANTI_WINDUPS:
        r = run("fault-stall", aw)
        d = drive(r)
        _, _, t_release = stall_times(r)
        step = compute_metrics(r)["load_steps"][1]
        assert step["t_s"] == t_release
        overshoot = np.max(r.speed_rpm[r.t_s > t_release]) - r.speed_ref_rpm[-1]
        w_release = r.w_m_radps[np.searchsorted(r.t_s, t_release)]
        figures[aw] = (step["recovery_time_s"]["value"], overshoot, (d["w_ref"] - w_release) * d["J"] / d["T_max"])
    for aw in ("back_calculation", "clamping"):
        recovery, overshoot, fastest = figures[aw]
        assert recovery is not None and fastest < recovery < 25.0
        assert figures["none"][1] > 2.5 * overshoot
        assert figures["none"][0] is None or figures["none"][0] > recovery


@pytest.mark.slow
def test_stall_recovery_time_in_the_cli_output(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", "fault-stall", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    line = next(s for s in stdout.splitlines() if "load step at 3.5 s" in s)
    metrics = json.loads((out / "metrics.json").read_text())
    recovery = metrics["load_steps"][1]["recovery_time_s"]["value"]
    assert recovery == pytest.approx(
        compute_metrics(run("fault-stall", "back_calculation"))["load_steps"][1]["recovery_time_s"]["value"]
    )
    assert f"recovery {recovery:.4g} s" in line


# --- DC-link sag -------------------------------------------------------------------------------


def test_dc_link_sag_scales_the_link_over_its_window():
    r = run("fault-dc-link-sag", "back_calculation")
    (fault,) = r.scenario.data["fault"]
    u_dc = r.scenario.data["limits"]["u_dc_V"]
    inside = rows(r, fault["t_s"], fault["t_s"] + fault["duration_s"])
    assert inside.sum() == round(fault["duration_s"] / drive(r)["Ts"])
    assert np.all(r.u_dc_V[inside] == fault["u_dc_factor"] * u_dc)
    assert np.all(r.u_dc_V[~inside] == u_dc)
    # the back-EMF p w_m psi_f exceeds the sagged range: the inverter sits at its limit
    m = r.scenario.data["motor"]
    assert m["pole_pairs"] * r.w_m_radps[inside][0] * m["psi_f_Wb"] > fault["u_dc_factor"] * u_dc / math.sqrt(3)
    late = rows(r, fault["t_s"] + 0.5, fault["t_s"] + fault["duration_s"])
    # (limited first by the float32 current controller, which measures the same link); with d-axis
    # priority the d current is back at its reference 0 while the q axis takes what is left
    assert np.allclose(np.hypot(r.ud_V, r.uq_V)[late], fault["u_dc_factor"] * u_dc / math.sqrt(3), rtol=1e-6)
    assert np.all(r.voltage_limited[late] == 1.0) and np.max(np.abs(r.id_A[late])) < 0.05 * drive(r)["i_max"]


def test_dc_link_sag_each_anti_windup_mode():
    """While the link is down the speed falls the same way in every mode (the command sits at the
    current limit or below it identically); once it is back, the anti-windup decides the overshoot."""
    runs = {aw: run("fault-dc-link-sag", aw) for aw in ANTI_WINDUPS}
    r = runs["back_calculation"]
    (fault,) = r.scenario.data["fault"]
    t_end = fault["t_s"] + fault["duration_s"]
    inside = rows(r, fault["t_s"], t_end)
    assert r.speed_rpm[inside][-1] < r.speed_rpm[inside][0] - 100.0
    for aw in ("clamping", "none"):
        assert np.array_equal(runs[aw].speed_rpm[inside], r.speed_rpm[inside])
    after = r.t_s >= t_end
    overshoot = {aw: np.max(x.speed_rpm[after]) - x.speed_ref_rpm[-1] for aw, x in runs.items()}
    saturation = {aw: compute_metrics(x)["faults"][0]["current_limit_time_s"]["value"] for aw, x in runs.items()}
    assert overshoot["none"] > 1.2 * overshoot["back_calculation"]
    assert overshoot["none"] > 1.2 * overshoot["clamping"]
    assert saturation["none"] > saturation["back_calculation"] > saturation["clamping"] > 0.0


def test_total_loss_of_the_dc_link_stays_within_the_short_circuit_current():
    """u = 0 shorts the windings (zero vectors): the stator flux cannot grow, |L i + psi_f| <=
    psi_f + L i(0), so |i| <= (2 psi_f + L i_max) / L; the drive comes back afterwards."""
    fault = [{"kind": "dc_link_sag", "t_s": 20.0, "duration_s": 0.3, "u_dc_factor": 0.0}]
    r = run("fault-dc-link-sag", "back_calculation", fault=fault)
    m = r.scenario.data["motor"]
    i = np.hypot(r.id_A, r.iq_A)
    assert np.max(i) <= (2 * m["psi_f_Wb"] + m["Ld_H"] * 7.6) / m["Ld_H"]
    assert np.max(i) > 7.6  # the current limit bounds the command, not a short-circuit current
    inside = rows(r, 20.0, 20.3)
    assert np.all(r.u_dc_V[inside] == 0.0) and np.all(r.ud_V[inside] == 0.0) and np.all(r.uq_V[inside] == 0.0)
    assert compute_metrics(r)["faults"][0]["recovery_time_s"]["value"] is not None


# --- speed sensor ------------------------------------------------------------------------------


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
def test_sensor_hold_freezes_the_reading_and_the_command(anti_windup):
    r = run("fault-sensor-hold", anti_windup)
    d = drive(r)
    (fault,) = r.scenario.data["fault"]
    t0, t1 = fault["t_s"], fault["t_s"] + fault["duration_s"]
    inside = rows(r, t0, t1)
    before = np.nonzero(r.t_s < t0 - 1e-9)[0][-1]
    assert np.all(r.speed_meas_rpm[inside] == r.speed_meas_rpm[before])
    assert np.array_equal(r.speed_meas_rpm[~inside], r.speed_rpm[~inside])
    # reading = reference: e = 0, the command stays where it was (zero torque at no load) ...
    assert np.ptp(r.torque_ref_Nm[inside]) < 1e-5 and abs(r.torque_ref_Nm[before]) < 1e-4
    # ... so the 8 Nm load decelerates the shaft freely: w(t1) = w(t0) - T_load / J (t1 - t0)
    T_load = r.scenario.data["load"][0]["torque_Nm"]
    k1 = np.searchsorted(r.t_s, t1 - 1e-9)
    assert r.w_m_radps[k1] == pytest.approx(d["w_ref"] - T_load / d["J"] * (t1 - t0), abs=2e-3)


def test_sensor_hold_deepens_the_load_dip():
    with_fault = compute_metrics(run("fault-sensor-hold", "back_calculation"))["load_steps"][0]
    without = compute_metrics(run("fault-sensor-hold", "back_calculation", fault=None))["load_steps"][0]
    assert with_fault["speed_dip_rpm"]["value"] > without["speed_dip_rpm"]["value"] + 10.0


def test_sensor_zero_charges_the_integrator_as_each_mode_prescribes():
    """Reading 0 at 500 rpm: e = w_ref, Kp e > T_max, saturated for all N samples of the window.
    Integrator at the window's end: none x0 + N Ki Ts w_ref; clamping x0; back-calculation
    x* - (x* - x0)(1 - c)^N with x* = T_max + Ki/alpha w_ref - w_ref Ki Ts / 2."""
    charge = {}
    for aw in ANTI_WINDUPS:
        r = run("fault-sensor-zero", aw)
        d = drive(r)
        (fault,) = r.scenario.data["fault"]
        inside = rows(r, fault["t_s"], fault["t_s"] + fault["duration_s"])
        n = int(inside.sum())
        assert n == round(fault["duration_s"] / d["Ts"])
        assert np.all(r.speed_meas_rpm[inside] == 0.0) and np.all(r.saturated[inside])
        assert np.allclose(r.torque_ref_Nm[inside], d["T_max"], rtol=1e-6)
        k0 = np.nonzero(inside)[0][0] - 1
        x0, x_end = r.x_i_Nm[k0], r.x_i_Nm[inside][-1]
        c = d["Ki"] * d["Ka"] * d["Ts"]
        x_star = d["T_max"] + d["Ki"] / d["alpha"] * d["w_ref"] - d["w_ref"] * d["Ki"] * d["Ts"] / 2
        expected = {
            "none": x0 + n * d["Ki"] * d["Ts"] * d["w_ref"],
            "clamping": x0,
            "back_calculation": x_star - (x_star - x0) * (1 - c) ** n,
        }[aw]
        assert x_end == pytest.approx(expected, abs=2e-4)
        charge[aw] = compute_metrics(r)["faults"][0]["speed_deviation_rpm"]["value"]
    # the same speed at the window's end; the integrator's charge sets the overshoot after it
    assert charge["clamping"] < charge["back_calculation"] < charge["none"]


@pytest.mark.parametrize("anti_windup", ANTI_WINDUPS)
def test_sensor_spike_is_one_sample_and_what_it_leaves_in_the_integrator(anti_windup):
    r = run("fault-sensor-spike", anti_windup)
    d = drive(r)
    (fault,) = r.scenario.data["fault"]
    wrong = np.nonzero(r.speed_meas_rpm != r.speed_rpm)[0]
    assert len(wrong) == 1 and r.t_s[wrong[0]] == pytest.approx(fault["t_s"])
    k = wrong[0]
    assert r.speed_meas_rpm[k] == pytest.approx(fault["speed_rpm"], rel=1e-12)
    assert r.saturated[k] and not r.saturated[k - 1] and not r.saturated[k + 1]
    e = error_radps(r)[k]
    u = r.torque_unsat_Nm[k]
    step = {
        "none": d["Ki"] * d["Ts"] * e,
        "clamping": 0.0,
        "back_calculation": d["Ki"] * d["Ts"] * e + d["Ki"] * d["Ka"] * d["Ts"] * (d["T_max"] - u),
    }[anti_windup]
    assert r.x_i_Nm[k] - r.x_i_Nm[k - 1] == pytest.approx(step, abs=1e-4)


def test_sensor_spike_upsets_the_speed_only_without_anti_windup():
    deviation = {
        aw: compute_metrics(run("fault-sensor-spike", aw))["faults"][0]["speed_deviation_rpm"]["value"]
        for aw in ANTI_WINDUPS
    }
    assert deviation["none"] > 20 * max(deviation["back_calculation"], deviation["clamping"])


def test_sensor_spike_between_samples_hits_the_next_one():
    r = run("fault-sensor-spike", "back_calculation", **{"fault.0.t_s": 1.0004})
    wrong = np.nonzero(r.speed_meas_rpm != r.speed_rpm)[0]
    assert len(wrong) == 1 and r.t_s[wrong[0]] == pytest.approx(1.001)


# --- the engine's own checks of fault entries -------------------------------------------------


@pytest.mark.parametrize(
    "field, value",
    [
        ("value", 1.5),
        ("value", -0.1),
        ("value", math.nan),
        ("duration_s", 0.0),
        ("t_s", -1.0),
        ("t_s", math.inf),
        ("kind", 7),
    ],
)
def test_engine_rejects_bad_fault_entries_naming_the_fault_key(field, value):
    r = Simulation(load_scenario("fault-dc-link-sag"))
    setattr(r.cfg.faults[0], field, value)
    status = lib.p2d_sim_init(r.sim, r.cfg)
    assert status == lib.P2D_SIM_ERR_FAULTS
    with pytest.raises(ConfigError) as exc:
        r._raise_config(status)
    assert exc.value.param == "fault"


def test_engine_rejects_a_sag_without_an_inverter():
    r = Simulation(load_scenario("fault-dc-link-sag"))
    r.cfg.current_model = lib.P2D_CURRENT_FIRST_ORDER
    assert lib.p2d_sim_init(r.sim, r.cfg) == lib.P2D_SIM_ERR_FAULTS


def test_adjacent_sags_follow_each_other():
    faults = [
        {"kind": "dc_link_sag", "t_s": 20.0, "duration_s": 0.5, "u_dc_factor": 0.5},
        {"kind": "dc_link_sag", "t_s": 20.5, "duration_s": 0.5, "u_dc_factor": 0.8},
    ]
    r = run("fault-dc-link-sag", "back_calculation", fault=faults)
    assert np.all(r.u_dc_V[rows(r, 20.0, 20.5)] == 0.5 * 540.0)
    assert np.all(r.u_dc_V[rows(r, 20.5, 21.0)] == 0.8 * 540.0)
    assert np.sum(r.u_dc_V != 540.0) == 1000


# --- the report's fault section ---------------------------------------------------------------


def test_report_fault_figures_are_those_of_the_traces():
    assert set(FAULT_PRESETS) == set(PRESETS)
    for preset in FAULT_PRESETS:
        r = run(preset, "none")
        d = r.scenario.data
        t0 = (d["fault"] or d["load"])[0]["t_s"]
        after = r.t_s >= t0 - 1e-9
        k0 = np.nonzero(after)[0][0]
        f = fault_figures(r)
        assert f["t_s"] == t0
        assert f["deviation_rpm"] == pytest.approx(np.max(np.abs(r.speed_ref_rpm - r.speed_rpm)[after]))
        assert f["x_i_excursion_Nm"] == pytest.approx(np.max(np.abs(r.x_i_Nm[after] - r.x_i_Nm[k0 - 1])))
        assert f["i_peak_A"] == pytest.approx(np.max(np.hypot(r.id_A, r.iq_A)[after]))
        # time at the current limit from the flags and the command, each sample holding over one speed period
        limited = r.saturated | (np.hypot(r.id_ref_A, r.iq_ref_A) >= 0.99 * d["limits"]["i_max_A"])
        assert f["current_limit_time_s"] == pytest.approx(np.sum(limited[after]) * drive(r)["Ts"], abs=2e-3)


@pytest.mark.slow
def test_report_fault_section_names_runs_that_cannot_run():
    runs = run_faults({"current_loop.model": "first_order", "simulation.t_end_s": 25.0})
    assert all(isinstance(runs["fault-dc-link-sag", aw], str) for aw in ANTI_WINDUPS)
    assert "fault.0.kind" in runs["fault-dc-link-sag", "none"]
    header, rows = _fault_blocks(runs, {"faults": "caption"})[3][1:]
    assert len(rows) == len(runs) == 15
    assert [row[2].startswith("did not run: fault.0.kind") for row in rows].count(True) == 3
