/* tests/unit/test_seams.c - welding, seam / boundary / non-manifold edges and charts of
 * meshes (synthetic ones, and the shared meshes against the figures of the data README),
 * atlas chart masks and chart-relative Discard. */
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

#include "atlas.h"
#include "import.h"
#include "mesh.h"
#include "../common/testdata.h"
#include "mesh_io.h"

static st_mesh *obj_str(const char *text)
{
    st_mesh *m = NULL;
    st_error e;
    int rc = st_obj_read_mem(text, strlen(text), NULL, NULL, &m, &e);
    if (rc)
        print_message("obj: %s\n", e.msg);
    assert_int_equal(rc, ST_OK);
    return m;
}

static void two_triangles_with_split_uvs_make_one_seam(void **state)
{
    (void)state;
    /* a quad split along 1-3; the second triangle's UVs come from another chart */
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt .5 0\nvt .5 .5\nvt 0 .5\nvt .6 .6\nvt .9 .9\n"
                         "f 1/1 2/2 3/3\nf 1/5 3/6 4/4\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    const st_seams *s = m->seams;
    assert_int_equal(s->nseams, 1);
    assert_int_equal(s->nboundary, 4);
    assert_int_equal(s->nnonmanifold, 0);
    assert_int_equal(s->ncharts, 2);
    const st_seam_edge *se = &s->seams[0];
    assert_true(se->pos[0] < se->pos[1]);
    /* both segments run from pos[0] (vertex 1) to pos[1] (vertex 3) */
    assert_float_equal(se->uv[0][0][0], 0.0f, 1e-6);
    assert_float_equal(se->uv[0][1][0], 0.5f, 1e-6);
    assert_float_equal(se->uv[1][0][0], 0.6f, 1e-6);
    assert_float_equal(se->uv[1][1][0], 0.9f, 1e-6);
    /* v is flipped into texture space */
    assert_float_equal(se->uv[0][1][1], 0.5f, 1e-6);
    assert_float_equal(se->uv[1][1][1], 1.0f - 0.9f, 1e-6);
    st_mesh_free(m);
}

static void shared_uvs_are_not_a_seam_even_with_duplicate_vt_entries(void **state)
{
    (void)state;
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0 0\nvt 1 1\n"
                         "f 1/1 2/2 3/3\nf 1/5 3/6 4/4\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->seams->nseams, 0);
    assert_int_equal(m->seams->ncharts, 1);
    st_mesh_free(m);
}

static void mirrored_chart_is_flagged(void **state)
{
    (void)state;
    /* the second triangle's UVs are mirrored (opposite winding in UV space) */
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 2 0\nvt 2 1\n"
                         "f 1/1 2/2 3/3\nf 1/2 3/3 4/5\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->seams->nseams, 1);
    const st_seam_edge *se = &m->seams->seams[0];
    assert_int_not_equal(se->winding[0], 0);
    assert_int_equal(se->winding[0], -se->winding[1]);
    assert_int_equal(se->mirrored, 1);
    st_mesh_free(m);
}

static void welding_merges_split_positions_before_seams(void **state)
{
    (void)state;
    /* the same quad with its shared edge's vertices duplicated (as Draco writes them) */
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 0\nv 1 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 5\nvt 6 6\n"
                         "f 1/1 2/2 3/3\nf 5/5 6/6 4/4\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->nweld, 4);
    assert_int_equal(m->seams->nseams, 1);
    assert_int_equal(m->seams->nboundary, 4);
    st_mesh_free(m);
}

static void three_triangles_on_one_edge_are_non_manifold(void **state)
{
    (void)state;
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nvt 0 0\n"
                         "f 1/1 2/1 3/1\nf 2/1 1/1 4/1\nf 1/1 2/1 5/1\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->seams->nnonmanifold, 1);
    assert_int_equal(m->seams->nonmanifold[0].count, 3);
    assert_int_equal(m->seams->nboundary, 6);
    assert_int_equal(m->seams->nseams, 0);
    st_mesh_free(m);
}

static void edge_to_a_triangle_without_uvs_is_not_a_seam(void **state)
{
    (void)state;
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                         "f 1/1 2/2 3/3\nf 1 3 4\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->ntri_nouv, 1);
    assert_int_equal(m->seams->nseams, 0);
    assert_int_equal(m->seams->nuv_border, 1);
    assert_int_equal(m->seams->ncharts, 2);
    st_mesh_free(m);
}

/* Texture coordinates are compared by value: an exporter that writes "vt -0 0" on one side of
 * an edge and "vt 0 0" on the other (printf of a negative zero) makes no seam (mesh27: it
 * used to be one, with two charts, when the UVs were compared bitwise). */
static void negative_zero_uv_is_the_same_coordinate_as_zero(void **state)
{
    (void)state;
    st_mesh *m = obj_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt -0 0\nvt -0.0 1\n"
                         "f 1/1 2/2 3/3\nf 1/5 3/3 4/6\n");
    st_error e;
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->seams->nseams, 0);
    assert_int_equal(m->seams->ncharts, 1);
    assert_int_equal(m->seams->nboundary, 4);
    st_mesh_free(m);
}

typedef struct expect {
    const char *rel;
    int draco;
    uint32_t ntri, seams, boundary, nonmanifold, charts;
} expect;

/* Figures from the shared data README. */
static const expect EXPECTED[] = {
    {"meshes/duck/Duck.obj", 0, 4212, 166, 0, 0, 10},
    {"meshes/waterbottle/WaterBottle.obj", 0, 4510, 119, 264, 0, 5},
    {"meshes/cesiummilktruck/CesiumMilkTruck.obj", 0, 3624, 479, 8, 0, 376},
    {"meshes/spider/spider.obj", 0, 1368, 172, 72, 16, 91},
    {"drc/cube_att.obj", 0, 12, 12, 0, 0, 6},
    {"drc/cube_att.drc", 1, 12, 12, 0, 0, 6},
    {"drc/cube_att.obj.edgebreaker.cl10.2.2.drc", 1, 12, 12, 0, 0, 6},
    {"drc/cube_att.obj.sequential.cl3.2.2.drc", 1, 12, 12, 0, 0, 6},
    {"drc/converted/Duck.drc", 1, 4212, 166, 0, 0, 10},
};

static void shared_meshes_match_the_data_readme(void **state)
{
    (void)state;
    char path[1024];
    for (size_t i = 0; i < sizeof EXPECTED / sizeof EXPECTED[0]; i++) {
        const expect *x = &EXPECTED[i];
        if (st_test_data_path(path, sizeof path, x->rel))
            skip();
        st_mesh *m = NULL;
        st_error e;
        int rc = x->draco ? st_draco_read_file(path, NULL, &m, &e) : st_obj_read_file(path, NULL, &m, &e);
        if (rc)
            print_message("%s: %s\n", x->rel, e.msg);
        assert_int_equal(rc, ST_OK);
        assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
        print_message("%-45s tris %5u seams %4u boundary %4u non-manifold %3u charts %4u\n", x->rel,
                      m->ntri, m->seams->nseams, m->seams->nboundary, m->seams->nnonmanifold,
                      m->seams->ncharts);
        assert_int_equal(m->ntri, x->ntri);
        assert_int_equal(m->seams->nseams, x->seams);
        assert_int_equal(m->seams->nboundary, x->boundary);
        assert_int_equal(m->seams->nnonmanifold, x->nonmanifold);
        assert_int_equal(m->seams->ncharts, x->charts);
        /* every seam's two segments really differ */
        for (uint32_t k = 0; k < m->seams->nseams; k++)
            assert_true(memcmp(m->seams->seams[k].uv[0], m->seams->seams[k].uv[1],
                               sizeof m->seams->seams[k].uv[0]) != 0);
        st_mesh_free(m);
    }
}

static void draco_mesh_without_uvs_is_refused_with_enouv(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, "drc/bunny_gltf.drc"))
        skip();
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_draco_read_file(path, NULL, &m, &e), ST_OK);
    assert_int_equal(m->nuv, 0);
    assert_int_equal(st_mesh_require_uv(m, &e), ST_ENOUV);
    assert_non_null(strstr(e.msg, "no texture coordinates"));
    assert_int_equal(st_mesh_find_seams(m, &e), ST_OK);
    assert_int_equal(m->seams->nboundary, 223); /* README: boundary 223 */
    st_mesh_free(m);
    st_set *s = NULL;
    assert_int_equal(st_import_file(path, NULL, &s, &e), ST_ENOUV);
    assert_null(s);
}

/* The duck's atlas set (Duck.obj with its texture), or NULL when the shared data is absent. */
static st_set *duck_atlas(void)
{
    char obj[1024];
    if (st_test_data_path(obj, sizeof obj, "meshes/duck/Duck.obj"))
        return NULL;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_import_file(obj, NULL, &s, &e), ST_OK);
    return s;
}

static void duck_atlas_has_a_chart_mask_and_chart_discard_drops_outside_taps(void **state)
{
    (void)state;
    st_set *s = duck_atlas();
    if (!s)
        skip();
    const st_atlas *a = st_atlas_get(s);
    assert_non_null(a);
    assert_non_null(a->mesh);
    assert_int_equal(a->mesh->seams->nseams, 166);
    assert_int_equal(a->mask_w, 512);
    size_t in = 0, out_px = 0;
    for (size_t i = 0; i < (size_t)a->mask_w * a->mask_h; i++)
        a->chart_mask[i] ? in++ : out_px++;
    print_message("duck chart mask: %zu texels in charts, %zu outside\n", in, out_px);
    assert_true(in > 1000 && out_px > 1000);
    /* find a masked-out texel with a masked-in neighbour to the right */
    long fx = -1, fy = -1;
    for (uint32_t y = 0; y < a->mask_h && fx < 0; y++)
        for (uint32_t x = 0; x + 1 < a->mask_w; x++)
            if (!a->chart_mask[y * a->mask_w + x] && a->chart_mask[y * a->mask_w + x + 1]) {
                fx = x;
                fy = y;
                break;
            }
    assert_true(fx >= 0);
    st_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = ST_MODE_DISCARD;
    o.filter = ST_FILTER_BILINEAR;
    st_query q;
    memset(&q, 0, sizeof q);
    q.u = ((float)fx + 1.0f) / 512.0f; /* between the outside texel and the inside one */
    q.v = ((float)fy + 0.5f) / 512.0f;
    float v1[4], v2[4], c1, c2;
    uint8_t s1, s2;
    assert_true(st_atlas_sample(s, &o, ST_ATLAS_CHART_DISCARD, &q, 1, v1, &c1, &s1) >= 0);
    st_sample_opts oc = o;
    oc.mode = ST_MODE_CLAMP; /* the image alone (SAMPLE's Discard is chart Discard: below) */
    assert_true(st_atlas_sample(s, &oc, 0, &q, 1, v2, &c2, &s2) >= 0);
    assert_int_equal(s1, ST_Q_OK);
    assert_float_equal(c1, 0.5f, 1e-3);  /* half the bilinear weight was outside the chart */
    assert_float_equal(c2, 1.0f, 1e-3);
    /* the chart-discard result is the inside texel alone */
    const uint8_t *px = st_face_level(s, 0, 0) + ((size_t)fy * 512 + (size_t)fx + 1) * 3;
    assert_float_equal(v1[0], px[0] / 255.0f, 1e-4);
    st_set_free(s);
}

/* st_atlas_sample (without the masked discard) is st_sample_batch on face 0 in every mode, the
 * path SAMPLE takes over the wire: Traverse at the image border drops the taps beyond it and
 * renormalises (the border is a boundary); with the mesh it is chart Traverse, which keeps
 * every tap chart Discard keeps and reads some of the others across seams: its coverage is
 * at least Discard's, and where it is equal so are the values. Clamp gives coverage 1. (It
 * used to take Traverse as Clamp, unlike the daemon.) */
static void atlas_sampling_takes_the_modes_as_the_wire_does(void **state)
{
    (void)state;
    st_set *s = duck_atlas();
    if (!s)
        skip();
    st_set *plain = duck_atlas(); /* the image alone */
    st_error e;
    assert_int_equal(st_atlas_attach_mesh(plain, NULL, &e), ST_OK);
    enum { N = 64 };
    st_query q[N];
    memset(q, 0, sizeof q);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)(i % 3); /* the face is ignored: an atlas has face 0 only */
        q[i].u = (i & 1) ? 0.0003f * (float)(i % 7) : 1.0f - 0.0002f * (float)(i % 5);
        q[i].v = 0.015625f * (float)i;
        q[i].dudx = q[i].dvdy = (i % 4) ? 0.001f * (float)(i % 4) : 0.0f;
    }
    static const uint8_t modes[3] = {ST_MODE_DISCARD, ST_MODE_TRAVERSE, ST_MODE_CLAMP};
    static const uint8_t filters[3] = {ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR};
    float out[3][N * 4], cov[3][N];
    assert_true(s->info.nchan <= 4);
    for (int f = 0; f < 3; f++) {
        for (int m = 0; m < 3; m++) {
            st_sample_opts o = {.mode = modes[m], .filter = filters[f]};
            float a[N * 4], ca[N], b[N * 4], cb[N];
            uint8_t sa[N], sb[N];
            st_query q0[N];
            memcpy(q0, q, sizeof q);
            for (int i = 0; i < N; i++)
                q0[i].face = 0;
            assert_int_equal(st_atlas_sample(s, &o, 0, q, N, a, ca, sa),
                             st_sample_batch(s, &o, q0, N, b, cb, sb));
            assert_memory_equal(a, b, N * s->info.nchan * sizeof(float));
            assert_memory_equal(ca, cb, sizeof ca);
            assert_memory_equal(sa, sb, sizeof sa);
            if (modes[m] == ST_MODE_DISCARD) /* the image Discard */
                assert_true(st_sample_batch(plain, &o, q0, N, a, ca, sa) >= 0);
            memcpy(out[m], a, sizeof a);
            memcpy(cov[m], ca, sizeof ca);
        }
        int border = 0, across = 0;
        size_t nc = s->info.nchan;
        for (int i = 0; i < N; i++) {
            assert_float_equal(cov[2][i], 1.0f, 0.0f);                  /* Clamp */
            assert_true(cov[1][i] >= cov[0][i] - 1e-6f); /* Traverse keeps what Discard does */
            if (cov[1][i] == cov[0][i])
                assert_memory_equal(&out[1][i * nc], &out[0][i * nc], nc * sizeof(float));
            else
                across++;
            border += cov[1][i] < 1.0f;
        }
        print_message("filter %d: %d of %d queries past the border, %d read across a seam\n",
                      f, border, N, across);
        if (f)
            assert_true(border >= N / 4); /* the queries do reach past the border */
    }
    st_set_free(plain);
    st_set_free(s);
}

/* A Draco mesh may hold any finite UV: a triangle (0,0) (1e20,0) (0,1e20) covers the whole
 * image, and its chart mask must too (mesh27: the bounding box went through (long) of 1e20 * w,
 * undefined, LONG_MIN on x86, and the mask stayed empty, so chart Discard found no texel);
 * chart Discard refuses |u| over ST_MAX_COORD as st_sample_batch does. */
static void huge_uvs_keep_the_chart_mask_and_chart_discard_defined(void **state)
{
    (void)state;
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_mesh_alloc(3, 3, 1, &m, &e), ST_OK);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const float uv[6] = {0, 0, 1e20f, 0, 0, 1e20f};
    memcpy(m->pos, pos, sizeof pos);
    memcpy(m->uv, uv, sizeof uv);
    for (uint32_t k = 0; k < 3; k++)
        m->tri_pos[k] = m->tri_uv[k] = k;
    uint8_t px[8 * 8];
    for (int i = 0; i < 64; i++)
        px[i] = (uint8_t)(i * 3);
    st_image img = {.w = 8, .h = 8, .nchan = 1, .dtype = ST_DT_U8, .alpha_chan = -1, .data = px};
    st_set *s = NULL;
    assert_int_equal(st_atlas_from_image(&img, m, 0, &s, &e), ST_OK);
    const st_atlas *a = st_atlas_get(s);
    size_t covered = 0;
    for (size_t i = 0; i < 64; i++)
        covered += a->chart_mask[i];
    assert_int_equal(covered, 64);
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_POINT};
    st_query q[2];
    memset(q, 0, sizeof q);
    q[0].u = 0.5f;
    q[0].v = 0.5f;
    q[1].u = 1e30f;
    q[1].v = 0.5f;
    float out[2], cov[2];
    uint8_t st[2];
    assert_int_equal(st_atlas_sample(s, &o, ST_ATLAS_CHART_DISCARD, q, 2, out, cov, st), 1);
    assert_int_equal(st[0], ST_Q_OK);
    assert_float_equal(out[0], (float)px[4 * 8 + 4] / 255.0f, 1e-6);
    assert_int_equal(st[1], ST_Q_BAD_FOOTPRINT);
    st_set_free(s);
}

/* The atlas set of a w x h RGBA8 image (px, copied) and mesh m (taken over), which has two
 * charts and their ids at every level. */
static st_set *two_charts_of(const uint8_t *px, uint32_t w, uint32_t h, st_mesh *m)
{
    st_image img = {.w = w, .h = h, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                    .data = (void *)px};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_atlas_from_image(&img, m, 0, &s, &e), ST_OK);
    const st_atlas *a = st_atlas_get(s);
    assert_int_equal(a->mesh->seams->ncharts, 2);
    assert_int_equal(a->ids.nlevels, s->faces[0].nlevels);
    return s;
}

/* Two unit squares apart in 3D (no shared edge: two charts), two triangles each, the first
 * over u in [0, a], the second over [b, 1], v in [0, 1]. */
static st_mesh *two_apart(float a, float b)
{
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_mesh_alloc(8, 8, 4, &m, &e), ST_OK);
    const float pos[24] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 3, 0, 0, 4, 0, 0, 4, 1, 0, 3, 1, 0};
    const float uv[16] = {0, 0, a, 0, a, 1, 0, 1, b, 0, 1, 0, 1, 1, b, 1};
    const uint32_t tri[12] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
    memcpy(m->pos, pos, sizeof pos);
    memcpy(m->uv, uv, sizeof uv);
    memcpy(m->tri_pos, tri, sizeof tri);
    memcpy(m->tri_uv, tri, sizeof tri);
    return m;
}

/* atl28b: chart Discard. A 64 x 32 RGBA8 atlas of two charts side by side - A (a quad over
 * columns 0..27, red with a gradient) and B (columns 36..63, green) - with an 8-texel blue
 * gutter between them. */
static st_set *two_chart_atlas(void)
{
    st_mesh *m = two_apart(28 / 64.0f, 36 / 64.0f);   /* uv [0, 28/64] and [36/64, 1] */
    static uint8_t px[32][64][4];
    for (int j = 0; j < 32; j++)
        for (int i = 0; i < 64; i++) {
            uint8_t g = (uint8_t)(64 + (i * 3 + j * 5) % 128);
            px[j][i][0] = i < 28 ? g : 0;
            px[j][i][1] = i >= 36 ? g : 0;
            px[j][i][2] = i >= 28 && i < 36 ? 255 : 0;
            px[j][i][3] = 255;
        }
    return two_charts_of(&px[0][0][0], 64, 32, m);
}

/* Near the seam, Discard keeps to the query's chart at every level (no green from B, no blue
 * from the gutter at level 0) and says how much it dropped (coverage < 1), where Clamp bleeds
 * B's green in from the coarser levels with coverage 1. */
static void chart_discard_does_not_bleed_the_other_chart_at_any_level(void **state)
{
    (void)state;
    st_set *s = two_chart_atlas();
    struct {
        uint8_t filter;
        float du, dv; /* footprint in texels of level 0 along u and v */
    } cases[] = {
        {ST_FILTER_BILINEAR, 0, 0},    /* level 0: taps on columns 27 and 28 (the gutter) */
        {ST_FILTER_BILINEAR, 16, 16},  /* level 4: its column 2 is mostly B */
        {ST_FILTER_TRILINEAR, 12, 12}, /* levels 3 and 4 */
        {ST_FILTER_ANISO, 32, 4},      /* 8 probes along u at level 2, reaching into B */
        {ST_FILTER_POINT, 0, 0},
    };
    for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
        for (int k = 0; k < 8; k++) {
            st_query q = {.face = 0, .u = (27.55f + 0.05f * (float)k) / 64.0f,
                          .v = (4.0f + 3.0f * (float)k) / 32.0f,
                          .dudx = cases[c].du / 64.0f, .dvdy = cases[c].dv / 32.0f};
            float d[4], cl[4], cd, cc;
            uint8_t sd, sc;
            st_sample_opts od = {.mode = ST_MODE_DISCARD, .filter = cases[c].filter,
                                 .max_aniso = 8};
            st_sample_opts oc = od;
            oc.mode = ST_MODE_CLAMP;
            assert_int_equal(st_sample_batch(s, &od, &q, 1, d, &cd, &sd), 0);
            assert_int_equal(st_sample_batch(s, &oc, &q, 1, cl, &cc, &sc), 0);
            assert_int_equal(sd, ST_Q_OK);
            assert_float_equal(cc, 1.0f, 0.0f);
            assert_float_equal(d[1], 0.0f, 0.0f); /* nothing of B's green */
            assert_true(d[0] > 0.2f);             /* A's red, renormalised */
            if (cases[c].filter == ST_FILTER_POINT) {
                assert_float_equal(cd, 1.0f, 0.0f); /* the query's own texel, in A */
                continue;
            }
            assert_true(cd < 1.0f);
            if (cases[c].du == 0)
                assert_float_equal(d[2], 0.0f, 0.0f); /* nor the gutter's blue at level 0 */
            if (cases[c].du >= 12) {
                print_message("filter %u k %d: clamp green %.4f, discard coverage %.4f\n",
                              cases[c].filter, k, cl[1], cd);
                assert_true(cl[1] > 0.01f); /* Clamp bleeds B */
            } else {
                assert_true(cl[2] > 0.01f); /* Clamp bleeds the gutter */
            }
        }
    }
    st_set_free(s);
}

/* Where a query's footprint lies well inside its chart, Discard takes the fast path as Clamp
 * and Traverse do: the three agree bit for bit, coverage exactly 1. */
static void chart_discard_equals_clamp_bit_for_bit_inside_a_chart(void **state)
{
    (void)state;
    st_set *s = two_chart_atlas();
    enum { N = 512 };
    st_query q[N];
    unsigned r = 12345;
    for (int i = 0; i < N; i++) {
        r = r * 1103515245u + 12345u;
        float a = (float)(r >> 8) / 16777216.0f;
        r = r * 1103515245u + 12345u;
        float b = (float)(r >> 8) / 16777216.0f;
        r = r * 1103515245u + 12345u;
        float f = (float)(r >> 8) / 16777216.0f * 2.0f; /* up to 2 texels: levels 0..2 */
        int chart_b = i & 1;
        /* columns 6..20 of A or 42..56 of B, rows 3..28: inside the chart at levels 0..2 */
        q[i] = (st_query){.face = 0, .u = ((chart_b ? 42.0f : 6.0f) + 14.0f * a) / 64.0f,
                          .v = (3.0f + 25.0f * b) / 32.0f, .dudx = f / 64.0f,
                          .dvdx = (i % 3) * f / 128.0f, .dudy = 0, .dvdy = f / 32.0f};
        if (i % 5 == 0)
            q[i].dudx = q[i].dvdx = q[i].dvdy = 0;
    }
    static const uint8_t filters[4] = {ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR,
                                       ST_FILTER_ANISO};
    for (int f = 0; f < 4; f++) {
        float out[3][N * 4], cov[3][N];
        uint8_t st[3][N];
        for (int m = 0; m < 3; m++) {
            st_sample_opts o = {.mode = (uint8_t)m, .filter = filters[f], .max_aniso = 4};
            assert_int_equal(st_sample_batch(s, &o, q, N, out[m], cov[m], st[m]), 0);
        }
        assert_memory_equal(out[ST_MODE_DISCARD], out[ST_MODE_CLAMP], sizeof out[0]);
        assert_memory_equal(out[ST_MODE_TRAVERSE], out[ST_MODE_CLAMP], sizeof out[0]);
        for (int i = 0; i < N; i++)
            assert_float_equal(cov[ST_MODE_DISCARD][i], 1.0f, 0.0f);
    }
    st_set_free(s);
}

/* The chart of a query in the gutter is the nearest chart texel among the 3 x 3 around it;
 * with none there, Discard takes the image as one face (the rule before chart Discard). */
static void chart_discard_in_the_gutter(void **state)
{
    (void)state;
    st_set *s = two_chart_atlas();
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_BILINEAR};
    st_query q[2] = {{.face = 0, .u = 28.2f / 64.0f, .v = 0.5f},  /* gutter column 28 */
                     {.face = 0, .u = 32.0f / 64.0f, .v = 0.5f}}; /* gutter middle */
    float out[8], cov[2];
    uint8_t st[2];
    assert_int_equal(st_sample_batch(s, &o, q, 2, out, cov, st), 0);
    /* column 27 (A) is the nearest: the taps on 27 and 28 keep 27 alone */
    const uint8_t *p = st_face_level(s, 0, 0) + ((size_t)15 * 64 + 27) * 4;
    const uint8_t *p2 = st_face_level(s, 0, 0) + ((size_t)16 * 64 + 27) * 4;
    assert_float_equal(out[0], 0.5f * (p[0] + p2[0]) / 255.0f, 1e-5);
    assert_float_equal(cov[0], 0.3f, 1e-5);
    /* no chart within a texel: the image as one face, the gutter's blue, coverage 1 */
    assert_float_equal(out[6], 1.0f, 0.0f);
    assert_float_equal(cov[1], 1.0f, 0.0f);
    st_set_free(s);
}

/* The query's chart at triangle resolution: two charts that touch in UV with no gutter, A
 * over [0, 30.4] texels and B over [30.4, 64] (x), two unit squares apart in 3D (no seam between
 * them). Column 30's centre (30.5) lies in B, so its id is B's; a query at x = 30.2 lies in A's
 * triangle, and Discard and Traverse read A there (the texel rule took B: green, coverage 0.7). */
static void query_chart_is_the_triangle_s_where_charts_touch(void **state)
{
    (void)state;
    st_mesh *m = two_apart(30.4f / 64.0f, 30.4f / 64.0f);
    static uint8_t px[32][64][4];
    for (int j = 0; j < 32; j++)
        for (int i = 0; i < 64; i++) {
            uint8_t g = (uint8_t)(64 + (i * 3 + j * 5) % 128);
            px[j][i][0] = i < 30 ? g : 0;
            px[j][i][1] = i >= 30 ? g : 0;
            px[j][i][2] = 0;
            px[j][i][3] = 255;
        }
    st_set *s = two_charts_of(&px[0][0][0], 64, 32, m);
    const st_atlas *a = st_atlas_get(s);
    assert_int_equal(a->ids.level[0][16 * 64 + 30], a->ids.level[0][16 * 64 + 40]);   /* B's */
    assert_non_null(a->ids.near_bits);
    const uint8_t *p15 = st_face_level(s, 0, 0) + ((size_t)15 * 64 + 29) * 4;
    const uint8_t *p16 = st_face_level(s, 0, 0) + ((size_t)16 * 64 + 29) * 4;
    for (int mode = 0; mode < 2; mode++) {
        st_sample_opts o = {.mode = mode ? ST_MODE_TRAVERSE : ST_MODE_DISCARD,
                            .filter = ST_FILTER_BILINEAR};
        /* in A (left of 30.4), on column 30 (B's id); then in B on the same texel */
        st_query q[2] = {{.face = 0, .u = 30.2f / 64.0f, .v = 0.5f},
                         {.face = 0, .u = 30.6f / 64.0f, .v = 0.5f}};
        float out[8], cov[2];
        uint8_t st[2];
        assert_int_equal(st_sample_batch(s, &o, q, 2, out, cov, st), 0);
        /* A: column 29's two rows alone (column 30 is B's: dropped), red, no green */
        assert_float_equal(out[0], 0.5f * (p15[0] + p16[0]) / 255.0f, 1e-5);
        assert_float_equal(out[1], 0.0f, 0.0f);
        assert_float_equal(cov[0], 0.3f, 1e-5);
        /* B: columns 30 and 31 are B's, no red */
        assert_float_equal(out[4], 0.0f, 0.0f);
        assert_true(out[5] > 0.0f);
        assert_float_equal(cov[1], 1.0f, 1e-6);
    }
    st_set_free(s);
}

/* Chart Traverse. A 64 x 64 RGBA8 atlas of two unit squares side by side in 3D, A over
 * [0, 1] x [0, 1] and B over [1, 2] x [0, 1], sharing the edge x = 1 (a UV seam): A's chart at
 * columns and rows 0..27, B's at columns 36..63, rows 0..27 - as A is (turn 0), turned a
 * quarter (turn 1) or mirrored (turn 2) - the rest a blue gutter. Every chart texel holds the
 * surface function red = x / 2, green = y at its centre, so reading across the seam on the
 * surface continues the same straight ramps. */
/* The two unit squares of seam_atlas in 3D, A over [0, 1] x [0, 1] and B over [1, 2] x [0, 1]
 * sharing x = 1, two triangles each, with the UVs uv: A's corners (0,0) (1,0) (1,1) (0,1), then
 * B's (1,0) (2,0) (2,1) (1,1), 8 pairs. */
static st_mesh *two_squares(const float uv[16])
{
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_mesh_alloc(6, 8, 4, &m, &e), ST_OK);
    const float pos[18] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 2, 1, 0};
    const uint32_t tp[12] = {0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2};
    const uint32_t tu[12] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
    memcpy(m->pos, pos, sizeof pos);
    memcpy(m->tri_pos, tp, sizeof tp);
    memcpy(m->tri_uv, tu, sizeof tu);
    memcpy(m->uv, uv, 16 * sizeof *uv);
    return m;
}

/* An RGBA8 texel of the two squares' surface at (x, y): red = x / 2, green = y; x < 0 is the
 * gutter, blue. */
static void surface_texel(uint8_t *p, float x, float y)
{
    p[0] = x < 0 ? 0 : (uint8_t)lrintf(x / 2.0f * 255.0f);
    p[1] = x < 0 ? 0 : (uint8_t)lrintf(y * 255.0f);
    p[2] = x < 0 ? 255 : 0;
    p[3] = 255;
}

static st_set *seam_atlas(int turn)
{
    const float o = 36.0f / 64.0f, z = 28.0f / 64.0f;
    /* A's corners (0,0) (1,0) (1,1) (0,1); B's (1,0) (2,0) (2,1) (1,1) as placed */
    const float uv[3][16] = {
        {0, 0, z, 0, z, z, 0, z, o, 0, o + z, 0, o + z, z, o, z},  /* x - 1 -> u, y -> v */
        {0, 0, z, 0, z, z, 0, z, o + z, 0, o + z, z, o, z, o, 0},  /* 1 - y -> u, x - 1 -> v */
        {0, 0, z, 0, z, z, 0, z, o, 0, o, z, o + z, z, o + z, 0},  /* y -> u, x - 1 -> v */
    };
    st_mesh *m = two_squares(uv[turn]);
    static uint8_t px[64][64][4];
    for (int j = 0; j < 64; j++)
        for (int i = 0; i < 64; i++) {
            float x = -1, y = -1;
            if (j < 28 && i < 28) {
                x = (i + 0.5f) / 28.0f;
                y = (j + 0.5f) / 28.0f;
            } else if (i >= 36 && j < 28) {
                float a = (i - 36 + 0.5f) / 28.0f, b = (j + 0.5f) / 28.0f;
                x = 1.0f + (turn == 0 ? a : b);
                y = turn == 0 ? b : turn == 1 ? 1.0f - a : a;
            }
            surface_texel(px[j][i], x, y);
        }
    st_set *s = two_charts_of(&px[0][0][0], 64, 64, m);
    const st_atlas *a = st_atlas_get(s);
    assert_int_equal(a->mesh->seams->nseams, 1);
    assert_true(a->ids.nlink[0] > 0);
    return s;
}

/* Near the seam, Traverse reads B's texels for the taps past A's edge: the surface ramps go on
 * (value within u8 rounding of the function at the query's point), coverage 1, no gutter blue
 * - where Discard renormalises A's taps alone (coverage < 1) and Clamp reads the gutter - for B
 * as placed, turned and mirrored, at level 0 and coarser levels, point, bilinear, trilinear
 * and aniso. */
static void chart_traverse_reads_across_the_seam(void **state)
{
    (void)state;
    struct {
        uint8_t filter;
        float du, dv;   /* footprint in level-0 texels */
        float tol;
    } cases[] = {
        {ST_FILTER_BILINEAR, 0, 0, 1.0f},
        {ST_FILTER_BILINEAR, 4, 4, 1.5f},    /* level 2 */
        {ST_FILTER_TRILINEAR, 3, 3, 1.5f},   /* levels 1 and 2 */
        {ST_FILTER_ANISO, 8, 1, 1.5f},       /* 8 probes along x across the seam */
    };
    for (int turn = 0; turn < 3; turn++) {
        st_set *s = seam_atlas(turn);
        for (size_t c = 0; c < sizeof cases / sizeof *cases; c++)
            for (int k = 0; k < 6; k++) {
                float tx = 27.55f + 0.05f * (float)k, ty = 6.3f + 3.0f * (float)k;
                st_query q = {.face = 0, .u = tx / 64.0f, .v = ty / 64.0f,
                              .dudx = cases[c].du / 64.0f, .dvdy = cases[c].dv / 64.0f};
                float t[4], d[4], cl[4], ct, cd, cc;
                uint8_t st;
                st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = cases[c].filter,
                                    .max_aniso = 8};
                assert_int_equal(st_sample_batch(s, &o, &q, 1, t, &ct, &st), 0);
                o.mode = ST_MODE_DISCARD;
                assert_int_equal(st_sample_batch(s, &o, &q, 1, d, &cd, &st), 0);
                o.mode = ST_MODE_CLAMP;
                assert_int_equal(st_sample_batch(s, &o, &q, 1, cl, &cc, &st), 0);
                float fx = tx / 28.0f / 2.0f, fy = ty / 28.0f;
                if (fabsf(t[0] - fx) * 255.0f > cases[c].tol ||
                    fabsf(t[1] - fy) * 255.0f > cases[c].tol || t[2] != 0.0f ||
                    fabsf(ct - 1.0f) > 1e-6f)
                    fail_msg("turn %d filter %u k %d: Traverse (%g %g %g) coverage %g, the "
                             "surface (%g %g 0); Discard (%g %g) coverage %g", turn,
                             cases[c].filter, k, t[0], t[1], t[2], ct, fx, fy, d[0], d[1], cd);
                assert_true(cd < 1.0f);      /* Discard dropped the taps past the seam */
                assert_true(cl[2] > 0.01f);  /* Clamp read the gutter's blue */
            }
        /* a point query in the gutter next to A: its chart is A, its texel is past A's edge:
         * Traverse reads the texel across the seam, Discard has nothing */
        st_query q = {.face = 0, .u = 28.3f / 64.0f, .v = 10.5f / 64.0f};
        float t[4], ct;
        uint8_t st;
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_POINT};
        assert_int_equal(st_sample_batch(s, &o, &q, 1, t, &ct, &st), 0);
        assert_float_equal(t[0], (1.0f + 0.5f / 28.0f) / 2.0f, 0.5f / 255.0f);
        assert_float_equal(t[1], 10.5f / 28.0f, 0.5f / 255.0f);
        assert_float_equal(ct, 1.0f, 0.0f);
        o.mode = ST_MODE_DISCARD;
        assert_int_equal(st_sample_batch(s, &o, &q, 1, t, &ct, &st), 1);
        assert_int_equal(st, ST_Q_ZERO_COVERAGE);
        st_set_free(s);
    }
}

/* Per-chart mips: a texel of level L >= 1 with a chart id is the mean of those of its level
 * L - 1 texels with that id alone - no gutter, no other chart - and a texel without an id the
 * mean of all of its texels (the box mean). */
static void per_chart_mips_keep_each_chart_to_itself(void **state)
{
    (void)state;
    st_set *s = two_chart_atlas();
    const st_atlas *a = st_atlas_get(s);
    const st_face *F = &s->faces[0];
    uint16_t ida = a->ids.level[0][0], idb = a->ids.level[0][63];
    assert_true(ida && idb && ida != idb);
    unsigned mixed = 0; /* chart texels whose 2 x 2 holds the gutter or the other chart */
    for (unsigned l = 1; l < F->nlevels; l++) {
        uint32_t sw = st_level_w(F, l - 1), dw = st_level_w(F, l), dh = st_level_h(F, l);
        uint32_t xs = sw > 1 ? 2 : 1, ys = st_level_h(F, l - 1) > 1 ? 2 : 1;
        const uint8_t *src = st_face_level(s, 0, l - 1), *dst = st_face_level(s, 0, l);
        for (uint32_t y = 0; y < dh; y++)
            for (uint32_t x = 0; x < dw; x++) {
                uint16_t d = a->ids.level[l][y * dw + x];
                float acc[4] = {0};
                unsigned n = 0, other = 0;
                for (uint32_t j = 0; j < ys; j++)
                    for (uint32_t i = 0; i < xs; i++) {
                        size_t t = (size_t)(y * ys + j) * sw + x * xs + i;
                        if (d && a->ids.level[l - 1][t] != d) {
                            other++;
                            continue;
                        }
                        for (int c = 0; c < 4; c++)
                            acc[c] += src[t * 4 + c];
                        n++;
                    }
                mixed += d && other;
                const uint8_t *p = dst + ((size_t)y * dw + x) * 4;
                for (int c = 0; c < 4; c++)
                    if (fabsf((float)p[c] - acc[c] / (float)n) > 0.5f + 1e-3f)
                        fail_msg("level %u texel (%u, %u) id %u channel %d: %u, the mean of its "
                                 "%u texels of that id %g", l, x, y, d, c, p[c], n,
                                 acc[c] / (float)n);
                if (d == ida)
                    assert_true(p[1] == 0 && p[2] == 0); /* A: red alone */
                else if (d == idb)
                    assert_true(p[0] == 0 && p[2] == 0); /* B: green alone */
            }
    }
    assert_true(mixed > 0); /* the case was met: chart texels next to the gutter */
    st_set_free(s);
    /* sampled: trilinear across A's edge at levels 3 and 4, where a texel of A takes 4 of
     * its 8 columns from the gutter - Traverse and Discard read no blue and stay near the
     * surface's ramps: Traverse within 8 steps of 255, Discard (which renormalises A's taps
     * alone) within 15 (box mips over the whole image gave blue 73-107 and red 36-62 steps
     * short: a texel of A there averaged the gutter) */
    for (int turn = 0; turn < 3; turn++) {
        s = seam_atlas(turn);
        for (int k = 0; k < 6; k++) {
            float tx = 26.0f + 0.3f * (float)k, ty = 8.3f + 2.0f * (float)k;
            st_query q = {.face = 0, .u = tx / 64.0f, .v = ty / 64.0f, .dudx = 12.0f / 64.0f,
                          .dvdy = 12.0f / 64.0f};
            float fx = tx / 28.0f / 2.0f, fy = ty / 28.0f;
            for (uint8_t mode = ST_MODE_DISCARD; mode <= ST_MODE_TRAVERSE; mode++) {
                st_sample_opts o = {.mode = mode, .filter = ST_FILTER_TRILINEAR};
                float t[4], ct;
                uint8_t st;
                assert_int_equal(st_sample_batch(s, &o, &q, 1, t, &ct, &st), 0);
                float tol = mode == ST_MODE_TRAVERSE ? 8.0f : 15.0f;
                if (t[2] != 0.0f || fabsf(t[0] - fx) * 255.0f > tol ||
                    fabsf(t[1] - fy) * 255.0f > tol)
                    fail_msg("turn %d k %d mode %u: (%g %g %g), the surface (%g %g 0)", turn, k,
                             mode, t[0], t[1], t[2], fx, fy);
            }
        }
        st_set_free(s);
    }
}

/* Chart Traverse across a seam to a denser chart: A (28 x 28 texels) and B (40 x 40, 1.43x
 * the density) of a 96 x 64 atlas, the same two squares in 3D as seam_atlas. The seam carries a
 * texel centre of A to a point between B's texel centres; reading B bilinearly there continues
 * the surface's ramps (red = x / 2, green = y) to within the u8 rounding (measured: mean 0.21,
 * max 0.28 steps of 255), where reading B's one texel under the point was up to half of B's
 * texel off (mean 0.53, max 1.18). */
static void chart_traverse_reads_between_texels_of_a_denser_chart(void **state)
{
    (void)state;
    const float az = 28.0f / 96.0f, av = 28.0f / 64.0f, b0 = 44.0f / 96.0f, b1 = 84.0f / 96.0f,
                bv = 40.0f / 64.0f;
    const float uv[16] = {0, 0, az, 0, az, av, 0, av, b0, 0, b1, 0, b1, bv, b0, bv};
    st_mesh *m = two_squares(uv);
    static uint8_t px[64][96][4];
    for (int j = 0; j < 64; j++)
        for (int i = 0; i < 96; i++) {
            float x = -1, y = -1;
            if (j < 28 && i < 28) {
                x = (i + 0.5f) / 28.0f;
                y = (j + 0.5f) / 28.0f;
            } else if (i >= 44 && i < 84 && j < 40) {
                x = 1.0f + (i - 44 + 0.5f) / 40.0f;
                y = (j + 0.5f) / 40.0f;
            }
            surface_texel(px[j][i], x, y);
        }
    st_set *s = two_charts_of(&px[0][0][0], 96, 64, m);
    assert_true(st_atlas_get(s)->ids.nlink[0] > 0);
    double worst = 0, sum = 0;
    int n = 0;
    for (int k = 0; k < 40; k++) {
        /* bilinear at level 0, 25-45 % of its weight past A's edge (column 27.75 .. 27.95) */
        float tx = 27.75f + 0.05f * (float)(k % 5), ty = 2.3f + 0.6f * (float)k;
        st_query q = {.face = 0, .u = tx / 96.0f, .v = ty / 64.0f};
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_BILINEAR};
        float t[4], ct;
        uint8_t st;
        assert_int_equal(st_sample_batch(s, &o, &q, 1, t, &ct, &st), 0);
        float fx = tx / 28.0f / 2.0f, fy = ty / 28.0f;
        double err = fmax(fabs(t[0] - fx), fabs(t[1] - fy)) * 255.0;
        if (t[2] != 0.0f || fabsf(ct - 1.0f) > 1e-6f)
            fail_msg("k %d: (%g %g %g) coverage %g", k, t[0], t[1], t[2], ct);
        worst = fmax(worst, err);
        sum += err;
        n++;
    }
    print_message("denser chart: error to the surface, steps of 255: mean %.3f, max %.3f\n",
                  sum / n, worst);
    assert_true(worst < 0.6);
    st_set_free(s);
}

/* Four unit squares of a plane in 3D - (a, b) over [a, a + 1] x [b, b + 1], a, b in {0, 1} -
 * meeting at the vertex (1, 1), each its own chart in a 72 x 72 atlas: square (a, b) over
 * texels [4 + 36a, 32 + 36a) x [4 + 36b, 32 + 36b), (1, 1) turned a quarter, the rest a blue
 * gutter (4 texels at the image's border: a tap beyond the image has no link);
 * every chart texel holds red = x / 2, green = y / 2 of its centre on the surface. */
static st_set *four_charts_at_a_vertex(void)
{
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_mesh_alloc(9, 16, 8, &m, &e), ST_OK);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            m->pos[(j * 3 + i) * 3] = (float)i;
            m->pos[(j * 3 + i) * 3 + 1] = (float)j;
            m->pos[(j * 3 + i) * 3 + 2] = 0;
        }
    for (int q = 0; q < 4; q++) {
        int a = q & 1, b = q >> 1;
        uint32_t c[4] = {(uint32_t)(b * 3 + a), (uint32_t)(b * 3 + a + 1),
                         (uint32_t)((b + 1) * 3 + a + 1), (uint32_t)((b + 1) * 3 + a)};
        float ox = 4.0f + 36.0f * (float)a, oy = 4.0f + 36.0f * (float)b;
        /* the corners' texel places: (0,0) (28,0) (28,28) (0,28), square (1, 1) turned */
        const float loc[2][8] = {{0, 0, 28, 0, 28, 28, 0, 28}, {28, 0, 28, 28, 0, 28, 0, 0}};
        for (int k = 0; k < 4; k++) {
            m->uv[(q * 4 + k) * 2] = (ox + loc[q == 3][2 * k]) / 72.0f;
            m->uv[(q * 4 + k) * 2 + 1] = (oy + loc[q == 3][2 * k + 1]) / 72.0f;
        }
        const int tri[6] = {0, 1, 2, 0, 2, 3};
        for (int k = 0; k < 6; k++) {
            m->tri_pos[q * 6 + k] = c[tri[k]];
            m->tri_uv[q * 6 + k] = (uint32_t)(q * 4 + tri[k]);
        }
    }
    static uint8_t px[72][72][4];
    for (int j = 0; j < 72; j++)
        for (int i = 0; i < 72; i++) {
            int a = i >= 40, b = j >= 40, li = i - 4 - 36 * a, lj = j - 4 - 36 * b;
            uint8_t *p = px[j][i];
            if (li < 0 || lj < 0 || li >= 28 || lj >= 28) {
                p[0] = p[1] = 0;
                p[2] = p[3] = 255;
                continue;
            }
            float sx = (li + 0.5f) / 28.0f, ty = (lj + 0.5f) / 28.0f;
            float x = (float)a + sx, y = (float)b + ty;
            if (a && b) {   /* turned: texel-local (s, t) = (1 - (y - 1), x - 1) */
                x = 1.0f + ty;
                y = 2.0f - sx;
            }
            p[0] = (uint8_t)lrintf(x / 2.0f * 255.0f);
            p[1] = (uint8_t)lrintf(y / 2.0f * 255.0f);
            p[2] = 0;
            p[3] = 255;
        }
    st_image img = {.w = 72, .h = 72, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                    .data = &px[0][0][0]};
    st_set *s = NULL;
    assert_int_equal(st_atlas_from_image(&img, m, 0, &s, &e), ST_OK);
    const st_atlas *at = st_atlas_get(s);
    assert_int_equal(at->mesh->seams->ncharts, 4);
    assert_int_equal(at->mesh->seams->nseams, 4);
    return s;
}

/* Where four charts meet at a vertex, a tap past the query's chart's corner lies in the chart
 * diagonally across the vertex, which shares no seam with the query's chart: it is carried
 * across the seam to a neighbour and on across that neighbour's seam at the same vertex. So
 * Traverse near the corner reads every tap (coverage 1), on the surface's ramps (red = x / 2,
 * green = y / 2), no gutter blue - before, those taps had no link and were dropped (bilinear
 * 0.2 texels from the corner: coverage 0.91) - from each of the four charts' corners, at level
 * 0 and coarser levels. */
static void chart_traverse_reads_across_a_vertex_of_four_charts(void **state)
{
    (void)state;
    st_set *s = four_charts_at_a_vertex();
    struct {
        uint8_t filter;
        float fp;   /* footprint in level-0 texels */
        float tol;  /* steps of 255 */
    } cases[] = {
        {ST_FILTER_BILINEAR, 0, 1.0f},
        {ST_FILTER_BILINEAR, 2, 1.5f},    /* level 1 */
        {ST_FILTER_TRILINEAR, 3, 2.0f},   /* levels 1 and 2 */
    };
    /* each chart's corner at the shared vertex, in its own texels, and the surface there */
    for (int q = 0; q < 4; q++)
        for (size_t c = 0; c < sizeof cases / sizeof *cases; c++)
            for (int k = 0; k < 5; k++) {
                /* d: how far inside the chart, from its corner, in level-0 texels */
                float d = 0.2f + 0.15f * (float)k, dd = d * (1.0f + 0.3f * (float)(k & 1));
                float a = q & 1, b = q >> 1, tx, ty, x, y;
                if (q == 3) {   /* turned: the vertex (1, 1) is texel-local (28, 0) */
                    tx = 40.0f + 28.0f - d;
                    ty = 40.0f + dd;
                    x = 1.0f + dd / 28.0f;
                    y = 1.0f + d / 28.0f;
                } else {
                    tx = a ? 40.0f + d : 32.0f - d;
                    ty = b ? 40.0f + dd : 32.0f - dd;
                    x = a ? 1.0f + d / 28.0f : 1.0f - d / 28.0f;
                    y = b ? 1.0f + dd / 28.0f : 1.0f - dd / 28.0f;
                }
                st_query qq = {.face = 0, .u = tx / 72.0f, .v = ty / 72.0f,
                               .dudx = cases[c].fp / 72.0f, .dvdy = cases[c].fp / 72.0f};
                st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = cases[c].filter};
                float t[4], ct;
                uint8_t st;
                assert_int_equal(st_sample_batch(s, &o, &qq, 1, t, &ct, &st), 0);
                float er = fabsf(t[0] - x / 2.0f) * 255.0f, eg = fabsf(t[1] - y / 2.0f) * 255.0f;
                if (fabsf(ct - 1.0f) > 1e-6f || t[2] != 0.0f || er > cases[c].tol ||
                    eg > cases[c].tol)
                    fail_msg("chart %d filter %u fp %g d %g: Traverse (%g %g %g) coverage %g, "
                             "the surface (%g %g 0): %g %g steps", q, cases[c].filter,
                             (double)cases[c].fp, (double)d, t[0], t[1], t[2], ct, x / 2.0f,
                             y / 2.0f, er, eg);
            }
    st_set_free(s);
}

/* A mesh of 400 seams each drawn across the whole of a 1024^2 image (a hostile upload: each
 * seam side's band is about 26 K texels of level 0): level 0's bands would cover more than 8
 * times its texels plus 512 a seam, so it gets no links (Traverse is chart Discard there) -
 * the import neither fails nor takes time and memory out of proportion - while levels whose
 * bands fit keep theirs, and sampling works in every mode. */
static void seams_over_the_whole_image_are_bounded(void **state)
{
    (void)state;
    enum { NP = 400, W = 1024 };
    st_mesh *m = NULL;
    st_error e;
    assert_int_equal(st_mesh_alloc(4 * NP, 6 * NP, 2 * NP, &m, &e), ST_OK);
    for (uint32_t p = 0; p < NP; p++) {
        /* 3D: A B C and A B D, the pair apart from every other pair */
        const float pos[12] = {0, 0, (float)p, 1, 1, (float)p, 1, 0, (float)p, 0, 1, (float)p};
        memcpy(&m->pos[p * 12], pos, sizeof pos);
        /* A B along the image's diagonal on one side, a slightly other diagonal on the other */
        float d = 0.0005f * (float)(1 + p % 7);
        const float uv[12] = {d, 0, 1, 1 - d, 1, 0, 0, d, 1 - d, 1, 0, 1};
        memcpy(&m->uv[p * 12], uv, sizeof uv);
        const uint32_t tp[6] = {4 * p, 4 * p + 1, 4 * p + 2, 4 * p, 4 * p + 1, 4 * p + 3};
        const uint32_t tu[6] = {6 * p, 6 * p + 1, 6 * p + 2, 6 * p + 3, 6 * p + 4, 6 * p + 5};
        memcpy(&m->tri_pos[p * 6], tp, sizeof tp);
        memcpy(&m->tri_uv[p * 6], tu, sizeof tu);
    }
    uint8_t *px = calloc((size_t)W * W, 4);
    assert_non_null(px);
    st_image img = {.w = W, .h = W, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3, .data = px};
    st_set *s = NULL;
    assert_int_equal(st_atlas_from_image(&img, m, 0, &s, &e), ST_OK);
    free(px);
    const st_atlas *a = st_atlas_get(s);
    assert_int_equal(a->mesh->seams->nseams, NP);
    assert_true(a->ids.nlevels > 0);
    assert_int_equal(a->ids.nlink[0], 0);
    size_t coarse = 0;
    for (unsigned l = 1; l < a->ids.nlevels; l++)
        coarse += a->ids.nlink[l];
    print_message("links by level 0 / coarser: %zu / %zu\n", a->ids.nlink[0], coarse);
    assert_true(coarse > 0);
    st_query q[64];
    memset(q, 0, sizeof q);
    for (int i = 0; i < 64; i++) {
        q[i].u = (float)i / 64.0f;
        q[i].v = 1.0f - (float)i / 64.0f;
        q[i].dudx = q[i].dvdy = (float)(i % 4) / 256.0f;
    }
    for (unsigned mode = 0; mode < 3; mode++) {
        st_sample_opts o = {.mode = (uint8_t)mode, .filter = ST_FILTER_TRILINEAR};
        float out[64 * 4], cov[64];
        uint8_t st[64];
        assert_true(st_sample_batch(s, &o, q, 64, out, cov, st) >= 0);
    }
    st_set_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(two_triangles_with_split_uvs_make_one_seam),
        cmocka_unit_test(chart_discard_does_not_bleed_the_other_chart_at_any_level),
        cmocka_unit_test(chart_discard_equals_clamp_bit_for_bit_inside_a_chart),
        cmocka_unit_test(chart_discard_in_the_gutter),
        cmocka_unit_test(query_chart_is_the_triangle_s_where_charts_touch),
        cmocka_unit_test(chart_traverse_reads_across_the_seam),
        cmocka_unit_test(seams_over_the_whole_image_are_bounded),
        cmocka_unit_test(per_chart_mips_keep_each_chart_to_itself),
        cmocka_unit_test(chart_traverse_reads_between_texels_of_a_denser_chart),
        cmocka_unit_test(chart_traverse_reads_across_a_vertex_of_four_charts),
        cmocka_unit_test(shared_uvs_are_not_a_seam_even_with_duplicate_vt_entries),
        cmocka_unit_test(mirrored_chart_is_flagged),
        cmocka_unit_test(welding_merges_split_positions_before_seams),
        cmocka_unit_test(three_triangles_on_one_edge_are_non_manifold),
        cmocka_unit_test(edge_to_a_triangle_without_uvs_is_not_a_seam),
        cmocka_unit_test(negative_zero_uv_is_the_same_coordinate_as_zero),
        cmocka_unit_test(shared_meshes_match_the_data_readme),
        cmocka_unit_test(draco_mesh_without_uvs_is_refused_with_enouv),
        cmocka_unit_test(duck_atlas_has_a_chart_mask_and_chart_discard_drops_outside_taps),
        cmocka_unit_test(atlas_sampling_takes_the_modes_as_the_wire_does),
        cmocka_unit_test(huge_uvs_keep_the_chart_mask_and_chart_discard_defined),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
