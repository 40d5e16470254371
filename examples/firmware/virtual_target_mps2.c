/*
 * The virtual board's machine on QEMU -M mps2-an386 (a Cortex-M4F at 25 MHz):
 * the control interrupt is SysTick, counting the core clock (Armv7-M
 * Architecture Reference Manual, B3.3); the outputs, the arguments and the
 * exit go through semihosting (csrc/target/semihost.h).
 *
 * Run with -icount shift=7,sleep=off: every instruction then advances QEMU's
 * virtual clock by 128 ns, 3.2 SysTick ticks of 40 ns, and WFI jumps to the next
 * SysTick, so that a run is deterministic and t ticks between two readings of
 * the clock are round(t / 3.2) instructions exactly (t = floor(3.2 n + f) with a
 * phase f in [0, 1), so t / 3.2 is within 0.32 of n). The firmware's time is
 * that of a 170 MHz Cortex-M4 at 1.5 cycles per instruction (113 million
 * instructions per second): the control interrupt comes every Ts_s 170e6 / 1.5
 * instructions, 3.2 times as many ticks, and an interrupt longer than that is
 * an overrun. While the virtual motor's physics runs (vt_hold), SysTick is
 * stopped: the motor turns between interrupts without taking the firmware's time.
 *
 * The link to the XCP master is UART0 (QEMU's first -serial: -serial pty, or
 * -serial tcp:127.0.0.1:PORT,server), polled by the background loop: a byte
 * per poll, one poll per control period at least. Time on the link. With
 * sleep=off QEMU's clock jumps over the idle time (WFI), so the firmware's
 * time (the control periods, the link's clock, its watchdog, the DAQ
 * timestamps) runs as fast as QEMU executes it: slower than the wall clock
 * while the virtual motor's soft-float physics runs (a few times for a 20 kHz
 * drive), faster while the drive idles. The run stays deterministic whatever
 * the link does: the reference and load schedules are played by the firmware
 * at its own samples, and only the instant a master's command or calibration
 * takes effect depends on the wall clock (the link reports that sample).
 * sleep=on would tie the idle time to the wall clock, give up the determinism
 * of the instruction counts (a late wake-up lands past the SysTick deadline)
 * and not bring a busy drive closer to real time: the physics sets the pace.
 */
#include "cmsdk_uart.h"
#include "semihost.h"
#include "virtual_target.h"

#define VT_CORE_CLOCK_HZ 170e6f        /* the firmware's core clock [Hz] */
#define VT_CYCLES_PER_INSTRUCTION 1.5f /* the firmware's core [cycles/instruction] */
#define VT_TICKS_PER_INSTRUCTION 3.2f  /* SysTick ticks (25 MHz) per instruction at -icount shift=7 */
#define VT_ARGS_CHARS 256u
#define VT_UART_PCLK_HZ 25000000u /* the MPS2's peripheral clock [Hz] */
#define VT_UART_BAUD 115200u      /* the link's bit rate (QEMU does not pace the bytes) [bit/s] */

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u) /* SysTick control and status */
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u) /* SysTick reload value */
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u) /* SysTick current value */
#define SYST_CSR_RUN 0x7u                            /* counter on, interrupt on, core clock */
#define SYST_CSR_HELD 0x6u                           /* counter off, interrupt on, core clock */
#define SYST_CSR_COUNTFLAG 0x10000u                  /* the counter reached 0 since the last read */

static const char *const file_name[] = {[VT_TRACE] = "trace.bin", [VT_COST] = "cost.bin"};
static int32_t handle[2] = {-1, -1}; /* semihosting handles of the outputs */
static char args[VT_ARGS_CHARS];     /* the command line of the run */

void SysTick_Handler(void)
{
    /* reading the control register clears COUNTFLAG: set again only if the next period ends in the interrupt */
    (void)SYST_CSR;
    board_virtual_interrupt();
}

static uint32_t primask; /* PRIMASK saved by vt_lock */

void vt_init(void)
{
    p2d_uart_init(P2D_UART0, VT_UART_PCLK_HZ, VT_UART_BAUD);
    if (!p2d_semihost_cmdline(args, VT_ARGS_CHARS)) args[0] = '\0';
    for (uint32_t s = VT_TRACE; s <= VT_COST; ++s) {
        handle[s] = p2d_semihost_create(file_name[s]);
        if (handle[s] < 0) {
            p2d_semihost_write("virtual drive: cannot create an output file in QEMU's working folder\n");
            p2d_semihost_exit(false);
        }
    }
}

uint64_t vt_argument(const char *name, uint64_t fallback)
{
    /* find "name=" at the start of an argument and read its decimal digits */
    for (const char *p = args; *p != '\0'; ++p) {
        const char *a = p, *b = name;
        if (p != args && p[-1] != ' ') continue;
        while (*b != '\0' && *a == *b) {
            ++a;
            ++b;
        }
        if (*b == '\0' && *a == '=') {
            uint64_t value = 0u;
            for (++a; *a >= '0' && *a <= '9'; ++a) {
                value = 10u * value + (uint64_t)(*a - '0');
            }
            return value;
        }
    }
    return fallback;
}

void vt_start_interrupt(float Ts_s)
{
    SYST_RVR = (uint32_t)(Ts_s * VT_CORE_CLOCK_HZ / VT_CYCLES_PER_INSTRUCTION * VT_TICKS_PER_INSTRUCTION + 0.5f) - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_RUN;
}

bool vt_hold(bool hold)
{
    bool overrun;
    if (!hold) {
        SYST_CSR = SYST_CSR_RUN;
        return false;
    }
    overrun = (SYST_CSR & SYST_CSR_COUNTFLAG) != 0u;
    SYST_CSR = SYST_CSR_HELD;
    return overrun;
}

uint32_t vt_clock(void) { return SYST_CVR; }

uint32_t vt_instructions(uint32_t clock_start, uint32_t clock_end)
{
    /* round(t / 3.2) = (5 t + 8) / 16 for t ticks of 40 ns at 128 ns an instruction */
    return (5u * (clock_start - clock_end) + 8u) / 16u;
}

void vt_wait(void) { __asm__ volatile("wfi"); }

void vt_write(vt_stream_t stream, const void *bytes, uint32_t n)
{
    if (!p2d_semihost_write_file(handle[stream], bytes, n)) {
        p2d_semihost_write("virtual drive: writing an output file failed\n");
        p2d_semihost_exit(false);
    }
}

void vt_report(const char *text)
{
    p2d_semihost_write(text);
    p2d_semihost_write("\n");
}

uint32_t vt_link_receive(uint8_t *bytes, uint32_t capacity) { return p2d_uart_receive(P2D_UART0, bytes, capacity); }

uint32_t vt_link_send(const uint8_t *bytes, uint32_t n) { return p2d_uart_send(P2D_UART0, bytes, n); }

void vt_lock(bool enter)
{
    if (enter) {
        uint32_t mask;
        __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(mask)::"memory");
        primask = mask;
    } else {
        __asm__ volatile("msr primask, %0" ::"r"(primask) : "memory");
    }
}

void vt_exit(bool ok)
{
    SYST_CSR = 0u;
    for (uint32_t s = VT_TRACE; s <= VT_COST; ++s) {
        p2d_semihost_close(handle[s]);
    }
    p2d_semihost_exit(ok);
}
