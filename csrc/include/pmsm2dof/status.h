/*
 * pmsm2dof: the status codes of every controller init and parameter update,
 * and the types the controllers share (discretization method, anti-windup
 * mode, coefficients of a discrete PI).
 *
 * Each error code names exactly one configuration field, so that callers
 * (the Python bindings, firmware diagnostics) can report which parameter was
 * rejected and what its valid range is, without parsing text.
 */
#ifndef PMSM2DOF_STATUS_H
#define PMSM2DOF_STATUS_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    P2D_OK = 0,
    P2D_ERR_NULL,        /* a pointer argument is NULL */
    P2D_ERR_J,           /* J_kgm2 */
    P2D_ERR_ALPHA,       /* alpha_radps */
    P2D_ERR_ZETA,        /* zeta */
    P2D_ERR_M,           /* m */
    P2D_ERR_M_LOWPASS,   /* m must be 1 with the lowpass feedforward (eq 13) */
    P2D_ERR_TAU_I,       /* tau_i_s */
    P2D_ERR_KA,          /* Ka */
    P2D_ERR_TS,          /* Ts_s */
    P2D_ERR_TS_UNSTABLE, /* Ts_s too large: forward-Euler filter pole leaves the unit circle */
    P2D_ERR_I_MAX,       /* i_max_A */
    P2D_ERR_POLE_PAIRS,  /* pole_pairs */
    P2D_ERR_PSI_F,       /* psi_f_Wb */
    P2D_ERR_LD,          /* Ld_H */
    P2D_ERR_LQ,          /* Lq_H */
    P2D_ERR_RS,          /* Rs_ohm */
    P2D_ERR_METHOD,      /* method */
    P2D_ERR_FEEDFORWARD, /* feedforward */
    P2D_ERR_ANTI_WINDUP, /* anti_windup */
    /* commissioning (commission.h) */
    P2D_ERR_I_TEST,        /* i_test_A */
    P2D_ERR_I_SPIN,        /* i_spin_A */
    P2D_ERR_I_TRIP,        /* i_trip_A */
    P2D_ERR_T_ALIGN,       /* t_align_s */
    P2D_ERR_T_LEVEL,       /* t_level_s */
    P2D_ERR_T_INDUCTANCE,  /* t_inductance_s */
    P2D_ERR_T_RAMP,        /* t_ramp_s */
    P2D_ERR_T_SPIN,        /* t_spin_s */
    P2D_ERR_W_E_SPIN,      /* w_e_spin_radps */
    P2D_ERR_VOLTAGE_DELAY, /* voltage_delay_samples */
    /* speed from an encoder (encoder.h) */
    P2D_ERR_ENC_COUNTS_PER_REV, /* counts_per_rev */
    P2D_ERR_ENC_COUNTER_BITS,   /* counter_bits */
    P2D_ERR_ENC_ESTIMATOR,      /* estimator */
    P2D_ERR_ENC_BANDWIDTH,      /* bandwidth_radps */
    P2D_ERR_ENC_LOWPASS,        /* lowpass_radps */
    /* field weakening (field_weakening.h) */
    P2D_ERR_FW_KP,            /* Kp_A_per_V */
    P2D_ERR_FW_KI,            /* Ki_A_per_Vs */
    P2D_ERR_FW_KA,            /* Ka_V_per_A */
    P2D_ERR_FW_VOLTAGE_RATIO, /* voltage_ratio */
    P2D_ERR_FW_ID_MIN,        /* id_min_A */
    /* inertia estimator (inertia.h) */
    P2D_ERR_J0,           /* J0_kgm2 */
    P2D_ERR_J_MIN,        /* J_min_kgm2 */
    P2D_ERR_J_MAX,        /* J_max_kgm2 */
    P2D_ERR_B_MAX,        /* B_max_Nms */
    P2D_ERR_T_LOAD_MAX,   /* T_load_max_Nm */
    P2D_ERR_SIGMA_T,      /* sigma_T_Nm */
    P2D_ERR_J_MEMORY,     /* J_memory_s */
    P2D_ERR_LOAD_MEMORY,  /* load_memory_s */
    P2D_ERR_W_F,          /* w_f_radps */
    P2D_ERR_J_REL_SD_MAX, /* J_rel_sd_max */
    /* torque filters (filter.h) */
    P2D_ERR_NOTCH_FREQ,   /* notch_freq_Hz */
    P2D_ERR_NOTCH_WIDTH,  /* notch_width_Hz */
    P2D_ERR_NOTCH_DEPTH,  /* notch_depth */
    P2D_ERR_LOWPASS_FREQ, /* lowpass_freq_Hz */
    P2D_ERR_LOWPASS_ZETA, /* lowpass_zeta */
    /* fixed-point speed controllers (speed_fixed.h) */
    P2D_ERR_SPEED_FULL_SCALE,   /* speed_full_scale_radps */
    P2D_ERR_TORQUE_FULL_SCALE,  /* torque_full_scale_Nm */
    P2D_ERR_CURRENT_FULL_SCALE, /* current_full_scale_A */
    P2D_ERR_SALIENT,            /* Lq_H: equal to Ld_H (surface PMSM) */
    P2D_STATUS_COUNT            /* number of codes, not a code */
} p2d_status_t;

/* Name of the configuration field that a status code rejects ("" for P2D_OK). */
const char *p2d_status_param(p2d_status_t status);

/* Human-readable valid range of that field, e.g. "finite and > 0". */
const char *p2d_status_range(p2d_status_t status);

/* Discretization of every dynamic part (paper Table 1). */
typedef enum {
    P2D_FORWARD_EULER = 0,  /* s = (z - 1) / Ts */
    P2D_BACKWARD_EULER = 1, /* s = (z - 1) / (z Ts) */
    P2D_TUSTIN = 2          /* s = 2 (z - 1) / (Ts (z + 1)), eq 14 and 15 */
} p2d_method_t;

/* Integrator anti-windup (paper section 3.2, Fig. 5). */
typedef enum {
    P2D_AW_NONE = 0,             /* plain integrator: winds up */
    P2D_AW_BACK_CALCULATION = 1, /* dx_i/dt = Ki (e + Ka u*), u* = u_sat - u */
    P2D_AW_CLAMPING = 2          /* conditional integration: hold while the limit is active
                                    and the error would drive further into it */
} p2d_anti_windup_t;

/*
 * Coefficients of one discrete PI, u[k] = b_e0 e[k] + x[k-1],
 * x[k] = x[k-1] + Ki Ts e[k] + Ki Ka Ts u*[k] (eq 14, Table 1, Fig. 5). Units
 * with e in [E] and u in [U]: [U] = [Nm], [E] = [rad/s] in the speed
 * controller; [U] = [V], [E] = [A] in the current controller.
 */
typedef struct {
    float Kp;       /* proportional gain [U/E] */
    float Ki;       /* integral gain [U/(E s)] */
    float b_e0;     /* weight of e[k] in u[k]: Kp, Kp + Ki Ts or Kp + Ki Ts / 2 by method [U/E] */
    float Ki_Ts;    /* integrator increment per unit of error [U/E] */
    float Ki_Ka_Ts; /* integrator increment per unit of u* [-]; 0 unless back calculation */
} p2d_pi_coef_t;

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_STATUS_H */
