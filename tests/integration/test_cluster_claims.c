/* tests/integration/test_cluster_claims.c - a pending claim whose origin node was killed
 * between its claim (and staging its copy) and the write quorum, and restarted at once, is
 * abandoned (docs/cluster.md "Repair"): the name is free again and the refused upload's copy
 * goes. Claims carry the origin's incarnation; the restarted node is a member again, but of
 * another incarnation.
 *
 * Deterministic: 2 nodes with R=2 and W=2 on a real etcd; n1 is stopped (SIGSTOP) so that
 * n0's push of the upload to n1 waits; n0 is killed once the upload is staged on it (STATS
 * cluster_copies_staged; the staged copy is kept across the restart until the catalogue
 * decides), n1 continued, n0 restarted with its data dir. Leases of 5 s keep n1 a member
 * while it is stopped and n0 one across its restart. Waits are deadlines against a hang.
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

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/testdata.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"

#define DEADLINE_MS 60000
#define LEASE "5"    /* s: n1 stays a member while stopped until n0 has claimed, on a slow machine */

static st_etcd ETCD;
static st_daemon N[2];
static char files[2][300];
static float red[2];

/* node i of the cluster, R = W = 2, with LEASE (cluster_fixture.h's nodes have 2 s) */
static int start_node(int i)
{
    const char *id = i ? "n1" : "n0";
    const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise", "127.0.0.1:0",
                          "--replicas", "2", "--write-quorum", "2", "--lease-ttl", LEASE,
                          "--repair-interval", "1", "--no-default-set", NULL};
    return st_daemon_start(&N[i], args);
}

static int both_members(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

/* n0 has staged one more upload than before (its copy is durable, not published) */
static uint64_t staged_before;
static int n0_staged(void *arg)
{
    (void)arg;
    return st_daemon_stat(&N[0], "cluster_copies_staged") > staged_before;
}

/* entries in <data-dir of node i>/staged */
static int staged_count(int i)
{
    char p[400];
    snprintf(p, sizeof p, "%s/staged", N[i].datadir);
    return st_test_dir_entries(p);
}

static int n0_staged_none(void *arg) { (void)arg; return staged_count(0) == 0; }

static int upload_rc = -1;

static void *upload_main(void *arg)
{
    (void)arg;
    stc_conn *c = st_daemon_client(&N[0], NULL);
    if (c)
        upload_rc = stc_upload_file(c, files[0], "stuck", NULL, NULL);   /* n0 dies under it */
    stc_close(c);
    return NULL;
}

/* the other contents are accepted under the name (each try is EXISTS while the claim holds) */
static int name_free(void *arg)
{
    (void)arg;
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    int rc = cl ? stc_cluster_upload_file(cl, files[1], "stuck", NULL, NULL) : -1;
    stc_cluster_close(cl);
    return rc == 0;
}

/* both nodes serve "stuck" with the second contents */
static int both_serve_second(void *arg)
{
    (void)arg;
    for (int i = 0; i < 2; i++) {
        stc_conn *c = st_daemon_client(&N[i], NULL);
        float r = -1;
        int rc = c ? st_red_at(c, "stuck", &r) : -1;
        stc_close(c);
        if (rc || r != red[1])
            return 0;
    }
    return 1;
}

/* etcd under prefix, both nodes (fresh data dirs) members of it, the two tints' reds known */
static void start_pair(const char *prefix)
{
    assert_int_equal(st_etcd_start(&ETCD, prefix), 0);
    for (int i = 0; i < 2; i++) {
        st_daemon_cleanup(&N[i]);
        assert_int_equal(st_daemon_init(&N[i]), 0);
    }
    assert_int_equal(st_cluster_tint_files(N[0].dir, 2, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(start_node(i), 0);
    if (st_wait_until(both_members, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(st_cluster_tint_reds(cl, 2, files, red), 0);
    stc_cluster_close(cl);
    assert_true(red[0] != red[1]);
}

static void claim_of_a_restarted_origin_is_abandoned(void **state)
{
    (void)state;
    start_pair("/claims");

    /* n0 claims and commits "stuck", then waits on its push to the stopped n1 */
    staged_before = st_daemon_stat(&N[0], "cluster_copies_staged");
    assert_int_equal(st_daemon_signal(&N[1], SIGSTOP), 0);
    pthread_t up;
    assert_int_equal(pthread_create(&up, NULL, upload_main, NULL), 0);
    int committed = st_wait_until(n0_staged, NULL, DEADLINE_MS) == 0;
    st_daemon_kill(&N[0]);
    st_daemon_signal(&N[1], SIGCONT);
    pthread_join(up, NULL);
    if (!committed)
        fail_msg("n0 never committed the upload");
    if (upload_rc == 0)
        fail_msg("the upload was acknowledged: n1 left (its lease ran out) before n0 claimed");
    /* back at once with its data dir: a member again before its lease ran out */
    assert_int_equal(start_node(0), 0);
    if (st_wait_until(both_members, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes did not see each other again");

    if (st_wait_until(name_free, NULL, DEADLINE_MS) != 0) {
        st_daemon_dump_log(&N[0], 20);
        fail_msg("the claim of the killed upload still holds the name");
    }
    if (st_wait_until(both_serve_second, NULL, DEADLINE_MS) != 0)
        fail_msg("the second contents are not on both nodes");
    /* the killed upload's staged copy goes (the catalogue records other contents) */
    if (st_wait_until(n0_staged_none, NULL, DEADLINE_MS) != 0)
        fail_msg("n0 keeps the staged copy of the abandoned upload");
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

static uint64_t claims_before;
static int n0_claimed(void *arg) { (void)arg; return st_daemon_stat(&N[0], "cluster_claims") > claims_before; }

static int replace_rc = -1;

static void *replace_main(void *arg)
{
    (void)arg;
    stc_conn *c = st_daemon_client(&N[0], NULL);
    stc_upload_opts uo = {.flags = STC_UPLOAD_REPLACE};
    if (c)
        replace_rc = stc_upload_file(c, files[1], "kept", &uo, NULL);   /* n0 dies under it */
    stc_close(c);
    return NULL;
}

/* both nodes serve "kept" with the first contents */
static int both_serve_first(void *arg)
{
    (void)arg;
    for (int i = 0; i < 2; i++) {
        stc_conn *c = st_daemon_client(&N[i], NULL);
        float r = -1;
        int rc = c ? st_red_at(c, "kept", &r) : -1;
        stc_close(c);
        if (rc || r != red[0])
            return 0;
    }
    return 1;
}

/* The same for a REPLACE (found by an outside client's churn, cl27): abandoning the claim used
 * to delete the record, and with it the acknowledged contents the REPLACE had not replaced -
 * NOT_FOUND on every node for good. Now the claim's transaction keeps the replaced record
 * (prev/) and abandoning records it again: both nodes serve the first contents. */
static void replace_claim_of_a_restarted_origin_gives_the_name_back(void **state)
{
    (void)state;
    start_pair("/claims-replace");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "kept", NULL, NULL), 0);
    stc_cluster_close(cl);
    if (st_wait_until(both_serve_first, NULL, DEADLINE_MS) != 0)
        fail_msg("the first contents are not on both nodes");

    /* n0 claims the REPLACE, then waits on its push to the stopped n1; killed there */
    claims_before = st_daemon_stat(&N[0], "cluster_claims");
    staged_before = st_daemon_stat(&N[0], "cluster_copies_staged");
    assert_int_equal(st_daemon_signal(&N[1], SIGSTOP), 0);
    pthread_t up;
    assert_int_equal(pthread_create(&up, NULL, replace_main, NULL), 0);
    int claimed = st_wait_until(n0_claimed, NULL, DEADLINE_MS) == 0 &&
                  st_wait_until(n0_staged, NULL, DEADLINE_MS) == 0;   /* staged durably */
    /* while the REPLACE waits on its push, n0 still serves the acknowledged contents */
    float mid = -1;
    stc_conn *c0 = claimed ? st_daemon_client(&N[0], NULL) : NULL;
    int mid_rc = c0 ? st_red_at(c0, "kept", &mid) : -1;
    stc_close(c0);
    st_daemon_kill(&N[0]);
    st_daemon_signal(&N[1], SIGCONT);
    pthread_join(up, NULL);
    if (!claimed)
        fail_msg("n0 never claimed the replace");
    if (replace_rc == 0)
        fail_msg("the replace was acknowledged: n1 left (its lease ran out) before n0 claimed");
    if (mid_rc != 0 || mid != red[0])
        fail_msg("during the replace n0 read 'kept' as %d (red %g), not the acknowledged %g",
                 mid_rc, mid, red[0]);
    assert_int_equal(staged_count(0), 1);   /* kept across the kill: the catalogue decides */
    assert_int_equal(start_node(0), 0);
    if (st_wait_until(both_members, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes did not see each other again");
    if (st_wait_until(both_serve_first, NULL, DEADLINE_MS) != 0) {
        st_daemon_dump_log(&N[0], 20);
        st_daemon_dump_log(&N[1], 20);
        fail_msg("the acknowledged contents are gone after the abandoned replace");
    }
    /* the abandoned replace's staged copy goes; nothing of it was ever published */
    if (st_wait_until(n0_staged_none, NULL, DEADLINE_MS) != 0)
        fail_msg("n0 keeps the staged copy of the abandoned replace");
    assert_int_equal(st_daemon_stat(&N[0], "cluster_staged_published"), 0);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(claim_of_a_restarted_origin_is_abandoned),
        cmocka_unit_test(replace_claim_of_a_restarted_origin_gives_the_name_back),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
