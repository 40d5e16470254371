/*
 * Speed sensor, current measurement and field weakening of the simulation engine: see sensing.h.
 */
#include "sensing.h"

#include <math.h>

#define P2D_SENSING_INV_SQRT3 0.57735026918962576 /* 1 / sqrt(3) */
#define P2D_SENSING_WHOLE_TOL 1e-9                /* a delay this close to whole current periods is whole [-] */

static bool is_nonnegative(double x) { return isfinite(x) && x >= 0.0; }

/* The encoder configuration the engine runs: the speed period, and for the ideal sensor only its low-pass. */
static p2d_encoder_config_t encoder_config(const p2d_speed_sensor_config_t *speed, float Ts_speed_s)
{
    p2d_encoder_config_t e = speed->encoder;
    e.Ts_s = Ts_speed_s;
    if (speed->model == P2D_SPEED_SENSOR_IDEAL) {
        e.counts_per_rev = 1u;
        e.counter_bits = 32u;
        e.estimator = P2D_ESTIMATOR_DIFFERENCE;
        e.bandwidth_radps = 0.0f;
    }
    return e;
}

/* The regulator configuration the engine runs: the speed period. */
static p2d_field_weakening_config_t fw_config(const p2d_sim_field_weakening_config_t *fw, float Ts_speed_s)
{
    p2d_field_weakening_config_t c = fw->config;
    c.Ts_s = Ts_speed_s;
    return c;
}

p2d_sensing_check_t p2d_sensing_check(const p2d_speed_sensor_config_t *speed,
                                      const p2d_current_sensor_config_t *current,
                                      const p2d_sim_field_weakening_config_t *fw, double Ts_current_s, float Ts_speed_s,
                                      bool dq_pi, p2d_status_t *status)
{
    p2d_encoder_t enc;
    p2d_field_weakening_t reg;
    p2d_encoder_config_t ec = encoder_config(speed, Ts_speed_s);
    p2d_field_weakening_config_t fc = fw_config(fw, Ts_speed_s);
    bool measured;
    *status = P2D_OK;
    if ((unsigned)speed->model > (unsigned)P2D_SPEED_SENSOR_ENCODER) return P2D_SENSING_BAD_SPEED_SENSOR;
    if (!is_nonnegative(speed->delay_s) || speed->delay_s > (double)(P2D_SIM_HISTORY - 2) * Ts_current_s) {
        return P2D_SENSING_BAD_SPEED_SENSOR;
    }
    if (!is_nonnegative(speed->noise_rms_radps)) return P2D_SENSING_BAD_SPEED_SENSOR;
    *status = p2d_encoder_init(&enc, &ec);
    if (*status != P2D_OK) return P2D_SENSING_BAD_SPEED_SENSOR;
    measured = current->gain_error_a != 0.0 || current->gain_error_b != 0.0 || current->offset_a_A != 0.0 ||
               current->offset_b_A != 0.0 || current->noise_rms_A != 0.0;
    if (measured && !dq_pi) return P2D_SENSING_BAD_CURRENT_SENSOR;
    if (fw->enabled) {
        if (!dq_pi) return P2D_SENSING_BAD_FIELD_WEAKENING;
        *status = p2d_field_weakening_init(&reg, &fc);
        if (*status != P2D_OK) return P2D_SENSING_BAD_FIELD_WEAKENING;
    }
    return P2D_SENSING_VALID;
}

/* ---- angle and counts --------------------------------------------------- */

/* Angle and speed at boundary n (t = n Ts_current); before t = 0, theta = w_m0 t at w_m0. */
static void boundary(const p2d_sim_sensing_t *s, int64_t n, double Ts_current_s, double w_m0_radps, double *theta_rad,
                     double *w_radps)
{
    if (n < 0) {
        *theta_rad = w_m0_radps * (double)n * Ts_current_s;
        *w_radps = w_m0_radps;
        return;
    }
    *theta_rad = s->theta_hist_rad[(uint64_t)n % P2D_SIM_HISTORY];
    *w_radps = s->w_hist_radps[(uint64_t)n % P2D_SIM_HISTORY];
}

/*
 * Angle and speed at t = (n + f) Ts_current, f in [0, 1): the cubic Hermite polynomial of theta
 * through (theta_n, w_n) and (theta_n+1, w_n+1), h = Ts_current,
 *   theta(f) = (2f^3 - 3f^2 + 1) theta_n + (f^3 - 2f^2 + f) h w_n + (-2f^3 + 3f^2) theta_n+1 + (f^3 - f^2) h w_n+1,
 * and its derivative for the speed; f = 0 gives (theta_n, w_n) exactly.
 */
static void angle_at(const p2d_sim_sensing_t *s, int64_t n, double f, double Ts_current_s, double w_m0_radps,
                     double *theta_rad, double *w_radps)
{
    double th0, w0, th1, w1, f2, f3;
    boundary(s, n, Ts_current_s, w_m0_radps, &th0, &w0);
    if (f == 0.0) {
        *theta_rad = th0;
        *w_radps = w0;
        return;
    }
    boundary(s, n + 1, Ts_current_s, w_m0_radps, &th1, &w1);
    f2 = f * f;
    f3 = f2 * f;
    *theta_rad = (2.0 * f3 - 3.0 * f2 + 1.0) * th0 + (f3 - 2.0 * f2 + f) * Ts_current_s * w0 +
                 (3.0 * f2 - 2.0 * f3) * th1 + (f3 - f2) * Ts_current_s * w1;
    *w_radps =
        (6.0 * f2 - 6.0 * f) * (th0 - th1) / Ts_current_s + (3.0 * f2 - 4.0 * f + 1.0) * w0 + (3.0 * f2 - 2.0 * f) * w1;
}

/* The delay in current periods as whole periods and a fraction; a fraction within 1e-9 of 0 or 1 is 0. */
static void delay_periods(double delay_s, double Ts_current_s, uint64_t *whole, double *frac)
{
    double d = delay_s / Ts_current_s;
    double r = floor(d + 0.5);
    if (fabs(d - r) <= P2D_SENSING_WHOLE_TOL * fmax(1.0, d)) {
        *whole = (uint64_t)r;
        *frac = 0.0;
        return;
    }
    *whole = (uint64_t)floor(d);
    *frac = d - floor(d);
}

/* ---- public ------------------------------------------------------------- */

void p2d_sensing_init(p2d_sim_sensing_t *s, const p2d_speed_sensor_config_t *speed,
                      const p2d_current_sensor_config_t *current, const p2d_sim_field_weakening_config_t *fw,
                      float Ts_speed_s, double w_m0_radps)
{
    p2d_encoder_config_t ec = encoder_config(speed, Ts_speed_s);
    p2d_field_weakening_config_t fc = fw_config(fw, Ts_speed_s);
    double theta_prev;
    s->current_sensor = current->gain_error_a != 0.0 || current->gain_error_b != 0.0 || current->offset_a_A != 0.0 ||
                        current->offset_b_A != 0.0 || current->noise_rms_A != 0.0;
    s->history = speed->delay_s > 0.0;
    s->angle = speed->model == P2D_SPEED_SENSOR_ENCODER || s->current_sensor || s->history;
    (void)p2d_encoder_init(&s->encoder, &ec);
    /* the previous reading, one speed period before the first: steady state at w_m0 */
    theta_prev = -w_m0_radps * ((double)Ts_speed_s + speed->delay_s);
    p2d_encoder_reset(&s->encoder, p2d_encoder_counter(ec.counts_per_rev, theta_prev), (float)w_m0_radps);
    s->w_lowpass_radps = (float)w_m0_radps;
    s->w_sensor_radps = w_m0_radps;
    s->speed_rng = speed->seed;
    if (fw->enabled) (void)p2d_field_weakening_init(&s->fw, &fc);
    s->ud_unsat_V = 0.0f;
    s->uq_unsat_V = 0.0f;
    p2d_sensing_record(s, 0u, 0.0, w_m0_radps);
}

void p2d_sensing_record(p2d_sim_sensing_t *s, uint64_t n_current, double theta_m_rad, double w_m_radps)
{
    if (!s->history) return;
    s->theta_hist_rad[n_current % P2D_SIM_HISTORY] = theta_m_rad;
    s->w_hist_radps[n_current % P2D_SIM_HISTORY] = w_m_radps;
}

bool p2d_sensing_speed(p2d_sim_sensing_t *s, const p2d_speed_sensor_config_t *speed, uint64_t n_current,
                       double Ts_current_s, double w_m0_radps, double theta_m_rad, double w_m_radps,
                       double *w_read_radps)
{
    double theta = theta_m_rad, w = w_m_radps, y;
    bool ok = true;
    if (s->history) {
        uint64_t whole;
        double frac;
        delay_periods(speed->delay_s, Ts_current_s, &whole, &frac);
        /* t_k - delay = (n_current - whole - frac) Ts_current = (n + f) Ts_current */
        if (frac > 0.0) {
            angle_at(s, (int64_t)n_current - (int64_t)whole - 1, 1.0 - frac, Ts_current_s, w_m0_radps, &theta, &w);
        } else {
            angle_at(s, (int64_t)n_current - (int64_t)whole, 0.0, Ts_current_s, w_m0_radps, &theta, &w);
        }
    }
    if (speed->model == P2D_SPEED_SENSOR_ENCODER) {
        p2d_encoder_output_t out;
        p2d_encoder_step(&s->encoder, p2d_encoder_counter(speed->encoder.counts_per_rev, theta), &out);
        ok = !out.fault;
        y = (double)out.w_m_radps;
    } else if (speed->encoder.lowpass_radps > 0.0f) {
        const p2d_encoder_coef_t *c = &s->encoder.coef[s->encoder.active];
        /* y[k] = q y[k-1] + (1 - q) w[k], float32 as the encoder's low-pass */
        s->w_lowpass_radps = fmaf(c->lowpass_pole, s->w_lowpass_radps, c->lowpass_one_minus_pole * (float)w);
        y = (double)s->w_lowpass_radps;
    } else {
        y = w;
    }
    if (speed->noise_rms_radps > 0.0) y += speed->noise_rms_radps * p2d_normal(&s->speed_rng);
    s->w_sensor_radps = y;
    *w_read_radps = y;
    return ok;
}

void p2d_sensing_currents(p2d_plant_t *plant, double *id_meas_A, double *iq_meas_A)
{
    double th_e = plant->p * plant->theta_m_rad, c = cos(th_e), sn = sin(th_e);
    double ia, ib, i_alpha, i_beta;
    p2d_plant_sense_currents(plant, &ia, &ib);
    /* i_alpha = ia', i_beta = (ia' + 2 ib') / sqrt(3) (ic' = -ia' - ib') */
    i_alpha = ia;
    i_beta = (ia + 2.0 * ib) * P2D_SENSING_INV_SQRT3;
    /* id' = i_alpha cos + i_beta sin, iq' = -i_alpha sin + i_beta cos */
    *id_meas_A = i_alpha * c + i_beta * sn;
    *iq_meas_A = -i_alpha * sn + i_beta * c;
}

bool p2d_sensing_field_weakening(p2d_sim_sensing_t *s, double u_dc_V, float *id_fw_A)
{
    p2d_field_weakening_output_t out;
    p2d_field_weakening_step(&s->fw, s->ud_unsat_V, s->uq_unsat_V, (float)u_dc_V, &out);
    *id_fw_A = out.id_ref_A;
    return !out.fault;
}
