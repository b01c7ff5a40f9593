/* client/libshm.c - libseamtex's shared-memory sampling (PROTOCOL.md 4.12; stc_shm_attach in
 * seamtex.h).
 *
 * Owns: the connection's region (a sealed memfd, mapped; util/shmfd.c makes it), SHM_ATTACH,
 * and a ring of spans in it: each shared-memory SAMPLE takes one span for its queries, which
 * its reply then overwrites (the server reads the queries whole before it writes), and gives
 * it back when its reply is read or dropped. Replies come in request order (the library uses
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
        int64_t left = deadline < 0 ? 1000 : deadline - stc__now_ms();
        if (left <= 0)
            return stc__break(c, STC_ETIMEDOUT, "SHM_ATTACH could not be sent in time");
        struct pollfd p = { c->fd, POLLOUT, 0 };
        poll(&p, 1, left > 1000 ? 1000 : (int)left);
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
        if (rc == STC_ETIMEDOUT)
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

/* Takes need bytes: *off where they start, *span what the ring gives (need, plus the end of
 * the ring skipped when it wraps). 0 when there is no room. */
static int ring_take(stc_conn *c, uint64_t need, uint64_t *off, uint64_t *span)
{
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
    c->shm_head = *off + need;
    c->shm_used += *span;
    return 1;
}

int stc__shm_place(stc_conn *c, uint8_t opcode, stp_sample_req *r)
{
    uint64_t q = stp_sample_query_bytes(opcode, r->p.flags, r->count);
    uint64_t rep = stp_sample_reply_bytes(r->count, 4, r->p.outfmt, r->p.flags);
    uint64_t need = (q > rep ? q : rep) + (SHM_ALIGN - 1);
    need -= need % SHM_ALIGN;
    uint64_t at = c->shm_used ? c->shm_head : 0, off = 0, span = 0;
    if (!c->shm || !rep || c->pn == c->phead || !ring_take(c, need, &off, &span)) {
        c->sock_n++;
        return 0;
    }
    stp_put_queries(opcode, r, c->shm + off);
    r->p.flags |= STP_SF_SHM;
    r->shm.query_off = off;
    r->shm.reply_off = off;
    r->shm.reply_cap = need;
    stc_pend *p = &c->pend[c->pn - 1];
    p->shm = 1;
    p->shm_at = at;
    p->shm_span = span;
    p->shm_off = off;
    p->shm_len = need;
    c->shm_n++;
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
    if (!p->shm)
        return 0;
    if (p->shm_at != c->shm_tail)
        return stc__break(c, STC_EPROTO, "shared-memory reply out of request order");
    c->shm_tail = p->shm_at + p->shm_span;
    if (c->shm_tail > c->shm_size)
        c->shm_tail -= c->shm_size;
    c->shm_used -= p->shm_span;
    if (c->shm_used == 0)
        c->shm_head = c->shm_tail = 0;
    if (drop || f->h.status != 0)
        return 0;
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
