/* client/libshm.c - libseamtex's shared-memory sampling (PROTOCOL.md 4.12; stc_shm_attach in
 * seamtex.h).
 *
 * Owns: the connection's region (a sealed memfd, mapped; util/shmfd.c makes it), SHM_ATTACH,
 * and a ring of spans in it: each shared-memory SAMPLE takes one span, its queries followed
 * by a disjoint reply room (so the server samples in place, PROTOCOL.md 4.12), and gives it
 * back after its reply was read (held until the next call, so the caller may read the reply
 * where it lies) or dropped; stc_shm_reserve hands a span out for the caller to write its
 * queries into, stc_shm_append (libcalls.c) sends it. Replies come in request order (the library uses
 * the region only with a server that does not offer OUT_OF_ORDER), so spans are given back in
 * the order they were taken and the ring needs no more than a head, a tail and a count.
 * Does not own: the frames (protocol/), pending-request bookkeeping (libconn.c), decoding the
 * reply (libcalls.c decodes the 4.6 body wherever it lies).
 *
 * The server is not trusted either: the offset and length of each reply are checked against
 * the span of its request before the body is looked at (a reply outside it is EPROTO).
 */
#include "libseamtex_int.h"
#include "shmfd.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#define SHM_DEFAULT (64u << 20)
#define SHM_ALIGN   64u          /* spans start on cache lines */

void stc_shm_counts(const stc_conn *c, uint64_t *via_shm, uint64_t *via_socket)
{
    if (via_shm)
        *via_shm = c ? c->shm_n : 0;
    if (via_socket)
        *via_socket = c ? c->sock_n : 0;
}

void stc__shm_free(stc_conn *c)
{
    if (c->shm)
        munmap(c->shm, c->shm_size);
    c->shm = NULL;
}

/* Sends one frame with the descriptor on its first byte; the rest (a partial sendmsg) is
 * queued in c->out. 0 or a sticky error. */
static int send_with_fd(stc_conn *c, const stp_buf *b, int fd, int64_t deadline)
{
    for (;;) {
        ssize_t n = stu_send_with_fd(c->fd, stp_buf_head(b), stp_buf_avail(b), fd);
        if (n >= 0) {
            stp_put_bytes(&c->out, stp_buf_head(b) + n, stp_buf_avail(b) - (size_t)n);
            return c->out.err ? stc__break(c, STC_ENOMEM, "out of memory") : 0;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK)
            return stc__break(c, STC_EIO, "sendmsg: %s", strerror(errno));
        struct pollfd p = { c->fd, POLLOUT, 0 };
        int pr = stc__poll(&c->intr, &p, deadline);
        if (pr == 0)
            return stc__break(c, STC_ETIMEDOUT, "SHM_ATTACH could not be sent in time");
        if (pr == STC_EINTERRUPTED) {       /* nothing of it was sent: forget it */
            stc__pend_drop_last(c);
            return stc__fail(c, pr, "interrupted sending SHM_ATTACH");
        }
        if (pr < 0)
            return stc__break(c, STC_EIO, "poll: %s", strerror(errno));
    }
}

int stc_shm_attach(stc_conn *c, size_t bytes)
{
    int rc = stc__begin_blocking(c);
    if (rc)
        return rc;
    struct sockaddr_storage sa;
    socklen_t salen = sizeof sa;
    if (getsockname(c->fd, (struct sockaddr *)&sa, &salen) != 0 || sa.ss_family != AF_UNIX)
        return stc__fail(c, STC_EINVAL, "shared memory needs a Unix-socket connection "
                         "(unix:/path)");
    if (c->shm)
        return stc__fail(c, STC_ESTATE, "a shared-memory region is attached already");
    if (!(c->server.caps & STP_CAP_SHM) || (c->server.caps & STP_CAP_OUT_OF_ORDER))
        return stc__fail(c, STC_EUNSUPPORTED, "the server does not offer shared-memory "
                         "sampling (HELLO capability SHM)");
    if (!bytes)
        bytes = SHM_DEFAULT;
    int mfd = -1;
    void *map = NULL;
    if (stu_memfd_sealed("libseamtex", bytes, &mfd, &map) != 0)
        return stc__fail(c, errno == EINVAL ? STC_EINVAL : STC_ENOMEM,
                         "shared-memory region of %zu bytes: %s", bytes, strerror(errno));
    int64_t dl = stc__deadline(c->timeout_ms);
    uint32_t id = stc__next_reqid(c);
    stp_buf b;
    stp_buf_init(&b);
    stc_frame f;
    uint64_t size = 0;
    const char *why = NULL;
    if ((rc = stc__flush(c, dl)) != 0)
        goto out;
    if (stp_enc_id_req(&b, STP_OP_SHM_ATTACH, id, (uint32_t)c->timeout_ms, bytes) != 0) {
        rc = stc__fail(c, STC_ENOMEM, "out of memory");
        goto out;
    }
    if ((rc = stc__pend_add(c, id, STP_OP_SHM_ATTACH, 0)) != 0)
        goto out;
    if ((rc = send_with_fd(c, &b, mfd, dl)) != 0 || (rc = stc__flush(c, dl)) != 0 ||
        (rc = stc__wait(c, id, 0, dl, &f)) != 0) {
        if (stc__gave_up(rc))
            stc__pend_abandon(c, id);
        goto out;
    }
    if (f.h.status) {
        rc = stc__status_error(c, &f);
        goto out;
    }
    if (stp_dec_id_reply(f.body, f.h.body_len, &size, &why) != 0 || size != bytes) {
        rc = stc__break(c, STC_EPROTO, "malformed SHM_ATTACH reply");
        goto out;
    }
    c->shm = map;
    c->shm_size = bytes;
    c->shm_head = c->shm_tail = c->shm_used = 0;
    map = NULL;
out:
    stp_buf_free(&b);
    close(mfd);               /* the server has its own descriptor (or none: refused) */
    if (map)
        munmap(map, bytes);
    return rc;
}

/* ---- the ring ------------------------------------------------------------------------------ */

/* Gives back the span of the last reply read (held while the caller read it in place). */
static void release_kept(stc_conn *c)
{
    if (!c->shm_kept_span)
        return;
    c->shm_tail = c->shm_kept_at + c->shm_kept_span;
    if (c->shm_tail > c->shm_size)
        c->shm_tail -= c->shm_size;
    c->shm_used -= c->shm_kept_span;
    c->shm_kept_span = 0;
    if (c->shm_used == 0)
        c->shm_head = c->shm_tail = 0;
}

/* Takes need bytes: *off where they start, *span what the ring gives (need, plus the end of
 * the ring skipped when it wraps), *at where the span starts. 0 when there is no room. */
static int ring_take(stc_conn *c, uint64_t need, uint64_t *at, uint64_t *off, uint64_t *span)
{
    release_kept(c);             /* a new request: the last reply's results are let go */
    uint64_t size = c->shm_size;
    if (c->shm_used == 0)
        c->shm_head = c->shm_tail = 0;
    uint64_t head = c->shm_head, tail = c->shm_tail;
    if (need == 0 || need > size)
        return 0;
    if (c->shm_used == 0 || head > tail) {          /* free: [head, size) and [0, tail) */
        if (size - head >= need) {
            *off = head;
            *span = need;
        } else if (tail >= need) {
            *off = 0;
            *span = size - head + need;
        } else {
            return 0;
        }
    } else if (head < tail && tail - head >= need) { /* free: [head, tail) */
        *off = head;
        *span = need;
    } else {
        return 0;
    }
    *at = head;
    c->shm_head = *off + need;
    c->shm_used += *span;
    return 1;
}

static uint64_t align_up(uint64_t v)
{
    return (v + SHM_ALIGN - 1) / SHM_ALIGN * SHM_ALIGN;
}

/* Room for a request: its queries, then (disjoint, so the server samples in place) its reply
 * room sized for 4 channels. 0 when it does not fit. */
static int take_room(stc_conn *c, uint8_t opcode, uint8_t flags, uint8_t outfmt, uint32_t n,
                     uint64_t *at, uint64_t *span, uint64_t *qoff, uint64_t *roff,
                     uint64_t *rcap)
{
    uint64_t q = align_up(stp_sample_query_bytes(opcode, flags, n));
    uint64_t rep = stp_sample_reply_bytes(n, 4, outfmt, flags);
    if (!c->shm || !rep || !ring_take(c, q + align_up(rep), at, qoff, span))
        return 0;
    *roff = *qoff + q;
    *rcap = align_up(rep);
    return 1;
}

size_t stc_shm_request_bytes(int dir, size_t n, unsigned outfmt)
{
    if (n == 0 || n > UINT32_MAX || outfmt > UINT8_MAX)
        return 0;
    uint8_t op = dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE;
    uint64_t q = align_up(stp_sample_query_bytes(op, 0, (uint32_t)n));
    uint64_t rep = stp_sample_reply_bytes((uint32_t)n, 4, (uint8_t)outfmt,
                                          STP_SF_COVERAGE | STP_SF_STATUS);
    if (!rep)                       /* an unknown outfmt */
        return 0;
    rep = align_up(rep);
    return q + rep > SIZE_MAX ? 0 : (size_t)(q + rep);
}

/* The last pending request holds the span. */
static void hold_span(stc_conn *c, uint64_t at, uint64_t span, uint64_t roff, uint64_t rcap)
{
    stc_pend *p = &c->pend[c->pn - 1];
    p->shm = 1;
    p->shm_at = at;
    p->shm_span = span;
    p->shm_off = roff;
    p->shm_len = rcap;
    c->shm_n++;
}

int stc__shm_place(stc_conn *c, uint8_t opcode, stp_sample_req *r)
{
    uint64_t at = 0, span = 0, qoff = 0, roff = 0, rcap = 0;
    /* an open reservation is the next span in the ring: other requests go over the socket */
    if (c->shm_resv.open || c->pn == c->phead ||
        !take_room(c, opcode, r->p.flags, r->p.outfmt, r->count, &at, &span, &qoff, &roff,
                   &rcap)) {
        c->sock_n++;
        return 0;
    }
    stp_put_queries(opcode, r, c->shm + qoff);
    r->p.flags |= STP_SF_SHM;
    r->shm.query_off = qoff;
    r->shm.reply_off = roff;
    r->shm.reply_cap = rcap;
    hold_span(c, at, span, roff, rcap);
    return 1;
}

void stc__shm_unplace(stc_conn *c, stc_pend *p)
{
    if (!p->shm)
        return;
    c->shm_head = p->shm_at;         /* it was the last span taken */
    c->shm_used -= p->shm_span;
    p->shm = 0;
    c->shm_n--;
}

int stc__shm_reply(stc_conn *c, const stc_pend *p, stc_frame *f, int drop)
{
    release_kept(c);
    if (!p->shm)
        return 0;
    if (p->shm_at != c->shm_tail)
        return stc__break(c, STC_EPROTO, "shared-memory reply out of request order");
    /* held until the next call: the caller may read the reply where it lies */
    c->shm_kept_at = p->shm_at;
    c->shm_kept_span = p->shm_span;
    if (drop || f->h.status != 0) {
        release_kept(c);
        return 0;
    }
    stp_shm_reply r;
    const char *why = NULL;
    if (stp_dec_shm_reply(f->body, f->h.body_len, &r, &why) != 0)
        return stc__break(c, STC_EPROTO, "malformed reply: %s", why);
    if (r.offset != p->shm_off || r.length > p->shm_len)
        return stc__break(c, STC_EPROTO, "shared-memory reply at [%llu, +%llu) is outside the "
                          "request's room [%llu, +%llu)", (unsigned long long)r.offset,
                          (unsigned long long)r.length, (unsigned long long)p->shm_off,
                          (unsigned long long)p->shm_len);
    f->body = c->shm + r.offset;
    f->h.body_len = (uint32_t)r.length;
    return 0;
}

int stc__shm_holds(const stc_conn *c, const uint8_t *body, size_t len)
{
    return c->shm && body >= c->shm && (size_t)(body - c->shm) <= c->shm_size &&
           len <= c->shm_size - (size_t)(body - c->shm);
}

/* ---- zero-copy requests ------------------------------------------------------------------- */

int stc_shm_reserve(stc_conn *c, const char *set, const stc_sample_opts *o, int dir, size_t n,
                    void **queries)
{
    int rc = stc__begin(c);
    if (rc)
        return rc;
    if (!queries)
        return stc__fail(c, STC_EINVAL, "queries is NULL");
    *queries = NULL;
    if (!c->shm)
        return stc__fail(c, STC_ESTATE, "no shared-memory region (stc_shm_attach first)");
    if (c->shm_resv.open)
        return stc__fail(c, STC_ESTATE, "a reservation is open: send it (stc_shm_append, "
                         "stc_shm_sample) or cancel it");
    stp_sample_params p;
    if ((rc = stc__fill_params(c, set, o, n, &p)) != 0)
        return rc;
    if (dir && (p.flags & (STP_SF_UV16 | STP_SF_FACE16)))
        return stc__fail(c, STC_EINVAL, "compact queries (UV16, FACE16) are for SAMPLE only");
    if (n > c->server.max_batch)
        return stc__fail(c, STC_EINVAL, "%zu queries: over the server's max_batch (%u)", n,
                         (unsigned)c->server.max_batch);
    uint8_t op = dir ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE;
    uint64_t at, span, qoff, roff, rcap;
    if (!take_room(c, op, p.flags, p.outfmt, (uint32_t)n, &at, &span, &qoff, &roff, &rcap))
        return stc__fail(c, STC_ESTATE, "no room for %zu queries and their reply in the region "
                         "(%zu bytes; read replies to free room)", n, c->shm_size);
    c->shm_resv.open = 1;
    c->shm_resv.dir = dir;
    c->shm_resv.n = (uint32_t)n;
    c->shm_resv.p = p;
    c->shm_resv.at = at;
    c->shm_resv.span = span;
    c->shm_resv.qoff = qoff;
    c->shm_resv.roff = roff;
    c->shm_resv.rcap = rcap;
    *queries = c->shm + qoff;
    return 0;
}

void stc_shm_cancel(stc_conn *c)
{
    if (!c || !c->shm_resv.open)
        return;
    c->shm_head = c->shm_resv.at;    /* nothing was taken after it */
    c->shm_used -= c->shm_resv.span;
    if (c->shm_used == 0)
        c->shm_head = c->shm_tail = 0;
    c->shm_resv.open = 0;
}

void stc__shm_take_reserved(stc_conn *c, stp_sample_req *r)
{
    memset(r, 0, sizeof *r);
    r->p = c->shm_resv.p;
    r->p.flags |= STP_SF_SHM;
    r->count = c->shm_resv.n;
    r->shm.query_off = c->shm_resv.qoff;
    r->shm.reply_off = c->shm_resv.roff;
    r->shm.reply_cap = c->shm_resv.rcap;
    hold_span(c, c->shm_resv.at, c->shm_resv.span, c->shm_resv.roff, c->shm_resv.rcap);
    c->shm_resv.open = 0;
}
