/* tests/unit/test_ptextri_outputs.c - Ptex's point and triangle filters on triangle meshes
 * (ptextri_filter.c) give exactly the outputs of the build before their speed-up (main at
 * eb912b6): the two shared triangle .ptx files as read (f32, 3 channels, with the files'
 * constant and neighbourhood-constant flags) and the first of them remade in u8, u16 and half
 * with 1, 2 and 4 channels and with some faces constant; the point filter and the triangle
 * filter (gaussian, and bicubic with width 1.5 and blur 0.01) in Traverse, Discard and Clamp,
 * the zero rules NaN and Clamp; 3000 queries per group - uv inside the triangle, within two
 * texels of an edge or a corner, or past an edge by up to 10% of the face, footprints from a
 * quarter texel to 32 texels, anisotropic and rotated, a few refused ones. Outputs, coverage
 * and status of each group are hashed (FNV-1a over their bytes) and compared with the hash
 * the old build gave for the same queries (this file built against it; on a mismatch the test
 * prints the line to compare). Bit for bit, so skipped on a CPU without AVX2 + FMA + F16C
 * (libm's expf, which the weights call, picks another variant there). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "../common/skip_unless.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "ptextri.h"
#include "sample.h"
#include "set.h"
#include "../common/testdata.h"
#include "../common/testhash.h"

enum { NQ = 3000 };

static const char *const files[] = {
    "ptx/wdas-ptex-2009/tri/tri.ptx",
    "ptx/wdas-ptex-samples/triangle/triangle.ptx",
};

/* The sets: 0, 1 the files; 2.. the first file remade as {dtype, nchan, constant faces}. */
static const struct { unsigned dt, nc, constant; } remade[] = {
    {ST_DT_U8, 1, 0}, {ST_DT_U16, 2, 0}, {ST_DT_HALF, 4, 1}, {ST_DT_F32, 1, 1},
    {ST_DT_U8, 4, 1}, {ST_DT_F32, 3, 1},
};
#define NSETS (2 + sizeof remade / sizeof remade[0])
#define NGROUP 5 /* point, gaussian, bicubic w 1.5 blur 0.01, gaussian zero rule clamp, box */

/* The old build's hashes, [set][group][mode] (st_mode order: discard, traverse, clamp). */
static const uint64_t want[NSETS][NGROUP][3] = {
#include "ptextri_outputs_hashes.inc"
};

static uint32_t rng;
/* s's faces and adjacency with dtype dt and nc channels, level 0 from s's channel c % 3
 * (every third face constant when asked; constant < 0: instead, f32 only, a texel of every
 * fourth face infinite and one of every other fourth NaN, which reach their 1 x 1 levels),
 * its levels made as the reader makes them. */
static st_set *remake(const st_set *s, unsigned dt, unsigned nc, int constant)
{
    uint32_t n = s->info.nfaces;
    st_face_desc *fd = calloc(n, sizeof *fd);
    assert_non_null(fd);
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        fd[f].w = F->w;
        fd[f].h = F->h;
        fd[f].flags = constant > 0 && f % 3 == 1 ? ST_FACE_CONSTANT : 0;
        for (int e = 0; e < 4; e++) {
            fd[f].adjface[e] = F->adjface[e];
            fd[f].adjedge[e] = F->adjface[e] < 0 ? 0 : (int8_t)F->adjedge[e];
        }
    }
    st_set_info info = {.nfaces = n, .nchan = (uint8_t)nc, .dtype = (uint8_t)dt,
                        .alpha_chan = -1, .kind = ST_KIND_PERFACE,
                        .meshtype = ST_MESH_TRIANGLE};
    st_set *d;
    st_error e = {0};
    int rc = st_set_create(&info, fd, 0, &d, &e);
    if (rc)
        print_message("%s\n", e.msg);
    assert_int_equal(rc, 0);
    free(fd);
    for (uint32_t f = 0; f < n; f++) {
        const uint8_t *sp = st_face_level(s, f, 0);
        uint8_t *dp = st_face_level(d, f, 0);
        size_t nt = (d->faces[f].flags & ST_FACE_CONSTANT) ? 1
                    : (s->faces[f].flags & ST_FACE_CONSTANT) ? 0
                    : (size_t)d->faces[f].w * d->faces[f].h;
        if (!nt) { /* constant in the file: every texel its value */
            for (size_t i = 0; i < (size_t)d->faces[f].w * d->faces[f].h; i++)
                for (unsigned c = 0; c < nc; c++)
                    st_channel_put(dt, dp + i * st_texel_size(d), c,
                                   st_channel_get(s->info.dtype, sp, c % 3));
            continue;
        }
        for (size_t i = 0; i < nt; i++)
            for (unsigned c = 0; c < nc; c++)
                st_channel_put(dt, dp + i * st_texel_size(d), c,
                               st_channel_get(s->info.dtype, sp + i * st_texel_size(s), c % 3));
        if (constant < 0 && f % 2 == 0 && dt == ST_DT_F32)
            st_channel_put(dt, dp + (f % 7) * st_texel_size(d), f % nc,
                           f % 4 == 0 ? INFINITY : NAN);
    }
    st_set_build_mips(d, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(d, &e), 0);
    return d;
}

/* The queries of one set: faces uniform; uv inside the triangle (40%), within two texels of
 * an edge or a corner (35%), past the triangle by up to 10% (20%), refused (5%: a bad face,
 * a NaN, a huge derivative); footprints 2^[-2, 5] texels, anisotropic, a third rotated. */
static void make_queries(const st_set *s, st_query *q, uint32_t seed)
{
    rng = seed;
    for (int i = 0; i < NQ; i++) {
        uint32_t f = (uint32_t)(st_test_rndf(&rng) * (float)s->info.nfaces) % s->info.nfaces;
        float R = (float)s->faces[f].w;
        float u = st_test_rndf(&rng), v = st_test_rndf(&rng), r = st_test_rndf(&rng);
        if (u + v > 1.0f) {
            u = 1.0f - u;
            v = 1.0f - v;
        }
        if (r < 0.35f) {
            float d = 2.0f * st_test_rndf(&rng) / R;
            int side = (int)(st_test_rndf(&rng) * 6.0f);
            if (side == 0 || side == 3)
                v = d;
            if (side == 1 || side == 3)
                u = d;
            if (side == 2 || side == 4) {
                float t = 0.5f * (u + v - 1.0f + d);
                u -= t;
                v -= t;
            }
            if (side == 5)
                u = 1.0f - d, v = 0.5f * d;
        } else if (r < 0.55f) {
            u = -0.1f + 1.2f * u;
            v = -0.1f + 1.2f * v;
        }
        float fpu = exp2f(-2.0f + 7.0f * st_test_rndf(&rng)), fpv = fpu * exp2f(-1.0f + 2.0f * st_test_rndf(&rng));
        float rot = st_test_rndf(&rng) < 0.33f ? st_test_rndf(&rng) * 6.2831853f : 0.0f;
        float c = cosf(rot), sn = sinf(rot);
        q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = c * fpu / R, .dvdx = sn * fpv / R,
                          .dudy = -sn * fpu / R, .dvdy = c * fpv / R};
        if (r > 0.95f) {
            int k = (int)(st_test_rndf(&rng) * 3.0f);
            if (k == 0)
                q[i].face = s->info.nfaces + 3;
            else if (k == 1)
                q[i].v = NAN;
            else
                q[i].dvdy = 2.0e4f;
        }
    }
}

/* Group g's options in mode `mode`: point, gaussian, bicubic (width 1.5, blur 0.01), gaussian
 * with the clamp zero rule, box. */
static st_sample_opts group_opts(int g, int mode)
{
    static const uint8_t filt[NGROUP] = {ST_FILTER_PTEX_POINT, ST_FILTER_PTEX_GAUSSIAN,
                                         ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_GAUSSIAN,
                                         ST_FILTER_PTEX_BOX};
    st_sample_opts o = {.filter = filt[g], .mode = (uint8_t)mode, .sharpness = 0.3f,
                        .width = g == 2 ? 1.5f : 0.0f, .blur = g == 2 ? 0.01f : 0.0f,
                        .zero_rule = g == 3 ? ST_ZERO_CLAMP : ST_ZERO_NAN};
    return o;
}

/* The si-th set of the tests: the two shared files, then file 0 remade as remade[si - 2]
 * says. *file0 keeps file 0 (the caller frees it last), *own the set to free after it is
 * sampled (NULL for file 0); NULL: skipped (its file is not in the shared data). */
static const st_set *nth_set(size_t si, st_set **file0, st_set **own)
{
    *own = NULL;
    if (si >= 2) {
        if (!*file0)
            return NULL;
        *own = remake(*file0, remade[si - 2].dt, remade[si - 2].nc, remade[si - 2].constant);
        return *own;
    }
    char path[1024];
    st_error e = {0};
    st_set *s;
    if (st_test_data_path(path, sizeof path, files[si]))
        return NULL;
    assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
    if (si == 0)
        *file0 = s;
    else
        *own = s;
    return s;
}

static void triangle_filters_give_the_old_builds_outputs_bit_for_bit(void **state)
{
    (void)state;
    ST_SKIP_WITHOUT_AVX2();
    char path[1024];
    if (st_test_data_path(path, sizeof path, files[0]))
        skip();
    st_query *q = malloc(sizeof *q * NQ);
    float *out = malloc(sizeof(float) * 4 * NQ), *cov = malloc(sizeof(float) * NQ);
    uint8_t *stat = malloc(NQ);
    assert_true(q && out && cov && stat);
    st_set *file0 = NULL;
    int bad = 0, checked = 0;
    for (size_t si = 0; si < NSETS; si++) {
        st_set *s;
        const st_set *ss = nth_set(si, &file0, &s);
        if (!ss)
            continue;
        assert_int_equal(ss->info.meshtype, ST_MESH_TRIANGLE);
        make_queries(ss, q, 2000u + (uint32_t)si);
        for (int g = 0; g < NGROUP; g++)
            for (int mode = 0; mode < 3; mode++) {
                st_sample_opts o = group_opts(g, mode);
                memset(out, 0, sizeof(float) * 4 * NQ);
                /* the per-tap weights (Clamp's and Discard's coverage are stepped by
                 * recurrence in st_ptexfilter_batch: compared below) */
                int r = st_ptextri_batch_pertap(ss, &o, q, NQ, out, cov, stat);
                assert_true(r >= 0);
                uint64_t h = 0xcbf29ce484222325ull;
                h = st_test_fnv(h, out, sizeof(float) * ss->info.nchan * NQ);
                h = st_test_fnv(h, cov, sizeof(float) * NQ);
                h = st_test_fnv(h, stat, NQ);
                checked++;
                if (h != want[si][g][mode]) {
                    bad++;
                    print_message("differs: set %zu group %d mode %d: [%zu][%d][%d] = "
                                  "0x%016llxull\n", si, g, mode, si, g, mode,
                                  (unsigned long long)h);
                }
            }
        st_set_free(s);
    }
    st_set_free(file0);
    free(q);
    free(out);
    free(cov);
    free(stat);
    print_message("%d (set, filter, mode) groups of %d queries, %d differ from the old "
                  "build\n", checked, NQ, bad);
    assert_int_equal(bad, 0);
}

/* The buffers of two runs of the same NQ queries compared: outputs (up to 4 channels),
 * coverage and statuses of each. pair_begin skips the test when the data folder lacks the
 * first file and fails it when memory is short. */
typedef struct {
    st_query *q;
    float *o1, *c1, *o2, *c2;
    uint8_t *s1, *s2;
} pair_bufs;

static pair_bufs pair_begin(void)
{
    char path[1024];
    if (st_test_data_path(path, sizeof path, files[0]))
        skip();
    pair_bufs b = {.q = malloc(sizeof *b.q * NQ),
                   .o1 = malloc(sizeof(float) * 4 * NQ), .c1 = malloc(sizeof(float) * NQ),
                   .o2 = malloc(sizeof(float) * 4 * NQ), .c2 = malloc(sizeof(float) * NQ),
                   .s1 = malloc(NQ), .s2 = malloc(NQ)};
    assert_true(b.q && b.o1 && b.c1 && b.o2 && b.c2 && b.s1 && b.s2);
    return b;
}

static void pair_free(pair_bufs *b)
{
    free(b->q);
    free(b->o1);
    free(b->c1);
    free(b->o2);
    free(b->c2);
    free(b->s1);
    free(b->s2);
}

/* st_ptextri_batch against st_ptextri_batch_pertap (every weight one libm expf, the old
 * build's outputs: the hashes above) on the same sets and queries. The read sweeps (Traverse,
 * Discard, Clamp's kernels inside the face) take the weights by the shared polynomial exp
 * (pk_exp2_4, four taps at a time; at levels of 8 x 8 texels or more every kept tap, each
 * row summed in a lane of its own and the lanes added after: rows_apply_t, which moves the
 * sums' order as well - measured 3.9e-7 at most, session 29; Clamp's kernels that overhang
 * the face at those levels the same way, each tap's texel by fold_tap's rule a lane since
 * session 33: 5.4e-7 at most, a wrong texel for folded taps moves values far more than
 * 1e-5), Clamp's folded sweeps at smaller levels and
 * Discard's whole-kernel weight
 * (the coverage's denominator) step them by recurrence (pt_rec): the same taps, so the same
 * statuses, and each weight within about 1e-6 relatively of the expf's (the polynomial's
 * 2e-7, the roundings of the exponent's argument in either); a value, a weighted mean of
 * texels in [0, 1], then moves by at most about twice that: Traverse's and Discard's values
 * within 4e-6, Clamp's values and the coverage within 1e-5 (the Ptex reference lines are
 * checked to 1e-4; measured: below 1e-6). A wrong weight (a coefficient of the polynomial,
 * a weight given to the wrong tap) moves some values far more. */
static void fast_weights_match_the_per_tap_expf(void **state)
{
    (void)state;
    pair_bufs b = pair_begin();
    st_query *q = b.q;
    float *o1 = b.o1, *c1 = b.c1, *o2 = b.o2, *c2 = b.c2;
    uint8_t *s1 = b.s1, *s2 = b.s2;
    st_set *file0 = NULL;
    double max_out[3] = {0.0, 0.0, 0.0}, max_cov = 0.0;
    int differ[3] = {0, 0, 0};
    for (size_t si = 0; si < NSETS; si++) {
        st_set *s;
        const st_set *ss = nth_set(si, &file0, &s);
        if (!ss)
            continue;
        unsigned nc = ss->info.nchan;
        make_queries(ss, q, 4000u + (uint32_t)si);
        for (int g = 1; g < NGROUP; g++)
            for (int mode = 0; mode < 3; mode++) {
                st_sample_opts o = group_opts(g, mode);
                assert_int_equal(st_ptextri_batch(ss, &o, q, NQ, o1, c1, s1),
                                 st_ptextri_batch_pertap(ss, &o, q, NQ, o2, c2, s2));
                assert_memory_equal(s1, s2, NQ);
                differ[mode] += memcmp(o1, o2, sizeof(float) * nc * NQ) != 0;
                for (size_t i = 0; i < NQ; i++) {
                    if (s1[i] != ST_Q_OK)
                        continue;
                    for (unsigned ch = 0; ch < nc; ch++) {
                        double d = fabs((double)o1[i * nc + ch] - (double)o2[i * nc + ch]);
                        assert_false(isnan(d));
                        if (d > max_out[mode])
                            max_out[mode] = d;
                    }
                    double dc = fabs((double)c1[i] - (double)c2[i]);
                    assert_false(isnan(dc));
                    if (dc > max_cov)
                        max_cov = dc;
                }
            }
        st_set_free(s);
    }
    st_set_free(file0);
    pair_free(&b);
    print_message("polynomial / recurrence weights vs per-tap expf: max |value difference| "
                  "Discard %.3g, Traverse %.3g, Clamp %.3g; max |coverage difference| %.3g; "
                  "groups that differ at all: %d, %d, %d\n", max_out[ST_MODE_DISCARD],
                  max_out[ST_MODE_TRAVERSE], max_out[ST_MODE_CLAMP], max_cov,
                  differ[ST_MODE_DISCARD], differ[ST_MODE_TRAVERSE], differ[ST_MODE_CLAMP]);
    /* the fast weights ran in every mode */
    assert_true(differ[0] > 0 && differ[1] > 0 && differ[2] > 0);
    assert_true(max_out[ST_MODE_TRAVERSE] <= 4e-6);
    assert_true(max_out[ST_MODE_DISCARD] <= 4e-6);
    assert_true(max_out[ST_MODE_CLAMP] <= 1e-5);
    assert_true(max_cov <= 1e-5);
}

/* The shared polynomial exp (ptexfilter_kernel.h, pk_exp2_4: the quad filters' gaussian
 * weights and the triangle filter's read sweeps) against exp2 in double, lane by lane over
 * y in [-126, 0.5) (the quad kernel's range and the triangle weights' [-8.84, 0], densely):
 * relative error below 3e-7 (its polynomial's about 2e-7), each lane its own. */
static void the_shared_exp2_is_within_3e_7_of_exp2(void **state)
{
    (void)state;
    double worst = 0.0;
    long n = 0;
    for (int part = 0; part < 2; part++) {
        float lo = part ? -9.0f : -126.0f, hi = part ? 0.5f : -9.0f;
        int steps = part ? 400000 : 100000;
        for (int i = 0; i < steps; i += 4) {
            pk_v4f y;
            for (int l = 0; l < 4; l++)
                y[l] = lo + (hi - lo) * (float)(i + l) / (float)steps;
            pk_v4f r = pk_exp2_4(y);
            for (int l = 0; l < 4; l++) {
                double want = exp2((double)y[l]);
                double e = fabs((double)r[l] - want) / want;
                if (e > worst)
                    worst = e;
                n++;
            }
        }
    }
    print_message("pk_exp2_4: %ld points, max relative error %.3g\n", n, worst);
    assert_true(worst < 3e-7);
}

/* The lean recurrence sweeps st_ptextri_batch runs (Clamp's fold sweeps, Discard's
 * whole-kernel weight) and their baseline instances (st_ptextri_batch_baseline: the same
 * sweeps without AVX2) against the general ones (st_ptextri_batch_general: row_clamp over
 * row_same, row_step and row_band_t): every output, coverage and status the same bits, on
 * every set and group above (with and without the coverage array), on queries like
 * bench_ptex's (uv uniform over the square, so half past the diagonal edge, isotropic
 * footprints of 2^-3 to 2^6 texels) and on queries whose footprints repeat or change one
 * derivative at a time. The lean builds' own shortcuts are checked the same way: the kernel's
 * shape taken from the query before (same footprint and face size) and the read sweeps of
 * pieces at resolution 0, 1 and 2 (piece_r1, piece_r2, piece_r4 and its AVX2 instance: the
 * large, middling and small footprints on triangle.ptx's 4-texel faces) and at 3 or more
 * (piece_rn and its AVX2 instance, against the general build's sweep2_t: both run the rows a
 * lane, rows_apply_t, on the 32-texel faces). Clamp's overhanging kernels at levels of 8 x 8
 * or more run the rows a lane with the fold a lane in both builds (rows_apply_t with FOLD),
 * so here they are compared lane code with lane code; their texels are checked against
 * fold_tap in test_ptextri.c (clamp_fold_lanes_read_the_folded_texels) and their values
 * against the per-tap build above (fast_weights_match_the_per_tap_expf).
 * Checks that the recurrence ran: Clamp's values differ from the per-tap expf's in some
 * groups. */
static void lean_sweeps_match_the_general_sweeps_bit_for_bit(void **state)
{
    (void)state;
    pair_bufs b = pair_begin();
    st_query *q = b.q;
    float *o1 = b.o1, *c1 = b.c1, *o2 = b.o2, *c2 = b.c2;
    uint8_t *s1 = b.s1, *s2 = b.s2;
    st_set *file0 = NULL;
    int groups = 0, differ = 0, base_differ = 0, recurrence_ran = 0;
    for (size_t si = 0; si <= NSETS; si++) {
        st_set *s;
        /* one more set: file 0 in f32 with texels not finite (piece_r1 leaves those faces'
         * pieces to the sweeps, which add such a texel times 0) */
        const st_set *ss = si < NSETS ? nth_set(si, &file0, &s)
                           : (s = file0 ? remake(file0, ST_DT_F32, 3, -1) : NULL);
        if (!ss)
            continue;
        unsigned nc = ss->info.nchan;
        for (int kind = 0; kind < 3; kind++) {
            make_queries(ss, q, 6000u + (uint32_t)si);
            if (kind == 2) { /* footprints that repeat (st_ptextri_batch reuses the kernel's
                              * shape of the query before when its footprint and face size
                              * are the same): a query keeps the last one's footprint (3 in
                              * 4) or changes one of its four derivatives, on faces at
                              * random; footprints in uv (not texels), a quarter texel to 64
                              * texels of a 32-texel face */
                rng = 8000u + (uint32_t)si;
                float d[4] = {0.01f, 0.0f, 0.0f, 0.01f};
                for (int i = 0; i < NQ; i++) {
                    if (st_test_rndf(&rng) >= 0.75f) {
                        int j = (int)(st_test_rndf(&rng) * 4.0f) & 3;
                        d[j] = (j == 1 || j == 2 ? 0.5f : 1.0f) *
                               exp2f(-7.0f + 8.0f * st_test_rndf(&rng));
                    }
                    uint32_t f = (uint32_t)(st_test_rndf(&rng) * (float)ss->info.nfaces) %
                                 ss->info.nfaces;
                    float u = st_test_rndf(&rng), v = st_test_rndf(&rng);
                    q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = d[0], .dvdx = d[1],
                                      .dudy = d[2], .dvdy = d[3]};
                }
            }
            if (kind == 1) { /* bench_ptex's random queries */
                rng = 7000u + (uint32_t)si;
                for (int i = 0; i < NQ; i++) {
                    uint32_t f = (uint32_t)(st_test_rndf(&rng) * (float)ss->info.nfaces) %
                                 ss->info.nfaces;
                    float R = (float)ss->faces[f].w, u = st_test_rndf(&rng);
                    float v = st_test_rndf(&rng);
                    float fp = exp2f(-3.0f + 9.0f * st_test_rndf(&rng));
                    q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = fp / R, .dvdy = fp / R};
                }
            }
            for (int g = 1; g < NGROUP; g++)
                for (int mode = 0; mode < 3; mode++)
                    for (int wc = 0; wc < 2; wc++) {
                        st_sample_opts o = group_opts(g, mode);
                        memset(c2, 0, sizeof(float) * NQ);
                        int r2 = st_ptextri_batch_general(ss, &o, q, NQ, o2, wc ? c2 : NULL, s2);
                        groups++;
                        /* st_ptextri_batch (its AVX2 instances on a CPU with AVX2), then the
                         * baseline instances (what a CPU without AVX2 runs) */
                        for (int base = 0; base < 2; base++) {
                            memset(c1, 0, sizeof(float) * NQ);
                            int r1 = (base ? st_ptextri_batch_baseline : st_ptextri_batch)(
                                ss, &o, q, NQ, o1, wc ? c1 : NULL, s1);
                            int d = r1 != r2 || memcmp(s1, s2, NQ) != 0 ||
                                    memcmp(o1, o2, sizeof(float) * nc * NQ) != 0 ||
                                    memcmp(c1, c2, sizeof(float) * NQ) != 0;
                            if (d)
                                print_message("%s differs: set %zu kind %d group %d mode %d "
                                              "coverage %d\n", base ? "baseline" : "lean", si,
                                              kind, g, mode, wc);
                            *(base ? &base_differ : &differ) += d;
                        }
                        if (mode == ST_MODE_CLAMP && !wc) {
                            st_ptextri_batch_pertap(ss, &o, q, NQ, o2, NULL, s2);
                            recurrence_ran += memcmp(o1, o2, sizeof(float) * nc * NQ) != 0;
                        }
                    }
        }
        st_set_free(s);
    }
    st_set_free(file0);
    pair_free(&b);
    print_message("lean vs general recurrence sweeps: %d of %d groups of %d queries differ "
                  "(baseline instances: %d); %d Clamp groups differ from the per-tap expf\n",
                  differ, groups, NQ, base_differ, recurrence_ran);
    assert_int_equal(differ, 0);
    assert_int_equal(base_differ, 0);
    assert_true(recurrence_ran > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(triangle_filters_give_the_old_builds_outputs_bit_for_bit),
        cmocka_unit_test(fast_weights_match_the_per_tap_expf),
        cmocka_unit_test(the_shared_exp2_is_within_3e_7_of_exp2),
        cmocka_unit_test(lean_sweeps_match_the_general_sweeps_bit_for_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
