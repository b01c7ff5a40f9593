/* client/libconn.c - libseamtex's transport: connecting (with a timeout), HELLO, the
 * non-blocking socket driven by poll with deadlines and the interrupt hook (stc_set_interrupt:
 * asked on EINTR and every every_ms while a wait lasts), reading frames with the protocol's
 * incremental parser, the list of outstanding requests (so late replies of timed-out requests
 * are recognised and dropped), sticky errors, and the pipelined flush / get-reply calls.
 *
 * Does not own: request encodings (libcalls.c, libxfer.c use protocol/), printing (never).
 *
 * Why non-blocking + poll: every wait has a deadline, and while a flush waits for room to
 * write it also reads replies, so a client pipelining many requests never deadlocks against
 * a server that is blocked writing replies the client is not reading.
 */
#include "libseamtex_int.h"
#include "unixaddr.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define STC_DEFAULT_CONNECT_MS 5000
#define STC_DEFAULT_MAX_BODY   (256u << 20)
#define STC_READ_CHUNK         (64u << 10)

/* ---- errors ----------------------------------------------------------------------------------- */

static void vmsg(stc_conn *c, const char *fmt, va_list ap)
{
    vsnprintf(c->msg, sizeof c->msg, fmt, ap);
}

int stc__fail(stc_conn *c, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg(c, fmt, ap);
    va_end(ap);
    return code;
}

int stc__break(stc_conn *c, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vmsg(c, fmt, ap);
    va_end(ap);
    if (!c->sticky)
        c->sticky = code;
    return code;
}

/* seamtex.h spells the protocol's numbers out so that it needs no other header; each must be
 * the protocol's own (proto_lists.h, proto.h), so that adding or renumbering one there fails
 * to compile here until seamtex.h agrees. */
#define SAME_STATUS(NAME, value, client)                                                   \
    _Static_assert(STC_##client == (value ? -(STC_SERVER_BASE + value) : 0),               \
                   "STC_" #client " is not -(STC_SERVER_BASE + STP_S_" #NAME ")");
STP_STATUSES(SAME_STATUS)
#undef SAME_STATUS
_Static_assert(STC_EINTERRUPTED > -STC_SERVER_BASE, "local codes stay above the server's");
#define SAME(a, b) _Static_assert((int)(a) == (int)(b), #a " != " #b);
SAME(STC_CAP_PIPELINE, STP_CAP_PIPELINE)
SAME(STC_CAP_OUT_OF_ORDER, STP_CAP_OUT_OF_ORDER)
SAME(STC_CAP_SAMPLE_DIR, STP_CAP_SAMPLE_DIR)
SAME(STC_CAP_UPLOAD_RESUME, STP_CAP_UPLOAD_RESUME)
SAME(STC_CAP_COMPRESS, STP_CAP_COMPRESS)
SAME(STC_CAP_FETCH, STP_CAP_FETCH)
SAME(STC_CAP_PTEX_FILTERS, STP_CAP_PTEX_FILTERS)
SAME(STC_CAP_AUTH, STP_CAP_AUTH)
SAME(STC_CAP_COMPACT, STP_CAP_COMPACT)
SAME(STC_CAP_SHM, STP_CAP_SHM)
SAME(STC_CAP_LERP, STP_CAP_LERP)
SAME(STC_OUT_F32, STP_OUT_F32)
SAME(STC_OUT_UNORM8, STP_OUT_UNORM8)
SAME(STC_OUT_UNORM16, STP_OUT_UNORM16)
SAME(STC_WANT_COVERAGE, STP_SF_COVERAGE)
SAME(STC_WANT_STATUS, STP_SF_STATUS)
SAME(STC_UPLOAD_REPLACE, STP_UF_REPLACE)
SAME(STC_UPLOAD_RESUME, STP_UF_RESUME)
SAME(STC_COMPRESS_SEAM_AWARE, STP_CF_SEAM_AWARE)
SAME(STC_COMPRESS_REPLACE, STP_CF_REPLACE)
SAME(STC_JOB_QUEUED, STP_JOB_QUEUED)
SAME(STC_JOB_RUNNING, STP_JOB_RUNNING)
SAME(STC_JOB_DONE, STP_JOB_DONE)
SAME(STC_JOB_FAILED, STP_JOB_FAILED)
SAME(STC_JOB_CANCELED, STP_JOB_CANCELED)
SAME(STC_FETCH_PTX, STP_FETCH_PTX)
SAME(STC_FETCH_DDS, STP_FETCH_DDS)
SAME(STC_FETCH_EXR, STP_FETCH_EXR)
SAME(STC_FETCH_PNG, STP_FETCH_PNG)
SAME(STC_FETCH_OBJ, STP_FETCH_OBJ)
#undef SAME

const char *stc_strerror(int code)
{
    switch (code) {
    case STC_OK: return "OK";
#define X(NAME, value) case value: return #NAME;
    STC_LOCAL_ERRORS(X)
#undef X
    default:
        /* a server code: a status the protocol lists, OK (-STC_SERVER_BASE) not being one;
         * anything else, local or server, unknown: "?" (the protocol's own unknown name) */
        if (stc_is_server_error(code) && stc_server_status(code) > 0 &&
            stc_server_status(code) < STP_S_COUNT_)
            return stp_status_name((unsigned)stc_server_status(code));
        return "?";
    }
}

const char *stc_errmsg(const stc_conn *c)
{
    return c ? c->msg : "no connection";
}

int stc_error(const stc_conn *c)
{
    return c ? c->sticky : STC_EINVAL;
}

void stc_set_timeout(stc_conn *c, int timeout_ms)
{
    if (c)
        c->timeout_ms = timeout_ms > 0 ? timeout_ms : 0;
}

void stc_set_interrupt(stc_conn *c, stc_interrupt_fn fn, void *user, int every_ms)
{
    if (!c)
        return;
    c->intr.fn = fn;
    c->intr.user = fn ? user : NULL;
    c->intr.every_ms = fn && every_ms > 0 ? every_ms : 0;
}

const stc_server *stc_server_info(const stc_conn *c)
{
    return c ? &c->server : NULL;
}

size_t stc_pending(const stc_conn *c)
{
    return c ? c->npipelined : 0;
}

size_t stc_discard_pending(stc_conn *c)
{
    size_t n = 0;
    if (!c)
        return 0;
    for (size_t i = c->phead; i < c->pn; i++)
        if (c->pend[i].pipelined && !c->pend[i].abandoned) {
            c->pend[i].abandoned = 1;
            n++;
        }
    c->npipelined = 0;
    return n;
}

int stc__grow(void **p, size_t *cap, size_t need)
{
    void *q;
    if (need <= *cap)
        return 0;
    if (need < 64)
        need = 64;
    q = realloc(*p, need);
    if (!q)
        return STC_ENOMEM;
    *p = q;
    *cap = need;
    return 0;
}

int stc__enc_error(stc_conn *c, int st)
{
    if (st == STP_S_NOMEM)
        return stc__fail(c, STC_ENOMEM, "out of memory encoding the request");
    return stc__fail(c, STC_EINVAL, "request cannot be encoded: %s", stp_status_name((unsigned)st));
}

/* ---- time ---------------------------------------------------------------------------------------- */

int64_t stc__now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int64_t stc__deadline(int timeout_ms)
{
    return timeout_ms > 0 ? stc__now_ms() + timeout_ms : -1;
}

static int poll_wait_ms(int64_t deadline)
{
    int64_t left;
    if (deadline < 0)
        return -1;
    left = deadline - stc__now_ms();
    if (left < 0)
        return 0;
    return left > 1000000 ? 1000000 : (int)left;
}

int stc__interrupted(stc_intr *h)
{
    if (h->fn && h->fn(h->user)) {
        h->said = 1;
        return 1;
    }
    return 0;
}

/* stc__poll's body, inlined into the transport's own waits: the hot path (ready at once, or
 * a reply within the first poll) pays one test of h->fn before poll(2) and nothing after. */
static inline int wait_fd(stc_intr *h, struct pollfd *pfd, int64_t deadline)
{
    for (;;) {
        int ms = poll_wait_ms(deadline), capped = 0;
        if (h->fn && h->every_ms > 0 && (ms < 0 || ms > h->every_ms)) {
            ms = h->every_ms;
            capped = 1;
        }
        int pr = poll(pfd, 1, ms);
        if (pr > 0 || (pr == 0 && !capped))
            return pr;
        if (pr < 0 && errno != EINTR)
            return -1;
        /* a signal, or every_ms of waiting with the deadline still ahead */
        if (stc__interrupted(h))
            return STC_EINTERRUPTED;
    }
}

int stc__poll(stc_intr *h, struct pollfd *pfd, int64_t deadline)
{
    return wait_fd(h, pfd, deadline);
}

/* ---- call bookkeeping ------------------------------------------------------------------------- */

int stc__begin(stc_conn *c)
{
    if (!c)
        return STC_EINVAL;
    /* After fork the child holds the same socket (and shared-memory region) with the same
     * request ids: its requests and the parent's would interleave, each could read the
     * other's replies (wrong results through the region, ProtocolError for the parent). Only
     * stc_close of the copy is allowed there; it leaves the parent's connection alone. */
    if (c->forkpage ? !c->forkpage[0] : c->pid != (long)getpid())
        return stc__fail(c, STC_ESTATE, "this connection was opened by process %ld: a child "
                         "after fork must open its own (stc_close on the copy is fine)", c->pid);
    if (c->hold) {
        stp_buf_consume(&c->in, c->hold);
        c->hold = 0;
    }
    if (c->sticky)
        return c->sticky;   /* keep the message that broke it */
    c->msg[0] = 0;
    c->intr.said = 0;
    return 0;
}

int stc__begin_blocking(stc_conn *c)
{
    int rc = stc__begin(c);
    if (rc)
        return rc;
    if (c->npipelined)
        return stc__fail(c, STC_ESTATE, "%zu pipelined replies are unread: read them with "
                         "stc_get_reply before a blocking call", c->npipelined);
    return 0;
}

uint32_t stc__next_reqid(stc_conn *c)
{
    uint32_t id = c->next_reqid++;
    if (c->next_reqid == 0)
        c->next_reqid = 1;
    return id;
}

int stc__pend_add(stc_conn *c, uint32_t reqid, uint8_t opcode, int pipelined)
{
    if (c->phead && c->phead == c->pn)
        c->phead = c->pn = 0;
    if (c->pn == c->pcap) {
        if (c->phead > c->pcap / 2) {
            memmove(c->pend, c->pend + c->phead, (c->pn - c->phead) * sizeof *c->pend);
            c->pn -= c->phead;
            c->phead = 0;
        } else {
            size_t ncap = c->pcap ? c->pcap * 2 : 64;
            stc_pend *p = realloc(c->pend, ncap * sizeof *p);
            if (!p)
                return stc__fail(c, STC_ENOMEM, "out of memory tracking requests");
            c->pend = p;
            c->pcap = ncap;
        }
    }
    c->pend[c->pn].reqid = reqid;
    c->pend[c->pn].opcode = opcode;
    c->pend[c->pn].abandoned = 0;
    c->pend[c->pn].pipelined = (uint8_t)(pipelined != 0);
    c->pend[c->pn].shm = 0;
    c->pn++;
    if (pipelined)
        c->npipelined++;
    return 0;
}

static size_t pend_find(const stc_conn *c, uint32_t reqid)
{
    for (size_t i = c->phead; i < c->pn; i++)
        if (c->pend[i].reqid == reqid)
            return i;
    return SIZE_MAX;
}

static void pend_remove(stc_conn *c, size_t i)
{
    if (c->pend[i].pipelined && !c->pend[i].abandoned)
        c->npipelined--;
    if (i == c->phead) {
        c->phead++;
    } else {
        memmove(c->pend + i, c->pend + i + 1, (c->pn - i - 1) * sizeof *c->pend);
        c->pn--;
    }
}

void stc__pend_drop_last(stc_conn *c)
{
    if (c->pn > c->phead) {
        stc__shm_unplace(c, &c->pend[c->pn - 1]);
        if (c->pend[c->pn - 1].pipelined)
            c->npipelined--;
        c->pn--;
    }
}

void stc__pend_abandon(stc_conn *c, uint32_t reqid)
{
    size_t i = pend_find(c, reqid);
    if (i == SIZE_MAX || c->pend[i].abandoned)
        return;
    if (c->pend[i].pipelined)
        c->npipelined--;
    c->pend[i].abandoned = 1;
}

/* ---- socket I/O ---------------------------------------------------------------------------------- */

/* Reads what is available (at most one recv, offered room for `want` more bytes, at least
 * STC_READ_CHUNK: a reply whose size is known comes in one recv when it is all there). 0 on
 * progress, 1 when it would block. */
static int read_some(stc_conn *c, size_t want)
{
    ssize_t n;
    if (stp_buf_reserve(&c->in, want > STC_READ_CHUNK ? want : STC_READ_CHUNK) != 0) {
        c->in.err = 0;
        return stc__break(c, STC_ENOMEM, "out of memory for the receive buffer");
    }
    n = recv(c->fd, c->in.data + c->in.len, c->in.cap - c->in.len, MSG_DONTWAIT);
    if (n > 0) {
        c->in.len += (size_t)n;
        return 0;
    }
    if (n == 0)
        return stc__break(c, STC_ECLOSED, "the server closed the connection");
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
        return 1;
    return stc__break(c, STC_EIO, "recv: %s", strerror(errno));
}

int stc__flush(stc_conn *c, int64_t deadline)
{
    while (stp_buf_avail(&c->out)) {
        ssize_t n = send(c->fd, stp_buf_head(&c->out), stp_buf_avail(&c->out),
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0) {
            stp_buf_consume(&c->out, (size_t)n);
            continue;
        }
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)
            return stc__break(c, errno == EPIPE || errno == ECONNRESET ? STC_ECLOSED : STC_EIO,
                              "send: %s", strerror(errno));
        /* Would block: wait for room, and keep reading so the server is never stuck writing
         * replies to us while we are stuck writing requests to it. */
        struct pollfd pfd = { c->fd, POLLOUT | POLLIN, 0 };
        int pr = wait_fd(&c->intr, &pfd, deadline);
        if (pr == STC_EINTERRUPTED || pr == 0)
            return stc__fail(c, pr ? pr : STC_ETIMEDOUT, "%s sending (%zu bytes queued)",
                             pr ? "interrupted" : "timed out", stp_buf_avail(&c->out));
        if (pr < 0)
            return stc__break(c, STC_EIO, "poll: %s", strerror(errno));
        if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
            int rc = read_some(c, 0);
            if (rc < 0)
                return rc;
        }
    }
    return 0;
}

/* Makes sure at least `need` unconsumed bytes sit in c->in (c->hold is 0 here). Polls
 * before reading: right after a request was sent its reply is rarely there yet, so trying
 * recv first would cost a wasted syscall per round trip. */
static int fill(stc_conn *c, size_t need, int64_t deadline)
{
    while (stp_buf_avail(&c->in) < need) {
        /* Also push out queued requests while waiting (an append may have left some). */
        struct pollfd pfd = { c->fd, POLLIN | (stp_buf_avail(&c->out) ? POLLOUT : 0), 0 };
        int pr = wait_fd(&c->intr, &pfd, deadline);
        if (pr == STC_EINTERRUPTED)
            return pr;
        if (pr < 0)
            return stc__break(c, STC_EIO, "poll: %s", strerror(errno));
        if (pr == 0)
            return STC_ETIMEDOUT;
        if ((pfd.revents & POLLOUT) && stp_buf_avail(&c->out)) {
            ssize_t n = send(c->fd, stp_buf_head(&c->out), stp_buf_avail(&c->out),
                             MSG_NOSIGNAL | MSG_DONTWAIT);
            if (n > 0)
                stp_buf_consume(&c->out, (size_t)n);
            else if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                return stc__break(c, errno == EPIPE || errno == ECONNRESET ? STC_ECLOSED
                                  : STC_EIO, "send: %s", strerror(errno));
        }
        if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
            int rc = read_some(c, need - stp_buf_avail(&c->in));
            if (rc < 0)
                return rc;
        }
    }
    return 0;
}

/* Reads the next whole frame. Oversized bodies are dropped as they arrive. */
static int next_frame(stc_conn *c, int64_t deadline, stc_frame *f)
{
    int reason, pr, rc;
    for (;;) {
        while (c->skip) {
            size_t have = stp_buf_avail(&c->in);
            if (have == 0) {
                rc = fill(c, 1, deadline);
                if (rc)
                    return rc;
                continue;
            }
            size_t n = have < c->skip ? have : (size_t)c->skip;
            stp_buf_consume(&c->in, n);
            c->skip -= n;
        }
        pr = stp_parse_header(stp_buf_head(&c->in), stp_buf_avail(&c->in), c->max_body, &f->h,
                              &reason);
        if (pr == STP_NEED_MORE) {
            rc = fill(c, STP_HEADER_SIZE, deadline);
            if (rc)
                return rc;
            continue;
        }
        if (pr == STP_BAD && reason != STP_R_TOO_LARGE)
            return stc__break(c, STC_EPROTO, "bad reply header: %s", stp_reason_name(reason));
        if (!(f->h.flags & STP_F_REPLY))
            return stc__break(c, STC_EPROTO, "the server sent a frame without the REPLY flag");
        if (pr == STP_BAD) {
            /* Too large for us: drop the body, report it for that request. */
            stp_buf_consume(&c->in, STP_HEADER_SIZE);
            c->skip = f->h.body_len;
            f->body = NULL;
            f->oversized = 1;
            return 0;
        }
        rc = fill(c, STP_HEADER_SIZE + (size_t)f->h.body_len, deadline);
        if (rc)
            return rc;
        f->body = stp_buf_head(&c->in) + STP_HEADER_SIZE;
        f->oversized = 0;
        return 0;
    }
}

int stc__wait(stc_conn *c, uint32_t reqid, int reqid_any, int64_t deadline, stc_frame *f)
{
    /* Waiting for another reply releases the one held from before (callers copy out what
     * they need first). */
    if (c->hold) {
        stp_buf_consume(&c->in, c->hold);
        c->hold = 0;
    }
    f->oversized = 0;
    for (;;) {
        int rc = next_frame(c, deadline, f);
        size_t i, flen;
        if (stc__gave_up(rc)) {
            if (!reqid_any)
                stc__pend_abandon(c, reqid);
            return stc__fail(c, rc, "%s%s", rc == STC_ETIMEDOUT ? "no reply within the timeout"
                             : "interrupted waiting for the reply",
                             reqid_any ? "" : " (the request is abandoned; its reply will be "
                             "dropped when it comes)");
        }
        if (rc)
            return rc;
        flen = f->oversized ? 0 : STP_HEADER_SIZE + (size_t)f->h.body_len;
        i = pend_find(c, f->h.reqid);
        if (i == SIZE_MAX) {
            /* An unsolicited error (reqid 0, e.g. BUSY before closing) breaks the
             * connection with that status; anything else is a protocol violation. */
            if (f->h.status != 0 && !f->oversized) {
                char m[STP_MAX_MSG + 1];
                stp_dec_error(f->body, f->h.body_len, m, sizeof m);
                stp_buf_consume(&c->in, flen);
                return stc__break(c, -(STC_SERVER_BASE + (int)f->h.status), "server: %s%s%s",
                                  stp_status_name(f->h.status), m[0] ? ": " : "", m);
            }
            return stc__break(c, STC_EPROTO, "reply for request id %u that is not outstanding",
                              (unsigned)f->h.reqid);
        }
        if (f->h.opcode != c->pend[i].opcode)
            return stc__break(c, STC_EPROTO, "reply opcode 0x%02x for a 0x%02x request",
                              f->h.opcode, c->pend[i].opcode);
        if (c->pend[i].abandoned || (!reqid_any && f->h.reqid != reqid)) {
            if (!c->pend[i].abandoned && !reqid_any)
                return stc__break(c, STC_EPROTO, "reply out of order (request id %u)",
                                  (unsigned)f->h.reqid);
            if ((rc = stc__shm_reply(c, &c->pend[i], f, 1)) != 0)
                return rc;
            pend_remove(c, i);
            stp_buf_consume(&c->in, flen);
            continue;
        }
        if (!f->oversized && (rc = stc__shm_reply(c, &c->pend[i], f, 0)) != 0)
            return rc;
        pend_remove(c, i);
        c->hold = flen;
        if (f->oversized)
            return stc__fail(c, STC_ENOMEM, "reply body of %u bytes is over the client's cap "
                             "of %u (dropped)", (unsigned)f->h.body_len, (unsigned)c->max_body);
        return 0;
    }
}

int stc__in_holds(const stc_conn *c, const uint8_t *body, size_t len)
{
    const uint8_t *p = stp_buf_head(&c->in);
    return c->hold && body >= p && (size_t)(body - p) <= c->hold &&
           len <= c->hold - (size_t)(body - p);
}

int stc__status_error(stc_conn *c, const stc_frame *f)
{
    char m[STP_MAX_MSG + 1];
    stp_dec_error(f->body, f->h.body_len, m, sizeof m);
    return stc__fail(c, -(STC_SERVER_BASE + (int)f->h.status), "%s: %s%s%s",
                     stp_opcode_name(f->h.opcode) ? stp_opcode_name(f->h.opcode) : "request",
                     stp_status_name(f->h.status), m[0] ? ": " : "", m);
}

/* ---- pipelined API ------------------------------------------------------------------------ */

int stc_flush(stc_conn *c)
{
    int rc = stc__begin(c);
    if (rc)
        return rc;
    return stc__flush(c, stc__deadline(c->timeout_ms));
}

int stc_get_reply(stc_conn *c, int timeout_ms, stc_reply *r)
{
    stc_frame f;
    int rc = stc__begin(c);
    f.oversized = 0;
    if (rc)
        return rc;
    if (!r)
        return stc__fail(c, STC_EINVAL, "reply is NULL");
    if (c->npipelined == 0)
        return stc__fail(c, STC_ESTATE, "no pipelined request is outstanding");
    int64_t dl = timeout_ms > 0 ? stc__deadline(timeout_ms)
                 : timeout_ms == 0 ? stc__now_ms() : stc__deadline(c->timeout_ms);
    /* a flush that times out (the server is not reading yet) still lets a reply that is
     * already there be returned: the server may be waiting for us to read it */
    rc = stc__flush(c, dl);
    if (rc && rc != STC_ETIMEDOUT)
        return rc;
    rc = stc__wait(c, 0, 1, dl, &f);
    if (rc && !(rc == STC_ENOMEM && f.oversized))
        return rc;
    memset(r, 0, sizeof *r);
    r->reqid = f.h.reqid;
    r->opcode = f.h.opcode;
    r->errmsg = "";
    if (rc) {                       /* oversized: the request failed, the connection is fine */
        r->status = rc;
        r->errmsg = c->msg;
        return 0;
    }
    if (f.h.status) {
        stc__status_error(c, &f);
        r->status = -(STC_SERVER_BASE + (int)f.h.status);
        snprintf(c->reply_msg, sizeof c->reply_msg, "%s", c->msg);
        r->errmsg = c->reply_msg;
        c->msg[0] = 0;
        return 0;
    }
    r->body = f.body;
    r->body_len = f.h.body_len;
    return 0;
}

/* ---- connecting ------------------------------------------------------------------------------- */

/* The connected descriptor; -1 (a failure), -2 (the deadline passed) or -3 (the hook said
 * stop) with the reason in err. */
static int connect_one(const struct addrinfo *ai, int64_t deadline, stc_intr *h, char *err,
                       size_t errlen)
{
    int fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                    ai->ai_protocol);
    if (fd < 0) {
        snprintf(err, errlen, "socket: %s", strerror(errno));
        return -1;
    }
    if (connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
        if (errno != EINPROGRESS) {
            snprintf(err, errlen, "connect: %s", strerror(errno));
            close(fd);
            return -1;
        }
        struct pollfd pfd = { fd, POLLOUT, 0 };
        int pr = wait_fd(h, &pfd, deadline);
        if (pr <= 0) {
            snprintf(err, errlen, pr == 0 ? "connect: timed out" : pr == STC_EINTERRUPTED
                     ? "connect: interrupted" : "poll: %s", strerror(errno));
            close(fd);
            return pr == 0 ? -2 : pr == STC_EINTERRUPTED ? -3 : -1;
        }
        int soerr = 0;
        socklen_t sl = sizeof soerr;
        if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) != 0 || soerr != 0) {
            snprintf(err, errlen, "connect: %s", strerror(soerr ? soerr : errno));
            close(fd);
            return -1;
        }
    }
    int one = 1;
    if (ai->ai_family != AF_UNIX)
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    else
        stu_unix_sndbuf(fd);   /* a big request in one write (unixaddr.h) */
    return fd;
}

static void defaults_server(stc_server *s)
{
    memset(s, 0, sizeof *s);
    s->version = STP_VERSION;
    s->caps = STP_CAP_PIPELINE;
    s->max_body = STP_DEFAULT_MAX_BODY;
    s->max_batch = STP_DEFAULT_MAX_BATCH;
    s->max_chunk = STP_DEFAULT_MAX_CHUNK;
    s->max_inflight = 64;
}

static int hello(stc_conn *c, const stc_opts *o, int64_t deadline)
{
    stp_hello_req rq;
    stp_hello_reply rp;
    stc_frame f;
    const char *why = "";
    uint32_t id = stc__next_reqid(c);
    int rc;

    memset(&rq, 0, sizeof rq);
    rq.min_version = rq.max_version = STP_VERSION;
    rq.caps = STP_CAP_PIPELINE | STP_CAP_OUT_OF_ORDER | STP_CAP_SAMPLE_DIR | STP_CAP_COMPRESS |
              STP_CAP_FETCH | STP_CAP_PTEX_FILTERS;
    if (o && o->token) {
        if (strlen(o->token) > STP_MAX_TOKEN)
            return stc__fail(c, STC_EINVAL, "token longer than %d bytes", STP_MAX_TOKEN);
        snprintf(rq.token, sizeof rq.token, "%s", o->token);
    }
    snprintf(rq.client_name, sizeof rq.client_name, "%.200s",
             o && o->client_name ? o->client_name : "libseamtex");
    rc = stp_enc_hello_req(&c->out, id, 0, &rq);
    if (rc)
        return stc__enc_error(c, rc);
    if ((rc = stc__pend_add(c, id, STP_OP_HELLO, 0)) != 0 || (rc = stc__flush(c, deadline)) != 0)
        return rc;
    rc = stc__wait(c, id, 0, deadline, &f);
    if (stc__gave_up(rc))           /* stc_connect_opts closes it: no late reply to drop */
        return stc__fail(c, rc, "%s (the connection is closed)", rc == STC_ETIMEDOUT
                         ? "no reply within the connect timeout" : "interrupted");
    if (rc)
        return rc;
    if (f.h.status == STP_S_UNKNOWN_OPCODE)
        return 0;                   /* a server without HELLO: version 1 defaults */
    if (f.h.status)
        return stc__status_error(c, &f);
    if (stp_dec_hello_reply(f.body, f.h.body_len, &rp, &why) != 0)
        return stc__break(c, STC_EPROTO, "%s", why);
    if (rp.version != STP_VERSION)
        return stc__break(c, STC_EPROTO, "the server chose version %u", rp.version);
    c->server.version = rp.version;
    c->server.caps = rp.caps;
    c->server.max_body = rp.max_body;
    c->server.max_batch = rp.max_batch;
    c->server.max_chunk = rp.max_chunk;
    c->server.max_inflight = rp.max_inflight;
    c->server.authenticated = rp.authenticated;
    snprintf(c->server.name, sizeof c->server.name, "%s", rp.server_name);
    return 0;
}

/* c->forkpage: one page that a fork gives the child zeroed, so that stc__begin tells a child
 * from the connecting process by a load instead of a getpid system call (without
 * MADV_WIPEONFORK, Linux before 4.14: NULL, and getpid it is). */
static void fork_guard(stc_conn *c)
{
    long pg = sysconf(_SC_PAGESIZE);
    size_t len = pg > 0 ? (size_t)pg : 4096;
    void *p = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    c->forkpage = NULL;
    if (p == MAP_FAILED)
        return;
#ifdef MADV_WIPEONFORK
    if (madvise(p, len, MADV_WIPEONFORK) == 0) {
        ((uint8_t *)p)[0] = 1;
        c->forkpage = p;
        return;
    }
#endif
    munmap(p, len);
}

stc_conn *stc_connect_opts(const char *host, unsigned port, const stc_opts *o, int *err,
                           char *errmsg, size_t errmsg_len)
{
    struct addrinfo hints, *res = NULL, *ai;
    char portstr[16], why[512] = "";
    int64_t deadline;
    int ctmo, fd = -1, rc, timed_out = 0;
    stc_intr intr = { o ? o->interrupt : NULL, o && o->interrupt ? o->interrupt_user : NULL,
                      o && o->interrupt && o->interrupt_every_ms > 0 ? o->interrupt_every_ms
                      : 0, 0 };
    stc_conn *c;

    if (err)
        *err = 0;
    if (errmsg && errmsg_len)
        errmsg[0] = 0;
#define CONNECT_FAIL(code, ...) do { \
        if (err) *err = (code); \
        if (errmsg && errmsg_len) snprintf(errmsg, errmsg_len, __VA_ARGS__); \
        return NULL; } while (0)

    if (stu_is_unix_addr(host)) {
        struct sockaddr_un sa;
        socklen_t salen;
        struct addrinfo uai;
        if (stu_unix_addr(host, &sa, &salen) != 0)
            CONNECT_FAIL(STC_EINVAL, "%s: %s", host, errno == ENAMETOOLONG
                         ? "path too long for a Unix socket" : "unix: needs a path");
        ctmo = o && o->connect_timeout_ms ? o->connect_timeout_ms : STC_DEFAULT_CONNECT_MS;
        deadline = stc__deadline(ctmo);
        memset(&uai, 0, sizeof uai);
        uai.ai_family = AF_UNIX;
        uai.ai_socktype = SOCK_STREAM;
        uai.ai_addr = (struct sockaddr *)&sa;
        uai.ai_addrlen = salen;
        fd = connect_one(&uai, deadline, &intr, why, sizeof why);
        if (fd < 0)
            CONNECT_FAIL(fd == -2 ? STC_ETIMEDOUT : fd == -3 ? STC_EINTERRUPTED : STC_ECONNECT,
                         "%s: %s", host, why);
        goto connected;
    }
    if (!host || !host[0] || port == 0 || port > 65535)
        CONNECT_FAIL(STC_EINVAL, "bad host or port");
    ctmo = o && o->connect_timeout_ms ? o->connect_timeout_ms : STC_DEFAULT_CONNECT_MS;
    deadline = stc__deadline(ctmo);

    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    snprintf(portstr, sizeof portstr, "%u", port);
    rc = getaddrinfo(host, portstr, &hints, &res);
    if (rc != 0)
        CONNECT_FAIL(STC_ECONNECT, "cannot resolve %s: %s", host, gai_strerror(rc));
    for (ai = res; ai; ai = ai->ai_next) {
        fd = connect_one(ai, deadline, &intr, why, sizeof why);
        if (fd >= 0)
            break;
        if (fd == -2 || fd == -3) {
            timed_out = fd;
            break;
        }
    }
    freeaddrinfo(res);
    if (fd < 0)
        CONNECT_FAIL(timed_out == -2 ? STC_ETIMEDOUT : timed_out == -3 ? STC_EINTERRUPTED
                     : STC_ECONNECT, "%s:%u: %s", host, port, why);

connected:
    c = calloc(1, sizeof *c);
    if (!c) {
        close(fd);
        CONNECT_FAIL(STC_ENOMEM, "out of memory");
    }
    c->fd = fd;
    c->pid = (long)getpid();
    fork_guard(c);
    c->next_reqid = 1;
    c->timeout_ms = o && o->request_timeout_ms > 0 ? o->request_timeout_ms : 0;
    c->max_body = o && o->max_body ? o->max_body : STC_DEFAULT_MAX_BODY;
    c->intr = intr;
    stp_buf_init(&c->out);
    stp_buf_init(&c->in);
    defaults_server(&c->server);
    if (!(o && o->no_hello)) {
        rc = hello(c, o, deadline);
        if (rc) {
            if (err)
                *err = rc;
            if (errmsg && errmsg_len)
            {
                char where[160];
                if (stu_is_unix_addr(host))
                    snprintf(where, sizeof where, "%.150s", host);
                else
                    snprintf(where, sizeof where, "%.140s:%u", host, port);
                snprintf(errmsg, errmsg_len, "%s: HELLO: %s", where, c->msg);
            }
            stc_close(c);
            return NULL;
        }
        stc__begin(c);              /* release the HELLO reply */
    }
    return c;
#undef CONNECT_FAIL
}

stc_conn *stc_connect(const char *host, unsigned port, int timeout_ms, int *err)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = timeout_ms;
    return stc_connect_opts(host, port, &o, err, NULL, 0);
}

void stc_close(stc_conn *c)
{
    if (!c)
        return;
    if (c->fd >= 0)
        close(c->fd);
    stp_buf_free(&c->out);
    stp_buf_free(&c->in);
    free(c->pend);
    free(c->vals);
    free(c->cov);
    free(c->qst);
    free(c->sets);
    free(c->names);
    free(c->stats);
    free(c->faces);
    stc__shm_free(c);
    if (c->forkpage) {
        long pg = sysconf(_SC_PAGESIZE);
        munmap((void *)c->forkpage, pg > 0 ? (size_t)pg : 4096);
    }
    free(c);
}
