/* tests/integration/test_cluster_wipe.c - an etcd that lost its data loses no set
 * (docs/cluster.md "Catalogue lost", server/cluster_mark.c).
 *
 * 3 nodes, R = W = 2, 2 s leases, on a real etcd. Five sets are uploaded with their own
 * contents, one of them replaced, and a sixth uploaded and deleted (every node's copy of it
 * gone). Then etcd is killed, its data dir removed and etcd started again on the same ports:
 * an empty store. For 3 lease TTLs and more every set is read through the cluster client
 * every 50 ms, always with its contents; the deleted one stays NOT_FOUND; every set is
 * recorded again (a cluster client on the etcd URL lists it through its owners), a new upload
 * and a DELETE work. Then the whole cluster goes down, etcd is wiped again, and the nodes
 * start on the empty etcd: every set reads again with its contents.
 * Before the mark, each node's repair pass found its sets missing from the catalogue and
 * dropped them as deleted two lease TTLs later: every set NOT_FOUND, on every node.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"
#include "seamtex_etcd.h"

#define DEADLINE_MS 60000
#define NSETS 5

static st_etcd ETCD;
static st_daemon N[3];
static char files[7][300];
static const char *names[NSETS] = {"alpha", "bravo", "charlie", "delta", "echo"};

static int all_see_three(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 3, 3);
}

static int gone_from_every_data_dir(void *arg)
{
    for (int i = 0; i < 3; i++) {
        char p[512];
        struct stat st;
        snprintf(p, sizeof p, "%s/sets/%s", N[i].datadir, (const char *)arg);
        if (stat(p, &st) == 0)
            return 0;
    }
    return 1;
}

static int rerecorded(void *arg)
{
    (void)arg;
    uint64_t n = 0;
    for (int i = 0; i < 3; i++)
        n += st_daemon_stat(&N[i], "cluster_sets_rerecorded");
    return n >= NSETS;
}

/* reads every set through cl for ms milliseconds, every 50 ms; the reads that failed or gave
 * other contents */

static void start_all(void)
{
    for (int i = 0; i < 3; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 2, 2), 0);
    if (st_wait_until(all_see_three, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
}

static void an_etcd_that_lost_its_data_loses_no_set(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/wipe"), 0);
    for (int i = 0; i < 3; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 7, 30, files), 0);
    start_all();
    stc_cluster *cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    for (int s = 0; s < NSETS; s++)
        assert_int_equal(stc_cluster_upload_file(cl, files[s], names[s], NULL, NULL), 0);
    stc_upload_opts rep = {.flags = STC_UPLOAD_REPLACE};
    assert_int_equal(stc_cluster_upload_file(cl, files[5], "charlie", &rep, NULL), 0);
    assert_int_equal(stc_cluster_upload_file(cl, files[6], "gone", NULL, NULL), 0);
    assert_int_equal(stc_cluster_delete(cl, "gone"), 0);
    float want[NSETS];
    for (int s = 0; s < NSETS; s++)
        assert_int_equal(st_cluster_red_at(cl, names[s], &want[s]), 0);
    if (st_wait_until(gone_from_every_data_dir, "gone", DEADLINE_MS) != 0)
        fail_msg("the deleted set stayed in a data dir");
    stc_cluster_close(cl);

    /* etcd loses its data under the running cluster */
    assert_int_equal(st_etcd_restart(&ETCD, 1), 0);
    cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    assert_int_equal(st_cluster_read_all_for(cl, names, NSETS, want, 7000), 0);   /* past 2 lease TTLs and passes */
    if (st_wait_until(rerecorded, NULL, DEADLINE_MS) != 0)
        fail_msg("the sets were never recorded again");
    float red;
    assert_int_equal(st_cluster_red_at(cl, "gone", &red), STC_ENOTFOUND);
    for (int s = 0; s < NSETS; s++) {   /* on R nodes, each with its own copy */
        int held = 0;
        for (int i = 0; i < 3; i++)
            held += st_red_on(&N[i], names[s]) == want[s];
        assert_true(held >= 2);
    }
    /* the catalogue is whole again: a client opened from etcd reads, writes go on */
    char msg[256];
    int err = 0;
    stc_cluster *ce = stc_cluster_open_url(ETCD.url, NULL, &err, msg, sizeof msg);
    assert_non_null(ce);
    for (int s = 0; s < NSETS; s++)
        assert_int_equal(st_cluster_red_at(ce, names[s], &red), 0);
    assert_int_equal(stc_cluster_upload_file(ce, files[6], "gone", NULL, NULL), 0);
    assert_int_equal(stc_cluster_delete(ce, "alpha"), 0);
    assert_int_equal(st_cluster_red_at(ce, "alpha", &red), STC_ENOTFOUND);
    assert_int_equal(stc_cluster_upload_file(ce, files[0], "alpha", NULL, NULL), 0);
    stc_cluster_close(ce);
    stc_cluster_close(cl);

    /* the whole site goes down; etcd comes back empty; the nodes start on it */
    for (int i = 0; i < 3; i++)
        st_daemon_kill(&N[i]);
    assert_int_equal(st_etcd_restart(&ETCD, 1), 0);
    start_all();
    if (st_wait_until(rerecorded, NULL, DEADLINE_MS) != 0)
        fail_msg("the sets were never recorded again after the restart");
    cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    want[0] = -1;   /* alpha: uploaded again, with the same contents */
    assert_int_equal(st_cluster_red_at(cl, "alpha", &want[0]), 0);
    assert_int_equal(st_cluster_read_all_for(cl, names, NSETS, want, 7000), 0);
    assert_int_equal(st_cluster_red_at(cl, "gone", &red), 0);
    stc_cluster_close(cl);
    for (int i = 0; i < 3; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(an_etcd_that_lost_its_data_loses_no_set),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 3; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
