/*
 * The virtual board's machine on the PC: the control interrupt is a call (the
 * background loop's wait runs the next one), the trace goes to trace.bin in
 * the working folder, the diagnostics to stderr, the arguments name=N come from
 * the environment variable P2D_VIRTUAL_DRIVE_ARGS. The same foc.c and
 * board_virtual.c as on the MCU; the firmware's time and cost are not modelled
 * (no cost.bin).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "virtual_target.h"

static FILE *trace;  /* the trace output */
static bool started; /* the control interrupt runs */

void vt_init(void)
{
    trace = fopen("trace.bin", "wb");
    if (trace == NULL) {
        fprintf(stderr, "virtual drive: cannot create trace.bin\n");
        exit(1);
    }
}

uint64_t vt_argument(const char *name, uint64_t fallback)
{
    const char *args = getenv("P2D_VIRTUAL_DRIVE_ARGS");
    size_t len = strlen(name);
    for (const char *p = args; p != NULL && *p != '\0'; ++p) {
        if ((p == args || p[-1] == ' ') && strncmp(p, name, len) == 0 && p[len] == '=') {
            return strtoull(p + len + 1, NULL, 10);
        }
    }
    return fallback;
}

void vt_start_interrupt(float Ts_s)
{
    (void)Ts_s;
    started = true;
}

bool vt_hold(bool hold)
{
    (void)hold;
    return false;
}

uint32_t vt_clock(void) { return 0u; }

uint32_t vt_instructions(uint32_t clock_start, uint32_t clock_end)
{
    (void)clock_start;
    (void)clock_end;
    return 0u;
}

void vt_wait(void)
{
    if (!started) {
        fprintf(stderr, "virtual drive: waiting with no control interrupt started\n");
        exit(1);
    }
    board_virtual_interrupt();
}

void vt_write(vt_stream_t stream, const void *bytes, uint32_t n)
{
    if (stream != VT_TRACE) return; /* no cost runs on the PC */
    if (fwrite(bytes, 1, n, trace) != n) {
        fprintf(stderr, "virtual drive: writing trace.bin failed\n");
        exit(1);
    }
}

void vt_report(const char *text) { fprintf(stderr, "%s\n", text); }

void vt_exit(bool ok)
{
    if (fclose(trace) != 0) ok = false;
    exit(ok ? 0 : 1);
}
