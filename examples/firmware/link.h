/*
 * The firmware's XCP link (csrc/include/pmsm2dof/xcp.h): an XCP master
 * (CANape, INCA, pyxcp) measures and calibrates the drive and runs it, through
 * variables that the A2L file of the build describes (`pmsm2dof firmware`
 * writes it from the ELF and the comments below).
 *
 * Memory the master reaches (segments; on the MCU the XCP address is the real one):
 *   measurement  foc_now (foc_signals_t: speeds, currents, torques, integrator,
 *                references, status of the last interrupt), link_status
 *                (the run, the guard, the calibration commits, the DAQ losses),
 *                and the board's own (board_link_segments)
 *   calibration  link_speed_config (p2d_speed_config_t) and
 *                link_current_config (p2d_current_config_t): taken at the next
 *                speed sample through p2d_speed_set_config / p2d_current_set_config
 *                (validating, bumpless); a rejected configuration is answered
 *                ERR_OUT_OF_RANGE and leaves the drive unchanged;
 *                link_command and link_reference: the run control (below);
 *                and the board's own (the virtual board's load schedule);
 *                capture_config (capture.h): a triggered capture into capture_buffer
 *   measurement  capture_status_now, capture_buffer (read after the capture is done)
 *   commissioning commission_config, commission_command (calibration) and
 *                commission_now (measurement): the commissioning routine run
 *                between runs (commission_task.h; code 1004: its page refused)
 *   identification identify_config, identify_command (calibration) and
 *                identify_now (measurement): the electrical identification's
 *                current steps run between runs (identify_task.h; code 1006)
 * Events: 0 "current" (every control interrupt), 1 "speed" (every speed sample),
 * sampled at the end of the interrupt, after the control.
 *
 * Run control. Power-up leaves the drive idle: control interrupt running,
 * power stage off. Writing link_command (one DOWNLOAD of both fields) acts at
 * the next speed sample:
 *   command 1  start a run of `samples` speed samples from the initial state
 *              (foc_start with board_read_start_state; board_run_begin): the
 *              reference plays link_reference from t = 0 (t = k Ts_speed at speed
 *              sample k), the link guard is re-armed, the power stage switched on;
 *              refused (ERR_OUT_OF_RANGE, nothing changes) when a schedule is invalid
 *   command 2  stop: power stage off, state STOPPED
 * A run ends after `samples` samples (DONE, power off), or when the master that
 * started it goes silent for longer than the link timeout: the guard ramps the
 * reference to zero, holds it, then switches the power stage off (TRIPPED,
 * latched until the next start). The master follows link_status.
 *
 * Contexts: link_isr in the control interrupt, link_poll in the background
 * loop; the slave's shared sections run with interrupts off (board_link_lock).
 */
#ifndef LINK_H
#define LINK_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/xcp.h"

/* Most entries of the reference schedule. */
#define LINK_SCHEDULE_MAX 32u

/* The run-control command (calibration): written by the master, taken at the next speed sample. */
typedef struct {
    uint32_t command; /* 1: start a run, 2: stop it, 0: none [-], 0..2 */
    uint32_t samples; /* speed samples of a run started by this command [-], >= 1 */
} link_command_t;

/* The speed reference of a run (calibration): a piecewise-linear schedule (schedule.h). */
typedef struct {
    uint32_t n;                        /* entries in use [-], 0..32 */
    uint32_t reserved;                 /* 0 (alignment of the arrays) [-] */
    double t_s[LINK_SCHEDULE_MAX];     /* time of each entry from the run's start [s], >= 0, nondecreasing */
    double w_radps[LINK_SCHEDULE_MAX]; /* speed reference of each entry [rad/s] */
    double ramp_s[LINK_SCHEDULE_MAX];  /* ramp from the value reached to each entry's [s], >= 0 */
} link_reference_t;

/* States of a run (link_status_t.state). */
enum { LINK_IDLE = 0, LINK_RUNNING = 1, LINK_DONE = 2, LINK_TRIPPED = 3, LINK_STOPPED = 4 };

/* Codes of link_status_t.commit_status that are not a controller's p2d_status_t. */
enum {
    LINK_REJECT_COMMAND = 1001,  /* link_command: an unknown command or samples 0 */
    LINK_REJECT_SCHEDULE = 1002, /* a schedule is invalid, or changed during a run */
    LINK_REJECT_BOARD = 1003,    /* the board refused its page or the run's start, or a routine runs */
    LINK_REJECT_CAPTURE = 1005   /* capture_config: invalid, or a signal outside the readable segments */
};

/* What the link reports (measurement), updated at every speed sample. */
typedef struct {
    uint32_t state;            /* run: 0 idle, 1 running, 2 done, 3 tripped by the link watchdog, 4 stopped [-] */
    uint32_t runs;             /* runs started since power-up [-] */
    uint32_t sample;           /* speed sample k of the run, at t = k Ts_speed [-] */
    uint32_t periods;          /* control interrupts since power-up: the link's clock [-] */
    double t_s;                /* time of the run's speed sample k [s] */
    double w_cmd_radps;        /* the schedule's reference at sample k, before the link guard [rad/s] */
    double w_ref_radps;        /* the reference applied at sample k, after the link guard [rad/s] */
    uint32_t guard_state;      /* link guard: 0 armed, 1 ramping, 2 holding, 3 stopped [-] */
    uint32_t power_on;         /* 1 while the power stage is on [-] */
    uint32_t trip_sample;      /* sample at which the guard left armed in this run (0: not) [-] */
    uint32_t stop_sample;      /* sample at which the guard switched the power stage off (0: not) [-] */
    uint32_t commit_run;       /* the run during which the last calibration took effect [-] */
    uint32_t commit_sample;    /* the speed sample at which it took effect, before the control [-] */
    uint32_t commits_applied;  /* calibration pages taken into force [-] */
    uint32_t commits_rejected; /* calibration pages rejected [-] */
    int32_t commit_status;     /* code of the last rejection: the controller's p2d_status_t, or 1001..1006 [-] */
    uint32_t dtos_lost;        /* DAQ samples dropped for want of room in the DTO queue [-] */
} link_status_t;

/* What link_init needs: the loops, the guard, the initial reference and an optional run at power-up. */
typedef struct {
    double Ts_current_s;        /* control interrupt period, as the board's timer makes it [s], > 0 */
    uint32_t current_per_speed; /* control interrupts per speed sample [-], >= 1 */
    float timeout_s;            /* link watchdog: longest silence of the master of a run [s], >= 0; 0: off */
    float ramp_radps_per_s;     /* guard: deceleration of the reference after a trip [rad/s^2], > 0 */
    float hold_s;               /* guard: zero reference before the power stage is switched off [s], >= 0 */
    uint32_t max_packet_bytes;  /* longest packet the link carries [bytes], 8..255 (SxI, TCP: 255; CAN 8, CAN FD 64) */
    const double *t_s;          /* initial reference schedule: entry times [s] */
    const double *w_radps;      /* its speed references [rad/s] */
    const double *ramp_s;       /* its ramps [s] */
    uint32_t n;                 /* its entries [-], 0..32 */
    uint32_t autostart_samples; /* > 0: a run of that many samples starts at power-up, as if commanded [-] */
} link_config_t;

/* The outcome of link_init. */
typedef struct {
    p2d_xcp_status_t xcp; /* the slave's or the guard's code (p2d_xcp_status_param names the field) */
    bool schedule;        /* false: the initial reference schedule is invalid or too long */
} link_init_status_t;

/*
 * Set up the slave (segments, events; its clock counts control interrupts) and
 * the guard, the drive idle; the initial reference schedule is copied. Call
 * after foc_init and before the control interrupt starts.
 */
link_init_status_t link_init(const link_config_t *cfg);

/* The control interrupt of the linked firmware: commit, guard, reference, foc_isr when running, events. */
void link_isr(void);

/* Background: the received bytes to the slave, its responses and DAQ packets to the link (bounded work). */
void link_poll(void);

/* True while DAQ packets fill more than half the DTO queue (the link does not keep up). */
bool link_daq_backlog(void);

/* The link's report (the measurement segment). */
const link_status_t *link_status(void);

#endif /* LINK_H */
