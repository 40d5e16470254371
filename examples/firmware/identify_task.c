/*
 * Electrical identification on the drive (identify_task.h): a plan of dq
 * current steps in the control interrupt, its configuration, command and
 * report for the XCP master.
 */
#include "identify_task.h"

#include <math.h>

#include "board.h"
#include "foc.h"
#include "pmsm2dof/current.h"
#include "pmsm2dof/transforms.h"

identify_config_t identify_config;   /* the plan (calibration) */
identify_command_t identify_command; /* the master's request (calibration) */
identify_status_t identify_now;      /* the task's report (measurement) */
static identify_config_t plan;       /* the plan taken at the start */
static p2d_current_t current_ctl;    /* the plan's current controller */
static float Ts_s;                   /* control period [s] */
static uint32_t step_samples;        /* interrupts the step under way lasts at most [-] */
static uint32_t step_start;          /* interrupt at which it started [-] */
static uint32_t n;                   /* interrupts since the plan started [-] */
static bool start_request;           /* start the plan at the next control interrupt */
static bool abort_request;           /* end it at the next control interrupt */

void identify_init(float Ts_current_s)
{
    Ts_s = Ts_current_s;
    identify_now.state = IDENTIFY_IDLE;
}

uint16_t identify_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity)
{
    if (capacity < IDENTIFY_SEGMENTS) return 0u;
    segments[0] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&identify_config, &identify_config, sizeof identify_config,
                                      P2D_XCP_CALIBRATION};
    segments[1] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&identify_command, &identify_command,
                                      sizeof identify_command, P2D_XCP_CALIBRATION};
    segments[2] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&identify_now, &identify_now, sizeof identify_now,
                                      P2D_XCP_MEASUREMENT};
    return IDENTIFY_SEGMENTS;
}

bool identify_running(void) { return identify_now.state == IDENTIFY_RUNNING; }

/* A plan within its ranges (identify_config_t). */
static bool plan_valid(const identify_config_t *c)
{
    if (c->n < 1u || c->n > IDENTIFY_STEPS_MAX || !(c->i_trip_A > 0.0f) || !isfinite(c->i_trip_A) ||
        !(c->w_trip_radps > 0.0f) || !isfinite(c->w_trip_radps)) {
        return false;
    }
    for (uint32_t k = 0; k < c->n; ++k) {
        float i2 = c->id_A[k] * c->id_A[k] + c->iq_A[k] * c->iq_A[k];
        if (!(i2 < c->i_trip_A * c->i_trip_A) || !(c->t_s[k] > 0.0f && c->t_s[k] <= IDENTIFY_STEP_MAX_S) ||
            !isfinite(c->w_end_radps[k])) {
            return false;
        }
    }
    return true;
}

int32_t identify_commit(uint16_t index, const void *page, bool busy)
{
    if (index == 0u) {
        /* the plan does not change while it runs; it is written in parts (one DOWNLOAD each, 6 bytes on CAN) and
           checked whole when the start comes */
        return identify_running() ? IDENTIFY_REJECT : 0;
    }
    if (index == 1u) {
        uint32_t command = ((const identify_command_t *)page)->command;
        if (command > 2u || (command == 1u && (busy || identify_running() || !plan_valid(&identify_config)))) {
            return IDENTIFY_REJECT;
        }
        start_request = command == 1u;
        abort_request = command == 2u;
        return 0;
    }
    return IDENTIFY_REJECT;
}

/* The plan's end: its state, zero voltage, the power stage off (by the caller). */
static void finish(uint32_t state, uint32_t reason)
{
    identify_now.state = state;
    identify_now.reason = reason;
    board_write_duties(0.5f, 0.5f, 0.5f);
}

/* Step k starts at interrupt n: its longest time in interrupts. */
static void begin_step(uint32_t k)
{
    identify_now.step = k;
    step_start = n;
    step_samples = (uint32_t)(plan.t_s[k] / Ts_s + 0.5f);
}

/* One interrupt of the plan; false when it ended. */
static bool step(void)
{
    identify_status_t *s = &identify_now;
    p2d_current_output_t cur;
    float ia_A, ib_A, ic_A, i_alpha_A, i_beta_A, id_A, iq_A, theta_m_rad, w_m_radps, theta_e_rad, sin_e, cos_e;
    float u_alpha_V, u_beta_V, u_alpha_app_V, u_beta_app_V, ud_app_V, uq_app_V, id_ref_A, iq_ref_A, w_end_radps;
    float p = (float)foc_speed_config()->pole_pairs, u_dc_V = board_read_dc_link_V();
    uint32_t k = s->step;

    board_read_phase_currents(&ia_A, &ib_A, &ic_A);
    board_read_rotor(&theta_m_rad, &w_m_radps);
    /* theta_e = p theta_m: the currents at the rotor's angle */
    theta_e_rad = p * theta_m_rad;
    sin_e = sinf(theta_e_rad);
    cos_e = cosf(theta_e_rad);
    p2d_clarke(ia_A, ib_A, ic_A, &i_alpha_A, &i_beta_A);
    p2d_park(i_alpha_A, i_beta_A, sin_e, cos_e, &id_A, &iq_A);
    s->sample = n;
    s->t_s = (float)n * Ts_s;
    s->u_dc_V = u_dc_V;
    s->id_A = id_A;
    s->iq_A = iq_A;
    s->w_m_radps = w_m_radps;
    if (!(id_A * id_A + iq_A * iq_A <= plan.i_trip_A * plan.i_trip_A)) {
        finish(IDENTIFY_FAILED, IDENTIFY_REASON_CURRENT);
        return false;
    }
    if (!(fabsf(w_m_radps) <= plan.w_trip_radps)) {
        finish(IDENTIFY_FAILED, IDENTIFY_REASON_SPEED);
        return false;
    }
    /* the step ends after its time, or at its speed in the direction of its q current's torque */
    iq_ref_A = plan.iq_A[k];
    w_end_radps = plan.w_end_radps[k];
    if (n - step_start >= step_samples || (iq_ref_A > 0.0f && w_m_radps >= w_end_radps) ||
        (iq_ref_A < 0.0f && w_m_radps <= w_end_radps)) {
        if (++k == plan.n) {
            finish(IDENTIFY_DONE, IDENTIFY_REASON_NONE);
            return false;
        }
        begin_step(k);
    }
    id_ref_A = plan.id_A[k];
    iq_ref_A = plan.iq_A[k];
    /* the current loop at the rotor's angle and electrical speed w_e = p w_m, through the firmware's modulator */
    p2d_current_compute(&current_ctl, id_ref_A, iq_ref_A, id_A, iq_A, p * w_m_radps, u_dc_V, &cur);
    p2d_inv_park(cur.ud_ref_V, cur.uq_ref_V, sin_e, cos_e, &u_alpha_V, &u_beta_V);
    if (foc_modulate(u_alpha_V, u_beta_V, u_dc_V, &u_alpha_app_V, &u_beta_app_V)) {
        /* the modulator cut the voltage: what it applied, in dq */
        p2d_park(u_alpha_app_V, u_beta_app_V, sin_e, cos_e, &ud_app_V, &uq_app_V);
    } else {
        ud_app_V = cur.ud_ref_V;
        uq_app_V = cur.uq_ref_V;
    }
    p2d_current_update(&current_ctl, &cur, ud_app_V, uq_app_V);
    s->ud_V = ud_app_V;
    s->uq_V = uq_app_V;
    s->fault_count = current_ctl.fault_count;
    n++;
    return true;
}

bool identify_isr(bool silent)
{
    identify_status_t *s = &identify_now;
    if (start_request) {
        start_request = false;
        plan = identify_config;
        /* the firmware's current controller configuration, valid: init accepts it */
        (void)p2d_current_init(&current_ctl, foc_current_config());
        s->state = IDENTIFY_RUNNING;
        s->reason = IDENTIFY_REASON_NONE;
        s->starts++;
        n = 0u;
        begin_step(0u);
    }
    if (s->state != IDENTIFY_RUNNING) {
        abort_request = false;
        return false;
    }
    if (silent || abort_request) {
        abort_request = false;
        finish(silent ? IDENTIFY_TRIPPED : IDENTIFY_ABORTED, IDENTIFY_REASON_NONE);
        return false;
    }
    return step();
}
