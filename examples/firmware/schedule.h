/*
 * A piecewise-linear schedule of a signal, as the engine plays its reference
 * and load (csrc/sim/drive.h, p2d_schedule_t): 0 before the first entry; entry
 * i moves from the value reached at t_s[i] to value[i] in a step (ramp_s[i] = 0)
 * or linearly over ramp_s[i]. The firmware's link plays the speed reference
 * with it, the virtual board the load. Double precision, as the engine, so that
 * a run played on the firmware meets the engine's at the same instants.
 */
#ifndef SCHEDULE_H
#define SCHEDULE_H

#include <stdbool.h>
#include <stdint.h>

/* The entries of a schedule (arrays of n entries, owned by the caller). */
typedef struct {
    const double *t_s;    /* entry times [s], finite, >= 0, nondecreasing */
    const double *value;  /* targets [unit of the signal], finite */
    const double *ramp_s; /* ramp durations [s], finite, >= 0 */
    uint32_t n;           /* number of entries [-] */
} schedule_t;

/* The segment of a schedule in force at some time. */
typedef struct {
    double t0_s;   /* its start [s] */
    double v0;     /* value at its start [unit of the signal] */
    double v1;     /* its target [unit of the signal] */
    double ramp_s; /* its ramp duration [s]; 0: a step */
    uint32_t next; /* index of the first entry not entered [-] */
} schedule_segment_t;

/* True when every entry is finite, the times >= 0 and nondecreasing, the ramps >= 0. */
bool schedule_valid(const schedule_t *s);

/* The segment in force once every entry with t_s[i] <= t_s has started. */
schedule_segment_t schedule_segment_at(const schedule_t *s, double t_s);

/* The value of a segment at t_s: v0 + (v1 - v0) (t - t0) / ramp during the ramp, v1 after. */
double schedule_segment_value(const schedule_segment_t *seg, double t_s);

/* The schedule's value at t_s, the entries within tol_s of t_s started [unit of the signal]. */
double schedule_value(const schedule_t *s, double t_s, double tol_s);

#endif /* SCHEDULE_H */
