/*
 * Field-oriented control with the pmsm2dof controllers (paper Fig. 1: speed
 * controller of Fig. 6 outside, dq current controllers inside).
 *
 * Every control interrupt (1 / Ts_current, 10 kHz here):
 *   currents -> Clarke -> Park -> current controller -> inverse Park -> SVPWM
 * and every FOC_SPEED_DIVIDER-th interrupt (1 kHz) first the speed controller,
 * whose current references are then held for the next FOC_SPEED_DIVIDER
 * current samples.
 *
 * Each controller runs as compute, apply, update: the update receives the
 * command that was actually applied after every limit downstream, which is
 * what makes the back-calculation anti-windup (Fig. 5) see the true u*.
 */
#include "foc.h"

#include <math.h>

#include "board.h"
#include "pmsm2dof/current.h"
#include "pmsm2dof/speed.h"
#include "pmsm2dof/transforms.h"

/*
 * Generated in the build by `pmsm2dof design ... --emit-c-header p2d_design.h`
 * (see CMakeLists.txt): p2d_design_speed_config and p2d_design_current_config.
 */
#include "p2d_design.h"

static p2d_speed_t speed_ctl;     /* speed controller state */
static p2d_current_t current_ctl; /* dq current controllers state */
static float pole_pairs;          /* p [-] */
static uint32_t tick;             /* control interrupts since the last speed sample, 0 .. FOC_SPEED_DIVIDER-1 */
static float id_ref_A;            /* d-axis current reference, held between speed samples [A] */
static float iq_ref_A;            /* q-axis current reference, held between speed samples [A] */

bool foc_init(uint32_t *rate_hz)
{
    float Ts_speed_s = p2d_design_speed_config.Ts_s;
    float Ts_current_s = p2d_design_current_config.Ts_s;

    if (p2d_speed_init(&speed_ctl, &p2d_design_speed_config) != P2D_OK) return false;
    if (p2d_current_init(&current_ctl, &p2d_design_current_config) != P2D_OK) return false;
    /* the speed controller was designed for Ts_speed = FOC_SPEED_DIVIDER * Ts_current */
    if (fabsf(Ts_speed_s - (float)FOC_SPEED_DIVIDER * Ts_current_s) > 1e-6f * Ts_speed_s) return false;
    pole_pairs = (float)p2d_design_speed_config.pole_pairs;
    tick = 0u;
    id_ref_A = 0.0f;
    iq_ref_A = 0.0f;
    *rate_hz = (uint32_t)(1.0f / Ts_current_s + 0.5f);
    return true;
}

/*
 * Space-vector modulation by min-max zero-sequence injection: linear for
 * ||u_ab|| <= u_dc / sqrt(3), the limit the current controller enforces.
 * Writes the duty cycles; returns true when a duty had to be clipped to
 * [0, 1], and then in *u_alpha_app_V, *u_beta_app_V the voltage actually
 * applied.
 */
static bool svpwm(float u_alpha_V, float u_beta_V, float u_dc_V, float *u_alpha_app_V, float *u_beta_app_V)
{
    float u[3], duty[3], u_max, u_min;
    bool clipped = false;

    if (!(u_dc_V > 0.0f)) {
        /* no DC link: zero voltage */
        board_write_duties(0.5f, 0.5f, 0.5f);
        *u_alpha_app_V = 0.0f;
        *u_beta_app_V = 0.0f;
        return true;
    }
    p2d_inv_clarke(u_alpha_V, u_beta_V, &u[0], &u[1], &u[2]);
    u_max = u[0] > u[1] ? u[0] : u[1];
    u_max = u_max > u[2] ? u_max : u[2];
    u_min = u[0] < u[1] ? u[0] : u[1];
    u_min = u_min < u[2] ? u_min : u[2];
    for (int n = 0; n < 3; ++n) {
        /* duty = 1/2 + (u - (u_max + u_min)/2) / u_dc, clipped to [0, 1] */
        float d = 0.5f + (u[n] - 0.5f * (u_max + u_min)) / u_dc_V;
        duty[n] = d < 0.0f ? 0.0f : (d > 1.0f ? 1.0f : d);
        clipped = clipped || duty[n] != d;
        /* phase voltage applied, up to the common mode that the Clarke transform removes */
        u[n] = (duty[n] - 0.5f) * u_dc_V;
    }
    board_write_duties(duty[0], duty[1], duty[2]);
    p2d_clarke(u[0], u[1], u[2], u_alpha_app_V, u_beta_app_V);
    return clipped;
}

void foc_isr(void)
{
    float ia_A, ib_A, ic_A, i_alpha_A, i_beta_A, id_A, iq_A;
    float theta_m_rad, w_m_radps, sin_e, cos_e, w_e_radps, u_dc_V;
    float u_alpha_V, u_beta_V, u_alpha_app_V, u_beta_app_V, ud_app_V, uq_app_V;
    p2d_current_output_t cur;

    board_read_phase_currents(&ia_A, &ib_A, &ic_A);
    u_dc_V = board_read_dc_link_V();
    board_read_rotor(&theta_m_rad, &w_m_radps);
    /* electrical angle and speed: theta_e = p theta_m, w_e = p w_m (sinf/cosf: or your sine table, CORDIC) */
    sin_e = sinf(pole_pairs * theta_m_rad);
    cos_e = cosf(pole_pairs * theta_m_rad);
    w_e_radps = pole_pairs * w_m_radps;
    p2d_clarke(ia_A, ib_A, ic_A, &i_alpha_A, &i_beta_A);
    p2d_park(i_alpha_A, i_beta_A, sin_e, cos_e, &id_A, &iq_A);

    /* speed loop, every FOC_SPEED_DIVIDER-th interrupt */
    if (tick == 0u) {
        p2d_speed_output_t spd;
        p2d_speed_compute(&speed_ctl, board_speed_reference_radps(), w_m_radps, &spd);
        /*
         * Apply. The references go to the current loop as computed, so the
         * applied torque is spd.T_ref_Nm (zero after a fault: non-finite
         * speed). A further limit here (thermal derating, ...) must change
         * the current references and pass its limited torque to the update.
         */
        id_ref_A = spd.id_ref_A;
        iq_ref_A = spd.iq_ref_A;
        p2d_speed_update(&speed_ctl, &spd, spd.T_ref_Nm);
    }
    tick = tick + 1u == FOC_SPEED_DIVIDER ? 0u : tick + 1u;

    /* current loop, every interrupt */
    p2d_current_compute(&current_ctl, id_ref_A, iq_ref_A, id_A, iq_A, w_e_radps, u_dc_V, &cur);
    p2d_inv_park(cur.ud_ref_V, cur.uq_ref_V, sin_e, cos_e, &u_alpha_V, &u_beta_V);
    if (svpwm(u_alpha_V, u_beta_V, u_dc_V, &u_alpha_app_V, &u_beta_app_V)) {
        /* the modulator limited the voltage: the integrators must see what it applied, in dq */
        p2d_park(u_alpha_app_V, u_beta_app_V, sin_e, cos_e, &ud_app_V, &uq_app_V);
    } else {
        /*
         * applied as commanded: pass the command itself, not its round trip
         * through the transforms, whose rounding would make u* a tiny non-zero
         * value (and flip the clamping mode's sign test at random)
         */
        ud_app_V = cur.ud_ref_V;
        uq_app_V = cur.uq_ref_V;
    }
    p2d_current_update(&current_ctl, &cur, ud_app_V, uq_app_V);
}
