/* tests/integration/test_render_study.c - the Toth study end to end on a tiny orbit:
 * tools/toth-study.sh starts its own seamtexd on a Unix socket (queries through shared memory), seamtex-render --toth
 * renders the teapot and the holey cube of the shared data for 3 frames at 64x48 through it,
 * and the CSVs, tables, plots and close-ups it promises are there with the right shapes.
 * Skipped when the shared data is missing.
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

#include "testdata.h"

static unsigned count_lines(const char *path, char *first, size_t cap)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char buf[8192];
    unsigned n = 0;
    while (fgets(buf, sizeof buf, f)) {
        if (n == 0 && first)
            snprintf(first, cap, "%s", buf);
        n++;
    }
    fclose(f);
    return n;
}

static void assert_file(const char *dir, const char *name)
{
    char p[1024];
    struct stat st;
    snprintf(p, sizeof p, "%s/%s", dir, name);
    if (stat(p, &st) != 0 || st.st_size == 0)
        fail_msg("%s is missing or empty", p);
}

static void test_study_tiny_orbit(void **state)
{
    (void)state;
    const char *data = st_test_data_dir();
    char teapot[512];
    snprintf(teapot, sizeof teapot, "%s/ptx/wdas-ptex-samples/teapot/teapot.obj", data);
    if (access(teapot, R_OK) != 0) {
        fprintf(stderr, "skipped: %s is missing\n", teapot);
        skip();
    }
    char dir[] = "/tmp/test_render_study.XXXXXX";
    assert_non_null(mkdtemp(dir));
    const char *build = getenv("SEAMTEX_BUILD");
    const char *b = build && *build ? strrchr(build, '/') : NULL;
    char cmd[1024];
    snprintf(cmd, sizeof cmd,
             "B=%s bash tools/toth-study.sh %s/out --frames 3 --size 64x48 --ref-ss 2 "
             "--closeup 12 --quiet > %s/log 2>&1", b ? b + 1 : "build", dir, dir);
    int rc = system(cmd);
    if (rc != 0) {
        snprintf(cmd, sizeof cmd, "cat %s/log >&2", dir);
        (void)system(cmd);
        fail_msg("toth-study.sh exited with %d", rc);
    }
    char out[600], head[8192];
    snprintf(out, sizeof out, "%s/out", dir);
    char p[700];
    /* Figure 5: x plus 3 comparisons x 4 rates, one row per bin, fraction 1 at x = 0 */
    snprintf(p, sizeof p, "%s/fig5_all.csv", out);
    assert_int_equal(count_lines(p, head, sizeof head), 1 + 1024);
    unsigned commas = 0;
    for (char *c = head; *c; c++)
        commas += *c == ',';
    assert_int_equal(commas, 12);
    assert_non_null(strstr(head, "traverse_vs_discard_8x"));
    FILE *f = fopen(p, "r");
    assert_non_null(f);
    assert_non_null(fgets(head, sizeof head, f));
    assert_non_null(fgets(head, sizeof head, f));
    fclose(f);
    assert_string_equal(head, "0.000000,1,1,1,1,1,1,1,1,1,1,1,1\n");
    /* Table 1: per mesh 2 modes x 4 rates + 4 ratio rows; every frame's 8 renders */
    snprintf(p, sizeof p, "%s/table1.csv", out);
    assert_int_equal(count_lines(p, NULL, 0), 1 + 2 * 12);
    snprintf(p, sizeof p, "%s/table1_frames.csv", out);
    assert_int_equal(count_lines(p, NULL, 0), 1 + 2 * 3 * 8);
    /* the daemon is on a Unix socket and the queries went through the shared region: a frame
     * sends far less than the 28 bytes per query the socket would carry */
    f = fopen(p, "r");
    assert_non_null(f);
    assert_non_null(fgets(head, sizeof head, f));
    unsigned rows = 0;
    while (fgets(head, sizeof head, f)) {
        char mesh[64], mode[16];
        unsigned frame, msaa;
        double ms[4], queries, bytes_out, bytes_in;
        assert_int_equal(sscanf(head, "%63[^,],%u,%15[^,],%u,%lf,%lf,%lf,%lf,%lf,%lf,%lf", mesh,
                                &frame, mode, &msaa, &ms[0], &ms[1], &ms[2], &ms[3], &queries,
                                &bytes_out, &bytes_in), 11);
        assert_true(queries > 0);
        if (bytes_out * 4 >= queries * 28)
            fail_msg("frame %u %s %ux: %.0f bytes out for %.0f queries: not through the region",
                     frame, mode, msaa, bytes_out, queries);
        rows++;
    }
    fclose(f);
    assert_int_equal(rows, 2 * 3 * 8);
    snprintf(p, sizeof p, "%s/log", dir);
    assert_true(count_lines(p, head, sizeof head) > 0);
    snprintf(cmd, sizeof cmd, "grep -q 'seamtexd on unix:' %s/log", dir);
    assert_int_equal(system(cmd), 0);
    const char *files[] = { "fig5_teapot.csv", "fig5_holeycube.csv", "fig5_all.png",
                            "fig5_teapot.png", "table1.md", "closeup_seam.png",
                            "closeup_clamp_1x.png", "closeup_traverse_4x.png", "bc1_seam.png",
                            "bc1.txt", "teapot_reference_f000.png" };
    for (size_t i = 0; i < sizeof files / sizeof *files; i++)
        assert_file(out, files[i]);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_study_tiny_orbit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
