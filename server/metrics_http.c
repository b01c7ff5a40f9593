/* server/metrics_http.c - the --metrics-listen endpoint: GET /metrics over plain HTTP/1.x
 * (metrics.h).
 *
 * Owns: the endpoint's listening socket, its thread, its connections and the little HTTP it
 * speaks. Does not own: the exposition text (metrics_text.c), the counters.
 *
 * One thread, one poll(2) loop, at most STS_METRICS_MAX_CONNS connections (a newcomer past it
 * closes the oldest, so a flood of idle connections cannot lock a scraper out for longer than
 * it keeps flooding), each with a fixed STS_METRICS_MAX_REQUEST-byte input buffer and one
 * deadline of STS_METRICS_DEADLINE_MS from accept to the response's last byte (a byte-a-second
 * sender is closed at the deadline however much it sent). Every response closes the
 * connection ("Connection: close"; no keep-alive, no pipelining). The thread never touches the
 * data path: it reads the counters with relaxed atomic loads, like STATS does on an I/O
 * thread, and takes the registry's lock only as long as a STATS takes it.
 *
 * What it answers (judged by sts_metrics_judge, metrics_req.c; the request line and headers
 * must be whole, at most 8 KiB, CRLF or LF line ends):
 *   GET /metrics, HEAD /metrics (a query string is ignored)      200, text format 0.0.4
 *   another path                                                 404
 *   another method (a well-formed token)                         405, Allow: GET, HEAD
 *   control or non-ASCII bytes in the request line, no HTTP/1.0 or HTTP/1.1 version, a header
 *   line without a colon or with control bytes, a folded header  400
 *   a request line longer than 8 KiB                             414
 *   headers past 8 KiB                                           431
 * A request body is never read. After its response the connection is half-closed and what the
 * client still sends is read and dropped (up to 64 KiB or 1 s) so that the response is not
 * lost to a reset. Out of file descriptors (EMFILE), the listener sits out of the poll for a
 * second at a time, with one warning per 10 s, instead of waking the thread again at once.
 */
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include "metrics.h"
#include "server.h"

#define LINGER_MS    1000
#define LINGER_BYTES (64u << 10)

enum { C_READ, C_WRITE, C_LINGER };

typedef struct mconn {
    int      fd;             /* -1: free slot */
    int      state;
    int64_t  accepted_ms;
    int64_t  deadline_ms;
    size_t   len;            /* request bytes read */
    size_t   drained;        /* bytes dropped while lingering */
    stp_buf  out;            /* the response; written from out.start */
    char     req[STS_METRICS_MAX_REQUEST];
} mconn;

/* ---- the response ------------------------------------------------------------------------ */

static const char *reason(int status)
{
    switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 414: return "URI Too Long";
    case 431: return "Request Header Fields Too Large";
    default:  return "Internal Server Error";
    }
}

/* Fills c->out with the response to status; a 200's body is the exposition. */
static void respond(sts_server *srv, mconn *c, int status, int head)
{
    stp_buf body;
    stp_buf_init(&body);
    const char *type = "text/plain; charset=utf-8";
    if (status == 200) {
        if (sts_metrics_render(srv, &body) != 0)
            status = 500;
        else
            type = "text/plain; version=0.0.4; charset=utf-8";
    }
    if (status != 200) {
        stp_buf_clear(&body);
        char msg[160];
        int n = snprintf(msg, sizeof msg, "%d %s: this port serves GET /metrics only\n", status,
                         reason(status));
        stp_put_bytes(&body, msg, (size_t)n);
    }
    char hdr[320];
    int n = snprintf(hdr, sizeof hdr,
                     "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\n%s"
                     "Connection: close\r\n\r\n", status, reason(status), type,
                     stp_buf_avail(&body), status == 405 ? "Allow: GET, HEAD\r\n" : "");
    stp_put_bytes(&c->out, hdr, (size_t)n);
    if (!head)
        stp_put_bytes(&c->out, stp_buf_head(&body), stp_buf_avail(&body));
    stp_buf_free(&body);
    if (status == 200)
        __atomic_add_fetch(&srv->metrics.scrapes, 1, __ATOMIC_RELAXED);
    else
        __atomic_add_fetch(&srv->metrics.refused, 1, __ATOMIC_RELAXED);
    c->state = C_WRITE;
}

/* ---- connections --------------------------------------------------------------------------- */

static void conn_close(sts_server *srv, mconn *c, int unanswered)
{
    if (unanswered)
        __atomic_add_fetch(&srv->metrics.refused, 1, __ATOMIC_RELAXED);
    close(c->fd);
    c->fd = -1;
    stp_buf_free(&c->out);
}

static void on_read(sts_server *srv, mconn *c)
{
    if (c->state == C_LINGER) {
        char junk[4096];
        ssize_t r = read(c->fd, junk, sizeof junk);
        if (r > 0)
            c->drained += (size_t)r;
        if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR) || c->drained > LINGER_BYTES)
            conn_close(srv, c, 0);
        return;
    }
    ssize_t r = read(c->fd, c->req + c->len, sizeof c->req - c->len);
    if (r < 0 && (errno == EAGAIN || errno == EINTR))
        return;
    if (r <= 0) {
        conn_close(srv, c, 1);   /* gone before a whole request */
        return;
    }
    c->len += (size_t)r;
    int head = 0, st = sts_metrics_judge(c->req, c->len, &head);
    if (st)
        respond(srv, c, st, head);
}

static void on_write(sts_server *srv, mconn *c)
{
    while (stp_buf_avail(&c->out)) {
        ssize_t w = send(c->fd, stp_buf_head(&c->out), stp_buf_avail(&c->out), MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0 && errno == EAGAIN)
            return;
        if (w <= 0) {
            conn_close(srv, c, 0);
            return;
        }
        stp_buf_consume(&c->out, (size_t)w);
    }
    shutdown(c->fd, SHUT_WR);
    c->state = C_LINGER;
    int64_t linger = sts_now_ms() + LINGER_MS;
    if (linger < c->deadline_ms)
        c->deadline_ms = linger;
}

/* Returns 0, or the errno of an accept that failed for want of file descriptors (EMFILE,
 * ENFILE): the listener then stays readable, so the caller leaves it out of its poll for a
 * second rather than spin on it (dur28: the thread logged it ~32,000 times a second). */
static int on_accept(sts_server *srv, mconn *conns)
{
    for (;;) {
        int fd = accept4(srv->metrics.fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR || errno == ECONNABORTED)
                continue;
            if (errno == EMFILE || errno == ENFILE)
                return errno;
            if (errno != EAGAIN)
                sts_logf(&srv->log, STS_WARN, "metrics: accept: %s", strerror(errno));
            return 0;
        }
        mconn *slot = NULL, *oldest = NULL;
        for (int i = 0; i < STS_METRICS_MAX_CONNS && !slot; i++) {
            if (conns[i].fd < 0)
                slot = &conns[i];
            else if (!oldest || conns[i].accepted_ms < oldest->accepted_ms)
                oldest = &conns[i];
        }
        if (!slot) {
            conn_close(srv, oldest, oldest->state == C_READ);
            slot = oldest;
        }
        int64_t now = sts_now_ms();
        slot->fd = fd;
        slot->state = C_READ;
        slot->accepted_ms = now;
        slot->deadline_ms = now + STS_METRICS_DEADLINE_MS;
        slot->len = 0;
        slot->drained = 0;
        stp_buf_init(&slot->out);
    }
    return 0;
}

static void *metrics_main(void *arg)
{
    sts_server *srv = arg;
    sts_metrics *m = &srv->metrics;
    mconn *conns = malloc(STS_METRICS_MAX_CONNS * sizeof *conns);
    if (!conns) {
        sts_logf(&srv->log, STS_ERROR, "metrics: out of memory: /metrics not served");
        return NULL;
    }
    for (int i = 0; i < STS_METRICS_MAX_CONNS; i++)
        conns[i].fd = -1;
    struct pollfd pfd[2 + STS_METRICS_MAX_CONNS];
    mconn *who[2 + STS_METRICS_MAX_CONNS];
    int64_t paused_until = 0, starved_log_ms = 0;  /* out of fds: on_accept */
    for (;;) {
        int n = 0, timeout = -1;
        int64_t now = sts_now_ms();
        pfd[n++] = (struct pollfd){m->wakefd, POLLIN, 0};
        /* a negative fd is ignored by poll: the listener sits out a pause */
        pfd[n++] = (struct pollfd){now < paused_until ? -1 : m->fd, POLLIN, 0};
        if (now < paused_until)
            timeout = (int)(paused_until - now);
        for (int i = 0; i < STS_METRICS_MAX_CONNS; i++) {
            mconn *c = &conns[i];
            if (c->fd < 0)
                continue;
            if (now >= c->deadline_ms) {
                conn_close(srv, c, c->state == C_READ);   /* slow or silent: the deadline */
                continue;
            }
            int64_t left = c->deadline_ms - now;
            if (timeout < 0 || left < timeout)
                timeout = (int)left;
            who[n] = c;
            pfd[n++] = (struct pollfd){c->fd, c->state == C_WRITE ? POLLOUT : POLLIN, 0};
        }
        int rc = poll(pfd, (nfds_t)n, timeout);
        if (rc < 0 && errno != EINTR) {
            sts_logf(&srv->log, STS_ERROR, "metrics: poll: %s", strerror(errno));
            break;
        }
        if (rc <= 0)
            continue;
        if (pfd[0].revents)
            break;                                         /* sts_metrics_stop */
        for (int i = 2; i < n; i++) {
            mconn *c = who[i];
            if (!pfd[i].revents || c->fd < 0)
                continue;
            if (c->state == C_WRITE)
                on_write(srv, c);
            else
                on_read(srv, c);
            if (c->fd >= 0 && c->state == C_WRITE)
                on_write(srv, c);                          /* most responses go at once */
        }
        if (pfd[1].revents) {
            int err = on_accept(srv, conns);
            if (err) {
                int64_t t = sts_now_ms();
                paused_until = t + 1000;
                if (starved_log_ms == 0 || t - starved_log_ms >= 10000) {
                    starved_log_ms = t;
                    sts_logf(&srv->log, STS_WARN, "metrics: accept: %s (scrapes wait; raise "
                             "the fd limit)", strerror(err));
                }
            }
        }
    }
    for (int i = 0; i < STS_METRICS_MAX_CONNS; i++)
        if (conns[i].fd >= 0)
            conn_close(srv, &conns[i], 0);
    free(conns);
    return NULL;
}

/* ---- life ---------------------------------------------------------------------------------- */

int sts_metrics_open(sts_server *srv)
{
    sts_metrics *m = &srv->metrics;
    m->fd = -1;
    m->wakefd = -1;
    if (!srv->cfg.metrics_listen[0])
        return 0;
    char host[128];
    int port;
    if (sts_metrics_addr(srv->cfg.metrics_listen, host, sizeof host, &port) != 0) {
        sts_logf(&srv->log, STS_ERROR, "metrics-listen: '%s' is not HOST:PORT or PORT",
                 srv->cfg.metrics_listen);
        return -1;
    }
    m->fd = sts_tcp_listen(srv, "metrics-listen", host, port, 64, &m->port);
    return m->fd < 0 ? -1 : 0;
}

int sts_metrics_start(sts_server *srv)
{
    sts_metrics *m = &srv->metrics;
    if (m->fd < 0)
        return 0;
    m->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (m->wakefd < 0 || pthread_create(&m->thread, NULL, metrics_main, srv) != 0) {
        sts_logf(&srv->log, STS_ERROR, "metrics: cannot start its thread");
        return -1;
    }
    m->started = 1;
    char host[128], addr[160];
    int port;
    sts_metrics_addr(srv->cfg.metrics_listen, host, sizeof host, &port);
    snprintf(addr, sizeof addr, strchr(host, ':') ? "[%s]:%d" : "%s:%d", host, m->port);
    sts_logkv(&srv->log, STS_INFO, STS_FIELDS(STS_FS("event", "metrics_serving"), STS_FS("listen", addr), STS_FI("port", m->port)),
              "metrics: serving http://%s/metrics", addr);
    return 0;
}

void sts_metrics_stop(sts_server *srv)
{
    sts_metrics *m = &srv->metrics;
    if (!m->started)
        return;
    uint64_t one = 1;
    ssize_t w = write(m->wakefd, &one, sizeof one);
    (void)w;
    pthread_join(m->thread, NULL);
    m->started = 0;
}

void sts_metrics_close(sts_server *srv)
{
    sts_metrics *m = &srv->metrics;
    if (m->fd >= 0)
        close(m->fd);
    if (m->wakefd >= 0)
        close(m->wakefd);
    m->fd = m->wakefd = -1;
}
