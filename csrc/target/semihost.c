#include "semihost.h"

#include <string.h>

#define P2D_SYS_OPEN 0x01
#define P2D_SYS_CLOSE 0x02
#define P2D_SYS_WRITE0 0x04
#define P2D_SYS_WRITE 0x05
#define P2D_SYS_GET_CMDLINE 0x15
#define P2D_SYS_EXIT 0x18
#define P2D_OPEN_MODE_WB 5u                       /* "wb" in the mode table of SYS_OPEN */
#define P2D_ADP_STOPPED_APPLICATION_EXIT 0x20026u /* QEMU exits with status 0 */
#define P2D_ADP_STOPPED_RUNTIME_ERROR 0x20023u    /* QEMU exits with status 1 */

/* r0 = operation, r1 = argument, BKPT 0xAB traps to the debugger (here QEMU). */
static uint32_t semihost_call(uint32_t op, uint32_t arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register uint32_t r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void p2d_semihost_write(const char *text) { (void)semihost_call(P2D_SYS_WRITE0, (uint32_t)(uintptr_t)text); }

int32_t p2d_semihost_create(const char *name)
{
    /* parameter block: name, mode, length of the name */
    uint32_t block[3] = {(uint32_t)(uintptr_t)name, P2D_OPEN_MODE_WB, (uint32_t)strlen(name)};
    return (int32_t)semihost_call(P2D_SYS_OPEN, (uint32_t)(uintptr_t)block);
}

bool p2d_semihost_write_file(int32_t handle, const void *bytes, uint32_t n)
{
    /* parameter block: handle, data, length; returns the number of bytes not written */
    uint32_t block[3] = {(uint32_t)handle, (uint32_t)(uintptr_t)bytes, n};
    return semihost_call(P2D_SYS_WRITE, (uint32_t)(uintptr_t)block) == 0u;
}

void p2d_semihost_close(int32_t handle)
{
    uint32_t block[1] = {(uint32_t)handle};
    (void)semihost_call(P2D_SYS_CLOSE, (uint32_t)(uintptr_t)block);
}

bool p2d_semihost_cmdline(char *text, uint32_t size)
{
    /* parameter block: buffer, its size (in: capacity; out: length); returns 0 on success */
    uint32_t block[2] = {(uint32_t)(uintptr_t)text, size};
    if (size == 0u) return false;
    text[0] = '\0';
    return semihost_call(P2D_SYS_GET_CMDLINE, (uint32_t)(uintptr_t)block) == 0u;
}

void p2d_semihost_exit(bool ok)
{
    /* on AArch32 the argument of SYS_EXIT is the reason code itself */
    (void)semihost_call(P2D_SYS_EXIT, ok ? P2D_ADP_STOPPED_APPLICATION_EXIT : P2D_ADP_STOPPED_RUNTIME_ERROR);
    for (;;) {
    }
}

static void line_char(p2d_line_t *line, char ch)
{
    /* keep room for the newline and the NUL */
    if (line->len < P2D_LINE_CHARS - 2u) {
        line->text[line->len++] = ch;
    }
}

void p2d_line_hex(p2d_line_t *line, uint32_t word)
{
    static const char digits[] = "0123456789abcdef";
    for (int shift = 28; shift >= 0; shift -= 4) {
        line_char(line, digits[(word >> shift) & 0xFu]);
    }
    line_char(line, ' ');
}

void p2d_line_float(p2d_line_t *line, float x)
{
    uint32_t bits;
    memcpy(&bits, &x, sizeof bits);
    p2d_line_hex(line, bits);
}

void p2d_line_text(p2d_line_t *line, const char *text)
{
    while (*text != '\0') {
        line_char(line, *text++);
    }
}

void p2d_line_flush(p2d_line_t *line)
{
    line->text[line->len++] = '\n';
    line->text[line->len] = '\0';
    p2d_semihost_write(line->text);
    line->len = 0u;
}
