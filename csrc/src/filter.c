/*
 * Second-order notch and low-pass filters: the contract and the equations are
 * in pmsm2dof/filter.h, the building blocks shared with the speed controller
 * in biquad.h.
 */
#include "pmsm2dof/filter.h"

#include <math.h>

#include "biquad.h"
#include "pi.h"

/*
 * tan(pi u) for 0 < u < 1/2, from +, *, / and fmaf only, so that every
 * IEEE-754 target computes the same bits (the libm tanf, sinf and cosf of the
 * host and of the MCU may differ in the last bit; the filter's coefficients
 * and so the simulated torque command must not). With t = u, or t = 1/2 - u
 * (exact) and tan(pi u) = 1 / tan(pi t) for u > 1/4, the Taylor series of
 * sin(pi t) and cos(pi t) on 0 < t <= 1/4 (pi t <= pi/4), truncated where the
 * first omitted term is below 1e-11; the quotient is within a few float32
 * roundings of tan(pi u).
 */
static float tan_pi(float u)
{
    /* (-1)^n pi^(2n+1) / (2n+1)! and (-1)^n pi^(2n) / (2n)! */
    static const float S[6] = {3.14159265f, -5.16771278f, 2.55016404f, -0.599264529f, 0.0821458866f, -0.00737043095f};
    static const float C[7] = {1.0f,         -4.93480220f,   4.05871213f,   -1.33526277f,
                               0.235330630f, -0.0258068914f, 0.00192957431f};
    const bool reflect = u > 0.25f;
    const float t = reflect ? 0.5f - u : u;
    const float t2 = t * t;
    float sin_pi_t = S[5], cos_pi_t = C[6];
    for (int n = 4; n >= 0; --n) sin_pi_t = fmaf(sin_pi_t, t2, S[n]);
    sin_pi_t *= t;
    for (int n = 5; n >= 0; --n) cos_pi_t = fmaf(cos_pi_t, t2, C[n]);
    return reflect ? cos_pi_t / sin_pi_t : sin_pi_t / cos_pi_t;
}

/* 0 < x * Ts_s < 1/2: a frequency [Hz] strictly between 0 and the Nyquist frequency; its x Ts into *u. */
static bool below_nyquist(float f_Hz, float Ts_s, float *u)
{
    *u = f_Hz * Ts_s;
    return p2d_is_positive(f_Hz) && *u > 0.0f && *u < 0.5f;
}

/*
 * The section's coefficients are finite, its frequency (g g h) and damping (g h k) normal
 * float32 numbers, and 1 + g (g + k) = 1/h at most 4001: the realized q^2 coefficient
 * 1 - g h (g + k) then differs from h by at most (1/h - 1) 4 * 2^-24 h < 1e-3 h (four
 * roundings: g^2 or g + k, the sum 1/h, the quotient g h, and the notch's k = B_v / g;
 * filter.h). The status names the
 * field to blame: `freq` for a frequency too low (g^2 not normal, or the notch's
 * k = B_v / g overflowing) or too near the Nyquist frequency (g dominates k while h -> 0),
 * `damping` for a damping too small (g h k not normal) or too large.
 */
static p2d_status_t section_check(const p2d_biquad_coef_t *s, float one_over_h, p2d_status_t freq, p2d_status_t damping)
{
    if (!isnormal(s->g * s->g) || !isfinite(s->k) || !isfinite(s->c_band)) return freq;
    if (!isnormal(s->g * s->g_h) || !isnormal(s->g_h * s->k)) return damping;
    if (!(one_over_h <= 4001.0f)) return s->g >= s->k ? freq : damping;
    return P2D_OK;
}

/*
 * Notch: g = tan(pi f0 Ts), B_v = (1 + g^2) tan(pi W Ts) / sqrt(1 - 2 d^2),
 * k = B_v / g, h = 1 / (1 + g^2 + B_v), c_band = -(1 - d) k (filter.h).
 */
static p2d_status_t notch_coefficients(const p2d_filter_config_t *cfg, float Ts_s, p2d_biquad_coef_t *s)
{
    float u, u_w, d = cfg->notch_depth, g, one_g2, B_v;
    if (!below_nyquist(cfg->notch_freq_Hz, Ts_s, &u)) return P2D_ERR_NOTCH_FREQ;
    if (!below_nyquist(cfg->notch_width_Hz, Ts_s, &u_w)) return P2D_ERR_NOTCH_WIDTH;
    if (!(d >= 0.0f && 2.0f * d * d < 1.0f)) return P2D_ERR_NOTCH_DEPTH;
    g = tan_pi(u);
    one_g2 = fmaf(g, g, 1.0f);
    B_v = one_g2 * tan_pi(u_w) / sqrtf(fmaf(-2.0f * d, d, 1.0f));
    s->g = g;
    s->k = B_v / g;
    s->g_h = g / (one_g2 + B_v);
    s->c_band = -(1.0f - d) * s->k;
    return section_check(s, one_g2 + B_v, P2D_ERR_NOTCH_FREQ, P2D_ERR_NOTCH_WIDTH);
}

/* Low-pass: g = tan(pi f0 Ts), k = 2 zeta, h = 1 / (1 + g (g + k)), c_band = 0 (filter.h). */
static p2d_status_t lowpass_coefficients(const p2d_filter_config_t *cfg, float Ts_s, p2d_biquad_coef_t *s)
{
    float u, g, one_g_gk;
    if (!below_nyquist(cfg->lowpass_freq_Hz, Ts_s, &u)) return P2D_ERR_LOWPASS_FREQ;
    if (!p2d_is_positive(cfg->lowpass_zeta) || !isfinite(2.0f * cfg->lowpass_zeta)) return P2D_ERR_LOWPASS_ZETA;
    g = tan_pi(u);
    s->g = g;
    s->k = 2.0f * cfg->lowpass_zeta;
    one_g_gk = fmaf(g, g + s->k, 1.0f);
    s->g_h = g / one_g_gk;
    s->c_band = 0.0f;
    return section_check(s, one_g_gk, P2D_ERR_LOWPASS_FREQ, P2D_ERR_LOWPASS_ZETA);
}

/* The coefficients of a section that is off. */
static const p2d_biquad_coef_t P2D_BIQUAD_OFF = {0.0f, 0.0f, 0.0f, 0.0f};

p2d_status_t p2d_filter_coefficients(const p2d_filter_config_t *cfg, float Ts_s, p2d_filter_coef_t *c)
{
    p2d_filter_coef_t k;
    p2d_status_t status;
    /* a frequency of exactly 0 switches the section off (its coefficients 0, unused); its other fields are not read */
    k.has_notch = cfg->notch_freq_Hz != 0.0f;
    k.has_lowpass = cfg->lowpass_freq_Hz != 0.0f;
    k.notch = P2D_BIQUAD_OFF;
    k.lowpass = P2D_BIQUAD_OFF;
    if (k.has_notch) {
        status = notch_coefficients(cfg, Ts_s, &k.notch);
        if (status != P2D_OK) return status;
    }
    if (k.has_lowpass) {
        status = lowpass_coefficients(cfg, Ts_s, &k.lowpass);
        if (status != P2D_OK) return status;
    }
    *c = k;
    return P2D_OK;
}

/*
 * The section's denominator a and numerator b in q = (z - 1)/(z + 1), as
 * realized by the rounded coefficients (coefficient i of q^i; both are scaled
 * by the same factor, b(0) = a(0): unit DC gain):
 *   a = g g h + g h k q + (1 - g h (g + k)) q^2
 *   notch    b = a + c_band g h q       low-pass  b = g g h
 */
static void section_polynomials(const p2d_biquad_coef_t *s, bool notch, float a[3], float b[3])
{
    a[0] = s->g * s->g_h;
    a[1] = s->g_h * s->k;
    a[2] = fmaf(-s->g_h, s->k, fmaf(-s->g_h, s->g, 1.0f));
    b[0] = a[0];
    b[1] = notch ? s->g_h * (s->k + s->c_band) : 0.0f;
    b[2] = notch ? a[2] : 0.0f;
}

/* p = p f in place, p of degree *n (<= 2), f of degree 2; *n += 2. */
static void polynomial_times(float p[5], int *n, const float f[3])
{
    /* from the top down, p[i] = sum_j p[i - j] f[j] reads only coefficients not yet overwritten */
    for (int i = *n + 2; i >= 0; --i) {
        float sum = 0.0f;
        for (int j = 0; j < 3; ++j) {
            if (i - j >= 0 && i - j <= *n) sum = fmaf(p[i - j], f[j], sum);
        }
        p[i] = sum;
    }
    *n += 2;
}

/*
 * Every root of q[0] + q[1] s + ... + q[n] s^n (n <= 5) has a negative real
 * part: the first column of Routh's array is positive (Routh-Hurwitz).
 */
static bool hurwitz(const float *q, int n)
{
    float upper[3] = {0.0f, 0.0f, 0.0f}, lower[3] = {0.0f, 0.0f, 0.0f};
    for (int j = 0; 2 * j <= n; ++j) upper[j] = q[n - 2 * j];
    for (int j = 0; 2 * j + 1 <= n; ++j) lower[j] = q[n - 2 * j - 1];
    if (!(upper[0] > 0.0f)) return false;
    for (int row = 1; row <= n; ++row) {
        float next[3];
        if (!(lower[0] > 0.0f)) return false;
        /* r[j] = upper[j + 1] - upper[0] lower[j + 1] / lower[0] */
        for (int j = 0; j < 2; ++j) next[j] = upper[j + 1] - upper[0] * lower[j + 1] / lower[0];
        next[2] = 0.0f;
        for (int j = 0; j < 3; ++j) {
            upper[j] = lower[j];
            lower[j] = next[j];
        }
    }
    return true;
}

/*
 * With q = (z - 1)/(z + 1) (z + 1 = 2 / (1 - q)) and H = b(q) / a(q),
 *   z - 1 + g H(z) = 2 / (a(q) (1 - q)) * Q(q),   Q = q a(q) + (g/2) (1 - q) b(q),
 * and |z| < 1 exactly where Re q < 0: the loop is stable iff Q is Hurwitz
 * (of full degree, else a root is at z = -1). The coefficients of a and b are
 * small positive numbers of full relative precision at any f0 Ts, where those
 * of the same polynomial in z cluster near the binomial ones of (z - 1)^n.
 */
bool p2d_filter_loop_stable(const p2d_filter_coef_t *c, float g)
{
    float a[5] = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f}, b[5] = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f}, Q[6];
    float sa[3], sb[3];
    int n = 0, nb = 0;
    if (c->has_notch) {
        section_polynomials(&c->notch, true, sa, sb);
        polynomial_times(a, &n, sa);
        polynomial_times(b, &nb, sb);
    }
    if (c->has_lowpass) {
        section_polynomials(&c->lowpass, false, sa, sb);
        polynomial_times(a, &n, sa);
        polynomial_times(b, &nb, sb);
    }
    /* Q[i] = a[i-1] + (g/2) (b[i] - b[i-1]), i = 0 .. n + 1 */
    for (int i = 0; i <= n + 1; ++i) {
        float a_prev = i > 0 ? a[i - 1] : 0.0f, b_prev = i > 0 ? b[i - 1] : 0.0f, b_i = i <= n ? b[i] : 0.0f;
        Q[i] = fmaf(0.5f * g, b_i - b_prev, a_prev);
    }
    return hurwitz(Q, n + 1);
}

void p2d_filter_switch_on(const p2d_filter_coef_t *from, const p2d_filter_coef_t *to, p2d_filter_state_t *s,
                          float level)
{
    if (to->has_notch && !from->has_notch) {
        s->notch.s1 = 0.0f;
        s->notch.s2 = level;
    }
    if (to->has_lowpass && !from->has_lowpass) {
        s->lowpass.s1 = 0.0f;
        s->lowpass.s2 = level;
    }
}

p2d_status_t p2d_filter_init(p2d_filter_t *f, const p2d_filter_config_t *cfg, float Ts_s)
{
    p2d_status_t status;
    if (f == 0 || cfg == 0) return P2D_ERR_NULL;
    if (!p2d_is_positive(Ts_s)) return P2D_ERR_TS;
    status = p2d_filter_coefficients(cfg, Ts_s, &f->coef[0]);
    if (status != P2D_OK) return status;
    f->coef[1] = f->coef[0];
    f->active = 0u;
    f->config = *cfg;
    f->Ts_s = Ts_s;
    f->fault_count = 0u;
    p2d_filter_rest(&f->state, 0.0f);
    f->x_prev = 0.0f;
    return P2D_OK;
}

/* The shadow swap of pi.h; sections switched on start at rest at the last input. */
p2d_status_t p2d_filter_set_config(p2d_filter_t *f, const p2d_filter_config_t *cfg)
{
    p2d_status_t status;
    uint32_t inactive;
    if (f == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(f->active);
    status = p2d_filter_coefficients(cfg, f->Ts_s, &f->coef[inactive]);
    if (status != P2D_OK) return status;
    p2d_filter_switch_on(&f->coef[f->active], &f->coef[inactive], &f->state, f->x_prev);
    f->config = *cfg;
    p2d_shadow_activate(&f->active, inactive);
    return P2D_OK;
}

void p2d_filter_reset(p2d_filter_t *f, float x)
{
    if (!isfinite(x)) {
        /* non-finite policy: rest at 0 instead, count the fault */
        f->fault_count++;
        x = 0.0f;
    }
    p2d_filter_rest(&f->state, x);
    f->x_prev = x;
}

void p2d_filter_step(p2d_filter_t *f, float x, p2d_filter_output_t *out)
{
    const p2d_filter_coef_t *c = &f->coef[f->active];
    p2d_filter_state_t next;
    const float y = p2d_filter_output(c, &f->state, x, &next);
    if (!isfinite(y) || !p2d_filter_state_finite(c, &next)) {
        /* non-finite policy: a NaN or inf input, or an overflow, reaches neither the output nor the state */
        out->y = 0.0f;
        out->fault = true;
        f->fault_count++;
        return;
    }
    p2d_filter_store(c, &f->state, &next);
    f->x_prev = x;
    out->y = y;
    out->fault = false;
}
