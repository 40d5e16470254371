/*
 * pmsm2dof: the online inertia estimator of the C library (pmsm2dof/inertia.h)
 * run by the simulation engine beside the speed controller, and the gain
 * scheduling by the identified J through the bumpless p2d_speed_set_config.
 *
 * Per speed sample k the estimator receives what an MCU has: the speed reading
 * the speed controller samples at t_k and the mean of the electromagnetic
 * torque 1.5 p (psi_f iq + (Ld - Lq) id iq) over the current samples of the
 * speed period that ends at t_k (the currents at the start of each current
 * period). With adapt_gains, whenever the estimate is valid (J_valid) and has
 * moved by more than adapt_rel_change from the J the gains were last designed
 * for, the speed controller is reconfigured with J_kgm2 = the estimate (and,
 * with Ka_follows_J, the default Ka = 1 / (J alpha) of section 3.3) before it
 * computes sample k; a configuration the controller rejects changes nothing.
 * Only at a quiet sample: the reference unchanged since the last sample, the
 * last output inside the current limit and |w_ref - w_meas| <= e_quiet_radps. p2d_speed_set_config keeps the
 * state x = x_i + Fr0 r, so the output does not jump, and at a steady state
 * x is the torque the new design needs there too; in a transient (a
 * reference step, the loop at its limit) the new Fr0 would leave the
 * integrator (Fr0_old - Fr0_new) r away from the new design's trajectory, a
 * disturbance that the loop then takes seconds to unwind.
 */
#ifndef PMSM2DOF_SIM_ADAPT_H
#define PMSM2DOF_SIM_ADAPT_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/inertia.h"
#include "pmsm2dof/speed.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The estimator in the engine: off by default (all zero). */
typedef struct {
    bool enabled;                /* run the estimator on the speed samples */
    bool adapt_gains;            /* re-design the speed controller for the valid estimate of J */
    bool Ka_follows_J;           /* with adapt_gains: Ka = 1 / (J alpha) (the default of section 3.3) */
    double adapt_rel_change;     /* re-design when |J - J_gains| > adapt_rel_change J_gains [-], >= 0 */
    double e_quiet_radps;        /* re-design only while |w_ref - w_meas| <= e_quiet_radps [rad/s], >= 0 */
    p2d_inertia_config_t config; /* estimator configuration; its Ts_s is the speed period */
} p2d_adapt_config_t;

/* State of the estimator in the engine. */
typedef struct {
    p2d_adapt_config_t cfg;   /* configuration */
    p2d_inertia_t est;        /* the estimator of the C library */
    p2d_inertia_output_t out; /* its output of the last speed sample */
    double T_sum_Nm;          /* sum of the torque samples of the present speed period [Nm] */
    uint32_t n_T;             /* number of those samples [-] */
    double J_gains_kgm2;      /* J the speed controller's gains are designed for now [kg m^2] */
    uint32_t n_adapt;         /* re-designs applied [-] */
} p2d_adapt_t;

/* Validate and initialize; J_gains_kgm2 is the J of the speed controller's initial design. */
p2d_status_t p2d_adapt_init(p2d_adapt_t *a, const p2d_adapt_config_t *cfg, double J_gains_kgm2);

/* One current sample of the electromagnetic torque [Nm]. */
void p2d_adapt_torque(p2d_adapt_t *a, double T_e_Nm);

/*
 * Speed sample: step the estimator with the speed reading and the period's mean torque; re-design the gains
 * when quiet: w_ref_radps equals the last reference of the controller, `saturated` (its last output) is false
 * and the speed error is within e_quiet_radps.
 */
void p2d_adapt_sample(p2d_adapt_t *a, double w_meas_radps, double w_ref_radps, bool saturated, p2d_speed_t *speed);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_ADAPT_H */
