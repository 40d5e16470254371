/*
 * pmsm2dof: host-only run of the commissioning routine against a simulated
 * motor. See commission_run.h.
 */
#include "commission_run.h"

#include <math.h>
#include <stddef.h>

#define P2D_CRUN_SQRT3 1.7320508075688772        /* sqrt(3) */
#define P2D_CRUN_TWO_PI 6.283185307179586        /* 2 pi */
#define P2D_CRUN_PI 3.141592653589793            /* pi */
#define P2D_CRUN_SEED_ZERO 0x9e3779b97f4a7c15ull /* xorshift64* state used for seed 0 (a zero state stays 0) */

/* the log's phase_start array holds one entry per phase */
typedef char p2d_crun_phase_count_check[(P2D_PHASE_COUNT == 11) ? 1 : -1];

static const struct {
    const char *param;
    const char *text;
} STATUS[P2D_CRUN_STATUS_COUNT] = {
    [P2D_CRUN_OK] = {"", "ok"},
    [P2D_CRUN_ERR_NULL] = {"run", "a non-NULL pointer"},
    [P2D_CRUN_ERR_POLE_PAIRS] = {"motor.pole_pairs", "an integer >= 1"},
    [P2D_CRUN_ERR_RS] = {"motor.Rs_ohm", "finite and > 0"},
    [P2D_CRUN_ERR_LD] = {"motor.Ld_H", "finite and > 0"},
    [P2D_CRUN_ERR_LQ] = {"motor.Lq_H", "finite and > 0"},
    [P2D_CRUN_ERR_PSI_F] = {"motor.psi_f_Wb", "finite and > 0"},
    [P2D_CRUN_ERR_J] = {"motor.J_kgm2", "finite and > 0"},
    [P2D_CRUN_ERR_B] = {"motor.B_Nms", "finite and >= 0"},
    [P2D_CRUN_ERR_T_COULOMB] = {"motor.T_coulomb_Nm", "finite and >= 0"},
    [P2D_CRUN_ERR_U_DC] = {"u_dc_V", "finite and > 0"},
    [P2D_CRUN_ERR_SUBSTEPS] = {"substeps", "an integer >= 1"},
    [P2D_CRUN_ERR_LOG_EVERY] = {"log_every", "an integer >= 1"},
    [P2D_CRUN_ERR_DEAD_TIME] = {"dead_time_V", "finite and >= 0"},
    [P2D_CRUN_ERR_NOISE] = {"noise_A", "finite and >= 0"},
    [P2D_CRUN_ERR_THETA0] = {"theta0_rad", "finite"},
    [P2D_CRUN_ERR_T_LOAD] = {"T_load_Nm", "finite"},
    [P2D_CRUN_ERR_COMMISSIONING] = {"commissioning", "accepted by p2d_commission_init (see commission_status)"},
    [P2D_CRUN_ERR_LOG_FULL] = {"log_rows", "room for every logged sample of the run"},
    [P2D_CRUN_STOP_NONFINITE] = {"", "the plant state became NaN or infinite"},
    [P2D_CRUN_STOP_TIMEOUT] = {"", "the routine had not ended after max_samples current samples"},
};

static const char *const LOG_NAMES[P2D_CLOG_COUNT] = {
    [P2D_CLOG_T_S] = "t_s",
    [P2D_CLOG_PHASE] = "phase",
    [P2D_CLOG_ID_A] = "id_A",
    [P2D_CLOG_IQ_A] = "iq_A",
    [P2D_CLOG_UD_V] = "ud_V",
    [P2D_CLOG_UQ_V] = "uq_V",
    [P2D_CLOG_W_E_FRAME_RADPS] = "w_e_frame_radps",
    [P2D_CLOG_W_E_RADPS] = "w_e_radps",
    [P2D_CLOG_THETA_ERR_RAD] = "theta_err_rad",
};

static bool finite_ge0(double x) { return isfinite(x) && x >= 0.0; }
static bool finite_gt0(double x) { return isfinite(x) && x > 0.0; }

/* Uniform in (0, 1) from the xorshift64* generator (Vigna, "An experimental exploration of Marsaglia's
   xorshift generators, scrambled", ACM TOMS 42(4), 2016) */
static double uniform(p2d_crun_t *run)
{
    run->rng ^= run->rng >> 12;
    run->rng ^= run->rng << 25;
    run->rng ^= run->rng >> 27;
    return ((double)((run->rng * 2685821657736338717ull) >> 11) + 0.5) / 9007199254740992.0;
}

/* Standard normal (Box-Muller) */
static double gauss(p2d_crun_t *run)
{
    double u1 = uniform(run), u2 = uniform(run);
    return sqrt(-2.0 * log(u1)) * cos(P2D_CRUN_TWO_PI * u2);
}

static double sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }

/* x wrapped to [-pi, pi) */
static double wrap_pi(double x) { return x - P2D_CRUN_TWO_PI * floor((x + P2D_CRUN_PI) / P2D_CRUN_TWO_PI); }

/* Precompute the motor's coefficients from validated parameters and set it at rest. */
static void pmsm_setup(p2d_crun_pmsm_t *m, const p2d_pmsm_params_t *mp, double Ts_s)
{
    m->pole_pairs = (double)mp->pole_pairs;
    m->Rs_ohm = mp->Rs_ohm;
    m->Ld_H = mp->Ld_H;
    m->Lq_H = mp->Lq_H;
    m->psi_f_Wb = mp->psi_f_Wb;
    m->inv_Ld_per_H = 1.0 / mp->Ld_H;
    m->inv_Lq_per_H = 1.0 / mp->Lq_H;
    m->inv_J_per_kgm2 = 1.0 / mp->J_kgm2;
    m->kt_Nm_per_A = 1.5 * m->pole_pairs * mp->psi_f_Wb;
    m->c_T_Nm_per_A2 = 1.5 * m->pole_pairs * (mp->Ld_H - mp->Lq_H);
    m->B_Nms = mp->B_Nms;
    m->T_coulomb_Nm = mp->T_coulomb_Nm;
    m->inv_w_c_s_per_rad = 1.0 / p2d_plant_friction_band_radps(mp, Ts_s);
    m->id_A = 0.0;
    m->iq_A = 0.0;
    m->w_m_radps = 0.0;
}

p2d_crun_status_t p2d_commission_run_init(p2d_crun_t *run, const p2d_crun_config_t *cfg)
{
    const p2d_pmsm_params_t *mp;
    p2d_crun_pmsm_t *m;
    p2d_status_t status;
    if (run == NULL || cfg == NULL) return P2D_CRUN_ERR_NULL;
    mp = &cfg->motor;
    if (mp->pole_pairs < 1u) return P2D_CRUN_ERR_POLE_PAIRS;
    if (!finite_gt0(mp->Rs_ohm)) return P2D_CRUN_ERR_RS;
    if (!finite_gt0(mp->Ld_H)) return P2D_CRUN_ERR_LD;
    if (!finite_gt0(mp->Lq_H)) return P2D_CRUN_ERR_LQ;
    if (!finite_gt0(mp->psi_f_Wb)) return P2D_CRUN_ERR_PSI_F;
    if (!finite_gt0(mp->J_kgm2)) return P2D_CRUN_ERR_J;
    if (!finite_ge0(mp->B_Nms)) return P2D_CRUN_ERR_B;
    if (!finite_ge0(mp->T_coulomb_Nm)) return P2D_CRUN_ERR_T_COULOMB;
    if (!finite_gt0(cfg->u_dc_V)) return P2D_CRUN_ERR_U_DC;
    if (cfg->substeps < 1u) return P2D_CRUN_ERR_SUBSTEPS;
    if (cfg->log_every < 1u) return P2D_CRUN_ERR_LOG_EVERY;
    if (!finite_ge0(cfg->dead_time_V)) return P2D_CRUN_ERR_DEAD_TIME;
    if (!finite_ge0(cfg->noise_A)) return P2D_CRUN_ERR_NOISE;
    if (!isfinite(cfg->theta0_rad)) return P2D_CRUN_ERR_THETA0;
    if (!isfinite(cfg->T_load_Nm)) return P2D_CRUN_ERR_T_LOAD;
    status = p2d_commission_init(&run->routine, &cfg->commissioning);
    run->commission_status = status;
    if (status != P2D_OK) return P2D_CRUN_ERR_COMMISSIONING;

    run->cfg = *cfg;
    m = &run->pmsm;
    pmsm_setup(m, mp, (double)cfg->commissioning.Ts_s);
    run->theta_e_rad = wrap_pi(cfg->theta0_rad - P2D_CRUN_PI) + P2D_CRUN_PI;
    run->dt_s = (double)cfg->commissioning.Ts_s / (double)cfg->substeps;
    run->ua_next_V = 0.0;
    run->ub_next_V = 0.0;
    run->rng = cfg->seed != 0u ? cfg->seed : P2D_CRUN_SEED_ZERO;
    run->n = 0u;
    run->n_rows = 0u;
    for (size_t i = 0; i < sizeof run->phase_start / sizeof run->phase_start[0]; ++i) run->phase_start[i] = UINT64_MAX;
    run->phase_start[P2D_PHASE_PROBE] = 0u;
    run->status = P2D_CRUN_OK;
    return P2D_CRUN_OK;
}

/* d/dt of (id, iq, w_m, theta_e) under the stationary-frame voltage (ua, ub) held by the inverter */
static void derivative(const p2d_crun_t *run, const double x[4], double ua_V, double ub_V, double dx[4])
{
    const p2d_crun_pmsm_t *m = &run->pmsm;
    const double u_dt_V = run->cfg.dead_time_V;
    double c = cos(x[3]), s = sin(x[3]);
    /* the rotor-frame current in alpha beta, and its phase currents (amplitude invariant) */
    double i_al = c * x[0] - s * x[1], i_be = s * x[0] + c * x[1];
    double i_a = i_al, i_b = -0.5 * i_al + 0.5 * P2D_CRUN_SQRT3 * i_be, i_c = -0.5 * i_al - 0.5 * P2D_CRUN_SQRT3 * i_be;
    /* e_x = -u_dt sign(i_x) per phase, in alpha beta: (2/3)(e_a - (e_b + e_c)/2), (e_b - e_c)/sqrt(3) */
    double e_a = -u_dt_V * sign(i_a), e_b = -u_dt_V * sign(i_b), e_c = -u_dt_V * sign(i_c);
    double v_al = ua_V + (2.0 / 3.0) * (e_a - 0.5 * (e_b + e_c)), v_be = ub_V + (e_b - e_c) / P2D_CRUN_SQRT3;
    /* Park at the rotor's angle */
    double ud = c * v_al + s * v_be, uq = -s * v_al + c * v_be;
    double w_e = m->pole_pairs * x[2];
    /* Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
    double Te = x[1] * (m->kt_Nm_per_A + m->c_T_Nm_per_A2 * x[0]);
    /* T_f = B w_m + T_c tanh(w_m / w_c) */
    double Tf = m->B_Nms * x[2] + m->T_coulomb_Nm * tanh(x[2] * m->inv_w_c_s_per_rad);
    /* Ld did/dt = ud - Rs id + w_e Lq iq */
    dx[0] = (ud - m->Rs_ohm * x[0] + w_e * m->Lq_H * x[1]) * m->inv_Ld_per_H;
    /* Lq diq/dt = uq - Rs iq - w_e (Ld id + psi_f) */
    dx[1] = (uq - m->Rs_ohm * x[1] - w_e * (m->Ld_H * x[0] + m->psi_f_Wb)) * m->inv_Lq_per_H;
    /* J dw_m/dt = Te - T_load - T_f */
    dx[2] = (Te - run->cfg.T_load_Nm - Tf) * m->inv_J_per_kgm2;
    /* dtheta_e/dt = p w_m */
    dx[3] = w_e;
}

/* The plant over one current period with (ua, ub) held: substeps RK4 steps */
static void integrate(p2d_crun_t *run, double ua_V, double ub_V)
{
    const double h = run->dt_s;
    double x[4] = {run->pmsm.id_A, run->pmsm.iq_A, run->pmsm.w_m_radps, run->theta_e_rad};
    for (uint32_t j = 0; j < run->cfg.substeps; ++j) {
        double k1[4], k2[4], k3[4], k4[4], y[4];
        derivative(run, x, ua_V, ub_V, k1);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + 0.5 * h * k1[i];
        derivative(run, y, ua_V, ub_V, k2);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + 0.5 * h * k2[i];
        derivative(run, y, ua_V, ub_V, k3);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + h * k3[i];
        derivative(run, y, ua_V, ub_V, k4);
        for (int i = 0; i < 4; ++i) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    run->pmsm.id_A = x[0];
    run->pmsm.iq_A = x[1];
    run->pmsm.w_m_radps = x[2];
    run->theta_e_rad = x[3] - P2D_CRUN_TWO_PI * floor(x[3] / P2D_CRUN_TWO_PI);
}

/* The currents that firmware measures, in the routine's frame at the angle theta_c */
static void measure(p2d_crun_t *run, double theta_c_rad, float *id_A, float *iq_A)
{
    double c = cos(run->theta_e_rad), s = sin(run->theta_e_rad);
    double i_al = c * run->pmsm.id_A - s * run->pmsm.iq_A, i_be = s * run->pmsm.id_A + c * run->pmsm.iq_A;
    /* phases a and b measured with noise, c = -a - b; Clarke: alpha = a, beta = (a + 2 b) / sqrt(3) */
    double i_a = i_al, i_b = -0.5 * i_al + 0.5 * P2D_CRUN_SQRT3 * i_be;
    if (run->cfg.noise_A > 0.0) {
        i_a += run->cfg.noise_A * gauss(run);
        i_b += run->cfg.noise_A * gauss(run);
    }
    i_al = i_a;
    i_be = (i_a + 2.0 * i_b) / P2D_CRUN_SQRT3;
    /* Park at the routine's angle */
    *id_A = (float)(cos(theta_c_rad) * i_al + sin(theta_c_rad) * i_be);
    *iq_A = (float)(-sin(theta_c_rad) * i_al + cos(theta_c_rad) * i_be);
}

p2d_crun_status_t p2d_commission_run(p2d_crun_t *run, uint64_t max_samples, double *log, uint64_t log_rows)
{
    if (run == NULL || log == NULL) return P2D_CRUN_ERR_NULL;
    while (run->status == P2D_CRUN_OK && run->routine.phase < P2D_PHASE_DONE) {
        p2d_commission_output_t out;
        double theta_c_rad = (double)run->routine.theta_e_rad, ua_V, ub_V;
        float id_A, iq_A;
        if (run->n >= max_samples) return P2D_CRUN_STOP_TIMEOUT;
        if (run->n % run->cfg.log_every == 0u && run->n_rows >= log_rows) {
            run->status = P2D_CRUN_ERR_LOG_FULL;
            break;
        }
        measure(run, theta_c_rad, &id_A, &iq_A);
        p2d_commission_step(&run->routine, id_A, iq_A, (float)run->cfg.u_dc_V, &out);
        if (run->routine.phase < P2D_PHASE_COUNT && run->phase_start[run->routine.phase] == UINT64_MAX) {
            run->phase_start[run->routine.phase] = run->n + 1u;
        }
        if (run->n % run->cfg.log_every == 0u) {
            uint64_t r = run->n_rows++;
            log[P2D_CLOG_T_S * log_rows + r] = (double)run->n * (double)run->cfg.commissioning.Ts_s;
            log[P2D_CLOG_PHASE * log_rows + r] = (double)out.phase;
            log[P2D_CLOG_ID_A * log_rows + r] = (double)id_A;
            log[P2D_CLOG_IQ_A * log_rows + r] = (double)iq_A;
            log[P2D_CLOG_UD_V * log_rows + r] = (double)out.ud_V;
            log[P2D_CLOG_UQ_V * log_rows + r] = (double)out.uq_V;
            log[P2D_CLOG_W_E_FRAME_RADPS * log_rows + r] = (double)out.w_e_radps;
            log[P2D_CLOG_W_E_RADPS * log_rows + r] = run->pmsm.pole_pairs * run->pmsm.w_m_radps;
            log[P2D_CLOG_THETA_ERR_RAD * log_rows + r] = wrap_pi(run->theta_e_rad - theta_c_rad);
        }
        /* inverse Park at the angle the routine asks for */
        ua_V = cos((double)out.theta_e_rad) * (double)out.ud_V - sin((double)out.theta_e_rad) * (double)out.uq_V;
        ub_V = sin((double)out.theta_e_rad) * (double)out.ud_V + cos((double)out.theta_e_rad) * (double)out.uq_V;
        if (run->cfg.computation_delay) {
            double ua_now_V = run->ua_next_V, ub_now_V = run->ub_next_V;
            run->ua_next_V = ua_V;
            run->ub_next_V = ub_V;
            ua_V = ua_now_V;
            ub_V = ub_now_V;
        }
        integrate(run, ua_V, ub_V);
        run->n++;
        if (!isfinite(run->pmsm.id_A) || !isfinite(run->pmsm.iq_A) || !isfinite(run->pmsm.w_m_radps) ||
            !isfinite(run->theta_e_rad)) {
            run->status = P2D_CRUN_STOP_NONFINITE;
        }
    }
    return run->status;
}

const char *p2d_crun_status_param(p2d_crun_status_t status)
{
    return (unsigned)status < P2D_CRUN_STATUS_COUNT ? STATUS[status].param : "";
}

const char *p2d_crun_status_text(p2d_crun_status_t status)
{
    return (unsigned)status < P2D_CRUN_STATUS_COUNT ? STATUS[status].text : "unknown status";
}

const char *p2d_crun_log_name(uint32_t column) { return column < P2D_CLOG_COUNT ? LOG_NAMES[column] : ""; }
