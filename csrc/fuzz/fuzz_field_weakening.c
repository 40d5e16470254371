/*
 * libFuzzer target: the voltage-feedback field weakening
 * (pmsm2dof/field_weakening.h) and the speed controller's field-weakening
 * entry (p2d_speed_compute_fw, p2d_speed_step_fw in pmsm2dof/speed.h), built
 * with -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a field-weakening configuration and a
 * speed-controller configuration, valid or not, then to operations until the
 * bytes run out:
 *   op % 8 in 0..2  one field-weakening sample: ud, uq, u_dc drawn at random
 *   op % 8 == 3     one speed sample with a random id_fw; the applied torque is,
 *                   by (op >> 3) % 3, the own T_ref (step_fw), T_ref scaled by a
 *                   fraction, or any float
 *   op % 8 == 4     a closed run of 1..2048 samples at a constant electrical
 *                   speed: the steady-state voltages of eq 1 at the last
 *                   commands (ideal current loop) feed the field weakening,
 *                   its id feeds the speed controller's step_fw
 *   op % 8 == 5     field-weakening set_config with one field redrawn
 *   op % 8 == 6     field-weakening set_config with a fresh configuration
 *   op % 8 == 7     p2d_field_weakening_reset and p2d_speed_reset at random points
 *
 * Invariants, checked after every call (abort on violation):
 *  - field weakening: init and set_config accept or reject; a rejection leaves
 *    it bit-identical and names a field-weakening parameter; an accepted one is
 *    inside the documented ranges with Ki Ka Ts in [0, 2); set_config equals
 *    init, keeps the state and the set in force.
 *  - a non-finite ud, uq or u_dc raises the fault; a fault outputs
 *    Sat(x[k-1]) and only counts; otherwise id_ref = Sat(id_unsat) within
 *    [id_min_A, 0], u_ref = voltage_ratio max(u_dc, 0)/sqrt(3) to the bit,
 *    the flags agree with id_ref, and the state is finite.
 *  - integrator bounds (as RELIABILITY.md derives them for the controllers),
 *    g = Ki Ka Ts, b = b_e0, v = b e + x[k-1]:
 *      back calculation: x[k] = (1 - g) x[k-1] + (Ki Ts - g b) e + g id_ref, so
 *        |x[k]| <= max(|x[k-1]|, (|Ki Ts - g b| |e| + g |id_ref|) / (1 - |1 - g|));
 *      clamping: x[k] lies between x[k-1] and z = id_ref + (Ki Ts - b) e.
 *  - speed entry: a non-finite w_ref, w_m or id_fw raises the fault (zero
 *    torque and current); otherwise the outputs are finite, |T_ref| <= T_max,
 *    T_ref = T_unsat unless saturated (then of its sign and smaller),
 *    ||i_dq|| <= i_max up to 4 FLT_EPSILON, id_ref <= max(min(id_fw, 0), -i_max)
 *    (= for a surface PMSM), iq of the sign of T_ref and, with id_ref on that
 *    bound (not the MTPA vector), 1.5 p (psi_f + dL id_ref) iq_ref = T_ref up
 *    to 1e-5 relative (away from subnormals); with id_fw >= 0 on a
 *    surface PMSM or Ld < Lq it computes p2d_speed_compute to the bit.
 */
#include "fuzz_common.h"

#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/speed.h"

#include "../src/mtpa.h" /* the MTPA relation the controller uses, to tell its vector from the bound */

/* The controllers of one fuzz input. */
typedef struct {
    p2d_field_weakening_t fw; /* field weakening under test */
    p2d_speed_t spd;          /* speed controller whose step_fw is under test */
    bool have_speed;          /* the speed configuration was accepted */
    float id_A;               /* last d current command (ideal current loop) [A] */
    float iq_A;               /* last q current command [A] */
} fz_fw_rig_t;

/* A field weakening around a 48 V servo at 10 kHz. */
static void fz_fw_config(fz_reader_t *r, p2d_field_weakening_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->Kp_A_per_V = fz_float(r, 0.02, false);
    cfg->Ki_A_per_Vs = fz_float(r, 100.0, false);
    cfg->Ka_V_per_A = fz_float(r, 50.0, false);
    cfg->Ts_s = fz_float(r, 1e-4, false);
    cfg->voltage_ratio = fz_float(r, 0.95, false);
    cfg->id_min_A = -fz_float(r, 10.0, true);
    cfg->method = (p2d_method_t)fz_enum(r, 3u);
    cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u);
}

static void fz_fw_config_mutated(fz_reader_t *r, const p2d_field_weakening_config_t *active,
                                 p2d_field_weakening_config_t *cfg)
{
    *cfg = *active;
    switch (fz_u8(r) % 8u) {
    case 0: cfg->Kp_A_per_V = fz_float(r, 0.02, false); break;
    case 1: cfg->Ki_A_per_Vs = fz_float(r, 100.0, false); break;
    case 2: cfg->Ka_V_per_A = fz_float(r, 50.0, false); break;
    case 3: cfg->Ts_s = fz_float(r, 1e-4, false); break;
    case 4: cfg->voltage_ratio = fz_float(r, 0.95, false); break;
    case 5: cfg->id_min_A = -fz_float(r, 10.0, true); break;
    case 6: cfg->method = (p2d_method_t)fz_enum(r, 3u); break;
    default: cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u); break;
    }
}

/*
 * A speed controller for the same servo (J = 1e-3 kg m^2, alpha = 100 rad/s, 1 kHz,
 * 15 A, p = 4): by the shape byte a surface PMSM, Ld < Lq or Ld > Lq.
 */
static void fz_speed_config(fz_reader_t *r, p2d_speed_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    memset(cfg, 0, sizeof *cfg);
    cfg->J_kgm2 = fz_float(r, 1e-3, false);
    cfg->alpha_radps = fz_float(r, 100.0, false);
    cfg->zeta = 1.0f;
    cfg->m = 1.0f;
    cfg->Ka = p2d_speed_Ka_default(cfg->J_kgm2, cfg->alpha_radps);
    cfg->Ts_s = 1e-3f;
    cfg->i_max_A = fz_float(r, 15.0, false);
    cfg->psi_f_Wb = fz_float(r, 0.02, false);
    cfg->Ld_H = fz_float(r, 1e-3, false);
    cfg->Lq_H = shape % 3u == 0u ? cfg->Ld_H : cfg->Ld_H * (shape % 3u == 1u ? 2.0f : 0.5f);
    cfg->pole_pairs = 4u;
    cfg->method = P2D_TUSTIN;
    cfg->feedforward = P2D_FF_LOWPASS;
    cfg->anti_windup = (p2d_anti_windup_t)(shape / 3u % 3u);
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }
static bool fz_nonnegative(float x) { return isfinite(x) && x >= 0.0f; }

static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status == P2D_ERR_TS || status == P2D_ERR_METHOD || status == P2D_ERR_ANTI_WINDUP ||
                   (status >= P2D_ERR_FW_KP && status <= P2D_ERR_FW_ID_MIN),
               "status %d is not a field-weakening parameter", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
               "status %d has no parameter name or range", (int)status);
}

static void fz_check_accepted(const p2d_field_weakening_config_t *cfg, const p2d_field_weakening_coef_t *c)
{
    FZ_REQUIRE(fz_nonnegative(cfg->Kp_A_per_V) && fz_positive(cfg->Ki_A_per_Vs) && fz_nonnegative(cfg->Ka_V_per_A) &&
                   fz_positive(cfg->Ts_s) && fz_positive(cfg->voltage_ratio) && cfg->voltage_ratio <= 1.0f &&
                   isfinite(cfg->id_min_A) && cfg->id_min_A < 0.0f && (unsigned)cfg->method <= 2u &&
                   (unsigned)cfg->anti_windup <= 2u,
               "accepted a configuration outside the documented ranges");
    FZ_REQUIRE(isfinite(c->pi.b_e0) && fz_positive(c->pi.Ki_Ts) && isfinite(c->u_ref_per_u_dc) &&
                   c->id_min_A == cfg->id_min_A,
               "coefficients b_e0 %g Ki_Ts %g", (double)c->pi.b_e0, (double)c->pi.Ki_Ts);
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        FZ_REQUIRE(c->pi.Ki_Ka_Ts >= 0.0f && c->pi.Ki_Ka_Ts < 2.0f, "Ki Ka Ts = %g", (double)c->pi.Ki_Ka_Ts);
    } else {
        FZ_REQUIRE(c->pi.Ki_Ka_Ts == 0.0f, "Ki Ka Ts = %g without back calculation", (double)c->pi.Ki_Ka_Ts);
    }
    FZ_REQUIRE(c->clamping == (cfg->anti_windup == P2D_AW_CLAMPING), "clamping flag");
}

static bool fz_fw_init(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg)
{
    p2d_field_weakening_t pattern;
    p2d_status_t status;
    memset(fw, 0xa5, sizeof *fw);
    memcpy(&pattern, fw, sizeof pattern);
    status = p2d_field_weakening_init(fw, cfg);
    if (status != P2D_OK) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(fw, &pattern, sizeof pattern) == 0, "rejected init (status %d) wrote", (int)status);
        return false;
    }
    fz_check_accepted(cfg, &fw->coef[fw->active]);
    FZ_REQUIRE(fw->x_A == 0.0f && fw->fault_count == 0u, "init did not clear the state");
    return true;
}

static void fz_fw_set_config(p2d_field_weakening_t *fw, const p2d_field_weakening_config_t *cfg)
{
    p2d_field_weakening_t before, fresh;
    p2d_status_t status, status_init;
    memcpy(&before, fw, sizeof before);
    status_init = p2d_field_weakening_init(&fresh, cfg);
    status = p2d_field_weakening_set_config(fw, cfg);
    FZ_REQUIRE(status == status_init, "set_config status %d, init status %d", (int)status, (int)status_init);
    if (status != P2D_OK) {
        FZ_REQUIRE(memcmp(fw, &before, sizeof before) == 0, "rejected set_config (status %d) wrote", (int)status);
        return;
    }
    FZ_REQUIRE(fw->active == 1u - before.active, "active %u -> %u", before.active, fw->active);
    FZ_REQUIRE(memcmp(&fw->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0,
               "set_config wrote the coefficient set in force");
    FZ_REQUIRE(memcmp(&fw->coef[fw->active], &fresh.coef[fresh.active], sizeof fresh.coef[0]) == 0,
               "set_config and init computed different coefficients");
    fz_check_accepted(cfg, &fw->coef[fw->active]);
    FZ_REQUIRE(memcmp(&fw->config, cfg, sizeof *cfg) == 0, "config not stored");
    FZ_REQUIRE(fz_bits_equal(fw->x_A, before.x_A) && fw->fault_count == before.fault_count,
               "set_config changed the state");
}

/* Sat(v) within [id_min, 0] */
static float fz_sat(const p2d_field_weakening_coef_t *c, float v)
{
    return v > 0.0f ? 0.0f : v >= c->id_min_A ? v : c->id_min_A;
}

/* One field-weakening sample and its invariants; returns the d current command. */
static float fz_fw_sample(fz_fw_rig_t *rig, float ud, float uq, float u_dc)
{
    p2d_field_weakening_t before;
    p2d_field_weakening_output_t out;
    const p2d_field_weakening_coef_t *c;
    double x0, x1, e, g, kits, b, id, slack;
    memcpy(&before, &rig->fw, sizeof before);
    c = &before.coef[before.active];
    p2d_field_weakening_step(&rig->fw, ud, uq, u_dc, &out);
    FZ_REQUIRE(memcmp(rig->fw.coef, before.coef, sizeof before.coef) == 0 && rig->fw.active == before.active,
               "the step changed the coefficients");
    FZ_REQUIRE(isfinite(rig->fw.x_A), "state poisoned: x %g", (double)rig->fw.x_A);
    if (!isfinite(ud) || !isfinite(uq) || !isfinite(u_dc)) {
        FZ_REQUIRE(out.fault, "non-finite input ud %g uq %g u_dc %g without fault", (double)ud, (double)uq,
                   (double)u_dc);
    }
    FZ_REQUIRE(out.id_ref_A <= 0.0f && out.id_ref_A >= c->id_min_A && out.active == (out.id_ref_A < 0.0f) &&
                   out.at_id_min == (out.id_ref_A == c->id_min_A),
               "id_ref %g outside [%g, 0] or flags wrong", (double)out.id_ref_A, (double)c->id_min_A);
    if (out.fault) {
        FZ_REQUIRE(fz_bits_equal(out.id_ref_A, fz_sat(c, before.x_A)), "fault output %g is not Sat(x) = %g",
                   (double)out.id_ref_A, (double)fz_sat(c, before.x_A));
        FZ_REQUIRE(fz_bits_equal(rig->fw.x_A, before.x_A) && rig->fw.fault_count == before.fault_count + 1u,
                   "a fault changed the state or was not counted");
        return out.id_ref_A;
    }
    FZ_REQUIRE(fz_bits_equal(out.u_ref_V, u_dc > 0.0f ? c->u_ref_per_u_dc * u_dc : 0.0f), "u_ref %g for u_dc %g",
               (double)out.u_ref_V, (double)u_dc);
    FZ_REQUIRE(isfinite(out.e_V) && isfinite(out.id_unsat_A) && fz_bits_equal(out.id_ref_A, fz_sat(c, out.id_unsat_A)),
               "id_ref %g is not Sat(%g)", (double)out.id_ref_A, (double)out.id_unsat_A);
    x0 = before.x_A;
    x1 = rig->fw.x_A;
    e = out.e_V;
    g = c->pi.Ki_Ka_Ts;
    kits = c->pi.Ki_Ts;
    b = c->pi.b_e0;
    id = out.id_ref_A;
    if (rig->fw.fault_count != before.fault_count) {
        /* refused: only when a term of the update comes near the float32 range */
        FZ_REQUIRE(rig->fw.fault_count == before.fault_count + 1u && fz_bits_equal(rig->fw.x_A, before.x_A),
                   "a refused update changed the state");
        FZ_REQUIRE(fmax(fmax(fabs(x0), fabs(kits * e)), fabs(g * (id - (double)out.id_unsat_A))) > 0.25 * FLT_MAX,
                   "update refused although the new state is finite: x %g e %g", x0, e);
        return out.id_ref_A;
    }
    slack = fz_slack(fabs(x0) + fabs(kits * e) + (1.0 + g) * (fabs(id) + fabs(b * e)) + g * fabs(x0) + fabs(x1));
    if (g > 0.0) {
        double bound = (fabs(kits - g * b) * fabs(e) + g * fabs(id)) / (1.0 - fabs(1.0 - g));
        FZ_REQUIRE(fabs(x1) <= fmax(fabs(x0), bound) + slack,
                   "back calculation: |x| %.9g -> %.9g above the bound %.9g (g %g e %g id %g)", x0, x1, bound, g, e,
                   id);
    } else if (c->clamping) {
        double z = id + (kits - b) * e;
        FZ_REQUIRE(x1 <= fmax(x0, z) + slack && x1 >= fmin(x0, z) - slack,
                   "clamping: x %.9g -> %.9g passed z = %.9g (e %g id %g)", x0, x1, z, e, id);
    }
    return out.id_ref_A;
}

/* One speed sample through the field-weakening entry and its invariants; returns the applied torque. */
static float fz_speed_sample(fz_fw_rig_t *rig, fz_reader_t *r, unsigned mode, float w_ref, float w_m, float id_fw)
{
    p2d_speed_t before;
    p2d_speed_output_t out;
    const p2d_speed_coef_t *c;
    float T_app, id_bound;
    double norm;
    memcpy(&before, &rig->spd, sizeof before);
    c = &before.coef[before.active];
    if (mode == 0u) {
        p2d_speed_step_fw(&rig->spd, w_ref, w_m, id_fw, &out);
        T_app = out.T_ref_Nm;
    } else {
        p2d_speed_compute_fw(&rig->spd, w_ref, w_m, id_fw, &out);
        FZ_REQUIRE(memcmp(&rig->spd, &before, sizeof before) == 0, "compute_fw changed the controller");
        T_app = mode == 1u ? (float)(fz_unit(r) * (double)out.T_ref_Nm) : fz_float(r, (double)c->T_max_Nm, true);
        p2d_speed_update(&rig->spd, &out, T_app);
    }
    FZ_REQUIRE(isfinite(rig->spd.x_Nm) && isfinite(rig->spd.r_prev_radps) && isfinite(rig->spd.y_ff_prev_Nm),
               "speed state poisoned");
    if (!isfinite(w_ref) || !isfinite(w_m) || !isfinite(id_fw)) {
        FZ_REQUIRE(out.fault, "non-finite input w_ref %g w_m %g id_fw %g without fault", (double)w_ref, (double)w_m,
                   (double)id_fw);
    }
    if (out.fault) {
        FZ_REQUIRE(out.T_ref_Nm == 0.0f && out.id_ref_A == 0.0f && out.iq_ref_A == 0.0f && !out.saturated,
                   "fault output T %g id %g iq %g", (double)out.T_ref_Nm, (double)out.id_ref_A, (double)out.iq_ref_A);
        return 0.0f;
    }
    FZ_REQUIRE(isfinite(out.T_unsat_Nm) && isfinite(out.T_ref_Nm) && isfinite(out.id_ref_A) && isfinite(out.iq_ref_A),
               "non-finite output without fault");
    FZ_REQUIRE(fabsf(out.T_ref_Nm) <= c->T_max_Nm, "|T_ref| %g > T_max %g", (double)out.T_ref_Nm, (double)c->T_max_Nm);
    FZ_REQUIRE(out.saturated ? (fabsf(out.T_ref_Nm) < fabsf(out.T_unsat_Nm) &&
                                (double)out.T_ref_Nm * (double)out.T_unsat_Nm >= 0.0)
                             : fz_bits_equal(out.T_ref_Nm, out.T_unsat_Nm),
               "T_ref %g is not a limit of T_unsat %g (saturated %d)", (double)out.T_ref_Nm, (double)out.T_unsat_Nm,
               (int)out.saturated);
    norm = hypot((double)out.id_ref_A, (double)out.iq_ref_A);
    FZ_REQUIRE(fz_within_circle(norm, before.config.i_max_A),
               "||i_dq|| %.9g > i_max %.9g (id %g iq %g id_fw %g T %g T_max %g psi_f %g Ld %g Lq %g)", norm,
               (double)before.config.i_max_A, (double)out.id_ref_A, (double)out.iq_ref_A, (double)id_fw,
               (double)out.T_ref_Nm, (double)c->T_max_Nm, (double)before.config.psi_f_Wb, (double)before.config.Ld_H,
               (double)before.config.Lq_H);
    id_bound = id_fw < 0.0f ? (id_fw > -c->i_max_A ? id_fw : -c->i_max_A) : 0.0f;
    FZ_REQUIRE(c->salient ? out.id_ref_A <= id_bound : out.id_ref_A == id_bound,
               "id_ref %g against the bound %g (salient %d)", (double)out.id_ref_A, (double)id_bound, (int)c->salient);
    FZ_REQUIRE(fabsf(out.T_ref_Nm) < FLT_MIN || (double)out.iq_ref_A * (double)out.T_ref_Nm >= 0.0,
               "iq %g against T_ref %g", (double)out.iq_ref_A, (double)out.T_ref_Nm);
    if (out.id_ref_A == id_bound && (!c->salient || id_bound < 0.0f) &&
        !(c->salient && p2d_mtpa_id_of_iq_A(out.iq_ref_A, c->psi_f_Wb, c->dL_H) == out.id_ref_A)) {
        /*
         * on the bound (and not the MTPA vector, whose inversion is the speed controller's and
         * checked there; a vector on the MTPA trajectory whose id equals the bound, e.g. both the same
         * subnormal, is that vector), the current gives the torque: 1.5 p (psi_f + dL id) iq = T_ref (away
         * from subnormals: a subnormal T_ref, e.g. 2.8e-44 Nm, holds a few bits, and one rounding of iq
         * moves it by several %)
         */
        double k_T = 1.5 * before.config.pole_pairs * ((double)before.config.psi_f_Wb + (double)c->dL_H * id_bound);
        FZ_REQUIRE(k_T < 1e-30 || fabsf(out.T_ref_Nm) < FLT_MIN || fabs((double)out.T_ref_Nm / k_T) < 1e-30 ||
                       fabs(k_T * (double)out.iq_ref_A - (double)out.T_ref_Nm) <= 1e-5 * fabs((double)out.T_ref_Nm),
                   "the current (%g, %g) gives %g Nm, not T_ref %g (psi_f %g Ld %g Lq %g i_max %g id_fw %g)",
                   (double)out.id_ref_A, (double)out.iq_ref_A, k_T * (double)out.iq_ref_A, (double)out.T_ref_Nm,
                   (double)before.config.psi_f_Wb, (double)before.config.Ld_H, (double)before.config.Lq_H,
                   (double)before.config.i_max_A, (double)id_fw);
    }
    if (id_fw >= 0.0f && c->dL_H <= 0.0f) {
        p2d_speed_output_t plain;
        p2d_speed_compute(&before, w_ref, w_m, &plain);
        FZ_REQUIRE(fz_bits_equal(plain.T_ref_Nm, out.T_ref_Nm) && fz_bits_equal(plain.id_ref_A, out.id_ref_A) &&
                       fz_bits_equal(plain.iq_ref_A, out.iq_ref_A) && plain.saturated == out.saturated,
                   "id_fw %g >= 0: compute_fw (T %g id %g iq %g) differs from compute (T %g id %g iq %g)",
                   (double)id_fw, (double)out.T_ref_Nm, (double)out.id_ref_A, (double)out.iq_ref_A,
                   (double)plain.T_ref_Nm, (double)plain.id_ref_A, (double)plain.iq_ref_A);
    }
    rig->iq_A = out.iq_ref_A;
    return T_app;
}

/*
 * 1..2048 samples at a constant electrical speed w_e, with the steady-state voltages
 * (eq 1) of the last commands: ud = Rs id - w_e Lq iq, uq = Rs iq + w_e (Ld id + psi_f).
 */
static void fz_closed_run(fz_fw_rig_t *rig, fz_reader_t *r)
{
    uint32_t n = 1u + fz_u16(r) % 2048u;
    double w_e = fz_float(r, 2000.0, true);
    float w_ref = fz_float(r, 300.0, true), u_dc = fz_float(r, 48.0, false);
    double Rs = 0.2, Ld = 1e-3, Lq = 1e-3, psi = 0.02;
    if (rig->have_speed) {
        Ld = rig->spd.config.Ld_H;
        Lq = rig->spd.config.Lq_H;
        psi = rig->spd.config.psi_f_Wb;
    }
    for (uint32_t k = 0; k < n; ++k) {
        double ud = Rs * rig->id_A - w_e * Lq * rig->iq_A;
        double uq = Rs * rig->iq_A + w_e * (Ld * rig->id_A + psi);
        float id = fz_fw_sample(rig, (float)ud, (float)uq, u_dc);
        rig->id_A = id;
        if (rig->have_speed) {
            (void)fz_speed_sample(rig, r, 0u, w_ref, (float)(w_e / 4.0), id);
        } else {
            rig->iq_A = 0.0f;
        }
    }
}

static void fz_resets(fz_fw_rig_t *rig, fz_reader_t *r)
{
    float id = fz_float(r, 5.0, true), w_ref = fz_float(r, 100.0, true), T = fz_float(r, 0.1, true);
    p2d_field_weakening_t before;
    memcpy(&before, &rig->fw, sizeof before);
    p2d_field_weakening_reset(&rig->fw, id);
    FZ_REQUIRE(memcmp(rig->fw.coef, before.coef, sizeof before.coef) == 0, "reset changed the coefficients");
    if (isfinite(id)) {
        FZ_REQUIRE(fz_bits_equal(rig->fw.x_A, fz_sat(&before.coef[before.active], id)) &&
                       rig->fw.fault_count == before.fault_count,
                   "reset(%g): x %g", (double)id, (double)rig->fw.x_A);
    } else {
        FZ_REQUIRE(rig->fw.x_A == 0.0f && rig->fw.fault_count == before.fault_count + 1u,
                   "a refused reset(%g) must start at 0 and count one fault", (double)id);
    }
    if (rig->have_speed) p2d_speed_reset(&rig->spd, w_ref, T);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_fw_rig_t rig;
    p2d_field_weakening_config_t cfg;
    p2d_speed_config_t speed_cfg;

    FZ_REQUIRE(p2d_field_weakening_init(NULL, &cfg) == P2D_ERR_NULL &&
                   p2d_field_weakening_set_config(&rig.fw, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_fw_config(&r, &cfg);
    fz_speed_config(&r, &speed_cfg);
    if (!fz_fw_init(&rig.fw, &cfg)) return 0;
    rig.have_speed = p2d_speed_init(&rig.spd, &speed_cfg) == P2D_OK;
    rig.id_A = 0.0f;
    rig.iq_A = 0.0f;
    while (!fz_done(&r)) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 3:
            if (rig.have_speed) {
                float w_ref = fz_float(&r, 100.0, true), w_m = fz_float(&r, 100.0, true);
                float id_fw = fz_float(&r, 5.0, true);
                (void)fz_speed_sample(&rig, &r, (op >> 3) % 3u, w_ref, w_m, id_fw);
            }
            break;
        case 4: fz_closed_run(&rig, &r); break;
        case 5:
            fz_fw_config_mutated(&r, &rig.fw.config, &cfg);
            fz_fw_set_config(&rig.fw, &cfg);
            break;
        case 6:
            fz_fw_config(&r, &cfg);
            fz_fw_set_config(&rig.fw, &cfg);
            break;
        case 7: fz_resets(&rig, &r); break;
        default: {
            float ud = fz_float(&r, 20.0, true), uq = fz_float(&r, 20.0, true), u_dc = fz_float(&r, 48.0, true);
            (void)fz_fw_sample(&rig, ud, uq, u_dc);
            break;
        }
        }
    }
    return 0;
}
