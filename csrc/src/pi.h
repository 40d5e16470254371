/*
 * Internal (not installed, not part of the API): the discrete PI building
 * block of the speed and the current controllers.
 *
 * - validation helpers of the init functions;
 * - the coefficients of the discrete PI per method (eq 14, Table 1);
 * - its output and its anti-windup state update, static inline so that the
 *   steps pay no call (they take the coefficients by value: once inlined,
 *   only the fields used are loaded, and GCC allocates the registers of the
 *   step as well as with the fields written out);
 * - the shadow coefficient-set swap of the parameter updates.
 * Plain functions and typed pointers only (no function pointers), so that the
 * static call graph of every entry point stays complete.
 *
 * The discrete PI of F(s) = Kp + Ki/s with back calculation (Fig. 5), the
 * same equations for every method (only b_e0 differs):
 *   u[k] = b_e0 e[k] + x[k-1]
 *   x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k],   u* = u_sat - u
 *   b_e0 = Kp (forward Euler), Kp + Ki Ts (backward Euler), Kp + Ki Ts / 2 (Tustin, eq 14)
 * The applied command is only known after the output is computed, so u*
 * enters the state one sample later for every method.
 */
#ifndef PMSM2DOF_SRC_PI_H
#define PMSM2DOF_SRC_PI_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

/* Keeps a function out of line where the compiler supports it (a code-size and register-saving hint only). */
#if defined(__GNUC__)
#define P2D_NOINLINE __attribute__((noinline))
#else
#define P2D_NOINLINE
#endif

/* Inlines a function even where it is large, if the compiler supports it. */
#if defined(__GNUC__)
#define P2D_ALWAYS_INLINE __attribute__((always_inline)) inline
#else
#define P2D_ALWAYS_INLINE inline
#endif

/* finite and > 0 */
static inline bool p2d_is_positive(float x) { return isfinite(x) && x > 0.0f; }

/* finite and >= 0 */
static inline bool p2d_is_nonnegative(float x) { return isfinite(x) && x >= 0.0f; }

/*
 * Square root of an argument that is >= 0 by construction (or NaN). Through
 * fabsf the compiler sees that, and emits the bare vsqrt.f32 without the
 * errno path (a call into libm's sqrtf for a negative argument).
 */
static inline float p2d_sqrt_nonnegative(float x) { return sqrtf(fabsf(x)); }

/* a < 0 < b or b < 0 < a, without a product that can underflow to 0 */
static inline bool p2d_opposite_signs(float a, float b) { return (a < 0.0f && b > 0.0f) || (a > 0.0f && b < 0.0f); }

/*
 * Kp, Ki, b_e0 and Ki Ts of the discrete PI of F(s) = Kp + Ki/s at the
 * sampling period Ts_s (eq 14, Table 1). Ki_Ka_Ts is 0: the controller that
 * uses back calculation sets it, as its Ka and its stability bound
 * Ki Ka Ts < 2 are its own. Not validated: the caller checks finiteness.
 */
p2d_pi_coef_t p2d_pi_coefficients(float Kp, float Ki, float Ts_s, p2d_method_t method);

/* Every coefficient of pi is finite. */
bool p2d_pi_finite(const p2d_pi_coef_t *pi);

/* u[k] = b_e0 e[k] + x (x: the state x[k-1] plus what the controller adds before the limit), rounded once */
static inline float p2d_pi_output(p2d_pi_coef_t pi, float e, float x) { return fmaf(pi.b_e0, e, x); }

/*
 * The integration x[k] - x[k-1] = Ki Ts e[k] + Ki Ka Ts u*[k] (Fig. 5, eq 14).
 * Clamping (conditional integration) holds it at 0 while the limit is active
 * and the error drives further into it: u* and e of opposite signs.
 */
static inline float p2d_pi_integration(p2d_pi_coef_t pi, bool clamping, float e, float u_star)
{
    float dx = fmaf(pi.Ki_Ka_Ts, u_star, pi.Ki_Ts * e);
    if (clamping && p2d_opposite_signs(u_star, e)) dx = 0.0f;
    return dx;
}

/*
 * The same integration when the limit is not active: u_sat = u, so u* = u - u
 * = +0 for a finite u, the clamping test is false and Ki Ka Ts u* = +0
 * (Ki Ka Ts >= 0 and finite): fmaf(Ki Ka Ts, +0, Ki Ts e) = Ki Ts e + 0,
 * where + 0 turns a -0 into +0 as the fused sum does. Equal to the bit to
 * p2d_pi_integration(pi, clamping, e, u - u), in fewer instructions.
 */
static inline float p2d_pi_integration_unlimited(p2d_pi_coef_t pi, float e) { return pi.Ki_Ts * e + 0.0f; }

/*
 * Shadow coefficient sets (as in TI's DCL): a controller keeps two sets
 * coef[2] and the index `active` of the one its step reads. A parameter update
 *   1. validates the new configuration and computes its set into
 *      coef[p2d_shadow_inactive(active)], writing nothing on error,
 *   2. copies the configuration,
 *   3. switches with p2d_shadow_activate,
 * so that on error nothing changes, and a step that preempts the update reads
 * the old set or the new one, never a mix.
 */
static inline uint32_t p2d_shadow_inactive(uint32_t active) { return 1u - active; }

/*
 * Makes the set `index` active with one aligned 32-bit store, after a compiler
 * barrier so that the set is complete in memory first (on a single-core MCU,
 * the step in an interrupt then sees either set whole).
 */
static inline void p2d_shadow_activate(uint32_t *active, uint32_t index)
{
#if defined(__GNUC__)
    __asm__ volatile("" ::: "memory");
#endif
    *active = index;
}

#endif /* PMSM2DOF_SRC_PI_H */
