/*
 * Output, files, arguments and exit through Arm semihosting (Arm "Semihosting
 * for AArch32 and AArch64": SYS_OPEN = 0x01, SYS_CLOSE = 0x02, SYS_WRITE0 =
 * 0x04, SYS_WRITE = 0x05, SYS_EXIT = 0x18, SYS_GET_CMDLINE = 0x15), for
 * programs run on QEMU with -semihosting-config enable=on,target=native (files
 * relative to QEMU's working folder; the arguments from arg=...). On a board
 * without a debugger attached, the BKPT instruction stops the core: use these
 * on the emulator only.
 */
#ifndef P2D_SEMIHOST_H
#define P2D_SEMIHOST_H

#include <stdbool.h>
#include <stdint.h>

/* Write a NUL-terminated string to the host's stdout. */
void p2d_semihost_write(const char *text);

/* End the emulation: exit status 0 when ok, 1 otherwise. Does not return. */
void p2d_semihost_exit(bool ok) __attribute__((noreturn));

/* Open the host file name for binary writing (created or truncated): its handle, or -1. */
int32_t p2d_semihost_create(const char *name);

/* Write n bytes to the file handle: true when all were written. */
bool p2d_semihost_write_file(int32_t handle, const void *bytes, uint32_t n);

/* Close the file handle. */
void p2d_semihost_close(int32_t handle);

/* The command line of the run (QEMU: the arg= values, separated by spaces) into text (NUL-terminated). */
bool p2d_semihost_cmdline(char *text, uint32_t size);

/* Characters of one output line, newline and NUL included. */
#define P2D_LINE_CHARS 256

/* One line of output being assembled; characters beyond its capacity are dropped. */
typedef struct {
    char text[P2D_LINE_CHARS]; /* characters written so far */
    uint32_t len;              /* number of characters in text [-] */
} p2d_line_t;

/* Append the 8 hex digits of word, then a space. */
void p2d_line_hex(p2d_line_t *line, uint32_t word);

/* Append the IEEE 754 binary32 bits of x as 8 hex digits, then a space. */
void p2d_line_float(p2d_line_t *line, float x);

/* Append text. */
void p2d_line_text(p2d_line_t *line, const char *text);

/* Terminate the line with a newline, write it and empty it. */
void p2d_line_flush(p2d_line_t *line);

#endif /* P2D_SEMIHOST_H */
