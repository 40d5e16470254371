/*
 * Unit tests of the self-commissioning routine (pmsm2dof/commission.h).
 *
 * The truth is a motor written here in double precision, independent of the
 * routine: the dq model of eq 1 in the rotor frame with the rotor's angle and
 * mechanics,
 *   Ld did/dt = ud - Rs id + w_e Lq iq,  Lq diq/dt = uq - Rs iq - w_e (Ld id + psi_f),
 *   J dw_m/dt = 1.5 p (psi_f iq + (Ld - Lq) id iq) - T_load - B w_m,  dtheta_e/dt = p w_m,
 * integrated by RK4 (10 steps per sample), fed by an inverter that holds the
 * stationary-frame voltage over each period (after a delay of 0 or 1 period),
 * with a dead-time error of u_dt per phase, -u_dt sign(i_phase), and
 * measuring two phase currents with Gaussian noise. The routine only sees the
 * currents in its own frame, as firmware does.
 */
#include <stdint.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/commission.h"

#define SQRT3 1.7320508075688772

typedef struct {
    double Rs_ohm, Ld_H, Lq_H, psi_f_Wb; /* electrical parameters (the truth) */
    int p;                               /* pole pairs */
    double J_kgm2, B_Nms;                /* mechanics */
    double u_dt_V;                       /* dead-time voltage error per phase [V] */
    double noise_A;                      /* standard deviation of each measured phase current [A] */
    int delay;                           /* periods before a command is applied: 0 or 1 */
} motor_t;

typedef struct {
    double u_dc_V;                     /* DC link [V] */
    double theta0_rad;                 /* initial electrical angle of the rotor [rad] */
    p2d_commission_phase_t load_from;  /* the load acts from the start of this phase on */
    double T_load_Nm;                  /* load torque [Nm] */
    int invert_sensing;                /* the measured currents have the wrong sign */
    long nan_every;                    /* every nan_every-th sample reads a NaN current (0: never) */
    p2d_commission_phase_t drive_from; /* from the start of this phase on, the rotor turns at w_drive_e_radps */
    double w_drive_e_radps;            /* speed of a rotor driven by another machine [rad/s, electrical] */
} run_options_t;

typedef struct {
    double id, iq;  /* rotor-frame currents [A] */
    double w_m;     /* mechanical speed [rad/s] */
    double theta_e; /* rotor electrical angle [rad] */
    double T_load;  /* load torque now [Nm] */
    int driven;     /* the speed is held by another machine */
    uint64_t rng;   /* noise generator state */
} plant_t;

/* Uniform in (0, 1) (xorshift64*) */
static double uniform(plant_t *s)
{
    s->rng ^= s->rng >> 12;
    s->rng ^= s->rng << 25;
    s->rng ^= s->rng >> 27;
    return ((double)((s->rng * 2685821657736338717ull) >> 11) + 0.5) / 9007199254740992.0;
}

/* Standard normal (Box-Muller) */
static double gauss(plant_t *s)
{
    double u1 = uniform(s), u2 = uniform(s);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

static double sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }

/* d/dt of (id, iq, w_m, theta_e) under the stationary-frame voltage (ua, ub) */
static void derivative(const motor_t *m, const plant_t *s, const double x[4], double ua, double ub, double dx[4])
{
    double c = cos(x[3]), sn = sin(x[3]);
    double ia = c * x[0] - sn * x[1], ib = sn * x[0] + c * x[1];
    /* phase currents, their dead-time errors, and those errors in alpha beta (amplitude invariant) */
    double i_a = ia, i_b = -0.5 * ia + 0.5 * SQRT3 * ib, i_c = -0.5 * ia - 0.5 * SQRT3 * ib;
    double e_a = -m->u_dt_V * sign(i_a), e_b = -m->u_dt_V * sign(i_b), e_c = -m->u_dt_V * sign(i_c);
    double va = ua + (2.0 / 3.0) * (e_a - 0.5 * (e_b + e_c)), vb = ub + (e_b - e_c) / SQRT3;
    double ud = c * va + sn * vb, uq = -sn * va + c * vb;
    double w_e = m->p * x[2];
    double Te = 1.5 * m->p * (m->psi_f_Wb * x[1] + (m->Ld_H - m->Lq_H) * x[0] * x[1]);
    dx[0] = (ud - m->Rs_ohm * x[0] + w_e * m->Lq_H * x[1]) / m->Ld_H;
    dx[1] = (uq - m->Rs_ohm * x[1] - w_e * (m->Ld_H * x[0] + m->psi_f_Wb)) / m->Lq_H;
    dx[2] = s->driven ? 0.0 : (Te - s->T_load - m->B_Nms * x[2]) / m->J_kgm2;
    dx[3] = w_e;
}

/* The plant over one period Ts with (ua, ub) held: RK4, 10 steps */
static void integrate(const motor_t *m, plant_t *s, double ua, double ub, double Ts)
{
    const int n = 10;
    const double h = Ts / n;
    double x[4] = {s->id, s->iq, s->w_m, s->theta_e};
    for (int j = 0; j < n; ++j) {
        double k1[4], k2[4], k3[4], k4[4], y[4];
        derivative(m, s, x, ua, ub, k1);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + 0.5 * h * k1[i];
        derivative(m, s, y, ua, ub, k2);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + 0.5 * h * k2[i];
        derivative(m, s, y, ua, ub, k3);
        for (int i = 0; i < 4; ++i) y[i] = x[i] + h * k3[i];
        derivative(m, s, y, ua, ub, k4);
        for (int i = 0; i < 4; ++i) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    s->id = x[0];
    s->iq = x[1];
    s->w_m = x[2];
    s->theta_e = x[3];
}

/* The currents that firmware measures, in the routine's frame at angle theta_c */
static void measure(const motor_t *m, plant_t *s, double theta_c, float *id, float *iq)
{
    double c = cos(s->theta_e), sn = sin(s->theta_e);
    double ia = c * s->id - sn * s->iq, ib = sn * s->id + c * s->iq;
    /* phases a and b measured with noise, c = -a - b, then Clarke and Park */
    double i_a = ia + m->noise_A * gauss(s), i_b = -0.5 * ia + 0.5 * SQRT3 * ib + m->noise_A * gauss(s);
    double alpha = i_a, beta = (i_a + 2.0 * i_b) / SQRT3;
    *id = (float)(cos(theta_c) * alpha + sin(theta_c) * beta);
    *iq = (float)(-sin(theta_c) * alpha + cos(theta_c) * beta);
}

/* Run the routine against the motor until it ends; the routine's final state into c. */
static void run(const motor_t *m, const p2d_commission_config_t *cfg, const run_options_t *o, p2d_commission_t *c)
{
    plant_t s = {0.0, 0.0, 0.0, o->theta0_rad, 0.0, 0, 0x9e3779b97f4a7c15ull};
    double ua_next = 0.0, ub_next = 0.0;
    p2d_commission_output_t out;
    long k = 0;
    CHECK(p2d_commission_init(c, cfg) == P2D_OK);
    while (c->phase < P2D_PHASE_DONE && k < 20000000L) {
        float id, iq;
        double ua, ub;
        measure(m, &s, (double)c->theta_e_rad, &id, &iq);
        if (o->invert_sensing) {
            id = -id;
            iq = -iq;
        }
        if (o->nan_every > 0 && k % o->nan_every == o->nan_every - 1) id = NAN;
        p2d_commission_step(c, id, iq, (float)o->u_dc_V, &out);
        if (c->phase >= o->load_from) s.T_load = o->T_load_Nm;
        if (c->phase >= o->drive_from && !s.driven) {
            s.driven = 1;
            s.w_m = o->w_drive_e_radps / m->p;
        }
        /* inverse Park at the angle the routine asks for */
        ua = cos(out.theta_e_rad) * out.ud_V - sin(out.theta_e_rad) * out.uq_V;
        ub = sin(out.theta_e_rad) * out.ud_V + cos(out.theta_e_rad) * out.uq_V;
        if (m->delay) {
            double ua_now = ua_next, ub_now = ub_next;
            ua_next = ua;
            ub_next = ub;
            ua = ua_now;
            ub = ub_now;
        }
        integrate(m, &s, ua, ub, (double)cfg->Ts_s);
        ++k;
    }
}

static const run_options_t NOMINAL_RUN = {540.0, 1.0, P2D_PHASE_COUNT, 0.0, 0, 0, P2D_PHASE_COUNT, 0.0};

/*
 * The paper's drive (presets/paper-condition-2.toml): surface PMSM, Rs = 0.5 ohm,
 * Ld = Lq = 10 mH, psi_f = 0.2 Wb, p = 4, J = 0.4 kg m^2 without friction,
 * 540 V DC link, 10 kHz current loop.
 */
static motor_t paper_drive(void)
{
    motor_t m = {0.5, 0.01, 0.01, 0.2, 4, 0.4, 0.0, 0.0, 0.0, 0};
    return m;
}

/* Commissioning of the paper's drive: 3 A, the flux test at 100 rad/s (electrical, 239 rpm). */
static p2d_commission_config_t paper_config(void)
{
    p2d_commission_config_t cfg;
    cfg.Ts_s = 1e-4f;
    cfg.i_test_A = 3.0f;
    cfg.i_spin_A = 3.0f;
    cfg.i_trip_A = 6.0f;
    cfg.tau_i_s = 2e-3f;
    cfg.t_align_s = 4.0f;
    cfg.t_level_s = 0.2f;
    cfg.t_inductance_s = 0.1f;
    cfg.t_ramp_s = 10.0f;
    cfg.t_spin_s = 2.0f;
    cfg.w_e_spin_radps = 100.0f;
    cfg.voltage_delay_samples = 0u;
    return cfg;
}

/* A salient servo: Rs = 0.8 ohm, Ld = 4 mH, Lq = 8 mH, psi_f = 0.05 Wb, p = 4, 48 V DC link. */
static motor_t servo(void)
{
    motor_t m = {0.8, 4e-3, 8e-3, 0.05, 4, 2e-4, 1e-5, 0.0, 0.0, 0};
    return m;
}

static p2d_commission_config_t servo_config(void)
{
    p2d_commission_config_t cfg = paper_config();
    cfg.i_test_A = 2.0f;
    cfg.i_spin_A = 1.5f;
    cfg.i_trip_A = 4.0f;
    cfg.tau_i_s = 1e-3f;
    cfg.t_align_s = 0.2f;
    cfg.t_level_s = 0.05f;
    cfg.t_inductance_s = 0.05f;
    cfg.t_ramp_s = 0.5f;
    cfg.t_spin_s = 0.5f;
    cfg.w_e_spin_radps = 300.0f;
    return cfg;
}

/* Relative error of an estimate */
static double rel(double estimate, double truth) { return fabs(estimate - truth) / truth; }

static void report(const char *name, const p2d_commission_t *c, const motor_t *m)
{
    printf("%s: %s; Rs %.5g (%+.3f %%), Ld %.5g (%+.3f %%), Lq %.5g (%+.3f %%), psi_f %.5g (%+.3f %%), u_err %.3g V, "
           "asymmetry %.3g, Rs spread %.3g, uq ratio %.3g, coherence %.4f, psi_f spread %.3g, slip %.3g\n",
           name, p2d_commission_phase_name(c->phase), (double)c->Rs_ohm, 100.0 * ((double)c->Rs_ohm / m->Rs_ohm - 1.0),
           (double)c->Ld_H, 100.0 * ((double)c->Ld_H / m->Ld_H - 1.0), (double)c->Lq_H,
           100.0 * ((double)c->Lq_H / m->Lq_H - 1.0), (double)c->psi_f_Wb,
           100.0 * ((double)c->psi_f_Wb / m->psi_f_Wb - 1.0), (double)c->u_err_V, (double)c->asymmetry,
           (double)c->rs_spread, (double)c->uq_ratio, (double)c->coherence, (double)c->psi_spread, (double)c->slip);
}

/* Every estimate within tol of the truth, relative */
static void check_estimates(const p2d_commission_t *c, const motor_t *m, double tol_Rs, double tol_Ld, double tol_Lq,
                            double tol_psi)
{
    CHECK(c->phase == P2D_PHASE_DONE);
    CHECK(c->reason == P2D_REASON_NONE);
    CHECK_CLOSE(rel(c->Rs_ohm, m->Rs_ohm), 0.0, tol_Rs);
    CHECK_CLOSE(rel(c->Ld_H, m->Ld_H), 0.0, tol_Ld);
    CHECK_CLOSE(rel(c->Lq_H, m->Lq_H), 0.0, tol_Lq);
    CHECK_CLOSE(rel(c->psi_f_Wb, m->psi_f_Wb), 0.0, tol_psi);
}

static p2d_status_t init_with(p2d_commission_config_t cfg)
{
    p2d_commission_t c;
    return p2d_commission_init(&c, &cfg);
}

static void test_validation(void)
{
    p2d_commission_config_t cfg;
    p2d_commission_t c;
    CHECK(init_with(paper_config()) == P2D_OK);
    CHECK(p2d_commission_init(0, &cfg) == P2D_ERR_NULL);
    cfg = paper_config();
    CHECK(p2d_commission_init(&c, 0) == P2D_ERR_NULL);
    cfg.Ts_s = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = paper_config();
    cfg.tau_i_s = 9.9e-4f; /* < 10 Ts */
    CHECK(init_with(cfg) == P2D_ERR_TAU_I);
    cfg.tau_i_s = NAN;
    CHECK(init_with(cfg) == P2D_ERR_TAU_I);
    cfg = paper_config();
    cfg.i_test_A = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_I_TEST);
    cfg = paper_config();
    cfg.i_spin_A = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_I_SPIN);
    cfg = paper_config();
    cfg.i_trip_A = 4.4f; /* < 1.5 * 3 A */
    CHECK(init_with(cfg) == P2D_ERR_I_TRIP);
    cfg.i_trip_A = 4.5f;
    CHECK(init_with(cfg) == P2D_OK);
    cfg.i_trip_A = 2e19f; /* its square overflows float32 */
    CHECK(init_with(cfg) == P2D_ERR_I_TRIP);
    cfg.i_test_A = cfg.i_spin_A = 1e-20f;
    cfg.i_trip_A = 1e-19f; /* its square is subnormal */
    CHECK(init_with(cfg) == P2D_ERR_I_TRIP);
    cfg = paper_config();
    cfg.t_align_s = 0.039f; /* < 20 tau_i */
    CHECK(init_with(cfg) == P2D_ERR_T_ALIGN);
    cfg.t_align_s = 0.04f;
    CHECK(init_with(cfg) == P2D_OK);
    cfg.t_align_s = 1e4f; /* > 2^24 Ts */
    CHECK(init_with(cfg) == P2D_ERR_T_ALIGN);
    cfg = paper_config();
    cfg.t_level_s = NAN;
    CHECK(init_with(cfg) == P2D_ERR_T_LEVEL);
    cfg = paper_config();
    cfg.t_inductance_s = 6.3e-3f; /* < 64 Ts */
    CHECK(init_with(cfg) == P2D_ERR_T_INDUCTANCE);
    cfg = paper_config();
    cfg.t_ramp_s = 9e-3f; /* < 100 Ts */
    CHECK(init_with(cfg) == P2D_ERR_T_RAMP);
    cfg = paper_config();
    cfg.t_spin_s = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_T_SPIN);
    cfg = paper_config();
    cfg.w_e_spin_radps = 1001.0f; /* w_e Ts > 0.1 */
    CHECK(init_with(cfg) == P2D_ERR_W_E_SPIN);
    cfg.w_e_spin_radps = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_W_E_SPIN);
    cfg = paper_config();
    cfg.voltage_delay_samples = 2u;
    CHECK(init_with(cfg) == P2D_ERR_VOLTAGE_DELAY);
    /* a rejected init leaves the routine as it was */
    cfg = paper_config();
    CHECK(p2d_commission_init(&c, &cfg) == P2D_OK);
    {
        p2d_commission_t before = c;
        cfg.i_test_A = 0.0f;
        CHECK(p2d_commission_init(&c, &cfg) == P2D_ERR_I_TEST);
        CHECK(memcmp(&before, &c, sizeof c) == 0);
    }
    for (int s = P2D_ERR_I_TEST; s <= P2D_ERR_VOLTAGE_DELAY; ++s) {
        CHECK(p2d_status_param((p2d_status_t)s)[0] != '\0' && p2d_status_range((p2d_status_t)s)[0] != '\0');
    }
    CHECK(strcmp(p2d_status_param(P2D_ERR_W_E_SPIN), "w_e_spin_radps") == 0);
}

static void test_names(void)
{
    CHECK(strcmp(p2d_commission_phase_name(P2D_PHASE_PROBE), "probe") == 0);
    CHECK(strcmp(p2d_commission_phase_name(P2D_PHASE_FAILED), "failed") == 0);
    CHECK(strcmp(p2d_commission_phase_name(P2D_PHASE_COUNT), "unknown") == 0);
    CHECK(p2d_commission_reason_text(P2D_REASON_NONE)[0] == '\0');
    for (int r = 1; r < P2D_REASON_COUNT; ++r)
        CHECK(strlen(p2d_commission_reason_text((p2d_commission_reason_t)r)) > 20);
    CHECK(strcmp(p2d_commission_reason_text(P2D_REASON_COUNT), "unknown reason") == 0);
}

/* The paper's drive, ideal inverter: every estimate within 0.5 %, the inverter error 0 */
static void test_paper_drive(void)
{
    motor_t m = paper_drive();
    p2d_commission_config_t cfg = paper_config();
    p2d_commission_t c;
    run(&m, &cfg, &NOMINAL_RUN, &c);
    report("paper drive, ideal inverter", &c, &m);
    check_estimates(&c, &m, 0.005, 0.005, 0.005, 0.005);
    CHECK_CLOSE(c.u_err_V, 0.0, 0.01);
    CHECK(c.asymmetry < 0.01f && c.coherence > 0.99f);
    CHECK(c.fault_count == 0u && c.w_e_radps == 0.0f);
}

/*
 * The paper's drive through a real inverter: 4 V dead-time error per phase
 * (the u_dt of about 0.75 us at 10 kHz on 540 V), one period of computation
 * delay, 1 % current noise. The two-level Rs cancels the dead time, which
 * would add (4/3) 4 V / 3 A = 1.8 ohm to a one-level Rs.
 */
static void test_paper_drive_real_inverter(void)
{
    motor_t m = paper_drive();
    p2d_commission_config_t cfg = paper_config();
    p2d_commission_t c;
    m.u_dt_V = 4.0;
    m.delay = 1;
    m.noise_A = 0.03;
    cfg.voltage_delay_samples = 1u;
    run(&m, &cfg, &NOMINAL_RUN, &c);
    report("paper drive, dead time, delay, noise", &c, &m);
    check_estimates(&c, &m, 0.02, 0.02, 0.02, 0.01);
    /* the error of the dead time at a current along phase a: (4/3) u_dt */
    CHECK_CLOSE(c.u_err_V, 4.0 / 3.0 * 4.0, 0.3);
}

/* A salient servo from several rotor positions, with a real inverter */
static void test_salient_servo(void)
{
    const double starts[] = {0.0, 1.0, 2.5, -2.0};
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    for (unsigned i = 0; i < sizeof starts / sizeof starts[0]; ++i) {
        run_options_t o = NOMINAL_RUN;
        p2d_commission_t c;
        o.u_dc_V = 48.0;
        o.theta0_rad = starts[i];
        m.u_dt_V = i % 2 ? 0.5 : 0.0;
        m.delay = (int)(i / 2);
        m.noise_A = 0.01;
        cfg.voltage_delay_samples = (uint32_t)m.delay;
        run(&m, &cfg, &o, &c);
        report("salient servo", &c, &m);
        check_estimates(&c, &m, 0.02, 0.02, 0.02, 0.01);
    }
}

static void expect_failure(const char *name, const p2d_commission_t *c, p2d_commission_phase_t phase,
                           p2d_commission_reason_t reason)
{
    printf("%s: failed in %s: %s\n", name, p2d_commission_phase_name(c->failed_phase),
           p2d_commission_reason_text(c->reason));
    CHECK(c->phase == P2D_PHASE_FAILED);
    CHECK(c->failed_phase == phase);
    CHECK(c->reason == reason);
}

/*
 * A load of 0.3 kt i_test on the shaft once the rotor is aligned (from
 * RS_LOW on): the lower Rs level lets it turn the salient rotor asin(0.6) =
 * 37 degrees (electrical) off the frame, the upper one back to asin(0.3) =
 * 17.5 degrees, and the inductance tests see it 17.5 degrees off: the
 * diagonal alone would read Ld 4.7 % high (1 / (G_sum + G_diff cos 35 deg)
 * against 1 / (G_sum + G_diff)); the eigenvalues of the admittance matrix
 * give both inductances, and the still rotor keeps the matrix symmetric.
 * With levels of 0.3 s the damping settles both swings in their first half;
 * with levels of 50 ms it does not, the swing's back-EMF would put Rs 14 %
 * high, and the early and late half-windows disagree: the routine stops.
 */
static void test_rotor_under_load(void)
{
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    p2d_commission_t c;
    run_options_t o = NOMINAL_RUN;
    o.u_dc_V = 48.0;
    o.load_from = P2D_PHASE_RS_LOW;
    o.T_load_Nm = 0.3 * 1.5 * 4 * 0.05 * 2.0;
    cfg.t_level_s = 0.3f;
    run(&m, &cfg, &o, &c);
    report("salient servo under 0.3 kt i_test of load", &c, &m);
    check_estimates(&c, &m, 0.02, 0.02, 0.02, 0.01);
    CHECK(c.asymmetry < 0.05f && c.rs_spread < 0.02f);
    cfg.t_level_s = 0.05f;
    run(&m, &cfg, &o, &c);
    expect_failure("the same with 50 ms levels", &c, P2D_PHASE_RS_HIGH, P2D_REASON_ROTOR_MOVED);
    CHECK(c.rs_spread > 0.02f);
}

/*
 * A salient servo (Lq = 3 Ld) under 0.2 Nm of load from the start, 90 ms
 * levels: the rotor creeps towards the equilibrium of each level (42 then
 * 20 degrees off the frame) through the averaging windows, slowly enough that
 * Rs of their early and late halves agree within 0.5 %, while its back-EMF
 * would put Rs 7 % high; the mean q voltage of a still rotor is 0, and its
 * 3 % of ud_high - ud_low stops the routine.
 */
static void test_rotor_creeping_under_load(void)
{
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    p2d_commission_t c;
    run_options_t o = NOMINAL_RUN;
    m.Lq_H = 12e-3;
    o.u_dc_V = 48.0;
    o.load_from = P2D_PHASE_PROBE;
    o.T_load_Nm = 0.2;
    cfg.t_level_s = 0.09f;
    run(&m, &cfg, &o, &c);
    expect_failure("salient servo creeping under 0.2 Nm", &c, P2D_PHASE_RS_HIGH, P2D_REASON_ROTOR_MOVED);
    CHECK(c.uq_ratio > 0.02f && c.rs_spread < 0.02f && rel(c.Rs_ohm, m.Rs_ohm) > 0.05);
}

/* The injection does not depend on the delay: the same motor with and without it */
static void test_inductance_delay_independent(void)
{
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    p2d_commission_t c0, c1;
    run_options_t o = NOMINAL_RUN;
    o.u_dc_V = 48.0;
    run(&m, &cfg, &o, &c0);
    m.delay = 1;
    cfg.voltage_delay_samples = 1u;
    run(&m, &cfg, &o, &c1);
    CHECK(c0.phase == P2D_PHASE_DONE && c1.phase == P2D_PHASE_DONE);
    CHECK_CLOSE(rel(c1.Ld_H, c0.Ld_H), 0.0, 2e-3);
    CHECK_CLOSE(rel(c1.Lq_H, c0.Lq_H), 0.0, 2e-3);
}

static void test_failures(void)
{
    p2d_commission_t c;
    {
        /* a DC link too low for any current: 2 V */
        motor_t m = paper_drive();
        p2d_commission_config_t cfg = paper_config();
        run_options_t o = NOMINAL_RUN;
        o.u_dc_V = 2.0;
        run(&m, &cfg, &o, &c);
        expect_failure("2 V DC link", &c, P2D_PHASE_PROBE, P2D_REASON_CURRENT_NOT_REACHED);
    }
    {
        /* enough for the injection, not for 3 A through 5 ohm */
        motor_t m = paper_drive();
        p2d_commission_config_t cfg = paper_config();
        run_options_t o = NOMINAL_RUN;
        m.Rs_ohm = 5.0;
        o.u_dc_V = 20.0;
        run(&m, &cfg, &o, &c);
        expect_failure("3 A through 5 ohm on 20 V", &c, P2D_PHASE_ALIGN, P2D_REASON_CURRENT_NOT_REACHED);
    }
    {
        /* current sensing of the wrong sign: the loop runs away */
        motor_t m = paper_drive();
        p2d_commission_config_t cfg = paper_config();
        run_options_t o = NOMINAL_RUN;
        o.invert_sensing = 1;
        run(&m, &cfg, &o, &c);
        expect_failure("inverted current sensing", &c, P2D_PHASE_ALIGN, P2D_REASON_OVERCURRENT);
    }
    {
        /* a load of half the holding torque from the start of LQ turns the salient rotor */
        motor_t m = servo();
        p2d_commission_config_t cfg = servo_config();
        run_options_t o = NOMINAL_RUN;
        o.u_dc_V = 48.0;
        o.load_from = P2D_PHASE_LQ;
        o.T_load_Nm = 0.5 * 1.5 * 4 * 0.05 * 2.0;
        run(&m, &cfg, &o, &c);
        expect_failure("load during LQ", &c, P2D_PHASE_LQ, P2D_REASON_ROTOR_MOVED);
        CHECK(c.asymmetry > 0.05f);
    }
    {
        /* a locked rotor cannot follow the I-f frame */
        motor_t m = paper_drive();
        p2d_commission_config_t cfg = paper_config();
        m.J_kgm2 = 1e9;
        run(&m, &cfg, &NOMINAL_RUN, &c);
        expect_failure("locked rotor", &c, P2D_PHASE_SPIN, P2D_REASON_SPEED_NOT_REACHED);
        CHECK(c.coherence < 0.9f);
    }
    {
        /*
         * a ramp to 300 rad/s in 15 ms asks 1 Nm of a rotor that 1.5 A gives 0.45 Nm: it slips; its
         * saliency leaves a still, coherent psi_a, but one against the current
         */
        motor_t m = servo();
        p2d_commission_config_t cfg = servo_config();
        run_options_t o = NOMINAL_RUN;
        o.u_dc_V = 48.0;
        m.B_Nms = 0.0;
        cfg.t_ramp_s = 0.015f;
        run(&m, &cfg, &o, &c);
        expect_failure("salient rotor that slips", &c, P2D_PHASE_SPIN, P2D_REASON_SPEED_NOT_REACHED);
        CHECK(c.coherence > 0.9f);
    }
    {
        /*
         * from SPIN on another machine holds the rotor at 0.9 w_e_spin: its back-EMF stands still in
         * magnitude (no swing), turns by only 0.3 rad in the 10 ms window (coherent), and would give
         * psi_f 10 % low; the slip, 10 % of the frame's speed, stops the routine
         */
        motor_t m = servo();
        p2d_commission_config_t cfg = servo_config();
        run_options_t o = NOMINAL_RUN;
        o.u_dc_V = 48.0;
        o.drive_from = P2D_PHASE_SPIN;
        o.w_drive_e_radps = 0.9 * 300.0;
        cfg.t_spin_s = 0.02f;
        run(&m, &cfg, &o, &c);
        expect_failure("rotor driven at 0.9 w_e_spin", &c, P2D_PHASE_SPIN, P2D_REASON_SPEED_NOT_REACHED);
        CHECK(c.slip > 0.05f && c.coherence > 0.9f && c.psi_spread < 0.02f);
    }
    {
        /* 400 rad/s needs 20 V of back-EMF: more than 24 V / sqrt(3) */
        motor_t m = servo();
        p2d_commission_config_t cfg = servo_config();
        run_options_t o = NOMINAL_RUN;
        o.u_dc_V = 24.0;
        cfg.w_e_spin_radps = 400.0f;
        run(&m, &cfg, &o, &c);
        expect_failure("flux test beyond the DC link", &c, P2D_PHASE_RAMP_UP, P2D_REASON_VOLTAGE_LIMIT);
    }
    {
        /* 30 ohm against w0 L = 15.7 ohm at 2.5 kHz: the injection sees the resistance, not L */
        motor_t m = paper_drive();
        p2d_commission_config_t cfg = paper_config();
        m.Rs_ohm = 30.0;
        m.Ld_H = m.Lq_H = 1e-3;
        cfg.i_test_A = 0.5f;
        cfg.i_spin_A = 0.5f;
        cfg.i_trip_A = 1.0f;
        run(&m, &cfg, &NOMINAL_RUN, &c);
        expect_failure("30 ohm, 1 mH at 10 kHz", &c, P2D_PHASE_LQ, P2D_REASON_NOT_IDENTIFIABLE);
        CHECK_CLOSE(rel(c.Rs_ohm, 30.0), 0.0, 0.01);
    }
}

/* Non-finite measurements: zero voltage, fault raised and counted, the routine unchanged */
static void test_non_finite_policy(void)
{
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    p2d_commission_t c, before;
    p2d_commission_output_t out;
    run_options_t o = NOMINAL_RUN;
    CHECK(p2d_commission_init(&c, &cfg) == P2D_OK);
    for (int k = 0; k < 37; ++k) p2d_commission_step(&c, 0.01f * (float)k, 0.0f, 48.0f, &out);
    before = c;
    p2d_commission_step(&c, NAN, 0.0f, 48.0f, &out);
    CHECK(out.fault && out.ud_V == 0.0f && out.uq_V == 0.0f && c.fault_count == 1u);
    before.fault_count = 1u;
    CHECK(memcmp(&before, &c, sizeof c) == 0);
    p2d_commission_step(&c, 0.0f, INFINITY, 48.0f, &out);
    p2d_commission_step(&c, 0.0f, 0.0f, NAN, &out);
    CHECK(out.fault && c.fault_count == 3u && c.k == before.k && c.phase == before.phase);
    /* a NaN every 1000 samples through a whole run: the routine finishes, and counted every one */
    o.u_dc_V = 48.0;
    o.nan_every = 1000;
    run(&m, &cfg, &o, &c);
    report("salient servo, a NaN current every 1000 samples", &c, &m);
    check_estimates(&c, &m, 0.02, 0.02, 0.02, 0.01);
    CHECK(c.fault_count > 10u);
}

/* After DONE or FAILED the command is zero, and the routine does not change */
static void test_end_states(void)
{
    motor_t m = servo();
    p2d_commission_config_t cfg = servo_config();
    run_options_t o = NOMINAL_RUN;
    p2d_commission_t c, before;
    p2d_commission_output_t out;
    o.u_dc_V = 48.0;
    run(&m, &cfg, &o, &c);
    CHECK(c.phase == P2D_PHASE_DONE);
    before = c;
    p2d_commission_step(&c, 1.0f, 1.0f, 48.0f, &out);
    CHECK(out.ud_V == 0.0f && out.uq_V == 0.0f && !out.fault && out.phase == P2D_PHASE_DONE);
    CHECK(memcmp(&before, &c, sizeof c) == 0);
    /* overcurrent: the command of the failing sample is already zero */
    CHECK(p2d_commission_init(&c, &cfg) == P2D_OK);
    p2d_commission_step(&c, 4.1f, 0.0f, 48.0f, &out);
    CHECK(out.ud_V == 0.0f && out.uq_V == 0.0f && out.phase == P2D_PHASE_FAILED);
    CHECK(c.phase == P2D_PHASE_FAILED && c.failed_phase == P2D_PHASE_PROBE && c.reason == P2D_REASON_OVERCURRENT);
}

int main(void)
{
    test_validation();
    test_names();
    test_paper_drive();
    test_paper_drive_real_inverter();
    test_salient_servo();
    test_rotor_under_load();
    test_rotor_creeping_under_load();
    test_inductance_delay_independent();
    test_failures();
    test_non_finite_policy();
    test_end_states();
    return check_summary();
}
