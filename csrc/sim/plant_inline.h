/*
 * pmsm2dof: the plant's arithmetic of one period as static inline functions
 * on plain values, internal to the plant (plant.c) and the engine (drive.c):
 * the RK4 step of the equations of plant.h and the inverter. The engine's
 * loops, over one drive or over several in lockstep (an array per state
 * variable, which the compiler vectorises across the drives), inline them, so
 * that they compute what p2d_plant_advance and p2d_plant_command compute, from
 * this one source. C99, double; no declarations for the Python bindings
 * (ffibuild.py leaves the *_inline.h headers out).
 */
#ifndef PMSM2DOF_SIM_PLANT_INLINE_H
#define PMSM2DOF_SIM_PLANT_INLINE_H

#include <math.h>
#include <stdbool.h>

#include "plant.h"

/* Inlines a function where the compiler supports it (the RK4 step into its specialised loops). */
#if defined(__GNUC__)
#define P2D_PLANT_INLINE __attribute__((always_inline)) static inline
#else
#define P2D_PLANT_INLINE static inline
#endif

/* A plant state x = (id, iq, w_m, theta_m, theta, w_L), or its time derivative (each field then per second). */
typedef struct {
    double id_A;         /* d-axis current [A] */
    double iq_A;         /* q-axis current [A] */
    double w_m_radps;    /* motor speed [rad/s] */
    double theta_m_rad;  /* motor angle [rad] */
    double theta_rad;    /* two_mass: shaft twist theta_M - theta_L [rad] */
    double w_load_radps; /* two_mass: load-side speed [rad/s] */
} p2d_plant_x_t;

/* T_s = K (theta - sign(theta) b/2) + D (w_m - w_L) in contact, 0 in the play |theta| < b/2 */
P2D_PLANT_INLINE double p2d_plant_shaft(const p2d_plant_coef_t *c, double theta_rad, double w_twist_radps)
{
    double b_half = c->half_backlash_rad;
    if (fabs(theta_rad) < b_half) return 0.0;
    return c->K_Nm_per_rad * (theta_rad - copysign(b_half, theta_rad)) + c->D_Nms_per_rad * w_twist_radps;
}

/*
 * dx/dt at x (theta_m's rate is not needed: RK4 of dtheta_m/dt = w_m is closed-form below).
 * u_d, u_q: eq 1: ud / Ld, uq / Lq [A/s]; eq 3 (first_order): id_ref, iq_ref [A]. T_load: rigid:
 * T_load / J [rad/s^2]; two_mass: T_load [Nm]. Flags are constants at each call; lean: the caller
 * knows that Ld = Lq and B = 0 (cT_J = B_J = 0: the terms they scale are left out).
 */
P2D_PLANT_INLINE p2d_plant_x_t p2d_plant_rate(const p2d_plant_coef_t *c, p2d_plant_x_t x, double u_d, double u_q,
                                              double T_load, bool first_order, bool coulomb, bool two_mass, bool lean)
{
    p2d_plant_x_t dx;
    if (!first_order) {
        /* eq 1: did/dt = ud / Ld - (Rs / Ld) id + (p Lq / Ld) w_m iq */
        dx.id_A = u_d - c->Rs_Ld_per_s * x.id_A + c->p_Lq_Ld * x.w_m_radps * x.iq_A;
        /* eq 1: diq/dt = uq / Lq - (Rs / Lq) iq - w_m ((p Ld / Lq) id + p psi_f / Lq) */
        dx.iq_A = u_q - c->Rs_Lq_per_s * x.iq_A - x.w_m_radps * (c->p_Ld_Lq * x.id_A + c->p_psi_Lq_A);
    } else {
        /* eq 3: di/dt = (i_ref - i) / tau_i */
        dx.id_A = (u_d - x.id_A) * c->inv_tau_i_per_s;
        dx.iq_A = (u_q - x.iq_A) * c->inv_tau_i_per_s;
    }
    /* dw_m/dt = Te / J - (B / J) w_m, Te / J = iq (1.5 p psi_f / J + 1.5 p (Ld - Lq) / J id) */
    if (lean) {
        dx.w_m_radps = x.iq_A * c->kt_J;
    } else {
        dx.w_m_radps = x.iq_A * (c->kt_J + c->cT_J * x.id_A) - c->B_J_per_s * x.w_m_radps;
    }
    /* - (T_c / J) tanh(w_m / w_c) */
    if (coulomb) dx.w_m_radps -= c->Tc_J_radps2 * tanh(x.w_m_radps * c->inv_w_c_s_per_rad);
    dx.theta_m_rad = 0.0;
    if (two_mass) {
        double T_s = p2d_plant_shaft(c, x.theta_rad, x.w_m_radps - x.w_load_radps);
        /* J_M dw_m/dt = Te - T_s - T_f */
        dx.w_m_radps -= T_s * c->inv_J_per_kgm2;
        /* dtheta/dt = w_m - w_L */
        dx.theta_rad = x.w_m_radps - x.w_load_radps;
        /* J_L dw_L/dt = T_s - T_load */
        dx.w_load_radps = (T_s - T_load) * c->inv_J_load_per_kgm2;
    } else {
        /* J dw_m/dt = Te - T_load - T_f */
        dx.w_m_radps -= T_load;
        dx.theta_rad = 0.0;
        dx.w_load_radps = 0.0;
    }
    return dx;
}

/* x + k dx (theta and w_L with two_mass, else left as x's; theta_m left) */
P2D_PLANT_INLINE p2d_plant_x_t p2d_plant_x_step(bool two_mass, p2d_plant_x_t x, double k, p2d_plant_x_t dx)
{
    p2d_plant_x_t y = x;
    y.id_A = x.id_A + k * dx.id_A;
    y.iq_A = x.iq_A + k * dx.iq_A;
    y.w_m_radps = x.w_m_radps + k * dx.w_m_radps;
    if (two_mass) {
        y.theta_rad = x.theta_rad + k * dx.theta_rad;
        y.w_load_radps = x.w_load_radps + k * dx.w_load_radps;
    }
    return y;
}

/*
 * One classical RK4 step of length h [s] from x with the input (a_d, a_q) held (eq 1: ud, uq
 * [V]; eq 3: id_ref, iq_ref [A]) and the load T0 + dT_dt (t - t_start) [Nm] over the step.
 * lean (rigid, no Coulomb friction): Ld = Lq and B = 0, and theta_m is left as it is (its
 * caller needs no angle).
 */
P2D_PLANT_INLINE p2d_plant_x_t p2d_plant_rk4(const p2d_plant_coef_t *c, p2d_plant_x_t x, double a_d, double a_q,
                                             double h, double T0_Nm, double dT_dt_Nmps, bool first_order, bool coulomb,
                                             bool two_mass, bool lean)
{
    double h_half = 0.5 * h, h_6 = h / 6.0;
    double u_d = first_order ? a_d : a_d * c->inv_Ld_per_H, u_q = first_order ? a_q : a_q * c->inv_Lq_per_H;
    /* the load at the stages, on the rigid shaft per unit inertia */
    double T1 = two_mass ? T0_Nm : T0_Nm * c->inv_J_per_kgm2;
    double dT = two_mass ? dT_dt_Nmps : dT_dt_Nmps * c->inv_J_per_kgm2;
    double T2 = T1 + h_half * dT, T4 = T1 + h * dT;
    p2d_plant_x_t k1, k2, k3, k4, y;
    k1 = p2d_plant_rate(c, x, u_d, u_q, T1, first_order, coulomb, two_mass, lean);
    k2 = p2d_plant_rate(c, p2d_plant_x_step(two_mass, x, h_half, k1), u_d, u_q, T2, first_order, coulomb, two_mass,
                        lean);
    k3 = p2d_plant_rate(c, p2d_plant_x_step(two_mass, x, h_half, k2), u_d, u_q, T2, first_order, coulomb, two_mass,
                        lean);
    k4 = p2d_plant_rate(c, p2d_plant_x_step(two_mass, x, h, k3), u_d, u_q, T4, first_order, coulomb, two_mass, lean);
    /* x(t + h) = x(t) + h (k1 + 2 k2 + 2 k3 + k4) / 6 */
    y.id_A = x.id_A + h_6 * (k1.id_A + k4.id_A + 2.0 * (k2.id_A + k3.id_A));
    y.iq_A = x.iq_A + h_6 * (k1.iq_A + k4.iq_A + 2.0 * (k2.iq_A + k3.iq_A));
    y.w_m_radps = x.w_m_radps + h_6 * (k1.w_m_radps + k4.w_m_radps + 2.0 * (k2.w_m_radps + k3.w_m_radps));
    /* RK4 of dtheta_m/dt = w_m over the stages above: theta_m + h w_m + h^2 (k1 + k2 + k3) / 6 (speed rates) */
    y.theta_m_rad =
        lean ? x.theta_m_rad : x.theta_m_rad + h * x.w_m_radps + h * h_6 * (k1.w_m_radps + k2.w_m_radps + k3.w_m_radps);
    if (two_mass) {
        y.theta_rad = x.theta_rad + h_6 * (k1.theta_rad + k4.theta_rad + 2.0 * (k2.theta_rad + k3.theta_rad));
        y.w_load_radps =
            x.w_load_radps + h_6 * (k1.w_load_radps + k4.w_load_radps + 2.0 * (k2.w_load_radps + k3.w_load_radps));
    } else {
        y.theta_rad = x.theta_rad;
        y.w_load_radps = x.w_load_radps;
    }
    return y;
}

/* The state of the plant. */
P2D_PLANT_INLINE p2d_plant_x_t p2d_plant_state(const p2d_plant_t *plant)
{
    p2d_plant_x_t x;
    x.id_A = plant->id_A;
    x.iq_A = plant->iq_A;
    x.w_m_radps = plant->w_m_radps;
    x.theta_m_rad = plant->theta_m_rad;
    x.theta_rad = plant->theta_rad;
    x.w_load_radps = plant->w_load_radps;
    return x;
}

/* Set the state of the plant to x. */
P2D_PLANT_INLINE void p2d_plant_set_state(p2d_plant_t *plant, p2d_plant_x_t x)
{
    plant->id_A = x.id_A;
    plant->iq_A = x.iq_A;
    plant->w_m_radps = x.w_m_radps;
    plant->theta_m_rad = x.theta_m_rad;
    plant->theta_rad = x.theta_rad;
    plant->w_load_radps = x.w_load_radps;
}

/* ud^2 + uq^2 < u_inside2: the vector is inside the range, and hypot(ud, uq) <= u_max (p2d_plant_set_dc_link). */
P2D_PLANT_INLINE bool p2d_plant_inside_range(const p2d_plant_t *plant, double ud_V, double uq_V)
{
    return ud_V * ud_V + uq_V * uq_V < plant->u_inside2_V2;
}

/*
 * Scale (*ud, *uq) to ||u|| <= u_max; return true when it was cut. hypot neither underflows nor
 * overflows, so a zero range (a DC link at 0 V) applies exactly zero to any nonzero command, a
 * subnormal one included.
 */
P2D_PLANT_INLINE bool p2d_plant_limit_voltage(const p2d_plant_t *plant, double *ud_V, double *uq_V)
{
    double norm;
    if (p2d_plant_inside_range(plant, *ud_V, *uq_V)) return false;
    norm = hypot(*ud_V, *uq_V);
    if (!(norm > plant->u_max_V)) return false;
    *ud_V *= plant->u_max_V / norm;
    *uq_V *= plant->u_max_V / norm;
    return true;
}

/* The inverter's part of p2d_plant_command (plant.h): limit the command, apply it now or next period. */
P2D_PLANT_INLINE void p2d_plant_inverter(p2d_plant_t *plant, double ud_V, double uq_V, p2d_inverter_output_t *out)
{
    bool limited = p2d_plant_limit_voltage(plant, &ud_V, &uq_V), applied_limited = limited;
    if (!plant->cfg.computation_delay) {
        plant->a_d = ud_V;
        plant->a_q = uq_V;
    } else {
        /* the previous command, limited again by the range of this period */
        plant->a_d = plant->ud_next_V;
        plant->a_q = plant->uq_next_V;
        applied_limited = p2d_plant_limit_voltage(plant, &plant->a_d, &plant->a_q) || plant->limited_next;
        plant->ud_next_V = ud_V;
        plant->uq_next_V = uq_V;
        plant->limited_next = limited;
    }
    out->ud_V = ud_V;
    out->uq_V = uq_V;
    out->limited = limited;
    out->applied_limited = applied_limited;
}

#endif /* PMSM2DOF_SIM_PLANT_INLINE_H */
