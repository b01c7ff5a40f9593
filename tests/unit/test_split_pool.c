/* tests/unit/test_split_pool.c - split SAMPLE batches (sts_pool_parallel, server/workers.c) and
 * the cores they may use:
 *   - every part of a split batch runs exactly once and the results add up;
 *   - helpers are woken only onto CPUs that are not sampling already: with another thread
 *     sampling on a 2-CPU pool, a batch is one call on its caller, no helper woken;
 *   - nor onto a CPU another I/O thread keeps: one inside a batch, or out of one for less than
 *     a millisecond (its next pipelined batch is a send and a read away); an I/O thread's own
 *     last batch, or another's long ago, does not count;
 *   - a helper that is sampling parts when another batch starts (more samplers than CPUs)
 *     leaves after the part it has, the caller takes the rest (STATS helpers_yielded), and
 *     the worker does not come back to the batch while every CPU is sampling.
 * The pool's CPU count is set to 2 whatever the machine has, so the rules are tested alike on
 * any host; the threads are synchronised by flags, not by timing.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <pthread.h>
#include <string.h>
#include <time.h>

#include "server.h"
#include "workers.h"

enum { NPARTS = 16 };

typedef struct part_log {
    sts_pool *pool;
    pthread_t caller;
    int       ran[NPARTS];        /* atomic: times each part ran */
    int       by_helper[NPARTS];  /* atomic: times a worker ran it */
    int       calls;              /* atomic: calls of the part function */
    size_t    whole;              /* count of the last call (1 call = the whole batch) */
    int       stage;              /* 1: make a helper meet another batch (atomic flags below) */
    int       helper_in;          /* a helper is inside its first part */
    int       go;                 /* the helper may finish that part */
    int       caller_waited;
} part_log;

/* Waits (sleeping 100 us at a time, up to 60 s) until *flag is at least `want`. */
static int wait_flag(const int *flag, int want)
{
    struct timespec ts = {0, 100000};
    for (int i = 0; i < 600000; i++) {
        if (__atomic_load_n(flag, __ATOMIC_ACQUIRE) >= want)
            return 1;
        nanosleep(&ts, NULL);
    }
    return 0;
}

static int wait_sampling(const sts_pool *p, uint32_t want)
{
    struct timespec ts = {0, 100000};
    for (int i = 0; i < 600000; i++) {
        if (__atomic_load_n(&p->sampling, __ATOMIC_ACQUIRE) == want)
            return 1;
        nanosleep(&ts, NULL);
    }
    return 0;
}

static int part(void *arg, size_t first, size_t count)
{
    part_log *l = arg;
    __atomic_add_fetch(&l->calls, 1, __ATOMIC_RELAXED);
    l->whole = count;
    int helper = !pthread_equal(pthread_self(), l->caller);
    if (count == 1) {
        __atomic_add_fetch(&l->ran[first], 1, __ATOMIC_RELAXED);
        if (helper)
            __atomic_add_fetch(&l->by_helper[first], 1, __ATOMIC_RELAXED);
    }
    if (l->stage && helper && !__atomic_exchange_n(&l->helper_in, 1, __ATOMIC_ACQ_REL)) {
        /* the helper's first part: hold it until another batch has "started" */
        if (!wait_flag(&l->go, 1))
            return -99;
    } else if (l->stage && !helper && !l->caller_waited) {
        l->caller_waited = 1;
        /* the caller's first part: wait for a helper, then start "another batch" (one more
         * sampler than the pool's 2 CPUs), let the helper finish its part, and wait until it
         * has left the batch (sampling back to this thread + the other batch) */
        if (!wait_flag(&l->helper_in, 1))
            return -98;
        __atomic_add_fetch(&l->pool->sampling, 1, __ATOMIC_RELEASE);
        __atomic_store_n(&l->go, 1, __ATOMIC_RELEASE);
        if (!wait_sampling(l->pool, 2))
            return -97;
    }
    return (int)count;   /* "bad queries": the sum over the parts is the batch's size */
}

static void wait_idle(sts_pool *p)
{
    struct timespec ts = {0, 100000};
    for (int i = 0; i < 600000; i++) {
        pthread_mutex_lock(&p->mu);
        uint32_t idle = p->idle;
        pthread_mutex_unlock(&p->mu);
        if (idle == 2)
            return;
        nanosleep(&ts, NULL);
    }
    fail_msg("the workers are not waiting");
}

static sts_server srv;   /* no task is queued: the workers only help split batches */

static void start(sts_pool *p)
{
    memset(p, 0, sizeof *p);
    assert_int_equal(sts_pool_start(&srv, p, 2), 0);
    p->ncpu = 2;
    wait_idle(p);   /* only workers already waiting are woken for a batch */
}

static void every_part_runs_once_and_the_results_add_up(void **st)
{
    (void)st;
    sts_pool p;
    start(&p);
    for (int round = 0; round < 20; round++) {
        part_log l;
        memset(&l, 0, sizeof l);
        l.pool = &p;
        l.caller = pthread_self();
        assert_int_equal(sts_pool_parallel(&p, -1, NPARTS, 1, part, &l), NPARTS);
        for (int i = 0; i < NPARTS; i++)
            assert_int_equal(l.ran[i], 1);
        assert_int_equal(__atomic_load_n(&p.sampling, __ATOMIC_ACQUIRE), 0);
        wait_idle(&p);
    }
    /* a helper was woken for each of them: both workers idle, no other sampler */
    assert_int_equal(p.split_batches, 20);
    sts_pool_stop(&p);
}

static void no_helper_when_every_cpu_is_sampling(void **st)
{
    (void)st;
    sts_pool p;
    start(&p);
    /* another thread (another connection's I/O thread) is sampling on one of the 2 CPUs:
     * this batch takes the other, alone, in one call */
    __atomic_store_n(&p.sampling, 1, __ATOMIC_RELEASE);
    part_log l;
    memset(&l, 0, sizeof l);
    l.pool = &p;
    l.caller = pthread_self();
    assert_int_equal(sts_pool_parallel(&p, -1, NPARTS, 1, part, &l), NPARTS);
    assert_int_equal(l.calls, 1);
    assert_int_equal(l.whole, NPARTS);
    assert_int_equal(p.split_batches, 0);
    assert_int_equal(p.parts_helped, 0);
    assert_int_equal(__atomic_load_n(&p.sampling, __ATOMIC_ACQUIRE), 1);
    __atomic_store_n(&p.sampling, 0, __ATOMIC_RELEASE);
    sts_pool_stop(&p);
}

/* One batch from I/O thread `slot` (another, slot 0, in the state given; with age_us > 0
 * instead: slot 0 ended a batch age_us before the call, timed after the pool's threads have
 * started, which on a loaded machine can take longer than the window tested); returns
 * whether a helper was woken for it. */
static int woken_with_slot0_aged(int slot, int64_t slot0, int64_t age_us)
{
    sts_pool p;
    start(&p);
    p.slot_state[0] = age_us > 0 ? sts_now_us() - age_us : slot0;
    p.nslots = 2;
    part_log l;
    memset(&l, 0, sizeof l);
    l.pool = &p;
    l.caller = pthread_self();
    assert_int_equal(sts_pool_parallel(&p, slot, NPARTS, 1, part, &l), NPARTS);
    for (int i = 0; i < NPARTS; i++)
        assert_true(l.calls == 1 || l.ran[i] == 1);
    int woken = p.split_batches == 1;
    assert_int_equal(woken ? NPARTS : 1, l.calls);   /* unsplit: one call, the whole batch */
    /* the caller's own slot now says when its batch ended */
    assert_true(p.slot_state[slot] > 0);
    sts_pool_stop(&p);
    return woken;
}

static int woken_with_slot0(int slot, int64_t slot0)
{
    return woken_with_slot0_aged(slot, slot0, 0);
}

static void no_helper_while_another_io_thread_samples_or_just_did(void **st)
{
    (void)st;
    int64_t now = sts_now_us();
    /* slot 0 inside a batch */
    assert_false(woken_with_slot0(1, -1));
    /* slot 0 ended a batch "just now" (a time ahead of the clock: within the millisecond
     * however late this thread runs) */
    assert_false(woken_with_slot0(1, now + 10 * 1000000));
    /* slot 0 ended one 2 ms ago: a loaded machine's gap between a connection's batches (the
     * client waiting for a time slice) still keeps its CPU (RECENT_US, 10 ms) */
    assert_false(woken_with_slot0_aged(1, 0, 2000));
    /* slot 0 ended one 10 s ago, or never: its CPU is free */
    assert_true(woken_with_slot0(1, now - 10 * 1000000));
    assert_true(woken_with_slot0(1, 0));
    /* the caller's own last batch does not keep a CPU from helping it */
    assert_true(woken_with_slot0(0, now + 10 * 1000000));
}

static void a_helper_leaves_when_another_batch_starts(void **st)
{
    (void)st;
    sts_pool p;
    start(&p);
    part_log l;
    memset(&l, 0, sizeof l);
    l.pool = &p;
    l.caller = pthread_self();
    l.stage = 1;
    assert_int_equal(sts_pool_parallel(&p, -1, NPARTS, 1, part, &l), NPARTS);
    int helped = 0;
    for (int i = 0; i < NPARTS; i++) {
        assert_int_equal(l.ran[i], 1);
        helped += l.by_helper[i];
    }
    /* the helper sampled the one part it had begun, then left; the caller did the rest */
    assert_int_equal(helped, 1);
    assert_int_equal(p.parts_helped, 1);
    assert_int_equal(p.helpers_yielded, 1);
    assert_int_equal(p.split_batches, 1);
    /* the "other batch" ends */
    assert_int_equal(__atomic_sub_fetch(&p.sampling, 1, __ATOMIC_ACQ_REL), 0);
    sts_pool_stop(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_part_runs_once_and_the_results_add_up),
        cmocka_unit_test(no_helper_when_every_cpu_is_sampling),
        cmocka_unit_test(no_helper_while_another_io_thread_samples_or_just_did),
        cmocka_unit_test(a_helper_leaves_when_another_batch_starts),
    };
    return cmocka_run_group_tests_name("split_pool", tests, NULL, NULL);
}
