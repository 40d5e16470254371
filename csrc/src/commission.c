/*
 * Self-commissioning of a PMSM: see pmsm2dof/commission.h for the sequence
 * and the equations.
 */
#include "pmsm2dof/commission.h"

#include <math.h>

#include "pi.h"

#define P2D_INV_SQRT3 0.57735026918962576f /* 1/sqrt(3) */
#define P2D_INV_SQRT2 0.70710678118654752f /* 1/sqrt(2) = sin(w0 Ts / 2) at w0 Ts = pi / 2 */
#define P2D_TWO_PI 6.28318530717958648f    /* 2 pi */
#define P2D_PI_3 1.04719755119659775f      /* pi / 3: the sectors of the phase-current signs */
#define P2D_MAX_SAMPLES 16777216.0f        /* 2^24: phase lengths stay exact in float32 */

/* Relative tolerance of a current level (end of the alignment, Rs levels). */
#define P2D_LEVEL_TOL 0.1f
/* Injection: ripple i_test / 2 peak to peak, accepted within [0.7, 1.4] of it; at the voltage limit down to 1/16. */
#define P2D_RIPPLE_PER_I_TEST 0.5f
#define P2D_RIPPLE_LOW 0.7f
#define P2D_RIPPLE_HIGH 1.4f
#define P2D_RIPPLE_MIN 0.0625f
#define P2D_SEARCH_PERIODS 32u   /* most periods of the amplitude search */
#define P2D_SETTLE_PERIODS 2u    /* periods between the search and the averaging */
#define P2D_U_START 1e-4f        /* first amplitude of PROBE, per unit of u_dc / sqrt(3) */
#define P2D_U_HEADROOM 0.9f      /* bias plus square wave within 0.9 u_dc / sqrt(3) */
#define P2D_ZERO_PER_TAU 0.25f   /* zero of the loop before Rs is known: 1 / (4 tau_i) [1/tau_i] */
#define P2D_RHO_MAX 0.5f         /* Rs G below it: the injection measures L, not Rs */
#define P2D_ASYMMETRY_MAX 0.05f  /* |G_qd - G_dq| / mean(G_dd, G_qq) above it: the rotor moved */
#define P2D_RS_SPREAD_MAX 0.02f  /* |Rs of the early half-windows - Rs of the late ones| / Rs above it: it moved */
#define P2D_UQ_MAX 0.02f         /* |mean uq| / (ud_high - ud_low) of an Rs level above it: the rotor crept */
#define P2D_COHERENCE_MIN 0.9f   /* |sum psi_a| / sum |psi_a| below it: the rotor did not follow */
#define P2D_ID_R_MIN 0.5f        /* mean id_r / i_spin below it (a load angle beyond 60 degrees): it did not follow */
#define P2D_PSI_SPREAD_MAX 0.02f /* |psi_f of the late half-window - of the early one| / psi_f above it: it swung */
#define P2D_SLIP_MAX 0.02f       /* rotor speed off the frame's by more than this share over the window: slip */

/* Stages of an injection test. */
enum { HF_SEARCH = 0, HF_SETTLE = 1, HF_AVERAGE = 2 };

/* Outcome of one sample of a phase. */
typedef enum { RUN, NEXT, FAIL } p2d_outcome_t;

static const char *const PHASE_NAME[P2D_PHASE_COUNT] = {
    "probe", "align", "rs_low", "rs_high", "ld", "lq", "ramp_up", "spin", "ramp_down", "done", "failed",
};

static const char *const REASON_TEXT[P2D_REASON_COUNT] = {
    "",
    "the current did not reach its level: the DC link is too low for i_test_A through Rs (lower i_test_A), a "
    "phase is open, or the current measurement is wrong (gain, offset, phase order)",
    "the current exceeded i_trip_A: check the current measurement's sign and phase order, or raise i_trip_A",
    "the rotor moved during a standstill test: a load or cogging torque that i_test_A does not hold still "
    "(raise i_test_A, uncouple the load), or a swing that has not settled (longer t_align_s or t_level_s)",
    "the voltage reached u_dc/sqrt(3) before the flux test's speed: lower w_e_spin_radps or i_spin_A",
    "the rotor did not follow the I-f frame steadily (it slipped, stalled, is blocked, or still swung about "
    "it): raise i_spin_A, lengthen t_ramp_s and t_spin_s, uncouple the load, or raise w_e_spin_radps",
    "the measurement does not determine a parameter: Rs not > 0 (current sensing), an inductance whose "
    "impedance at 1/(4 Ts_s) is not at least twice Rs (sample faster), or psi_f not > 0 (raise w_e_spin_radps)",
};

const char *p2d_commission_phase_name(p2d_commission_phase_t phase)
{
    if ((unsigned)phase >= (unsigned)P2D_PHASE_COUNT) return "unknown";
    return PHASE_NAME[phase];
}

const char *p2d_commission_reason_text(p2d_commission_reason_t reason)
{
    if ((unsigned)reason >= (unsigned)P2D_REASON_COUNT) return "unknown reason";
    return REASON_TEXT[reason];
}

/*
 * The length t_s / Ts_s rounded to whole samples if it is finite and within
 * [min_samples, 2^24] (to within the rounding to whole samples), else 0.
 */
static uint32_t samples_of(float t_s, float Ts_s, float min_samples)
{
    float n = t_s / Ts_s;
    if (!isfinite(n) || !(n + 0.5f >= min_samples) || !(n <= P2D_MAX_SAMPLES)) return 0u;
    return (uint32_t)(n + 0.5f);
}

/* Phase lengths of a configuration [samples]. */
typedef struct {
    uint32_t n_align, n_level, n_inductance, n_ramp, n_spin;
} p2d_lengths_t;

/* Validate cfg and compute its phase lengths into *len. */
static p2d_status_t commission_lengths(const p2d_commission_config_t *cfg, p2d_lengths_t *len)
{
    uint32_t n_align, n_level, n_inductance, n_ramp, n_spin;
    float tau_samples, i_big, trip2;
    if (!p2d_is_positive(cfg->Ts_s)) return P2D_ERR_TS;
    tau_samples = cfg->tau_i_s / cfg->Ts_s;
    if (!isfinite(cfg->tau_i_s) || !isfinite(tau_samples) || !(tau_samples >= 10.0f)) return P2D_ERR_TAU_I;
    if (!p2d_is_positive(cfg->i_test_A)) return P2D_ERR_I_TEST;
    if (!p2d_is_positive(cfg->i_spin_A)) return P2D_ERR_I_SPIN;
    i_big = cfg->i_test_A > cfg->i_spin_A ? cfg->i_test_A : cfg->i_spin_A;
    /* the step compares ||i||^2 with i_trip^2: that must be a normal float, in [2^-126, inf) */
    trip2 = cfg->i_trip_A * cfg->i_trip_A;
    if (!(trip2 >= 0x1p-126f && trip2 < INFINITY) || !(cfg->i_trip_A >= 1.5f * i_big)) return P2D_ERR_I_TRIP;
    n_align = samples_of(cfg->t_align_s, cfg->Ts_s, 20.0f * tau_samples);
    if (n_align == 0u) return P2D_ERR_T_ALIGN;
    n_level = samples_of(cfg->t_level_s, cfg->Ts_s, 20.0f * tau_samples);
    if (n_level == 0u) return P2D_ERR_T_LEVEL;
    n_inductance = samples_of(cfg->t_inductance_s, cfg->Ts_s, 64.0f);
    if (n_inductance == 0u) return P2D_ERR_T_INDUCTANCE;
    n_ramp = samples_of(cfg->t_ramp_s, cfg->Ts_s, 100.0f);
    if (n_ramp == 0u) return P2D_ERR_T_RAMP;
    n_spin = samples_of(cfg->t_spin_s, cfg->Ts_s, 20.0f * tau_samples);
    if (n_spin == 0u) return P2D_ERR_T_SPIN;
    if (!p2d_is_positive(cfg->w_e_spin_radps) || !(cfg->w_e_spin_radps * cfg->Ts_s <= 0.1f)) return P2D_ERR_W_E_SPIN;
    if (cfg->voltage_delay_samples > 1u) return P2D_ERR_VOLTAGE_DELAY;

    len->n_align = n_align;
    len->n_level = n_level;
    /* whole injection periods */
    len->n_inductance = n_inductance & ~3u;
    len->n_ramp = n_ramp;
    len->n_spin = n_spin;
    return P2D_OK;
}

static void sum_clear(p2d_sum_t *s)
{
    s->sum = 0.0f;
    s->carry = 0.0f;
}

/* Kahan: sum += x, with the rounding error of each addition carried into the next */
static void sum_add(p2d_sum_t *s, float x)
{
    float y = x - s->carry;
    float t = s->sum + y;
    s->carry = (t - s->sum) - y;
    s->sum = t;
}

/* A new injection test: amplitude search from the present hf_U_V, partial and total transforms cleared. */
static void hf_start(p2d_commission_t *c)
{
    c->hf_n = 0u;
    c->hf_stage = HF_SEARCH;
    c->hf_periods = 0u;
    c->hf_ix_c_A = 0.0f;
    c->hf_ix_s_A = 0.0f;
    c->hf_iy_c_A = 0.0f;
    c->hf_iy_s_A = 0.0f;
    c->hf_u_c_V = 0.0f;
    c->hf_u_s_V = 0.0f;
    sum_clear(&c->sum_ix_c_A);
    sum_clear(&c->sum_ix_s_A);
    sum_clear(&c->sum_iy_c_A);
    sum_clear(&c->sum_iy_s_A);
    sum_clear(&c->sum_u_c_V);
    sum_clear(&c->sum_u_s_V);
}

/* Enter phase: its sample count and its sums from zero. */
static void start_phase(p2d_commission_t *c, p2d_commission_phase_t phase)
{
    c->phase = phase;
    c->k = 0u;
    sum_clear(&c->sum_ud_V);
    sum_clear(&c->sum_uq_V);
    sum_clear(&c->sum_id_A);
    sum_clear(&c->sum_ud_late_V);
    sum_clear(&c->sum_id_late_A);
    sum_clear(&c->sum_psi_Wb);
    sum_clear(&c->sum_psi_late_Wb);
    sum_clear(&c->sum_psi_d_Wb);
    sum_clear(&c->sum_psi_q_Wb);
    sum_clear(&c->sum_psi_d_late_Wb);
    sum_clear(&c->sum_psi_q_late_Wb);
    sum_clear(&c->sum_id_r_A);
    sum_clear(&c->sum_id_r_late_A);
    sum_clear(&c->sum_turn_rad);
    sum_clear(&c->sum_turn_late_rad);
    if (phase == P2D_PHASE_PROBE || phase == P2D_PHASE_LD || phase == P2D_PHASE_LQ) hf_start(c);
}

p2d_status_t p2d_commission_init(p2d_commission_t *c, const p2d_commission_config_t *cfg)
{
    p2d_lengths_t len;
    p2d_status_t status;
    if (c == 0 || cfg == 0) return P2D_ERR_NULL;
    status = commission_lengths(cfg, &len);
    if (status != P2D_OK) return status;
    c->config = *cfg;
    c->n_align = len.n_align;
    c->n_level = len.n_level;
    c->n_inductance = len.n_inductance;
    c->n_ramp = len.n_ramp;
    c->n_spin = len.n_spin;
    c->inv_n_ramp = 1.0f / (float)len.n_ramp;
    c->theta_lead = cfg->Ts_s * ((float)cfg->voltage_delay_samples + 0.5f);
    c->failed_phase = P2D_PHASE_PROBE;
    c->reason = P2D_REASON_NONE;
    c->theta_e_rad = 0.0f;
    c->w_e_radps = 0.0f;
    c->id_prev_A = 0.0f;
    c->iq_prev_A = 0.0f;
    /* the current loop is designed at the end of PROBE and stepped only after */
    c->current.x_d_V = 0.0f;
    c->current.x_q_V = 0.0f;
    c->current.fault_count = 0u;
    c->u_hold_d_V = 0.0f;
    c->u_hold_q_V = 0.0f;
    c->hf_U_V = 0.0f;
    c->ud_low_V = 0.0f;
    c->id_low_A = 0.0f;
    c->ud_low_early_V = 0.0f;
    c->id_low_early_A = 0.0f;
    c->ud_high_V = 0.0f;
    c->uq_high_V = 0.0f;
    c->id_high_A = 0.0f;
    c->G_dd_A_per_V = 0.0f;
    c->c_qd = 0.0f;
    c->G_qq_A_per_V = 0.0f;
    c->c_dq = 0.0f;
    c->L_probe_H = 0.0f;
    c->Rs_ohm = 0.0f;
    c->u_err_V = 0.0f;
    c->Ld_H = 0.0f;
    c->Lq_H = 0.0f;
    c->rs_spread = 0.0f;
    c->uq_ratio = 0.0f;
    c->uq_low_V = 0.0f;
    c->asymmetry = 0.0f;
    c->coherence = 0.0f;
    c->psi_spread = 0.0f;
    c->slip = 0.0f;
    c->psi_d_prev_Wb = 0.0f;
    c->psi_q_prev_Wb = 0.0f;
    c->psi_f_Wb = 0.0f;
    c->fault_count = 0u;
    start_phase(c, P2D_PHASE_PROBE);
    return P2D_OK;
}

/*
 * (ud, uq) scaled onto the circle of radius u_lim when it is outside, into
 * out, keeping the direction; true when it was outside.
 */
static bool voltage_limited(float ud, float uq, float u_lim, p2d_commission_output_t *out)
{
    /* ||u|| = u_big sqrt((ud/u_big)^2 + (uq/u_big)^2): no square overflows */
    float u_big = fabsf(ud) > fabsf(uq) ? fabsf(ud) : fabsf(uq);
    float norm = 0.0f;
    if (u_big > 0.0f) norm = u_big * p2d_sqrt_nonnegative(fmaf(ud / u_big, ud / u_big, (uq / u_big) * (uq / u_big)));
    out->ud_V = norm > u_lim ? u_lim * (ud / norm) : ud;
    out->uq_V = norm > u_lim ? u_lim * (uq / norm) : uq;
    return norm > u_lim;
}

/* The routine's current loop for an inductance L_H and a zero Ki / Kp = R_ohm / L_H (eq 3). */
static bool current_loop(p2d_commission_t *c, float R_ohm, float L_H)
{
    p2d_current_config_t cfg;
    cfg.Rs_ohm = R_ohm;
    cfg.Ld_H = L_H;
    cfg.Lq_H = L_H;
    cfg.psi_f_Wb = 0.0f;
    cfg.tau_i_s = c->config.tau_i_s;
    cfg.Ts_s = c->config.Ts_s;
    cfg.method = P2D_TUSTIN;
    cfg.anti_windup = P2D_AW_BACK_CALCULATION;
    cfg.decouple = false;
    return p2d_current_init(&c->current, &cfg) == P2D_OK;
}

/*
 * One sample of the current loop at (id_ref, iq_ref) into out; false when its
 * non-finite policy engaged (an overflow). Every phase calls it before it
 * changes anything, so that the routine then stays as it was.
 */
static bool closed_loop(p2d_commission_t *c, float id_ref_A, float iq_ref_A, float id_A, float iq_A, float u_dc_V,
                        p2d_commission_output_t *out, bool *saturated)
{
    p2d_current_output_t v;
    /* the frame is not the rotor's: no decoupling (w_e = 0), the integrators take the back-EMF */
    p2d_current_compute(&c->current, id_ref_A, iq_ref_A, id_A, iq_A, 0.0f, u_dc_V, &v);
    if (v.fault) return false;
    p2d_current_update(&c->current, &v, v.ud_ref_V, v.uq_ref_V);
    out->ud_V = v.ud_ref_V;
    out->uq_V = v.uq_ref_V;
    out->id_ref_A = id_ref_A;
    out->iq_ref_A = iq_ref_A;
    *saturated = v.saturated;
    return true;
}

/* The integrators of the current loop at the voltage (ud, uq): the loop starts from it without a jump. */
static void current_loop_from(p2d_commission_t *c, float ud_V, float uq_V)
{
    c->current.x_d_V = ud_V;
    c->current.x_q_V = uq_V;
}

/* Weight of sample n of a period in the transform at w0 = pi / (2 Ts): cos -> 1, 0, -1, 0 */
static float hf_cos(uint32_t n, float x) { return n == 0u ? x : (n == 2u ? -x : 0.0f); }

/* sin -> 0, 1, 0, -1 */
static float hf_sin(uint32_t n, float x) { return n == 1u ? x : (n == 3u ? -x : 0.0f); }

/* |(a, b)| without overflow of the squares */
static float magnitude(float a, float b)
{
    float big = fabsf(a) > fabsf(b) ? fabsf(a) : fabsf(b);
    if (!(big > 0.0f)) return big;
    return big * p2d_sqrt_nonnegative(fmaf(a / big, a / big, (b / big) * (b / big)));
}

/*
 * End of an amplitude-search period with the transform magnitude M of its
 * current (the ripple peak to peak): the next amplitude, or the end of the
 * search. U_max is what the bias leaves of 0.9 u_dc / sqrt(3).
 */
static p2d_outcome_t hf_search(p2d_commission_t *c, float M_A, float U_max_V, p2d_commission_reason_t *why)
{
    const float target = P2D_RIPPLE_PER_I_TEST * c->config.i_test_A;
    float ratio;
    if (!(U_max_V > 0.0f)) {
        *why = P2D_REASON_CURRENT_NOT_REACHED;
        return FAIL;
    }
    if (c->hf_U_V > U_max_V) {
        /* an amplitude from the test before beyond what this bias leaves would be clipped (its mean moves) */
        c->hf_U_V = U_max_V;
        return RUN;
    }
    if (M_A >= P2D_RIPPLE_LOW * target && M_A <= P2D_RIPPLE_HIGH * target) return NEXT;
    if (c->hf_U_V >= U_max_V && M_A < P2D_RIPPLE_LOW * target) {
        /* the voltage limit: a smaller ripple is still measured, none is not */
        if (M_A >= P2D_RIPPLE_MIN * target) return NEXT;
        *why = P2D_REASON_CURRENT_NOT_REACHED;
        return FAIL;
    }
    if (c->hf_periods >= P2D_SEARCH_PERIODS) {
        *why = P2D_REASON_CURRENT_NOT_REACHED;
        return FAIL;
    }
    /* the ripple is proportional to U: U <- U target / M, by at most 4x a period */
    ratio = M_A > 0.25f * target ? target / M_A : 4.0f;
    if (ratio < 0.25f) ratio = 0.25f;
    c->hf_U_V = c->hf_U_V * ratio < U_max_V ? c->hf_U_V * ratio : U_max_V;
    return RUN;
}

/*
 * One sample of an injection test: bias (bx, by) held on the injected axis x
 * and the other axis y, plus the square wave +U, -U, -U, +U on x; dix, diy
 * the measured currents' changes since the previous sample. The command goes
 * to *ux, *uy. NEXT when the averaging is complete (its transforms are in the
 * sums).
 *
 * The currents enter by their differences di[k] = i[k] - i[k-1]: their
 * transform at w0 is (e^(j w0 Ts) - 1) = (-1 + j) times that of the currents,
 * |.| = sqrt(2) (for the signal and for white noise alike), while a drift of
 * the bias current (a settling, the motor warming) turns into a near constant
 * that the zero-mean weights cancel instead of leaking into the transform.
 */
static p2d_outcome_t hf_sample(p2d_commission_t *c, float dix_A, float diy_A, float bx_V, float by_V, float u_lim_V,
                               float *ux_V, float *uy_V, p2d_commission_reason_t *why)
{
    const uint32_t n = c->hf_n;
    p2d_commission_output_t u;
    p2d_outcome_t next = RUN;
    /* u_x[k] = b_x + U sq[n],  sq = +1, -1, -1, +1: the current ripple is centred on its value at a period start */
    (void)voltage_limited(bx_V + (n == 0u || n == 3u ? c->hf_U_V : -c->hf_U_V), by_V, u_lim_V, &u);
    *ux_V = u.ud_V;
    *uy_V = u.uq_V;
    /* X_c += cos(w0 Ts n) x[k],  X_s += sin(w0 Ts n) x[k], for the currents and the applied voltage */
    c->hf_ix_c_A += hf_cos(n, dix_A);
    c->hf_ix_s_A += hf_sin(n, dix_A);
    c->hf_iy_c_A += hf_cos(n, diy_A);
    c->hf_iy_s_A += hf_sin(n, diy_A);
    c->hf_u_c_V += hf_cos(n, u.ud_V);
    c->hf_u_s_V += hf_sin(n, u.ud_V);
    if (n < 3u) {
        c->hf_n = n + 1u;
        return RUN;
    }
    /* end of a period */
    c->hf_n = 0u;
    c->hf_periods++;
    if (c->hf_stage == HF_SEARCH) {
        float U_max = P2D_U_HEADROOM * u_lim_V - magnitude(bx_V, by_V);
        /* the ripple peak to peak: the transform of the differences over sqrt(2) */
        next = hf_search(c, magnitude(c->hf_ix_c_A, c->hf_ix_s_A) * P2D_INV_SQRT2, U_max, why);
        if (next == NEXT) {
            c->hf_stage = HF_SETTLE;
            c->hf_periods = 0u;
            next = RUN;
        }
    } else if (c->hf_stage == HF_SETTLE) {
        if (c->hf_periods >= P2D_SETTLE_PERIODS) {
            c->hf_stage = HF_AVERAGE;
            c->hf_periods = 0u;
        }
    } else {
        sum_add(&c->sum_ix_c_A, c->hf_ix_c_A);
        sum_add(&c->sum_ix_s_A, c->hf_ix_s_A);
        sum_add(&c->sum_iy_c_A, c->hf_iy_c_A);
        sum_add(&c->sum_iy_s_A, c->hf_iy_s_A);
        sum_add(&c->sum_u_c_V, c->hf_u_c_V);
        sum_add(&c->sum_u_s_V, c->hf_u_s_V);
        if (4u * c->hf_periods >= c->n_inductance) next = NEXT;
    }
    c->hf_ix_c_A = 0.0f;
    c->hf_ix_s_A = 0.0f;
    c->hf_iy_c_A = 0.0f;
    c->hf_iy_s_A = 0.0f;
    c->hf_u_c_V = 0.0f;
    c->hf_u_s_V = 0.0f;
    return next;
}

/*
 * The averaged transforms of an injection test: G = |I_x| / |U_x| [A/V]
 * (|I_x| = |dI_x| / sqrt(2), hf_sample) and the cross ratio Re(I_y / I_x) =
 * (dI_y . dI_x) / |dI_x|^2. False if G is not finite and > 0.
 */
static bool hf_admittance(const p2d_commission_t *c, float *G_A_per_V, float *cross)
{
    float Ix = magnitude(c->sum_ix_c_A.sum, c->sum_ix_s_A.sum);
    float Ux = magnitude(c->sum_u_c_V.sum, c->sum_u_s_V.sum);
    float G = Ix / Ux * P2D_INV_SQRT2;
    /* Re(I_y conj(I_x)) / |I_x|^2, with I_x / |I_x| first so that nothing overflows */
    *cross =
        ((c->sum_iy_c_A.sum / Ix) * (c->sum_ix_c_A.sum / Ix) + (c->sum_iy_s_A.sum / Ix) * (c->sum_ix_s_A.sum / Ix));
    *G_A_per_V = G;
    return p2d_is_positive(G) && isfinite(*cross);
}

/*
 * L [H] of an RL branch whose sampled response to a held voltage has the
 * admittance magnitude G_A_per_V at w0 = pi / (2 Ts) (commission.h):
 *   L = Rs Ts / (2 asinh(y)) = Ts sqrt(1 - rho^2) / (sqrt(2) G S(y)),
 *   y = rho / (sqrt(2) sqrt(1 - rho^2)),  rho = Rs G,  S(y) = asinh(y) / y.
 * S by its series 1 - y^2/6 + 3 y^4/40 - 15 y^6/336, within 2e-5 for
 * rho < 0.5 (y < 0.41). Returns 0 when rho >= 0.5: the branch is then
 * mostly resistive at w0 and L is poorly determined.
 */
static float inductance_of(float G_A_per_V, float Rs_ohm, float Ts_s)
{
    float rho = Rs_ohm * G_A_per_V;
    float root, y2, S;
    if (!(rho >= 0.0f && rho < P2D_RHO_MAX)) return 0.0f;
    root = p2d_sqrt_nonnegative(1.0f - rho * rho);
    y2 = 0.5f * (rho / root) * (rho / root);
    S = fmaf(y2, fmaf(y2, fmaf(y2, -15.0f / 336.0f, 3.0f / 40.0f), -1.0f / 6.0f), 1.0f);
    return Ts_s * root / (G_A_per_V * S) * P2D_INV_SQRT2;
}

/* |mean - level| <= 10 % of the level */
static bool at_level(float i_A, float level_A) { return fabsf(i_A - level_A) <= P2D_LEVEL_TOL * level_A; }

/*
 * The q reference of the standstill phases under current control, -g x_q: a
 * rotor that swings induces a back-EMF that the q integrator x_q takes up
 * (x_q = Rs iq + e_q at the swing's low frequency), and iq = -g (Rs iq + e_q)
 * = -g e_q / (1 + g Rs) brakes it with the torque of the machine's own
 * short circuit, psi_f / Rs per unit of speed, when g Rs >> 1; 0 at rest. The
 * loop x_q -> iq_ref -> x_q is stable for any g in continuous time; sampled,
 * its integrator x[k] = (1 - g Ki Ts) x[k-1] + ... needs g Ki Ts < 2:
 * g = 1 / (4 Ki Ts), Ki = R_zero / tau_i the loop's integral gain.
 */
static float damping_gain(const p2d_commission_t *c, float R_zero_ohm)
{
    return 0.25f * c->config.tau_i_s / (R_zero_ohm * c->config.Ts_s);
}

/* PROBE: the square wave on d at zero bias; at its end the first inductance and the current loop. */
static p2d_outcome_t phase_probe(p2d_commission_t *c, float id_A, float iq_A, float u_lim_V,
                                 p2d_commission_output_t *out, p2d_commission_reason_t *why)
{
    float G, cross, L;
    p2d_outcome_t next;
    if (c->k++ == 0u) c->hf_U_V = P2D_U_START * u_lim_V;
    next = hf_sample(c, id_A - c->id_prev_A, iq_A - c->iq_prev_A, 0.0f, 0.0f, u_lim_V, &out->ud_V, &out->uq_V, why);
    if (next != NEXT) return next;
    /* Rs unknown yet, and small against w0 L: L = Ts / (sqrt(2) G) */
    L = hf_admittance(c, &G, &cross) ? c->config.Ts_s / G * P2D_INV_SQRT2 : 0.0f;
    /* Kp = L / tau_i, zero at 1 / (4 tau_i): stable and without overshoot whatever Rs */
    if (!p2d_is_positive(L) || !current_loop(c, P2D_ZERO_PER_TAU * L / c->config.tau_i_s, L)) {
        *why = P2D_REASON_NOT_IDENTIFIABLE;
        return FAIL;
    }
    c->L_probe_H = L;
    c->g_damp_A_per_V = damping_gain(c, P2D_ZERO_PER_TAU * L / c->config.tau_i_s);
    return NEXT;
}

/*
 * ALIGN: the d current ramped to i_test_A over the first half, held over the
 * second, the swing damped (damping_gain). The mean of ud over the last eighth,
 * over that of id, is R_hold = Rs plus the inverter's error per ampere.
 */
static p2d_outcome_t phase_align(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V,
                                 p2d_commission_output_t *out, p2d_commission_reason_t *why)
{
    const uint32_t n_ramp = c->n_align / 2u;
    const uint32_t n_hold_from = c->n_align - c->n_align / 8u;
    /* id_ref[k] = i_test min(1, (k + 1) / n_ramp) */
    const float id_ref = c->k < n_ramp ? c->config.i_test_A * ((float)(c->k + 1u) / (float)n_ramp) : c->config.i_test_A;
    bool saturated = false;
    if (!closed_loop(c, id_ref, -c->g_damp_A_per_V * c->current.x_q_V, id_A, iq_A, u_dc_V, out, &saturated)) {
        return FAIL;
    }
    if (c->k >= n_hold_from) {
        sum_add(&c->sum_ud_V, out->ud_V);
        sum_add(&c->sum_id_A, id_A);
    }
    if (++c->k < c->n_align) return RUN;
    /*
     * the loop's zero now at R_hold / L_probe, R_hold >= Rs, so that a resistive motor settles in a few
     * tau_i too; never below 1 / (4 tau_i). The integrators keep the voltage they hold.
     */
    {
        const float id_mean = c->sum_id_A.sum / (float)(c->n_align - n_hold_from);
        const float R_hold = c->sum_ud_V.sum / c->sum_id_A.sum;
        const float ud_V = c->current.x_d_V, uq_V = c->current.x_q_V;
        float R_zero = P2D_ZERO_PER_TAU * c->L_probe_H / c->config.tau_i_s;
        if (saturated || !at_level(id_mean, c->config.i_test_A)) {
            *why = P2D_REASON_CURRENT_NOT_REACHED;
            return FAIL;
        }
        if (R_hold > R_zero) R_zero = R_hold;
        if (!current_loop(c, R_zero, c->L_probe_H)) {
            *why = P2D_REASON_NOT_IDENTIFIABLE;
            return FAIL;
        }
        c->g_damp_A_per_V = damping_gain(c, R_zero);
        current_loop_from(c, ud_V, uq_V);
    }
    return NEXT;
}

/* Rs = (ud_high - ud_low) / (id_high - id_low) of mean voltages and currents */
static float resistance(float ud_low_V, float id_low_A, float ud_high_V, float id_high_A)
{
    return (ud_high_V - ud_low_V) / (id_high_A - id_low_A);
}

/*
 * RS_LOW, RS_HIGH: the d current at i_test_A / 2 or i_test_A; means of ud,
 * uq, id over the second half, each half of it also on its own. A change of
 * the holding current moves a rotor under load, its swing damped
 * (damping_gain). A swing still going, or a current still settling, would
 * enter Rs; then Rs of the early halves of the two windows differs from Rs
 * of the late halves, which a still rotor keeps equal.
 */
static p2d_outcome_t phase_rs(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V, p2d_commission_output_t *out,
                              p2d_commission_reason_t *why)
{
    const bool high = c->phase == P2D_PHASE_RS_HIGH;
    const float level = high ? c->config.i_test_A : 0.5f * c->config.i_test_A;
    const uint32_t n_settle = c->n_level / 2u, n_late = (c->n_level - n_settle) / 2u;
    const uint32_t n_early = c->n_level - n_settle - n_late;
    float ud_early, id_early, ud_late, id_late, Rs_early, Rs_late;
    bool saturated = false;
    if (!closed_loop(c, level, -c->g_damp_A_per_V * c->current.x_q_V, id_A, iq_A, u_dc_V, out, &saturated)) {
        return FAIL;
    }
    if (c->k >= n_settle) {
        if (c->k == n_settle && (saturated || !at_level(id_A, level))) {
            *why = P2D_REASON_CURRENT_NOT_REACHED;
            return FAIL;
        }
        /* early half-window into sum_ud_V, sum_id_A; late into sum_ud_late_V, sum_id_late_A */
        sum_add(c->k < n_settle + n_early ? &c->sum_ud_V : &c->sum_ud_late_V, out->ud_V);
        sum_add(c->k < n_settle + n_early ? &c->sum_id_A : &c->sum_id_late_A, id_A);
        sum_add(&c->sum_uq_V, out->uq_V);
    }
    if (++c->k < c->n_level) return RUN;
    ud_early = c->sum_ud_V.sum / (float)n_early;
    id_early = c->sum_id_A.sum / (float)n_early;
    ud_late = c->sum_ud_late_V.sum / (float)n_late;
    id_late = c->sum_id_late_A.sum / (float)n_late;
    if (!at_level(0.5f * (id_early + id_late), level) || !isfinite(ud_early) || !isfinite(ud_late)) {
        *why = P2D_REASON_CURRENT_NOT_REACHED;
        return FAIL;
    }
    if (!high) {
        c->ud_low_V = 0.5f * (ud_early + ud_late);
        c->uq_low_V = c->sum_uq_V.sum / (float)(n_early + n_late);
        c->id_low_A = 0.5f * (id_early + id_late);
        c->ud_low_early_V = ud_early;
        c->id_low_early_A = id_early;
        return NEXT;
    }
    c->ud_high_V = 0.5f * (ud_early + ud_late);
    c->uq_high_V = c->sum_uq_V.sum / (float)(n_early + n_late);
    c->id_high_A = 0.5f * (id_early + id_late);
    c->Rs_ohm = resistance(c->ud_low_V, c->id_low_A, c->ud_high_V, c->id_high_A);
    /* u_err = ud_high - Rs id_high */
    c->u_err_V = fmaf(-c->Rs_ohm, c->id_high_A, c->ud_high_V);
    if (!p2d_is_positive(c->Rs_ohm) || !isfinite(c->u_err_V) || !isfinite(c->uq_high_V)) {
        *why = P2D_REASON_NOT_IDENTIFIABLE;
        return FAIL;
    }
    /* the late halves: ud_low_late = 2 ud_low - ud_low_early (equal weights) */
    Rs_early = resistance(c->ud_low_early_V, c->id_low_early_A, ud_early, id_early);
    Rs_late =
        resistance(2.0f * c->ud_low_V - c->ud_low_early_V, 2.0f * c->id_low_A - c->id_low_early_A, ud_late, id_late);
    c->rs_spread = fabsf(Rs_late - Rs_early) / c->Rs_ohm;
    /* the back-EMF of a rotor that creeps or swings, on q (a still rotor needs no q voltage), per volt of Rs */
    c->uq_ratio = (fabsf(c->uq_low_V) > fabsf(c->uq_high_V) ? fabsf(c->uq_low_V) : fabsf(c->uq_high_V)) /
                  (c->ud_high_V - c->ud_low_V);
    if (!(c->rs_spread <= P2D_RS_SPREAD_MAX) || !(c->uq_ratio <= P2D_UQ_MAX)) {
        *why = P2D_REASON_ROTOR_MOVED;
        return FAIL;
    }
    /* the injection tests hold the voltage of i_test_A */
    c->u_hold_d_V = c->ud_high_V;
    c->u_hold_q_V = c->uq_high_V;
    return NEXT;
}

/*
 * End of LQ: Ld and Lq from the eigenvalues of the admittance matrix
 *   [G_dd G_dq; G_qd G_qq],  G_qd = c_qd G_dd,  G_dq = c_dq G_qq,
 * symmetric for a still rotor; the eigenvalue whose direction is nearer the
 * frame's d axis is d's: G_d,q = m +- sign(h) sqrt(h^2 + o^2), m = (G_dd + G_qq) / 2,
 * h = (G_dd - G_qq) / 2, o = (G_qd + G_dq) / 2.
 */
static p2d_outcome_t inductances(p2d_commission_t *c, p2d_commission_reason_t *why)
{
    const float G_qd = c->c_qd * c->G_dd_A_per_V, G_dq = c->c_dq * c->G_qq_A_per_V;
    const float m = 0.5f * (c->G_dd_A_per_V + c->G_qq_A_per_V);
    const float h = 0.5f * (c->G_dd_A_per_V - c->G_qq_A_per_V);
    const float r = copysignf(magnitude(h, 0.5f * (G_qd + G_dq)), h);
    c->asymmetry = fabsf(G_qd - G_dq) / m;
    if (!(c->asymmetry <= P2D_ASYMMETRY_MAX)) {
        *why = P2D_REASON_ROTOR_MOVED;
        return FAIL;
    }
    c->Ld_H = inductance_of(m + r, c->Rs_ohm, c->config.Ts_s);
    c->Lq_H = inductance_of(m - r, c->Rs_ohm, c->config.Ts_s);
    /* I-f: Kp = (Ld + Lq) / (2 tau_i) on both axes of a frame that is not the rotor's, Ki = Rs / tau_i */
    if (!p2d_is_positive(c->Ld_H) || !p2d_is_positive(c->Lq_H) ||
        !current_loop(c, c->Rs_ohm, 0.5f * (c->Ld_H + c->Lq_H))) {
        *why = P2D_REASON_NOT_IDENTIFIABLE;
        return FAIL;
    }
    /* RAMP_UP feeds u_err forward, along d at the frame's angle 0: the integrators hold the rest, Rs id_high */
    current_loop_from(c, c->u_hold_d_V - c->u_err_V, c->u_hold_q_V);
    return NEXT;
}

/* LD, LQ: the square wave on d, then q, over the held bias. */
static p2d_outcome_t phase_inductance(p2d_commission_t *c, float id_A, float iq_A, float u_lim_V,
                                      p2d_commission_output_t *out, p2d_commission_reason_t *why)
{
    p2d_outcome_t next;
    if (c->phase == P2D_PHASE_LD) {
        next = hf_sample(c, id_A - c->id_prev_A, iq_A - c->iq_prev_A, c->u_hold_d_V, c->u_hold_q_V, u_lim_V, &out->ud_V,
                         &out->uq_V, why);
    } else {
        next = hf_sample(c, iq_A - c->iq_prev_A, id_A - c->id_prev_A, c->u_hold_q_V, c->u_hold_d_V, u_lim_V, &out->uq_V,
                         &out->ud_V, why);
    }
    c->k++;
    if (next != NEXT) return next;
    if (c->phase == P2D_PHASE_LD) {
        if (!hf_admittance(c, &c->G_dd_A_per_V, &c->c_qd)) {
            *why = P2D_REASON_NOT_IDENTIFIABLE;
            return FAIL;
        }
        return NEXT;
    }
    if (!hf_admittance(c, &c->G_qq_A_per_V, &c->c_dq)) {
        *why = P2D_REASON_NOT_IDENTIFIABLE;
        return FAIL;
    }
    return inductances(c, why);
}

/* theta + dtheta, for theta in [0, 2 pi) and 0 <= dtheta < 2 pi, back into [0, 2 pi) */
static float angle_add(float theta_rad, float dtheta_rad)
{
    float t = theta_rad + dtheta_rad;
    if (t >= P2D_TWO_PI) t -= P2D_TWO_PI;
    /* rounding can leave 2 pi - t below an ulp: then the angle is 0 */
    return t < P2D_TWO_PI ? t : 0.0f;
}

/*
 * The direction of the inverter's voltage error for a current along the
 * angle theta_rad in [0, 2 pi): each phase loses about u_dt sign(i_x), which
 * in alpha beta is (4/3) u_dt against the centre sigma = k pi / 3 of the
 * sector of the phase-current signs that theta lies in, at e^(j phi),
 * phi = sigma - theta in [-pi/6, pi/6] seen from the current. cos and sin
 * of phi by their series to phi^6 and phi^5 (within 3e-6 on the sector):
 * only +, -, *, so that the MCU and the host agree to the bit.
 */
static void error_direction(float theta_rad, float *cos_phi, float *sin_phi)
{
    const uint32_t k = (uint32_t)(theta_rad / P2D_PI_3 + 0.5f);
    const float phi = (float)k * P2D_PI_3 - theta_rad;
    const float phi2 = phi * phi;
    /* cos phi = 1 - phi^2/2 (1 - phi^2/12 (1 - phi^2/30)) */
    *cos_phi = 1.0f - 0.5f * phi2 * (1.0f - phi2 / 12.0f * (1.0f - phi2 / 30.0f));
    /* sin phi = phi (1 - phi^2/6 (1 - phi^2/20)) */
    *sin_phi = phi * (1.0f - phi2 / 6.0f * (1.0f - phi2 / 20.0f));
}

/*
 * One SPIN sample of the flux estimate, w_e the frame speed (> 0), u the
 * current loop's command without the inverter-error feedforward (which the
 * inverter's error takes back):
 *   v = u - Rs i - j w_e Lq i                      vd = ud - Rs id + w_e Lq iq, vq = uq - Rs iq - w_e Lq id
 *   psi_a = v / (j w_e)                            psi_d = vq / w_e, psi_q = -vd / w_e
 *   id_r = i . psi_a / |psi_a|                     the current along the rotor's d axis
 *   dphi = psi_a[k-1] x psi_a[k] / (|psi_a[k-1]| |psi_a[k]|)
 *                                                  sin of the angle psi_a turned by since the previous sample,
 *                                                  the angle itself within (w_r - w_e)^2 Ts^2 / 6 of it
 * summed into the window's half (early or late) when window is set.
 */
static void flux_sample(p2d_commission_t *c, float id_A, float iq_A, float ud_V, float uq_V, bool window, bool late)
{
    const float w = c->w_e_radps, wLq = w * c->Lq_H;
    const float prev = magnitude(c->psi_d_prev_Wb, c->psi_q_prev_Wb);
    float vd, vq, psi_d, psi_q, psi;
    vd = fmaf(wLq, iq_A, fmaf(-c->Rs_ohm, id_A, ud_V));
    vq = fmaf(-wLq, id_A, fmaf(-c->Rs_ohm, iq_A, uq_V));
    psi_d = vq / w;
    psi_q = -vd / w;
    psi = magnitude(psi_d, psi_q);
    if (window) {
        sum_add(late ? &c->sum_psi_late_Wb : &c->sum_psi_Wb, psi);
        sum_add(late ? &c->sum_psi_d_late_Wb : &c->sum_psi_d_Wb, psi_d);
        sum_add(late ? &c->sum_psi_q_late_Wb : &c->sum_psi_q_Wb, psi_q);
        if (psi > 0.0f) {
            sum_add(late ? &c->sum_id_r_late_A : &c->sum_id_r_A, (id_A / psi) * psi_d + (iq_A / psi) * psi_q);
        }
        if (psi > 0.0f && prev > 0.0f) {
            sum_add(late ? &c->sum_turn_late_rad : &c->sum_turn_rad,
                    (c->psi_d_prev_Wb / prev) * (psi_q / psi) - (c->psi_q_prev_Wb / prev) * (psi_d / psi));
        }
    }
    c->psi_d_prev_Wb = psi_d;
    c->psi_q_prev_Wb = psi_q;
}

/*
 * End of SPIN: psi_f from the active flux, if the rotor followed the frame.
 * psi_a of a sample is w_r / w_e times the active flux, on the rotor's d
 * axis, plus the terms of the currents' changes (Lq di/dt + e^(j delta) (Ld -
 * Lq) did_r/dt) / (j w_e) that average out; w_r the rotor's speed, delta its
 * angle in the frame, which psi_a's turns track: over a half-window of n
 * samples,
 *   mean w_r / w_e = 1 + sum dphi / (w_e n Ts) = 1 + s,
 * exact whatever the rotor did within it (a swing about the frame that does
 * not end where it began leaves s != 0 however alike the halves look). So,
 * for each half,
 *   psi_f,half = mean |psi_a| / (1 + s) - (Ld - Lq) mean id_r,
 * and psi_f their mean weighted by their lengths; the routine stops
 * (speed_not_reached) unless:
 *  - slip: |s| of the whole window <= 2 %: the rotor followed the frame (a
 *    rotor that slips, creeps or stands still turns psi_a round); the
 *    correction 1 / (1 + s) removes its first order, 2 % bounds what the
 *    rotor's speed and flux co-varying within the window leave;
 *  - the means of psi_a over the two halves point the same way;
 *  - swing: psi_f of the early half within 2 % of that of the late half;
 *  - coherence: |sum psi_a| / sum |psi_a| >= 0.9;
 *  - the current leads psi_a by less than 60 degrees, mean id_r >= i_spin / 2
 *    (a rotor that follows lags on the stable side of its pull-out; a stalled
 *    salient one leaves psi_a = ((Ld + Lq) / 2 - Lq) i, still but against the
 *    current);
 *  - the back-EMF w_e mean |psi_a| exceeds the drops Rs i_spin + |u_err| that
 *    the estimate subtracts.
 */
static p2d_outcome_t flux(p2d_commission_t *c, p2d_commission_reason_t *why)
{
    const uint32_t n_mean = c->n_spin - c->n_spin / 2u, n_late = n_mean / 2u, n_early = n_mean - n_late;
    const float drops_V = fmaf(c->Rs_ohm, c->config.i_spin_A, fabsf(c->u_err_V));
    const float dL_H = c->Ld_H - c->Lq_H;
    const float wTs = c->w_e_radps * c->config.Ts_s;
    /* 1 + s = mean w_r / w_e of each half */
    const float r_early = 1.0f + c->sum_turn_rad.sum / (wTs * (float)n_early);
    const float r_late = 1.0f + c->sum_turn_late_rad.sum / (wTs * (float)n_late);
    /* psi_f,half = mean |psi_a| / (1 + s) - (Ld - Lq) mean id_r */
    const float psi_early =
        fmaf(-dL_H, c->sum_id_r_A.sum / (float)n_early, c->sum_psi_Wb.sum / ((float)n_early * r_early));
    const float psi_late =
        fmaf(-dL_H, c->sum_id_r_late_A.sum / (float)n_late, c->sum_psi_late_Wb.sum / ((float)n_late * r_late));
    const float psi_mean_Wb = (c->sum_psi_Wb.sum + c->sum_psi_late_Wb.sum) / (float)n_mean;
    const float id_r_A = (c->sum_id_r_A.sum + c->sum_id_r_late_A.sum) / (float)n_mean;
    /* the directions of psi_a's early and late means (unit vectors) */
    const float a = magnitude(c->sum_psi_d_Wb.sum, c->sum_psi_q_Wb.sum);
    const float b = magnitude(c->sum_psi_d_late_Wb.sum, c->sum_psi_q_late_Wb.sum);
    const float ad = c->sum_psi_d_Wb.sum / a, aq = c->sum_psi_q_Wb.sum / a;
    const float bd = c->sum_psi_d_late_Wb.sum / b, bq = c->sum_psi_q_late_Wb.sum / b;
    /* |s| of the window: |sum dphi| / (w_e n_mean Ts) */
    c->slip = fabsf(c->sum_turn_rad.sum + c->sum_turn_late_rad.sum) / (wTs * (float)n_mean);
    c->coherence =
        magnitude(c->sum_psi_d_Wb.sum + c->sum_psi_d_late_Wb.sum, c->sum_psi_q_Wb.sum + c->sum_psi_q_late_Wb.sum) /
        (psi_mean_Wb * (float)n_mean);
    /* the halves' estimates weighted by their lengths */
    c->psi_f_Wb = ((float)n_early * psi_early + (float)n_late * psi_late) / (float)n_mean;
    c->psi_spread = fabsf(psi_late - psi_early) / c->psi_f_Wb;
    if (!(ad * bd + aq * bq > 0.0f) || !(c->slip <= P2D_SLIP_MAX) || !(c->psi_spread <= P2D_PSI_SPREAD_MAX) ||
        !(c->coherence >= P2D_COHERENCE_MIN) || !(id_r_A >= P2D_ID_R_MIN * c->config.i_spin_A) ||
        !(c->w_e_radps * psi_mean_Wb > drops_V)) {
        *why = P2D_REASON_SPEED_NOT_REACHED;
        return FAIL;
    }
    if (!p2d_is_positive(c->psi_f_Wb)) {
        *why = P2D_REASON_NOT_IDENTIFIABLE;
        return FAIL;
    }
    return NEXT;
}

/*
 * RAMP_UP, SPIN, RAMP_DOWN: I-f at i_spin_A on the frame's d axis, with the
 * inverter's error u_err fed forward along its direction for the current
 * reference over the period that applies the command (error_direction).
 */
static p2d_outcome_t phase_spin(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V, float u_lim_V,
                                p2d_commission_output_t *out, p2d_commission_reason_t *why)
{
    const p2d_commission_phase_t phase = c->phase;
    const uint32_t n = phase == P2D_PHASE_SPIN ? c->n_spin : c->n_ramp;
    float w = c->w_e_radps, ud_pi, uq_pi, cos_phi, sin_phi;
    bool saturated = false;
    if (phase != P2D_PHASE_SPIN) {
        /*
         * S ramp of constant jerk: w[k] = w_spin S(x), x = (k + 1) / n_ramp, S = 2 x^2 up to x = 1/2,
         * 1 - 2 (1 - x)^2 after (down: S(1 - x)); its acceleration starts and ends at 0, so that it
         * excites little of the load-angle oscillation that a rotor without friction keeps
         */
        float x = (float)(c->k + 1u) * c->inv_n_ramp;
        if (phase == P2D_PHASE_RAMP_DOWN) x = 1.0f - x;
        x = x < 0.5f ? 2.0f * x * x : 1.0f - 2.0f * (1.0f - x) * (1.0f - x);
        w = c->config.w_e_spin_radps * x;
    }
    if (!closed_loop(c, c->config.i_spin_A, 0.0f, id_A, iq_A, u_dc_V, out, &saturated)) return FAIL;
    ud_pi = out->ud_V;
    uq_pi = out->uq_V;
    /* u = u_loop + u_err e^(j phi) */
    error_direction(angle_add(c->theta_e_rad, w * c->theta_lead), &cos_phi, &sin_phi);
    if (voltage_limited(fmaf(c->u_err_V, cos_phi, ud_pi), fmaf(c->u_err_V, sin_phi, uq_pi), u_lim_V, out)) {
        saturated = true;
    }
    if (saturated && phase != P2D_PHASE_RAMP_DOWN) {
        *why = P2D_REASON_VOLTAGE_LIMIT;
        return FAIL;
    }
    c->w_e_radps = w;
    if (phase == P2D_PHASE_SPIN) {
        /* the averaging window: the second half of SPIN, its early half first; psi_a of every sample for dphi */
        flux_sample(c, id_A, iq_A, ud_pi, uq_pi, c->k >= n / 2u, c->k >= n / 2u + (n - n / 2u) - (n - n / 2u) / 2u);
    }
    if (++c->k < n) return RUN;
    return phase == P2D_PHASE_SPIN ? flux(c, why) : NEXT;
}

/* Zero command (faults, the end of the routine). */
static void zero_output(const p2d_commission_t *c, p2d_commission_output_t *out)
{
    out->ud_V = 0.0f;
    out->uq_V = 0.0f;
    out->theta_e_rad = c->theta_e_rad;
    out->w_e_radps = c->w_e_radps;
    out->id_ref_A = 0.0f;
    out->iq_ref_A = 0.0f;
}

void p2d_commission_step(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V, p2d_commission_output_t *out)
{
    const float u_lim = u_dc_V > 0.0f ? u_dc_V * P2D_INV_SQRT3 : 0.0f;
    p2d_commission_reason_t why = P2D_REASON_NONE;
    p2d_outcome_t next = RUN;

    zero_output(c, out);
    out->phase = c->phase;
    out->fault = false;
    if (!isfinite(id_A) || !isfinite(iq_A) || !isfinite(u_dc_V)) {
        /* non-finite policy: zero voltage, the routine stays where it was */
        out->fault = true;
        c->fault_count++;
        return;
    }
    if (c->phase >= P2D_PHASE_DONE) return;
    if (fmaf(id_A, id_A, iq_A * iq_A) > c->config.i_trip_A * c->config.i_trip_A) {
        why = P2D_REASON_OVERCURRENT;
        next = FAIL;
    } else {
        switch (c->phase) {
        case P2D_PHASE_PROBE: next = phase_probe(c, id_A, iq_A, u_lim, out, &why); break;
        case P2D_PHASE_ALIGN: next = phase_align(c, id_A, iq_A, u_dc_V, out, &why); break;
        case P2D_PHASE_RS_LOW:
        case P2D_PHASE_RS_HIGH: next = phase_rs(c, id_A, iq_A, u_dc_V, out, &why); break;
        case P2D_PHASE_LD:
        case P2D_PHASE_LQ: next = phase_inductance(c, id_A, iq_A, u_lim, out, &why); break;
        default: next = phase_spin(c, id_A, iq_A, u_dc_V, u_lim, out, &why); break;
        }
        if (next == FAIL && why == P2D_REASON_NONE) {
            /* the current loop's non-finite policy (an overflow) engaged, before the phase changed anything */
            zero_output(c, out);
            out->fault = true;
            c->fault_count++;
            return;
        }
        c->id_prev_A = id_A;
        c->iq_prev_A = iq_A;
    }
    if (next == FAIL) {
        c->failed_phase = c->phase;
        c->reason = why;
        c->phase = P2D_PHASE_FAILED;
        zero_output(c, out);
        out->phase = P2D_PHASE_FAILED;
        return;
    }
    /* the frame's mean angle over the period that applies this command, then the next sample's angle */
    out->theta_e_rad = angle_add(c->theta_e_rad, c->w_e_radps * c->theta_lead);
    out->w_e_radps = c->w_e_radps;
    c->theta_e_rad = angle_add(c->theta_e_rad, c->w_e_radps * c->config.Ts_s);
    if (next == NEXT) start_phase(c, (p2d_commission_phase_t)(c->phase + 1));
}
