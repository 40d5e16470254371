/*
 * Self-commissioning on the drive (commission_task.h): the library's routine in
 * the control interrupt, its configuration, command and report for the XCP
 * master.
 */
#include "commission_task.h"

#include <math.h>

#include "board.h"
#include "foc.h"
#include "pmsm2dof/transforms.h"

#define CT_PI 3.14159265f     /* pi */
#define CT_TWO_PI 6.28318531f /* 2 pi */

p2d_commission_config_t commission_config; /* the routine's configuration (calibration) */
commission_command_t commission_command;   /* the master's request (calibration) */
commission_status_t commission_now;        /* the task's report (measurement) */
static p2d_commission_t routine;           /* the routine's state */
static p2d_commission_t scratch;           /* a configuration validated before it is taken */
static bool start_request;                 /* start the routine at the next control interrupt */
static bool abort_request;                 /* end it at the next control interrupt */

void commission_init(float Ts_current_s)
{
    commission_config.Ts_s = Ts_current_s;
    commission_config.voltage_delay_samples = COMMISSION_VOLTAGE_DELAY_SAMPLES;
    commission_now.state = COMMISSION_IDLE;
}

uint16_t commission_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity)
{
    if (capacity < COMMISSION_SEGMENTS) return 0u;
    segments[0] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&commission_config, &commission_config,
                                      sizeof commission_config, P2D_XCP_CALIBRATION};
    segments[1] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&commission_command, &commission_command,
                                      sizeof commission_command, P2D_XCP_CALIBRATION};
    segments[2] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&commission_now, &commission_now, sizeof commission_now,
                                      P2D_XCP_MEASUREMENT};
    return COMMISSION_SEGMENTS;
}

bool commission_running(void) { return commission_now.state == COMMISSION_RUNNING; }

int32_t commission_commit(uint16_t index, const void *page, bool run_active)
{
    if (index == 0u) {
        const p2d_commission_config_t *cfg = (const p2d_commission_config_t *)page;
        p2d_status_t st;
        /* the routine's parameters do not change while it runs (commission.h) */
        if (commission_running()) return COMMISSION_REJECT;
        if (cfg->Ts_s != commission_config.Ts_s) return (int32_t)P2D_ERR_TS;
        st = p2d_commission_init(&scratch, cfg);
        return st == P2D_OK ? 0 : (int32_t)st;
    }
    if (index == 1u) {
        uint32_t command = ((const commission_command_t *)page)->command;
        if (command > 2u || (command == 1u && (run_active || commission_running()))) return COMMISSION_REJECT;
        start_request = command == 1u;
        abort_request = command == 2u;
        return 0;
    }
    return COMMISSION_REJECT;
}

/* The routine's end: its state, the power stage off. */
static void finish(uint32_t state)
{
    commission_now.state = state;
    board_write_duties(0.5f, 0.5f, 0.5f);
}

/* The routine's results into the report. */
static void report_estimates(void)
{
    commission_status_t *s = &commission_now;
    s->sample++;
    /* the step the routine is in now started with the next sample */
    if ((uint32_t)routine.phase != s->phase) s->phase_start[routine.phase] = s->sample;
    s->phase = (uint32_t)routine.phase;
    s->failed_phase = (uint32_t)routine.failed_phase;
    s->reason = (uint32_t)routine.reason;
    s->fault_count = routine.fault_count;
    s->L_probe_H = routine.L_probe_H;
    s->Rs_ohm = routine.Rs_ohm;
    s->u_err_V = routine.u_err_V;
    s->Ld_H = routine.Ld_H;
    s->Lq_H = routine.Lq_H;
    s->psi_f_Wb = routine.psi_f_Wb;
    s->rs_spread = routine.rs_spread;
    s->uq_ratio = routine.uq_ratio;
    s->asymmetry = routine.asymmetry;
    s->coherence = routine.coherence;
    s->psi_spread = routine.psi_spread;
    s->slip = routine.slip;
}

/* One sample of the routine: currents in its frame, its step, its voltage through the modulator. */
static void step(float u_dc_V)
{
    commission_status_t *s = &commission_now;
    p2d_commission_output_t out;
    float ia_A, ib_A, ic_A, i_alpha_A, i_beta_A, id_A, iq_A, u_alpha_V, u_beta_V, u_alpha_app_V, u_beta_app_V;
    float theta_m_rad, w_m_radps, p = (float)foc_speed_config()->pole_pairs, err_rad;
    float frame_rad = routine.theta_e_rad;

    board_read_phase_currents(&ia_A, &ib_A, &ic_A);
    board_read_rotor(&theta_m_rad, &w_m_radps);
    p2d_clarke(ia_A, ib_A, ic_A, &i_alpha_A, &i_beta_A);
    /* the currents in the routine's frame at its angle of this sample */
    p2d_park(i_alpha_A, i_beta_A, sinf(frame_rad), cosf(frame_rad), &id_A, &iq_A);
    p2d_commission_step(&routine, id_A, iq_A, u_dc_V, &out);
    /* the command at the angle the routine asks for, through the firmware's modulator */
    p2d_inv_park(out.ud_V, out.uq_V, sinf(out.theta_e_rad), cosf(out.theta_e_rad), &u_alpha_V, &u_beta_V);
    (void)foc_modulate(u_alpha_V, u_beta_V, u_dc_V, &u_alpha_app_V, &u_beta_app_V);

    /* theta_err = p theta_m - theta_frame, wrapped to [-pi, pi) */
    err_rad = p * theta_m_rad - frame_rad;
    err_rad -= CT_TWO_PI * floorf((err_rad + CT_PI) / CT_TWO_PI);
    s->id_A = id_A;
    s->iq_A = iq_A;
    s->ud_V = out.ud_V;
    s->uq_V = out.uq_V;
    s->w_e_frame_radps = out.w_e_radps;
    s->w_e_radps = p * w_m_radps;
    s->theta_err_rad = err_rad;
    report_estimates();
}

bool commission_isr(bool silent)
{
    commission_status_t *s = &commission_now;
    float u_dc_V = board_read_dc_link_V();
    s->u_dc_V = u_dc_V;
    if (start_request) {
        start_request = false;
        /* validated when committed: init accepts it */
        (void)p2d_commission_init(&routine, &commission_config);
        s->state = COMMISSION_RUNNING;
        s->starts++;
        s->sample = 0u;
        s->phase = (uint32_t)P2D_PHASE_PROBE;
        for (uint32_t i = 0; i < (uint32_t)P2D_PHASE_COUNT; ++i) s->phase_start[i] = UINT32_MAX;
        s->phase_start[P2D_PHASE_PROBE] = 0u;
    }
    if (s->state != COMMISSION_RUNNING) {
        abort_request = false;
        return false;
    }
    if (silent || abort_request) {
        abort_request = false;
        finish(silent ? COMMISSION_TRIPPED : COMMISSION_ABORTED);
        return false;
    }
    step(u_dc_V);
    if (routine.phase == P2D_PHASE_DONE || routine.phase == P2D_PHASE_FAILED) {
        finish(routine.phase == P2D_PHASE_DONE ? COMMISSION_DONE : COMMISSION_FAILED);
        return false;
    }
    return true;
}
