/* client/bench_cluster.c - seamtex-bench's load through libseamtex instead of raw frames:
 *   --cluster SEEDS|URL   stc_cluster's pipelined routed calls, -P requests outstanding per
 *                         handle (spread over the nodes that own the sets asked for);
 *   --cluster ... --blocking   one stc_cluster_sample at a time (the client before pipelining);
 *   --lib                 the same pipelined loop on one direct stc_conn to -h/-p: the
 *                         baseline --cluster's routing overhead is measured against.
 * Closed loop, SAMPLE only; one handle per connection (-c), each driven by its own thread.
 * Each request gets a fresh random batch, encoded by the library (with --compact in the
 * compact layouts): what a library client pays per request, unlike the raw-frame loop, whose
 * frames are encoded once (bench_wire.c).
 * -s may name several sets (a,b,c): request k samples set k mod n.
 *
 * Owns: the handles, the per-thread loop, latency per request (append to reply: corrected and
 * service are the same in a closed loop). Does not own: the client library, the report
 * (bench_main.c).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "seamtex_cluster.h"
#include "seamtex_etcd.h"

#define MAX_SETS 64

typedef struct lib_ctx {
    stc_cluster *cl;              /* --cluster */
    stc_conn    *c;               /* --lib */
    char         names[1024];
    const char  *sets[MAX_SETS];
    unsigned     nsets;
    uint32_t     nfaces;
    stc_query   *q;
    uint64_t     rng;
} lib_ctx;

static uint64_t rnd(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

static float unit(uint64_t *s) { return (float)(rnd(s) >> 40) / (float)(1ull << 24); }

static void make_batch(lib_ctx *x, const bench_cfg *cfg)
{
    for (unsigned i = 0; i < cfg->batch; i++) {
        stc_query *q = &x->q[i];
        q->face = (uint32_t)(rnd(&x->rng) % x->nfaces);
        q->u = unit(&x->rng);
        q->v = unit(&x->rng);
        q->dudx = q->dvdy = cfg->footprint;
        q->dvdx = q->dudy = 0;
    }
}

static void opts_of(const bench_cfg *cfg, const lib_ctx *x, uint64_t *rng, stc_sample_opts *o)
{
    memset(o, 0, sizeof *o);
    o->mode = cfg->modes[rnd(rng) % cfg->nmodes];
    o->filter = cfg->filters[rnd(rng) % cfg->nfilters];
    o->outfmt = cfg->outfmt;
    if (cfg->compact)             /* as the raw-frame loop does (bench_wire.c) */
        o->want = STC_WANT_UV16 | (x->nfaces <= 65536 ? STC_WANT_FACE16 : 0);
}

/* 0, or -1 with msg set; -2 when no connection could be made (a server that answered and
 * refused, e.g. CLUSTER from a node outside a cluster, is -1). */
static int open_handle(lib_ctx *x, const bench_cfg *cfg, char *msg, size_t ml)
{
    snprintf(x->names, sizeof x->names, "%s", cfg->set);
    for (char *p = x->names, *s; x->nsets < MAX_SETS && (s = strtok_r(p, ",", &p)) != NULL;)
        x->sets[x->nsets++] = s;
    if (!x->nsets) {
        snprintf(msg, ml, "no set named (-s)");
        return -1;
    }
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.token = cfg->token;
    o.client_name = "seamtex-bench";
    o.request_timeout_ms = (int)(cfg->timeout_s * 1000);
    int err = 0;
    stc_info info;
    int rc;
    if (cfg->cluster) {
        x->cl = stc_cluster_open_url(cfg->cluster, &o, &err, msg, ml);
        if (!x->cl)
            return stc_is_server_error(err) ? -1 : -2;
        rc = stc_cluster_info(x->cl, x->sets[0], 0, 0, &info);
        if (rc)
            snprintf(msg, ml, "info %s: %s %s", x->sets[0], stc_strerror(rc),
                     stc_cluster_errmsg(x->cl));
    } else {
        x->c = stc_connect_opts(cfg->host, (unsigned)atoi(cfg->port), &o, &err, msg, ml);
        if (!x->c)
            return stc_is_server_error(err) ? -1 : -2;
        rc = stc_info_get(x->c, x->sets[0], 0, 0, &info);
        if (rc)
            snprintf(msg, ml, "info %s: %s %s", x->sets[0], stc_strerror(rc), stc_errmsg(x->c));
    }
    if (rc)
        return -1;
    x->nfaces = info.nfaces ? info.nfaces : 1;
    x->q = malloc(cfg->batch * sizeof *x->q);
    if (!x->q) {
        snprintf(msg, ml, "out of memory");
        return -1;
    }
    return 0;
}

typedef struct inflight { uint32_t id; uint64_t t; } inflight;

static void record(bench_thread *th, uint64_t t0, int ok, uint32_t nq)
{
    bench_result *r = th->res;
    uint64_t now = bench_now_ns();
    r->completed++;
    if (!ok)
        r->errors++;
    if (t0 >= th->t_measure && t0 < th->t_end) {
        stc_hist_record(&r->corrected, now - t0);
        stc_hist_record(&r->service, now - t0);
        r->measured++;
        r->t_last = now;
        if (ok)
            r->queries += nq;
    }
}

/* --cluster --blocking: one routed call at a time */
static void run_blocking(bench_thread *th, lib_ctx *x)
{
    const bench_cfg *cfg = th->cfg;
    uint64_t k = 0;
    while (bench_now_ns() < th->t_end && (!th->max_requests || k < th->max_requests)) {
        stc_sample_opts o;
        opts_of(cfg, x, &x->rng, &o);
        make_batch(x, cfg);
        stc_sample_result res;
        uint64_t t0 = bench_now_ns();
        th->res->sent++;
        int rc = stc_cluster_sample(x->cl, x->sets[k++ % x->nsets], &o, x->q, cfg->batch, &res);
        record(th, t0, rc == 0, cfg->batch);
    }
}

/* --cluster / --lib: -P outstanding; a reply is matched to its append by request id */
static int run_pipelined(bench_thread *th, lib_ctx *x)
{
    const bench_cfg *cfg = th->cfg;
    unsigned P = cfg->pipeline ? cfg->pipeline : 1, n = 0;
    inflight *fl = calloc(P, sizeof *fl);
    if (!fl) {
        snprintf(th->err, sizeof th->err, "out of memory");
        return -1;
    }
    uint64_t k = 0;
    uint64_t t_stop = th->t_end + 2000000000ull;
    for (;;) {
        uint64_t now = bench_now_ns();
        int issuing = now < th->t_end && (!th->max_requests || k < th->max_requests);
        while (issuing && n < P && (!th->max_requests || k < th->max_requests)) {
            stc_sample_opts o;
            opts_of(cfg, x, &x->rng, &o);
            make_batch(x, cfg);
            const char *set = x->sets[k++ % x->nsets];
            uint32_t id;
            int rc = x->cl ? stc_cluster_append_sample(x->cl, set, &o, x->q, cfg->batch, &id)
                           : stc_append_sample(x->c, set, &o, x->q, cfg->batch, &id);
            if (rc) {
                snprintf(th->err, sizeof th->err, "append: %s: %s", stc_strerror(rc),
                         x->cl ? stc_cluster_errmsg(x->cl) : stc_errmsg(x->c));
                free(fl);
                return -1;
            }
            fl[n].id = id;
            fl[n++].t = bench_now_ns();
            th->res->sent++;
        }
        if (!n || now >= t_stop)
            break;
        uint32_t id;
        int rc, status;
        if (x->cl) {
            stc_cluster_reply r;
            rc = stc_cluster_get_reply(x->cl, -1, &r);
            id = r.reqid;
            status = r.status;
        } else {
            stc_reply r;
            rc = stc_get_reply(x->c, -1, &r);
            id = r.reqid;
            status = r.status;
        }
        if (rc == STC_ETIMEDOUT)
            continue;                     /* the request timeout fails a node over */
        if (rc) {
            snprintf(th->err, sizeof th->err, "get_reply: %s: %s", stc_strerror(rc),
                     x->cl ? stc_cluster_errmsg(x->cl) : stc_errmsg(x->c));
            th->res->conn_errors++;
            th->res->timeouts += n;
            free(fl);
            return -1;
        }
        unsigned j = 0;
        while (j < n && fl[j].id != id)
            j++;
        if (j == n) {
            snprintf(th->err, sizeof th->err, "a reply to request %u that is not outstanding",
                     (unsigned)id);
            free(fl);
            return -1;
        }
        record(th, fl[j].t, status == 0, cfg->batch);
        fl[j] = fl[--n];
    }
    th->res->timeouts += n;
    free(fl);
    return 0;
}

int bench_lib_run(bench_thread *th)
{
    lib_ctx x;
    memset(&x, 0, sizeof x);
    x.rng = th->cfg->seed * 7919u + th->index + 1;
    int rc = -1, opened = open_handle(&x, th->cfg, th->err, sizeof th->err);
    th->no_conn = opened == -2;
    if (opened == 0) {
        uint64_t now = bench_now_ns();     /* every thread begins at the same instant */
        if (now < th->t_start) {
            struct timespec ts = { (time_t)((th->t_start - now) / 1000000000ull),
                                   (long)((th->t_start - now) % 1000000000ull) };
            nanosleep(&ts, NULL);
        }
        if (th->cfg->blocking) {
            run_blocking(th, &x);
            rc = 0;
        } else {
            rc = run_pipelined(th, &x);
        }
        if (x.cl) {
            stc_cluster_counters cnt;
            stc_cluster_get_counters(x.cl, &cnt);
            th->res->failovers = cnt.failovers;
            th->res->moved = cnt.moved;
        }
    }
    stc_cluster_close(x.cl);
    stc_close(x.c);
    free(x.q);
    return rc;
}
