/*
 * Speed from an incremental encoder: see pmsm2dof/encoder.h for the equations.
 */
#include "pmsm2dof/encoder.h"

#include <math.h>

#include "pi.h"

#define P2D_TWO_PI 6.28318530717958648f /* 2 pi */

/*
 * The bilinear image p = (2 - x) / (2 + x) of the pole s = -w, x = w Ts in (0, 2]
 * (pole in [0, 1)), written as 1 - p = 2 x / (2 + x), which keeps its relative
 * precision for small x. Returns false if x is out of range or float32 rounds
 * 1 - p to 0 (the pole onto 1).
 */
static bool bilinear_pole(float w_radps, float Ts_s, float *p, float *one_minus_p)
{
    const float x = w_radps * Ts_s;
    if (!p2d_is_positive(w_radps) || !(x > 0.0f && x <= 2.0f)) return false;
    *p = (2.0f - x) / (2.0f + x);
    *one_minus_p = 2.0f * x / (2.0f + x);
    return *p < 1.0f && *one_minus_p > 0.0f;
}

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t encoder_coefficients(const p2d_encoder_config_t *cfg, p2d_encoder_coef_t *c)
{
    p2d_encoder_coef_t k;
    float p, one_minus_p;

    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (cfg->counts_per_rev < 1u) return P2D_ERR_ENC_COUNTS_PER_REV;
    if (cfg->counter_bits < 2u || cfg->counter_bits > 32u) return P2D_ERR_ENC_COUNTER_BITS;
    if ((unsigned)cfg->estimator > (unsigned)P2D_ESTIMATOR_PLL) return P2D_ERR_ENC_ESTIMATOR;

    /* w_res = 2 pi / (counts_per_rev Ts): one count per period */
    k.w_res_radps = P2D_TWO_PI / ((float)cfg->counts_per_rev * cfg->Ts_s);
    k.counts_per_radps = 1.0f / k.w_res_radps;
    if (!p2d_is_positive(k.w_res_radps) || !p2d_is_positive(k.counts_per_radps)) return P2D_ERR_ENC_COUNTS_PER_REV;
    k.counter_mask = cfg->counter_bits == 32u ? 0xffffffffu : (1u << cfg->counter_bits) - 1u;
    k.counter_half = 1u << (cfg->counter_bits - 1u);
    k.estimator = cfg->estimator;

    if (cfg->estimator == P2D_ESTIMATOR_PLL) {
        if (!bilinear_pole(cfg->bandwidth_radps, cfg->Ts_s, &p, &one_minus_p)) return P2D_ERR_ENC_BANDWIDTH;
        /* speed gain w_res (1 - p)^2 and angle residual factor p^2 (encoder.h) */
        k.pll_gain_radps_per_count = k.w_res_radps * (one_minus_p * one_minus_p);
        k.pll_pole2 = p * p;
        if (!p2d_is_positive(k.pll_gain_radps_per_count)) return P2D_ERR_ENC_BANDWIDTH;
    } else {
        k.pll_gain_radps_per_count = 0.0f;
        k.pll_pole2 = 0.0f;
    }

    if (cfg->lowpass_radps == 0.0f) {
        /* no filter: y = 0 y[k-1] + 1 w[k] = w[k] exactly */
        k.lowpass_pole = 0.0f;
        k.lowpass_gain = 1.0f;
    } else if (!bilinear_pole(cfg->lowpass_radps, cfg->Ts_s, &k.lowpass_pole, &k.lowpass_gain)) {
        return P2D_ERR_ENC_LOWPASS;
    }
    *c = k;
    return P2D_OK;
}

p2d_status_t p2d_encoder_init(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg)
{
    p2d_status_t status;
    if (enc == 0 || cfg == 0) return P2D_ERR_NULL;
    status = encoder_coefficients(cfg, &enc->coef[0]);
    if (status != P2D_OK) return status;
    enc->coef[1] = enc->coef[0];
    enc->active = 0u;
    enc->config = *cfg;
    enc->fault_count = 0u;
    p2d_encoder_reset(enc, 0u, 0.0f);
    return P2D_OK;
}

/* The shadow swap of pi.h. */
p2d_status_t p2d_encoder_set_config(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg)
{
    p2d_status_t status;
    uint32_t inactive;
    if (enc == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(enc->active);
    status = encoder_coefficients(cfg, &enc->coef[inactive]);
    if (status != P2D_OK) return status;
    enc->config = *cfg;
    p2d_shadow_activate(&enc->active, inactive);
    return P2D_OK;
}

void p2d_encoder_reset(p2d_encoder_t *enc, uint32_t count, float w_m_radps)
{
    if (!isfinite(w_m_radps)) {
        /* non-finite policy: start from rest instead, count the fault */
        enc->fault_count++;
        w_m_radps = 0.0f;
    }
    enc->count_prev = count;
    enc->theta_err_counts = 0.0f;
    enc->w_pll_radps = w_m_radps;
    enc->w_lowpass_radps = w_m_radps;
}

void p2d_encoder_step(p2d_encoder_t *enc, uint32_t count, p2d_encoder_output_t *out)
{
    const p2d_encoder_coef_t *c = &enc->coef[enc->active];
    uint32_t d;
    int32_t dn;
    float w, e;

    /* dn[k] = (n[k] - n[k-1]) mod 2^bits, read in [-2^(bits-1), 2^(bits-1)) (unsigned arithmetic wraps mod 2^32) */
    d = (count - enc->count_prev) & c->counter_mask;
    dn = d >= c->counter_half ? -(int32_t)(c->counter_mask - d) - 1 : (int32_t)d;
    enc->count_prev = count;

    if (c->estimator == P2D_ESTIMATOR_PLL) {
        /* e[k] = dn[k] - (theta_hat[k-1] - theta[k-1]) - w[k-1] / w_res   [count] */
        e = (float)dn - enc->theta_err_counts - enc->w_pll_radps * c->counts_per_radps;
        /* theta_hat[k] - theta[k] = -p^2 e[k] */
        enc->theta_err_counts = -c->pll_pole2 * e;
        /* w[k] = w[k-1] + w_res (1 - p)^2 e[k] */
        w = fmaf(c->pll_gain_radps_per_count, e, enc->w_pll_radps);
        enc->w_pll_radps = w;
    } else {
        /* w[k] = w_res dn[k] */
        w = c->w_res_radps * (float)dn;
    }
    /* y[k] = q y[k-1] + (1 - q) w[k] */
    enc->w_lowpass_radps = fmaf(c->lowpass_pole, enc->w_lowpass_radps, c->lowpass_gain * w);

    out->dn_counts = dn;
    out->w_raw_radps = w;
    out->w_m_radps = enc->w_lowpass_radps;
}
