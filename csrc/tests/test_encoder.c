/*
 * Unit tests of the encoder speed estimators (pmsm2dof/encoder.h). Expected
 * values come from the angle trajectory itself (counts = floor of the angle
 * in counts, the wrap of a hardware counter), and from the designed discrete
 * transfer function of the PLL and of the low-pass, run as difference
 * equations in double.
 */
#include <stdint.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/encoder.h"

#define TWO_PI 6.283185307179586

/* 2500-line quadrature encoder (10000 counts/rev), 16-bit timer, speed loop at 1 kHz. */
static p2d_encoder_config_t encoder_config(p2d_estimator_t estimator)
{
    p2d_encoder_config_t cfg;
    cfg.counts_per_rev = 10000u;
    cfg.counter_bits = 16u;
    cfg.Ts_s = 1e-3f;
    cfg.estimator = estimator;
    cfg.bandwidth_radps = 200.0f;
    cfg.lowpass_radps = 0.0f;
    return cfg;
}

static p2d_status_t init_with(p2d_encoder_config_t cfg)
{
    p2d_encoder_t enc;
    return p2d_encoder_init(&enc, &cfg);
}

/* The counted angle floor(theta cpr / 2 pi) [count] of a hardware counter, unwrapped. */
static int64_t counted(double theta_rad, uint32_t cpr) { return (int64_t)floor(theta_rad * cpr / TWO_PI); }

/* The reading of a counter of `bits` bits that started at `offset` (the unwrapped count mod 2^bits). */
static uint32_t reading(int64_t count, uint32_t offset, uint32_t bits)
{
    uint64_t modulus = (uint64_t)1 << bits;
    int64_t r = ((int64_t)offset + count) % (int64_t)modulus;
    return (uint32_t)(r < 0 ? r + (int64_t)modulus : r);
}

static void test_validation(void)
{
    p2d_encoder_config_t cfg;
    p2d_encoder_t enc, before;

    CHECK(init_with(encoder_config(P2D_ESTIMATOR_DIFFERENCE)) == P2D_OK);
    CHECK(init_with(encoder_config(P2D_ESTIMATOR_PLL)) == P2D_OK);
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.counts_per_rev = 0u;
    CHECK(init_with(cfg) == P2D_ERR_ENC_COUNTS_PER_REV);
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.counter_bits = 1u;
    CHECK(init_with(cfg) == P2D_ERR_ENC_COUNTER_BITS);
    cfg.counter_bits = 33u;
    CHECK(init_with(cfg) == P2D_ERR_ENC_COUNTER_BITS);
    cfg.counter_bits = 32u;
    CHECK(init_with(cfg) == P2D_OK);
    cfg.counter_bits = 2u;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.Ts_s = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg.Ts_s = NAN;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.estimator = (p2d_estimator_t)2;
    CHECK(init_with(cfg) == P2D_ERR_ENC_ESTIMATOR);
    /* bandwidth: 1e-3 <= w Ts <= 2 */
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.bandwidth_radps = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_ENC_BANDWIDTH);
    cfg.bandwidth_radps = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_ENC_BANDWIDTH);
    cfg.bandwidth_radps = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_ENC_BANDWIDTH);
    cfg.bandwidth_radps = 2000.0f; /* w Ts = 2: both poles at 0 */
    CHECK(init_with(cfg) == P2D_OK);
    cfg.bandwidth_radps = 2001.0f;
    CHECK(init_with(cfg) == P2D_ERR_ENC_BANDWIDTH);
    cfg.bandwidth_radps = 1.0f; /* w Ts = 1e-3: the smallest */
    CHECK(init_with(cfg) == P2D_OK);
    cfg.bandwidth_radps = 0.99f; /* below: the increments of the state would fall under its float32 resolution */
    CHECK(init_with(cfg) == P2D_ERR_ENC_BANDWIDTH);
    /* the bandwidth is not checked for the difference estimator */
    cfg.estimator = P2D_ESTIMATOR_DIFFERENCE;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = encoder_config(P2D_ESTIMATOR_DIFFERENCE);
    cfg.lowpass_radps = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_ENC_LOWPASS);
    cfg.lowpass_radps = NAN;
    CHECK(init_with(cfg) == P2D_ERR_ENC_LOWPASS);
    cfg.lowpass_radps = 2500.0f;
    CHECK(init_with(cfg) == P2D_ERR_ENC_LOWPASS);
    cfg.lowpass_radps = 500.0f;
    CHECK(init_with(cfg) == P2D_OK);
    /* a resolution that overflows float32 */
    cfg = encoder_config(P2D_ESTIMATOR_DIFFERENCE);
    cfg.Ts_s = 1e-44f;
    cfg.counts_per_rev = 1u;
    CHECK(init_with(cfg) == P2D_ERR_ENC_COUNTS_PER_REV);
    CHECK(p2d_encoder_init(NULL, &cfg) == P2D_ERR_NULL);

    /* a rejected init writes nothing; every code names a parameter and a range */
    memset(&enc, 0x5a, sizeof enc);
    memcpy(&before, &enc, sizeof enc);
    cfg = encoder_config(P2D_ESTIMATOR_PLL);
    cfg.counter_bits = 0u;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_ERR_ENC_COUNTER_BITS);
    CHECK(memcmp(&enc, &before, sizeof enc) == 0);
    for (int s = P2D_ERR_ENC_COUNTS_PER_REV; s <= P2D_ERR_ENC_LOWPASS; ++s) {
        CHECK(strlen(p2d_status_param((p2d_status_t)s)) > 0 && strlen(p2d_status_range((p2d_status_t)s)) > 0);
    }
    CHECK(strcmp(p2d_status_param(P2D_ERR_ENC_BANDWIDTH), "bandwidth_radps") == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_ENC_COUNTS_PER_REV), "counts_per_rev") == 0);
}

/*
 * Difference estimator on an angle trajectory that accelerates, reverses and
 * wraps the counter: dn is the hand count floor(theta[k]) - floor(theta[k-1]),
 * and every speed is dn times the resolution 2 pi / (cpr Ts).
 */
static void check_difference_on(uint32_t bits, uint32_t cpr, uint32_t offset, double w0, double a)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_DIFFERENCE);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    const double Ts = 1e-3, w_res = TWO_PI / (cpr * Ts);
    int64_t prev;
    int wrong_dn = 0, not_multiple = 0, wraps = 0;

    cfg.counter_bits = bits;
    cfg.counts_per_rev = cpr;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    CHECK_CLOSE(enc.coef[enc.active].w_res_radps, w_res, 1e-6 * w_res);
    prev = counted(0.0, cpr);
    p2d_encoder_reset(&enc, reading(prev, offset, bits), 0.0f);
    for (int k = 1; k <= 3000; ++k) {
        double t = k * Ts;
        double theta = w0 * t + 0.5 * a * t * t; /* [rad] */
        int64_t n = counted(theta, cpr);
        uint32_t r = reading(n, offset, bits);
        if (r < reading(prev, offset, bits) && n > prev) wraps++;
        p2d_encoder_step(&enc, r, &out);
        if (out.dn_counts != (int32_t)(n - prev)) wrong_dn++;
        /* w = w_res dn: an integer multiple of the resolution (float32 rounding of the product) */
        if (fabs(out.w_raw_radps - w_res * (double)(n - prev)) > 1e-6 * fabs(w_res * (double)(n - prev))) {
            not_multiple++;
        }
        if (out.w_m_radps != out.w_raw_radps) not_multiple++;
        prev = n;
    }
    CHECK(wrong_dn == 0);
    CHECK(not_multiple == 0);
    if (w0 > 0.0) CHECK(wraps > 0); /* the trajectory did wrap the counter */
}

static void test_difference_with_wrap(void)
{
    /* 16-bit timer, 10000 counts/rev: from 300 rad/s braking through zero to -300 rad/s */
    check_difference_on(16u, 10000u, 0u, 300.0, -200.0);
    /* 16-bit timer starting just below its wrap */
    check_difference_on(16u, 10000u, 65500u, 300.0, -200.0);
    /* 32-bit timer starting just below 2^32 */
    check_difference_on(32u, 10000u, 0xffffff00u, 300.0, -200.0);
    /* a 12-bit counter that wraps twice per revolution of a 8192-count encoder */
    check_difference_on(12u, 8192u, 100u, 150.0, -100.0);
    /* 2-bit counter (the smallest), 4 counts/rev: at most one count per period */
    check_difference_on(2u, 4u, 0u, 100.0, 0.0);
}

/*
 * Largest increment: the counter may move up to 2^(bits-1) - 1 counts forward
 * and 2^(bits-1) back in one period.
 */
static void test_wrap_extremes(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_DIFFERENCE);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    p2d_encoder_reset(&enc, 65535u, 0.0f);
    p2d_encoder_step(&enc, 32766u, &out); /* 65535 + 32767 mod 65536 */
    CHECK(out.dn_counts == 32767);
    p2d_encoder_step(&enc, 65534u, &out); /* 32766 + 32768 */
    CHECK(out.dn_counts == -32768);
    /* bits above the counter width are ignored */
    p2d_encoder_step(&enc, 0xabcd0000u | 65535u, &out);
    CHECK(out.dn_counts == 1);
    cfg.counter_bits = 32u;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    p2d_encoder_reset(&enc, 0u, 0.0f);
    p2d_encoder_step(&enc, 0x7fffffffu, &out);
    CHECK(out.dn_counts == 2147483647);
    p2d_encoder_step(&enc, 0xffffffffu, &out);
    CHECK(out.dn_counts == -2147483647 - 1);
    p2d_encoder_step(&enc, 0u, &out);
    CHECK(out.dn_counts == 1);
}

/*
 * PLL on a trajectory (ramp up, constant speed, reversal): the estimate equals the
 * designed transfer function W(z) = w_res (1 - p)^2 / (1 - p z^-1)^2 DN(z), run as
 * two first-order recursions in double with p = (2 - w Ts) / (2 + w Ts).
 */
static void test_pll_transfer_function(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_PLL);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    const double Ts = 1e-3, w_pll = 200.0, w_res = TWO_PI / (10000.0 * Ts);
    const double p = (2.0 - w_pll * Ts) / (2.0 + w_pll * Ts);
    double y1 = 0.0, y2 = 0.0, worst = 0.0;
    int64_t prev = 0;

    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    p2d_encoder_reset(&enc, 0u, 0.0f);
    for (int k = 1; k <= 4000; ++k) {
        double t = k * Ts, theta;
        int64_t n;
        /* 0..0.5 s: 400 rad/s^2 ramp; then 200 rad/s; from 2 s: -600 rad/s^2 */
        if (t <= 0.5) {
            theta = 200.0 * t * t;
        } else if (t <= 2.0) {
            theta = 50.0 + 200.0 * (t - 0.5);
        } else {
            theta = 350.0 + 200.0 * (t - 2.0) - 300.0 * (t - 2.0) * (t - 2.0);
        }
        n = counted(theta, 10000u);
        p2d_encoder_step(&enc, reading(n, 0u, 16u), &out);
        y1 = p * y1 + (1.0 - p) * w_res * (double)(n - prev);
        y2 = p * y2 + (1.0 - p) * y1;
        if (fabs(out.w_raw_radps - y2) > worst) worst = fabs(out.w_raw_radps - y2);
        prev = n;
    }
    /* float32 state of a 400 rad/s signal: a few 1e-5 relative */
    CHECK_CLOSE(worst, 0.0, 2e-3);
}

/*
 * At constant speed the PLL settles within one count per period of the speed
 * (|w - w_true| < w_res), although each increment is a whole count: the
 * difference estimator is off by up to w_res at every sample.
 */
static void test_pll_settles_within_one_count(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_PLL);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    const double Ts = 1e-3, w_res = TWO_PI / (10000.0 * Ts);
    const double speeds[4] = {0.37 * w_res, 3.3 * w_res, 123.456, -271.828};
    for (int s = 0; s < 4; ++s) {
        double worst = 0.0;
        CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
        p2d_encoder_reset(&enc, reading(counted(0.1, 10000u), 0u, 16u), 0.0f);
        for (int k = 1; k <= 3000; ++k) {
            int64_t n = counted(0.1 + speeds[s] * k * Ts, 10000u);
            p2d_encoder_step(&enc, reading(n, 0u, 16u), &out);
            /* after 20 / w_pll = 0.1 s */
            if (k > 100 && fabs(out.w_m_radps - speeds[s]) > worst) worst = fabs(out.w_m_radps - speeds[s]);
        }
        CHECK(worst < w_res);
    }
}

/* The low-pass: y[k] = q y[k-1] + (1 - q) w[k], q = (2 - w_lp Ts) / (2 + w_lp Ts), on the difference. */
static void test_lowpass(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_DIFFERENCE);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    const double Ts = 1e-3, q = (2.0 - 0.3) / (2.0 + 0.3);
    double y = 50.0, worst = 0.0;
    int64_t prev = counted(1.0, 10000u);
    cfg.lowpass_radps = 300.0f;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    /* bumpless start at 50 rad/s */
    p2d_encoder_reset(&enc, reading(prev, 7u, 16u), 50.0f);
    for (int k = 1; k <= 2000; ++k) {
        int64_t n = counted(1.0 + 50.0 * k * Ts + 20.0 * sin(30.0 * k * Ts), 10000u);
        p2d_encoder_step(&enc, reading(n, 7u, 16u), &out);
        CHECK(out.w_raw_radps == enc.coef[enc.active].w_res_radps * (float)(n - prev));
        y = q * y + (1.0 - q) * out.w_raw_radps;
        if (fabs(out.w_m_radps - y) > worst) worst = fabs(out.w_m_radps - y);
        prev = n;
    }
    CHECK_CLOSE(worst, 0.0, 1e-3);
}

/* Reset: the first step after it counts from the given reading; a NaN speed is refused and counted. */
static void test_reset(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_PLL);
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    CHECK(enc.count_prev == 0u && enc.v_pll_counts == 0.0f && enc.fault_count == 0u);
    p2d_encoder_reset(&enc, 40000u, 100.0f);
    CHECK(enc.v_pll_counts == 100.0f * enc.coef[enc.active].counts_per_radps && enc.w_lowpass_radps == 100.0f &&
          enc.theta_err_counts == 0.0f);
    /* 100 rad/s = 159.15 counts per period: the PLL holds its speed if the count advances as predicted */
    p2d_encoder_step(&enc, 40159u, &out);
    CHECK(out.dn_counts == 159);
    CHECK_CLOSE(out.w_m_radps, 100.0, 0.1);
    p2d_encoder_reset(&enc, 3u, NAN);
    CHECK(enc.fault_count == 1u && enc.v_pll_counts == 0.0f && enc.w_lowpass_radps == 0.0f && enc.count_prev == 3u);
    p2d_encoder_reset(&enc, 3u, -INFINITY);
    CHECK(enc.fault_count == 2u);
    /* finite, but 3e38 rad/s is beyond float32 in counts per period */
    p2d_encoder_reset(&enc, 3u, 3e38f);
    CHECK(enc.fault_count == 3u && enc.v_pll_counts == 0.0f && enc.w_lowpass_radps == 0.0f);
}

/* set_config: atomic, state kept; a rejected one leaves everything as it was. */
static void test_set_config(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_PLL);
    p2d_encoder_t enc, before;
    p2d_encoder_output_t out;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    p2d_encoder_reset(&enc, 0u, 0.0f);
    for (uint32_t k = 1u; k <= 50u; ++k) p2d_encoder_step(&enc, 100u * k, &out);
    memcpy(&before, &enc, sizeof enc);
    cfg.bandwidth_radps = -3.0f;
    CHECK(p2d_encoder_set_config(&enc, &cfg) == P2D_ERR_ENC_BANDWIDTH);
    CHECK(memcmp(&enc, &before, sizeof enc) == 0);
    cfg.bandwidth_radps = 50.0f;
    cfg.lowpass_radps = 100.0f;
    CHECK(p2d_encoder_set_config(&enc, &cfg) == P2D_OK);
    CHECK(enc.active == 1u - before.active);
    CHECK(enc.v_pll_counts == before.v_pll_counts && enc.count_prev == before.count_prev);
    CHECK(memcmp(&enc.coef[before.active], &before.coef[before.active], sizeof enc.coef[0]) == 0);
    CHECK(enc.config.bandwidth_radps == 50.0f);
    CHECK(p2d_encoder_set_config(&enc, NULL) == P2D_ERR_NULL);
}

/*
 * Non-finite policy of the step: a state far beyond a new configuration's range (a
 * 32-bit counter at 2^30 counts per period, then a 2-bit counter whose resolution is
 * near FLT_MAX) overflows the estimate; the output holds the last measured speed, the
 * state is kept and the fault counted.
 */
static void test_step_overflow_holds(void)
{
    p2d_encoder_config_t cfg = encoder_config(P2D_ESTIMATOR_PLL);
    p2d_encoder_t enc, before;
    p2d_encoder_output_t out;
    float w_big;
    cfg.counter_bits = 32u;
    CHECK(p2d_encoder_init(&enc, &cfg) == P2D_OK);
    w_big = enc.coef[enc.active].w_res_radps * 1073741824.0f; /* 2^30 counts per period */
    p2d_encoder_reset(&enc, 0u, w_big);
    CHECK(enc.fault_count == 0u);
    cfg.counter_bits = 2u;
    cfg.counts_per_rev = 1u;
    cfg.Ts_s = 6.3e-38f; /* w_res = 2 pi / Ts ~ 1e38 rad/s */
    cfg.bandwidth_radps = 1e-3f / 6.3e-38f;
    CHECK(p2d_encoder_set_config(&enc, &cfg) == P2D_OK);
    memcpy(&before, &enc, sizeof enc);
    p2d_encoder_step(&enc, 1u, &out);
    CHECK(out.fault && enc.fault_count == 1u);
    CHECK(out.w_m_radps == w_big && out.w_raw_radps == w_big);
    CHECK(enc.v_pll_counts == before.v_pll_counts && enc.theta_err_counts == before.theta_err_counts &&
          enc.w_lowpass_radps == before.w_lowpass_radps && enc.count_prev == 1u);
    /* a reset in range recovers */
    p2d_encoder_reset(&enc, 1u, 0.0f);
    p2d_encoder_step(&enc, 2u, &out);
    CHECK(!out.fault && isfinite(out.w_m_radps) && enc.fault_count == 1u);
}

int main(void)
{
    test_validation();
    test_difference_with_wrap();
    test_wrap_extremes();
    test_pll_transfer_function();
    test_pll_settles_within_one_count();
    test_lowpass();
    test_reset();
    test_set_config();
    test_step_overflow_holds();
    return check_summary();
}
