"""
Design a speed controller from inertia and bandwidth
====================================================

The paper's drive (section 4): design inertia ``J = 0.4 kg m^2``, bandwidth ``alpha = 0.5
rad/s``, damping ``zeta = 0.2887``, current loop ``tau_i = 0.05 s``, and the 2DOF feedforward of
eq 11 with ``m = 1``. :func:`pmsm2dof.design` gives the PI gains of eq 9, the transfer functions
of the loop (python-control), its closed-loop poles and margins; ``discretize`` gives the
coefficients the C controller computes for a sampling period, with the margins of the sampled
loop.
"""

import pmsm2dof
from pmsm2dof.ui.plots.design import bode_gn, step_responses

d = pmsm2dof.design(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887, m=1.0, tau_i_s=0.05, feedforward="full")
print(f"Kp = {d.Kp:.4g} Nm/(rad/s), Ki = {d.Ki:.4g} Nm/rad (eq 9), Ka = {d.Ka:.4g} (rad/s)/Nm (1/Kp)")
print("closed-loop poles [rad/s]:", d.closed_loop_poles())
print(f"tracking bandwidth {d.bandwidth_radps():.3g} rad/s (m alpha), overshoot {d.overshoot_pct():.2g} %")
print(d.margins())

# %%
# Tracking and load rejection
# ---------------------------
# The feedforward makes the tracking first order, ``Gx = m alpha / (s + m alpha)`` (eq 10),
# while the load rejection ``GN`` (eq 8) is that of the PI alone: the two degrees of freedom.

fig_steps = step_responses(d)
fig_gn = bode_gn(d)

# %%
# The sampled controller
# ----------------------
# At 1 kHz with Tustin's method (Table 1, eq 14 and 15): the coefficients are read from the C
# core, the margins are those of the sampled loop (the plant held by a zero-order hold).

dd = d.discretize(1e-3, "tustin")
for name, value in dd.as_dict()["discrete"]["coefficients"].items():
    print(f"{name:>13} = {value:.9g}")
print(dd.as_dict()["discrete"]["margins"])
