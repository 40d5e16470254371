/*
 * pmsm2dof: the speed of an incremental encoder, from the reading of its
 * hardware counter once per speed period Ts_s.
 *
 * The counter counts counts_per_rev per mechanical revolution (4 x the lines
 * of a quadrature encoder) and wraps at 2^counter_bits (16-bit or 32-bit MCU
 * timers). The increment over one period is taken modulo 2^counter_bits as a
 * signed number,
 *   dn[k] = ((n[k] - n[k-1]) mod 2^bits) in [-2^(bits-1), 2^(bits-1))   [count]
 * which is right while the rotor moves less than half the counter range in one
 * period: |w_m| < pi 2^bits / (counts_per_rev Ts_s).
 *
 * Estimators, with the resolution w_res = 2 pi / (counts_per_rev Ts_s) [rad/s]
 * (one count per period; 60 / (counts_per_rev Ts_s) rpm):
 *   DIFFERENCE  w[k] = w_res dn[k]: the mean speed over the last period, an
 *               integer multiple of w_res (M method).
 *   PLL         a type-2 tracking loop on the counted angle theta[k], in counts
 *               and counts per period (v = w / w_res):
 *                 e[k]         = theta[k] - theta_hat[k-1] - v[k-1]          angle error [count]
 *                 theta_hat[k] = theta_hat[k-1] + v[k-1] + (1 - p^2) e[k]
 *                 v[k]         = v[k-1] + (1 - p)^2 e[k],   w[k] = w_res v[k]
 *               a critically damped loop whose two poles are the bilinear
 *               image of s = -bandwidth_radps:
 *                 p = (2 - bandwidth_radps Ts_s) / (2 + bandwidth_radps Ts_s).
 *               From the counted increments to the estimate,
 *                 W(z) / (w_res DN(z)) = (1 - p)^2 / (1 - p z^-1)^2,
 *               the discrete counterpart of w_pll^2 / (s + w_pll)^2 of the
 *               continuous loop d theta_hat/dt = w + 2 w_pll e, dw/dt = w_pll^2 e
 *               (-3 dB at about 0.644 w_pll; at low frequencies a delay of
 *               2 / w_pll - Ts_s after the increment, which itself lags the
 *               speed by Ts_s / 2). Unity gain at DC: at constant speed the
 *               estimate settles on the mean speed. The angle is kept as
 *               theta_hat - theta (bounded), never as a growing float; p and
 *               1 - p are stored so that they sum to 1 exactly and the gains
 *               are applied as products of them, so that float32 keeps the
 *               double pole (no coefficient rounding splits it).
 * Optional first-order low-pass on the estimate (lowpass_radps > 0), its pole
 * the bilinear image of s = -lowpass_radps:
 *   y[k] = q y[k-1] + (1 - q) w[k],   q = (2 - lowpass_radps Ts_s) / (2 + lowpass_radps Ts_s),
 * unity gain at DC, a low-frequency delay of 1 / lowpass_radps - Ts_s / 2.
 * lowpass_radps = 0: no filter, y[k] = w[k] exactly.
 *
 * The step reads only an integer counter, and init requires the largest
 * difference estimate w_res 2^(counter_bits - 1) to be finite: the estimators
 * are stable, so the outputs stay finite. Non-finite policy: should the new
 * estimate still not be finite (an overflow, only reachable by switching
 * parameters while the state is far out of the new range), the output holds
 * the previous measured speed with `fault` set, the state is not updated (the
 * reading is taken) and fault_count is incremented; p2d_encoder_reset with a
 * speed that is not finite or not measurable (|w| > w_res 2^(counter_bits - 1))
 * starts from rest and counts a fault. The lower bound 1e-3 on the poles'
 * w Ts keeps their increments above the float32 resolution of the state.
 *
 * Parameter updates: p2d_encoder_set_config validates into the inactive of two
 * coefficient sets and activates it with one aligned 32-bit store (as
 * p2d_speed_set_config); the state is kept. The PLL's state is in counts
 * per period: after a change of counts_per_rev, counter_bits or Ts_s while
 * running, reset with the present reading and speed.
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_ENCODER_H
#define PMSM2DOF_ENCODER_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    P2D_ESTIMATOR_DIFFERENCE = 0, /* counts over one period */
    P2D_ESTIMATOR_PLL = 1         /* type-2 tracking loop on the counted angle */
} p2d_estimator_t;

typedef struct {
    uint32_t counts_per_rev;   /* counts per mechanical revolution [count], >= 1 */
    uint32_t counter_bits;     /* width of the hardware counter [bit], 2..32: it wraps at 2^counter_bits */
    float Ts_s;                /* speed period, time between two readings [s], > 0 */
    p2d_estimator_t estimator; /* difference or pll */
    float bandwidth_radps;     /* PLL pole (double) w_pll [rad/s], > 0, 1e-3 <= bandwidth_radps Ts_s <= 2; pll only */
    float lowpass_radps;       /* low-pass pole on the estimate [rad/s], >= 0: 0 or 1e-3 <= lowpass_radps Ts_s <= 2 */
} p2d_encoder_config_t;

/* Precomputed coefficients: everything the step needs for one Ts. */
typedef struct {
    float w_res_radps;            /* speed of one count per period 2 pi / (counts_per_rev Ts_s) [rad/s] */
    float counts_per_radps;       /* 1 / w_res: counts per period at 1 rad/s [count/(rad/s)] */
    float pll_pole;               /* PLL pole p [-]; 0 for difference */
    float pll_one_minus_pole;     /* PLL 1 - p [-], p + (1 - p) = 1 exactly; 1 for difference */
    float lowpass_pole;           /* low-pass pole q [-]; 0 without the filter */
    float lowpass_one_minus_pole; /* low-pass 1 - q [-], q + (1 - q) = 1 exactly; 1 without the filter */
    uint32_t counter_mask;        /* 2^counter_bits - 1 [count] */
    uint32_t counter_half;        /* 2^(counter_bits - 1): the first increment read as negative [count] */
    p2d_estimator_t estimator;    /* difference or pll */
} p2d_encoder_coef_t;

typedef struct {
    p2d_encoder_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;             /* index of the active set, 0 or 1 */
    p2d_encoder_config_t config; /* configuration of the active set */
    uint32_t count_prev;         /* counter reading of the previous period n[k-1] [count] */
    float theta_err_counts;      /* PLL: theta_hat[k-1] - theta[k-1] [count] */
    float v_pll_counts;          /* PLL speed v[k-1] = w[k-1] / w_res [count per period] */
    float w_lowpass_radps;       /* low-pass output y[k-1] [rad/s] */
    uint32_t fault_count;        /* resets refused by the non-finite policy [-] */
} p2d_encoder_t;

/* Result of one step. */
typedef struct {
    int32_t dn_counts; /* counted increment of this period dn[k] [count] */
    float w_raw_radps; /* estimator output w[k], before the low-pass [rad/s] */
    float w_m_radps;   /* measured speed y[k], after the low-pass (the speed controller's input) [rad/s] */
    bool fault;        /* non-finite policy engaged: w_raw_radps and w_m_radps hold y[k-1] */
} p2d_encoder_output_t;

/* Validate cfg and precompute; on error enc is left unchanged. Resets the state with reading 0 and speed 0. */
p2d_status_t p2d_encoder_init(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; state is kept. On error nothing changes. */
p2d_status_t p2d_encoder_set_config(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg);

/*
 * Start from the counter reading count (call it before the first step) with
 * the speed estimate and the low-pass at w_m_radps [rad/s]. A w_m_radps that
 * is not finite or beyond w_res 2^(counter_bits - 1) starts them at 0 and
 * counts a fault.
 */
void p2d_encoder_reset(p2d_encoder_t *enc, uint32_t count, float w_m_radps);

/* One speed period: the counter reading count [count] (bits above counter_bits are ignored). */
void p2d_encoder_step(p2d_encoder_t *enc, uint32_t count, p2d_encoder_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_ENCODER_H */
