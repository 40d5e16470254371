/*
 * Unit tests of the dq current controllers (pmsm2dof/current.h). Expected
 * values come from the dq model (paper eq 1), the loop design of eq 3 and an
 * exactly discretized RL circuit, all in double.
 */
#include <string.h>

#include "check.h"
#include "pmsm2dof/current.h"

/* Rs = 0.5 ohm, Ld = 2 mH, Lq = 3 mH, psi_f = 0.05 Wb, tau_i = 1 ms, Ts = 10 us */
static p2d_current_config_t base_config(void)
{
    p2d_current_config_t cfg;
    cfg.Rs_ohm = 0.5f;
    cfg.Ld_H = 2e-3f;
    cfg.Lq_H = 3e-3f;
    cfg.psi_f_Wb = 0.05f;
    cfg.tau_i_s = 1e-3f;
    cfg.Ts_s = 1e-5f;
    cfg.method = P2D_TUSTIN;
    cfg.anti_windup = P2D_AW_BACK_CALCULATION;
    cfg.decouple = true;
    return cfg;
}

static p2d_status_t init_with(p2d_current_config_t cfg)
{
    p2d_current_t ctl;
    return p2d_current_init(&ctl, &cfg);
}

static void test_validation(void)
{
    p2d_current_config_t cfg;
    CHECK(init_with(base_config()) == P2D_OK);
    cfg = base_config();
    cfg.Rs_ohm = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_RS);
    cfg = base_config();
    cfg.Ld_H = NAN;
    CHECK(init_with(cfg) == P2D_ERR_LD);
    cfg = base_config();
    cfg.Lq_H = -1.0f;
    CHECK(init_with(cfg) == P2D_ERR_LQ);
    cfg = base_config();
    cfg.psi_f_Wb = -0.1f;
    CHECK(init_with(cfg) == P2D_ERR_PSI_F);
    cfg = base_config();
    cfg.psi_f_Wb = 0.0f;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = base_config();
    cfg.Ts_s = 0.0f;
    CHECK(init_with(cfg) == P2D_ERR_TS);
    cfg = base_config();
    cfg.tau_i_s = 0.5e-5f;
    CHECK(init_with(cfg) == P2D_ERR_TAU_I);
    cfg = base_config();
    cfg.tau_i_s = INFINITY;
    CHECK(init_with(cfg) == P2D_ERR_TAU_I);
    cfg = base_config();
    cfg.method = (p2d_method_t)9;
    CHECK(init_with(cfg) == P2D_ERR_METHOD);
    cfg = base_config();
    cfg.anti_windup = (p2d_anti_windup_t)9;
    CHECK(init_with(cfg) == P2D_ERR_ANTI_WINDUP);
    /* back calculation loop 1 - Rs Ts / L: Rs Ts / Ld = 2.5 is unstable; without back calculation it is no pole */
    cfg = base_config();
    cfg.Rs_ohm = 500.0f;
    CHECK(init_with(cfg) == P2D_ERR_TS_UNSTABLE);
    cfg.anti_windup = P2D_AW_CLAMPING;
    CHECK(init_with(cfg) == P2D_OK);
    cfg = base_config();
    CHECK(p2d_current_init(0, &cfg) == P2D_ERR_NULL);
}

static void test_gains(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    const p2d_current_coef_t *c;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    c = &ctl.coef[ctl.active];
    /* eq 3 design: Kp = L / tau_i, Ki = Rs / tau_i */
    CHECK_CLOSE(c->d.Kp, 2.0, 1e-6);
    CHECK_CLOSE(c->q.Kp, 3.0, 1e-6);
    CHECK_CLOSE(c->d.Ki, 500.0, 1e-3);
    CHECK_CLOSE(c->q.Ki, 500.0, 1e-3);
    /* Ka = 1/Kp: Ki Ka Ts = Rs Ts / L */
    CHECK_CLOSE(c->d.Ki_Ka_Ts, 0.5 * 1e-5 / 2e-3, 1e-9);
    CHECK_CLOSE(c->q.Ki_Ka_Ts, 0.5 * 1e-5 / 3e-3, 1e-9);
}

/* At zero current error the output is the decoupling voltage of eq 1 */
static void test_decoupling(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    p2d_current_compute(&ctl, -2.0f, 4.0f, -2.0f, 4.0f, 1000.0f, 600.0f, &out);
    /* ud = -w_e Lq iq = -12 V, uq = w_e (Ld id + psi_f) = 46 V */
    CHECK_CLOSE(out.ud_ref_V, -1000.0 * 3e-3 * 4.0, 1e-4);
    CHECK_CLOSE(out.uq_ref_V, 1000.0 * (2e-3 * -2.0 + 0.05), 1e-4);
    CHECK(!out.saturated && !out.fault);
    cfg.decouple = false;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    p2d_current_compute(&ctl, -2.0f, 4.0f, -2.0f, 4.0f, 1000.0f, 600.0f, &out);
    CHECK(out.ud_ref_V == 0.0f && out.uq_ref_V == 0.0f);
}

/* The limit with d-axis priority: ud to [-u_max, u_max], uq to what is left; integrators bounded with back calculation */
static void test_voltage_limit(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    const double u_max = 48.0 / sqrt(3.0);
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 100000; ++k) p2d_current_step(&ctl, 30.0f, 40.0f, 0.0f, 0.0f, 0.0f, 48.0f, &out);
    CHECK(out.saturated);
    /* ud_unsat > u_max: the whole circle goes to the d axis, none is left for q */
    CHECK(out.ud_unsat_V > u_max && out.uq_unsat_V > 0.0f);
    CHECK_CLOSE(out.ud_ref_V, u_max, 1e-5);
    CHECK(out.uq_ref_V == 0.0f);
    /* per-axis fixed point x* = u_sat - b_e0 e + e / Ka with Ka = 1/Kp: x* = u_sat - (b_e0 - Kp) e */
    CHECK_CLOSE(ctl.x_d_V, out.ud_ref_V - 0.5 * 500.0 * 1e-5 * 30.0, 1e-3);
    CHECK_CLOSE(ctl.x_q_V, 0.0 - 0.5 * 500.0 * 1e-5 * 40.0, 1e-3);

    cfg.anti_windup = P2D_AW_CLAMPING;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 1000; ++k) p2d_current_step(&ctl, 30.0f, 40.0f, 0.0f, 0.0f, 0.0f, 48.0f, &out);
    CHECK(ctl.x_d_V == 0.0f && ctl.x_q_V == 0.0f);

    cfg.anti_windup = P2D_AW_NONE;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 1000; ++k) p2d_current_step(&ctl, 30.0f, 40.0f, 0.0f, 0.0f, 0.0f, 48.0f, &out);
    CHECK_CLOSE(ctl.x_q_V, 1000 * 500.0 * 1e-5 * 40.0, 0.05);

    /* zero or negative DC link: zero voltage */
    p2d_current_compute(&ctl, 1.0f, 1.0f, 0.0f, 0.0f, 0.0f, -5.0f, &out);
    CHECK(out.ud_ref_V == 0.0f && out.uq_ref_V == 0.0f && out.saturated && !out.fault);
    /* a tiny vector (its square underflows) against a zero limit, a huge one (its square overflows) */
    p2d_current_reset(&ctl);
    p2d_current_compute(&ctl, 0.0f, 0.0f, 0.0f, 0.0f, 4e-24f, 0.0f, &out);
    CHECK(out.uq_unsat_V > 0.0f && out.uq_ref_V == 0.0f && out.saturated);
    p2d_current_compute(&ctl, 3e19f, 4e19f, 0.0f, 0.0f, 0.0f, 48.0f, &out);
    CHECK(out.saturated && out.ud_ref_V == (float)(48.0 / sqrt(3.0)) && out.uq_ref_V == 0.0f);
    /* near the float32 range: u_max^2 would overflow, u_max + |ud| too (1.7e38 + 1.7e38) */
    p2d_current_compute(&ctl, -1e38f, -1e38f, 0.0f, 0.0f, 0.0f, 3e38f, &out);
    CHECK(!out.fault && out.saturated && out.uq_ref_V == 0.0f);
    CHECK_CLOSE(out.ud_ref_V, -3e38 / sqrt(3.0), 1e-6 * 3e38 / sqrt(3.0));
    /* ud inside, uq beyond: uq takes sqrt(u_max^2 - ud^2) with its own sign */
    p2d_current_compute(&ctl, 5.0f, -40.0f, 0.0f, 0.0f, 0.0f, 48.0f, &out);
    {
        double ud = (2.0 + 0.5 * 500.0 * 1e-5) * 5.0;
        CHECK(out.saturated && out.ud_ref_V == out.ud_unsat_V);
        CHECK_CLOSE(out.ud_ref_V, ud, 1e-5);
        CHECK_CLOSE(out.uq_ref_V, -sqrt(u_max * u_max - ud * ud), 1e-5);
    }
}

/*
 * d-axis priority in closed loop: the dq model of eq 1 at a constant electrical speed
 * w_e = 500 rad/s, 48 V DC link (u_max = 27.7 V), id_ref = 0 and iq_ref = 40 A, which needs
 * uq = Rs iq + w_e psi_f = 45 V. In steady state the d axis, not limited, holds id = 0, so
 * ud = -w_e Lq iq and uq = Rs iq + w_e psi_f lie on the circle:
 *   (w_e^2 Lq^2 + Rs^2) iq^2 + 2 Rs w_e psi_f iq + (w_e psi_f)^2 - u_max^2 = 0,
 *   iq = (-25 + sqrt(25^2 + 4 * 2.5 * 143)) / 5 = 4.066 A with the base configuration.
 * The plant: forward Euler in double, 100 steps per Ts, the voltage held over the period
 * (its fixed point is the steady state of eq 1 exactly).
 */
static void test_d_axis_priority_holds_id_at_the_voltage_limit(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    const double Rs = 0.5, Ld = 2e-3, Lq = 3e-3, psi = 0.05, w_e = 500.0, u_max = 48.0 / sqrt(3.0);
    const double a = w_e * w_e * Lq * Lq + Rs * Rs, b = 2.0 * Rs * w_e * psi, c = w_e * w_e * psi * psi - u_max * u_max;
    const double iq_ss = (-b + sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
    const double h = 1e-5 / 100.0;
    double id = 0.0, iq = 0.0;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 40000; ++k) {
        p2d_current_step(&ctl, 0.0f, 40.0f, (float)id, (float)iq, (float)w_e, 48.0f, &out);
        for (int j = 0; j < 100; ++j) {
            /* eq 1: L di/dt = u - Rs i -+ w_e (cross-coupling, back-EMF) */
            double did = (out.ud_ref_V - Rs * id + w_e * Lq * iq) / Ld;
            double diq = (out.uq_ref_V - Rs * iq - w_e * (Ld * id + psi)) / Lq;
            id += h * did;
            iq += h * diq;
        }
    }
    CHECK(out.saturated && out.ud_ref_V == out.ud_unsat_V);
    CHECK(fabs(id) < 1e-4);
    CHECK_CLOSE(iq, iq_ss, 1e-3 * iq_ss);
    CHECK_CLOSE(sqrt((double)out.ud_ref_V * out.ud_ref_V + (double)out.uq_ref_V * out.uq_ref_V), u_max, 1e-5);
}

static void test_non_finite_policy(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    float xd, xq;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    p2d_current_step(&ctl, 1.0f, 2.0f, 0.0f, 0.0f, 100.0f, 300.0f, &out);
    xd = ctl.x_d_V;
    xq = ctl.x_q_V;
    p2d_current_step(&ctl, 1.0f, 2.0f, NAN, 0.0f, 100.0f, 300.0f, &out);
    CHECK(out.fault && out.ud_ref_V == 0.0f && out.uq_ref_V == 0.0f);
    CHECK(ctl.x_d_V == xd && ctl.x_q_V == xq && ctl.fault_count == 1u);
    /* a NaN DC-link measurement is a fault, not a zero voltage limit */
    p2d_current_step(&ctl, 1.0f, 2.0f, 0.0f, 0.0f, 100.0f, NAN, &out);
    CHECK(out.fault && ctl.x_d_V == xd && ctl.x_q_V == xq && ctl.fault_count == 2u);
    p2d_current_step(&ctl, 1.0f, 2.0f, 0.0f, 0.0f, INFINITY, 300.0f, &out);
    CHECK(out.fault && ctl.fault_count == 3u);
    /* one axis alone not finite: a NaN d reference, an infinite q reference */
    p2d_current_step(&ctl, NAN, 2.0f, 0.0f, 0.0f, 100.0f, 300.0f, &out);
    CHECK(out.fault && out.ud_ref_V == 0.0f && out.uq_ref_V == 0.0f && ctl.fault_count == 4u);
    p2d_current_step(&ctl, 1.0f, INFINITY, 0.0f, 0.0f, 100.0f, 300.0f, &out);
    CHECK(out.fault && ctl.fault_count == 5u && ctl.x_d_V == xd && ctl.x_q_V == xq);
}

/*
 * Closed loop on the q-axis RL circuit at standstill, discretized exactly (ZOH):
 * i[k+1] = a i[k] + (1 - a) u[k] / Rs, a = exp(-Rs Ts / Lq).
 * Eq 3: the loop follows 1 / (tau_i s + 1); at t = tau_i the current is 1 - 1/e.
 */
static void test_first_order_loop(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    const double Rs = 0.5, Lq = 3e-3, Ts = 1e-5, tau = 1e-3;
    const double a = exp(-Rs * Ts / Lq);
    double iq = 0.0;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    for (int k = 0; k < 500; ++k) {
        if (k == 100) CHECK_CLOSE(iq, 1.0 - exp(-1.0), 0.01);
        p2d_current_step(&ctl, 0.0f, 1.0f, 0.0f, (float)iq, 0.0f, 1000.0f, &out);
        iq = a * iq + (1.0 - a) * out.uq_ref_V / Rs;
    }
    CHECK_CLOSE(iq, 1.0 - exp(-500 * Ts / tau), 0.01);
}

/* Parameter update: invalid changes nothing; valid keeps the integrators */
static void test_set_config(void)
{
    p2d_current_config_t cfg = base_config();
    p2d_current_t ctl;
    p2d_current_output_t out;
    p2d_current_t before;
    CHECK(p2d_current_init(&ctl, &cfg) == P2D_OK);
    p2d_current_step(&ctl, 1.0f, 2.0f, 0.0f, 0.0f, 0.0f, 300.0f, &out);
    before = ctl;
    cfg.Rs_ohm = -1.0f;
    CHECK(p2d_current_set_config(&ctl, &cfg) == P2D_ERR_RS);
    CHECK(ctl.active == before.active && ctl.config.Rs_ohm == 0.5f);
    cfg.Rs_ohm = 1.0f;
    CHECK(p2d_current_set_config(&ctl, &cfg) == P2D_OK);
    CHECK(ctl.active != before.active && ctl.x_q_V == before.x_q_V);
    CHECK_CLOSE(ctl.coef[ctl.active].q.Ki, 1000.0, 1e-3);
    p2d_current_reset(&ctl);
    CHECK(ctl.x_d_V == 0.0f && ctl.x_q_V == 0.0f);
}

int main(void)
{
    test_validation();
    test_gains();
    test_decoupling();
    test_voltage_limit();
    test_d_axis_priority_holds_id_at_the_voltage_limit();
    test_non_finite_policy();
    test_first_order_loop();
    test_set_config();
    return check_summary();
}
