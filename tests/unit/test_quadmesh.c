/* tests/unit/test_quadmesh.c - building sets from quad meshes: adjacency from shared edges,
 * non-manifold and orientation errors, the cube generators and their frame rotations,
 * per-face sizes and baking at texel centres. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "quadmesh.h"

static void plain_cube_has_four_neighbours_per_face_and_valence_three(void **state)
{
    (void)state;
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(1, 0, &m, NULL), 0);
    assert_int_equal(m.nverts, 8);
    assert_int_equal(m.nquads, 6);
    st_quadmesh_opts o = {.nchan = 1, .dtype = ST_DT_U8, .ulog2 = 2, .vlog2 = 2};
    st_set *s;
    st_error e;
    assert_int_equal(st_quadmesh_build(&m, &o, &s, &e), 0); /* st_set_create checks symmetry */
    for (uint32_t f = 0; f < 6; f++)
        for (int k = 0; k < 4; k++) {
            assert_true(s->faces[f].adjface[k] >= 0 && s->faces[f].adjface[k] != (int32_t)f);
            assert_int_equal(s->faces[f].valence[k], 3);
            assert_int_equal(s->faces[f].cornerface[k], -1);
        }
    st_set_free(s);
    st_quadmesh_free(&m);
}

static void cube_faces_point_outward(void **state)
{
    (void)state;
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(3, 17, &m, NULL), 0);
    for (uint32_t f = 0; f < m.nquads; f++) {
        const float *p[4];
        for (int k = 0; k < 4; k++)
            p[k] = &m.pos[3 * m.quads[4 * f + k]];
        float a[3], b[3], n[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = p[1][k] - p[0][k];
            b[k] = p[3][k] - p[0][k];
            c[k] = (p[0][k] + p[2][k]) * 0.5f;
        }
        n[0] = a[1] * b[2] - a[2] * b[1];
        n[1] = a[2] * b[0] - a[0] * b[2];
        n[2] = a[0] * b[1] - a[1] * b[0];
        assert_true(n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0); /* counter-clockwise outside */
    }
    st_quadmesh_free(&m);
}

static void subdivided_rotated_cube_has_every_edge_rotation_and_regular_corners(void **state)
{
    (void)state;
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(4, 5, &m, NULL), 0);
    assert_int_equal(m.nquads, 96);
    assert_int_equal(m.nverts, 5 * 5 * 5 - 3 * 3 * 3);
    st_quadmesh_opts o = {.nchan = 1, .dtype = ST_DT_U8, .ulog2 = 2, .vlog2 = 2};
    st_set *s;
    assert_int_equal(st_quadmesh_build(&m, &o, &s, NULL), 0);
    int rot[4] = {0}, v3 = 0, v4 = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        for (unsigned k = 0; k < 4; k++) {
            rot[(s->faces[f].adjedge[k] - k + 4) & 3]++;
            if (s->faces[f].valence[k] == 3) {
                v3++;
            } else {
                assert_int_equal(s->faces[f].valence[k], 4);
                assert_true(s->faces[f].cornerface[k] >= 0);
                v4++;
            }
        }
    for (int r = 0; r < 4; r++)
        assert_true(rot[r] > 0);
    assert_int_equal(v3, 8 * 3); /* 8 cube corners, 3 faces each */
    assert_int_equal(v4, 96 * 4 - 24);
    /* unrotated: every shared edge inside a side has the opposite edge id */
    st_set_free(s);
    st_quadmesh_free(&m);
}

static void non_manifold_edge_is_refused_naming_edge_and_faces(void **state)
{
    (void)state;
    /* three quads on edge 0-1 */
    float pos[8 * 3] = {0};
    uint32_t quads[12] = {0, 1, 2, 3, 1, 0, 4, 5, 1, 0, 6, 7};
    st_quadmesh m = {.nverts = 8, .nquads = 3, .pos = pos, .quads = quads};
    st_face_desc fd[3];
    st_error e;
    assert_int_equal(st_quadmesh_adjacency(&m, fd, &e), ST_EADJ);
    assert_non_null(strstr(e.msg, "non-manifold"));
    assert_non_null(strstr(e.msg, "1-0"));
    assert_non_null(strstr(e.msg, "(0, 1, 2)"));
}

static void inconsistent_orientation_is_refused(void **state)
{
    (void)state;
    float pos[6 * 3] = {0};
    uint32_t quads[8] = {0, 1, 2, 3, 0, 1, 4, 5}; /* both run 0 -> 1 */
    st_quadmesh m = {.nverts = 6, .nquads = 2, .pos = pos, .quads = quads};
    st_face_desc fd[2];
    st_error e;
    assert_int_equal(st_quadmesh_adjacency(&m, fd, &e), ST_EADJ);
    assert_non_null(strstr(e.msg, "orientation"));
    assert_non_null(strstr(e.msg, "faces 0 and 1"));
    st_set *s;
    st_quadmesh_opts o = {.nchan = 1, .dtype = ST_DT_U8};
    assert_int_equal(st_quadmesh_build(&m, &o, &s, &e), ST_EADJ);
    assert_null(s);
}

static void bad_indices_and_degenerate_quads_are_refused(void **state)
{
    (void)state;
    float pos[4 * 3] = {0};
    uint32_t quads[4] = {0, 1, 2, 9};
    st_quadmesh m = {.nverts = 4, .nquads = 1, .pos = pos, .quads = quads};
    st_face_desc fd[1];
    st_error e;
    assert_int_equal(st_quadmesh_adjacency(&m, fd, &e), ST_EINVAL);
    assert_non_null(strstr(e.msg, "out of range"));
    quads[3] = 1;
    assert_int_equal(st_quadmesh_adjacency(&m, fd, &e), ST_EINVAL);
    assert_non_null(strstr(e.msg, "repeated"));
    m.nquads = 0;
    assert_int_equal(st_quadmesh_adjacency(&m, fd, &e), ST_ETOOBIG);
    st_quadmesh c;
    assert_int_equal(st_quadmesh_cube(0, 0, &c, &e), ST_EINVAL);
    assert_int_equal(st_quadmesh_cube(5000, 0, &c, &e), ST_EINVAL);
}

static void open_grid_has_boundaries(void **state)
{
    (void)state;
    float pos[9 * 3] = {0};
    uint32_t quads[16] = {0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7};
    st_quadmesh m = {.nverts = 9, .nquads = 4, .pos = pos, .quads = quads};
    st_face_desc fd[4];
    assert_int_equal(st_quadmesh_adjacency(&m, fd, NULL), 0);
    assert_int_equal(fd[0].adjface[0], -1);
    assert_int_equal(fd[0].adjface[3], -1);
    assert_int_equal(fd[0].adjface[1], 1);
    assert_int_equal(fd[0].adjedge[1], 3);
    assert_int_equal(fd[0].adjface[2], 2);
    assert_int_equal(fd[0].adjedge[2], 0);
}

typedef struct bake_check {
    unsigned calls;
} bake_check;

static void bake_position(void *user, uint32_t face, float u, float v, const float P[3],
                          float *out)
{
    (void)face;
    (void)u;
    (void)v;
    ((bake_check *)user)->calls++;
    out[0] = P[0];
    out[1] = P[1];
    out[2] = P[2];
}

static void bakes_the_bilinear_position_at_texel_centres(void **state)
{
    (void)state;
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(2, 9, &m, NULL), 0);
    bake_check bc = {0};
    st_quadmesh_opts o = {.nchan = 3, .dtype = ST_DT_F32, .ulog2 = 3, .vlog2 = 2,
                          .bake = bake_position, .user = &bc};
    st_set *s;
    assert_int_equal(st_quadmesh_build(&m, &o, &s, NULL), 0);
    assert_int_equal(bc.calls, 24 * 8 * 4);
    for (uint32_t f = 0; f < 24; f++) {
        const float *t = (const float *)st_face_level(s, f, 0);
        const uint32_t *q = &m.quads[4 * f];
        for (uint32_t j = 0; j < 4; j++)
            for (uint32_t i = 0; i < 8; i++) {
                float u = (i + 0.5f) / 8, v = (j + 0.5f) / 4;
                for (int k = 0; k < 3; k++) {
                    float P = (1 - u) * (1 - v) * m.pos[3 * q[0] + k] + u * (1 - v) * m.pos[3 * q[1] + k] +
                              u * v * m.pos[3 * q[2] + k] + (1 - u) * v * m.pos[3 * q[3] + k];
                    assert_true(fabsf(t[(j * 8 + i) * 3 + k] - P) < 1e-6f);
                }
            }
        /* the mip chain is built: the last level is the mean */
        const st_face *F = &s->faces[f];
        const float *last = (const float *)st_face_level(s, f, F->nlevels - 1);
        float mean = 0;
        for (int i = 0; i < 32; i++)
            mean += t[i * 3] / 32;
        assert_true(fabsf(last[0] - mean) < 1e-5f);
    }
    st_set_free(s);
    st_quadmesh_free(&m);
}

static void mixed_sizes_come_from_the_callback_deterministically(void **state)
{
    (void)state;
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(3, 2, &m, NULL), 0);
    st_quad_res_range r = {.seed = 42, .lo = 3, .hi = 6};
    st_quadmesh_opts o = {.nchan = 2, .dtype = ST_DT_U16, .res = st_quad_res_random, .user = &r};
    st_set *a, *b;
    assert_int_equal(st_quadmesh_build(&m, &o, &a, NULL), 0);
    assert_int_equal(st_quadmesh_build(&m, &o, &b, NULL), 0);
    int seen[16] = {0}, nonsquare = 0;
    for (uint32_t f = 0; f < a->info.nfaces; f++) {
        assert_true(a->faces[f].ulog2 >= 3 && a->faces[f].ulog2 <= 6);
        assert_true(a->faces[f].vlog2 >= 3 && a->faces[f].vlog2 <= 6);
        assert_int_equal(a->faces[f].w, b->faces[f].w);
        assert_int_equal(a->faces[f].h, b->faces[f].h);
        seen[a->faces[f].ulog2]++;
        nonsquare += a->faces[f].w != a->faces[f].h;
    }
    for (int l = 3; l <= 6; l++)
        assert_true(seen[l] > 0);
    assert_true(nonsquare > 0);
    st_set_free(a);
    st_set_free(b);
    /* a size over the cap is refused */
    r.hi = r.lo = 16;
    st_error e;
    assert_int_equal(st_quadmesh_build(&m, &o, &a, &e), ST_ETOOBIG);
    st_quadmesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(plain_cube_has_four_neighbours_per_face_and_valence_three),
        cmocka_unit_test(cube_faces_point_outward),
        cmocka_unit_test(subdivided_rotated_cube_has_every_edge_rotation_and_regular_corners),
        cmocka_unit_test(non_manifold_edge_is_refused_naming_edge_and_faces),
        cmocka_unit_test(inconsistent_orientation_is_refused),
        cmocka_unit_test(bad_indices_and_degenerate_quads_are_refused),
        cmocka_unit_test(open_grid_has_boundaries),
        cmocka_unit_test(bakes_the_bilinear_position_at_texel_centres),
        cmocka_unit_test(mixed_sizes_come_from_the_callback_deterministically),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
