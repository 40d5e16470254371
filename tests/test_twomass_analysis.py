"""pmsm2dof.analysis.twomass and the `pmsm2dof twomass` command against truths from outside them.

- the resonance from the eigenvalues of the two-mass state matrix written here from Newton's law;
- the torque filters against the designs of tests/test_torque_filter.py (the notch's B solved there
  numerically for the discrete -3 dB width);
- the loop's stability against the engine (tests/test_twomass_engine.py: the load-side loop that
  the notch stabilizes).
"""

import math

import numpy as np
import pytest
from test_torque_filter import designed_lowpass, designed_notch

from pmsm2dof.analysis.design import design
from pmsm2dof.analysis.twomass import filter_tf, sampled_loop, two_mass
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
    args = ["twomass", "--J-motor", "0.1", "--J-load", "0.3", "--stiffness", str(K), "--damping", str(D)]
    assert main([*args, "--alpha", "20", "--tau-i", "2e-3", "--Ts", "1e-3", "--feedback", "load"]) == 0
    out = capsys.readouterr().out
    assert "resonance                  30 Hz" in out and "UNSTABLE" in out


def test_cli_twomass_bad_input_is_one_line(capsys):
    args = ["twomass", "--J-motor", "0.1", "--J-load", "-1", "--stiffness", "1", "--alpha", "20", "--Ts", "1e-3"]
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.err.splitlines() == ["pmsm2dof: error: --J-load = -1.0 is invalid: valid range is finite and > 0"]
    assert captured.out == ""
