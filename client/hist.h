/* client/hist.h - a small log-linear latency histogram for seamtex-bench (HdrHistogram_c is
 * not packaged in Debian, so this is our own, much smaller one).
 *
 * Owns: recording values (nanoseconds), merging histograms of several threads, percentiles.
 * Does not own: clocks, threads, output formatting (bench_main.c).
 *
 * Buckets: values below 2^STC_HIST_SUB_BITS are counted exactly; above, every power of two
 * [2^m, 2^(m+1)) is cut into 2^(STC_HIST_SUB_BITS-1) equal sub-buckets, so a bucket is at
 * most 1/128 of its value wide (relative error of a reported percentile below 0.8%). The
 * range ends at 2^STC_HIST_MAX_LOG2 ns (about 137 s); larger values land in the last
 * bucket, while the exact maximum is kept beside the buckets.
 *
 * Memory: one histogram is a fixed struct of ~30 KiB, no allocation; the caller owns it
 * (stack, array or heap). Not thread-safe: one histogram per thread, merged at the end.
 */
#ifndef STC_HIST_H
#define STC_HIST_H

#include <stdint.h>

#define STC_HIST_SUB_BITS  8
#define STC_HIST_MAX_LOG2  37
#define STC_HIST_HALF      (1u << (STC_HIST_SUB_BITS - 1))
#define STC_HIST_BUCKETS   ((1u << STC_HIST_SUB_BITS) + \
                            (STC_HIST_MAX_LOG2 - STC_HIST_SUB_BITS) * STC_HIST_HALF)

typedef struct stc_hist {
    uint64_t count;        /* values recorded */
    uint64_t min, max;     /* exact extremes (min is UINT64_MAX while count is 0) */
    double   sum;          /* for the mean */
    uint64_t b[STC_HIST_BUCKETS];
} stc_hist;

/* Empties h. */
void stc_hist_reset(stc_hist *h);

/* Records one value (nanoseconds, any uint64_t; beyond the range it counts in the top bucket). */
void stc_hist_record(stc_hist *h, uint64_t v);

/* Adds every count of src into dst. */
void stc_hist_merge(stc_hist *dst, const stc_hist *src);

/* The value at percentile p (0..100): the highest value that falls in the bucket holding the
 * ceil(p/100 * count)-th smallest value, clamped to [min, max]; p = 100 gives max exactly.
 * Returns 0 for an empty histogram. */
uint64_t stc_hist_percentile(const stc_hist *h, double p);

/* Mean of the recorded values (exact, from the running sum); 0 when empty. */
double stc_hist_mean(const stc_hist *h);

/* Bucket helpers, exposed for tests: index of a value, and the [lo, hi] values of a bucket. */
unsigned stc_hist_index(uint64_t v);
void stc_hist_bucket_range(unsigned idx, uint64_t *lo, uint64_t *hi);

#endif
