/*
 * Unit tests of the speed controller's torque filters (p2d_speed_set_filter,
 * pmsm2dof/speed.h): the filters act on the whole torque command, before the
 * limit, inside the anti-windup loop. Expected values: the designed filters as
 * direct forms in double (filter_design.h) and the back-calculation update of
 * Fig. 5 written out by hand with u* = u_sat - u_f.
 */
#include <float.h>
#include <string.h>

#include "check.h"
#include "filter_design.h"
#include "pmsm2dof/speed.h"

/* The paper's section 4 inertia with a faster loop: J = 0.4 kg m^2, alpha = 20 rad/s, 1 kHz, 7.6 A. */
static p2d_speed_config_t drive_config(bool salient)
{
    p2d_speed_config_t cfg;
    cfg.J_kgm2 = 0.4f;
    cfg.alpha_radps = 20.0f;
    cfg.zeta = 0.7f;
    cfg.m = 1.0f;
    cfg.tau_i_s = 0.0f;
    cfg.Ka = p2d_speed_Ka_default(0.4f, 20.0f);
    cfg.Ts_s = 1e-3f;
    cfg.i_max_A = 7.6f;
    cfg.psi_f_Wb = 0.35f;
    cfg.Ld_H = salient ? 8e-3f : 12e-3f;
    cfg.Lq_H = 12e-3f;
    cfg.pole_pairs = 4u;
    cfg.method = P2D_TUSTIN;
    cfg.feedforward = P2D_FF_LOWPASS;
    cfg.anti_windup = P2D_AW_BACK_CALCULATION;
    return cfg;
}

/* A notch at 40 Hz (a torsional resonance), 15 Hz wide, -26 dB, and a low-pass at 200 Hz. */
static p2d_filter_config_t torque_filter(void)
{
    p2d_filter_config_t f;
    f.notch_freq_Hz = 40.0f;
    f.notch_width_Hz = 15.0f;
    f.notch_depth = 0.05f;
    f.lowpass_freq_Hz = 200.0f;
    f.lowpass_zeta = 0.70710678f;
    return f;
}

static p2d_filter_config_t no_filter(void)
{
    p2d_filter_config_t f;
    memset(&f, 0, sizeof f);
    return f;
}

/* A controller of cfg with the torque filters f. */
static p2d_status_t filtered(p2d_speed_t *ctl, bool salient, p2d_filter_config_t f)
{
    p2d_speed_config_t cfg = drive_config(salient);
    p2d_status_t status = p2d_speed_init(ctl, &cfg);
    return status == P2D_OK ? p2d_speed_set_filter(ctl, &f) : status;
}

static bool same_bits(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

/* Every field of two outputs, to the bit (memcmp would compare the padding too). */
static bool same_output(const p2d_speed_output_t *a, const p2d_speed_output_t *b)
{
    return same_bits(a->w_ref_radps, b->w_ref_radps) && same_bits(a->e_radps, b->e_radps) &&
           same_bits(a->T_ff_Nm, b->T_ff_Nm) && same_bits(a->y_ff_Nm, b->y_ff_Nm) &&
           same_bits(a->T_unsat_Nm, b->T_unsat_Nm) && same_bits(a->T_ref_Nm, b->T_ref_Nm) &&
           same_bits(a->id_ref_A, b->id_ref_A) && same_bits(a->iq_ref_A, b->iq_ref_A) && a->saturated == b->saturated &&
           a->fault == b->fault;
}

/* The states of two controllers, to the bit. */
static bool same_state(const p2d_speed_t *a, const p2d_speed_t *b)
{
    return same_bits(a->x_Nm, b->x_Nm) && same_bits(a->r_prev_radps, b->r_prev_radps) &&
           same_bits(a->y_ff_prev_Nm, b->y_ff_prev_Nm) && a->fault_count == b->fault_count &&
           memcmp(&a->filter, &b->filter, sizeof a->filter) == 0;
}

/* A reference and a noisy speed measurement, k = 0 .. n-1: steps, ramps and a 40 Hz ripple. */
static void inputs(int k, float scale, float *w_ref, float *w_m)
{
    double t = 1e-3 * k;
    *w_ref = (float)(scale * (k < 300 ? 1.0 : k < 600 ? -0.5 : 0.2 + 0.001 * (k - 600)));
    *w_m = (float)(0.9 * *w_ref + 0.05 * scale * sin(2.0 * PI * 40.0 * t) + 0.01 * scale * sin(17.0 * k));
}

static void test_validation(void)
{
    p2d_speed_t ctl, before;
    p2d_filter_config_t f;
    p2d_speed_config_t cfg;

    CHECK(filtered(&ctl, false, torque_filter()) == P2D_OK);
    CHECK(ctl.coef[ctl.active].filtered && ctl.coef[ctl.active].general_step);
    CHECK(filtered(&ctl, false, no_filter()) == P2D_OK);
    CHECK(!ctl.coef[ctl.active].filtered && !ctl.coef[ctl.active].general_step);
    f = torque_filter();
    CHECK(p2d_speed_set_filter(0, &f) == P2D_ERR_NULL);
    CHECK(p2d_speed_set_filter(&ctl, 0) == P2D_ERR_NULL);
    f.notch_freq_Hz = 500.0f; /* the Nyquist frequency at Ts = 1 ms */
    CHECK(filtered(&ctl, false, f) == P2D_ERR_NOTCH_FREQ);
    f = torque_filter();
    f.notch_depth = 0.8f;
    CHECK(filtered(&ctl, false, f) == P2D_ERR_NOTCH_DEPTH);
    f = torque_filter();
    f.lowpass_zeta = -1.0f;
    CHECK(filtered(&ctl, false, f) == P2D_ERR_LOWPASS_ZETA);

    /* a rejected update changes nothing, and the filters in force stay */
    CHECK(filtered(&ctl, false, torque_filter()) == P2D_OK);
    f = torque_filter();
    f.notch_width_Hz = -2.0f;
    memcpy(&before, &ctl, sizeof ctl);
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_ERR_NOTCH_WIDTH);
    CHECK(memcmp(&ctl, &before, sizeof ctl) == 0);
    /* set_config recomputes the filters in force for its Ts: at Ts = 5 ms the 200 Hz low-pass is at Nyquist */
    cfg = drive_config(false);
    cfg.Ts_s = 5e-3f;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_ERR_LOWPASS_FREQ);
    CHECK(memcmp(&ctl, &before, sizeof ctl) == 0);
    cfg.Ts_s = 2e-3f;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_OK);
    CHECK_CLOSE(ctl.filter_coef[ctl.active].lowpass.g, tan(PI * 200.0 * 2e-3), 1e-6);
    CHECK(memcmp(&ctl.filter_config, &before.filter_config, sizeof ctl.filter_config) == 0);
}

/*
 * Unsaturated, the command of the filtered controller is the command of the
 * plain one through the designed filters: H(z) acts on the feedback and the
 * feedforward alike, and the back calculation (u* = 0) keeps both PIs equal.
 */
static void test_command_through_the_filters(void)
{
    const bool salient_cases[2] = {false, true};
    for (int m = 0; m < 2; ++m) {
        p2d_speed_t plain, ctl;
        p2d_filter_config_t f = torque_filter();
        direct_form_t n = notch_design(&f, 1e-3), l = lowpass_design(&f, 1e-3);
        direct_state_t sn = {{0.0, 0.0}, {0.0, 0.0}}, sl = {{0.0, 0.0}, {0.0, 0.0}};
        double worst = 0.0, largest = 0.0;
        CHECK(filtered(&plain, salient_cases[m], no_filter()) == P2D_OK);
        CHECK(filtered(&ctl, salient_cases[m], torque_filter()) == P2D_OK);
        for (int k = 0; k < 1200; ++k) {
            p2d_speed_output_t op, of;
            float w_ref, w_m;
            double u_f;
            inputs(k, 2.0f, &w_ref, &w_m);
            p2d_speed_step(&plain, w_ref, w_m, &op);
            p2d_speed_step(&ctl, w_ref, w_m, &of);
            u_f = direct_step(&l, &sl, direct_step(&n, &sn, op.T_unsat_Nm));
            CHECK(!op.saturated && !of.saturated && !of.fault);
            CHECK(of.T_ref_Nm == of.T_unsat_Nm && op.T_ff_Nm == of.T_ff_Nm && op.e_radps == of.e_radps);
            worst = fmax(worst, fabs((double)of.T_unsat_Nm - u_f));
            largest = fmax(largest, fabs(u_f));
        }
        CHECK(largest > 1.0);
        CHECK_CLOSE(worst / largest, 0.0, 2e-6);
        CHECK(plain.x_Nm == ctl.x_Nm);
    }
}

/*
 * Saturated, the limit acts on u_f and the back calculation sees it: per sample
 * x[k] = x[k-1] + Ki Ts e + Ki Ka Ts (T_ref - u_f) + Fr0 dr (Fig. 5), with
 * T_ref = Sat(u_f); clamping holds x while u* and e have opposite signs.
 */
static void test_anti_windup_sees_the_filtered_command(void)
{
    const p2d_anti_windup_t modes[2] = {P2D_AW_BACK_CALCULATION, P2D_AW_CLAMPING};
    for (int m = 0; m < 2; ++m) {
        p2d_speed_t ctl;
        p2d_speed_config_t cfg = drive_config(false);
        p2d_filter_config_t f = torque_filter();
        int saturated = 0;
        cfg.anti_windup = modes[m];
        CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
        CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_OK);
        for (int k = 0; k < 1200; ++k) {
            const p2d_speed_coef_t *c = &ctl.coef[ctl.active];
            p2d_speed_output_t out;
            float w_ref, w_m, T_max = c->T_max_Nm;
            double x0 = ctl.x_Nm, dr = 0.0, u_star, dx;
            inputs(k, 40.0f, &w_ref, &w_m);
            dr = (double)w_ref - (double)ctl.r_prev_radps;
            p2d_speed_step(&ctl, w_ref, w_m, &out);
            CHECK(!out.fault);
            CHECK(out.T_ref_Nm == (out.T_unsat_Nm > T_max ? T_max : out.T_unsat_Nm < -T_max ? -T_max : out.T_unsat_Nm));
            CHECK(out.saturated == (out.T_ref_Nm != out.T_unsat_Nm));
            saturated += out.saturated;
            u_star = (double)out.T_ref_Nm - (double)out.T_unsat_Nm;
            dx = (double)c->pi.Ki_Ts * out.e_radps + (double)c->pi.Ki_Ka_Ts * u_star;
            if (c->clamping && ((u_star < 0.0 && out.e_radps > 0.0f) || (u_star > 0.0 && out.e_radps < 0.0f))) dx = 0.0;
            CHECK_CLOSE(ctl.x_Nm, x0 + dx + (double)c->ff_Fr0 * dr,
                        1e-6 * (fabs(x0) + fabs(dx) + fabs((double)c->ff_Fr0 * dr) + 1.0));
        }
        CHECK(saturated > 100);
    }
}

/* step is compute + update with the controller's own command, to the bit, filtered too. */
static void test_step_is_compute_and_update(void)
{
    const bool salient_cases[2] = {false, true};
    for (int m = 0; m < 2; ++m) {
        p2d_speed_t a, b;
        CHECK(filtered(&a, salient_cases[m], torque_filter()) == P2D_OK);
        CHECK(filtered(&b, salient_cases[m], torque_filter()) == P2D_OK);
        for (int k = 0; k < 1200; ++k) {
            p2d_speed_output_t oa, ob;
            float w_ref, w_m;
            inputs(k, 40.0f, &w_ref, &w_m);
            p2d_speed_step(&a, w_ref, w_m, &oa);
            p2d_speed_compute(&b, w_ref, w_m, &ob);
            p2d_speed_update(&b, &ob, ob.T_ref_Nm);
            CHECK(same_output(&oa, &ob));
            CHECK(same_state(&a, &b));
        }
    }
}

/* A filter switched on at a steady state does not move the command; reset puts the filters at rest. */
static void test_bumpless(void)
{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_filter_config_t f = torque_filter();
    CHECK(filtered(&ctl, false, no_filter()) == P2D_OK);
    p2d_speed_reset(&ctl, 50.0f, 3.25f);
    p2d_speed_step(&ctl, 50.0f, 50.0f, &out);
    CHECK(out.T_ref_Nm == 3.25f);
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_OK);
    for (int k = 0; k < 10; ++k) {
        p2d_speed_step(&ctl, 50.0f, 50.0f, &out);
        CHECK(out.T_ref_Nm == 3.25f);
    }
    /* new filter frequencies keep the state: at rest the command stays */
    f.notch_freq_Hz = 60.0f;
    f.lowpass_freq_Hz = 0.0f;
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_OK);
    p2d_speed_step(&ctl, 50.0f, 50.0f, &out);
    CHECK(out.T_ref_Nm == 3.25f);
    /* the low-pass switched on again starts at rest at the command */
    f.lowpass_freq_Hz = 150.0f;
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_OK);
    CHECK(ctl.filter.lowpass.s1 == 0.0f && ctl.filter.lowpass.s2 == ctl.x_Nm);
    p2d_speed_reset(&ctl, 10.0f, -1.5f);
    CHECK(ctl.filter.notch.s1 == 0.0f && ctl.filter.notch.s2 == -1.5f && ctl.filter.lowpass.s2 == -1.5f);
    p2d_speed_step(&ctl, 10.0f, 10.0f, &out);
    CHECK(out.T_ref_Nm == -1.5f);
}

/* Filters switched off: the controller computes the bits of one that never had filters. */
static void test_switched_off_is_the_plain_controller(void)
{
    p2d_speed_t plain, ctl;
    p2d_filter_config_t off = no_filter();
    CHECK(filtered(&plain, false, no_filter()) == P2D_OK);
    CHECK(filtered(&ctl, false, torque_filter()) == P2D_OK);
    for (int k = 0; k < 400; ++k) {
        p2d_speed_output_t out;
        float w_ref, w_m;
        inputs(k, 40.0f, &w_ref, &w_m);
        p2d_speed_step(&ctl, w_ref, w_m, &out);
    }
    CHECK(p2d_speed_set_filter(&ctl, &off) == P2D_OK);
    plain.x_Nm = ctl.x_Nm;
    plain.r_prev_radps = ctl.r_prev_radps;
    plain.y_ff_prev_Nm = ctl.y_ff_prev_Nm;
    for (int k = 400; k < 1200; ++k) {
        p2d_speed_output_t op, oc;
        float w_ref, w_m;
        inputs(k, 40.0f, &w_ref, &w_m);
        p2d_speed_step(&plain, w_ref, w_m, &op);
        p2d_speed_step(&ctl, w_ref, w_m, &oc);
        CHECK(same_output(&op, &oc));
    }
    CHECK(plain.x_Nm == ctl.x_Nm);
}

/*
 * The back-calculation loop runs through the filters: a low-pass far below
 * the anti-windup bandwidth Ki Ka makes it unstable, which init refuses; the
 * same Ka without the filter (Ki Ka Ts < 2) is accepted.
 */
static void test_anti_windup_loop_stability(void)
{
    p2d_speed_t ctl;
    p2d_speed_config_t cfg = drive_config(false);
    p2d_filter_config_t f = no_filter();
    /* Ki Ka Ts = 1.5: the anti-windup loop pole at 1 - 1.5 = -0.5 alone */
    cfg.Ka =
        1.5f / (cfg.J_kgm2 * (cfg.alpha_radps / (2.0f * cfg.zeta)) * (cfg.alpha_radps / (2.0f * cfg.zeta)) * cfg.Ts_s);
    CHECK(p2d_speed_init(&ctl, &cfg) == P2D_OK);
    f.lowpass_freq_Hz = 20.0f;
    f.lowpass_zeta = 0.7f;
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_ERR_KA);
    /* with the paper's Ka = 1/Kp (Ki Ka Ts = 0.0255) the loop through the same low-pass is stable */
    cfg.Ka = p2d_speed_Ka_default(cfg.J_kgm2, cfg.alpha_radps);
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_OK);
    CHECK(p2d_speed_set_filter(&ctl, &f) == P2D_OK);
    /* and set_config refuses the large Ka while the low-pass is on */
    cfg.Ka =
        1.5f / (cfg.J_kgm2 * (cfg.alpha_radps / (2.0f * cfg.zeta)) * (cfg.alpha_radps / (2.0f * cfg.zeta)) * cfg.Ts_s);
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_ERR_KA);
    /* clamping has no such loop */
    cfg.anti_windup = P2D_AW_CLAMPING;
    CHECK(p2d_speed_set_config(&ctl, &cfg) == P2D_OK);
}

/* Non-finite policy with filters: a command that overflows in the filters faults; the state is never poisoned. */
static void test_non_finite_policy(void)
{
    p2d_speed_t ctl, before;
    p2d_speed_output_t out;
    p2d_filter_config_t f = no_filter();
    f.lowpass_freq_Hz = 100.0f;
    f.lowpass_zeta = 0.05f; /* a resonant low-pass: gain 10 at 100 Hz */
    CHECK(filtered(&ctl, false, f) == P2D_OK);
    p2d_speed_step(&ctl, NAN, 0.0f, &out);
    CHECK(out.fault && out.T_ref_Nm == 0.0f && ctl.fault_count == 1u);
    memcpy(&before, &ctl, sizeof ctl);
    p2d_speed_compute(&ctl, 1.0f, 0.5f, &out);
    p2d_speed_update(&ctl, &out, NAN);
    before.fault_count++;
    CHECK(memcmp(&ctl, &before, sizeof ctl) == 0);
    /* an error of 1e37 rad/s alternating at 100 Hz drives the resonant low-pass past FLT_MAX */
    for (int k = 0; k < 100 && ctl.fault_count == before.fault_count; ++k) {
        p2d_speed_step(&ctl, 0.0f, k % 10 < 5 ? 1e37f : -1e37f, &out);
    }
    CHECK(ctl.fault_count > before.fault_count && out.fault && out.T_ref_Nm == 0.0f);
    CHECK(isfinite(ctl.x_Nm) && isfinite(ctl.filter.lowpass.s1) && isfinite(ctl.filter.lowpass.s2));
}

int main(void)
{
    test_validation();
    test_command_through_the_filters();
    test_anti_windup_sees_the_filtered_command();
    test_step_is_compute_and_update();
    test_bumpless();
    test_switched_off_is_the_plain_controller();
    test_anti_windup_loop_stability();
    test_non_finite_policy();
    return check_summary();
}
