/*
 * Unit tests of the fixed-point speed controllers (pmsm2dof/speed_fixed.h). Expected integers are
 * derived by hand from the header's rules for a design whose gains are powers of two; the sweep of
 * extreme inputs (every method, feedforward and anti-windup, gains at the top of their range) checks
 * the bounds and, built with -DP2D_SANITIZE=ON, runs under UndefinedBehaviorSanitizer.
 */
#include <stdint.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/speed_fixed.h"

/*
 * J = 1, alpha = 1, zeta = 0.5: Kp = 1, Ki = 1 (eq 9); Ts = 2^-10 s; 1DOF, no anti-windup. W_fs = 1 rad/s,
 * T_fs = 2 Nm: per unit b_e0 = (1 + 2^-11) / 2 = 16392 2^-15, Ki Ts = 2^-11 = 16384 2^-25 (Q15).
 * p = 2, psi_f = 0.5 Wb: kt = 1.5 Nm/A; i_max = 1 A: T_max = 1.5 Nm = 0.75 T_fs; I_fs = 2 A.
 */
static p2d_speed_fixed_config_t simple_config(void)
{
    p2d_speed_fixed_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.speed.J_kgm2 = 1.0f;
    cfg.speed.alpha_radps = 1.0f;
    cfg.speed.zeta = 0.5f;
    cfg.speed.m = 1.0f;
    cfg.speed.tau_i_s = 0.0f;
    cfg.speed.Ka = 1.0f;
    cfg.speed.Ts_s = 0x1p-10f;
    cfg.speed.i_max_A = 1.0f;
    cfg.speed.psi_f_Wb = 0.5f;
    cfg.speed.Ld_H = 1e-3f;
    cfg.speed.Lq_H = 1e-3f;
    cfg.speed.pole_pairs = 2u;
    cfg.speed.method = P2D_TUSTIN;
    cfg.speed.feedforward = P2D_FF_NONE;
    cfg.speed.anti_windup = P2D_AW_NONE;
    cfg.speed_full_scale_radps = 1.0f;
    cfg.torque_full_scale_Nm = 2.0f;
    cfg.current_full_scale_A = 2.0f;
    return cfg;
}

static void test_validation(void)
{
    p2d_speed_fixed_config_t cfg = simple_config();
    p2d_speed_q15_t q15, before;
    p2d_speed_q31_t q31;

    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_OK && p2d_speed_q31_init(&q31, &cfg) == P2D_OK);
    CHECK(p2d_speed_q15_init(0, &cfg) == P2D_ERR_NULL && p2d_speed_q31_init(&q31, 0) == P2D_ERR_NULL);
    cfg.speed.Lq_H = 2e-3f; /* salient */
    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_ERR_SALIENT && p2d_speed_q31_init(&q31, &cfg) == P2D_ERR_SALIENT);
    cfg = simple_config();
    cfg.torque_full_scale_Nm = 1.4f; /* below T_max = 1.5 Nm */
    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_ERR_TORQUE_FULL_SCALE);
    cfg = simple_config();
    cfg.current_full_scale_A = 0.9f; /* below i_max */
    CHECK(p2d_speed_q31_init(&q31, &cfg) == P2D_ERR_CURRENT_FULL_SCALE);
    cfg = simple_config();
    cfg.speed_full_scale_radps = 16384.0f; /* b_e0 per unit 8192: at the bound 2^13 */
    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_ERR_SPEED_FULL_SCALE);
    cfg.speed_full_scale_radps = NAN;
    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_ERR_SPEED_FULL_SCALE);
    cfg = simple_config();
    cfg.speed_full_scale_radps = 1e-7f; /* Ki Ts per unit 4.9e-11 < 2^-32: Q31 refuses, Q15 has its dead zone */
    CHECK(p2d_speed_q31_init(&q31, &cfg) == P2D_ERR_SPEED_FULL_SCALE && p2d_speed_q15_init(&q15, &cfg) == P2D_OK);
    cfg = simple_config();
    cfg.speed.zeta = 0.0f; /* the float controller's rules */
    CHECK(p2d_speed_q31_init(&q31, &cfg) == P2D_ERR_ZETA);

    /* set_config keeps the scalings: a changed one is refused and nothing changes */
    cfg = simple_config();
    CHECK(p2d_speed_q15_init(&q15, &cfg) == P2D_OK);
    memcpy(&before, &q15, sizeof before);
    cfg.torque_full_scale_Nm = 4.0f;
    CHECK(p2d_speed_q15_set_config(&q15, &cfg) == P2D_ERR_TORQUE_FULL_SCALE);
    CHECK(memcmp(&before, &q15, sizeof before) == 0);
}

static void test_q15_by_hand(void)
{
    p2d_speed_fixed_config_t cfg = simple_config();
    p2d_speed_q15_t ctl;
    p2d_speed_q15_output_t out;

    p2d_speed_fixed_gains_t g;
    CHECK(p2d_speed_q15_gains(&cfg, &g) == P2D_OK);
    /* the gains before quantisation, per unit: exact in double here */
    CHECK_CLOSE(g.b_e0, 0.5 + 0x1p-12, 0.0);
    CHECK_CLOSE(g.Ki_Ts, 0x1p-11, 0.0);
    CHECK_CLOSE(g.T_max, 0.75, 0.0);
    CHECK(p2d_speed_q15_init(&ctl, &cfg) == P2D_OK);
    CHECK(ctl.coef[0].b_e0.mantissa == 16392 && ctl.coef[0].b_e0.shift == 15u);
    CHECK(ctl.coef[0].Ki_Ts.mantissa == 16384 && ctl.coef[0].Ki_Ts.shift == 25u);
    CHECK(ctl.coef[0].T_max_q15 == 24576 && ctl.coef[0].iq_max_q15 == 16384);
    /* iq per T = T_fs / (kt I_fs) = 2/3: 21845.33 2^-15 */
    CHECK(ctl.coef[0].iq_per_T.mantissa == 21845 && ctl.coef[0].iq_per_T.shift == 15u);

    /* e = 1000: u = R(16392 * 1000, 15) = floor(500.24 + 0.5) = 500, iq = R(21845 * 500, 15) = 333 */
    p2d_speed_q15_reset(&ctl, 1000, 0);
    p2d_speed_q15_step(&ctl, 1000, 0, &out);
    CHECK(out.e_q15 == 1000 && out.T_unsat_q15 == 500 && out.T_ref_q15 == 500 && out.iq_ref_q15 == 333);
    CHECK(!out.saturated && out.T_ff_q15 == 0 && out.y_ff_q15 == 0);
    /* the dead zone: R(16384 e, 25) = 0 for -2^24 <= 16384 e < 2^24, i.e. -1024 <= e <= 1023 */
    CHECK(ctl.x_q15 == 0);
    p2d_speed_q15_reset(&ctl, 1000, 0);
    p2d_speed_q15_step(&ctl, 1000, 1000 - 1023, &out);
    CHECK(ctl.x_q15 == 0);
    p2d_speed_q15_reset(&ctl, 1000, 0);
    p2d_speed_q15_step(&ctl, 1000, 1000 - 1024, &out);
    CHECK(ctl.x_q15 == 1);
    p2d_speed_q15_reset(&ctl, 0, 0);
    p2d_speed_q15_step(&ctl, 0, 1024, &out); /* R(-2^24, 25) = floor(-1/2 + 1/2) = 0: round half up */
    CHECK(ctl.x_q15 == 0);
    p2d_speed_q15_reset(&ctl, 0, 0);
    p2d_speed_q15_step(&ctl, 0, 1025, &out);
    CHECK(ctl.x_q15 == -1);
    /* the limit: e = 32767 - (-32768) = 65535, u = R(16392 * 65535, 15) = floor(32783.49976 + 1/2) = 32783 > T_max */
    p2d_speed_q15_reset(&ctl, 32767, 0);
    p2d_speed_q15_step(&ctl, 32767, -32768, &out);
    CHECK(out.T_unsat_q15 == 32783 && out.T_ref_q15 == 24576 && out.saturated);
    /* iq = R(21845 * 24576, 15) = 16384 = iq_max */
    CHECK(out.iq_ref_q15 == 16384);
}

static void test_q31_by_hand(void)
{
    p2d_speed_fixed_config_t cfg = simple_config();
    p2d_speed_q31_t ctl;
    p2d_speed_q31_output_t out;

    CHECK(p2d_speed_q31_init(&ctl, &cfg) == P2D_OK);
    /* b_e0 = (1 + 2^-11) / 2 = 1074266112 2^-31, Ki Ts = 2^-11 = 2^30 2^-41 */
    CHECK(ctl.coef[0].b_e0.mantissa == 1074266112 && ctl.coef[0].b_e0.shift == 31u);
    CHECK(ctl.coef[0].Ki_Ts.mantissa == 1073741824 && ctl.coef[0].Ki_Ts.shift == 41u);
    CHECK(ctl.coef[0].T_max_q31 == 1610612736); /* 0.75 2^31 */
    /* one LSB of error: x_q62 += R(2^30, 41 - 31) = 2^20, 2^-11 of a torque LSB in Q62 */
    p2d_speed_q31_reset(&ctl, 5, 0);
    p2d_speed_q31_step(&ctl, 5, 4, &out);
    CHECK(ctl.x_q62 == ((int64_t)1 << 20));
    /* and -1: -2^20 */
    p2d_speed_q31_reset(&ctl, 5, 0);
    p2d_speed_q31_step(&ctl, 5, 6, &out);
    CHECK(ctl.x_q62 == -((int64_t)1 << 20));
    /* e = 2^32 - 1: u = R(1074266112 (2^32 - 1), 31) = 2148532223 (saturates at T_max) */
    p2d_speed_q31_reset(&ctl, INT32_MAX, 0);
    p2d_speed_q31_step(&ctl, INT32_MAX, INT32_MIN, &out);
    CHECK(out.e_q31 == INT64_C(4294967295) && out.T_unsat_q31 == INT64_C(2148532223));
    CHECK(out.T_ref_q31 == 1610612736 && out.saturated);
}

/* x, y and the outputs within their bounds (speed_fixed.h) */
static int q15_bounded(const p2d_speed_q15_t *c, const p2d_speed_q15_output_t *o)
{
    const p2d_speed_q15_coef_t *k = &c->coef[c->active];
    return c->x_q15 <= 65535 && c->x_q15 >= -65535 && c->y_ff_prev_q15 <= 65535 && c->y_ff_prev_q15 >= -65535 &&
           o->T_unsat_q15 <= 65535 && o->T_unsat_q15 >= -65535 && o->T_ff_q15 <= 65535 && o->T_ff_q15 >= -65535 &&
           o->T_ref_q15 <= k->T_max_q15 && o->T_ref_q15 >= -k->T_max_q15 && o->iq_ref_q15 <= k->iq_max_q15 &&
           o->iq_ref_q15 >= -k->iq_max_q15;
}

static int q31_bounded(const p2d_speed_q31_t *c, const p2d_speed_q31_output_t *o)
{
    const p2d_speed_q31_coef_t *k = &c->coef[c->active];
    const int64_t L = INT64_C(4294967295);
    return c->x_q62 >= -INT64_MAX && c->y_ff_prev_q31 <= L && c->y_ff_prev_q31 >= -L && o->T_unsat_q31 <= L &&
           o->T_unsat_q31 >= -L && o->T_ff_q31 <= L && o->T_ff_q31 >= -L && o->T_ref_q31 <= k->T_max_q31 &&
           o->T_ref_q31 >= -k->T_max_q31 && o->iq_ref_q31 <= k->iq_max_q31 && o->iq_ref_q31 >= -k->iq_max_q31;
}

/*
 * Every method, feedforward and anti-windup, with the gains near their bound (b_e0 3000 per unit,
 * the FULL derivative 4600: 2^13 is the bound) and near the smallest shift, driven by every triple of extreme speeds
 * and applied torques: all bounds hold, and (under UBSan) no shift of a negative number, no overflow.
 */
static void test_extremes(void)
{
    const int32_t speeds16[] = {INT16_MIN, INT16_MIN + 1, -1, 0, 1, INT16_MAX - 1, INT16_MAX};
    const int32_t speeds32[] = {INT32_MIN, INT32_MIN + 1, -1, 0, 1, INT32_MAX - 1, INT32_MAX};
    const size_t n = sizeof speeds16 / sizeof speeds16[0];
    unsigned bad = 0u, runs = 0u;
    for (int method = 0; method <= (int)P2D_TUSTIN; ++method) {
        for (int ff = 0; ff <= (int)P2D_FF_FULL; ++ff) {
            for (int aw = 0; aw <= (int)P2D_AW_CLAMPING; ++aw) {
                p2d_speed_fixed_config_t cfg = simple_config();
                p2d_speed_q15_t a;
                p2d_speed_q31_t b;
                cfg.speed.method = (p2d_method_t)method;
                cfg.speed.feedforward = (p2d_feedforward_t)ff;
                cfg.speed.anti_windup = (p2d_anti_windup_t)aw;
                cfg.speed.m = ff == (int)P2D_FF_LOWPASS ? 1.0f : 1.5f;
                cfg.speed.tau_i_s = 1e-3f; /* Kd / Ts = J alpha m tau / Ts = 1.5 Nm s/rad: 4600 per unit */
                cfg.speed_full_scale_radps = 6000.0f;
                cfg.torque_full_scale_Nm = 2.0f;
                if (p2d_speed_q15_init(&a, &cfg) != P2D_OK || p2d_speed_q31_init(&b, &cfg) != P2D_OK) {
                    bad++;
                    continue;
                }
                for (size_t i = 0; i < n; ++i) {
                    for (size_t j = 0; j < n; ++j) {
                        for (size_t k = 0; k < n; ++k) {
                            p2d_speed_q15_output_t oa;
                            p2d_speed_q31_output_t ob;
                            p2d_speed_q15_compute(&a, (int16_t)speeds16[i], (int16_t)speeds16[j], &oa);
                            p2d_speed_q15_update(&a, &oa, (int16_t)speeds16[k]);
                            p2d_speed_q31_compute(&b, speeds32[i], speeds32[j], &ob);
                            p2d_speed_q31_update(&b, &ob, speeds32[k]);
                            if (!q15_bounded(&a, &oa) || !q31_bounded(&b, &ob)) bad++;
                            runs++;
                        }
                    }
                }
            }
        }
    }
    CHECK(bad == 0u);
    CHECK(runs == 36u * 343u);
}

/* A parameter update at rest at a constant reference does not move the command. */
static void test_bumpless(void)
{
    p2d_speed_fixed_config_t cfg = simple_config();
    p2d_speed_q15_t a;
    p2d_speed_q31_t b;
    p2d_speed_q15_output_t oa, oa2;
    p2d_speed_q31_output_t ob, ob2;
    cfg.speed.anti_windup = P2D_AW_BACK_CALCULATION;
    CHECK(p2d_speed_q15_init(&a, &cfg) == P2D_OK && p2d_speed_q31_init(&b, &cfg) == P2D_OK);
    for (int k = 0; k < 50; ++k) {
        p2d_speed_q15_step(&a, 3000, 1500, &oa);
        p2d_speed_q31_step(&b, 3000 << 16, 1500 << 16, &ob);
    }
    p2d_speed_q15_compute(&a, 3000, 3000, &oa);
    p2d_speed_q31_compute(&b, 3000 << 16, 3000 << 16, &ob);
    cfg.speed.alpha_radps = 3.0f;
    cfg.speed.Ka = 0.2f;
    CHECK(p2d_speed_q15_set_config(&a, &cfg) == P2D_OK && p2d_speed_q31_set_config(&b, &cfg) == P2D_OK);
    CHECK(a.active == 1u && b.active == 1u);
    p2d_speed_q15_compute(&a, 3000, 3000, &oa2);
    p2d_speed_q31_compute(&b, 3000 << 16, 3000 << 16, &ob2);
    CHECK(oa2.T_ref_q15 == oa.T_ref_q15 && ob2.T_ref_q31 == ob.T_ref_q31 && oa.T_ref_q15 != 0);
}

int main(void)
{
    test_validation();
    test_q15_by_hand();
    test_q31_by_hand();
    test_extremes();
    test_bumpless();
    return check_summary();
}
