/* tests/common/benchstat.h - the clocks and order statistics of the benchmarks in tests/bench/.
 *
 * Owns: reading a clock in seconds, the comparison of doubles for qsort, the median and the
 * nearest-rank percentile of a sample, and the "[--json PATH] [--reps N]" command line of the
 * benchmarks that take only those. Does not own: what is timed, nor the JSON the
 * benchmarks write. The client's load tester (client/bench*.c) keeps its own nanosecond clock
 * and histograms: client/ does not link the test helpers.
 */
#ifndef ST_TEST_BENCHSTAT_H
#define ST_TEST_BENCHSTAT_H

#include <time.h>

/* Clock c (CLOCK_MONOTONIC, CLOCK_THREAD_CPUTIME_ID, ...) in seconds. */
double st_bench_clock(clockid_t c);

/* CLOCK_MONOTONIC in seconds. */
double st_bench_now(void);

/* qsort comparison of two doubles, ascending. */
int st_bench_cmp_double(const void *a, const void *b);

/* The median of v[0..n-1] (n >= 1; the mean of the middle two when n is even). Sorts v. */
double st_bench_median(double *v, int n);

/* The nearest-rank p-quantile (0 < p <= 1) of v[0..n-1] (n >= 1). Sorts v. */
double st_bench_pct(double *v, int n, double p);

/* Reads "[--json PATH] [--reps N]" from argv: *json (NULL when not given) and *reps
 * (reps_default when not given or outside 1..101). Anything else: the usage on stderr and -1. */
int st_bench_args(int argc, char **argv, const char **json, int *reps, int reps_default);

#endif
