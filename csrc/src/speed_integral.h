/*
 * Internal (not installed, not part of the API): the integral of the float32 speed controller's PI
 * (pmsm2dof/speed.h) as a static inline function. speed.c builds p2d_speed_integrator_Nm of it; the
 * host's simulation engine (csrc/sim/drive.c) inlines it into its log row, with no call.
 */
#ifndef PMSM2DOF_SRC_SPEED_INTEGRAL_H
#define PMSM2DOF_SRC_SPEED_INTEGRAL_H

#include <math.h>

#include "pmsm2dof/speed.h"

/* x_i[k-1] = x[k-1] - Fr0 r[k-1] [Nm] */
static inline float p2d_speed_integral_Nm(const p2d_speed_t *ctl)
{
    return fmaf(-ctl->coef[ctl->active].ff_Fr0, ctl->r_prev_radps, ctl->x_Nm);
}

#endif /* PMSM2DOF_SRC_SPEED_INTEGRAL_H */
