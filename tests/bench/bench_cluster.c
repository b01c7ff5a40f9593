/* tests/bench/bench_cluster.c - the cluster (docs/cluster.md) on this machine, against a real
 * etcd on loopback.
 *
 * Usage: bench_cluster [--json PATH] [--kills N] [--secs S] [--routing-only]
 *   routing:    SAMPLE of one set (64 bilinear queries per request) through a direct
 *               connection to the set's first owner (A) vs through stc_cluster (B), same
 *               requests, alternating A B A B, 7 rounds of 1000 requests a side; medians of the
 *               per-request time and their ratio B/A. Then the same pipelined PIPE_DEPTH deep:
 *               stc_append_sample / stc_get_reply on the direct connection (A) vs
 *               stc_cluster_append_sample / stc_cluster_get_reply (B), 7 rounds of 2000.
 *   client throughput: a cluster grown from 1 to 2 to 3 nodes (R=3: every node holds every
 *               set), 12 sets; 2 client threads, each with its own stc_cluster, sample the sets
 *               in turn (1024 bilinear queries per request) for --secs / 2 seconds with the
 *               blocking client (A: one stc_cluster_sample at a time, as before pipelining) and
 *               pipelined (B: PIPE_DEPTH outstanding per handle, each request to its set's
 *               first owner), A B A B A B at each size; aggregate queries/s (medians), B/A.
 *   failover:   3 nodes, R=2; a client samples a set through stc_cluster; its first owner is
 *               killed with SIGKILL; the time from the kill to the first successful read of that
 *               set, over --kills kills (default 10; the node is restarted and the cluster
 *               converges between kills); p50 / p99.
 *   rereplicate: 3 nodes, R=2, 24 sets of ~600 KB; one node killed: bytes pushed by the live
 *               nodes (STATS cluster_push_bytes) over the time from the membership change to
 *               every set back at 2 copies: MB/s.
 *   throughput: 3 nodes, R=3 (every node holds the set); 4 client threads sample (4096
 *               bilinear queries per request) for --secs seconds (default 3) against the first
 *               1, 2, 3 nodes (threads spread round robin), the three configurations
 *               alternated twice; aggregate queries/s (median of the two) and per node the CPU
 *               time per query (utime + stime of the daemon from /proc over the queries it
 *               served: what predicts throughput on N machines, since on 2 cores the client
 *               threads and the daemons share the same CPUs).
 * Machine load is printed and stored in the JSON.
 */
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "seamtex.h"
#include "seamtex_cluster.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/ptx_fixture.h"
#include "../common/wait.h"
#include "../common/benchstat.h"

#define MAXN 3
static st_etcd ETCD;
static st_daemon NODE[MAXN];
static char FILE_PTX[400];

static int start_cluster(const char *prefix, const char *replicas)
{
    if (st_etcd_start(&ETCD, prefix) != 0)
        return -1;
    for (int i = 0; i < MAXN; i++) {
        char id[16];
        snprintf(id, sizeof id, "n%d", i);
        const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise", "127.0.0.1:0",
                              "--replicas", replicas, "--lease-ttl", "2", "--repair-interval",
                              "1", "--no-default-set", NULL};
        if (st_daemon_init(&NODE[i]) != 0 || st_daemon_start(&NODE[i], args) != 0)
            return -1;
    }
    return 0;
}

static void restart_node(int i)
{
    char id[16];
    snprintf(id, sizeof id, "n%d", i);
    const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise", "127.0.0.1:0",
                          "--replicas", "2", "--lease-ttl", "2", "--repair-interval", "1",
                          "--no-default-set", NULL};
    st_daemon_start(&NODE[i], args);
}

static void stop_cluster(void)
{
    for (int i = 0; i < MAXN; i++)
        st_daemon_down(&NODE[i], 10000);
    st_etcd_stop(&ETCD);
}

static char SEEDS[128];

static stc_cluster *open_cl(void)
{
    snprintf(SEEDS, sizeof SEEDS, "127.0.0.1:%d,127.0.0.1:%d", NODE[0].port, NODE[1].port);
    int err;
    char msg[256];
    stc_cluster *cl = stc_cluster_open(SEEDS, NULL, &err, msg, sizeof msg);
    if (!cl)
        fprintf(stderr, "stc_cluster_open: %s\n", msg);
    return cl;
}

/* copies of nsets sets at R each on the live nodes, every live node seeing live members */
static int g_live[MAXN], g_nsets, g_R;
static int settled(void *arg)
{
    (void)arg;
    uint64_t total = 0, nlive = 0;
    for (int i = 0; i < MAXN; i++)
        nlive += g_live[i];
    for (int i = 0; i < MAXN; i++) {
        if (!g_live[i])
            continue;
        if (st_daemon_stat(&NODE[i], "cluster_members") != nlive)
            return 0;
        total += st_daemon_stat(&NODE[i], "sets");
    }
    return total == (uint64_t)g_nsets * (uint64_t)g_R;
}

static stc_sample_opts SOPTS = {.mode = 1, .filter = 1};
static stc_query *make_queries(size_t n)
{
    stc_query *q = calloc(n, sizeof *q);
    for (size_t i = 0; q && i < n; i++) {
        q[i].face = (uint32_t)(i % 6);
        q[i].u = (float)((i * 37) % 97) / 97.0f;
        q[i].v = (float)((i * 53) % 89) / 89.0f;
        q[i].dudx = q[i].dvdy = 0.002f;
    }
    return q;
}

static int upload_sets(stc_cluster *cl, int n, const char *prefix)
{
    for (int s = 0; s < n; s++) {
        char name[32];
        snprintf(name, sizeof name, "%s%02d", prefix, s);
        if (stc_cluster_upload_file(cl, FILE_PTX, name, NULL, NULL) != 0) {
            fprintf(stderr, "upload %s: %s\n", name, stc_cluster_errmsg(cl));
            return -1;
        }
    }
    return 0;
}

/* ---- routing ------------------------------------------------------------------------------------ */

static double routing_direct_us, routing_cluster_us;
static int bench_routing(stc_cluster *cl)
{
    stc_query *q = make_queries(64);
    size_t idx[1];
    stc_cluster_rank(cl, "b00", idx, 1);
    int err;
    stc_conn *direct;
    const stc_cluster_node *nodes;
    stc_cluster_nodes(cl, &nodes);
    char host[64];
    int port = 0;
    sscanf(nodes[idx[0]].addr, "%63[^:]:%d", host, &port);
    stc_opts o;   /* the options stc_cluster gives its connections (5 s request timeout) */
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 5000;
    direct = stc_connect_opts(host, (unsigned)port, &o, &err, NULL, 0);
    if (!direct)
        return -1;
    double a[7], b[7];
    stc_sample_result r;
    for (int round = 0; round < 14; round++) {   /* A B, then B A: neither always goes first */
        int cluster_side = (round % 2) ^ ((round / 2) % 2);
        double t0 = st_bench_now();
        for (int k = 0; k < 1000; k++)
            if ((cluster_side ? stc_cluster_sample(cl, "b00", &SOPTS, q, 64, &r)
                              : stc_sample(direct, "b00", &SOPTS, q, 64, &r)) != 0)
                return -1;
        (cluster_side ? b : a)[round / 2] = (st_bench_now() - t0) / 1000 * 1e6;
    }
    routing_direct_us = st_bench_median(a, 7);
    routing_cluster_us = st_bench_median(b, 7);
    printf("routing: direct %.1f us/request, cluster client %.1f us/request, ratio %.3f "
           "(medians of 7 alternating rounds of 1000 SAMPLE x 64, same connection options)\n",
           routing_direct_us,
           routing_cluster_us, routing_cluster_us / routing_direct_us);
    stc_close(direct);
    free(q);
    return 0;
}

static double pipe_direct_us, pipe_cluster_us;
#define PIPE_DEPTH 8

/* n requests PIPE_DEPTH deep on a direct connection (cl NULL) or through cl; us per request */
static double pipe_round(stc_conn *direct, stc_cluster *cl, const char *const *sets,
                         int nsets, const stc_query *q, size_t nq, int n)
{
    double t0 = st_bench_now();
    int sent = 0, got = 0;
    while (got < n) {
        while (sent < n && sent - got < PIPE_DEPTH) {
            uint32_t id;
            const char *set = sets[sent % nsets];
            int rc = cl ? stc_cluster_append_sample(cl, set, &SOPTS, q, nq, &id)
                        : stc_append_sample(direct, set, &SOPTS, q, nq, &id);
            if (rc) {
                fprintf(stderr, "append: %s\n", cl ? stc_cluster_errmsg(cl) : stc_errmsg(direct));
                return -1;
            }
            sent++;
        }
        int rc, st;
        if (cl) {
            stc_cluster_reply r;
            rc = stc_cluster_get_reply(cl, -1, &r);
            st = r.status;
        } else {
            stc_reply r;
            rc = stc_get_reply(direct, -1, &r);
            st = r.status;
        }
        if (rc || st) {
            fprintf(stderr, "get_reply: %s %s\n", stc_strerror(rc ? rc : st),
                    cl ? stc_cluster_errmsg(cl) : stc_errmsg(direct));
            return -1;
        }
        got++;
    }
    return (st_bench_now() - t0) / n * 1e6;
}

static int bench_routing_pipelined(stc_cluster *cl)
{
    stc_query *q = make_queries(64);
    size_t idx[1];
    stc_cluster_rank(cl, "b00", idx, 1);
    const stc_cluster_node *nodes;
    stc_cluster_nodes(cl, &nodes);
    char host[64];
    int port = 0, err;
    sscanf(nodes[idx[0]].addr, "%63[^:]:%d", host, &port);
    stc_opts o;   /* the options stc_cluster gives its connections (5 s request timeout) */
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 5000;
    stc_conn *direct = stc_connect_opts(host, (unsigned)port, &o, &err, NULL, 0);
    if (!direct)
        return -1;
    const char *set[] = {"b00"};
    double a[7], b[7];
    for (int round = 0; round < 7; round++) {   /* A B, then B A: neither always goes first */
        if (round % 2 == 0)
            a[round] = pipe_round(direct, NULL, set, 1, q, 64, 2000);
        b[round] = pipe_round(NULL, cl, set, 1, q, 64, 2000);
        if (round % 2 == 1)
            a[round] = pipe_round(direct, NULL, set, 1, q, 64, 2000);
        if (a[round] < 0 || b[round] < 0)
            return -1;
    }
    pipe_direct_us = st_bench_median(a, 7);
    pipe_cluster_us = st_bench_median(b, 7);
    printf("routing, pipelined %d deep: direct %.2f us/request, cluster client %.2f us/request, "
           "ratio %.3f (medians of 7 alternating rounds of 2000 SAMPLE x 64)\n", PIPE_DEPTH,
           pipe_direct_us, pipe_cluster_us, pipe_cluster_us / pipe_direct_us);
    stc_close(direct);
    free(q);
    return 0;
}

/* ---- throughput ------------------------------------------------------------------------------- */

typedef struct tput_arg {
    int node;
    double t_end;
    uint64_t queries;
} tput_arg;

static void *tput_main(void *p)
{
    tput_arg *a = p;
    stc_conn *c = st_daemon_client(&NODE[a->node], NULL);
    stc_query *q = make_queries(4096);
    stc_sample_result r;
    while (c && st_bench_now() < a->t_end)
        if (stc_sample(c, "b00", &SOPTS, q, 4096, &r) == 0)
            a->queries += 4096;
    stc_close(c);
    free(q);
    return NULL;
}

static double cpu_s(pid_t pid)
{
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    char *p = strrchr(buf, ')');
    unsigned long ut = 0, st = 0;
    if (p)
        sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st);
    return (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
}

static double tput_qps[MAXN + 1], tput_cpu_us[MAXN + 1];
static int bench_throughput(double secs)
{
    double qps[MAXN + 1][2], cpq[MAXN + 1][2];
    for (int round = 0; round < 2; round++)
        for (int nn = 1; nn <= MAXN; nn++) {
            tput_arg args[4];
            pthread_t th[4];
            double c0[MAXN];
            uint64_t q0[MAXN];
            for (int i = 0; i < nn; i++) {
                c0[i] = cpu_s(NODE[i].pid);
                q0[i] = st_daemon_stat(&NODE[i], "queries");
            }
            double t0 = st_bench_now();
            for (int k = 0; k < 4; k++) {
                args[k] = (tput_arg){k % nn, t0 + secs, 0};
                pthread_create(&th[k], NULL, tput_main, &args[k]);
            }
            uint64_t total = 0;
            for (int k = 0; k < 4; k++) {
                pthread_join(th[k], NULL);
                total += args[k].queries;
            }
            double el = st_bench_now() - t0, cpu = 0;
            uint64_t served = 0;
            for (int i = 0; i < nn; i++) {
                cpu += cpu_s(NODE[i].pid) - c0[i];
                served += st_daemon_stat(&NODE[i], "queries") - q0[i];
            }
            qps[nn][round] = (double)total / el;
            cpq[nn][round] = served ? cpu / (double)served * 1e6 : 0;
        }
    for (int nn = 1; nn <= MAXN; nn++) {
        tput_qps[nn] = st_bench_median(qps[nn], 2);
        tput_cpu_us[nn] = st_bench_median(cpq[nn], 2);
        printf("throughput: %d node(s): %.0f queries/s aggregate, %.3f us of daemon CPU per "
               "query\n", nn, tput_qps[nn], tput_cpu_us[nn]);
    }
    return 0;
}

/* ---- client throughput: blocking vs pipelined stc_cluster, 1 / 2 / 3 nodes ------------------ */

#define CT_SETS 12
#define CT_THREADS 2
#define CT_BATCH 1024
static const char *CT_NAMES[CT_SETS] = {"c00", "c01", "c02", "c03", "c04", "c05",
                                        "c06", "c07", "c08", "c09", "c10", "c11"};

typedef struct ct_arg {
    stc_cluster *cl;
    int pipelined;
    double t_end;
    uint64_t queries;
    int failed;
} ct_arg;

static void *ct_main(void *p)
{
    ct_arg *a = p;
    stc_query *q = make_queries(CT_BATCH);
    stc_sample_result r;
    int sent = 0, out = 0;
    while (q && !a->failed) {
        int issuing = st_bench_now() < a->t_end;
        if (!a->pipelined) {
            if (!issuing)
                break;
            if (stc_cluster_sample(a->cl, CT_NAMES[sent++ % CT_SETS], &SOPTS, q, CT_BATCH, &r))
                a->failed = 1;
            else
                a->queries += CT_BATCH;
            continue;
        }
        while (issuing && out < PIPE_DEPTH) {
            uint32_t id;
            if (stc_cluster_append_sample(a->cl, CT_NAMES[sent++ % CT_SETS], &SOPTS, q, CT_BATCH,
                                          &id)) {
                a->failed = 1;
                break;
            }
            out++;
        }
        if (!out)
            break;
        stc_cluster_reply rep;
        if (stc_cluster_get_reply(a->cl, -1, &rep) || rep.status)
            a->failed = 1;
        else
            a->queries += CT_BATCH;
        out--;
    }
    free(q);
    return NULL;
}

static double ct_qps[MAXN + 1][2], ct_ratio[MAXN + 1];
static int ct_bad;
static int bench_client_throughput(double secs)
{
    if (st_etcd_start(&ETCD, "/bt") != 0)
        return -1;
    for (int i = 0; i < MAXN; i++)
        g_live[i] = 0;   /* the nodes start one by one below */
    for (int nn = 1; nn <= MAXN; nn++) {
        char id[16];
        snprintf(id, sizeof id, "n%d", nn - 1);
        const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise",
                              "127.0.0.1:0", "--replicas", "3", "--lease-ttl", "2",
                              "--repair-interval", "1", "--no-default-set", NULL};
        if (st_daemon_init(&NODE[nn - 1]) != 0 || st_daemon_start(&NODE[nn - 1], args) != 0)
            return -1;
        g_live[nn - 1] = 1;
        if (nn == 1) {
            snprintf(SEEDS, sizeof SEEDS, "127.0.0.1:%d", NODE[0].port);
            int err;
            char msg[256];
            stc_cluster *up = stc_cluster_open(SEEDS, NULL, &err, msg, sizeof msg);
            if (!up || upload_sets(up, CT_SETS, "c") != 0)
                return -1;
            stc_cluster_close(up);
        }
        g_nsets = CT_SETS;
        g_R = nn;
        if (st_wait_until(settled, NULL, 120000) != 0)
            return -1;
        double qa[3], qb[3];
        for (int round = 0; round < 6; round++) {
            int pip = round % 2;
            ct_arg args2[CT_THREADS];
            pthread_t th[CT_THREADS];
            double t0 = st_bench_now();
            for (int k = 0; k < CT_THREADS; k++) {
                int err;
                char msg[256];
                args2[k] = (ct_arg){stc_cluster_open(SEEDS, NULL, &err, msg, sizeof msg), pip,
                                    0, 0, 0};
                if (!args2[k].cl)
                    return -1;
            }
            t0 = st_bench_now();
            for (int k = 0; k < CT_THREADS; k++) {
                args2[k].t_end = t0 + secs / 2;
                pthread_create(&th[k], NULL, ct_main, &args2[k]);
            }
            uint64_t total = 0;
            for (int k = 0; k < CT_THREADS; k++) {
                pthread_join(th[k], NULL);
                total += args2[k].queries;
                ct_bad += args2[k].failed;
                stc_cluster_close(args2[k].cl);
            }
            (pip ? qb : qa)[round / 2] = (double)total / (st_bench_now() - t0);
        }
        ct_qps[nn][0] = st_bench_median(qa, 3);
        ct_qps[nn][1] = st_bench_median(qb, 3);
        ct_ratio[nn] = ct_qps[nn][1] / ct_qps[nn][0];
        printf("client throughput, %d node(s): blocking stc_cluster %.0f queries/s, pipelined "
               "(%d deep) %.0f queries/s, ratio %.2f (%d threads x %d queries per request, "
               "medians of 3 alternating rounds)\n", nn, ct_qps[nn][0], PIPE_DEPTH, ct_qps[nn][1],
               ct_ratio[nn], CT_THREADS, CT_BATCH);
    }
    stop_cluster();
    if (ct_bad)
        fprintf(stderr, "client throughput: %d client threads saw a failed request\n", ct_bad);
    return ct_bad ? -1 : 0;
}

/* ---- failover ------------------------------------------------------------------------------- */

static double fo_p50, fo_p99, fo_after_p50, fo_after_p99;
static int fo_n;
static int bench_failover(stc_cluster *cl, int kills)
{
    double *t = calloc((size_t)kills, sizeof *t), *ta = calloc((size_t)kills, sizeof *ta);
    stc_query *q = make_queries(1);
    stc_sample_result r;
    for (int k = 0; k < kills; k++) {
        char name[32];
        snprintf(name, sizeof name, "f%02d", k % 10);
        stc_cluster_refresh(cl);
        size_t idx[1];
        stc_cluster_rank(cl, name, idx, 1);
        const stc_cluster_node *nodes;
        stc_cluster_nodes(cl, &nodes);
        int victim = -1;
        for (int i = 0; i < MAXN; i++) {
            char addr[64];
            snprintf(addr, sizeof addr, "127.0.0.1:%d", NODE[i].port);
            if (!strcmp(addr, nodes[idx[0]].addr))
                victim = i;
        }
        int src = victim < 0 ? -1 : stc_cluster_sample(cl, name, &SOPTS, q, 1, &r);
        if (src != 0) {   /* the connection to the victim is open and used */
            fprintf(stderr, "failover: kill %d: victim %d, read before the kill: %s (%s)\n", k,
                    victim, stc_strerror(src), stc_cluster_errmsg(cl));
            break;
        }
        double t0 = st_bench_now();
        st_daemon_kill(&NODE[victim]);   /* SIGKILL, then waitpid: the process is gone */
        double t1 = st_bench_now();
        while (stc_cluster_sample(cl, name, &SOPTS, q, 1, &r) != 0 && st_bench_now() - t0 < 30)
            ;
        ta[fo_n] = (st_bench_now() - t1) * 1e3;
        t[fo_n++] = (st_bench_now() - t0) * 1e3;
        restart_node(victim);
        g_live[victim] = 1;
        if (st_wait_until(settled, NULL, 120000) != 0) {
            fprintf(stderr, "failover: the cluster did not settle after kill %d\n", k);
            break;
        }
        /* the restarted node has a new port: wait until the nodes' views (and so the client's)
         * carry it (it re-registers before its old lease expires: the count never drops) */
        for (int tries = 0; tries < 200; tries++) {
            stc_cluster_refresh(cl);
            int n = (int)stc_cluster_nodes(cl, &nodes), found = 0;
            char addr[64];
            snprintf(addr, sizeof addr, "127.0.0.1:%d", NODE[victim].port);
            for (int i = 0; i < n; i++)
                found |= !strcmp(nodes[i].addr, addr);
            if (found)
                break;
            st_sleep_ms(50);
        }
    }
    if (fo_n) {
        fo_p50 = st_bench_pct(t, fo_n, 0.5);
        fo_p99 = st_bench_pct(t, fo_n, 0.99);
        fo_after_p50 = st_bench_pct(ta, fo_n, 0.5);
        fo_after_p99 = st_bench_pct(ta, fo_n, 0.99);
        printf("failover: kill -9 of the first owner -> first successful read: p50 %.2f ms, "
               "p99 %.2f ms over %d kills (of which after the process was reaped: p50 %.2f ms, "
               "p99 %.2f ms)\n", fo_p50, fo_p99, fo_n, fo_after_p50, fo_after_p99);
    }
    free(t);
    free(ta);
    free(q);
    return 0;
}

/* ---- re-replication ---------------------------------------------------------------------------- */

static double rr_mbps, rr_secs;
static uint64_t rr_bytes;
static int bench_rereplicate(void)
{
    uint64_t b0 = 0;
    for (int i = 0; i < 2; i++)
        b0 += st_daemon_stat(&NODE[i], "cluster_push_bytes");
    st_daemon_kill(&NODE[2]);
    g_live[2] = 0;
    /* from the membership change (the lease expires) to every set back at 2 copies */
    while (st_daemon_stat(&NODE[0], "cluster_members") != 2)
        st_sleep_ms(5);
    double t0 = st_bench_now();
    if (st_wait_until(settled, NULL, 120000) != 0)
        return -1;
    rr_secs = st_bench_now() - t0;
    uint64_t b1 = 0;
    for (int i = 0; i < 2; i++)
        b1 += st_daemon_stat(&NODE[i], "cluster_push_bytes");
    rr_bytes = b1 - b0;
    rr_mbps = (double)rr_bytes / rr_secs / 1e6;
    printf("re-replication: %.1f MB pushed in %.2f s after the membership change: %.1f MB/s "
           "(1 s repair interval included)\n", rr_bytes / 1e6, rr_secs, rr_mbps);
    return 0;
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int kills = 10, routing_only = 0;
    double secs = 3;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--kills") && i + 1 < argc)
            kills = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--secs") && i + 1 < argc)
            secs = atof(argv[++i]);
        else if (!strcmp(argv[i], "--routing-only"))
            routing_only = 1;
        else {
            fprintf(stderr, "usage: %s [--json PATH] [--kills N] [--secs S] [--routing-only]\n",
                    argv[0]);
            return 2;
        }
    }
    char load0[64] = "";
    FILE *lf = fopen("/proc/loadavg", "r");
    if (lf) {
        if (!fgets(load0, sizeof load0, lf))
            load0[0] = 0;
        fclose(lf);
        load0[strcspn(load0, "\n")] = 0;
    }
    printf("machine load: %s\n", load0);
    const char *tmp = getenv("TMPDIR");
    snprintf(FILE_PTX, sizeof FILE_PTX, "%s/bench_cluster_%d.ptx", tmp && *tmp ? tmp : "/tmp",
             (int)getpid());
    size_t len;
    void *p = st_fixture_default_ptx(&len, 10);
    FILE *f = fopen(FILE_PTX, "wb");
    if (!p || !f || fwrite(p, 1, len, f) != len)
        return 1;
    fclose(f);
    free(p);

    /* R=3: routing and throughput */
    if (start_cluster("/b3", "3") != 0)
        return 1;
    stc_cluster *cl = open_cl();
    int rc = !cl || upload_sets(cl, 1, "b") != 0;
    g_live[0] = g_live[1] = g_live[2] = 1;
    g_nsets = 1;
    g_R = 3;
    rc = rc || st_wait_until(settled, NULL, 60000) != 0 || bench_routing(cl) != 0 ||
         bench_routing_pipelined(cl) != 0 || (!routing_only && bench_throughput(secs) != 0);
    stc_cluster_close(cl);
    stop_cluster();
    if (rc) {
        fprintf(stderr, "bench_cluster: the R=3 part failed\n");
        return 1;
    }

    if (routing_only) {
        unlink(FILE_PTX);
        return 0;
    }
    /* blocking vs pipelined cluster client over 1, 2, 3 nodes */
    if (bench_client_throughput(secs) != 0) {
        fprintf(stderr, "bench_cluster: the client throughput part failed\n");
        return 1;
    }

    /* R=2: failover, then re-replication */
    if (start_cluster("/b2", "2") != 0)
        return 1;
    cl = open_cl();
    g_nsets = 24;
    g_R = 2;
    rc = !cl || upload_sets(cl, 10, "f") != 0 || upload_sets(cl, 14, "r") != 0 ||
         st_wait_until(settled, NULL, 60000) != 0;
    rc = rc || bench_failover(cl, kills) != 0 || bench_rereplicate() != 0;
    stc_cluster_close(cl);
    stop_cluster();
    unlink(FILE_PTX);
    if (rc) {
        fprintf(stderr, "bench_cluster: the R=2 part failed\n");
        return 1;
    }
    if (json) {
        FILE *o = fopen(json, "w");
        if (!o)
            return 1;
        fprintf(o, "{\"load\":\"%s\",\"routing\":{\"direct_us\":%.2f,\"cluster_us\":%.2f,"
                "\"ratio\":%.4f,\"batch\":64,\"rounds\":7},\"failover_ms\":{\"p50\":%.3f,"
                "\"p99\":%.3f,\"kills\":%d,\"after_reap_p50\":%.3f,\"after_reap_p99\":%.3f},\"rereplication\":{\"bytes\":%llu,\"seconds\":%.3f,"
                "\"mb_per_s\":%.2f},\"throughput\":[",
                load0, routing_direct_us, routing_cluster_us, routing_cluster_us / routing_direct_us,
                fo_p50, fo_p99, fo_n, fo_after_p50, fo_after_p99, (unsigned long long)rr_bytes, rr_secs, rr_mbps);
        for (int nn = 1; nn <= MAXN; nn++)
            fprintf(o, "%s{\"nodes\":%d,\"queries_per_s\":%.0f,\"cpu_us_per_query\":%.4f}",
                    nn > 1 ? "," : "", nn, tput_qps[nn], tput_cpu_us[nn]);
        fprintf(o, "],\"routing_pipelined\":{\"depth\":%d,\"direct_us\":%.3f,"
                "\"cluster_us\":%.3f,\"ratio\":%.4f,\"batch\":64,\"rounds\":7},"
                "\"client_throughput\":[", PIPE_DEPTH, pipe_direct_us, pipe_cluster_us,
                pipe_cluster_us / pipe_direct_us);
        for (int nn = 1; nn <= MAXN; nn++)
            fprintf(o, "%s{\"nodes\":%d,\"blocking_queries_per_s\":%.0f,"
                    "\"pipelined_queries_per_s\":%.0f,\"ratio\":%.3f,\"threads\":%d,"
                    "\"batch\":%d,\"depth\":%d,\"sets\":%d}", nn > 1 ? "," : "", nn,
                    ct_qps[nn][0], ct_qps[nn][1], ct_ratio[nn], CT_THREADS, CT_BATCH, PIPE_DEPTH,
                    CT_SETS);
        fprintf(o, "]}\n");
        fclose(o);
    }
    return 0;
}
