/*
 * The discrete PI building block of the speed and the current controllers:
 * see pi.h.
 */
#include "pi.h"

p2d_pi_coef_t p2d_pi_coefficients(float Kp, float Ki, float Ts_s, p2d_method_t method)
{
    p2d_pi_coef_t pi;
    pi.Kp = Kp;
    pi.Ki = Ki;
    pi.Ki_Ts = Ki * Ts_s;
    pi.Ki_Ka_Ts = 0.0f;
    /* eq 14 and Table 1: the weight of e[k] in u[k] */
    if (method == P2D_FORWARD_EULER) {
        pi.b_e0 = Kp;
    } else if (method == P2D_BACKWARD_EULER) {
        pi.b_e0 = Kp + pi.Ki_Ts;
    } else {
        pi.b_e0 = Kp + 0.5f * pi.Ki_Ts;
    }
    return pi;
}

bool p2d_pi_finite(const p2d_pi_coef_t *pi)
{
    return isfinite(pi->Kp) && isfinite(pi->Ki) && isfinite(pi->b_e0) && isfinite(pi->Ki_Ts) && isfinite(pi->Ki_Ka_Ts);
}
