/*
 * 2DOF PI speed controller with anti-windup: the contract and the equations
 * are in pmsm2dof/speed.h, their derivation in docs/theory/speed-controller.md.
 */
#include "pmsm2dof/speed.h"

#include <math.h>

#include "biquad.h"
#include "mtpa.h"
#include "pi.h"
#include "speed_integral.h"

/* Newton iterations of the MTPA torque-to-current inversion (salient PMSM). */
#define P2D_MTPA_NEWTON_ITERATIONS 5

/*
 * Validate cfg with the torque filters fcfg and compute their coefficients into *c and *f.
 * They are written only on success.
 */
static p2d_status_t speed_coefficients(const p2d_speed_config_t *cfg, const p2d_filter_config_t *fcfg,
                                       p2d_speed_coef_t *c, p2d_filter_coef_t *f)
{
    p2d_speed_coef_t k;
    p2d_filter_coef_t filter;
    p2d_status_t status;
    float Kp, Ki, m_eff, tau_eff, p_radps, c_ff, b_dr, a1, A, B, r;

    if (!p2d_is_positive(cfg->J_kgm2)) return P2D_ERR_J;
    if (!p2d_is_positive(cfg->alpha_radps)) return P2D_ERR_ALPHA;
    if (!p2d_is_positive(cfg->zeta)) return P2D_ERR_ZETA;
    if (!p2d_is_positive(cfg->m)) return P2D_ERR_M;
    if (!p2d_is_nonnegative(cfg->tau_i_s)) return P2D_ERR_TAU_I;
    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (!p2d_is_positive(cfg->i_max_A)) return P2D_ERR_I_MAX;
    if (!p2d_is_positive(cfg->psi_f_Wb)) return P2D_ERR_PSI_F;
    if (!p2d_is_positive(cfg->Ld_H)) return P2D_ERR_LD;
    if (!p2d_is_positive(cfg->Lq_H)) return P2D_ERR_LQ;
    if (cfg->pole_pairs < 1u) return P2D_ERR_POLE_PAIRS;
    if ((unsigned)cfg->method > (unsigned)P2D_TUSTIN) return P2D_ERR_METHOD;
    if ((unsigned)cfg->feedforward > (unsigned)P2D_FF_FULL) return P2D_ERR_FEEDFORWARD;
    if ((unsigned)cfg->anti_windup > (unsigned)P2D_AW_CLAMPING) return P2D_ERR_ANTI_WINDUP;
    if (cfg->feedforward == P2D_FF_LOWPASS && cfg->m != 1.0f) return P2D_ERR_M_LOWPASS;

    /* eq 9: Kp = J alpha, Ki = J (alpha / (2 zeta))^2 */
    Kp = cfg->J_kgm2 * cfg->alpha_radps;
    Ki = cfg->J_kgm2 * (cfg->alpha_radps / (2.0f * cfg->zeta)) * (cfg->alpha_radps / (2.0f * cfg->zeta));
    /* gains outside the normal float32 range (overflow, or underflow that makes Ka = 1/Kp infinite) */
    if (!isnormal(Kp) || !isnormal(Ki) || !isfinite(1.0f / Kp)) return P2D_ERR_J;
    /* eq 14 and Table 1 */
    k.pi = p2d_pi_coefficients(Kp, Ki, cfg->Ts_s, cfg->method);
    k.clamping = cfg->anti_windup == P2D_AW_CLAMPING;
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        /* the discrete back-calculation loop x[k] = (1 - Ki Ka Ts) x[k-1] + ... must be stable */
        if (!p2d_is_nonnegative(cfg->Ka) || !(Ki * cfg->Ka * cfg->Ts_s < 2.0f)) return P2D_ERR_KA;
        k.pi.Ki_Ka_Ts = Ki * cfg->Ka * cfg->Ts_s;
    } else if (!p2d_is_nonnegative(cfg->Ka)) {
        return P2D_ERR_KA;
    }

    /*
     * eq 11: Fr = J alpha (m tau s^2 + (m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)
     *           = Kd s + D + c_ff / (s + p),  p = m alpha,
     * with A = m tau, B = (m - 1) - A p, r = -alpha/(4 zeta^2) - B p,
     * Kd = J alpha A, D = J alpha B, c_ff = J alpha r; D only enters the static gain Fr(0).
     * lowpass (eq 13) is the case m = 1, tau = 0; no_tau is tau = 0.
     */
    m_eff = cfg->feedforward == P2D_FF_LOWPASS ? 1.0f : cfg->m;
    tau_eff = cfg->feedforward == P2D_FF_FULL ? cfg->tau_i_s : 0.0f;
    p_radps = m_eff * cfg->alpha_radps;
    A = m_eff * tau_eff;
    B = (m_eff - 1.0f) - A * p_radps;
    r = -cfg->alpha_radps / (4.0f * cfg->zeta * cfg->zeta) - B * p_radps;
    c_ff = Kp * r;

    /*
     * c_ff / (s + p) -> (b0 + b1 z^-1) / (1 + a1 z^-1), realized around its static
     * gain c_ff / p as c_ff / p + b_dr (1 - z^-1) / (1 + a1 z^-1), b_dr = b0 - c_ff / p
     */
    if (cfg->method == P2D_FORWARD_EULER) {
        /* s = (z - 1)/Ts: c Ts z^-1 / (1 - (1 - p Ts) z^-1); pole 1 - p Ts inside the unit circle */
        if (cfg->feedforward != P2D_FF_NONE && !(p_radps * cfg->Ts_s < 2.0f)) return P2D_ERR_TS_UNSTABLE;
        b_dr = -c_ff / p_radps;
        a1 = p_radps * cfg->Ts_s - 1.0f;
    } else if (cfg->method == P2D_BACKWARD_EULER) {
        /* s = (z - 1)/(z Ts): c Ts / ((1 + p Ts) - z^-1), b0 = c Ts / (1 + p Ts) */
        b_dr = -c_ff / p_radps / (1.0f + p_radps * cfg->Ts_s);
        a1 = -1.0f / (1.0f + p_radps * cfg->Ts_s);
    } else {
        /* s = 2(z - 1)/(Ts (z + 1)): c Ts (1 + z^-1) / ((2 + p Ts) - (2 - p Ts) z^-1), eq 15 */
        b_dr = -2.0f * c_ff / p_radps / (2.0f + p_radps * cfg->Ts_s);
        a1 = -(2.0f - p_radps * cfg->Ts_s) / (2.0f + p_radps * cfg->Ts_s);
    }
    /* float32 can round the pole -a1 onto the unit circle (m alpha Ts tiny, or huge with Tustin) */
    if (cfg->feedforward != P2D_FF_NONE && !(fabsf(a1) < 1.0f)) return P2D_ERR_TS_UNSTABLE;
    if (cfg->feedforward == P2D_FF_NONE) {
        k.ff_Fr0 = 0.0f;
        k.ff_b_dr = 0.0f;
        k.ff_a1 = 0.0f;
        k.ff_Kd_per_Ts = 0.0f;
    } else {
        /* Fr(0) = D + c_ff / p = -J alpha / (4 zeta^2 m) (eq 11 at s = 0) */
        k.ff_Fr0 = -Kp / (4.0f * cfg->zeta * cfg->zeta * m_eff);
        k.ff_b_dr = b_dr;
        k.ff_a1 = a1;
        /* Kd s by the backward difference: Kd (r[k] - r[k-1]) / Ts */
        k.ff_Kd_per_Ts = Kp * A / cfg->Ts_s;
    }

    /* torque to current and the current-vector limit as a torque limit on the MTPA trajectory */
    k.i_max_A = cfg->i_max_A;
    k.psi_f_Wb = cfg->psi_f_Wb;
    k.dL_H = cfg->Ld_H - cfg->Lq_H;
    k.salient = cfg->Ld_H != cfg->Lq_H;
    k.kt_Nm_per_A = 1.5f * (float)cfg->pole_pairs * cfg->psi_f_Wb;
    k.k_mtpa_Wb_per_sqrt_Nm = 2.0f * sqrtf(fabsf(k.dL_H) / (1.5f * (float)cfg->pole_pairs));
    {
        /* the MTPA point at ||i|| = I */
        float I = cfg->i_max_A;
        float id = p2d_mtpa_id_of_norm_A(I, k.psi_f_Wb, k.dL_H);
        float iq = sqrtf(I * I - id * id);
        /* Te = iq (kt + c_T id), c_T = 1.5 p (Ld - Lq) [Nm/A^2] */
        k.T_max_Nm = iq * (k.kt_Nm_per_A + 1.5f * (float)cfg->pole_pairs * k.dL_H * id);
    }
    if (!k.salient && isfinite(k.T_max_Nm)) {
        /*
         * surface: iq = T / kt must stay within i_max_A in float32 for every |T| <= T_max.
         * The rounded quotient is monotonic in T, so it is enough at T_max: lower
         * T_max by ulps until it holds (kt i_max rounded, then divided by kt, can
         * come out one ulp above i_max).
         */
        while (k.T_max_Nm / k.kt_Nm_per_A > cfg->i_max_A) k.T_max_Nm = nextafterf(k.T_max_Nm, 0.0f);
    }
    if (!p2d_is_positive(k.T_max_Nm) || !isfinite(k.ff_Fr0) || !isfinite(k.ff_b_dr) || !isfinite(k.ff_Kd_per_Ts) ||
        !p2d_pi_finite(&k.pi)) {
        return P2D_ERR_TS; /* only reachable through float overflow of extreme inputs */
    }

    /* the torque filters (filter.h) at the speed loop's Ts, after every other field */
    status = p2d_filter_coefficients(fcfg, cfg->Ts_s, &filter);
    if (status != P2D_OK) return status;
    k.filtered = p2d_filter_on(&filter);
    k.general_step = k.salient || k.filtered;
    /* the back-calculation loop through them, x[k] = x[k-1] - Ki Ka Ts H(z) x[k-1] + ..., must be stable too */
    if (k.filtered && k.pi.Ki_Ka_Ts > 0.0f && !p2d_filter_loop_stable(&filter, k.pi.Ki_Ka_Ts)) return P2D_ERR_KA;
    *c = k;
    *f = filter;
    return P2D_OK;
}

/* No torque filter: the configuration of init. */
static const p2d_filter_config_t P2D_NO_FILTER = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};

p2d_status_t p2d_speed_init(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    status = speed_coefficients(cfg, &P2D_NO_FILTER, &ctl->coef[0], &ctl->filter_coef[0]);
    if (status != P2D_OK) return status;
    ctl->coef[1] = ctl->coef[0];
    ctl->filter_coef[1] = ctl->filter_coef[0];
    ctl->active = 0u;
    ctl->config = *cfg;
    ctl->filter_config = P2D_NO_FILTER;
    ctl->fault_count = 0u;
    p2d_speed_reset(ctl, 0.0f, 0.0f);
    return P2D_OK;
}

/*
 * The shadow swap of pi.h for the configuration cfg with the torque filters fcfg; torque
 * filters switched on start at rest at the command at zero error, x[k-1].
 */
static p2d_status_t speed_swap(p2d_speed_t *ctl, const p2d_speed_config_t *cfg, const p2d_filter_config_t *fcfg)
{
    const uint32_t inactive = p2d_shadow_inactive(ctl->active);
    p2d_status_t status = speed_coefficients(cfg, fcfg, &ctl->coef[inactive], &ctl->filter_coef[inactive]);
    if (status != P2D_OK) return status;
    p2d_filter_switch_on(&ctl->filter_coef[ctl->active], &ctl->filter_coef[inactive], &ctl->filter, ctl->x_Nm);
    ctl->config = *cfg;
    ctl->filter_config = *fcfg;
    p2d_shadow_activate(&ctl->active, inactive);
    return P2D_OK;
}

p2d_status_t p2d_speed_set_config(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    return speed_swap(ctl, cfg, &ctl->filter_config);
}

p2d_status_t p2d_speed_set_filter(p2d_speed_t *ctl, const p2d_filter_config_t *cfg)
{
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    return speed_swap(ctl, &ctl->config, cfg);
}

void p2d_speed_reset(p2d_speed_t *ctl, float w_ref_radps, float T_init_Nm)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    /*
     * steady state at r[k] = r[k-1] = w_ref: transient y = 0, T_ff = Fr0 w_ref, and u = x at e = 0,
     * so x = T_init; the integral x_i = T_init - Fr0 w_ref must be finite too
     */
    float x = T_init_Nm;
    if (!isfinite(w_ref_radps) || !isfinite(T_init_Nm - c->ff_Fr0 * w_ref_radps)) {
        /* non-finite policy (arguments, or a steady state that overflows): clear the state instead, count the fault */
        ctl->fault_count++;
        w_ref_radps = 0.0f;
        x = 0.0f;
    }
    ctl->r_prev_radps = w_ref_radps;
    ctl->y_ff_prev_Nm = 0.0f;
    ctl->x_Nm = x;
    p2d_filter_rest(&ctl->filter, x);
}

/* Non-finite policy: zero torque and current, fault raised, so that the update leaves the state alone. */
static bool fault_output(p2d_speed_output_t *out)
{
    out->T_ref_Nm = 0.0f;
    out->id_ref_A = 0.0f;
    out->iq_ref_A = 0.0f;
    out->saturated = false;
    out->fault = true;
    return false;
}

/*
 * u[k] from e[k], dr[k] = r[k] - r[k-1] and the feedforward transient y[k];
 * the move dT[k] of the feedforward into *dT_ff.
 */
static inline float speed_sum(const p2d_speed_t *ctl, const p2d_speed_coef_t *c, float e, float dr, float y_ff,
                              float *dT_ff)
{
    /* dT[k] = Fr0 dr[k] + y[k] + Kd dr[k] / Ts, the move of T_ff from Fr0 r[k-1] */
    *dT_ff = fmaf(c->ff_Fr0, dr, fmaf(c->ff_Kd_per_Ts, dr, y_ff));
    /* u[k] = b_e0 e[k] + x[k-1] + dT[k], x[k-1] = x_i[k-1] + Fr0 r[k-1] */
    return p2d_pi_output(c->pi, e, ctl->x_Nm + *dT_ff);
}

/*
 * u[k], the torque of this sample before the limit (eq 11-15), with the
 * outputs that come before the limit (reference, error, feedforward, u) into out.
 */
static inline float speed_unlimited(const p2d_speed_t *ctl, const p2d_speed_coef_t *c, float w_ref_radps,
                                    float w_m_radps, p2d_speed_output_t *out)
{
    float e, dr, y_ff, dT_ff, T_ff, u;

    e = w_ref_radps - w_m_radps;
    /* dr[k] = r[k] - r[k-1] */
    dr = w_ref_radps - ctl->r_prev_radps;
    /* feedforward transient: y[k] = b_dr dr[k] - a1 y[k-1] */
    y_ff = fmaf(-c->ff_a1, ctl->y_ff_prev_Nm, c->ff_b_dr * dr);
    u = speed_sum(ctl, c, e, dr, y_ff, &dT_ff);
    /* T_ff[k] = Fr0 r[k-1] + dT[k] = Fr0 r[k] + y[k] + Kd dr[k] / Ts */
    T_ff = fmaf(c->ff_Fr0, ctl->r_prev_radps, dT_ff);

    out->w_ref_radps = w_ref_radps;
    out->e_radps = e;
    out->T_ff_Nm = T_ff;
    out->y_ff_Nm = y_ff;
    out->T_unsat_Nm = u;
    return u;
}

/*
 * u_f[k] = H(z) u[k], the command through the torque filters, into out->T_unsat_Nm
 * (returned); the filter states after this sample into *next.
 */
static inline float filtered_command(const p2d_speed_t *ctl, float u, p2d_speed_output_t *out, p2d_filter_state_t *next)
{
    out->T_unsat_Nm = p2d_filter_output(&ctl->filter_coef[ctl->active], &ctl->filter, u, next);
    return out->T_unsat_Nm;
}

/*
 * The limit T_lim_Nm of the command u before it (u_f with torque filters) into out.
 * Returns false, with the fault output, if u is not finite.
 */
static inline bool speed_limit(float T_lim_Nm, float u, p2d_speed_output_t *out)
{
    float T_sat = u;
    bool saturated = false;
    /* u_sat = Sat(u): the current-vector limit ||i_dq|| <= I_max as the torque limit T_lim (T_max, or less) */
    if (!(fabsf(u) <= T_lim_Nm)) {
        /* the limit is active, or u is NaN or inf */
        if (!(fabsf(u) < INFINITY)) return fault_output(out);
        T_sat = u > 0.0f ? T_lim_Nm : -T_lim_Nm;
        saturated = true;
    }
    out->T_ref_Nm = T_sat;
    out->saturated = saturated;
    out->fault = false;
    return true;
}

/*
 * u_f[k] = H(z) u[k] into out->T_unsat_Nm (returned), the filter states left as they are; out of
 * line, so that the unfiltered compute keeps no filter state on its stack.
 */
static P2D_NOINLINE float filtered_compute(const p2d_speed_t *ctl, float u, p2d_speed_output_t *out)
{
    p2d_filter_state_t next; /* unused: compute does not change the state */
    return filtered_command(ctl, u, out, &next);
}

/*
 * The torque command of this sample (eq 11-15, the torque filters and the limit) into
 * out, all but the current vector. Returns false, with the fault output, if the command
 * before the limit is not finite.
 */
static inline bool speed_torque(const p2d_speed_t *ctl, const p2d_speed_coef_t *c, float w_ref_radps, float w_m_radps,
                                float T_lim_Nm, p2d_speed_output_t *out)
{
    float u = speed_unlimited(ctl, c, w_ref_radps, w_m_radps, out);
    if (c->filtered) u = filtered_compute(ctl, u, out);
    return speed_limit(T_lim_Nm, u, out);
}

/* Surface PMSM: id = 0, iq = T / (1.5 p psi_f); |iq| <= I_max by the choice of T_max. */
static inline void surface_current(const p2d_speed_coef_t *c, p2d_speed_output_t *out)
{
    out->id_ref_A = 0.0f;
    out->iq_ref_A = out->T_ref_Nm / c->kt_Nm_per_A;
}

/*
 * Salient PMSM: the MTPA current vector of the torque T = out->T_ref_Nm (|T| <= T_max).
 * Returns false, with the fault output, if the inversion overflowed.
 *
 * Newton on the quartic of the MTPA flux v = sqrt(psi_f^2 + 4 dL^2 iq^2) - psi_f,
 *   g(t) = t (t + 2 psi)^3 - K = 0,   t = v / sigma,   psi = psi_f / sigma,   K = (sqrt(q) / sigma)^4,
 * q = 4 |dL| |T| / (1.5 p), in units of sigma = max(psi_f, sqrt(q)) so that nothing overflows or
 * underflows, started at the smaller of the upper bounds K^(1/4) and K / (8 psi^3) of the root
 * (derivation: docs/theory/speed-controller.md). iq follows from v, and id from iq by the MTPA
 * relation of mtpa.h, the one p2d_mtpa_id_A computes: the command is on its trajectory to the bit.
 */
static bool mtpa_current(const p2d_speed_coef_t *c, p2d_speed_output_t *out)
{
    const float T = out->T_ref_Nm;
    float sqrt_q, sigma, psi, Q, K, t_magnet, t, id, iq, norm;

    /* sqrt(q) = 2 sqrt(|dL| / (1.5 p)) sqrt(|T|): q itself [Wb^2] could overflow */
    sqrt_q = c->k_mtpa_Wb_per_sqrt_Nm * p2d_sqrt_nonnegative(T);
    sigma = sqrt_q > c->psi_f_Wb ? sqrt_q : c->psi_f_Wb;
    psi = c->psi_f_Wb / sigma;
    Q = sqrt_q / sigma;
    K = (Q * Q) * (Q * Q);
    t = Q;
    t_magnet = K / (8.0f * psi * psi * psi);
    if (t_magnet < t) t = t_magnet;
    for (int n = 0; n < P2D_MTPA_NEWTON_ITERATIONS; ++n) {
        float w = t + 2.0f * psi;
        float w2 = w * w;
        /* t <- t - g(t) / g'(t),  g = t w^3 - K,  g' = w^2 (4 t + 2 psi),  w = t + 2 psi */
        t -= fmaf(w2 * w, t, -K) / (w2 * fmaf(4.0f, t, 2.0f * psi));
    }
    iq = copysignf(sigma * p2d_sqrt_nonnegative(t * (t + 2.0f * psi)) / (2.0f * fabsf(c->dL_H)), T);
    /* id on the MTPA trajectory for this iq: the relation p2d_mtpa_id_A computes, to the bit */
    id = p2d_mtpa_id_of_iq_A(iq, c->psi_f_Wb, c->dL_H);
    /* the last rounding can leave ||i|| a few ulps above the limit: scale back onto it */
    norm = p2d_sqrt_nonnegative(fmaf(id, id, iq * iq));
    if (norm > c->i_max_A) {
        float k = c->i_max_A / norm;
        id *= k;
        iq *= k;
    }
    /* id = iq x / (psi_f + h) is NaN whenever iq or x = 2 dL iq is not finite (inf / inf), else finite */
    if (!isfinite(id)) {
        /* the MTPA inversion overflowed (extreme configurations only) */
        return fault_output(out);
    }
    out->id_ref_A = id;
    out->iq_ref_A = iq;
    return true;
}

/* The new state x[k], r[k] and y[k] of out; an x that is not finite is refused (counted, state kept). */
static inline bool speed_store(p2d_speed_t *ctl, const p2d_speed_output_t *out, float x)
{
    if (!isfinite(x)) {
        /* non-finite policy: an update that would overflow the integrator is refused */
        ctl->fault_count++;
        return false;
    }
    ctl->x_Nm = x;
    ctl->r_prev_radps = out->w_ref_radps;
    ctl->y_ff_prev_Nm = out->y_ff_Nm;
    return true;
}

/*
 * The state update with the applied torque T_applied_Nm (finite) of an output that is not a fault;
 * false if refused.
 */
static inline bool speed_integrate(p2d_speed_t *ctl, const p2d_speed_coef_t *c, const p2d_speed_output_t *out,
                                   float T_applied_Nm)
{
    float dx, x;
    /* integration Ki Ts e[k] + Ki Ka Ts u*[k], u* = u_sat - u with u_sat the torque actually applied (u_f with
       torque filters: T_unsat_Nm holds it) */
    dx = p2d_pi_integration(c->pi, c->clamping, out->e_radps, T_applied_Nm - out->T_unsat_Nm);
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] + Fr0 dr[k]: the static feedforward moves with r, never held */
    x = fmaf(c->ff_Fr0, out->w_ref_radps - ctl->r_prev_radps, ctl->x_Nm + dx);
    return speed_store(ctl, out, x);
}

/*
 * The update of a filtered configuration: speed_integrate (its u* = u_sat - u_f), then the
 * filter states *next; refused whole (counted, nothing written) if either is not finite.
 */
static void filtered_integrate(p2d_speed_t *ctl, const p2d_speed_coef_t *c, const p2d_speed_output_t *out,
                               float T_applied_Nm, const p2d_filter_state_t *next)
{
    const p2d_filter_coef_t *f = &ctl->filter_coef[ctl->active];
    if (!p2d_filter_state_finite(f, next)) {
        /* non-finite policy: an update that would overflow a filter is refused */
        ctl->fault_count++;
        return;
    }
    if (speed_integrate(ctl, c, out, T_applied_Nm)) p2d_filter_store(f, &ctl->filter, next);
}

/*
 * Step of a filtered configuration, after p2d_speed_step has computed a finite u
 * (out->T_unsat_Nm) and limited it: the limit is redone on u_f, then the current
 * vector (MTPA or surface) and the update.
 */
static P2D_NOINLINE void filtered_step_end(p2d_speed_t *ctl, p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    p2d_filter_state_t next;
    if (!speed_limit(c->T_max_Nm, filtered_command(ctl, out->T_unsat_Nm, out, &next), out) ||
        (c->salient && !mtpa_current(c, out))) {
        /* non-finite policy: u_f overflowed, or the MTPA inversion did */
        ctl->fault_count++;
        return;
    }
    if (!c->salient) surface_current(c, out);
    filtered_integrate(ctl, c, out, out->T_ref_Nm, &next);
}

/* Step of a salient PMSM or a filtered configuration, after the limit of u. */
static P2D_NOINLINE void general_step_end(p2d_speed_t *ctl, p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    if (c->filtered) {
        filtered_step_end(ctl, out);
        return;
    }
    /* salient PMSM: the MTPA current, then the update */
    if (mtpa_current(c, out)) {
        speed_integrate(ctl, c, out, out->T_ref_Nm);
    } else {
        ctl->fault_count++;
    }
}

void p2d_speed_compute(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    if (!speed_torque(ctl, c, w_ref_radps, w_m_radps, c->T_max_Nm, out)) return;
    if (c->salient) {
        (void)mtpa_current(c, out);
    } else {
        surface_current(c, out);
    }
}

/*
 * The update of a filtered configuration with the applied torque T_applied_Nm (finite) of an
 * output that is not a fault; out of line, so that the unfiltered update stays small enough to
 * be inlined (p2d_speed_step_fw).
 */
static P2D_NOINLINE void filtered_update(p2d_speed_t *ctl, const p2d_speed_output_t *out, float T_applied_Nm)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    p2d_filter_state_t next;
    float dT_ff;
    /* u[k] again, rounded as compute rounded it, advances the torque filters */
    const float u = speed_sum(ctl, c, out->e_radps, out->w_ref_radps - ctl->r_prev_radps, out->y_ff_Nm, &dT_ff);
    (void)p2d_filter_output(&ctl->filter_coef[ctl->active], &ctl->filter, u, &next);
    filtered_integrate(ctl, c, out, T_applied_Nm, &next);
}

void p2d_speed_update(p2d_speed_t *ctl, const p2d_speed_output_t *out, float T_applied_Nm)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    if (out->fault || !isfinite(T_applied_Nm)) {
        ctl->fault_count++;
        return;
    }
    if (c->filtered) {
        filtered_update(ctl, out, T_applied_Nm);
        return;
    }
    speed_integrate(ctl, c, out, T_applied_Nm);
}

/*
 * compute + update with the own command, written out per branch of the limit
 * (the same numbers as compute and update, in fewer instructions). The
 * salient and the filtered paths are a tail call, so the surface path calls
 * nothing and saves no registers. Unlimited (|u| <= T_max, so u is finite),
 * u* = u - u = +0 and the integration is p2d_pi_integration_unlimited.
 */
void p2d_speed_step(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    const float u = speed_unlimited(ctl, c, w_ref_radps, w_m_radps, out);
    float T_sat;

    if (fabsf(u) <= c->T_max_Nm) {
        out->T_ref_Nm = u;
        out->saturated = false;
        out->fault = false;
        if (c->general_step) {
            general_step_end(ctl, out);
            return;
        }
        surface_current(c, out);
        /* x[k] = x[k-1] + (Ki Ts e[k] + 0) + Fr0 dr[k] */
        speed_store(ctl, out,
                    fmaf(c->ff_Fr0, w_ref_radps - ctl->r_prev_radps,
                         ctl->x_Nm + p2d_pi_integration_unlimited(c->pi, out->e_radps)));
    } else {
        if (!(fabsf(u) < INFINITY)) {
            /* non-finite policy: u is NaN or inf */
            (void)fault_output(out);
            ctl->fault_count++;
            return;
        }
        T_sat = u > 0.0f ? c->T_max_Nm : -c->T_max_Nm;
        out->T_ref_Nm = T_sat;
        out->saturated = true;
        out->fault = false;
        if (c->general_step) {
            general_step_end(ctl, out);
            return;
        }
        surface_current(c, out);
        speed_integrate(ctl, c, out, T_sat);
    }
}

/* 1.5 p (psi_f + (Ld - Lq) id) [Nm/A]: the torque per q-axis current at the d-axis current id_A */
static inline float torque_per_iq(const p2d_speed_coef_t *c, float id_A)
{
    /* 1.5 p = kt / psi_f */
    return (c->kt_Nm_per_A / c->psi_f_Wb) * fmaf(c->dL_H, id_A, c->psi_f_Wb);
}

/*
 * The torque limit at the d-axis current id_A in [-i_max, 0] with the q current iq_max_A that
 * remains: the largest torque of a vector with ||i_dq|| <= i_max and id <= id_A. Surface PMSM:
 * kt iq_max. Salient: T_max where the MTPA vector of length i_max has id <= id_A, else the point
 * (id_A, iq_max) of the circle (the torque is unimodal along it), 0 where the torque per iq is not
 * positive.
 */
static float fw_torque_limit(const p2d_speed_coef_t *c, float id_A, float iq_max_A)
{
    float T_lim;
    if (!c->salient) {
        T_lim = c->kt_Nm_per_A * iq_max_A;
    } else if (p2d_mtpa_id_of_norm_A(c->i_max_A, c->psi_f_Wb, c->dL_H) <= id_A) {
        return c->T_max_Nm;
    } else {
        T_lim = torque_per_iq(c, id_A) * iq_max_A;
        if (!(T_lim > 0.0f)) return 0.0f;
    }
    return T_lim < c->T_max_Nm ? T_lim : c->T_max_Nm;
}

/*
 * The current vector of the limited torque out->T_ref_Nm under the bound id <= id_A: the MTPA
 * vector where its id is already below (salient PMSM), else (id_A, T / (1.5 p (psi_f + dL id_A))),
 * iq within iq_max_A (T / k rounds above it only by an ulp, or by more where k is subnormal).
 */
static void fw_current(const p2d_speed_coef_t *c, float id_A, float iq_max_A, p2d_speed_output_t *out)
{
    float k_T, iq;
    if (c->salient) {
        if (!mtpa_current(c, out) || out->id_ref_A <= id_A) return;
        k_T = torque_per_iq(c, id_A);
    } else {
        k_T = c->kt_Nm_per_A;
    }
    /* iq = T / k_T; the limit is 0 where k_T <= 0, and the torque with it */
    iq = k_T > 0.0f ? out->T_ref_Nm / k_T : 0.0f;
    out->id_ref_A = id_A;
    out->iq_ref_A = fabsf(iq) <= iq_max_A ? iq : copysignf(iq_max_A, iq);
}

void p2d_speed_compute_fw(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, float id_fw_A,
                          p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    float id, iq_max;
    if (!isfinite(id_fw_A)) {
        /* non-finite policy: the outputs before the limit for the diagnostics, then the fault output */
        (void)speed_unlimited(ctl, c, w_ref_radps, w_m_radps, out);
        (void)fault_output(out);
        return;
    }
    /* id_fw clamped to [-i_max, 0] */
    id = id_fw_A < 0.0f ? (id_fw_A > -c->i_max_A ? id_fw_A : -c->i_max_A) : 0.0f;
    /* iq_max = sqrt((i_max + id) (i_max - id)): i_max + id is exact near id = -i_max, where i_max^2 - id^2 cancels */
    iq_max = p2d_sqrt_nonnegative((c->i_max_A + id) * (c->i_max_A - id));
    if (!speed_torque(ctl, c, w_ref_radps, w_m_radps, fw_torque_limit(c, id, iq_max), out)) return;
    fw_current(c, id, iq_max, out);
}

/* compute_fw + update with the own command (not written out per branch as p2d_speed_step is). */
void p2d_speed_step_fw(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, float id_fw_A, p2d_speed_output_t *out)
{
    p2d_speed_compute_fw(ctl, w_ref_radps, w_m_radps, id_fw_A, out);
    p2d_speed_update(ctl, out, out->T_ref_Nm);
}

float p2d_speed_integrator_Nm(const p2d_speed_t *ctl) { return p2d_speed_integral_Nm(ctl); }

float p2d_speed_Ka_default(float J_kgm2, float alpha_radps)
{
    /* Ka = 1 / Kp = 1 / (J alpha), section 3.3 */
    return 1.0f / (J_kgm2 * alpha_radps);
}
