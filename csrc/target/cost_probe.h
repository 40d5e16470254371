/*
 * The cost probes' instruments, shared by the probe programs that
 * benchmarks/footprint.py traces on QEMU (target_cost.c,
 * target_commission_cost.c, target_fixed_cost.c):
 * - p2d_cost_mark(), called right before a measured step, marks it in an
 *   instruction trace (-singlestep -d exec,nochain): the step's instructions
 *   run from its entry to the return address of its call;
 * - the stack a call uses: paint the free stack below SP with a pattern
 *   before the call, find the lowest word overwritten after it;
 * - the size of a struct as the target compiler lays it out, as a line of output.
 */
#ifndef P2D_COST_PROBE_H
#define P2D_COST_PROBE_H

#include <stdint.h>

#include "semihost.h"

/* Painted words below SP (2 KiB). */
#define P2D_STACK_PAINT_WORDS 512u

/* Marks the next step call in the instruction trace (out of line, does nothing). */
void p2d_cost_mark(void);

/* Write the line "sizeof <type> <bytes>" (bytes in hex). */
void p2d_cost_sizeof(p2d_line_t *line, const char *type, uint32_t bytes);

/* The stack pointer, read in the caller. */
static inline uint32_t p2d_stack_pointer(void)
{
    uint32_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

/* Paint pattern of the free stack. */
#define P2D_STACK_PATTERN 0xC5A5C5A5u

/* Fill the free stack below sp with the pattern (inline: no frame of its own below sp). */
static inline void p2d_stack_paint(uint32_t sp)
{
    volatile uint32_t *w = (volatile uint32_t *)(uintptr_t)(sp - 4u * P2D_STACK_PAINT_WORDS);
    for (uint32_t i = 0u; i < P2D_STACK_PAINT_WORDS; ++i) {
        w[i] = P2D_STACK_PATTERN;
    }
}

/* Bytes below sp overwritten since p2d_stack_paint(sp). */
static inline uint32_t p2d_stack_used(uint32_t sp)
{
    volatile const uint32_t *w = (volatile const uint32_t *)(uintptr_t)(sp - 4u * P2D_STACK_PAINT_WORDS);
    uint32_t i = 0u;
    while (i < P2D_STACK_PAINT_WORDS && w[i] == P2D_STACK_PATTERN) {
        ++i;
    }
    return 4u * (P2D_STACK_PAINT_WORDS - i);
}

#endif /* P2D_COST_PROBE_H */
