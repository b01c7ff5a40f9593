/* tests/unit/test_hist.c - the load tester's latency histogram (client/hist.c) and its
 * open-loop arrival schedules (client/bench_sched.c).
 *
 * Both sources belong to seamtex-bench, not to a library, so they are compiled into this test
 * directly (#include of the .c files below).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <cmocka.h>

#include "../../client/hist.c"
#include "../../client/bench_sched.c"

static stc_hist *new_hist(void)
{
    stc_hist *h = malloc(sizeof *h);
    assert_non_null(h);
    stc_hist_reset(h);
    return h;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Exact percentile of sorted values with the same rank rule as the histogram. */
static uint64_t exact_pct(const uint64_t *v, size_t n, double p)
{
    double r = p / 100.0 * (double)n;
    size_t rank = (size_t)r;
    if ((double)rank < r)
        rank++;
    if (rank == 0)
        rank = 1;
    return v[rank - 1];
}

static void buckets_cover_every_value_once_in_order(void **state)
{
    (void)state;
    uint64_t prev_hi = 0;
    for (unsigned i = 0; i < STC_HIST_BUCKETS; i++) {
        uint64_t lo, hi;
        stc_hist_bucket_range(i, &lo, &hi);
        if (i > 0)
            assert_int_equal(lo, prev_hi + 1);      /* contiguous, no gap, no overlap */
        assert_true(hi >= lo);
        assert_int_equal(stc_hist_index(lo), i);
        if (i + 1 < STC_HIST_BUCKETS)
            assert_int_equal(stc_hist_index(hi), i);
        /* width at most 1/128 of the value */
        if (i + 1 < STC_HIST_BUCKETS && lo >= 256)
            assert_true((double)(hi - lo + 1) <= (double)lo / 128.0 + 1e-9);
        prev_hi = hi;
    }
    assert_int_equal(stc_hist_index(UINT64_MAX), STC_HIST_BUCKETS - 1);
}

static void small_values_are_exact(void **state)
{
    (void)state;
    stc_hist *h = new_hist();
    for (uint64_t v = 1; v <= 100; v++)
        stc_hist_record(h, v);
    assert_int_equal(h->count, 100);
    assert_int_equal(stc_hist_percentile(h, 50), 50);
    assert_int_equal(stc_hist_percentile(h, 99), 99);
    assert_int_equal(stc_hist_percentile(h, 100), 100);
    assert_int_equal(stc_hist_percentile(h, 0), 1);
    assert_true(fabs(stc_hist_mean(h) - 50.5) < 1e-9);
    free(h);
}

static void empty_histogram_reports_zero(void **state)
{
    (void)state;
    stc_hist *h = new_hist();
    assert_int_equal(stc_hist_percentile(h, 50), 0);
    assert_int_equal(stc_hist_percentile(h, 100), 0);
    assert_true(stc_hist_mean(h) == 0.0);
    free(h);
}

/* Uniform and exponential samples: every percentile within 0.8% of the exact one. */
static void percentiles_match_sorted_samples_within_one_percent(void **state)
{
    (void)state;
    const size_t n = 200000;
    uint64_t *v = malloc(n * sizeof *v);
    assert_non_null(v);
    const double ps[] = { 50, 90, 99, 99.9, 99.99 };
    for (int dist = 0; dist < 2; dist++) {
        stc_hist *h = new_hist();
        uint64_t rng = stc_rng_seed(42 + dist);
        for (size_t i = 0; i < n; i++) {
            double u = stc_rng_unit(&rng);
            /* uniform 10 us .. 1 ms, or exponential of mean 200 us (+ 20 us floor) */
            double x = dist == 0 ? 1e4 + u * (1e6 - 1e4) : 2e4 - 2e5 * log1p(-u);
            v[i] = (uint64_t)x;
            stc_hist_record(h, v[i]);
        }
        qsort(v, n, sizeof *v, cmp_u64);
        for (size_t k = 0; k < sizeof ps / sizeof ps[0]; k++) {
            uint64_t want = exact_pct(v, n, ps[k]);
            uint64_t got = stc_hist_percentile(h, ps[k]);
            assert_true(got >= want);                         /* upper edge of the bucket */
            assert_true((double)(got - want) <= 0.008 * (double)want);
        }
        assert_int_equal(stc_hist_percentile(h, 100), v[n - 1]);
        assert_int_equal(h->min, v[0]);
        free(h);
    }
    free(v);
}

static void merge_equals_recording_everything_in_one(void **state)
{
    (void)state;
    stc_hist *a = new_hist(), *b = new_hist(), *all = new_hist();
    uint64_t rng = stc_rng_seed(7);
    for (int i = 0; i < 50000; i++) {
        uint64_t x = 1000 + stc_rng_next(&rng) % 5000000;
        stc_hist_record(i & 1 ? a : b, x);
        stc_hist_record(all, x);
    }
    stc_hist_merge(a, b);
    assert_int_equal(a->count, all->count);
    assert_int_equal(a->min, all->min);
    assert_int_equal(a->max, all->max);
    const double ps[] = { 50, 90, 99, 99.9, 99.99, 100 };
    for (size_t k = 0; k < sizeof ps / sizeof ps[0]; k++)
        assert_int_equal(stc_hist_percentile(a, ps[k]), stc_hist_percentile(all, ps[k]));
    free(a);
    free(b);
    free(all);
}

static void huge_values_land_in_top_bucket_but_max_is_exact(void **state)
{
    (void)state;
    stc_hist *h = new_hist();
    stc_hist_record(h, 5);
    stc_hist_record(h, (uint64_t)1 << 50);
    assert_int_equal(h->b[STC_HIST_BUCKETS - 1], 1);
    assert_int_equal(stc_hist_percentile(h, 100), (uint64_t)1 << 50);
    assert_int_equal(stc_hist_percentile(h, 99.99), (uint64_t)1 << 50);
    assert_int_equal(stc_hist_percentile(h, 50), 5);
    free(h);
}

static void uniform_schedule_is_evenly_spaced_and_staggered(void **state)
{
    (void)state;
    stc_sched s;
    stc_sched_init(&s, STC_ARRIVAL_UNIFORM, 1000.0, 1000000, 0.5, 1);
    assert_int_equal(stc_sched_peek(&s), 1000000 + 500000);
    uint64_t t0 = stc_sched_next(&s);
    assert_int_equal(t0, 1500000);
    uint64_t last = t0;
    for (int i = 1; i <= 10000; i++)
        last = stc_sched_next(&s);
    /* 10000 intervals of 1 ms, no accumulated drift */
    assert_int_equal(last - t0, 10000ull * 1000000ull);
}

static void poisson_schedule_has_the_right_rate_and_spread(void **state)
{
    (void)state;
    stc_sched s;
    const double rate = 50000.0;
    const int n = 200000;
    stc_sched_init(&s, STC_ARRIVAL_POISSON, rate, 0, 0.0, 99);
    uint64_t prev = stc_sched_next(&s), first = prev;
    double sum = 0, sum2 = 0;
    int below_mean = 0;
    for (int i = 0; i < n; i++) {
        uint64_t t = stc_sched_next(&s);
        assert_true(t >= prev);
        double g = (double)(t - prev);
        sum += g;
        sum2 += g * g;
        if (g < 1e9 / rate)
            below_mean++;
        prev = t;
    }
    double mean = sum / n, sd = sqrt(sum2 / n - mean * mean);
    double achieved = (double)n / ((double)(prev - first) / 1e9);
    assert_true(fabs(achieved - rate) / rate < 0.01);
    /* exponential: standard deviation equals the mean, P(gap < mean) = 1 - 1/e */
    assert_true(fabs(sd - mean) / mean < 0.02);
    assert_true(fabs((double)below_mean / n - (1.0 - exp(-1.0))) < 0.01);
}

static void same_seed_gives_the_same_schedule(void **state)
{
    (void)state;
    stc_sched a, b, c;
    stc_sched_init(&a, STC_ARRIVAL_POISSON, 1000.0, 0, 0.0, 5);
    stc_sched_init(&b, STC_ARRIVAL_POISSON, 1000.0, 0, 0.0, 5);
    stc_sched_init(&c, STC_ARRIVAL_POISSON, 1000.0, 0, 0.0, 6);
    int differ = 0;
    for (int i = 0; i < 100; i++) {
        uint64_t x = stc_sched_next(&a), y = stc_sched_next(&b), z = stc_sched_next(&c);
        assert_int_equal(x, y);
        differ += x != z;
    }
    assert_true(differ > 90);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(buckets_cover_every_value_once_in_order),
        cmocka_unit_test(small_values_are_exact),
        cmocka_unit_test(empty_histogram_reports_zero),
        cmocka_unit_test(percentiles_match_sorted_samples_within_one_percent),
        cmocka_unit_test(merge_equals_recording_everything_in_one),
        cmocka_unit_test(huge_values_land_in_top_bucket_but_max_is_exact),
        cmocka_unit_test(uniform_schedule_is_evenly_spaced_and_staggered),
        cmocka_unit_test(poisson_schedule_has_the_right_rate_and_spread),
        cmocka_unit_test(same_seed_gives_the_same_schedule),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
