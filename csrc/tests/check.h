/*
 * Minimal checks for the C unit tests: each CHECK counts a pass or prints the
 * failing expression with its location; check_summary prints the standard
 * closing line "N passed, M failed" and gives the process exit status.
 */
#ifndef PMSM2DOF_TESTS_CHECK_H
#define PMSM2DOF_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>

static unsigned check_passed;
static unsigned check_failed;

static void check_record(int ok, const char *what, const char *file, int line)
{
    if (ok) {
        check_passed++;
    } else {
        check_failed++;
        printf("FAIL %s:%d: %s\n", file, line, what);
    }
}

/* |a - b| <= tol, with both numbers printed on failure */
static void check_close_at(double a, double b, double tol, const char *what, const char *file, int line)
{
    int ok = fabs(a - b) <= tol;
    check_record(ok, what, file, line);
    if (!ok) printf("     got %.9g, expected %.9g (tolerance %.3g)\n", a, b, tol);
}

#define CHECK(cond) check_record((cond) ? 1 : 0, #cond, __FILE__, __LINE__)
#define CHECK_CLOSE(a, b, tol) check_close_at((double)(a), (double)(b), (double)(tol), #a " == " #b, __FILE__, __LINE__)

static int check_summary(void)
{
    printf("%u passed, %u failed\n", check_passed, check_failed);
    return check_failed == 0u ? 0 : 1;
}

#endif /* PMSM2DOF_TESTS_CHECK_H */
