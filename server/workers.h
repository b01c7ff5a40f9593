/* server/workers.h - the worker pool for heavy requests and split SAMPLE batches (workers.c).
 *
 * Owns: struct sts_task (one request out on a worker), struct sts_pool (the FIFO, the worker
 * threads, the open split batches and their counters), the request deadline. Does not own:
 * the connection (a finished task goes back to its I/O thread through sts_io_complete, io.h),
 * what a handler or a part does.
 *
 * Ownership: sts_dispatch allocates a task; sts_pool_submit hands it to the pool; the worker
 * fills t->out and hands it to the I/O thread, which moves the reply out and frees the task.
 */
#ifndef STS_WORKERS_H
#define STS_WORKERS_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include "proto.h"

typedef struct sts_server sts_server;
typedef struct sts_conn sts_conn;
typedef struct sts_task sts_task;
typedef struct sts_handler sts_handler;

struct sts_task {
    sts_conn          *conn;
    const sts_handler *hd;
    stp_header         h;
    const uint8_t     *body;   /* inside conn->in, stable while conn->busy */
    int64_t            start_ms;
    int64_t            start_us; /* when the request was parsed (opstats latency) */
    int                close;  /* handler asked to close */
    stp_buf            out;    /* the reply, moved into conn->out by the I/O thread */
    sts_task          *next;
};

/* One part of a split batch: samples queries [first, first + count). Returns the number of
 * bad queries (>= 0) or a negative ST_E* code. Runs on the caller or on a helping worker. */
typedef int (*sts_part_fn)(void *arg, size_t first, size_t count);

typedef struct sts_par sts_par;   /* a split batch open for helpers (workers.c) */

/* Split-batch callers that are tracked (one per I/O thread: io-threads is at most 64). */
#define STS_POOL_SLOTS 64

typedef struct sts_pool {
    pthread_mutex_t mu;
    pthread_cond_t  cv;           /* workers wait here for tasks or open split batches */
    pthread_cond_t  par_cv;       /* a split batch's caller waits here for its helpers */
    sts_task       *head, *tail;
    uint32_t        queued;
    uint32_t        idle;         /* workers waiting on cv */
    uint32_t        ncpu;         /* online CPUs */
    uint32_t        sampling;     /* atomic: threads inside a split-able batch (callers and
                                     helpers); helpers are woken only while this < ncpu */
    sts_par        *par;          /* open split batches (helpers take the first with parts left) */
    int64_t         slot_state[STS_POOL_SLOTS]; /* atomic, per I/O thread: -1 while it samples a
                                     split-able batch, else when its last one ended (us), 0 never */
    uint32_t        nslots;       /* atomic: slots used (highest + 1) */
    uint64_t        split_batches;/* atomic: batches a helper was woken for (STATS) */
    uint64_t        parts_helped; /* atomic: parts workers sampled for others (STATS) */
    uint64_t        helpers_yielded; /* atomic: helpers that left a batch with parts still to
                                     take because more threads than CPUs were sampling (STATS) */
    int             stop;
    pthread_t      *threads;
    uint32_t        nthreads;
} sts_pool;

int sts_pool_start(sts_server *srv, sts_pool *p, uint32_t n);
/* Queues t (the pool owns it until a worker hands it to its I/O thread). */
void sts_pool_submit(sts_pool *p, sts_task *t);
/* Workers finish what is queued, then exit; joins them. */
void sts_pool_stop(sts_pool *p);
/* Runs fn over [0, n) in parts of `grain` items: the calling thread takes parts itself and
 * idle workers (only those already idle, and only as many as there are CPUs not already
 * sampling a batch, nor kept by another I/O thread that ended a batch less than 10 ms ago
 * and is likely to start the next: `slot` is the caller's I/O thread index, -1 on a worker)
 * take the others as they wake,
 * so the call never waits for a worker to start, only for parts a worker has already begun.
 * With no idle worker, or n <= grain, it is one call fn(arg, 0, n) on the caller. Returns the
 * sum of the parts' results, or the first negative one. Any thread may call it (I/O threads,
 * a worker running a heavy request); fn must be safe to run concurrently on disjoint parts. */
int sts_pool_parallel(sts_pool *p, int slot, size_t n, size_t grain, sts_part_fn fn, void *arg);

#endif
