/* tests/unit/test_ptex_read.c - the Ptex reader: every shared .ptx loads (or is refused for
 * the documented reason), its faces, resolutions and adjacency match the .obj beside it,
 * metadata and border modes are kept, and hostile files are refused with a message, never a
 * crash. Shared files come from SEAMTEX_DATA; without it those tests are skipped. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ptex.h"
#include "ptex_format.h"
#include "ptexres.h"
#include "sample.h"
#include "../common/testdata.h"

/* 1 when the shared file is there (test_ptex_read reads it as a condition). */
#define st_test_data_ok(buf, cap, rel) (st_test_data_path((buf), (cap), (rel)) == 0)

#define NEED_DATA(path, rel)                                                                  \
    do {                                                                                      \
        if (!st_test_data_ok(path, sizeof path, rel)) {                                             \
            print_message("SEAMTEX_DATA (%s) has no %s: skipped\n", st_test_data_dir(), rel);        \
            skip();                                                                           \
        }                                                                                     \
    } while (0)

/* ---- every shared file --------------------------------------------------------------- */

typedef struct expect {
    const char *rel;
    int rc;                  /* 0, or the refusal code */
    uint32_t nfaces;
    unsigned nchan, dtype;
    uint32_t w0, h0;         /* face 0 size (0 = not checked) */
} expect;

static const expect files[] = {
    {"ptex-ref/cube1_k6_u8.ptx", 0, 6, 4, ST_DT_U8, 0, 0},
    {"ptex-ref/cube8_k6_u8.ptx", 0, 384, 4, ST_DT_U8, 0, 0},
    {"ptex-ref/cube8_k6_u8_rot.ptx", 0, 384, 4, ST_DT_U8, 0, 0},
    {"ptex-ref/cube8_k7varrot_f32.ptx", 0, 384, 3, ST_DT_F32, 0, 0},
    {"ptx/wdas-ptex-2009/bordermodes/black.ptx", 0, 1, 3, ST_DT_HALF, 4, 4},
    {"ptx/wdas-ptex-2009/bordermodes/clamp.ptx", 0, 1, 3, ST_DT_HALF, 4, 4},
    {"ptx/wdas-ptex-2009/bordermodes/periodic.ptx", 0, 1, 3, ST_DT_HALF, 4, 4},
    {"ptx/wdas-ptex-2009/cube/text/cube.ptx", 0, 72, 1, ST_DT_U8, 512, 512},
    {"ptx/wdas-ptex-2009/dispplane/rand/pPlane1.ptx", 0, 9, 1, ST_DT_U16, 256, 256},
    {"ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx", 0, 9, 1, ST_DT_U16, 0, 0},
    {"ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx", 0, 9, 1, ST_DT_U16, 0, 0},
    {"ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx", 0, 66, 3, ST_DT_U8, 64, 64},
    {"ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx", 0, 66, 3, ST_DT_U8, 64, 64},
    {"ptx/wdas-ptex-2009/tri/quad.ptx", 0, 1, 3, ST_DT_U8, 8, 8},
    {"ptx/wdas-ptex-2009/tri/uv.ptx", 0, 1, 3, ST_DT_U8, 512, 512},
    {"ptx/wdas-ptex-2009/tri/tri.ptx", 0, 9, 3, ST_DT_F32, 32, 32},         /* triangles */
    {"ptx/wdas-ptex-samples/envcube/envcube.ptx", 0, 6, 3, ST_DT_U16, 0, 0},
    {"ptx/wdas-ptex-samples/holeycube/holeycube.ptx", 0, 72, 1, ST_DT_U16, 0, 0},
    {"ptx/wdas-ptex-samples/teapot/teapot.ptx", 0, 448, 1, ST_DT_U8, 0, 0},
    {"ptx/wdas-ptex-samples/triangle/triangle.ptx", 0, 9, 3, ST_DT_F32, 4, 4}, /* triangles */
};

static void every_shared_ptx_loads_or_is_refused_for_a_stated_reason(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx");
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        const expect *x = &files[i];
        if (!st_test_data_ok(path, sizeof path, x->rel)) {
            print_message("missing %s\n", x->rel);
            fail();
        }
        st_set *s = NULL;
        st_error e = {0};
        int rc = st_ptex_read_file(path, 0, &s, &e);
        if (rc != x->rc)
            print_message("%s: rc %d (%s)\n", x->rel, rc, e.msg);
        assert_int_equal(rc, x->rc);
        if (rc) {
            assert_non_null(strstr(e.msg, "triangle"));
            assert_null(s);
            continue;
        }
        assert_int_equal(st_set_levels(s, &e), ST_OK); /* its stored reductions inflate too */
        assert_int_equal(s->info.nfaces, x->nfaces);
        assert_int_equal(s->info.nchan, x->nchan);
        assert_int_equal(s->info.dtype, x->dtype);
        assert_int_equal(s->info.kind, ST_KIND_PERFACE);
        if (x->w0) {
            for (uint32_t f = 0; f < s->info.nfaces; f++)
                if (!(s->faces[f].flags & ST_FACE_CONSTANT)) {
                    assert_int_equal(s->faces[f].w, x->w0);
                    assert_int_equal(s->faces[f].h, x->h0);
                }
        }
        assert_non_null(st_ptexres_get(s));
        st_set_free(s);
    }
}

/* Memory accounting sees every byte a Ptex set holds: the import no longer builds the
 * resolution table the Ptex filters read (often larger than the texels) - it costs two bytes
 * per face until the first Ptex-filter call builds it - and once built st_set_memory, which
 * the registry, the daemon's caps, `ls`, `info` and STATS all use, counts all of it. */
static void set_memory_counts_the_ptex_resolution_table_once_built(void **state)
{
    (void)state;
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptex-ref/cube8_k6_u8.ptx"))
        skip();
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_ptex_read_file(path, 0, &s, &e), ST_OK);
    const st_ptexres *rec = st_ptexres_get(s);
    assert_non_null(rec);
    assert_int_equal(atomic_load(&((st_ptexres *)(uintptr_t)rec)->built), 0);
    /* the stored reductions made (until then st_set_memory also counts their zipped copy,
     * test_ptex_deferred.c) */
    assert_int_equal(st_set_levels(s, &e), ST_OK);
    size_t faces = (size_t)s->info.nfaces * sizeof(st_face);
    size_t before = st_set_memory(s);
    assert_true(before >= sizeof *s + faces + s->texel_bytes);
    /* texels, faces, level offsets, two bytes per face of the unbuilt table, some metadata */
    assert_true(before <= sizeof *s + faces + s->texel_bytes + 65536 +
                           (size_t)s->info.nfaces * (ST_MAX_LEVELS * sizeof(uint64_t) + 2));
    const st_ptexres *t = st_ptexres_table(s, &e);
    assert_ptr_equal(t, rec);
    assert_true(t->bytes > t->arena_bytes);
    /* the table's pointers alone are 8 bytes per (face, ulog2', vlog2') entry */
    assert_true(st_set_memory(s) >= before + t->bytes);
    assert_ptr_equal(st_ptexres_table(s, &e), t); /* built once */
    print_message("cube8_k6_u8: %zu texel bytes, st_set_memory %zu after import, %zu table "
                  "bytes once a Ptex filter ran\n", s->texel_bytes, before, t->bytes);
    st_set_free(s);
}

/* The table is built by whichever Ptex-filter call comes first, while other threads sample
 * the same published set: every thread gets the results of a set whose table was built
 * before sharing, bit for bit. */
typedef struct lazy_job {
    const st_set *s;
    const st_query *q;
    size_t n;
    float *out;
    int rc;
} lazy_job;

static void *lazy_sampler(void *p)
{
    lazy_job *j = p;
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_GAUSSIAN};
    j->rc = st_sample_batch(j->s, &o, j->q, j->n, j->out, NULL, NULL);
    return NULL;
}

static void the_table_is_built_once_under_concurrent_first_use(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx/wdas-ptex-samples/teapot/teapot.ptx");
    enum { N = 2000, T = 6 };
    static st_query q[N];
    static float ref[N * 4], out[T][N * 4];
    st_set *a = NULL, *b = NULL;
    st_error e;
    assert_int_equal(st_ptex_read_file(path, 0, &a, &e), ST_OK);
    assert_int_equal(st_ptex_read_file(path, 0, &b, &e), ST_OK);
    uint32_t x = 11;
    for (int k = 0; k < N; k++) {
        x = x * 1664525u + 1013904223u;
        q[k].face = (x >> 8) % a->info.nfaces;
        x = x * 1664525u + 1013904223u;
        q[k].u = (float)(x >> 8) / 16777216.0f;
        x = x * 1664525u + 1013904223u;
        q[k].v = (float)(x >> 8) / 16777216.0f;
        q[k].dudx = q[k].dvdy = 1.0f / (float)(1u << (k % 9));
        q[k].dvdx = q[k].dudy = 0;
    }
    assert_non_null(st_ptexres_table(a, &e)); /* reference: built before sharing */
    lazy_job r = {.s = a, .q = q, .n = N, .out = ref};
    lazy_sampler(&r);
    assert_int_equal(r.rc, 0);
    pthread_t th[T];
    lazy_job j[T];
    for (int i = 0; i < T; i++) {
        j[i] = (lazy_job){.s = b, .q = q, .n = N, .out = out[i]};
        assert_int_equal(pthread_create(&th[i], NULL, lazy_sampler, &j[i]), 0);
    }
    for (int i = 0; i < T; i++) {
        pthread_join(th[i], NULL);
        assert_int_equal(j[i].rc, 0);
        assert_memory_equal(out[i], ref, sizeof(float) * N * a->info.nchan);
    }
    assert_int_equal(st_set_memory(a), st_set_memory(b));
    st_set_free(a);
    st_set_free(b);
}

/* The import leaves every level as Ptex serves it (the GPU-style filters read the levels
 * before any Ptex filter ran), so building the table later writes no level - a set mapped
 * read-only can be given a table - and the table points into the set for every resolution
 * that is a set level instead of copying it. */
static void building_the_table_writes_no_level_and_reuses_set_levels(void **state)
{
    (void)state;
    static const char *rels[] = {"ptx/wdas-ptex-samples/teapot/teapot.ptx",
                                 "ptex-ref/cube8_k7varrot_f32.ptx",
                                 "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx"};
    for (size_t i = 0; i < sizeof rels / sizeof rels[0]; i++) {
        char path[1024];
        if (st_test_data_path(path, sizeof path, rels[i]))
            continue;
        st_set *s = NULL;
        st_error e;
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), ST_OK);
        /* a copy of the levels as the import left them, once made (ptex.h) */
        assert_int_equal(st_set_levels(s, &e), ST_OK);
        uint8_t *copy = malloc(s->texel_bytes);
        assert_non_null(copy);
        memcpy(copy, s->texels, s->texel_bytes);
        const st_ptexres *t = st_ptexres_table(s, &e);
        assert_non_null(t);
        assert_memory_equal(copy, s->texels, s->texel_bytes); /* the build writes no level */
        for (uint32_t f = 0; f < s->info.nfaces; f++) {
            const st_face *F = &s->faces[f];
            if (F->flags & ST_FACE_CONSTANT)
                continue;
            for (unsigned l = 0; l < F->nlevels; l++) {
                unsigned ru = F->ulog2 > l ? F->ulog2 - l : 0, rv = F->vlog2 > l ? F->vlog2 - l : 0;
                assert_ptr_equal(st_ptexres_data(t, s, f, ru, rv), st_face_level(s, f, l));
            }
        }
        free(copy);
        st_set_free(s);
    }
}

static void mixed_resolutions_are_read_per_face(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx");
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
    /* README: face res 16x16:5, 8x8:1, 8x16:1, 16x8:1, 32x32:1 */
    int n16 = 0, n8 = 0, n8x16 = 0, n16x8 = 0, n32 = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        uint32_t w = s->faces[f].w, h = s->faces[f].h;
        n16 += w == 16 && h == 16;
        n8 += w == 8 && h == 8;
        n8x16 += w == 8 && h == 16;
        n16x8 += w == 16 && h == 8;
        n32 += w == 32 && h == 32;
    }
    assert_int_equal(n16, 5);
    assert_int_equal(n8, 1);
    assert_int_equal(n8x16, 1);
    assert_int_equal(n16x8, 1);
    assert_int_equal(n32, 1);
    st_set_free(s);
}

/* ---- adjacency against the OBJ beside the file --------------------------------------- */

typedef struct objmesh {
    uint32_t nfaces;
    uint32_t *nv;            /* vertices per face */
    uint32_t *v;             /* 4 per face (quads) */
} objmesh;

static int obj_load(const char *path, objmesh *m)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return -1;
    char line[1024];
    size_t cap = 0;
    m->nfaces = 0;
    m->nv = NULL;
    m->v = NULL;
    uint32_t nverts = 0;
    while (fgets(line, sizeof line, fp)) {
        if (line[0] == 'v' && line[1] == ' ')
            nverts++;
        if (line[0] != 'f' || line[1] != ' ')
            continue;
        if (m->nfaces == cap) {
            cap = cap ? cap * 2 : 64;
            m->nv = realloc(m->nv, cap * sizeof *m->nv);
            m->v = realloc(m->v, cap * 4 * sizeof *m->v);
        }
        uint32_t k = 0;
        char *p = line + 1;
        while (*p) {
            while (*p == ' ' || *p == '\t')
                p++;
            if (!*p || *p == '\n' || *p == '\r')
                break;
            long idx = strtol(p, &p, 10);
            while (*p && *p != ' ' && *p != '\t' && *p != '\n')
                p++;
            if (idx < 0)
                idx = (long)nverts + idx + 1;
            if (k < 4)
                m->v[m->nfaces * 4 + k] = (uint32_t)idx;
            k++;
        }
        m->nv[m->nfaces++] = k;
    }
    fclose(fp);
    return 0;
}

/* Edge e of a face runs from vertex e to vertex e+1; a neighbour holds it reversed. */
static void check_adjacency(const char *ptx, const char *obj)
{
    char pp[1024], po[1024];
    if (!st_test_data_ok(pp, sizeof pp, ptx) || !st_test_data_ok(po, sizeof po, obj)) {
        print_message("missing %s or %s\n", ptx, obj);
        fail();
    }
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_ptex_read_file(pp, 0, &s, &e), 0);
    objmesh m = {0};
    assert_int_equal(obj_load(po, &m), 0);
    assert_int_equal(m.nfaces, s->info.nfaces);
    int matched = 0, checked = 0;
    for (uint32_t f = 0; f < m.nfaces; f++) {
        assert_int_equal(m.nv[f], 4);
        for (int ed = 0; ed < 4; ed++) {
            uint32_t a = m.v[f * 4 + ed], b = m.v[f * 4 + (ed + 1) % 4];
            int32_t twin = -1;
            int twin_e = 0;
            for (uint32_t g = 0; g < m.nfaces && twin < 0; g++)
                for (int ge = 0; ge < 4; ge++)
                    if (g != f && m.v[g * 4 + ge] == b && m.v[g * 4 + (ge + 1) % 4] == a) {
                        twin = (int32_t)g;
                        twin_e = ge;
                        break;
                    }
            const st_face *F = &s->faces[f];
            if (twin >= 0) {
                checked++;
                if (F->adjface[ed] == twin && F->adjedge[ed] == twin_e)
                    matched++;
                else
                    print_message("%s face %u edge %d: obj %d/%d ptx %d/%d\n", ptx, f, ed, twin,
                                  twin_e, F->adjface[ed], F->adjedge[ed]);
            } else if (!(F->flags & ST_FACE_SUBFACE) && F->adjface[ed] >= 0 &&
                       !(s->faces[F->adjface[ed]].flags & ST_FACE_SUBFACE)) {
                checked++; /* a plain boundary must be a boundary (subface T-joints aside) */
                print_message("%s face %u edge %d: obj boundary, ptx %d\n", ptx, f, ed,
                              F->adjface[ed]);
            } else {
                checked++;
                matched++;
            }
        }
    }
    assert_true(checked > 0);
    assert_int_equal(matched, checked);
    free(m.nv);
    free(m.v);
    st_set_free(s);
}

static void adjacency_matches_the_obj_beside_each_file(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx");
    check_adjacency("ptx/wdas-ptex-2009/cube/text/cube.ptx", "ptx/wdas-ptex-2009/cube/cube.obj");
    check_adjacency("ptx/wdas-ptex-2009/dispplane/rand/pPlane1.ptx",
                    "ptx/wdas-ptex-2009/dispplane/plane.obj");
    check_adjacency("ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx",
                    "ptx/wdas-ptex-2009/dispplane/plane.obj");
    check_adjacency("ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx",
                    "ptx/wdas-ptex-2009/nonquad/tritestsub.obj");
    check_adjacency("ptx/wdas-ptex-samples/teapot/teapot.ptx",
                    "ptx/wdas-ptex-samples/teapot/teapot.obj");
    check_adjacency("ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
                    "ptx/wdas-ptex-samples/holeycube/holeycube.obj");
    check_adjacency("ptx/wdas-ptex-samples/envcube/envcube.ptx",
                    "ptx/wdas-ptex-samples/envcube/envcube.obj");
}

static void nonquad_file_of_2009_is_plain_quads(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx");
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
    /* this 2009 file predates the subface flag: its subdivided faces are ordinary quads
     * (adjacency is conforming, checked against tritestsub.obj above); subfaces are covered
     * by synthetic sets in test_ptex_write and test_ptexfilter */
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        assert_int_equal(s->faces[f].flags & ST_FACE_SUBFACE, 0);
    st_set_free(s);
}

static void metadata_is_kept_and_listed(void **state)
{
    (void)state;
    char path[1024];
    NEED_DATA(path, "ptx/wdas-ptex-samples/teapot/teapot.ptx");
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
    assert_int_equal(s->nmeta, 4);
    const st_meta_entry *m = st_set_meta_find(s, "PtexFaceVertCounts");
    assert_non_null(m); /* large metadata (over 1 KiB) */
    assert_int_equal(m->type, 3);
    assert_int_equal(m->count, 448);
    for (uint32_t i = 0; i < m->count; i++)
        assert_int_equal(((const int32_t *)m->data)[i], 4);
    const st_meta_entry *n = st_set_meta_find(s, "P3dNameHierarchy");
    assert_non_null(n);
    assert_int_equal(n->type, 0);
    assert_int_equal(((const char *)n->data)[n->count - 1], 0);
    const st_meta_entry *p = st_set_meta_find(s, "PtexVertPositions");
    assert_non_null(p);
    assert_int_equal(p->type, 4);
    assert_int_equal(p->count % 3, 0);
    st_set_free(s);
}

static void border_modes_go_into_the_set_info(void **state)
{
    (void)state;
    static const struct { const char *rel; unsigned mode; } bm[] = {
        {"ptx/wdas-ptex-2009/bordermodes/clamp.ptx", 0},
        {"ptx/wdas-ptex-2009/bordermodes/black.ptx", 1},
        {"ptx/wdas-ptex-2009/bordermodes/periodic.ptx", 2},
    };
    char path[1024];
    NEED_DATA(path, "ptx/wdas-ptex-2009/bordermodes/clamp.ptx");
    for (int i = 0; i < 3; i++) {
        assert_true(st_test_data_ok(path, sizeof path, bm[i].rel));
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        assert_int_equal(s->info.border_u, bm[i].mode);
        assert_int_equal(s->info.border_v, bm[i].mode);
        assert_int_equal(s->info.alpha_chan, -1);
        assert_int_equal(s->info.premultiplied, 0);
        st_set_free(s);
    }
}

/* ---- hostile input ----------------------------------------------------------------- */

/* A small valid file made by our writer (so that these tests need no shared data): a strip of
 * six 8x8 RGBA u8 faces, each face's right edge meeting the next face's left edge. */
static uint8_t *small_file(size_t *len)
{
    st_face_desc fd[6];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 6; f++) {
        fd[f].w = fd[f].h = 8;
        for (int ed = 0; ed < 4; ed++)
            fd[f].adjface[ed] = -1;
        if (f > 0) {
            fd[f].adjface[3] = f - 1;
            fd[f].adjedge[3] = 1;
            fd[f - 1].adjface[1] = f;
            fd[f - 1].adjedge[1] = 3;
        }
    }
    st_set_info info = {.nfaces = 6, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    if (st_set_create(&info, fd, 0, &s, &e))
        return NULL;
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)(i * 37 + (i >> 5));
    st_set_build_mips(s, UINT32_MAX);
    assert_int_equal(st_set_meta_add(s, "note", 0, "small", 6, &e), 0);
    void *buf = NULL;
    int rc = st_ptex_write_mem(s, &buf, len, &e);
    st_set_free(s);
    return rc ? NULL : buf;
}

static void expect_refused(const uint8_t *b, size_t len, int code, const char *needle)
{
    st_set *s = (st_set *)1;
    st_error e = {0};
    int rc = st_ptex_read_mem(b, len, 0, &s, &e);
    if (rc != code || (needle && !strstr(e.msg, needle)))
        print_message("rc %d msg '%s' (want %d '%s')\n", rc, e.msg, code, needle ? needle : "");
    assert_int_equal(rc, code);
    assert_null(s);
    assert_true(strlen(e.msg) > 0);
    if (needle)
        assert_non_null(strstr(e.msg, needle));
}

static void header_fields_are_checked_before_allocating(void **state)
{
    (void)state;
    size_t len;
    uint8_t *b = small_file(&len);
    assert_non_null(b);
    uint8_t *c = malloc(len);
    expect_refused(b, 10, ST_EFORMAT, "shorter than the Ptex header");
    memcpy(c, b, len); c[0] = 'X';
    expect_refused(c, len, ST_EFORMAT, "magic");
    memcpy(c, b, len); ptx_wr32(c + 4, 2);
    expect_refused(c, len, ST_EUNSUPPORTED, "version");
    memcpy(c, b, len); ptx_wr32(c + 8, 2);
    expect_refused(c, len, ST_EFORMAT, "mesh type");
    /* read as a triangle mesh, the quads' edge id 3 is out of a triangle's 0..2 */
    memcpy(c, b, len); ptx_wr32(c + 8, 0);
    expect_refused(c, len, ST_EADJ, "0..2");
    memcpy(c, b, len); ptx_wr32(c + 12, 7);
    expect_refused(c, len, ST_EFORMAT, "data type");
    memcpy(c, b, len); ptx_wr16(c + 20, 9);
    expect_refused(c, len, ST_EUNSUPPORTED, "channels");
    memcpy(c, b, len); ptx_wr32(c + 24, 0xffffffffu);
    expect_refused(c, len, ST_ETOOBIG, "face count");
    memcpy(c, b, len); ptx_wr32(c + 24, 60000000u); /* under the cap, absurd for 57 bytes */
    expect_refused(c, len, ST_EFORMAT, "cannot hold");
    memcpy(c, b, len); ptx_wr16(c + 22, 200);
    expect_refused(c, len, ST_EFORMAT, "level count");
    memcpy(c, b, len); ptx_wr64(c + 48, (uint64_t)1 << 62);
    expect_refused(c, len, ST_EFORMAT, "overrun");
    memcpy(c, b, len); ptx_wr32(c + 28, 0x7fffffffu);
    expect_refused(c, len, ST_EFORMAT, "extended header");
    /* an edit position near 2^64 must not wrap (found by fuzz_ptex): no edits, file loads */
    memcpy(c, b, len); ptx_wr64(c + PTX_HEADER_SIZE + 32, UINT64_MAX - 2);
    {
        st_set *s = NULL;
        st_error e = {0};
        assert_int_equal(st_ptex_read_mem(c, len, 0, &s, &e), 0);
        st_set_free(s);
    }
    /* a metadata block declared far larger than its zipped bytes could hold */
    memcpy(c, b, len); ptx_wr32(c + 60, 0xfffffffau);
    expect_refused(c, len, ST_EFORMAT, "metadata");
    free(c);
    free(b);
}

static void bad_zlib_streams_and_overruns_are_refused(void **state)
{
    (void)state;
    size_t len;
    uint8_t *b = small_file(&len);
    assert_non_null(b);
    uint8_t *c = malloc(len);
    uint32_t ext = ptx_rd32(b + 28);
    size_t fipos = PTX_HEADER_SIZE + ext;
    /* corrupt the face info stream */
    memcpy(c, b, len);
    for (int i = 2; i < 12; i++) c[fipos + i] ^= 0x5a;
    expect_refused(c, len, ST_EFORMAT, "face info");
    /* the zlib wrapper is checked as zlib checks it: header, method, check value */
    memcpy(c, b, len); c[fipos] ^= 0x01;
    expect_refused(c, len, ST_EFORMAT, "face info: bad zlib stream");
    memcpy(c, b, len); c[fipos + ptx_rd32(b + 32) - 1] ^= 0x01; /* last byte of the Adler-32 */
    expect_refused(c, len, ST_EFORMAT, "incorrect data check");
    /* level info: level 0 larger than the level data */
    size_t lipos = fipos + ptx_rd32(b + 32) + ptx_rd32(b + 36);
    memcpy(c, b, len); ptx_wr64(c + lipos, (uint64_t)len * 4);
    expect_refused(c, len, ST_EFORMAT, "level 0");
    /* face count in level 0 that differs from the header */
    memcpy(c, b, len); ptx_wr32(c + lipos + 12, 5);
    expect_refused(c, len, ST_EFORMAT, "level 0 holds");
    /* every truncation is refused (and never crashes) */
    for (size_t n = 0; n < len; n += 1 + n / 64) {
        st_set *s = NULL;
        st_error e = {0};
        assert_true(st_ptex_read_mem(b, n, 0, &s, &e) < 0);
        assert_null(s);
    }
    free(c);
    free(b);
}

static void inconsistent_adjacency_is_refused(void **state)
{
    (void)state;
    size_t len;
    uint8_t *b = small_file(&len);
    assert_non_null(b);
    /* re-zip a face info table whose face 0 names face 99 / a non-symmetric neighbour */
    uint32_t nf = ptx_rd32(b + 24), ext = ptx_rd32(b + 28), fisize = ptx_rd32(b + 32);
    size_t fipos = PTX_HEADER_SIZE + ext;
    uint8_t fi[6 * PTX_FACEINFO_SIZE];
    uLongf fl = sizeof fi;
    assert_int_equal(nf, 6);
    assert_int_equal(uncompress(fi, &fl, b + fipos, fisize), Z_OK);
    for (int variant = 0; variant < 2; variant++) {
        uint8_t f2[sizeof fi];
        memcpy(f2, fi, sizeof fi);
        if (variant == 0)
            ptx_wr32(f2 + 4, 99);
        else
            ptx_wr32(f2 + 4, (ptx_rd32(f2 + 4) + 1) % 6 == 0 ? 1 : (ptx_rd32(f2 + 4) + 1) % 6);
        uint8_t z[256];
        uLongf zl = sizeof z;
        assert_int_equal(compress(z, &zl, f2, sizeof f2), Z_OK);
        size_t nlen = len - fisize + zl;
        uint8_t *c = malloc(nlen);
        memcpy(c, b, fipos);
        memcpy(c + fipos, z, zl);
        memcpy(c + fipos + zl, b + fipos + fisize, len - fipos - fisize);
        ptx_wr32(c + 32, (uint32_t)zl);
        ptx_wr64(c + PTX_HEADER_SIZE + 32, 0); /* editdatapos: scan to EOF */
        expect_refused(c, nlen, ST_EADJ, "face 0");
        free(c);
    }
    free(b);
}

static void random_corruption_never_crashes(void **state)
{
    (void)state;
    size_t len;
    uint8_t *b = small_file(&len);
    assert_non_null(b);
    uint8_t *c = malloc(len);
    uint32_t x = 12345;
    int refused = 0;
    for (int it = 0; it < 3000; it++) {
        memcpy(c, b, len);
        int nflip = 1 + it % 4;
        for (int k = 0; k < nflip; k++) {
            x = x * 1664525u + 1013904223u;
            size_t at = (x >> 8) % (it < 1500 ? 200 : len);
            c[at] ^= (uint8_t)(1u << ((x >> 4) & 7));
        }
        st_set *s = NULL;
        st_error e = {0};
        int rc = st_ptex_read_mem(c, len, (size_t)64 << 20, &s, &e);
        if (rc == ST_OK && (rc = st_set_levels(s, &e)) != ST_OK) { /* found late: kept */
            assert_int_equal(st_set_levels(s, NULL), rc);
            st_set_free(s);
            s = NULL;
        }
        if (rc) {
            refused++;
            assert_null(s);
            assert_true(strlen(e.msg) > 0);
        } else {
            st_set_free(s);
        }
    }
    assert_true(refused > 0);
    free(c);
    free(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_shared_ptx_loads_or_is_refused_for_a_stated_reason),
        cmocka_unit_test(mixed_resolutions_are_read_per_face),
        cmocka_unit_test(set_memory_counts_the_ptex_resolution_table_once_built),
        cmocka_unit_test(the_table_is_built_once_under_concurrent_first_use),
        cmocka_unit_test(building_the_table_writes_no_level_and_reuses_set_levels),
        cmocka_unit_test(adjacency_matches_the_obj_beside_each_file),
        cmocka_unit_test(nonquad_file_of_2009_is_plain_quads),
        cmocka_unit_test(metadata_is_kept_and_listed),
        cmocka_unit_test(border_modes_go_into_the_set_info),
        cmocka_unit_test(header_fields_are_checked_before_allocating),
        cmocka_unit_test(bad_zlib_streams_and_overruns_are_refused),
        cmocka_unit_test(inconsistent_adjacency_is_refused),
        cmocka_unit_test(random_corruption_never_crashes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
