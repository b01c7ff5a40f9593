/* tests/integration/test_cluster_publish.c - REPLICA_PUBLISH naming contents the catalogue
 * does not record (PROTOCOL.md 4.11; pc32): the node answers NOT_FOUND and keeps serving its
 * copy when the catalogue records that copy's contents. Before, it hid the copy until its next
 * repair pass: with R = 1 the set was UNAVAILABLE on its owner (an outside probe: 2.4 s with
 * 5 s passes), although nothing had been written.
 *
 * 2 nodes, R = W = 1, 2 s leases, a repair pass every second, on a real etcd; no token. A set
 * is uploaded, its holder is sent REPLICA_PUBLISH with another CRC-32 (cluster/peer.h, as a
 * node sends it), and read at once and for two repair intervals. Waits are deadlines.
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
#include "peer.h"
#include "proto.h"
#include "seamtex_cluster.h"

#define DEADLINE_MS 60000

static st_etcd ETCD;
static st_daemon N[2];
static char files[1][300];

static int both_see(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

static void a_publish_of_unrecorded_contents_hides_no_current_copy(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/publish"), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 1, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 1, 1), 0);
    if (st_wait_until(both_see, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "pub", NULL, NULL), 0);
    stc_cluster_close(cl);

    /* the holder: the node that reads it itself */
    int holder = -1;
    for (int64_t t0 = st_now_ms(); holder < 0 && st_now_ms() - t0 < DEADLINE_MS;) {
        for (int i = 0; i < 2 && holder < 0; i++) {
            stc_conn *c = st_daemon_client(&N[i], NULL);
            float r = -1;
            if (c && st_red_at(c, "pub", &r) == 0)
                holder = i;
            stc_close(c);
        }
        if (holder < 0)
            st_sleep_ms(50);
    }
    assert_true(holder >= 0);

    for (int round = 0; round < 3; round++) {
        char addr[64], msg[512];
        snprintf(addr, sizeof addr, "127.0.0.1:%d", N[holder].port);
        int st = scl_peer_publish(addr, "", "pub", 0x12345678u + (uint32_t)round, 5000, msg,
                                  sizeof msg);
        if (st != STC_ENOTFOUND)
            fail_msg("REPLICA_PUBLISH of unrecorded contents: status %d (%s), want NOT_FOUND",
                     st, msg);
        /* read at once, then for two repair intervals */
        int refused = 0, reads = 0;
        for (int64_t t0 = st_now_ms(); st_now_ms() - t0 < 2000; reads++) {
            stc_conn *c = st_daemon_client(&N[holder], NULL);
            float r = -1;
            refused += !c || st_red_at(c, "pub", &r) != 0;
            stc_close(c);
            st_sleep_ms(20);
        }
        if (refused)
            fail_msg("round %d: %d of %d reads of the holder's current copy refused after a "
                     "REPLICA_PUBLISH naming other contents", round, refused, reads);
    }
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_publish_of_unrecorded_contents_hides_no_current_copy),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
