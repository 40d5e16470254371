/*
 * Golden-vector runner of the commissioning routine: feeds the stored current
 * and DC-link sequences of p2d_commission_vectors.h through
 * p2d_commission_step, one configuration per case, and prints every output of
 * every sample and the routine's results at the end as the hex bits of their
 * float32 (or uint32) values. tests/test_target_qemu_commission.py writes the
 * header from closed-loop runs on the host, builds this program for the
 * Cortex-M4F, runs it on QEMU and compares each word with the same C code
 * built for the host (pmsm2dof._core).
 *
 * Output (all words hex):
 *   I case status                                           after init
 *   M case k  ud uq theta w_e id_ref iq_ref phase fault      every sample
 *   E case  phase failed_phase reason fault_count L_probe Rs u_err Ld Lq psi_f
 *           rs_spread asymmetry coherence psi_spread slip    after the last sample
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "pmsm2dof/commission.h"
#include "semihost.h"

/*
 * Generated: P2D_CVEC_CASES, p2d_cvec_config[], p2d_cvec_samples[] (samples
 * of each case) and p2d_cvec_input[] (id, iq, u_dc bits of every sample, the
 * cases one after the other).
 */
#include "p2d_commission_vectors.h"

static float from_bits(uint32_t bits)
{
    float x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

static void line_case(p2d_line_t *line, const char *tag, uint32_t c)
{
    p2d_line_text(line, tag);
    p2d_line_hex(line, c);
}

static void run_case(uint32_t c, const uint32_t *in, p2d_line_t *line)
{
    static p2d_commission_t routine;
    p2d_commission_output_t out;
    p2d_status_t status = p2d_commission_init(&routine, &p2d_cvec_config[c]);

    line_case(line, "I ", c);
    p2d_line_hex(line, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < p2d_cvec_samples[c]; ++k, in += 3) {
        p2d_commission_step(&routine, from_bits(in[0]), from_bits(in[1]), from_bits(in[2]), &out);
        line_case(line, "M ", c);
        p2d_line_hex(line, k);
        p2d_line_float(line, out.ud_V);
        p2d_line_float(line, out.uq_V);
        p2d_line_float(line, out.theta_e_rad);
        p2d_line_float(line, out.w_e_radps);
        p2d_line_float(line, out.id_ref_A);
        p2d_line_float(line, out.iq_ref_A);
        p2d_line_hex(line, (uint32_t)out.phase);
        p2d_line_hex(line, out.fault);
        p2d_line_flush(line);
    }
    line_case(line, "E ", c);
    p2d_line_hex(line, (uint32_t)routine.phase);
    p2d_line_hex(line, (uint32_t)routine.failed_phase);
    p2d_line_hex(line, (uint32_t)routine.reason);
    p2d_line_hex(line, routine.fault_count);
    p2d_line_float(line, routine.L_probe_H);
    p2d_line_float(line, routine.Rs_ohm);
    p2d_line_float(line, routine.u_err_V);
    p2d_line_float(line, routine.Ld_H);
    p2d_line_float(line, routine.Lq_H);
    p2d_line_float(line, routine.psi_f_Wb);
    p2d_line_float(line, routine.rs_spread);
    p2d_line_float(line, routine.asymmetry);
    p2d_line_float(line, routine.coherence);
    p2d_line_float(line, routine.psi_spread);
    p2d_line_float(line, routine.slip);
    p2d_line_flush(line);
}

int main(void)
{
    static p2d_line_t line;
    const uint32_t *in = p2d_cvec_input;

    for (uint32_t c = 0u; c < P2D_CVEC_CASES; ++c) {
        run_case(c, in, &line);
        in += 3u * p2d_cvec_samples[c];
    }
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
