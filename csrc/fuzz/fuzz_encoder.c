/*
 * libFuzzer target: the encoder speed estimators (pmsm2dof/encoder.h), built
 * with -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a configuration, valid or not, and
 * then to operations until the bytes run out:
 *   op % 8 in 0..2  one reading: the previous one plus a small signed increment
 *   op % 8 == 3     one reading: any 32-bit word
 *   op % 8 == 4     a run of 1..2048 periods on an angle trajectory at a
 *                   constant acceleration (the counts floor(theta cpr / 2 pi))
 *   op % 8 == 5     set_config with one field of the active configuration redrawn
 *   op % 8 == 6     set_config with a fresh configuration
 *   op % 8 == 7     p2d_encoder_reset with a random reading and speed
 *
 * Invariants, checked after every call (abort on violation):
 *  - init and set_config either accept or reject; a rejected call leaves the
 *    estimator bit-identical and names an encoder parameter (or Ts_s); an
 *    accepted configuration is inside the documented ranges, with a finite
 *    resolution, PLL pole p^2 in [0, 1) and gain > 0, low-pass pole in [0, 1)
 *    (0 and gain 1 without the filter); set_config gives the same status as
 *    init and the same coefficients, leaves the set in force untouched and
 *    keeps the state.
 *  - dn is the increment modulo 2^counter_bits in [-2^(bits-1), 2^(bits-1)),
 *    recomputed here in 64-bit integers; the difference estimate is w_res dn
 *    to the bit; without the low-pass the output is the estimate to the bit.
 *  - every output and the state are finite after every call; a fault (an
 *    overflow) holds the last measured speed and keeps the state, and happens
 *    only where the state or the increment come near the float32 range;
 *    reset accepts exactly the finite, measurable speeds.
 *  - bounds (float32 rounding slack FZ_SUM_SLACK of the magnitudes involved):
 *      low-pass: |y[k]| <= max(|y[k-1]|, |w[k]|) (a convex combination);
 *      PLL: in counts per period v = w / w_res and with the angle residual r,
 *        the loop is the cascade of two first-order sections with pole p,
 *          y1[k] = p y1[k-1] + (1 - p) dn[k],  v[k] = p v[k-1] + (1 - p) y1[k],
 *        with y1 = v - (1 - p) r / p (p > 0): |y1[k]| <= max(|y1[k-1]|, |dn[k]|)
 *        and |v[k]| <= max(|v[k-1]|, |y1[k]|). (p = 0, deadbeat: v[k] = dn[k] - r[k-1].)
 *        Exact in float32 too, because p + (1 - p) = 1 exactly (encoder.h).
 */
#include "fuzz_common.h"

#include "pmsm2dof/encoder.h"

/* Estimator and trajectory state of one fuzz input. */
typedef struct {
    p2d_encoder_t enc; /* estimator under test */
    uint32_t count;    /* the last reading handed to the estimator [count] */
    double theta_rad;  /* angle of the trajectory runs [rad] */
    double w_m_radps;  /* speed of the trajectory runs [rad/s] */
} fz_encoder_rig_t;

static uint32_t fz_counts_per_rev(fz_reader_t *r)
{
    static const uint32_t odd[8] = {0u, 1u, 3u, 1u << 20, 1u << 24, 1u << 31, 0x80000001u, 0xffffffffu};
    uint8_t b = fz_u8(r);
    if (b >= 248u) return odd[b - 248u];
    /* 4 x (2^4 .. 2^15) lines, and odd counts */
    return b % 2u ? 4u << (4u + b / 2u % 12u) : 1u + fz_u16(r);
}

static uint32_t fz_counter_bits(fz_reader_t *r)
{
    static const uint32_t odd[8] = {0u, 1u, 33u, 64u, 255u, 0x80000000u, 0xffffffffu, 2u};
    uint8_t b = fz_u8(r);
    if (b >= 248u) return odd[b - 248u];
    return b % 3u == 0u ? 16u : b % 3u == 1u ? 32u : 2u + b % 31u;
}

/* A configuration around a 10000-count encoder read at 1 kHz. Bit 0 of the shape byte disables the low-pass. */
static void fz_encoder_config(fz_reader_t *r, p2d_encoder_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    memset(cfg, 0, sizeof *cfg);
    cfg->counts_per_rev = fz_counts_per_rev(r);
    cfg->counter_bits = fz_counter_bits(r);
    cfg->Ts_s = fz_float(r, 1e-3, false);
    cfg->estimator = (p2d_estimator_t)fz_enum(r, 2u);
    cfg->bandwidth_radps = fz_float(r, 200.0, false);
    cfg->lowpass_radps = (shape & 1u) ? 0.0f : fz_float(r, 300.0, false);
}

static void fz_encoder_config_mutated(fz_reader_t *r, const p2d_encoder_config_t *active, p2d_encoder_config_t *cfg)
{
    *cfg = *active;
    switch (fz_u8(r) % 6u) {
    case 0: cfg->counts_per_rev = fz_counts_per_rev(r); break;
    case 1: cfg->counter_bits = fz_counter_bits(r); break;
    case 2: cfg->Ts_s = fz_float(r, 1e-3, false); break;
    case 3: cfg->estimator = (p2d_estimator_t)fz_enum(r, 2u); break;
    case 4: cfg->bandwidth_radps = fz_float(r, 200.0, false); break;
    default: cfg->lowpass_radps = fz_u8(r) % 4u == 0u ? 0.0f : fz_float(r, 300.0, false); break;
    }
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }

static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status == P2D_ERR_TS || (status >= P2D_ERR_ENC_COUNTS_PER_REV && status <= P2D_ERR_ENC_LOWPASS),
               "status %d is not an encoder parameter", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

static void fz_check_accepted(const p2d_encoder_config_t *cfg, const p2d_encoder_coef_t *c)
{
    /* w Ts as the init computes it, in float32 */
    float x_pll = cfg->bandwidth_radps * cfg->Ts_s;
    float x_lp = cfg->lowpass_radps * cfg->Ts_s;
    FZ_REQUIRE(fz_positive(cfg->Ts_s) && cfg->counts_per_rev >= 1u && cfg->counter_bits >= 2u &&
                   cfg->counter_bits <= 32u && (unsigned)cfg->estimator <= 1u,
               "accepted a configuration outside the documented ranges");
    FZ_REQUIRE(cfg->estimator != P2D_ESTIMATOR_PLL ||
                   (fz_positive(cfg->bandwidth_radps) && x_pll >= 1e-3f && x_pll <= 2.0f),
               "accepted bandwidth %g with Ts %g", (double)cfg->bandwidth_radps, (double)cfg->Ts_s);
    FZ_REQUIRE(cfg->lowpass_radps == 0.0f || (fz_positive(cfg->lowpass_radps) && x_lp >= 1e-3f && x_lp <= 2.0f),
               "accepted lowpass %g with Ts %g", (double)cfg->lowpass_radps, (double)cfg->Ts_s);
    FZ_REQUIRE(fz_positive(c->w_res_radps) && fz_positive(c->counts_per_radps) &&
                   isfinite(c->w_res_radps * (float)c->counter_half),
               "resolution %g, 1/resolution %g", (double)c->w_res_radps, (double)c->counts_per_radps);
    /* each pole in [0, 1), and p + (1 - p) = 1 exactly (in double, exact for two floats) */
    FZ_REQUIRE(c->pll_pole >= 0.0f && c->pll_pole < 1.0f && (double)c->pll_pole + (double)c->pll_one_minus_pole == 1.0,
               "PLL pole %.9g, 1 - pole %.9g", (double)c->pll_pole, (double)c->pll_one_minus_pole);
    FZ_REQUIRE(cfg->estimator == P2D_ESTIMATOR_PLL || c->pll_pole == 0.0f, "difference with a PLL pole");
    FZ_REQUIRE(c->lowpass_pole >= 0.0f && c->lowpass_pole < 1.0f &&
                   (double)c->lowpass_pole + (double)c->lowpass_one_minus_pole == 1.0,
               "low-pass pole %.9g, 1 - pole %.9g", (double)c->lowpass_pole, (double)c->lowpass_one_minus_pole);
    FZ_REQUIRE(cfg->lowpass_radps != 0.0f || c->lowpass_pole == 0.0f, "no filter with pole %g",
               (double)c->lowpass_pole);
    FZ_REQUIRE(c->counter_mask == (uint32_t)(((uint64_t)1 << cfg->counter_bits) - 1u) &&
                   c->counter_half == (uint32_t)1 << (cfg->counter_bits - 1u),
               "counter mask %x half %x for %u bits", c->counter_mask, c->counter_half, cfg->counter_bits);
}

static void fz_check_state_finite(const p2d_encoder_t *enc)
{
    FZ_REQUIRE(isfinite(enc->theta_err_counts) && isfinite(enc->v_pll_counts) && isfinite(enc->w_lowpass_radps),
               "state not finite: r %g v %g y %g", (double)enc->theta_err_counts, (double)enc->v_pll_counts,
               (double)enc->w_lowpass_radps);
}

static bool fz_init(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg)
{
    p2d_encoder_t pattern;
    p2d_status_t status;
    memset(enc, 0xa5, sizeof *enc);
    memcpy(&pattern, enc, sizeof pattern);
    status = p2d_encoder_init(enc, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(enc, &pattern, sizeof pattern) == 0, "rejected init (status %d) wrote", (int)status);
        return false;
    }
    fz_check_accepted(cfg, &enc->coef[enc->active]);
    FZ_REQUIRE(enc->count_prev == 0u && enc->theta_err_counts == 0.0f && enc->v_pll_counts == 0.0f &&
                   enc->w_lowpass_radps == 0.0f && enc->fault_count == 0u,
               "init did not clear the state");
    return true;
}

static void fz_set_config(p2d_encoder_t *enc, const p2d_encoder_config_t *cfg)
{
    p2d_encoder_t before, fresh;
    p2d_status_t status, status_init;
    memcpy(&before, enc, sizeof before);
    status_init = p2d_encoder_init(&fresh, cfg);
    status = p2d_encoder_set_config(enc, cfg);
    FZ_REQUIRE(status == status_init, "set_config status %d, init status %d", (int)status, (int)status_init);
    if (status != P2D_OK) {
        FZ_REQUIRE(memcmp(enc, &before, sizeof before) == 0, "rejected set_config (status %d) wrote", (int)status);
        return;
    }
    FZ_REQUIRE(enc->active == 1u - before.active, "active %u -> %u", before.active, enc->active);
    FZ_REQUIRE(memcmp(&enc->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0,
               "set_config wrote the coefficient set in force");
    FZ_REQUIRE(memcmp(&enc->coef[enc->active], &fresh.coef[fresh.active], sizeof fresh.coef[0]) == 0,
               "set_config and init computed different coefficients");
    FZ_REQUIRE(memcmp(&enc->config, cfg, sizeof *cfg) == 0, "config not stored");
    FZ_REQUIRE(enc->count_prev == before.count_prev && fz_bits_equal(enc->v_pll_counts, before.v_pll_counts) &&
                   fz_bits_equal(enc->theta_err_counts, before.theta_err_counts) &&
                   fz_bits_equal(enc->w_lowpass_radps, before.w_lowpass_radps) &&
                   enc->fault_count == before.fault_count,
               "set_config changed the state");
}

/* One reading and every invariant of the step. */
static void fz_step(fz_encoder_rig_t *rig, uint32_t count)
{
    p2d_encoder_t before;
    p2d_encoder_output_t out;
    const p2d_encoder_coef_t *c;
    uint64_t modulus;
    int64_t d, dn;
    memcpy(&before, &rig->enc, sizeof before);
    c = &before.coef[before.active];
    p2d_encoder_step(&rig->enc, count, &out);
    rig->count = count;

    modulus = (uint64_t)c->counter_mask + 1u;
    d = (int64_t)(((uint64_t)count + modulus * 2u - (uint64_t)(before.count_prev & c->counter_mask)) % modulus);
    dn = d >= (int64_t)c->counter_half ? d - (int64_t)modulus : d;
    FZ_REQUIRE(out.dn_counts == dn, "dn %d, expected %lld (count %u, prev %u, mask %x)", out.dn_counts, (long long)dn,
               count, before.count_prev, c->counter_mask);
    FZ_REQUIRE(rig->enc.count_prev == count && memcmp(rig->enc.coef, before.coef, sizeof before.coef) == 0,
               "the step changed more than the state");
    FZ_REQUIRE(isfinite(out.w_raw_radps) && isfinite(out.w_m_radps), "output not finite: w %g y %g",
               (double)out.w_raw_radps, (double)out.w_m_radps);
    fz_check_state_finite(&rig->enc);
    if (out.fault) {
        /* an overflow: only where the state or the increment come near the float32 range */
        double scale =
            fmax(fmax(fabs((double)before.v_pll_counts), fabs((double)before.theta_err_counts)), fabs((double)dn));
        FZ_REQUIRE(rig->enc.fault_count == before.fault_count + 1u &&
                       fz_bits_equal(out.w_m_radps, before.w_lowpass_radps) &&
                       fz_bits_equal(out.w_raw_radps, before.w_lowpass_radps) &&
                       fz_bits_equal(rig->enc.v_pll_counts, before.v_pll_counts) &&
                       fz_bits_equal(rig->enc.theta_err_counts, before.theta_err_counts) &&
                       fz_bits_equal(rig->enc.w_lowpass_radps, before.w_lowpass_radps),
                   "a fault must hold the last speed, keep the state and count");
        FZ_REQUIRE(fmax(scale * (double)c->w_res_radps, fabs((double)before.w_lowpass_radps)) > 0.05 * FLT_MAX,
                   "fault without an overflow: v %g r %g dn %lld w_res %g", (double)before.v_pll_counts,
                   (double)before.theta_err_counts, (long long)dn, (double)c->w_res_radps);
        return;
    }
    FZ_REQUIRE(rig->enc.fault_count == before.fault_count, "counted a fault without raising it");
    if (c->estimator == P2D_ESTIMATOR_DIFFERENCE) {
        FZ_REQUIRE(fz_bits_equal(out.w_raw_radps, c->w_res_radps * (float)out.dn_counts),
                   "difference estimate %g is not w_res dn = %g x %d", (double)out.w_raw_radps, (double)c->w_res_radps,
                   out.dn_counts);
    } else {
        /* the cascade form of the PLL (file comment), in counts per period */
        double p = c->pll_pole, q = c->pll_one_minus_pole;
        double v0 = before.v_pll_counts, v1 = rig->enc.v_pll_counts;
        double r0 = before.theta_err_counts, r1 = rig->enc.theta_err_counts;
        FZ_REQUIRE(fz_bits_equal(out.w_raw_radps, c->w_res_radps * rig->enc.v_pll_counts), "PLL output is not w_res v");
        if (p == 0.0) {
            /* deadbeat: v[k] = dn[k] - r[k-1] (r = 0 after one period) */
            FZ_REQUIRE(fabs(v1 - ((double)dn - r0)) <= fz_slack(fabs((double)dn) + fabs(r0) + fabs(v0)) && r1 == 0.0,
                       "deadbeat PLL: v %g, dn %lld, r %g -> %g", v1, (long long)dn, r0, r1);
        } else {
            double y1_0 = v0 - q * r0 / p, y1_1 = v1 - q * r1 / p;
            /* relative rounding, and the subnormal spacing of r amplified by (1 - p) / p */
            double slack = fz_slack(fabs(v0) + fabs(v1) + fabs((double)dn) + q * (fabs(r0) + fabs(r1)) / p) +
                           8.0 * 0x1p-149 * (1.0 + q / p);
            FZ_REQUIRE(fabs(y1_1) <= fmax(fabs(y1_0), fabs((double)dn)) + slack,
                       "PLL first section grew: %.9g -> %.9g with dn %lld (p %g)", y1_0, y1_1, (long long)dn, p);
            FZ_REQUIRE(fabs(v1) <= fmax(fabs(v0), fabs(y1_1)) + slack,
                       "PLL second section grew: %.9g -> %.9g with y1 %.9g (p %g)", v0, v1, y1_1, p);
        }
    }
    if (rig->enc.config.lowpass_radps == 0.0f) {
        FZ_REQUIRE(out.w_m_radps == out.w_raw_radps, "no filter, but y %g != w %g", (double)out.w_m_radps,
                   (double)out.w_raw_radps);
    }
    FZ_REQUIRE(fabs((double)out.w_m_radps) <=
                   fmax(fabs((double)before.w_lowpass_radps), fabs((double)out.w_raw_radps)) *
                       (1.0 + 4.0 * FLT_EPSILON),
               "low-pass output %g beyond its previous %g and its input %g", (double)out.w_m_radps,
               (double)before.w_lowpass_radps, (double)out.w_raw_radps);
}

/* A trajectory theta(t) = theta0 + w t + a t^2 / 2 read for 1..2048 periods. */
static void fz_trajectory(fz_encoder_rig_t *rig, fz_reader_t *r)
{
    uint32_t n = 1u + fz_u16(r) % 2048u;
    double w_end = (double)fz_float(r, 100.0, true);
    double cpr = rig->enc.config.counts_per_rev, Ts = rig->enc.config.Ts_s;
    double a;
    if (!isfinite(w_end) || !(Ts > 0.0)) return;
    /* limit the speed to less than half the counter per period: beyond, the increment aliases (encoder.h) */
    w_end =
        fmax(fmin(w_end, 0.45 * 6.283185307179586 * (double)rig->enc.coef[rig->enc.active].counter_half / (cpr * Ts)),
             -0.45 * 6.283185307179586 * (double)rig->enc.coef[rig->enc.active].counter_half / (cpr * Ts));
    if (fabs(rig->w_m_radps) > fabs(w_end) + 1.0 || !isfinite(rig->w_m_radps)) rig->w_m_radps = 0.0;
    a = (w_end - rig->w_m_radps) / (n * Ts);
    for (uint32_t k = 0; k < n; ++k) {
        double theta_counts;
        rig->theta_rad += rig->w_m_radps * Ts + 0.5 * a * Ts * Ts;
        rig->w_m_radps += a * Ts;
        theta_counts = floor(fmod(rig->theta_rad * cpr / 6.283185307179586, 4294967296.0));
        if (theta_counts < 0.0) theta_counts += 4294967296.0;
        fz_step(rig, (uint32_t)theta_counts);
    }
}

static void fz_reset(fz_encoder_rig_t *rig, fz_reader_t *r)
{
    uint32_t count = fz_u32(r);
    float w = fz_float(r, 100.0, true);
    p2d_encoder_t before;
    memcpy(&before, &rig->enc, sizeof before);
    p2d_encoder_reset(&rig->enc, count, w);
    rig->count = count;
    FZ_REQUIRE(memcmp(rig->enc.coef, before.coef, sizeof before.coef) == 0, "reset changed the coefficients");
    fz_check_state_finite(&rig->enc);
    FZ_REQUIRE(rig->enc.count_prev == count && rig->enc.theta_err_counts == 0.0f, "reset did not take the reading");
    if (fabs((double)(w * rig->enc.coef[rig->enc.active].counts_per_radps)) <=
        (double)rig->enc.coef[rig->enc.active].counter_half) {
        FZ_REQUIRE(rig->enc.fault_count == before.fault_count &&
                       rig->enc.v_pll_counts == w * rig->enc.coef[rig->enc.active].counts_per_radps &&
                       rig->enc.w_lowpass_radps == w,
                   "reset(%g) accepted: v %g", (double)w, (double)rig->enc.v_pll_counts);
    } else {
        FZ_REQUIRE(rig->enc.fault_count == before.fault_count + 1u && rig->enc.v_pll_counts == 0.0f &&
                       rig->enc.w_lowpass_radps == 0.0f,
                   "a refused reset(%g) must start at 0 and count one fault", (double)w);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_encoder_rig_t rig;
    p2d_encoder_config_t cfg;

    FZ_REQUIRE(p2d_encoder_init(NULL, &cfg) == P2D_ERR_NULL && p2d_encoder_set_config(&rig.enc, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_encoder_config(&r, &cfg);
    if (!fz_init(&rig.enc, &cfg)) return 0;
    rig.count = 0u;
    rig.theta_rad = 0.0;
    rig.w_m_radps = 0.0;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 3: fz_step(&rig, fz_u32(&r)); break;
        case 4: fz_trajectory(&rig, &r); break;
        case 5:
            fz_encoder_config_mutated(&r, &rig.enc.config, &cfg);
            fz_set_config(&rig.enc, &cfg);
            break;
        case 6:
            fz_encoder_config(&r, &cfg);
            fz_set_config(&rig.enc, &cfg);
            break;
        case 7: fz_reset(&rig, &r); break;
        default: fz_step(&rig, rig.count + (uint32_t)(int32_t)(int16_t)fz_u16(&r)); break;
        }
    }
    return 0;
}
