/*
 * pmsm2dof: the 2DOF PI speed controller with anti-windup in fixed point, for
 * MCUs without an FPU (Q15 for a Cortex-M0, Q31 for a Cortex-M3).
 *
 * The controller of pmsm2dof/speed.h (paper Fig. 5 and 6, eq 9-15: the three
 * feedforward forms, back calculation and clamping, the three discretizations,
 * the current-vector limit), its step in integers only. The coefficients are
 * computed once, in double, by init (on the host or the MCU).
 *
 * Scalings (config): a speed w [rad/s] is the integer w_q = w 2^N / W_fs, a
 * torque T [Nm] is T_q = T 2^N / T_fs, a current i [A] is i_q = i 2^N / I_fs;
 * N = 15 (Q15: int16 inputs and outputs, int32 arithmetic) or N = 31 (Q31:
 * int32 inputs and outputs, int64 arithmetic). "pu" below is one full scale.
 *
 * The step, in these units (the float controller's equations, speed.h):
 *   e[k]  = w_ref[k] - w_m[k],  dr[k] = w_ref[k] - r[k-1]          exact, |.| <= 2 pu
 *   y[k]  = b_dr dr[k] + y[k-1] - (1 + a1) y[k-1]                  feedforward transient, b_dr dr[k] - a1 y[k-1]
 *   u[k]  = b_e0 e[k] + x[k-1] + Fr0 dr[k] + Kd/Ts dr[k] + y[k]    x = x_i + Fr0 r (eq 14, 15)
 *   T_ff  = Fr0 w_ref[k] + Kd/Ts dr[k] + y[k]                      the feedforward torque (output only)
 *   u_sat = Sat(u) to [-T_max, T_max],  iq = u_sat / kt limited to [-i_max, i_max]
 *   x[k]  = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] + Fr0 dr[k],  u* = u_sat - u   (back calculation;
 *           clamping holds Ki Ts e + Ki Ka Ts u* at 0 while u* and e have opposite signs)
 * Surface PMSM only (Ld_H == Lq_H): id = 0, the current-vector limit is |iq| <= i_max_A.
 *
 * Arithmetic rules (the same in both formats; tests/test_fixed_point_model.py
 * holds an independent model of them):
 * - A gain g is stored as a mantissa m and a shift s, g = m 2^-s, |m| <= 2^N - 1,
 *   normalised (2^(N-1) <= |m|) unless s is at its largest, 2N + 1; m is g 2^s
 *   rounded to the nearest integer, ties away from zero.
 * - A product g v is m v, exact in the accumulator (int32 for Q15, int64 for
 *   Q31), rounded to the unit of the result: R(m v, s) = floor(m v / 2^s + 1/2)
 *   (round half up), computed without shifting a negative number and without
 *   overflow. Each product term is rounded on its own, then the terms are added.
 * - Every signal and state held within +-(2^(N+1) - 1), two full scales (a
 *   17-bit number in Q15, a 33-bit one in Q31), by saturation: y[k], u[k], T_ff,
 *   u*[k] and the Q15 integrator x; e and dr are within it by construction. So
 *   every product fits the accumulator (|m v| < 2^(2N+1)) and nothing overflows.
 *   Every speed-to-torque gain is below 2^13 per unit (init checks it), so each
 *   product term is below 2^(N+14) and their sums fit too.
 * - Q15: x is held in torque LSBs. Each sample adds R(m_KiTs e, s_KiTs) LSBs,
 *   which is 0 while |Ki Ts e| < 1/2 LSB: a dead zone of the integrator,
 *   |e| < T_fs 2^-(N+1) / (Ki Ts) (the exact edges follow from R), in which a
 *   load's steady-state error is never removed (pmsm2dof.analysis.fixedpoint
 *   computes it).
 * - Q31: x is held with 31 more fractional bits (x_q62: int64, LSB 2^-62 pu,
 *   range +-2 pu), and init refuses a configuration in which one LSB of error
 *   does not move it (Ki Ts W_fs / T_fs >= 2^-32); its contribution to u is
 *   R(x_q62, 31). Its terms are rounded to its LSB, R(m v, s - 31) (or, for a
 *   shift of 31 or less, m v 2^(31 - s)), each limited to +-(2^63 - 1), and added one
 *   at a time with saturation S to that range:
 *   x = S(S(x + S(R(Ki Ts e) + R(Ki Ka Ts u*))) + R(Fr0 dr)).
 * - The feedforward's pole -a1, near 1 when m alpha Ts is small, is stored as 1 + a1 (= m alpha Ts
 *   with forward Euler), which keeps its distance to 1, the section's time constant, to the
 *   precision of a mantissa; -a1 itself would keep it to 2^-N only.
 * - The limits: |T_ref| <= T_max_q = floor(T_max 2^N / T_fs) with T_max = 1.5 p psi_f i_max_A,
 *   and iq, rounded, limited to |iq_ref| <= floor(i_max_A 2^N / I_fs) (each at most 2^N - 1).
 *
 * Parameter updates: p2d_speed_q15_set_config and p2d_speed_q31_set_config
 * validate the new configuration and compute its coefficients into the
 * inactive of two coefficient sets, then activate it with one aligned 32-bit
 * store (as p2d_speed_set_config); on an invalid configuration nothing changes.
 * The state is kept, so the output at rest at a constant reference (no
 * feedforward transient) does not jump; the full scales must stay as they are
 * (the state is held in their LSBs).
 *
 * Portable C99, no allocation, no global state; the step uses integers only.
 */
#ifndef PMSM2DOF_SPEED_FIXED_H
#define PMSM2DOF_SPEED_FIXED_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/speed.h"
#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Configuration of a fixed-point speed controller (Q15 and Q31 alike). */
typedef struct {
    p2d_speed_config_t speed;     /* the design and the drive (speed.h), validated as by p2d_speed_init;
                                     surface PMSM: Ld_H == Lq_H */
    float speed_full_scale_radps; /* W_fs: the speed of the integer 2^N [rad/s], > 0 */
    float torque_full_scale_Nm;   /* T_fs: the torque of the integer 2^N [Nm], > 0 and >= T_max = 1.5 p psi_f i_max_A */
    float current_full_scale_A;   /* I_fs: the current of the integer 2^N [A], > 0 and >= i_max_A */
} p2d_speed_fixed_config_t;

/*
 * The coefficients before quantisation, in double, per unit of the scalings (a speed-to-torque
 * gain G [Nm/(rad/s)] is G W_fs / T_fs): what the quantised mantissas and shifts approximate.
 */
typedef struct {
    double b_e0;           /* weight of e[k] in u[k], Kp (forward Euler), Kp + Ki Ts (backward), Kp + Ki Ts / 2
                            (Tustin) (eq 14) [T_fs/W_fs] */
    double Ki_Ts;          /* integrator increment per unit of error [T_fs/W_fs] */
    double Ki_Ka_Ts;       /* integrator increment per unit of u*, 0 unless back calculation [-] */
    double ff_Fr0;         /* feedforward static gain Fr(0) [T_fs/W_fs] */
    double ff_b_dr;        /* feedforward transient, weight of dr[k] [T_fs/W_fs] */
    double ff_one_plus_a1; /* feedforward transient: 1 + a1, a1 the weight of -y[k-1] [-] */
    double ff_Kd_per_Ts;   /* FULL derivative term J alpha m tau_i / Ts [T_fs/W_fs] */
    double iq_per_T;       /* current per torque 1 / (1.5 p psi_f) [I_fs/T_fs] */
    double T_max;          /* torque limit 1.5 p psi_f i_max_A [T_fs] */
    double iq_max;         /* current limit i_max_A [I_fs] */
} p2d_speed_fixed_gains_t;

/* A Q15 gain m 2^-s. */
typedef struct {
    int16_t mantissa; /* m [-], |m| <= 2^15 - 1 */
    uint16_t shift;   /* s [-], 2..31 */
} p2d_q15_gain_t;

/* A Q31 gain m 2^-s. */
typedef struct {
    int32_t mantissa; /* m [-], |m| <= 2^31 - 1 */
    uint32_t shift;   /* s [-], 2..63 */
} p2d_q31_gain_t;

/* Precomputed Q15 coefficients (units: LSB of the result per LSB of the operand). */
typedef struct {
    p2d_q15_gain_t b_e0;           /* weight of e[k] in u[k] (eq 14) */
    p2d_q15_gain_t Ki_Ts;          /* integrator increment per unit of error */
    p2d_q15_gain_t Ki_Ka_Ts;       /* integrator increment per unit of u*; 0 unless back calculation */
    p2d_q15_gain_t ff_Fr0;         /* feedforward static gain Fr(0) */
    p2d_q15_gain_t ff_b_dr;        /* feedforward transient, weight of dr[k] */
    p2d_q15_gain_t ff_one_plus_a1; /* feedforward transient: 1 + a1, a1 the weight of -y[k-1] */
    p2d_q15_gain_t ff_Kd_per_Ts;   /* FULL derivative term */
    p2d_q15_gain_t iq_per_T;       /* current per torque 1 / kt */
    int16_t T_max_q15;             /* torque limit [Q15 of T_fs], >= 1 */
    int16_t iq_max_q15;            /* current limit [Q15 of I_fs], >= 1 */
    bool clamping;                 /* conditional integration */
} p2d_speed_q15_coef_t;

/* Precomputed Q31 coefficients (units as p2d_speed_q15_coef_t). */
typedef struct {
    p2d_q31_gain_t b_e0;           /* weight of e[k] in u[k] (eq 14) */
    p2d_q31_gain_t Ki_Ts;          /* integrator increment per unit of error */
    p2d_q31_gain_t Ki_Ka_Ts;       /* integrator increment per unit of u*; 0 unless back calculation */
    p2d_q31_gain_t ff_Fr0;         /* feedforward static gain Fr(0) */
    p2d_q31_gain_t ff_b_dr;        /* feedforward transient, weight of dr[k] */
    p2d_q31_gain_t ff_one_plus_a1; /* feedforward transient: 1 + a1, a1 the weight of -y[k-1] */
    p2d_q31_gain_t ff_Kd_per_Ts;   /* FULL derivative term */
    p2d_q31_gain_t iq_per_T;       /* current per torque 1 / kt */
    int32_t T_max_q31;             /* torque limit [Q31 of T_fs], >= 1 */
    int32_t iq_max_q31;            /* current limit [Q31 of I_fs], >= 1 */
    bool clamping;                 /* conditional integration */
} p2d_speed_q31_coef_t;

/* The Q15 controller: int16 inputs and outputs, int32 arithmetic. */
typedef struct {
    p2d_speed_q15_coef_t coef[2];    /* active and shadow coefficient sets */
    uint32_t active;                 /* index of the active set, 0 or 1 */
    p2d_speed_fixed_config_t config; /* configuration of the active set */
    int32_t x_q15;                   /* integrator plus static feedforward x[k-1] [Q15 of T_fs], |x| <= 2^16 - 1 */
    int32_t y_ff_prev_q15;           /* feedforward transient y[k-1] [Q15 of T_fs], |y| <= 2^16 - 1 */
    int16_t r_prev_q15;              /* reference of the previous sample r[k-1] [Q15 of W_fs] */
} p2d_speed_q15_t;

/* Result of p2d_speed_q15_compute: the command and what the update needs. */
typedef struct {
    int32_t e_q15;       /* speed error w_ref - w_m [Q15 of W_fs] */
    int32_t T_ff_q15;    /* feedforward torque Fr(z) w_ref [Q15 of T_fs] */
    int32_t y_ff_q15;    /* transient y[k] of the feedforward [Q15 of T_fs] */
    int32_t T_unsat_q15; /* u: feedback plus feedforward before the limit [Q15 of T_fs] */
    int16_t w_ref_q15;   /* reference used this sample [Q15 of W_fs] */
    int16_t T_ref_q15;   /* u_sat: torque of the limited current vector [Q15 of T_fs] */
    int16_t iq_ref_q15;  /* q-axis current command (id = 0) [Q15 of I_fs] */
    bool saturated;      /* the current-vector limit is active */
} p2d_speed_q15_output_t;

/* The Q31 controller: int32 inputs and outputs, int64 arithmetic. */
typedef struct {
    p2d_speed_q31_coef_t coef[2];    /* active and shadow coefficient sets */
    uint32_t active;                 /* index of the active set, 0 or 1 */
    p2d_speed_fixed_config_t config; /* configuration of the active set */
    int64_t x_q62;                   /* integrator plus static feedforward x[k-1] [2^-62 T_fs], +-2 pu */
    int64_t y_ff_prev_q31;           /* feedforward transient y[k-1] [Q31 of T_fs], |y| <= 2^32 - 1 */
    int32_t r_prev_q31;              /* reference of the previous sample r[k-1] [Q31 of W_fs] */
} p2d_speed_q31_t;

/* Result of p2d_speed_q31_compute: the command and what the update needs. */
typedef struct {
    int64_t e_q31;       /* speed error w_ref - w_m [Q31 of W_fs] */
    int64_t T_ff_q31;    /* feedforward torque Fr(z) w_ref [Q31 of T_fs] */
    int64_t y_ff_q31;    /* transient y[k] of the feedforward [Q31 of T_fs] */
    int64_t T_unsat_q31; /* u: feedback plus feedforward before the limit [Q31 of T_fs] */
    int32_t w_ref_q31;   /* reference used this sample [Q31 of W_fs] */
    int32_t T_ref_q31;   /* u_sat: torque of the limited current vector [Q31 of T_fs] */
    int32_t iq_ref_q31;  /* q-axis current command (id = 0) [Q31 of I_fs] */
    bool saturated;      /* the current-vector limit is active */
} p2d_speed_q31_output_t;

/*
 * Validate cfg for the Q15 controller, as p2d_speed_q15_init does, and compute its gains before
 * quantisation into *gains (written only on success).
 */
p2d_status_t p2d_speed_q15_gains(const p2d_speed_fixed_config_t *cfg, p2d_speed_fixed_gains_t *gains);

/* The same for the Q31 controller (p2d_speed_q31_init's validation). */
p2d_status_t p2d_speed_q31_gains(const p2d_speed_fixed_config_t *cfg, p2d_speed_fixed_gains_t *gains);

/* Validate cfg and precompute; on error ctl is left unchanged. Resets the state. */
p2d_status_t p2d_speed_q15_init(p2d_speed_q15_t *ctl, const p2d_speed_fixed_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_speed_q15_set_config(p2d_speed_q15_t *ctl, const p2d_speed_fixed_config_t *cfg);

/* Bumpless reset: feedforward at rest at the reference w_ref_q15, x = T_init_q15 (the output at zero error). */
void p2d_speed_q15_reset(p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t T_init_q15);

/* Compute the command for this sample; does not change the state. */
void p2d_speed_q15_compute(const p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t w_m_q15, p2d_speed_q15_output_t *out);

/* Update the state with the torque actually applied (after every limit) [Q15 of T_fs]. */
void p2d_speed_q15_update(p2d_speed_q15_t *ctl, const p2d_speed_q15_output_t *out, int16_t T_applied_q15);

/* compute + update with the controller's own limited torque. */
void p2d_speed_q15_step(p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t w_m_q15, p2d_speed_q15_output_t *out);

/* Validate cfg and precompute; on error ctl is left unchanged. Resets the state. */
p2d_status_t p2d_speed_q31_init(p2d_speed_q31_t *ctl, const p2d_speed_fixed_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_speed_q31_set_config(p2d_speed_q31_t *ctl, const p2d_speed_fixed_config_t *cfg);

/* Bumpless reset: feedforward at rest at the reference w_ref_q31, x = T_init_q31 (the output at zero error). */
void p2d_speed_q31_reset(p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t T_init_q31);

/* Compute the command for this sample; does not change the state. */
void p2d_speed_q31_compute(const p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t w_m_q31, p2d_speed_q31_output_t *out);

/* Update the state with the torque actually applied (after every limit) [Q31 of T_fs]. */
void p2d_speed_q31_update(p2d_speed_q31_t *ctl, const p2d_speed_q31_output_t *out, int32_t T_applied_q31);

/* compute + update with the controller's own limited torque. */
void p2d_speed_q31_step(p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t w_m_q31, p2d_speed_q31_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SPEED_FIXED_H */
