/*
 * pmsm2dof: voltage-feedback field weakening.
 *
 * Above base speed the back-EMF w_e psi_f takes the inverter's voltage range
 * ||u_dq|| <= u_dc / sqrt(3) (amplitude-invariant dq, space-vector
 * modulation) and the current controller can no longer hold its currents. A
 * negative d-axis current lowers the flux (eq 1 of the paper at steady state):
 *   ud = Rs id - w_e Lq iq,   uq = Rs iq + w_e (Ld id + psi_f).
 * A PI on the voltage margin finds that current without the motor data: it
 * holds the voltage command of the current controller at a share of the range,
 *   u_ref   = voltage_ratio max(u_dc, 0) / sqrt(3)                      [V]
 *   e       = u_ref - ||u_dq||                                          margin [V]
 *   v       = PI(e): v[k] = b_e0 e[k] + x[k-1]                          [A]
 *   id_ref  = Sat(v) within [id_min_A, 0]                               [A]
 *   x[k]    = x[k-1] + Ki Ts e[k] + Ki Ka Ts (id_ref - v)               anti-windup (pi.h)
 * (Kim, Sul, "Speed control of interior permanent magnet synchronous motor
 * drive for the flux weakening operation", IEEE Trans. Ind. Appl. 33(1), 1997:
 * the voltage-feedback regulator). Below base speed e > 0 and id_ref = 0 with
 * the integrator held at the limit; a margin that turns negative drives id
 * negative until ||u_dq|| = u_ref or id_ref = id_min_A (the weakening is
 * exhausted). Feed ||u_dq|| of the current controller's command before its
 * limit (ud_unsat_V, uq_unsat_V of p2d_current_output_t), so that a demand
 * beyond the range shows as a negative margin.
 *
 * The speed controller keeps ||i_dq|| <= i_max_A with this d current through
 * p2d_speed_step_fw (speed.h): its torque limit follows the q-axis current
 * that remains, sqrt(i_max^2 - id^2), and its anti-windup sees that limit.
 *
 * Loop gain: near the operating point d||u_dq||/d id is about w_e Ld, so an
 * integral gain Ki gives a crossover near Ki w_e Ld [rad/s]: choose Ki for
 * the highest speed (and well below 1/tau_i of the current loop).
 *
 * Non-finite policy: if ud, uq or u_dc is not finite, ||u_dq|| overflows, or
 * v is not finite, the output holds the integrator's current
 * Sat(x[k-1]) (dropping the weakening at speed would lose the current
 * control), `fault` is set, the state is not updated and fault_count is
 * incremented; an update whose new state would not be finite is refused the
 * same way. A finite negative u_dc_V counts as 0 V.
 *
 * Parameter updates: p2d_field_weakening_set_config validates into the
 * inactive of two coefficient sets and activates it with one aligned 32-bit
 * store, as p2d_speed_set_config; the state is kept.
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_FIELD_WEAKENING_H
#define PMSM2DOF_FIELD_WEAKENING_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float Kp_A_per_V;    /* proportional gain [A/V], >= 0 */
    float Ki_A_per_Vs;   /* integral gain [A/(V s)], > 0 */
    float Ka_V_per_A;    /* back-calculation gain [V/A], >= 0, Ki Ka Ts < 2 (1/Kp is usual) */
    float Ts_s;          /* sampling period [s], > 0 */
    float voltage_ratio; /* ||u_dq|| held at voltage_ratio u_dc / sqrt(3) [-], in (0, 1] */
    float id_min_A;      /* most negative d-axis current [A], < 0 (e.g. -i_max_A, or a demagnetization limit) */
    p2d_method_t method; /* discretization of the PI (Table 1) */
    p2d_anti_windup_t anti_windup; /* anti-windup of the PI at 0 and id_min_A */
} p2d_field_weakening_config_t;

/* Precomputed coefficients: everything the step needs for one Ts. */
typedef struct {
    p2d_pi_coef_t pi;     /* PI on the voltage margin (u in A, e in V) */
    float u_ref_per_u_dc; /* voltage_ratio / sqrt(3) [-] */
    float id_min_A;       /* most negative d-axis current [A] */
    bool clamping;        /* conditional integration */
} p2d_field_weakening_coef_t;

typedef struct {
    p2d_field_weakening_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;                     /* index of the active set, 0 or 1 */
    p2d_field_weakening_config_t config; /* configuration of the active set */
    float x_A;                           /* integrator x[k-1] [A] */
    uint32_t fault_count;                /* samples rejected by the non-finite policy [-] */
} p2d_field_weakening_t;

typedef struct {
    float u_ref_V;    /* voltage held u_ref [V] */
    float e_V;        /* margin e = u_ref - ||u_dq|| [V] */
    float id_unsat_A; /* PI output v before the limit [A] */
    float id_ref_A;   /* d-axis current command, in [id_min_A, 0] [A] */
    bool active;      /* id_ref_A < 0: the field is weakened */
    bool at_id_min;   /* id_ref_A = id_min_A: no weakening left */
    bool fault;       /* non-finite policy engaged: id_ref_A holds Sat(x[k-1]) */
} p2d_field_weakening_output_t;

/* Validate cfg and precompute; on error fw is left unchanged. Resets the state (id 0). */
p2d_status_t p2d_field_weakening_init(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_field_weakening_set_config(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg);

/*
 * Bumpless start at the d current id_A [A] (clamped to [id_min_A, 0]): the output at zero
 * margin. A non-finite id_A starts at 0 and counts a fault.
 */
void p2d_field_weakening_reset(p2d_field_weakening_t *fw, float id_A);

/* One sample: the current controller's voltage command ud_V, uq_V [V] and the measured DC link u_dc_V [V]. */
void p2d_field_weakening_step(p2d_field_weakening_t *fw, float ud_V, float uq_V, float u_dc_V,
                              p2d_field_weakening_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_FIELD_WEAKENING_H */
