/*
 * Golden-vector runner of the filters: the coefficients and the outputs of the
 * notch and low-pass filters (p2d_filter_t) and of the speed controller with
 * torque filters, for every configuration in p2d_target_filter_vectors.h, as
 * the hex bits of the float32 values. tests/test_target_qemu_filter.py writes
 * the header, builds this program for the Cortex-M4F, runs it on QEMU and
 * compares each word with the same C code built for the host
 * (pmsm2dof._core): the coefficients come from tan(pi f0 Ts) computed with
 * +, *, / and fmaf only, which must round alike on both.
 *
 * Output (all words hex):
 *   I F case status               after p2d_filter_init
 *   K F case g k g_h c_band g k g_h c_band    notch and low-pass coefficients
 *   F case k  y fault  notch.s1 notch.s2 lowpass.s1 lowpass.s2 fault_count
 *   I S case status               after p2d_speed_init and p2d_speed_set_filter
 *   S case k  T_unsat T_ref iq_ref saturated fault  x notch.s1 notch.s2 lowpass.s1 lowpass.s2 fault_count
 * A speed sample is split into compute and update with the applied torque
 * limited to [-lim, lim], as in target_vectors.c.
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "pmsm2dof/filter.h"
#include "pmsm2dof/speed.h"
#include "semihost.h"

/*
 * Generated: P2D_FVEC_SAMPLES, P2D_FVEC_FILTER_CASES, p2d_fvec_filter_config[],
 * p2d_fvec_filter_Ts[], p2d_fvec_filter_input[][] (x bits), P2D_FVEC_SPEED_CASES,
 * p2d_fvec_speed_config[], p2d_fvec_speed_filter[], p2d_fvec_speed_input[][][3]
 * (w_ref, w_m, lim bits).
 */
#include "p2d_target_filter_vectors.h"

static float from_bits(uint32_t bits)
{
    float x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

/* x limited to [-lim, lim]; NaN when lim is NaN */
static float limit(float x, float lim)
{
    if (!(x <= lim)) x = lim;
    if (!(x >= -lim)) x = -lim;
    return x;
}

static void line_case(p2d_line_t *line, const char *tag, uint32_t c, uint32_t k)
{
    p2d_line_text(line, tag);
    p2d_line_hex(line, c);
    p2d_line_hex(line, k);
}

static void line_section(p2d_line_t *line, const p2d_biquad_coef_t *s)
{
    p2d_line_float(line, s->g);
    p2d_line_float(line, s->k);
    p2d_line_float(line, s->g_h);
    p2d_line_float(line, s->c_band);
}

static void line_state(p2d_line_t *line, const p2d_filter_state_t *s)
{
    p2d_line_float(line, s->notch.s1);
    p2d_line_float(line, s->notch.s2);
    p2d_line_float(line, s->lowpass.s1);
    p2d_line_float(line, s->lowpass.s2);
}

static void run_filter_case(uint32_t c, p2d_line_t *line)
{
    p2d_filter_t f;
    p2d_filter_output_t out;
    p2d_status_t status = p2d_filter_init(&f, &p2d_fvec_filter_config[c], p2d_fvec_filter_Ts[c]);

    line_case(line, "I F ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    p2d_line_text(line, "K F ");
    p2d_line_hex(line, c);
    line_section(line, &f.coef[f.active].notch);
    line_section(line, &f.coef[f.active].lowpass);
    p2d_line_flush(line);
    for (uint32_t k = 0u; k < P2D_FVEC_SAMPLES; ++k) {
        p2d_filter_step(&f, from_bits(p2d_fvec_filter_input[c][k]), &out);
        line_case(line, "F ", c, k);
        p2d_line_float(line, out.y);
        p2d_line_hex(line, out.fault);
        line_state(line, &f.state);
        p2d_line_hex(line, f.fault_count);
        p2d_line_flush(line);
    }
}

static void run_speed_case(uint32_t c, p2d_line_t *line)
{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_status_t status = p2d_speed_init(&ctl, &p2d_fvec_speed_config[c]);

    if (status == P2D_OK) status = p2d_speed_set_filter(&ctl, &p2d_fvec_speed_filter[c]);
    line_case(line, "I S ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_FVEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_fvec_speed_input[c][k];
        p2d_speed_compute(&ctl, from_bits(in[0]), from_bits(in[1]), &out);
        p2d_speed_update(&ctl, &out, limit(out.T_ref_Nm, from_bits(in[2])));
        line_case(line, "S ", c, k);
        p2d_line_float(line, out.T_unsat_Nm);
        p2d_line_float(line, out.T_ref_Nm);
        p2d_line_float(line, out.iq_ref_A);
        p2d_line_hex(line, out.saturated);
        p2d_line_hex(line, out.fault);
        p2d_line_float(line, ctl.x_Nm);
        line_state(line, &ctl.filter);
        p2d_line_hex(line, ctl.fault_count);
        p2d_line_flush(line);
    }
}

int main(void)
{
    static p2d_line_t line;
    for (uint32_t c = 0u; c < P2D_FVEC_FILTER_CASES; ++c) run_filter_case(c, &line);
    for (uint32_t c = 0u; c < P2D_FVEC_SPEED_CASES; ++c) run_speed_case(c, &line);
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
