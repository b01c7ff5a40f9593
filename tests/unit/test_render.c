/* tests/unit/test_render.c - seamtex-render's rasteriser and frame on cases with known answers:
 * the top-left rule (two triangles sharing a diagonal cover every sample exactly once, a
 * triangle covers the count of samples worked out by hand, an edge-on triangle none), a
 * full-screen quad on a constant face (every pixel the same colour), derivatives and shading
 * points of a tilted plane against a ray-cast of the same plane, the Mitchell-Netravali filter,
 * Traverse renders of generated cubes whose seams are no rougher than their interiors
 * (where Clamp's are), derivatives bounded where helper lanes pass a plane's horizon, and
 * queries the sampler refuses drawn magenta and counted.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "cube_fixture.h"
#include "ptex.h"
#include "ptx_fixture.h"
#include "render.h"

/* A camera at the origin looking down +z, focal 1, square image: a point (x, y, 1) lands on
 * pixel ((x * 0.5 + 0.5) * W, (0.5 - y * 0.5) * H). */
static rc_camera front_camera(void)
{
    rc_camera c = { .eye = { 0, 0, 0 }, .right = { 1, 0, 0 }, .up = { 0, 1, 0 },
                    .fwd = { 0, 0, 1 }, .focal = 1, .aspect = 1, .znear = 1e-3 };
    return c;
}

/* A mesh of one triangle from pixel coordinates on a W x W screen at depth 1. */
static rm_mesh *pixel_triangle(const double px[3][2], unsigned W)
{
    rm_mesh *m = calloc(1, sizeof *m);
    m->nverts = 3;
    m->ntris = 1;
    m->nfaces = 1;
    m->pos = calloc(9, sizeof(float));
    m->nrm = calloc(9, sizeof(float));
    m->tri = calloc(3, sizeof(uint32_t));
    m->uv = calloc(6, sizeof(float));
    m->face = calloc(1, sizeof(uint32_t));
    for (int k = 0; k < 3; k++) {
        m->pos[3 * k] = (float)((px[k][0] / W - 0.5) * 2);
        m->pos[3 * k + 1] = (float)((0.5 - px[k][1] / W) * 2);
        m->pos[3 * k + 2] = 1;
        m->nrm[3 * k + 2] = -1;
        m->tri[k] = (uint32_t)k;
    }
    return m;
}

static unsigned covered(const rr_target *t)
{
    unsigned n = 0;
    for (size_t i = 0; i < (size_t)t->width * t->height * t->nsamp; i++)
        n += t->owner[i] != UINT32_MAX;
    return n;
}

static unsigned count_tri(const double px[3][2], unsigned W, unsigned msaa)
{
    rm_mesh *m = pixel_triangle(px, W);
    rr_target t;
    char msg[256];
    assert_int_equal(rr_target_init(&t, W, W, msaa, msg, sizeof msg), 0);
    rc_camera cam = front_camera();
    assert_int_equal(rr_rasterise(&t, m, &cam, msg, sizeof msg), 0);
    unsigned n = covered(&t);
    rr_target_free(&t);
    rm_free(m);
    return n;
}

static void test_patterns(void **state)
{
    (void)state;
    const int8_t *p;
    assert_int_equal(rr_pattern(1, &p), 1);
    assert_int_equal(rr_pattern(2, &p), 2);
    assert_int_equal(rr_pattern(4, &p), 4);
    assert_int_equal(rr_pattern(8, &p), 8);
    assert_int_equal(rr_pattern(3, &p), 0);
    assert_int_equal(rr_pattern(16, &p), 0);
    /* D3D's 4x pattern is the rotated grid */
    rr_pattern(4, &p);
    int8_t want[8] = { -2, -6, 6, -2, -6, 2, 2, 6 };
    assert_memory_equal(p, want, 8);
}

static void test_top_left_rule_counts(void **state)
{
    (void)state;
    const unsigned W = 16;
    /* upper-left half: samples (i + .5, j + .5) with i + j < 15; the diagonal i + j = 15 lies
     * on the hypotenuse, a bottom-right edge, so it is not covered: 120 of 256 */
    const double a[3][2] = { { 0, 0 }, { 16, 0 }, { 0, 16 } };
    const double b[3][2] = { { 16, 0 }, { 16, 16 }, { 0, 16 } };
    assert_int_equal(count_tri(a, W, 1), 120);
    assert_int_equal(count_tri(b, W, 1), 136);
    /* the two halves at every rate: each sample exactly once, no gap, no overlap */
    for (unsigned msaa = 1; msaa <= 8; msaa *= 2)
        assert_int_equal(count_tri(a, W, msaa) + count_tri(b, W, msaa), W * W * msaa);
    /* the same triangle wound the other way covers the same samples */
    const double a2[3][2] = { { 0, 0 }, { 0, 16 }, { 16, 0 } };
    assert_int_equal(count_tri(a2, W, 1), 120);
    /* a thin sliver between x = 3.25 and 3.75 in rows 0..15 holds exactly the centres of
     * column 3: 16 samples at 1x */
    const double s[3][2] = { { 3.25, -100 }, { 3.75, 100 }, { 3.25, 100 } };
    const double s2[3][2] = { { 3.25, -100 }, { 3.75, -100 }, { 3.75, 100 } };
    assert_int_equal(count_tri(s, W, 1) + count_tri(s2, W, 1), 16);
    /* edge-on: three points on a line cover nothing, even through sample positions */
    const double e[3][2] = { { 0.5, 0.5 }, { 8.5, 8.5 }, { 15.5, 15.5 } };
    assert_int_equal(count_tri(e, W, 1), 0);
    assert_int_equal(count_tri(e, W, 8), 0);
}

static char tmpdir[64];

/* Writes a set as .ptx into the test's temp dir; returns the path (static buffer). */
static const char *write_ptx(const st_set *s, const char *name)
{
    static char path[128];
    snprintf(path, sizeof path, "%s/%s.ptx", tmpdir, name);
    st_error e;
    assert_int_equal(st_ptex_write_file(s, path, &e), 0);
    return path;
}

/* An in-process sampler of one 8 x 8 face of a single colour (200, 100, 50, 255), written as
 * a .ptx named after tag. */
static rs_sampler *constant_face_sampler(const char *tag, char *msg, size_t cap)
{
    st_set *set = st_fixture_rgba8_faces(8);
    assert_non_null(set);
    for (size_t i = 0; i < 8 * 8; i++) {
        uint8_t *t = st_face_level(set, 0, 0) + 4 * i;
        t[0] = 200, t[1] = 100, t[2] = 50, t[3] = 255;
    }
    st_set_build_mips(set, 0);
    const char *path = write_ptx(set, tag);
    st_set_free(set);
    return rs_inproc_new(path, NULL, msg, cap);
}

static void test_fullscreen_constant_face(void **state)
{
    (void)state;
    /* one quad beyond the screen's corners, facing the camera; its one face is constant */
    const float pos[12] = { -2, -2, 1, 2, -2, 1, 2, 2, 1, -2, 2, 1 };
    const uint32_t quad[4] = { 0, 1, 2, 3 };
    char msg[256];
    rm_mesh *m = rm_from_quads(pos, 4, quad, 1, msg, sizeof msg);
    assert_non_null(m);
    rs_sampler *s = constant_face_sampler("const", msg, sizeof msg);
    assert_non_null(s);
    rc_camera cam = front_camera();
    for (unsigned msaa = 1; msaa <= 8; msaa *= 2)
        for (unsigned mode = 0; mode < 3; mode++) {
            rf_opts o = { .width = 32, .height = 32, .msaa = msaa, .mode = mode, .filter = 3,
                          .max_aniso = 16, .bg = { 1, 0, 1 } };
            float rgb[32 * 32 * 3];
            rr_target t = { 0 };
            rs_stats st = { 0 };
            assert_int_equal(rf_render(m, &cam, &o, s, &t, rgb, NULL, &st, msg, sizeof msg), 0);
            assert_int_equal(covered(&t), 32 * 32 * msaa);   /* no background sample */
            if (msaa == 1)
                assert_int_equal(t.nfrag, 32 * 32);   /* one fragment per pixel */
            assert_true(t.nfrag >= 32 * 32);
            assert_int_equal(st.queries, t.nfrag);
            float light = t.frags[0].light;
            for (size_t i = 0; i < 32 * 32; i++) {
                assert_float_equal(rgb[3 * i], 200 / 255.0f * light, 1e-5);
                assert_float_equal(rgb[3 * i + 1], 100 / 255.0f * light, 1e-5);
                assert_float_equal(rgb[3 * i + 2], 50 / 255.0f * light, 1e-5);
            }
            rr_target_free(&t);
        }
    rs_free(s);
    rm_free(m);
}

/* Intersects the ray through pixel point (x, y) of a W x W front camera with the parallelogram
 * P0 + u (P1 - P0) + v (P3 - P0); returns (u, v). */
static void raycast_uv(const float P[4][3], unsigned W, double x, double y, double *u, double *v)
{
    double d[3] = { (x / W - 0.5) * 2, (0.5 - y / W) * 2, 1 };
    double a[3], b[3], o[3] = { P[0][0], P[0][1], P[0][2] };
    for (int k = 0; k < 3; k++) {
        a[k] = P[1][k] - P[0][k];
        b[k] = P[3][k] - P[0][k];
    }
    /* solve t d = o + u a + v b (Cramer on [d, -a, -b]) */
    double M[3][3], r[3];
    for (int k = 0; k < 3; k++) {
        M[k][0] = d[k];
        M[k][1] = -a[k];
        M[k][2] = -b[k];
        r[k] = o[k];
    }
    double det = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
                 M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                 M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
    double du = M[0][0] * (r[1] * M[2][2] - M[1][2] * r[2]) -
                r[0] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                M[0][2] * (M[1][0] * r[2] - r[1] * M[2][0]);
    double dv = M[0][0] * (M[1][1] * r[2] - r[1] * M[2][1]) -
                M[0][1] * (M[1][0] * r[2] - r[1] * M[2][0]) +
                r[0] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
    *u = du / det;
    *v = dv / det;
}

static void check_plane(const float P[4][3], unsigned W, double tol)
{
    const uint32_t quad[4] = { 0, 1, 2, 3 };
    char msg[256];
    rm_mesh *m = rm_from_quads(&P[0][0], 4, quad, 1, msg, sizeof msg);
    assert_non_null(m);
    rr_target t;
    assert_int_equal(rr_target_init(&t, W, W, 1, msg, sizeof msg), 0);
    rc_camera cam = front_camera();
    assert_int_equal(rr_rasterise(&t, m, &cam, msg, sizeof msg), 0);
    assert_true(t.nfrag > W * W / 8);
    for (size_t i = 0; i < t.nfrag; i++) {
        const stc_query *q = &t.queries[i];
        unsigned x = t.frags[i].pixel % W, y = t.frags[i].pixel / W;
        if (t.frags[i].centroid)
            continue;   /* a centroid shading point is checked by the edge-on tests */
        double u, v, u1, v1, u2, v2;
        raycast_uv(P, W, x + 0.5, y + 0.5, &u, &v);
        assert_float_equal(q->u, u, tol);
        assert_float_equal(q->v, v, tol);
        /* fine derivatives: the difference across the pixel's 2x2 quad row and column */
        unsigned qx = x & ~1u, qy = y & ~1u;
        raycast_uv(P, W, qx + 0.5, y + 0.5, &u1, &v1);
        raycast_uv(P, W, qx + 1.5, y + 0.5, &u2, &v2);
        assert_float_equal(q->dudx, u2 - u1, tol);
        assert_float_equal(q->dvdx, v2 - v1, tol);
        raycast_uv(P, W, x + 0.5, qy + 0.5, &u1, &v1);
        raycast_uv(P, W, x + 0.5, qy + 1.5, &u2, &v2);
        assert_float_equal(q->dudy, u2 - u1, tol);
        assert_float_equal(q->dvdy, v2 - v1, tol);
    }
    rr_target_free(&t);
    rm_free(m);
}

static void test_derivatives_planar(void **state)
{
    (void)state;
    /* facing the camera, the map is affine: du/dx = 1 / (quad width in pixels) exactly */
    const float flat[4][3] = { { -0.5f, 0.5f, 1 }, { 0.5f, 0.5f, 1 }, { 0.5f, -0.5f, 1 },
                               { -0.5f, -0.5f, 1 } };
    check_plane(flat, 64, 1e-6);
    char msg[256];
    const uint32_t quad[4] = { 0, 1, 2, 3 };
    rm_mesh *m = rm_from_quads(&flat[0][0], 4, quad, 1, msg, sizeof msg);
    rr_target t;
    assert_int_equal(rr_target_init(&t, 64, 64, 1, msg, sizeof msg), 0);
    rc_camera cam = front_camera();
    assert_int_equal(rr_rasterise(&t, m, &cam, msg, sizeof msg), 0);
    assert_int_equal(t.nfrag, 32 * 32);   /* the quad spans pixels 16..47 */
    for (size_t i = 0; i < t.nfrag; i++) {
        assert_float_equal(t.queries[i].dudx, 1.0 / 32, 1e-7);
        assert_float_equal(t.queries[i].dvdy, 1.0 / 32, 1e-7);   /* corner 3 (v = 1) is below */
        assert_float_equal(t.queries[i].dvdx, 0, 1e-7);
        assert_float_equal(t.queries[i].dudy, 0, 1e-7);
    }
    rr_target_free(&t);
    rm_free(m);
    /* tilted (depth 1..3 across, rotated in the image): perspective-correct values and the
     * finite differences of a ray-cast of the same plane */
    const float tilt[4][3] = { { -0.6f, 0.3f, 1.0f }, { 0.9f, 0.5f, 3.0f },
                               { 1.1f, -1.3f, 3.2f }, { -0.4f, -1.5f, 1.2f } };
    check_plane(tilt, 96, 2e-5);
}

static void test_centroid_when_centre_outside(void **state)
{
    (void)state;
    /* a triangle whose edge passes between a pixel's centre and two of its 4x samples: that
     * pixel's fragment is shaded at the centroid of the covered samples, inside the triangle */
    const double a[3][2] = { { 0, 0 }, { 16, 0 }, { 0, 8.45 } };
    rm_mesh *m = pixel_triangle(a, 16);
    for (int k = 0; k < 3; k++) {
        m->uv[2 * k] = (float)(a[k][0] / 16);
        m->uv[2 * k + 1] = (float)(a[k][1] / 16);
    }
    rr_target t;
    char msg[256];
    assert_int_equal(rr_target_init(&t, 16, 16, 4, msg, sizeof msg), 0);
    rc_camera cam = front_camera();
    assert_int_equal(rr_rasterise(&t, m, &cam, msg, sizeof msg), 0);
    unsigned ncentroid = 0;
    for (size_t i = 0; i < t.nfrag; i++) {
        const stc_query *q = &t.queries[i];
        /* uv = pixel position / 16 here: inside the triangle means x/16 / 1 + y/8.45 <= 1 */
        assert_true(q->u * 16 / 16.0 + q->v * 16 / 8.45 <= 1 + 1e-6);
        ncentroid += t.frags[i].centroid;
    }
    assert_true(ncentroid > 0);
    rr_target_free(&t);
    rm_free(m);
}

static void test_mitchell(void **state)
{
    (void)state;
    /* B = C = 1/3: k(0) = 8/9, k(1) = 1/18, k(2) = 0, and the shifted copies sum to 1 */
    assert_float_equal(rf_mitchell(0), 8.0 / 9, 1e-12);
    assert_float_equal(rf_mitchell(1), 1.0 / 18, 1e-12);
    assert_float_equal(rf_mitchell(2), 0, 1e-12);
    for (double x = 0; x < 1; x += 0.1) {
        double s = 0;
        for (int k = -3; k <= 3; k++)
            s += rf_mitchell(x + k);
        assert_float_equal(s, 1, 1e-12);
    }
    /* a constant image stays constant; a one-pixel-wide stripe spreads symmetrically */
    enum { w = 9, h = 5, ss = 4 };
    static float hi[w * ss * h * ss * 3], out[w * h * 3];
    for (size_t i = 0; i < sizeof hi / sizeof *hi; i++)
        hi[i] = 0.25f;
    assert_int_equal(rf_mitchell_down(hi, w, h, ss, out), 0);
    for (size_t i = 0; i < sizeof out / sizeof *out; i++)
        assert_float_equal(out[i], 0.25f, 1e-6);
    memset(hi, 0, sizeof hi);
    for (unsigned y = 0; y < h * ss; y++)
        for (unsigned x = 4 * ss; x < 5 * ss; x++)
            for (int c = 0; c < 3; c++)
                hi[3 * (y * w * ss + x) + c] = 1;
    assert_int_equal(rf_mitchell_down(hi, w, h, ss, out), 0);
    assert_true(out[3 * (2 * w + 4)] > 0.7f);
    assert_float_equal(out[3 * (2 * w + 3)], out[3 * (2 * w + 5)], 1e-6);
    assert_true(out[3 * (2 * w + 2)] < 0);   /* the negative lobe */
}

/* Largest colour step between 4-neighbour pixels both covered by the mesh, split by whether
 * their nearest triangles (1x target) lie on the same texture face or not. */
static void steps(const rr_target *t, const rm_mesh *m, const float *rgb, double *seam,
                  double *interior, unsigned *nseam)
{
    *seam = *interior = 0;
    *nseam = 0;
    for (unsigned y = 0; y + 1 < t->height; y++)
        for (unsigned x = 0; x + 1 < t->width; x++) {
            size_t p = (size_t)y * t->width + x;
            size_t nb[2] = { p + 1, p + t->width };
            if (t->owner[p] == UINT32_MAX)
                continue;
            for (int k = 0; k < 2; k++) {
                if (t->owner[nb[k]] == UINT32_MAX)
                    continue;
                double d = ri_pixel_dist(rgb, rgb, 0);   /* 0 */
                double dd[3];
                for (int c = 0; c < 3; c++)
                    dd[c] = rgb[3 * p + c] - rgb[3 * nb[k] + c];
                d = sqrt(dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]);
                if (m->face[t->owner[p]] != m->face[t->owner[nb[k]]]) {
                    (*nseam)++;
                    if (d > *seam)
                        *seam = d;
                } else if (d > *interior) {
                    *interior = d;
                }
            }
        }
}

static void test_traverse_cube_seams_smooth(void **state)
{
    (void)state;
    struct { unsigned n; uint32_t rot; uint8_t lo, hi; } cubes[] = {
        { 2, 0, 3, 3 },    /* 24 faces of 8x8 texels: magnified, seams show at once */
        { 3, 7, 3, 4 },    /* rotated frames, mixed sizes 8..16 */
    };
    for (size_t ci = 0; ci < sizeof cubes / sizeof *cubes; ci++) {
        cf_cube cube;
        assert_int_equal(cf_cube_build(&cube, cubes[ci].n, cubes[ci].rot, cubes[ci].lo,
                                       cubes[ci].hi, 11, ST_DT_U8, 4), 0);
        char msg[256], name[32];
        rm_mesh *m = rm_from_quads(cube.mesh.pos, cube.mesh.nverts, cube.mesh.quads,
                                   cube.mesh.nquads, msg, sizeof msg);
        assert_non_null(m);
        snprintf(name, sizeof name, "cube%zu", ci);
        rs_sampler *s = rs_inproc_new(write_ptx(cube.set, name), NULL, msg, sizeof msg);
        assert_non_null(s);
        rc_orbit orbit = { .frames = 8, .elev_deg = 30, .dist = 0.9, .fov_deg = 40 };
        for (unsigned f = 0; f < 8; f += 3) {
            rc_camera cam;
            rc_orbit_camera(&orbit, m, f, 160, 160, &cam);
            double seam[3], inner[3];
            unsigned nseam;
            for (unsigned mode = 0; mode < 3; mode++) {
                rf_opts o = { .width = 160, .height = 160, .msaa = 1, .mode = mode,
                              .filter = 3, .max_aniso = 16, .unlit = 1 };
                static float rgb[160 * 160 * 3];
                rr_target t = { 0 };
                rs_stats st = { 0 };
                assert_int_equal(rf_render(m, &cam, &o, s, &t, rgb, NULL, &st, msg, sizeof msg),
                                 0);
                steps(&t, m, rgb, &seam[mode], &inner[mode], &nseam);
                assert_true(nseam > 50);
                rr_target_free(&t);
            }
            printf("cube %zu frame %u: seam/interior D %.4f/%.4f T %.4f/%.4f C %.4f/%.4f\n", ci, f,
                   seam[0], inner[0], seam[1], inner[1], seam[2], inner[2]);
            /* Traverse: no seam step beyond the largest interior step */
            assert_true(seam[1] <= inner[1]);
            /* the test can fail: Clamp's seams are rougher than its interior (1.4-2.1x measured) */
            assert_true(seam[2] > 1.25 * inner[2]);
        }
        rs_free(s);
        rm_free(m);
        cf_cube_free(&cube);
    }
}

/* A ground plane seen at a grazing angle (elevation 0.2 degrees): the 2x2 quads along its far
 * edge have helper lanes past the plane's horizon, extrapolated to uv of 1e26 and more. The
 * queries' derivatives stay finite and within RR_MAX_DERIV (the sampler refuses a derivative
 * over 1e4 with NaN values, which came out as black pixels), the same at 1e3 and 1e-12 scale
 * (at 1e-12 the float derivatives overflowed to infinity), and every covered pixel is the
 * face's colour times the light: no NaN, no black, no refused query. */
static void test_horizon_derivatives_bounded(void **state)
{
    (void)state;
    char msg[256];
    rs_sampler *s = constant_face_sampler("ground", msg, sizeof msg);
    assert_non_null(s);
    const double scales[2] = { 1e3, 1e-12 };
    for (int k = 0; k < 2; k++) {
        float a = (float)scales[k];
        const float pos[12] = { -a, 0, -a, a, 0, -a, a, 0, a, -a, 0, a };
        const uint32_t quad[4] = { 0, 1, 2, 3 };
        rm_mesh *m = rm_from_quads(pos, 4, quad, 1, msg, sizeof msg);
        assert_non_null(m);
        rc_orbit orb = { .frames = 120, .elev_deg = 0.2, .dist = 0.8, .fov_deg = 40,
                         .azim0_deg = 30 };
        rc_camera cam;
        rc_orbit_camera(&orb, m, 0, 320, 240, &cam);
        rf_opts o = { .width = 320, .height = 240, .msaa = 4, .mode = 1, .filter = 3,
                      .max_aniso = 16, .unlit = 1, .bg = { 0, 0, 0 } };
        float *rgb = malloc(320 * 240 * 3 * sizeof *rgb);
        rr_target t = { 0 };
        rs_stats st = { 0 };
        assert_int_equal(rf_render(m, &cam, &o, s, &t, rgb, NULL, &st, msg, sizeof msg), 0);
        assert_true(t.nfrag > 100);
        for (size_t i = 0; i < t.nfrag; i++) {
            const stc_query *q = &t.queries[i];
            const float d[4] = { q->dudx, q->dvdx, q->dudy, q->dvdy };
            for (int j = 0; j < 4; j++)
                if (!(fabsf(d[j]) <= RR_MAX_DERIV))
                    fail_msg("scale %g: query %zu derivative %d is %g", scales[k], i, j,
                             (double)d[j]);
        }
        assert_int_equal(st.refused, 0);
        assert_true(t.clamped_derivs > 0);   /* the case is exercised */
        /* every query is answered with the face's colour, and no covered pixel is black */
        float *vals = malloc(t.nfrag * 4 * sizeof *vals);
        stc_sample_opts so = { .mode = 1, .filter = 3, .zero_rule = 1, .max_aniso = 16 };
        rs_stats ign = { 0 };
        assert_int_equal(s->sample(s, &so, t.queries, t.nfrag, vals, NULL, &ign, msg,
                                   sizeof msg), 0);
        for (size_t i = 0; i < t.nfrag; i++) {
            if (!(fabsf(vals[4 * i] - 200 / 255.0f) < 1e-4f &&
                  fabsf(vals[4 * i + 1] - 100 / 255.0f) < 1e-4f))
                fail_msg("scale %g: query %zu gave (%g, %g)", scales[k], i,
                         (double)vals[4 * i], (double)vals[4 * i + 1]);
            const float *px = rgb + 3 * t.frags[i].pixel;
            if (!(px[0] > 0.01f))
                fail_msg("scale %g: pixel %u is %g", scales[k], t.frags[i].pixel, (double)px[0]);
        }
        free(vals);
        rr_target_free(&t);
        free(rgb);
        rm_free(m);
    }
    rs_free(s);
}

/* An atlas mesh whose texture coordinates are 2e4 (tiling; the OBJ importer takes up to 1e6)
 * makes queries the sampler refuses (|u| over 1e4: BAD_FOOTPRINT, NaN values). They are counted
 * and drawn magenta: before, the NaN went through the resolve into a black PNG pixel, with
 * nothing said. */
static void test_refused_queries_counted_magenta(void **state)
{
    (void)state;
    char msg[256], png[128], obj[128];
    float img[4 * 4 * 3];
    for (size_t i = 0; i < 4 * 4 * 3; i++)
        img[i] = 0.5f;
    snprintf(png, sizeof png, "%s/grey.png", tmpdir);
    assert_int_equal(ri_write_png(png, img, 4, 4, msg, sizeof msg), 0);
    snprintf(obj, sizeof obj, "%s/tile.obj", tmpdir);
    FILE *f = fopen(obj, "w");
    assert_non_null(f);
    fprintf(f, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
               "vt 20000 0\nvt 20001 0\nvt 20001 1\nvt 20000 1\nf 1/1 2/2 3/3 4/4\n");
    assert_int_equal(fclose(f), 0);
    rm_mesh *m = rm_load_obj(obj, RM_ATLAS, msg, sizeof msg);
    assert_non_null(m);
    rs_sampler *s = rs_inproc_new(obj, png, msg, sizeof msg);
    if (!s)
        fail_msg("%s", msg);
    rc_orbit orb = { .frames = 120, .elev_deg = 25, .dist = 0.8, .fov_deg = 40, .azim0_deg = 30 };
    rc_camera cam;
    rc_orbit_camera(&orb, m, 0, 64, 48, &cam);
    rf_opts o = { .width = 64, .height = 48, .msaa = 1, .mode = 2, .filter = 3, .max_aniso = 16,
                  .unlit = 1, .bg = { 0, 0, 0 } };
    float rgb[64 * 48 * 3];
    rr_target t = { 0 };
    rs_stats st = { 0 };
    assert_int_equal(rf_render(m, &cam, &o, s, &t, rgb, NULL, &st, msg, sizeof msg), 0);
    assert_true(t.nfrag > 100);
    for (size_t i = 0; i < t.nfrag; i++) {
        const float *p = rgb + 3 * t.frags[i].pixel;
        if (!(fabsf(p[0] - 1) < 1e-6f && fabsf(p[1]) < 1e-6f && fabsf(p[2] - 1) < 1e-6f))
            fail_msg("pixel %u is (%g, %g, %g), not magenta", t.frags[i].pixel, (double)p[0],
                     (double)p[1], (double)p[2]);
    }
    assert_int_equal(st.refused, t.nfrag);
    rr_target_free(&t);
    rs_free(s);
    rm_free(m);
}

static int setup_dir(void **state)
{
    (void)state;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/test_render.XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown_dir(void **state)
{
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_patterns),
        cmocka_unit_test(test_top_left_rule_counts),
        cmocka_unit_test(test_fullscreen_constant_face),
        cmocka_unit_test(test_derivatives_planar),
        cmocka_unit_test(test_centroid_when_centre_outside),
        cmocka_unit_test(test_mitchell),
        cmocka_unit_test(test_traverse_cube_seams_smooth),
        cmocka_unit_test(test_horizon_derivatives_bounded),
        cmocka_unit_test(test_refused_queries_counted_magenta),
    };
    return cmocka_run_group_tests(tests, setup_dir, teardown_dir);
}
