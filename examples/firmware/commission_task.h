/*
 * Self-commissioning on the drive: the library's routine (pmsm2dof/commission.h)
 * run by the control interrupt when the XCP master asks for it, between runs.
 *
 * The master writes the routine's configuration (commission_config, a
 * calibration variable: p2d_commission_config_t, validated by
 * p2d_commission_init when it is committed; Ts_s must be the control period),
 * then commission_command.command = 1. At the next speed sample, with no run
 * under way, the routine starts at PROBE with the power stage on; every control
 * interrupt then measures the phase currents in the routine's frame, steps the
 * routine and applies its voltage through the firmware's modulator (foc.h). The
 * master follows commission_now (a measurement variable: the step, its sample
 * count, the signals, the estimates and checks) and reads the estimates once
 * its state is DONE.
 *
 * Safety. The routine itself ends in FAILED with a zero voltage when the
 * current exceeds i_trip_A; DONE and FAILED switch the power stage off. The
 * link watchdog (link.h) applies as during a run: the master that started the
 * routine silent (or gone) for longer than the link timeout ends it at once,
 * whoever else talks, zero voltage and the power stage off (TRIPPED: the
 * rotor, at most at the flux test's speed, coasts).
 * commission_command.command = 2 aborts it the same way (ABORTED). A start is
 * refused while a run or the electrical identification (identify_task.h) is
 * under way, and they while the routine runs.
 */
#ifndef COMMISSION_TASK_H
#define COMMISSION_TASK_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/commission.h"
#include "pmsm2dof/xcp.h"

/*
 * Periods from a current sample to the PWM period that applies its voltage:
 * 0 when the interrupt ends before the next period starts (board.h, Timing),
 * 1 with a computation delay. The initial voltage_delay_samples of
 * commission_config.
 */
#ifndef COMMISSION_VOLTAGE_DELAY_SAMPLES
#define COMMISSION_VOLTAGE_DELAY_SAMPLES 0u
#endif

/* Code of a page the task refuses that is not a p2d_status_t (link_status_t.commit_status). */
#define COMMISSION_REJECT 1004

/* Segments the task adds to the link: commission_config, commission_command, commission_now. */
#define COMMISSION_SEGMENTS 3u

/* States of the task (commission_status_t.state). */
enum {
    COMMISSION_IDLE = 0,    /* never started */
    COMMISSION_RUNNING = 1, /* the routine runs, power on */
    COMMISSION_DONE = 2,    /* ended in DONE: the estimates are valid, power off */
    COMMISSION_FAILED = 3,  /* ended in FAILED: failed_phase, reason; power off */
    COMMISSION_TRIPPED = 4, /* ended by the link watchdog: power off */
    COMMISSION_ABORTED = 5  /* ended by the master (command 2): power off */
};

/* The master's request (calibration), taken at the next speed sample. */
typedef struct {
    uint32_t command; /* 1: start the routine with commission_config, 2: abort it, 0: none [-], 0..2 */
} commission_command_t;

/* What the task reports (measurement), updated at every control interrupt while the routine runs. */
typedef struct {
    uint32_t state;        /* 0 idle, 1 running, 2 done, 3 failed, 4 tripped by the link watchdog, 5 aborted [-] */
    uint32_t starts;       /* routines started since power-up [-] */
    uint32_t phase;        /* the routine's step, p2d_commission_phase_t: 0 probe .. 9 done, 10 failed [-] */
    uint32_t failed_phase; /* the step that failed (state failed) [-] */
    uint32_t reason;       /* why, p2d_commission_reason_t (state failed) [-] */
    uint32_t sample;       /* current samples since the routine started [-] */
    uint32_t phase_start[P2D_PHASE_COUNT]; /* sample at which each step started; 4294967295: not reached [-] */
    uint32_t fault_count;                  /* samples the routine rejected by its non-finite policy [-] */
    float u_dc_V;                          /* DC link of the last control interrupt [V] */
    float id_A;                            /* measured current on the routine's d axis [A] */
    float iq_A;                            /* measured current on the routine's q axis [A] */
    float ud_V;                            /* the routine's d voltage command [V] */
    float uq_V;                            /* the routine's q voltage command [V] */
    float w_e_frame_radps;                 /* the routine's frame speed [rad/s] */
    float w_e_radps;                       /* the rotor's electrical speed, from the position sensor [rad/s] */
    float theta_err_rad;                   /* the rotor's electrical angle less the frame's, in [-pi, pi) [rad] */
    float L_probe_H;                       /* the first inductance, for the routine's current loop [H] */
    float Rs_ohm;                          /* stator resistance [ohm] */
    float u_err_V;                         /* inverter voltage error at i_test_A on d [V] */
    float Ld_H;                            /* d-axis inductance [H] */
    float Lq_H;                            /* q-axis inductance [H] */
    float psi_f_Wb;                        /* permanent-magnet flux linkage [Wb] */
    float rs_spread;                       /* Rs of the late half-windows against the early ones [-] */
    float uq_ratio;                        /* mean q voltage of the Rs levels against their d voltage step [-] */
    float asymmetry;                       /* asymmetry of the admittance matrix of the inductance tests [-] */
    float coherence;                       /* coherence of the active flux in the flux test [-] */
    float psi_spread;                      /* psi_f of the late half-window against the early one [-] */
    float slip;                            /* mean slip of the rotor against the I-f frame [-] */
} commission_status_t;

/* Initialise the task (idle) and its configuration's Ts_s for the control period Ts_current_s [s]. */
void commission_init(float Ts_current_s);

/* The task's segments for the link (address, memory, size, access), at most capacity; returns how many. */
uint16_t commission_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity);

/*
 * Validate and take the master's page of the task's segment index (0 config, 1 command), at a speed
 * sample; run_active: a run of the link is under way. Returns 0 when taken, else a p2d_status_t of
 * p2d_commission_init or COMMISSION_REJECT (an unknown command, a start during a run or while the
 * routine runs, a configuration changed while it runs).
 */
int32_t commission_commit(uint16_t index, const void *page, bool run_active);

/* True while the routine runs. */
bool commission_running(void);

/*
 * The control interrupt when no run of the link is under way: latches the DC link and, while the
 * routine runs, steps it (silent: the link watchdog's verdict ends it). Returns whether the power
 * stage must be on.
 */
bool commission_isr(bool silent);

#endif /* COMMISSION_TASK_H */
