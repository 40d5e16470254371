/*
 * Two-mass drive train of the simulation engine: see drive.h for the model.
 */
#include "mechanics.h"

#include <math.h>

static bool is_positive(double x) { return isfinite(x) && x > 0.0; }
static bool is_nonnegative(double x) { return isfinite(x) && x >= 0.0; }

p2d_sim_status_t p2d_mechanics_check(const p2d_mechanics_config_t *cfg)
{
    if ((unsigned)cfg->model > (unsigned)P2D_MECHANICS_TWO_MASS) return P2D_SIM_ERR_MECHANICS_MODEL;
    if ((unsigned)cfg->feedback > (unsigned)P2D_FEEDBACK_LOAD) return P2D_SIM_ERR_FEEDBACK;
    if (cfg->model == P2D_MECHANICS_RIGID) return P2D_SIM_OK;
    if (!is_positive(cfg->J_load_kgm2)) return P2D_SIM_ERR_J_LOAD;
    if (!is_positive(cfg->stiffness_Nm_per_rad)) return P2D_SIM_ERR_STIFFNESS;
    if (!is_nonnegative(cfg->damping_Nms_per_rad)) return P2D_SIM_ERR_DAMPING;
    if (!is_nonnegative(cfg->backlash_rad)) return P2D_SIM_ERR_BACKLASH;
    return P2D_SIM_OK;
}

void p2d_mechanics_init(p2d_mechanics_t *mech, const p2d_mechanics_config_t *cfg, double w_m0_radps)
{
    bool two_mass = cfg->model == P2D_MECHANICS_TWO_MASS;
    mech->inv_J_load_per_kgm2 = two_mass ? 1.0 / cfg->J_load_kgm2 : 0.0;
    mech->K_Nm_per_rad = two_mass ? cfg->stiffness_Nm_per_rad : 0.0;
    mech->D_Nms_per_rad = two_mass ? cfg->damping_Nms_per_rad : 0.0;
    mech->half_backlash_rad = two_mass ? 0.5 * cfg->backlash_rad : 0.0;
    mech->theta_rad = 0.0;
    mech->w_load_radps = w_m0_radps;
}

double p2d_shaft_torque_Nm(const p2d_mechanics_t *mech, double theta_rad, double w_twist_radps)
{
    double b_half = mech->half_backlash_rad;
    /* in the play |theta| < b/2 the shaft carries nothing */
    if (fabs(theta_rad) < b_half) return 0.0;
    /* T_s = K (theta - sign(theta) b/2) + D (w_m - w_L) */
    return mech->K_Nm_per_rad * (theta_rad - copysign(b_half, theta_rad)) + mech->D_Nms_per_rad * w_twist_radps;
}
