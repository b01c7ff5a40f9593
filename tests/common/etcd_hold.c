/* tests/common/etcd_hold.c - a loopback proxy that can hold etcd transactions (etcd_hold.h). */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#include "etcd_hold.h"
#include "wire.h"

#define MAX_CONNS 512
#define MAX_HEADER 65536

typedef struct held {
    char  *buf;
    size_t len, need;                 /* complete when len == need */
    struct held *next;
} held;

struct st_etcd_hold {
    int             lfd, etcd_port;
    int             stop;             /* atomic */
    pthread_t       acceptor;
    pthread_mutex_t mu;               /* holding, the queue, held contents, conns */
    int             holding, muting;
    int             cut;              /* atomic: every connection closed */
    int             pass;             /* transactions still let through while holding/muting */
    held           *first, **last;
    pthread_t       conns[MAX_CONNS];
    int             nconns;
};

typedef struct conn_arg { st_etcd_hold *p; int fd; } conn_arg;

static int stopping(st_etcd_hold *p) { return __atomic_load_n(&p->stop, __ATOMIC_RELAXED); }
static int cut(st_etcd_hold *p) { return __atomic_load_n(&p->cut, __ATOMIC_RELAXED); }

static int connect_etcd(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        fd = -1;
    }
    return fd;
}

/* the request's header length (through the blank line) or 0 when not all there yet; *body
 * its Content-Length, *txn 1 for POST /v3/kv/txn */
static size_t parse_header(const char *b, size_t n, size_t *body, int *txn)
{
    const char *end = NULL;
    for (size_t i = 0; i + 3 < n; i++)
        if (!memcmp(b + i, "\r\n\r\n", 4)) {
            end = b + i;
            break;
        }
    if (!end)
        return 0;
    *txn = n > 18 && !strncmp(b, "POST /v3/kv/txn ", 16);
    *body = 0;
    for (const char *l = b; l && l < end; l = memchr(l, '\n', (size_t)(end - l))) {
        l += *l == '\n';
        if ((size_t)(end - l) > 15 && !strncasecmp(l, "content-length:", 15))
            *body = strtoul(l + 15, NULL, 10);
    }
    return (size_t)(end - b) + 4;
}

static void *conn_main(void *arg)
{
    conn_arg a = *(conn_arg *)arg;
    free(arg);
    st_etcd_hold *p = a.p;
    int c = a.fd, u = connect_etcd(p->etcd_port);
    char *ib = malloc(MAX_HEADER), rb[65536];
    size_t in = 0, remaining = 0;
    int in_body = 0;
    held *h = NULL;   /* the kept request being read, when in_body */
    int mute = 0;     /* a transaction was muted: nothing more goes back to the client */
    while (u >= 0 && ib && !stopping(p) && !cut(p)) {
        struct pollfd pf[2] = {{c, POLLIN, 0}, {u, POLLIN, 0}};
        if (poll(pf, 2, 20) < 0 || cut(p))
            break;
        if (pf[1].revents) {
            ssize_t r = recv(u, rb, sizeof rb, 0);
            if (r <= 0 || (!mute && st_wire_send_all(c, rb, (size_t)r) != 0))
                break;
        }
        if (!pf[0].revents)
            continue;
        ssize_t r = recv(c, ib + in, MAX_HEADER - in, 0);
        if (r <= 0)
            break;   /* the client has gone: what it left in the queue stays there */
        in += (size_t)r;
        int bad = 0;
        while (in && !bad) {
            if (!in_body) {
                size_t body = 0;
                int txn = 0;
                size_t hl = parse_header(ib, in, &body, &txn);
                if (!hl) {
                    bad = in == MAX_HEADER;
                    break;
                }
                pthread_mutex_lock(&p->mu);
                int act = (p->holding || p->muting) && txn && !(p->pass > 0 && p->pass--);
                mute |= act && p->muting;
                h = act && p->holding ? calloc(1, sizeof *h) : NULL;
                if (h && !(h->buf = malloc(hl + body))) {
                    free(h);
                    h = NULL;
                }
                if (h) {
                    memcpy(h->buf, ib, hl);
                    h->len = hl;
                    h->need = hl + body;
                    *p->last = h;
                    p->last = &h->next;
                }
                pthread_mutex_unlock(&p->mu);
                if (!h && st_wire_send_all(u, ib, hl) != 0)
                    bad = 1;
                memmove(ib, ib + hl, in - hl);
                in -= hl;
                remaining = body;
                in_body = 1;
            }
            size_t k = remaining < in ? remaining : in;
            if (h) {
                pthread_mutex_lock(&p->mu);
                memcpy(h->buf + h->len, ib, k);
                h->len += k;
                pthread_mutex_unlock(&p->mu);
            } else if (k && st_wire_send_all(u, ib, k) != 0) {
                bad = 1;
            }
            memmove(ib, ib + k, in - k);
            in -= k;
            remaining -= k;
            if (!remaining) {
                in_body = 0;
                h = NULL;
            } else {
                break;
            }
        }
        if (bad)
            break;
    }
    free(ib);
    if (u >= 0)
        close(u);
    close(c);
    return NULL;
}

static void *accept_main(void *arg)
{
    st_etcd_hold *p = arg;
    while (!stopping(p)) {
        struct pollfd pf = {p->lfd, POLLIN, 0};
        if (poll(&pf, 1, 100) <= 0)
            continue;
        int fd = accept4(p->lfd, NULL, NULL, SOCK_CLOEXEC);
        if (fd < 0)
            continue;
        if (cut(p)) {
            close(fd);
            continue;
        }
        conn_arg *a = malloc(sizeof *a);
        pthread_mutex_lock(&p->mu);
        int ok = a && p->nconns < MAX_CONNS;
        if (ok) {
            *a = (conn_arg){p, fd};
            ok = pthread_create(&p->conns[p->nconns], NULL, conn_main, a) == 0;
            p->nconns += ok;
        }
        pthread_mutex_unlock(&p->mu);
        if (!ok) {
            free(a);
            close(fd);
        }
    }
    return NULL;
}

st_etcd_hold *st_etcd_hold_start(int etcd_port, const char *prefix, char *url, size_t cap)
{
    st_etcd_hold *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    p->etcd_port = etcd_port;
    p->last = &p->first;
    pthread_mutex_init(&p->mu, NULL);
    int port = 0;
    p->lfd = st_wire_listen(64, &port);
    if (p->lfd < 0 || pthread_create(&p->acceptor, NULL, accept_main, p) != 0) {
        perror("etcd_hold: listen");
        if (p->lfd >= 0)
            close(p->lfd);
        pthread_mutex_destroy(&p->mu);
        free(p);
        return NULL;
    }
    snprintf(url, cap, "etcd://127.0.0.1:%d%s", port, prefix);
    return p;
}

static void set_mode(st_etcd_hold *p, int holding, int muting, int pass)
{
    pthread_mutex_lock(&p->mu);
    p->holding = holding;
    p->muting = muting;
    p->pass = pass;
    pthread_mutex_unlock(&p->mu);
}

void st_etcd_hold_on(st_etcd_hold *p, int pass) { set_mode(p, 1, 0, pass); }
void st_etcd_hold_mute(st_etcd_hold *p, int pass) { set_mode(p, 0, 1, pass); }
void st_etcd_hold_off(st_etcd_hold *p) { set_mode(p, 0, 0, 0); }
void st_etcd_hold_cut(st_etcd_hold *p, int on) { __atomic_store_n(&p->cut, on, __ATOMIC_RELAXED); }

int st_etcd_hold_count(st_etcd_hold *p)
{
    int n = 0;
    pthread_mutex_lock(&p->mu);
    for (held *h = p->first; h; h = h->next)
        n += h->len == h->need;
    pthread_mutex_unlock(&p->mu);
    return n;
}

/* sends one kept request on a connection of its own; 1 when etcd answered (headers read) */
static int replay(int port, const held *h)
{
    int fd = connect_etcd(port);
    if (fd < 0 || st_wire_send_all(fd, h->buf, h->len) != 0) {
        if (fd >= 0)
            close(fd);
        return 0;
    }
    char rb[4096];
    size_t n = 0;
    int answered = 0;
    while (!answered && n < sizeof rb - 1) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 5000) <= 0)
            break;
        ssize_t r = recv(fd, rb + n, sizeof rb - 1 - n, 0);
        if (r <= 0)
            break;
        n += (size_t)r;
        rb[n] = 0;
        answered = strstr(rb, "\r\n\r\n") != NULL;
    }
    close(fd);
    return answered;
}

int st_etcd_hold_replay(st_etcd_hold *p)
{
    held *done = NULL, **dl = &done;
    pthread_mutex_lock(&p->mu);
    /* the complete ones go, in order; one still being read stays (its client sends no more) */
    for (held **pp = &p->first; *pp;) {
        held *h = *pp;
        if (h->len == h->need) {
            *pp = h->next;
            h->next = NULL;
            *dl = h;
            dl = &h->next;
        } else {
            pp = &h->next;
        }
    }
    p->last = &p->first;
    while (*p->last)
        p->last = &(*p->last)->next;
    pthread_mutex_unlock(&p->mu);
    int answered = 0;
    while (done) {
        held *h = done;
        done = h->next;
        answered += replay(p->etcd_port, h);
        free(h->buf);
        free(h);
    }
    return answered;
}

void st_etcd_hold_stop(st_etcd_hold *p)
{
    if (!p)
        return;
    __atomic_store_n(&p->stop, 1, __ATOMIC_RELAXED);
    pthread_join(p->acceptor, NULL);
    for (int i = 0; i < p->nconns; i++)
        pthread_join(p->conns[i], NULL);
    close(p->lfd);
    while (p->first) {
        held *h = p->first;
        p->first = h->next;
        free(h->buf);
        free(h);
    }
    pthread_mutex_destroy(&p->mu);
    free(p);
}
