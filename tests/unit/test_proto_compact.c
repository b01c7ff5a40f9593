/* tests/unit/test_proto_compact.c - the compact SAMPLE forms of PROTOCOL.md 4.4.1 without
 * sockets: binary16 conversion in both directions (every half, and binary32 values against
 * the compiler's own _Float16 conversion), the u16 fixed-point rule at its ties and ends, the
 * compact request layouts round trip through encoder and decoder, the length rule with each
 * layout, the statuses of malformed compact bodies, f16 replies, and stp_sample_peek_count. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "proto.h"

static uint32_t bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return u;
}

static float from_bits(uint32_t u)
{
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static void every_half_widens_exactly_and_narrows_back(void **state)
{
    (void)state;
    for (uint32_t h = 0; h < 65536; h++) {
        float f = stp_f16_to_f32((uint16_t)h);
        unsigned e = (h >> 10) & 31, m = h & 0x3FF;
        if (e == 31 && m) {                       /* NaN: stays NaN, sign kept */
            assert_true(isnan(f));
            assert_int_equal(stp_f32_to_f16(f) & 0x7E00, 0x7E00);
            continue;
        }
        /* the value is exact: sign x 2^(e-15) x (1 + m/1024), or m x 2^-24 */
        double want = e == 0 ? ldexp(m, -24) : e == 31 ? INFINITY : ldexp(1024 + m, (int)e - 25);
        if (h & 0x8000)
            want = -want;
        assert_true((double)f == want);
        assert_int_equal(signbit(f) != 0, (h & 0x8000) != 0);
        assert_int_equal(stp_f32_to_f16(f), h);
    }
}

#if defined(__FLT16_MAX__)
/* binary32 -> binary16 against the compiler's conversion (round to nearest even), over a
 * stride through every exponent and the values around each rounding boundary. */
static void narrowing_matches_the_compiler_round_to_nearest_even(void **state)
{
    (void)state;
    for (uint64_t x = 0; x <= 0xFFFFFFFFu; x += 4093) {
        float f = from_bits((uint32_t)x);
        if (isnan(f))
            continue;
        _Float16 r = (_Float16)f;
        uint16_t want;
        memcpy(&want, &r, 2);
        assert_int_equal(stp_f32_to_f16(f), want);
    }
    /* every halfway point between neighbouring halves, and one ulp either side */
    for (uint32_t h = 0; h < 0x7C00; h++) {
        double mid = ((double)stp_f16_to_f32((uint16_t)h) + (double)stp_f16_to_f32((uint16_t)(h + 1))) / 2;
        float m = (float)mid;                     /* exact: the midpoint has <= 12 bits */
        for (int d = -1; d <= 1; d++) {
            float f = from_bits(bits(m) + (uint32_t)d);
            if (d < 0 && m == 0.0f)
                continue;
            _Float16 r = (_Float16)f;
            uint16_t want;
            memcpy(&want, &r, 2);
            assert_int_equal(stp_f32_to_f16(f), want);
            assert_int_equal(stp_f32_to_f16(-f), want | 0x8000);
        }
    }
}
#endif

static void narrowing_edges(void **state)
{
    (void)state;
    assert_int_equal(stp_f32_to_f16(65504.0f), 0x7BFF);
    assert_int_equal(stp_f32_to_f16(65519.99f), 0x7BFF);
    assert_int_equal(stp_f32_to_f16(65520.0f), 0x7C00);       /* the tie goes to even: inf */
    assert_int_equal(stp_f32_to_f16(INFINITY), 0x7C00);
    assert_int_equal(stp_f32_to_f16(-INFINITY), 0xFC00);
    assert_int_equal(stp_f32_to_f16(NAN), 0x7E00);
    assert_int_equal(stp_f32_to_f16(0x1p-25f), 0);             /* tie with 0: even */
    assert_int_equal(stp_f32_to_f16(0x1.000002p-25f), 1);
    assert_int_equal(stp_f32_to_f16(0x1.8p-24f), 2);           /* 1.5 ulp: tie, even = 2 */
    assert_int_equal(stp_f32_to_f16(0x1p-14f), 0x0400);        /* smallest normal */
    assert_int_equal(stp_f32_to_f16(0x1.ff8p-15f), 0x03FF);    /* the largest subnormal */
    assert_int_equal(stp_f32_to_f16(0x1.ffcp-15f), 0x0400);    /* tie, odd: up to normal */
    assert_int_equal(stp_f32_to_f16(-0.0f), 0x8000);
    assert_int_equal(stp_f32_to_f16(1.0f + 0x1p-11f), 0x3C00); /* tie: even mantissa */
    assert_int_equal(stp_f32_to_f16(1.0f + 0x1.8p-10f), 0x3C02);
}

static void unit16_rounds_to_nearest_even_and_clamps(void **state)
{
    (void)state;
    for (uint32_t q = 0; q < 65536; q++) {
        float u = stp_unit16_to_f32((uint16_t)q);
        assert_true((double)u == q / 65536.0);                 /* exact */
        assert_int_equal(stp_f32_to_unit16(u), q);
    }
    assert_int_equal(stp_f32_to_unit16(0.5f / 65536.0f), 0);   /* tie: even */
    assert_int_equal(stp_f32_to_unit16(1.5f / 65536.0f), 2);
    assert_int_equal(stp_f32_to_unit16(2.5f / 65536.0f), 2);
    assert_int_equal(stp_f32_to_unit16(0x1.000002p-17f), 1);    /* just over the tie */
    assert_int_equal(stp_f32_to_unit16(1.0f), 65535);
    assert_int_equal(stp_f32_to_unit16(7.0f), 65535);
    assert_int_equal(stp_f32_to_unit16(INFINITY), 65535);
    assert_int_equal(stp_f32_to_unit16(-0.25f), 0);
    assert_int_equal(stp_f32_to_unit16(-INFINITY), 0);
    assert_int_equal(stp_f32_to_unit16(NAN), 0);
    assert_int_equal(stp_f32_to_unit16(65534.5f / 65536.0f), 65534);   /* tie: even */
    assert_int_equal(stp_f32_to_unit16(65534.75f / 65536.0f), 65535);
}

/* Encodes queries with the given flags, decodes them, and checks the decoded queries are
 * stp_query_round of the originals, bit for bit; returns the body length. */
static size_t round_trip(const stp_query *q, uint32_t n, unsigned flags)
{
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.p.name, sizeof rq.p.name, "default");
    rq.p.flags = (uint8_t)flags;
    rq.p.outfmt = STP_OUT_F16;
    rq.count = n;
    rq.queries = q;
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(stp_enc_sample_req(&b, 7, 0, &rq), 0);
    const uint8_t *body = stp_buf_head(&b) + STP_HEADER_SIZE;
    size_t len = stp_buf_avail(&b) - STP_HEADER_SIZE;
    assert_int_equal(len, 2 + 7 + 24 + (size_t)n * stp_query_size(flags));
    assert_int_equal(stp_sample_peek_count(body, len), n);
    stp_sample_req d;
    const char *why = NULL;
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &d, &why), 0);
    assert_int_equal(d.p.flags, flags);
    assert_int_equal(d.count, n);
    stp_query *all = malloc((n ? n : 1) * sizeof *all);
    stp_sample_queries(&d, 0, n, all);
    for (uint32_t i = 0; i < n; i++) {
        stp_query want, got;
        stp_query_round(&q[i], flags, &want);
        stp_sample_query(&d, i, &got);
        assert_memory_equal(&got, &want, sizeof got);
        assert_memory_equal(&all[i], &want, sizeof got);
    }
    free(all);
    stp_buf_free(&b);
    return len;
}

static void compact_layouts_round_trip_to_the_rounded_query(void **state)
{
    (void)state;
    enum { N = 2000 };
    stp_query *q = calloc(N, sizeof *q);
    uint32_t s = 12345;
    for (int i = 0; i < N; i++) {
        s = s * 1664525u + 1013904223u;
        q[i].face = s % 70000;                 /* over 65535 too: FACE16 keeps face & 0xFFFF */
        q[i].u = (float)((s >> 8) % 100000) / 99999.0f;
        s = s * 1664525u + 1013904223u;
        q[i].v = (float)((s >> 8) % 100000) / 99999.0f;
        q[i].dudx = from_bits(0x30000000u + (s % 0x12000000u));
        q[i].dvdx = -q[i].dudx / 3;
        q[i].dudy = (i % 7) ? 0.0f : NAN;
        q[i].dvdy = (i % 11) ? 1e-3f : INFINITY;
    }
    q[0].u = 1.0f;
    q[1].u = -0.5f;
    q[2].v = NAN;
    assert_int_equal(round_trip(q, N, 0), 2 + 7 + 24 + 28u * N);
    assert_int_equal(round_trip(q, N, STP_SF_FACE16), 2 + 7 + 24 + 26u * N);
    assert_int_equal(round_trip(q, N, STP_SF_UV16), 2 + 7 + 24 + 16u * N);
    assert_int_equal(round_trip(q, N, STP_SF_UV16 | STP_SF_FACE16 | STP_SF_COVERAGE),
                     2 + 7 + 24 + 14u * N);
    round_trip(q, 0, STP_SF_UV16);
    stp_query r;
    stp_query_round(&q[0], STP_SF_UV16, &r);
    assert_true(r.u == 65535.0f / 65536.0f);
    stp_query_round(&q[2], STP_SF_UV16, &r);
    assert_true(r.v == 0.0f);
    stp_query_round(&q[0], STP_SF_UV16, &r);
    assert_true(isnan(r.dudy));                /* NaN derivatives stay NaN: NONFINITE */
    free(q);
}

/* A body of SAMPLE params with these flags and count, and `qbytes` query bytes. */
static size_t body_of(uint8_t *out, unsigned flags, uint32_t count, size_t qbytes)
{
    size_t n = 0;
    stp_wr16(out, 3);
    memcpy(out + 2, "abc", 3);
    n = 5;
    memset(out + n, 0, 24);
    out[n + 1] = 1;                            /* bilinear */
    out[n + 5] = (uint8_t)flags;
    stp_wr32(out + n + 20, count);
    n += 24;
    memset(out + n, 0, qbytes);
    return n + qbytes;
}

static void malformed_compact_bodies_get_the_defined_statuses(void **state)
{
    (void)state;
    static uint8_t body[1024];
    stp_sample_req r;
    const char *why = NULL;
    size_t len;
    /* the length rule uses the flags' layout */
    len = body_of(body, STP_SF_UV16 | STP_SF_FACE16, 10, 140);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), 0);
    len = body_of(body, STP_SF_UV16 | STP_SF_FACE16, 10, 160);   /* UV16-only length */
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    len = body_of(body, STP_SF_UV16, 10, 140);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    len = body_of(body, STP_SF_FACE16, 3, 3 * 26);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), 0);
    len = body_of(body, STP_SF_FACE16, 3, 3 * 26 + 1);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    len = body_of(body, STP_SF_UV16, 5, 5 * 16 - 1);             /* cut short */
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    /* over max_batch with the right compact length: TOO_LARGE */
    len = body_of(body, STP_SF_UV16 | STP_SF_FACE16, 10, 140);
    assert_int_equal(stp_dec_sample_req(body, len, 9, &r, &why), STP_S_TOO_LARGE);
    /* bit 4 (SHM) wants 24 bytes of offsets instead of queries; bit 5 (LERP, session 26)
     * goes with any layout; bits 6-7 are still reserved: INVALID, whatever the layout bits
     * say */
    len = body_of(body, STP_SF_SHM | STP_SF_UV16, 2, 32);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    len = body_of(body, STP_SF_LERP | STP_SF_UV16, 2, 32);
    assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), 0);
    assert_true(r.p.flags & STP_SF_LERP);
    for (unsigned bit = 6; bit < 8; bit++) {
        len = body_of(body, (1u << bit) | STP_SF_UV16, 2, 32);
        assert_int_equal(stp_dec_sample_req(body, len, 1u << 20, &r, &why), STP_S_INVALID);
    }
    /* SAMPLE_DIR has one layout: compact flags there are INVALID (length checked first, at
     * 36 bytes a query) */
    len = body_of(body, STP_SF_UV16, 2, 72);
    assert_int_equal(stp_dec_sample_dir_req(body, len, 1u << 20, &r, &why), STP_S_INVALID);
    assert_non_null(strstr(why, "SAMPLE only"));
    len = body_of(body, STP_SF_FACE16, 2, 72);
    assert_int_equal(stp_dec_sample_dir_req(body, len, 1u << 20, &r, &why), STP_S_INVALID);
    len = body_of(body, STP_SF_UV16, 2, 28);
    assert_int_equal(stp_dec_sample_dir_req(body, len, 1u << 20, &r, &why), STP_S_BAD_REQUEST);
    /* peeking never reads past the body */
    assert_int_equal(stp_sample_peek_count(body, 1), 0);
    assert_int_equal(stp_sample_peek_count(body, 5 + 23), 0);
    len = body_of(body, 0, 77, 0);
    assert_int_equal(stp_sample_peek_count(body, len), 77);
}

static void f16_replies_carry_the_rounded_values(void **state)
{
    (void)state;
    const float v[8] = { 0.1f, 1.0f, -2.5f, 70000.0f, NAN, 0x1p-30f, 0.333333f, 65504.0f };
    stp_sample_reply rp;
    memset(&rp, 0, sizeof rp);
    rp.count = 2;
    rp.nchan = 4;
    rp.outfmt = STP_OUT_F16;
    rp.values = v;
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(stp_enc_sample_reply(&b, STP_OP_SAMPLE, 3, &rp), 0);
    const uint8_t *body = stp_buf_head(&b) + STP_HEADER_SIZE;
    size_t len = stp_buf_avail(&b) - STP_HEADER_SIZE;
    assert_int_equal(len, 12 + 8 * 2);
    stp_sample_reply d;
    const char *why = NULL;
    assert_int_equal(stp_dec_sample_reply(body, len, &d, &why), 0);
    float out[8];
    stp_sample_values_f32(&d, out);
    for (int i = 0; i < 8; i++) {
        assert_int_equal(stp_rd16(d.raw_values + 2 * i), stp_f32_to_f16(v[i]));
        if (isnan(v[i]))
            assert_true(isnan(out[i]));
        else
            assert_int_equal(bits(out[i]), bits(stp_f16_to_f32(stp_f32_to_f16(v[i]))));
    }
    assert_true(isinf(out[3]));
    uint16_t raw[8];
    assert_int_equal(stp_sample_values_u16(&d, raw), -1);   /* not a unorm format */
    assert_string_equal(stp_outfmt_name(STP_OUT_F16), "f16");
    assert_int_equal(stp_outfmt_parse("f16"), STP_OUT_F16);
    assert_int_equal(stp_outfmt_size(STP_OUT_F16), 2);
    stp_buf_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_half_widens_exactly_and_narrows_back),
#if defined(__FLT16_MAX__)
        cmocka_unit_test(narrowing_matches_the_compiler_round_to_nearest_even),
#endif
        cmocka_unit_test(narrowing_edges),
        cmocka_unit_test(unit16_rounds_to_nearest_even_and_clamps),
        cmocka_unit_test(compact_layouts_round_trip_to_the_rounded_query),
        cmocka_unit_test(malformed_compact_bodies_get_the_defined_statuses),
        cmocka_unit_test(f16_replies_carry_the_rounded_values),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
