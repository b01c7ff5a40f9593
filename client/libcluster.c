/* client/libcluster.c - the cluster client (seamtex_cluster.h): membership from CLUSTER,
 * routing by the shared HRW ranking, failover, MOVED, for blocking calls. The handle is in
 * libcluster_int.h; pipelined calls are libcluster_pipe.c.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "libcluster_int.h"
#include "libseamtex_int.h"
#include "seamtex_cluster.h"
#include "stp_cluster.h"

const char *stc_cluster_errmsg(const stc_cluster *cl) { return cl ? cl->msg : ""; }

/* Every entry point that takes a handle accepts NULL (libseamtex(3)): STC_EINVAL from those
 * that return a code, an empty answer from the others. */
void stc_cluster_get_counters(const stc_cluster *cl, stc_cluster_counters *out)
{
    if (out)
        *out = cl ? cl->cnt : (stc_cluster_counters){ 0, 0, 0, 0 };
}

unsigned stc_cluster_replicas(const stc_cluster *cl) { return cl ? cl->replicas : 0; }

static int is_conn_error(int rc)
{
    return rc == STC_ECONNECT || rc == STC_EIO || rc == STC_ECLOSED || rc == STC_EPROTO ||
           rc == STC_ETIMEDOUT || rc == STC_ESHUTDOWN || rc == STC_ESERVERTIMEOUT;
}

static int find_addr(stc_cluster *cl, const char *addr)
{
    for (size_t i = 0; i < cl->n; i++)
        if (!strcmp(cl->nodes[i].addr, addr))
            return (int)i;
    return -1;
}

/* adds a node (id may equal the address); returns its index or -1 */
static int add_node(stc_cluster *cl, const char *id, const char *addr)
{
    int i = find_addr(cl, addr);
    if (i >= 0)
        return i;
    if (cl->n == MAX_NODES)
        return -1;
    cl_node *d = &cl->nodes[cl->n];
    memset(d, 0, sizeof *d);
    snprintf(d->id, sizeof d->id, "%s", id);
    snprintf(d->addr, sizeof d->addr, "%s", addr);
    return (int)cl->n++;
}

stc_conn *stc_cluster_conn(stc_cluster *cl, size_t i, int *err)
{
    if (!cl || i >= cl->n) {      /* i from outside: it used to index past the nodes */
        if (err)
            *err = STC_EINVAL;
        if (cl)
            snprintf(cl->msg, sizeof cl->msg, "node %zu: the view has %zu nodes", i, cl->n);
        return NULL;
    }
    cl_node *d = &cl->nodes[i];
    if (d->conn && stc_error(d->conn)) {
        stc_close(d->conn);
        d->conn = NULL;
    }
    if (d->conn)
        return d->conn;
    char host[256];
    unsigned port;
    if (stp_split_addr(d->addr, host, sizeof host, &port) != 0) {
        if (err)
            *err = STC_EINVAL;
        snprintf(cl->msg, sizeof cl->msg, "bad node address '%s'", d->addr);
        return NULL;
    }
    char em[512] = "";
    /* cl->opts is the caller's stc_opts copied whole: the interrupt hook goes to every
     * connection (stc_opts.interrupt*, and so stc_set_interrupt's) */
    int cerr = 0;
    d->conn = stc_connect_opts(host, port, &cl->opts, &cerr, em, sizeof em);
    if (err)
        *err = cerr;
    if (!d->conn) {
        snprintf(cl->msg, sizeof cl->msg, "node %s (%s): %s", d->id, d->addr, em);
        if (cerr != STC_EINTERRUPTED)   /* the caller stopped it: says nothing of the node */
            d->down_until = stc__now_ms() + DOWN_MS;
    }
    return d->conn;
}

/* CLUSTER on one connection; replaces the node list (connections to unchanged addresses kept) */
static int ask_cluster(stc_cluster *cl, stc_conn *c)
{
    uint32_t reqid;
    int rc = stc_append_raw(c, STP_OP_CLUSTER, NULL, 0, &reqid);
    if (rc == 0)
        rc = stc_flush(c);
    stc_reply r;
    if (rc == 0)
        rc = stc_get_reply(c, -1, &r);
    if (rc == 0 && r.status) {   /* refused (UNSUPPORTED: not a cluster node): its message */
        snprintf(cl->msg, sizeof cl->msg, "%s", r.errmsg);
        return r.status;
    }
    if (rc) {
        snprintf(cl->msg, sizeof cl->msg, "CLUSTER: %s", stc_errmsg(c));
        return rc;
    }
    stp_cluster_reply cr;
    const char *why = NULL;
    if (stp_dec_cluster_reply(r.body, r.body_len, &cr, &why) != 0 || cr.count == 0 ||
        cr.count > MAX_NODES) {
        snprintf(cl->msg, sizeof cl->msg, "CLUSTER: %s", why ? why : "no nodes in the reply");
        return STC_EPROTO;
    }
    cl_node old[MAX_NODES];
    size_t nold = cl->n;
    memcpy(old, cl->nodes, nold * sizeof *old);
    cl->n = 0;
    size_t pos = 0;
    stp_cluster_node e;
    while (stp_cluster_next(&cr, &pos, &e) && cl->n < MAX_NODES) {
        cl_node *d = &cl->nodes[cl->n++];
        memset(d, 0, sizeof *d);
        memcpy(d->id, e.id, e.id_len);
        memcpy(d->addr, e.addr, e.addr_len);
        for (size_t k = 0; k < nold; k++)
            if (old[k].conn && !strcmp(old[k].addr, d->addr)) {
                d->conn = old[k].conn;   /* c itself may be one of these: kept */
                old[k].conn = NULL;
            }
    }
    for (size_t k = 0; k < nold; k++)
        if (old[k].conn && old[k].conn != c)
            stc_close(old[k].conn);
        else if (old[k].conn == c) {
            /* the node that answered is not in its own view (leaving): keep it reachable */
            int i = add_node(cl, old[k].id, old[k].addr);
            if (i >= 0)
                cl->nodes[i].conn = c;
            else
                stc_close(c);
        }
    cl->replicas = cr.replicas ? cr.replicas : 1;
    cl->last_refresh = stc__now_ms();
    cl->cnt.refreshes++;
    return 0;
}

int stc_cluster_refresh(stc_cluster *cl)
{
    if (!cl)
        return STC_EINVAL;
    if (stc__cluster_pipe_pending(cl))   /* node indices are in use (libcluster_pipe.c) */
        return STC_ESTATE;
    int rc = STC_ECONNECT;
    for (size_t i = 0; i < cl->n; i++) {
        int err = 0;
        stc_conn *c = stc_cluster_conn(cl, i, &err);
        if (!c) {
            rc = err;
            if (rc == STC_EINTERRUPTED)
                return rc;            /* the caller's hook: no other node is asked */
            continue;
        }
        rc = ask_cluster(cl, c);
        if (rc == 0 || rc == STC_EINTERRUPTED)
            return rc;
    }
    return rc;
}

stc_cluster *stc_cluster_open(const char *seeds, const stc_opts *opts, int *err, char *errmsg,
                              size_t errmsg_len)
{
    int dummy;
    if (!err)                     /* may be NULL, as for stc_connect_opts and
                                     stc_cluster_open_etcd (a failure used to crash here) */
        err = &dummy;
    stc_cluster *cl = calloc(1, sizeof *cl);
    if (!cl) {
        *err = STC_ENOMEM;
        return NULL;
    }
    if (opts)
        cl->opts = *opts;
    if (opts && opts->token) {
        snprintf(cl->token, sizeof cl->token, "%s", opts->token);
        cl->opts.token = cl->token;
    }
    snprintf(cl->name, sizeof cl->name, "%s", opts && opts->client_name ? opts->client_name
                                                                         : "libseamtex-cluster");
    cl->opts.client_name = cl->name;
    if (!cl->opts.request_timeout_ms)
        cl->opts.request_timeout_ms = 5000;
    if (!cl->opts.connect_timeout_ms)
        cl->opts.connect_timeout_ms = 2000;
    const char *p = seeds ? seeds : "";
    while (*p) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        char addr[STP_MAX_NODE_ADDR + 1];
        if (len && len < sizeof addr) {
            memcpy(addr, p, len);
            addr[len] = 0;
            add_node(cl, addr, addr);
        }
        p += len + (comma ? 1 : 0);
    }
    if (!cl->n) {
        *err = STC_EINVAL;
        snprintf(errmsg, errmsg_len, "no seed nodes (HOST:PORT[,HOST:PORT...])");
        free(cl);
        return NULL;
    }
    int rc = stc_cluster_refresh(cl);
    if (rc) {
        *err = rc;
        snprintf(errmsg, errmsg_len, "%s", cl->msg);
        stc_cluster_close(cl);
        return NULL;
    }
    return cl;
}

void stc_cluster_close(stc_cluster *cl)
{
    if (!cl)
        return;
    for (size_t i = 0; i < cl->n; i++)
        stc_close(cl->nodes[i].conn);
    stc__cluster_pipe_free(cl->pipe);
    free(cl);
}

size_t stc_cluster_nodes(stc_cluster *cl, const stc_cluster_node **nodes)
{
    if (!cl || !nodes) {
        if (nodes)
            *nodes = NULL;
        return 0;
    }
    for (size_t i = 0; i < cl->n; i++) {
        cl->pub[i].id = cl->nodes[i].id;
        cl->pub[i].addr = cl->nodes[i].addr;
    }
    *nodes = cl->pub;
    return cl->n;
}

size_t stc_cluster_rank(stc_cluster *cl, const char *set, size_t *idx, size_t max)
{
    if (!cl || !set || (max && !idx))
        return 0;
    for (size_t i = 0; i < cl->n; i++)
        cl->ids[i] = cl->nodes[i].id;
    return stp_hrw_rank(cl->ids, cl->n, set, idx, max);
}

/* The NOT_FOUND rule, shared with the pipelined calls (libcluster_int.h). */
size_t stc__cluster_next_after_not_found(const size_t *tries, size_t nt, const char *tried,
                                         const char *owner, int unreached)
{
    size_t u = 0;
    while (u < nt && (tried[tries[u]] || !owner[tries[u]]))
        u++;
    if (u == nt && unreached)
        for (u = 0; u < nt && tried[tries[u]]; u++)
            ;
    return u;
}

/* One pass of a routed call over the current view. *refresh: the view looked stale (a node
 * failed or sent MOVED); *retry: the call failed in a way a fresher view may cure. */
static int route(stc_cluster *cl, const char *set, stc_cluster_fn fn, void *arg,
                 stc_conn **used, int *refresh_out, int *retry)
{
    size_t order[MAX_NODES];
    size_t no = stc_cluster_rank(cl, set, order, cl->n);
    /* the owners: NOT_FOUND from one of them is final only when every owner says so (an
     * owner that has just joined or restarted may not hold the set yet); when an owner could
     * not be reached, the rest of the ranking is asked too (a node that owned the set before
     * the membership changed may hold it still) */
    char owner[MAX_NODES] = {0};
    for (size_t r = 0; r < no && r < cl->replicas; r++)
        owner[order[r]] = 1;
    /* nodes marked down go last */
    size_t tries[MAX_NODES], nt = 0;
    int64_t now = stc__now_ms();
    for (int pass = 0; pass < 2; pass++)
        for (size_t r = 0; r < no; r++)
            if ((cl->nodes[order[r]].down_until > now) == pass)
                tries[nt++] = order[r];
    int rc = STC_ECONNECT, hops = 0, refresh = 0, notfound = 0, unreached = 0;
    char tried[MAX_NODES] = {0};
    for (size_t t = 0; t < nt;) {
        size_t i = tries[t];
        if (tried[i]) {
            t++;
            continue;
        }
        tried[i] = 1;
        int err = 0;
        stc_conn *c = stc_cluster_conn(cl, i, &err);
        if (!c && err == STC_EINTERRUPTED) {
            rc = err;                 /* the caller's hook stopped the connect: not a node */
            break;                    /* failure, no failover (msg: stc_cluster_conn's) */
        }
        if (!c) {
            rc = err;
            cl->cnt.failovers++;
            refresh = 1;
            unreached |= owner[i];
            t = notfound ? stc__cluster_next_after_not_found(tries, nt, tried, owner, unreached) : t + 1;
            continue;
        }
        rc = fn(c, arg);
        if (used)
            *used = c;
        if (rc == STC_EMOVED && hops < 4) {
            /* the message is the address of a node that holds the set */
            const char *m = stc_errmsg(c), *a = strrchr(m, ' ');
            a = a ? a + 1 : m;
            int j = add_node(cl, a, a);
            cl->cnt.moved++;
            hops++;
            refresh = 1;
            if (j >= 0 && !tried[j]) {
                tries[t] = (size_t)j;   /* try it next, then go on with the ranking */
                continue;
            }
            t = notfound ? stc__cluster_next_after_not_found(tries, nt, tried, owner, unreached) : t + 1;
            continue;
        }
        if (rc == STC_ENOTFOUND) {
            size_t u = stc__cluster_next_after_not_found(tries, nt, tried, owner, unreached);
            if (u < nt) {
                /* another owner may hold it: ask it, and answer NOT_FOUND if it fails too */
                snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
                notfound = 1;
                cl->cnt.failovers++;
                t = u;
                continue;
            }
            snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
            break;
        }
        if (is_conn_error(rc)) {
            snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
            stc_close(cl->nodes[i].conn);
            cl->nodes[i].conn = NULL;
            cl->nodes[i].down_until = stc__now_ms() + DOWN_MS;
            cl->cnt.failovers++;
            refresh = 1;
            unreached |= owner[i];
            t = notfound ? stc__cluster_next_after_not_found(tries, nt, tried, owner, unreached) : t + 1;
            continue;
        }
        /* the node's answer, a refusal (FORMAT, EXISTS, ...) or the result, or STC_EINTERRUPTED
         * (the caller's hook stopped the wait: returned at once, no failover, the node not
         * marked down, its connection kept): its message is the call's (stc_cluster_errmsg;
         * "" after a success) */
        if (rc)
            snprintf(cl->msg, sizeof cl->msg, "node %s: %s", cl->nodes[i].id, stc_errmsg(c));
        else
            cl->msg[0] = 0;
        break;
    }
    if (notfound && is_conn_error(rc))
        rc = STC_ENOTFOUND;    /* an owner's answer, the others could not be asked */
    *refresh_out = refresh;
    *retry = is_conn_error(rc) || rc == STC_EMOVED || (rc == STC_ENOTFOUND && unreached);
    return rc;
}

int stc_cluster_call(stc_cluster *cl, const char *set, stc_cluster_fn fn, void *arg,
                     stc_conn **used)
{
    if (used)
        *used = NULL;
    if (!cl)
        return STC_EINVAL;
    if (!set || !fn) {
        snprintf(cl->msg, sizeof cl->msg, "set or function is NULL");
        return STC_EINVAL;
    }
    if (stc__cluster_pipe_pending(cl)) {
        snprintf(cl->msg, sizeof cl->msg, "pipelined requests are outstanding: read their "
                 "replies with stc_cluster_get_reply before a blocking call");
        return STC_ESTATE;
    }
    cl->cnt.calls++;
    /* the refresh a previous call asked for runs now, not at the end of that call: it may
     * close the connection whose reply that call's results point into */
    if (cl->refresh_due && stc__now_ms() - cl->last_refresh > 500) {
        cl->refresh_due = 0;
        stc_cluster_refresh(cl);
    }
    int refresh = 0, retry = 0;
    int rc = route(cl, set, fn, arg, used, &refresh, &retry);
    if (retry && refresh && stc_cluster_refresh(cl) == 0) {
        /* failed on a stale view (a node restarted elsewhere, one that holds the set is not
         * in it yet): once more on a fresh one; no result of this call exists to clobber */
        if (used)
            *used = NULL;
        rc = route(cl, set, fn, arg, used, &refresh, &retry);
    }
    if (refresh)
        cl->refresh_due = 1;   /* for the next call; this one has its answer */
    return rc;
}

typedef struct sample_arg {
    const char *set; const stc_sample_opts *o; const stc_query *q; size_t n;
    stc_sample_result *res;
} sample_arg;
static int do_sample(stc_conn *c, void *p)
{
    sample_arg *a = p;
    return stc_sample(c, a->set, a->o, a->q, a->n, a->res);
}
int stc_cluster_sample(stc_cluster *cl, const char *set, const stc_sample_opts *o,
                       const stc_query *q, size_t n, stc_sample_result *res)
{
    sample_arg a = {set, o, q, n, res};
    return stc_cluster_call(cl, set, do_sample, &a, NULL);
}

typedef struct info_arg { const char *set; uint32_t first, count; stc_info *out; } info_arg;
static int do_info(stc_conn *c, void *p)
{
    info_arg *a = p;
    return stc_info_get(c, a->set, a->first, a->count, a->out);
}
int stc_cluster_info(stc_cluster *cl, const char *set, uint32_t face_first, uint32_t face_count,
                     stc_info *out)
{
    info_arg a = {set, face_first, face_count, out};
    return stc_cluster_call(cl, set, do_info, &a, NULL);
}

typedef struct upload_arg {
    const char *path, *set; const stc_upload_opts *o; stc_upload_result *out;
} upload_arg;
static int do_upload(stc_conn *c, void *p)
{
    upload_arg *a = p;
    return stc_upload_file(c, a->path, a->set, a->o, a->out);
}
int stc_cluster_upload_file(stc_cluster *cl, const char *path, const char *set,
                            const stc_upload_opts *o, stc_upload_result *out)
{
    upload_arg a = {path, set, o, out};
    return stc_cluster_call(cl, set, do_upload, &a, NULL);
}

static int do_delete(stc_conn *c, void *p) { return stc_delete(c, (const char *)p); }
int stc_cluster_delete(stc_cluster *cl, const char *set)
{
    return stc_cluster_call(cl, set, do_delete, (void *)set, NULL);
}

/* ---- for libcluster_pipe.c (libcluster_int.h) ---- */
int stc__cluster_conn_error(int rc) { return is_conn_error(rc); }
int stc__cluster_add_node(stc_cluster *cl, const char *id, const char *addr)
{
    return add_node(cl, id, addr);
}
