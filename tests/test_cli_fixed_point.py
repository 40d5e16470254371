"""`pmsm2dof design --fixed-point q15|q31`: the scaling check on the command line.

Truth: the dead zone's edge from its formula, ``T_fs 2^-(N+1) / (Ki Ts)`` with the paper's Ki = 0.3
(eq 9: J (alpha / (2 zeta))^2), and the series-form count ``round(Ki Ts W_fs / T_fs 2^15)``.
"""

import json
import math
import re

import pytest

from pmsm2dof.ui.cli import main

PAPER = ["--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", str(1.0 / (2.0 * math.sqrt(3.0))), "--tau-i-s", "0.05"]
DRIVE = ["--i-max-A", "7.6", "--pole-pairs", "4", "--psi-f-Wb", "0.2"]
Q15 = ["--fixed-point", "q15", "--speed-full-scale-rpm", "1000", "--torque-full-scale-Nm", "10"]
RPM = math.pi / 30.0


def test_the_paper_design_at_1e_4_s_in_q15_is_flagged_with_its_dead_zone(capsys):
    assert main(["design", *PAPER, "--Ts-s", "1e-4", *DRIVE, *Q15]) == 0
    out = capsys.readouterr().out
    print(out)
    assert "Fixed-point scaling check: Q15, Ts = 0.0001 s, tustin -- FLAGGED" in out and "limit 9.12 Nm" in out
    # the edge, half a torque LSB over Ki Ts, to within one speed LSB (the error is an integer)
    edge_rpm = 0.5 * (10.0 / 2**15) / (0.3 * 1e-4) / RPM
    low, high = re.search(r"\(([-\d.]+) to ([-\d.]+) rpm, ", out).groups()
    assert float(high) == -float(low) == pytest.approx(edge_rpm, abs=1000.0 / 2**15)
    # a series-form Q15 PI stores Ki Ts W_fs / T_fs = 3.14e-4 as round(10.3) = 10 counts
    counts = round(0.3 * 1e-4 * 1000.0 * RPM / 10.0 * 2**15)
    assert counts == 10 and f"   {counts} (" in out
    assert "fmt = q31: dead zone 0 rad/s" in out and "feasible" in out


def test_q31_has_no_dead_zone_and_the_json_carries_the_report(capsys):
    argv = ["design", *PAPER, "--Ts-s", "1e-4", "--fixed-point", "q31", "--speed-full-scale-rpm", "1000"]
    assert main([*argv, "--torque-full-scale-Nm", "64", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)  # strict JSON: no Infinity
    fixed = data["fixed_point"]
    assert fixed["fmt"] == "q31" and fixed["dead_zone"]["removed"] and fixed["dead_zone"]["width_rpm"] == 0.0
    assert fixed["speed_full_scale_radps"] == pytest.approx(1000.0 * RPM)
    assert [g["name"] for g in fixed["coefficients"]][:2] == ["b_e0", "Ki_Ts"]
    assert main([*argv, "--torque-full-scale-Nm", "64"]) == 0
    assert "integrator dead zone: none" in capsys.readouterr().out


def test_without_fixed_point_the_design_prints_no_check(capsys):
    assert main(["design", *PAPER, "--Ts-s", "1e-4"]) == 0
    assert "scaling check" not in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, option",
    [
        (["--fixed-point", "q16", "--speed-full-scale-rpm", "1000", "--torque-full-scale-Nm", "10"], "--fixed-point"),
        (["--fixed-point", "q15", "--speed-full-scale-rpm", "-5", "--torque-full-scale-Nm", "10"],
         "--speed-full-scale-rpm"),
        (["--fixed-point", "q15", "--speed-full-scale-rpm", "1000", "--torque-full-scale-Nm", "0"],
         "--torque-full-scale-Nm"),
        ([*DRIVE, "--fixed-point", "q15", "--speed-full-scale-rpm", "1000", "--torque-full-scale-Nm", "5"],
         "--torque-full-scale-Nm"),
        (["--fixed-point", "q15", "--speed-full-scale-rpm", "1000"], "--torque-full-scale-Nm"),
        (["--speed-full-scale-rpm", "1000"], "--fixed-point"),
        (["--fixed-point", "q31", "--speed-full-scale-rpm", "1e12", "--torque-full-scale-Nm", "10"],
         "--speed-full-scale-rpm"),
    ],
)  # fmt: skip
def test_bad_values_exit_2_with_one_stderr_line_naming_the_option(capsys, extra, option):
    assert main(["design", *PAPER, "--Ts-s", "1e-4", *extra]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pmsm2dof: error:") and option in lines[0], captured.err


def test_the_1dof_pi_has_no_feedforward_state_to_hold(capsys):
    """Without feedforward (b_dr = 0) y stays 0: nothing winds up, and a full scale holds x alone."""
    argv = ["design", *PAPER, "--Ts-s", "1e-4", "--feedforward", "none", *DRIVE, *Q15]
    assert main(argv) == 0
    out = capsys.readouterr().out.split("Fixed-point scaling check")[1]
    assert "winds up" not in out and ">= inf" not in out
    assert "y_ff            0 full scales,   +inf bits: ok" in out
