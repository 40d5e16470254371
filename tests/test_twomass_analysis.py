"""pmsm2dof.analysis.twomass, the `pmsm2dof twomass` command and the design header's torque filters
against truths from outside them.

- the resonance from the eigenvalues of the two-mass state matrix written here from Newton's law;
- the torque filters against the designs of tests/test_torque_filter.py (the notch's B solved there
  numerically for the discrete -3 dB width);
- the loop's stability against the engine (tests/test_twomass_engine.py: the load-side loop that
  the notch stabilizes);
- the C header with the torque filters, compiled with the library, against the Python controller.
"""

import math
import subprocess

import numpy as np
import pytest
from test_codegen import CFLAGS, CSRC, GCC, N_STEPS, c_array, inputs
from test_torque_filter import designed_lowpass, designed_notch

from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.twomass import filter_tf, largest_stable_alpha, sampled_loop, two_mass
from pmsm2dof.core import SpeedController
from pmsm2dof.studies.configuration import configuration, design_scenario
from pmsm2dof.ui.cli import main

J_M, J_L, F_R_HZ, ZETA_R = 0.1, 0.3, 30.0, 0.02
W_R = 2 * math.pi * F_R_HZ
K = W_R**2 * J_M * J_L / (J_M + J_L)
D = 2 * ZETA_R * W_R * J_M * J_L / (J_M + J_L)


def test_resonance_is_the_eigenvalue_of_the_two_mass_equations():
    train = two_mass(J_M, J_L, K, D)
    # x = (w_m, theta, w_L): J_M w_m' = -K theta - D (w_m - w_L), theta' = w_m - w_L, J_L w_L' = K theta + D (w_m - w_L)
    A = np.array([[-D / J_M, -K / J_M, D / J_M], [1.0, 0.0, -1.0], [D / J_L, K / J_L, -D / J_L]])
    lam = max(np.linalg.eigvals(A), key=lambda v: v.imag)
    assert abs(lam) == pytest.approx(train.resonance_radps, rel=1e-12)
    assert -lam.real / abs(lam) == pytest.approx(train.resonance_damping, rel=1e-12)
    # the anti-resonance: the load alone on the shaft, motor held (w_m = 0)
    assert train.antiresonance_radps == pytest.approx(math.sqrt(K / J_L), rel=1e-15)
    zeros = train.Gm("motor").zeros()
    assert np.max(np.abs(zeros)) == pytest.approx(train.antiresonance_radps, rel=1e-9)


def test_filters_are_the_designed_ones():
    Ts = 1e-3
    H = filter_tf(
        Ts, notch_freq_Hz=30.0, notch_width_Hz=20.0, notch_depth=0.05, lowpass_freq_Hz=150.0, lowpass_zeta=0.7
    )
    bn, an = designed_notch(30.0, 20.0, 0.05, Ts)
    bl, al = designed_lowpass(150.0, 0.7, Ts)
    w = 2 * math.pi * np.geomspace(0.1, 499.0, 400) * Ts
    z = np.exp(1j * w)
    expected = np.polyval(bn, z) / np.polyval(an, z) * np.polyval(bl, z) / np.polyval(al, z)
    got = H(z)
    assert np.max(np.abs(got - expected)) < 1e-9


def test_sampled_loop_stability_is_the_engines():
    d = design(J_M + J_L, 20.0, 0.7, tau_i_s=2e-3)
    train = two_mass(J_M, J_L, K, D)
    plain = sampled_loop(d, train, 1e-3, feedback="load")
    notched = sampled_loop(
        d, train, 1e-3, feedback="load", filters={"notch_freq_Hz": 30.0, "notch_width_Hz": 20.0, "notch_depth": 0.05}
    )
    assert not plain.stable and notched.stable
    # the growing mode is the resonance
    growing = max(plain.poles, key=abs)
    assert abs(np.angle(growing)) / 1e-3 == pytest.approx(W_R, rel=0.05)
    # the motor side (collocated) is stable without a filter
    assert sampled_loop(d, train, 1e-3, feedback="motor").stable


def test_cli_twomass_prints_the_analysis(capsys):
    args = [
        "twomass",
        "--J-motor-kgm2",
        "0.1",
        "--J-load-kgm2",
        "0.3",
        "--stiffness-Nm-per-rad",
        str(K),
        "--damping-Nms-per-rad",
        str(D),
    ]
    assert main([*args, "--alpha-radps", "20", "--tau-i-s", "2e-3", "--Ts-s", "1e-3", "--feedback", "load"]) == 0
    out = capsys.readouterr().out
    assert "resonance                  30 Hz" in out and "UNSTABLE" in out


def test_cli_twomass_bad_input_is_one_line(capsys):
    args = [
        "twomass",
        "--J-motor-kgm2",
        "0.1",
        "--J-load-kgm2",
        "-1",
        "--stiffness-Nm-per-rad",
        "1",
        "--alpha-radps",
        "20",
        "--Ts-s",
        "1e-3",
    ]
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        "pmsm2dof: error: --J-load-kgm2 = -1.0 is invalid: valid range is finite and > 0"
    ]
    assert captured.out == ""


FILTERED_PROGRAM = """\
#include <stdio.h>

#include "notched.h"

{arrays}

int main(void)
{{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    int k;
    if (p2d_speed_init(&ctl, &notched_speed) != P2D_OK) return 1;
    if (p2d_speed_set_filter(&ctl, &notched_speed_filter) != P2D_OK) return 1;
    for (k = 0; k < {n}; ++k) {{
        p2d_speed_step(&ctl, w_ref[k], w_m[k], &out);
        printf("%a %a\\n", (double)out.T_unsat_Nm, (double)out.T_ref_Nm);
    }}
    return 0;
}}
"""


@pytest.mark.skipif(GCC is None, reason="gcc is not installed")
def test_header_with_torque_filters_compiles_and_matches_python(tmp_path):
    """The design's C header with a notch and a low-pass, built with the library: the filtered command
    equals, bit for bit, a SpeedController configured in Python with the same filters."""
    filters = dict(notch_freq_Hz=30.0, notch_width_Hz=20.0, notch_depth=0.05, lowpass_freq_Hz=150.0, lowpass_zeta=0.7)
    motor = dict(i_max_A=7.6, pole_pairs=4, psi_f_Wb=0.2, Ld_H=0.01, Lq_H=0.01)
    # tau_i (eq 3) sets the current loop's; the lowpass feedforward does not use it
    dd = design(J_M + J_L, 20.0, 0.7, tau_i_s=2e-3).discretize(1e-3, "tustin")
    scenario = design_scenario(dd, **motor, Rs_ohm=0.5, Ts_current_s=1e-4, speed_filter=filters)
    configuration(scenario).write_header(tmp_path / "notched.h", prefix="notched")
    w_ref, w_m = inputs(N_STEPS)
    arrays = "\n".join([c_array("w_ref", w_ref), c_array("w_m", w_m)])
    (tmp_path / "main.c").write_text(FILTERED_PROGRAM.format(arrays=arrays, n=N_STEPS))
    sources = [str(tmp_path / "main.c"), *sorted(str(p) for p in (CSRC / "src").glob("*.c"))]
    exe = tmp_path / "run"
    subprocess.run(
        [GCC, *CFLAGS, f"-I{CSRC / 'include'}", f"-I{tmp_path}", *sources, "-o", str(exe), "-lm"], check=True
    )
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=30, check=True)
    c = np.array([[float.fromhex(v) for v in line.split()] for line in run.stdout.splitlines()])
    ctl = SpeedController(J_kgm2=J_M + J_L, alpha_radps=20.0, zeta=0.7, Ts_s=1e-3, **motor, **filters)
    py = ctl.run(w_ref, w_m)
    np.testing.assert_array_equal(c[:, 0].astype(np.float32), py["T_unsat_Nm"])
    np.testing.assert_array_equal(c[:, 1].astype(np.float32), py["T_ref_Nm"])
    plain = SpeedController(J_kgm2=J_M + J_L, alpha_radps=20.0, zeta=0.7, Ts_s=1e-3, **motor).run(w_ref, w_m)
    assert not np.array_equal(plain["T_unsat_Nm"], py["T_unsat_Nm"])  # the filters act


def test_a_stiff_shaft_has_the_rigid_drives_bound():
    """The largest stable alpha of a very stiff train equals the rigid loop's, decided by the w-plane
    Routh test of pmsm2dof.analysis.discretize (another code path), and lies below the continuous
    bound 4 zeta^2 / tau_i of eq 9 with the current loop (Routh on J tau_i s^3 + J s^2 + Kp s + Ki)."""
    from pmsm2dof.errors import ConfigError

    zeta, tau_i, Ts = 0.2887, 0.05, 1e-3

    def rigid_stable(alpha):
        try:
            design(0.4, alpha, zeta, tau_i_s=tau_i).discretize(Ts, "tustin")
        except ConfigError:
            return False
        return True

    lo, hi = 1.0, 4 * zeta**2 / tau_i
    assert rigid_stable(lo) and not rigid_stable(hi)
    while hi / lo > 1.0 + 1e-4:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if rigid_stable(mid) else (lo, mid)
    stiff = two_mass(0.1, 0.3, 1e7, 10.0)
    assert largest_stable_alpha(stiff, zeta, tau_i, Ts, rtol=1e-4) == pytest.approx(lo, rel=1e-3)


def test_cli_region_refuses_other_formats_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a short path: a message cuts a value longer than 80 characters
    args = [
        "twomass",
        "--J-motor-kgm2",
        "0.1",
        "--J-load-kgm2",
        "0.3",
        "--stiffness-Nm-per-rad",
        str(K),
        "--alpha-radps",
        "20",
        "--Ts-s",
        "1e-3",
    ]
    assert main([*args, "--region", "region.pdf"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "pmsm2dof: error: --region = 'region.pdf' is invalid: valid range is a file name ending in .png or .svg"
    ]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_cli_region_draws_the_stable_region(tmp_path, capsys):
    args = [
        "twomass",
        "--J-motor-kgm2",
        "0.1",
        "--J-load-kgm2",
        "0.3",
        "--stiffness-Nm-per-rad",
        str(K),
        "--damping-Nms-per-rad",
        str(D),
    ]
    args += ["--alpha-radps", "20", "--tau-i-s", "2e-3", "--Ts-s", "1e-3", "--feedback", "load"]
    assert main([*args, "--region", str(tmp_path / "region.svg")]) == 0
    assert (tmp_path / "region.svg").read_text().lstrip().startswith("<?xml")
    assert [p.name for p in tmp_path.iterdir()] == ["region.svg"]
