/*
 * Cost probes of the controllers on the Cortex-M4F, read by
 * benchmarks/footprint.py:
 *
 * - the size of every controller struct, as the target compiler lays it out;
 * - one p2d_speed_step / p2d_current_step (and p2d_encoder_step,
 *   p2d_field_weakening_step, p2d_speed_step_fw, p2d_inertia_step) per configuration
 *   and operating point, each right after a call of p2d_cost_mark(), so that an instruction
 *   trace of QEMU (-singlestep -d exec,nochain) can count the instructions
 *   executed from the entry of that step to its return;
 * - the stack that step used, by painting the free stack below SP with a
 *   pattern before the call and finding the lowest word overwritten.
 *
 * Output lines (semihosting):
 *   sizeof <type> <bytes>
 *   probe <index> <controller> <method> <anti_windup> <feedforward|coupling> <motor> <point> stack <bytes>
 * (encoder: probe <index> encoder - - <estimator> <lowpass|no_lowpass> <point> stack <bytes>;
 * controller speed_fw is p2d_speed_step_fw)
 *   probe <index> inertia <speed input> <point> stack <bytes>
 *   filter_probe <index> <speed|filter> <sections> <motor> <point> stack <bytes>
 * The index counts the calls of p2d_cost_mark() in order. A filter_probe is a
 * speed step with torque filters (Tustin, back calculation, lowpass
 * feedforward) or one p2d_filter_step; its sections are notch, lowpass or
 * notch+lowpass.
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "cost_probe.h"
#include "pmsm2dof/current.h"
#include "pmsm2dof/encoder.h"
#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/filter.h"
#include "pmsm2dof/inertia.h"
#include "pmsm2dof/speed.h"
#include "semihost.h"

#define P2D_WARMUP_STEPS 4u /* steps before the probe, so the state is not all zero */

static p2d_line_t line;
static uint32_t probe_index;

/* Start the line of the next probe; its description follows. */
static void probe_begin(const char *controller)
{
    p2d_line_text(&line, "probe ");
    p2d_line_hex(&line, probe_index++);
    p2d_line_text(&line, controller);
}

/* End the line of a probe with the stack it used. */
static void probe_end(uint32_t stack_bytes)
{
    p2d_line_text(&line, " stack ");
    p2d_line_hex(&line, stack_bytes);
    p2d_line_flush(&line);
}

static const char *const METHOD[] = {"forward_euler", "backward_euler", "tustin"};
static const char *const ANTI_WINDUP[] = {"none", "back_calculation", "clamping"};
static const char *const FEEDFORWARD[] = {"none", "lowpass", "no_tau", "full"};

/*
 * The drive of the paper's section 4 (J = 0.4 kg m^2, tau_i = 0.05 s,
 * i_max = 7.6 A, alpha = 0.5 rad/s), with an assumed magnet flux and pole
 * count, speed loop at 1 kHz.
 */
static p2d_speed_config_t speed_config(p2d_method_t method, p2d_anti_windup_t aw, p2d_feedforward_t ff, bool salient)
{
    p2d_speed_config_t cfg;
    cfg.J_kgm2 = 0.4f;
    cfg.alpha_radps = 0.5f;
    cfg.zeta = 0.2887f;
    cfg.m = ff == P2D_FF_NO_TAU || ff == P2D_FF_FULL ? 1.5f : 1.0f;
    cfg.tau_i_s = 0.05f;
    cfg.Ka = p2d_speed_Ka_default(cfg.J_kgm2, cfg.alpha_radps);
    cfg.Ts_s = 1e-3f;
    cfg.i_max_A = 7.6f;
    cfg.psi_f_Wb = 0.35f;
    cfg.Ld_H = salient ? 8e-3f : 12e-3f;
    cfg.Lq_H = 12e-3f;
    cfg.pole_pairs = 4u;
    cfg.method = method;
    cfg.feedforward = ff;
    cfg.anti_windup = aw;
    return cfg;
}

/* One speed probe: unsaturated (small error) or saturated (large error). */
static void probe_speed(p2d_method_t method, p2d_anti_windup_t aw, p2d_feedforward_t ff, bool salient, bool saturate)
{
    p2d_speed_config_t cfg = speed_config(method, aw, ff, salient);
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    float w_ref = saturate ? 100.0f : 10.0f;
    float w_m = saturate ? 0.0f : 9.9f;
    uint32_t sp, stack_bytes;

    if (p2d_speed_init(&ctl, &cfg) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_reset(&ctl, w_ref, 0.0f);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_speed_step(&ctl, w_ref, w_m, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_step(&ctl, w_ref, w_m, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate || out.fault) p2d_semihost_exit(false);

    probe_begin("speed ");
    p2d_line_text(&line, METHOD[method]);
    p2d_line_text(&line, " ");
    p2d_line_text(&line, ANTI_WINDUP[aw]);
    p2d_line_text(&line, " ");
    p2d_line_text(&line, FEEDFORWARD[ff]);
    p2d_line_text(&line, salient ? " salient" : " surface");
    p2d_line_text(&line, saturate ? " saturated" : " unsaturated");
    probe_end(stack_bytes);
}

static const char *const SECTIONS[] = {"none", "notch", "lowpass", "notch+lowpass"};

/* Torque filters for a 40 Hz resonance at the speed loop's 1 kHz: bit 0 the notch, bit 1 the low-pass. */
static p2d_filter_config_t torque_filter(uint32_t sections)
{
    p2d_filter_config_t f;
    f.notch_freq_Hz = (sections & 1u) ? 40.0f : 0.0f;
    f.notch_width_Hz = 15.0f;
    f.notch_depth = 0.05f;
    f.lowpass_freq_Hz = (sections & 2u) ? 200.0f : 0.0f;
    f.lowpass_zeta = 0.70710678f;
    return f;
}

/* End the line of a filter probe. */
static void filter_probe_line(const char *controller, uint32_t sections, const char *motor, const char *point,
                              uint32_t stack_bytes)
{
    p2d_line_text(&line, "filter_probe ");
    p2d_line_hex(&line, probe_index++);
    p2d_line_text(&line, controller);
    p2d_line_text(&line, " ");
    p2d_line_text(&line, SECTIONS[sections]);
    p2d_line_text(&line, " ");
    p2d_line_text(&line, motor);
    p2d_line_text(&line, " ");
    p2d_line_text(&line, point);
    probe_end(stack_bytes);
}

/* One speed probe with torque filters (Tustin, back calculation, lowpass feedforward). */
static void probe_speed_filtered(uint32_t sections, bool salient, bool saturate)
{
    p2d_speed_config_t cfg = speed_config(P2D_TUSTIN, P2D_AW_BACK_CALCULATION, P2D_FF_LOWPASS, salient);
    p2d_filter_config_t f = torque_filter(sections);
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    /* deep into the limit: the filters' step response dips below it at 100 rad/s */
    float w_ref = saturate ? 1000.0f : 10.0f;
    float w_m = saturate ? 0.0f : 9.9f;
    uint32_t sp, stack_bytes;

    if (p2d_speed_init(&ctl, &cfg) != P2D_OK || p2d_speed_set_filter(&ctl, &f) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_reset(&ctl, w_ref, 0.0f);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_speed_step(&ctl, w_ref, w_m, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_step(&ctl, w_ref, w_m, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate || out.fault) p2d_semihost_exit(false);
    filter_probe_line("speed", sections, salient ? "salient" : "surface", saturate ? "saturated" : "unsaturated",
                      stack_bytes);
}

/* One p2d_filter_step of the same filters on a signal. */
static void probe_filter(uint32_t sections)
{
    p2d_filter_config_t f = torque_filter(sections);
    p2d_filter_t flt;
    p2d_filter_output_t out;
    uint32_t sp, stack_bytes;

    if (p2d_filter_init(&flt, &f, 1e-3f) != P2D_OK) p2d_semihost_exit(false);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_filter_step(&flt, (float)k, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_filter_step(&flt, 1.5f, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.fault) p2d_semihost_exit(false);
    filter_probe_line("filter", sections, "-", "step", stack_bytes);
}

/* One current probe, 10 kHz loop of a small drive, unsaturated or saturated voltage. */
static void probe_current(p2d_anti_windup_t aw, bool decouple, bool saturate)
{
    p2d_current_config_t cfg;
    p2d_current_t ctl;
    p2d_current_output_t out;
    float iq_ref = saturate ? 7.6f : 2.0f;
    float u_dc = saturate ? 24.0f : 300.0f;
    uint32_t sp, stack_bytes;

    cfg.Rs_ohm = 0.5f;
    cfg.Ld_H = 8e-3f;
    cfg.Lq_H = 12e-3f;
    cfg.psi_f_Wb = 0.35f;
    cfg.tau_i_s = 1e-3f;
    cfg.Ts_s = 1e-4f;
    cfg.method = P2D_TUSTIN;
    cfg.anti_windup = aw;
    cfg.decouple = decouple;
    if (p2d_current_init(&ctl, &cfg) != P2D_OK) p2d_semihost_exit(false);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_current_step(&ctl, 0.0f, iq_ref, 0.0f, 0.5f, 200.0f, u_dc, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_current_step(&ctl, 0.0f, iq_ref, 0.0f, 0.5f, 200.0f, u_dc, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate || out.fault) p2d_semihost_exit(false);

    probe_begin("current tustin ");
    p2d_line_text(&line, ANTI_WINDUP[aw]);
    p2d_line_text(&line, decouple ? " decoupled" : " coupled");
    p2d_line_text(&line, " surface");
    p2d_line_text(&line, saturate ? " saturated" : " unsaturated");
    probe_end(stack_bytes);
}

/*
 * One speed probe through the field-weakening entry, with the d current id_fw_A of a
 * field weakening at work: unsaturated (small error) or saturated at the reduced limit.
 */
static void probe_speed_fw(bool salient, bool saturate)
{
    p2d_speed_config_t cfg = speed_config(P2D_TUSTIN, P2D_AW_BACK_CALCULATION, P2D_FF_LOWPASS, salient);
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    float w_ref = saturate ? 100.0f : 10.0f;
    float w_m = saturate ? 0.0f : 9.9f;
    float id_fw = -4.0f;
    uint32_t sp, stack_bytes;

    if (p2d_speed_init(&ctl, &cfg) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_reset(&ctl, w_ref, 0.0f);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_speed_step_fw(&ctl, w_ref, w_m, id_fw, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_step_fw(&ctl, w_ref, w_m, id_fw, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate || out.fault || out.id_ref_A > id_fw) p2d_semihost_exit(false);

    probe_begin("speed_fw tustin back_calculation lowpass");
    p2d_line_text(&line, salient ? " salient" : " surface");
    p2d_line_text(&line, saturate ? " saturated" : " unsaturated");
    probe_end(stack_bytes);
}

/* One encoder probe: a 10000-count encoder on a 16-bit timer read at 1 kHz, turning forward. */
static void probe_encoder(p2d_estimator_t estimator, bool lowpass)
{
    p2d_encoder_config_t cfg;
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    uint32_t count = 65000u, sp, stack_bytes;

    cfg.counts_per_rev = 10000u;
    cfg.counter_bits = 16u;
    cfg.Ts_s = 1e-3f;
    cfg.estimator = estimator;
    cfg.bandwidth_radps = 200.0f;
    cfg.lowpass_radps = lowpass ? 300.0f : 0.0f;
    if (p2d_encoder_init(&enc, &cfg) != P2D_OK) p2d_semihost_exit(false);
    p2d_encoder_reset(&enc, count, 0.0f);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        count += 159u;
        p2d_encoder_step(&enc, count, &out);
    }
    count += 160u; /* across the wrap of the 16-bit timer */
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_encoder_step(&enc, count, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.fault || out.dn_counts != 160) p2d_semihost_exit(false);

    probe_begin("encoder - - ");
    p2d_line_text(&line, estimator == P2D_ESTIMATOR_PLL ? "pll" : "difference");
    p2d_line_text(&line, lowpass ? " lowpass" : " no_lowpass");
    p2d_line_text(&line, " forward");
    probe_end(stack_bytes);
}

/*
 * One field-weakening probe at 10 kHz on a 48 V link: below base speed (off), weakening,
 * or at id_min (the voltage demand beyond what id_min can take away).
 */
static void probe_field_weakening(p2d_anti_windup_t aw, float u_norm_V, bool active, bool at_id_min, const char *point)
{
    p2d_field_weakening_config_t cfg;
    p2d_field_weakening_t fw;
    p2d_field_weakening_output_t out;
    uint32_t sp, stack_bytes;

    cfg.Kp_A_per_V = 0.02f;
    cfg.Ki_A_per_Vs = 100.0f;
    cfg.Ka_V_per_A = 50.0f;
    cfg.Ts_s = 1e-4f;
    cfg.voltage_ratio = 0.95f;
    cfg.id_min_A = -0.5f;
    cfg.method = P2D_TUSTIN;
    cfg.anti_windup = aw;
    if (p2d_field_weakening_init(&fw, &cfg) != P2D_OK) p2d_semihost_exit(false);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) {
        p2d_field_weakening_step(&fw, 0.6f * u_norm_V, 0.8f * u_norm_V, 48.0f, &out);
    }
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_field_weakening_step(&fw, 0.6f * u_norm_V, 0.8f * u_norm_V, 48.0f, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.fault || out.active != active || out.at_id_min != at_id_min) p2d_semihost_exit(false);

    probe_begin("field_weakening tustin ");
    p2d_line_text(&line, ANTI_WINDUP[aw]);
    p2d_line_text(&line, " - - ");
    p2d_line_text(&line, point);
    probe_end(stack_bytes);
}

/*
 * One estimator probe on a servo at 1 kHz (J = 0.01 kg m^2, 2 Nm), at a point:
 *   start      the first sample (the prefilter starts)
 *   prior      the first update, J still at its prior variance (the time update scales it back onto the prior)
 *   update     an update 200 samples into an accelerating run (forgetting)
 *   fault      a NaN speed
 */
static void probe_inertia(bool period_mean, const char *point)
{
    p2d_inertia_config_t cfg;
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    uint32_t sp, stack_bytes, warmup = 0u;
    float w = 0.0f, T = 0.5f;

    cfg.Ts_s = 1e-3f;
    cfg.J0_kgm2 = 0.02f;
    cfg.J_min_kgm2 = 0.002f;
    cfg.J_max_kgm2 = 0.2f;
    cfg.B_max_Nms = 0.01f;
    cfg.T_load_max_Nm = 2.0f;
    cfg.sigma_T_Nm = 0.05f;
    cfg.J_memory_s = 10.0f;
    cfg.load_memory_s = 0.5f;
    cfg.w_f_radps = 20.0f;
    cfg.J_rel_sd_max = 0.05f;
    cfg.speed_is_period_mean = period_mean;
    if (p2d_inertia_init(&est, &cfg) != P2D_OK) p2d_semihost_exit(false);
    if (point[0] == 'p') warmup = 1u;
    if (point[0] == 'u' || point[0] == 'f') warmup = 200u;
    for (uint32_t k = 0u; k < warmup; ++k) {
        /* a torque square wave on J = 0.01 kg m^2 */
        T = (k / 50u) % 2u ? -0.5f : 1.5f;
        p2d_inertia_step(&est, w, T, &out);
        w += 1e-3f / 0.01f * (T - 0.2f);
    }
    if (point[0] == 'f') w = NAN;
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_inertia_step(&est, w, T, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.fault != (point[0] == 'f') || out.updated != (point[0] == 'p' || point[0] == 'u')) {
        p2d_semihost_exit(false);
    }

    probe_begin("inertia ");
    p2d_line_text(&line, period_mean ? "period_mean " : "sampled ");
    p2d_line_text(&line, point);
    probe_end(stack_bytes);
}

int main(void)
{
    p2d_cost_sizeof(&line, "p2d_speed_t", sizeof(p2d_speed_t));
    p2d_cost_sizeof(&line, "p2d_speed_coef_t", sizeof(p2d_speed_coef_t));
    p2d_cost_sizeof(&line, "p2d_speed_config_t", sizeof(p2d_speed_config_t));
    p2d_cost_sizeof(&line, "p2d_speed_output_t", sizeof(p2d_speed_output_t));
    p2d_cost_sizeof(&line, "p2d_current_t", sizeof(p2d_current_t));
    p2d_cost_sizeof(&line, "p2d_current_coef_t", sizeof(p2d_current_coef_t));
    p2d_cost_sizeof(&line, "p2d_current_config_t", sizeof(p2d_current_config_t));
    p2d_cost_sizeof(&line, "p2d_current_output_t", sizeof(p2d_current_output_t));
    p2d_cost_sizeof(&line, "p2d_encoder_t", sizeof(p2d_encoder_t));
    p2d_cost_sizeof(&line, "p2d_encoder_coef_t", sizeof(p2d_encoder_coef_t));
    p2d_cost_sizeof(&line, "p2d_encoder_config_t", sizeof(p2d_encoder_config_t));
    p2d_cost_sizeof(&line, "p2d_encoder_output_t", sizeof(p2d_encoder_output_t));
    p2d_cost_sizeof(&line, "p2d_field_weakening_t", sizeof(p2d_field_weakening_t));
    p2d_cost_sizeof(&line, "p2d_field_weakening_coef_t", sizeof(p2d_field_weakening_coef_t));
    p2d_cost_sizeof(&line, "p2d_field_weakening_config_t", sizeof(p2d_field_weakening_config_t));
    p2d_cost_sizeof(&line, "p2d_field_weakening_output_t", sizeof(p2d_field_weakening_output_t));
    p2d_cost_sizeof(&line, "p2d_inertia_t", sizeof(p2d_inertia_t));
    p2d_cost_sizeof(&line, "p2d_inertia_coef_t", sizeof(p2d_inertia_coef_t));
    p2d_cost_sizeof(&line, "p2d_inertia_config_t", sizeof(p2d_inertia_config_t));
    p2d_cost_sizeof(&line, "p2d_inertia_output_t", sizeof(p2d_inertia_output_t));
    p2d_cost_sizeof(&line, "p2d_filter_t", sizeof(p2d_filter_t));
    p2d_cost_sizeof(&line, "p2d_filter_coef_t", sizeof(p2d_filter_coef_t));
    p2d_cost_sizeof(&line, "p2d_filter_config_t", sizeof(p2d_filter_config_t));
    p2d_cost_sizeof(&line, "p2d_filter_state_t", sizeof(p2d_filter_state_t));

    for (int aw = P2D_AW_NONE; aw <= P2D_AW_CLAMPING; ++aw) {
        for (int ff = P2D_FF_NONE; ff <= P2D_FF_FULL; ++ff) {
            for (int sat = 0; sat <= 1; ++sat) {
                probe_speed(P2D_TUSTIN, (p2d_anti_windup_t)aw, (p2d_feedforward_t)ff, false, sat != 0);
            }
        }
    }
    /* the method changes coefficients only: the same path length is expected */
    for (int method = P2D_FORWARD_EULER; method <= P2D_BACKWARD_EULER; ++method) {
        probe_speed((p2d_method_t)method, P2D_AW_BACK_CALCULATION, P2D_FF_LOWPASS, false, false);
    }
    /* salient PMSM: MTPA current split by Newton iterations */
    for (int sat = 0; sat <= 1; ++sat) {
        probe_speed(P2D_TUSTIN, P2D_AW_BACK_CALCULATION, P2D_FF_LOWPASS, true, sat != 0);
    }
    /* torque filters: each section alone and both, on the target configuration; both on a salient PMSM */
    for (uint32_t sections = 1u; sections <= 3u; ++sections) {
        for (int sat = 0; sat <= 1; ++sat) {
            probe_speed_filtered(sections, false, sat != 0);
        }
    }
    for (int sat = 0; sat <= 1; ++sat) {
        probe_speed_filtered(3u, true, sat != 0);
    }
    for (uint32_t sections = 1u; sections <= 3u; ++sections) {
        probe_filter(sections);
    }
    for (int aw = P2D_AW_NONE; aw <= P2D_AW_CLAMPING; ++aw) {
        for (int dec = 0; dec <= 1; ++dec) {
            for (int sat = 0; sat <= 1; ++sat) {
                probe_current((p2d_anti_windup_t)aw, dec != 0, sat != 0);
            }
        }
    }
    /* speed sensing and field weakening */
    for (int sat = 0; sat <= 1; ++sat) {
        probe_speed_fw(false, sat != 0);
        probe_speed_fw(true, sat != 0);
    }
    for (int estimator = P2D_ESTIMATOR_DIFFERENCE; estimator <= P2D_ESTIMATOR_PLL; ++estimator) {
        probe_encoder((p2d_estimator_t)estimator, false);
        probe_encoder((p2d_estimator_t)estimator, true);
    }
    for (int aw = P2D_AW_BACK_CALCULATION; aw <= P2D_AW_CLAMPING; ++aw) {
        probe_field_weakening((p2d_anti_windup_t)aw, 10.0f, false, false, "off");
        probe_field_weakening((p2d_anti_windup_t)aw, 26.5f, true, false, "weakening");
        probe_field_weakening((p2d_anti_windup_t)aw, 60.0f, true, true, "at_id_min");
    }
    probe_inertia(false, "start");
    probe_inertia(false, "prior");
    probe_inertia(false, "update");
    probe_inertia(true, "update");
    probe_inertia(false, "fault");
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
