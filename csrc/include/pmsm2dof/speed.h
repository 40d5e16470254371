/*
 * pmsm2dof: the 2DOF PI speed controller with anti-windup (paper Fig. 5 and 6).
 *
 * Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet
 * Synchronous Motor Speed Controller". Equation numbers below are the paper's.
 *
 *   e      = w_ref - w_m                                  speed error [rad/s]
 *   T_fb   = F(z) e,  F(s) = Kp + Ki/s                    PI feedback (eq 14)
 *   T_ff   = Fr(z) w_ref                                  2DOF feedforward (eq 11-13, 15)
 *   u      = T_fb + T_ff                                  torque before the limit [Nm]
 *   u_sat  = torque of the current vector limited to ||i_dq|| <= i_max_A
 *   u*     = u_sat - u                                    anti-windup signal [Nm]
 *   dx_i/dt = Ki (e + Ka u*)                              back calculation (Fig. 5)
 *
 * Gains (eq 9): Kp = J alpha, Ki = J (alpha / (2 zeta))^2.
 *
 * Feedforward forms:
 *   NONE     Fr = 0 (1DOF PI).
 *   LOWPASS  Fr = -Ki / (s + alpha)                                  eq 13 (m = 1, tau_i neglected)
 *   NO_TAU   Fr = J alpha ((m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)   eq 11 with tau_i = 0
 *   FULL     Fr = J alpha (m tau_i s^2 + (m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)   eq 11
 *            FULL is improper. It is split by polynomial division into
 *            Kd s + D + c / (s + m alpha); the proper part is discretized by the
 *            chosen method and the derivative Kd s always by the backward
 *            difference (r[k] - r[k-1]) / Ts, the only causal choice that has no
 *            pole on the unit circle (Tustin's s has one at z = -1).
 *
 * Realization of the feedforward. Every method keeps the static gain, so the
 * discretized proper part (b0 + b1 z^-1) / (1 + a1 z^-1) (D included) equals
 *   Fr0 + b_dr (1 - z^-1) / (1 + a1 z^-1),   b_dr = b0 - Fr0,
 * with Fr0 = Fr(s = 0) = -J alpha / (4 zeta^2 m) (eq 11 at s = 0; -Ki/alpha for
 * LOWPASS), because b0 + b1 = Fr0 (1 + a1). With dr[k] = r[k] - r[k-1]:
 *   y[k]    = b_dr dr[k] - a1 y[k-1]                            transient [Nm]
 *   T_ff[k] = Fr0 r[k] + y[k] + Kd dr[k] / Ts
 * y decays to exactly 0 under a constant reference. A section on r itself,
 * whose pole -a1 ~ 1 - m alpha Ts is near 1, amplifies the float32 rounding of
 * its coefficients and of its state (which stops moving once its increments
 * fall under half an ulp) by about 1/(m alpha Ts): folded with D it left
 * offsets of 6e-5 to 3e-4 Nm on 46 to 105 Nm (m alpha Ts = 0.014 to 0.032) and
 * 8e-4 to 9e-3 Nm on 18 to 40 Nm (m alpha Ts = 3.5e-4 to 8e-4).
 *
 * Discrete PI (eq 14), the same for all methods (only b_e0 differs):
 *   u[k]   = b_e0 e[k] + x_i[k-1] + T_ff[k]
 *   x_i[k] = x_i[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k]        (back_calculation)
 *   b_e0   = Kp (forward Euler), Kp + Ki Ts (backward Euler), Kp + Ki Ts / 2 (Tustin, eq 14)
 * The error path is exactly F(z) of the chosen method. The applied command is
 * only known after the output is computed, so the u* path enters the state one
 * sample later for every method (the usual embedded realization).
 *
 * The state x: integrator plus static feedforward. At a constant reference
 * the integral x_i holds the load torque minus Fr0 r (39.4 Nm for 8 Nm of
 * load on the paper's drive at 500 rpm: Fr0 r = -31.4 Nm), and in float32 an
 * increment Ki Ts e under half an ulp of x_i is lost: the speed error stalls
 * in a dead band that grows with |Fr0 r| (0.31 rpm at Ts = 1e-4 s there, about
 * 20 times that of the 1DOF PI). The step therefore keeps the sum that the limit
 * sees at steady state,
 *   x[k] = x_i[k] + Fr0 r[k],
 * and realizes the same equations as
 *   dT[k]   = Fr0 dr[k] + y[k] + Kd dr[k] / Ts      move of T_ff from Fr0 r[k-1] [Nm]
 *   u[k]    = b_e0 e[k] + x[k-1] + dT[k]
 *   x[k]    = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] + Fr0 dr[k]
 *   T_ff[k] = Fr0 r[k-1] + dT[k]                     (the output T_ff_Nm)
 * Check: x[k-1] + Fr0 dr[k] = x_i[k-1] + Fr0 r[k], so u[k] is the u[k] above;
 * and x[k] - Fr0 r[k] = x_i[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] = x_i[k], so
 * x[k] = x_i[k] + Fr0 r[k] holds at every k by induction. The transfer
 * functions from r, w_m and u* are unchanged. The term Fr0 dr[k] is the
 * feedforward moving, not integration: clamping holds only the integration
 * (Ki Ts e + Ki Ka Ts u*), so x_i is held exactly as before. At a constant
 * reference x holds the load torque alone (8 Nm), and the dead band is that of
 * the 1DOF PI (0.016 rpm there, the same as with Fr = 0).
 * p2d_speed_integrator_Nm returns x_i = x - Fr0 r[k-1], the integral of the
 * PI, for logs and analysis (one rounding of the difference).
 *
 * Torque to current: surface PMSM (Ld == Lq): id = 0, iq = T / (1.5 p psi_f).
 * Salient PMSM: maximum torque per ampere. The current-vector limit
 * ||i_dq|| <= i_max_A is applied as the equivalent torque limit T_max on the
 * MTPA trajectory. Torque uses the amplitude-invariant Park transform:
 * Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) (the paper's eq 1 omits the 1.5 and
 * calls p the number of poles while using it as pole pairs).
 * For a surface PMSM, init lowers T_max by float32 ulps until
 * T_max / kt <= i_max_A holds in float32; a rounded quotient is monotonic in
 * its dividend, so every |T| <= T_max gives |iq| <= i_max_A exactly and the
 * step needs no current clamp. The MTPA inversion of a salient PMSM (Newton on
 * a quartic, see speed.c) is a separate function that the step enters by a
 * tail call, so that the surface path calls nothing and saves no registers.
 *
 * Rounding: where the step writes fmaf(a, b, c), a b + c is rounded once.
 * fmaf is correctly rounded on every IEEE 754 system (vfma.f32 on the
 * Cortex-M4F, the FMA instruction or libm on the host), so the MCU and the
 * simulation stay equal to the bit; implicit contraction stays off
 * (-ffp-contract=off), as the other sums are rounded twice on both.
 *
 * Non-finite policy: if the computed torque or current is not finite (NaN or
 * inf speed, reference, or an overflow), the output is zero torque and zero
 * current, the state is left untouched by the update, `fault` is set in the
 * output and the latched fault counter of the controller is incremented. An
 * update with a non-finite applied torque, or whose new integrator state would
 * not be finite, is refused the same way (counted, state kept), so the state
 * is never poisoned. The command does not use Fr0 r itself (the state holds
 * it): where Fr0 r overflows float32 only the diagnostic T_ff_Nm is infinite.
 *
 * Parameter updates: p2d_speed_set_config validates the new configuration and
 * computes its coefficients into the inactive of two coefficient sets, then
 * makes it active with one aligned 32-bit store. On an invalid configuration
 * nothing changes. The state (x, r[k-1], y[k-1]) is kept as it is, so the
 * output at a constant reference and zero error, x + y, does not jump: when
 * Fr0 changes, the integral x_i = x - Fr0 r[k-1] takes the difference
 * (Fr0_old - Fr0_new) r[k-1] over and the sum that the limit sees stays put
 * (bumpless transfer). Call it from a context that the step cannot preempt
 * mid-update in reverse (on a single-core MCU: from the background loop,
 * with step in the interrupt).
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_SPEED_H
#define PMSM2DOF_SPEED_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    P2D_FF_NONE = 0,    /* 1DOF PI */
    P2D_FF_LOWPASS = 1, /* eq 13 / 15 */
    P2D_FF_NO_TAU = 2,  /* eq 11 with tau_i = 0 */
    P2D_FF_FULL = 3     /* eq 11 */
} p2d_feedforward_t;

/* Design inputs of the speed controller. */
typedef struct {
    float J_kgm2;                  /* design inertia [kg m^2], > 0 */
    float alpha_radps;             /* bandwidth of the P loop [rad/s], > 0 (eq 9) */
    float zeta;                    /* relative damping of the PI loop [-], > 0 (eq 9) */
    float m;                       /* tracking pole factor: Gx = m alpha / (s + m alpha) [-], > 0 (eq 10) */
    float tau_i_s;                 /* current-loop time constant [s], >= 0 (eq 3); used by FULL only */
    float Ka;                      /* back-calculation gain [(rad/s)/Nm], >= 0; paper default 1/Kp */
    float Ts_s;                    /* sampling period [s], > 0 */
    float i_max_A;                 /* current-vector limit ||i_dq|| <= i_max_A [A], > 0 */
    float psi_f_Wb;                /* permanent-magnet flux linkage [Wb], > 0 */
    float Ld_H;                    /* d-axis inductance [H], > 0 */
    float Lq_H;                    /* q-axis inductance [H], > 0 */
    uint32_t pole_pairs;           /* pole pairs p [-], >= 1 */
    p2d_method_t method;           /* discretization (Table 1) */
    p2d_feedforward_t feedforward; /* 2DOF feedforward form */
    p2d_anti_windup_t anti_windup; /* anti-windup mode */
} p2d_speed_config_t;

/* Precomputed coefficients: everything the step needs for one Ts. */
typedef struct {
    p2d_pi_coef_t pi;     /* PI, Kp = J alpha, Ki = J (alpha / (2 zeta))^2 (eq 9) (u in Nm, e in rad/s) */
    float ff_Fr0;         /* feedforward static gain Fr(0), weight of r[k] [Nm/(rad/s)] */
    float ff_b_dr;        /* feedforward transient section, weight of r[k] - r[k-1] [Nm/(rad/s)] */
    float ff_a1;          /* feedforward transient section, weight of -y[k-1] [-] */
    float ff_Kd_per_Ts;   /* FULL derivative term J alpha m tau_i / Ts [Nm/(rad/s)] */
    float T_max_Nm;       /* torque at ||i_dq|| = i_max_A on the MTPA trajectory [Nm]; surface
                             PMSM: kt i_max_A, lowered until T_max_Nm / kt_Nm_per_A <= i_max_A */
    float i_max_A;        /* current-vector limit [A] */
    float kt_Nm_per_A;    /* 1.5 p psi_f [Nm/A] */
    float k_mtpa_Wb_per_sqrt_Nm; /* 2 sqrt(|Ld - Lq| / (1.5 p)): flux scale sqrt(q) = k sqrt(|T|) of the MTPA
                                    inversion (speed.c) [Wb/sqrt(Nm)]; 0 for a surface PMSM */
    float psi_f_Wb;       /* flux linkage [Wb], MTPA */
    float dL_H;           /* Ld - Lq [H], MTPA */
    bool salient;         /* Ld != Lq: MTPA current split */
    bool clamping;        /* conditional integration */
} p2d_speed_coef_t;

typedef struct {
    p2d_speed_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;           /* index of the active set, 0 or 1 */
    p2d_speed_config_t config; /* configuration of the active set */
    float x_Nm;                /* integrator plus static feedforward x[k-1] = x_i[k-1] + Fr0 r[k-1] [Nm] */
    float r_prev_radps;        /* reference of the previous sample r[k-1] [rad/s] */
    float y_ff_prev_Nm;        /* feedforward transient y[k-1] [Nm]; 0 at a constant reference */
    uint32_t fault_count;      /* samples rejected by the non-finite policy [-] */
} p2d_speed_t;

/* Result of p2d_speed_compute: the command and what the update needs. */
typedef struct {
    float w_ref_radps;  /* reference used this sample [rad/s] */
    float e_radps;      /* speed error w_ref - w_m [rad/s] */
    float T_ff_Nm;      /* feedforward torque Fr(z) w_ref [Nm] */
    float y_ff_Nm;      /* transient y[k] of the feedforward: T_ff - Fr0 w_ref - derivative [Nm] */
    float T_unsat_Nm;   /* u: feedback plus feedforward before the limit [Nm] */
    float T_ref_Nm;     /* u_sat: torque of the limited current vector [Nm] */
    float id_ref_A;     /* d-axis current command [A] */
    float iq_ref_A;     /* q-axis current command [A] */
    bool saturated;     /* the current-vector limit is active */
    bool fault;         /* non-finite policy engaged: outputs are zero */
} p2d_speed_output_t;

/* Validate cfg and precompute; on error ctl is left unchanged. Resets state. */
p2d_status_t p2d_speed_init(p2d_speed_t *ctl, const p2d_speed_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_speed_set_config(p2d_speed_t *ctl, const p2d_speed_config_t *cfg);

/*
 * Bumpless reset: the feedforward at its steady state for a constant
 * reference w_ref_radps (transient y = 0), and the integrator such that the output equals
 * T_init_Nm at zero error (x = T_init_Nm, x_i = T_init_Nm - Fr0 w_ref_radps). p2d_speed_reset(ctl, 0, 0) clears everything.
 * A non-finite argument, or a steady state that overflows float32, clears the
 * state as (0, 0) and counts a fault.
 */
void p2d_speed_reset(p2d_speed_t *ctl, float w_ref_radps, float T_init_Nm);

/* Compute the command for this sample; does not change the state. */
void p2d_speed_compute(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps,
                       p2d_speed_output_t *out);

/* Update the state with the torque actually applied (after every limit). */
void p2d_speed_update(p2d_speed_t *ctl, const p2d_speed_output_t *out, float T_applied_Nm);

/* compute + update with the controller's own limited torque. */
void p2d_speed_step(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps,
                    p2d_speed_output_t *out);

/* The integral of the PI, x_i[k-1] = x[k-1] - Fr0 r[k-1] [Nm] (rounded once). */
float p2d_speed_integrator_Nm(const p2d_speed_t *ctl);

/* The paper's default back-calculation gain Ka = 1/Kp = 1/(J alpha) (section 3.3). */
float p2d_speed_Ka_default(float J_kgm2, float alpha_radps);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SPEED_H */
