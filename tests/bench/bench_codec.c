/* tests/bench/bench_codec.c - cost of the per-value codecs on the SAMPLE hot path
 * (protocol/codec_simd.h), in ns per value (per query for the query widening), the portable
 * reference loops against the AVX2 + F16C forms the daemon runs when the CPU has them:
 * f16 reply encode, f16 reply decode (client), unorm8 and unorm16 reply encode, and the
 * compact query widening (UV16 + FACE16 and UV16 layouts, PROTOCOL.md 4.4.1) to the f32
 * layout, and the client's narrowing of stp_query to those layouts. A batch of 4096 RGBA values (16384) or 4096 queries, in cache, 64 passes per timing.
 *
 * Usage: bench_codec [--json PATH] [--reps N]   (medians of N repetitions, default 7)
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/benchstat.h"
#include "codec_simd.h"

#define NV    16384     /* values: 4096 RGBA */
#define NQ    4096      /* queries */
#define PASS  64

typedef struct row {
    const char *name, *key;
    double      ref_ns, fast_ns;
} row;

static float    vals[NV];
static uint8_t  out[NV * 4];
static float    back[NV];
static uint8_t  halves[NV * 2];
static uint8_t  raw14[NQ * 14], raw16[NQ * 16];
static uint8_t  wide[NQ * STP_QUERY_SIZE];
static stp_query qry[NQ];

typedef void (*run_fn)(int fast);

static void f16_enc(int fast)
{
    (fast ? stp_f16_encode_avx2 : stp_f16_encode_scalar)(vals, NV, out);
}
static void f16_dec(int fast)
{
    (fast ? stp_f16_decode_avx2 : stp_f16_decode_scalar)(halves, NV, back);
}
static void un8_enc(int fast)
{
    (fast ? stp_unorm8_encode_avx2 : stp_unorm8_encode_scalar)(vals, NV, out);
}
static void un16_enc(int fast)
{
    (fast ? stp_unorm16_encode_avx2 : stp_unorm16_encode_scalar)(vals, NV, out);
}
static stp_sample_req rq;
static void widen(int fast)
{
    (fast ? stp_sample_queries_f32_avx2 : stp_sample_queries_f32_scalar)(&rq, 0, NQ, wide);
}
static int narrow_face16;
static void narrow(int fast)
{
    (fast ? stp_put_queries_uv16_avx2 : stp_put_queries_uv16_scalar)(qry, NQ, narrow_face16, out);
}

/* median ns per item over reps timings of PASS passes */
static double time_ns(run_fn f, int fast, size_t items, int reps, double *t)
{
    f(fast);   /* warm */
    for (int r = 0; r < reps; r++) {
        double t0 = st_bench_clock(CLOCK_THREAD_CPUTIME_ID);
        for (int k = 0; k < PASS; k++)
            f(fast);
        t[r] = (st_bench_clock(CLOCK_THREAD_CPUTIME_ID) - t0) / ((double)PASS * items) * 1e9;
    }
    return st_bench_median(t, reps);
}

int main(int argc, char **argv)
{
    const char *json;
    int reps;
    if (st_bench_args(argc, argv, &json, &reps, 7) != 0)
        return 2;
    double *t = calloc((size_t)reps, sizeof *t);
    uint32_t x = 12345;
    for (int i = 0; i < NV; i++) {
        x = x * 1664525u + 1013904223u;
        vals[i] = (float)(x >> 8) * 0x1p-24f;          /* sampled colours, in [0, 1) */
    }
    stp_f16_encode_scalar(vals, NV, halves);
    /* faces, u, v anything; derivatives finite halves about 2^-8, as a renderer sends */
    for (int i = 0; i < NQ; i++) {
        uint16_t f[7];
        for (int k = 0; k < 7; k++) {
            x = x * 1664525u + 1013904223u;
            f[k] = k < 3 ? (uint16_t)(x >> 16) : (uint16_t)(0x1C00 + (x >> 24));
        }
        for (int k = 0; k < 7; k++) {
            stp_wr16(raw14 + 14 * i + 2 * k, f[k]);
            stp_wr16(raw16 + 16 * i + 2 + 2 * k, f[k]);
        }
        stp_wr16(raw16 + 16 * i, 0);
    }
    memset(&rq, 0, sizeof rq);
    rq.count = NQ;
    /* what a renderer sends: u, v in [0, 1), derivatives about 2^-8 */
    for (int i = 0; i < NQ; i++) {
        float d[6];
        for (int k = 0; k < 6; k++) {
            x = x * 1664525u + 1013904223u;
            d[k] = k < 2 ? (float)(x >> 8) * 0x1p-24f : (float)(x >> 8) * 0x1p-31f;
        }
        qry[i] = (stp_query){ x % 5000, d[0], d[1], d[2], d[3], d[4], d[5] };
    }

    int have = stp_codec_have_avx2();
    row rows[] = {
        { "f16 reply encode (ns/value)", "f16_encode", 0, 0 },
        { "f16 reply decode, client (ns/value)", "f16_decode", 0, 0 },
        { "unorm8 reply encode (ns/value)", "unorm8_encode", 0, 0 },
        { "unorm16 reply encode (ns/value)", "unorm16_encode", 0, 0 },
        { "query widen, UV16+FACE16 14 B (ns/query)", "widen_uv16_face16", 0, 0 },
        { "query widen, UV16 16 B (ns/query)", "widen_uv16", 0, 0 },
        { "query narrow, client, UV16+FACE16 (ns/query)", "narrow_uv16_face16", 0, 0 },
        { "query narrow, client, UV16 (ns/query)", "narrow_uv16", 0, 0 },
    };
    run_fn fns[] = { f16_enc, f16_dec, un8_enc, un16_enc, widen, widen, narrow, narrow };
    size_t items[] = { NV, NV, NV, NV, NQ, NQ, NQ, NQ };
    for (size_t i = 0; i < sizeof rows / sizeof *rows; i++) {
        rq.p.flags = i == 4 ? STP_SF_UV16 | STP_SF_FACE16 : STP_SF_UV16;
        rq.raw = i == 4 ? raw14 : raw16;
        narrow_face16 = i == 6;
        rows[i].ref_ns = time_ns(fns[i], 0, items[i], reps, t);
        rows[i].fast_ns = have ? time_ns(fns[i], 1, items[i], reps, t) : 0;
    }
    printf("%-46s %10s %10s %8s\n", "codec", "scalar", "avx2", "speedup");
    for (size_t i = 0; i < sizeof rows / sizeof *rows; i++)
        printf("%-46s %10.3f %10.3f %7.1fx\n", rows[i].name, rows[i].ref_ns, rows[i].fast_ns,
               rows[i].fast_ns > 0 ? rows[i].ref_ns / rows[i].fast_ns : 0.0);
    printf("(thread CPU time, medians of %d repetitions of %d passes; avx2 %s)\n", reps, PASS,
           have ? "available" : "not available on this CPU: 0");
    if (json) {
        FILE *fp = fopen(json, "w");
        if (!fp) {
            perror(json);
            return 1;
        }
        fprintf(fp, "{\n  \"bench\": \"bench_codec\",\n  \"reps\": %d,\n  \"avx2\": %d", reps, have);
        for (size_t i = 0; i < sizeof rows / sizeof *rows; i++)
            fprintf(fp, ",\n  \"%s_scalar_ns\": %.4f,\n  \"%s_avx2_ns\": %.4f", rows[i].key,
                    rows[i].ref_ns, rows[i].key, rows[i].fast_ns);
        fprintf(fp, "\n}\n");
        fclose(fp);
    }
    free(t);
    return 0;
}
