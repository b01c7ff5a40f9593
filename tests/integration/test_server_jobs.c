/* tests/integration/test_server_jobs.c - seamtexd's compress jobs: a BC1 job with its
 * report, the DDS form in the data dir and through FETCH, cancel, and --job-threads giving the
 * same blocks as one thread.
 *
 * One daemon with defaults for the group plus one with --job-threads 0
 * (tests/common/daemon_fixture.h); nothing here needs SEAMTEX_DATA.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"
#include "sample.h"

/* How long a compress job may take before the test gives up: a deadline against a hung job,
 * not a speed check (jobs take seconds, many times that on a loaded machine). */
#define JOB_DEADLINE_MS 300000

/* ---- helpers --------------------------------------------------------------------------------- */

/* Compresses "default" on daemon d into a .dds file (fetched) at out. */
static void compress_default_to(const st_daemon *d, const char *target, const char *out)
{
    stc_conn *c = st_daemon_client(d, NULL);
    assert_non_null(c);
    uint64_t job = 0;
    stc_job js;
    assert_int_equal(stc_compress(c, "default", target, 5, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_wait(c, job, JOB_DEADLINE_MS, &js), 0);
    assert_int_equal(js.state, STC_JOB_DONE);
    assert_int_equal(stc_fetch_file(c, target, STC_FETCH_DDS, out, NULL, NULL), 0);
    assert_int_equal(stc_delete(c, target), 0);
    stc_close(c);
}

/* the group's daemon: defaults, --heavy-batch 2048 (set in main) */
#define D1 ST_GROUP

/* ---- tests ---------------------------------------------------------------------------------- */

static void compress_job_fetch_dds_and_cancel(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    uint64_t job = 0;
    assert_int_equal(stc_compress(c, "default", "default-bc1", 0, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_true(job > 0);
    stc_job js;
    assert_int_equal(stc_job_status(c, job, &js), 0);
    assert_int_equal(js.id, job);
    assert_true(js.state <= STC_JOB_DONE);
    int rc = stc_job_wait(c, job, JOB_DEADLINE_MS, &js);
    if (rc)
        fprintf(stderr, "job: %s %s\n", stc_strerror(rc), js.message);
    assert_int_equal(rc, 0);
    assert_int_equal(js.state, STC_JOB_DONE);
    /* the job's report: quality against the source, seams before -> after */
    print_message("# job: %s\n", js.message);
    assert_non_null(strstr(js.message, "PSNR"));
    double rms_src = 0, rms_bc1 = 0;
    const char *r = strstr(js.message, "seam RMS ");
    assert_non_null(r);
    assert_int_equal(sscanf(r, "seam RMS %lf -> %lf", &rms_src, &rms_bc1), 2);
    assert_true(rms_bc1 < rms_src);
    stc_info info;
    assert_int_equal(stc_info_get(c, "default-bc1", 0, 0, &info), 0);
    assert_int_equal(info.kind, ST_KIND_BC1);
    assert_int_equal(info.nfaces, 384);
    /* durable as a .dds in the data dir: every BC1 set has a DDS form, the default set's
     * mixed face sizes included (dds.c's set record) */
    char p[700];
    snprintf(p, sizeof p, "%s/sets/default-bc1/manifest", D1.datadir);
    assert_int_equal(access(p, R_OK), 0);
    /* the target exists now: a second job without replace is refused at once */
    assert_int_equal(stc_compress(c, "default", "default-bc1", 0, 0, &job), STC_EEXISTS);
    /* FETCH: .ptx is for per-face sets (not BC1 ones), .dds for BC1 sets */
    char out[600];
    snprintf(out, sizeof out, "%s/fetched.dds", D1.dir);
    assert_int_equal(stc_fetch_file(c, "default-bc1", STC_FETCH_PTX, out, NULL, NULL),
                     STC_EUNSUPPORTED);
    size_t ulen = 0;
    void *uptx = st_fixture_uniform_ptx(&ulen);
    assert_non_null(uptx);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, uptx, ulen, "uniform", &uo, &ur), 0);
    free(uptx);
    assert_int_equal(stc_compress(c, "uniform", "uniform-bc1", 9, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_wait(c, job, JOB_DEADLINE_MS, &js), 0);
    snprintf(p, sizeof p, "%s/sets/uniform-bc1/manifest", D1.datadir);
    assert_int_equal(access(p, R_OK), 0);  /* durable as .dds */
    assert_int_equal(stc_fetch_file(c, "uniform-bc1", STC_FETCH_DDS, out, NULL, NULL), 0);
    FILE *f = fopen(out, "rb");
    assert_non_null(f);
    char magic[4];
    assert_int_equal(fread(magic, 1, 4, f), 4);
    fclose(f);
    assert_memory_equal(magic, "DDS ", 4);
    assert_int_equal(stc_delete(c, "uniform-bc1"), 0);
    assert_int_equal(stc_delete(c, "uniform"), 0);
    /* cancel: the job ends CANCELED (or DONE when it was quicker than the cancel) */
    assert_int_equal(stc_compress(c, "default", "bc1-canceled", 9, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_cancel(c, job, &js), 0);
    int wrc = stc_job_wait(c, job, JOB_DEADLINE_MS, &js);
    assert_true(wrc == 0 || wrc == STC_ESERVERCANCELED);
    assert_true(js.state == STC_JOB_CANCELED || js.state == STC_JOB_DONE);
    if (js.state == STC_JOB_CANCELED)
        assert_int_equal(stc_info_get(c, "bc1-canceled", 0, 0, &info), STC_ENOTFOUND);
    assert_int_equal(stc_job_status(c, 999999, &js), STC_ENOTFOUND);
    assert_int_equal(stc_delete(c, "default-bc1"), 0);
    stc_delete(c, "bc1-canceled");
    stc_close(c);
}

/* stc_job_wait with wait_ms 0 polls once: a running job gives STC_ETIMEDOUT at once (it used
 * to wait for ever, 0 being taken as "no deadline"; seamtex.h says only a negative wait_ms
 * does that), and the connection stays usable. */
static void job_wait_zero_polls_once(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    uint64_t job = 0;
    stc_job js;
    /* level 9 of the default set takes seconds: running when polled right after */
    assert_int_equal(stc_compress(c, "default", "bc1-wait0", 9, STC_COMPRESS_SEAM_AWARE, &job), 0);
    memset(&js, 0, sizeof js);
    assert_int_equal(stc_job_wait(c, job, 0, &js), STC_ETIMEDOUT);
    assert_true(js.state == STC_JOB_QUEUED || js.state == STC_JOB_RUNNING);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_job_cancel(c, job, &js), 0);
    int rc = stc_job_wait(c, job, JOB_DEADLINE_MS, &js);
    assert_true(rc == 0 || rc == STC_ESERVERCANCELED);
    stc_delete(c, "bc1-wait0");
    stc_close(c);
}

/* --job-threads spreads a job's encoding over threads; the blocks do not depend on it. */
static void job_threads_give_the_same_blocks(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--job-threads", "0", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    char a[700], b[700];
    snprintf(a, sizeof a, "%s/threads-all.dds", d.dir);
    snprintf(b, sizeof b, "%s/threads-one.dds", d.dir);
    compress_default_to(&d, "jt-all", a);
    compress_default_to(&D1, "jt-one", b);
    size_t la, lb;
    uint8_t *fa = st_test_read_file(a, &la), *fb = st_test_read_file(b, &lb);
    assert_non_null(fa);
    assert_non_null(fb);
    assert_int_equal(la, lb);
    assert_memory_equal(fa, fb, la);
    free(fa);
    free(fb);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(compress_job_fetch_dds_and_cancel),
        cmocka_unit_test(job_wait_zero_polls_once),
        cmocka_unit_test(job_threads_give_the_same_blocks),
    };
    static const char *const args[] = {"--heavy-batch", "2048", NULL};
    st_group_args = args;
    return cmocka_run_group_tests_name("server_jobs", tests, st_group_setup,
                                       st_group_teardown);
}
