/* tests/integration/test_cli.c - the command-line programs against a real daemon: `seamtex`
 * (every command, its output and exit codes 0 / 1 / 2 / 3; `--json` of ls, info, stats and
 * compress parsed with json-c and compared with the text output and libseamtex's answers)
 * and `seamtex-bench` (closed and open loop, JSON, loopback-only refusal).
 *
 * One seamtexd (tests/common/daemon_fixture.h) serves the whole group; each program runs as a
 * child through posix_spawn (this binary links OpenImageIO: no bare fork) with stdout and
 * stderr captured to files in the fixture's temp dir. Programs come from $SEAMTEX_BUILD.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <json-c/json.h>

#include "../common/daemon_fixture.h"
#include "seamtex.h"

extern char **environ;

static st_daemon D;
static char OUTF[400], ERRF[400];
static char OUT[1 << 16], ERR[1 << 14];
static size_t OUTLEN;

static void slurp(const char *path, char *buf, size_t cap, size_t *len)
{
    size_t n = 0;
    FILE *f = fopen(path, "rb");
    if (f) {
        n = fread(buf, 1, cap - 1, f);
        fclose(f);
    }
    buf[n] = '\0';
    if (len)
        *len = n;
}

static const char *bin(const char *name)
{
    static char path[2][512];
    static int k;
    const char *b = getenv("SEAMTEX_BUILD");
    k ^= 1;
    snprintf(path[k], sizeof path[k], "%s/%s", b && *b ? b : "build", name);
    return path[k];
}

/* Runs a program (NULL-terminated argv after the program name), stdin from `in` (or
 * /dev/null), stdout to `out`, and returns its exit status (128 + signal when killed); OUT and
 * ERR hold its output (OUT: what `out` holds when it is OUTF). */
static int runv_to(const char *prog, const char *in, const char *out, const char *const *args)
{
    const char *argv[64];
    int ac = 0;
    argv[ac++] = prog;
    for (int i = 0; args[i] && ac < 63; i++)
        argv[ac++] = args[i];
    argv[ac] = NULL;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, in ? in : "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, ERRF, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid;
    int rc = posix_spawn(&pid, prog, &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    assert_int_equal(rc, 0);
    int st;
    while (waitpid(pid, &st, 0) < 0)
        ;
    slurp(OUTF, OUT, sizeof OUT, &OUTLEN);
    slurp(ERRF, ERR, sizeof ERR, NULL);
    int code = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
    if (getenv("TEST_CLI_VERBOSE"))
        fprintf(stderr, "$ %s ... -> %d\n%s%s", prog, code, OUT, ERR);
    return code;
}

static int runv(const char *prog, const char *in, const char *const *args)
{
    return runv_to(prog, in, OUTF, args);
}

static char PORT[16];

/* seamtex -p PORT args... */
#define CLI(...) runv(bin("seamtex"), NULL, (const char *const[]){ "-p", PORT, __VA_ARGS__, NULL })
#define CLI_IN(in, ...) runv(bin("seamtex"), in, (const char *const[]){ "-p", PORT, __VA_ARGS__, NULL })
#define BENCH(...) runv(bin("seamtex-bench"), NULL, (const char *const[]){ "-p", PORT, __VA_ARGS__, NULL })

static int count_lines_ending(const char *text, const char *suffix)
{
    int n = 0;
    size_t sl = strlen(suffix);
    for (const char *p = text; *p;) {
        const char *e = strchr(p, '\n');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        if (len >= sl && !memcmp(p + len - sl, suffix, sl))
            n++;
        p += len + (e ? 1 : 0);
    }
    return n;
}

static double json_num(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\": ", key);
    const char *p = strstr(json, k);
    return p ? strtod(p + strlen(k), NULL) : -1.0;
}

static int group_setup(void **state)
{
    (void)state;
    if (st_daemon_init(&D) != 0 || st_daemon_start(&D, NULL) != 0)
        return -1;
    snprintf(PORT, sizeof PORT, "%d", D.port);
    snprintf(OUTF, sizeof OUTF, "%s/cli.out", D.dir);
    snprintf(ERRF, sizeof ERRF, "%s/cli.err", D.dir);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    int rc = st_daemon_stop(&D, 10000);
    st_daemon_cleanup(&D);
    return rc == 0 ? 0 : -1;
}

static void ping_prints_pong_and_exits_zero(void **state)
{
    (void)state;
    assert_int_equal(CLI("ping"), 0);
    assert_non_null(strstr(OUT, "PONG"));
}

static void ls_lists_the_default_set(void **state)
{
    (void)state;
    assert_int_equal(CLI("ls"), 0);
    assert_non_null(strstr(OUT, "NAME"));
    assert_non_null(strstr(OUT, "default"));
    assert_non_null(strstr(OUT, "384"));
}

static void info_describes_the_default_set(void **state)
{
    (void)state;
    assert_int_equal(CLI("info", "default"), 0);
    assert_non_null(strstr(OUT, "faces:             384"));
    assert_non_null(strstr(OUT, "channels:          4 u8"));
    assert_int_equal(CLI("info", "default", "--faces", "0:2"), 0);
    assert_non_null(strstr(OUT, "face 0: "));
    assert_non_null(strstr(OUT, "face 1: "));
    assert_null(strstr(OUT, "face 2: "));
}

static void sample_one_query_prints_four_values_coverage_and_ok(void **state)
{
    (void)state;
    assert_int_equal(CLI("sample", "default", "3", "0.5", "0.5", "--mode", "traverse",
                         "--filter", "bilinear"), 0);
    unsigned face;
    float u, v, c[4], cov;
    char st[32];
    assert_int_equal(sscanf(OUT, "%u %f %f: %f %f %f %f coverage %f %31s", &face, &u, &v, &c[0],
                            &c[1], &c[2], &c[3], &cov, st), 9);
    assert_int_equal(face, 3);
    for (int i = 0; i < 4; i++)
        assert_true(c[i] >= 0.0f && c[i] <= 1.0f);
    assert_true(cov > 0.99f && cov < 1.01f);
    assert_string_equal(st, "OK");
}

static void sample_query_file_answers_every_line_in_each_mode(void **state)
{
    (void)state;
    char qf[400];
    snprintf(qf, sizeof qf, "%s/queries.txt", D.dir);
    FILE *f = fopen(qf, "w");
    assert_non_null(f);
    fprintf(f, "# face u v [dudx dvdx dudy dvdy]\n0 0.5 0.5\n\n7 0.98 0.5 0.05 0 0 0.05\n"
               "100 0.5 0.01 0.05 0 0 0.05\n383 0.01 0.99 0.08 0 0 0.08\n");
    fclose(f);
    const char *modes[] = { "traverse", "discard", "clamp" };
    for (int m = 0; m < 3; m++) {
        assert_int_equal(CLI("sample", "default", "--queries", qf, "--mode", modes[m]), 0);
        assert_int_equal(count_lines_ending(OUT, " OK"), 4);
        assert_non_null(strstr(OUT, "(4 queries, 0 not OK)"));
    }
    /* the same file through stdin */
    assert_int_equal(CLI_IN(qf, "sample", "default", "--queries", "-"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 4);
}

static void sample_reports_a_bad_face_per_query(void **state)
{
    (void)state;
    assert_int_equal(CLI("sample", "default", "99999", "0.5", "0.5"), 0);
    assert_non_null(strstr(OUT, "BAD_FACE"));
}

/* "-inf" and "-nan" are numbers like "inf", "nan" and "-0.5" (they were taken for unknown
 * options, exit 2), and the echoed query is the float that was sampled: 10000.001 is past
 * the 1e4 limit, and %g echoed it as "10000" beside BAD_FOOTPRINT. */
static void sample_takes_negative_infinity_and_echoes_the_exact_query(void **state)
{
    (void)state;
    assert_int_equal(CLI("sample", "default", "3", "-inf", "0.5"), 0);
    assert_non_null(strstr(OUT, "3 -inf 0.5:"));
    assert_non_null(strstr(OUT, "NONFINITE"));
    assert_int_equal(CLI("sample", "default", "3", "0.5", "-nan"), 0);
    assert_non_null(strstr(OUT, "NONFINITE"));
    assert_int_equal(CLI("sample", "default", "3", "0.5", "0.5", "--dudx", "-inf"), 0);
    assert_non_null(strstr(OUT, "NONFINITE"));
    assert_int_equal(CLI("sample", "default", "3", "10000.001", "0.5", "--mode", "clamp"), 0);
    assert_non_null(strstr(OUT, "3 10000.001 0.5:"));
    assert_non_null(strstr(OUT, "BAD_FOOTPRINT"));
    assert_int_equal(CLI("sample", "default", "3", "-10000", "0.98", "--mode", "clamp"), 0);
    assert_non_null(strstr(OUT, "3 -10000 0.98:"));     /* %g kept where it reads back */
    assert_non_null(strstr(OUT, " OK"));
    assert_int_equal(CLI("sample", "default", "3", "-x", "0.5"), 2);   /* still an option */
}

static void sample_binary_writes_count_times_channels_floats(void **state)
{
    (void)state;
    char qf[400];
    snprintf(qf, sizeof qf, "%s/q10.txt", D.dir);
    FILE *f = fopen(qf, "w");
    assert_non_null(f);
    for (int i = 0; i < 10; i++)
        fprintf(f, "%d 0.25 0.75\n", i * 7);
    fclose(f);
    assert_int_equal(CLI("sample", "default", "--queries", qf, "--binary"), 0);
    assert_int_equal(OUTLEN, 10 * 4 * sizeof(float));
    float v[40];
    memcpy(v, OUT, sizeof v);
    for (int i = 0; i < 40; i++)
        assert_true(v[i] >= 0.0f && v[i] <= 1.0f);
    assert_int_equal(CLI("sample", "default", "--queries", qf, "--binary", "--format", "unorm8"), 0);
    assert_int_equal(OUTLEN, 10 * 4);
}

/* --compact sends the queries compact (PROTOCOL.md 4.4.1: u, v rounded to multiples of 2^-16):
 * its values are bit for bit those of the same queries rounded beforehand and sent as f32,
 * and differ from the unrounded queries' (the CLI once dropped the flag and sent f32). */
static void sample_compact_sends_the_rounded_queries(void **state)
{
    (void)state;
    enum { N = 16 };
    char qf[400], rf[400];
    snprintf(qf, sizeof qf, "%s/qc.txt", D.dir);
    snprintf(rf, sizeof rf, "%s/qr.txt", D.dir);
    FILE *f = fopen(qf, "w"), *g = fopen(rf, "w");
    assert_non_null(f);
    assert_non_null(g);
    for (int i = 0; i < N; i++) {
        /* a quarter of a 2^-16 step off the grid: the nearest multiple is k / 65536 */
        long ku = 13000 + 2711 * i, kv = 40000 - 1907 * i;
        double u = ((double)ku + 0.25) / 65536.0, v = ((double)kv - 0.25) / 65536.0;
        fprintf(f, "%d %.9g %.9g\n", i % 6, u, v);
        fprintf(g, "%d %.9g %.9g\n", i % 6, (double)ku / 65536.0, (double)kv / 65536.0);
    }
    fclose(f);
    fclose(g);
    static char compact[N * 4 * sizeof(float)], rounded[sizeof compact], plain[sizeof compact];
    assert_int_equal(CLI("sample", "default", "--queries", qf, "--binary", "--compact"), 0);
    assert_int_equal(OUTLEN, sizeof compact);
    memcpy(compact, OUT, sizeof compact);
    assert_int_equal(CLI("sample", "default", "--queries", rf, "--binary"), 0);
    assert_int_equal(OUTLEN, sizeof rounded);
    memcpy(rounded, OUT, sizeof rounded);
    assert_int_equal(CLI("sample", "default", "--queries", qf, "--binary"), 0);
    assert_int_equal(OUTLEN, sizeof plain);
    memcpy(plain, OUT, sizeof plain);
    assert_memory_equal(compact, rounded, sizeof compact);
    assert_true(memcmp(compact, plain, sizeof plain) != 0);
    /* the compact layouts are SAMPLE's: with --dir a usage error */
    assert_int_equal(CLI("sample", "default", "--dir", "1", "0", "0", "--compact"), 2);
}

static void an_unknown_set_exits_1_with_the_servers_message(void **state)
{
    (void)state;
    assert_int_equal(CLI("info", "no-such-set"), 1);
    assert_non_null(strstr(ERR, "NOT_FOUND"));
    assert_int_equal(CLI("sample", "no-such-set", "0", "0.5", "0.5"), 1);
    /* said once: "seamtex: no-such-set: SAMPLE: NOT_FOUND: no set named ...", not the
     * status again in front of the library's message */
    const char *nf = strstr(ERR, "NOT_FOUND");
    assert_non_null(nf);
    assert_null(strstr(nf + 1, "NOT_FOUND"));
    assert_non_null(strstr(ERR, "SAMPLE: NOT_FOUND: "));
    assert_int_equal(CLI("delete", "no-such-set"), 1);
}

static void bad_usage_exits_2(void **state)
{
    (void)state;
    assert_int_equal(CLI("frobnicate"), 2);
    assert_non_null(strstr(ERR, "unknown command"));
    assert_int_equal(CLI("sample", "default", "1"), 2);
    assert_int_equal(CLI("sample", "default", "x", "0.5", "0.5"), 2);
    assert_int_equal(CLI("sample", "default", "0", "0.5", "0.5", "--mode", "sideways"), 2);
    assert_int_equal(CLI("info"), 2);
    assert_int_equal(runv(bin("seamtex"), NULL, (const char *const[]){ "-p", "0", "ping", NULL }), 2);
    /* --help is not an error */
    assert_int_equal(CLI("sample", "--help"), 0);
    assert_non_null(strstr(OUT, "usage: seamtex sample"));
}

/* Output that cannot be written (a full disk: /dev/full) is an error, exit 1 - the usage
 * text of --help too (it exited 0) */
static void an_unwritable_output_exits_1(void **state)
{
    (void)state;
    if (access("/dev/full", W_OK)) {
        print_message("no /dev/full here: skipped\n");
        skip();
    }
    static const char *const cases[][3] = {{"--help", NULL}, {"ping", "--help", NULL},
                                           {"-?", NULL}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        assert_int_equal(runv_to(bin("seamtex"), NULL, "/dev/full", cases[k]), 1);
        assert_non_null(strstr(ERR, "writing the output failed"));
    }
}

static void no_server_exits_3(void **state)
{
    (void)state;
    /* a port nobody listens on: bind one, learn it, close it */
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(fd >= 0);
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
    socklen_t al = sizeof a;
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &al), 0);
    char port[16];
    snprintf(port, sizeof port, "%u", ntohs(a.sin_port));
    close(fd);
    assert_int_equal(runv(bin("seamtex"), NULL, (const char *const[]){ "-p", port, "ping", NULL }),
                     3);
    assert_non_null(strstr(ERR, "cannot connect"));
    assert_int_equal(runv(bin("seamtex-bench"), NULL,
                          (const char *const[]){ "-p", port, "-d", "0.1", NULL }), 3);
    /* the same through libseamtex's handles (--lib, --cluster): it was 1 */
    assert_int_equal(runv(bin("seamtex-bench"), NULL,
                          (const char *const[]){ "--lib", "-p", port, "-o", "sample", "-d", "0.1",
                                                 "-w", "0", NULL }), 3);
    char seed[64];
    snprintf(seed, sizeof seed, "127.0.0.1:%s", port);
    assert_int_equal(runv(bin("seamtex-bench"), NULL,
                          (const char *const[]){ "--cluster", seed, "-o", "sample", "-d", "0.1",
                                                 "-w", "0", NULL }), 3);
}

static void upload_ls_sample_delete_round_trip(void **state)
{
    (void)state;
    char ptx[512];
    if (st_daemon_data_path(ptx, sizeof ptx, "ptex-ref/cube1_k6_u8.ptx") != 0) {
        printf("# SEAMTEX_DATA has no ptex-ref/cube1_k6_u8.ptx: skipping the upload test\n");
        skip();
    }
    assert_int_equal(CLI("upload", ptx, "cli-cube"), 0);
    assert_non_null(strstr(OUT, "as cli-cube"));
    assert_non_null(strstr(ERR, "upload: 100%"));      /* plain progress: stderr is a file */
    assert_int_equal(CLI("ls"), 0);
    assert_non_null(strstr(OUT, "cli-cube"));
    assert_int_equal(CLI("sample", "cli-cube", "2", "0.5", "0.5"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    /* the same name again without --replace is refused */
    assert_int_equal(CLI("upload", ptx, "cli-cube"), 1);
    assert_int_equal(CLI("delete", "cli-cube"), 0);
    assert_int_equal(CLI("info", "cli-cube"), 1);
    /* --resume with nothing kept on the server: a whole upload, no "resumed" line */
    assert_int_equal(CLI("upload", ptx, "cli-cube", "--resume", "--retries", "0"), 0);
    assert_null(strstr(ERR, "resumed at"));
    assert_non_null(strstr(ERR, "held nothing of this upload to resume"));
    assert_int_equal(CLI("delete", "cli-cube"), 0);
    assert_int_equal(CLI("upload", ptx, "cli-cube", "--retries", "many"), 2);
}

static void sample_dir_answers_on_a_cube_map_and_refuses_other_sets(void **state)
{
    (void)state;
    char exr[512];
    if (st_daemon_data_path(exr, sizeof exr, "env/WavyLinesCube.exr") != 0) {
        printf("# SEAMTEX_DATA has no env/WavyLinesCube.exr: skipping the cube test\n");
        skip();
    }
    assert_int_equal(CLI("upload", exr, "cli-wavy"), 0);
    assert_non_null(strstr(OUT, "cube, 6 faces"));
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "1", "0.2", "0.1"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "1", "1", "1", "--cone", "0.1",
                         "--filter", "trilinear"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    /* --cone without --dir is a usage error; a per-face set has no directions */
    assert_int_equal(CLI("sample", "cli-wavy", "0", "0.5", "0.5", "--cone", "0.1"), 2);
    assert_int_equal(CLI("sample", "default", "--dir", "1", "0", "0"), 1);
    assert_non_null(strstr(ERR, "UNSUPPORTED"));
    /* the load tester's direction batches */
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/dir.json", D.dir);
    assert_int_equal(BENCH("-o", "sample-dir", "-s", "cli-wavy", "-b", "256", "-n", "20", "-w", "0",
                           "-d", "10", "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    assert_true(json_num(js, "completed") == 20);
    assert_true(json_num(js, "errors") == 0);
    assert_int_equal(BENCH("-o", "sample-dir", "-s", "default", "-d", "0.2"), 1);
    /* FLT_MAX as printf prints it (%.8g, %.9g: a little above FLT_MAX, rounding to it) is a
     * direction like any other; past the rounding midpoint (3.5e38) it is still refused */
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "3.4028235e+38", "-3.40282347e+38", "0"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "3.5e38", "0", "0"), 2);
    /* a NaN or negative cone reaches the server and is answered, not dropped for a point
     * lookup */
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "1", "0", "0", "--cone", "nan"), 0);
    assert_int_equal(count_lines_ending(OUT, " NONFINITE"), 1);
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "1", "0", "0", "--cone", "-0.1"), 0);
    assert_int_equal(count_lines_ending(OUT, " BAD_FOOTPRINT"), 1);
    assert_int_equal(CLI("sample", "cli-wavy", "--dir", "1", "0", "0", "--cone", "0"), 0);
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    assert_int_equal(CLI("delete", "cli-wavy"), 0);
}

static void compress_reports_sizes_and_fetch_writes_a_ptex_file(void **state)
{
    (void)state;
    assert_int_equal(CLI("compress", "default", "cli-bc1", "--level", "0"), 0);
    assert_non_null(strstr(OUT, "compressed default -> cli-bc1"));
    assert_non_null(strstr(OUT, ":1)"));                 /* the compression ratio */
    assert_non_null(strstr(OUT, "seam RMS"));            /* the quality report */
    assert_non_null(strstr(ERR, "compress: 100%"));
    assert_int_equal(CLI("info", "cli-bc1"), 0);
    assert_non_null(strstr(OUT, "kind:              bc1"));
    assert_int_equal(CLI("delete", "cli-bc1"), 0);

    char path[400], magic[4] = { 0 };
    snprintf(path, sizeof path, "%s/default.ptx", D.dir);
    assert_int_equal(CLI("fetch", "default", path), 0);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    assert_int_equal(fread(magic, 1, 4, f), 4);
    fclose(f);
    assert_memory_equal(magic, "Ptex", 4);
    assert_int_equal(CLI("fetch", "no-such-set", path), 1);
    /* the format comes from the extension: a per-face set is not a .png (the server names
     * what fits); --format overrides the extension */
    char png[400];
    snprintf(png, sizeof png, "%s/default.png", D.dir);
    assert_int_equal(CLI("fetch", "default", png), 1);
    assert_non_null(strstr(ERR, "it can be as: ptx"));
    assert_int_equal(access(png, F_OK), -1);
    assert_int_equal(CLI("fetch", "default", png, "--format", "ptx"), 0);
    f = fopen(png, "rb");
    assert_non_null(f);
    assert_int_equal(fread(magic, 1, 4, f), 4);
    fclose(f);
    assert_memory_equal(magic, "Ptex", 4);
    assert_int_equal(CLI("fetch", "default", png, "--format", "tga"), 2);
}

static void commands_piped_on_stdin_share_one_connection(void **state)
{
    (void)state;
    char cf[400];
    snprintf(cf, sizeof cf, "%s/commands.txt", D.dir);
    FILE *f = fopen(cf, "w");
    assert_non_null(f);
    fprintf(f, "ping\n# a comment\n\nls\nsample default 3 0.5 0.5 --mode \"discard\"\nping\n");
    fclose(f);
    assert_int_equal(runv(bin("seamtex"), cf, (const char *const[]){ "-p", PORT, NULL }), 0);
    assert_non_null(strstr(OUT, "PONG"));
    assert_non_null(strstr(strstr(OUT, "PONG") + 4, "PONG"));   /* twice */
    assert_non_null(strstr(OUT, "default"));
    assert_int_equal(count_lines_ending(OUT, " OK"), 1);
    /* a failing line makes the exit status, the lines after it still run */
    f = fopen(cf, "w");
    assert_non_null(f);
    fprintf(f, "info no-such-set\nping\n");
    fclose(f);
    assert_int_equal(runv(bin("seamtex"), cf, (const char *const[]){ "-p", PORT, NULL }), 1);
    assert_non_null(strstr(OUT, "PONG"));
}

static void stats_prints_counters(void **state)
{
    (void)state;
    assert_int_equal(CLI("stats"), 0);
    assert_true(OUTLEN > 0);
    assert_non_null(strchr(OUT, '\n'));
}


static void bench_closed_loop_answers_every_request(void **state)
{
    (void)state;
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/bench.json", D.dir);
    assert_int_equal(BENCH("-c", "4", "-P", "4", "-n", "2000", "-d", "10", "-w", "0", "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    assert_true(json_num(js, "sent") == 2000);
    assert_true(json_num(js, "completed") == 2000);
    assert_true(json_num(js, "measured") == 2000);
    assert_true(json_num(js, "errors") == 0);
    assert_true(json_num(js, "timeouts") == 0);
    assert_non_null(strstr(js, "\"corrected_us\": {\"p50\": "));
}

/* The open loop issues its schedule - rate x (warmup + duration) requests, 2000/s x 1.2 s =
 * 2400, each either sent or reported unsent - answers every one it sent, and measures latency
 * from the intended send time (corrected >= service). How close the achieved rate comes to the
 * target is a benchmark's figure (make bench), not asserted here. */
static void bench_open_loop_sends_its_schedule_and_corrects_latency(void **state)
{
    (void)state;
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/open.json", D.dir);
    assert_int_equal(BENCH("-c", "8", "-r", "2000", "-d", "1", "-w", "0.2", "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    assert_non_null(strstr(js, "\"loop\": \"open\""));
    assert_true(json_num(js, "target_rate") == 2000);
    double sent = json_num(js, "sent"), unsent = json_num(js, "unsent");
    double measured = json_num(js, "measured");
    assert_true(sent + unsent == 2400);
    assert_true(json_num(js, "completed") == sent);
    /* 2000 of them are due in the measured second; the ones sent are all measured */
    assert_true(measured <= 2000 && measured + unsent >= 2000);
    assert_true(json_num(js, "errors") == 0);
    assert_true(json_num(js, "timeouts") == 0);
    const char *cor = strstr(js, "\"corrected_us\": {");
    const char *svc = strstr(js, "\"service_us\": {");
    assert_non_null(cor);
    assert_non_null(svc);
    assert_true(json_num(cor, "p50") >= json_num(svc, "p50"));
    assert_true(json_num(cor, "max") >= json_num(svc, "max"));
    assert_true(json_num(svc, "p50") >= 0);
}

static void bench_sample_batches_are_answered(void **state)
{
    (void)state;
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/sample.json", D.dir);
    assert_int_equal(BENCH("-o", "sample", "-b", "512", "-m", "traverse,discard,clamp", "-f",
                           "bilinear,trilinear", "-n", "50", "-d", "10", "-w", "0", "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    assert_true(json_num(js, "completed") == 50);
    assert_true(json_num(js, "errors") == 0);
    assert_true(json_num(js, "queries_per_s") > 0);
}

/* The load tester's own CPU over its measured window (JSON cpu_window_s, with the window's
 * edges and the queries recorded in it), which net_wire.py divides by queries_measured: less
 * than the whole process's (start-up, connecting and the request pools are outside it), the
 * edges a warm-up apart from the start and a duration apart from each other; under a request
 * cap (-n) the window ends with the last thread, not at t_end. */
static void bench_reports_its_cpu_over_the_measured_window(void **state)
{
    (void)state;
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/window.json", D.dir);
    assert_int_equal(BENCH("-o", "sample", "-b", "512", "-c", "2", "-T", "2", "-P", "2", "-d",
                           "1", "-w", "0.3", "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    double cpu = json_num(js, "cpu_s"), win = json_num(js, "cpu_window_s");
    double t0 = json_num(js, "window_start_ns"), t1 = json_num(js, "window_end_ns");
    assert_true(win > 0 && win < cpu);
    assert_true(t1 - t0 >= 0.99e9 && t1 - t0 < 1.5e9);
    assert_true(json_num(js, "vcsw_window") + json_num(js, "ivcsw_window") > 0);
    double q = json_num(js, "queries_measured");
    assert_true(q > 0 && (long long)q % 512 == 0);
    assert_true(fabs(q - json_num(js, "queries_per_s") * json_num(js, "duration_s")) < 1024);

    /* -n ends the run long before -d: so does the window */
    assert_int_equal(BENCH("-o", "sample", "-b", "512", "-n", "20", "-d", "30", "-w", "0",
                           "-j", jf), 0);
    slurp(jf, js, sizeof js, NULL);
    assert_true(json_num(js, "completed") == 20);
    t0 = json_num(js, "window_start_ns");
    t1 = json_num(js, "window_end_ns");
    assert_true(t1 >= t0 && t1 - t0 < 10e9);
    assert_true(json_num(js, "queries_measured") == 20 * 512);
}

/* Closed-loop SAMPLE wakes for several whole replies (--lowat, SO_RCVLOWAT): the last
 * replies of a run, fewer than the mark, still arrive (the mark is dropped when no more
 * requests are issued), whatever the mark, with -n not a multiple of the pipeline. */
static void bench_sample_pipeline_with_a_low_water_mark_answers_every_request(void **state)
{
    (void)state;
    char jf[400], js[8192];
    snprintf(jf, sizeof jf, "%s/lowat.json", D.dir);
    const char *marks[] = {"6", "0", "8"};
    for (unsigned i = 0; i < 3; i++) {
        assert_int_equal(BENCH("-o", "sample", "-b", "1024", "-c", "2", "-T", "2", "-P", "8",
                               "--lowat", marks[i], "-n", "45", "-d", "10", "-w", "0", "-j", jf),
                         0);
        slurp(jf, js, sizeof js, NULL);
        assert_true(json_num(js, "completed") == 45);
        assert_true(json_num(js, "errors") == 0);
        assert_true(json_num(js, "timeouts") == 0);
    }
}

static void bench_refuses_a_non_loopback_host(void **state)
{
    (void)state;
    /* refused before any socket is made: no packet leaves the machine */
    assert_int_equal(runv(bin("seamtex-bench"), NULL,
                          (const char *const[]){ "-h", "192.0.2.1", "-p", PORT, "-d", "0.1",
                                                 NULL }), 3);
    assert_non_null(strstr(ERR, "not a loopback address"));
    assert_int_equal(BENCH("--conns", "0"), 2);
    assert_int_equal(BENCH("--rate", "-5"), 2);
}

/* `seamtex cluster` (and --cluster routing) on a daemon that is not in a cluster: the server
 * answers CLUSTER with UNSUPPORTED, a refusal (exit 1 with its message), not a lost
 * connection (3) with an empty message. */
static void cluster_on_a_daemon_outside_a_cluster_exits_1_with_its_message(void **state)
{
    (void)state;
    assert_int_equal(CLI("cluster"), 1);
    assert_non_null(strstr(ERR, "UNSUPPORTED"));
    assert_non_null(strstr(ERR, "not in a cluster"));
    assert_int_equal(CLI("cluster", "--json"), 1);
    assert_int_equal(OUTLEN, 0);
    char seed[64];
    snprintf(seed, sizeof seed, "127.0.0.1:%s", PORT);
    assert_int_equal(runv(bin("seamtex"), NULL,
                          (const char *const[]){ "--cluster", seed, "info", "default", NULL }), 1);
    assert_non_null(strstr(ERR, "not in a cluster"));
    /* seamtex-bench --cluster: the seed answered and refused: 1, not 3 */
    assert_int_equal(runv(bin("seamtex-bench"), NULL,
                          (const char *const[]){ "--cluster", seed, "-o", "sample", "-d", "0.1",
                                                 "-w", "0", NULL }), 1);
    assert_non_null(strstr(ERR, "not in a cluster"));
    /* a command without a set goes to the first seed, which answers it */
    assert_int_equal(runv(bin("seamtex"), NULL,
                          (const char *const[]){ "--cluster", seed, "ping", NULL }), 0);
}

/* $SEAMTEX_PORT is the default port (seamtex(1) ENVIRONMENT); one that is not a port is
 * refused (2) rather than silently replaced by 7450, where another daemon may answer. -p
 * replaces it, and --help needs no port. */
static void seamtex_port_from_the_environment_and_a_bad_one_refused(void **state)
{
    (void)state;
    setenv("SEAMTEX_PORT", PORT, 1);
    int ok = runv(bin("seamtex"), NULL, (const char *const[]){ "ping", NULL });
    setenv("SEAMTEX_PORT", "74x50", 1);
    int bad = runv(bin("seamtex"), NULL, (const char *const[]){ "ping", NULL });
    char err[sizeof ERR];
    snprintf(err, sizeof err, "%s", ERR);
    int bad_cluster = runv(bin("seamtex"), NULL, (const char *const[]){ "cluster", NULL });
    int replaced = CLI("ping");
    int help = runv(bin("seamtex"), NULL, (const char *const[]){ "ping", "--help", NULL });
    unsetenv("SEAMTEX_PORT");
    assert_int_equal(ok, 0);
    assert_int_equal(bad, 2);
    assert_non_null(strstr(err, "SEAMTEX_PORT '74x50'"));
    assert_int_equal(bad_cluster, 2);
    assert_int_equal(replaced, 0);
    assert_int_equal(help, 0);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

/* --timeout bounds the whole wait, HELLO included: a server that accepts and never answers
 * makes `seamtex --timeout 200 ping` give up (exit 3, ETIMEDOUT) long before the library's
 * 5 s connect default, which it used to wait out whatever --timeout said. */
static void timeout_bounds_the_connect_and_hello_too(void **state)
{
    (void)state;
    int fd = socket(AF_INET, SOCK_STREAM, 0);   /* listens, never accepts: the kernel does */
    assert_true(fd >= 0);
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
    socklen_t al = sizeof a;
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(listen(fd, 4), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &al), 0);
    char port[16];
    snprintf(port, sizeof port, "%u", ntohs(a.sin_port));
    double t0 = now_s();
    int rc = runv(bin("seamtex"), NULL,
                  (const char *const[]){ "-p", port, "--timeout", "200", "ping", NULL });
    double took = now_s() - t0;
    close(fd);
    assert_int_equal(rc, 3);
    assert_non_null(strstr(ERR, "ETIMEDOUT"));
    assert_true(took < 4.0);   /* 0.2 s asked; the old wait was 5 s */
}

/* Runs seamtex with stdin and stdout on a pseudo-terminal (interactive mode prompts only on a
 * terminal), writes `input`, and collects what the terminal shows into OUT (input echo
 * included). Returns the exit status. */
static int run_on_a_tty(const char *const *args, const char *input)
{
    int m = posix_openpt(O_RDWR | O_NOCTTY);
    assert_true(m >= 0);
    assert_int_equal(grantpt(m), 0);
    assert_int_equal(unlockpt(m), 0);
    const char *slave = ptsname(m);
    assert_non_null(slave);
    const char *argv[16];
    int ac = 0;
    argv[ac++] = bin("seamtex");
    for (int i = 0; args[i] && ac < 15; i++)
        argv[ac++] = args[i];
    argv[ac] = NULL;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, slave, O_RDWR | O_NOCTTY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, slave, O_RDWR | O_NOCTTY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, ERRF, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addclose(&fa, m);
    pid_t pid;
    assert_int_equal(posix_spawn(&pid, argv[0], &fa, NULL, (char *const *)argv, environ), 0);
    posix_spawn_file_actions_destroy(&fa);
    assert_true(write(m, input, strlen(input)) == (ssize_t)strlen(input));
    size_t n = 0;
    for (;;) {                           /* EIO once the child closed the terminal */
        ssize_t r = read(m, OUT + n, sizeof OUT - 1 - n);
        if (r <= 0)
            break;
        n += (size_t)r;
    }
    OUT[n] = '\0';
    OUTLEN = n;
    close(m);
    int st;
    while (waitpid(pid, &st, 0) < 0)
        ;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/* The interactive prompt names the server as -h and -p give it; a unix: host has no port
 * (seamtex(1): "the port is then unused"), so none is shown (it printed ":7450"). The
 * prompt comes before any connection: no daemon is needed for it. */
static void the_prompt_names_a_unix_host_without_a_port(void **state)
{
    (void)state;
    assert_int_equal(run_on_a_tty((const char *const[]){ "-p", PORT, NULL }, "quit\n"), 0);
    char want[64];
    snprintf(want, sizeof want, "seamtex 127.0.0.1:%s> ", PORT);
    assert_non_null(strstr(OUT, want));
    assert_int_equal(run_on_a_tty((const char *const[]){ "-h", "unix:/nonexistent/seamtex.sock",
                                                         NULL }, "quit\n"), 0);
    assert_non_null(strstr(OUT, "seamtex unix:/nonexistent/seamtex.sock> "));
    assert_null(strstr(OUT, "sock:"));
}

/* A daemon with a token: a mutation without it is PERM (exit 1); with a wrong one the CLI
 * says that the token it sent was not accepted (the server's message asks for "the server's
 * token" either way); with the right one, from $SEAMTEX_TOKEN, it runs. */
static void a_wrong_token_is_named_as_such(void **state)
{
    (void)state;
    st_daemon t;
    assert_int_equal(st_daemon_init(&t), 0);
    const char *extra[] = {"--token", "s3cret", NULL};
    assert_int_equal(st_daemon_start(&t, extra), 0);
    char port[16];
    snprintf(port, sizeof port, "%d", t.port);
    int none = runv(bin("seamtex"), NULL,
                    (const char *const[]){ "-p", port, "delete", "default", NULL });
    int none_named = strstr(ERR, "PERM") && !strstr(ERR, "not accepted");
    int wrong = runv(bin("seamtex"), NULL,
                     (const char *const[]){ "-p", port, "-t", "guess", "delete", "default", NULL });
    int wrong_named = strstr(ERR, "PERM") && strstr(ERR, "was not accepted");
    setenv("SEAMTEX_TOKEN", "s3cret", 1);
    int right = runv(bin("seamtex"), NULL,
                     (const char *const[]){ "-p", port, "delete", "default", NULL });
    unsetenv("SEAMTEX_TOKEN");
    assert_int_equal(st_daemon_stop(&t, 10000), 0);
    st_daemon_cleanup(&t);
    assert_int_equal(none, 1);
    assert_true(none_named);
    assert_int_equal(wrong, 1);
    assert_true(wrong_named);
    assert_int_equal(right, 0);
}

/* A refused value is named with the option it was given to, not only answered with the
 * usage text (or, in seamtex-bench, as "--" for options without a letter). */
static void a_bad_value_names_its_option(void **state)
{
    (void)state;
    assert_int_equal(CLI("compress", "default", "x", "--level", "10"), 2);
    assert_non_null(strstr(ERR, "--level takes 0..9, not '10'"));
    assert_int_equal(CLI("fetch", "default", "x.ptx", "--format", "tiff"), 2);
    assert_non_null(strstr(ERR, "--format takes ptx, dds, exr, png or obj, not 'tiff'"));
    assert_int_equal(BENCH("--proto", "gopher"), 2);
    assert_non_null(strstr(ERR, "bad value for --proto: 'gopher'"));
    assert_int_equal(BENCH("--outfmt", "f64"), 2);
    assert_non_null(strstr(ERR, "bad value for --outfmt: 'f64'"));
    assert_int_equal(BENCH("-c", "0"), 2);
    assert_non_null(strstr(ERR, "bad value for -c: '0'"));
    /* options of --dir queries and of face queries, crossed: usage, refused before sending
     * (--lerp with --dir went to the server, whose INVALID made it exit 1) */
    assert_int_equal(CLI("sample", "default", "--dir", "1", "0", "0", "--lerp"), 2);
    assert_non_null(strstr(ERR, "--lerp is for face queries, not --dir"));
    assert_int_equal(CLI("sample", "default", "0", "0.5", "0.5", "--cone", "0.1"), 2);
    assert_non_null(strstr(ERR, "--cone is a footprint of --dir queries"));
}

/* ---- --json ------------------------------------------------------------------------------ */

/* OUT parsed strictly as one JSON document (UTF-8 validated, nothing after it but a newline). */
static json_object *out_json(void)
{
    json_tokener *tok = json_tokener_new();
    assert_non_null(tok);
    json_tokener_set_flags(tok, JSON_TOKENER_STRICT | JSON_TOKENER_VALIDATE_UTF8);
    json_object *o = json_tokener_parse_ex(tok, OUT, (int)OUTLEN);
    assert_int_equal(json_tokener_get_error(tok), json_tokener_success);
    size_t end = json_tokener_get_parse_end(tok);
    assert_true(end <= OUTLEN && strspn(OUT + end, "\n") == OUTLEN - end);  /* then only "\n" */
    assert_true(OUTLEN > 0 && OUT[OUTLEN - 1] == '\n');
    json_tokener_free(tok);
    assert_non_null(o);
    return o;
}

static json_object *jget(json_object *o, const char *key)
{
    json_object *v = NULL;
    if (!json_object_object_get_ex(o, key, &v))
        fail_msg("no key '%s' in the JSON output", key);
    return v;
}
#define JU(o, k) json_object_get_uint64(jget((o), (k)))
#define JI(o, k) json_object_get_int64(jget((o), (k)))
#define JS(o, k) json_object_get_string(jget((o), (k)))
#define JB(o, k) json_object_get_boolean(jget((o), (k)))

static stc_conn *lib_conn(void)
{
    int err = 0;
    stc_conn *c = stc_connect("127.0.0.1", (unsigned)D.port, 10000, &err);
    assert_non_null(c);
    return c;
}

static void ls_json_lists_what_the_library_lists(void **state)
{
    (void)state;
    assert_int_equal(CLI("ls", "--json"), 0);
    json_object *o = out_json();
    stc_conn *c = lib_conn();
    const stc_set_entry *s;
    size_t n;
    assert_int_equal(stc_list(c, &s, &n), 0);
    assert_int_equal(JU(o, "count"), n);
    json_object *sets = jget(o, "sets");
    assert_int_equal(json_object_array_length(sets), n);
    for (size_t i = 0; i < n; i++) {
        json_object *e = json_object_array_get_idx(sets, i);
        assert_string_equal(JS(e, "name"), s[i].name);
        assert_int_equal(JU(e, "channels"), s[i].nchan);
        assert_int_equal(JU(e, "faces"), s[i].nfaces);
        assert_true(JU(e, "memory_bytes") == s[i].memory);
    }
    stc_close(c);
    json_object_put(o);
    /* the text output names the same kinds and types */
    assert_int_equal(CLI("ls"), 0);
    assert_non_null(strstr(OUT, "default"));
    assert_non_null(strstr(OUT, " perface "));
    assert_non_null(strstr(OUT, " u8 "));
    assert_int_equal(CLI("ls", "--json"), 0);
    o = out_json();
    json_object *d = json_object_array_get_idx(jget(o, "sets"), 0);
    assert_string_equal(JS(d, "kind"), "perface");
    assert_string_equal(JS(d, "type"), "u8");
    json_object_put(o);
}

static void info_json_matches_the_text_and_the_library(void **state)
{
    (void)state;
    assert_int_equal(CLI("info", "default", "--faces", "2:3", "--json"), 0);
    json_object *o = out_json();
    stc_conn *c = lib_conn();
    stc_info in;
    assert_int_equal(stc_info_get(c, "default", 2, 3, &in), 0);
    assert_string_equal(JS(o, "name"), "default");
    assert_string_equal(JS(o, "kind"), "perface");
    assert_string_equal(JS(o, "type"), "u8");
    assert_string_equal(JS(o, "colorspace"), in.colorspace ? "srgb" : "linear");
    assert_string_equal(JS(o, "mesh"), "quad");
    assert_int_equal(JU(o, "faces"), in.nfaces);
    assert_int_equal(JU(o, "constant_faces"), in.nconstant);
    assert_int_equal(JU(o, "subfaces"), in.nsubfaces);
    assert_int_equal(JU(o, "channels"), in.nchan);
    assert_int_equal(JI(o, "alpha_channel"), in.alpha_chan);
    assert_int_equal(JB(o, "premultiplied"), in.premultiplied);
    assert_int_equal(JU(o, "min_width"), in.min_w);
    assert_int_equal(JU(o, "min_height"), in.min_h);
    assert_int_equal(JU(o, "max_width"), in.max_w);
    assert_int_equal(JU(o, "max_height"), in.max_h);
    assert_true(JU(o, "memory_bytes") == in.memory);
    assert_true(JU(o, "texel_bytes") == in.texel_bytes);
    assert_int_equal(JU(o, "boundary_edges"), in.boundary_edges);
    assert_int_equal(JU(o, "irregular_corners"), in.irregular_corners);
    assert_int_equal(JU(o, "max_valence"), in.max_valence);
    assert_int_equal(JU(o, "border_u"), in.border_u);
    assert_int_equal(JU(o, "border_v"), in.border_v);
    assert_int_equal(JU(o, "metadata_entries"), in.nmeta);
    json_object *recs = jget(o, "face_records");
    assert_int_equal(json_object_array_length(recs), 3);
    for (uint32_t i = 0; i < 3; i++) {
        json_object *r = json_object_array_get_idx(recs, i);
        assert_int_equal(JU(r, "face"), 2 + i);
        assert_int_equal(JU(r, "width"), in.faces[i].w);
        assert_int_equal(JU(r, "height"), in.faces[i].h);
        assert_int_equal(JU(r, "levels"), in.faces[i].nlevels);
        assert_int_equal(JB(r, "constant"), in.faces[i].flags & 1);
        json_object *adj = jget(r, "adjacent");
        assert_int_equal(json_object_array_length(adj), 4);
        for (int k = 0; k < 4; k++) {
            json_object *a = json_object_array_get_idx(adj, (size_t)k);
            assert_int_equal(JI(a, "face"), in.faces[i].adjface[k]);
            assert_int_equal(JU(a, "edge"), in.faces[i].adjface[k] < 0 ? 0 : in.faces[i].adjedge[k]);
        }
    }
    stc_close(c);
    /* the text says the same */
    char line[128];
    unsigned nfaces = (unsigned)JU(o, "faces");
    json_object_put(o);
    assert_int_equal(CLI("info", "default"), 0);
    snprintf(line, sizeof line, "faces:             %u (", nfaces);
    assert_non_null(strstr(OUT, line));
    /* without --faces there is no face_records key */
    assert_int_equal(CLI("info", "default", "--json"), 0);
    o = out_json();
    assert_false(json_object_object_get_ex(o, "face_records", NULL));
    json_object_put(o);
}

/* `stats --json` between two stc_stats calls: it has every key of the first and only keys of
 * the second (keys only appear: a latency bucket is listed once it is not empty); a value that
 * did not move between the two calls equals them exactly, one that moved lies between them;
 * the text output, taken after, has every key of the JSON. */
static void stats_json_has_every_counter_with_its_value(void **state)
{
    (void)state;
    stc_conn *c = lib_conn();
    const stc_stat *s;
    size_t n;
    assert_int_equal(stc_stats(c, &s, &n), 0);
    stc_stat *before = malloc(n * sizeof *before);
    char (*keys)[64] = malloc(n * sizeof *keys);
    assert_non_null(before);
    assert_non_null(keys);
    size_t nb = n;
    for (size_t i = 0; i < n; i++) {
        before[i] = s[i];
        snprintf(keys[i], sizeof keys[i], "%s", s[i].key);
        before[i].key = keys[i];
    }
    assert_int_equal(CLI("stats", "--json"), 0);
    json_object *o = out_json();
    assert_int_equal(stc_stats(c, &s, &n), 0);
    size_t nj = (size_t)json_object_object_length(o);
    assert_true(nj >= nb && nj <= n);
    json_object_object_foreach(o, jk, jv) {
        (void)jv;
        if (!stc_stat_find(s, n, jk))
            fail_msg("stats --json has '%s', which stc_stats after it has not", jk);
    }
    for (size_t i = 0; i < nb; i++) {
        const stc_stat *a = &before[i];
        json_object *v = jget(o, a->key);
        if (a->is_float)
            assert_true(json_object_is_type(v, json_type_double) ||
                        json_object_is_type(v, json_type_int) || json_object_is_type(v, json_type_null));
        else
            assert_true(json_object_is_type(v, json_type_int));
    }
    /* settings are exact; counters that only grow lie between the two library calls */
    static const char *const fixed[] = { "max_conns", "max_frame", "io_threads", "workers", "sets" };
    static const char *const growing[] = { "requests", "conns_accepted", "bytes_in", "bytes_out",
                                           "req_stats", "uptime_ms" };
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        const stc_stat *a = stc_stat_find(before, nb, fixed[i]), *b = stc_stat_find(s, n, fixed[i]);
        assert_non_null(a);
        assert_non_null(b);
        assert_true(a->u == b->u);
        assert_true(JU(o, fixed[i]) == a->u);
    }
    for (size_t i = 0; i < sizeof growing / sizeof growing[0]; i++) {
        const stc_stat *a = stc_stat_find(before, nb, growing[i]), *b = stc_stat_find(s, n, growing[i]);
        assert_non_null(a);
        assert_non_null(b);
        uint64_t x = JU(o, growing[i]);
        if (!(x >= a->u && x <= b->u))
            fail_msg("%s: %llu in the JSON, %llu before and %llu after", growing[i],
                     (unsigned long long)x, (unsigned long long)a->u, (unsigned long long)b->u);
    }
    assert_true(JU(o, "max_conns") == stc_stat_find(s, n, "max_conns")->u);
    stc_close(c);
    /* the text output has every key of the JSON, one per line */
    assert_int_equal(CLI("stats"), 0);
    size_t lines = 0;
    for (const char *p = OUT; (p = strchr(p, '\n')); p++)
        lines++;
    assert_true(lines >= nj);
    json_object_object_foreach(o, key, val) {
        (void)val;
        char k[80];
        snprintf(k, sizeof k, "\n%s ", key);
        if (strncmp(OUT, k + 1, strlen(k + 1)) != 0 && !strstr(OUT, k))
            fail_msg("'%s' of stats --json is not a line of the text output", key);
    }
    json_object_put(o);
    free(before);
    free(keys);
}

static void compress_json_reports_the_job_and_sizes(void **state)
{
    (void)state;
    assert_int_equal(CLI("compress", "default", "cli-json-bc1", "--level", "0", "--json"), 0);
    json_object *o = out_json();
    assert_true(JU(o, "job") > 0);
    assert_string_equal(JS(o, "source"), "default");
    assert_string_equal(JS(o, "target"), "cli-json-bc1");
    assert_int_equal(JU(o, "level"), 0);
    assert_true(JB(o, "seam_aware"));
    assert_false(JB(o, "replace"));
    assert_string_equal(JS(o, "state"), "done");
    assert_string_equal(JS(o, "result"), "OK");
    assert_non_null(strstr(JS(o, "message"), "seam RMS"));
    assert_true(json_object_get_double(jget(o, "seconds")) >= 0);
    stc_conn *c = lib_conn();
    stc_info a, b;
    assert_int_equal(stc_info_get(c, "default", 0, 0, &a), 0);
    assert_int_equal(stc_info_get(c, "cli-json-bc1", 0, 0, &b), 0);
    assert_int_equal(JU(o, "faces"), a.nfaces);
    assert_true(JU(o, "texel_bytes_before") == a.texel_bytes);
    assert_true(JU(o, "texel_bytes_after") == b.texel_bytes);
    assert_true(json_object_get_double(jget(o, "ratio")) ==
                (double)a.texel_bytes / (double)b.texel_bytes);
    stc_job job;
    assert_int_equal(stc_job_status(c, JU(o, "job"), &job), 0);
    assert_string_equal(JS(o, "message"), job.message);
    json_object_put(o);
    /* --no-wait: the job's id, which the library can wait on */
    assert_int_equal(CLI("-t", "x", "compress", "default", "cli-json-bc1", "--level", "0",
                         "--replace", "--no-wait", "--json"), 0);
    o = out_json();
    assert_true(JB(o, "replace"));
    assert_false(json_object_object_get_ex(o, "state", NULL));
    assert_int_equal(stc_job_wait(c, JU(o, "job"), 600000, &job), 0);
    json_object_put(o);
    assert_int_equal(stc_delete(c, "cli-json-bc1"), 0);
    stc_close(c);
}

/* --json leaves the exit codes as they are and writes nothing to stdout on an error. */
static void json_keeps_the_exit_codes(void **state)
{
    (void)state;
    assert_int_equal(CLI("info", "no-such-set", "--json"), 1);
    assert_int_equal(OUTLEN, 0);
    assert_non_null(strstr(ERR, "NOT_FOUND"));
    assert_int_equal(CLI("compress", "no-such-set", "x", "--json"), 1);
    assert_int_equal(OUTLEN, 0);
    assert_int_equal(CLI("ls", "--json", "extra"), 2);
    assert_int_equal(OUTLEN, 0);
    assert_int_equal(CLI("stats", "--jsn"), 2);
    assert_int_equal(CLI("ls", "--help"), 0);
    assert_non_null(strstr(OUT, "--json"));
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(fd >= 0);
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
    socklen_t al = sizeof a;
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &al), 0);
    char port[16];
    snprintf(port, sizeof port, "%u", ntohs(a.sin_port));
    close(fd);
    assert_int_equal(runv(bin("seamtex"), NULL,
                          (const char *const[]){ "-p", port, "stats", "--json", NULL }), 3);
    assert_int_equal(OUTLEN, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ping_prints_pong_and_exits_zero),
        cmocka_unit_test(ls_lists_the_default_set),
        cmocka_unit_test(info_describes_the_default_set),
        cmocka_unit_test(sample_one_query_prints_four_values_coverage_and_ok),
        cmocka_unit_test(sample_query_file_answers_every_line_in_each_mode),
        cmocka_unit_test(sample_reports_a_bad_face_per_query),
        cmocka_unit_test(sample_takes_negative_infinity_and_echoes_the_exact_query),
        cmocka_unit_test(sample_binary_writes_count_times_channels_floats),
        cmocka_unit_test(sample_compact_sends_the_rounded_queries),
        cmocka_unit_test(an_unknown_set_exits_1_with_the_servers_message),
        cmocka_unit_test(bad_usage_exits_2),
        cmocka_unit_test(no_server_exits_3),
        cmocka_unit_test(an_unwritable_output_exits_1),
        cmocka_unit_test(upload_ls_sample_delete_round_trip),
        cmocka_unit_test(sample_dir_answers_on_a_cube_map_and_refuses_other_sets),
        cmocka_unit_test(compress_reports_sizes_and_fetch_writes_a_ptex_file),
        cmocka_unit_test(commands_piped_on_stdin_share_one_connection),
        cmocka_unit_test(stats_prints_counters),
        cmocka_unit_test(bench_closed_loop_answers_every_request),
        cmocka_unit_test(bench_open_loop_sends_its_schedule_and_corrects_latency),
        cmocka_unit_test(bench_sample_batches_are_answered),
        cmocka_unit_test(bench_reports_its_cpu_over_the_measured_window),
        cmocka_unit_test(bench_sample_pipeline_with_a_low_water_mark_answers_every_request),
        cmocka_unit_test(bench_refuses_a_non_loopback_host),
        cmocka_unit_test(cluster_on_a_daemon_outside_a_cluster_exits_1_with_its_message),
        cmocka_unit_test(seamtex_port_from_the_environment_and_a_bad_one_refused),
        cmocka_unit_test(a_bad_value_names_its_option),
        cmocka_unit_test(timeout_bounds_the_connect_and_hello_too),
        cmocka_unit_test(the_prompt_names_a_unix_host_without_a_port),
        cmocka_unit_test(a_wrong_token_is_named_as_such),
        cmocka_unit_test(ls_json_lists_what_the_library_lists),
        cmocka_unit_test(info_json_matches_the_text_and_the_library),
        cmocka_unit_test(stats_json_has_every_counter_with_its_value),
        cmocka_unit_test(compress_json_reports_the_job_and_sizes),
        cmocka_unit_test(json_keeps_the_exit_codes),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
