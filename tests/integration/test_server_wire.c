/* tests/integration/test_server_wire.c - how SAMPLE travels: connections spread over the I/O
 * threads (STATS io<i>_conns), compact queries and f16 replies (PROTOCOL.md 4.4.1) that sample
 * bit for bit like the f32 form of the rounded query, and the Unix socket listener (file mode
 * as access control, refused by the kernel for a user without permission; a stale socket
 * replaced; a live one or a non-socket file left alone; the file removed at exit; a 256 KiB
 * reply leaves in one write), and a pipeline deeper than a read's room answered in one write.
 *
 * With --pin-io each I/O thread runs on its own CPU (STATS io<i>_cpu, the kernel's affinity of
 * the threads) and samples what an unpinned daemon does.
 *
 * The first tests share one daemon with defaults (2 I/O threads, --heavy-batch 2048 so that
 * large batches run on a worker and split); the Unix-socket tests start their own.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <math.h>
#include <poll.h>
#include <setjmp.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/unix_daemon.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"

extern char **environ;

#define D1 ST_GROUP

/* ---- connections over I/O threads ------------------------------------------------------------ */

static void connections_land_on_different_io_threads(void **state)
{
    (void)state;
    stc_conn *c[4];
    c[0] = st_daemon_client(&D1, NULL);
    assert_non_null(c[0]);
    /* earlier connections (the fixture's probe) are gone once conns_current is 1 */
    assert_int_equal(st_wait_stat(&D1, c[0], "conns_current", ST_STAT_EQ, 1, 10000), 0);
    c[1] = st_daemon_client(&D1, NULL);
    assert_non_null(c[1]);
    assert_int_equal(st_wait_stat(&D1, c[0], "conns_current", ST_STAT_EQ, 2, 10000), 0);
    assert_int_equal(st_conn_stat(c[0], "io_threads"), 2);
    assert_int_equal(st_conn_stat(c[0], "io0_conns"), 1);
    assert_int_equal(st_conn_stat(c[0], "io1_conns"), 1);
    c[2] = st_daemon_client(&D1, NULL);
    c[3] = st_daemon_client(&D1, NULL);
    assert_non_null(c[2]);
    assert_non_null(c[3]);
    assert_int_equal(st_wait_stat(&D1, c[0], "conns_current", ST_STAT_EQ, 4, 10000), 0);
    assert_int_equal(st_conn_stat(c[0], "io0_conns"), 2);
    assert_int_equal(st_conn_stat(c[0], "io1_conns"), 2);
    assert_true(st_conn_stat(c[0], "io0_accepted") >= 2);
    assert_true(st_conn_stat(c[0], "io1_accepted") >= 2);
    /* every connection works wherever it landed */
    for (int i = 0; i < 4; i++)
        assert_int_equal(stc_ping(c[i]), 0);
    for (int i = 0; i < 4; i++)
        stc_close(c[i]);
}

/* ---- compact queries and f16 replies ----------------------------------------------------------- */

typedef struct result_copy {
    uint32_t count, nbad;
    unsigned nchan, outfmt;
    float   *values, *coverage;
    uint8_t *status;
} result_copy;

static void copy_result(const stc_sample_result *r, result_copy *o)
{
    o->count = r->count;
    o->nbad = r->nbad;
    o->nchan = r->nchan;
    o->outfmt = r->outfmt;
    size_t nv = (size_t)r->count * r->nchan;
    o->values = malloc((nv ? nv : 1) * sizeof(float));
    o->coverage = malloc((r->count ? r->count : 1) * sizeof(float));
    o->status = malloc(r->count ? r->count : 1);
    memcpy(o->values, r->values, nv * sizeof(float));
    assert_non_null(r->coverage);
    assert_non_null(r->status);
    memcpy(o->coverage, r->coverage, r->count * sizeof(float));
    memcpy(o->status, r->status, r->count);
}

static void free_result(result_copy *o)
{
    free(o->values);
    free(o->coverage);
    free(o->status);
}

/* got has n results equal, bit for bit, to want's (values, coverage, status, nbad) */
static void assert_same_result(const result_copy *got, const result_copy *want, size_t n)
{
    assert_int_equal(got->count, n);
    assert_int_equal(got->nbad, want->nbad);
    assert_memory_equal(got->values, want->values, (size_t)n * want->nchan * sizeof(float));
    assert_memory_equal(got->coverage, want->coverage, (size_t)n * sizeof(float));
    assert_memory_equal(got->status, want->status, n);
}

static void compact_queries_sample_like_f32_of_the_rounded_query(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    assert_true(stc_server_info(c)->caps & STP_CAP_COMPACT);
    static const unsigned modes[] = {STP_MODE_DISCARD, STP_MODE_TRAVERSE, STP_MODE_CLAMP};
    static const unsigned filters[] = {STP_FILTER_POINT, STP_FILTER_BILINEAR,
                                       STP_FILTER_TRILINEAR, STP_FILTER_ANISO,
                                       STP_FILTER_PTEX_BILINEAR};
    static const size_t sizes[] = {1, 300, 5000};   /* inline; on a worker and split */
    static const unsigned layouts[] = {STP_SF_UV16 | STP_SF_FACE16, STP_SF_UV16, STP_SF_FACE16};
    size_t checked = 0, bad = 0;
    for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++) {
        size_t n = sizes[si];
        stc_query *q = st_default_set_queries(n, 17u + (uint32_t)n);
        stc_query *rounded = calloc(n, sizeof *rounded);
        for (size_t li = 0; li < sizeof layouts / sizeof layouts[0]; li++) {
            unsigned lay = layouts[li];
            for (size_t i = 0; i < n; i++) {
                _Static_assert(sizeof(stc_query) == sizeof(stp_query), "query layouts");
                stp_query in, out;
                memcpy(&in, &q[i], sizeof in);
                stp_query_round(&in, lay, &out);
                memcpy(&rounded[i], &out, sizeof out);
            }
            for (size_t mi = 0; mi < 3; mi++)
                for (size_t fi = 0; fi < sizeof filters / sizeof filters[0]; fi++) {
                    stc_sample_opts o;
                    memset(&o, 0, sizeof o);
                    o.mode = modes[mi];
                    o.filter = filters[fi];
                    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
                    stc_sample_result r;
                    result_copy ref, got;
                    assert_int_equal(stc_sample(c, "default", &o, rounded, n, &r), 0);
                    copy_result(&r, &ref);
                    o.want |= lay;
                    assert_int_equal(stc_sample(c, "default", &o, q, n, &r), 0);
                    copy_result(&r, &got);
                    assert_same_result(&got, &ref, n);
                    free_result(&got);
                    /* f16 replies: the f32 values rounded to binary16 (NaN stays NaN) */
                    o.outfmt = STC_OUT_F16;
                    assert_int_equal(stc_sample(c, "default", &o, q, n, &r), 0);
                    assert_int_equal(r.outfmt, STC_OUT_F16);
                    const float *hv = r.values;
                    for (size_t k = 0; k < n * ref.nchan; k++) {
                        float want = stp_f16_to_f32(stp_f32_to_f16(ref.values[k]));
                        if (isnan(want))
                            assert_true(isnan(hv[k]));
                        else
                            assert_memory_equal(&hv[k], &want, sizeof want);
                    }
                    checked += n;
                    bad += ref.nbad;
                    free_result(&ref);
                }
        }
        free(rounded);
        free(q);
    }
    assert_true(bad > 0 && bad < checked);   /* the bad faces and NaNs were in there */
    stc_close(c);
}

/* ---- pin-io: I/O threads pinned to CPUs -------------------------------------------------------- */

/* Threads of `pid` allowed on exactly one CPU. */
static int single_cpu_threads(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
    DIR *d = opendir(path);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        cpu_set_t m;
        CPU_ZERO(&m);
        if (sched_getaffinity(atoi(e->d_name), sizeof m, &m) == 0 && CPU_COUNT(&m) == 1)
            n++;
    }
    closedir(d);
    return n;
}

static void pin_io_pins_each_io_thread_and_samples_the_same(void **state)
{
    (void)state;
    cpu_set_t mask;
    CPU_ZERO(&mask);
    assert_int_equal(sched_getaffinity(0, sizeof mask, &mask), 0);   /* the daemon inherits it */
    int ncpu = CPU_COUNT(&mask), cpus[CPU_SETSIZE], k = 0;
    for (int i = 0; i < CPU_SETSIZE; i++)
        if (CPU_ISSET(i, &mask))
            cpus[k++] = i;
    /* unpinned by default: no io<i>_cpu */
    stc_conn *ref = st_daemon_client(&D1, NULL);
    assert_non_null(ref);
    assert_int_equal(st_conn_stat(ref, "io0_cpu"), UINT64_MAX);

    st_daemon d;
    static const char *const args[] = {"--pin-io", "yes", "--io-threads", "3", "--heavy-batch",
                                       "2048", NULL};
    assert_int_equal(st_daemon_up(&d, args), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    /* thread i on the i-th CPU of the mask, wrapping around */
    for (unsigned i = 0; i < 3; i++) {
        char key[16];
        snprintf(key, sizeof key, "io%u_cpu", i);
        assert_int_equal(st_conn_stat(c, key), (uint64_t)cpus[i % (unsigned)ncpu]);
    }
    assert_int_equal(st_conn_stat(c, "io3_cpu"), UINT64_MAX);
    /* and the kernel holds them there: three threads on one CPU each (every thread is, on a
     * one-CPU machine) */
    if (ncpu > 1)
        assert_int_equal(single_cpu_threads(d.pid), 3);
    /* the same values as the unpinned daemon: inline, on a worker, split */
    static const size_t sizes[] = {300, 5000};
    for (size_t si = 0; si < 2; si++) {
        size_t n = sizes[si];
        stc_query *q = st_default_set_queries(n, 5u + (uint32_t)n);
        stc_sample_opts o;
        memset(&o, 0, sizeof o);
        o.mode = STP_MODE_TRAVERSE;
        o.filter = STP_FILTER_BILINEAR;
        o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
        stc_sample_result r;
        result_copy want, got;
        assert_int_equal(stc_sample(ref, "default", &o, q, n, &r), 0);
        copy_result(&r, &want);
        assert_int_equal(stc_sample(c, "default", &o, q, n, &r), 0);
        copy_result(&r, &got);
        assert_same_result(&got, &want, n);
        free_result(&want);
        free_result(&got);
        free(q);
    }
    stc_close(c);
    stc_close(ref);
    assert_int_equal(st_daemon_down(&d, 30000), 0);
}

static void compact_flags_on_sample_dir_are_invalid(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.filter = STP_FILTER_BILINEAR;
    o.want = STC_WANT_UV16;
    stc_dir_query d;
    memset(&d, 0, sizeof d);
    d.dir[0] = 1;
    stc_sample_result r;
    assert_int_equal(stc_sample_dir(c, "default", &o, &d, 1, &r), STC_EINVALID);
    assert_non_null(strstr(stc_errmsg(c), "SAMPLE only"));
    assert_int_equal(stc_ping(c), 0);        /* the connection is fine */
    stc_close(c);
}

/* ---- the Unix socket listener ------------------------------------------------------------------ */

static void unix_socket_serves_with_its_mode_and_is_removed_at_exit(void **state)
{
    st_unix_daemon *u = *state;
    assert_int_equal(st_unix_start(u, "0660"), 0);
    struct stat st;
    assert_int_equal(lstat(u->sock, &st), 0);
    assert_true(S_ISSOCK(st.st_mode));
    assert_int_equal(st.st_mode & 0777, 0660);
    stc_opts o;
    memset(&o, 0, sizeof o);
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts(u->addr, 0, &o, &err, msg, sizeof msg);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    stc_query q = {3, 0.25f, 0.75f, 0.01f, 0, 0, 0.01f};
    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    so.filter = STP_FILTER_BILINEAR;
    stc_sample_result r;
    assert_int_equal(stc_sample(c, "default", &so, &q, 1, &r), 0);
    assert_int_equal(r.count, 1);
    assert_int_equal(r.nbad, 0);
    stc_close(c);
    assert_int_equal(st_unix_stop(u), 0);
    assert_int_equal(lstat(u->sock, &st), -1);   /* removed at exit */
    assert_int_equal(errno, ENOENT);
}

/* The kernel's net.core.wmem_max, or 0 when it cannot be read. */

/* ---- a pipeline deeper than the read room ------------------------------------------------------ */

/* Reads n bytes whole from a blocking socket, waiting at most 20 s for each piece. 0 or -1. */
static int st_read_exact(int fd, void *p, size_t n)
{
    uint8_t *d = p;
    while (n) {
        struct pollfd pfd = {fd, POLLIN, 0};
        if (poll(&pfd, 1, 20000) <= 0)
            return -1;
        ssize_t r = read(fd, d, n);
        if (r <= 0)
            return -1;
        d += r;
        n -= (size_t)r;
    }
    return 0;
}

/* 8 SAMPLE requests of 256 queries (57 KiB) sent in one write reach the daemon at once but
 * are more than a read's room (32 KiB): the I/O thread reads again while a read fills all
 * its room (io.c, conn_readable) and answers the 8 in one write; before, it answered the
 * first read's frames, went back to epoll, read the rest and wrote again (2 writes a burst).
 * From the second burst on, the first read of a wake-up is offered the room the last one
 * needed (io.c, read_hint): one read a burst, where the 32 KiB room took two. Every reply
 * comes back whole and in order. Counted in STATS writes and reads: the first STATS reply
 * follows the first snapshot (one write more than the bursts'), the second STATS request is
 * read before its snapshot (one read more); the first burst takes two reads. The client's
 * send buffer is set large so that each burst leaves in one segment. */
static void deep_pipeline_is_read_at_once_and_answered_in_one_write(void **state)
{
    (void)state;
    enum { DEPTH = 8, N = 256, ROUNDS = 20 };
    stc_conn *sc = st_daemon_client(&D1, NULL);
    assert_non_null(sc);
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    int sndbuf = 1 << 20;
    setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf);
    stc_query *q = st_default_set_queries(N, 7);
    assert_non_null(q);
    stp_buf b;
    stp_buf_init(&b);
    stp_sample_req r;
    memset(&r, 0, sizeof r);
    snprintf(r.p.name, sizeof r.p.name, "default");
    r.p.mode = STP_MODE_TRAVERSE;
    r.p.filter = STP_FILTER_BILINEAR;
    r.count = N;
    _Static_assert(sizeof(stc_query) == sizeof(stp_query), "query layouts differ");
    r.queries = (const stp_query *)q;
    for (uint32_t k = 0; k < DEPTH; k++)
        assert_int_equal(stp_enc_sample_req(&b, k + 1, 0, &r), 0);
    assert_true(stp_buf_avail(&b) > 48u << 10);
    size_t cap = 64u << 10;
    uint8_t *in = malloc(cap);
    assert_non_null(in);
    uint64_t w0 = st_conn_stat(sc, "writes");
    uint64_t r0 = st_conn_stat(sc, "reads");
    for (int round = 0; round < ROUNDS; round++) {
        assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
        for (uint32_t k = 0; k < DEPTH; k++) {
            uint8_t hdr[STP_HEADER_SIZE];
            assert_int_equal(st_read_exact(fd, hdr, sizeof hdr), 0);
            stp_header h;
            int reason = 0;
            assert_int_equal(stp_parse_header(hdr, sizeof hdr, cap, &h, &reason), STP_OK);
            assert_int_equal(h.reqid, k + 1);
            assert_int_equal(h.status, STP_S_OK);
            assert_true(h.body_len > 4u * N);
            assert_int_equal(st_read_exact(fd, in, h.body_len), 0);
        }
    }
    uint64_t w1 = st_conn_stat(sc, "writes");
    uint64_t r1 = st_conn_stat(sc, "reads");
    assert_true(w1 - w0 <= ROUNDS + 1 + 2);   /* 2 to spare: not 2 a round */
    /* ROUNDS + 2 when every burst arrives whole; a burst the kernel delivers in two pieces
     * takes two wake-ups. Before the hint: at least 2 * ROUNDS. */
    assert_true(r1 - r0 < 2 * ROUNDS * 3 / 4);
    free(in);
    free(q);
    stp_buf_free(&b);
    close(fd);
    stc_close(sc);
}

static long wmem_max(void)
{
    FILE *f = fopen("/proc/sys/net/core/wmem_max", "r");
    long v = 0;
    if (f) {
        if (fscanf(f, "%ld", &v) != 1)
            v = 0;
        fclose(f);
    }
    return v;
}

/* A Unix stream socket's in-flight bytes are bounded by the sender's send buffer (208 KiB by
 * default): the daemon asks for more (unixaddr.h), so a 16384-query reply (256 KiB of RGBA
 * f32) leaves in one send instead of two or more with waits for EPOLLOUT between them.
 * Counted in STATS writes: the STATS reply after the first snapshot, then the SAMPLE reply. */
static void unix_big_reply_leaves_in_one_write(void **state)
{
    st_unix_daemon *u = *state;
    enum { N = 16384 };
    /* the buffer the kernel grants is twice the request, capped at wmem_max (doubled) */
    if (2 * wmem_max() < 2L * N * 4 * 4)
        skip();
    assert_int_equal(st_unix_start(u, "0600"), 0);
    stc_opts o;
    memset(&o, 0, sizeof o);
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts(u->addr, 0, &o, &err, msg, sizeof msg);
    assert_non_null(c);
    stc_query *q = calloc(N, sizeof *q);
    assert_non_null(q);
    for (unsigned i = 0; i < N; i++)
        q[i] = (stc_query){i % 6, (float)(i % 128) / 128.0f, (float)(i / 128) / 128.0f, 0.001f,
                           0, 0, 0.001f};
    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    so.filter = STP_FILTER_BILINEAR;
    stc_sample_result r;
    assert_int_equal(stc_sample(c, "default", &so, q, N, &r), 0);   /* buffers grown */
    uint64_t w0 = st_conn_stat(c, "writes");
    assert_int_equal(stc_sample(c, "default", &so, q, N, &r), 0);
    assert_int_equal(r.count, N);
    assert_int_equal(r.nchan, 4);
    uint64_t w1 = st_conn_stat(c, "writes");
    assert_int_equal(w1 - w0, 2);
    free(q);
    stc_close(c);
    assert_int_equal(st_unix_stop(u), 0);
}

static void unix_socket_mode_is_the_access_control(void **state)
{
    st_unix_daemon *u = *state;
    char errpath[290], cli[512];
    snprintf(errpath, sizeof errpath, "%.250s/cli.err", u->d.dir);
    snprintf(cli, sizeof cli, "%s/seamtex", st_build_dir());
    if (geteuid() != 0) {
        /* not root: the owner itself has no write permission on a 0000 socket */
        assert_int_equal(st_unix_start(u, "0000"), 0);
        int err = 0;
        char msg[256];
        stc_conn *c = stc_connect_opts(u->addr, 0, NULL, &err, msg, sizeof msg);
        assert_null(c);
        assert_int_equal(err, STC_ECONNECT);
        assert_non_null(strstr(msg, strerror(EACCES)));
        assert_int_equal(st_unix_stop(u), 0);
        return;
    }
    /* root passes every permission check: the client runs as nobody (setpriv) instead */
    const char *probe[] = {"setpriv", "--help", NULL};
    if (st_run(probe, errpath, NULL) != 0)
        skip();
    char abs_cli[600];
    if (!realpath(cli, abs_cli))
        skip();
    const char *as_nobody[] = {"setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                               abs_cli, "-h", u->addr, "ping", NULL};
    assert_int_equal(st_unix_start(u, "0600"), 0);
    unlink(errpath);
    assert_int_equal(st_run(as_nobody, errpath, NULL), 3);   /* 3: connection failed */
    st_unix_daemon probe_err = *u;
    snprintf(probe_err.d.log, sizeof probe_err.d.log, "%s", errpath);
    assert_true(st_unix_log_has(&probe_err, strerror(EACCES)));
    assert_int_equal(st_unix_stop(u), 0);
    /* the same user gets in once the mode lets others write */
    assert_int_equal(st_unix_start(u, "0666"), 0);
    assert_int_equal(st_run(as_nobody, errpath, NULL), 0);
    assert_int_equal(st_unix_stop(u), 0);
}

static void unix_stale_socket_is_replaced_live_one_and_files_are_not(void **state)
{
    st_unix_daemon *u = *state;
    /* a socket file nobody listens on: what a killed daemon leaves */
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    struct sockaddr_un sa;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    assert_true(strlen(u->sock) < sizeof sa.sun_path);
    memcpy(sa.sun_path, u->sock, strlen(u->sock) + 1);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    close(fd);
    assert_int_equal(st_unix_start(u, "0600"), 0);
    assert_true(st_unix_log_has(u, "removed a stale socket"));
    /* a second daemon on the same path refuses: the first is alive */
    st_unix_daemon second = *u;
    assert_true(st_unix_start(&second, "0600") > 0);
    assert_true(st_unix_log_has(u, "another server is listening"));
    stc_conn *c = stc_connect_opts(u->addr, 0, NULL, NULL, NULL, 0);
    assert_non_null(c);                       /* the first still serves */
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    assert_int_equal(st_unix_stop(u), 0);
    /* a regular file at the path is not ours to remove */
    FILE *f = fopen(u->sock, "w");
    assert_non_null(f);
    fputs("keep me\n", f);
    fclose(f);
    assert_true(st_unix_start(u, "0600") > 0);
    assert_true(st_unix_log_has(u, "exists and is not a socket"));
    struct stat st;
    assert_int_equal(lstat(u->sock, &st), 0);
    assert_true(S_ISREG(st.st_mode));
    unlink(u->sock);
}

int main(void)
{
    const struct CMUnitTest group[] = {
        cmocka_unit_test(connections_land_on_different_io_threads),
        cmocka_unit_test(compact_queries_sample_like_f32_of_the_rounded_query),
        cmocka_unit_test(compact_flags_on_sample_dir_are_invalid),
        cmocka_unit_test(pin_io_pins_each_io_thread_and_samples_the_same),
        cmocka_unit_test(deep_pipeline_is_read_at_once_and_answered_in_one_write),
    };
    const struct CMUnitTest unix_tests[] = {
        cmocka_unit_test_setup_teardown(unix_socket_serves_with_its_mode_and_is_removed_at_exit,
                                        st_unix_setup, st_unix_teardown),
        cmocka_unit_test_setup_teardown(unix_socket_mode_is_the_access_control, st_unix_setup,
                                        st_unix_teardown),
        cmocka_unit_test_setup_teardown(unix_big_reply_leaves_in_one_write, st_unix_setup,
                                        st_unix_teardown),
        cmocka_unit_test_setup_teardown(unix_stale_socket_is_replaced_live_one_and_files_are_not,
                                        st_unix_setup, st_unix_teardown),
    };
    static const char *const args[] = {"--heavy-batch", "2048", NULL};
    st_group_args = args;
    int rc = cmocka_run_group_tests_name("server_wire", group, st_group_setup,
                                         st_group_teardown);
    rc |= cmocka_run_group_tests_name("server_wire_unix", unix_tests, NULL, NULL);
    return rc;
}
