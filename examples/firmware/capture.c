/*
 * The triggered capture buffer (capture.h): records of the signals in a ring
 * at the control interrupt, a trigger, then read out by UPLOAD.
 */
#include "capture.h"

#include <string.h>

capture_config_t capture_config;
capture_status_t capture_status_now;
uint64_t capture_buffer[CAPTURE_BYTES / 8u];

static capture_config_t armed;                      /* the capture under way */
static const uint8_t *sources[CAPTURE_SIGNALS_MAX]; /* where each signal is read */
static uint32_t post_left;                          /* records still to write after the trigger's [-] */
static float previous;                              /* the trigger signal at the last sample */

static uint32_t record_bytes(const capture_config_t *c)
{
    uint32_t bytes = 0u;
    for (uint32_t i = 0; i < c->n && i < CAPTURE_SIGNALS_MAX; ++i) bytes += c->size[i];
    return bytes;
}

bool capture_valid(const capture_config_t *c)
{
    if (c->command > 2u) return false;
    if (c->command != 1u) return true;
    if (c->event > 1u || c->n < 1u || c->n > CAPTURE_SIGNALS_MAX || c->trigger > 3u || c->samples < 1u ||
        c->pre_samples >= c->samples) {
        return false;
    }
    for (uint32_t i = 0; i < c->n; ++i) {
        if (c->size[i] != 1u && c->size[i] != 2u && c->size[i] != 4u && c->size[i] != 8u) return false;
    }
    if ((c->trigger == 1u || c->trigger == 2u) && (c->trigger_signal >= c->n || c->size[c->trigger_signal] != 4u)) {
        return false;
    }
    return c->samples <= CAPTURE_BYTES / record_bytes(c);
}

void capture_command(const capture_config_t *c, const uint8_t *const *source)
{
    capture_status_t *s = &capture_status_now;
    if (c->command == 2u) s->state = CAPTURE_IDLE;
    if (c->command != 1u) return;
    armed = *c;
    for (uint32_t i = 0; i < c->n; ++i) sources[i] = source[i];
    s->state = CAPTURE_ARMED;
    s->arms++;
    s->record_bytes = record_bytes(c);
    s->written = 0u;
    s->first = 0u;
    s->trigger_period = 0u;
}

/* The trigger at this record: the crossing between the last sample and this one, or the run's start; only once
   the pre_samples records before it are in the buffer. */
static bool triggered(float now, bool run_start)
{
    uint32_t before = capture_status_now.written - 1u; /* records before this one [-] */
    if (before < armed.pre_samples) return false;
    switch (armed.trigger) {
    case 0: return true;
    case 1: return before > 0u && previous < armed.level && now >= armed.level;
    case 2: return before > 0u && previous > armed.level && now <= armed.level;
    default: return run_start;
    }
}

void capture_sample(bool speed, bool run_start, uint32_t period)
{
    capture_status_t *s = &capture_status_now;
    uint8_t *record;
    float now = 0.0f;
    if ((s->state != CAPTURE_ARMED && s->state != CAPTURE_TRIGGERED) || (armed.event == 1u && !speed)) return;
    record = (uint8_t *)capture_buffer + (s->written % armed.samples) * s->record_bytes;
    for (uint32_t i = 0; i < armed.n; ++i) {
        memcpy(record, sources[i], armed.size[i]);
        record += armed.size[i];
    }
    if (armed.trigger == 1u || armed.trigger == 2u) memcpy(&now, sources[armed.trigger_signal], sizeof now);
    s->written++;
    if (s->state == CAPTURE_ARMED && triggered(now, run_start)) {
        s->state = CAPTURE_TRIGGERED;
        s->trigger_period = period;
        post_left = armed.samples - armed.pre_samples;
    }
    previous = now;
    if (s->state == CAPTURE_TRIGGERED && --post_left == 0u) {
        s->first = s->written % armed.samples;
        s->state = CAPTURE_DONE;
    }
}
