"""Tuning guide, zeta: the 1DOF PI's reference step (eq 4) and the load step (eq 8) for several zeta."""

import control
import matplotlib.pyplot as plt
import numpy as np

import pmsm2dof

fig, (ax_ref, ax_load) = plt.subplots(1, 2, figsize=(9, 3.4))
t_s = np.linspace(0, 30, 3000)
for zeta in (0.2, 0.2887, 0.5, 0.8):
    d = pmsm2dof.design(J_kgm2=0.4, alpha_radps=0.5, zeta=zeta, tau_i_s=0.05, feedforward="none")
    ax_ref.plot(t_s, control.step_response(d.Gx, t_s).outputs, label=f"zeta = {zeta:g}")
    ax_load.plot(t_s, control.step_response(d.GN, t_s).outputs * 60 / (2 * np.pi), label=f"zeta = {zeta:g}")
ax_ref.set(xlabel="time [s]", ylabel="speed / reference", title="1DOF PI, reference step (eq 4)")
ax_load.set(xlabel="time [s]", ylabel="speed [rpm]", title="1 Nm load step (eq 8), 1DOF and 2DOF")
for ax in (ax_ref, ax_load):
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
fig.tight_layout()
