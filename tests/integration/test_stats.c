/* tests/integration/test_stats.c - seamtexd's per-opcode STATS keys (server/opstats.c):
 * requests, errors and the latency histogram counted per opcode, inline and on a worker.
 *
 * Owns: these behaviours only; the other STATS keys are checked in test_server.c. Each test
 * starts its own daemon (tests/common/daemon_fixture.h) on 127.0.0.1 port 0. Nothing here
 * needs SEAMTEX_DATA.
 */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_fixture.h"
#include "proto.h"
#include "seamtex.h"

static stc_conn *conn_to(const st_daemon *d)
{
    int err = 0;
    stc_conn *c = stc_connect(d->host, (unsigned)d->port, 20000, &err);
    if (!c)
        fprintf(stderr, "connect: %s\n", stc_strerror(err));
    return c;
}

static uint64_t stat_u(const stc_stat *st, size_t n, const char *key)
{
    const stc_stat *s = stc_stat_find(st, n, key);
    if (!s) {
        fprintf(stderr, "STATS has no key %s\n", key);
        fail();
    }
    return s->u;
}

/* Sum of the histogram buckets op_<op>_lat_*, and how many buckets were listed. */
static uint64_t hist_sum(const stc_stat *st, size_t n, const char *op, int *nbuckets)
{
    char prefix[64];
    snprintf(prefix, sizeof prefix, "op_%s_lat_", op);
    uint64_t sum = 0;
    *nbuckets = 0;
    for (size_t i = 0; i < n; i++)
        if (!strncmp(st[i].key, prefix, strlen(prefix))) {
            assert_true(st[i].u > 0);   /* empty buckets are left out */
            sum += st[i].u;
            (*nbuckets)++;
        }
    return sum;
}

static int write_all(int fd, const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = send(fd, p, n, MSG_NOSIGNAL);
        if (w <= 0)
            return -1;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

static int read_all(int fd, uint8_t *p, size_t n)
{
    while (n) {
        ssize_t r = recv(fd, p, n, 0);
        if (r <= 0)
            return -1;
        p += r;
        n -= (size_t)r;
    }
    return 0;
}

/* Sends m INFO requests with an empty body (malformed: INFO needs a name), pipelined on a raw
 * connection without HELLO, and checks each is answered BAD_REQUEST. */
static void send_bad_infos(const st_daemon *d, unsigned m)
{
    int fd = st_daemon_connect(d);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    for (unsigned i = 0; i < m; i++)
        stp_enc_empty(&b, STP_OP_INFO, 0, 100 + i, 0);
    assert_int_equal(write_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    stp_buf_free(&b);
    for (unsigned i = 0; i < m; i++) {
        uint8_t hdr[STP_HEADER_SIZE];
        assert_int_equal(read_all(fd, hdr, sizeof hdr), 0);
        stp_header h;
        int reason = 0;
        assert_int_equal(stp_parse_header(hdr, sizeof hdr, 1 << 20, &h, &reason), STP_OK);
        assert_int_equal(h.opcode, STP_OP_INFO);
        assert_int_equal(h.reqid, 100 + i);
        assert_int_equal(h.status, STP_S_BAD_REQUEST);
        uint8_t body[1024];
        assert_true(h.body_len <= sizeof body);
        assert_int_equal(read_all(fd, body, h.body_len), 0);
    }
    close(fd);
}

static void ping_and_bad_info_counts_are_exact(void **state)
{
    (void)state;
    enum { N = 37, M = 5 };
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    stc_conn *c = conn_to(&d);
    assert_non_null(c);
    for (int i = 0; i < N; i++)
        assert_int_equal(stc_ping(c), 0);
    send_bad_infos(&d, M);

    const stc_stat *st = NULL;
    size_t n = 0;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stat_u(st, n, "op_ping_requests"), N);
    assert_int_equal(stat_u(st, n, "op_ping_errors"), 0);
    assert_int_equal(stat_u(st, n, "req_ping"), N);
    assert_int_equal(stat_u(st, n, "op_info_requests"), M);
    assert_int_equal(stat_u(st, n, "op_info_errors"), M);
    assert_int_equal(stat_u(st, n, "op_hello_requests"), 1);
    /* the STATS request being answered is counted once its reply is queued */
    assert_int_equal(stat_u(st, n, "op_stats_requests"), 0);
    assert_int_equal(stat_u(st, n, "op_sample_requests"), 0);
    assert_null(stc_stat_find(st, n, "op_sample_p50_us"));   /* no requests: no latency keys */
    int nb = 0;
    assert_int_equal(hist_sum(st, n, "ping", &nb), N);
    assert_true(nb >= 1);
    assert_int_equal(hist_sum(st, n, "info", &nb), M);
    assert_int_equal(hist_sum(st, n, "sample", &nb), 0);
    assert_int_equal(nb, 0);
    uint64_t p50 = stat_u(st, n, "op_ping_p50_us"), p99 = stat_u(st, n, "op_ping_p99_us");
    assert_true(p50 >= 1 && p50 <= p99);
    assert_true(p99 < 60u * 1000 * 1000);

    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stat_u(st, n, "op_stats_requests"), 1);
    assert_int_equal(stat_u(st, n, "op_stats_errors"), 0);
    assert_int_equal(hist_sum(st, n, "stats", &nb), 1);
    assert_int_equal(nb, 1);
    assert_int_equal(stat_u(st, n, "op_ping_requests"), N);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

/* The largest buffer TCP autotuning may give a socket: the third field of
 * /proc/sys/net/ipv4/tcp_rmem or tcp_wmem (4 MiB when it cannot be read). */
static size_t tcp_buf_max(const char *path)
{
    unsigned long lo = 0, def = 0, max = 0;
    FILE *f = fopen(path, "r");
    int ok = f && fscanf(f, "%lu %lu %lu", &lo, &def, &max) == 3;
    if (f)
        fclose(f);
    return ok && max > 0 ? (size_t)max : (size_t)4 << 20;
}

/* Many pipelined PINGs with a payload (echoed back) and bad INFOs in between, read slowly
 * through a small receive buffer: the server's output buffer is partly sent and compacted
 * while replies are appended, and each reply is still found and counted right. */
static void counts_stay_exact_when_replies_back_up(void **state)
{
    (void)state;
    enum { EVERY = 10, PAY = 1000 };
    /* more requests than the kernel can buffer (the daemon's receive buffer, autotuned up to
     * tcp_rmem's maximum, 32 MiB on some hosts, its send buffer and ours) on top of
     * conn-out-cap: the writes must stall whatever the host's TCP settings */
    size_t room = tcp_buf_max("/proc/sys/net/ipv4/tcp_rmem") +
                  2 * tcp_buf_max("/proc/sys/net/ipv4/tcp_wmem") + ((size_t)1 << 20);
    unsigned TOTAL = (unsigned)(room / PAY * 5 / 4);
    if (TOTAL < 20000)
        TOTAL = 20000;
    const char *extra[] = {"--conn-out-cap", "256K", NULL};
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    int small = 32 * 1024;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    stp_buf b;
    stp_buf_init(&b);
    uint8_t pay[PAY];
    memset(pay, 0x5C, sizeof pay);
    unsigned nbad = 0;
    for (unsigned i = 0; i < TOTAL; i++) {
        if (i % EVERY == EVERY - 1) {
            stp_enc_empty(&b, STP_OP_INFO, 0, i, 0);
            nbad++;
        } else {
            size_t at = stp_frame_begin(&b, STP_OP_PING, 0, i, 0, 0);
            stp_put_bytes(&b, pay, sizeof pay);
            stp_frame_end(&b, at);
        }
    }
    assert_int_equal(b.err, 0);
    const uint8_t *out = stp_buf_head(&b);
    size_t left = stp_buf_avail(&b), have = 0;
    static uint8_t in[1 << 16];
    unsigned got = 0, got_bad = 0;
    /* write without reading until the server stops reading us (past conn-out-cap), ask
     * another connection for STATS meanwhile, then read everything, writing the rest as the
     * server takes it: its output is sent in pieces while more replies are appended */
    int stalled = 0;
    while (left && !stalled) {
        struct pollfd p = {fd, POLLOUT, 0};
        stalled = poll(&p, 1, 300) == 0;
        ssize_t w = stalled ? 0 : send(fd, out, left, MSG_NOSIGNAL | MSG_DONTWAIT);
        assert_true(w >= 0 || errno == EAGAIN);   /* the daemon must not drop us */
        if (w > 0) {
            out += w;
            left -= (size_t)w;
        }
    }
    assert_true(stalled);   /* more than conn-out-cap and the socket buffers hold */
    stc_conn *mid = conn_to(&d);
    assert_non_null(mid);
    const stc_stat *mst = NULL;
    size_t mn = 0;
    assert_int_equal(stc_stats(mid, &mst, &mn), 0);
    stc_close(mid);
    while (got < TOTAL) {
        struct pollfd p = {fd, POLLOUT, 0};
        if (left && poll(&p, 1, 10) > 0 && (p.revents & POLLOUT)) {
            ssize_t w = send(fd, out, left < 8192 ? left : 8192, MSG_NOSIGNAL | MSG_DONTWAIT);
            assert_true(w >= 0 || errno == EAGAIN);
            if (w > 0) {
                out += w;
                left -= (size_t)w;
            }
            continue;
        }
        p.events = POLLIN;
        assert_true(poll(&p, 1, 20000) > 0);
        ssize_t r = recv(fd, in + have, sizeof in - have, 0);
        assert_true(r > 0);
        have += (size_t)r;
        for (;;) {   /* every complete reply in `in` */
            stp_header h;
            int reason = 0;
            if (have < STP_HEADER_SIZE ||
                stp_parse_header(in, have, 1 << 20, &h, &reason) != STP_OK ||
                have < STP_HEADER_SIZE + (size_t)h.body_len)
                break;
            assert_int_equal(h.reqid, got);
            assert_int_equal(h.status != STP_S_OK, got % EVERY == EVERY - 1);
            got_bad += h.status != STP_S_OK;
            got++;
            size_t fl = STP_HEADER_SIZE + (size_t)h.body_len;
            memmove(in, in + fl, have - fl);
            have -= fl;
        }
    }
    stp_buf_free(&b);
    close(fd);
    assert_int_equal(got_bad, nbad);
    stc_conn *c = conn_to(&d);
    assert_non_null(c);
    const stc_stat *st = NULL;
    size_t n = 0;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stat_u(st, n, "op_ping_requests"), TOTAL - nbad);
    assert_int_equal(stat_u(st, n, "op_ping_errors"), 0);
    assert_int_equal(stat_u(st, n, "op_info_requests"), nbad);
    assert_int_equal(stat_u(st, n, "op_info_errors"), nbad);
    assert_int_equal(stat_u(st, n, "replies_error"), nbad);
    int nb = 0;
    assert_int_equal(hist_sum(st, n, "ping", &nb), TOTAL - nbad);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

/* DELETE runs on a worker: its replies are counted on the worker's completion path. */
static void worker_requests_are_counted_too(void **state)
{
    (void)state;
    enum { K = 4 };
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    stc_conn *c = conn_to(&d);
    assert_non_null(c);
    for (int i = 0; i < K; i++)
        assert_int_not_equal(stc_delete(c, "no-such-set"), 0);
    const stc_stat *st = NULL;
    size_t n = 0;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stat_u(st, n, "op_delete_requests"), K);
    assert_int_equal(stat_u(st, n, "op_delete_errors"), K);
    int nb = 0;
    assert_int_equal(hist_sum(st, n, "delete", &nb), K);
    assert_true(stat_u(st, n, "worker_tasks") >= K);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ping_and_bad_info_counts_are_exact),
        cmocka_unit_test(worker_requests_are_counted_too),
        cmocka_unit_test(counts_stay_exact_when_replies_back_up),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
