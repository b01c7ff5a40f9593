/* tests/unit/test_budget_rule.c - the memory budget's release rule (server/budget.c,
 * sts_budget_plan): a pass releases past 95% of the budget, down to 90%, so that pages faulted
 * in between two ticks stay under the budget; an unlimited budget never releases.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "budget.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_releases_past_the_high_mark_not_only_past_the_budget),
        cmocka_unit_test(test_goal_is_under_the_high_mark),
        cmocka_unit_test(test_unlimited_budget_never_releases),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
