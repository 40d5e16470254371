/*
 * Unit tests of the Clarke and Park transforms and the MTPA split
 * (pmsm2dof/transforms.h), against the definitions computed in double.
 */
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

int main(void)
{
    test_balanced_set_gives_constant_dq();
    test_round_trips();
    test_mtpa();
    return check_summary();
}
