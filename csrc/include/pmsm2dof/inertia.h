/*
 * pmsm2dof: online estimator of the inertia J, the viscous friction B and the
 * load torque T_load of the drive, on the samples of the speed loop, for the
 * MCU (float32, no allocation, no global state). Its J feeds the gains of eq 9
 * (Kp = J alpha, Ki = J (alpha / (2 zeta))^2) through p2d_speed_set_config.
 * The derivation and the choices are in docs/theory/inertia-estimator.md.
 *
 * Model (rigid shaft): J dw/dt = T_e - B w - T_load, T_load the load torque
 * including Coulomb friction, slowly varying. Over one speed period Ts, with
 * T[k] the mean torque over the period that ends at sample k:
 *   J (w[k] - w[k-1]) = Ts T[k] - Ts B (w[k] + w[k-1]) / 2 - Ts T_load
 * (exact for the mean torque; the trapezoid for the friction). A speed that is
 * itself the mean over the period (encoder counts differenced over Ts)
 * changes by the torque of the two periods, T_in[k] = (T[k] + T[k-1]) / 2
 * (config speed_is_period_mean); otherwise T_in[k] = T[k].
 *
 * Prefilter: both sides pass through the same lowpass F(s) = w_f / (s + w_f),
 * by backward Euler (Table 1), c_f = w_f Ts / (1 + w_f Ts), xF = F(z) x:
 *   xF[k] = xF[k-1] + c_f (x[k] - xF[k-1]),   xF[0] = 0
 * F is linear with F(1) = 1, and starts from rest at the first sample (the
 * relation holds from the second on), so the filtered sequences obey the same
 * relation exactly, with the constant filtered too, while the quantization
 * noise of a differenced speed is cut above w_f. With w0 = w[0] and
 * wF = w0 + F(z) (w - w0), the regression y = phi' theta + e is
 *   dwF[k] = c_f (w[k] - wF[k-1]) = F(z) (w[k] - w[k-1])   [rad/s]
 *   1F[k]  = F(z) 1 = 1 - (1 - c_f)^k                       [-]
 *   phi[k] = [dwF[k] / Ts, (wF[k] + wF[k-1]) / 2 - w0 (1 - 1F[k]), 1F[k]]
 *   y[k]   = TF[k] = F(z) T_in[k]                           [Nm]
 *   theta  = [J_kgm2, B_Nms, T_load_Nm]
 * (phi_B is F(z) (w[k] + w[k-1]) / 2). A start of the filter at w and T
 * instead of at rest would add (1 - c_f)^k (T[0] - B w0 - T_load) to the
 * residual: the net torque at the start, a bias that weakly excited B and
 * T_load keep for long.
 *
 * Recursive least squares (a Kalman filter) of theta, in the order
 * [T_load, J, B], with
 *  - the covariance P = U D U' kept as a unit upper triangular U and a
 *    positive diagonal D, updated by Bierman's algorithm (G. J. Bierman,
 *    "Factorization Methods for Discrete Sequential Estimation", 1977, ch. V):
 *    P stays positive definite by construction in float32;
 *  - a time update before each measurement, P <- S P S + q e_L e_L',
 *    S = diag(1, s, s): J and B forgotten exponentially (memory J_memory_s),
 *    s^2 = 1 / lambda, lambda = 1 - Ts / J_memory_s; T_load a random walk,
 *    q = sigma_T^2 (Ts / load_memory_s)^2, so that at steady state the gain of
 *    T_load is about Ts / load_memory_s: the estimate follows a load step with
 *    a time constant of about load_memory_s. T_load comes first so that the
 *    walk is D_L += q (the first column of U is e_L). Forgetting T_load by the
 *    congruence of J and B instead would keep its correlation with B, and with
 *    it an error of B that the data hardly correct;
 *  - no covariance windup: after each update a variance P_ii above its prior
 *    variance (grown by the forgetting or the walk without excitation, or by
 *    the rounding of an update of nearly collinear parameters) is brought back
 *    onto it by the congruence P <- S P S, s_i^2 = prior_ii / P_ii, which keeps
 *    U D U' positive definite. So every variance stays within its prior, the
 *    estimate is held without excitation, and a lower prior of a new
 *    configuration applies from the next update;
 *  - the prior theta = [0, J0, 0], P = diag(T_load_max^2, J0^2, B_max^2).
 * With eps = y - phi' theta and alpha = phi' P phi + sigma_T^2:
 *   K = P phi / alpha,  theta <- theta + K eps,  P <- P - K phi' P
 * sigma_T_Nm is the standard deviation of the white noise of the torque input
 * sample to sample (kt times the current noise). The prefilter turns it into
 * a noise of variance sigma_F^2 = sigma_T^2 c_f / (2 - c_f), correlated over
 * about 2 / c_f samples: weighting the filtered samples by sigma_T^2 instead of
 * sigma_F^2 counts them as the independent samples they amount to.
 * The outputs are limited to the plausible box J_min_kgm2 <= J <= J_max_kgm2,
 * 0 <= B <= B_max_Nms, |T_load| <= T_load_max_Nm; the estimate in the state
 * is not (a coordinate held at a bound while P does not know it makes the
 * correlated ones run away when the regressors are nearly collinear, as in a
 * constant acceleration), and J is valid only strictly inside its bounds.
 *
 * Excitation: J is reported (J_valid) once its standard deviation,
 * sqrt(P_JJ max(1, nis)), is below J_rel_sd_max J and J is strictly inside
 * its bounds. nis is the mean over J_memory_s of eps^2 / (phi' P phi + sigma_F^2),
 * about 1 when the residual is the torque noise of sigma_T_Nm and larger when
 * it is not (sigma_T_Nm set too small, speed noise, model error): then sd(J)
 * grows with it, and J does not look better known than the data show. Without
 * acceleration P_JJ grows by 1 / lambda_J per sample: J_valid falls after about
 * J_memory_s ln((J_rel_sd_max J / sd(J))^2), and P_JJ stops at J0^2. The spread
 * does not include the bias of the quantization noise of an encoder in the
 * acceleration (J reads low by about var(noise) / var(acceleration) of the
 * filtered signals; a lower w_f_radps for a coarser encoder).
 *
 * Non-finite policy: a NaN or infinite input, or an update whose new state
 * would not be finite (or a D that leaves the normal float32 range), changes
 * nothing but fault_count and a restart of the prefilter at the next sample
 * (so that no regression pairs a speed change and a torque of different
 * periods); the output holds the last estimate with J_valid false and fault
 * set.
 *
 * Parameter updates: p2d_inertia_set_config validates into the inactive of two
 * coefficient sets and swaps with one aligned 32-bit store; the state (in
 * physical units) is kept; on an invalid configuration nothing changes.
 *
 * Inputs per speed sample: the measured speed and the mean electromagnetic
 * torque over the period that ends at this sample, best the mean of
 * 1.5 p (psi_f iq + (Ld - Lq) id iq) over the current-loop samples of the
 * period; the torque command of the previous speed sample is a fair substitute
 * where the current loop is much faster than Ts.
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_INERTIA_H
#define PMSM2DOF_INERTIA_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Configuration of the estimator. */
typedef struct {
    float Ts_s;          /* speed-loop sampling period [s], > 0 */
    float J0_kgm2;       /* initial J, and the prior standard deviation of J [kg m^2], > 0 */
    float J_min_kgm2;    /* smallest plausible J: the estimate stays >= it [kg m^2], in (0, J0_kgm2] */
    float J_max_kgm2;    /* largest plausible J: the estimate stays <= it [kg m^2], > 0, >= J0_kgm2 */
    float B_max_Nms;     /* largest plausible viscous friction, prior sd of B [Nm s/rad], > 0 */
    float T_load_max_Nm; /* largest plausible |T_load| (e.g. the peak torque), prior sd of T_load [Nm], > 0 */
    float sigma_T_Nm;    /* standard deviation of the white noise of the torque input [Nm], > 0 */
    float J_memory_s;    /* memory of J and B [s], > 0, >= 2 Ts_s, <= 1e6 Ts_s (forgetting: 1 - Ts_s/J_memory_s) */
    float load_memory_s; /* time constant of the T_load estimate after a step [s], > 0, >= 2 Ts_s, <= 1e6 Ts_s */
    float w_f_radps;     /* bandwidth of the prefilter of speed and torque [rad/s], > 0 */
    float J_rel_sd_max;  /* J_valid once sd(J) <= J_rel_sd_max J [-], in (0, 1) */
    bool speed_is_period_mean; /* the speed input is the mean over the period (counts differenced over Ts) */
} p2d_inertia_config_t;

/* Precomputed coefficients: everything the step needs for one Ts. */
typedef struct {
    float c_f;           /* prefilter gain w_f Ts / (1 + w_f Ts) (backward Euler) [-] */
    float T_prev_weight; /* weight of T[k-1] in T_in: 1/2 for a period-mean speed, else 0 [-] */
    float inv_Ts_per_s;  /* 1 / Ts [1/s] */
    float sigma2_N2m2;   /* sigma_T^2, the measurement variance of the update [Nm^2] */
    float sigma2_F_N2m2; /* sigma_T^2 c_f / (2 - c_f): white noise of variance sigma_T^2 after the prefilter [Nm^2] */
    float var0_L_N2m2;   /* prior variance of T_load, T_load_max^2 [Nm^2] */
    float var0_J_kg2m4;  /* prior variance of J, J0^2 [kg^2 m^4] */
    float var0_B_N2m2s2; /* prior variance of B, B_max^2 [(Nm s/rad)^2] */
    float q_L_N2m2;      /* random walk of T_load per sample, sigma_T^2 (Ts / load_memory)^2 [Nm^2] */
    float g_J;           /* variance growth per sample of J and B, 1 / lambda_J [-] */
    float inv_s_J;       /* 1 / sqrt(g_J): 1 / s of J and B in the forgetting P <- S P S [-] */
    float kappa_nis;     /* weight of one sample in the mean nis, Ts / J_memory [-] */
    float J0_kgm2;       /* prior standard deviation of J [kg m^2] */
    float J_min_kgm2;    /* lower bound of J [kg m^2] */
    float J_max_kgm2;    /* upper bound of J [kg m^2] */
    float B_max_Nms;     /* upper bound of B, and its prior standard deviation [Nm s/rad] */
    float T_load_max_Nm; /* bound of |T_load|, and its prior standard deviation [Nm] */
    float J_rel_sd_max;  /* validity threshold of sd(J) / J [-] */
} p2d_inertia_coef_t;

typedef struct {
    p2d_inertia_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;             /* index of the active set, 0 or 1 */
    p2d_inertia_config_t config; /* configuration of the active set */
    float J_kgm2;                /* estimate of J [kg m^2] */
    float B_Nms;                 /* estimate of B [Nm s/rad] */
    float T_load_Nm;             /* estimate of T_load [Nm] */
    float U_LJ_per_s2;           /* P = U D U', U unit upper triangular: element (T_load, J) [Nm / (kg m^2) = 1/s^2] */
    float U_LB_per_s;            /* element (T_load, B) [Nm / (Nm s/rad) = 1/s] */
    float U_JB_s;                /* element (J, B) [kg m^2 / (Nm s/rad) = s] */
    float D_L_N2m2;              /* D, element T_load [Nm^2], > 0 */
    float D_J_kg2m4;             /* D, element J [kg^2 m^4], > 0 */
    float D_B_N2m2s2;            /* D, element B [(Nm s/rad)^2], > 0 */
    float wF_radps;              /* prefiltered speed wF[k-1] = w0 + F(z) (w - w0) [rad/s] */
    float w0_radps;              /* speed at the start of the prefilter w0 [rad/s] */
    float TF_Nm;                 /* prefiltered torque TF[k-1] [Nm] */
    float oneF;                  /* prefiltered constant 1F[k-1] [-] */
    float T_prev_Nm;             /* torque input of the previous sample T[k-1] [Nm] */
    float nis;                   /* mean of eps^2 / (phi' P phi + sigma_F^2) over J_memory_s [-], 1 at reset */
    bool primed;                 /* the prefilter holds a sample */
    uint32_t fault_count;        /* samples rejected by the non-finite policy [-] */
} p2d_inertia_t;

/* Result of one step. */
typedef struct {
    float J_kgm2;         /* estimate of J after this sample, within [J_min_kgm2, J_max_kgm2] [kg m^2] */
    float J_sd_kgm2;      /* its standard deviation sqrt(P_JJ max(1, nis)) [kg m^2] */
    float B_Nms;          /* estimate of B, within [0, B_max_Nms] [Nm s/rad] */
    float T_load_Nm;      /* estimate of T_load, within [-T_load_max_Nm, T_load_max_Nm] [Nm] */
    float residual_Nm;    /* prediction error eps of the filtered torque before the update [Nm]; 0 if not updated */
    float residual_sd_Nm; /* its predicted standard deviation sqrt(alpha) [Nm]; 0 if not updated */
    bool J_valid;         /* sd(J) <= J_rel_sd_max J and J strictly inside [J_min, J_max]; false on a fault */
    bool updated;         /* this sample updated the estimate (false while the prefilter primes, and on a fault) */
    bool fault;           /* non-finite policy engaged: the estimate is held */
} p2d_inertia_output_t;

/* Validate cfg and precompute; on error est is left unchanged. Resets the estimate to the prior. */
p2d_status_t p2d_inertia_init(p2d_inertia_t *est, const p2d_inertia_config_t *cfg);

/* Validate cfg into the shadow set and swap it in; the state is kept. On error nothing changes. */
p2d_status_t p2d_inertia_set_config(p2d_inertia_t *est, const p2d_inertia_config_t *cfg);

/*
 * Restart the prefilter at the next sample (after a gap in the samples, or
 * with the drive disabled); with keep_estimate false also return the estimate
 * and its covariance to the prior of the active configuration.
 */
void p2d_inertia_reset(p2d_inertia_t *est, bool keep_estimate);

/* One speed sample: w_m_radps at this sample, T_e_Nm the mean torque over the period that ends at it. */
void p2d_inertia_step(p2d_inertia_t *est, float w_m_radps, float T_e_Nm, p2d_inertia_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_INERTIA_H */
