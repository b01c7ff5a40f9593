/* tests/integration/test_cluster_join.c - what a node checks when it joins a cluster: its id
 * and the cluster's settings (docs/cluster.md "Node ids", "Flags").
 *
 * One node id, one process: two nodes started with the same --node-id must not both act as
 * that node, and the one that goes must not take the other out of the cluster.
 *
 * 2 nodes n0, n1 (R = W = 2, 2 s leases) on a real etcd. (1) A third process started with
 * --node-id n1 (its own port and data dir) while n1 answers: it refuses to start and says
 * why. Before, it put nodes/n1 over n1's key, and both processes acted as n1. (2) n1 stopped
 * (SIGSTOP: it does not answer), the third process started as n1 (it takes the id over: the
 * process that registered it does not answer), n1 continued, then the third process stopped
 * (SIGTERM, a graceful leave): n1 is a member again at its own address, and stays one past a
 * lease TTL. Before, the leaver deleted nodes/n1 whoever had put it last, and n1 - alive,
 * its lease kept alive - was out of the membership for good, without a word in its log.
 * (3) A node started with --replicas 3, or --write-quorum 1, against the cluster's 2 / 2
 * (PREFIX/config, put by the first node) refuses to start and names both; one with 2 / 2
 * joins. Before, it joined and placed sets by its own R: it pushed third copies that the
 * others dropped as extra, over and over (clu35's probe).
 */
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
#include "../common/wait.h"

#define DEADLINE_MS 30000

static st_etcd ETCD;
static st_daemon N[2], D;

static int all_see_two(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

/* `seamtex --cluster <etcd> cluster --json` lists n1 at its own address, not at D's */
static int n1_home(void)
{
    const char *args[] = {"cluster", "--json", NULL};
    char out[8192];
    if (st_cluster_cli(N[0].dir, ETCD.url, args, out, sizeof out) < 0)
        return 0;
    char want[64], dup[64];
    snprintf(want, sizeof want, "127.0.0.1:%d", N[1].port);
    snprintf(dup, sizeof dup, "127.0.0.1:%d", D.port);
    return strstr(out, want) && !(D.port && strstr(out, dup));
}

static int n1_back(void *arg)
{
    (void)arg;
    return n1_home();
}

static void a_second_process_with_a_live_nodes_id_refuses_to_start(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/nodeid"), 0);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(st_daemon_init(&N[i]), 0);
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 2, 2), 0);
    }
    assert_int_equal(st_daemon_init(&D), 0);
    if (st_wait_until(all_see_two, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    if (st_cluster_node_start(&D, ETCD.url, 1, 2, 2) == 0) {
        st_daemon_kill(&D);
        fail_msg("a second process with node id n1 started while n1 answers");
    }
    assert_true(st_daemon_log_count(&D, "node id 'n1' is in use") >= 1);
    D.port = 0;
    assert_true(n1_home());
}

static void the_leave_of_another_process_of_the_id_keeps_the_node_in(void **state)
{
    (void)state;
    assert_int_equal(st_daemon_signal(&N[1], SIGSTOP), 0);
    int started = st_cluster_node_start(&D, ETCD.url, 1, 2, 2);   /* n1 does not answer */
    assert_int_equal(kill(N[1].pid, SIGCONT), 0);
    assert_int_equal(started, 0);
    st_sleep_ms(1500);
    assert_int_equal(st_daemon_stop(&D, 10000), 0);
    if (st_wait_until(n1_back, NULL, DEADLINE_MS) != 0)
        fail_msg("n1 (alive) is not a member after the other process of its id left");
    st_sleep_ms(3000);   /* past a lease TTL: still a member */
    assert_true(n1_home());
    assert_true(st_daemon_log_count(&N[1], "registering again") +
                st_daemon_log_count(&D, "its key was another process's") >= 1);
}

static void a_node_with_other_replicas_or_quorum_refuses_to_start(void **state)
{
    (void)state;
    static const unsigned rw[2][2] = {{3, 2}, {2, 1}};
    for (int k = 0; k < 2; k++) {
        if (st_cluster_node_start(&D, ETCD.url, 2, rw[k][0], rw[k][1]) == 0) {
            st_daemon_kill(&D);
            fail_msg("n2 started with --replicas %u --write-quorum %u in a 2 / 2 cluster",
                     rw[k][0], rw[k][1]);
        }
    }
    assert_int_equal(st_daemon_log_count(&D, "this cluster has replicas 2, write quorum 2"), 2);
    assert_int_equal(st_cluster_node_start(&D, ETCD.url, 2, 2, 2), 0);
    st_daemon_down(&D, 10000);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_second_process_with_a_live_nodes_id_refuses_to_start),
        cmocka_unit_test(the_leave_of_another_process_of_the_id_keeps_the_node_in),
        cmocka_unit_test(a_node_with_other_replicas_or_quorum_refuses_to_start),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    st_daemon_cleanup(&D);
    return rc;
}
