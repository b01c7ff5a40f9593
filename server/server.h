/* server/server.h - seamtexd's shared core: the sts_server, its counters and the functions of
 * server.c. Every other part of the daemon has its own header, named after its file, so a
 * file's #includes show what it depends on:
 *
 *   main.c                  flags, signals (sigwaitinfo on the main thread), reload
 *   server.c   server.h     the sts_server: create, listen, start threads, drain, stop, reload,
 *                           token, memory accounting
 *   startup.c  startup.h    loading the data dir into the registry at start
 *   io.c       io.h         I/O threads, connections, sampling scratch (poller: ev.h, ev_epoll.c)
 *   dispatch.c dispatch.h   the table {opcode, name, max body, flags, handler}, token checks,
 *                           inline vs worker, error replies
 *   workers.c  workers.h    worker threads for heavy requests, split SAMPLE batches
 *   opstats.c  opstats.h    per-opcode request, error and latency counters (STATS)
 *   metrics_http.c metrics.h  the --metrics-listen thread: GET /metrics over plain HTTP/1.x
 *   metrics_text.c metrics.h  the Prometheus text rendering of the STATS counters
 *   handles.c  handles.h    one table of handles (ids, owner, capacity, lock): uploads,
 *                           fetches and jobs
 *   uploads.c  uploads.h    the upload records and their life (kept, resumed, done, swept)
 *   h_basic.c  h_basic.h    handlers: HELLO PING LIST INFO STATS SAMPLE SAMPLE_DIR
 *   h_upload.c h_upload.h   handlers: UPLOAD_* DELETE; import of a file by format
 *   h_jobs.c   h_jobs.h     handlers: COMPRESS JOB_* FETCH_*; the job thread
 *   config.c   config.h     settings = flags = config keys; log.c log.h: the log
 *   cluster_*.c cluster_node.h  membership, catalogue, copies (--cluster; docs/cluster.md)
 *   store/                  sets, registry, data dir, sampler, importers, BC1
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
 * and idle workers together (sts_pool_parallel), only onto CPUs no other sampler keeps.
 *
 * No globals: everything hangs off the sts_server passed by pointer (main.c keeps it in a
 * function-local static because of its size; signals are taken synchronously, no flag).
 */
#ifndef STS_SERVER_H
#define STS_SERVER_H

#include <pthread.h>
#include <stdint.h>

#include "budget.h"
#include "config.h"
#include "datadir.h"
#include "handles.h"
#include "listen_unix.h"
#include "log.h"
#include "metrics.h"
#include "opstats.h"
#include "proto.h"
#include "registry.h"
#include "workers.h"

typedef struct sts_server sts_server;
typedef struct sts_io sts_io;
typedef struct sts_jobs sts_jobs;
typedef struct sts_cluster sts_cluster;

/* Wire values of modes and filters are below these (protocol/proto_lists.h). */
#define STS_QMODES   4
#define STS_QFILTERS 16

/* Counters, updated with relaxed atomics, reported by STATS (h_basic.c), /metrics
 * (metrics_text.c, from the same counters) and at exit. */
typedef struct sts_stats {
    uint64_t conns_accepted, conns_rejected, conns_closed, conns_idle_closed;
    uint64_t requests, replies_error, bytes_in, bytes_out, reads, writes;
    uint64_t frames_bad_magic, frames_bad_version, frames_too_large, frames_unknown_op;
    uint64_t bad_requests, perm_denied, mem_rejected, deadline_expired;
    uint64_t backpressure_pauses, worker_tasks, inline_tasks;
    uint64_t queries, query_errors;
    uint64_t uploads_begun, uploads_committed, uploads_failed, upload_bytes, deletes;
    uint64_t uploads_resumed, uploads_expired;
    uint64_t native_write_failed;  /* commits without their native file (server.c, WARN) */
    uint64_t jobs_started, jobs_done, jobs_failed, jobs_canceled, fetches, fetches_refused;
    uint64_t conns_request_timeout, conns_evicted;
    uint64_t shm_attached, shm_refused, shm_maps, shm_bytes;   /* shm.c; maps, bytes: now */
    uint64_t shm_requests, shm_too_small, shm_fds_dropped;
    uint64_t shm_overlap_copies;   /* shm_sample.c: query and reply rooms overlapped */
    uint64_t by_op[256];
    uint64_t queries_by[STS_QMODES][STS_QFILTERS];  /* queries by wire mode and filter value */
} sts_stats;

#define STS_STAT_ADD(srv, field, n) __atomic_add_fetch(&(srv)->stats.field, (n), __ATOMIC_RELAXED)
#define STS_LIVE(srv, field) __atomic_load_n(&(srv)->cfg.field, __ATOMIC_RELAXED)

struct sts_server {
    sts_config      cfg;          /* reloadable fields read with STS_LIVE; strings under cfg_mu */
    pthread_mutex_t cfg_mu;       /* guards cfg.token while reloading */
    pthread_mutex_t commit_mu;    /* "name free?" check + disk commit + publish, atomically */
    sts_log         log;
    sts_stats       stats;
    sts_opstats     opstats;      /* per opcode: errors and latency histogram (opstats.c) */
    st_registry    *reg;
    st_datadir     *dd;           /* NULL without --data-dir */
    int             listen_fd;
    int             spare_fd;     /* /dev/null, held so that at EMFILE / ENFILE an I/O thread
                                     can close it, accept one waiting connection and answer it
                                     BUSY instead of leaving the listener readable (io.c:
                                     accept_starved); -1 while it could not be reopened (retried
                                     each I/O tick); atomic, changed under accept_mu */
    pthread_mutex_t accept_mu;    /* every accept4 and the spare's close / reopen: no other
                                     I/O thread's accept can take the slot the spare frees */
    int64_t         starved_log_ms; /* atomic: when the last "out of file descriptors" line was
                                       logged (one per 10 s, with the count since) */
    uint64_t        starved_shed;   /* atomic: connections shed that way since that line */
    int             port;         /* bound port (0 on a Unix socket) */
    sts_unix_listener ulisten;    /* --listen unix:PATH (listen_unix.h) */
    sts_io         *io;           /* cfg.io_threads of them (io.h) */
    uint32_t        nio;
    sts_pool        pool;         /* workers.h */
    sts_jobs       *jobs;         /* COMPRESS jobs and the job thread (h_jobs.c), from start */
    sts_handles     uploads;      /* upload records (uploads.c) */
    sts_handles     fetches;      /* FETCH handles (h_jobs.c) */
    sts_budget      budget;       /* budget.c: --memory-budget */
    sts_metrics     metrics;      /* metrics_http.c: --metrics-listen */
    sts_cluster    *cluster;      /* cluster_node.h: NULL without --cluster */
    uint64_t        next_conn_id; /* atomic */
    uint32_t        nconns;       /* atomic: live connections */
    uint64_t        mem_used;     /* atomic: bytes in connection buffers */
    uint64_t        fetch_mem;    /* atomic: bytes of open fetches (h_jobs.c); max-memory
                                     bounds mem_used + fetch_mem */
    int             stopping;     /* atomic: 1 drain, 2 force-close what is left */
    uint32_t        token_gen;    /* bumped when the token changes (under cfg_mu) */
    int64_t         started_ms;
    char            tmpdir[1600]; /* absolute: the data dir's tmp/, else a folder of this
                                     daemon's own under $TMPDIR or /tmp (private_tmpdir); where
                                     uploads without a data dir and FETCH's image writers put
                                     their temp files (server paths never reach a reply) */
    int             tmpdir_fd;    /* that own folder, flock'ed for the daemon's life; -1 with a
                                     data dir */
};

/* ---- server.c ------------------------------------------------------------------------------- */

int64_t sts_now_ms(void);         /* monotonic */
int64_t sts_now_us(void);         /* monotonic, microseconds */

/* Creates the server from a checked config: registry, data dir (loads it: startup.c),
 * default set, listening socket. Threads are not started yet. 0 or -1 (logged). */
int sts_server_init(sts_server *srv, const sts_config *cfg);
/* Starts the I/O threads, workers and job thread; writes the port file. */
int sts_server_start(sts_server *srv);
/* Stops accepting, waits for in-flight requests and replies (up to grace_ms), joins every
 * thread. */
void sts_server_stop(sts_server *srv, int grace_ms);
/* Frees what init and start made (the sts_server itself belongs to the caller). */
void sts_server_free(sts_server *srv);
/* Applies a reloaded config (limits, token, log level) and logs the differences. */
void sts_server_reload(sts_server *srv, const sts_config *fresh);
/* HELLO: the token generation a token authenticates for, 0 when it does not. */
uint32_t sts_token_check(sts_server *srv, const char *token);
/* May a connection authenticated for generation `authed` mutate? */
int sts_token_allows(sts_server *srv, uint32_t authed);

/* A listening TCP socket (non-blocking, close-on-exec, SO_REUSEADDR) on host:port; *bound gets
 * the port bound (port 0 picks one). The fd, or -1 with the error logged under `what`. */
int sts_tcp_listen(sts_server *srv, const char *what, const char *host, int port, int backlog,
                   int *bound);

/* Memory accounting for connection buffers (io.c keeps srv->mem_used equal to the capacity
 * of every buffer) and open fetches (srv->fetch_mem): 0 when n more bytes fit under
 * max-memory. */
int sts_mem_take(sts_server *srv, uint64_t n);
/* The same against half of max-memory: for room reserved ahead of the bytes it is for (a
 * frame's body that has not arrived), which may not take the second half (res36, io.c). */
int sts_mem_take_ahead(sts_server *srv, uint64_t n);

#endif
