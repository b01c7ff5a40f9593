/* tests/unit/test_cube.c - cube maps: face frames and adjacency, direction lookup, Traverse
 * continuity versus Clamp across every edge and corner of the shared environment maps,
 * lat-long versus cube agreement (with the Orientation maps), Castano's edge fixup, layout
 * round trips (strips, crosses), six-face and Ptex environment cube imports. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "bc1.h"
#include "cube.h"
#include "import.h"
#include "ptex.h"
#include "../common/testdata.h"
#include "image_io.h"
#include "cube_io.h"

static char tmpdir[256];

static int setup(void **state)
{
    (void)state;
    return st_test_mkdtemp(tmpdir, sizeof tmpdir, "test_cube");
}

static int teardown(void **state)
{
    (void)state;
    return st_test_rmtree(tmpdir);
}

static st_set *load(const char *rel, unsigned cube, uint32_t face_size)
{
    char path[1024];
    if (st_test_data_path(path, sizeof path, rel))
        return NULL;
    st_import_opts o;
    st_import_opts_init(&o);
    o.cube = (uint8_t)cube;
    o.face_size = face_size;
    st_set *s = NULL;
    st_error e;
    int rc = st_import_file(path, &o, &s, &e);
    if (rc)
        print_message("%s: %s\n", rel, e.msg);
    assert_int_equal(rc, ST_OK);
    assert_int_equal(s->info.kind, ST_KIND_CUBE);
    return s;
}

static void normalize(float d[3])
{
    float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; k++)
        d[k] /= l;
}

/* (u, v) at parameter t along edge e of a face, running from corner e to corner e+1 */
static void edge_point(unsigned e, float t, float *u, float *v)
{
    switch (e) {
    case 0: *u = t; *v = 0; break;
    case 1: *u = 1; *v = t; break;
    case 2: *u = 1 - t; *v = 1; break;
    default: *u = 0; *v = 1 - t; break;
    }
}

static void adjacency_matches_the_face_frames_and_corners_have_valence_3(void **state)
{
    (void)state;
    st_set_info in = {.nchan = 3, .dtype = ST_DT_U8, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, 8, 0, &s, &e), ST_OK);
    for (unsigned f = 0; f < 6; f++) {
        const st_face *F = &s->faces[f];
        for (unsigned ed = 0; ed < 4; ed++) {
            assert_int_equal(F->valence[ed], 3);
            unsigned g = (unsigned)F->adjface[ed], ge = F->adjedge[ed];
            for (int i = 0; i <= 8; i++) {
                float t = (float)i / 8.0f, u, v, a[3], b[3];
                edge_point(ed, t, &u, &v);
                st_cube_face_dir(f, u, v, a);
                /* consistent orientation: the neighbour runs the edge the other way */
                edge_point(ge, 1.0f - t, &u, &v);
                st_cube_face_dir(g, u, v, b);
                for (int k = 0; k < 3; k++)
                    assert_float_equal(a[k], b[k], 1e-6);
            }
        }
        /* du x dv points out of the cube */
        float c[3], du[3], dv[3];
        st_cube_face_dir(f, 0.5f, 0.5f, c);
        st_cube_face_dir(f, 1.0f, 0.5f, du);
        st_cube_face_dir(f, 0.5f, 1.0f, dv);
        for (int k = 0; k < 3; k++) {
            du[k] -= c[k];
            dv[k] -= c[k];
        }
        float n[3] = {du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2],
                      du[0] * dv[1] - du[1] * dv[0]};
        assert_true(n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0);
    }
    st_set_free(s);
}

static void directions_round_trip_through_face_and_uv(void **state)
{
    (void)state;
    uint32_t seed = 12345;
    for (int i = 0; i < 10000; i++) {
        float d[3];
        for (int k = 0; k < 3; k++) {
            seed = seed * 1664525u + 1013904223u;
            d[k] = (float)(seed >> 8) / (float)(1u << 24) * 2.0f - 1.0f;
        }
        float u, v, r[3];
        int f = st_cube_dir_to_face(d, &u, &v);
        assert_true(f >= 0 && f < 6);
        assert_true(u >= 0 && u <= 1 && v >= 0 && v <= 1);
        st_cube_face_dir((unsigned)f, u, v, r);
        normalize(d);
        normalize(r);
        for (int k = 0; k < 3; k++)
            assert_float_equal(d[k], r[k], 1e-5);
    }
    /* the OpenEXR face order: +X -X +Y -Y +Z -Z */
    const float ax[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int f = 0; f < 6; f++) {
        float u, v;
        assert_int_equal(st_cube_dir_to_face(ax[f], &u, &v), f);
        assert_float_equal(u, 0.5f, 1e-6);
        assert_float_equal(v, 0.5f, 1e-6);
    }
    float zero[3] = {0, 0, 0}, nan3[3] = {NAN, 0, 1}, u, v;
    assert_int_equal(st_cube_dir_to_face(zero, &u, &v), -1);
    assert_int_equal(st_cube_dir_to_face(nan3, &u, &v), -1);
}

static void footprints_from_derivatives_and_cones_follow_the_projection(void **state)
{
    (void)state;
    st_set_info in = {.nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, 64, 0, &s, &e), ST_OK);
    uint32_t seed = 4242;
    int checked = 0;
    for (int i = 0; i < 500; i++) {
        st_cube_query q;
        memset(&q, 0, sizeof q);
        for (int k = 0; k < 3; k++) {
            seed = seed * 1664525u + 1013904223u;
            q.dir[k] = (float)(seed >> 8) / (float)(1u << 24) * 2.0f - 1.0f;
            seed = seed * 1664525u + 1013904223u;
            q.ddx[k] = ((float)(seed >> 8) / (float)(1u << 24) - 0.5f) * 1e-3f;
            seed = seed * 1664525u + 1013904223u;
            q.ddy[k] = ((float)(seed >> 8) / (float)(1u << 24) - 0.5f) * 1e-3f;
        }
        st_query fq;
        uint8_t st;
        st_cube_queries(s, ST_CUBE_LOOKUP_PLAIN, &q, 1, &fq, &st);
        assert_int_equal(st, ST_Q_OK);
        /* central differences of the projection itself */
        float a[3], b[3], ua, va, ub, vb;
        for (int k = 0; k < 3; k++) {
            a[k] = q.dir[k] - q.ddx[k];
            b[k] = q.dir[k] + q.ddx[k];
        }
        int fa = st_cube_dir_to_face(a, &ua, &va), fb = st_cube_dir_to_face(b, &ub, &vb);
        if (fa != (int)fq.face || fb != (int)fq.face || ua <= 0 || ua >= 1 || ub <= 0 || ub >= 1 ||
            va <= 0 || va >= 1 || vb <= 0 || vb >= 1)
            continue; /* too close to an edge for a one-face difference */
        float scale = fmaxf(fabsf(fq.dudx), fabsf(fq.dvdx)) + 1e-6f;
        assert_float_equal((ub - ua) / 2.0f, fq.dudx, 0.02f * scale + 1e-6f);
        assert_float_equal((vb - va) / 2.0f, fq.dvdx, 0.02f * scale + 1e-6f);
        checked++;
    }
    assert_true(checked > 400);
    /* a cone of angle c at a face centre is c/2 in uv both ways; at the edge midpoint the
     * radial axis is stretched by r^2 = 2 and the tangential one by r = sqrt 2 */
    st_cube_query q;
    memset(&q, 0, sizeof q);
    q.dir[2] = 1;
    q.cone = 0.01f;
    st_query fq;
    uint8_t st;
    st_cube_queries(s, 0, &q, 1, &fq, &st);
    assert_float_equal(hypotf(fq.dudx, fq.dvdx), 0.005f, 1e-6);
    assert_float_equal(hypotf(fq.dudy, fq.dvdy), 0.005f, 1e-6);
    q.dir[0] = 0.999f;
    st_cube_queries(s, 0, &q, 1, &fq, &st);
    assert_float_equal(hypotf(fq.dudx, fq.dvdx), 0.005f * (1 + 0.999f * 0.999f), 1e-5);
    assert_float_equal(hypotf(fq.dudy, fq.dvdy), 0.005f * sqrtf(1 + 0.999f * 0.999f), 1e-5);
    q.cone = NAN;
    st_cube_queries(s, 0, &q, 1, &fq, &st);
    assert_int_equal(st, ST_Q_NONFINITE);
    /* a negative cone is neither a cone nor the derivatives of cone == 0: refused, not a
     * silent point lookup (with zero ddx / ddy as SAMPLE_DIR's cone form sends them) */
    q.cone = -0.01f;
    for (unsigned lookup = 0; lookup < 2; lookup++) {
        st_cube_queries(s, lookup, &q, 1, &fq, &st);
        assert_int_equal(st, ST_Q_BAD_FOOTPRINT);
    }
    st_sample_opts so;
    memset(&so, 0, sizeof so);
    so.filter = ST_FILTER_BILINEAR;
    float val;
    float cov = 1;
    assert_int_equal(st_cube_sample_dir(s, &so, 0, &q, 1, &val, &cov, &st), 1);
    assert_int_equal(st, ST_Q_BAD_FOOTPRINT);
    assert_true(isnan(val));
    assert_float_equal(cov, 0, 0);
    q.cone = -INFINITY;
    st_cube_queries(s, 0, &q, 1, &fq, &st);
    assert_int_equal(st, ST_Q_NONFINITE);
    st_set_free(s);
}

static void bad_directions_get_a_status_not_a_crash(void **state)
{
    (void)state;
    st_set_info in = {.nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, 4, 0, &s, &e), ST_OK);
    st_cube_query q[3];
    memset(q, 0, sizeof q);
    q[0].dir[0] = 1;
    q[1].dir[0] = NAN;
    q[2].dir[2] = INFINITY;
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.filter = ST_FILTER_BILINEAR;
    float out[3];
    uint8_t st[3];
    assert_int_equal(st_cube_sample_dir(s, &o, ST_CUBE_LOOKUP_PLAIN, q, 3, out, NULL, st), 2);
    assert_int_equal(st[0], ST_Q_OK);
    assert_int_equal(st[1], ST_Q_NONFINITE);
    assert_int_equal(st[2], ST_Q_NONFINITE);
    assert_true(isnan(out[1]));
    assert_int_equal(st_cube_sample_dir(NULL, &o, 0, q, 3, out, NULL, st), ST_EINVAL);
    st_set_free(s);
}

/* Mean |f(a) - f(b)| over directions a, b about 2 eps apart on both sides of every edge. */
static double edge_jump_eps(const st_set *s, unsigned mode, unsigned lookup, float cone, float eps)
{
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = (uint8_t)mode;
    o.filter = ST_FILTER_BILINEAR;
    enum { N = 64 };
    st_cube_query q[2 * N];
    float out[2 * N * 4];
    double acc = 0;
    int cnt = 0;
    unsigned nc = s->info.nchan;
    for (unsigned f = 0; f < 6; f++)
        for (unsigned ed = 0; ed < 4; ed++) {
            memset(q, 0, sizeof q);
            for (int i = 0; i < N; i++) {
                float u, v, d[3], c[3];
                edge_point(ed, ((float)i + 0.5f) / N, &u, &v);
                st_cube_face_dir(f, u, v, d);
                st_cube_face_dir(f, 0.5f, 0.5f, c);
                for (int k = 0; k < 3; k++) {
                    float dd = d[k] - c[k];
                    q[2 * i].dir[k] = d[k] - eps * dd;
                    q[2 * i + 1].dir[k] = d[k] + eps * dd;
                }
                q[2 * i].cone = q[2 * i + 1].cone = cone;
            }
            assert_int_equal(st_cube_sample_dir(s, &o, lookup, q, 2 * N, out, NULL, NULL), 0);
            for (int i = 0; i < N; i++)
                for (unsigned c = 0; c < 3 && c < nc; c++) {
                    acc += fabs(out[2 * i * nc + c] - out[(2 * i + 1) * nc + c]);
                    cnt++;
                }
        }
    return acc / cnt;
}

static double edge_jump(const st_set *s, unsigned mode, unsigned lookup, float cone)
{
    return edge_jump_eps(s, mode, lookup, cone, 1e-4f);
}

/* Directions near each of the 8 corners, one in each of the 3 faces, all within a tiny cone:
 * mean spread (max - min) of the samples. */
static double corner_spread(const st_set *s, unsigned mode, float cone)
{
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = (uint8_t)mode;
    o.filter = ST_FILTER_BILINEAR;
    double acc = 0;
    int cnt = 0;
    unsigned nc = s->info.nchan;
    for (int c = 0; c < 8; c++) {
        float corner[3] = {c & 1 ? 1.0f : -1.0f, c & 2 ? 1.0f : -1.0f, c & 4 ? 1.0f : -1.0f};
        st_cube_query q[3];
        memset(q, 0, sizeof q);
        for (int a = 0; a < 3; a++) {
            for (int k = 0; k < 3; k++)
                q[a].dir[k] = corner[k] * (k == a ? 1.0f : 1.0f - 2e-4f);
            q[a].cone = cone;
        }
        float out[12];
        assert_int_equal(st_cube_sample_dir(s, &o, 0, q, 3, out, NULL, NULL), 0);
        for (unsigned ch = 0; ch < 3; ch++) {
            float lo = out[ch], hi = out[ch];
            for (int a = 1; a < 3; a++) {
                lo = fminf(lo, out[a * nc + ch]);
                hi = fmaxf(hi, out[a * nc + ch]);
            }
            acc += hi - lo;
            cnt++;
        }
    }
    return acc / cnt;
}

static void traverse_is_continuous_across_every_edge_and_corner_and_clamp_is_not(void **state)
{
    (void)state;
    const struct { const char *rel; unsigned cube; } maps[] = {
        {"env/WavyLinesCube.exr", 0}, {"env/StageEnvCube.exr", 0},
        {"env/WavyLinesLatLong.exr", ST_IMPORT_CUBE_LATLONG},
        {"env/StageEnvLatLong.exr", ST_IMPORT_CUBE_LATLONG}};
    for (int m = 0; m < 4; m++) {
        st_set *s = load(maps[m].rel, maps[m].cube, 256);
        if (!s)
            skip();
        float n = (float)s->faces[0].w;
        /* footprints of about 1 and 4 texels (levels ~0..1 and ~2..3 near the edges) */
        for (int l = 0; l <= 2; l += 2) {
            float cone = exp2f((float)l) * 2.0f / n;
            /* continuity: the jump between two directions on both sides of an edge shrinks
             * with their distance (Traverse); a seam keeps it (Clamp) */
            double tr = edge_jump_eps(s, ST_MODE_TRAVERSE, 0, cone, 1e-4f);
            double tr2 = edge_jump_eps(s, ST_MODE_TRAVERSE, 0, cone, 1e-5f);
            double cl = edge_jump_eps(s, ST_MODE_CLAMP, 0, cone, 1e-4f);
            double cl2 = edge_jump_eps(s, ST_MODE_CLAMP, 0, cone, 1e-5f);
            double ctr = corner_spread(s, ST_MODE_TRAVERSE, cone);
            double ccl = corner_spread(s, ST_MODE_CLAMP, cone);
            print_message("%-26s %-8s cone %.4f: edge jump at 1e-4 / 1e-5: traverse %.5f / %.6f,"
                          " clamp %.5f / %.5f; corner spread traverse %.5f clamp %.5f\n",
                          maps[m].rel, maps[m].cube ? "latlong" : "cube", cone, tr, tr2, cl, cl2,
                          ctr, ccl);
            assert_true(tr2 < 0.3 * tr + 1e-6);
            assert_true(cl2 > 0.7 * cl);
            assert_true(cl2 > 20.0 * tr2);
            assert_true(ctr < ccl);
        }
        st_set_free(s);
    }
}

/* Relative mean difference between two cube sets sampled at random directions that stay
 * `margin` texels away from any cube edge. */
static double cube_agreement(const st_set *a, unsigned la, unsigned ma, const st_set *b,
                             unsigned lb, unsigned mb, int mirror_b, float margin)
{
    enum { N = 3000 };
    static st_cube_query qa[N], qb[N];
    static float oa[N * 4], ob[N * 4];
    uint32_t seed = 777;
    int k = 0;
    float lim = 1.0f - 2.0f * margin / (float)a->faces[0].w;
    while (k < N) {
        float d[3], u, v;
        for (int c = 0; c < 3; c++) {
            seed = seed * 1664525u + 1013904223u;
            d[c] = (float)(seed >> 8) / (float)(1u << 24) * 2.0f - 1.0f;
        }
        if (st_cube_dir_to_face(d, &u, &v) < 0 || fabsf(2 * u - 1) > lim || fabsf(2 * v - 1) > lim)
            continue;
        memset(&qa[k], 0, sizeof qa[k]);
        memcpy(qa[k].dir, d, sizeof d);
        qa[k].cone = 1e-5f;
        qb[k] = qa[k];
        if (mirror_b)
            qb[k].dir[0] = -qb[k].dir[0];
        k++;
    }
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.filter = ST_FILTER_BILINEAR;
    o.mode = (uint8_t)ma;
    assert_int_equal(st_cube_sample_dir(a, &o, la, qa, N, oa, NULL, NULL), 0);
    o.mode = (uint8_t)mb;
    assert_int_equal(st_cube_sample_dir(b, &o, lb, qb, N, ob, NULL, NULL), 0);
    double diff = 0, mag = 0;
    unsigned na = a->info.nchan, nb = b->info.nchan;
    for (int i = 0; i < N; i++)
        for (unsigned c = 0; c < 3; c++) {
            diff += fabs(oa[i * na + c] - ob[i * nb + c]);
            mag += fabs(oa[i * na + c]);
        }
    return diff / (mag > 0 ? mag : 1);
}

static void latlong_and_cube_versions_of_a_scene_agree_away_from_seams(void **state)
{
    (void)state;
    /* Tolerance: mean relative difference below 6% over 3000 directions at least 2 texels
     * from any cube edge, sampled bilinearly at level 0. The cube files follow OpenEXR's
     * convention (pixel centres 0 and n-1 on the edges), so they are looked up with the
     * edge-fixup lookup. A mirrored lookup (x -> -x) is the control that the test can fail. */
    const char *pairs[3][2] = {{"env/StageEnvLatLong.exr", "env/StageEnvCube.exr"},
                               {"env/WavyLinesLatLong.exr", "env/WavyLinesCube.exr"},
                               {"env/OrientationLatLong.exr", "env/OrientationCube.exr"}};
    for (int p = 0; p < 3; p++) {
        st_set *cube = load(pairs[p][1], 0, 0);
        if (!cube)
            skip();
        st_set *ll = load(pairs[p][0], ST_IMPORT_CUBE_LATLONG, cube->faces[0].w);
        double good = cube_agreement(ll, 0, ST_MODE_TRAVERSE, cube, ST_CUBE_LOOKUP_FIXUP,
                                     ST_MODE_CLAMP, 0, 2.0f);
        double plain = cube_agreement(ll, 0, ST_MODE_TRAVERSE, cube, 0, ST_MODE_TRAVERSE, 0, 2.0f);
        double mirrored = cube_agreement(ll, 0, ST_MODE_TRAVERSE, cube, ST_CUBE_LOOKUP_FIXUP,
                                         ST_MODE_CLAMP, 1, 2.0f);
        print_message("%-28s vs %-24s rel. diff: fixup lookup %.4f, plain %.4f, mirrored %.4f\n",
                      pairs[p][0], pairs[p][1], good, plain, mirrored);
        assert_true(good < 0.06);
        assert_true(mirrored > 3.0 * good);
        st_set_free(ll);
        st_set_free(cube);
    }
}

static void castano_fixup_scales_the_minor_components(void **state)
{
    (void)state;
    float d[3] = {0.5f, -1.0f, 0.25f}, o[3];
    st_cube_fixup_dir(d, 8, 0, o);
    assert_float_equal(o[0], 0.5f * 7.0f / 8.0f, 1e-6);
    assert_float_equal(o[1], -1.0f, 1e-6);
    assert_float_equal(o[2], 0.25f * 7.0f / 8.0f, 1e-6);
    st_cube_fixup_dir(d, 8, 1.5f, o); /* 1 - 2^lod / n */
    assert_float_equal(o[0], 0.5f * (1.0f - exp2f(1.5f) / 8.0f), 1e-6);
    assert_float_equal(o[1], -1.0f, 1e-6);
}

/* Finite directions whose magnitudes sum past FLT_MAX (components near FLT_MAX) are valid:
 * they pick a face and (u, v) as the same direction scaled down does (OpenEXR's
 * CubeMap::faceAndPixelPosition answers them; they were refused as non-finite). */
static void huge_finite_directions_get_their_face(void **state)
{
    (void)state;
    st_set_info in = {.nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, 8, 0, &s, &e), ST_OK);
    const float M = 3.4028235e38f; /* FLT_MAX */
    const float huge[4][3] = {{M, -M, 0.5f * M}, {M, M, M}, {-M, 0.0f, 0.7f * M}, {0.25f * M, -M, M}};
    for (int i = 0; i < 4; i++) {
        float small[3], u, v, su, sv;
        for (int k = 0; k < 3; k++)
            small[k] = huge[i][k] * 0x1p-100f;
        int fs = st_cube_dir_to_face(small, &su, &sv);
        assert_true(fs >= 0);
        assert_int_equal(st_cube_dir_to_face(huge[i], &u, &v), fs);
        assert_float_equal(u, su, 1e-6);
        assert_float_equal(v, sv, 1e-6);
        for (unsigned lookup = 0; lookup < 2; lookup++) {
            st_cube_query q, qs;
            memset(&q, 0, sizeof q);
            memset(&qs, 0, sizeof qs);
            memcpy(q.dir, huge[i], sizeof q.dir);
            memcpy(qs.dir, small, sizeof qs.dir);
            q.cone = qs.cone = 0.01f;
            st_query fq, fqs;
            uint8_t st, sts;
            st_cube_queries(s, lookup, &q, 1, &fq, &st);
            st_cube_queries(s, lookup, &qs, 1, &fqs, &sts);
            assert_int_equal(sts, ST_Q_OK);
            assert_int_equal(st, ST_Q_OK);
            assert_int_equal(fq.face, fqs.face);
            assert_float_equal(fq.u, fqs.u, 1e-6);
            assert_float_equal(fq.v, fqs.v, 1e-6);
        }
    }
    st_set_free(s);
}

/* At an exact tie of the two largest components (a cube edge; all three: a corner) the fixup
 * lookup scales every component but the one that picks the face, so pixel centre 0 / n-1
 * lands on the edge exactly as OpenEXR's lookup puts it: u n - 1/2 = (s + 1)/2 (n - 1).
 * (The tied component was left unscaled, half a texel off: u = 0 or 1.) */
static void fixup_lookup_at_edge_and_corner_ties_matches_openexr(void **state)
{
    (void)state;
    const uint32_t n = 16;
    st_set_info in = {.nchan = 1, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, n, 0, &s, &e), ST_OK);
    const float d0[4][3] = {{1, 1, 0.3f}, {-1, -1, -1}, {0.5f, -0.2f, 0.5f}, {0.1f, -2, 2}};
    /* OpenEXR's face and in-face pixel (x right, y down; centres 0 .. n-1 span the face) */
    const int face[4] = {0, 1, 0, 3};
    const float px[4][2] = {{(0.3f + 1) / 2 * (n - 1), 0},         /* +X: s = z, t = -y */
                            {(float)(n - 1), (float)(n - 1)},       /* -X: s = -z, t = -y */
                            {(float)(n - 1), (0.4f + 1) / 2 * (n - 1)},                 /* +X, z tied */
                            {(0.05f + 1) / 2 * (n - 1), (float)(n - 1)}}; /* -Y: s = x/2, t = z/2 */
    for (int i = 0; i < 4; i++) {
        st_cube_query q;
        memset(&q, 0, sizeof q);
        memcpy(q.dir, d0[i], sizeof q.dir);
        st_query fq;
        uint8_t st;
        st_cube_queries(s, ST_CUBE_LOOKUP_FIXUP, &q, 1, &fq, &st);
        assert_int_equal(st, ST_Q_OK);
        assert_int_equal(fq.face, face[i]);
        assert_float_equal(fq.u * n - 0.5f, px[i][0], 1e-4);
        assert_float_equal(fq.v * n - 0.5f, px[i][1], 1e-4);
    }
    /* the fixup direction itself: the tied y is scaled, x (the face's axis) is not */
    float d[3] = {1, -1, 0.5f}, o[3];
    st_cube_fixup_dir(d, 8, 0, o);
    assert_float_equal(o[0], 1.0f, 0);
    assert_float_equal(o[1], -7.0f / 8.0f, 1e-6);
    assert_float_equal(o[2], 0.5f * 7.0f / 8.0f, 1e-6);
    st_set_free(s);
}

/* st_cube_from_faces knows three conventions; any other value is refused (it was taken as
 * the GL one: +Z and -Z exchanged without a word). */
static void six_faces_with_an_unknown_convention_are_refused(void **state)
{
    (void)state;
    float px[6][4];
    st_image faces[6];
    memset(faces, 0, sizeof faces);
    for (int f = 0; f < 6; f++) {
        for (int k = 0; k < 4; k++)
            px[f][k] = (float)(f * 4 + k);
        faces[f].w = faces[f].h = 2;
        faces[f].nchan = 1;
        faces[f].dtype = ST_DT_F32;
        faces[f].alpha_chan = -1;
        faces[f].data = px[f];
    }
    st_set *s = NULL;
    st_error e;
    for (int conv = 0; conv <= 2; conv++) {
        assert_int_equal(st_cube_from_faces(faces, (st_cube_faces_conv)conv, 0, &s, &e), ST_OK);
        st_set_free(s);
    }
    assert_int_equal(st_cube_from_faces(faces, (st_cube_faces_conv)3, 0, &s, &e), ST_EINVAL);
    assert_null(s);
    assert_non_null(strstr(e.msg, "convention"));
}

/* st_cube_write: an EXR vertical strip is tagged envmap=cube (OpenEXR's layout) and imports
 * back as the same cube with no option; the other layouts carry no envmap (a cross tagged
 * envmap=cube would be read as a vertical strip) and come back with cube=auto. (The strip was
 * written untagged and came back as a one-face atlas.) */
static void written_layouts_import_back_as_the_same_cube(void **state)
{
    (void)state;
    const uint32_t n = 4;
    st_set_info in = {.nchan = 3, .dtype = ST_DT_F32, .alpha_chan = -1};
    st_set *c = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&in, n, 0, &c, &e), ST_OK);
    for (unsigned f = 0; f < 6; f++) {
        float *t = (float *)st_face_level(c, f, 0);
        for (uint32_t k = 0; k < n * n * 3; k++)
            t[k] = (float)(f * 1000 + k);
    }
    st_set_build_mips(c, UINT32_MAX);
    static const char *const name[4] = {"strip_v", "strip_h", "cross_h", "cross_v"};
    for (unsigned l = 0; l < 4; l++) {
        char p[512];
        snprintf(p, sizeof p, "%s/written_%s.exr", tmpdir, name[l]);
        assert_int_equal(st_cube_write(c, 0, (st_cube_layout)l, p, &e), ST_OK);
        for (unsigned opt = 0; opt < 2; opt++) {
            st_import_opts o;
            st_import_opts_init(&o);
            o.cube = opt ? ST_IMPORT_CUBE_AUTO : ST_IMPORT_CUBE_NONE;
            st_set *b = NULL;
            assert_int_equal(st_import_file(p, &o, &b, &e), ST_OK);
            if (!opt && l != ST_CUBE_STRIP_V) {
                assert_int_equal(b->info.kind, ST_KIND_ATLAS);
                st_set_free(b);
                continue;
            }
            assert_int_equal(b->info.kind, ST_KIND_CUBE);
            for (unsigned f = 0; f < 6; f++)
                assert_memory_equal(st_face_level(b, f, 0), st_face_level(c, f, 0),
                                    (size_t)n * n * 3 * sizeof(float));
            st_set_free(b);
        }
    }
    st_set_free(c);
}

static void baked_edge_fixup_faces_are_seamless_with_clamp_and_match_traverse(void **state)
{
    (void)state;
    st_set *ll = load("env/WavyLinesLatLong.exr", ST_IMPORT_CUBE_LATLONG, 128);
    if (!ll)
        skip();
    st_set *b = NULL;
    st_error e;
    assert_int_equal(st_cube_bake_fixup(ll, 0, &b, &e), ST_OK);
    float n = 128.0f;
    for (int l = 0; l <= 4; l += 2) {
        float cone = exp2f((float)l) / n;
        double plain_clamp = edge_jump(ll, ST_MODE_CLAMP, 0, cone);
        double baked = edge_jump(b, ST_MODE_CLAMP, ST_CUBE_LOOKUP_FIXUP, cone);
        print_message("lod ~%d: edge jump clamp %.5f, baked + fixup lookup + clamp %.5f\n", l,
                      plain_clamp, baked);
        assert_true(baked < 0.5 * plain_clamp);
    }
    /* level 0, everywhere including the edges: baked + fixup vs the original with Traverse */
    double agree = cube_agreement(ll, 0, ST_MODE_TRAVERSE, b, ST_CUBE_LOOKUP_FIXUP, ST_MODE_CLAMP,
                                  0, 0.0f);
    print_message("baked + fixup lookup vs traverse on the original: rel. diff %.4f\n", agree);
    assert_true(agree < 0.12);
    /* export of the baked faces */
    char p[512];
    snprintf(p, sizeof p, "%s/baked_strip.exr", tmpdir);
    assert_int_equal(st_cube_write(b, 0, ST_CUBE_STRIP_V, p, &e), ST_OK);
    st_import_opts o;
    st_import_opts_init(&o);
    o.cube = ST_IMPORT_CUBE_STRIP_V;
    st_set *back = NULL;
    assert_int_equal(st_import_file(p, &o, &back, &e), ST_OK);
    assert_memory_equal(st_face_level(back, 0, 0), st_face_level(b, 0, 0),
                        (size_t)128 * 128 * st_texel_size(b));
    st_set_free(back);
    st_set_free(b);
    st_set_free(ll);
}

static void layouts_round_trip_exactly(void **state)
{
    (void)state;
    st_set *c = load("env/StageEnvCube.exr", 0, 0);
    if (!c)
        skip();
    const struct { st_cube_layout l; unsigned imp; const char *name; } L[] = {
        {ST_CUBE_STRIP_H, ST_IMPORT_CUBE_STRIP_H, "strip_h.exr"},
        {ST_CUBE_CROSS_H, ST_IMPORT_CUBE_CROSS_H, "cross_h.exr"},
        {ST_CUBE_CROSS_V, ST_IMPORT_CUBE_CROSS_V, "cross_v.exr"},
        {ST_CUBE_CROSS_H, ST_IMPORT_CUBE_AUTO, "cross_h_auto.exr"},
        {ST_CUBE_STRIP_V, ST_IMPORT_CUBE_AUTO, "strip_v_auto.exr"}};
    for (size_t i = 0; i < sizeof L / sizeof L[0]; i++) {
        char p[512];
        snprintf(p, sizeof p, "%s/%s", tmpdir, L[i].name);
        st_error e;
        assert_int_equal(st_cube_write(c, 0, L[i].l, p, &e), ST_OK);
        st_import_opts o;
        st_import_opts_init(&o);
        o.cube = (uint8_t)L[i].imp;
        st_set *b = NULL;
        assert_int_equal(st_import_file(p, &o, &b, &e), ST_OK);
        assert_int_equal(b->info.kind, ST_KIND_CUBE);
        for (unsigned f = 0; f < 6; f++)
            assert_memory_equal(st_face_level(b, f, 0), st_face_level(c, f, 0),
                                (size_t)256 * 256 * st_texel_size(c));
        st_set_free(b);
    }
    st_set_free(c);
}

/* Mean |a - b| between the cells on both sides of every internal edge of a cross image,
 * over the mean |a - b| between neighbouring rows inside the cells. */
static void cross_images_are_continuous_across_their_internal_edges(void **state)
{
    (void)state;
    st_set *c = load("env/StageEnvLatLong.exr", ST_IMPORT_CUBE_LATLONG, 128);
    if (!c)
        skip();
    char p[512];
    snprintf(p, sizeof p, "%s/cross.exr", tmpdir);
    st_error e;
    assert_int_equal(st_cube_write(c, 0, ST_CUBE_CROSS_H, p, &e), ST_OK);
    st_image img;
    assert_int_equal(st_image_read_any(p, NULL, &img, &e), ST_OK);
    const uint32_t n = 128, W = img.w;
    const uint16_t *px = img.data;
    /* internal edges of the horizontal cross: vertical ones in row 1 between columns
     * 0|1, 1|2, 2|3; horizontal ones above and below the centre cell */
    double edge = 0, inner = 0;
    int ce = 0, ci = 0;
    for (uint32_t k = 0; k < n; k++)
        for (unsigned ch = 0; ch < 3; ch++) {
            for (uint32_t col = 1; col <= 3; col++) {
                size_t y = n + k, x = (size_t)col * n;
                edge += fabsf(st_half_to_float(px[(y * W + x - 1) * 3 + ch]) -
                              st_half_to_float(px[(y * W + x) * 3 + ch]));
                inner += fabsf(st_half_to_float(px[(y * W + x - n / 2 - 1) * 3 + ch]) -
                               st_half_to_float(px[(y * W + x - n / 2) * 3 + ch]));
                ce++;
                ci++;
            }
            for (uint32_t row = 1; row <= 2; row++) {
                size_t y = (size_t)row * n, x = n + k;
                edge += fabsf(st_half_to_float(px[((y - 1) * W + x) * 3 + ch]) -
                              st_half_to_float(px[(y * W + x) * 3 + ch]));
                ce++;
            }
        }
    print_message("cross: mean jump across internal edges %.4f, inside cells %.4f\n", edge / ce,
                  inner / ci);
    assert_true(edge / ce < 3.0 * (inner / ci));
    st_image_free(&img);
    st_set_free(c);
}

/* Mean texel jump across the 12 edges (texel at the edge vs the one across it, found by
 * direction) over the jump between neighbouring texels inside the faces. */
static double texel_edge_ratio(const st_set *s)
{
    unsigned n = s->faces[0].w;
    size_t ts = st_texel_size(s);
    double acc = 0, inner = 0;
    int cnt = 0, ci = 0;
    for (unsigned f = 0; f < 6; f++)
        for (unsigned ed = 0; ed < 4; ed++)
            for (unsigned i = 0; i < n; i++) {
                float t = ((float)i + 0.5f) / (float)n, u, v, d[3];
                edge_point(ed, t, &u, &v);
                float cu = fminf(fmaxf(u, 0.5f / n), 1 - 0.5f / n), cv = fminf(fmaxf(v, 0.5f / n), 1 - 0.5f / n);
                float ou = u + (u - cu), ov = v + (v - cv); /* half a texel outside */
                st_cube_face_dir(f, ou, ov, d);
                float u2, v2;
                int g = st_cube_dir_to_face(d, &u2, &v2);
                unsigned x1 = (unsigned)(cu * n), y1 = (unsigned)(cv * n);
                unsigned x2 = (unsigned)fminf(u2 * n, n - 1), y2 = (unsigned)fminf(v2 * n, n - 1);
                const uint8_t *a = st_face_level(s, f, 0), *b = st_face_level(s, (unsigned)g, 0);
                for (unsigned c = 0; c < 3; c++) {
                    acc += fabsf(st_channel_get(s->info.dtype, a + ((size_t)y1 * n + x1) * ts, c) -
                                 st_channel_get(s->info.dtype, b + ((size_t)y2 * n + x2) * ts, c));
                    cnt++;
                    unsigned yy = n / 2;
                    inner += fabsf(st_channel_get(s->info.dtype, a + ((size_t)yy * n + i) * ts, c) -
                                   st_channel_get(s->info.dtype, a + ((size_t)(yy + 1) * n + i) * ts, c));
                    ci++;
                }
            }
    return (acc / cnt) / (inner / ci + 1e-9);
}

static void six_face_humus_cube_imports_in_the_gl_convention(void **state)
{
    (void)state;
    char pat[1024];
    if (st_test_data_path(pat, sizeof pat, "cube/humus-6face/+x.jpg"))
        skip();
    snprintf(pat, sizeof pat, "%s/cube/humus-6face/%%s.jpg", st_test_data_dir());
    double ratio[3];
    for (int conv = 0; conv < 3; conv++) {
        st_import_opts o;
        st_import_opts_init(&o);
        o.cube = ST_IMPORT_CUBE_SIX;
        o.six_conv = (uint8_t)conv;
        st_set *s = NULL;
        st_error e;
        assert_int_equal(st_import_file(pat, &o, &s, &e), ST_OK);
        assert_int_equal(s->info.kind, ST_KIND_CUBE);
        assert_int_equal(s->faces[0].w, 512);
        ratio[conv] = texel_edge_ratio(s);
        st_set_free(s);
    }
    print_message("humus edge/interior jump: as OpenEXR faces %.2f, GL %.2f, GL upside down %.2f\n",
                  ratio[0], ratio[1], ratio[2]);
    /* the right convention joins the faces about as smoothly as a face's inside */
    double best = fmin(ratio[0], fmin(ratio[1], ratio[2]));
    assert_true(best < 2.0);
    assert_true(ratio[ST_CUBE_FACES_GL] == best || ratio[ST_CUBE_FACES_GL_FLIPPED] == best);
}

static void ptex_environment_cube_maps_each_face_by_direction(void **state)
{
    (void)state;
    /* Ptex's envcube frames (envcube.obj: px u -> -z, v -> +y; nx u -> +z, v -> +y;
     * py u -> +x, v -> -z; ny u -> +x, v -> +z; pz u -> +x, v -> +y; nz u -> -x, v -> +y)
     * are seamtex's frames turned by 180 degrees on the four side faces and the same on +-Y:
     * every texel must land there exactly. (The sample's faces are axis labels, not a
     * continuous scene, so continuity says nothing here.) */
    static const int rot180[6] = {1, 1, 0, 0, 1, 1};
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptx/wdas-ptex-samples/envcube/envcube.ptx"))
        skip();
    st_set *p = NULL, *c = NULL;
    st_error e;
    assert_int_equal(st_ptex_read_file(path, 0, &p, &e), ST_OK);
    c = load("ptx/wdas-ptex-samples/envcube/envcube.ptx", 0, 0);
    uint32_t n = c->faces[0].w;
    size_t ts = st_texel_size(c);
    assert_int_equal(n, p->faces[0].w);
    for (unsigned f = 0; f < 6; f++)
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++)
            {
                uint32_t pi = rot180[f] ? n - 1 - i : i, pj = rot180[f] ? n - 1 - j : j;
                assert_memory_equal(st_face_level(c, f, 0) + ((size_t)j * n + i) * ts,
                                    st_face_level(p, f, 0) + ((size_t)pj * n + pi) * ts, ts);
            }
    st_set_free(p);
    st_set_free(c);
    /* a continuous scene joins across the edges texel for texel (OpenEXR duplicates them) */
    st_set *w = load("env/WavyLinesCube.exr", 0, 0);
    if (w) {
        double rw = texel_edge_ratio(w);
        print_message("WavyLinesCube.exr: edge/interior jump %.3f\n", rw);
        assert_true(rw < 0.5);
        st_set_free(w);
    }
}

/* A BC1 set made from a cube map is sampled by direction like the cube (same frames and
 * adjacency): the values equal those of its decoded set, in every mode; a BC1 set made from
 * anything else is not a cube. */
static void bc1_cube_is_sampled_by_direction(void **state)
{
    (void)state;
    st_set *w = load("env/WavyLinesCube.exr", 0, 0);
    if (!w)
        skip();
    st_bc1_opts bo;
    st_bc1_opts_default(&bo);
    bo.level = ST_BC1_FAST;
    bo.threads = 1;
    st_set *b = NULL, *d = NULL;
    st_error e;
    assert_int_equal(st_bc1_compress_set(w, &bo, NULL, NULL, NULL, &b, &e), ST_OK);
    assert_int_equal(b->info.kind, ST_KIND_BC1);
    assert_true(st_cube_is_cube(b));
    assert_int_equal(st_bc1_decode_set(b, ST_BC1_DEC_EXACT, &d, &e), ST_OK);
    assert_int_equal(d->info.kind, ST_KIND_CUBE);
    enum { N = 500 };
    st_cube_query q[N];
    uint32_t rng = 7;
    for (int i = 0; i < N; i++) {
        memset(&q[i], 0, sizeof q[i]);
        for (int k = 0; k < 3; k++) {
            rng = rng * 1664525u + 1013904223u;
            q[i].dir[k] = (float)(rng >> 8) / (float)(1u << 24) * 2.0f - 1.0f;
        }
        q[i].cone = 0.02f * (float)(i % 4);
    }
    q[0].dir[0] = q[0].dir[1] = q[0].dir[2] = 0; /* a bad direction keeps its status */
    for (unsigned mode = 0; mode <= ST_MODE_CLAMP; mode++) {
        st_sample_opts o;
        memset(&o, 0, sizeof o);
        o.mode = (uint8_t)mode;
        o.filter = ST_FILTER_TRILINEAR;
        float ob[N * 4], od[N * 4];
        uint8_t sb[N], sd[N];
        int rb = st_cube_sample_dir(b, &o, ST_CUBE_LOOKUP_PLAIN, q, N, ob, NULL, sb);
        int rd = st_cube_sample_dir(d, &o, ST_CUBE_LOOKUP_PLAIN, q, N, od, NULL, sd);
        assert_int_equal(rb, 1);
        assert_int_equal(rd, 1);
        assert_int_equal(sb[0], ST_Q_NONFINITE);
        assert_memory_equal(sb, sd, N);
        assert_int_equal(b->info.nchan, d->info.nchan);
        assert_memory_equal(ob + 4, od + 4, (N - 1) * b->info.nchan * sizeof(float));
    }
    st_set_free(d);
    st_set_free(b);
    st_set_free(w);
    /* a BC1 atlas is not a cube */
    char path[1024];
    st_set *img = NULL;
    if (!st_test_data_path(path, sizeof path, "images/bc1-set/kodim23.png") &&
        st_import_file(path, NULL, &img, &e) == ST_OK) {
        assert_int_equal(st_bc1_compress_set(img, &bo, NULL, NULL, NULL, &b, &e), ST_OK);
        assert_false(st_cube_is_cube(b));
        st_sample_opts o;
        memset(&o, 0, sizeof o);
        float v[4];
        assert_int_equal(st_cube_sample_dir(b, &o, ST_CUBE_LOOKUP_PLAIN, q + 1, 1, v, NULL, NULL),
                         ST_EINVAL);
        st_set_free(b);
        st_set_free(img);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(adjacency_matches_the_face_frames_and_corners_have_valence_3),
        cmocka_unit_test(directions_round_trip_through_face_and_uv),
        cmocka_unit_test(footprints_from_derivatives_and_cones_follow_the_projection),
        cmocka_unit_test(bad_directions_get_a_status_not_a_crash),
        cmocka_unit_test(traverse_is_continuous_across_every_edge_and_corner_and_clamp_is_not),
        cmocka_unit_test(latlong_and_cube_versions_of_a_scene_agree_away_from_seams),
        cmocka_unit_test(castano_fixup_scales_the_minor_components),
        cmocka_unit_test(huge_finite_directions_get_their_face),
        cmocka_unit_test(fixup_lookup_at_edge_and_corner_ties_matches_openexr),
        cmocka_unit_test(six_faces_with_an_unknown_convention_are_refused),
        cmocka_unit_test(written_layouts_import_back_as_the_same_cube),
        cmocka_unit_test(baked_edge_fixup_faces_are_seamless_with_clamp_and_match_traverse),
        cmocka_unit_test(layouts_round_trip_exactly),
        cmocka_unit_test(cross_images_are_continuous_across_their_internal_edges),
        cmocka_unit_test(six_face_humus_cube_imports_in_the_gl_convention),
        cmocka_unit_test(ptex_environment_cube_maps_each_face_by_direction),
        cmocka_unit_test(bc1_cube_is_sampled_by_direction),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
