/* tests/integration/test_cluster_stop.c - SIGTERM to cluster nodes whose etcd has stopped
 * answering (SIGSTOP: connections hang, nothing is refused): each node exits 0 within the stop
 * deadline (deploy/seamtexd.service: TimeoutStopSec=20) although its membership and repair
 * threads are inside etcd calls and its graceful leave cannot reach etcd; once etcd answers
 * again the restarted nodes serve the set acknowledged before, with its contents, on both.
 *
 * The nodes' cluster URL lists, after the real etcd, HOLES more endpoints that accept
 * connections and never answer (listening sockets nobody accepts on), as a node cut off from
 * a whole etcd cluster sees it: every etcd call then waits its 2 s deadline on each of the 6
 * endpoints, 12 s, and the membership thread makes two calls a round, so a stop that waited
 * for the calls in progress and then tried a graceful leave took up to 36 s.
 *
 * 2 nodes, R = W = 2, a real etcd (etcd_fixture.h); the waits are deadlines against a hang,
 * never speed checks.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "../common/wire.h"

#define STOP_MS 20000
#define HOLES 5

static st_etcd ETCD;
static st_daemon NODE[2];
static int HOLE_FD[HOLES];
static char URL[640];   /* ETCD.url with the holes added to its endpoints */

/* URL = etcd://127.0.0.1:<etcd>,127.0.0.1:<hole>.../stop */
static void url_with_holes(void)
{
    const char *slash = strchr(ETCD.url + strlen("etcd://"), '/');
    assert_non_null(slash);
    int n = snprintf(URL, sizeof URL, "%.*s", (int)(slash - ETCD.url), ETCD.url);
    for (int i = 0; i < HOLES; i++) {
        int port = 0;
        HOLE_FD[i] = st_wire_listen(64, &port);   /* never accepted on */
        assert_true(HOLE_FD[i] >= 0);
        n += snprintf(URL + n, sizeof URL - (size_t)n, ",127.0.0.1:%d", port);
    }
    snprintf(URL + n, sizeof URL - (size_t)n, "%s", slash);
}

typedef struct kept_read { stc_conn *c; float red; } kept_read;

/* st_wait_until's condition: "kept" read through k->c (its red into k->red) */
static int reads_kept(void *arg)
{
    kept_read *k = arg;
    return st_red_at(k->c, "kept", &k->red) == 0;
}

static void sigterm_with_etcd_unresponsive_exits_and_keeps_acknowledged_sets(void **state)
{
    (void)state;
    assert_int_equal(st_etcd_start(&ETCD, "/stop"), 0);
    url_with_holes();
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&NODE[i]), 0);
    char files[1][300];
    assert_int_equal(st_cluster_tint_files(NODE[0].dir, 1, 70, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&NODE[i], URL, i, 2, 2), 0);
    /* both nodes listed (an upload with W = 2 needs the other as well) */
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_wait_stat(&NODE[i], NULL, "cluster_members", ST_STAT_EQ, 2, 30000), 0);

    stc_conn *c = st_daemon_client(&NODE[0], NULL);
    assert_non_null(c);
    int rc = stc_upload_file(c, files[0], "kept", NULL, NULL);
    if (rc)
        fail_msg("upload: %s (%s)", stc_strerror(rc), stc_errmsg(c));
    float red = 0;
    assert_int_equal(st_red_at(c, "kept", &red), 0);
    stc_close(c);

    /* etcd stops answering; the nodes notice (a keepalive or poll times out) */
    assert_int_equal(st_etcd_pause(&ETCD, 1), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_wait_stat(&NODE[i], NULL, "cluster_etcd_ok", ST_STAT_EQ, 0,
                                      30000), 0);
    for (int i = 0; i < 2; i++) {
        int64_t t0 = st_now_ms();
        int st = st_daemon_stop(&NODE[i], STOP_MS);
        print_message("node %d stopped with etcd unresponsive: %lld ms, exit %d\n", i,
                      (long long)(st_now_ms() - t0), st);
        if (st != 0)
            st_daemon_dump_log(&NODE[i], 20);
        assert_int_equal(st, 0);
    }

    /* etcd back: both nodes restart and serve the acknowledged set */
    assert_int_equal(st_etcd_pause(&ETCD, 0), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&NODE[i], URL, i, 2, 2), 0);
    for (int i = 0; i < 2; i++) {   /* once the catalogue has confirmed the copy */
        kept_read k = {st_daemon_client(&NODE[i], NULL), 0};
        assert_non_null(k.c);
        int64_t t0 = st_now_ms();
        assert_int_equal(st_wait_until(reads_kept, &k, 30000), 0);
        print_message("node %d serves it %lld ms after its restart\n", i,
                      (long long)(st_now_ms() - t0));
        assert_true(k.red == red);
        stc_close(k.c);
    }
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_down(&NODE[i], STOP_MS), 0);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < HOLES; i++)
        close(HOLE_FD[i]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sigterm_with_etcd_unresponsive_exits_and_keeps_acknowledged_sets),
    };
    int rc = cmocka_run_group_tests_name("cluster_stop", tests, NULL, NULL);
    st_etcd_stop(&ETCD);   /* after a failed assertion too */
    return rc;
}
