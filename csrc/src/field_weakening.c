/*
 * Voltage-feedback field weakening: see pmsm2dof/field_weakening.h for the equations.
 */
#include "pmsm2dof/field_weakening.h"

#include <math.h>

#include "pi.h"

#define P2D_INV_SQRT3 0.57735026918962576f /* 1/sqrt(3) */

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t field_weakening_coefficients(const p2d_field_weakening_config_t *cfg, p2d_field_weakening_coef_t *c)
{
    p2d_field_weakening_coef_t k;
    if (!p2d_is_nonnegative(cfg->Kp_A_per_V)) return P2D_ERR_FW_KP;
    if (!p2d_is_positive(cfg->Ki_A_per_Vs)) return P2D_ERR_FW_KI;
    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (!p2d_is_positive(cfg->voltage_ratio) || !(cfg->voltage_ratio <= 1.0f)) return P2D_ERR_FW_VOLTAGE_RATIO;
    if (!isfinite(cfg->id_min_A) || !(cfg->id_min_A < 0.0f)) return P2D_ERR_FW_ID_MIN;
    if ((unsigned)cfg->method > (unsigned)P2D_TUSTIN) return P2D_ERR_METHOD;
    if ((unsigned)cfg->anti_windup > (unsigned)P2D_AW_CLAMPING) return P2D_ERR_ANTI_WINDUP;
    if (!p2d_is_nonnegative(cfg->Ka_V_per_A)) return P2D_ERR_FW_KA;

    /* eq 14 and Table 1, e in V, u in A */
    k.pi = p2d_pi_coefficients(cfg->Kp_A_per_V, cfg->Ki_A_per_Vs, cfg->Ts_s, cfg->method);
    if (!p2d_is_positive(k.pi.Ki_Ts) || !p2d_pi_finite(&k.pi)) return P2D_ERR_FW_KI;
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        /* the discrete back-calculation loop x[k] = (1 - Ki Ka Ts) x[k-1] + ... must be stable */
        k.pi.Ki_Ka_Ts = k.pi.Ki_Ts * cfg->Ka_V_per_A;
        if (!(k.pi.Ki_Ka_Ts < 2.0f)) return P2D_ERR_FW_KA;
    }
    k.u_ref_per_u_dc = cfg->voltage_ratio * P2D_INV_SQRT3;
    k.id_min_A = cfg->id_min_A;
    k.clamping = cfg->anti_windup == P2D_AW_CLAMPING;
    *c = k;
    return P2D_OK;
}

p2d_status_t p2d_field_weakening_init(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg)
{
    p2d_status_t status;
    if (fw == 0 || cfg == 0) return P2D_ERR_NULL;
    status = field_weakening_coefficients(cfg, &fw->coef[0]);
    if (status != P2D_OK) return status;
    fw->coef[1] = fw->coef[0];
    fw->active = 0u;
    fw->config = *cfg;
    fw->fault_count = 0u;
    p2d_field_weakening_reset(fw, 0.0f);
    return P2D_OK;
}

/* The shadow swap of pi.h. */
p2d_status_t p2d_field_weakening_set_config(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg)
{
    p2d_status_t status;
    uint32_t inactive;
    if (fw == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(fw->active);
    status = field_weakening_coefficients(cfg, &fw->coef[inactive]);
    if (status != P2D_OK) return status;
    fw->config = *cfg;
    p2d_shadow_activate(&fw->active, inactive);
    return P2D_OK;
}

/* Sat(v) within [id_min, 0]; NaN gives id_min */
static inline float id_limited(const p2d_field_weakening_coef_t *c, float v)
{
    if (v > 0.0f) return 0.0f;
    return v >= c->id_min_A ? v : c->id_min_A;
}

void p2d_field_weakening_reset(p2d_field_weakening_t *fw, float id_A)
{
    if (!isfinite(id_A)) {
        /* non-finite policy: start at id = 0 instead, count the fault */
        fw->fault_count++;
        id_A = 0.0f;
    }
    fw->x_A = id_limited(&fw->coef[fw->active], id_A);
}

/* Non-finite policy: hold the integrator's current, fault raised; the caller leaves the state alone. */
static void fault_output(p2d_field_weakening_t *fw, const p2d_field_weakening_coef_t *c,
                         p2d_field_weakening_output_t *out)
{
    out->id_ref_A = id_limited(c, fw->x_A);
    out->active = out->id_ref_A < 0.0f;
    out->at_id_min = out->id_ref_A == c->id_min_A;
    out->fault = true;
    fw->fault_count++;
}

void p2d_field_weakening_step(p2d_field_weakening_t *fw, float ud_V, float uq_V, float u_dc_V,
                              p2d_field_weakening_output_t *out)
{
    const p2d_field_weakening_coef_t *c = &fw->coef[fw->active];
    float norm2, u_ref, e, v, id, x;

    /* u_ref = voltage_ratio max(u_dc, 0) / sqrt(3) */
    u_ref = u_dc_V > 0.0f ? c->u_ref_per_u_dc * u_dc_V : 0.0f;
    /* ||u_dq||^2 = ud^2 + uq^2 */
    norm2 = fmaf(ud_V, ud_V, uq_V * uq_V);
    /* e[k] = u_ref - ||u_dq|| */
    e = u_ref - p2d_sqrt_nonnegative(norm2);
    /* v[k] = b_e0 e[k] + x[k-1] */
    v = p2d_pi_output(c->pi, e, fw->x_A);
    out->u_ref_V = u_ref;
    out->e_V = e;
    out->id_unsat_A = v;
    /* u_dc_V is tested itself: a NaN measurement must not pass as a zero voltage range */
    if (!(fabsf(v) < INFINITY) || !(fabsf(u_dc_V) < INFINITY)) {
        /* NaN or inf input, or ||u_dq||^2 or v overflowed */
        fault_output(fw, c, out);
        return;
    }
    /* id_ref = Sat(v) within [id_min, 0] */
    id = id_limited(c, v);
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts (id_ref - v) */
    x = fw->x_A + p2d_pi_integration(c->pi, c->clamping, e, id - v);
    out->id_ref_A = id;
    out->active = id < 0.0f;
    out->at_id_min = id == c->id_min_A;
    out->fault = false;
    if (!isfinite(x)) {
        /* non-finite policy: an update that would overflow the integrator is refused */
        fw->fault_count++;
        return;
    }
    fw->x_A = x;
}
