/*
 * The hardware access of the firmware example: the interface a board
 * implements. foc.c and main.c call nothing else of the hardware.
 *
 * Two implementations come with the example: board_stub.c, the porting stub
 * (replace its bodies with your MCU's drivers), and board_virtual.c, a virtual
 * board whose motor, inverter, sensors and load are the simulation engine's
 * plant (csrc/sim/plant.c), so that the firmware runs closed loop on QEMU or on
 * the PC.
 *
 * Timing. One control interrupt per PWM period Ts_current (foc_isr). On a
 * drive it is the ADC end-of-conversion interrupt, the ADC triggered by the
 * PWM timer at the centre of the period, where the phase currents carry no
 * switching ripple. Everything foc_isr reads must describe that sampling
 * instant t_n: the currents of the conversion, the DC link, the rotor angle and
 * the encoder counter latched with it. The duties it writes take effect at the
 * next update of the PWM compare registers: in the period that starts at t_n
 * when the interrupt ends before it (shadow registers loaded at the period's
 * start), else one period later (a computation delay; the engine's
 * inverter.computation_delay). foc_isr must end within Ts_current.
 *
 *   background (main)          board_init, board_report, board_read_start_state,
 *                              board_start_control_interrupt, board_pwm_enable,
 *                              board_wait_for_interrupt, board_halt
 *   control interrupt          board_read_phase_currents, board_read_dc_link_V,
 *   (foc_isr)                  board_read_rotor, board_read_speed_radps,
 *                              board_read_encoder_count, board_speed_reference_radps,
 *                              board_write_duties
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdbool.h>
#include <stdint.h>

/*
 * Clocks, ADC, PWM timer, encoder interface and the diagnostic output (a UART),
 * the PWM outputs disabled. First call of main.
 */
void board_init(void);

/* Write one line of text to the diagnostic output (a UART on a drive). Background only. */
void board_report(const char *text);

/* Stop for good in a safe state: PWM outputs off, control interrupt off. Never returns. */
void board_halt(void);

/*
 * The motor when the firmware starts: its mechanical speed [rad/s] (from the
 * encoder) and the torque that holds that speed [Nm]. A drive that starts at
 * rest returns 0 and 0.
 */
void board_read_start_state(float *w_m_radps, float *T_Nm);

/*
 * Start the control interrupt: every Ts_current_s [s], call foc_isr() with the
 * sensors of the sampling instant (see Timing above). On a drive: the PWM
 * timer's period (centre-aligned: f_clk Ts_current / 2 counts), the ADC
 * triggered at its centre, the ADC interrupt enabled with the highest priority.
 */
void board_start_control_interrupt(float Ts_current_s);

/* Control interrupt: the phase currents of the last conversion [A] (counts -> A: offset and gain of the sensors). */
void board_read_phase_currents(float *ia_A, float *ib_A, float *ic_A);

/* Control interrupt: the DC-link voltage of the last conversion [V]. */
float board_read_dc_link_V(void);

/*
 * Control interrupt: the mechanical rotor angle in [0, 2 pi) [rad], 0 where the
 * d axis is on phase a, and the mechanical speed [rad/s], at the sampling
 * instant (from the encoder or resolver, aligned at commissioning).
 */
void board_read_rotor(float *theta_m_rad, float *w_m_radps);

/*
 * Control interrupt (speed samples): the speed the speed loop controls, as its
 * sensor measures it at the sampling instant [rad/s]: the motor's, or the
 * load's with a sensor on the load side (P2D_CONFIG_ENCODER 0).
 */
float board_read_speed_radps(void);

/*
 * Control interrupt (speed samples): the hardware counter of the speed loop's
 * encoder latched at the sampling instant [count] (it wraps; P2D_CONFIG_ENCODER 1).
 */
uint32_t board_read_encoder_count(void);

/* Control interrupt (speed samples): the speed reference from the application (fieldbus, ...) [rad/s]. */
float board_speed_reference_radps(void);

/*
 * Control interrupt: the duty cycles of the three half bridges for the next PWM
 * update, each in [0, 1] (0.5: zero phase voltage) -> the compare registers.
 */
void board_write_duties(float duty_a, float duty_b, float duty_c);

/* Enable (true) or disable (false) the PWM outputs (the gate driver). Background only. */
void board_pwm_enable(bool enable);

/* Sleep until the next interrupt (WFI). Background only. */
void board_wait_for_interrupt(void);

#endif /* BOARD_H */
