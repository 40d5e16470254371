/*
 * Internal (not installed, not part of the API): the integer arithmetic of the
 * fixed-point speed controllers (pmsm2dof/speed_fixed.h) and their shared
 * initialisation.
 *
 * Rounding R(p, s) = floor(p / 2^s + 1/2), round half up, for 1 <= s < the
 * width of p. A right shift of a negative number is implementation-defined in
 * C and a left shift of one undefined: floor(p / 2^s) is taken as p >> s for
 * p >= 0 and as ~(~p >> s) for p < 0 (~p = -p - 1 >= 0 in two's complement,
 * which the exact-width types are), and R as floor((floor(p / 2^(s-1)) + 1) / 2),
 * equal to floor(p / 2^s + 1/2) (with t = floor(p / 2^(s-1)), p / 2^(s-1) = t + f,
 * 0 <= f < 1: floor((t + f + 1) / 2) = floor((t + 1) / 2) for integer t), whose
 * sum cannot overflow: |t| <= 2^(width-2).
 */
#ifndef PMSM2DOF_SRC_FIXED_H
#define PMSM2DOF_SRC_FIXED_H

#include <stdint.h>

#include "pmsm2dof/speed_fixed.h"

/* floor(p / 2^s), 0 <= s <= 31 */
static inline int32_t p2d_floor_shift32(int32_t p, uint32_t s) { return p >= 0 ? p >> s : ~(~p >> s); }

/* floor(p / 2^s), 0 <= s <= 63 */
static inline int64_t p2d_floor_shift64(int64_t p, uint32_t s) { return p >= 0 ? p >> s : ~(~p >> s); }

/* R(p, s) = floor(p / 2^s + 1/2), 1 <= s <= 31 (every gain's shift is >= 1: p2d_fixed_gain) */
static inline int32_t p2d_round_shift32(int32_t p, uint32_t s)
{
    return p2d_floor_shift32(p2d_floor_shift32(p, s - 1u) + 1, 1u);
}

/* R(p, s) = floor(p / 2^s + 1/2), 1 <= s <= 63 */
static inline int64_t p2d_round_shift64(int64_t p, uint32_t s)
{
    return p2d_floor_shift64(p2d_floor_shift64(p, s - 1u) + 1, 1u);
}

/* v limited to [-limit, limit] */
static inline int32_t p2d_clamp32(int32_t v, int32_t limit) { return v > limit ? limit : (v < -limit ? -limit : v); }

/* v limited to [-limit, limit] */
static inline int64_t p2d_clamp64(int64_t v, int64_t limit) { return v > limit ? limit : (v < -limit ? -limit : v); }

/* a + b limited to [-INT64_MAX, INT64_MAX] */
static inline int64_t p2d_add_sat64(int64_t a, int64_t b)
{
    if (b > 0 && a > INT64_MAX - b) return INT64_MAX;
    if (b < 0 && a < -INT64_MAX - b) return -INT64_MAX;
    return a + b;
}

/* p 2^n limited to [-INT64_MAX, INT64_MAX], 0 <= n <= 62 (a product, never a shift of a negative number) */
static inline int64_t p2d_scale_sat64(int64_t p, uint32_t n)
{
    const int64_t bound = INT64_MAX >> n;
    if (p > bound) return INT64_MAX;
    if (p < -bound) return -INT64_MAX;
    return p * ((int64_t)1 << n);
}

/* Largest shift of a gain of N fractional bits: 2N + 1 (31 for Q15, 63 for Q31). */
#define P2D_FIXED_MAX_SHIFT(bits) (2u * (bits) + 1u)

/*
 * The gain g as m 2^-s with |m| <= 2^bits - 1 (speed_fixed.h): the largest s <= 2 bits + 1 with
 * |g| 2^s < 2^bits, m = g 2^s rounded to the nearest integer, ties away from zero (and s one
 * less if that rounds up to 2^bits). |g| < 2^(bits - 2) is required (init checks it), so that
 * s >= 2.
 */
void p2d_fixed_gain(double g, uint32_t bits, int32_t *mantissa, uint32_t *shift);

/*
 * Validate cfg for a controller of `bits` fractional bits (15 or 31), compute its gains
 * (p2d_speed_q15_gains, p2d_speed_q31_gains) and the integer limits T_max = floor(T_max 2^bits) and
 * iq_max = floor(iq_max 2^bits) (each >= 1, <= 2^bits - 1); the clamping flag. When `active`
 * is not NULL (set_config), the full scales must equal its.
 */
p2d_status_t p2d_speed_fixed_prepare(const p2d_speed_fixed_config_t *cfg, uint32_t bits,
                                     const p2d_speed_fixed_config_t *active, p2d_speed_fixed_gains_t *gains,
                                     int32_t *T_max, int32_t *iq_max);

#endif /* PMSM2DOF_SRC_FIXED_H */
