/*
 * libFuzzer target: the online inertia and load estimator (pmsm2dof/inertia.h),
 * built with -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a configuration, valid or not, and
 * then to operations until the bytes run out:
 *   op % 8 in 0..3  one sample: speed and torque drawn at random (any float)
 *   op % 8 == 4     a closed-loop run of 1..2048 samples on a rigid drive
 *                   J dw/dt = T - B w - T_load (forward Euler, double) under a
 *                   PI speed controller on a square-wave reference, J from
 *                   J0/30 to 30 J0, optionally with an encoder (speed from
 *                   counts differenced over Ts) and torque noise
 *   op % 8 == 5     set_config with one field of the active configuration redrawn
 *   op % 8 == 6     set_config with a fresh configuration
 *   op % 8 == 7     p2d_inertia_reset, keeping the estimate or not
 *
 * Invariants, checked after every call (abort on violation):
 *  - init and set_config either accept or reject; a rejected call leaves the
 *    estimator bit-identical and names an estimator parameter; an accepted
 *    configuration is inside the documented ranges and has finite
 *    coefficients (c_f in (0, 1], g_J in (1, 2], q_L >= 0); set_config gives
 *    the coefficients init gives and keeps the state.
 *  - a non-finite input raises the fault flag; a fault changes nothing but
 *    fault_count (+1) and primed (false); a sample without fault leaves
 *    fault_count alone.
 *  - the state stays finite after every call (never poisoned), D stays
 *    positive and normal (P = U D U' positive definite), 1F stays in [0, 1].
 *  - no covariance windup: after an update each variance P_ii is within its
 *    prior variance in the active configuration, up to the float32 rounding
 *    of the scaling that brings it back (a relative 1e-6).
 *  - the outputs are finite and within the plausible box of the active
 *    configuration; J_valid only with sd(J) <= J_rel_sd_max J and the
 *    estimate strictly inside [J_min, J_max]; a fault is never valid nor
 *    updated; an update has a positive predicted residual spread.
 */
#include "fuzz_common.h"

#include "pmsm2dof/inertia.h"

/* Relative slack of the covariance bounds: the float32 rounding of the scaling back onto the prior. */
#define FZ_P_SLACK 1e-6

/* Estimator and drive of one fuzz input. */
typedef struct {
    p2d_inertia_t est; /* estimator under test */
    double w_radps;    /* drive speed [rad/s] */
    double theta_rad;  /* drive angle [rad] */
    double x_Nm;       /* integrator of the drive's PI [Nm] */
    double T_Nm;       /* torque applied over the current period [Nm] */
    double count_prev; /* encoder count at the previous sample [-] */
    uint64_t noise;    /* state of the noise generator */
} fz_inertia_rig_t;

/*
 * A configuration around a small servo (J0 = 0.01 kg m^2, 2 Nm) at 1 kHz;
 * bit 0 of the shape byte selects a period-mean speed.
 */
static void fz_inertia_config(fz_reader_t *r, p2d_inertia_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    memset(cfg, 0, sizeof *cfg);
    cfg->Ts_s = fz_float(r, 1e-3, false);
    cfg->J0_kgm2 = fz_float(r, 0.01, false);
    cfg->J_min_kgm2 = fz_float(r, 0.001, false);
    cfg->J_max_kgm2 = fz_float(r, 0.1, false);
    cfg->B_max_Nms = fz_float(r, 0.01, false);
    cfg->T_load_max_Nm = fz_float(r, 2.0, false);
    cfg->sigma_T_Nm = fz_float(r, 0.05, false);
    cfg->J_memory_s = fz_float(r, 10.0, false);
    cfg->load_memory_s = fz_float(r, 0.5, false);
    cfg->w_f_radps = fz_float(r, 20.0, false);
    cfg->J_rel_sd_max = fz_float(r, 0.05, false);
    cfg->speed_is_period_mean = (shape & 1u) != 0u;
}

/* A value near the current one (within two or eight decades), or any float. */
static float fz_near(fz_reader_t *r, float current, double fallback)
{
    double nominal = (isfinite(current) && current != 0.0f) ? fabs((double)current) : fallback;
    return fz_float(r, nominal, false);
}

/* The active configuration with one field redrawn. */
static void fz_inertia_config_mutated(fz_reader_t *r, const p2d_inertia_config_t *active, p2d_inertia_config_t *cfg)
{
    *cfg = *active;
    switch (fz_u8(r) % 12u) {
    case 0: cfg->Ts_s = fz_near(r, cfg->Ts_s, 1e-3); break;
    case 1: cfg->J0_kgm2 = fz_near(r, cfg->J0_kgm2, 0.01); break;
    case 2: cfg->J_min_kgm2 = fz_near(r, cfg->J_min_kgm2, 0.001); break;
    case 3: cfg->J_max_kgm2 = fz_near(r, cfg->J_max_kgm2, 0.1); break;
    case 4: cfg->B_max_Nms = fz_near(r, cfg->B_max_Nms, 0.01); break;
    case 5: cfg->T_load_max_Nm = fz_near(r, cfg->T_load_max_Nm, 2.0); break;
    case 6: cfg->sigma_T_Nm = fz_near(r, cfg->sigma_T_Nm, 0.05); break;
    case 7: cfg->J_memory_s = fz_near(r, cfg->J_memory_s, 10.0); break;
    case 8: cfg->load_memory_s = fz_near(r, cfg->load_memory_s, 0.5); break;
    case 9: cfg->w_f_radps = fz_near(r, cfg->w_f_radps, 20.0); break;
    case 10: cfg->J_rel_sd_max = fz_near(r, cfg->J_rel_sd_max, 0.05); break;
    default: cfg->speed_is_period_mean = !cfg->speed_is_period_mean; break;
    }
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }

/* P_LL, P_JJ, P_BB of P = U D U' (order T_load, J, B), in double. */
static void fz_variances(const p2d_inertia_t *e, double P[3])
{
    double U_LJ = e->U_LJ_per_s2, U_LB = e->U_LB_per_s, U_JB = e->U_JB_s;
    P[0] = e->D_L_N2m2 + U_LJ * U_LJ * e->D_J_kg2m4 + U_LB * U_LB * e->D_B_N2m2s2;
    P[1] = e->D_J_kg2m4 + U_JB * U_JB * e->D_B_N2m2s2;
    P[2] = e->D_B_N2m2s2;
}

/* A rejection names one estimator parameter. */
static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status == P2D_ERR_TS || (status >= P2D_ERR_J0 && status <= P2D_ERR_J_REL_SD_MAX), "status %d",
               (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

/* An accepted configuration is in the documented ranges and gives usable coefficients. */
static void fz_check_accepted(const p2d_inertia_config_t *cfg, const p2d_inertia_coef_t *c)
{
    double r_J = (double)cfg->Ts_s / (double)cfg->J_memory_s, r_L = (double)cfg->Ts_s / (double)cfg->load_memory_s;
    FZ_REQUIRE(fz_positive(cfg->Ts_s) && fz_positive(cfg->J0_kgm2) && fz_positive(cfg->J_min_kgm2) &&
                   cfg->J_min_kgm2 <= cfg->J0_kgm2 && isfinite(cfg->J_max_kgm2) && cfg->J_max_kgm2 >= cfg->J0_kgm2 &&
                   fz_positive(cfg->B_max_Nms) && fz_positive(cfg->T_load_max_Nm) && fz_positive(cfg->sigma_T_Nm) &&
                   fz_positive(cfg->w_f_radps) && fz_positive(cfg->J_rel_sd_max) && cfg->J_rel_sd_max < 1.0f,
               "accepted a configuration outside the documented ranges");
    FZ_REQUIRE(r_J >= 0.999e-6 && r_J <= 0.5001 && r_L >= 0.999e-6 && r_L <= 0.5001,
               "accepted memories J %g load %g with Ts %g", (double)cfg->J_memory_s, (double)cfg->load_memory_s,
               (double)cfg->Ts_s);
    FZ_REQUIRE(c->c_f > 0.0f && c->c_f <= 1.0f && c->g_J > 1.0f && c->g_J <= 2.0f && isfinite(c->q_L_N2m2) &&
                   c->q_L_N2m2 >= 0.0f && isfinite(c->inv_Ts_per_s) && c->sigma2_N2m2 >= 0x1p-126f &&
                   isfinite(c->sigma2_N2m2) && c->sigma2_F_N2m2 > 0.0f && c->var0_J_kg2m4 >= 0x1p-126f &&
                   c->var0_B_N2m2s2 >= 0x1p-126f && c->var0_L_N2m2 >= 0x1p-126f && isfinite(c->var0_J_kg2m4) &&
                   isfinite(c->var0_B_N2m2s2) && isfinite(c->var0_L_N2m2) && isfinite(c->inv_s_J),
               "unusable coefficients: c_f %g g_J %g q_L %g", (double)c->c_f, (double)c->g_J, (double)c->q_L_N2m2);
}

/* The state is finite and P = U D U' positive definite. */
static void fz_check_state(const p2d_inertia_t *e)
{
    FZ_REQUIRE(isfinite(e->J_kgm2) && isfinite(e->B_Nms) && isfinite(e->T_load_Nm) && isfinite(e->U_LJ_per_s2) &&
                   isfinite(e->U_LB_per_s) && isfinite(e->U_JB_s) && isfinite(e->wF_radps) && isfinite(e->w0_radps) &&
                   isfinite(e->TF_Nm) && isfinite(e->T_prev_Nm) && isfinite(e->nis) && e->nis >= 0.0f,
               "state poisoned: J %g B %g T_load %g nis %g", (double)e->J_kgm2, (double)e->B_Nms, (double)e->T_load_Nm,
               (double)e->nis);
    FZ_REQUIRE(e->D_L_N2m2 >= 0x1p-126f && e->D_J_kg2m4 >= 0x1p-126f && e->D_B_N2m2s2 >= 0x1p-126f &&
                   e->D_L_N2m2 < INFINITY && e->D_J_kg2m4 < INFINITY && e->D_B_N2m2s2 < INFINITY,
               "D not positive and normal: %g %g %g", (double)e->D_L_N2m2, (double)e->D_J_kg2m4, (double)e->D_B_N2m2s2);
    FZ_REQUIRE(e->oneF >= 0.0f && e->oneF <= 1.0f, "1F = %g", (double)e->oneF);
}

/* No covariance windup: after an update, every variance within its prior. */
static void fz_check_bounds(const p2d_inertia_t *e)
{
    const p2d_inertia_coef_t *c = &e->coef[e->active];
    const double var0[3] = {c->var0_L_N2m2, c->var0_J_kg2m4, c->var0_B_N2m2s2};
    double P[3];
    fz_variances(e, P);
    for (int i = 0; i < 3; ++i) {
        FZ_REQUIRE(P[i] <= var0[i] * (1.0 + FZ_P_SLACK), "variance %d = %.9g above its prior %.9g", i, P[i], var0[i]);
    }
}

/* An accepted init or set_config. */
static void fz_accepted(fz_inertia_rig_t *rig, const p2d_inertia_config_t *cfg)
{
    p2d_inertia_t fresh;
    fz_check_accepted(cfg, &rig->est.coef[rig->est.active]);
    FZ_REQUIRE(p2d_inertia_init(&fresh, cfg) == P2D_OK, "init rejects what set_config accepted");
    FZ_REQUIRE(memcmp(&fresh.coef[0], &rig->est.coef[rig->est.active], sizeof fresh.coef[0]) == 0,
               "set_config computes other coefficients than init");
    FZ_REQUIRE(memcmp(&fresh.coef[0], &fresh.coef[1], sizeof fresh.coef[0]) == 0, "init: the two sets differ");
}

static bool fz_init(fz_inertia_rig_t *rig, const p2d_inertia_config_t *cfg)
{
    p2d_inertia_t before;
    p2d_status_t status;
    memset(&rig->est, 0xa5, sizeof rig->est);
    memcpy(&before, &rig->est, sizeof before);
    status = p2d_inertia_init(&rig->est, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(&before, &rig->est, sizeof before) == 0, "a rejected init changed the estimator");
        return false;
    }
    fz_accepted(rig, cfg);
    fz_check_state(&rig->est);
    return true;
}

static void fz_set_config(fz_inertia_rig_t *rig, const p2d_inertia_config_t *cfg)
{
    p2d_inertia_t before;
    p2d_status_t status;
    memcpy(&before, &rig->est, sizeof before);
    status = p2d_inertia_set_config(&rig->est, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(&before, &rig->est, sizeof before) == 0, "a rejected set_config changed the estimator");
        return;
    }
    fz_accepted(rig, cfg);
    FZ_REQUIRE(memcmp(&before.coef[before.active], &rig->est.coef[before.active], sizeof before.coef[0]) == 0,
               "set_config changed the set in force");
    FZ_REQUIRE(rig->est.active != before.active, "set_config did not swap");
    /* the state: every field after the configuration */
    FZ_REQUIRE(memcmp(&before.J_kgm2, &rig->est.J_kgm2, sizeof before - offsetof(p2d_inertia_t, J_kgm2)) == 0,
               "set_config changed the state");
}

static void fz_reset(fz_inertia_rig_t *rig, fz_reader_t *r)
{
    bool keep = (fz_u8(r) & 1u) != 0u;
    p2d_inertia_t before;
    memcpy(&before, &rig->est, sizeof before);
    p2d_inertia_reset(&rig->est, keep);
    FZ_REQUIRE(!rig->est.primed && rig->est.fault_count == before.fault_count, "reset: primed or fault_count");
    if (keep) {
        before.primed = false;
        FZ_REQUIRE(memcmp(&before, &rig->est, sizeof before) == 0, "reset(keep) changed more than the prefilter");
    } else {
        FZ_REQUIRE(rig->est.J_kgm2 == rig->est.config.J0_kgm2 && rig->est.B_Nms == 0.0f && rig->est.T_load_Nm == 0.0f &&
                       rig->est.nis == 1.0f,
                   "reset to the prior");
    }
    fz_check_state(&rig->est);
}

/* One sample with its checks; returns the output. */
static p2d_inertia_output_t fz_sample(fz_inertia_rig_t *rig, float w_m, float T_e)
{
    p2d_inertia_t before;
    p2d_inertia_output_t out;
    const p2d_inertia_coef_t *c = &rig->est.coef[rig->est.active];
    memcpy(&before, &rig->est, sizeof before);
    p2d_inertia_step(&rig->est, w_m, T_e, &out);

    if (!isfinite(w_m) || !isfinite(T_e)) {
        FZ_REQUIRE(out.fault, "non-finite input %g %g without fault", (double)w_m, (double)T_e);
    }
    if (out.fault) {
        p2d_inertia_t expected;
        memcpy(&expected, &before, sizeof expected);
        expected.fault_count++;
        expected.primed = false;
        FZ_REQUIRE(memcmp(&expected, &rig->est, sizeof expected) == 0, "a fault changed the estimate");
        FZ_REQUIRE(!out.J_valid && !out.updated, "a fault output is valid or updated");
    } else {
        FZ_REQUIRE(rig->est.fault_count == before.fault_count, "fault_count moved without fault");
        FZ_REQUIRE(out.updated == before.primed, "updated %d with primed %d", (int)out.updated, (int)before.primed);
    }
    fz_check_state(&rig->est);
    if (out.updated) fz_check_bounds(&rig->est);
    FZ_REQUIRE(isfinite(out.J_kgm2) && isfinite(out.J_sd_kgm2) && out.J_sd_kgm2 >= 0.0f && isfinite(out.B_Nms) &&
                   isfinite(out.T_load_Nm) && isfinite(out.residual_Nm) && isfinite(out.residual_sd_Nm),
               "non-finite output: J %g sd %g B %g T_load %g", (double)out.J_kgm2, (double)out.J_sd_kgm2,
               (double)out.B_Nms, (double)out.T_load_Nm);
    FZ_REQUIRE(out.J_kgm2 >= c->J_min_kgm2 && out.J_kgm2 <= c->J_max_kgm2 && out.B_Nms >= 0.0f &&
                   out.B_Nms <= c->B_max_Nms && fabsf(out.T_load_Nm) <= c->T_load_max_Nm,
               "output outside the plausible box: J %g B %g T_load %g", (double)out.J_kgm2, (double)out.B_Nms,
               (double)out.T_load_Nm);
    if (out.J_valid) {
        FZ_REQUIRE(out.J_sd_kgm2 <= c->J_rel_sd_max * rig->est.J_kgm2 && rig->est.J_kgm2 > c->J_min_kgm2 &&
                       rig->est.J_kgm2 < c->J_max_kgm2,
                   "J_valid with sd %g, J %g in [%g, %g]", (double)out.J_sd_kgm2, (double)rig->est.J_kgm2,
                   (double)c->J_min_kgm2, (double)c->J_max_kgm2);
    }
    if (out.updated) FZ_REQUIRE(out.residual_sd_Nm > 0.0f, "update with residual sd %g", (double)out.residual_sd_Nm);
    return out;
}

/* uniform in [0, 1) from a 64-bit xorshift */
static double fz_noise_unit(fz_inertia_rig_t *rig)
{
    rig->noise ^= rig->noise >> 12;
    rig->noise ^= rig->noise << 25;
    rig->noise ^= rig->noise >> 27;
    return (double)((rig->noise * 0x2545F4914F6CDD1Dull) >> 11) / 9007199254740992.0;
}

/*
 * Closed loop on a rigid drive: a PI (eq 9, zeta = 1) on a square-wave
 * reference, the torque limited to T_max, forward Euler in 10 substeps.
 */
static void fz_closed_loop(fz_inertia_rig_t *rig, fz_reader_t *r)
{
    const p2d_inertia_config_t *cfg = &rig->est.config;
    uint32_t n = 1u + fz_u16(r) % 2048u;
    double J = (double)cfg->J0_kgm2 * pow(30.0, 2.0 * fz_unit(r) - 1.0);
    double B = (double)cfg->B_max_Nms * fz_unit(r);
    double T_load = (double)fz_float(r, 0.3, true);
    double w_amp = (double)fz_float(r, 100.0, false);
    double T_max = (double)fz_float(r, 2.0, false);
    double alpha = 10.0 + 100.0 * fz_unit(r);
    double T_noise = 0.05 * fz_unit(r);
    double counts_per_rad = (fz_u8(r) & 1u) ? 16384.0 / (2.0 * 3.14159265358979) : 0.0;
    uint32_t half_period = 1u + fz_u16(r) % 1000u;
    double Ts = cfg->Ts_s, h, Kp = J * alpha, Ki = J * alpha * alpha / 4.0;
    if (!(Ts > 0.0 && Ts < 1.0)) Ts = 1e-3;
    h = Ts / 10.0;
    if (!isfinite(rig->w_radps) || !isfinite(rig->theta_rad) || fabs(rig->w_radps) > 1e6) {
        rig->w_radps = 0.0;
        rig->theta_rad = 0.0;
        rig->x_Nm = 0.0;
        rig->T_Nm = 0.0;
        rig->count_prev = 0.0;
    }
    for (uint32_t k = 0; k < n; ++k) {
        double w_m = rig->w_radps, ref = (k / half_period) % 2u ? w_amp : -0.5 * w_amp, e, u, T;
        if (counts_per_rad > 0.0) {
            double count = floor(rig->theta_rad * counts_per_rad);
            w_m = (count - rig->count_prev) / (counts_per_rad * Ts);
            rig->count_prev = count;
        }
        (void)fz_sample(rig, (float)w_m, (float)(rig->T_Nm + T_noise * (2.0 * fz_noise_unit(rig) - 1.0)));
        e = ref - w_m;
        u = Kp * e + rig->x_Nm;
        T = u > T_max ? T_max : (u < -T_max ? -T_max : u);
        rig->x_Nm += Ki * Ts * (e + (T - u) / Kp);
        if (!isfinite(rig->x_Nm)) rig->x_Nm = 0.0;
        rig->T_Nm = T;
        for (int i = 0; i < 10; ++i) {
            rig->theta_rad += h * rig->w_radps;
            rig->w_radps += h / J * (T - B * rig->w_radps - T_load);
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_inertia_rig_t rig;
    p2d_inertia_config_t cfg;

    FZ_REQUIRE(p2d_inertia_init(NULL, &cfg) == P2D_ERR_NULL && p2d_inertia_set_config(&rig.est, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_inertia_config(&r, &cfg);
    if (!fz_init(&rig, &cfg)) return 0;
    rig.w_radps = 0.0;
    rig.theta_rad = 0.0;
    rig.x_Nm = 0.0;
    rig.T_Nm = 0.0;
    rig.count_prev = 0.0;
    rig.noise = 0x9E3779B97F4A7C15ull;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 4: fz_closed_loop(&rig, &r); break;
        case 5:
            fz_inertia_config_mutated(&r, &rig.est.config, &cfg);
            fz_set_config(&rig, &cfg);
            break;
        case 6:
            fz_inertia_config(&r, &cfg);
            fz_set_config(&rig, &cfg);
            break;
        case 7: fz_reset(&rig, &r); break;
        default: {
            float w_m = fz_float(&r, 100.0, true);
            float T_e = fz_float(&r, 1.0, true);
            (void)fz_sample(&rig, w_m, T_e);
            break;
        }
        }
    }
    return 0;
}
