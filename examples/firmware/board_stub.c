/*
 * STUBS: replace this file with your MCU's drivers (board.h says what each
 * function must do, in which context, with which timing).
 *
 * What is real here: the control interrupt runs from SysTick, which every
 * Cortex-M has (Armv7-M Architecture Reference Manual, B3.3), and the
 * diagnostic output is UART0 of the Arm MPS2 board (a CMSDK APB UART at
 * 0x40004000; QEMU -M mps2-an386 -nographic shows it on the terminal). On a
 * drive, the control interrupt is rather the ADC end-of-conversion triggered
 * by the PWM timer, so that the currents are sampled at the PWM centre. The
 * core clock is that of the MPS2 AN386 board (25 MHz).
 */
#include "board.h"

#include "foc.h"

#define BOARD_CORE_CLOCK_HZ 25000000.0f

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u) /* SysTick control and status */
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u) /* SysTick reload value */
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u) /* SysTick current value */
#define SYST_CSR_ENABLE_TICKINT_CORECLK 0x7u         /* counter on, interrupt on, core clock */

#define UART0_DATA (*(volatile uint32_t *)0x40004000u)  /* CMSDK UART data */
#define UART0_STATE (*(volatile uint32_t *)0x40004004u) /* bit 0: transmit buffer full */
#define UART0_CTRL (*(volatile uint32_t *)0x40004008u)  /* bit 0: transmit enable */
#define UART0_BAUDDIV (*(volatile uint32_t *)0x40004010u)
#define UART0_BAUD 115200.0f

/* STUB: clocks, ADC triggered by the PWM timer, PWM timer, encoder interface */
void board_init(void)
{
    UART0_BAUDDIV = (uint32_t)(BOARD_CORE_CLOCK_HZ / UART0_BAUD);
    UART0_CTRL = 1u;
}

static void uart_put(char ch)
{
    while ((UART0_STATE & 1u) != 0u) {
    }
    UART0_DATA = (uint32_t)(unsigned char)ch;
}

void board_report(const char *text)
{
    while (*text != '\0') {
        uart_put(*text++);
    }
    uart_put('\r');
    uart_put('\n');
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
void SysTick_Handler(void) { foc_isr(); }

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

float board_speed_reference_radps(void)
{
    /* STUB: the application's set point (here 500 rpm, the paper's step) */
    return 52.35988f;
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
