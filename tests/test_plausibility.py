"""Valid but implausible inputs are warned about with their reason, and errors name what the user set.

The drive is the maxon EC 45 flat of examples/ec45-flat, entered from its catalogue page. Truths:
the catalogue's values and the formulas of block commutation written here (the no-load speed
``u_dc / (sqrt(3) p psi_f)``, the peak torque ``1.5 p psi_f i_max``), the largest torque of a
current vector found by a bounded search over its angle, the C speed controller's own torque limit,
and the stability bound of the back-calculation loop ``Ki Ka Ts < 2`` probed on both sides.
"""

import math
from pathlib import Path

import pytest
from scipy.optimize import minimize_scalar

from pmsm2dof.analysis.design import design
from pmsm2dof.core import SpeedController
from pmsm2dof.errors import ConfigError, SimulationError
from pmsm2dof.sim.plausibility import implausible, peak_torque_Nm
from pmsm2dof.sim.scenario import list_presets, load_scenario
from pmsm2dof.sim.simulate import simulate
from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
EC45 = str(ROOT / "examples" / "ec45-flat" / "drive.toml")
# the catalogue: kn = 236 rpm/V in block commutation, 8 pole pairs; the drive: 24 V, 10 A
PSI_F = math.pi / (3 * math.sqrt(3) * 8 * 236 * math.pi / 30)
NO_LOAD_RPM = 24 / (math.sqrt(3) * 8 * PSI_F) * 30 / math.pi
T_PEAK_NM = 1.5 * 8 * PSI_F * 10.0


def findings(**changes):
    return implausible(load_scenario(EC45).with_overrides(changes))


def test_the_shipped_drive_and_the_presets_are_plausible_but_the_stall():
    assert findings() == []
    flagged = {name: implausible(load_scenario(name)) for name in list_presets()}
    assert {name for name, found in flagged.items() if found} == {"fault-stall"}
    assert "above the peak torque" in flagged["fault-stall"][0]


ROTOR = "times the motor's rotor inertia"
BELOW = "below the motor's rotor inertia"
TRAIN = "times the inertia of the drive train"


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        # 181 g cm^2 typed as kg m^2
        ({"speed_controller.J_kgm2": 181.0}, [("speed_controller.J_kgm2 = 181", ROTOR), ("speed_controller", TRAIN)]),
        ({"speed_controller.J_kgm2": 1e-6}, [("speed_controller.J_kgm2 = 1e-06", BELOW), ("speed_controller", TRAIN)]),
        (
            {"motor.J_kgm2": 9.05e-6},
            [("speed_controller.J_kgm2 = 9.05e-06", BELOW), ("motor.J_kgm2 = 9.05e-06", BELOW)],
        ),
        ({"speed_controller.J_kgm2": 1.2e-3}, [("speed_controller.J_kgm2 = 0.0012", TRAIN)]),
        ({"limits.i_max_A": 1e6}, [("limits.i_max_A = 1e+06 A", "rated current")]),
        ({"motor.i_peak_A": 8.0}, [("limits.i_max_A = 10 A", "peak current")]),
        (
            {"reference.0.speed_rpm": 1e6},
            [("reference.0.speed_rpm = 1e+06 rpm", f"no-load speed {NO_LOAD_RPM:.5g} rpm")],
        ),
        ({"reference.1.speed_rpm": -5500.0}, [("reference.1.speed_rpm = -5500 rpm", "limits.u_dc_V = 24 V")]),
        ({"load.0.torque_Nm": 0.4}, [("load.0.torque_Nm = 0.4 Nm", f"peak torque {T_PEAK_NM:.4g} Nm")]),
    ],
)
def test_each_implausible_value_is_named_with_its_reason(changes, expected):
    found = findings(**changes)
    assert len(found) == len(expected), found
    for text, (key, reason) in zip(found, expected):
        assert text.startswith(key) and reason in text, text


def test_limits_at_the_edge_are_not_flagged():
    assert findings(**{"reference.0.speed_rpm": 0.999 * NO_LOAD_RPM, "load.0.torque_Nm": 0.999 * T_PEAK_NM}) == []
    assert findings(**{"limits.i_max_A": 4.99 * 3.29 * 2 / math.sqrt(3)}) == []
    # field weakening reaches beyond the no-load speed: no speed finding then
    assert findings(**{"reference.0.speed_rpm": 6000.0}) != []
    weakened = {"field_weakening.enabled": True, "field_weakening.Ki_A_per_Vs": 100.0}
    assert findings(**{"reference.0.speed_rpm": 6000.0, **weakened}) == []


@pytest.mark.parametrize(("Ld_H", "Lq_H"), [(2e-3, 2e-3), (1e-3, 4e-3), (4e-3, 1e-3)])
def test_peak_torque_is_the_largest_torque_of_the_current_circle(Ld_H, Lq_H):
    p, psi_f, i_max = 4, 0.05, 12.0

    def torque(angle):
        i_d, i_q = i_max * math.cos(angle), i_max * math.sin(angle)
        return 1.5 * p * (psi_f * i_q + (Ld_H - Lq_H) * i_d * i_q)

    best = -minimize_scalar(lambda a: -torque(a), bounds=(0.0, math.pi), method="bounded", options={"xatol": 1e-12}).fun
    assert peak_torque_Nm(i_max, p, psi_f, Ld_H, Lq_H) == pytest.approx(best, rel=1e-9)
    # the torque limit the C speed controller computes on its MTPA trajectory (float32)
    ctl = SpeedController(
        J_kgm2=0.01,
        alpha_radps=100.0,
        zeta=0.7,
        Ts_s=1e-3,
        i_max_A=i_max,
        psi_f_Wb=psi_f,
        Ld_H=Ld_H,
        Lq_H=Lq_H,
        pole_pairs=p,
    )
    assert peak_torque_Nm(i_max, p, psi_f, Ld_H, Lq_H) == pytest.approx(ctl.coefficients["T_max_Nm"], rel=1e-5)


def test_the_cli_warns_once_per_finding_after_the_run(tmp_path, capsys):
    argv = ["simulate", EC45, "--set", "reference.0.speed_rpm=1e6", "--set", "limits.i_max_A=1e6"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(line.startswith("pmsm2dof: warning: ") for line in err), err
    assert "limits.i_max_A = 1e+06 A" in err[0] and "reference.0.speed_rpm = 1e+06 rpm" in err[1]


def test_a_load_above_the_peak_torque_stops_the_run_said_as_such():
    """A load held above the peak torque: the drive stalls, the load turns it to overspeed."""
    scenario = load_scenario(EC45).with_overrides({"load.0.torque_Nm": 1.0, "load.1.torque_Nm": 1.0})
    with pytest.raises(SimulationError) as err:
        simulate(scenario)
    text = str(err.value)
    assert f"load.1.torque_Nm = 1 Nm is above the peak torque {T_PEAK_NM:.4g} Nm" in text
    assert "stalled the drive and turned it backwards" in text


# ---------------------------------------------------------------------------------------------
# Errors name the input the user set, not a derived default
# ---------------------------------------------------------------------------------------------

ALPHA, TS = 200.0, 5e-4  # the example's speed loop


def run_with(**changes):
    """Simulate a short step of the example with ``changes`` (the engine validates the controller)."""
    short = {"simulation.t_end_s": 0.01, "reference": [{"t_s": 0.0, "speed_rpm": 1000.0}], "load": None}
    return simulate(load_scenario(EC45).with_overrides({**short, **changes}))


def test_a_low_zeta_is_blamed_not_the_default_ka():
    """Ka = 1/Kp gives Ki Ka Ts = alpha Ts / (4 zeta^2) < 2, so zeta > sqrt(alpha Ts / 8)."""
    bound = math.sqrt(ALPHA * TS / 8)
    run_with(**{"speed_controller.zeta": 1.01 * bound})
    with pytest.raises(ConfigError) as err:
        run_with(**{"speed_controller.zeta": 0.99 * bound})
    assert err.value.param == "speed_controller.zeta"
    with pytest.raises(ConfigError) as err:
        run_with(**{"speed_controller.zeta": 0.01})
    assert err.value.param == "speed_controller.zeta" and f"{bound:.4g}" in err.value.valid
    assert "speed_controller.Ka is absent" in err.value.valid


def test_a_large_alpha_is_blamed_not_the_default_ka():
    zeta = 0.7
    bound = 8 * zeta**2 / TS  # alpha < 8 zeta^2 / Ts
    with pytest.raises(ConfigError) as err:
        run_with(**{"speed_controller.alpha_radps": 10000.0})
    assert err.value.param == "speed_controller.alpha_radps" and f"{bound:.6g}" in err.value.valid
    with pytest.raises(ConfigError) as err:
        run_with(**{"speed_controller.alpha_radps": 1.01 * bound})
    assert err.value.param == "speed_controller.alpha_radps"
    # a Ka the user gives is named itself
    with pytest.raises(ConfigError) as err:
        run_with(**{"speed_controller.Ka": 1e9})
    assert err.value.param == "speed_controller.Ka"


@pytest.mark.filterwarnings("ignore::pmsm2dof.analysis.discretize.SamplingWarning")
def test_design_names_zeta_and_alpha_too(capsys):
    with pytest.raises(ConfigError) as err:
        design(7.24e-5, ALPHA, 0.01).discretize(TS, "tustin")
    assert err.value.param == "zeta"
    with pytest.raises(ConfigError) as err:
        design(7.24e-5, 10000.0, 0.7).discretize(TS, "tustin")
    assert err.value.param == "alpha_radps"
    assert main(["design", "--J-kgm2", "7.24e-5", "--alpha-radps", "200", "--zeta", "0.01", "--Ts-s", "5e-4"]) == 2
    assert capsys.readouterr().err.startswith("pmsm2dof: error: --zeta = 0.01 is invalid")


def test_a_default_taken_from_another_key_names_that_key():
    """speed_controller.J_kgm2 absent takes motor.J_kgm2: an overflowing gain names motor.J_kgm2."""
    with pytest.raises(ConfigError) as err:
        run_with(**{"motor.J_kgm2": 1e37})
    assert err.value.param == "motor.J_kgm2" and "speed_controller.J_kgm2" in err.value.valid


# ---------------------------------------------------------------------------------------------
# design --motor: a scenario, a datasheet motor file, an identified motor.toml
# ---------------------------------------------------------------------------------------------

IDENTIFIED = """# identified
[motor]
pole_pairs = 8
Rs_ohm = 0.2865
Ld_H = 0.0001505
Lq_H = 0.0001505
psi_f_Wb = 0.003058
Rs_ohm_ci = [0.28, 0.29]
"""

SHEET_ONLY = """[motor.datasheet]
commutation = "block"
pole_pairs = 8
Kt_Nm_per_A = 0.0404
Kv_rpm_per_V = 236.0
R_ohm = 0.573
L_H = 0.301e-3
J_rotor_gcm2 = 181.0
"""


@pytest.mark.parametrize("kind", ["scenario", "datasheet", "identified"])
def test_design_motor_takes_every_kind_of_motor_file(kind, tmp_path, capsys):
    path = {"scenario": Path(EC45), "datasheet": tmp_path / "m.toml", "identified": tmp_path / "motor.toml"}[kind]
    if kind != "scenario":
        path.write_text(SHEET_ONLY if kind == "datasheet" else IDENTIFIED)
    header = tmp_path / "h.h"
    argv = [
        "design",
        "--motor",
        str(path),
        "--J-kgm2",
        "7.24e-5",
        "--alpha-radps",
        "200",
        "--zeta",
        "0.7",
        "--Ts-s",
        "5e-4",
    ]
    argv += [
        "--current-bandwidth-radps",
        "4000",
        "--Ts-current-s",
        "5e-5",
        "--emit-c-header",
        str(header),
        "--i-max-A",
        "10",
    ]
    assert main(argv) == 0, capsys.readouterr().err
    captured = capsys.readouterr()
    assert captured.err == ""
    assert f"Kp_q = Lq alpha_c          {0.1505e-3 * 4000:.6g} V/A" in captured.out
    text = header.read_text()
    assert ".pole_pairs = 8" in text and ".psi_f_Wb = 0.00305" in text


def test_design_motor_warns_of_an_inertia_in_the_wrong_unit(capsys):
    argv = ["design", "--motor", EC45, "--J-kgm2", "181", "--alpha-radps", "200", "--zeta", "0.7", "--Ts-s", "5e-4"]
    assert main(argv) == 0
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("pmsm2dof: warning: --J-kgm2 = 181 kg m^2 is 1e+07 times the motor's rotor inertia")
