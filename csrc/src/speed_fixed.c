/*
 * The fixed-point speed controllers' initialisation shared by Q15 and Q31: the
 * validation, the gains in double and their quantisation (pmsm2dof/speed_fixed.h).
 * The equations of the gains are those of speed.c, in double.
 */
#include <math.h>

#include "fixed.h"
#include "pi.h"

/* Speed-to-torque gains and the torque-to-current gain must stay below 2^13 per unit (speed_fixed.h). */
#define P2D_FIXED_GAIN_BOUND 8192.0

/* Largest magnitude of the mantissa of a gain of `bits` fractional bits, as a double */
static double mantissa_bound(uint32_t bits) { return (double)(((uint64_t)1 << bits) - 1u); }

/* x rounded to the nearest integer, ties away from zero, |x| < 2^62 */
static int64_t round_away(double x)
{
    const double a = x < 0.0 ? -x : x;
    int64_t n = (int64_t)a; /* truncation; a - n is exact */
    if (a - (double)n >= 0.5) n++;
    return x < 0.0 ? -n : n;
}

void p2d_fixed_gain(double g, uint32_t bits, int32_t *mantissa, uint32_t *shift)
{
    const double top = mantissa_bound(bits) + 1.0; /* 2^bits */
    const uint32_t max_shift = P2D_FIXED_MAX_SHIFT(bits);
    double a = g < 0.0 ? -g : g;
    uint32_t s = 0u;
    int64_t m;
    /* the largest s with |g| 2^s < 2^bits (multiplying by 2 is exact) */
    while (s < max_shift && a * 2.0 < top) {
        a *= 2.0;
        s++;
    }
    m = round_away(a);
    if ((double)m >= top) {
        /* a rounded up to 2^bits: one shift less (s >= 1 as |g| < 2^(bits-2)) */
        s--;
        m = round_away(a * 0.5);
    }
    *mantissa = (int32_t)(g < 0.0 ? -m : m);
    *shift = s;
}

/*
 * The gains of cfg (validated as by p2d_speed_init), per unit; the scalings are checked by
 * the caller. Kp = J alpha, Ki = J (alpha / (2 zeta))^2 (eq 9); the feedforward as in speed.c.
 */
static void design_gains(const p2d_speed_config_t *cfg, double W_fs, double T_fs, double I_fs,
                         p2d_speed_fixed_gains_t *g)
{
    const double J = (double)cfg->J_kgm2, alpha = (double)cfg->alpha_radps, zeta = (double)cfg->zeta;
    const double Ts = (double)cfg->Ts_s;
    const double w_per_T = W_fs / T_fs; /* a speed-to-torque gain [Nm/(rad/s)] times this is per unit */
    const double Kp = J * alpha;
    const double Ki = J * (alpha / (2.0 * zeta)) * (alpha / (2.0 * zeta));
    const double kt = 1.5 * (double)cfg->pole_pairs * (double)cfg->psi_f_Wb;
    double b_e0, m_eff, tau_eff, p, A, B, r, c_ff, b_dr, one_plus_a1;

    /* eq 14 and Table 1: the weight of e[k] in u[k] */
    if (cfg->method == P2D_FORWARD_EULER) {
        b_e0 = Kp;
    } else if (cfg->method == P2D_BACKWARD_EULER) {
        b_e0 = Kp + Ki * Ts;
    } else {
        b_e0 = Kp + 0.5 * Ki * Ts;
    }
    g->b_e0 = b_e0 * w_per_T;
    g->Ki_Ts = Ki * Ts * w_per_T;
    g->Ki_Ka_Ts = cfg->anti_windup == P2D_AW_BACK_CALCULATION ? Ki * (double)cfg->Ka * Ts : 0.0;

    /* eq 11: Fr = Kd s + D + c_ff / (s + p), p = m alpha; lowpass (eq 13) is m = 1, tau = 0 (speed.c) */
    m_eff = cfg->feedforward == P2D_FF_LOWPASS ? 1.0 : (double)cfg->m;
    tau_eff = cfg->feedforward == P2D_FF_FULL ? (double)cfg->tau_i_s : 0.0;
    p = m_eff * alpha;
    A = m_eff * tau_eff;
    B = (m_eff - 1.0) - A * p;
    r = -alpha / (4.0 * zeta * zeta) - B * p;
    c_ff = Kp * r;
    /* 1 + a1 written without the cancellation of 1 - (1 - ...): a1 = p Ts - 1, -1 / (1 + p Ts), -(2 - p Ts) / (2 + p Ts) */
    if (cfg->method == P2D_FORWARD_EULER) {
        b_dr = -c_ff / p;
        one_plus_a1 = p * Ts;
    } else if (cfg->method == P2D_BACKWARD_EULER) {
        b_dr = -c_ff / p / (1.0 + p * Ts);
        one_plus_a1 = p * Ts / (1.0 + p * Ts);
    } else {
        b_dr = -2.0 * c_ff / p / (2.0 + p * Ts);
        one_plus_a1 = 2.0 * p * Ts / (2.0 + p * Ts);
    }
    if (cfg->feedforward == P2D_FF_NONE) {
        g->ff_Fr0 = 0.0;
        g->ff_b_dr = 0.0;
        g->ff_one_plus_a1 = 0.0;
        g->ff_Kd_per_Ts = 0.0;
    } else {
        /* Fr(0) = -J alpha / (4 zeta^2 m) (eq 11 at s = 0) */
        g->ff_Fr0 = -Kp / (4.0 * zeta * zeta * m_eff) * w_per_T;
        g->ff_b_dr = b_dr * w_per_T;
        g->ff_one_plus_a1 = one_plus_a1;
        /* Kd s by the backward difference: Kd (r[k] - r[k-1]) / Ts */
        g->ff_Kd_per_Ts = Kp * A / Ts * w_per_T;
    }
    /* surface PMSM: T = kt iq, kt = 1.5 p psi_f; the limit |iq| <= i_max is |T| <= kt i_max */
    g->iq_per_T = T_fs / (kt * I_fs);
    g->T_max = kt * (double)cfg->i_max_A / T_fs;
    g->iq_max = (double)cfg->i_max_A / I_fs;
}

/* The gains that multiply a speed (and the torque-to-current gain) are below the bound of speed_fixed.h. */
static bool gains_bounded(const p2d_speed_fixed_gains_t *g)
{
    return fabs(g->b_e0) < P2D_FIXED_GAIN_BOUND && fabs(g->Ki_Ts) < P2D_FIXED_GAIN_BOUND &&
           fabs(g->ff_Fr0) < P2D_FIXED_GAIN_BOUND && fabs(g->ff_b_dr) < P2D_FIXED_GAIN_BOUND &&
           fabs(g->ff_Kd_per_Ts) < P2D_FIXED_GAIN_BOUND;
}

/* floor(x 2^bits) for 0 <= x <= 1 */
static int32_t floor_scaled(double x, uint32_t bits)
{
    const double scaled = x * (mantissa_bound(bits) + 1.0);
    return (int32_t)(scaled >= mantissa_bound(bits) ? mantissa_bound(bits) : scaled);
}

/* Validate the scalings for `bits` fractional bits, with the gains g. */
static p2d_status_t scaling_status(uint32_t bits, const p2d_speed_fixed_gains_t *g)
{
    int32_t m;
    uint32_t s;
    if (!gains_bounded(g)) return P2D_ERR_SPEED_FULL_SCALE;
    if (bits == 31u) {
        /* one LSB of error moves the Q62 integrator: R(m, s - 31) >= 1 (speed_q31.c) */
        p2d_fixed_gain(g->Ki_Ts, bits, &m, &s);
        if (s > 31u && p2d_round_shift64(m, s - 31u) < 1) return P2D_ERR_SPEED_FULL_SCALE;
    }
    if (!(g->T_max <= 1.0) || floor_scaled(g->T_max, bits) < 1) return P2D_ERR_TORQUE_FULL_SCALE;
    if (!(g->iq_max <= 1.0) || floor_scaled(g->iq_max, bits) < 1 || !(g->iq_per_T < P2D_FIXED_GAIN_BOUND)) {
        return P2D_ERR_CURRENT_FULL_SCALE;
    }
    return P2D_OK;
}

/* Validate cfg for `bits` fractional bits and compute its gains into *gains (written only on success). */
static p2d_status_t fixed_gains(const p2d_speed_fixed_config_t *cfg, uint32_t bits, p2d_speed_fixed_gains_t *gains)
{
    p2d_speed_t check;
    p2d_speed_fixed_gains_t g;
    p2d_status_t status;
    if (cfg == 0 || gains == 0) return P2D_ERR_NULL;
    /* the design and the drive: the float controller's rules */
    status = p2d_speed_init(&check, &cfg->speed);
    if (status != P2D_OK) return status;
    if (cfg->speed.Ld_H != cfg->speed.Lq_H) return P2D_ERR_SALIENT;
    if (!p2d_is_positive(cfg->speed_full_scale_radps)) return P2D_ERR_SPEED_FULL_SCALE;
    if (!p2d_is_positive(cfg->torque_full_scale_Nm)) return P2D_ERR_TORQUE_FULL_SCALE;
    if (!p2d_is_positive(cfg->current_full_scale_A)) return P2D_ERR_CURRENT_FULL_SCALE;
    design_gains(&cfg->speed, (double)cfg->speed_full_scale_radps, (double)cfg->torque_full_scale_Nm,
                 (double)cfg->current_full_scale_A, &g);
    status = scaling_status(bits, &g);
    if (status != P2D_OK) return status;
    *gains = g;
    return P2D_OK;
}

p2d_status_t p2d_speed_q15_gains(const p2d_speed_fixed_config_t *cfg, p2d_speed_fixed_gains_t *gains)
{
    return fixed_gains(cfg, 15u, gains);
}

p2d_status_t p2d_speed_q31_gains(const p2d_speed_fixed_config_t *cfg, p2d_speed_fixed_gains_t *gains)
{
    return fixed_gains(cfg, 31u, gains);
}

p2d_status_t p2d_speed_fixed_prepare(const p2d_speed_fixed_config_t *cfg, uint32_t bits,
                                     const p2d_speed_fixed_config_t *active, p2d_speed_fixed_gains_t *gains,
                                     int32_t *T_max, int32_t *iq_max)
{
    p2d_status_t status = fixed_gains(cfg, bits, gains);
    if (status != P2D_OK) return status;
    /* set_config keeps the scalings: the state is held in their LSBs */
    if (active != 0) {
        if (cfg->speed_full_scale_radps != active->speed_full_scale_radps) return P2D_ERR_SPEED_FULL_SCALE;
        if (cfg->torque_full_scale_Nm != active->torque_full_scale_Nm) return P2D_ERR_TORQUE_FULL_SCALE;
        if (cfg->current_full_scale_A != active->current_full_scale_A) return P2D_ERR_CURRENT_FULL_SCALE;
    }
    *T_max = floor_scaled(gains->T_max, bits);
    *iq_max = floor_scaled(gains->iq_max, bits);
    return P2D_OK;
}
