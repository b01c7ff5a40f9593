/* tests/unit/test_ptex_tanvec.c - Ptex's tanvec edge filter mode (docs/ptex.md section 6; docs/ptex-log.md,
 * "tv25"): in a set whose edge filter mode is tanvec, channels 0-1 are a tangent-space vector,
 * and what Traverse reads from a neighbour whose frame is turned against the query face's
 * (the kernel piece's quarter turns, adjedge) comes back with its vector turned the other way:
 * (x, y) -> (-y, x) per quarter turn. The other channels, Discard and Clamp, the point filter,
 * an unturned neighbour and a neighbour read at 1 x 1 (Ptex serves that as a constant, which
 * it never turns) are as without the mode. The mode survives the Ptex writer and reader and
 * the native set file.
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

#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "set.h"
#include "testdata.h"

/* Face 0 (8x8) and face 1 (8x8, or 1x1) side by side: face 0's right edge (1) meets face 1's
 * edge ae, so a kernel piece crossing it turns by 1 - ae + 2 quarter turns. 3 float channels:
 * face 0 holds (1, 0.5, 0.25) plus noise, face 1 a vector field (x, y, 0.75) (zero with
 * zero_nb). */
static st_set *pair(int ae, unsigned efm, int zero_nb, int nb1x1)
{
    st_face_desc fd[2];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 2; f++)
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
    fd[0].w = fd[0].h = 8;
    fd[1].w = fd[1].h = nb1x1 ? 1 : 8;
    fd[0].adjface[1] = 1;
    fd[0].adjedge[1] = (int8_t)ae;
    fd[1].adjface[ae] = 0;
    fd[1].adjedge[ae] = 1;
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
            for (int m = 0; m < 2; m++) {
                run(none, modes[m], filters[fi], n);
                run(tv, modes[m], filters[fi], t);
                assert_memory_equal(t, n, sizeof t);
            }
        }
        float n[3 * NQ], t[3 * NQ];
        run(none, ST_MODE_TRAVERSE, ST_FILTER_PTEX_POINT, n);
        run(tv, ST_MODE_TRAVERSE, ST_FILTER_PTEX_POINT, t);
        assert_memory_equal(t, n, sizeof t);
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
        float n[3 * NQ], t[3 * NQ];
        run(none, ST_MODE_TRAVERSE, ST_FILTER_PTEX_GAUSSIAN, n);
        run(tv, ST_MODE_TRAVERSE, ST_FILTER_PTEX_GAUSSIAN, t);
        assert_memory_equal(t, n, sizeof t);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(turned_neighbours_turn_the_vector),
        cmocka_unit_test(one_texel_neighbour_is_not_turned),
        cmocka_unit_test(mode_survives_the_writers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
