"""The `pmsm2dof design` and `pmsm2dof bode` commands."""

import json
import math
import re
import subprocess
import sys

import pytest

from pmsm2dof.ui.cli import main

PAPER = [
    "--J-kgm2",
    "0.4",
    "--alpha-radps",
    "0.5",
    "--zeta",
    "0.2887",
    "--m",
    "1",
    "--tau-i-s",
    "0.05",
    "--Ts-s",
    "1e-3",
    "--method",
    "tustin",
    "--feedforward",
    "full",
]


def test_design_table_shows_gains_poles_margins_and_coefficients(capsys):
    assert main(["design", *PAPER]) == 0
    out = capsys.readouterr().out
    for label in ("Kp = J alpha", "loop poles", "bandwidth", "margins", "b_e0", "ff_Kd_per_Ts"):
        assert label in out
    # eq 9 by hand: Kp = 0.4 * 0.5, Ki = 0.4 * (0.5 / (2 * 0.2887))^2
    assert "0.2 Nm/(rad/s)" in out
    assert f"{0.4 * (0.5 / (2 * 0.2887)) ** 2:.6g} Nm/rad" in out


@pytest.mark.slow
def test_design_json_in_a_fresh_process():
    run = subprocess.run(
        [sys.executable, "-m", "pmsm2dof", "design", *PAPER, "--json"], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    data = json.loads(run.stdout)
    assert data["Kp"] == pytest.approx(0.2, rel=1e-12)
    assert data["Ki"] == pytest.approx(0.4 * (0.5 / (2 * 0.2887)) ** 2, rel=1e-12)
    assert data["Ka"] == pytest.approx(5.0, rel=1e-12)
    # the C controller's coefficient, computed in float32
    assert data["discrete"]["coefficients"]["b_e0"] == pytest.approx(0.2 + data["Ki"] * 1e-3 / 2, rel=1e-6)


def test_design_emits_c_header(tmp_path, capsys):
    header = tmp_path / "speed_design.h"
    motor = ["--i-max-A", "5", "--pole-pairs", "3", "--psi-f-Wb", "0.1", "--Ld-H", "0.002", "--Lq-H", "0.003"]
    motor += ["--Rs-ohm", "0.5", "--Ts-current-s", "1e-4", "--tau-i-s", "0.05"]
    assert main(["design", *PAPER, *motor, "--emit-c-header", str(header), "--prefix", "motor1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    text = header.read_text()
    assert "static const p2d_speed_config_t motor1_speed = {" in text
    assert ".i_max_A = 5.0f" in text and ".pole_pairs = 3u" in text and ".Lq_H = 0.003f" in text
    assert "static const p2d_current_config_t motor1_current = {" in text and ".Rs_ohm = 0.5f" in text
    assert "#define MOTOR1_CURRENT_PER_SPEED 10u" in text
    assert data["header"]["motor"]["psi_f_Wb"] == {"value": 0.1, "source": "given: --psi-f-Wb"}
    assert data["header"]["motor"]["Ts_current_s"] == {"value": 1e-4, "source": "given: --Ts-current-s"}


def test_header_without_motor_data_names_what_is_missing(tmp_path, capsys):
    header = tmp_path / "speed.h"
    assert main(["design", *PAPER, "--emit-c-header", str(header), "--psi-f-Wb", "0.1"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert (
        "--i-max-A, --pole-pairs, --Ld-H, --Rs-ohm, --Ts-current-s missing" in captured.err
        and "--paper-drive" in captured.err
    )
    assert not any(tmp_path.iterdir())


def test_paper_drive_fills_in_what_is_not_given_and_says_so(tmp_path, capsys):
    header = tmp_path / "speed.h"
    assert (
        main(
            [
                "design",
                *PAPER,
                "--emit-c-header",
                str(header),
                "--paper-drive",
                "--Ld-H",
                "0.012",
                "--Rs-ohm",
                "0.3",
                "--Ts-current-s",
                "1e-4",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    # the paper's drive is the preset's: 7.6 A limit (section 4), 4 pole pairs, 0.2 Wb
    from pmsm2dof import load_scenario

    preset = load_scenario("paper-condition-1").data
    expected = {
        "i_max_A": (preset["limits"]["i_max_A"], "paper drive"),
        "pole_pairs": (preset["motor"]["pole_pairs"], "paper drive"),
        "psi_f_Wb": (preset["motor"]["psi_f_Wb"], "paper drive"),
        "Ld_H": (0.012, "given: --Ld-H"),
        "Lq_H": (0.012, "= Ld_H: surface PMSM"),
        "Rs_ohm": (0.3, "given: --Rs-ohm"),
    }
    summary = {line.split()[0]: line for line in out.split("C header written to")[1].splitlines()[1:]}
    text = header.read_text()
    for name, (value, source) in expected.items():
        assert f"= {value:<8g}" in summary[name] and source in summary[name], summary[name]
        recorded = re.search(rf"^ \*   {name}\s+= (\S+) .*\((.*)\)$", text, flags=re.M)
        assert float(recorded.group(1)) == value and source in recorded.group(2)
    assert "placeholder" in summary["i_max_A"] and "placeholder" not in summary["Ld_H"]


def test_sampling_warning_is_one_stderr_line(capsys):
    assert main(["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.2887", "--Ts-s", "0.5"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pmsm2dof: warning: Ts_s = 0.5")


BAD = [
    (["design", "--J-kgm2", "-0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"], "--J-kgm2"),
    (["design", "--J-kgm2", "0.4", "--alpha-radps", "nan", "--zeta", "0.3", "--Ts-s", "1e-3"], "--alpha-radps"),
    (["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0", "--Ts-s", "1e-3"], "--zeta"),
    (["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "inf"], "--Ts-s"),
    (
        ["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3", "--tau-i-s", "-1"],
        "--tau-i-s",
    ),
    (["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3", "--Ka", "-2"], "--Ka"),
    (
        [
            "design",
            "--J-kgm2",
            "0.4",
            "--alpha-radps",
            "0.5",
            "--zeta",
            "0.3",
            "--Ts-s",
            "1e-3",
            "--m",
            "2",
            "--feedforward",
            "lowpass",
        ],
        "--m",
    ),
    (
        ["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3", "--method", "zoh"],
        "method",
    ),
    (["design", "--J-kgm2", "heavy", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"], "--J-kgm2"),
    (["design", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"], "--J-kgm2"),
    (["bode", "--alpha-radps", "0.5", "--m", "0.2,x", "--out", "fig.png"], "m"),
    (["bode", "--alpha-radps", "0", "--out", "fig.png"], "alpha_radps"),
    (["bode", "--alpha-radps", "0.5", "--out", "fig.pdf"], "out"),
]


@pytest.mark.parametrize("argv, param", BAD)
def test_bad_values_exit_2_with_one_stderr_line(tmp_path, monkeypatch, capsys, argv, param):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith("pmsm2dof: error: ")
    assert param in captured.err
    assert "Traceback" not in captured.err
    assert not any(tmp_path.iterdir())


def test_design_with_a_vanishing_integral_action_is_not_refused(capsys):
    # zeta = 1e10 leaves Ki = J (alpha / (2 zeta))^2 ~ 1e-22: a stable loop whose slowest pole,
    # -Ki / Kp = -1.25e-21 rad/s, is nearly cancelled by the PI's zero; the P loop alone gives the
    # first-order response Kp / (J s + Kp), without overshoot
    assert (
        main(["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "1e10", "--Ts-s", "1e-3", "--json"]) == 0
    )
    data = json.loads(capsys.readouterr().out)
    for part in ("continuous", "discrete"):
        assert "overshoot_pct" not in data[part]["missing"]
        assert data[part]["overshoot_pct"] == pytest.approx(0.0, abs=1e-9)


# designs once refused with "the step response does not rise in a computable time"
SLOW_OR_FINE = [
    ["--J-kgm2", "0.4", "--alpha-radps", "0.45", "--zeta", "0.2887", "--Ts-s", "1e-3", "--feedforward", "lowpass"],
    [
        "--J-kgm2",
        "0.4",
        "--alpha-radps",
        "0.5",
        "--zeta",
        "0.2887",
        "--tau-i-s",
        "0.05",
        "--Ts-s",
        "1e-4",
        "--feedforward",
        "lowpass",
    ],
    [
        "--J-kgm2",
        "0.4",
        "--alpha-radps",
        "0.5",
        "--zeta",
        "0.2887",
        "--tau-i-s",
        "0.05",
        "--Ts-s",
        "1e-4",
        "--feedforward",
        "none",
    ],
]


@pytest.mark.parametrize("argv", SLOW_OR_FINE)
def test_slow_or_finely_sampled_designs_are_not_refused(tmp_path, capsys, argv):
    header = tmp_path / "speed.h"
    motor = ["--i-max-A", "7.6", "--pole-pairs", "4", "--psi-f-Wb", "0.2", "--Ld-H", "0.01"]
    motor += ["--Rs-ohm", "0.5", "--Ts-current-s", "1e-4"]
    motor += [] if "--tau-i-s" in argv else ["--tau-i-s", "0.05"]  # the header's current loop has eq 3's tau_i
    assert main(["design", *argv, *motor, "--emit-c-header", str(header), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    for part in ("continuous", "discrete"):
        assert data[part]["overshoot_pct"] is not None and "overshoot_pct" not in data[part]["missing"]
    assert max(math.hypot(*p) for p in data["discrete"]["poles_z"]) < 1.0
    assert "p2d_config_speed" in header.read_text()


def test_margins_json_has_gain_margin_in_dB_and_no_infinity(capsys):
    assert main(["design", *PAPER, "--json"]) == 0
    out = capsys.readouterr().out
    data = json.loads(out, parse_constant=lambda name: pytest.fail(f"{name} is not JSON"))
    continuous, discrete = data["continuous"], data["discrete"]
    assert "gain_margin" not in continuous["margins"] and "gain_margin" not in discrete["margins"]
    # the continuous loop of eq 8 is stable for every gain (Routh: Kp > tau Ki): infinite margin
    assert continuous["margins"]["gain_margin_dB"] is None
    assert continuous["missing"]["gain_margin_dB"].startswith("infinite")
    # discrete (Tustin PI, ZOH plant): the -180 deg crossing; the table prints the same number in dB
    assert discrete["margins"]["gain_margin_dB"] > 20.0
    assert main(["design", *PAPER]) == 0
    table = capsys.readouterr().out
    assert f"gain {discrete['margins']['gain_margin_dB']:.4g} dB" in table


def test_bad_header_option_writes_nothing(tmp_path, capsys):
    header = tmp_path / "h.h"
    assert main(["design", *PAPER, "--emit-c-header", str(header), "--paper-drive", "--pole-pairs", "0"]) == 2
    assert capsys.readouterr().err.startswith("pmsm2dof: error: --pole-pairs = 0")
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
def test_bad_value_in_a_fresh_process_has_no_traceback():
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmsm2dof",
            "design",
            "--J-kgm2",
            "0",
            "--alpha-radps",
            "0.5",
            "--zeta",
            "0.3",
            "--Ts-s",
            "1e-3",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "pmsm2dof: error: --J-kgm2 = 0.0 is invalid: valid range is finite and > 0"
    ]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["fig7.png", "fig7.svg"])
def test_bode_draws_fig7(tmp_path, name):
    out = tmp_path / name
    assert main(["bode", "--alpha-radps", "0.5", "--feedforward", "full", "--m", "0.2,0.5,1,2", "--out", str(out)]) == 0
    data = out.read_bytes()
    assert data.startswith(b"\x89PNG") if name.endswith(".png") else b"<svg" in data[:2000]


@pytest.mark.slow
def test_bode_says_what_it_wrote(tmp_path, capsys):
    out = tmp_path / "gx.svg"
    assert main(["bode", "--alpha-radps", "0.5", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.out.count("\n") == 1 and captured.out.startswith(f"wrote {out}")
    assert captured.err == ""
