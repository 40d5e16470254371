/*
 * pmsm2dof: host-only batch runners of the deployable controllers.
 *
 * Each runner calls the controller's own step function once per sample, in
 * order, so that bulk runs (tests, design studies, the Python `run` methods)
 * execute exactly the code that ships on the MCU, without a Python call per
 * sample. The controller state carries over between calls.
 */
#ifndef PMSM2DOF_SIM_BATCH_H
#define PMSM2DOF_SIM_BATCH_H

#include <stddef.h>

#include "pmsm2dof/current.h"
#include "pmsm2dof/speed.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * For k = 0 .. n-1: p2d_speed_step(ctl, w_ref_radps[k], w_m_radps[k], &out[k]),
 * then x_i_Nm[k] = p2d_speed_integrator_Nm(ctl), the integral of the PI after that sample [Nm].
 */
void p2d_speed_run(p2d_speed_t *ctl, size_t n, const float *w_ref_radps, const float *w_m_radps,
                   p2d_speed_output_t *out, float *x_i_Nm);

/*
 * For k = 0 .. n-1: p2d_current_step(ctl, id_ref_A[k], iq_ref_A[k], id_A[k], iq_A[k],
 * w_e_radps[k], u_dc_V[k], &out[k]), then x_d_V[k], x_q_V[k] = the integrator
 * states after that sample [V].
 */
void p2d_current_run(p2d_current_t *ctl, size_t n, const float *id_ref_A, const float *iq_ref_A, const float *id_A,
                     const float *iq_A, const float *w_e_radps, const float *u_dc_V, p2d_current_output_t *out,
                     float *x_d_V, float *x_q_V);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_BATCH_H */
