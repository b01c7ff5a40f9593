/* tests/unit/test_ptex_write.c - the Ptex writer: files it writes read back bit for bit
 * (every shared .ptx, synthetic sets with constant faces, subfaces, mixed resolutions, alpha,
 * border modes, small and large metadata), writing what the reader gives reproduces the same
 * bytes (no growth over upload/fetch loops, repeated metadata keys written once), large faces
 * are tiled as Ptex tiles them, and the file is replaced atomically. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "defaultset.h"
#include "ptex.h"
#include "ptex_format.h"

static const char *data_dir(void)
{
    const char *d = getenv("SEAMTEX_DATA");
    return d && *d ? d : "../shared/data";
}

/* levels_all: compare every level; else level 0 and the square reductions only */
static void assert_same_set(const st_set *a, const st_set *b, int levels_all)
{
    /* the levels are read below: a deferred import's are made first (ptex.h) */
    assert_int_equal(st_set_levels(a, NULL), ST_OK);
    assert_int_equal(st_set_levels(b, NULL), ST_OK);
    assert_int_equal(a->info.nfaces, b->info.nfaces);
    assert_int_equal(a->info.nchan, b->info.nchan);
    assert_int_equal(a->info.dtype, b->info.dtype);
    assert_int_equal(a->info.alpha_chan, b->info.alpha_chan);
    assert_int_equal(a->info.border_u, b->info.border_u);
    assert_int_equal(a->info.border_v, b->info.border_v);
    size_t ts = st_texel_size(a);
    for (uint32_t f = 0; f < a->info.nfaces; f++) {
        const st_face *A = &a->faces[f], *B = &b->faces[f];
        assert_int_equal(A->w, B->w);
        assert_int_equal(A->h, B->h);
        assert_int_equal(A->flags, B->flags);
        for (int ed = 0; ed < 4; ed++) {
            assert_int_equal(A->adjface[ed], B->adjface[ed]);
            if (A->adjface[ed] >= 0)
                assert_int_equal(A->adjedge[ed], B->adjedge[ed]);
        }
        if (A->flags & ST_FACE_CONSTANT) {
            assert_memory_equal(st_face_level(a, f, 0), st_face_level(b, f, 0), ts);
            continue;
        }
        unsigned sq = (A->ulog2 < A->vlog2 ? A->ulog2 : A->vlog2) + 1u;
        unsigned nl = levels_all || A->w == A->h ? A->nlevels : sq;
        for (unsigned l = 0; l < nl; l++) {
            size_t bytes = (size_t)st_level_w(A, l) * st_level_h(A, l) * ts;
            if (memcmp(st_face_level(a, f, l), st_face_level(b, f, l), bytes)) {
                print_message("face %u level %u differs\n", f, l);
                fail();
            }
        }
    }
    assert_int_equal(a->nmeta, b->nmeta);
    for (uint32_t i = 0; i < a->nmeta; i++) {
        const st_meta_entry *m = st_set_meta_find(b, a->meta[i].key);
        assert_non_null(m);
        assert_int_equal(m->type, a->meta[i].type);
        assert_int_equal(m->count, a->meta[i].count);
        static const size_t tsz[] = {1, 1, 2, 4, 4, 8};
        assert_memory_equal(m->data, a->meta[i].data, tsz[m->type] * m->count);
    }
}

static st_set *roundtrip(const st_set *s)
{
    void *buf;
    size_t len;
    st_error e = {0};
    int rc = st_ptex_write_mem(s, &buf, &len, &e);
    if (rc)
        print_message("write: %s\n", e.msg);
    assert_int_equal(rc, 0);
    st_set *r = NULL;
    rc = st_ptex_read_mem(buf, len, 0, &r, &e);
    if (rc)
        print_message("read back: %s\n", e.msg);
    assert_int_equal(rc, 0);
    free(buf);
    return r;
}

static void every_shared_file_round_trips_bit_exactly(void **state)
{
    (void)state;
    static const char *rel[] = {
        "ptex-ref/cube1_k6_u8.ptx", "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx",
        "ptx/wdas-ptex-2009/bordermodes/black.ptx", "ptx/wdas-ptex-2009/bordermodes/periodic.ptx",
        "ptx/wdas-ptex-2009/cube/text/cube.ptx", "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
        "ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx", "ptx/wdas-ptex-2009/tri/uv.ptx",
        "ptx/wdas-ptex-samples/envcube/envcube.ptx", "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
        "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    };
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", data_dir(), rel[0]);
    if (access(path, R_OK)) {
        print_message("SEAMTEX_DATA (%s) missing: skipped\n", data_dir());
        skip();
    }
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", data_dir(), rel[i]);
        st_set *s;
        st_error e = {0};
        assert_int_equal(st_ptex_read_file(path, 0, &s, &e), 0);
        st_set *r = roundtrip(s);
        assert_same_set(s, r, 1);
        st_set_free(r);
        st_set_free(s);
    }
}

/* A synthetic set: 4 faces in a strip (one constant, one non-square), values from a hash. */
static st_set *make_set(unsigned dtype, unsigned nchan, int alpha, int subfaces)
{
    st_face_desc fd[4];
    memset(fd, 0, sizeof fd);
    uint32_t sizes[4][2] = {{16, 16}, {8, 32}, {4, 4}, {64, 64}};
    for (int f = 0; f < 4; f++) {
        fd[f].w = sizes[f][0];
        fd[f].h = sizes[f][1];
        for (int ed = 0; ed < 4; ed++)
            fd[f].adjface[ed] = -1;
        if (f > 0) {                  /* left edge of f meets right edge of f-1 */
            fd[f].adjface[3] = f - 1;
            fd[f].adjedge[3] = 1;
            fd[f - 1].adjface[1] = f;
            fd[f - 1].adjedge[1] = 3;
        }
        if (subfaces && f >= 2)
            fd[f].flags |= ST_FACE_SUBFACE;
    }
    fd[2].flags |= ST_FACE_CONSTANT;
    st_set_info info = {.nfaces = 4, .nchan = (uint8_t)nchan, .dtype = (uint8_t)dtype,
                        .alpha_chan = (int8_t)alpha, .kind = ST_KIND_PERFACE, .border_u = 2,
                        .border_v = 1};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, fd, 0, &s, &e), 0);
    uint32_t x = 77;
    for (uint32_t f = 0; f < 4; f++) {
        const st_face *F = &s->faces[f];
        size_t n = F->flags & ST_FACE_CONSTANT ? 1 : (size_t)F->w * F->h;
        uint8_t *p = st_face_level(s, f, 0);
        for (size_t i = 0; i < n; i++)
            for (unsigned c = 0; c < nchan; c++) {
                x = x * 1664525u + 1013904223u;
                float v = (float)((x >> 8) & 0xffff) / 65535.0f;
                st_channel_put(dtype, p + i * st_texel_size(s), c, v);
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    return s;
}

static void synthetic_sets_round_trip_in_every_data_type(void **state)
{
    (void)state;
    for (unsigned dt = 0; dt < 4; dt++)
        for (unsigned nc = 1; nc <= 4; nc++) {
            st_set *s = make_set(dt, nc, nc == 4 ? 3 : -1, nc == 2);
            st_error e = {0};
            assert_int_equal(st_set_meta_add(s, "name", 0, "synthetic", 10, &e), 0);
            int32_t big[600];
            for (int i = 0; i < 600; i++)
                big[i] = i * 7 - 300;
            assert_int_equal(st_set_meta_add(s, "big", 3, big, 600, &e), 0); /* large metadata */
            double d = 1.5;
            assert_int_equal(st_set_meta_add(s, "d", 5, &d, 1, &e), 0);
            st_set *r = roundtrip(s);
            assert_same_set(s, r, 0);
            /* what the reader gives is a fixed point: write it again, read it again */
            st_set *r2 = roundtrip(r);
            assert_same_set(r, r2, 1);
            st_set_free(r2);
            st_set_free(r);
            st_set_free(s);
        }
}

static void write_mem_ok(const st_set *s, void **buf, size_t *len)
{
    st_error e = {0};
    int rc = st_ptex_write_mem(s, buf, len, &e);
    if (rc)
        print_message("write: %s\n", e.msg);
    assert_int_equal(rc, 0);
}

/* write(read(b)) must give b again, byte for byte; returns the set read from b. */
static st_set *assert_fixed_point(const void *b, size_t len, const char *what)
{
    st_set *r = NULL;
    st_error e = {0};
    int rc = st_ptex_read_mem(b, len, 0, &r, &e);
    if (rc)
        print_message("%s: read: %s\n", what, e.msg);
    assert_int_equal(rc, 0);
    void *b2;
    size_t len2;
    write_mem_ok(r, &b2, &len2);
    if (len2 != len || memcmp(b, b2, len)) {
        print_message("%s: %zu bytes written, %zu after read + write\n", what, len, len2);
        fail();
    }
    free(b2);
    return r;
}

/* The daemon's upload/fetch loop: import reads the .ptx and appends "seamtex:source_format",
 * FETCH writes the set. The file must not change from one round to the next:
 * write(read(write(x))) == write(x), also with the importer's key added (once or twice). */
static void writing_what_the_reader_gives_is_a_fixed_point(void **state)
{
    (void)state;
    static const char *rel[] = {
        "ptex-ref/cube1_k6_u8.ptx", "ptex-ref/cube8_k6_u8_rot.ptx",
        "ptex-ref/cube8_k7varrot_f32.ptx", "ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx",
        "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx", "ptx/wdas-ptex-2009/tri/uv.ptx",
        "ptx/wdas-ptex-samples/envcube/envcube.ptx", "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    };
    st_set *sets[sizeof rel / sizeof rel[0] + 2] = {0};
    size_t nsets = 0;
    st_error e = {0};
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", data_dir(), rel[0]);
    if (access(path, R_OK)) {
        print_message("SEAMTEX_DATA (%s) missing: shared files skipped\n", data_dir());
    } else {
        for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
            snprintf(path, sizeof path, "%s/%s", data_dir(), rel[i]);
            assert_int_equal(st_ptex_read_file(path, 0, &sets[nsets], &e), 0);
            nsets++;
        }
    }
    assert_int_equal(st_default_set(&sets[nsets++], &e), 0);
    st_set *syn = make_set(ST_DT_U16, 3, -1, 1);
    assert_int_equal(st_set_meta_add(syn, "name", 0, "synthetic", 10, &e), 0);
    sets[nsets++] = syn;
    for (size_t i = 0; i < nsets; i++) {
        const char *what = i < nsets - 2 ? rel[i] : i == nsets - 2 ? "default set" : "synthetic";
        st_set *x = sets[i];
        void *b1, *b2;
        size_t len1, len2;
        write_mem_ok(x, &b1, &len1);
        /* what the importer adds to a set is not written: the same bytes */
        assert_int_equal(st_set_meta_add(x, "seamtex:source_format", 0, "png", 4, &e), 0);
        write_mem_ok(x, &b2, &len2);
        if (len2 != len1 || memcmp(b1, b2, len1)) {
            print_message("%s: %zu bytes, %zu with the importer's key\n", what, len1, len2);
            fail();
        }
        free(b2);
        st_set *r = assert_fixed_point(b1, len1, what);
        /* upload: the importer sets its key, over two rounds (a key holds one value) */
        uint32_t nmeta = r->nmeta;
        for (int round = 0; round < 2; round++) {
            assert_int_equal(st_set_meta_add(r, "seamtex:source_format", 0, "ptex", 5, &e), 0);
            assert_int_equal(r->nmeta, nmeta + 1);
            write_mem_ok(r, &b2, &len2);
            if (len2 != len1 || memcmp(b1, b2, len1)) {
                print_message("%s: %zu bytes, %zu after upload round %d\n", what, len1, len2,
                              round);
                fail();
            }
            st_set *r2 = assert_fixed_point(b2, len2, what);
            assert_int_equal(r2->nmeta, nmeta);
            assert_null(st_set_meta_find(r2, "seamtex:source_format"));
            free(b2);
            st_set_free(r2);
        }
        st_set_free(r);
        free(b1);
        st_set_free(x);
    }
}

/* A repeated key keeps its first position and takes its last value (the reader's rule for
 * repeated records and metadata edits). */
static void a_repeated_metadata_key_is_written_once_with_its_last_value(void **state)
{
    (void)state;
    st_set *s = make_set(ST_DT_U8, 1, -1, 0);
    st_error e = {0};
    int32_t one = 1, two = 2;
    int32_t big[400];
    for (int i = 0; i < 400; i++)
        big[i] = i;
    assert_int_equal(st_set_meta_add(s, "a", 3, &one, 1, &e), 0);
    assert_int_equal(st_set_meta_add(s, "b", 0, "x", 2, &e), 0);
    assert_int_equal(st_set_meta_add(s, "a", 3, big, 400, &e), 0);  /* now large */
    assert_int_equal(st_set_meta_add(s, "c", 0, "y", 2, &e), 0);
    assert_int_equal(st_set_meta_add(s, "a", 3, &two, 1, &e), 0);   /* small again */
    void *buf;
    size_t len;
    write_mem_ok(s, &buf, &len);
    st_set *r = NULL;
    assert_int_equal(st_ptex_read_mem(buf, len, 0, &r, &e), 0);
    assert_int_equal(r->nmeta, 3);
    assert_string_equal(r->meta[0].key, "a");
    assert_string_equal(r->meta[1].key, "b");
    assert_string_equal(r->meta[2].key, "c");
    assert_int_equal(r->meta[0].count, 1);
    assert_int_equal(*(const int32_t *)r->meta[0].data, 2);
    st_set_free(assert_fixed_point(buf, len, "repeated keys"));
    st_set_free(r);
    free(buf);
    st_set_free(s);
}

static void large_faces_are_tiled_as_ptex_tiles_them(void **state)
{
    (void)state;
    st_face_desc fd = {.w = 512, .h = 256, .adjface = {-1, -1, -1, -1}};
    st_set_info info = {.nfaces = 1, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = -1,
                        .kind = ST_KIND_PERFACE};
    st_set *s;
    st_error e = {0};
    assert_int_equal(st_set_create(&info, &fd, 0, &s, &e), 0);
    uint8_t *p = st_face_level(s, 0, 0);
    for (uint32_t y = 0; y < 256; y++)
        for (uint32_t x = 0; x < 512; x++) {
            uint8_t *t = p + ((size_t)y * 512 + x) * 4;
            /* left half varies, right half uniform: constant tiles appear */
            t[0] = x < 256 ? (uint8_t)(x ^ y) : 7;
            t[1] = x < 256 ? (uint8_t)(x * 3) : 7;
            t[2] = x < 256 ? (uint8_t)y : 7;
            t[3] = 255;
        }
    st_set_build_mips(s, UINT32_MAX);
    void *buf;
    size_t len;
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    const uint8_t *b = buf;
    /* level 0 header: one face, tiled; 512*256*4 bytes = 8 x 64 KiB -> 2^3 tiles of 128x128 */
    uint32_t ext = ptx_rd32(b + 28);
    size_t lipos = PTX_HEADER_SIZE + ext + ptx_rd32(b + 32) + ptx_rd32(b + 36);
    size_t l0 = lipos + ptx_rd16(b + 22) * PTX_LEVELINFO_SIZE;
    uint32_t hsize = ptx_rd32(b + lipos + 8);
    uint8_t fdh[4];
    uLongf fl = 4;
    assert_int_equal(uncompress(fdh, &fl, b + l0, hsize), Z_OK);
    assert_int_equal(ptx_rd32(fdh) >> 30, PTX_ENC_TILED);
    const uint8_t *t = b + l0 + hsize;
    assert_int_equal((int8_t)t[0], 7); /* tile res 128 x 128 */
    assert_int_equal((int8_t)t[1], 7);
    st_set *r = NULL;
    assert_int_equal(st_ptex_read_mem(buf, len, 0, &r, &e), 0);
    assert_same_set(s, r, 0);
    st_set_free(r);
    free(buf);
    st_set_free(s);
}

static void write_file_replaces_atomically(void **state)
{
    (void)state;
    char dir[] = "/tmp/seamtex_ptexw_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256], tmp[300];
    snprintf(path, sizeof path, "%s/out.ptx", dir);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    st_set *s = make_set(ST_DT_HALF, 3, -1, 0);
    st_error e = {0};
    assert_int_equal(st_ptex_write_file(s, path, &e), 0);
    assert_int_equal(st_ptex_write_file(s, path, &e), 0); /* over an existing file */
    assert_int_not_equal(access(tmp, F_OK), 0);
    st_set *r;
    assert_int_equal(st_ptex_read_file(path, 0, &r, &e), 0);
    assert_same_set(s, r, 0);
    st_set_free(r);
    char bad[300];
    snprintf(bad, sizeof bad, "%s/no/such/dir/x.ptx", dir);
    assert_int_equal(st_ptex_write_file(s, bad, &e), ST_EIO);
    assert_true(strlen(e.msg) > 0);
    st_set_free(s);
    unlink(path);
    rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_shared_file_round_trips_bit_exactly),
        cmocka_unit_test(synthetic_sets_round_trip_in_every_data_type),
        cmocka_unit_test(writing_what_the_reader_gives_is_a_fixed_point),
        cmocka_unit_test(a_repeated_metadata_key_is_written_once_with_its_last_value),
        cmocka_unit_test(large_faces_are_tiled_as_ptex_tiles_them),
        cmocka_unit_test(write_file_replaces_atomically),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
