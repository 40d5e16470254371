/*
 * STUBS: replace this file with your MCU's drivers.
 *
 * Only board_start_control_interrupt() does something real: it runs the
 * control interrupt from SysTick, which every Cortex-M has (Armv7-M
 * Architecture Reference Manual, B3.3). On a drive, the control interrupt is
 * rather the ADC end-of-conversion triggered by the PWM timer, so that the
 * currents are sampled at the PWM centre. The core clock is that of the Arm
 * MPS2 AN386 board (25 MHz).
 */
#include "board.h"

#include "foc.h"

#define BOARD_CORE_CLOCK_HZ 25000000u

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u) /* SysTick control and status */
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u) /* SysTick reload value */
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u) /* SysTick current value */
#define SYST_CSR_ENABLE_TICKINT_CORECLK 0x7u         /* counter on, interrupt on, core clock */

/* STUB: clocks, ADC triggered by the PWM timer, PWM timer, encoder */
void board_init(void) {}

void board_start_control_interrupt(uint32_t rate_hz)
{
    SYST_RVR = BOARD_CORE_CLOCK_HZ / rate_hz - 1u;
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

void board_pwm_enable(int enable)
{
    /* STUB: main output enable of the PWM timer / gate driver */
    (void)enable;
}

void board_wait_for_interrupt(void) { __asm__ volatile("wfi"); }
