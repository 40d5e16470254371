/*
 * libFuzzer target: the notch and low-pass filters (pmsm2dof/filter.h), built
 * with -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a sampling period and a configuration,
 * valid or not, then to operations until the bytes run out:
 *   op % 4 == 0  one sample of any float
 *   op % 4 == 1  a run of 1..2048 samples: a sinusoid of random frequency
 *                (up to Nyquist) and amplitude on a random offset
 *   op % 4 == 2  set_config with a fresh configuration, or one field redrawn
 *   op % 4 == 3  p2d_filter_reset at any float
 *
 * Invariants, checked after every call (abort on violation):
 *  - init and set_config accept or reject; a rejection names Ts_s (init) or a
 *    filter field and leaves the filter bit-identical; set_config gives the
 *    verdict of init at the same Ts_s and its coefficients, keeps the states
 *    of the sections that stay on and starts those switched on at rest at the
 *    last input.
 *  - an accepted configuration is inside the documented ranges; its sections'
 *    g equal tan(pi f0 Ts) (double) within 1e-6, and the realized denominator
 *    g g h + g h k q + (1 - g h (g + k)) q^2 (filter.h), evaluated in double
 *    from the float32 coefficients, has positive coefficients (a stable
 *    section) and a q^2 coefficient within 2e-3 of h = 1 / (1 + g (g + k))
 *    designed in double from the configuration.
 *  - a step with a non-finite input faults; a fault gives y = 0, leaves the
 *    state alone and counts once, and with a finite input happens only where
 *    input or states are large enough for an overflow (fz_filter_may_overflow);
 *    otherwise y and the state are finite.
 *  - reset(x) puts every section at rest at x (s1 = 0, s2 = x); a step of x
 *    then returns x exactly (as a number: -0 gives +0) and leaves the state as
 *    it is (the exact unit DC gain); a non-finite x rests at 0 and counts a
 *    fault.
 */
#include "fuzz_common.h"

#include "pmsm2dof/filter.h"

/* 1/sqrt(2): the upper bound of notch_depth */
#define FZ_DEPTH_MAX 0.70710678118654752

static const double FZ_PI = 3.14159265358979323846;

/*
 * A configuration around a torsional resonance: notch at 50 Hz, 20 Hz wide,
 * -20 dB, low-pass at 300 Hz. Bits 0 and 1 of the shape byte switch the notch
 * and the low-pass on.
 */
static void fz_filter_config(fz_reader_t *r, p2d_filter_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    memset(cfg, 0, sizeof *cfg);
    if (shape & 1u) {
        cfg->notch_freq_Hz = fz_float(r, 50.0, true);
        cfg->notch_width_Hz = fz_float(r, 20.0, true);
        cfg->notch_depth = fz_float(r, 0.1, true);
    }
    if (shape & 2u) {
        cfg->lowpass_freq_Hz = fz_float(r, 300.0, true);
        cfg->lowpass_zeta = fz_float(r, 0.7, true);
    }
}

/* The active configuration with one field redrawn. */
static void fz_filter_config_mutated(fz_reader_t *r, const p2d_filter_config_t *active, p2d_filter_config_t *cfg)
{
    *cfg = *active;
    switch (fz_u8(r) % 6u) {
    case 0: cfg->notch_freq_Hz = fz_float(r, 50.0, true); break;
    case 1: cfg->notch_width_Hz = fz_float(r, 20.0, true); break;
    case 2: cfg->notch_depth = fz_float(r, 0.1, true); break;
    case 3: cfg->lowpass_freq_Hz = fz_float(r, 300.0, true); break;
    case 4: cfg->lowpass_zeta = fz_float(r, 0.7, true); break;
    default: cfg->notch_freq_Hz = 0.0f; break; /* switch the notch off */
    }
}

/* Both coefficient sets of a section hold the same numbers (fields compared: bools leave padding). */
static bool fz_same_section(const p2d_biquad_coef_t *a, const p2d_biquad_coef_t *b)
{
    return fz_bits_equal(a->g, b->g) && fz_bits_equal(a->k, b->k) && fz_bits_equal(a->g_h, b->g_h) &&
           fz_bits_equal(a->c_band, b->c_band);
}

static bool fz_same_coef(const p2d_filter_coef_t *a, const p2d_filter_coef_t *b)
{
    return a->has_notch == b->has_notch && a->has_lowpass == b->has_lowpass && fz_same_section(&a->notch, &b->notch) &&
           fz_same_section(&a->lowpass, &b->lowpass);
}

/* One accepted section: coefficients against tan(pi f0 Ts) and the design h, realized stable. */
static void fz_check_section(const p2d_biquad_coef_t *s, double f0_Hz, double k_design, double Ts, const char *name)
{
    double g = s->g, k = s->k, gh = s->g_h;
    double g_exact = tan(FZ_PI * (double)((float)f0_Hz * (float)Ts));
    double h = 1.0 / (1.0 + g_exact * (g_exact + k_design));
    double a0 = g * gh, a1 = gh * k, a2 = 1.0 - gh * (g + k);
    FZ_REQUIRE(isfinite(g) && isfinite(k) && isfinite(gh) && isfinite(s->c_band), "%s: non-finite coefficient", name);
    FZ_REQUIRE(fabs(g - g_exact) <= 1e-6 * g_exact, "%s: g %.9g against tan(pi f0 Ts) = %.9g", name, g, g_exact);
    FZ_REQUIRE(a0 > 0.0 && a1 > 0.0 && a2 > 0.0, "%s: realized denominator %g %g %g not Hurwitz", name, a0, a1, a2);
    FZ_REQUIRE(fabs(a2 - h) <= 2e-3 * h, "%s: realized q^2 coefficient %.9g against the designed h %.9g", name, a2, h);
}

/* An accepted configuration is in the documented ranges and realizes its design. */
static void fz_check_accepted(const p2d_filter_t *f)
{
    const p2d_filter_config_t *cfg = &f->config;
    const p2d_filter_coef_t *c = &f->coef[f->active];
    const double nyquist = 0.5 / (double)f->Ts_s;
    FZ_REQUIRE(isfinite(f->Ts_s) && f->Ts_s > 0.0f, "accepted Ts_s %g", (double)f->Ts_s);
    FZ_REQUIRE(c->has_notch == (cfg->notch_freq_Hz != 0.0f) && c->has_lowpass == (cfg->lowpass_freq_Hz != 0.0f),
               "sections on: notch %d low-pass %d", (int)c->has_notch, (int)c->has_lowpass);
    if (c->has_notch) {
        double d = cfg->notch_depth, g = tan(FZ_PI * (double)(cfg->notch_freq_Hz * f->Ts_s));
        double B_v = (1.0 + g * g) * tan(FZ_PI * (double)(cfg->notch_width_Hz * f->Ts_s)) / sqrt(1.0 - 2.0 * d * d);
        FZ_REQUIRE(cfg->notch_freq_Hz > 0.0f && cfg->notch_freq_Hz < nyquist && cfg->notch_width_Hz > 0.0f &&
                       cfg->notch_width_Hz < nyquist && d >= 0.0 && d < FZ_DEPTH_MAX,
                   "accepted notch %g Hz, %g Hz wide, depth %g at Ts %g", (double)cfg->notch_freq_Hz,
                   (double)cfg->notch_width_Hz, d, (double)f->Ts_s);
        fz_check_section(&c->notch, cfg->notch_freq_Hz, B_v / g, f->Ts_s, "notch");
    }
    if (c->has_lowpass) {
        FZ_REQUIRE(cfg->lowpass_freq_Hz > 0.0f && cfg->lowpass_freq_Hz < nyquist && cfg->lowpass_zeta > 0.0f &&
                       isfinite(cfg->lowpass_zeta),
                   "accepted low-pass %g Hz, zeta %g at Ts %g", (double)cfg->lowpass_freq_Hz, (double)cfg->lowpass_zeta,
                   (double)f->Ts_s);
        fz_check_section(&c->lowpass, cfg->lowpass_freq_Hz, 2.0 * (double)cfg->lowpass_zeta, f->Ts_s, "low-pass");
    }
}

/* A rejection names Ts_s (init only) or one filter field. */
static void fz_check_rejection(p2d_status_t status, bool init)
{
    FZ_REQUIRE((status >= P2D_ERR_NOTCH_FREQ && status <= P2D_ERR_LOWPASS_ZETA) || (init && status == P2D_ERR_TS),
               "status %d", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

static double fz_state_magnitude(const p2d_filter_t *f)
{
    const p2d_filter_state_t *s = &f->state;
    return fmax(fmax(fabs((double)s->notch.s1), fabs((double)s->notch.s2)),
                fmax(fabs((double)s->lowpass.s1), fabs((double)s->lowpass.s2)));
}

static void fz_check_state_finite(const p2d_filter_t *f)
{
    const p2d_filter_coef_t *c = &f->coef[f->active];
    FZ_REQUIRE(!c->has_notch || (isfinite(f->state.notch.s1) && isfinite(f->state.notch.s2)), "notch state poisoned");
    FZ_REQUIRE(!c->has_lowpass || (isfinite(f->state.lowpass.s1) && isfinite(f->state.lowpass.s2)),
               "low-pass state poisoned");
}

/* One step of x, with the invariants of the non-finite policy. */
static float fz_step(p2d_filter_t *f, float x)
{
    p2d_filter_t before;
    p2d_filter_output_t out;
    memcpy(&before, f, sizeof before);
    p2d_filter_step(f, x, &out);
    if (!isfinite(x)) FZ_REQUIRE(out.fault, "non-finite input %g without fault", (double)x);
    if (out.fault) {
        before.fault_count++;
        FZ_REQUIRE(out.y == 0.0f && memcmp(f, &before, sizeof before) == 0, "a fault changed the state or gave %g",
                   (double)out.y);
        FZ_REQUIRE(!isfinite(x) || fz_filter_may_overflow(&before.coef[before.active],
                                                          fmax(fabs((double)x), fz_state_magnitude(&before))),
                   "fault on the finite input %g from states of magnitude %g", (double)x, fz_state_magnitude(&before));
        return 0.0f;
    }
    FZ_REQUIRE(isfinite(out.y) && f->fault_count == before.fault_count && f->x_prev == x, "step y %g", (double)out.y);
    fz_check_state_finite(f);
    return out.y;
}

/* init: accept (state at rest at 0) or reject without writing. */
static bool fz_init(p2d_filter_t *f, const p2d_filter_config_t *cfg, float Ts)
{
    p2d_filter_t pattern;
    p2d_status_t status;
    memset(f, 0xa5, sizeof *f);
    memcpy(&pattern, f, sizeof pattern);
    status = p2d_filter_init(f, cfg, Ts);
    if (status != P2D_OK) {
        fz_check_rejection(status, true);
        FZ_REQUIRE(memcmp(f, &pattern, sizeof pattern) == 0, "rejected init (status %d) wrote", (int)status);
        return false;
    }
    fz_check_accepted(f);
    FZ_REQUIRE(f->state.notch.s1 == 0.0f && f->state.notch.s2 == 0.0f && f->state.lowpass.s1 == 0.0f &&
                   f->state.lowpass.s2 == 0.0f && f->x_prev == 0.0f && f->fault_count == 0u,
               "init did not put the filter at rest at 0");
    return true;
}

/* set_config: atomic, init's verdict and coefficients, states kept or started at rest at the last input. */
static void fz_set_config(p2d_filter_t *f, const p2d_filter_config_t *cfg)
{
    p2d_filter_t before, fresh;
    const p2d_filter_coef_t *old, *now;
    p2d_status_t status, status_init;
    memcpy(&before, f, sizeof before);
    status_init = p2d_filter_init(&fresh, cfg, f->Ts_s);
    status = p2d_filter_set_config(f, cfg);
    FZ_REQUIRE(status == status_init, "set_config status %d, init status %d", (int)status, (int)status_init);
    if (status != P2D_OK) {
        fz_check_rejection(status, false);
        FZ_REQUIRE(memcmp(f, &before, sizeof before) == 0, "rejected set_config (status %d) wrote", (int)status);
        return;
    }
    old = &before.coef[before.active];
    now = &f->coef[f->active];
    FZ_REQUIRE(f->active == 1u - before.active && fz_same_coef(now, &fresh.coef[0]) &&
                   fz_same_coef(&f->coef[before.active], old),
               "set_config: wrong set swapped in, or the set in force written");
    fz_check_accepted(f);
    if (now->has_notch) {
        const p2d_biquad_state_t *s = &f->state.notch, *s0 = &before.state.notch;
        FZ_REQUIRE(old->has_notch ? fz_bits_equal(s->s1, s0->s1) && fz_bits_equal(s->s2, s0->s2)
                                  : s->s1 == 0.0f && fz_bits_equal(s->s2, before.x_prev),
                   "notch state after set_config");
    }
    if (now->has_lowpass) {
        const p2d_biquad_state_t *s = &f->state.lowpass, *s0 = &before.state.lowpass;
        FZ_REQUIRE(old->has_lowpass ? fz_bits_equal(s->s1, s0->s1) && fz_bits_equal(s->s2, s0->s2)
                                    : s->s1 == 0.0f && fz_bits_equal(s->s2, before.x_prev),
                   "low-pass state after set_config");
    }
}

/* reset: at rest at x, where a step of x returns x to the bit. */
static void fz_reset(p2d_filter_t *f, float x)
{
    const uint32_t faults = f->fault_count;
    p2d_filter_reset(f, x);
    if (!isfinite(x)) {
        FZ_REQUIRE(f->fault_count == faults + 1u && f->state.notch.s2 == 0.0f && f->state.lowpass.s2 == 0.0f,
                   "reset(%g) did not rest at 0 with one fault", (double)x);
        return;
    }
    FZ_REQUIRE(f->state.notch.s1 == 0.0f && fz_bits_equal(f->state.notch.s2, x) && f->state.lowpass.s1 == 0.0f &&
                   fz_bits_equal(f->state.lowpass.s2, x) && f->fault_count == faults,
               "reset(%g): not at rest", (double)x);
    {
        /* as numbers: a rest at -0 steps to +0 (-0 + +0 = +0) */
        p2d_filter_state_t rest = f->state, *s = &f->state;
        float y = fz_step(f, x);
        FZ_REQUIRE(y == x && s->notch.s1 == rest.notch.s1 && s->notch.s2 == rest.notch.s2 &&
                       s->lowpass.s1 == rest.lowpass.s1 && s->lowpass.s2 == rest.lowpass.s2,
                   "at rest at %.9g a step gave %.9g or moved the state: the DC gain is not exactly 1", (double)x,
                   (double)y);
    }
}

/* A sinusoid of 1..2048 samples. */
static void fz_run(p2d_filter_t *f, fz_reader_t *r)
{
    uint32_t n = 1u + fz_u16(r) % 2048u;
    double amplitude = fz_float(r, 1.0, false), offset = fz_float(r, 1.0, true);
    double cycles_per_sample = 0.5 * fz_unit(r);
    if (!isfinite(amplitude) || !isfinite(offset)) return;
    for (uint32_t k = 0; k < n; ++k) {
        (void)fz_step(f, (float)(offset + amplitude * sin(2.0 * FZ_PI * cycles_per_sample * (double)k)));
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    p2d_filter_t f;
    p2d_filter_config_t cfg;
    float Ts = fz_float(&r, 1e-3, false);

    FZ_REQUIRE(p2d_filter_init(NULL, &cfg, Ts) == P2D_ERR_NULL && p2d_filter_set_config(&f, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_filter_config(&r, &cfg);
    if (!fz_init(&f, &cfg, Ts)) return 0;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 4u) {
        case 0: (void)fz_step(&f, fz_float(&r, 1.0, true)); break;
        case 1: fz_run(&f, &r); break;
        case 2:
            if (op & 4u) {
                fz_filter_config_mutated(&r, &f.config, &cfg);
            } else {
                fz_filter_config(&r, &cfg);
            }
            fz_set_config(&f, &cfg);
            break;
        default: fz_reset(&f, fz_float(&r, 1.0, true)); break;
        }
    }
    return 0;
}
