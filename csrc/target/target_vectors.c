/*
 * Golden-vector runner: feeds stored input sequences through the speed and the
 * current controller and the inertia estimator, for every configuration in
 * p2d_target_vectors.h, and prints every output and the state after every
 * sample as the hex bits of the float32 values. tests/test_target_qemu.py writes the header, builds this
 * program for the Cortex-M4F, runs it on QEMU and compares each word with the
 * same C code built for the host (pmsm2dof._core).
 *
 * Each sample is split into compute and update, with an applied command that
 * may differ from the controller's own (an external limit), as in firmware:
 *   applied = the command limited to [-lim, lim]; a NaN lim gives a NaN
 *   applied command (exercises the non-finite policy of the update).
 *
 * Output, one line per sample (all words hex):
 *   S case k  w_ref e T_ff y_ff T_unsat T_ref id_ref iq_ref saturated fault x r_prev y_ff_prev fault_count
 *   C case k  ed eq ud_unsat uq_unsat ud_ref uq_ref saturated fault x_d x_q fault_count
 *   F case k  as S, through p2d_speed_compute_fw with the id_fw of the sample
 *   E case k  dn w_raw w_m fault count_prev theta_err v_pll w_lowpass fault_count
 *   W case k  u_ref e id_unsat id_ref active at_id_min fault x fault_count
 *   J case k  J J_sd B T_load residual residual_sd J_valid updated fault   (inertia estimator)
 *   K case k  T_load J B U_LJ U_LB U_JB D_L D_J D_B wF w0 TF 1F T_prev nis primed fault_count
 * and one line per case after init: "I S case status" (likewise C, F, E, W, J).
 * The estimator gets the speed and torque of its input row as they are.
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "pmsm2dof/current.h"
#include "pmsm2dof/encoder.h"
#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/inertia.h"
#include "pmsm2dof/speed.h"
#include "semihost.h"

/*
 * Generated: P2D_VEC_SAMPLES, P2D_VEC_SPEED_CASES, P2D_VEC_CURRENT_CASES,
 * p2d_vec_speed_config[], p2d_vec_speed_input[][][3] (w_ref, w_m, lim bits),
 * p2d_vec_current_config[], p2d_vec_current_input[][][7]
 * (id_ref, iq_ref, id, iq, w_e, u_dc, lim bits),
 * p2d_vec_speed_fw_input[P2D_VEC_SPEED_CASES][][4] (w_ref, w_m, id_fw, lim bits),
 * P2D_VEC_ENCODER_CASES, p2d_vec_encoder_config[], p2d_vec_encoder_input[][] (readings),
 * P2D_VEC_FW_CASES, p2d_vec_fw_config[], p2d_vec_fw_input[][][3] (ud, uq, u_dc bits),
 * P2D_VEC_INERTIA_CASES, p2d_vec_inertia_config[], p2d_vec_inertia_input[][][2] (w_m, T_e bits).
 */
#include "p2d_target_vectors.h"

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

static void run_speed_case(uint32_t c, p2d_line_t *line)
{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_status_t status = p2d_speed_init(&ctl, &p2d_vec_speed_config[c]);

    line_case(line, "I S ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_vec_speed_input[c][k];
        p2d_speed_compute(&ctl, from_bits(in[0]), from_bits(in[1]), &out);
        p2d_speed_update(&ctl, &out, limit(out.T_ref_Nm, from_bits(in[2])));

        line_case(line, "S ", c, k);
        p2d_line_float(line, out.w_ref_radps);
        p2d_line_float(line, out.e_radps);
        p2d_line_float(line, out.T_ff_Nm);
        p2d_line_float(line, out.y_ff_Nm);
        p2d_line_float(line, out.T_unsat_Nm);
        p2d_line_float(line, out.T_ref_Nm);
        p2d_line_float(line, out.id_ref_A);
        p2d_line_float(line, out.iq_ref_A);
        p2d_line_hex(line, out.saturated);
        p2d_line_hex(line, out.fault);
        p2d_line_float(line, ctl.x_Nm);
        p2d_line_float(line, ctl.r_prev_radps);
        p2d_line_float(line, ctl.y_ff_prev_Nm);
        p2d_line_hex(line, ctl.fault_count);
        p2d_line_flush(line);
    }
}

/* The speed controller's field-weakening entry, split as run_speed_case. */
static void run_speed_fw_case(uint32_t c, p2d_line_t *line)
{
    p2d_speed_t ctl;
    p2d_speed_output_t out;
    p2d_status_t status = p2d_speed_init(&ctl, &p2d_vec_speed_config[c]);

    line_case(line, "I F ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_vec_speed_fw_input[c][k];
        p2d_speed_compute_fw(&ctl, from_bits(in[0]), from_bits(in[1]), from_bits(in[2]), &out);
        p2d_speed_update(&ctl, &out, limit(out.T_ref_Nm, from_bits(in[3])));

        line_case(line, "F ", c, k);
        p2d_line_float(line, out.w_ref_radps);
        p2d_line_float(line, out.e_radps);
        p2d_line_float(line, out.T_ff_Nm);
        p2d_line_float(line, out.y_ff_Nm);
        p2d_line_float(line, out.T_unsat_Nm);
        p2d_line_float(line, out.T_ref_Nm);
        p2d_line_float(line, out.id_ref_A);
        p2d_line_float(line, out.iq_ref_A);
        p2d_line_hex(line, out.saturated);
        p2d_line_hex(line, out.fault);
        p2d_line_float(line, ctl.x_Nm);
        p2d_line_float(line, ctl.r_prev_radps);
        p2d_line_float(line, ctl.y_ff_prev_Nm);
        p2d_line_hex(line, ctl.fault_count);
        p2d_line_flush(line);
    }
}

static void run_encoder_case(uint32_t c, p2d_line_t *line)
{
    p2d_encoder_t enc;
    p2d_encoder_output_t out;
    p2d_status_t status = p2d_encoder_init(&enc, &p2d_vec_encoder_config[c]);

    line_case(line, "I E ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    p2d_encoder_reset(&enc, p2d_vec_encoder_input[c][0], 0.0f);
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        p2d_encoder_step(&enc, p2d_vec_encoder_input[c][k], &out);

        line_case(line, "E ", c, k);
        p2d_line_hex(line, (uint32_t)out.dn_counts);
        p2d_line_float(line, out.w_raw_radps);
        p2d_line_float(line, out.w_m_radps);
        p2d_line_hex(line, out.fault);
        p2d_line_hex(line, enc.count_prev);
        p2d_line_float(line, enc.theta_err_counts);
        p2d_line_float(line, enc.v_pll_counts);
        p2d_line_float(line, enc.w_lowpass_radps);
        p2d_line_hex(line, enc.fault_count);
        p2d_line_flush(line);
    }
}

static void run_fw_case(uint32_t c, p2d_line_t *line)
{
    p2d_field_weakening_t fw;
    p2d_field_weakening_output_t out;
    p2d_status_t status = p2d_field_weakening_init(&fw, &p2d_vec_fw_config[c]);

    line_case(line, "I W ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_vec_fw_input[c][k];
        p2d_field_weakening_step(&fw, from_bits(in[0]), from_bits(in[1]), from_bits(in[2]), &out);

        line_case(line, "W ", c, k);
        p2d_line_float(line, out.u_ref_V);
        p2d_line_float(line, out.e_V);
        p2d_line_float(line, out.id_unsat_A);
        p2d_line_float(line, out.id_ref_A);
        p2d_line_hex(line, out.active);
        p2d_line_hex(line, out.at_id_min);
        p2d_line_hex(line, out.fault);
        p2d_line_float(line, fw.x_A);
        p2d_line_hex(line, fw.fault_count);
        p2d_line_flush(line);
    }
}

static void run_current_case(uint32_t c, p2d_line_t *line)
{
    p2d_current_t ctl;
    p2d_current_output_t out;
    p2d_status_t status = p2d_current_init(&ctl, &p2d_vec_current_config[c]);

    line_case(line, "I C ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_vec_current_input[c][k];
        float lim = from_bits(in[6]);
        p2d_current_compute(&ctl, from_bits(in[0]), from_bits(in[1]), from_bits(in[2]), from_bits(in[3]),
                            from_bits(in[4]), from_bits(in[5]), &out);
        p2d_current_update(&ctl, &out, limit(out.ud_ref_V, lim), limit(out.uq_ref_V, lim));

        line_case(line, "C ", c, k);
        p2d_line_float(line, out.ed_A);
        p2d_line_float(line, out.eq_A);
        p2d_line_float(line, out.ud_unsat_V);
        p2d_line_float(line, out.uq_unsat_V);
        p2d_line_float(line, out.ud_ref_V);
        p2d_line_float(line, out.uq_ref_V);
        p2d_line_hex(line, out.saturated);
        p2d_line_hex(line, out.fault);
        p2d_line_float(line, ctl.x_d_V);
        p2d_line_float(line, ctl.x_q_V);
        p2d_line_hex(line, ctl.fault_count);
        p2d_line_flush(line);
    }
}

static void run_inertia_case(uint32_t c, p2d_line_t *line)
{
    p2d_inertia_t est;
    p2d_inertia_output_t out;
    p2d_status_t status = p2d_inertia_init(&est, &p2d_vec_inertia_config[c]);

    line_case(line, "I J ", c, (uint32_t)status);
    p2d_line_flush(line);
    if (status != P2D_OK) return;
    for (uint32_t k = 0u; k < P2D_VEC_SAMPLES; ++k) {
        const uint32_t *in = p2d_vec_inertia_input[c][k];
        p2d_inertia_step(&est, from_bits(in[0]), from_bits(in[1]), &out);

        line_case(line, "J ", c, k);
        p2d_line_float(line, out.J_kgm2);
        p2d_line_float(line, out.J_sd_kgm2);
        p2d_line_float(line, out.B_Nms);
        p2d_line_float(line, out.T_load_Nm);
        p2d_line_float(line, out.residual_Nm);
        p2d_line_float(line, out.residual_sd_Nm);
        p2d_line_hex(line, out.J_valid);
        p2d_line_hex(line, out.updated);
        p2d_line_hex(line, out.fault);
        p2d_line_flush(line);
        line_case(line, "K ", c, k);
        p2d_line_float(line, est.T_load_Nm);
        p2d_line_float(line, est.J_kgm2);
        p2d_line_float(line, est.B_Nms);
        p2d_line_float(line, est.U_LJ_per_s2);
        p2d_line_float(line, est.U_LB_per_s);
        p2d_line_float(line, est.U_JB_s);
        p2d_line_float(line, est.D_L_N2m2);
        p2d_line_float(line, est.D_J_kg2m4);
        p2d_line_float(line, est.D_B_N2m2s2);
        p2d_line_float(line, est.wF_radps);
        p2d_line_float(line, est.w0_radps);
        p2d_line_float(line, est.TF_Nm);
        p2d_line_float(line, est.oneF);
        p2d_line_float(line, est.T_prev_Nm);
        p2d_line_float(line, est.nis);
        p2d_line_hex(line, est.primed);
        p2d_line_hex(line, est.fault_count);
        p2d_line_flush(line);
    }
}

int main(void)
{
    static p2d_line_t line;

    for (uint32_t c = 0u; c < P2D_VEC_SPEED_CASES; ++c) {
        run_speed_case(c, &line);
    }
    for (uint32_t c = 0u; c < P2D_VEC_CURRENT_CASES; ++c) {
        run_current_case(c, &line);
    }
    for (uint32_t c = 0u; c < P2D_VEC_SPEED_CASES; ++c) {
        run_speed_fw_case(c, &line);
    }
    for (uint32_t c = 0u; c < P2D_VEC_ENCODER_CASES; ++c) {
        run_encoder_case(c, &line);
    }
    for (uint32_t c = 0u; c < P2D_VEC_FW_CASES; ++c) {
        run_fw_case(c, &line);
    }
    for (uint32_t c = 0u; c < P2D_VEC_INERTIA_CASES; ++c) {
        run_inertia_case(c, &line);
    }
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(true);
}
