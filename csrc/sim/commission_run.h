/*
 * pmsm2dof: host-only run of the self-commissioning routine
 * (pmsm2dof/commission.h) against a simulated motor, in double precision, so
 * that the firmware routine is tested before it meets a motor.
 *
 * Plant: the dq model of eq 1 in the rotor frame with the rotor's electrical
 * angle theta_e and its mechanics (the plant of drive.h with the angle added),
 *   Ld did/dt   = ud - Rs id + w_e Lq iq
 *   Lq diq/dt   = uq - Rs iq - w_e (Ld id + psi_f)
 *   J dw_m/dt   = 1.5 p (psi_f iq + (Ld - Lq) id iq) - T_load - B w_m - T_c tanh(w_m / w_c)
 *   dtheta_e/dt = w_e = p w_m,
 * w_c as in plant.h, integrated by `substeps` RK4 steps per current period.
 * The routine works in its own frame, whose angle it chooses (alignment, I-f):
 * its command (ud, uq) at the angle out.theta_e_rad is turned into the
 * stationary frame (inverse Park), held over the current period (after one
 * period with computation_delay), plus a dead-time voltage error of
 * -dead_time_V sign(i_x) on each phase x (the phase current's sign at each
 * RK4 stage, amplitude-invariant Clarke), and turned into the rotor frame at
 * the rotor's angle. The routine measures the phase currents a and b, each
 * with Gaussian noise of standard deviation noise_A (seeded generator),
 * c = -a - b, in its frame at its angle c.theta_e_rad of the sample: only what
 * firmware sees. The DC link is u_dc_V; the routine limits its own command to
 * u_dc / sqrt(3).
 *
 * Log: one row for every log_every-th current sample, column-major
 * (P2D_CLOG_COUNT columns of log_rows doubles), as drive.h.
 *
 * Stops: the routine ends (DONE or FAILED: P2D_CRUN_OK, see the routine's
 * phase), the plant state is NaN or infinite (P2D_CRUN_STOP_NONFINITE), or
 * max_samples passed before the routine ended (P2D_CRUN_STOP_TIMEOUT).
 */
#ifndef PMSM2DOF_SIM_COMMISSION_RUN_H
#define PMSM2DOF_SIM_COMMISSION_RUN_H

#include <stdbool.h>
#include <stdint.h>

#include "plant.h"
#include "pmsm2dof/commission.h"
#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Outcome of p2d_commission_run_init (configuration errors) and p2d_commission_run (stops). */
typedef enum {
    P2D_CRUN_OK = 0,
    P2D_CRUN_ERR_NULL,          /* a pointer argument is NULL */
    P2D_CRUN_ERR_POLE_PAIRS,    /* motor.pole_pairs */
    P2D_CRUN_ERR_RS,            /* motor.Rs_ohm */
    P2D_CRUN_ERR_LD,            /* motor.Ld_H */
    P2D_CRUN_ERR_LQ,            /* motor.Lq_H */
    P2D_CRUN_ERR_PSI_F,         /* motor.psi_f_Wb */
    P2D_CRUN_ERR_J,             /* motor.J_kgm2 */
    P2D_CRUN_ERR_B,             /* motor.B_Nms */
    P2D_CRUN_ERR_T_COULOMB,     /* motor.T_coulomb_Nm */
    P2D_CRUN_ERR_U_DC,          /* u_dc_V */
    P2D_CRUN_ERR_SUBSTEPS,      /* substeps */
    P2D_CRUN_ERR_LOG_EVERY,     /* log_every */
    P2D_CRUN_ERR_DEAD_TIME,     /* dead_time_V */
    P2D_CRUN_ERR_NOISE,         /* noise_A */
    P2D_CRUN_ERR_THETA0,        /* theta0_rad */
    P2D_CRUN_ERR_T_LOAD,        /* T_load_Nm */
    P2D_CRUN_ERR_COMMISSIONING, /* p2d_commission_init rejected commissioning: see commission_status */
    P2D_CRUN_ERR_LOG_FULL,      /* the log buffer has no room for the next row */
    P2D_CRUN_STOP_NONFINITE,    /* the plant state is NaN or infinite */
    P2D_CRUN_STOP_TIMEOUT,      /* max_samples passed and the routine had not ended */
    P2D_CRUN_STATUS_COUNT       /* number of codes, not a code */
} p2d_crun_status_t;

/* Columns of a log row of a commissioning run. */
typedef enum {
    P2D_CLOG_T_S = 0,         /* time of the current sample [s] */
    P2D_CLOG_PHASE,           /* phase that computed the command (p2d_commission_phase_t) [-] */
    P2D_CLOG_ID_A,            /* d current measured in the routine's frame [A] */
    P2D_CLOG_IQ_A,            /* q current measured in the routine's frame [A] */
    P2D_CLOG_UD_V,            /* d voltage command in the routine's frame [V] */
    P2D_CLOG_UQ_V,            /* q voltage command in the routine's frame [V] */
    P2D_CLOG_W_E_FRAME_RADPS, /* electrical speed of the routine's frame [rad/s] */
    P2D_CLOG_W_E_RADPS,       /* electrical speed of the rotor p w_m [rad/s] */
    P2D_CLOG_THETA_ERR_RAD,   /* rotor angle minus the frame's, wrapped to [-pi, pi) [rad] */
    P2D_CLOG_COUNT            /* number of columns, not a column */
} p2d_clog_column_t;

/* The motor of a commissioning run: its parameters, coefficients precomputed at init, and its state. */
typedef struct {
    double pole_pairs;        /* pole pairs p [-] */
    double Rs_ohm;            /* stator resistance [ohm] */
    double Ld_H;              /* d-axis inductance [H] */
    double Lq_H;              /* q-axis inductance [H] */
    double psi_f_Wb;          /* flux linkage [Wb] */
    double inv_Ld_per_H;      /* 1 / Ld [1/H] */
    double inv_Lq_per_H;      /* 1 / Lq [1/H] */
    double inv_J_per_kgm2;    /* 1 / J [1/(kg m^2)] */
    double kt_Nm_per_A;       /* 1.5 p psi_f [Nm/A] */
    double c_T_Nm_per_A2;     /* 1.5 p (Ld - Lq) [Nm/A^2] */
    double B_Nms;             /* viscous friction [Nm s/rad] */
    double T_coulomb_Nm;      /* Coulomb friction [Nm] */
    double inv_w_c_s_per_rad; /* 1 / w_c, friction smoothing band of plant.h [s/rad] */
    double id_A;              /* state: d-axis current [A] */
    double iq_A;              /* state: q-axis current [A] */
    double w_m_radps;         /* state: mechanical speed [rad/s] */
} p2d_crun_pmsm_t;

/* Everything a commissioning run needs. */
typedef struct {
    p2d_pmsm_params_t motor;               /* true plant (plant.h) */
    double u_dc_V;                         /* DC-link voltage [V], > 0 */
    bool computation_delay;                /* the inverter applies the command one current period later */
    uint32_t substeps;                     /* RK4 steps per current period [-], >= 1 */
    uint32_t log_every;                    /* log one current sample in log_every [-], >= 1 */
    double dead_time_V;                    /* dead-time voltage error per phase [V], finite, >= 0 */
    double noise_A;                        /* standard deviation of each measured phase current [A], finite, >= 0 */
    uint64_t seed;                         /* seed of the measurement noise [-] */
    double theta0_rad;                     /* initial electrical angle of the rotor [rad], finite */
    double T_load_Nm;                      /* constant load torque [Nm], finite */
    p2d_commission_config_t commissioning; /* the routine's configuration */
} p2d_crun_config_t;

typedef struct {
    p2d_crun_config_t cfg;          /* configuration */
    p2d_commission_t routine;       /* the firmware routine under test */
    p2d_crun_pmsm_t pmsm;           /* plant: parameters and id, iq, w_m */
    double theta_e_rad;             /* state: rotor electrical angle [rad], in [0, 2 pi) */
    double dt_s;                    /* RK4 step Ts / substeps [s] */
    double ua_next_V;               /* delay: alpha voltage for the next period [V] */
    double ub_next_V;               /* delay: beta voltage for the next period [V] */
    uint64_t rng;                   /* noise generator state (xorshift64*) [-] */
    uint64_t n;                     /* current samples done [-] */
    uint64_t n_rows;                /* log rows written [-] */
    uint64_t phase_start[11];       /* sample at which each phase (p2d_commission_phase_t, P2D_PHASE_COUNT
                                            of them) started; UINT64_MAX: not reached [samples] */
    p2d_status_t commission_status; /* p2d_commission_init's code after P2D_CRUN_ERR_COMMISSIONING */
    p2d_crun_status_t status;       /* P2D_CRUN_OK or the reason of the stop */
} p2d_crun_t;

/* Validate cfg, initialize the routine and set the rotor at rest at theta0_rad. */
p2d_crun_status_t p2d_commission_run_init(p2d_crun_t *run, const p2d_crun_config_t *cfg);

/*
 * Step the routine and the plant until the routine ends or max_samples current
 * samples in all have passed, appending rows to the log (P2D_CLOG_COUNT columns
 * of log_rows doubles, the same buffer on every call).
 */
p2d_crun_status_t p2d_commission_run(p2d_crun_t *run, uint64_t max_samples, double *log, uint64_t log_rows);

/* Name of the configuration field a code rejects ("" for OK and stops). */
const char *p2d_crun_status_param(p2d_crun_status_t status);

/* Valid range of that field, or the reason of a stop. */
const char *p2d_crun_status_text(p2d_crun_status_t status);

/* Name of a log column with its unit ("" if out of range). */
const char *p2d_crun_log_name(uint32_t column);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_COMMISSION_RUN_H */
