/*
 * pmsm2dof fuzzing: decoding of the libFuzzer byte string and the invariant check.
 *
 * The byte string is read front to back; past its end every read returns 0,
 * so any string decodes to a complete configuration and input sequence.
 *
 * A float is read as one tag byte and four value bytes. The tag chooses how
 * the value bytes are used:
 *   tag % 8 == 0     the raw IEEE-754 bit pattern (NaN, inf, subnormals, any sign)
 *   tag % 8 == 1     one of the special values of FZ_SPECIAL
 *   tag % 8 in 2..5  nominal * 10^(k / 16384), k a signed 16-bit integer:
 *                    within two decades of the nominal value (realistic)
 *   tag % 8 in 6..7  nominal * 10^(k / 4096): within eight decades
 * In the last two cases bit 16 of the value bytes flips the sign when the
 * quantity may be negative. Tag 2 with value 0 is the nominal value itself,
 * which is how the seed corpus writes a nominal configuration.
 */
#ifndef P2D_FUZZ_COMMON_H
#define P2D_FUZZ_COMMON_H

#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pmsm2dof/filter.h"

/* Abort (a crash for libFuzzer, which then saves the input) when cond is false. */
#define FZ_REQUIRE(cond, ...)                                                                                \
    do {                                                                                                     \
        if (!(cond)) {                                                                                       \
            fprintf(stderr, "pmsm2dof fuzz invariant violated at %s:%d: %s\n  ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                                                    \
            fputc('\n', stderr);                                                                             \
            abort();                                                                                         \
        }                                                                                                    \
    } while (0)

/*
 * Relative slack of the float32 invariants: a result that went through a few
 * float32 roundings may exceed its exact bound by a few units in the last
 * place; 4 FLT_EPSILON (4.8e-7) covers the scaling of a vector onto a limit
 * circle (one sqrt, one division, one product per component).
 */
#define FZ_LIMIT_SLACK (4.0 * FLT_EPSILON)

/*
 * ||v|| <= limit up to float32 rounding. The controllers compare squared
 * norms, so besides the relative slack the comparison carries the absolute
 * spacing of the smallest float32 subnormals in the squares (2^-149 each):
 * this matters only for limits below sqrt(FLT_MIN) = 1.1e-19.
 */
static inline bool fz_within_circle(double norm, float limit)
{
    double lim = (double)limit;
    return norm * norm <= lim * lim * (1.0 + 2.0 * FZ_LIMIT_SLACK) + 4.0 * 0x1p-149;
}

/*
 * Relative slack of the integrator bounds, applied to the sum of the
 * magnitudes of every term that enters the update: about 8 roundings of
 * FLT_EPSILON / 2 each, doubled.
 */
#define FZ_SUM_SLACK (8.0 * FLT_EPSILON)

/* The rounding slack of a float32 update whose terms have magnitudes summing to
 * magnitude_sum: relative, plus a few subnormal spacings (2^-149) for results near 0. */
static inline double fz_slack(double magnitude_sum) { return FZ_SUM_SLACK * magnitude_sum + 4.0 * 0x1p-149; }

typedef struct {
    const uint8_t *data; /* unread bytes */
    size_t size;         /* number of unread bytes */
} fz_reader_t;

static inline bool fz_done(const fz_reader_t *r) { return r->size == 0; }

static inline uint8_t fz_u8(fz_reader_t *r)
{
    uint8_t b = 0;
    if (r->size > 0) {
        b = r->data[0];
        r->data++;
        r->size--;
    }
    return b;
}

/* Little-endian 32-bit unsigned integer. */
static inline uint32_t fz_u32(fz_reader_t *r)
{
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= (uint32_t)fz_u8(r) << (8 * i);
    return v;
}

/* Little-endian 16-bit unsigned integer. */
static inline uint32_t fz_u16(fz_reader_t *r)
{
    uint32_t lo = fz_u8(r);
    return lo | ((uint32_t)fz_u8(r) << 8);
}

/* A fraction in [0, 1]. */
static inline double fz_unit(fz_reader_t *r) { return (double)fz_u16(r) / 65535.0; }

/* 1.40129846e-45f: the smallest subnormal */
static const float FZ_SPECIAL[16] = {0.0f,    -0.0f,    NAN,     -NAN,     INFINITY,        -INFINITY,
                                     FLT_MAX, -FLT_MAX, FLT_MIN, -FLT_MIN, 1.40129846e-45f, 1e-30f,
                                     1e30f,   -1e30f,   1.0f,    -1.0f};

/* A float for a quantity of typical magnitude nominal (see the file comment). */
static inline float fz_float(fz_reader_t *r, double nominal, bool may_be_negative)
{
    uint8_t tag = fz_u8(r);
    uint32_t bits = fz_u32(r);
    double decades, v;
    float f;
    switch (tag % 8u) {
    case 0: memcpy(&f, &bits, sizeof f); return f;
    case 1: return FZ_SPECIAL[bits % 16u];
    case 6:
    case 7: decades = (double)(int16_t)(uint16_t)(bits & 0xffffu) / 4096.0; break;
    default: decades = (double)(int16_t)(uint16_t)(bits & 0xffffu) / 16384.0; break;
    }
    v = nominal * pow(10.0, decades);
    if (may_be_negative && (bits & 0x10000u)) v = -v;
    return (float)v;
}

/*
 * An enumeration value: mostly one of the n_valid valid values, rarely
 * (bytes 248..255) an invalid one, including negative and huge values.
 */
static inline uint32_t fz_enum(fz_reader_t *r, uint32_t n_valid)
{
    uint8_t b = fz_u8(r);
    const uint32_t invalid[8] = {n_valid,     n_valid + 1u, n_valid + 5u, 100u,
                                 0x7fffffffu, 0x80000000u,  0xfffffffeu,  0xffffffffu};
    if (b < 248u) return b % n_valid;
    return invalid[b - 248u];
}

static inline bool fz_bits_equal(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

/*
 * The magnitude beyond which one sample of the filter chain c (filter.h) may
 * overflow float32 when its input and states are at most `magnitude`: every
 * intermediate of a section is at most about 4 (1 + K)^2 times its input or
 * states, K the largest of g, k and |c_band| of the sections that are on, and
 * the low-pass takes the notch's output; 16 (1 + K)^2 covers both.
 */
static inline bool fz_filter_may_overflow(const p2d_filter_coef_t *c, double magnitude)
{
    double K = 0.0;
    if (c->has_notch) K = fmax(fmax(K, c->notch.g), fmax(c->notch.k, fabs(c->notch.c_band)));
    if (c->has_lowpass) K = fmax(fmax(K, c->lowpass.g), c->lowpass.k);
    return 16.0 * (1.0 + K) * (1.0 + K) * magnitude > 0.5 * FLT_MAX;
}

#endif /* P2D_FUZZ_COMMON_H */
