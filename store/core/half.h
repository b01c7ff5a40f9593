/* store/core/half.h - IEEE 754 binary16 <-> float conversion, inline, no tables, no globals.
 * Used by the sampler (half texels are sampled to float), the Ptex and EXR readers/writers. */
#ifndef ST_HALF_H
#define ST_HALF_H

#include <stdint.h>
#include <string.h>

static inline float st_half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t exp = (h >> 10) & 0x1fu;
    uint32_t man = h & 0x3ffu;
    uint32_t bits;
    if (exp == 0) {
        if (man == 0) {
            bits = sign;
        } else { /* subnormal: renormalise */
            int e = -1;
            do { e++; man <<= 1; } while (!(man & 0x400u));
            bits = sign | ((uint32_t)(127 - 15 - e) << 23) | ((man & 0x3ffu) << 13);
        }
    } else if (exp == 31) {
        bits = sign | 0x7f800000u | (man << 13);
    } else {
        bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
    }
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

/* Round to nearest even; overflow gives infinity, NaN stays NaN. */
static inline uint16_t st_float_to_half(float f)
{
    uint32_t x;
    memcpy(&x, &f, sizeof x);
    uint32_t sign = (x >> 16) & 0x8000u;
    uint32_t ax = x & 0x7fffffffu;
    if (ax >= 0x7f800000u) /* inf or nan */
        return (uint16_t)(sign | 0x7c00u | (ax > 0x7f800000u ? 0x200u : 0));
    if (ax >= 0x477ff000u) /* rounds to >= 65520: overflow */
        return (uint16_t)(sign | 0x7c00u);
    if (ax < 0x38800000u) { /* result is subnormal or zero */
        if (ax < 0x33000000u)
            return (uint16_t)sign;
        uint32_t e = ax >> 23;
        uint32_t m = (ax & 0x7fffffu) | 0x800000u;
        uint32_t shift = 126 - e; /* 14..24 */
        uint32_t r = m >> (shift);
        uint32_t rem = m & ((1u << shift) - 1);
        uint32_t halfway = 1u << (shift - 1);
        if (rem > halfway || (rem == halfway && (r & 1)))
            r++;
        return (uint16_t)(sign | r);
    }
    uint32_t r = ((ax - 0x38000000u) >> 13);
    uint32_t rem = ax & 0x1fffu;
    if (rem > 0x1000u || (rem == 0x1000u && (r & 1)))
        r++;
    return (uint16_t)(sign | r);
}

/* Ptex's float -> half (PtexHalf::fromFloat, v2.4), which the Ptex reader and writer use for
 * every half value they compute (reductions, averages): normal results round half away from
 * zero (mantissa + 0x1000, then >> 13; a carry moves into the exponent, up to infinity),
 * subnormal results are int(|f| * 2^24 + 0.5) computed in double, +-0 gives +0, too large
 * values give infinity and NaN keeps the top mantissa bits (0x7c00 | m >> 13). It differs from
 * st_float_to_half (nearest even) on ties, so the levels seamtex computes the way Ptex does
 * (store/ptex/ptexres.c, core/trilevel.c) use this one to match Ptex's bits. */
static inline uint16_t st_float_to_half_ptex(float f)
{
    if (f == 0.0f)
        return 0;
    uint32_t x;
    memcpy(&x, &f, sizeof x);
    uint32_t sign = (x >> 16) & 0x8000u, E = (x >> 23) & 0xffu;
    if (E >= 113 && E <= 142)
        return (uint16_t)((sign | ((E - 112) << 10)) + (((x & 0x7fffffu) + 0x1000u) >> 13));
    if (E <= 112) {
        double a = (double)(f < 0 ? -f : f);
        return (uint16_t)(sign | (uint32_t)(int)(a * 1.6777216e7 + .5));
    }
    if (E == 255)
        return (uint16_t)(sign | 0x7c00u | ((x & 0x7fffffu) >> 13));
    return (uint16_t)(sign | 0x7c00u);
}

#endif
