/*
 * Firmware example: the pmsm2dof speed and current controllers in a FOC
 * interrupt on a Cortex-M4F. See foc.c for the control, board.h for the
 * hardware access to replace, and docs/mcu.md for the build.
 */
#include "board.h"
#include "foc.h"

int main(void)
{
    uint32_t rate_hz;

    board_init();
    if (!foc_init(&rate_hz)) {
        /* a configuration was rejected: never switch the power stage on */
        for (;;) {
            board_wait_for_interrupt();
        }
    }
    board_start_control_interrupt(rate_hz);
    board_pwm_enable(1);
    for (;;) {
        /* background work (communication, parameter updates with p2d_speed_set_config) */
        board_wait_for_interrupt();
    }
}
