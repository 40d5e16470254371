/*
 * Internal (not installed, not part of the API): the filter chain of
 * pmsm2dof/filter.h as building blocks, shared by p2d_filter_t (filter.c) and
 * the torque filters of the speed controller (speed.c).
 *
 * - the design and validation of the chain's coefficients;
 * - the stability test of an integrator loop closed through the chain (the
 *   speed controller's back-calculation anti-windup loop);
 * - the output of the chain with its next state, static inline, without
 *   writing the state (the speed controller computes, then updates);
 * - the state at rest, and the start of sections switched on by an update.
 * Equations and their derivation: pmsm2dof/filter.h.
 */
#ifndef PMSM2DOF_SRC_BIQUAD_H
#define PMSM2DOF_SRC_BIQUAD_H

#include <math.h>
#include <stdbool.h>

#include "pmsm2dof/filter.h"
#include "pmsm2dof/status.h"

/*
 * Validate cfg at the sampling period Ts_s (finite and > 0: the caller's to
 * validate first) and compute the chain's coefficients into *c; *c is written
 * only on success.
 */
p2d_status_t p2d_filter_coefficients(const p2d_filter_config_t *cfg, float Ts_s, p2d_filter_coef_t *c);

/*
 * The loop x[k] = x[k-1] - g y[k], y = H(z) x[k-1] (an integrator closed
 * through the chain H with the loop gain g > 0 per sample) is stable: every
 * root of z - 1 + g H(z) is inside the unit circle.
 */
bool p2d_filter_loop_stable(const p2d_filter_coef_t *c, float g);

/* The sections of `to` that `from` has off start at rest at `level` (a parameter update). */
void p2d_filter_switch_on(const p2d_filter_coef_t *from, const p2d_filter_coef_t *to, p2d_filter_state_t *s,
                          float level);

/* A section of the chain is on. */
static inline bool p2d_filter_on(const p2d_filter_coef_t *c) { return c->has_notch || c->has_lowpass; }

/* Every state of the sections that are on is finite. */
static inline bool p2d_filter_state_finite(const p2d_filter_coef_t *c, const p2d_filter_state_t *s)
{
    return (!c->has_notch || (isfinite(s->notch.s1) && isfinite(s->notch.s2))) &&
           (!c->has_lowpass || (isfinite(s->lowpass.s1) && isfinite(s->lowpass.s2)));
}

/* The chain at rest at the constant input `level`: s1 = 0, s2 = level in each section. */
static inline void p2d_filter_rest(p2d_filter_state_t *s, float level)
{
    s->notch.s1 = 0.0f;
    s->notch.s2 = level;
    s->lowpass.s1 = 0.0f;
    s->lowpass.s2 = level;
}

/*
 * Stores the states of the sections that are on (those that are off are not
 * written, so that a parameter update may start them meanwhile).
 */
static inline void p2d_filter_store(const p2d_filter_coef_t *c, p2d_filter_state_t *s, const p2d_filter_state_t *next)
{
    if (c->has_notch) s->notch = next->notch;
    if (c->has_lowpass) s->lowpass = next->lowpass;
}

/*
 * One section: the band-pass v1 of this sample (returned), the low-pass v2
 * into *v2, the state after this sample into *next.
 */
static inline float p2d_biquad_run(const p2d_biquad_coef_t *c, const p2d_biquad_state_t *s, float x, float *v2,
                                   p2d_biquad_state_t *next)
{
    /* v1 = s1 + g h (x - s2 - g s1 - k s1) */
    const float v1 = fmaf(c->g_h, fmaf(-c->k, s->s1, fmaf(-c->g, s->s1, x - s->s2)), s->s1);
    /* v2 = s2 + g v1 */
    *v2 = fmaf(c->g, v1, s->s2);
    /* s1[k] = 2 v1 - s1[k-1] */
    next->s1 = fmaf(2.0f, v1, -s->s1);
    /* s2[k] = 2 v2 - s2[k-1] */
    next->s2 = fmaf(2.0f, *v2, -s->s2);
    return v1;
}

/*
 * y = H(z) x, the chain's output for the input x from the state s, and the
 * state after this sample into *next (sections off keep theirs); s is not written.
 */
static inline float p2d_filter_output(const p2d_filter_coef_t *c, const p2d_filter_state_t *s, float x,
                                      p2d_filter_state_t *next)
{
    float y = x, v1, v2;
    *next = *s;
    if (c->has_notch) {
        v1 = p2d_biquad_run(&c->notch, &s->notch, y, &v2, &next->notch);
        /* notch: y = x - (1 - d) k v1 */
        y = fmaf(c->notch.c_band, v1, y);
    }
    if (c->has_lowpass) {
        (void)p2d_biquad_run(&c->lowpass, &s->lowpass, y, &v2, &next->lowpass);
        /* low-pass: y = v2 */
        y = v2;
    }
    return y;
}

#endif /* PMSM2DOF_SRC_BIQUAD_H */
