/* server/dispatch.c - the request table and the decision made for every parsed frame.
 *
 * Owns: the table {opcode, name, max body, flags, handler}; unknown opcodes, a REPLY flag in a
 * request and the token rule (mutating requests need the HELLO token when the server has
 * one) answered here, before any handler runs; inline vs worker. Does not own: parsing
 * frames (io.c + protocol/), what handlers do.
 *
 * Inline on the I/O thread: everything cheap (HELLO, PING, LIST, INFO, STATS, job and upload
 * status, FETCH reads, SAMPLE batches up to heavy-batch queries). On a worker: upload chunks
 * (disk writes), commits (import + fsync), deletes (fsync), FETCH_OPEN (serialises a set),
 * COMPRESS (queues a job; cheap, but needs the registry and job table only) and SAMPLE
 * batches over heavy-batch.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dispatch.h"
#include "h_basic.h"
#include "h_jobs.h"
#include "h_upload.h"
#include "io.h"
#include "opstats.h"
#include "server.h"
#include "workers.h"

static const sts_handler TABLE[] = {
    {STP_OP_HELLO, "HELLO", 4096, 0, sts_h_hello},
    {STP_OP_PING, "PING", 0, 0, sts_h_ping},
    {STP_OP_LIST, "LIST", 64, 0, sts_h_list},
    {STP_OP_INFO, "INFO", 512, 0, sts_h_info},
    {STP_OP_SAMPLE, "SAMPLE", 0, STS_H_SIZED, sts_h_sample},
    {STP_OP_SAMPLE_DIR, "SAMPLE_DIR", 0, STS_H_SIZED, sts_h_sample_dir},
    {STP_OP_STATS, "STATS", 64, 0, sts_h_stats},
    {STP_OP_UPLOAD_BEGIN, "UPLOAD_BEGIN", 2048, STS_H_MUTATING, sts_h_upload_begin},
    {STP_OP_UPLOAD_CHUNK, "UPLOAD_CHUNK", STP_DEFAULT_MAX_CHUNK + 64,
     STS_H_MUTATING | STS_H_HEAVY, sts_h_upload_chunk},
    {STP_OP_UPLOAD_COMMIT, "UPLOAD_COMMIT", 64, STS_H_MUTATING | STS_H_HEAVY,
     sts_h_upload_commit},
    {STP_OP_UPLOAD_ABORT, "UPLOAD_ABORT", 64, STS_H_MUTATING, sts_h_upload_abort},
    {STP_OP_UPLOAD_STATUS, "UPLOAD_STATUS", 64, 0, sts_h_upload_status},
    {STP_OP_DELETE, "DELETE", 512, STS_H_MUTATING | STS_H_HEAVY, sts_h_delete},
    {STP_OP_COMPRESS, "COMPRESS", 1024, STS_H_MUTATING, sts_h_compress},
    {STP_OP_JOB_STATUS, "JOB_STATUS", 64, 0, sts_h_job_status},
    {STP_OP_JOB_CANCEL, "JOB_CANCEL", 64, STS_H_MUTATING, sts_h_job_cancel},
    {STP_OP_FETCH_OPEN, "FETCH_OPEN", 512, STS_H_HEAVY, sts_h_fetch_open},
    {STP_OP_FETCH_READ, "FETCH_READ", 64, 0, sts_h_fetch_read},
    {STP_OP_FETCH_CLOSE, "FETCH_CLOSE", 64, 0, sts_h_fetch_close},
};
#define NTABLE (sizeof TABLE / sizeof TABLE[0])

const sts_handler *sts_handler_find(unsigned op)
{
    for (size_t i = 0; i < NTABLE; i++)
        if (TABLE[i].op == op)
            return &TABLE[i];
    return NULL;
}

void sts_reply_error(stp_buf *out, const stp_header *h, int status, const char *msg)
{
    stp_enc_error(out, h->opcode, h->reqid, (uint16_t)status, msg ? msg : "");
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
    sts_reply_error(out, h, stp_status_from_st(st_code), msg && *msg ? msg : st_strerror(st_code));
}

int sts_dispatch(sts_io *io, sts_conn *conn, const stp_header *h, const uint8_t *body)
{
    sts_server *srv = io->srv;
    int64_t t0 = sts_opstats_now_us();   /* request parsed: its latency starts here */
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
        goto replied;
    }
    int heavy = (hd->flags & STS_H_HEAVY) != 0;
    if (hd->flags & STS_H_SIZED) {
        uint64_t per = h->opcode == STP_OP_SAMPLE ? STP_QUERY_SIZE : STP_DIR_QUERY_SIZE;
        heavy = h->body_len > (uint64_t)STS_LIVE(srv, heavy_batch) * per;
    }
    if (heavy) {
        sts_task *t = calloc(1, sizeof *t);
        if (!t) {
            sts_reply_error(&conn->out, h, STP_S_NOMEM, "out of memory");
            goto replied;
        }
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
    STS_STAT_ADD(srv, inline_tasks, 1);
    sts_ctx ctx = {srv, conn, &io->scratch, t0 / 1000};
    r = hd->fn(&ctx, h, body, &conn->out) ? 2 : 0;
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
