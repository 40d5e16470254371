/*
 * dq current controllers: see pmsm2dof/current.h for the equations.
 */
#include "pmsm2dof/current.h"

#include <math.h>

#include "current_step.h"
#include "pi.h"

/* PI coefficients of one axis with inductance L_H (eq 3: Kp = L/tau_i, Ki = Rs/tau_i; eq 14, Table 1). */
static p2d_pi_coef_t axis_coefficients(const p2d_current_config_t *cfg, float L_H)
{
    p2d_pi_coef_t a = p2d_pi_coefficients(L_H / cfg->tau_i_s, cfg->Rs_ohm / cfg->tau_i_s, cfg->Ts_s, cfg->method);
    /* back calculation with Ka = 1/Kp: Ki Ka Ts = Ki Ts / Kp = Rs Ts / L */
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) a.Ki_Ka_Ts = a.Ki_Ts / a.Kp;
    return a;
}

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t current_coefficients(const p2d_current_config_t *cfg, p2d_current_coef_t *c)
{
    p2d_current_coef_t k;
    if (!p2d_is_positive(cfg->Rs_ohm)) return P2D_ERR_RS;
    if (!p2d_is_positive(cfg->Ld_H)) return P2D_ERR_LD;
    if (!p2d_is_positive(cfg->Lq_H)) return P2D_ERR_LQ;
    if (!p2d_is_nonnegative(cfg->psi_f_Wb)) return P2D_ERR_PSI_F;
    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (!isfinite(cfg->tau_i_s) || !(cfg->tau_i_s >= cfg->Ts_s)) return P2D_ERR_TAU_I;
    if ((unsigned)cfg->method > (unsigned)P2D_TUSTIN) return P2D_ERR_METHOD;
    if ((unsigned)cfg->anti_windup > (unsigned)P2D_AW_CLAMPING) return P2D_ERR_ANTI_WINDUP;
    /* the discrete back-calculation loop x[k] = (1 - Rs Ts / L) x[k-1] + ... must be stable */
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION &&
        !(cfg->Rs_ohm * cfg->Ts_s < 2.0f * (cfg->Ld_H < cfg->Lq_H ? cfg->Ld_H : cfg->Lq_H))) {
        return P2D_ERR_TS_UNSTABLE;
    }

    k.d = axis_coefficients(cfg, cfg->Ld_H);
    k.q = axis_coefficients(cfg, cfg->Lq_H);
    if (!p2d_pi_finite(&k.d) || !p2d_pi_finite(&k.q))
        return P2D_ERR_TAU_I; /* float32 overflow of L/tau_i or Rs/tau_i */
    /* the same stability bound on the float32 loop gains: rounding can make Rs Ts / L exactly 2 */
    if (!(k.d.Ki_Ka_Ts < 2.0f && k.q.Ki_Ka_Ts < 2.0f)) return P2D_ERR_TS_UNSTABLE;
    k.Ld_H = cfg->decouple ? cfg->Ld_H : 0.0f;
    k.Lq_H = cfg->decouple ? cfg->Lq_H : 0.0f;
    k.psi_f_Wb = cfg->decouple ? cfg->psi_f_Wb : 0.0f;
    k.clamping = cfg->anti_windup == P2D_AW_CLAMPING;
    *c = k;
    return P2D_OK;
}

p2d_status_t p2d_current_init(p2d_current_t *ctl, const p2d_current_config_t *cfg)
{
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    status = current_coefficients(cfg, &ctl->coef[0]);
    if (status != P2D_OK) return status;
    ctl->coef[1] = ctl->coef[0];
    ctl->active = 0u;
    ctl->config = *cfg;
    ctl->fault_count = 0u;
    p2d_current_reset(ctl);
    return P2D_OK;
}

/* The shadow swap of pi.h. */
p2d_status_t p2d_current_set_config(p2d_current_t *ctl, const p2d_current_config_t *cfg)
{
    p2d_status_t status;
    uint32_t inactive;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(ctl->active);
    status = current_coefficients(cfg, &ctl->coef[inactive]);
    if (status != P2D_OK) return status;
    ctl->config = *cfg;
    p2d_shadow_activate(&ctl->active, inactive);
    return P2D_OK;
}

void p2d_current_reset(p2d_current_t *ctl)
{
    ctl->x_d_V = 0.0f;
    ctl->x_q_V = 0.0f;
}

void p2d_current_compute(const p2d_current_t *ctl, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                         float w_e_radps, float u_dc_V, p2d_current_output_t *out)
{
    (void)p2d_current_voltage(ctl, &ctl->coef[ctl->active], id_ref_A, iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V, out);
}

void p2d_current_update(p2d_current_t *ctl, const p2d_current_output_t *out, float ud_applied_V, float uq_applied_V)
{
    if (out->fault || !isfinite(ud_applied_V) || !isfinite(uq_applied_V)) {
        ctl->fault_count++;
        return;
    }
    p2d_current_integrate(ctl, &ctl->coef[ctl->active], out, ud_applied_V, uq_applied_V);
}

/* compute + update with the own command, which is finite whenever the output is not a fault. */
void p2d_current_step(p2d_current_t *ctl, float id_ref_A, float iq_ref_A, float id_A, float iq_A, float w_e_radps,
                      float u_dc_V, p2d_current_output_t *out)
{
    const p2d_current_coef_t *c = &ctl->coef[ctl->active];
    if (p2d_current_voltage(ctl, c, id_ref_A, iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V, out)) {
        p2d_current_integrate(ctl, c, out, out->ud_ref_V, out->uq_ref_V);
    } else {
        ctl->fault_count++;
    }
}
