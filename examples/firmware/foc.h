/*
 * Field-oriented control with the pmsm2dof controllers (paper Fig. 1): the
 * current loop at every control interrupt (1 / Ts_current), the speed loop at
 * every P2D_CONFIG_CURRENT_PER_SPEED-th, both configured by p2d_config.h (the
 * header `pmsm2dof header SCENARIO --out p2d_config.h` writes; every command
 * that writes a header writes this shape).
 */
#ifndef FOC_H
#define FOC_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/current.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/status.h"

/* Most current periods per speed period the firmware accepts (the engine's bound is far higher). */
#define FOC_CURRENT_PER_SPEED_MAX 1000u

/* The part of the configuration that foc_init rejected. */
typedef enum {
    FOC_OK = 0,              /* everything accepted */
    FOC_ERR_SPEED,           /* p2d_config_speed (p2d_speed_init) */
    FOC_ERR_SPEED_FILTER,    /* p2d_config_speed_filter (p2d_speed_set_filter) */
    FOC_ERR_CURRENT,         /* p2d_config_current (p2d_current_init) */
    FOC_ERR_ENCODER,         /* p2d_config_encoder (p2d_encoder_init) */
    FOC_ERR_FIELD_WEAKENING, /* p2d_config_field_weakening (p2d_field_weakening_init) */
    FOC_ERR_INERTIA,         /* p2d_config_inertia (p2d_inertia_init) */
    FOC_ERR_LOOP_RATIO       /* speed Ts_s != P2D_CONFIG_CURRENT_PER_SPEED * current Ts_s, or the ratio out of range */
} foc_part_t;

/* Outcome of foc_init. */
typedef struct {
    foc_part_t part;     /* the rejected part, FOC_OK when none */
    p2d_status_t status; /* the library's code for it (p2d_status_param names the field); P2D_OK otherwise */
} foc_status_t;

/*
 * What the control computed at the last interrupt: the measurement variables
 * a trace, a debugger or an XCP master reads (written by foc_isr only; the
 * variable foc_now, which the A2L file of the build describes).
 */
typedef struct {
    bool speed_sample;    /* this interrupt ran the speed loop [-] */
    float w_ref_radps;    /* speed reference of the last speed sample [rad/s] */
    float w_meas_radps;   /* speed reading of the last speed sample (after the encoder estimator) [rad/s] */
    float T_unsat_Nm;     /* speed controller's torque before the limit (after the torque filters) [Nm] */
    float T_ref_Nm;       /* speed controller's torque after the current limit [Nm] */
    float id_ref_A;       /* d-axis current reference, held between speed samples [A] */
    float iq_ref_A;       /* q-axis current reference, held between speed samples [A] */
    bool saturated;       /* the speed controller's current limit is active [-] */
    float x_i_Nm;         /* speed PI integral after the last update [Nm] */
    float id_fw_A;        /* field weakening's d-axis current bound (0 without it) [A] */
    float id_A;           /* measured d-axis current of this interrupt [A] */
    float iq_A;           /* measured q-axis current of this interrupt [A] */
    float ud_ref_V;       /* d-axis voltage command of this interrupt [V] */
    float uq_ref_V;       /* q-axis voltage command of this interrupt [V] */
    bool voltage_limited; /* the current controller cut its voltage to u_dc / sqrt(3) [-] */
    float J_est_kgm2;     /* inertia estimate (0 without the estimator) [kg m^2] */
    bool J_valid;         /* the inertia estimate is valid [-] */
    float T_load_est_Nm;  /* load-torque estimate [Nm] */
    float J_gains_kgm2;   /* inertia the speed controller's gains are designed for [kg m^2] */
    uint32_t fault_count; /* samples a controller refused by its non-finite policy [-] */
} foc_signals_t;

/* The signals of the last interrupt (foc_signals() points to it). */
extern foc_signals_t foc_now;

/*
 * Initialize every controller from p2d_config.h. Returns the first part
 * rejected; then never start the control interrupt nor the power stage.
 */
foc_status_t foc_init(void);

/*
 * The state the control starts from, before the control interrupt starts: the
 * motor at the speed w_m_radps [rad/s] held by the torque T_Nm [Nm] (a drive at
 * rest: 0, 0; a flying start: the measured speed). The speed controller is set
 * bumpless there with its reference at w_m_radps (p2d_speed_reset), the current
 * integrators at the steady-state voltage of the currents that torque needs,
 * the encoder estimator at that speed, the field weakening at id = 0.
 */
void foc_start(float w_m_radps, float T_Nm);

/* The period of the control interrupt, Ts_s of p2d_config_current [s]. */
float foc_current_period_s(void);

/* The speed reference of the next speed samples [rad/s] (the application's: the link plays it). */
void foc_set_speed_reference(float w_ref_radps);

/*
 * Take a new configuration of the speed controller (p2d_speed_set_config: validated, bumpless,
 * state kept) or of the current controller (p2d_current_set_config). Ts_s (and the speed
 * controller's pole_pairs) must be the firmware's: else P2D_ERR_TS (P2D_ERR_POLE_PAIRS). On an
 * error nothing changes. Call in the control interrupt, before foc_isr.
 */
p2d_status_t foc_set_speed_config(const p2d_speed_config_t *cfg);
p2d_status_t foc_set_current_config(const p2d_current_config_t *cfg);

/* The configurations in force. */
const p2d_speed_config_t *foc_speed_config(void);
const p2d_current_config_t *foc_current_config(void);

/*
 * Space-vector modulation by min-max zero-sequence injection: linear for
 * ||u_ab|| <= u_dc / sqrt(3), the limit the current controller enforces.
 * Writes the duty cycles; returns true when a duty had to be clipped to
 * [0, 1], and then in *u_alpha_app_V, *u_beta_app_V the voltage actually
 * applied. Control interrupt only.
 */
bool foc_modulate(float u_alpha_V, float u_beta_V, float u_dc_V, float *u_alpha_app_V, float *u_beta_app_V);

/* The control interrupt: call at 1 / Ts_current, from the PWM or ADC interrupt. */
void foc_isr(void);

/* The signals of the last interrupt. */
const foc_signals_t *foc_signals(void);

#endif /* FOC_H */
