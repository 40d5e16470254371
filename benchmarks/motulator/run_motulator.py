"""Simulate one drive situation with motulator and time it (runs in its own venv).

This script is executed by ``benchmarks/bench_motulator.py`` with the Python of a
separate virtual environment that holds motulator; it never imports pmsm2dof.
Usage::

    python run_motulator.py SPEC.json OUT.npz

SPEC.json (SI units) describes the situation that ``bench_motulator.py`` derived
from a pmsm2dof scenario: machine, inertia, limits, controller gains, control
period, speed-reference and load-torque events, the stop time and the number of
timed runs. Every run builds the model and the control system from scratch and
simulates the whole situation; the wall and CPU time of each run are printed as JSON
on stdout, and the rotor speed of the last run is written to OUT.npz.

Mapping onto motulator's API (motulator.drive, version >= 0.10):

- machine: ``SynchronousMachine(SynchronousMachinePars(n_p, R_s, L_d, L_q, psi_f))``,
  peak-valued space vectors, so the torque is 1.5 n_p psi_f i_q as in pmsm2dof;
- mechanics: ``MechanicalSystem(J, B_L)`` with viscous friction B and the load
  torque as a function of time;
- converter: ``VoltageSourceConverter(u_dc)``, averaged (no PWM), with the
  ``Drive`` default of one sampling period of computational delay;
- current control: ``CurrentVectorController`` in sensored mode, its current PI given the
  decoupling feedforward and gains of pmsm2dof's dq PIs (see :func:`controller_classes`), so
  that the current loop is 1/(tau_i s + 1) (eq 3);
- speed control: ``PIController(k_p, k_i, k_t=k_p, u_max)``, the 1DOF PI whose
  integrator is driven by the realized (limited) torque; with k_t = k_p this is the
  back-calculation anti-windup of the paper's Fig. 5 with Ka = 1/Kp, integrated by
  the forward Euler rule at the control period.
"""

import json
import sys
import time
from math import inf

import numpy as np


def piecewise(events):
    """A function of time: 0 before the first event, then steps or linear ramps.

    Each event is ``(t_s, value, ramp_s)``: from ``t_s`` the signal moves from its
    previous value to ``value``, at once if ``ramp_s`` is 0, else linearly over
    ``ramp_s`` seconds (the same rule as pmsm2dof's scenario references).
    """
    events = [tuple(float(x) for x in ev) for ev in events]

    def value(t):
        y = 0.0
        for t_k, v_k, ramp_k in events:
            if t < t_k:
                break
            if ramp_k > 0.0 and t < t_k + ramp_k:
                y = y + (v_k - y) * (t - t_k) / ramp_k
            else:
                y = v_k
        return y

    return value


def controller_classes():
    """motulator subclasses that give its current control pmsm2dof's decoupled dq PIs.

    motulator's complex-vector PI rejects the back-EMF ``j w_m psi_f`` and the cross coupling
    through its integrator (with a rotation term ``j w_c``). At the paper's slow current loop
    (tau_i = 50 ms) that leaves a current error that grows with the acceleration (a ramp
    disturbance through a PI), which the dq PIs of pmsm2dof (``decouple = true``) do not
    have: they add ``j w_m psi_s(i)`` (back-EMF and cross coupling, from the measured current)
    as feedforward. The subclasses pass that feedforward as motulator's ``u_ff`` input, drop
    the rotation term of the integrator, and set k_p = k_t = alpha_c = 1/tau_i with integral
    bandwidth alpha_i = R_s/L: on flux linkages this is pmsm2dof's Kp = L/tau_i,
    Ki = R_s/tau_i per axis, whose zero cancels the stator pole, so that the current loop is
    1/(tau_i s + 1) of eq 3.
    """
    import motulator.drive.control.sm as control

    class DecoupledCurrentController(control.CurrentController):
        def __init__(self, par, alpha_c, alpha_i):
            super().__init__(par, alpha_c, alpha_i)
            self.k_p = self.k_t
            self.w_m = 0.0  # electrical rotor speed of this sample [rad/s]

        def compute_output(self, i_ref, i, u_ff=0j):
            u_dec = 1j * self.w_m * complex(self.par.psi_s_dq(i))
            return super().compute_output(i_ref, i, u_ff + u_dec)

        def update(self, T_s, u, w_c):
            super().update(T_s, u, 0.0)

    class DecoupledVectorController(control.CurrentVectorController):
        def get_feedback(self, u_s_ab, i_s_ab, w_M_meas, theta_M_meas):
            fbk = super().get_feedback(u_s_ab, i_s_ab, w_M_meas, theta_M_meas)
            self.current_ctrl.w_m = fbk.w_m
            return fbk

    return DecoupledCurrentController, DecoupledVectorController


def build(spec):
    """The drive model and its control system for ``spec``."""
    import motulator.drive.control.sm as control
    import motulator.drive.model as model

    DecoupledCurrentController, DecoupledVectorController = controller_classes()
    par = model.SynchronousMachinePars(
        n_p=int(spec["n_p"]), R_s=spec["R_s"], L_d=spec["L_d"], L_q=spec["L_q"], psi_f=spec["psi_f"]
    )
    machine = model.SynchronousMachine(par)
    mechanics = model.MechanicalSystem(J=spec["J"], B_L=spec["B"])
    mechanics.state.w_M = complex(spec["w_M0"])
    mechanics.set_external_load_torque(piecewise(spec["load"]))
    converter = model.VoltageSourceConverter(u_dc=spec["u_dc"])
    mdl = model.Drive(machine, mechanics, converter)

    cfg = control.CurrentVectorControllerCfg(
        i_s_max=spec["i_s_max"], alpha_c=spec["alpha_c"], sensorless=False, T_s=spec["T_s"]
    )
    vector_ctrl = DecoupledVectorController(par, cfg)
    vector_ctrl.current_ctrl = DecoupledCurrentController(par, spec["alpha_c"], spec["alpha_i"])
    speed_ctrl = control.PIController(k_p=spec["k_p"], k_i=spec["k_i"], k_t=spec["k_p"], u_max=inf)
    ctrl = control.VectorControlSystem(vector_ctrl, speed_ctrl)
    ctrl.set_speed_ref(piecewise(spec["reference"]))
    return mdl, ctrl


def simulate_once(spec):
    """Build the drive and its control system from ``spec``, simulate, return (t, w_M)."""
    import motulator.drive.model as model

    mdl, ctrl = build(spec)
    sim = model.Simulation(mdl, ctrl, show_progress=False)
    res = sim.simulate(t_stop=spec["t_end"])
    if not res.success:
        raise RuntimeError("motulator stopped before t_end")
    return np.asarray(res.mdl.t), np.asarray(res.mdl.mechanics.w_M)


def main(spec_path, out_path):
    from importlib.metadata import version

    import motulator  # noqa: F401  (fail early if the venv lacks it)

    with open(spec_path) as f:
        spec = json.load(f)
    walls, cpus = [], []
    for _ in range(int(spec["runs"])):
        start, cpu = time.perf_counter(), time.process_time()
        t_s, w_M = simulate_once(spec)
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    np.savez(out_path, t_s=t_s, w_M_radps=w_M)
    print(json.dumps({"motulator_version": version("motulator"), "wall_s": walls, "cpu_s": cpus}))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
