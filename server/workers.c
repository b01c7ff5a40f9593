/* server/workers.c - the worker pool for heavy requests and split SAMPLE batches.
 *
 * Owns: a FIFO of tasks under one mutex + condition variable, the worker threads, the
 * request deadline (a task that waited longer than deadline-ms, or than the client's own
 * timeout hint, is answered TIMEOUT without running), and split batches (sts_pool_parallel):
 * a thread sampling a big batch publishes it in parts; idle workers take parts (before queued
 * tasks) while the caller takes the rest. Does not own: the connection (the reply goes back
 * to its I/O thread through sts_io_complete), what the handler or a part does.
 * Each worker has its own sampling scratch.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "dispatch.h"
#include "io.h"
#include "opstats.h"
#include "server.h"
#include "workers.h"

struct sts_par {
    sts_part_fn fn;
    void       *arg;
    size_t      n, grain, nparts;
    size_t      next;       /* atomic: the next part to take */
    size_t      sum;        /* atomic: sum of the parts' results */
    int         err;        /* atomic: first negative result, 0 = none */
    uint32_t    helpers;    /* atomic (changed under the pool mutex): workers inside */
    sts_par    *next_open;  /* the pool's list of open split batches */
};

/* How long a split batch's caller spins for its helpers' last parts before sleeping. */
#define SPIN_US 200

/* An I/O thread that ended a split-able batch this recently still counts as sampling: with
 * pipelined requests its next batch starts after a send and a read (tens of microseconds), so
 * a helper woken into that gap would make three samplers on two cores (measured on 2 cores, 2
 * connections x 4096 queries: helpers woken for 55% of the batches, daemon CPU per query
 * +15% against no splitting). On a loaded machine that gap is often a whole time slice of
 * the client's (milliseconds), hence 10 ms, not 1: 2 connections x 4096 over Unix + shm at
 * load 8, helpers woken for 4-40% of the batches with 1 ms, 0-0.5% with 10 ms (TCP 3-12% ->
 * 0-3%), daemon CPU per query median of 8 alternated runs 45.2 -> 43.2 ns. A lone connection
 * still gets helpers as soon as the others have been out of their batches for 10 ms. */
#define RECENT_US 10000

/* Threads sampling now or about to, as far as helpers are concerned: the larger of those
 * inside a batch (this one included) and this one + the other I/O threads inside a batch or
 * out of one for less than RECENT_US. */
static uint32_t busy_cpus(sts_pool *p, int slot, int64_t now)
{
    uint32_t inside = __atomic_load_n(&p->sampling, __ATOMIC_RELAXED);
    uint32_t recent = 1, ns = __atomic_load_n(&p->nslots, __ATOMIC_RELAXED);
    for (uint32_t i = 0; i < ns; i++) {
        if ((int)i == slot)
            continue;
        int64_t st = __atomic_load_n(&p->slot_state[i], __ATOMIC_RELAXED);
        if (st == -1 || (st > 0 && now - st < RECENT_US))
            recent++;
    }
    return inside > recent ? inside : recent;
}

static void slot_enter(sts_pool *p, int slot)
{
    if (slot < 0 || slot >= STS_POOL_SLOTS)
        return;
    __atomic_store_n(&p->slot_state[slot], -1, __ATOMIC_RELAXED);
    uint32_t ns = __atomic_load_n(&p->nslots, __ATOMIC_RELAXED);
    while ((uint32_t)slot >= ns &&
           !__atomic_compare_exchange_n(&p->nslots, &ns, (uint32_t)slot + 1, 0,
                                        __ATOMIC_RELAXED, __ATOMIC_RELAXED))
        ;
}

static void slot_leave(sts_pool *p, int slot)
{
    if (slot >= 0 && slot < STS_POOL_SLOTS)
        __atomic_store_n(&p->slot_state[slot], sts_now_us(), __ATOMIC_RELAXED);
}

static inline void cpu_relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

/* The first open split batch that still has parts to take, while a CPU is not sampling (under
 * the pool mutex; a woken worker that finds every CPU busy goes back to sleep). */
static sts_par *open_par(sts_pool *p)
{
    if (!p->par || __atomic_load_n(&p->sampling, __ATOMIC_RELAXED) >= p->ncpu)
        return NULL;
    for (sts_par *j = p->par; j; j = j->next_open)
        if (__atomic_load_n(&j->next, __ATOMIC_RELAXED) < j->nparts)
            return j;
    return NULL;
}

/* Takes parts until none is left; returns how many it took. A helper (`ncpu` nonzero) also
 * stops before a part when more threads than `ncpu` are sampling (another connection's batch
 * started on an I/O thread after it was woken): the caller takes the rest, so two busy
 * connections on two cores do not run three samplers for longer than one part. */
static size_t par_run(sts_par *j, const sts_pool *p, uint32_t ncpu)
{
    for (size_t taken = 0;; taken++) {
        if (ncpu && __atomic_load_n(&p->sampling, __ATOMIC_RELAXED) > ncpu)
            return taken;
        size_t i = __atomic_fetch_add(&j->next, 1, __ATOMIC_RELAXED);
        if (i >= j->nparts)
            return taken;
        size_t first = i * j->grain;
        size_t count = j->n - first < j->grain ? j->n - first : j->grain;
        int r = j->fn(j->arg, first, count);
        if (r < 0) {
            int zero = 0;
            __atomic_compare_exchange_n(&j->err, &zero, r, 0, __ATOMIC_RELAXED,
                                        __ATOMIC_RELAXED);
        } else {
            __atomic_add_fetch(&j->sum, (size_t)r, __ATOMIC_RELAXED);
        }
    }
}

int sts_pool_parallel(sts_pool *p, int slot, size_t n, size_t grain, sts_part_fn fn, void *arg)
{
    if (grain == 0)
        grain = 1;
    size_t nparts = n / grain + (n % grain != 0);
    if (nparts <= 1 || !p->threads)
        return fn(arg, 0, n);
    /* threads sampling a batch right now or between two, this one included: helpers only
     * fill idle CPUs (two connections on two I/O threads already keep a 2-core machine busy) */
    __atomic_add_fetch(&p->sampling, 1, __ATOMIC_RELAXED);
    uint32_t busy = busy_cpus(p, slot, sts_now_us());
    slot_enter(p, slot);
    uint32_t free_cpus = p->ncpu > busy ? p->ncpu - busy : 0;
    sts_par j;
    memset(&j, 0, sizeof j);
    j.fn = fn;
    j.arg = arg;
    j.n = n;
    j.grain = grain;
    j.nparts = nparts;
    uint32_t wake = 0;
    if (free_cpus) {
        pthread_mutex_lock(&p->mu);
        if (p->idle && !p->stop) {
            wake = p->idle < free_cpus ? p->idle : free_cpus;
            if (wake > nparts - 1)
                wake = (uint32_t)(nparts - 1);
            j.next_open = p->par;
            p->par = &j;
            for (uint32_t i = 0; i < wake; i++)
                pthread_cond_signal(&p->cv);
        }
        pthread_mutex_unlock(&p->mu);
    }
    if (!wake) {
        int r = fn(arg, 0, n);   /* nobody to help: one call, no part overhead */
        slot_leave(p, slot);
        __atomic_sub_fetch(&p->sampling, 1, __ATOMIC_RELAXED);
        return r;
    }
    __atomic_add_fetch(&p->split_batches, 1, __ATOMIC_RELAXED);
    par_run(&j, p, 0);

    /* close the batch to new helpers, then wait for the parts helpers have begun (at most one
     * part each: spin briefly, it is tens of microseconds, then sleep) */
    pthread_mutex_lock(&p->mu);
    for (sts_par **pp = &p->par; *pp; pp = &(*pp)->next_open)
        if (*pp == &j) {
            *pp = j.next_open;
            break;
        }
    pthread_mutex_unlock(&p->mu);
    /* no sched_yield here: on a loaded machine it hands this core to another process for a
     * whole time slice (measured: batches 5x slower) */
    int64_t t0 = 0;
    for (unsigned spin = 0; __atomic_load_n(&j.helpers, __ATOMIC_ACQUIRE) != 0; spin++) {
        if ((spin & 63) == 0) {
            int64_t t = sts_now_us();
            if (spin == 0)
                t0 = t;
            else if (t - t0 > SPIN_US)
                break;
        }
        cpu_relax();
    }
    if (__atomic_load_n(&j.helpers, __ATOMIC_ACQUIRE) != 0) {
        pthread_mutex_lock(&p->mu);
        while (__atomic_load_n(&j.helpers, __ATOMIC_ACQUIRE) != 0)
            pthread_cond_wait(&p->par_cv, &p->mu);
        pthread_mutex_unlock(&p->mu);
    }
    slot_leave(p, slot);
    __atomic_sub_fetch(&p->sampling, 1, __ATOMIC_RELAXED);
    int err = __atomic_load_n(&j.err, __ATOMIC_ACQUIRE);
    if (err < 0)
        return err;
    size_t sum = __atomic_load_n(&j.sum, __ATOMIC_ACQUIRE);
    return sum > (size_t)INT32_MAX ? INT32_MAX : (int)sum;
}

typedef struct worker_arg {
    sts_server *srv;
    sts_pool   *pool;
} worker_arg;

static void *worker_main(void *arg)
{
    worker_arg wa = *(worker_arg *)arg;
    free(arg);
    sts_server *srv = wa.srv;
    sts_pool *p = wa.pool;
    sts_scratch scratch;
    memset(&scratch, 0, sizeof scratch);
    for (;;) {
        pthread_mutex_lock(&p->mu);
        sts_par *j;
        while (!(j = open_par(p)) && !p->head && !p->stop) {
            p->idle++;
            pthread_cond_wait(&p->cv, &p->mu);
            p->idle--;
        }
        if (j) {
            /* help a split batch first: its caller is already sampling it */
            __atomic_add_fetch(&j->helpers, 1, __ATOMIC_RELAXED);
            pthread_mutex_unlock(&p->mu);
            __atomic_add_fetch(&p->sampling, 1, __ATOMIC_RELAXED);
            size_t done = par_run(j, p, p->ncpu);
            __atomic_sub_fetch(&p->sampling, 1, __ATOMIC_RELAXED);
            __atomic_add_fetch(&p->parts_helped, done, __ATOMIC_RELAXED);
            if (__atomic_load_n(&j->next, __ATOMIC_RELAXED) < j->nparts)
                __atomic_add_fetch(&p->helpers_yielded, 1, __ATOMIC_RELAXED);
            pthread_mutex_lock(&p->mu);
            /* release: the parts' output is visible to the caller once it reads 0 */
            if (__atomic_sub_fetch(&j->helpers, 1, __ATOMIC_RELEASE) == 0)
                pthread_cond_broadcast(&p->par_cv);
            pthread_mutex_unlock(&p->mu);
            continue;
        }
        if (!p->head) {
            pthread_mutex_unlock(&p->mu);
            break;
        }
        sts_task *t = p->head;
        p->head = t->next;
        if (!p->head)
            p->tail = NULL;
        __atomic_fetch_sub(&p->queued, 1, __ATOMIC_RELAXED); /* STATS reads it unlocked */
        pthread_mutex_unlock(&p->mu);

        int64_t now = sts_now_ms();
        uint32_t dl = STS_LIVE(srv, deadline_ms);
        uint32_t hint = t->h.timeout_ms;
        uint32_t limit = dl && hint ? (dl < hint ? dl : hint) : dl ? dl : hint;
        if (limit && now - t->start_ms > (int64_t)limit) {
            STS_STAT_ADD(srv, deadline_expired, 1);
            STS_STAT_ADD(srv, replies_error, 1);
            char msg[96];
            snprintf(msg, sizeof msg, "waited %lld ms for a worker, the deadline is %u ms",
                     (long long)(now - t->start_ms), limit);
            sts_reply_error(&t->out, &t->h, STP_S_TIMEOUT, msg);
        } else {
            sts_ctx ctx = {srv, t->conn, &scratch, t->start_ms, 0};
            t->close = t->hd->fn(&ctx, &t->h, t->body, &t->out) != 0;
            if (stp_buf_avail(&t->out) >= STP_HEADER_SIZE &&
                stp_rd16(stp_buf_head(&t->out) + 12) != STP_S_OK)
                STS_STAT_ADD(srv, replies_error, 1);
        }
        sts_opstats_record(&srv->opstats, t->h.opcode, t->start_us, &t->out, 0);
        sts_io_complete(t->conn->io, t);
    }
    sts_scratch_free(&scratch);
    return NULL;
}

int sts_pool_start(sts_server *srv, sts_pool *p, uint32_t n)
{
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    pthread_cond_init(&p->par_cv, NULL);
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    p->ncpu = ncpu > 1 ? (uint32_t)ncpu : 1;
    p->threads = calloc(n, sizeof *p->threads);
    if (!p->threads)
        return -1;
    for (uint32_t i = 0; i < n; i++) {
        worker_arg *wa = malloc(sizeof *wa);
        if (!wa)
            return -1;
        wa->srv = srv;
        wa->pool = p;
        if (pthread_create(&p->threads[i], NULL, worker_main, wa) != 0) {
            free(wa);
            return -1;
        }
        p->nthreads++;
    }
    return 0;
}

void sts_pool_submit(sts_pool *p, sts_task *t)
{
    t->next = NULL;
    pthread_mutex_lock(&p->mu);
    if (p->tail)
        p->tail->next = t;
    else
        p->head = t;
    p->tail = t;
    __atomic_fetch_add(&p->queued, 1, __ATOMIC_RELAXED);
    pthread_cond_signal(&p->cv);
    pthread_mutex_unlock(&p->mu);
}

/* Workers finish what is queued, then exit. */
void sts_pool_stop(sts_pool *p)
{
    if (!p->threads)
        return;
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    for (uint32_t i = 0; i < p->nthreads; i++)
        pthread_join(p->threads[i], NULL);
    free(p->threads);
    p->threads = NULL;
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->cv);
    pthread_cond_destroy(&p->par_cv);
}
