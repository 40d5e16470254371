/*
 * pmsm2dof: host-only models of what the drive measures and of its field
 * weakening, for the simulation engine (drive.c).
 *
 * Speed sensor (what the speed controller reads at t_k = k Ts_speed):
 *   P2D_SPEED_SENSOR_IDEAL    the true speed w_m(t_k - delay_s);
 *   P2D_SPEED_SENSOR_ENCODER  the hardware counter at t_k - delay_s,
 *                               n = floor(theta_m counts_per_rev / (2 pi)) mod 2^counter_bits,
 *                             read by the C estimator p2d_encoder_step (difference or PLL,
 *                             encoder.h), the code that runs on the MCU;
 * then the low-pass of encoder.h when lowpass_radps > 0 (ideal: the same float32 filter,
 * y[k] = q y[k-1] + (1 - q) w[k]), then white Gaussian noise of noise_rms_radps (seeded) on
 * the reading. The rotor angle theta_m is integrated with the plant (RK4, the angle rate being
 * the speed); it is 0 at t = 0 and the drive turns at w_m0 before, theta_m(t) = w_m0 t for t < 0.
 * A delayed reading interpolates the angle and speed stored at the current-period boundaries
 * by the cubic Hermite polynomial of theta_m through its values and slopes w_m there (the speed
 * is its derivative): exact for a delay that is a multiple of Ts_current; delay_s is at most
 * (P2D_SIM_HISTORY - 2) Ts_current. With the load side fed back (a two-mass train, drive.h),
 * the sensor reads the load angle theta_L = theta_m - theta (the twist, 0 at t = 0) and the
 * load speed w_L instead of theta_m and w_m.
 *
 * Current measurement: the phase-current sensors of the plant (plant.h,
 * p2d_plant_sense_currents) transformed back to dq at the electrical angle
 * th_e = p theta_m,
 *   i_alpha = ia',  i_beta = (ia' + 2 ib') / sqrt(3),
 *   id' = i_alpha cos(th_e) + i_beta sin(th_e),  iq' = -i_alpha sin(th_e) + i_beta cos(th_e);
 * the current controller reads (id', iq') (dq_pi only). An offset I0 on phase a reads as a
 * vector of 2 I0 / sqrt(3) fixed in the stator, a ripple at the electrical frequency in dq.
 *
 * Field weakening: p2d_field_weakening_step (field_weakening.h) at each speed sample with the
 * current controller's last voltage command before its limit and the DC link, and the speed
 * controller's p2d_speed_step_fw with that d-axis current (dq_pi only).
 *
 * Noise: p2d_normal of plant.h, one stream per seed, so that a run is reproduced by its seeds.
 */
#ifndef PMSM2DOF_SIM_SENSING_H
#define PMSM2DOF_SIM_SENSING_H

#include <stdbool.h>
#include <stdint.h>

#include "plant.h"
#include "pmsm2dof/encoder.h"
#include "pmsm2dof/field_weakening.h"
#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Angle and speed stored at the current-period boundaries for a delayed reading (ring length). */
enum { P2D_SIM_HISTORY = 2048 };

/* What the speed sensor reads. */
typedef enum {
    P2D_SPEED_SENSOR_IDEAL = 0,  /* the true speed */
    P2D_SPEED_SENSOR_ENCODER = 1 /* an encoder's counter, read by the C estimator */
} p2d_speed_sensor_model_t;

/* Speed sensor; all zero: the ideal sensor, no delay, no filter, no noise. */
typedef struct {
    p2d_speed_sensor_model_t model; /* ideal or encoder */
    p2d_encoder_config_t encoder;   /* estimator and low-pass (Ts_s = the speed period); ideal: lowpass_radps only */
    double delay_s;                 /* transport delay of the reading [s], >= 0, <= (P2D_SIM_HISTORY - 2) Ts_current */
    double noise_rms_radps;         /* rms of the white Gaussian noise on the reading [rad/s], >= 0 */
    uint64_t seed;                  /* seed of the noise [-] */
} p2d_speed_sensor_config_t;

/* Field weakening in the current reference path. */
typedef struct {
    bool enabled;                        /* false: id_fw = 0 and p2d_speed_step as without it */
    p2d_field_weakening_config_t config; /* the C regulator (Ts_s = the speed period) */
} p2d_sim_field_weakening_config_t;

/* The three in the engine's configuration; all zero: ideal speed sensor, exact currents, no field weakening. */
typedef struct {
    p2d_speed_sensor_config_t speed_sensor;           /* what the speed controller reads */
    p2d_current_sensor_config_t current_sensor;       /* what the current controller reads (plant.h) */
    p2d_sim_field_weakening_config_t field_weakening; /* field weakening in the current reference path */
} p2d_sim_sensing_config_t;

/* State of the models above inside p2d_sim_t. */
typedef struct {
    bool angle;                             /* the rotor angle is integrated (a model needs it) */
    bool history;                           /* the angle and speed are stored for a delayed reading */
    bool current_sensor;                    /* the current controller reads the measured currents */
    p2d_encoder_t encoder;                  /* estimator (ideal: its low-pass coefficients) */
    float w_lowpass_radps;                  /* ideal sensor: low-pass output y[k-1] [rad/s] */
    double w_sensor_radps;                  /* last reading of the sensor, before the faults [rad/s] */
    uint64_t speed_rng;                     /* splitmix64 state of the speed noise [-] */
    p2d_field_weakening_t fw;               /* field-weakening regulator */
    float ud_unsat_V;                       /* current controller's last d voltage before its limit [V] */
    float uq_unsat_V;                       /* current controller's last q voltage before its limit [V] */
    double theta_hist_rad[P2D_SIM_HISTORY]; /* angle at boundary n, at n mod P2D_SIM_HISTORY [rad] */
    double w_hist_radps[P2D_SIM_HISTORY];   /* speed at boundary n, at n mod P2D_SIM_HISTORY [rad/s] */
} p2d_sim_sensing_t;

/* Outcome of p2d_sensing_check: the table at fault. */
typedef enum {
    P2D_SENSING_VALID = 0,          /* all valid */
    P2D_SENSING_BAD_SPEED_SENSOR,   /* speed_sensor: model, delay_s, noise_rms_radps or the encoder */
    P2D_SENSING_BAD_CURRENT_SENSOR, /* current_sensor: not exact without dq_pi (its ranges: plant.h) */
    P2D_SENSING_BAD_FIELD_WEAKENING /* field_weakening: the regulator, or not dq_pi */
} p2d_sensing_check_t;

/*
 * Validate the three configurations for a current period Ts_current_s [s] and a speed period
 * Ts_speed_s [s] (the encoder's and the regulator's Ts_s are taken from it); dq_pi: the current
 * loop is the dq current controller. *status gets the C library's code of an encoder or
 * regulator that its init rejects (else P2D_OK).
 */
p2d_sensing_check_t p2d_sensing_check(const p2d_speed_sensor_config_t *speed,
                                      const p2d_current_sensor_config_t *current,
                                      const p2d_sim_field_weakening_config_t *fw, double Ts_current_s, float Ts_speed_s,
                                      bool dq_pi, p2d_status_t *status);

/*
 * Initialize the state for valid configurations: the encoder reset to the counts at
 * -Ts_speed - delay with the speed w_m0_radps (steady state before t = 0), the regulator at
 * id = 0, the speed noise at its seed, the history with theta_m(0) = 0.
 */
void p2d_sensing_init(p2d_sim_sensing_t *s, const p2d_speed_sensor_config_t *speed,
                      const p2d_current_sensor_config_t *current, const p2d_sim_field_weakening_config_t *fw,
                      float Ts_speed_s, double w_m0_radps);

/*
 * The speed sensor's reading at t_k = n_current Ts_current [s] (a speed sample), after its
 * estimator, low-pass and noise; theta_m_rad, w_m_radps: the plant's angle and speed at t_k.
 * Returns false when the encoder's non-finite policy engaged.
 */
bool p2d_sensing_speed(p2d_sim_sensing_t *s, const p2d_speed_sensor_config_t *speed, uint64_t n_current,
                       double Ts_current_s, double w_m0_radps, double theta_m_rad, double w_m_radps,
                       double *w_read_radps);

/* Store the angle and speed of boundary n_current (when the history is kept). */
void p2d_sensing_record(p2d_sim_sensing_t *s, uint64_t n_current, double theta_m_rad, double w_m_radps);

/* The dq currents the current controller reads, from the plant's current sensors at its angle. */
void p2d_sensing_currents(p2d_plant_t *plant, double *id_meas_A, double *iq_meas_A);

/*
 * Field weakening at a speed sample: the d-axis current bound from the last voltage command
 * before the limit and the DC link u_dc_V [V]. Returns false when its non-finite policy engaged.
 */
bool p2d_sensing_field_weakening(p2d_sim_sensing_t *s, double u_dc_V, float *id_fw_A);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_SIM_SENSING_H */
