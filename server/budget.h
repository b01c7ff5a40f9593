/* server/budget.h - the memory budget (budget.c): resident texture memory bounded by releasing
 * the least recently sampled sets, and its STATS figures. */
#ifndef STS_BUDGET_H
#define STS_BUDGET_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include "native.h"
#include "proto.h"
#include "set.h"

#define STS_COLD_HIST 12   /* first-sample latency buckets (budget.c: <= 50 us .. > 100 ms) */

typedef struct sts_budget {
    pthread_t       thread;
    pthread_mutex_t mu;
    pthread_cond_t  cv;
    int             started, stop, kick;
    long            majflt0;         /* ru_majflt at start */
    pthread_mutex_t pass_mu;         /* held by a pass: the thread's, or a sample's (touch) */
    uint64_t        full_ms;         /* under pass_mu: the last pass over every mapping */
    uint64_t        pass_ms;         /* under pass_mu: the last pass */
    int             statm_fd;        /* /proc/self/statm, -1 when closed (started only) */
    int             base_ok;         /* atomic: base_pages and other_bytes are set */
    int64_t         base_pages;      /* atomic: statm's file pages that are not the sets'
                                      * (executable, libraries) at the last measured pass */
    uint64_t        other_bytes;     /* atomic: heap sets + mapped sets' heap bytes
                                        then, less drops since */
    uint64_t        look_ms;         /* atomic: the last look at the estimate (touch) */
    uint64_t        resident;        /* atomic: last measured by the thread */
    uint64_t        releases;        /* atomic: sets released */
    uint64_t        released_bytes;  /* atomic: resident bytes those releases let go */
    uint64_t        cold_batches;    /* atomic: SAMPLE batches that woke a released set */
    uint64_t        cold_queries;    /* atomic: the queries of those batches */
    uint64_t        cold_hist[STS_COLD_HIST];  /* atomic: their sampling latency */
    uint64_t        cold_sum_us;     /* atomic: those latencies added up */
} sts_budget;

struct sts_server;

int sts_budget_start(struct sts_server *srv);
void sts_budget_stop(struct sts_server *srv);
/* A sample to s: marks it hot now; returns 1 when it had been released (a cold set). At most
 * every 2 ms one sampling thread also looks at the resident estimate (one read of
 * /proc/self/statm) and runs a pass itself when it is past the high mark (budget.c, look). */
int sts_budget_touch(struct sts_server *srv, st_set *s);
/* A cold set's first batch, sampled since t0_us (sts_now_us). */
void sts_budget_cold_done(struct sts_server *srv, int64_t t0_us, uint32_t nqueries);
/* The release rule of one budget pass, with `total` resident bytes under `budget`: returns 1
 * when the pass must release sets - resident past the high mark, 95% of the budget, so that
 * what samples fault in before the next tick (50 ms) stays under the budget - and sets *goal to
 * the low mark it releases down to (90%). A budget of 0 (unlimited) never releases. */
int sts_budget_plan(uint64_t total, uint64_t budget, uint64_t *goal);
/* Resident bytes of s as the budget counts them (its mapped pages as the meter counts them,
 * native.h, + what it holds on the heap, st_set_heap_memory: a built Ptex table, an atlas's
 * mesh, mask and built chart data; or the whole heap set). The figure of a mapping is taken again
 * only when `full` or when s was sampled (last_use_ms) since the last one; otherwise the last
 * figure is reused: pages of a set nobody samples can only leave, so it stays an upper bound
 * until the next full pass. now_ms is the monotonic clock in ms (sts_now_ms). */
uint64_t sts_budget_set_resident(st_set *s, const st_native_meter *m, uint64_t now_ms,
                                 int full);
/* One budget pass (the budget thread runs one every tick, a sample one when the estimate is
 * past the high mark, each under pass_mu; tests call it directly): measures
 * resident - every mapping in a full pass (every 5 s) and whenever the estimate cannot be
 * made (sts_budget_set_resident), else the statm estimate (one read) - and, when
 * sts_budget_plan says so, releases the least recently sampled mapped sets, whole, until
 * under the low mark, marking each cold. Updates the resident figure and the counters. */
void sts_budget_pass(struct sts_server *srv, uint64_t budget);
/* Stored and resident texture bytes of every set now (STATS): resident is the statm estimate
 * while the budget thread runs and has made a measured pass, else measured set by set. */
void sts_budget_measure(struct sts_server *srv, uint64_t *stored, uint64_t *resident);
/* The first-sample histogram now: counts[k] batches took at most bound_us[k] microseconds
 * and more than bound_us[k - 1] (the last bound is UINT32_MAX: no bound); *sum_us their sum.
 * STATS and /metrics both read it through here. */
void sts_budget_hist(struct sts_server *srv, uint64_t counts[STS_COLD_HIST],
                     uint32_t bound_us[STS_COLD_HIST], uint64_t *sum_us);
/* Appends the budget's STATS entries; returns how many. */
size_t sts_budget_stats(struct sts_server *srv, stp_stat *s, size_t cap);

#endif
