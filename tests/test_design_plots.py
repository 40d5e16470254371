"""Design figures: the curves drawn equal the paper's transfer functions evaluated here."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy import signal

from pmsm2dof.analysis.design import design
from pmsm2dof.ui.plots.canvas import save_figure
from pmsm2dof.ui.plots.design import bode_gn, bode_gx_sweep, step_responses

J, ALPHA, ZETA, TAU = 0.4, 0.5, 0.2887, 0.05
KP, KI = J * ALPHA, J * ALPHA**2 / (4 * ZETA**2)


def lines(ax):
    return [(line.get_xdata(), line.get_ydata()) for line in ax.get_lines()]


def test_fig7_bode_of_gx_is_first_order_for_each_m():
    m_values = [0.2, 0.5, 1.0, 2.0]
    fig = bode_gx_sweep(ALPHA, m_values, J_kgm2=J, zeta=ZETA, tau_i_s=TAU, feedforward="full")
    mag_ax, phase_ax = fig.axes[:2]
    assert len(mag_ax.get_lines()) == len(m_values)
    for m, (w, mag_dB), (_, phase_deg) in zip(m_values, lines(mag_ax), lines(phase_ax)):
        gx = m * ALPHA / (1j * w + m * ALPHA)  # eq 10
        np.testing.assert_allclose(mag_dB, 20 * np.log10(np.abs(gx)), atol=1e-6)
        np.testing.assert_allclose(phase_deg, np.degrees(np.angle(gx)), atol=1e-6)
        assert w.min() < 0.1 * m * ALPHA and w.max() > 10 * m * ALPHA


def test_bode_of_gn_is_eq8_and_the_same_for_1dof_and_2dof():
    fig = bode_gn(design(J, ALPHA, ZETA, tau_i_s=TAU, feedforward="full"))
    (w, mag_1dof), (w2, mag_2dof) = lines(fig.axes[0])
    s = 1j * w
    gn = -(TAU * s**2 + s) / (J * TAU * s**3 + J * s**2 + KP * s + KI)  # eq 8
    np.testing.assert_allclose(mag_1dof, 20 * np.log10(np.abs(gn)), atol=1e-6)
    np.testing.assert_array_equal(w, w2)
    np.testing.assert_array_equal(mag_1dof, mag_2dof)


def test_step_responses_match_scipy_integration():
    fig = step_responses(design(J, ALPHA, ZETA, m=1.0, tau_i_s=TAU, feedforward="full"))
    (t, y_1dof), (_, y_2dof) = lines(fig.axes[0])
    np.testing.assert_allclose(y_2dof, 1.0 - np.exp(-ALPHA * t), atol=1e-6)  # eq 10
    # 1DOF: F G / (1 + F G) = (Kp s + Ki) / (J tau s^3 + J s^2 + Kp s + Ki)
    _, y_ref = signal.step(([KP, KI], [J * TAU, J, KP, KI]), T=t)
    np.testing.assert_allclose(y_1dof, y_ref, atol=1e-6)
    assert y_1dof.max() > 1.3  # the overshoot the feedforward removes
    ((_, y_load),) = lines(fig.axes[1])
    _, y_load_ref = signal.step(([-TAU, -1.0, 0.0], [J * TAU, J, KP, KI]), T=t)  # eq 8
    np.testing.assert_allclose(y_load, y_load_ref, atol=1e-6)
    assert abs(y_load[-1]) < 1e-2 * abs(y_load).max()  # the integrator rejects a constant load


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_save_figure_writes_png_and_svg(tmp_path, suffix):
    path = save_figure(bode_gx_sweep(ALPHA, [1.0]), tmp_path / ("fig7" + suffix))
    data = path.read_bytes()
    if suffix == ".png":
        assert data.startswith(b"\x89PNG\r\n\x1a\n")
    else:
        assert ET.fromstring(data).tag.endswith("svg")
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_save_figure_refuses_unknown_format(tmp_path):
    with pytest.raises(ValueError, match="^out = .*png"):
        save_figure(bode_gx_sweep(ALPHA, [1.0]), tmp_path / "fig7.pdf")
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("m_values", [[], [0.5, -1.0], [float("nan")]])
def test_bode_sweep_refuses_bad_m(m_values):
    with pytest.raises(ValueError, match="^m = "):
        bode_gx_sweep(ALPHA, m_values)
