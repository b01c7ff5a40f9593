/* tests/unit/test_ptextri.c - triangle-mesh Ptex files: reading them (square faces, three
 * edges, the packed triangle layout and its reductions), Ptex's point and triangle filters
 * against the Ptex library's own outputs (SEAMTEX_DATA/ptex-ref/ref_tri.txt and
 * ref_triangle.txt: PtexFilter::eval of Ptex v2.4.3), Discard and Clamp, the GPU-style point
 * filter, and round trips through the .ptx writer and the native set file.
 *
 * The reference check requires, per file and filter, at least 99.9% of the queries within
 * 1e-4 on every channel (float data, the tolerance of the quad files) and prints the table. */
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

#include "bc1.h"
#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "ptextri.h"
#include "sample.h"
#include "trilevel.h"
#include "../common/ptexref.h"
#include "../common/testdata.h"

static const char *const tri_files[2][2] = {
    {"ptx/wdas-ptex-2009/tri/tri.ptx", "ptex-ref/ref_tri.txt"},
    {"ptx/wdas-ptex-samples/triangle/triangle.ptx", "ptex-ref/ref_triangle.txt"},
};

static st_set *read_rel(const char *rel)
{
    char path[1024];
    if (st_test_data_path(path, sizeof path, rel))
        return NULL;
    st_set *s;
    st_error e = {0};
    int rc = st_ptex_read_file(path, 0, &s, &e);
    if (rc)
        print_message("%s: %s\n", rel, e.msg);
    assert_int_equal(rc, 0);
    return s;
}

static void triangle_filters_match_the_ptex_library(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, tri_files[0][1]))
        skip();
    st_reftally_header();
    for (int r = 0; r < 2; r++) {
        st_set *s = read_rel(tri_files[r][0]);
        assert_non_null(s);
        assert_int_equal(s->info.meshtype, ST_MESH_TRIANGLE);
        assert_int_equal(st_test_data_path(path, sizeof path, tri_files[r][1]), 0);
        st_reftally t;
        assert_int_equal(st_reftally_run(s, path, getenv("PTEXTRI_VERBOSE") != NULL, &t), 0);
        const char *base = strrchr(tri_files[r][0], '/') + 1;
        /* the lines whose kernel reaches past an edge into a neighbour (Discard, which stays
         * in the face, answers otherwise): they exercise the splitting */
        print_message("%s: %d of the lines read a neighbour across an edge\n", base, t.crossing);
        assert_true(t.crossing >= 50);
        assert_int_equal(st_reftally_print(&t, base), 0);
        st_set_free(s);
    }
}


/* Two triangles sharing edge 1 (a unit square cut along its diagonal), R x R, one value per
 * face or a ramp; face 1 is face 0 rotated half a turn. */
static st_set *two_triangles(uint32_t R, unsigned dtype, int ramp)
{
    st_face_desc fd[2];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 2; f++) {
        fd[f].w = fd[f].h = R;
        for (int ed = 0; ed < 4; ed++)
            fd[f].adjface[ed] = -1;
        fd[f].adjface[1] = 1 - f;
        fd[f].adjedge[1] = 1;
    }
    st_set_info info = {.nfaces = 2, .nchan = 3, .dtype = (uint8_t)dtype, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .meshtype = ST_MESH_TRIANGLE};
    st_set *s;
    st_error e = {0};
    int rc = st_set_create(&info, fd, 0, &s, &e);
    if (rc)
        print_message("%s\n", e.msg);
    assert_int_equal(rc, 0);
    for (uint32_t f = 0; f < 2; f++) {
        uint8_t *p = st_face_level(s, f, 0);
        for (uint32_t i = 0; i < R * R; i++)
            for (unsigned c = 0; c < 3; c++)
                st_channel_put(dtype, p + i * st_texel_size(s), c,
                               ramp ? (float)((i * 7 + c * 3 + f) % 11) / 10.0f : 0.25f * (c + 1));
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

static void the_point_rule_picks_the_small_triangle_holding_uv(void **state)
{
    (void)state;
    uint32_t x, y;
    st_tri_texel(4, 0.1f, 0.1f, &x, &y);   /* cell (0,0), below its diagonal */
    assert_true(x == 0 && y == 0);
    st_tri_texel(4, 0.2f, 0.2f, &x, &y);   /* cell (0,0), above: inverted, stored mirrored */
    assert_true(x == 3 && y == 3);
    st_tri_texel(4, 0.6f, 0.1f, &x, &y);   /* cell (2,0), upright */
    assert_true(x == 2 && y == 0);
    st_tri_texel(4, 0.45f, 0.45f, &x, &y); /* cell (1,1), inverted -> (4-1-1, 4-1-1) */
    assert_true(x == 2 && y == 2);
    st_tri_texel(4, 0.7f, 0.1f, &x, &y);   /* cell (2,0), inverted -> (3, 1) */
    assert_true(x == 3 && y == 1);
    st_tri_texel(4, -1.0f, 2.0f, &x, &y);  /* clamped into the last cell of a column */
    assert_true(x == 0 && y == 3);
    st_tri_texel(1, 0.3f, 0.3f, &x, &y);
    assert_true(x == 0 && y == 0);
}

static void triangle_files_read_as_square_faces_with_three_edges(void **state)
{
    (void)state;
    for (int r = 0; r < 2; r++) {
        st_set *s = read_rel(tri_files[r][0]);
        if (!s)
            skip();
        assert_int_equal(s->info.meshtype, ST_MESH_TRIANGLE);
        assert_int_equal(s->info.nfaces, 9);
        int shared = 0;
        for (uint32_t f = 0; f < s->info.nfaces; f++) {
            const st_face *F = &s->faces[f];
            assert_int_equal(F->w, F->h);
            assert_int_equal(F->adjface[3], -1);
            assert_false(F->flags & ST_FACE_SUBFACE);
            for (int ed = 0; ed < 3; ed++) {
                if (F->adjface[ed] < 0)
                    continue;
                shared++;
                assert_true(F->adjedge[ed] <= 2);
                const st_face *G = &s->faces[F->adjface[ed]];
                assert_int_equal(G->adjface[F->adjedge[ed]], (int32_t)f);
            }
            if (F->flags & ST_FACE_CONSTANT)
                continue;
            /* every level past 0 but the 1x1 one is the triangle reduction of the level
             * before (the file's stored reductions were made by Ptex's writer that way) */
            assert_int_equal(st_set_levels(s, NULL), ST_OK); /* deferred by the reader */
            size_t ts = st_texel_size(s);
            for (unsigned l = 1; l + 1 < F->nlevels; l++) {
                uint32_t R = st_level_w(F, l - 1);
                uint8_t buf[32 * 32 * 16];
                assert_true((size_t)R * R * ts / 4 <= sizeof buf);
                st_tri_reduce(s->info.dtype, s->info.nchan, st_face_level(s, f, l - 1), R, buf);
                assert_memory_equal(buf, st_face_level(s, f, l), (size_t)R / 2 * (R / 2) * ts);
            }
        }
        assert_true(shared > 0);
        st_set_free(s);
    }
}

static int same_set(const st_set *a, const st_set *b)
{
    return st_set_levels(a, NULL) == ST_OK && st_set_levels(b, NULL) == ST_OK && /* ptex.h */
           a->info.nfaces == b->info.nfaces && a->info.meshtype == b->info.meshtype &&
           a->info.dtype == b->info.dtype && a->info.nchan == b->info.nchan &&
           a->texel_bytes == b->texel_bytes &&
           !memcmp(a->faces, b->faces, (size_t)a->info.nfaces * sizeof(st_face)) &&
           !memcmp(a->texels, b->texels, a->texel_bytes);
}

static void ptx_round_trip_is_bit_exact_and_a_fixed_point(void **state)
{
    (void)state;
    for (int r = 0; r < 3; r++) {
        st_set *s = r < 2 ? read_rel(tri_files[r][0]) : two_triangles(8, ST_DT_U8, 1);
        if (!s)
            skip();
        void *b1, *b2;
        size_t n1, n2;
        st_error e = {0};
        assert_int_equal(st_ptex_write_mem(s, &b1, &n1, &e), 0);
        assert_int_equal(((const uint8_t *)b1)[8], 0); /* Ptex mesh type triangle */
        st_set *t;
        assert_int_equal(st_ptex_read_mem(b1, n1, 0, &t, &e), 0);
        assert_true(same_set(s, t));
        assert_int_equal(st_ptex_write_mem(t, &b2, &n2, &e), 0);
        assert_int_equal(n1, n2);
        assert_memory_equal(b1, b2, n1);
        free(b1);
        free(b2);
        st_set_free(t);
        st_set_free(s);
    }
}

/* every Ptex filter and GPU point in every mode, on n random queries in and near the face */
static void sample_all(const st_set *s, float *out, float *cov, size_t n)
{
    uint32_t seed = 7;
    st_query *q = calloc(n, sizeof *q);
    assert_non_null(q);
    for (size_t i = 0; i < n; i++) {
        seed = seed * 1103515245u + 12345u;
        q[i].face = (seed >> 8) % s->info.nfaces;
        seed = seed * 1103515245u + 12345u;
        q[i].u = (float)((seed >> 8) & 1023) / 1023.0f;
        seed = seed * 1103515245u + 12345u;
        q[i].v = (1.0f - q[i].u) * (float)((seed >> 8) & 1023) / 1023.0f;
        q[i].dudx = 0.004f * (float)(i % 50);
        q[i].dvdy = 0.003f * (float)(i % 37);
        q[i].dvdx = 0.001f * (float)(i % 5);
    }
    size_t k = 0;
    for (unsigned m = 0; m < 3; m++)
        for (unsigned f = ST_FILTER_PTEX_POINT; f <= ST_FILTER_PTEX_MITCHELL + 1; f++) {
            st_sample_opts o = {.mode = (uint8_t)m,
                                .filter = (uint8_t)(f > ST_FILTER_PTEX_MITCHELL ? ST_FILTER_POINT : f)};
            int rc = st_sample_batch(s, &o, q, n, out + k * n * s->info.nchan, cov + k * n, NULL);
            assert_true(rc >= 0);
            k++;
        }
    free(q);
}

static void native_set_file_keeps_triangle_sets(void **state)
{
    (void)state;
    char dir[512], path[700];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "ptextri"), 0);
    snprintf(path, sizeof path, "%s/tri.native", dir);
    for (int r = 0; r < 2; r++) {
        st_set *s = read_rel(tri_files[r][0]);
        if (!s)
            skip();
        st_error e = {0};
        assert_int_equal(st_native_write(path, s, NULL, &e), 0);
        st_set *m;
        int rc = st_native_open(path, ST_NATIVE_VERIFY, NULL, &m, &e);
        if (rc)
            print_message("%s\n", e.msg);
        assert_int_equal(rc, 0);
        assert_true(same_set(s, m));
        size_t n = 300, cells = 3 * 9 * n;
        float *o1 = malloc(cells * 3 * sizeof(float)), *o2 = malloc(cells * 3 * sizeof(float));
        float *c1 = malloc(cells * sizeof(float)), *c2 = malloc(cells * sizeof(float));
        assert_true(o1 && o2 && c1 && c2);
        sample_all(s, o1, c1, n);
        sample_all(m, o2, c2, n);
        assert_memory_equal(o1, o2, cells * 3 * sizeof(float));
        assert_memory_equal(c1, c2, cells * sizeof(float));
        /* and a .ptx of the mapped set is the .ptx of the original */
        void *b1, *b2;
        size_t n1, n2;
        assert_int_equal(st_ptex_write_mem(s, &b1, &n1, &e), 0);
        assert_int_equal(st_ptex_write_mem(m, &b2, &n2, &e), 0);
        assert_int_equal(n1, n2);
        assert_memory_equal(b1, b2, n1);
        free(b1);
        free(b2);
        free(o1);
        free(o2);
        free(c1);
        free(c2);
        st_set_free(m);
        st_set_free(s);
    }
    st_test_rmtree(dir);
}

static void a_constant_texture_stays_constant_in_every_mode(void **state)
{
    (void)state;
    st_set *s = two_triangles(16, ST_DT_F32, 0);
    size_t n = 200, cells = 3 * 9 * n;
    float *o = malloc(cells * 3 * sizeof(float)), *c = malloc(cells * sizeof(float));
    assert_true(o && c);
    sample_all(s, o, c, n);
    for (size_t i = 0; i < cells; i++)
        for (unsigned ch = 0; ch < 3; ch++)
            assert_float_equal(o[i * 3 + ch], 0.25f * (ch + 1), 1e-5f);
    free(o);
    free(c);
    st_set_free(s);
}

static void discard_renormalises_at_boundaries_and_modes_agree_inside(void **state)
{
    (void)state;
    st_set *s = two_triangles(32, ST_DT_F32, 1);
    float out[3][3], cov[3];
    /* small footprint at the centroid: the kernel stays inside face 0 */
    st_query in = {0, 1.0f / 3, 1.0f / 3, 0.02f, 0, 0, 0.02f};
    for (unsigned m = 0; m < 3; m++) {
        st_sample_opts o = {.mode = (uint8_t)m, .filter = ST_FILTER_PTEX_GAUSSIAN};
        assert_int_equal(st_sample_batch(s, &o, &in, 1, out[m], &cov[m], NULL), 0);
        assert_float_equal(cov[m], 1.0f, 0.0f);
    }
    for (unsigned ch = 0; ch < 3; ch++) {
        assert_float_equal(out[0][ch], out[1][ch], 0.0f);
        assert_float_equal(out[2][ch], out[1][ch], 0.0f);
    }
    /* on the boundary edge v = 0 with a wide footprint: Discard keeps part of the kernel */
    st_query edge = {0, 0.5f, 0.0f, 0.2f, 0, 0, 0.2f};
    st_sample_opts d = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_PTEX_BOX};
    assert_int_equal(st_sample_batch(s, &d, &edge, 1, out[0], &cov[0], NULL), 0);
    assert_true(cov[0] > 0.2f && cov[0] < 0.8f);
    /* across the shared edge u + v = 1, Traverse reads face 1: its result differs from
     * Discard's, which only reads face 0 */
    st_query diag = {0, 0.5f, 0.5f, 0.15f, 0, 0, 0.15f};
    st_sample_opts t = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_GAUSSIAN};
    assert_int_equal(st_sample_batch(s, &t, &diag, 1, out[1], &cov[1], NULL), 0);
    assert_int_equal(st_sample_batch(s, &d, &diag, 1, out[0], &cov[0], NULL), 0);
    assert_float_equal(cov[1], 1.0f, 0.0f);
    assert_true(cov[0] < 0.9f);
    assert_true(fabsf(out[1][0] - out[0][0]) + fabsf(out[1][1] - out[0][1]) > 1e-4f);
    /* far past a boundary edge nothing of a small kernel is left: zero coverage, or the
     * clamped point with ST_ZERO_CLAMP */
    st_query far = {0, 1.0f, 1.0f, 0, 0, 0, 0};
    st_set_free(s);
    s = two_triangles(32, ST_DT_F32, 1);
    s->faces[0].adjface[1] = -1; /* make edge 1 of face 0 a boundary */
    uint8_t st;
    assert_int_equal(st_sample_batch(s, &t, &far, 1, out[0], &cov[0], &st), 1);
    assert_int_equal(st, ST_Q_ZERO_COVERAGE);
    assert_true(isnan(out[0][0]));
    t.zero_rule = ST_ZERO_CLAMP;
    assert_int_equal(st_sample_batch(s, &t, &far, 1, out[0], &cov[0], &st), 0);
    assert_false(isnan(out[0][0]));
    assert_float_equal(cov[0], 0.0f, 0.0f);
    st_set_free(s);
}

/* Discard's values and statuses do not depend on whether the caller asks for coverage (the
 * whole kernel's weight, its denominator, is only summed when it does): queries in, near
 * and past the edges of both faces, footprints up to a third of the face, compared bit for
 * bit; and with coverage, some of them are cut by a boundary edge (coverage < 1). */
static void discard_values_do_not_depend_on_asking_for_coverage(void **state)
{
    (void)state;
    st_set *s = two_triangles(32, ST_DT_F32, 3);
    enum { N = 600 };
    st_query q[N];
    uint32_t seed = 11;
    for (size_t i = 0; i < N; i++) {
        seed = seed * 1103515245u + 12345u;
        float u = -0.1f + 1.2f * (float)((seed >> 8) & 1023) / 1023.0f;
        seed = seed * 1103515245u + 12345u;
        float v = -0.1f + 1.2f * (float)((seed >> 8) & 1023) / 1023.0f;
        float d = 0.002f + 0.3f * (float)(i % 17) / 16.0f;
        q[i] = (st_query){(uint32_t)(i & 1), u, v, d, 0.3f * d * (float)(i % 3), 0.0f, d};
    }
    static float with[N * 3], without[N * 3], cov[N];
    uint8_t st_with[N], st_without[N];
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_PTEX_GAUSSIAN};
    int r1 = st_sample_batch(s, &o, q, N, with, cov, st_with);
    int r2 = st_sample_batch(s, &o, q, N, without, NULL, st_without);
    assert_int_equal(r1, r2);
    assert_memory_equal(st_with, st_without, sizeof st_with);
    assert_memory_equal(with, without, sizeof with);
    size_t cut = 0;
    for (size_t i = 0; i < N; i++)
        cut += st_with[i] == ST_Q_OK && cov[i] < 1.0f;
    assert_true(cut > N / 20);
    st_set_free(s);
}

static void gpu_point_uses_the_footprint_level_and_the_rest_is_refused(void **state)
{
    (void)state;
    st_set *s = two_triangles(16, ST_DT_F32, 1);
    st_query q = {1, 0.3f, 0.2f, 0, 0, 0, 0};
    float a[3], b[3], cov;
    st_sample_opts gp = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_POINT};
    st_sample_opts pp = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_POINT};
    assert_int_equal(st_sample_batch(s, &gp, &q, 1, a, &cov, NULL), 0);
    assert_int_equal(st_sample_batch(s, &pp, &q, 1, b, NULL, NULL), 0);
    assert_memory_equal(a, b, sizeof a);
    assert_float_equal(cov, 1.0f, 0.0f);
    /* a footprint of 4 level-0 texels reads level 2 (4x4) */
    q.dudx = q.dvdy = 4.0f / 16.0f;
    assert_int_equal(st_sample_batch(s, &gp, &q, 1, a, NULL, NULL), 0);
    uint32_t x, y;
    st_tri_texel(4, q.u, q.v, &x, &y);
    const float *l2 = (const float *)(const void *)st_face_level(s, 1, 2);
    for (unsigned c = 0; c < 3; c++)
        assert_float_equal(a[c], l2[(y * 4 + x) * 3 + c], 0.0f);
    for (unsigned f = ST_FILTER_BILINEAR; f <= ST_FILTER_ANISO; f++) {
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = (uint8_t)f};
        assert_int_equal(st_sample_batch(s, &o, &q, 1, a, NULL, NULL), ST_EUNSUPPORTED);
    }
    st_set_free(s);
}

static void a_point_across_an_edge_lands_on_the_neighbours_side(void **state)
{
    (void)state;
    st_set *s = two_triangles(8, ST_DT_U8, 0);
    uint32_t g;
    float gu, gv;
    /* on the shared edge u + v = 1: face 1 is face 0 turned half a turn */
    assert_int_equal(st_uv_across_edge(s, 0, 1, 0.3f, 0.7f, &g, &gu, &gv), 0);
    assert_int_equal(g, 1);
    assert_float_equal(gu, 0.7f, 1e-6f);
    assert_float_equal(gv, 0.3f, 1e-6f);
    /* 0.1 past the edge: 0.1 inside the neighbour, and back again */
    assert_int_equal(st_uv_across_edge(s, 0, 1, 0.4f, 0.7f, &g, &gu, &gv), 0);
    assert_float_equal(1.0f - gu - gv, 0.1f, 1e-6f);
    float bu, bv;
    assert_int_equal(st_uv_across_edge(s, 1, 1, gu, gv, &g, &bu, &bv), 0);
    assert_int_equal(g, 0);
    assert_float_equal(bu, 0.4f, 1e-6f);
    assert_float_equal(bv, 0.7f, 1e-6f);
    /* boundary edges and the missing fourth edge have no neighbour */
    assert_int_equal(st_uv_across_edge(s, 0, 0, 0.5f, 0.0f, &g, &gu, &gv), -1);
    assert_int_equal(st_uv_across_edge(s, 0, 3, 0.0f, 0.5f, &g, &gu, &gv), -1);
    assert_int_equal(st_uv_across_corner(s, 0, 1, 1.0f, 0.0f, &g, &gu, &gv), -1);
    /* every rotation of the edge-id pair maps the edge onto itself, end for end */
    float p[3], q[3];
    for (unsigned e = 0; e < 3; e++)
        for (unsigned ae = 0; ae < 3; ae++) {
            /* the start corner of edge e (coordinate (e+2)%3 is 1) is the end of edge ae
             * (coordinate ae is 1) */
            memset(p, 0, sizeof p);
            p[(e + 2) % 3] = 1.0f;
            st_tri_across_edge(e, ae, p, q);
            assert_float_equal(q[ae], 1.0f, 0.0f);
            assert_float_equal(q[(ae + 1) % 3], 0.0f, 0.0f);
        }
    st_set_free(s);
}

static void triangle_sets_are_checked_and_bc1_refuses_them(void **state)
{
    (void)state;
    st_face_desc fd[1];
    memset(fd, 0, sizeof fd);
    fd[0].w = 8;
    fd[0].h = 4;
    for (int ed = 0; ed < 4; ed++)
        fd[0].adjface[ed] = -1;
    st_set_info info = {.nfaces = 1, .nchan = 1, .dtype = ST_DT_U8, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .meshtype = ST_MESH_TRIANGLE};
    st_set *s = NULL;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), ST_EADJ);
    assert_non_null(strstr(e.msg, "square"));
    fd[0].h = 8;
    fd[0].adjface[3] = 0;
    fd[0].adjedge[3] = 3;
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), ST_EADJ);
    fd[0].adjface[3] = -1;
    info.meshtype = 2;
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), ST_EINVAL);
    assert_null(s);
    /* a .ptx whose header says triangle but whose face is not square is refused */
    info.meshtype = ST_MESH_QUAD;
    fd[0].h = 4;
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    void *buf;
    size_t len;
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    st_set_free(s);
    ((uint8_t *)buf)[8] = 0; /* Ptex mesh type triangle */
    s = NULL;
    assert_int_equal(st_ptex_read_mem(buf, len, 0, &s, &e), ST_EFORMAT);
    assert_non_null(strstr(e.msg, "square"));
    assert_null(s);
    free(buf);
    s = two_triangles(8, ST_DT_U8, 1);
    st_set *out = NULL;
    assert_int_equal(st_bc1_compress_set(s, NULL, NULL, NULL, NULL, &out, &e), ST_EUNSUPPORTED);
    assert_non_null(strstr(e.msg, "triangle"));
    assert_null(out);
    st_set_free(s);
}

/* Clamp walks the band past a face's diagonal edge (ptextri_filter.c, row_band_t) instead of
 * folding each tap's centroid onto the face: the walk must read, tap by tap, the texel the
 * fold gives, in both sweeps, for every row the fold reaches and wherever a run of taps starts
 * (the sums of a row, walked and folded, the same bits on random texels). Every row of every
 * resolution up to 512 (each tap alone and the whole row, twice shifted), whole rows up to
 * 2048; all runs of rows of an 8 x 8 level. */
static void clamp_band_walk_reads_the_folded_texels(void **state)
{
    (void)state;
    enum { RMAX = 2048 };
    float *tex = malloc(sizeof(float) * RMAX * RMAX);
    assert_non_null(tex);
    uint32_t r = 12345u;
    for (size_t i = 0; i < (size_t)RMAX * RMAX; i++) {
        r = r * 1664525u + 1013904223u;
        tex[i] = (float)(r >> 8) * (1.0f / 16777216.0f) + 0.5f;
    }
    long checked = 0, bad = 0;
    for (int R = 2; R <= RMAX; R *= 2) {
        int far = 2 * R + 2; /* kernel bounds stay within 1 of a centre in [0, 1] */
        for (int odd = 0; odd < 2; odd++) {
            int ya = odd ? -far : 0, yb = odd ? R - 1 : far;
            for (int y = ya; y <= yb; y++) {
                /* the row's taps the fold reads: upright x >= max(0, R - y), inverted
                 * x <= min(R - 1, R - 1 - y) */
                int xa = odd ? -far : (R - y > 0 ? R - y : 0);
                int xb = odd ? (R - y < R ? R - y : R) : far + 1;
                for (int rec = 0; rec < 2; rec++) {
                    for (int s = 0; s < 3; s++) {
                        checked++;
                        bad += !st_ptextri_band_check(R, odd, y, xa + s, xb, tex, rec);
                    }
                    if (R > 512 || (R > 64 && rec))
                        continue;
                    for (int x = xa; x < xb; x++) {
                        checked++;
                        bad += !st_ptextri_band_check(R, odd, y, x, x + 1, tex, rec);
                    }
                    if (R != 8)
                        continue;
                    for (int a = xa; a < xb; a++)
                        for (int b = a + 2; b <= xb; b++) {
                            checked++;
                            bad += !st_ptextri_band_check(R, odd, y, a, b, tex, rec);
                        }
                }
            }
        }
    }
    free(tex);
    print_message("%ld runs of band taps checked, %ld differ\n", checked, bad);
    assert_true(checked > 100000);
    assert_int_equal(bad, 0);
}

/* Clamp's whole kernel at levels of 8 x 8 texels or more runs eight rows at a time, a row a
 * lane (ptextri_filter.c, rows_apply_t with fold_idx8): each lane must read, tap by tap, the
 * texel fold_tap gives (the per-tap build's fold). Every tap (x, y) with |x|, |y| <= 2R + 10
 * (kernel bounds stay within 1 of a centre in [0, 1], so the taps lie within 2R + 2), rows of
 * both orientations and mixed in one group, for R = 1 .. 1024 (every tap) and 2^15 (rows near
 * the face's corners and edges). */
static void clamp_fold_lanes_read_the_folded_texels(void **state)
{
    (void)state;
    static const unsigned masks[] = {0xffu, 0x00u, 0x0fu, 0xf0u, 0x55u};
    long checked = 0, bad = 0;
    for (int R = 1; R <= 1024; R *= 2) {
        int far = 2 * R + 10;
        for (size_t mi = 0; mi < sizeof masks / sizeof masks[0]; mi++) {
            if (R > 256 && mi > 1)
                continue;
            for (int y0 = -far; y0 <= far; y0 += 8) {
                int r = st_ptextri_fold_check(R, y0, -far + 7, 2 * far + 1, masks[mi]);
                assert_true(r >= 0);
                bad += r;
                checked += 8L * (2 * far + 1);
            }
        }
    }
    {
        const int R = 1 << 15, far = 2 * R + 10;
        static const int ys[] = {-far, -R, -9, -1, 0, R - 9, R - 1, R, 2 * R - 8, far - 8};
        for (size_t i = 0; i < sizeof ys / sizeof ys[0]; i++)
            for (int mi = 0; mi < 2; mi++) {
                int r = st_ptextri_fold_check(R, ys[i], -far + 7, 2 * far + 1, masks[mi]);
                assert_true(r >= 0);
                bad += r;
                checked += 8L * (2 * far + 1);
            }
    }
    print_message("%ld taps folded a lane checked against fold_tap, %ld differ\n", checked,
                  bad);
    assert_true(checked > 10000000);
    assert_int_equal(bad, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(triangle_filters_match_the_ptex_library),
        cmocka_unit_test(the_point_rule_picks_the_small_triangle_holding_uv),
        cmocka_unit_test(triangle_files_read_as_square_faces_with_three_edges),
        cmocka_unit_test(ptx_round_trip_is_bit_exact_and_a_fixed_point),
        cmocka_unit_test(native_set_file_keeps_triangle_sets),
        cmocka_unit_test(a_constant_texture_stays_constant_in_every_mode),
        cmocka_unit_test(discard_renormalises_at_boundaries_and_modes_agree_inside),
        cmocka_unit_test(discard_values_do_not_depend_on_asking_for_coverage),
        cmocka_unit_test(gpu_point_uses_the_footprint_level_and_the_rest_is_refused),
        cmocka_unit_test(a_point_across_an_edge_lands_on_the_neighbours_side),
        cmocka_unit_test(triangle_sets_are_checked_and_bc1_refuses_them),
        cmocka_unit_test(clamp_band_walk_reads_the_folded_texels),
        cmocka_unit_test(clamp_fold_lanes_read_the_folded_texels),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
