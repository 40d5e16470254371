/*
 * Drive simulation engine: see drive.h for the model, the sampled-data loop,
 * the initial state, the log and the stops.
 */
#include "drive.h"
#include "mechanics.h"

#include <math.h>

#define P2D_SIM_INV_SQRT3 0.57735026918962576 /* 1/sqrt(3) */
#define P2D_SIM_W_C_MIN_RADPS 0.01            /* narrowest Coulomb smoothing band [rad/s] */
#define P2D_SIM_W_C_PERIODS 10.0              /* friction time constant J w_c / T_c in current periods [-] */
#define P2D_SIM_OVERSPEED_FACTOR 2.0          /* overspeed bound in no-load speeds [-] */
#define P2D_SIM_OVERCURRENT_FACTOR 10.0       /* overcurrent bound in max(i_max, short-circuit current) [-] */
#define P2D_SIM_TS_MATCH_TOL 1e-6             /* relative mismatch allowed between float and double periods [-] */
#define P2D_SIM_T_TOL 1e-6                    /* times closer than this many RK4 steps are equal [-] */

/* Inlines a function where the compiler supports it (the plant's RK4 step into its specialised loops). */
#if defined(__GNUC__)
#define P2D_SIM_INLINE __attribute__((always_inline)) inline
#else
#define P2D_SIM_INLINE inline
#endif

/* Keeps a function out of line where the compiler supports it. */
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

static p2d_sim_status_t config_status(const p2d_sim_config_t *cfg)
{
    const p2d_pmsm_params_t *m = &cfg->motor;
    double Ts_speed_s;
    if (m->pole_pairs < 1u) return P2D_SIM_ERR_POLE_PAIRS;
    if (!is_positive(m->Rs_ohm)) return P2D_SIM_ERR_RS;
    if (!is_positive(m->Ld_H)) return P2D_SIM_ERR_LD;
    if (!is_positive(m->Lq_H)) return P2D_SIM_ERR_LQ;
    if (!is_positive(m->psi_f_Wb)) return P2D_SIM_ERR_PSI_F;
    if (!is_positive(m->J_kgm2)) return P2D_SIM_ERR_J;
    if (!is_nonnegative(m->B_Nms)) return P2D_SIM_ERR_B;
    if (!is_nonnegative(m->T_coulomb_Nm)) return P2D_SIM_ERR_T_COULOMB;
    if (!is_positive(cfg->u_dc_V)) return P2D_SIM_ERR_U_DC;
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
    if (cfg->substeps < 1u) return P2D_SIM_ERR_SUBSTEPS;
    if (cfg->log_every < 1u) return P2D_SIM_ERR_LOG_EVERY;
    if (!isfinite(cfg->w_m0_radps)) return P2D_SIM_ERR_W_M0;
    if (!schedule_valid(&cfg->reference)) return P2D_SIM_ERR_REFERENCE;
    if (!schedule_valid(&cfg->load)) return P2D_SIM_ERR_LOAD;
    if (!faults_valid(cfg)) return P2D_SIM_ERR_FAULTS;
    return p2d_mechanics_check(&cfg->mechanics);
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

/* Enter every entry with t_s[i] <= t; a new segment starts from the value reached. */
static void cursor_advance(p2d_schedule_cursor_t *c, const p2d_schedule_t *s, double t_s)
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

/* The load-side speed: w_L (two_mass), else w_m. */
static double load_speed_radps(const p2d_sim_t *sim)
{
    return sim->cfg.mechanics.model == P2D_MECHANICS_TWO_MASS ? sim->mechanics.w_load_radps : sim->pmsm.w_m_radps;
}

/* The speed the speed sensor measures: w_L with feedback from the load, else w_m. */
static double sensed_speed_radps(const p2d_sim_t *sim)
{
    return sim->cfg.mechanics.feedback == P2D_FEEDBACK_LOAD ? load_speed_radps(sim) : sim->pmsm.w_m_radps;
}

/*
 * The angle the speed sensor measures: theta_L = theta_M - theta (0 at t = 0, as the twist) with
 * feedback from the load of a two-mass train, else theta_m.
 */
static double sensed_angle_rad(const p2d_sim_t *sim)
{
    if (sim->cfg.mechanics.model == P2D_MECHANICS_TWO_MASS && sim->cfg.mechanics.feedback == P2D_FEEDBACK_LOAD) {
        return sim->pmsm.theta_m_rad - sim->mechanics.theta_rad;
    }
    return sim->pmsm.theta_m_rad;
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

/* ---- plant -------------------------------------------------------------- */

/* T_f = B w_m + T_c tanh(w_m / w_c); coulomb: T_c > 0 */
static P2D_SIM_INLINE double friction_Nm(const p2d_pmsm_t *m, bool coulomb, double w_m_radps)
{
    double T = m->B_Nms * w_m_radps;
    if (coulomb) T += m->T_coulomb_Nm * tanh(w_m_radps * m->inv_w_c_s_per_rad);
    return T;
}

/* Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
static double torque_Nm(const p2d_pmsm_t *m, double id_A, double iq_A)
{
    return iq_A * (m->kt_Nm_per_A + m->c_T_Nm_per_A2 * id_A);
}

/*
 * A plant state x = (id, iq, w_m, theta, w_L), or its time derivative (each field then per
 * second); theta and w_L are used by the two-mass train only (two_mass, a constant at each call).
 */
typedef struct {
    double id_A;         /* d-axis current [A] */
    double iq_A;         /* q-axis current [A] */
    double w_m_radps;    /* mechanical speed of the motor [rad/s] */
    double theta_rad;    /* two_mass: shaft twist theta_M - theta_L [rad] */
    double w_load_radps; /* two_mass: load-side speed [rad/s] */
} p2d_plant_x_t;

/*
 * Time derivative of x under the current-loop model `model`. Inputs a, b: (ud, uq) [V] for
 * DQ_PI, (id_ref, iq_ref) [A] for FIRST_ORDER.
 */
static P2D_SIM_INLINE p2d_plant_x_t plant_rate(const p2d_sim_t *sim, p2d_current_model_t model, bool coulomb,
                                               bool two_mass, p2d_plant_x_t x, double a, double b, double T_load_Nm)
{
    const p2d_pmsm_t *m = &sim->pmsm;
    p2d_plant_x_t dx;
    if (model == P2D_CURRENT_DQ_PI) {
        double w_e = m->pole_pairs * x.w_m_radps;
        /* Ld did/dt = ud - Rs id + w_e Lq iq */
        dx.id_A = (a - m->Rs_ohm * x.id_A + w_e * m->Lq_H * x.iq_A) * m->inv_Ld_per_H;
        /* Lq diq/dt = uq - Rs iq - w_e (Ld id + psi_f) */
        dx.iq_A = (b - m->Rs_ohm * x.iq_A - w_e * (m->Ld_H * x.id_A + m->psi_f_Wb)) * m->inv_Lq_per_H;
    } else {
        /* eq 3: tau_i di/dt = i_ref - i */
        dx.id_A = (a - x.id_A) * sim->inv_tau_i_per_s;
        dx.iq_A = (b - x.iq_A) * sim->inv_tau_i_per_s;
    }
    if (two_mass) {
        double T_s = p2d_shaft_torque_Nm(&sim->mechanics, x.theta_rad, x.w_m_radps - x.w_load_radps);
        /* J_M dw_m/dt = Te - T_s - B w_m - T_c tanh(w_m / w_c) */
        dx.w_m_radps = (torque_Nm(m, x.id_A, x.iq_A) - T_s - friction_Nm(m, coulomb, x.w_m_radps)) * m->inv_J_per_kgm2;
        /* dtheta/dt = w_m - w_L */
        dx.theta_rad = x.w_m_radps - x.w_load_radps;
        /* J_L dw_L/dt = T_s - T_load */
        dx.w_load_radps = (T_s - T_load_Nm) * sim->mechanics.inv_J_load_per_kgm2;
    } else {
        /* J dw_m/dt = Te - T_load - B w_m - T_c tanh(w_m / w_c) */
        dx.w_m_radps =
            (torque_Nm(m, x.id_A, x.iq_A) - T_load_Nm - friction_Nm(m, coulomb, x.w_m_radps)) * m->inv_J_per_kgm2;
        dx.theta_rad = 0.0;
        dx.w_load_radps = 0.0;
    }
    return dx;
}

/* x + c dx (theta and w_L with two_mass, else left as x's) */
static P2D_SIM_INLINE p2d_plant_x_t plant_x_step(bool two_mass, p2d_plant_x_t x, double c, p2d_plant_x_t dx)
{
    p2d_plant_x_t y = x;
    y.id_A = x.id_A + c * dx.id_A;
    y.iq_A = x.iq_A + c * dx.iq_A;
    y.w_m_radps = x.w_m_radps + c * dx.w_m_radps;
    if (two_mass) {
        y.theta_rad = x.theta_rad + c * dx.theta_rad;
        y.w_load_radps = x.w_load_radps + c * dx.w_load_radps;
    }
    return y;
}

/* One classical RK4 step of length h; the load is T0 + dT_dt (t - t_start) over the step. */
static P2D_SIM_INLINE void rk4_step(p2d_sim_t *sim, p2d_current_model_t model, bool coulomb, bool two_mass, bool angle,
                                    double h, double a, double b, double T0_Nm, double dT_dt_Nmps)
{
    p2d_pmsm_t *m = &sim->pmsm;
    p2d_mechanics_t *mech = &sim->mechanics;
    p2d_plant_x_t x = {m->id_A, m->iq_A, m->w_m_radps, 0.0, 0.0};
    double h_half = 0.5 * h;
    p2d_plant_x_t k1, k2, k3, k4;
    if (two_mass) {
        x.theta_rad = mech->theta_rad;
        x.w_load_radps = mech->w_load_radps;
    }
    k1 = plant_rate(sim, model, coulomb, two_mass, x, a, b, T0_Nm);
    k2 = plant_rate(sim, model, coulomb, two_mass, plant_x_step(two_mass, x, h_half, k1), a, b,
                    T0_Nm + h_half * dT_dt_Nmps);
    k3 = plant_rate(sim, model, coulomb, two_mass, plant_x_step(two_mass, x, h_half, k2), a, b,
                    T0_Nm + h_half * dT_dt_Nmps);
    k4 = plant_rate(sim, model, coulomb, two_mass, plant_x_step(two_mass, x, h, k3), a, b, T0_Nm + h * dT_dt_Nmps);
    /* x(t + h) = x(t) + h (k1 + 2 k2 + 2 k3 + k4) / 6 */
    m->id_A = x.id_A + h / 6.0 * (k1.id_A + 2.0 * k2.id_A + 2.0 * k3.id_A + k4.id_A);
    m->iq_A = x.iq_A + h / 6.0 * (k1.iq_A + 2.0 * k2.iq_A + 2.0 * k3.iq_A + k4.iq_A);
    m->w_m_radps = x.w_m_radps + h / 6.0 * (k1.w_m_radps + 2.0 * k2.w_m_radps + 2.0 * k3.w_m_radps + k4.w_m_radps);
    if (two_mass) {
        mech->theta_rad =
            x.theta_rad + h / 6.0 * (k1.theta_rad + 2.0 * k2.theta_rad + 2.0 * k3.theta_rad + k4.theta_rad);
        mech->w_load_radps =
            x.w_load_radps +
            h / 6.0 * (k1.w_load_radps + 2.0 * k2.w_load_radps + 2.0 * k3.w_load_radps + k4.w_load_radps);
    }
    /* RK4 of dtheta/dt = w_m over the stages above: theta + h w_m + h^2 (k1 + k2 + k3) / 6 (speed rates) */
    if (angle) m->theta_m_rad += h * x.w_m_radps + h * h / 6.0 * (k1.w_m_radps + k2.w_m_radps + k3.w_m_radps);
}

/*
 * Integrate the plant over the current period starting at t_start with the inputs held, under
 * the current-loop model `model`, with Coulomb friction if `coulomb`, the two-mass train if
 * `two_mass` and the rotor angle if `angle` (constants at each call).
 */
static P2D_SIM_INLINE void plant_advance_model(p2d_sim_t *sim, p2d_current_model_t model, bool coulomb, bool two_mass,
                                               bool angle, double t_start_s, double a, double b)
{
    for (uint32_t s = 0; s < sim->cfg.substeps; ++s) {
        double t = t_start_s + (double)s * sim->dt_s;
        double t_end = t_start_s + (double)(s + 1u) * sim->dt_s;
        while (t < t_end - sim->t_tol_s) {
            double t_break, t_stop, h;
            t_break = cursor_break_after(&sim->load, &sim->cfg.load, t + sim->t_tol_s);
            /* split the step at a load breakpoint inside it */
            t_stop = t_break < t_end - sim->t_tol_s ? t_break : t_end;
            h = t_stop - t;
            rk4_step(sim, model, coulomb, two_mass, angle, h, a, b, segment_value(&sim->load, t),
                     segment_slope(&sim->load, t + 0.5 * h));
            t = t_stop;
        }
    }
}

/*
 * Integrate the plant over the current period starting at t_start with the inputs held. One
 * specialised copy of the loop per current-loop model, with and without Coulomb friction (whose
 * tanh call would otherwise make every RK4 stage save its registers); out of line, so that the
 * loop of p2d_sim_run keeps its registers too. The two-mass train has one copy per current-loop
 * model, with the friction and the angle decided at run time; a rigid one with the rotor angle
 * one generic copy.
 */
static P2D_SIM_NOINLINE void plant_advance(p2d_sim_t *sim, double t_start_s, double a, double b)
{
    bool coulomb = sim->pmsm.T_coulomb_Nm > 0.0;
    if (sim->cfg.mechanics.model == P2D_MECHANICS_TWO_MASS) {
        if (sim->cfg.current_model == P2D_CURRENT_DQ_PI) {
            plant_advance_model(sim, P2D_CURRENT_DQ_PI, coulomb, true, sim->sensing.angle, t_start_s, a, b);
        } else {
            plant_advance_model(sim, P2D_CURRENT_FIRST_ORDER, coulomb, true, sim->sensing.angle, t_start_s, a, b);
        }
    } else if (sim->sensing.angle) {
        /* with the rotor angle (sensing.h): one generic copy */
        plant_advance_model(sim, sim->cfg.current_model, coulomb, false, true, t_start_s, a, b);
    } else if (sim->cfg.current_model == P2D_CURRENT_DQ_PI) {
        if (coulomb) {
            plant_advance_model(sim, P2D_CURRENT_DQ_PI, true, false, false, t_start_s, a, b);
        } else {
            plant_advance_model(sim, P2D_CURRENT_DQ_PI, false, false, false, t_start_s, a, b);
        }
    } else {
        if (coulomb) {
            plant_advance_model(sim, P2D_CURRENT_FIRST_ORDER, true, false, false, t_start_s, a, b);
        } else {
            plant_advance_model(sim, P2D_CURRENT_FIRST_ORDER, false, false, false, t_start_s, a, b);
        }
    }
}

/* ---- inverter ----------------------------------------------------------- */

/*
 * The range u_max = u_dc / sqrt(3), and u_inside2 = (1 - 2^-40) u_max^2: a sum of squares
 * ud^2 + uq^2 below u_inside2 is inside the range whatever the rounding of the sum (< 2^-51
 * relative; squares that underflow, < 2^-1074 absolute) and of hypot (< 1 ulp), so that
 * inside_range decides without hypot, as hypot would. u_inside2 is 0 (hypot always) for a range
 * outside [2^-450, 2^450] V, whose square could underflow or overflow.
 */
static void inverter_set_range(p2d_inverter_t *inv, double u_dc_V)
{
    double u_max_V = u_dc_V * P2D_SIM_INV_SQRT3;
    bool square_normal = u_max_V >= 0x1p-450 && u_max_V <= 0x1p450;
    inv->u_max_V = u_max_V;
    inv->u_inside2_V2 = square_normal ? u_max_V * u_max_V * (1.0 - 0x1p-40) : 0.0;
}

/* ud^2 + uq^2 < u_inside2: the vector is inside the range, and hypot(ud, uq) <= u_max. */
static bool inside_range(const p2d_inverter_t *inv, double ud_V, double uq_V)
{
    return ud_V * ud_V + uq_V * uq_V < inv->u_inside2_V2;
}

/*
 * Scale (*ud, *uq) to ||u|| <= u_max; return true when it was cut. hypot neither underflows nor
 * overflows, so a zero range (a DC link at 0 V) applies exactly zero to any nonzero command, a
 * subnormal one included.
 */
static bool limit_voltage(const p2d_inverter_t *inv, double *ud_V, double *uq_V)
{
    double norm;
    if (inside_range(inv, *ud_V, *uq_V)) return false;
    norm = hypot(*ud_V, *uq_V);
    if (!(norm > inv->u_max_V)) return false;
    *ud_V *= inv->u_max_V / norm;
    *uq_V *= inv->u_max_V / norm;
    return true;
}

/*
 * Limit the command to ||u|| <= u_dc / sqrt(3) into (*ud, *uq) and apply it now or one period
 * later; a delayed command is limited again by the range of the period it is applied in (which
 * differs only when the DC link sags in between). cmd_limited says that the controller already
 * cut the command to its range. Returns true when the voltage applied over the present period was
 * cut, by the controller or by the inverter, in this period or in the one it was computed in.
 */
static bool inverter_apply(p2d_inverter_t *inv, double ud_cmd_V, double uq_cmd_V, bool cmd_limited, double *ud_V,
                           double *uq_V)
{
    bool limited;
    *ud_V = ud_cmd_V;
    *uq_V = uq_cmd_V;
    cmd_limited |= limit_voltage(inv, ud_V, uq_V);
    if (!inv->delay) {
        inv->ud_V = *ud_V;
        inv->uq_V = *uq_V;
        return cmd_limited;
    }
    inv->ud_V = inv->ud_next_V;
    inv->uq_V = inv->uq_next_V;
    limited = limit_voltage(inv, &inv->ud_V, &inv->uq_V) || inv->limited_next;
    inv->ud_next_V = *ud_V;
    inv->uq_next_V = *uq_V;
    inv->limited_next = cmd_limited;
    return limited;
}

/* ---- loop --------------------------------------------------------------- */

static p2d_sim_status_t stop(p2d_sim_t *sim, p2d_sim_status_t status, double t_s, double value, double bound)
{
    sim->status = status;
    sim->t_stop_s = t_s;
    sim->stop_value = value;
    sim->stop_bound = bound;
    return status;
}

static p2d_sim_status_t check_state(p2d_sim_t *sim, double t_s)
{
    const p2d_pmsm_t *m = &sim->pmsm;
    double i2;
    if (!isfinite(m->id_A) || !isfinite(m->iq_A) || !isfinite(m->w_m_radps)) {
        return stop(sim, P2D_SIM_STOP_NONFINITE, t_s, 0.0, 0.0);
    }
    if (fabs(m->w_m_radps) > sim->w_bound_radps) {
        return stop(sim, P2D_SIM_STOP_OVERSPEED, t_s, fabs(m->w_m_radps), sim->w_bound_radps);
    }
    if (sim->cfg.mechanics.model == P2D_MECHANICS_TWO_MASS) {
        const p2d_mechanics_t *mech = &sim->mechanics;
        if (!isfinite(mech->theta_rad) || !isfinite(mech->w_load_radps)) {
            return stop(sim, P2D_SIM_STOP_NONFINITE, t_s, 0.0, 0.0);
        }
        if (fabs(mech->w_load_radps) > sim->w_bound_radps) {
            return stop(sim, P2D_SIM_STOP_OVERSPEED, t_s, fabs(mech->w_load_radps), sim->w_bound_radps);
        }
    }
    i2 = m->id_A * m->id_A + m->iq_A * m->iq_A;
    if (i2 > sim->i_bound_A * sim->i_bound_A) {
        return stop(sim, P2D_SIM_STOP_OVERCURRENT, t_s, sqrt(i2), sim->i_bound_A);
    }
    return P2D_SIM_OK;
}

/* Steady-state voltage of eq 1 for the currents, speed and current slopes given. */
static void pmsm_voltage(const p2d_pmsm_t *m, double did_dt, double diq_dt, double *ud_V, double *uq_V)
{
    double w_e = m->pole_pairs * m->w_m_radps;
    /* ud = Rs id + Ld did/dt - w_e Lq iq */
    *ud_V = m->Rs_ohm * m->id_A + m->Ld_H * did_dt - w_e * m->Lq_H * m->iq_A;
    /* uq = Rs iq + Lq diq/dt + w_e (Ld id + psi_f) */
    *uq_V = m->Rs_ohm * m->iq_A + m->Lq_H * diq_dt + w_e * (m->Ld_H * m->id_A + m->psi_f_Wb);
}

void p2d_pmsm_setup(p2d_pmsm_t *m, const p2d_pmsm_params_t *mp, double Ts_current_s)
{
    m->pole_pairs = (double)mp->pole_pairs;
    m->Rs_ohm = mp->Rs_ohm;
    m->Ld_H = mp->Ld_H;
    m->Lq_H = mp->Lq_H;
    m->psi_f_Wb = mp->psi_f_Wb;
    m->inv_Ld_per_H = 1.0 / mp->Ld_H;
    m->inv_Lq_per_H = 1.0 / mp->Lq_H;
    m->inv_J_per_kgm2 = 1.0 / mp->J_kgm2;
    m->kt_Nm_per_A = 1.5 * m->pole_pairs * mp->psi_f_Wb;
    m->c_T_Nm_per_A2 = 1.5 * m->pole_pairs * (mp->Ld_H - mp->Lq_H);
    m->B_Nms = mp->B_Nms;
    m->T_coulomb_Nm = mp->T_coulomb_Nm;
    /* w_c = max(w_c_min, 10 Ts_current T_c / J): friction time constant J w_c / T_c >= 10 Ts_current */
    m->inv_w_c_s_per_rad =
        1.0 / fmax(P2D_SIM_W_C_MIN_RADPS, P2D_SIM_W_C_PERIODS * Ts_current_s * mp->T_coulomb_Nm / mp->J_kgm2);
    m->id_A = 0.0;
    m->iq_A = 0.0;
    m->w_m_radps = 0.0;
    m->theta_m_rad = 0.0;
}

p2d_sim_status_t p2d_sim_init(p2d_sim_t *sim, const p2d_sim_config_t *cfg)
{
    const p2d_pmsm_params_t *mp;
    p2d_pmsm_t *m;
    p2d_sim_status_t status;
    p2d_status_t ctl_status;
    p2d_speed_output_t so;
    p2d_sensing_check_t sensing;
    double T_hold_Nm, L_min_H;

    if (sim == 0 || cfg == 0) return P2D_SIM_ERR_NULL;
    status = config_status(cfg);
    if (status != P2D_SIM_OK) return status;
    sim->cfg = *cfg;
    sim->controller_status = P2D_OK;
    ctl_status = p2d_speed_init(&sim->speed, &cfg->speed);
    /* the torque filters, if any (p2d_speed_init leaves none) */
    if (ctl_status == P2D_OK &&
        (cfg->speed_filter.notch_freq_Hz != 0.0f || cfg->speed_filter.lowpass_freq_Hz != 0.0f)) {
        ctl_status = p2d_speed_set_filter(&sim->speed, &cfg->speed_filter);
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

    mp = &cfg->motor;
    m = &sim->pmsm;
    p2d_pmsm_setup(m, mp, cfg->Ts_current_s);

    inverter_set_range(&sim->inverter, cfg->u_dc_V);
    sim->inverter.delay = cfg->computation_delay;
    sim->inv_tau_i_per_s = cfg->current_model == P2D_CURRENT_FIRST_ORDER ? 1.0 / cfg->tau_i_s : 0.0;
    sim->dt_s = cfg->Ts_current_s / (double)cfg->substeps;
    sim->t_tol_s = P2D_SIM_T_TOL * sim->dt_s;
    /* twice the no-load speed: 2 u_dc / (sqrt(3) p psi_f) */
    sim->w_bound_radps = P2D_SIM_OVERSPEED_FACTOR * sim->inverter.u_max_V / (m->pole_pairs * mp->psi_f_Wb);
    /* ten times max(i_max, psi_f / min(Ld, Lq)) */
    L_min_H = fmin(mp->Ld_H, mp->Lq_H);
    sim->i_bound_A = P2D_SIM_OVERCURRENT_FACTOR * fmax((double)cfg->speed.i_max_A, mp->psi_f_Wb / L_min_H);
    if (fabs(cfg->w_m0_radps) > sim->w_bound_radps) return P2D_SIM_ERR_W_M0;

    p2d_mechanics_init(&sim->mechanics, &cfg->mechanics, cfg->w_m0_radps);
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
    sim->u_dc_V = cfg->u_dc_V;
    sim->saturated = false;

    /* steady state at w_m0 before t = 0: the torque that holds w_m0 against friction */
    m->w_m_radps = cfg->w_m0_radps;
    m->theta_m_rad = 0.0;
    p2d_sensing_init(&sim->sensing, &cfg->sensing.speed_sensor, &cfg->sensing.current_sensor,
                     &cfg->sensing.field_weakening, cfg->speed.Ts_s, cfg->w_m0_radps);
    T_hold_Nm = friction_Nm(m, m->T_coulomb_Nm > 0.0, cfg->w_m0_radps);
    p2d_speed_reset(&sim->speed, (float)cfg->w_m0_radps, (float)T_hold_Nm);
    p2d_speed_compute(&sim->speed, (float)cfg->w_m0_radps, (float)cfg->w_m0_radps, &so);
    if (so.fault) return P2D_SIM_ERR_W_M0;
    sim->id_ref_A = (double)so.id_ref_A;
    sim->iq_ref_A = (double)so.iq_ref_A;
    m->id_A = sim->id_ref_A;
    m->iq_A = sim->iq_ref_A;
    sim->inverter.ud_V = 0.0;
    sim->inverter.uq_V = 0.0;
    sim->inverter.ud_next_V = 0.0;
    sim->inverter.uq_next_V = 0.0;
    sim->inverter.limited_next = false;
    if (cfg->current_model == P2D_CURRENT_DQ_PI) {
        const p2d_current_coef_t *c = &sim->current.coef[sim->current.active];
        double w_e = m->pole_pairs * m->w_m_radps;
        double ud_V, uq_V;
        pmsm_voltage(m, 0.0, 0.0, &ud_V, &uq_V);
        /* integrators: zero error gives ud = x_d - w_e Lq iq, uq = x_q + w_e (Ld id + psi_f) (decoupling) */
        sim->current.x_d_V = (float)(ud_V + w_e * (double)c->Lq_H * m->iq_A);
        sim->current.x_q_V = (float)(uq_V - w_e * ((double)c->Ld_H * m->id_A + (double)c->psi_f_Wb));
        /* the command applied over the first period under the computation delay */
        sim->inverter.ud_next_V = ud_V;
        sim->inverter.uq_next_V = uq_V;
    }
    return P2D_SIM_OK;
}

/* The shaft torque T_s (two_mass), else the load torque T_load_Nm the rigid shaft carries. */
static double shaft_torque_Nm(const p2d_sim_t *sim, double T_load_Nm)
{
    const p2d_mechanics_t *mech = &sim->mechanics;
    if (sim->cfg.mechanics.model != P2D_MECHANICS_TWO_MASS) return T_load_Nm;
    return p2d_shaft_torque_Nm(mech, mech->theta_rad, sim->pmsm.w_m_radps - mech->w_load_radps);
}

/* Write row r (speed sample k at t_k) of the column-major log of log_rows rows. */
static void log_write(p2d_sim_t *sim, double *log, uint64_t log_rows, double t_k_s, double w_ref_radps,
                      const p2d_speed_output_t *so, double ud_V, double uq_V)
{
    const p2d_pmsm_t *m = &sim->pmsm;
    double *row = log + sim->n_rows;
    cursor_advance(&sim->load, &sim->cfg.load, t_k_s + sim->t_tol_s);
    row[P2D_LOG_T_S * log_rows] = t_k_s;
    row[P2D_LOG_W_REF_RADPS * log_rows] = w_ref_radps;
    row[P2D_LOG_W_M_RADPS * log_rows] = m->w_m_radps;
    row[P2D_LOG_ID_REF_A * log_rows] = (double)so->id_ref_A;
    row[P2D_LOG_IQ_REF_A * log_rows] = (double)so->iq_ref_A;
    row[P2D_LOG_ID_A * log_rows] = m->id_A;
    row[P2D_LOG_IQ_A * log_rows] = m->iq_A;
    row[P2D_LOG_UD_V * log_rows] = ud_V;
    row[P2D_LOG_UQ_V * log_rows] = uq_V;
    row[P2D_LOG_TORQUE_NM * log_rows] = torque_Nm(m, m->id_A, m->iq_A);
    row[P2D_LOG_TORQUE_REF_NM * log_rows] = (double)so->T_ref_Nm;
    row[P2D_LOG_TORQUE_UNSAT_NM * log_rows] = (double)so->T_unsat_Nm;
    row[P2D_LOG_LOAD_NM * log_rows] = segment_value(&sim->load, t_k_s);
    row[P2D_LOG_SATURATED * log_rows] = so->saturated ? 1.0 : 0.0;
    row[P2D_LOG_X_I_NM * log_rows] = (double)p2d_speed_integrator_Nm(&sim->speed);
    row[P2D_LOG_W_MEAS_RADPS * log_rows] = sim->w_meas_radps;
    row[P2D_LOG_U_DC_V * log_rows] = sim->u_dc_V;
    row[P2D_LOG_VOLTAGE_LIMITED * log_rows] = 0.0; /* counted over the speed period by the loop */
    row[P2D_LOG_J_EST_KGM2 * log_rows] = (double)sim->adapt.out.J_kgm2;
    row[P2D_LOG_J_VALID * log_rows] = sim->adapt.out.J_valid ? 1.0 : 0.0;
    row[P2D_LOG_T_LOAD_EST_NM * log_rows] = (double)sim->adapt.out.T_load_Nm;
    row[P2D_LOG_J_GAINS_KGM2 * log_rows] = sim->adapt.J_gains_kgm2;
    row[P2D_LOG_W_LOAD_RADPS * log_rows] = load_speed_radps(sim);
    row[P2D_LOG_SHAFT_TORQUE_NM * log_rows] = shaft_torque_Nm(sim, row[P2D_LOG_LOAD_NM * log_rows]);
    sim->n_rows++;
}

p2d_sim_status_t p2d_sim_run(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows)
{
    const p2d_sim_config_t *cfg;
    if (sim == 0) return P2D_SIM_ERR_NULL;
    if (sim->status != P2D_SIM_OK) return sim->status;
    cfg = &sim->cfg;
    for (uint64_t k = 0; k < n_samples; ++k) {
        double t_k = (double)sim->n_current * cfg->Ts_current_s;
        bool log_row = sim->n_speed % cfg->log_every == 0u;
        uint32_t n_limited = 0u; /* current periods of this speed sample at the voltage limit */
        double w_ref, w_sensor;
        p2d_speed_output_t so;
        if (log_row && (log == 0 || sim->n_rows >= log_rows)) return P2D_SIM_ERR_LOG_FULL;

        /* speed sample k: reference and speed reading sampled at t_k */
        cursor_advance(&sim->reference, &cfg->reference, t_k + sim->t_tol_s);
        w_ref = segment_value(&sim->reference, t_k);
        if (!p2d_sensing_speed(&sim->sensing, &cfg->sensing.speed_sensor, sim->n_current, cfg->Ts_current_s,
                               cfg->w_m0_radps, sensed_angle_rad(sim), sensed_speed_radps(sim), &w_sensor)) {
            return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k, 0.0, 0.0);
        }
        sim->w_meas_radps = speed_reading(sim, t_k, w_sensor);
        if (cfg->adapt.enabled) p2d_adapt_sample(&sim->adapt, sim->w_meas_radps, w_ref, sim->saturated, &sim->speed);
        if (cfg->sensing.field_weakening.enabled) {
            float id_fw_A;
            if (!p2d_sensing_field_weakening(&sim->sensing, sim->u_dc_V, &id_fw_A)) {
                return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k, 0.0, 0.0);
            }
            p2d_speed_step_fw(&sim->speed, (float)w_ref, (float)sim->w_meas_radps, id_fw_A, &so);
        } else {
            p2d_speed_step(&sim->speed, (float)w_ref, (float)sim->w_meas_radps, &so);
        }
        if (so.fault) return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k, 0.0, 0.0);
        sim->id_ref_A = (double)so.id_ref_A;
        sim->iq_ref_A = (double)so.iq_ref_A;
        sim->saturated = so.saturated;

        for (uint32_t j = 0; j < cfg->current_per_speed; ++j) {
            double t = (double)sim->n_current * cfg->Ts_current_s;
            double a, b, ud_log_V, uq_log_V;
            p2d_sim_status_t status;
            if (cfg->current_model == P2D_CURRENT_DQ_PI) {
                p2d_current_output_t co;
                double ud_cmd_V, uq_cmd_V, u_dc_V, id_meas_A = sim->pmsm.id_A, iq_meas_A = sim->pmsm.iq_A;
                /* the DC link of this period sets the inverter's range and the controller's measurement */
                u_dc_V = dc_link_V(sim, t);
                if (u_dc_V != sim->u_dc_V) {
                    sim->u_dc_V = u_dc_V;
                    inverter_set_range(&sim->inverter, u_dc_V);
                }
                if (sim->sensing.current_sensor) {
                    p2d_sensing_currents(&sim->sensing, &cfg->sensing.current_sensor, sim->pmsm.id_A, sim->pmsm.iq_A,
                                         sim->pmsm.pole_pairs * sim->pmsm.theta_m_rad, &id_meas_A, &iq_meas_A);
                }
                p2d_current_compute(&sim->current, (float)sim->id_ref_A, (float)sim->iq_ref_A, (float)id_meas_A,
                                    (float)iq_meas_A, (float)(sim->pmsm.pole_pairs * sim->pmsm.w_m_radps),
                                    (float)sim->u_dc_V, &co);
                if (co.fault) return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t, 0.0, 0.0);
                sim->sensing.ud_unsat_V = co.ud_unsat_V;
                sim->sensing.uq_unsat_V = co.uq_unsat_V;
                n_limited += inverter_apply(&sim->inverter, (double)co.ud_ref_V, (double)co.uq_ref_V, co.saturated,
                                            &ud_cmd_V, &uq_cmd_V);
                /* the integrators learn the command the inverter accepted */
                p2d_current_update(&sim->current, &co, (float)ud_cmd_V, (float)uq_cmd_V);
                a = sim->inverter.ud_V;
                b = sim->inverter.uq_V;
                ud_log_V = a;
                uq_log_V = b;
            } else {
                a = sim->id_ref_A;
                b = sim->iq_ref_A;
                /* the voltage eq 1 needs for the current slopes of eq 3 */
                pmsm_voltage(&sim->pmsm, (a - sim->pmsm.id_A) * sim->inv_tau_i_per_s,
                             (b - sim->pmsm.iq_A) * sim->inv_tau_i_per_s, &ud_log_V, &uq_log_V);
                n_limited += !inside_range(&sim->inverter, ud_log_V, uq_log_V) &&
                             hypot(ud_log_V, uq_log_V) > sim->inverter.u_max_V;
            }
            if (j == 0u && log_row) log_write(sim, log, log_rows, t_k, w_ref, &so, ud_log_V, uq_log_V);
            if (cfg->adapt.enabled)
                p2d_adapt_torque(&sim->adapt, torque_Nm(&sim->pmsm, sim->pmsm.id_A, sim->pmsm.iq_A));
            plant_advance(sim, t, a, b);
            sim->n_current++;
            p2d_sensing_record(&sim->sensing, sim->n_current, sensed_angle_rad(sim), sensed_speed_radps(sim));
            status = check_state(sim, (double)sim->n_current * cfg->Ts_current_s);
            if (status != P2D_SIM_OK) return status;
        }
        if (log_row) {
            log[P2D_LOG_VOLTAGE_LIMITED * log_rows + sim->n_rows - 1u] =
                (double)n_limited / (double)cfg->current_per_speed;
        }
        sim->n_speed++;
    }
    return P2D_SIM_OK;
}
