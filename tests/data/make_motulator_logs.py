"""Write tests/data/motulator_identification.npz: a drive log made by motulator, not by pmsm2dof.

Run once with a Python (3.12) that has motulator (0.18 made the committed file); it never imports
pmsm2dof::

    python tests/data/make_motulator_logs.py

The drive: motulator's PMSM model (amplitude-invariant space vectors, p = 4, Rs = 0.5 ohm,
Ld = Lq = 10 mH, psi_f = 0.2 Wb), its mechanics with J = 0.01 kg m^2 and a friction function
B_L(w) w = B w + Tc tanh(w / 0.5 rad/s) (B = 0.003 Nm s/rad, Tc = 0.3 Nm), a load of 1.5 Nm
from 1.5 to 1.8 s that the log does not record, its averaged converter (540 V), its sensored
current-vector controller (4 kHz) and PI speed controller, speed steps of +-1000 rpm held for 1 s each. The log
holds what the controller sees at its samples, decimated to 1 kHz: time_s, speed_rpm, id_A,
iq_A, iq_ref_A, speed_ref_rpm; the true values are stored beside them (true_J_kgm2, ...).
"""

from pathlib import Path

import numpy as np

J, B, TC, W_C = 0.01, 0.003, 0.3, 0.5
REFERENCE_RPM = [(0.05, 1000.0), (1.0, -800.0), (2.0, 600.0), (3.0, -1200.0), (4.0, 300.0)]


def friction_coefficient(w_M):
    """B_L of motulator's MechanicalSystem: the friction torque divided by the speed."""
    if abs(w_M) < 1e-9:
        return B + TC / W_C
    return B + TC * np.tanh(w_M / W_C) / w_M


def speed_reference(t):
    w = 0.0
    for t_k, rpm in REFERENCE_RPM:
        if t >= t_k:
            w = rpm * np.pi / 30.0
    return w


def main():
    import motulator.drive.control.sm as control
    import motulator.drive.model as model

    par = model.SynchronousMachinePars(n_p=4, R_s=0.5, L_d=0.01, L_q=0.01, psi_f=0.2)
    mechanics = model.MechanicalSystem(J=J, B_L=friction_coefficient)
    mechanics.set_external_load_torque(lambda t: 1.5 if 1.5 <= t < 1.8 else 0.0)
    drive = model.Drive(model.SynchronousMachine(par), mechanics, model.VoltageSourceConverter(u_dc=540.0))
    vector = control.CurrentVectorController(par, control.CurrentVectorControllerCfg(i_s_max=7.6, T_s=2.5e-4))
    speed = control.PIController(k_p=0.3, k_i=4.6, k_t=0.3, u_max=9.0)
    ctrl = control.VectorControlSystem(vector, speed)
    ctrl.set_speed_ref(speed_reference)
    res = model.Simulation(drive, ctrl, show_progress=False).simulate(t_stop=5.0)
    every = slice(None, None, 4)
    t = np.asarray(res.ctrl.t)[every]
    i_s = np.asarray(res.ctrl.fbk.i_s)[every]
    i_ref = np.asarray(res.ctrl.ref.i_s)[every]
    w_M = np.real(np.asarray(res.ctrl.fbk.w_M))[every]
    w_ref = np.real(np.asarray(res.ctrl.ref.w_M))[every]
    out = Path(__file__).with_name("motulator_identification.npz")
    np.savez_compressed(
        out,
        time_s=t,
        speed_rpm=w_M * 30.0 / np.pi,
        speed_ref_rpm=w_ref * 30.0 / np.pi,
        id_A=i_s.real,
        iq_A=i_s.imag,
        iq_ref_A=i_ref.imag,
        true_J_kgm2=J,
        true_B_Nms=B,
        true_T_coulomb_Nm=TC,
    )
    print(f"wrote {out} ({t.size} rows)")


if __name__ == "__main__":
    main()
