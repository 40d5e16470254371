/*
 * pmsm2dof: dq current controllers (paper Fig. 1, inner loop).
 *
 * Two PI regulators on the d and q current errors, optional decoupling of the
 * back-EMF and cross-coupling terms of the dq model (eq 1):
 *   ud = PI_d(id_ref - id) - w_e Lq iq
 *   uq = PI_q(iq_ref - iq) + w_e (Ld id + psi_f)
 * and the voltage vector limited to the inverter's linear range
 * ||u_dq|| <= u_max = u_dc / sqrt(3) (amplitude-invariant dq, space-vector
 * modulation) with d-axis priority:
 *   ud_sat = Sat(ud) within [-u_max, u_max]
 *   uq_sat = Sat(uq) within [-uq_max, uq_max], uq_max = sqrt(u_max^2 - ud_sat^2)
 * The d axis keeps the voltage it needs (the cross-coupling -w_e Lq iq and the
 * regulation of id, the flux) and the q axis, the torque, takes what is left:
 * at the voltage limit id stays at its reference while iq falls short of its
 * own. Scaling the whole vector instead cuts ud in the ratio of the q-axis
 * excess, and id drifts positive at high speed, strengthening the flux that
 * already exhausts the voltage. Anti-windup per axis: dx/dt = Ki (e + Ka u*),
 * u* = u_sat - u [V] of that axis, Ka = 1/Kp: each integrator sees the
 * voltage its axis actually got.
 *
 * Gains from the desired loop time constant tau_i (eq 3):
 *   Kp = L / tau_i, Ki = Rs / tau_i
 * The PI zero cancels the stator pole R/L and the closed loop is
 * 1 / (tau_i s + 1) when decoupled and unsaturated.
 *
 * Discrete PI, as in speed.h: u[k] = b_e0 e[k] + x[k-1],
 * x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k]. Rounding as in speed.h: the
 * fmaf of the step round once, equally on the MCU and the host.
 *
 * Non-finite policy: a non-finite voltage command (NaN/inf input or overflow)
 * gives a zero voltage output, no state update, `fault` set and the fault
 * counter incremented. An update with a non-finite applied voltage, or whose
 * new integrator state would not be finite, is refused the same way (counted,
 * state kept), so the state is never poisoned.
 */
#ifndef PMSM2DOF_CURRENT_H
#define PMSM2DOF_CURRENT_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float Rs_ohm;                  /* stator resistance [ohm], > 0 */
    float Ld_H;                    /* d-axis inductance [H], > 0 */
    float Lq_H;                    /* q-axis inductance [H], > 0 */
    float psi_f_Wb;                /* permanent-magnet flux linkage [Wb], >= 0 */
    float tau_i_s;                 /* desired closed-loop time constant [s], > 0 */
    float Ts_s;                    /* sampling period [s], > 0 */
    p2d_method_t method;           /* discretization (Table 1) */
    p2d_anti_windup_t anti_windup; /* anti-windup mode, Ka = 1/Kp per axis */
    bool decouple;                 /* add the back-EMF and cross-coupling feedforward */
} p2d_current_config_t;

typedef struct {
    p2d_pi_coef_t d; /* d-axis PI, Kp = Ld / tau_i, Ki = Rs / tau_i (u in V, e in A) */
    p2d_pi_coef_t q; /* q-axis PI, Kp = Lq / tau_i, Ki = Rs / tau_i (u in V, e in A) */
    float Ld_H;      /* decoupling [H] (0 when decoupling is off) */
    float Lq_H;      /* decoupling [H] (0 when decoupling is off) */
    float psi_f_Wb;  /* decoupling [Wb] (0 when decoupling is off) */
    bool clamping;   /* conditional integration */
} p2d_current_coef_t;

typedef struct {
    p2d_current_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;             /* index of the active set, 0 or 1 */
    p2d_current_config_t config; /* configuration of the active set */
    float x_d_V;                 /* d-axis integrator x[k-1] [V] */
    float x_q_V;                 /* q-axis integrator x[k-1] [V] */
    uint32_t fault_count;        /* samples rejected by the non-finite policy [-] */
} p2d_current_t;

typedef struct {
    float ed_A;       /* d-axis current error [A] */
    float eq_A;       /* q-axis current error [A] */
    float ud_unsat_V; /* d-axis voltage before the limit [V] */
    float uq_unsat_V; /* q-axis voltage before the limit [V] */
    float ud_ref_V;   /* d-axis voltage command, limited first, to [-u_max, u_max] [V] */
    float uq_ref_V;   /* q-axis voltage command, limited to what ud_ref_V leaves of the circle [V] */
    bool saturated;   /* the voltage-vector limit is active (either axis cut) */
    bool fault;       /* non-finite policy engaged: outputs are zero */
} p2d_current_output_t;

/* Validate cfg and precompute; on error ctl is left unchanged. Resets state. */
p2d_status_t p2d_current_init(p2d_current_t *ctl, const p2d_current_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_current_set_config(p2d_current_t *ctl, const p2d_current_config_t *cfg);

/* Clear both integrators (zero voltage at zero error); the fault counter is kept. */
void p2d_current_reset(p2d_current_t *ctl);

/* Compute the voltage command; w_e_radps is the electrical speed, u_dc_V the measured DC link. */
void p2d_current_compute(const p2d_current_t *ctl, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                         float w_e_radps, float u_dc_V, p2d_current_output_t *out);

/* Update the integrators with the voltage actually applied. */
void p2d_current_update(p2d_current_t *ctl, const p2d_current_output_t *out, float ud_applied_V, float uq_applied_V);

/* compute + update with the controller's own limited voltage. */
void p2d_current_step(p2d_current_t *ctl, float id_ref_A, float iq_ref_A, float id_A, float iq_A, float w_e_radps,
                      float u_dc_V, p2d_current_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_CURRENT_H */
