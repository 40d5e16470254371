/*
 * Unit tests of the speed controller (pmsm2dof/speed.h). Expected values are
 * derived by hand from the paper's equations (eq 9, 13-15, Fig. 5) in double.
 */
#include <float.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/transforms.h"

/* A surface PMSM: J = 0.02 kg m^2, alpha = 200 rad/s, zeta = 1, Ts = 100 us, 10 A, p = 4. */
static p2d_speed_config_t surface_config(void)
{
    p2d_speed_config_t cfg;
    cfg.J_kgm2 = 0.02f;
    cfg.alpha_radps = 200.0f;
    cfg.zeta = 1.0f;
    cfg.m = 1.0f;
    cfg.tau_i_s = 0.0f;
    cfg.Ka = 1.0f / (0.02f * 200.0f);
    cfg.Ts_s = 1e-4f;
    cfg.i_max_A = 10.0f;
    cfg.psi_f_Wb = 0.05f;
    cfg.Ld_H = 2e-3f;
    cfg.Lq_H = 2e-3f;
    cfg.pole_pairs = 4u;
    cfg.method = P2D_TUSTIN;
    cfg.feedforward = P2D_FF_NONE;
    cfg.anti_windup = P2D_AW_BACK_CALCULATION;
    return cfg;
}

static p2d_status_t init_with(p2d_speed_config_t cfg)
{
    p2d_speed_t ctl;
    return p2d_speed_init(&ctl, &cfg);
}

static void test_validation(void)
{
    p2d_speed_config_t cfg;
    p2d_speed_t ctl;
    p2d_speed_t before;

    CHECK(init_with(surface_config()) == P2D_OK);
    cfg = surface_config();
    cfg.J_kgm2 = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_J);
    cfg = surface_config();
    cfg.J_kgm2 = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_J);
    cfg = surface_config();
    cfg.alpha_radps = NAN;
    CHECK(init_with(cfg) == P2D_ERR_ALPHA);
    cfg = surface_config();
    cfg.zeta = -0.5f;
    CHECK(init_with(cfg) == P2D_ERR_ZETA);
    cfg = surface_config();
    cfg.m = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_M);
    cfg = surface_config();
    cfg.tau_i_s = -1e-3f;
    CHECK(init_with(cfg) == P2D_ERR_TAU_I);
    cfg = surface_config();
    cfg.Ts_s = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = surface_config();
    cfg.i_max_A = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_I_MAX);
    cfg = surface_config();
    cfg.Ka = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_KA);
    cfg = surface_config();
    cfg.Ka = -1.0f;
    cfg.anti_windup = P2D_AW_NONE;
    CHECK(init_with(cfg) == P2D_ERR_KA);
    cfg = surface_config();
    cfg.psi_f_Wb = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_PSI_F);
    cfg = surface_config();
    cfg.Ld_H = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_LD);
    cfg = surface_config();
    cfg.Lq_H = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_LQ);
    cfg = surface_config();
    cfg.pole_pairs = 0u;
    CHECK(init_with(cfg) == P2D_ERR_POLE_PAIRS);
    cfg = surface_config();
    cfg.method = (p2d_method_t)3;
    CHECK(init_with(cfg) == P2D_ERR_METHOD);
    cfg = surface_config();
    cfg.feedforward = (p2d_feedforward_t)4;
    CHECK(init_with(cfg) == P2D_ERR_FEEDFORWARD);
    cfg = surface_config();
    cfg.anti_windup = (p2d_anti_windup_t)3;
    CHECK(init_with(cfg) == P2D_ERR_ANTI_WINDUP);
    cfg = surface_config();
    cfg.feedforward = P2D_FF_LOWPASS;
    cfg.m = 2.0f;
    CHECK(init_with(cfg) == P2D_ERR_M_LOWPASS);
    /* back calculation: Ki Ka Ts = 100^2 * 0.02 * 1000 * 1e-4 = 20 >= 2 */
    cfg = surface_config();
    cfg.Ka = 1000.0f;
    CHECK(init_with(cfg) == P2D_ERR_KA);
    /* forward-Euler feedforward pole 1 - m alpha Ts: m alpha Ts = 2 is rejected, but only with a feedforward */
    cfg = surface_config();
    cfg.method = P2D_FORWARD_EULER;
    cfg.Ts_s = 0.01f;
    cfg.anti_windup = P2D_AW_NONE;
    CHECK(init_with(cfg) == P2D_OK);
    cfg.feedforward = P2D_FF_NO_TAU;
    CHECK(init_with(cfg) == P2D_ERR_TS_UNSTABLE);
    cfg = surface_config();
    CHECK(p2d_speed_init(0, &cfg) == P2D_ERR_NULL);
    CHECK(p2d_speed_init(&ctl, 0) == P2D_ERR_NULL);

    /* a failed init leaves the object untouched */
    memset(&ctl, 0x5a, sizeof ctl);
    before = ctl;
    cfg = surface_config();
    cfg.zeta = 0.0f;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_ERR_ZETA);
    CHECK(memcmp(&ctl, &before, sizeof ctl) == 0);

    /* every code names its parameter and range */
    for (int s = 1; s < (int)P2D_STATUS_COUNT; ++s) {
        CHECK(p2d_status_param((p2d_status_t)s)[0] != '\0');
        CHECK(p2d_status_range((p2d_status_t)s)[0] != '\0');
    }
    CHECK(strcmp(p2d_status_param(P2D_ERR_J), "J_kgm2") == 0);
    CHECK(strcmp(p2d_status_param(P2D_ERR_M_LOWPASS), "m") == 0);
}

static void test_gains(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    const p2d_speed_coef_t *c;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    c = &ctl.coef[ctl.active];
    /* eq 9: Kp = J alpha = 4, Ki = J (alpha / 2 zeta)^2 = 200 */
    CHECK_CLOSE(c->pi.Kp, 4.0, 1e-6);
    CHECK_CLOSE(c->pi.Ki, 200.0, 1e-4);
    /* surface PMSM: T_max = 1.5 p psi_f i_max = 3 Nm */
    CHECK_CLOSE(c->T_max_Nm, 3.0, 1e-6);
    CHECK_CLOSE(p2d_speed_Ka_default(0.02f, 200.0f), 0.25, 1e-7);
}

/* eq 14, Tustin, constant error e from rest: u[k] = Kp e + Ki Ts e (k + 1/2) */
static void test_tustin_pi_sequence(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double Kp = 4.0, Ki = 200.0, Ts = 1e-4, e = 0.5;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 5; ++k) {
        p2d_speed_step(&ctl, 0.5f, 0.0f, &out);
        CHECK_CLOSE(out.T_unsat_Nm, Kp * e + Ki * Ts * e * (k + 0.5), 1e-5);
        CHECK(!out.saturated);
        /* surface PMSM: id = 0, iq = T / (1.5 p psi_f) */
        CHECK(out.id_ref_A == 0.0f);
        CHECK_CLOSE(out.iq_ref_A, out.T_ref_Nm / 0.3, 1e-5);
    }
}

/* Backward and forward Euler of the integrator: u[k] = Kp e + Ki Ts e (k + 1) and (k) */
static void test_euler_pi_sequences(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    cfg.method = P2D_BACKWARD_EULER;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 4; ++k) {
        p2d_speed_step(&ctl, 0.5f, 0.0f, &out);
        CHECK_CLOSE(out.T_unsat_Nm, 0.5 * (4.0 + 200.0 * 1e-4 * (k + 1)), 1e-5);
    }
    cfg.method = P2D_FORWARD_EULER;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 4; ++k) {
        p2d_speed_step(&ctl, 0.5f, 0.0f, &out);
        CHECK_CLOSE(out.T_unsat_Nm, 0.5 * (4.0 + 200.0 * 1e-4 * k), 1e-5);
    }
}

/*
 * Sustained saturating error e. Fixed point of x = x + Ki Ts e + Ki Ka Ts (T_max - b_e0 e - x):
 * x* = T_max - b_e0 e + e / Ka (back calculation); clamping holds x; none grows by Ki Ts e.
 */
static void test_anti_windup_modes(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double e = 100.0, b_e0 = 4.0 + 0.5 * 200.0 * 1e-4, Ka = 0.25;

    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 20000; ++k) p2d_speed_step(&ctl, 100.0f, 0.0f, &out);
    CHECK(out.saturated);
    CHECK_CLOSE(out.T_ref_Nm, 3.0, 1e-6);
    CHECK_CLOSE(out.iq_ref_A, 10.0, 1e-5);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 3.0 - b_e0 * e + e / Ka, 1e-3);

    cfg.anti_windup = P2D_AW_CLAMPING;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 1000; ++k) p2d_speed_step(&ctl, 100.0f, 0.0f, &out);
    CHECK(p2d_speed_integrator_Nm(&ctl) == 0.0f);
    /* the error reverses: integration resumes at once */
    p2d_speed_step(&ctl, -0.001f, 0.0f, &out);
    CHECK(!out.saturated);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), -0.001 * 200.0 * 1e-4, 1e-9);

    cfg.anti_windup = P2D_AW_NONE;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 1000; ++k) p2d_speed_step(&ctl, 100.0f, 0.0f, &out);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 1000 * 200.0 * 1e-4 * e, 0.05);
}

/* update() uses the torque actually applied: u* = T_applied - u */
static void test_update_with_applied_torque(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_compute(&ctl, 0.2f, 0.0f, &out);
    CHECK(p2d_speed_integrator_Nm(&ctl) == 0.0f); /* compute leaves the state alone */
    p2d_speed_update(&ctl, &out, 0.5f);
    /* x[0] = Ki Ts e + Ki Ka Ts (0.5 - u) */
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 200e-4 * 0.2 + 200e-4 * 0.25 * (0.5 - out.T_unsat_Nm), 1e-7);
}

static void test_non_finite_policy(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_t before;
    p2d_speed_output_t out;
    cfg.feedforward = P2D_FF_LOWPASS;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_step(&ctl, 10.0f, 1.0f, &out);
    before = ctl;
    p2d_speed_step(&ctl, 10.0f, NAN, &out);
    CHECK(out.fault);
    CHECK(out.T_ref_Nm == 0.0f && out.id_ref_A == 0.0f && out.iq_ref_A == 0.0f);
    CHECK(ctl.x_Nm == before.x_Nm);
    CHECK(ctl.y_ff_prev_Nm == before.y_ff_prev_Nm);
    CHECK(ctl.r_prev_radps == before.r_prev_radps);
    CHECK(ctl.fault_count == 1u);
    p2d_speed_step(&ctl, INFINITY, 1.0f, &out);
    CHECK(out.fault && ctl.fault_count == 2u && ctl.x_Nm == before.x_Nm);
    /* a non-finite applied torque is refused too */
    p2d_speed_compute(&ctl, 10.0f, 1.0f, &out);
    p2d_speed_update(&ctl, &out, NAN);
    CHECK(ctl.fault_count == 3u && ctl.x_Nm == before.x_Nm);
    p2d_speed_step(&ctl, 10.0f, 1.0f, &out);
    CHECK(!out.fault && isfinite(out.T_ref_Nm));
    /* a non-finite reset clears the state and counts a fault */
    p2d_speed_reset(&ctl, NAN, 1.0f);
    CHECK(ctl.fault_count == 4u && ctl.x_Nm == 0.0f && ctl.r_prev_radps == 0.0f);
}

/* Bumpless reset: at zero error and constant reference the output is T_init */
static void test_reset(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    cfg.feedforward = P2D_FF_LOWPASS;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_reset(&ctl, 50.0f, 1.25f);
    /* eq 13 at s = 0: Fr(0) r = -Ki / alpha r = -50 Nm, no transient; u = x = 1.25 Nm at e = 0 */
    CHECK(ctl.y_ff_prev_Nm == 0.0f && ctl.r_prev_radps == 50.0f);
    CHECK(ctl.x_Nm == 1.25f);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 1.25 + 200.0 / 200.0 * 50.0, 1e-5);
    for (int k = 0; k < 3; ++k) {
        p2d_speed_step(&ctl, 50.0f, 50.0f, &out);
        CHECK_CLOSE(out.T_ff_Nm, -50.0, 1e-5);
        CHECK_CLOSE(out.T_unsat_Nm, 1.25, 1e-5);
    }
    p2d_speed_reset(&ctl, 0.0f, 0.0f);
    CHECK(ctl.x_Nm == 0.0f && ctl.y_ff_prev_Nm == 0.0f && ctl.r_prev_radps == 0.0f);
}

/* Lowpass feedforward, Tustin (eq 15): y[k] = ((2 - a Ts) y[k-1] - Ki Ts (r[k] + r[k-1])) / (2 + a Ts) */
static void test_lowpass_feedforward_sequence(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double a = 200.0, Ki = 200.0, Ts = 1e-4;
    double y = 0.0, r_prev = 0.0;
    cfg.feedforward = P2D_FF_LOWPASS;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 50; ++k) {
        double r = k < 10 ? 0.0 : 10.0;
        y = ((2.0 - a * Ts) * y - Ki * Ts * (r + r_prev)) / (2.0 + a * Ts);
        r_prev = r;
        p2d_speed_step(&ctl, (float)r, (float)r, &out);
        CHECK_CLOSE(out.T_ff_Nm, y, 1e-4);
    }
}

/* Parameter update: atomic, keeps the state; an invalid update changes nothing */
static void test_set_config(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_speed_t before;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 10; ++k) p2d_speed_step(&ctl, 1.0f, 0.0f, &out);
    before = ctl;
    cfg.zeta = -1.0f;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_ERR_ZETA);
    CHECK(ctl.active == before.active);
    CHECK(memcmp(&ctl.coef[ctl.active], &before.coef[before.active], sizeof ctl.coef[0]) == 0);
    CHECK(ctl.config.zeta == 1.0f);
    cfg.zeta = 2.0f;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_OK);
    CHECK(ctl.active != before.active);
    CHECK(ctl.x_Nm == before.x_Nm);
    /* Ki = J (alpha / (2 zeta))^2 = 0.02 * 50^2 = 50 */
    CHECK_CLOSE(ctl.coef[ctl.active].pi.Ki, 50.0, 1e-4);
}

/*
 * A change of Fr(0) across set_config is bumpless: at a constant reference and
 * zero error u = x_i + Fr(0) r keeps its value, and the integral takes the
 * difference. Lowpass (eq 13): Fr(0) = -Ki / alpha = -J alpha / (4 zeta^2).
 */
static void test_set_config_bumpless_feedforward(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double J = 0.02, alpha = 200.0, r = 50.0, T0 = 1.25;
    double Fr0_old, Fr0_new;
    cfg.feedforward = P2D_FF_LOWPASS;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_reset(&ctl, (float)r, (float)T0);
    p2d_speed_step(&ctl, (float)r, (float)r, &out);
    CHECK_CLOSE(out.T_unsat_Nm, T0, 1e-6);
    Fr0_old = -J * alpha / (4.0 * 1.0 * 1.0);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), T0 - Fr0_old * r, 1e-5);
    cfg.zeta = 2.0f;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_OK);
    Fr0_new = -J * alpha / (4.0 * 2.0 * 2.0);
    for (int k = 0; k < 3; ++k) {
        p2d_speed_step(&ctl, (float)r, (float)r, &out);
        CHECK_CLOSE(out.T_unsat_Nm, T0, 1e-6);
        CHECK_CLOSE(out.T_ff_Nm, Fr0_new * r, 1e-5);
    }
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), T0 - Fr0_new * r, 1e-5);
}

/*
 * The integrator state holds the load torque, not the static feedforward:
 * under a constant reference r = 500 rad/s with Fr(0) r = -500 Nm (lowpass,
 * eq 13: Fr(0) = -Ki / alpha = -1 Nm/(rad/s)), an error e = 2^-11 rad/s gives
 * increments Ki Ts e = 9.8e-6 Nm, under half an ulp of 501 Nm (1.5e-5 Nm) but
 * far above half an ulp of the 1 Nm load (6e-8 Nm). They must move the command
 * exactly as in the 1DOF PI (Fr = 0), whose state is the same 1 Nm.
 */
static void test_integrator_resolution_under_feedforward(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl, pi;
    p2d_speed_output_t out, out_pi;
    const float r = 500.0f, e = 0x1p-11f;
    const double Ki_Ts = 200.0 * 1e-4;
    cfg.anti_windup = P2D_AW_NONE;
    cfg.i_max_A = 1e4f;
    CHECK(p2d_speed_init(&pi, &cfg) == P2D_OK);
    cfg.feedforward = P2D_FF_LOWPASS;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    CHECK_CLOSE(ctl.coef[ctl.active].ff_Fr0 * r, -500.0, 1e-3);
    p2d_speed_reset(&ctl, r, 1.0f);
    p2d_speed_reset(&pi, r, 1.0f);
    for (int k = 0; k < 1000; ++k) {
        p2d_speed_step(&ctl, r, r - e, &out);
        p2d_speed_step(&pi, r, r - e, &out_pi);
    }
    CHECK(!out.saturated && out.e_radps == e);
    CHECK(out.T_unsat_Nm == out_pi.T_unsat_Nm);
    /* 1000 increments Ki Ts e on x = 1 Nm */
    CHECK_CLOSE(ctl.x_Nm, 1.0 + 1000.0 * Ki_Ts * (double)e, 1e-4);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 501.0 + 1000.0 * Ki_Ts * (double)e, 1e-4);
}

/* Salient PMSM: MTPA current gives the commanded torque, ||i|| <= i_max */
static void test_mtpa(void)
{
    p2d_speed_config_t cfg = surface_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    /* reluctance dominated: |Ld - Lq| i_max = 0.9 Wb against psi_f = 0.01 Wb */
    cfg.Ld_H = 1e-3f;
    cfg.Lq_H = 10e-3f;
    cfg.psi_f_Wb = 0.01f;
    cfg.i_max_A = 100.0f;
    cfg.anti_windup = P2D_AW_NONE;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    for (int n = -10; n <= 10; ++n) {
        float T = 0.1f * (float)n * ctl.coef[ctl.active].T_max_Nm;
        double id, iq, Te;
        p2d_speed_reset(&ctl, 0.0f, T);
        p2d_speed_compute(&ctl, 0.0f, 0.0f, &out);
        id = out.id_ref_A;
        iq = out.iq_ref_A;
        /* Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
        Te = 1.5 * 4.0 * (0.01 * iq + (1e-3 - 10e-3) * id * iq);
        CHECK_CLOSE(Te, T, 1e-5 * ctl.coef[ctl.active].T_max_Nm);
        CHECK(id * id + iq * iq <= 100.0 * 100.0 * (1.0 + 1e-6));
        CHECK(id <= 0.0);
    }
}

/* Deterministic uniform numbers in [0, 1) for the randomized checks (xorshift32). */
static double uniform(unsigned *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 17;
    *state ^= *state << 5;
    return (double)(*state >> 8) / 16777216.0;
}

/* lo (hi/lo)^u: log-uniform in [lo, hi) */
static float log_uniform(unsigned *state, double lo, double hi) { return (float)(lo * pow(hi / lo, uniform(state))); }

/* float32 units in the last place of x */
static double ulp(double x)
{
    int e;
    (void)frexp(x, &e);
    return ldexp(1.0, e - 24);
}

/*
 * After a reference step the feedforward settles on Fr(0) r, Fr(0) = -J alpha / (4 zeta^2 m)
 * (eq 11 at s = 0; -Ki/alpha for eq 13), to float32 rounding, also where the pole
 * -a1 ~ 1 - m alpha Ts is close to 1 (m alpha Ts down to 5e-4).
 */
static void test_feedforward_steady_state(void)
{
    /* J, alpha, zeta, Ts: the golden-test drive at 10 kHz, and the paper's drive (section 4) at 1 kHz */
    static const double designs[2][4] = {{0.02, 200.0, 0.8, 1e-4}, {0.4, 0.5, 0.2887, 1e-3}};
    static const p2d_feedforward_t forms[3] = {P2D_FF_LOWPASS, P2D_FF_NO_TAU, P2D_FF_FULL};
    static const float ms[3] = {1.0f, 1.6f, 0.7f};
    double worst_ulps = 0.0;
    for (int d = 0; d < 2; ++d) {
        for (int method = P2D_FORWARD_EULER; method <= P2D_TUSTIN; ++method) {
            for (int f = 0; f < 3; ++f) {
                p2d_speed_config_t cfg = surface_config();
                p2d_speed_t ctl;
                p2d_speed_output_t out;
                double Fr0, expected;
                long settle;
                cfg.J_kgm2 = (float)designs[d][0];
                cfg.alpha_radps = (float)designs[d][1];
                cfg.zeta = (float)designs[d][2];
                cfg.Ts_s = (float)designs[d][3];
                cfg.m = ms[f];
                cfg.tau_i_s = 2e-3f;
                cfg.feedforward = forms[f];
                cfg.method = (p2d_method_t)method;
                cfg.anti_windup = P2D_AW_NONE;
                cfg.i_max_A = 1e6f; /* no torque limit */
                CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
                Fr0 = -(double)cfg.J_kgm2 * cfg.alpha_radps / (4.0 * cfg.zeta * cfg.zeta * cfg.m);
                expected = Fr0 * 47.0;
                /* the transient decays by about 1 - m alpha Ts per sample: 40 time constants */
                settle = (long)(40.0 / ((double)cfg.m * cfg.alpha_radps * cfg.Ts_s));
                for (long k = 0; k < settle; ++k) p2d_speed_step(&ctl, 47.0f, 47.0f, &out);
                CHECK(!out.saturated && !out.fault);
                worst_ulps = fmax(worst_ulps, fabs(out.T_ff_Nm - expected) / ulp(expected));
                /* the float32 coefficient Fr0 (4 roundings) and one product: a few ulps */
                CHECK_CLOSE(out.T_ff_Nm, expected, 4.0 * ulp(expected));
            }
        }
    }
    printf("feedforward steady state: worst %.2f float32 ulps from Fr(0) r\n", worst_ulps);
}

/*
 * Surface PMSM: at the torque limit iq = T_max / kt never exceeds i_max_A in
 * float32 (init lowers T_max where kt i_max, rounded, divides back to more),
 * and stays within 2 ulps of it. Random machines over 6 decades.
 */
static void test_surface_current_limit_is_exact(void)
{
    unsigned state = 12345u;
    int over = 0, loose = 0, rounding_cases = 0;
    for (int n = 0; n < 20000; ++n) {
        p2d_speed_config_t cfg = surface_config();
        p2d_speed_t ctl;
        p2d_speed_output_t out;
        float kt;
        cfg.psi_f_Wb = log_uniform(&state, 1e-3, 2.0);
        cfg.pole_pairs = 1u + (uint32_t)(uniform(&state) * 12.0);
        cfg.i_max_A = log_uniform(&state, 1e-2, 1e4);
        cfg.Ld_H = cfg.Lq_H = 1e-3f;
        cfg.anti_windup = P2D_AW_NONE;
        if (p2d_speed_init(&ctl, &cfg) != P2D_OK) {
            over++;
            continue;
        }
        /* the rounding the limit has to absorb: (kt i_max) / kt > i_max in float32 */
        kt = 1.5f * (float)cfg.pole_pairs * cfg.psi_f_Wb;
        if ((kt * cfg.i_max_A) / kt > cfg.i_max_A) rounding_cases++;
        for (int sign = -1; sign <= 1; sign += 2) {
            p2d_speed_reset(&ctl, 0.0f, 0.0f);
            p2d_speed_step(&ctl, (float)sign * 1e30f, 0.0f, &out);
            if (!out.saturated || fabsf(out.iq_ref_A) > cfg.i_max_A) over++;
            if (fabsf(out.iq_ref_A) < cfg.i_max_A - 2.0f * (float)ulp(cfg.i_max_A)) loose++;
        }
    }
    CHECK(rounding_cases > 100);
    CHECK(over == 0);
    CHECK(loose == 0);
}

/*
 * Salient PMSM, random machines (magnet to reluctance dominated, Ld < Lq and
 * Ld > Lq) and torques over 6 decades up to T_max: the current command gives
 * the torque Te = 1.5 p (psi_f iq + (Ld - Lq) id iq), lies on the MTPA curve
 * id = 2 dL iq^2 / (psi_f + sqrt(psi_f^2 + 4 dL^2 iq^2)) and within i_max, all
 * evaluated here in double.
 */
static void test_mtpa_random_machines(void)
{
    unsigned state = 777u;
    double worst_T = 0.0, worst_mtpa = 0.0, worst_norm = 0.0;
    int wrong = 0;
    for (int n = 0; n < 20000; ++n) {
        p2d_speed_config_t cfg = surface_config();
        p2d_speed_t ctl;
        p2d_speed_output_t out;
        double psi, dL, id, iq, T, T_max, Te, id_mtpa;
        cfg.psi_f_Wb = log_uniform(&state, 1e-3, 1.0);
        cfg.Lq_H = log_uniform(&state, 1e-4, 1e-1);
        cfg.Ld_H = cfg.Lq_H * (float)(0.05 + 3.0 * uniform(&state));
        cfg.pole_pairs = 1u + (uint32_t)(uniform(&state) * 8.0);
        cfg.i_max_A = log_uniform(&state, 1e-1, 1e3);
        cfg.anti_windup = P2D_AW_NONE;
        if (cfg.Ld_H == cfg.Lq_H || p2d_speed_init(&ctl, &cfg) != P2D_OK) continue;
        psi = cfg.psi_f_Wb;
        dL = (double)cfg.Ld_H - (double)cfg.Lq_H;
        T_max = ctl.coef[ctl.active].T_max_Nm;
        T = T_max * (n % 5 == 0 ? 1.0 : pow(10.0, -6.0 * uniform(&state))) * (n % 2 ? -1.0 : 1.0);
        p2d_speed_reset(&ctl, 0.0f, (float)T);
        p2d_speed_compute(&ctl, 0.0f, 0.0f, &out);
        id = out.id_ref_A;
        iq = out.iq_ref_A;
        Te = 1.5 * cfg.pole_pairs * (psi * iq + dL * id * iq);
        id_mtpa = 2.0 * dL * iq * iq / (psi + sqrt(psi * psi + 4.0 * dL * dL * iq * iq));
        worst_T = fmax(worst_T, fabs(Te - out.T_ref_Nm) / fmax(fabs(out.T_ref_Nm), 1e-6 * T_max));
        worst_mtpa = fmax(worst_mtpa, fabs(id - id_mtpa) / hypot(id, iq));
        worst_norm = fmax(worst_norm, hypot(id, iq) / cfg.i_max_A - 1.0);
        /* iq has the sign of the torque; dL id >= 0 on the MTPA curve */
        if (out.fault || iq * T < 0.0 || id * dL < 0.0) wrong++;
    }
    CHECK(wrong == 0);
    printf("MTPA: worst torque error %.3g, distance from the MTPA curve %.3g, ||i|| / i_max - 1 = %.3g\n", worst_T,
           worst_mtpa, worst_norm);
    CHECK(worst_T < 2e-6);
    CHECK(worst_mtpa < 2e-6);
    CHECK(worst_norm <= 4.0 * FLT_EPSILON);
}

/*
 * One MTPA: inside the current limit, the salient command is on the trajectory of
 * the public p2d_mtpa_id_A to the bit, id_ref = p2d_mtpa_id_A(iq_ref, psi_f, Ld - Lq),
 * on random machines and torques up to 0.9 T_max (so that the vector is not
 * scaled back onto the limit).
 */
static void test_mtpa_is_the_public_relation(void)
{
    unsigned state = 4242u;
    int compared = 0, equal = 0;
    for (int n = 0; n < 5000; ++n) {
        p2d_speed_config_t cfg = surface_config();
        p2d_speed_t ctl;
        p2d_speed_output_t out;
        float T;
        cfg.psi_f_Wb = log_uniform(&state, 1e-3, 1.0);
        cfg.Lq_H = log_uniform(&state, 1e-4, 1e-1);
        cfg.Ld_H = cfg.Lq_H * (float)(0.05 + 3.0 * uniform(&state));
        cfg.pole_pairs = 1u + (uint32_t)(uniform(&state) * 8.0);
        cfg.i_max_A = log_uniform(&state, 1e-1, 1e3);
        if (cfg.Ld_H == cfg.Lq_H || p2d_speed_init(&ctl, &cfg) != P2D_OK) continue;
        T = (float)(0.9 * ctl.coef[ctl.active].T_max_Nm * pow(10.0, -4.0 * uniform(&state)) * (n % 2 ? -1.0 : 1.0));
        p2d_speed_reset(&ctl, 0.0f, T);
        p2d_speed_compute(&ctl, 0.0f, 0.0f, &out);
        compared++;
        equal += out.id_ref_A == p2d_mtpa_id_A(out.iq_ref_A, cfg.psi_f_Wb, cfg.Ld_H - cfg.Lq_H);
    }
    CHECK(compared > 4000);
    CHECK(equal == compared);
}

int main(void)
{
    test_validation();
    test_gains();
    test_tustin_pi_sequence();
    test_euler_pi_sequences();
    test_anti_windup_modes();
    test_update_with_applied_torque();
    test_non_finite_policy();
    test_reset();
    test_lowpass_feedforward_sequence();
    test_set_config();
    test_set_config_bumpless_feedforward();
    test_integrator_resolution_under_feedforward();
    test_mtpa();
    test_feedforward_steady_state();
    test_surface_current_limit_is_exact();
    test_mtpa_random_machines();
    test_mtpa_is_the_public_relation();
    return check_summary();
}
