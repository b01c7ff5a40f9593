/* tests/integration/test_faults_daemon.c - seamtexd with its data-dir calls failing one at a
 * time, end to end: UPLOAD (begin, chunks, commit) of a new name and replacing one, COMPRESS
 * storing its .dds, FETCH_OPEN.
 *
 * One daemon serves many injection points: it runs with tests/common/faultpreload.c preloaded
 * (SEAMTEX_FAULT_PATH = its data dir, so socket writes and the log never fail), and the test
 * arms it between requests by writing <ctl>/arm (SEAMTEX_FAULT_CTL; faultpreload.c reads it on
 * every call under the data dir and reports what it counted in <ctl>/state). For each kind
 * (open, write, fsync, rename) and errno (EIO, ENOSPC; also a short write for writes) the
 * operation is first run counting the calls, then again with the 1st, 2nd, ... Nth call
 * failing, until it no longer reaches N. At every point:
 *   - the reply is OK or a defined status (IO, NOMEM), never a dropped connection; a point
 *     that did not fire (or a short write) must succeed; with ENOSPC the message says so;
 *   - the daemon keeps serving: PING, a SAMPLE of the built-in set, LIST shows exactly the
 *     acknowledged sets, and the operation's target holds what was acknowledged (the new
 *     bytes after OK; after a failure the old bytes, or NOT_FOUND for a new name).
 * Every RESTART_EVERY points and after each operation the daemon is stopped (exit status 0)
 * and started again on the same data dir: every acknowledged set is listed and fetched back
 * byte for byte (the COMPRESS results as .dds, compared with the .dds fetched before any
 * restart), nothing else is listed, broken/ stays empty.
 * Each operation prints one "fault-table:" line (docs/daemon.md, "Fault injection").
 */
#include <errno.h>
#include <limits.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "../common/ptx_fixture.h"
#include "../common/daemon_client.h"
#include "../common/daemon_fixture.h"
#include "../common/testdata.h"
#include "fdio.h"
#include "ptex.h"
#include "set.h"

#define MAXSETS 512
#define RESTART_EVERY 32

static st_daemon D;
static stc_conn *C;
static char CTL[400], REALDD[PATH_MAX];
static long SESSION;
static void *PTX[2];
static size_t PTXLEN[2];
static unsigned RESTARTS;

typedef struct acked { char name[64]; int variant; } acked;   /* variant -1: a compress result */
static acked ACK[MAXSETS];
static int NACK;
static void *BC_REF;          /* the .dds the compress of "uni" gives, fetched before any restart */
static size_t BC_REF_LEN;

static const char *KINDS[] = {"open", "write", "fsync", "rename"};

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + t.tv_nsec / 1e9;
}

/* A small per-face set as .ptx (four 16x16 RGBA8 faces, no neighbours), texels from seed. */
static void *make_ptx(unsigned seed, size_t *len)
{
    st_set *s = st_fixture_rgba8_faces(16);
    if (!s)
        return NULL;
    st_error e;
    st_error_clear(&e);
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)(i * (13 + 2 * seed) + (i >> 6) + seed);
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0)
        buf = NULL;
    st_set_free(s);
    return buf;
}

static void arm(const char *kind, unsigned long n, const char *how)
{
    char path[500], text[128];
    snprintf(path, sizeof path, "%s/arm", CTL);
    snprintf(text, sizeof text, "%ld %s %lu %s\n", ++SESSION, kind, n, how);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
}

/* Disarms; returns the calls counted in this session, *fired whether the nth failed. */
static unsigned long disarm(int *fired)
{
    char path[500];
    snprintf(path, sizeof path, "%s/arm", CTL);
    unlink(path);
    snprintf(path, sizeof path, "%s/state", CTL);
    long s = -1;
    unsigned long n = 0;
    int f = 0;
    FILE *fp = fopen(path, "r");
    if (fp) {
        if (fscanf(fp, "%ld %lu %d", &s, &n, &f) != 3)
            s = -1;
        fclose(fp);
    }
    if (s != SESSION)
        n = 0, f = 0;
    *fired = f;
    return n;
}

static int find_ack(const char *name)
{
    for (int i = 0; i < NACK; i++)
        if (!strcmp(ACK[i].name, name))
            return i;
    return -1;
}

static void ack(const char *name, int variant)
{
    int i = find_ack(name);
    if (i < 0) {
        assert_true(NACK < MAXSETS);
        i = NACK++;
        snprintf(ACK[i].name, sizeof ACK[i].name, "%s", name);
    }
    ACK[i].variant = variant;
}

/* Fetches `name` in its acknowledged form; 1 when the bytes are the acknowledged ones. */
static int fetch_matches(const acked *a)
{
    char path[500];
    snprintf(path, sizeof path, "%s/fetched", D.dir);
    int rc = stc_fetch_file(C, a->name, a->variant < 0 ? STC_FETCH_DDS : STC_FETCH_PTX, path,
                            NULL, NULL);
    if (rc) {
        fprintf(stderr, "fetch '%s': %s (%s)\n", a->name, stc_strerror(rc), stc_errmsg(C));
        return 0;
    }
    const void *want = a->variant < 0 ? BC_REF : PTX[a->variant];
    size_t len = a->variant < 0 ? BC_REF_LEN : PTXLEN[a->variant];
    void *got = NULL;
    size_t n = 0;
    int same = stu_read_file(path, 1u << 30, &got, &n) == 0 && n == len && !memcmp(got, want, n);
    if (!same)
        fprintf(stderr, "set '%s': fetched %zu bytes, acknowledged %zu (differ)\n", a->name, n,
                len);
    free(got);
    unlink(path);
    return same;
}

typedef struct tally {
    unsigned long counted[4];
    unsigned points, lost, half;
    char statuses[200];
} tally;

static void note(tally *t, int rc)
{
    const char *s = rc ? stc_strerror(rc) : "OK";
    char pad[64], hay[210];
    snprintf(pad, sizeof pad, " %s ", s);
    snprintf(hay, sizeof hay, " %s ", t->statuses);
    if (!strstr(hay, pad))
        snprintf(t->statuses + strlen(t->statuses), sizeof t->statuses - strlen(t->statuses),
                 "%s%s", t->statuses[0] ? " " : "", s);
}

/* LIST shows exactly the acknowledged sets (and the built-in one). */
static void check_list(tally *t)
{
    const stc_set_entry *sets;
    size_t n;
    assert_int_equal(stc_list(C, &sets, &n), 0);
    int seen[MAXSETS] = {0};
    for (size_t i = 0; i < n; i++) {
        if (!strcmp(sets[i].name, "default"))
            continue;
        int k = find_ack(sets[i].name);
        if (k < 0) {
            fprintf(stderr, "set '%s' listed but never acknowledged\n", sets[i].name);
            t->half++;
        } else {
            seen[k] = 1;
        }
    }
    for (int k = 0; k < NACK; k++)
        if (!seen[k]) {
            fprintf(stderr, "acknowledged set '%s' is gone\n", ACK[k].name);
            t->lost++;
        }
}

/* PING and a SAMPLE of the built-in set. */
static void check_serving(void)
{
    assert_int_equal(stc_ping(C), 0);
    stc_sample_opts o = {.mode = 1, .filter = 1, .outfmt = STC_OUT_F32};
    stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    stc_sample_result r;
    assert_int_equal(stc_sample(C, "default", &o, &q, 1, &r), 0);
    assert_int_equal(r.count, 1);
}

/* Stop (clean exit), start on the same data dir, everything acknowledged is there whole,
 * nothing else is. */
static double T_STOP, T_START, T_CHECK;
static int VERIFIED;          /* ACK[0..VERIFIED) were fetched back whole after a restart and
                                 not written since (uni, kept and bc-ref are always fetched) */
static void restart_check(tally *t, int all)
{
    double t0 = now_s();
    if (C) {
        stc_close(C);
        C = NULL;
    }
    if (D.pid) {
        int st = st_daemon_stop(&D, 20000);
        if (st != 0)
            st_daemon_dump_log(&D, 30);
        assert_int_equal(st, 0);
    }
    double t1 = now_s();
    assert_int_equal(st_daemon_start(&D, NULL), 0);
    double t2 = now_s();
    RESTARTS++;
    C = st_daemon_client(&D, NULL);
    assert_non_null(C);
    check_list(t);
    for (int k = 0; k < NACK; k++)
        if ((all || k < 3 || k >= VERIFIED) && !fetch_matches(&ACK[k]))
            t->lost++;
    VERIFIED = NACK;
    char broken[600];
    snprintf(broken, sizeof broken, "%s/broken", D.datadir);
    assert_int_equal(st_test_dir_entries(broken), 0);
    assert_int_equal(t->lost, 0);
    assert_int_equal(t->half, 0);
    check_serving();
    T_STOP += t1 - t0;
    T_START += t2 - t1;
    T_CHECK += now_s() - t2;
}

/* the operations: 0 upload a new name, 1 upload replacing "kept", 2 compress, 3 fetch */
static int ROUND;
static char JOBMSG[1024];     /* a failed COMPRESS job's message */
static int op_run(int op, int *variant, char *name, size_t cap)
{
    ROUND++;
    if (op == 0 || op == 1) {
        /* a replace always sends the other variant, so a failed one must show the old bytes */
        *variant = op == 0 ? 0 : 1 - ACK[find_ack("kept")].variant;
        snprintf(name, cap, op == 0 ? "up-%d" : "kept", ROUND);
        stc_upload_opts o = {.hint = "ptx", .flags = op == 1 ? STC_UPLOAD_REPLACE : 0};
        stc_upload_result r;
        return stc_upload_buffer(C, PTX[*variant], PTXLEN[*variant], name, &o, &r);
    }
    if (op == 2) {
        *variant = -1;
        snprintf(name, cap, "bc-%d", ROUND);
        uint64_t job = 0;
        int rc = stc_compress(C, "uni", name, 0, 0, &job);
        snprintf(JOBMSG, sizeof JOBMSG, "%s", rc ? stc_errmsg(C) : "");
        if (rc)
            return rc;
        stc_job j;
        memset(&j, 0, sizeof j);
        rc = stc_job_wait(C, job, 60000, &j);
        snprintf(JOBMSG, sizeof JOBMSG, "%s", j.message);
        return rc;
    }
    name[0] = 0;
    char path[500];
    snprintf(path, sizeof path, "%s/fetched", D.dir);
    int rc = stc_fetch_file(C, "uni", STC_FETCH_PTX, path, NULL, NULL);
    unlink(path);
    return rc;
}

/* The target of the operation after it returned rc: acknowledged bytes, or absent. */
static void check_target(const char *name, int rc, tally *t)
{
    if (!name[0])
        return;
    int k = find_ack(name);
    if (k >= 0) {
        if (!fetch_matches(&ACK[k]))
            t->lost++;
    } else {
        char path[500];
        snprintf(path, sizeof path, "%s/fetched", D.dir);
        int frc = stc_fetch_file(C, name, STC_FETCH_PTX, path, NULL, NULL);
        unlink(path);
        if (frc != STC_ENOTFOUND) {
            fprintf(stderr, "'%s' failed (%s) but fetching it gives %s\n", name,
                    stc_strerror(rc), stc_strerror(frc));
            t->half++;
        }
    }
}

static void run_op(int op, const char *label)
{
    double t0 = now_s();
    unsigned r0 = RESTARTS;
    tally t = {0};
    int since = 0;
    for (int k = 0; k < 4; k++) {
        static const char *const hows[] = {"EIO", "ENOSPC", "short"};
        int nh = !strcmp(KINDS[k], "write") ? 3 : 2;
        for (int h = 0; h < nh; h++) {
            unsigned long cnt0 = 0;
            for (unsigned long n = 0;; n++) {
                char name[64] = "";
                int variant = 0;
                arm(KINDS[k], n, hows[h]);
                int rc = op_run(op, &variant, name, sizeof name);
                int fired;
                unsigned long cnt = disarm(&fired);
                const char *msg = op == 2 && stc_is_server_error(rc) ? JOBMSG : stc_errmsg(C);
                if (n == 0) {
                    cnt0 = cnt;
                    if (cnt > t.counted[k])
                        t.counted[k] = cnt;
                }
                if (rc && rc != STC_ESERVERIO && rc != STC_ESERVERNOMEM)
                    fprintf(stderr, "%s: %s #%lu %s: %s (%s)\n", label, KINDS[k], n, hows[h],
                            stc_strerror(rc), msg);
                assert_true(rc == 0 || rc == STC_ESERVERIO || rc == STC_ESERVERNOMEM);
                if (rc && (!fired || !strcmp(hows[h], "short")))
                    fprintf(stderr, "%s: %s #%lu %s: %s although %s (%s)\n", label, KINDS[k],
                            n, hows[h], stc_strerror(rc), fired ? "a short write" : "nothing failed",
                            msg);
                if (!fired || !strcmp(hows[h], "short"))
                    assert_int_equal(rc, 0);
                if (rc && !strcmp(hows[h], "ENOSPC") && !strcasestr(msg, "no space")) {
                    fprintf(stderr, "%s: %s #%lu ENOSPC: message '%s'\n", label, KINDS[k], n, msg);
                    fail();
                }
                note(&t, rc);
                if (rc == 0 && name[0])
                    ack(name, variant);
                check_serving();
                check_list(&t);
                check_target(name, rc, &t);
                assert_int_equal(t.lost, 0);
                assert_int_equal(t.half, 0);
                if (n > 0)
                    t.points++;
                if (++since >= RESTART_EVERY) {
                    restart_check(&t, 0);
                    since = 0;
                }
                if (n > 0 && !fired)
                    break;
                if (n == 0 && cnt == 0)
                    break;
                assert_true(n <= cnt0 + 2);
            }
        }
    }
    restart_check(&t, 1);
    /* the operation's sets were checked across a restart: delete them (unarmed), so that the
       next operation's restarts load a small data dir; the next restart shows none of them */
    for (int k = 3; k < NACK; k++)
        assert_int_equal(stc_delete(C, ACK[k].name), 0);
    NACK = VERIFIED = 3;
    printf("# fault-table: %-24s | calls open=%lu write=%lu fsync=%lu rename=%lu | points %u | "
           "statuses %s | sets lost %u | half-written visible %u | restarts %u | %.1f s\n",
           label, t.counted[0], t.counted[1], t.counted[2], t.counted[3], t.points, t.statuses,
           t.lost, t.half, RESTARTS - r0, now_s() - t0);
    printf("# timing so far: daemon stops %.1f s, starts %.1f s, restart checks %.1f s\n", T_STOP,
           T_START, T_CHECK);
    fflush(stdout);
}

static int group_setup(void **state)
{
    (void)state;
    PTX[0] = make_ptx(0, &PTXLEN[0]);
    PTX[1] = make_ptx(1, &PTXLEN[1]);
    if (!PTX[0] || !PTX[1] || st_daemon_init(&D) != 0)
        return -1;
    const char *b = getenv("SEAMTEX_BUILD");
    char so[PATH_MAX];
    snprintf(so, sizeof so, "%s/tests/libfaultpreload.so", b && *b ? b : "build");
    char abs_so[PATH_MAX];
    if (!realpath(so, abs_so)) {
        fprintf(stderr, "no %s (make tests-build)\n", so);
        return -1;
    }
    mkdir(D.datadir, 0700);
    if (!realpath(D.datadir, REALDD))
        return -1;
    snprintf(CTL, sizeof CTL, "%s/fault", D.dir);
    mkdir(CTL, 0700);
    /* only the daemon (spawned with this environment) gets the preload */
    setenv("LD_PRELOAD", abs_so, 1);
    setenv("SEAMTEX_FAULT_PATH", REALDD, 1);
    setenv("SEAMTEX_FAULT_CTL", CTL, 1);
    /* an ASan daemon accepts a preloaded object ahead of its runtime */
    const char *asan = getenv("ASAN_OPTIONS");
    char opts[1024];
    snprintf(opts, sizeof opts, "%s%sverify_asan_link_order=0", asan ? asan : "",
             asan && *asan ? ":" : "");
    setenv("ASAN_OPTIONS", opts, 1);
    if (st_daemon_start(&D, NULL) != 0)
        return -1;
    C = st_daemon_client(&D, NULL);
    if (!C)
        return -1;
    /* the sets the operations use, and the reference .dds (fetched before any restart) */
    stc_upload_opts o = {.hint = "ptx"};
    stc_upload_result r;
    int rc = stc_upload_buffer(C, PTX[0], PTXLEN[0], "uni", &o, &r);
    if (!rc)
        rc = stc_upload_buffer(C, PTX[1], PTXLEN[1], "kept", &o, &r);
    uint64_t job = 0;
    stc_job j;
    if (!rc)
        rc = stc_compress(C, "uni", "bc-ref", 0, 0, &job);
    if (!rc)
        rc = stc_job_wait(C, job, 60000, &j);
    char path[500];
    snprintf(path, sizeof path, "%s/ref.dds", D.dir);
    if (!rc)
        rc = stc_fetch_file(C, "bc-ref", STC_FETCH_DDS, path, NULL, NULL);
    if (!rc)
        rc = stu_read_file(path, 1u << 30, &BC_REF, &BC_REF_LEN);
    if (rc) {
        fprintf(stderr, "setup: %s (%s)\n", stc_strerror(rc), stc_errmsg(C));
        return -1;
    }
    ack("uni", 0);        /* ACK[0..2]: kept through every operation */
    ack("kept", 1);
    ack("bc-ref", -1);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    if (C)
        stc_close(C);
    unsetenv("LD_PRELOAD");
    int st = D.pid ? st_daemon_stop(&D, 20000) : 0;
    st_daemon_cleanup(&D);
    free(PTX[0]);
    free(PTX[1]);
    free(BC_REF);
    return st == 0 ? 0 : -1;
}

/* A restart before any fault: the COMPRESS result's .dds is the one served before it. */
static void test_compress_result_survives_a_restart(void **s)
{
    (void)s;
    tally t = {0};
    restart_check(&t, 1);
}

static void test_upload_new_name(void **s) { (void)s; run_op(0, "upload commit (new)"); }
static void test_upload_replace(void **s) { (void)s; run_op(1, "upload commit (replace)"); }
static void test_compress_result(void **s) { (void)s; run_op(2, "compress result (.dds)"); }
static void test_fetch_open(void **s) { (void)s; run_op(3, "fetch_open (ptx)"); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compress_result_survives_a_restart),
        cmocka_unit_test(test_upload_new_name),
        cmocka_unit_test(test_upload_replace),
        cmocka_unit_test(test_compress_result),
        cmocka_unit_test(test_fetch_open),
    };
    return cmocka_run_group_tests_name("faults_daemon", tests, group_setup, group_teardown);
}
