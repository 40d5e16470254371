"""Write tests/data/motulator_electrical.npz: an electrical drive log made by motulator, not by pmsm2dof.

Run once with a Python (3.12) that has motulator (0.18.0 made the committed file); it never imports
pmsm2dof::

    python3.12 -m venv /tmp/motulator312 && /tmp/motulator312/bin/pip install motulator==0.18.0
    /tmp/motulator312/bin/python tests/data/make_motulator_electrical_log.py

The drive
---------
A salient interior-PM servo motor, values of the order of a 1 kW, 3000 rpm, 300 V-bus servo
(chosen, not from one datasheet): p = 4, Rs = 0.45 ohm, Ld = 3.2 mH, Lq = 6.4 mH (Lq/Ld = 2),
psi_f = 0.09 Wb, rated current 6 A (peak, amplitude-invariant dq), current limit 9 A. motulator's
linear machine model (``SynchronousMachinePars``, no saturation, no core losses), its mechanics with
J = 6e-4 kg m^2 and viscous friction B = 1e-4 Nm s/rad, an external load torque, its averaged
(switching-cycle) converter on a constant 300 V bus without dead time, its sensored current-vector
controller (continuous-time design, ``discrete=False``, T_s = 125 us, alpha_c = 2 pi 200 rad/s,
MTPA and field-weakening reference generator, the inertia J given to its angle observer) and its
2DOF PI speed controller (alpha_s = 2 pi 10 rad/s). The phase-current sensors add Gaussian noise
of 0.02 A rms per phase (seed 20). motulator's solver runs at rtol 1e-7, atol 1e-9 (its default
1e-3 is coarser than the targets).

The experiment excites every parameter of eq 1: a load torque of 2.5 Nm at standstill and a slow
run at 60 rpm under it (Rs: the resistive drop is most of the voltage), speed steps to 1500 and
4500 rpm (iq moves at the current limit; MTPA gives a negative id at high current, and at 4500 rpm
the voltage limit drives the machine into field weakening: id spans about 6 A, more than the
20 % of the rated current the Ld target needs), the load released and reapplied, a reversal to
-2000 rpm and a return to standstill (psi_f from the back-EMF at every speed).

The log
-------
What the controller sees at each sampling instant, every sample (8 kHz, 2 s): ``time_s``,
``speed_rpm`` (the sensored speed estimate the controller uses, ``fbk.w_M``), ``id_A``, ``iq_A``
(the measured currents in the controller's dq frame, ``fbk.i_s``), ``ud_V``, ``uq_V`` (the
controller's dq voltage reference, ``ref.u_s``, as a drive logs it). Signals as float32 (what a
drive logs), time as float64. Beside them: ``true_Rs_ohm``, ``true_Ld_H``, ``true_Lq_H``,
``true_psi_f_Wb``, ``pole_pairs``, ``rated_current_A``, ``Ts_s``, ``voltage_delay_samples``,
``angle_lead_samples``, ``max_angle_error_rad`` and ``conventions`` (this docstring's summary).

How motulator 0.18.0 turns the dq voltage reference into the machine's voltage
-----------------------------------------------------------------------------
(paths in the installed package ``motulator/``)

- Computational delay: one sampling period. ``Drive(delay=1)`` (drive/model/_drive.py, lines 37-40
  and 55) puts the duty ratios through ``Delay`` (common/model/_base.py, lines 330 and 367, the ring
  buffer of lines 462-496): the duty ratios computed at sample k are applied over [t_{k+1}, t_{k+2}).
  ``voltage_delay_samples = 1``.
- Angle: ``DriveControlSystem.modulate`` (drive/control/_base.py, lines 244-245) turns the
  reference into the stator frame with ``exp(1j*theta_c) * exp(1j*k_comp*T_s*w_c)``, theta_c the
  controller's rotor angle at sample k and w_c the speed of its frame; ``k_comp = 1.5`` for the
  continuous-time current controller (drive/control/_sm_current_vector.py, line 223; the docstring
  of ``DriveControlSystem``, drive/control/_base.py, lines 135-140: one period of computational
  delay plus half a period of the hold). ``angle_lead_samples = 1.5``.
- Hold: the averaged converter (``ZOH``, common/model/_pwm.py, lines 55-80, chosen by ``pwm=False``
  in common/model/_base.py, line 333) holds the phase duty ratios, so the stator-frame voltage
  vector, constant over the sampling period (double update: the half carrier period equals T_s);
  the machine model turns it into its rotor frame at every solver step (drive/model/_machine.py,
  line 338). Over the period it applies in, the rotor-frame voltage is
  ``u_logged * exp(j (1.5 w_e T_s - w_e (tau + T_s)))``, tau in [0, T_s): its mean over the period
  is ``u_logged * sinc(w_e T_s / 2)``, no rotation left, which is what the 1.5 compensates. Within
  the period the rotor-frame flux moves along an arc, so the currents sampled at the period
  boundaries are not the period means (at 4500 rpm, w_e T_s = 0.24 rad, the flux at the samples is
  about (w_e T_s)^2 / 12 = 0.5 % above its period mean).
- Frame: sensored mode (``sensorless=False``) tracks the measured angle with an observer
  (drive/control/_sm_observers.py, lines 430-431 and 170, ``h = 1``; the angle predicted to the
  next sample at line 228); given ``J`` (as here) it feeds the torque estimate forward
  (drive/control/_common.py, line 254), so its angle stays on the measured one under acceleration
  (largest electrical error ``max_angle_error_rad`` over the run; without ``J`` it lags by up to
  0.01 rad during the accelerations at the current limit, which shows in the fit as volts of
  residual).
- Scaling: peak-value (amplitude-invariant) space vectors (common/utils/_utils.py, lines 11-33,
  ``abc2complex``), the model's convention; motulator's rotor angle is electrical, d on the magnet.
- Voltage limit: space-vector PWM with minimum-phase-error overmodulation
  (common/control/_pwm.py, lines 271-281) clips the reference beyond u_dc/sqrt(3); the logged
  ``ref.u_s`` is the reference before that limit. The run stays inside the linear range at every
  sample: this script checks that the limited voltage equals the advanced reference
  (``ref.u_s_lim``, drive/control/_base.py, line 231) and refuses to write the file otherwise.
"""

import math
from pathlib import Path

import numpy as np

P = 4
RS, LD, LQ, PSI_F = 0.45, 3.2e-3, 6.4e-3, 0.09
I_RATED, I_MAX = 6.0, 9.0
J, B = 6e-4, 1e-4
U_DC = 300.0
TS = 125e-6
T_STOP = 2.0
NOISE_A = 0.02
SEED = 20
#: (time s, speed reference rpm)
SPEED_RPM = [(0.0, 0.0), (0.15, 60.0), (0.35, 1500.0), (0.6, 4500.0), (1.2, -2000.0), (1.65, 0.0)]
#: (time s, load torque Nm)
LOAD_NM = [(0.0, 0.0), (0.02, 2.5), (0.5, 0.0), (0.95, 2.0), (1.85, 0.0)]

CONVENTIONS = (
    "motulator 0.18.0, Drive(delay=1), averaged converter (stator-frame voltage held over each period), "
    "CurrentVectorController(discrete=False): k_comp = 1.5, sensored; ud_V, uq_V = ref.u_s, the dq reference "
    "before the PWM limit (never reached); voltage_delay_samples = 1, angle_lead_samples = 1.5; "
    "amplitude-invariant dq, electrical angle, d on the magnet"
)


def schedule(table):
    """The value of a (time, value) table at t, held from each entry to the next."""

    def value(t):
        out = table[0][1]
        for t_k, v in table:
            if t >= t_k:
                out = v
        return out

    return value


def main():
    import motulator.drive.control.sm as control
    import motulator.drive.model as model
    from motulator.common.model import Sensor
    from motulator.common.model._simulation import SolverCfg

    par = model.SynchronousMachinePars(n_p=P, R_s=RS, L_d=LD, L_q=LQ, psi_f=PSI_F)
    sensor = Sensor(std=NOISE_A, rng=np.random.default_rng(SEED))
    machine = model.SynchronousMachine(par, i_s_sensor=sensor)
    mechanics = model.MechanicalSystem(J=J, B_L=B)
    load = schedule(LOAD_NM)
    mechanics.set_external_load_torque(load)
    drive = model.Drive(machine, mechanics, model.VoltageSourceConverter(u_dc=U_DC))
    cfg = control.CurrentVectorControllerCfg(i_s_max=I_MAX, T_s=TS, sensorless=False, J=J)
    vector = control.CurrentVectorController(par, cfg)
    tau_max = 1.5 * P * PSI_F * I_MAX
    speed = control.SpeedController(J=J, alpha_s=2 * math.pi * 10, tau_M_max=tau_max)
    ctrl = control.VectorControlSystem(vector, speed)
    rpm = schedule(SPEED_RPM)
    ctrl.set_speed_ref(lambda t: rpm(t) * math.pi / 30.0)
    sim = model.Simulation(drive, ctrl, show_progress=False, cfg=SolverCfg(rtol=1e-7, atol=1e-9))
    res = sim.simulate(t_stop=T_STOP)
    assert res.success, "motulator's simulation failed"

    t = np.asarray(res.ctrl.t)
    fbk, ref = res.ctrl.fbk, res.ctrl.ref
    i_s = np.asarray(fbk.i_s)
    u_s = np.asarray(ref.u_s)
    w_c = np.real(np.asarray(fbk.w_c))
    # the voltage the PWM realized (limited) against the advanced reference: equal inside the linear range
    advanced = u_s * np.exp(1j * vector.k_comp * TS * w_c)
    clipped = np.abs(np.asarray(ref.u_s_lim) - advanced) > 1e-6 * U_DC
    if np.any(clipped):
        raise SystemExit(f"{np.count_nonzero(clipped)} samples at the voltage limit: change the experiment")
    angle_error = P * np.abs(np.real(np.asarray(fbk.eps)))
    keep = t < T_STOP
    out = Path(__file__).with_name("motulator_electrical.npz")
    np.savez_compressed(
        out,
        time_s=t[keep],
        speed_rpm=(np.real(np.asarray(fbk.w_M)) * 30.0 / math.pi)[keep].astype(np.float32),
        id_A=i_s.real[keep].astype(np.float32),
        iq_A=i_s.imag[keep].astype(np.float32),
        ud_V=u_s.real[keep].astype(np.float32),
        uq_V=u_s.imag[keep].astype(np.float32),
        true_Rs_ohm=RS,
        true_Ld_H=LD,
        true_Lq_H=LQ,
        true_psi_f_Wb=PSI_F,
        pole_pairs=P,
        rated_current_A=I_RATED,
        Ts_s=TS,
        voltage_delay_samples=1,
        angle_lead_samples=vector.k_comp,
        max_angle_error_rad=float(np.max(angle_error)),
        conventions=CONVENTIONS,
    )
    i_d = i_s.real[keep]
    print(
        f"wrote {out} ({np.count_nonzero(keep)} rows, {out.stat().st_size / 1e3:.0f} kB); id {i_d.min():.2f} .. "
        f"{i_d.max():.2f} A, |u| max {np.max(np.abs(u_s)):.1f} V of {U_DC / math.sqrt(3):.1f} V, "
        f"angle error max {np.max(angle_error):.2e} rad"
    )


if __name__ == "__main__":
    main()
