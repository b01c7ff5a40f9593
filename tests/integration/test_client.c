/* tests/integration/test_client.c - libseamtex behaviours over real sockets.
 *
 * Two kinds of peer:
 *   - a scripted mock server (a thread in this process on a loopback port) for behaviours a
 *     healthy daemon never shows on demand: late replies, garbage, closes, oversized replies,
 *     unsolicited BUSY, silence during HELLO;
 *   - the real seamtexd (tests/common/daemon_fixture) for end-to-end calls: HELLO, ping,
 *     upload of a .ptx from the shared data, list, info, sample, stats, delete, and server-side
 *     statuses reaching the client (unknown opcode, lying SAMPLE length, body over the cap)
 *     without breaking the connection. Skipped (with the reason) when the daemon or the shared
 *     data are missing.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "../common/daemon_fixture.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"
#include "seamtex.h"
#include "seamtex_cluster.h"

/* ---- scripted mock server ------------------------------------------------------------------- */

enum mock_mode {
    M_NORMAL,          /* HELLO, PING echo, SAMPLE (values = u), INFO, UPLOAD_*, FETCH_* */
    M_DELAY_PING1,     /* the first PING is answered after 400 ms */
    M_GARBAGE_PING,    /* a PING is answered with bytes that are not a frame */
    M_CLOSE_PING,      /* a PING closes the connection */
    M_HUGE_PING1,      /* the first PING is answered with a 2 MiB body */
    M_BUSY,            /* an unsolicited BUSY with reqid 0 at accept, then close */
    M_SILENT,          /* never answers anything */
    M_REVERSE,         /* answers pipelined PINGs in batches of 4 in reverse order */
    M_SLOW_START,      /* stops reading after HELLO until the test sets `resume` */
    M_DEAF             /* answers HELLO, then never reads again (until the test ends) */
};

typedef struct mock {
    int lfd, port, mode, stop, resume;
    pthread_t th;
    int pings;                     /* PINGs seen */
    int aborts;                    /* UPLOAD_ABORTs seen */
    uint8_t *up;                   /* upload being received */
    uint64_t up_total, up_got;
    uint32_t up_crc;
    uint8_t *fetch;                /* file served by FETCH */
    size_t fetch_len;
    stp_buf held;                  /* M_REVERSE: replies held back */
    int nheld;
    int mute;                      /* set by a test: requests are read and not answered */
    int muted_cleanups;            /* UPLOAD_ABORTs and FETCH_CLOSEs read while muted */
} mock;

/* The mock sends whole frames; a failed send shows as the client's error. */
static void send_all(int fd, const void *p, size_t n)
{
    (void)st_wire_send_all(fd, p, n);
}

/* Waiting for the test to end the mock's deafness (stop or resume). */
static int deaf_over(void *arg)
{
    mock *m = arg;
    return __atomic_load_n(&m->stop, __ATOMIC_ACQUIRE) ||
           __atomic_load_n(&m->resume, __ATOMIC_ACQUIRE);
}

/* Answers one request; returns -1 to close the connection. */
static int mock_handle(mock *m, int fd, const stp_header *h, const uint8_t *body)
{
    stp_buf o;
    int rc = 0;
    stp_buf_init(&o);
    switch (h->opcode) {
    case STP_OP_HELLO: {
        stp_hello_reply r;
        memset(&r, 0, sizeof r);
        r.version = 1;
        r.caps = STP_CAP_PIPELINE | (m->mode == M_REVERSE ? STP_CAP_OUT_OF_ORDER : 0);
        r.max_body = 1u << 20;
        r.max_batch = 1000;
        r.max_chunk = 1000;          /* small: uploads and fetches take many chunks */
        r.max_inflight = 16;
        strcpy(r.server_name, "mock");
        stp_enc_hello_reply(&o, h->reqid, &r);
        if (m->mode == M_SLOW_START || m->mode == M_DEAF) {
            send_all(fd, stp_buf_head(&o), stp_buf_avail(&o));
            stp_buf_free(&o);
            /* deaf until the test says so (at most 120 s: under ASan on a loaded machine,
             * queueing the 64 MiB the deaf test needs took more than 10 s, and a mock that
             * starts reading then answers the PINGs and breaks the test's premise) */
            st_wait_until(deaf_over, m, 120000);
            return 0;
        }
        break;
    }
    case STP_OP_PING:
        m->pings++;
        /* a sleep on purpose: the late reply (after the client's 100 ms timeout) is what
         * the M_DELAY_PING1 tests are about */
        if (m->mode == M_DELAY_PING1 && m->pings == 1)
            st_sleep_ms(400);
        if (m->mode == M_GARBAGE_PING) {
            send_all(fd, "HTTP/1.1 400 Bad Request\r\n\r\n", 28);
            return 0;
        }
        if (m->mode == M_CLOSE_PING)
            return -1;
        if (m->mode == M_HUGE_PING1 && m->pings == 1) {
            uint8_t *big = calloc(1, 2u << 20);
            stp_enc_raw(&o, STP_OP_PING, STP_F_REPLY, h->reqid, 0, 0, big, 2u << 20);
            free(big);
            break;
        }
        if (m->mode == M_REVERSE) {
            stp_buf tmp;
            stp_buf_init(&tmp);
            stp_enc_raw(&tmp, STP_OP_PING, STP_F_REPLY, h->reqid, 0, 0, body, h->body_len);
            /* prepend: the held buffer ends up in reverse order */
            stp_put_bytes(&tmp, stp_buf_head(&m->held), stp_buf_avail(&m->held));
            stp_buf_free(&m->held);
            m->held = tmp;
            if (++m->nheld == 4) {
                send_all(fd, stp_buf_head(&m->held), stp_buf_avail(&m->held));
                stp_buf_clear(&m->held);
                m->nheld = 0;
            }
            return 0;
        }
        stp_enc_raw(&o, STP_OP_PING, STP_F_REPLY, h->reqid, 0, 0, body, h->body_len);
        break;
    case STP_OP_INFO:
        stp_enc_error(&o, STP_OP_INFO, h->reqid, STP_S_NOT_FOUND, "no set here");
        break;
    case STP_OP_SAMPLE: {
        stp_sample_req rq;
        const char *why = NULL;
        int s = stp_dec_sample_req(body, h->body_len, 1000, &rq, &why);
        if (s) {
            stp_enc_error(&o, h->opcode, h->reqid, (uint16_t)s, why);
            break;
        }
        float *v = calloc(rq.count * 2 + 1, sizeof *v), *cov = calloc(rq.count + 1, 4);
        uint8_t *st = calloc(rq.count + 1, 1);
        uint32_t bad = 0;
        for (uint32_t i = 0; i < rq.count; i++) {
            stp_query q;
            stp_sample_query(&rq, i, &q);
            v[2 * i] = q.u;
            v[2 * i + 1] = q.v;
            cov[i] = 1.0f;
            st[i] = isfinite(q.u) ? 0 : 2;
            bad += st[i] != 0;
        }
        stp_sample_reply rp = { rq.count, 2, rq.p.outfmt, rq.p.flags, bad, v, cov, st,
                                NULL, NULL, NULL };
        stp_enc_sample_reply(&o, STP_OP_SAMPLE, h->reqid, &rp);
        free(v);
        free(cov);
        free(st);
        break;
    }
    case STP_OP_UPLOAD_BEGIN: {
        stp_upload_begin b;
        stp_dec_upload_begin(body, h->body_len, &b, NULL);
        free(m->up);
        m->up = malloc(b.total_size + 1);
        m->up_total = b.total_size;
        m->up_got = 0;
        m->up_crc = b.crc32c;
        stp_upload_begin_reply r = { 99, 0, 1000 };
        stp_enc_upload_begin_reply(&o, h->reqid, &r);
        break;
    }
    case STP_OP_UPLOAD_CHUNK: {
        stp_upload_chunk c;
        if (stp_dec_upload_chunk(body, h->body_len, &c, NULL) || c.offset != m->up_got ||
            c.len > m->up_total - m->up_got || c.len > 1000) {
            stp_enc_error(&o, h->opcode, h->reqid, STP_S_INVALID, "bad chunk");
            break;
        }
        memcpy(m->up + c.offset, c.data, c.len);
        m->up_got += c.len;
        stp_upload_progress p = { m->up_got, m->up_total };
        stp_enc_upload_progress(&o, STP_OP_UPLOAD_CHUNK, h->reqid, &p);
        break;
    }
    case STP_OP_UPLOAD_COMMIT:
        if (m->up_got != m->up_total || stp_crc32c(0, m->up, m->up_got) != m->up_crc) {
            stp_enc_error(&o, h->opcode, h->reqid, STP_S_CORRUPT, "checksum");
        } else {
            stp_upload_done d = { "up", 0, 1, 0, 1, m->up_total };
            stp_enc_upload_done(&o, h->reqid, &d);
        }
        break;
    case STP_OP_UPLOAD_ABORT:
        m->aborts++;
        stp_enc_empty(&o, STP_OP_UPLOAD_ABORT, STP_F_REPLY, h->reqid, 0);
        break;
    case STP_OP_FETCH_OPEN: {
        stp_fetch_open_reply r = { 7, m->fetch_len, stp_crc32c(0, m->fetch, m->fetch_len),
                                   1000 };
        stp_enc_fetch_open_reply(&o, h->reqid, &r);
        break;
    }
    case STP_OP_FETCH_READ: {
        stp_fetch_read r;
        stp_dec_fetch_read(body, h->body_len, &r, NULL);
        size_t n = r.offset >= m->fetch_len ? 0 : m->fetch_len - r.offset;
        if (n > r.max_len)
            n = r.max_len;
        if (n > 1000)
            n = 1000;
        stp_fetch_data d = { r.offset, (uint32_t)n, m->fetch + (n ? r.offset : 0) };
        stp_enc_fetch_data(&o, h->reqid, &d);
        break;
    }
    case STP_OP_FETCH_CLOSE:
        stp_enc_empty(&o, STP_OP_FETCH_CLOSE, STP_F_REPLY, h->reqid, 0);
        break;
    default:
        stp_enc_error(&o, h->opcode, h->reqid, STP_S_UNKNOWN_OPCODE, "mock");
        break;
    }
    send_all(fd, stp_buf_head(&o), stp_buf_avail(&o));
    stp_buf_free(&o);
    return rc;
}

static void mock_serve(mock *m, int fd)
{
    stp_buf in;
    stp_buf_init(&in);
    if (m->mode == M_BUSY) {
        stp_buf o;
        stp_buf_init(&o);
        stp_enc_error(&o, 0, 0, STP_S_BUSY, "too many connections");
        send_all(fd, o.data, o.len);
        stp_buf_free(&o);
        close(fd);
        return;
    }
    while (!__atomic_load_n(&m->stop, __ATOMIC_ACQUIRE)) {
        struct pollfd p = { fd, POLLIN, 0 };
        if (poll(&p, 1, 100) <= 0)
            continue;
        stp_buf_reserve(&in, 65536);
        ssize_t n = recv(fd, in.data + in.len, in.cap - in.len, 0);
        if (n <= 0)
            break;
        in.len += (size_t)n;
        for (;;) {
            stp_header h;
            int reason;
            int r = stp_parse_header(stp_buf_head(&in), stp_buf_avail(&in), 1u << 20, &h, &reason);
            if (r != STP_OK || stp_buf_avail(&in) < STP_HEADER_SIZE + (size_t)h.body_len)
                break;
            int mute = __atomic_load_n(&m->mute, __ATOMIC_ACQUIRE);
            if (mute && (h.opcode == STP_OP_UPLOAD_ABORT || h.opcode == STP_OP_FETCH_CLOSE))
                __atomic_add_fetch(&m->muted_cleanups, 1, __ATOMIC_RELEASE);
            int rc = m->mode == M_SILENT || mute
                     ? 0 : mock_handle(m, fd, &h, stp_buf_head(&in) + STP_HEADER_SIZE);
            stp_buf_consume(&in, STP_HEADER_SIZE + h.body_len);
            if (rc < 0)
                goto out;
        }
    }
out:
    close(fd);
    stp_buf_free(&in);
}

static void *mock_main(void *arg)
{
    mock *m = arg;
    while (!__atomic_load_n(&m->stop, __ATOMIC_ACQUIRE)) {
        struct pollfd p = { m->lfd, POLLIN, 0 };
        if (poll(&p, 1, 50) <= 0)
            continue;
        int fd = accept(m->lfd, NULL, NULL);
        if (fd >= 0)
            mock_serve(m, fd);
    }
    return NULL;
}

static mock *mock_start(int mode)
{
    mock *m = calloc(1, sizeof *m);
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    m->mode = mode;
    stp_buf_init(&m->held);
    m->lfd = socket(AF_INET, SOCK_STREAM, 0);
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(bind(m->lfd, (struct sockaddr *)&sa, sizeof sa), 0);
    assert_int_equal(listen(m->lfd, 8), 0);
    getsockname(m->lfd, (struct sockaddr *)&sa, &sl);
    m->port = ntohs(sa.sin_port);
    pthread_create(&m->th, NULL, mock_main, m);
    return m;
}

static void mock_stop(mock *m)
{
    __atomic_store_n(&m->stop, 1, __ATOMIC_RELEASE);
    pthread_join(m->th, NULL);
    close(m->lfd);
    free(m->up);
    free(m->fetch);
    stp_buf_free(&m->held);
    free(m);
}

static stc_conn *mock_connect(mock *m, int request_timeout_ms)
{
    stc_opts o;
    int err = 0;
    char msg[256];
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = 2000;
    o.request_timeout_ms = request_timeout_ms;
    o.max_body = 1u << 20;
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)m->port, &o, &err, msg, sizeof msg);
    if (!c)
        fail_msg("connect to mock: %d %s", err, msg);
    return c;
}

/* ---- mock tests ------------------------------------------------------------------------------ */

static void connect_reports_hello_limits(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 0);
    const stc_server *s = stc_server_info(c);
    assert_string_equal(s->name, "mock");
    assert_int_equal(s->max_batch, 1000);
    assert_int_equal(s->max_inflight, 16);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    mock_stop(m);
}

static void connect_to_closed_port_fails_with_message(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    int port = m->port, err = 0;
    mock_stop(m);                            /* nothing listens there now */
    char msg[256] = "";
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)port, NULL, &err, msg, sizeof msg);
    assert_null(c);
    assert_int_equal(err, STC_ECONNECT);
    assert_non_null(strstr(msg, "127.0.0.1"));
    assert_null(stc_connect("no-such-host.invalid", 1, 1000, &err));
    assert_int_equal(err, STC_ECONNECT);
}

static void connect_timeout_covers_a_silent_hello(void **state)
{
    (void)state;
    mock *m = mock_start(M_SILENT);
    stc_opts o;
    int err = 0;
    char msg[256];
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = 200;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)m->port, &o, &err, msg, sizeof msg);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ms = (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) / 1e6;
    assert_null(c);
    assert_int_equal(err, STC_ETIMEDOUT);
    assert_true(ms >= 150 && ms < 2000);
    /* py35: the message said the abandoned HELLO reply "will be dropped when it comes",
     * though the connection is closed: it says so now. */
    if (strstr(msg, "dropped") || !strstr(msg, "connection is closed"))
        fail_msg("connect timeout message: \"%s\"", msg);
    assert_non_null(strstr(msg, "HELLO"));
    mock_stop(m);
}

static void request_timeout_does_not_poison_the_connection(void **state)
{
    (void)state;
    mock *m = mock_start(M_DELAY_PING1);
    stc_conn *c = mock_connect(m, 100);
    assert_int_equal(stc_ping(c), STC_ETIMEDOUT);
    assert_non_null(strstr(stc_errmsg(c), "timeout"));
    assert_int_equal(stc_error(c), 0);           /* not sticky */
    /* the next call works; the late reply to the first ping arrives first and is dropped */
    stc_set_timeout(c, 2000);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(m->pings, 3);
    stc_close(c);
    mock_stop(m);
}

static void protocol_violation_is_sticky(void **state)
{
    (void)state;
    mock *m = mock_start(M_GARBAGE_PING);
    stc_conn *c = mock_connect(m, 2000);
    assert_int_equal(stc_ping(c), STC_EPROTO);
    assert_non_null(strstr(stc_errmsg(c), "magic"));
    assert_int_equal(stc_error(c), STC_EPROTO);
    /* every later call fails the same way without touching the socket */
    assert_int_equal(stc_ping(c), STC_EPROTO);
    assert_int_equal(stc_delete(c, "x"), STC_EPROTO);
    assert_int_equal(m->pings, 1);
    stc_close(c);
    mock_stop(m);
}

static void server_close_is_sticky(void **state)
{
    (void)state;
    mock *m = mock_start(M_CLOSE_PING);
    stc_conn *c = mock_connect(m, 2000);
    int rc = stc_ping(c);
    assert_true(rc == STC_ECLOSED || rc == STC_EIO);
    assert_int_equal(stc_error(c), rc);
    assert_int_equal(stc_ping(c), rc);
    stc_close(c);
    mock_stop(m);
}

static void server_status_is_not_sticky(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 2000);
    stc_info inf;
    assert_int_equal(stc_info_get(c, "nothing", 0, 0, &inf), STC_ENOTFOUND);
    assert_non_null(strstr(stc_errmsg(c), "no set here"));
    assert_true(stc_is_server_error(STC_ENOTFOUND));
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_ping(c), 0);
    assert_string_equal(stc_errmsg(c), "");
    /* a name the protocol does not allow is refused before anything is sent */
    assert_int_equal(stc_info_get(c, "../etc", 0, 0, &inf), STC_EINVAL);
    /* every call says the same about a bad name (the rule included), and fetch says which of
     * its arguments it refuses (it said "bad set name, path or format") */
    const char *rule = "is not a valid set name (1..255 of A-Z a-z 0-9 . _ -";
    assert_non_null(strstr(stc_errmsg(c), rule));
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, "x", 1, "a/b", NULL, &ur), STC_EINVAL);
    assert_non_null(strstr(stc_errmsg(c), rule));
    assert_int_equal(stc_fetch_file(c, "a/b", STC_FETCH_PTX, "/nonexistent/x", NULL, NULL),
                     STC_EINVAL);
    assert_non_null(strstr(stc_errmsg(c), rule));
    assert_int_equal(stc_fetch_file(c, "ok", 99, "/nonexistent/x", NULL, NULL), STC_EINVAL);
    assert_non_null(strstr(stc_errmsg(c), "format 99"));
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    mock_stop(m);
}

static void oversized_reply_fails_that_request_only(void **state)
{
    (void)state;
    mock *m = mock_start(M_HUGE_PING1);
    stc_conn *c = mock_connect(m, 5000);     /* client cap 1 MiB, reply 2 MiB */
    assert_int_equal(stc_ping(c), STC_ENOMEM);
    assert_non_null(strstr(stc_errmsg(c), "cap"));
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    mock_stop(m);
}

static void unsolicited_busy_fails_connect_with_busy(void **state)
{
    (void)state;
    mock *m = mock_start(M_BUSY);
    int err = 0;
    char msg[256] = "";
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)m->port, NULL, &err, msg, sizeof msg);
    assert_null(c);
    assert_int_equal(err, STC_EBUSY);
    assert_non_null(strstr(msg, "too many connections"));
    mock_stop(m);
}

static void pipelined_pings_are_matched_by_reqid(void **state)
{
    (void)state;
    for (int mode = M_NORMAL; mode <= M_REVERSE; mode += M_REVERSE - M_NORMAL) {
        mock *m = mock_start(mode);
        stc_conn *c = mock_connect(m, 5000);
        uint32_t ids[64];
        char payload[64][16];
        for (int i = 0; i < 64; i++) {
            snprintf(payload[i], sizeof payload[i], "p%d", i);
            assert_int_equal(stc_append_ping(c, payload[i], strlen(payload[i]), &ids[i]), 0);
        }
        assert_int_equal(stc_pending(c), 64);
        assert_int_equal(stc_ping(c), STC_ESTATE);   /* blocking call while replies are due */
        assert_int_equal(stc_flush(c), 0);
        int seen[64] = { 0 }, inorder = 1;
        for (int k = 0; k < 64; k++) {
            stc_reply r;
            assert_int_equal(stc_get_reply(c, 5000, &r), 0);
            int i;
            for (i = 0; i < 64 && ids[i] != r.reqid; i++)
                ;
            assert_true(i < 64);
            assert_int_equal(r.status, 0);
            assert_int_equal(r.body_len, strlen(payload[i]));
            assert_memory_equal(r.body, payload[i], r.body_len);
            inorder &= i == k;
            seen[i]++;
        }
        for (int i = 0; i < 64; i++)
            assert_int_equal(seen[i], 1);
        assert_int_equal(inorder, mode == M_NORMAL);
        assert_int_equal(stc_pending(c), 0);
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 10, &r), STC_ESTATE);
        if (mode == M_NORMAL)        /* the reversing mock holds a lone reply back */
            assert_int_equal(stc_ping(c), 0);
        stc_close(c);
        mock_stop(m);
    }
}

static void pipelined_timeout_keeps_the_reply_coming(void **state)
{
    (void)state;
    mock *m = mock_start(M_DELAY_PING1);
    stc_conn *c = mock_connect(m, 0);
    uint32_t id;
    stc_reply r;
    assert_int_equal(stc_append_ping(c, "x", 1, &id), 0);
    assert_int_equal(stc_get_reply(c, 0, &r), STC_ETIMEDOUT);    /* nothing there yet */
    assert_int_equal(stc_get_reply(c, 50, &r), STC_ETIMEDOUT);
    assert_int_equal(stc_pending(c), 1);          /* still due: the caller may wait again */
    assert_int_equal(stc_get_reply(c, 3000, &r), 0);
    assert_int_equal(r.reqid, id);
    /* giving up on pipelined requests re-allows blocking calls; their replies are dropped */
    assert_int_equal(stc_append_ping(c, "y", 1, &id), 0);
    assert_int_equal(stc_append_ping(c, "z", 1, &id), 0);
    assert_int_equal(stc_ping(c), STC_ESTATE);
    assert_int_equal(stc_discard_pending(c), 2);
    assert_int_equal(stc_pending(c), 0);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    mock_stop(m);
}

static void send_timeout_keeps_the_rest_queued(void **state)
{
    (void)state;
    mock *m = mock_start(M_SLOW_START);
    stc_conn *c = mock_connect(m, 100);
    size_t len = 900 * 1000;
    uint8_t *payload = malloc(len);
    uint32_t ids[40];
    for (size_t i = 0; i < len; i++)
        payload[i] = (uint8_t)(i * 13);
    for (int k = 0; k < 40; k++)
        assert_int_equal(stc_append_ping(c, payload, len, &ids[k]), 0);
    /* 36 MB cannot all go into the socket buffers while the peer is not reading */
    int rc = stc_flush(c);
    assert_int_equal(rc, STC_ETIMEDOUT);
    assert_int_equal(stc_error(c), 0);
    __atomic_store_n(&m->resume, 1, __ATOMIC_RELEASE);
    /* waiting for replies also sends the rest: every frame arrives whole */
    for (int k = 0; k < 40; k++) {
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 10000, &r), 0);
        assert_int_equal(r.reqid, ids[k]);
        assert_int_equal(r.body_len, len);
        assert_memory_equal(r.body, payload, len);
    }
    assert_int_equal(stc_ping(c), 0);
    free(payload);
    stc_close(c);
    mock_stop(m);
}

static void appends_to_a_server_that_never_reads_are_bounded(void **state)
{
    (void)state;
    mock *m = mock_start(M_DEAF);
    stc_conn *c = mock_connect(m, 100);
    size_t len = 900 * 1000, ok = 0;
    uint8_t *payload = calloc(1, len);
    uint32_t id;
    int rc = 0;
    for (int k = 0; k < 400 && rc == 0; k++) {
        rc = stc_append_ping(c, payload, len, &id);
        ok += rc == 0;
    }
    /* refused once ~64 MiB are queued unsent: not hundreds of MB */
    assert_int_equal(rc, STC_ETIMEDOUT);
    assert_true(ok * len >= (64u << 20) && ok * len < (64u << 20) + (64u << 20));
    assert_non_null(strstr(stc_errmsg(c), "not reading"));
    assert_int_equal(stc_error(c), 0);              /* not sticky */
    assert_int_equal(stc_pending(c), ok);           /* the refused one was not queued */
    free(payload);
    stc_close(c);
    mock_stop(m);
}

static void sample_results_in_every_format(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 5000);
    stc_query q[3] = { { 0, 0.25f, 0.5f, 0, 0, 0, 0 }, { 1, NAN, 1.0f, 0, 0, 0, 0 },
                       { 2, 1.5f, -1.0f, 0, 0, 0, 0 } };
    for (unsigned fmt = 0; fmt < 3; fmt++) {
        stc_sample_opts o;
        stc_sample_result res;
        memset(&o, 0, sizeof o);
        o.outfmt = fmt;
        o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
        assert_int_equal(stc_sample(c, "tex", &o, q, 3, &res), 0);
        assert_int_equal(res.count, 3);
        assert_int_equal(res.nchan, 2);
        assert_int_equal(res.nbad, 1);
        assert_non_null(res.coverage);
        assert_int_equal(res.status[1], 2);
        if (fmt == STC_OUT_F32) {
            const float *v = res.values;
            assert_true(v[0] == 0.25f && v[1] == 0.5f && isnan(v[2]) && v[4] == 1.5f);
        } else if (fmt == STC_OUT_UNORM8) {
            const uint8_t *v = res.values;
            assert_int_equal(v[0], 64);
            assert_int_equal(v[1], 128);
            assert_int_equal(v[2], 0);
            assert_int_equal(v[4], 255);
            assert_int_equal(v[5], 0);
        } else {
            const uint16_t *v = res.values;
            assert_int_equal(v[0], 16384);
            assert_int_equal(v[3], 65535);
        }
    }
    /* no coverage / status asked: none returned; zero queries is fine */
    stc_sample_opts o;
    stc_sample_result res;
    memset(&o, 0, sizeof o);
    assert_int_equal(stc_sample(c, "tex", &o, q, 3, &res), 0);
    assert_null(res.coverage);
    assert_null(res.status);
    assert_int_equal(stc_sample(c, "tex", &o, NULL, 0, &res), 0);
    assert_int_equal(res.count, 0);
    /* a batch over the server's max_batch (1000) comes back whole, in order */
    size_t nbig = 2500;
    stc_query *big = malloc(nbig * sizeof *big);
    for (size_t i = 0; i < nbig; i++) {
        stc_query x = { 0, (float)i / nbig, 0.5f, 0, 0, 0, 0 };
        big[i] = x;
    }
    big[1700].u = NAN;
    o.want = STC_WANT_STATUS;
    assert_int_equal(stc_sample(c, "tex", &o, big, nbig, &res), 0);
    assert_int_equal(res.count, nbig);
    assert_int_equal(res.nbad, 1);
    assert_int_equal(res.status[1700], 2);
    for (size_t i = 0; i < nbig; i++)
        if (i != 1700 && ((const float *)res.values)[2 * i] != (float)i / nbig)
            fail_msg("query %zu came back out of place", i);
    free(big);
    o.want = 0;
    /* pipelined: append two batches, decode both replies */
    uint32_t a, b;
    assert_int_equal(stc_append_sample(c, "tex", &o, q, 1, &a), 0);
    assert_int_equal(stc_append_sample(c, "tex", &o, q, 3, &b), 0);
    assert_int_equal(stc_flush(c), 0);
    for (int k = 0; k < 2; k++) {
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 3000, &r), 0);
        assert_int_equal(stc_reply_sample(c, &r, &res), 0);
        assert_int_equal(res.count, r.reqid == a ? 1 : 3);
    }
    stc_close(c);
    mock_stop(m);
}

typedef struct progress { int calls; uint64_t last; int stop_at; } progress;

static int on_progress(void *user, uint64_t done, uint64_t total)
{
    progress *p = user;
    assert_true(done <= total);
    assert_true(done >= p->last);
    p->last = done;
    p->calls++;
    return p->stop_at && p->calls >= p->stop_at;
}

static void upload_sends_chunks_with_checksum_and_aborts_on_cancel(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 5000);
    size_t n = 25500;                               /* 26 chunks of <= 1000 bytes */
    uint8_t *data = malloc(n);
    for (size_t i = 0; i < n; i++)
        data[i] = (uint8_t)(i * 31 + 7);
    progress p = { 0, 0, 0 };
    stc_upload_opts o;
    stc_upload_result res;
    memset(&o, 0, sizeof o);
    o.progress = on_progress;
    o.user = &p;
    assert_int_equal(stc_upload_buffer(c, data, n, "up", &o, &res), 0);
    assert_int_equal(m->up_got, n);
    assert_memory_equal(m->up, data, n);
    assert_int_equal(res.crc32c, stp_crc32c(0, data, n));
    assert_int_equal(res.memory, n);
    assert_int_equal(p.calls, 26);
    assert_int_equal(p.last, n);

    /* a callback that says stop: ECANCELED, the server is told to abort */
    progress q = { 0, 0, 3 };
    o.user = &q;
    assert_int_equal(stc_upload_buffer(c, data, n, "up", &o, &res), STC_ECANCELED);
    assert_int_equal(m->aborts, 1);
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_ping(c), 0);               /* in-flight chunk replies were dropped */

    /* an upload of a file from disk, empty file included */
    char path[] = "/tmp/stc-upload-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, data, 3000), 3000);
    close(fd);
    assert_int_equal(stc_upload_file(c, path, "up", NULL, &res), 0);
    assert_int_equal(m->up_got, 3000);
    fd = open(path, O_WRONLY | O_TRUNC);
    close(fd);
    assert_int_equal(stc_upload_file(c, path, "up", NULL, &res), 0);
    assert_int_equal(m->up_total, 0);
    unlink(path);
    assert_int_equal(stc_upload_file(c, "/nonexistent/file.ptx", "up", NULL, &res), STC_EFILE);
    free(data);
    stc_close(c);
    mock_stop(m);
}

/* py35: n over 2^32-1 is refused: (n + per - 1) wrapped for n near SIZE_MAX, so such a call
 * made 0 parts and returned 0 with nothing sampled and the result unset (the result's count is
 * 32 bits anyway). */
static void a_batch_over_2_32_queries_is_refused_not_dropped(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 5000);
    stc_query q[1] = { { 0, 0.25f, 0.5f, 0, 0, 0, 0 } };
    stc_dir_query dq[1] = { { { 1, 0, 0 }, { 0, 0, 0 }, { 0, 0, 0 } } };
    stc_sample_opts o;
    stc_sample_result res;
    memset(&o, 0, sizeof o);
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    assert_int_equal(stc_sample(c, "tex", &o, q, SIZE_MAX, &res), STC_EINVAL);
    assert_int_equal(stc_sample(c, "tex", &o, q, SIZE_MAX - 1000, &res), STC_EINVAL);
    assert_int_equal(stc_sample_dir(c, "tex", &o, dq, SIZE_MAX, &res), STC_EINVAL);
    assert_int_equal(stc_sample(c, "tex", &o, q, (size_t)UINT32_MAX + 1, &res), STC_EINVAL);
    assert_non_null(strstr(stc_errmsg(c), "2^32-1"));
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_sample(c, "tex", &o, q, 1, &res), 0);   /* usable, not sticky */
    assert_int_equal(res.count, 1);
    stc_close(c);
    mock_stop(m);
}

/* py35: a hint longer than the protocol's 15 bytes was dropped silently (the server then
 * imported the file by its magic) while a short unknown one is refused; unknown flag bits
 * were ignored. Both are STC_EINVAL now, before anything is sent. */
static void upload_refuses_a_long_hint_and_unknown_flags(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 5000);
    stc_upload_opts o;
    stc_upload_result res;
    memset(&o, 0, sizeof o);
    o.hint = "averyveryverylonghint";
    assert_int_equal(stc_upload_buffer(c, "abc", 3, "up", &o, &res), STC_EINVAL);
    assert_non_null(strstr(stc_errmsg(c), "hint"));
    assert_int_equal(m->up_total, 0);               /* no UPLOAD_BEGIN reached the server */
    o.hint = "ptx";
    o.flags = 0x80;
    assert_int_equal(stc_upload_buffer(c, "abc", 3, "up", &o, &res), STC_EINVAL);
    assert_int_equal(m->up_total, 0);
    o.flags = STC_UPLOAD_REPLACE;
    o.hint = "0123456789abcde";                     /* 15 bytes: sent as it is */
    assert_int_equal(stc_upload_buffer(c, "abc", 3, "up", &o, &res), 0);
    assert_int_equal(m->up_got, 3);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    mock_stop(m);
}

/* py35: a connection used in a child after fork shared the parent's socket and request ids:
 * replies crossed (the parent's connection broke with EPROTO, and through a shared-memory
 * region results came back wrong). A child's call is STC_ESTATE now; its stc_close leaves the
 * parent's connection working. */
static void a_child_after_fork_cannot_use_the_parents_connection(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 5000);
    assert_int_equal(stc_ping(c), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {                   /* no cmocka asserts in the child: its exit status says */
        int rc = stc_ping(c), ok = rc == STC_ESTATE && strstr(stc_errmsg(c), "fork") != NULL;
        uint32_t id;
        ok = ok && stc_append_ping(c, NULL, 0, &id) == STC_ESTATE;
        stc_close(c);
        _exit(ok ? 0 : 1);
    }
    int status = 0;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
    assert_int_equal(stc_ping(c), 0);               /* the parent's connection is untouched */
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    mock_stop(m);
}

/* py35: stc_cluster_open wrote *err through a NULL err on failure (a crash; stc_connect_opts
 * and stc_cluster_open_etcd take NULL), and stc_cluster_conn indexed past the nodes for an i
 * out of range. */
static void cluster_open_takes_a_null_err_and_conn_checks_its_index(void **state)
{
    (void)state;
    assert_null(stc_cluster_open("", NULL, NULL, NULL, 0));          /* no seed */
    mock *m = mock_start(M_NORMAL);                                   /* no CLUSTER: refused */
    char seeds[64];
    snprintf(seeds, sizeof seeds, "127.0.0.1:%d", m->port);
    assert_null(stc_cluster_open(seeds, NULL, NULL, NULL, 0));
    int err = 0;
    char msg[128];
    assert_null(stc_cluster_open(seeds, NULL, &err, msg, sizeof msg));
    assert_true(err != 0);
    err = 0;
    assert_null(stc_cluster_conn(NULL, 0, &err));   /* the index check's NULL half */
    assert_int_equal(err, STC_EINVAL);
    mock_stop(m);
}

/* py35: an upload or fetch that timed out waited a second full timeout for its UPLOAD_ABORT /
 * FETCH_CLOSE: with a server that stops answering mid-transfer a call with timeout T took 2 T.
 * The clean-up wait after a timeout is 1 s at most (libseamtex(3)): T + 1 s, and the clean-up
 * request is sent all the same. */
typedef struct mute_at_first { mock *m; } mute_at_first;
static int mute_on_progress(void *user, uint64_t done, uint64_t total)
{
    (void)done;
    (void)total;
    __atomic_store_n(&((mute_at_first *)user)->m->mute, 1, __ATOMIC_RELEASE);
    return 0;
}

static int mute_on_last(void *user, uint64_t done, uint64_t total)
{
    if (done == total)
        __atomic_store_n(&((mute_at_first *)user)->m->mute, 1, __ATOMIC_RELEASE);
    return 0;
}

static int muted_cleanup_seen(void *arg)
{
    return __atomic_load_n(&((mock *)arg)->muted_cleanups, __ATOMIC_ACQUIRE) > 0;
}

static void a_timed_out_transfer_waits_briefly_for_its_cleanup(void **state)
{
    (void)state;
    enum { T = 3000, ALLOWANCE = 1000, SLACK = 1500 };   /* 2 T = 6000 > T + ALLOWANCE + SLACK */
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, T);
    size_t n = 40000;                                    /* 40 chunks of the mock's 1000 */
    uint8_t *data = malloc(n);
    for (size_t i = 0; i < n; i++)
        data[i] = (uint8_t)(i * 7);
    mute_at_first u = { m };
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.progress = mute_on_progress;
    o.user = &u;
    int64_t t0 = st_now_ms();
    assert_int_equal(stc_upload_buffer(c, data, n, "up", &o, NULL), STC_ETIMEDOUT);
    int64_t took = st_now_ms() - t0;
    if (took < T || took > T + ALLOWANCE + SLACK)
        fail_msg("upload with timeout %d ms that timed out took %lld ms", T, (long long)took);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the abort was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    assert_int_equal(stc_ping(c), 0);                   /* not sticky: late replies dropped */

    __atomic_store_n(&m->muted_cleanups, 0, __ATOMIC_RELEASE);
    m->fetch_len = n;
    m->fetch = data;                                     /* freed by mock_stop */
    char dir[] = "/tmp/stc-fetchto-XXXXXX", path[300];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/out.ptx", dir);
    t0 = st_now_ms();
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, mute_on_progress, &u),
                     STC_ETIMEDOUT);
    took = st_now_ms() - t0;
    if (took < T || took > T + ALLOWANCE + SLACK)
        fail_msg("fetch with timeout %d ms that timed out took %lld ms", T, (long long)took);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the close was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(access(path, F_OK), -1);            /* nothing left behind */
    rmdir(dir);
    stc_close(c);
    mock_stop(m);
}

/* ---- the interrupt hook (stc_set_interrupt, stc_opts.interrupt) -------------------------- */

/* py36: with no timeout a call waiting on a silent server could only end when the server
 * answered (poll was retried on EINTR): Ctrl-C could not stop a Python call. The hook is asked
 * while a call waits and stops it with STC_EINTERRUPTED, not sticky. */
typedef struct hook_count {
    int calls, stop_at;           /* stop_at 0: never says stop */
    pthread_t caller;
} hook_count;

static int counting_hook(void *user)
{
    hook_count *h = user;
    /* only ever the calling thread (the mock's thread never calls it) */
    assert_true(pthread_equal(pthread_self(), h->caller));
    h->calls++;
    return h->stop_at && h->calls >= h->stop_at;
}

static void interrupt_hook_stops_a_wait_and_leaves_the_connection_usable(void **state)
{
    (void)state;
    mock *m = mock_start(M_DELAY_PING1);         /* the first PING answered after 400 ms */
    stc_conn *c = mock_connect(m, 0);            /* no request timeout */
    hook_count h = { 0, 3, pthread_self() };
    stc_set_interrupt(c, counting_hook, &h, 20);
    assert_int_equal(stc_ping(c), STC_EINTERRUPTED);
    assert_int_equal(h.calls, 3);                /* every 20 ms until it said stop */
    assert_non_null(strstr(stc_errmsg(c), "interrupted"));
    assert_string_equal(stc_strerror(STC_EINTERRUPTED), "EINTERRUPTED");
    assert_int_equal(stc_error(c), 0);           /* not sticky */
    assert_int_equal(stc_pending(c), 0);
    /* the next call works: the abandoned PING's late reply comes first and is dropped */
    h.stop_at = 0;
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(m->pings, 3);
    /* a call that gets its reply within every_ms never asks the hook */
    h.calls = 0;
    stc_set_interrupt(c, counting_hook, &h, 10000);
    for (int i = 0; i < 50; i++)
        assert_int_equal(stc_ping(c), 0);
    assert_int_equal(h.calls, 0);
    stc_set_interrupt(c, NULL, NULL, 0);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    mock_stop(m);
}

static void on_usr1(int sig)
{
    (void)sig;
}

typedef struct kicker { pthread_t target; int after_ms; } kicker;
static void *kick(void *arg)
{
    kicker *k = arg;
    st_sleep_ms(k->after_ms);
    pthread_kill(k->target, SIGUSR1);
    return NULL;
}

/* every_ms 0: the hook is asked only when a signal interrupts the wait (poll's EINTR, which
 * used to be retried without a word). */
static void interrupt_hook_is_asked_when_a_signal_interrupts_the_wait(void **state)
{
    (void)state;
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_usr1;               /* no SA_RESTART (poll is never restarted anyway) */
    sigemptyset(&sa.sa_mask);
    assert_int_equal(sigaction(SIGUSR1, &sa, &old), 0);
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 10000);        /* a bound for a broken hook, not needed */
    __atomic_store_n(&m->mute, 1, __ATOMIC_RELEASE);   /* never answers now */
    hook_count h = { 0, 1, pthread_self() };
    stc_set_interrupt(c, counting_hook, &h, 0);
    kicker k = { pthread_self(), 200 };
    pthread_t th;
    pthread_create(&th, NULL, kick, &k);
    assert_int_equal(stc_ping(c), STC_EINTERRUPTED);
    pthread_join(th, NULL);
    assert_int_equal(h.calls, 1);
    assert_int_equal(stc_error(c), 0);
    /* a signal the hook lets pass: the wait goes on (here until the request timeout) */
    h.calls = 0;
    h.stop_at = 0;
    stc_set_timeout(c, 600);
    pthread_create(&th, NULL, kick, &k);
    assert_int_equal(stc_ping(c), STC_ETIMEDOUT);
    pthread_join(th, NULL);
    assert_int_equal(h.calls, 1);
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    stc_set_timeout(c, 5000);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    mock_stop(m);
    sigaction(SIGUSR1, &old, NULL);
}

/* Connecting: the connect and HELLO's reply are waits too (stc_opts.interrupt); the
 * connection is closed, as after a connect timeout. */
static void interrupt_hook_stops_a_connect(void **state)
{
    (void)state;
    mock *m = mock_start(M_SILENT);
    hook_count h = { 0, 2, pthread_self() };
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.connect_timeout_ms = 10000;              /* a bound for a broken hook, not needed */
    o.interrupt = counting_hook;
    o.interrupt_user = &h;
    o.interrupt_every_ms = 20;
    int err = 0;
    char msg[256] = "";
    assert_null(stc_connect_opts("127.0.0.1", (unsigned)m->port, &o, &err, msg, sizeof msg));
    assert_int_equal(err, STC_EINTERRUPTED);
    assert_int_equal(h.calls, 2);
    if (!strstr(msg, "HELLO") || !strstr(msg, "interrupted") || !strstr(msg, "closed"))
        fail_msg("interrupted connect: \"%s\"", msg);
    mock_stop(m);
}

/* A transfer stopped mid-way: STC_EINTERRUPTED at once, UPLOAD_ABORT / FETCH_CLOSE sent but
 * not waited for (waiting would ask the hook again: it is asked 3 times in all), the
 * connection usable after. */
static void interrupt_hook_stops_a_transfer_without_waiting_for_its_cleanup(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 10000);        /* a bound for a broken hook, not needed */
    size_t n = 40000;                                    /* 40 chunks of the mock's 1000 */
    uint8_t *data = malloc(n);
    for (size_t i = 0; i < n; i++)
        data[i] = (uint8_t)(i * 7);
    hook_count h = { 0, 3, pthread_self() };
    stc_set_interrupt(c, counting_hook, &h, 20);
    mute_at_first u = { m };
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.progress = mute_on_progress;
    o.user = &u;
    assert_int_equal(stc_upload_buffer(c, data, n, "up", &o, NULL), STC_EINTERRUPTED);
    assert_int_equal(h.calls, 3);      /* not asked again: the abort's reply not waited for */
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the abort was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    h.stop_at = 0;
    assert_int_equal(stc_ping(c), 0);                    /* late replies dropped */

    __atomic_store_n(&m->muted_cleanups, 0, __ATOMIC_RELEASE);
    m->fetch_len = n;
    m->fetch = data;                                     /* freed by mock_stop */
    char dir[] = "/tmp/stc-fetchint-XXXXXX", path[300];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/out.ptx", dir);
    h.calls = 0;
    h.stop_at = 3;
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, mute_on_progress, &u),
                     STC_EINTERRUPTED);
    assert_int_equal(h.calls, 3);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the close was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    h.stop_at = 0;
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(access(path, F_OK), -1);            /* nothing left behind */
    /* the hook stops the FETCH_CLOSE of a fetch that got all its data: still
     * STC_EINTERRUPTED (a stop always shows: a Python caller's KeyboardInterrupt is not
     * lost), the file complete and in place */
    h.calls = 0;
    h.stop_at = 3;
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, mute_on_last, &u),
                     STC_EINTERRUPTED);
    assert_int_equal(h.calls, 3);
    assert_non_null(strstr(stc_errmsg(c), "is complete"));
    struct stat sb;
    assert_int_equal(stat(path, &sb), 0);
    assert_int_equal(sb.st_size, (off_t)n);
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    h.stop_at = 0;
    assert_int_equal(stc_ping(c), 0);
    unlink(path);
    rmdir(dir);
    stc_close(c);
    mock_stop(m);
}

static int mute_and_stop(void *user, uint64_t done, uint64_t total)
{
    (void)done;
    (void)total;
    __atomic_store_n(&((mute_at_first *)user)->m->mute, 1, __ATOMIC_RELEASE);
    return 1;
}

/* A transfer its own progress callback stopped (Python: an exception, or Ctrl-C seen between
 * chunks) on a connection with an interrupt hook: STC_ECANCELED at once, UPLOAD_ABORT /
 * FETCH_CLOSE sent but not waited for (left36). It used to wait for the clean-up's reply
 * under the request timeout - for ever with none on a hung server; Python's hook had nothing
 * to report then (the callback had taken the Ctrl-C). The hook here never says stop and is
 * not asked at all (the wait used to ask it every 20 ms until the timeout, the bound here). */
static void a_transfer_its_caller_stopped_does_not_wait_for_its_cleanup(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    stc_conn *c = mock_connect(m, 10000);        /* a bound for the unfixed wait */
    size_t n = 40000;                                    /* 40 chunks of the mock's 1000 */
    uint8_t *data = malloc(n);
    for (size_t i = 0; i < n; i++)
        data[i] = (uint8_t)(i * 5);
    hook_count h = { 0, 0, pthread_self() };
    stc_set_interrupt(c, counting_hook, &h, 20);
    mute_at_first u = { m };
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.progress = mute_and_stop;
    o.user = &u;
    assert_int_equal(stc_upload_buffer(c, data, n, "up", &o, NULL), STC_ECANCELED);
    assert_int_equal(h.calls, 0);                        /* the abort's reply not waited for */
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the abort was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    assert_int_equal(stc_ping(c), 0);                    /* its late reply dropped */

    __atomic_store_n(&m->muted_cleanups, 0, __ATOMIC_RELEASE);
    m->fetch_len = n;
    m->fetch = data;                                     /* freed by mock_stop */
    char dir[] = "/tmp/stc-fetchstop-XXXXXX", path[300];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/out.ptx", dir);
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, mute_and_stop, &u),
                     STC_ECANCELED);
    assert_int_equal(h.calls, 0);
    assert_int_equal(st_wait_until(muted_cleanup_seen, m, 5000), 0);   /* the close was sent */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(access(path, F_OK), -1);            /* nothing left behind */

    /* without a hook the stop still waits for the clean-up's reply (as before) */
    stc_set_interrupt(c, NULL, NULL, 0);
    __atomic_store_n(&m->muted_cleanups, 0, __ATOMIC_RELEASE);
    stc_set_timeout(c, 300);
    int64_t t0 = st_now_ms();
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, mute_and_stop, &u),
                     STC_ECANCELED);
    assert_true(st_now_ms() - t0 >= 300);                /* waited, up to the timeout */
    __atomic_store_n(&m->mute, 0, __ATOMIC_RELEASE);
    stc_set_timeout(c, 10000);
    assert_int_equal(stc_ping(c), 0);
    rmdir(dir);
    stc_close(c);
    mock_stop(m);
}

/* py35: the cluster functions other than close and conn crashed on a NULL handle: each now
 * gives STC_EINVAL, or an empty answer where it returns no code (libseamtex(3)). */
static int never_called(stc_conn *c, void *arg)
{
    (void)c;
    (void)arg;
    fail_msg("fn called for a NULL handle");
    return 0;
}

static void cluster_functions_take_a_null_handle(void **state)
{
    (void)state;
    stc_cluster *cl = NULL;
    assert_int_equal(stc_cluster_refresh(cl), STC_EINVAL);
    const stc_cluster_node *nodes = (const stc_cluster_node *)&nodes;
    assert_int_equal(stc_cluster_nodes(cl, &nodes), 0);
    assert_null(nodes);
    assert_int_equal(stc_cluster_replicas(cl), 0);
    size_t idx[4];
    assert_int_equal(stc_cluster_rank(cl, "set", idx, 4), 0);
    int err = 0;
    assert_null(stc_cluster_conn(cl, 0, &err));
    assert_int_equal(err, STC_EINVAL);
    stc_conn *used = (stc_conn *)&used;
    assert_int_equal(stc_cluster_call(cl, "set", never_called, NULL, &used), STC_EINVAL);
    assert_null(used);
    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    stc_query q;
    memset(&q, 0, sizeof q);
    stc_sample_result res;
    stc_info inf;
    assert_int_equal(stc_cluster_sample(cl, "set", &so, &q, 1, &res), STC_EINVAL);
    assert_int_equal(stc_cluster_info(cl, "set", 0, 0, &inf), STC_EINVAL);
    assert_int_equal(stc_cluster_upload_file(cl, "/nonexistent", "set", NULL, NULL), STC_EINVAL);
    assert_int_equal(stc_cluster_delete(cl, "set"), STC_EINVAL);
    stc_cluster_counters cnt;
    memset(&cnt, 0xff, sizeof cnt);
    stc_cluster_get_counters(cl, &cnt);
    assert_true(cnt.calls == 0 && cnt.failovers == 0 && cnt.moved == 0 && cnt.refreshes == 0);
    uint32_t reqid;
    stc_dir_query dq;
    memset(&dq, 0, sizeof dq);
    assert_int_equal(stc_cluster_append_sample(cl, "set", &so, &q, 1, &reqid), STC_EINVAL);
    assert_int_equal(stc_cluster_append_sample_dir(cl, "set", &so, &dq, 1, &reqid), STC_EINVAL);
    assert_int_equal(stc_cluster_append_info(cl, "set", &reqid), STC_EINVAL);
    assert_int_equal(stc_cluster_flush(cl), STC_EINVAL);
    stc_cluster_reply r;
    assert_int_equal(stc_cluster_get_reply(cl, 0, &r), STC_EINVAL);
    assert_int_equal(stc_cluster_reply_sample(NULL, &res), STC_EINVAL);
    assert_int_equal(stc_cluster_reply_info(NULL, &inf), STC_EINVAL);
    assert_int_equal(stc_cluster_pending(cl), 0);
    assert_int_equal(stc_cluster_discard_pending(cl), 0);
    assert_string_equal(stc_cluster_errmsg(cl), "");
    stc_cluster_close(cl);
}

/* py35: stc_strerror said "E?" for an unknown local code and "?" for an unknown server one
 * (and "OK" for -STC_SERVER_BASE, which is no error): one answer, "?", for every unknown. */
static void strerror_has_one_name_for_every_unknown_code(void **state)
{
    (void)state;
    assert_string_equal(stc_strerror(STC_OK), "OK");
    assert_string_equal(stc_strerror(STC_EINVAL), "EINVAL");
    assert_string_equal(stc_strerror(STC_ECANCELED), "ECANCELED");
    assert_string_equal(stc_strerror(STC_EINTERRUPTED), "EINTERRUPTED");
    assert_string_equal(stc_strerror(STC_EBADREQUEST), "BAD_REQUEST");
    assert_string_equal(stc_strerror(STC_EUNAVAILABLE), "UNAVAILABLE");
    const int unknown[] = { STC_EINTERRUPTED - 1, -50, -(STC_SERVER_BASE - 1), -STC_SERVER_BASE,
                            STC_EUNAVAILABLE - 1, -(STC_SERVER_BASE + 1000), 1, 12345,
                            INT32_MIN, INT32_MAX };
    for (size_t i = 0; i < sizeof unknown / sizeof unknown[0]; i++) {
        const char *n = stc_strerror(unknown[i]);
        if (strcmp(n, "?") != 0)
            fail_msg("stc_strerror(%d) = \"%s\", not \"?\"", unknown[i], n);
    }
}

/* py35: stc_shm_request_bytes gave a size (the queries alone) for an unknown outfmt, and an
 * outfmt past 255 was cut to a known one: 0 for every unknown one now, as for n 0. */
static void shm_request_bytes_refuses_an_unknown_outfmt(void **state)
{
    (void)state;
    const unsigned known[] = { STC_OUT_F32, STC_OUT_UNORM8, STC_OUT_UNORM16, STC_OUT_F16 };
    for (int dir = 0; dir <= 1; dir++) {
        for (size_t i = 0; i < sizeof known / sizeof known[0]; i++) {
            assert_true(stc_shm_request_bytes(dir, 1000, known[i]) > 1000 * 12);
            assert_int_equal(stc_shm_request_bytes(dir, 0, known[i]), 0);
        }
        const unsigned unknown[] = { STC_OUT_F16 + 1, 255, 256, 256 + STC_OUT_F32, ~0u };
        for (size_t i = 0; i < sizeof unknown / sizeof unknown[0]; i++) {
            size_t b = stc_shm_request_bytes(dir, 1000, unknown[i]);
            if (b != 0)
                fail_msg("stc_shm_request_bytes(%d, 1000, %u) = %zu, not 0", dir, unknown[i], b);
        }
    }
}

static void fetch_writes_the_file_and_checks_crc(void **state)
{
    (void)state;
    mock *m = mock_start(M_NORMAL);
    m->fetch_len = 12345;
    m->fetch = malloc(m->fetch_len);
    for (size_t i = 0; i < m->fetch_len; i++)
        m->fetch[i] = (uint8_t)(i ^ (i >> 8));
    stc_conn *c = mock_connect(m, 5000);
    char dir[] = "/tmp/stc-fetch-XXXXXX", path[300];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/out.ptx", dir);
    progress p = { 0, 0, 0 };
    assert_int_equal(stc_fetch_file(c, "set", STC_FETCH_PTX, path, on_progress, &p), 0);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    uint8_t *got = malloc(m->fetch_len + 1);
    assert_int_equal(fread(got, 1, m->fetch_len + 1, f), m->fetch_len);
    fclose(f);
    assert_memory_equal(got, m->fetch, m->fetch_len);
    assert_int_equal(p.last, m->fetch_len);
    free(got);
    unlink(path);
    rmdir(dir);
    stc_close(c);
    mock_stop(m);
}

/* ---- against the real daemon ---------------------------------------------------------------------- */

typedef struct real {
    st_daemon d;
    int up;
} real;

static int real_setup(void **state)
{
    static real r;
    memset(&r, 0, sizeof r);
    *state = &r;
    if (st_daemon_init(&r.d) == 0 && st_daemon_start(&r.d, NULL) == 0)
        r.up = 1;
    return 0;
}

static int real_teardown(void **state)
{
    real *r = *state;
    st_daemon_cleanup(&r->d);
    return 0;
}

static stc_conn *real_connect(real *r)
{
    int err = 0;
    char msg[256];
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 20000;
    stc_conn *c = stc_connect_opts(r->d.host, (unsigned)r->d.port, &o, &err, msg, sizeof msg);
    if (!c)
        fail_msg("connect to seamtexd: %s", msg);
    return c;
}

static void real_daemon_end_to_end(void **state)
{
    real *r = *state;
    char path[512];
    if (!r->up)
        skip();   /* seamtexd missing or failed to start (see the fixture's message) */
    if (st_daemon_data_path(path, sizeof path, "ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx")) {
        fprintf(stderr, "# SEAMTEX_DATA missing: skipping the upload round trip\n");
        skip();
    }
    stc_conn *c = real_connect(r);
    assert_int_equal(stc_ping(c), 0);
    assert_true(stc_server_info(c)->max_body > 0);

    stc_upload_result up;
    int rc = stc_upload_file(c, path, "wave", NULL, &up);
    if (rc)
        fail_msg("upload: %s: %s", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(up.nfaces, 9);
    assert_int_equal(up.nchan, 1);

    const stc_set_entry *sets;
    size_t n, i;
    assert_int_equal(stc_list(c, &sets, &n), 0);
    for (i = 0; i < n && strcmp(sets[i].name, "wave") != 0; i++)
        ;
    assert_true(i < n);
    assert_int_equal(sets[i].nfaces, 9);

    stc_info inf;
    assert_int_equal(stc_info_get(c, "wave", 0, 9, &inf), 0);
    assert_int_equal(inf.nfaces, 9);
    assert_int_equal(inf.dtype, 1);                 /* uint16 */
    assert_int_equal(inf.max_w, 32);
    assert_int_equal(inf.nrec, 9);
    assert_int_equal(inf.faces[0].nlevels > 0, 1);

    stc_query q[4] = { { 0, 0.5f, 0.5f, 0.01f, 0, 0, 0.01f }, { 8, 0.1f, 0.9f, 0, 0, 0, 0 },
                       { 9, 0.5f, 0.5f, 0, 0, 0, 0 }, { 0, NAN, 0.5f, 0, 0, 0, 0 } };
    stc_sample_opts so;
    stc_sample_result res;
    memset(&so, 0, sizeof so);
    so.mode = 1;
    so.filter = 1;
    so.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    rc = stc_sample(c, "wave", &so, q, 4, &res);
    if (rc)
        fail_msg("sample: %s: %s", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(res.count, 4);
    assert_int_equal(res.nchan, 1);
    assert_int_equal(res.status[0], 0);
    assert_int_equal(res.status[2], 1);             /* face out of range */
    assert_int_equal(res.status[3], 2);             /* NaN */
    assert_int_equal(res.nbad, 2);
    assert_true(isfinite(((const float *)res.values)[0]));

    const stc_stat *st;
    size_t nst;
    assert_int_equal(stc_stats(c, &st, &nst), 0);
    assert_true(nst > 0);

    assert_int_equal(stc_info_get(c, "no_such_set", 0, 0, &inf), STC_ENOTFOUND);
    assert_int_equal(stc_delete(c, "wave"), 0);
    assert_int_equal(stc_info_get(c, "wave", 0, 0, &inf), STC_ENOTFOUND);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
}

static void real_daemon_answers_malformed_requests_with_statuses(void **state)
{
    real *r = *state;
    if (!r->up)
        skip();
    stc_conn *c = real_connect(r);
    uint32_t id;
    stc_reply rp;

    /* unknown opcode */
    assert_int_equal(stc_append_raw(c, 0x7E, NULL, 0, &id), 0);
    assert_int_equal(stc_get_reply(c, 5000, &rp), 0);
    assert_int_equal(rp.status, STC_EUNKNOWNOP);

    /* a SAMPLE whose count lies about the body */
    uint8_t body[2 + 3 + 24 + 28];
    memset(body, 0, sizeof body);
    stp_wr16(body, 3);
    memcpy(body + 2, "tex", 3);
    stp_wr32(body + 2 + 3 + 20, 5);                 /* says 5 queries, carries 1 */
    assert_int_equal(stc_append_raw(c, STP_OP_SAMPLE, body, sizeof body, &id), 0);
    assert_int_equal(stc_get_reply(c, 5000, &rp), 0);
    assert_int_equal(rp.status, STC_EBADREQUEST);

    /* a body over the server's cap is answered TOO_LARGE and skipped */
    uint32_t cap = stc_server_info(c)->max_body;
    if (cap && cap < (64u << 20)) {
        uint8_t *big = calloc(1, (size_t)cap + 1);
        assert_int_equal(stc_append_raw(c, STP_OP_PING, big, (size_t)cap + 1, &id), 0);
        assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
        assert_int_equal(rp.status, STC_ETOOLARGE);
        free(big);
    }
    /* and the connection still works */
    assert_int_equal(stc_ping(c), 0);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
}

static int count_progress(void *user, uint64_t done, uint64_t total)
{
    progress *p = user;
    if (done < p->last || done > total)
        return 1;                      /* a regression: stop (the test then fails) */
    p->last = done;
    p->calls++;
    return 0;
}

static void real_daemon_transfers_and_pipelines(void **state)
{
    real *r = *state;
    char path[512], fetched[300], dir[] = "/tmp/stc-e2e-XXXXXX";
    if (!r->up)
        skip();
    if (st_daemon_data_path(path, sizeof path, "ptx/wdas-ptex-2009/cube/text/cube.ptx")) {
        fprintf(stderr, "# SEAMTEX_DATA missing: skipping\n");
        skip();
    }
    stc_conn *c = real_connect(r);
    /* a multi-chunk upload (2.37 MB in 256 KiB chunks) with progress */
    progress p = { 0, 0, 0 };
    stc_upload_opts uo;
    stc_upload_result up;
    memset(&uo, 0, sizeof uo);
    uo.chunk = 256 << 10;
    uo.progress = count_progress;
    uo.user = &p;
    int rc = stc_upload_file(c, path, "cube_text", &uo, &up);
    if (rc)
        fail_msg("upload: %s: %s", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(up.nfaces, 72);
    assert_true(p.calls >= 9);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_int_equal(p.last, (uint64_t)st.st_size);
    /* the same name again without REPLACE: EXISTS; with REPLACE: fine */
    assert_int_equal(stc_upload_file(c, path, "cube_text", NULL, &up), STC_EEXISTS);
    uo.flags = STC_UPLOAD_REPLACE;
    uo.progress = NULL;
    assert_int_equal(stc_upload_file(c, path, "cube_text", &uo, &up), 0);

    /* pipelined batches against the real sampler */
    stc_query q[64];
    for (int i = 0; i < 64; i++) {
        stc_query x = { (uint32_t)i, (i % 8) / 8.0f + 0.05f, (i / 8) / 8.0f + 0.05f, 0.002f, 0,
                        0, 0.002f };
        q[i] = x;
    }
    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    so.mode = 1;
    so.filter = 2;
    so.outfmt = STC_OUT_UNORM8;
    uint32_t ids[8];
    for (int k = 0; k < 8; k++)
        assert_int_equal(stc_append_sample(c, "cube_text", &so, q, 64, &ids[k]), 0);
    assert_int_equal(stc_flush(c), 0);
    stc_sample_result res;
    for (int k = 0; k < 8; k++) {
        stc_reply rp;
        assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
        assert_int_equal(rp.status, 0);
        assert_int_equal(stc_reply_sample(c, &rp, &res), 0);
        assert_int_equal(res.count, 64);
        assert_int_equal(res.nchan, 1);
        assert_int_equal(res.nbad, 0);
    }
    /* the same queries blocking give the same bytes as a pipelined reply */
    const uint8_t *last = res.values;
    uint8_t keep[64];
    memcpy(keep, last, 64);
    assert_int_equal(stc_sample(c, "cube_text", &so, q, 64, &res), 0);
    assert_memory_equal(res.values, keep, 64);

    /* fetch as .ptx, upload the fetched file under another name, compare */
    if (stc_server_info(c)->caps & STP_CAP_FETCH) {
        assert_non_null(mkdtemp(dir));
        snprintf(fetched, sizeof fetched, "%s/cube.ptx", dir);
        rc = stc_fetch_file(c, "cube_text", STC_FETCH_PTX, fetched, NULL, NULL);
        if (rc)
            fail_msg("fetch: %s: %s", stc_strerror(rc), stc_errmsg(c));
        assert_int_equal(stc_upload_file(c, fetched, "cube_again", NULL, &up), 0);
        assert_int_equal(up.nfaces, 72);
        stc_sample_result res2;
        assert_int_equal(stc_sample(c, "cube_again", &so, q, 64, &res2), 0);
        assert_memory_equal(res2.values, keep, 64);
        unlink(fetched);
        rmdir(dir);
        assert_int_equal(stc_delete(c, "cube_again"), 0);
    }
    /* a compress job, polled to the end */
    if (stc_server_info(c)->caps & STP_CAP_COMPRESS) {
        uint64_t job;
        stc_job j;
        assert_int_equal(stc_compress(c, "cube_text", "cube_bc1", 1, STC_COMPRESS_SEAM_AWARE,
                                      &job), 0);
        rc = stc_job_wait(c, job, 300000, &j) /* a hang guard, not a speed check */;
        if (rc)
            fail_msg("job: %s: %s", stc_strerror(rc), stc_errmsg(c));
        assert_int_equal(j.state, STC_JOB_DONE);
        stc_info inf;
        assert_int_equal(stc_info_get(c, "cube_bc1", 0, 0, &inf), 0);
        assert_int_equal(inf.kind, 3);
        assert_int_equal(stc_job_status(c, job + 1000, &j), STC_ENOTFOUND);
        assert_int_equal(stc_delete(c, "cube_bc1"), 0);
    }
    assert_int_equal(stc_delete(c, "cube_text"), 0);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
}

static void real_daemon_samples_cube_maps_by_direction(void **state)
{
    real *r = *state;
    char path[512];
    if (!r->up)
        skip();
    if (st_daemon_data_path(path, sizeof path, "env/StageEnvLatLong.exr")) {
        fprintf(stderr, "# SEAMTEX_DATA missing: skipping\n");
        skip();
    }
    stc_conn *c = real_connect(r);
    if (!(stc_server_info(c)->caps & STP_CAP_SAMPLE_DIR)) {
        stc_close(c);
        skip();
    }
    stc_upload_opts uo;
    stc_upload_result up;
    memset(&uo, 0, sizeof uo);
    uo.options = "cube=latlong:64";
    int rc = stc_upload_file(c, path, "env64", &uo, &up);
    if (rc)
        fail_msg("upload: %s: %s", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(up.kind, 1);                   /* cube map */
    assert_int_equal(up.nfaces, 6);
    stc_dir_query q[4] = { { { 1, 0, 0 }, { 0, 0.01f, 0 }, { 0, 0, 0.01f } },
                           { { 0, 0, -2 }, { 0, 0, 0 }, { 0, 0, 0 } },
                           { { 0, 0, 0 }, { 0, 0, 0 }, { 0, 0, 0 } },
                           { { NAN, 1, 0 }, { 0, 0, 0 }, { 0, 0, 0 } } };
    stc_sample_opts so;
    stc_sample_result res;
    memset(&so, 0, sizeof so);
    so.mode = 1;
    so.filter = 2;
    so.want = STC_WANT_STATUS | STC_WANT_COVERAGE;
    rc = stc_sample_dir(c, "env64", &so, q, 4, &res);
    if (rc)
        fail_msg("sample_dir: %s: %s", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(res.count, 4);
    assert_int_equal(res.nchan, 3);
    assert_int_equal(res.status[0], 0);
    assert_int_equal(res.status[1], 0);
    assert_int_not_equal(res.status[2], 0);         /* a zero direction is not a direction */
    assert_int_not_equal(res.status[3], 0);         /* NaN */
    assert_int_equal(res.nbad, 2);
    const float *v = res.values;
    for (int k = 0; k < 6; k++)
        assert_true(isfinite(v[k]));
    /* a cone footprint */
    so.footprint = 1;
    stc_dir_query cone = { { 0, 1, 0 }, { 0.05f, 0, 0 }, { 0, 0, 0 } };
    assert_int_equal(stc_sample_dir(c, "env64", &so, &cone, 1, &res), 0);
    assert_int_equal(res.status[0], 0);
    /* direction sampling of a per-face set is refused, the connection stays fine */
    stc_sample_opts po = so;
    po.footprint = 0;
    rc = stc_sample_dir(c, "default", &po, q, 1, &res);
    assert_true(stc_is_server_error(rc));
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_delete(c, "env64"), 0);
    stc_close(c);
}

static void real_daemon_deep_pipeline_does_not_deadlock(void **state)
{
    real *r = *state;
    if (!r->up)
        skip();
    stc_conn *c = real_connect(r);
    /* far more requests than max_inflight, each reply bigger than its request, nothing read
     * until everything is sent: flush must keep reading replies while it writes */
    enum { N = 3000, Q = 64 };
    stc_query q[Q];
    for (int i = 0; i < Q; i++) {
        stc_query x = { (uint32_t)(i % 384), 0.5f, 0.5f, 0, 0, 0, 0 };
        q[i] = x;
    }
    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    so.filter = 1;
    so.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    static uint32_t ids[N];
    for (int k = 0; k < N; k++)
        assert_int_equal(stc_append_sample(c, "default", &so, q, Q, &ids[k]), 0);
    assert_int_equal(stc_flush(c), 0);
    for (int k = 0; k < N; k++) {
        stc_reply rp;
        stc_sample_result res;
        int rc = stc_get_reply(c, 20000, &rp);
        if (rc)
            fail_msg("reply %d: %s: %s", k, stc_strerror(rc), stc_errmsg(c));
        assert_int_equal(rp.status, 0);
        assert_int_equal(rp.reqid, ids[k]);
        assert_int_equal(stc_reply_sample(c, &rp, &res), 0);
        assert_int_equal(res.count, Q);
    }
    assert_int_equal(stc_pending(c), 0);
    stc_close(c);
}

static int stop_after_first(void *user, uint64_t done, uint64_t total)
{
    (void)done;
    (void)total;
    return ++*(int *)user >= 1;
}

static void real_daemon_upload_abort_and_checksum(void **state)
{
    real *r = *state;
    char path[512];
    if (!r->up)
        skip();
    if (st_daemon_data_path(path, sizeof path, "ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx")) {
        fprintf(stderr, "# SEAMTEX_DATA missing: skipping\n");
        skip();
    }
    stc_conn *c = real_connect(r);
    stc_info inf;
    /* cancelled after the first chunk: aborted, no set, the name stays free */
    int calls = 0;
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.chunk = 1024;
    uo.progress = stop_after_first;
    uo.user = &calls;
    assert_int_equal(stc_upload_file(c, path, "half", &uo, NULL), STC_ECANCELED);
    assert_int_equal(stc_info_get(c, "half", 0, 0, &inf), STC_ENOTFOUND);
    assert_int_equal(stc_upload_file(c, path, "half", NULL, NULL), 0);
    assert_int_equal(stc_info_get(c, "half", 0, 0, &inf), 0);
    assert_int_equal(stc_delete(c, "half"), 0);

    /* a wrong CRC32C is CORRUPT at commit and leaves nothing behind (raw frames) */
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    uint8_t data[8192];
    size_t n = fread(data, 1, sizeof data, fp);
    fclose(fp);
    stp_buf b;
    stp_buf_init(&b);
    stp_upload_begin bg;
    memset(&bg, 0, sizeof bg);
    strcpy(bg.name, "bad_crc");
    strcpy(bg.hint, "ptx");
    bg.total_size = n;
    bg.crc32c = stp_crc32c(0, data, n) ^ 1;
    assert_int_equal(stp_enc_upload_begin(&b, 0, 0, &bg), 0);
    uint32_t id;
    stc_reply rp;
    assert_int_equal(stc_append_raw(c, STP_OP_UPLOAD_BEGIN, b.data + STP_HEADER_SIZE,
                                    b.len - STP_HEADER_SIZE, &id), 0);
    assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
    assert_int_equal(rp.status, 0);
    stp_upload_begin_reply br;
    assert_int_equal(stp_dec_upload_begin_reply(rp.body, rp.body_len, &br, NULL), 0);
    stp_buf_clear(&b);
    stp_upload_chunk ch = { br.upload_id, 0, (uint32_t)n, data };
    assert_int_equal(stp_enc_upload_chunk(&b, 0, 0, &ch), 0);
    assert_int_equal(stc_append_raw(c, STP_OP_UPLOAD_CHUNK, b.data + STP_HEADER_SIZE,
                                    b.len - STP_HEADER_SIZE, &id), 0);
    assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
    assert_int_equal(rp.status, 0);
    uint8_t idb[8];
    stp_wr64(idb, br.upload_id);
    assert_int_equal(stc_append_raw(c, STP_OP_UPLOAD_COMMIT, idb, 8, &id), 0);
    assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
    assert_int_equal(rp.status, STC_ECORRUPT);
    assert_int_equal(stc_info_get(c, "bad_crc", 0, 0, &inf), STC_ENOTFOUND);
    /* a chunk for an upload that does not exist */
    ch.upload_id = br.upload_id + 777;
    stp_buf_clear(&b);
    assert_int_equal(stp_enc_upload_chunk(&b, 0, 0, &ch), 0);
    assert_int_equal(stc_append_raw(c, STP_OP_UPLOAD_CHUNK, b.data + STP_HEADER_SIZE,
                                    b.len - STP_HEADER_SIZE, &id), 0);
    assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
    assert_int_equal(rp.status, STC_ENOTFOUND);
    stp_buf_free(&b);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
}

static void real_daemon_requires_the_token_for_mutations(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = { "--token", "s3cret", NULL };
    if (st_daemon_init(&d) != 0 || st_daemon_start(&d, extra) != 0) {
        st_daemon_cleanup(&d);
        skip();
    }
    stc_opts o;
    int err = 0;
    char msg[256];
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 20000;
    stc_conn *c = stc_connect_opts(d.host, (unsigned)d.port, &o, &err, msg, sizeof msg);
    if (!c) {
        st_daemon_cleanup(&d);
        fail_msg("connect: %s", msg);
    }
    assert_true(stc_server_info(c)->caps & STP_CAP_AUTH);
    assert_false(stc_server_info(c)->authenticated);
    assert_int_equal(stc_ping(c), 0);                       /* reads need no token */
    assert_int_equal(stc_delete(c, "default"), STC_EPERM);
    assert_int_equal(stc_error(c), 0);
    stc_close(c);

    o.token = "wrong";
    c = stc_connect_opts(d.host, (unsigned)d.port, &o, &err, msg, sizeof msg);
    assert_non_null(c);
    assert_false(stc_server_info(c)->authenticated);
    assert_int_equal(stc_upload_buffer(c, "x", 1, "t1", NULL, NULL), STC_EPERM);
    stc_close(c);

    o.token = "s3cret";
    c = stc_connect_opts(d.host, (unsigned)d.port, &o, &err, msg, sizeof msg);
    assert_non_null(c);
    assert_true(stc_server_info(c)->authenticated);
    /* allowed now: the garbage file is refused for what it is, not for permission */
    int rc = stc_upload_buffer(c, "not a texture", 13, "t1", NULL, NULL);
    assert_int_not_equal(rc, STC_EPERM);
    assert_true(stc_is_server_error(rc));
    assert_int_equal(stc_error(c), 0);
    stc_close(c);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest mock_tests[] = {
        cmocka_unit_test(connect_reports_hello_limits),
        cmocka_unit_test(connect_to_closed_port_fails_with_message),
        cmocka_unit_test(connect_timeout_covers_a_silent_hello),
        cmocka_unit_test(request_timeout_does_not_poison_the_connection),
        cmocka_unit_test(protocol_violation_is_sticky),
        cmocka_unit_test(server_close_is_sticky),
        cmocka_unit_test(server_status_is_not_sticky),
        cmocka_unit_test(oversized_reply_fails_that_request_only),
        cmocka_unit_test(unsolicited_busy_fails_connect_with_busy),
        cmocka_unit_test(pipelined_pings_are_matched_by_reqid),
        cmocka_unit_test(pipelined_timeout_keeps_the_reply_coming),
        cmocka_unit_test(send_timeout_keeps_the_rest_queued),
        cmocka_unit_test(appends_to_a_server_that_never_reads_are_bounded),
        cmocka_unit_test(sample_results_in_every_format),
        cmocka_unit_test(upload_sends_chunks_with_checksum_and_aborts_on_cancel),
        cmocka_unit_test(fetch_writes_the_file_and_checks_crc),
        cmocka_unit_test(a_batch_over_2_32_queries_is_refused_not_dropped),
        cmocka_unit_test(upload_refuses_a_long_hint_and_unknown_flags),
        cmocka_unit_test(a_child_after_fork_cannot_use_the_parents_connection),
        cmocka_unit_test(cluster_open_takes_a_null_err_and_conn_checks_its_index),
        cmocka_unit_test(strerror_has_one_name_for_every_unknown_code),
        cmocka_unit_test(shm_request_bytes_refuses_an_unknown_outfmt),
        cmocka_unit_test(cluster_functions_take_a_null_handle),
        cmocka_unit_test(a_timed_out_transfer_waits_briefly_for_its_cleanup),
        cmocka_unit_test(interrupt_hook_stops_a_wait_and_leaves_the_connection_usable),
        cmocka_unit_test(interrupt_hook_is_asked_when_a_signal_interrupts_the_wait),
        cmocka_unit_test(interrupt_hook_stops_a_connect),
        cmocka_unit_test(interrupt_hook_stops_a_transfer_without_waiting_for_its_cleanup),
        cmocka_unit_test(a_transfer_its_caller_stopped_does_not_wait_for_its_cleanup),
    };
    const struct CMUnitTest real_tests[] = {
        cmocka_unit_test(real_daemon_end_to_end),
        cmocka_unit_test(real_daemon_answers_malformed_requests_with_statuses),
        cmocka_unit_test(real_daemon_transfers_and_pipelines),
        cmocka_unit_test(real_daemon_samples_cube_maps_by_direction),
        cmocka_unit_test(real_daemon_deep_pipeline_does_not_deadlock),
        cmocka_unit_test(real_daemon_upload_abort_and_checksum),
        cmocka_unit_test(real_daemon_requires_the_token_for_mutations),
    };
    int fails = cmocka_run_group_tests_name("client_mock", mock_tests, NULL, NULL);
    fails += cmocka_run_group_tests_name("client_daemon", real_tests, real_setup, real_teardown);
    return fails;
}
