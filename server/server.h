/* server/server.h - seamtexd's internal interfaces: the server, its I/O threads, connections,
 * the worker pool, the dispatch table and the handlers. Sections name the file they belong to.
 *
 * Layers (each knows only those below it):
 *   main.c            flags, signals (sigwaitinfo on the main thread), reload
 *   server.c          the sts_server: create, listen, start threads, drain, stop, stats
 *   io.c + ev_epoll.c I/O threads: accept, read, frame parsing, backpressure, writes, timeouts
 *   dispatch.c        the table {opcode, name, max body, flags, handler}, token checks, inline
 *                     vs worker decision
 *   workers.c         worker threads for heavy requests, the job thread for COMPRESS
 *   h_*.c             handlers: decode the body (protocol/), call the store, encode the reply
 *   store/            sets, registry, data dir, sampler, importers, BC1
 *
 * Threads: main (signals), io_threads I/O threads (each with its own poller; the listening
 * socket is in every poller with EPOLLEXCLUSIVE, so whichever thread wakes accepts), workers
 * worker threads, one job thread. A connection belongs to one I/O thread for its whole life;
 * only that thread touches its buffers. A heavy request is handed to a worker together with
 * a pointer to its body inside the connection's input buffer: while it is out, the
 * connection neither reads nor parses (so the buffer cannot move), and the worker's reply
 * comes back through the I/O thread's completion list + eventfd. Replies therefore leave in
 * request order on every connection (the server does not offer STP_CAP_OUT_OF_ORDER).
 * A SAMPLE batch of split-batch queries or more is sampled in parts by the thread that has it
 * and idle workers together (sts_pool_parallel), only onto CPUs not already sampling.
 *
 * No globals: everything hangs off the sts_server passed by pointer.
 */
#ifndef STS_SERVER_H
#define STS_SERVER_H

#include <pthread.h>
#include <stdint.h>

#include "budget.h"
#include "config.h"
#include "datadir.h"
#include "ev.h"
#include "log.h"
#include "proto.h"
#include "registry.h"
#include "sample.h"

typedef struct sts_server sts_server;
typedef struct sts_io sts_io;
typedef struct sts_conn sts_conn;
typedef struct sts_task sts_task;

/* ---- io.c: connections -------------------------------------------------------------------- */

/* A connection's input: bytes [start, len) are unparsed; compacted before it grows. */
typedef struct sts_inbuf {
    uint8_t *data;
    size_t   start, len, cap;
} sts_inbuf;

struct sts_conn {
    int       fd;
    sts_io   *io;
    uint64_t  id;
    sts_inbuf in;            /* allocated lazily on the first read */
    stp_buf   out;           /* replies not yet written; allocated lazily */
    int64_t   last_ms;       /* last traffic, monotonic ms */
    uint64_t  skip;          /* body bytes of a refused frame still to discard */
    uint64_t  mem;           /* bytes of in+out capacity counted in srv->mem_used */
    uint32_t  authed;        /* token generation HELLO authenticated for (0 = none) */
    uint8_t   busy;          /* a request is out on a worker */
    uint8_t   close_after;   /* close once `out` is flushed (bad magic, refused connection) */
    uint8_t   dead;          /* peer gone or error: free as soon as not busy */
    uint8_t   paused;        /* not reading (backpressure or busy) */
    unsigned  ev_mask;       /* events registered with the poller */
    sts_conn *prev, *next;   /* the I/O thread's list (idle scan, drain) */
};

/* Scratch memory for sampling, one per thread (I/O or worker); grows, never shrinks, so a
 * batch allocates nothing once the thread has seen one as large. */
typedef struct sts_scratch {
    st_query *q;
    float    *out, *cov;
    uint8_t  *status;
    size_t    cap;           /* queries the arrays hold */
    struct st_cube_query *cq;
    size_t    cqcap;         /* direction queries cq holds (SAMPLE_DIR only) */
} sts_scratch;
/* Room for n queries (and n direction queries when dir). 0 or -1. */
int sts_scratch_reserve(sts_scratch *s, size_t n, int dir);
void sts_scratch_free(sts_scratch *s);

struct sts_io {
    sts_server     *srv;
    int             index;
    pthread_t       thread;
    sts_ev         *ev;
    int             wakefd;        /* eventfd: completions or stop */
    pthread_mutex_t mu;            /* guards done */
    sts_task       *done;          /* finished tasks to hand back */
    sts_conn       *conns;         /* list of live connections */
    uint32_t        nconns;
    sts_scratch     scratch;
};

void *sts_io_main(void *arg);
/* Called by a worker: queue a finished task for its connection's I/O thread. */
void sts_io_complete(sts_io *io, sts_task *t);
/* Wakes an I/O thread (stop, reload). */
void sts_io_wake(sts_io *io);

/* ---- dispatch.c: the table ----------------------------------------------------------------- */

enum sts_hflags {
    STS_H_MUTATING = 1,    /* needs the token when the server has one */
    STS_H_HEAVY    = 2,    /* always runs on a worker */
    STS_H_SIZED    = 4     /* runs on a worker when the body is large (SAMPLE batches) */
};

typedef struct sts_ctx {
    sts_server  *srv;
    sts_conn    *conn;     /* on a worker: read-only fields (id, authed) only */
    sts_scratch *scratch;
    int64_t      start_ms; /* when the request was parsed */
} sts_ctx;

/* A handler decodes body (body_len bytes), does the work and appends exactly one reply frame
 * to out (an error reply on failure). Return value: 0, or 1 to ask for the connection to be
 * closed after the reply. */
typedef int (*sts_handler_fn)(sts_ctx *c, const stp_header *h, const uint8_t *body,
                              stp_buf *out);

typedef struct sts_handler {
    uint8_t        op;
    const char    *name;
    uint32_t       max_body;   /* 0 = the server's max-frame */
    unsigned       flags;      /* sts_hflags */
    sts_handler_fn fn;
} sts_handler;

/* The entry for an opcode, NULL when unknown (one array lookup). */
const sts_handler *sts_handler_find(unsigned op);

/* Decides and runs one parsed request: error replies for unknown opcodes and missing tokens,
 * inline handling, or a task for a worker. Returns 0 (reply appended to conn->out), 1 (a task
 * was queued: the connection is busy), 2 (reply appended; close the connection after it). */
int sts_dispatch(sts_io *io, sts_conn *conn, const stp_header *h, const uint8_t *body);

/* Appends an error reply; a store error code gives its status. */
void sts_reply_error(stp_buf *out, const stp_header *h, int status, const char *msg);
/* An error reply "<OPCODE>: <why>" ("malformed body" when why is NULL); returns 0 so that a
 * handler can `return sts_reply_bad(...)`. */
int sts_reply_bad(stp_buf *out, const stp_header *h, int status, const char *why);
void sts_reply_st(stp_buf *out, const stp_header *h, int st_code, const char *msg);
/* The wire status of a store code (0 or ST_E*); INTERNAL for an unknown code. */
int sts_status_from_st(int st_code);

/* ---- h_basic.c, h_upload.c, h_jobs.c: the handlers (see the table in dispatch.c) ---------- */
int sts_h_hello(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_ping(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_list(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_info(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_sample(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_sample_dir(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_stats(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_upload_begin(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_upload_chunk(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_upload_commit(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_upload_abort(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_upload_status(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_delete(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_compress(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_job_status(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_job_cancel(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_fetch_open(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_fetch_read(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);
int sts_h_fetch_close(sts_ctx *, const stp_header *, const uint8_t *, stp_buf *);

/* ---- workers.c ------------------------------------------------------------------------------ */

struct sts_task {
    sts_conn          *conn;
    const sts_handler *hd;
    stp_header         h;
    const uint8_t     *body;   /* inside conn->in, stable while conn->busy */
    int64_t            start_ms;
    int                close;  /* handler asked to close */
    stp_buf            out;    /* the reply, moved into conn->out by the I/O thread */
    sts_task          *next;
};

/* One part of a split batch: samples queries [first, first + count). Returns the number of
 * bad queries (>= 0) or a negative ST_E* code. Runs on the caller or on a helping worker. */
typedef int (*sts_part_fn)(void *arg, size_t first, size_t count);

typedef struct sts_par sts_par;   /* a split batch open for helpers (workers.c) */

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
    uint64_t        split_batches;/* atomic: batches a helper was woken for (STATS) */
    uint64_t        parts_helped; /* atomic: parts workers sampled for others (STATS) */
    int             stop;
    pthread_t      *threads;
    uint32_t        nthreads;
} sts_pool;

int sts_pool_start(sts_server *srv, sts_pool *p, uint32_t n);
void sts_pool_submit(sts_pool *p, sts_task *t);
void sts_pool_stop(sts_pool *p);
/* Runs fn over [0, n) in parts of `grain` items: the calling thread takes parts itself and
 * idle workers (only those already idle, and only as many as there are CPUs not already
 * sampling a batch) take the others as they wake,
 * so the call never waits for a worker to start, only for parts a worker has already begun.
 * With no idle worker, or n <= grain, it is one call fn(arg, 0, n) on the caller. Returns the
 * sum of the parts' results, or the first negative one. Any thread may call it (I/O threads,
 * a worker running a heavy request); fn must be safe to run concurrently on disjoint parts. */
int sts_pool_parallel(sts_pool *p, size_t n, size_t grain, sts_part_fn fn, void *arg);

/* ---- h_jobs.c: COMPRESS jobs and FETCH handles ---------------------------------------------- */

typedef struct sts_job sts_job;
typedef struct sts_fetch sts_fetch;

typedef struct sts_jobs {
    pthread_mutex_t mu;
    pthread_cond_t  cv;
    sts_job        *list;      /* every job, newest first; finished ones kept for STATUS */
    uint32_t        active;    /* queued + running */
    uint64_t        next_id;
    int             stop;
    pthread_t       thread;
    int             started;
    sts_fetch      *fetches;
    uint32_t        nfetches;
    uint64_t        next_fetch;
} sts_jobs;

int sts_jobs_start(sts_server *srv);
void sts_jobs_stop(sts_server *srv);
/* Drops the fetch handles a connection opened (when it closes). */
void sts_fetch_drop_conn(sts_server *srv, uint64_t conn_id);
/* A closing connection's unfinished uploads are kept for upload-keep seconds (resume), or
 * dropped when it is 0. */
void sts_upload_drop_conn(sts_server *srv, uint64_t conn_id);
/* Drops kept uploads older than upload-keep (the I/O threads call it once a second). */
void sts_uploads_sweep(sts_server *srv, int64_t now_ms);

/* ---- h_upload.c: uploads and the data dir ---------------------------------------------------- */

typedef struct sts_upload sts_upload;
typedef struct sts_uploads {
    pthread_mutex_t mu;
    sts_upload     *list;
    uint32_t        n;
    uint64_t        next_id;
} sts_uploads;

/* Loads every set of the data dir into the registry (start). Returns sets loaded or < 0. */
int sts_load_datadir(sts_server *srv);
void sts_uploads_free(sts_server *srv);
/* Imports one file into a set, choosing the reader by format ("ptx", "dds", or anything the
 * importer knows). */
int sts_import_path(sts_server *srv, const char *path, const char *fmt, const char *options,
                    st_set **out, st_error *e);

/* ---- server.c ---------------------------------------------------------------------------------- */

/* Counters, updated with relaxed atomics, reported by STATS and at exit. */
typedef struct sts_stats {
    uint64_t conns_accepted, conns_rejected, conns_closed, conns_idle_closed;
    uint64_t requests, replies_error, bytes_in, bytes_out, reads, writes;
    uint64_t frames_bad_magic, frames_bad_version, frames_too_large, frames_unknown_op;
    uint64_t bad_requests, perm_denied, mem_rejected, deadline_expired;
    uint64_t backpressure_pauses, worker_tasks, inline_tasks;
    uint64_t queries, query_errors;
    uint64_t uploads_begun, uploads_committed, uploads_failed, upload_bytes, deletes;
    uint64_t uploads_resumed, uploads_expired;
    uint64_t jobs_started, jobs_done, jobs_failed, jobs_canceled, fetches;
    uint64_t by_op[256];
} sts_stats;

#define STS_STAT_ADD(srv, field, n) __atomic_add_fetch(&(srv)->stats.field, (n), __ATOMIC_RELAXED)
#define STS_LIVE(srv, field) __atomic_load_n(&(srv)->cfg.field, __ATOMIC_RELAXED)

struct sts_server {
    sts_config      cfg;          /* reloadable fields read with STS_LIVE; strings under cfg_mu */
    pthread_mutex_t cfg_mu;       /* guards cfg.token while reloading */
    pthread_mutex_t commit_mu;    /* "name free?" check + disk commit + publish, atomically */
    sts_log         log;
    sts_stats       stats;
    st_registry    *reg;
    st_datadir     *dd;           /* NULL without --data-dir */
    int             listen_fd;
    int             port;         /* bound port */
    sts_io         *io;           /* cfg.io_threads of them */
    uint32_t        nio;
    sts_pool        pool;
    sts_jobs        jobs;
    sts_uploads     uploads;
    sts_budget      budget;       /* budget.c: --memory-budget */
    uint64_t        next_conn_id; /* atomic */
    uint32_t        nconns;       /* atomic: live connections */
    uint64_t        mem_used;     /* atomic: bytes in connection buffers */
    int             stopping;     /* atomic: 1 drain, 2 force-close what is left */
    uint32_t        token_gen;    /* bumped when the token changes (under cfg_mu) */
    int64_t         started_ms;
};

int64_t sts_now_ms(void);         /* monotonic */

/* Creates the server from a checked config: registry, data dir (loads it), default set,
 * listening socket. Threads are not started yet. 0 or -1 (logged). */
int sts_server_init(sts_server *srv, const sts_config *cfg);
/* Starts the I/O threads, workers and job thread; writes the port file. */
int sts_server_start(sts_server *srv);
/* Stops accepting, waits for in-flight requests and replies (up to grace_ms), joins every
 * thread. */
void sts_server_stop(sts_server *srv, int grace_ms);
void sts_server_free(sts_server *srv);
/* Applies a reloaded config (limits, token, log level) and logs the differences. */
void sts_server_reload(sts_server *srv, const sts_config *fresh);
/* Does the connection's token state allow a mutating request? */
/* HELLO: the token generation a token authenticates for, 0 when it does not. */
uint32_t sts_token_check(sts_server *srv, const char *token);
/* May a connection authenticated for generation `authed` mutate? */
int sts_token_allows(sts_server *srv, uint32_t authed);

/* Memory accounting for connection buffers (io.c keeps srv->mem_used equal to the capacity
 * of every buffer): 0 when n more bytes fit under max-memory. */
int sts_mem_take(sts_server *srv, uint64_t n);

#endif
