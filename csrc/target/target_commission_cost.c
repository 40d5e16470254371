/*
 * Cost probes of the commissioning routine on the Cortex-M4F, read by
 * benchmarks/footprint.py: one whole commissioning, every p2d_commission_step
 * right after a call of p2d_cost_mark(), so that an instruction trace of QEMU
 * (-singlestep -d exec,nochain) counts the instructions of each step; the
 * steps of a phase cost differently (a sample, the end of an injection
 * period, the end of a phase with its estimates).
 *
 * The motor runs on the target too, in float32, in the routine's own frame:
 * a surface PMSM (Rs = 0.8 ohm, L = 4 mH, psi_f = 0.05 Wb) whose rotor
 * follows the frame (it stands still at standstill and turns with the I-f
 * frame), so that no trigonometry is needed:
 *   L did/dt = ud - Rs id + w_e L iq,  L diq/dt = uq - Rs iq - w_e (L id + psi_f)
 * by forward Euler, 4 steps per sample. It is a load for the routine, not a
 * check of its estimates (tests do that).
 *
 * Output lines (semihosting):
 *   sizeof <type> <bytes>
 *   cstep <index> <phase>        one per step; index counts the calls of p2d_cost_mark()
 *   stack <bytes>                the most stack any step used (painted stack)
 *   result <phase> <reason>      where the routine ended
 */
#include <stdbool.h>
#include <stdint.h>

#include "cost_probe.h"
#include "pmsm2dof/commission.h"
#include "semihost.h"

#define P2D_MAX_STEPS 20000u /* a bound on the run */

static p2d_line_t line;
static p2d_commission_t routine;
static uint8_t phase_of_step[P2D_MAX_STEPS]; /* printed after the run, so that the loop calls the step only */

static void print_hex(const char *what, uint32_t a, uint32_t b, bool two)
{
    p2d_line_text(&line, what);
    p2d_line_hex(&line, a);
    if (two) p2d_line_hex(&line, b);
    p2d_line_flush(&line);
}

/*
 * A commissioning of a small servo with short phases: 100 us samples,
 * tau_i = 1 ms, 2 A test, 1.5 A spin, the flux test at 100 rad/s.
 */
static p2d_commission_config_t servo_config(void)
{
    p2d_commission_config_t cfg;
    cfg.Ts_s = 1e-4f;
    cfg.i_test_A = 2.0f;
    cfg.i_spin_A = 1.5f;
    cfg.i_trip_A = 4.0f;
    cfg.tau_i_s = 1e-3f;
    cfg.t_align_s = 0.02f;
    cfg.t_level_s = 0.02f;
    cfg.t_inductance_s = 0.0064f;
    cfg.t_ramp_s = 0.01f;
    cfg.t_spin_s = 0.02f;
    cfg.w_e_spin_radps = 100.0f;
    cfg.voltage_delay_samples = 0u;
    return cfg;
}

int main(void)
{
    const float Rs = 0.8f, L = 4e-3f, psi_f = 0.05f, Ts = 1e-4f, h = Ts / 4.0f, u_dc = 48.0f;
    p2d_commission_config_t cfg = servo_config();
    p2d_commission_output_t out;
    float id = 0.0f, iq = 0.0f;
    uint32_t sp, n = 0u;
    volatile uint32_t *paint;

    p2d_cost_sizeof(&line, "p2d_commission_t", sizeof(p2d_commission_t));
    p2d_cost_sizeof(&line, "p2d_commission_config_t", sizeof(p2d_commission_config_t));
    p2d_cost_sizeof(&line, "p2d_commission_output_t", sizeof(p2d_commission_output_t));
    if (p2d_commission_init(&routine, &cfg) != P2D_OK) p2d_semihost_exit(false);

    /* the steps run from here, with this stack pointer: paint once, read the high-water mark at the end */
    sp = p2d_stack_pointer();
    paint = (volatile uint32_t *)(uintptr_t)(sp - 4u * P2D_STACK_PAINT_WORDS);
    for (uint32_t i = 0u; i < P2D_STACK_PAINT_WORDS; ++i) paint[i] = P2D_STACK_PATTERN;

    while (routine.phase < P2D_PHASE_DONE && n < P2D_MAX_STEPS) {
        p2d_cost_mark();
        p2d_commission_step(&routine, id, iq, u_dc, &out);
        phase_of_step[n++] = (uint8_t)out.phase;
        for (int j = 0; j < 4; ++j) {
            const float w = out.w_e_radps;
            const float did = (out.ud_V - Rs * id + w * L * iq) / L;
            const float diq = (out.uq_V - Rs * iq - w * (L * id + psi_f)) / L;
            id += h * did;
            iq += h * diq;
        }
    }
    {
        uint32_t i = 0u;
        while (i < P2D_STACK_PAINT_WORDS && paint[i] == P2D_STACK_PATTERN) ++i;
        print_hex("stack ", 4u * (P2D_STACK_PAINT_WORDS - i), 0u, false);
    }
    for (uint32_t k = 0u; k < n; ++k) print_hex("cstep ", k, phase_of_step[k], true);
    print_hex("result ", (uint32_t)routine.phase, (uint32_t)routine.reason, true);
    p2d_line_text(&line, "END");
    p2d_line_flush(&line);
    p2d_semihost_exit(routine.phase == P2D_PHASE_DONE);
}
