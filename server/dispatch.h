/* server/dispatch.h - the request table and the decision made for every parsed frame
 * (dispatch.c), and the error-reply helpers every handler uses.
 *
 * Owns: the handler contract (sts_ctx, sts_handler_fn), the table's entry type and flags,
 * sts_dispatch. Does not own: parsing frames (io.c + protocol/), the handlers (h_*.h), the
 * worker queue (workers.h), the per-opcode counters (opstats.h; sts_dispatch calls them).
 */
#ifndef STS_DISPATCH_H
#define STS_DISPATCH_H

#include <stdint.h>

#include "proto.h"

typedef struct sts_server sts_server;
typedef struct sts_io sts_io;
typedef struct sts_conn sts_conn;
typedef struct sts_scratch sts_scratch;

enum sts_hflags {
    STS_H_MUTATING = 1,    /* needs the token when the server has one */
    STS_H_HEAVY    = 2,    /* always runs on a worker */
    STS_H_SIZED    = 4     /* runs on a worker when the body is large (SAMPLE batches) */
};

typedef struct sts_ctx {
    sts_server  *srv;
    sts_conn    *conn;     /* on a worker: read-only fields (id, authed) only */
    sts_scratch *scratch;  /* the running thread's own */
    int64_t      start_ms; /* when the request was parsed */
    int          on_io;    /* 1: run inline on an I/O thread (may return STS_DEFER) */
} sts_ctx;

/* A handler decodes body (body_len bytes), does the work and appends exactly one reply frame
 * to out (an error reply on failure). Return value: 0, or 1 to ask for the connection to be
 * closed after the reply; or, only when c->on_io, STS_DEFER with nothing appended to out: the
 * request would first build data its set builds lazily (a SAMPLE that builds an atlas's chart
 * data or a Ptex table, h_basic.c) and is run again on a worker, so that the build does not
 * hold up the other connections of the I/O thread. */
#define STS_DEFER (-1)
typedef int (*sts_handler_fn)(sts_ctx *c, const stp_header *h, const uint8_t *body,
                              stp_buf *out);
/* Declares a handler: STS_HANDLER(sts_h_ping); in the h_*.h headers. */
#define STS_HANDLER(fn) int fn(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)

typedef struct sts_handler {
    uint8_t        op;
    const char    *name;
    uint32_t       max_body;   /* 0 = the server's max-frame */
    unsigned       flags;      /* sts_hflags */
    sts_handler_fn fn;
} sts_handler;

/* The entry for an opcode, NULL when unknown. Points into a static table. */
const sts_handler *sts_handler_find(unsigned op);

/* Decides and runs one parsed request: error replies for unknown opcodes and missing tokens,
 * inline handling, or a task for a worker (the task is owned by the pool, then by the I/O
 * thread that takes it back). Every reply appended here is counted per opcode (opstats.h);
 * a worker counts its own. Returns 0 (reply appended to conn->out), 1 (a task was queued:
 * the connection is busy), 2 (reply appended; close the connection after it). */
int sts_dispatch(sts_io *io, sts_conn *conn, const stp_header *h, const uint8_t *body);

/* Copies msg into out (cap bytes, NUL-terminated, truncated when needed) with every server
 * path in it (a token starting with '/': the daemon's folders are absolute) replaced by
 * "(server file)". Every error reply and job message goes through it, so no handler can tell
 * a client where the daemon keeps its files (the log keeps the paths). Returns the length. */
size_t sts_scrub_paths(const char *msg, char *out, size_t cap);

/* Appends an error reply (its text through sts_scrub_paths); a store error code gives its
 * status. */
void sts_reply_error(stp_buf *out, const stp_header *h, int status, const char *msg);
/* An error reply "<OPCODE>: <why>" ("malformed body" when why is NULL); returns 0 so that a
 * handler can `return sts_reply_bad(...)`. */
int sts_reply_bad(stp_buf *out, const stp_header *h, int status, const char *why);
void sts_reply_st(stp_buf *out, const stp_header *h, int st_code, const char *msg);
/* The wire status of a store code (0 or ST_E*); INTERNAL for an unknown code (one table,
 * checked at compile time to cover every code of store/core/err.h). */
int sts_status_from_st(int st_code);

#endif
