/*
 * Field-oriented control with the pmsm2dof controllers: current loop at every
 * control interrupt (10 kHz), speed loop at every FOC_SPEED_DIVIDER-th (1 kHz).
 */
#ifndef FOC_H
#define FOC_H

#include <stdbool.h>
#include <stdint.h>

/* Speed-loop period in control interrupts: Ts_speed = FOC_SPEED_DIVIDER * Ts_current. */
#define FOC_SPEED_DIVIDER 10u

/*
 * Initialize both controllers from the generated configuration; false when a
 * configuration is rejected or the two sampling periods do not fit
 * FOC_SPEED_DIVIDER. *rate_hz is the control-interrupt rate, 1 / Ts_current.
 */
bool foc_init(uint32_t *rate_hz);

/* The control interrupt: call at 1 / Ts_current, from the ADC or PWM interrupt. */
void foc_isr(void);

#endif /* FOC_H */
