"""Datasheet units: the conversion to the per-phase, amplitude-invariant model of eq 1.

Truth: the three phase waveforms of a sinusoidal star-connected machine sampled numerically (line
voltages and their rms, the power balance sum(e_k i_k) = Te w_m), independent of the formulas of
pmsm2dof.core.motor.
"""

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.core.motor import DatasheetWarning, convert_datasheet, load_motor
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.scenario import load_scenario

P, PSI_F = 4, 0.2  # the machine of the paper presets


def _waveforms(p, psi_f, i_peak, w_m=1000 * 2 * math.pi / 60):
    """Phase back-EMFs and currents over one electrical period at w_m, currents in phase (iq only)."""
    theta = np.linspace(0.0, 2 * math.pi, 20000, endpoint=False)
    shifts = np.array([0.0, -2 * math.pi / 3, 2 * math.pi / 3])[:, None]
    # flux linkage of phase k: psi_f cos(theta - shift); e = d(psi)/dt = -p w_m psi_f sin(theta - shift)
    e = -p * w_m * psi_f * np.sin(theta + shifts)
    i = -i_peak * np.sin(theta + shifts)
    return e, i, w_m


def _rms(x):
    return float(np.sqrt(np.mean(x**2)))


def test_ke_and_kt_from_the_waveforms_give_back_the_flux_linkage():
    e, i, w_m = _waveforms(P, PSI_F, i_peak=3.0)
    ke_line_rms = _rms(e[0] - e[1])  # V at 1000 rpm
    ke_line_peak = float(np.max(np.abs(e[0] - e[1])))
    ke_phase_rms = _rms(e[0])
    torque = float(np.mean(np.sum(e * i, axis=0))) / w_m  # power balance
    kt_rms = torque / _rms(i[0])
    kt_peak = torque / 3.0
    base = {"poles": 2 * P, "R_ohm": 1.0, "L_H": 0.02}
    for sheet in (
        {"Ke_V_per_krpm": ke_line_rms},
        {"Ke_V_per_krpm": ke_line_peak, "Ke_voltage": "line_peak"},
        {"Ke_V_per_krpm": ke_phase_rms, "Ke_voltage": "phase_rms"},
        {"Kt_Nm_per_A": kt_rms},
        {"Kt_Nm_per_A": kt_peak, "Kt_current": "peak"},
        {"Kt_Nm_per_A": kt_rms, "Ke_V_per_krpm": ke_line_rms},
    ):
        m = convert_datasheet({**base, **sheet})
        assert m.psi_f_Wb == pytest.approx(PSI_F, rel=1e-7), sheet  # the sampled peak: 2e-8
        assert m.kt_Nm_per_A == pytest.approx(1.5 * P * PSI_F, rel=1e-7)
        assert m.notes == () or m.notes[0].endswith("consistent")
    # the SI identity between the two constants of one machine
    assert kt_rms == pytest.approx(math.sqrt(3) * ke_line_rms / w_m, rel=1e-9)


def test_line_to_line_resistance_and_inductance_are_two_phases_in_series():
    m = convert_datasheet({"pole_pairs": 3, "Kt_Nm_per_A": 1.0, "R_ohm": 1.2, "L_H": 0.008, "I_rated_A": 5.0})
    assert (m.pole_pairs, m.Rs_ohm, m.Ld_H, m.Lq_H) == (3, 0.6, 0.004, 0.004)
    assert m.i_rated_A == pytest.approx(5.0 * math.sqrt(2))
    m = convert_datasheet(
        {"pole_pairs": 3, "Kt_Nm_per_A": 1.0, "R_ohm": 1.2, "R_between": "phase", "Ld_H": 0.004, "Lq_H": 0.006}
    )
    assert (m.Rs_ohm, m.Ld_H, m.Lq_H) == (1.2, 0.002, 0.003)


def test_disagreeing_kt_and_ke_are_reported():
    e, _, w_m = _waveforms(P, PSI_F, 1.0)
    sheet = {"poles": 8, "R_ohm": 1.0, "L_H": 0.02, "Ke_V_per_krpm": _rms(e[0] - e[1])}
    # a Kt given per A peak but labelled rms: sqrt(2) too small
    kt_peak_mislabelled = 1.5 * P * PSI_F
    with pytest.warns(DatasheetWarning, match="disagree"):
        m = convert_datasheet({**sheet, "Kt_Nm_per_A": kt_peak_mislabelled})
    assert m.psi_f_Wb == pytest.approx(PSI_F)
    assert "-29.3 %" in m.notes[0]


@pytest.mark.parametrize(
    ("change", "param"),
    [
        ({"poles": 7}, "motor.datasheet.poles"),
        ({"pole_pairs": 4}, "motor.datasheet.poles"),
        ({"Kt_current": "RMS"}, "motor.datasheet.Kt_current"),
        ({"R_ohm": -1.0}, "motor.datasheet.R_ohm"),
        ({"Kv": 3.0}, "motor.datasheet.Kv"),
        ({"Ld_H": 0.001}, "motor.datasheet.L_H"),
    ],
)
def test_bad_datasheet_names_the_key(change, param):
    with pytest.raises(ConfigError) as exc:
        convert_datasheet({"poles": 8, "R_ohm": 1.0, "L_H": 0.02, "Kt_Nm_per_A": 1.0, **change})
    assert exc.value.param == param


DATASHEET_TOML = """
[motor]
J_kgm2 = 0.4
[motor.datasheet]
poles = 8
Kt_Nm_per_A = {kt}
R_ohm = 1.0
L_H = 0.02
"""


def test_a_scenario_with_a_datasheet_equals_the_one_with_the_model_keys(tmp_path):
    preset = load_scenario("paper-condition-2")
    data = preset.data
    kt_rms = 1.5 * P * PSI_F * math.sqrt(2)
    src = preset.to_toml()
    start = src.index("[motor]")
    end = src.index("\n[", start + 1)
    path = tmp_path / "ds.toml"
    path.write_text(src[:start] + DATASHEET_TOML.format(kt=kt_rms).strip() + "\n" + src[end:])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        from_sheet = load_scenario(path)
    motor = from_sheet.data["motor"]
    assert motor["pole_pairs"] == 4
    assert motor["psi_f_Wb"] == pytest.approx(PSI_F, rel=1e-12)
    assert (motor["Rs_ohm"], motor["Ld_H"]) == (0.5, 0.01)
    assert data["motor"]["Rs_ohm"] == 0.5
    assert load_motor(path).psi_f_Wb == motor["psi_f_Wb"]
    both = DATASHEET_TOML.format(kt=kt_rms).replace("J_kgm2 = 0.4", "J_kgm2 = 0.4\nRs_ohm = 0.5")
    path.write_text(src[:start] + both.strip() + "\n" + src[end:])
    with pytest.raises(ConfigError, match="motor.Rs_ohm = 0.5 is invalid: valid range is absent when"):
        load_scenario(path)


def test_cli_motor_prints_the_converted_parameters_and_refuses_a_bad_key(tmp_path, capsys):
    from pmsm2dof.ui.cli import main

    path = tmp_path / "m.toml"
    path.write_text(DATASHEET_TOML.format(kt=1.5 * P * PSI_F * math.sqrt(2)))
    assert main(["motor", str(path), "--json"]) == 0
    import json

    out = json.loads(capsys.readouterr().out)
    assert out["psi_f_Wb"] == pytest.approx(PSI_F) and out["Rs_ohm"] == 0.5
    assert out["sources"]["Rs_ohm"] == "R 1 ohm line_to_line / 2"
    path.write_text(DATASHEET_TOML.format(kt=-1.0))
    assert main(["motor", str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and "motor.datasheet.Kt_Nm_per_A = -1.0" in captured.err


# ---------------------------------------------------------------------------------------------
# Block commutation (maxon's kM, kn and currents), Kv, and the shipped catalogue motor
# ---------------------------------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
EC45 = ROOT / "examples" / "ec45-flat" / "drive.toml"


def _block_commutation(p, psi_f, I_dc, w_m=1000 * 2 * math.pi / 60):
    """Six-step (120-degree) operation of the sinusoidal machine, sampled over one electrical period.

    In each 60-degree sector the DC-link current I_dc flows into the phase whose back-EMF is the
    largest and out of the one whose back-EMF is the smallest (the commutation a Hall-sensor drive
    makes); the DC side sees the difference of their back-EMFs. Returns the mean torque (power
    balance sum(e_k i_k) = Te w_m), the mean DC-side back-EMF, and the phase currents.
    """
    e, _, _ = _waveforms(p, psi_f, 0.0, w_m)
    hi, lo = np.argmax(e, axis=0), np.argmin(e, axis=0)
    i = np.zeros_like(e)
    cols = np.arange(e.shape[1])
    i[hi, cols] = I_dc
    i[lo, cols] = -I_dc
    torque = float(np.mean(np.sum(e * i, axis=0))) / w_m
    u_dc_side = float(np.mean(e[hi, cols] - e[lo, cols]))
    return torque, u_dc_side, i


def test_block_commutation_constants_from_the_waveforms_give_back_the_flux_linkage():
    """kM (torque per DC-link ampere) and kn (rpm per volt of mean DC-side back-EMF) of six-step operation."""
    I_dc = 2.0
    torque, u_dc_side, i = _block_commutation(P, PSI_F, I_dc)
    kM = torque / I_dc  # Nm/A
    ke_block = u_dc_side  # V at 1000 rpm
    kn = 1000.0 / ke_block  # rpm/V
    base = {"commutation": "block", "pole_pairs": P, "R_ohm": 1.0, "L_H": 0.02}
    for sheet in (
        {"Kt_Nm_per_A": kM},
        {"Kv_rpm_per_V": kn},
        {"Ke_V_per_krpm": ke_block},
        {"Kt_Nm_per_A": kM, "Kv_rpm_per_V": kn},
    ):
        m = convert_datasheet({**base, **sheet})
        assert m.psi_f_Wb == pytest.approx(PSI_F, rel=2e-5), sheet  # the sampled sector edges: 1e-5
        assert m.commutation == "block"
    # maxon's identity kM kn = 30000 / pi (mNm/A, rpm/V), from the same waveforms
    assert kM * 1e3 * kn == pytest.approx(30000 / math.pi, rel=1e-9)
    # the rated current: a sinusoidal phase current of the same rms as the block current's
    rms = _rms(i[0])
    m = convert_datasheet({**base, "Kt_Nm_per_A": kM, "I_rated_A": I_dc, "I_peak_A": 3 * I_dc})
    assert m.i_rated_A == pytest.approx(math.sqrt(2) * rms, rel=1e-4)
    assert m.i_peak_A == pytest.approx(3 * I_dc)  # the phase current's peak
    assert "block" in m.sources["psi_f_Wb"] and "block" in m.sources["i_rated_A"]


def test_kv_is_rpm_per_volt_of_the_voltage_ke_voltage_names():
    e, _, _ = _waveforms(P, PSI_F, 0.0)
    ke_line_peak = float(np.max(np.abs(e[0] - e[1])))  # V at 1000 rpm
    m = convert_datasheet(
        {"poles": 2 * P, "R_ohm": 1.0, "L_H": 0.02, "Kv_rpm_per_V": 1000 / ke_line_peak, "Ke_voltage": "line_peak"}
    )
    assert m.psi_f_Wb == pytest.approx(PSI_F, rel=1e-7)
    # ODrive's rule for a hobby motor's Kv (line-to-line peak): Kt = (60 / (2 pi)) (sqrt(3) / 2) / Kv [Nm/A peak]
    assert m.kt_Nm_per_A == pytest.approx(60 / (2 * math.pi) * math.sqrt(3) / 2 / (1000 / ke_line_peak), rel=1e-7)


@pytest.mark.parametrize(
    ("change", "param"),
    [
        ({"commutation": "trapezoid"}, "motor.datasheet.commutation"),
        ({"commutation": "block", "Kt_current": "rms"}, "motor.datasheet.Kt_current"),
        ({"commutation": "block", "I_rated_current": "peak", "I_rated_A": 3.0}, "motor.datasheet.I_rated_current"),
        ({"Kv_rpm_per_V": 236.0, "Ke_V_per_krpm": 4.2}, "motor.datasheet.Kv_rpm_per_V"),
        ({"J_rotor_gcm2": 0.0}, "motor.datasheet.J_rotor_gcm2"),
    ],
)
def test_bad_block_and_kv_keys_name_the_key(change, param):
    with pytest.raises(ConfigError) as exc:
        convert_datasheet({"pole_pairs": 8, "R_ohm": 1.0, "L_H": 0.02, "Kt_Nm_per_A": 0.04, **change})
    assert exc.value.param == param


def test_the_catalogue_motor_converts_as_the_formulas_of_its_convention(capsys):
    """The maxon EC 45 flat 70 W (24 V) of examples/ec45-flat, typed from the catalogue page.

    Truth: the formulas of block commutation written here from the catalogue's kM = 40.4 mNm/A,
    kn = 236 rpm/V, 0.573 ohm and 0.301 mH phase to phase, 3.29 A nominal current, 181 g cm^2,
    8 pole pairs; and the catalogue's own cross-check kM kn = 30000 / pi within its rounding.
    """
    from pmsm2dof.ui.cli import main

    assert main(["motor", str(EC45), "--json"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert captured.err == ""  # kM and kn agree: no warning
    assert 40.4 * 236 == pytest.approx(30000 / math.pi, rel=2e-3)
    kn_si = 236 * math.pi / 30  # rad/s per volt
    psi_f = 1 / (kn_si * 3 * math.sqrt(3) / math.pi * 8)  # kn^-1 = (3 sqrt(3) / pi) p psi_f
    assert out["psi_f_Wb"] == pytest.approx(psi_f, rel=1e-12)
    assert out["kt_Nm_per_A"] == pytest.approx(1.5 * 8 * psi_f, rel=1e-12)
    assert (out["Rs_ohm"], out["Ld_H"], out["Lq_H"]) == pytest.approx((0.2865, 0.1505e-3, 0.1505e-3))
    assert out["i_rated_A"] == pytest.approx(3.29 * 2 / math.sqrt(3))
    assert out["J_rotor_kgm2"] == pytest.approx(181e-7)
    assert out["no_load_rpm"] == pytest.approx(24 / (math.sqrt(3) * 8 * psi_f) * 30 / math.pi)
    assert "consistent" in out["notes"][0]


def test_datasheet_keys_are_listed_by_presets_keys_motor_help_and_the_readme(capsys):
    from pmsm2dof.core.motor import DATASHEET_KEYS
    from pmsm2dof.ui.cli import main

    assert main(["presets", "--keys"]) == 0
    keys_out = capsys.readouterr().out
    assert main(["motor", "--help"]) == 0
    help_out = capsys.readouterr().out
    readme = (ROOT / "docs" / "your-motor.md").read_text()
    section = readme[readme.index("### Datasheet keys") :]
    section = section[: section.index("\n## ")]
    for key in DATASHEET_KEYS:
        assert f"motor.datasheet.{key}" in keys_out, key
        assert f"{key}:" in help_out, key
        assert f"`{key}`" in section, key


DISAGREEING = """
name = "datasheet with Kt and Ke that disagree"
[motor]
J_kgm2 = 7.24e-5
[motor.datasheet]
pole_pairs = 8
Kt_Nm_per_A = 0.0404
Ke_V_per_krpm = 4.2373
R_ohm = 0.573
L_H = 0.301e-3
[limits]
i_max_A = 10.0
u_dc_V = 24.0
[current_loop]
model = "first_order"
tau_i_s = 2.5e-4
Ts_s = 5e-5
[speed_controller]
alpha_radps = 200.0
zeta = 0.7
Ts_s = 5e-4
[simulation]
t_end_s = 0.05
[[reference]]
t_s = 0.0
speed_rpm = 1000.0
"""


def test_the_kt_ke_warning_is_one_line_without_a_source_path_once_per_command(tmp_path, capsys):
    """A scenario converted three times (file, two overrides) warns once, as one line."""
    from pmsm2dof.ui.cli import main

    path = tmp_path / "sheet.toml"
    path.write_text(DISAGREEING)
    argv = ["simulate", str(path), "--set", "reference.0.speed_rpm=900", "--set", "simulation.t_end_s=0.04"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("pmsm2dof: warning: Kt 0.0404 Nm/A rms gives psi_f") and ".py" not in err[0]


def test_ratings_beside_a_datasheet_and_in_a_model_file(tmp_path):
    """A rating the sheet does not give may stand in [motor]; one it gives may not."""
    path = tmp_path / "m.toml"
    path.write_text(
        "[motor]\ni_peak_A = 20.0\n[motor.datasheet]\npole_pairs = 8\nKt_Nm_per_A = 0.0404\n"
        'commutation = "block"\nR_ohm = 0.573\nL_H = 0.301e-3\nI_rated_A = 3.29\n'
    )
    m = load_motor(path)
    assert (m.i_peak_A, m.sources["i_peak_A"]) == (20.0, "motor.i_peak_A")
    assert m.i_rated_A == pytest.approx(3.29 * 2 / math.sqrt(3))
    path.write_text(path.read_text().replace("i_peak_A = 20.0", "i_rated_A = 4.0"))
    with pytest.raises(ConfigError, match="motor.i_rated_A = 4.0 is invalid: valid range is absent when"):
        load_motor(path)
    path.write_text(
        "[motor]\npole_pairs = 4\nRs_ohm = 0.5\nLd_H = 0.01\nLq_H = 0.01\npsi_f_Wb = 0.2\nJ_rotor_kgm2 = 1e-4\n"
    )
    assert load_motor(path).J_rotor_kgm2 == 1e-4


def test_motor_file_reads_back_the_motor(tmp_path):
    """Motor.motor_file writes what load_motor reads: every key, ratings, mechanics and intervals."""
    from pmsm2dof.core.motor import Motor

    motor = Motor(
        pole_pairs=5,
        Rs_ohm=0.31,
        Ld_H=1.1e-3,
        Lq_H=1.7e-3,
        psi_f_Wb=0.021,
        i_peak_A=12.0,
        J_rotor_kgm2=3.3e-5,
        J_kgm2=1.2e-4,
        B_Nms=0.0,
        T_coulomb_Nm=0.004,
        intervals={"Rs_ohm": (0.3, 0.32), "psi_f_Wb": (0.0205, 0.0215)},
    )
    path = tmp_path / "motor.toml"
    path.write_text(motor.motor_file(["a comment"]))
    back = load_motor(path)
    for name in ("pole_pairs", "Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb", "i_peak_A", "J_rotor_kgm2", "J_kgm2", "B_Nms"):
        assert getattr(back, name) == getattr(motor, name), name
    assert (back.T_coulomb_Nm, back.i_rated_A, back.intervals) == (0.004, None, motor.intervals)
    assert back.kt_Nm_per_A == pytest.approx(1.5 * 5 * 0.021, rel=1e-15)
    path.write_text(motor.motor_file().replace("B_Nms = 0.0", "B_Nms = -1.0"))
    with pytest.raises(ConfigError, match=r"motor\.B_Nms = -1\.0 .*>= 0"):
        load_motor(path)
