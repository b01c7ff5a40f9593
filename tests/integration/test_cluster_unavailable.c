/* tests/integration/test_cluster_unavailable.c - a set the catalogue records but that no live
 * node holds is UNAVAILABLE, not NOT_FOUND (PROTOCOL.md 4.11, docs/cluster.md "Reads and
 * MOVED"): "no such set" is a wrong answer for an acknowledged set whose holders are all down.
 *
 * 2 nodes, R = W = 1, 2 s leases, on a real etcd. "solo" is uploaded (acknowledged, one copy on
 * its owner), a name "never" is not. The owner is killed; once the other node's membership has
 * dropped it (its lease ended) the survivor is the set's owner in its own view and holds no
 * copy: a read of "solo" there, directly and through the cluster client, must be UNAVAILABLE
 * ("no live node holds a copy"), while "never" stays NOT_FOUND. After the owner restarts, "solo" reads
 * with its contents again. Without the rule the survivor answered NOT_FOUND.
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

static st_etcd ETCD;
static st_daemon N[2];
static char files[1][300];

static int all_see_two(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

static int survivor_alone(void *arg)
{
    return st_cluster_all_see(&N[*(int *)arg], 1, 1);
}

struct reads {
    stc_cluster *cl;
    float red;
};

static int solo_reads(void *arg)
{
    struct reads *r = arg;
    return st_cluster_red_at(r->cl, "solo", &r->red) == 0;
}

static void a_set_whose_holders_are_down_is_unavailable_not_missing(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/unavail"), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 1, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 1, 1), 0);
    if (st_wait_until(all_see_two, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "solo", NULL, NULL), 0);
    float red0 = -1;
    assert_int_equal(st_cluster_red_at(cl, "solo", &red0), 0);
    int owner = -1;
    for (int i = 0; i < 2; i++) {   /* the owner is the node that holds the only copy */
        stc_conn *c = st_daemon_client(&N[i], NULL);
        assert_non_null(c);
        float r;
        if (st_red_at(c, "solo", &r) == 0 && owner < 0)
            owner = i;
        stc_close(c);
    }
    assert_true(owner >= 0);
    int other = 1 - owner;
    stc_cluster_close(cl);

    st_daemon_kill(&N[owner]);
    if (st_wait_until(survivor_alone, &other, DEADLINE_MS) != 0)
        fail_msg("n%d never dropped the killed owner from its membership", other);
    stc_conn *c = st_daemon_client(&N[other], NULL);
    assert_non_null(c);
    float r;
    int rc = st_red_at(c, "solo", &r);
    print_message("survivor n%d on 'solo': rc %d (%s)\n", other, rc, stc_errmsg(c));
    assert_int_equal(rc, STC_EUNAVAILABLE);
    assert_non_null(strstr(stc_errmsg(c), "no live node holds a copy"));
    assert_int_equal(st_red_at(c, "never", &r), STC_ENOTFOUND);
    stc_close(c);
    cl = st_cluster_open_nodes(&N[other], 1);
    assert_non_null(cl);
    assert_int_equal(st_cluster_red_at(cl, "solo", &r), STC_EUNAVAILABLE);
    assert_int_equal(st_cluster_red_at(cl, "never", &r), STC_ENOTFOUND);
    stc_cluster_close(cl);

    /* the holder comes back: the set is read again, with its contents */
    assert_int_equal(st_cluster_node_start(&N[owner], ETCD.url, owner, 1, 1), 0);
    if (st_wait_until(all_see_two, NULL, DEADLINE_MS) != 0)
        fail_msg("the restarted owner never rejoined");
    struct reads rd = {.cl = st_cluster_open_nodes(N, 2), .red = -1};
    assert_non_null(rd.cl);
    if (st_wait_until(solo_reads, &rd, DEADLINE_MS) != 0)
        fail_msg("'solo' never read again after its holder returned");
    assert_true(rd.red == red0);
    stc_cluster_close(rd.cl);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_set_whose_holders_are_down_is_unavailable_not_missing),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
