/* tests/unit/test_budget.c - the memory budget's rules (server/budget.c):
 *   - the release rule (sts_budget_plan): a pass releases past 95% of the budget, down to 90%,
 *     so that pages faulted in between two ticks stay under the budget; an unlimited budget
 *     never releases;
 *   - the resident measure (sts_budget_set_resident): a mapped set's pages are counted again
 *     (st_native_resident) only when it was sampled since its last measure or in a full pass;
 *     otherwise its last figure stands (a tick must not cost a pass over every mapping);
 *   - a pass (sts_budget_pass) releases the least recently sampled mapped sets, whole, down to
 *     the low mark and no further: the recently sampled ones keep their pages, the released
 *     ones count 0 and read back the same bytes; a heap set is counted and never released;
 *   - between full passes a pass takes resident from /proc/self/statm, so pages mapped since
 *     the last pass count even for sets no sample stamped;
 *   - an atlas set mapped from its native file counts its heap (mesh, mask, its chart data once
 *     a chart-mode sample built it); a release drops the chart data with the pages unless a
 *     sampler has it pinned, and the next chart sample rebuilds it, the same outputs.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "atlas.h"
#include "budget.h"
#include "registry.h"
#include "native.h"
#include "server.h"
#include "../common/atlas_fixture.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

static void test_releases_past_the_high_mark_not_only_past_the_budget(void **st)
{
    (void)st;
    uint64_t goal = 0, b = 2048ull << 20;
    /* 96% of the budget: under it, yet a pass releases (the old rule waited for > budget) */
    assert_int_equal(sts_budget_plan(b / 100 * 96, b, &goal), 1);
    assert_int_equal(goal, b - b / 10);
    assert_int_equal(sts_budget_plan(b + 1, b, &goal), 1);
    /* at the high mark exactly and below it: nothing to do */
    assert_int_equal(sts_budget_plan(b - b / 20, b, &goal), 0);
    assert_int_equal(sts_budget_plan(b / 100 * 94, b, &goal), 0);
    assert_int_equal(sts_budget_plan(0, b, &goal), 0);
}

static void test_goal_is_under_the_high_mark(void **st)
{
    (void)st;
    static const uint64_t budgets[] = {1, 19, 20, 4096, 8192, 1000003, UINT64_MAX};
    for (size_t i = 0; i < sizeof budgets / sizeof budgets[0]; i++) {
        uint64_t b = budgets[i], goal = 0;
        assert_int_equal(sts_budget_plan(b, b, &goal), b >= 20);
        assert_true(goal <= b);
        assert_true(goal <= b - b / 20);
        /* anything above the budget is released */
        if (b < UINT64_MAX)
            assert_int_equal(sts_budget_plan(b + 1, b, &goal), 1);
    }
}

static void test_unlimited_budget_never_releases(void **st)
{
    (void)st;
    uint64_t goal = 1;
    assert_int_equal(sts_budget_plan(UINT64_MAX, 0, &goal), 0);
    assert_int_equal(sts_budget_plan(1, 0, &goal), 0);
}

static void test_resident_measured_again_only_for_sampled_sets(void **st)
{
    (void)st;
    char dir[512], path[700];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "budget"), 0);
    snprintf(path, sizeof path, "%s/set.native", dir);
    st_set *h = st_fixture_rgba8_faces(256);   /* 4 faces of 256 x 256 RGBA8: 1.3 MB */
    assert_non_null(h);
    st_error e;
    assert_int_equal(st_native_write(path, h, NULL, &e), 0);
    st_set *m = NULL;
    assert_int_equal(st_native_open(path, 0, NULL, &m, &e), 0);
    volatile uint8_t sum = 0;
    for (size_t i = 0; i < m->texel_bytes; i += 4096)
        sum += m->texels[i];
    (void)sum;   /* the reads are the point; clang counts no volatile read as a use */
    uint64_t t = (uint64_t)sts_now_ms();
    st_native_meter mt;   /* the mapped count; the page-cache count where pagemap is closed */
    st_native_meter_open(&mt);
    uint64_t full = sts_budget_set_resident(m, &mt, t, 1);
    assert_true(full >= m->texel_bytes);
    st_native_release(m, &mt);
    uint64_t after = st_native_resident(m, &mt);
    if (after >= full) {   /* page-cache count: a file system ignoring POSIX_FADV_DONTNEED */
        st_native_meter_close(&mt);
        st_set_free(m);
        st_set_free(h);
        st_test_rmtree(dir);
        skip();
    }
    /* not sampled since the last measure: the last figure stands */
    assert_int_equal(sts_budget_set_resident(m, &mt, t + 1, 0), full);
    /* a sample stamps the set (sts_budget_touch): the next measure counts its pages again */
    static sts_server srv;   /* no budget thread: touch only stamps a set that is not cold */
    assert_int_equal(sts_budget_touch(&srv, m), 0);
    uint64_t stamp = m->last_use_ms;
    assert_true(stamp >= t);
    uint64_t fresh = sts_budget_set_resident(m, &mt, stamp + 10, 0);
    assert_true(fresh < full);
    assert_int_equal(fresh, st_native_resident(m, &mt));
    /* pages faulted in without a sample are caught by the next full pass */
    for (size_t i = 0; i < m->texel_bytes; i += 4096)
        sum += m->texels[i];
    uint64_t t2 = stamp + 20;
    assert_int_equal(sts_budget_set_resident(m, &mt, t2, 0), fresh);
    assert_true(sts_budget_set_resident(m, &mt, t2, 1) >= m->texel_bytes);
    st_native_meter_close(&mt);
    st_set_free(m);
    st_set_free(h);
    assert_int_equal(st_test_rmtree(dir), 0);
}

/* Four mapped sets of R bytes sampled in order (set 0 longest ago) and one heap set H, under a
 * budget whose low mark leaves room for H and two and a half mapped sets: one pass releases
 * sets 0 and 1 - the two least recently sampled - and nothing else. */
static void test_pass_releases_the_least_recently_sampled_sets_whole(void **st)
{
    (void)st;
    st_native_meter mt;
    if (st_native_meter_open(&mt) != ST_NATIVE_COUNT_MAPPED) {
        printf("# /proc/self/pagemap cannot be read here: skipped\n");
        skip();
    }
    char dir[512], path[4][700];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "budgetpass"), 0);
    static sts_server srv;
    memset(&srv, 0, sizeof srv);
    srv.reg = st_registry_create();
    assert_non_null(srv.reg);
    st_set *h = st_fixture_rgba8_faces(128);
    assert_non_null(h);
    for (size_t i = 0; i < h->texel_bytes; i++)
        h->texels[i] = (uint8_t)(i * 7 + i / 4096);
    st_error e;
    st_set *m[4];
    for (int k = 0; k < 4; k++) {
        snprintf(path[k], sizeof path[k], "%s/s%d.native", dir, k);
        assert_int_equal(st_native_write(path[k], h, NULL, &e), 0);
        assert_int_equal(st_native_open(path[k], 0, NULL, &m[k], &e), 0);
        char name[16];
        snprintf(name, sizeof name, "s%d", k);
        assert_int_equal(st_registry_put(srv.reg, name, m[k], NULL, 0, NULL, &e), 0);
    }
    st_set *heap = st_fixture_rgba8_faces(64);
    assert_non_null(heap);
    uint64_t H = st_set_memory(heap);
    assert_int_equal(st_registry_put(srv.reg, "heap", heap, NULL, 0, NULL, &e), 0);
    uint64_t now = (uint64_t)sts_now_ms();
    volatile uint8_t sum = 0;
    for (int k = 0; k < 4; k++) {
        for (size_t i = 0; i < m[k]->map_len; i += 4096)
            sum += ((const uint8_t *)m[k]->map)[i];
        m[k]->last_use_ms = now - 40 + (uint64_t)k * 10;   /* set 3 sampled last */
    }
    uint64_t R = m[0]->map_len;
    for (int k = 0; k < 4; k++)
        assert_int_equal(st_native_resident(m[k], &mt), R);
    /* low mark (90%) = H + 2.5 R: releasing set 0 leaves H + 3 R, set 1 then H + 2 R */
    uint64_t budget = (H + 5 * R / 2) * 10 / 9 + 1, goal;
    assert_int_equal(sts_budget_plan(H + 4 * R, budget, &goal), 1);
    sts_budget_pass(&srv, budget);
    assert_int_equal(srv.budget.releases, 2);
    assert_int_equal(srv.budget.released_bytes, 2 * R);
    assert_int_equal(srv.budget.resident, H + 2 * R);
    for (int k = 0; k < 4; k++) {
        assert_int_equal(m[k]->cold, k < 2);
        assert_int_equal(st_native_resident(m[k], &mt), k < 2 ? 0 : R);
    }
    /* a second pass has nothing to do: the count went down by what was released */
    sts_budget_pass(&srv, budget);
    assert_int_equal(srv.budget.releases, 2);
    /* the released sets read back the bytes that were written; a sample stamps them first
     * (sts_budget_touch: cold until then), so the next measure counts their pages again */
    for (int k = 0; k < 2; k++) {
        assert_int_equal(sts_budget_touch(&srv, m[k]), 1);
        assert_int_equal(m[k]->cold, 0);
        assert_memory_equal(m[k]->texels, h->texels, h->texel_bytes);
    }
    uint64_t stored, resident;
    sts_budget_measure(&srv, &stored, &resident);
    assert_true(resident >= H + 2 * R + 2 * h->texel_bytes);
    assert_true(resident <= H + 4 * R);
    (void)sum;
    st_native_meter_close(&mt);
    st_registry_free(srv.reg);
    st_set_free(h);
    assert_int_equal(st_test_rmtree(dir), 0);
}

/* With the budget thread started, a pass between full passes takes resident from statm (the
 * process's mapped file pages): pages mapped since the last pass count at once, even for sets
 * no sample stamped (the per-set measure would not look at those until the next full pass). */
static void test_pass_between_full_passes_counts_what_statm_sees(void **st)
{
    (void)st;
    st_native_meter mt;
    if (st_native_meter_open(&mt) != ST_NATIVE_COUNT_MAPPED) {
        printf("# /proc/self/pagemap cannot be read here: skipped\n");
        skip();
    }
    char dir[512], path[700];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "budgetstatm"), 0);
    static sts_server srv;
    memset(&srv, 0, sizeof srv);
    srv.reg = st_registry_create();
    assert_non_null(srv.reg);
    st_set *h = st_fixture_rgba8_faces(512);   /* 5.3 MB a set: statm's counters are exact to
                                                * a few dozen pages */
    assert_non_null(h);
    st_error e;
    st_set *m[4];
    for (int k = 0; k < 4; k++) {
        snprintf(path, sizeof path, "%s/s%d.native", dir, k);
        assert_int_equal(st_native_write(path, h, NULL, &e), 0);
        assert_int_equal(st_native_open(path, 0, NULL, &m[k], &e), 0);
        char name[16];
        snprintf(name, sizeof name, "s%d", k);
        assert_int_equal(st_registry_put(srv.reg, name, m[k], NULL, 0, NULL, &e), 0);
    }
    uint64_t R = m[0]->map_len, budget = (5 * R / 2) * 10 / 9 + 1;
    assert_int_equal(sts_budget_start(&srv), 0);   /* memory_budget 0: the thread idles */
    uint64_t now = (uint64_t)sts_now_ms();
    for (int k = 0; k < 4; k++)
        m[k]->last_use_ms = now - 4000 + (uint64_t)k * 10;   /* set 3 sampled last */
    sts_budget_pass(&srv, budget);   /* the first is a full pass: it measures every set */
    assert_int_equal(srv.budget.releases, 0);
    /* every page read without a sample: no stamp after the last measure */
    volatile uint8_t sum = 0;
    for (int k = 0; k < 4; k++)
        for (size_t i = 0; i < m[k]->map_len; i += 4096)
            sum += ((const uint8_t *)m[k]->map)[i];
    (void)sum;
    uint64_t stored, resident;
    sts_budget_measure(&srv, &stored, &resident);   /* STATS: the same estimate */
    assert_true(resident > 3 * R + R / 2);
    assert_true(resident < 4 * R + R / 2);
    sts_budget_pass(&srv, budget);
    assert_int_equal(srv.budget.releases, 2);
    for (int k = 0; k < 4; k++) {
        assert_int_equal(m[k]->cold, k < 2);
        assert_int_equal(st_native_resident(m[k], &mt), k < 2 ? 0 : R);
    }
    sts_budget_measure(&srv, &stored, &resident);
    assert_true(resident > 3 * R / 2);
    assert_true(resident < 5 * R / 2);
    sts_budget_stop(&srv);
    st_native_meter_close(&mt);
    st_registry_free(srv.reg);
    st_set_free(h);
    assert_int_equal(st_test_rmtree(dir), 0);
}

/* A small atlas set (a 64 x 48 RGBA8 image, a quad folded at its diagonal into two charts). */
static st_set *small_atlas(void)
{
    st_mesh *msh = st_fixture_folded_quad();
    assert_non_null(msh);
    st_error e;
    st_image img = {.w = 64, .h = 48, .nchan = 4, .dtype = ST_DT_U8, .alpha_chan = -1};
    img.data = malloc(64 * 48 * 4);
    for (int i = 0; i < 64 * 48 * 4; i++)
        ((uint8_t *)img.data)[i] = (uint8_t)(i * 13 + i / 97);
    st_set *s = NULL;
    assert_int_equal(st_atlas_from_image(&img, msh, 0, &s, &e), 0);
    free(img.data);
    return s;
}

/* An atlas set mapped from its native file: resident counts its pages and what it holds on the
 * heap (mesh, mask, and its chart data once a chart-mode sample built it); a release drops the
 * chart data with the pages, unless a sampler has it pinned, and the next chart sample
 * rebuilds it with the same outputs. */
static void test_atlas_chart_data_counted_and_released(void **st)
{
    (void)st;
    st_native_meter mt;
    if (st_native_meter_open(&mt) != ST_NATIVE_COUNT_MAPPED) {
        printf("# /proc/self/pagemap cannot be read here: skipped\n");
        skip();
    }
    char dir[512], path[700];
    assert_int_equal(st_test_mkdtemp(dir, sizeof dir, "budgetatlas"), 0);
    snprintf(path, sizeof path, "%s/a.native", dir);
    static sts_server srv;
    memset(&srv, 0, sizeof srv);
    srv.reg = st_registry_create();
    assert_non_null(srv.reg);
    st_set *h = small_atlas(), *m = NULL;
    st_error e;
    assert_int_equal(st_native_write(path, h, NULL, &e), 0);
    assert_int_equal(st_native_open(path, 0, NULL, &m, &e), 0);
    assert_int_equal(st_registry_put(srv.reg, "atlas", m, NULL, 0, NULL, &e), 0);
    const st_atlas *ha = st_atlas_get(h);
    size_t built = ha->chart_id_bytes + ha->chart_link_bytes + ha->loc.bytes;
    assert_true(built > 0);
    /* opened: the heap holds the mesh and the mask, no chart data, and resident counts them */
    assert_int_equal(st_atlas_charts_built_bytes(m), 0);
    size_t heap0 = st_set_heap_memory(m);
    assert_true(heap0 > 0);
    uint64_t now = (uint64_t)sts_now_ms();
    assert_int_equal(sts_budget_set_resident(m, &mt, now, 1), st_native_resident(m, &mt) + heap0);

    enum { N = 256 };
    st_query q[N];
    for (int i = 0; i < N; i++)
        q[i] = (st_query){.u = (float)(i % 16) / 16 + 0.01f, .v = (float)(i / 16) / 16 + 0.02f,
                          .dudx = 0.02f, .dvdy = 0.02f};
    static float ref[N * 4], out[N * 4];
    st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_TRILINEAR};
    assert_true(st_sample_batch(h, &o, q, N, ref, NULL, NULL) >= 0);
    assert_true(st_sample_batch(m, &o, q, N, out, NULL, NULL) >= 0);
    assert_memory_equal(out, ref, sizeof out);
    assert_int_equal(st_atlas_charts_built_bytes(m), built);
    assert_int_equal(st_set_heap_memory(m), heap0 + built);
    uint64_t R = st_native_resident(m, &mt);
    assert_true(R > 0);
    assert_int_equal(sts_budget_set_resident(m, &mt, now + 1, 1), R + heap0 + built);
    uint64_t stored, resident;
    sts_budget_measure(&srv, &stored, &resident);
    assert_int_equal(stored, st_set_memory(m));
    assert_true(resident >= heap0 + built);

    /* a budget under the set: the pass releases it whole, the chart data with the pages */
    m->last_use_ms = now;
    sts_budget_pass(&srv, 4096);
    assert_int_equal(srv.budget.releases, 1);
    assert_int_equal(srv.budget.released_bytes, R + built);
    assert_int_equal(m->cold, 1);
    assert_int_equal(st_atlas_charts_built_bytes(m), 0);
    assert_int_equal(st_set_heap_memory(m), heap0);
    /* the next chart sample rebuilds it: the same outputs */
    memset(out, 0, sizeof out);
    assert_true(st_sample_batch(m, &o, q, N, out, NULL, NULL) >= 0);
    assert_memory_equal(out, ref, sizeof out);
    assert_int_equal(st_atlas_charts_built_bytes(m), built);

    /* a sampler holding the data while a release runs keeps it: only the pages go */
    assert_int_equal(st_atlas_charts_pin(m, &e), ST_OK);
    m->last_use_ms = (uint64_t)sts_now_ms();
    uint64_t before = srv.budget.released_bytes;
    sts_budget_pass(&srv, 4096);
    assert_int_equal(srv.budget.releases, 2);
    assert_int_equal(st_atlas_charts_built_bytes(m), built);
    assert_true(srv.budget.released_bytes - before < built + R + 1);
    assert_int_equal(st_native_resident(m, &mt), 0);
    st_atlas_charts_unpin(m);
    assert_true(st_sample_batch(m, &o, q, N, out, NULL, NULL) >= 0);
    assert_memory_equal(out, ref, sizeof out);

    st_native_meter_close(&mt);
    st_registry_free(srv.reg);
    st_set_free(h);
    assert_int_equal(st_test_rmtree(dir), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_releases_past_the_high_mark_not_only_past_the_budget),
        cmocka_unit_test(test_goal_is_under_the_high_mark),
        cmocka_unit_test(test_unlimited_budget_never_releases),
        cmocka_unit_test(test_resident_measured_again_only_for_sampled_sets),
        cmocka_unit_test(test_pass_releases_the_least_recently_sampled_sets_whole),
        cmocka_unit_test(test_pass_between_full_passes_counts_what_statm_sees),
        cmocka_unit_test(test_atlas_chart_data_counted_and_released),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
