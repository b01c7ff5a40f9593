/* tests/integration/test_cluster_refused.c - an upload the cluster refused (UNAVAILABLE: the
 * write quorum was not reached) does not take effect, also not on the node that took it
 * (PROTOCOL.md 4.11, docs/cluster.md "Reads and MOVED"): that node published its copy before
 * the pushes, and used to serve it to reads until its next repair pass began (an outside
 * probe, 2026-12-05, read refused contents up to 2.3 s after the refusal, 4.2 s when etcd
 * went away meanwhile; a refused REPLACE left its set unreadable on that node).
 *
 * 2 nodes, R = W = 2, 2 s leases, a repair pass every second, on a real etcd. "keep" is
 * uploaded (acknowledged), n1 is killed, and while n0 still counts it a member (its lease
 * runs) n0 is sent a REPLACE of "keep" and an upload of the new name "never": each refused
 * UNAVAILABLE (the push to n1 fails). Reads on n0 right after each refusal must never return
 * the refused contents: "keep" reads with its acknowledged contents or not at all (MOVED,
 * NOT_FOUND), "never" is not found. Fails without sts_cluster_refuse_copy.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"

#define DEADLINE_MS 60000

static st_etcd ETCD;
static st_daemon N[2];
static char files[2][300];
static float red[2];

static int both_see(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

static void a_refused_upload_is_not_read_on_the_node_that_took_it(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/refused"), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 2, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 2, 0), 0);
    if (st_wait_until(both_see, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = st_cluster_open_nodes(N, 2);
    assert_non_null(cl);
    assert_int_equal(st_cluster_tint_reds(cl, 2, files, red), 0);
    assert_true(red[0] != red[1]);
    assert_int_equal(stc_cluster_upload_file(cl, files[0], "keep", NULL, NULL), 0);
    stc_cluster_close(cl);

    st_daemon_kill(&N[1]);   /* n0 counts n1 a member until its lease ends (2 s) */
    int refused = 0, served_refused = 0, keep_ok = 0;
    int64_t t0 = st_now_ms();
    while (st_now_ms() - t0 < 1500) {
        stc_conn *c0 = st_daemon_client(&N[0], NULL);
        assert_non_null(c0);
        stc_upload_opts uo = {.flags = STC_UPLOAD_REPLACE};
        int a = stc_upload_file(c0, files[1], "keep", &uo, NULL);
        int b = stc_upload_file(c0, files[1], "never", NULL, NULL);
        if (a != STC_EUNAVAILABLE || b != STC_EUNAVAILABLE) {   /* n0 dropped n1 by now */
            stc_close(c0);
            break;
        }
        refused += 2;
        for (int k = 0; k < 20; k++) {   /* at once, on the node that took them */
            float r = -1;
            if (st_red_at(c0, "keep", &r) == 0) {
                served_refused += r == red[1];
                keep_ok += r == red[0];
            }
            served_refused += st_red_at(c0, "never", &r) == 0;
        }
        stc_close(c0);
    }
    print_message("%d uploads refused, %d reads of the acknowledged contents\n", refused,
                  keep_ok);
    if (refused < 2)
        fail_msg("no upload was refused while n1's lease ran");
    if (served_refused)
        fail_msg("n0 served the refused contents %d times", served_refused);
    for (int i = 0; i < 2; i++)
        st_daemon_down(&N[i], 10000);
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_refused_upload_is_not_read_on_the_node_that_took_it),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
