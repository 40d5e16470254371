/*
 * pmsm2dof: self-commissioning of a PMSM: Rs, Ld, Lq and psi_f measured by
 * the drive itself, without a datasheet.
 *
 * A state machine called once per current sample. The caller measures the
 * phase currents, transforms them into the routine's dq frame with the angle
 * c->theta_e_rad (the frame's electrical angle at this sample; Park transform
 * of transforms.h), calls p2d_commission_step, and applies the voltage
 * command (out->ud_V, out->uq_V) with the inverse Park transform at the angle
 * out->theta_e_rad. The routine runs the standard sequence:
 *
 *   PROBE      Square-wave voltage +U, -U, -U, +U on d (period 4 Ts, zero
 *              mean, the current ripple centred on its starting value) at
 *              zero current, U raised until the ripple is i_test_A / 2 peak
 *              to peak: a first inductance L_probe for the routine's current
 *              loop, which then has Kp = L_probe / tau_i and its zero at
 *              1 / (4 tau_i), stable without knowing Rs.
 *   ALIGN      The d current ramped to i_test_A over the first half (the
 *              rotor turns its d axis onto the frame's, angle 0), held over
 *              the second. A rotor that swings induces a back-EMF that the
 *              loop's q integrator x_q takes up; the q current reference
 *              -g x_q brakes the swing with the torque of the machine's own
 *              short circuit (psi_f / Rs per unit of speed when g Rs >> 1),
 *              which settles even a frictionless rotor, and is 0 at rest.
 *              g = tau_i / (4 R_zero Ts) keeps the integrator's own loop
 *              stable (g Ki Ts = 1/4, Ki = R_zero / tau_i) without knowing
 *              Rs. The loop's zero then moves to R_hold / L_probe, R_hold =
 *              ud / id over the last eighth (Rs plus the inverter's error
 *              per ampere), if that is higher.
 *   RS_LOW,    The d current held at i_test_A / 2, then at i_test_A, under
 *   RS_HIGH    current control: settling over the first half of t_level_s,
 *              averages of ud and id over the second. The inverter's voltage
 *              error (dead time, switch drops) is about the same at both
 *              levels, so it cancels in
 *                Rs = (ud_high - ud_low) / (id_high - id_low)
 *              and u_err = ud_high - Rs id_high is that error at i_test_A.
 *              A rotor under load turns when the holding current changes;
 *              the damping of ALIGN settles it. Its back-EMF must not
 *              enter Rs: a swing still going makes Rs of the early halves
 *              of the two averaging windows differ from Rs of the late
 *              halves (more than 2 % apart), a slow creep leaves a mean q
 *              voltage that a still rotor does not need (above 2 % of
 *              ud_high - ud_low at either level); either stops the routine.
 *   LD, LQ     The voltage of RS_HIGH held open loop (the rotor stays held
 *              by i_test_A on d, and the phase currents keep their signs, so
 *              the dead-time error stays constant) plus the square wave of
 *              PROBE on d, then on q, its amplitude within what the bias
 *              leaves of the voltage range. The discrete Fourier transform
 *              at the injection frequency w0 = pi / (2 Ts) (weights 1, 0,
 *              -1, 0: no trigonometry) of the voltage on the injected axis x
 *              and of both currents' sample-to-sample differences (|e^(j w0
 *              Ts) - 1| = sqrt(2) times the currents', while a drift of the
 *              bias current turns into a near constant that cancels), over
 *              whole periods, gives the admittance magnitude G_xx = |I_x| /
 *              |U_x| and the cross ratio Re(I_y / I_x). The
 *              exact sampled response of an RL branch to a held (zero-order
 *              hold) voltage, i[k+1] = a i[k] + b u[k - n], a = exp(-Rs Ts / L),
 *              b = (1 - a) / Rs, has a magnitude at w0 that does not depend on
 *              the delay n; solved for L:
 *                L = Rs Ts / (2 asinh(y)),  y = rho sin(w0 Ts / 2) / sqrt(1 - rho^2),
 *                rho = Rs G  (L = Ts / (sqrt(2) G) when Rs = 0).
 *              The admittances of both tests form the matrix G (G_dd, G_qd =
 *              Re(I_q / I_d) G_dd; G_qq, G_dq = Re(I_d / I_q) G_qq); its
 *              eigenvalues give Ld and Lq even when the rotor rests a little
 *              off the frame. A still rotor makes it symmetric: when
 *              |G_qd - G_dq| > 0.05 (G_dd + G_qq) / 2 the rotor moved between or
 *              during the tests. Only a salient rotor shows it, and only a
 *              salient rotor's inductances depend on where it stands.
 *   RAMP_UP,   I-f: the current loop, now Kp = (Ld + Lq) / (2 tau_i),
 *   SPIN,      Ki = Rs / tau_i, holds i_spin_A on the frame's d axis while the
 *   RAMP_DOWN  frame turns at a speed ramped to w_e_spin_radps over t_ramp_s
 *              (an S ramp: constant jerk, acceleration from 0 back to 0, which
 *              excites little of the load-angle oscillation a rotor without
 *              friction keeps); the rotor follows, lagging by the angle its
 *              torque needs, while the inverter's error u_err is fed forward
 *              along its direction for the current reference (each phase's
 *              error follows its current's sign: against the centre of the
 *              60 degree sector of the current's angle). At
 *              w_e_spin_radps, over the second half of t_spin_s, the active
 *              flux (Boldea, Paicu, Andreescu, "Active flux concept for
 *              motion-sensorless unified AC drives", IEEE Trans. Power
 *              Electron. 23(5), 2008) of every sample,
 *                psi_a = (u - Rs i - j w_e Lq i) / (j w_e),
 *              u the current loop's command without that feedforward,
 *              lies on the rotor's d axis with length psi_f + (Ld - Lq) id_r,
 *              id_r the current along it, whatever the load angle:
 *                psi_f = mean |psi_a| - (Ld - Lq) mean id_r.
 *              |psi_a| of a sample is w_r / w_e times the active flux (w_r
 *              the rotor's speed) and psi_a turns in the frame at w_r - w_e:
 *              summed sample by sample over a half-window of n samples, the
 *              angle it turns through gives the rotor's mean speed exactly,
 *              mean w_r / w_e = 1 + s, s = sum dphi / (w_e n Ts), whatever
 *              the rotor did within it (a swing that ends away from where it
 *              began leaves s != 0 however alike the halves look); mean
 *              |psi_a| of each half is divided by its 1 + s. The routine
 *              checks that |s| of the window is at most 2 % (a rotor that
 *              slips, creeps or stalls turns psi_a round), that the means of
 *              psi_a over the window's early and late halves point the same
 *              way, that psi_f of the two halves agrees within 2 % (a rotor
 *              still swinging about the frame), that |sum psi_a| / sum
 *              |psi_a| >= 0.9
 *              ("coherence"), that the current leads psi_a by less than 60
 *              degrees, mean id_r >= i_spin_A / 2 (a rotor that follows lags
 *              on the stable side of pull-out; a stalled salient one leaves
 *              a still psi_a against the current), and that the back-EMF
 *              w_e mean |psi_a| exceeds the drops Rs i_spin_A + |u_err| that
 *              the estimate subtracts; else it stops.
 *              Then the speed is ramped back to zero and the routine ends
 *              (DONE).
 *
 * It ends in DONE with Rs_ohm, Ld_H, Lq_H, psi_f_Wb (per phase, amplitude-
 * invariant dq) or in FAILED with failed_phase and reason: the current did
 * not reach its level (voltage limit, open phase, current sensing), the
 * current exceeded i_trip_A, the rotor moved during the inductance tests,
 * the voltage limit was reached before the flux test's speed, the rotor did
 * not follow the I-f frame, or a quantity was not identifiable from the
 * measurement (p2d_commission_reason_text says which and what to change).
 * DONE and FAILED output a zero voltage for ever.
 *
 * Timing: the voltage computed at sample k is applied voltage_delay_samples
 * periods later, for one period. out->theta_e_rad is the frame's mean angle
 * over that period, theta + w_e Ts (voltage_delay_samples + 1/2), so that
 * the applied vector is the command in the turning frame; the injection
 * tests do not depend on the delay.
 *
 * Means are compensated (Kahan) sums: float32 keeps them to a few ulps over
 * any window length (Kahan, "Further remarks on reducing truncation errors",
 * Comm. ACM 8(1), 1965). Every operation of the step is +, -, *, /, sqrt or
 * fmaf, correctly rounded in IEEE 754: the MCU and the host compute the same
 * bits (build with -ffp-contract=off).
 *
 * Non-finite policy: a NaN or infinite measured current or DC link gives a
 * zero voltage with `fault` set, leaves the routine where it was (its time
 * does not advance) and increments fault_count. The parameters do not change
 * while the routine runs: there is no set_config; p2d_commission_init starts
 * it again.
 *
 * Portable C99, float32, no allocation, no global state.
 */
#ifndef PMSM2DOF_COMMISSION_H
#define PMSM2DOF_COMMISSION_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/current.h"
#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Steps of the sequence, in order; DONE and FAILED end it. */
typedef enum {
    P2D_PHASE_PROBE = 0,     /* square wave on d at zero current: L for the routine's current loop */
    P2D_PHASE_ALIGN = 1,     /* d current ramped to i_test_A, then its voltage held: the rotor aligns */
    P2D_PHASE_RS_LOW = 2,    /* d current i_test_A / 2: first level of Rs */
    P2D_PHASE_RS_HIGH = 3,   /* d current i_test_A: second level of Rs */
    P2D_PHASE_LD = 4,        /* square wave on d over the held bias: Ld */
    P2D_PHASE_LQ = 5,        /* square wave on q over the held bias: Lq */
    P2D_PHASE_RAMP_UP = 6,   /* I-f: frame speed ramped to w_e_spin_radps */
    P2D_PHASE_SPIN = 7,      /* I-f at w_e_spin_radps: psi_f from the back-EMF */
    P2D_PHASE_RAMP_DOWN = 8, /* I-f: frame speed ramped back to 0 */
    P2D_PHASE_DONE = 9,      /* estimates valid; zero voltage */
    P2D_PHASE_FAILED = 10,   /* see failed_phase and reason; zero voltage */
    P2D_PHASE_COUNT          /* number of phases, not a phase */
} p2d_commission_phase_t;

/* Why the routine failed. */
typedef enum {
    P2D_REASON_NONE = 0,            /* not failed */
    P2D_REASON_CURRENT_NOT_REACHED, /* the current did not reach its level */
    P2D_REASON_OVERCURRENT,         /* ||i_dq|| > i_trip_A */
    P2D_REASON_ROTOR_MOVED,         /* the rotor moved during the Rs levels or the inductance tests */
    P2D_REASON_VOLTAGE_LIMIT,       /* u_dc / sqrt(3) reached before or at the flux test's speed */
    P2D_REASON_SPEED_NOT_REACHED,   /* the rotor did not follow the I-f frame (slipped or stalled) */
    P2D_REASON_NOT_IDENTIFIABLE,    /* the measurement does not determine the quantity */
    P2D_REASON_COUNT                /* number of reasons, not a reason */
} p2d_commission_reason_t;

typedef struct {
    float Ts_s;                     /* current sampling period: one step per sample [s], > 0 */
    float i_test_A;                 /* test current: alignment, upper Rs level (the lower is i_test_A / 2),
                                       bias of the inductance tests, twice the ripple [A], > 0 */
    float i_spin_A;                 /* current of the I-f flux test [A], > 0 */
    float i_trip_A;                 /* ||i_dq|| above it ends the routine [A], >= 1.5 max(i_test_A, i_spin_A),
                                       i_trip_A^2 a normal float32 */
    float tau_i_s;                  /* time constant of the routine's current loop (eq 3) [s], >= 10 Ts_s */
    float t_align_s;                /* alignment: current ramp, then voltage hold, half each [s], >= 20 tau_i_s */
    float t_level_s;                /* each Rs level: settling, then averaging, half each [s], >= 20 tau_i_s */
    float t_inductance_s;           /* averaging of each injection test [s], >= 64 Ts_s */
    float t_ramp_s;                 /* I-f speed ramp, up and down [s], >= 100 Ts_s */
    float t_spin_s;                 /* at the flux test's speed: settling, then averaging, half each [s],
                                       >= 20 tau_i_s */
    float w_e_spin_radps;           /* electrical speed of the flux test [rad/s], > 0, w_e_spin_radps Ts_s <= 0.1 */
    uint32_t voltage_delay_samples; /* periods from the current sample to the one that applies its voltage
                                       [-], 0 or 1 */
} p2d_commission_config_t;

/* Compensated (Kahan) sum of float32 samples. */
typedef struct {
    float sum;   /* running sum [unit of the samples] */
    float carry; /* low-order part lost by the last addition, to subtract from the next [unit of the samples] */
} p2d_sum_t;

typedef struct {
    p2d_commission_config_t config; /* configuration */
    uint32_t n_align;               /* ALIGN length [samples] */
    uint32_t n_level;               /* length of each Rs level [samples] */
    uint32_t n_inductance;          /* averaging of each injection test [samples], a multiple of 4 */
    uint32_t n_ramp;                /* each I-f ramp [samples] */
    uint32_t n_spin;                /* SPIN length [samples] */
    float inv_n_ramp;               /* 1 / n_ramp [1/samples] */
    float theta_lead;               /* out->theta_e_rad - theta_e_rad per unit of w_e_radps:
                                       Ts (voltage_delay_samples + 1/2) [s] */

    p2d_commission_phase_t phase;        /* present step of the sequence */
    p2d_commission_phase_t failed_phase; /* step that failed (FAILED only) */
    p2d_commission_reason_t reason;      /* why (FAILED only) */
    uint32_t k;                          /* samples since the present phase started [samples] */
    float theta_e_rad;                   /* frame angle at this sample [rad], in [0, 2 pi) */
    float w_e_radps;                     /* frame speed [rad/s] */
    float id_prev_A;                     /* d current of the previous sample [A] */
    float iq_prev_A;                     /* q current of the previous sample [A] */
    p2d_current_t current;               /* the routine's current loop (closed-loop phases) */
    float u_hold_d_V;                    /* open-loop d voltage of the injection tests [V] */
    float u_hold_q_V;                    /* open-loop q voltage: injection bias [V] */
    float g_damp_A_per_V;                /* standstill damping: q current per volt of the q integrator [A/V] */

    /* square-wave injection (PROBE, LD, LQ) */
    float hf_U_V;         /* square-wave amplitude [V] */
    uint32_t hf_n;        /* sample within the period, 0..3 [-] */
    uint32_t hf_stage;    /* 0 amplitude search, 1 settling, 2 averaging [-] */
    uint32_t hf_periods;  /* periods spent in the stage [-] */
    float hf_ix_c_A;      /* this period's transform of the injected axis' current, cosine part [A] */
    float hf_ix_s_A;      /* sine part [A] */
    float hf_iy_c_A;      /* the other axis' current, cosine part [A] */
    float hf_iy_s_A;      /* sine part [A] */
    float hf_u_c_V;       /* the injected axis' voltage command, cosine part [V] */
    float hf_u_s_V;       /* sine part [V] */
    p2d_sum_t sum_ix_c_A; /* over the averaging periods: hf_ix_c_A [A] */
    p2d_sum_t sum_ix_s_A; /* hf_ix_s_A [A] */
    p2d_sum_t sum_iy_c_A; /* hf_iy_c_A [A] */
    p2d_sum_t sum_iy_s_A; /* hf_iy_s_A [A] */
    p2d_sum_t sum_u_c_V;  /* hf_u_c_V [V] */
    p2d_sum_t sum_u_s_V;  /* hf_u_s_V [V] */

    /* alignment and Rs levels */
    p2d_sum_t sum_ud_V;      /* d voltage command: end of the ALIGN ramp; early half of an Rs window [V] */
    p2d_sum_t sum_id_A;      /* d current: end of the ALIGN hold; early half of an Rs window [A] */
    p2d_sum_t sum_ud_late_V; /* d voltage command over the late half of an Rs window [V] */
    p2d_sum_t sum_id_late_A; /* d current over the late half of an Rs window [A] */
    p2d_sum_t sum_uq_V;      /* q voltage command over an Rs window [V] */
    float ud_low_V;          /* mean d voltage at i_test_A / 2 [V] */
    float uq_low_V;          /* mean q voltage at i_test_A / 2 [V] */
    float id_low_A;          /* mean d current at i_test_A / 2 [A] */
    float ud_low_early_V;    /* the same over the early half-window [V] */
    float id_low_early_A;    /* the same over the early half-window [A] */
    float ud_high_V;         /* mean d voltage at i_test_A [V] */
    float uq_high_V;         /* mean q voltage at i_test_A [V] */
    float id_high_A;         /* mean d current at i_test_A [A] */

    /* injection results */
    float G_dd_A_per_V; /* LD: |I_d| / |U_d| at w0 [A/V] */
    float c_qd;         /* LD: Re(I_q / I_d) [-] */
    float G_qq_A_per_V; /* LQ: |I_q| / |U_q| at w0 [A/V] */
    float c_dq;         /* LQ: Re(I_d / I_q) [-] */

    /* flux test */
    p2d_sum_t sum_psi_Wb;        /* |psi_a| over the early half of the averaging window [Wb] */
    p2d_sum_t sum_psi_late_Wb;   /* |psi_a| over its late half [Wb] */
    p2d_sum_t sum_psi_d_Wb;      /* d component of psi_a in the frame, early half [Wb] */
    p2d_sum_t sum_psi_q_Wb;      /* q component of psi_a in the frame, early half [Wb] */
    p2d_sum_t sum_psi_d_late_Wb; /* d component of psi_a, late half [Wb] */
    p2d_sum_t sum_psi_q_late_Wb; /* q component of psi_a, late half [Wb] */
    p2d_sum_t sum_id_r_A;        /* current along psi_a, id_r, early half [A] */
    p2d_sum_t sum_id_r_late_A;   /* id_r, late half [A] */
    p2d_sum_t sum_turn_rad;      /* angle psi_a turned by in the frame over the early half, (w_r - w_e) dt [rad] */
    p2d_sum_t sum_turn_late_rad; /* the same over the late half [rad] */
    float psi_d_prev_Wb;         /* d component of psi_a at the previous SPIN sample [Wb] */
    float psi_q_prev_Wb;         /* q component of psi_a at the previous SPIN sample [Wb] */

    /* estimates (valid in DONE; those of the finished phases in FAILED) */
    float L_probe_H;  /* PROBE's inductance: the routine's current loop [H] */
    float Rs_ohm;     /* stator resistance [ohm] */
    float u_err_V;    /* inverter voltage error at i_test_A on d [V] */
    float rs_spread;  /* |Rs(late half-windows) - Rs(early ones)| / Rs: the rotor moved when > 0.02 [-] */
    float uq_ratio;   /* max |mean uq| of the Rs levels / (ud_high - ud_low): the rotor crept when > 0.02 [-] */
    float Ld_H;       /* d-axis inductance [H] */
    float Lq_H;       /* q-axis inductance [H] */
    float asymmetry;  /* |G_qd - G_dq| / ((G_dd + G_qq) / 2): rotor moved when > 0.05 [-] */
    float coherence;  /* |sum psi_a| / sum |psi_a| of SPIN: the rotor followed when >= 0.9 [-] */
    float psi_spread; /* |psi_f(late half-window) - psi_f(early)| / psi_f: the rotor swung when > 0.02 [-] */
    float slip;       /* |mean w_r - w_e| / w_e over the averaging window: it did not follow when > 0.02 [-] */
    float psi_f_Wb;   /* permanent-magnet flux linkage [Wb] */

    uint32_t fault_count; /* samples rejected by the non-finite policy [-] */
} p2d_commission_t;

typedef struct {
    float ud_V;                   /* d voltage command in the routine's frame [V] */
    float uq_V;                   /* q voltage command [V] */
    float theta_e_rad;            /* angle of the inverse Park transform of the command [rad], in [0, 2 pi) */
    float w_e_radps;              /* frame speed [rad/s] */
    float id_ref_A;               /* d current reference of the routine's loop; 0 open loop [A] */
    float iq_ref_A;               /* q current reference; 0 open loop [A] */
    p2d_commission_phase_t phase; /* phase that computed this command */
    bool fault;                   /* non-finite policy engaged: zero voltage */
} p2d_commission_output_t;

/* Validate cfg and start the routine at PROBE; on error c is left unchanged. */
p2d_status_t p2d_commission_init(p2d_commission_t *c, const p2d_commission_config_t *cfg);

/*
 * One current sample: id_A, iq_A measured now in the frame at c->theta_e_rad,
 * u_dc_V the DC link; the command to apply into out.
 */
void p2d_commission_step(p2d_commission_t *c, float id_A, float iq_A, float u_dc_V, p2d_commission_output_t *out);

/* Name of a phase ("probe", "align", ..., "failed"); "unknown" out of range. */
const char *p2d_commission_phase_name(p2d_commission_phase_t phase);

/* What a failure reason means and what to change; "" for P2D_REASON_NONE. */
const char *p2d_commission_reason_text(p2d_commission_reason_t reason);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_COMMISSION_H */
