/*
 * Unit tests of the voltage-feedback field weakening (pmsm2dof/field_weakening.h)
 * and of the speed controller's field-weakening entry (p2d_speed_step_fw,
 * speed.h). Expected values: the steady-state voltage equations of the dq
 * model (eq 1) solved for id in double, the discrete PI (eq 14, Fig. 5) by
 * hand, and the largest torque inside the current circle found by a scan.
 */
#include <float.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/speed.h"

/* A 48 V servo: Rs = 0.2 ohm, Ld = Lq = 1 mH, psi_f = 0.02 Wb; the field weakening runs at 10 kHz. */
#define RS 0.2
#define LD 1e-3
#define LQ 1e-3
#define PSI 0.02
#define U_DC 48.0

static p2d_field_weakening_config_t fw_config(p2d_anti_windup_t aw)
{
    p2d_field_weakening_config_t cfg;
    cfg.Kp_A_per_V = 0.02f;
    cfg.Ki_A_per_Vs = 100.0f;
    cfg.Ka_V_per_A = 50.0f; /* 1 / Kp */
    cfg.Ts_s = 1e-4f;
    cfg.voltage_ratio = 0.95f;
    cfg.id_min_A = -15.0f;
    cfg.method = P2D_TUSTIN;
    cfg.anti_windup = aw;
    return cfg;
}

static p2d_status_t init_with(p2d_field_weakening_config_t cfg)
{
    p2d_field_weakening_t fw;
    return p2d_field_weakening_init(&fw, &cfg);
}

static void test_validation(void)
{
    p2d_field_weakening_config_t cfg;
    p2d_field_weakening_t fw, before;

    CHECK(init_with(fw_config(P2D_AW_BACK_CALCULATION)) == P2D_OK);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.Kp_A_per_V = -0.1f;
    CHECK(init_with(cfg) == P2D_ERR_FW_KP);
    cfg.Kp_A_per_V = 0.0f; /* integral only */
    cfg.Ka_V_per_A = 0.0f;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.Ki_A_per_Vs = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_FW_KI);
    cfg.Ki_A_per_Vs = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_FW_KI);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.Ka_V_per_A = 200.0f; /* Ki Ka Ts = 2 */
    CHECK(init_with(cfg) == P2D_ERR_FW_KA);
    cfg.anti_windup = P2D_AW_CLAMPING; /* Ka unused, but still a number >= 0 */
    CHECK(init_with(cfg) == P2D_OK);
    cfg.Ka_V_per_A = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_FW_KA);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.Ts_s = -1e-4f;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.voltage_ratio = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_FW_VOLTAGE_RATIO);
    cfg.voltage_ratio = 1.0001f;
    CHECK(init_with(cfg) == P2D_ERR_FW_VOLTAGE_RATIO);
    cfg.voltage_ratio = 1.0f;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.id_min_A = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_FW_ID_MIN);
    cfg.id_min_A = -INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_FW_ID_MIN);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.method = (p2d_method_t)3;
    CHECK(init_with(cfg) == P2D_ERR_METHOD);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.anti_windup = (p2d_anti_windup_t)7;
    CHECK(init_with(cfg) == P2D_ERR_ANTI_WINDUP);
    CHECK(p2d_field_weakening_init(NULL, &cfg) == P2D_ERR_NULL);

    memset(&fw, 0x5a, sizeof fw);
    memcpy(&before, &fw, sizeof fw);
    cfg = fw_config(P2D_AW_BACK_CALCULATION);
    cfg.voltage_ratio = NAN;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_ERR_FW_VOLTAGE_RATIO);
    CHECK(memcmp(&fw, &before, sizeof fw) == 0);
    for (int s = P2D_ERR_FW_KP; s <= P2D_ERR_FW_ID_MIN; ++s) {
        CHECK(strlen(p2d_status_param((p2d_status_t)s)) > 0 && strlen(p2d_status_range((p2d_status_t)s)) > 0);
    }
    CHECK(strcmp(p2d_status_param(P2D_ERR_FW_ID_MIN), "id_min_A") == 0);
}

/* Steady-state voltages of the dq model (eq 1, d/dt = 0) at the electrical speed w_e. */
static void voltages(double w_e, double id, double iq, double *ud, double *uq)
{
    *ud = RS * id - w_e * LQ * iq;
    *uq = RS * iq + w_e * (LD * id + PSI);
}

/*
 * The id at which ||u_dq|| = U for the given iq and w_e: the larger root of
 * (Rs id - c1)^2 + (c2 + w Ld id)^2 = U^2, c1 = w Lq iq, c2 = Rs iq + w psi_f.
 */
static double id_analytic(double w_e, double iq, double U)
{
    double c1 = w_e * LQ * iq, c2 = RS * iq + w_e * PSI;
    double a = RS * RS + w_e * w_e * LD * LD;
    double b = 2.0 * (-RS * c1 + c2 * w_e * LD);
    double c = c1 * c1 + c2 * c2 - U * U;
    return (-b + sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
}

/*
 * Closed loop with an ideal current loop (the motor's currents are last sample's
 * commands) at a constant speed: n steps, returns the last output.
 */
static p2d_field_weakening_output_t run_static(p2d_field_weakening_t *fw, double w_e, double iq, int n)
{
    p2d_field_weakening_output_t out;
    double id = fw->x_A, ud, uq;
    memset(&out, 0, sizeof out);
    for (int k = 0; k < n; ++k) {
        voltages(w_e, id, iq, &ud, &uq);
        p2d_field_weakening_step(fw, (float)ud, (float)uq, (float)U_DC, &out);
        id = out.id_ref_A;
    }
    return out;
}

/* Above base speed the current settles where the steady-state voltage equals u_ref (within 1 %, in fact 1e-5). */
static void test_settles_on_the_voltage_equations(void)
{
    const double U = 0.95 * U_DC / sqrt(3.0);
    const double speeds[3] = {1800.0, 2000.0, 2500.0}; /* electrical [rad/s]; base speed about 1300 rad/s */
    for (int aw = P2D_AW_BACK_CALCULATION; aw <= P2D_AW_CLAMPING; ++aw) {
        for (int s = 0; s < 3; ++s) {
            p2d_field_weakening_config_t cfg = fw_config((p2d_anti_windup_t)aw);
            p2d_field_weakening_t fw;
            p2d_field_weakening_output_t out;
            double id_expected = id_analytic(speeds[s], 5.0, U), ud, uq;
            CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
            out = run_static(&fw, speeds[s], 5.0, 20000);
            CHECK(out.active && !out.at_id_min && !out.fault);
            CHECK(id_expected < -1.0 && id_expected > -15.0);
            CHECK_CLOSE(out.id_ref_A, id_expected, 1e-5 * fabs(id_expected));
            voltages(speeds[s], out.id_ref_A, 5.0, &ud, &uq);
            CHECK_CLOSE(hypot(ud, uq), U, 1e-4);
            CHECK_CLOSE(out.u_ref_V, U, 1e-5);
        }
    }
}

/*
 * Below base speed: id stays 0 with a positive margin and the integrator does not
 * wind up (back calculation: its fixed point x* = e (1/Ka - b_e0); clamping: 0).
 * Beyond the weakening range: id = id_min_A, and the integrator settles at
 * x* = id_min + e (1/Ka - b_e0), or is held.
 */
static void test_anti_windup_at_both_limits(void)
{
    const double b_e0 = 0.02 + 0.5 * 100.0 * 1e-4;
    p2d_field_weakening_config_t cfg = fw_config(P2D_AW_BACK_CALCULATION);
    p2d_field_weakening_t fw;
    p2d_field_weakening_output_t out;
    float x_held;

    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    out = run_static(&fw, 500.0, 5.0, 20000);
    CHECK(out.id_ref_A == 0.0f && !out.active && out.e_V > 10.0);
    CHECK_CLOSE(fw.x_A, out.e_V * (1.0 / 50.0 - b_e0), 1e-5);

    out = run_static(&fw, 9000.0, 5.0, 20000);
    CHECK(out.id_ref_A == -15.0f && out.at_id_min && out.active && out.e_V < 0.0);
    CHECK_CLOSE(fw.x_A, -15.0 + out.e_V * (1.0 / 50.0 - b_e0), 1e-4);

    cfg.anti_windup = P2D_AW_CLAMPING;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    out = run_static(&fw, 500.0, 5.0, 20000);
    CHECK(out.id_ref_A == 0.0f && fw.x_A == 0.0f);
    out = run_static(&fw, 9000.0, 5.0, 20000);
    x_held = fw.x_A;
    out = run_static(&fw, 9000.0, 5.0, 1000);
    CHECK(out.at_id_min && fw.x_A == x_held && x_held >= -15.0f - (float)(b_e0 * 40.0));
    /* back below base speed: the weakening returns to 0 */
    out = run_static(&fw, 500.0, 5.0, 20000);
    CHECK(out.id_ref_A == 0.0f && !out.active);

    cfg.anti_windup = P2D_AW_NONE;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    out = run_static(&fw, 500.0, 5.0, 1000);
    /* no anti-windup: the integrator grows by Ki Ts e every sample */
    CHECK(fw.x_A > 0.9f * 1000.0f * 100.0f * 1e-4f * out.e_V);
}

/* eq 14, Tustin, a constant negative margin from rest: v[k] = Kp e + Ki Ts e (k + 1/2), inside the limits. */
static void test_pi_sequence(void)
{
    p2d_field_weakening_config_t cfg = fw_config(P2D_AW_BACK_CALCULATION);
    p2d_field_weakening_t fw;
    p2d_field_weakening_output_t out;
    const double U = 0.95 * U_DC / sqrt(3.0), e = U - 30.0;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    for (int k = 0; k < 5; ++k) {
        /* ||(18, 24)|| = 30 V */
        p2d_field_weakening_step(&fw, 18.0f, 24.0f, (float)U_DC, &out);
        CHECK_CLOSE(out.e_V, e, 1e-5);
        CHECK_CLOSE(out.id_unsat_A, 0.02 * e + 100.0 * 1e-4 * e * (k + 0.5), 1e-6);
        CHECK(out.id_ref_A == out.id_unsat_A);
    }
}

static void test_non_finite_policy(void)
{
    p2d_field_weakening_config_t cfg = fw_config(P2D_AW_BACK_CALCULATION);
    p2d_field_weakening_t fw, before;
    p2d_field_weakening_output_t out;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    (void)run_static(&fw, 2000.0, 5.0, 5000);
    memcpy(&before, &fw, sizeof fw);
    p2d_field_weakening_step(&fw, NAN, 1.0f, (float)U_DC, &out);
    CHECK(out.fault && fw.fault_count == 1u && fw.x_A == before.x_A);
    /* the hold: the integrator's current, within the limits */
    CHECK(out.id_ref_A == before.x_A && out.active);
    p2d_field_weakening_step(&fw, 1.0f, 1.0f, NAN, &out);
    CHECK(out.fault && fw.fault_count == 2u);
    p2d_field_weakening_step(&fw, 1.0f, 1.0f, INFINITY, &out);
    CHECK(out.fault && fw.fault_count == 3u);
    p2d_field_weakening_step(&fw, 1e20f, 1.0f, (float)U_DC, &out); /* ||u||^2 overflows */
    CHECK(out.fault && fw.fault_count == 4u && fw.x_A == before.x_A);
    /* a negative DC link is 0 V: the whole voltage is a negative margin, no fault */
    p2d_field_weakening_step(&fw, 3.0f, 4.0f, -10.0f, &out);
    CHECK(!out.fault && out.u_ref_V == 0.0f && out.e_V == -5.0f && fw.fault_count == 4u);
    p2d_field_weakening_reset(&fw, NAN);
    CHECK(fw.fault_count == 5u && fw.x_A == 0.0f);
    p2d_field_weakening_reset(&fw, -40.0f); /* clamped to id_min */
    CHECK(fw.x_A == -15.0f);
    p2d_field_weakening_reset(&fw, 2.0f);
    CHECK(fw.x_A == 0.0f);
}

static void test_set_config(void)
{
    p2d_field_weakening_config_t cfg = fw_config(P2D_AW_BACK_CALCULATION);
    p2d_field_weakening_t fw, before;
    CHECK(p2d_field_weakening_init(&fw, &cfg) == P2D_OK);
    (void)run_static(&fw, 2000.0, 5.0, 3000);
    memcpy(&before, &fw, sizeof fw);
    cfg.id_min_A = 1.0f;
    CHECK(p2d_field_weakening_set_config(&fw, &cfg) == P2D_ERR_FW_ID_MIN);
    CHECK(memcmp(&fw, &before, sizeof fw) == 0);
    cfg.id_min_A = -10.0f;
    cfg.Ki_A_per_Vs = 50.0f;
    CHECK(p2d_field_weakening_set_config(&fw, &cfg) == P2D_OK);
    CHECK(fw.active == 1u - before.active && fw.x_A == before.x_A);
    CHECK(memcmp(&fw.coef[before.active], &before.coef[before.active], sizeof fw.coef[0]) == 0);
    CHECK(fw.coef[fw.active].id_min_A == -10.0f);
}

/* ---------------------------------------------------------------------------------------- */
/* the speed controller's field-weakening entry                                              */

/* A surface PMSM: J = 0.02 kg m^2, alpha = 200 rad/s, zeta = 1, Ts = 100 us, 10 A, p = 4, kt = 0.3 Nm/A. */
static p2d_speed_config_t speed_config(p2d_anti_windup_t aw)
{
    p2d_speed_config_t cfg;
    cfg.J_kgm2 = 0.02f;
    cfg.alpha_radps = 200.0f;
    cfg.zeta = 1.0f;
    cfg.m = 1.0f;
    cfg.tau_i_s = 0.0f;
    cfg.Ka = 0.25f;
    cfg.Ts_s = 1e-4f;
    cfg.i_max_A = 10.0f;
    cfg.psi_f_Wb = 0.05f;
    cfg.Ld_H = 2e-3f;
    cfg.Lq_H = 2e-3f;
    cfg.pole_pairs = 4u;
    cfg.method = P2D_TUSTIN;
    cfg.feedforward = P2D_FF_LOWPASS;
    cfg.anti_windup = aw;
    return cfg;
}

static bool same_output(const p2d_speed_output_t *a, const p2d_speed_output_t *b)
{
    return memcmp(&a->T_unsat_Nm, &b->T_unsat_Nm, sizeof(float)) == 0 &&
           memcmp(&a->T_ref_Nm, &b->T_ref_Nm, sizeof(float)) == 0 &&
           memcmp(&a->id_ref_A, &b->id_ref_A, sizeof(float)) == 0 &&
           memcmp(&a->iq_ref_A, &b->iq_ref_A, sizeof(float)) == 0 && a->saturated == b->saturated &&
           a->fault == b->fault;
}

/* Deterministic uniform numbers in [0, 1) (xorshift32). */
static double uniform(unsigned *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 17;
    *state ^= *state << 5;
    return (double)*state / 4294967296.0;
}

/* With id_fw = 0 (or > 0) the entry is p2d_speed_step to the bit: surface and Ld < Lq, every anti-windup mode. */
static void test_fw_entry_at_zero_is_the_step(void)
{
    unsigned state = 99u;
    int differ = 0, compared = 0;
    for (int salient = 0; salient <= 1; ++salient) {
        for (int aw = P2D_AW_NONE; aw <= P2D_AW_CLAMPING; ++aw) {
            p2d_speed_config_t cfg = speed_config((p2d_anti_windup_t)aw);
            p2d_speed_t a, b;
            if (salient) cfg.Ld_H = 1e-3f;
            CHECK(p2d_speed_init(&a, &cfg) == P2D_OK);
            CHECK(p2d_speed_init(&b, &cfg) == P2D_OK);
            for (int k = 0; k < 3000; ++k) {
                p2d_speed_output_t oa, ob;
                float w_ref = (float)(200.0 * (uniform(&state) - 0.5) * (k % 500 < 250 ? 1.0 : 0.01));
                float w_m = (float)(w_ref * uniform(&state));
                p2d_speed_step(&a, w_ref, w_m, &oa);
                p2d_speed_step_fw(&b, w_ref, w_m, k % 3 == 0 ? 3.0f : 0.0f, &ob);
                differ += !same_output(&oa, &ob) || memcmp(&a.x_Nm, &b.x_Nm, sizeof(float)) != 0;
                compared++;
            }
        }
    }
    CHECK(compared == 18000);
    CHECK(differ == 0);
}

/*
 * Surface PMSM with id_fw = -6 A of 10 A: the torque limit is kt sqrt(10^2 - 6^2) = 0.3 * 8 = 2.4 Nm,
 * the current (-6, 8) A, and the back calculation integrates u* = 2.4 - u (its fixed point under
 * a sustained error e: x* = T_lim - b_e0 e + e / Ka, as for the full limit).
 */
static void test_fw_entry_surface_limit_and_anti_windup(void)
{
    p2d_speed_config_t cfg = speed_config(P2D_AW_BACK_CALCULATION);
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double Ki_Ts = 200.0 * 1e-4, b_e0 = 4.0 + 0.5 * Ki_Ts, e = 100.0;
    double expected;
    cfg.feedforward = P2D_FF_NONE;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_compute_fw(&ctl, 100.0f, 0.0f, -6.0f, &out);
    CHECK(out.saturated && !out.fault);
    CHECK_CLOSE(out.T_ref_Nm, 2.4, 1e-6);
    CHECK(out.id_ref_A == -6.0f);
    CHECK_CLOSE(out.iq_ref_A, 8.0, 1e-5);
    CHECK(hypot(out.id_ref_A, out.iq_ref_A) <= 10.0 * (1.0 + 4.0 * FLT_EPSILON));
    /* x[0] = Ki Ts e + Ki Ka Ts (T_lim - u) */
    expected = Ki_Ts * e + Ki_Ts * 0.25 * (out.T_ref_Nm - out.T_unsat_Nm);
    p2d_speed_update(&ctl, &out, out.T_ref_Nm);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), expected, 1e-5);
    for (int k = 0; k < 20000; ++k) p2d_speed_step_fw(&ctl, 100.0f, 0.0f, -6.0f, &out);
    CHECK_CLOSE(p2d_speed_integrator_Nm(&ctl), 2.4 - b_e0 * e + e / 0.25, 1e-3);
    /* the torque returns below the reduced limit: unsaturated, iq = T / kt */
    p2d_speed_reset(&ctl, 0.0f, 1.0f);
    p2d_speed_step_fw(&ctl, 0.0f, 0.0f, -6.0f, &out);
    CHECK(!out.saturated && out.T_ref_Nm == 1.0f && out.id_ref_A == -6.0f);
    CHECK_CLOSE(out.iq_ref_A, 1.0 / 0.3, 1e-6);
    /* beyond -i_max: clamped to -10 A, nothing left for the torque */
    p2d_speed_step_fw(&ctl, 100.0f, 0.0f, -25.0f, &out);
    CHECK(out.id_ref_A == -10.0f && out.T_ref_Nm == 0.0f && out.iq_ref_A == 0.0f && out.saturated);
}

/* Salient PMSM (Ld = 1 mH < Lq = 2 mH): below the MTPA id, on the circle; above it, MTPA or the bound. */
static void test_fw_entry_salient(void)
{
    p2d_speed_config_t cfg = speed_config(P2D_AW_BACK_CALCULATION);
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const double dL = -1e-3, psi = 0.05, k = 1.5 * 4.0;
    double id_mtpa_max = 2.0 * dL * 100.0 / (psi + sqrt(psi * psi + 8.0 * dL * dL * 100.0)); /* -1.86 A */
    cfg.Ld_H = 1e-3f;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    CHECK(id_mtpa_max < -1.8 && id_mtpa_max > -1.9);
    /* id_fw = -5 A below the MTPA point: T_lim = 1.5 p (psi_f + dL id) sqrt(i_max^2 - id^2) */
    p2d_speed_compute_fw(&ctl, 1000.0f, 0.0f, -5.0f, &out);
    CHECK(out.saturated && out.id_ref_A == -5.0f);
    CHECK_CLOSE(out.T_ref_Nm, k * (psi + dL * -5.0) * sqrt(75.0), 1e-5);
    CHECK_CLOSE(out.iq_ref_A, sqrt(75.0), 1e-5);
    /* id_fw = -1 A above it: the full MTPA torque, on the MTPA vector */
    p2d_speed_compute_fw(&ctl, 1000.0f, 0.0f, -1.0f, &out);
    CHECK(out.T_ref_Nm == ctl.coef[ctl.active].T_max_Nm);
    CHECK_CLOSE(out.id_ref_A, id_mtpa_max, 1e-5);
    /* a small torque, whose MTPA id is above -1 A: id = -1 A and the torque kept */
    p2d_speed_reset(&ctl, 0.0f, 0.5f);
    p2d_speed_compute_fw(&ctl, 0.0f, 0.0f, -1.0f, &out);
    CHECK(out.id_ref_A == -1.0f);
    CHECK_CLOSE(k * (psi * out.iq_ref_A + dL * out.id_ref_A * out.iq_ref_A), 0.5, 1e-6);
}

/*
 * Random machines (surface and salient, both saliencies), random id_fw and saturating
 * errors: ||i_dq|| <= i_max (up to 4 FLT_EPSILON), id <= id_fw, the current gives the
 * commanded torque, and the torque limit is the largest torque of the current circle
 * with id <= id_fw (a scan of 20001 points on it, in double).
 */
static void test_fw_entry_random_machines(void)
{
    unsigned state = 2024u;
    double worst_limit = 0.0, worst_T = 0.0, worst_norm = 0.0;
    int wrong = 0, tested = 0;
    for (int n = 0; n < 3000; ++n) {
        p2d_speed_config_t cfg = speed_config(P2D_AW_BACK_CALCULATION);
        p2d_speed_t ctl;
        p2d_speed_output_t out;
        double I, id_fw, id_b, dL, kp, best = 0.0, Te;
        cfg.psi_f_Wb = (float)(0.01 + 0.5 * uniform(&state));
        cfg.Lq_H = (float)(1e-3 + 2e-2 * uniform(&state));
        cfg.Ld_H = n % 3 == 0 ? cfg.Lq_H : cfg.Lq_H * (float)(0.2 + 1.6 * uniform(&state));
        cfg.i_max_A = (float)(1.0 + 50.0 * uniform(&state));
        cfg.pole_pairs = 1u + (uint32_t)(7.0 * uniform(&state));
        if (p2d_speed_init(&ctl, &cfg) != P2D_OK) continue;
        I = cfg.i_max_A;
        dL = (double)cfg.Ld_H - (double)cfg.Lq_H;
        kp = 1.5 * cfg.pole_pairs;
        id_fw = (float)(-1.1 * I * uniform(&state));
        id_b = fmax(id_fw, -I);
        for (int j = 0; j <= 20000; ++j) {
            double id = -I + (id_b + I) * j / 20000.0;
            double T = kp * (cfg.psi_f_Wb + dL * id) * sqrt(fmax(I * I - id * id, 0.0));
            if (T > best) best = T;
        }
        p2d_speed_compute_fw(&ctl, 1e4f * (n % 2 ? 1.0f : -1.0f), 0.0f, (float)id_fw, &out);
        tested++;
        if (out.fault || !out.saturated || out.id_ref_A > (float)id_b || out.iq_ref_A * out.T_ref_Nm < 0.0f) wrong++;
        worst_limit = fmax(worst_limit, fabs(fabs(out.T_ref_Nm) - best) / ctl.coef[ctl.active].T_max_Nm);
        Te = kp * (cfg.psi_f_Wb * out.iq_ref_A + dL * out.id_ref_A * out.iq_ref_A);
        worst_T = fmax(worst_T, fabs(Te - out.T_ref_Nm) / ctl.coef[ctl.active].T_max_Nm);
        worst_norm = fmax(worst_norm, hypot(out.id_ref_A, out.iq_ref_A) / I - 1.0);
    }
    printf("field-weakening limit: worst limit error %.3g, torque error %.3g, ||i|| / i_max - 1 = %.3g (%d machines)\n",
           worst_limit, worst_T, worst_norm, tested);
    CHECK(tested > 2500);
    CHECK(wrong == 0);
    CHECK(worst_limit < 1e-5);
    CHECK(worst_T < 1e-5);
    CHECK(worst_norm <= 4.0 * FLT_EPSILON);
}

/* A non-finite id_fw: zero torque and current, fault counted by the step, state kept. */
static void test_fw_entry_non_finite(void)
{
    p2d_speed_config_t cfg = speed_config(P2D_AW_BACK_CALCULATION);
    p2d_speed_t ctl, before;
    p2d_speed_output_t out;
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    p2d_speed_step_fw(&ctl, 10.0f, 0.0f, -1.0f, &out);
    memcpy(&before, &ctl, sizeof ctl);
    p2d_speed_step_fw(&ctl, 10.0f, 0.0f, NAN, &out);
    CHECK(out.fault && out.T_ref_Nm == 0.0f && out.id_ref_A == 0.0f && out.iq_ref_A == 0.0f);
    CHECK(ctl.fault_count == before.fault_count + 1u && ctl.x_Nm == before.x_Nm);
    p2d_speed_step_fw(&ctl, 10.0f, 0.0f, -INFINITY, &out);
    CHECK(out.fault && ctl.fault_count == before.fault_count + 2u);
    p2d_speed_step_fw(&ctl, NAN, 0.0f, -1.0f, &out);
    CHECK(out.fault && ctl.fault_count == before.fault_count + 3u);
}

int main(void)
{
    test_validation();
    test_settles_on_the_voltage_equations();
    test_anti_windup_at_both_limits();
    test_pi_sequence();
    test_non_finite_policy();
    test_set_config();
    test_fw_entry_at_zero_is_the_step();
    test_fw_entry_surface_limit_and_anti_windup();
    test_fw_entry_salient();
    test_fw_entry_random_machines();
    test_fw_entry_non_finite();
    return check_summary();
}
