/*
 * A virtual board: board.h implemented by the simulation engine's plant
 * (csrc/sim/plant.c, the same source: the PMSM of eq 1, the inverter, the
 * drive train with friction, the current sensors and the encoder) and the
 * scenario's reference and load schedules, all from p2d_virtual_drive.h
 * (written by `pmsm2dof firmware` from the scenario). The firmware (main.c,
 * foc.c) runs on it unchanged, closed loop, on the MCU under QEMU or on the PC
 * (virtual_target.h: the machine's interrupt, output and exit).
 *
 * Every control interrupt (period n, t_n = n Ts_current):
 *   foc_isr() reads the sensors latched at t_n and writes the duties;
 *   then, the interrupt's clock held (vt_hold: the motor takes no firmware time),
 *   the inverter turns the duties into the stator voltage
 *     u_alpha = u_dc (2 d_a - d_b - d_c) / 3,  u_beta = u_dc (d_b - d_c) / sqrt(3),
 *   and that into the rotor frame at the electrical angle th_e(t_n) the firmware
 *   sampled, ud + j uq = e^(-j th_e) (u_alpha + j u_beta), which the plant
 *   holds in the rotor frame over the period (p2d_plant_command: the engine's
 *   inverter, limited to u_dc / sqrt(3), with its computation delay); the plant
 *   is integrated to t_n+1 (RK4 steps split at the load's breakpoints, the load
 *   linear over each, as the engine does), and the sensors are latched for t_n+1.
 * This is the engine's sampled-data loop (csrc/sim/drive.h) with the firmware in
 * place of its controllers, so the trace compares with the engine's
 * simulation of the same scenario. The rotor angle and speed the firmware reads
 * for its transforms are the motor's (an ideal position sensor), as the engine's
 * current loop sees them; the speed loop reads the side mechanics.feedback
 * names (the motor, or the load of a two-mass train), as the speed or, in an
 * encoder scenario, as the plant's counter (p2d_plant_encoder_count). Not modelled here (the engine has them): faults, a
 * delay or noise on the speed reading, the current loop of eq 3.
 *
 * The trace: a line "pmsm2dof-trace 1 <columns> <name> ..." then one row of
 * doubles (the machine's byte order) per logged speed sample, in the columns
 * of the engine's log (csrc/sim/drive.h, p2d_log_column_t), filled as the
 * engine fills them: the plant at t_k before it moves, the firmware's speed
 * sample k, the voltage applied over the period from t_k, the share of the
 * speed period's current periods at the voltage limit.
 *
 * Trace mode (the default): the board starts the scenario's run at power-up
 * and stops after P2D_VD_SPEED_SAMPLES speed samples (argument samples=N
 * overrides it), or as the engine stops: a non-finite state, twice the no-load
 * speed, ten times max(i_max, psi_f / min(Ld, Lq)); or when the control
 * interrupt overruns its period.
 *
 * Link mode (argument link=1): the drive idles until its XCP master starts a
 * run (link.h); the motor stands still while the power stage is off. The
 * master plays the reference (link_reference) and the load (vd_load, the
 * board's calibration variable, initialised from the scenario) and captures
 * the trace row of each speed period (vd_trace, a measurement variable: the
 * row of period k is complete at speed sample k + 1); between runs, while the
 * master's routines turn the motor, the load is off. No trace file; the
 * costs only with cost=1. The virtual motor waits for the link: a period is
 * skipped while DAQ packets fill half the queue. Arguments: timeout_ms=N (the
 * link watchdog, default 200), ramp_radps_per_s=N and hold_ms=N (its guard).
 *
 * The cost: on a machine that counts instructions (virtual_target_mps2.c), the
 * instructions foc_isr executed at each interrupt, callees included, one
 * uint32 each (bit 31 set for a speed sample): the clock is read around the
 * call, and the reading's own instructions, measured at the start on an empty
 * function called the same way, are taken off.
 */
#include <math.h>
#include <string.h>

#include "board.h"
#include "foc.h"
#include "p2d_virtual_drive.h"
#include "plant.h"
#include "schedule.h"
#include "virtual_target.h"

#define VB_INV_SQRT3 0.57735026918962576 /* 1 / sqrt(3) */
#define VB_TWO_PI 6.283185307179586      /* 2 pi */
#define VB_T_TOL 1e-6                    /* times closer than this many RK4 steps are equal [-] */
#define VB_ROWS_BUFFERED 32u             /* trace rows written at once */
#define VB_COSTS_BUFFERED 256u           /* interrupt costs written at once */
#define VB_SPEED_SAMPLE_BIT 0x80000000u  /* cost of an interrupt that ran the speed loop */
#define VB_LINE_CHARS 160u               /* characters of a diagnostic line */

/* Columns of a trace row: those of the engine's log, in its order. */
enum {
    VB_T_S = 0,
    VB_W_REF_RADPS,
    VB_W_M_RADPS,
    VB_ID_REF_A,
    VB_IQ_REF_A,
    VB_ID_A,
    VB_IQ_A,
    VB_UD_V,
    VB_UQ_V,
    VB_TORQUE_NM,
    VB_TORQUE_REF_NM,
    VB_TORQUE_UNSAT_NM,
    VB_LOAD_NM,
    VB_SATURATED,
    VB_X_I_NM,
    VB_W_MEAS_RADPS,
    VB_U_DC_V,
    VB_VOLTAGE_LIMITED,
    VB_J_EST_KGM2,
    VB_J_VALID,
    VB_T_LOAD_EST_NM,
    VB_J_GAINS_KGM2,
    VB_W_LOAD_RADPS,
    VB_SHAFT_TORQUE_NM,
    VB_COLUMNS
};

/* The first line of the trace: its format, the number of columns and their names. */
static const char trace_header[] =
    "pmsm2dof-trace 1 24 t_s w_ref_radps w_m_radps id_ref_A iq_ref_A id_A iq_A ud_V uq_V torque_Nm "
    "torque_ref_Nm torque_unsat_Nm load_Nm saturated x_i_Nm w_meas_radps u_dc_V voltage_limited J_est_kgm2 "
    "J_valid T_load_est_Nm J_gains_kgm2 w_load_radps shaft_torque_Nm\n";

/* Most entries of the load schedule (the master's calibration page vd_load). */
#define VB_LOAD_MAX 32u

/* The load torque of a run (calibration in link mode): a piecewise-linear schedule (schedule.h). */
typedef struct {
    uint32_t n;                    /* entries in use [-], 0..32 */
    uint32_t reserved;             /* 0 (alignment of the arrays) [-] */
    double t_s[VB_LOAD_MAX];       /* time of each entry from the run's start [s], >= 0, nondecreasing */
    double torque_Nm[VB_LOAD_MAX]; /* load torque of each entry [Nm] */
    double ramp_s[VB_LOAD_MAX];    /* ramp from the value reached to each entry's [s], >= 0 */
} vd_load_t;

vd_load_t vd_load;           /* the load schedule (calibration) */
double vd_trace[VB_COLUMNS]; /* the last complete trace row, the engine's log columns (measurement) */
static const schedule_t load = {vd_load.t_s, vd_load.torque_Nm, vd_load.ramp_s, 0u};
static bool link_mode;                                 /* the master runs the drive (argument link=1), no trace file */
static bool cost_output;                               /* the interrupts' costs go to cost.bin */
static bool powered;                                   /* the power stage is on: the physics runs */
static p2d_plant_t plant;                              /* the virtual motor, inverter and sensors */
static double t_tol_s;                                 /* times closer than this are equal [s] */
static double w_bound_radps;                           /* the engine's overspeed bound [rad/s] */
static double i_bound_A;                               /* the engine's overcurrent bound [A] */
static uint64_t n_current;                             /* current periods done: t = n_current Ts [-] */
static uint64_t n_periods_end;                         /* current periods of the run [-] */
static float adc_ia_A, adc_ib_A, adc_ic_A, adc_u_dc_V; /* the sensors latched at t_n */
static float rotor_theta_m_rad, rotor_w_m_radps;       /* the rotor latched at t_n */
static float sensed_w_radps;                           /* the speed loop's side latched at t_n */
static uint32_t encoder_count;                         /* the encoder counter latched at t_n */
static float duty[3];                                  /* the duties written by foc_isr */
static uint32_t n_limited;                        /* current periods of this speed sample at the voltage limit [-] */
static bool current_saturated;                    /* delay: the controller limited the command applied next */
static bool row_open;                             /* a trace row for this speed sample waits for its end */
static double rows[VB_ROWS_BUFFERED][VB_COLUMNS]; /* trace rows not written yet */
static uint32_t n_rows;                           /* rows in rows[] [-] */
static void (*volatile control)(void) = link_isr; /* the code measured: link_isr (an empty function to calibrate) */
static uint32_t reading_instructions;             /* instructions the measurement itself adds [-] */
static uint32_t costs[VB_COSTS_BUFFERED];         /* interrupt costs not written yet */
static uint32_t n_costs;                          /* costs in costs[] [-] */

/*
 * The load schedule in force (its entries counted in vd_load) during a run of the link; none between runs: the
 * routines the master starts there (commissioning, electrical identification) turn the motor uncoupled, as a
 * drive's motor is commissioned.
 */
static schedule_t load_schedule(void)
{
    schedule_t l = load;
    l.n = link_status()->state == LINK_RUNNING ? vd_load.n : 0u;
    return l;
}

/* ---- physics ----------------------------------------------------------- */

/*
 * The plant over the current period from t_start with its input held: `substeps` RK4 steps, each
 * split at the load's breakpoints (an entry, the end of a ramp) inside it, the load linear over
 * each piece.
 */
static void advance(double t_start_s)
{
    const double dt_s = plant.dt_s;
    const schedule_t l = load_schedule();
    for (uint32_t s = 0; s < plant.cfg.substeps; ++s) {
        double t = t_start_s + (double)s * dt_s;
        double t_end = t_start_s + (double)(s + 1u) * dt_s;
        while (t < t_end - t_tol_s) {
            schedule_segment_t seg = schedule_segment_at(&l, t + t_tol_s);
            double t_break = seg.next < l.n ? l.t_s[seg.next] : HUGE_VAL;
            double t_ramp_end = seg.t0_s + seg.ramp_s, t_stop, h, t_mid, slope = 0.0;
            if (seg.ramp_s > 0.0 && t_ramp_end > t + t_tol_s && t_ramp_end < t_break) t_break = t_ramp_end;
            t_stop = t_break < t_end - t_tol_s ? t_break : t_end;
            h = t_stop - t;
            t_mid = t + 0.5 * h;
            if (seg.ramp_s > 0.0 && t_mid > seg.t0_s && t_mid < t_ramp_end) slope = (seg.v1 - seg.v0) / seg.ramp_s;
            p2d_plant_advance(&plant, h, schedule_segment_value(&seg, t), slope);
            t = t_stop;
        }
    }
}

/* The sensors of the present state, as the board's registers hold them at the sampling instant. */
static void latch_sensors(void)
{
    double ia, ib, ic, theta_m, w_m, theta_s, w_s;
    if (P2D_VD_CURRENT_SENSOR_ERRORS) {
        p2d_plant_sense_currents(&plant, &ia, &ib);
        ic = -ia - ib;
    } else {
        p2d_plant_phase_currents(&plant, &ia, &ib, &ic);
    }
    p2d_plant_rotor(&plant, &theta_m, &w_m);
    theta_m = fmod(theta_m, VB_TWO_PI);
    adc_ia_A = (float)ia;
    adc_ib_A = (float)ib;
    adc_ic_A = (float)ic;
    adc_u_dc_V = (float)p2d_plant_dc_link_V(&plant);
    rotor_theta_m_rad = (float)(theta_m < 0.0 ? theta_m + VB_TWO_PI : theta_m);
    rotor_w_m_radps = (float)w_m;
    encoder_count = p2d_plant_encoder_count(&plant);
    if (p2d_vd_plant.mechanics.feedback == P2D_FEEDBACK_LOAD) {
        p2d_plant_load_side(&plant, &theta_s, &w_s);
    } else {
        w_s = w_m;
    }
    sensed_w_radps = (float)w_s;
}

/* Write the buffered (closed) trace rows. */
static void flush_rows(void)
{
    vt_write(VT_TRACE, rows, (uint32_t)(n_rows * sizeof rows[0]));
    n_rows = 0u;
}

/* Write the buffered interrupt costs. */
static void flush_costs(void)
{
    vt_write(VT_COST, costs, (uint32_t)(n_costs * sizeof costs[0]));
    n_costs = 0u;
}

/* The instructions of one call of `control`, the reading of the clock included. */
static uint32_t measured_call(void)
{
    uint32_t clock_start = vt_clock(), clock_end;
    control();
    clock_end = vt_clock();
    return vt_instructions(clock_start, clock_end);
}

/* measured_call, never inlined: the same instructions around the calibration and every interrupt */
static uint32_t (*volatile measure)(void) = measured_call;

/* An empty function: its one instruction (the return) calibrates the measurement. */
static void empty(void) {}

/* A diagnostic line: text, then the time of period n_current [s] in microseconds. */
static void report_at(const char *text)
{
    char line[VB_LINE_CHARS];
    char digits[21];
    uint32_t len = 0u, k = 0u;
    uint64_t t_us = (uint64_t)((double)n_current * p2d_vd_plant.Ts_s * 1e6 + 0.5);
    while (*text != '\0' && len < VB_LINE_CHARS - 32u) {
        line[len++] = *text++;
    }
    memcpy(line + len, " at t = ", 8);
    len += 8u;
    do {
        digits[k++] = (char)('0' + t_us % 10u);
        t_us /= 10u;
    } while (t_us > 0u);
    while (k > 0u) {
        line[len++] = digits[--k];
    }
    memcpy(line + len, " us", 4);
    vt_report(line);
}

/* End the run: the rows and costs so far, then the exit. */
static void finish(bool ok)
{
    flush_rows();
    flush_costs();
    vt_exit(ok);
}

/* The engine's stops: a non-finite state, overspeed, overcurrent. */
static void check_state(void)
{
    double i2 = plant.id_A * plant.id_A + plant.iq_A * plant.iq_A;
    const char *stop = 0;
    if (!isfinite(plant.id_A) || !isfinite(plant.iq_A) || !isfinite(plant.w_m_radps) ||
        (plant.two_mass && (!isfinite(plant.theta_rad) || !isfinite(plant.w_load_radps)))) {
        stop = "virtual drive: stopped: the plant state became non-finite";
    } else if (fabs(plant.w_m_radps) > w_bound_radps || (plant.two_mass && fabs(plant.w_load_radps) > w_bound_radps)) {
        stop = "virtual drive: stopped: the speed exceeds twice the no-load speed of the DC link";
    } else if (i2 > i_bound_A * i_bound_A) {
        stop = "virtual drive: stopped: the current exceeds ten times max(i_max, psi_f / min(Ld, Lq))";
    }
    if (stop != 0) {
        report_at(stop);
        finish(false);
    }
}

/* Open the trace row of speed sample k at t_k: the plant before it moves and the firmware's sample. */
static void open_row(double t_k_s)
{
    const foc_signals_t *sig = foc_signals();
    double *row = rows[n_rows];
    const schedule_t l = load_schedule();
    double theta_L_rad, w_L_radps, ud_V, uq_V, T_load_Nm = schedule_value(&l, t_k_s, t_tol_s);
    p2d_plant_load_side(&plant, &theta_L_rad, &w_L_radps);
    p2d_plant_applied_voltage(&plant, &ud_V, &uq_V);
    row[VB_T_S] = t_k_s;
    row[VB_W_REF_RADPS] = link_status()->w_ref_radps;
    row[VB_W_M_RADPS] = plant.w_m_radps;
    row[VB_ID_REF_A] = (double)sig->id_ref_A;
    row[VB_IQ_REF_A] = (double)sig->iq_ref_A;
    row[VB_ID_A] = plant.id_A;
    row[VB_IQ_A] = plant.iq_A;
    row[VB_UD_V] = ud_V;
    row[VB_UQ_V] = uq_V;
    row[VB_TORQUE_NM] = p2d_plant_torque_Nm(&plant);
    row[VB_TORQUE_REF_NM] = (double)sig->T_ref_Nm;
    row[VB_TORQUE_UNSAT_NM] = (double)sig->T_unsat_Nm;
    row[VB_LOAD_NM] = T_load_Nm;
    row[VB_SATURATED] = sig->saturated ? 1.0 : 0.0;
    row[VB_X_I_NM] = (double)sig->x_i_Nm;
    row[VB_W_MEAS_RADPS] = (double)sig->w_meas_radps;
    row[VB_U_DC_V] = plant.u_dc_V;
    row[VB_VOLTAGE_LIMITED] = 0.0; /* counted over the speed period */
    row[VB_J_EST_KGM2] = (double)sig->J_est_kgm2;
    row[VB_J_VALID] = sig->J_valid ? 1.0 : 0.0;
    row[VB_T_LOAD_EST_NM] = (double)sig->T_load_est_Nm;
    row[VB_J_GAINS_KGM2] = (double)sig->J_gains_kgm2;
    row[VB_W_LOAD_RADPS] = w_L_radps;
    row[VB_SHAFT_TORQUE_NM] = p2d_plant_shaft_torque_Nm(&plant, T_load_Nm);
    row_open = true;
}

/* One current period of the motor: the duties as the inverter applies them, the plant to t_n+1. */
static void physics(void)
{
    const foc_signals_t *sig = foc_signals();
    double t_s = (double)n_current * p2d_vd_plant.Ts_s;
    double u_dc_V = p2d_plant_dc_link_V(&plant), th_e = plant.p * plant.theta_m_rad;
    double c = cos(th_e), s = sin(th_e), u_alpha_V, u_beta_V;
    uint64_t k = n_current / P2D_VD_CURRENT_PER_SPEED;
    p2d_inverter_output_t io;

    /* u_alpha = u_dc (2 d_a - d_b - d_c) / 3, u_beta = u_dc (d_b - d_c) / sqrt(3) */
    u_alpha_V = u_dc_V * (2.0 * (double)duty[0] - (double)duty[1] - (double)duty[2]) / 3.0;
    u_beta_V = u_dc_V * ((double)duty[1] - (double)duty[2]) * VB_INV_SQRT3;
    /* ud = u_alpha cos + u_beta sin, uq = -u_alpha sin + u_beta cos */
    p2d_plant_command(&plant, u_alpha_V * c + u_beta_V * s, -u_alpha_V * s + u_beta_V * c, &io);
    /* the voltage of this period was cut: by the controller or the inverter, now or when it was given */
    if (p2d_vd_plant.computation_delay) {
        n_limited += io.applied_limited || current_saturated;
        current_saturated = sig->voltage_limited;
    } else {
        n_limited += sig->voltage_limited || io.limited;
    }
    if (sig->speed_sample && (link_mode || k % P2D_VD_LOG_EVERY == 0u)) open_row(t_s);
    advance(t_s);
    n_current++;
    check_state();
    if (n_current % P2D_VD_CURRENT_PER_SPEED == 0u) {
        /* the end of the speed period */
        if (row_open) {
            rows[n_rows][VB_VOLTAGE_LIMITED] = (double)n_limited / (double)P2D_VD_CURRENT_PER_SPEED;
            row_open = false;
            memcpy(vd_trace, rows[n_rows], sizeof vd_trace);
            /* link mode: the master captures vd_trace; the file holds the run of trace mode */
            if (!link_mode && ++n_rows == VB_ROWS_BUFFERED) flush_rows();
        }
        n_limited = 0u;
        if (!link_mode && n_current == n_periods_end) finish(true);
    }
    latch_sensors();
}

void board_virtual_interrupt(void)
{
    uint32_t instructions;
    /*
     * link mode: the virtual motor waits for the link. While the DAQ packets fill more than half the
     * queue, the period is skipped whole (the firmware's time stands still) and the background loop
     * sends them: no sample is lost however slow the master reads. A drive's motor cannot wait: its
     * firmware drops the samples and counts them (link_status_now.dtos_lost).
     */
    if (link_mode && link_daq_backlog()) return;
    instructions = measure() - reading_instructions;
    if (vt_hold(true)) {
        report_at("virtual drive: the control interrupt overran its period Ts_current");
        finish(false);
    }
    if (!powered) {
        /* idle: the motor stands in its state, the firmware's link runs */
        (void)vt_hold(false);
        return;
    }
    if (cost_output) {
        costs[n_costs++] = instructions | (foc_signals()->speed_sample ? VB_SPEED_SAMPLE_BIT : 0u);
        if (n_costs == VB_COSTS_BUFFERED) flush_costs();
    }
    physics();
    (void)vt_hold(false);
}

/* ---- board.h ----------------------------------------------------------- */

void board_init(void)
{
    p2d_plant_config_t cfg = p2d_vd_plant;
    p2d_plant_status_t status;
    vt_init();
    link_mode = vt_argument("link", 0u) != 0u;
    cost_output = !link_mode || vt_argument("cost", 0u) != 0u;
    n_periods_end = vt_argument("samples", P2D_VD_SPEED_SAMPLES) * P2D_VD_CURRENT_PER_SPEED;
    if (P2D_VD_LOAD_N > VB_LOAD_MAX) {
        vt_report("virtual drive: the load schedule has more than 32 entries");
        vt_exit(false);
    }
    vd_load.n = P2D_VD_LOAD_N;
    memcpy(vd_load.t_s, p2d_vd_load_t_s, P2D_VD_LOAD_N * sizeof(double));
    memcpy(vd_load.torque_Nm, p2d_vd_load_Nm, P2D_VD_LOAD_N * sizeof(double));
    memcpy(vd_load.ramp_s, p2d_vd_load_ramp_s, P2D_VD_LOAD_N * sizeof(double));
    /* at rest until board_start_control_interrupt: the friction at the initial speed needs the plant */
    cfg.id0_A = 0.0;
    cfg.iq0_A = 0.0;
    status = p2d_plant_init(&plant, &cfg);
    if (status != P2D_PLANT_OK) {
        vt_report("virtual drive: p2d_virtual_drive.h: the plant rejects this field of p2d_vd_plant:");
        vt_report(p2d_plant_status_param(status));
        vt_exit(false);
    }
    vt_write(VT_TRACE, trace_header, (uint32_t)(sizeof trace_header - 1u));
}

void board_report(const char *text) { vt_report(text); }

void board_halt(void) { finish(false); }

void board_read_start_state(float *w_m_radps, float *T_Nm)
{
    /* the engine's initial state: steady at w_m0, the torque holding it against friction (the motor's physics,
       in double: none of the firmware's time, as board_run_begin). The plant and its sensors are put back in it
       here already: foc_start reads the encoder's counter, which must be the initial state's and not where the
       rotor of the last run stopped (board_run_begin sets the currents foc_start chose) */
    (void)vt_hold(true);
    (void)p2d_plant_init(&plant, &p2d_vd_plant);
    latch_sensors();
    *w_m_radps = (float)p2d_vd_plant.w_m0_radps;
    *T_Nm = (float)p2d_plant_friction_Nm(&plant, p2d_vd_plant.w_m0_radps);
    (void)vt_hold(false);
}

void board_run_begin(void)
{
    p2d_plant_config_t cfg = p2d_vd_plant;
    const foc_signals_t *sig = foc_signals();
    /* the motor's physics takes none of the firmware's time */
    (void)vt_hold(true);
    /* the engine's initial state, the currents equal to the firmware's command (foc_start) */
    cfg.id0_A = (double)sig->id_ref_A;
    cfg.iq0_A = (double)sig->iq_ref_A;
    (void)p2d_plant_init(&plant, &cfg);
    n_current = 0u;
    n_limited = 0u;
    current_saturated = false;
    row_open = false;
    latch_sensors();
    (void)vt_hold(false);
}

void board_start_control_interrupt(float Ts_current_s)
{
    const p2d_plant_config_t *cfg = &p2d_vd_plant;
    double L_min_H = fmin(cfg->motor.Ld_H, cfg->motor.Lq_H);
    t_tol_s = VB_T_TOL * plant.dt_s;
    /* twice the no-load speed 2 u_dc / (sqrt(3) p psi_f); ten times max(i_max, psi_f / min(Ld, Lq)) */
    w_bound_radps = 2.0 * plant.u_max_V / (plant.p * cfg->motor.psi_f_Wb);
    i_bound_A = 10.0 * fmax(P2D_VD_I_MAX_A, cfg->motor.psi_f_Wb / L_min_H);
    n_current = 0u;
    latch_sensors();
    if (!link_mode && n_periods_end == 0u) finish(true);
    vt_start_interrupt(Ts_current_s);
    /* the instructions of the measurement alone: an empty function called as foc_isr is, less its return */
    control = empty;
    reading_instructions = measure() - 1u;
    control = link_isr;
}

void board_read_phase_currents(float *ia_A, float *ib_A, float *ic_A)
{
    *ia_A = adc_ia_A;
    *ib_A = adc_ib_A;
    *ic_A = adc_ic_A;
}

float board_read_dc_link_V(void) { return adc_u_dc_V; }

void board_read_rotor(float *theta_m_rad, float *w_m_radps)
{
    *theta_m_rad = rotor_theta_m_rad;
    *w_m_radps = rotor_w_m_radps;
}

float board_read_speed_radps(void) { return sensed_w_radps; }

uint32_t board_read_encoder_count(void) { return encoder_count; }

void board_write_duties(float duty_a, float duty_b, float duty_c)
{
    duty[0] = duty_a;
    duty[1] = duty_b;
    duty[2] = duty_c;
}

void board_pwm_enable(bool enable) { powered = enable; }

void board_wait_for_interrupt(void) { vt_wait(); }

/* ---- the link -------------------------------------------------------------- */

void board_link_config(link_config_t *cfg)
{
    const p2d_pmsm_params_t *m = &p2d_vd_plant.motor;
    /* half the acceleration of the current limit, 1.5 p psi_f i_max / J, unless ramp_radps_per_s=N */
    double ramp = 0.75 * (double)m->pole_pairs * m->psi_f_Wb * P2D_VD_I_MAX_A / m->J_kgm2;
    cfg->Ts_current_s = p2d_vd_plant.Ts_s;
    cfg->timeout_s = (float)vt_argument("timeout_ms", 200u) * 1e-3f;
    cfg->ramp_radps_per_s = (float)vt_argument("ramp_radps_per_s", (uint64_t)(ramp + 0.5));
    cfg->hold_s = (float)vt_argument("hold_ms", 50u) * 1e-3f;
    /* 255 on TCP; the PC's drive behind a CAN (FD) bridge: max_packet=8 (64) */
    cfg->max_packet_bytes = (uint32_t)vt_argument("max_packet", 255u);
    cfg->t_s = p2d_vd_reference_t_s;
    cfg->w_radps = p2d_vd_reference_radps;
    cfg->ramp_s = p2d_vd_reference_ramp_s;
    cfg->n = P2D_VD_REFERENCE_N;
    /* trace mode: the scenario's run at power-up */
    cfg->autostart_samples = link_mode ? 0u : (uint32_t)(n_periods_end / P2D_VD_CURRENT_PER_SPEED);
}

uint32_t board_link_receive(uint8_t *bytes, uint32_t capacity) { return vt_link_receive(bytes, capacity); }

uint32_t board_link_send(const uint8_t *bytes, uint32_t n) { return vt_link_send(bytes, n); }

void board_link_lock(void) { vt_lock(true); }

void board_link_unlock(void) { vt_lock(false); }

uint16_t board_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity)
{
    if (capacity < 2u) return 0u;
    segments[0] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&vd_load, &vd_load, sizeof vd_load, P2D_XCP_CALIBRATION};
    segments[1] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)vd_trace, vd_trace, sizeof vd_trace, P2D_XCP_MEASUREMENT};
    return 2u;
}

bool board_link_commit(uint16_t index, const void *page, bool running)
{
    /* vd_load: between runs only (checked whole when a run starts) */
    return index == 0u && !running && ((const vd_load_t *)page)->n <= VB_LOAD_MAX;
}

bool board_run_valid(void)
{
    schedule_t l = load;
    l.n = vd_load.n;
    return schedule_valid(&l);
}
