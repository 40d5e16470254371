/*
 * Piecewise-linear schedules (schedule.h), the engine's p2d_schedule_t played
 * by the firmware and the virtual board.
 */
#include "schedule.h"

#include <math.h>

bool schedule_valid(const schedule_t *s)
{
    for (uint32_t i = 0; i < s->n; ++i) {
        if (!isfinite(s->t_s[i]) || !isfinite(s->value[i]) || !isfinite(s->ramp_s[i]) || s->t_s[i] < 0.0 ||
            s->ramp_s[i] < 0.0 || (i > 0u && s->t_s[i] < s->t_s[i - 1u])) {
            return false;
        }
    }
    return true;
}

double schedule_segment_value(const schedule_segment_t *seg, double t_s)
{
    if (seg->ramp_s > 0.0 && t_s < seg->t0_s + seg->ramp_s) {
        return seg->v0 + (seg->v1 - seg->v0) * fmax(t_s - seg->t0_s, 0.0) / seg->ramp_s;
    }
    return seg->v1;
}

schedule_segment_t schedule_segment_at(const schedule_t *s, double t_s)
{
    schedule_segment_t seg = {0.0, 0.0, 0.0, 0.0, 0u};
    while (seg.next < s->n && s->t_s[seg.next] <= t_s) {
        double t_entry = s->t_s[seg.next];
        seg.v0 = schedule_segment_value(&seg, t_entry);
        seg.t0_s = t_entry;
        seg.v1 = s->value[seg.next];
        seg.ramp_s = s->ramp_s[seg.next];
        seg.next++;
    }
    return seg;
}

double schedule_value(const schedule_t *s, double t_s, double tol_s)
{
    schedule_segment_t seg = schedule_segment_at(s, t_s + tol_s);
    return schedule_segment_value(&seg, t_s);
}
