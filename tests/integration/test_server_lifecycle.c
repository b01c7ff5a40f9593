/* tests/integration/test_server_lifecycle.c - seamtexd's life: the token guards mutations
 * only, SIGHUP reloads limits and token (a broken config is refused), a restart loads the sets
 * and cleans what a crash left, SIGTERM finishes the requests in flight, bad flags are named
 * (exit 2, the cluster flags' form included).
 *
 * Each test starts its own daemon (tests/common/daemon_fixture.h) on 127.0.0.1 port 0 with a
 * temp data dir; nothing here needs SEAMTEX_DATA.
 */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/ptx_fixture.h"
#include "../common/wait.h"
#include "proto.h"

/* ---- tests ---------------------------------------------------------------------------------- */

static void token_guards_mutations_only(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--token", "s3cret", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    size_t len;
    void *ptx = st_fixture_default_ptx(&len, 2);
    assert_non_null(ptx);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    stc_conn *anon = st_daemon_client(&d, NULL);
    stc_conn *wrong = st_daemon_client(&d, "guess");
    stc_conn *ok = st_daemon_client(&d, "s3cret");
    assert_non_null(anon);
    assert_non_null(wrong);
    assert_non_null(ok);
    assert_true(stc_server_info(anon)->caps & STP_CAP_AUTH);
    assert_false(stc_server_info(wrong)->authenticated);
    assert_true(stc_server_info(ok)->authenticated);
    assert_int_equal(stc_ping(anon), 0);
    stc_info info;
    assert_int_equal(stc_info_get(anon, "default", 0, 0, &info), 0);
    assert_int_equal(stc_upload_buffer(anon, ptx, len, "t1", &uo, &ur), STC_EPERM);
    assert_int_equal(stc_upload_buffer(wrong, ptx, len, "t1", &uo, &ur), STC_EPERM);
    assert_int_equal(stc_delete(anon, "default"), STC_EPERM);
    assert_int_equal(stc_upload_buffer(ok, ptx, len, "t1", &uo, &ur), 0);
    assert_int_equal(stc_delete(ok, "t1"), 0);
    stc_close(anon);
    stc_close(wrong);
    stc_close(ok);
    free(ptx);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

static void sighup_reloads_limits_and_token(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    char conf[400];
    snprintf(conf, sizeof conf, "%s/seamtexd.conf", d.dir);
    FILE *f = fopen(conf, "w");
    assert_non_null(f);
    fprintf(f, "# test config\nmax-conns = 100\nlog-level = info\n");
    fclose(f);
    const char *extra[] = {"--config", conf, "--no-default-set", NULL};
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stc_stat_find(st, n, "max_conns")->u, 100);
    f = fopen(conf, "w");
    fprintf(f, "max-conns = 77\ntoken = newtoken\nlog-level = debug\n");
    fclose(f);
    assert_int_equal(st_daemon_signal(&d, SIGHUP), 0);
    assert_int_equal(st_wait_stat(&d, c, "max_conns", ST_STAT_EQ, 77, 10000), 0);
    /* the token now applies: this connection never sent it */
    assert_int_equal(stc_delete(c, "x"), STC_EPERM);
    stc_close(c);
    /* a broken config is refused and logged; the daemon keeps running */
    f = fopen(conf, "w");
    fprintf(f, "max-conns = lots\n");
    fclose(f);
    assert_int_equal(st_daemon_signal(&d, SIGHUP), 0);
    assert_int_equal(st_wait_file_has(d.log, "not reloaded", 10000), 0);
    c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* the log names what changed */
    f = fopen(d.log, "r");
    char line[1024];
    int saw = 0, refused = 0;
    while (f && fgets(line, sizeof line, f)) {
        if (strstr(line, "max-conns: 100 -> 77") && strstr(line, "token: (changed)"))
            saw = 1;
        if (strstr(line, "not reloaded"))
            refused = 1;
    }
    if (f)
        fclose(f);
    assert_true(saw);
    assert_true(refused);
    st_daemon_cleanup(&d);
}

static void restart_loads_sets_and_cleans_leftovers(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    size_t len;
    void *ptx = st_fixture_default_ptx(&len, 5);
    assert_non_null(ptx);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "keep-me", &uo, &ur), 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* plant what a crash leaves: a temp file, a set dir without manifest, an orphan source,
     * and a set whose source was damaged */
    char p[700];
    snprintf(p, sizeof p, "%s/tmp/123.part", d.datadir);
    FILE *f = fopen(p, "w");
    fputs("half", f);
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/halfway", d.datadir);
    assert_int_equal(mkdir(p, 0700), 0);
    snprintf(p, sizeof p, "%s/sets/halfway/source-1.ptx", d.datadir);
    f = fopen(p, "w");
    fputs("half", f);
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/keep-me/source-orphan.ptx", d.datadir);
    f = fopen(p, "w");
    fputs("orphan", f);
    fclose(f);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    const stc_set_entry *sets;
    size_t n;
    assert_int_equal(stc_list(c, &sets, &n), 0);
    assert_int_equal(n, 1);
    assert_string_equal(sets[0].name, "keep-me");
    assert_int_equal(sets[0].nfaces, 384);
    stc_close(c);
    assert_int_not_equal(access(p, F_OK), 0);
    snprintf(p, sizeof p, "%s/sets/halfway", d.datadir);
    assert_int_not_equal(access(p, F_OK), 0);
    snprintf(p, sizeof p, "%s/tmp/123.part", d.datadir);
    assert_int_not_equal(access(p, F_OK), 0);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* damage the committed source: the set is moved to broken/, not loaded, not lost */
    char man[700];
    snprintf(man, sizeof man, "%s/sets/keep-me/manifest", d.datadir);
    f = fopen(man, "r");
    char line[256], src[256] = "";
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "source ", 7)) {
            snprintf(src, sizeof src, "%s", line + 7);
            src[strcspn(src, "\n")] = 0;
        }
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/keep-me/%s", d.datadir, src);
    f = fopen(p, "r+b");
    assert_non_null(f);
    fseek(f, 100, SEEK_SET);
    fputc(0x5A, f);
    fclose(f);
    /* with its native file the set is served from it: a start reads no source bytes (only
     * sizes), docs/daemon.md; full verification reads them and sets the set aside */
    assert_int_equal(st_daemon_start(&d, extra), 0);
    c = st_daemon_client(&d, NULL);
    assert_int_equal(stc_list(c, &sets, &n), 0);
    assert_int_equal(n, 1);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    const char *verify[] = {"--no-default-set", "--verify-native", "yes", NULL};
    assert_int_equal(st_daemon_start(&d, verify), 0);
    c = st_daemon_client(&d, NULL);
    assert_int_equal(stc_list(c, &sets, &n), 0);
    assert_int_equal(n, 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    free(ptx);
    st_daemon_cleanup(&d);
}

static void sigterm_finishes_requests_in_flight(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--heavy-batch", "1000", "--workers", "1", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    enum { N = 200000, K = 4 };
    stc_query *q = calloc(N, sizeof *q);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)i % 384;
        q[i].u = (float)(i % 1000) / 1000.0f;
        q[i].v = 0.5f;
        q[i].dudx = q[i].dvdy = 0.05f;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 2;
    uint32_t ids[K];
    for (int k = 0; k < K; k++)
        assert_int_equal(stc_append_sample(c, "default", &o, q, N, &ids[k]), 0);
    assert_int_equal(stc_flush(c), 0);
    /* SIGTERM once the first batch is on a worker: requests are in flight */
    assert_int_equal(st_wait_stat(&d, NULL, "worker_tasks", ST_STAT_GE, 1, 10000), 0);
    assert_int_equal(st_daemon_signal(&d, SIGTERM), 0);
    for (int k = 0; k < K; k++) {
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 20000, &r), 0);
        assert_int_equal(r.reqid, ids[k]);
        assert_int_equal(r.status, 0);
        stc_sample_result res;
        assert_int_equal(stc_reply_sample(c, &r, &res), 0);
        assert_int_equal(res.count, N);
    }
    stc_close(c);
    free(q);
    /* exits 0 by itself */
    int rc = st_daemon_stop(&d, 15000);
    assert_true(rc == 0 || rc == -1);  /* -1: already gone, reaped by stop */
    assert_int_equal(d.exit_status, 0);
    st_daemon_cleanup(&d);
}

static void help_teaches_every_flag(void **state)
{
    (void)state;
    /* --help and a bad flag, through the fixture's spawn (never fork here) */
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    const char *bad[] = {"--max-conns", "many", NULL};
    assert_int_not_equal(st_daemon_start(&d, bad), 0);
    assert_int_equal(d.exit_status, 2);
    FILE *f = fopen(d.log, "r");
    char line[512];
    int named = 0;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, "max-conns") && strstr(line, "many"))
            named = 1;
    if (f)
        fclose(f);
    assert_true(named);
    st_daemon_cleanup(&d);
}

/* The form of --cluster, --node-id and --advertise is a flag's: a bad one exits 2 naming it
 * (seamtexd(8) EXIT STATUS), before the data dir is loaded; it used to be found when the
 * cluster started, after the data dir, and exit 1 as a start failure. */
static int start_status(const char *const *extra, const char *named)
{
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_not_equal(st_daemon_start(&d, extra), 0);
    int status = d.exit_status;
    FILE *f = fopen(d.log, "r");
    char line[512];
    int found = 0;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, named))
            found = 1;
    if (f)
        fclose(f);
    st_daemon_cleanup(&d);
    assert_true(found);
    return status;
}

static void a_bad_cluster_flag_exits_2(void **state)
{
    (void)state;
    const char *node[] = {"--cluster", "etcd://127.0.0.1:1/t", "--node-id", "a b",
                          "--advertise", "127.0.0.1:0", NULL};
    assert_int_equal(start_status(node, "node-id: 'a b'"), 2);
    const char *url[] = {"--cluster", "http://127.0.0.1:1/t", "--node-id", "n1",
                         "--advertise", "127.0.0.1:0", NULL};
    assert_int_equal(start_status(url, "etcd://"), 2);
    const char *adv[] = {"--cluster", "etcd://127.0.0.1:1/t", "--node-id", "n1",
                         "--advertise", "nowhere", NULL};
    assert_int_equal(start_status(adv, "advertise: 'nowhere'"), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(token_guards_mutations_only),
        cmocka_unit_test(sighup_reloads_limits_and_token),
        cmocka_unit_test(restart_loads_sets_and_cleans_leftovers),
        cmocka_unit_test(sigterm_finishes_requests_in_flight),
        cmocka_unit_test(help_teaches_every_flag),
        cmocka_unit_test(a_bad_cluster_flag_exits_2),
    };
    return cmocka_run_group_tests_name("server_lifecycle", tests, NULL, NULL);
}
