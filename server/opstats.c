/* server/opstats.c - per-opcode request, error and latency counters (opstats.h).
 *
 * Owns: recording a reply (bucket by latency, error by status) and turning the counters into
 * STATS entries. Does not own: where replies are made (dispatch.c inline, workers.c for heavy
 * requests call sts_opstats_record), the STATS request itself (h_basic.c).
 *
 * The request count of an opcode is the sum of its buckets (no separate counter), so the
 * histogram always adds up to it; p50 / p99 are the upper bound of the bucket that holds that
 * rank (an over-estimate by at most 2x, which is what power-of-two buckets can say).
 */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "opstats.h"
#include "server.h"


static unsigned bucket_of(int64_t us)
{
    if (us <= 0)
        return 0;
    unsigned b = 64u - (unsigned)__builtin_clzll((unsigned long long)us);  /* bit length */
    return b < STS_LAT_BUCKETS ? b : STS_LAT_BUCKETS - 1;
}

void sts_opstats_record(sts_opstats *s, unsigned opcode, int64_t start_us, const stp_buf *out,
                        size_t avail_before)
{
    sts_opstat *o = &s->op[opcode & 0xFF];
    int64_t us = sts_now_us() - start_us;
    __atomic_add_fetch(&o->lat[bucket_of(us)], 1, __ATOMIC_RELAXED);
    __atomic_add_fetch(&o->sum_us, (uint64_t)(us > 0 ? us : 0), __ATOMIC_RELAXED);
    size_t avail = stp_buf_avail(out);
    size_t added = avail > avail_before ? avail - avail_before : 0;
    if (added >= STP_HEADER_SIZE &&                 /* status at offset 12 of the frame */
        stp_rd16(out->data + out->len - added + 12) != STP_S_OK)
        __atomic_add_fetch(&o->errors, 1, __ATOMIC_RELAXED);
}

/* Lower and upper bounds (us) of bucket b; the last bucket has no upper bound. */
static uint64_t bucket_lo(unsigned b)
{
    return b == 0 ? 0 : (uint64_t)1 << (b - 1);
}

static uint64_t bucket_hi(unsigned b)
{
    return (uint64_t)1 << b;
}

uint64_t sts_opstats_bucket_hi_us(unsigned b)
{
    return bucket_hi(b);
}

uint64_t sts_opstats_read(const sts_opstats *s, unsigned opcode, uint64_t *lat,
                          uint64_t *errors, uint64_t *sum_us)
{
    const sts_opstat *o = &s->op[opcode & 0xFF];
    uint64_t total = 0;
    /* errors first: record adds an error after its bucket, so reading the buckets last shows
     * no more errors than requests (on x86, whose stores are seen in order) */
    *errors = __atomic_load_n(&o->errors, __ATOMIC_RELAXED);
    *sum_us = __atomic_load_n(&o->sum_us, __ATOMIC_RELAXED);
    for (unsigned b = 0; b < STS_LAT_BUCKETS; b++) {
        lat[b] = __atomic_load_n(&o->lat[b], __ATOMIC_RELAXED);
        total += lat[b];
    }
    return total;
}

/* The upper bound of the bucket holding the request of rank ceil(q * n) (1-based). */
static uint64_t quantile_us(const uint64_t *lat, uint64_t n, double q)
{
    uint64_t rank = (uint64_t)((double)n * q);
    if ((double)rank < (double)n * q)
        rank++;
    if (rank == 0)
        rank = 1;
    uint64_t seen = 0;
    for (unsigned b = 0; b < STS_LAT_BUCKETS; b++) {
        seen += lat[b];
        if (seen >= rank)
            return b == STS_LAT_BUCKETS - 1 ? bucket_lo(b) : bucket_hi(b);
    }
    return bucket_lo(STS_LAT_BUCKETS - 1);
}

size_t sts_opstats_max_keys(void)
{
    size_t named = 0;
    for (unsigned op = 0; op < 256; op++)
        named += stp_opcode_name(op) != NULL;
    return named * (5 + STS_LAT_BUCKETS);
}

static void put(stp_stat *out, size_t cap, size_t *n, const char *key, uint64_t v)
{
    if (*n >= cap)
        return;
    stp_stat *s = &out[(*n)++];
    snprintf(s->key, sizeof s->key, "%s", key);
    s->type = STP_STAT_U64;
    s->v.u = v;
}

size_t sts_opstats_report(const sts_opstats *s, stp_stat *out, size_t cap)
{
    size_t n = 0;
    for (unsigned op = 0; op < 256; op++) {
        const char *name = stp_opcode_name(op);
        if (!name)
            continue;
        char lower[32], key[STP_MAX_STAT_KEY + 1];
        snprintf(lower, sizeof lower, "%s", name);
        for (char *p = lower; *p; p++)
            if (*p >= 'A' && *p <= 'Z')
                *p = (char)(*p - 'A' + 'a');
        uint64_t lat[STS_LAT_BUCKETS], errors, sum_us;
        uint64_t total = sts_opstats_read(s, op, lat, &errors, &sum_us);
        snprintf(key, sizeof key, "op_%s_requests", lower);
        put(out, cap, &n, key, total);
        snprintf(key, sizeof key, "op_%s_errors", lower);
        put(out, cap, &n, key, errors);
        if (!total)
            continue;
        snprintf(key, sizeof key, "op_%s_p50_us", lower);
        put(out, cap, &n, key, quantile_us(lat, total, 0.50));
        snprintf(key, sizeof key, "op_%s_p99_us", lower);
        put(out, cap, &n, key, quantile_us(lat, total, 0.99));
        snprintf(key, sizeof key, "op_%s_sum_us", lower);
        put(out, cap, &n, key, sum_us);
        for (unsigned b = 0; b < STS_LAT_BUCKETS; b++) {
            if (!lat[b])
                continue;
            if (b == STS_LAT_BUCKETS - 1)
                snprintf(key, sizeof key, "op_%s_lat_over_%lluus", lower,
                         (unsigned long long)bucket_lo(b));
            else
                snprintf(key, sizeof key, "op_%s_lat_%llu_%lluus", lower,
                         (unsigned long long)bucket_lo(b), (unsigned long long)bucket_hi(b));
            put(out, cap, &n, key, lat[b]);
        }
    }
    return n;
}
