/*
 * pmsm2dof: the 2DOF PI speed controller with anti-windup (paper Fig. 5 and 6).
 *
 * Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet
 * Synchronous Motor Speed Controller". Equation numbers are the paper's. The
 * derivation of the realization below (feedforward section, the state
 * x = x_i + Fr0 r, rounding, MTPA inversion) is in docs/theory/speed-controller.md.
 *
 *   e       = w_ref - w_m                                 speed error [rad/s]
 *   T_fb    = F(z) e,  F(s) = Kp + Ki/s                   PI feedback (eq 14)
 *   T_ff    = Fr(z) w_ref                                 2DOF feedforward (eq 11-13, 15)
 *   u       = T_fb + T_ff                                 torque before the limit [Nm]
 *   u_sat   = torque of the current vector limited to ||i_dq|| <= i_max_A
 *   u*      = u_sat - u                                   anti-windup signal [Nm]
 *   dx_i/dt = Ki (e + Ka u*)                              back calculation (Fig. 5)
 * Gains (eq 9): Kp = J alpha, Ki = J (alpha / (2 zeta))^2.
 *
 * Feedforward forms:
 *   NONE     Fr = 0 (1DOF PI)
 *   LOWPASS  Fr = -Ki / (s + alpha)                                            eq 13 (m = 1)
 *   NO_TAU   Fr = J alpha ((m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)      eq 11, tau_i = 0
 *   FULL     Fr = J alpha (m tau_i s^2 + (m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)   eq 11
 * Every dynamic part is discretized by the chosen method (Table 1); the
 * derivative of FULL, which is improper, by the backward difference.
 *
 * Discrete PI (eq 14), every method: u[k] = b_e0 e[k] + x_i[k-1] + T_ff[k],
 * x_i[k] = x_i[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] (back calculation; clamping
 * holds the integration while the limit is active and e drives into it),
 * b_e0 = Kp (forward Euler), Kp + Ki Ts (backward Euler), Kp + Ki Ts / 2 (Tustin).
 * The state is x = x_i + Fr0 r with Fr0 = Fr(0), which keeps the float32
 * resolution of the 1DOF PI at steady state; p2d_speed_integrator_Nm returns x_i.
 *
 * Torque to current (Te = 1.5 p (psi_f iq + (Ld - Lq) id iq), amplitude-
 * invariant dq; the paper's eq 1 omits the 1.5): surface PMSM (Ld == Lq)
 * id = 0, iq = T / (1.5 p psi_f); salient PMSM: the maximum-torque-per-ampere
 * vector (id on the trajectory of p2d_mtpa_id_A). The limit ||i_dq|| <= i_max_A
 * is applied as the torque limit T_max_Nm of the MTPA vector of length
 * i_max_A; the command never exceeds i_max_A, also after rounding.
 *
 * Torque filters (optional, p2d_speed_set_filter; pmsm2dof/filter.h): a
 * notch and a low-pass on the torque command, inside the anti-windup loop,
 * before the limit:
 *   u_f     = H(z) u                                      H = H_notch H_lowpass, sections with f0 > 0
 *   u_sat   = Sat(u_f)                                    the limit acts on the filtered command
 *   u*      = u_sat - u_f                                 what the limit (and any later one) removed
 *   x_i[k]  = x_i[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k]     back calculation sees u_f, clamping the sign of u*
 * so the output T_unsat_Nm is u_f, and every command the drive gets (T_ref,
 * the currents) has passed the filters. The filters are linear and run on u
 * whether the limit is active or not; the back calculation pulls u_f, not u,
 * back to the limit, and its loop now runs through H: it is stable iff every
 * root of z - 1 + Ki Ka Ts H(z) is inside the unit circle (checked by
 * p2d_speed_set_filter and p2d_speed_set_config, exactly, with a Routh test in
 * q = (z - 1)/(z + 1), filter.c, besides Ki Ka Ts < 2). p2d_speed_update
 * recomputes u from the output (e, w_ref, y_ff) and the state, with the
 * roundings of compute, to advance the filters. Without filters (after
 * p2d_speed_init, or with both frequencies 0) the controller is the one above,
 * bit for bit and instruction for instruction. A filter switched on starts at
 * rest at the command x[k-1] (the output at zero error and constant
 * reference); p2d_speed_reset puts the filters at rest at T_init_Nm.
 *
 * Rounding: every fmaf(a, b, c) of the step is rounded once, on the MCU as on
 * the host; build with -ffp-contract=off so that nothing else is fused.
 *
 * Non-finite policy: if the computed torque or current is not finite (NaN or
 * inf input, or an overflow), the output is zero torque and current with
 * `fault` set, the state is not updated and fault_count is incremented. An
 * update with a non-finite applied torque, or whose new state would not be
 * finite, is refused the same way. The state is never poisoned.
 *
 * Parameter updates: p2d_speed_set_config validates the new configuration and
 * computes its coefficients into the inactive of two coefficient sets, then
 * activates it with one aligned 32-bit store; on an invalid configuration
 * nothing changes. The state is kept and the output at a constant reference
 * does not jump (bumpless). Call it where the step cannot preempt it in
 * reverse (single-core MCU: from the background loop, step in the interrupt).
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_SPEED_H
#define PMSM2DOF_SPEED_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/filter.h"
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
    p2d_pi_coef_t pi;            /* PI, Kp = J alpha, Ki = J (alpha / (2 zeta))^2 (eq 9) (u in Nm, e in rad/s) */
    float ff_Fr0;                /* feedforward static gain Fr(0), weight of r[k] [Nm/(rad/s)] */
    float ff_b_dr;               /* feedforward transient section, weight of r[k] - r[k-1] [Nm/(rad/s)] */
    float ff_a1;                 /* feedforward transient section, weight of -y[k-1] [-] */
    float ff_Kd_per_Ts;          /* FULL derivative term J alpha m tau_i / Ts [Nm/(rad/s)] */
    float T_max_Nm;              /* torque at ||i_dq|| = i_max_A on the MTPA trajectory [Nm]; surface
                                    PMSM: kt i_max_A, lowered until T_max_Nm / kt_Nm_per_A <= i_max_A */
    float i_max_A;               /* current-vector limit [A] */
    float kt_Nm_per_A;           /* 1.5 p psi_f [Nm/A] */
    float k_mtpa_Wb_per_sqrt_Nm; /* 2 sqrt(|Ld - Lq| / (1.5 p)): flux scale sqrt(q) = k sqrt(|T|) of the MTPA
                                    inversion (speed.c) [Wb/sqrt(Nm)]; 0 for a surface PMSM */
    float psi_f_Wb;              /* flux linkage [Wb], MTPA */
    float dL_H;                  /* Ld - Lq [H], MTPA */
    bool salient;                /* Ld != Lq: MTPA current split */
    bool clamping;               /* conditional integration */
    bool filtered;               /* a torque filter is on (filter_coef) */
    bool general_step;           /* salient or filtered: p2d_speed_step leaves its surface-PMSM path after u */
} p2d_speed_coef_t;

typedef struct {
    p2d_speed_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;           /* index of the active set, 0 or 1 */
    p2d_speed_config_t config; /* configuration of the active set */
    float x_Nm;                /* integrator plus static feedforward x[k-1] = x_i[k-1] + Fr0 r[k-1] [Nm] */
    float r_prev_radps;        /* reference of the previous sample r[k-1] [rad/s] */
    float y_ff_prev_Nm;        /* feedforward transient y[k-1] [Nm]; 0 at a constant reference */
    uint32_t fault_count;      /* samples rejected by the non-finite policy [-] */

    p2d_filter_coef_t filter_coef[2];  /* torque filters of each coefficient set (a set stays 64 bytes without them) */
    p2d_filter_config_t filter_config; /* torque filters of the active set */
    p2d_filter_state_t filter;         /* torque-filter states [Nm] */
} p2d_speed_t;

/* Result of p2d_speed_compute: the command and what the update needs. */
typedef struct {
    float w_ref_radps; /* reference used this sample [rad/s] */
    float e_radps;     /* speed error w_ref - w_m [rad/s] */
    float T_ff_Nm;     /* feedforward torque Fr(z) w_ref [Nm] */
    float y_ff_Nm;     /* transient y[k] of the feedforward: T_ff - Fr0 w_ref - derivative [Nm] */
    float T_unsat_Nm;  /* u: feedback plus feedforward before the limit, through the torque filters if on [Nm] */
    float T_ref_Nm;    /* u_sat: torque of the limited current vector [Nm] */
    float id_ref_A;    /* d-axis current command [A] */
    float iq_ref_A;    /* q-axis current command [A] */
    bool saturated;    /* the current-vector limit is active */
    bool fault;        /* non-finite policy engaged: outputs are zero */
} p2d_speed_output_t;

/* Validate cfg and precompute; on error ctl is left unchanged. Resets state. */
p2d_status_t p2d_speed_init(p2d_speed_t *ctl, const p2d_speed_config_t *cfg);

/*
 * Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes.
 * The torque filters in force are recomputed for the new Ts_s (and must stay valid).
 */
p2d_status_t p2d_speed_set_config(p2d_speed_t *ctl, const p2d_speed_config_t *cfg);

/*
 * Set the torque filters (filter.h; both frequencies 0: none, as after init) at the
 * configuration's Ts_s, with the anti-windup loop through them (see above), into the
 * shadow set and swap it in, as p2d_speed_set_config; state is kept. On error nothing changes.
 */
p2d_status_t p2d_speed_set_filter(p2d_speed_t *ctl, const p2d_filter_config_t *cfg);

/*
 * Bumpless reset: the feedforward at its steady state for a constant
 * reference w_ref_radps (transient y = 0), and the integrator such that the output equals
 * T_init_Nm at zero error (x = T_init_Nm, x_i = T_init_Nm - Fr0 w_ref_radps). p2d_speed_reset(ctl, 0, 0) clears everything.
 * A non-finite argument, or a steady state that overflows float32, clears the
 * state as (0, 0) and counts a fault.
 */
void p2d_speed_reset(p2d_speed_t *ctl, float w_ref_radps, float T_init_Nm);

/* Compute the command for this sample; does not change the state. */
void p2d_speed_compute(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, p2d_speed_output_t *out);

/* Update the state with the torque actually applied (after every limit). */
void p2d_speed_update(p2d_speed_t *ctl, const p2d_speed_output_t *out, float T_applied_Nm);

/* compute + update with the controller's own limited torque. */
void p2d_speed_step(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, p2d_speed_output_t *out);

/*
 * Field weakening (field_weakening.h): compute with the upper bound id_fw_A [A] on the d-axis
 * current that a field-weakening controller demands, clamped to [-i_max_A, 0]. The current
 * vector is (id_fw, T / (1.5 p (psi_f + (Ld - Lq) id_fw))), or the MTPA vector where its id is
 * already <= id_fw (surface PMSM: id = id_fw, iq = T / kt). The torque limit follows the q-axis
 * current that remains, so that ||i_dq|| <= i_max_A up to float32 rounding:
 *   T_lim = 1.5 p (psi_f + (Ld - Lq) id_fw) sqrt(i_max^2 - id_fw^2)   (surface: kt sqrt(i_max^2 - id_fw^2)),
 * or T_max where the MTPA vector of length i_max_A has id <= id_fw; u_sat = Sat(u) with T_lim,
 * so the anti-windup sees the reduced limit. With id_fw_A = 0 the outputs are those of
 * p2d_speed_compute, to the bit, for a surface PMSM and for Ld < Lq (a machine with Ld > Lq
 * keeps id <= 0). A non-finite id_fw_A engages the non-finite policy (zero torque and current).
 */
void p2d_speed_compute_fw(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, float id_fw_A,
                          p2d_speed_output_t *out);

/* compute_fw + update with the own command. */
void p2d_speed_step_fw(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, float id_fw_A, p2d_speed_output_t *out);

/* The integral of the PI, x_i[k-1] = x[k-1] - Fr0 r[k-1] [Nm] (rounded once). */
float p2d_speed_integrator_Nm(const p2d_speed_t *ctl);

/* The paper's default back-calculation gain Ka = 1/Kp = 1/(J alpha) (section 3.3). */
float p2d_speed_Ka_default(float J_kgm2, float alpha_radps);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SPEED_H */
