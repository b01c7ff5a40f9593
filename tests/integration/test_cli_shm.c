/* tests/integration/test_cli_shm.c - `seamtex sample --queries FILE` on a unix: host through a
 * shared-memory region (--shm auto|on|off; PROTOCOL.md 4.12): the binary and text outputs are
 * byte for byte those of the socket; the daemon's STATS show the region attached and the
 * requests served through it only when asked (auto, on) and not with off; a file larger than
 * one call (65536 queries) reuses the region; a daemon that refuses (over --shm-max) gets the
 * socket under auto and exit 1 under on; a TCP daemon exit 2 under on; a bad value exit 2.
 * Each test starts its own daemon (unix_daemon.h; daemon_fixture.h for TCP).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/unix_daemon.h"

static int sh(const char *cmd)
{
    int rc = system(cmd);
    return rc == -1 ? -1 : WEXITSTATUS(rc);
}

/* n random queries (some on faces past the default set's 384: per-query statuses) into
 * dir/q.txt. */
static void write_queries(const char *dir, unsigned n)
{
    char p[400];
    snprintf(p, sizeof p, "%.300s/q.txt", dir);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    uint32_t s = 12345;
    for (unsigned i = 0; i < n; i++) {
        s = s * 1664525u + 1013904223u;
        unsigned face = (s >> 8) % 400;
        s = s * 1664525u + 1013904223u;
        float u = (float)(s >> 8) / 16777216.0f;
        s = s * 1664525u + 1013904223u;
        float v = (float)(s >> 8) / 16777216.0f;
        fprintf(f, "%u %.7g %.7g 0.01 0 0 0.02\n", face, u, v);
    }
    assert_int_equal(fclose(f), 0);
}

/* seamtex -h HOST sample default --queries q.txt ARGS > dir/OUT; the exit status. */
static int cli(const char *dir, const char *host, const char *args, const char *out)
{
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s/seamtex -h %s sample default --queries %s/q.txt "
             "--mode traverse --filter trilinear %s > %s/%s 2> %s/%s.err", st_build_dir(), host,
             dir, args, dir, out, dir, out);
    return sh(cmd);
}

static int same_files(const char *dir, const char *a, const char *b)
{
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "cmp -s %s/%s %s/%s", dir, a, dir, b);
    return sh(cmd) == 0;
}

static uint64_t stat_of(const st_unix_daemon *u, const char *key)
{
    int err = 0;
    stc_conn *c = stc_connect(u->addr, 0, 10000, &err);
    assert_non_null(c);
    uint64_t v = st_conn_stat(c, key);
    stc_close(c);
    return v;
}

static void test_outputs_equal_and_stats_count(void **state)
{
    st_unix_daemon *u = *state;
    assert_int_equal(st_unix_start(u, "0600"), 0);
    const char *d = u->d.dir;
    write_queries(d, 70000);          /* two calls of the CLI's 65536-query chunks */
    assert_int_equal(cli(d, u->addr, "--binary --shm off", "off.bin"), 0);
    assert_int_equal(stat_of(u, "shm_attached"), 0);
    assert_int_equal(stat_of(u, "shm_requests"), 0);
    assert_int_equal(cli(d, u->addr, "--binary --shm on", "on.bin"), 0);
    assert_int_equal(stat_of(u, "shm_attached"), 1);
    assert_int_equal(stat_of(u, "shm_requests"), 2);
    assert_int_equal(cli(d, u->addr, "--binary", "auto.bin"), 0);      /* auto by default */
    assert_int_equal(stat_of(u, "shm_attached"), 2);
    assert_int_equal(stat_of(u, "shm_requests"), 4);
    assert_true(same_files(d, "off.bin", "on.bin"));
    assert_true(same_files(d, "off.bin", "auto.bin"));
    /* text output: values, coverage and status through the region too */
    assert_int_equal(cli(d, u->addr, "--shm off", "off.txt"), 0);
    assert_int_equal(cli(d, u->addr, "--shm on --format unorm16", "on16.txt"), 0);
    assert_int_equal(cli(d, u->addr, "--shm off --format unorm16", "off16.txt"), 0);
    assert_int_equal(cli(d, u->addr, "--shm on", "on.txt"), 0);
    assert_true(same_files(d, "off.txt", "on.txt"));
    assert_true(same_files(d, "off16.txt", "on16.txt"));
    assert_false(same_files(d, "on.txt", "on16.txt"));   /* the comparison can fail */
    assert_int_equal(stat_of(u, "shm_requests"), 8);
    assert_int_equal(cli(d, u->addr, "--shm maybe", "bad.txt"), 2);
    assert_int_equal(st_unix_stop(u), 0);
}

static void test_refused_region(void **state)
{
    st_unix_daemon *u = *state;
    static const char *const args[] = { "--shm-max", "4096", NULL };
    assert_int_equal(st_unix_start_args(u, "0600", args), 0);
    const char *d = u->d.dir;
    write_queries(d, 3000);
    assert_int_equal(cli(d, u->addr, "--binary --shm off", "off.bin"), 0);
    assert_int_equal(cli(d, u->addr, "--binary", "auto.bin"), 0);
    assert_true(same_files(d, "off.bin", "auto.bin"));
    assert_int_equal(cli(d, u->addr, "--binary --shm on", "on.bin"), 1);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "grep -q 'shm-max' %s/on.bin.err", d);
    assert_int_equal(sh(cmd), 0);
    assert_int_equal(stat_of(u, "shm_refused"), 2);
    assert_int_equal(stat_of(u, "shm_requests"), 0);
    assert_int_equal(st_unix_stop(u), 0);
}

static void test_tcp_host(void **state)
{
    st_unix_daemon *u = *state;
    st_daemon t;
    assert_int_equal(st_daemon_up(&t, NULL), 0);
    const char *d = u->d.dir;
    write_queries(d, 100);
    char host[64];
    snprintf(host, sizeof host, "%s -p %d", t.host, t.port);
    assert_int_equal(cli(d, host, "--binary", "auto.bin"), 0);
    assert_int_equal(cli(d, host, "--binary --shm on", "on.bin"), 2);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "grep -q 'unix:' %s/on.bin.err", d);
    assert_int_equal(sh(cmd), 0);
    assert_int_equal(st_daemon_down(&t, 10000), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_outputs_equal_and_stats_count, st_unix_setup,
                                        st_unix_teardown),
        cmocka_unit_test_setup_teardown(test_refused_region, st_unix_setup, st_unix_teardown),
        cmocka_unit_test_setup_teardown(test_tcp_host, st_unix_setup, st_unix_teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
