/*
 * Hardware access of the firmware example. Every function here is a stub in
 * board_stub.c: replace that file with your MCU's drivers (ADC, PWM timer,
 * encoder, interrupt setup). The control code in foc.c only calls these.
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

/* Clocks, ADC, PWM timer and encoder interface; PWM outputs disabled. */
void board_init(void);

/* Start the control interrupt at rate_hz; it calls foc_isr(). */
void board_start_control_interrupt(uint32_t rate_hz);

/* Phase currents of the last ADC conversion [A]. */
void board_read_phase_currents(float *ia_A, float *ib_A, float *ic_A);

/* DC-link voltage [V]. */
float board_read_dc_link_V(void);

/* Mechanical rotor angle [rad] and speed [rad/s] from the encoder. */
void board_read_rotor(float *theta_m_rad, float *w_m_radps);

/* Speed reference from the application (fieldbus, potentiometer, ...) [rad/s]. */
float board_speed_reference_radps(void);

/* Duty cycles of the three half bridges, each in [0, 1]. */
void board_write_duties(float duty_a, float duty_b, float duty_c);

/* Enable (1) or disable (0) the PWM outputs. */
void board_pwm_enable(int enable);

/* Sleep until the next interrupt. */
void board_wait_for_interrupt(void);

#endif /* BOARD_H */
