/*
 * libFuzzer target: the 2DOF PI speed controller with anti-windup
 * (pmsm2dof/speed.h; paper Fig. 5 and 6, eq 9-15), built with
 * -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a configuration, valid or not, and
 * then to operations until the bytes run out:
 *   op % 8 in 0..2  one sample: w_ref, w_m and the applied torque drawn at random
 *   op % 8 == 3     p2d_speed_set_filter with fresh torque filters (a notch, a
 *                   low-pass, both or none around a 40 Hz resonance)
 *   op % 8 == 4     a closed-loop run of 1..2048 samples on the rigid-body plant
 *                   J_plant dw/dt = T_applied - T_load (forward Euler, double)
 *   op % 8 == 5     set_config with one field of the active configuration redrawn
 *   op % 8 == 6     set_config with a fresh configuration
 *   op % 8 == 7     p2d_speed_reset with random w_ref and T_init
 * The applied torque handed to p2d_speed_update is, by (op >> 3) % 4: the
 * controller's own T_ref (p2d_speed_step), T_ref scaled by a fraction in
 * [0, 1] (a later limit took some away), any torque in [-T_max, T_max], or
 * any float (NaN, inf, huge, out of the limit).
 *
 * Invariants, checked after every call (abort on violation):
 *  - init and set_config either accept or reject; a rejected call leaves the
 *    controller bit-identical and names a speed-controller parameter; an
 *    accepted configuration is inside the documented ranges, has finite
 *    coefficients (a probe sample of 1e-30 rad/s neither faults nor is
 *    refused), a feedforward pole strictly inside the unit circle and a
 *    back-calculation loop gain Ki Ka Ts in [0, 2); set_config gives the same
 *    status as init and a controller that computes the same outputs bit for
 *    bit, leaves the set that was in force untouched and keeps the state.
 *  - compute does not change the controller.
 *  - a non-finite input raises the fault flag; a fault gives zero torque and
 *    zero current; otherwise every output is finite, |T_ref| <= T_max,
 *    T_ref = Sat(T_unsat), ||i_dq|| <= i_max (1 + 4 FLT_EPSILON), id = 0 for
 *    a surface PMSM and iq has the sign of T_ref (unless T_ref is subnormal).
 *  - update with a fault or a non-finite applied torque only counts the fault;
 *    the state stays finite after every call (it is never poisoned).
 *  - integrator bounds for every accepted update (derivations in
 *    RELIABILITY.md), with g = Ki Ka Ts, b = b_e0 and u = b e + x[k-1] + T_ff:
 *      back calculation, 0 < g < 2: x[k] = (1 - g) x[k-1] + (Ki Ts - g b) e + g (T_app - T_ff),
 *      a contraction by |1 - g| < 1, so
 *        |x[k]| <= max(|x[k-1]|, (|Ki Ts - g b| |e| + g (|T_app| + |T_ff|)) / (1 - |1 - g|));
 *      clamping: x moves only while u has not passed T_app in the direction of e, so x[k]
 *        lies between x[k-1] and z = T_app + (Ki Ts - b) e - T_ff.
 *    With |T_app| <= T_max, |T_ff| <= F and |e| <= E both bounds stay finite for all k.
 *    Each is checked up to a float32 rounding slack of FZ_SUM_SLACK times the
 *    sum of the magnitudes of the terms that enter the update.
 *  - with torque filters (speed.h): the limit acts on the filtered command,
 *    T_ref = Sat(T_unsat) with T_unsat = u_f, and the update is
 *    x[k] = x[k-1] + Ki Ts e + g (T_app - u_f) + Fr0 dr (clamping: the
 *    integration held while T_app - u_f and e have opposite signs), up to the
 *    same slack; the contraction bound above does not apply, as the
 *    anti-windup loop runs through the filters (init checks it is stable).
 *    set_filter: atomic, the verdict and the coefficients of init followed by
 *    set_filter, the PI state kept, filter states kept where a section stays
 *    on and at rest at x[k-1] where one is switched on; reset puts the filters
 *    at rest at T_init.
 */
#include "fuzz_common.h"
#include "fuzz_speed_config.h"

#include "pmsm2dof/speed.h"

/* Plant and loop state of one fuzz input. */
typedef struct {
    p2d_speed_t ctl;  /* controller under test */
    double w_m_radps; /* plant speed of the closed-loop runs [rad/s] */
} fz_speed_rig_t;

/* Torque filters around a 40 Hz resonance: bit 0 of the shape byte a notch, bit 1 a low-pass. */
static void fz_filter_config(fz_reader_t *r, p2d_filter_config_t *f)
{
    uint8_t shape = fz_u8(r);
    memset(f, 0, sizeof *f);
    if (shape & 1u) {
        f->notch_freq_Hz = fz_float(r, 40.0, true);
        f->notch_width_Hz = fz_float(r, 15.0, true);
        f->notch_depth = fz_float(r, 0.05, true);
    }
    if (shape & 2u) {
        f->lowpass_freq_Hz = fz_float(r, 200.0, true);
        f->lowpass_zeta = fz_float(r, 0.7, true);
    }
}

/* A value near the current one (within two or eight decades), or any float. */
static float fz_near(fz_reader_t *r, float current, double fallback)
{
    double nominal = (isfinite(current) && current != 0.0f) ? fabs((double)current) : fallback;
    return fz_float(r, nominal, false);
}

/* The active configuration with one field redrawn. */
static void fz_speed_config_mutated(fz_reader_t *r, const p2d_speed_config_t *active, p2d_speed_config_t *cfg)
{
    *cfg = *active;
    switch (fz_u8(r) % 15u) {
    case 0: cfg->J_kgm2 = fz_near(r, cfg->J_kgm2, 0.4); break;
    case 1: cfg->alpha_radps = fz_near(r, cfg->alpha_radps, 20.0); break;
    case 2: cfg->zeta = fz_near(r, cfg->zeta, 1.0); break;
    case 3: cfg->m = fz_near(r, cfg->m, 1.0); break;
    case 4: cfg->tau_i_s = fz_near(r, cfg->tau_i_s, 0.005); break;
    case 5: cfg->Ka = fz_near(r, cfg->Ka, 0.1); break;
    case 6: cfg->Ts_s = fz_near(r, cfg->Ts_s, 1e-3); break;
    case 7: cfg->i_max_A = fz_near(r, cfg->i_max_A, 7.6); break;
    case 8: cfg->psi_f_Wb = fz_near(r, cfg->psi_f_Wb, 0.2); break;
    case 9: cfg->Ld_H = fz_near(r, cfg->Ld_H, 0.01); break;
    case 10: cfg->Lq_H = fz_near(r, cfg->Lq_H, 0.01); break;
    case 11: cfg->pole_pairs = fz_pole_pairs(r); break;
    case 12: cfg->method = (p2d_method_t)fz_enum(r, 3u); break;
    case 13: cfg->feedforward = (p2d_feedforward_t)fz_enum(r, 4u); break;
    default: cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u); break;
    }
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }
static bool fz_nonnegative(float x) { return isfinite(x) && x >= 0.0f; }

/* A rejection names one speed-controller parameter. */
static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status > P2D_OK && status < P2D_STATUS_COUNT && status != P2D_ERR_NULL && status != P2D_ERR_RS,
               "status %d", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

/* An accepted configuration is in the documented ranges and gives usable coefficients. */
static void fz_check_accepted(const p2d_speed_config_t *cfg, const p2d_speed_coef_t *c)
{
    FZ_REQUIRE(fz_positive(cfg->J_kgm2) && fz_positive(cfg->alpha_radps) && fz_positive(cfg->zeta) &&
                   fz_positive(cfg->m) && fz_nonnegative(cfg->tau_i_s) && fz_nonnegative(cfg->Ka) &&
                   fz_positive(cfg->Ts_s) && fz_positive(cfg->i_max_A) && fz_positive(cfg->psi_f_Wb) &&
                   fz_positive(cfg->Ld_H) && fz_positive(cfg->Lq_H) && cfg->pole_pairs >= 1u,
               "accepted a configuration outside the documented ranges");
    FZ_REQUIRE((unsigned)cfg->method <= 2u && (unsigned)cfg->feedforward <= 3u && (unsigned)cfg->anti_windup <= 2u,
               "accepted method %u feedforward %u anti_windup %u", (unsigned)cfg->method, (unsigned)cfg->feedforward,
               (unsigned)cfg->anti_windup);
    FZ_REQUIRE(cfg->feedforward != P2D_FF_LOWPASS || cfg->m == 1.0f, "lowpass with m = %g", (double)cfg->m);
    FZ_REQUIRE(isfinite(c->pi.b_e0) && isfinite(c->pi.Ki_Ts) && isfinite(c->pi.Ki_Ka_Ts) && isfinite(c->ff_a1) &&
                   isfinite(c->T_max_Nm),
               "non-finite coefficient: b_e0 %g Ki_Ts %g Ki_Ka_Ts %g ff_a1 %g T_max %g", (double)c->pi.b_e0,
               (double)c->pi.Ki_Ts, (double)c->pi.Ki_Ka_Ts, (double)c->ff_a1, (double)c->T_max_Nm);
    FZ_REQUIRE(c->T_max_Nm > 0.0f && c->i_max_A == cfg->i_max_A, "T_max %g i_max %g", (double)c->T_max_Nm,
               (double)c->i_max_A);
    /* the pole -a1 of the feedforward section must stay strictly inside the unit circle in float32 too */
    FZ_REQUIRE(cfg->feedforward == P2D_FF_NONE || fabsf(c->ff_a1) < 1.0f,
               "feedforward pole on or outside the unit circle: a1 = %.9g (m alpha Ts = %g)", (double)c->ff_a1,
               (double)cfg->m * (double)cfg->alpha_radps * (double)cfg->Ts_s);
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        FZ_REQUIRE(c->pi.Ki_Ka_Ts >= 0.0f && c->pi.Ki_Ka_Ts < 2.0f, "Ki Ka Ts = %g", (double)c->pi.Ki_Ka_Ts);
    } else {
        FZ_REQUIRE(c->pi.Ki_Ka_Ts == 0.0f, "Ki Ka Ts = %g without back calculation", (double)c->pi.Ki_Ka_Ts);
    }
    FZ_REQUIRE(c->clamping == (cfg->anti_windup == P2D_AW_CLAMPING), "clamping flag");
    FZ_REQUIRE(c->general_step == (c->salient || c->filtered), "general_step flag");
}

/* The torque filters in force are those of filter_config, on exactly when a frequency is not 0. */
static void fz_check_filter(const p2d_speed_t *ctl)
{
    const p2d_filter_coef_t *f = &ctl->filter_coef[ctl->active];
    const p2d_filter_config_t *cfg = &ctl->filter_config;
    FZ_REQUIRE(f->has_notch == (cfg->notch_freq_Hz != 0.0f) && f->has_lowpass == (cfg->lowpass_freq_Hz != 0.0f) &&
                   ctl->coef[ctl->active].filtered == (f->has_notch || f->has_lowpass),
               "torque filters on: notch %d low-pass %d, filtered %d", (int)f->has_notch, (int)f->has_lowpass,
               (int)ctl->coef[ctl->active].filtered);
}

static void fz_check_state_finite(const p2d_speed_t *ctl)
{
    const p2d_filter_coef_t *f = &ctl->filter_coef[ctl->active];
    FZ_REQUIRE(isfinite(ctl->x_Nm) && isfinite(ctl->r_prev_radps) && isfinite(ctl->y_ff_prev_Nm),
               "state poisoned: x %g r_prev %g y_ff_prev %g", (double)ctl->x_Nm, (double)ctl->r_prev_radps,
               (double)ctl->y_ff_prev_Nm);
    FZ_REQUIRE((!f->has_notch || (isfinite(ctl->filter.notch.s1) && isfinite(ctl->filter.notch.s2))) &&
                   (!f->has_lowpass || (isfinite(ctl->filter.lowpass.s1) && isfinite(ctl->filter.lowpass.s2))),
               "torque-filter state poisoned");
}

/* The largest magnitude of the torque-filter states [Nm]. */
static double fz_filter_magnitude(const p2d_speed_t *ctl)
{
    const p2d_filter_state_t *s = &ctl->filter;
    return fmax(fmax(fabs((double)s->notch.s1), fabs((double)s->notch.s2)),
                fmax(fabs((double)s->lowpass.s1), fabs((double)s->lowpass.s2)));
}

/*
 * A probe sample on a copy of an accepted controller, from a cleared state:
 * with inputs of 1e-30 no product of a finite coefficient overflows, so a
 * fault or a refused update can only come from a non-finite coefficient.
 */
static void fz_probe(const p2d_speed_t *ctl)
{
    p2d_speed_t copy;
    p2d_speed_output_t out;
    memcpy(&copy, ctl, sizeof copy);
    p2d_speed_reset(&copy, 0.0f, 0.0f);
    p2d_speed_step(&copy, 1e-30f, 0.0f, &out);
    FZ_REQUIRE(!out.fault && copy.fault_count == ctl->fault_count,
               "an accepted configuration faults on a 1e-30 rad/s "
               "probe (T_unsat %g): a coefficient is not finite",
               (double)out.T_unsat_Nm);
}

/*
 * a and b compute the same outputs, bit for bit, from the state of a, on a
 * few probe inputs: their active coefficient sets are equivalent.
 */
static bool fz_same_controller(const p2d_speed_t *a, const p2d_speed_t *b)
{
    static const float probes[5][2] = {{0.0f, 0.0f}, {100.0f, 90.0f}, {-50.0f, 10.0f}, {1e3f, -1e3f}, {1e-30f, 0.0f}};
    p2d_speed_t b_state;
    memcpy(&b_state, b, sizeof b_state);
    b_state.x_Nm = a->x_Nm;
    b_state.r_prev_radps = a->r_prev_radps;
    b_state.y_ff_prev_Nm = a->y_ff_prev_Nm;
    b_state.filter = a->filter;
    for (int k = 0; k < 5; ++k) {
        p2d_speed_output_t oa, ob;
        p2d_speed_compute(a, probes[k][0], probes[k][1], &oa);
        p2d_speed_compute(&b_state, probes[k][0], probes[k][1], &ob);
        if (!fz_bits_equal(oa.T_unsat_Nm, ob.T_unsat_Nm) || !fz_bits_equal(oa.T_ref_Nm, ob.T_ref_Nm) ||
            !fz_bits_equal(oa.id_ref_A, ob.id_ref_A) || !fz_bits_equal(oa.iq_ref_A, ob.iq_ref_A) ||
            !fz_bits_equal(oa.T_ff_Nm, ob.T_ff_Nm) || oa.fault != ob.fault) {
            return false;
        }
    }
    return true;
}

/* init: accept (finite, cleared state) or reject without writing. */
static bool fz_init(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    p2d_speed_t pattern;
    p2d_status_t status;
    memset(ctl, 0xa5, sizeof *ctl);
    memcpy(&pattern, ctl, sizeof pattern);
    status = p2d_speed_init(ctl, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(ctl, &pattern, sizeof pattern) == 0, "rejected init (status %d) wrote", (int)status);
        return false;
    }
    fz_check_accepted(cfg, &ctl->coef[ctl->active]);
    fz_probe(ctl);
    FZ_REQUIRE(!ctl->coef[ctl->active].filtered, "init switched a torque filter on");
    FZ_REQUIRE(ctl->x_Nm == 0.0f && ctl->r_prev_radps == 0.0f && ctl->y_ff_prev_Nm == 0.0f && ctl->fault_count == 0u,
               "init did not clear the state: x %g r_prev %g y_ff_prev %g", (double)ctl->x_Nm,
               (double)ctl->r_prev_radps, (double)ctl->y_ff_prev_Nm);
    return true;
}

/* init with cfg, then the torque filters f: the reference for set_config and set_filter. */
static p2d_status_t fz_init_filtered(p2d_speed_t *fresh, const p2d_speed_config_t *cfg, const p2d_filter_config_t *f)
{
    p2d_status_t status = p2d_speed_init(fresh, cfg);
    return status == P2D_OK ? p2d_speed_set_filter(fresh, f) : status;
}

/* set_config: atomic, same verdict and coefficients as init (with the torque filters in force), state kept. */
static void fz_set_config(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    p2d_speed_t before, fresh;
    p2d_status_t status, status_init;
    memcpy(&before, ctl, sizeof before);
    status_init = fz_init_filtered(&fresh, cfg, &ctl->filter_config);
    status = p2d_speed_set_config(ctl, cfg);
    FZ_REQUIRE(status == status_init, "set_config status %d, init status %d", (int)status, (int)status_init);
    if (status != P2D_OK) {
        FZ_REQUIRE(memcmp(ctl, &before, sizeof before) == 0, "rejected set_config (status %d) wrote", (int)status);
        return;
    }
    FZ_REQUIRE(ctl->active == 1u - before.active, "active %u -> %u", before.active, ctl->active);
    /* the set in force was not written while the shadow set was computed */
    FZ_REQUIRE(memcmp(&ctl->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0,
               "set_config wrote the coefficient set in force");
    FZ_REQUIRE(fz_same_controller(ctl, &fresh), "set_config and init computed different coefficients");
    fz_probe(ctl);
    FZ_REQUIRE(memcmp(&ctl->config, cfg, sizeof *cfg) == 0, "config not stored");
    FZ_REQUIRE(fz_bits_equal(ctl->x_Nm, before.x_Nm) && fz_bits_equal(ctl->r_prev_radps, before.r_prev_radps) &&
                   fz_bits_equal(ctl->y_ff_prev_Nm, before.y_ff_prev_Nm) && ctl->fault_count == before.fault_count &&
                   memcmp(&ctl->filter, &before.filter, sizeof ctl->filter) == 0,
               "set_config changed the state");
}

/* One section's state after set_filter: kept if it was on, at rest at x[k-1] if switched on. */
static bool fz_section_started(bool was_on, bool is_on, const p2d_biquad_state_t *s, const p2d_biquad_state_t *s0,
                               float x)
{
    if (!is_on) return true;
    if (was_on) return fz_bits_equal(s->s1, s0->s1) && fz_bits_equal(s->s2, s0->s2);
    return s->s1 == 0.0f && fz_bits_equal(s->s2, x);
}

/* set_filter: atomic, the verdict and coefficients of init + set_filter, the PI state kept, bumpless switch-on. */
static void fz_set_filter(p2d_speed_t *ctl, const p2d_filter_config_t *f)
{
    p2d_speed_t before, fresh;
    const p2d_filter_coef_t *old, *now;
    p2d_status_t status, status_init;
    memcpy(&before, ctl, sizeof before);
    status_init = fz_init_filtered(&fresh, &ctl->config, f);
    status = p2d_speed_set_filter(ctl, f);
    FZ_REQUIRE(status == status_init, "set_filter status %d, init + set_filter status %d", (int)status,
               (int)status_init);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(ctl, &before, sizeof before) == 0, "rejected set_filter (status %d) wrote", (int)status);
        return;
    }
    FZ_REQUIRE(ctl->active == 1u - before.active && memcmp(&ctl->filter_config, f, sizeof *f) == 0,
               "set_filter: active %u -> %u, or the configuration not stored", before.active, ctl->active);
    FZ_REQUIRE(memcmp(&ctl->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0 &&
                   memcmp(&ctl->filter_coef[before.active], &before.filter_coef[before.active],
                          sizeof before.filter_coef[0]) == 0,
               "set_filter wrote the coefficient set in force");
    fz_check_accepted(&ctl->config, &ctl->coef[ctl->active]);
    fz_check_filter(ctl);
    old = &before.filter_coef[before.active];
    now = &ctl->filter_coef[ctl->active];
    FZ_REQUIRE(fz_bits_equal(ctl->x_Nm, before.x_Nm) && fz_bits_equal(ctl->r_prev_radps, before.r_prev_radps) &&
                   fz_bits_equal(ctl->y_ff_prev_Nm, before.y_ff_prev_Nm) && ctl->fault_count == before.fault_count,
               "set_filter changed the PI state");
    FZ_REQUIRE(
        fz_section_started(old->has_notch, now->has_notch, &ctl->filter.notch, &before.filter.notch, before.x_Nm) &&
            fz_section_started(old->has_lowpass, now->has_lowpass, &ctl->filter.lowpass, &before.filter.lowpass,
                               before.x_Nm),
        "set_filter: a section kept on lost its state, or one switched on is not at rest at x = %g",
        (double)before.x_Nm);
    FZ_REQUIRE(fz_same_controller(ctl, &fresh), "set_filter and init + set_filter computed different coefficients");
    fz_probe(ctl);
}

/* The outputs of one compute. */
static void fz_check_output(const p2d_speed_t *ctl, float w_ref, float w_m, const p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    float T_sat;
    double i_norm;
    if (!isfinite(w_ref) || !isfinite(w_m)) {
        FZ_REQUIRE(out->fault, "non-finite input w_ref %g w_m %g without fault", (double)w_ref, (double)w_m);
    }
    if (out->fault) {
        FZ_REQUIRE(out->T_ref_Nm == 0.0f && out->id_ref_A == 0.0f && out->iq_ref_A == 0.0f && !out->saturated,
                   "fault output T %g id %g iq %g", (double)out->T_ref_Nm, (double)out->id_ref_A,
                   (double)out->iq_ref_A);
        return;
    }
    /*
     * the command does not use the static feedforward Fr0 r (the state holds it, speed.h): the
     * diagnostic T_ff = Fr0 r[k-1] + Fr0 dr + Kd dr + y[k] may overflow only where Fr0 r[k-1] or Fr0 r[k]
     * is out of the float32 range, or the sum of its terms (a transient y[k] near the range)
     */
    FZ_REQUIRE(isfinite(out->T_ff_Nm) ||
                   fmax(fabs((double)c->ff_Fr0 * (double)ctl->r_prev_radps), fabs((double)c->ff_Fr0 * (double)w_ref)) >
                       0.25 * FLT_MAX ||
                   fabs((double)c->ff_Fr0 * (double)ctl->r_prev_radps) +
                           (fabs((double)c->ff_Fr0) + fabs((double)c->ff_Kd_per_Ts)) *
                               fabs((double)w_ref - (double)ctl->r_prev_radps) +
                           fabs((double)out->y_ff_Nm) >
                       0.5 * FLT_MAX,
               "non-finite T_ff %g without fault (w_ref %g r_prev %g Fr0 %g y_ff %g)", (double)out->T_ff_Nm,
               (double)w_ref, (double)ctl->r_prev_radps, (double)c->ff_Fr0, (double)out->y_ff_Nm);
    FZ_REQUIRE(isfinite(out->T_unsat_Nm) && isfinite(out->T_ref_Nm) && isfinite(out->id_ref_A) &&
                   isfinite(out->iq_ref_A) && isfinite(out->e_radps) && isfinite(out->y_ff_Nm),
               "non-finite output without fault: T %g id %g iq %g (w_ref %g w_m %g; T_max %g, salient %d)",
               (double)out->T_ref_Nm, (double)out->id_ref_A, (double)out->iq_ref_A, (double)w_ref, (double)w_m,
               (double)c->T_max_Nm, (int)c->salient);
    /* u_sat = Sat(u) with the torque limit T_max */
    T_sat = out->T_unsat_Nm > c->T_max_Nm    ? c->T_max_Nm
            : out->T_unsat_Nm < -c->T_max_Nm ? -c->T_max_Nm
                                             : out->T_unsat_Nm;
    FZ_REQUIRE(out->T_ref_Nm == T_sat && out->saturated == (T_sat != out->T_unsat_Nm),
               "T_ref %g is not Sat(%g) with T_max %g", (double)out->T_ref_Nm, (double)out->T_unsat_Nm,
               (double)c->T_max_Nm);
    i_norm = hypot((double)out->id_ref_A, (double)out->iq_ref_A);
    FZ_REQUIRE(fz_within_circle(i_norm, ctl->config.i_max_A), "||i_dq|| = %.9g > i_max %.9g (id %g iq %g, salient %d)",
               i_norm, (double)ctl->config.i_max_A, (double)out->id_ref_A, (double)out->iq_ref_A, (int)c->salient);
    FZ_REQUIRE(c->salient || out->id_ref_A == 0.0f, "surface PMSM with id %g", (double)out->id_ref_A);
    /* a subnormal torque carries too few digits for the MTPA inversion to keep its sign */
    FZ_REQUIRE(fabsf(out->T_ref_Nm) < FLT_MIN || (double)out->iq_ref_A * (double)out->T_ref_Nm >= 0.0,
               "iq %g against T_ref %g", (double)out->iq_ref_A, (double)out->T_ref_Nm);
}

/* The update with T_app: fault handling, finiteness and the integrator bounds. */
static void fz_check_update(const p2d_speed_t *before, const p2d_speed_t *ctl, const p2d_speed_output_t *out,
                            float T_app)
{
    const p2d_speed_coef_t *c = &before->coef[before->active];
    /*
     * The state is x = x_i + Fr0 r[k-1]; the bounds below are on the integral x_i, exact in
     * double from the float32 state (a product of two floats is exact in double). The
     * realization through x rounds sums of magnitude |x| and |Fr0 r|: they join the slack.
     */
    double Fr0 = c->ff_Fr0, dr = (double)out->w_ref_radps - (double)before->r_prev_radps;
    double xs0 = before->x_Nm, xs1 = ctl->x_Nm;
    double x0 = xs0 - Fr0 * (double)before->r_prev_radps, x1 = xs1 - Fr0 * (double)ctl->r_prev_radps;
    double e = out->e_radps, T_ff = out->T_ff_Nm;
    double g = c->pi.Ki_Ka_Ts, kits = c->pi.Ki_Ts, b = c->pi.b_e0, T = T_app;
    double u_star = T - (double)out->T_unsat_Nm;
    double ff_sum = fabs(xs0) + fabs(Fr0 * (double)before->r_prev_radps) + fabs(Fr0 * (double)out->w_ref_radps) +
                    fabs(Fr0 * dr) + fabs((double)out->y_ff_Nm);
    double slack;
    fz_check_state_finite(ctl);
    if (ctl->fault_count != before->fault_count) {
        /* a rejected sample: only the counter moves */
        p2d_speed_t expected;
        memcpy(&expected, before, sizeof expected);
        expected.fault_count++;
        FZ_REQUIRE(memcmp(ctl, &expected, sizeof expected) == 0, "a rejected update changed the state");
        /*
         * refused only when a term of x[k-1] + Ki Ts e + g (T_app - T_unsat) + Fr0 dr comes near the float32 range,
         * or, with torque filters, one of their states or inputs (an overflow of the filters)
         */
        FZ_REQUIRE(out->fault || !isfinite(T_app) ||
                       fmax(fmax(fmax(fabs(xs0), fabs(kits * e)), fmax(fabs(u_star), fabs(g * u_star))),
                            fabs(Fr0 * dr)) > 0.25 * FLT_MAX ||
                       (c->filtered && fz_filter_may_overflow(
                                           &before->filter_coef[before->active],
                                           fmax(fmax(fz_filter_magnitude(before), fabs((double)out->T_unsat_Nm)),
                                                fabs(b * e) + fabs(xs0) + fabs(Fr0 * dr) +
                                                    fabs((double)c->ff_Kd_per_Ts * dr) + fabs((double)out->y_ff_Nm)))),
                   "update refused a sample whose new state is finite: x %g e %g Ki_Ts %g g %g T_app %g T_unsat %g "
                   "Fr0 dr %g",
                   xs0, e, kits, g, T, (double)out->T_unsat_Nm, Fr0 * dr);
        return;
    }
    FZ_REQUIRE(!out->fault && isfinite(T_app), "a fault or a non-finite applied torque %g was not counted", T);
    FZ_REQUIRE(ctl->r_prev_radps == out->w_ref_radps && ctl->y_ff_prev_Nm == out->y_ff_Nm,
               "feedforward state not advanced");
    if (c->filtered) {
        /* x[k] = x[k-1] + Ki Ts e + g u* + Fr0 dr, u* = T_app - u_f; clamping holds the integration (speed.h) */
        double dx = kits * e + g * u_star;
        if (c->clamping && ((u_star < 0.0 && e > 0.0) || (u_star > 0.0 && e < 0.0))) dx = 0.0;
        slack = fz_slack(fabs(xs0) + fabs(kits * e) + g * (fabs(T) + fabs((double)out->T_unsat_Nm)) + fabs(Fr0 * dr) +
                         fabs(xs1));
        FZ_REQUIRE(fabs(xs1 - (xs0 + dx + Fr0 * dr)) <= slack,
                   "filtered update: x %.9g -> %.9g, expected %.9g (e %g T_app %g u_f %g g %g clamping %d)", xs0, xs1,
                   xs0 + dx + Fr0 * dr, e, T, (double)out->T_unsat_Nm, g, (int)c->clamping);
    } else if (c->pi.Ki_Ka_Ts > 0.0f) {
        /* x[k] = (1 - g) x[k-1] + (Ki Ts - g b) e + g (T_app - T_ff): a contraction by |1 - g| < 1 */
        double bound = (fabs(kits - g * b) * fabs(e) + g * (fabs(T) + fabs(T_ff))) / (1.0 - fabs(1.0 - g));
        slack = fz_slack(fabs(x0) + fabs(kits * e) + g * (fabs(T) + fabs(b * e) + fabs(x0) + fabs(T_ff)) +
                         (1.0 + g) * ff_sum + fabs(xs1));
        FZ_REQUIRE(fabs(x1) <= fmax(fabs(x0), bound) + slack,
                   "back calculation: |x| %.9g -> %.9g above the bound %.9g (g %g e %g T_app %g T_ff %g)", x0, x1,
                   bound, g, e, T, T_ff);
    } else if (c->clamping) {
        /* x moves towards z only while u has not passed T_app (see above) */
        double z = T + (kits - b) * e - T_ff;
        slack = fz_slack(fabs(x0) + fabs(b * e) + fabs(kits * e) + fabs(T_ff) + fabs(T) + ff_sum + fabs(xs1));
        FZ_REQUIRE(x1 <= fmax(x0, z) + slack && x1 >= fmin(x0, z) - slack,
                   "clamping: x %.9g -> %.9g passed z = %.9g (e %g T_app %g T_unsat %g T_ff %g)", x0, x1, z, e, T,
                   (double)out->T_unsat_Nm, T_ff);
    }
}

/* One sample with the applied torque chosen by mode. */
static float fz_sample(fz_speed_rig_t *rig, fz_reader_t *r, unsigned mode, double fraction, float w_ref, float w_m)
{
    p2d_speed_t before;
    p2d_speed_output_t out;
    float T_app, T_max = rig->ctl.coef[rig->ctl.active].T_max_Nm;
    memcpy(&before, &rig->ctl, sizeof before);
    if (mode == 0u) {
        p2d_speed_step(&rig->ctl, w_ref, w_m, &out);
        T_app = out.T_ref_Nm;
    } else {
        p2d_speed_compute(&rig->ctl, w_ref, w_m, &out);
        FZ_REQUIRE(memcmp(&rig->ctl, &before, sizeof before) == 0, "compute changed the controller");
        if (mode == 1u) {
            T_app = (float)(fraction * (double)out.T_ref_Nm);
        } else if (mode == 2u) {
            T_app = (float)((2.0 * fraction - 1.0) * (double)T_max);
        } else {
            T_app = fz_float(r, (double)T_max, true);
        }
        p2d_speed_update(&rig->ctl, &out, T_app);
    }
    fz_check_output(&before, w_ref, w_m, &out);
    fz_check_update(&before, &rig->ctl, &out, T_app);
    return out.fault ? 0.0f : T_app;
}

/* Closed loop on J_plant dw/dt = T_applied - T_load for 1..2048 samples. */
static void fz_closed_loop(fz_speed_rig_t *rig, fz_reader_t *r)
{
    uint32_t n = 1u + fz_u16(r) % 2048u;
    float w_ref = fz_float(r, 100.0, true);
    float T_load = fz_float(r, 1.0, true);
    unsigned mode = fz_u8(r) % 3u;
    double fraction = fz_unit(r);
    double J_plant = (double)rig->ctl.config.J_kgm2 * pow(10.0, fz_unit(r) - 0.5);
    double Ts = rig->ctl.config.Ts_s;
    if (!isfinite(rig->w_m_radps)) rig->w_m_radps = 0.0;
    for (uint32_t k = 0; k < n; ++k) {
        float T_app = fz_sample(rig, r, mode, fraction, w_ref, (float)rig->w_m_radps);
        rig->w_m_radps += Ts / J_plant * ((double)T_app - (double)T_load);
    }
}

/* p2d_speed_reset: coefficients untouched, state finite. */
static void fz_reset(p2d_speed_t *ctl, fz_reader_t *r)
{
    float w_ref = fz_float(r, 100.0, true);
    float T_init = fz_float(r, 1.0, true);
    p2d_speed_t before;
    memcpy(&before, ctl, sizeof before);
    p2d_speed_reset(ctl, w_ref, T_init);
    FZ_REQUIRE(memcmp(ctl->coef, before.coef, sizeof before.coef) == 0 && ctl->active == before.active,
               "reset changed the coefficients");
    fz_check_state_finite(ctl);
    if (ctl->fault_count == before.fault_count) {
        FZ_REQUIRE(isfinite(w_ref) && isfinite(T_init) && ctl->r_prev_radps == w_ref,
                   "reset(%g, %g) accepted: r_prev %g", (double)w_ref, (double)T_init, (double)ctl->r_prev_radps);
        FZ_REQUIRE(ctl->filter.notch.s1 == 0.0f && ctl->filter.notch.s2 == T_init && ctl->filter.lowpass.s1 == 0.0f &&
                       ctl->filter.lowpass.s2 == T_init,
                   "reset(%g, %g): the torque filters are not at rest at T_init", (double)w_ref, (double)T_init);
    } else {
        FZ_REQUIRE(ctl->fault_count == before.fault_count + 1u && ctl->x_Nm == 0.0f && ctl->r_prev_radps == 0.0f &&
                       ctl->y_ff_prev_Nm == 0.0f,
                   "a refused reset(%g, %g) must clear the state and count one fault", (double)w_ref, (double)T_init);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_speed_rig_t rig;
    p2d_speed_config_t cfg;

    FZ_REQUIRE(p2d_speed_init(NULL, &cfg) == P2D_ERR_NULL && p2d_speed_set_config(&rig.ctl, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_speed_config(&r, &cfg);
    if (!fz_init(&rig.ctl, &cfg)) return 0;
    rig.w_m_radps = 0.0;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 3: {
            p2d_filter_config_t f;
            fz_filter_config(&r, &f);
            fz_set_filter(&rig.ctl, &f);
            break;
        }
        case 4: fz_closed_loop(&rig, &r); break;
        case 5:
            fz_speed_config_mutated(&r, &rig.ctl.config, &cfg);
            fz_set_config(&rig.ctl, &cfg);
            break;
        case 6:
            fz_speed_config(&r, &cfg);
            fz_set_config(&rig.ctl, &cfg);
            break;
        case 7: fz_reset(&rig.ctl, &r); break;
        default: {
            float w_ref = fz_float(&r, 100.0, true);
            float w_m = fz_float(&r, 100.0, true);
            double fraction = fz_unit(&r);
            fz_sample(&rig, &r, (op >> 3) % 4u, fraction, w_ref, w_m);
            break;
        }
        }
    }
    return 0;
}
