/* tests/integration/test_render_cli.c - seamtex-render's command line refuses what it cannot
 * draw before it loads or uploads anything: an image size whose multisample target is over the
 * rasteriser's limits (16384 per axis, 2^28 samples) for the job asked (a frame at --msaa, the
 * reference at --reference SS, the study's frames at 8x, its reference at --ref-ss and its
 * close-ups and BC1 pictures at two and four times the size) is a bad --size value: exit 2,
 * the flag named (docs/render.md "Command line"). The mesh path does not exist, so a size that
 * passes the check fails later on the mesh with exit 1: the two outcomes are told apart.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/testdata.h"
#include "unix_daemon.h"

static char scratch[256], errpath[512], studydir[512];

/* Runs seamtex-render --inproc ARGS... /nonexistent/m.obj; the exit status, stderr in errpath. */
static int render(const char *const *args)
{
    char exe[512];
    snprintf(exe, sizeof exe, "%s/seamtex-render", st_build_dir());
    const char *argv[32] = { exe, "--inproc", "--out", "/nonexistent/out" };
    size_t n = 4;
    for (size_t i = 0; args[i] && n + 2 < sizeof argv / sizeof argv[0]; i++)
        argv[n++] = args[i];
    argv[n++] = "/nonexistent/m.obj";
    argv[n] = NULL;
    if (truncate(errpath, 0) != 0)
        fail_msg("cannot truncate %s", errpath);
    return st_run(argv, errpath, NULL);
}

static int err_has(const char *text)
{
    FILE *f = fopen(errpath, "r");
    assert_non_null(f);
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    return strstr(buf, text) != NULL;
}

#define REFUSED(...) do { \
        const char *a_[] = { __VA_ARGS__, NULL }; \
        int rc_ = render(a_); \
        if (rc_ != 2 || !err_has("bad value for --size")) \
            fail_msg("%s %s: exit %d, expected 2 naming --size", a_[0], a_[1], rc_); \
    } while (0)
#define PASSES(...) do { \
        const char *a_[] = { __VA_ARGS__, NULL }; \
        int rc_ = render(a_); \
        if (rc_ != 1 || !err_has("m.obj")) \
            fail_msg("%s %s: exit %d, expected 1 on the missing mesh", a_[0], a_[1], rc_); \
    } while (0)

static void test_size_limits_per_job(void **state)
{
    (void)state;
    /* a frame: w * h * msaa <= 2^28 */
    REFUSED("--size", "16384x16384", "--msaa", "8");
    REFUSED("--size", "8192x8193", "--msaa", "4");
    PASSES("--size", "8192x8192", "--msaa", "4");
    PASSES("--size", "16384x16384", "--msaa", "1");
    /* the reference: SS x SS the size, one sample, each axis <= 16384 */
    REFUSED("--size", "1280x720", "--reference", "16");
    REFUSED("--size", "4096x4096", "--reference", "8");
    PASSES("--size", "1280x720", "--reference", "8");
    /* the study: reference at --ref-ss, BC1 pictures at 4x the size and 4x MSAA */
    REFUSED("--toth", studydir, "--size", "4096x10");
    REFUSED("--toth", studydir, "--size", "2049x2048");
    REFUSED("--toth", studydir, "--size", "1025x1024", "--ref-ss", "16");
    PASSES("--toth", studydir, "--size", "2048x2048");
    PASSES("--toth", studydir, "--size", "1024x1024", "--ref-ss", "16");
    /* the per-axis bound itself stays a --size error */
    REFUSED("--size", "16385x1");
}

/* A mesh that cannot be read is named as such (exit 1), not reported as a mesh without a
 * .ptx beside it, which sent one looking for the texture. */
static void test_a_missing_mesh_is_named(void **state)
{
    (void)state;
    assert_int_equal(render((const char *const[]){ "--size", "64x48", NULL }), 1);
    assert_true(err_has("/nonexistent/m.obj: cannot read the mesh"));
    assert_false(err_has("beside it"));
}

int main(void)
{
    if (st_test_mkdtemp(scratch, sizeof scratch, "render_cli") != 0)
        return 1;
    snprintf(errpath, sizeof errpath, "%s/stderr.txt", scratch);
    snprintf(studydir, sizeof studydir, "%s/study", scratch);
    if (mkdir(studydir, 0700) != 0)
        return 1;
    FILE *f = fopen(errpath, "w");
    if (!f)
        return 1;
    fclose(f);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_size_limits_per_job),
        cmocka_unit_test(test_a_missing_mesh_is_named),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    if (st_test_rmtree(scratch) != 0)
        rc = 1;
    return rc;
}
