/*
 * Electrical identification on the drive: a plan of current steps run by the
 * control interrupt when the XCP master asks for it, between runs, for the
 * host's fit of eq 1 (`pmsm2dof drive identify --electrical`).
 *
 * The master writes the plan (identify_config, a calibration variable: the
 * steps' dq current references, their longest times and speed bounds, the
 * trips; in as many DOWNLOADs as it takes), then identify_command.command = 1,
 * refused unless the plan is valid whole. At the next speed sample, with
 * no run nor commissioning under way, the routine starts at step 0 with the
 * power stage on: every control interrupt measures the phase currents at the
 * rotor's angle (the position sensor), runs a current controller of the
 * library (current.h, configured as the firmware's: link_current_config)
 * towards the step's references and applies its voltage through the
 * firmware's modulator (foc.h). A step ends after its time, or earlier when
 * the rotor's speed reaches the step's w_end_radps in the direction of its q
 * current's torque (iq > 0: w_m >= w_end; iq < 0: w_m <= w_end): q-current
 * steps that turn the rotor between two speeds whatever its inertia. After
 * the last step the routine ends DONE, power off. The master captures
 * identify_now (its time t_s, the dq currents, the voltage applied, the speed)
 * at the current period with the capture buffer (capture.h), a window a run,
 * by a rising trigger on identify_now.t_s.
 *
 * Safety. |i_dq| above i_trip_A or |w_m| above w_trip_radps ends the routine
 * at once (FAILED, zero voltage, power off). The link watchdog (link.h)
 * applies as to a run: the master that started the routine silent for longer
 * than the link timeout ends it at once, zero voltage and the power stage off
 * (TRIPPED: the rotor coasts from at most the plan's speed);
 * identify_command.command = 2 aborts it the same way (ABORTED). A start is
 * refused while a run or the commissioning is under way, and they while the
 * routine runs.
 */
#ifndef IDENTIFY_TASK_H
#define IDENTIFY_TASK_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/xcp.h"

/* Most steps of a plan. */
#define IDENTIFY_STEPS_MAX 16u

/* Longest step [s]. */
#define IDENTIFY_STEP_MAX_S 10.0f

/* Code of a page the task refuses (link_status_t.commit_status). */
#define IDENTIFY_REJECT 1006

/* Segments the task adds to the link: identify_config, identify_command, identify_now. */
#define IDENTIFY_SEGMENTS 3u

/* States of the task (identify_status_t.state). */
enum {
    IDENTIFY_IDLE = 0,    /* never started */
    IDENTIFY_RUNNING = 1, /* the plan runs, power on */
    IDENTIFY_DONE = 2,    /* every step played: power off */
    IDENTIFY_FAILED = 3,  /* a trip (reason): power off */
    IDENTIFY_TRIPPED = 4, /* ended by the link watchdog: power off */
    IDENTIFY_ABORTED = 5  /* ended by the master (command 2): power off */
};

/* Why a plan failed (identify_status_t.reason). */
enum { IDENTIFY_REASON_NONE = 0, IDENTIFY_REASON_CURRENT = 1, IDENTIFY_REASON_SPEED = 2 };

/* The plan (calibration): written in parts between plays, checked whole by the start command, taken at the start. */
typedef struct {
    uint32_t n;                            /* steps in use [-], 1..16 */
    float i_trip_A;                        /* |i_dq| that ends the routine [A], > 0 */
    float w_trip_radps;                    /* |w_m| that ends the routine [rad/s], > 0 */
    float id_A[IDENTIFY_STEPS_MAX];        /* d-axis current reference of each step [A], |i_dq| < i_trip_A */
    float iq_A[IDENTIFY_STEPS_MAX];        /* q-axis current reference of each step [A] */
    float t_s[IDENTIFY_STEPS_MAX];         /* longest time of each step [s], (0, 10] */
    float w_end_radps[IDENTIFY_STEPS_MAX]; /* speed that ends a step with iq != 0 early [rad/s], finite */
} identify_config_t;

/* The master's request (calibration), taken at the next speed sample. */
typedef struct {
    uint32_t command; /* 1: start the plan of identify_config, 2: abort it, 0: none [-], 0..2 */
} identify_command_t;

/* What the task reports (measurement), updated at every control interrupt while the plan runs. */
typedef struct {
    uint32_t state;       /* 0 idle, 1 running, 2 done, 3 failed, 4 tripped by the link watchdog, 5 aborted [-] */
    uint32_t starts;      /* plans started since power-up [-] */
    uint32_t step;        /* the step of the last interrupt [-] */
    uint32_t reason;      /* why it failed: 0 none, 1 current above i_trip_A, 2 speed above w_trip_radps [-] */
    uint32_t sample;      /* control interrupts since the plan started (the last one's index) [-] */
    float t_s;            /* time of the last interrupt since the plan started, sample Ts_current [s] */
    float u_dc_V;         /* DC link of the last interrupt [V] */
    float id_A;           /* measured d-axis current at the rotor's angle [A] */
    float iq_A;           /* measured q-axis current [A] */
    float ud_V;           /* d-axis voltage applied over the period that starts at this interrupt [V] */
    float uq_V;           /* q-axis voltage applied over that period [V] */
    float w_m_radps;      /* the rotor's mechanical speed from the position sensor [rad/s] */
    uint32_t fault_count; /* samples the current controller rejected by its non-finite policy [-] */
} identify_status_t;

/* Initialise the task (idle) for the control period Ts_current_s [s]. */
void identify_init(float Ts_current_s);

/* The task's segments for the link (address, memory, size, access), at most capacity; returns how many. */
uint16_t identify_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity);

/*
 * Validate and take the master's page of the task's segment index (0 plan, 1 command), at a speed
 * sample; busy: a run or the commissioning is under way. Returns 0 when taken, else IDENTIFY_REJECT
 * (a plan changed while it runs, an unknown command, a start while busy or running or with a plan out
 * of its ranges).
 */
int32_t identify_commit(uint16_t index, const void *page, bool busy);

/* True while the plan runs. */
bool identify_running(void);

/*
 * The control interrupt when no run of the link is under way: while the plan runs, steps it
 * (silent: the link watchdog's verdict ends it). Returns whether the power stage must be on.
 */
bool identify_isr(bool silent);

#endif /* IDENTIFY_TASK_H */
