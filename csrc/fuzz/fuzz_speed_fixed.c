/*
 * libFuzzer target: the fixed-point speed controllers, Q15 and Q31 side by side
 * (pmsm2dof/speed_fixed.h), built with -fsanitize=fuzzer,address,undefined
 * -fno-sanitize-recover=all: UBSan aborts on a shift of a negative number, an
 * out-of-range shift or a signed overflow anywhere in the integer arithmetic.
 *
 * The input decodes (fuzz_common.h, fuzz_speed_config.h) to a configuration,
 * valid or not: the design of fuzz_speed.c (bit 0 of a shape byte makes the
 * motor surface, which the fixed-point controllers require) and full scales
 * around a nominal scaling (torque 2 T_max, speed 4 T_fs / Kp, current
 * 2 i_max, within two or eight decades), then to operations until the bytes
 * run out:
 *   op % 8 in 0..2  one sample: w_ref and w_m any integers of each format,
 *                   the applied torque by (op >> 3) % 3: the own T_ref, any
 *                   integer, or u itself where it fits (u* = 0)
 *   op % 8 == 3     the integrator's rounding probed on copies at rest
 *   op % 8 == 4     a closed-loop run of 1..2048 samples on the rigid-body plant
 *                   J dw/dt = T_ref - T_load (double), each format on its own plant
 *   op % 8 == 5     set_config with one design field redrawn (scalings kept)
 *   op % 8 == 6     set_config with a fresh configuration (scalings may change)
 *   op % 8 == 7     reset with any w_ref and T_init
 *
 * Invariants, checked after every call (abort on violation):
 *  - init accepts or rejects; a rejection names a parameter and writes
 *    nothing; p2d_speed_q15_gains (q31) gives the same verdict. An accepted
 *    set: mantissas within 2^N - 1, shifts within 2N + 1, normalised
 *    (|m| >= 2^(N-1)) unless at the largest shift, shifts >= 2, T_max and iq_max >= 1,
 *    and in Q31 one LSB of error moves the integrator.
 *  - compute does not change the controller; e = w_ref - w_m exactly; u, T_ff,
 *    y within +-(2^(N+1) - 1); T_ref = Sat(u) at T_max, saturated iff they
 *    differ; |iq| <= iq_max with the sign of T_ref (or 0).
 *  - update: r = w_ref, y = the output's, Q15 x within +-(2^16 - 1); at zero
 *    error, no reference move and u* = 0 the integrator stays; with clamping,
 *    while u* and e have opposite signs and the reference stays, it stays too.
 *  - the probe: Q15 at rest leaves x unchanged for an error at either edge of
 *    the dead zone (the header's rule on the stored Ki Ts) and moves it one
 *    LSB beyond; Q31 moves x in the direction of an error of one LSB.
 *  - set_config: same verdict as init; rejected: nothing written; accepted:
 *    the other set made active, the set in force and the state untouched, the
 *    new set equal to init's, the command at rest (zero error, reference kept,
 *    no feedforward transient) unchanged (bumpless).
 *  - reset: x = T_init (Q31: T_init 2^31), y = 0, r = w_ref.
 */
#include "fuzz_common.h"
#include "fuzz_speed_config.h"

#include "pmsm2dof/speed_fixed.h"

#define FZ_L15 65535
#define FZ_L31 INT64_C(4294967295)

typedef struct {
    p2d_speed_q15_t q15;         /* the Q15 controller (valid when on15) */
    p2d_speed_q31_t q31;         /* the Q31 controller (valid when on31) */
    bool on15, on31;             /* accepted by init */
    double w15_radps, w31_radps; /* plant speeds of the closed-loop runs [rad/s] */
} fz_fixed_rig_t;

static void fz_fixed_config(fz_reader_t *r, p2d_speed_fixed_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    double T_max, Kp, T_fs;
    memset(cfg, 0, sizeof *cfg);
    fz_speed_config(r, &cfg->speed);
    if (shape & 1u) cfg->speed.Lq_H = cfg->speed.Ld_H;
    T_max = 1.5 * (double)cfg->speed.pole_pairs * (double)cfg->speed.psi_f_Wb * (double)cfg->speed.i_max_A;
    Kp = (double)cfg->speed.J_kgm2 * (double)cfg->speed.alpha_radps;
    T_fs = isfinite(T_max) && T_max > 0.0 ? 2.0 * T_max : 10.0;
    cfg->torque_full_scale_Nm = fz_float(r, T_fs, false);
    cfg->speed_full_scale_radps = fz_float(r, isfinite(Kp) && Kp > 0.0 ? 4.0 * T_fs / Kp : 100.0, false);
    cfg->current_full_scale_A =
        fz_float(r, isfinite((double)cfg->speed.i_max_A) ? 2.0 * (double)cfg->speed.i_max_A : 10.0, false);
}

static void fz_check_rejection(p2d_status_t status)
{
    FZ_REQUIRE(status > P2D_OK && status < P2D_STATUS_COUNT && status != P2D_ERR_NULL && status != P2D_ERR_RS,
               "status %d", (int)status);
    FZ_REQUIRE(p2d_status_param(status)[0] != '\0', "status %d has no parameter name", (int)status);
}

/* One stored gain of N fractional bits: within the mantissa's range, normalised unless at the largest shift. */
static bool fz_gain_ok(int64_t m, uint32_t s, uint32_t bits)
{
    const int64_t top = (int64_t)1 << bits;
    const int64_t a = m < 0 ? -m : m;
    return a < top && s >= 2u && s <= 2u * bits + 1u &&
           (a == 0 ? s == 2u * bits + 1u : (a >= top / 2 || s == 2u * bits + 1u));
}

#define FZ_GAINS_OK(c, bits)                                                      \
    (fz_gain_ok((c)->b_e0.mantissa, (c)->b_e0.shift, bits) &&                     \
     fz_gain_ok((c)->Ki_Ts.mantissa, (c)->Ki_Ts.shift, bits) &&                   \
     fz_gain_ok((c)->Ki_Ka_Ts.mantissa, (c)->Ki_Ka_Ts.shift, bits) &&             \
     fz_gain_ok((c)->ff_Fr0.mantissa, (c)->ff_Fr0.shift, bits) &&                 \
     fz_gain_ok((c)->ff_b_dr.mantissa, (c)->ff_b_dr.shift, bits) &&               \
     fz_gain_ok((c)->ff_one_plus_a1.mantissa, (c)->ff_one_plus_a1.shift, bits) && \
     fz_gain_ok((c)->ff_Kd_per_Ts.mantissa, (c)->ff_Kd_per_Ts.shift, bits) &&     \
     fz_gain_ok((c)->iq_per_T.mantissa, (c)->iq_per_T.shift, bits))

/* Two coefficient sets of the format fmt hold the same numbers (a memcmp would compare their padding). */
#define FZ_GAIN_EQ(a, b, g) ((a)->g.mantissa == (b)->g.mantissa && (a)->g.shift == (b)->g.shift)
#define FZ_COEF_EQ(a, b, fmt)                                                                                        \
    (FZ_GAIN_EQ(a, b, b_e0) && FZ_GAIN_EQ(a, b, Ki_Ts) && FZ_GAIN_EQ(a, b, Ki_Ka_Ts) && FZ_GAIN_EQ(a, b, ff_Fr0) &&  \
     FZ_GAIN_EQ(a, b, ff_b_dr) && FZ_GAIN_EQ(a, b, ff_one_plus_a1) && FZ_GAIN_EQ(a, b, ff_Kd_per_Ts) &&              \
     FZ_GAIN_EQ(a, b, iq_per_T) && (a)->T_max_##fmt == (b)->T_max_##fmt && (a)->iq_max_##fmt == (b)->iq_max_##fmt && \
     (a)->clamping == (b)->clamping)

/* R(p, s) = floor(p / 2^s + 1/2), written with a division (an oracle independent of the library's shifts) */
static int64_t fz_round(int64_t p, uint32_t s)
{
    int64_t d, q;
    if (s == 0u) return p;
    d = (int64_t)1 << s;
    /* floor((2p + d) / (2d)), with 2p + d computed in two halves so that nothing overflows */
    q = p / d;
    p -= q * d; /* remainder in (-d, d) */
    if (2 * p >= d) q++;
    if (2 * p < -d) q--;
    return q;
}

static void fz_init15(fz_fixed_rig_t *rig, const p2d_speed_fixed_config_t *cfg)
{
    p2d_speed_q15_t pattern;
    p2d_speed_fixed_gains_t g;
    p2d_status_t status;
    memset(&rig->q15, 0xa5, sizeof rig->q15);
    memcpy(&pattern, &rig->q15, sizeof pattern);
    status = p2d_speed_q15_init(&rig->q15, cfg);
    FZ_REQUIRE(p2d_speed_q15_gains(cfg, &g) == status, "q15 gains and init disagree (%d)", (int)status);
    rig->on15 = status == P2D_OK;
    if (!rig->on15) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(&rig->q15, &pattern, sizeof pattern) == 0, "rejected q15 init wrote");
        return;
    }
    const p2d_speed_q15_coef_t *c = &rig->q15.coef[0];
    FZ_REQUIRE(FZ_GAINS_OK(c, 15u) && c->T_max_q15 >= 1 && c->iq_max_q15 >= 1, "q15 coefficients out of range");
    FZ_REQUIRE(FZ_COEF_EQ(&rig->q15.coef[0], &rig->q15.coef[1], q15), "q15 shadow set differs");
}

static void fz_init31(fz_fixed_rig_t *rig, const p2d_speed_fixed_config_t *cfg)
{
    p2d_speed_q31_t pattern;
    p2d_speed_fixed_gains_t g;
    p2d_status_t status;
    memset(&rig->q31, 0xa5, sizeof rig->q31);
    memcpy(&pattern, &rig->q31, sizeof pattern);
    status = p2d_speed_q31_init(&rig->q31, cfg);
    FZ_REQUIRE(p2d_speed_q31_gains(cfg, &g) == status, "q31 gains and init disagree (%d)", (int)status);
    rig->on31 = status == P2D_OK;
    if (!rig->on31) {
        fz_check_rejection(status);
        FZ_REQUIRE(memcmp(&rig->q31, &pattern, sizeof pattern) == 0, "rejected q31 init wrote");
        return;
    }
    const p2d_speed_q31_coef_t *c = &rig->q31.coef[0];
    FZ_REQUIRE(FZ_GAINS_OK(c, 31u) && c->T_max_q31 >= 1 && c->iq_max_q31 >= 1, "q31 coefficients out of range");
    /* one LSB of error moves the Q62 integrator */
    FZ_REQUIRE(c->Ki_Ts.shift <= 31u || fz_round(c->Ki_Ts.mantissa, c->Ki_Ts.shift - 31u) >= 1,
               "q31 integrator deaf to one LSB: Ki_Ts %d 2^-%u", (int)c->Ki_Ts.mantissa, (unsigned)c->Ki_Ts.shift);
}

static void fz_check15(const p2d_speed_q15_t *before, const p2d_speed_q15_t *after, int16_t w_ref, int16_t w_m,
                       const p2d_speed_q15_output_t *o, int16_t T_app)
{
    const p2d_speed_q15_coef_t *c = &before->coef[before->active];
    const int32_t T_sat = o->T_unsat_q15 > c->T_max_q15
                              ? c->T_max_q15
                              : (o->T_unsat_q15 < -c->T_max_q15 ? -c->T_max_q15 : o->T_unsat_q15);
    const int32_t u_star = T_app - o->T_unsat_q15;
    const int32_t dr = (int32_t)w_ref - before->r_prev_q15;
    FZ_REQUIRE(o->e_q15 == (int32_t)w_ref - w_m && o->w_ref_q15 == w_ref, "q15 e %d for %d - %d", (int)o->e_q15,
               (int)w_ref, (int)w_m);
    FZ_REQUIRE(o->T_unsat_q15 <= FZ_L15 && o->T_unsat_q15 >= -FZ_L15 && o->T_ff_q15 <= FZ_L15 &&
                   o->T_ff_q15 >= -FZ_L15 && o->y_ff_q15 <= FZ_L15 && o->y_ff_q15 >= -FZ_L15,
               "q15 signal beyond two full scales: u %d T_ff %d y %d", (int)o->T_unsat_q15, (int)o->T_ff_q15,
               (int)o->y_ff_q15);
    FZ_REQUIRE(o->T_ref_q15 == T_sat && o->saturated == (T_sat != o->T_unsat_q15), "q15 T_ref %d for u %d",
               (int)o->T_ref_q15, (int)o->T_unsat_q15);
    FZ_REQUIRE(o->iq_ref_q15 <= c->iq_max_q15 && o->iq_ref_q15 >= -c->iq_max_q15 &&
                   (o->T_ref_q15 >= 0 || o->iq_ref_q15 <= 0) && (o->T_ref_q15 <= 0 || o->iq_ref_q15 >= 0),
               "q15 iq %d for T %d (iq_max %d)", (int)o->iq_ref_q15, (int)o->T_ref_q15, (int)c->iq_max_q15);
    FZ_REQUIRE(after->r_prev_q15 == w_ref && after->y_ff_prev_q15 == o->y_ff_q15 && after->x_q15 <= FZ_L15 &&
                   after->x_q15 >= -FZ_L15,
               "q15 state after update: x %d", (int)after->x_q15);
    if (dr == 0 && u_star == 0 && o->e_q15 == 0) {
        FZ_REQUIRE(after->x_q15 == before->x_q15, "q15 integrator moved at zero error");
    }
    if (dr == 0 && c->clamping && ((u_star < 0 && o->e_q15 > 0) || (u_star > 0 && o->e_q15 < 0))) {
        FZ_REQUIRE(after->x_q15 == before->x_q15, "q15 clamping did not hold the integrator");
    }
}

static void fz_check31(const p2d_speed_q31_t *before, const p2d_speed_q31_t *after, int32_t w_ref, int32_t w_m,
                       const p2d_speed_q31_output_t *o, int32_t T_app)
{
    const p2d_speed_q31_coef_t *c = &before->coef[before->active];
    const int64_t T_sat = o->T_unsat_q31 > c->T_max_q31
                              ? c->T_max_q31
                              : (o->T_unsat_q31 < -c->T_max_q31 ? -c->T_max_q31 : o->T_unsat_q31);
    const int64_t u_star = T_app - o->T_unsat_q31;
    const int64_t dr = (int64_t)w_ref - before->r_prev_q31;
    FZ_REQUIRE(o->e_q31 == (int64_t)w_ref - w_m && o->w_ref_q31 == w_ref, "q31 e");
    FZ_REQUIRE(o->T_unsat_q31 <= FZ_L31 && o->T_unsat_q31 >= -FZ_L31 && o->T_ff_q31 <= FZ_L31 &&
                   o->T_ff_q31 >= -FZ_L31 && o->y_ff_q31 <= FZ_L31 && o->y_ff_q31 >= -FZ_L31,
               "q31 signal beyond two full scales");
    FZ_REQUIRE(o->T_ref_q31 == T_sat && o->saturated == (T_sat != o->T_unsat_q31), "q31 T_ref");
    FZ_REQUIRE(o->iq_ref_q31 <= c->iq_max_q31 && o->iq_ref_q31 >= -c->iq_max_q31 &&
                   (o->T_ref_q31 >= 0 || o->iq_ref_q31 <= 0) && (o->T_ref_q31 <= 0 || o->iq_ref_q31 >= 0),
               "q31 iq %ld for T %ld", (long)o->iq_ref_q31, (long)o->T_ref_q31);
    FZ_REQUIRE(after->r_prev_q31 == w_ref && after->y_ff_prev_q31 == o->y_ff_q31 && after->x_q62 >= -INT64_MAX,
               "q31 state after update");
    if (dr == 0 && u_star == 0 && o->e_q31 == 0) {
        FZ_REQUIRE(after->x_q62 == before->x_q62, "q31 integrator moved at zero error");
    }
    if (dr == 0 && c->clamping && ((u_star < 0 && o->e_q31 > 0) || (u_star > 0 && o->e_q31 < 0))) {
        FZ_REQUIRE(after->x_q62 == before->x_q62, "q31 clamping did not hold the integrator");
    }
}

/* The applied torque of a sample: the own T_ref, any integer, or u itself where it fits (u* = 0). */
static int64_t fz_applied(unsigned mode, int64_t T_ref, int64_t u, int64_t any, int64_t limit)
{
    if (mode == 1u) return any;
    if (mode == 2u && u <= limit && u >= -limit - 1) return u;
    return T_ref;
}

/* One sample of both formats; the torques applied into *T15 and *T31 [LSB]. */
static void fz_sample(fz_fixed_rig_t *rig, unsigned mode, int16_t w_ref, int16_t w_m, int16_t any15, int32_t w_ref31,
                      int32_t w_m31, int32_t any31, int32_t *T15, int32_t *T31)
{
    if (rig->on15) {
        p2d_speed_q15_t before;
        p2d_speed_q15_output_t o;
        int16_t T_app;
        memcpy(&before, &rig->q15, sizeof before);
        p2d_speed_q15_compute(&rig->q15, w_ref, w_m, &o);
        FZ_REQUIRE(memcmp(&before, &rig->q15, sizeof before) == 0, "q15 compute changed the controller");
        T_app = (int16_t)fz_applied(mode, o.T_ref_q15, o.T_unsat_q15, any15, INT16_MAX);
        p2d_speed_q15_update(&rig->q15, &o, T_app);
        fz_check15(&before, &rig->q15, w_ref, w_m, &o, T_app);
        *T15 = T_app;
    }
    if (rig->on31) {
        p2d_speed_q31_t before;
        p2d_speed_q31_output_t o;
        int32_t T_app;
        memcpy(&before, &rig->q31, sizeof before);
        p2d_speed_q31_compute(&rig->q31, w_ref31, w_m31, &o);
        FZ_REQUIRE(memcmp(&before, &rig->q31, sizeof before) == 0, "q31 compute changed the controller");
        T_app = (int32_t)fz_applied(mode, o.T_ref_q31, o.T_unsat_q31, any31, INT32_MAX);
        p2d_speed_q31_update(&rig->q31, &o, T_app);
        fz_check31(&before, &rig->q31, w_ref31, w_m31, &o, T_app);
        *T31 = T_app;
    }
}

/* Q15 at rest at w, x = 0: one sample of error e with u* = 0; did x move? (false when u does not fit int16) */
static bool fz_q15_moves(const p2d_speed_q15_t *ctl, int16_t w, int32_t e, bool *fits)
{
    p2d_speed_q15_t copy;
    p2d_speed_q15_output_t o;
    memcpy(&copy, ctl, sizeof copy);
    p2d_speed_q15_reset(&copy, w, 0);
    p2d_speed_q15_compute(&copy, w, (int16_t)(w - e), &o);
    *fits = o.T_unsat_q15 <= INT16_MAX && o.T_unsat_q15 >= INT16_MIN;
    p2d_speed_q15_update(&copy, &o, (int16_t)(*fits ? o.T_unsat_q15 : 0));
    return copy.x_q15 != 0;
}

/* The integrator's rounding: the Q15 dead zone's edges, one LSB of Q31 error. */
static void fz_probe(const fz_fixed_rig_t *rig)
{
    if (rig->on15) {
        const p2d_q15_gain_t g = rig->q15.coef[rig->q15.active].Ki_Ts;
        /* R(m e, s) = 0 for -2^(s-1) <= m e < 2^(s-1): e from -floor(2^(s-1)/m) to ceil(2^(s-1)/m) - 1 */
        if (g.mantissa > 0 && g.shift >= 1u) {
            const int64_t half = (int64_t)1 << (g.shift - 1u);
            const int64_t hi = (half + g.mantissa - 1) / g.mantissa - 1, lo = -(half / g.mantissa);
            bool fits_in, fits_out;
            /* e from w = 0: within +-32767 */
            if (hi + 1 <= INT16_MAX) {
                bool in = fz_q15_moves(&rig->q15, 0, (int32_t)hi, &fits_in);
                bool out = fz_q15_moves(&rig->q15, 0, (int32_t)(hi + 1), &fits_out);
                FZ_REQUIRE(!fits_in || !in, "q15 integrator moved at the dead zone's edge e = %ld", (long)hi);
                FZ_REQUIRE(!fits_out || out, "q15 integrator did not move beyond the edge, e = %ld", (long)hi + 1);
            }
            if (lo - 1 >= -INT16_MAX) {
                bool in = fz_q15_moves(&rig->q15, 0, (int32_t)lo, &fits_in);
                bool out = fz_q15_moves(&rig->q15, 0, (int32_t)(lo - 1), &fits_out);
                FZ_REQUIRE(!fits_in || !in, "q15 integrator moved at the dead zone's edge e = %ld", (long)lo);
                FZ_REQUIRE(!fits_out || out, "q15 integrator did not move beyond the edge, e = %ld", (long)lo - 1);
            }
        }
    }
    if (rig->on31) {
        for (int32_t e = -1; e <= 1; e += 2) {
            p2d_speed_q31_t copy;
            p2d_speed_q31_output_t o;
            memcpy(&copy, &rig->q31, sizeof copy);
            p2d_speed_q31_reset(&copy, 0, 0);
            p2d_speed_q31_compute(&copy, 0, -e, &o);
            if (o.T_unsat_q31 > INT32_MAX || o.T_unsat_q31 < INT32_MIN) continue;
            p2d_speed_q31_update(&copy, &o, (int32_t)o.T_unsat_q31);
            FZ_REQUIRE(e > 0 ? copy.x_q62 > 0 : copy.x_q62 < 0, "q31 integrator deaf to e = %d LSB", (int)e);
        }
    }
}

/* x as the nearest integer of `bits` fractional bits of the full scale fs, saturated to the format's range */
static double fz_q(double x, double fs, double bits)
{
    const double top = ldexp(1.0, (int)bits);
    return isfinite(x) ? fmax(-top, fmin(top - 1.0, round(x / fs * top))) : 0.0;
}

/* Closed loop, each format on its plant J dw/dt = T_ref - T_load (double), for 1..2048 samples. */
static void fz_closed_loop(fz_fixed_rig_t *rig, fz_reader_t *r)
{
    const p2d_speed_fixed_config_t *cfg = rig->on15 ? &rig->q15.config : &rig->q31.config;
    const double W = (double)cfg->speed_full_scale_radps, T = (double)cfg->torque_full_scale_Nm;
    const double Ts_per_J = (double)cfg->speed.Ts_s / (double)cfg->speed.J_kgm2;
    const uint32_t n = 1u + fz_u16(r) % 2048u;
    const double w_ref = (double)fz_float(r, 0.5 * W, true);
    const double T_load = (double)fz_float(r, 0.3 * T, true);
    if (!isfinite(T_load)) return;
    for (uint32_t k = 0; k < n; ++k) {
        int32_t T15 = 0, T31 = 0;
        fz_sample(rig, 0u, (int16_t)fz_q(w_ref, W, 15.0), (int16_t)fz_q(rig->w15_radps, W, 15.0), 0,
                  (int32_t)fz_q(w_ref, W, 31.0), (int32_t)fz_q(rig->w31_radps, W, 31.0), 0, &T15, &T31);
        rig->w15_radps += Ts_per_J * (ldexp((double)T15, -15) * T - T_load);
        rig->w31_radps += Ts_per_J * (ldexp((double)T31, -31) * T - T_load);
    }
}

/* set_config's verdict against init's: the same, except that set_config keeps the scalings. */
static void fz_check_set_status(p2d_status_t status, p2d_status_t status_init, bool same_scales)
{
    if (status_init == P2D_OK && !same_scales) {
        FZ_REQUIRE(status == P2D_ERR_SPEED_FULL_SCALE || status == P2D_ERR_TORQUE_FULL_SCALE ||
                       status == P2D_ERR_CURRENT_FULL_SCALE,
                   "set_config accepted new scalings (%d)", (int)status);
    } else {
        FZ_REQUIRE(status == status_init, "set_config %d, init %d", (int)status, (int)status_init);
    }
}

static bool fz_same_scales(const p2d_speed_fixed_config_t *a, const p2d_speed_fixed_config_t *b)
{
    return a->speed_full_scale_radps == b->speed_full_scale_radps &&
           a->torque_full_scale_Nm == b->torque_full_scale_Nm && a->current_full_scale_A == b->current_full_scale_A;
}

static void fz_set15(p2d_speed_q15_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    p2d_speed_q15_t before, fresh;
    p2d_speed_q15_output_t o1, o2;
    p2d_status_t status, status_init;
    memcpy(&before, ctl, sizeof before);
    status_init = p2d_speed_q15_init(&fresh, cfg);
    status = p2d_speed_q15_set_config(ctl, cfg);
    fz_check_set_status(status, status_init, fz_same_scales(cfg, &before.config));
    if (status != P2D_OK) {
        FZ_REQUIRE(memcmp(ctl, &before, sizeof before) == 0, "q15 rejected set_config wrote");
        return;
    }
    FZ_REQUIRE(ctl->active == 1u - before.active &&
                   memcmp(&ctl->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0 &&
                   FZ_COEF_EQ(&ctl->coef[ctl->active], &fresh.coef[0], q15),
               "q15 set_config: not the shadow swap of init's coefficients");
    FZ_REQUIRE(ctl->x_q15 == before.x_q15 && ctl->y_ff_prev_q15 == before.y_ff_prev_q15 &&
                   ctl->r_prev_q15 == before.r_prev_q15,
               "q15 set_config changed the state");
    if (before.y_ff_prev_q15 == 0) {
        p2d_speed_q15_compute(&before, before.r_prev_q15, before.r_prev_q15, &o1);
        p2d_speed_q15_compute(ctl, before.r_prev_q15, before.r_prev_q15, &o2);
        FZ_REQUIRE(o1.T_unsat_q15 == o2.T_unsat_q15, "q15 set_config not bumpless: %d -> %d", (int)o1.T_unsat_q15,
                   (int)o2.T_unsat_q15);
    }
}

static void fz_set31(p2d_speed_q31_t *ctl, const p2d_speed_fixed_config_t *cfg)
{
    p2d_speed_q31_t before, fresh;
    p2d_speed_q31_output_t o1, o2;
    p2d_status_t status, status_init;
    memcpy(&before, ctl, sizeof before);
    status_init = p2d_speed_q31_init(&fresh, cfg);
    status = p2d_speed_q31_set_config(ctl, cfg);
    fz_check_set_status(status, status_init, fz_same_scales(cfg, &before.config));
    if (status != P2D_OK) {
        FZ_REQUIRE(memcmp(ctl, &before, sizeof before) == 0, "q31 rejected set_config wrote");
        return;
    }
    FZ_REQUIRE(ctl->active == 1u - before.active &&
                   memcmp(&ctl->coef[before.active], &before.coef[before.active], sizeof before.coef[0]) == 0 &&
                   FZ_COEF_EQ(&ctl->coef[ctl->active], &fresh.coef[0], q31),
               "q31 set_config: not the shadow swap of init's coefficients");
    FZ_REQUIRE(ctl->x_q62 == before.x_q62 && ctl->y_ff_prev_q31 == before.y_ff_prev_q31 &&
                   ctl->r_prev_q31 == before.r_prev_q31,
               "q31 set_config changed the state");
    if (before.y_ff_prev_q31 == 0) {
        p2d_speed_q31_compute(&before, before.r_prev_q31, before.r_prev_q31, &o1);
        p2d_speed_q31_compute(ctl, before.r_prev_q31, before.r_prev_q31, &o2);
        FZ_REQUIRE(o1.T_unsat_q31 == o2.T_unsat_q31, "q31 set_config not bumpless");
    }
}

static void fz_set_config(fz_fixed_rig_t *rig, const p2d_speed_fixed_config_t *cfg)
{
    if (rig->on15) fz_set15(&rig->q15, cfg);
    if (rig->on31) fz_set31(&rig->q31, cfg);
}

static void fz_reset(fz_fixed_rig_t *rig, int32_t w, int32_t T)
{
    if (rig->on15) {
        p2d_speed_q15_reset(&rig->q15, (int16_t)(w >> 16), (int16_t)(T >> 16));
        FZ_REQUIRE(rig->q15.x_q15 == (T >> 16) && rig->q15.y_ff_prev_q15 == 0 && rig->q15.r_prev_q15 == (w >> 16),
                   "q15 reset");
    }
    if (rig->on31) {
        p2d_speed_q31_reset(&rig->q31, w, T);
        FZ_REQUIRE(rig->q31.x_q62 == (int64_t)T * ((int64_t)1 << 31) && rig->q31.y_ff_prev_q31 == 0 &&
                       rig->q31.r_prev_q31 == w,
                   "q31 reset");
    }
}

/* A signed 32-bit integer from the input (any bit pattern). */
static int32_t fz_i32(fz_reader_t *r) { return (int32_t)fz_u32(r); }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r = {data, size};
    fz_fixed_rig_t rig;
    p2d_speed_fixed_config_t cfg, next;

    FZ_REQUIRE(p2d_speed_q15_init(NULL, &cfg) == P2D_ERR_NULL && p2d_speed_q31_init(&rig.q31, NULL) == P2D_ERR_NULL &&
                   p2d_speed_q15_set_config(&rig.q15, NULL) == P2D_ERR_NULL,
               "NULL pointer accepted");
    fz_fixed_config(&r, &cfg);
    fz_init15(&rig, &cfg);
    fz_init31(&rig, &cfg);
    if (!rig.on15 && !rig.on31) return 0;
    rig.w15_radps = 0.0;
    rig.w31_radps = 0.0;
    while (!fz_done(&r)) {
        const uint8_t op = fz_u8(&r);
        switch (op % 8u) {
        case 3: fz_probe(&rig); break;
        case 4: fz_closed_loop(&rig, &r); break;
        case 5:
            /* a fresh design, the scalings kept */
            next = rig.on15 ? rig.q15.config : rig.q31.config;
            fz_speed_config(&r, &next.speed);
            if (fz_u8(&r) & 1u) next.speed.Lq_H = next.speed.Ld_H;
            fz_set_config(&rig, &next);
            break;
        case 6:
            fz_fixed_config(&r, &next);
            fz_set_config(&rig, &next);
            break;
        case 7: {
            const int32_t w = fz_i32(&r);
            fz_reset(&rig, w, fz_i32(&r));
            break;
        }
        default: {
            const int32_t w_ref = fz_i32(&r), w_m = fz_i32(&r), any = fz_i32(&r);
            int32_t T15 = 0, T31 = 0;
            /* Q15 takes the upper halves: the same speeds at 2^-16 of the resolution */
            fz_sample(&rig, (op >> 3) % 3u, (int16_t)(w_ref >> 16), (int16_t)(w_m >> 16), (int16_t)(any >> 16), w_ref,
                      w_m, any, &T15, &T31);
            break;
        }
        }
    }
    return 0;
}
