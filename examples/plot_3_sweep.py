"""
A small sweep: bandwidth against the true inertia
=================================================

A sweep runs a scenario over a grid (or Monte Carlo draws) of any scenario keys on all cores and
stores one row of metrics per point. Here the paper's 2DOF controller, designed for ``J = 0.4
kg m^2``, drives plants from half to twice that inertia, for five bandwidths: a 4 x 5 grid of
condition 2 (speed steps and an 8 Nm load step). ``pmsm2dof sweep FILE.toml`` runs the same
description from a TOML file (``examples/sweeps/``) and draws the heatmaps itself.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from pmsm2dof.studies.sweep import parse_sweep
from pmsm2dof.studies.sweep_run import run_sweep

sweep = parse_sweep(
    {
        "name": "alpha-inertia-small",
        "base": "paper-condition-2",
        "axes": {
            "speed_controller.alpha_radps": {"start": 0.25, "stop": 2.0, "num": 4, "scale": "log"},
            "motor.J_kgm2": {"start": 0.2, "stop": 0.8, "num": 5},
        },
    }
)
with tempfile.TemporaryDirectory() as tmp:
    run = run_sweep(sweep, Path(tmp) / "sweep", progress=False)
table = run.table
print(f"{len(table)} points, {run.computed} simulated")
print(table[["speed_controller.alpha_radps", "motor.J_kgm2", "load0_speed_dip_rpm", "ref0_overshoot_pct"]])

# %%
# The speed dip after the load step: the bandwidth sets the rejection (eq 8), the true inertia
# scales it.

dip = table.pivot(index="motor.J_kgm2", columns="speed_controller.alpha_radps", values="load0_speed_dip_rpm")
fig, ax = plt.subplots(figsize=(6, 3.6))
image = ax.imshow(dip.to_numpy(dtype=float), origin="lower", aspect="auto", cmap="viridis")
ax.set_xticks(range(dip.shape[1]), [f"{a:.2g}" for a in dip.columns])
ax.set_yticks(range(dip.shape[0]), [f"{j:.2g}" for j in dip.index])
ax.set_xlabel("alpha [rad/s]")
ax.set_ylabel("plant inertia [kg m^2]")
fig.colorbar(image, label="speed dip after the 8 Nm load step [rpm]")
fig.tight_layout()
