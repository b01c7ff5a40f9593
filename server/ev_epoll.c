/* server/ev_epoll.c - the poller of ev.h on Linux epoll (level-triggered). */
#include "ev.h"

#include <errno.h>
#include <stdlib.h>
#include <sys/epoll.h>
#include <unistd.h>

struct sts_ev {
    int epfd;
    struct epoll_event buf[256];
};

sts_ev *sts_ev_create(void)
{
    sts_ev *ev = calloc(1, sizeof *ev);
    if (!ev)
        return NULL;
    ev->epfd = epoll_create1(EPOLL_CLOEXEC);
    if (ev->epfd < 0) {
        free(ev);
        return NULL;
    }
    return ev;
}

void sts_ev_free(sts_ev *ev)
{
    if (!ev)
        return;
    close(ev->epfd);
    free(ev);
}

static uint32_t to_epoll(unsigned events)
{
    uint32_t e = 0;
    if (events & STS_EV_READ)  /* EPOLLEXCLUSIVE refuses EPOLLRDHUP (EINVAL) */
        e |= (events & STS_EV_EXCLUSIVE) ? EPOLLIN : EPOLLIN | EPOLLRDHUP;
    if (events & STS_EV_WRITE)
        e |= EPOLLOUT;
    if (events & STS_EV_EXCLUSIVE)
        e |= EPOLLEXCLUSIVE;
    return e;
}

int sts_ev_add(sts_ev *ev, int fd, unsigned events, void *ptr)
{
    struct epoll_event e = {.events = to_epoll(events), .data.ptr = ptr};
    return epoll_ctl(ev->epfd, EPOLL_CTL_ADD, fd, &e);
}

int sts_ev_mod(sts_ev *ev, int fd, unsigned events, void *ptr)
{
    struct epoll_event e = {.events = to_epoll(events), .data.ptr = ptr};
    return epoll_ctl(ev->epfd, EPOLL_CTL_MOD, fd, &e);
}

int sts_ev_del(sts_ev *ev, int fd)
{
    struct epoll_event e = {0};
    return epoll_ctl(ev->epfd, EPOLL_CTL_DEL, fd, &e);
}

int sts_ev_wait(sts_ev *ev, sts_ev_event *out, int max, int timeout_ms)
{
    if (max > 256)
        max = 256;
    int n = epoll_wait(ev->epfd, ev->buf, max, timeout_ms);
    if (n < 0)
        return 0;  /* EINTR: the caller loops */
    for (int i = 0; i < n; i++) {
        unsigned r = 0;
        uint32_t e = ev->buf[i].events;
        if (e & (EPOLLIN | EPOLLRDHUP))
            r |= STS_EV_READ;
        if (e & EPOLLOUT)
            r |= STS_EV_WRITE;
        if (e & (EPOLLERR | EPOLLHUP))
            r |= STS_EV_ERROR | STS_EV_READ;
        out[i].ptr = ev->buf[i].data.ptr;
        out[i].events = r;
    }
    return n;
}
