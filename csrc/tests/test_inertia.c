/*
 * Unit tests of the inertia estimator (pmsm2dof/inertia.h). The truth is a
 * rigid drive J dw/dt = T - B w - T_load simulated here in double, solved
 * exactly over each period of constant torque, in closed loop with a PI speed
 * controller written here; and the estimator's recursion written again here in
 * double in covariance form (P, not its U D U' factors).
 */
#include <float.h>
#include <stdint.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/inertia.h"

#define PI_D 3.14159265358979323846

/* A 1 kHz speed loop of a small servo: J around 0.01 kg m^2, 2 Nm peak. */
static p2d_inertia_config_t nominal_config(void)
{
    p2d_inertia_config_t cfg;
    cfg.Ts_s = 1e-3f;
    cfg.J0_kgm2 = 0.02f;
    cfg.J_min_kgm2 = 0.002f;
    cfg.J_max_kgm2 = 0.2f;
    cfg.B_max_Nms = 0.01f;
    cfg.T_load_max_Nm = 2.0f;
    cfg.sigma_T_Nm = 0.05f;
    cfg.J_memory_s = 10.0f;
    cfg.load_memory_s = 0.5f;
    cfg.w_f_radps = 20.0f;
    cfg.J_rel_sd_max = 0.05f;
    cfg.speed_is_period_mean = false;
    return cfg;
}

static p2d_status_t init_with(p2d_inertia_config_t cfg)
{
    p2d_inertia_t est;
    return p2d_inertia_init(&est, &cfg);
}

/* ---------------------------------------------------------------------------------------------- */
/* the rigid drive in closed loop (double)                                                          */
/* ---------------------------------------------------------------------------------------------- */

typedef struct {
    double J_kgm2, B_Nms, T_load_Nm; /* plant */
    double w_radps, theta_rad;       /* shaft state */
    double Ts_s;                     /* period */
    double Kp, Ki, x_Nm, T_max_Nm;   /* PI speed controller, back calculation Ka = 1/Kp */
    double counts_per_rad;           /* encoder counts per rad; 0: the speed is sampled exactly */
    double count_prev;               /* encoder count at the previous sample */
    double T_noise_Nm;               /* standard deviation of the torque measurement noise */
    uint64_t rng;                    /* state of the noise generator */
    double T_cmd_Nm;                 /* torque applied over the current period */
} drive_t;

static drive_t drive_new(double J, double B, double T_load, double alpha)
{
    drive_t d;
    memset(&d, 0, sizeof d);
    d.J_kgm2 = J;
    d.B_Nms = B;
    d.T_load_Nm = T_load;
    d.Ts_s = 1e-3;
    /* eq 9 with zeta = 1: Kp = J alpha, Ki = J alpha^2 / 4 */
    d.Kp = J * alpha;
    d.Ki = J * alpha * alpha / 4.0;
    d.T_max_Nm = 2.0;
    d.rng = 0x2545F4914F6CDD1Dull;
    return d;
}

/* uniform in (0, 1), xorshift64* */
static double uniform(drive_t *d)
{
    d->rng ^= d->rng >> 12;
    d->rng ^= d->rng << 25;
    d->rng ^= d->rng >> 27;
    return ((double)((d->rng * 0x2545F4914F6CDD1Dull) >> 11) + 0.5) / 9007199254740992.0;
}

/* standard normal (Box-Muller) */
static double normal(drive_t *d)
{
    double u1 = uniform(d), u2 = uniform(d);
    return sqrt(-2.0 * log(u1)) * cos(2.0 * PI_D * u2);
}

/*
 * One period with the torque T held: J dw/dt = T - B w - T_load solved exactly,
 * w(t) = w_ss + (w0 - w_ss) exp(-t/tau), tau = J/B, w_ss = (T - T_load)/B.
 */
static void drive_advance(drive_t *d, double T)
{
    double tau = d->J_kgm2 / d->B_Nms, w_ss = (T - d->T_load_Nm) / d->B_Nms, h = d->Ts_s;
    double decay = -expm1(-h / tau); /* 1 - exp(-h/tau) */
    d->theta_rad += w_ss * h + (d->w_radps - w_ss) * tau * decay;
    d->w_radps = w_ss + (d->w_radps - w_ss) * (1.0 - decay);
}

/* The speed measurement at this sample: exact, or counts differenced over the period (its mean). */
static double drive_measure(drive_t *d)
{
    double count, w;
    if (d->counts_per_rad == 0.0) return d->w_radps;
    count = floor(d->theta_rad * d->counts_per_rad);
    w = (count - d->count_prev) / (d->counts_per_rad * d->Ts_s);
    d->count_prev = count;
    return w;
}

/* The reference: a square wave between 50 and 150 rad/s, period 0.5 s. */
static double reference(long k) { return (k % 500) < 250 ? 150.0 : 50.0; }

/*
 * One sample k of the loop: the measured speed and the (noisy) torque of the
 * period that ended go to the estimator, the PI computes the next torque, the
 * plant runs one period with it.
 */
static void drive_sample(drive_t *d, long k, double w_ref, p2d_inertia_t *est, p2d_inertia_output_t *out)
{
    double w_m = drive_measure(d), e, u, T;
    p2d_inertia_step(est, (float)w_m, (float)(d->T_cmd_Nm + d->T_noise_Nm * normal(d)), out);
    (void)k;
    e = w_ref - w_m;
    u = d->Kp * e + d->x_Nm;
    T = u > d->T_max_Nm ? d->T_max_Nm : (u < -d->T_max_Nm ? -d->T_max_Nm : u);
    d->x_Nm += d->Ki * d->Ts_s * (e + (T - u) / d->Kp);
    d->T_cmd_Nm = T;
    drive_advance(d, T);
}

/* n samples from sample k0 on the square-wave reference */
static void drive_run(drive_t *d, long k0, long n, p2d_inertia_t *est, p2d_inertia_output_t *out)
{
    for (long k = k0; k < k0 + n; ++k) drive_sample(d, k, reference(k), est, out);
}

/* ---------------------------------------------------------------------------------------------- */
/* the estimator written again, in double, covariance form                                          */
/* ---------------------------------------------------------------------------------------------- */

typedef struct {
    double theta[3]; /* J, B, T_load */
    double P[3][3];  /* covariance */
    double w_prev, dF, wbarF, TF, oneF, T_prev, nis;
    int primed;
} reference_t;

static void reference_init(reference_t *r, const p2d_inertia_t *est)
{
    const p2d_inertia_coef_t *c = &est->coef[est->active];
    memset(r, 0, sizeof *r);
    r->theta[0] = est->config.J0_kgm2;
    r->P[0][0] = c->var0_J_kg2m4;
    r->P[1][1] = c->var0_B_N2m2s2;
    r->P[2][2] = c->var0_L_N2m2;
    r->nis = 1.0;
}

/* One sample (inertia.h): the prefilter, forgetting and walk, the Kalman update, the variances within the prior. */
static void reference_step(reference_t *r, const p2d_inertia_config_t *cfg, double w, double T)
{
    const double Ts = cfg->Ts_s, c_f = (double)cfg->w_f_radps * Ts / (1.0 + (double)cfg->w_f_radps * Ts);
    const double var0[3] = {(double)cfg->J0_kgm2 * cfg->J0_kgm2, (double)cfg->B_max_Nms * cfg->B_max_Nms,
                            (double)cfg->T_load_max_Nm * cfg->T_load_max_Nm};
    const double lambda_J = 1.0 - Ts / cfg->J_memory_s;
    const double sigma2 = (double)cfg->sigma_T_Nm * cfg->sigma_T_Nm;
    double T_in, phi[3], y, eps, s[3], h[3], alpha, q;
    if (!r->primed) {
        r->w_prev = w;
        r->T_prev = T;
        r->primed = 1;
        return;
    }
    /* every sequence of the relation filtered from rest: F(dw), F((w[k] + w[k-1]) / 2), F(T_in), F(1) */
    T_in = cfg->speed_is_period_mean ? 0.5 * (T + r->T_prev) : T;
    r->T_prev = T;
    r->dF += c_f * ((w - r->w_prev) - r->dF);
    r->wbarF += c_f * (0.5 * (w + r->w_prev) - r->wbarF);
    r->TF += c_f * (T_in - r->TF);
    r->oneF += c_f * (1.0 - r->oneF);
    r->w_prev = w;
    phi[0] = r->dF / Ts;
    phi[1] = r->wbarF;
    phi[2] = r->oneF;
    y = r->TF;
    eps = y - (phi[0] * r->theta[0] + phi[1] * r->theta[1] + phi[2] * r->theta[2]);
    /* time update P <- S P S + q e_L e_L': s^2 = 1 / lambda_J for J and B, the walk q for T_load */
    q = sigma2 * (Ts / cfg->load_memory_s) * (Ts / cfg->load_memory_s);
    for (int i = 0; i < 3; ++i) s[i] = i < 2 ? 1.0 / sqrt(lambda_J) : 1.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r->P[i][j] *= s[i] * s[j];
    r->P[2][2] += q;
    /* K = P phi / alpha, alpha = phi' P phi + sigma^2; P <- P - P phi phi' P / alpha */
    alpha = sigma2;
    for (int i = 0; i < 3; ++i) {
        h[i] = r->P[i][0] * phi[0] + r->P[i][1] * phi[1] + r->P[i][2] * phi[2];
        alpha += phi[i] * h[i];
    }
    for (int i = 0; i < 3; ++i) {
        r->theta[i] += h[i] / alpha * eps;
        for (int j = 0; j < 3; ++j) r->P[i][j] -= h[i] * h[j] / alpha;
    }
    /* every variance above its prior back onto it: P <- S P S, s_i = sqrt(var0_i / P_ii) */
    for (int i = 0; i < 3; ++i) s[i] = r->P[i][i] > var0[i] ? sqrt(var0[i] / r->P[i][i]) : 1.0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r->P[i][j] *= s[i] * s[j];
    /* nis: eps^2 against phi' P phi + sigma_F^2, sigma_F^2 = sigma^2 c_f / (2 - c_f) */
    r->nis += Ts / cfg->J_memory_s * (eps * eps / (alpha - sigma2 + sigma2 * c_f / (2.0 - c_f)) - r->nis);
}

/* P = U D U' of the estimator, in the order J, B, T_load of the reference (the estimator's is T_load, J, B) */
static void estimator_P(const p2d_inertia_t *est, double P[3][3])
{
    const double U[3][3] = {{1.0, est->U_LJ_per_s2, est->U_LB_per_s}, {0.0, 1.0, est->U_JB_s}, {0.0, 0.0, 1.0}};
    const double D[3] = {est->D_L_N2m2, est->D_J_kg2m4, est->D_B_N2m2s2};
    const int order[3] = {1, 2, 0}; /* J, B, T_load in the estimator's indices */
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            P[i][j] = 0.0;
            for (int k = 0; k < 3; ++k) P[i][j] += U[order[i]][k] * D[k] * U[order[j]][k];
        }
}

/* ---------------------------------------------------------------------------------------------- */

static void test_validation(void)
{
    p2d_inertia_config_t cfg;
    p2d_inertia_t est, before;

    CHECK(init_with(nominal_config()) == P2D_OK);
    cfg = nominal_config();
    cfg.Ts_s = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = nominal_config();
    cfg.J0_kgm2 = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_J0);
    cfg = nominal_config();
    cfg.J0_kgm2 = 1e-20f; /* J0^2 below the normal float32 range */
    CHECK(init_with(cfg) == P2D_ERR_J0);
    cfg = nominal_config();
    cfg.J_min_kgm2 = 0.03f; /* above J0 */
    CHECK(init_with(cfg) == P2D_ERR_J_MIN);
    cfg = nominal_config();
    cfg.J_min_kgm2 = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_J_MIN);
    cfg = nominal_config();
    cfg.J_max_kgm2 = 0.01f; /* below J0 */
    CHECK(init_with(cfg) == P2D_ERR_J_MAX);
    cfg = nominal_config();
    cfg.J_max_kgm2 = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_J_MAX);
    cfg = nominal_config();
    cfg.B_max_Nms = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_B_MAX);
    cfg = nominal_config();
    cfg.T_load_max_Nm = NAN;
    CHECK(init_with(cfg) == P2D_ERR_T_LOAD_MAX);
    cfg = nominal_config();
    cfg.sigma_T_Nm = 1e30f; /* sigma^2 overflows */
    CHECK(init_with(cfg) == P2D_ERR_SIGMA_T);
    cfg = nominal_config();
    cfg.J_memory_s = 1.5e-3f; /* < 2 Ts */
    CHECK(init_with(cfg) == P2D_ERR_J_MEMORY);
    cfg = nominal_config();
    cfg.J_memory_s = 2e3f; /* > 1e6 Ts */
    CHECK(init_with(cfg) == P2D_ERR_J_MEMORY);
    cfg = nominal_config();
    cfg.load_memory_s = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_LOAD_MEMORY);
    cfg = nominal_config();
    cfg.w_f_radps = 1e-4f; /* w_f Ts = 1e-7 */
    CHECK(init_with(cfg) == P2D_ERR_W_F);
    cfg = nominal_config();
    cfg.J_rel_sd_max = 1.0f;
    CHECK(init_with(cfg) == P2D_ERR_J_REL_SD_MAX);
    /* the limits of the ranges are accepted */
    cfg = nominal_config();
    cfg.J_min_kgm2 = cfg.J0_kgm2;
    cfg.J_max_kgm2 = cfg.J0_kgm2;
    cfg.J_memory_s = 2e-3f;
    cfg.load_memory_s = 1e3f;
    cfg.w_f_radps = 1e30f; /* w_f Ts huge: no filtering, c_f = 1 */
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    CHECK(est.coef[0].c_f == 1.0f);
    cfg = nominal_config();
    CHECK(p2d_inertia_init(0, &cfg) == P2D_ERR_NULL);
    CHECK(p2d_inertia_init(&est, 0) == P2D_ERR_NULL);

    /* a failed init leaves the object untouched */
    memset(&est, 0x5a, sizeof est);
    before = est;
    cfg = nominal_config();
    cfg.w_f_radps = 0.0f;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_ERR_W_F);
    CHECK(memcmp(&est, &before, sizeof est) == 0);

    CHECK(strcmp(p2d_status_param(P2D_ERR_J0), "J0_kgm2") == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_T_LOAD_MAX), "T_load_max_Nm") == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_J_REL_SD_MAX), "J_rel_sd_max") == 0);
}

/* Prior and coefficients, by hand: c_f = w_f Ts / (1 + w_f Ts), g = 1 / (1 - Ts / memory). */
static void test_prior_and_coefficients(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    const p2d_inertia_coef_t *c;
    /* the first update, from the prior: forgetting g of B, walk q of T_load, then alpha = phi' P phi + sigma^2 */
    const double c_f = 5.0 / 6.0, g = 1.0 / (1.0 - 1e-4), q = 0.0025 * 2e-3 * 2e-3;
    const double alpha = 100.0 * 1e-4 * g * (c_f * c_f) + (4.0 + q) * (c_f * c_f) + 0.0025;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    c = &est.coef[est.active];
    CHECK_CLOSE(c->c_f, 0.02 / 1.02, 1e-8);
    CHECK_CLOSE(c->g_J, 1.0 / (1.0 - 1e-4), 1e-7);
    CHECK_CLOSE(c->q_L_N2m2, 0.0025 * 2e-3 * 2e-3, 1e-14);
    CHECK_CLOSE(c->sigma2_F_N2m2, 0.0025 * (0.02 / 1.02) / (2.0 - 0.02 / 1.02), 1e-10);
    CHECK(c->T_prev_weight == 0.0f);
    CHECK(est.J_kgm2 == 0.02f && est.B_Nms == 0.0f && est.T_load_Nm == 0.0f);
    CHECK(est.D_J_kg2m4 == 0.02f * 0.02f && est.D_B_N2m2s2 == 0.01f * 0.01f && est.D_L_N2m2 == 4.0f);

    /* w_f Ts = 5: c_f = 5/6 */
    cfg.w_f_radps = 5000.0f;
    cfg.speed_is_period_mean = true;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    c = &est.coef[est.active];
    CHECK_CLOSE(c->c_f, c_f, 1e-7);
    CHECK(c->T_prev_weight == 0.5f);
    /* the first sample only starts the prefilter */
    p2d_inertia_step(&est, 10.0f, 0.3f, &out);
    CHECK(!out.updated && !out.fault && !out.J_valid);
    CHECK(out.J_kgm2 == 0.02f);
    CHECK_CLOSE(out.J_sd_kgm2, 0.02, 1e-9); /* the prior standard deviation J0 */
    CHECK(est.wF_radps == 10.0f && est.w0_radps == 10.0f && est.TF_Nm == 0.0f && est.oneF == 0.0f);
    /* the second updates: at a constant speed, phi = [0, c_f 10, c_f], y = c_f (0.3 + 0.6) / 2 */
    p2d_inertia_step(&est, 10.0f, 0.6f, &out);
    CHECK(out.updated);
    CHECK_CLOSE(est.TF_Nm, c_f * 0.45, 1e-7);
    CHECK_CLOSE(est.oneF, c_f, 1e-7);
    /* eps = y - (0.02 * 0 + 0 * 10 c_f + 0 c_f) */
    CHECK_CLOSE(out.residual_Nm, c_f * 0.45, 1e-7);
    CHECK_CLOSE(out.residual_sd_Nm, sqrt(alpha), 1e-6);
    /* no acceleration: J does not move */
    CHECK(out.J_kgm2 == 0.02f);
    /* T_load and B move by K eps, K = P phi / alpha */
    CHECK_CLOSE(out.T_load_Nm, (4.0 + q) * c_f / alpha * out.residual_Nm, 1e-7);
    CHECK_CLOSE(out.B_Nms, 10.0 * c_f * 1e-4 * g / alpha * out.residual_Nm, 1e-9);
    /* and the variance of J, forgotten beyond its prior without information, is back on it */
    CHECK_CLOSE(est.D_J_kg2m4, 0.02 * 0.02, 1e-6 * 0.02 * 0.02);
}

/* The U D U' recursion is the covariance-form recursion of the header, sample by sample. */
static void test_matches_covariance_form(void)
{
    for (int mean = 0; mean <= 1; ++mean) {
        p2d_inertia_config_t cfg = nominal_config();
        p2d_inertia_t est;
        p2d_inertia_output_t out;
        reference_t ref;
        drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
        double worst_theta = 0.0, worst_P = 0.0;
        cfg.speed_is_period_mean = mean != 0;
        d.counts_per_rad = mean ? 16384.0 / (2.0 * PI_D) : 0.0;
        d.T_noise_Nm = 0.01;
        CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
        reference_init(&ref, &est);
        for (long k = 0; k < 3000; ++k) {
            double w_m = drive_measure(&d), T = d.T_cmd_Nm + d.T_noise_Nm * normal(&d), P[3][3], e, u, Tc;
            float w32 = (float)w_m, T32 = (float)T;
            p2d_inertia_step(&est, w32, T32, &out);
            reference_step(&ref, &cfg, w32, T32);
            estimator_P(&est, P);
            /* relative errors: theta against its scale, P against the prior variances */
            {
                double dJ = fabs(est.J_kgm2 - ref.theta[0]) / 0.01, dB = fabs(est.B_Nms - ref.theta[1]) / 1e-3;
                double dL = fabs(est.T_load_Nm - ref.theta[2]) / 0.2;
                double eJ = fabs(P[0][0] - ref.P[0][0]) / ref.P[0][0], eL = fabs(P[2][2] - ref.P[2][2]) / ref.P[2][2];
                double eJL = fabs(P[0][2] - ref.P[0][2]) / sqrt(ref.P[0][0] * ref.P[2][2]);
                worst_theta = fmax(worst_theta, fmax(dJ, fmax(dB, dL)));
                worst_P = fmax(worst_P, fmax(eJ, fmax(eL, eJL)));
            }
            e = reference(k) - w_m;
            u = d.Kp * e + d.x_Nm;
            Tc = fmin(fmax(u, -d.T_max_Nm), d.T_max_Nm);
            d.x_Nm += d.Ki * d.Ts_s * (e + (Tc - u) / d.Kp);
            d.T_cmd_Nm = Tc;
            drive_advance(&d, Tc);
        }
        printf("covariance form (period mean %d): theta within %.2g, P within %.2g\n", mean, worst_theta, worst_P);
        CHECK(worst_theta < 1e-3);
        CHECK(worst_P < 1e-3);
        CHECK_CLOSE(est.nis, ref.nis, 1e-3 * ref.nis);
    }
}

/* Noise-free samples of the speed at the instants: J, B and T_load to within a fraction of a percent. */
static void test_identifies_rigid_drive(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
    long first_valid = -1;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    for (long k = 0; k < 20000; ++k) {
        drive_sample(&d, k, reference(k), &est, &out);
        if (out.J_valid && first_valid < 0) first_valid = k;
    }
    printf("noise free: J %.6g B %.6g T_load %.6g sd(J) %.3g, valid from sample %ld\n", (double)out.J_kgm2,
           (double)out.B_Nms, (double)out.T_load_Nm, (double)out.J_sd_kgm2, first_valid);
    CHECK_CLOSE(out.J_kgm2, 0.01, 0.002 * 0.01);
    CHECK_CLOSE(out.B_Nms, 1e-3, 0.02 * 1e-3);
    CHECK_CLOSE(out.T_load_Nm, 0.2, 0.01 * 0.2);
    CHECK(out.J_valid);
    /* valid within the first period of the reference: a constant acceleration (the first step, at the
       current limit) does not separate J from T_load, the change of acceleration at the second step does */
    CHECK(first_valid >= 250 && first_valid < 500);
    CHECK(est.fault_count == 0u);
}

/*
 * An encoder of 4096 lines (16384 counts per turn) whose counts are differenced
 * over the period, and a torque measurement with 0.02 Nm of noise: J within 1 %.
 * Paired as the period mean it is (speed_is_period_mean), B within 10 % and
 * T_load within 2 %; paired as an instant speed, the half-period shift between
 * speed and torque biases B and T_load (not J, to first order), by more than
 * twice as much.
 */
static void test_encoder_and_noise(void)
{
    double B_err[2], L_err[2];
    for (int mean = 0; mean <= 1; ++mean) {
        p2d_inertia_config_t cfg = nominal_config();
        p2d_inertia_t est;
        p2d_inertia_output_t out;
        drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
        cfg.speed_is_period_mean = mean != 0;
        d.counts_per_rad = 16384.0 / (2.0 * PI_D);
        d.T_noise_Nm = 0.02;
        CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
        drive_run(&d, 0, 20000, &est, &out);
        printf("encoder, period mean %d: J %.6g B %.6g T_load %.6g sd(J) %.3g nis %.3g\n", mean, (double)out.J_kgm2,
               (double)out.B_Nms, (double)out.T_load_Nm, (double)out.J_sd_kgm2, (double)est.nis);
        CHECK_CLOSE(out.J_kgm2, 0.01, 0.01 * 0.01);
        CHECK(out.J_valid);
        B_err[mean] = fabs(out.B_Nms - 1e-3) / 1e-3;
        L_err[mean] = fabs(out.T_load_Nm - 0.2) / 0.2;
    }
    CHECK(B_err[1] < 0.1 && L_err[1] < 0.02);
    CHECK(B_err[0] > 2.0 * B_err[1] && L_err[0] > 2.0 * L_err[1]);
}

/*
 * An unannounced load step of 0.5 Nm: J stays within 1 %; the friction torque
 * at the mean speed, T_load + B 100 rad/s, follows within 5 load memories
 * (2.5 s); the step looks like a change of B at first (B w and T_load are
 * correlated through the mean speed), which the data undo within a few
 * J memories.
 */
static void test_unannounced_load_step(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
    float J_lo = INFINITY, J_hi = 0.0f;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    drive_run(&d, 0, 10000, &est, &out);
    d.T_load_Nm = 0.7; /* in the middle of a period of the reference */
    for (long k = 10125; k < 50125; ++k) {
        drive_sample(&d, k, reference(k), &est, &out);
        J_lo = fminf(J_lo, out.J_kgm2);
        J_hi = fmaxf(J_hi, out.J_kgm2);
        if (k == 10125 + 2500) {
            printf("load step, 2.5 s after: T_load %.6g B %.6g\n", (double)out.T_load_Nm, (double)out.B_Nms);
            CHECK_CLOSE(out.T_load_Nm + 100.0f * out.B_Nms, 0.8, 0.04);
        }
        if ((k - 10125) % 10000 == 0)
            printf("load step, %ld s after: T_load %.6g B %.6g\n", (k - 10125) / 1000, (double)out.T_load_Nm,
                   (double)out.B_Nms);
    }
    printf("load step: J within [%.6g, %.6g], T_load %.6g B %.6g\n", (double)J_lo, (double)J_hi, (double)out.T_load_Nm,
           (double)out.B_Nms);
    CHECK(J_lo > 0.99f * 0.01f && J_hi < 1.01f * 0.01f);
    CHECK_CLOSE(out.T_load_Nm, 0.7, 0.01);
    CHECK_CLOSE(out.B_Nms, 1e-3, 1e-4);
}

/*
 * No acceleration for 25 J memories: J is held, its variance grows back to the
 * prior J0^2 and no further (no windup), and so does the variance of T_load
 * towards T_load_max^2; J_valid falls; an excitation makes it valid again.
 */
static void test_low_excitation(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
    double P[3][3], P_JJ_max = 0.0, P_LL_max = 0.0;
    float J_held;
    long invalid_at = -1;
    cfg.J_memory_s = 2.0f;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    drive_run(&d, 0, 5000, &est, &out);
    CHECK(out.J_valid);
    J_held = out.J_kgm2;
    for (long k = 5000; k < 55000; ++k) {
        drive_sample(&d, k, 100.0, &est, &out);
        estimator_P(&est, P);
        P_JJ_max = fmax(P_JJ_max, P[0][0]);
        P_LL_max = fmax(P_LL_max, P[2][2]);
        if (!out.J_valid && invalid_at < 0) invalid_at = k;
    }
    printf("low excitation: J %.6g (held %.6g), sd(J) %.3g, invalid after %.2f s, max P_JJ / J0^2 = %.6f\n",
           (double)out.J_kgm2, (double)J_held, (double)out.J_sd_kgm2, (double)(invalid_at - 5000) * 1e-3,
           P_JJ_max / (0.02 * 0.02));
    CHECK(!out.J_valid);
    CHECK(invalid_at > 5000);
    CHECK_CLOSE(out.J_kgm2, J_held, 0.005 * 0.01);
    /* bounded by the prior times one sample's growth 1 / lambda */
    CHECK(P_JJ_max <= 0.02 * 0.02 * (1.0 + 1e-6));
    CHECK(P_JJ_max > 0.5 * 0.02 * 0.02);
    CHECK(P_LL_max <= 4.0 * (1.0 + 1e-6));
    /* excitation again */
    drive_run(&d, 55000, 1000, &est, &out);
    CHECK(out.J_valid);
    CHECK_CLOSE(out.J_kgm2, 0.01, 0.005 * 0.01);
}

/* A drive far beyond J_max: the output stays at J_max and is not valid; the estimate inside is not limited. */
static void test_projection(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.6, 3e-3, 0.2, 10.0);
    d.T_max_Nm = 50.0;
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    drive_run(&d, 0, 10000, &est, &out);
    printf("J_plant 0.6 above J_max: estimate %.6g, output %.6g\n", (double)est.J_kgm2, (double)out.J_kgm2);
    CHECK(out.J_kgm2 == cfg.J_max_kgm2);
    CHECK_CLOSE(est.J_kgm2, 0.6, 0.01 * 0.6);
    CHECK(!out.J_valid);
    CHECK(out.B_Nms >= 0.0f && out.B_Nms <= cfg.B_max_Nms);
    CHECK(fabsf(out.T_load_Nm) <= cfg.T_load_max_Nm);
}

static void test_non_finite_policy(void)
{
    p2d_inertia_config_t cfg = nominal_config();
    p2d_inertia_t est, before;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
    const float bad[4][2] = {{NAN, 0.1f}, {INFINITY, 0.1f}, {10.0f, -INFINITY}, {10.0f, NAN}};
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    drive_run(&d, 0, 3000, &est, &out);
    for (int i = 0; i < 4; ++i) {
        before = est;
        p2d_inertia_step(&est, bad[i][0], bad[i][1], &out);
        CHECK(out.fault && !out.updated && !out.J_valid);
        CHECK(out.J_kgm2 == before.J_kgm2 && out.B_Nms == before.B_Nms && out.T_load_Nm == before.T_load_Nm);
        CHECK(isfinite(out.J_sd_kgm2) && out.residual_Nm == 0.0f);
        /* only the counter and the prefilter restart change */
        CHECK(est.fault_count == before.fault_count + 1u && !est.primed);
        before.fault_count++;
        before.primed = false;
        CHECK(memcmp(&est, &before, sizeof est) == 0);
    }
    /* an overflow inside the update is refused the same way */
    drive_run(&d, 3000, 10, &est, &out);
    before = est;
    p2d_inertia_step(&est, 3e38f, 0.1f, &out);
    CHECK(out.fault && est.fault_count == before.fault_count + 1u);
    CHECK(est.J_kgm2 == before.J_kgm2 && est.D_J_kg2m4 == before.D_J_kg2m4);
    /* the next sample restarts the prefilter, the one after updates; the restart leaves no bias */
    drive_sample(&d, 3010, reference(3010), &est, &out);
    CHECK(!out.fault && !out.updated);
    drive_sample(&d, 3011, reference(3011), &est, &out);
    CHECK(!out.fault && out.updated);
    drive_run(&d, 3012, 2000, &est, &out);
    CHECK_CLOSE(out.J_kgm2, 0.01, 0.001 * 0.01);
    CHECK_CLOSE(out.T_load_Nm, 0.2, 0.01 * 0.2);
}

static void test_set_config_and_reset(void)
{
    p2d_inertia_config_t cfg = nominal_config(), bad;
    p2d_inertia_t est, before, fresh;
    p2d_inertia_output_t out;
    drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
    CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
    drive_run(&d, 0, 3000, &est, &out);

    /* a rejected update changes nothing */
    before = est;
    bad = cfg;
    bad.J_rel_sd_max = -0.1f;
    CHECK(p2d_inertia_set_config(&est, &bad) == P2D_ERR_J_REL_SD_MAX);
    CHECK(memcmp(&est, &before, sizeof est) == 0);
    CHECK(p2d_inertia_set_config(0, &cfg) == P2D_ERR_NULL && p2d_inertia_set_config(&est, 0) == P2D_ERR_NULL);

    /* an accepted one keeps the state, swaps the coefficients, and computes them as init does */
    cfg.load_memory_s = 0.1f;
    CHECK(p2d_inertia_set_config(&est, &cfg) == P2D_OK);
    CHECK(est.active != before.active);
    CHECK(est.J_kgm2 == before.J_kgm2 && est.D_J_kg2m4 == before.D_J_kg2m4 && est.wF_radps == before.wF_radps);
    CHECK(memcmp(&est.coef[before.active], &before.coef[before.active], sizeof est.coef[0]) == 0);
    CHECK(p2d_inertia_init(&fresh, &cfg) == P2D_OK);
    CHECK(memcmp(&est.coef[est.active], &fresh.coef[0], sizeof fresh.coef[0]) == 0);
    CHECK(memcmp(&fresh.coef[0], &fresh.coef[1], sizeof fresh.coef[0]) == 0);
    /* the new bounds hold for the next output even before the next update */
    cfg.J_max_kgm2 = 0.02f;
    cfg.J_min_kgm2 = 0.015f;
    CHECK(p2d_inertia_set_config(&est, &cfg) == P2D_OK);
    p2d_inertia_reset(&est, true);
    p2d_inertia_step(&est, 100.0f, 0.3f, &out);
    CHECK(!out.updated && out.J_kgm2 == 0.015f && !out.J_valid);

    /* reset(keep) only restarts the prefilter; reset(prior) returns to the prior */
    before = est;
    p2d_inertia_reset(&est, true);
    CHECK(!est.primed && est.J_kgm2 == before.J_kgm2 && est.D_J_kg2m4 == before.D_J_kg2m4);
    p2d_inertia_reset(&est, false);
    CHECK(est.J_kgm2 == cfg.J0_kgm2 && est.B_Nms == 0.0f && est.T_load_Nm == 0.0f && est.nis == 1.0f);
    CHECK(est.D_J_kg2m4 == cfg.J0_kgm2 * cfg.J0_kgm2 && est.U_JB_s == 0.0f && est.U_LJ_per_s2 == 0.0f);
    CHECK(est.fault_count == before.fault_count);
}

/*
 * sd(J) is honest when sigma_T_Nm is set 10 times too small: the mean nis
 * grows, and sd(J) with it, so that J_valid does not claim more than the data
 * show. The estimate itself does not depend on sigma_T_Nm once the data
 * outweigh the prior.
 */
static void test_sigma_misset(void)
{
    float J[2], sd[2];
    const float sigma[2] = {0.02f, 0.002f};
    for (int i = 0; i < 2; ++i) {
        p2d_inertia_config_t cfg = nominal_config();
        p2d_inertia_t est;
        p2d_inertia_output_t out;
        drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
        d.T_noise_Nm = 0.02;
        cfg.sigma_T_Nm = sigma[i];
        CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
        drive_run(&d, 0, 30000, &est, &out);
        J[i] = out.J_kgm2;
        sd[i] = out.J_sd_kgm2;
        printf("sigma_T %.3g: J %.6g sd(J) %.3g nis %.3g\n", (double)sigma[i], (double)J[i], (double)sd[i],
               (double)est.nis);
    }
    CHECK_CLOSE(J[1], J[0], 0.002 * 0.01);
    CHECK(sd[1] > 0.5f * sd[0]);
}

/*
 * sd(J) against the scatter of J over 20 drives that differ in their torque
 * noise only (0.05 Nm, sigma_T_Nm set to it): the spread is honest, neither
 * smaller than the errors nor more than 3 times larger.
 */
static void test_sd_against_scatter(void)
{
    double sum_e2 = 0.0, sum_sd = 0.0;
    int within_2sd = 0;
    const int n = 20;
    for (int seed = 0; seed < n; ++seed) {
        p2d_inertia_config_t cfg = nominal_config();
        p2d_inertia_t est;
        p2d_inertia_output_t out;
        drive_t d = drive_new(0.01, 1e-3, 0.2, 50.0);
        d.T_noise_Nm = 0.05;
        d.rng += 7919u * (uint64_t)seed;
        CHECK(p2d_inertia_init(&est, &cfg) == P2D_OK);
        drive_run(&d, 0, 20000, &est, &out);
        sum_e2 += (out.J_kgm2 - 0.01) * (out.J_kgm2 - 0.01);
        sum_sd += out.J_sd_kgm2;
        within_2sd += fabs(out.J_kgm2 - 0.01) <= 2.0 * out.J_sd_kgm2;
    }
    printf("20 noise seeds: rms error of J %.3g, mean sd(J) %.3g, %d within 2 sd\n", sqrt(sum_e2 / n), sum_sd / n,
           within_2sd);
    CHECK(sqrt(sum_e2 / n) <= sum_sd / n);
    CHECK(sqrt(sum_e2 / n) >= sum_sd / n / 3.0);
    CHECK(within_2sd >= 18);
}

int main(void)
{
    test_validation();
    test_prior_and_coefficients();
    test_matches_covariance_form();
    test_identifies_rigid_drive();
    test_encoder_and_noise();
    test_unannounced_load_step();
    test_low_excitation();
    test_projection();
    test_non_finite_policy();
    test_set_config_and_reset();
    test_sigma_misset();
    test_sd_against_scatter();
    return check_summary();
}
