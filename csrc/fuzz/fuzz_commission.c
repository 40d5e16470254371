/*
 * libFuzzer target: the self-commissioning routine (pmsm2dof/commission.h),
 * built with -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all.
 *
 * The input decodes (fuzz_common.h) to a configuration, valid or not, and
 * then to operations until the bytes run out:
 *   op % 8 in 0..3  one sample: measured currents and DC link drawn at random
 *   op % 8 == 4     a closed-loop run of 1..16384 samples against a motor: the
 *                   dq model of eq 1 in the rotor frame with the rotor's angle
 *                   and mechanics (forward Euler in double, 8 steps per
 *                   sample), the stationary-frame voltage held over the
 *                   period (after 0 or 1 period of delay), parameters within
 *                   a factor 4 of a small salient servo, a load torque, and
 *                   current sensing of either sign
 *   op % 8 == 5     p2d_commission_init with a fresh configuration
 *   op % 8 == 6     p2d_commission_init with the configuration in force (a restart)
 *   op % 8 == 7     one sample with a NaN or infinite input
 *
 * Invariants, checked after every call (abort on violation):
 *  - init accepts or rejects; a rejected call leaves the routine
 *    bit-identical and names a commissioning parameter with its range; an
 *    accepted configuration is inside the documented ranges.
 *  - a non-finite input gives the fault flag, a zero voltage, and leaves the
 *    routine bit-identical but for fault_count + 1.
 *  - otherwise the command is finite, ||u_dq|| <= max(u_dc, 0) / sqrt(3) up to
 *    float32 rounding, the angle is in [0, 2 pi), the frame speed in
 *    [0, w_e_spin_radps].
 *  - the phase never goes back; DONE and FAILED keep the routine as it is and
 *    command a zero voltage; FAILED names a reason and the phase that failed,
 *    any other phase none; DONE holds finite, positive Rs, Ld, Lq, psi_f.
 *  - a current beyond i_trip_A in a running phase ends the routine with
 *    P2D_REASON_OVERCURRENT.
 *  - a routine that ran from its init to DONE within one closed-loop run
 *    (one motor, nothing else in between) measured that motor within the
 *    targets of the identification: Rs and Lq within 5 %, Ld within 10 %,
 *    psi_f within 2 % (the forward-Euler motor is the truth to a few 0.1 %).
 *    The routine must fail rather than end with a wrong estimate.
 */
#include "fuzz_common.h"

#include "pmsm2dof/commission.h"

#define FZ_INV_SQRT3 0.57735026918962576
#define FZ_TWO_PI 6.283185307179586

/* The routine and the motor of one fuzz input. */
typedef struct {
    p2d_commission_t c;          /* routine under test */
    bool started;                /* an init was accepted */
    bool fresh;                  /* nothing but the init happened since the init */
    double id_A, iq_A;           /* rotor-frame currents of the motor [A] */
    double w_m_radps;            /* mechanical speed [rad/s] */
    double theta_rad;            /* rotor electrical angle [rad] */
    double ua_next_V, ub_next_V; /* command waiting for the next period (delay 1) [V] */
} fz_rig_t;

/*
 * A configuration around a small servo commissioned quickly: Ts = 100 us,
 * tau_i = 1 ms, 2 A test, 1.5 A spin, 4 A trip, standstill phases of 30
 * tau_i or so, the flux test at w_e_spin Ts = 0.01 after a ramp of 3000 Ts,
 * averaged over 150 tau_i (a frictionless rotor swings less than 2 % then).
 */
static void fz_config(fz_reader_t *r, p2d_commission_config_t *cfg)
{
    double Ts, tau;
    memset(cfg, 0, sizeof *cfg);
    cfg->Ts_s = fz_float(r, 1e-4, false);
    Ts = isfinite(cfg->Ts_s) && cfg->Ts_s > 0.0f ? (double)cfg->Ts_s : 1e-4;
    cfg->tau_i_s = fz_float(r, 10.5 * Ts, false);
    tau = isfinite(cfg->tau_i_s) && cfg->tau_i_s > 0.0f ? (double)cfg->tau_i_s : 10.5 * Ts;
    cfg->i_test_A = fz_float(r, 2.0, false);
    cfg->i_spin_A = fz_float(r, 1.5, false);
    cfg->i_trip_A = fz_float(r, 4.0, false);
    cfg->t_align_s = fz_float(r, 30.0 * tau, false);
    cfg->t_level_s = fz_float(r, 30.0 * tau, false);
    cfg->t_inductance_s = fz_float(r, 128.0 * Ts, false);
    cfg->t_ramp_s = fz_float(r, 3000.0 * Ts, false);
    cfg->t_spin_s = fz_float(r, 300.0 * tau, false);
    cfg->w_e_spin_radps = fz_float(r, 0.01 / Ts, false);
    cfg->voltage_delay_samples = fz_enum(r, 2u);
}

static bool fz_positive(float x) { return isfinite(x) && x > 0.0f; }

static bool fz_is_commissioning_status(p2d_status_t s)
{
    return s == P2D_ERR_TS || s == P2D_ERR_TAU_I || s == P2D_ERR_I_TEST || s == P2D_ERR_I_SPIN || s == P2D_ERR_I_TRIP ||
           s == P2D_ERR_T_ALIGN || s == P2D_ERR_T_LEVEL || s == P2D_ERR_T_INDUCTANCE || s == P2D_ERR_T_RAMP ||
           s == P2D_ERR_T_SPIN || s == P2D_ERR_W_E_SPIN || s == P2D_ERR_VOLTAGE_DELAY;
}

/* The documented ranges, with half a sample of slack on the lengths (they are whole samples). */
static void fz_check_accepted(const p2d_commission_config_t *cfg)
{
    double Ts = cfg->Ts_s, tau = cfg->tau_i_s;
    double i_big = fmax((double)cfg->i_test_A, (double)cfg->i_spin_A);
    FZ_REQUIRE(fz_positive(cfg->Ts_s) && isfinite(cfg->tau_i_s) && tau >= 10.0 * Ts * (1.0 - 1e-6),
               "accepted Ts %g tau_i %g", Ts, tau);
    FZ_REQUIRE(fz_positive(cfg->i_test_A) && fz_positive(cfg->i_spin_A) && (double)cfg->i_trip_A < 1.9e19 &&
                   (double)cfg->i_trip_A > 1e-19 && (double)cfg->i_trip_A >= 1.5 * i_big * (1.0 - 1e-6),
               "accepted i_test %g i_spin %g i_trip %g", (double)cfg->i_test_A, (double)cfg->i_spin_A,
               (double)cfg->i_trip_A);
    FZ_REQUIRE((double)cfg->t_align_s >= 20.0 * tau - 0.5 * Ts - 1e-5 * tau &&
                   (double)cfg->t_level_s >= 20.0 * tau - 0.5 * Ts - 1e-5 * tau &&
                   (double)cfg->t_spin_s >= 20.0 * tau - 0.5 * Ts - 1e-5 * tau &&
                   (double)cfg->t_inductance_s >= 63.5 * Ts * (1.0 - 1e-5) &&
                   (double)cfg->t_ramp_s >= 99.5 * Ts * (1.0 - 1e-5),
               "accepted phase lengths align %g level %g inductance %g ramp %g spin %g (Ts %g tau %g)",
               (double)cfg->t_align_s, (double)cfg->t_level_s, (double)cfg->t_inductance_s, (double)cfg->t_ramp_s,
               (double)cfg->t_spin_s, Ts, tau);
    FZ_REQUIRE(fz_positive(cfg->w_e_spin_radps) && (double)cfg->w_e_spin_radps * Ts <= 0.1 * (1.0 + 1e-6),
               "accepted w_e_spin %g", (double)cfg->w_e_spin_radps);
    FZ_REQUIRE(cfg->voltage_delay_samples <= 1u, "accepted voltage_delay_samples %u", cfg->voltage_delay_samples);
}

static void fz_init(fz_rig_t *rig, const p2d_commission_config_t *cfg)
{
    p2d_commission_t before;
    p2d_status_t status;
    memcpy(&before, &rig->c, sizeof before);
    status = p2d_commission_init(&rig->c, cfg);
    if (status != P2D_OK) {
        FZ_REQUIRE(fz_is_commissioning_status(status), "status %d names no commissioning parameter", (int)status);
        FZ_REQUIRE(p2d_status_param(status)[0] != '\0' && p2d_status_range(status)[0] != '\0',
                   "status %d has no parameter name or range", (int)status);
        FZ_REQUIRE(memcmp(&before, &rig->c, sizeof before) == 0, "a rejected init changed the routine");
        return;
    }
    fz_check_accepted(cfg);
    FZ_REQUIRE(rig->c.phase == P2D_PHASE_PROBE && rig->c.reason == P2D_REASON_NONE && rig->c.fault_count == 0u,
               "init did not start at PROBE");
    rig->started = true;
    rig->fresh = true;
}

/* One step with the invariants; returns the command through out. */
static void fz_step(fz_rig_t *rig, float id_A, float iq_A, float u_dc_V, p2d_commission_output_t *out)
{
    p2d_commission_t before;
    const bool finite = isfinite(id_A) && isfinite(iq_A) && isfinite(u_dc_V);
    double u_max = fmax((double)u_dc_V, 0.0) * FZ_INV_SQRT3, i2 = (double)id_A * id_A + (double)iq_A * iq_A;
    double trip2 = (double)rig->c.config.i_trip_A * rig->c.config.i_trip_A;
    memcpy(&before, &rig->c, sizeof before);
    p2d_commission_step(&rig->c, id_A, iq_A, u_dc_V, out);
    if (!finite) {
        p2d_commission_t expected;
        memcpy(&expected, &before, sizeof expected);
        expected.fault_count++;
        FZ_REQUIRE(out->fault && out->ud_V == 0.0f && out->uq_V == 0.0f, "non-finite input without the fault output");
        FZ_REQUIRE(memcmp(&expected, &rig->c, sizeof expected) == 0, "a non-finite input changed the routine");
        return;
    }
    FZ_REQUIRE(isfinite(out->ud_V) && isfinite(out->uq_V), "non-finite command (%g, %g)", (double)out->ud_V,
               (double)out->uq_V);
    FZ_REQUIRE(fz_within_circle(hypot((double)out->ud_V, (double)out->uq_V), (float)u_max),
               "||u_dq|| = %.9g > u_dc/sqrt(3) = %.9g in %s", hypot((double)out->ud_V, (double)out->uq_V), u_max,
               p2d_commission_phase_name(out->phase));
    FZ_REQUIRE(out->theta_e_rad >= 0.0f && out->theta_e_rad < (float)FZ_TWO_PI && rig->c.theta_e_rad >= 0.0f &&
                   rig->c.theta_e_rad < (float)FZ_TWO_PI,
               "angle %.9g, next %.9g outside [0, 2 pi)", (double)out->theta_e_rad, (double)rig->c.theta_e_rad);
    FZ_REQUIRE(out->w_e_radps >= 0.0f && out->w_e_radps <= rig->c.config.w_e_spin_radps, "frame speed %g",
               (double)out->w_e_radps);
    FZ_REQUIRE(rig->c.phase >= before.phase, "phase went back from %s to %s", p2d_commission_phase_name(before.phase),
               p2d_commission_phase_name(rig->c.phase));
    if (before.phase >= P2D_PHASE_DONE) {
        FZ_REQUIRE(memcmp(&before, &rig->c, sizeof before) == 0, "an ended routine changed");
    }
    if (out->phase >= P2D_PHASE_DONE) {
        FZ_REQUIRE(out->ud_V == 0.0f && out->uq_V == 0.0f, "%s commands (%g, %g)",
                   p2d_commission_phase_name(out->phase), (double)out->ud_V, (double)out->uq_V);
    }
    if (rig->c.phase == P2D_PHASE_FAILED) {
        FZ_REQUIRE(rig->c.reason > P2D_REASON_NONE && rig->c.reason < P2D_REASON_COUNT &&
                       rig->c.failed_phase < P2D_PHASE_DONE && p2d_commission_reason_text(rig->c.reason)[0] != '\0',
                   "FAILED with reason %d in phase %d", (int)rig->c.reason, (int)rig->c.failed_phase);
    } else {
        FZ_REQUIRE(rig->c.reason == P2D_REASON_NONE, "reason %d without a failure", (int)rig->c.reason);
    }
    if (rig->c.phase == P2D_PHASE_DONE) {
        FZ_REQUIRE(fz_positive(rig->c.Rs_ohm) && fz_positive(rig->c.Ld_H) && fz_positive(rig->c.Lq_H) &&
                       fz_positive(rig->c.psi_f_Wb),
                   "DONE with Rs %g Ld %g Lq %g psi_f %g", (double)rig->c.Rs_ohm, (double)rig->c.Ld_H,
                   (double)rig->c.Lq_H, (double)rig->c.psi_f_Wb);
    }
    if (before.phase < P2D_PHASE_DONE && i2 > trip2 * (1.0 + 1e-5)) {
        FZ_REQUIRE(rig->c.phase == P2D_PHASE_FAILED && rig->c.reason == P2D_REASON_OVERCURRENT,
                   "||i|| = %g above i_trip %g did not end the routine", sqrt(i2), sqrt(trip2));
    }
}

static float fz_nonfinite(fz_reader_t *r)
{
    static const float values[4] = {NAN, -NAN, INFINITY, -INFINITY};
    return values[fz_u8(r) % 4u];
}

/*
 * Closed loop against a motor within a factor 4 of Rs = 0.8 ohm, Ld = 4 mH,
 * Lq = 1..3 Ld, psi_f = 0.05 Wb, J = 2e-4 kg m^2, p = 4, with a load torque
 * up to 0.1 Nm (0.17 kt i_test):
 *   Ld did/dt = ud - Rs id + w_e Lq iq,  Lq diq/dt = uq - Rs iq - w_e (Ld id + psi_f),
 *   J dw_m/dt = 1.5 p (psi_f iq + (Ld - Lq) id iq) - T_load,  dtheta/dt = p w_m.
 */
static void fz_closed_loop(fz_rig_t *rig, fz_reader_t *r)
{
    const uint32_t n = 1u + fz_u16(r) % 16384u;
    const double R = 0.8 * pow(4.0, 2.0 * fz_unit(r) - 1.0), Ld = 4e-3 * pow(4.0, 2.0 * fz_unit(r) - 1.0);
    const double Lq = Ld * (1.0 + 2.0 * fz_unit(r)), psi_f = 0.05 * pow(4.0, 2.0 * fz_unit(r) - 1.0);
    const double J = 2e-4 * pow(4.0, 2.0 * fz_unit(r) - 1.0), T_load = 0.1 * fz_unit(r);
    const double u_dc = 48.0 * pow(4.0, 2.0 * fz_unit(r) - 1.0);
    const uint8_t flags = fz_u8(r);
    const bool inverted = (flags & 1u) != 0u, delayed = (flags & 2u) != 0u;
    const double Ts = fmin(fmax((double)rig->c.config.Ts_s, 1e-6), 1e-3), h = Ts / 8.0;
    const int p = 4;
    /* the whole run against this motor, from a motor at rest: its estimates must be right */
    const bool whole_run = rig->fresh && (double)rig->c.config.Ts_s == Ts;
    if (!rig->started) return;
    rig->fresh = false;
    if (whole_run) rig->id_A = rig->iq_A = rig->w_m_radps = rig->ua_next_V = rig->ub_next_V = 0.0;
    for (uint32_t k = 0; k < n; ++k) {
        p2d_commission_output_t out;
        double th = rig->c.theta_e_rad, cr = cos(rig->theta_rad), sr = sin(rig->theta_rad);
        double ia = cr * rig->id_A - sr * rig->iq_A, ib = sr * rig->id_A + cr * rig->iq_A;
        double s = inverted ? -1.0 : 1.0, ua, ub;
        fz_step(rig, (float)(s * (cos(th) * ia + sin(th) * ib)), (float)(s * (-sin(th) * ia + cos(th) * ib)),
                (float)u_dc, &out);
        ua = cos((double)out.theta_e_rad) * out.ud_V - sin((double)out.theta_e_rad) * out.uq_V;
        ub = sin((double)out.theta_e_rad) * out.ud_V + cos((double)out.theta_e_rad) * out.uq_V;
        if (delayed) {
            double ua_now = rig->ua_next_V, ub_now = rig->ub_next_V;
            rig->ua_next_V = ua;
            rig->ub_next_V = ub;
            ua = ua_now;
            ub = ub_now;
        }
        for (int j = 0; j < 8; ++j) {
            double c = cos(rig->theta_rad), sn = sin(rig->theta_rad);
            double ud = c * ua + sn * ub, uq = -sn * ua + c * ub, w_e = p * rig->w_m_radps;
            double id = rig->id_A, iq = rig->iq_A;
            double Te = 1.5 * p * (psi_f * iq + (Ld - Lq) * id * iq);
            rig->id_A = id + h / Ld * (ud - R * id + w_e * Lq * iq);
            rig->iq_A = iq + h / Lq * (uq - R * iq - w_e * (Ld * id + psi_f));
            rig->w_m_radps += h / J * (Te - T_load);
            rig->theta_rad = fmod(rig->theta_rad + h * w_e, FZ_TWO_PI);
        }
        if (!isfinite(rig->id_A) || !isfinite(rig->iq_A) || !isfinite(rig->w_m_radps) || !isfinite(rig->theta_rad) ||
            fabs(rig->id_A) + fabs(rig->iq_A) > 1e6) {
            /* the explicit integration of an extreme motor diverged: a new motor at rest */
            rig->id_A = rig->iq_A = rig->w_m_radps = rig->theta_rad = 0.0;
            return;
        }
        if (whole_run && rig->c.phase == P2D_PHASE_DONE) {
            /* open (RELIABILITY.md): the q injection at w0 = pi / (2 Ts) swings a light rotor, whose inertia adds
               -1.5 p^2 psi_f^2 / (J w0) to w0 Lq: Lq is low by up to that share, on top of the target */
            const double w0 = 0.25 * FZ_TWO_PI / Ts, q_motion = 1.5 * p * p * psi_f * psi_f / (J * w0 * w0 * Lq);
            FZ_REQUIRE(fabs(rig->c.Rs_ohm / R - 1.0) <= 0.05 && fabs(rig->c.Ld_H / Ld - 1.0) <= 0.1 &&
                           fabs(rig->c.Lq_H / Lq - 1.0) <= 0.05 + q_motion &&
                           fabs(rig->c.psi_f_Wb / psi_f - 1.0) <= 0.02,
                       "DONE with Rs %g Ld %g Lq %g psi_f %g for a motor of Rs %g Ld %g Lq %g psi_f %g (J %g, "
                       "load %g Nm, u_dc %g V)",
                       (double)rig->c.Rs_ohm, (double)rig->c.Ld_H, (double)rig->c.Lq_H, (double)rig->c.psi_f_Wb, R, Ld,
                       Lq, psi_f, J, T_load, u_dc);
            return;
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_rig_t rig;
    p2d_commission_config_t cfg;
    p2d_commission_output_t out;

    memset(&rig, 0, sizeof rig);
    FZ_REQUIRE(p2d_commission_init(NULL, &cfg) == P2D_ERR_NULL && p2d_commission_init(&rig.c, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    FZ_REQUIRE(strcmp(p2d_commission_phase_name((p2d_commission_phase_t)fz_u8(&r)), "") != 0 &&
                   p2d_commission_reason_text((p2d_commission_reason_t)fz_u8(&r)) != NULL,
               "a name or text is missing");
    fz_config(&r, &cfg);
    fz_init(&rig, &cfg);
    while (!fz_done(&r) && rig.started) {
        uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 4: fz_closed_loop(&rig, &r); break;
        case 5:
            fz_config(&r, &cfg);
            fz_init(&rig, &cfg);
            break;
        case 6: fz_init(&rig, &rig.c.config); break;
        case 7: {
            float bad = fz_nonfinite(&r);
            uint8_t which = fz_u8(&r) % 3u;
            fz_step(&rig, which == 0u ? bad : 1.0f, which == 1u ? bad : 0.5f, which == 2u ? bad : 48.0f, &out);
            break;
        }
        default: {
            float id = fz_float(&r, 2.0, true), iq = fz_float(&r, 2.0, true), u_dc = fz_float(&r, 48.0, false);
            fz_step(&rig, id, iq, u_dc, &out);
            rig.fresh = false;
            break;
        }
        }
    }
    return 0;
}
