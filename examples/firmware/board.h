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
 *   background (main)          board_init, board_report, board_link_config,
 *                              board_start_control_interrupt, board_wait_for_interrupt,
 *                              board_halt, board_link_receive, board_link_send,
 *                              board_link_segments
 *   control interrupt          board_read_phase_currents, board_read_dc_link_V,
 *   (link_isr, foc_isr)        board_read_rotor, board_read_speed_radps,
 *                              board_read_encoder_count, board_write_duties,
 *                              board_read_start_state, board_run_valid, board_run_begin,
 *                              board_pwm_enable, board_link_commit
 *   both                       board_link_lock, board_link_unlock
 *
 * The link. The firmware speaks XCP (link.h) on a byte link to the master, a
 * UART on a drive (XCP on SxI: LEN CTR header, no checksum), TCP on the PC;
 * the master starts and stops runs, measures and calibrates.
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdbool.h>
#include <stdint.h>

#include "link.h"
#include "pmsm2dof/xcp.h"

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

/*
 * Control interrupt: the duty cycles of the three half bridges for the next PWM
 * update, each in [0, 1] (0.5: zero phase voltage) -> the compare registers.
 */
void board_write_duties(float duty_a, float duty_b, float duty_c);

/* Enable (true) or disable (false) the PWM outputs (the gate driver): at the start and the end of a run. */
void board_pwm_enable(bool enable);

/* Sleep until the next interrupt (WFI). Background only. */
void board_wait_for_interrupt(void);

/*
 * The board's part of the link's configuration (link.h): the control period
 * as its timer makes it, the watchdog's timeout, the guard's ramp and hold,
 * the initial reference schedule and a run to start at power-up (0: none, the
 * drive waits for its master). main.c fills in the loop ratio.
 */
void board_link_config(link_config_t *cfg);

/* The bytes received on the link since the last call, at most capacity; 0: none. Never waits. */
uint32_t board_link_receive(uint8_t *bytes, uint32_t capacity);

/* Send up to n bytes on the link without waiting; returns how many it took (0: busy). */
uint32_t board_link_send(const uint8_t *bytes, uint32_t n);

/* Enter and leave a section shared by the background and the control interrupt (interrupts off, then restored). */
void board_link_lock(void);
void board_link_unlock(void);

/*
 * The board's own variables for the master, after the link's: write up to
 * capacity segments (address, memory, size, access); returns how many.
 */
uint16_t board_link_segments(p2d_xcp_segment_t *segments, uint16_t capacity);

/*
 * Validate and apply the master's page of the board's calibration segment
 * index (0: the first of board_link_segments), at a speed sample; running: a
 * run is under way. False: refused, nothing changed.
 */
bool board_link_commit(uint16_t index, const void *page, bool running);

/* True when the board can start a run as configured now (its schedules valid). */
bool board_run_valid(void);

/* A run starts (after foc_start): the board's time and schedules from t = 0 (a virtual motor: its initial state). */
void board_run_begin(void);

#endif /* BOARD_H */
