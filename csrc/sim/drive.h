/*
 * pmsm2dof: host-only simulation of the drive of the paper's Fig. 1, in double
 * precision, driven by the deployable float32 controllers of csrc/src.
 *
 * Plant (plant.h: the PMSM of eq 1, the inverter, the rigid or two-mass drive
 * train with friction, the load, the current sensors and the encoder): one
 * p2d_plant_t, the same source the firmware's virtual board runs. The speed
 * controller reads w_m (feedback P2D_FEEDBACK_MOTOR) or w_L (P2D_FEEDBACK_LOAD)
 * through the speed sensor of sensing.h, whose encoder then counts the load
 * angle; the current controller always sees p w_m and the electrical angle
 * p theta_M. Rigid: the log's load speed is w_m and its shaft torque the load
 * torque.
 *
 * Current loop, two models:
 *   P2D_CURRENT_DQ_PI        p2d_current_* at Ts_current drives the electrical
 *                            model of eq 1 through the inverter (plant.h);
 *   P2D_CURRENT_FIRST_ORDER  eq 3, i = i_ref / (tau_i s + 1) per axis, no
 *                            electrical model and no inverter.
 *
 * Sampled-data loop, per speed sample k at t_k = k Ts_speed,
 * Ts_speed = current_per_speed Ts_current:
 *   the speed controller samples w_ref(t_k) and w_m(t_k) and computes the
 *   current command (p2d_speed_step); then current_per_speed times: the
 *   current controller samples id, iq, w_e and computes the voltage (dq_pi
 *   only), the inverter applies it, and the plant is integrated over
 *   Ts_current by `substeps` classical Runge-Kutta (RK4) steps of
 *   dt = Ts_current / substeps (p2d_plant_advance). A load breakpoint (step,
 *   start or end of a ramp) inside a step splits it, so every RK4 step sees a
 *   smooth load.
 *   The speed reference is sampled by the speed controller (0 before the
 *   first entry); the load acts in continuous time.
 *
 * Lockstep (p2d_sim_run_many): drives of one shape (p2d_sim_lockstep) run
 * this loop together, P2D_SIM_LANES at a time: each drive's controllers and
 * inverter in turn, then one RK4 step of all their plants through an array
 * per state variable, coefficient and input, which the compiler vectorises
 * across the drives (plant_inline.h's step, the same arithmetic as a lone
 * drive's: every log is bit for bit that of p2d_sim_run). A period in which
 * a drive's load has a breakpoint runs each drive on its own; a drive that
 * stops leaves the group, the others run on. Drives logging at the current
 * rate run one after the other, each in the loop's copy that logs every
 * current period (the default loop has no test for it).
 *
 * Initial state: the drive is in steady state at the speed w_m0 before
 * t = 0, with the reference equal to w_m0 and no load: the speed controller is
 * reset bumplessly (p2d_speed_reset) to the torque holding w_m0 against
 * friction, the currents equal the command for that torque and the current
 * integrators hold the steady-state voltage. Schedule entries at t = 0 are
 * steps at t = 0.
 *
 * Faults (p2d_fault_t, at most one of each group active at a time: the
 * first active one in the list):
 *   P2D_FAULT_DC_LINK_SAG   over [t_s, t_s + duration_s) the DC link is
 *                           value * u_dc (value in [0, 1]): the inverter's
 *                           range u_dc / sqrt(3) and the DC link the current
 *                           controller measures shrink with it, for each
 *                           current period by its start (dq_pi only; the
 *                           overspeed bound keeps the nominal u_dc);
 *   P2D_FAULT_SENSOR_HOLD   speed sensor group: the speed controller's
 *                           samples in [t_s, t_s + duration_s) read the last
 *                           reading before the window (a frozen sensor);
 *   P2D_FAULT_SENSOR_ZERO   speed sensor group: they read 0 (a lost sensor);
 *   P2D_FAULT_SENSOR_SPIKE  speed sensor group: the first speed sample at or
 *                           after t_s reads value [rad/s] (one wrong sample).
 * The sensor faults act on the speed the speed controller samples only; the
 * current controllers keep the true electrical speed for their decoupling.
 *
 * Measurement and field weakening (cfg.sensing, sensing.h): the speed sensor
 * (ideal or an encoder read by the C estimator, low-pass, delay, noise) gives
 * the reading the sensor faults act on; the current controller reads the
 * phase-current sensors' errors transformed to dq; the field weakening sets
 * the d-axis current bound of p2d_speed_step_fw at each speed sample. The
 * rotor angle is integrated only when one of them needs it; with cfg.sensing
 * all zero the loop is the one described above.
 *
 * Arithmetic (cfg.arithmetic): the speed controller is the float32 p2d_speed_t, or the
 * fixed-point p2d_speed_q15_t or p2d_speed_q31_t of speed_fixed.h in the configuration's full
 * scales (a surface PMSM, without torque filters, field weakening or gain scheduling). Its
 * inputs are the reference and the reading rounded to the nearest integer of the format (half
 * up), saturated to its input range [-2^N, 2^N - 1]; its current command, id = 0 and iq in
 * current LSBs, drives the current loop as iq I_fs 2^-N [A] (float32 for the dq current
 * controller, double for eq 3); the initial steady state holds the torque rounded to the nearest
 * LSB. The log holds its outputs in Nm and A as its integers say, and its integrator x - Fr0 r
 * from its integers (x in its LSBs, Fr0 as its mantissa and shift).
 *
 * Log: one row for every log_every-th speed sample (log_rate SPEED), or for
 * every log_every-th current period (log_rate CURRENT), starting with the
 * first, in a column-major buffer of P2D_LOG_COUNT columns of log_rows
 * doubles (column c of row r at log[c * log_rows + r]), so that every signal
 * is a contiguous array. The row of the current period starting at t (at
 * the speed rate: t = t_k of speed sample k) holds the plant state at t
 * (before the plant moves), the outputs of the last speed sample (at or
 * before t: the speed controller's command, its integrator after the
 * update, the reference and the speed reading it sampled, the estimator),
 * the voltage applied over the current period starting at t (first_order:
 * the voltage eq 1 needs to make the currents follow eq 3 at t, unlimited),
 * the load at t, the DC link over that current period, and the share of
 * the speed sample's current periods at the voltage limit (the current
 * controller's voltage-vector limit active, or the inverter cutting a
 * delayed command; first_order: the voltage that eq 1 needs for eq 3 beyond
 * the inverter's range, a sign that eq 3 does not describe the drive there),
 * written into every row of that speed sample. The log rate changes which
 * rows are written, nothing else: the row of a speed sample's first current
 * period at the current rate is bit for bit its row at the speed rate.
 *
 * Stops (p2d_sim_run returns the code, sim->t_stop_s holds the time):
 *   P2D_SIM_STOP_NONFINITE         a state variable is NaN or infinite;
 *   P2D_SIM_STOP_OVERSPEED         |w_m| > 2 u_dc / (sqrt(3) p psi_f): twice the
 *                                  no-load speed of the DC link, where the
 *                                  back-EMF is twice the inverter's voltage
 *                                  range and the average model no longer
 *                                  describes the drive;
 *   P2D_SIM_STOP_OVERCURRENT       ||i_dq|| > 10 max(i_max, psi_f / min(Ld, Lq)):
 *                                  ten times the larger of the current limit and
 *                                  the short-circuit current of the machine;
 *   P2D_SIM_STOP_CONTROLLER_FAULT  a controller's non-finite policy engaged.
 */
#ifndef PMSM2DOF_SIM_DRIVE_H
#define PMSM2DOF_SIM_DRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "adapt.h"
#include "plant.h"
#include "pmsm2dof/current.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/speed_fixed.h"
#include "pmsm2dof/status.h"
#include "sensing.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Drives per lockstep group of p2d_sim_run_many: two SSE2 vectors of doubles. */
enum { P2D_SIM_LANES = 4 };

/* Current-loop model. */
typedef enum {
    P2D_CURRENT_DQ_PI = 0,      /* C current controller + electrical model + inverter */
    P2D_CURRENT_FIRST_ORDER = 1 /* eq 3: i = i_ref / (tau_i s + 1) */
} p2d_current_model_t;

/* Arithmetic of the speed controller. */
typedef enum {
    P2D_ARITHMETIC_FLOAT32 = 0, /* p2d_speed_* (speed.h): float32 */
    P2D_ARITHMETIC_Q15 = 1,     /* p2d_speed_q15_* (speed_fixed.h): int16 data, int32 arithmetic */
    P2D_ARITHMETIC_Q31 = 2      /* p2d_speed_q31_* (speed_fixed.h): int32 data, int64 arithmetic */
} p2d_arithmetic_t;
/* Rate of the log's rows; log_every counts rows of that rate. */
typedef enum {
    P2D_LOG_RATE_SPEED = 0,  /* a row per speed sample */
    P2D_LOG_RATE_CURRENT = 1 /* a row per current period */
} p2d_log_rate_t;

/* Outcome of p2d_sim_init (configuration errors) and p2d_sim_run (stops). */
typedef enum {
    P2D_SIM_OK = 0,
    P2D_SIM_ERR_NULL,               /* a pointer argument is NULL */
    P2D_SIM_ERR_POLE_PAIRS,         /* motor.pole_pairs */
    P2D_SIM_ERR_RS,                 /* motor.Rs_ohm */
    P2D_SIM_ERR_LD,                 /* motor.Ld_H */
    P2D_SIM_ERR_LQ,                 /* motor.Lq_H */
    P2D_SIM_ERR_PSI_F,              /* motor.psi_f_Wb */
    P2D_SIM_ERR_J,                  /* motor.J_kgm2 */
    P2D_SIM_ERR_B,                  /* motor.B_Nms */
    P2D_SIM_ERR_T_COULOMB,          /* motor.T_coulomb_Nm */
    P2D_SIM_ERR_U_DC,               /* u_dc_V */
    P2D_SIM_ERR_CURRENT_MODEL,      /* current_model */
    P2D_SIM_ERR_TAU_I,              /* tau_i_s (first_order) */
    P2D_SIM_ERR_TS_CURRENT,         /* Ts_current_s */
    P2D_SIM_ERR_CURRENT_PER_SPEED,  /* current_per_speed */
    P2D_SIM_ERR_SUBSTEPS,           /* substeps */
    P2D_SIM_ERR_LOG_EVERY,          /* log_every */
    P2D_SIM_ERR_W_M0,               /* w_m0_radps */
    P2D_SIM_ERR_REFERENCE,          /* reference schedule */
    P2D_SIM_ERR_LOAD,               /* load schedule */
    P2D_SIM_ERR_FAULTS,             /* faults */
    P2D_SIM_ERR_SPEED_CONTROLLER,   /* p2d_speed_init rejected speed: see controller_status */
    P2D_SIM_ERR_CURRENT_CONTROLLER, /* p2d_current_init rejected current: see controller_status */
    P2D_SIM_ERR_MECHANICS_MODEL,    /* mechanics.model */
    P2D_SIM_ERR_J_LOAD,             /* mechanics.J_load_kgm2 */
    P2D_SIM_ERR_STIFFNESS,          /* mechanics.stiffness_Nm_per_rad */
    P2D_SIM_ERR_DAMPING,            /* mechanics.damping_Nms_per_rad */
    P2D_SIM_ERR_BACKLASH,           /* mechanics.backlash_rad */
    P2D_SIM_ERR_FEEDBACK,           /* mechanics.feedback */
    P2D_SIM_ERR_LOG_FULL,           /* the log buffer has no room for the next row */
    P2D_SIM_STOP_NONFINITE,         /* the plant state is NaN or infinite */
    P2D_SIM_STOP_OVERSPEED,         /* |w_m| or |w_L| beyond twice the no-load speed of the DC link */
    P2D_SIM_STOP_OVERCURRENT,       /* ||i_dq|| beyond ten times max(i_max, short-circuit current) */
    P2D_SIM_STOP_CONTROLLER_FAULT,  /* a controller's non-finite policy engaged */
    P2D_SIM_ERR_SPEED_SENSOR,       /* speed_sensor (an encoder init's code in controller_status) */
    P2D_SIM_ERR_CURRENT_SENSOR,     /* current_sensor */
    P2D_SIM_ERR_FIELD_WEAKENING,    /* field_weakening (the regulator init's code in controller_status) */
    P2D_SIM_ERR_ESTIMATOR,          /* p2d_inertia_init rejected adapt.config: see controller_status */
    P2D_SIM_ERR_ADAPT_REL_CHANGE,   /* adapt.adapt_rel_change */
    P2D_SIM_ERR_E_QUIET,            /* adapt.e_quiet_radps */
    P2D_SIM_ERR_LOCKSTEP,           /* p2d_sim_run_many: drives of different shapes (p2d_sim_lockstep) */
    P2D_SIM_ERR_ARITHMETIC,         /* arithmetic (and what fixed point does not support) */
    P2D_SIM_ERR_LOG_RATE,           /* log_rate */
    P2D_SIM_STATUS_COUNT            /* number of codes, not a code */
} p2d_sim_status_t;

/* Columns of a log row. */
typedef enum {
    P2D_LOG_T_S = 0,         /* time t_k [s] */
    P2D_LOG_W_REF_RADPS,     /* speed reference sampled by the speed controller [rad/s] */
    P2D_LOG_W_M_RADPS,       /* mechanical speed [rad/s] */
    P2D_LOG_ID_REF_A,        /* d-axis current command [A] */
    P2D_LOG_IQ_REF_A,        /* q-axis current command [A] */
    P2D_LOG_ID_A,            /* d-axis current [A] */
    P2D_LOG_IQ_A,            /* q-axis current [A] */
    P2D_LOG_UD_V,            /* d-axis voltage applied [V] */
    P2D_LOG_UQ_V,            /* q-axis voltage applied [V] */
    P2D_LOG_TORQUE_NM,       /* electromagnetic torque Te [Nm] */
    P2D_LOG_TORQUE_REF_NM,   /* speed controller output u_sat [Nm] */
    P2D_LOG_TORQUE_UNSAT_NM, /* speed controller output before the limit u [Nm] */
    P2D_LOG_LOAD_NM,         /* load torque [Nm] */
    P2D_LOG_SATURATED,       /* 1 when the current-vector limit is active, else 0 [-] */
    P2D_LOG_X_I_NM,          /* speed integrator after the update x[k] [Nm] */
    P2D_LOG_W_MEAS_RADPS,    /* speed reading sampled by the speed controller [rad/s] */
    P2D_LOG_U_DC_V,          /* DC-link voltage over the current period starting at t_k [V] */
    P2D_LOG_VOLTAGE_LIMITED, /* share of the current periods of speed sample k whose voltage was
                                limited to u_dc / sqrt(3) [-] in [0, 1] (first_order: whose
                                voltage of eq 1 exceeded that range, which eq 3 ignores) */
    P2D_LOG_J_EST_KGM2,      /* inertia estimator (adapt.h): estimate of J after sample k [kg m^2] */
    P2D_LOG_J_VALID,         /* 1 when the estimate of J is valid (p2d_inertia_output_t), else 0 [-] */
    P2D_LOG_T_LOAD_EST_NM,   /* estimate of the load torque T_load [Nm] */
    P2D_LOG_J_GAINS_KGM2,    /* J the speed controller's gains are designed for at sample k [kg m^2] */
    P2D_LOG_W_LOAD_RADPS,    /* load-side speed w_L [rad/s] (rigid: w_m) */
    P2D_LOG_SHAFT_TORQUE_NM, /* shaft torque T_s [Nm] (rigid: the load torque) */
    P2D_LOG_COUNT            /* number of columns, not a column */
} p2d_log_column_t;

/* Piecewise-linear signal: 0 before the first entry; entry i starts at t_s[i]
   and moves from the value reached at t_s[i] to value[i], in one step
   (ramp_s[i] = 0) or linearly over ramp_s[i]. */
typedef struct {
    const double *t_s;    /* entry times [s], finite, >= 0, nondecreasing */
    const double *value;  /* target of each entry [unit of the signal], finite */
    const double *ramp_s; /* ramp duration of each entry [s], finite, >= 0 */
    uint32_t n;           /* number of entries; 0: the signal is 0 */
} p2d_schedule_t;

/* Read position in a schedule; time only moves forward. */
typedef struct {
    uint32_t next;    /* index of the first entry not yet reached [-] */
    double t0_s;      /* start of the present segment [s] */
    double v0;        /* value at the start of the segment [unit of the signal] */
    double v1;        /* target of the segment [unit of the signal] */
    double ramp_s;    /* ramp duration of the segment [s]; 0: a step */
    double t_break_s; /* next time the signal jumps or changes slope, known until then [s]; -HUGE_VAL: unknown */
} p2d_schedule_cursor_t;

/* Fault kinds: see the comment at the top. */
typedef enum {
    P2D_FAULT_DC_LINK_SAG = 0, /* u_dc scaled by value over the window */
    P2D_FAULT_SENSOR_HOLD = 1, /* speed reading frozen over the window */
    P2D_FAULT_SENSOR_ZERO = 2, /* speed reading 0 over the window */
    P2D_FAULT_SENSOR_SPIKE = 3 /* one speed sample reads value */
} p2d_fault_kind_t;

/* One fault. */
typedef struct {
    p2d_fault_kind_t kind; /* what fails */
    double t_s;            /* start [s], finite, >= 0 */
    double duration_s;     /* length of the window [s], finite, > 0 (SENSOR_SPIKE: unused) */
    double value;          /* DC_LINK_SAG: factor of u_dc [-] in [0, 1]; SENSOR_SPIKE: the reading
                              [rad/s], finite; others: unused */
} p2d_fault_t;

/* Everything a simulation needs; rpm never appears here. */
typedef struct {
    p2d_pmsm_params_t motor;           /* true plant (plant.h) */
    double u_dc_V;                     /* DC-link voltage [V], > 0 */
    bool computation_delay;            /* inverter applies the command one current period later */
    p2d_current_model_t current_model; /* DQ_PI or FIRST_ORDER */
    double tau_i_s;                    /* FIRST_ORDER time constant of eq 3 [s], > 0 */
    double Ts_current_s;               /* current-controller and PWM period [s], > 0 */
    uint32_t current_per_speed;        /* Ts_speed / Ts_current [-], >= 1 */
    uint32_t substeps;                 /* RK4 steps per current period [-], >= 1 */
    uint32_t log_every;                /* log one speed sample (or current period) in log_every [-], >= 1 */
    p2d_log_rate_t log_rate;           /* SPEED or CURRENT: the rows log_every counts; 0: SPEED */
    double w_m0_radps;                 /* initial speed [rad/s], finite */
    p2d_schedule_t reference;          /* speed reference [rad/s] */
    p2d_schedule_t load;               /* load torque [Nm] */
    p2d_speed_config_t speed;          /* speed controller (its i_max_A is the drive's limit) */
    p2d_current_config_t current;      /* current controller, DQ_PI only */
    const p2d_fault_t *faults;         /* faults, in any order (not copied); DC_LINK_SAG needs DQ_PI */
    uint32_t n_faults;                 /* number of faults; 0: none */
    p2d_sim_sensing_config_t sensing;  /* speed sensor, current sensors, field weakening (sensing.h); 0: none */
    p2d_adapt_config_t adapt;          /* inertia estimator and gain scheduling (adapt.h); off when zero */
    p2d_mechanics_config_t mechanics;  /* drive train (plant.h); all zero: rigid, motor-side feedback */
    p2d_filter_config_t speed_filter;  /* torque filters of the speed controller (filter.h); all zero: none */
    p2d_arithmetic_t arithmetic;       /* speed controller: FLOAT32 (0, speed.h), Q15 or Q31 (speed_fixed.h: surface
                                          PMSM, no torque filters, field weakening or gain scheduling) */
    float speed_full_scale_radps;      /* Q15, Q31: speed of the integer 2^N [rad/s], > 0 (speed_fixed.h) */
    float torque_full_scale_Nm;        /* Q15, Q31: torque of the integer 2^N [Nm], > 0 (speed_fixed.h) */
    float current_full_scale_A;        /* Q15, Q31: current of the integer 2^N [A], > 0 (speed_fixed.h) */
} p2d_sim_config_t;

/* The fixed-point speed controller of a drive (arithmetic Q15 or Q31) and its scalings. */
typedef struct {
    p2d_speed_q15_t q15;            /* the Q15 controller (arithmetic Q15) */
    p2d_speed_q31_t q31;            /* the Q31 controller (arithmetic Q31) */
    p2d_speed_q15_output_t out_q15; /* its output of the present speed sample (Q15) */
    p2d_speed_q31_output_t out_q31; /* its output of the present speed sample (Q31) */
    double q_per_radps;             /* speed LSBs per rad/s, 2^N / speed_full_scale_radps [s/rad] */
    double q_max;                   /* largest input 2^N - 1 (the smallest -2^N) [-] */
    double T_lsb_Nm;                /* torque of one LSB, torque_full_scale_Nm 2^-N [Nm] */
    double i_lsb_A;                 /* current of one LSB, current_full_scale_A 2^-N [A] */
} p2d_sim_fixed_t;

typedef struct {
    p2d_sim_config_t cfg;            /* configuration (the schedules are not copied) */
    p2d_speed_t speed;               /* speed controller */
    p2d_current_t current;           /* current controller (DQ_PI) */
    p2d_plant_t plant;               /* PMSM, inverter, drive train and current sensors (plant.h) */
    p2d_schedule_cursor_t reference; /* read position in the reference */
    p2d_schedule_cursor_t load;      /* read position in the load */
    double t_tol_s;                  /* times closer than this are equal: 1e-6 dt [s] */
    double id_ref_A;                 /* current command held over the speed period [A] */
    double iq_ref_A;                 /* current command held over the speed period [A] */
    double w_bound_radps;            /* overspeed bound [rad/s] */
    double i_bound_A;                /* overcurrent bound [A] */
    double i_bound2_A2;              /* its square [A^2] */
    uint64_t n_current;              /* current periods done: t = n_current Ts_current [-] */
    uint64_t n_speed;                /* speed samples done [-] */
    uint64_t n_rows;                 /* log rows written [-] */
    p2d_status_t controller_status;  /* the controller init's code after a *_CONTROLLER error */
    p2d_sim_status_t status;         /* P2D_SIM_OK or the reason of the stop */
    double t_stop_s;                 /* time of the stop [s] */
    double stop_value;               /* offending value (|w_m| [rad/s] or ||i_dq|| [A]) */
    double stop_bound;               /* bound it crossed (same unit) */
    double w_meas_radps;             /* last speed reading given to the speed controller [rad/s] */
    p2d_sim_sensing_t sensing;       /* speed sensor, current measurement and field weakening (sensing.h) */
    p2d_adapt_t adapt;               /* inertia estimator beside the speed controller (adapt.h) */
    bool saturated;                  /* the speed controller's last output was at the current limit */
    bool current_saturated;          /* delay: the current controller limited the command applied next */
    bool dc_link_sag;                /* a DC_LINK_SAG fault is configured */
    p2d_speed_output_t speed_out;    /* the speed controller's output of the present speed sample */
    double w_ref_radps;              /* the reference it sampled [rad/s] */
    uint32_t n_limited;              /* current periods of the present speed sample at the voltage limit [-] */
    bool fma;                        /* run the loop's copy for x86-64 CPUs with FMA (p2d_sim_init: whether the CPU
                                        has it; false: the baseline copy, which computes the same bits) */
    bool speed_special;              /* the speed sample is not the float32 step alone: field weakening, or a
                                        fixed-point controller */
    p2d_sim_fixed_t fixed;           /* the speed controller of arithmetic Q15 or Q31 (speed is then unused) */
} p2d_sim_t;

/* Validate cfg, initialize the controllers and set the initial state. */
p2d_sim_status_t p2d_sim_init(p2d_sim_t *sim, const p2d_sim_config_t *cfg);

/*
 * Run n_samples speed samples, appending rows to the column-major log
 * (P2D_LOG_COUNT columns of log_rows doubles, the same buffer on every call). Returns
 * P2D_SIM_OK or the stop code; after a stop every call returns that code. P2D_SIM_ERR_LOG_FULL
 * (nothing run) when the log has no room for the rows of the n_samples samples (at the current
 * rate: of their n_samples current_per_speed current periods).
 */
p2d_sim_status_t p2d_sim_run(p2d_sim_t *sim, uint64_t n_samples, double *log, uint64_t log_rows);

/*
 * p2d_sim_run of n_sims drives in lockstep, each into its own log (logs[i], log_rows[i] rows):
 * groups of P2D_SIM_LANES drives share one loop, their plants' states in an array per state
 * variable, so that the compiler vectorises the plant's RK4 step across the drives. Each
 * drive's log and state are bit for bit those of p2d_sim_run. The drives must be of one shape
 * (p2d_sim_lockstep), at the same sample; each ends with its own status (sims[i]->status),
 * OK or the stop that ended it. Returns P2D_SIM_OK, P2D_SIM_ERR_NULL,
 * P2D_SIM_ERR_LOCKSTEP (shapes differ; nothing run) or P2D_SIM_ERR_LOG_FULL (a log lacks room;
 * nothing run).
 */
p2d_sim_status_t p2d_sim_run_many(p2d_sim_t *const *sims, uint32_t n_sims, uint64_t n_samples, double *const *logs,
                                  const uint64_t *log_rows);

/*
 * Whether a and b can run in lockstep: both initialized, at the same speed sample, with equal
 * Ts_current_s, current_per_speed, substeps, log_every, log_rate, current model, mechanics model and
 * Coulomb friction (present or not).
 */
bool p2d_sim_lockstep(const p2d_sim_t *a, const p2d_sim_t *b);

/* Name of the configuration field a code rejects ("" for OK and stops). */
const char *p2d_sim_status_param(p2d_sim_status_t status);

/* Valid range of that field, or the reason of a stop. */
const char *p2d_sim_status_text(p2d_sim_status_t status);

/* Name of a log column with its unit, e.g. "w_m_radps" ("" if out of range). */
const char *p2d_sim_log_name(uint32_t column);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_DRIVE_H */
