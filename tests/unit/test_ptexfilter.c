/* tests/unit/test_ptexfilter.c - Ptex's filter family against the Ptex library's own outputs
 * (SEAMTEX_DATA/ptex-ref: PtexFilter::eval of Ptex v2.4.3 on real and generated files) and
 * its own invariants: constant textures stay constant in every mode, Discard renormalises and
 * reports coverage, the sampler's batch entry point dispatches here, bad queries get a status.
 *
 * The reference check requires, per file and filter, at least 99.9% of the queries within
 * 1e-4 (float data) or half an 8-bit step (u8 data) on every channel, and prints the table. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "sample.h"
#include "../common/ptexref.h"
#include "../common/testdata.h"

typedef struct refcase {
    const char *ptx, *ref;
} refcase;

static const refcase refs[] = {
    {"ptex-ref/cube1_k6_u8.ptx", "ptex-ref/ref_cube1_k6_u8.txt"},
    {"ptex-ref/cube8_k6_u8_rot.ptx", "ptex-ref/ref_cube8_k6_u8_rot.txt"},
    {"ptex-ref/cube8_k7varrot_f32.ptx", "ptex-ref/ref_cube8_k7varrot_f32.txt"},
    {"ptx/wdas-ptex-samples/teapot/teapot.ptx", "ptex-ref/ref_teapot.txt"},
    {"ptx/wdas-ptex-samples/envcube/envcube.ptx", "ptex-ref/ref_envcube.txt"},
};

static void traverse_matches_the_ptex_library_on_every_reference_file(void **state)
{
    (void)state;
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), refs[0].ref);
    if (access(path, R_OK)) {
        print_message("SEAMTEX_DATA (%s) has no ptex-ref: skipped\n", st_test_data_dir());
        skip();
    }
    st_reftally_header();
    for (size_t r = 0; r < sizeof refs / sizeof refs[0]; r++) {
        snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), refs[r].ptx);
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), refs[r].ref);
        st_reftally t;
        /* through the sampler's public entry point */
        assert_int_equal(st_reftally_run(s, path, 0, &t), 0);
        for (int fi = 0; fi < 8; fi++)
            assert_true(t.total[fi] > 0);
        assert_int_equal(st_reftally_print(&t, strrchr(refs[r].ptx, '/') + 1), 0);
        st_set_free(s);
    }
}

/* 3x3 grid of faces (an open plane) of one texel value; face 4 in the middle is 4x8. */
static st_set *plane(unsigned dtype, int constant_value, int subfaces)
{
    st_face_desc fd[9];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 9; f++) {
        int x = f % 3, y = f / 3;
        fd[f].w = f == 4 ? 4 : 8;
        fd[f].h = 8;
        fd[f].adjface[0] = y > 0 ? f - 3 : -1; fd[f].adjedge[0] = 2;
        fd[f].adjface[1] = x < 2 ? f + 1 : -1; fd[f].adjedge[1] = 3;
        fd[f].adjface[2] = y < 2 ? f + 3 : -1; fd[f].adjedge[2] = 0;
        fd[f].adjface[3] = x > 0 ? f - 1 : -1; fd[f].adjedge[3] = 1;
        if (subfaces && (f == 2 || f == 5))
            fd[f].flags |= ST_FACE_SUBFACE;
    }
    st_set_info info = {.nfaces = 9, .nchan = 2, .dtype = (uint8_t)dtype, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    uint32_t r = 5;
    for (uint32_t f = 0; f < 9; f++) {
        uint8_t *p = st_face_level(s, f, 0);
        for (size_t i = 0; i < (size_t)s->faces[f].w * s->faces[f].h; i++) {
            r = r * 1103515245u + 12345u;
            st_channel_put(dtype, p + i * st_texel_size(s), 0,
                           constant_value ? 0.5f : (float)((r >> 16) & 255) / 255.0f);
            st_channel_put(dtype, p + i * st_texel_size(s), 1, 0.25f);
        }
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

/* A main face M (8x8) whose right edge meets two subfaces (4x4, half its size) of a
 * non-quad face, Ptex style: M's edge names the lower (primary) subface A; A and B both name
 * M across their left edge; A's top edge meets B's bottom edge. */
static st_set *subface_set(void)
{
    st_face_desc fd[3];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 3; f++) {
        fd[f].w = fd[f].h = f == 0 ? 8 : 4;
        for (int ed = 0; ed < 4; ed++)
            fd[f].adjface[ed] = -1;
    }
    fd[0].adjface[1] = 1; fd[0].adjedge[1] = 3;
    fd[1].flags = fd[2].flags = ST_FACE_SUBFACE;
    fd[1].adjface[3] = 0; fd[1].adjedge[3] = 1;
    fd[2].adjface[3] = 0; fd[2].adjedge[3] = 1;
    fd[1].adjface[2] = 2; fd[1].adjedge[2] = 0;
    fd[2].adjface[0] = 1; fd[2].adjedge[0] = 2;
    st_set_info info = {.nfaces = 3, .nchan = 2, .dtype = ST_DT_F32, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    for (uint32_t f = 0; f < 3; f++) {
        float *p = (float *)(void *)st_face_level(s, f, 0);
        for (size_t i = 0; i < (size_t)s->faces[f].w * s->faces[f].h; i++) {
            p[2 * i] = 0.5f;
            p[2 * i + 1] = 0.25f;
        }
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

static void constant_texture_stays_constant_in_every_mode_and_filter(void **state)
{
    (void)state;
    for (int sub = 0; sub < 2; sub++) {
        st_set *s = sub ? subface_set() : plane(ST_DT_F32, 1, 0);
        uint32_t nf = s->info.nfaces;
        uint32_t x = 1;
        for (int m = 0; m < 3; m++)
            for (int flt = ST_FILTER_PTEX_POINT; flt <= ST_FILTER_PTEX_MITCHELL; flt++)
                for (int i = 0; i < 300; i++) {
                    x = x * 1664525u + 1013904223u;
                    st_query q = {.face = (x >> 8) % nf,
                                  .u = (float)((x >> 3) & 1023) / 1023.0f,
                                  .v = (float)((x >> 13) & 1023) / 1023.0f,
                                  .dudx = (float)((x >> 23) & 63) / 100.0f + 1e-3f,
                                  .dvdy = (float)((x >> 17) & 63) / 100.0f + 1e-3f};
                    st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)flt};
                    float out[2], cov;
                    uint8_t st;
                    assert_int_equal(st_ptexfilter_batch(s, &o, &q, 1, out, &cov, &st), 0);
                    if (fabsf(out[0] - 0.5f) > 1e-4f)
                        print_message("sub %d mode %d filter %d face %u u %g v %g w %g %g out %g\n", sub, m, flt, q.face, q.u, q.v, q.dudx, q.dvdy, out[0]);
                    assert_float_equal(out[0], 0.5f, 1e-4f);
                    assert_float_equal(out[1], 0.25f, 1e-4f);
                    if (!(cov > 0.0f && cov <= 1.0f + 1e-6f))
                        print_message("mode %d filter %d face %u u %g v %g w %g %g cov %g\n", m, flt, q.face, q.u, q.v, q.dudx, q.dvdy, cov);
                    assert_true(cov > 0.0f && cov <= 1.0f + 1e-6f);
                }
        st_set_free(s);
    }
}

/* 3x3 grid of faces of f32 noise (3 channels; face 0 16x16, face 4 4x8, the others 8x8) with
 * the border modes bu, bv; cut: every edge a boundary (the same texels). */
static st_set *noise_grid(unsigned bu, unsigned bv, int cut)
{
    st_face_desc fd[9];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 9; f++) {
        int x = f % 3, y = f / 3;
        fd[f].w = f == 0 ? 16 : f == 4 ? 4 : 8;
        fd[f].h = f == 0 ? 16 : 8;
        fd[f].adjface[0] = y > 0 ? f - 3 : -1; fd[f].adjedge[0] = 2;
        fd[f].adjface[1] = x < 2 ? f + 1 : -1; fd[f].adjedge[1] = 3;
        fd[f].adjface[2] = y < 2 ? f + 3 : -1; fd[f].adjedge[2] = 0;
        fd[f].adjface[3] = x > 0 ? f - 1 : -1; fd[f].adjedge[3] = 1;
        for (int ed = 0; cut && ed < 4; ed++)
            fd[f].adjface[ed] = -1;
    }
    st_set_info info = {.nfaces = 9, .nchan = 3, .dtype = ST_DT_F32, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .border_u = (uint8_t)bu,
                        .border_v = (uint8_t)bv};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    uint32_t r = 77;
    for (uint32_t f = 0; f < 9; f++) {
        float *p = (float *)(void *)st_face_level(s, f, 0);
        for (size_t i = 0; i < (size_t)s->faces[f].w * s->faces[f].h * 3; i++) {
            r = r * 1103515245u + 12345u;
            p[i] = (float)((r >> 8) & 0xffff) / 65536.0f;
        }
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

/* Clamp is Ptex's noedgeblend option (PtexSeparableFilter::splitAndApply: every overhang
 * merged by the border mode, no neighbour read): on a set with neighbours it gives what
 * Traverse gives on the same texels with every edge a boundary - clamp and periodic fold the
 * overhang onto the edge texels, black drops it - for every quad Ptex filter, near edges and
 * corners, footprints of a quarter texel to a whole face and more. Outside the project the
 * two were compared with Ptex 2.4.3 itself (docs/ptex.md, Clamp). */
static void clamp_is_traverse_with_every_edge_a_boundary(void **state)
{
    (void)state;
    enum { N = 800 };
    static st_query q[N];
    static float a[N * 3], b[N * 3], t[N * 3];
    static uint8_t sa[N], sb[N];
    static const float fps[] = {0.25f, 1.0f, 3.0f, 7.0f, 16.0f, 40.0f};
    uint32_t r = 3;
    for (unsigned bm = 0; bm < 3; bm++) {
        st_set *s = noise_grid(bm, (bm + 1) % 3, 0), *c = noise_grid(bm, (bm + 1) % 3, 1);
        for (int i = 0; i < N; i++) {
            r = r * 1664525u + 1013904223u;
            uint32_t f = (r >> 8) % 9;
            const st_face *F = &s->faces[f];
            float u = (float)((r >> 4) & 1023) / 1024.0f, v = (float)((r >> 14) & 1023) / 1024.0f;
            if (i % 2) /* within two texels of an edge or (i % 4 == 3) a corner */
                u = i % 8 < 4 ? u * 2.0f / (float)F->w : 1.0f - u * 2.0f / (float)F->w;
            if (i % 4 == 3)
                v = i % 16 < 8 ? v * 2.0f / (float)F->h : 1.0f - v * 2.0f / (float)F->h;
            float fu = fps[(r >> 24) % 6], fv = i % 3 ? fu : fps[(r >> 27) % 6];
            q[i] = (st_query){.face = f, .u = u, .v = v, .dudx = fu / (float)F->w,
                              .dvdy = fv / (float)F->h};
        }
        int differ = 0;
        for (unsigned flt = ST_FILTER_PTEX_POINT; flt <= ST_FILTER_PTEX_MITCHELL; flt++) {
            st_sample_opts oc = {.mode = ST_MODE_CLAMP, .filter = flt, .sharpness = 0.5f};
            st_sample_opts ot = oc;
            ot.mode = ST_MODE_TRAVERSE;
            assert_int_equal(st_ptexfilter_batch(s, &oc, q, N, a, NULL, sa), 0);
            assert_int_equal(st_ptexfilter_batch(c, &ot, q, N, b, NULL, sb), 0);
            assert_int_equal(st_ptexfilter_batch(s, &ot, q, N, t, NULL, NULL), 0);
            assert_memory_equal(sa, sb, N);
            for (int k = 0; k < N * 3; k++) {
                float d = fabsf(a[k] - b[k]);
                if (!(d <= 1e-6f * fmaxf(1.0f, fabsf(b[k]))))
                    fail_msg("border %u filter %u query %d (face %u u %.9g v %.9g fp %g x %g): "
                             "Clamp %.9g, Traverse without neighbours %.9g", bm, flt, k / 3,
                             q[k / 3].face, (double)q[k / 3].u, (double)q[k / 3].v,
                             (double)(q[k / 3].dudx * (float)s->faces[q[k / 3].face].w),
                             (double)(q[k / 3].dvdy * (float)s->faces[q[k / 3].face].h),
                             (double)a[k], (double)b[k]);
                differ += fabsf(a[k] - t[k]) > 1e-3f;
            }
        }
        assert_true(differ > N); /* the neighbours' texels do reach Traverse's outputs */
        st_set_free(s);
        st_set_free(c);
    }
}

static void discard_drops_the_overhang_and_reports_coverage(void **state)
{
    (void)state;
    st_set *s = plane(ST_DT_U8, 0, 0);
    /* near the right edge of the middle face with a wide box: part of the kernel overhangs */
    st_query q = {.face = 4, .u = 0.95f, .v = 0.5f, .dudx = 0.3f, .dvdy = 0.3f};
    float a[2], b[2], ca, cb;
    uint8_t st;
    st_sample_opts od = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_PTEX_BOX};
    st_sample_opts ot = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BOX};
    assert_int_equal(st_ptexfilter_batch(s, &od, &q, 1, a, &ca, &st), 0);
    assert_int_equal(st_ptexfilter_batch(s, &ot, &q, 1, b, &cb, &st), 0);
    assert_true(ca < 0.99f && ca > 0.2f);
    assert_float_equal(cb, 1.0f, 1e-6f);
    assert_true(fabsf(a[0] - b[0]) > 1e-6f);   /* the neighbour contributes in Traverse only */
    assert_float_equal(a[1], 0.25f, 2e-3f);    /* renormalised: a constant channel stays put */
    /* in the interior all modes agree */
    st_query qi = {.face = 4, .u = 0.5f, .v = 0.5f, .dudx = 0.01f, .dvdy = 0.01f};
    assert_int_equal(st_ptexfilter_batch(s, &od, &qi, 1, a, &ca, &st), 0);
    assert_int_equal(st_ptexfilter_batch(s, &ot, &qi, 1, b, &cb, &st), 0);
    assert_float_equal(a[0], b[0], 1e-6f);
    assert_float_equal(ca, 1.0f, 1e-6f);
    st_set_free(s);
}

static void bad_queries_get_a_status_and_nan(void **state)
{
    (void)state;
    st_set *s = plane(ST_DT_HALF, 0, 0);
    st_query q[4] = {
        {.face = 99, .u = 0.5f, .v = 0.5f},
        {.face = 1, .u = NAN, .v = 0.5f},
        {.face = 1, .u = 0.5f, .v = 0.5f, .dudx = 1e9f},
        {.face = 1, .u = 0.5f, .v = 0.5f, .dudx = 0.1f, .dvdy = 0.1f},
    };
    float out[8], cov[4];
    uint8_t st[4];
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_GAUSSIAN};
    assert_int_equal(st_ptexfilter_batch(s, &o, q, 4, out, cov, st), 3);
    assert_int_equal(st[0], ST_Q_BAD_FACE);
    assert_int_equal(st[1], ST_Q_NONFINITE);
    assert_int_equal(st[2], ST_Q_BAD_FOOTPRINT);
    assert_int_equal(st[3], ST_Q_OK);
    assert_true(isnan(out[0]) && isnan(out[2]) && isnan(out[4]));
    assert_false(isnan(out[6]));
    o.sharpness = 2.0f;
    assert_int_equal(st_ptexfilter_batch(s, &o, q, 4, out, cov, st), ST_EINVAL);
    st_set_free(s);
}

static void a_set_without_the_table_is_refused_until_prepared(void **state)
{
    (void)state;
    st_face_desc fd = {.w = 4, .h = 4, .adjface = {-1, -1, -1, -1}};
    st_set_info info = {.nfaces = 1, .nchan = 1, .dtype = ST_DT_U8, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, &fd, 0, &s, &e), 0);
    st_query q = {.face = 0, .u = 0.5f, .v = 0.5f, .dudx = 0.1f, .dvdy = 0.1f};
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BILINEAR};
    float out;
    assert_int_equal(st_ptexfilter_batch(s, &o, &q, 1, &out, NULL, NULL), ST_EUNSUPPORTED);
    assert_int_equal(st_ptexfilter_memory(s), 0);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    assert_true(st_ptexfilter_memory(s) > 0);
    assert_int_equal(st_ptexfilter_batch(s, &o, &q, 1, &out, NULL, NULL), 0);
    assert_float_equal(out, 0.0f, 1e-7f);
    st_set_free(s);
}

static void border_modes_follow_ptex(void **state)
{
    (void)state;
    char path[1024];
    snprintf(path, sizeof path, "%s/ptx/wdas-ptex-2009/bordermodes/clamp.ptx", st_test_data_dir());
    if (access(path, R_OK)) {
        print_message("SEAMTEX_DATA (%s) has no bordermodes: skipped\n", st_test_data_dir());
        skip();
    }
    static const char *names[3] = {"clamp", "black", "periodic"};
    st_set *s[3];
    for (int m = 0; m < 3; m++) {
        snprintf(path, sizeof path, "%s/ptx/wdas-ptex-2009/bordermodes/%s.ptx", st_test_data_dir(), names[m]);
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s[m], &e), 0);
        assert_int_equal(s[m]->info.border_u, m);
    }
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BILINEAR};
    float a[3], b[3], z[3];
    st_query in = {.face = 0, .u = 0.1f, .v = 0.6f, .dudx = 0.01f, .dvdy = 0.01f};
    st_query left = in, wrap = in, far = in;
    left.u = -0.4f;   /* clamp: same as u = 0 */
    wrap.u = 1.1f;    /* periodic: same as u = 0.1 */
    far.u = -1.5f;    /* black: beyond one face width, black */
    st_query at0 = in;
    at0.u = 0.0f;
    assert_int_equal(st_ptexfilter_batch(s[0], &o, &left, 1, a, NULL, NULL), 0);
    assert_int_equal(st_ptexfilter_batch(s[0], &o, &at0, 1, b, NULL, NULL), 0);
    for (int c = 0; c < 3; c++)
        assert_float_equal(a[c], b[c], 1e-6f);
    assert_int_equal(st_ptexfilter_batch(s[2], &o, &wrap, 1, a, NULL, NULL), 0);
    assert_int_equal(st_ptexfilter_batch(s[2], &o, &in, 1, b, NULL, NULL), 0);
    for (int c = 0; c < 3; c++)
        assert_float_equal(a[c], b[c], 1e-5f);
    assert_int_equal(st_ptexfilter_batch(s[1], &o, &far, 1, z, NULL, NULL), 0);
    for (int c = 0; c < 3; c++)
        assert_float_equal(z[c], 0.0f, 0.0f);
    for (int m = 0; m < 3; m++)
        st_set_free(s[m]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(traverse_matches_the_ptex_library_on_every_reference_file),
        cmocka_unit_test(constant_texture_stays_constant_in_every_mode_and_filter),
        cmocka_unit_test(discard_drops_the_overhang_and_reports_coverage),
        cmocka_unit_test(bad_queries_get_a_status_and_nan),
        cmocka_unit_test(a_set_without_the_table_is_refused_until_prepared),
        cmocka_unit_test(border_modes_follow_ptex),
        cmocka_unit_test(clamp_is_traverse_with_every_edge_a_boundary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
