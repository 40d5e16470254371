"""Design figures: Bode diagrams and linear step responses (paper Fig. 7, eq 5, 6, 8).

Figures are built on ``matplotlib.figure.Figure`` with the Agg canvas (no
display, no global pyplot state) and saved as PNG or SVG by file extension.
Frequency and time responses come from python-control.
"""

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import control
import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ...analysis.design import Design, design
from ...core.bindings import Feedforward
from ...errors import ConfigError, require_positive

_POINTS = 600


def _figure(rows: int) -> tuple[Figure, list[Axes]]:
    fig = Figure(figsize=(7.0, 2.6 * rows + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, list(fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0])


def _omega_radps(systems: Sequence[control.LTI]) -> npt.NDArray[np.float64]:
    """A log-spaced frequency grid two decades around every pole and zero [rad/s]."""
    corners = np.concatenate([np.abs(np.concatenate([control.poles(s), control.zeros(s)])) for s in systems])
    corners = corners[corners > 0.0]
    lo, hi = (corners.min(), corners.max()) if corners.size else (1.0, 1.0)
    return np.logspace(np.log10(lo) - 2.0, np.log10(hi) + 2.0, _POINTS)


def _bode(
    axes: Sequence[Axes],
    systems: Sequence[control.LTI],
    labels: Sequence[str],
    styles: Sequence[Mapping[str, Any]] | None = None,
) -> None:
    """Magnitude [dB] and unwrapped phase [deg] of ``systems`` on two axes."""
    omega = _omega_radps(systems)
    for k, (sys, label) in enumerate(zip(systems, labels)):
        response = control.frequency_response(sys, omega)
        style = styles[k] if styles else {}
        axes[0].semilogx(omega, 20.0 * np.log10(np.abs(response.magnitude)), label=label, **style)
        axes[1].semilogx(omega, np.degrees(np.unwrap(response.phase)), label=label, **style)
    axes[0].set_ylabel("magnitude [dB]")
    axes[1].set_ylabel("phase [deg]")
    axes[1].set_xlabel("frequency [rad/s]")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize="small")


def bode_gx_sweep(
    alpha_radps: float,
    m_values: Iterable[float],
    J_kgm2: float = 0.4,
    zeta: float = 0.2887,
    tau_i_s: float = 0.05,
    feedforward: Feedforward = "lowpass",
) -> Figure:
    """Bode diagram of the tracking response ``Gx`` (eq 6) for several ``m`` (paper Fig. 7).

    With the ``full`` feedforward ``Gx = m alpha / (s + m alpha)`` (eq 10) whatever
    J, zeta and tau_i; the paper's Fig. 7 is alpha = 0.5 and m from 0.2 to 2 with it.
    The default feedforward, ``lowpass`` (eq 13), takes m = 1 only. The defaults of J,
    zeta and tau_i are the paper's section 4 values.

    Returns
    -------
    matplotlib.figure.Figure
    """
    ms = [require_positive("m", m) for m in m_values]
    if not ms:
        raise ConfigError("m", ms, "at least one value > 0")
    designs = [design(J_kgm2, alpha_radps, zeta, m=m, tau_i_s=tau_i_s, feedforward=feedforward) for m in ms]
    fig, axes = _figure(2)
    _bode(axes, [d.Gx for d in designs], [f"m = {m:g}" for m in ms])
    axes[0].set_title(f"Tracking Gx(s), alpha = {alpha_radps:g} rad/s, feedforward {feedforward} (Fig. 7)")
    return fig


def bode_gn(d: Design) -> Figure:
    """Bode diagram of the load rejection ``GN`` (eq 5, 8) of the 1DOF PI and of ``d``.

    The two curves coincide: the feedforward does not enter ``GN``.
    """
    one_dof = dataclasses.replace(d, feedforward="none")
    fig, axes = _figure(2)
    _bode(
        axes,
        [one_dof.GN, d.GN],
        ["1DOF PI", f"2DOF, feedforward {d.feedforward}"],
        styles=[{"linewidth": 3.0, "alpha": 0.5}, {"linestyle": "--"}],
    )
    axes[0].set_title("Load rejection GN(s), load torque [Nm] to speed [rad/s] (eq 8)")
    return fig


def step_responses(d: Design) -> Figure:
    """Linear unit-step responses: tracking ``Gx`` (1DOF and 2DOF) and load rejection ``GN``.

    Top: speed [rad/s] after a 1 rad/s reference step. Bottom: speed [rad/s]
    after a 1 Nm load-torque step (eq 8).
    """
    one_dof = dataclasses.replace(d, feedforward="none")
    slowest = min(np.min(np.abs(np.real(d.closed_loop_poles()))), d.m * d.alpha_radps)
    t_s = np.linspace(0.0, 8.0 / slowest, 2000)
    fig, axes = _figure(2)
    for sys, label in ((one_dof.Gx, "1DOF PI"), (d.Gx, f"2DOF, feedforward {d.feedforward}")):
        axes[0].plot(t_s, control.step_response(sys, t_s).outputs, label=label)
    axes[0].set_ylabel("speed [rad/s]")
    axes[0].set_title("Reference step of 1 rad/s")
    axes[1].plot(t_s, control.step_response(d.GN, t_s).outputs, color="C3", label="1DOF and 2DOF")
    axes[1].set_ylabel("speed [rad/s]")
    axes[1].set_title("Load-torque step of 1 Nm")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    return fig
