/* tests/unit/test_ptexfilter_lerp.c - session 26 (opt26): Ptex's lerp filter option
 * (st_sample_opts.lerp; PtexFilter::Options::lerp, PtexWidth4Filter::buildKernelAxis): the
 * gaussian and bicubic-family kernels blended toward the next lower resolution.
 *
 * - pk_width4_axis_lerp against a model of Ptex's rule written here from its description
 *   (docs/ptex.md section 6): the window exactly, the weights within 2e-6 (the model's kernel
 *   functions in double), every width-4 filter and sharpness, widths from a texel to a face,
 *   faces of 1 to 256 texels;
 * - lerp on at footprints on a level (widths 1/2^r), and lerp on with point, bilinear and box
 *   at any footprint, give lerp off's outputs, coverage and status bit for bit, every mode
 *   (lerp on takes the general path, lerp off the fast paths: this also checks that the
 *   fast paths still give the general path's bits);
 * - lerp on at footprints between levels: the outputs of the Ptex library (2.4.3, ptexq
 *   --lerp) on lines of the shared reference files, pinned in ptexfilter_lerp_pinned.inc,
 *   within the reference tolerance; and most of them further than that from lerp off (so the
 *   check fails without lerp). Skipped without SEAMTEX_DATA. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/faces.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "ptexfilter_kernel.h"
#include "sample.h"
#include "set.h"
#include "testdata.h"

static uint32_t rng = 2026;
static float rnd01(void) /* [0, 1) */
{
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static const unsigned w4filters[] = {ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC,
                                     ST_FILTER_PTEX_BSPLINE, ST_FILTER_PTEX_CATMULLROM,
                                     ST_FILTER_PTEX_MITCHELL};

/* ---- the model -------------------------------------------------------------------------- */

static double model_k(unsigned ft, double sharp, double x)
{
    if (ft == ST_FILTER_PTEX_GAUSSIAN)
        return exp(-2.0 * x * x);
    double s = ft == ST_FILTER_PTEX_BSPLINE ? 0.0 : ft == ST_FILTER_PTEX_CATMULLROM ? 1.0
             : ft == ST_FILTER_PTEX_MITCHELL ? 2.0 / 3.0 : sharp;
    double B = 1.0 - s, C = (1.0 - B) / 2.0; /* Mitchell-Netravali, C = (1 - B) / 2 */
    x = fabs(x);
    if (x < 1.0)
        return ((12 - 9 * B - 6 * C) * x * x * x + (-18 + 12 * B + 6 * C) * x * x + (6 - 2 * B)) /
               6.0;
    if (x < 2.0)
        return ((-B - 6 * C) * x * x * x + (6 * B + 30 * C) * x * x + (-12 * B - 48 * C) * x +
                (8 * B + 24 * C)) / 6.0;
    return 0.0;
}
static double model_h(double x) /* the 2-unit Hermite blur */
{
    x = fabs(x);
    return x < 1.0 ? (2.0 * x - 3.0) * x * x + 1.0 : 0.0;
}

/* Ptex's rule with lerp for a width under 1 (clamped to a texel first): level r with
 * 1/2^r <= uw < 2/2^r, l = (uw - 1/2^r) * 2^r; each even pair of taps (a, b) becomes
 * (k(a) (1 - l) + m l, k(b) (1 - l) + m l), m the kernel at the pair's middle (under 1/4),
 * the Hermite blur of the middle at the lower level's spread (1/4..1/2: 1/(uw + 3/4), the
 * middle at half scale; 1/2..1: 1/(1.5 uw + 1/2), and Hermite taps). The window in float as
 * Ptex computes it. Returns the tap count, -1 when l is 0 (no blend). */
static int model_axis(unsigned ft, double sharp, float u, float uw, int fres, int *kres,
                      int *ku, double *w)
{
    float lo = ldexpf(1.0f, -fres);
    if (uw < lo)
        uw = lo;
    int r = 0;
    while (ldexpf(1.0f, -r) > uw)
        r++;
    double l = ((double)uw - ldexp(1.0, -r)) * ldexp(1.0, r);
    if (uw >= 1.0f || l == 0.0)
        return -1;
    if (uw >= 0.5f) {
        *kres = 1;
        float upix = u * 2.0f - 0.5f;
        *ku = (int)floorf(u - 0.5f) * 2;
        double x1 = (double)((float)*ku - upix), s = 1.0 / (1.5 * (double)uw + 0.5);
        for (int i = 0; i < 4; i += 2) {
            double a = x1 + i, b = a + 1, m = model_h((a + b) * 0.5 * s);
            w[i] = model_h(a * s) * (1 - l) + m * l;
            w[i + 1] = model_h(b * s) * (1 - l) + m * l;
        }
        return 4;
    }
    float res = ldexpf(1.0f, r), upix = u * res - 0.5f, uwpix = uw * res;
    float half = uw >= 0.25f ? 2.0f : 2.0f * uwpix;
    if (uw >= 0.25f)
        r = 2, res = 4.0f, upix = u * 4.0f - 0.5f, uwpix = 1.0f;
    int u1 = (int)ceilf(upix - half) & ~1, u2 = ((int)ceilf(upix + half) + 1) & ~1;
    *kres = r;
    *ku = u1;
    double step = 1.0 / (double)uwpix, x1 = ((double)u1 - (double)upix) * step;
    for (int i = 0; i < u2 - u1; i += 2) {
        double a = x1 + i * step, b = a + step, m;
        if (uw >= 0.25f)
            m = model_h((a + b) * 0.25 / ((double)uw + 0.75));
        else
            m = model_k(ft, sharp, (a + b) * 0.5);
        w[i] = model_k(ft, sharp, a) * (1 - l) + m * l;
        w[i + 1] = model_k(ft, sharp, b) * (1 - l) + m * l;
    }
    return u2 - u1;
}

static void lerp_axis_matches_the_model(void **state)
{
    (void)state;
    long cases = 0, blended = 0, bad = 0;
    double worst = 0;
    for (size_t fi = 0; fi < sizeof w4filters / sizeof w4filters[0]; fi++)
        for (int sh = 0; sh < 3; sh++) {
            pk_params p;
            float sharp = 0.5f * (float)sh;
            pk_params_init(&p, w4filters[fi], sharp, 0);
            p.lerp = 1;
            for (int t = 0; t < 4000; t++) {
                int fres = (int)(rnd01() * 9.0f);
                float u = rnd01();
                float uw = exp2f(-(float)fres - 0.5f + rnd01() * ((float)fres + 0.5f));
                if (t % 10 == 0)
                    uw = exp2f(-(float)(int)(rnd01() * (float)(fres + 1))); /* on a level */
                int kres, ku, kw, mres = -9, mku = -9;
                float w[PK_MAX];
                double mw[PK_MAX];
                pk_width4_axis_lerp(&p, &kres, &ku, &kw, w, u, uw, fres);
                int mn = model_axis(w4filters[fi], sharp, u, uw, fres, &mres, &mku, mw);
                cases++;
                if (mn < 0) { /* no blend: the kernel without lerp, bit for bit */
                    int kres2, ku2, kw2;
                    float w2[PK_MAX], x1, step;
                    if (pk_width4_axis(&kres2, &ku2, &kw2, w2, u, uw, fres, &x1, &step))
                        pk_kernel_eval(&p, x1, step, w2, kw2);
                    bad += kres != kres2 || ku != ku2 || kw != kw2 ||
                           memcmp(w, w2, sizeof(float) * (size_t)kw) != 0;
                    continue;
                }
                blended++;
                if (kres != mres || ku != mku || kw != mn) {
                    if (bad++ < 5)
                        print_message("window: u %.9g uw %.9g fres %d: %d %d %d, model %d %d %d\n",
                                      (double)u, (double)uw, fres, kres, ku, kw, mres, mku, mn);
                    continue;
                }
                for (int i = 0; i < kw; i++) {
                    double d = fabs((double)w[i] - mw[i]);
                    worst = d > worst ? d : worst;
                    if (d > 2e-6 && bad++ < 5)
                        print_message("weight %d: u %.9g uw %.9g fres %d: %.9g, model %.9g\n", i,
                                      (double)u, (double)uw, fres, (double)w[i], mw[i]);
                }
            }
        }
    print_message("%ld axes, %ld blended, largest weight difference %.3g\n", cases, blended,
                  worst);
    assert_true(blended > cases / 2);
    assert_int_equal(bad, 0);
}

/* ---- outputs ---------------------------------------------------------------------------- */

/* Face 0 (16 x 16) with face 1 (8 x 8) to its right and face 2 (16 x 16) above, 2 float
 * channels of noise, reductions made. */
static st_set *three_faces(void)
{
    st_face_desc fd[3];
    st_test_faces(fd, 3, 16, 16);
    fd[1].w = fd[1].h = 8;
    st_test_join(fd, 0, 1, 1, 3);
    st_test_join(fd, 0, 2, 2, 0);
    st_set_info info = {.nfaces = 3, .nchan = 2, .dtype = ST_DT_F32, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    for (uint32_t f = 0; f < 3; f++) {
        float *p = (float *)st_face_level(s, f, 0);
        for (uint32_t i = 0; i < 2 * s->faces[f].w * s->faces[f].h; i++)
            p[i] = rnd01();
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

enum { NQ = 600 };

/* lerp on vs off, bit for bit: outputs, coverage, status */
static int same_on_off(const st_set *s, unsigned filter, unsigned mode, const st_query *q)
{
    static float out[2][2 * NQ], cov[2][NQ];
    static uint8_t st[2][NQ];
    for (int l = 0; l < 2; l++) {
        st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)filter, .sharpness = 0.3f,
                            .lerp = (uint8_t)l};
        assert_true(st_ptexfilter_batch(s, &o, q, NQ, out[l], cov[l], st[l]) >= 0);
    }
    return !memcmp(out[0], out[1], sizeof out[0]) && !memcmp(cov[0], cov[1], sizeof cov[0]) &&
           !memcmp(st[0], st[1], sizeof st[0]);
}

static void lerp_on_a_level_or_other_filters_is_lerp_off(void **state)
{
    (void)state;
    st_set *s = three_faces();
    static st_query on[NQ], any[NQ];
    for (int i = 0; i < NQ; i++) {
        uint32_t f = (uint32_t)(rnd01() * 3.0f);
        /* widths 1/2^r of the face (r = 0..5; under a texel they clamp to one texel: on a
         * level too), axis-aligned: uw = |dudx|, vw = |dvdy| */
        float wu = exp2f(-(float)(int)(rnd01() * 6.0f)), wv = exp2f(-(float)(int)(rnd01() * 6.0f));
        on[i] = (st_query){.face = f, .u = rnd01() * 1.1f - 0.05f, .v = rnd01() * 1.1f - 0.05f,
                           .dudx = i & 1 ? wu : -wu, .dvdy = wv};
        float fu = exp2f(-6.0f + 7.0f * rnd01()), fv = exp2f(-6.0f + 7.0f * rnd01());
        any[i] = (st_query){.face = f, .u = rnd01(), .v = rnd01(), .dudx = fu * 0.7f,
                            .dudy = fu * 0.3f, .dvdx = fv * 0.2f, .dvdy = fv * 0.8f};
    }
    int bad = 0;
    for (unsigned mode = 0; mode < 3; mode++) {
        for (size_t fi = 0; fi < sizeof w4filters / sizeof w4filters[0]; fi++)
            bad += !same_on_off(s, w4filters[fi], mode, on);
        for (unsigned f = ST_FILTER_PTEX_POINT; f <= ST_FILTER_PTEX_BOX; f++)
            bad += !same_on_off(s, f, mode, any) + !same_on_off(s, f, mode, on);
    }
    /* and between levels lerp changes the width-4 filters' outputs */
    int changed = 0;
    for (size_t fi = 0; fi < sizeof w4filters / sizeof w4filters[0]; fi++)
        changed += !same_on_off(s, w4filters[fi], ST_MODE_TRAVERSE, any);
    st_set_free(s);
    assert_int_equal(bad, 0);
    assert_int_equal(changed, 5);
}

/* ---- against Ptex ----------------------------------------------------------------------- */

typedef struct pinned {
    const char *file;            /* under SEAMTEX_DATA */
    float sharpness;
    uint32_t face;
    float u, v, uw1, vw1, uw2, vw2;
    unsigned filter;
    float ref[3];                /* Ptex 2.4.3 with lerp, first min(3, nchan) channels */
} pinned;

#include "ptexfilter_lerp_pinned.inc"

static void lerp_between_levels_gives_ptex_outputs(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, lerp_pinned[0].file)) {
        print_message("no SEAMTEX_DATA: skipped\n");
        skip();
    }
    size_t n = sizeof lerp_pinned / sizeof lerp_pinned[0];
    int bad = 0, far = 0;
    st_set *s = NULL;
    const char *cur = NULL;
    for (size_t i = 0; i < n; i++) {
        const pinned *p = &lerp_pinned[i];
        if (!cur || strcmp(cur, p->file)) {
            st_set_free(s);
            st_error e;
            assert_int_equal(st_test_data_path(path, sizeof path, p->file), 0);
            assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
            cur = p->file;
        }
        st_query q = {.face = p->face, .u = p->u, .v = p->v, .dudx = p->uw1, .dvdx = p->vw1,
                      .dudy = p->uw2, .dvdy = p->vw2};
        float out[2][4];
        for (int l = 0; l < 2; l++) {
            st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = (uint8_t)p->filter,
                                .sharpness = p->sharpness, .lerp = (uint8_t)!l};
            assert_int_equal(st_ptexfilter_batch(s, &o, &q, 1, out[l], NULL, NULL), 0);
        }
        float tol = s->info.dtype == ST_DT_U8 ? 0.5f / 255.0f : 1e-4f;
        unsigned nc = s->info.nchan < 3 ? s->info.nchan : 3;
        int off = 0;
        for (unsigned c = 0; c < nc; c++) {
            float t = tol * (fabsf(p->ref[c]) > 1.0f ? fabsf(p->ref[c]) : 1.0f);
            if (!(fabsf(out[0][c] - p->ref[c]) <= t)) {
                if (bad++ < 5)
                    print_message("%s line %zu channel %u: %.9g, Ptex %.9g\n", p->file, i, c,
                                  (double)out[0][c], (double)p->ref[c]);
            }
            off |= !(fabsf(out[1][c] - p->ref[c]) <= t);
        }
        far += off;
    }
    st_set_free(s);
    print_message("%zu pinned lines, %d outside the tolerance, %d of them further than it from "
                  "lerp off\n", n, bad, far);
    assert_int_equal(bad, 0);
    assert_true((size_t)far * 2 > n);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lerp_axis_matches_the_model),
        cmocka_unit_test(lerp_on_a_level_or_other_filters_is_lerp_off),
        cmocka_unit_test(lerp_between_levels_gives_ptex_outputs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
