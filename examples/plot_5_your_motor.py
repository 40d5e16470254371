"""
Your motor: from its parameters to the C header
===============================================

A 750 W servo motor with a load of three times its own inertia, on a 325 V DC link. The steps:
the motor's data in the units pmsm2dof uses, a speed-controller design checked for margins and
for the sampling period, a simulation of the drive with its limits, and the C header that
configures the controllers on the MCU (``docs/mcu.md`` shows the firmware that includes it).

pmsm2dof takes SI units, per-phase values and the amplitude-invariant dq transform
(``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)``, see the conventions page).
"""

import tempfile
from pathlib import Path

import pmsm2dof
from pmsm2dof.core.motor import convert_datasheet
from pmsm2dof.ui.plots.trace import trace_figure

# %%
# The motor's data
# ----------------
# Datasheets give line-to-line resistance and inductance, a torque constant per RMS ampere and
# RMS currents. :func:`pmsm2dof.core.motor.convert_datasheet` converts them to per-phase,
# amplitude-invariant values and says where each one came from (``pmsm2dof motor FILE`` does the
# same for a ``[motor.datasheet]`` table; a scenario can hold that table instead of the values).

motor = convert_datasheet(
    {
        "poles": 8,
        "R_ohm": 1.8,  # line to line
        "L_H": 7.2e-3,  # line to line, surface PMSM
        "Kt_Nm_per_A": 0.80,  # per RMS phase ampere
        "I_rated_A": 9.0,  # peak rating of the drive, RMS
    }
)
for name, source in motor.sources.items():
    print(f"{name:>10}: {source}")
pole_pairs, Rs_ohm, Ld_H, Lq_H, psi_f_Wb = (motor.pole_pairs, motor.Rs_ohm, motor.Ld_H, motor.Lq_H, motor.psi_f_Wb)
assert motor.i_rated_A is not None
i_max_A = motor.i_rated_A  # dq amplitude = phase peak
J_motor_kgm2 = 1.2e-4
J_kgm2 = 4 * J_motor_kgm2  # motor plus a load of three times its inertia

# %%
# Design
# ------
# A current loop of ``tau_i = 1 ms`` (eq 3) at 10 kHz; the speed loop's bandwidth a decade below
# it, ``alpha = 60 rad/s`` with ``zeta = 0.5``, sampled at 1 kHz with Tustin's method.

Ts_s, method = 1e-3, "tustin"
d = pmsm2dof.design(J_kgm2=J_kgm2, alpha_radps=60.0, zeta=0.5, tau_i_s=1e-3)
dd = d.discretize(Ts_s, method)
print(f"Kp = {d.Kp:.4g} Nm/(rad/s), Ki = {d.Ki:.4g} Nm/rad")
print("sampled loop:", dd.as_dict()["discrete"]["margins"])

# %%
# Simulate the drive
# ------------------
# A step to 2000 rpm, then 2 Nm of load at 0.3 s.

scenario = pmsm2dof.Scenario.from_dict(
    {
        "name": "750 W servo",
        "motor": {
            "pole_pairs": pole_pairs,
            "Rs_ohm": Rs_ohm,
            "Ld_H": Ld_H,
            "Lq_H": Lq_H,
            "psi_f_Wb": psi_f_Wb,
            "J_kgm2": J_kgm2,
        },
        "limits": {"i_max_A": i_max_A, "u_dc_V": 325.0},
        "current_loop": {"model": "dq_pi", "tau_i_s": 1e-3, "Ts_s": 1e-4, "method": method},
        "speed_controller": {"alpha_radps": 60.0, "zeta": 0.5, "Ts_s": Ts_s, "method": method, "tau_i_s": 1e-3},
        "simulation": {"t_end_s": 0.6, "dt_s": 1e-5},
        "reference": [{"t_s": 0.0, "speed_rpm": 2000.0}],
        "load": [{"t_s": 0.3, "torque_Nm": 2.0}],
    }
)
r = pmsm2dof.simulate(scenario)
fig = trace_figure(r)
m = pmsm2dof.compute_metrics(r)
for event, names in (
    (m["reference_steps"][0], ("overshoot_pct", "rise_time_s")),
    (m["load_steps"][0], ("speed_dip_rpm", "recovery_time_s")),
):
    for name in names:  # each metric is a value, or None and the reason why
        print(f"{name:>16}: {event[name]['value'] if event[name]['value'] is not None else event[name]['reason']}")

# %%
# The C header
# ------------
# The complete configuration of the firmware's controllers for this scenario (speed and current
# controllers, speed-sensor estimator, loop rates): ``static const`` initializers for
# ``p2d_speed_init``, ``p2d_current_init``, ... (the same as ``pmsm2dof header SCENARIO --out
# p2d_config.h``, which the firmware of ``examples/firmware`` includes unchanged).

from pmsm2dof.studies.configuration import configuration  # noqa: E402

with tempfile.TemporaryDirectory() as tmp:
    header = configuration(scenario, source="examples/plot_5_your_motor.py").write_header(Path(tmp) / "p2d_config.h")
    print(header.read_text())
