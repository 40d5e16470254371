/*
 * Internal (not installed, not part of the API): the maximum-torque-per-ampere
 * (MTPA) relations of a PMSM, written once for the speed controller's torque to
 * current inversion and for the public p2d_mtpa_id_A.
 *
 * With the amplitude-invariant torque Te = 1.5 p iq (psi_f + dL id),
 * dL = Ld - Lq, the current vector of a given length that gives the most
 * torque satisfies d Te / d angle = 0, the MTPA trajectory
 *   dL id^2 + psi_f id - dL iq^2 = 0
 * (Morimoto, Takeda, Hirasa, Taniguchi, "Expansion of operating limits for
 * permanent magnet motor by current vector control considering inverter
 * capacity", IEEE Trans. Ind. Appl. 26(5), 1990). Its root that is 0 for
 * dL = 0 is id = 2 dL iq^2 / (psi_f + sqrt(psi_f^2 + 4 dL^2 iq^2)): negative
 * for the usual dL < 0, |id| < |iq|.
 */
#ifndef PMSM2DOF_SRC_MTPA_H
#define PMSM2DOF_SRC_MTPA_H

#include <math.h>

/*
 * id [A] on the MTPA trajectory for iq_A [A] (psi_f_Wb >= 0 [Wb], dL_H [H]):
 *   id = iq x / (psi_f + h),   x = 2 dL iq [Wb],   h = sqrt(psi_f^2 + x^2),
 * with |x| / (psi_f + h) < 1. h is taken as big sqrt(1 + (small / big)^2),
 * big and small the larger and the smaller of psi_f and |x|, so that no square
 * overflows or underflows and id keeps its relative precision (a few ulps)
 * from the tiniest machine to the largest, for every finite x; id = 0 for
 * dL = 0. Needs max(psi_f, |x|) > 0 (0 / 0 otherwise). NaN in, NaN out.
 * (fabsf of the argument >= 1 lets the compiler emit the bare square root,
 * without the errno path.)
 */
static inline float p2d_mtpa_id_of_iq_A(float iq_A, float psi_f_Wb, float dL_H)
{
    const float x = 2.0f * dL_H * iq_A;
    const float ax = fabsf(x);
    const float big = ax > psi_f_Wb ? ax : psi_f_Wb;
    const float small = ax > psi_f_Wb ? psi_f_Wb : ax;
    const float q = small / big;
    return iq_A * (x / (psi_f_Wb + big * sqrtf(fabsf(fmaf(q, q, 1.0f)))));
}

/*
 * id [A] of the MTPA point whose current vector has the length i_A [A]:
 *   id = 2 dL i^2 / (psi_f + sqrt(psi_f^2 + 8 dL^2 i^2)),
 * the trajectory above with iq^2 = i^2 - id^2. Used at init for the torque
 * limit; the squares overflow only for |dL| i beyond about 6e18 Wb.
 */
static inline float p2d_mtpa_id_of_norm_A(float i_A, float psi_f_Wb, float dL_H)
{
    return 2.0f * dL_H * i_A * i_A / (psi_f_Wb + sqrtf(psi_f_Wb * psi_f_Wb + 8.0f * dL_H * dL_H * i_A * i_A));
}

#endif /* PMSM2DOF_SRC_MTPA_H */
