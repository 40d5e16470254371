/*
 * libFuzzer target: the dq current controllers (pmsm2dof/current.h; paper
 * Fig. 1 inner loop, eq 1 and 3), built with
 * -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a configuration, valid or not, and
 * then to operations until the bytes run out:
 *   op % 8 in 0..3  one sample: references, measured currents, w_e, u_dc and
 *                   the applied voltage drawn at random
 *   op % 8 == 4     a closed-loop run of 1..2048 samples on the dq model of eq 1
 *                   (forward Euler in double, motor parameters near the design ones)
 *   op % 8 == 5     set_config with one field of the active configuration redrawn
 *   op % 8 == 6     set_config with a fresh configuration
 *   op % 8 == 7     p2d_current_reset
 * The applied voltage handed to p2d_current_update is, by (op >> 3) % 4: the
 * controller's own command (p2d_current_step), that command scaled by a
 * fraction in [0, 1], any vector inside the limit circle, or any two floats.
 *
 * Invariants, checked after every call (abort on violation):
 *  - init and set_config either accept or reject; a rejected call leaves the
 *    controller bit-identical and names a current-controller parameter; an
 *    accepted configuration is inside the documented ranges with finite
 *    coefficients (a probe sample of 1e-30 neither faults nor is refused) and
 *    a back-calculation loop gain Rs Ts / L in [0, 2); set_config gives the
 *    same status as init and a controller that computes the same outputs bit
 *    for bit, leaves the set in force untouched and keeps the state.
 *  - compute does not change the controller.
 *  - a non-finite input (u_dc included) raises the fault flag; a fault gives a
 *    zero voltage; otherwise the command is finite, ||u_dq|| <= max(u_dc, 0)/sqrt(3)
 *    up to float32 rounding, equal to the unlimited vector when not saturated;
 *    with d-axis priority ud_ref = Sat(ud) within +-u_max exactly, and uq_ref
 *    is uq or, cut, of its sign and on the circle that ud_ref leaves.
 *  - update with a fault or a non-finite applied voltage only counts the
 *    fault; the state stays finite after every call.
 *  - per axis, with g = Ki Ka Ts, b = b_e0 and the decoupling term dec
 *    (u = b e + x[k-1] + dec), the integrator bounds of fuzz_speed.c with
 *    T_app -> u_applied and T_ff -> dec.
 */
#include "fuzz_common.h"

#include "pmsm2dof/current.h"

#define FZ_INV_SQRT3 0.57735026918962576

/* Controller and plant of one fuzz input. */
typedef struct {
    p2d_current_t ctl; /* controller under test */
    double id_A;       /* plant d-axis current of the closed-loop runs [A] */
    double iq_A;       /* plant q-axis current [A] */
} fz_current_rig_t;

/* Inputs of one sample. */
typedef struct {
    float id_ref_A, iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V;
} fz_current_in_t;

/*
 * A configuration around a small servo motor: Rs = 0.5 ohm, Ld = 5 mH,
 * Lq = 8 mH, psi_f = 0.1 Wb, Ts = 100 us, tau_i = 10 Ts. Bit 0 of the shape
 * byte makes it a surface PMSM (Lq = Ld), bit 1 turns decoupling on.
 */
static void fz_current_config(fz_reader_t *r, p2d_current_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    double Ts_nominal;
    memset(cfg, 0, sizeof *cfg);
    cfg->Rs_ohm = fz_float(r, 0.5, false);
    cfg->Ld_H = fz_float(r, 5e-3, false);
    cfg->Lq_H = (shape & 1u) ? cfg->Ld_H : fz_float(r, 8e-3, false);
    cfg->psi_f_Wb = fz_float(r, 0.1, false);
    cfg->Ts_s = fz_float(r, 1e-4, false);
    Ts_nominal = (isfinite(cfg->Ts_s) && cfg->Ts_s > 0.0f) ? (double)cfg->Ts_s : 1e-4;
    cfg->tau_i_s = fz_float(r, 10.0 * Ts_nominal, false);
    cfg->method = (p2d_method_t)fz_enum(r, 3u);
    cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u);
    cfg->decouple = (shape & 2u) != 0u;
}

static float fz_near(fz_reader_t *r, float current, double fallback)
{
    double nominal = (isfinite(current) && current != 0.0f) ? fabs((double)current) : fallback;
    return fz_float(r, nominal, false);
}

/* The active configuration with one field redrawn. */
static void fz_current_config_mutated(fz_reader_t *r, const p2d_current_config_t *active, p2d_current_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->Rs_ohm = active->Rs_ohm;
    cfg->Ld_H = active->Ld_H;
    cfg->Lq_H = active->Lq_H;
    cfg->psi_f_Wb = active->psi_f_Wb;
    cfg->tau_i_s = active->tau_i_s;
    cfg->Ts_s = active->Ts_s;
    cfg->method = active->method;
    cfg->anti_windup = active->anti_windup;
    cfg->decouple = active->decouple;
    switch (fz_u8(r) % 9u) {
    case 0: cfg->Rs_ohm = fz_near(r, cfg->Rs_ohm, 0.5); break;
    case 1: cfg->Ld_H = fz_near(r, cfg->Ld_H, 5e-3); break;
    case 2: cfg->Lq_H = fz_near(r, cfg->Lq_H, 8e-3); break;
    case 3: cfg->psi_f_Wb = fz_near(r, cfg->psi_f_Wb, 0.1); break;
    case 4: cfg->tau_i_s = fz_near(r, cfg->tau_i_s, 1e-3); break;
    case 5: cfg->Ts_s = fz_near(r, cfg->Ts_s, 1e-4); break;
    case 6: cfg->method = (p2d_method_t)fz_enum(r, 3u); break;
    case 7: cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u); break;
    default: cfg->decouple = !cfg->decouple; break;
    }
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }

static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status > P2D_OK && status < P2D_STATUS_COUNT && status != P2D_ERR_NULL, "status %d", (int)status);
    FZ_REQUIRE(status == P2D_ERR_RS || status == P2D_ERR_LD || status == P2D_ERR_LQ || status == P2D_ERR_PSI_F ||
                   status == P2D_ERR_TAU_I || status == P2D_ERR_TS || status == P2D_ERR_TS_UNSTABLE ||
                   status == P2D_ERR_METHOD || status == P2D_ERR_ANTI_WINDUP,
               "status %d names no current-controller parameter", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

static bool fz_axis_finite(const p2d_pi_coef_t *a)
{
    return isfinite(a->b_e0) && isfinite(a->Ki_Ts) && isfinite(a->Ki_Ka_Ts);
}

static void fz_check_accepted(const p2d_current_config_t *cfg, const p2d_current_coef_t *c)
{
    FZ_REQUIRE(fz_positive(cfg->Rs_ohm) && fz_positive(cfg->Ld_H) && fz_positive(cfg->Lq_H) &&
                   isfinite(cfg->psi_f_Wb) && cfg->psi_f_Wb >= 0.0f && fz_positive(cfg->Ts_s) &&
                   isfinite(cfg->tau_i_s) && cfg->tau_i_s >= cfg->Ts_s,
               "accepted a configuration outside the documented ranges");
    FZ_REQUIRE((unsigned)cfg->method <= 2u && (unsigned)cfg->anti_windup <= 2u, "accepted method %u anti_windup %u",
               (unsigned)cfg->method, (unsigned)cfg->anti_windup);
    FZ_REQUIRE(fz_axis_finite(&c->d) && fz_axis_finite(&c->q) && isfinite(c->Ld_H) && isfinite(c->Lq_H) &&
                   isfinite(c->psi_f_Wb),
               "non-finite coefficient: d b_e0 %g Ki_Ts %g Ki_Ka_Ts %g; q b_e0 %g Ki_Ts %g Ki_Ka_Ts %g",
               (double)c->d.b_e0, (double)c->d.Ki_Ts, (double)c->d.Ki_Ka_Ts, (double)c->q.b_e0, (double)c->q.Ki_Ts,
               (double)c->q.Ki_Ka_Ts);
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        FZ_REQUIRE(c->d.Ki_Ka_Ts >= 0.0f && c->d.Ki_Ka_Ts < 2.0f && c->q.Ki_Ka_Ts >= 0.0f && c->q.Ki_Ka_Ts < 2.0f,
                   "back-calculation loop gain d %g q %g", (double)c->d.Ki_Ka_Ts, (double)c->q.Ki_Ka_Ts);
    } else {
        FZ_REQUIRE(c->d.Ki_Ka_Ts == 0.0f && c->q.Ki_Ka_Ts == 0.0f, "Ki Ka Ts without back calculation");
    }
    FZ_REQUIRE(c->clamping == (cfg->anti_windup == P2D_AW_CLAMPING), "clamping flag");
}

static void fz_check_state_finite(const p2d_current_t *ctl)
{
    FZ_REQUIRE(isfinite(ctl->x_d_V) && isfinite(ctl->x_q_V), "state poisoned: x_d %g x_q %g", (double)ctl->x_d_V,
               (double)ctl->x_q_V);
}

/*
 * A probe sample on a copy of an accepted controller, from cleared
 * integrators: with inputs of 1e-30 no product of a finite coefficient
 * overflows, so a fault or a refused update can only come from a non-finite
 * coefficient.
 */
static void fz_probe(const p2d_current_t *ctl)
{
    p2d_current_t copy;
    p2d_current_output_t out;
    memcpy(&copy, ctl, sizeof copy);
    p2d_current_reset(&copy);
    p2d_current_step(&copy, 1e-30f, 1e-30f, 0.0f, 0.0f, 1e-30f, 1.0f, &out);
    FZ_REQUIRE(!out.fault && copy.fault_count == ctl->fault_count,
               "an accepted configuration faults on a 1e-30 "
               "probe (ud %g uq %g): a coefficient is not finite",
               (double)out.ud_unsat_V, (double)out.uq_unsat_V);
}

/*
 * a and b compute the same outputs, bit for bit, from the integrators of a,
 * on a few probe inputs: their active coefficient sets are equivalent.
 */
static bool fz_same_controller(const p2d_current_t *a, const p2d_current_t *b)
{
    static const float probes[4][6] = {
        {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 300.0f},
        {2.0f, 5.0f, 1.5f, 4.0f, 400.0f, 300.0f},
        {-3.0f, 50.0f, 0.0f, -10.0f, -2000.0f, 50.0f},
        {1e-30f, 1e-30f, 0.0f, 0.0f, 1e-30f, 1.0f},
    };
    p2d_current_t b_state;
    memcpy(&b_state, b, sizeof b_state);
    b_state.x_d_V = a->x_d_V;
    b_state.x_q_V = a->x_q_V;
    for (int k = 0; k < 4; ++k) {
        const float *p = probes[k];
        p2d_current_output_t oa, ob;
        p2d_current_compute(a, p[0], p[1], p[2], p[3], p[4], p[5], &oa);
        p2d_current_compute(&b_state, p[0], p[1], p[2], p[3], p[4], p[5], &ob);
        if (!fz_bits_equal(oa.ud_unsat_V, ob.ud_unsat_V) || !fz_bits_equal(oa.uq_unsat_V, ob.uq_unsat_V) ||
            !fz_bits_equal(oa.ud_ref_V, ob.ud_ref_V) || !fz_bits_equal(oa.uq_ref_V, ob.uq_ref_V) ||
            oa.fault != ob.fault) {
            return false;
        }
    }
    return true;
}

static bool fz_config_equal(const p2d_current_config_t *a, const p2d_current_config_t *b)
{
    return fz_bits_equal(a->Rs_ohm, b->Rs_ohm) && fz_bits_equal(a->Ld_H, b->Ld_H) && fz_bits_equal(a->Lq_H, b->Lq_H) &&
           fz_bits_equal(a->psi_f_Wb, b->psi_f_Wb) && fz_bits_equal(a->tau_i_s, b->tau_i_s) &&
           fz_bits_equal(a->Ts_s, b->Ts_s) && a->method == b->method && a->anti_windup == b->anti_windup &&
           a->decouple == b->decouple;
}

static bool fz_init(p2d_current_t *ctl, const p2d_current_config_t *cfg)
{
    p2d_current_t pattern;
    p2d_status_t status;
    memset(ctl, 0xa5, sizeof *ctl);
    memcpy(&pattern, ctl, sizeof pattern);
    status = p2d_current_init(ctl, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(ctl, &pattern, sizeof pattern) == 0, "rejected init (status %d) wrote", (int)status);
        return false;
    }
    fz_check_accepted(cfg, &ctl->coef[ctl->active]);
    fz_probe(ctl);
    FZ_REQUIRE(ctl->x_d_V == 0.0f && ctl->x_q_V == 0.0f && ctl->fault_count == 0u, "init did not clear the state");
    return true;
}

static void fz_set_config(p2d_current_t *ctl, const p2d_current_config_t *cfg)
{
    p2d_current_t before, fresh;
    p2d_status_t status, status_init;
    memcpy(&before, ctl, sizeof before);
    status_init = p2d_current_init(&fresh, cfg);
    status = p2d_current_set_config(ctl, cfg);
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
    FZ_REQUIRE(fz_config_equal(&ctl->config, cfg), "config not stored");
    FZ_REQUIRE(fz_bits_equal(ctl->x_d_V, before.x_d_V) && fz_bits_equal(ctl->x_q_V, before.x_q_V) &&
                   ctl->fault_count == before.fault_count,
               "set_config changed the state");
}

static void fz_check_output(const fz_current_in_t *in, const p2d_current_output_t *out)
{
    double u_max = fmax((double)in->u_dc_V, 0.0) * FZ_INV_SQRT3, u_norm;
    if (!isfinite(in->id_ref_A) || !isfinite(in->iq_ref_A) || !isfinite(in->id_A) || !isfinite(in->iq_A) ||
        !isfinite(in->w_e_radps) || !isfinite(in->u_dc_V)) {
        FZ_REQUIRE(out->fault, "non-finite input without fault: id_ref %g iq_ref %g id %g iq %g w_e %g u_dc %g",
                   (double)in->id_ref_A, (double)in->iq_ref_A, (double)in->id_A, (double)in->iq_A,
                   (double)in->w_e_radps, (double)in->u_dc_V);
    }
    if (out->fault) {
        FZ_REQUIRE(out->ud_ref_V == 0.0f && out->uq_ref_V == 0.0f && !out->saturated, "fault output ud %g uq %g",
                   (double)out->ud_ref_V, (double)out->uq_ref_V);
        return;
    }
    FZ_REQUIRE(isfinite(out->ud_unsat_V) && isfinite(out->uq_unsat_V) && isfinite(out->ud_ref_V) &&
                   isfinite(out->uq_ref_V) && isfinite(out->ed_A) && isfinite(out->eq_A),
               "non-finite output without fault: ud %g uq %g", (double)out->ud_ref_V, (double)out->uq_ref_V);
    u_norm = hypot((double)out->ud_ref_V, (double)out->uq_ref_V);
    FZ_REQUIRE(fz_within_circle(u_norm, (float)u_max),
               "||u_dq|| = %.9g > u_dc/sqrt(3) = %.9g (u_dc %g; u (%g, %g), unlimited (%g, %g), saturated %d)", u_norm,
               u_max, (double)in->u_dc_V, (double)out->ud_ref_V, (double)out->uq_ref_V, (double)out->ud_unsat_V,
               (double)out->uq_unsat_V, (int)out->saturated);
    if (!out->saturated) {
        FZ_REQUIRE(out->ud_ref_V == out->ud_unsat_V && out->uq_ref_V == out->uq_unsat_V,
                   "unsaturated output changed the vector");
        return;
    }
    {
        /* d-axis priority: ud_ref = Sat(ud) within +-u_max (the controller's float32 u_max), exactly */
        float u_max_f = in->u_dc_V > 0.0f ? in->u_dc_V * (float)FZ_INV_SQRT3 : 0.0f;
        float ud_sat = out->ud_unsat_V > u_max_f ? u_max_f : (out->ud_unsat_V < -u_max_f ? -u_max_f : out->ud_unsat_V);
        double uq_room = sqrt(fmax((double)u_max_f * u_max_f - (double)out->ud_ref_V * out->ud_ref_V, 0.0));
        FZ_REQUIRE(out->ud_ref_V == ud_sat, "ud_ref %.9g is not Sat(ud %.9g) within +-%.9g", (double)out->ud_ref_V,
                   (double)out->ud_unsat_V, (double)u_max_f);
        FZ_REQUIRE((double)out->uq_ref_V * (double)out->uq_unsat_V >= 0.0 &&
                       fabs((double)out->uq_ref_V) <= fabs((double)out->uq_unsat_V),
                   "uq_ref %g is not uq %g or a cut of it", (double)out->uq_ref_V, (double)out->uq_unsat_V);
        /* a cut uq lies on the circle: |uq_ref| = sqrt(u_max^2 - ud_ref^2) up to rounding */
        FZ_REQUIRE(out->uq_ref_V == out->uq_unsat_V ||
                       fabs(fabs((double)out->uq_ref_V) - uq_room) <= 8.0 * FLT_EPSILON * (double)u_max_f + 0x1p-146,
                   "uq cut to %.9g, not to the room %.9g that ud_ref %.9g leaves of u_max %.9g", (double)out->uq_ref_V,
                   uq_room, (double)out->ud_ref_V, (double)u_max_f);
    }
}

/* The integrator bounds of one axis (see fuzz_speed.c and RELIABILITY.md). */
static void fz_check_axis(const p2d_pi_coef_t *a, bool clamping, char axis, double x0, double x1, double e,
                          double u_app, double dec, double dec_magnitude, double dec_subnormal)
{
    double g = a->Ki_Ka_Ts, kits = a->Ki_Ts, b = a->b_e0, slack;
    if (g > 0.0) {
        /* x[k] = (1 - g) x[k-1] + (Ki Ts - g b) e + g (u_app - dec), a contraction by |1 - g| < 1 */
        double bound = (fabs(kits - g * b) * fabs(e) + g * (fabs(u_app) + fabs(dec))) / (1.0 - fabs(1.0 - g));
        slack = fz_slack(fabs(x0) + fabs(kits * e) + g * (fabs(u_app) + fabs(b * e) + fabs(x0) + dec_magnitude)) +
                g * dec_subnormal;
        FZ_REQUIRE(fabs(x1) <= fmax(fabs(x0), bound) + slack,
                   "%c axis, back calculation: |x| %.9g -> %.9g above the bound %.9g (g %g Ki_Ts %g b_e0 %g e %g "
                   "u_app %g dec %g)",
                   axis, x0, x1, bound, g, kits, b, e, u_app, dec);
    } else if (clamping) {
        /* x moves towards z only while u has not passed u_app in the direction of e */
        double z = u_app + (kits - b) * e - dec;
        slack = fz_slack(fabs(x0) + fabs(b * e) + fabs(kits * e) + dec_magnitude + fabs(u_app)) + dec_subnormal;
        FZ_REQUIRE(x1 <= fmax(x0, z) + slack && x1 >= fmin(x0, z) - slack,
                   "%c axis, clamping: x %.9g -> %.9g passed z = %.9g (e %g u_app %g dec %g)", axis, x0, x1, z, e,
                   u_app, dec);
    }
}

static void fz_check_update(const p2d_current_t *before, const p2d_current_t *ctl, const fz_current_in_t *in,
                            const p2d_current_output_t *out, float ud_app, float uq_app)
{
    const p2d_current_coef_t *c = &before->coef[before->active];
    /*
     * decoupling terms of eq 1 as the compute adds them, the magnitudes of their
     * parts (relative rounding), and the absolute rounding of a first product
     * w_e Lq or Ld id that falls into the subnormals (2^-150 times the other factor)
     */
    double w_e = in->w_e_radps;
    double dec_d = -w_e * (double)c->Lq_H * (double)in->iq_A;
    double dec_q = w_e * ((double)c->Ld_H * (double)in->id_A + (double)c->psi_f_Wb);
    double dec_q_magnitude = fabs(w_e) * (fabs((double)c->Ld_H * (double)in->id_A) + (double)c->psi_f_Wb);
    fz_check_state_finite(ctl);
    if (ctl->fault_count != before->fault_count) {
        p2d_current_t expected;
        double ud_star = (double)ud_app - (double)out->ud_unsat_V, uq_star = (double)uq_app - (double)out->uq_unsat_V;
        double big = fmax(fmax(fabs((double)before->x_d_V), fabs((double)before->x_q_V)),
                          fmax(fmax(fabs(c->d.Ki_Ts * (double)out->ed_A), fabs(c->q.Ki_Ts * (double)out->eq_A)),
                               fmax(fabs(ud_star), fabs(uq_star))));
        memcpy(&expected, before, sizeof expected);
        expected.fault_count++;
        FZ_REQUIRE(memcmp(ctl, &expected, sizeof expected) == 0, "a rejected update changed the state");
        FZ_REQUIRE(out->fault || !isfinite(ud_app) || !isfinite(uq_app) || big > 0.25 * FLT_MAX,
                   "update refused a sample whose new state is finite (largest term %g)", big);
        return;
    }
    FZ_REQUIRE(!out->fault && isfinite(ud_app) && isfinite(uq_app),
               "a fault or a non-finite applied voltage (%g, %g) was not counted", (double)ud_app, (double)uq_app);
    fz_check_axis(&c->d, c->clamping, 'd', before->x_d_V, ctl->x_d_V, out->ed_A, ud_app, dec_d, fabs(dec_d),
                  0x1p-149 * fabs((double)in->iq_A));
    fz_check_axis(&c->q, c->clamping, 'q', before->x_q_V, ctl->x_q_V, out->eq_A, uq_app, dec_q, dec_q_magnitude,
                  0x1p-149 * fabs(w_e));
}

/* One sample; returns the applied voltage through ud_app, uq_app (0 on a fault). */
static void fz_sample(fz_current_rig_t *rig, fz_reader_t *r, unsigned mode, double fraction, double angle,
                      const fz_current_in_t *in, double *ud_out, double *uq_out)
{
    p2d_current_t before;
    p2d_current_output_t out;
    float ud_app, uq_app;
    memcpy(&before, &rig->ctl, sizeof before);
    if (mode == 0u) {
        p2d_current_step(&rig->ctl, in->id_ref_A, in->iq_ref_A, in->id_A, in->iq_A, in->w_e_radps, in->u_dc_V, &out);
        ud_app = out.ud_ref_V;
        uq_app = out.uq_ref_V;
    } else {
        p2d_current_compute(&rig->ctl, in->id_ref_A, in->iq_ref_A, in->id_A, in->iq_A, in->w_e_radps, in->u_dc_V, &out);
        FZ_REQUIRE(memcmp(&rig->ctl, &before, sizeof before) == 0, "compute changed the controller");
        if (mode == 1u) {
            ud_app = (float)(fraction * (double)out.ud_ref_V);
            uq_app = (float)(fraction * (double)out.uq_ref_V);
        } else if (mode == 2u) {
            double radius = fraction * fmax((double)in->u_dc_V, 0.0) * FZ_INV_SQRT3;
            ud_app = (float)(radius * cos(angle));
            uq_app = (float)(radius * sin(angle));
        } else {
            ud_app = fz_float(r, 100.0, true);
            uq_app = fz_float(r, 100.0, true);
        }
        p2d_current_update(&rig->ctl, &out, ud_app, uq_app);
    }
    fz_check_output(in, &out);
    fz_check_update(&before, &rig->ctl, in, &out, ud_app, uq_app);
    *ud_out = out.fault ? 0.0 : (double)ud_app;
    *uq_out = out.fault ? 0.0 : (double)uq_app;
}

static void fz_read_inputs(fz_reader_t *r, fz_current_in_t *in)
{
    in->id_ref_A = fz_float(r, 2.0, true);
    in->iq_ref_A = fz_float(r, 5.0, true);
    in->id_A = fz_float(r, 2.0, true);
    in->iq_A = fz_float(r, 5.0, true);
    in->w_e_radps = fz_float(r, 400.0, true);
    in->u_dc_V = fz_float(r, 300.0, false);
}

/*
 * Closed loop on the dq model of eq 1 with constant w_e:
 *   L_d did/dt = ud - R id + w_e L_q iq,  L_q diq/dt = uq - R iq - w_e (L_d id + psi_f)
 * with the motor parameters equal to the design ones times a factor in [0.5, 2].
 */
static void fz_closed_loop(fz_current_rig_t *rig, fz_reader_t *r)
{
    const p2d_current_config_t *cfg = &rig->ctl.config;
    uint32_t n = 1u + fz_u16(r) % 2048u;
    fz_current_in_t in;
    unsigned mode = fz_u8(r) % 3u;
    double fraction = fz_unit(r), angle = 6.283185307179586 * fz_unit(r);
    double mismatch = pow(2.0, 2.0 * fz_unit(r) - 1.0);
    double R = cfg->Rs_ohm * mismatch, Ld = cfg->Ld_H * mismatch, Lq = cfg->Lq_H * mismatch;
    double psi_f = cfg->psi_f_Wb, Ts = cfg->Ts_s;
    fz_read_inputs(r, &in);
    if (!isfinite(rig->id_A) || !isfinite(rig->iq_A)) {
        rig->id_A = 0.0;
        rig->iq_A = 0.0;
    }
    for (uint32_t k = 0; k < n; ++k) {
        double ud, uq, id = rig->id_A, iq = rig->iq_A, w_e = in.w_e_radps;
        in.id_A = (float)id;
        in.iq_A = (float)iq;
        fz_sample(rig, r, mode, fraction, angle, &in, &ud, &uq);
        rig->id_A = id + Ts / Ld * (ud - R * id + w_e * Lq * iq);
        rig->iq_A = iq + Ts / Lq * (uq - R * iq - w_e * (Ld * id + psi_f));
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_current_rig_t rig;
    p2d_current_config_t cfg;

    FZ_REQUIRE(p2d_current_init(NULL, &cfg) == P2D_ERR_NULL && p2d_current_set_config(&rig.ctl, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_current_config(&r, &cfg);
    if (!fz_init(&rig.ctl, &cfg)) return 0;
    rig.id_A = 0.0;
    rig.iq_A = 0.0;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 4: fz_closed_loop(&rig, &r); break;
        case 5:
            fz_current_config_mutated(&r, &rig.ctl.config, &cfg);
            fz_set_config(&rig.ctl, &cfg);
            break;
        case 6:
            fz_current_config(&r, &cfg);
            fz_set_config(&rig.ctl, &cfg);
            break;
        case 7: {
            p2d_current_t before;
            memcpy(&before, &rig.ctl, sizeof before);
            p2d_current_reset(&rig.ctl);
            FZ_REQUIRE(rig.ctl.x_d_V == 0.0f && rig.ctl.x_q_V == 0.0f &&
                           memcmp(rig.ctl.coef, before.coef, sizeof before.coef) == 0 &&
                           rig.ctl.active == before.active && rig.ctl.fault_count == before.fault_count,
                       "reset must clear the integrators and nothing else");
            break;
        }
        default: {
            fz_current_in_t in;
            double ud, uq, fraction, angle;
            fz_read_inputs(&r, &in);
            fraction = fz_unit(&r);
            angle = 6.283185307179586 * fz_unit(&r);
            fz_sample(&rig, &r, (op >> 3) % 4u, fraction, angle, &in, &ud, &uq);
            break;
        }
        }
    }
    return 0;
}
