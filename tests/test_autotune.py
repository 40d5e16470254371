"""The autotuner, checked independently of its search.

Truth: the returned design simulated again (``pmsm2dof.simulate``, ``compute_metrics``) at inertia
ratios across the range, both ends and seeded random interior points; its margins recomputed in
the z plane by python-control from the C controller's PI coefficients and the ZOH plant
(``control.sample_system``), not in the w plane of the analysis module; a physical bound (no step
settles before the drive reaches the new speed at full torque, ``t >= J dw / T_max``); and a
brute-force grid, whose best feasible point the autotuner must match or beat.
"""

import json
import math
import warnings

import control
import numpy as np
import pytest

from pmsm2dof import ConfigError, Scenario, SpeedController, autotune, compute_metrics, load_scenario, simulate
from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.sampled_loop import margins_on_plant
from pmsm2dof.studies.autotune import (
    FIGURES,
    Candidate,
    Evaluation,
    RunRecord,
    Spec,
    pareto_front,
    run_figures,
    step_figures,
)
from pmsm2dof.studies.autotune_search import _Search, bounds_reached
from pmsm2dof.studies.autotune_space import KA_KP_RANGE, ZETA_RANGE
from pmsm2dof.ui.cli import main

#: A small servo: 0.6 Nm at the 10 A limit, J = 1e-4 kg m^2; 2000 rpm, 0.3 Nm load, 1000 rpm.
SERVO = {
    "name": "test servo",
    "motor": {
        "pole_pairs": 4,
        "Rs_ohm": 0.5,
        "Ld_H": 5e-4,
        "Lq_H": 5e-4,
        "psi_f_Wb": 0.01,
        "J_kgm2": 1e-4,
    },
    "limits": {"i_max_A": 10.0, "u_dc_V": 48.0},
    "current_loop": {"model": "dq_pi", "tau_i_s": 1e-3, "Ts_s": 1e-4},
    "speed_controller": {"alpha_radps": 100.0, "zeta": 0.707, "Ts_s": 1e-4},
    "simulation": {"t_end_s": 0.45},
    "reference": [{"t_s": 0.0, "speed_rpm": 2000.0}, {"t_s": 0.3, "speed_rpm": 1000.0}],
    "load": [{"t_s": 0.15, "torque_Nm": 0.3}],
}
T_MAX_NM = 1.5 * 4 * 0.01 * 10.0  # Te = 1.5 p psi_f i_max
J_KGM2 = 1e-4
TAU_I_S = 1e-3
TS_S = 1e-4


def servo():
    return Scenario.from_dict(SERVO)


def z_margins(keys, J_plant_kgm2):
    """(phase margin [deg], gain margin [dB], stable) of the realized PI on the ZOH plant, in the z plane."""
    ctl = SpeedController(
        J_kgm2=J_KGM2,
        alpha_radps=keys["alpha_radps"],
        zeta=keys["zeta"],
        m=keys["m"],
        tau_i_s=TAU_I_S,
        Ka=keys["Ka"],
        Ts_s=TS_S,
        i_max_A=10.0,
        psi_f_Wb=0.01,
        Ld_H=5e-4,
        Lq_H=5e-4,
        pole_pairs=4,
        feedforward=keys["feedforward"],
        anti_windup=keys["anti_windup"],
    )
    b_e0, Ki_Ts = ctl.coefficients["b_e0"], ctl.coefficients["Ki_Ts"]
    F = control.tf([b_e0, Ki_Ts - b_e0], [1.0, -1.0], TS_S)
    G = control.sample_system(control.tf([1.0], [J_plant_kgm2 * TAU_I_S, J_plant_kgm2, 0.0]), TS_S, "zoh")
    L = F * G
    stable = bool(np.all(np.abs(control.poles(control.feedback(L, 1))) < 1.0))
    with warnings.catch_warnings():  # python-control checks its polynomial crossings on the frequency response
        warnings.filterwarnings("ignore", message="stability_margins: Falling back")
        gms, pms, _sms, _wpc, _wgc, _wms = control.stability_margins(L, returnall=True)
    gm = min([g for g in gms if g > 1.0], default=math.inf)
    return min(pms), 20.0 * math.log10(gm), stable


def figures(keys, J_ratio):
    """Overshoot [%], settling [s] of the reference steps, load dip and IAE per Nm, of one simulation."""
    run = servo().with_overrides(
        {f"speed_controller.{k}": v for k, v in keys.items()}
        | {"motor.J_kgm2": J_ratio * J_KGM2, "speed_controller.J_kgm2": J_KGM2}
    )
    metrics = compute_metrics(simulate(run))
    steps = metrics["reference_steps"]
    overshoot = max(s["overshoot_pct"]["value"] for s in steps)
    settling = [s["settling_time_s"]["value"] for s in steps]
    settling_s = math.inf if None in settling else max(settling)
    (load,) = metrics["load_steps"]
    return overshoot, settling_s, load["speed_dip_rpm"]["value"] / 0.3, load["iae_rpm_s"]["value"] / 0.3


# ---------------------------------------------------------------------------------------------
# fast: validation, margins, Pareto front
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("max_overshoot_pct", -1.0),
        ("max_overshoot_pct", math.nan),
        ("min_phase_margin_deg", 180.0),
        ("min_gain_margin_dB", -3.0),
        ("max_settling_s", 0.0),
        ("max_load_dip_rpm_per_Nm", math.inf),
        ("max_recovery_s", -0.1),
        ("max_current_limit_time_s", True),
        ("max_settling_s", "1"),
        ("J_range", (2.0, 1.0)),
        ("J_range", (0.0, 1.0)),
        ("J_range", (0.1, 100.0)),
        ("J_range", (1.0,)),
        ("J_range", "0.5,2"),
        ("feedforwards", ("lowpass", "fast")),
        ("feedforwards", ()),
        ("anti_windups", "clamping"),
    ],
)
def test_spec_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ConfigError) as info:
        Spec(**{field: value})
    assert info.value.param == field
    assert info.value.valid


def test_autotune_rejects_what_it_cannot_tune():
    with pytest.raises(ConfigError) as info:
        autotune(servo().with_overrides({"load": []}))
    assert info.value.param == "scenario"
    with pytest.raises(ConfigError) as info:
        autotune("paper-condition-2")  # type: ignore[arg-type]
    assert info.value.param == "scenario"
    with pytest.raises(ConfigError) as info:
        autotune(servo(), {"J_range": (0.5, 2.0)})  # type: ignore[arg-type]
    assert info.value.param == "spec"
    with pytest.raises(ConfigError) as info:
        autotune(servo(), workers=0)
    assert info.value.param == "workers"


@pytest.mark.parametrize("J_ratio", [0.3, 1.0, 3.0])
@pytest.mark.parametrize(("alpha_radps", "zeta"), [(300.0, 0.707), (900.0, 1.2)])
def test_margins_on_plant_match_the_z_plane(alpha_radps, zeta, J_ratio):
    keys = {"alpha_radps": alpha_radps, "zeta": zeta, "m": 1.0, "Ka": None}
    keys |= {"feedforward": "lowpass", "anti_windup": "back_calculation"}
    d = design(J_KGM2, alpha_radps, zeta, tau_i_s=TAU_I_S)
    margins = margins_on_plant(d, TS_S, "tustin", J_ratio * J_KGM2, TAU_I_S)
    pm, gm, stable = z_margins(keys, J_ratio * J_KGM2)
    assert stable and margins is not None
    assert margins.phase_margin_deg == pytest.approx(pm, abs=1e-6)
    assert margins.gain_margin_dB == pytest.approx(gm, abs=1e-6)


def test_margins_on_plant_is_none_when_the_loop_is_unstable():
    # alpha > 4 zeta^2 / tau_i: the continuous loop is unstable (Routh on eq 8), so is the discrete one
    keys = {"alpha_radps": 2500.0, "zeta": 0.707, "m": 1.0, "Ka": None}
    keys |= {"feedforward": "lowpass", "anti_windup": "back_calculation"}
    d = design(J_KGM2, 2500.0, 0.707, tau_i_s=TAU_I_S)
    assert margins_on_plant(d, TS_S, "tustin", J_KGM2, TAU_I_S) is None
    assert not z_margins(keys, J_KGM2)[2]


def test_pareto_front_keeps_exactly_the_non_dominated():
    def evaluation(i, iae, load_iae, pm):
        worst = {"tracking_iae_rpm_s": iae, "load_iae_rpm_s_per_Nm": load_iae, "phase_margin_deg": pm}
        return Evaluation(Candidate(float(i), 1.0, 1.0, 1.0, "lowpass", "none"), "engine", worst, {}, (1.0,), (), "")

    points = [
        evaluation(1, 1.0, 5.0, 50.0),
        evaluation(2, 2.0, 4.0, 50.0),
        evaluation(3, 2.0, 5.0, 50.0),  # dominated by 1 and 2
        evaluation(4, 3.0, 6.0, 70.0),  # the most robust
        evaluation(5, 3.0, 6.0, 60.0),  # dominated by 4
    ]
    front = {e.candidate.alpha_radps for e in pareto_front(points)}
    assert front == {1.0, 2.0, 4.0}


# ---------------------------------------------------------------------------------------------
# slow: the spec re-checked by simulation, an impossible spec, a brute-force grid
# ---------------------------------------------------------------------------------------------

SPEC = Spec(
    max_overshoot_pct=5.0,
    min_phase_margin_deg=45.0,
    min_gain_margin_dB=6.0,
    max_settling_s=0.1,
    J_range=(0.5, 2.0),
    feedforwards=("lowpass", "none"),
)


@pytest.fixture(scope="module")
def tuned():
    return autotune(servo(), SPEC, workers=2)


@pytest.mark.slow
def test_the_spec_holds_across_the_inertia_range(tuned):
    assert tuned.feasible and tuned.binding is None
    keys = tuned.speed_controller
    assert set(keys) == {"alpha_radps", "zeta", "m", "Ka", "feedforward", "anti_windup"}
    rng = np.random.default_rng(15)
    ratios = [0.5, 2.0, *np.exp(rng.uniform(math.log(0.5), math.log(2.0), 4))]
    dips = []
    for r in ratios:
        pm, gm, stable = z_margins(keys, r * J_KGM2)
        assert stable
        assert pm >= 45.0 and gm >= 6.0, r
        overshoot, settling_s, dip, _iae = figures(keys, r)
        assert overshoot <= 5.0, r
        assert settling_s <= 0.1, r
        dips.append(dip)
    # the reported worst case is the worst of the ratios it checked: no point of the range is worse
    assert max(dips) <= tuned.chosen.worst["load_dip_rpm_per_Nm"] * (1.0 + 1e-9)


@pytest.mark.slow
def test_the_result_reproduces_with_set_and_reports_its_search(tuned):
    rerun = tuned.tuned_scenario()
    assert rerun.data["speed_controller"] | tuned.speed_controller == rerun.data["speed_controller"]
    assert tuned.pareto and all(e.stage == "engine" for e in tuned.pareto)
    assert tuned.chosen.candidate in {e.candidate for e in tuned.evaluations}
    for e in tuned.rejected:
        assert e.error or e.violations or e.stage == "partial"  # each rejected candidate says why
        if e.stage == "partial" and not e.violations:  # simulated in part: ranks below the chosen one there
            assert _Search.rank(e) > _Search.rank(tuned.chosen)
        for v in e.violations:
            limit = getattr(SPEC, v.constraint)
            assert v.limit == limit and v.miss > 0.0
    simulated = {(run.candidate, run.J_ratio) for run in tuned.runs}
    assert {(tuned.chosen.candidate, r) for r in tuned.J_ratios_checked} <= simulated


@pytest.mark.slow
def test_an_impossible_spec_reports_its_binding_constraint():
    # the 2000 rpm step cannot settle before the drive gets there at full torque: t >= J dw / T_max
    result = autotune(servo(), Spec(max_settling_s=0.01, J_range=(0.5, 2.0)), workers=2)
    assert not result.feasible
    assert result.binding is not None and result.binding.constraint == "max_settling_s"
    t_min_s = 2.0 * J_KGM2 * 2000.0 * math.pi / 30.0 / T_MAX_NM
    assert result.binding.value >= 0.98 * t_min_s
    assert result.binding.miss == pytest.approx(result.binding.value - 0.01)
    assert result.binding.J_ratio == pytest.approx(2.0)


@pytest.mark.slow
def test_at_least_as_good_as_a_brute_force_grid():
    spec = Spec(max_overshoot_pct=5.0, J_range=(0.8, 1.25))
    result = autotune(servo(), spec, workers=2)
    ratios = np.geomspace(0.8, 1.25, 5)
    best_iae = math.inf
    for alpha_radps in (150.0, 300.0, 450.0, 600.0, 800.0):
        for zeta in (0.5, 0.707, 1.0, 1.4, 1.8):
            keys = {"alpha_radps": alpha_radps, "zeta": zeta, "m": 1.0, "Ka": 1.0 / (J_KGM2 * alpha_radps)}
            keys |= {"feedforward": "lowpass", "anti_windup": "back_calculation"}
            margins = [z_margins(keys, r * J_KGM2) for r in ratios]
            if not all(stable and pm >= 45.0 and gm >= 6.0 for pm, gm, stable in margins):
                continue
            runs = [figures(keys, r) for r in ratios]
            if all(overshoot <= 5.0 for overshoot, _s, _d, _i in runs):
                best_iae = min(best_iae, max(iae for _o, _s, _d, iae in runs))
    assert math.isfinite(best_iae)  # the grid has a feasible point: the comparison means something
    assert result.feasible
    assert result.chosen.worst["load_iae_rpm_s_per_Nm"] <= best_iae


# ---------------------------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------------------------


@pytest.fixture()
def servo_file(tmp_path):
    path = tmp_path / "servo.toml"
    path.write_text(servo().to_toml())
    return str(path)


@pytest.mark.parametrize(
    ("args", "must_mention"),
    [
        (["--J-range", "2,1"], "--J-range"),
        (["--J-range", "0.5"], "--J-range"),
        (["--J-range", "a,b"], "--J-range"),
        (["--max-overshoot-pct", "-1"], "--max-overshoot-pct"),
        (["--min-phase-margin-deg", "200"], "--min-phase-margin-deg"),
        (["--max-settling-s", "nan"], "--max-settling-s"),
        (["--max-recovery-s", "0"], "--max-recovery-s"),
        (["--feedforward", "fast"], "--feedforward"),
        (["--anti-windup", "clamp"], "--anti-windup"),
        (["--workers", "0"], "--workers"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "--workers"),
        (["--scheduler", "127.0.0.1:9"], "--scheduler"),
        (["--set", "load=[]"], "scenario"),
        (["--set", "motor.J_kgm2=0"], "motor.J_kgm2"),
        (["--emit-c-header", "missing/dir/x.h"], "--emit-c-header"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2_and_writes_nothing(servo_file, tmp_path, capsys, args, must_mention):
    code = main(["autotune", servo_file, "--out", str(tmp_path / "out"), *args])
    out, err = capsys.readouterr()
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("pmsm2dof: error: "), err
    assert must_mention in lines[0]
    assert not (tmp_path / "out").exists()
    assert not list(tmp_path.glob(".out.*"))


def test_cli_refuses_a_folder_it_did_not_write_before_the_search_and_keeps_its_files(servo_file, tmp_path, capsys):
    """The output folder is checked first (then the header), before any simulation: one line, exit 2."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    code = main(["autotune", servo_file, "--out", str(out), "--emit-c-header", str(tmp_path / "missing" / "x.h")])
    stdout, err = capsys.readouterr()
    assert code == 2 and stdout == ""
    assert err.startswith("pmsm2dof: error: --out = ") and "notes.txt" in err and len(err.splitlines()) == 1
    assert [p.name for p in out.iterdir()] == ["notes.txt"] and (out / "notes.txt").read_text() == "mine"
    assert not (tmp_path / "missing").exists()


@pytest.mark.slow
def test_cli_writes_the_tuned_scenario_tables_figure_and_header(servo_file, tmp_path, capsys):
    out = tmp_path / "out"
    header = tmp_path / "servo.h"
    args = ["autotune", servo_file, "--J-range", "0.5,2", "--max-overshoot-pct", "5", "--max-settling-s", "0.1"]
    code = main(
        [*args, "--feedforward", "lowpass", "--feedforward", "none", "--workers", "2", "--json"]
        + ["--out", str(out), "--emit-c-header", str(header)]
    )
    stdout, err = capsys.readouterr()
    assert code == 0, err
    data = json.loads(stdout)
    assert data["feasible"] is True and data["binding"] is None
    keys = data["speed_controller"]
    # the keys are the scenario's: --set speed_controller.KEY=VALUE reproduces the design
    sets = [a for k, v in keys.items() for a in ("--set", f"speed_controller.{k}={v}")]
    assert main(["simulate", servo_file, *sets, "--out", str(tmp_path / "sim")]) == 0
    capsys.readouterr()
    simulated = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert max(s["overshoot_pct"]["value"] for s in simulated["reference_steps"]) <= 5.0
    tuned = load_scenario(str(out / "scenario.toml"))
    assert {k: tuned.data["speed_controller"][k] for k in keys} == keys
    assert {p.name for p in out.iterdir()} == {
        ".pmsm2dof-outputs.json",
        "scenario.toml",
        "autotune.json",
        "pareto.csv",
        "pareto.png",
        "runs.csv",
        "rejected.csv",
    }
    runs = (out / "runs.csv").read_text().splitlines()
    assert len(runs) == 1 + data["counts"]["runs"]
    rejected = (out / "rejected.csv").read_text().splitlines()
    assert rejected[0].split(",")[6:12] == ["stage", "constraint", "limit", "value", "miss", "J_ratio"]
    assert len(rejected) > 1
    assert (out / "pareto.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = header.read_text()
    assert f"alpha_radps = {keys['alpha_radps']:g}" in text


@pytest.mark.slow
def test_cli_exits_1_and_names_the_binding_constraint_when_nothing_meets_the_spec(servo_file, capsys):
    code = main(["autotune", servo_file, "--J-range", "0.5,2", "--max-settling-s", "0.01", "--workers", "2"])
    stdout, err = capsys.readouterr()
    assert code == 1, err
    assert "NO design meets the specification" in stdout
    assert "binding constraint: max_settling_s" in stdout


@pytest.mark.slow
def test_on_a_dask_cluster_the_search_chooses_what_it_chooses_on_threads():
    distributed = pytest.importorskip("dask.distributed")
    spec = Spec(max_overshoot_pct=5.0, J_range=(0.8, 1.25))
    local = autotune(servo(), spec, workers=2)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=False, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        remote = autotune(servo(), spec, scheduler=cluster.scheduler_address)
    assert remote.speed_controller == local.speed_controller
    assert remote.chosen.worst == local.chosen.worst
    assert len(remote.runs) == len(local.runs)


@pytest.mark.slow
def test_the_forms_of_eq_11_and_clamping_stay_within_the_bound_of_the_work():
    from pmsm2dof.studies.autotune_space import runs_bound

    spec = Spec(max_overshoot_pct=5.0, J_range=(0.8, 1.25), feedforwards=("no_tau", "full"), anti_windups=("clamping",))
    result = autotune(servo(), spec, workers=2)
    assert len(result.runs) <= runs_bound(servo(), spec)
    keys = result.speed_controller
    assert keys["feedforward"] in ("no_tau", "full") and keys["anti_windup"] == "clamping"
    assert {e.candidate.m for e in result.evaluations} != {1.0}  # m is searched with the feedforwards of eq 11
    assert result.feasible
    overshoot, _settling_s, _dip, _iae = figures(keys, 1.25)
    assert overshoot <= 5.0


# ---------------------------------------------------------------------------------------------
# the objective, chattering candidates, the bounds of the search
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "keys",
    [
        {"alpha_radps": 432.7, "zeta": 1.072},  # settles, overshoots a little
        {"alpha_radps": 40.0, "zeta": 2.0},  # too slow to settle or recover in its windows
        {"alpha_radps": 2500.0, "zeta": 0.3},  # beyond the stability bound: a limit cycle that chatters
    ],
)
def test_the_search_measures_each_run_as_the_full_metrics_would(keys):
    """run_figures computes only the figures step_figures reads: the same numbers, bit for bit."""
    run = servo().with_overrides({f"speed_controller.{k}": v for k, v in keys.items()})
    result = simulate(run)
    assert run_figures(result) == step_figures(compute_metrics(result))


@pytest.mark.parametrize("zeta", [1.4, 2.0])
def test_the_objective_is_the_load_iae_which_for_an_overdamped_response_is_dT_over_Ki(zeta):
    """The integrator supplies the load: Ki times the integral of the error is dT, so a response whose error
    keeps its sign has IAE = dT / Ki, Ki = J (alpha / (2 zeta))^2 (eq 9): zeta at the top of the range
    costs the most integral action, which the dip alone does not see."""
    alpha = 551.0
    keys = {"alpha_radps": alpha, "zeta": zeta}
    run = servo().with_overrides({f"speed_controller.{k}": v for k, v in keys.items()})
    got = step_figures(compute_metrics(simulate(run)))
    Ki = J_KGM2 * (alpha / (2.0 * zeta)) ** 2
    assert got["load_iae_rpm_s_per_Nm"] == pytest.approx(30.0 / math.pi / Ki, rel=0.02)
    assert got["load_dip_rpm_per_Nm"] < got["load_iae_rpm_s_per_Nm"] / 0.005  # the dip lasts longer than 5 ms


def test_a_chattering_candidate_is_rejected():
    search = _Search(servo(), Spec(min_phase_margin_deg=None, min_gain_margin_dB=None), 1, None, False)
    c = search.candidate(500.0, 0.7, 1.0, 1.0, "lowpass", "back_calculation")
    figures = dict.fromkeys(FIGURES, 0.0) | {"chatter_share": 0.3}
    for name in ("phase_margin_deg", "gain_margin_dB"):
        del figures[name]
    search.figures[(c, 1.0)] = RunRecord(c, 1.0, figures, "", 0.01)
    search.simulated_at[c] = [1.0]
    e = search.evaluation(c)
    assert not e.feasible and "chatters" in e.error
    search.figures[(c, 1.0)] = RunRecord(c, 1.0, figures | {"chatter_share": 0.0}, "", 0.01)
    search.known.clear()
    assert search.evaluation(c).feasible


def test_a_design_on_a_bound_of_the_search_is_reported():
    search = _Search(servo(), Spec(), 1, None, False)
    top = search.candidate(500.0, ZETA_RANGE[1], 1.0, 1.0, "lowpass", "back_calculation")
    assert any(f"zeta = {ZETA_RANGE[1]:g} is at the upper bound" in n for n in bounds_reached(search, top))
    inside = search.candidate(500.0, 0.7, 1.0, 1.0, "lowpass", "back_calculation")
    assert bounds_reached(search, inside) == ()
    edge = search.candidate(search.alpha_max_radps(0.7, 1.0), 0.7, 1.0, 1.0, "lowpass", "back_calculation")
    assert any("alpha_radps" in n for n in bounds_reached(search, edge))
    low_ka = search.candidate(500.0, 0.7, 1.0, KA_KP_RANGE[0], "lowpass", "back_calculation")
    assert any("Ka Kp" in n and "lower bound" in n for n in bounds_reached(search, low_ka))


@pytest.mark.slow
def test_the_chosen_damping_is_inside_the_search_and_the_recovery_bounded(tuned):
    """With the dip alone as objective zeta ran to the top of its range (2.0) with a slow recovery."""
    assert tuned.chosen.candidate.zeta < 0.95 * ZETA_RANGE[1]
    assert not [n for n in tuned.on_bounds if n.startswith("zeta")]
    result = autotune(servo(), Spec(max_recovery_s=1e-3, J_range=(0.5, 2.0)), workers=2)
    assert not result.feasible and result.binding.constraint == "max_recovery_s"


# ---------------------------------------------------------------------------------------------
# the search's shortcuts: margins without python-control, candidates simulated where they matter
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("tau_i_s", [0.0, 1e-3, 0.05])
def test_margins_on_plants_equal_python_controls_polynomial_method(tau_i_s):
    """The margins of the loop gain L(w) at many inertias, found together, are those python-control's
    stability_margins finds on each L(w) as a transfer function (the same crossings, picked alike)."""
    from dataclasses import replace

    from pmsm2dof.analysis.margins import pick_margins
    from pmsm2dof.analysis.sampled_loop import c_coefficients, loop_w, margins_on_plants

    rng = np.random.default_rng(31)
    for _ in range(12):
        J = 10.0 ** rng.uniform(-5, 0)
        tau = tau_i_s if tau_i_s else 0.0
        alpha = 10.0 ** rng.uniform(-1, 2.3) / max(tau, 1e-3)
        d = design(J, alpha, rng.uniform(0.3, 2.0), tau_i_s=tau)
        Ts = 10.0 ** rng.uniform(-5, -3)
        ratios = np.geomspace(0.3, 3.0, 5)
        got = margins_on_plants(d, Ts, "tustin", J * ratios, tau)
        pi = c_coefficients(d, Ts, "tustin", feedforward="none", anti_windup="none")
        for r, margins in zip(ratios, got):
            num, den = loop_w(replace(d, J_kgm2=J * r), Ts, pi["b_e0"], pi["Ki_Ts"])
            char = np.polyadd(den, num)
            stable = bool(np.all(np.real(np.roots(char)) < 0.0))
            assert (margins is not None) == stable
            if margins is None:
                continue
            gms, pms, _sms, w_pcs, w_gcs, _w_sms = control.stability_margins(control.tf(num, den), returnall=True)
            w_pc = 2.0 / Ts * np.arctan(0.5 * Ts * np.asarray(w_pcs, dtype=float))
            w_gc = 2.0 / Ts * np.arctan(0.5 * Ts * np.asarray(w_gcs, dtype=float))
            extra = [(abs(den[0] / num[0]), math.pi / Ts)] if num[0] / den[0] < 0.0 else []
            want = pick_margins(gms, pms, w_pc, w_gc, extra)
            for name in ("gain_margin_dB", "phase_margin_deg", "w_gain_crossover_radps", "w_phase_crossover_radps"):
                a, b = getattr(margins, name), getattr(want, name)
                assert (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, rel=1e-7, abs=1e-9), name


def test_the_search_chooses_what_it_chooses_when_every_candidate_is_simulated_everywhere(monkeypatch):
    """The search simulates a new candidate at the largest inertia ratio first and at the others only where
    it could still be the best (_Search.best): the same choice, the same worst case, as a search that
    simulates every candidate at every ratio; each partial evaluation's figures bound the complete ones."""
    spec = Spec(max_overshoot_pct=5.0, J_range=(0.5, 2.0), feedforwards=("lowpass", "none"))
    lazy = autotune(servo(), spec, workers=2)
    evaluate = _Search.evaluate

    def everywhere(self, candidates, J_ratios_sim=None):
        return evaluate(self, candidates, self.J_ratios_search if J_ratios_sim is None else J_ratios_sim)

    monkeypatch.setattr(_Search, "evaluate", everywhere)
    full = autotune(servo(), spec, workers=2)
    assert lazy.speed_controller == full.speed_controller and lazy.feasible == full.feasible
    assert lazy.chosen.worst == full.chosen.worst
    assert len(lazy.runs) < 0.75 * len(full.runs)
    complete = {e.candidate: e for e in full.evaluations}
    partial = [e for e in lazy.evaluations if e.stage == "partial"]
    assert partial and all(not e.feasible for e in partial)
    for e in partial:
        f = complete[e.candidate]
        assert _Search.rank(e) <= _Search.rank(f)
        for name, value in e.worst.items():
            if FIGURES[name] == "max":
                assert value <= f.worst[name]
