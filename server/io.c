/* server/io.c - the I/O threads: accept, read, frame parsing, backpressure, writes, idle
 * timeouts, the hand-back of worker replies, and the drain at stop.
 *
 * Owns: every connection's buffers and fd (only its I/O thread touches them). Does not own:
 * what a request means (dispatch.c and the handlers), the worker queue (workers.c).
 *
 * Per wake-up a readable connection gets one read of up to the free input space (at least
 * 16 KiB, or what the last wake-up read when that was more than the default room: read_hint;
 * another, up to READS_MAX in all, while a read fills all the room it was offered),
 * every complete frame in the buffer is parsed and answered into the output buffer, then
 * the output is written with one send: a pipelined burst of N requests costs one read and
 * one write, not N (once 64 KiB of replies are pending they are sent at once, so a
 * pipeline of big SAMPLE replies streams instead of waiting for the whole burst). Level-triggered polling keeps the loop fair between connections,
 * and a wake-up parses at most a time slice (~2 ms) of frames: the rest waits for the loop's
 * next pass (the ready list, "Time slices").
 * Backpressure: when a connection's unsent replies pass conn-out-cap, or while the daemon's
 * buffers are past max-memory and it has any, it is no longer read (nor parsed) until the
 * peer drains them (out_backed_up). Memory: buffers are allocated when data arrives
 * and released as soon as everything is parsed and answered (small ones to the thread's
 * spare slots, which the next connection that reads takes), so an idle connection holds
 * only its struct (~200 bytes) plus the kernel's socket.
 */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#include "cube.h"
#include "dispatch.h"
#include "h_jobs.h"
#include "io.h"
#include "server.h"
#include "shm.h"
#include "unixaddr.h"
#include "uploads.h"
#include "workers.h"

#define READ_MIN   (16u << 10)   /* free input space guaranteed before a read */
#define KEEP_SMALL (64u << 10)   /* buffers up to this are released as soon as idle */
#define FLUSH_AT   (64u << 10)   /* replies pending past this are sent inside the parse loop */
#define SPLIT_MIN  (16u << 10)   /* SAMPLE frames from this long on end a read at their end
                                    (split reads, conn_readable) */
#define ROOM_STEP  (1u << 20)    /* a frame's room is reserved whole up to this (every SAMPLE
                                    of up to ~37k queries: the read path is unchanged); a longer
                                    one's grows with what has arrived (conn_process): a header
                                    alone claiming a 64 MiB body held 64 MiB of max-memory for
                                    the 517 s its deadline allowed, and 16 such connections (33
                                    bytes sent each) made every other big frame BUSY (pc35) */
#define ROOM_AHEAD (READ_MIN * 2) /* past half of max-memory a frame's room is at most
                                    twice what has arrived, at least this (the size of a new
                                    input buffer): room ahead of a body's bytes cannot take
                                    the second half. Before, 64 headers claiming 1 MiB each
                                    made every other big frame BUSY for 5-6 s under
                                    --max-memory 64M (1000 under the default 1G; res36) */

int sts_scratch_reserve(sts_scratch *s, size_t n, int dir)
{
    if (dir && n > s->cqcap) {
        size_t cap = n < 4096 ? 4096 : n;
        st_cube_query *cq = realloc(s->cq, cap * sizeof *cq);
        if (!cq)
            return -1;
        s->cq = cq;
        s->cqcap = cap;
    }
    if (n <= s->cap)
        return 0;
    size_t cap = n < 4096 ? 4096 : n;
    st_query *q = realloc(s->q, cap * sizeof *q);
    if (q)
        s->q = q;
    float *out = realloc(s->out, cap * ST_MAX_CHANNELS * sizeof *out);
    if (out)
        s->out = out;
    float *cov = realloc(s->cov, cap * sizeof *cov);
    if (cov)
        s->cov = cov;
    uint8_t *st = realloc(s->status, cap);
    if (st)
        s->status = st;
    if (!q || !out || !cov || !st)
        return -1;
    s->cap = cap;
    return 0;
}

void sts_scratch_free(sts_scratch *s)
{
    free(s->q);
    free(s->out);
    free(s->cov);
    free(s->status);
    free(s->cq);
    sts_shm_scratch_free(s->shm);
    memset(s, 0, sizeof *s);
}

/* ---- memory accounting -------------------------------------------------------------------- */

static void account(sts_conn *c)
{
    uint64_t now = (uint64_t)c->in.cap + (uint64_t)c->in2.cap + (uint64_t)c->out.cap;
    sts_server *srv = c->io->srv;
    if (now > c->mem)
        __atomic_add_fetch(&srv->mem_used, now - c->mem, __ATOMIC_RELAXED);
    else if (now < c->mem)
        __atomic_sub_fetch(&srv->mem_used, c->mem - now, __ATOMIC_RELAXED);
    c->mem = now;
}

/* 1 when the connection's unsent replies hold it back (it is neither read nor parsed until
 * the peer drains them): past conn-out-cap, or any at all while the connection buffers and
 * open fetches together are past max-memory (sts_mem_take). Replies are written without a
 * check of their own, so the second rule is what bounds many clients that never read: each
 * stops at its first reply left unsent once the daemon is at max-memory, not at conn-out-cap
 * (N x 4 MiB). A connection whose replies have all gone is always served. */
static int out_backed_up(const sts_conn *c)
{
    size_t pending = stp_buf_avail(&c->out);
    if (!pending)
        return 0;
    sts_server *srv = c->io->srv;
    return pending > STS_LIVE(srv, conn_out_cap) || sts_mem_take(srv, 0) != 0;
}

/* Where compaction puts the unparsed bytes p[0 .. avail): 0, or for a SAMPLE frame (whose
 * head is there) 1-3 bytes in, so that its f32 queries lie 4-byte aligned and are sampled
 * where they lie (h_basic.c) instead of being copied out a chunk at a time: with a set name
 * of 7 bytes, such as `default`, they start at an odd offset of the frame (PROTOCOL.md 4.4:
 * u16 name length, name, 20 bytes of parameters, u32 count, the queries). The buffer from
 * malloc is 16-byte aligned. A read into an empty buffer starts at the last frame's pad
 * (c->in_pad), so the first frame of a read is aligned too when the client repeats it. */
static size_t in_pad(const uint8_t *p, size_t avail)
{
    if (avail < STP_HEADER_SIZE + 2 || p[5] != STP_OP_SAMPLE)
        return 0;
    size_t q = STP_HEADER_SIZE + 2 + (size_t)stp_rd16(p + STP_HEADER_SIZE) + 24;
    return (4 - q % 4) % 4;
}

/* Gives the empty buffer b one of the thread's spare input buffers (release_idle_buffers)
 * of at least `need` bytes. 0 or -1 (none). */
static int spare_in_take(sts_io *io, sts_inbuf *b, size_t need)
{
    for (int k = 0; k < 2; k++) {
        if (io->spare_in[k] && io->spare_in_cap[k] >= need) {
            b->data = io->spare_in[k];
            b->cap = io->spare_in_cap[k];
            b->start = b->len = 0;
            io->spare_in[k] = NULL;
            io->spare_in_cap[k] = 0;
            return 0;
        }
    }
    return -1;
}

/* Makes room for `need` unparsed bytes in total (compacting first). 0 or -1. */
static int in_reserve(sts_conn *c, size_t need)
{
    sts_inbuf *b = &c->in;
    if (b->start > 0 && (b->cap - b->len < need - (b->len - b->start) || b->start == b->len)) {
        size_t n = b->len - b->start;
        size_t pad = in_pad(b->data + b->start, n);
        if (pad != b->start) {
            memmove(b->data + pad, b->data + b->start, n);
            b->len = pad + n;
            b->start = pad;
        }
    }
    if (b->cap - b->start >= need)
        return 0;
    if (!b->data && spare_in_take(c->io, b, need) == 0) {
        account(c);
        return 0;
    }
    size_t cap = b->cap ? b->cap : READ_MIN * 2;
    while (cap - b->start < need)
        cap *= 2;
    uint8_t *d = realloc(b->data, cap);
    if (!d)
        return -1;
    b->data = d;
    b->cap = cap;
    account(c);
    return 0;
}

static void in_consume(sts_conn *c, size_t n)
{
    c->in.start += n;
    if (c->in.start == c->in.len)
        c->in.start = c->in.len = 0;
}

/* ---- split reads ---------------------------------------------------------------------------
 * A SAMPLE frame of SPLIT_MIN bytes or more ends a read: when the frame being read has its
 * header in the buffer (or, in an empty buffer, when the last frame was such a SAMPLE: the
 * client repeats its batches, c->next_total), the read is one recvmsg with two iovecs: the
 * rest of that frame into `in`, whatever follows into `in2` at the pad the frame has
 * (in_pad), `in2` sized for a frame as long. So the next frame lands at its final, aligned
 * place in a buffer that has room for all of it: it is never moved to make room (the
 * compaction in in_reserve) and its queries are sampled where recvmsg put them. Once `in`
 * is parsed to its end the two buffers swap (in_swap). When the guess was wrong (the next
 * frame is longer than its room, or the split fell inside a frame) `in2`'s bytes are
 * appended to `in` (in_join) and parsing goes on as with one buffer. */

static size_t in2_avail(const sts_conn *c)
{
    return c->in2.len - c->in2.start;
}

/* `in` is parsed to its end: `in2`'s bytes become the input, `in` the next buffer. */
static void in_swap(sts_conn *c)
{
    sts_inbuf t = c->in;
    c->in = c->in2;
    t.start = t.len = 0;
    c->in2 = t;
}

/* Appends `in2`'s bytes to the unparsed ones of `in`. 0 or -1 (no memory). */
static int in_join(sts_conn *c)
{
    size_t n = in2_avail(c);
    if (in_reserve(c, c->in.len - c->in.start + n) != 0)
        return -1;
    memcpy(c->in.data + c->in.len, c->in2.data + c->in2.start, n);
    c->in.len += n;
    c->in2.start = c->in2.len = 0;
    return 0;
}

/* in_join for conn_process (a split read whose split was not a frame's end); without memory
 * the connection is closed once its replies are out. 0 or -1. */
static int in_join_or_close(sts_conn *c)
{
    if (in_join(c) == 0)
        return 0;
    STS_STAT_ADD(c->io->srv, mem_rejected, 1);
    c->close_after = 1;
    c->in.start = c->in.len = c->in2.start = c->in2.len = 0;
    return -1;
}

/* Makes `in2` (empty) ready to take a frame of n bytes at offset pad. 0 or -1 (the read is
 * then not split). */
static int in2_prepare(sts_conn *c, size_t pad, size_t n)
{
    sts_inbuf *b = &c->in2;
    if (b->cap < pad + n) {
        if (b->data && b->cap) {
            free(b->data);
            b->data = NULL;
            b->cap = 0;
        }
        if (spare_in_take(c->io, b, pad + n) != 0) {
            size_t cap = READ_MIN * 2;
            while (cap < pad + n)
                cap *= 2;
            if (sts_mem_take(c->io->srv, cap) != 0 || !(b->data = malloc(cap))) {
                account(c);
                return -1;
            }
            b->cap = cap;
        }
        account(c);
    }
    b->start = b->len = pad;
    return 0;
}

/* An idle connection keeps no buffers: when everything read is parsed and everything
 * answered is sent, small buffers (<= KEEP_SMALL) are released at once (so 10k idle
 * connections hold only their structs) and big ones once the connection has been quiet for
 * a second (re-growing a 100 KiB+ buffer per SAMPLE request would cost mmap and page faults).
 * A small buffer goes to its I/O thread's spare slots (two input buffers, a split read's
 * pair, and one output buffer) when one is empty, else back to malloc; the next connection of the thread that reads takes the
 * spares (in_reserve, out_take_spare). Measured (callgrind, 2 connections x -P 2, 256-query
 * SAMPLE over TCP): before, each request pair re-malloced the input buffer and regrew the
 * output buffer from 256 bytes to 16 KiB, copying the first reply on the way, ~2,600 of the
 * ~5,800 instructions per request spent outside the sampler. */
static void release_in(sts_io *io, sts_inbuf *b)
{
    if (!b->data)
        return;
    int k = !io->spare_in[0] ? 0 : !io->spare_in[1] ? 1 : -1;
    if (k >= 0 && b->cap <= KEEP_SMALL) {
        io->spare_in[k] = b->data;
        io->spare_in_cap[k] = b->cap;
    } else {
        free(b->data);
    }
    b->data = NULL;
    b->cap = b->start = b->len = 0;
}

static void release_idle_buffers(sts_conn *c)
{
    if (c->busy || c->in.len != c->in.start || c->in2.len != c->in2.start ||
        stp_buf_avail(&c->out))
        return;
    sts_io *io = c->io;
    release_in(io, &c->in);
    release_in(io, &c->in2);
    if (c->out.data) {
        if (!io->spare_out.data && c->out.cap <= KEEP_SMALL && !c->out.err) {
            io->spare_out = c->out;
            stp_buf_clear(&io->spare_out);
        } else {
            stp_buf_free(&c->out);
        }
        stp_buf_init(&c->out);
    }
    account(c);
}

/* Gives a connection with no output buffer its thread's spare one (release_idle_buffers). */
static void out_take_spare(sts_conn *c)
{
    sts_io *io = c->io;
    if (c->out.data || !io->spare_out.data)
        return;
    c->out = io->spare_out;
    stp_buf_init(&io->spare_out);
    account(c);
}

/* ---- time slices -----------------------------------------------------------------------------
 * A wake-up of one connection parses at most about SLICE_MS of its frames; with frames left
 * it yields: it goes on its thread's ready list, is not read meanwhile, and the loop's next
 * pass (after an epoll_wait that does not sleep) parses on, after the other connections'
 * events. Before, one wake-up answered every frame read, up to conn-out-cap of replies: 1000
 * pipelined STATS (24 bytes each, ~30-80 us to answer) held the thread 30-80 ms a client,
 * and 40 such clients kept a PING of a well-behaved client waiting up to 9.2 s (pc35). A
 * frame already begun is never cut; the check reads the clock conn_process reads anyway. */
#define SLICE_MS 2

static void ready_push(sts_conn *c)
{
    if (c->yielded)
        return;
    c->yielded = 1;
    c->ready_next = c->io->ready;
    c->io->ready = c;
}

static void ready_unlink(sts_conn **list, sts_conn *c)
{
    for (sts_conn **p = list; *p; p = &(*p)->ready_next)
        if (*p == c) {
            *p = c->ready_next;
            return;
        }
}

static void ready_remove(sts_conn *c)
{
    if (!c->yielded)
        return;
    ready_unlink(&c->io->ready, c);
    ready_unlink(&c->io->ready_pass, c);
    c->yielded = 0;
    c->ready_next = NULL;
}

/* ---- connection lifetime ------------------------------------------------------------------ */

static void set_interest(sts_conn *c)
{
    sts_server *srv = c->io->srv;
    unsigned want = 0;
    size_t pending = stp_buf_avail(&c->out);
    account(c);
    int over = out_backed_up(c);
    if (!c->dead && !c->busy && !c->close_after && !over && !c->held && !c->yielded)
        want |= STS_EV_READ;  /* also while stopping: requests already sent get answered */
    if (pending)
        want |= STS_EV_WRITE;
    if (over && !c->paused)
        STS_STAT_ADD(srv, backpressure_pauses, 1);
    c->paused = (uint8_t)over;
    if (want != c->ev_mask) {
        sts_ev_mod(c->io->ev, c->fd, want, c);
        c->ev_mask = want;
    }
}

static void conn_free(sts_conn *c)
{
    sts_io *io = c->io;
    sts_server *srv = io->srv;
    sts_ev_del(io->ev, c->fd);
    close(c->fd);
    ready_remove(c);
    if (c->prev)
        c->prev->next = c->next;
    else
        io->conns = c->next;
    if (c->next)
        c->next->prev = c->prev;
    __atomic_sub_fetch(&io->nconns, 1, __ATOMIC_RELAXED);  /* read by sts_server_stop */
    free(c->in.data);
    c->in.data = NULL;
    c->in.cap = 0;
    free(c->in2.data);
    c->in2.data = NULL;
    c->in2.cap = 0;
    stp_buf_free(&c->out);
    account(c);
    sts_fetch_drop_conn(srv, c->id);
    sts_upload_drop_conn(srv, c->id);
    sts_shm_conn_free(srv, c);
    __atomic_sub_fetch(&srv->nconns, 1, __ATOMIC_RELAXED);
    STS_STAT_ADD(srv, conns_closed, 1);
    free(c);
}

/* Closes now unless a worker holds the connection (then when its reply comes back). */
static void conn_close(sts_conn *c)
{
    c->dead = 1;
    if (!c->busy) {
        conn_free(c);
    } else if (c->ev_mask != (unsigned)-1) {
        sts_ev_del(c->io->ev, c->fd);  /* a hung-up socket would wake the poller forever */
        c->ev_mask = (unsigned)-1;
    }
}

/* Closing a socket whose input holds unread bytes makes the kernel reset the connection, and
 * the reset drops what is still unsent in its send queue: replies the client has not received
 * yet. So a connection the server ends (at stop once quiet, after a bad magic, a refusal or a
 * request timeout: close_after) is not closed at once: its sending side is shut (the client
 * reads every reply, then end of stream), whatever the client still sends is read and dropped
 * (requests after that get no reply), and it is closed at the client's end of stream, an
 * error, or LINGER_MS later (checked on its events, at stop and by idle_scan). */
#define LINGER_MS 2000

static void linger_drain(sts_conn *c)
{
    uint8_t b[4096];
    for (int i = 0; i < 64; i++) {
        ssize_t r = recv(c->fd, b, sizeof b, MSG_DONTWAIT);
        if (r > 0 || (r < 0 && errno == EINTR))
            continue; /* dropped */
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            break;    /* nothing more for now */
        conn_close(c); /* the client's end of stream, or an error */
        return;
    }
    if (sts_now_ms() >= c->linger_until)
        conn_close(c);
}

static void linger_start(sts_conn *c)
{
    shutdown(c->fd, SHUT_WR);
    c->linger_until = sts_now_ms() + LINGER_MS;
    /* nothing buffered is served any more: dropped with its buffers (the out queue is empty) */
    c->in.start = c->in.len;
    c->in2.start = c->in2.len;
    c->skip = 0;
    c->req_start_ms = 0;
    release_idle_buffers(c);
    if (c->ev_mask != STS_EV_READ) {
        sts_ev_mod(c->io->ev, c->fd, STS_EV_READ, c);
        c->ev_mask = STS_EV_READ;
    }
    linger_drain(c);
}

/* Writes what is pending. Returns -1 when the connection died (and was closed) or is ended
 * (close_after: lingering, linger_start). */
static int conn_flush(sts_conn *c)
{
    sts_server *srv = c->io->srv;
    while (stp_buf_avail(&c->out)) {
        ssize_t w = send(c->fd, stp_buf_head(&c->out), stp_buf_avail(&c->out),
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                break;
            conn_close(c);
            return -1;
        }
        STS_STAT_ADD(srv, writes, 1);
        STS_STAT_ADD(srv, bytes_out, (uint64_t)w);
        stp_buf_consume(&c->out, (size_t)w);
    }
    if (!stp_buf_avail(&c->out)) {
        stp_buf_clear(&c->out);
        if (c->in.cap <= KEEP_SMALL && c->in2.cap <= KEEP_SMALL && c->out.cap <= KEEP_SMALL)
            release_idle_buffers(c);  /* small: malloc reuses the chunks, no page faults */
        if (c->close_after) {
            linger_start(c);
            return -1;
        }
    }
    return 0;
}

static void conn_process(sts_conn *c);

/* Writes what is pending and, while the output empties and frames wait that backpressure
 * held back (c->held), parses on: with the daemon at max-memory a connection may leave one
 * reply unsent (out_backed_up), so each reply the socket takes lets it answer the next frame
 * already read, and it is read again only once those are answered (set_interest), so its
 * input does not grow while it is held. -1 as conn_flush. */
static int conn_serve(sts_conn *c)
{
    for (;;) {
        if (conn_flush(c) != 0)
            return -1;
        if (!c->held || stp_buf_avail(&c->out))
            return 0;
        conn_process(c);
        if (c->dead)
            return -1;
    }
}

/* Sends what the socket takes now, without closing on error (conn_flush, run after the
 * parse loop, sees the error again and closes). Used inside the parse loop once big replies
 * pile up, so the peer can start reading the first while the next are computed. */
static void try_send(sts_conn *c)
{
    sts_server *srv = c->io->srv;
    while (stp_buf_avail(&c->out)) {
        ssize_t w = send(c->fd, stp_buf_head(&c->out), stp_buf_avail(&c->out),
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w <= 0)
            return;
        STS_STAT_ADD(srv, writes, 1);
        STS_STAT_ADD(srv, bytes_out, (uint64_t)w);
        stp_buf_consume(&c->out, (size_t)w);
    }
}

/* Answers a frame the server refuses before dispatch, and arranges to skip its body. */
static void refuse(sts_conn *c, const stp_header *h, int status, const char *msg)
{
    sts_reply_error(&c->out, h, status, msg);
    STS_STAT_ADD(c->io->srv, replies_error, 1);
}

/* ---- request deadline ----------------------------------------------------------------------
 * A request frame must arrive whole within request-timeout seconds of its first byte, plus
 * its body's size at request-min-rate (a 4 MiB chunk at the default 128 KiB/s: +32 s). A
 * connection holding a half-sent frame past that is closed (conns_request_timeout), whatever
 * it trickles: bytes that arrive do not reset this clock (they do reset the idle clock). While
 * the server does not read the connection (a request on a worker, or backpressure: its unsent
 * replies over conn-out-cap) the clock is stopped, and it starts again from the next read. */

/* Keeps c->req_start_ms: set when an incomplete frame (or the body of a refused one being
 * skipped) is left in the input, 0 when there is none or the server is not reading. */
static void note_partial(sts_conn *c)
{
    int partial = c->in.len > c->in.start || c->in2.len > c->in2.start || c->skip;
    if (!partial || c->busy || c->yielded || out_backed_up(c))
        c->req_start_ms = 0;
    else if (!c->req_start_ms)
        c->req_start_ms = sts_now_ms();
}

/* Milliseconds the frame in progress may take in all. */
static int64_t request_allowance_ms(sts_server *srv, const sts_conn *c)
{
    uint64_t body = c->skip;
    if (!body && c->in.len - c->in.start >= STP_HEADER_SIZE)
        body = stp_rd32(c->in.data + c->in.start + 16);
    uint64_t rate = STS_LIVE(srv, request_min_rate);
    return (int64_t)STS_LIVE(srv, request_timeout) * 1000 + (int64_t)(body * 1000 / (rate ? rate : 1));
}

/* 1 when the frame in progress is past its deadline (request_allowance_ms), or - once
 * request-timeout has passed since its first byte - has fewer bytes here than
 * request-min-rate for the time since (a frame whose room is held: not a refused body being
 * skipped). The second rule stops a header that claims a big body from holding its room for
 * the whole allowance (5 s + 512 s for 64 MiB) while sending nothing. */
static int request_too_slow(sts_server *srv, const sts_conn *c, int64_t now)
{
    int64_t elapsed = now - c->req_start_ms;
    if (elapsed > request_allowance_ms(srv, c))
        return 1;
    int64_t grace = (int64_t)STS_LIVE(srv, request_timeout) * 1000;
    uint64_t rate = STS_LIVE(srv, request_min_rate);
    if (c->skip || elapsed <= grace || !rate)
        return 0;
    uint64_t got = (uint64_t)(c->in.len - c->in.start) + in2_avail(c);
    return got < (uint64_t)(elapsed - grace) * rate / 1000;
}

/* Parses and answers every complete frame in the input (see the file comment). */
static void conn_process(sts_conn *c)
{
    sts_server *srv = c->io->srv;
    c->held = 0;
    int64_t t0 = sts_now_ms();
    unsigned nframes = 0;
    while (!c->busy && !c->close_after && !c->dead) {
        account(c);   /* the replies written so far count against max-memory */
        if (out_backed_up(c)) {
            c->held = 1;   /* backpressure: answer the rest once the peer has read */
            break;
        }
        if (nframes && c->last_ms - t0 >= SLICE_MS &&
            (c->in.len > c->in.start || in2_avail(c))) {
            ready_push(c);   /* its time slice is used: the rest in the loop's next pass */
            break;
        }
        size_t avail = c->in.len - c->in.start;
        if (c->skip) {
            size_t n = avail < c->skip ? avail : (size_t)c->skip;
            in_consume(c, n);
            c->skip -= n;
            if (c->skip) {
                if (!in2_avail(c))
                    break;
                in_swap(c);   /* a split read: the rest is in the other buffer */
                continue;
            }
            c->req_start_ms = 0;   /* the refused frame is over */
            continue;
        }
        if (avail == 0) {
            if (!in2_avail(c))
                break;
            in_swap(c);   /* a split read: the next frame is in the other buffer */
            continue;
        }
        const uint8_t *head = c->in.data + c->in.start;
        uint64_t max_frame = STS_LIVE(srv, max_frame);
        stp_header h;
        int reason = 0;
        memset(&h, 0, sizeof h);
        int rc = stp_parse_header(head, avail, (size_t)max_frame, &h, &reason);
        if (rc == STP_NEED_MORE) {
            if (!in2_avail(c) || in_join_or_close(c) != 0)
                break;
            continue;
        }
        if (rc == STP_BAD) {
            if (stp_reason_fatal(reason)) {
                /* PROTOCOL.md 2.1: the stream cannot be resynchronised; close without a reply
                 * (replies already queued still go out first) */
                STS_STAT_ADD(srv, frames_bad_magic, 1);
                c->close_after = 1;
                in_consume(c, avail);
                break;
            }
            if (reason == STP_R_BAD_VERSION)
                STS_STAT_ADD(srv, frames_bad_version, 1);
            else
                STS_STAT_ADD(srv, frames_too_large, 1);
            char msg[160];
            if (reason == STP_R_TOO_LARGE)
                snprintf(msg, sizeof msg, "body of %u bytes is over max-frame %llu", h.body_len,
                         (unsigned long long)max_frame);
            else
                snprintf(msg, sizeof msg, "protocol version %u is not spoken here (1)", h.version);
            refuse(c, &h, stp_reason_status(reason), msg);
            in_consume(c, STP_HEADER_SIZE);
            c->skip = h.body_len;
            continue;
        }
        const sts_handler *hd = sts_handler_find(h.opcode);
        if (hd && hd->max_body && h.body_len > hd->max_body) {
            STS_STAT_ADD(srv, frames_too_large, 1);
            char msg[160];
            snprintf(msg, sizeof msg, "%s body of %u bytes is over its cap of %u", hd->name,
                     h.body_len, hd->max_body);
            refuse(c, &h, STP_S_TOO_LARGE, msg);
            in_consume(c, STP_HEADER_SIZE);
            c->skip = h.body_len;
            continue;
        }
        size_t total = STP_HEADER_SIZE + (size_t)h.body_len;
        if (avail < total) {
            if (in2_avail(c)) {
                if (in_join_or_close(c) != 0)
                    break;
                continue;
            }
            /* the frame is not all here: make room for it, within the memory limit - all of
             * it up to ROOM_STEP, else twice what has arrived (at least ROOM_STEP), grown as
             * more arrives (this runs after every read) */
            size_t room = total;
            if (total > ROOM_STEP)
                room = avail < ROOM_STEP / 2 ? ROOM_STEP : avail < total / 2 ? avail * 2 : total;
            /* room past twice what has arrived is taken ahead of its bytes: only while the
             * buffers stay under half of max-memory; else the frame's room grows as its bytes
             * arrive (ROOM_AHEAD) */
            size_t earned = avail < ROOM_AHEAD / 2 ? ROOM_AHEAD : avail * 2;
            if (room > earned && c->in.cap - c->in.start < room &&
                sts_mem_take_ahead(srv, room > c->in.cap ? room - c->in.cap : 0) != 0)
                room = earned;
            if (c->in.cap - c->in.start < room) {
                uint64_t grow = room > c->in.cap ? room - c->in.cap : 0;
                if (sts_mem_take(srv, grow) != 0 || in_reserve(c, room) != 0) {
                    STS_STAT_ADD(srv, mem_rejected, 1);
                    refuse(c, &h, STP_S_BUSY, "server buffer memory is at max-memory; retry");
                    in_consume(c, STP_HEADER_SIZE);
                    c->skip = h.body_len;
                    continue;
                }
            }
            break;
        }
        c->last_ms = sts_now_ms();
        c->req_start_ms = 0;   /* the frame is whole: its deadline is met */
        nframes++;
        c->in_pad = (uint8_t)in_pad(head, avail);
        c->next_total = h.opcode == STP_OP_SAMPLE && total >= SPLIT_MIN ? (uint32_t)total : 0;
        int d = sts_dispatch(c->io, c, &h, head + STP_HEADER_SIZE);
        if (d == 1)
            break;  /* on a worker: the frame stays in the buffer until the reply is back */
        in_consume(c, total);
        if (d == 2)
            c->close_after = 1;
        if (stp_buf_avail(&c->out) >= FLUSH_AT)
            try_send(c);
    }
    note_partial(c);
}

/* One read into the input (split in two buffers when a big SAMPLE frame ends it), then every
 * complete frame answered (conn_process). Returns 1 when the read filled all the room it was
 * offered (more is likely waiting in the socket), 0 when it did not or read nothing, -1 when
 * reading is over for this wake-up (the peer half-closed), -2 when the connection is closed
 * (c may be freed: not to be touched). */
static int read_once(sts_conn *c)
{
    sts_server *srv = c->io->srv;
    if (in2_avail(c) && in_join(c) != 0) {   /* not left by conn_process; kept safe */
        conn_close(c);
        return -2;
    }
    size_t unparsed = c->in.len - c->in.start;
    size_t need = unparsed + READ_MIN;
    size_t frame = 0;   /* a split read (above): the length of the frame it ends */
    size_t pad2 = c->in_pad;
    if (unparsed >= STP_HEADER_SIZE && !c->skip) {
        /* a frame is half-read and conn_process made room for all of it: read the rest
         * into that room rather than growing the buffer past the frame */
        const uint8_t *head = c->in.data + c->in.start;
        size_t total = STP_HEADER_SIZE + (size_t)stp_rd32(head + 16);
        if (total > unparsed && c->in.cap - c->in.start >= total) {
            need = total;
            if (head[5] == STP_OP_SAMPLE && total >= SPLIT_MIN) {
                frame = total;
                pad2 = in_pad(head, unparsed);
            }
        }
    } else if (unparsed == 0 && !c->skip && c->next_total) {
        frame = need = c->next_total;
    } else if (c->read_hint > need) {
        need = c->read_hint;   /* a deep burst of small frames: one read (conn_readable) */
    }
    if (in_reserve(c, need) != 0) {
        conn_close(c);
        return -2;
    }
    if (c->in.start == c->in.len && c->in.len != c->in_pad && c->in.cap - c->in_pad >= need)
        c->in.start = c->in.len = c->in_pad;   /* the next frame's queries aligned (in_pad) */
    struct iovec iov[2];
    iov[0].iov_base = c->in.data + c->in.len;
    iov[0].iov_len = c->in.cap - c->in.len;
    int niov = 1;
    if (frame && in2_prepare(c, pad2, frame) == 0) {
        iov[0].iov_len = c->in.start + frame - c->in.len;
        iov[1].iov_base = c->in2.data + c->in2.start;
        iov[1].iov_len = c->in2.cap - c->in2.start;
        niov = 2;
    }
    ssize_t r;
    do {
        if (c->unix_sock)
            r = sts_shm_recv(srv, c, iov, niov);
        else if (niov == 1)
            r = recv(c->fd, iov[0].iov_base, iov[0].iov_len, MSG_DONTWAIT);
        else
            r = recvmsg(c->fd, &(struct msghdr){.msg_iov = iov, .msg_iovlen = 2}, MSG_DONTWAIT);
    } while (r < 0 && errno == EINTR);
    if (r == 0 && stp_buf_avail(&c->out)) {
        c->close_after = 1;  /* the peer half-closed: still send what it asked for */
        return -1;
    }
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) {
        conn_close(c);
        return -2;
    }
    if (r < 0)
        return 0;
    size_t offered = iov[0].iov_len + (niov == 2 ? iov[1].iov_len : 0);
    if ((size_t)r > iov[0].iov_len) {
        c->in.len += iov[0].iov_len;
        c->in2.len += (size_t)r - iov[0].iov_len;
    } else {
        c->in.len += (size_t)r;
    }
    STS_STAT_ADD(srv, reads, 1);
    STS_STAT_ADD(srv, bytes_in, (uint64_t)r);
    c->wake_bytes += (uint32_t)r;
    c->last_ms = sts_now_ms();
    out_take_spare(c);
    conn_process(c);
    if (c->dead)
        return -2;
    return (size_t)r == offered;
}

/* A readable connection: read_once, and again while a read filled all its room (READS_MAX
 * reads a wake-up at most, for fairness between connections), then one flush of every reply.
 * A pipeline deeper than the buffer (8 x 256-query requests: 57 KiB against 32 KiB of room)
 * is so read and answered in one go instead of in two wake-ups, each with an epoll_wait and a
 * send, and the client is woken once for all of its replies.
 * One read for such a burst: when a wake-up read more than the default room (READ_MIN * 2)
 * its byte count becomes the connection's read_hint, and the next wake-up's first read is
 * offered that much room (at most HINT_MAX, so the buffer stays one the thread recycles,
 * KEEP_SMALL), 2 reads a burst -> 1 (a recv is 1-1.5 us of system call on this VM); a
 * wake-up that reads no more than the default room clears it. Split reads (SAMPLE frames of
 * SPLIT_MIN bytes and up) size their reads by the frame instead. */
#define READS_MAX 4
#define HINT_MAX  (KEEP_SMALL - 64)
static void conn_readable(sts_conn *c)
{
    if (c->busy || c->close_after)
        return;
    c->wake_bytes = 0;
    for (int k = 0; k < READS_MAX; k++) {
        if (k && (c->busy || c->close_after))
            break;
        if (out_backed_up(c) || c->held || c->yielded)
            break;   /* backpressure, or frames left for the next pass: not read now */
        int rc = read_once(c);
        if (rc == -2)
            return;
        if (rc != 1)
            break;
    }
    c->read_hint = c->wake_bytes <= READ_MIN * 2 ? 0
                   : c->wake_bytes < HINT_MAX ? c->wake_bytes : HINT_MAX;
    if (conn_serve(c) == 0)
        set_interest(c);
}

/* ---- eviction ------------------------------------------------------------------------------
 * When max-conns is reached, a new connection is not refused while a connection holds a
 * half-sent frame that began at least EVICT_AGE_MS ago: the one whose frame began first (the
 * slowest sender) is closed with a BUSY frame (conns_evicted) and the new one takes its slot.
 * Each I/O thread publishes its oldest candidate once a second (idle_scan); the accepting
 * thread evicts its own candidate at once, or asks the thread that owns an older one (claiming
 * the published value, so one candidate serves one newcomer). Only when no connection is half-
 * sent is the newcomer refused with BUSY. */
#define EVICT_AGE_MS 1000

/* The connection of this thread whose partial frame began first, at least EVICT_AGE_MS ago. */
static sts_conn *oldest_partial(sts_io *io, int64_t now)
{
    sts_conn *best = NULL;
    for (sts_conn *c = io->conns; c; c = c->next)
        if (!c->busy && !c->dead && c->req_start_ms && now - c->req_start_ms >= EVICT_AGE_MS &&
            (!best || c->req_start_ms < best->req_start_ms))
            best = c;
    return best;
}

/* Closes c with a frame (opcode HELLO, reqid 0) that says why. */
static void close_with(sts_conn *c, int status, const char *msg)
{
    stp_header h;
    memset(&h, 0, sizeof h);
    h.opcode = STP_OP_HELLO;
    sts_reply_error(&c->out, &h, status, msg);
    try_send(c);
    conn_close(c);
}

static void evict(sts_conn *c, int64_t now)
{
    sts_server *srv = c->io->srv;
    STS_STAT_ADD(srv, conns_evicted, 1);
    sts_logkv(&srv->log, STS_INFO,
              STS_FIELDS(STS_FS("event", "conn_evicted"), STS_FS("peer", c->peer),
                         STS_FI("incomplete_ms", now - c->req_start_ms)),
              "connection from %s evicted for a new one (max-conns): a request frame incomplete "
              "for %lld ms", c->peer, (long long)(now - c->req_start_ms));
    close_with(c, STP_S_BUSY, "evicted: a request frame incomplete for over a second while the "
               "server is at max-conns");
}

/* Frees a slot for a newcomer on `io`; 1 when one is (being) freed. */
static int evict_for(sts_io *io)
{
    sts_server *srv = io->srv;
    int64_t now = sts_now_ms();
    sts_conn *own = oldest_partial(io, now);
    sts_io *other = NULL;
    int64_t other_t = 0;
    for (uint32_t i = 0; i < srv->nio; i++) {
        sts_io *k = &srv->io[i];
        int64_t t = k == io ? 0 : __atomic_load_n(&k->oldest_partial_ms, __ATOMIC_RELAXED);
        if (t && (!other_t || t < other_t)) {
            other = k;
            other_t = t;
        }
    }
    if (own && (!other || own->req_start_ms <= other_t)) {
        evict(own, now);
        return 1;
    }
    if (other && __atomic_compare_exchange_n(&other->oldest_partial_ms, &other_t, 0, 0,
                                             __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
        __atomic_add_fetch(&other->evict_req, 1, __ATOMIC_RELAXED);
        sts_io_wake(other);
        return 1;
    }
    return 0;
}

/* Evictions other threads asked of this one (their newcomers are admitted already). */
static void take_evictions(sts_io *io)
{
    uint32_t n = __atomic_exchange_n(&io->evict_req, 0, __ATOMIC_RELAXED);
    int64_t now = sts_now_ms();
    while (n--) {
        sts_conn *c = oldest_partial(io, now);
        if (!c)
            break;   /* it finished its frame meanwhile: the table is one over for a while */
        evict(c, now);
    }
}

/* ---- accept ---------------------------------------------------------------------------------- */

static void reject(sts_server *srv, int fd, int status, const char *msg)
{
    stp_buf b;
    stp_buf_init(&b);
    stp_header h;
    memset(&h, 0, sizeof h);
    h.opcode = STP_OP_HELLO;
    sts_reply_error(&b, &h, status, msg);
    if (stp_buf_avail(&b)) {
        ssize_t w = send(fd, stp_buf_head(&b), stp_buf_avail(&b), MSG_NOSIGNAL | MSG_DONTWAIT);
        (void)w;
    }
    stp_buf_free(&b);
    /* no lingering here (the descriptor is wanted back at once), but the request the client
     * sent right after connecting is usually queued by now: read and dropped, so that the
     * close sends an end of stream after the answer, not a reset that may discard it */
    shutdown(fd, SHUT_WR);
    uint8_t drop[512];
    for (int i = 0; i < 16 && recv(fd, drop, sizeof drop, MSG_DONTWAIT) > 0; i++)
        ;
    close(fd);
    STS_STAT_ADD(srv, conns_rejected, 1);
}

/* "1.2.3.4:5678" or "[::1]:5678". */
static void peer_name(const struct sockaddr_storage *sa, char *out, size_t cap)
{
    char a[INET6_ADDRSTRLEN] = "?";
    unsigned port = 0;
    if (sa->ss_family == AF_INET) {
        const struct sockaddr_in *in = (const struct sockaddr_in *)sa;
        inet_ntop(AF_INET, &in->sin_addr, a, sizeof a);
        port = ntohs(in->sin_port);
        if (snprintf(out, cap, "%.46s:%u", a, port) < 0 && cap)
            out[0] = 0;
    } else if (sa->ss_family == AF_INET6) {
        const struct sockaddr_in6 *in6 = (const struct sockaddr_in6 *)sa;
        inet_ntop(AF_INET6, &in6->sin6_addr, a, sizeof a);
        port = ntohs(in6->sin6_port);
        if (snprintf(out, cap, "[%.46s]:%u", a, port) < 0 && cap)
            out[0] = 0;
    } else if (sa->ss_family == AF_UNIX) {
        snprintf(out, cap, "(unix socket)");
    } else {
        snprintf(out, cap, "(unknown peer)");
    }
}

/* The I/O thread a new connection goes to: the one with the fewest connections, this one
 * on a tie (no hand-off). The listening socket wakes one poller per connection
 * (EPOLLEXCLUSIVE) but not in turn: clients that connect one after another are often all
 * accepted by the same thread, so the acceptor balances instead of the kernel. */
static sts_io *pick_io(sts_io *self)
{
    sts_server *srv = self->srv;
    sts_io *best = self;
    uint32_t least = __atomic_load_n(&self->nconns, __ATOMIC_RELAXED);
    for (uint32_t i = 0; i < srv->nio; i++) {
        uint32_t n = __atomic_load_n(&srv->io[i].nconns, __ATOMIC_RELAXED);
        if (n < least) {
            least = n;
            best = &srv->io[i];
        }
    }
    return best;
}

/* Puts a connection assigned to this thread (c->io, counted in io->nconns already) in its
 * poller and list; on failure it is answered INTERNAL and closed. */
static void conn_attach(sts_conn *c)
{
    sts_io *io = c->io;
    sts_server *srv = io->srv;
    if (sts_ev_add(io->ev, c->fd, STS_EV_READ, c) != 0) {
        int fd = c->fd;
        stp_buf_free(&c->out);
        free(c);
        __atomic_sub_fetch(&io->nconns, 1, __ATOMIC_RELAXED);
        __atomic_sub_fetch(&srv->nconns, 1, __ATOMIC_RELAXED);
        reject(srv, fd, STP_S_INTERNAL, "poller");
        return;
    }
    c->prev = NULL;
    c->next = io->conns;
    if (io->conns)
        io->conns->prev = c;
    io->conns = c;
    __atomic_add_fetch(&io->accepted, 1, __ATOMIC_RELAXED);
    STS_STAT_ADD(srv, conns_accepted, 1);
}

/* Connections other I/O threads accepted for this one. */
static void take_adopted(sts_io *io)
{
    pthread_mutex_lock(&io->mu);
    sts_conn *list = io->adopt;
    io->adopt = NULL;
    pthread_mutex_unlock(&io->mu);
    while (list) {
        sts_conn *c = list;
        list = c->next;
        conn_attach(c);
    }
}

/* accept4 failed with EMFILE / ENFILE while connections wait in the backlog. The listener
 * stays readable (level-triggered), so returning would wake this loop again at once: before
 * dur28 an fd limit below the connections offered spun the I/O threads and logged the
 * warning millions of times a minute. Instead the spare descriptor is closed, one waiting
 * connection accepted and answered BUSY ("out of file descriptors"), and the spare taken
 * again; 1 when one was shed (the caller goes on with the backlog). Called with accept_mu
 * held, as every accept4 is: before, another I/O thread's accept could take the slot the
 * spare had just freed, this accept then failed, the spare could not be reopened, and with
 * no spare left the waiting connections were never answered while the limit held (seen as a
 * connection without an answer in test_server_limits at load ~5). Without a spare (it could
 * not be reopened: some other open took the slot) the listener leaves this thread's poller
 * until its next 1 s tick, which tries to reopen it (spare_reopen). One log line per 10 s,
 * with the count shed since the last one. */
static int accept_starved(sts_io *io, int err)
{
    sts_server *srv = io->srv;
    int shed = 0;
    int spare = __atomic_load_n(&srv->spare_fd, __ATOMIC_RELAXED);
    if (spare >= 0) {
        close(spare);
        int fd = accept4(srv->listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd >= 0) {
            reject(srv, fd, STP_S_BUSY,
                   "out of file descriptors: the server cannot take a connection now");
            __atomic_add_fetch(&srv->starved_shed, 1, __ATOMIC_RELAXED);
            shed = 1;
        }
        __atomic_store_n(&srv->spare_fd, open("/dev/null", O_RDONLY | O_CLOEXEC), __ATOMIC_RELAXED);
    }
    if (!shed && !io->listen_paused && sts_ev_del(io->ev, srv->listen_fd) == 0)
        io->listen_paused = 1;
    int64_t now = sts_now_ms();
    int64_t last = __atomic_load_n(&srv->starved_log_ms, __ATOMIC_RELAXED);
    if ((last == 0 || now - last >= 10000) &&
        __atomic_compare_exchange_n(&srv->starved_log_ms, &last, now, 0, __ATOMIC_RELAXED,
                                    __ATOMIC_RELAXED)) {
        uint64_t n = __atomic_exchange_n(&srv->starved_shed, 0, __ATOMIC_RELAXED);
        sts_logf(&srv->log, STS_WARN, "accept: %s: %llu connections answered BUSY in the last "
                 "10 s (raise the fd limit or lower max-conns)", strerror(err),
                 (unsigned long long)n);
    }
    return shed;
}

/* The spare descriptor, when accept_starved could not reopen it: taken again once a slot is
 * free (each I/O thread's 1 s tick). */
static void spare_reopen(sts_server *srv)
{
    pthread_mutex_lock(&srv->accept_mu);
    if (__atomic_load_n(&srv->spare_fd, __ATOMIC_RELAXED) < 0)
        __atomic_store_n(&srv->spare_fd, open("/dev/null", O_RDONLY | O_CLOEXEC), __ATOMIC_RELAXED);
    pthread_mutex_unlock(&srv->accept_mu);
}

static void do_accept(sts_io *io)
{
    sts_server *srv = io->srv;
    for (int i = 0; i < 64; i++) {
        struct sockaddr_storage sa;
        socklen_t salen = sizeof sa;
        pthread_mutex_lock(&srv->accept_mu);
        int fd = accept4(srv->listen_fd, (struct sockaddr *)&sa, &salen,
                         SOCK_NONBLOCK | SOCK_CLOEXEC);
        int err = fd < 0 ? errno : 0, shed = 0;
        if (fd < 0 && (err == EMFILE || err == ENFILE))
            shed = accept_starved(io, err);
        pthread_mutex_unlock(&srv->accept_mu);
        if (fd < 0) {
            if (shed)
                continue;
            return;
        }
        if (__atomic_load_n(&srv->stopping, __ATOMIC_RELAXED)) {
            reject(srv, fd, STP_S_SHUTDOWN, "server is stopping");
            continue;
        }
        uint32_t n = __atomic_add_fetch(&srv->nconns, 1, __ATOMIC_RELAXED);
        if (n > STS_LIVE(srv, max_conns) && !evict_for(io)) {
            __atomic_sub_fetch(&srv->nconns, 1, __ATOMIC_RELAXED);
            reject(srv, fd, STP_S_BUSY, "too many connections (max-conns)");
            continue;
        }
        sts_conn *c = calloc(1, sizeof *c);
        if (!c) {
            __atomic_sub_fetch(&srv->nconns, 1, __ATOMIC_RELAXED);
            reject(srv, fd, STP_S_NOMEM, "out of memory");
            continue;
        }
        int one = 1;
        if (sa.ss_family != AF_UNIX)
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        else
            stu_unix_sndbuf(fd);  /* a big reply in one write (unixaddr.h) */
        c->unix_sock = sa.ss_family == AF_UNIX;
        c->fd = fd;
        c->id = __atomic_add_fetch(&srv->next_conn_id, 1, __ATOMIC_RELAXED);
        c->last_ms = sts_now_ms();
        peer_name(&sa, c->peer, sizeof c->peer);
        stp_buf_init(&c->out);
        c->ev_mask = STS_EV_READ;
        sts_io *to = pick_io(io);
        c->io = to;
        __atomic_add_fetch(&to->nconns, 1, __ATOMIC_RELAXED);
        if (to == io) {
            conn_attach(c);
        } else {
            pthread_mutex_lock(&to->mu);
            c->next = to->adopt;
            to->adopt = c;
            pthread_mutex_unlock(&to->mu);
            sts_io_wake(to);
        }
    }
}

/* ---- completions from workers ---------------------------------------------------------------- */

void sts_io_wake(sts_io *io)
{
    uint64_t one = 1;
    ssize_t w = write(io->wakefd, &one, sizeof one);
    (void)w;
}

void sts_io_complete(sts_io *io, sts_task *t)
{
    pthread_mutex_lock(&io->mu);
    t->next = io->done;
    io->done = t;
    pthread_mutex_unlock(&io->mu);
    sts_io_wake(io);
}

static void take_completions(sts_io *io)
{
    uint64_t v;
    ssize_t r = read(io->wakefd, &v, sizeof v);
    (void)r;
    take_adopted(io);
    pthread_mutex_lock(&io->mu);
    sts_task *list = io->done;
    io->done = NULL;
    pthread_mutex_unlock(&io->mu);
    /* the list is newest first; different connections are independent and a connection has
     * at most one task out, so the order between them does not matter */
    while (list) {
        sts_task *t = list;
        list = t->next;
        sts_conn *c = t->conn;
        c->busy = 0;
        if (!c->dead) {
            if (!stp_buf_avail(&c->out)) {
                stp_buf tmp = c->out;   /* nothing pending: take the worker's buffer, no copy */
                c->out = t->out;
                t->out = tmp;
            } else {
                stp_put_bytes(&c->out, stp_buf_head(&t->out), stp_buf_avail(&t->out));
            }
            in_consume(c, STP_HEADER_SIZE + (size_t)t->h.body_len);
            if (t->close)
                c->close_after = 1;
        }
        stp_buf_free(&t->out);
        free(t);
        if (c->dead) {
            conn_free(c);
            continue;
        }
        account(c);
        conn_process(c);   /* pipelined requests that waited behind this one */
        if (c->dead)
            continue;
        if (conn_serve(c) == 0)
            set_interest(c);
    }
}

/* ---- the loop ------------------------------------------------------------------------------ */

/* Once a second: close connections whose request frame is past its deadline or that were
 * silent for idle-timeout, release the buffers of those quiet for a second, publish the
 * oldest half-sent frame (eviction). */
static void idle_scan(sts_io *io, int64_t now)
{
    sts_server *srv = io->srv;
    uint32_t idle = STS_LIVE(srv, idle_timeout);
    int deadline = STS_LIVE(srv, request_timeout) != 0;
    int64_t oldest = 0;
    sts_uploads_sweep(srv, now);
    sts_conn *c = io->conns;
    while (c) {
        sts_conn *next = c->next;
        if (c->linger_until) {
            if (!c->dead && now >= c->linger_until)
                conn_close(c);
        } else if (deadline && !c->busy && !c->dead && c->req_start_ms &&
                   request_too_slow(srv, c, now)) {
            STS_STAT_ADD(srv, conns_request_timeout, 1);
            sts_logkv(&srv->log, STS_INFO,
                      STS_FIELDS(STS_FS("event", "conn_request_timeout"), STS_FS("peer", c->peer),
                                 STS_FI("incomplete_ms", now - c->req_start_ms)),
                      "connection from %s closed: a request frame incomplete %lld ms after its "
                      "first byte (request-timeout)", c->peer, (long long)(now - c->req_start_ms));
            close_with(c, STP_S_TIMEOUT, "a request frame did not arrive whole within "
                       "request-timeout: connection closed");
        } else if (!c->busy && idle && now - c->last_ms > (int64_t)idle * 1000) {
            STS_STAT_ADD(io->srv, conns_idle_closed, 1);
            conn_close(c);
        } else {
            if (now - c->last_ms >= 1000 && (c->in.data || c->in2.data || c->out.data))
                release_idle_buffers(c);
            if (!c->busy && c->req_start_ms && now - c->req_start_ms >= EVICT_AGE_MS &&
                (!oldest || c->req_start_ms < oldest))
                oldest = c->req_start_ms;
        }
        c = next;
    }
    __atomic_store_n(&io->oldest_partial_ms, oldest, __ATOMIC_RELAXED);
}

/* 1 when the connection is quiet: no request on a worker, no reply unsent, no partial frame
 * buffered, and nothing waiting in the socket. */
static int conn_quiet(sts_conn *c)
{
    if (c->busy || stp_buf_avail(&c->out) || c->in.len > c->in.start ||
        c->in2.len > c->in2.start || c->skip)
        return 0;
    uint8_t b;
    ssize_t r = recv(c->fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
    return r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
}

/* At stop (SIGTERM): no new connections; every request a client sent before the stop is
 * still read and answered; a connection is shut once it is quiet (see conn_quiet) and closed
 * after lingering (linger_start), or when it has hung up. When forced (the grace period is
 * over) whatever is not on a worker is closed. Returns connections left. */
static uint32_t drain_step(sts_io *io, int force)
{
    sts_conn *c = io->conns;
    while (c) {
        sts_conn *next = c->next;
        if (!c->busy) {
            if (force) {
                conn_close(c);
            } else if (c->linger_until && !c->dead) {
                linger_drain(c);
            } else if (!c->dead && conn_serve(c) == 0) {
                if (conn_quiet(c))
                    linger_start(c);
                else
                    set_interest(c);
            }
        }
        c = next;
    }
    return io->nconns;
}

void *sts_io_main(void *arg)
{
    sts_io *io = arg;
    sts_server *srv = io->srv;
    sts_ev_event evs[256];
    int listening = sts_ev_add(io->ev, srv->listen_fd, STS_EV_READ | STS_EV_EXCLUSIVE, srv) == 0;
    if (!listening)
        sts_logf(&srv->log, STS_ERROR, "I/O thread %d cannot poll the listening socket: %s",
                 io->index, strerror(errno));
    sts_ev_add(io->ev, io->wakefd, STS_EV_READ, io);
    int64_t last_scan = sts_now_ms();
    for (;;) {
        int stopping = __atomic_load_n(&srv->stopping, __ATOMIC_ACQUIRE);
        if (stopping) {
            if (listening) {
                if (!io->listen_paused)
                    sts_ev_del(io->ev, srv->listen_fd);
                listening = 0;
            }
            if (drain_step(io, stopping >= 2) == 0)
                break;
        }
        int n = sts_ev_wait(io->ev, evs, 256, io->ready ? 0 : stopping ? 20 : 1000);
        for (int i = 0; i < n; i++) {
            void *p = evs[i].ptr;
            if (p == srv) {
                do_accept(io);
            } else if (p == io) {
                take_completions(io);
            } else {
                sts_conn *c = p;
                if (c->dead)
                    continue;
                if (c->linger_until) { /* shut at stop: input is dropped (linger_start) */
                    linger_drain(c);
                    continue;
                }
                if (evs[i].events & STS_EV_WRITE) {
                    if (conn_flush(c) != 0)
                        continue;
                    conn_process(c);  /* backpressure released: parse what waited */
                    if (c->dead || conn_serve(c) != 0)
                        continue;
                    set_interest(c);
                }
                if (evs[i].events & STS_EV_ERROR) {
                    if (!c->busy && !(c->ev_mask & STS_EV_READ)) {
                        conn_close(c);
                        continue;
                    }
                }
                if ((evs[i].events & STS_EV_READ) && (c->ev_mask & STS_EV_READ))
                    conn_readable(c);
                else if ((evs[i].events & STS_EV_ERROR) && c->busy)
                    conn_close(c);  /* freed when the worker's reply comes back */
            }
        }
        /* connections that yielded their time slice (above) parse on, each one slice more */
        io->ready_pass = io->ready;
        io->ready = NULL;
        sts_conn *c;
        while ((c = io->ready_pass)) {
            io->ready_pass = c->ready_next;
            c->ready_next = NULL;
            c->yielded = 0;
            if (c->dead || c->linger_until)
                continue;
            conn_process(c);
            if (c->dead || conn_serve(c) != 0)
                continue;
            set_interest(c);
        }
        if (__atomic_load_n(&io->evict_req, __ATOMIC_RELAXED))
            take_evictions(io);
        int64_t now = sts_now_ms();
        if (now - last_scan >= 1000) {
            idle_scan(io, now);
            last_scan = now;
            /* back to accepting after an fd shortage paused it (accept_starved) */
            if (__atomic_load_n(&srv->spare_fd, __ATOMIC_RELAXED) < 0)
                spare_reopen(srv);
            if (io->listen_paused && listening && !stopping &&
                sts_ev_add(io->ev, srv->listen_fd, STS_EV_READ | STS_EV_EXCLUSIVE, srv) == 0)
                io->listen_paused = 0;
        }
    }
    /* the loop ends with no connection left; a task still out would have kept one */
    return NULL;
}
