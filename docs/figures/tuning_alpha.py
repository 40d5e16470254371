"""Tuning guide, alpha: the speed after a 1 Nm load step (eq 8) and the phase margin of L = F G against alpha."""

import control
import matplotlib.pyplot as plt
import numpy as np

import pmsm2dof

fig, (ax_dip, ax_pm) = plt.subplots(1, 2, figsize=(9, 3.4))
t_s = np.linspace(0, 20, 2000)
for alpha in (0.25, 0.5, 1.0, 2.0):
    d = pmsm2dof.design(J_kgm2=0.4, alpha_radps=alpha, zeta=0.2887, tau_i_s=0.05)
    ax_dip.plot(t_s, control.step_response(d.GN, t_s).outputs * 60 / (2 * np.pi), label=f"alpha = {alpha:g}")
ax_dip.set(xlabel="time [s]", ylabel="speed [rpm]", title="1 Nm load step (eq 8)")
ax_dip.legend(fontsize="small")
alphas = np.geomspace(0.05, 6.5, 60)
pm = [pmsm2dof.design(J_kgm2=0.4, alpha_radps=a, zeta=0.2887, tau_i_s=0.05).margins().phase_margin_deg for a in alphas]
ax_pm.semilogx(alphas, pm)
ax_pm.axvline(4 * 0.2887**2 / 0.05, color="k", linestyle=":", label="alpha tau_i = 4 zeta^2")
ax_pm.set(xlabel="alpha [rad/s]", ylabel="phase margin [deg]", title="zeta = 0.2887, tau_i = 0.05 s")
ax_pm.legend(fontsize="small")
for ax in (ax_dip, ax_pm):
    ax.grid(True, alpha=0.3)
fig.tight_layout()
