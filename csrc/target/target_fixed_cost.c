/*
 * Cost probes of the speed controller in float32 and in fixed point, on every board
 * (Cortex-M4F, M3, M0), read by benchmarks/footprint.py:
 *
 * - the size of the controller structs, as the target compiler lays them out;
 * - one p2d_speed_step, p2d_speed_q15_step and p2d_speed_q31_step per operating point
 *   (unsaturated, saturated), each right after a call of p2d_cost_mark(), for the
 *   instruction trace of QEMU, and the stack it used. Without an FPU the float32 step
 *   runs on the compiler's software floating point.
 *
 * The configuration: the paper's drive (J = 0.4 kg m^2, alpha = 0.5 rad/s, zeta = 0.2887,
 * 7.6 A; a surface PMSM, kt = 1.2 Nm/A), Tustin, back calculation, lowpass feedforward,
 * at 1 kHz; fixed point scaled to 1000 rpm and 32 Nm, 10 A.
 *
 * Output lines (semihosting):
 *   sizeof <type> <bytes>
 *   probe <index> <speed|speed_q15|speed_q31> <point> stack <bytes>
 * The index counts the calls of p2d_cost_mark() in order.
 */
#include <stdbool.h>
#include <stdint.h>

#include "cost_probe.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/speed_fixed.h"
#include "semihost.h"

#define P2D_WARMUP_STEPS 4u /* steps before the probe, so the state is not all zero */

static p2d_line_t line;
static uint32_t probe_index;

static p2d_speed_fixed_config_t paper_config(void)
{
    p2d_speed_fixed_config_t cfg;
    cfg.speed.J_kgm2 = 0.4f;
    cfg.speed.alpha_radps = 0.5f;
    cfg.speed.zeta = 0.2887f;
    cfg.speed.m = 1.0f;
    cfg.speed.tau_i_s = 0.05f;
    cfg.speed.Ka = 5.0f;
    cfg.speed.Ts_s = 1e-3f;
    cfg.speed.i_max_A = 7.6f;
    cfg.speed.psi_f_Wb = 0.2f;
    cfg.speed.Ld_H = 0.01f;
    cfg.speed.Lq_H = 0.01f;
    cfg.speed.pole_pairs = 4u;
    cfg.speed.method = P2D_TUSTIN;
    cfg.speed.feedforward = P2D_FF_LOWPASS;
    cfg.speed.anti_windup = P2D_AW_BACK_CALCULATION;
    cfg.speed_full_scale_radps = 104.719755f; /* 1000 rpm */
    cfg.torque_full_scale_Nm = 32.0f;
    cfg.current_full_scale_A = 10.0f;
    return cfg;
}

static void probe_line(const char *controller, bool saturate, uint32_t stack_bytes)
{
    p2d_line_text(&line, "probe ");
    p2d_line_hex(&line, probe_index++);
    p2d_line_text(&line, controller);
    p2d_line_text(&line, saturate ? " saturated" : " unsaturated");
    p2d_line_text(&line, " stack ");
    p2d_line_hex(&line, stack_bytes);
    p2d_line_flush(&line);
}

/* The float32 step at 50 rad/s: an error of 0.1 rad/s (unsaturated) or 50 rad/s (saturated). */
static void probe_float(bool saturate)
{
    const p2d_speed_fixed_config_t cfg = paper_config();
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    const float w_ref = 50.0f, w_m = saturate ? 0.0f : 49.9f;
    uint32_t sp, stack_bytes;
    if (p2d_speed_init(&ctl, &cfg.speed) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_reset(&ctl, w_ref, 0.0f);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) p2d_speed_step(&ctl, w_ref, w_m, &out);
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_step(&ctl, w_ref, w_m, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate) p2d_semihost_exit(false);
    probe_line("speed", saturate, stack_bytes);
}

/* The Q15 step at the same speeds (16000 LSB: 48.8 rad/s). */
static void probe_q15(bool saturate)
{
    const p2d_speed_fixed_config_t cfg = paper_config();
    p2d_speed_q15_t ctl;
    p2d_speed_q15_output_t out;
    const int16_t w_ref = 16000, w_m = saturate ? 0 : 15970;
    uint32_t sp, stack_bytes;
    if (p2d_speed_q15_init(&ctl, &cfg) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_q15_reset(&ctl, w_ref, 0);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) p2d_speed_q15_step(&ctl, w_ref, w_m, &out);
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_q15_step(&ctl, w_ref, w_m, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate) p2d_semihost_exit(false);
    probe_line("speed_q15", saturate, stack_bytes);
}

/* The Q31 step at the same speeds. */
static void probe_q31(bool saturate)
{
    const p2d_speed_fixed_config_t cfg = paper_config();
    p2d_speed_q31_t ctl;
    p2d_speed_q31_output_t out;
    const int32_t w_ref = 16000 * 65536, w_m = saturate ? 0 : 15970 * 65536;
    uint32_t sp, stack_bytes;
    if (p2d_speed_q31_init(&ctl, &cfg) != P2D_OK) p2d_semihost_exit(false);
    p2d_speed_q31_reset(&ctl, w_ref, 0);
    for (uint32_t k = 0u; k < P2D_WARMUP_STEPS; ++k) p2d_speed_q31_step(&ctl, w_ref, w_m, &out);
    sp = p2d_stack_pointer();
    p2d_stack_paint(sp);
    p2d_cost_mark();
    p2d_speed_q31_step(&ctl, w_ref, w_m, &out);
    stack_bytes = p2d_stack_used(sp);
    if (out.saturated != saturate) p2d_semihost_exit(false);
    probe_line("speed_q31", saturate, stack_bytes);
}

int main(void)
{
    p2d_cost_sizeof(&line, "p2d_speed_t", sizeof(p2d_speed_t));
    p2d_cost_sizeof(&line, "p2d_speed_q15_t", sizeof(p2d_speed_q15_t));
    p2d_cost_sizeof(&line, "p2d_speed_q31_t", sizeof(p2d_speed_q31_t));
    p2d_cost_sizeof(&line, "p2d_speed_q15_output_t", sizeof(p2d_speed_q15_output_t));
    p2d_cost_sizeof(&line, "p2d_speed_q31_output_t", sizeof(p2d_speed_q31_output_t));
    for (int saturate = 0; saturate <= 1; ++saturate) {
        probe_float(saturate != 0);
        probe_q15(saturate != 0);
        probe_q31(saturate != 0);
    }
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
