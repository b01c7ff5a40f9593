/* tests/integration/test_cluster_advertise.c - a node notices when its --advertise address
 * does not reach it (docs/cluster.md "Operating a cluster", server/cluster_node.c
 * sts_cluster_advertise_check).
 *
 * 3 nodes on a real etcd: n0 advertises its own address (127.0.0.1:0, the port it bound), n1
 * a loopback port where nothing listens, n2 n0's address (another node answers there). Each
 * starts all the same (a wrong address is never fatal). Within a few repair passes n0's STATS
 * cluster_advertise_ok is 1 and it logs nothing about it; n1's and n2's are 0, each logged
 * one WARN naming the address and the cause ("Connection refused", "node 'n0' answers
 * there"), and several passes later still one: logged on a change only.
 * Before the check the node did not notice (no key, no log).
 */
#include <netinet/in.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "../common/wire.h"

#define DEADLINE_MS 30000
#define WARN_TEXT "does not reach this node"

static st_etcd ETCD;
static st_daemon N[3];

static int start_node(int i, const char *advertise)
{
    char id[16];
    snprintf(id, sizeof id, "n%d", i);
    const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise", advertise,
                          "--replicas", "1", "--write-quorum", "1", "--lease-ttl", "2",
                          "--repair-interval", "1", "--no-default-set", NULL};
    return st_daemon_start(&N[i], args);
}

static int settled(void *arg)
{
    (void)arg;
    return st_daemon_stat(&N[0], "cluster_advertise_ok") == 1 &&
           st_daemon_log_count(&N[1], WARN_TEXT) >= 1 && st_daemon_log_count(&N[2], WARN_TEXT) >= 1;
}

static void a_wrong_advertise_is_noticed(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/adv"), 0);
    for (int i = 0; i < 3; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(start_node(0, "127.0.0.1:0"), 0);
    char dead[64], other[64];
    int port = st_wire_free_port() /* nothing listens there */;
    assert_true(port > 0);
    snprintf(dead, sizeof dead, "127.0.0.1:%d", port);
    snprintf(other, sizeof other, "127.0.0.1:%d", N[0].port);
    assert_int_equal(start_node(1, dead), 0);    /* started all the same */
    assert_int_equal(start_node(2, other), 0);
    if (st_wait_until(settled, NULL, DEADLINE_MS) != 0)
        fail_msg("the self-check did not run: n0 ok %llu, n1 warns %d, n2 warns %d",
                 (unsigned long long)st_daemon_stat(&N[0], "cluster_advertise_ok"),
                 st_daemon_log_count(&N[1], WARN_TEXT), st_daemon_log_count(&N[2], WARN_TEXT));
    uint64_t p1 = st_daemon_stat(&N[1], "cluster_repair_passes");
    st_sleep_ms(3500);   /* three passes more, each checking again */
    assert_true(st_daemon_stat(&N[1], "cluster_repair_passes") >= p1 + 2);
    assert_int_equal(st_daemon_stat(&N[0], "cluster_advertise_ok"), 1);
    assert_int_equal(st_daemon_stat(&N[1], "cluster_advertise_ok"), 0);
    assert_int_equal(st_daemon_stat(&N[2], "cluster_advertise_ok"), 0);
    assert_int_equal(st_daemon_log_count(&N[0], WARN_TEXT), 0);
    assert_int_equal(st_daemon_log_count(&N[1], WARN_TEXT), 1);   /* on a change only */
    assert_int_equal(st_daemon_log_count(&N[2], WARN_TEXT), 1);
    char needle[128];
    snprintf(needle, sizeof needle, "address %s " WARN_TEXT, dead);
    assert_int_equal(st_daemon_log_count(&N[1], needle), 1);
    assert_int_equal(st_daemon_log_count(&N[2], "node 'n0' answers there"), 1);
    for (int i = 0; i < 3; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_wrong_advertise_is_noticed),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 3; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
