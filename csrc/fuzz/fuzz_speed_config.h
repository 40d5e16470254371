/*
 * pmsm2dof fuzzing: the decoding of a speed-controller configuration (pmsm2dof/speed.h), shared by
 * the float (fuzz_speed.c) and the fixed-point (fuzz_speed_fixed.c) targets.
 */
#ifndef P2D_FUZZ_SPEED_CONFIG_H
#define P2D_FUZZ_SPEED_CONFIG_H

#include "fuzz_common.h"
#include "pmsm2dof/speed.h"

/* The paper's default Ka = 1/Kp (section 3.3) when it is a usable nominal value. */
static inline double fz_ka_nominal(float J_kgm2, float alpha_radps)
{
    float Ka = p2d_speed_Ka_default(J_kgm2, alpha_radps);
    return (isfinite(Ka) && Ka > 0.0f) ? (double)Ka : 0.1;
}

static inline uint32_t fz_pole_pairs(fz_reader_t *r)
{
    static const uint32_t odd[6] = {0u, 64u, 255u, 100000u, 0x80000000u, 0xffffffffu};
    uint8_t b = fz_u8(r);
    return b < 250u ? 1u + b % 8u : odd[b - 250u];
}

/*
 * A configuration around a 0.4 kg m^2 drive (the paper's section 4 inertia),
 * alpha = 20 rad/s, Ts = 1 ms. Bit 0 of the shape byte makes it a surface
 * PMSM (Lq = Ld), bit 1 sets m = 1 (so that the lowpass form is valid).
 */
static inline void fz_speed_config(fz_reader_t *r, p2d_speed_config_t *cfg)
{
    uint8_t shape = fz_u8(r);
    memset(cfg, 0, sizeof *cfg);
    cfg->J_kgm2 = fz_float(r, 0.4, false);
    cfg->alpha_radps = fz_float(r, 20.0, false);
    cfg->zeta = fz_float(r, 1.0, false);
    cfg->m = (shape & 2u) ? 1.0f : fz_float(r, 1.0, false);
    cfg->tau_i_s = fz_float(r, 0.005, false);
    cfg->Ka = fz_float(r, fz_ka_nominal(cfg->J_kgm2, cfg->alpha_radps), false);
    cfg->Ts_s = fz_float(r, 1e-3, false);
    cfg->i_max_A = fz_float(r, 7.6, false);
    cfg->psi_f_Wb = fz_float(r, 0.2, false);
    cfg->Ld_H = fz_float(r, 0.01, false);
    cfg->Lq_H = (shape & 1u) ? cfg->Ld_H : fz_float(r, 0.02, false);
    cfg->pole_pairs = fz_pole_pairs(r);
    cfg->method = (p2d_method_t)fz_enum(r, 3u);
    cfg->feedforward = (p2d_feedforward_t)fz_enum(r, 4u);
    cfg->anti_windup = (p2d_anti_windup_t)fz_enum(r, 3u);
}

#endif /* P2D_FUZZ_SPEED_CONFIG_H */
