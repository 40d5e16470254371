/*
 * pmsm2dof: the drive's plant, a "virtual motor": the PMSM of eq 1, the
 * inverter, the mechanics with friction and load, and what a board measures.
 * The simulation engine (drive.h) runs it on the host; the firmware example's
 * virtual board runs the same source on the target (C99, double precision,
 * soft-float on a Cortex-M4F; <math.h>, <stdint.h>, <stdbool.h>, <string.h>
 * only, no allocation, no global state: everything lives in p2d_plant_t).
 *
 * Model (SI units; mechanical speed w_m, electrical w_e = p w_m, electrical
 * angle p theta_m; the paper's eq 1 calls p0 the number of poles while using
 * it as pole pairs, and its torque lacks the factor 1.5 of the
 * amplitude-invariant Park transform used here):
 *   Ld did/dt = ud - Rs id + w_e Lq iq
 *   Lq diq/dt = uq - Rs iq - w_e (Ld id + psi_f)
 *   Te        = 1.5 p (psi_f iq + (Ld - Lq) id iq)
 *   J dw_m/dt = Te - T_load - B w_m - T_c tanh(w_m / w_c),   dtheta_m/dt = w_m
 * or, with the closed current loop of eq 3 instead of eq 1 (tau_i_s > 0,
 * p2d_plant_command_currents), tau_i di/dt = i_ref - i per axis.
 *
 * Two-mass drive train (mechanics.model = P2D_MECHANICS_TWO_MASS): motor.J_kgm2
 * is then the motor side J_M alone, coupled to the load inertia J_L by a
 * shaft of stiffness K, damping D and total play b (dead zone), twist
 * theta = theta_M - theta_L:
 *   J_M dw_m/dt  = Te - T_s - B w_m - T_c tanh(w_m / w_c)
 *   J_L dw_L/dt  = T_s - T_load
 *   dtheta/dt    = w_m - w_L
 *   T_s          = K (theta - sign(theta) b/2) + D (w_m - w_L)   |theta| >= b/2 (contact)
 *                = 0                                             |theta| <  b/2 (in the play)
 * (the dead-zone model of backlash: M. Nordin, P.-O. Gutman, "Controlling
 * mechanical systems with backlash - a survey", Automatica 38, 2002). The
 * friction acts on the motor side, the load torque on the load side; the
 * initial state has no twist and both sides at w_m0. Without play the
 * resonance is at sqrt(K (J_M + J_L) / (J_M J_L)), the anti-resonance at
 * sqrt(K / J_L). Rigid (the default): one inertia motor.J_kgm2, the load
 * side is the motor side and the shaft carries the load torque.
 *
 * Coulomb friction T_c is smoothed by tanh over the speed band
 *   w_c = max(0.01 rad/s, 10 Ts T_c / J)          (p2d_plant_friction_band_radps)
 * so that the friction's linearization around zero speed, a time constant
 * J w_c / T_c >= 10 Ts, is resolved by the integrator (the band depends on the
 * plant's period Ts, never on the integration step). Outside the band the
 * friction is T_c sign(w_m); inside, the model has no stiction: a load below
 * T_c lets the shaft creep at w_c atanh(T_load / T_c).
 *
 * Inverter: switching-cycle average model. A dq voltage command
 * (p2d_plant_command) is limited to the linear range of space-vector
 * modulation ||u_dq|| <= u_dc / sqrt(3) by scaling the vector, and held in
 * the rotor frame over the period (the modulator rotates it with the rotor).
 * With computation_delay the command given in period n is applied over period
 * n + 1 (a controller that writes the PWM registers for the next period),
 * limited again by the range of period n + 1; over the first period the
 * steady-state voltage of the initial state is applied (limited to the range).
 * Duty cycles (p2d_plant_step_duties) are applied over the step they are given
 * for, whatever computation_delay says: a board whose PWM registers take
 * effect one period later passes the duties it wrote one period earlier.
 *
 * Integration: classical Runge-Kutta (RK4) steps of at most Ts / substeps,
 * with the voltage (or eq 3's current command) held and the load torque
 * linear in time over each step (p2d_plant_advance; a caller splits a period
 * at the kinks of its load, so that each step sees a smooth load).
 *
 * Measurement (what a board reads):
 *   phase currents  ia = id cos(th_e) - iq sin(th_e), ib = id cos(th_e - 2 pi/3) - iq sin(th_e - 2 pi/3),
 *                   ic = -ia - ib, th_e = p theta_m; the sensors of phases a and b read
 *                   (1 + gain_error) i + offset + noise (white Gaussian, noise_rms_A, seeded);
 *   encoder         n = floor(theta counts_per_rev / (2 pi)) mod 2^32 of the angle theta of the
 *                   side mechanics.feedback names (the motor theta_m or the load theta_L =
 *                   theta_m - theta, 0 at t = 0); a counter of fewer bits keeps the low bits;
 *   rotor           theta_m (0 at t = 0) and w_m; the load side theta_L, w_L;
 *   DC link         u_dc (p2d_plant_set_dc_link changes it, e.g. a sag).
 * Noise: splitmix64 (Steele, Lea, Flood, "Fast splittable pseudorandom number
 * generators", OOPSLA 2014) for uniform numbers, the Box-Muller transform for
 * normal ones (p2d_normal).
 *
 * Use (one current/PWM period Ts per step):
 *   p2d_plant_t plant;
 *   p2d_plant_config_t cfg = {...};                   all fields below; zero means "none" where it can
 *   if (p2d_plant_init(&plant, &cfg) != P2D_PLANT_OK) ...   validates, precomputes, sets the initial state
 *   every period:
 *     p2d_plant_sense_currents(&plant, &ia, &ib);       the ADC
 *     n = p2d_plant_encoder_count(&plant);              the encoder counter
 *     ... the controller computes the voltage ...
 *     p2d_plant_step(&plant, ud_V, uq_V, T_load_Nm, &out);   or p2d_plant_step_duties(...)
 * A caller that needs more control (the engine: a load that changes inside the
 * period) calls p2d_plant_command (or p2d_plant_command_currents) once and
 * p2d_plant_advance over the pieces of the period instead of p2d_plant_step.
 * The state fields of p2d_plant_t may be read directly (the engine does); the
 * functions below are the interface, and the only writers.
 */
#ifndef PMSM2DOF_SIM_PLANT_H
#define PMSM2DOF_SIM_PLANT_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Parameters of the PMSM and its friction. */
typedef struct {
    uint32_t pole_pairs; /* pole pairs p [-], >= 1 */
    double Rs_ohm;       /* stator resistance [ohm], > 0 */
    double Ld_H;         /* d-axis inductance [H], > 0 */
    double Lq_H;         /* q-axis inductance [H], > 0 */
    double psi_f_Wb;     /* permanent-magnet flux linkage [Wb], > 0 */
    double J_kgm2;       /* total inertia (two_mass: the motor side J_M) [kg m^2], > 0 */
    double B_Nms;        /* viscous friction [Nm s/rad], >= 0 */
    double T_coulomb_Nm; /* Coulomb friction [Nm], >= 0 */
} p2d_pmsm_params_t;

/* Mechanical model of the drive train: see the comment at the top. */
typedef enum {
    P2D_MECHANICS_RIGID = 0,   /* one inertia, motor.J_kgm2 */
    P2D_MECHANICS_TWO_MASS = 1 /* motor.J_kgm2 and J_load_kgm2 coupled by an elastic shaft */
} p2d_mechanics_model_t;

/* The side whose speed and angle the speed sensor (encoder) measures. */
typedef enum {
    P2D_FEEDBACK_MOTOR = 0, /* the motor side w_m, theta_m */
    P2D_FEEDBACK_LOAD = 1   /* the load side w_L, theta_L (two_mass; rigid: the motor side) */
} p2d_feedback_t;

/* Parameters of the drive train (TWO_MASS; RIGID uses feedback only). */
typedef struct {
    p2d_mechanics_model_t model; /* RIGID or TWO_MASS */
    double J_load_kgm2;          /* load inertia J_L [kg m^2], > 0 */
    double stiffness_Nm_per_rad; /* shaft stiffness K [Nm/rad], > 0 */
    double damping_Nms_per_rad;  /* shaft damping D [Nm s/rad], >= 0 */
    double backlash_rad;         /* total play b of the dead zone [rad], >= 0 */
    p2d_feedback_t feedback;     /* side the speed sensor measures */
} p2d_mechanics_config_t;

/* Current sensors of phases a and b; all zero: exact. */
typedef struct {
    double gain_error_a; /* relative gain error of phase a's sensor [-], > -1 */
    double gain_error_b; /* relative gain error of phase b's sensor [-], > -1 */
    double offset_a_A;   /* offset of phase a's sensor [A], finite */
    double offset_b_A;   /* offset of phase b's sensor [A], finite */
    double noise_rms_A;  /* rms of the white Gaussian noise of each sensor [A], >= 0 */
    uint64_t seed;       /* seed of the noise [-] */
} p2d_current_sensor_config_t;

/* Everything the plant needs. */
typedef struct {
    p2d_pmsm_params_t motor;                    /* PMSM of eq 1 and its friction */
    p2d_mechanics_config_t mechanics;           /* drive train; all zero: rigid, motor-side sensor */
    double u_dc_V;                              /* DC-link voltage [V], finite and > 0 */
    bool computation_delay;                     /* a dq command is applied one period later */
    double Ts_s;                                /* period of p2d_plant_step, the PWM period [s], > 0 */
    uint32_t substeps;                          /* RK4 steps per period [-], >= 1 */
    double tau_i_s;                             /* eq 3's time constant [s], > 0; 0: eq 1 (voltage input) */
    double w_m0_radps;                          /* initial speed of both sides [rad/s], finite */
    double id0_A;                               /* initial d-axis current [A], finite */
    double iq0_A;                               /* initial q-axis current [A], finite */
    p2d_current_sensor_config_t current_sensor; /* phase current sensors; all zero: exact */
    uint32_t counts_per_rev;                    /* encoder counts per revolution [-]; 0: no encoder */
} p2d_plant_config_t;

/* Outcome of p2d_plant_init: the first field of the configuration out of its range. */
typedef enum {
    P2D_PLANT_OK = 0,
    P2D_PLANT_ERR_NULL,            /* a pointer argument is NULL */
    P2D_PLANT_ERR_POLE_PAIRS,      /* motor.pole_pairs */
    P2D_PLANT_ERR_RS,              /* motor.Rs_ohm */
    P2D_PLANT_ERR_LD,              /* motor.Ld_H */
    P2D_PLANT_ERR_LQ,              /* motor.Lq_H */
    P2D_PLANT_ERR_PSI_F,           /* motor.psi_f_Wb */
    P2D_PLANT_ERR_J,               /* motor.J_kgm2 */
    P2D_PLANT_ERR_B,               /* motor.B_Nms */
    P2D_PLANT_ERR_T_COULOMB,       /* motor.T_coulomb_Nm */
    P2D_PLANT_ERR_MECHANICS_MODEL, /* mechanics.model */
    P2D_PLANT_ERR_J_LOAD,          /* mechanics.J_load_kgm2 */
    P2D_PLANT_ERR_STIFFNESS,       /* mechanics.stiffness_Nm_per_rad */
    P2D_PLANT_ERR_DAMPING,         /* mechanics.damping_Nms_per_rad */
    P2D_PLANT_ERR_BACKLASH,        /* mechanics.backlash_rad */
    P2D_PLANT_ERR_FEEDBACK,        /* mechanics.feedback */
    P2D_PLANT_ERR_U_DC,            /* u_dc_V */
    P2D_PLANT_ERR_TS,              /* Ts_s */
    P2D_PLANT_ERR_SUBSTEPS,        /* substeps */
    P2D_PLANT_ERR_TAU_I,           /* tau_i_s */
    P2D_PLANT_ERR_W_M0,            /* w_m0_radps */
    P2D_PLANT_ERR_I0,              /* id0_A, iq0_A */
    P2D_PLANT_ERR_CURRENT_SENSOR,  /* current_sensor */
    P2D_PLANT_STATUS_COUNT         /* number of codes, not a code */
} p2d_plant_status_t;

/* What the inverter did with a dq command (p2d_plant_command). */
typedef struct {
    double ud_V;          /* the command as accepted: limited to u_dc / sqrt(3) [V] */
    double uq_V;          /* the command as accepted: limited to u_dc / sqrt(3) [V] */
    bool limited;         /* the command was cut to the range */
    bool applied_limited; /* the voltage applied over this period was cut (delay: the previous
                             command, cut again by this period's range; else: = limited) */
} p2d_inverter_output_t;

/* Coefficients of the plant's equations as its RK4 step uses them, precomputed at init. */
typedef struct {
    double Rs_Ld_per_s;         /* Rs / Ld [1/s] */
    double Rs_Lq_per_s;         /* Rs / Lq [1/s] */
    double p_Lq_Ld;             /* p Lq / Ld [-] */
    double p_Ld_Lq;             /* p Ld / Lq [-] */
    double p_psi_Lq_A;          /* p psi_f / Lq [A] */
    double inv_Ld_per_H;        /* 1 / Ld [1/H] */
    double inv_Lq_per_H;        /* 1 / Lq [1/H] */
    double kt_J;                /* 1.5 p psi_f / J [rad/s^2 per A] */
    double cT_J;                /* 1.5 p (Ld - Lq) / J [rad/s^2 per A^2] */
    double B_J_per_s;           /* B / J [1/s] */
    double Tc_J_radps2;         /* T_c / J [rad/s^2] */
    double inv_w_c_s_per_rad;   /* 1 / w_c, friction smoothing band [s/rad] */
    double inv_J_per_kgm2;      /* 1 / J (two_mass: 1 / J_M) [1/(kg m^2)] */
    double inv_tau_i_per_s;     /* 1 / tau_i (eq 3) [1/s] */
    double K_Nm_per_rad;        /* shaft stiffness K (two_mass) [Nm/rad] */
    double D_Nms_per_rad;       /* shaft damping D (two_mass) [Nm s/rad] */
    double half_backlash_rad;   /* b / 2 (two_mass) [rad] */
    double inv_J_load_per_kgm2; /* 1 / J_L (two_mass) [1/(kg m^2)] */
} p2d_plant_coef_t;

/*
 * The plant: coefficients precomputed at init, the state, the inverter and the
 * sensors' noise. The state fields may be read; only the functions write them.
 */
typedef struct {
    p2d_plant_config_t cfg; /* configuration */
    p2d_plant_coef_t coef;  /* coefficients of the RK4 step */
    bool coulomb;           /* T_c > 0 [-] */
    bool two_mass;          /* the two-mass train [-] */
    bool first_order;       /* the currents follow eq 3 (tau_i_s > 0) [-] */
    double p;               /* pole pairs p [-] */
    double kt_Nm_per_A;     /* 1.5 p psi_f [Nm/A] */
    double c_T_Nm_per_A2;   /* 1.5 p (Ld - Lq) [Nm/A^2] */
    double dt_s;            /* RK4 step Ts / substeps [s] */
    double id_A;            /* state: d-axis current [A] */
    double iq_A;            /* state: q-axis current [A] */
    double w_m_radps;       /* state: motor speed [rad/s] */
    double theta_m_rad;     /* state: motor angle, 0 at t = 0 [rad] */
    double theta_rad;       /* state: twist theta_M - theta_L (two_mass), 0 at t = 0 [rad] */
    double w_load_radps;    /* state: load-side speed w_L (two_mass) [rad/s] */
    double u_dc_V;          /* DC link [V] */
    double u_max_V;         /* range of the inverter u_dc / sqrt(3) [V] */
    double u_inside2_V2;    /* squared norms below it are inside u_max for sure [V^2] */
    double a_d;             /* input held over the period: ud [V] (eq 3: id_ref [A]) */
    double a_q;             /* input held over the period: uq [V] (eq 3: iq_ref [A]) */
    double ud_next_V;       /* delay: d-axis command for the next period [V] */
    double uq_next_V;       /* delay: q-axis command for the next period [V] */
    bool limited_next;      /* delay: the command for the next period was cut to the range [-] */
    uint64_t current_rng;   /* splitmix64 state of the current sensors' noise [-] */
} p2d_plant_t;

/* The friction smoothing band w_c = max(0.01 rad/s, 10 Ts T_c / J) of motor at the period Ts_s [rad/s]. */
double p2d_plant_friction_band_radps(const p2d_pmsm_params_t *motor, double Ts_s);

/*
 * Validate cfg, precompute the coefficients and set the initial state: currents id0, iq0, both
 * sides at w_m0 without twist, angle 0, the DC link u_dc_V; with computation_delay the voltage
 * of the first period is the steady state of eq 1 at that state (dI/dt = 0), limited to the range.
 * Returns the first field out of its range (p2d_plant_status_param names it).
 */
p2d_plant_status_t p2d_plant_init(p2d_plant_t *plant, const p2d_plant_config_t *cfg);

/* The DC link u_dc_V [V] (finite, >= 0) from now on: the inverter's range follows it. */
void p2d_plant_set_dc_link(p2d_plant_t *plant, double u_dc_V);

/*
 * The dq command (ud_V, uq_V) [V] given for the period that starts now (eq 1): the inverter
 * limits it to its range and applies it now or, with computation_delay, over the next period
 * (the previous command then applies now). *out (may be NULL) says what it did.
 */
void p2d_plant_command(p2d_plant_t *plant, double ud_V, double uq_V, p2d_inverter_output_t *out);

/*
 * The current command (id_ref_A, iq_ref_A) [A] of eq 3 for the period that starts now (tau_i_s > 0).
 * Returns true when the voltage eq 1 needs now for the current slopes of eq 3
 * (p2d_plant_applied_voltage) exceeds the inverter's range, which eq 3 ignores.
 */
bool p2d_plant_command_currents(p2d_plant_t *plant, double id_ref_A, double iq_ref_A);

/*
 * Integrate the plant over h_s [s], 0 < h_s <= Ts / substeps, by one RK4 step with the input of
 * the period held and the load torque T_load_Nm + dT_load_Nm_per_s (t - t_now) [Nm].
 */
void p2d_plant_advance(p2d_plant_t *plant, double h_s, double T_load_Nm, double dT_load_Nm_per_s);

/*
 * One period Ts: p2d_plant_command, then `substeps` RK4 steps with the load T_load_Nm [Nm] held.
 * *out may be NULL.
 */
void p2d_plant_step(p2d_plant_t *plant, double ud_V, double uq_V, double T_load_Nm, p2d_inverter_output_t *out);

/*
 * One period Ts with the duty cycles of the three half bridges (each clipped to [0, 1]) applied
 * over it: the average phase voltages d_x u_dc, in the stator frame
 *   u_alpha = u_dc (2 d_a - d_b - d_c) / 3,  u_beta = u_dc (d_b - d_c) / sqrt(3)
 * (amplitude invariant, the common mode removed), held in the stator frame while the rotor turns:
 * their mean over the period in the rotor frame, at the speed of its start,
 *   ud + j uq = sinc(w_e Ts / 2) e^(-j th_mid) (u_alpha + j u_beta),  th_mid = th_e + w_e Ts / 2,
 * sinc(x) = sin(x) / x, then `substeps` RK4 steps with the load T_load_Nm [Nm] held. Not limited
 * to the circle u_dc / sqrt(3): the duties reach the hexagon of space-vector modulation.
 */
void p2d_plant_step_duties(p2d_plant_t *plant, double duty_a, double duty_b, double duty_c, double T_load_Nm);

/* Friction torque B w_m + T_c tanh(w_m / w_c) at the speed w_m_radps [Nm]. */
double p2d_plant_friction_Nm(const p2d_plant_t *plant, double w_m_radps);

/* The voltage of eq 1 that holds the present currents at the present speed (dI/dt = 0) [V]. */
void p2d_plant_steady_voltage(const p2d_plant_t *plant, double *ud_V, double *uq_V);

/* Electromagnetic torque Te = 1.5 p (psi_f iq + (Ld - Lq) id iq) of the present state [Nm]. */
double p2d_plant_torque_Nm(const p2d_plant_t *plant);

/* Torque the shaft carries from the motor to the load [Nm] (rigid: T_load_Nm, the load given). */
double p2d_plant_shaft_torque_Nm(const p2d_plant_t *plant, double T_load_Nm);

/* The phase currents ia, ib, ic [A] of the present state (amplitude-invariant transform). */
void p2d_plant_phase_currents(const p2d_plant_t *plant, double *ia_A, double *ib_A, double *ic_A);

/* What the sensors of phases a and b read now [A] (gain error, offset, noise: draws the noise). */
void p2d_plant_sense_currents(p2d_plant_t *plant, double *ia_A, double *ib_A);

/* The encoder counter at the sensed side's angle (0 without an encoder) [counts]. */
uint32_t p2d_plant_encoder_count(const p2d_plant_t *plant);

/* Motor angle theta_m [rad] (0 at t = 0) and speed w_m [rad/s]. */
void p2d_plant_rotor(const p2d_plant_t *plant, double *theta_m_rad, double *w_m_radps);

/* Load-side angle theta_L = theta_m - theta [rad] and speed w_L [rad/s] (rigid: the motor's). */
void p2d_plant_load_side(const p2d_plant_t *plant, double *theta_L_rad, double *w_L_radps);

/*
 * The dq voltage applied over the present period [V]; eq 3: the voltage eq 1 needs at the present
 * state for the current slopes of eq 3, not limited.
 */
void p2d_plant_applied_voltage(const p2d_plant_t *plant, double *ud_V, double *uq_V);

/* The DC link [V]. */
double p2d_plant_dc_link_V(const p2d_plant_t *plant);

/* The counter floor(theta_rad counts_per_rev / (2 pi)) mod 2^32 at the angle theta_rad [counts]. */
uint32_t p2d_encoder_counter(uint32_t counts_per_rev, double theta_rad);

/* A standard normal number from the splitmix64 stream *state (Box-Muller) [-]. */
double p2d_normal(uint64_t *state);

/* Name of the configuration field a code rejects ("" for OK, "unknown" out of range). */
const char *p2d_plant_status_param(p2d_plant_status_t status);

/* Valid range of that field. */
const char *p2d_plant_status_text(p2d_plant_status_t status);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_PLANT_H */
