/* pmsm2dof: the inertia estimator beside the speed controller in the engine (adapt.h). */
#include "adapt.h"

#include <math.h>

p2d_status_t p2d_adapt_init(p2d_adapt_t *a, const p2d_adapt_config_t *cfg, double J_gains_kgm2)
{
    p2d_status_t status;
    a->cfg = *cfg;
    a->T_sum_Nm = 0.0;
    a->n_T = 0u;
    a->J_gains_kgm2 = J_gains_kgm2;
    a->n_adapt = 0u;
    a->out = (p2d_inertia_output_t){0};
    if (!cfg->enabled) return P2D_OK;
    status = p2d_inertia_init(&a->est, &cfg->config);
    a->out.J_kgm2 = cfg->config.J0_kgm2;
    return status;
}

void p2d_adapt_torque(p2d_adapt_t *a, double T_e_Nm)
{
    a->T_sum_Nm += T_e_Nm;
    a->n_T++;
}

void p2d_adapt_sample(p2d_adapt_t *a, double w_meas_radps, double w_ref_radps, bool saturated, p2d_speed_t *speed)
{
    double J_kgm2;
    /* the first speed sample has no period behind it: the estimator starts at the second */
    if (!a->cfg.enabled || a->n_T == 0u) return;
    /* T[k] = the mean of the torque samples of the period that ends at t_k */
    p2d_inertia_step(&a->est, (float)w_meas_radps, (float)(a->T_sum_Nm / (double)a->n_T), &a->out);
    a->T_sum_Nm = 0.0;
    a->n_T = 0u;
    if (!a->cfg.adapt_gains || !a->out.J_valid || saturated || (float)w_ref_radps != speed->r_prev_radps ||
        !(fabs(w_ref_radps - w_meas_radps) <= a->cfg.e_quiet_radps))
        return;
    J_kgm2 = (double)a->out.J_kgm2;
    if (fabs(J_kgm2 - a->J_gains_kgm2) > a->cfg.adapt_rel_change * a->J_gains_kgm2) {
        p2d_speed_config_t c = speed->config;
        c.J_kgm2 = (float)J_kgm2;
        if (a->cfg.Ka_follows_J) c.Ka = p2d_speed_Ka_default(c.J_kgm2, c.alpha_radps);
        if (p2d_speed_set_config(speed, &c) == P2D_OK) {
            a->J_gains_kgm2 = J_kgm2;
            a->n_adapt++;
        }
    }
}
