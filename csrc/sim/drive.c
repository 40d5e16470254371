/*
 * Drive simulation engine: see drive.h for the model, the sampled-data loop,
 * the initial state, the log and the stops.
 */
#include "drive.h"

#include <math.h>
#include <string.h>

#define P2D_SIM_OVERSPEED_FACTOR 2.0    /* overspeed bound in no-load speeds [-] */
#define P2D_SIM_OVERCURRENT_FACTOR 10.0 /* overcurrent bound in max(i_max, short-circuit current) [-] */
#define P2D_SIM_TS_MATCH_TOL 1e-6       /* relative mismatch allowed between float and double periods [-] */
#define P2D_SIM_T_TOL 1e-6              /* times closer than this many RK4 steps are equal [-] */

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
    if (!schedule_valid(&cfg->reference)) return P2D_SIM_ERR_REFERENCE;
    if (!schedule_valid(&cfg->load)) return P2D_SIM_ERR_LOAD;
    if (!faults_valid(cfg)) return P2D_SIM_ERR_FAULTS;
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

/* ---- loop --------------------------------------------------------------- */

/*
 * Integrate the plant over the current period starting at t_start with its input held: `substeps`
 * RK4 steps, each split at the load's breakpoints inside it, so that every step sees a load
 * linear in time.
 */
static void plant_advance(p2d_sim_t *sim, double t_start_s)
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

    sim->t_tol_s = P2D_SIM_T_TOL * m->dt_s;
    /* twice the no-load speed: 2 u_dc / (sqrt(3) p psi_f) */
    sim->w_bound_radps = P2D_SIM_OVERSPEED_FACTOR * m->u_max_V / (m->p * cfg->motor.psi_f_Wb);
    /* ten times max(i_max, psi_f / min(Ld, Lq)) */
    L_min_H = fmin(cfg->motor.Ld_H, cfg->motor.Lq_H);
    sim->i_bound_A = P2D_SIM_OVERCURRENT_FACTOR * fmax((double)cfg->speed.i_max_A, cfg->motor.psi_f_Wb / L_min_H);
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

    /* steady state at w_m0 before t = 0: the torque that holds w_m0 against friction */
    p2d_sensing_init(&sim->sensing, &cfg->sensing.speed_sensor, &cfg->sensing.current_sensor,
                     &cfg->sensing.field_weakening, cfg->speed.Ts_s, cfg->w_m0_radps);
    T_hold_Nm = p2d_plant_friction_Nm(m, cfg->w_m0_radps);
    p2d_speed_reset(&sim->speed, (float)cfg->w_m0_radps, (float)T_hold_Nm);
    p2d_speed_compute(&sim->speed, (float)cfg->w_m0_radps, (float)cfg->w_m0_radps, &so);
    if (so.fault) return P2D_SIM_ERR_W_M0;
    sim->id_ref_A = (double)so.id_ref_A;
    sim->iq_ref_A = (double)so.iq_ref_A;
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

/* Write row r (speed sample k at t_k) of the column-major log of log_rows rows. */
static void log_write(p2d_sim_t *sim, double *log, uint64_t log_rows, double t_k_s, double w_ref_radps,
                      const p2d_speed_output_t *so, double ud_V, double uq_V)
{
    const p2d_plant_t *m = &sim->plant;
    double *row = log + sim->n_rows;
    double theta_L_rad, w_L_radps;
    cursor_advance(&sim->load, &sim->cfg.load, t_k_s + sim->t_tol_s);
    p2d_plant_load_side(m, &theta_L_rad, &w_L_radps);
    row[P2D_LOG_T_S * log_rows] = t_k_s;
    row[P2D_LOG_W_REF_RADPS * log_rows] = w_ref_radps;
    row[P2D_LOG_W_M_RADPS * log_rows] = m->w_m_radps;
    row[P2D_LOG_ID_REF_A * log_rows] = (double)so->id_ref_A;
    row[P2D_LOG_IQ_REF_A * log_rows] = (double)so->iq_ref_A;
    row[P2D_LOG_ID_A * log_rows] = m->id_A;
    row[P2D_LOG_IQ_A * log_rows] = m->iq_A;
    row[P2D_LOG_UD_V * log_rows] = ud_V;
    row[P2D_LOG_UQ_V * log_rows] = uq_V;
    row[P2D_LOG_TORQUE_NM * log_rows] = p2d_plant_torque_Nm(m);
    row[P2D_LOG_TORQUE_REF_NM * log_rows] = (double)so->T_ref_Nm;
    row[P2D_LOG_TORQUE_UNSAT_NM * log_rows] = (double)so->T_unsat_Nm;
    row[P2D_LOG_LOAD_NM * log_rows] = segment_value(&sim->load, t_k_s);
    row[P2D_LOG_SATURATED * log_rows] = so->saturated ? 1.0 : 0.0;
    row[P2D_LOG_X_I_NM * log_rows] = (double)p2d_speed_integrator_Nm(&sim->speed);
    row[P2D_LOG_W_MEAS_RADPS * log_rows] = sim->w_meas_radps;
    row[P2D_LOG_U_DC_V * log_rows] = m->u_dc_V;
    row[P2D_LOG_VOLTAGE_LIMITED * log_rows] = 0.0; /* counted over the speed period by the loop */
    row[P2D_LOG_J_EST_KGM2 * log_rows] = (double)sim->adapt.out.J_kgm2;
    row[P2D_LOG_J_VALID * log_rows] = sim->adapt.out.J_valid ? 1.0 : 0.0;
    row[P2D_LOG_T_LOAD_EST_NM * log_rows] = (double)sim->adapt.out.T_load_Nm;
    row[P2D_LOG_J_GAINS_KGM2 * log_rows] = sim->adapt.J_gains_kgm2;
    row[P2D_LOG_W_LOAD_RADPS * log_rows] = w_L_radps;
    row[P2D_LOG_SHAFT_TORQUE_NM * log_rows] = p2d_plant_shaft_torque_Nm(m, row[P2D_LOG_LOAD_NM * log_rows]);
    sim->n_rows++;
}

p2d_sim_status_t p2d_sim_run(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows)
{
    const p2d_sim_config_t *cfg;
    p2d_plant_t *m;
    if (sim == 0) return P2D_SIM_ERR_NULL;
    if (sim->status != P2D_SIM_OK) return sim->status;
    cfg = &sim->cfg;
    m = &sim->plant;
    for (uint64_t k = 0; k < n_samples; ++k) {
        double t_k = (double)sim->n_current * cfg->Ts_current_s;
        bool log_row = sim->n_speed % cfg->log_every == 0u;
        uint32_t n_limited = 0u; /* current periods of this speed sample at the voltage limit */
        double w_ref, w_sensor, theta_s_rad, w_s_radps;
        p2d_speed_output_t so;
        if (log_row && (log == 0 || sim->n_rows >= log_rows)) return P2D_SIM_ERR_LOG_FULL;

        /* speed sample k: reference and speed reading sampled at t_k */
        cursor_advance(&sim->reference, &cfg->reference, t_k + sim->t_tol_s);
        w_ref = segment_value(&sim->reference, t_k);
        sensed_side(sim, &theta_s_rad, &w_s_radps);
        if (!p2d_sensing_speed(&sim->sensing, &cfg->sensing.speed_sensor, sim->n_current, cfg->Ts_current_s,
                               cfg->w_m0_radps, theta_s_rad, w_s_radps, &w_sensor)) {
            return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t_k, 0.0, 0.0);
        }
        sim->w_meas_radps = speed_reading(sim, t_k, w_sensor);
        if (cfg->adapt.enabled) p2d_adapt_sample(&sim->adapt, sim->w_meas_radps, w_ref, sim->saturated, &sim->speed);
        if (cfg->sensing.field_weakening.enabled) {
            float id_fw_A;
            if (!p2d_sensing_field_weakening(&sim->sensing, m->u_dc_V, &id_fw_A)) {
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
            double ud_log_V, uq_log_V;
            p2d_sim_status_t status;
            if (cfg->current_model == P2D_CURRENT_DQ_PI) {
                p2d_current_output_t co;
                p2d_inverter_output_t io;
                double u_dc_V, id_meas_A = m->id_A, iq_meas_A = m->iq_A;
                /* the DC link of this period sets the inverter's range and the controller's measurement */
                u_dc_V = dc_link_V(sim, t);
                if (u_dc_V != m->u_dc_V) p2d_plant_set_dc_link(m, u_dc_V);
                if (sim->sensing.current_sensor) p2d_sensing_currents(m, &id_meas_A, &iq_meas_A);
                p2d_current_compute(&sim->current, (float)sim->id_ref_A, (float)sim->iq_ref_A, (float)id_meas_A,
                                    (float)iq_meas_A, (float)(m->p * m->w_m_radps), (float)m->u_dc_V, &co);
                if (co.fault) return stop(sim, P2D_SIM_STOP_CONTROLLER_FAULT, t, 0.0, 0.0);
                sim->sensing.ud_unsat_V = co.ud_unsat_V;
                sim->sensing.uq_unsat_V = co.uq_unsat_V;
                p2d_plant_command(m, (double)co.ud_ref_V, (double)co.uq_ref_V, &io);
                /* the voltage of this period was cut: by the controller or the inverter, now or when it was given */
                if (cfg->computation_delay) {
                    n_limited += io.applied_limited || sim->current_saturated;
                    sim->current_saturated = co.saturated;
                } else {
                    n_limited += co.saturated || io.limited;
                }
                /* the integrators learn the command the inverter accepted */
                p2d_current_update(&sim->current, &co, (float)io.ud_V, (float)io.uq_V);
            } else {
                n_limited += p2d_plant_command_currents(m, sim->id_ref_A, sim->iq_ref_A);
            }
            p2d_plant_applied_voltage(m, &ud_log_V, &uq_log_V);
            if (j == 0u && log_row) log_write(sim, log, log_rows, t_k, w_ref, &so, ud_log_V, uq_log_V);
            if (cfg->adapt.enabled) p2d_adapt_torque(&sim->adapt, p2d_plant_torque_Nm(m));
            plant_advance(sim, t);
            sim->n_current++;
            sensed_side(sim, &theta_s_rad, &w_s_radps);
            p2d_sensing_record(&sim->sensing, sim->n_current, theta_s_rad, w_s_radps);
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
