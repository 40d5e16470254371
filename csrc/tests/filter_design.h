/*
 * The designs of pmsm2dof/filter.h written out by hand, in double, for the C
 * unit tests: the continuous prototypes mapped by the bilinear transform with
 * prewarping, as difference equations in direct form (a realization other
 * than the filter's state-variable one).
 */
#ifndef PMSM2DOF_TESTS_FILTER_DESIGN_H
#define PMSM2DOF_TESTS_FILTER_DESIGN_H

#include <math.h>

#include "pmsm2dof/filter.h"

static const double PI = 3.14159265358979323846;

/*
 * The designed discrete filter in direct form, in double, from the continuous
 * prototype N(s)/D(s) = (n2 s^2 + n1 w0 s + n0 w0^2) / (s^2 + d1 w0 s + w0^2)
 * and s = (w0 / g) (z - 1)/(z + 1): multiplying by (z + 1)^2 g^2 / w0^2,
 *   N -> n2 (z - 1)^2 + n1 g (z - 1)(z + 1) + n0 g^2 (z + 1)^2, and D alike.
 */
typedef struct {
    double b[3], a[3]; /* b0 + b1 z^-1 + b2 z^-2 over 1 + a1 z^-1 + a2 z^-2 */
} direct_form_t;

static inline direct_form_t bilinear(double n2, double n1, double n0, double d1, double g)
{
    direct_form_t df;
    double a0 = 1.0 + d1 * g + g * g;
    df.b[0] = (n2 + n1 * g + n0 * g * g) / a0;
    df.b[1] = (-2.0 * n2 + 2.0 * n0 * g * g) / a0;
    df.b[2] = (n2 - n1 * g + n0 * g * g) / a0;
    df.a[0] = 1.0;
    df.a[1] = (-2.0 + 2.0 * g * g) / a0;
    df.a[2] = (1.0 - d1 * g + g * g) / a0;
    return df;
}

/* |H(e^{j w Ts})| of a direct form */
static inline double gain(const direct_form_t *df, double w_Ts)
{
    double nr = df->b[0] + df->b[1] * cos(w_Ts) + df->b[2] * cos(2.0 * w_Ts);
    double ni = -df->b[1] * sin(w_Ts) - df->b[2] * sin(2.0 * w_Ts);
    double dr = 1.0 + df->a[1] * cos(w_Ts) + df->a[2] * cos(2.0 * w_Ts);
    double di = -df->a[1] * sin(w_Ts) - df->a[2] * sin(2.0 * w_Ts);
    return sqrt((nr * nr + ni * ni) / (dr * dr + di * di));
}

/* The notch of cfg at Ts: d1 = B / w0 with B_v = (1 + g^2) tan(pi W Ts) / sqrt(1 - 2 d^2) = g B / w0. */
static inline direct_form_t notch_design(const p2d_filter_config_t *cfg, double Ts)
{
    double g = tan(PI * cfg->notch_freq_Hz * Ts), d = cfg->notch_depth;
    double B_v = (1.0 + g * g) * tan(PI * cfg->notch_width_Hz * Ts) / sqrt(1.0 - 2.0 * d * d);
    return bilinear(1.0, d * B_v / g, 1.0, B_v / g, g);
}

static inline direct_form_t lowpass_design(const p2d_filter_config_t *cfg, double Ts)
{
    double g = tan(PI * cfg->lowpass_freq_Hz * Ts);
    return bilinear(0.0, 0.0, 1.0, 2.0 * cfg->lowpass_zeta, g);
}

/* One sample of a direct form, y = b0 x[k] + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]. */
typedef struct {
    double x[2], y[2]; /* x[k-1], x[k-2] and y[k-1], y[k-2] */
} direct_state_t;

static inline double direct_step(const direct_form_t *df, direct_state_t *s, double x)
{
    double y = df->b[0] * x + df->b[1] * s->x[0] + df->b[2] * s->x[1] - df->a[1] * s->y[0] - df->a[2] * s->y[1];
    s->x[1] = s->x[0];
    s->x[0] = x;
    s->y[1] = s->y[0];
    s->y[0] = y;
    return y;
}

#endif /* PMSM2DOF_TESTS_FILTER_DESIGN_H */
