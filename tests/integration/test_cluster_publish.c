/* tests/integration/test_cluster_publish.c - REPLICA_PUBLISH naming contents the catalogue
 * does not record (PROTOCOL.md 4.11; pc32): the node answers NOT_FOUND and keeps serving its
 * copy when the catalogue records that copy's contents. Before, it hid the copy until its next
 * repair pass: with R = 1 the set was UNAVAILABLE on its owner (an outside probe: 2.4 s with
 * 5 s passes), although nothing had been written.
 *
 * With etcd out of the node's reach the message cannot be checked: the node answers
 * UNAVAILABLE and keeps serving its copy, as every copy is served while etcd is away (left33:
 * before, it believed the message and hid the copy, so one unverifiable message took the set
 * off the air); once etcd answers, the catalogue decides - the copy stays served when it
 * records the copy's contents, and stops being served when it records other contents.
 *
 * 2 nodes, R = W = 1, 2 s leases, a repair pass every second, on a real etcd; no token; n0
 * reaches etcd through a proxy that can cut it off (tests/common/etcd_hold.h). A set is
 * uploaded, its holder is sent REPLICA_PUBLISH with another CRC-32 (cluster/peer.h, as a node
 * sends it), and read at once and for two repair intervals. Waits are deadlines.
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
#include "../common/etcd_hold.h"
#include "../common/wait.h"
#include "catalog.h"
#include "etcd.h"
#include "peer.h"
#include "proto.h"
#include "seamtex_cluster.h"
#include "stp_cluster.h"

#define DEADLINE_MS 60000

static st_etcd ETCD;
static st_etcd_hold *PROXY;
static scl_etcd *E;          /* the test's own handle on etcd (not through the proxy) */
static st_daemon N[2];
static char files[1][300];
static char proxy_url[320];

static int both_see(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

static void a_publish_of_unrecorded_contents_hides_no_current_copy(void **state)
{
    (void)state;
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
        if (st != SCL_PEER_NOT_FOUND)   /* the receiver's NOT_FOUND (peer.h) */
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
}

static int n0_serves(void *arg)
{
    return st_red_on(&N[0], arg) >= 0;
}

static int n0_does_not_serve(void *arg)
{
    return st_red_on(&N[0], arg) < 0;
}

/* A name whose owner (R = 1) is n0, the node behind the proxy. */
static void name_owned_by_n0(char *name, size_t cap)
{
    const char *ids[2] = {"n0", "n1"};
    for (int k = 0; k < 1000; k++) {
        snprintf(name, cap, "cut%d", k);
        size_t order[2];
        if (stp_hrw_rank(ids, 2, name, order, 1) == 1 && order[0] == 0)
            return;
    }
    fail_msg("no name of 1000 is owned by n0");
}

static int publish_to_n0(const char *name, uint32_t crc, char *msg, size_t cap)
{
    char addr[64];
    snprintf(addr, sizeof addr, "127.0.0.1:%d", N[0].port);
    return scl_peer_publish(addr, "", name, crc, 5000, msg, cap);
}

/* Reads of n0 for ms: how many were refused (*reads: how many were made). */
static int refused_on_n0(const char *name, int ms, int *reads)
{
    int refused = 0;
    *reads = 0;
    for (int64_t t0 = st_now_ms(); st_now_ms() - t0 < ms; (*reads)++) {
        refused += st_red_on(&N[0], name) < 0;
        st_sleep_ms(20);
    }
    return refused;
}

static void a_publish_that_cannot_be_checked_hides_nothing_until_etcd_answers(void **state)
{
    (void)state;
    char name[32], msg[512];
    name_owned_by_n0(name, sizeof name);
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], name, NULL, NULL), 0);
    stc_cluster_close(cl);
    if (st_wait_until(n0_serves, name, DEADLINE_MS) != 0)
        fail_msg("n0 never served '%s'", name);

    /* 1. n0 cut off etcd; a publish naming contents nobody recorded: not believed */
    st_etcd_hold_cut(PROXY, 1);
    int st = publish_to_n0(name, 0x12345678u, msg, sizeof msg);
    int reads = 0, refused = refused_on_n0(name, 2000, &reads);
    st_etcd_hold_cut(PROXY, 0);
    if (refused)
        fail_msg("%d of %d reads of n0's copy refused after a REPLICA_PUBLISH it could not "
                 "check (etcd cut off; status %d)", refused, reads, st);
    if (st != STC_EUNAVAILABLE)
        fail_msg("REPLICA_PUBLISH n0 cannot check: status %d (%s), want UNAVAILABLE", st, msg);
    /* etcd back: the catalogue records n0's copy, which stays served */
    if (st_wait_until(both_see, NULL, DEADLINE_MS) != 0)
        fail_msg("n0 never rejoined");
    refused = refused_on_n0(name, 2000, &reads);
    if (refused)
        fail_msg("%d of %d reads of n0's copy refused once etcd answered again", refused, reads);

    /* 2. n0 cut off again; other contents of the set recorded meanwhile (a write recorded by
     * another node, whose tell n0 cannot check): still served while n0 cannot read etcd, and
     * no longer once it can */
    st_etcd_hold_cut(PROXY, 1);
    char key[SCL_KEY_MAX], val[2048];
    scl_key_set(key, "/publish", name);
    scl_kvs kvs;
    assert_int_equal(scl_etcd_range(E, key, 0, &kvs), SCL_OK);
    assert_int_equal(kvs.n, 1);
    scl_setrec rec;
    assert_int_equal(scl_setrec_parse(kvs.v[0].val, &rec), 0);
    scl_kvs_free(&kvs);
    rec.crc32 ^= 0x5a5a5a5au;
    rec.crc32c ^= 0x5a5a5a5au;
    rec.version++;
    assert_int_equal(scl_setrec_format(val, sizeof val, &rec), 0);
    assert_int_equal(scl_etcd_put(E, key, val, 0), SCL_OK);
    st = publish_to_n0(name, rec.crc32, msg, sizeof msg);
    refused = refused_on_n0(name, 1000, &reads);
    st_etcd_hold_cut(PROXY, 0);
    if (refused)
        fail_msg("%d of %d reads of n0's copy refused while etcd was out of its reach",
                 refused, reads);
    if (st != STC_EUNAVAILABLE)
        fail_msg("REPLICA_PUBLISH n0 cannot check: status %d (%s), want UNAVAILABLE", st, msg);
    int64_t back = st_now_ms();
    if (st_wait_until(n0_does_not_serve, name, DEADLINE_MS) != 0)
        fail_msg("n0 still serves '%s' whose other contents the catalogue records", name);
    print_message("n0 stopped serving the superseded copy %lld ms after etcd was back\n",
                  (long long)(st_now_ms() - back));
}

static int setup(void **state)
{
    (void)state;
    scl_etcd_global_init();
    if (st_etcd_start(&ETCD, "/publish") != 0)
        return -1;
    PROXY = st_etcd_hold_start(ETCD.client_port, "/publish", proxy_url, sizeof proxy_url);
    char err[256];
    E = scl_etcd_open(ETCD.url, 5000, err, sizeof err);
    if (!PROXY || !E)
        return -1;
    for (int i = 0; i < 2; i++)
        if (st_daemon_init(&N[i]) != 0)
            return -1;
    if (st_cluster_tint_files(N[0].dir, 1, 40, files) != 0 ||
        st_cluster_node_start(&N[0], proxy_url, 0, 1, 1) != 0 ||
        st_cluster_node_start(&N[1], ETCD.url, 1, 1, 1) != 0)
        return -1;
    return st_wait_until(both_see, NULL, DEADLINE_MS);
}

static int teardown(void **state)
{
    (void)state;
    int bad = 0;
    for (int i = 0; i < 2; i++)
        bad |= st_daemon_down(&N[i], 10000) != 0;
    st_etcd_hold_stop(PROXY);
    scl_etcd_close(E);
    st_etcd_stop(&ETCD);
    return bad;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_publish_of_unrecorded_contents_hides_no_current_copy),
        cmocka_unit_test(a_publish_that_cannot_be_checked_hides_nothing_until_etcd_answers),
    };
    int rc = cmocka_run_group_tests(tests, setup, teardown);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
