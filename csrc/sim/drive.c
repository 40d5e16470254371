/*
 * Drive simulation engine: see drive.h for the model, the sampled-data loop,
 * the initial state, the log and the stops.
 */
/*
 * No product and sum contracted into an FMA (C99 7.12.2), in this file and the inline code it
 * includes: the loop's FMA copy below computes the bits of the baseline one only so (clang honours
 * the pragma, GCC the attribute of P2D_SIM_FMA_TARGET; ffibuild.py passes -ffp-contract=off too).
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include "drive.h"

#include <math.h>
#include <string.h>

#include "../src/current_step.h"
#include "../src/speed_integral.h"
#include "plant_inline.h"

#define P2D_SIM_OVERSPEED_FACTOR 2.0    /* overspeed bound in no-load speeds [-] */
#define P2D_SIM_OVERCURRENT_FACTOR 10.0 /* overcurrent bound in max(i_max, short-circuit current) [-] */
#define P2D_SIM_TS_MATCH_TOL 1e-6       /* relative mismatch allowed between float and double periods [-] */
#define P2D_SIM_T_TOL 1e-6              /* times closer than this many RK4 steps are equal [-] */

/* Inlines a function where the compiler supports it (the per-period work into the loop). */
#if defined(__GNUC__)
#define P2D_SIM_INLINE __attribute__((always_inline)) inline
#else
#define P2D_SIM_INLINE inline
#endif

/*
 * A copy of the loop for x86-64 CPUs with FMA (and so AVX), chosen at run time: the controllers'
 * fmaf is then one instruction instead of a call into libm (which spills every SSE register around
 * it), and the plant's double arithmetic takes the three-operand AVX forms. fmaf rounds once either
 * way and -ffp-contract=off keeps every other product and sum apart, so that both copies compute
 * the same bits.
 */
#if defined(__GNUC__) && defined(__x86_64__)
#if defined(__clang__)
#define P2D_SIM_FMA_TARGET __attribute__((target("fma")))
#else
#define P2D_SIM_FMA_TARGET __attribute__((target("fma"), optimize("fp-contract=off")))
#endif
/* The CPU executes FMA (and AVX) instructions. */
static bool cpu_has_fma(void)
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("fma");
}
#else
static bool cpu_has_fma(void) { return false; }
#endif

/* Keeps a function out of line where the compiler supports it (rare paths, out of the loop's registers). */
#if defined(__GNUC__)
#define P2D_SIM_NOINLINE __attribute__((noinline))
#else
#define P2D_SIM_NOINLINE
#endif

typedef struct {
    const char *param; /* configuration field */
    const char *text;  /* valid range, or reason of a stop */
} p2d_sim_status_text_t;

static const p2d_sim_status_text_t P2D_SIM_STATUS_TEXT[P2D_SIM_STATUS_COUNT] = {
    [P2D_SIM_OK] = {"", ""},
    [P2D_SIM_ERR_NULL] = {"pointer", "non-NULL"},
    [P2D_SIM_ERR_POLE_PAIRS] = {"motor.pole_pairs", "an integer >= 1"},
    [P2D_SIM_ERR_RS] = {"motor.Rs_ohm", "finite and > 0"},
    [P2D_SIM_ERR_LD] = {"motor.Ld_H", "finite and > 0"},
    [P2D_SIM_ERR_LQ] = {"motor.Lq_H", "finite and > 0"},
    [P2D_SIM_ERR_PSI_F] = {"motor.psi_f_Wb", "finite and > 0"},
    [P2D_SIM_ERR_J] = {"motor.J_kgm2", "finite and > 0"},
    [P2D_SIM_ERR_B] = {"motor.B_Nms", "finite and >= 0"},
    [P2D_SIM_ERR_T_COULOMB] = {"motor.T_coulomb_Nm", "finite and >= 0"},
    [P2D_SIM_ERR_U_DC] = {"u_dc_V", "finite and > 0"},
    [P2D_SIM_ERR_CURRENT_MODEL] = {"current_model", "dq_pi (0) or first_order (1)"},
    [P2D_SIM_ERR_TAU_I] = {"tau_i_s", "finite and > 0"},
    [P2D_SIM_ERR_TS_CURRENT] = {"Ts_current_s", "finite, > 0 and equal to current.Ts_s (dq_pi)"},
    [P2D_SIM_ERR_CURRENT_PER_SPEED] = {"current_per_speed",
                                       "an integer >= 1 with current_per_speed * Ts_current_s = speed.Ts_s"},
    [P2D_SIM_ERR_SUBSTEPS] = {"substeps", "an integer >= 1"},
    [P2D_SIM_ERR_LOG_EVERY] = {"log_every", "an integer >= 1"},
    [P2D_SIM_ERR_W_M0] = {"w_m0_radps", "finite, within twice the no-load speed 2 u_dc / (sqrt(3) p psi_f)"},
    [P2D_SIM_ERR_REFERENCE] = {"reference", "entries with finite t_s >= 0 in nondecreasing order, finite "
                                            "values and finite ramp_s >= 0"},
    [P2D_SIM_ERR_LOAD] = {"load", "entries with finite t_s >= 0 in nondecreasing order, finite values "
                                  "and finite ramp_s >= 0"},
    [P2D_SIM_ERR_FAULTS] = {"faults", "entries with a known kind, finite t_s >= 0, finite duration_s > 0 (but "
                                      "sensor_spike), a DC-link factor in [0, 1] with dq_pi, a finite spike "
                                      "reading"},
    [P2D_SIM_ERR_SPEED_CONTROLLER] = {"speed", "accepted by p2d_speed_init (see controller_status)"},
    [P2D_SIM_ERR_CURRENT_CONTROLLER] = {"current", "accepted by p2d_current_init (see controller_status)"},
    [P2D_SIM_ERR_MECHANICS_MODEL] = {"mechanics.model", "rigid (0) or two_mass (1)"},
    [P2D_SIM_ERR_J_LOAD] = {"mechanics.J_load_kgm2", "finite and > 0 (two_mass)"},
    [P2D_SIM_ERR_STIFFNESS] = {"mechanics.stiffness_Nm_per_rad", "finite and > 0 (two_mass)"},
    [P2D_SIM_ERR_DAMPING] = {"mechanics.damping_Nms_per_rad", "finite and >= 0 (two_mass)"},
    [P2D_SIM_ERR_BACKLASH] = {"mechanics.backlash_rad", "finite and >= 0 (two_mass)"},
    [P2D_SIM_ERR_FEEDBACK] = {"mechanics.feedback", "motor (0) or load (1)"},
    [P2D_SIM_ERR_LOG_FULL] = {"log_rows", "room for every logged sample"},
    [P2D_SIM_STOP_NONFINITE] = {"", "the plant state became non-finite (NaN or infinite)"},
    [P2D_SIM_STOP_OVERSPEED] = {"", "the speed exceeds twice the no-load speed of the DC link, "
                                    "2 u_dc / (sqrt(3) p psi_f) (two_mass: on the motor or the load side)"},
    [P2D_SIM_STOP_OVERCURRENT] = {"", "the current exceeds ten times the larger of the current limit and "
                                      "the short-circuit current psi_f / min(Ld, Lq)"},
    [P2D_SIM_STOP_CONTROLLER_FAULT] = {"", "a controller's output became non-finite (non-finite policy)"},
    [P2D_SIM_ERR_SPEED_SENSOR] = {"speed_sensor", "model ideal (0) or encoder (1), finite delay_s in [0, 2046 "
                                                  "Ts_current_s], finite noise_rms_radps >= 0, an encoder "
                                                  "accepted by p2d_encoder_init (see controller_status)"},
    [P2D_SIM_ERR_CURRENT_SENSOR] = {"current_sensor", "finite gain errors > -1, finite offsets, finite "
                                                      "noise_rms_A >= 0; all 0 with first_order"},
    [P2D_SIM_ERR_FIELD_WEAKENING] = {"field_weakening", "disabled with first_order; a regulator accepted by "
                                                        "p2d_field_weakening_init (see controller_status)"},
    [P2D_SIM_ERR_ESTIMATOR] = {"adapt.config", "accepted by p2d_inertia_init (see controller_status)"},
    [P2D_SIM_ERR_ADAPT_REL_CHANGE] = {"adapt.adapt_rel_change", "finite and >= 0"},
    [P2D_SIM_ERR_E_QUIET] = {"adapt.e_quiet_radps", "finite and >= 0"},
    [P2D_SIM_ERR_LOCKSTEP] = {"sims", "drives of one shape at the same sample (p2d_sim_lockstep)"},
    [P2D_SIM_ERR_ARITHMETIC] = {"arithmetic", "float32 (0), q15 (1) or q31 (2); q15 and q31 without torque filters "
                                              "(speed_filter), field weakening or gain scheduling (adapt.adapt_gains)"},
    [P2D_SIM_ERR_LOG_RATE] = {"log_rate", "speed (0) or current (1)"},
};

static const char *const P2D_LOG_NAMES[P2D_LOG_COUNT] = {
    [P2D_LOG_T_S] = "t_s",
    [P2D_LOG_W_REF_RADPS] = "w_ref_radps",
    [P2D_LOG_W_M_RADPS] = "w_m_radps",
    [P2D_LOG_ID_REF_A] = "id_ref_A",
    [P2D_LOG_IQ_REF_A] = "iq_ref_A",
    [P2D_LOG_ID_A] = "id_A",
    [P2D_LOG_IQ_A] = "iq_A",
    [P2D_LOG_UD_V] = "ud_V",
    [P2D_LOG_UQ_V] = "uq_V",
    [P2D_LOG_TORQUE_NM] = "torque_Nm",
    [P2D_LOG_TORQUE_REF_NM] = "torque_ref_Nm",
    [P2D_LOG_TORQUE_UNSAT_NM] = "torque_unsat_Nm",
    [P2D_LOG_LOAD_NM] = "load_Nm",
    [P2D_LOG_SATURATED] = "saturated",
    [P2D_LOG_X_I_NM] = "x_i_Nm",
    [P2D_LOG_W_MEAS_RADPS] = "w_meas_radps",
    [P2D_LOG_U_DC_V] = "u_dc_V",
    [P2D_LOG_VOLTAGE_LIMITED] = "voltage_limited",
    [P2D_LOG_J_EST_KGM2] = "J_est_kgm2",
    [P2D_LOG_J_VALID] = "J_valid",
    [P2D_LOG_T_LOAD_EST_NM] = "T_load_est_Nm",
    [P2D_LOG_J_GAINS_KGM2] = "J_gains_kgm2",
    [P2D_LOG_W_LOAD_RADPS] = "w_load_radps",
    [P2D_LOG_SHAFT_TORQUE_NM] = "shaft_torque_Nm",
};

const char *p2d_sim_status_param(p2d_sim_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_SIM_STATUS_COUNT) return "unknown";
    return P2D_SIM_STATUS_TEXT[status].param;
}

const char *p2d_sim_status_text(p2d_sim_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_SIM_STATUS_COUNT) return "unknown status code";
    return P2D_SIM_STATUS_TEXT[status].text;
}

const char *p2d_sim_log_name(uint32_t column)
{
    if (column >= (uint32_t)P2D_LOG_COUNT) return "";
    return P2D_LOG_NAMES[column];
}

/*
 * A count n as a double: the signed conversion, one instruction on x86-64 where the unsigned one
 * takes a branch; the same value for every count of a run (n < 2^63).
 */
static P2D_SIM_INLINE double count_as_double(uint64_t n) { return (double)(int64_t)n; }

static bool is_positive(double x) { return isfinite(x) && x > 0.0; }
static bool is_nonnegative(double x) { return isfinite(x) && x >= 0.0; }

/* |a - b| <= tol |b| */
static bool nearly_equal(double a, double b, double tol) { return fabs(a - b) <= tol * fabs(b); }

static bool schedule_valid(const p2d_schedule_t *s)
{
    if (s->n == 0u) return true;
    if (s->t_s == 0 || s->value == 0 || s->ramp_s == 0) return false;
    for (uint32_t i = 0; i < s->n; ++i) {
        if (!is_nonnegative(s->t_s[i]) || !isfinite(s->value[i]) || !is_nonnegative(s->ramp_s[i])) return false;
        if (i > 0u && s->t_s[i] < s->t_s[i - 1u]) return false;
    }
    return true;
}

static bool faults_valid(const p2d_sim_config_t *cfg)
{
    if (cfg->n_faults == 0u) return true;
    if (cfg->faults == 0) return false;
    for (uint32_t i = 0; i < cfg->n_faults; ++i) {
        const p2d_fault_t *f = &cfg->faults[i];
        if (!is_nonnegative(f->t_s)) return false;
        switch (f->kind) {
        case P2D_FAULT_DC_LINK_SAG:
            if (cfg->current_model != P2D_CURRENT_DQ_PI || !is_nonnegative(f->value) || f->value > 1.0) return false;
            if (!is_positive(f->duration_s)) return false;
            break;
        case P2D_FAULT_SENSOR_HOLD:
        case P2D_FAULT_SENSOR_ZERO:
            if (!is_positive(f->duration_s)) return false;
            break;
        case P2D_FAULT_SENSOR_SPIKE:
            if (!isfinite(f->value)) return false;
            break;
        default: return false;
        }
    }
    return true;
}

/* The engine's own fields (the plant's are validated by p2d_plant_init). */
static p2d_sim_status_t config_status(const p2d_sim_config_t *cfg)
{
    double Ts_speed_s;
    if ((unsigned)cfg->current_model > (unsigned)P2D_CURRENT_FIRST_ORDER) return P2D_SIM_ERR_CURRENT_MODEL;
    if (cfg->current_model == P2D_CURRENT_FIRST_ORDER && !is_positive(cfg->tau_i_s)) return P2D_SIM_ERR_TAU_I;
    if (!is_positive(cfg->Ts_current_s)) return P2D_SIM_ERR_TS_CURRENT;
    if (cfg->current_model == P2D_CURRENT_DQ_PI &&
        !nearly_equal((double)cfg->current.Ts_s, cfg->Ts_current_s, P2D_SIM_TS_MATCH_TOL)) {
        return P2D_SIM_ERR_TS_CURRENT;
    }
    Ts_speed_s = (double)cfg->current_per_speed * cfg->Ts_current_s;
    if (cfg->current_per_speed < 1u || !nearly_equal((double)cfg->speed.Ts_s, Ts_speed_s, P2D_SIM_TS_MATCH_TOL)) {
        return P2D_SIM_ERR_CURRENT_PER_SPEED;
    }
    if (cfg->log_every < 1u) return P2D_SIM_ERR_LOG_EVERY;
    if ((unsigned)cfg->log_rate > (unsigned)P2D_LOG_RATE_CURRENT) return P2D_SIM_ERR_LOG_RATE;
    if (!schedule_valid(&cfg->reference)) return P2D_SIM_ERR_REFERENCE;
    if (!schedule_valid(&cfg->load)) return P2D_SIM_ERR_LOAD;
    if (!faults_valid(cfg)) return P2D_SIM_ERR_FAULTS;
    if ((unsigned)cfg->arithmetic > (unsigned)P2D_ARITHMETIC_Q31) return P2D_SIM_ERR_ARITHMETIC;
    if (cfg->arithmetic != P2D_ARITHMETIC_FLOAT32 &&
        (cfg->speed_filter.notch_freq_Hz != 0.0f || cfg->speed_filter.lowpass_freq_Hz != 0.0f ||
         cfg->sensing.field_weakening.enabled || (cfg->adapt.enabled && cfg->adapt.adapt_gains))) {
        return P2D_SIM_ERR_ARITHMETIC;
    }
    return P2D_SIM_OK;
}

/* The engine's code of a configuration error of the plant. */
static p2d_sim_status_t plant_error(p2d_plant_status_t status)
{
    static const p2d_sim_status_t code[P2D_PLANT_STATUS_COUNT] = {
        [P2D_PLANT_OK] = P2D_SIM_OK,
        [P2D_PLANT_ERR_NULL] = P2D_SIM_ERR_NULL,
        [P2D_PLANT_ERR_POLE_PAIRS] = P2D_SIM_ERR_POLE_PAIRS,
        [P2D_PLANT_ERR_RS] = P2D_SIM_ERR_RS,
        [P2D_PLANT_ERR_LD] = P2D_SIM_ERR_LD,
        [P2D_PLANT_ERR_LQ] = P2D_SIM_ERR_LQ,
        [P2D_PLANT_ERR_PSI_F] = P2D_SIM_ERR_PSI_F,
        [P2D_PLANT_ERR_J] = P2D_SIM_ERR_J,
        [P2D_PLANT_ERR_B] = P2D_SIM_ERR_B,
        [P2D_PLANT_ERR_T_COULOMB] = P2D_SIM_ERR_T_COULOMB,
        [P2D_PLANT_ERR_MECHANICS_MODEL] = P2D_SIM_ERR_MECHANICS_MODEL,
        [P2D_PLANT_ERR_J_LOAD] = P2D_SIM_ERR_J_LOAD,
        [P2D_PLANT_ERR_STIFFNESS] = P2D_SIM_ERR_STIFFNESS,
        [P2D_PLANT_ERR_DAMPING] = P2D_SIM_ERR_DAMPING,
        [P2D_PLANT_ERR_BACKLASH] = P2D_SIM_ERR_BACKLASH,
        [P2D_PLANT_ERR_FEEDBACK] = P2D_SIM_ERR_FEEDBACK,
        [P2D_PLANT_ERR_U_DC] = P2D_SIM_ERR_U_DC,
        [P2D_PLANT_ERR_TS] = P2D_SIM_ERR_TS_CURRENT,
        [P2D_PLANT_ERR_SUBSTEPS] = P2D_SIM_ERR_SUBSTEPS,
        [P2D_PLANT_ERR_TAU_I] = P2D_SIM_ERR_TAU_I,
        [P2D_PLANT_ERR_W_M0] = P2D_SIM_ERR_W_M0,
        [P2D_PLANT_ERR_I0] = P2D_SIM_ERR_W_M0,
        [P2D_PLANT_ERR_CURRENT_SENSOR] = P2D_SIM_ERR_CURRENT_SENSOR,
    };
    return (unsigned)status < (unsigned)P2D_PLANT_STATUS_COUNT ? code[status] : P2D_SIM_ERR_NULL;
}

/* ---- schedules ---------------------------------------------------------- */

static void cursor_reset(p2d_schedule_cursor_t *c)
{
    c->next = 0u;
    c->t0_s = 0.0;
    c->v0 = 0.0;
    c->v1 = 0.0;
    c->ramp_s = 0.0;
    c->t_break_s = -HUGE_VAL;
}

/* Value of the present segment at t: v0 + (v1 - v0) (t - t0) / ramp during the ramp, v1 after. */
static double segment_value(const p2d_schedule_cursor_t *c, double t_s)
{
    if (c->ramp_s > 0.0 && t_s < c->t0_s + c->ramp_s) {
        return c->v0 + (c->v1 - c->v0) * fmax(t_s - c->t0_s, 0.0) / c->ramp_s;
    }
    return c->v1;
}

/* Slope of the present segment at t (inside a ramp: (v1 - v0) / ramp, else 0). */
static double segment_slope(const p2d_schedule_cursor_t *c, double t_s)
{
    if (c->ramp_s > 0.0 && t_s > c->t0_s && t_s < c->t0_s + c->ramp_s) return (c->v1 - c->v0) / c->ramp_s;
    return 0.0;
}

/* From t on the present segment is constant: its value v1 (segment_value) and no slope (segment_slope). */
static bool segment_constant(const p2d_schedule_cursor_t *c, double t_s)
{
    return !(c->ramp_s > 0.0 && t_s < c->t0_s + c->ramp_s);
}

/* Enter every entry with t_s[i] <= t; a new segment starts from the value reached. */
static P2D_SIM_NOINLINE void cursor_enter(p2d_schedule_cursor_t *c, const p2d_schedule_t *s, double t_s)
{
    while (c->next < s->n && s->t_s[c->next] <= t_s) {
        double t_entry = s->t_s[c->next];
        c->v0 = segment_value(c, t_entry);
        c->t0_s = t_entry;
        c->v1 = s->value[c->next];
        c->ramp_s = s->ramp_s[c->next];
        c->t_break_s = -HUGE_VAL;
        c->next++;
    }
}

/* cursor_enter, with the test that finds no entry to enter (most calls) inline. */
static P2D_SIM_INLINE void cursor_advance(p2d_schedule_cursor_t *c, const p2d_schedule_t *s, double t_s)
{
    if (c->next < s->n && s->t_s[c->next] <= t_s) cursor_enter(c, s, t_s);
}

/* First time after t where the signal jumps or changes slope (HUGE_VAL if none). */
static double cursor_next_break(const p2d_schedule_cursor_t *c, const p2d_schedule_t *s, double t_s)
{
    double t_break = c->next < s->n ? s->t_s[c->next] : HUGE_VAL;
    double t_ramp_end = c->t0_s + c->ramp_s;
    if (c->ramp_s > 0.0 && t_ramp_end > t_s && t_ramp_end < t_break) t_break = t_ramp_end;
    return t_break;
}

/*
 * Enter every entry with t_s[i] <= t and return the first breakpoint after t, as
 * cursor_advance and cursor_next_break do; between breakpoints both are constant, so that
 * this is a comparison with the breakpoint known (t_break_s) until t reaches it.
 */
static double cursor_break_after(p2d_schedule_cursor_t *c, const p2d_schedule_t *s, double t_s)
{
    if (!(t_s < c->t_break_s)) {
        cursor_advance(c, s, t_s);
        c->t_break_s = cursor_next_break(c, s, t_s);
    }
    return c->t_break_s;
}

/* ---- faults ------------------------------------------------------------- */

/* t in [t_s, t_s + length) up to the time tolerance */
static bool fault_active(const p2d_sim_t *sim, const p2d_fault_t *f, double length_s, double t_s)
{
    return t_s >= f->t_s - sim->t_tol_s && t_s < f->t_s + length_s - sim->t_tol_s;
}

/* The speed and angle the speed sensor measures: the load side with feedback from the load, else the motor's. */
static void sensed_side(const p2d_sim_t *sim, double *theta_rad, double *w_radps)
{
    if (sim->cfg.mechanics.feedback == P2D_FEEDBACK_LOAD) {
        p2d_plant_load_side(&sim->plant, theta_rad, w_radps);
    } else {
        p2d_plant_rotor(&sim->plant, theta_rad, w_radps);
    }
}

/*
 * The speed the speed controller reads at t_k: the first active sensor fault's, else the sensor's
 * reading w_sensor_radps (of the sensed side).
 */
static double speed_reading(const p2d_sim_t *sim, double t_k_s, double w_sensor_radps)
{
    const double Ts_speed_s = (double)sim->cfg.current_per_speed * sim->cfg.Ts_current_s;
    for (uint32_t i = 0; i < sim->cfg.n_faults; ++i) {
        const p2d_fault_t *f = &sim->cfg.faults[i];
        if (f->kind == P2D_FAULT_SENSOR_HOLD && fault_active(sim, f, f->duration_s, t_k_s)) return sim->w_meas_radps;
        if (f->kind == P2D_FAULT_SENSOR_ZERO && fault_active(sim, f, f->duration_s, t_k_s)) return 0.0;
        /* a spike is the one speed sample in [t_s, t_s + Ts_speed) */
        if (f->kind == P2D_FAULT_SENSOR_SPIKE && fault_active(sim, f, Ts_speed_s, t_k_s)) return f->value;
    }
    return w_sensor_radps;
}

/* The DC link over the current period starting at t: value u_dc under the first active sag, else u_dc. */
static double dc_link_V(const p2d_sim_t *sim, double t_s)
{
    for (uint32_t i = 0; i < sim->cfg.n_faults; ++i) {
        const p2d_fault_t *f = &sim->cfg.faults[i];
        if (f->kind == P2D_FAULT_DC_LINK_SAG && fault_active(sim, f, f->duration_s, t_s)) {
            return f->value * sim->cfg.u_dc_V;
        }
    }
    return sim->cfg.u_dc_V;
}

static p2d_sim_status_t stop(p2d_sim_t *sim, p2d_sim_status_t status, double t_s, double value, double bound)
{
    sim->status = status;
    sim->t_stop_s = t_s;
    sim->stop_value = value;
    sim->stop_bound = bound;
    return status;
}

/* The stop of the state at t, if any: non-finite, overspeed, overcurrent, checked in that order. */
static P2D_SIM_NOINLINE p2d_sim_status_t state_stop(p2d_sim_t *sim, double t_s)
{
    const p2d_plant_t *m = &sim->plant;
    double i2;
    if (!isfinite(m->id_A) || !isfinite(m->iq_A) || !isfinite(m->w_m_radps)) {
        return stop(sim, P2D_SIM_STOP_NONFINITE, t_s, 0.0, 0.0);
    }
    if (fabs(m->w_m_radps) > sim->w_bound_radps) {
        return stop(sim, P2D_SIM_STOP_OVERSPEED, t_s, fabs(m->w_m_radps), sim->w_bound_radps);
    }
    if (m->two_mass) {
        if (!isfinite(m->theta_rad) || !isfinite(m->w_load_radps)) {
            return stop(sim, P2D_SIM_STOP_NONFINITE, t_s, 0.0, 0.0);
        }
        if (fabs(m->w_load_radps) > sim->w_bound_radps) {
            return stop(sim, P2D_SIM_STOP_OVERSPEED, t_s, fabs(m->w_load_radps), sim->w_bound_radps);
        }
    }
    i2 = m->id_A * m->id_A + m->iq_A * m->iq_A;
    if (i2 > sim->i_bound_A * sim->i_bound_A) {
        return stop(sim, P2D_SIM_STOP_OVERCURRENT, t_s, sqrt(i2), sim->i_bound_A);
    }
    return P2D_SIM_OK;
}

/*
 * state_stop at the end of the current period, n_current periods done (t = n_current Ts_current),
 * with the state inside every bound decided by comparisons that NaN fails: ||i||^2 <= i_bound^2,
 * |w_m| <= w_bound (and |w_L|, theta finite with two_mass).
 */
static P2D_SIM_INLINE p2d_sim_status_t check_state(p2d_sim_t *sim, uint64_t n_current, bool plain)
{
    const p2d_plant_t *m = &sim->plant;
    double i2 = m->id_A * m->id_A + m->iq_A * m->iq_A;
    bool inside = i2 <= sim->i_bound2_A2 && fabs(m->w_m_radps) <= sim->w_bound_radps;
    if (!plain && m->two_mass) inside = inside && fabs(m->w_load_radps) <= sim->w_bound_radps && isfinite(m->theta_rad);
    return inside ? P2D_SIM_OK : state_stop(sim, count_as_double(n_current) * sim->cfg.Ts_current_s);
}

/* The plant's configuration of cfg, with the initial currents id0, iq0. */
static p2d_plant_config_t plant_config(const p2d_sim_config_t *cfg, double id0_A, double iq0_A)
{
    p2d_plant_config_t pc;
    memset(&pc, 0, sizeof pc);
    pc.motor = cfg->motor;
    pc.mechanics = cfg->mechanics;
    pc.u_dc_V = cfg->u_dc_V;
    pc.computation_delay = cfg->computation_delay;
    pc.Ts_s = cfg->Ts_current_s;
    pc.substeps = cfg->substeps;
    pc.tau_i_s = cfg->current_model == P2D_CURRENT_FIRST_ORDER ? cfg->tau_i_s : 0.0;
    pc.w_m0_radps = cfg->w_m0_radps;
    pc.id0_A = id0_A;
    pc.iq0_A = iq0_A;
    pc.current_sensor = cfg->sensing.current_sensor;
    pc.counts_per_rev = cfg->sensing.speed_sensor.model == P2D_SPEED_SENSOR_ENCODER
                            ? cfg->sensing.speed_sensor.encoder.counts_per_rev
                            : 0u;
    return pc;
}

/* ---- the fixed-point speed controller ----------------------------------- */

/* Fractional bits N of the arithmetic Q15 or Q31. */
static int fixed_bits(p2d_arithmetic_t arithmetic) { return arithmetic == P2D_ARITHMETIC_Q15 ? 15 : 31; }

/* Initialise the fixed-point speed controller of cfg (arithmetic Q15 or Q31) and its scalings. */
static p2d_status_t fixed_init(p2d_sim_fixed_t *f, const p2d_sim_config_t *cfg)
{
    const p2d_speed_fixed_config_t fc = {cfg->speed, cfg->speed_full_scale_radps, cfg->torque_full_scale_Nm,
                                         cfg->current_full_scale_A};
    const int bits = fixed_bits(cfg->arithmetic);
    const p2d_status_t status = bits == 15 ? p2d_speed_q15_init(&f->q15, &fc) : p2d_speed_q31_init(&f->q31, &fc);
    if (status != P2D_OK) return status;
    f->q_per_radps = ldexp(1.0, bits) / (double)cfg->speed_full_scale_radps;
    f->q_max = ldexp(1.0, bits) - 1.0;
    f->T_lsb_Nm = ldexp((double)cfg->torque_full_scale_Nm, -bits);
    f->i_lsb_A = ldexp((double)cfg->current_full_scale_A, -bits);
    return P2D_OK;
}

/* x (an integer) limited to [-q_max - 1, q_max]: an input or a torque of the format. */
static int32_t fixed_saturate(const p2d_sim_fixed_t *f, double x)
{
    return (int32_t)(x > f->q_max ? f->q_max : (x < -f->q_max - 1.0 ? -f->q_max - 1.0 : x));
}

/* The speed w [rad/s] as the nearest integer of the format (half up), saturated to its input range; false if
   w is not finite. */
static bool fixed_speed(const p2d_sim_fixed_t *f, double w_radps, int32_t *w_q)
{
    if (!isfinite(w_radps)) return false;
    *w_q = fixed_saturate(f, floor(w_radps * f->q_per_radps + 0.5));
    return true;
}

/*
 * The command of the fixed-point controller's present output: id = 0 and iq = iq_q I_fs 2^-N into
 * sim's command (double, for eq 3) and speed_out (float32, for the dq current controller).
 */
static void fixed_command(p2d_sim_t *sim)
{
    const p2d_sim_fixed_t *f = &sim->fixed;
    const bool q15 = sim->cfg.arithmetic == P2D_ARITHMETIC_Q15;
    sim->id_ref_A = 0.0;
    sim->iq_ref_A = (q15 ? (double)f->out_q15.iq_ref_q15 : (double)f->out_q31.iq_ref_q31) * f->i_lsb_A;
    sim->speed_out.id_ref_A = 0.0f;
    sim->speed_out.iq_ref_A = (float)sim->iq_ref_A;
}

/* Steady state at the reference w_m0 holding the torque T_Nm (rounded to the nearest LSB): reset and command. */
static void fixed_rest(p2d_sim_t *sim, double w_m0_radps, double T_Nm)
{
    p2d_sim_fixed_t *f = &sim->fixed;
    int32_t w_q = 0;
    const int32_t T_q = fixed_saturate(f, floor(T_Nm / f->T_lsb_Nm + 0.5));
    (void)fixed_speed(f, w_m0_radps, &w_q); /* w_m0 is finite (p2d_plant_init) */
    if (sim->cfg.arithmetic == P2D_ARITHMETIC_Q15) {
        p2d_speed_q15_reset(&f->q15, (int16_t)w_q, (int16_t)T_q);
        p2d_speed_q15_compute(&f->q15, (int16_t)w_q, (int16_t)w_q, &f->out_q15);
    } else {
        p2d_speed_q31_reset(&f->q31, w_q, T_q);
        p2d_speed_q31_compute(&f->q31, w_q, w_q, &f->out_q31);
    }
    fixed_command(sim);
}

p2d_sim_status_t p2d_sim_init(p2d_sim_t *sim, const p2d_sim_config_t *cfg)
{
    p2d_plant_config_t pc;
    p2d_plant_t *m;
    p2d_sim_status_t status;
    p2d_status_t ctl_status;
    p2d_speed_output_t so;
    p2d_sensing_check_t sensing;
    double T_hold_Nm, L_min_H;

    if (sim == 0 || cfg == 0) return P2D_SIM_ERR_NULL;
    status = config_status(cfg);
    if (status != P2D_SIM_OK) return status;
    m = &sim->plant;
    pc = plant_config(cfg, 0.0, 0.0);
    status = plant_error(p2d_plant_init(m, &pc));
    if (status != P2D_SIM_OK) return status;
    sim->cfg = *cfg;
    sim->controller_status = P2D_OK;
    if (cfg->arithmetic == P2D_ARITHMETIC_FLOAT32) {
        ctl_status = p2d_speed_init(&sim->speed, &cfg->speed);
        /* the torque filters, if any (p2d_speed_init leaves none) */
        if (ctl_status == P2D_OK &&
            (cfg->speed_filter.notch_freq_Hz != 0.0f || cfg->speed_filter.lowpass_freq_Hz != 0.0f)) {
            ctl_status = p2d_speed_set_filter(&sim->speed, &cfg->speed_filter);
        }
    } else {
        ctl_status = fixed_init(&sim->fixed, cfg);
    }
    if (ctl_status != P2D_OK) {
        sim->controller_status = ctl_status;
        return P2D_SIM_ERR_SPEED_CONTROLLER;
    }
    if (cfg->current_model == P2D_CURRENT_DQ_PI) {
        ctl_status = p2d_current_init(&sim->current, &cfg->current);
        if (ctl_status != P2D_OK) {
            sim->controller_status = ctl_status;
            return P2D_SIM_ERR_CURRENT_CONTROLLER;
        }
    } else {
        /* no current controller (eq 3): its state defined all the same, the periods address its coefficients */
        memset(&sim->current, 0, sizeof sim->current);
    }
    sensing =
        p2d_sensing_check(&cfg->sensing.speed_sensor, &cfg->sensing.current_sensor, &cfg->sensing.field_weakening,
                          cfg->Ts_current_s, cfg->speed.Ts_s, cfg->current_model == P2D_CURRENT_DQ_PI, &ctl_status);
    if (sensing != P2D_SENSING_VALID) {
        sim->controller_status = ctl_status;
        return sensing == P2D_SENSING_BAD_SPEED_SENSOR     ? P2D_SIM_ERR_SPEED_SENSOR
               : sensing == P2D_SENSING_BAD_CURRENT_SENSOR ? P2D_SIM_ERR_CURRENT_SENSOR
                                                           : P2D_SIM_ERR_FIELD_WEAKENING;
    }

    if (cfg->adapt.enabled && !is_nonnegative(cfg->adapt.adapt_rel_change)) return P2D_SIM_ERR_ADAPT_REL_CHANGE;
    if (cfg->adapt.enabled && !is_nonnegative(cfg->adapt.e_quiet_radps)) return P2D_SIM_ERR_E_QUIET;
    ctl_status = p2d_adapt_init(&sim->adapt, &cfg->adapt, (double)cfg->speed.J_kgm2);
    if (ctl_status != P2D_OK) {
        sim->controller_status = ctl_status;
        return P2D_SIM_ERR_ESTIMATOR;
    }

    sim->t_tol_s = P2D_SIM_T_TOL * m->dt_s;
    /* twice the no-load speed: 2 u_dc / (sqrt(3) p psi_f) */
    sim->w_bound_radps = P2D_SIM_OVERSPEED_FACTOR * m->u_max_V / (m->p * cfg->motor.psi_f_Wb);
    /* ten times max(i_max, psi_f / min(Ld, Lq)) */
    L_min_H = fmin(cfg->motor.Ld_H, cfg->motor.Lq_H);
    sim->i_bound_A = P2D_SIM_OVERCURRENT_FACTOR * fmax((double)cfg->speed.i_max_A, cfg->motor.psi_f_Wb / L_min_H);
    sim->i_bound2_A2 = sim->i_bound_A * sim->i_bound_A;
    if (fabs(cfg->w_m0_radps) > sim->w_bound_radps) return P2D_SIM_ERR_W_M0;

    cursor_reset(&sim->reference);
    cursor_reset(&sim->load);
    sim->n_current = 0u;
    sim->n_speed = 0u;
    sim->n_rows = 0u;
    sim->status = P2D_SIM_OK;
    sim->t_stop_s = 0.0;
    sim->stop_value = 0.0;
    sim->stop_bound = 0.0;
    sim->w_meas_radps = cfg->w_m0_radps;
    sim->saturated = false;
    sim->current_saturated = false;
    sim->dc_link_sag = false;
    for (uint32_t i = 0; i < cfg->n_faults; ++i) sim->dc_link_sag |= cfg->faults[i].kind == P2D_FAULT_DC_LINK_SAG;
    sim->w_ref_radps = cfg->w_m0_radps;
    sim->n_limited = 0u;
    sim->fma = cpu_has_fma();
    sim->speed_special = cfg->arithmetic != P2D_ARITHMETIC_FLOAT32 || cfg->sensing.field_weakening.enabled;

    /* steady state at w_m0 before t = 0: the torque that holds w_m0 against friction */
    p2d_sensing_init(&sim->sensing, &cfg->sensing.speed_sensor, &cfg->sensing.current_sensor,
                     &cfg->sensing.field_weakening, cfg->speed.Ts_s, cfg->w_m0_radps);
    T_hold_Nm = p2d_plant_friction_Nm(m, cfg->w_m0_radps);
    if (cfg->arithmetic == P2D_ARITHMETIC_FLOAT32) {
        p2d_speed_reset(&sim->speed, (float)cfg->w_m0_radps, (float)T_hold_Nm);
        p2d_speed_compute(&sim->speed, (float)cfg->w_m0_radps, (float)cfg->w_m0_radps, &so);
        if (so.fault) return P2D_SIM_ERR_W_M0;
        sim->id_ref_A = (double)so.id_ref_A;
        sim->iq_ref_A = (double)so.iq_ref_A;
    } else {
        fixed_rest(sim, cfg->w_m0_radps, T_hold_Nm);
    }
    /* the currents equal the command */
    pc = plant_config(cfg, sim->id_ref_A, sim->iq_ref_A);
    (void)p2d_plant_init(m, &pc);
    if (cfg->current_model == P2D_CURRENT_DQ_PI) {
        const p2d_current_coef_t *c = &sim->current.coef[sim->current.active];
        double w_e = m->p * m->w_m_radps;
        double ud_V, uq_V;
        p2d_plant_steady_voltage(m, &ud_V, &uq_V);
        /* integrators: zero error gives ud = x_d - w_e Lq iq, uq = x_q + w_e (Ld id + psi_f) (decoupling) */
        sim->current.x_d_V = (float)(ud_V + w_e * (double)c->Lq_H * m->iq_A);
        sim->current.x_q_V = (float)(uq_V - w_e * ((double)c->Ld_H * m->id_A + (double)c->psi_f_Wb));
    }
    return P2D_SIM_OK;
}

/* ---- loop --------------------------------------------------------------- */

/*
 * The fixed-point speed controller's columns of the log row `row` (of a log of log_rows rows): its
 * outputs in Nm and A, and its integrator x - Fr0 r from x in its LSBs (2^-(N + F) of T_fs, F = 0 in
 * Q15, 31 in Q31) and Fr0 = m 2^-s per unit, (x 2^-F - m r 2^-s) T_fs 2^-N.
 */
static P2D_SIM_NOINLINE void fixed_columns(const p2d_sim_t *sim, double *row, uint64_t log_rows)
{
    const p2d_sim_fixed_t *f = &sim->fixed;
    double T_ref, T_unsat, iq_ref, x_i;
    bool saturated;
    if (sim->cfg.arithmetic == P2D_ARITHMETIC_Q15) {
        const p2d_q15_gain_t Fr0 = f->q15.coef[f->q15.active].ff_Fr0;
        T_ref = (double)f->out_q15.T_ref_q15;
        T_unsat = (double)f->out_q15.T_unsat_q15;
        iq_ref = (double)f->out_q15.iq_ref_q15;
        saturated = f->out_q15.saturated;
        x_i = (double)f->q15.x_q15 - ldexp((double)Fr0.mantissa * (double)f->q15.r_prev_q15, -(int)Fr0.shift);
    } else {
        const p2d_q31_gain_t Fr0 = f->q31.coef[f->q31.active].ff_Fr0;
        T_ref = (double)f->out_q31.T_ref_q31;
        T_unsat = (double)f->out_q31.T_unsat_q31;
        iq_ref = (double)f->out_q31.iq_ref_q31;
        saturated = f->out_q31.saturated;
        x_i =
            ldexp((double)f->q31.x_q62, -31) - ldexp((double)Fr0.mantissa * (double)f->q31.r_prev_q31, -(int)Fr0.shift);
    }
    row[P2D_LOG_ID_REF_A * log_rows] = 0.0;
    row[P2D_LOG_IQ_REF_A * log_rows] = iq_ref * f->i_lsb_A;
    row[P2D_LOG_TORQUE_REF_NM * log_rows] = T_ref * f->T_lsb_Nm;
    row[P2D_LOG_TORQUE_UNSAT_NM * log_rows] = T_unsat * f->T_lsb_Nm;
    row[P2D_LOG_SATURATED * log_rows] = saturated ? 1.0 : 0.0;
    row[P2D_LOG_X_I_NM * log_rows] = x_i * f->T_lsb_Nm;
}

/*
 * Write the row of the current period starting at t_k into the column-major log of log_rows rows (at n_rows);
 * the speed controller's columns of the float32 one or, with a fixed-point one, fixed_columns.
 */
static P2D_SIM_INLINE void log_write(p2d_sim_t *sim, double *log, uint64_t log_rows, double t_k_s, double ud_V,
                                     double uq_V)
{
    const p2d_plant_t *m = &sim->plant;
    const p2d_speed_output_t *so = &sim->speed_out;
    double *row = log + sim->n_rows;
    double theta_L_rad, w_L_radps;
    cursor_advance(&sim->load, &sim->cfg.load, t_k_s + sim->t_tol_s);
    p2d_plant_load_side(m, &theta_L_rad, &w_L_radps);
    row[P2D_LOG_T_S * log_rows] = t_k_s;
    row[P2D_LOG_W_REF_RADPS * log_rows] = sim->w_ref_radps;
    row[P2D_LOG_W_M_RADPS * log_rows] = m->w_m_radps;
    row[P2D_LOG_ID_A * log_rows] = m->id_A;
    row[P2D_LOG_IQ_A * log_rows] = m->iq_A;
    row[P2D_LOG_UD_V * log_rows] = ud_V;
    row[P2D_LOG_UQ_V * log_rows] = uq_V;
    row[P2D_LOG_TORQUE_NM * log_rows] = p2d_plant_torque_Nm(m);
    if (sim->cfg.arithmetic == P2D_ARITHMETIC_FLOAT32) {
        row[P2D_LOG_ID_REF_A * log_rows] = (double)so->id_ref_A;
        row[P2D_LOG_IQ_REF_A * log_rows] = (double)so->iq_ref_A;
        row[P2D_LOG_TORQUE_REF_NM * log_rows] = (double)so->T_ref_Nm;
        row[P2D_LOG_TORQUE_UNSAT_NM * log_rows] = (double)so->T_unsat_Nm;
        row[P2D_LOG_SATURATED * log_rows] = so->saturated ? 1.0 : 0.0;
        row[P2D_LOG_X_I_NM * log_rows] = (double)p2d_speed_integral_Nm(&sim->speed);
    } else {
        fixed_columns(sim, row, log_rows);
    }
    row[P2D_LOG_LOAD_NM * log_rows] = segment_value(&sim->load, t_k_s);
    row[P2D_LOG_W_MEAS_RADPS * log_rows] = sim->w_meas_radps;
    row[P2D_LOG_U_DC_V * log_rows] = m->u_dc_V;
    row[P2D_LOG_VOLTAGE_LIMITED * log_rows] = 0.0; /* the share, written at the end of the speed sample */
    row[P2D_LOG_J_EST_KGM2 * log_rows] = (double)sim->adapt.out.J_kgm2;
    row[P2D_LOG_J_VALID * log_rows] = sim->adapt.out.J_valid ? 1.0 : 0.0;
    row[P2D_LOG_T_LOAD_EST_NM * log_rows] = (double)sim->adapt.out.T_load_Nm;
    row[P2D_LOG_J_GAINS_KGM2 * log_rows] = sim->adapt.J_gains_kgm2;
    row[P2D_LOG_W_LOAD_RADPS * log_rows] = w_L_radps;
    row[P2D_LOG_SHAFT_TORQUE_NM * log_rows] = p2d_plant_shaft_torque_Nm(m, row[P2D_LOG_LOAD_NM * log_rows]);
    sim->n_rows++;
}

/*
 * The fixed-point speed controller's step of speed sample k at t_k (after the inputs of speed_sample):
 * the reference and the reading rounded to its integers, its output in sim->fixed, the command in sim.
 */
static P2D_SIM_NOINLINE p2d_sim_status_t fixed_sample(p2d_sim_t *sim, double t_k_s)
{
    p2d_sim_fixed_t *f = &sim->fixed;
    int32_t w_ref_q, w_meas_q;
    if (!fixed_speed(f, sim->w_ref_radps, &w_ref_q) || !fixed_speed(f, sim->w_meas_radps, &w_meas_q)) {
        return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k_s, 0.0, 0.0);
    }
    if (sim->cfg.arithmetic == P2D_ARITHMETIC_Q15) {
        p2d_speed_q15_step(&f->q15, (int16_t)w_ref_q, (int16_t)w_meas_q, &f->out_q15);
        sim->saturated = f->out_q15.saturated;
    } else {
        p2d_speed_q31_step(&f->q31, w_ref_q, w_meas_q, &f->out_q31);
        sim->saturated = f->out_q31.saturated;
    }
    fixed_command(sim);
    sim->n_limited = 0u;
    return P2D_SIM_OK;
}

/*
 * Speed sample k at t_k: the reference and the speed reading sampled, the estimator, and the speed
 * controller: the float32 one (with the field weakening, if any; its output in sim->speed_out) or
 * the fixed-point one (fixed_sample).
 */
static p2d_sim_status_t speed_sample(p2d_sim_t *sim, double t_k_s)
{
    const p2d_sim_config_t *cfg = &sim->cfg;
    p2d_speed_output_t *so = &sim->speed_out;
    double w_sensor, theta_s_rad, w_s_radps;
    cursor_advance(&sim->reference, &cfg->reference, t_k_s + sim->t_tol_s);
    sim->w_ref_radps = segment_value(&sim->reference, t_k_s);
    sensed_side(sim, &theta_s_rad, &w_s_radps);
    if (!p2d_sensing_speed(&sim->sensing, &cfg->sensing.speed_sensor, sim->n_current, cfg->Ts_current_s,
                           cfg->w_m0_radps, theta_s_rad, w_s_radps, &w_sensor)) {
        return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k_s, 0.0, 0.0);
    }
    sim->w_meas_radps = speed_reading(sim, t_k_s, w_sensor);
    if (cfg->adapt.enabled) {
        p2d_adapt_sample(&sim->adapt, sim->w_meas_radps, sim->w_ref_radps, sim->saturated, &sim->speed);
    }
    if (sim->speed_special) {
        float id_fw_A;
        /* a fixed-point controller (with no field weakening, p2d_sim_init), or the field weakening */
        if (cfg->arithmetic != P2D_ARITHMETIC_FLOAT32) return fixed_sample(sim, t_k_s);
        if (!p2d_sensing_field_weakening(&sim->sensing, sim->plant.u_dc_V, &id_fw_A)) {
            return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k_s, 0.0, 0.0);
        }
        p2d_speed_step_fw(&sim->speed, (float)sim->w_ref_radps, (float)sim->w_meas_radps, id_fw_A, so);
    } else {
        p2d_speed_step(&sim->speed, (float)sim->w_ref_radps, (float)sim->w_meas_radps, so);
    }
    if (so->fault) return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k_s, 0.0, 0.0);
    sim->id_ref_A = (double)so->id_ref_A;
    sim->iq_ref_A = (double)so->iq_ref_A;
    sim->saturated = so->saturated;
    sim->n_limited = 0u;
    return P2D_SIM_OK;
}

/*
 * The start of the current period at t = n_current Ts_current: the DC link, the current
 * controller and the inverter (dq_pi) or eq 3's command (first_order), the log row of the period
 * (log_row) and the estimator's torque sample. cc: the current controller's active coefficients;
 * plain: the drive is plain (drive_plain).
 */
static P2D_SIM_INLINE p2d_sim_status_t period_start(p2d_sim_t *sim, const p2d_current_coef_t *cc, double t_s,
                                                    bool first_order, bool plain, bool log_row, double *log,
                                                    uint64_t log_rows)
{
    const p2d_sim_config_t *cfg = &sim->cfg;
    p2d_plant_t *m = &sim->plant;
    if (!first_order) {
        p2d_current_output_t co;
        p2d_inverter_output_t io;
        float id_meas_A = (float)m->id_A, iq_meas_A = (float)m->iq_A;
        /* the DC link of this period sets the inverter's range and the controller's measurement */
        if (!plain && sim->dc_link_sag) {
            double u_dc_V = dc_link_V(sim, t_s);
            if (u_dc_V != m->u_dc_V) p2d_plant_set_dc_link(m, u_dc_V);
        }
        if (!plain && sim->sensing.current_sensor) {
            double id_A, iq_A;
            p2d_sensing_currents(m, &id_A, &iq_A);
            id_meas_A = (float)id_A;
            iq_meas_A = (float)iq_A;
        }
        /* p2d_current_compute, inlined */
        if (!p2d_current_voltage(&sim->current, cc, sim->speed_out.id_ref_A, sim->speed_out.iq_ref_A, id_meas_A,
                                 iq_meas_A, (float)(m->p * m->w_m_radps), (float)m->u_dc_V, &co)) {
            return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_s, 0.0, 0.0);
        }
        sim->sensing.ud_unsat_V = co.ud_unsat_V;
        sim->sensing.uq_unsat_V = co.uq_unsat_V;
        p2d_plant_inverter(m, (double)co.ud_ref_V, (double)co.uq_ref_V, &io);
        /* the voltage of this period was cut: by the controller or the inverter, now or when it was given */
        if (cfg->computation_delay) {
            sim->n_limited += io.applied_limited || sim->current_saturated;
            sim->current_saturated = co.saturated;
        } else {
            sim->n_limited += co.saturated || io.limited;
        }
        /*
         * the integrators learn the command the inverter accepted: p2d_current_update, inlined, of an
         * output that is no fault with a command that is finite (the controller's, at most scaled down)
         */
        p2d_current_integrate(&sim->current, cc, &co, (float)io.ud_V, (float)io.uq_V);
    } else {
        sim->n_limited += p2d_plant_command_currents(m, sim->id_ref_A, sim->iq_ref_A);
    }
    if (log_row) {
        double ud_V, uq_V;
        p2d_plant_applied_voltage(m, &ud_V, &uq_V);
        log_write(sim, log, log_rows, t_s, ud_V, uq_V);
    }
    if (!plain && cfg->adapt.enabled) p2d_adapt_torque(&sim->adapt, p2d_plant_torque_Nm(m));
    return P2D_SIM_OK;
}

/*
 * The length h = t_end - t of substep s of the current period starting at t_start (as the split
 * steps of plant_advance_split compute it), and its start t.
 */
static P2D_SIM_INLINE double substep_length(const p2d_sim_t *sim, double t_start_s, uint32_t s, double *t_s)
{
    double dt_s = sim->plant.dt_s;
    /* t_start + s dt and t_start + (s + 1) dt; for s = 0 the same values without the products (0 dt = +0, 1 dt = dt) */
    double t_end = t_start_s + (s == 0u ? dt_s : (double)(s + 1u) * dt_s);
    *t_s = s == 0u ? t_start_s : t_start_s + (double)s * dt_s;
    return t_end - *t_s;
}

/*
 * Substep s of the current period starting at t_start: its length h (substep_length) and the load
 * T0 at its start with the slope dT_dt at its middle. Valid when the load has no breakpoint inside
 * the period (load_smooth).
 */
static P2D_SIM_INLINE void substep(const p2d_sim_t *sim, double t_start_s, uint32_t s, double *h_s, double *T0_Nm,
                                   double *dT_dt_Nmps)
{
    double t;
    *h_s = substep_length(sim, t_start_s, s, &t);
    *T0_Nm = segment_value(&sim->load, t);
    *dT_dt_Nmps = segment_slope(&sim->load, t + 0.5 * *h_s);
}

/*
 * No load breakpoint falls inside the current period starting at t_start, as far as the cursor
 * knows (its next breakpoint, -HUGE_VAL when unknown): every substep is then one RK4 step with
 * the load of `substep`, and the cursor needs no advance, as in plant_advance_split.
 * substeps_dt_s = (double)substeps dt, the period's end t_start + substeps dt.
 */
static P2D_SIM_INLINE bool load_smooth(const p2d_sim_t *sim, double t_start_s, double substeps_dt_s)
{
    double t_end = t_start_s + substeps_dt_s;
    return sim->load.t_break_s >= t_end - sim->t_tol_s;
}

/*
 * The plant over the current period starting at t_start with its input held: `substeps` RK4
 * steps, each split at the load's breakpoints inside it, so that every step sees a load linear
 * in time.
 */
static P2D_SIM_NOINLINE void plant_advance_split(p2d_sim_t *sim, double t_start_s)
{
    const double dt_s = sim->plant.dt_s;
    for (uint32_t s = 0; s < sim->cfg.substeps; ++s) {
        double t = t_start_s + (double)s * dt_s;
        double t_end = t_start_s + (double)(s + 1u) * dt_s;
        while (t < t_end - sim->t_tol_s) {
            double t_break, t_stop, h;
            t_break = cursor_break_after(&sim->load, &sim->cfg.load, t + sim->t_tol_s);
            /* split the step at a load breakpoint inside it */
            t_stop = t_break < t_end - sim->t_tol_s ? t_break : t_end;
            h = t_stop - t;
            p2d_plant_advance(&sim->plant, h, segment_value(&sim->load, t), segment_slope(&sim->load, t + 0.5 * h));
            t = t_stop;
        }
    }
}

/* The end of the current period: the time advances, the sensor's history, the checks. */
static P2D_SIM_INLINE p2d_sim_status_t period_end(p2d_sim_t *sim, bool plain)
{
    sim->n_current++;
    if (!plain && sim->sensing.history) {
        double theta_s_rad, w_s_radps;
        sensed_side(sim, &theta_s_rad, &w_s_radps);
        p2d_sensing_record(&sim->sensing, sim->n_current, theta_s_rad, w_s_radps);
    }
    return check_state(sim, sim->n_current, plain);
}

/*
 * The end of speed sample k: the share of its current periods at the voltage limit, into its rows
 * (log_row: its first period's, at the speed rate; at the current rate its periods' from row0 on).
 */
static P2D_SIM_INLINE void sample_end(p2d_sim_t *sim, bool per_current, bool log_row, uint64_t row0, double *log,
                                      uint64_t log_rows)
{
    if (per_current) {
        for (uint64_t r = row0; r < sim->n_rows; ++r) {
            log[P2D_LOG_VOLTAGE_LIMITED * log_rows + r] = (double)sim->n_limited / (double)sim->cfg.current_per_speed;
        }
    } else if (log_row) {
        log[P2D_LOG_VOLTAGE_LIMITED * log_rows + sim->n_rows - 1u] =
            (double)sim->n_limited / (double)sim->cfg.current_per_speed;
    }
    sim->n_speed++;
}

/* The multiples of E in [n0, n0 + n): ceil((n0 + n) / E) - ceil(n0 / E), without overflow. */
static uint64_t multiples_in(uint64_t n0, uint64_t n, uint64_t E)
{
    uint64_t first = n0 % E == 0u ? n0 : n0 + (E - n0 % E);
    if (n == 0u || first - n0 >= n) return 0u;
    return (n - 1u - (first - n0)) / E + 1u;
}

/*
 * Rows the log needs for the next n_samples speed samples: their samples (SPEED) or current periods
 * (CURRENT) counted by log_every; UINT64_MAX when the periods overflow the count.
 */
static uint64_t rows_needed(const p2d_sim_t *sim, uint64_t n_samples)
{
    const uint64_t cps = sim->cfg.current_per_speed;
    if (sim->cfg.log_rate == P2D_LOG_RATE_SPEED) return multiples_in(sim->n_speed, n_samples, sim->cfg.log_every);
    if (n_samples > (UINT64_MAX - sim->n_current) / cps) return UINT64_MAX;
    return multiples_in(sim->n_current, n_samples * cps, sim->cfg.log_every);
}

/* The log of log_rows rows has room for the rows of the next n_samples speed samples. */
static bool log_room(const p2d_sim_t *sim, uint64_t n_samples, const double *log, uint64_t log_rows)
{
    uint64_t rows = rows_needed(sim, n_samples);
    return rows == 0u || (log != 0 && sim->n_rows <= log_rows && rows <= log_rows - sim->n_rows);
}

/*
 * The RK4 step kinds: one specialised copy of the step for each (current model, Coulomb friction,
 * drive train), and a lean one of a rigid train without Coulomb friction for a surface PMSM
 * without viscous friction whose angle no sensor needs (p2d_plant_rk4). Every drive of a
 * lockstep group has the kind of a lone one: the same copy, the same arithmetic.
 */
enum { P2D_KIND_FIRST_ORDER = 1, P2D_KIND_COULOMB = 2, P2D_KIND_TWO_MASS = 4, P2D_KIND_LEAN = 8 };

static uint32_t step_kind(const p2d_sim_t *sim)
{
    const p2d_plant_t *m = &sim->plant;
    bool lean = !m->coulomb && !m->two_mass && m->coef.cT_J == 0.0 && m->coef.B_J_per_s == 0.0 && !sim->sensing.angle;
    return (m->first_order ? (uint32_t)P2D_KIND_FIRST_ORDER : 0u) | (m->coulomb ? (uint32_t)P2D_KIND_COULOMB : 0u) |
           (m->two_mass ? (uint32_t)P2D_KIND_TWO_MASS : 0u) | (lean ? (uint32_t)P2D_KIND_LEAN : 0u);
}

/* One RK4 step of the plant m of the kind given (its input held): the kind's copy of the step. */
static P2D_SIM_INLINE void step_one(p2d_plant_t *m, uint32_t kind, double h, double T0, double dT)
{
    p2d_plant_x_t x = p2d_plant_state(m);
    const p2d_plant_coef_t *c = &m->coef;
    switch (kind) {
    case P2D_KIND_LEAN: x = p2d_plant_rk4(c, x, m->a_d, m->a_q, h, T0, dT, false, false, false, true); break;
    case P2D_KIND_LEAN | P2D_KIND_FIRST_ORDER:
        x = p2d_plant_rk4(c, x, m->a_d, m->a_q, h, T0, dT, true, false, false, true);
        break;
    case 0: x = p2d_plant_rk4(c, x, m->a_d, m->a_q, h, T0, dT, false, false, false, false); break;
    case P2D_KIND_FIRST_ORDER: x = p2d_plant_rk4(c, x, m->a_d, m->a_q, h, T0, dT, true, false, false, false); break;
    default: p2d_plant_advance(m, h, T0, dT); return;
    }
    p2d_plant_set_state(m, x);
}

/* ---- lockstep ----------------------------------------------------------- */

/* The plants of a lockstep group: one array per coefficient, state variable and input, one element per drive. */
typedef struct {
    double Rs_Ld_per_s[P2D_SIM_LANES];         /* Rs / Ld [1/s] */
    double Rs_Lq_per_s[P2D_SIM_LANES];         /* Rs / Lq [1/s] */
    double p_Lq_Ld[P2D_SIM_LANES];             /* p Lq / Ld [-] */
    double p_Ld_Lq[P2D_SIM_LANES];             /* p Ld / Lq [-] */
    double p_psi_Lq_A[P2D_SIM_LANES];          /* p psi_f / Lq [A] */
    double inv_Ld_per_H[P2D_SIM_LANES];        /* 1 / Ld [1/H] */
    double inv_Lq_per_H[P2D_SIM_LANES];        /* 1 / Lq [1/H] */
    double kt_J[P2D_SIM_LANES];                /* 1.5 p psi_f / J [rad/s^2 per A] */
    double cT_J[P2D_SIM_LANES];                /* 1.5 p (Ld - Lq) / J [rad/s^2 per A^2] */
    double B_J_per_s[P2D_SIM_LANES];           /* B / J [1/s] */
    double Tc_J_radps2[P2D_SIM_LANES];         /* T_c / J [rad/s^2] */
    double inv_w_c_s_per_rad[P2D_SIM_LANES];   /* 1 / w_c [s/rad] */
    double inv_J_per_kgm2[P2D_SIM_LANES];      /* 1 / J [1/(kg m^2)] */
    double inv_tau_i_per_s[P2D_SIM_LANES];     /* 1 / tau_i [1/s] */
    double K_Nm_per_rad[P2D_SIM_LANES];        /* K [Nm/rad] */
    double D_Nms_per_rad[P2D_SIM_LANES];       /* D [Nm s/rad] */
    double half_backlash_rad[P2D_SIM_LANES];   /* b / 2 [rad] */
    double inv_J_load_per_kgm2[P2D_SIM_LANES]; /* 1 / J_L [1/(kg m^2)] */
    double id_A[P2D_SIM_LANES];                /* state: d-axis current [A] */
    double iq_A[P2D_SIM_LANES];                /* state: q-axis current [A] */
    double w_m_radps[P2D_SIM_LANES];           /* state: motor speed [rad/s] */
    double theta_m_rad[P2D_SIM_LANES];         /* state: motor angle [rad] */
    double theta_rad[P2D_SIM_LANES];           /* state: twist [rad] */
    double w_load_radps[P2D_SIM_LANES];        /* state: load-side speed [rad/s] */
    double a_d[P2D_SIM_LANES];                 /* input: ud [V] (eq 3: id_ref [A]) */
    double a_q[P2D_SIM_LANES];                 /* input: uq [V] (eq 3: iq_ref [A]) */
    double T0_Nm[P2D_SIM_LANES];               /* load at the start of the step [Nm] */
    double dT_Nmps[P2D_SIM_LANES];             /* its slope [Nm/s] */
} p2d_sim_lanes_t;

/* Coefficients of lane l from the plant m. */
static void lanes_set_coef(p2d_sim_lanes_t *L, uint32_t l, const p2d_plant_coef_t *c)
{
    L->Rs_Ld_per_s[l] = c->Rs_Ld_per_s;
    L->Rs_Lq_per_s[l] = c->Rs_Lq_per_s;
    L->p_Lq_Ld[l] = c->p_Lq_Ld;
    L->p_Ld_Lq[l] = c->p_Ld_Lq;
    L->p_psi_Lq_A[l] = c->p_psi_Lq_A;
    L->inv_Ld_per_H[l] = c->inv_Ld_per_H;
    L->inv_Lq_per_H[l] = c->inv_Lq_per_H;
    L->kt_J[l] = c->kt_J;
    L->cT_J[l] = c->cT_J;
    L->B_J_per_s[l] = c->B_J_per_s;
    L->Tc_J_radps2[l] = c->Tc_J_radps2;
    L->inv_w_c_s_per_rad[l] = c->inv_w_c_s_per_rad;
    L->inv_J_per_kgm2[l] = c->inv_J_per_kgm2;
    L->inv_tau_i_per_s[l] = c->inv_tau_i_per_s;
    L->K_Nm_per_rad[l] = c->K_Nm_per_rad;
    L->D_Nms_per_rad[l] = c->D_Nms_per_rad;
    L->half_backlash_rad[l] = c->half_backlash_rad;
    L->inv_J_load_per_kgm2[l] = c->inv_J_load_per_kgm2;
}

/* One RK4 step of every lane (inputs and loads of the arrays), the kind's copy; the compiler vectorises it. */
static P2D_SIM_INLINE void lanes_step_kind(p2d_sim_lanes_t *L, double h, bool first_order, bool coulomb, bool two_mass,
                                           bool lean)
{
    for (uint32_t l = 0; l < P2D_SIM_LANES; ++l) {
        p2d_plant_coef_t c = {
            L->Rs_Ld_per_s[l],
            L->Rs_Lq_per_s[l],
            L->p_Lq_Ld[l],
            L->p_Ld_Lq[l],
            L->p_psi_Lq_A[l],
            L->inv_Ld_per_H[l],
            L->inv_Lq_per_H[l],
            L->kt_J[l],
            L->cT_J[l],
            L->B_J_per_s[l],
            L->Tc_J_radps2[l],
            L->inv_w_c_s_per_rad[l],
            L->inv_J_per_kgm2[l],
            L->inv_tau_i_per_s[l],
            L->K_Nm_per_rad[l],
            L->D_Nms_per_rad[l],
            L->half_backlash_rad[l],
            L->inv_J_load_per_kgm2[l],
        };
        p2d_plant_x_t x = {L->id_A[l],        L->iq_A[l],      L->w_m_radps[l],
                           L->theta_m_rad[l], L->theta_rad[l], L->w_load_radps[l]};
        x = p2d_plant_rk4(&c, x, L->a_d[l], L->a_q[l], h, L->T0_Nm[l], L->dT_Nmps[l], first_order, coulomb, two_mass,
                          lean);
        L->id_A[l] = x.id_A;
        L->iq_A[l] = x.iq_A;
        L->w_m_radps[l] = x.w_m_radps;
        L->theta_m_rad[l] = x.theta_m_rad;
        L->theta_rad[l] = x.theta_rad;
        L->w_load_radps[l] = x.w_load_radps;
    }
}

/* One RK4 step of every lane, the copy of the kind (step_kind) as step_one's. */
static P2D_SIM_INLINE void lanes_step_any(p2d_sim_lanes_t *L, uint32_t kind, double h)
{
    switch (kind) {
    case P2D_KIND_LEAN: lanes_step_kind(L, h, false, false, false, true); break;
    case P2D_KIND_LEAN | P2D_KIND_FIRST_ORDER: lanes_step_kind(L, h, true, false, false, true); break;
    case 0: lanes_step_kind(L, h, false, false, false, false); break;
    case P2D_KIND_FIRST_ORDER: lanes_step_kind(L, h, true, false, false, false); break;
    case P2D_KIND_COULOMB: lanes_step_kind(L, h, false, true, false, false); break;
    case P2D_KIND_FIRST_ORDER | P2D_KIND_COULOMB: lanes_step_kind(L, h, true, true, false, false); break;
    case P2D_KIND_TWO_MASS: lanes_step_kind(L, h, false, false, true, false); break;
    case P2D_KIND_TWO_MASS | P2D_KIND_FIRST_ORDER: lanes_step_kind(L, h, true, false, true, false); break;
    case P2D_KIND_TWO_MASS | P2D_KIND_COULOMB: lanes_step_kind(L, h, false, true, true, false); break;
    default: lanes_step_kind(L, h, true, true, true, false); break;
    }
}

/* lanes_step_any out of the loop's registers, for the baseline ISA (and P2D_SIM_FMA_TARGET below). */
static P2D_SIM_NOINLINE void lanes_step(p2d_sim_lanes_t *L, uint32_t kind, double h) { lanes_step_any(L, kind, h); }
#ifdef P2D_SIM_FMA_TARGET
static P2D_SIM_FMA_TARGET P2D_SIM_NOINLINE void lanes_step_fma(p2d_sim_lanes_t *L, uint32_t kind, double h)
{
    lanes_step_any(L, kind, h);
}
#else
#define lanes_step_fma lanes_step
#endif

/* The state and input of lane l from the plant m. */
static P2D_SIM_INLINE void lanes_load(p2d_sim_lanes_t *L, uint32_t l, const p2d_plant_t *m)
{
    L->id_A[l] = m->id_A;
    L->iq_A[l] = m->iq_A;
    L->w_m_radps[l] = m->w_m_radps;
    L->theta_m_rad[l] = m->theta_m_rad;
    L->theta_rad[l] = m->theta_rad;
    L->w_load_radps[l] = m->w_load_radps;
    L->a_d[l] = m->a_d;
    L->a_q[l] = m->a_q;
}

/* The state of lane l into the plant m. */
static P2D_SIM_INLINE void lanes_store(const p2d_sim_lanes_t *L, uint32_t l, p2d_plant_t *m)
{
    m->id_A = L->id_A[l];
    m->iq_A = L->iq_A[l];
    m->w_m_radps = L->w_m_radps[l];
    m->theta_m_rad = L->theta_m_rad[l];
    m->theta_rad = L->theta_rad[l];
    m->w_load_radps = L->w_load_radps[l];
}

/* Lane l idle (no drive, or one that stopped): a plant at rest with no input and no load, which stays finite. */
static void lanes_idle(p2d_sim_lanes_t *L, uint32_t l)
{
    L->id_A[l] = L->iq_A[l] = L->w_m_radps[l] = L->theta_m_rad[l] = L->theta_rad[l] = L->w_load_radps[l] = 0.0;
    L->a_d[l] = L->a_q[l] = L->T0_Nm[l] = L->dT_Nmps[l] = 0.0;
}

/* The loop's constants of a lockstep group (or of a lone drive), the same for every drive of it. */
typedef struct {
    uint32_t n;               /* drives [-] */
    uint32_t lanes;           /* 1: the plant stepped in place; P2D_SIM_LANES: the plants through the arrays of L */
    uint32_t kind;            /* the RK4 step's kind (step_kind) */
    uint32_t substeps;        /* RK4 steps per current period [-] */
    double substeps_dt_s;     /* substeps dt, the current period as the steps add up [s] */
    bool first_order;         /* the current loop of eq 3 (no current controller) */
    bool fma;                 /* the lanes' step of the FMA copy */
    double *const *logs;      /* the logs of the drives */
    const uint64_t *log_rows; /* their rows [-] */
} p2d_sim_group_t;

/*
 * The lone drive has none of the features a current period tests for: a DC-link sag, current
 * sensors, a sensor's history, the estimator, the two-mass train; and one RK4 step per period.
 */
static bool drive_plain(const p2d_sim_t *sim)
{
    return !sim->dc_link_sag && !sim->sensing.current_sensor && !sim->sensing.history && !sim->cfg.adapt.enabled &&
           !sim->plant.two_mass && sim->cfg.substeps == 1u;
}

/* Drive l leaves the group (a stop): its lane idles. */
static P2D_SIM_INLINE void group_leave(uint32_t lanes, p2d_sim_lanes_t *L, bool *active, uint32_t *n_active, uint32_t l)
{
    active[l] = false;
    (*n_active)--;
    if (lanes > 1u) lanes_idle(L, l);
}

/*
 * The current period of the group starting at t: the controllers and the inverters (with the
 * period's log row if log_row), the plants over the period, the checks at its end. smooth_known: no
 * drive's load has a breakpoint inside the period, known before (else the period's own test,
 * load_smooth); load_v1: moreover the lone drive's load constant over it, its value v1 and no slope;
 * plain: the lone drive is plain (drive_plain).
 */
static P2D_SIM_INLINE void group_period(p2d_sim_t *const *sims, const p2d_sim_group_t g, p2d_sim_lanes_t *L,
                                        bool *active, uint32_t *n_active, double t, bool log_row, bool smooth_known,
                                        bool load_v1, bool plain)
{
    const uint32_t substeps = plain ? 1u : g.substeps;
    double h = 0.0;
    bool smooth = true;
    /* the controllers and the inverters; the plants' states and inputs into the lanes */
    for (uint32_t l = 0; l < g.n; ++l) {
        if (!active[l]) continue;
        if (period_start(sims[l], &sims[l]->current.coef[sims[l]->current.active], t, g.first_order, plain, log_row,
                         g.logs[l], g.log_rows[l]) != P2D_SIM_OK) {
            group_leave(g.lanes, L, active, n_active, l);
            continue;
        }
        if (!smooth_known) smooth = smooth && load_smooth(sims[l], t, g.substeps_dt_s);
        if (g.lanes > 1u) {
            lanes_load(L, l, &sims[l]->plant);
            substep(sims[l], t, 0u, &h, &L->T0_Nm[l], &L->dT_Nmps[l]);
        }
    }
    if (!smooth) {
        /* a load breakpoint inside the period: each drive on its own, its steps split there */
        for (uint32_t l = 0; l < g.n; ++l) {
            if (active[l]) plant_advance_split(sims[l], t);
        }
    } else if (g.lanes == 1u) {
        for (uint32_t s = 0; s < substeps; ++s) {
            if (load_v1) {
                double t_s;
                h = substep_length(sims[0], t, s, &t_s);
                step_one(&sims[0]->plant, g.kind, h, sims[0]->load.v1, 0.0);
            } else {
                double T0, dT;
                substep(sims[0], t, s, &h, &T0, &dT);
                step_one(&sims[0]->plant, g.kind, h, T0, dT);
            }
        }
    } else {
        for (uint32_t s = 0; s < g.substeps; ++s) {
            for (uint32_t l = 0; l < g.n && s > 0u; ++l) {
                if (active[l]) substep(sims[l], t, s, &h, &L->T0_Nm[l], &L->dT_Nmps[l]);
            }
            if (g.fma) {
                lanes_step_fma(L, g.kind, h);
            } else {
                lanes_step(L, g.kind, h);
            }
        }
    }
    for (uint32_t l = 0; l < g.n; ++l) {
        if (!active[l]) continue;
        if (g.lanes > 1u && smooth) lanes_store(L, l, &sims[l]->plant);
        if (period_end(sims[l], plain) != P2D_SIM_OK) group_leave(g.lanes, L, active, n_active, l);
    }
}

/* The periods [n_current, n_current + count) of the group (none after the last drive stopped), as group_period. */
static P2D_SIM_INLINE void group_periods(p2d_sim_t *const *sims, const p2d_sim_group_t g, p2d_sim_lanes_t *L,
                                         bool *active, uint32_t *n_active, uint64_t n_current, uint64_t count,
                                         double Ts_current_s, bool smooth_known, bool load_v1, bool plain)
{
    for (uint64_t j = 0; *n_active > 0u && j < count; ++j) {
        group_period(sims, g, L, active, n_active, count_as_double(n_current + j) * Ts_current_s, false, smooth_known,
                     load_v1, plain);
    }
}

/*
 * The periods [n_current, n_current + count) of a plain lone drive (drive_plain) whose load is
 * constant over them (its value v1, no slope), as group_period; false after a stop.
 */
static P2D_SIM_INLINE bool lone_periods(p2d_sim_t *sim, uint64_t n_current, uint64_t count, double Ts_current_s,
                                        uint32_t kind, bool first_order)
{
    const double T_load_Nm = sim->load.v1;
    const p2d_current_coef_t *cc = &sim->current.coef[sim->current.active];
    for (uint64_t j = 0; j < count; ++j) {
        const double t = count_as_double(n_current + j) * Ts_current_s;
        double t_step, h;
        /* the plant steps after a stop in period_start too, as in group_period; period_end with the count kept here */
        const bool started = period_start(sim, cc, t, first_order, true, false, 0, 0u) == P2D_SIM_OK;
        h = substep_length(sim, t, 0u, &t_step);
        step_one(&sim->plant, kind, h, T_load_Nm, 0.0);
        if (!started || check_state(sim, n_current + j + 1u, true) != P2D_SIM_OK) {
            sim->n_current = n_current + j + (started ? 1u : 0u);
            return false;
        }
    }
    sim->n_current = n_current + count;
    return true;
}

/* lone_periods in the copy of the step's kind: a constant kind keeps the state in registers across the period. */
static P2D_SIM_INLINE bool lone_periods_kind(p2d_sim_t *sim, uint64_t n_current, uint64_t count, double Ts_current_s,
                                             uint32_t kind)
{
    switch (kind) {
    case P2D_KIND_LEAN: return lone_periods(sim, n_current, count, Ts_current_s, P2D_KIND_LEAN, false);
    case P2D_KIND_LEAN | P2D_KIND_FIRST_ORDER:
        return lone_periods(sim, n_current, count, Ts_current_s, P2D_KIND_LEAN | P2D_KIND_FIRST_ORDER, true);
    case 0: return lone_periods(sim, n_current, count, Ts_current_s, 0u, false);
    case P2D_KIND_FIRST_ORDER: return lone_periods(sim, n_current, count, Ts_current_s, P2D_KIND_FIRST_ORDER, true);
    default: return lone_periods(sim, n_current, count, Ts_current_s, kind, (kind & P2D_KIND_FIRST_ORDER) != 0u);
    }
}

/*
 * The periods after the first of the speed sample starting at period n_current (of cps periods)
 * in one stretch: their loads known smooth if no active drive's load breaks before the end of the
 * last period (the per-period test load_smooth, monotone in t, with the cursor that the first
 * period left and none of these periods moves), and the lone drive's load moreover constant if its
 * segment is from the second period on (segment_constant); the lone plain drive's in lone_periods.
 */
static P2D_SIM_INLINE void group_rest(p2d_sim_t *const *sims, const p2d_sim_group_t g, p2d_sim_lanes_t *L, bool *active,
                                      uint32_t *n_active, uint64_t n_current, uint64_t cps, double Ts_current_s,
                                      bool plain)
{
    const double t_last = count_as_double(n_current + cps - 1u) * Ts_current_s;
    bool smooth = true, load_v1;
    for (uint32_t l = 0; l < g.n; ++l) {
        if (active[l]) smooth = smooth && load_smooth(sims[l], t_last, g.substeps_dt_s);
    }
    load_v1 =
        smooth && g.lanes == 1u && segment_constant(&sims[0]->load, count_as_double(n_current + 1u) * Ts_current_s);
    if (load_v1 && plain) {
        if (!lone_periods_kind(sims[0], n_current + 1u, cps - 1u, Ts_current_s, g.kind)) {
            group_leave(g.lanes, L, active, n_active, 0u);
        }
    } else if (load_v1) {
        group_periods(sims, g, L, active, n_active, n_current + 1u, cps - 1u, Ts_current_s, true, true, false);
    } else if (smooth && g.lanes > 1u) {
        group_periods(sims, g, L, active, n_active, n_current + 1u, cps - 1u, Ts_current_s, true, false, false);
    } else {
        group_periods(sims, g, L, active, n_active, n_current + 1u, cps - 1u, Ts_current_s, false, false, false);
    }
}

/*
 * n (1 <= n <= lanes) drives of one shape in lockstep over n_samples speed samples; lanes = 1:
 * the plant stepped in place; lanes = P2D_SIM_LANES: the plants through the arrays of L (lanes
 * of no drive idle). A drive that stops leaves the group. At the speed rate a sample is its first
 * period, with the log row, and the rest in one stretch (group_rest).
 */
static P2D_SIM_INLINE void run_group(p2d_sim_t *const *sims, uint32_t n, uint32_t lanes, p2d_sim_lanes_t *L,
                                     uint64_t n_samples, double *const *logs, const uint64_t *log_rows, bool fma,
                                     bool per_current)
{
    const p2d_sim_config_t *cfg = &sims[0]->cfg;
    const uint64_t cps = cfg->current_per_speed;
    /* every drive of a group has the same step dt = Ts_current / substeps */
    const p2d_sim_group_t g = {n,
                               lanes,
                               step_kind(sims[0]),
                               cfg->substeps,
                               (double)cfg->substeps * sims[0]->plant.dt_s,
                               cfg->current_model == P2D_CURRENT_FIRST_ORDER,
                               fma,
                               logs,
                               log_rows};
    /* every drive is at the same sample: the time and the log decision are the group's */
    uint64_t n_current = sims[0]->n_current, n_speed = sims[0]->n_speed;
    const bool plain = lanes == 1u && drive_plain(sims[0]);
    uint64_t row0[P2D_SIM_LANES];
    bool active[P2D_SIM_LANES];
    uint32_t n_active = 0u;
    for (uint32_t l = 0; l < lanes; ++l) {
        active[l] = l < n && sims[l]->status == P2D_SIM_OK;
        n_active += active[l];
        if (lanes > 1u) {
            lanes_set_coef(L, l, &sims[l < n ? l : 0u]->plant.coef);
            lanes_idle(L, l);
        }
    }
    for (uint64_t k = 0; k < n_samples && n_active > 0u; ++k, ++n_speed, n_current += cps) {
        const double t_k = count_as_double(n_current) * cfg->Ts_current_s;
        /* at the speed rate: the row of the sample's first period */
        const bool log_row = !per_current && n_speed % cfg->log_every == 0u;
        for (uint32_t l = 0; l < n; ++l) {
            row0[l] = sims[l]->n_rows;
            if (active[l] && speed_sample(sims[l], t_k) != P2D_SIM_OK) group_leave(g.lanes, L, active, &n_active, l);
        }
        if (per_current) {
            /* the sample's first row's period j_row (beyond the sample: none), then every log_every-th */
            uint64_t j_row = (cfg->log_every - n_current % cfg->log_every) % cfg->log_every;
            for (uint64_t j = 0; j < cps && n_active > 0u; ++j) {
                group_period(sims, g, L, active, &n_active, count_as_double(n_current + j) * cfg->Ts_current_s,
                             j == j_row, false, false, false);
                if (j == j_row) j_row += cfg->log_every;
            }
        } else if (n_active > 0u) {
            group_period(sims, g, L, active, &n_active, t_k, log_row, false, false, false);
            if (n_active > 0u && cps > 1u)
                group_rest(sims, g, L, active, &n_active, n_current, cps, cfg->Ts_current_s, plain);
        }
        for (uint32_t l = 0; l < n; ++l) {
            if (active[l]) sample_end(sims[l], per_current, log_row, row0[l], logs[l], log_rows[l]);
        }
    }
}

/* run_group of one drive, and of the groups of P2D_SIM_LANES drives of p2d_sim_run_many. */
static P2D_SIM_NOINLINE void run_lone(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows)
{
    run_group(&sim, 1u, 1u, 0, n_samples, &log, &log_rows, false, false);
}

/* run_lone with a row per log_every-th current period (and its FMA copy below): every drive at the current rate runs
   alone in it (a lockstep group's copies compute the lone run's bits, so that its logs are those of the groups'). */
static P2D_SIM_NOINLINE void run_lone_current(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows)
{
    run_group(&sim, 1u, 1u, 0, n_samples, &log, &log_rows, false, true);
}

static P2D_SIM_NOINLINE void run_lanes(p2d_sim_t *const *sims, uint32_t n, p2d_sim_lanes_t *L, uint64_t n_samples,
                                       double *const *logs, const uint64_t *log_rows)
{
    run_group(sims, n, P2D_SIM_LANES, L, n_samples, logs, log_rows, false, false);
}

#ifdef P2D_SIM_FMA_TARGET
static P2D_SIM_FMA_TARGET P2D_SIM_NOINLINE void run_lone_fma(p2d_sim_t *sim, uint64_t n_samples, double *log,
                                                             uint64_t log_rows)
{
    run_group(&sim, 1u, 1u, 0, n_samples, &log, &log_rows, true, false);
}

static P2D_SIM_FMA_TARGET P2D_SIM_NOINLINE void run_lanes_fma(p2d_sim_t *const *sims, uint32_t n, p2d_sim_lanes_t *L,
                                                              uint64_t n_samples, double *const *logs,
                                                              const uint64_t *log_rows)
{
    run_group(sims, n, P2D_SIM_LANES, L, n_samples, logs, log_rows, true, false);
}

static P2D_SIM_FMA_TARGET P2D_SIM_NOINLINE void run_lone_current_fma(p2d_sim_t *sim, uint64_t n_samples, double *log,
                                                                     uint64_t log_rows)
{
    run_group(&sim, 1u, 1u, 0, n_samples, &log, &log_rows, true, true);
}

#else
#define run_lone_fma run_lone
#define run_lanes_fma run_lanes
#define run_lone_current_fma run_lone_current
#endif

p2d_sim_status_t p2d_sim_run(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows)
{
    if (sim == 0) return P2D_SIM_ERR_NULL;
    if (sim->status != P2D_SIM_OK) return sim->status;
    if (!log_room(sim, n_samples, log, log_rows)) return P2D_SIM_ERR_LOG_FULL;
    if (sim->cfg.log_rate == P2D_LOG_RATE_CURRENT && sim->fma) {
        run_lone_current_fma(sim, n_samples, log, log_rows);
    } else if (sim->cfg.log_rate == P2D_LOG_RATE_CURRENT) {
        run_lone_current(sim, n_samples, log, log_rows);
    } else if (sim->fma) {
        run_lone_fma(sim, n_samples, log, log_rows);
    } else {
        run_lone(sim, n_samples, log, log_rows);
    }
    return sim->status;
}

bool p2d_sim_lockstep(const p2d_sim_t *a, const p2d_sim_t *b)
{
    const p2d_sim_config_t *x = &a->cfg, *y = &b->cfg;
    return a->n_speed == b->n_speed && a->n_current == b->n_current && x->Ts_current_s == y->Ts_current_s &&
           x->current_per_speed == y->current_per_speed && x->substeps == y->substeps && x->log_every == y->log_every &&
           x->log_rate == y->log_rate && x->current_model == y->current_model && step_kind(a) == step_kind(b);
}

p2d_sim_status_t p2d_sim_run_many(p2d_sim_t *const *sims, uint32_t n_sims, uint64_t n_samples, double *const *logs,
                                  const uint64_t *log_rows)
{
    p2d_sim_lanes_t L;
    bool fma = true;
    if (n_sims == 0u) return P2D_SIM_OK;
    if (sims == 0 || logs == 0 || log_rows == 0) return P2D_SIM_ERR_NULL;
    for (uint32_t i = 0; i < n_sims; ++i) {
        if (sims[i] == 0) return P2D_SIM_ERR_NULL;
        fma = fma && sims[i]->fma;
        if (!p2d_sim_lockstep(sims[0], sims[i])) return P2D_SIM_ERR_LOCKSTEP;
        if (!log_room(sims[i], n_samples, logs[i], log_rows[i])) return P2D_SIM_ERR_LOG_FULL;
    }
    if (sims[0]->cfg.log_rate == P2D_LOG_RATE_CURRENT) {
        for (uint32_t i = 0; i < n_sims; ++i) {
            if (fma) {
                run_lone_current_fma(sims[i], n_samples, logs[i], log_rows[i]);
            } else {
                run_lone_current(sims[i], n_samples, logs[i], log_rows[i]);
            }
        }
        return P2D_SIM_OK;
    }
    memset(&L, 0, sizeof L);
    for (uint32_t i = 0; i < n_sims; i += P2D_SIM_LANES) {
        uint32_t n = n_sims - i < P2D_SIM_LANES ? n_sims - i : P2D_SIM_LANES;
        if (fma) {
            run_lanes_fma(sims + i, n, &L, n_samples, logs + i, log_rows + i);
        } else {
            run_lanes(sims + i, n, &L, n_samples, logs + i, log_rows + i);
        }
    }
    return P2D_SIM_OK;
}
