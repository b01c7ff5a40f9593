/* tests/integration/test_cluster_stale.c - a node that was down while a set was deleted or
 * replaced does not serve its old copy when it returns (docs/cluster.md "Reads and MOVED"):
 * reads of a local copy wait until the catalogue has confirmed it. And the gate does not hold
 * back a write just acknowledged: both owners serve it at once.
 *
 * 2 nodes, R = W = 2, 2 s leases, a repair pass every second, on a real etcd. n1 is killed,
 * "gone" deleted and "swap" replaced through n0, n1 restarted with its data dir (its copies
 * are the old ones); for three lease TTLs after it answers again, every read of "gone" on n1
 * is refused (MOVED or NOT_FOUND), "swap" comes back with the new contents or not at all, and
 * LIST never shows "gone"; in the end n1 serves the new "swap" itself. Before the gate, n1
 * served the deleted set for about two lease TTLs after its first repair pass, and the cluster
 * client, asking it as the set's next owner after NOT_FOUND, returned the deleted contents.
 * Waits are deadlines against a hang.
 */
#include <setjmp.h>
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
#include "../common/wait.h"
#include "seamtex_cluster.h"

#define DEADLINE_MS 60000
#define WATCH_MS    6000    /* three lease TTLs of the fixture's nodes */

static st_etcd ETCD;
static st_daemon N[2];
static char files[2][300];
static float red[2];

static int both_see(void *arg)
{
    return st_cluster_all_see(N, 2, (uint64_t)(intptr_t)arg);
}

static int n0_alone(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 1, 1);
}

/* 1 when node i's LIST names set */
static int lists(stc_conn *c, const char *set)
{
    const stc_set_entry *sets;
    size_t n;
    int found = 0;
    if (c && stc_list(c, &sets, &n) == 0)
        for (size_t k = 0; k < n; k++)
            found |= !strcmp(sets[k].name, set);
    return found;
}

static void a_just_acknowledged_upload_is_served_by_both_owners(void)
{
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    for (int t = 0; t < 6; t++) {
        char name[32];
        snprintf(name, sizeof name, "fresh%d", t);
        assert_int_equal(stc_cluster_upload_file(cl, files[t & 1], name, NULL, NULL), 0);
        for (int i = 0; i < 2; i++) {   /* at once, on each node directly */
            stc_conn *c = st_daemon_client(&N[i], NULL);
            float r = -1;
            int rc = c ? st_red_at(c, name, &r) : -1;
            stc_close(c);
            if (rc != 0 || r != red[t & 1])
                fail_msg("node %d answers %d (red %g, want %g) for %s just acknowledged", i,
                         rc, r, red[t & 1], name);
        }
    }
    stc_cluster_close(cl);
}

static void a_returning_node_does_not_serve_deleted_or_replaced_copies(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/stale"), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 2, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 2, 0), 0);
    if (st_wait_until(both_see, (void *)(intptr_t)2, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(st_cluster_tint_reds(cl, 2, files, red), 0);
    assert_true(red[0] != red[1]);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "gone", NULL, NULL), 0);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "swap", NULL, NULL), 0);
    stc_cluster_close(cl);
    a_just_acknowledged_upload_is_served_by_both_owners();

    /* n1 away; n0 alone deletes one set and replaces the other */
    st_daemon_kill(&N[1]);
    if (st_wait_until(n0_alone, NULL, DEADLINE_MS) != 0)
        fail_msg("n0 still counts n1 a member");
    stc_conn *c0 = st_daemon_client(&N[0], NULL);
    assert_non_null(c0);
    assert_int_equal(stc_delete(c0, "gone"), 0);
    stc_upload_opts uo = {.flags = STC_UPLOAD_REPLACE};
    assert_int_equal(stc_upload_file(c0, files[1], "swap", &uo, NULL), 0);
    stc_close(c0);

    /* n1 back with its old copies of both */
    assert_int_equal(st_cluster_node_start(&N[1], ETCD.url, 1, 2, 0), 0);
    int64_t t0 = st_now_ms();
    int served_old = 0, served_gone = 0, listed_gone = 0, served_new = 0, rounds = 0;
    while (st_now_ms() - t0 < WATCH_MS || !served_new) {
        if (st_now_ms() - t0 > DEADLINE_MS)
            break;
        stc_conn *c1 = st_daemon_client(&N[1], NULL);
        if (!c1)
            continue;
        float r = -1;
        served_gone += st_red_at(c1, "gone", &r) == 0;
        listed_gone += lists(c1, "gone");
        if (st_red_at(c1, "swap", &r) == 0) {
            served_old += r != red[1];
            served_new |= r == red[1];
        }
        stc_close(c1);
        stc_cluster *cl2 = st_cluster_open_nodes(N, 2);   /* the cluster client, n1 among its seeds */
        if (cl2) {
            served_gone += st_cluster_red_at(cl2, "gone", &r) == 0;
            if (st_cluster_red_at(cl2, "swap", &r) == 0)
                served_old += r != red[1];
            stc_cluster_close(cl2);
        }
        rounds++;
        st_sleep_ms(10);   /* the rounds are the watch: a pause between them, not a spin */
    }
    print_message("%d rounds over n1's return\n", rounds);
    if (served_gone || listed_gone)
        fail_msg("the deleted set was read %d times and listed %d times after n1 returned",
                 served_gone, listed_gone);
    if (served_old)
        fail_msg("the replaced set came back with its old contents %d times", served_old);
    if (!served_new)
        fail_msg("n1 never served the new contents itself");
    assert_true(st_daemon_stat(&N[1], "cluster_reads_unconfirmed") >= 1);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_returning_node_does_not_serve_deleted_or_replaced_copies),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
