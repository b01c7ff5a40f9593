/* server/io.h - the I/O threads and their connections (io.c).
 *
 * Owns: struct sts_conn (a connection's fd and buffers: only its I/O thread touches them),
 * struct sts_io (one event loop, its connection list and completion list), the per-thread
 * sampling scratch. Does not own: what a request means (dispatch.h), the worker queue
 * (workers.h), the poller (ev.h).
 *
 * Ownership: connections are allocated at accept by whichever I/O thread the listening
 * socket woke, which assigns each to the thread with the fewest connections (itself or
 * another: then the struct travels through that thread's adopt list, and from then on only
 * the owner touches it); they are freed by their I/O thread once closed and not busy; a worker only reads conn->id, conn->authed and conn->io while it holds a
 * task. Scratch arrays belong to their thread and are freed with sts_scratch_free.
 */
#ifndef STS_IO_H
#define STS_IO_H

#include <pthread.h>
#include <stdint.h>

#include "ev.h"
#include "proto.h"
#include "sample.h"

typedef struct sts_server sts_server;
typedef struct sts_io sts_io;
typedef struct sts_conn sts_conn;
typedef struct sts_task sts_task;

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
    sts_inbuf in2;           /* the next buffer of a split read (io.c, "Split reads"): its
                                bytes [start, len) follow in's on the wire; empty but for the
                                moment between such a read and the parse that takes them */
    stp_buf   out;           /* replies not yet written; allocated lazily */
    int64_t   last_ms;       /* last traffic, monotonic ms */
    int64_t   req_start_ms;  /* when the first byte of the frame still incomplete in `in` (or
                                being skipped) arrived; 0 = no partial frame (request deadline) */
    char      peer[48];      /* "address:port" of the client, for the log */
    uint64_t  skip;          /* body bytes of a refused frame still to discard */
    uint64_t  mem;           /* bytes of in+out capacity counted in srv->mem_used */
    uint32_t  authed;        /* token generation HELLO authenticated for (0 = none) */
    uint8_t   busy;          /* a request is out on a worker */
    uint8_t   close_after;   /* close once `out` is flushed (bad magic, refused connection) */
    uint8_t   dead;          /* peer gone or error: free as soon as not busy */
    uint8_t   paused;        /* not reading for backpressure (counted once per pause) */
    uint8_t   held;          /* conn_process stopped at backpressure with input unparsed: not
                                read again until that is parsed (io.c, conn_serve) */
    uint8_t   yielded;       /* conn_process used its time slice with frames left: on its I/O
                                thread's ready list, parsed on in the loop's next pass, not
                                read meanwhile (io.c, "Time slices") */
    sts_conn *ready_next;    /* the ready list (io->ready or io->ready_pass) */
    int64_t   linger_until;  /* stopping: our side shut (SHUT_WR) after the last reply; input
                                is read and dropped until the peer's end or this monotonic ms,
                                then closed (io.c, linger_start); 0 = not lingering */
    unsigned  ev_mask;       /* events registered with the poller */
    uint8_t   unix_sock;     /* a Unix-domain connection: may pass descriptors (shm.h) */
    uint8_t   in_pad;        /* where a read into an empty input buffer starts (0-3): the last
                                frame's in_pad (io.c), so a client's next SAMPLE of the same
                                set lands with its queries aligned */
    uint32_t  next_total;    /* the length of the last whole frame when it was a SAMPLE of
                                SPLIT_MIN bytes or more, else 0: where a read into an empty
                                buffer is split (the client repeats its batches) */
    uint32_t  read_hint;     /* room the first read of a wake-up is offered (0 = the default):
                                what the last wake-up read when that took more than one read
                                of the default room (io.c, conn_readable) */
    uint32_t  wake_bytes;    /* bytes read so far in this wake-up (conn_readable) */
    struct sts_shm_conn *shm;  /* shm.c: descriptors held and the mapped region; NULL = none */
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
    struct sts_shm_scratch *shm;  /* shm.c: private copies of shared-memory requests */
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
    pthread_mutex_t mu;            /* guards done and adopt */
    sts_task       *done;          /* finished tasks to hand back */
    sts_conn       *adopt;         /* connections another thread accepted for this one */
    sts_conn       *conns;         /* list of live connections */
    sts_conn       *ready;         /* connections that yielded their time slice (io.c) */
    sts_conn       *ready_pass;    /* the ones the loop's current pass is serving */
    uint32_t        nconns;        /* atomic: live connections, adopt list included (the
                                      acceptor picks the thread with the fewest) */
    uint64_t        accepted;      /* atomic: connections assigned to this thread (STATS) */
    sts_scratch     scratch;
    int64_t         oldest_partial_ms; /* atomic: published by each idle scan, the first-byte
                                          time of this thread's oldest half-sent frame at least
                                          a second old (0 = none): eviction candidates */
    uint32_t        evict_req;     /* atomic: evictions other threads asked of this one */
    int             cpu;           /* the CPU this thread is pinned to (pin-io), -1 = none */
    int             listen_paused; /* out of file descriptors with no spare to shed with: the
                                      listener is out of this poller until the next 1 s tick
                                      (io.c: accept_starved), so a readable listener whose
                                      accept fails cannot spin the loop */
    /* Two input buffers (a split read's pair) and one output buffer (<= 64 KiB each) that a
     * connection of this thread released when everything was answered, kept for the next
     * connection that reads: a request / reply cycle then neither mallocs and frees them nor
     * regrows the output buffer (with a copy) from 256 bytes (io.c). Not counted in
     * buffer_memory. */
    uint8_t        *spare_in[2];
    size_t          spare_in_cap[2];
    stp_buf         spare_out;
};

void *sts_io_main(void *arg);
/* Called by a worker: queue a finished task for its connection's I/O thread, which moves
 * the task's reply into the connection's output and frees the task. */
void sts_io_complete(sts_io *io, sts_task *t);
/* Wakes an I/O thread (stop, reload). */
void sts_io_wake(sts_io *io);

#endif
