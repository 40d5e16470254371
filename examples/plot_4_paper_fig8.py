"""
Reproduce the paper's Fig. 8: speed with and without anti-windup
================================================================

Simulation condition 1 (section 4.1): no load, 500 rpm at 0 s, 200 rpm at 5 s, current vector
limited to 7.6 A, ``Kp = 0.2``, ``Ki = 0.3`` (``J = 0.4 kg m^2``, ``alpha = 0.5 rad/s``, eq 9).
Top: the 1DOF PI, bottom: the 2DOF controller of eq 15, each without anti-windup, with back
calculation (Fig. 5) and with clamping. The paper reports more than 55 % overshoot without
anti-windup and about 16 % with it; ``pmsm2dof reproduce`` compares every claim with these runs
(see the claims table of the getting-started page for why the numbers differ).
"""

import matplotlib.pyplot as plt

import pmsm2dof

base = pmsm2dof.load_scenario("paper-condition-1")
controllers = {"1DOF PI": "none", "2DOF (eq 15)": "lowpass"}
modes = {"none": "no anti-windup", "back_calculation": "back calculation", "clamping": "clamping"}

fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
for ax, (title, feedforward) in zip(axes, controllers.items()):
    for anti_windup, label in modes.items():
        r = pmsm2dof.simulate(
            base.with_overrides(
                {"speed_controller.feedforward": feedforward, "speed_controller.anti_windup": anti_windup}
            )
        )
        overshoot = pmsm2dof.compute_metrics(r)["reference_steps"][0]["overshoot_pct"]["value"]
        ax.plot(r.t_s, r.speed_rpm, label=f"{label} (overshoot {overshoot or 0:.1f} %)")
    ax.plot(r.t_s, r.speed_ref_rpm, "k:", linewidth=1, label="reference")
    ax.set_title(title)
    ax.set_ylabel("speed [rpm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper right")
axes[-1].set_xlabel("time [s]")
fig.tight_layout()
