/*
 * Firmware example: the pmsm2dof speed and current controllers in a FOC
 * interrupt on a Cortex-M4F. See foc.c for the control, board.h for the
 * hardware access to replace, and docs/mcu.md for the build and the runs.
 */
#include "board.h"
#include "foc.h"
#include "pmsm2dof/status.h"

/* Characters of a diagnostic line, NUL included. */
#define MAIN_LINE_CHARS 200u

/* Name of each part of the configuration foc_init checks. */
static const char *const part_name[] = {
    [FOC_OK] = "",
    [FOC_ERR_SPEED] = "speed controller (p2d_config_speed)",
    [FOC_ERR_SPEED_FILTER] = "torque filters (p2d_config_speed_filter)",
    [FOC_ERR_CURRENT] = "current controller (p2d_config_current)",
    [FOC_ERR_ENCODER] = "encoder estimator (p2d_config_encoder)",
    [FOC_ERR_FIELD_WEAKENING] = "field weakening (p2d_config_field_weakening)",
    [FOC_ERR_INERTIA] = "inertia estimator (p2d_config_inertia)",
    [FOC_ERR_LOOP_RATIO] = "loop rates (P2D_CONFIG_CURRENT_PER_SPEED)",
};

/* Append text to line (of *len characters), keeping room for the NUL. */
static void append(char *line, uint32_t *len, const char *text)
{
    while (*text != '\0' && *len < MAIN_LINE_CHARS - 1u) {
        line[(*len)++] = *text++;
    }
    line[*len] = '\0';
}

/* Append the decimal digits of n. */
static void append_number(char *line, uint32_t *len, uint32_t n)
{
    char digits[11];
    uint32_t k = 0u;
    do {
        digits[k++] = (char)('0' + n % 10u);
        n /= 10u;
    } while (n > 0u);
    while (k > 0u && *len < MAIN_LINE_CHARS - 1u) {
        line[(*len)++] = digits[--k];
    }
    line[*len] = '\0';
}

/* Report a rejected configuration: which part, which field, its valid range, the status code. */
static void report_rejected(foc_status_t st)
{
    char line[MAIN_LINE_CHARS];
    uint32_t len = 0u;
    append(line, &len, "pmsm2dof firmware: configuration rejected: ");
    append(line, &len, part_name[st.part]);
    append(line, &len, ": ");
    if (st.part == FOC_ERR_LOOP_RATIO) {
        append(line, &len, "Ts_s of p2d_config_speed and p2d_config_encoder must be ");
        append(line, &len, "P2D_CONFIG_CURRENT_PER_SPEED times Ts_s of p2d_config_current");
    } else {
        append(line, &len, p2d_status_param(st.status));
        append(line, &len, " must be ");
        append(line, &len, p2d_status_range(st.status));
    }
    append(line, &len, " (p2d_status_t ");
    append_number(line, &len, (uint32_t)st.status);
    append(line, &len, ")");
    board_report(line);
}

int main(void)
{
    foc_status_t st;
    float w_m_radps, T_Nm;

    board_init();
    st = foc_init();
    if (st.part != FOC_OK) {
        /* never switch the power stage on */
        report_rejected(st);
        board_halt();
        return 1;
    }
    board_read_start_state(&w_m_radps, &T_Nm);
    foc_start(w_m_radps, T_Nm);
    board_start_control_interrupt(foc_current_period_s());
    board_pwm_enable(true);
    for (;;) {
        /* background work (communication, parameter updates with p2d_speed_set_config) */
        board_wait_for_interrupt();
    }
}
