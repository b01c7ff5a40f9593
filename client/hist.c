/* client/hist.c - the log-linear latency histogram of hist.h.
 *
 * Owns: bucket indexing, merging and percentile lookup. Does not own: clocks or threads.
 *
 * Index of a value v:
 *   v < 2^S                    -> v                      (exact buckets, S = STC_HIST_SUB_BITS)
 *   2^m <= v < 2^(m+1), m >= S -> 2^S + (m - S) * H + ((v >> (m - S + 1)) - H)
 * where H = 2^(S-1): the top S bits of v, whose leading bit is always set, pick one of H
 * sub-buckets of the octave, each 2^(m-S+1) wide.
 */
#include "hist.h"

#include <string.h>

#define S  STC_HIST_SUB_BITS
#define H  STC_HIST_HALF

unsigned stc_hist_index(uint64_t v)
{
    if (v < (1u << S))
        return (unsigned)v;
    unsigned m = 63u - (unsigned)__builtin_clzll(v);
    if (m >= STC_HIST_MAX_LOG2)
        return STC_HIST_BUCKETS - 1;
    unsigned shift = m - S + 1;
    return (1u << S) + (m - S) * H + (unsigned)((v >> shift) - H);
}

void stc_hist_bucket_range(unsigned idx, uint64_t *lo, uint64_t *hi)
{
    if (idx >= STC_HIST_BUCKETS)
        idx = STC_HIST_BUCKETS - 1;
    if (idx < (1u << S)) {
        *lo = *hi = idx;
        return;
    }
    unsigned k = idx - (1u << S);
    unsigned m = S + k / H;                 /* octave [2^m, 2^(m+1)) */
    unsigned sub = k % H;
    unsigned shift = m - S + 1;
    *lo = ((uint64_t)(H + sub)) << shift;
    *hi = *lo + (((uint64_t)1) << shift) - 1;
    if (idx == STC_HIST_BUCKETS - 1)
        *hi = UINT64_MAX;                   /* the top bucket also takes everything above */
}

void stc_hist_reset(stc_hist *h)
{
    memset(h, 0, sizeof *h);
    h->min = UINT64_MAX;
}

void stc_hist_record(stc_hist *h, uint64_t v)
{
    h->b[stc_hist_index(v)]++;
    h->count++;
    h->sum += (double)v;
    if (v < h->min)
        h->min = v;
    if (v > h->max)
        h->max = v;
}

void stc_hist_merge(stc_hist *dst, const stc_hist *src)
{
    if (src->count == 0)
        return;
    for (unsigned i = 0; i < STC_HIST_BUCKETS; i++)
        dst->b[i] += src->b[i];
    dst->count += src->count;
    dst->sum += src->sum;
    if (src->min < dst->min)
        dst->min = src->min;
    if (src->max > dst->max)
        dst->max = src->max;
}

uint64_t stc_hist_percentile(const stc_hist *h, double p)
{
    if (h->count == 0)
        return 0;
    if (!(p < 100.0))                       /* also catches NaN: report the maximum */
        return h->max;
    if (p <= 0.0)
        return h->min;
    double r = p / 100.0 * (double)h->count;
    uint64_t rank = (uint64_t)r;
    if ((double)rank < r)
        rank++;                             /* ceil */
    if (rank == 0)
        rank = 1;
    uint64_t seen = 0;
    for (unsigned i = 0; i < STC_HIST_BUCKETS; i++) {
        seen += h->b[i];
        if (seen >= rank) {
            uint64_t lo, hi;
            stc_hist_bucket_range(i, &lo, &hi);
            (void)lo;
            if (hi > h->max)
                hi = h->max;
            if (hi < h->min)
                hi = h->min;
            return hi;
        }
    }
    return h->max;
}

double stc_hist_mean(const stc_hist *h)
{
    return h->count ? h->sum / (double)h->count : 0.0;
}
