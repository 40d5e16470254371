/*
 * Host-only batch runners: see batch.h.
 */
#include "batch.h"

void p2d_speed_run(p2d_speed_t *ctl, size_t n, const float *w_ref_radps, const float *w_m_radps,
                   p2d_speed_output_t *out, float *x_i_Nm)
{
    for (size_t k = 0; k < n; ++k) {
        p2d_speed_step(ctl, w_ref_radps[k], w_m_radps[k], &out[k]);
        x_i_Nm[k] = p2d_speed_integrator_Nm(ctl);
    }
}

void p2d_current_run(p2d_current_t *ctl, size_t n, const float *id_ref_A, const float *iq_ref_A, const float *id_A,
                     const float *iq_A, const float *w_e_radps, const float *u_dc_V, p2d_current_output_t *out,
                     float *x_d_V, float *x_q_V)
{
    for (size_t k = 0; k < n; ++k) {
        p2d_current_step(ctl, id_ref_A[k], iq_ref_A[k], id_A[k], iq_A[k], w_e_radps[k], u_dc_V[k], &out[k]);
        x_d_V[k] = ctl->x_d_V;
        x_q_V[k] = ctl->x_q_V;
    }
}
