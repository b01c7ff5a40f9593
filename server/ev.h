/* server/ev.h - the poller under each I/O thread: register file descriptors with a pointer,
 * wait for readiness. One poller per thread, never shared.
 *
 * Owns: the readiness API. Does not own: what a ready fd means (io.c), timers (io.c checks
 * its own deadlines after each wait, with the timeout passed here).
 * Implementation: ev_epoll.c (level-triggered epoll). Another platform would add its own
 * ev_<name>.c behind the same functions.
 */
#ifndef STS_EV_H
#define STS_EV_H

#include <stdint.h>

enum { STS_EV_READ = 1, STS_EV_WRITE = 2, STS_EV_ERROR = 4, STS_EV_EXCLUSIVE = 8 };

typedef struct sts_ev_event {
    void    *ptr;       /* what was registered */
    unsigned events;    /* STS_EV_* that are ready */
} sts_ev_event;

typedef struct sts_ev sts_ev;

sts_ev *sts_ev_create(void);
void sts_ev_free(sts_ev *ev);
/* Registers fd for events (STS_EV_READ | STS_EV_WRITE, STS_EV_EXCLUSIVE for a listening
 * socket shared by several pollers). 0 or -1 (errno). */
int sts_ev_add(sts_ev *ev, int fd, unsigned events, void *ptr);
int sts_ev_mod(sts_ev *ev, int fd, unsigned events, void *ptr);
int sts_ev_del(sts_ev *ev, int fd);
/* Waits up to timeout_ms (-1 forever); returns the number of events written (0 on timeout
 * or EINTR). */
int sts_ev_wait(sts_ev *ev, sts_ev_event *out, int max, int timeout_ms);

#endif
