/* server/dispatch.c - the request table and the decision made for every parsed frame.
 *
 * Owns: the table {opcode, name, max body, flags, handler}, an array indexed by opcode and
 * generated from STP_OPCODES (protocol/proto_lists.h) with this file's body caps and run
 * flags; unknown opcodes, a REPLY flag in a request and the token rule (mutating requests
 * need the HELLO token when the server has one) answered here, before any handler runs;
 * inline vs worker; the one mapping from store codes (ST_E*) to wire statuses.
 * Does not own: parsing frames (io.c + protocol/), what handlers do.
 *
 * Inline on the I/O thread: everything cheap (HELLO, PING, LIST, INFO, STATS, job and upload
 * status, upload begin and abort, COMPRESS (it only checks names and queues a job for the
 * job thread: the encoding runs there, never on an I/O thread), JOB_CANCEL, FETCH reads and
 * closes, SAMPLE batches up to heavy-batch queries). On a worker (STS_H_HEAVY): upload chunks
 * (disk writes), commits (import + fsync), deletes (fsync), FETCH_OPEN (serialises a set),
 * and SAMPLE / SAMPLE_DIR batches over heavy-batch (STS_H_SIZED), and a smaller batch whose
 * handler returns STS_DEFER (it would first build the chart data or Ptex table its set builds
 * lazily: h_basic.c).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dispatch.h"
#include "cluster_node.h"
#include "h_basic.h"
#include "h_jobs.h"
#include "h_upload.h"
#include "io.h"
#include "opstats.h"
#include "server.h"
#include "shm.h"
#include "workers.h"

/* Body caps per opcode, bytes (io.c refuses a longer body with TOO_LARGE before reading it);
 * 0 = only the server's max-frame. Each request's largest legal body fits: e.g. INFO is
 * 2 + 255 + 8 bytes, COMPRESS 2 + 255 + 2 + 255 + 2, UPLOAD_BEGIN 1315 at most. UPLOAD_CHUNK's
 * is its 20-byte head + max_chunk, so a chunk over max_chunk is TOO_LARGE (and skipped) like
 * any body over a cap, never a second status. PROTOCOL.md 2.2 prints this table;
 * tests/unit/test_protodoc.c checks that it does, row by row. */
enum {
    STS_CAP_HELLO         = 4096,
    STS_CAP_PING          = 0,
    STS_CAP_LIST          = 64,
    STS_CAP_INFO          = 512,
    STS_CAP_SAMPLE        = 0,
    STS_CAP_SAMPLE_DIR    = 0,
    STS_CAP_STATS         = 64,
    STS_CAP_UPLOAD_BEGIN  = 2048,
    STS_CAP_UPLOAD_CHUNK  = STP_DEFAULT_MAX_CHUNK + 20,   /* exactly a max_chunk chunk */
    STS_CAP_UPLOAD_COMMIT = 64,
    STS_CAP_UPLOAD_ABORT  = 64,
    STS_CAP_UPLOAD_STATUS = 64,
    STS_CAP_DELETE        = 512,
    STS_CAP_COMPRESS      = 1024,
    STS_CAP_JOB_STATUS    = 64,
    STS_CAP_JOB_CANCEL    = 64,
    STS_CAP_FETCH_OPEN    = 512,
    STS_CAP_FETCH_READ    = 64,
    STS_CAP_FETCH_CLOSE   = 64,
    STS_CAP_CLUSTER       = 64,
    STS_CAP_REPLICA_PUBLISH = 512,
    STS_CAP_SHM_ATTACH    = 64
};

/* Where each opcode runs (sts_hflags without STS_H_MUTATING, which comes from the protocol's
 * list): 0 inline, STS_H_HEAVY a worker, STS_H_SIZED a worker when the batch is large. */
enum {
    STS_RUN_HELLO         = 0,
    STS_RUN_PING          = 0,
    STS_RUN_LIST          = 0,
    STS_RUN_INFO          = 0,
    STS_RUN_SAMPLE        = STS_H_SIZED,
    STS_RUN_SAMPLE_DIR    = STS_H_SIZED,
    STS_RUN_STATS         = 0,
    STS_RUN_UPLOAD_BEGIN  = 0,
    STS_RUN_UPLOAD_CHUNK  = STS_H_HEAVY,
    STS_RUN_UPLOAD_COMMIT = STS_H_HEAVY,
    STS_RUN_UPLOAD_ABORT  = 0,
    STS_RUN_UPLOAD_STATUS = 0,
    STS_RUN_DELETE        = STS_H_HEAVY,
    STS_RUN_COMPRESS      = 0,
    STS_RUN_JOB_STATUS    = 0,
    STS_RUN_JOB_CANCEL    = 0,
    STS_RUN_FETCH_OPEN    = STS_H_HEAVY,
    STS_RUN_FETCH_READ    = 0,
    STS_RUN_FETCH_CLOSE   = 0,
    STS_RUN_CLUSTER       = 0,
    STS_RUN_REPLICA_PUBLISH = STS_H_HEAVY,
    STS_RUN_SHM_ATTACH    = 0
};

/* One row per opcode of STP_OPCODES, at its opcode; the other rows are zero (fn NULL =
 * unknown opcode). A new opcode in the list fails to compile here until it has a cap, a run
 * flag and a handler sts_h_<lower>. */
static const sts_handler TABLE[STP_OP_MAX_ + 1] = {
#define ROW(NAME, lower, code, mut)                                                        \
    [code] = {code, #NAME, STS_CAP_##NAME, (mut ? STS_H_MUTATING : 0u) | STS_RUN_##NAME,     \
              sts_h_##lower},
    STP_OPCODES(ROW)
#undef ROW
};

const sts_handler *sts_handler_find(unsigned op)
{
    return op < sizeof TABLE / sizeof TABLE[0] && TABLE[op].fn ? &TABLE[op] : NULL;
}

/* ---- store codes -> wire statuses ---------------------------------------------------------
 * The one table (PROTOCOL.md section 3 prints it): X(store code, status). Every ST_E* code of
 * store/err.h must be here exactly once: a duplicate is a duplicate case label, and the count
 * must equal the number of codes, so a code added to err.h without a row fails to compile. */
#define STS_ST_STATUSES(X)                                                                  \
    X(ST_OK, OK)                                                                            \
    X(ST_EINVAL, INVALID)                                                                   \
    X(ST_ENOMEM, NOMEM)                                                                     \
    X(ST_EIO, IO)                                                                           \
    X(ST_EFORMAT, FORMAT)                                                                   \
    X(ST_ETOOBIG, TOO_LARGE)                                                                \
    X(ST_EADJ, ADJ)                                                                         \
    X(ST_ENOTFOUND, NOT_FOUND)                                                              \
    X(ST_EUNSUPPORTED, UNSUPPORTED)                                                         \
    X(ST_EEXIST, EXISTS)                                                                    \
    X(ST_ECORRUPT, CORRUPT)                                                                 \
    X(ST_ENOUV, NOUV)                                                                       \
    X(ST_ECANCELED, CANCELED)                                                               \
    X(ST_EBUSY, BUSY)                                                                       \
    X(ST_EPERM, PERM)                                                                       \
    X(ST_ETIMEDOUT, TIMEOUT)

#define COUNT_ROW(code, status) +1
#define RANGE_ROW(code, status) \
    _Static_assert(code <= 0 && code >= ST_ECODE_MIN, #code " is not a store code");
_Static_assert(0 STS_ST_STATUSES(COUNT_ROW) == 1 - ST_ECODE_MIN,
               "every store code from ST_OK down to ST_ECODE_MIN needs a status");
STS_ST_STATUSES(RANGE_ROW)
#undef COUNT_ROW
#undef RANGE_ROW

int sts_status_from_st(int st_code)
{
    switch (st_code) {
#define ROW(code, status) case code: return STP_S_##status;
    STS_ST_STATUSES(ROW)
#undef ROW
    default: return STP_S_INTERNAL;
    }
}

/* A server path starts with '/' (the daemon makes every folder it writes to absolute at
 * start: server.c) at the start of the text or after one of these, and is followed by a
 * byte that is not a space (a lone "/" in prose is not a path). */
static int path_starts(const char *msg, const char *p)
{
    if (p[0] != '/' || p[1] == 0 || p[1] == ' ')
        return 0;
    return p == msg || strchr(" '\"(<[=,:", p[-1]) != NULL;
}

/* A path ends at a space, a quote, a closing bracket, a comma or semicolon, or ": ". */
static const char *path_end(const char *p)
{
    while (*p && !strchr(" '\")]>,;", *p) && !(p[0] == ':' && (p[1] == ' ' || !p[1])))
        p++;
    return p;
}

size_t sts_scrub_paths(const char *msg, char *out, size_t cap)
{
    static const char HIDDEN[] = "(server file)";
    size_t n = 0;
    if (!cap)
        return 0;
    for (const char *p = msg ? msg : ""; *p && n + 1 < cap;) {
        if (path_starts(msg, p)) {
            p = path_end(p);
            for (const char *q = HIDDEN; *q && n + 1 < cap; q++)
                out[n++] = *q;
        } else {
            out[n++] = *p++;
        }
    }
    out[n] = 0;
    return n;
}

void sts_reply_error(stp_buf *out, const stp_header *h, int status, const char *msg)
{
    /* the one place every error text leaves the server: no server path gets through */
    char clean[STP_MAX_MSG + 1];
    sts_scrub_paths(msg, clean, sizeof clean);
    stp_enc_error(out, h->opcode, h->reqid, (uint16_t)status, clean);
}

int sts_reply_bad(stp_buf *out, const stp_header *h, int status, const char *why)
{
    const char *op = stp_opcode_name(h->opcode);
    char msg[200];
    snprintf(msg, sizeof msg, "%s: %s", op ? op : "request", why ? why : "malformed body");
    sts_reply_error(out, h, status, msg);
    return 0;
}

void sts_reply_st(stp_buf *out, const stp_header *h, int st_code, const char *msg)
{
    sts_reply_error(out, h, sts_status_from_st(st_code), msg && *msg ? msg : st_strerror(st_code));
}

/* Hands the request to the worker pool (the connection reads nothing more until its reply
 * is queued: workers.c); 1, or 0 when out of memory (nothing handed over). */
static int to_worker(sts_server *srv, sts_conn *conn, const sts_handler *hd, const stp_header *h,
                     const uint8_t *body, int64_t t0)
{
    sts_task *t = calloc(1, sizeof *t);
    if (!t)
        return 0;
    t->conn = conn;
    t->hd = hd;
    t->h = *h;
    t->body = body;
    t->start_ms = t0 / 1000;
    t->start_us = t0;    /* the worker records its reply (workers.c) */
    stp_buf_init(&t->out);
    conn->busy = 1;
    STS_STAT_ADD(srv, worker_tasks, 1);
    sts_pool_submit(&srv->pool, t);
    return 1;
}

int sts_dispatch(sts_io *io, sts_conn *conn, const stp_header *h, const uint8_t *body)
{
    sts_server *srv = io->srv;
    int64_t t0 = sts_now_us();   /* request parsed: its latency starts here */
    size_t before = stp_buf_avail(&conn->out);   /* not len: appending may compact */
    int r = 0;
    STS_STAT_ADD(srv, requests, 1);
    STS_STAT_ADD(srv, by_op[h->opcode], 1);
    if (h->flags & STP_F_REPLY) {
        STS_STAT_ADD(srv, bad_requests, 1);
        STS_STAT_ADD(srv, replies_error, 1);
        sts_reply_error(&conn->out, h, STP_S_BAD_REQUEST, "REPLY flag set in a request");
        goto replied;
    }
    const sts_handler *hd = sts_handler_find(h->opcode);
    if (!hd) {
        STS_STAT_ADD(srv, frames_unknown_op, 1);
        STS_STAT_ADD(srv, replies_error, 1);
        char msg[64];
        snprintf(msg, sizeof msg, "unknown opcode 0x%02x", h->opcode);
        sts_reply_error(&conn->out, h, STP_S_UNKNOWN_OPCODE, msg);
        goto replied;
    }
    if ((hd->flags & STS_H_MUTATING) && !sts_token_allows(srv, conn->authed)) {
        STS_STAT_ADD(srv, perm_denied, 1);
        STS_STAT_ADD(srv, replies_error, 1);
        char msg[128];
        snprintf(msg, sizeof msg, "%s needs the server's token (send it in HELLO)", hd->name);
        sts_reply_error(&conn->out, h, STP_S_PERM, msg);
        if (h->opcode >= STP_OP_UPLOAD_BEGIN && h->opcode <= STP_OP_UPLOAD_COMMIT)
            sts_logf(&srv->log, STS_WARN, "upload from %s refused at %s (PERM): no token",
                     conn->peer, hd->name);
        goto replied;
    }
    int heavy = (hd->flags & STS_H_HEAVY) != 0;
    if (hd->flags & STS_H_SIZED) {
        /* PROTOCOL.md 2.2: longer than heavy-batch f32 queries, with compact queries (4.4.1)
         * counted as f32 ones: they are as much work. (Exactly heavy-batch queries count as
         * heavy, as the f32 body's parameters make it longer: measured, 16384-query batches
         * of 2 connections ran at 11.7 M queries/s on workers against 5.7 M inline.) */
        uint64_t per = h->opcode == STP_OP_SAMPLE ? STP_QUERY_SIZE : STP_DIR_QUERY_SIZE;
        uint64_t fixed = h->body_len >= 2 ? 2u + (uint64_t)stp_rd16(body) + 24u : 0;
        uint64_t equiv = fixed + (uint64_t)stp_sample_peek_count(body, h->body_len) * per;
        heavy = equiv > (uint64_t)STS_LIVE(srv, heavy_batch) * per;
    }
    if (heavy && to_worker(srv, conn, hd, h, body, t0))
        return 1;
    if (heavy) {
        sts_reply_error(&conn->out, h, STP_S_NOMEM, "out of memory");
        goto replied;
    }
    STS_STAT_ADD(srv, inline_tasks, 1);   /* before the handler: STATS counts itself */
    sts_ctx ctx = {srv, conn, &io->scratch, t0 / 1000, 1};
    int hr = hd->fn(&ctx, h, body, &conn->out);
    if (hr == STS_DEFER) {   /* out untouched: a worker runs the request from the start */
        if (to_worker(srv, conn, hd, h, body, t0))
            return 1;
        sts_reply_error(&conn->out, h, STP_S_NOMEM, "out of memory");
        goto replied;
    }
    r = hr ? 2 : 0;
    size_t added = stp_buf_avail(&conn->out) - before;
    if (added >= STP_HEADER_SIZE) {
        /* count error replies: status is at offset 12 of the frame just written, which ends
         * the buffer (appending may have moved the pending bytes to the front) */
        const uint8_t *f = conn->out.data + conn->out.len - added;
        if (stp_rd16(f + 12) != STP_S_OK)
            STS_STAT_ADD(srv, replies_error, 1);
    }
replied:
    sts_opstats_record(&srv->opstats, h->opcode, t0, &conn->out, before);
    return r;
}
