#include "pmsm2dof/transforms.h"

#include <math.h>

#include "mtpa.h"

#define P2D_INV_SQRT3 0.57735026918962576f /* 1/sqrt(3) */
#define P2D_SQRT3_2 0.86602540378443865f   /* sqrt(3)/2 */

void p2d_clarke(float a, float b, float c, float *x_alpha, float *x_beta)
{
    /* x_alpha = (2a - b - c) / 3 */
    *x_alpha = (2.0f * a - b - c) * (1.0f / 3.0f);
    /* x_beta = (b - c) / sqrt(3) */
    *x_beta = (b - c) * P2D_INV_SQRT3;
}

void p2d_inv_clarke(float x_alpha, float x_beta, float *a, float *b, float *c)
{
    *a = x_alpha;
    /* b = -x_alpha/2 + sqrt(3)/2 x_beta */
    *b = -0.5f * x_alpha + P2D_SQRT3_2 * x_beta;
    /* c = -x_alpha/2 - sqrt(3)/2 x_beta */
    *c = -0.5f * x_alpha - P2D_SQRT3_2 * x_beta;
}

void p2d_park(float x_alpha, float x_beta, float sin_th, float cos_th, float *d, float *q)
{
    *d = cos_th * x_alpha + sin_th * x_beta;
    *q = -sin_th * x_alpha + cos_th * x_beta;
}

void p2d_inv_park(float d, float q, float sin_th, float cos_th, float *x_alpha, float *x_beta)
{
    *x_alpha = cos_th * d - sin_th * q;
    *x_beta = sin_th * d + cos_th * q;
}

float p2d_mtpa_id_A(float iq_A, float psi_f_Wb, float dL_H)
{
    /* id = 2 dL iq^2 / (psi_f + sqrt(psi_f^2 + 4 dL^2 iq^2)); without a magnet at zero current: 0 */
    if (psi_f_Wb == 0.0f && dL_H * iq_A == 0.0f) return 0.0f;
    return p2d_mtpa_id_of_iq_A(iq_A, psi_f_Wb, dL_H);
}
