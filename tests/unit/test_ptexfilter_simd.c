/* tests/unit/test_ptexfilter_simd.c - the Ptex filters' AVX2 loops (ptexfilter_simd.c) against
 * their definitions: the width-4 kernel weights are bit for bit the portable evaluation for
 * every filter, offset, step and tap count; the window loop gives sum_j kv[j] sum_i ku[i]
 * texel(i, j) to float rounding for every texel type, channel count 1..4 and window shape,
 * and a NaN or Inf just past the window (its loads overrun it) never reaches the result; the
 * fused path of a kernel inside one face gives the general path's results bit for bit, and
 * the 8-query paths (width-4 filters, box) the fused path's.
 * Skipped on a CPU without AVX2 + FMA + F16C (the portable loops run there). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "skip_unless.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "half.h"
#include "ptexfilter_kernel.h"
#include "ptexfilter_lanes.h"
#include "sample.h"
#include "set.h"

static uint32_t rng = 7;
static float rndf(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static void kernel_weights_are_the_portable_ones_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    static const unsigned filters[] = {ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC,
                                       ST_FILTER_PTEX_BSPLINE, ST_FILTER_PTEX_CATMULLROM,
                                       ST_FILTER_PTEX_MITCHELL};
    int cases = 0;
    for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++)
        for (int sharp = 0; sharp < 3; sharp++) {
            pk_params p;
            pk_params_init(&p, filters[fi], 0.5f * (float)sharp, 1);
            for (int r = 0; r < 400; r++) {
                int nu = 1 + r % (PK_MAX / 2), nv = 1 + (r / 7) % (PK_MAX / 2);
                /* offsets and steps as the kernel builder makes them (x1 in [-2.5, 0],
                 * step 1 / uwpix with uwpix in [1, 2), or 1), plus far tails */
                float x1u = -2.5f * rndf(), su = r % 5 ? 1.0f / (1.0f + rndf()) : 1.0f;
                float x1v = r % 11 ? -2.5f * rndf() : -40.0f * rndf(), sv = 1.0f / (1.0f + rndf());
                float wu[PK_MAX], wv[PK_MAX], ru[PK_MAX], rv[PK_MAX];
                pk_kernel_eval(&p, x1u, su, ru, nu);
                pk_kernel_eval(&p, x1v, sv, rv, nv);
                pf_kernel_eval2_avx2(&p, x1u, su, wu, nu, x1v, sv, wv, nv);
                assert_memory_equal(wu, ru, sizeof(float) * (size_t)nu);
                assert_memory_equal(wv, rv, sizeof(float) * (size_t)nv);
                /* one axis (pk_build when the other axis' width is 1/4 face or more) */
                pf_kernel_eval1_avx2(&p, x1v, sv, wu, nv);
                assert_memory_equal(wu, rv, sizeof(float) * (size_t)nv);
                cases++;
            }
        }
    print_message("%d kernels, both axes identical\n", cases);
}

static void put(unsigned dt, uint8_t *p, float x)
{
    switch (dt) {
    case ST_DT_U8: *p = (uint8_t)x; break;
    case ST_DT_U16: { uint16_t v = (uint16_t)x; memcpy(p, &v, 2); break; }
    case ST_DT_HALF: { uint16_t v = st_float_to_half(x); memcpy(p, &v, 2); break; }
    default: memcpy(p, &x, 4); break;
    }
}

static double get(unsigned dt, const uint8_t *p)
{
    switch (dt) {
    case ST_DT_U8: return *p;
    case ST_DT_U16: { uint16_t v; memcpy(&v, p, 2); return v; }
    case ST_DT_HALF: { uint16_t v; memcpy(&v, p, 2); return st_half_to_float(v); }
    default: { float v; memcpy(&v, p, 4); return v; }
    }
}

static void window_sums_match_the_definition_for_every_type_and_channel_count(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    enum { RES = 32, SLACK = 64 };
    static const float maxv[4] = {255.0f, 65535.0f, 1000.0f, 1000.0f};
    int cases = 0;
    for (unsigned dt = ST_DT_U8; dt <= ST_DT_F32; dt++)
        for (unsigned nc = 1; nc <= 4; nc++) {
            size_t es = st_dtype_size(dt), ts = es * nc, rowb = RES * ts;
            uint8_t *face = malloc(RES * rowb + SLACK);
            assert_non_null(face);
            for (int r = 0; r < 300; r++) {
                for (size_t i = 0; i < RES * RES * nc; i++)
                    put(dt, face + i * es, floorf(rndf() * maxv[dt]));
                memset(face + RES * rowb, 0, SLACK);
                pk k;
                memset(&k, 0, sizeof k);
                k.uw = 1 + r % (PK_MAX / 2);
                k.vw = 1 + (r / 3) % 10;
                k.ku0 = r % 3;
                k.kv0 = (r / 5) % 3;
                /* the window ends at the face's last column and row now and then, so its
                 * loads run into the arena's slack */
                int u0 = r % 4 == 0 ? RES - k.uw : (int)(rndf() * (float)(RES - k.uw));
                int v0 = r % 6 == 0 ? RES - k.vw : (int)(rndf() * (float)(RES - k.vw));
                for (int i = 0; i < k.uw; i++)
                    k.kub[k.ku0 + i] = rndf() * 2.0f - 0.5f;
                for (int j = 0; j < k.vw; j++)
                    k.kvb[k.kv0 + j] = rndf() * 2.0f - 0.5f;
                /* a NaN (half, float) or the largest value past the window's right edge */
                if (u0 + k.uw < RES)
                    for (int j = 0; j < k.vw; j++)
                        for (unsigned ch = 0; ch < nc; ch++)
                            put(dt, face + (size_t)(v0 + j) * rowb + (size_t)(u0 + k.uw) * ts +
                                ch * es, dt >= ST_DT_HALF ? NAN : maxv[dt]);
                const uint8_t *base = face + (size_t)v0 * rowb + (size_t)u0 * ts;
                double want[4] = {0, 0, 0, 0}, mag[4] = {0, 0, 0, 0};
                for (int j = 0; j < k.vw; j++)
                    for (int i = 0; i < k.uw; i++)
                        for (unsigned ch = 0; ch < nc; ch++) {
                            double t = get(dt, base + (size_t)j * rowb + (size_t)i * ts + ch * es);
                            double w = (double)k.kub[k.ku0 + i] * k.kvb[k.kv0 + j];
                            want[ch] += w * t;
                            mag[ch] += fabs(w * t);
                        }
                pf_v4 acc = {1, 2, 3, 4};
                pf_v4 got = pf_apply_avx2(base, rowb, &k, dt, nc, acc);
                for (unsigned ch = 0; ch < nc; ch++) {
                    double d = fabs((double)got[ch] - (want[ch] + acc[ch]));
                    assert_true(isfinite(got[ch]));
                    assert_true(d <= 1e-5 * (mag[ch] + 1.0));
                }
                cases++;
            }
            free(face);
        }
    print_message("%d windows within rounding of the definition\n", cases);
}

/* The fused path of a kernel inside one face (pf_fast_select) against the general one
 * (pk_build, pk_strip_zeros, pk_weight, pf_apply_avx2, divided by weight * one value) on a
 * 32 x 16 face with every (ru, rv) resolution: bit for bit equal wherever it takes a query,
 * for every texel type, channel count and filter that has one; a kernel that overhangs the
 * face is declined, or handed over (kout given) as exactly the kernel the general path
 * builds. */
static void fused_inside_face_path_is_the_kernel_path_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    enum { UL = 5, VL = 4, SLACK = 64 };
    static const float maxv[4] = {255.0f, 65535.0f, 1000.0f, 1000.0f};
    int taken = 0, declined = 0, handed = 0;
    for (unsigned dt = ST_DT_U8; dt <= ST_DT_F32; dt++)
        for (unsigned nc = 1; nc <= 4; nc++) {
            size_t es = st_dtype_size(dt), ts = es * nc;
            uint8_t *px[(UL + 1) * (VL + 1)];
            for (int ru = 0; ru <= UL; ru++)
                for (int rv = 0; rv <= VL; rv++) {
                    size_t nt = (size_t)1 << (ru + rv);
                    uint8_t *d = malloc(nt * ts + SLACK);
                    assert_non_null(d);
                    for (size_t i = 0; i < nt * nc; i++) {
                        float y = rndf(); /* half, float: now and then an Inf or a NaN */
                        put(dt, d + i * es, dt >= ST_DT_HALF && y < 0.004f ? INFINITY
                                            : dt >= ST_DT_HALF && y < 0.008f ? NAN
                                                                               : floorf(rndf() * maxv[dt]));
                    }
                    memset(d + nt * ts, 0, SLACK);
                    px[ru * (VL + 1) + rv] = d;
                }
            for (unsigned ft = ST_FILTER_PTEX_POINT; ft <= ST_FILTER_PTEX_MITCHELL; ft++) {
                pf_fast_fn fast = pf_fast_select(dt, nc, ft);
                if (ft < ST_FILTER_PTEX_BOX) {
                    assert_null(fast);
                    continue;
                }
                assert_non_null(fast);
                pk_params p;
                pk_params_init(&p, ft, 0.3f, 1);
                float one = dt == ST_DT_U8 ? 255.0f : dt == ST_DT_U16 ? 65535.0f : 1.0f;
                for (int r = 0; r < 400; r++) {
                    float u = rndf(), v = rndf();
                    /* widths from under a texel to a third of the face, now and then exact
                     * powers of two (the kernels' taps then land on texel edges) */
                    float uw = exp2f(-7.0f + 6.0f * rndf()), vw = exp2f(-7.0f + 6.0f * rndf());
                    if (r % 5 == 0) {
                        uw = exp2f(-(float)(2 + r % 5));
                        vw = uw * 2.0f;
                    }
                    float got[4] = {0, 0, 0, 0};
                    pk k, kh;
                    int took = fast(&p, (const uint8_t *const *)px, UL, VL, u, v, uw, vw, got,
                                    r % 2 ? &kh : NULL);
                    pk_build(&p, &k, u, v, uw, vw, UL, VL);
                    pk_strip_zeros(&k);
                    int inside = k.uw > 0 && k.vw > 0 && k.u >= 0 && k.v >= 0 &&
                                 k.u + k.uw <= (1 << k.ulog2) && k.v + k.vw <= (1 << k.vlog2);
                    if (took == 2) { /* handed over: the general path's kernel, bit for bit */
                        assert_true(r % 2 && !inside && k.uw > 0 && k.vw > 0);
                        assert_int_equal(kh.ulog2, k.ulog2);
                        assert_int_equal(kh.vlog2, k.vlog2);
                        assert_int_equal(kh.u, k.u);
                        assert_int_equal(kh.v, k.v);
                        assert_int_equal(kh.uw, k.uw);
                        assert_int_equal(kh.vw, k.vw);
                        assert_int_equal(kh.rot, 0);
                        assert_memory_equal(pk_ku(&kh), pk_ku(&k), sizeof(float) * (size_t)k.uw);
                        assert_memory_equal(pk_kv(&kh), pk_kv(&k), sizeof(float) * (size_t)k.vw);
                        handed++;
                        continue;
                    }
                    if (!took) {
                        declined++;
                        continue;
                    }
                    assert_true(inside);
                    float total = pk_weight(&k);
                    size_t rowb = ((size_t)1 << k.ulog2) * ts;
                    const uint8_t *base = px[k.ulog2 * (VL + 1) + k.vlog2] +
                                          (size_t)k.v * rowb + (size_t)k.u * ts;
                    pf_v4 acc = pf_apply_avx2(base, rowb, &k, dt, nc, (pf_v4){0, 0, 0, 0});
                    float scale = 1.0f / (total * one), want[4] = {0, 0, 0, 0};
                    for (unsigned ch = 0; ch < nc; ch++)
                        want[ch] = acc[ch] * scale;
                    assert_memory_equal(got, want, sizeof(float) * nc);
                    taken++;
                }
            }
            for (int i = 0; i < (UL + 1) * (VL + 1); i++)
                free(px[i]);
        }
    print_message("%d queries on the fused path, identical; %d kernels over an edge handed "
                  "over, identical; %d declined\n", taken, handed, declined);
    assert_true(taken > declined / 4); /* the fused path is exercised, not always declined */
    assert_true(handed > 100);         /* and so is the hand-over */
}

/* The 8-query tests' faces: NF faces of FL[f] = (u, v) log2 sizes, every resolution of each
 * a table of random texels (integers for u8 / u16; signed fractions for half and float, now
 * and then an Inf or a NaN), SLACK zero bytes past each; px[f][ru * (FL[f][1] + 1) + rv]. */
enum { NF = 3, SLACK = 64 };
static const int FL[NF][2] = {{5, 4}, {3, 6}, {6, 3}};

static void tables_make(unsigned dt, unsigned nc, uint8_t *px[NF][8 * 8])
{
    static const float maxv[4] = {255.0f, 65535.0f, 1000.0f, 1000.0f};
    size_t es = st_dtype_size(dt), ts = es * nc;
    for (int f = 0; f < NF; f++)
        for (int ru = 0; ru <= FL[f][0]; ru++)
            for (int rv = 0; rv <= FL[f][1]; rv++) {
                size_t nt = (size_t)1 << (ru + rv);
                uint8_t *d = malloc(nt * ts + SLACK);
                assert_non_null(d);
                for (size_t i = 0; i < nt * nc; i++) {
                    float x = rndf() * maxv[dt], y = rndf();
                    if (dt >= ST_DT_HALF)
                        x = y < 0.004f ? INFINITY : y < 0.008f ? NAN : x - 500.0f;
                    put(dt, d + i * es, dt <= ST_DT_U16 ? floorf(x) : x);
                }
                memset(d + nt * ts, 0, SLACK);
                px[f][ru * (FL[f][1] + 1) + rv] = d;
            }
}

static void tables_free(uint8_t *px[NF][8 * 8])
{
    for (int f = 0; f < NF; f++)
        for (int i = 0; i < (FL[f][0] + 1) * (FL[f][1] + 1); i++)
            free(px[f][i]);
}

/* A block of 8 lanes, every lane plain; in every fourth block (r % 4 == 0) a random subset
 * offered to the fused path, else all of them. */
static void block_start(pf_klanes *k, int r)
{
    memset(k, 0, sizeof *k);
    k->plain = 0xff;
    k->fast = r % 4 ? 0xffu : (unsigned)(rndf() * 256.0f);
}

/* Lane j of k on a random one of the faces, at a random (u, v); returns the face. */
static int lane_on_face(pf_klanes *k, int j, uint8_t *px[NF][8 * 8])
{
    int f = (int)(rndf() * NF) % NF;
    k->px[j] = (const uint8_t *const *)px[f];
    k->ulog2[j] = FL[f][0];
    k->vlog2[j] = FL[f][1];
    k->u[j] = rndf();
    k->v[j] = rndf();
    return f;
}

/* One block k through an 8-query function (w8: pf_w4x8_select's or pf_box8_select's) and
 * each lane through the per-query fused path (fast) on the same query: a lane the block
 * serves must be one the fused path serves, with the same output bytes; a lane it hands over
 * one the fused path hands over, with the same kernel and its pk_weight (box: the whole
 * kernel's taps from index 0, and a lane left alone one the fused path does not serve or was
 * not offered); a lane left alone keeps its output bytes. Counts the lanes; returns the mask
 * of those served. */
static unsigned check_block(pf_w4x8_fn w8, pf_fast_fn fast, const pk_params *p,
                            const pf_klanes *k, unsigned nc, int box, long *served,
                            long *handed, long *left)
{
    float got[8 * 4], want[4];
    pk kout[8], kh;
    float wout[8];
    unsigned over = 0;
    memset(got, 0x5a, sizeof got);
    unsigned done = w8(p, k, got, kout, wout, &over);
    assert_int_equal(done & over, 0);
    assert_int_equal((done | over) & ~k->fast, 0);
    for (int j = 0; j < 8; j++) {
        memset(want, 0, sizeof want);
        int took = fast(p, k->px[j], k->ulog2[j], k->vlog2[j], k->u[j], k->v[j], k->bu[j],
                        k->bv[j], want, &kh);
        if (done >> j & 1) {
            assert_int_equal(took, 1);
            assert_memory_equal(got + j * nc, want, sizeof(float) * nc);
            (*served)++;
        } else if (over >> j & 1) {
            assert_int_equal(took, 2);
            assert_int_equal(kout[j].ulog2, kh.ulog2);
            assert_int_equal(kout[j].vlog2, kh.vlog2);
            assert_int_equal(kout[j].u, kh.u);
            assert_int_equal(kout[j].v, kh.v);
            assert_int_equal(kout[j].uw, kh.uw);
            assert_int_equal(kout[j].vw, kh.vw);
            if (box) {
                assert_int_equal(kout[j].ku0, 0);
                assert_int_equal(kout[j].kv0, 0);
            }
            assert_int_equal(kout[j].rot, 0);
            size_t nu = box ? (size_t)kh.uw : 4, nv = box ? (size_t)kh.vw : 4;
            assert_memory_equal(pk_ku(&kout[j]), pk_ku(&kh), sizeof(float) * nu);
            assert_memory_equal(pk_kv(&kout[j]), pk_kv(&kh), sizeof(float) * nv);
            float wt = pk_weight(&kh);
            assert_memory_equal(&wout[j], &wt, sizeof wt);
            (*handed)++;
        } else {
            if (box)
                assert_true(!(k->fast >> j & 1) || took == 0);
            for (unsigned ch = 0; ch < nc; ch++) {
                uint32_t b;
                memcpy(&b, &got[j * nc + ch], 4);
                assert_int_equal(b, 0x5a5a5a5au);
            }
            (*left)++;
        }
    }
    return done;
}

/* The width-4 filters' 8-query path (pf_w4x8_select) against the per-query fused path
 * (pf_fast_select) on the same queries, for every texel type, channel count 1..4 and width-4
 * filter: blocks of 8 random queries on three faces of different sizes (so each lane reads
 * its own table), widths under a texel, powers of two (4 x 4 taps, the batch's case; half of
 * those on a texel centre, where the bicubic family's tap 0 is zero and stripped, and
 * Catmull-Rom's taps 0, 1 and 3 too: (0, 0, 1, 0), stripped at both ends) and
 * arbitrary, some lanes not offered. A lane the batch serves must be one the fused path
 * serves, with the same output bytes (every channel); a lane it hands over one the fused
 * path hands over, with the same kernel and its pk_weight; a lane it leaves alone may be
 * anything, its outputs untouched. Texels: integers for u8 / u16, signed fractions for half
 * and float. */
static void batch_of_8_is_the_fused_path_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    long served = 0, handed = 0, left = 0, centred = 0, crom = 0, one_fl = 0;
    for (unsigned dt = ST_DT_U8; dt <= ST_DT_F32; dt++)
        for (unsigned nc = 1; nc <= 4; nc++) {
            uint8_t *px[NF][8 * 8];
            tables_make(dt, nc, px);
            for (unsigned ft = ST_FILTER_PTEX_GAUSSIAN; ft <= ST_FILTER_PTEX_MITCHELL; ft++) {
                pf_w4x8_fn w8 = pf_w4x8_select(dt, nc, ft);
                pf_fast_fn fast = pf_fast_select(dt, nc, ft);
                assert_non_null(w8);
                assert_non_null(fast);
                pk_params p;
                pk_params_init(&p, ft, 0.3f, 1);
                for (int r = 0; r < 300; r++) {
                    pf_klanes k;
                    block_start(&k, r);
                    int centre[8] = {0};
                    for (int j = 0; j < 8; j++) {
                        int f = lane_on_face(&k, j, px);
                        int c = (int)(rndf() * 3.0f);
                        for (int ax = 0; ax < 2; ax++) {
                            int lg = ax ? FL[f][1] : FL[f][0];
                            int m = lg - (int)(rndf() * 4);
                            float w = c == 0   ? rndf() * exp2f(-(float)lg)           /* < a texel */
                                      : c == 1 ? exp2f(-(float)m) /* 2^-n */
                                               : exp2f(-7.0f + 5.0f * rndf());
                            if (ax)
                                k.bv[j] = w;
                            else
                                k.bu[j] = w;
                            /* half of those on a texel centre of the resolution the width
                             * picks (2^m): tap 0 at distance 2, zero but for the gaussian */
                            if (c == 1 && rndf() < 0.5f) {
                                float x = ((float)(int)(rndf() * exp2f((float)m)) + 0.5f) *
                                          exp2f(-(float)m);
                                if (ax)
                                    k.v[j] = x;
                                else
                                    k.u[j] = x;
                                centre[j] = 1;
                            }
                        }
                    }
                    unsigned done = check_block(w8, fast, &p, &k, nc, 0, &served, &handed, &left);
                    for (int j = 0; j < 8; j++)
                        if (centre[j] && (done >> j & 1) && ft != ST_FILTER_PTEX_GAUSSIAN) {
                            centred++;
                            crom += ft == ST_FILTER_PTEX_CATMULLROM;
                            one_fl += nc == 1 && dt >= ST_DT_HALF;
                        }
                }
            }
            tables_free(px);
        }
    print_message("%ld lanes served by the batch, identical; %ld handed over, identical; "
                  "%ld left to the per-query path; %ld served on a texel centre (the "
                  "bicubic family's zero taps stripped; Catmull-Rom's %ld, 1-channel half "
                  "and float %ld)\n", served, handed, left, centred, crom, one_fl);
    assert_true(served > 16 * 4 * 300);  /* every type and channel count is exercised */
    assert_true(handed > 16 * 4 * 20);
    assert_true(centred > 16 * 4 * 30);  /* the strip's lanes too */
    assert_true(crom > 16 * 30);         /* stripped at both ends */
    assert_true(one_fl > 2 * 4 * 30);    /* w4x8_each's 1-channel strip */
}

/* The box filter's 8-query path (pf_box8_select) against the per-query fused path
 * (pf_fast_select's box) on the same queries, for every texel type and channel count 1..4:
 * blocks of 8 random queries on three faces of different sizes (each lane its own table),
 * footprints of a quarter texel, 1, 4 and 16 texels (every 1..3 x 1..3 window shape and
 * every resolution), exact powers of two (weights of 0 at an end: declined), widths of the
 * whole face, some lanes not offered. A lane the batch serves must be one the fused path
 * serves, with the same output bytes; a lane it hands over one the fused path hands over,
 * with the same kernel and its pk_weight; a lane it leaves alone keeps its output bytes.
 * Texels: integers for u8 / u16; signed fractions for half and float, with now and then an
 * Inf or a NaN (a window next to one must not read it: 0 * Inf is NaN). */
static void box_batch_of_8_is_the_fused_path_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    static const float fps[4] = {0.25f, 1.0f, 4.0f, 16.0f};
    long served = 0, handed = 0, left = 0, shapes[9] = {0};
    pk_params p;
    pk_params_init(&p, ST_FILTER_PTEX_BOX, 0.0f, 1);
    for (unsigned dt = ST_DT_U8; dt <= ST_DT_F32; dt++)
        for (unsigned nc = 1; nc <= 4; nc++) {
            uint8_t *px[NF][8 * 8];
            tables_make(dt, nc, px);
            pf_w4x8_fn b8 = pf_box8_select(dt, nc);
            pf_fast_fn fast = pf_fast_select(dt, nc, ST_FILTER_PTEX_BOX);
            assert_non_null(b8);
            assert_non_null(fast);
            for (int r = 0; r < 600; r++) {
                pf_klanes k;
                block_start(&k, r);
                for (int j = 0; j < 8; j++) {
                    int f = lane_on_face(&k, j, px);
                    for (int ax = 0; ax < 2; ax++) {
                        int lg = ax ? FL[f][1] : FL[f][0], c = (int)(rndf() * 4.0f) & 3;
                        float fp = fps[(int)(rndf() * 4.0f) & 3];
                        int m = lg - (int)(rndf() * 5.0f); /* 2^-m: a texel at resolution m */
                        m = m < 0 ? 0 : m;
                        float w = c == 0   ? fp * (0.5f + rndf()) * exp2f(-(float)lg)
                                  : c == 1 ? exp2f(-(float)m)
                                  : c == 2 ? exp2f(-8.0f + 8.5f * rndf())
                                           : fp * exp2f(-(float)lg);
                        float *x = ax ? &k.v[j] : &k.u[j];
                        float sx = exp2f((float)m), y = rndf();
                        if (c == 1 && y < 0.4f) /* a texel centre: 1 tap */
                            *x = (floorf(*x * sx) + 0.5f) / sx;
                        else if (c == 1 && y < 0.6f) /* a texel edge: a weight of 0 */
                            *x = floorf(*x * sx) / sx;
                        if (ax)
                            k.bv[j] = w;
                        else
                            k.bu[j] = w;
                    }
                }
                unsigned done = check_block(b8, fast, &p, &k, nc, 1, &served, &handed, &left);
                for (int j = 0; j < 8; j++)
                    if (done >> j & 1) {
                        pk kb;
                        pk_build(&p, &kb, k.u[j], k.v[j], k.bu[j], k.bv[j], k.ulog2[j],
                                 k.vlog2[j]);
                        assert_true(kb.uw >= 1 && kb.uw <= 3 && kb.vw >= 1 && kb.vw <= 3);
                        shapes[(kb.uw - 1) * 3 + kb.vw - 1]++;
                    }
            }
            tables_free(px);
        }
    print_message("box: %ld lanes served by the batch, identical; %ld handed over, identical; "
                  "%ld left to the per-query path; shapes 1x1 .. 3x3: %ld %ld %ld %ld %ld %ld "
                  "%ld %ld %ld\n", served, handed, left, shapes[0], shapes[1], shapes[2],
                  shapes[3], shapes[4], shapes[5], shapes[6], shapes[7], shapes[8]);
    assert_true(served > 16 * 8 * 200); /* every type and channel count is exercised */
    assert_true(handed > 16 * 500);
    for (int s = 0; s < 9; s++)
        assert_true(shapes[s] > 16 * 5); /* and every window shape */
}

/* pk_strip_zeros' mask path (a kernel as pk_build makes it: weights at index 0, 1..12
 * taps) leaves the window and weights its loops leave, for weights with zeros (+0 and -0) at
 * either end or everywhere, NaN, Inf and denormals, and whatever lies past the taps. */
static void strip_zeros_mask_is_the_loops(void **state)
{
    (void)state;
    static const float vals[] = {0.0f, -0.0f, 0.0f, 1.0f, 0.25f, -0.5f, 1e-40f, INFINITY, NAN};
    int cases = 0;
    for (int r = 0; r < 20000; r++) {
        pk a;
        memset(&a, 0, sizeof a);
        a.u = (int)(rndf() * 20.0f) - 10, a.v = (int)(rndf() * 20.0f) - 10;
        a.ulog2 = 3, a.vlog2 = 4;
        a.uw = 1 + r % 12, a.vw = 1 + (r / 12) % 12;
        for (int i = 0; i < PK_MAX; i++) {
            /* mostly zeros near the ends, garbage (NaN, Inf, ...) past the taps */
            int su = r % 17 == 0 ? 3 : i < 2 || i >= a.uw - 2 ? 5 : 9;
            int sv = r % 13 == 0 ? 3 : i < 2 || i >= a.vw - 2 ? 5 : 9;
            a.kub[i] = i < a.uw ? vals[(int)(rndf() * (float)su)] : vals[(int)(rndf() * 9.0f)];
            a.kvb[i] = i < a.vw ? vals[(int)(rndf() * (float)sv)] : vals[(int)(rndf() * 9.0f)];
        }
        pk b = a;
        pk_strip_zeros(&a);
        pk_strip_zeros_loops(&b);
        assert_int_equal(a.u, b.u);
        assert_int_equal(a.v, b.v);
        assert_int_equal(a.uw, b.uw);
        assert_int_equal(a.vw, b.vw);
        assert_int_equal(a.ku0, b.ku0);
        assert_int_equal(a.kv0, b.kv0);
        cases++;
    }
    print_message("%d kernels stripped alike\n", cases);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(kernel_weights_are_the_portable_ones_bit_for_bit),
        cmocka_unit_test(strip_zeros_mask_is_the_loops),
        cmocka_unit_test(window_sums_match_the_definition_for_every_type_and_channel_count),
        cmocka_unit_test(fused_inside_face_path_is_the_kernel_path_bit_for_bit),
        cmocka_unit_test(batch_of_8_is_the_fused_path_bit_for_bit),
        cmocka_unit_test(box_batch_of_8_is_the_fused_path_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
