/* tests/unit/test_native_resident.c - what the memory budget counts of a mapped set and what a
 * release does (store/native/native_resident.c, the two counts of native.h):
 *   - the mapped count (pagemap) counts the pages present in this process's page tables for
 *     this mapping only: a second mapping of the same file whose texels were never read counts
 *     only what its open read while the page cache holds the whole file;
 *   - a release under the mapped count unmaps every page (count 0), leaves the file in the
 *     page cache, and the bytes read back identical to the set that was written;
 *   - it does so while the file is still dirty (written, not yet written back): the page-cache
 *     count could not drop those pages, the mapped count goes to 0 all the same;
 *   - a release under the page-cache count (the fallback) drops the file from the page cache
 *     (skipped where the file system ignores POSIX_FADV_DONTNEED), and the bytes are identical;
 *   - a heap set counts 0 and a release of it does nothing.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "native.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

typedef struct fx {
    char    dir[512], path[700];
    st_set *heap;   /* the set written, texels filled with a pattern */
} fx;

static int setup(void **state)
{
    fx *f = calloc(1, sizeof *f);
    if (!f || st_test_mkdtemp(f->dir, sizeof f->dir, "resident") != 0)
        return -1;
    snprintf(f->path, sizeof f->path, "%s/set.native", f->dir);
    f->heap = st_fixture_rgba8_faces(256);   /* 4 faces of 256 x 256 RGBA8 + levels: 1.3 MB */
    if (!f->heap)
        return -1;
    uint32_t x = 12345;
    for (size_t i = 0; i < f->heap->texel_bytes; i++) {
        x = x * 1103515245u + 12345u;
        f->heap->texels[i] = (uint8_t)(x >> 24);
    }
    st_error e;
    if (st_native_write(f->path, f->heap, NULL, &e) != 0)
        return -1;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fx *f = *state;
    st_set_free(f->heap);
    int rc = st_test_rmtree(f->dir);
    free(f);
    return rc;
}

static st_set *open_mapped(const char *path)
{
    st_set *m = NULL;
    st_error e;
    assert_int_equal(st_native_open(path, 0, NULL, &m, &e), 0);
    assert_non_null(m->map);
    return m;
}

/* Reads every page of the mapping (header pages included). */
static void touch_all(const st_set *m)
{
    volatile uint8_t sum = 0;
    const uint8_t *p = m->map;
    for (size_t i = 0; i < m->map_len; i += 4096)
        sum += p[i];
    (void)sum;
}

static void same_bytes(const st_set *heap, const st_set *m)
{
    assert_int_equal(m->texel_bytes, heap->texel_bytes);
    assert_memory_equal(m->texels, heap->texels, heap->texel_bytes);
}

/* The mapped count, or skip where /proc/self/pagemap cannot be read. */
static void open_meter_or_skip(st_native_meter *mt)
{
    if (st_native_meter_open(mt) != ST_NATIVE_COUNT_MAPPED) {
        printf("# /proc/self/pagemap cannot be read here: the mapped count is not tested\n");
        skip();
    }
}

static void test_mapped_count_is_this_mappings_pages_only(void **state)
{
    fx *f = *state;
    st_native_meter mt, cache = {-1};
    open_meter_or_skip(&mt);
    /* a bigger file than the fixture's (21 MB): the kernel maps a read's neighbourhood at
     * once (fault-around, and whole large folios of the page cache, up to 2 MB), and the
     * counts below must stay clear of the whole file */
    char path[800];
    snprintf(path, sizeof path, "%s/big.native", f->dir);
    st_set *h = st_fixture_rgba8_faces(1024);
    assert_non_null(h);
    st_error e;
    assert_int_equal(st_native_write(path, h, NULL, &e), 0);
    st_set_free(h);
    st_set *a = open_mapped(path), *b = open_mapped(path);
    assert_int_equal(st_native_meter_count(&cache), ST_NATIVE_COUNT_CACHED);
    touch_all(a);
    assert_int_equal(st_native_resident(a, &mt), a->map_len);
    /* b maps the same file, whose pages are all in the page cache, and read only what the
     * open checks (the small sections' CRCs, the face table): not the texels */
    assert_int_equal(st_native_resident(b, &cache), b->map_len);
    size_t opened = st_native_resident(b, &mt);
    assert_true(opened < b->map_len / 2);
    /* reading one texel maps its neighbourhood, not the file */
    volatile uint8_t t = b->texels[b->texel_bytes - b->texel_bytes / 4];
    (void)t;
    size_t one = st_native_resident(b, &mt);
    assert_true(one > opened);
    assert_true(one < b->map_len);
    /* and a's count is still its own */
    assert_int_equal(st_native_resident(a, &mt), a->map_len);
    st_set_free(b);
    st_set_free(a);
    st_native_meter_close(&mt);
}

static void test_release_unmaps_and_keeps_the_page_cache(void **state)
{
    fx *f = *state;
    st_native_meter mt, cache = {-1};
    open_meter_or_skip(&mt);
    st_set *m = open_mapped(f->path);
    touch_all(m);
    size_t cached = st_native_resident(m, &cache);
    assert_int_equal(cached, m->map_len);
    assert_int_equal(st_native_release(m, &mt), m->map_len);
    assert_int_equal(st_native_resident(m, &mt), 0);
    /* the file stays in the page cache: the next faults are minor ones */
    assert_int_equal(st_native_resident(m, &cache), cached);
    same_bytes(f->heap, m);
    assert_true(st_native_resident(m, &mt) >= m->texel_bytes);
    /* released again, and again the same bytes */
    assert_true(st_native_release(m, &mt) >= m->texel_bytes);
    assert_int_equal(st_native_resident(m, &mt), 0);
    same_bytes(f->heap, m);
    st_set_free(m);
    st_native_meter_close(&mt);
}

static void test_release_of_a_dirty_file_counts_zero(void **state)
{
    fx *f = *state;
    st_native_meter mt;
    open_meter_or_skip(&mt);
    /* a copy written with write(2) and not synced: its pages are dirty in the page cache, and
     * posix_fadvise DONTNEED (the page-cache count's release) leaves dirty pages there */
    char copy[800];
    snprintf(copy, sizeof copy, "%s/copy.native", f->dir);
    int in = open(f->path, O_RDONLY), out = open(copy, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(in >= 0 && out >= 0);
    char buf[65536];
    ssize_t n;
    while ((n = read(in, buf, sizeof buf)) > 0)
        assert_int_equal(write(out, buf, (size_t)n), n);
    assert_int_equal(n, 0);
    close(in);
    close(out);
    st_set *m = open_mapped(copy);
    touch_all(m);
    assert_int_equal(st_native_resident(m, &mt), m->map_len);
    st_native_release(m, &mt);
    assert_int_equal(st_native_resident(m, &mt), 0);
    same_bytes(f->heap, m);
    st_set_free(m);
    st_native_meter_close(&mt);
}

static void test_page_cache_count_release_drops_the_cache(void **state)
{
    fx *f = *state;
    st_native_meter cache = {-1};
    st_set *m = open_mapped(f->path);
    touch_all(m);
    assert_int_equal(st_native_resident(m, &cache), m->map_len);
    assert_int_equal(st_native_release(m, &cache), m->map_len);
    size_t after = st_native_resident(m, &cache);
    same_bytes(f->heap, m);   /* read back from the disk when the cache let the pages go */
    st_set_free(m);
    if (after > 0) {   /* a file system whose page cache ignores POSIX_FADV_DONTNEED */
        printf("# the page cache kept %zu bytes after POSIX_FADV_DONTNEED: skipped\n", after);
        skip();
    }
}

static void test_heap_set_counts_nothing(void **state)
{
    fx *f = *state;
    st_native_meter mt, cache = {-1};
    st_native_meter_open(&mt);
    assert_int_equal(st_native_resident(f->heap, &mt), 0);
    assert_int_equal(st_native_resident(f->heap, &cache), 0);
    assert_int_equal(st_native_release(f->heap, &mt), 0);
    assert_int_equal(st_native_release(f->heap, &cache), 0);
    assert_int_equal(st_native_resident(NULL, &mt), 0);
    st_native_meter_close(&mt);
    assert_int_equal(mt.pagemap_fd, -1);
    st_native_meter_close(&mt);   /* closing twice is harmless */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_mapped_count_is_this_mappings_pages_only, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_release_unmaps_and_keeps_the_page_cache, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_release_of_a_dirty_file_counts_zero, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_page_cache_count_release_drops_the_cache, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_heap_set_counts_nothing, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
