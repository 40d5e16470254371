/*
 * Online estimator of J, B and the load torque: the contract and the equations
 * are in pmsm2dof/inertia.h, their derivation in docs/theory/inertia-estimator.md.
 */
#include "pmsm2dof/inertia.h"

#include <math.h>

#include "pi.h"

/* The smallest normal float32, FLT_MIN (<float.h> is not among the headers the library uses). */
#define P2D_FLT_MIN 0x1p-126f

/* Finite and > 0 with x^2 finite and normal: a usable prior variance. */
static bool normal_square(float x) { return p2d_is_positive(x) && isfinite(x * x) && x * x >= P2D_FLT_MIN; }

/* Ts_s / memory_s within [1e-6, 0.5]: a forgetting factor 1 - Ts/memory in [0.5, 1 - 1e-6]. */
static bool memory_valid(float memory_s, float Ts_s)
{
    float r = Ts_s / memory_s;
    return isfinite(memory_s) && r >= 1e-6f && r <= 0.5f;
}

/* x limited to [lo, hi]; a NaN x stays NaN (the caller refuses it). */
static inline float clamp(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

/*
 * The scale s <= 1 that brings a variance P back onto its prior variance sd0^2
 * by the congruence P <- S P S (inertia.h): 1 where P <= sd0^2, else
 * sd0 / sqrt(P) (not sqrt(sd0^2 / P), which is subnormal, and imprecise, when
 * a new configuration lowers the prior by many decades). Returns s, writes 1 / s.
 */
static inline float prior_scale(float P, float sd0, float *inv_s)
{
    float sqrt_P;
    if (P <= sd0 * sd0) {
        *inv_s = 1.0f;
        return 1.0f;
    }
    sqrt_P = p2d_sqrt_nonnegative(P);
    *inv_s = sqrt_P / sd0;
    return sd0 / sqrt_P;
}

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t inertia_coefficients(const p2d_inertia_config_t *cfg, p2d_inertia_coef_t *c)
{
    p2d_inertia_coef_t k;
    float r_J, r_L;

    if (!p2d_is_positive(cfg->Ts_s) || !isfinite(1.0f / cfg->Ts_s)) return P2D_ERR_TS;
    if (!normal_square(cfg->J0_kgm2)) return P2D_ERR_J0;
    if (!p2d_is_positive(cfg->J_min_kgm2) || !(cfg->J_min_kgm2 <= cfg->J0_kgm2)) return P2D_ERR_J_MIN;
    if (!isfinite(cfg->J_max_kgm2) || !(cfg->J_max_kgm2 >= cfg->J0_kgm2)) return P2D_ERR_J_MAX;
    if (!normal_square(cfg->B_max_Nms)) return P2D_ERR_B_MAX;
    if (!normal_square(cfg->T_load_max_Nm)) return P2D_ERR_T_LOAD_MAX;
    if (!normal_square(cfg->sigma_T_Nm)) return P2D_ERR_SIGMA_T;
    if (!memory_valid(cfg->J_memory_s, cfg->Ts_s)) return P2D_ERR_J_MEMORY;
    if (!memory_valid(cfg->load_memory_s, cfg->Ts_s)) return P2D_ERR_LOAD_MEMORY;
    if (!p2d_is_positive(cfg->w_f_radps) || !(cfg->w_f_radps * cfg->Ts_s >= 1e-6f)) return P2D_ERR_W_F;
    if (!p2d_is_positive(cfg->J_rel_sd_max) || !(cfg->J_rel_sd_max < 1.0f)) return P2D_ERR_J_REL_SD_MAX;

    /* backward Euler of w_f / (s + w_f): c_f = w_f Ts / (1 + w_f Ts), written so that w_f Ts = inf gives 1 */
    k.c_f = 1.0f / (1.0f + 1.0f / (cfg->w_f_radps * cfg->Ts_s));
    k.inv_Ts_per_s = 1.0f / cfg->Ts_s;
    k.sigma2_N2m2 = cfg->sigma_T_Nm * cfg->sigma_T_Nm;
    /* white noise of variance sigma^2 through the prefilter: variance sigma^2 c_f / (2 - c_f) */
    k.sigma2_F_N2m2 = k.sigma2_N2m2 * (k.c_f / (2.0f - k.c_f));
    /* the prior, and the bound of the forgetting and of the random walk: P = diag(T_load_max^2, J0^2, B_max^2) */
    k.var0_L_N2m2 = cfg->T_load_max_Nm * cfg->T_load_max_Nm;
    k.var0_J_kg2m4 = cfg->J0_kgm2 * cfg->J0_kgm2;
    k.var0_B_N2m2s2 = cfg->B_max_Nms * cfg->B_max_Nms;
    /* T_load: random walk q = sigma_T^2 (Ts / load_memory)^2, steady-state gain about Ts / load_memory */
    r_L = cfg->Ts_s / cfg->load_memory_s;
    k.q_L_N2m2 = k.sigma2_N2m2 * (r_L * r_L);
    /* J and B: lambda = 1 - Ts / J_memory; the variance grows by g = 1 / lambda per sample */
    r_J = cfg->Ts_s / cfg->J_memory_s;
    k.g_J = 1.0f / (1.0f - r_J);
    k.inv_s_J = 1.0f / p2d_sqrt_nonnegative(k.g_J);
    k.kappa_nis = r_J;
    k.J0_kgm2 = cfg->J0_kgm2;
    k.J_min_kgm2 = cfg->J_min_kgm2;
    k.J_max_kgm2 = cfg->J_max_kgm2;
    k.B_max_Nms = cfg->B_max_Nms;
    k.T_load_max_Nm = cfg->T_load_max_Nm;
    k.J_rel_sd_max = cfg->J_rel_sd_max;
    k.T_prev_weight = cfg->speed_is_period_mean ? 0.5f : 0.0f;
    *c = k;
    return P2D_OK;
}

p2d_status_t p2d_inertia_init(p2d_inertia_t *est, const p2d_inertia_config_t *cfg)
{
    p2d_status_t status;
    if (est == 0 || cfg == 0) return P2D_ERR_NULL;
    status = inertia_coefficients(cfg, &est->coef[0]);
    if (status != P2D_OK) return status;
    /* the shadow set too (computed, not copied: a copy of the set would be a call of memcpy) */
    (void)inertia_coefficients(cfg, &est->coef[1]);
    est->active = 0u;
    est->config = *cfg;
    est->fault_count = 0u;
    p2d_inertia_reset(est, false);
    return P2D_OK;
}

/* The shadow swap of pi.h. */
p2d_status_t p2d_inertia_set_config(p2d_inertia_t *est, const p2d_inertia_config_t *cfg)
{
    p2d_status_t status;
    uint32_t inactive;
    if (est == 0 || cfg == 0) return P2D_ERR_NULL;
    inactive = p2d_shadow_inactive(est->active);
    status = inertia_coefficients(cfg, &est->coef[inactive]);
    if (status != P2D_OK) return status;
    est->config = *cfg;
    p2d_shadow_activate(&est->active, inactive);
    return P2D_OK;
}

void p2d_inertia_reset(p2d_inertia_t *est, bool keep_estimate)
{
    const p2d_inertia_coef_t *c = &est->coef[est->active];
    est->primed = false;
    if (keep_estimate) return;
    /* the prior: theta = [0, J0, 0], P = diag(T_load_max^2, J0^2, B_max^2) */
    est->T_load_Nm = 0.0f;
    est->J_kgm2 = est->config.J0_kgm2;
    est->B_Nms = 0.0f;
    est->U_LJ_per_s2 = 0.0f;
    est->U_LB_per_s = 0.0f;
    est->U_JB_s = 0.0f;
    est->D_L_N2m2 = c->var0_L_N2m2;
    est->D_J_kg2m4 = c->var0_J_kg2m4;
    est->D_B_N2m2s2 = c->var0_B_N2m2s2;
    est->wF_radps = 0.0f;
    est->w0_radps = 0.0f;
    est->TF_Nm = 0.0f;
    est->oneF = 0.0f;
    est->T_prev_Nm = 0.0f;
    est->nis = 1.0f;
}

/* The output of the state's estimate, limited to the plausible box of the active configuration. */
static void hold_output(const p2d_inertia_t *est, const p2d_inertia_coef_t *c, p2d_inertia_output_t *out)
{
    const float J = est->J_kgm2;
    /* P_JJ = D_J + U_JB^2 D_B, as (U_JB D_B) U_JB (see the step) */
    float P_J = fmaf(est->U_JB_s * est->D_B_N2m2s2, est->U_JB_s, est->D_J_kg2m4);
    out->J_kgm2 = clamp(J, c->J_min_kgm2, c->J_max_kgm2);
    /* sd(J) = sqrt(P_JJ max(1, nis)) */
    out->J_sd_kgm2 = p2d_sqrt_nonnegative(P_J * (est->nis > 1.0f ? est->nis : 1.0f));
    out->B_Nms = clamp(est->B_Nms, 0.0f, c->B_max_Nms);
    out->T_load_Nm = clamp(est->T_load_Nm, -c->T_load_max_Nm, c->T_load_max_Nm);
    out->residual_Nm = 0.0f;
    out->residual_sd_Nm = 0.0f;
    out->J_valid = out->J_sd_kgm2 <= c->J_rel_sd_max * J && J > c->J_min_kgm2 && J < c->J_max_kgm2;
    out->updated = false;
    out->fault = false;
}

/* Non-finite policy: the estimate held, J_valid false, the prefilter restarts at the next sample, the fault counted. */
static void fault_output(p2d_inertia_t *est, const p2d_inertia_coef_t *c, p2d_inertia_output_t *out)
{
    est->fault_count++;
    est->primed = false;
    hold_output(est, c, out);
    out->J_valid = false;
    out->fault = true;
}

void p2d_inertia_step(p2d_inertia_t *est, float w_m_radps, float T_e_Nm, p2d_inertia_output_t *out)
{
    const p2d_inertia_coef_t *c = &est->coef[est->active];
    float T_in, dwF, wF, TF, oneF, phi_J, phi_B, eps, P_L, P_J, s_L, s_J, s_B, is_L, is_J, is_B;
    float U_LJ, U_LB, U_JB, D_L, D_J, D_B;
    float f_J, f_B, v_L, v_J, v_B, a_L, a_J, alpha, inv_a_L, inv_a_J, inv_alpha, b_L, b_J, e_n, phi_P_phi;
    float T_load, J, B, nis, var_J, residual_sd;

    if (!isfinite(w_m_radps) || !isfinite(T_e_Nm)) {
        fault_output(est, c, out);
        return;
    }
    if (!est->primed) {
        /* the first sample: the prefilter starts from rest, wF = w0 = w, TF = 1F = 0 */
        est->wF_radps = w_m_radps;
        est->w0_radps = w_m_radps;
        est->TF_Nm = 0.0f;
        est->oneF = 0.0f;
        est->T_prev_Nm = T_e_Nm;
        est->primed = true;
        hold_output(est, c, out);
        return;
    }

    /* the regression (inertia.h): T_in[k] = T[k] + T_prev_weight (T[k-1] - T[k]) = (T[k] + T[k-1]) / 2 or T[k] */
    T_in = fmaf(c->T_prev_weight, est->T_prev_Nm - T_e_Nm, T_e_Nm);
    /* dwF[k] = c_f (w[k] - wF[k-1]) */
    dwF = c->c_f * (w_m_radps - est->wF_radps);
    /* wF[k] = wF[k-1] + dwF[k] */
    wF = est->wF_radps + dwF;
    /* y[k] = TF[k] = TF[k-1] + c_f (T_in[k] - TF[k-1]) */
    TF = fmaf(c->c_f, T_in - est->TF_Nm, est->TF_Nm);
    /* phi_L = 1F[k] = 1F[k-1] + c_f (1 - 1F[k-1]) */
    oneF = fmaf(c->c_f, 1.0f - est->oneF, est->oneF);
    /* phi_J = dwF[k] / Ts */
    phi_J = dwF * c->inv_Ts_per_s;
    /* phi_B = (wF[k] + wF[k-1]) / 2 - w0 (1 - 1F[k]) */
    phi_B = fmaf(-est->w0_radps, 1.0f - oneF, fmaf(0.5f, dwF, est->wF_radps));
    /* eps = y - phi' theta = TF - (J phi_J + B phi_B + T_load 1F) */
    eps = TF - fmaf(est->J_kgm2, phi_J, fmaf(est->B_Nms, phi_B, est->T_load_Nm * oneF));

    /*
     * Time update P <- S P S + q e_L e_L', S = diag(1, s, s), s^2 = g = 1 / lambda_J: J and B forgotten, T_load a
     * random walk; U_ij <- s_i U_ij / s_j (i < j), D_j <- s_j^2 D_j, and D_L + q (U e_L = e_L)
     */
    U_LJ = est->U_LJ_per_s2 * c->inv_s_J;
    U_LB = est->U_LB_per_s * c->inv_s_J;
    U_JB = est->U_JB_s;
    D_L = est->D_L_N2m2 + c->q_L_N2m2;
    D_J = est->D_J_kg2m4 * c->g_J;
    D_B = est->D_B_N2m2s2 * c->g_J;

    /* Bierman's update of U D U' by the scalar measurement y = phi' theta + e, var(e) = sigma^2 */
    /* f = U' phi (f_L = phi_L = 1F), v = D f */
    f_J = fmaf(U_LJ, oneF, phi_J);
    f_B = fmaf(U_LB, oneF, fmaf(U_JB, phi_J, phi_B));
    v_L = D_L * oneF;
    v_J = D_J * f_J;
    v_B = D_B * f_B;
    /* a_L = sigma^2 + f_L v_L;  D_L <- D_L sigma^2 / a_L;  b_L = v_L */
    a_L = fmaf(oneF, v_L, c->sigma2_N2m2);
    inv_a_L = 1.0f / a_L;
    D_L = D_L * (c->sigma2_N2m2 * inv_a_L);
    b_L = v_L;
    /* a_J = a_L + f_J v_J;  D_J <- D_J a_L / a_J;  U_LJ <- U_LJ - b_L f_J / a_L;  b_L <- b_L + U_LJ v_J (old U_LJ) */
    a_J = fmaf(f_J, v_J, a_L);
    inv_a_J = 1.0f / a_J;
    D_J = D_J * (a_L * inv_a_J);
    {
        float U_old = U_LJ;
        U_LJ = fmaf(-b_L, f_J * inv_a_L, U_old);
        b_L = fmaf(U_old, v_J, b_L);
    }
    b_J = v_J;
    /* alpha = a_J + f_B v_B = phi' P phi + sigma^2;  D_B <- D_B a_J / alpha */
    alpha = fmaf(f_B, v_B, a_J);
    inv_alpha = 1.0f / alpha;
    D_B = D_B * (a_J * inv_alpha);
    {
        /* U_iB <- U_iB - b_i f_B / a_J;  b_i <- b_i + U_iB v_B (old U_iB), i = T_load, J */
        float U_LB_old = U_LB, U_JB_old = U_JB;
        U_LB = fmaf(-b_L, f_B * inv_a_J, U_LB_old);
        b_L = fmaf(U_LB_old, v_B, b_L);
        U_JB = fmaf(-b_J, f_B * inv_a_J, U_JB_old);
        b_J = fmaf(U_JB_old, v_B, b_J);
    }
    /* theta <- theta + K eps, K = b / alpha (b_B = v_B) */
    e_n = eps * inv_alpha;
    T_load = fmaf(b_L, e_n, est->T_load_Nm);
    J = fmaf(b_J, e_n, est->J_kgm2);
    B = fmaf(v_B, e_n, est->B_Nms);
    /* nis <- nis + kappa (eps^2 / (phi' P phi + sigma_F^2) - nis), phi' P phi = f' D f */
    phi_P_phi = fmaf(oneF, v_L, fmaf(f_J, v_J, f_B * v_B));
    nis = fmaf(c->kappa_nis, eps * eps / (phi_P_phi + c->sigma2_F_N2m2) - est->nis, est->nis);
    /*
     * No windup: a variance above its prior (a parameter without excitation, which the forgetting or the walk
     * grew; or the rounding of an ill-conditioned update) goes back onto it by P <- S P S, s_i = sqrt(var0 / P_ii);
     * P_LL = D_L + U_LJ^2 D_J + U_LB^2 D_B, P_JJ = D_J + U_JB^2 D_B, P_BB = D_B. Each term U^2 D is computed as
     * (U D) U: U^2 alone underflows or overflows for extreme ratios of the variances, U D never does (|U D| < D
     * for |U| < 1, |U D| <= U^2 D for |U| >= 1).
     */
    P_L = fmaf(U_LJ * D_J, U_LJ, fmaf(U_LB * D_B, U_LB, D_L));
    P_J = fmaf(U_JB * D_B, U_JB, D_J);
    if (P_L > c->var0_L_N2m2 || P_J > c->var0_J_kg2m4 || D_B > c->var0_B_N2m2s2) {
        s_L = prior_scale(P_L, c->T_load_max_Nm, &is_L);
        s_J = prior_scale(P_J, c->J0_kgm2, &is_J);
        s_B = prior_scale(D_B, c->B_max_Nms, &is_B);
        /* U_ij <- s_i U_ij / s_j (i < j), D_j <- s_j^2 D_j (as (D s) s: s^2 alone can be subnormal) */
        U_LJ = U_LJ * s_L * is_J;
        U_LB = U_LB * s_L * is_B;
        U_JB = U_JB * s_J * is_B;
        D_L = D_L * s_L * s_L;
        D_J = D_J * s_J * s_J;
        D_B = D_B * s_B * s_B;
    }
    /* sqrt(alpha): the predicted spread of eps */
    residual_sd = p2d_sqrt_nonnegative(alpha);
    /* var(J) = P_JJ max(1, nis) with the updated P, the square of the output sd(J) */
    var_J = fmaf(U_JB * D_B, U_JB, D_J) * (nis > 1.0f ? nis : 1.0f);

    /* non-finite policy: an update that overflows, or leaves D outside the normal range, is refused */
    if (!isfinite(wF) || !isfinite(TF) || !isfinite(J) || !isfinite(B) || !isfinite(T_load) || !isfinite(U_LJ) ||
        !isfinite(U_LB) || !isfinite(U_JB) || !(D_L >= P2D_FLT_MIN && D_L < INFINITY) ||
        !(D_J >= P2D_FLT_MIN && D_J < INFINITY) || !(D_B >= P2D_FLT_MIN && D_B < INFINITY) || !isfinite(nis) ||
        !isfinite(var_J) || !isfinite(eps) || !isfinite(residual_sd)) {
        fault_output(est, c, out);
        return;
    }
    est->T_load_Nm = T_load;
    est->J_kgm2 = J;
    est->B_Nms = B;
    est->U_LJ_per_s2 = U_LJ;
    est->U_LB_per_s = U_LB;
    est->U_JB_s = U_JB;
    est->D_L_N2m2 = D_L;
    est->D_J_kg2m4 = D_J;
    est->D_B_N2m2s2 = D_B;
    est->wF_radps = wF;
    est->TF_Nm = TF;
    est->oneF = oneF;
    est->T_prev_Nm = T_e_Nm;
    est->nis = nis;

    hold_output(est, c, out);
    out->residual_Nm = eps;
    out->residual_sd_Nm = residual_sd;
    out->updated = true;
}
