#include "cost_probe.h"

#define P2D_STACK_PATTERN 0xC5A5C5A5u /* paint pattern */

__attribute__((noinline)) void p2d_cost_mark(void) { __asm__ volatile("" ::: "memory"); }

__attribute__((noinline)) uint32_t p2d_stack_pointer(void)
{
    uint32_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

void p2d_stack_paint(uint32_t sp)
{
    volatile uint32_t *w = (volatile uint32_t *)(uintptr_t)(sp - 4u * P2D_STACK_PAINT_WORDS);
    for (uint32_t i = 0u; i < P2D_STACK_PAINT_WORDS; ++i) {
        w[i] = P2D_STACK_PATTERN;
    }
}

uint32_t p2d_stack_used(uint32_t sp)
{
    volatile const uint32_t *w = (volatile const uint32_t *)(uintptr_t)(sp - 4u * P2D_STACK_PAINT_WORDS);
    uint32_t i = 0u;
    while (i < P2D_STACK_PAINT_WORDS && w[i] == P2D_STACK_PATTERN) {
        ++i;
    }
    return 4u * (P2D_STACK_PAINT_WORDS - i);
}
