/*
 * pmsm2dof: the two-mass drive train of the simulation engine (drive.h has
 * the model): validation of its parameters, its initial state and the shaft
 * torque of the dead-zone shaft.
 */
#ifndef PMSM2DOF_SIM_MECHANICS_H
#define PMSM2DOF_SIM_MECHANICS_H

#include "drive.h"

#ifdef __cplusplus
extern "C" {
#endif

/* P2D_SIM_OK, or the code of the first field of cfg out of its range (drive.h). */
p2d_sim_status_t p2d_mechanics_check(const p2d_mechanics_config_t *cfg);

/* Precompute the coefficients of a checked cfg; no twist, the load side at w_m0_radps. */
void p2d_mechanics_init(p2d_mechanics_t *mech, const p2d_mechanics_config_t *cfg, double w_m0_radps);

/*
 * Shaft torque T_s [Nm] at the twist theta_rad and the twist rate w_twist_radps = w_m - w_L:
 * K (theta - sign(theta) b/2) + D w_twist in contact (|theta| >= b/2), 0 in the play.
 */
double p2d_shaft_torque_Nm(const p2d_mechanics_t *mech, double theta_rad, double w_twist_radps);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_MECHANICS_H */
