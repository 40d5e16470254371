"""Tuning guide, m: the linear tracking step (eq 6, 11) and a simulated 500 rpm step at the 7.6 A current limit."""

import control
import matplotlib.pyplot as plt
import numpy as np

import pmsm2dof

fig, (ax_lin, ax_sim) = plt.subplots(1, 2, figsize=(9, 3.4))
t_s = np.linspace(0, 12, 1200)
base = pmsm2dof.load_scenario("paper-condition-1").with_overrides(
    {
        "speed_controller.feedforward": "full",
        "simulation.t_end_s": 12.0,
        "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
    }
)
for m in (0.5, 1.0, 2.0, 4.0):
    d = pmsm2dof.design(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, m=m, tau_i_s=0.05, feedforward="full")
    ax_lin.plot(t_s, control.step_response(d.Gx, t_s).outputs, label=f"m = {m:g}")
    r = pmsm2dof.simulate(base.with_overrides({"speed_controller.m": m}))
    at_limit = pmsm2dof.compute_metrics(r)["reference_steps"][0]["current_limit_time_s"]["value"]
    ax_sim.plot(r.t_s, r.speed_rpm, label=f"m = {m:g} ({at_limit:.2f} s at the limit)")
ax_lin.set(xlabel="time [s]", ylabel="speed / reference", title="linear tracking Gx (eq 6, 11)")
ax_sim.set(xlabel="time [s]", ylabel="speed [rpm]", title="500 rpm step, 7.6 A limit")
for ax in (ax_lin, ax_sim):
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
fig.tight_layout()
