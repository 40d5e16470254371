"""Datasheet units: the conversion to the per-phase, amplitude-invariant model of eq 1.

Truth: the three phase waveforms of a sinusoidal star-connected machine sampled numerically (line
voltages and their rms, the power balance sum(e_k i_k) = Te w_m), independent of the formulas of
pmsm2dof.sim.datasheet.
"""

import math
import warnings

import numpy as np
import pytest

from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.datasheet import DatasheetWarning, convert_datasheet, load_motor
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
