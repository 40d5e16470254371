#include "cost_probe.h"

__attribute__((noinline)) void p2d_cost_mark(void) { __asm__ volatile("" ::: "memory"); }

void p2d_cost_sizeof(p2d_line_t *line, const char *type, uint32_t bytes)
{
    p2d_line_text(line, "sizeof ");
    p2d_line_text(line, type);
    p2d_line_text(line, " ");
    p2d_line_hex(line, bytes);
    p2d_line_flush(line);
}
