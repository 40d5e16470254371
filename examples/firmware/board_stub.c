/*
 * STUBS: replace this file with your MCU's drivers (board.h says what each
 * function must do, in which context, with which timing).
 *
 * What is real here: the control interrupt runs from SysTick, which every
 * Cortex-M has (Armv7-M Architecture Reference Manual, B3.3), the link to the
 * XCP master and the diagnostic output are UART0 of the Arm MPS2 board (a
 * CMSDK APB UART at 0x40004000, csrc/target/cmsdk_uart.h; QEMU -M mps2-an386
 * -nographic shows it on the terminal), and the shared sections of the link
 * mask the interrupts (PRIMASK). On a
 * drive, the control interrupt is rather the ADC end-of-conversion triggered
 * by the PWM timer, so that the currents are sampled at the PWM centre. The
 * core clock is that of the MPS2 AN386 board (25 MHz).
 */
#include "board.h"

#include "cmsdk_uart.h"
#include "foc.h"

#define BOARD_CORE_CLOCK_HZ 25000000.0f

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u) /* SysTick control and status */
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u) /* SysTick reload value */
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u) /* SysTick current value */
#define SYST_CSR_ENABLE_TICKINT_CORECLK 0x7u         /* counter on, interrupt on, core clock */

#define BOARD_UART_BAUD 115200u /* the link's and the diagnostics' bit rate [bit/s] */

static uint32_t primask; /* PRIMASK saved by board_link_lock */

/* STUB: clocks, ADC triggered by the PWM timer, PWM timer, encoder interface */
void board_init(void) { p2d_uart_init(P2D_UART0, (uint32_t)BOARD_CORE_CLOCK_HZ, BOARD_UART_BAUD); }

/* on the link's UART: only before the link starts (a rejected configuration) */
void board_report(const char *text)
{
    while (*text != '\0') {
        p2d_uart_put(P2D_UART0, (uint8_t)*text++);
    }
    p2d_uart_put(P2D_UART0, '\r');
    p2d_uart_put(P2D_UART0, '\n');
}

void board_halt(void)
{
    board_pwm_enable(false);
    SYST_CSR = 0u;
    for (;;) {
        board_wait_for_interrupt();
    }
}

void board_read_start_state(float *w_m_radps, float *T_Nm)
{
    /* STUB: the speed from the encoder; a drive that starts at rest has 0 and 0 */
    *w_m_radps = 0.0f;
    *T_Nm = 0.0f;
}

void board_start_control_interrupt(float Ts_current_s)
{
    SYST_RVR = (uint32_t)(BOARD_CORE_CLOCK_HZ * Ts_current_s + 0.5f) - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CORECLK;
}

/* The control interrupt of this example. */
void SysTick_Handler(void) { link_isr(); }

void board_read_phase_currents(float *ia_A, float *ib_A, float *ic_A)
{
    /* STUB: ADC counts -> amperes (offset, gain of the current sensors) */
    *ia_A = 0.0f;
    *ib_A = 0.0f;
    *ic_A = 0.0f;
}

float board_read_dc_link_V(void)
{
    /* STUB: ADC counts -> volts */
    return 300.0f;
}

void board_read_rotor(float *theta_m_rad, float *w_m_radps)
{
    /* STUB: encoder counts -> angle; speed from the angle difference over the sample (filtered) */
    *theta_m_rad = 0.0f;
    *w_m_radps = 0.0f;
}

float board_read_speed_radps(void)
{
    /* STUB: the speed loop's sensor (the motor's encoder: the speed board_read_rotor gives) */
    return 0.0f;
}

uint32_t board_read_encoder_count(void)
{
    /* STUB: the encoder timer's counter, latched with the ADC trigger */
    return 0u;
}

void board_write_duties(float duty_a, float duty_b, float duty_c)
{
    /* STUB: duty -> compare registers of the PWM timer */
    (void)duty_a;
    (void)duty_b;
    (void)duty_c;
}

void board_pwm_enable(bool enable)
{
    /* STUB: main output enable of the PWM timer / gate driver */
    (void)enable;
}

void board_wait_for_interrupt(void) { __asm__ volatile("wfi"); }

void board_link_config(link_config_t *cfg)
{
    /* STUB: the master must talk every 0.1 s during a run; the guard brakes at 1000 rad/s^2 and holds 0.1 s */
    cfg->Ts_current_s = (double)foc_current_period_s();
    cfg->timeout_s = 0.1f;
    cfg->ramp_radps_per_s = 1000.0f;
    cfg->hold_s = 0.1f;
    cfg->max_packet_bytes = 255u; /* XCP on SxI (a UART); on CAN 8, on CAN FD 64 */
    cfg->n = 0u;
    cfg->autostart_samples = 0u;
}

uint32_t board_link_receive(uint8_t *bytes, uint32_t capacity) { return p2d_uart_receive(P2D_UART0, bytes, capacity); }

uint32_t board_link_send(const uint8_t *bytes, uint32_t n) { return p2d_uart_send(P2D_UART0, bytes, n); }

void board_link_lock(void)
{
    uint32_t mask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(mask)::"memory");
    primask = mask;
}

void board_link_unlock(void) { __asm__ volatile("msr primask, %0" ::"r"(primask) : "memory"); }

uint16_t board_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity)
{
    /* STUB: the board's own variables for the master (a temperature, the DC link, ...) */
    (void)segments;
    (void)capacity;
    return 0u;
}

bool board_link_commit(uint16_t index, const void *page, bool running)
{
    (void)index;
    (void)page;
    (void)running;
    return false;
}

bool board_run_valid(void) { return true; }

/* STUB: what a run needs first (the DC link precharged, the brake released, ...) */
void board_run_begin(void) {}
