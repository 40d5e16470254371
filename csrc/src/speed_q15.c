/*
 * The Q15 speed controller: int16 inputs and outputs, int32 arithmetic (what a
 * Cortex-M0 multiplies in one instruction). The contract and the arithmetic
 * rules are in pmsm2dof/speed_fixed.h.
 */
#include "fixed.h"
#include "pi.h"

/* Fractional bits of the format */
#define Q15_BITS 15u
/* Two full scales less one LSB: the bound of every signal and state, 2^16 - 1 */
#define Q15_SIGNAL_MAX 65535

/* The gain g as a Q15 gain. */
static p2d_q15_gain_t q15_gain(double g)
{
    p2d_q15_gain_t q;
    int32_t m;
    uint32_t s;
    p2d_fixed_gain(g, Q15_BITS, &m, &s);
    q.mantissa = (int16_t)m;
    q.shift = (uint16_t)s;
    return q;
}

/* R(g v): |v| <= 2^16 - 1 and |m| <= 2^15 - 1, so m v fits an int32 */
static inline int32_t q15_mul(p2d_q15_gain_t g, int32_t v) { return p2d_round_shift32(g.mantissa * v, g.shift); }

/* Validate cfg and compute its coefficients into *c (written only on success). */
static p2d_status_t q15_coefficients(const p2d_speed_fixed_config_t *cfg, const p2d_speed_fixed_config_t *active,
                                     p2d_speed_q15_coef_t *c)
{
    p2d_speed_fixed_gains_t g;
    int32_t T_max, iq_max;
    p2d_status_t status = p2d_speed_fixed_prepare(cfg, Q15_BITS, active, &g, &T_max, &iq_max);
    if (status != P2D_OK) return status;
    c->b_e0 = q15_gain(g.b_e0);
    c->Ki_Ts = q15_gain(g.Ki_Ts);
    c->Ki_Ka_Ts = q15_gain(g.Ki_Ka_Ts);
    c->ff_Fr0 = q15_gain(g.ff_Fr0);
    c->ff_b_dr = q15_gain(g.ff_b_dr);
    c->ff_one_plus_a1 = q15_gain(g.ff_one_plus_a1);
    c->ff_Kd_per_Ts = q15_gain(g.ff_Kd_per_Ts);
    c->iq_per_T = q15_gain(g.iq_per_T);
    c->T_max_q15 = (int16_t)T_max;
    c->iq_max_q15 = (int16_t)iq_max;
    c->clamping = cfg->speed.anti_windup == P2D_AW_CLAMPING;
    return P2D_OK;
}

p2d_status_t p2d_speed_q15_init(p2d_speed_q15_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    status = q15_coefficients(cfg, 0, &ctl->coef[0]);
    if (status != P2D_OK) return status;
    /* the shadow set equal to the active one, computed again rather than copied (a copy would call memcpy) */
    (void)q15_coefficients(cfg, 0, &ctl->coef[1]);
    ctl->active = 0u;
    ctl->config = *cfg;
    p2d_speed_q15_reset(ctl, 0, 0);
    return P2D_OK;
}

p2d_status_t p2d_speed_q15_set_config(p2d_speed_q15_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    uint32_t inactive;
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(ctl->active);
    status = q15_coefficients(cfg, &ctl->config, &ctl->coef[inactive]);
    if (status != P2D_OK) return status;
    ctl->config = *cfg;
    p2d_shadow_activate(&ctl->active, inactive);
    return P2D_OK;
}

void p2d_speed_q15_reset(p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t T_init_q15)
{
    /* steady state at r[k] = r[k-1] = w_ref: y = 0, and u = x at e = 0 */
    ctl->x_q15 = T_init_q15;
    ctl->y_ff_prev_q15 = 0;
    ctl->r_prev_q15 = w_ref_q15;
}

void p2d_speed_q15_compute(const p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t w_m_q15, p2d_speed_q15_output_t *out)
{
    const p2d_speed_q15_coef_t *c = &ctl->coef[ctl->active];
    /* e[k] = w_ref[k] - w_m[k], dr[k] = w_ref[k] - r[k-1]: |.| <= 2^16 - 1 */
    const int32_t e = (int32_t)w_ref_q15 - w_m_q15;
    const int32_t dr = (int32_t)w_ref_q15 - ctl->r_prev_q15;
    /* Kd dr[k] / Ts, the derivative of FULL (0 otherwise) */
    const int32_t T_d = q15_mul(c->ff_Kd_per_Ts, dr);
    int32_t y, u, T_sat;

    /* y[k] = b_dr dr[k] - a1 y[k-1] = b_dr dr[k] + y[k-1] - (1 + a1) y[k-1] */
    y = p2d_clamp32(q15_mul(c->ff_b_dr, dr) + ctl->y_ff_prev_q15 - q15_mul(c->ff_one_plus_a1, ctl->y_ff_prev_q15),
                    Q15_SIGNAL_MAX);
    /* u[k] = b_e0 e[k] + x[k-1] + Fr0 dr[k] + Kd dr[k] / Ts + y[k]: each term < 2^29 + 1, the sum < 2^31 */
    u = p2d_clamp32(q15_mul(c->b_e0, e) + ctl->x_q15 + q15_mul(c->ff_Fr0, dr) + T_d + y, Q15_SIGNAL_MAX);
    /* u_sat = Sat(u): the current-vector limit |iq| <= i_max as the torque limit T_max */
    T_sat = p2d_clamp32(u, c->T_max_q15);

    out->w_ref_q15 = w_ref_q15;
    out->e_q15 = e;
    /* T_ff[k] = Fr0 r[k] + Kd dr[k] / Ts + y[k] */
    out->T_ff_q15 = p2d_clamp32(q15_mul(c->ff_Fr0, w_ref_q15) + T_d + y, Q15_SIGNAL_MAX);
    out->y_ff_q15 = y;
    out->T_unsat_q15 = u;
    out->T_ref_q15 = (int16_t)T_sat;
    /* iq = u_sat / kt, within the current limit after rounding; id = 0 */
    out->iq_ref_q15 = (int16_t)p2d_clamp32(q15_mul(c->iq_per_T, T_sat), c->iq_max_q15);
    out->saturated = T_sat != u;
}

void p2d_speed_q15_update(p2d_speed_q15_t *ctl, const p2d_speed_q15_output_t *out, int16_t T_applied_q15)
{
    const p2d_speed_q15_coef_t *c = &ctl->coef[ctl->active];
    const int32_t dr = (int32_t)out->w_ref_q15 - ctl->r_prev_q15;
    /* u*[k] = u_sat - u with u_sat the torque actually applied */
    const int32_t u_star = p2d_clamp32(T_applied_q15 - out->T_unsat_q15, Q15_SIGNAL_MAX);
    /* Ki Ts e[k] + Ki Ka Ts u*[k], each rounded to the LSB: 0 while |Ki Ts e| < 1/2 LSB (the dead zone) */
    int32_t dx = q15_mul(c->Ki_Ts, out->e_q15) + q15_mul(c->Ki_Ka_Ts, u_star);
    /* clamping holds the integration while the limit is active and e drives further into it */
    if (c->clamping && ((u_star < 0 && out->e_q15 > 0) || (u_star > 0 && out->e_q15 < 0))) dx = 0;
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] + Fr0 dr[k] */
    ctl->x_q15 = p2d_clamp32(ctl->x_q15 + dx + q15_mul(c->ff_Fr0, dr), Q15_SIGNAL_MAX);
    ctl->y_ff_prev_q15 = out->y_ff_q15;
    ctl->r_prev_q15 = out->w_ref_q15;
}

void p2d_speed_q15_step(p2d_speed_q15_t *ctl, int16_t w_ref_q15, int16_t w_m_q15, p2d_speed_q15_output_t *out)
{
    p2d_speed_q15_compute(ctl, w_ref_q15, w_m_q15, out);
    p2d_speed_q15_update(ctl, out, out->T_ref_q15);
}
