/* client/bench_loop.c - one load-tester thread: an epoll loop over its own non-blocking
 * connections, in open loop (requests due at intended times from a schedule per connection)
 * or closed loop (a fixed number of requests outstanding per connection).
 *
 * Owns: per-connection buffers, the table of outstanding requests, timestamps, timeouts.
 * Does not own: sockets' creation (bench_main.c connects them), frame bytes (bench_wire.c).
 *
 * What a request costs the client (it shares the machine with the daemon): the pool's frames
 * are encoded once (bench_wire.c), so a request is not re-encoded, and not copied either: it
 * is queued as an iovec pair, its own 16-byte header (the pool's with the request id
 * patched) and the pool frame's body where it lies, written with writev (a --shm frame, a few
 * dozen bytes, is built in a per-slot buffer). Replies are read into one buffer (256 KiB,
 * grown for larger ones), a read offered all the free room (a short read means the socket is
 * drained, so no read ends in EAGAIN), their headers parsed where they lie; the unparsed tail
 * of a partly read reply is moved to the front, so the buffer's hot part stays small.
 * Closed-loop SAMPLE sets a low-water mark (SO_RCVLOWAT, --lowat: half the pipeline's replies
 * by default, sized from the first reply) so that a thread is woken for several whole replies
 * instead of each: every wake-up of the load tester is a context switch that preempts a
 * daemon I/O thread on these 2 cores (measured, 2 connections x -P 8, 4096 queries, TCP:
 * 0.95 -> 0.29 switches a request, 12.4 -> 4.6 ns of client CPU a query). The mark is
 * dropped when the run stops issuing (fewer replies than it are left) and at a connection's
 * first error reply (shorter than the others), and after 50 ms without an event the
 * connections are read anyway (error replies that arrive together below the mark).
 *
 * Timestamps: t_intended comes from the schedule (closed loop: equal to the send time);
 * t_send is read just before the write() that carries the request's first byte; t_reply just
 * after the read() that completed its reply. corrected = t_reply - t_intended (what a user
 * waiting on that schedule sees, coordinated omission corrected), service = t_reply - t_send.
 * Replies are matched by request id (the server may answer out of order when it offers
 * OUT_OF_ORDER): request ids on a connection are consecutive and request r lives in slot
 * r % cap, so at most cap requests are outstanding and a lookup is one array access. The
 * peers (--proto memcached / redis) answer in order: their reply takes the oldest id.
 *
 * A request is recorded when its intended time lies in [t_measure, t_end). No request is
 * issued from t_end on; outstanding ones get until t_end + min(timeout, 2 s), and whatever is
 * left then counts as a timeout.
 */
#include "bench.h"
#include "proto.h"

#include <errno.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#define IN_INIT    (256 * 1024)
#define IN_ROOM    (128 * 1024)            /* free room wanted behind the data before a read */
#define SLOT_BYTES 512                     /* a --shm frame: header, name, parameters, refs */
#define IOV_BATCH  1024                    /* iovecs per writev (IOV_MAX) */
_Static_assert(STP_HEADER_SIZE + 2 + STP_MAX_NAME + 24 + STP_SHM_REF_SIZE <= SLOT_BYTES,
               "a --shm frame fits its slot");
#define IN_MAX     ((size_t)256 << 20)     /* one reply may not exceed this */
#define LATE_NS    1000000ull              /* a send more than 1 ms after due is "late" */

typedef struct bconn {
    int       fd;
    int       dead;
    uint32_t  events;           /* current epoll interest */
    struct iovec *iov;          /* bytes not yet written: iov[iov_head .. iov_n) */
    unsigned  iov_head, iov_n, iov_cap;
    uint8_t  *slotbuf;          /* per slot: the request's header (or whole --shm frame) */
    size_t    slot_bytes;
    uint8_t  *in;               /* bytes read, not yet parsed: in[0 .. in_len) */
    size_t    in_len, in_cap;
    /* outstanding requests: request id r in slot r % cap */
    uint64_t *t_int, *t_send;
    uint32_t *nq;
    uint32_t *rid;              /* request id held by a slot, 0 = free */
    uint32_t  next_rid;         /* id of the next request (ids start at 1) */
    uint32_t  stamp_from;       /* ids from here to next_rid are queued, not yet written */
    uint32_t  oldest;           /* no request older than this is outstanding */
    uint32_t  count;            /* outstanding (queued or sent) */
    uint32_t  cap;
    uint8_t  *shm;              /* --shm: the connection's region (cap slots), else NULL */
    int       lowat;            /* SO_RCVLOWAT set: 0 not yet, >0 bytes, -1 reset to 1 */
    stc_sched sched;
} bconn;

static int grow(uint8_t **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return 0;
    size_t c = *cap ? *cap : 4096;
    while (c < need) {
        if (c > ((size_t)1 << 40))
            return -1;
        c *= 2;
    }
    uint8_t *p = realloc(*buf, c);
    if (!p)
        return -1;
    *buf = p;
    *cap = c;
    return 0;
}

static void conn_set_events(int ep, bconn *c, uint32_t ev, unsigned idx)
{
    if (c->dead || c->events == ev)
        return;
    struct epoll_event e = { .events = ev, .data.u32 = idx };
    if (epoll_ctl(ep, EPOLL_CTL_MOD, c->fd, &e) == 0)
        c->events = ev;
}

/* The connection is unusable: everything outstanding on it counts as a timeout. */
static void conn_kill(bench_thread *th, int ep, bconn *c)
{
    if (c->dead)
        return;
    th->res->conn_errors++;
    th->res->timeouts += c->count;
    c->count = 0;
    epoll_ctl(ep, EPOLL_CTL_DEL, c->fd, NULL);
    c->dead = 1;
}

/* A new request fits: fewer than cap outstanding and its slot is free. */
static inline int can_issue(const bconn *c)
{
    return c->count < c->cap && c->rid[c->next_rid % c->cap] == 0;
}

static inline int out_pending(const bconn *c)
{
    return c->iov_head < c->iov_n;
}

static void out_add(bconn *c, const uint8_t *p, size_t len)
{
    if (c->iov_n == c->iov_cap) {           /* room was freed at the front: reuse it */
        memmove(c->iov, c->iov + c->iov_head, (c->iov_n - c->iov_head) * sizeof *c->iov);
        c->iov_n -= c->iov_head;
        c->iov_head = 0;
    }
    c->iov[c->iov_n++] = (struct iovec){ (void *)(uintptr_t)p, len };
}

/* Queues one request frame with its intended time. */
static int conn_queue(bench_thread *th, bconn *c, uint64_t t_int)
{
    const uint8_t *frame;
    uint32_t nq;
    size_t len = bench_wire_next(th->wire, &frame, &nq);
    uint32_t rid = c->next_rid++;
    uint32_t slot = rid % c->cap;
    uint8_t *own = c->slotbuf + (size_t)slot * c->slot_bytes;
    if (c->shm) { /* --shm: the pool frame's queries are in the region already (--shm-copy:
                   * copied into the slot's room now); the frame carries offsets only */
        uint64_t qoff = (uint64_t)bench_wire_last(th->wire) * th->shm_qroom;
        if (th->cfg->shm_copy) {
            qoff = (uint64_t)slot * th->shm_qroom;
            bench_wire_shm_copy(frame, len, c->shm + qoff);
        }
        len = bench_wire_shm_frame(frame, qoff,
                                   (uint64_t)th->shm_qarea + (uint64_t)slot * th->shm_slot,
                                   th->shm_slot, own);
        stp_wr32(own + BENCH_REQID_OFFSET, rid);
        out_add(c, own, len);
    } else if (th->cfg->proto == BENCH_PROTO_SEAMTEX) {
        /* the header with this request's id, then the pool frame's body as it lies */
        memcpy(own, frame, STP_HEADER_SIZE);
        stp_wr32(own + BENCH_REQID_OFFSET, rid);
        out_add(c, own, STP_HEADER_SIZE);
        if (len > STP_HEADER_SIZE)
            out_add(c, frame + STP_HEADER_SIZE, len - STP_HEADER_SIZE);
    } else {
        out_add(c, frame, len);             /* peers: the same line every time */
    }
    c->rid[slot] = rid;
    c->t_int[slot] = t_int;
    c->t_send[slot] = 0;
    c->nq[slot] = nq;
    c->count++;
    th->res->sent++;
    return 0;
}

/* Writes what is pending; stamps the requests whose bytes go out with this write. */
static int conn_flush(bench_thread *th, bconn *c)
{
    while (out_pending(c)) {
        uint64_t now = bench_now_ns();
        for (; c->stamp_from != c->next_rid; c->stamp_from++) {
            uint32_t slot = c->stamp_from % c->cap;
            c->t_send[slot] = now;
            if (th->cfg->open_loop && now > c->t_int[slot] + LATE_NS)
                th->res->late_sends++;
        }
        unsigned k = c->iov_n - c->iov_head;
        ssize_t w = writev(c->fd, c->iov + c->iov_head, (int)(k < IOV_BATCH ? k : IOV_BATCH));
        if (w < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return 0;
            return -1;
        }
        th->res->bytes_out += (uint64_t)w;
        for (size_t left = (size_t)w; left > 0;) {  /* drop what went out */
            struct iovec *v = &c->iov[c->iov_head];
            if (left < v->iov_len) {
                v->iov_base = (uint8_t *)v->iov_base + left;
                v->iov_len -= left;
                break;
            }
            left -= v->iov_len;
            c->iov_head++;
        }
    }
    c->iov_head = c->iov_n = 0;
    return 0;
}

/* the connection's low-water mark back to 1 byte (every reply wakes its thread again) */
static void lowat_drop(bconn *c)
{
    int one = 1;
    setsockopt(c->fd, SOL_SOCKET, SO_RCVLOWAT, &one, sizeof one);
    c->lowat = -1;
}

/* Reads what is there and consumes every complete reply. */
static int conn_read(bench_thread *th, bconn *c)
{
    bench_result *r = th->res;
    for (;;) {
        if (c->in_cap - c->in_len < IN_ROOM && grow(&c->in, &c->in_cap, c->in_len + IN_ROOM) < 0)
            return -1;
        size_t room = c->in_cap - c->in_len;
        ssize_t n = read(c->fd, c->in + c->in_len, room);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return 0;
            return -1;
        }
        if (n == 0)
            return -1;                      /* the server closed the connection */
        uint64_t now = bench_now_ns();
        c->in_len += (size_t)n;
        r->bytes_in += (uint64_t)n;
        size_t off = 0;
        for (;;) {
            int ok = 0;
            uint32_t rid = 0;
            long flen = bench_wire_reply(th->cfg->proto, c->in + off, c->in_len - off, &ok,
                                         &rid);
            if (flen < 0)
                return -1;
            if (flen == 0)
                break;
            if (th->cfg->proto != BENCH_PROTO_SEAMTEX)
                rid = c->oldest;            /* peers answer in order */
            uint32_t slot = rid % c->cap;
            if (rid == 0 || c->rid[slot] != rid || rid - c->oldest >= c->stamp_from - c->oldest)
                return -1;                  /* a reply to no request that was sent */
            c->rid[slot] = 0;
            c->count--;
            while (c->oldest != c->stamp_from && c->rid[c->oldest % c->cap] != c->oldest)
                c->oldest++;
            r->completed++;
            if (!ok)
                r->errors++;
            uint64_t ti = c->t_int[slot], ts = c->t_send[slot];
            if (ti >= th->t_measure && ti < th->t_end) {
                stc_hist_record(&r->corrected, now > ti ? now - ti : 0);
                stc_hist_record(&r->service, now > ts ? now - ts : 0);
                r->measured++;
                r->t_last = now;
                if (ok)
                    r->queries += c->nq[slot];
            }
            off += (size_t)flen;
            if (!c->lowat && th->lowat_k && ok && th->t_end > now) {
                /* the first reply gives the size of them all (same batch, same format) */
                int lw = (int)(th->lowat_k * (unsigned)flen);
                setsockopt(c->fd, SOL_SOCKET, SO_RCVLOWAT, &lw, sizeof lw);
                c->lowat = lw;
            } else if (!ok && c->lowat > 0) {
                /* error replies are shorter: the mark could wait for bytes that never come */
                lowat_drop(c);
            }
        }
        /* the unparsed tail to the front: replies land in the same few hundred KiB, which
         * stay in cache, rather than walking the buffer */
        if (off > 0) {
            memmove(c->in, c->in + off, c->in_len - off);
            c->in_len -= off;
        }
        if (c->in_len > IN_MAX)
            return -1;
        if ((size_t)n < room)
            return 0;                       /* a short read: the socket is drained */
    }
}

/* Sleeps in epoll until `deadline` (ns, 0 = don't sleep) or an event. */
static int wait_events(int ep, struct epoll_event *ev, int maxev, uint64_t deadline)
{
    uint64_t now = bench_now_ns();
    struct timespec ts = { 0, 0 };
    if (deadline > now) {
        uint64_t d = deadline - now;
        ts.tv_sec = (time_t)(d / 1000000000ull);
        ts.tv_nsec = (long)(d % 1000000000ull);
    }
    int n = epoll_pwait2(ep, ev, maxev, &ts, NULL);
    if (n < 0 && errno == ENOSYS) {
        int ms = (int)((ts.tv_sec * 1000) + (ts.tv_nsec + 999999) / 1000000);
        n = epoll_wait(ep, ev, maxev, ms);
    }
    return n;
}

int bench_loop_run(bench_thread *th)
{
    const bench_cfg *cfg = th->cfg;
    unsigned nc = th->conn_count;
    bconn *cs = calloc(nc ? nc : 1, sizeof *cs);
    struct epoll_event *evs = calloc(256, sizeof *evs);
    int ep = epoll_create1(EPOLL_CLOEXEC);
    int rc = -1;
    /* the default 50 us timer slack would show up as send lateness in every open-loop figure */
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
    /* closed-loop SAMPLE: wake for half the pipeline's replies, not for each (--lowat) */
    th->lowat_k = cfg->open_loop || !bench_op_samples(cfg->op) ? 0
                  : cfg->lowat >= 0 ? (unsigned)cfg->lowat
                  : cfg->pipeline / 2 ? cfg->pipeline / 2 : 1;
    if (!cs || !evs || ep < 0) {
        snprintf(th->err, sizeof th->err, "thread %u: out of memory or epoll: %s", th->index,
                 strerror(errno));
        goto out;
    }
    uint32_t cap = cfg->open_loop ? (cfg->pipeline > 0 ? cfg->pipeline : 1024) : cfg->pipeline;
    if (cap == 0)
        cap = 1;
    for (unsigned i = 0; i < nc; i++) {
        bconn *c = &cs[i];
        c->fd = th->fds[i];
        c->cap = cap;
        c->shm = th->shm ? th->shm[i] : NULL;
        c->t_int = malloc(cap * sizeof *c->t_int);
        c->t_send = malloc(cap * sizeof *c->t_send);
        c->nq = malloc(cap * sizeof *c->nq);
        c->rid = calloc(cap, sizeof *c->rid);
        c->next_rid = c->stamp_from = c->oldest = 1;
        c->slot_bytes = c->shm ? SLOT_BYTES : STP_HEADER_SIZE;
        c->slotbuf = malloc((size_t)cap * c->slot_bytes);
        c->iov_cap = 2 * cap + 2;           /* at most two per outstanding request */
        c->iov = malloc(c->iov_cap * sizeof *c->iov);
        if (!c->t_int || !c->t_send || !c->nq || !c->rid || !c->slotbuf || !c->iov ||
            grow(&c->in, &c->in_cap, IN_INIT) < 0) {
            snprintf(th->err, sizeof th->err, "thread %u: out of memory", th->index);
            goto out;
        }
        c->events = EPOLLIN;
        struct epoll_event e = { .events = EPOLLIN, .data.u32 = i };
        if (epoll_ctl(ep, EPOLL_CTL_ADD, c->fd, &e) < 0) {
            snprintf(th->err, sizeof th->err, "epoll_ctl: %s", strerror(errno));
            goto out;
        }
        if (cfg->open_loop) {
            /* the total rate split evenly; uniform schedules staggered across connections */
            unsigned gi = th->conn_first + i;
            stc_sched_init(&c->sched, (stc_arrival)cfg->arrival, cfg->rate / cfg->conns,
                           th->t_start, (double)gi / cfg->conns,
                           cfg->seed * 1000003ull + gi);
        }
    }

    uint64_t issued = 0;
    uint64_t timeout_ns = (uint64_t)(cfg->timeout_s * 1e9);
    uint64_t spin_ns = (uint64_t)cfg->spin_us * 1000u;
    uint64_t drain = timeout_ns < 2000000000ull ? timeout_ns : 2000000000ull;
    uint64_t t_stop = th->t_end + drain;
    unsigned alive = nc;

    for (;;) {
        uint64_t now = bench_now_ns();
        if (now < th->t_start) {            /* every thread begins at the same instant */
            wait_events(ep, evs, 256, th->t_start);
            continue;
        }
        int issuing = now < th->t_end && (!th->max_requests || issued < th->max_requests);
        uint64_t next_due = 0;              /* earliest intended time still to issue */
        uint64_t outstanding = 0;

        for (unsigned i = 0; i < nc; i++) {
            bconn *c = &cs[i];
            if (c->dead)
                continue;
            int queued = 0;
            if (issuing) {
                if (cfg->open_loop) {
                    while (can_issue(c) && stc_sched_peek(&c->sched) <= now &&
                           stc_sched_peek(&c->sched) < th->t_end &&
                           (!th->max_requests || issued < th->max_requests)) {
                        if (conn_queue(th, c, stc_sched_next(&c->sched)) < 0)
                            goto oom;
                        issued++;
                        queued = 1;
                    }
                    uint64_t nd = stc_sched_peek(&c->sched);
                    if (can_issue(c) && nd < th->t_end && (!next_due || nd < next_due))
                        next_due = nd;
                } else {
                    while (can_issue(c) &&
                           (!th->max_requests || issued < th->max_requests)) {
                        if (conn_queue(th, c, now) < 0)
                            goto oom;
                        issued++;
                        queued = 1;
                    }
                }
            }
            if (queued || out_pending(c)) {
                if (conn_flush(th, c) < 0) {
                    conn_kill(th, ep, c);
                    alive--;
                    continue;
                }
                conn_set_events(ep, c, out_pending(c) ? EPOLLIN | EPOLLOUT : EPOLLIN, i);
            }
            /* the oldest request sent on this connection is too old: give up on it */
            if (c->count > 0 && c->oldest != c->stamp_from && timeout_ns &&
                now > c->t_send[c->oldest % c->cap] + timeout_ns) {
                conn_kill(th, ep, c);
                alive--;
                continue;
            }
            outstanding += c->count;
        }

        if (alive == 0)
            break;
        if (!issuing && outstanding == 0)
            break;
        if (now >= t_stop)
            break;

        /* sleep until the next due request, an event, or at most 50 ms. A timed sleep here
         * wakes ~60 us late (measured on this VM even with 1 ns timer slack), which would
         * count as send lateness: in open loop the last spin_ns before a due time are spent
         * polling instead (epoll with a zero timeout after sched_yield, so that on a small
         * machine the spinning client does not take a core from the server). */
        uint64_t deadline = now + 50000000ull;
        if (issuing && cfg->open_loop && next_due && next_due < deadline) {
            deadline = next_due;
            if (spin_ns && deadline > now && deadline - now <= spin_ns) {
                deadline = now;             /* poll, giving way to the server's threads */
                sched_yield();
            }
            else if (spin_ns)
                deadline -= spin_ns;
        }
        if (issuing && th->t_end < deadline)
            deadline = th->t_end;
        if (!issuing && t_stop < deadline)
            deadline = t_stop;
        if (!issuing) {   /* draining: fewer replies than the low-water mark are left */
            for (unsigned i = 0; i < nc; i++)
                if (cs[i].lowat > 0 && !cs[i].dead)
                    lowat_drop(&cs[i]);
        }
        int n = wait_events(ep, evs, 256, deadline);
        if (n == 0) {   /* a low-water mark that short (error) replies never reach: read */
            for (unsigned i = 0; i < nc; i++)
                if (cs[i].lowat > 0 && !cs[i].dead && cs[i].count && conn_read(th, &cs[i]) < 0) {
                    conn_kill(th, ep, &cs[i]);
                    alive--;
                }
        }
        if (n < 0 && errno != EINTR) {
            snprintf(th->err, sizeof th->err, "epoll: %s", strerror(errno));
            goto out;
        }
        for (int k = 0; k < n; k++) {
            unsigned i = evs[k].data.u32;
            bconn *c = &cs[i];
            if (c->dead)
                continue;
            int bad = 0;
            if (evs[k].events & (EPOLLIN | EPOLLERR | EPOLLHUP))
                bad = conn_read(th, c) < 0;
            if (!bad && (evs[k].events & EPOLLOUT)) {
                bad = conn_flush(th, c) < 0;
                if (!bad)
                    conn_set_events(ep, c, out_pending(c) ? EPOLLIN | EPOLLOUT : EPOLLIN, i);
            }
            if (bad) {
                conn_kill(th, ep, c);
                alive--;
            }
        }
    }
    /* whatever is still outstanding never got its reply in time */
    for (unsigned i = 0; i < nc; i++)
        if (!cs[i].dead)
            th->res->timeouts += cs[i].count;
    /* open loop: requests that were due before t_end but never left the schedule (the
     * connection was full or dead) are reported, not silently dropped */
    if (cfg->open_loop) {
        for (unsigned i = 0; i < nc; i++) {
            stc_sched *sc = &cs[i].sched;
            uint64_t k = 0;
            while (stc_sched_peek(sc) < th->t_end && k < 10000000u) {
                stc_sched_next(sc);
                k++;
            }
            if (stc_sched_peek(sc) < th->t_end)    /* bounded walk: estimate the rest */
                k += (uint64_t)((double)(th->t_end - stc_sched_peek(sc)) / sc->interval_ns);
            if (!th->max_requests)
                th->res->unsent += k;
        }
    }
    rc = 0;
    goto out;
oom:
    snprintf(th->err, sizeof th->err, "thread %u: out of memory", th->index);
out:
    if (cs) {
        for (unsigned i = 0; i < nc; i++) {
            free(cs[i].iov);
            free(cs[i].slotbuf);
            free(cs[i].in);
            free(cs[i].t_int);
            free(cs[i].t_send);
            free(cs[i].nq);
            free(cs[i].rid);
        }
    }
    free(cs);
    free(evs);
    if (ep >= 0)
        close(ep);
    return rc;
}
