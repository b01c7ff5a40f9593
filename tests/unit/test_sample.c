/* tests/unit/test_sample.c - the sampler on cube sets baked from a smooth 3D function: seams
 * under Traverse, Discard and Clamp, mode agreement in face interiors, renormalisation and
 * coverage, the zero-coverage rule, irregular corners, boundaries, mip selection, anisotropic
 * probes, texel types, BC1, bad queries and options. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "bc1_texel.h"
#include "../common/cube_fixture.h"
#include "defaultset.h"

static float maxf(float a, float b) { return a > b ? a : b; }

/* ---- seams ----------------------------------------------------------------------------- */

/* For every face, edge and a few points along the edge: the same point sampled from both
 * sides, bilinear at level 0. Returns the largest difference over all channels. */
static float seam_gap(const cf_cube *cb, unsigned mode, int *pairs)
{
    const st_set *s = cb->set;
    unsigned nc = s->info.nchan;
    float worst = 0;
    *pairs = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        for (unsigned e = 0; e < 4; e++)
            for (int k = 0; k < 7; k++) {
                float t = (k + 0.5f) / 7.0f, u, v;
                switch (e) {
                case 0: u = t; v = 0; break;
                case 1: u = 1; v = t; break;
                case 2: u = t; v = 1; break;
                default: u = 0; v = t; break;
                }
                uint32_t g;
                float gu, gv;
                assert_int_equal(st_uv_across_edge(s, f, e, u, v, &g, &gu, &gv), 0);
                st_query qa = cf_q(f, u, v), qb = cf_q(g, gu, gv);
                float a[4], b[4];
                assert_int_equal(cf_sample1(s, mode, ST_FILTER_BILINEAR, &qa, a, NULL), 0);
                assert_int_equal(cf_sample1(s, mode, ST_FILTER_BILINEAR, &qb, b, NULL), 0);
                for (unsigned c = 0; c < nc; c++)
                    worst = maxf(worst, fabsf(a[c] - b[c]));
                (*pairs)++;
            }
    return worst;
}

static void traverse_is_continuous_across_every_seam_and_clamp_is_not(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 4, 77, 5, 5, 0, ST_DT_F32, 3), 0);
    /* every edge rotation occurs */
    int rot[4] = {0};
    for (uint32_t f = 0; f < cb.set->info.nfaces; f++)
        for (unsigned e = 0; e < 4; e++)
            rot[(cb.set->faces[f].adjedge[e] - e + 4) & 3]++;
    for (int r = 0; r < 4; r++)
        assert_true(rot[r] > 0);
    int pairs;
    float gt = seam_gap(&cb, ST_MODE_TRAVERSE, &pairs);
    float gc = seam_gap(&cb, ST_MODE_CLAMP, &pairs);
    float gd = seam_gap(&cb, ST_MODE_DISCARD, &pairs);
    printf("# %d seam point pairs: traverse gap %.3g, clamp gap %.3g, discard gap %.3g\n", pairs,
           gt, gc, gd);
    assert_true(gt < 1e-5f);
    assert_true(gc > 1e-3f);
    assert_true(gd > 1e-3f);
    cf_cube_free(&cb);
}

/* The same point and footprint seen from both sides of every seam (the footprint carried
 * through the edge rotation, which is affine): trilinear and anisotropic Traverse agree too,
 * with probes reaching several texels across the seam. */
static void traverse_is_continuous_for_trilinear_and_aniso_footprints(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 3, 41, 5, 5, 0, ST_DT_F32, 3), 0);
    const st_set *s = cb.set;
    uint32_t rng = 8;
    float worst[2] = {0, 0}, clampw = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        for (unsigned e = 0; e < 4; e++)
            for (int k = 0; k < 6; k++) {
                float t = 0.25f + 0.5f * cf_rand(&rng), u, v;
                switch (e) {
                case 0: u = t; v = 0; break;
                case 1: u = 1; v = t; break;
                case 2: u = t; v = 1; break;
                default: u = 0; v = t; break;
                }
                float ang = 6.2831853f * cf_rand(&rng), major = 1.0f + 7.0f * cf_rand(&rng);
                st_query qa = {.face = f, .u = u, .v = v,
                               .dudx = major * cosf(ang) / 32, .dvdx = major * sinf(ang) / 32,
                               .dudy = -sinf(ang) / 32, .dvdy = cosf(ang) / 32};
                uint32_t g, g1, g2;
                float gu, gv, x1, y1, x2, y2;
                assert_int_equal(st_uv_across_edge(s, f, e, u, v, &g, &gu, &gv), 0);
                st_uv_across_edge(s, f, e, u + qa.dudx, v + qa.dvdx, &g1, &x1, &y1);
                st_uv_across_edge(s, f, e, u + qa.dudy, v + qa.dvdy, &g2, &x2, &y2);
                st_query qb = {.face = g, .u = gu, .v = gv, .dudx = x1 - gu, .dvdx = y1 - gv,
                               .dudy = x2 - gu, .dvdy = y2 - gv};
                for (int fi = 0; fi < 2; fi++) {
                    unsigned filter = fi ? ST_FILTER_ANISO : ST_FILTER_TRILINEAR;
                    float a[3], b[3];
                    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, filter, &qa, a, NULL), 0);
                    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, filter, &qb, b, NULL), 0);
                    for (int c = 0; c < 3; c++)
                        worst[fi] = maxf(worst[fi], fabsf(a[c] - b[c]));
                    assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, filter, &qa, a, NULL), 0);
                    assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, filter, &qb, b, NULL), 0);
                    for (int c = 0; c < 3; c++)
                        clampw = maxf(clampw, fabsf(a[c] - b[c]));
                }
            }
    printf("# trilinear gap %.3g, aniso gap %.3g (clamp %.3g)\n", worst[0], worst[1], clampw);
    assert_true(worst[0] < 1e-5f && worst[1] < 1e-5f);
    assert_true(clampw > 1e-3f);
    cf_cube_free(&cb);
}

static void traverse_is_continuous_on_a_plain_cube_with_rotated_frames(void **state)
{
    (void)state;
    for (uint32_t seed = 0; seed < 4; seed++) {
        cf_cube cb;
        assert_int_equal(cf_cube_build(&cb, 1, seed * 13, 4, 4, 0, ST_DT_F32, 1), 0);
        int pairs;
        assert_true(seam_gap(&cb, ST_MODE_TRAVERSE, &pairs) < 1e-5f);
        cf_cube_free(&cb);
    }
}

/* Error against the analytic function: near seams (the query within half a texel of an edge,
 * so one tap pair straddles the seam) and in face interiors. Seams between quads of the same
 * cube side are flat; seams on the cube's edges are folds (the 3D function has a kink along
 * the surface there, so any seamless reconstruction has an O(h) error at folds). */
typedef struct err_stats {
    float interior, flat, fold;
} err_stats;

static int on_fold(const cf_cube *cb, uint32_t f, float u, float v)
{
    float P[3];
    cf_point(&cb->mesh, f, u, v, P);
    int at = 0;
    for (int k = 0; k < 3; k++)
        at += fabsf(fabsf(P[k]) - 1.0f) < 1e-4f;
    return at >= 2;
}

static err_stats seam_errors(const cf_cube *cb, unsigned mode)
{
    const st_set *s = cb->set;
    unsigned nc = s->info.nchan;
    err_stats st = {0, 0, 0};
    uint32_t rng = 12345;
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        for (int k = 0; k < 40; k++) {
            float u, v, ex[4], got[4], P[3];
            int near = k >= 20;
            if (!near) {
                u = 0.25f + 0.5f * cf_rand(&rng);
                v = 0.25f + 0.5f * cf_rand(&rng);
            } else {
                float t = cf_rand(&rng), d = 0.5f * cf_rand(&rng);
                unsigned e = k & 3;
                u = e == 0 || e == 2 ? t : e == 1 ? 1 - d / F->w : d / F->w;
                v = e == 1 || e == 3 ? t : e == 2 ? 1 - d / F->h : d / F->h;
            }
            st_query q = cf_q(f, u, v);
            assert_int_equal(cf_sample1(s, mode, ST_FILTER_BILINEAR, &q, got, NULL), 0);
            cf_point(&cb->mesh, f, u, v, P);
            cf_smooth(P, nc, ex);
            float err = 0;
            for (unsigned c = 0; c < nc; c++)
                err = maxf(err, fabsf(got[c] - ex[c]));
            if (!near) {
                st.interior = maxf(st.interior, err);
            } else {
                unsigned e = k & 3;
                float eu = e == 1 ? 1 : e == 3 ? 0 : u, ev = e == 0 ? 0 : e == 2 ? 1 : v;
                float t = e & 1 ? v : u;
                if (on_fold(cb, f, eu, ev))
                    st.fold = maxf(st.fold, err);
                else if (t > 0.15f && t < 0.85f) /* away from the face's corners */
                    st.flat = maxf(st.flat, err);
            }
        }
    }
    return st;
}

static void traverse_error_near_seams_is_of_interior_order(void **state)
{
    (void)state;
    cf_cube cb;
    /* mixed resolutions 16..64 per axis, rotated frames */
    assert_int_equal(cf_cube_build(&cb, 4, 99, 4, 6, 5, ST_DT_F32, 3), 0);
    err_stats t = seam_errors(&cb, ST_MODE_TRAVERSE);
    err_stats c = seam_errors(&cb, ST_MODE_CLAMP);
    err_stats d = seam_errors(&cb, ST_MODE_DISCARD);
    printf("# max error vs analytic  interior / flat seams / cube-edge folds\n");
    printf("#   traverse %.2e %.2e %.2e\n", t.interior, t.flat, t.fold);
    printf("#   clamp    %.2e %.2e %.2e\n", c.interior, c.flat, c.fold);
    printf("#   discard  %.2e %.2e %.2e\n", d.interior, d.flat, d.fold);
    assert_true(t.interior == c.interior && t.interior == d.interior);
    /* flat seams, mixed sizes: the same order as the interior (second order) */
    assert_true(t.flat < 3 * t.interior);
    assert_true(t.flat < 0.5f * c.flat);
    assert_true(t.fold < c.fold);
    /* at mixed sizes the two sides of a seam differ a little (each side's own texels), far
     * less than under Clamp */
    int pairs;
    float gt = seam_gap(&cb, ST_MODE_TRAVERSE, &pairs), gc = seam_gap(&cb, ST_MODE_CLAMP, &pairs);
    printf("# mixed sizes, seam gap: traverse %.3g, clamp %.3g\n", gt, gc);
    assert_true(gt < 0.25f * gc);
    cf_cube_free(&cb);
}

static void modes_agree_exactly_in_face_interiors(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 3, 5, 4, 6, 9, ST_DT_F32, 4), 0);
    enum { N = 2000 };
    static st_query q[N];
    static float out[3][N * 4], cov[3][N];
    uint32_t rng = 7;
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)(cf_rand(&rng) * cb.set->info.nfaces);
        q[i].u = 0.3f + 0.4f * cf_rand(&rng);
        q[i].v = 0.3f + 0.4f * cf_rand(&rng);
        q[i].dudx = 0.02f * cf_rand(&rng);
        q[i].dvdx = 0.01f * cf_rand(&rng);
        q[i].dudy = -0.01f * cf_rand(&rng);
        q[i].dvdy = 0.03f * cf_rand(&rng);
    }
    for (unsigned filter = 0; filter <= ST_FILTER_ANISO; filter++) {
        for (unsigned m = 0; m < 3; m++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)filter};
            assert_int_equal(st_sample_batch(cb.set, &o, q, N, out[m], cov[m], NULL), 0);
        }
        assert_memory_equal(out[0], out[1], sizeof out[0]);
        assert_memory_equal(out[0], out[2], sizeof out[0]);
        for (int i = 0; i < N; i++)
            assert_true(cov[0][i] == 1.0f && cov[1][i] == 1.0f);
    }
    cf_cube_free(&cb);
}

/* ---- Discard ------------------------------------------------------------------------------ */

/* A cube whose faces are constant (one texel each), value 0.1 * (face + 1). */
static st_set *constant_cube(uint32_t w)
{
    st_quadmesh m;
    assert_int_equal(st_quadmesh_cube(1, 3, &m, NULL), 0);
    st_face_desc fd[6];
    memset(fd, 0, sizeof fd);
    assert_int_equal(st_quadmesh_adjacency(&m, fd, NULL), 0);
    for (int f = 0; f < 6; f++) {
        fd[f].w = fd[f].h = w;
        fd[f].flags = ST_FACE_CONSTANT;
    }
    st_set_info in = {.nfaces = 6, .nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    assert_int_equal(st_set_create(&in, fd, 0, &s, NULL), 0);
    for (int f = 0; f < 6; f++)
        *(float *)st_face_level(s, f, 0) = 0.1f * (f + 1);
    st_quadmesh_free(&m);
    return s;
}

static void discard_renormalises_and_coverage_falls_across_the_edge(void **state)
{
    (void)state;
    const uint32_t W = 16;
    st_set *s = constant_cube(W);
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_BILINEAR};
    float prev = 2.0f;
    /* Figure 7: from well inside to half a texel beyond the right edge */
    for (int k = 0; k <= 64; k++) {
        float u = 1.0f - 2.0f / W + k * (2.5f / W) / 64, out, cov;
        uint8_t st;
        st_query q = cf_q(2, u, 0.5f);
        int bad = st_sample_batch(s, &o, &q, 1, &out, &cov, &st);
        float x = u * W - 0.5f;
        float expect = x <= W - 1 ? 1.0f : x >= W ? 0.0f : W - x;
        assert_true(fabsf(cov - expect) < 1e-5f);
        assert_true(cov <= prev + 1e-6f);
        prev = cov;
        if (cov > 0) {
            assert_int_equal(bad, 0);
            assert_true(fabsf(out - 0.3f) < 1e-6f);
        } else {
            assert_int_equal(st, ST_Q_ZERO_COVERAGE);
            assert_true(isnan(out));
        }
    }
    /* at u = 1 exactly coverage is 1/2 */
    float out, cov;
    st_query q = cf_q(0, 1.0f, 0.5f);
    assert_int_equal(st_sample_batch(s, &o, &q, 1, &out, &cov, NULL), 0);
    assert_true(fabsf(cov - 0.5f) < 1e-6f);
    /* Figure 8: centre outside the face, but the mip footprint still reaches in */
    o.filter = ST_FILTER_TRILINEAR;
    q = cf_q(0, 1.0f + 1.0f / W, 0.5f);
    q.dudx = 4.0f / W;
    q.dvdy = 4.0f / W;
    assert_int_equal(st_sample_batch(s, &o, &q, 1, &out, &cov, NULL), 0);
    assert_true(cov > 0.0f && cov < 1.0f);
    assert_true(fabsf(out - 0.1f) < 1e-6f);
    st_set_free(s);
}

static void discard_at_the_edge_equals_clamp_on_a_textured_face(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 2, 0, 5, 5, 0, ST_DT_F32, 2), 0);
    for (uint32_t f = 0; f < cb.set->info.nfaces; f++) {
        float a[2], b[2], cov;
        st_query q = cf_q(f, 1.0f, 0.37f);
        assert_int_equal(cf_sample1(cb.set, ST_MODE_DISCARD, ST_FILTER_BILINEAR, &q, a, &cov), 0);
        assert_int_equal(cf_sample1(cb.set, ST_MODE_CLAMP, ST_FILTER_BILINEAR, &q, b, NULL), 0);
        assert_true(fabsf(cov - 0.5f) < 1e-6f);
        assert_true(fabsf(a[0] - b[0]) < 1e-6f && fabsf(a[1] - b[1]) < 1e-6f);
    }
    cf_cube_free(&cb);
}

static void zero_coverage_rule_nan_or_clamp(void **state)
{
    (void)state;
    st_set *s = constant_cube(8);
    st_query q = cf_q(4, 1.5f, -0.25f);
    float out = 0, cov = 1;
    uint8_t st = 9;
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_BILINEAR,
                        .zero_rule = ST_ZERO_NAN};
    assert_int_equal(st_sample_batch(s, &o, &q, 1, &out, &cov, &st), 1);
    assert_int_equal(st, ST_Q_ZERO_COVERAGE);
    assert_true(isnan(out));
    assert_true(cov == 0.0f);
    o.zero_rule = ST_ZERO_CLAMP;
    assert_int_equal(st_sample_batch(s, &o, &q, 1, &out, &cov, &st), 0);
    assert_int_equal(st, ST_Q_OK);
    assert_true(cov == 0.0f);
    assert_true(fabsf(out - 0.5f) < 1e-6f);
    st_set_free(s);
    /* on a textured face the clamp rule reads the face's corner texel region */
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 1, 0, 4, 4, 0, ST_DT_F32, 1), 0);
    float ref;
    st_query qc = cf_q(1, 1.0f, 0.0f);
    assert_int_equal(cf_sample1(cb.set, ST_MODE_CLAMP, ST_FILTER_BILINEAR, &qc, &ref, NULL), 0);
    q = cf_q(1, 3.0f, -2.0f);
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, &out, &cov, &st), 0);
    assert_true(cov == 0.0f && out == ref);
    cf_cube_free(&cb);
}

/* ---- corners and boundaries -------------------------------------------------------------- */

static void valence3_corner_gives_one_value_from_its_three_faces(void **state)
{
    (void)state;
    for (uint32_t seed = 0; seed < 3; seed++) {
        cf_cube cb;
        assert_int_equal(cf_cube_build(&cb, 1, seed * 7, 4, 4, 0, ST_DT_F32, 3), 0);
        for (uint32_t vert = 0; vert < cb.mesh.nverts; vert++) {
            uint32_t faces[8];
            unsigned corners[8];
            unsigned n = cf_faces_at_vertex(&cb.mesh, vert, faces, corners, 8);
            assert_int_equal(n, 3);
            float first[3];
            for (unsigned i = 0; i < n; i++) {
                static const float cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
                assert_int_equal(cb.set->faces[faces[i]].valence[corners[i]], 3);
                st_query q = cf_q(faces[i], cu[corners[i]], cv[corners[i]]);
                float out[3], cov;
                assert_int_equal(cf_sample1(cb.set, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q,
                                            out, &cov), 0);
                assert_true(fabsf(cov - 0.75f) < 1e-6f); /* the missing quadrant is dropped */
                if (i == 0)
                    memcpy(first, out, sizeof first);
                for (int c = 0; c < 3; c++)
                    assert_true(fabsf(out[c] - first[c]) < 1e-6f);
            }
        }
        cf_cube_free(&cb);
    }
}

static void valence4_corner_reads_the_diagonal_face(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 3, 31, 4, 4, 0, ST_DT_F32, 2), 0);
    int checked = 0;
    for (uint32_t vert = 0; vert < cb.mesh.nverts; vert++) {
        uint32_t faces[8];
        unsigned corners[8];
        unsigned n = cf_faces_at_vertex(&cb.mesh, vert, faces, corners, 8);
        if (n != 4)
            continue;
        float first[2];
        for (unsigned i = 0; i < n; i++) {
            static const float cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
            st_query q = cf_q(faces[i], cu[corners[i]], cv[corners[i]]);
            float out[2], cov;
            assert_int_equal(cf_sample1(cb.set, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, out,
                                        &cov), 0);
            assert_true(fabsf(cov - 1.0f) < 1e-6f);
            if (i == 0)
                memcpy(first, out, sizeof first);
            assert_true(fabsf(out[0] - first[0]) < 1e-5f && fabsf(out[1] - first[1]) < 1e-5f);
        }
        checked++;
    }
    assert_true(checked > 0);
    cf_cube_free(&cb);
}

/* Five quads around one interior vertex (valence 5): the corner quadrant has no single face,
 * its tap is dropped (coverage 3/4 at the vertex), the two edge taps come from the
 * neighbours. */
static void valence5_corner_drops_the_corner_quadrant(void **state)
{
    (void)state;
    float pos[11 * 3] = {0};
    uint32_t quads[5 * 4];
    for (int k = 0; k < 5; k++) {
        float a = 6.2831853f * k / 5, b = a + 6.2831853f / 10;
        pos[3 * (1 + k)] = cosf(a);
        pos[3 * (1 + k) + 1] = sinf(a);
        pos[3 * (6 + k)] = 1.3f * cosf(b);
        pos[3 * (6 + k) + 1] = 1.3f * sinf(b);
        quads[4 * k] = 0;
        quads[4 * k + 1] = (uint32_t)(1 + k);
        quads[4 * k + 2] = (uint32_t)(6 + k);
        quads[4 * k + 3] = (uint32_t)(1 + (k + 1) % 5);
    }
    st_quadmesh m = {.nverts = 11, .nquads = 5, .pos = pos, .quads = quads};
    unsigned nc = 1;
    st_quadmesh_opts o = {.nchan = 1, .dtype = ST_DT_F32, .ulog2 = 3, .vlog2 = 3,
                          .bake = cf_bake_smooth, .user = &nc};
    st_set *s;
    assert_int_equal(st_quadmesh_build(&m, &o, &s, NULL), 0);
    for (uint32_t f = 0; f < 5; f++) {
        assert_int_equal(s->faces[f].valence[0], 5);
        assert_int_equal(s->faces[f].cornerface[0], -1);
        float out, cov;
        st_query q = cf_q(f, 0.0f, 0.0f);
        assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
        assert_true(fabsf(cov - 0.75f) < 1e-6f);
        /* own corner texel and the two neighbours' texels at the vertex, 1/3 each */
        uint32_t g0 = (uint32_t)s->faces[f].adjface[0], g3 = (uint32_t)s->faces[f].adjface[3];
        float t0 = *(float *)st_face_level(s, f, 0);
        float ta, tb;
        st_query qa = cf_q(g0, 0.5f / 8, 0.5f / 8), qb = cf_q(g3, 0.5f / 8, 0.5f / 8);
        assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_POINT, &qa, &ta, NULL), 0);
        assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_POINT, &qb, &tb, NULL), 0);
        assert_true(fabsf(out - (t0 + ta + tb) / 3) < 1e-6f);
    }
    st_set_free(s);
}

/* A flat 2 x 2 grid of quads: 9 vertices, a boundary all around, one interior vertex. */
static void boundary_taps_are_dropped_and_renormalised(void **state)
{
    (void)state;
    float pos[9 * 3];
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            pos[3 * (3 * j + i) + 0] = (float)i;
            pos[3 * (3 * j + i) + 1] = (float)j;
            pos[3 * (3 * j + i) + 2] = 0;
        }
    uint32_t quads[16] = {0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7};
    st_quadmesh m = {.nverts = 9, .nquads = 4, .pos = pos, .quads = quads};
    unsigned nc = 1;
    st_quadmesh_opts o = {.nchan = 1, .dtype = ST_DT_F32, .ulog2 = 3, .vlog2 = 3,
                          .bake = cf_bake_smooth, .user = &nc};
    st_set *s;
    assert_int_equal(st_quadmesh_build(&m, &o, &s, NULL), 0);
    float out, cov, in0;
    /* boundary edge: half the taps have no face */
    st_query q = cf_q(0, 0.5f / 8, 0.0f);
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    assert_true(fabsf(cov - 0.5f) < 1e-6f);
    in0 = *(float *)st_face_level(s, 0, 0);
    assert_true(fabsf(out - in0) < 1e-6f); /* only texel (0,0) is left */
    /* boundary corner: one tap of four */
    q = cf_q(0, 0.0f, 0.0f);
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    assert_true(fabsf(cov - 0.25f) < 1e-6f);
    assert_true(fabsf(out - in0) < 1e-6f);
    /* a corner on the boundary but with a neighbour along one edge: 2 taps of 4 */
    q = cf_q(0, 1.0f, 0.0f);
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    assert_true(fabsf(cov - 0.5f) < 1e-6f);
    /* the interior vertex: full coverage, all four faces agree */
    static const uint32_t fc[4][2] = {{0, 2}, {1, 3}, {2, 1}, {3, 0}};
    float first = 0;
    for (int i = 0; i < 4; i++) {
        static const float cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
        q = cf_q(fc[i][0], cu[fc[i][1]], cv[fc[i][1]]);
        assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
        assert_true(fabsf(cov - 1.0f) < 1e-6f);
        if (!i)
            first = out;
        assert_true(fabsf(out - first) < 1e-6f);
    }
    /* beyond the boundary with no face anywhere: the zero-coverage rule applies */
    q = cf_q(0, -0.5f, -0.5f);
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov),
                     ST_Q_ZERO_COVERAGE);
    st_set_free(s);
}

/* ---- levels and probes ------------------------------------------------------------------- */

/* One 64 x 64 float face whose level L holds the value L everywhere. */
static st_set *level_face(void)
{
    st_face_desc fd = {.w = 64, .h = 64, .adjface = {-1, -1, -1, -1}};
    st_set_info in = {.nfaces = 1, .nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    assert_int_equal(st_set_create(&in, &fd, 0, &s, NULL), 0);
    for (unsigned l = 0; l < s->faces[0].nlevels; l++) {
        float *p = (float *)st_face_level(s, 0, l);
        size_t n = (size_t)st_level_w(&s->faces[0], l) * st_level_h(&s->faces[0], l);
        for (size_t i = 0; i < n; i++)
            p[i] = (float)l;
    }
    return s;
}

static float at_footprint(const st_set *s, unsigned filter, unsigned maxa, float dudx,
                          float dvdx, float dudy, float dvdy)
{
    st_query q = {.face = 0, .u = 0.5f, .v = 0.5f, .dudx = dudx / 64, .dvdx = dvdx / 64,
                  .dudy = dudy / 64, .dvdy = dvdy / 64};
    st_sample_opts o = {.mode = ST_MODE_CLAMP, .filter = (uint8_t)filter,
                        .max_aniso = (uint8_t)maxa};
    float out;
    assert_int_equal(st_sample_batch(s, &o, &q, 1, &out, NULL, NULL), 0);
    return out;
}

static void mip_level_follows_the_footprint(void **state)
{
    (void)state;
    st_set *s = level_face();
    /* nearest level: lod = log2(rho), level 0 up to lod 0.5, then ceil(lod + 0.5) - 1 */
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0) == 0.0f);
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 1, 0, 0, 1) == 0.0f);
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 1.41f, 0, 0, 1) == 0.0f);
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 1.5f, 0, 0, 1) == 1.0f);
    assert_true(at_footprint(s, ST_FILTER_POINT, 0, 0, 2, 0, 1) == 1.0f);
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 0, 0, 2.9f, 0) == 2.0f);
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 3, 4, 0, 0) == 2.0f); /* rho = 5 */
    assert_true(at_footprint(s, ST_FILTER_BILINEAR, 0, 1e3f, 0, 0, 0) == 6.0f); /* clamped */
    /* trilinear: the fraction of lod */
    assert_true(fabsf(at_footprint(s, ST_FILTER_TRILINEAR, 0, powf(2, 1.25f), 0, 0, 1) - 1.25f)
                < 1e-5f);
    assert_true(at_footprint(s, ST_FILTER_TRILINEAR, 0, 0.5f, 0, 0, 0.5f) == 0.0f);
    assert_true(at_footprint(s, ST_FILTER_TRILINEAR, 0, 500, 0, 0, 0) == 6.0f);
    /* aniso: N = min(ceil(Pmax/Pmin), max_aniso), lod = log2(Pmax / N) */
    assert_true(at_footprint(s, ST_FILTER_ANISO, 0, 8, 0, 0, 1) == 0.0f);
    assert_true(fabsf(at_footprint(s, ST_FILTER_ANISO, 8, 16, 0, 0, 1) - 1.0f) < 1e-6f);
    assert_true(at_footprint(s, ST_FILTER_ANISO, 16, 16, 0, 0, 1) == 0.0f);
    assert_true(fabsf(at_footprint(s, ST_FILTER_ANISO, 0, 0, 8, 0, 2) - 1.0f) < 1e-6f);
    /* isotropic footprint: aniso is trilinear */
    assert_true(fabsf(at_footprint(s, ST_FILTER_ANISO, 0, 3, 0, 0, 3) -
                      at_footprint(s, ST_FILTER_TRILINEAR, 0, 3, 0, 0, 3)) < 1e-6f);
    st_set_free(s);
}

static void aniso_probes_lie_along_the_major_axis(void **state)
{
    (void)state;
    st_face_desc fd = {.w = 128, .h = 128, .adjface = {-1, -1, -1, -1}};
    st_set_info in = {.nfaces = 1, .nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    assert_int_equal(st_set_create(&in, &fd, 0, &s, NULL), 0);
    float *p = (float *)st_face_level(s, 0, 0);
    uint32_t rng = 3;
    for (int i = 0; i < 128 * 128; i++)
        p[i] = cf_rand(&rng);
    st_set_build_mips(s, UINT32_MAX);
    /* major axes of 6 to 9 texels, minor below 1: N = ceil(Pmax/Pmin) probes at level 0 */
    static const float axes[3][4] = {{8, 4, -0.35f, 0.7f}, {0, 1, 6, 0}, {-5, 5, 0.45f, 0.5f}};
    for (int t = 0; t < 3; t++) {
        const float *A = axes[t];
        st_query q = {.face = 0, .u = 0.47f, .v = 0.52f, .dudx = A[0] / 128, .dvdx = A[1] / 128,
                      .dudy = A[2] / 128, .dvdy = A[3] / 128};
        float rx = hypotf(A[0], A[1]), ry = hypotf(A[2], A[3]);
        float pmax = fmaxf(rx, ry), pmin = fminf(rx, ry);
        unsigned N = (unsigned)ceilf(pmax / pmin);
        float mu = rx >= ry ? q.dudx : q.dudy, mv = rx >= ry ? q.dvdx : q.dvdy;
        assert_true(pmax / N <= 1.0f); /* level 0 only, so bilinear probes are the reference */
        float expect = 0;
        for (unsigned k = 0; k < N; k++) {
            float o = (k + 0.5f) / N - 0.5f, b;
            st_query pq = cf_q(0, q.u + o * mu, q.v + o * mv);
            assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_BILINEAR, &pq, &b, NULL), 0);
            expect += b / N;
        }
        float got;
        assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_ANISO, &q, &got, NULL), 0);
        assert_true(fabsf(got - expect) < 1e-5f);
        /* and differs from a single trilinear probe */
        float tri;
        assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_TRILINEAR, &q, &tri, NULL), 0);
        assert_true(fabsf(got - tri) > 1e-4f);
    }
    st_set_free(s);
}

static void traverse_reads_the_neighbour_at_its_matching_level(void **state)
{
    (void)state;
    /* two faces side by side: face 0 is 8 x 8 of value 1, face 1 is 32 x 32 whose level L holds
     * the value 10 + L; face 0's right edge is face 1's left edge */
    st_face_desc fd[2] = {
        {.w = 8, .h = 8, .adjface = {-1, 1, -1, -1}, .adjedge = {0, 3, 0, 0}},
        {.w = 32, .h = 32, .adjface = {-1, -1, -1, 0}, .adjedge = {0, 0, 0, 1}},
    };
    st_set_info in = {.nfaces = 2, .nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s;
    assert_int_equal(st_set_create(&in, fd, 0, &s, NULL), 0);
    for (int f = 0; f < 2; f++)
        for (unsigned l = 0; l < s->faces[f].nlevels; l++) {
            float *p = (float *)st_face_level(s, f, l);
            size_t n = (size_t)st_level_w(&s->faces[f], l) * st_level_h(&s->faces[f], l);
            for (size_t i = 0; i < n; i++)
                p[i] = f ? 10.0f + l : 1.0f;
        }
    float out, cov;
    /* a one-texel footprint on face 0 (8 wide) is 4 texels of face 1: its level 2 */
    st_query q = cf_q(0, 1.0f, 0.5f);
    q.dudx = q.dvdy = 1.0f / 8;
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    assert_true(fabsf(out - (0.5f * 1 + 0.5f * 12)) < 1e-6f);
    assert_true(cov == 1.0f);
    /* the other way: a one-texel footprint on face 1 is a quarter texel of face 0: level 0 */
    q = cf_q(1, 0.0f, 0.5f);
    q.dudx = q.dvdy = 1.0f / 32;
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    /* the outside tap's centre (depth 1/64) lies in face 0's border half-texel: face 0's
     * bilinear there takes its own outside tap (weight 0.375) back from face 1 */
    assert_true(fabsf(out - (0.5f * 10 + 0.5f * (0.375f * 10 + 0.625f * 1))) < 1e-6f);
    /* a zero footprint magnifies: level 0 on both sides */
    q = cf_q(0, 1.0f, 0.5f);
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, &q, &out, &cov), 0);
    assert_true(fabsf(out - (0.5f * 1 + 0.5f * 10)) < 1e-6f);
    /* trilinear between levels 0 and 1 of face 0 reads levels 2 and 3 of face 1 */
    q.dudx = q.dvdy = 1.5f / 8;
    assert_int_equal(cf_sample1(s, ST_MODE_TRAVERSE, ST_FILTER_TRILINEAR, &q, &out, &cov), 0);
    float t = log2f(1.5f);
    assert_true(fabsf(out - ((1 - t) * (0.5f + 0.5f * 12) + t * (0.5f + 0.5f * 13))) < 1e-5f);
    st_set_free(s);
}

/* ---- texel types, BC1 -------------------------------------------------------------------- */

static void every_texel_type_samples_to_float(void **state)
{
    (void)state;
    static const struct { st_dtype dt; float tol; } types[] = {
        {ST_DT_U8, 3.0f / 255}, {ST_DT_U16, 1e-4f}, {ST_DT_HALF, 2e-3f}, {ST_DT_F32, 0}};
    cf_cube ref;
    assert_int_equal(cf_cube_build(&ref, 2, 11, 4, 5, 2, ST_DT_F32, 4), 0);
    for (size_t t = 0; t < 3; t++) {
        for (unsigned nc = 1; nc <= 4; nc += 3) {
            cf_cube cb;
            assert_int_equal(cf_cube_build(&cb, 2, 11, 4, 5, 2, types[t].dt, nc), 0);
            uint32_t rng = 1;
            for (int i = 0; i < 500; i++) {
                st_query q = cf_q((uint32_t)(cf_rand(&rng) * 24), cf_rand(&rng) * 1.2f - 0.1f,
                                  cf_rand(&rng) * 1.2f - 0.1f);
                q.dudx = 0.05f * cf_rand(&rng);
                q.dvdy = 0.02f * cf_rand(&rng);
                for (unsigned f = 0; f <= ST_FILTER_ANISO; f++) {
                    float a[4], b[4];
                    /* beyond a cube corner (valence 3) there is no face: zero coverage */
                    int sa = cf_sample1(cb.set, ST_MODE_TRAVERSE, f, &q, a, NULL);
                    int sb = cf_sample1(ref.set, ST_MODE_TRAVERSE, f, &q, b, NULL);
                    assert_int_equal(sa, sb);
                    if (sa == ST_Q_ZERO_COVERAGE)
                        continue;
                    assert_int_equal(sa, 0);
                    for (unsigned c = 0; c < nc; c++)
                        assert_true(fabsf(a[c] - b[c]) <= types[t].tol);
                }
            }
            cf_cube_free(&cb);
        }
    }
    cf_cube_free(&ref);
}

static void bc1_texel_decodes_both_palette_modes(void **state)
{
    (void)state;
    /* c0 = pure red 0xF800 > c1 = pure blue 0x001F: four-colour mode */
    uint8_t blk[8] = {0x00, 0xF8, 0x1F, 0x00, 0, 0, 0, 0};
    blk[4] = 0 | (1 << 2) | (2 << 4) | (3 << 6); /* row 0: selectors 0,1,2,3 */
    uint8_t t[4];
    st_bc1_texel(blk, 0, 0, t);
    assert_true(t[0] == 255 && t[1] == 0 && t[2] == 0 && t[3] == 255);
    st_bc1_texel(blk, 1, 0, t);
    assert_true(t[0] == 0 && t[2] == 255);
    st_bc1_texel(blk, 2, 0, t);
    assert_true(t[0] == 170 && t[2] == 85 && t[3] == 255);
    st_bc1_texel(blk, 3, 0, t);
    assert_true(t[0] == 85 && t[2] == 170);
    st_bc1_texel(blk, 3, 3, t); /* selector 0 */
    assert_true(t[0] == 255);
    /* c0 <= c1: three colours + transparent black; green 6-bit replication */
    uint8_t b2[8] = {0x1F, 0x00, 0xE0, 0x07, 0, 0, 0, 0xC0 | 0x20}; /* blue, green */
    st_bc1_texel(b2, 3, 3, t);                                     /* selector 3 */
    assert_true(t[0] == 0 && t[1] == 0 && t[2] == 0 && t[3] == 0);
    st_bc1_texel(b2, 2, 3, t); /* selector 2: (blue + green) / 2 */
    assert_true(t[1] == 127 && t[2] == 127 && t[3] == 255);
    st_bc1_texel(b2, 1, 3, t); /* selector 0 */
    assert_true(t[2] == 255 && t[1] == 0);
}

static void bc1_set_is_sampled_as_rgba8(void **state)
{
    (void)state;
    st_face_desc fd = {.w = 8, .h = 4, .adjface = {-1, -1, -1, -1}};
    st_set_info in = {.nfaces = 1, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                      .kind = ST_KIND_BC1};
    st_set *s;
    assert_int_equal(st_set_create(&in, &fd, 0, &s, NULL), 0);
    uint8_t *lv = st_face_level(s, 0, 0); /* two blocks: red, then blue */
    uint8_t red[8] = {0x00, 0xF8, 0x00, 0xF8, 0, 0, 0, 0}, blue[8] = {0x1F, 0, 0x1F, 0, 0, 0, 0, 0};
    memcpy(lv, red, 8);
    memcpy(lv + 8, blue, 8);
    float out[4], cov;
    st_query q = cf_q(0, 0.3f / 8, 0.5f);
    assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_POINT, &q, out, &cov), 0);
    assert_true(out[0] == 1.0f && out[2] == 0.0f && out[3] == 1.0f);
    q = cf_q(0, 0.5f, 0.5f); /* between texel 3 (red) and 4 (blue) */
    assert_int_equal(cf_sample1(s, ST_MODE_CLAMP, ST_FILTER_BILINEAR, &q, out, &cov), 0);
    assert_true(fabsf(out[0] - 0.5f) < 1e-6f && fabsf(out[2] - 0.5f) < 1e-6f);
    st_set_free(s);
}

/* ---- bad input ---------------------------------------------------------------------------- */

static void bad_queries_get_a_status_not_undefined_behaviour(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 1, 0, 3, 3, 0, ST_DT_F32, 2), 0);
    st_query q[7] = {cf_q(6, 0.5f, 0.5f), cf_q(0, NAN, 0.5f), cf_q(0, 0.5f, INFINITY),
                     cf_q(0, 0.5f, 0.5f), cf_q(0, 2e4f, 0.5f), cf_q(0, 0.5f, 0.5f),
                     cf_q(UINT32_MAX, 0, 0)};
    q[3].dvdy = -INFINITY;
    q[5].dudx = 5e4f;
    float out[14], cov[7];
    uint8_t st[7];
    for (unsigned m = 0; m < 3; m++)
        for (unsigned f = 0; f <= ST_FILTER_ANISO; f++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)f};
            assert_int_equal(st_sample_batch(cb.set, &o, q, 7, out, cov, st), 7);
            static const uint8_t expect[7] = {ST_Q_BAD_FACE, ST_Q_NONFINITE, ST_Q_NONFINITE,
                                              ST_Q_NONFINITE, ST_Q_BAD_FOOTPRINT,
                                              ST_Q_BAD_FOOTPRINT, ST_Q_BAD_FACE};
            assert_memory_equal(st, expect, 7);
            for (int i = 0; i < 14; i++)
                assert_true(isnan(out[i]));
        }
    /* far outside but allowed: a valid (clamped) answer */
    st_query far = {.face = 0, .u = -9e3f, .v = 9e3f, .dudx = 9e3f, .dvdy = -9e3f};
    for (unsigned m = 0; m < 3; m++)
        for (unsigned f = 0; f <= ST_FILTER_ANISO; f++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)f,
                                .zero_rule = ST_ZERO_CLAMP};
            assert_int_equal(st_sample_batch(cb.set, &o, &far, 1, out, cov, st), 0);
            assert_false(isnan(out[0]));
        }
    cf_cube_free(&cb);
}

/* Random queries anywhere within the accepted ranges (and beyond), on mixed-size sets of every
 * texel type including constant and non-square faces: every status is defined, every OK
 * result is finite, every coverage is in [0, 1]. (Run under ASan/UBSan by `make asan`.) */
static void random_queries_give_finite_results_or_a_status(void **state)
{
    (void)state;
    uint32_t rng = 77;
    for (unsigned dt = 0; dt < 4; dt++) {
        cf_cube cb;
        assert_int_equal(cf_cube_build(&cb, 2, 3 + dt, 0, 7, dt, (st_dtype)dt, 1 + dt), 0);
        cb.set->faces[5].flags |= ST_FACE_CONSTANT; /* reads its first texel only */
        enum { N = 3000 };
        static st_query q[N];
        static float out[N * 4], cov[N];
        static uint8_t st[N];
        for (int i = 0; i < N; i++) {
            float scale = powf(10.0f, 5.0f * cf_rand(&rng) - 3.0f); /* 1e-3 .. 1e2 */
            q[i].face = (uint32_t)(cf_rand(&rng) * 26);             /* 24, 25: bad face */
            q[i].u = (cf_rand(&rng) - 0.5f) * 3 * (i % 50 ? 1 : 5000);
            q[i].v = (cf_rand(&rng) - 0.5f) * 3;
            q[i].dudx = (cf_rand(&rng) - 0.5f) * scale;
            q[i].dvdx = (cf_rand(&rng) - 0.5f) * scale * (i % 7 ? 1 : 0);
            q[i].dudy = (cf_rand(&rng) - 0.5f) * scale * (i % 5 ? 1 : 0);
            q[i].dvdy = (cf_rand(&rng) - 0.5f) * scale * (i % 3 ? 1 : 1e5f);
        }
        for (unsigned m = 0; m < 3; m++)
            for (unsigned f = 0; f <= ST_FILTER_ANISO; f++)
                for (unsigned z = 0; z < 2; z++) {
                    st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)f,
                                        .zero_rule = (uint8_t)z, .max_aniso = (uint8_t)(f * 4)};
                    int bad = st_sample_batch(cb.set, &o, q, N, out, cov, st);
                    assert_true(bad >= 0 && bad < N);
                    for (int i = 0; i < N; i++) {
                        assert_true(st[i] <= ST_Q_ZERO_COVERAGE);
                        assert_true(cov[i] >= 0.0f && cov[i] <= 1.0f);
                        if (st[i] == ST_Q_OK)
                            for (unsigned c = 0; c < cb.set->info.nchan; c++)
                                assert_true(isfinite(out[i * cb.set->info.nchan + c]));
                    }
                }
        cf_cube_free(&cb);
    }
}

static void bad_options_are_refused_before_writing(void **state)
{
    (void)state;
    cf_cube cb;
    assert_int_equal(cf_cube_build(&cb, 1, 0, 2, 2, 0, ST_DT_F32, 1), 0);
    st_query q = cf_q(0, 0.5f, 0.5f);
    float out = 42;
    st_sample_opts o = {.mode = 3};
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, &out, NULL, NULL), ST_EINVAL);
    o = (st_sample_opts){.filter = 5};
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, &out, NULL, NULL), ST_EINVAL);
    o = (st_sample_opts){.zero_rule = 2};
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, &out, NULL, NULL), ST_EINVAL);
    o = (st_sample_opts){.filter = ST_FILTER_ANISO, .max_aniso = 17};
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, &out, NULL, NULL), ST_EINVAL);
    o = (st_sample_opts){0};
    assert_int_equal(st_sample_batch(cb.set, &o, &q, 1, NULL, NULL, NULL), ST_EINVAL);
    assert_int_equal(st_sample_batch(cb.set, &o, NULL, 0, NULL, NULL, NULL), 0);
    assert_true(out == 42);
    cf_cube_free(&cb);
}

static void names_round_trip(void **state)
{
    (void)state;
    for (unsigned m = 0; m < 3; m++)
        assert_int_equal(st_mode_parse(st_mode_name(m)), (int)m);
    for (unsigned f = 0; f < 16; f++)
        if (st_filter_name(f))
            assert_int_equal(st_filter_parse(st_filter_name(f)), (int)f);
    assert_string_equal(st_filter_name(ST_FILTER_ANISO), "aniso");
    assert_null(st_mode_name(3));
    assert_int_equal(st_filter_parse("nope"), -1);
    assert_int_equal(st_mode_parse(NULL), -1);
}

static void default_set_is_deterministic_and_seamless(void **state)
{
    (void)state;
    st_set *a, *b;
    assert_int_equal(st_default_set(&a, NULL), 0);
    assert_int_equal(st_default_set(&b, NULL), 0);
    assert_int_equal(a->info.nfaces, 384);
    assert_int_equal(a->info.nchan, 4);
    assert_int_equal(a->texel_bytes, b->texel_bytes);
    assert_memory_equal(a->texels, b->texels, a->texel_bytes);
    int sizes[7] = {0};
    for (uint32_t f = 0; f < a->info.nfaces; f++) {
        assert_true(a->faces[f].w >= 16 && a->faces[f].w <= 64);
        assert_true(a->faces[f].h >= 16 && a->faces[f].h <= 64);
        sizes[a->faces[f].ulog2]++;
    }
    assert_true(sizes[4] && sizes[5] && sizes[6]);
    st_set_free(a);
    st_set_free(b);
}

/* The daemon serves the default set with every filter, the Ptex family included: in a face
 * interior, at level 0 and zero footprint, Ptex's bilinear equals the GPU-style bilinear. */
static void default_set_samples_with_the_ptex_filters(void **state)
{
    (void)state;
    st_set *s;
    assert_int_equal(st_default_set(&s, NULL), 0);
    st_query q[64];
    for (int i = 0; i < 64; i++)
        q[i] = (st_query){.face = (uint32_t)(i * 5) % s->info.nfaces,
                          .u = 0.25f + 0.5f * (float)(i % 8) / 8.0f,
                          .v = 0.25f + 0.5f * (float)(i / 8) / 8.0f};
    float gpu[64 * 4], ptx[64 * 4], cov[64];
    uint8_t st[64];
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_BILINEAR};
    assert_int_equal(st_sample_batch(s, &o, q, 64, gpu, cov, st), 0);
    o.filter = ST_FILTER_PTEX_BILINEAR;
    assert_int_equal(st_sample_batch(s, &o, q, 64, ptx, cov, st), 0);
    for (int i = 0; i < 64; i++) {
        assert_int_equal(st[i], ST_Q_OK);
        for (int c = 0; c < 4; c++)
            assert_float_equal(gpu[i * 4 + c], ptx[i * 4 + c], 1e-5);
    }
    o.filter = ST_FILTER_PTEX_GAUSSIAN;
    assert_int_equal(st_sample_batch(s, &o, q, 64, ptx, cov, st), 0);
    st_set_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(traverse_is_continuous_across_every_seam_and_clamp_is_not),
        cmocka_unit_test(traverse_is_continuous_for_trilinear_and_aniso_footprints),
        cmocka_unit_test(traverse_is_continuous_on_a_plain_cube_with_rotated_frames),
        cmocka_unit_test(traverse_error_near_seams_is_of_interior_order),
        cmocka_unit_test(modes_agree_exactly_in_face_interiors),
        cmocka_unit_test(discard_renormalises_and_coverage_falls_across_the_edge),
        cmocka_unit_test(discard_at_the_edge_equals_clamp_on_a_textured_face),
        cmocka_unit_test(zero_coverage_rule_nan_or_clamp),
        cmocka_unit_test(valence3_corner_gives_one_value_from_its_three_faces),
        cmocka_unit_test(valence4_corner_reads_the_diagonal_face),
        cmocka_unit_test(valence5_corner_drops_the_corner_quadrant),
        cmocka_unit_test(boundary_taps_are_dropped_and_renormalised),
        cmocka_unit_test(mip_level_follows_the_footprint),
        cmocka_unit_test(aniso_probes_lie_along_the_major_axis),
        cmocka_unit_test(traverse_reads_the_neighbour_at_its_matching_level),
        cmocka_unit_test(every_texel_type_samples_to_float),
        cmocka_unit_test(bc1_texel_decodes_both_palette_modes),
        cmocka_unit_test(bc1_set_is_sampled_as_rgba8),
        cmocka_unit_test(bad_queries_get_a_status_not_undefined_behaviour),
        cmocka_unit_test(random_queries_give_finite_results_or_a_status),
        cmocka_unit_test(bad_options_are_refused_before_writing),
        cmocka_unit_test(names_round_trip),
        cmocka_unit_test(default_set_is_deterministic_and_seamless),
        cmocka_unit_test(default_set_samples_with_the_ptex_filters),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
