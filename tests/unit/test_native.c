/* tests/unit/test_native.c - the native set file (store/native/native.h): every kind of set
 * written and opened by mmap samples bit for bit as the heap set it was written from (every
 * mode and filter, the Ptex family included, many random queries); the mapped set points into
 * its mapping; a flipped bit in each section, a truncation at every section boundary and
 * offsets that lie are refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "atlas.h"
#include "bc1.h"
#include "crc32c.h"
#include "cube.h"
#include "mesh.h"
#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "ptexres.h"
#include "sample.h"
#include "../common/atlas_fixture.h"
#include "../common/cube_fixture.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

static char g_dir[512];

static int setup(void **st)
{
    (void)st;
    return st_test_mkdtemp(g_dir, sizeof g_dir, "native") == 0 ? 0 : -1;
}
static int teardown(void **st)
{
    (void)st;
    st_test_rmtree(g_dir);
    return 0;
}

static uint32_t rng(uint32_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return *s;
}
static float frand(uint32_t *s) { return (float)(rng(s) >> 8) * (1.0f / 16777216.0f); }

/* Writes s and opens it again (texel CRC checked too). */
static st_set *roundtrip(const st_set *s, const char *tag)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.native", g_dir, tag);
    st_error e;
    st_error_clear(&e);
    st_native_source src = {1234, 0xabcdef01u, "source-x.ptx"};
    int rc = st_native_write(path, s, &src, &e);
    if (rc)
        print_message("write %s: %s\n", tag, e.msg);
    assert_int_equal(rc, 0);
    st_set *m = NULL;
    st_native_source got;
    rc = st_native_open(path, ST_NATIVE_VERIFY, &got, &m, &e);
    if (rc)
        print_message("open %s: %s\n", tag, e.msg);
    assert_int_equal(rc, 0);
    assert_non_null(m->map);
    assert_true(m->texels >= (uint8_t *)m->map && m->texels < (uint8_t *)m->map + m->map_len);
    assert_true((uint8_t *)m->faces >= (uint8_t *)m->map);
    assert_int_equal(got.bytes, 1234);
    assert_int_equal(got.crc, 0xabcdef01u);
    assert_string_equal(got.name, "source-x.ptx");
    assert_memory_equal(&m->info, &s->info, offsetof(st_set_info, meshtype) + 1);
    assert_int_equal(m->texel_bytes, s->texel_bytes);
    assert_memory_equal(m->faces, s->faces, (size_t)s->info.nfaces * sizeof(st_face));
    assert_memory_equal(m->texels, s->texels, s->texel_bytes);
    assert_int_equal(m->nmeta, s->nmeta);
    for (uint32_t i = 0; i < s->nmeta; i++) {
        const st_meta_entry *x = st_set_meta_find(m, s->meta[i].key);
        assert_non_null(x);
        assert_int_equal(x->type, s->meta[i].type);
        assert_int_equal(x->count, s->meta[i].count);
    }
    assert_int_equal(m->ext.kind, s->ext.kind);
    return m;
}

/* Random queries over every face, a spread of footprints, some outside [0,1]. */
static void make_queries(const st_set *s, st_query *q, size_t n, uint32_t seed)
{
    for (size_t i = 0; i < n; i++) {
        q[i].face = rng(&seed) % s->info.nfaces;
        q[i].u = frand(&seed) * 1.2f - 0.1f;
        q[i].v = frand(&seed) * 1.2f - 0.1f;
        float sc = (rng(&seed) & 3) == 0 ? 0.0f : powf(2.0f, -(float)(rng(&seed) % 12));
        q[i].dudx = sc * (frand(&seed) - 0.3f);
        q[i].dvdx = sc * (frand(&seed) - 0.5f) * 0.5f;
        q[i].dudy = sc * (frand(&seed) - 0.5f) * 0.5f;
        q[i].dvdy = sc * (frand(&seed) - 0.3f);
    }
}

/* Every mode and filter (the Ptex family when the set has its table): bit for bit. */
static void same_sampling(const st_set *a, const st_set *b, size_t n)
{
    st_query *q = malloc(n * sizeof *q);
    unsigned nc = a->info.nchan;
    float *oa = malloc(n * nc * sizeof(float)), *ob = malloc(n * nc * sizeof(float));
    float *ca = malloc(n * sizeof(float)), *cb = malloc(n * sizeof(float));
    uint8_t *sa = malloc(n), *sb = malloc(n);
    make_queries(a, q, n, 0x9e3779b9u ^ a->info.nfaces);
    static const uint8_t filters[] = {
        ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR, ST_FILTER_ANISO,
        ST_FILTER_PTEX_POINT, ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,
        ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_BSPLINE,
        ST_FILTER_PTEX_CATMULLROM, ST_FILTER_PTEX_MITCHELL};
    int ptex_ok = 0;
    for (unsigned mode = 0; mode <= ST_MODE_CLAMP; mode++)
        for (size_t fi = 0; fi < sizeof filters; fi++) {
            st_sample_opts o = {.mode = (uint8_t)mode, .filter = filters[fi], .max_aniso = 8,
                                .sharpness = 0.5f};
            memset(oa, 0, n * nc * sizeof(float));
            memset(ob, 0, n * nc * sizeof(float));
            int ra = st_sample_batch(a, &o, q, n, oa, ca, sa);
            int rb = st_sample_batch(b, &o, q, n, ob, cb, sb);
            assert_int_equal(ra, rb);
            if (ra < 0)
                continue;
            ptex_ok += filters[fi] >= ST_FILTER_PTEX_POINT;
            assert_memory_equal(oa, ob, n * nc * sizeof(float));
            assert_memory_equal(ca, cb, n * sizeof(float));
            assert_memory_equal(sa, sb, n);
        }
    if (st_set_ext_get(a, ST_EXT_PTEXRES))
        assert_int_equal(ptex_ok, 3 * 8);  /* the lazy table was built and filtered */
    free(q);
    free(oa);
    free(ob);
    free(ca);
    free(cb);
    free(sa);
    free(sb);
}

static void check_kind(const st_set *s, const char *tag, size_t nq)
{
    st_set *m = roundtrip(s, tag);
    same_sampling(s, m, nq);
    /* the lazy Ptex table: nothing until used, counted once built, dropped and rebuilt */
    if (st_set_ext_get(m, ST_EXT_PTEXRES)) {
        assert_true(st_ptexres_built_bytes(m) > 0);
        size_t with = st_set_memory(m);
        assert_true(st_ptexres_drop(m) > 0);
        assert_int_equal(st_ptexres_built_bytes(m), 0);
        assert_true(st_set_memory(m) < with);
        same_sampling(s, m, nq / 4);
        assert_true(st_ptexres_built_bytes(m) > 0);
    }
    /* released pages fault back in with the same values: from the page cache (the mapped
     * count's release) and from the disk (the page-cache count's) */
    st_native_meter mt, cache = {-1};
    st_native_meter_open(&mt);
    st_native_release(m, &mt);
    same_sampling(s, m, nq / 4);
    st_native_release(m, &cache);
    same_sampling(s, m, nq / 4);
    st_native_meter_close(&mt);
    st_set_free(m);
}

/* ---- per-face sets of every texel type ------------------------------------------------------ */

static void test_perface_types(void **st)
{
    (void)st;
    static const struct { st_dtype dt; unsigned nc; } types[] = {
        {ST_DT_U8, 4}, {ST_DT_U8, 1}, {ST_DT_U16, 3}, {ST_DT_HALF, 2}, {ST_DT_F32, 3},
        {ST_DT_F32, 1}};
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++) {
        cf_cube c;
        assert_int_equal(cf_cube_build(&c, 2, 7 + (uint32_t)i, 2, 5, 11, types[i].dt,
                                       types[i].nc), 0);
        st_error e;
        assert_int_equal(st_ptexfilter_prepare(c.set, &e), 0);
        assert_int_equal(st_set_meta_add(c.set, "note", 0, "hello", 6, &e), 0);
        double d[2] = {1.5, -2};
        assert_int_equal(st_set_meta_add(c.set, "pair", 5, d, 2, &e), 0);
        char tag[32];
        snprintf(tag, sizeof tag, "perface%zu", i);
        check_kind(c.set, tag, 1500);
        cf_cube_free(&c);
    }
}

/* A .ptx read by the Ptex reader (stored reductions, constant faces) */
static void test_ptex_files(void **st)
{
    (void)st;
    size_t len;
    st_error e;
    for (int k = 0; k < 2; k++) {
        void *buf = k ? st_fixture_uniform_ptx(&len) : st_fixture_default_ptx(&len, 1);
        assert_non_null(buf);
        st_set *s = NULL;
        assert_int_equal(st_ptex_read_mem(buf, len, 0, &s, &e), 0);
        free(buf);
        check_kind(s, k ? "ptx-uniform" : "ptx-default", 1500);
        st_set_free(s);
    }
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptex-ref/cube8_k7varrot_f32.ptx") == 0) {
        st_set *s = NULL;
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        check_kind(s, "ptx-cube8", 3000);
        st_set_free(s);
    } else {
        print_message("SEAMTEX_DATA has no ptex-ref: the shared .ptx case is skipped\n");
    }
}

/* Constant faces mixed with textured ones, by hand */
static void test_constant_faces(void **st)
{
    (void)st;
    st_set_info info = {.nfaces = 4, .nchan = 3, .dtype = ST_DT_U8, .alpha_chan = -1};
    st_face_desc fd[4];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 4; f++) {
        fd[f].w = f == 1 ? 1 : 16;
        fd[f].h = f == 1 ? 1 : 8;
        fd[f].flags = f == 1 || f == 3 ? ST_FACE_CONSTANT : 0;
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
    }
    fd[0].adjface[1] = 2;
    fd[0].adjedge[1] = 3;
    fd[2].adjface[3] = 0;
    fd[2].adjedge[3] = 1;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    uint32_t seed = 5;
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)rng(&seed);
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_ptexfilter_prepare(s, &e), 0);
    check_kind(s, "constant", 1500);
    st_set_free(s);
}

static void test_cube(void **st)
{
    (void)st;
    st_set_info info = {.nchan = 3, .dtype = ST_DT_HALF, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_cube_create(&info, 16, 0, &s, &e), 0);
    uint32_t seed = 9;
    uint16_t *t = (uint16_t *)(void *)s->texels;
    for (size_t i = 0; i < s->texel_bytes / 2; i++)
        t[i] = st_float_to_half(frand(&seed));
    st_set_build_mips(s, UINT32_MAX);
    check_kind(s, "cube", 1500);
    st_set_free(s);
}

/* An atlas: image + a small mesh with a UV seam, and its BC1 compression */
static st_set *make_atlas(void)
{
    /* a quad folded at its diagonal, the two triangles in separate charts (a seam) */
    st_mesh *m = st_fixture_folded_quad();
    assert_non_null(m);
    st_error e;
    st_image img = {.w = 48, .h = 40, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3};
    img.data = malloc(48 * 40 * 4);
    uint32_t seed = 3;
    for (int i = 0; i < 48 * 40 * 4; i++)
        ((uint8_t *)img.data)[i] = (uint8_t)(rng(&seed) | (i % 4 == 3 ? 0x80 : 0));
    st_set *s = NULL;
    assert_int_equal(st_atlas_from_image(&img, m, 0, &s, &e), 0);
    free(img.data);
    const st_atlas *a = st_atlas_get(s);
    assert_non_null(a);
    assert_non_null(a->mesh->seams);
    assert_int_equal(a->mesh->seams->nseams, 1);
    return s;
}

static void test_atlas_and_bc1(void **st)
{
    (void)st;
    st_set *s = make_atlas();
    st_set *m = roundtrip(s, "atlas");
    same_sampling(s, m, 2000);
    const st_atlas *x = st_atlas_get(s), *y = st_atlas_get(m);
    assert_non_null(y);
    assert_string_equal(x->texture_name, y->texture_name);
    assert_int_equal(x->mask_w, y->mask_w);
    assert_memory_equal(x->chart_mask, y->chart_mask, (size_t)x->mask_w * x->mask_h);
    /* the chart ids of chart Discard are not in the file: rebuilt from the mesh, the same */
    assert_true(x->ids.nlevels > 0);
    assert_int_equal(y->ids.nlevels, x->ids.nlevels);
    assert_int_equal(y->chart_id_bytes, x->chart_id_bytes);
    assert_memory_equal(x->chart_id, y->chart_id, x->chart_id_bytes);
    /* and so are chart Traverse's links across the seam */
    assert_true(x->ids.nlink[0] > 0);
    assert_int_equal(y->chart_link_bytes, x->chart_link_bytes);
    assert_memory_equal(x->chart_link, y->chart_link, x->chart_link_bytes);
    for (unsigned l = 0; l < x->ids.nlevels; l++)
        assert_int_equal(y->ids.nlink[l], x->ids.nlink[l]);
    assert_ptr_equal(m->ext.charts, &y->ids);
    assert_int_equal(y->mesh->ntri, 2);
    assert_memory_equal(x->mesh->tri_weld, y->mesh->tri_weld, 6 * 4);
    assert_int_equal(y->mesh->seams->nseams, 1);
    assert_memory_equal(&x->mesh->seams->seams[0], &y->mesh->seams->seams[0],
                        sizeof(st_seam_edge));
    assert_int_equal(y->mesh->seams->ncharts, x->mesh->seams->ncharts);
    assert_int_equal(st_mesh_memory(x->mesh), st_mesh_memory(y->mesh));
    /* chart-relative Discard reads the copied mask */
    st_query q[256];
    make_queries(s, q, 256, 77);
    float oa[256 * 4], ob[256 * 4], ca[256], cb[256];
    uint8_t sa[256], sb[256];
    st_sample_opts o = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_BILINEAR};
    assert_int_equal(st_atlas_sample(s, &o, ST_ATLAS_CHART_DISCARD, q, 256, oa, ca, sa),
                     st_atlas_sample(m, &o, ST_ATLAS_CHART_DISCARD, q, 256, ob, cb, sb));
    assert_memory_equal(oa, ob, sizeof oa);
    assert_memory_equal(ca, cb, sizeof ca);

    /* BC1 of the mapped atlas (the compressor reads the mapping) equals BC1 of the heap one */
    st_bc1_opts bo;
    st_bc1_opts_default(&bo);
    bo.level = ST_BC1_FAST;
    bo.threads = 1;
    st_set *b1 = NULL, *b2 = NULL;
    st_error e;
    assert_int_equal(st_bc1_compress_set(s, &bo, NULL, NULL, NULL, &b1, &e), 0);
    assert_int_equal(st_bc1_compress_set(m, &bo, NULL, NULL, NULL, &b2, &e), 0);
    assert_memory_equal(b1->texels, b2->texels, b1->texel_bytes);
    check_kind(b1, "bc1", 2000);
    const st_bc1_ext *bx = st_set_ext_get(b1, ST_EXT_BC1);
    st_set *bm = roundtrip(b1, "bc1b");
    assert_memory_equal(bx, st_set_ext_get(bm, ST_EXT_BC1), sizeof *bx);
    st_set_free(bm);
    st_set_free(b1);
    st_set_free(b2);
    st_set_free(m);
    st_set_free(s);
}

/* An atlas opened from its native file holds no chart data (ids, links, triangle lists) until
 * a chart Discard / chart Traverse sample needs it; then it is built once, the same bytes as
 * the heap atlas's, and counted (st_set_memory, st_set_heap_memory); a drop frees it unless a
 * sampler has it pinned, and the next chart sample rebuilds it with the same outputs. */
typedef struct chart_arg {
    const st_set *m;
    const st_query *q;
    size_t n;
    const float *ref;
    int mismatches;
} chart_arg;

static void *chart_sampler(void *p)
{
    chart_arg *a = p;
    float *out = malloc(a->n * 4 * sizeof(float));
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_TRILINEAR};
    for (int i = 0; i < 300; i++) {
        if (st_sample_batch(a->m, &o, a->q, a->n, out, NULL, NULL) < 0 ||
            memcmp(out, a->ref, a->n * a->m->info.nchan * sizeof(float)))
            a->mismatches++;
    }
    free(out);
    return NULL;
}

static void test_atlas_chart_data_is_lazy_counted_and_dropped(void **st)
{
    (void)st;
    st_set *s = make_atlas();
    const st_atlas *x = st_atlas_get(s);
    size_t built = x->chart_id_bytes + x->chart_link_bytes + x->loc.bytes;
    assert_true(x->ids.nlevels > 0 && x->chart_link_bytes > 0 && built > 0);
    st_set *m = roundtrip(s, "atlaslazy");
    const st_atlas *y = st_atlas_get(m);
    /* opened: nothing rasterised */
    assert_int_equal(y->ids.nlevels, 0);
    assert_null(y->chart_id);
    assert_null(y->chart_link);
    assert_int_equal(st_atlas_charts_built_bytes(m), 0);
    size_t mem0 = st_set_memory(m), heap0 = st_set_heap_memory(m);
    assert_true(heap0 >= st_mesh_memory(y->mesh) + (size_t)y->mask_w * y->mask_h);
    assert_true(heap0 < mem0);

    enum { N = 512 };
    st_query q[N];
    make_queries(s, q, N, 4242);
    unsigned nc = s->info.nchan;
    static float oa[N * 4], ob[N * 4], ca[N], cb[N];
    static uint8_t sa[N], sb[N];
    /* Clamp and the heap-mask Discard of st_atlas_sample build nothing */
    for (unsigned f = ST_FILTER_POINT; f <= ST_FILTER_ANISO; f++) {
        st_sample_opts o = {.mode = ST_MODE_CLAMP, .filter = (uint8_t)f, .max_aniso = 8};
        assert_int_equal(st_sample_batch(s, &o, q, N, oa, ca, sa),
                         st_sample_batch(m, &o, q, N, ob, cb, sb));
        assert_memory_equal(oa, ob, N * nc * sizeof(float));
    }
    st_sample_opts od = {.mode = ST_MODE_DISCARD, .filter = ST_FILTER_BILINEAR};
    assert_true(st_atlas_sample(m, &od, ST_ATLAS_CHART_DISCARD, q, N, ob, cb, sb) >= 0);
    assert_int_equal(st_atlas_charts_built_bytes(m), 0);
    assert_int_equal(st_set_memory(m), mem0);

    /* every chart-mode filter, twice: built by the first, the same outputs as the heap atlas,
     * then dropped and rebuilt by the second */
    for (int round = 0; round < 2; round++)
        for (unsigned mode = ST_MODE_DISCARD; mode <= ST_MODE_TRAVERSE; mode++)
            for (unsigned f = ST_FILTER_POINT; f <= ST_FILTER_ANISO; f++) {
                st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)f, .max_aniso = 8};
                int ra = st_sample_batch(s, &o, q, N, oa, ca, sa);
                int rb = st_sample_batch(m, &o, q, N, ob, cb, sb);
                assert_true(ra >= 0);
                assert_int_equal(ra, rb);
                assert_memory_equal(oa, ob, N * nc * sizeof(float));
                assert_memory_equal(ca, cb, N * sizeof(float));
                assert_memory_equal(sa, sb, N);
                /* built once, counted, the heap atlas's bytes */
                assert_int_equal(st_atlas_charts_built_bytes(m), built);
                assert_int_equal(st_set_memory(m), mem0 + built);
                assert_int_equal(st_set_heap_memory(m), heap0 + built);
                assert_int_equal(y->ids.nlevels, x->ids.nlevels);
                assert_memory_equal(y->chart_id, x->chart_id, x->chart_id_bytes);
                assert_memory_equal(y->chart_link, x->chart_link, x->chart_link_bytes);
                if (round == 0 && mode == ST_MODE_TRAVERSE && f == ST_FILTER_ANISO) {
                    assert_int_equal(st_atlas_charts_drop(m), built);
                    assert_int_equal(st_atlas_charts_built_bytes(m), 0);
                    assert_int_equal(st_set_memory(m), mem0);
                    assert_int_equal(y->ids.nlevels, 0);
                    assert_null(y->chart_id);
                }
            }

    /* a pinned sampler keeps it: the drop gives up, and succeeds once unpinned */
    st_error e;
    assert_int_equal(st_atlas_charts_pin(m, &e), ST_OK);
    assert_int_equal(st_atlas_charts_drop(m), 0);
    assert_int_equal(st_atlas_charts_built_bytes(m), built);
    assert_int_equal(y->ids.nlevels, x->ids.nlevels);
    st_atlas_charts_unpin(m);
    assert_int_equal(st_atlas_charts_drop(m), built);
    /* a heap set's pin (built at import) never rebuilds: the same pointers */
    const uint16_t *hid = x->chart_id;
    assert_int_equal(st_atlas_charts_pin(s, &e), ST_OK);
    st_atlas_charts_unpin(s);
    assert_ptr_equal(x->chart_id, hid);

    /* samplers racing drops: every batch reads whole data, the same outputs */
    static float ref[N * 4];
    st_sample_opts ot = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_TRILINEAR};
    assert_true(st_sample_batch(s, &ot, q, N, ref, NULL, NULL) >= 0);
    chart_arg args[2] = {{m, q, N, ref, 0}, {m, q, N, ref, 0}};
    pthread_t th[2];
    for (int i = 0; i < 2; i++)
        assert_int_equal(pthread_create(&th[i], NULL, chart_sampler, &args[i]), 0);
    size_t drops = 0;
    for (int i = 0; i < 2000; i++) {
        drops += st_atlas_charts_drop(m) != 0;
        sched_yield();
    }
    for (int i = 0; i < 2; i++)
        assert_int_equal(pthread_join(th[i], NULL), 0);
    assert_int_equal(args[0].mismatches, 0);
    assert_int_equal(args[1].mismatches, 0);
    print_message("# %zu drops while two samplers ran\n", drops);
    st_set_free(m);
    st_set_free(s);
}

/* ---- corruption ----------------------------------------------------------------------------- */

static uint8_t *slurp(const char *path, size_t *len)
{
    return st_test_read_file(path, len);
}
static void spit(const char *path, const uint8_t *p, size_t n)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, p, n), (ssize_t)n);
    close(fd);
}
static int try_open(const char *path, unsigned flags, char *msg)
{
    st_set *m = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_native_open(path, flags, NULL, &m, &e);
    st_set_free(m);
    if (msg)
        snprintf(msg, ST_ERRMSG_LEN, "%s", e.msg);
    return rc;
}
static uint64_t r64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }
static void w64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }
static void w32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static void fix_header_crc(uint8_t *h) { w32(h + 4092, stu_crc32c(0, h, 4092)); }

static void corrupt_all(const st_set *s, const char *tag)
{
    char path[700], bad[720], msg[ST_ERRMSG_LEN];
    snprintf(path, sizeof path, "%s/%s.native", g_dir, tag);
    snprintf(bad, sizeof bad, "%s/%s.bad", g_dir, tag);
    st_error e;
    assert_int_equal(st_native_write(path, s, NULL, &e), 0);
    size_t n;
    uint8_t *orig = slurp(path, &n), *b = malloc(n);
    assert_non_null(orig);
    assert_int_equal(try_open(path, ST_NATIVE_VERIFY, NULL), 0);
    uint32_t nsec;
    memcpy(&nsec, orig + 24, 4);
    /* a flipped bit in the header and in every section (several places each) */
    size_t hdr_spots[] = {3, 20, 33, 50, 1024 + 9, 4093};
    for (size_t i = 0; i < sizeof hdr_spots / sizeof hdr_spots[0]; i++) {
        memcpy(b, orig, n);
        b[hdr_spots[i]] ^= 0x10;
        spit(bad, b, n);
        assert_true(try_open(bad, 0, NULL) < 0);
    }
    for (uint32_t i = 0; i < nsec; i++) {
        const uint8_t *t = orig + 1024 + 32 * i;
        uint32_t id;
        memcpy(&id, t, 4);
        uint64_t off = r64(t + 8), size = r64(t + 16);
        for (int spot = 0; spot < 3 && size; spot++) {
            uint64_t at = off + (spot == 0 ? 0 : spot == 1 ? size / 2 : size - 1);
            memcpy(b, orig, n);
            b[at] ^= (uint8_t)(1u << (spot + 2));
            spit(bad, b, n);
            int rc = try_open(bad, ST_NATIVE_VERIFY, msg);
            if (rc >= 0)
                print_message("%s: flip in section %u at %llu not refused\n", tag, id,
                              (unsigned long long)at);
            assert_true(rc < 0);
            if (id != ST_NSEC_TEXELS)   /* small sections: always checked */
                assert_true(try_open(bad, 0, NULL) < 0);
        }
        /* truncated at this section's start and end */
        uint64_t cuts[2] = {off, off + size};
        for (int k = 0; k < 2; k++) {
            spit(bad, orig, (size_t)cuts[k]);
            assert_true(try_open(bad, 0, msg) < 0);
        }
        /* an offset past the end, and one that overlaps, with a valid header CRC */
        memcpy(b, orig, n);
        w64(b + 1024 + 32 * i + 8, (uint64_t)n + 4096);
        fix_header_crc(b);
        spit(bad, b, n);
        assert_int_equal(try_open(bad, 0, msg), ST_EFORMAT);
        memcpy(b, orig, n);
        w64(b + 1024 + 32 * i + 16, r64(t + 16) + (uint64_t)n);
        fix_header_crc(b);
        spit(bad, b, n);
        assert_int_equal(try_open(bad, 0, msg), ST_EFORMAT);
        /* the file says it is longer than it is */
        memcpy(b, orig, n);
        w64(b + 16, (uint64_t)n + 4096);
        fix_header_crc(b);
        spit(bad, b, n);
        assert_int_equal(try_open(bad, 0, msg), ST_EFORMAT);
    }
    /* every prefix at a page boundary, and a few odd sizes */
    for (size_t cut = 0; cut < n; cut += 4096) {
        spit(bad, orig, cut);
        assert_true(try_open(bad, 0, NULL) < 0);
        if (cut + 100 < n) {
            spit(bad, orig, cut + 100);
            assert_true(try_open(bad, 0, NULL) < 0);
        }
    }
    /* a level offset that lies, with every CRC fixed up: the layout check refuses it */
    for (uint32_t i = 0; i < nsec; i++) {
        const uint8_t *t = orig + 1024 + 32 * i;
        uint32_t id;
        memcpy(&id, t, 4);
        if (id != ST_NSEC_LEVELS && id != ST_NSEC_FACES)
            continue;
        uint64_t off = r64(t + 8), size = r64(t + 16);
        memcpy(b, orig, n);
        if (id == ST_NSEC_LEVELS)
            w64(b + off + size - 8, r64(b + off + size - 8) + (uint64_t)n * 8);
        else
            w32(b + off + 16, 0x7fffffffu);  /* face 0's neighbour far out of range */
        w32(b + 1024 + 32 * i + 24, stu_crc32c(0, b + off, (size_t)size));
        fix_header_crc(b);
        spit(bad, b, n);
        assert_int_equal(try_open(bad, 0, msg), ST_EFORMAT);
    }
    free(orig);
    free(b);
}

static void test_corruption(void **st)
{
    (void)st;
    cf_cube c;
    assert_int_equal(cf_cube_build(&c, 2, 3, 2, 4, 5, ST_DT_U8, 4), 0);
    st_error e;
    assert_int_equal(st_ptexfilter_prepare(c.set, &e), 0);
    assert_int_equal(st_set_meta_add(c.set, "note", 0, "hello", 6, &e), 0);
    corrupt_all(c.set, "corrupt-ptex");
    cf_cube_free(&c);
    st_set *a = make_atlas();
    corrupt_all(a, "corrupt-atlas");
    st_set_free(a);
}

/* Texel flips pass a plain open (documented: the texel CRC is checked on demand) and never
 * make sampling read outside the mapping. */
static void test_texel_flip_without_verify(void **st)
{
    (void)st;
    cf_cube c;
    assert_int_equal(cf_cube_build(&c, 1, 3, 3, 3, 5, ST_DT_U8, 4), 0);
    char path[700];
    snprintf(path, sizeof path, "%s/flip.native", g_dir);
    st_error e;
    assert_int_equal(st_native_write(path, c.set, NULL, &e), 0);
    int fd = open(path, O_RDWR);
    uint8_t h[4096], x;
    assert_int_equal(pread(fd, h, sizeof h, 0), 4096);
    uint64_t at = 0;
    for (int i = 0; i < 5; i++)
        if (h[1024 + 32 * i] == ST_NSEC_TEXELS)
            at = r64(h + 1024 + 32 * i + 8) + 10;
    assert_true(at > 0);
    assert_int_equal(pread(fd, &x, 1, (off_t)at), 1);
    x ^= 1;
    assert_int_equal(pwrite(fd, &x, 1, (off_t)at), 1);
    close(fd);
    assert_int_equal(try_open(path, 0, NULL), 0);
    assert_int_equal(try_open(path, ST_NATIVE_VERIFY, NULL), ST_ECORRUPT);
    assert_int_equal(try_open("/nonexistent/x.native", 0, NULL), ST_ENOTFOUND);
    cf_cube_free(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_perface_types),
        cmocka_unit_test(test_ptex_files),
        cmocka_unit_test(test_constant_faces),
        cmocka_unit_test(test_cube),
        cmocka_unit_test(test_atlas_and_bc1),
        cmocka_unit_test(test_atlas_chart_data_is_lazy_counted_and_dropped),
        cmocka_unit_test(test_corruption),
        cmocka_unit_test(test_texel_flip_without_verify),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
