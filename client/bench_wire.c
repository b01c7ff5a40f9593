/* client/bench_wire.c - the load tester's side of the protocol: connecting (loopback only,
 * HELLO with the token), asking INFO for the set's size, building pools of ready request
 * frames, and recognising complete replies in a byte stream.
 *
 * Owns: the request pools (one per thread) and the random query batches. Does not own:
 * framing or body layouts - every byte comes from protocol/'s encoders (stp_enc_*) and the
 * header parser (stp_parse_header); nothing here re-implements them.
 *
 * The peers (--proto memcached | redis) exist only to put seamtexd's PING beside other
 * servers' cheapest request under the same load generator: memcached's text-protocol
 * "version\r\n" (answered "VERSION 1.6.18\r\n") and Redis's PING in RESP
 * ("*1\r\n$4\r\nPING\r\n", answered "+PONG\r\n"). Their replies are one line each and
 * come back in request order. Not memcached's meta no-op "mn": it is meant to end a batch of
 * quiet requests and memcached flushes its output after each one, so pipelined mn measured
 * about 3x below "version" (115-135k against 315-370k req/s at 50 x 16 in flight, load 7).
 *
 * The event loop copies a pool frame into a connection's output and patches the request id
 * (header offset 8), so frames are built once, not per request.
 */
#include "bench.h"

#include <errno.h>
#include <math.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/mman.h>
#include <unistd.h>

#include "proto.h"
#include "sample.h"
#include "fdio.h"
#include "shmfd.h"
#include "unixaddr.h"

struct bench_wire {
    stp_buf  buf;               /* every frame of the pool, back to back */
    size_t   off[BENCH_POOL + 1];
    uint32_t nq[BENCH_POOL];
    unsigned n, next;
};

void bench_make_queries(struct st_query *q, size_t n, uint32_t nfaces, float fp, uint64_t *rng)
{
    for (size_t i = 0; i < n; i++) {
        q[i].face = nfaces ? (uint32_t)(stc_rng_next(rng) % nfaces) : 0;
        q[i].u = (float)stc_rng_unit(rng);
        q[i].v = (float)stc_rng_unit(rng);
        q[i].dudx = fp;
        q[i].dvdx = 0;
        q[i].dudy = 0;
        q[i].dvdy = fp;
    }
}

static int is_loopback(const struct sockaddr *sa)
{
    if (sa->sa_family == AF_INET) {
        const struct sockaddr_in *a = (const struct sockaddr_in *)sa;
        return (ntohl(a->sin_addr.s_addr) >> 24) == 127;
    }
    if (sa->sa_family == AF_INET6) {
        const struct sockaddr_in6 *a = (const struct sockaddr_in6 *)sa;
        if (IN6_IS_ADDR_LOOPBACK(&a->sin6_addr))
            return 1;
        if (IN6_IS_ADDR_V4MAPPED(&a->sin6_addr))
            return a->sin6_addr.s6_addr[12] == 127;
    }
    return 0;
}

/* Blocking request/reply on a fresh socket: sends b's frame (with descriptor passfd as
 * SCM_RIGHTS when >= 0), reads one reply frame into *body (malloc'd, caller frees). Returns 0,
 * or -1 with msg. */
static int roundtrip_fd(int fd, stp_buf *b, stp_header *h, uint8_t **body, char *msg,
                        size_t ml, int passfd)
{
    *body = NULL;
    ssize_t first = 0;
    if (passfd >= 0 && (first = stu_send_with_fd(fd, stp_buf_head(b), stp_buf_avail(b),
                                                 passfd)) < 0) {
        snprintf(msg, ml, "sendmsg: %s", strerror(errno));
        return -1;
    }
    if (stu_write_all(fd, stp_buf_head(b) + first, stp_buf_avail(b) - (size_t)first) < 0) {
        snprintf(msg, ml, "write: %s", strerror(errno));
        return -1;
    }
    uint8_t hdr[STP_HEADER_SIZE];
    int reason = 0;
    if (stu_read_all(fd, hdr, sizeof hdr) < 0) {
        snprintf(msg, ml, errno == EAGAIN || errno == EWOULDBLOCK ? "no reply within the timeout"
                                                                   : "the server closed the connection");
        return -1;
    }
    if (stp_parse_header(hdr, sizeof hdr, STP_DEFAULT_MAX_BODY, h, &reason) != STP_OK) {
        snprintf(msg, ml, "bad reply header (%s)", stp_reason_name(reason));
        return -1;
    }
    *body = malloc(h->body_len ? h->body_len : 1);
    if (!*body || stu_read_all(fd, *body, h->body_len) < 0) {
        free(*body);
        *body = NULL;
        snprintf(msg, ml, "reply body cut short");
        return -1;
    }
    return 0;
}

static int roundtrip(int fd, stp_buf *b, stp_header *h, uint8_t **body, char *msg, size_t ml)
{
    return roundtrip_fd(fd, b, h, body, msg, ml, -1);
}

static void status_msg(const stp_header *h, const uint8_t *body, const char *what, char *msg,
                       size_t ml)
{
    char m[STP_MAX_MSG + 1];
    stp_dec_error(body, h->body_len, m, sizeof m);
    snprintf(msg, ml, "%s: %s: %s", what, stp_status_name(h->status), m);
}

/* HELLO on a blocking socket: 0, or -1 with msg. */
static int hello(const bench_cfg *cfg, int fd, char *msg, size_t ml)
{
    stp_buf b;
    stp_buf_init(&b);
    stp_hello_req hr;
    memset(&hr, 0, sizeof hr);
    hr.min_version = hr.max_version = STP_VERSION;
    hr.caps = STP_CAP_PIPELINE;
    if (cfg->token)
        snprintf(hr.token, sizeof hr.token, "%s", cfg->token);
    snprintf(hr.client_name, sizeof hr.client_name, "seamtex-bench");
    stp_header h;
    uint8_t *body = NULL;
    int rc = -1;
    if (stp_enc_hello_req(&b, 1, 0, &hr) != 0) {
        snprintf(msg, ml, "cannot encode HELLO");
    } else if (roundtrip(fd, &b, &h, &body, msg, ml) == 0) {
        if (h.status != STP_S_OK)
            status_msg(&h, body, "HELLO", msg, ml);
        else
            rc = 0;
    }
    free(body);
    stp_buf_free(&b);
    return rc;
}

/* One reply line of a peer on a blocking socket, "\r\n" stripped: 0, or -1 with msg. */
static int peer_line(int fd, char *line, size_t cap, char *msg, size_t ml)
{
    size_t n = 0;
    for (;;) {
        char ch;
        ssize_t r = read(fd, &ch, 1);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0) {
            snprintf(msg, ml, r < 0 ? "no reply within the timeout"
                                    : "the server closed the connection");
            return -1;
        }
        if (ch == '\n' && n > 0 && line[n - 1] == '\r') {
            line[n - 1] = 0;
            return 0;
        }
        if (n + 1 >= cap) {
            snprintf(msg, ml, "a reply line longer than %zu bytes", cap);
            return -1;
        }
        line[n++] = ch;
    }
}

/* Checks that the port speaks the peer's protocol: memcached "version" must get "VERSION x",
 * Redis PING must get +PONG. 0, or -1 with msg. */
static int peer_hello(const bench_cfg *cfg, int fd, char *msg, size_t ml)
{
    const char *req = cfg->proto == BENCH_PROTO_MEMCACHED ? "version\r\n"
                                                          : "*1\r\n$4\r\nPING\r\n";
    char line[256];
    if (stu_write_all(fd, req, strlen(req)) < 0) {
        snprintf(msg, ml, "write: %s", strerror(errno));
        return -1;
    }
    if (peer_line(fd, line, sizeof line, msg, ml) < 0)
        return -1;
    if (cfg->proto == BENCH_PROTO_REDIS) {
        if (strcmp(line, "+PONG") == 0)
            return 0;
        snprintf(msg, ml, "redis PING answered '%.100s'", line);
        return -1;
    }
    if (strncmp(line, "VERSION ", 8) == 0)
        return 0;
    snprintf(msg, ml, "memcached 'version' answered '%.100s'", line);
    return -1;
}

/* A connected socket to a "unix:/path" address (same host by construction), or -1. */
static int connect_unix(const bench_cfg *cfg, char *msg, size_t ml)
{
    struct sockaddr_un sa;
    socklen_t len;
    if (stu_unix_addr(cfg->host, &sa, &len) != 0) {
        snprintf(msg, ml, "%s: %s", cfg->host, strerror(errno));
        return -1;
    }
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        snprintf(msg, ml, "socket: %s", strerror(errno));
        return -1;
    }
    if (connect(fd, (struct sockaddr *)&sa, len) != 0) {
        snprintf(msg, ml, "connect %s: %s", cfg->host, strerror(errno));
        close(fd);
        return -1;
    }
    stu_unix_sndbuf(fd);   /* a big request in one write (unixaddr.h) */
    return fd;
}

int bench_wire_connect(const bench_cfg *cfg, char *msg, size_t ml)
{
    int fd = -1;
    if (stu_is_unix_addr(cfg->host)) {
        fd = connect_unix(cfg, msg, ml);
        if (fd < 0)
            return -1;
        goto connected;
    }
    struct addrinfo hints = { .ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM }, *ai = NULL;
    int g = getaddrinfo(cfg->host, cfg->port, &hints, &ai);
    if (g != 0) {
        snprintf(msg, ml, "%s:%s: %s", cfg->host, cfg->port, gai_strerror(g));
        return -1;
    }
    for (struct addrinfo *a = ai; a; a = a->ai_next) {
        if (!is_loopback(a->ai_addr)) {
            snprintf(msg, ml, "%s is not a loopback address: seamtex-bench only loads "
                     "servers on this machine", cfg->host);
            continue;
        }
        fd = socket(a->ai_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd < 0) {
            snprintf(msg, ml, "socket: %s", strerror(errno));
            continue;
        }
        if (connect(fd, a->ai_addr, a->ai_addrlen) == 0)
            break;
        snprintf(msg, ml, "connect %s:%s: %s", cfg->host, cfg->port, strerror(errno));
        close(fd);
        fd = -1;
    }
    freeaddrinfo(ai);
    if (fd < 0)
        return -1;
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
connected:;
    /* the blocking set-up exchanges (HELLO, INFO) give up after the request timeout */
    struct timeval tv = { .tv_sec = (time_t)cfg->timeout_s,
                          .tv_usec = (suseconds_t)((cfg->timeout_s - (double)(time_t)cfg->timeout_s) * 1e6) };
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);

    int rc = cfg->proto == BENCH_PROTO_SEAMTEX ? hello(cfg, fd, msg, ml)
                                               : peer_hello(cfg, fd, msg, ml);
    if (rc < 0) {
        close(fd);
        return -1;
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        snprintf(msg, ml, "fcntl: %s", strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}


int bench_wire_set_info(bench_cfg *cfg, int fd, char *msg, size_t ml)
{
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl & ~O_NONBLOCK) < 0) {
        snprintf(msg, ml, "fcntl: %s", strerror(errno));
        return -1;
    }
    stp_buf b;
    stp_buf_init(&b);
    stp_info_req ir;
    memset(&ir, 0, sizeof ir);
    snprintf(ir.name, sizeof ir.name, "%s", cfg->set);
    stp_header h;
    uint8_t *body = NULL;
    int rc = -1;
    if (stp_enc_info_req(&b, 2, 0, &ir) != 0) {
        snprintf(msg, ml, "cannot encode INFO for '%s'", cfg->set);
    } else if (roundtrip(fd, &b, &h, &body, msg, ml) == 0) {
        stp_info_reply r;
        const char *why = "";
        if (h.status != STP_S_OK) {
            status_msg(&h, body, "INFO", msg, ml);
        } else if (stp_dec_info_reply(body, h.body_len, &r, &why) != 0) {
            snprintf(msg, ml, "INFO reply malformed (%s)", why);
        } else if (r.nfaces == 0) {
            snprintf(msg, ml, "set '%s' has no faces", cfg->set);
        } else if (cfg->op == BENCH_OP_SAMPLE_DIR && r.kind != STP_KIND_CUBE) {
            snprintf(msg, ml, "set '%s' is not a cube map: -o sample-dir needs one", cfg->set);
        } else {
            cfg->nfaces = r.nfaces;
            cfg->nchan = r.nchan;
            cfg->kind = r.kind;
            rc = 0;
        }
    }
    free(body);
    stp_buf_free(&b);
    if (rc == 0 && fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        snprintf(msg, ml, "fcntl: %s", strerror(errno));
        rc = -1;
    }
    return rc;
}

/* SAMPLE_DIR frames: directions uniform on the sphere, a cone footprint of cfg->footprint
 * radians (0 = a point-like derivative footprint). */
static bench_wire *dir_pool(bench_wire *w, const bench_cfg *cfg, uint64_t *rng, char *msg,
                            size_t ml)
{
    stp_dir_query *q = malloc(cfg->batch * sizeof *q);
    if (!q)
        goto fail;
    w->n = BENCH_POOL;
    for (unsigned i = 0; i < BENCH_POOL; i++) {
        for (unsigned k = 0; k < cfg->batch; k++) {
            /* uniform on the sphere: z uniform in [-1,1], the angle around z uniform */
            double z = 2.0 * stc_rng_unit(rng) - 1.0, a = 6.283185307179586 * stc_rng_unit(rng);
            double rxy = sqrt(1.0 - z * z);
            memset(&q[k], 0, sizeof q[k]);
            q[k].dir[0] = (float)(rxy * cos(a));
            q[k].dir[1] = (float)(rxy * sin(a));
            q[k].dir[2] = (float)z;
            q[k].ddx[0] = cfg->footprint;
        }
        stp_sample_req r;
        memset(&r, 0, sizeof r);
        snprintf(r.p.name, sizeof r.p.name, "%s", cfg->set);
        r.p.mode = cfg->modes[stc_rng_next(rng) % cfg->nmodes];
        r.p.filter = cfg->filters[stc_rng_next(rng) % cfg->nfilters];
        r.p.outfmt = cfg->outfmt;
        r.p.footprint = cfg->footprint > 0 ? STP_FP_CONE : STP_FP_DERIV;
        r.count = cfg->batch;
        r.dqueries = q;
        w->off[i] = w->buf.len;
        if (stp_enc_sample_dir_req(&w->buf, 0, 0, &r) != 0) {
            free(q);
            goto fail;
        }
        w->nq[i] = cfg->batch;
    }
    w->off[BENCH_POOL] = w->buf.len;
    free(q);
    return w;
fail:
    snprintf(msg, ml, "cannot build SAMPLE_DIR frames (out of memory or bad set name)");
    bench_wire_free(w);
    return NULL;
}

bench_wire *bench_wire_new(const bench_cfg *cfg, uint64_t seed, char *msg, size_t ml)
{
    bench_wire *w = calloc(1, sizeof *w);
    if (!w) {
        snprintf(msg, ml, "out of memory");
        return NULL;
    }
    stp_buf_init(&w->buf);
    if (cfg->proto != BENCH_PROTO_SEAMTEX) {
        static const char version[] = "version\r\n", ping[] = "*1\r\n$4\r\nPING\r\n";
        const char *req = cfg->proto == BENCH_PROTO_MEMCACHED ? version : ping;
        w->n = 1;
        stp_put_bytes(&w->buf, req, strlen(req));
        if (w->buf.err)
            goto fail;
        w->off[1] = w->buf.len;
        return w;
    }
    if (cfg->op == BENCH_OP_PING) {
        w->n = 1;
        if (stp_enc_empty(&w->buf, STP_OP_PING, 0, 0, 0) != 0)
            goto fail;
        w->off[1] = w->buf.len;
        return w;
    }
    uint64_t rng = stc_rng_seed(seed);
    if (cfg->op == BENCH_OP_SAMPLE_DIR)
        return dir_pool(w, cfg, &rng, msg, ml);
    st_query *q = malloc(cfg->batch * sizeof *q);
    if (!q)
        goto fail;
    w->n = BENCH_POOL;
    for (unsigned i = 0; i < BENCH_POOL; i++) {
        bench_make_queries(q, cfg->batch, cfg->nfaces, cfg->footprint, &rng);
        stp_sample_req r;
        memset(&r, 0, sizeof r);
        snprintf(r.p.name, sizeof r.p.name, "%s", cfg->set);
        r.p.mode = cfg->modes[stc_rng_next(&rng) % cfg->nmodes];
        r.p.filter = cfg->filters[stc_rng_next(&rng) % cfg->nfilters];
        r.p.outfmt = cfg->outfmt;
        if (cfg->compact)
            r.p.flags = STP_SF_UV16 | (cfg->nfaces <= 65536 ? STP_SF_FACE16 : 0);
        r.count = cfg->batch;
        /* st_query and stp_query have the same fields in the same order */
        _Static_assert(sizeof(st_query) == sizeof(stp_query), "query layouts differ");
        r.queries = (const stp_query *)q;
        w->off[i] = w->buf.len;
        if (stp_enc_sample_req(&w->buf, 0, 0, &r) != 0) {
            free(q);
            goto fail;
        }
        w->nq[i] = cfg->batch;
    }
    w->off[BENCH_POOL] = w->buf.len;
    free(q);
    return w;
fail:
    snprintf(msg, ml, "cannot build request frames (out of memory or bad set name)");
    bench_wire_free(w);
    return NULL;
}

void bench_wire_free(bench_wire *w)
{
    if (!w)
        return;
    stp_buf_free(&w->buf);
    free(w);
}

size_t bench_wire_next(bench_wire *w, const uint8_t **frame, uint32_t *nq)
{
    unsigned i = w->next;
    w->next = (w->next + 1) % w->n;
    *frame = w->buf.data + w->off[i];
    *nq = w->nq[i];
    return w->off[i + 1] - w->off[i];
}

/* A peer's reply: one line. memcached: "VERSION ..." is the answer; ERROR, CLIENT_ERROR and
 * SERVER_ERROR lines are complete replies that count as errors. Redis: "+PONG" is the answer,
 * an error line ("-...") counts as an error. Anything else is a protocol violation. */
static long peer_reply(unsigned proto, const uint8_t *buf, size_t len, int *ok)
{
    enum { LINE_MAX_LEN = 1024 };
    const uint8_t *nl = memchr(buf, '\n', len < LINE_MAX_LEN ? len : LINE_MAX_LEN);
    if (!nl)
        return len < LINE_MAX_LEN ? 0 : -1;
    size_t n = (size_t)(nl - buf) + 1;
    if (n < 3 || buf[n - 2] != '\r')
        return -1;
    const char *l = (const char *)buf;
    if (proto == BENCH_PROTO_MEMCACHED) {
        *ok = n > 10 && memcmp(l, "VERSION ", 8) == 0;
        if (*ok || !strncmp(l, "ERROR", 5) || !strncmp(l, "CLIENT_ERROR", 12) ||
            !strncmp(l, "SERVER_ERROR", 12))
            return (long)n;
        return -1;
    }
    *ok = n == 7 && memcmp(l, "+PONG\r\n", 7) == 0;
    return *ok || l[0] == '-' ? (long)n : -1;
}

long bench_wire_reply(unsigned proto, const uint8_t *buf, size_t len, int *ok, uint32_t *reqid)
{
    if (proto != BENCH_PROTO_SEAMTEX) {
        *reqid = 0;
        return len ? peer_reply(proto, buf, len, ok) : 0;
    }
    stp_header h;
    int reason = 0;
    int r = stp_parse_header(buf, len, (size_t)256 << 20, &h, &reason);
    if (r == STP_NEED_MORE)
        return 0;
    if (r != STP_OK || !(h.flags & STP_F_REPLY))
        return -1;
    size_t total = STP_HEADER_SIZE + (size_t)h.body_len;
    if (len < total)
        return 0;
    *ok = h.status == STP_S_OK;
    *reqid = h.reqid;
    return (long)total;
}

/* ---- --shm: a shared-memory region per connection (PROTOCOL.md 4.12) ----------------------- */

/* page-rounded */
static size_t page_up(uint64_t v)
{
    return (size_t)((v + 4095) & ~(uint64_t)4095);
}

size_t bench_wire_shm_slot(const bench_cfg *cfg)
{
    return page_up(stp_sample_reply_bytes(cfg->batch, 4, cfg->outfmt, 0));
}

size_t bench_wire_shm_qrooms(const bench_cfg *cfg)
{
    return cfg->shm_copy ? (cfg->pipeline ? cfg->pipeline : 1) : BENCH_POOL;
}

size_t bench_wire_shm_qroom(const bench_cfg *cfg)
{
    uint8_t op = cfg->op == BENCH_OP_SAMPLE_DIR ? STP_OP_SAMPLE_DIR : STP_OP_SAMPLE;
    uint8_t flags = cfg->compact ? STP_SF_UV16 | STP_SF_FACE16 : 0;
    return page_up(stp_sample_query_bytes(op, flags, cfg->batch));
}

int bench_wire_shm_attach(const bench_cfg *cfg, int fd, uint8_t **map, size_t *size,
                          char *msg, size_t ml)
{
    *map = NULL;
    *size = bench_wire_shm_qroom(cfg) * bench_wire_shm_qrooms(cfg) +
            bench_wire_shm_slot(cfg) * (cfg->pipeline ? cfg->pipeline : 1);
    int mfd = -1;
    void *p = NULL;
    if (stu_memfd_sealed("seamtex-bench", *size, &mfd, &p) != 0) {
        snprintf(msg, ml, "memfd of %zu bytes: %s", *size, strerror(errno));
        return -1;
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl & ~O_NONBLOCK) < 0) {
        snprintf(msg, ml, "fcntl: %s", strerror(errno));
        close(mfd);
        munmap(p, *size);
        return -1;
    }
    stp_buf b;
    stp_buf_init(&b);
    stp_header h;
    uint8_t *body = NULL;
    int rc = -1;
    if (stp_enc_id_req(&b, STP_OP_SHM_ATTACH, 3, 0, (uint64_t)*size) != 0)
        snprintf(msg, ml, "cannot encode SHM_ATTACH");
    else if (roundtrip_fd(fd, &b, &h, &body, msg, ml, mfd) == 0) {
        if (h.status != STP_S_OK)
            status_msg(&h, body, "SHM_ATTACH", msg, ml);
        else
            rc = 0;
    }
    free(body);
    stp_buf_free(&b);
    close(mfd);
    if (rc == 0 && fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        snprintf(msg, ml, "fcntl: %s", strerror(errno));
        rc = -1;
    }
    if (rc != 0)
        munmap(p, *size);
    else
        *map = p;
    return rc;
}

/* Bytes of a pool frame before its queries: header, name, 24 bytes of parameters and count. */
static size_t frame_fixed(const uint8_t *frame)
{
    return STP_HEADER_SIZE + 2 + (size_t)stp_rd16(frame + STP_HEADER_SIZE) + 24;
}

void bench_wire_shm_copy(const uint8_t *frame, size_t len, uint8_t *room)
{
    size_t fixed = frame_fixed(frame);
    memcpy(room, frame + fixed, len - fixed);
}

void bench_wire_shm_place(const bench_wire *w, uint8_t *region, size_t qroom)
{
    for (unsigned i = 0; i < w->n; i++)
        bench_wire_shm_copy(w->buf.data + w->off[i], w->off[i + 1] - w->off[i],
                            region + (size_t)i * qroom);
}

unsigned bench_wire_last(const bench_wire *w)
{
    return (w->next + w->n - 1) % w->n;
}

size_t bench_wire_shm_frame(const uint8_t *frame, uint64_t query_off, uint64_t reply_off,
                            uint64_t reply_cap, uint8_t *out)
{
    size_t fixed = frame_fixed(frame);
    memcpy(out, frame, fixed);
    out[fixed - 24 + 5] |= STP_SF_SHM;          /* the flags byte of the parameters */
    stp_wr64(out + fixed, query_off);
    stp_wr64(out + fixed + 8, reply_off);       /* a room of its own: sampled in place */
    stp_wr64(out + fixed + 16, reply_cap);
    stp_wr32(out + 16, (uint32_t)(fixed + STP_SHM_REF_SIZE - STP_HEADER_SIZE));
    return fixed + STP_SHM_REF_SIZE;
}
