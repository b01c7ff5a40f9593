/* server/budget.c - the memory budget: the texture memory seamtexd keeps resident while any
 * amount is stored (--memory-budget, docs/daemon.md "Memory budget").
 *
 * Owns: the budget thread, the cold/hot state of sets (st_set.last_use_ms, st_set.cold), the
 * STATS figures of stored and resident bytes, releases, major faults and the latency of first
 * samples to a cold set. Does not own: the mapping and its release (store/native/native.h),
 * the lazy Ptex tables (store/ptex/ptexres.h), an atlas's lazy chart data (store/kinds/atlas.h),
 * the registry.
 *
 * Resident texture memory = the pages of every mapped native file present in this process's
 * page tables (/proc/self/pagemap; where it cannot be read, the file's pages in the page cache
 * by mincore: store/native/native.h, st_native_meter) + what every mapped set holds on the
 * heap (st_set_heap_memory: a built lazy Ptex table, an atlas's mesh, chart mask and built
 * chart data, metadata) + every heap set (sets that have no native file: the built-in default
 * set, or a set whose native file could not be written; they cannot be released and are
 * counted as they are). A pass
 * (sts_budget_pass) runs every BUDGET_TICK_MS on the budget thread, at once when a sample wakes
 * a released set, and on a sampling thread when its look (every BUDGET_LOOK_MS, look()) finds
 * the estimate past the high mark. Every BUDGET_FULL_MS a pass measures every mapping
 * (pagemap) and keeps the base: /proc/self/statm's file pages that are not the sets'; between
 * full passes resident is estimated from statm (one read, whatever the number of sets), and the
 * sets are looked at only past the high mark (95% of the budget). Then the least recently
 * sampled mapped sets are released, whole (st_native_release: MADV_COLD + MADV_DONTNEED on the
 * mapping, the file stays in the page cache; the Ptex table and an atlas's chart data dropped,
 * rebuilt by the next sample that needs them), until resident is
 * under 90% of the budget (sts_budget_plan). A released set stays published: the next sample
 * faults in only the pages it touches, from the page cache while the kernel keeps them there
 * (the kernel, not the budget, decides when the page cache lets a file go; released pages are
 * the first it takes). A budget below one set's size still serves it: it is released at every
 * pass and faults back in. Without statm every pass measures the sets sampled since their last
 * measure (sts_budget_set_resident). (mincore over every mapping at every tick cost 53 ms of
 * CPU per pass at 8 GB stored: more than one core at a 50 ms tick.)
 *
 * Before 2026-12-02 a release also dropped the file from the page cache (posix_fadvise
 * DONTNEED), because mincore - the count then - counts the page cache: every fault after a
 * release read the disk (~430 us a page on this VM against ~1.7 us from the page cache), and
 * pages still dirty from writing the file could not be dropped at all, so the count stayed up
 * and a pass went on releasing more recently sampled sets (docs/native.md "Measured").
 */
#include "budget.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "atlas.h"
#include "native.h"
#include "ptexres.h"
#include "server.h"

#define BUDGET_TICK_MS 50
#define BUDGET_LOOK_MS 2      /* sts_budget_touch looks at the statm estimate this often */
#define BUDGET_FULL_MS 5000   /* a pass that measures every mapping (else only sampled sets) */

static const uint32_t hist_us[STS_COLD_HIST] = {50, 100, 200, 500, 1000, 2000, 5000, 10000,
                                                 20000, 50000, 100000, UINT32_MAX};

static long majflt_now(void)
{
    struct rusage ru;
    return getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_majflt : 0;
}

/* Pages of files mapped in this process now (RssFile + RssShmem: statm's third field, which
 * the kernel keeps as a counter, so one read costs the same at any mapping size); -1 when it
 * cannot be read. */
static int64_t file_pages_now(int fd)
{
    char buf[160];
    ssize_t n = fd >= 0 ? pread(fd, buf, sizeof buf - 1, 0) : -1;
    if (n <= 0)
        return -1;
    buf[n] = 0;
    unsigned long long size, res, shared;
    return sscanf(buf, "%llu %llu %llu", &size, &res, &shared) == 3 ? (int64_t)shared : -1;
}

uint64_t sts_budget_set_resident(st_set *s, const st_native_meter *m, uint64_t now_ms,
                                 int full)
{
    if (!s->map)
        return st_set_memory(s);
    uint64_t at = __atomic_load_n(&s->res_ms, __ATOMIC_RELAXED);
    uint64_t res = __atomic_load_n(&s->res_bytes, __ATOMIC_RELAXED);
    if (full || !at || __atomic_load_n(&s->last_use_ms, __ATOMIC_RELAXED) >= at) {
        res = st_native_resident(s, m);
        __atomic_store_n(&s->res_bytes, res, __ATOMIC_RELAXED);
        /* a sample stamped in this same ms counts as "since" (>=): measured again next tick */
        __atomic_store_n(&s->res_ms, now_ms ? now_ms : 1, __ATOMIC_RELAXED);
    }
    /* and what the set holds on the heap: a built Ptex table, an atlas's mesh, mask and
     * built chart data, metadata */
    return res + st_set_heap_memory(s);
}

typedef struct cand {
    st_setref *ref;
    uint64_t   res, last;
} cand;

static int cmp_last(const void *a, const void *b)
{
    const cand *x = a, *y = b;
    return x->last < y->last ? -1 : x->last > y->last;
}

/* Takes a snapshot of every set (the caller releases the refs and frees the array). */
static size_t snapshot(sts_server *srv, st_setref ***out)
{
    size_t cap = st_registry_count(srv->reg) + 16;
    st_setref **refs = malloc(cap * sizeof *refs);
    *out = refs;
    return refs ? st_registry_snapshot(srv->reg, refs, cap) : 0;
}

/* Resident now from statm: the process's mapped file pages less the base (what is not a set),
 * plus the heap sets and the mapped sets' heap bytes of the last measured pass; *ok = 0 when it
 * cannot be made (the budget thread not started, no measured pass yet, statm unreadable). */
static uint64_t estimate(sts_budget *b, int *ok)
{
    *ok = 0;
    if (!b->started || !__atomic_load_n(&b->base_ok, __ATOMIC_ACQUIRE))
        return 0;
    int64_t fp = file_pages_now(b->statm_fd);
    if (fp < 0)
        return 0;
    *ok = 1;
    int64_t pages = fp - __atomic_load_n(&b->base_pages, __ATOMIC_RELAXED);
    return (pages > 0 ? (uint64_t)pages * (uint64_t)sysconf(_SC_PAGESIZE) : 0) +
           __atomic_load_n(&b->other_bytes, __ATOMIC_RELAXED);
}

void sts_budget_measure(sts_server *srv, uint64_t *stored, uint64_t *resident)
{
    st_setref **refs;
    size_t n = snapshot(srv, &refs);
    int est = 0;
    uint64_t st = 0, res = estimate(&srv->budget, &est), now = (uint64_t)sts_now_ms();
    st_native_meter m = {-1};
    if (!est)
        st_native_meter_open(&m);
    for (size_t i = 0; i < n; i++) {
        st += st_set_memory(refs[i]->set);
        if (!est)
            res += sts_budget_set_resident(refs[i]->set, &m, now, 0);
        st_setref_release(refs[i]);
    }
    st_native_meter_close(&m);
    free(refs);
    *stored = st;
    *resident = res;
}

int sts_budget_plan(uint64_t total, uint64_t budget, uint64_t *goal)
{
    *goal = budget - budget / 10;
    return budget && total > budget - budget / 20;
}

void sts_budget_pass(sts_server *srv, uint64_t budget)
{
    sts_budget *b = &srv->budget;
    uint64_t now = (uint64_t)sts_now_ms(), goal;
    b->pass_ms = now;
    int full = now - b->full_ms >= BUDGET_FULL_MS;
    if (full)
        b->full_ms = now;
    /* between full passes, resident is the statm estimate: one read, whatever the number of
     * sets; the sets are looked at only when it is past the high mark */
    int est = 0;
    uint64_t total = full ? 0 : estimate(b, &est);
    if (est && !sts_budget_plan(total, budget, &goal)) {
        __atomic_store_n(&b->resident, total, __ATOMIC_RELAXED);
        return;
    }
    st_setref **refs;
    size_t n = snapshot(srv, &refs);
    cand *c = malloc((n ? n : 1) * sizeof *c);
    uint64_t mapped = 0, other_freed = 0;
    size_t nc = 0;
    st_native_meter m;
    st_native_meter_open(&m);
    for (size_t i = 0; i < n; i++) {
        st_set *s = refs[i]->set;
        uint64_t r;
        if (est) {
            /* released, or measured empty, and not sampled since: nothing of it to release
             * (a set never sampled is not worth a pagemap read and a cold mark) */
            uint64_t at = __atomic_load_n(&s->res_ms, __ATOMIC_RELAXED);
            r = !__atomic_load_n(&s->cold, __ATOMIC_RELAXED) &&
                !(at && !__atomic_load_n(&s->res_bytes, __ATOMIC_RELAXED) &&
                  __atomic_load_n(&s->last_use_ms, __ATOMIC_RELAXED) < at);
        } else {
            r = sts_budget_set_resident(s, &m, now, full);
            total += r;
            if (s->map) {
                uint64_t t = st_set_heap_memory(s);
                mapped += r > t ? r - t : 0;
            }
        }
        if (c && s->map)
            c[nc++] = (cand){refs[i], r, __atomic_load_n(&s->last_use_ms, __ATOMIC_RELAXED)};
    }
    __atomic_store_n(&b->resident, total, __ATOMIC_RELAXED);
    if (sts_budget_plan(total, budget, &goal) && c) {
        qsort(c, nc, sizeof *c, cmp_last);
        for (size_t i = 0; i < nc && total > goal; i++) {
            if (!c[i].res)
                continue;
            st_set *s = c[i].ref->set;
            size_t unmapped = st_native_release(s, &m);
            size_t freed = unmapped + st_ptexres_drop(s) + st_atlas_charts_drop(s);
            mapped -= unmapped < mapped ? unmapped : mapped;
            other_freed += freed - unmapped;
            __atomic_store_n(&s->cold, 1, __ATOMIC_RELAXED);
            __atomic_store_n(&s->res_bytes, 0, __ATOMIC_RELAXED);
            __atomic_store_n(&s->res_ms, 0, __ATOMIC_RELAXED);   /* measure it again */
            total -= freed < total ? freed : total;
            __atomic_add_fetch(&b->releases, 1, __ATOMIC_RELAXED);
            __atomic_add_fetch(&b->released_bytes, freed, __ATOMIC_RELAXED);
        }
        __atomic_store_n(&b->resident, total, __ATOMIC_RELAXED);
    }
    int64_t fp = b->started ? file_pages_now(b->statm_fd) : -1;
    if (est) {
        /* the releases left statm by themselves; the Ptex tables and atlas chart data
         * dropped leave the rest */
        uint64_t o = __atomic_load_n(&b->other_bytes, __ATOMIC_RELAXED);
        __atomic_store_n(&b->other_bytes, o > other_freed ? o - other_freed : 0,
                         __ATOMIC_RELAXED);
    } else if (fp >= 0 && st_native_meter_count(&m) == ST_NATIVE_COUNT_MAPPED) {
        /* what statm counts besides the sets (the executable, the libraries); the figures of
         * sets not sampled since their last measure are upper bounds, so the estimate errs
         * high until the next full pass */
        __atomic_store_n(&b->base_pages,
                         fp - (int64_t)(mapped / (uint64_t)sysconf(_SC_PAGESIZE)),
                         __ATOMIC_RELAXED);
        __atomic_store_n(&b->other_bytes, total > mapped ? total - mapped : 0,
                         __ATOMIC_RELAXED);
        __atomic_store_n(&b->base_ok, 1, __ATOMIC_RELEASE);
    }
    st_native_meter_close(&m);
    for (size_t i = 0; i < n; i++)
        st_setref_release(refs[i]);
    free(refs);
    free(c);
}

/* A pass every BUDGET_TICK_MS (and at once when a sample wakes a released set). Samples look
 * at the statm estimate themselves (sts_budget_touch), which does not wait for this thread to
 * be scheduled. */
static void *budget_main(void *arg)
{
    sts_server *srv = arg;
    sts_budget *b = &srv->budget;
    pthread_setname_np(pthread_self(), "st-budget");
    pthread_mutex_lock(&b->mu);
    while (!b->stop) {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        ts.tv_nsec += BUDGET_TICK_MS * 1000000L;
        if (ts.tv_nsec >= 1000000000L) {
            ts.tv_sec++;
            ts.tv_nsec -= 1000000000L;
        }
        if (!b->kick)
            pthread_cond_timedwait(&b->cv, &b->mu, &ts);
        b->kick = 0;
        if (b->stop)
            break;
        uint64_t budget = STS_LIVE(srv, memory_budget);
        if (!budget)
            continue;
        pthread_mutex_unlock(&b->mu);
        pthread_mutex_lock(&b->pass_mu);
        sts_budget_pass(srv, budget);
        pthread_mutex_unlock(&b->pass_mu);
        pthread_mutex_lock(&b->mu);
    }
    pthread_mutex_unlock(&b->mu);
    return NULL;
}

int sts_budget_start(sts_server *srv)
{
    sts_budget *b = &srv->budget;
    pthread_mutex_init(&b->mu, NULL);
    pthread_mutex_init(&b->pass_mu, NULL);
    pthread_cond_init(&b->cv, NULL);
    b->majflt0 = majflt_now();
    b->stop = 0;
    st_native_meter m;
    if (st_native_meter_open(&m) == ST_NATIVE_COUNT_CACHED)
        sts_logf(&srv->log, STS_WARN, "/proc/self/pagemap cannot be read: the memory budget "
                 "counts the native files' pages in the page cache (mincore) and a release "
                 "drops them from it, so a released set's next samples read the disk");
    st_native_meter_close(&m);
    b->statm_fd = open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
    b->base_ok = 0;
    b->started = 1;   /* before the thread: its passes read statm_fd only when started */
    if (pthread_create(&b->thread, NULL, budget_main, srv) != 0) {
        b->started = 0;
        if (b->statm_fd >= 0)
            close(b->statm_fd);
        b->statm_fd = -1;
        return -1;
    }
    return 0;
}

void sts_budget_stop(sts_server *srv)
{
    sts_budget *b = &srv->budget;
    if (!b->started)
        return;
    pthread_mutex_lock(&b->mu);
    b->stop = 1;
    pthread_cond_signal(&b->cv);
    pthread_mutex_unlock(&b->mu);
    pthread_join(b->thread, NULL);
    b->started = 0;
    if (b->statm_fd >= 0)
        close(b->statm_fd);
    b->statm_fd = -1;
}

/* At most every BUDGET_LOOK_MS (one sampling thread wins the stamp): the statm estimate, and a
 * pass on this thread when it is past the high mark and no other pass is running. A fault back
 * from the page cache takes microseconds, and at 100k-300k queries/s resident grew to three or
 * four times a 129 MB budget between passes of the budget thread, which at load 15-30 waited
 * 2-10 ms for a core at every wake-up (docs/native.md "Measured"). */
static void look(sts_server *srv, uint64_t now)
{
    sts_budget *b = &srv->budget;
    uint64_t budget, last = __atomic_load_n(&b->look_ms, __ATOMIC_RELAXED), goal;
    if (!b->started || !(budget = STS_LIVE(srv, memory_budget)) || now - last < BUDGET_LOOK_MS ||
        !__atomic_compare_exchange_n(&b->look_ms, &last, now, 0, __ATOMIC_RELAXED,
                                     __ATOMIC_RELAXED))
        return;
    int ok;
    uint64_t est = estimate(b, &ok);
    if (ok && sts_budget_plan(est, budget, &goal) && pthread_mutex_trylock(&b->pass_mu) == 0) {
        sts_budget_pass(srv, budget);
        pthread_mutex_unlock(&b->pass_mu);
    }
}

int sts_budget_touch(sts_server *srv, st_set *s)
{
    uint64_t now = (uint64_t)sts_now_ms();
    if (__atomic_load_n(&s->last_use_ms, __ATOMIC_RELAXED) != now)
        __atomic_store_n(&s->last_use_ms, now, __ATOMIC_RELAXED);
    look(srv, now);
    if (!__atomic_load_n(&s->cold, __ATOMIC_RELAXED) || !__atomic_exchange_n(&s->cold, 0,
                                                                            __ATOMIC_RELAXED))
        return 0;
    /* a released set wakes: let the budget thread look at once */
    sts_budget *b = &srv->budget;
    if (b->started && STS_LIVE(srv, memory_budget)) {
        pthread_mutex_lock(&b->mu);
        b->kick = 1;
        pthread_cond_signal(&b->cv);
        pthread_mutex_unlock(&b->mu);
    }
    return 1;
}


void sts_budget_cold_done(sts_server *srv, int64_t t0_us, uint32_t nqueries)
{
    sts_budget *b = &srv->budget;
    int64_t us = sts_now_us() - t0_us;
    unsigned k = 0;
    while (k + 1 < STS_COLD_HIST && (uint64_t)us > hist_us[k])
        k++;
    __atomic_add_fetch(&b->cold_hist[k], 1, __ATOMIC_RELAXED);
    __atomic_add_fetch(&b->cold_sum_us, (uint64_t)(us > 0 ? us : 0), __ATOMIC_RELAXED);
    __atomic_add_fetch(&b->cold_batches, 1, __ATOMIC_RELAXED);
    __atomic_add_fetch(&b->cold_queries, nqueries, __ATOMIC_RELAXED);
}

void sts_budget_hist(sts_server *srv, uint64_t counts[STS_COLD_HIST],
                     uint32_t bound_us[STS_COLD_HIST], uint64_t *sum_us)
{
    sts_budget *b = &srv->budget;
    *sum_us = __atomic_load_n(&b->cold_sum_us, __ATOMIC_RELAXED);
    for (unsigned k = 0; k < STS_COLD_HIST; k++) {
        counts[k] = __atomic_load_n(&b->cold_hist[k], __ATOMIC_RELAXED);
        bound_us[k] = hist_us[k];
    }
}

size_t sts_budget_stats(sts_server *srv, stp_stat *s, size_t cap)
{
    sts_budget *b = &srv->budget;
    size_t n = 0;
    uint64_t stored, resident;
    sts_budget_measure(srv, &stored, &resident);
#define PUT(k, val) do { if (n < cap) { snprintf(s[n].key, sizeof s[n].key, "%s", k); \
    s[n].type = STP_STAT_U64; s[n].v.u = (val); n++; } } while (0)
    PUT("memory_budget", STS_LIVE(srv, memory_budget));
    PUT("stored_bytes", stored);
    PUT("resident_bytes", resident);
    PUT("budget_releases", __atomic_load_n(&b->releases, __ATOMIC_RELAXED));
    PUT("budget_released_bytes", __atomic_load_n(&b->released_bytes, __ATOMIC_RELAXED));
    long mf = majflt_now() - b->majflt0;
    PUT("major_faults", (uint64_t)(mf > 0 ? mf : 0));
    PUT("cold_batches", __atomic_load_n(&b->cold_batches, __ATOMIC_RELAXED));
    PUT("cold_queries", __atomic_load_n(&b->cold_queries, __ATOMIC_RELAXED));
    uint64_t counts[STS_COLD_HIST], sum_us;
    uint32_t bound_us[STS_COLD_HIST];
    sts_budget_hist(srv, counts, bound_us, &sum_us);
    for (unsigned k = 0; k < STS_COLD_HIST; k++) {
        char key[48];
        if (bound_us[k] == UINT32_MAX)
            snprintf(key, sizeof key, "cold_first_us_inf");
        else
            snprintf(key, sizeof key, "cold_first_us_le_%u", bound_us[k]);
        PUT(key, counts[k]);
    }
    PUT("cold_first_us_sum", sum_us);
#undef PUT
    return n;
}
