/* tests/unit/test_codec_simd.c - the AVX2 + F16C codecs of protocol/codec_avx2.c against the
 * portable reference loops (codec_simd.h), bit for bit: binary32 -> binary16 over every
 * binary32 value next to a binary16 value or to a rounding tie, every edge class (zeros,
 * subnormals, 2^-25, 65504..65520, infinities, signalling and quiet NaNs with payloads) and
 * millions of random bit patterns; binary16 -> binary32 over all 65536 halves; unorm8 and
 * unorm16 around every step and tie, out of range, NaN; the compact query layouts (UV16,
 * UV16 + FACE16) over random bytes (NaN and infinite derivatives included), and the other
 * way (a client's stp_query narrowed to those layouts) over every u16 step and tie of u and v
 * with their neighbours, out-of-range, infinite and NaN u and v, every edge class of the
 * derivatives and random bit patterns, in each rounding mode. Every length
 * 0..67 at unaligned offsets, with the input ending at an unreadable page (an over-read
 * faults) and canaries around the output (an over-write fails). Also that the public entry
 * points (stp_f16_encode, stp_f16_decode, stp_enc_sample_values, stp_sample_queries_f32) give
 * the reference's bytes whichever path they take. Skips the comparisons on a CPU without
 * AVX2 and F16C.
 */
#include <fenv.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>
#include <cmocka.h>

#include "../common/skip_unless.h"

#include "codec_simd.h"

static uint64_t rng = 0x9E3779B97F4A7C15ull;
static uint32_t rnd(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (uint32_t)(rng >> 16);
}

static float from_bits(uint32_t u)
{
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* `bytes` readable bytes that end where an unreadable page begins (munmap with guard_free). */
typedef struct guard {
    uint8_t *map;
    size_t   len;
    uint8_t *p;
} guard;

static guard guard_alloc(size_t bytes)
{
    size_t pg = (size_t)sysconf(_SC_PAGESIZE);
    size_t data = (bytes + pg - 1) / pg * pg + pg;
    guard g;
    g.len = data + pg;
    g.map = mmap(NULL, g.len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    assert_true(g.map != MAP_FAILED);
    assert_int_equal(mprotect(g.map + data, pg, PROT_NONE), 0);
    g.p = g.map + data - bytes;
    return g;
}

static void guard_free(guard *g)
{
    munmap(g->map, g->len);
}

#define SKIP_WITHOUT_AVX2()                                                                \
    ST_SKIP_UNLESS(stp_codec_have_avx2(), "no AVX2 + F16C on this CPU: only the portable loops run")

typedef void (*enc_fn)(const float *, size_t, uint8_t *);

/* Encodes v[0..n) both ways, in chunks of up to 4096, and fails at the first value whose
 * bytes differ (naming it). esz: output bytes per value. */
static void same_encoding(const char *what, enc_fn fast, enc_fn ref, const float *v, size_t n,
                          size_t esz)
{
    uint8_t a[4096 * 2], b[4096 * 2];
    for (size_t at = 0; at < n; at += 4096) {
        size_t m = n - at < 4096 ? n - at : 4096;
        fast(v + at, m, a);
        ref(v + at, m, b);
        if (memcmp(a, b, m * esz) != 0) {
            for (size_t i = 0; i < m; i++) {
                if (memcmp(a + i * esz, b + i * esz, esz) != 0) {
                    uint32_t x;
                    memcpy(&x, v + at + i, 4);
                    fail_msg("%s of 0x%08x (%g): fast %02x%02x, reference %02x%02x", what, x,
                             (double)v[at + i], a[i * esz + esz - 1], a[i * esz],
                             b[i * esz + esz - 1], b[i * esz]);
                }
            }
        }
    }
}

/* Every length 0..67 at input offsets 0..7 (values, so misaligned for vectors) and output
 * offsets 0..7 bytes, the input ending at an unreadable page, canaries around the output. */
static void every_length_and_offset(const char *what, enc_fn fast, enc_fn ref,
                                    const float *pool, size_t esz)
{
    guard g = guard_alloc(80 * sizeof(float));
    for (size_t n = 0; n <= 67; n++) {
        for (size_t io = 0; io < 8; io++) {
            float *in = (float *)(void *)g.p + (80 - n);
            memcpy(in, pool + io * 7, n * sizeof *in);
            for (size_t oo = 0; oo < 8; oo++) {
                uint8_t a[16 + 80 * 2 + 16], b[sizeof a];
                memset(a, 0xA5, sizeof a);
                memset(b, 0xA5, sizeof b);
                fast(in, n, a + 16 + oo);
                ref(in, n, b + 16 + oo);
                size_t span = 16 + oo + n * esz + 16;   /* the values and canaries both sides */
                if (memcmp(a, b, span) != 0)
                    fail_msg("%s: %zu values at output offset %zu differ (or the fast path wrote "
                             "outside them)", what, n, oo);
            }
        }
    }
    /* inputs at every misalignment from a 32-byte boundary, the end of the run not at a page */
    float *buf = aligned_alloc(32, 128 * sizeof(float));
    memcpy(buf, pool, 128 * sizeof(float));
    for (size_t io = 0; io < 8; io++) {
        for (size_t n = 0; n <= 67; n++) {
            uint8_t a[80 * 2], b[80 * 2];
            memset(a, 0x5A, sizeof a);
            memset(b, 0x5A, sizeof b);
            fast(buf + io, n, a);
            ref(buf + io, n, b);
            assert_memory_equal(a, b, sizeof a);
        }
    }
    free(buf);
    guard_free(&g);
}

/* A pool of values of every class, for the length and offset runs. */
static void edge_pool(float *pool, size_t n)
{
    static const uint32_t edges[] = {
        0x00000000, 0x80000000, 0x00000001, 0x807FFFFF, 0x00800000, 0x33000000, 0x33000001,
        0xB3000000, 0x337FFFFF, 0x33800000, 0x387FC000, 0x387FE000, 0x387FF000, 0x38800000,
        0x3F000000, 0x3F800000, 0xBF800000, 0x3F7FFFFF, 0x3B808081, 0x3F0C0C0C, 0x477FE000,
        0x477FEFFF, 0x477FF000, 0xC77FF000, 0x477FF001, 0x47800000, 0x7F7FFFFF, 0x7F800000,
        0xFF800000, 0x7F800001, 0x7FBFFFFF, 0x7FC00000, 0xFFC00000, 0x7FFFFFFF, 0xFFFFFFFF,
        0x7F802000, 0x7FC02000, 0xFF801FFF, 0x40490FDB, 0xC2F6E979,
    };
    size_t ne = sizeof edges / sizeof *edges;
    for (size_t i = 0; i < n; i++)
        pool[i] = from_bits(i % 3 == 0 ? edges[(i / 3) % ne] : i % 3 == 1 ? rnd()
                                                       : 0x3C000000u + (rnd() & 0x03FFFFFFu));
}

static void f16_encode_equals_the_reference(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    size_t cap = 1u << 22;
    float *v = malloc(cap * sizeof *v);
    size_t n = 0;
    /* every binary16 value as binary32, its neighbours, and the ties halfway to the next
     * half (normal: 0x1000 ulps up; subnormal halves are 2^-24 apart: 2^-25 up) and theirs */
    for (uint32_t h = 0; h < 65536; h++) {
        float f = stp_f16_to_f32((uint16_t)h);
        uint32_t b;
        memcpy(&b, &f, 4);
        uint32_t half_up = (h & 0x7C00) ? 0x1000u : 0;
        static const int32_t d[] = { -1, 0, 1 };
        for (int k = 0; k < 3; k++) {
            v[n++] = from_bits(b + (uint32_t)d[k]);
            if (half_up)
                v[n++] = from_bits(b + half_up + (uint32_t)d[k]);
        }
        if (!(h & 0x7C00)) {   /* subnormal (or zero) half: the tie with the next one */
            double tie = ((h & 0x3FF) + 0.5) * 0x1p-24 * ((h & 0x8000) ? -1 : 1);
            float t = (float)tie;
            v[n++] = t;
            v[n++] = nextafterf(t, 0.0f);
            v[n++] = nextafterf(t, t * 2);
        }
    }
    /* random bit patterns, and random values in the range that becomes normal halves */
    for (; n < cap; n++) {
        uint32_t x = rnd();
        v[n] = from_bits(n & 1 ? x : (x & 0x80000000u) | (0x30000000u + (x & 0x1FFFFFFFu)));
    }
    same_encoding("f16", stp_f16_encode_avx2, stp_f16_encode_scalar, v, n, 2);
    /* the public entry point */
    uint8_t a[64], b[64];
    stp_f16_encode(v, 32, a);
    stp_f16_encode_scalar(v, 32, b);
    assert_memory_equal(a, b, 64);
    float pool[200];
    edge_pool(pool, 200);
    every_length_and_offset("f16", stp_f16_encode_avx2, stp_f16_encode_scalar, pool, 2);
    free(v);
}

static void f16_nan_and_overflow_follow_the_spec(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    /* the spec's answers themselves (PROTOCOL.md 4.4.1), on the fast path */
    const uint32_t in[8] = { 0x7FFFFFFF, 0xFF800001, 0x7F802000, 0x477FF000,
                             0x477FEFFF, 0x33000000, 0xB3000001, 0x80000000 };
    const uint16_t want[8] = { 0x7E00, 0xFE00, 0x7E00, 0x7C00, 0x7BFF, 0x0000, 0x8001, 0x8000 };
    float v[8];
    uint8_t out[16];
    for (int i = 0; i < 8; i++)
        v[i] = from_bits(in[i]);
    stp_f16_encode_avx2(v, 8, out);
    for (int i = 0; i < 8; i++)
        assert_int_equal(stp_rd16(out + 2 * i), want[i]);
}

static void f16_decode_equals_the_reference_for_every_half(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    guard g = guard_alloc(65536 * 2);
    for (uint32_t h = 0; h < 65536; h++)
        stp_wr16(g.p + 2 * h, (uint16_t)h);
    float *a = malloc(65536 * sizeof *a), *b = malloc(65536 * sizeof *b);
    stp_f16_decode_avx2(g.p, 65536, a);
    stp_f16_decode_scalar(g.p, 65536, b);
    for (uint32_t h = 0; h < 65536; h++) {
        uint32_t x, y;
        memcpy(&x, a + h, 4);
        memcpy(&y, b + h, 4);
        if (x != y)
            fail_msg("half 0x%04x: fast 0x%08x, reference 0x%08x", h, x, y);
    }
    /* every length 0..67 at every byte offset, ending at the unreadable page */
    for (size_t n = 0; n <= 67; n++) {
        for (size_t off = 0; off < 8; off++) {
            const uint8_t *p = g.p + 65536 * 2 - 2 * n;
            float x[80], y[80];
            memset(x, 0xA5, sizeof x);
            memset(y, 0xA5, sizeof y);
            /* a misaligned copy of the same halves (h values drawn from the NaN range too) */
            uint8_t src[2 * 67 + 8];
            memcpy(src + off, g.p + 2 * (0x7BF0 + 37 * off), 2 * n);
            stp_f16_decode_avx2(p, n, x + 1);
            stp_f16_decode_scalar(p, n, y + 1);
            assert_memory_equal(x, y, sizeof x);
            stp_f16_decode_avx2(src + off, n, x + 1);
            stp_f16_decode_scalar(src + off, n, y + 1);
            assert_memory_equal(x, y, sizeof x);
        }
    }
    /* the public entry point */
    stp_f16_decode(g.p + 2 * 0x7C00, 1024, a);
    stp_f16_decode_scalar(g.p + 2 * 0x7C00, 1024, b);
    assert_memory_equal(a, b, 1024 * sizeof *a);
    free(a);
    free(b);
    guard_free(&g);
}

static void unorm_encodes_equal_the_reference(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    size_t cap = 1u << 22;
    float *v = malloc(cap * sizeof *v);
    size_t n = 0;
    /* each step k / max and each tie (k + 0.5) / max, with their binary32 neighbours */
    for (uint32_t k = 0; k <= 65535; k++) {
        float s[2] = { (float)k / 65535.0f, (float)((k + 0.5) / 65535.0) };
        float s8[2] = { (float)(k % 256) / 255.0f, (float)((k % 256 + 0.5) / 255.0) };
        for (int j = 0; j < 2; j++) {
            v[n++] = s[j];
            v[n++] = nextafterf(s[j], -1.0f);
            v[n++] = nextafterf(s[j], 2.0f);
            v[n++] = s8[j];
            v[n++] = nextafterf(s8[j], 2.0f);
        }
    }
    static const uint32_t edges[] = { 0x7FC00000, 0xFFC00000, 0x7F800001, 0x7F800000, 0xFF800000,
                                      0x80000000, 0x00000000, 0x00000001, 0x3F800000, 0x3F800001,
                                      0x3F7FFFFF, 0x3F000000, 0xBF000000, 0x7F7FFFFF, 0xFF7FFFFF,
                                      0x4F000000, 0xCF000000, 0x3B000000, 0x37800000 };
    for (size_t i = 0; i < sizeof edges / sizeof *edges; i++)
        v[n++] = from_bits(edges[i]);
    for (; n < cap; n++) {
        uint32_t x = rnd();
        v[n] = (n & 1) ? from_bits(x) : (float)(x >> 8) * 0x1.2p-24f - 0.05f;
    }
    same_encoding("unorm8", stp_unorm8_encode_avx2, stp_unorm8_encode_scalar, v, n, 1);
    same_encoding("unorm16", stp_unorm16_encode_avx2, stp_unorm16_encode_scalar, v, n, 2);
    float pool[200];
    edge_pool(pool, 200);
    every_length_and_offset("unorm8", stp_unorm8_encode_avx2, stp_unorm8_encode_scalar, pool, 1);
    every_length_and_offset("unorm16", stp_unorm16_encode_avx2, stp_unorm16_encode_scalar, pool,
                            2);
    /* the public entry point, each format */
    uint8_t a[4 * 100], b[4 * 100];
    for (uint8_t fmt = 0; fmt < 4; fmt++) {
        size_t esz = stp_outfmt_size(fmt);
        stp_enc_sample_values(a, v, 100, fmt);
        switch (fmt) {
        case STP_OUT_UNORM8:  stp_unorm8_encode_scalar(v, 100, b); break;
        case STP_OUT_UNORM16: stp_unorm16_encode_scalar(v, 100, b); break;
        case STP_OUT_F16:     stp_f16_encode_scalar(v, 100, b); break;
        default:
            for (size_t i = 0; i < 100; i++)
                memcpy(b + 4 * i, v + i, 4);
        }
        assert_memory_equal(a, b, 100 * esz);
    }
    free(v);
}

/* Widens n queries of layout flags at raw both ways (from query `first`), out at offset oo
 * with canaries, and compares. */
static void same_queries(unsigned flags, const uint8_t *raw, uint32_t first, uint32_t n,
                         size_t oo)
{
    stp_sample_req r;
    memset(&r, 0, sizeof r);
    r.p.flags = (uint8_t)flags;
    r.raw = raw;
    r.count = first + n;
    size_t bytes = 16 + (size_t)n * STP_QUERY_SIZE + 16 + 8;
    uint8_t *a = malloc(bytes), *b = malloc(bytes);
    memset(a, 0xA5, bytes);
    memset(b, 0xA5, bytes);
    stp_sample_queries_f32_avx2(&r, first, n, a + 16 + oo);
    stp_sample_queries_f32_scalar(&r, first, n, b + 16 + oo);
    if (memcmp(a, b, bytes) != 0) {
        for (size_t i = 0; i < bytes; i++)
            if (a[i] != b[i])
                fail_msg("flags %u, %u queries from %u, output offset %zu: byte %zd differs "
                         "(fast %02x, reference %02x)", flags, n, first, oo,
                         (ssize_t)i - 16 - (ssize_t)oo, a[i], b[i]);
    }
    /* the public entry point, and the queries as stp_sample_queries gives them */
    stp_sample_queries_f32(&r, first, n, a + 16 + oo);
    assert_memory_equal(a, b, bytes);
    for (uint32_t i = 0; i < n; i++) {
        stp_query q;
        stp_sample_query(&r, first + i, &q);
        const uint8_t *w = b + 16 + oo + (size_t)i * STP_QUERY_SIZE;
        assert_int_equal(stp_rd32(w), q.face);
        assert_int_equal(stp_rd32(w + 4), stp_f2u(q.u));
        assert_int_equal(stp_rd32(w + 24), stp_f2u(q.dvdy));
    }
    free(a);
    free(b);
}

static void compact_queries_widen_as_the_reference(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    static const unsigned layouts[] = { STP_SF_UV16 | STP_SF_FACE16, STP_SF_UV16, STP_SF_FACE16,
                                        0 };
    for (size_t l = 0; l < 4; l++) {
        unsigned fl = layouts[l];
        size_t qs = stp_query_size(fl);
        /* random bytes: every half pattern turns up among the derivatives, NaNs included;
         * one query in 4 gets a NaN or infinite derivative on purpose */
        size_t nq = 1u << 17;
        uint8_t *raw = malloc(nq * qs);
        for (size_t i = 0; i < nq * qs; i++)
            raw[i] = (uint8_t)rnd();
        if (fl & STP_SF_UV16) {
            for (size_t i = 0; i < nq; i += 4) {
                size_t d = (fl & STP_SF_FACE16 ? 2 : 4) + 4 + 2 * (rnd() % 4);
                stp_wr16(raw + i * qs + d, (uint16_t)(0x7C00 | (rnd() & 0x83FF)));
            }
        }
        for (size_t at = 0; at < nq; at += 4096)
            same_queries(fl, raw, (uint32_t)at, 4096, at / 4096 % 4);
        /* every count 0..67, ending at an unreadable page, at byte offsets of the output */
        guard g = guard_alloc(67 * qs);
        for (uint32_t n = 0; n <= 67; n++) {
            uint8_t *p = g.p + (67 - n) * qs;
            memcpy(p, raw + n * 97, n * qs);
            for (size_t oo = 0; oo < 8; oo++)
                same_queries(fl, p, 0, n, oo);
            if (n)
                same_queries(fl, g.p + 66 * qs - (n - 1) * qs, n - 1, 1, n % 8);  /* first > 0 */
        }
        guard_free(&g);
        free(raw);
    }
}

/* Narrows q[0..n) both ways for one layout, the output at offset oo with canaries, and fails
 * at the first query whose bytes differ (naming it). */
static void same_narrowing(int face16, const stp_query *q, size_t n, size_t oo)
{
    size_t qs = face16 ? 14 : 16, bytes = 16 + n * qs + 16 + 8;
    uint8_t *a = malloc(bytes), *b = malloc(bytes);
    memset(a, 0xA5, bytes);
    memset(b, 0xA5, bytes);
    stp_put_queries_uv16_avx2(q, n, face16, a + 16 + oo);
    stp_put_queries_uv16_scalar(q, n, face16, b + 16 + oo);
    if (memcmp(a, b, bytes) != 0) {
        for (size_t i = 0; i < bytes; i++) {
            if (a[i] == b[i])
                continue;
            ssize_t at = (ssize_t)i - 16 - (ssize_t)oo;
            if (at < 0 || at >= (ssize_t)(n * qs))
                fail_msg("face16 %d, %zu queries: the fast path wrote byte %zd, outside them",
                         face16, n, at);
            const stp_query *x = &q[(size_t)at / qs];
            fail_msg("face16 %d, query %zd (face %u u 0x%08x v 0x%08x d 0x%08x 0x%08x 0x%08x "
                     "0x%08x): byte %zd: fast %02x, reference %02x", face16, at / (ssize_t)qs,
                     x->face, stp_f2u(x->u), stp_f2u(x->v), stp_f2u(x->dudx), stp_f2u(x->dvdx),
                     stp_f2u(x->dudy), stp_f2u(x->dvdy), at % (ssize_t)qs, a[i], b[i]);
        }
    }
    /* the public entry point */
    memset(a, 0xA5, bytes);
    stp_put_queries_uv16(q, n, face16, a + 16 + oo);
    assert_memory_equal(a, b, bytes);
    free(a);
    free(b);
}

/* A u or v of every kind: each u16 step k / 2^16 and tie (k + 0.5) / 2^16 (the even and odd
 * cases) with their binary32 neighbours, the clamp at 65535 / 65536, out of range, zeros,
 * subnormals, infinities, NaNs, random bit patterns and random values in [0, 1). */
static float uv_value(size_t i)
{
    static const uint32_t edges[] = {
        0x00000000, 0x80000000, 0x00000001, 0x80000001, 0x007FFFFF, 0x00800000, 0x37800000,
        0x377FFFFF, 0x37000000, 0x37000001, 0x36FFFFFF, 0x37C00000, 0x3F7FFF00, 0x3F7FFEFF,
        0x3F7FFF01, 0x3F7FFF80, 0x3F7FFF7F, 0x3F7FFFFF, 0x3F800000, 0x3F800001, 0x40000000,
        0x7F7FFFFF, 0x7F800000, 0xFF800000, 0x7FC00000, 0xFFC00000, 0x7F800001, 0xFFBFFFFF,
        0xBF800000, 0xB7800000, 0x4F800000, 0xCF800000,
    };
    size_t ne = sizeof edges / sizeof *edges;
    switch (i % 8) {
    case 0: case 1: case 2: {                    /* steps and ties, walked in order */
        uint32_t k = (uint32_t)(i / 8) % 65536;
        float t = (i % 8 == 0) ? (float)k * 0x1p-16f : ((float)k + 0.5f) * 0x1p-16f;
        return i % 3 == 0 ? t : i % 3 == 1 ? nextafterf(t, -1.0f) : nextafterf(t, 2.0f);
    }
    case 3: return from_bits(edges[(i / 8) % ne]);
    case 4: return from_bits(rnd());
    case 5: return (float)(rnd() >> 8) * 0x1p-24f;
    case 6: return ((float)(rnd() % 65536) + 0.5f) * 0x1p-16f;
    default: return (float)(rnd() >> 8) * 0x1p-23f - 0.5f;   /* [-0.5, 1.5) */
    }
}

static void fill_queries(stp_query *q, size_t n, size_t salt)
{
    float pool[512];
    edge_pool(pool, 512);
    for (size_t i = 0; i < n; i++) {
        q[i].face = (i & 1) ? rnd() : rnd() % 70000;
        q[i].u = uv_value(i + salt);
        q[i].v = uv_value(i * 7 + 3 + salt);
        float *d = &q[i].dudx;
        for (int k = 0; k < 4; k++)
            d[k] = (i + k) % 2 ? pool[(i * 4 + (size_t)k + salt) % 512] : from_bits(rnd());
    }
}

static void compact_queries_narrow_as_the_reference(void **state)
{
    (void)state;
    SKIP_WITHOUT_AVX2();
    /* the spec's answers themselves (PROTOCOL.md 4.4.1), on the fast path */
    stp_query s[6];
    static const float su[6] = { 0.5f / 65536, 1.5f / 65536, 65534.5f / 65536, 65535.0f / 65536,
                                 -0.0f, 2.0f };
    static const uint16_t want[6] = { 0, 2, 65534, 65535, 0, 65535 };
    for (int i = 0; i < 6; i++) {
        memset(&s[i], 0, sizeof s[i]);
        s[i].face = 0x12345u + (uint32_t)i;
        s[i].u = su[i];
        s[i].v = from_bits(0x7FC00000);          /* NaN: 0 */
        s[i].dudx = 65520.0f;                    /* inf */
        s[i].dvdx = from_bits(0xFFC00001);       /* NaN: 0xFE00 */
        s[i].dudy = 0x1p-25f;                    /* the tie with 0: 0 */
        s[i].dvdy = -1.0f;
    }
    uint8_t o[6 * 14];
    stp_put_queries_uv16_avx2(s, 6, 1, o);
    for (int i = 0; i < 6; i++) {
        const uint8_t *p = o + 14 * i;
        assert_int_equal(stp_rd16(p), 0x2345u + (unsigned)i);
        assert_int_equal(stp_rd16(p + 2), want[i]);
        assert_int_equal(stp_rd16(p + 4), 0);
        assert_int_equal(stp_rd16(p + 6), 0x7C00);
        assert_int_equal(stp_rd16(p + 8), 0xFE00);
        assert_int_equal(stp_rd16(p + 10), 0);
        assert_int_equal(stp_rd16(p + 12), 0xBC00);
    }
    size_t nq = (size_t)8 * 65536 * 2 + 1000;     /* every step and tie, twice over */
    stp_query *q = malloc(nq * sizeof *q);
    fill_queries(q, nq, 0);
    static const int modes[] = { FE_TONEAREST, FE_UPWARD, FE_DOWNWARD, FE_TOWARDZERO };
    for (int face16 = 0; face16 < 2; face16++) {
        for (size_t m = 0; m < 4; m++) {
            assert_int_equal(fesetround(modes[m]), 0);
            for (size_t at = 0; at < nq; at += 4096)
                same_narrowing(face16, q + at, nq - at < 4096 ? nq - at : 4096, at / 4096 % 8);
        }
        assert_int_equal(fesetround(FE_TONEAREST), 0);
        /* every count 0..67, the input ending at an unreadable page, at output offsets */
        guard g = guard_alloc(67 * sizeof *q);
        for (size_t n = 0; n <= 67; n++) {
            stp_query *p = (stp_query *)(void *)g.p + (67 - n);
            memcpy(p, q + n * 131, n * sizeof *q);
            for (size_t oo = 0; oo < 8; oo++)
                same_narrowing(face16, p, n, oo);
        }
        guard_free(&g);
    }
    /* the frame encoder (bodies.c stp_put_queries) gives the reference's bytes */
    for (unsigned fl = 0; fl < 16; fl += 4) {
        stp_sample_req r;
        memset(&r, 0, sizeof r);
        snprintf(r.p.name, sizeof r.p.name, "default");
        r.p.flags = (uint8_t)fl;
        r.count = 300;
        r.queries = q + 77;
        size_t qs = stp_query_size(fl);
        uint8_t *a = malloc(300 * 28), *b = malloc(300 * 28);
        stp_put_queries(STP_OP_SAMPLE, &r, a);
        if (fl & STP_SF_UV16)
            stp_put_queries_uv16_scalar(r.queries, 300, (fl & STP_SF_FACE16) != 0, b);
        else
            for (size_t i = 0; i < 300; i++) {
                const stp_query *x = &r.queries[i];
                uint8_t *w = b + i * qs, *f = w + ((fl & STP_SF_FACE16) ? 2 : 4);
                if (fl & STP_SF_FACE16)
                    stp_wr16(w, (uint16_t)x->face);
                else
                    stp_wr32(w, x->face);
                const float *v = &x->u;
                for (int k = 0; k < 6; k++)
                    stp_wr32(f + 4 * k, stp_f2u(v[k]));
            }
        assert_memory_equal(a, b, 300 * qs);
        /* and what the daemon widens back is the rounded query (stp_query_round) */
        if (fl & STP_SF_UV16) {
            stp_sample_req d;
            memset(&d, 0, sizeof d);
            d.p.flags = (uint8_t)fl;
            d.raw = a;
            d.count = 300;
            for (uint32_t i = 0; i < 300; i++) {
                stp_query got, rounded;
                stp_sample_query(&d, i, &got);
                stp_query_round(&r.queries[i], fl, &rounded);
                assert_memory_equal(&got, &rounded, sizeof got);
            }
        }
        free(a);
        free(b);
    }
    free(q);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(f16_encode_equals_the_reference),
        cmocka_unit_test(f16_nan_and_overflow_follow_the_spec),
        cmocka_unit_test(f16_decode_equals_the_reference_for_every_half),
        cmocka_unit_test(unorm_encodes_equal_the_reference),
        cmocka_unit_test(compact_queries_widen_as_the_reference),
        cmocka_unit_test(compact_queries_narrow_as_the_reference),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
