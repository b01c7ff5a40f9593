/* tests/integration/test_cluster.c - a seamtex cluster on loopback coordinated by a real etcd
 * (docs/cluster.md): 3 nodes with R=2 take 30 uploads; a reader loop through the cluster
 * client sees zero failed reads while one node is killed with SIGKILL, while a 4th node joins
 * and sets move, while the killed node returns with stale copies, and while etcd is paused for
 * 10 s (uploads are then refused UNAVAILABLE); after each step every set is back to exactly 2
 * copies with the recorded contents; two clients racing different contents under one name
 * through two nodes: exactly one wins, everywhere.
 *
 * Lease TTL 2 s and a repair pass every second keep it bounded; the waits are deadlines (60 s)
 * against a hang, never speed checks. etcd is a declared dependency: without it the test fails.
 */
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
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

#define NSETS 30
#define NNODES 4
#define CONVERGE_MS 60000

static st_etcd ETCD;
static st_daemon NODE[NNODES];
static int live[NNODES];
static char files[4][300];      /* tints 0..3 as .ptx files */
static int set_tint[NSETS];     /* the contents each set should have; -1 deleted */

static void start_node(int i)
{
    assert_int_equal(st_cluster_node_start(&NODE[i], ETCD.url, i, 2, 0), 0);
    live[i] = 1;
}

static void setname(char *out, int k) { snprintf(out, 16, "s%02d", k); }

static float tint_red[4];

/* 1 when every live node's LIST gives each set exactly 2 holders with its contents, and
 * deleted sets nowhere */
static int converged(void *arg)
{
    (void)arg;
    int count[NSETS] = {0}, bad = 0;
    for (int i = 0; i < NNODES && !bad; i++) {
        if (!live[i])
            continue;
        stc_conn *c = st_daemon_client(&NODE[i], NULL);
        if (!c)
            return 0;
        const stc_set_entry *sets;
        size_t n;
        if (stc_list(c, &sets, &n) != 0) {
            stc_close(c);
            return 0;
        }
        char names[64][16];
        size_t nn = 0;
        for (size_t k = 0; k < n && nn < 64; k++)
            snprintf(names[nn++], 16, "%s", sets[k].name);
        for (size_t k = 0; k < nn; k++) {
            int s = atoi(names[k] + 1);
            if (names[k][0] != 's' || s < 0 || s >= NSETS || set_tint[s] < 0) {
                bad = 1;
                break;
            }
            float red;
            if (st_red_at(c, names[k], &red) != 0 || red != tint_red[set_tint[s]]) {
                bad = 1;
                break;
            }
            count[s]++;
        }
        stc_close(c);
    }
    for (int s = 0; s < NSETS && !bad; s++)
        if (count[s] != (set_tint[s] < 0 ? 0 : 2))
            bad = 1;
    return !bad;
}

/* converged, and node *arg holds some sets (the join moved sets to it) */
static int converged_with(void *arg)
{
    const st_daemon *d = arg;
    return converged(NULL) && st_daemon_stat(d, "sets") > 0;
}

static void wait_converged_with(const char *what, int (*cond)(void *), void *arg)
{
    if (st_wait_until(cond, arg, CONVERGE_MS) != 0) {
        for (int i = 0; i < NNODES; i++)
            if (live[i])
                st_daemon_dump_log(&NODE[i], 30);
        fail_msg("the cluster did not converge after: %s", what);
    }
}

static void wait_converged(const char *what) { wait_converged_with(what, converged, NULL); }

/* every live node sees every live node (after an etcd outage the nodes register again) */
static int members_settled(void *arg)
{
    (void)arg;
    uint64_t want = 0;
    for (int i = 0; i < NNODES; i++)
        want += live[i];
    for (int i = 0; i < NNODES; i++)
        if (live[i] && (st_daemon_stat(&NODE[i], "cluster_members") != want ||
                        st_daemon_stat(&NODE[i], "cluster_etcd_ok") != 1))
            return 0;
    return converged(NULL);
}

/* ---- the reader loop ------------------------------------------------------------------------- */

typedef struct reader {
    pthread_t th;
    char      seeds[128];
    int       stop;         /* atomic */
    uint64_t  reads, failures;
    char      first_failure[512];
} reader;

static void *reader_main(void *arg)
{
    reader *r = arg;
    int err = 0;
    char msg[256];
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 3000;
    stc_cluster *cl = stc_cluster_open(r->seeds, &o, &err, msg, sizeof msg);
    if (!cl) {
        r->failures++;
        snprintf(r->first_failure, sizeof r->first_failure, "open: %s", msg);
        return NULL;
    }
    for (int k = 0; !__atomic_load_n(&r->stop, __ATOMIC_RELAXED); k = (k + 1) % NSETS) {
        if (__atomic_load_n(&set_tint[k], __ATOMIC_RELAXED) < 0)
            continue;
        char name[16];
        setname(name, k);
        stc_sample_opts so;
        memset(&so, 0, sizeof so);
        so.mode = 1;
        stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
        stc_sample_result res;
        int rc = stc_cluster_sample(cl, name, &so, &q, 1, &res);
        r->reads++;
        if (rc != 0) {
            if (!r->failures)
                snprintf(r->first_failure, sizeof r->first_failure, "%s: %s (%s)", name,
                         stc_strerror(rc), stc_cluster_errmsg(cl));
            r->failures++;
        }
    }
    stc_cluster_close(cl);
    return NULL;
}

static void reader_check(reader *r, const char *phase)
{
    if (r->failures)
        fail_msg("%llu failed reads of %llu during %s; first: %s",
                 (unsigned long long)r->failures, (unsigned long long)r->reads, phase,
                 r->first_failure);
}

/* ---- the race ------------------------------------------------------------------------------ */

typedef struct racer {
    pthread_t th;
    st_daemon *node;
    const char *file;
    int rc;
    int retries;   /* UNAVAILABLE replies retried */
} racer;

/* UNAVAILABLE means "retry later" (PROTOCOL.md: etcd or the write quorum did not answer in
 * time, and the claim was withdrawn), and a client retries it; on a loaded machine right
 * after the etcd outage above one racer's first try got it while the other saw its claim
 * (EXISTS), leaving no winner. So a racer retries UNAVAILABLE (up to 5 tries, 1 s apart), as
 * a client would; what is checked is the end state: exactly one OK, the other EXISTS or BUSY.
 * The retries made are printed. */
static void *race_main(void *arg)
{
    racer *r = arg;
    for (int k = 0; k < 5; k++) {
        if (k)
            st_sleep_ms(1000);
        stc_conn *c = st_daemon_client(r->node, NULL);
        r->rc = c ? stc_upload_file(c, r->file, "race", NULL, NULL) : STC_ECONNECT;
        stc_close(c);
        if (r->rc != STC_EUNAVAILABLE)
            break;
        r->retries++;
    }
    return NULL;
}

/* ---- the CLI ------------------------------------------------------------------------------------ */

/* runs `seamtex --cluster seeds args...`; its stdout into out; returns the exit status */
static int run_cli(const char *seeds, const char *const *args, char *out, size_t cap)
{
    int rc = st_cluster_cli(NODE[0].dir, seeds, args, out, cap);
    assert_true(rc >= 0);
    return rc;
}

/* ---- the test ------------------------------------------------------------------------------- */

static void cluster_survives_kills_joins_and_etcd_outage(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/t"), 0);
    for (int i = 0; i < NNODES; i++)
        assert_int_equal(st_daemon_init(&NODE[i]), 0);
    assert_int_equal(st_cluster_tint_files(NODE[0].dir, 4, 60, files), 0);
    for (int i = 0; i < 3; i++)
        start_node(i);

    /* 30 uploads through the cluster client */
    char seeds[128];
    snprintf(seeds, sizeof seeds, "127.0.0.1:%d,127.0.0.1:%d", NODE[0].port, NODE[1].port);
    int err = 0;
    char msg[256];
    stc_cluster *cl = stc_cluster_open(seeds, NULL, &err, msg, sizeof msg);
    if (!cl)
        fail_msg("stc_cluster_open: %s", msg);
    const stc_cluster_node *nodes;
    for (int s = 0; s < NSETS; s++) {
        char name[16];
        setname(name, s);
        set_tint[s] = s % 2;
        stc_upload_result ur;
        int rc = stc_cluster_upload_file(cl, files[set_tint[s]], name, NULL, &ur);
        if (rc)
            fail_msg("upload %s: %s", name, stc_cluster_errmsg(cl));
    }
    assert_int_equal(stc_cluster_refresh(cl), 0);
    assert_int_equal(stc_cluster_nodes(cl, &nodes), 3);
    if (st_cluster_tint_reds(cl, 4, files, tint_red) != 0)
        fail_msg("probe uploads: %s", stc_cluster_errmsg(cl));
    assert_true(tint_red[0] != tint_red[1] && tint_red[2] != tint_red[3]);
    wait_converged("30 uploads");

    reader rd;
    memset(&rd, 0, sizeof rd);
    snprintf(rd.seeds, sizeof rd.seeds, "%s", seeds);
    assert_int_equal(pthread_create(&rd.th, NULL, reader_main, &rd), 0);
    st_sleep_ms(500);

    /* kill -9 one node: reads go on; after its lease every set is back to 2 copies */
    st_daemon_kill(&NODE[2]);
    live[2] = 0;
    wait_converged("kill -9 of n2");
    reader_check(&rd, "the kill");

    /* a 4th node joins: sets move to it */
    start_node(3);
    wait_converged_with("n3 joined", converged_with, &NODE[3]);
    reader_check(&rd, "the join");

    /* while n2 is down: one set deleted, one replaced; n2 returns with stale copies */
    __atomic_store_n(&set_tint[5], -1, __ATOMIC_RELAXED);   /* the reader skips it */
    assert_int_equal(stc_cluster_delete(cl, "s05"), 0);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.flags = STC_UPLOAD_REPLACE;
    __atomic_store_n(&set_tint[6], 2, __ATOMIC_RELAXED);
    if (stc_cluster_upload_file(cl, files[2], "s06", &uo, NULL) != 0)
        fail_msg("replace s06: %s", stc_cluster_errmsg(cl));
    start_node(2);
    wait_converged("n2 returned with stale copies");
    reader_check(&rd, "the return of n2");

    /* etcd paused 10 s: sampling goes on, uploads are refused UNAVAILABLE */
    assert_int_equal(st_etcd_pause(&ETCD, 1), 0);
    st_sleep_ms(2500);
    stc_conn *c0 = st_daemon_client(&NODE[0], NULL);
    assert_non_null(c0);
    int urc = stc_upload_file(c0, files[3], "during-outage", NULL, NULL);
    if (urc != STC_EUNAVAILABLE)
        fail_msg("upload during the etcd outage: %s (%s), want UNAVAILABLE", stc_strerror(urc),
                 stc_errmsg(c0));
    assert_int_equal(stc_delete(c0, "s07"), STC_EUNAVAILABLE);
    stc_close(c0);
    st_sleep_ms(7500);
    reader_check(&rd, "the etcd outage");
    assert_int_equal(st_etcd_pause(&ETCD, 0), 0);
    wait_converged_with("etcd came back", members_settled, NULL);
    int rc = -1;
    for (int k = 0; k < 100 && rc != 0; k++) {   /* the nodes notice etcd is back */
        rc = stc_cluster_upload_file(cl, files[3], "s29", &uo, NULL);
        if (rc)
            st_sleep_ms(200);
    }
    assert_int_equal(rc, 0);
    __atomic_store_n(&set_tint[29], 3, __ATOMIC_RELAXED);
    wait_converged("an upload after the outage");
    reader_check(&rd, "after the outage");
    __atomic_store_n(&rd.stop, 1, __ATOMIC_RELAXED);
    pthread_join(rd.th, NULL);
    assert_true(rd.reads > 0);
    reader_check(&rd, "the whole test");
    print_message("reader: %llu reads, 0 failed\n", (unsigned long long)rd.reads);

    /* the CLI: every node up, 29 sets (s05 deleted), none under-replicated */
    char out[8192];
    assert_int_equal(run_cli(seeds, (const char *const[]){"cluster", "--json", NULL}, out,
                             sizeof out), 0);
    /* (the CLI's one JSON writer, client/cli_json.c: two-space indents, "key": value) */
    if (!strstr(out, "\n  \"sets\": 29,\n  \"under_replicated\": []\n}") ||
        !strstr(out, "\"up\": true") || strstr(out, "\"up\": false"))
        fail_msg("seamtex cluster --json: %s", out);
    assert_int_equal(run_cli(seeds, (const char *const[]){"info", "s07", NULL}, out, sizeof out), 0);
    assert_non_null(strstr(out, "s07"));

    /* two clients race different contents under one name through two nodes */
    racer ra = {0, &NODE[0], files[0], -1, 0}, rb = {0, &NODE[1], files[1], -1, 0};
    pthread_create(&ra.th, NULL, race_main, &ra);
    pthread_create(&rb.th, NULL, race_main, &rb);
    pthread_join(ra.th, NULL);
    pthread_join(rb.th, NULL);
    if (ra.retries || rb.retries)
        print_message("race: UNAVAILABLE retried %d + %d times\n", ra.retries, rb.retries);
    int wins = (ra.rc == 0) + (rb.rc == 0);
    if (wins != 1)
        fail_msg("race: %s / %s, want exactly one OK", stc_strerror(ra.rc), stc_strerror(rb.rc));
    int loser = ra.rc == 0 ? rb.rc : ra.rc;
    assert_true(loser == STC_EEXISTS || loser == STC_EBUSY);
    float want = tint_red[ra.rc == 0 ? 0 : 1];
    st_sleep_ms(3000);   /* a few repair passes: no other contents may appear anywhere */
    int holders = 0;
    for (int i = 0; i < NNODES; i++) {
        stc_conn *c = st_daemon_client(&NODE[i], NULL);
        assert_non_null(c);
        float red = 0;
        if (st_red_at(c, "race", &red) == 0) {
            assert_true(red == want);
            holders++;
        }
        stc_close(c);
    }
    assert_int_equal(holders, 2);

    stc_cluster_close(cl);
    for (int i = 0; i < NNODES; i++)
        st_daemon_down(&NODE[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cluster_survives_kills_joins_and_etcd_outage),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    return rc;
}
