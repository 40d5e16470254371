/*
 * Golden-vector runner of the fixed-point speed controllers (pmsm2dof/speed_fixed.h):
 * feeds the stored operations of p2d_fixed_vectors.h through the Q15 and the Q31
 * controller, for every configuration there, and prints the coefficients after
 * init and every output and state word after every operation.
 * tests/test_target_qemu_fixed.py writes the header, builds this program for the
 * Cortex-M3 (QEMU mps2-an385) and the Cortex-M0 (QEMU microbit), runs it and
 * compares each word with the same C code built for the host (pmsm2dof._core).
 *
 * An operation is {op, w_ref, w_m, a}: op 0 a step (the own torque applied), op 1
 * compute then update with the applied torque a (a later limit), op 2 reset to
 * (w_ref, T_init = a).
 *
 * Output (semihosting), all words hex; 64-bit numbers as two words, high first:
 *   I <fmt> case status
 *   K <fmt> case  mantissa shift (8 gains, speed_fixed.h order) T_max iq_max clamping
 *   A case k  w_ref e T_ff y_ff T_unsat T_ref iq_ref saturated x y_prev r_prev    (Q15)
 *   B case k  the same, Q31 (e, T_ff, y_ff, T_unsat, x, y_prev 64-bit)
 * then END.
 */
#include <stdint.h>

#include "pmsm2dof/speed_fixed.h"
#include "semihost.h"

/*
 * Generated: P2D_FV_SAMPLES, P2D_FV_CASES, p2d_fv_config[P2D_FV_CASES],
 * p2d_fv_q15[P2D_FV_CASES][P2D_FV_SAMPLES][4] (int16: op, w_ref, w_m, a),
 * p2d_fv_q31[P2D_FV_CASES][P2D_FV_SAMPLES][4] (int32: op, w_ref, w_m, a).
 */
#include "p2d_fixed_vectors.h"

static p2d_line_t line;

static void line_head(const char *tag, uint32_t c, uint32_t k)
{
    p2d_line_text(&line, tag);
    p2d_line_hex(&line, c);
    p2d_line_hex(&line, k);
}

static void line_i64(int64_t v)
{
    const uint64_t u = (uint64_t)v;
    p2d_line_hex(&line, (uint32_t)(u >> 32));
    p2d_line_hex(&line, (uint32_t)u);
}

static void line_gain(int32_t mantissa, uint32_t shift)
{
    p2d_line_hex(&line, (uint32_t)mantissa);
    p2d_line_hex(&line, shift);
}

/* The coefficient set k of the format fmt (q15, q31) on the line, which it writes out. */
#define P2D_LINE_COEF(k, fmt)                                               \
    do {                                                                    \
        line_gain((k)->b_e0.mantissa, (k)->b_e0.shift);                     \
        line_gain((k)->Ki_Ts.mantissa, (k)->Ki_Ts.shift);                   \
        line_gain((k)->Ki_Ka_Ts.mantissa, (k)->Ki_Ka_Ts.shift);             \
        line_gain((k)->ff_Fr0.mantissa, (k)->ff_Fr0.shift);                 \
        line_gain((k)->ff_b_dr.mantissa, (k)->ff_b_dr.shift);               \
        line_gain((k)->ff_one_plus_a1.mantissa, (k)->ff_one_plus_a1.shift); \
        line_gain((k)->ff_Kd_per_Ts.mantissa, (k)->ff_Kd_per_Ts.shift);     \
        line_gain((k)->iq_per_T.mantissa, (k)->iq_per_T.shift);             \
        p2d_line_hex(&line, (uint32_t)(k)->T_max_##fmt);                    \
        p2d_line_hex(&line, (uint32_t)(k)->iq_max_##fmt);                   \
        p2d_line_hex(&line, (k)->clamping);                                 \
        p2d_line_flush(&line);                                              \
    } while (0)

static void run_q15(uint32_t c)
{
    p2d_speed_q15_t ctl;
    p2d_speed_q15_output_t out;
    const p2d_status_t status = p2d_speed_q15_init(&ctl, &p2d_fv_config[c]);
    line_head("I Q15 ", c, (uint32_t)status);
    p2d_line_flush(&line);
    if (status != P2D_OK) return;
    line_head("K Q15 ", c, 0u);
    P2D_LINE_COEF(&ctl.coef[ctl.active], q15);
    for (uint32_t k = 0u; k < P2D_FV_SAMPLES; ++k) {
        const int16_t *in = p2d_fv_q15[c][k];
        if (in[0] == 2) {
            p2d_speed_q15_reset(&ctl, in[1], in[3]);
            continue;
        }
        if (in[0] == 1) {
            p2d_speed_q15_compute(&ctl, in[1], in[2], &out);
            p2d_speed_q15_update(&ctl, &out, in[3]);
        } else {
            p2d_speed_q15_step(&ctl, in[1], in[2], &out);
        }
        line_head("A ", c, k);
        p2d_line_hex(&line, (uint32_t)out.w_ref_q15);
        p2d_line_hex(&line, (uint32_t)out.e_q15);
        p2d_line_hex(&line, (uint32_t)out.T_ff_q15);
        p2d_line_hex(&line, (uint32_t)out.y_ff_q15);
        p2d_line_hex(&line, (uint32_t)out.T_unsat_q15);
        p2d_line_hex(&line, (uint32_t)out.T_ref_q15);
        p2d_line_hex(&line, (uint32_t)out.iq_ref_q15);
        p2d_line_hex(&line, out.saturated);
        p2d_line_hex(&line, (uint32_t)ctl.x_q15);
        p2d_line_hex(&line, (uint32_t)ctl.y_ff_prev_q15);
        p2d_line_hex(&line, (uint32_t)ctl.r_prev_q15);
        p2d_line_flush(&line);
    }
}

static void run_q31(uint32_t c)
{
    p2d_speed_q31_t ctl;
    p2d_speed_q31_output_t out;
    const p2d_status_t status = p2d_speed_q31_init(&ctl, &p2d_fv_config[c]);
    line_head("I Q31 ", c, (uint32_t)status);
    p2d_line_flush(&line);
    if (status != P2D_OK) return;
    line_head("K Q31 ", c, 0u);
    P2D_LINE_COEF(&ctl.coef[ctl.active], q31);
    for (uint32_t k = 0u; k < P2D_FV_SAMPLES; ++k) {
        const int32_t *in = p2d_fv_q31[c][k];
        if (in[0] == 2) {
            p2d_speed_q31_reset(&ctl, in[1], in[3]);
            continue;
        }
        if (in[0] == 1) {
            p2d_speed_q31_compute(&ctl, in[1], in[2], &out);
            p2d_speed_q31_update(&ctl, &out, in[3]);
        } else {
            p2d_speed_q31_step(&ctl, in[1], in[2], &out);
        }
        line_head("B ", c, k);
        p2d_line_hex(&line, (uint32_t)out.w_ref_q31);
        line_i64(out.e_q31);
        line_i64(out.T_ff_q31);
        line_i64(out.y_ff_q31);
        line_i64(out.T_unsat_q31);
        p2d_line_hex(&line, (uint32_t)out.T_ref_q31);
        p2d_line_hex(&line, (uint32_t)out.iq_ref_q31);
        p2d_line_hex(&line, out.saturated);
        line_i64(ctl.x_q62);
        line_i64(ctl.y_ff_prev_q31);
        p2d_line_hex(&line, (uint32_t)ctl.r_prev_q31);
        p2d_line_flush(&line);
    }
}

int main(void)
{
    for (uint32_t c = 0u; c < P2D_FV_CASES; ++c) {
        run_q15(c);
        run_q31(c);
    }
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
