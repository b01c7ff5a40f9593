/* tests/unit/test_ptex_tanvec.c - Ptex's tanvec edge filter mode (docs/ptex.md section 6; docs/ptex-log.md,
 * "tv25"): in a set whose edge filter mode is tanvec, channels 0-1 are a tangent-space vector,
 * and what Traverse reads from a neighbour whose frame is turned against the query face's
 * (the kernel piece's quarter turns, adjedge) comes back with its vector turned the other way:
 * (x, y) -> (-y, x) per quarter turn. The other channels, Discard and Clamp, the point filter,
 * an unturned neighbour and a neighbour read at 1 x 1 (Ptex serves that as a constant, which
 * it never turns) are as without the mode; nor is a reduction Ptex serves as a constant face
 * turned (a stored tiled face whose tiles are all one constant, reduced until it fits in a
 * tile). The mode survives the Ptex writer and reader and the native set file. The GPU-style
 * filters' Traverse turns likewise (a 1 x 1 neighbour too), across edges and across corners
 * into the diagonal face.
 *
 * The check uses linearity instead of a second implementation: with the neighbour's texels
 * zeroed the filter gives Z = A / W (the query face's share), with them N = (A + B) / W; the
 * tanvec result must be Z + turn(N - Z) on channels 0-1 and N on channel 2. */
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
#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "sample.h"
#include "crc32c.h"
#include "ptexres.h"
#include "set.h"
#include "testdata.h"

/* Face 0 (8x8) and face 1 (8x8, or 1x1) side by side: face 0's right edge (1) meets face 1's
 * edge ae, so a kernel piece crossing it turns by 1 - ae + 2 quarter turns. 3 float channels:
 * face 0 holds (1, 0.5, 0.25) plus noise, face 1 a vector field (x, y, 0.75) (zero with
 * zero_nb). */
static st_set *pair(int ae, unsigned efm, int zero_nb, int nb1x1)
{
    st_face_desc fd[2];
    st_test_faces(fd, 2, 8, 8);
    fd[1].w = fd[1].h = nb1x1 ? 1 : 8;
    st_test_join(fd, 0, 1, 1, ae);
    st_set_info info = {.nfaces = 2, .nchan = 3, .dtype = ST_DT_F32, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .edgefilter = (uint8_t)efm};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    uint32_t r = 7;
    for (uint32_t f = 0; f < 2; f++) {
        float *p = (float *)st_face_level(s, f, 0);
        uint32_t w = s->faces[f].w, h = s->faces[f].h;
        for (uint32_t j = 0; j < h; j++)
            for (uint32_t i = 0; i < w; i++) {
                float *t = p + 3 * (j * w + i);
                r = r * 1103515245u + 12345u;
                float n = (float)((r >> 16) & 255) / 2048.0f;
                if (f == 0) {
                    t[0] = 1.0f + n, t[1] = 0.5f - n, t[2] = 0.25f + n;
                } else if (zero_nb) {
                    t[0] = t[1] = t[2] = 0.0f;
                } else {
                    t[0] = 0.3f + 0.1f * (float)i + n;
                    t[1] = -0.6f + 0.05f * (float)j;
                    t[2] = 0.75f - n;
                }
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    return s;
}

/* Queries near face 0's right edge (some near its corners too), footprints reaching into
 * face 1. */
enum { NQ = 24 };
static void queries(st_query *q)
{
    for (int i = 0; i < NQ; i++) {
        float w = 0.05f + 0.03f * (float)(i % 6);
        q[i] = (st_query){.face = 0, .u = 0.97f + 0.003f * (float)(i % 5),
                          .v = 0.04f + 0.92f * (float)(i % 7) / 6.0f, .dudx = w,
                          .dvdy = w * (1.0f + 0.5f * (float)(i % 3))};
    }
}

static void run(st_set *s, unsigned mode, unsigned filter, float *out)
{
    st_query q[NQ];
    queries(q);
    st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)filter};
    float cov[NQ];
    uint8_t st[NQ];
    assert_int_equal(st_ptexfilter_batch(s, &o, q, NQ, out, cov, st), 0);
}

/* The two sets give the same outputs, bit for bit, in this mode with this filter. */
static void same_outputs(st_set *a, st_set *b, unsigned mode, unsigned filter)
{
    float x[3 * NQ], y[3 * NQ];
    run(a, mode, filter, x);
    run(b, mode, filter, y);
    assert_memory_equal(x, y, sizeof x);
}

static void turn(int rot, float x, float y, float *ox, float *oy)
{
    switch (rot & 3) {
    case 1: *ox = -y, *oy = x; break;
    case 2: *ox = -x, *oy = -y; break;
    case 3: *ox = y, *oy = -x; break;
    default: *ox = x, *oy = y; break;
    }
}

static void turned_neighbours_turn_the_vector(void **state)
{
    (void)state;
    static const unsigned filters[] = {ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,
                                       ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC,
                                       ST_FILTER_PTEX_MITCHELL};
    for (int ae = 0; ae < 4; ae++) {
        int rot = (1 - ae + 2) & 3;
        st_set *none = pair(ae, ST_EDGEFILTER_NONE, 0, 0);
        st_set *zero = pair(ae, ST_EDGEFILTER_NONE, 1, 0);
        st_set *tv = pair(ae, ST_EDGEFILTER_TANVEC, 0, 0);
        for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++) {
            float n[3 * NQ], z[3 * NQ], t[3 * NQ];
            run(none, ST_MODE_TRAVERSE, filters[fi], n);
            run(zero, ST_MODE_TRAVERSE, filters[fi], z);
            run(tv, ST_MODE_TRAVERSE, filters[fi], t);
            int crossed = 0;
            for (int i = 0; i < NQ; i++) {
                float bx = n[3 * i] - z[3 * i], by = n[3 * i + 1] - z[3 * i + 1], ex, ey;
                if (fabsf(bx) + fabsf(by) > 1e-3f)
                    crossed++;
                turn(rot, bx, by, &ex, &ey);
                if (fabsf(t[3 * i] - (z[3 * i] + ex)) > 1e-5f ||
                    fabsf(t[3 * i + 1] - (z[3 * i + 1] + ey)) > 1e-5f)
                    fail_msg("ae %d rot %d filter %u query %d: tanvec (%g, %g), want (%g, %g) "
                             "(none (%g, %g))", ae, rot, filters[fi], i, t[3 * i],
                             t[3 * i + 1], z[3 * i] + ex, z[3 * i + 1] + ey, n[3 * i],
                             n[3 * i + 1]);
                assert_true(t[3 * i + 2] == n[3 * i + 2]); /* channel 2: not a vector */
                if (rot == 0) /* nothing turned: bit for bit the set without the mode */
                    assert_memory_equal(t + 3 * i, n + 3 * i, 3 * sizeof(float));
            }
            assert_true(crossed >= NQ / 2); /* the queries do read face 1 */
            /* Discard and Clamp read no neighbour; the point filter reads one texel of the
             * query face: all as without the mode */
            static const unsigned modes[] = {ST_MODE_DISCARD, ST_MODE_CLAMP};
            for (int m = 0; m < 2; m++)
                same_outputs(none, tv, modes[m], filters[fi]);
        }
        same_outputs(none, tv, ST_MODE_TRAVERSE, ST_FILTER_PTEX_POINT);
        st_set_free(none);
        st_set_free(zero);
        st_set_free(tv);
    }
}

/* A neighbour read at 1 x 1: Ptex hands the filter its constant value, which it adds without
 * turning (PtexSeparableFilter::apply's constant case); so the result is the set's without
 * the mode, bit for bit. */
static void one_texel_neighbour_is_not_turned(void **state)
{
    (void)state;
    for (int ae = 0; ae < 4; ae++) {
        st_set *none = pair(ae, ST_EDGEFILTER_NONE, 0, 1);
        st_set *tv = pair(ae, ST_EDGEFILTER_TANVEC, 0, 1);
        same_outputs(none, tv, ST_MODE_TRAVERSE, ST_FILTER_PTEX_GAUSSIAN);
        st_set_free(none);
        st_set_free(tv);
    }
}

/* The mode through the Ptex writer and reader, and through the native set file; a set
 * without it reads back none. */
static void mode_survives_the_writers(void **state)
{
    (void)state;
    for (unsigned efm = 0; efm < 2; efm++) {
        st_set *s = pair(2, efm, 0, 0);
        st_error e = {0};
        void *buf = NULL;
        size_t len = 0;
        assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
        st_set *r = NULL;
        assert_int_equal(st_ptex_read_mem(buf, len, 0, &r, &e), 0);
        free(buf);
        assert_int_equal(r->info.edgefilter, efm);
        st_set_free(r);
        char dir[512], path[600];
        assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "tanvec"), 0);
        snprintf(path, sizeof path, "%s/set.stx", dir);
        assert_int_equal(st_native_write(path, s, NULL, &e), 0);
        r = NULL;
        assert_int_equal(st_native_open(path, 0, NULL, &r, &e), 0);
        assert_int_equal(r->info.edgefilter, efm);
        st_set_free(r);
        st_test_rmtree(dir);
        st_set_free(s);
    }
}

/* The GPU-style filters (docs/sampler.md) in Traverse turn what they read in a turned
 * neighbour the same way: the linearity check of the Ptex filters, with a 1 x 1 neighbour
 * turned too (its texel is a vector in its frame; only Ptex's own filters leave a constant
 * unturned). Discard and Clamp read no neighbour: as without the mode. */
static void gpu_filters_turn_the_vector(void **state)
{
    (void)state;
    static const unsigned filters[] = {ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR,
                                       ST_FILTER_ANISO};
    for (int nb1x1 = 0; nb1x1 < 2; nb1x1++)
        for (int ae = 0; ae < 4; ae++) {
            int rot = (1 - ae + 2) & 3;
            st_set *none = pair(ae, ST_EDGEFILTER_NONE, 0, nb1x1);
            st_set *zero = pair(ae, ST_EDGEFILTER_NONE, 1, nb1x1);
            st_set *tv = pair(ae, ST_EDGEFILTER_TANVEC, 0, nb1x1);
            st_query q[NQ];
            queries(q);
            for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++)
                for (unsigned mode = 0; mode < 3; mode++) {
                    st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)filters[fi]};
                    float n[3 * NQ], z[3 * NQ], t[3 * NQ];
                    for (int i = 0; i < NQ; i++) /* the point filter reads past the edge only */
                        q[i].u = filters[fi] == ST_FILTER_POINT ? 1.0f + 0.002f * (float)(i % 9)
                                                                : 0.97f + 0.003f * (float)(i % 5);
                    assert_true(st_sample_batch(none, &o, q, NQ, n, NULL, NULL) >= 0);
                    assert_true(st_sample_batch(zero, &o, q, NQ, z, NULL, NULL) >= 0);
                    assert_true(st_sample_batch(tv, &o, q, NQ, t, NULL, NULL) >= 0);
                    if (mode != ST_MODE_TRAVERSE) {
                        assert_memory_equal(t, n, sizeof t);
                        continue;
                    }
                    int crossed = 0;
                    for (int i = 0; i < NQ; i++) {
                        float bx = n[3 * i] - z[3 * i], by = n[3 * i + 1] - z[3 * i + 1], ex, ey;
                        crossed += fabsf(bx) + fabsf(by) > 1e-3f;
                        turn(rot, bx, by, &ex, &ey);
                        if (fabsf(t[3 * i] - (z[3 * i] + ex)) > 1e-5f ||
                            fabsf(t[3 * i + 1] - (z[3 * i + 1] + ey)) > 1e-5f)
                            fail_msg("1x1 %d ae %d filter %u query %d: tanvec (%g, %g), want "
                                     "(%g, %g)", nb1x1, ae, filters[fi], i, t[3 * i],
                                     t[3 * i + 1], z[3 * i] + ex, z[3 * i + 1] + ey);
                        assert_true(t[3 * i + 2] == n[3 * i + 2]);
                        if (rot == 0)
                            assert_memory_equal(t + 3 * i, n + 3 * i, 3 * sizeof(float));
                    }
                    assert_true(crossed >= NQ / 3); /* the queries do read face 1 */
                }
            st_set_free(none);
            st_set_free(zero);
            st_set_free(tv);
        }
}

/* A 2 x 2 grid of faces around one interior vertex, each face's frame turned by its own
 * quarter turns r[f] against the world, holding one world vector V in its own frame (channel 2
 * varies). In the tanvec mode Traverse near the middle vertex - across both edges and the
 * corner into the diagonal face - must give back the query face's own vector, with every GPU
 * filter; without the mode it mixes the frames. */
static void constant_vector_field_stays_constant_across_edges_and_corners(void **state)
{
    (void)state;
    static const float V[2] = {0.6f, -0.35f};
    static const int rsets[4][4] = {{0, 1, 2, 3}, {3, 3, 1, 0}, {2, 0, 1, 1}, {1, 2, 3, 0}};
    static const unsigned filters[] = {ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR, ST_FILTER_ANISO};
    for (int rs = 0; rs < 4; rs++)
        for (unsigned efm = 0; efm < 2; efm++) {
            const int *r = rsets[rs];
            /* cell of face f: (f & 1, f >> 1); world edges 0 bottom, 1 right, 2 top, 3 left;
             * the face's edge k is world edge (k + r[f]) mod 4 */
            st_face_desc fd[4];
            memset(fd, 0, sizeof fd);
            for (int f = 0; f < 4; f++) {
                fd[f].w = fd[f].h = 8;
                for (int k = 0; k < 4; k++) {
                    int W = (k + r[f]) & 3;
                    int cx = (f & 1) + (W == 1) - (W == 3), cy = (f >> 1) + (W == 2) - (W == 0);
                    if (cx < 0 || cx > 1 || cy < 0 || cy > 1) {
                        fd[f].adjface[k] = -1;
                        continue;
                    }
                    int g = cx + 2 * cy;
                    fd[f].adjface[k] = g;
                    fd[f].adjedge[k] = (int8_t)((W + 2 - r[g]) & 3);
                }
            }
            st_set_info info = {.nfaces = 4, .nchan = 3, .dtype = ST_DT_F32, .alpha_chan = -1,
                                .kind = ST_KIND_PERFACE, .edgefilter = (uint8_t)efm};
            st_set *s;
            st_error e = {0};
            assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
            float L[4][2];
            for (int f = 0; f < 4; f++) {
                turn(-r[f], V[0], V[1], &L[f][0], &L[f][1]); /* V in face f's frame */
                float *p = (float *)st_face_level(s, (uint32_t)f, 0);
                for (int t = 0; t < 64; t++) {
                    p[3 * t] = L[f][0];
                    p[3 * t + 1] = L[f][1];
                    p[3 * t + 2] = 0.1f * (float)f + 0.001f * (float)t;
                }
            }
            st_set_build_mips(s, UINT32_MAX);
            int mixed = 0;
            for (int f = 0; f < 4; f++) {
                /* the middle vertex in face f's own (u, v): the corner at world (1, 1) */
                float cu = 0.0f, cv = 0.0f;
                for (int c = 0; c < 4; c++) {
                    /* corner c of a face is where its edges c and c - 1 meet; corner c points
                     * world-wards to the diagonal quadrant of world corner (c + r[f]) */
                    int Wc = (c + r[f]) & 3; /* world corner: 0 (-,-) 1 (+,-) 2 (+,+) 3 (-,+) */
                    int wx = (f & 1) + (Wc == 1 || Wc == 2), wy = (f >> 1) + (Wc >= 2);
                    if (wx == 1 && wy == 1) {
                        cu = (c == 1 || c == 2) ? 1.0f : 0.0f;
                        cv = (c >= 2) ? 1.0f : 0.0f;
                    }
                }
                for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++)
                    for (int k = 0; k < 9; k++) {
                        float du = (float)(k % 3 - 1) * 0.04f, dv = (float)(k / 3 - 1) * 0.04f;
                        st_query q = {.face = (uint32_t)f,
                                      .u = cu + (cu > 0.5f ? -0.03f : 0.03f) + du * 0.25f,
                                      .v = cv + (cv > 0.5f ? -0.03f : 0.03f) + dv * 0.25f,
                                      .dudx = 0.2f, .dvdy = 0.15f + 0.05f * (float)(k % 2)};
                        st_sample_opts o = {.mode = ST_MODE_TRAVERSE,
                                            .filter = (uint8_t)filters[fi]};
                        float out[3], cov;
                        assert_int_equal(st_sample_batch(s, &o, &q, 1, out, &cov, NULL), 0);
                        assert_float_equal(cov, 1.0f, 0.0f); /* every tap found a face */
                        float d = fabsf(out[0] - L[f][0]) + fabsf(out[1] - L[f][1]);
                        if (efm)
                            assert_true(d < 1e-5f);
                        else
                            mixed += d > 1e-2f;
                    }
            }
            st_set_free(s);
            if (!efm)
                assert_true(mixed > 0 || (r[0] == r[1] && r[1] == r[2] && r[2] == r[3]));
        }
}

/* Ptex serves a reduction it makes from a tiled face whose tiles are all one constant as a
 * constant face once it fits in one tile (PtexReader::TiledFaceBase::reduce), and does not
 * turn it. Face 1 (128 x 256 floats x 4) is a 2 x 2 checker: level 0 is tiled and varies,
 * its stored level 1 (64 x 128, 128 KiB: two 64 x 64 tiles) is one value, so the writer
 * stores its tiles as constant tiles. Face 0's right edge meets face 1's bottom edge (one
 * quarter turn). Resolution (6, 6) of face 1 is Ptex's v-reduction of level 1 to one tile: a
 * constant face, not turned; (5, 5) is the stored level 2: turned. */
static st_set *checker_pair(unsigned efm)
{
    st_face_desc fd[2];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 2; f++) {
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
        fd[f].w = 128;
        fd[f].h = 256;
    }
    fd[0].adjface[1] = 1;
    fd[0].adjedge[1] = 0;
    fd[1].adjface[0] = 0;
    fd[1].adjedge[0] = 1;
    st_set_info info = {.nfaces = 2, .nchan = 4, .dtype = ST_DT_F32, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE, .edgefilter = (uint8_t)efm};
    st_set *s, *r;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    static const float c0[4] = {0.25f, 0.75f, 0.5f, 0.5f}, c1[4] = {-0.5f, 0.0f, 1.0f, 0.5f};
    for (uint32_t f = 0; f < 2; f++) {
        float *p = (float *)st_face_level(s, f, 0);
        for (uint32_t j = 0; j < 256; j++)
            for (uint32_t i = 0; i < 128; i++) {
                float *t = p + 4 * (j * 128 + i);
                unsigned c = ((i & 1) << 1) | (j & 1);
                if (f == 0) {
                    t[0] = 0.1f + 0.001f * (float)i, t[1] = 0.3f + 0.002f * (float)j;
                    t[2] = 0.5f, t[3] = 0.25f * (float)((i + j) & 1);
                } else {
                    t[0] = c0[c], t[1] = c1[c], t[2] = 0.125f * (float)c, t[3] = 1.0f;
                }
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    void *buf;
    size_t len;
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    st_set_free(s);
    assert_int_equal(st_ptex_read_mem(buf, len, 0, &r, &e), 0);
    free(buf);
    return r;
}

static void constant_tiled_reduction_is_not_turned(void **state)
{
    (void)state;
    st_set *none = checker_pair(ST_EDGEFILTER_NONE), *tv = checker_pair(ST_EDGEFILTER_TANVEC);
    const st_ptexres *t = st_ptexres_get(tv);
    assert_non_null(t);
    /* face 1: (6, 6) and its reductions in u or v made from it: constant; level 0, the
     * stored levels and what is made from those: not */
    static const int want[][3] = {{6, 6, 1}, {6, 5, 1}, {6, 3, 1}, {6, 0, 1}, {0, 0, 1},
                                  {7, 8, 0}, {6, 7, 0}, {5, 6, 0}, {5, 5, 0}, {4, 6, 0},
                                  {7, 7, 0}, {3, 3, 0}};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++)
        if (st_ptexres_served_const(t, tv, 1, want[i][0], want[i][1]) != want[i][2])
            fail_msg("face 1 (%d, %d): served const %d, want %d", want[i][0], want[i][1],
                     !want[i][2], want[i][2]);
    assert_int_equal(st_ptexres_served_const(t, tv, 0, 6, 6), 0); /* face 0: no constant tiles */
    static const unsigned filters[] = {ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,
                                       ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC,
                                       ST_FILTER_PTEX_MITCHELL};
    /* near face 0's right edge at footprints 2^-6 (face 1 read at (6, 6): as without the
     * mode, bit for bit) and 2^-5 (read at the stored (5, 5): turned, so channels 0-1 differ) */
    /* the native copy (what the daemon serves from its data dir) keeps the list */
    char dir[512], path[600];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "tanvec-ct"), 0);
    snprintf(path, sizeof path, "%s/set.stx", dir);
    st_error e = {0};
    assert_int_equal(st_native_write(path, tv, NULL, &e), 0);
    st_set *nat = NULL;
    assert_int_equal(st_native_open(path, 0, NULL, &nat, &e), 0);
    const st_ptexres *tn = st_ptexres_get(nat);
    assert_non_null(tn);
    assert_int_equal(tn->nctiles, t->nctiles);
    assert_memory_equal(tn->ctiles, t->ctiles, t->nctiles * sizeof *t->ctiles);
    for (int k = 5; k <= 6; k++) {
        float w = 1.0f / (float)(1 << k);
        st_query q[4];
        for (int i = 0; i < 4; i++)
            q[i] = (st_query){.face = 0, .u = 1.0f - w * (0.25f + 0.25f * (float)i), .v = 0.5f,
                              .dudx = w, .dvdy = w};
        for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++) {
            st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = (uint8_t)filters[fi]};
            float n[16], v[16], cov[4];
            uint8_t st[4];
            assert_int_equal(st_ptexfilter_batch(none, &o, q, 4, n, cov, st), 0);
            assert_int_equal(st_ptexfilter_batch(tv, &o, q, 4, v, cov, st), 0);
            float nv[16];
            assert_int_equal(st_ptexfilter_batch(nat, &o, q, 4, nv, cov, st), 0);
            assert_memory_equal(nv, v, sizeof v);
            if (k == 6) {
                assert_memory_equal(v, n, sizeof n);
            } else {
                float d = 0.0f;
                for (int i = 0; i < 4; i++)
                    d += fabsf(v[4 * i] - n[4 * i]) + fabsf(v[4 * i + 1] - n[4 * i + 1]);
                if (!(d > 1e-3f))
                    fail_msg("filter %u: footprint 2^-5 not turned (%g)", filters[fi], d);
            }
        }
    }
    st_set_free(nat);
    /* a list entry out of range, its CRCs made right again (a crafted file): refused */
    FILE *fp = fopen(path, "r+b");
    assert_non_null(fp);
    uint8_t h[4096];
    assert_int_equal(fread(h, 1, sizeof h, fp), sizeof h);
    uint32_t nsec;
    memcpy(&nsec, h + 24, 4);
    int found = 0;
    for (uint32_t i = 0; i < nsec; i++) {
        uint8_t *ent = h + 1024 + 32 * i;
        uint32_t id;
        uint64_t off, size;
        memcpy(&id, ent, 4);
        memcpy(&off, ent + 8, 8);
        memcpy(&size, ent + 16, 8);
        if (id != 4)
            continue;
        uint8_t *sec = malloc(size);
        assert_non_null(sec);
        assert_int_equal(fseek(fp, (long)off, SEEK_SET), 0);
        assert_int_equal(fread(sec, 1, size, fp), size);
        size_t base = (size_t)tv->info.nfaces * (2 + st_texel_size(tv));
        assert_true(size == base + 4 + 8 * (size_t)t->nctiles);
        uint32_t bad = tv->info.nfaces; /* one past the last face */
        memcpy(sec + base + 4, &bad, 4);
        uint32_t crc = stu_crc32c(0, sec, size);
        memcpy(ent + 24, &crc, 4);
        assert_int_equal(fseek(fp, (long)off, SEEK_SET), 0);
        assert_int_equal(fwrite(sec, 1, size, fp), size);
        free(sec);
        found = 1;
    }
    assert_true(found);
    uint32_t hcrc = stu_crc32c(0, h, 4092);
    memcpy(h + 4092, &hcrc, 4);
    assert_int_equal(fseek(fp, 0, SEEK_SET), 0);
    assert_int_equal(fwrite(h, 1, sizeof h, fp), sizeof h);
    assert_int_equal(fclose(fp), 0);
    nat = NULL;
    assert_int_equal(st_native_open(path, 0, NULL, &nat, &e), ST_EFORMAT);
    assert_null(nat);
    assert_non_null(strstr(e.msg, "constant-tile"));
    st_test_rmtree(dir);
    st_set_free(none);
    st_set_free(tv);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(turned_neighbours_turn_the_vector),
        cmocka_unit_test(one_texel_neighbour_is_not_turned),
        cmocka_unit_test(mode_survives_the_writers),
        cmocka_unit_test(gpu_filters_turn_the_vector),
        cmocka_unit_test(constant_vector_field_stays_constant_across_edges_and_corners),
        cmocka_unit_test(constant_tiled_reduction_is_not_turned),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
