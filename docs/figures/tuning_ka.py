"""Tuning guide, Ka: the 1DOF PI's 500 rpm step at the current limit, back calculation and clamping."""

import matplotlib.pyplot as plt

import pmsm2dof

base = pmsm2dof.load_scenario("paper-condition-1").with_overrides(
    {
        "speed_controller.feedforward": "none",
        "simulation.t_end_s": 12.0,
        "reference": [{"t_s": 0.0, "speed_rpm": 500.0}],
    }
)
Kp = pmsm2dof.design(J_kgm2=0.4, alpha_radps=0.5, zeta=0.2887).Kp
fig, ax = plt.subplots(figsize=(9, 3.4))
cases = {"no anti-windup": {"speed_controller.anti_windup": "none"}}
for factor, text in ((1 / 3, "1/(3 Kp)"), (1.0, "1/Kp"), (3.0, "3/Kp")):
    cases[f"Ka = {text}"] = {"speed_controller.Ka": factor / Kp}
cases["clamping"] = {"speed_controller.anti_windup": "clamping"}
for label, overrides in cases.items():
    r = pmsm2dof.simulate(base.with_overrides(overrides))
    overshoot = pmsm2dof.compute_metrics(r)["reference_steps"][0]["overshoot_pct"]["value"] or 0.0
    ax.plot(r.t_s, r.speed_rpm, label=f"{label}: overshoot {overshoot:.1f} %")
ax.set(xlabel="time [s]", ylabel="speed [rpm]", title="1DOF PI, 500 rpm step at the 7.6 A limit")
ax.grid(True, alpha=0.3)
ax.legend(fontsize="small")
fig.tight_layout()
