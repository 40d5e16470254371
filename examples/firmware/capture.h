/*
 * The firmware's triggered capture buffer: signals recorded in RAM at the
 * control interrupt, every sample, then read out by the master with UPLOAD
 * after the fact. For what the link cannot stream: a UART at 115200 baud
 * carries some 11 kB/s, four float32 signals at 20 kHz need 320 kB/s.
 *
 * The master writes capture_config (calibration, taken at the next speed
 * sample; link.c checks that every signal lies inside a measurement or
 * calibration segment and refuses the page otherwise) with command 1 (arm):
 * from then on each sample (every control interrupt, or every speed sample)
 * copies the signals' bytes, in their order, into capture_buffer, a ring of
 * `samples` records, until the trigger has come and `samples - pre_samples`
 * records from the trigger's on are written. The trigger:
 *   0  immediate: the first sample after arming
 *   1  rising: the first sample at which the float32 signal trigger_signal
 *      reaches level from below (previous < level <= now), once pre_samples
 *      samples are in the buffer
 *   2  falling: the same downwards (previous > level >= now)
 *   3  the start of a run: the run's first control interrupt (sample 0)
 * capture_status_now tells the state; once done, the oldest record is at
 * `first`, the trigger's `pre_samples` records later (in ring order).
 * The buffer's size is set at build: -DCAPTURE_BYTES=N (a multiple of 8).
 */
#ifndef CAPTURE_H
#define CAPTURE_H

#include <stdbool.h>
#include <stdint.h>

#ifndef CAPTURE_BYTES
#define CAPTURE_BYTES 16384u /* the buffer [bytes]; -DCAPTURE_BYTES=N at build */
#endif
/* Most signals of one capture. */
#define CAPTURE_SIGNALS_MAX 16u

/* What to capture (calibration): written by the master, taken at the next speed sample. */
typedef struct {
    uint32_t command;                      /* 1: arm, 2: disarm, 0: none [-], 0..2 */
    uint32_t event;                        /* 0: every control interrupt (current), 1: every speed sample [-], 0..1 */
    uint32_t n;                            /* signals in use [-], 1..16 */
    uint32_t samples;                      /* records of the capture [-], 1..CAPTURE_BYTES / record bytes */
    uint32_t pre_samples;                  /* records before the trigger's [-], 0..samples - 1 */
    uint32_t trigger;                      /* 0 immediate, 1 rising, 2 falling, 3 start of a run [-], 0..3 */
    uint32_t trigger_signal;               /* the float32 signal a rising or falling trigger watches [-], 0..n - 1 */
    float level;                           /* the level it crosses [the signal's unit] */
    uint32_t address[CAPTURE_SIGNALS_MAX]; /* XCP address of each signal [-] */
    uint32_t size[CAPTURE_SIGNALS_MAX];    /* bytes of each signal [bytes], 1, 2, 4 or 8 */
} capture_config_t;

/* States of a capture (capture_status_t.state). */
enum { CAPTURE_IDLE = 0, CAPTURE_ARMED = 1, CAPTURE_TRIGGERED = 2, CAPTURE_DONE = 3 };

/* What the capture reports (measurement). */
typedef struct {
    uint32_t state;          /* 0 idle, 1 armed (waiting for the trigger), 2 triggered, 3 done [-] */
    uint32_t arms;           /* captures armed since power-up [-] */
    uint32_t record_bytes;   /* bytes of one record: the signals' sizes summed [bytes] */
    uint32_t written;        /* records written since armed [-] */
    uint32_t first;          /* done: the record of the capture's first sample [-] */
    uint32_t trigger_period; /* the link's clock (control interrupts) at the trigger's sample [-] */
} capture_status_t;

extern capture_config_t capture_config;             /* what the master asked for (calibration) */
extern capture_status_t capture_status_now;         /* the capture's report (measurement) */
extern uint64_t capture_buffer[CAPTURE_BYTES / 8u]; /* the records (measurement), read as bytes by UPLOAD */

/* Check a page: counts, sizes, the records within the buffer (the signals' addresses are link.c's to check). */
bool capture_valid(const capture_config_t *c);

/* Arm (command 1) or disarm (command 2) by a valid page; source[i]: where signal i is read. */
void capture_command(const capture_config_t *c, const uint8_t *const *source);

/* One control interrupt, at its end: speed (a speed sample), run_start (a run's first interrupt), period (the
   link's clock). Bounded: one record of at most 16 signals. */
void capture_sample(bool speed, bool run_start, uint32_t period);

#endif /* CAPTURE_H */
