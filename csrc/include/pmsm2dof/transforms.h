/*
 * pmsm2dof: Clarke and Park transforms (amplitude invariant) and the MTPA
 * current split of a salient PMSM.
 *
 * Amplitude invariance: a balanced set of phase currents of amplitude I maps to
 * a space vector of length I, so Te = 1.5 p (psi_f iq + (Ld - Lq) id iq).
 * Angles are given as sin and cos of the electrical angle, so that firmware
 * uses its own sine table or CORDIC.
 */
#ifndef PMSM2DOF_TRANSFORMS_H
#define PMSM2DOF_TRANSFORMS_H

#ifdef __cplusplus
extern "C" {
#endif

/* abc -> alpha beta: x_alpha = (2 a - b - c) / 3, x_beta = (b - c) / sqrt(3). */
void p2d_clarke(float a, float b, float c, float *x_alpha, float *x_beta);

/* alpha beta -> abc (zero sequence 0). */
void p2d_inv_clarke(float x_alpha, float x_beta, float *a, float *b, float *c);

/* alpha beta -> dq: d = cos x_alpha + sin x_beta, q = -sin x_alpha + cos x_beta. */
void p2d_park(float x_alpha, float x_beta, float sin_th, float cos_th, float *d, float *q);

/* dq -> alpha beta. */
void p2d_inv_park(float d, float q, float sin_th, float cos_th, float *x_alpha, float *x_beta);

/*
 * MTPA d-axis current for a given q-axis current:
 *   id = 2 dL iq^2 / (psi_f + sqrt(psi_f^2 + 4 dL^2 iq^2)),  dL = Ld - Lq,
 * the root of dL id^2 + psi_f id - dL iq^2 = 0 that is 0 for dL = 0, written
 * without cancellation, and scaled so that no square overflows or underflows
 * (a few ulps for any finite iq_A, psi_f_Wb >= 0, dL_H). Negative for the
 * usual dL < 0. The speed controller's current command of a salient PMSM
 * satisfies id_ref_A = p2d_mtpa_id_A(iq_ref_A, psi_f_Wb, Ld_H - Lq_H) exactly
 * (inside the current limit).
 */
float p2d_mtpa_id_A(float iq_A, float psi_f_Wb, float dL_H);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_TRANSFORMS_H */
