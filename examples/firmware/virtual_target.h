/*
 * What the virtual board (board_virtual.c) needs from the machine it runs on:
 * a periodic interrupt whose clock can be held and read, outputs for the trace,
 * the cost and the diagnostics, the run's arguments, the end of the run and
 * the link to the XCP master. Two implementations: virtual_target_mps2.c (the
 * Cortex-M4F of QEMU -M mps2-an386: SysTick, semihosting, UART0) and
 * virtual_target_host.c (the PC: the interrupt is a call, the outputs stdio,
 * the link a TCP socket), so that foc.c and the virtual board build unchanged
 * for both.
 */
#ifndef VIRTUAL_TARGET_H
#define VIRTUAL_TARGET_H

#include <stdbool.h>
#include <stdint.h>

/* The outputs of a run. */
typedef enum {
    VT_TRACE = 0, /* the trace (trace.bin) */
    VT_COST = 1   /* the instructions of each control interrupt (cost.bin; a machine that counts them) */
} vt_stream_t;

/* The machine's control interrupt calls this every period (board_virtual.c). */
void board_virtual_interrupt(void);

/* Open the outputs and read the run's arguments. */
void vt_init(void);

/* The value of argument name=N of the run, or fallback when absent. */
uint64_t vt_argument(const char *name, uint64_t fallback);

/* Call board_virtual_interrupt() every Ts_s [s] of the firmware's time, from now. */
void vt_start_interrupt(float Ts_s);

/*
 * Hold (true) or release (false) the clock of the control interrupt: the
 * physics of the virtual motor runs held, so it takes none of the firmware's
 * time. Holding returns true when the next period already began during the
 * control code since the interrupt's entry (an overrun).
 */
bool vt_hold(bool hold);

/* The clock of the control interrupt, counting down [ticks]. */
uint32_t vt_clock(void);

/* The instructions executed between two readings of vt_clock (0 where the machine does not count them). */
uint32_t vt_instructions(uint32_t clock_start, uint32_t clock_end);

/* Sleep until the control interrupt (the PC: run it). */
void vt_wait(void);

/* Append n bytes to an output. */
void vt_write(vt_stream_t stream, const void *bytes, uint32_t n);

/* Write one line of text to the diagnostic output. */
void vt_report(const char *text);

/* The bytes received on the link to the XCP master, at most capacity; 0: none. Never waits. */
uint32_t vt_link_receive(uint8_t *bytes, uint32_t capacity);

/* Send up to n bytes on the link without waiting; returns how many were taken. */
uint32_t vt_link_send(const uint8_t *bytes, uint32_t n);

/* Enter (true) or leave (false) a section shared by the background and the control interrupt. */
void vt_lock(bool enter);

/* Close the outputs and end the run: exit status 0 when ok, else 1. Does not return. */
void vt_exit(bool ok);

#endif /* VIRTUAL_TARGET_H */
