/* client/libcluster_pipe.c - pipelined routed calls of stc_cluster (seamtex_cluster.h,
 * "pipelined routed calls"): SAMPLE, SAMPLE_DIR and INFO requests for any sets go out at once
 * on each owner's connection, several in flight per node; replies are taken from whichever
 * node answers first.
 *
 * Owns: the table of requests outstanding (each with a copy of its arguments, so that it can
 * be sent again), per node the requests in flight on its connection in send order, failover
 * of a failed node's requests to the next node of each set's ranking (a connection error, or
 * no reply to the node's oldest request by its deadline: the connection is closed and every
 * request on it is routed again), re-routing on MOVED, the wait over every busy node's socket
 * (one poll), the refresh of the view once nothing is in flight.
 * Does not own: membership, ranking, connections (libcluster.c); frames and the pending list
 * of one connection (libconn.c, libcalls.c).
 *
 * Memory: slots are reused; the to-route and done queues are sized with the slot table, so
 * moving requests between them never allocates (a failover cannot fail for lack of memory).
 */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "libcluster_int.h"
#include "libseamtex_int.h"

#define MOVED_HOPS 4

typedef struct cl_rq {
    uint32_t id;                  /* the caller's request id; 0 = free slot */
    uint8_t  op;                  /* STP_OP_SAMPLE, STP_OP_SAMPLE_DIR, STP_OP_INFO */
    uint8_t  hops;                /* MOVED replies followed */
    uint8_t  unreached;           /* a node of its ranking failed while it was routed */
    int      node;                /* node it is in flight on, -1 = none */
    int      prefer;              /* node to try first (a MOVED address), -1 = none */
    uint32_t wire_id;             /* its request id on that node's connection */
    int64_t  deadline;            /* its node counts as failed when no reply came by then */
    int      err;                 /* failed everywhere: the last error */
    char     emsg[256];           /* and its message */
    uint8_t  tried[MAX_NODES / 8];
    char     set[STP_MAX_NAME + 1];
    stc_sample_opts o;
    void    *q;                   /* copy of the queries: n of them */
    size_t   n, qcap;
} cl_rq;

typedef struct ivec { size_t *v; size_t n, cap; } ivec;   /* slot indices */

struct stc__cl_pipe {
    cl_rq   *rq;                  /* slots, nrq of them */
    size_t   nrq;
    ivec     freel;               /* free slots */
    ivec     on[MAX_NODES];       /* in flight per node, in send order */
    ivec     todo;                /* to be routed again */
    ivec     done;                /* failed on every node, to be handed out (FIFO) */
    size_t   outstanding;         /* slots in use */
    uint32_t next_id;
    size_t   rr;                  /* node looked at first by the next get_reply */
    int      want_refresh;        /* a failure or MOVED: refresh the view when idle */
    char     msg[256];            /* message of the last failed request handed out */
};

/* ---- small helpers ------------------------------------------------------------------------ */

static int ivec_reserve(ivec *a, size_t need)
{
    if (need <= a->cap)
        return 0;
    size_t cap = a->cap ? a->cap * 2 : 16;
    while (cap < need)
        cap *= 2;
    size_t *v = realloc(a->v, cap * sizeof *v);
    if (!v)
        return STC_ENOMEM;
    a->v = v;
    a->cap = cap;
    return 0;
}

/* capacity was reserved by the caller */
static void ivec_push(ivec *a, size_t x) { a->v[a->n++] = x; }

static size_t ivec_take(ivec *a, size_t k)
{
    size_t x = a->v[k];
    memmove(a->v + k, a->v + k + 1, (a->n - k - 1) * sizeof *a->v);
    a->n--;
    return x;
}

static int tried(const cl_rq *r, size_t i) { return (r->tried[i / 8] >> (i % 8)) & 1; }
static void set_tried(cl_rq *r, size_t i) { r->tried[i / 8] |= (uint8_t)(1u << (i % 8)); }

static int req_timeout_ms(const stc_cluster *cl)
{
    return cl->opts.request_timeout_ms > 0 ? cl->opts.request_timeout_ms : 5000;
}

size_t stc__cluster_pipe_pending(const stc_cluster *cl)
{
    return cl && cl->pipe ? cl->pipe->outstanding : 0;
}

size_t stc_cluster_pending(const stc_cluster *cl) { return stc__cluster_pipe_pending(cl); }

void stc__cluster_pipe_free(stc__cl_pipe *p)
{
    if (!p)
        return;
    for (size_t i = 0; i < p->nrq; i++)
        free(p->rq[i].q);
    free(p->rq);
    free(p->freel.v);
    free(p->todo.v);
    free(p->done.v);
    for (size_t i = 0; i < MAX_NODES; i++)
        free(p->on[i].v);
    free(p);
}

/* A free slot (the table grows by doubling; the queues grow with it). */
static int slot_new(stc__cl_pipe *p, size_t *si)
{
    if (!p->freel.n) {
        size_t ncap = p->nrq ? p->nrq * 2 : 16;
        if (ivec_reserve(&p->freel, ncap) || ivec_reserve(&p->todo, ncap) ||
            ivec_reserve(&p->done, ncap))
            return STC_ENOMEM;
        cl_rq *rq = realloc(p->rq, ncap * sizeof *rq);
        if (!rq)
            return STC_ENOMEM;
        memset(rq + p->nrq, 0, (ncap - p->nrq) * sizeof *rq);
        p->rq = rq;
        for (size_t i = ncap; i-- > p->nrq;)
            ivec_push(&p->freel, i);
        p->nrq = ncap;
    }
    *si = p->freel.v[--p->freel.n];
    return 0;
}

static void slot_free(stc__cl_pipe *p, size_t si)
{
    p->rq[si].id = 0;
    ivec_push(&p->freel, si);
    p->outstanding--;
}

/* ---- routing -------------------------------------------------------------------------------- */

/* Every request in flight on node i goes back to be routed again; the connection is closed
 * (its late replies cannot arrive any more) and the node is tried last for DOWN_MS. */
static void node_fail(stc_cluster *cl, stc__cl_pipe *p, size_t i)
{
    cl_node *d = &cl->nodes[i];
    stc_close(d->conn);
    d->conn = NULL;
    d->down_until = stc__now_ms() + DOWN_MS;
    p->want_refresh = 1;
    for (size_t k = 0; k < p->on[i].n; k++) {
        size_t si = p->on[i].v[k];
        p->rq[si].node = -1;
        p->rq[si].unreached = 1;
        ivec_push(&p->todo, si);
        cl->cnt.failovers++;
    }
    p->on[i].n = 0;
}

static int send_on(stc_cluster *cl, stc__cl_pipe *p, size_t si, size_t i, stc_conn *c)
{
    if (ivec_reserve(&p->on[i], p->on[i].n + 1))
        return STC_ENOMEM;
    cl_rq *r = &p->rq[si];
    uint32_t wid = 0;
    int rc = r->op == STP_OP_INFO ? stc_append_info(c, r->set, &wid)
           : r->op == STP_OP_SAMPLE_DIR ? stc_append_sample_dir(c, r->set, &r->o, r->q, r->n, &wid)
           : stc_append_sample(c, r->set, &r->o, r->q, r->n, &wid);
    if (rc)
        return rc;
    r->node = (int)i;
    r->wire_id = wid;
    r->deadline = stc__now_ms() + req_timeout_ms(cl);
    ivec_push(&p->on[i], si);
    return 0;
}

/* One try of request si on node i: 0 sent, 1 go on with the next node (the node failed;
 * *rc its error), -1 stop (*rc: a refusal no other node would change). */
static int try_node(stc_cluster *cl, stc__cl_pipe *p, size_t si, size_t i, int *rc)
{
    set_tried(&p->rq[si], i);
    cl_node *d = &cl->nodes[i];
    if (d->conn && stc_error(d->conn) && p->on[i].n)
        node_fail(cl, p, i);              /* broken under requests in flight: they move too */
    int err = 0;
    stc_conn *c = stc_cluster_conn(cl, i, &err);
    if (!c && err == STC_EINTERRUPTED) {
        *rc = err;                        /* the caller's hook stopped the connect: no failover */
        return -1;
    }
    if (!c) {
        *rc = err;
        p->rq[si].unreached = 1;
        cl->cnt.failovers++;
        p->want_refresh = 1;
        return 1;
    }
    *rc = send_on(cl, p, si, i, c);
    if (*rc == 0)
        return 0;
    snprintf(cl->msg, sizeof cl->msg, "node %s: %s", d->id,
             *rc == STC_ENOMEM && !stc_errmsg(c)[0] ? "out of memory" : stc_errmsg(c));
    if (!stc__cluster_conn_error(*rc))
        return -1;
    p->rq[si].unreached = 1;
    node_fail(cl, p, i);
    return 1;
}

/* Sends request si to the first node it has not tried: its MOVED address, then its set's
 * ranking with nodes marked down last. 0 when it is in flight; else the error (a connection
 * error when no node took it, or the refusal of a bad argument), message in cl->msg. The
 * common case (the first owner, up) costs one score per node, not a full ranking. */
static int route(stc_cluster *cl, stc__cl_pipe *p, size_t si)
{
    cl_rq *r = &p->rq[si];
    int rc = STC_ECONNECT, t;
    int64_t now = stc__now_ms();
    size_t first;
    if (r->prefer >= 0 && !tried(r, (size_t)r->prefer)) {
        if ((t = try_node(cl, p, si, (size_t)r->prefer, &rc)) <= 0)
            return t ? rc : 0;
    } else if (r->prefer < 0 && stc_cluster_rank(cl, r->set, &first, 1) == 1 &&
               !tried(r, first) && cl->nodes[first].down_until <= now) {
        if ((t = try_node(cl, p, si, first, &rc)) <= 0)
            return t ? rc : 0;
    }
    p->rq[si].prefer = -1;
    size_t order[MAX_NODES], no = stc_cluster_rank(cl, p->rq[si].set, order, cl->n), left = 0;
    for (int pass = 0; pass < 2; pass++)
        for (size_t k = 0; k < no; k++) {
            size_t i = order[k];
            if ((cl->nodes[i].down_until > now) != pass || tried(&p->rq[si], i))
                continue;
            left++;
            if ((t = try_node(cl, p, si, i, &rc)) <= 0)
                return t ? rc : 0;
        }
    if (!left && rc == STC_ECONNECT)
        snprintf(cl->msg, sizeof cl->msg, "set '%s': every node of the view was tried",
                 p->rq[si].set);
    return rc;
}

/* Routes everything waiting to be routed; what no node takes is done with its error. */
static void drain_todo(stc_cluster *cl, stc__cl_pipe *p)
{
    while (p->todo.n) {
        size_t si = ivec_take(&p->todo, 0);
        int rc = route(cl, p, si);
        if (rc) {
            p->rq[si].err = rc;
            snprintf(p->rq[si].emsg, sizeof p->rq[si].emsg, "%.200s", cl->msg);
            ivec_push(&p->done, si);
        }
    }
}

/* ---- appends -------------------------------------------------------------------------------- */

static int append(stc_cluster *cl, uint8_t op, const char *set, const stc_sample_opts *o,
                  const void *q, size_t n, size_t qsize, uint32_t *reqid)
{
    if (!cl)
        return STC_EINVAL;
    if (!reqid || !set || (op != STP_OP_INFO && (!o || (n && !q)))) {
        snprintf(cl->msg, sizeof cl->msg, "reqid, set, options or queries are NULL");
        return STC_EINVAL;
    }
    if (strlen(set) > STP_MAX_NAME || n > SIZE_MAX / (qsize ? qsize : 1)) {
        snprintf(cl->msg, sizeof cl->msg, "set name or batch too long");
        return STC_EINVAL;
    }
    if (!cl->pipe && !(cl->pipe = calloc(1, sizeof *cl->pipe))) {
        snprintf(cl->msg, sizeof cl->msg, "out of memory");
        return STC_ENOMEM;
    }
    stc__cl_pipe *p = cl->pipe;
    if (!p->outstanding && p->want_refresh && stc__now_ms() - cl->last_refresh > 500) {
        p->want_refresh = 0;
        stc_cluster_refresh(cl);   /* nothing in flight: node indices may change now */
    }
    size_t si;
    if (slot_new(p, &si)) {
        snprintf(cl->msg, sizeof cl->msg, "out of memory");
        return STC_ENOMEM;
    }
    if (n * qsize > p->rq[si].qcap && stc__grow(&p->rq[si].q, &p->rq[si].qcap, n * qsize)) {
        ivec_push(&p->freel, si);         /* still free: give it back */
        snprintf(cl->msg, sizeof cl->msg, "out of memory for a copy of %zu queries", n);
        return STC_ENOMEM;
    }
    cl_rq *r = &p->rq[si];
    if (++p->next_id == 0)
        p->next_id = 1;
    r->id = p->next_id;
    r->op = op;
    r->hops = 0;
    r->node = -1;
    r->prefer = -1;
    r->err = 0;
    r->emsg[0] = 0;
    memset(r->tried, 0, sizeof r->tried);
    r->unreached = 0;
    memcpy(r->set, set, strlen(set) + 1);
    if (o)
        r->o = *o;
    if (n)
        memcpy(r->q, q, n * qsize);
    r->n = n;
    p->outstanding++;
    int rc = route(cl, p, si);
    drain_todo(cl, p);                 /* requests of nodes that failed on the way */
    if (rc) {
        slot_free(p, si);
        return rc;
    }
    cl->cnt.calls++;
    *reqid = r->id;
    return 0;
}

int stc_cluster_append_sample(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                              const stc_query *q, size_t n, uint32_t *reqid)
{
    return append(cl, STP_OP_SAMPLE, set, o, q, n, sizeof *q, reqid);
}

int stc_cluster_append_sample_dir(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                                  const stc_dir_query *q, size_t n, uint32_t *reqid)
{
    return append(cl, STP_OP_SAMPLE_DIR, set, o, q, n, sizeof *q, reqid);
}

int stc_cluster_append_info(stc_cluster *cl, const char *set, uint32_t *reqid)
{
    return append(cl, STP_OP_INFO, set, NULL, NULL, 0, 0, reqid);
}

/* ---- replies -------------------------------------------------------------------------------- */

/* Sends what node i has queued without waiting; a broken connection fails the node. */
static void push_out(stc_cluster *cl, stc__cl_pipe *p, size_t i)
{
    stc_conn *c = cl->nodes[i].conn;
    if (!c || !stp_buf_avail(&c->out))
        return;
    int rc = stc_error(c) ? stc_error(c) : stc__flush(c, stc__now_ms());
    if (rc && rc != STC_ETIMEDOUT) {
        snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
        node_fail(cl, p, i);
    }
}

int stc_cluster_flush(stc_cluster *cl)
{
    if (!cl)
        return STC_EINVAL;
    stc__cl_pipe *p = cl->pipe;
    if (!p || !p->outstanding)
        return STC_ESTATE;
    /* a node that fails has its requests appended elsewhere: go round until all is sent */
    for (int again = 1; again;) {
        again = 0;
        for (size_t i = 0; i < cl->n; i++) {
            stc_conn *c = cl->nodes[i].conn;
            if (!c || !p->on[i].n || !stp_buf_avail(&c->out))
                continue;
            int rc = stc_flush(c);
            if (rc) {
                snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
                node_fail(cl, p, i);
                drain_todo(cl, p);
                again = 1;
            }
        }
    }
    return 0;
}

/* 1 when c holds a whole reply frame beyond the one handed out last (no I/O needed). */
static int frame_ready(const stc_conn *c)
{
    size_t avail = stp_buf_avail(&c->in);
    if (c->skip || avail < c->hold + STP_HEADER_SIZE)
        return 0;
    stp_header h;
    int reason;
    int pr = stp_parse_header(stp_buf_head(&c->in) + c->hold, avail - c->hold, c->max_body, &h,
                              &reason);
    return pr != STP_OK || avail - c->hold >= STP_HEADER_SIZE + (size_t)h.body_len;
}

static void hand_out(stc__cl_pipe *p, size_t si, size_t node, stc_conn *c, const stc_reply *rep,
                     stc_cluster_reply *out)
{
    cl_rq *r = &p->rq[si];
    memset(out, 0, sizeof *out);
    out->reqid = r->id;
    out->opcode = r->op;
    out->set = r->set;
    out->node = node;
    out->conn = c;
    if (rep) {
        out->reply = *rep;
        out->opcode = rep->opcode;
        out->status = rep->status;
        out->errmsg = rep->errmsg ? rep->errmsg : "";
    } else {
        out->status = r->err;
        snprintf(p->msg, sizeof p->msg, "%s", r->emsg);
        out->errmsg = p->msg;
        out->reply.reqid = 0;
        out->reply.opcode = r->op;
        out->reply.status = r->err;
        out->reply.errmsg = p->msg;
    }
    slot_free(p, si);   /* its set name stays readable until the next call on cl */
}

/* After NOT_FOUND for request r: the node to ask next by the blocking calls' rule
 * (stc__cluster_next_after_not_found, over r's ranking), -1 when none is left. */
static int next_after_not_found(stc_cluster *cl, const cl_rq *r)
{
    size_t order[MAX_NODES], no = stc_cluster_rank(cl, r->set, order, cl->n);
    char was_tried[MAX_NODES] = {0}, owner[MAX_NODES] = {0};
    for (size_t k = 0; k < no; k++) {
        was_tried[order[k]] = (char)tried(r, order[k]);
        owner[order[k]] = k < cl->replicas;
    }
    size_t u = stc__cluster_next_after_not_found(order, no, was_tried, owner, r->unreached);
    return u < no ? (int)order[u] : -1;
}

/* Reads one reply of node i, waiting up to timeout_ms (0: only what has arrived). 1 when a
 * reply was handed out in *out; 0 when none (nothing yet, a MOVED sent on, or the node failed
 * and its requests moved). */
static int take(stc_cluster *cl, stc__cl_pipe *p, size_t i, int timeout_ms, stc_cluster_reply *out)
{
    stc_conn *c = cl->nodes[i].conn;
    stc_reply rep;
    int rc = stc_get_reply(c, timeout_ms, &rep);
    if (rc == STC_ETIMEDOUT)
        return 0;
    size_t k = 0;
    while (rc == 0 && k < p->on[i].n && p->rq[p->on[i].v[k]].wire_id != rep.reqid)
        k++;
    if (rc || k == p->on[i].n) {       /* a broken connection (the reply ids are checked) */
        snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id,
                 rc ? stc_errmsg(c) : "reply to no request of ours");
        node_fail(cl, p, i);
        drain_todo(cl, p);
        return 0;
    }
    size_t si = ivec_take(&p->on[i], k);
    cl_rq *r = &p->rq[si];
    r->node = -1;
    if (rep.status == STC_EMOVED && r->hops < MOVED_HOPS) {
        /* the message ends with the address of a node that holds the set */
        const char *a = strrchr(rep.errmsg, ' ');
        a = a ? a + 1 : rep.errmsg;
        int j = stc__cluster_add_node(cl, a, a);
        cl->cnt.moved++;
        p->want_refresh = 1;
        r->hops++;
        r->prefer = j;
        ivec_push(&p->todo, si);
        drain_todo(cl, p);
        return 0;
    }
    int j;
    if (rep.status == STC_ENOTFOUND && (j = next_after_not_found(cl, r)) >= 0) {
        /* the blocking calls' rule (docs/cluster.md): NOT_FOUND from one owner is final only
         * when every owner said so, and when an owner could not be reached the rest of the
         * ranking is asked too */
        r->prefer = j;
        cl->cnt.failovers++;
        ivec_push(&p->todo, si);
        drain_todo(cl, p);
        return 0;
    }
    p->rr = i + 1;
    hand_out(p, si, i, c, &rep, out);
    return 1;
}

int stc_cluster_get_reply(stc_cluster *cl, int timeout_ms, stc_cluster_reply *out)
{
    if (!cl || !out)
        return STC_EINVAL;
    stc__cl_pipe *p = cl->pipe;
    if (!p || !p->outstanding) {
        snprintf(cl->msg, sizeof cl->msg, "no pipelined request is outstanding");
        return STC_ESTATE;
    }
    int64_t now = stc__now_ms();
    int64_t dl = timeout_ms > 0 ? now + timeout_ms : timeout_ms == 0 ? now
                 : now + req_timeout_ms(cl);
    for (;;) {
        if (p->done.n) {
            hand_out(p, ivec_take(&p->done, 0), SIZE_MAX, NULL, NULL, out);
            return 0;
        }
        /* replies already read, round robin from p->rr; queued requests pushed out; nodes
         * whose oldest request is past its deadline failed */
        size_t busy[MAX_NODES], nb = 0;
        int64_t wake = dl;
        now = stc__now_ms();
        for (size_t k = 0; k < cl->n; k++) {
            size_t i = (p->rr + k) % cl->n;
            if (!p->on[i].n)
                continue;
            stc_conn *c = cl->nodes[i].conn;
            if (!c) {                     /* closed under us (stc_cluster_conn): move them */
                node_fail(cl, p, i);
                drain_todo(cl, p);
                continue;
            }
            if (frame_ready(c)) {
                if (take(cl, p, i, 0, out))
                    return 0;
                k--;                      /* look at this node again */
                continue;
            }
            int64_t d = p->rq[p->on[i].v[0]].deadline;
            if (d <= now) {
                snprintf(cl->msg, sizeof cl->msg, "node %s: no reply within %d ms",
                         cl->nodes[i].id, req_timeout_ms(cl));
                node_fail(cl, p, i);
                drain_todo(cl, p);
                continue;
            }
            push_out(cl, p, i);
            if (!p->on[i].n)
                continue;
            busy[nb++] = i;
            if (d < wake)
                wake = d;
        }
        if (p->done.n)
            continue;
        if (!nb) {
            if (p->todo.n == 0 && p->outstanding == 0)
                return STC_ESTATE;        /* cannot happen: every request answers once */
            continue;
        }
        int ms = wake > now ? (int)(wake - now < 1000000 ? wake - now : 1000000) : 0;
        if (nb == 1) {
            /* one busy node: wait on its connection alone, as a direct client does */
            if (take(cl, p, busy[0], ms, out))
                return 0;
        } else {
            struct pollfd pf[MAX_NODES];
            for (size_t k = 0; k < nb; k++) {
                stc_conn *c = cl->nodes[busy[k]].conn;
                pf[k].fd = c->fd;
                pf[k].events = (short)(POLLIN | (stp_buf_avail(&c->out) ? POLLOUT : 0));
                pf[k].revents = 0;
            }
            int pr = poll(pf, nb, ms);
            if (pr < 0 && errno != EINTR) {
                snprintf(cl->msg, sizeof cl->msg, "poll: %s", strerror(errno));
                return STC_EIO;
            }
            for (size_t k = 0; pr > 0 && k < nb; k++) {
                size_t i = busy[k];
                if (!p->on[i].n || !cl->nodes[i].conn)
                    continue;
                if (pf[k].revents & POLLOUT)
                    push_out(cl, p, i);
                if ((pf[k].revents & (POLLIN | POLLHUP | POLLERR)) && p->on[i].n &&
                    take(cl, p, i, 0, out))
                    return 0;
            }
        }
        if (p->done.n)
            continue;
        if (stc__now_ms() >= dl) {
            snprintf(cl->msg, sizeof cl->msg, "no reply within the timeout (%zu outstanding)",
                     p->outstanding);
            return STC_ETIMEDOUT;
        }
    }
}

int stc_cluster_reply_sample(const stc_cluster_reply *r, stc_sample_result *res)
{
    if (!r || !res)
        return STC_EINVAL;
    if (r->status || !r->conn)
        return r->status ? r->status : STC_EINVAL;
    return stc_reply_sample(r->conn, &r->reply, res);
}

int stc_cluster_reply_info(const stc_cluster_reply *r, stc_info *out)
{
    if (!r || !out)
        return STC_EINVAL;
    if (r->status || !r->conn)
        return r->status ? r->status : STC_EINVAL;
    return stc_reply_info(r->conn, &r->reply, out);
}

size_t stc_cluster_discard_pending(stc_cluster *cl)
{
    stc__cl_pipe *p = cl ? cl->pipe : NULL;
    if (!p)
        return 0;
    size_t n = p->outstanding;
    for (size_t i = 0; i < MAX_NODES; i++) {
        if (p->on[i].n && i < cl->n)
            stc_discard_pending(cl->nodes[i].conn);
        p->on[i].n = 0;
    }
    p->todo.n = p->done.n = 0;
    p->freel.n = 0;
    for (size_t si = p->nrq; si-- > 0;) {
        p->rq[si].id = 0;
        ivec_push(&p->freel, si);
    }
    p->outstanding = 0;
    return n;
}
