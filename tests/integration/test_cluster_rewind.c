/* tests/integration/test_cluster_rewind.c - an etcd restored from an older backup loses no
 * set uploaded after the backup (docs/cluster.md "Catalogue lost", server/cluster_mark.c,
 * the revision watch of cluster/etcd.h).
 *
 * 3 nodes, R = W = 2, 2 s leases, on a real etcd. Three sets are uploaded, then etcd's data
 * dir is saved (a backup: etcd stopped, its dir copied, started again), then five more sets
 * are uploaded and another client of the same etcd writes 300 keys of its own (a backup is
 * older than many writes: its revision well below the nodes'). etcd is then restored from the backup under the running cluster: the same
 * mark, a lower revision, a catalogue without the five sets. For 3 lease TTLs and more every
 * set is read through the cluster client every 50 ms, always with its contents; each node
 * counts the going back once (STATS cluster_etcd_went_back), the five sets are recorded again (a
 * client opened on the etcd URL reads them), and each is on R nodes. Then the whole site goes
 * down (once each data dir's cluster-id keeps etcd's latest revision: another 300 writes,
 * then 10 passes at most), etcd is restored from the same backup again, and the nodes start
 * on it: the revision kept in each data dir catches it on each node, and every set reads
 * again.
 * Before the revision watch the nodes trusted the restored catalogue (its mark is theirs) and
 * dropped the five sets as deleted two lease TTLs later: acknowledged uploads lost.
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
#include "etcd.h"
#include "seamtex_cluster.h"
#include "seamtex_etcd.h"

#define DEADLINE_MS 60000
#define NOLD 3
#define NSETS 8

static st_etcd ETCD;
static st_daemon N[3];
static char files[NSETS][300];
static const char *names[NSETS] = {"old0", "old1", "old2",
                                   "new0", "new1", "new2", "new3", "new4"};

static int all_see_three(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 3, 3);
}

static uint64_t sum_stat(const char *key)
{
    uint64_t n = 0;
    for (int i = 0; i < 3; i++)
        n += st_daemon_stat(&N[i], key);
    return n;
}

/* the five new sets recorded again, by whichever nodes got there first */
static int rerecorded(void *arg)
{
    return sum_stat("cluster_sets_rerecorded") >= *(uint64_t *)arg + (NSETS - NOLD);
}

/* every set on 2 nodes (read from each node alone) */
static int replicated(void *arg)
{
    const float *want = arg;
    for (int s = 0; s < NSETS; s++) {
        int held = 0;
        for (int i = 0; i < 3; i++)
            held += st_red_on(&N[i], names[s]) == want[s];
        if (held < 2)
            return 0;
    }
    return 1;
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

/* 1 when every node counts n goings back of etcd */
static int each_went_back(void *arg)
{
    for (int i = 0; i < 3; i++)
        if (st_daemon_stat(&N[i], "cluster_etcd_went_back") != *(uint64_t *)arg)
            return 0;
    return 1;
}

/* another client of the same etcd writes k keys under a prefix of its own; returns etcd's
 * revision after them */
static int64_t other_writes(int k)
{
    char err[256], key[64];
    scl_etcd *e = scl_etcd_open(ETCD.url, 2000, err, sizeof err);
    assert_non_null(e);
    for (int i = 0; i < k; i++) {
        snprintf(key, sizeof key, "/another-app/k%d", i % 10);
        assert_int_equal(scl_etcd_put(e, key, "x", 0), SCL_OK);
    }
    scl_kvs kv;
    assert_int_equal(scl_etcd_range(e, "/another-app/k0", 0, &kv), SCL_OK);
    int64_t rev = kv.revision;
    scl_kvs_free(&kv);
    scl_etcd_close(e);
    return rev;
}

/* the revision node i's data dir keeps (the second line of cluster-id, "rev N"), 0 none */
static int64_t kept_rev(int i)
{
    char p[512], line[512];
    snprintf(p, sizeof p, "%s/cluster-id", N[i].datadir);
    FILE *f = fopen(p, "r");
    long long rev = 0;
    if (f) {
        if (fgets(line, sizeof line, f) && fgets(line, sizeof line, f) &&
            sscanf(line, "rev %lld", &rev) != 1)
            rev = 0;
        fclose(f);
    }
    return rev;
}

/* 1 when every data dir keeps revision *arg or later */
static int each_kept(void *arg)
{
    for (int i = 0; i < 3; i++)
        if (kept_rev(i) < *(int64_t *)arg)
            return 0;
    return 1;
}

/* every set read through a client opened on the etcd URL: the catalogue records them all */
static void catalogue_whole(const float *want)
{
    char msg[256];
    int err = 0;
    stc_cluster *ce = stc_cluster_open_url(ETCD.url, NULL, &err, msg, sizeof msg);
    assert_non_null(ce);
    for (int s = 0; s < NSETS; s++) {
        float red = -1;
        assert_int_equal(st_cluster_red_at(ce, names[s], &red), 0);
        assert_true(red == want[s]);
    }
    stc_cluster_close(ce);
}

static void an_etcd_restored_from_an_old_backup_loses_no_set(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/rewind"), 0);
    for (int i = 0; i < 3; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, NSETS, 25, files), 0);
    start_all();
    stc_cluster *cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    for (int s = 0; s < NOLD; s++)
        assert_int_equal(stc_cluster_upload_file(cl, files[s], names[s], NULL, NULL), 0);
    st_sleep_ms(1500);   /* a repair pass has confirmed them */

    /* the backup */
    assert_int_equal(st_etcd_save(&ETCD), 0);
    if (st_wait_until(all_see_three, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never came back after the backup");
    for (int s = NOLD; s < NSETS; s++)
        assert_int_equal(stc_cluster_upload_file(cl, files[s], names[s], NULL, NULL), 0);
    other_writes(300);
    float want[NSETS];
    for (int s = 0; s < NSETS; s++)
        assert_int_equal(st_cluster_red_at(cl, names[s], &want[s]), 0);
    st_sleep_ms(2500);   /* repair passes on the full catalogue */
    stc_cluster_close(cl);

    /* etcd restored from the backup under the running cluster */
    uint64_t rer0 = sum_stat("cluster_sets_rerecorded");
    assert_int_equal(sum_stat("cluster_etcd_went_back"), 0);
    assert_int_equal(st_etcd_restore(&ETCD), 0);
    cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    assert_int_equal(st_cluster_read_all_for(cl, names, NSETS, want, 7000), 0);   /* past 2 lease TTLs and passes */
    if (st_wait_until(rerecorded, &rer0, DEADLINE_MS) != 0)
        fail_msg("the sets uploaded after the backup were never recorded again");
    uint64_t one = 1;
    if (st_wait_until(each_went_back, &one, DEADLINE_MS) != 0)
        fail_msg("a node did not see etcd go back");
    if (st_wait_until(replicated, want, DEADLINE_MS) != 0)
        fail_msg("a set stayed on fewer than 2 nodes");
    catalogue_whole(want);
    assert_int_equal(st_cluster_read_all_for(cl, names, NSETS, want, 3000), 0);
    stc_cluster_close(cl);

    /* the whole site down; etcd restored from the same backup; the nodes start on it */
    /* the revision keeps moving (another client's writes): the nodes keep it in their data
     * dirs every 10th pass (1 s apart here) */
    int64_t now_rev = other_writes(300);
    if (st_wait_until(each_kept, &now_rev, DEADLINE_MS) != 0)
        fail_msg("a data dir never kept etcd's latest revision");
    for (int i = 0; i < 3; i++)
        st_daemon_kill(&N[i]);
    rer0 = 0;   /* new processes: their counters start at 0 */
    assert_int_equal(st_etcd_restore(&ETCD), 0);
    start_all();
    if (st_wait_until(rerecorded, &rer0, DEADLINE_MS) != 0)
        fail_msg("the sets were never recorded again after the restart");
    if (st_wait_until(each_went_back, &one, DEADLINE_MS) != 0)
        fail_msg("a restarted node did not see etcd go back");
    /* (a node answers NOT_FOUND for what it does not hold until its first ordinary pass,
     * run once its sets are recorded again: a cold start, as after a wipe) */
    if (st_wait_until(replicated, want, DEADLINE_MS) != 0)
        fail_msg("a set stayed on fewer than 2 nodes after the restart");
    cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    assert_int_equal(st_cluster_read_all_for(cl, names, NSETS, want, 7000), 0);
    catalogue_whole(want);
    stc_cluster_close(cl);
    for (int i = 0; i < 3; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(an_etcd_restored_from_an_old_backup_loses_no_set),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 3; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
