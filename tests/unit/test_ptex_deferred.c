/* tests/unit/test_ptex_deferred.c - the Ptex reader's deferred levels (ptex.h, set.h
 * st_set_levels): a deferred import gives, once its levels are made, the same set byte for
 * byte as an eager one; every public reader of levels past level 0 (GPU-style sampling in
 * every mode and filter, the Ptex filters, the triangle filter, the .ptx, native and DDS
 * writers, export, cube conversion, BC1) gives on a set whose levels are still pending what
 * it gives on an eager set; a stored reduction whose deflate data or Adler-32 is corrupt
 * imports, then fails every use with ST_EFORMAT and the eager import's message; several
 * threads may be the first user at once. Shared files come from SEAMTEX_DATA (default
 * ../shared/data); without them those tests are skipped. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bc1.h"
#include "cube.h"
#include "export.h"
#include "native.h"
#include "ptex.h"
#include "ptex_format.h"
#include "ptexfilter.h"
#include "ptexres.h"
#include "ptextri.h"
#include "sample.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

#define MAXF 64

static int shared_files(char (*rel)[512])
{
    int n = st_test_ptx_files(rel, MAXF);
    if (n == 0) {
        print_message("SEAMTEX_DATA (%s) has no .ptx files: skipped\n", st_test_data_dir());
        skip();
    }
    return n;
}

static st_set *load(const char *rel, int eager)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), rel);
    st_set *s = NULL;
    st_error e;
    int rc = eager ? st_ptex_read_file_eager(path, 0, &s, &e) : st_ptex_read_file(path, 0, &s, &e);
    if (rc)
        fail_msg("%s: %s", rel, e.msg);
    return s;
}

static int pending(const st_set *s)
{
    const st_ptexres *t = st_ptexres_get(s);
    return t && atomic_load(&((st_ptexres *)(uintptr_t)t)->levels) == 0;
}

/* (1) texels, level offsets, faces, info, metadata and the Ptex record: the same */
static void deferred_then_made_equals_eager_for_every_shared_file(void **state)
{
    (void)state;
    char rel[MAXF][512];
    int n = shared_files(rel);
    for (int i = 0; i < n; i++) {
        st_set *a = load(rel[i], 1), *b = load(rel[i], 0);
        assert_null(a->ext.levels); /* an eager set needs nothing */
        int deferred = b->ext.levels != NULL;
        size_t mem_pending = st_set_memory(b);
        st_error e;
        assert_int_equal(st_set_levels(b, &e), ST_OK);
        assert_int_equal(st_set_levels(b, &e), ST_OK); /* and again: made once */
        assert_memory_equal(&a->info, &b->info, sizeof a->info);
        assert_int_equal(a->texel_bytes, b->texel_bytes);
        assert_memory_equal(a->faces, b->faces, (size_t)a->info.nfaces * sizeof *a->faces);
        size_t nlev = 0;
        for (uint32_t f = 0; f < a->info.nfaces; f++)
            nlev += a->faces[f].nlevels;
        assert_memory_equal(a->level_off, b->level_off, nlev * sizeof *a->level_off);
        assert_memory_equal(a->texels, b->texels, a->texel_bytes);
        assert_int_equal(a->nmeta, b->nmeta);
        for (uint32_t k = 0; k < a->nmeta; k++) {
            assert_string_equal(a->meta[k].key, b->meta[k].key);
            assert_int_equal(a->meta[k].type, b->meta[k].type);
            assert_int_equal(a->meta[k].count, b->meta[k].count);
            static const size_t ts[] = {1, 1, 2, 4, 4, 8};
            assert_memory_equal(a->meta[k].data, b->meta[k].data,
                                ts[a->meta[k].type] * a->meta[k].count);
        }
        const st_ptexres *ta = st_ptexres_get(a), *tb = st_ptexres_get(b);
        assert_memory_equal(ta->ptxflags, tb->ptxflags, a->info.nfaces);
        assert_memory_equal(ta->nstored, tb->nstored, a->info.nfaces);
        /* memory: the kept zipped reductions are counted while pending, then freed */
        assert_int_equal(st_set_memory(a), st_set_memory(b));
        if (deferred)
            assert_true(mem_pending > st_set_memory(b));
        print_message("%s: %zu bytes pending, %zu made\n", rel[i], mem_pending, st_set_memory(b));
        st_set_free(a);
        st_set_free(b);
    }
}

/* ---- (2) every reader on a pending set ---------------------------------------------------- */

enum { NQ = 600 };

static void queries(const st_set *s, st_query *q, size_t n, uint32_t seed)
{
    uint32_t x = seed;
    for (size_t k = 0; k < n; k++) {
        x = x * 1664525u + 1013904223u;
        q[k].face = (x >> 8) % s->info.nfaces;
        x = x * 1664525u + 1013904223u;
        q[k].u = (float)(x >> 8) / 16777216.0f * 1.1f - 0.05f;
        x = x * 1664525u + 1013904223u;
        q[k].v = (float)(x >> 8) / 16777216.0f * 1.1f - 0.05f;
        float fp = 1.0f / (float)(1u << (k % 11));
        q[k].dudx = fp;
        q[k].dvdy = fp * (k % 3 ? 1.0f : 0.3f);
        q[k].dvdx = k % 5 ? 0.0f : fp * 0.4f;
        q[k].dudy = 0;
    }
}

typedef struct run_out {
    int rc;
    float out[NQ * 4], cov[NQ];
    uint8_t st[NQ];
} run_out;

static void sample(const st_set *s, const st_sample_opts *o, int direct, run_out *r)
{
    st_query q[NQ]; /* one per thread */
    queries(s, q, NQ, 7u + o->filter * 3u + o->mode);
    memset(r, 0, sizeof *r);
    if (direct == 1)
        r->rc = st_ptexfilter_batch(s, o, q, NQ, r->out, r->cov, r->st);
    else if (direct == 2)
        r->rc = st_ptextri_batch(s, o, q, NQ, r->out, r->cov, r->st);
    else
        r->rc = st_sample_batch(s, o, q, NQ, r->out, r->cov, r->st);
}

static void same_run(const run_out *a, const run_out *b, const char *what)
{
    if (a->rc != b->rc)
        fail_msg("%s: rc %d eager, %d pending", what, a->rc, b->rc);
    if (memcmp(a, b, sizeof *a))
        fail_msg("%s: outputs differ", what);
}

static void same_buf(const void *a, size_t la, const void *b, size_t lb, const char *what)
{
    if (la != lb || memcmp(a, b, la))
        fail_msg("%s: %zu vs %zu bytes, or different", what, la, lb);
}

static void *native_bytes(const st_set *s, size_t *len)
{
    char path[] = "/tmp/seamtex_deferred_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    unlink(path);
    st_error e;
    assert_int_equal(st_native_write_fd(fd, s, NULL, &e), ST_OK);
    off_t end = lseek(fd, 0, SEEK_END);
    uint8_t *b = malloc((size_t)end + 1);
    assert_int_equal(pread(fd, b, (size_t)end, 0), end);
    close(fd);
    *len = (size_t)end;
    return b;
}

static void every_reader_on_a_pending_set_matches_the_eager_set(void **state)
{
    (void)state;
    char rel[MAXF][512];
    int n = shared_files(rel);
    static const unsigned filters[] = {ST_FILTER_POINT, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR,
        ST_FILTER_ANISO, ST_FILTER_PTEX_POINT, ST_FILTER_PTEX_BILINEAR, ST_FILTER_PTEX_BOX,
        ST_FILTER_PTEX_GAUSSIAN, ST_FILTER_PTEX_BICUBIC, ST_FILTER_PTEX_BSPLINE,
        ST_FILTER_PTEX_CATMULLROM, ST_FILTER_PTEX_MITCHELL};
    static run_out ra, rb;
    char what[700];
    for (int i = 0; i < n; i++) {
        st_set *a = load(rel[i], 1);
        int tri = a->info.meshtype == ST_MESH_TRIANGLE;
        /* sampling: every mode and filter, each on a fresh pending set it is the first to use */
        for (unsigned m = 0; m <= ST_MODE_CLAMP; m++)
            for (size_t k = 0; k < sizeof filters / sizeof filters[0]; k++)
                for (int direct = 0; direct < 3; direct++) {
                    if (direct && filters[k] < ST_FILTER_PTEX_POINT)
                        continue;
                    if (direct == 2 && !tri)
                        continue;
                    st_sample_opts o = {.mode = (uint8_t)m, .filter = (uint8_t)filters[k],
                                        .sharpness = 0.5f, .max_aniso = 8};
                    st_set *b = load(rel[i], 0);
                    int was = pending(b);
                    sample(a, &o, direct, &ra);
                    sample(b, &o, direct, &rb);
                    snprintf(what, sizeof what, "%.400s mode %u filter %u entry %d", rel[i], m,
                             filters[k], direct);
                    same_run(&ra, &rb, what);
                    if (was && rb.rc >= 0)
                        assert_false(pending(b));
                    st_set_free(b);
                }
        /* the .ptx writer, export, the native writer */
        void *pa, *pb;
        size_t la, lb;
        st_error e;
        st_set *b = load(rel[i], 0);
        assert_int_equal(st_ptex_write_mem(a, &pa, &la, &e), ST_OK);
        assert_int_equal(st_ptex_write_mem(b, &pb, &lb, &e), ST_OK);
        same_buf(pa, la, pb, lb, rel[i]);
        free(pa);
        free(pb);
        st_set_free(b);
        b = load(rel[i], 0);
        assert_int_equal(st_export_mem(a, ST_EXPORT_PTX, "/tmp", &pa, &la, &e), ST_OK);
        assert_int_equal(st_export_mem(b, ST_EXPORT_PTX, "/tmp", &pb, &lb, &e), ST_OK);
        same_buf(pa, la, pb, lb, rel[i]);
        free(pa);
        free(pb);
        st_set_free(b);
        b = load(rel[i], 0);
        pa = native_bytes(a, &la);
        pb = native_bytes(b, &lb);
        same_buf(pa, la, pb, lb, rel[i]);
        free(pa);
        free(pb);
        st_set_free(b);
        /* the Ptex table, built straight from a pending set */
        b = load(rel[i], 0);
        if (!tri) {
            const st_ptexres *ta = st_ptexres_table(a, &e), *tb = st_ptexres_table(b, &e);
            assert_non_null(ta);
            assert_non_null(tb);
            assert_int_equal(ta->arena_bytes, tb->arena_bytes);
            assert_memory_equal(ta->arena, tb->arena, ta->arena_bytes);
            assert_memory_equal(a->texels, b->texels, a->texel_bytes);
        }
        st_set_free(b);
        /* BC1 (level 0 only) and its DDS, on the small files (the encoder is slow) */
        if (!tri && a->texel_bytes < ((size_t)1 << 20)) {
            st_bc1_opts bo;
            st_bc1_opts_default(&bo);
            bo.level = ST_BC1_FAST;
            bo.seam_mode = ST_BC1_SEAM_NONE;
            bo.threads = 1;
            st_set *ca = NULL, *cb = NULL;
            b = load(rel[i], 0);
            assert_int_equal(st_bc1_compress_set(a, &bo, NULL, NULL, NULL, &ca, &e), ST_OK);
            assert_int_equal(st_bc1_compress_set(b, &bo, NULL, NULL, NULL, &cb, &e), ST_OK);
            assert_int_equal(ca->texel_bytes, cb->texel_bytes);
            assert_memory_equal(ca->texels, cb->texels, ca->texel_bytes);
            uint8_t *da, *db;
            assert_int_equal(st_dds_write_mem(ca, &da, &la, &e), ST_OK);
            assert_int_equal(st_dds_write_mem(cb, &db, &lb, &e), ST_OK);
            same_buf(da, la, db, lb, rel[i]);
            free(da);
            free(db);
            st_set_free(ca);
            st_set_free(cb);
            st_set_free(b);
        }
        /* cube conversion (an environment cube's level 0) */
        if (a->info.nfaces == 6 && st_cube_is_ptex_env_layout(a)) {
            st_set *ca = NULL, *cb = NULL;
            b = load(rel[i], 0);
            assert_int_equal(st_cube_from_ptex_env(a, 0, &ca, &e), ST_OK);
            assert_int_equal(st_cube_from_ptex_env(b, 0, &cb, &e), ST_OK);
            assert_memory_equal(ca->texels, cb->texels, ca->texel_bytes);
            st_set_free(ca);
            st_set_free(cb);
            st_set_free(b);
        }
        /* st_set_build_mips and st_ptexfilter_prepare make the deferred levels first */
        b = load(rel[i], 0);
        assert_int_equal(st_ptexfilter_prepare(b, &e), ST_OK);
        assert_memory_equal(a->texels, b->texels, a->texel_bytes);
        st_set_free(b);
        st_set_free(a);
    }
}

/* ---- (3) a corrupt stored reduction ------------------------------------------------------ */

/* A copy of cube1_k6_u8 (stored reductions, zipped) with the deflate data (what = 0) or the
 * Adler-32 (what = 1) of its first level-1 block corrupt. */
static uint8_t *corrupt_reduction(const char *path, int what, size_t *len)
{
    uint8_t *b = st_test_read_file(path, len);
    assert_non_null(b);
    assert_int_equal(st_fixture_corrupt_reduction(b, *len, what), 0);
    return b;
}

static void a_corrupt_reduction_imports_then_fails_every_use(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptex-ref/cube1_k6_u8.ptx"))
        skip();
    for (int what = 0; what < 2; what++) {
        size_t len;
        uint8_t *c = corrupt_reduction(path, what, &len);
        st_set *s = NULL;
        st_error ee, e1, e2;
        /* the eager import refuses it, with the message the deferred one gives later */
        assert_int_equal(st_ptex_read_mem_eager(c, len, 0, &s, &ee), ST_EFORMAT);
        assert_null(s);
        assert_non_null(strstr(ee.msg, "level 1 face "));
        if (what == 1)
            assert_non_null(strstr(ee.msg, "incorrect data check"));
        assert_int_equal(st_ptex_read_mem(c, len, 0, &s, &e1), ST_OK);
        assert_true(pending(s));
        st_query q[64];
        float out[64 * 4];
        uint8_t st[64];
        queries(s, q, 64, 3);
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_TRILINEAR};
        memset(st, 0xee, sizeof st);
        assert_int_equal(st_sample_batch(s, &o, q, 64, out, NULL, st), ST_EFORMAT);
        assert_int_equal(st[0], 0xee); /* nothing written */
        assert_int_equal(st_set_levels(s, &e1), ST_EFORMAT);
        assert_string_equal(e1.msg, ee.msg);
        o.filter = ST_FILTER_PTEX_GAUSSIAN;
        assert_int_equal(st_sample_batch(s, &o, q, 64, out, NULL, st), ST_EFORMAT);
        assert_int_equal(st_ptexfilter_batch(s, &o, q, 64, out, NULL, st), ST_EFORMAT);
        o.filter = ST_FILTER_POINT; /* even a filter that may stay on level 0: the whole set */
        assert_int_equal(st_sample_batch(s, &o, q, 64, out, NULL, st), ST_EFORMAT);
        void *w;
        size_t wl;
        assert_int_equal(st_ptex_write_mem(s, &w, &wl, &e2), ST_EFORMAT);
        assert_string_equal(e2.msg, ee.msg);
        assert_int_equal(st_set_levels(s, &e2), ST_EFORMAT);
        assert_string_equal(e2.msg, ee.msg);
        assert_null(st_ptexres_table(s, &e2));
        assert_int_equal(e2.code, ST_EFORMAT);
        /* what it kept is freed at the failure: the set is back to what it holds for good */
        assert_int_equal(__atomic_load_n(&st_ptexres_get(s)->def_bytes, __ATOMIC_RELAXED), 0);
        st_set_free(s);
        free(c);
    }
}

/* ---- (4) concurrent first use ------------------------------------------------------------- */

typedef struct job {
    const st_set *s;
    st_sample_opts o;
    run_out *r;
    atomic_int *go;
} job;

static void *sampler(void *p)
{
    job *j = p;
    while (!atomic_load(j->go))
        ;
    sample(j->s, &j->o, 0, j->r);
    return NULL;
}

static void threads_sampling_a_pending_set_at_once_all_get_the_eager_results(void **state)
{
    (void)state;
    static const char *rels[] = {"ptx/wdas-ptex-samples/teapot/teapot.ptx",
                                 "ptex-ref/cube8_k7varrot_f32.ptx",
                                 "ptx/wdas-ptex-2009/tri/tri.ptx"};
    enum { T = 6 };
    static run_out ref[T], got[T];
    for (size_t i = 0; i < sizeof rels / sizeof rels[0]; i++) {
        char path[1024];
        if (st_test_data_path(path, sizeof path, rels[i]))
            continue;
        st_set *a = load(rels[i], 1);
        int tri = a->info.meshtype == ST_MESH_TRIANGLE;
        for (int round = 0; round < 4; round++) {
            st_set *b = load(rels[i], 0);
            assert_true(pending(b));
            pthread_t th[T];
            job j[T];
            atomic_int go = 0;
            for (int t = 0; t < T; t++) {
                /* different filters: GPU-style and Ptex ones race to make the levels */
                static const unsigned qf[] = {ST_FILTER_TRILINEAR, ST_FILTER_PTEX_GAUSSIAN,
                                              ST_FILTER_POINT, ST_FILTER_PTEX_BILINEAR};
                unsigned flt = qf[(t + round) % 4];
                if (tri && flt < ST_FILTER_PTEX_POINT)
                    flt = ST_FILTER_POINT;
                j[t] = (job){.s = b, .o = {.mode = (uint8_t)(t % 3), .filter = (uint8_t)flt},
                             .r = &got[t], .go = &go};
                sample(a, &j[t].o, 0, &ref[t]);
                assert_int_equal(pthread_create(&th[t], NULL, sampler, &j[t]), 0);
            }
            atomic_store(&go, 1);
            for (int t = 0; t < T; t++) {
                pthread_join(th[t], NULL);
                same_run(&ref[t], &got[t], rels[i]);
            }
            assert_false(pending(b));
            assert_memory_equal(a->texels, b->texels, a->texel_bytes);
            st_set_free(b);
        }
        st_set_free(a);
    }
}

typedef struct fjob {
    const st_set *s;
    int rc;
    char msg[ST_ERRMSG_LEN];
} fjob;

static void *failer(void *p)
{
    fjob *j = p;
    st_error e;
    j->rc = st_set_levels(j->s, &e);
    snprintf(j->msg, sizeof j->msg, "%s", e.msg);
    return NULL;
}

static void threads_first_using_a_corrupt_set_all_get_its_error(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptex-ref/cube1_k6_u8.ptx"))
        skip();
    size_t len;
    uint8_t *c = corrupt_reduction(path, 1, &len);
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_ptex_read_mem(c, len, 0, &s, &e), ST_OK);
    enum { T = 4 };
    pthread_t th[T];
    fjob j[T];
    for (int t = 0; t < T; t++) {
        j[t] = (fjob){.s = s};
        assert_int_equal(pthread_create(&th[t], NULL, failer, &j[t]), 0);
    }
    for (int t = 0; t < T; t++) {
        pthread_join(th[t], NULL);
        assert_int_equal(j[t].rc, ST_EFORMAT);
        assert_string_equal(j[t].msg, j[0].msg);
        assert_non_null(strstr(j[t].msg, "incorrect data check"));
    }
    st_set_free(s);
    free(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(deferred_then_made_equals_eager_for_every_shared_file),
        cmocka_unit_test(every_reader_on_a_pending_set_matches_the_eager_set),
        cmocka_unit_test(a_corrupt_reduction_imports_then_fails_every_use),
        cmocka_unit_test(threads_sampling_a_pending_set_at_once_all_get_the_eager_results),
        cmocka_unit_test(threads_first_using_a_corrupt_set_all_get_its_error),
    };
    if (getenv("ST_TEST_FILTER")) /* e.g. "*corrupt*" for a run under valgrind */
        cmocka_set_test_filter(getenv("ST_TEST_FILTER"));
    return cmocka_run_group_tests(tests, NULL, NULL);
}
