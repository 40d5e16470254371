/*
 * The Q31 speed controller: int32 inputs and outputs, int64 arithmetic, an
 * integrator with 31 more fractional bits (x_q62), so that one LSB of speed
 * error moves it. The contract and the arithmetic rules are in
 * pmsm2dof/speed_fixed.h.
 */
#include "fixed.h"
#include "pi.h"

/* Fractional bits of the format */
#define Q31_BITS 31u
/* Two full scales less one LSB: the bound of every signal, 2^32 - 1 */
#define Q31_SIGNAL_MAX INT64_C(4294967295)
/* Fractional bits of the integrator beyond the torque's: x_q62 = x_q31 2^31 */
#define Q31_X_EXTRA_BITS 31u

/* The gain g as a Q31 gain. */
static p2d_q31_gain_t q31_gain(double g)
{
    p2d_q31_gain_t q;
    p2d_fixed_gain(g, Q31_BITS, &q.mantissa, &q.shift);
    return q;
}

/* m v: |v| <= 2^32 - 1 and |m| <= 2^31 - 1, so it fits an int64 */
static inline int64_t q31_product(p2d_q31_gain_t g, int64_t v) { return (int64_t)g.mantissa * v; }

/* R(g v) in the LSB of the result */
static inline int64_t q31_mul(p2d_q31_gain_t g, int64_t v) { return p2d_round_shift64(q31_product(g, v), g.shift); }

/* R(g v) in the LSB of the integrator (2^-31 of the result's), limited to the int64 range */
static inline int64_t q31_mul_x(p2d_q31_gain_t g, int64_t v)
{
    const int64_t p = q31_product(g, v);
    return g.shift > Q31_X_EXTRA_BITS ? p2d_round_shift64(p, g.shift - Q31_X_EXTRA_BITS)
                                      : p2d_scale_sat64(p, Q31_X_EXTRA_BITS - g.shift);
}

/* Validate cfg and compute its coefficients into *c (written only on success). */
static p2d_status_t q31_coefficients(const p2d_speed_fixed_config_t *cfg, const p2d_speed_fixed_config_t *active,
                                     p2d_speed_q31_coef_t *c)
{
    p2d_speed_fixed_gains_t g;
    int32_t T_max, iq_max;
    p2d_status_t status = p2d_speed_fixed_prepare(cfg, Q31_BITS, active, &g, &T_max, &iq_max);
    if (status != P2D_OK) return status;
    c->b_e0 = q31_gain(g.b_e0);
    c->Ki_Ts = q31_gain(g.Ki_Ts);
    c->Ki_Ka_Ts = q31_gain(g.Ki_Ka_Ts);
    c->ff_Fr0 = q31_gain(g.ff_Fr0);
    c->ff_b_dr = q31_gain(g.ff_b_dr);
    c->ff_one_plus_a1 = q31_gain(g.ff_one_plus_a1);
    c->ff_Kd_per_Ts = q31_gain(g.ff_Kd_per_Ts);
    c->iq_per_T = q31_gain(g.iq_per_T);
    c->T_max_q31 = T_max;
    c->iq_max_q31 = iq_max;
    c->clamping = cfg->speed.anti_windup == P2D_AW_CLAMPING;
    return P2D_OK;
}

p2d_status_t p2d_speed_q31_init(p2d_speed_q31_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    status = q31_coefficients(cfg, 0, &ctl->coef[0]);
    if (status != P2D_OK) return status;
    /* the shadow set equal to the active one, computed again rather than copied (a copy would call memcpy) */
    (void)q31_coefficients(cfg, 0, &ctl->coef[1]);
    ctl->active = 0u;
    ctl->config = *cfg;
    p2d_speed_q31_reset(ctl, 0, 0);
    return P2D_OK;
}

p2d_status_t p2d_speed_q31_set_config(p2d_speed_q31_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    uint32_t inactive;
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(ctl->active);
    status = q31_coefficients(cfg, &ctl->config, &ctl->coef[inactive]);
    if (status != P2D_OK) return status;
    ctl->config = *cfg;
    p2d_shadow_activate(&ctl->active, inactive);
    return P2D_OK;
}

void p2d_speed_q31_reset(p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t T_init_q31)
{
    /* steady state at r[k] = r[k-1] = w_ref: y = 0, and u = x at e = 0 */
    ctl->x_q62 = (int64_t)T_init_q31 * ((int64_t)1 << Q31_X_EXTRA_BITS);
    ctl->y_ff_prev_q31 = 0;
    ctl->r_prev_q31 = w_ref_q31;
}

void p2d_speed_q31_compute(const p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t w_m_q31, p2d_speed_q31_output_t *out)
{
    const p2d_speed_q31_coef_t *c = &ctl->coef[ctl->active];
    /* e[k] = w_ref[k] - w_m[k], dr[k] = w_ref[k] - r[k-1]: |.| <= 2^32 - 1 */
    const int64_t e = (int64_t)w_ref_q31 - w_m_q31;
    const int64_t dr = (int64_t)w_ref_q31 - ctl->r_prev_q31;
    /* Kd dr[k] / Ts, the derivative of FULL (0 otherwise) */
    const int64_t T_d = q31_mul(c->ff_Kd_per_Ts, dr);
    /* x[k-1] in the LSB of the torque */
    const int64_t x = p2d_round_shift64(ctl->x_q62, Q31_X_EXTRA_BITS);
    int64_t y, u, T_sat;

    /* y[k] = b_dr dr[k] - a1 y[k-1] = b_dr dr[k] + y[k-1] - (1 + a1) y[k-1] */
    y = p2d_clamp64(q31_mul(c->ff_b_dr, dr) + ctl->y_ff_prev_q31 - q31_mul(c->ff_one_plus_a1, ctl->y_ff_prev_q31),
                    Q31_SIGNAL_MAX);
    /* u[k] = b_e0 e[k] + x[k-1] + Fr0 dr[k] + Kd dr[k] / Ts + y[k]: each term < 2^45 + 1 */
    u = p2d_clamp64(q31_mul(c->b_e0, e) + x + q31_mul(c->ff_Fr0, dr) + T_d + y, Q31_SIGNAL_MAX);
    /* u_sat = Sat(u): the current-vector limit |iq| <= i_max as the torque limit T_max */
    T_sat = p2d_clamp64(u, c->T_max_q31);

    out->w_ref_q31 = w_ref_q31;
    out->e_q31 = e;
    /* T_ff[k] = Fr0 r[k] + Kd dr[k] / Ts + y[k] */
    out->T_ff_q31 = p2d_clamp64(q31_mul(c->ff_Fr0, w_ref_q31) + T_d + y, Q31_SIGNAL_MAX);
    out->y_ff_q31 = y;
    out->T_unsat_q31 = u;
    out->T_ref_q31 = (int32_t)T_sat;
    /* iq = u_sat / kt, within the current limit after rounding; id = 0 */
    out->iq_ref_q31 = (int32_t)p2d_clamp64(q31_mul(c->iq_per_T, T_sat), c->iq_max_q31);
    out->saturated = T_sat != u;
}

void p2d_speed_q31_update(p2d_speed_q31_t *ctl, const p2d_speed_q31_output_t *out, int32_t T_applied_q31)
{
    const p2d_speed_q31_coef_t *c = &ctl->coef[ctl->active];
    const int64_t dr = (int64_t)out->w_ref_q31 - ctl->r_prev_q31;
    /* u*[k] = u_sat - u with u_sat the torque actually applied */
    const int64_t u_star = p2d_clamp64(T_applied_q31 - out->T_unsat_q31, Q31_SIGNAL_MAX);
    /* Ki Ts e[k] + Ki Ka Ts u*[k] in the integrator's LSB, 2^-31 of the torque's */
    int64_t dx = p2d_add_sat64(q31_mul_x(c->Ki_Ts, out->e_q31), q31_mul_x(c->Ki_Ka_Ts, u_star));
    /* clamping holds the integration while the limit is active and e drives further into it */
    if (c->clamping && ((u_star < 0 && out->e_q31 > 0) || (u_star > 0 && out->e_q31 < 0))) dx = 0;
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] + Fr0 dr[k] */
    ctl->x_q62 = p2d_add_sat64(p2d_add_sat64(ctl->x_q62, dx), q31_mul_x(c->ff_Fr0, dr));
    ctl->y_ff_prev_q31 = out->y_ff_q31;
    ctl->r_prev_q31 = out->w_ref_q31;
}

void p2d_speed_q31_step(p2d_speed_q31_t *ctl, int32_t w_ref_q31, int32_t w_m_q31, p2d_speed_q31_output_t *out)
{
    p2d_speed_q31_compute(ctl, w_ref_q31, w_m_q31, out);
    p2d_speed_q31_update(ctl, out, out->T_ref_q31);
}
