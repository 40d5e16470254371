/*
 * Field-oriented control with the pmsm2dof controllers (paper Fig. 1: speed
 * controller of Fig. 6 outside, dq current controllers inside), configured by
 * p2d_config.h alone.
 *
 * Every control interrupt (1 / Ts_current):
 *   currents -> Clarke -> Park -> current controller -> inverse Park -> SVPWM
 * and every P2D_CONFIG_CURRENT_PER_SPEED-th interrupt first the speed sample:
 *   speed reading (encoder estimator, or the rotor speed through the low-pass)
 *   -> inertia estimator and gain scheduling (when configured)
 *   -> field weakening's d-axis bound (when configured)
 *   -> speed controller (torque filters inside it when configured)
 * whose current references are then held for the next
 * P2D_CONFIG_CURRENT_PER_SPEED current samples. This is the sampled-data loop
 * of the simulation engine (csrc/sim/drive.h), in the same order, so that the
 * firmware on the virtual board (board_virtual.c) reproduces the engine's
 * simulation of the same scenario.
 *
 * Each controller runs as compute, apply, update: the update receives the
 * command that was actually applied after every limit downstream, which is
 * what makes the back-calculation anti-windup (Fig. 5) see the true u*.
 */
#include "foc.h"

#include <math.h>

#include "board.h"
#include "pmsm2dof/current.h"
#include "pmsm2dof/encoder.h"
#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/filter.h"
#include "pmsm2dof/inertia.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/transforms.h"

/*
 * Written by `pmsm2dof header` (or firmware, design --emit-c-header, autotune
 * --emit-c-header, commission --out, the tuner's download): the configuration
 * of every controller, P2D_CONFIG_CURRENT_PER_SPEED and the switches below.
 */
#include "p2d_config.h"

#if !defined(P2D_CONFIG_CURRENT_PER_SPEED) || !defined(P2D_CONFIG_TS_CURRENT_S) || !defined(P2D_CONFIG_TS_SPEED_S) || \
    !defined(P2D_CONFIG_ENCODER) || !defined(P2D_CONFIG_FIELD_WEAKENING) || !defined(P2D_CONFIG_INERTIA)
#error "p2d_config.h is not a pmsm2dof configuration: write it with `pmsm2dof header SCENARIO --out p2d_config.h`"
#endif

#define FOC_STR2(x) #x
#define FOC_STR(x) FOC_STR2(x)

/* The loop ratio, an integer, checked when the firmware is built. */
#define FOC_RATIO_TEXT "P2D_CONFIG_CURRENT_PER_SPEED = " FOC_STR(P2D_CONFIG_CURRENT_PER_SPEED)
__extension__ _Static_assert(P2D_CONFIG_CURRENT_PER_SPEED >= 1u &&
                                 P2D_CONFIG_CURRENT_PER_SPEED <= FOC_CURRENT_PER_SPEED_MAX,
                             FOC_RATIO_TEXT
                             ": the speed loop runs every 1 to " FOC_STR(FOC_CURRENT_PER_SPEED_MAX) " current periods");
#if defined(__GNUC__) && !defined(__clang__)
/* GCC folds floating constants in a static assertion (clang does not: foc_init checks it at run time). */
#define FOC_TS_ERROR ((double)P2D_CONFIG_TS_SPEED_S - P2D_CONFIG_CURRENT_PER_SPEED * (double)P2D_CONFIG_TS_CURRENT_S)
__extension__ _Static_assert(
    FOC_TS_ERROR <= 1e-6 * (double)P2D_CONFIG_TS_SPEED_S && FOC_TS_ERROR >= -1e-6 * (double)P2D_CONFIG_TS_SPEED_S,
    "P2D_CONFIG_TS_SPEED_S = " FOC_STR(P2D_CONFIG_TS_SPEED_S) " is not " FOC_RATIO_TEXT
                                                              " times P2D_CONFIG_TS_CURRENT_S "
                                                              "= " FOC_STR(P2D_CONFIG_TS_CURRENT_S));
#endif

#define FOC_TWO_PI_INV 0.15915494f /* 1 / (2 pi) */

static p2d_speed_t speed_ctl;                 /* speed controller */
static p2d_current_t current_ctl;             /* dq current controllers */
static p2d_encoder_t encoder;                 /* encoder estimator (ideal sensor: its low-pass coefficients) */
static p2d_field_weakening_t field_weakening; /* field-weakening regulator */
static p2d_inertia_t inertia;                 /* inertia estimator */
static float pole_pairs;                      /* p [-] */
static uint32_t tick;         /* interrupts since the last speed sample, 0 .. P2D_CONFIG_CURRENT_PER_SPEED-1 */
static float w_lowpass_radps; /* ideal sensor: low-pass output y[k-1] [rad/s] */
static float ud_unsat_V;      /* current controller's last d voltage before its limit [V] */
static float uq_unsat_V;      /* current controller's last q voltage before its limit [V] */
static float T_sum_Nm;        /* inertia estimator: sum of the torques of this speed period [Nm] */
static uint32_t n_T;          /* inertia estimator: number of those torques [-] */
static float reference_radps; /* speed reference of the next speed samples [rad/s] */
foc_signals_t foc_now;        /* what the last interrupt computed (measured by the XCP master: global) */

/* |a - b| <= tol |b| */
static bool nearly_equal(float a, float b, float tol) { return fabsf(a - b) <= tol * fabsf(b); }

foc_status_t foc_init(void)
{
    foc_status_t st = {FOC_OK, P2D_OK};
    const float Ts_speed_s = p2d_config_speed.Ts_s, Ts_current_s = p2d_config_current.Ts_s;

    st.status = p2d_speed_init(&speed_ctl, &p2d_config_speed);
    if (st.status != P2D_OK) {
        st.part = FOC_ERR_SPEED;
        return st;
    }
    /* the torque filters, if any (p2d_speed_init leaves none) */
    if (p2d_config_speed_filter.notch_freq_Hz != 0.0f || p2d_config_speed_filter.lowpass_freq_Hz != 0.0f) {
        st.status = p2d_speed_set_filter(&speed_ctl, &p2d_config_speed_filter);
        if (st.status != P2D_OK) {
            st.part = FOC_ERR_SPEED_FILTER;
            return st;
        }
    }
    st.status = p2d_current_init(&current_ctl, &p2d_config_current);
    if (st.status != P2D_OK) {
        st.part = FOC_ERR_CURRENT;
        return st;
    }
    /* the speed controller was designed for Ts_speed = P2D_CONFIG_CURRENT_PER_SPEED Ts_current */
    if (!nearly_equal(Ts_speed_s, (float)P2D_CONFIG_CURRENT_PER_SPEED * Ts_current_s, 1e-6f) ||
        !nearly_equal(p2d_config_encoder.Ts_s, Ts_speed_s, 1e-6f)) {
        st.part = FOC_ERR_LOOP_RATIO;
        st.status = P2D_ERR_TS;
        return st;
    }
    st.status = p2d_encoder_init(&encoder, &p2d_config_encoder);
    if (st.status != P2D_OK) {
        st.part = FOC_ERR_ENCODER;
        return st;
    }
    if (P2D_CONFIG_FIELD_WEAKENING) {
        st.status = p2d_field_weakening_init(&field_weakening, &p2d_config_field_weakening);
        if (st.status != P2D_OK) {
            st.part = FOC_ERR_FIELD_WEAKENING;
            return st;
        }
    }
    if (P2D_CONFIG_INERTIA) {
        st.status = p2d_inertia_init(&inertia, &p2d_config_inertia);
        if (st.status != P2D_OK) {
            st.part = FOC_ERR_INERTIA;
            return st;
        }
    }
    pole_pairs = (float)p2d_config_speed.pole_pairs;
    foc_now.J_est_kgm2 = P2D_CONFIG_INERTIA ? p2d_config_inertia.J0_kgm2 : 0.0f;
    foc_now.J_gains_kgm2 = p2d_config_speed.J_kgm2;
    return st;
}

void foc_start(float w_m_radps, float T_Nm)
{
    p2d_speed_output_t spd;
    const p2d_current_config_t *cc = &p2d_config_current;
    /* the encoder's previous reading, one speed period ago at w_m: n[-1] = n[0] + floor(-w_m Ts counts / (2 pi)) */
    float dn_counts =
        floorf(-w_m_radps * p2d_config_encoder.Ts_s * (float)p2d_config_encoder.counts_per_rev * FOC_TWO_PI_INV);
    uint32_t count = board_read_encoder_count() + (uint32_t)(int32_t)dn_counts;

    p2d_speed_reset(&speed_ctl, w_m_radps, T_Nm);
    p2d_speed_compute(&speed_ctl, w_m_radps, w_m_radps, &spd);
    foc_now.id_ref_A = spd.id_ref_A;
    foc_now.iq_ref_A = spd.iq_ref_A;
    foc_now.w_ref_radps = w_m_radps;
    foc_now.w_meas_radps = w_m_radps;
    foc_now.T_ref_Nm = spd.T_ref_Nm;
    foc_now.T_unsat_Nm = spd.T_unsat_Nm;
    /*
     * the current integrators at the steady state of eq 1 for these currents: zero error gives
     * ud = x_d - w_e Lq iq and uq = x_q + w_e (Ld id + psi_f) with the decoupling, so x_d = Rs id, x_q = Rs iq
     */
    p2d_current_reset(&current_ctl);
    current_ctl.x_d_V = cc->Rs_ohm * spd.id_ref_A;
    current_ctl.x_q_V = cc->Rs_ohm * spd.iq_ref_A;
    p2d_encoder_reset(&encoder, count, w_m_radps);
    w_lowpass_radps = w_m_radps;
    if (P2D_CONFIG_FIELD_WEAKENING) p2d_field_weakening_reset(&field_weakening, 0.0f);
    ud_unsat_V = 0.0f;
    uq_unsat_V = 0.0f;
    T_sum_Nm = 0.0f;
    n_T = 0u;
    tick = 0u;
}

const foc_signals_t *foc_signals(void) { return &foc_now; }

float foc_current_period_s(void) { return p2d_config_current.Ts_s; }

void foc_set_speed_reference(float w_ref_radps) { reference_radps = w_ref_radps; }

p2d_status_t foc_set_speed_config(const p2d_speed_config_t *cfg)
{
    p2d_status_t st;
    if (cfg->Ts_s != speed_ctl.config.Ts_s) return P2D_ERR_TS;
    if (cfg->pole_pairs != speed_ctl.config.pole_pairs) return P2D_ERR_POLE_PAIRS;
    st = p2d_speed_set_config(&speed_ctl, cfg);
    if (st == P2D_OK) foc_now.J_gains_kgm2 = cfg->J_kgm2;
    return st;
}

p2d_status_t foc_set_current_config(const p2d_current_config_t *cfg)
{
    if (cfg->Ts_s != current_ctl.config.Ts_s) return P2D_ERR_TS;
    return p2d_current_set_config(&current_ctl, cfg);
}

const p2d_speed_config_t *foc_speed_config(void) { return &speed_ctl.config; }

const p2d_current_config_t *foc_current_config(void) { return &current_ctl.config; }

/* Space-vector modulation by min-max zero-sequence injection (foc.h). */
bool foc_modulate(float u_alpha_V, float u_beta_V, float u_dc_V, float *u_alpha_app_V, float *u_beta_app_V)
{
    float u[3], duty[3], u_max, u_min;
    bool clipped = false;

    if (!(u_dc_V > 0.0f)) {
        /* no DC link: zero voltage */
        board_write_duties(0.5f, 0.5f, 0.5f);
        *u_alpha_app_V = 0.0f;
        *u_beta_app_V = 0.0f;
        return true;
    }
    p2d_inv_clarke(u_alpha_V, u_beta_V, &u[0], &u[1], &u[2]);
    u_max = u[0] > u[1] ? u[0] : u[1];
    u_max = u_max > u[2] ? u_max : u[2];
    u_min = u[0] < u[1] ? u[0] : u[1];
    u_min = u_min < u[2] ? u_min : u[2];
    for (int n = 0; n < 3; ++n) {
        /* duty = 1/2 + (u - (u_max + u_min)/2) / u_dc, clipped to [0, 1] */
        float d = 0.5f + (u[n] - 0.5f * (u_max + u_min)) / u_dc_V;
        duty[n] = d < 0.0f ? 0.0f : (d > 1.0f ? 1.0f : d);
        clipped = clipped || duty[n] != d;
        /* phase voltage applied, up to the common mode that the Clarke transform removes */
        u[n] = (duty[n] - 0.5f) * u_dc_V;
    }
    board_write_duties(duty[0], duty[1], duty[2]);
    p2d_clarke(u[0], u[1], u[2], u_alpha_app_V, u_beta_app_V);
    return clipped;
}

/*
 * Inertia estimator and gain scheduling at a speed sample (as csrc/sim/adapt.h): the estimator
 * steps with the speed reading and the mean torque of the period that ends now; when its J is
 * valid, the sample quiet (reference unchanged, output inside the limit, |error| small) and J has
 * moved by more than P2D_CONFIG_ADAPT_REL_CHANGE, the speed controller is re-designed for it.
 */
static void inertia_sample(float w_ref_radps, float w_meas_radps)
{
    p2d_inertia_output_t est;
    /* the first speed sample has no period behind it */
    if (n_T == 0u) return;
    p2d_inertia_step(&inertia, w_meas_radps, T_sum_Nm / (float)n_T, &est);
    T_sum_Nm = 0.0f;
    n_T = 0u;
    foc_now.J_est_kgm2 = est.J_kgm2;
    foc_now.J_valid = est.J_valid;
    foc_now.T_load_est_Nm = est.T_load_Nm;
    if (!P2D_CONFIG_ADAPT_GAINS || !est.J_valid || foc_now.saturated || w_ref_radps != speed_ctl.r_prev_radps ||
        !(fabsf(w_ref_radps - w_meas_radps) <= P2D_CONFIG_ADAPT_ERROR_RADPS)) {
        return;
    }
    if (fabsf(est.J_kgm2 - foc_now.J_gains_kgm2) > P2D_CONFIG_ADAPT_REL_CHANGE * foc_now.J_gains_kgm2) {
        p2d_speed_config_t c = speed_ctl.config;
        c.J_kgm2 = est.J_kgm2;
        if (P2D_CONFIG_KA_FOLLOWS_J) c.Ka = p2d_speed_Ka_default(c.J_kgm2, c.alpha_radps);
        /* bumpless (p2d_speed_set_config keeps the state); a rejected design changes nothing */
        if (p2d_speed_set_config(&speed_ctl, &c) == P2D_OK) foc_now.J_gains_kgm2 = est.J_kgm2;
    }
}

/* The speed loop: reading, estimator, field weakening, speed controller; sets the current references. */
static void speed_sample(void)
{
    p2d_speed_output_t spd;
    float w_ref_radps = reference_radps, w_meas_radps, id_fw_A = 0.0f;

    if (P2D_CONFIG_ENCODER) {
        p2d_encoder_output_t enc;
        p2d_encoder_step(&encoder, board_read_encoder_count(), &enc);
        w_meas_radps = enc.w_m_radps;
    } else if (p2d_config_encoder.lowpass_radps > 0.0f) {
        const p2d_encoder_coef_t *c = &encoder.coef[encoder.active];
        /* the encoder's low-pass on the speed as measured: y[k] = q y[k-1] + (1 - q) w[k] */
        w_lowpass_radps = fmaf(c->lowpass_pole, w_lowpass_radps, c->lowpass_one_minus_pole * board_read_speed_radps());
        w_meas_radps = w_lowpass_radps;
    } else {
        w_meas_radps = board_read_speed_radps();
    }
    if (P2D_CONFIG_INERTIA) inertia_sample(w_ref_radps, w_meas_radps);
    if (P2D_CONFIG_FIELD_WEAKENING) {
        p2d_field_weakening_output_t fw;
        p2d_field_weakening_step(&field_weakening, ud_unsat_V, uq_unsat_V, board_read_dc_link_V(), &fw);
        id_fw_A = fw.id_ref_A;
        p2d_speed_compute_fw(&speed_ctl, w_ref_radps, w_meas_radps, id_fw_A, &spd);
    } else {
        p2d_speed_compute(&speed_ctl, w_ref_radps, w_meas_radps, &spd);
    }
    /*
     * Apply. The references go to the current loop as computed, so the applied torque is
     * spd.T_ref_Nm (zero after a fault: non-finite speed). A further limit here (thermal
     * derating, ...) must change the current references and pass its limited torque to the update.
     */
    foc_now.id_ref_A = spd.id_ref_A;
    foc_now.iq_ref_A = spd.iq_ref_A;
    p2d_speed_update(&speed_ctl, &spd, spd.T_ref_Nm);
    foc_now.w_ref_radps = w_ref_radps;
    foc_now.w_meas_radps = w_meas_radps;
    foc_now.T_unsat_Nm = spd.T_unsat_Nm;
    foc_now.T_ref_Nm = spd.T_ref_Nm;
    foc_now.saturated = spd.saturated;
    foc_now.x_i_Nm = p2d_speed_integrator_Nm(&speed_ctl);
    foc_now.id_fw_A = id_fw_A;
}

void foc_isr(void)
{
    float ia_A, ib_A, ic_A, i_alpha_A, i_beta_A, id_A, iq_A;
    float theta_m_rad, w_m_radps, theta_e_rad, sin_e, cos_e, w_e_radps, u_dc_V;
    float u_alpha_V, u_beta_V, u_alpha_app_V, u_beta_app_V, ud_app_V, uq_app_V;
    p2d_current_output_t cur;

    board_read_phase_currents(&ia_A, &ib_A, &ic_A);
    u_dc_V = board_read_dc_link_V();
    board_read_rotor(&theta_m_rad, &w_m_radps);
    /* electrical angle and speed: theta_e = p theta_m, w_e = p w_m (sinf/cosf: or your sine table, CORDIC) */
    theta_e_rad = pole_pairs * theta_m_rad;
    sin_e = sinf(theta_e_rad);
    cos_e = cosf(theta_e_rad);
    w_e_radps = pole_pairs * w_m_radps;
    p2d_clarke(ia_A, ib_A, ic_A, &i_alpha_A, &i_beta_A);
    p2d_park(i_alpha_A, i_beta_A, sin_e, cos_e, &id_A, &iq_A);

    /* speed loop, every P2D_CONFIG_CURRENT_PER_SPEED-th interrupt */
    foc_now.speed_sample = tick == 0u;
    if (tick == 0u) speed_sample();
    tick = tick + 1u == P2D_CONFIG_CURRENT_PER_SPEED ? 0u : tick + 1u;

    /* current loop, every interrupt */
    p2d_current_compute(&current_ctl, foc_now.id_ref_A, foc_now.iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V, &cur);
    p2d_inv_park(cur.ud_ref_V, cur.uq_ref_V, sin_e, cos_e, &u_alpha_V, &u_beta_V);
    if (foc_modulate(u_alpha_V, u_beta_V, u_dc_V, &u_alpha_app_V, &u_beta_app_V)) {
        /* the modulator limited the voltage: the integrators must see what it applied, in dq */
        p2d_park(u_alpha_app_V, u_beta_app_V, sin_e, cos_e, &ud_app_V, &uq_app_V);
    } else {
        /*
         * applied as commanded: pass the command itself, not its round trip
         * through the transforms, whose rounding would make u* a tiny non-zero
         * value (and flip the clamping mode's sign test at random)
         */
        ud_app_V = cur.ud_ref_V;
        uq_app_V = cur.uq_ref_V;
    }
    p2d_current_update(&current_ctl, &cur, ud_app_V, uq_app_V);
    ud_unsat_V = cur.ud_unsat_V;
    uq_unsat_V = cur.uq_unsat_V;

    /* the inertia estimator's torque: the mean over the speed period of Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
    if (P2D_CONFIG_INERTIA) {
        const p2d_current_config_t *cc = &p2d_config_current;
        T_sum_Nm += 1.5f * pole_pairs * (cc->psi_f_Wb + (cc->Ld_H - cc->Lq_H) * id_A) * iq_A;
        n_T++;
    }
    foc_now.id_A = id_A;
    foc_now.iq_A = iq_A;
    foc_now.ud_ref_V = cur.ud_ref_V;
    foc_now.uq_ref_V = cur.uq_ref_V;
    foc_now.voltage_limited = cur.saturated;
    foc_now.fault_count = speed_ctl.fault_count + current_ctl.fault_count + encoder.fault_count;
}
