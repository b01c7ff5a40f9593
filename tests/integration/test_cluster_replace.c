/* tests/integration/test_cluster_replace.c - a REPLACE the cluster refuses loses no copy of
 * the acknowledged contents (docs/cluster.md "Writes": staged copies).
 *
 * Found by an outside probe (cl27, defect 7): the node that took a REPLACE overwrote its copy
 * (data dir and registry) before the write quorum was known; when the quorum then failed, the
 * acknowledged set had one copy fewer - none at all when the other owner was the node whose
 * failure made the quorum fail: the set read NOT_FOUND from the live node until the other
 * came back, and would have been gone with the other node's disk. Now the new contents are
 * staged (<data-dir>/staged/) and published only once the write is recorded.
 *
 * 2 nodes, R = W = 2, 5 s leases (n1 stays a member while n0 takes the REPLACE), a repair
 * pass every second, on a real etcd. "x" is uploaded (A, acknowledged), n1 is killed, a
 * REPLACE of x with B through n0 is refused UNAVAILABLE (the push to n1 fails). Then n0 must
 * read A at once and through the end of n1's lease and the repair passes after it (n0 the
 * only owner: it used to drop its copy, B, as stale), hold no staged copy, and after both
 * nodes are killed and restarted (etcd keeps the catalogue) both read A.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "datadir.h"
#include "stp_cluster.h"

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/testdata.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"

#define DEADLINE_MS 60000
#define LEASE "5"    /* s: n1 a member while n0 takes the REPLACE, on a slow machine too */

static st_etcd ETCD;
static st_daemon N[3];
static char files[2][300];
static float red[2];

/* node i of the cluster, R = W = 2, with LEASE (cluster_fixture.h's nodes have 2 s), a repair
 * pass every `every` seconds */
static int start_node_every(int i, const char *every)
{
    static const char *const ids[] = {"n0", "n1", "n2"};
    const char *id = ids[i];
    const char *args[] = {"--cluster", ETCD.url, "--node-id", id, "--advertise", "127.0.0.1:0",
                          "--replicas", "2", "--write-quorum", "2", "--lease-ttl", LEASE,
                          "--repair-interval", every, "--no-default-set", NULL};
    return st_daemon_start(&N[i], args);
}

static int start_node(int i)
{
    return start_node_every(i, "1");
}

static int both_members(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

static int n0_alone(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 1, 1);
}

static int n1_alone(void *arg)
{
    (void)arg;
    return st_cluster_all_see(&N[1], 1, 1);
}

/* the red value node i reads for x: 0 and *r, or the read's status */
static int red_on(int i, float *r)
{
    stc_conn *c = st_daemon_client(&N[i], NULL);
    int rc = c ? st_red_at(c, "x", r) : -1;
    stc_close(c);
    return rc;
}

/* both nodes read x (whatever its contents) */
static int both_read(void *arg)
{
    (void)arg;
    float r;
    return red_on(0, &r) == 0 && red_on(1, &r) == 0;
}

/* both nodes read x with the first contents */
static int both_serve_first(void *arg)
{
    (void)arg;
    float r0 = -1, r1 = -1;
    return red_on(0, &r0) == 0 && r0 == red[0] && red_on(1, &r1) == 0 && r1 == red[0];
}

/* entries in <data-dir of node i>/staged */
static int staged_count(int i)
{
    char p[400];
    snprintf(p, sizeof p, "%s/staged", N[i].datadir);
    return st_test_dir_entries(p);
}

static uint64_t passes_before;
static int two_more_passes(void *arg)
{
    (void)arg;
    return st_daemon_stat(&N[0], "cluster_repair_passes") >= passes_before + 2;
}

/* etcd under prefix, both nodes (fresh data dirs) members of it, the tints' reds known, x
 * uploaded with the first tint (and src with the second) and read on both nodes */
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
    assert_true(red[0] != red[1]);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "x", NULL, NULL), 0);
    assert_int_equal(stc_cluster_upload_file(cl, files[1], "src", NULL, NULL), 0);
    stc_cluster_close(cl);
    if (st_wait_until(both_serve_first, NULL, DEADLINE_MS) != 0)
        fail_msg("the first contents are not on both nodes");
}

static void a_refused_replace_keeps_the_acknowledged_copy(void **state)
{
    (void)state;
    start_pair("/replace");

    /* the other owner dies; n0 counts it a member until its lease ends */
    uint64_t staged0 = st_daemon_stat(&N[0], "cluster_copies_staged");
    uint64_t published0 = st_daemon_stat(&N[0], "cluster_staged_published");
    uint64_t dropped0 = st_daemon_stat(&N[0], "cluster_staged_dropped");
    st_daemon_kill(&N[1]);
    stc_conn *c0 = st_daemon_client(&N[0], NULL);
    assert_non_null(c0);
    stc_upload_opts uo = {.flags = STC_UPLOAD_REPLACE};
    int rc = stc_upload_file(c0, files[1], "x", &uo, NULL);
    stc_close(c0);
    if (rc != STC_EUNAVAILABLE)
        fail_msg("the REPLACE was answered %d, not UNAVAILABLE (did n1's lease run out?)", rc);

    /* at once, on the node that took it: the acknowledged contents */
    float r = -1;
    rc = red_on(0, &r);
    if (rc != 0 || r != red[0]) {
        st_daemon_dump_log(&N[0], 20);
        fail_msg("right after the refusal n0 reads x as %d (red %g; acknowledged %g, refused %g)",
                 rc, r, red[0], red[1]);
    }

    /* n1 leaves (its lease ends) and n0's repair passes judge x with n0 the only owner: it
     * keeps reading A all along */
    int reads = 0, wrong = 0, missing = 0;
    int64_t t0 = st_now_ms();
    while (!n0_alone(NULL) && st_now_ms() - t0 < DEADLINE_MS) {
        wrong += red_on(0, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    if (!n0_alone(NULL))
        fail_msg("n0 never saw n1 leave");
    passes_before = st_daemon_stat(&N[0], "cluster_repair_passes");
    while (!two_more_passes(NULL) && st_now_ms() - t0 < DEADLINE_MS) {
        wrong += red_on(0, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    /* a stale copy is dropped once published 2 s before a pass: past that too */
    int64_t t1 = st_now_ms();
    while (st_now_ms() - t1 < 2500) {
        wrong += red_on(0, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    print_message("%d reads on n0 after the refusal: %d missing, %d other contents\n", reads,
                  missing, wrong);
    if (missing || wrong) {
        st_daemon_dump_log(&N[0], 30);
        fail_msg("n0 lost the acknowledged contents: %d of %d reads missing, %d other contents",
                 missing, reads, wrong);
    }
    /* the refused copy was staged, never published, and dropped */
    assert_int_equal(st_daemon_stat(&N[0], "cluster_copies_staged"), staged0 + 1);
    assert_int_equal(st_daemon_stat(&N[0], "cluster_staged_published"), published0);
    assert_int_equal(st_daemon_stat(&N[0], "cluster_staged_dropped"), dropped0 + 1);
    assert_int_equal(staged_count(0), 0);

    /* everything restarted (etcd keeps the catalogue): A on both */
    st_daemon_kill(&N[0]);
    for (int i = 0; i < 2; i++)
        assert_int_equal(start_node(i), 0);
    if (st_wait_until(both_members, NULL, DEADLINE_MS) != 0)
        fail_msg("the restarted nodes never saw each other");
    if (st_wait_until(both_read, NULL, DEADLINE_MS) != 0) {
        st_daemon_dump_log(&N[0], 30);
        fail_msg("x is not read on both nodes after the restart");
    }
    for (int i = 0; i < 2; i++) {
        r = -1;
        assert_int_equal(red_on(i, &r), 0);
        if (r != red[0])
            fail_msg("n%d reads x as %g after the restart, not the acknowledged %g", i, r,
                     red[0]);
        assert_int_equal(staged_count(i), 0);
    }
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

/* The same through a COMPRESS job with the replace flag: its result for x is a write as an
 * upload is (it used to be published over n0's copy of x before the quorum was known, and
 * x then read NOT_FOUND on n0); a result for a new name is not published either. */
static void a_refused_compress_keeps_the_target(void **state)
{
    (void)state;
    start_pair("/replace-compress");
    uint64_t dropped0 = st_daemon_stat(&N[0], "cluster_staged_dropped");
    st_daemon_kill(&N[1]);
    stc_conn *c0 = st_daemon_client(&N[0], NULL);
    assert_non_null(c0);
    const char *targets[2] = {"x", "y"};
    for (int t = 0; t < 2; t++) {
        uint64_t job = 0;
        stc_job jr;
        assert_int_equal(stc_compress(c0, "src", targets[t], 1, STC_COMPRESS_REPLACE, &job), 0);
        int rc = stc_job_wait(c0, job, DEADLINE_MS, &jr);
        if (rc != STC_EUNAVAILABLE)
            fail_msg("COMPRESS into %s ended %d (%s), not UNAVAILABLE", targets[t], rc,
                     jr.message);
    }
    float r = -1;
    int rc = st_red_at(c0, "x", &r);
    if (rc != 0 || r != red[0]) {
        st_daemon_dump_log(&N[0], 20);
        fail_msg("after the refused COMPRESS n0 reads x as %d (red %g; acknowledged %g)", rc, r,
                 red[0]);
    }
    if (st_red_at(c0, "y", &r) == 0)
        fail_msg("n0 serves the refused COMPRESS result y");
    stc_close(c0);
    assert_int_equal(st_daemon_stat(&N[0], "cluster_staged_dropped"), dropped0 + 2);
    assert_int_equal(staged_count(0), 0);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

/* both nodes down, the catalogue recording the second contents: n0 reads x with them */
static int n0_serves_second(void *arg)
{
    (void)arg;
    float r = -1;
    return red_on(0, &r) == 0 && r == red[1];
}

static int n0_published_one(void *arg)
{
    (void)arg;
    return st_daemon_stat(&N[0], "cluster_staged_published") == 1 && staged_count(0) == 0;
}

/* The crash window between the finalize and the publish: a node killed there restarts with
 * the recorded contents staged and its old copy in sets/. Its repair pass publishes the staged
 * copy - without that it would drop its old copy as stale and hold nothing, and with the other
 * holder gone the recorded contents would be lost. Made by hand: n0 killed, B staged in its
 * data dir through the store's own API, B recorded through n1 alone (after n0's lease ran
 * out), n1 killed, n0 restarted alone. */
static void recorded_contents_staged_at_a_crash_are_published_at_restart(void **state)
{
    (void)state;
    start_pair("/replace-restart");
    st_daemon_kill(&N[0]);
    st_datadir *d = NULL;
    st_error e;
    assert_int_equal(st_datadir_open(N[0].datadir, &d, &e), 0);
    char tmp[4096], sid[64];
    int fd = -1;
    assert_int_equal(st_datadir_tmpfile(d, tmp, sizeof tmp, &fd, &e), 0);
    FILE *in = fopen(files[1], "rb");
    assert_non_null(in);
    char buf[65536];
    size_t k, total = 0;
    while ((k = fread(buf, 1, sizeof buf, in)) > 0) {
        assert_int_equal(write(fd, buf, k), (ssize_t)k);
        total += k;
    }
    fclose(in);
    close(fd);
    assert_int_equal(st_datadir_stage(d, "x", tmp, "ptx", "", total, sid, sizeof sid, &e), 0);
    st_datadir_close(d);

    if (st_wait_until(n1_alone, NULL, DEADLINE_MS) != 0)
        fail_msg("n1 never saw n0 leave");
    stc_conn *c1 = st_daemon_client(&N[1], NULL);
    assert_non_null(c1);
    stc_upload_opts uo = {.flags = STC_UPLOAD_REPLACE};
    assert_int_equal(stc_upload_file(c1, files[1], "x", &uo, NULL), 0);
    stc_close(c1);
    st_daemon_kill(&N[1]);

    assert_int_equal(start_node(0), 0);
    if (st_wait_until(n0_serves_second, NULL, DEADLINE_MS) != 0) {
        st_daemon_dump_log(&N[0], 30);
        fail_msg("restarted alone, n0 does not serve the recorded contents");
    }
    /* the publish counts once its staged copy is removed, a moment after the registry has
     * the set */
    if (st_wait_until(n0_published_one, NULL, DEADLINE_MS) != 0)
        fail_msg("n0 published %llu staged copies, %d left staged",
                 (unsigned long long)st_daemon_stat(&N[0], "cluster_staged_published"),
                 staged_count(0));
    st_daemon_down(&N[0], 10000);
    st_etcd_stop(&ETCD);
}

static char owned[16];   /* a set name whose two owners of {n0, n1, n2} are n1 and n2 */

static int three_members(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 3, 3);
}

/* the red value node i reads for set name: 0 and *r, or the read's status */
static int red_of(int i, const char *name, float *r)
{
    stc_conn *c = st_daemon_client(&N[i], NULL);
    int rc = c ? st_red_at(c, name, r) : -1;
    stc_close(c);
    return rc;
}

static int n1_alone_of_two(void *arg)
{
    (void)arg;
    return st_cluster_all_see(&N[1], 1, 2);
}

/* cl27's defect 2 and the rest of 7: a push of a write that then ends refused reached an owner
 * - a taker that is not an owner pushes to both owners, one of them is dead. The receiver used
 * to publish the push at once: it served the refused contents until its next pass, and had
 * replaced its copy of the acknowledged ones (with the other owner gone: none left). Now it
 * stages the push, publishes it on the writer's REPLICA_PUBLISH once the write is recorded -
 * an acknowledged write reads on both owners right after its OK - and drops it otherwise. */
/* etcd under prefix, 3 nodes (fresh data dirs; n0's repair pass every n0_every seconds)
 * members of it, owned[] a name n1 and n2 own, the tints' reds known */
static void start_three(const char *prefix, const char *n0_every)
{
    assert_int_equal(st_etcd_start(&ETCD, prefix), 0);
    for (int i = 0; i < 3; i++) {
        st_daemon_cleanup(&N[i]);
        assert_int_equal(st_daemon_init(&N[i]), 0);
    }
    assert_int_equal(st_cluster_tint_files(N[0].dir, 2, 40, files), 0);
    for (int i = 0; i < 3; i++)
        assert_int_equal(start_node_every(i, i ? "1" : n0_every), 0);
    if (st_wait_until(three_members, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    const char *ids[3] = {"n0", "n1", "n2"};
    owned[0] = 0;
    for (int k = 0; k < 200 && !owned[0]; k++) {
        char name[16];
        size_t own[2];
        snprintf(name, sizeof name, "r%d", k);
        stp_hrw_rank(ids, 3, name, own, 2);
        if (own[0] != 0 && own[1] != 0)
            snprintf(owned, sizeof owned, "%s", name);
    }
    assert_true(owned[0] != 0);
    stc_cluster *cl = st_cluster_open_nodes(N, 3);
    assert_non_null(cl);
    assert_int_equal(st_cluster_tint_reds(cl, 2, files, red), 0);
    stc_cluster_close(cl);
}

/* uploads tint `file` as owned[] through node i (a REPLACE when replace is set); the status */
static int upload_through(int i, int file, int replace)
{
    stc_conn *c = st_daemon_client(&N[i], NULL);
    assert_non_null(c);
    stc_upload_opts uo = {.flags = replace ? STC_UPLOAD_REPLACE : 0};
    int rc = stc_upload_file(c, files[file], owned, &uo, NULL);
    stc_close(c);
    return rc;
}

static void a_refused_write_pushed_to_an_owner_is_not_published_there(void **state)
{
    (void)state;
    start_three("/replace-pushed", "1");

    /* an acknowledged write through n0 (not an owner): both owners read it at once */
    assert_int_equal(upload_through(0, 0, 0), 0);
    for (int i = 1; i < 3; i++) {
        float r = -1;
        int rc = red_of(i, owned, &r);
        if (rc != 0 || r != red[0])
            fail_msg("right after the OK n%d reads %s as %d (red %g), not the written %g", i,
                     owned, rc, r, red[0]);
    }
    uint64_t staged1 = st_daemon_stat(&N[1], "cluster_copies_staged");

    /* n2 dies; the REPLACE through n0 reaches n1 only and is refused */
    st_daemon_kill(&N[2]);
    int rc = upload_through(0, 1, 1);
    if (rc != STC_EUNAVAILABLE)
        fail_msg("the REPLACE was answered %d, not UNAVAILABLE (did n2's lease run out?)", rc);

    /* n1 reads A at once, while n2's lease runs, and after it ended (n1 and n0 the owners:
     * n1's copy is the only one of A left) */
    int reads = 0, wrong = 0, missing = 0;
    float r = -1;
    int64_t t0 = st_now_ms();
    while (!n1_alone_of_two(NULL) && st_now_ms() - t0 < DEADLINE_MS) {
        wrong += red_of(1, owned, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    passes_before = st_daemon_stat(&N[1], "cluster_repair_passes");
    while (st_daemon_stat(&N[1], "cluster_repair_passes") < passes_before + 2 &&
           st_now_ms() - t0 < DEADLINE_MS) {
        wrong += red_of(1, owned, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    int64_t t1 = st_now_ms();
    while (st_now_ms() - t1 < 2500) {
        wrong += red_of(1, owned, &r) == 0 ? r != red[0] : (missing++, 0);
        reads++;
        st_sleep_ms(20);
    }
    print_message("%d reads of %s on n1 after the refusal: %d missing, %d other contents\n",
                  reads, owned, missing, wrong);
    if (missing || wrong) {
        st_daemon_dump_log(&N[1], 30);
        fail_msg("n1 lost the acknowledged contents: %d of %d reads missing, %d other contents",
                 missing, reads, wrong);
    }
    /* the refused copy was staged on n1, never published there, and dropped by its pass */
    assert_int_equal(st_daemon_stat(&N[1], "cluster_copies_staged"), staged1 + 1);
    assert_int_equal(staged_count(1), 0);
    assert_true(st_daemon_stat(&N[1], "cluster_staged_dropped") >= 1);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

/* cl27's defect 5: a node that holds a copy but is not an owner in the writer's view gets no
 * push of a REPLACE, and served the replaced contents until its next repair pass. Here n0 (not
 * an owner of the name, its repair pass every 60 s) took the first upload and keeps its copy,
 * served; a REPLACE through n1 is recorded: right after its OK, n0 must not read the old
 * contents (the writer tells it with REPLICA_PUBLISH, and n0 hides its stale copy), while the
 * owners read the new ones. */
static void a_replace_hides_the_old_copy_of_a_holder_that_is_not_an_owner(void **state)
{
    (void)state;
    start_three("/replace-stale", "60");
    assert_int_equal(upload_through(0, 0, 0), 0);
    float r = -1;
    assert_int_equal(red_of(0, owned, &r), 0);   /* n0's own copy, published and served */
    assert_true(r == red[0]);
    uint64_t hidden0 = st_daemon_stat(&N[0], "cluster_copies_hidden");

    assert_int_equal(upload_through(1, 1, 1), 0);
    float r0 = -1;
    int rc0 = red_of(0, owned, &r0);
    if (rc0 == 0 && r0 == red[0]) {
        st_daemon_dump_log(&N[0], 20);
        fail_msg("right after the REPLACE's OK n0 reads %s with the replaced contents", owned);
    }
    assert_int_equal(st_daemon_stat(&N[0], "cluster_copies_hidden"), hidden0 + 1);
    /* and the writer's log says n0 was told (n0's NOT_FOUND is that answer, not a failure) */
    char told[200];
    snprintf(told, sizeof told, "n0 told that '%s' was replaced", owned);
    if (st_daemon_log_count(&N[1], told) != 1) {
        st_daemon_dump_log(&N[1], 20);
        fail_msg("n1's log should say \"%s\" once", told);
    }
    for (int i = 1; i < 3; i++) {
        r = -1;
        if (red_of(i, owned, &r) != 0 || r != red[1])
            fail_msg("right after the REPLACE's OK owner n%d reads %g, not %g", i, r, red[1]);
    }
    for (int i = 0; i < 3; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_refused_replace_keeps_the_acknowledged_copy),
        cmocka_unit_test(a_refused_compress_keeps_the_target),
        cmocka_unit_test(recorded_contents_staged_at_a_crash_are_published_at_restart),
        cmocka_unit_test(a_refused_write_pushed_to_an_owner_is_not_published_there),
        cmocka_unit_test(a_replace_hides_the_old_copy_of_a_holder_that_is_not_an_owner),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 3; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
