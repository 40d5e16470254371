/*
 * Unit tests of the notch and low-pass filters (pmsm2dof/filter.h). The
 * expected responses come from the designs written out by hand in double: the
 * continuous prototypes, their bilinear map with prewarping, and the
 * resulting difference equation in direct form, a realization other than the
 * filter's state-variable one.
 */
#include <float.h>
#include <string.h>

#include "check.h"
#include "filter_design.h"
#include "pmsm2dof/filter.h"

static p2d_filter_config_t no_filter(void)
{
    p2d_filter_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    return cfg;
}

/* A notch at 50 Hz, 20 Hz wide, -20 dB deep, and a Butterworth low-pass at 300 Hz, at 1 kHz. */
static p2d_filter_config_t chain_config(void)
{
    p2d_filter_config_t cfg = no_filter();
    cfg.notch_freq_Hz = 50.0f;
    cfg.notch_width_Hz = 20.0f;
    cfg.notch_depth = 0.1f;
    cfg.lowpass_freq_Hz = 300.0f;
    cfg.lowpass_zeta = 0.70710678f;
    return cfg;
}

static p2d_status_t init_with(p2d_filter_config_t cfg, float Ts_s)
{
    p2d_filter_t f;
    return p2d_filter_init(&f, &cfg, Ts_s);
}

static void test_validation(void)
{
    p2d_filter_config_t cfg;
    p2d_filter_t f, before;
    const float Ts = 1e-3f;

    CHECK(init_with(no_filter(), Ts) == P2D_OK);
    CHECK(init_with(chain_config(), Ts) == P2D_OK);
    CHECK(init_with(chain_config(), 0.0f) == P2D_ERR_TS);
    CHECK(init_with(chain_config(), NAN) == P2D_ERR_TS);
    cfg = chain_config();
    CHECK(p2d_filter_init(0, &cfg, Ts) == P2D_ERR_NULL);
    CHECK(p2d_filter_init(&f, 0, Ts) == P2D_ERR_NULL);

    /* notch: frequency in (0, 1/(2 Ts)), width in (0, 1/(2 Ts)), depth in [0, 1/sqrt(2)) */
    cfg = chain_config();
    cfg.notch_freq_Hz = -1.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_FREQ);
    cfg.notch_freq_Hz = 500.0f; /* Nyquist */
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_FREQ);
    cfg.notch_freq_Hz = INFINITY;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_FREQ);
    cfg.notch_freq_Hz = 490.0f;
    CHECK(init_with(cfg, Ts) == P2D_OK);
    /* within 0.02 % of the Nyquist frequency float32 loses the realized denominator's q^2 coefficient */
    cfg.notch_freq_Hz = 499.9f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_FREQ);
    cfg = chain_config();
    cfg.notch_width_Hz = 0.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_WIDTH);
    cfg.notch_width_Hz = 500.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_WIDTH);
    cfg.notch_width_Hz = NAN;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_WIDTH);
    /* so narrow that the damping g h k is not a normal float32 number */
    cfg.notch_width_Hz = 1e-38f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_WIDTH);
    cfg.notch_width_Hz = 1e-6f; /* 1 uHz wide at 1 kHz: the damping is a product of stored numbers, kept */
    CHECK(init_with(cfg, Ts) == P2D_OK);
    cfg = chain_config();
    cfg.notch_depth = -0.1f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_DEPTH);
    cfg.notch_depth = 0.7072f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_DEPTH);
    cfg.notch_depth = NAN;
    CHECK(init_with(cfg, Ts) == P2D_ERR_NOTCH_DEPTH);
    cfg.notch_depth = 0.0f;
    CHECK(init_with(cfg, Ts) == P2D_OK);
    cfg.notch_depth = 0.707f;
    CHECK(init_with(cfg, Ts) == P2D_OK);

    /* low-pass: frequency in (0, 1/(2 Ts)), zeta > 0 */
    cfg = chain_config();
    cfg.lowpass_freq_Hz = 600.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_LOWPASS_FREQ);
    cfg.lowpass_freq_Hz = -5.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_LOWPASS_FREQ);
    cfg = chain_config();
    cfg.lowpass_zeta = 0.0f;
    CHECK(init_with(cfg, Ts) == P2D_ERR_LOWPASS_ZETA);
    cfg.lowpass_zeta = 1e-40f; /* subnormal: the damping g h k is not a normal number */
    CHECK(init_with(cfg, Ts) == P2D_ERR_LOWPASS_ZETA);
    cfg.lowpass_zeta = 1e-6f;
    CHECK(init_with(cfg, Ts) == P2D_OK);
    cfg.lowpass_zeta = 1e38f; /* 1 + g (g + 2 zeta) overflows */
    CHECK(init_with(cfg, Ts) == P2D_ERR_LOWPASS_ZETA);

    /* a section that is off ignores its other fields */
    cfg = no_filter();
    cfg.notch_width_Hz = NAN;
    cfg.notch_depth = -1.0f;
    cfg.lowpass_zeta = NAN;
    CHECK(init_with(cfg, Ts) == P2D_OK);

    /* a failed init leaves the object untouched */
    memset(&f, 0x5a, sizeof f);
    memcpy(&before, &f, sizeof f);
    cfg = chain_config();
    cfg.notch_depth = 2.0f;
    CHECK(p2d_filter_init(&f, &cfg, Ts) == P2D_ERR_NOTCH_DEPTH);
    CHECK(memcmp(&f, &before, sizeof f) == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_NOTCH_WIDTH), "notch_width_Hz") == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_LOWPASS_ZETA), "lowpass_zeta") == 0);
}

/* g = tan(pi f0 Ts) of the prewarping, within a few float32 roundings, for f0 Ts in (0, 0.49]. */
static void test_prewarping(void)
{
    const float Ts = 1e-4f;
    double worst = 0.0;
    for (int i = 1; i < 2000; ++i) {
        p2d_filter_config_t cfg = no_filter();
        p2d_filter_t f;
        double u, exact;
        cfg.lowpass_freq_Hz = (float)(0.49 * (double)i / 2000.0 / (double)Ts);
        cfg.lowpass_zeta = 1.0f;
        if (p2d_filter_init(&f, &cfg, Ts) != P2D_OK) {
            CHECK(0);
            continue;
        }
        u = (double)(cfg.lowpass_freq_Hz * Ts); /* the product as the filter rounds it */
        exact = tan(PI * u);
        worst = fmax(worst, fabs((double)f.coef[0].lowpass.g - exact) / exact);
    }
    CHECK_CLOSE(worst, 0.0, 4.0 * FLT_EPSILON);
}

/* The designed responses: depth at f0, -3 dB band exactly notch_width_Hz wide, 1/(2 zeta) at the low-pass f0. */
static void test_design_response(void)
{
    const double Ts = 1e-3;
    p2d_filter_config_t cfg = chain_config();
    direct_form_t n = notch_design(&cfg, Ts), l = lowpass_design(&cfg, Ts);
    double w0_Ts = 2.0 * PI * cfg.notch_freq_Hz * Ts, lo = 1e-9, hi = w0_Ts, w1, w2;
    CHECK_CLOSE(gain(&n, w0_Ts), cfg.notch_depth, 1e-7);
    CHECK_CLOSE(gain(&n, 0.0), 1.0, 1e-12);
    CHECK_CLOSE(gain(&n, PI), 1.0, 1e-12);
    CHECK_CLOSE(gain(&l, 2.0 * PI * cfg.lowpass_freq_Hz * Ts), 1.0 / (2.0 * cfg.lowpass_zeta), 1e-7);
    /* the -3 dB points by bisection on either side of the notch */
    for (int i = 0; i < 200; ++i) {
        double mid = 0.5 * (lo + hi);
        if (gain(&n, mid) > sqrt(0.5))
            lo = mid;
        else
            hi = mid;
    }
    w1 = lo;
    lo = w0_Ts;
    hi = PI;
    for (int i = 0; i < 200; ++i) {
        double mid = 0.5 * (lo + hi);
        if (gain(&n, mid) < sqrt(0.5))
            lo = mid;
        else
            hi = mid;
    }
    w2 = lo;
    CHECK_CLOSE((w2 - w1) / (2.0 * PI * Ts), cfg.notch_width_Hz, 1e-6);
}

/* The filter's impulse response against the designed direct forms, cascaded, in double. */
static void test_impulse_response(void)
{
    const float Ts_values[3] = {1e-3f, 1e-4f, 5e-5f};
    for (int t = 0; t < 3; ++t) {
        const float Ts = Ts_values[t];
        p2d_filter_config_t cfg = chain_config();
        p2d_filter_t f;
        direct_form_t n = notch_design(&cfg, Ts), l = lowpass_design(&cfg, Ts);
        direct_state_t sn = {{0.0, 0.0}, {0.0, 0.0}}, sl = {{0.0, 0.0}, {0.0, 0.0}};
        double worst = 0.0;
        CHECK(p2d_filter_init(&f, &cfg, Ts) == P2D_OK);
        for (int k = 0; k < 4000; ++k) {
            p2d_filter_output_t out;
            double x = k == 0 ? 1.0 : 0.0;
            /* notch then low-pass */
            double y = direct_step(&l, &sl, direct_step(&n, &sn, x));
            p2d_filter_step(&f, (float)x, &out);
            CHECK(!out.fault);
            worst = fmax(worst, fabs((double)out.y - y));
        }
        /* the impulse response peaks near 0.3 (1 kHz) .. 0.01 (20 kHz); float32 rounding */
        CHECK_CLOSE(worst, 0.0, 2e-6);
    }
}

/* At a constant input the output equals the input to the bit, at any f0 Ts: the DC gain is exactly 1. */
static void test_exact_dc_gain(void)
{
    const float inputs[4] = {1.0f, -3.7f, 1234.567f, 1e-30f};
    const float Ts = 1e-4f;
    p2d_filter_config_t cfg = no_filter();
    cfg.notch_freq_Hz = 0.05f; /* f0 Ts = 5e-6 */
    cfg.notch_width_Hz = 0.01f;
    cfg.notch_depth = 0.0f;
    cfg.lowpass_freq_Hz = 0.1f;
    cfg.lowpass_zeta = 0.5f;
    for (int i = 0; i < 4; ++i) {
        p2d_filter_t f;
        p2d_filter_state_t rest;
        p2d_filter_output_t out;
        CHECK(p2d_filter_init(&f, &cfg, Ts) == P2D_OK);
        p2d_filter_reset(&f, inputs[i]);
        memcpy(&rest, &f.state, sizeof rest);
        for (int k = 0; k < 100; ++k) {
            p2d_filter_step(&f, inputs[i], &out);
            CHECK(out.y == inputs[i] && !out.fault);
        }
        CHECK(memcmp(&rest, &f.state, sizeof rest) == 0);
    }
}

/* A step input settles at the step: the low-pass and the notch converge to the input. */
static void test_step_settles(void)
{
    p2d_filter_config_t cfg = chain_config();
    p2d_filter_t f;
    p2d_filter_output_t out;
    CHECK(p2d_filter_init(&f, &cfg, 1e-3f) == P2D_OK);
    for (int k = 0; k < 2000; ++k) p2d_filter_step(&f, 2.5f, &out);
    CHECK_CLOSE(out.y, 2.5, 1e-5);
}

static void test_non_finite_policy(void)
{
    p2d_filter_config_t cfg = chain_config();
    p2d_filter_t f, before;
    p2d_filter_output_t out;
    CHECK(p2d_filter_init(&f, &cfg, 1e-3f) == P2D_OK);
    for (int k = 0; k < 10; ++k) p2d_filter_step(&f, (float)k, &out);
    memcpy(&before, &f, sizeof f);
    p2d_filter_step(&f, NAN, &out);
    CHECK(out.fault && out.y == 0.0f && f.fault_count == before.fault_count + 1u);
    before.fault_count++;
    CHECK(memcmp(&f, &before, sizeof f) == 0);
    p2d_filter_step(&f, INFINITY, &out);
    CHECK(out.fault && out.y == 0.0f && f.fault_count == 2u);
    /* an overflow: a resonant low-pass (gain 1/(2 zeta) = 50 at f0) driven near FLT_MAX */
    cfg = no_filter();
    cfg.lowpass_freq_Hz = 100.0f;
    cfg.lowpass_zeta = 0.01f;
    CHECK(p2d_filter_init(&f, &cfg, 1e-3f) == P2D_OK);
    for (int k = 0; k < 200 && f.fault_count == 0u; ++k) {
        p2d_filter_step(&f, k % 10 < 5 ? 3e37f : -3e37f, &out);
    }
    CHECK(f.fault_count == 1u && out.fault && out.y == 0.0f);
    CHECK(isfinite(f.state.lowpass.s1) && isfinite(f.state.lowpass.s2));
    /* the filter recovers on the next good sample */
    p2d_filter_reset(&f, NAN);
    CHECK(f.fault_count == 2u && f.state.lowpass.s2 == 0.0f);
    p2d_filter_step(&f, 1.0f, &out);
    CHECK(!out.fault && isfinite(out.y));
}

static void test_set_config(void)
{
    p2d_filter_config_t cfg = no_filter(), bad;
    p2d_filter_t f, before;
    p2d_filter_output_t out;
    CHECK(p2d_filter_init(&f, &cfg, 1e-3f) == P2D_OK);
    for (int k = 0; k < 20; ++k) p2d_filter_step(&f, 4.0f, &out);
    CHECK(out.y == 4.0f);
    /* switched on at a constant input: the sections start at rest at the last input, nothing jumps */
    cfg = chain_config();
    CHECK(p2d_filter_set_config(&f, &cfg) == P2D_OK);
    CHECK(f.active == 1u);
    p2d_filter_step(&f, 4.0f, &out);
    CHECK(out.y == 4.0f);
    /* new coefficients keep the state: at rest, the output stays */
    cfg.notch_freq_Hz = 80.0f;
    cfg.lowpass_zeta = 0.5f;
    CHECK(p2d_filter_set_config(&f, &cfg) == P2D_OK);
    p2d_filter_step(&f, 4.0f, &out);
    CHECK(out.y == 4.0f);
    /* a rejected update changes nothing */
    bad = cfg;
    bad.lowpass_freq_Hz = 501.0f;
    memcpy(&before, &f, sizeof f);
    CHECK(p2d_filter_set_config(&f, &bad) == P2D_ERR_LOWPASS_FREQ);
    CHECK(memcmp(&f, &before, sizeof f) == 0);
    CHECK(p2d_filter_set_config(&f, 0) == P2D_ERR_NULL);
}

int main(void)
{
    test_validation();
    test_prewarping();
    test_design_response();
    test_impulse_response();
    test_exact_dc_gain();
    test_step_settles();
    test_non_finite_policy();
    test_set_config();
    return check_summary();
}
