"""A reference simulator of the electrical drive: the log a real drive records, from the physics.

An oracle for the electrical identification (``identify electrical``): it never imports
pmsm2dof. A PMSM on a dynamometer (the rotor speed is imposed by the caller, so there are no
mechanics) runs under a sampled dq current controller, and the log holds what a drive records,
with what real drives have and pmsm2dof's engine does not model:

- the inverter holds the STATOR-frame voltage vector over a PWM period, so the rotor-frame
  voltage turns by ``-w_e tau`` within the period;
- the reference is computed at the sample and applied ``voltage_delay_samples`` periods later,
  turned into the stator frame with an angle lead ``angle_lead_samples * w_e * Ts``;
- the inverter clips a vector beyond its linear range (|u| <= u_dc / sqrt(3)) to that circle;
- per-phase dead time: each phase voltage is short by ``dead_time_V * sign(i_phase)``;
- an optional q-axis saturation, ``i_q = psi_q / Lq (1 + sat_q (psi_q / psi_q_sat)^2)``.

Model (per phase, amplitude-invariant dq, d axis on the magnet, ``theta_e = p theta_m``): eq 1 of
the paper in flux form,

    d psi_dq / dt = u_dq(t) - Rs i_dq - j w_e psi_dq,
    i_d = (psi_d - psi_f) / Ld,   i_q = psi_q / Lq (1 + sat_q (psi_q / psi_q_sat)^2),

with the rotor-frame voltage inside a period ``u_dq(t) = u_alphabeta_held exp(-j theta_e(t))``.
Each sample period is integrated by SciPy ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-10 of each
state's scale). The electrical angle is a state of the same integration, ``d theta_e/dt = w_e(t)``
with ``w_e = p 2 pi / 60 speed_rpm(t)``: an adaptive quadrature of any speed profile, exact
for a piecewise-linear one to the integration's tolerance. The period means of the applied voltage
and of the currents, and the energies of the power balance, are states of the integration too.

Controller, at each sample ``t_k = k Ts``: the currents are sampled (the true currents plus seeded
Gaussian noise ``noise_A`` rms per axis: what is logged), a dq PI with decoupling tuned with the
nominal, unsaturated parameters (``Kp = L alpha_c``, ``Ki = Rs alpha_c``, ``alpha_c`` default 0.1 rad / Ts),

    u_d = Kp_d e_d + x_d - w_e Lq i_q,   u_q = Kp_q e_q + x_q + w_e (Ld i_d + psi_f),

gives ``u_ref`` (logged as ``ud_V``, ``uq_V``). Anti-windup by back-calculation with the gain
``Ka = 1 / Kp`` of each axis (the project's convention for the speed loop, Fig. 5 of the paper): the
controller knows the inverter's limit, ``u_lim = u_ref`` scaled to the circle ``|u| <= u_dc / sqrt(3)``,
and ``x_{k+1} = x_k + Ki Ts (e_k + (u_lim - u_ref) / Kp)`` (forward Euler).

Inverter: the reference of sample k is turned into the stator frame at
``theta_e(t_k) + angle_lead_samples w_e(t_k) Ts``, clipped to the circle (``voltage_limited`` = 1
at row k where it was), and applied over ``[t_{k+d}, t_{k+d+1})`` with ``d = voltage_delay_samples``
(zero voltage before the first reference arrives). With ``angle_lead_samples=None`` the clipped
reference is held in the rotor frame instead (the convention of pmsm2dof's engine).

Dead time, by the standard average-voltage approximation (Choi and Sul, "Inverter output voltage
synthesis using novel dead time compensation", IEEE Trans. Power Electronics, 1996): the sign of
each phase current at the start of the period, held over the period (a current that changes sign
within a period is not modelled; a zero current gives no error). Each phase voltage
(amplitude-invariant inverse Clarke of the vector) is short by ``dead_time_V sign(i_x)``; the
Clarke transform of these errors, which drops their common mode as an isolated neutral does, is
the stator-frame hexagon vector

    e_alphabeta = -(2/3) dead_time_V sum_{x = a, b, c} sign(i_x) exp(j 2 pi n_x / 3),  n = 0, 1, 2,

4/3 dead_time_V long when no phase current is zero, added to the held vector in either mode.

Cost: the per-period ``solve_ivp`` calls, 0.15 to 0.35 ms a period, growing with the angle the
rotor turns in a period (4000 periods of 100 us: 0.56 s at w_e Ts = 0.06 rad, 0.87 s with
saturation, dead time, noise and a speed ramp to w_e Ts = 0.13 rad, 1.3 s at w_e Ts = 0.42 rad),
measured on one core of a shared 2-core machine. No faster scheme is needed.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

RADPS_PER_RPM = 2.0 * math.pi / 60.0
SQRT3 = math.sqrt(3.0)

#: The columns a drive records, in the order :func:`write_csv` writes them.
CSV_COLUMNS = ("time_s", "speed_rpm", "id_A", "iq_A", "ud_V", "uq_V")


def _check_positive(name, value):
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} = {value!r}: must be finite and > 0")


@dataclass(frozen=True)
class Machine:
    """A PMSM's electrical parameters (per phase, amplitude-invariant dq).

    Attributes
    ----------
    Rs_ohm : stator resistance [ohm]
    Ld_H, Lq_H : d and q inductances [H] (Lq_H: the unsaturated one)
    psi_f_Wb : magnet flux linkage [Wb]
    pole_pairs : p
    sat_q : q-axis saturation strength [-], 0 for a linear machine
    psi_q_sat_Wb : the q flux at which ``i_q`` is ``1 + sat_q`` times the linear law's [Wb]
    """

    Rs_ohm: float
    Ld_H: float
    Lq_H: float
    psi_f_Wb: float
    pole_pairs: int
    sat_q: float = 0.0
    psi_q_sat_Wb: float = 1.0

    def __post_init__(self):
        for name in ("Rs_ohm", "Ld_H", "Lq_H", "psi_q_sat_Wb"):
            _check_positive(name, getattr(self, name))
        if not (math.isfinite(self.psi_f_Wb) and self.psi_f_Wb >= 0.0):
            raise ValueError(f"psi_f_Wb = {self.psi_f_Wb!r}: must be finite and >= 0")
        if not (math.isfinite(self.sat_q) and self.sat_q >= 0.0):
            raise ValueError(f"sat_q = {self.sat_q!r}: must be finite and >= 0")
        if int(self.pole_pairs) != self.pole_pairs or self.pole_pairs < 1:
            raise ValueError(f"pole_pairs = {self.pole_pairs!r}: must be an integer >= 1")

    def iq_from_psi_q(self, psi_q_Wb: float) -> float:
        """``i_q = psi_q / Lq (1 + sat_q (psi_q / psi_q_sat)^2)`` [A]."""
        return psi_q_Wb / self.Lq_H * (1.0 + self.sat_q * (psi_q_Wb / self.psi_q_sat_Wb) ** 2)

    def psi_q_from_iq(self, iq_A: float) -> float:
        """The q flux [Wb] at ``iq_A``: the root of the monotonic cubic of :meth:`iq_from_psi_q`."""
        if self.sat_q == 0.0 or iq_A == 0.0:
            return self.Lq_H * iq_A
        # |psi_q| <= Lq |i_q|, since the saturation only adds current
        bound = self.Lq_H * abs(iq_A)
        return brentq(lambda psi: self.iq_from_psi_q(psi) - iq_A, -bound, bound, xtol=1e-15 * bound, rtol=1e-15)

    def Lq_apparent_H(self, iq_A: float) -> float:
        """``psi_q / i_q`` at ``iq_A`` [H] (``Lq_H`` at zero current)."""
        if iq_A == 0.0:
            return self.Lq_H
        return self.psi_q_from_iq(iq_A) / iq_A

    def Lq_incremental_H(self, iq_A: float) -> float:
        """``d psi_q / d i_q`` at ``iq_A`` [H]: ``Lq / (1 + 3 sat_q (psi_q / psi_q_sat)^2)``."""
        psi_q = self.psi_q_from_iq(iq_A)
        return self.Lq_H / (1.0 + 3.0 * self.sat_q * (psi_q / self.psi_q_sat_Wb) ** 2)


def simulate_log(
    machine: Machine,
    *,
    Ts_s: float,
    t_end_s: float,
    speed_rpm: Callable[[float], float],
    i_ref_A: Callable[[float], tuple[float, float]],
    u_dc_V: float,
    voltage_delay_samples: int = 0,
    angle_lead_samples: float | None = 0.5,
    dead_time_V: float = 0.0,
    noise_A: float = 0.0,
    seed: int = 0,
    alpha_c_radps: float | None = None,
    theta_e0_rad: float = 0.0,
) -> dict[str, np.ndarray]:
    """Simulate the drive and return its log, one row per sample ``t_k = k Ts`` (module docstring).

    Parameters
    ----------
    machine : Machine
    Ts_s : sampling (and PWM) period [s]
    t_end_s : duration [s]; the log has ``round(t_end_s / Ts_s)`` rows
    speed_rpm : callable t_s -> mechanical speed [rpm], imposed by the dynamometer
    i_ref_A : callable t_s -> (id_ref, iq_ref) [A], read at each sample
    u_dc_V : DC-link voltage [V]; the linear range is |u| <= u_dc / sqrt(3)
    voltage_delay_samples : 0 or 1, periods between a reference and the period it applies over
    angle_lead_samples : float or None
        X: the reference is turned to the stator frame at theta_e + X w_e Ts and held there.
        None: the (clipped) reference is held in the rotor frame over its period, as pmsm2dof's
        engine does (the dead-time error stays a stator-frame vector).
    dead_time_V : per-phase voltage error [V], phase voltage = reference - dead_time_V sign(i_x)
    noise_A : rms Gaussian noise added to each measured current [A]
    seed : seed of the noise
    alpha_c_radps : current-loop bandwidth [rad/s] (default 0.1 / Ts)
    theta_e0_rad : electrical angle at t = 0 [rad]

    Returns
    -------
    dict of str -> ndarray
        The drive's log: ``time_s``, ``speed_rpm``, ``theta_e_rad`` (wrapped to [0, 2 pi)),
        ``id_A``, ``iq_A`` (measured, with noise), ``ud_V``, ``uq_V`` (the reference, before the
        inverter's clip and dead time), ``voltage_limited`` (1 where the row's reference was
        clipped), ``udc_V``. The truth: ``id_true_A``, ``iq_true_A``, ``psi_d_Wb``, ``psi_q_Wb`` at
        the sample; ``id_ref_A``, ``iq_ref_A``; over the period that starts at the row, the
        means of the applied rotor-frame voltage ``ud_mean_V``, ``uq_mean_V`` and of the true
        currents ``id_mean_A``, ``iq_mean_A``; the energies from t = 0 to the row [J]:
        ``energy_in_J`` (of (3/2) u.i), ``energy_copper_J`` (of (3/2) Rs |i|^2),
        ``energy_mech_J`` (of (3/2) w_e (psi_d i_q - psi_q i_d)).
    """
    _check_positive("Ts_s", Ts_s)
    _check_positive("t_end_s", t_end_s)
    _check_positive("u_dc_V", u_dc_V)
    if voltage_delay_samples not in (0, 1):
        raise ValueError(f"voltage_delay_samples = {voltage_delay_samples!r}: must be 0 or 1")
    if angle_lead_samples is not None and not math.isfinite(angle_lead_samples):
        raise ValueError(f"angle_lead_samples = {angle_lead_samples!r}: must be finite")
    for name, value in (("dead_time_V", dead_time_V), ("noise_A", noise_A)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{name} = {value!r}: must be finite and >= 0")
    n_rows = round(t_end_s / Ts_s)
    if n_rows < 1:
        raise ValueError(f"t_end_s = {t_end_s!r}: must hold at least one period of Ts_s = {Ts_s!r}")
    alpha_c = 0.1 / Ts_s if alpha_c_radps is None else alpha_c_radps
    _check_positive("alpha_c_radps", alpha_c)

    m = machine
    Rs, Ld, Lq, psi_f, p = m.Rs_ohm, m.Ld_H, m.Lq_H, m.psi_f_Wb, m.pole_pairs
    k_sat = m.sat_q / m.psi_q_sat_Wb**2
    u_max = u_dc_V / SQRT3
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, noise_A, size=(n_rows, 2)) if noise_A > 0.0 else np.zeros((n_rows, 2))

    # scales of the states for the absolute tolerances
    psi_scale = max(psi_f, u_max * Ts_s)
    i_scale = psi_scale / min(Ld, Lq)
    atol = 1e-10 * np.array(
        [psi_scale, psi_scale, 1.0, u_max * Ts_s, u_max * Ts_s, i_scale * Ts_s, i_scale * Ts_s]
        + [1.5 * u_max * i_scale * Ts_s] * 3
    )

    def currents(psi_d, psi_q):
        return (psi_d - psi_f) / Ld, psi_q / Lq * (1.0 + k_sat * psi_q * psi_q)

    def rhs(t, y, theta_k, u_rotor_d, u_rotor_q, u_alpha, u_beta):
        psi_d, psi_q, phi = y[0], y[1], y[2]
        theta = theta_k + phi
        c, s = math.cos(theta), math.sin(theta)
        # u_dq = u_rotor + u_alphabeta exp(-j theta_e)
        u_d = u_rotor_d + u_alpha * c + u_beta * s
        u_q = u_rotor_q - u_alpha * s + u_beta * c
        i_d, i_q = currents(psi_d, psi_q)
        w_e = p * RADPS_PER_RPM * speed_rpm(t)
        return [
            # eq 1 in flux form: d psi/dt = u - Rs i - j w_e psi
            u_d - Rs * i_d + w_e * psi_q,
            u_q - Rs * i_q - w_e * psi_d,
            w_e,
            u_d,
            u_q,
            i_d,
            i_q,
            1.5 * (u_d * i_d + u_q * i_q),
            1.5 * Rs * (i_d * i_d + i_q * i_q),
            1.5 * w_e * (psi_d * i_q - psi_q * i_d),
        ]

    keys = (
        "time_s speed_rpm theta_e_rad id_A iq_A ud_V uq_V voltage_limited udc_V id_true_A iq_true_A "
        "psi_d_Wb psi_q_Wb id_ref_A iq_ref_A ud_mean_V uq_mean_V id_mean_A iq_mean_A "
        "energy_in_J energy_copper_J energy_mech_J"
    ).split()
    log = {key: np.zeros(n_rows) for key in keys}
    log["udc_V"][:] = u_dc_V

    Kp_d, Kp_q, Ki = Ld * alpha_c, Lq * alpha_c, Rs * alpha_c
    x_d = x_q = 0.0  # PI integrators [V]
    psi_d, psi_q, theta = psi_f, 0.0, theta_e0_rad  # zero current at t = 0
    energies = np.zeros(3)
    # voltages not yet applied: (rotor-frame d, q, stator-frame alpha, beta) [V]
    pending = [(0.0, 0.0, 0.0, 0.0)] * voltage_delay_samples
    for k in range(n_rows):
        t_k = k * Ts_s
        speed_k = float(speed_rpm(t_k))
        w_e = p * RADPS_PER_RPM * speed_k
        i_d, i_q = currents(psi_d, psi_q)
        id_meas, iq_meas = i_d + noise[k, 0], i_q + noise[k, 1]
        id_ref, iq_ref = (float(v) for v in i_ref_A(t_k))

        # dq PI with decoupling, e = i_ref - i_measured
        e_d, e_q = id_ref - id_meas, iq_ref - iq_meas
        u_d = Kp_d * e_d + x_d - w_e * Lq * iq_meas
        u_q = Kp_q * e_q + x_q + w_e * (Ld * id_meas + psi_f)
        u_abs = math.hypot(u_d, u_q)
        limited = u_abs > u_max
        scale = u_max / u_abs if limited else 1.0
        # back-calculation, Ka = 1 / Kp: x_{k+1} = x_k + Ki Ts (e_k + (u_lim - u_ref) / Kp)
        x_d += Ki * Ts_s * (e_d + (scale - 1.0) * u_d / Kp_d)
        x_q += Ki * Ts_s * (e_q + (scale - 1.0) * u_q / Kp_q)

        if angle_lead_samples is None:
            pending.append((scale * u_d, scale * u_q, 0.0, 0.0))
        else:
            # to the stator frame at theta_e(t_k) + X w_e Ts, clipped to the linear range
            angle = theta + angle_lead_samples * w_e * Ts_s
            ca, sa = math.cos(angle), math.sin(angle)
            pending.append((0.0, 0.0, scale * (u_d * ca - u_q * sa), scale * (u_d * sa + u_q * ca)))
        u_rotor_d, u_rotor_q, u_alpha, u_beta = pending.pop(0)

        if dead_time_V > 0.0:
            # phase currents at the start of the period (inverse Clarke of i_dq exp(j theta_e))
            c, s = math.cos(theta), math.sin(theta)
            i_alpha, i_beta = i_d * c - i_q * s, i_d * s + i_q * c
            i_abc = (i_alpha, -0.5 * i_alpha + 0.5 * SQRT3 * i_beta, -0.5 * i_alpha - 0.5 * SQRT3 * i_beta)
            # the phase voltages' errors -dead_time_V sign(i_x), by the amplitude-invariant Clarke
            e_a, e_b, e_c = (-dead_time_V * float(np.sign(i)) for i in i_abc)
            u_alpha += (2.0 * e_a - e_b - e_c) / 3.0
            u_beta += (e_b - e_c) / SQRT3

        row = {
            "time_s": t_k,
            "speed_rpm": speed_k,
            "theta_e_rad": theta % (2.0 * math.pi),
            "id_A": id_meas,
            "iq_A": iq_meas,
            "ud_V": u_d,
            "uq_V": u_q,
            "voltage_limited": float(limited),
            "id_true_A": i_d,
            "iq_true_A": i_q,
            "psi_d_Wb": psi_d,
            "psi_q_Wb": psi_q,
            "id_ref_A": id_ref,
            "iq_ref_A": iq_ref,
            "energy_in_J": energies[0],
            "energy_copper_J": energies[1],
            "energy_mech_J": energies[2],
        }
        for key, value in row.items():
            log[key][k] = value

        sol = solve_ivp(
            rhs,
            (t_k, t_k + Ts_s),
            [psi_d, psi_q, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            method="DOP853",
            rtol=1e-10,
            atol=atol,
            args=(theta, u_rotor_d, u_rotor_q, u_alpha, u_beta),
        )
        if sol.status != 0 or not np.all(np.isfinite(sol.y[:, -1])):
            raise RuntimeError(f"the period at t = {t_k:g} s did not integrate: {sol.message}")
        y = sol.y[:, -1]
        psi_d, psi_q, theta = float(y[0]), float(y[1]), theta + float(y[2])
        log["ud_mean_V"][k], log["uq_mean_V"][k] = y[3] / Ts_s, y[4] / Ts_s
        log["id_mean_A"][k], log["iq_mean_A"][k] = y[5] / Ts_s, y[6] / Ts_s
        energies += y[7:10]
    return log


def write_csv(log: dict[str, np.ndarray], path, *, udc: bool = True, voltage_limited: bool = True) -> None:
    """Write the columns a drive records to a CSV file that ``pmsm2dof.sim.logs.read_log`` reads.

    Columns: ``time_s, speed_rpm, id_A, iq_A, ud_V, uq_V``, then (optionally) the DC link as
    ``u_dc_V`` (the name read_log knows) and ``voltage_limited`` (0 or 1). Values are written with
    17 significant digits, so the file holds the log's doubles exactly.
    """
    names = list(CSV_COLUMNS)
    columns = [np.asarray(log[name], dtype=float) for name in names]
    if udc:
        names.append("u_dc_V")
        columns.append(np.asarray(log["udc_V"], dtype=float))
    if voltage_limited:
        names.append("voltage_limited")
        columns.append(np.asarray(log["voltage_limited"], dtype=float))
    table = np.column_stack(columns)
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
