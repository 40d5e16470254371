/*
 * pmsm2dof: second-order notch and low-pass filters (biquads) of a command.
 *
 * The speed controller runs them on its torque command, inside its
 * anti-windup loop (p2d_speed_set_filter, pmsm2dof/speed.h): a torsional
 * resonance of the drive train is a peak of the loop gain that the notch
 * cancels and the low-pass rolls off. p2d_filter_t runs the same chain on any
 * other signal.
 *
 * Designs, f0 the filter frequency and w0 = 2 pi f0:
 *   notch     H_n(s) = (s^2 + d B s + w0^2) / (s^2 + B s + w0^2)        |H_n(j w0)| = d, the depth
 *   low-pass  H_l(s) = w0^2 / (s^2 + 2 zeta w0 s + w0^2)               |H_l(j w0)| = 1 / (2 zeta)
 * Both have unit gain at DC, the notch also at high frequency. The chain is
 * notch then low-pass, each on when its frequency is > 0.
 *
 * Discretization: Tustin with prewarping at f0, s = (w0 / g) (z - 1) / (z + 1)
 * with g = tan(pi f0 Ts), so that the discrete response at f0 is the
 * continuous one: the notch has exactly the depth d at f0, the low-pass
 * exactly 1 / (2 zeta) (-3 dB at f0 for zeta = 1/sqrt(2)). The notch width W
 * is its -3 dB bandwidth (|H| = 1/sqrt(2), so d < 1/sqrt(2)), exact in the
 * discrete filter: with v = tan(pi f Ts) the prewarped frequency of f, the
 * -3 dB points of H_n satisfy v1 v2 = g^2 and v2 - v1 = B_v sqrt(1 - 2 d^2)
 * (B_v the denominator's bandwidth in v), and tan(pi W Ts) =
 * tan(pi (f2 - f1) Ts) = (v2 - v1) / (1 + v1 v2), hence
 *   B_v = (1 + g^2) tan(pi W Ts) / sqrt(1 - 2 d^2).
 * (The bandwidth relation of the bilinear notch: S. J. Orfanidis, Introduction
 * to Signal Processing, Prentice Hall 1996, section 11.3.)
 *
 * Realization: each section is a state-variable filter whose two integrators
 * are trapezoidal, the loop solved for the current sample (the
 * "topology-preserving transform" of V. Zavalishin, The Art of VA Filter
 * Design, rev. 2.1.2, 2020, chapters 3 and 4). With k = B_v / g (notch) or
 * k = 2 zeta (low-pass) and h = 1 / (1 + g (g + k)), the band-pass is
 * v1 = h s1 + g h (x - s2); written with 1 - h = g h (g + k), per sample:
 *   v1 = s1 + g h (x - s2 - g s1 - k s1)   band-pass, v1 / x = g q / (q^2 + k g q + g^2), q = (z - 1)/(z + 1)
 *   v2 = s2 + g v1                         low-pass,  v2 / x = g^2 / (q^2 + k g q + g^2)
 *   notch: y = x - (1 - d) k v1            low-pass: y = v2
 *   s1 <- 2 v1 - s1,  s2 <- 2 v2 - s2
 * With the rounded coefficients g, k, g h the realized denominator is
 *   (1 - g h (g + k)) q^2 + (g h) k q + g (g h),
 * so the frequency (g g h) and the damping (g h k) are products of stored
 * numbers, exact to float32 precision at any f0 Ts however small, and the
 * section is stable iff g h (g + k) < 1.
 * Why not a direct form (DF2T): for f0 << 1/Ts its poles sit near z = 1, and
 * the coefficients a1 = -2 + O((w0 Ts)^2), a2 = 1 - O(w0 Ts) hold the
 * frequency only in their last bits: 1 + a1 + a2 ~ (w0 Ts)^2 is a difference
 * of numbers near 2, so in float32 the frequency and the DC gain
 * (b0 + b1 + b2) / (1 + a1 + a2) are off by about 1e-7 / (w0 Ts)^2 (1 % at
 * f0 = Ts^-1 / 2000), and the damping, in 1 + a2, by about 1e-7 / (zeta w0 Ts).
 * Here the DC gain is exactly 1 (at rest at a constant input x the state is
 * s1 = 0, s2 = x and every output equals x exactly), and the states hold
 * the signal (s2) and its scaled rate (s1), not differences of large partial
 * sums. Coming from elsewhere, the float32 recursion settles within its dead
 * band, about ulp(x) / (2 g k) from x, where the state increments round away:
 * 6e-5 of x at f0 Ts = 1e-4 (zeta = 0.7), where a float32 direct form settles
 * 16 % off (tests/test_torque_filter.py); inside the speed loop the integrator
 * takes up such an offset.
 *
 * Validation: a configuration is accepted only if every coefficient is finite
 * and each realized section holds its design in float32: g g h and g h k are
 * normal numbers, and 1 + g (g + k) = 1/h <= 4001, so that the q^2
 * coefficient 1 - g h (g + k), which loses precision as h -> 0, is within
 * 1e-3 of h (and positive: the section is stable). That bounds f0 Ts to about
 * 0.495 (g <= 63) and the damping to zeta g <= 2000, B_v <= 4000.
 *
 * Non-finite policy: a non-finite input or output gives y = 0 with `fault`
 * set, no state update, fault_count incremented. Parameter updates: the shadow
 * coefficient set of pi.h (see speed.h), the states kept; a section switched
 * on starts at rest at the last accepted input, so that at a constant input
 * nothing jumps (the state at rest does not depend on the coefficients).
 *
 * Portable C99, float32, no allocation, no global state. [U] is the unit of
 * the filtered signal ([Nm] for the torque command).
 */
#ifndef PMSM2DOF_FILTER_H
#define PMSM2DOF_FILTER_H

#include <stdbool.h>
#include <stdint.h>

#include "pmsm2dof/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Design inputs of the filter chain (the sampling period is its user's). All 0: no filter. */
typedef struct {
    float notch_freq_Hz;   /* notch frequency f0 [Hz], >= 0: 0 for no notch, else < 1/(2 Ts_s) */
    float notch_width_Hz;  /* -3 dB bandwidth of the notch [Hz], >= 0; with a notch > 0, < 1/(2 Ts_s) */
    float notch_depth;     /* gain at f0, |H(f0)| [-], >= 0 and < 0.7071067811865476 = 1/sqrt(2) (0.1: -20 dB) */
    float lowpass_freq_Hz; /* low-pass natural frequency f0 [Hz], >= 0: 0 for no low-pass, else < 1/(2 Ts_s) */
    float lowpass_zeta;    /* low-pass damping [-], >= 0; with a low-pass > 0 (1/sqrt(2): -3 dB at f0, no peak) */
} p2d_filter_config_t;

/* Coefficients of one section (see the file comment). */
typedef struct {
    float g;      /* tan(pi f0 Ts): one trapezoidal integration step, prewarped at f0 [-] */
    float k;      /* damping of the denominator: B_v / g (notch), 2 zeta (low-pass) [-] */
    float g_h;    /* g h = g / (1 + g (g + k)) [-] */
    float c_band; /* notch: weight -(1 - d) k of the band-pass v1 in the output [-]; low-pass: 0 (unused) */
} p2d_biquad_coef_t;

/* Coefficients of the chain. */
typedef struct {
    p2d_biquad_coef_t notch;   /* notch section, used when has_notch */
    p2d_biquad_coef_t lowpass; /* low-pass section, used when has_lowpass */
    bool has_notch;            /* notch_freq_Hz > 0 */
    bool has_lowpass;          /* lowpass_freq_Hz > 0 */
} p2d_filter_coef_t;

/* State of one section: its two trapezoidal integrators. */
typedef struct {
    float s1; /* band-pass integrator [U]; 0 at rest */
    float s2; /* low-pass integrator [U]; the input itself at rest */
} p2d_biquad_state_t;

/* State of the chain. */
typedef struct {
    p2d_biquad_state_t notch;   /* [U] */
    p2d_biquad_state_t lowpass; /* [U] */
} p2d_filter_state_t;

typedef struct {
    p2d_filter_coef_t coef[2];  /* active and shadow coefficient sets */
    uint32_t active;            /* index of the active set, 0 or 1 */
    p2d_filter_config_t config; /* configuration of the active set */
    float Ts_s;                 /* sampling period [s], > 0 */
    p2d_filter_state_t state;   /* section states [U] */
    float x_prev;               /* input of the last accepted sample [U]: where a section switched on starts */
    uint32_t fault_count;       /* samples rejected by the non-finite policy [-] */
} p2d_filter_t;

typedef struct {
    float y;    /* filtered signal [U] */
    bool fault; /* non-finite policy engaged: y is 0 */
} p2d_filter_output_t;

/*
 * Validate cfg and the sampling period Ts_s (finite, > 0) and precompute; on error f is left
 * unchanged. The state starts at rest at 0.
 */
p2d_status_t p2d_filter_init(p2d_filter_t *f, const p2d_filter_config_t *cfg, float Ts_s);

/* Validate cfg at the Ts_s of init into the shadow set and swap it in; the state is kept. On error nothing changes. */
p2d_status_t p2d_filter_set_config(p2d_filter_t *f, const p2d_filter_config_t *cfg);

/* The state at rest at the constant input x (output x). A non-finite x rests at 0 and counts a fault. */
void p2d_filter_reset(p2d_filter_t *f, float x);

/* One sample: y = H(z) x. */
void p2d_filter_step(p2d_filter_t *f, float x, p2d_filter_output_t *out);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_FILTER_H */
