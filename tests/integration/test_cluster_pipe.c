/* tests/integration/test_cluster_pipe.c - stc_cluster's pipelined routed calls and opening a
 * cluster from its etcd URL, against a real etcd and seamtexd nodes on loopback.
 *
 *   - 3 nodes, R=2, 12 sets of 3 distinct contents: 1500 SAMPLE and INFO requests pipelined
 *     24 deep through one stc_cluster go to all three nodes; one node is killed with SIGKILL
 *     after 300 replies: every request gets exactly one reply, each OK and equal (bitwise) to
 *     what a blocking read of the same queries gave before, and requests were failed over;
 *     then (a client with a 1 s request timeout) another node is stopped with SIGSTOP after 50
 *     replies: its requests time out and move to the other owner, again all correct;
 *   - a client whose view is {n0, n1} while n2 returns, n3 joins and sets move: requests sent
 *     to a node that dropped its copy come back MOVED and are re-routed: every reply correct;
 *   - stc_cluster_open_etcd on the cluster's etcd URL sees the live nodes and serves a
 *     pipelined stream; a bad URL, an etcd that does not answer and a prefix without nodes
 *     are refused with their codes; `seamtex --cluster etcd://...` routes a command, and
 *     its `ls` lists every set of the cluster once (before: the first node's sets only).
 * Waits are deadlines against a hang, never speed checks.
 */
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"
#include "seamtex_etcd.h"
#include "stp_cluster.h"

#define NSETS 12
#define NVAR  4          /* query variants: request k uses variant k % NVAR */
#define NQ    16
#define NNODES 4
#define MAXV  (NQ * 4)   /* values of one reply (at most 4 channels) */

static st_etcd ETCD;
static st_daemon NODE[NNODES];
static int live[NNODES];
static char files[3][300];
static stc_query Q[NVAR][NQ];
static float expect[NSETS][NVAR][MAXV];
static uint32_t expect_nfaces[NSETS];
static unsigned nchan;
static stc_sample_opts SO = {.mode = 1, .filter = 1};

static void setname(char *out, int s) { snprintf(out, 16, "p%02d", s); }

static void make_queries(void)
{
    for (int v = 0; v < NVAR; v++)
        for (int i = 0; i < NQ; i++) {
            stc_query *q = &Q[v][i];
            memset(q, 0, sizeof *q);
            q->face = (uint32_t)((i + v) % 3);   /* face 0 tells the contents apart */
            q->u = (float)((i * 7 + v * 3) % 16) / 16.0f + 0.03f;
            q->v = (float)((i * 5 + v) % 16) / 16.0f + 0.03f;
            q->dudx = q->dvdy = 0.01f;
        }
}

/* every live node sees `members` and holds exactly the sets it owns (R=2 over the live ids) */
static int settled(void *arg)
{
    uint64_t members = (uint64_t)(uintptr_t)arg;
    const char *ids[NNODES];
    int idx[NNODES];
    size_t n = 0;
    static const char *const names[NNODES] = {"n0", "n1", "n2", "n3"};
    for (int i = 0; i < NNODES; i++)
        if (live[i]) {
            idx[n] = i;
            ids[n++] = names[i];
        }
    for (size_t k = 0; k < n; k++) {
        st_daemon *d = &NODE[idx[k]];
        if (st_daemon_stat(d, "cluster_members") != members)
            return 0;
        stc_conn *c = st_daemon_client(d, NULL);
        const stc_set_entry *sets;
        size_t ns;
        if (!c || stc_list(c, &sets, &ns) != 0) {
            stc_close(c);
            return 0;
        }
        int ok = 1;
        for (int s = 0; s < NSETS && ok; s++) {
            char name[16];
            setname(name, s);
            size_t own[2];
            size_t no = stp_hrw_rank(ids, n, name, own, 2);
            int owner = 0, holds = 0;
            for (size_t j = 0; j < no; j++)
                owner |= own[j] == k;
            for (size_t j = 0; j < ns; j++)
                holds |= !strcmp(sets[j].name, name);
            ok = owner == holds;
        }
        stc_close(c);
        if (!ok)
            return 0;
    }
    return 1;
}

static void wait_settled(int members, const char *what)
{
    if (st_wait_until(settled, (void *)(uintptr_t)members, 60000) != 0)
        fail_msg("the cluster did not settle: %s", what);
}

static stc_cluster *open_seeds_tmo(int a, int b, int request_timeout_ms)
{
    char seeds[128], msg[256];
    snprintf(seeds, sizeof seeds, "127.0.0.1:%d,127.0.0.1:%d", NODE[a].port, NODE[b].port);
    int err = 0;
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = request_timeout_ms;
    stc_cluster *cl = stc_cluster_open(seeds, &o, &err, msg, sizeof msg);
    if (!cl)
        fail_msg("stc_cluster_open %s: %s", seeds, msg);
    return cl;
}

static stc_cluster *open_seeds(int a, int b) { return open_seeds_tmo(a, b, 5000); }

/* the index in NODE[] of the node at addr, -1 when none */
static int node_of(const char *addr)
{
    for (int i = 0; i < NNODES; i++) {
        char a[64];
        snprintf(a, sizeof a, "127.0.0.1:%d", NODE[i].port);
        if (NODE[i].port && !strcmp(a, addr))
            return i;
    }
    return -1;
}

typedef struct stream_result {
    int from[NNODES];     /* replies per node */
    stc_cluster_counters cnt;
} stream_result;

/* total requests pipelined `window` deep over the NSETS sets (every 10th an INFO); after
 * kill_after replies NODE[victim] gets sig (SIGKILL: killed and reaped; victim < 0: none).
 * Checks every reply. */
static void stream(stc_cluster *cl, int total, int window, int kill_after, int victim, int sig,
                   stream_result *sr)
{
    memset(sr, 0, sizeof *sr);
    uint32_t *ids = calloc((size_t)total, sizeof *ids);
    char *got = calloc((size_t)total, 1);
    assert_non_null(ids);
    assert_non_null(got);
    int sent = 0, recv = 0;
    while (recv < total) {
        while (sent < total && sent - recv < window) {
            char name[16];
            int s = (sent * 5) % NSETS;
            setname(name, s);
            int rc = sent % 10 == 9 ? stc_cluster_append_info(cl, name, &ids[sent])
                   : stc_cluster_append_sample(cl, name, &SO, Q[sent % NVAR], NQ, &ids[sent]);
            if (rc)
                fail_msg("append %d (%s): %s: %s", sent, name, stc_strerror(rc),
                         stc_cluster_errmsg(cl));
            sent++;
        }
        stc_cluster_reply r;
        int rc = stc_cluster_get_reply(cl, 30000, &r);
        if (rc)
            fail_msg("get_reply after %d replies: %s: %s", recv, stc_strerror(rc),
                     stc_cluster_errmsg(cl));
        int k = 0;
        while (k < sent && (got[k] || ids[k] != r.reqid))
            k++;
        if (k == sent)
            fail_msg("reply to request id %u, which is not outstanding", (unsigned)r.reqid);
        got[k] = 1;
        recv++;
        int s = (k * 5) % NSETS;
        char name[16];
        setname(name, s);
        assert_string_equal(r.set, name);
        if (r.status)
            fail_msg("request %d (%s): %s: %s", k, name, stc_strerror(r.status), r.errmsg);
        const stc_cluster_node *nodes;
        size_t nn = stc_cluster_nodes(cl, &nodes);
        assert_true(r.node < nn);
        int ni = node_of(nodes[r.node].addr);
        assert_true(ni >= 0);
        sr->from[ni]++;
        if (k % 10 == 9) {
            stc_info info;
            assert_int_equal(stc_cluster_reply_info(&r, &info), 0);
            assert_int_equal(info.nfaces, expect_nfaces[s]);
        } else {
            stc_sample_result res;
            assert_int_equal(stc_cluster_reply_sample(&r, &res), 0);
            assert_int_equal(res.count, NQ);
            assert_int_equal(res.nchan, nchan);
            if (memcmp(res.values, expect[s][k % NVAR], NQ * nchan * sizeof(float)) != 0)
                fail_msg("request %d (%s, variant %d): other values than a blocking read", k,
                         name, k % NVAR);
        }
        if (recv == kill_after && victim >= 0 && sig == SIGKILL) {
            st_daemon_kill(&NODE[victim]);
            live[victim] = 0;
        } else if (recv == kill_after && victim >= 0) {
            /* for SIGSTOP this returns once every thread has stopped: until one of them takes
             * the signal the others go on answering, on a loaded machine long enough to
             * answer everything still to come */
            assert_int_equal(st_daemon_signal(&NODE[victim], sig), 0);
        }
    }
    for (int k = 0; k < total; k++)
        assert_true(got[k]);
    assert_int_equal(stc_cluster_pending(cl), 0);
    stc_cluster_reply r;
    assert_int_equal(stc_cluster_get_reply(cl, 0, &r), STC_ESTATE);
    stc_cluster_get_counters(cl, &sr->cnt);
    free(ids);
    free(got);
}

static void pipelined_reads_survive_kill_moved_and_open_from_etcd(void **state)
{
    (void)state;
    make_queries();
    assert_int_equal(st_etcd_start(&ETCD, "/pp"), 0);
    for (int i = 0; i < NNODES; i++)
        assert_int_equal(st_daemon_init(&NODE[i]), 0);
    assert_int_equal(st_cluster_tint_files(NODE[0].dir, 3, 70, files), 0);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(st_cluster_node_start(&NODE[i], ETCD.url, i, 2, 0), 0);
        live[i] = 1;
    }
    stc_cluster *cl = open_seeds(0, 1);
    for (int s = 0; s < NSETS; s++) {
        char name[16];
        setname(name, s);
        if (stc_cluster_upload_file(cl, files[s % 3], name, NULL, NULL) != 0)
            fail_msg("upload %s: %s", name, stc_cluster_errmsg(cl));
    }
    wait_settled(3, "12 uploads");
    const stc_cluster_node *nodes;
    assert_int_equal(stc_cluster_refresh(cl), 0);
    assert_int_equal(stc_cluster_nodes(cl, &nodes), 3);
    /* what each request should give: blocking reads of the same queries */
    for (int s = 0; s < NSETS; s++) {
        char name[16];
        setname(name, s);
        stc_info info;
        assert_int_equal(stc_cluster_info(cl, name, 0, 0, &info), 0);
        expect_nfaces[s] = info.nfaces;
        for (int v = 0; v < NVAR; v++) {
            stc_sample_result res;
            assert_int_equal(stc_cluster_sample(cl, name, &SO, Q[v], NQ, &res), 0);
            assert_true(res.nchan >= 1 && res.nchan <= 4);
            nchan = res.nchan;
            memcpy(expect[s][v], res.values, NQ * nchan * sizeof(float));
        }
    }
    assert_true(memcmp(expect[0][0], expect[1][0], NQ * nchan * sizeof(float)) != 0);

    /* 1. pipelined over 3 nodes; n2 killed after 300 replies */
    stream_result sr;
    uint32_t id;
    assert_int_equal(stc_cluster_append_sample(cl, "p00", &SO, Q[0], NQ, &id), 0);
    stc_sample_result blocked;
    assert_int_equal(stc_cluster_sample(cl, "p00", &SO, Q[0], NQ, &blocked), STC_ESTATE);
    assert_int_equal(stc_cluster_refresh(cl), STC_ESTATE);
    assert_int_equal(stc_cluster_discard_pending(cl), 1);
    stream(cl, 1500, 24, 300, 2, SIGKILL, &sr);
    printf("kill: replies from n0 %d, n1 %d, n2 %d; failovers %llu\n", sr.from[0], sr.from[1],
           sr.from[2], (unsigned long long)sr.cnt.failovers);
    assert_true(sr.from[0] > 0 && sr.from[1] > 0 && sr.from[2] > 0);
    assert_true(sr.cnt.failovers > 0);
    wait_settled(2, "the kill of n2");

    /* 1b. a node that stops answering (SIGSTOP): no reply within the request timeout (1 s),
     * so its requests move to the other owner */
    stc_cluster *tc = open_seeds_tmo(0, 1, 1000);
    stream(tc, 300, 16, 50, 1, SIGSTOP, &sr);
    st_daemon_signal(&NODE[1], SIGCONT);
    printf("stop: replies from n0 %d, n1 %d; failovers %llu\n", sr.from[0], sr.from[1],
           (unsigned long long)sr.cnt.failovers);
    assert_true(sr.cnt.failovers > 0);
    stc_cluster_close(tc);
    wait_settled(2, "n1 stopped and continued");

    /* 2. MOVED: a client that sees {n0, n1} while n3 joins and sets move to it */
    stc_cluster *stale = open_seeds(0, 1);
    assert_int_equal(stc_cluster_nodes(stale, &nodes), 2);
    int moved_sets = 0;
    for (int s = 0; s < NSETS; s++) {
        char name[16];
        setname(name, s);
        const char *two[] = {"n0", "n1"}, *four[] = {"n0", "n1", "n2", "n3"};
        size_t first, own[2];
        stp_hrw_rank(two, 2, name, &first, 1);
        stp_hrw_rank(four, 4, name, own, 2);
        moved_sets += own[0] != first && own[1] != first;
    }
    assert_true(moved_sets > 0);   /* the names are fixed: HRW decides, not chance */
    for (int i = 2; i < 4; i++) {   /* n2 returns, n3 joins */
        assert_int_equal(st_cluster_node_start(&NODE[i], ETCD.url, i, 2, 0), 0);
        live[i] = 1;
    }
    wait_settled(4, "n2 returned and n3 joined");
    assert_int_equal(stc_cluster_nodes(stale, &nodes), 2);
    stream(stale, 400, 16, -1, -1, 0, &sr);
    printf("moved: %d sets left their first owner in the stale view; MOVED followed %llu\n",
           moved_sets, (unsigned long long)sr.cnt.moved);
    assert_true(sr.cnt.moved > 0);
    stc_cluster_close(stale);

    /* 3. open from the etcd URL */
    int err = 0;
    char msg[256];
    stc_cluster *ec = stc_cluster_open_etcd(ETCD.url, NULL, &err, msg, sizeof msg);
    if (!ec)
        fail_msg("stc_cluster_open_etcd %s: %s", ETCD.url, msg);
    assert_int_equal(stc_cluster_nodes(ec, &nodes), 4);
    assert_int_equal(stc_cluster_replicas(ec), 2);
    stream(ec, 200, 8, -1, -1, 0, &sr);
    stc_cluster_close(ec);
    assert_null(stc_cluster_open_url("http://127.0.0.1:1/pp", NULL, &err, msg, sizeof msg));
    assert_int_equal(err, STC_EINVAL);     /* not etcd://: taken as seeds, not an address */
    assert_null(stc_cluster_open_etcd("etcd://127.0.0.1:1", NULL, &err, msg, sizeof msg));
    assert_int_equal(err, STC_EINVAL);     /* no prefix */
    stc_opts quick;
    memset(&quick, 0, sizeof quick);
    quick.connect_timeout_ms = 500;
    assert_null(stc_cluster_open_etcd("etcd://127.0.0.1:1/pp", &quick, &err, msg, sizeof msg));
    assert_int_equal(err, STC_ECONNECT);
    char url[400];
    snprintf(url, sizeof url, "etcd://127.0.0.1:%d/nothing-here", ETCD.client_port);
    assert_null(stc_cluster_open_etcd(url, NULL, &err, msg, sizeof msg));
    assert_int_equal(err, STC_ECONNECT);
    assert_non_null(strstr(msg, "no seamtexd"));

    /* 4. the CLI takes the URL */
    char out[4096];
    const char *args[] = {"info", "p03", NULL};
    int st = st_cluster_cli(NODE[0].dir, ETCD.url, args, out, sizeof out);
    if (st != 0)
        fail_msg("seamtex --cluster %s info p03: exit %d: %s", ETCD.url, st, out);
    assert_non_null(strstr(out, "p03"));
    /* ls lists the cluster's sets, every node's, each once (it listed the first node's) */
    const char *ls[] = {"ls", "--json", NULL};
    st = st_cluster_cli(NODE[0].dir, ETCD.url, ls, out, sizeof out);
    if (st != 0 || !strstr(out, "\"count\": 12,"))
        fail_msg("seamtex --cluster %s ls --json: exit %d: %s", ETCD.url, st, out);
    for (int s = 0; s < NSETS; s++) {
        char name[40], *at = out;
        int seen = 0;
        snprintf(name, sizeof name, "\"name\": \"p%02d\"", s);
        while ((at = strstr(at, name)) != NULL && ++seen)
            at++;
        assert_int_equal(seen, 1);
    }

    stc_cluster_close(cl);
    for (int i = 0; i < NNODES; i++)
        st_daemon_down(&NODE[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pipelined_reads_survive_kill_moved_and_open_from_etcd),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    return rc;
}
