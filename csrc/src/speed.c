/*
 * 2DOF PI speed controller with anti-windup: see pmsm2dof/speed.h for the
 * equations and the paper references.
 */
#include "pmsm2dof/speed.h"

#include <math.h>

#include "pmsm2dof/transforms.h"

/* Newton iterations of the MTPA torque-to-current inversion (salient PMSM). */
#define P2D_MTPA_NEWTON_ITERATIONS 5

static bool is_positive(float x) { return isfinite(x) && x > 0.0f; }
static bool is_nonnegative(float x) { return isfinite(x) && x >= 0.0f; }

/* a < 0 < b or b < 0 < a, without a product that can underflow to 0 */
static bool opposite_signs(float a, float b) { return (a < 0.0f && b > 0.0f) || (a > 0.0f && b < 0.0f); }

/* Torque [Nm] of the MTPA current vector with q-axis current iq_A. */
static float mtpa_torque_Nm(const p2d_speed_coef_t *c, float iq_A)
{
    /* Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
    return iq_A * (c->kt_NmpA + c->c_T_Nm_per_A2 * p2d_mtpa_id_A(iq_A, c->psi_f_Wb, c->dL_H));
}

/* Validate cfg and compute its coefficients into *c. *c is written only on success. */
static p2d_status_t speed_coefficients(const p2d_speed_config_t *cfg, p2d_speed_coef_t *c)
{
    p2d_speed_coef_t k;
    float m_eff, tau_eff, p_radps, D, c_ff, b0, b1, a1, A, B, r;

    if (!is_positive(cfg->J_kgm2)) return P2D_ERR_J;
    if (!is_positive(cfg->alpha_radps)) return P2D_ERR_ALPHA;
    if (!is_positive(cfg->zeta)) return P2D_ERR_ZETA;
    if (!is_positive(cfg->m)) return P2D_ERR_M;
    if (!is_nonnegative(cfg->tau_i_s)) return P2D_ERR_TAU_I;
    if (!is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    if (!is_positive(cfg->i_max_A)) return P2D_ERR_I_MAX;
    if (!is_positive(cfg->psi_f_Wb)) return P2D_ERR_PSI_F;
    if (!is_positive(cfg->Ld_H)) return P2D_ERR_LD;
    if (!is_positive(cfg->Lq_H)) return P2D_ERR_LQ;
    if (cfg->pole_pairs < 1u) return P2D_ERR_POLE_PAIRS;
    if ((unsigned)cfg->method > (unsigned)P2D_TUSTIN) return P2D_ERR_METHOD;
    if ((unsigned)cfg->feedforward > (unsigned)P2D_FF_FULL) return P2D_ERR_FEEDFORWARD;
    if ((unsigned)cfg->anti_windup > (unsigned)P2D_AW_CLAMPING) return P2D_ERR_ANTI_WINDUP;
    if (cfg->feedforward == P2D_FF_LOWPASS && cfg->m != 1.0f) return P2D_ERR_M_LOWPASS;

    /* eq 9: Kp = J alpha, Ki = J (alpha / (2 zeta))^2 */
    k.Kp = cfg->J_kgm2 * cfg->alpha_radps;
    k.Ki = cfg->J_kgm2 * (cfg->alpha_radps / (2.0f * cfg->zeta)) * (cfg->alpha_radps / (2.0f * cfg->zeta));
    if (!isfinite(k.Kp) || !isfinite(k.Ki)) return P2D_ERR_J; /* float32 overflow of the gains */
    k.Ki_Ts = k.Ki * cfg->Ts_s;
    k.clamping = cfg->anti_windup == P2D_AW_CLAMPING;
    k.Ki_Ka_Ts = 0.0f;
    if (cfg->anti_windup == P2D_AW_BACK_CALCULATION) {
        /* the discrete back-calculation loop x[k] = (1 - Ki Ka Ts) x[k-1] + ... must be stable */
        if (!is_nonnegative(cfg->Ka) || !(k.Ki * cfg->Ka * cfg->Ts_s < 2.0f)) return P2D_ERR_KA;
        k.Ki_Ka_Ts = k.Ki * cfg->Ka * cfg->Ts_s;
    } else if (!is_nonnegative(cfg->Ka)) {
        return P2D_ERR_KA;
    }

    /* eq 14 and Table 1: the weight of e[k] in u[k] */
    if (cfg->method == P2D_FORWARD_EULER) {
        k.b_e0 = k.Kp;
    } else if (cfg->method == P2D_BACKWARD_EULER) {
        k.b_e0 = k.Kp + k.Ki_Ts;
    } else {
        k.b_e0 = k.Kp + 0.5f * k.Ki_Ts;
    }

    /*
     * eq 11: Fr = J alpha (m tau s^2 + (m - 1) s - alpha/(4 zeta^2)) / (s + m alpha)
     *           = Kd s + D + c_ff / (s + p),  p = m alpha,
     * with A = m tau, B = (m - 1) - A p, r = -alpha/(4 zeta^2) - B p,
     * Kd = J alpha A, D = J alpha B, c_ff = J alpha r.
     * lowpass (eq 13) is the case m = 1, tau = 0; no_tau is tau = 0.
     */
    m_eff = cfg->feedforward == P2D_FF_LOWPASS ? 1.0f : cfg->m;
    tau_eff = cfg->feedforward == P2D_FF_FULL ? cfg->tau_i_s : 0.0f;
    p_radps = m_eff * cfg->alpha_radps;
    A = m_eff * tau_eff;
    B = (m_eff - 1.0f) - A * p_radps;
    r = -cfg->alpha_radps / (4.0f * cfg->zeta * cfg->zeta) - B * p_radps;
    D = k.Kp * B;
    c_ff = k.Kp * r;

    /* c_ff / (s + p) -> (b0 + b1 z^-1) / (1 + a1 z^-1) */
    if (cfg->method == P2D_FORWARD_EULER) {
        /* s = (z - 1)/Ts: c Ts z^-1 / (1 - (1 - p Ts) z^-1); pole 1 - p Ts inside the unit circle */
        if (cfg->feedforward != P2D_FF_NONE && !(p_radps * cfg->Ts_s < 2.0f)) return P2D_ERR_TS_UNSTABLE;
        b0 = 0.0f;
        b1 = c_ff * cfg->Ts_s;
        a1 = p_radps * cfg->Ts_s - 1.0f;
    } else if (cfg->method == P2D_BACKWARD_EULER) {
        /* s = (z - 1)/(z Ts): c Ts / ((1 + p Ts) - z^-1) */
        b0 = c_ff * cfg->Ts_s / (1.0f + p_radps * cfg->Ts_s);
        b1 = 0.0f;
        a1 = -1.0f / (1.0f + p_radps * cfg->Ts_s);
    } else {
        /* s = 2(z - 1)/(Ts (z + 1)): c Ts (1 + z^-1) / ((2 + p Ts) - (2 - p Ts) z^-1), eq 15 */
        b0 = c_ff * cfg->Ts_s / (2.0f + p_radps * cfg->Ts_s);
        b1 = b0;
        a1 = -(2.0f - p_radps * cfg->Ts_s) / (2.0f + p_radps * cfg->Ts_s);
    }
    /* float32 can round the pole -a1 onto the unit circle (m alpha Ts tiny, or huge with Tustin) */
    if (cfg->feedforward != P2D_FF_NONE && !(fabsf(a1) < 1.0f)) return P2D_ERR_TS_UNSTABLE;
    if (cfg->feedforward == P2D_FF_NONE) {
        k.ff_b0 = 0.0f;
        k.ff_b1 = 0.0f;
        k.ff_a1 = 0.0f;
        k.ff_Kd_per_Ts = 0.0f;
    } else {
        /* D + (b0 + b1 z^-1)/(1 + a1 z^-1) = ((D + b0) + (D a1 + b1) z^-1) / (1 + a1 z^-1) */
        k.ff_b0 = D + b0;
        k.ff_b1 = D * a1 + b1;
        k.ff_a1 = a1;
        /* Kd s by the backward difference: Kd (r[k] - r[k-1]) / Ts */
        k.ff_Kd_per_Ts = k.Kp * A / cfg->Ts_s;
    }

    /* torque to current and the current-vector limit as a torque limit on the MTPA trajectory */
    k.i_max_A = cfg->i_max_A;
    k.psi_f_Wb = cfg->psi_f_Wb;
    k.dL_H = cfg->Ld_H - cfg->Lq_H;
    k.salient = cfg->Ld_H != cfg->Lq_H;
    k.kt_NmpA = 1.5f * (float)cfg->pole_pairs * cfg->psi_f_Wb;
    k.c_T_Nm_per_A2 = 1.5f * (float)cfg->pole_pairs * k.dL_H;
    {
        /* MTPA point at ||i|| = I: id = 2 dL I^2 / (psi_f + sqrt(psi_f^2 + 8 dL^2 I^2)) */
        float I = cfg->i_max_A;
        float id = 2.0f * k.dL_H * I * I /
                   (k.psi_f_Wb + sqrtf(k.psi_f_Wb * k.psi_f_Wb + 8.0f * k.dL_H * k.dL_H * I * I));
        float iq = sqrtf(I * I - id * id);
        k.T_max_Nm = iq * (k.kt_NmpA + k.c_T_Nm_per_A2 * id);
    }
    if (!is_positive(k.T_max_Nm) || !isfinite(k.ff_b0) || !isfinite(k.ff_b1) ||
        !isfinite(k.ff_Kd_per_Ts) || !isfinite(k.b_e0) || !isfinite(k.Ki_Ts)) {
        return P2D_ERR_TS; /* only reachable through float overflow of extreme inputs */
    }
    *c = k;
    return P2D_OK;
}

p2d_status_t p2d_speed_init(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    p2d_status_t status;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    status = speed_coefficients(cfg, &ctl->coef[0]);
    if (status != P2D_OK) return status;
    ctl->coef[1] = ctl->coef[0];
    ctl->active = 0u;
    ctl->config = *cfg;
    ctl->fault_count = 0u;
    p2d_speed_reset(ctl, 0.0f, 0.0f);
    return P2D_OK;
}

p2d_status_t p2d_speed_set_config(p2d_speed_t *ctl, const p2d_speed_config_t *cfg)
{
    p2d_status_t status;
    uint32_t shadow;
    if (ctl == 0 || cfg == 0) return P2D_ERR_NULL;
    shadow = 1u - ctl->active;
    status = speed_coefficients(cfg, &ctl->coef[shadow]);
    if (status != P2D_OK) return status;
    ctl->config = *cfg;
    ctl->active = shadow;
    return P2D_OK;
}

void p2d_speed_reset(p2d_speed_t *ctl, float w_ref_radps, float T_init_Nm)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    /* steady state of y[k] = b0 r + b1 r - a1 y: y = (b0 + b1) r / (1 + a1) */
    float y_ss = (c->ff_b0 + c->ff_b1) * w_ref_radps / (1.0f + c->ff_a1);
    float x_i = T_init_Nm - y_ss;
    if (!isfinite(w_ref_radps) || !isfinite(x_i)) {
        /* non-finite policy (arguments, or a steady state that overflows): clear the state instead, count the fault */
        ctl->fault_count++;
        w_ref_radps = 0.0f;
        y_ss = 0.0f;
        x_i = 0.0f;
    }
    ctl->r_prev_radps = w_ref_radps;
    ctl->y_ff_prev_Nm = y_ss;
    ctl->x_i_Nm = x_i;
}

/* Non-finite policy: zero torque and current, fault raised, so that the update leaves the state alone. */
static void fault_output(p2d_speed_output_t *out)
{
    out->T_ref_Nm = 0.0f;
    out->id_ref_A = 0.0f;
    out->iq_ref_A = 0.0f;
    out->saturated = false;
    out->fault = true;
}

void p2d_speed_compute(const p2d_speed_t *ctl, float w_ref_radps, float w_m_radps,
                       p2d_speed_output_t *out)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    float e, y_ff, T_ff, u, T_sat, T_abs, iq;

    e = w_ref_radps - w_m_radps;
    /* feedforward section: y[k] = b0 r[k] + b1 r[k-1] - a1 y[k-1] */
    y_ff = c->ff_b0 * w_ref_radps + c->ff_b1 * ctl->r_prev_radps - c->ff_a1 * ctl->y_ff_prev_Nm;
    /* T_ff[k] = y[k] + Kd (r[k] - r[k-1]) / Ts */
    T_ff = y_ff + c->ff_Kd_per_Ts * (w_ref_radps - ctl->r_prev_radps);
    /* u[k] = b_e0 e[k] + x[k-1] + T_ff[k] */
    u = c->b_e0 * e + ctl->x_i_Nm + T_ff;

    out->w_ref_radps = w_ref_radps;
    out->e_radps = e;
    out->T_ff_Nm = T_ff;
    out->y_ff_Nm = y_ff;
    out->T_unsat_Nm = u;
    if (!isfinite(u)) {
        fault_output(out);
        return;
    }
    out->fault = false;

    /* u_sat = Sat(u): the current-vector limit ||i_dq|| <= I_max as the torque limit T_max */
    T_sat = fminf(fmaxf(u, -c->T_max_Nm), c->T_max_Nm);
    out->saturated = T_sat != u;
    out->T_ref_Nm = T_sat;
    if (!c->salient) {
        /* surface PMSM: id = 0, iq = T / (1.5 p psi_f), kept within I_max against rounding */
        out->id_ref_A = 0.0f;
        out->iq_ref_A = fminf(fmaxf(T_sat / c->kt_NmpA, -c->i_max_A), c->i_max_A);
        return;
    }
    /*
     * salient PMSM: solve Te(iq, id_mtpa(iq)) = T_sat by Newton. For iq > 0 the
     * MTPA torque is increasing and convex, so Newton started above the root
     * descends monotonically onto it. Two upper bounds of |iq| are known:
     *   Te >= kt |iq|                       =>  |iq| <= |T| / kt
     *   Te >= |c_T| iq^2 + kt |iq| / 2      =>  |iq| <= 2 |T| / (kt/2 + sqrt(kt^2/4 + 4 |c_T| |T|))
     * (the second from |id| >= |iq| - psi_f / (2 |dL|) on the MTPA curve); the
     * smaller one is a start close to the root for magnet- and for
     * reluctance-dominated machines alike.
     */
    T_abs = fabsf(T_sat);
    iq = fminf(T_abs / c->kt_NmpA,
               2.0f * T_abs / (0.5f * c->kt_NmpA +
                               sqrtf(0.25f * c->kt_NmpA * c->kt_NmpA + 4.0f * fabsf(c->c_T_Nm_per_A2) * T_abs)));
    iq = copysignf(iq, T_sat);
    for (int n = 0; n < P2D_MTPA_NEWTON_ITERATIONS; ++n) {
        float id = p2d_mtpa_id_A(iq, c->psi_f_Wb, c->dL_H);
        /* MTPA: dL id^2 + psi_f id - dL iq^2 = 0 => did/diq = 2 dL iq / (2 dL id + psi_f) */
        float did_diq = 2.0f * c->dL_H * iq / (2.0f * c->dL_H * id + c->psi_f_Wb);
        float dT_diq = c->kt_NmpA + c->c_T_Nm_per_A2 * (id + iq * did_diq);
        iq -= (mtpa_torque_Nm(c, iq) - T_sat) / dT_diq;
    }
    out->iq_ref_A = iq;
    out->id_ref_A = p2d_mtpa_id_A(iq, c->psi_f_Wb, c->dL_H);
    {
        float norm2 = out->id_ref_A * out->id_ref_A + iq * iq;
        if (norm2 > c->i_max_A * c->i_max_A) {
            float k = c->i_max_A / sqrtf(norm2);
            out->id_ref_A *= k;
            out->iq_ref_A *= k;
        }
    }
    if (!isfinite(out->id_ref_A) || !isfinite(out->iq_ref_A)) {
        /* the MTPA inversion overflowed (extreme configurations only) */
        fault_output(out);
    }
}

void p2d_speed_update(p2d_speed_t *ctl, const p2d_speed_output_t *out, float T_applied_Nm)
{
    const p2d_speed_coef_t *c = &ctl->coef[ctl->active];
    float u_star, dx, x_i;

    if (out->fault || !isfinite(T_applied_Nm)) {
        ctl->fault_count++;
        return;
    }
    /* u* = u_sat - u, with u_sat the torque actually applied */
    u_star = T_applied_Nm - out->T_unsat_Nm;
    /* x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] */
    dx = c->Ki_Ts * out->e_radps + c->Ki_Ka_Ts * u_star;
    /* clamping: hold the integrator while the limit is active and e drives further into it */
    if (c->clamping && opposite_signs(u_star, out->e_radps)) dx = 0.0f;
    x_i = ctl->x_i_Nm + dx;
    if (!isfinite(x_i)) {
        /* non-finite policy: an update that would overflow the integrator is refused */
        ctl->fault_count++;
        return;
    }
    ctl->x_i_Nm = x_i;
    ctl->r_prev_radps = out->w_ref_radps;
    ctl->y_ff_prev_Nm = out->y_ff_Nm;
}

void p2d_speed_step(p2d_speed_t *ctl, float w_ref_radps, float w_m_radps, p2d_speed_output_t *out)
{
    p2d_speed_compute(ctl, w_ref_radps, w_m_radps, out);
    p2d_speed_update(ctl, out, out->T_ref_Nm);
}

float p2d_speed_Ka_default(float J_kgm2, float alpha_radps)
{
    /* Ka = 1 / Kp = 1 / (J alpha), section 3.3 */
    return 1.0f / (J_kgm2 * alpha_radps);
}
