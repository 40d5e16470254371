/*
 * Firmware example: the pmsm2dof speed and current controllers in a FOC
 * interrupt on a Cortex-M4F, run and tuned by an XCP master over its link.
 * See foc.c for the control, link.h for the link, board.h for the hardware
 * access to replace, and docs/mcu.md for the build and the runs.
 */
#include "board.h"
#include "foc.h"
#include "link.h"
#include "p2d_config.h"
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

/* Report a link configuration the slave or its guard rejected. */
static void report_link_rejected(link_init_status_t st)
{
    char line[MAIN_LINE_CHARS];
    uint32_t len = 0u;
    append(line, &len, "pmsm2dof firmware: link rejected: ");
    if (!st.schedule) {
        append(line, &len, "the reference schedule (at most 32 entries, times >= 0 nondecreasing, ramps >= 0)");
    } else {
        append(line, &len, p2d_xcp_status_param(st.xcp));
        append(line, &len, " must be ");
        append(line, &len, p2d_xcp_status_range(st.xcp));
    }
    board_report(line);
}

int main(void)
{
    foc_status_t st;
    link_config_t link = {0};
    link_init_status_t link_st;

    board_init();
    st = foc_init();
    if (st.part != FOC_OK) {
        /* never switch the power stage on */
        report_rejected(st);
        board_halt();
        return 1;
    }
    board_link_config(&link);
    link.current_per_speed = P2D_CONFIG_CURRENT_PER_SPEED;
    link_st = link_init(&link);
    if (link_st.xcp != P2D_XCP_OK || !link_st.schedule) {
        report_link_rejected(link_st);
        board_halt();
        return 1;
    }
    /* idle, power stage off, until the master (or the board's run at power-up) starts a run */
    board_start_control_interrupt(foc_current_period_s());
    for (;;) {
        /* background: the link (bounded work), then sleep until an interrupt */
        link_poll();
        board_wait_for_interrupt();
    }
}
