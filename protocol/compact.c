/* protocol/compact.c - the compact SAMPLE forms of PROTOCOL.md 4.4.1: binary16 (half) values
 * and u16 fixed-point (u, v), both directions, exact and without the F16C instructions (so
 * every host gives the same bits). These loops are the reference: the bulk entry points
 * (stp_f16_encode, stp_f16_decode, stp_sample_queries_f32, stp_put_queries_uv16) run
 * codec_avx2.c's forms instead when the CPU has AVX2 and F16C, bit for bit the same.
 *
 * Owns: stp_f32_to_f16, stp_f16_to_f32 (and stp_f16_encode / stp_f16_decode for replies),
 * stp_f32_to_unit16, stp_query_round, stp_sample_queries (every SAMPLE query layout widened
 * to stp_query, in this file so that the conversions inline into its loops),
 * stp_sample_queries_f32 (the same in the f32 wire layout, what the daemon samples) and
 * stp_put_queries_uv16 (the other way: stp_query narrowed to the UV16 layouts, what a client
 * sends; bodies.c's stp_put_queries calls it). Does not own the frame layouts around the
 * queries (bodies.c).
 */
#include "codec_simd.h"

static inline uint16_t f32_to_f16(float f)
{
    uint32_t x = stp_f2u(f);
    uint16_t sign = (uint16_t)((x >> 16) & 0x8000u);
    uint32_t ax = x & 0x7FFFFFFFu;
    /* the common cases first, without branches on the rounding: a normal result (adding
     * 0xFFF plus the kept bit's parity rounds to nearest, ties to even; a carry into the
     * exponent is right), and zero */
    if (ax - 0x38800000u < 0x477FF000u - 0x38800000u)
        return (uint16_t)(sign | (((ax + 0x0FFFu + ((ax >> 13) & 1u)) >> 13) - (112u << 10)));
    if (ax == 0)
        return sign;
    if (ax > 0x7F800000u)                 /* NaN: the quiet NaN, sign kept */
        return (uint16_t)(sign | 0x7E00u);
    if (ax >= 0x477FF000u)                /* >= 65520 (halfway past 65504, odd: rounds up), inf */
        return (uint16_t)(sign | 0x7C00u);
    if (ax >= 0x38800000u) {              /* >= 2^-14: a normal half */
        uint32_t h = (ax >> 13) - (112u << 10);
        uint32_t rem = ax & 0x1FFFu;
        if (rem > 0x1000u || (rem == 0x1000u && (h & 1u)))
            h++;                          /* a carry into the exponent is still right */
        return (uint16_t)(sign | h);
    }
    if (ax <= 0x33000000u)                /* <= 2^-25 (the tie with 0 goes to even: 0) */
        return sign;
    /* a subnormal half: value / 2^-24 = m x 2^(e - 126), e in 102..112 */
    uint32_t e = ax >> 23, m = (ax & 0x7FFFFFu) | 0x800000u;
    uint32_t shift = 126u - e;            /* 14..24 */
    uint32_t h = m >> shift, rem = m & ((1u << shift) - 1u), half = 1u << (shift - 1u);
    if (rem > half || (rem == half && (h & 1u)))
        h++;                              /* may become 0x400, the smallest normal: right */
    return (uint16_t)(sign | h);
}

static inline float f16_to_f32(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t em = h & 0x7FFFu;
    if (em - 0x0400u < 0x7C00u - 0x0400u)   /* normal: rebias the exponent */
        return stp_u2f(sign | ((em << 13) + (112u << 23)));
    uint32_t e = (h >> 10) & 0x1Fu, m = h & 0x3FFu;
    if (e == 0) {                         /* zero or subnormal: m x 2^-24, exact in binary32 */
        float v = (float)m * 0x1p-24f;
        return sign ? -v : v;
    }
    if (e == 31)                          /* inf, NaN (payload kept) */
        return stp_u2f(sign | 0x7F800000u | (m << 13));
    return stp_u2f(sign | ((e + 112u) << 23) | (m << 13));
}

uint16_t stp_f32_to_unit16(float u)
{
    if (!(u > 0.0f))                      /* NaN, negatives, 0 */
        return 0;
    if (u >= 65535.0f / 65536.0f)
        return 65535;
    /* u x 2^16 is exact, and so is its fraction: round to nearest, ties to even, by hand
     * (whatever rounding mode the caller's thread has set) */
    float x = u * 65536.0f;
    uint32_t i = (uint32_t)x;
    float frac = x - (float)i;
    if (frac > 0.5f || (frac == 0.5f && (i & 1u)))
        i++;
    return (uint16_t)i;
}

uint16_t stp_f32_to_f16(float f)
{
    return f32_to_f16(f);
}

float stp_f16_to_f32(uint16_t h)
{
    return f16_to_f32(h);
}

void stp_f16_encode_scalar(const float *v, size_t n, uint8_t *out)
{
    for (size_t i = 0; i < n; i++)
        stp_wr16(out + 2 * i, f32_to_f16(v[i]));
}

void stp_f16_encode(const float *v, size_t n, uint8_t *out)
{
    if (stp_codec_have_avx2())
        stp_f16_encode_avx2(v, n, out);
    else
        stp_f16_encode_scalar(v, n, out);
}

void stp_f16_decode_scalar(const uint8_t *p, size_t n, float *out)
{
    for (size_t i = 0; i < n; i++)
        out[i] = f16_to_f32(stp_rd16(p + 2 * i));
}

void stp_f16_decode(const uint8_t *p, size_t n, float *out)
{
    if (stp_codec_have_avx2())
        stp_f16_decode_avx2(p, n, out);
    else
        stp_f16_decode_scalar(p, n, out);
}

/* One layout per loop, so that no flag is tested per query (the daemon widens every compact
 * query through here). */
#define QUERY_LOOP(FACE_BYTES, RD_FACE, UV16)                                                 \
    for (uint32_t i = 0; i < n; i++, p += qs) {                                               \
        stp_query *q = &out[i];                                                               \
        const uint8_t *f = p + FACE_BYTES;                                                    \
        q->face = RD_FACE(p);                                                                 \
        if (UV16) {                                                                           \
            q->u = stp_unit16_to_f32(stp_rd16(f));                                            \
            q->v = stp_unit16_to_f32(stp_rd16(f + 2));                                        \
            q->dudx = f16_to_f32(stp_rd16(f + 4));                                        \
            q->dvdx = f16_to_f32(stp_rd16(f + 6));                                        \
            q->dudy = f16_to_f32(stp_rd16(f + 8));                                        \
            q->dvdy = f16_to_f32(stp_rd16(f + 10));                                       \
        } else {                                                                              \
            q->u = stp_u2f(stp_rd32(f));                                                      \
            q->v = stp_u2f(stp_rd32(f + 4));                                                  \
            q->dudx = stp_u2f(stp_rd32(f + 8));                                               \
            q->dvdx = stp_u2f(stp_rd32(f + 12));                                              \
            q->dudy = stp_u2f(stp_rd32(f + 16));                                              \
            q->dvdy = stp_u2f(stp_rd32(f + 20));                                              \
        }                                                                                     \
    }

void stp_sample_queries(const stp_sample_req *r, uint32_t first, uint32_t n, stp_query *out)
{
    unsigned fl = r->p.flags;
    size_t qs = stp_query_size(fl);
    const uint8_t *p = r->raw + (size_t)first * qs;
    switch (fl & STP_SF_COMPACT_MASK) {
    case STP_SF_UV16 | STP_SF_FACE16: QUERY_LOOP(2, stp_rd16, 1) break;
    case STP_SF_UV16:                 QUERY_LOOP(4, stp_rd32, 1) break;
    case STP_SF_FACE16:               QUERY_LOOP(2, stp_rd16, 0) break;
    default:                          QUERY_LOOP(4, stp_rd32, 0) break;
    }
}
#undef QUERY_LOOP

void stp_sample_queries_f32_scalar(const stp_sample_req *r, uint32_t first, uint32_t n,
                                   uint8_t *out)
{
    stp_query t[64];
    for (uint32_t i = 0; i < n;) {
        uint32_t m = n - i < 64 ? n - i : 64;
        stp_sample_queries(r, first + i, m, t);
        i += m;
        if (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && sizeof *t == STP_QUERY_SIZE) {
            memcpy(out, t, m * sizeof *t);   /* stp_query is the wire layout: one copy */
            out += m * sizeof *t;
            continue;
        }
        for (uint32_t j = 0; j < m; j++, out += STP_QUERY_SIZE) {
            stp_wr32(out, t[j].face);
            stp_wr32(out + 4, stp_f2u(t[j].u));
            stp_wr32(out + 8, stp_f2u(t[j].v));
            stp_wr32(out + 12, stp_f2u(t[j].dudx));
            stp_wr32(out + 16, stp_f2u(t[j].dvdx));
            stp_wr32(out + 20, stp_f2u(t[j].dudy));
            stp_wr32(out + 24, stp_f2u(t[j].dvdy));
        }
    }
}

void stp_sample_queries_f32(const stp_sample_req *r, uint32_t first, uint32_t n, uint8_t *out)
{
    if (stp_codec_have_avx2())
        stp_sample_queries_f32_avx2(r, first, n, out);
    else
        stp_sample_queries_f32_scalar(r, first, n, out);
}

void stp_put_queries_uv16_scalar(const stp_query *q, size_t n, int face16, uint8_t *out)
{
    size_t qs = face16 ? 14 : 16;
    for (size_t i = 0; i < n; i++, q++, out += qs) {
        uint8_t *f = out + (face16 ? 2 : 4);
        if (face16)
            stp_wr16(out, (uint16_t)q->face);
        else
            stp_wr32(out, q->face);
        stp_wr16(f, stp_f32_to_unit16(q->u));
        stp_wr16(f + 2, stp_f32_to_unit16(q->v));
        stp_wr16(f + 4, f32_to_f16(q->dudx));
        stp_wr16(f + 6, f32_to_f16(q->dvdx));
        stp_wr16(f + 8, f32_to_f16(q->dudy));
        stp_wr16(f + 10, f32_to_f16(q->dvdy));
    }
}

void stp_put_queries_uv16(const stp_query *q, size_t n, int face16, uint8_t *out)
{
    if (stp_codec_have_avx2())
        stp_put_queries_uv16_avx2(q, n, face16, out);
    else
        stp_put_queries_uv16_scalar(q, n, face16, out);
}

void stp_query_round(const stp_query *q, unsigned flags, stp_query *out)
{
    *out = *q;
    if (flags & STP_SF_FACE16)
        out->face = q->face & 0xFFFFu;
    if (flags & STP_SF_UV16) {
        out->u = stp_unit16_to_f32(stp_f32_to_unit16(q->u));
        out->v = stp_unit16_to_f32(stp_f32_to_unit16(q->v));
        out->dudx = stp_f16_to_f32(stp_f32_to_f16(q->dudx));
        out->dvdx = stp_f16_to_f32(stp_f32_to_f16(q->dvdx));
        out->dudy = stp_f16_to_f32(stp_f32_to_f16(q->dudy));
        out->dvdy = stp_f16_to_f32(stp_f32_to_f16(q->dvdy));
    }
}
