/* client/libseamtex_int.h - private to libseamtex (client/lib*.c): the connection struct and
 * the transport helpers shared by libconn.c (sockets, frames, pending requests), libcalls.c
 * (blocking calls and pipelined appends) and libxfer.c (upload, fetch). Not installed.
 */
#ifndef STC_INT_H
#define STC_INT_H

#include <stdint.h>

#include "proto.h"
#include "seamtex.h"

typedef struct stc_pend {
    uint32_t reqid;
    uint8_t  opcode;
    uint8_t  abandoned;   /* timed out: the reply is read and dropped when it comes */
    uint8_t  pipelined;   /* appended through stc_append_* (counts in stc_pending) */
    uint8_t  shm;         /* a shared-memory SAMPLE: holds [shm_off, +shm_len) of the region */
    uint64_t shm_at;      /* where its span starts in the ring (released in reply order) */
    uint64_t shm_span;    /* bytes the span takes from the ring (a wrap's waste included) */
    uint64_t shm_off, shm_len;   /* its reply room (its queries lie before it in the span) */
} stc_pend;

/* The interrupt hook (stc_set_interrupt, stc_opts.interrupt) and whether it said stop during
 * the current call (cleared by stc__begin). */
typedef struct stc_intr {
    stc_interrupt_fn fn;          /* NULL: none */
    void            *user;
    int              every_ms;    /* > 0: also called after each every_ms of waiting */
    int              said;        /* it returned non-zero during this call */
} stc_intr;

struct stc_conn {
    int      fd;
    long     pid;                 /* the process that connected (getpid): a child after fork
                                     gets STC_ESTATE, the socket and request ids are shared */
    volatile uint8_t *forkpage;   /* a page of 1s the kernel zeroes in a child
                                     (MADV_WIPEONFORK): the fork check without a getpid system
                                     call per call (1.3-1.7 us each on this VM); NULL: getpid */
    int      sticky;              /* 0, or the error that broke the connection */
    char     msg[1024];           /* message of the last failure */
    int      timeout_ms;          /* per-request timeout, 0 = none */
    stc_intr intr;                /* the interrupt hook, consulted only while waiting */
    uint32_t next_reqid;
    uint32_t max_body;            /* cap on reply bodies */
    stc_server server;

    stp_buf  out;                 /* encoded frames not yet sent */
    stp_buf  in;                  /* received bytes not yet consumed */
    uint64_t skip;                /* bytes of an oversized reply body still to drop */
    size_t   hold;                /* bytes of the last returned reply, consumed at the next call */

    stc_pend *pend;               /* outstanding requests: pend[phead .. pn) in send order */
    size_t   phead, pn, pcap;
    size_t   npipelined;          /* of them: appended, not abandoned */

    stc_reply reply;              /* last reply handed out by stc_get_reply */
    char     reply_msg[STP_MAX_MSG + 1];

    /* result storage owned by the connection (valid until the next call) */
    void    *vals;   size_t vals_cap;
    float   *cov;    size_t cov_cap;
    uint8_t *qst;    size_t qst_cap;
    stc_set_entry *sets; size_t sets_cap;
    char    *names;  size_t names_len, names_cap;
    stc_stat *stats; size_t stats_cap;
    stc_face *faces; size_t faces_cap;

    /* shared-memory region (libshm.c; PROTOCOL.md 4.12), NULL = none: a ring of spans, one
     * per shared-memory SAMPLE in flight, released in reply order */
    uint8_t *shm;
    size_t   shm_size;
    uint64_t shm_head, shm_tail, shm_used;
    uint64_t shm_n, sock_n;       /* SAMPLE requests sent each way (stc_shm_counts) */
    uint64_t shm_kept_at, shm_kept_span;  /* the span of the last reply read, held while the
                                     caller reads it in place (until the next call); 0 none */
    struct {                      /* an open stc_shm_reserve, not yet sent */
        int      open, dir;
        uint32_t n;
        stp_sample_params p;
        uint64_t at, span, qoff, roff, rcap;
    } shm_resv;
};

/* A frame as received: header plus a body that lives in c->in until the next call. */
typedef struct stc_frame {
    stp_header     h;
    const uint8_t *body;
    int            oversized;     /* body over max_body: dropped, body is NULL */
} stc_frame;

/* Records an error message (and returns code). Sticky codes also break the connection. */
int stc__fail(stc_conn *c, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
int stc__break(stc_conn *c, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* 0, or STC_EINVAL with the rule in the message when name is not a valid set name (every
 * call that sends one: libcalls.c, libxfer.c). */
int stc__check_name(stc_conn *c, const char *name);
/* Start of every call: refuses a process other than the one that connected (STC_ESTATE),
 * drops the previously returned reply, checks the sticky error, clears the message. */
int stc__begin(stc_conn *c);
/* As stc__begin, and refuses (ESTATE) while pipelined requests are outstanding. */
int stc__begin_blocking(stc_conn *c);
/* Monotonic milliseconds; deadline for a timeout (-1 = none). */
int64_t stc__now_ms(void);
int64_t stc__deadline(int timeout_ms);
/* The next request id of c (never 0: ids wrap past it). */
uint32_t stc__next_reqid(stc_conn *c);
/* Adds a request to the pending list. */
int stc__pend_add(stc_conn *c, uint32_t reqid, uint8_t opcode, int pipelined);
/* Removes the most recently added pending request (its frame could not be encoded). */
void stc__pend_drop_last(stc_conn *c);
/* Marks a pending request abandoned (its late reply will be dropped). */
void stc__pend_abandon(stc_conn *c, uint32_t reqid);
/* poll(2) of one descriptor until it is ready (poll's count), the deadline passes (0), the
 * interrupt hook h says stop (STC_EINTERRUPTED; h->said set) or poll fails otherwise (-1,
 * errno). EINTR without a stop is retried. The hook is called only when poll returns EINTR
 * or after h->every_ms of waiting, never when the descriptor is ready at once. */
struct pollfd;
int stc__poll(stc_intr *h, struct pollfd *pfd, int64_t deadline);
/* Calls the hook (when set); 1 (h->said set) when it says stop, else 0. */
int stc__interrupted(stc_intr *h);
/* A wait that gave up with the request still outstanding: a timeout or an interrupt (both
 * abandon the request; its late reply is dropped). */
static inline int stc__gave_up(int rc)
{
    return rc == STC_ETIMEDOUT || rc == STC_EINTERRUPTED;
}
/* Sends everything in c->out (reading replies meanwhile so that neither side stalls). */
int stc__flush(stc_conn *c, int64_t deadline);
/* Waits for the reply to `reqid` (or to any non-abandoned pending request when reqid_any),
 * dropping abandoned ones. On success *f describes it; the request is off the pending list
 * and the frame is held until the next call. Server statuses come back as 0 with
 * f->h.status set (the caller decides); oversized replies as STC_ENOMEM. */
int stc__wait(stc_conn *c, uint32_t reqid, int reqid_any, int64_t deadline, stc_frame *f);
/* Server status of f -> its code, with "OPCODE: STATUS: message" in c->msg. */
int stc__status_error(stc_conn *c, const stc_frame *f);
/* Maps an stp encode result to a client code. */
int stc__enc_error(stc_conn *c, int st);
/* libshm.c: takes room for a SAMPLE of n queries in the region and writes its queries there
 * (r->p.flags gets STP_SF_SHM, r->shm the offsets, the last pending request the span); 1 when
 * done, 0 when it goes over the socket (no region, no room), or an error code. */
int stc__shm_place(stc_conn *c, uint8_t opcode, stp_sample_req *r);
/* libshm.c: the open reservation (stc_shm_reserve) becomes the last pending request's: r
 * gets its parameters, count and offsets (flag SHM). */
void stc__shm_take_reserved(stc_conn *c, stp_sample_req *r);
/* libshm.c: body lies inside c's region (a shared-memory reply, read in place). */
int stc__shm_holds(const stc_conn *c, const uint8_t *body, size_t len);
/* 1 when body[0 .. len) lies in the reply held in the receive buffer until the next call
 * (libconn.c) */
int stc__in_holds(const stc_conn *c, const uint8_t *body, size_t len);
/* libcalls.c: sample options -> request parameters (checks the name and ranges). */
int stc__fill_params(stc_conn *c, const char *set, const stc_sample_opts *o, size_t n,
                     stp_sample_params *p);
/* libshm.c: gives the span of the most recent pending request back (its frame failed). */
void stc__shm_unplace(stc_conn *c, stc_pend *p);
/* libshm.c: a reply to pending request p arrived (dropped when `drop`): releases its span
 * and, for an OK reply, points f at the 4.6 body in the region. 0 or a sticky error. */
int stc__shm_reply(stc_conn *c, const stc_pend *p, stc_frame *f, int drop);
void stc__shm_free(stc_conn *c);

/* Grow helpers for result storage; 0 or STC_ENOMEM. */
int stc__grow(void **p, size_t *cap, size_t need);

#endif
