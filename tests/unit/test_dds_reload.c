/* tests/unit/test_dds_reload.c - a COMPRESS result gives the same .dds bytes before and after
 * a daemon restart.
 *
 * The daemon's path, without the daemon: a source is imported (st_import_file appends the
 * provenance entry "seamtex:source_format"), COMPRESS makes the BC1 set and stores it as a .dds
 * (st_dds_write_mem); FETCH_OPEN ... dds before a restart writes the set in memory again; after
 * a restart the data dir's .dds is imported (the importer appends "seamtex:source_format" =
 * "dds") and FETCH_OPEN writes that. The two fetches must be byte-identical, for every kind of
 * set COMPRESS makes: per-face of one size (a DX10 array), per-face of mixed sizes (the
 * STFACES1 layout), cube (a cube map) and atlas (a plain DXT1 texture). Found by the daemon
 * fault test (tests/integration/test_faults_daemon.c): the DDS set record carried the
 * importer's entry, so the reloaded set had two ("ptex" then "dds") and its .dds was longer.
 */
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
#include "import.h"
#include "set.h"
#include "../common/ptx_fixture.h"

static char DIR_[] = "/tmp/seamtex_dds_reload_XXXXXX";

static void write_file(const char *path, const void *b, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static st_set *import_or_fail(const char *path)
{
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_import_file(path, NULL, &s, &e);
    if (rc)
        print_message("import %s: %s\n", path, e.msg);
    assert_int_equal(rc, ST_OK);
    return s;
}

static st_set *compress_or_fail(const st_set *s, int level)
{
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    o.level = level;
    o.threads = 1;
    st_set *b = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_bc1_compress_set(s, &o, NULL, NULL, NULL, &b, &e);
    if (rc)
        print_message("compress: %s\n", e.msg);
    assert_int_equal(rc, ST_OK);
    return b;
}

/* COMPRESS's .dds of b; the set a restart imports from it; that set's .dds: the same bytes
 * (and again one restart later). */
static void assert_reload_identical(const st_set *b, const char *what)
{
    st_error e;
    st_error_clear(&e);
    uint8_t *before = NULL;
    size_t blen = 0;
    assert_int_equal(st_dds_write_mem(b, &before, &blen, &e), ST_OK);
    char path[300];
    snprintf(path, sizeof path, "%s/result.dds", DIR_);
    write_file(path, before, blen);
    for (int round = 0; round < 2; round++) {
        st_set *r = import_or_fail(path);
        assert_int_equal(r->info.kind, ST_KIND_BC1);
        assert_int_equal(r->info.nfaces, b->info.nfaces);
        uint8_t *after = NULL;
        size_t alen = 0;
        assert_int_equal(st_dds_write_mem(r, &after, &alen, &e), ST_OK);
        if (alen != blen || memcmp(after, before, blen)) {
            size_t at = 0;
            while (at < alen && at < blen && after[at] == before[at])
                at++;
            print_message("%s: .dds after reload %d differs: %zu bytes, before %zu; first "
                          "difference at offset %zu (metadata entries %u, before %u)\n", what,
                          round + 1, alen, blen, at, r->nmeta, b->nmeta);
            fail();
        }
        write_file(path, after, alen);
        free(after);
        st_set_free(r);
    }
    unlink(path);
    free(before);
}

static void per_face_sets_of_one_size(void **state)
{
    (void)state;
    size_t n = 0;
    void *ptx = st_fixture_uniform_ptx(&n);
    assert_non_null(ptx);
    char path[300];
    snprintf(path, sizeof path, "%s/uni.ptx", DIR_);
    write_file(path, ptx, n);
    free(ptx);
    st_set *s = import_or_fail(path);
    assert_non_null(st_set_meta_find(s, "seamtex:source_format"));
    for (int level = ST_BC1_FAST; level <= ST_BC1_HQ; level++) {
        st_set *b = compress_or_fail(s, level);
        assert_reload_identical(b, "per-face, one size");
        st_set_free(b);
    }
    st_set_free(s);
    unlink(path);
}

static void per_face_sets_of_mixed_sizes(void **state)
{
    (void)state;
    size_t n = 0;
    void *ptx = st_fixture_default_ptx(&n, 7);
    assert_non_null(ptx);
    char path[300];
    snprintf(path, sizeof path, "%s/default.ptx", DIR_);
    write_file(path, ptx, n);
    free(ptx);
    st_set *s = import_or_fail(path);
    st_set *b = compress_or_fail(s, ST_BC1_FAST);
    assert_reload_identical(b, "per-face, mixed sizes");
    st_set_free(b);
    st_set_free(s);
    unlink(path);
}

/* What the image importer makes of a cube or an atlas image: the set plus its provenance. */
static st_set *made_set(int kind, uint32_t nf, uint32_t w, uint32_t h, const char *fmt)
{
    static const int A[6][4][2] = {{{2, 1}, {4, 3}, {3, 1}, {5, 1}}, {{2, 3}, {5, 3}, {3, 3}, {4, 1}},
                                   {{4, 0}, {0, 0}, {5, 0}, {1, 0}}, {{5, 2}, {0, 2}, {4, 2}, {1, 2}},
                                   {{2, 0}, {1, 3}, {3, 2}, {0, 1}}, {{2, 2}, {0, 3}, {3, 0}, {1, 1}}};
    st_face_desc fd[6];
    memset(fd, 0, sizeof fd);
    for (uint32_t f = 0; f < nf; f++) {
        fd[f].w = w;
        fd[f].h = h;
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = kind == ST_KIND_CUBE ? A[f][k][0] : -1;
            fd[f].adjedge[k] = (int8_t)(kind == ST_KIND_CUBE ? A[f][k][1] : 0);
        }
    }
    st_set_info in = {.nfaces = nf, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = 3,
                      .kind = (uint8_t)kind, .colorspace = ST_CS_SRGB};
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_set_create(&in, fd, 0, &s, &e), ST_OK);
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)(i % 4 == 3 ? 255 : i * 7 + (i >> 6));
    st_set_build_mips(s, kind == ST_KIND_ATLAS ? 0 : UINT32_MAX);
    assert_int_equal(st_set_meta_add(s, "seamtex:source_format", 0, fmt,
                                     (uint32_t)strlen(fmt) + 1, &e), ST_OK);
    return s;
}

static void cube_sets(void **state)
{
    (void)state;
    st_set *s = made_set(ST_KIND_CUBE, 6, 16, 16, "exr");
    st_set *b = compress_or_fail(s, ST_BC1_FAST);
    assert_reload_identical(b, "cube");
    st_set_free(b);
    st_set_free(s);
}

static void atlas_sets(void **state)
{
    (void)state;
    st_set *s = made_set(ST_KIND_ATLAS, 1, 20, 12, "image");
    st_set *b = compress_or_fail(s, ST_BC1_FAST);
    assert_reload_identical(b, "atlas");
    st_set_free(b);
    st_set_free(s);
}

/* Other metadata is kept, in order, with its last value; only the provenance entry is left
 * out. */
static void other_metadata_survives(void **state)
{
    (void)state;
    st_set *s = made_set(ST_KIND_ATLAS, 1, 8, 8, "image");
    st_error e;
    st_error_clear(&e);
    int32_t v[2] = {4, -5};
    assert_int_equal(st_set_meta_add(s, "b", 3, v, 2, &e), ST_OK);
    assert_int_equal(st_set_meta_add(s, "a", 0, "x", 2, &e), ST_OK);
    assert_int_equal(st_set_meta_add(s, "b", 3, v + 1, 1, &e), ST_OK);
    st_set *b = compress_or_fail(s, ST_BC1_FAST);
    uint8_t *buf = NULL;
    size_t len = 0;
    assert_int_equal(st_dds_write_mem(b, &buf, &len, &e), ST_OK);
    st_set *r = NULL;
    assert_int_equal(st_dds_read_mem(buf, len, 0, &r, &e), ST_OK);
    assert_int_equal(r->nmeta, 2);
    assert_string_equal(r->meta[0].key, "b");
    assert_int_equal(r->meta[0].count, 1);
    assert_memory_equal(r->meta[0].data, v + 1, 4);
    assert_string_equal(r->meta[1].key, "a");
    assert_string_equal((const char *)r->meta[1].data, "x");
    assert_null(st_set_meta_find(r, "seamtex:source_format"));
    st_set_free(r);
    free(buf);
    assert_reload_identical(b, "atlas with metadata");
    st_set_free(b);
    st_set_free(s);
}

static int setup(void **state)
{
    (void)state;
    return mkdtemp(DIR_) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    return rmdir(DIR_);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(per_face_sets_of_one_size),
        cmocka_unit_test(per_face_sets_of_mixed_sizes),
        cmocka_unit_test(cube_sets),
        cmocka_unit_test(atlas_sets),
        cmocka_unit_test(other_metadata_survives),
    };
    return cmocka_run_group_tests_name("dds_reload", tests, setup, teardown);
}
