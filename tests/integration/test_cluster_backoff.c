/* tests/integration/test_cluster_backoff.c - repair backs off from a node that cannot take a
 * copy (docs/cluster.md "Repair and rebalance", backoff; server/cluster_repair.c).
 *
 * 2 nodes, R = 2, W = 1, 2 s leases, a repair pass every second, on a real etcd. Node n1's
 * data dir is a 4 MiB tmpfs (mount(2), as root; else the test is skipped, saying why), filled
 * to the last byte by a file of the test's own. A set uploaded to n0 is acknowledged with n0's
 * copy alone; n0's repair passes then owe n1 a copy and cannot give it ("No space left on
 * device"). Over a 10 s window n0 tries at most log2(10 s / 1 s) + 2 = 5 pushes (before the
 * backoff it tried one per pass: 10 and more), says so once in its log and counts the passes
 * it skipped (STATS cluster_pushes_backed_off). Then the filler goes: n1 gets its copy within
 * the wait the backoff had reached (8 s here) and a margin, and n0 logs once that the push
 * succeeded again.
 */
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex.h"

#define DEADLINE_MS 60000
#define WINDOW_MS 10000
#define MAX_TRIES 5          /* log2(WINDOW_MS / repair interval) + 2 */

static st_etcd ETCD;
static st_daemon N[2];
static int MOUNTED;
static char files[1][300];
static char filler[400];

static void unmount_now(void)
{
    if (MOUNTED) {
        if (umount2(N[1].datadir, MNT_DETACH) != 0)
            fprintf(stderr, "umount %s: %s\n", N[1].datadir, strerror(errno));
        MOUNTED = 0;
    }
}

static int all_see_two(void *arg)
{
    (void)arg;
    return st_cluster_all_see(N, 2, 2);
}

/* fills the file system of path's dir to the last byte; 0 or -1 */
static int fill(const char *path)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (fd < 0)
        return -1;
    static char buf[65536];
    size_t chunk = sizeof buf;
    while (chunk) {
        ssize_t w = write(fd, buf, chunk);
        if (w < 0 && errno == ENOSPC)
            chunk /= 2;
        else if (w < 0)
            break;
    }
    close(fd);
    return chunk ? -1 : 0;
}

static int n1_holds(void *arg)
{
    return st_red_on(&N[1], "full") == *(const float *)arg;
}

static void repair_backs_off_from_a_full_node_and_pushes_once_it_has_room(void **state)
{
    (void)state;
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_init(&N[i]), 0);
    if (mkdir(N[1].datadir, 0700) != 0 && errno != EEXIST)
        fail_msg("mkdir %s: %s", N[1].datadir, strerror(errno));
    if (mount("none", N[1].datadir, "tmpfs", 0, "size=4m,mode=0700") != 0) {
        print_message("cannot mount a tmpfs (%s): needs root or CAP_SYS_ADMIN\n",
                      strerror(errno));
        skip();
    }
    MOUNTED = 1;
    assert_int_equal(st_etcd_start(&ETCD, "/backoff"), 0);
    assert_int_equal(st_cluster_tint_files(N[0].dir, 1, 40, files), 0);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_cluster_node_start(&N[i], ETCD.url, i, 2, 1), 0);
    if (st_wait_until(all_see_two, NULL, DEADLINE_MS) != 0)
        fail_msg("the nodes never saw each other");
    snprintf(filler, sizeof filler, "%s/filler", N[1].datadir);
    assert_int_equal(fill(filler), 0);

    /* acknowledged with n0's copy (W = 1); n1 owes one and has no room */
    stc_conn *c = st_daemon_client(&N[0], NULL);
    assert_non_null(c);
    assert_int_equal(stc_upload_file(c, files[0], "full", NULL, NULL), 0);
    float want = -1;
    assert_int_equal(st_red_at(c, "full", &want), 0);
    stc_close(c);
    uint64_t f0 = st_daemon_stat(&N[0], "cluster_push_failures");
    uint64_t p0 = st_daemon_stat(&N[0], "cluster_repair_passes");
    st_sleep_ms(WINDOW_MS);   /* the thing under test: what repair does over the window */
    uint64_t tries = st_daemon_stat(&N[0], "cluster_push_failures") - f0;
    uint64_t passes = st_daemon_stat(&N[0], "cluster_repair_passes") - p0;
    uint64_t skipped = st_daemon_stat(&N[0], "cluster_pushes_backed_off");
    int said = st_daemon_log_count(&N[0], "backs off");
    print_message("%d ms: %llu repair passes, %llu failed pushes to the full node, %llu "
                  "skipped; 'backs off' logged %d time(s)\n", WINDOW_MS,
                  (unsigned long long)passes, (unsigned long long)tries,
                  (unsigned long long)skipped, said);
    assert_true(st_red_on(&N[1], "full") != want);   /* still full: no copy */
    assert_true(tries >= 1);
    assert_true(tries <= MAX_TRIES);
    assert_true(skipped >= 1);
    assert_int_equal(said, 1);

    /* room again: the copy arrives within the wait reached (8 s) and a margin */
    assert_int_equal(unlink(filler), 0);
    int64_t t = st_now_ms();
    if (st_wait_until(n1_holds, &want, 8000 + 7000) != 0)
        fail_msg("n1 did not get its copy within 15 s of having room");
    print_message("n1 holds its copy %lld ms after the filler went\n",
                  (long long)(st_now_ms() - t));
    if (st_wait_file_has(N[0].log, "backoff ended", 5000) != 0)
        fail_msg("n0 did not log that the push succeeded again");
    assert_int_equal(st_daemon_log_count(&N[0], "backoff ended"), 1);
    assert_int_equal(st_daemon_log_count(&N[0], "backs off"), 1);
    for (int i = 0; i < 2; i++)
        assert_int_equal(st_daemon_stop(&N[i], 10000), 0);   /* cleaned up after the unmount */
    st_etcd_stop(&ETCD);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(repair_backs_off_from_a_full_node_and_pushes_once_it_has_room),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&ETCD);
    for (int i = 0; i < 2; i++)
        if (N[i].pid)
            st_daemon_kill(&N[i]);
    unmount_now();
    for (int i = 0; i < 2; i++)
        st_daemon_cleanup(&N[i]);
    return rc;
}
