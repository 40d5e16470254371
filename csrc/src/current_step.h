/*
 * Internal (not installed, not part of the API): the arithmetic of one sample
 * of the dq current controllers (pmsm2dof/current.h) as static inline
 * functions. current.c builds p2d_current_compute, p2d_current_update and
 * p2d_current_step of them; the host's simulation engine (csrc/sim/drive.c)
 * inlines them into its loop, so that the engine runs this one source, with
 * no call and no output struct through memory per current period.
 */
#ifndef PMSM2DOF_SRC_CURRENT_STEP_H
#define PMSM2DOF_SRC_CURRENT_STEP_H

#include <math.h>
#include <stdbool.h>

#include "pi.h"
#include "pmsm2dof/current.h"

#define P2D_INV_SQRT3 0.57735026918962576f /* 1/sqrt(3) */
#define P2D_SQRT2 1.41421356237309505f     /* sqrt(2) */
/*
 * Smallest ud^2 + uq^2 [V^2] whose float32 sum is compared with u_max^2 as is: any square that
 * underflowed below it (< 2^-126, subnormal or 0) is < 2^-26 of the sum, under its rounding.
 * Below, or on overflow, the limit is applied the long way, which needs no square.
 */
#define P2D_NORM2_MIN_V2 0x1p-100f

/* Non-finite policy: zero voltage, fault raised, so that the update leaves the state alone. */
static inline bool p2d_current_fault_output(p2d_current_output_t *out)
{
    out->ud_ref_V = 0.0f;
    out->uq_ref_V = 0.0f;
    out->saturated = false;
    out->fault = true;
    return false;
}

/*
 * The voltage command of this sample into out (p2d_current_compute); returns !out->fault. Inlined
 * in step, which then saves no registers.
 */
static P2D_ALWAYS_INLINE bool p2d_current_voltage(const p2d_current_t *ctl, const p2d_current_coef_t *c, float id_ref_A,
                                                  float iq_ref_A, float id_A, float iq_A, float w_e_radps, float u_dc_V,
                                                  p2d_current_output_t *out)
{
    float ed, eq, ud, uq, u_max, norm2, ud_abs, uq_max;

    ed = id_ref_A - id_A;
    eq = iq_ref_A - iq_A;
    /* ud[k] = b_e0 ed[k] + xd[k-1] - w_e Lq iq (decoupling, eq 1) */
    ud = p2d_pi_output(c->d, ed, ctl->x_d_V) - w_e_radps * c->Lq_H * iq_A;
    /* uq[k] = b_e0 eq[k] + xq[k-1] + w_e (Ld id + psi_f) */
    uq = p2d_pi_output(c->q, eq, ctl->x_q_V) + w_e_radps * fmaf(c->Ld_H, id_A, c->psi_f_Wb);
    out->ed_A = ed;
    out->eq_A = eq;
    out->ud_unsat_V = ud;
    out->uq_unsat_V = uq;
    /* u_dc_V is tested itself: a NaN measurement must not pass as a zero voltage limit */
    if (!(fabsf(u_dc_V) < INFINITY && fabsf(ud) < INFINITY && fabsf(uq) < INFINITY))
        return p2d_current_fault_output(out);
    /* linear range of space-vector modulation: ||u_dq|| <= u_max = u_dc / sqrt(3) */
    u_max = u_dc_V > 0.0f ? u_dc_V * P2D_INV_SQRT3 : 0.0f;
    out->fault = false;
    norm2 = fmaf(ud, ud, uq * uq);
    if (norm2 >= P2D_NORM2_MIN_V2 && norm2 < INFINITY && norm2 <= u_max * u_max) {
        /* inside the circle, its squares neither overflowed nor lost: the vector as it is, no root */
        out->ud_ref_V = ud;
        out->uq_ref_V = uq;
        out->saturated = false;
        return true;
    }
    /* d-axis priority: ud_ref = Sat(ud) within [-u_max, u_max] */
    out->ud_ref_V = ud > u_max ? u_max : (ud < -u_max ? -u_max : ud);
    /*
     * uq_ref = Sat(uq) within what the circle leaves, |uq| <= sqrt(u_max^2 - ud_ref^2)
     * = sqrt(2) sqrt(u_max - |ud_ref|) sqrt(u_max/2 + |ud_ref|/2): no square to overflow or underflow
     */
    ud_abs = fabsf(out->ud_ref_V);
    uq_max = P2D_SQRT2 * p2d_sqrt_nonnegative(u_max - ud_abs) * p2d_sqrt_nonnegative(0.5f * u_max + 0.5f * ud_abs);
    out->uq_ref_V = uq > uq_max ? uq_max : (uq < -uq_max ? -uq_max : uq);
    out->saturated = out->ud_ref_V != ud || out->uq_ref_V != uq;
    return true;
}

/* The state update with the applied voltages (finite) of an output that is not a fault. */
static inline void p2d_current_integrate(p2d_current_t *ctl, const p2d_current_coef_t *c,
                                         const p2d_current_output_t *out, float ud_applied_V, float uq_applied_V)
{
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] per axis, u* = u_sat - u */
    float x_d = ctl->x_d_V + p2d_pi_integration(c->d, c->clamping, out->ed_A, ud_applied_V - out->ud_unsat_V);
    float x_q = ctl->x_q_V + p2d_pi_integration(c->q, c->clamping, out->eq_A, uq_applied_V - out->uq_unsat_V);
    if (!isfinite(x_d) || !isfinite(x_q)) {
        /* non-finite policy: an update that would overflow an integrator is refused */
        ctl->fault_count++;
        return;
    }
    ctl->x_d_V = x_d;
    ctl->x_q_V = x_q;
}

#endif /* PMSM2DOF_SRC_CURRENT_STEP_H */
