/*
 * Unit tests of the Clarke and Park transforms and the MTPA split
 * (pmsm2dof/transforms.h), against the definitions computed in double.
 */
#include <float.h>

#include "check.h"
#include "pmsm2dof/transforms.h"

static const double PI = 3.14159265358979323846;

/* A balanced set of amplitude I at electrical angle th + phi maps to the constant dq vector I (cos phi, sin phi). */
static void test_balanced_set_gives_constant_dq(void)
{
    const double I = 7.0, phi = 0.6;
    for (int k = 0; k < 36; ++k) {
        double th = 2.0 * PI * k / 36.0;
        float al, be, d, q;
        p2d_clarke((float)(I * cos(th + phi)), (float)(I * cos(th + phi - 2.0 * PI / 3.0)),
                   (float)(I * cos(th + phi + 2.0 * PI / 3.0)), &al, &be);
        /* amplitude invariance: |x_alpha beta| = I */
        CHECK_CLOSE(sqrt((double)al * al + (double)be * be), I, 1e-5);
        p2d_park(al, be, (float)sin(th), (float)cos(th), &d, &q);
        CHECK_CLOSE(d, I * cos(phi), 1e-5);
        CHECK_CLOSE(q, I * sin(phi), 1e-5);
    }
}

static void test_round_trips(void)
{
    for (int k = 0; k < 20; ++k) {
        double th = 0.37 * k - 3.0;
        float a, b, c, al, be, al2, be2, d, q;
        float a0 = (float)(3.0 * sin(0.9 * k)), b0 = (float)(2.0 * cos(1.3 * k));
        float c0 = -a0 - b0; /* no zero sequence */
        p2d_clarke(a0, b0, c0, &al, &be);
        p2d_inv_clarke(al, be, &a, &b, &c);
        CHECK_CLOSE(a, a0, 1e-5);
        CHECK_CLOSE(b, b0, 1e-5);
        CHECK_CLOSE(c, c0, 1e-5);
        p2d_park(al, be, (float)sin(th), (float)cos(th), &d, &q);
        p2d_inv_park(d, q, (float)sin(th), (float)cos(th), &al2, &be2);
        CHECK_CLOSE(al2, al, 1e-5);
        CHECK_CLOSE(be2, be, 1e-5);
        /* Park is a rotation: the length is kept */
        CHECK_CLOSE((double)d * d + (double)q * q, (double)al * al + (double)be * be, 1e-4);
    }
    /* a zero-sequence component is removed by Clarke */
    {
        float al, be, al0, be0;
        p2d_clarke(1.0f, 2.0f, -0.5f, &al0, &be0);
        p2d_clarke(11.0f, 12.0f, 9.5f, &al, &be);
        CHECK_CLOSE(al, al0, 1e-5);
        CHECK_CLOSE(be, be0, 1e-5);
    }
}

/*
 * MTPA: for a current of length I, the torque psi_f iq + dL id iq is maximal over the
 * current angle; p2d_mtpa_id_A must give that id for the corresponding iq.
 */
static void test_mtpa(void)
{
    const double psi = 0.05, dL = -4e-3;
    CHECK(p2d_mtpa_id_A(5.0f, 0.05f, 0.0f) == 0.0f);
    for (int n = 1; n <= 10; ++n) {
        double I = 10.0 * n, best_T = -1.0, best_id = 0.0, best_iq = 0.0;
        /* brute-force search of the current angle, then a finer search around the best */
        for (int pass = 0; pass < 2; ++pass) {
            double centre = pass == 0 ? 0.5 * PI : atan2(best_iq, best_id);
            double width = pass == 0 ? 0.5 * PI : 1e-3;
            for (int j = 0; j <= 20000; ++j) {
                double ang = centre - width + 2.0 * width * j / 20000.0;
                double id = I * cos(ang), iq = I * sin(ang);
                double T = psi * iq + dL * id * iq;
                if (T > best_T) {
                    best_T = T;
                    best_id = id;
                    best_iq = iq;
                }
            }
        }
        CHECK_CLOSE(p2d_mtpa_id_A((float)best_iq, 0.05f, -4e-3f), best_id, 1e-4 * I);
        CHECK_CLOSE(p2d_mtpa_id_A((float)-best_iq, 0.05f, -4e-3f), best_id, 1e-4 * I);
    }
}

/*
 * MTPA over the whole float32 range: machines from 1e-30 Wb to 1e10 Wb of magnet
 * flux (and none), inductance differences from 1e-30 H to 1e5 H, currents from
 * 1e-30 A to 1e30 A, where psi_f^2 or (2 dL iq)^2 overflow or underflow in
 * float32. Expected: id = iq x / (psi_f + hypot(psi_f, x)), x = 2 dL iq, in
 * double (no square of it leaves the double range here), to a relative 1e-6,
 * wherever x and id are normal float32 numbers.
 */
static void test_mtpa_extreme_machines(void)
{
    const double psis[] = {0.0, 1e-30, 1e-20, 0.05, 1e10};
    const double dLs[] = {-1e-30, -4e-3, -1e5, 3e-3};
    const double iqs[] = {1e-30, 1e-3, 5.0, 1e15, 1e30};
    double worst = 0.0;
    int checked = 0;
    for (unsigned a = 0; a < sizeof psis / sizeof psis[0]; ++a) {
        for (unsigned b = 0; b < sizeof dLs / sizeof dLs[0]; ++b) {
            for (unsigned c = 0; c < 2u * sizeof iqs / sizeof iqs[0]; ++c) {
                const double psi = psis[a], dL = dLs[b], iq = (c % 2u ? -1.0 : 1.0) * iqs[c / 2u];
                const double x = 2.0 * dL * iq;
                const double id = x == 0.0 && psi == 0.0 ? 0.0 : iq * x / (psi + hypot(psi, x));
                const float got = p2d_mtpa_id_A((float)iq, (float)psi, (float)dL);
                /* x and the exact id must be normal float32 numbers (or 0) */
                if (fabs(x) > FLT_MAX || (x != 0.0 && fabs(x) < FLT_MIN) || (id != 0.0 && fabs(id) < FLT_MIN)) continue;
                checked++;
                CHECK(isfinite(got));
                worst = fmax(worst, id == 0.0 ? fabs(got) : fabs(got - id) / fabs(id));
            }
        }
    }
    printf("MTPA id over extreme machines: %d cases, worst relative error %.3g\n", checked, worst);
    CHECK(checked > 100);
    CHECK(worst < 1e-6);
    /* no magnet (synchronous reluctance): id = sign(dL) |iq|, and 0 at zero current */
    CHECK(p2d_mtpa_id_A(3.0f, 0.0f, -1e-3f) == -3.0f);
    CHECK(p2d_mtpa_id_A(0.0f, 0.0f, -1e-3f) == 0.0f);
}

int main(void)
{
    test_balanced_set_gives_constant_dq();
    test_round_trips();
    test_mtpa();
    test_mtpa_extreme_machines();
    return check_summary();
}
