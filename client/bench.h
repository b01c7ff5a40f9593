/* client/bench.h - internal header of the load tester seamtex-bench (not installed).
 *
 * Owns: the run configuration, per-thread state and results shared by
 *   bench_main.c    arguments, threads, report and JSON
 *   bench_loop.c    one epoll loop per thread driving several connections (open/closed loop)
 *   bench_wire.c    request frames and reply parsing, through protocol/'s encoders and parser;
 *                   for --proto memcached / redis, those servers' cheapest no-op instead
 *   bench_inproc.c  the in-process sampler baseline (st_sample_batch on the same queries)
 *   bench_sched.c   arrival schedules;  hist.c  latency histograms
 *   bench_cluster.c --cluster / --lib: the load through libseamtex (stc_cluster, stc_conn)
 * Does not own: the protocol (protocol/), the client library (libseamtex).
 *
 * Clock: CLOCK_MONOTONIC nanoseconds everywhere (bench_now_ns).
 */
#ifndef STC_BENCH_H
#define STC_BENCH_H

#include <stddef.h>
#include <stdint.h>
#include <time.h>

#include "bench_sched.h"
#include "hist.h"

#define BENCH_MAX_CONNS     20000
#define BENCH_MAX_THREADS   64
#define BENCH_MAX_PIPELINE  4096
#define BENCH_MAX_BATCH     65536
#define BENCH_MAX_MIX       8

typedef enum bench_op {
    BENCH_OP_PING       = 0,
    BENCH_OP_SAMPLE     = 1,   /* face, u, v queries */
    BENCH_OP_SAMPLE_DIR = 2    /* cube-map direction queries (a cube set) */
} bench_op;

/* Which server the network loops talk to. The peers (memcached, Redis) are loaded with their
 * cheapest no-op request, so that PING figures can be compared side by side with the same
 * connections, pipelining, schedules and histograms. Peers answer in order and carry no
 * request id: a reply belongs to the oldest request outstanding on its connection. */
typedef enum bench_proto {
    BENCH_PROTO_SEAMTEX   = 0,
    BENCH_PROTO_MEMCACHED = 1,  /* text protocol: "version\r\n" -> "VERSION x\r\n" */
    BENCH_PROTO_REDIS     = 2   /* RESP: "*1\r\n$4\r\nPING\r\n" -> "+PONG\r\n" */
} bench_proto;

static inline const char *bench_proto_name(unsigned p)
{
    return p == BENCH_PROTO_MEMCACHED ? "memcached" : p == BENCH_PROTO_REDIS ? "redis" : "seamtex";
}

static inline const char *bench_op_name(unsigned op)
{
    return op == BENCH_OP_SAMPLE ? "sample" : op == BENCH_OP_SAMPLE_DIR ? "sample-dir" : "ping";
}
static inline int bench_op_samples(unsigned op)
{
    return op == BENCH_OP_SAMPLE || op == BENCH_OP_SAMPLE_DIR;
}

typedef struct bench_cfg {
    const char *host;          /* loopback only */
    const char *port;
    const char *token;         /* NULL = none */
    const char *set;           /* set name for SAMPLE */
    const char *json_path;     /* NULL = no JSON */
    uint8_t     op;            /* bench_op */
    uint8_t     proto;         /* bench_proto; a peer allows only BENCH_OP_PING */
    uint8_t     open_loop;     /* 1: --rate given */
    uint8_t     arrival;       /* stc_arrival */
    uint8_t     quiet;
    double      rate;          /* open loop: requests per second, all connections together */
    double      duration_s;    /* measured time */
    double      warmup_s;      /* before the measured time, not recorded */
    double      timeout_s;     /* a reply later than this counts as a timeout */
    unsigned    spin_us;       /* open loop: poll instead of sleeping this close to a due time */
    uint64_t    max_requests;  /* 0 = no cap */
    uint64_t    seed;
    unsigned    conns;         /* network: connections in all */
    unsigned    threads;       /* network: threads sharing the connections (at most conns);
                                * --inproc: sampling threads */
    unsigned    pipeline;      /* closed loop: outstanding per connection; open loop: cap */
    unsigned    batch;         /* SAMPLE: queries per request */
    unsigned    nmodes, nfilters;
    uint8_t     modes[BENCH_MAX_MIX];    /* st_mode values, one picked at random per request */
    uint8_t     filters[BENCH_MAX_MIX];  /* st_filter values */
    float       footprint;     /* SAMPLE: |du/dx| = |dv/dy| of every query (0 = point-like) */
    uint8_t     compact;       /* SAMPLE: --compact: UV16 queries, FACE16 too under 65536 faces */
    uint8_t     outfmt;        /* SAMPLE, SAMPLE_DIR: stp_outfmt of the replies (--outfmt) */
    uint32_t    nfaces;        /* SAMPLE: faces of the set (asked with INFO at start) */
    uint8_t     nchan;         /* SAMPLE: channels of the set */
    uint8_t     kind;          /* SAMPLE: st_kind of the set */
    unsigned    idle;          /* --idle N: open N connections, ping each once, hold */
    double      hold_s;        /* how long --idle holds them */
    const char *cluster;       /* --cluster SEEDS or etcd:// URL (bench_cluster.c), NULL = no */
    uint8_t     lib;           /* --lib: the same loop on a direct stc_conn (bench_cluster.c) */
    uint8_t     blocking;      /* --blocking: --cluster one stc_cluster_sample at a time */
    uint8_t     shm;           /* --shm: SAMPLE through a shared-memory region per connection */
    uint8_t     shm_copy;      /* --shm-copy: and copy each request's queries into it */
    int         lowat;         /* --lowat K: closed-loop SAMPLE wakes for K whole replies
                                * (SO_RCVLOWAT); -1 = pipeline / 2 (at least 1), 0 = off */
} bench_cfg;

/* What one thread measured; merged by bench_main.c. */
typedef struct bench_result {
    stc_hist corrected;        /* t_reply - t_intended */
    stc_hist service;          /* t_reply - t_actual_send */
    uint64_t sent;             /* requests written (whole run, warm-up included) */
    uint64_t completed;        /* replies received (whole run) */
    uint64_t measured;         /* replies recorded in the histograms */
    uint64_t errors;           /* replies with a non-OK status */
    uint64_t timeouts;         /* no reply within timeout_s, or left when the run ended */
    uint64_t conn_errors;      /* connections that failed (reset, bad frame) */
    uint64_t late_sends;       /* open loop: requests written more than 1 ms after due */
    uint64_t unsent;           /* open loop: due before the end but never sent */
    uint64_t queries;          /* SAMPLE: queries answered in the measured window */
    uint64_t bytes_out, bytes_in;
    uint64_t t_last;           /* time of the last measured reply (ns) */
    uint64_t failovers, moved; /* --cluster: stc_cluster_counters of the handle */
} bench_result;

typedef struct bench_wire bench_wire;   /* per-thread request pool, bench_wire.c */

typedef struct bench_thread {
    const bench_cfg *cfg;
    unsigned    index;
    unsigned    conn_first, conn_count;
    uint64_t    max_requests;  /* this thread's share of cfg->max_requests, 0 = none */
    uint64_t    t_start;       /* common start (intended time origin) */
    uint64_t    t_measure;     /* start + warm-up */
    uint64_t    t_end;         /* t_measure + duration: no request is issued from then */
    int        *fds;           /* connected sockets, conn_count of them, owned by the caller */
    uint8_t   **shm;           /* --shm: each connection's region (pipeline slots), or NULL */
    size_t      shm_slot;      /* --shm: bytes of one reply room */
    size_t      shm_qroom;     /* --shm: bytes of one pool frame's query room */
    size_t      shm_qarea;     /* --shm: the query rooms' bytes (the reply rooms follow) */
    bench_wire *wire;
    unsigned    lowat_k;       /* SO_RCVLOWAT: wake for this many whole replies (0 = off) */
    bench_result *res;         /* caller-owned, zeroed, histograms reset */
    char        err[256];      /* first fatal error of the thread */
    int         no_conn;       /* --cluster / --lib: its handle could not connect (exit 3) */
} bench_thread;

static inline uint64_t bench_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ---- bench_loop.c ---- */
/* Runs one thread's connections until t_end plus the drain time; returns 0, or -1 with
 * th->err set when the thread could not run at all. */
int bench_loop_run(bench_thread *th);

/* ---- bench_cluster.c ---- */
/* --cluster / --lib: one thread's handle (opened here), closed loop until t_end; 0, or -1 with
 * th->err set. */
int bench_lib_run(bench_thread *th);

/* ---- bench_wire.c ---- */
/* Connects one socket to cfg->host:port (loopback only, checked), does whatever handshake the
 * protocol needs (seamtex: HELLO with the token; memcached: "version"; Redis: PING, which
 * also checks that the port is the server asked for), and returns the fd, non-blocking, or
 * -1 with msg set. */
int bench_wire_connect(const bench_cfg *cfg, char *msg, size_t msglen);
/* Asks the server for the set's face count and channels (SAMPLE); 0 or -1 with msg. */
int bench_wire_set_info(bench_cfg *cfg, int fd, char *msg, size_t msglen);
/* Builds a pool of ready request frames for one thread. */
bench_wire *bench_wire_new(const bench_cfg *cfg, uint64_t seed, char *msg, size_t msglen);
void bench_wire_free(bench_wire *w);
/* Next request frame: *frame points into the pool (valid until the next call on w), returns
 * its length and the number of queries it carries (*nq, 0 for PING). */
size_t bench_wire_next(bench_wire *w, const uint8_t **frame, uint32_t *nq);
/* Looks at the front of buf: returns the length of one complete reply and sets *ok (1 = the
 * expected answer) and *reqid, 0 when more bytes are needed, or -1 when the bytes are not a
 * valid reply. For the peers *reqid is 0: their replies come in request order. */
long bench_wire_reply(unsigned proto, const uint8_t *buf, size_t len, int *ok, uint32_t *reqid);
/* Distinct SAMPLE frames in a thread's pool. */
#define BENCH_POOL 16
/* --shm (PROTOCOL.md 4.12): a connection's region is query rooms of bench_wire_shm_qroom
 * bytes, then pipeline reply rooms (each of bench_wire_shm_slot bytes: a reply for 4
 * channels), page-rounded. Without --shm-copy there are BENCH_POOL query rooms, each holding
 * the queries of one pool frame, written once before the run (as a renderer building its
 * queries in the region would): requests carry offsets only. With --shm-copy there is one
 * query room per request in flight, and each request's queries are copied into its room (a
 * client that builds its queries elsewhere). Either way the server samples in place. */
size_t bench_wire_shm_qrooms(const bench_cfg *cfg);
size_t bench_wire_shm_slot(const bench_cfg *cfg);
size_t bench_wire_shm_qroom(const bench_cfg *cfg);
/* Creates a sealed memfd of that size, attaches it to fd (SHM_ATTACH) and maps it at *map
 * (*size bytes; the caller munmaps). 0, or -1 with msg. */
int bench_wire_shm_attach(const bench_cfg *cfg, int fd, uint8_t **map, size_t *size,
                          char *msg, size_t msglen);
/* Copies the queries of a pool frame (len bytes) to room. */
void bench_wire_shm_copy(const uint8_t *frame, size_t len, uint8_t *room);
/* Writes the queries of every frame of w's pool into its query room of region. */
void bench_wire_shm_place(const bench_wire *w, uint8_t *region, size_t qroom);
/* The pool index of the frame the last bench_wire_next returned. */
unsigned bench_wire_last(const bench_wire *w);
/* The shared-memory form of a pool frame (flag SHM, the three offsets) written to out (at
 * least the frame's length up to its queries + 24 bytes); returns that frame's length. */
size_t bench_wire_shm_frame(const uint8_t *frame, uint64_t query_off, uint64_t reply_off,
                            uint64_t reply_cap, uint8_t *out);
/* Byte offset of the request id in a seamtex frame (the loop patches it per request; peers'
 * requests have none). */
#define BENCH_REQID_OFFSET 8

/* ---- bench_inproc.c ---- */
typedef struct bench_inproc_result {
    double   qps;              /* queries per second in the measured window */
    uint64_t queries_total;    /* every query answered, warm-up included */
    double   cpu_s;            /* CPU time of the process over the whole run */
} bench_inproc_result;
/* Samples the same kind of batches with st_sample_batch on the default set, in this process,
 * for warmup_s + duration_s; prints and fills r. 0 or -1 with msg. */
int bench_inproc_run(const bench_cfg *cfg, bench_inproc_result *r, char *msg, size_t msglen);

/* ---- shared query generator (bench_wire.c) ---- */
/* Fills n random queries for a set of nfaces faces: face uniform, (u, v) uniform in [0,1),
 * footprint (fp, 0) / (0, fp). */
struct st_query;
void bench_make_queries(struct st_query *q, size_t n, uint32_t nfaces, float fp, uint64_t *rng);

#endif
