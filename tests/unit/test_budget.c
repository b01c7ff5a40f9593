/* tests/unit/test_budget.c - the memory budget's rules (server/budget.c):
 *   - the release rule (sts_budget_plan): a pass releases past 95% of the budget, down to 90%,
 *     so that pages faulted in between two ticks stay under the budget; an unlimited budget
 *     never releases;
 *   - the resident measure (sts_budget_set_resident): a mapped set's pages are counted again
 *     (mincore) only when it was sampled since its last measure or in a full pass; otherwise
 *     its last figure stands (a tick must not cost a mincore pass over every mapping).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "budget.h"
#include "native.h"
#include "server.h"
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
    uint64_t t = (uint64_t)sts_now_ms();
    uint64_t full = sts_budget_set_resident(m, t, 1);
    assert_true(full >= m->texel_bytes);
    st_native_release(m);
    uint64_t after = st_native_resident(m);
    if (after >= full) {   /* a file system whose page cache ignores POSIX_FADV_DONTNEED */
        st_set_free(m);
        st_set_free(h);
        st_test_rmtree(dir);
        skip();
    }
    /* not sampled since the last measure: the last figure stands */
    assert_int_equal(sts_budget_set_resident(m, t + 1, 0), full);
    /* a sample stamps the set (sts_budget_touch): the next measure counts its pages again */
    static sts_server srv;   /* no budget thread: touch only stamps a set that is not cold */
    assert_int_equal(sts_budget_touch(&srv, m), 0);
    uint64_t stamp = m->last_use_ms;
    assert_true(stamp >= t);
    uint64_t fresh = sts_budget_set_resident(m, stamp + 10, 0);
    assert_true(fresh < full);
    assert_int_equal(fresh, st_native_resident(m));
    /* pages faulted in without a sample are caught by the next full pass */
    for (size_t i = 0; i < m->texel_bytes; i += 4096)
        sum += m->texels[i];
    uint64_t t2 = stamp + 20;
    assert_int_equal(sts_budget_set_resident(m, t2, 0), fresh);
    assert_true(sts_budget_set_resident(m, t2, 1) >= m->texel_bytes);
    st_set_free(m);
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
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
