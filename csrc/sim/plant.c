/*
 * The drive's plant, a virtual motor: see plant.h for the model and the interface.
 */
#include "plant.h"

#include <math.h>
#include <string.h>

#include "plant_inline.h"

#define P2D_PLANT_INV_SQRT3 0.57735026918962576    /* 1 / sqrt(3) */
#define P2D_PLANT_TWO_PI 6.283185307179586         /* 2 pi */
#define P2D_PLANT_TWO_PI_3 2.0943951023931957      /* 2 pi / 3 */
#define P2D_PLANT_COUNTER_RANGE 4294967296.0       /* 2^32 */
#define P2D_PLANT_W_C_MIN_RADPS 0.01               /* narrowest Coulomb smoothing band [rad/s] */
#define P2D_PLANT_W_C_PERIODS 10.0                 /* friction time constant J w_c / T_c in periods [-] */
#define P2D_PLANT_GOLDEN_GAMMA 0x9e3779b97f4a7c15u /* splitmix64 increment */

typedef struct {
    const char *param; /* configuration field */
    const char *text;  /* valid range */
} p2d_plant_status_text_t;

static const p2d_plant_status_text_t P2D_PLANT_STATUS_TEXT[P2D_PLANT_STATUS_COUNT] = {
    [P2D_PLANT_OK] = {"", ""},
    [P2D_PLANT_ERR_NULL] = {"pointer", "non-NULL"},
    [P2D_PLANT_ERR_POLE_PAIRS] = {"motor.pole_pairs", "an integer >= 1"},
    [P2D_PLANT_ERR_RS] = {"motor.Rs_ohm", "finite and > 0"},
    [P2D_PLANT_ERR_LD] = {"motor.Ld_H", "finite and > 0"},
    [P2D_PLANT_ERR_LQ] = {"motor.Lq_H", "finite and > 0"},
    [P2D_PLANT_ERR_PSI_F] = {"motor.psi_f_Wb", "finite and > 0"},
    [P2D_PLANT_ERR_J] = {"motor.J_kgm2", "finite and > 0"},
    [P2D_PLANT_ERR_B] = {"motor.B_Nms", "finite and >= 0"},
    [P2D_PLANT_ERR_T_COULOMB] = {"motor.T_coulomb_Nm", "finite and >= 0"},
    [P2D_PLANT_ERR_MECHANICS_MODEL] = {"mechanics.model", "rigid (0) or two_mass (1)"},
    [P2D_PLANT_ERR_J_LOAD] = {"mechanics.J_load_kgm2", "finite and > 0 (two_mass)"},
    [P2D_PLANT_ERR_STIFFNESS] = {"mechanics.stiffness_Nm_per_rad", "finite and > 0 (two_mass)"},
    [P2D_PLANT_ERR_DAMPING] = {"mechanics.damping_Nms_per_rad", "finite and >= 0 (two_mass)"},
    [P2D_PLANT_ERR_BACKLASH] = {"mechanics.backlash_rad", "finite and >= 0 (two_mass)"},
    [P2D_PLANT_ERR_FEEDBACK] = {"mechanics.feedback", "motor (0) or load (1)"},
    [P2D_PLANT_ERR_U_DC] = {"u_dc_V", "finite and > 0"},
    [P2D_PLANT_ERR_TS] = {"Ts_s", "finite and > 0"},
    [P2D_PLANT_ERR_SUBSTEPS] = {"substeps", "an integer >= 1"},
    [P2D_PLANT_ERR_TAU_I] = {"tau_i_s", "finite and > 0, or 0 (eq 1)"},
    [P2D_PLANT_ERR_W_M0] = {"w_m0_radps", "finite"},
    [P2D_PLANT_ERR_I0] = {"id0_A, iq0_A", "finite"},
    [P2D_PLANT_ERR_CURRENT_SENSOR] = {"current_sensor", "finite gain errors > -1, finite offsets, finite "
                                                        "noise_rms_A >= 0"},
};

const char *p2d_plant_status_param(p2d_plant_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_PLANT_STATUS_COUNT) return "unknown";
    return P2D_PLANT_STATUS_TEXT[status].param;
}

const char *p2d_plant_status_text(p2d_plant_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_PLANT_STATUS_COUNT) return "unknown status code";
    return P2D_PLANT_STATUS_TEXT[status].text;
}

static bool is_positive(double x) { return isfinite(x) && x > 0.0; }
static bool is_nonnegative(double x) { return isfinite(x) && x >= 0.0; }

static p2d_plant_status_t config_status(const p2d_plant_config_t *cfg)
{
    const p2d_pmsm_params_t *m = &cfg->motor;
    const p2d_mechanics_config_t *mech = &cfg->mechanics;
    const p2d_current_sensor_config_t *cs = &cfg->current_sensor;
    if (m->pole_pairs < 1u) return P2D_PLANT_ERR_POLE_PAIRS;
    if (!is_positive(m->Rs_ohm)) return P2D_PLANT_ERR_RS;
    if (!is_positive(m->Ld_H)) return P2D_PLANT_ERR_LD;
    if (!is_positive(m->Lq_H)) return P2D_PLANT_ERR_LQ;
    if (!is_positive(m->psi_f_Wb)) return P2D_PLANT_ERR_PSI_F;
    if (!is_positive(m->J_kgm2)) return P2D_PLANT_ERR_J;
    if (!is_nonnegative(m->B_Nms)) return P2D_PLANT_ERR_B;
    if (!is_nonnegative(m->T_coulomb_Nm)) return P2D_PLANT_ERR_T_COULOMB;
    if ((unsigned)mech->model > (unsigned)P2D_MECHANICS_TWO_MASS) return P2D_PLANT_ERR_MECHANICS_MODEL;
    if ((unsigned)mech->feedback > (unsigned)P2D_FEEDBACK_LOAD) return P2D_PLANT_ERR_FEEDBACK;
    if (mech->model == P2D_MECHANICS_TWO_MASS) {
        if (!is_positive(mech->J_load_kgm2)) return P2D_PLANT_ERR_J_LOAD;
        if (!is_positive(mech->stiffness_Nm_per_rad)) return P2D_PLANT_ERR_STIFFNESS;
        if (!is_nonnegative(mech->damping_Nms_per_rad)) return P2D_PLANT_ERR_DAMPING;
        if (!is_nonnegative(mech->backlash_rad)) return P2D_PLANT_ERR_BACKLASH;
    }
    if (!is_positive(cfg->u_dc_V)) return P2D_PLANT_ERR_U_DC;
    if (!is_positive(cfg->Ts_s)) return P2D_PLANT_ERR_TS;
    if (cfg->substeps < 1u) return P2D_PLANT_ERR_SUBSTEPS;
    if (!is_nonnegative(cfg->tau_i_s)) return P2D_PLANT_ERR_TAU_I;
    if (!isfinite(cfg->w_m0_radps)) return P2D_PLANT_ERR_W_M0;
    if (!isfinite(cfg->id0_A) || !isfinite(cfg->iq0_A)) return P2D_PLANT_ERR_I0;
    if (!(isfinite(cs->gain_error_a) && cs->gain_error_a > -1.0) ||
        !(isfinite(cs->gain_error_b) && cs->gain_error_b > -1.0) || !isfinite(cs->offset_a_A) ||
        !isfinite(cs->offset_b_A) || !is_nonnegative(cs->noise_rms_A)) {
        return P2D_PLANT_ERR_CURRENT_SENSOR;
    }
    return P2D_PLANT_OK;
}

double p2d_plant_friction_band_radps(const p2d_pmsm_params_t *motor, double Ts_s)
{
    /* w_c = max(w_c_min, 10 Ts T_c / J): friction time constant J w_c / T_c >= 10 Ts */
    return fmax(P2D_PLANT_W_C_MIN_RADPS, P2D_PLANT_W_C_PERIODS * Ts_s * motor->T_coulomb_Nm / motor->J_kgm2);
}

/* ---- inverter ----------------------------------------------------------- */

/*
 * The range u_max = u_dc / sqrt(3), and u_inside2 = (1 - 2^-40) u_max^2: a sum of squares
 * ud^2 + uq^2 below u_inside2 is inside the range whatever the rounding of the sum (< 2^-51
 * relative; squares that underflow, < 2^-1074 absolute) and of hypot (< 1 ulp), so that
 * inside_range decides without hypot, as hypot would. u_inside2 is 0 (hypot always) for a range
 * outside [2^-450, 2^450] V, whose square could underflow or overflow.
 */
void p2d_plant_set_dc_link(p2d_plant_t *plant, double u_dc_V)
{
    double u_max_V = u_dc_V * P2D_PLANT_INV_SQRT3;
    bool square_normal = u_max_V >= 0x1p-450 && u_max_V <= 0x1p450;
    plant->u_dc_V = u_dc_V;
    plant->u_max_V = u_max_V;
    plant->u_inside2_V2 = square_normal ? u_max_V * u_max_V * (1.0 - 0x1p-40) : 0.0;
}

void p2d_plant_command(p2d_plant_t *plant, double ud_V, double uq_V, p2d_inverter_output_t *out)
{
    p2d_inverter_output_t o;
    p2d_plant_inverter(plant, ud_V, uq_V, &o);
    if (out != 0) *out = o;
}

/* ---- eq 1 and eq 3 ------------------------------------------------------ */

/* Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) */
static double torque_Nm(const p2d_plant_t *plant, double id_A, double iq_A)
{
    return iq_A * (plant->kt_Nm_per_A + plant->c_T_Nm_per_A2 * id_A);
}

/* The voltage of eq 1 at the present state for the current slopes given. */
static void eq1_voltage(const p2d_plant_t *plant, double did_dt, double diq_dt, double *ud_V, double *uq_V)
{
    const p2d_pmsm_params_t *m = &plant->cfg.motor;
    double w_e = plant->p * plant->w_m_radps;
    /* ud = Rs id + Ld did/dt - w_e Lq iq */
    *ud_V = m->Rs_ohm * plant->id_A + m->Ld_H * did_dt - w_e * m->Lq_H * plant->iq_A;
    /* uq = Rs iq + Lq diq/dt + w_e (Ld id + psi_f) */
    *uq_V = m->Rs_ohm * plant->iq_A + m->Lq_H * diq_dt + w_e * (m->Ld_H * plant->id_A + m->psi_f_Wb);
}

bool p2d_plant_command_currents(p2d_plant_t *plant, double id_ref_A, double iq_ref_A)
{
    double ud_V, uq_V;
    plant->a_d = id_ref_A;
    plant->a_q = iq_ref_A;
    p2d_plant_applied_voltage(plant, &ud_V, &uq_V);
    return !p2d_plant_inside_range(plant, ud_V, uq_V) && hypot(ud_V, uq_V) > plant->u_max_V;
}

void p2d_plant_applied_voltage(const p2d_plant_t *plant, double *ud_V, double *uq_V)
{
    if (plant->first_order) {
        /* the voltage eq 1 needs for the current slopes of eq 3 */
        eq1_voltage(plant, (plant->a_d - plant->id_A) * plant->coef.inv_tau_i_per_s,
                    (plant->a_q - plant->iq_A) * plant->coef.inv_tau_i_per_s, ud_V, uq_V);
        return;
    }
    *ud_V = plant->a_d;
    *uq_V = plant->a_q;
}

/* ---- init --------------------------------------------------------------- */

/* The coefficients of the RK4 step for a valid cfg. */
static p2d_plant_coef_t coefficients(const p2d_plant_config_t *cfg, bool two_mass, bool first_order)
{
    const p2d_pmsm_params_t *m = &cfg->motor;
    const p2d_mechanics_config_t *mech = &cfg->mechanics;
    double p = (double)m->pole_pairs, inv_J = 1.0 / m->J_kgm2;
    p2d_plant_coef_t c;
    c.Rs_Ld_per_s = m->Rs_ohm / m->Ld_H;
    c.Rs_Lq_per_s = m->Rs_ohm / m->Lq_H;
    c.p_Lq_Ld = p * m->Lq_H / m->Ld_H;
    c.p_Ld_Lq = p * m->Ld_H / m->Lq_H;
    c.p_psi_Lq_A = p * m->psi_f_Wb / m->Lq_H;
    c.inv_Ld_per_H = 1.0 / m->Ld_H;
    c.inv_Lq_per_H = 1.0 / m->Lq_H;
    /* Te / J = iq (1.5 p psi_f + 1.5 p (Ld - Lq) id) / J */
    c.kt_J = 1.5 * p * m->psi_f_Wb * inv_J;
    c.cT_J = 1.5 * p * (m->Ld_H - m->Lq_H) * inv_J;
    c.B_J_per_s = m->B_Nms * inv_J;
    c.Tc_J_radps2 = m->T_coulomb_Nm * inv_J;
    c.inv_w_c_s_per_rad = 1.0 / p2d_plant_friction_band_radps(m, cfg->Ts_s);
    c.inv_J_per_kgm2 = inv_J;
    c.inv_tau_i_per_s = first_order ? 1.0 / cfg->tau_i_s : 0.0;
    c.K_Nm_per_rad = two_mass ? mech->stiffness_Nm_per_rad : 0.0;
    c.D_Nms_per_rad = two_mass ? mech->damping_Nms_per_rad : 0.0;
    c.half_backlash_rad = two_mass ? 0.5 * mech->backlash_rad : 0.0;
    c.inv_J_load_per_kgm2 = two_mass ? 1.0 / mech->J_load_kgm2 : 0.0;
    return c;
}

p2d_plant_status_t p2d_plant_init(p2d_plant_t *plant, const p2d_plant_config_t *cfg)
{
    const p2d_pmsm_params_t *m;
    p2d_plant_status_t status;
    if (plant == 0 || cfg == 0) return P2D_PLANT_ERR_NULL;
    status = config_status(cfg);
    if (status != P2D_PLANT_OK) return status;
    memset(plant, 0, sizeof *plant);
    plant->cfg = *cfg;
    m = &cfg->motor;
    plant->coulomb = m->T_coulomb_Nm > 0.0;
    plant->two_mass = cfg->mechanics.model == P2D_MECHANICS_TWO_MASS;
    plant->first_order = cfg->tau_i_s > 0.0;
    plant->p = (double)m->pole_pairs;
    plant->kt_Nm_per_A = 1.5 * plant->p * m->psi_f_Wb;
    plant->c_T_Nm_per_A2 = 1.5 * plant->p * (m->Ld_H - m->Lq_H);
    plant->coef = coefficients(cfg, plant->two_mass, plant->first_order);
    plant->dt_s = cfg->Ts_s / (double)cfg->substeps;
    plant->id_A = cfg->id0_A;
    plant->iq_A = cfg->iq0_A;
    plant->w_m_radps = cfg->w_m0_radps;
    plant->theta_m_rad = 0.0;
    plant->theta_rad = 0.0;
    plant->w_load_radps = cfg->w_m0_radps;
    p2d_plant_set_dc_link(plant, cfg->u_dc_V);
    plant->a_d = 0.0;
    plant->a_q = 0.0;
    plant->limited_next = false;
    plant->current_rng = cfg->current_sensor.seed;
    if (!plant->first_order) {
        /* the command applied over the first period under the computation delay: the steady state */
        eq1_voltage(plant, 0.0, 0.0, &plant->ud_next_V, &plant->uq_next_V);
    }
    return P2D_PLANT_OK;
}

/* ---- integration -------------------------------------------------------- */

/* T_f = B w_m + T_c tanh(w_m / w_c) */
double p2d_plant_friction_Nm(const p2d_plant_t *plant, double w_m_radps)
{
    const p2d_pmsm_params_t *m = &plant->cfg.motor;
    double T = m->B_Nms * w_m_radps;
    if (plant->coulomb) T += m->T_coulomb_Nm * tanh(w_m_radps * plant->coef.inv_w_c_s_per_rad);
    return T;
}

/* One RK4 step with the flags of the plant as constants (a specialised copy per model). */
P2D_PLANT_INLINE void advance(p2d_plant_t *plant, double h, double T0_Nm, double dT_dt_Nmps, bool first_order,
                              bool coulomb, bool two_mass)
{
    p2d_plant_set_state(plant, p2d_plant_rk4(&plant->coef, p2d_plant_state(plant), plant->a_d, plant->a_q, h, T0_Nm,
                                             dT_dt_Nmps, first_order, coulomb, two_mass, false));
}

void p2d_plant_advance(p2d_plant_t *plant, double h_s, double T_load_Nm, double dT_load_Nm_per_s)
{
    bool first_order = plant->first_order, coulomb = plant->coulomb;
    if (plant->two_mass) {
        advance(plant, h_s, T_load_Nm, dT_load_Nm_per_s, first_order, coulomb, true);
    } else if (first_order) {
        advance(plant, h_s, T_load_Nm, dT_load_Nm_per_s, true, coulomb, false);
    } else if (coulomb) {
        advance(plant, h_s, T_load_Nm, dT_load_Nm_per_s, false, true, false);
    } else {
        advance(plant, h_s, T_load_Nm, dT_load_Nm_per_s, false, false, false);
    }
}

void p2d_plant_step(p2d_plant_t *plant, double ud_V, double uq_V, double T_load_Nm, p2d_inverter_output_t *out)
{
    p2d_plant_command(plant, ud_V, uq_V, out);
    for (uint32_t s = 0; s < plant->cfg.substeps; ++s) p2d_plant_advance(plant, plant->dt_s, T_load_Nm, 0.0);
}

/* d clipped to [0, 1] (NaN to 0) */
static double duty(double d) { return d > 0.0 ? (d < 1.0 ? d : 1.0) : 0.0; }

void p2d_plant_step_duties(p2d_plant_t *plant, double duty_a, double duty_b, double duty_c, double T_load_Nm)
{
    double da = duty(duty_a), db = duty(duty_b), dc = duty(duty_c);
    /* u_alpha = u_dc (2 d_a - d_b - d_c) / 3, u_beta = u_dc (d_b - d_c) / sqrt(3) */
    double u_alpha = plant->u_dc_V * (2.0 * da - db - dc) / 3.0;
    double u_beta = plant->u_dc_V * (db - dc) * P2D_PLANT_INV_SQRT3;
    double w_e = plant->p * plant->w_m_radps, x = 0.5 * w_e * plant->cfg.Ts_s;
    double th_mid = plant->p * plant->theta_m_rad + x;
    /* sinc(x) = sin(x) / x, 1 - x^2 / 6 to double precision for |x| < 1e-4 */
    double sinc = fabs(x) < 1e-4 ? 1.0 - x * x / 6.0 : sin(x) / x;
    double c = cos(th_mid), s = sin(th_mid);
    /* ud + j uq = sinc e^(-j th_mid) (u_alpha + j u_beta) */
    plant->a_d = sinc * (c * u_alpha + s * u_beta);
    plant->a_q = sinc * (-s * u_alpha + c * u_beta);
    for (uint32_t k = 0; k < plant->cfg.substeps; ++k) p2d_plant_advance(plant, plant->dt_s, T_load_Nm, 0.0);
}

/* ---- what a board reads ------------------------------------------------- */

void p2d_plant_steady_voltage(const p2d_plant_t *plant, double *ud_V, double *uq_V)
{
    eq1_voltage(plant, 0.0, 0.0, ud_V, uq_V);
}

double p2d_plant_torque_Nm(const p2d_plant_t *plant) { return torque_Nm(plant, plant->id_A, plant->iq_A); }

double p2d_plant_shaft_torque_Nm(const p2d_plant_t *plant, double T_load_Nm)
{
    if (!plant->two_mass) return T_load_Nm;
    return p2d_plant_shaft(&plant->coef, plant->theta_rad, plant->w_m_radps - plant->w_load_radps);
}

/* ia = id cos(th_e) - iq sin(th_e), ib = id cos(th_e - 2 pi/3) - iq sin(th_e - 2 pi/3) */
static void phase_currents(const p2d_plant_t *plant, double *ia_A, double *ib_A)
{
    double th_e = plant->p * plant->theta_m_rad;
    double c = cos(th_e), sn = sin(th_e);
    double cb = cos(th_e - P2D_PLANT_TWO_PI_3), sb = sin(th_e - P2D_PLANT_TWO_PI_3);
    *ia_A = plant->id_A * c - plant->iq_A * sn;
    *ib_A = plant->id_A * cb - plant->iq_A * sb;
}

void p2d_plant_phase_currents(const p2d_plant_t *plant, double *ia_A, double *ib_A, double *ic_A)
{
    phase_currents(plant, ia_A, ib_A);
    *ic_A = -*ia_A - *ib_A;
}

void p2d_plant_sense_currents(p2d_plant_t *plant, double *ia_A, double *ib_A)
{
    const p2d_current_sensor_config_t *cs = &plant->cfg.current_sensor;
    double ia, ib;
    phase_currents(plant, &ia, &ib);
    /* i' = (1 + gain_error) i + offset + noise */
    ia = (1.0 + cs->gain_error_a) * ia + cs->offset_a_A;
    ib = (1.0 + cs->gain_error_b) * ib + cs->offset_b_A;
    if (cs->noise_rms_A > 0.0) {
        ia += cs->noise_rms_A * p2d_normal(&plant->current_rng);
        ib += cs->noise_rms_A * p2d_normal(&plant->current_rng);
    }
    *ia_A = ia;
    *ib_A = ib;
}

void p2d_plant_rotor(const p2d_plant_t *plant, double *theta_m_rad, double *w_m_radps)
{
    *theta_m_rad = plant->theta_m_rad;
    *w_m_radps = plant->w_m_radps;
}

void p2d_plant_load_side(const p2d_plant_t *plant, double *theta_L_rad, double *w_L_radps)
{
    *theta_L_rad = plant->two_mass ? plant->theta_m_rad - plant->theta_rad : plant->theta_m_rad;
    *w_L_radps = plant->two_mass ? plant->w_load_radps : plant->w_m_radps;
}

uint32_t p2d_plant_encoder_count(const p2d_plant_t *plant)
{
    double theta_rad = plant->theta_m_rad, w_radps;
    if (plant->cfg.counts_per_rev == 0u) return 0u;
    if (plant->cfg.mechanics.feedback == P2D_FEEDBACK_LOAD) p2d_plant_load_side(plant, &theta_rad, &w_radps);
    return p2d_encoder_counter(plant->cfg.counts_per_rev, theta_rad);
}

double p2d_plant_dc_link_V(const p2d_plant_t *plant) { return plant->u_dc_V; }

uint32_t p2d_encoder_counter(uint32_t counts_per_rev, double theta_rad)
{
    double n = fmod(floor(theta_rad * (double)counts_per_rev / P2D_PLANT_TWO_PI), P2D_PLANT_COUNTER_RANGE);
    if (n < 0.0) n += P2D_PLANT_COUNTER_RANGE;
    return (uint32_t)n;
}

/* splitmix64: the next 64 random bits of the stream *state. */
static uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += P2D_PLANT_GOLDEN_GAMMA);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9u;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebu;
    return z ^ (z >> 31);
}

/* Box-Muller: sqrt(-2 ln u1) cos(2 pi u2) with u1 in (0, 1], u2 in [0, 1). */
double p2d_normal(uint64_t *state)
{
    double u1 = ((double)(splitmix64(state) >> 11) + 1.0) * 0x1p-53;
    double u2 = (double)(splitmix64(state) >> 11) * 0x1p-53;
    return sqrt(-2.0 * log(u1)) * cos(P2D_PLANT_TWO_PI * u2);
}
