/*
 * Speed from an incremental encoder: see pmsm2dof/encoder.h for the equations.
 */
#include "pmsm2dof/encoder.h"

#include <math.h>

#include "pi.h"

#define P2D_TWO_PI 6.28318530717958648f /* 2 pi */

/*
 * The bilinear image p = (2 - x) / (2 + x) of the pole s = -w, x = w Ts in
 * [1e-3, 2] (pole in [0, 1)), and 1 - p, rounded so that p + (1 - p) = 1
 * exactly: 1 - p and 1 - (1 - p) are exact by Sterbenz's lemma where they
 * are >= 1/2, and the second subtraction makes the pair consistent where the
 * first rounded. Returns false if x is out of range.
 */
static bool bilinear_pole(float w_radps, float Ts_s, float *pole, float *one_minus_pole)
{
    const float x = w_radps * Ts_s;
    if (!p2d_is_positive(w_radps) || !(x >= 1e-3f && x <= 2.0f)) return false;
    *one_minus_pole = 1.0f - (2.0f - x) / (2.0f + x);
    *pole = 1.0f - *one_minus_pole;
    return true;
}

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t encoder_coefficients(const p2d_encoder_config_t *cfg, p2d_encoder_coef_t *c)
{
    p2d_encoder_coef_t k;

    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (cfg->counts_per_rev < 1u) return P2D_ERR_ENC_COUNTS_PER_REV;
    if (cfg->counter_bits < 2u || cfg->counter_bits > 32u) return P2D_ERR_ENC_COUNTER_BITS;
    if ((unsigned)cfg->estimator > (unsigned)P2D_ESTIMATOR_PLL) return P2D_ERR_ENC_ESTIMATOR;

    /* w_res = 2 pi / (counts_per_rev Ts): one count per period */
    k.w_res_radps = P2D_TWO_PI / ((float)cfg->counts_per_rev * cfg->Ts_s);
    k.counts_per_radps = 1.0f / k.w_res_radps;
    k.counter_mask = cfg->counter_bits == 32u ? 0xffffffffu : (1u << cfg->counter_bits) - 1u;
    k.counter_half = 1u << (cfg->counter_bits - 1u);
    /* the largest measurable speed w_res 2^(bits-1) must be finite too */
    if (!p2d_is_positive(k.w_res_radps) || !p2d_is_positive(k.counts_per_radps) ||
        !isfinite(k.w_res_radps * (float)k.counter_half)) {
        return P2D_ERR_ENC_COUNTS_PER_REV;
    }
    k.estimator = cfg->estimator;

    if (cfg->estimator == P2D_ESTIMATOR_PLL) {
        if (!bilinear_pole(cfg->bandwidth_radps, cfg->Ts_s, &k.pll_pole, &k.pll_one_minus_pole))
            return P2D_ERR_ENC_BANDWIDTH;
    } else {
        k.pll_pole = 0.0f;
        k.pll_one_minus_pole = 1.0f;
    }

    if (cfg->lowpass_radps == 0.0f) {
        /* no filter: y = 0 y[k-1] + 1 w[k] = w[k] exactly */
        k.lowpass_pole = 0.0f;
        k.lowpass_one_minus_pole = 1.0f;
    } else if (!bilinear_pole(cfg->lowpass_radps, cfg->Ts_s, &k.lowpass_pole, &k.lowpass_one_minus_pole)) {
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
    /* v = w / w_res [count per period] */
    float v = w_m_radps * enc->coef[enc->active].counts_per_radps;
    if (!(fabsf(v) <= (float)enc->coef[enc->active].counter_half)) {
        /* non-finite policy (NaN, inf, or beyond the measurable range): start from rest, count the fault */
        enc->fault_count++;
        w_m_radps = 0.0f;
        v = 0.0f;
    }
    enc->count_prev = count;
    enc->theta_err_counts = 0.0f;
    enc->v_pll_counts = v;
    enc->w_lowpass_radps = w_m_radps;
}

void p2d_encoder_step(p2d_encoder_t *enc, uint32_t count, p2d_encoder_output_t *out)
{
    const p2d_encoder_coef_t *c = &enc->coef[enc->active];
    uint32_t d;
    int32_t dn;
    float e, r, v, w, y;

    /* dn[k] = (n[k] - n[k-1]) mod 2^bits, read in [-2^(bits-1), 2^(bits-1)) (unsigned arithmetic wraps mod 2^32) */
    d = (count - enc->count_prev) & c->counter_mask;
    dn = d >= c->counter_half ? -(int32_t)(c->counter_mask - d) - 1 : (int32_t)d;
    enc->count_prev = count;

    if (c->estimator == P2D_ESTIMATOR_PLL) {
        /* e[k] = dn[k] - (theta_hat[k-1] - theta[k-1]) - v[k-1]   [count] */
        e = (float)dn - enc->theta_err_counts - enc->v_pll_counts;
        /* theta_hat[k] - theta[k] = -p^2 e[k] */
        r = -(c->pll_pole * (c->pll_pole * e));
        /* v[k] = v[k-1] + (1 - p)^2 e[k] */
        v = fmaf(c->pll_one_minus_pole, c->pll_one_minus_pole * e, enc->v_pll_counts);
        /* w[k] = w_res v[k] */
        w = c->w_res_radps * v;
    } else {
        r = enc->theta_err_counts;
        v = enc->v_pll_counts;
        /* w[k] = w_res dn[k] */
        w = c->w_res_radps * (float)dn;
    }
    /* y[k] = q y[k-1] + (1 - q) w[k] */
    y = fmaf(c->lowpass_pole, enc->w_lowpass_radps, c->lowpass_one_minus_pole * w);

    out->dn_counts = dn;
    /* y is finite only if w, v, e and r are (1 - q, 1 - p > 0) */
    if (!(fabsf(y) < INFINITY)) {
        /* non-finite policy: hold the last measured speed, keep the state, count the fault */
        out->w_raw_radps = enc->w_lowpass_radps;
        out->w_m_radps = enc->w_lowpass_radps;
        out->fault = true;
        enc->fault_count++;
        return;
    }
    enc->theta_err_counts = r;
    enc->v_pll_counts = v;
    enc->w_lowpass_radps = y;
    out->w_raw_radps = w;
    out->w_m_radps = y;
    out->fault = false;
}
