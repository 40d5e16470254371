/*
 * The simulation engine (csrc/sim/drive.c) on short scenarios, built by the
 * P2D_SANITIZE CMake option with AddressSanitizer and UndefinedBehaviorSanitizer
 * (first error fatal) and run as the ctest `sanitize_drive`.
 *
 * Each log buffer (column-major, drive.h) has exactly the rows the run needs, so that
 * AddressSanitizer catches a write past its end. Scenarios:
 *   1. the paper's condition 1 (section 4.1: J = 0.4 kg m^2, i_max = 7.6 A,
 *      500 rpm at 0 s and 200 rpm at 5 s, 10 s; dq current PIs, lowpass
 *      feedforward, back calculation, Tustin), run in four calls;
 *   2. a salient PMSM at 300 rpm with the first-order current loop (eq 3), full
 *      feedforward (eq 11), clamping, backward Euler, friction, and a load
 *      ramp beyond the torque limit (15 Nm, T_max about 10 Nm) and back: a
 *      stall and its recovery;
 *      the speed must be back on the reference at the end (integral action
 *      removes the steady-state error of friction);
 *   3. a salient PMSM with dq current PIs, decoupling and clamping in the
 *      current loop, computation delay, no_tau feedforward, forward Euler,
 *      no speed anti-windup, a reference ramp and a negative load;
 *   4. a load far beyond the limit that drives the shaft backwards until the
 *      engine stops with P2D_SIM_STOP_OVERSPEED;
 *   5. error paths: NULL, an invalid motor, an invalid controller, a log
 *      buffer too small (P2D_SIM_ERR_LOG_FULL before anything runs; then the
 *      samples it has room for), an invalid drive train, an invalid torque filter;
 *   6. the commissioning run (commission_run.h) of a salient servo with
 *      dead time, current noise and computation delay, into a log of exactly
 *      its rows: DONE, every estimate within 5 %; then a log one row short
 *      (P2D_CRUN_ERR_LOG_FULL) and a rejected routine configuration;
 *   7. measurement and field weakening (sensing.h): an encoder on a 16-bit
 *      counter read by the PLL with a low-pass, a fractional delay, speed and
 *      current noise, phase-current gain errors and offsets, and field
 *      weakening from 3000 to 4500 rpm with a light inertia (the speed must
 *      reach 4500 rpm); the longest delay the history holds (2045.5 current
 *      periods: the ring of angles wraps many times); and their error paths;
 *   8. a two-mass train with backlash read on the load side, with a notch and
 *      a low-pass in the speed controller, a load step: the trace ends at rest
 *      on the reference with the shaft carrying the load;
 *   9. six drives of condition 1 with different inertias, gains and loads in
 *      lockstep (p2d_sim_run_many: a full group and a partial one, one drive
 *      stopping inside its group), each into a log of exactly its rows: every
 *      log equal to the lone run's, bit for bit; then drives of two shapes
 *      (P2D_SIM_ERR_LOCKSTEP) and a log one row short (P2D_SIM_ERR_LOG_FULL),
 *      nothing run.
 * Besides the sanitizers' own checks: the status codes, every logged value
 * finite, ||i_ref|| <= i_max (float32 slack), and the recovery of scenario 2.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "commission_run.h"
#include "drive.h"

#define RADPS_PER_RPM (3.14159265358979323846 / 30.0)

static int failures = 0;

#define CHECK(cond, ...)                                                               \
    do {                                                                               \
        if (!(cond)) {                                                                 \
            fprintf(stderr, "sanitize_drive: %s:%d: %s: ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                              \
            fputc('\n', stderr);                                                       \
            failures++;                                                                \
        }                                                                              \
    } while (0)

/* The paper's condition 1 drive (preset paper-condition-1.toml). */
static void paper_drive(p2d_sim_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->motor.pole_pairs = 4u;
    cfg->motor.Rs_ohm = 0.5;
    cfg->motor.Ld_H = 0.01;
    cfg->motor.Lq_H = 0.01;
    cfg->motor.psi_f_Wb = 0.2;
    cfg->motor.J_kgm2 = 0.4;
    cfg->u_dc_V = 540.0;
    cfg->current_model = P2D_CURRENT_DQ_PI;
    cfg->tau_i_s = 0.05;
    cfg->Ts_current_s = 1e-4;
    cfg->current_per_speed = 10u;
    cfg->substeps = 1u;
    cfg->log_every = 1u;
    cfg->speed.J_kgm2 = 0.4f;
    cfg->speed.alpha_radps = 0.5f;
    cfg->speed.zeta = 0.28867513f;
    cfg->speed.m = 1.0f;
    cfg->speed.tau_i_s = 0.05f;
    cfg->speed.Ka = p2d_speed_Ka_default(0.4f, 0.5f);
    cfg->speed.Ts_s = 1e-3f;
    cfg->speed.i_max_A = 7.6f;
    cfg->speed.psi_f_Wb = 0.2f;
    cfg->speed.Ld_H = 0.01f;
    cfg->speed.Lq_H = 0.01f;
    cfg->speed.pole_pairs = 4u;
    cfg->speed.method = P2D_TUSTIN;
    cfg->speed.feedforward = P2D_FF_LOWPASS;
    cfg->speed.anti_windup = P2D_AW_BACK_CALCULATION;
    cfg->current.Rs_ohm = 0.5f;
    cfg->current.Ld_H = 0.01f;
    cfg->current.Lq_H = 0.01f;
    cfg->current.psi_f_Wb = 0.2f;
    cfg->current.tau_i_s = 0.05f;
    cfg->current.Ts_s = 1e-4f;
    cfg->current.method = P2D_TUSTIN;
    cfg->current.anti_windup = P2D_AW_BACK_CALCULATION;
    cfg->current.decouple = false;
}

/* A salient motor on the same mechanics. */
static void make_salient(p2d_sim_config_t *cfg)
{
    cfg->motor.Ld_H = 0.008;
    cfg->motor.Lq_H = 0.02;
    cfg->speed.Ld_H = 0.008f;
    cfg->speed.Lq_H = 0.02f;
    cfg->current.Ld_H = 0.008f;
    cfg->current.Lq_H = 0.02f;
}

/* Column c of row r in a column-major log of `capacity` rows (drive.h). */
static double cell(const double *log, uint64_t capacity, uint64_t r, uint32_t c)
{
    return log[(uint64_t)c * capacity + r];
}

/* Every logged value finite and the current command within the limit. */
static void check_log(const char *name, const double *log, uint64_t capacity, uint64_t rows, double i_max_A)
{
    for (uint64_t k = 0; k < rows; ++k) {
        double i_ref;
        for (uint32_t j = 0; j < (uint32_t)P2D_LOG_COUNT; ++j) {
            CHECK(isfinite(cell(log, capacity, k, j)), "%s: row %llu column %s = %g", name, (unsigned long long)k,
                  p2d_sim_log_name(j), cell(log, capacity, k, j));
        }
        i_ref = hypot(cell(log, capacity, k, P2D_LOG_ID_REF_A), cell(log, capacity, k, P2D_LOG_IQ_REF_A));
        CHECK(i_ref <= i_max_A * (1.0 + 1e-6), "%s: row %llu ||i_ref|| = %g > i_max %g", name, (unsigned long long)k,
              i_ref, i_max_A);
    }
}

/* Run n samples in `calls` equal calls into a buffer of exactly the rows needed. */
static p2d_sim_status_t run(const char *name, const p2d_sim_config_t *cfg, uint64_t n, uint64_t calls, double **log_out,
                            uint64_t *rows_out)
{
    p2d_sim_t *sim = malloc(sizeof *sim);
    uint64_t rows = (n + cfg->log_every - 1u) / cfg->log_every;
    double *log = malloc((size_t)(rows * (uint64_t)P2D_LOG_COUNT) * sizeof *log);
    p2d_sim_status_t status;
    if (sim == NULL || log == NULL) {
        fprintf(stderr, "sanitize_drive: out of memory\n");
        exit(2);
    }
    status = p2d_sim_init(sim, cfg);
    CHECK(status == P2D_SIM_OK, "%s: init returned %d (%s)", name, (int)status, p2d_sim_status_param(status));
    for (uint64_t c = 0; c < calls && status == P2D_SIM_OK; ++c) {
        status = p2d_sim_run(sim, n / calls, log, rows);
    }
    *rows_out = sim->n_rows;
    *log_out = log;
    check_log(name, log, rows, sim->n_rows, (double)cfg->speed.i_max_A);
    free(sim);
    return status;
}

int main(void)
{
    p2d_sim_config_t cfg;
    p2d_sim_status_t status;
    double *log;
    uint64_t rows;

    /* 1. paper condition 1: 500 rpm at 0 s, 200 rpm at 5 s, 10 s in four calls */
    {
        static const double ref_t[] = {0.0, 5.0};
        static const double ref_v[] = {500.0 * RADPS_PER_RPM, 200.0 * RADPS_PER_RPM}, ref_r[] = {0.0, 0.0};
        paper_drive(&cfg);
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 2u};
        status = run("paper condition 1", &cfg, 10000u, 4u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 10000u, "paper condition 1: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        free(log);
    }

    /* 2. salient, first-order current loop, full feedforward, clamping: a stall and its recovery */
    {
        static const double ref_t[] = {0.0}, ref_v[] = {300.0 * RADPS_PER_RPM}, ref_r[] = {0.0};
        static const double load_t[] = {0.3, 0.6}, load_v[] = {15.0, 0.0}, load_r[] = {0.2, 0.0};
        paper_drive(&cfg);
        make_salient(&cfg);
        cfg.motor.B_Nms = 0.01;
        cfg.motor.T_coulomb_Nm = 0.2;
        cfg.w_m0_radps = ref_v[0];
        cfg.current_model = P2D_CURRENT_FIRST_ORDER;
        cfg.tau_i_s = 0.005;
        cfg.substeps = 2u;
        cfg.log_every = 3u;
        cfg.speed.alpha_radps = 20.0f;
        cfg.speed.zeta = 1.0f;
        cfg.speed.m = 2.0f;
        cfg.speed.tau_i_s = 0.005f;
        cfg.speed.method = P2D_BACKWARD_EULER;
        cfg.speed.feedforward = P2D_FF_FULL;
        cfg.speed.anti_windup = P2D_AW_CLAMPING;
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 1u};
        cfg.load = (p2d_schedule_t){load_t, load_v, load_r, 2u};
        status = run("salient first-order stall", &cfg, 1500u, 1u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 500u, "salient first-order stall: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        if (rows == 500u) {
            /* the limit holds during the stall (row 180: t = 0.54 s, 15 Nm > T_max), and the
               speed is back on the reference at the last row (t = 1.497 s, 0.9 s after the load dropped) */
            double w = cell(log, rows, 499u, P2D_LOG_W_M_RADPS);
            CHECK(cell(log, rows, 180u, P2D_LOG_SATURATED) == 1.0, "salient first-order stall: not saturated");
            CHECK(fabs(w - ref_v[0]) < 0.01 * ref_v[0],
                  "salient first-order stall: w_m(1.497 s) = %g rad/s, "
                  "reference %g",
                  w, ref_v[0]);
        }
        free(log);
    }

    /* 3. salient, dq PIs with decoupling and clamping, delay, no_tau, forward Euler, no anti-windup */
    {
        static const double ref_t[] = {0.0, 0.2}, ref_v[] = {200.0, -100.0}, ref_r[] = {0.1, 0.3};
        static const double load_t[] = {0.1}, load_v[] = {-3.0}, load_r[] = {0.0};
        paper_drive(&cfg);
        make_salient(&cfg);
        cfg.computation_delay = true;
        cfg.w_m0_radps = 10.0;
        cfg.speed.alpha_radps = 30.0f;
        cfg.speed.zeta = 0.7f;
        cfg.speed.m = 0.5f;
        cfg.speed.method = P2D_FORWARD_EULER;
        cfg.speed.feedforward = P2D_FF_NO_TAU;
        cfg.speed.anti_windup = P2D_AW_NONE;
        cfg.current.tau_i_s = 0.002f;
        cfg.current.decouple = true;
        cfg.current.anti_windup = P2D_AW_CLAMPING;
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 2u};
        cfg.load = (p2d_schedule_t){load_t, load_v, load_r, 1u};
        status = run("salient dq_pi delay", &cfg, 800u, 2u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 800u, "salient dq_pi delay: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        free(log);
    }

    /* 4. a load far beyond the limit drives the shaft backwards into the overspeed stop */
    {
        static const double load_t[] = {0.0}, load_v[] = {400.0}, load_r[] = {0.0};
        paper_drive(&cfg);
        cfg.load = (p2d_schedule_t){load_t, load_v, load_r, 1u};
        status = run("overspeed", &cfg, 20000u, 1u, &log, &rows);
        CHECK(status == P2D_SIM_STOP_OVERSPEED, "overspeed: status %d (%s) after %llu rows", (int)status,
              p2d_sim_status_text(status), (unsigned long long)rows);
        free(log);
    }

    /* 5. error paths */
    {
        p2d_sim_t *sim = malloc(sizeof *sim);
        double *small;
        paper_drive(&cfg);
        CHECK(p2d_sim_init(NULL, &cfg) == P2D_SIM_ERR_NULL && p2d_sim_init(sim, NULL) == P2D_SIM_ERR_NULL,
              "NULL accepted");
        cfg.motor.Rs_ohm = -1.0;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_RS, "negative Rs accepted");
        paper_drive(&cfg);
        cfg.speed.zeta = NAN;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_SPEED_CONTROLLER && sim->controller_status == P2D_ERR_ZETA,
              "NaN zeta: status %d", (int)sim->controller_status);
        paper_drive(&cfg);
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_OK, "valid configuration rejected");
        small = malloc(10u * P2D_LOG_COUNT * sizeof *small);
        status = p2d_sim_run(sim, 11u, small, 10u);
        CHECK(status == P2D_SIM_ERR_LOG_FULL && sim->n_rows == 0u && sim->n_speed == 0u,
              "log of 10 rows for 11 samples: status %d rows %llu (nothing runs)", (int)status,
              (unsigned long long)sim->n_rows);
        status = p2d_sim_run(sim, 10u, small, 10u);
        CHECK(status == P2D_SIM_OK && sim->n_rows == 10u, "log of 10 rows for 10 samples: status %d rows %llu",
              (int)status, (unsigned long long)sim->n_rows);
        free(small);
        paper_drive(&cfg);
        cfg.mechanics.model = P2D_MECHANICS_TWO_MASS;
        cfg.mechanics.J_load_kgm2 = -0.3;
        cfg.mechanics.stiffness_Nm_per_rad = 1000.0;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_J_LOAD, "negative load inertia accepted");
        paper_drive(&cfg);
        cfg.speed_filter.notch_freq_Hz = 600.0f; /* above the speed loop's Nyquist frequency */
        cfg.speed_filter.notch_width_Hz = 10.0f;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_SPEED_CONTROLLER && sim->controller_status == P2D_ERR_NOTCH_FREQ,
              "notch above Nyquist: status %d", (int)sim->controller_status);
        free(sim);
    }

    /* 6. commissioning run */
    {
        p2d_crun_t *run = malloc(sizeof *run);
        p2d_crun_config_t cc;
        const double truth[4] = {0.8, 4e-3, 8e-3, 0.05};
        uint64_t n, rows;
        double *clog;
        memset(&cc, 0, sizeof cc);
        cc.motor.pole_pairs = 4u;
        cc.motor.Rs_ohm = truth[0];
        cc.motor.Ld_H = truth[1];
        cc.motor.Lq_H = truth[2];
        cc.motor.psi_f_Wb = truth[3];
        cc.motor.J_kgm2 = 2e-4;
        cc.motor.B_Nms = 1e-5;
        cc.u_dc_V = 48.0;
        cc.computation_delay = true;
        cc.substeps = 2u;
        cc.log_every = 7u;
        cc.dead_time_V = 0.5;
        cc.noise_A = 0.02;
        cc.seed = 3u;
        cc.theta0_rad = 2.0;
        cc.commissioning.Ts_s = 1e-4f;
        cc.commissioning.i_test_A = 2.0f;
        cc.commissioning.i_spin_A = 1.5f;
        cc.commissioning.i_trip_A = 4.0f;
        cc.commissioning.tau_i_s = 1e-3f;
        cc.commissioning.t_align_s = 0.2f;
        cc.commissioning.t_level_s = 0.05f;
        cc.commissioning.t_inductance_s = 0.05f;
        cc.commissioning.t_ramp_s = 0.5f;
        cc.commissioning.t_spin_s = 0.5f;
        cc.commissioning.w_e_spin_radps = 300.0f;
        cc.commissioning.voltage_delay_samples = 1u;
        /* the samples of the run, with a buffer large enough, then the same run into exactly its rows */
        clog = malloc(100000u * P2D_CLOG_COUNT * sizeof *clog);
        CHECK(p2d_commission_run_init(run, &cc) == P2D_CRUN_OK, "commissioning: init rejected");
        (void)p2d_commission_run(run, 1000000u, clog, 100000u);
        n = run->n;
        rows = (n + cc.log_every - 1u) / cc.log_every;
        free(clog);
        clog = malloc(rows * P2D_CLOG_COUNT * sizeof *clog);
        CHECK(p2d_commission_run_init(run, &cc) == P2D_CRUN_OK, "commissioning: init rejected");
        CHECK(p2d_commission_run(run, 1000000u, clog, rows) == P2D_CRUN_OK && run->n == n && run->n_rows == rows,
              "commissioning: status %d, %llu samples", (int)run->status, (unsigned long long)run->n);
        CHECK(run->routine.phase == P2D_PHASE_DONE && fabs(run->routine.Rs_ohm / truth[0] - 1.0) < 0.05 &&
                  fabs(run->routine.Ld_H / truth[1] - 1.0) < 0.05 && fabs(run->routine.Lq_H / truth[2] - 1.0) < 0.05 &&
                  fabs(run->routine.psi_f_Wb / truth[3] - 1.0) < 0.05,
              "commissioning: phase %d, Rs %g Ld %g Lq %g psi_f %g", (int)run->routine.phase,
              (double)run->routine.Rs_ohm, (double)run->routine.Ld_H, (double)run->routine.Lq_H,
              (double)run->routine.psi_f_Wb);
        for (uint64_t k = 0; k < rows; ++k) {
            for (uint32_t j = 0; j < P2D_CLOG_COUNT; ++j) {
                CHECK(isfinite(clog[(uint64_t)j * rows + k]), "commissioning: row %llu column %s",
                      (unsigned long long)k, p2d_crun_log_name(j));
            }
        }
        CHECK(p2d_commission_run_init(run, &cc) == P2D_CRUN_OK, "commissioning: init rejected");
        CHECK(p2d_commission_run(run, 1000000u, clog, rows - 1u) == P2D_CRUN_ERR_LOG_FULL && run->n_rows == rows - 1u,
              "commissioning: a log one row short: status %d", (int)run->status);
        cc.commissioning.i_trip_A = 2.0f;
        CHECK(p2d_commission_run_init(run, &cc) == P2D_CRUN_ERR_COMMISSIONING &&
                  run->commission_status == P2D_ERR_I_TRIP,
              "commissioning: i_trip_A below 1.5 i_test_A accepted");
        free(clog);
        free(run);
    }

    /* 7. encoder, PLL, delay, noise, current sensors, field weakening above base speed */
    {
        static const double ref_t[] = {0.0}, ref_v[] = {4500.0 * RADPS_PER_RPM}, ref_r[] = {0.0};
        static const double load_t[] = {0.0}, load_v[] = {2.0}, load_r[] = {0.0};
        p2d_sim_t *sim = malloc(sizeof *sim);
        paper_drive(&cfg);
        cfg.motor.J_kgm2 = 0.01;
        cfg.w_m0_radps = 3000.0 * RADPS_PER_RPM;
        cfg.speed.J_kgm2 = 0.01f;
        cfg.speed.alpha_radps = 20.0f;
        cfg.speed.zeta = 0.7f;
        cfg.speed.Ka = p2d_speed_Ka_default(0.01f, 20.0f);
        cfg.current.tau_i_s = 0.002f;
        cfg.current.decouple = true;
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 1u};
        cfg.load = (p2d_schedule_t){load_t, load_v, load_r, 1u};
        cfg.sensing.speed_sensor.model = P2D_SPEED_SENSOR_ENCODER;
        cfg.sensing.speed_sensor.encoder.counts_per_rev = 4096u;
        cfg.sensing.speed_sensor.encoder.counter_bits = 16u;
        cfg.sensing.speed_sensor.encoder.estimator = P2D_ESTIMATOR_PLL;
        cfg.sensing.speed_sensor.encoder.bandwidth_radps = 400.0f;
        cfg.sensing.speed_sensor.encoder.lowpass_radps = 1000.0f;
        cfg.sensing.speed_sensor.delay_s = 2.5 * cfg.Ts_current_s;
        cfg.sensing.speed_sensor.noise_rms_radps = 0.5;
        cfg.sensing.speed_sensor.seed = 12345u;
        cfg.sensing.current_sensor.gain_error_a = 0.02;
        cfg.sensing.current_sensor.gain_error_b = -0.01;
        cfg.sensing.current_sensor.offset_a_A = 0.05;
        cfg.sensing.current_sensor.offset_b_A = -0.03;
        cfg.sensing.current_sensor.noise_rms_A = 0.01;
        cfg.sensing.current_sensor.seed = 99u;
        cfg.sensing.field_weakening.enabled = true;
        cfg.sensing.field_weakening.config.Kp_A_per_V = 0.0f;
        cfg.sensing.field_weakening.config.Ki_A_per_Vs = 3.0f;
        cfg.sensing.field_weakening.config.Ka_V_per_A = 1.0f / (3.0f * 1e-3f);
        cfg.sensing.field_weakening.config.voltage_ratio = 0.95f;
        cfg.sensing.field_weakening.config.id_min_A = -7.6f;
        cfg.sensing.field_weakening.config.method = P2D_TUSTIN;
        cfg.sensing.field_weakening.config.anti_windup = P2D_AW_BACK_CALCULATION;
        status = run("sensing and field weakening", &cfg, 3000u, 3u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 3000u, "sensing and field weakening: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        if (rows == 3000u) {
            double w = cell(log, rows, 2999u, P2D_LOG_W_M_RADPS);
            CHECK(fabs(w - ref_v[0]) < 0.01 * ref_v[0], "sensing and field weakening: w_m(3 s) = %g rad/s, ref %g", w,
                  ref_v[0]);
            CHECK(cell(log, rows, 2999u, P2D_LOG_ID_REF_A) < -1.0, "sensing and field weakening: id_ref %g",
                  cell(log, rows, 2999u, P2D_LOG_ID_REF_A));
        }
        free(log);
        /* error paths */
        cfg.sensing.speed_sensor.delay_s = 2047.0 * cfg.Ts_current_s;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_SPEED_SENSOR, "a delay beyond the history accepted");
        cfg.sensing.speed_sensor.delay_s = 0.0;
        cfg.sensing.speed_sensor.encoder.bandwidth_radps = 1e6f;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_SPEED_SENSOR && sim->controller_status == P2D_ERR_ENC_BANDWIDTH,
              "PLL bandwidth beyond 2/Ts: controller_status %d", (int)sim->controller_status);
        cfg.sensing.speed_sensor.encoder.bandwidth_radps = 400.0f;
        cfg.sensing.current_sensor.gain_error_b = -1.0;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_CURRENT_SENSOR, "a gain error of -1 accepted");
        cfg.sensing.current_sensor.gain_error_b = 0.0;
        cfg.sensing.field_weakening.config.id_min_A = 0.0f;
        CHECK(p2d_sim_init(sim, &cfg) == P2D_SIM_ERR_FIELD_WEAKENING && sim->controller_status == P2D_ERR_FW_ID_MIN,
              "id_min_A = 0 accepted: controller_status %d", (int)sim->controller_status);
        /* the longest delay the history holds, on the paper's slow loop: the ring wraps 14 times */
        paper_drive(&cfg);
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 1u};
        cfg.sensing.speed_sensor.model = P2D_SPEED_SENSOR_ENCODER;
        cfg.sensing.speed_sensor.encoder.counts_per_rev = 4096u;
        cfg.sensing.speed_sensor.encoder.counter_bits = 16u;
        cfg.sensing.speed_sensor.delay_s = 2045.5 * cfg.Ts_current_s;
        status = run("longest delay", &cfg, 3000u, 2u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 3000u, "longest delay: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        free(log);
        free(sim);
    }

    /* 8. two-mass train with backlash, load-side feedback, notch and low-pass */
    {
        static const double ref_t[] = {0.0}, ref_v[] = {300.0 * RADPS_PER_RPM}, ref_r[] = {0.0};
        static const double load_t[] = {0.5}, load_v[] = {4.0}, load_r[] = {0.0};
        paper_drive(&cfg);
        cfg.motor.J_kgm2 = 0.1;
        cfg.mechanics.model = P2D_MECHANICS_TWO_MASS;
        cfg.mechanics.J_load_kgm2 = 0.3;
        cfg.mechanics.stiffness_Nm_per_rad = 2664.8; /* 30 Hz */
        cfg.mechanics.damping_Nms_per_rad = 0.5655;  /* zeta_r = 0.02 */
        cfg.mechanics.backlash_rad = 1e-3;
        cfg.mechanics.feedback = P2D_FEEDBACK_LOAD;
        cfg.speed.alpha_radps = 5.0f;
        cfg.speed.zeta = 0.7f;
        cfg.speed.Ka = p2d_speed_Ka_default(0.4f, 5.0f);
        cfg.current.tau_i_s = 0.002f;
        cfg.speed_filter.notch_freq_Hz = 30.0f;
        cfg.speed_filter.notch_width_Hz = 20.0f;
        cfg.speed_filter.notch_depth = 0.05f;
        cfg.speed_filter.lowpass_freq_Hz = 150.0f;
        cfg.speed_filter.lowpass_zeta = 0.7f;
        cfg.reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 1u};
        cfg.load = (p2d_schedule_t){load_t, load_v, load_r, 1u};
        status = run("two-mass with filters", &cfg, 7500u, 3u, &log, &rows);
        CHECK(status == P2D_SIM_OK && rows == 7500u, "two-mass with filters: status %d rows %llu", (int)status,
              (unsigned long long)rows);
        if (rows == 7500u) {
            double w_L = cell(log, rows, 7499u, P2D_LOG_W_LOAD_RADPS);
            double T_s = cell(log, rows, 7499u, P2D_LOG_SHAFT_TORQUE_NM);
            CHECK(fabs(w_L - ref_v[0]) < 1e-3 * ref_v[0], "two-mass with filters: w_L(7.5 s) = %g rad/s", w_L);
            CHECK(fabs(T_s - load_v[0]) < 1e-3 * load_v[0], "two-mass with filters: T_s(7.5 s) = %g Nm", T_s);
        }
        free(log);
    }

    /* 9. lockstep: six drives, a full group and a partial one, one that stops; then the error paths */
    {
        enum { N_MANY = 6 };
        static const double ref_t[] = {0.0}, ref_v[] = {500.0 * RADPS_PER_RPM}, ref_r[] = {0.0};
        static double load_t[N_MANY], load_v[N_MANY], load_r[N_MANY];
        p2d_sim_t *many[N_MANY], *alone = malloc(sizeof *alone);
        double *many_log[N_MANY], *alone_log;
        uint64_t many_rows[N_MANY], n = 1500u;
        size_t bytes = (size_t)(n * (uint64_t)P2D_LOG_COUNT) * sizeof(double);
        p2d_sim_config_t cfgs[N_MANY];
        alone_log = malloc(bytes);
        if (alone == NULL || alone_log == NULL) exit(2);
        for (int i = 0; i < N_MANY; ++i) {
            paper_drive(&cfgs[i]);
            cfgs[i].motor.J_kgm2 = i == 3 ? 0.01 : 0.2 + 0.1 * i;
            cfgs[i].speed.alpha_radps = 0.3f + 0.2f * (float)i;
            cfgs[i].speed.Ka = p2d_speed_Ka_default(0.4f, cfgs[i].speed.alpha_radps);
            load_t[i] = 0.7 + 0.0123 * i;
            load_v[i] = i == 3 ? -40.0 : 2.0 * i; /* drive 3: a load that runs it away into the overspeed stop */
            load_r[i] = i == 4 ? 0.0501 : 0.0;    /* drive 4: a ramp whose ends fall inside periods */
            cfgs[i].reference = (p2d_schedule_t){ref_t, ref_v, ref_r, 1u};
            cfgs[i].load = (p2d_schedule_t){&load_t[i], &load_v[i], &load_r[i], 1u};
            many[i] = malloc(sizeof *many[i]);
            many_log[i] = malloc(bytes);
            many_rows[i] = n;
            if (many[i] == NULL || many_log[i] == NULL) exit(2);
            CHECK(p2d_sim_init(many[i], &cfgs[i]) == P2D_SIM_OK, "lockstep: drive %d rejected", i);
        }
        status = p2d_sim_run_many(many, N_MANY, n, many_log, many_rows);
        CHECK(status == P2D_SIM_OK, "lockstep: status %d", (int)status);
        CHECK(many[3]->status == P2D_SIM_STOP_OVERSPEED, "lockstep: drive 3 ends with %d", (int)many[3]->status);
        for (int i = 0; i < N_MANY; ++i) {
            CHECK(p2d_sim_init(alone, &cfgs[i]) == P2D_SIM_OK, "lockstep: drive %d rejected alone", i);
            status = p2d_sim_run(alone, n, alone_log, n);
            CHECK(status == many[i]->status && alone->n_rows == many[i]->n_rows && alone->t_stop_s == many[i]->t_stop_s,
                  "lockstep: drive %d: status %d alone, %d in lockstep", i, (int)status, (int)many[i]->status);
            for (uint32_t c = 0; c < (uint32_t)P2D_LOG_COUNT; ++c) {
                CHECK(memcmp(alone_log + (uint64_t)c * n, many_log[i] + (uint64_t)c * n,
                             (size_t)alone->n_rows * sizeof(double)) == 0,
                      "lockstep: drive %d: column %s differs from the lone run", i, p2d_sim_log_name(c));
            }
        }
        for (int i = 0; i < 2; ++i) CHECK(p2d_sim_init(many[i], &cfgs[i]) == P2D_SIM_OK, "lockstep: init %d", i);
        many[1]->cfg.substeps = 2u;
        CHECK(p2d_sim_run_many(many, 2u, n, many_log, many_rows) == P2D_SIM_ERR_LOCKSTEP && many[0]->n_speed == 0u,
              "lockstep: drives of two shapes ran");
        many[1]->cfg.substeps = 1u;
        many_rows[1] = n - 1u;
        CHECK(p2d_sim_run_many(many, 2u, n, many_log, many_rows) == P2D_SIM_ERR_LOG_FULL && many[0]->n_speed == 0u,
              "lockstep: a short log ran");
        for (int i = 0; i < N_MANY; ++i) {
            free(many[i]);
            free(many_log[i]);
        }
        free(alone);
        free(alone_log);
    }

    if (failures != 0) {
        fprintf(stderr, "sanitize_drive: %d check(s) failed\n", failures);
        return 1;
    }
    printf("sanitize_drive: 9 scenarios passed\n");
    return 0;
}
