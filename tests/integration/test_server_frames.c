/* tests/integration/test_server_frames.c - seamtexd on the raw wire: the malformed-frame
 * table (bad magic and version, unknown opcode, lying lengths, truncated headers, bodies over
 * the caps, NaN queries), each on its own connection, and the server still serving after;
 * pipelines of big SAMPLE frames (the daemon's split reads) answered as each frame alone.
 *
 * One daemon with defaults for the group (tests/common/daemon_fixture.h) on 127.0.0.1 port 0;
 * frames are written byte by byte (tests/common/wire.h). Nothing here needs SEAMTEX_DATA.
 */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"
#include "sample.h"

/* ---- helpers --------------------------------------------------------------------------------- */

/* Waiting for the daemon to have read `more` bytes from other connections since bytes_in was
 * `base` (read through sc): every STATS request on sc adds its own 24-byte frame. */
typedef struct bytes_cond {
    stc_conn *sc;
    uint64_t base, more, asked;
} bytes_cond;

static int read_enough(void *arg)
{
    bytes_cond *b = arg;
    uint64_t v = st_conn_stat(b->sc, "bytes_in");
    b->asked++;
    return v != UINT64_MAX && v >= b->base + b->asked * ST_WIRE_HEADER + b->more;
}

static int wait_bytes_in(stc_conn *sc, uint64_t base, uint64_t more)
{
    bytes_cond b = {sc, base, more, 0};
    return st_wait_until(read_enough, &b, 10000);
}

/* the group's daemon: defaults, --heavy-batch 2048 (set in main) */
#define D1 ST_GROUP

/* ---- tests ---------------------------------------------------------------------------------- */

/* The malformed-frame table: each row is sent on its own connection, followed by a PING; the
 * expected status comes back (or the connection is closed, for a bad magic) and a separate
 * connection is served normally afterwards. */
static void malformed_frames_get_their_status(void **state)
{
    (void)state;
    float good[7] = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    float nanq[14] = {0, NAN, 0.5f, 0, 0, 0, 0, 1, 0.25f, 0.25f, 0, 0, 0, 0};
    struct row {
        const char *what;
        int kind;          /* 0 frame with body, 1 bad magic, 2 truncated header, 3 huge */
        unsigned version, op, flags;
        int body;          /* 0 none, 1 lying sample count, 2 zero batch, 3 NaN queries,
                              4 trailing byte, 5 one good query */
        int status;        /* expected; -1 = connection closed */
        uint32_t nbad;     /* SAMPLE rows: expected nbad */
    } rows[] = {
        {"bad magic", 1, 1, STP_OP_PING, 0, 0, -1, 0},
        {"bad version", 0, 7, STP_OP_PING, 0, 0, STP_S_BAD_VERSION, 0},
        {"unknown opcode", 0, 1, 0x5e, 0, 0, STP_S_UNKNOWN_OPCODE, 0},
        {"reply flag in a request", 0, 1, STP_OP_PING, STP_F_REPLY, 0, STP_S_BAD_REQUEST, 0},
        {"truncated header then more", 2, 1, STP_OP_PING, 0, 0, STP_S_OK, 0},
        {"body over max-frame", 3, 1, STP_OP_PING, 0, 0, STP_S_TOO_LARGE, 0},
        {"INFO body over its cap", 3, 1, STP_OP_INFO, 0, 0, STP_S_TOO_LARGE, 0},
        {"lying count in SAMPLE", 0, 1, STP_OP_SAMPLE, 0, 1, STP_S_BAD_REQUEST, 0},
        {"zero-length batch", 0, 1, STP_OP_SAMPLE, 0, 2, STP_S_OK, 0},
        {"NaN query", 0, 1, STP_OP_SAMPLE, 0, 3, STP_S_OK, 1},
        {"trailing byte in SAMPLE", 0, 1, STP_OP_SAMPLE, 0, 4, STP_S_BAD_REQUEST, 0},
        {"one good query", 0, 1, STP_OP_SAMPLE, 0, 5, STP_S_OK, 0},
        {"empty STATS body with bytes", 0, 1, STP_OP_STATS, 0, 5, STP_S_BAD_REQUEST, 0},
    };
    uint8_t *frame = malloc((1 << 16) + 64), body[4096];
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const struct row *w = &rows[i];
        int fd = st_daemon_connect(&D1);
        assert_true(fd >= 0);
        size_t bl = 0;
        uint32_t claimed;
        switch (w->body) {
        case 1: bl = st_wire_sample_body(body, "default", 3, good, 1); break;
        case 2: bl = st_wire_sample_body(body, "default", 0, good, 0); break;
        case 3: bl = st_wire_sample_body(body, "default", 2, nanq, 2); break;
        case 4: bl = st_wire_sample_body(body, "default", 1, good, 1); body[bl++] = 0; break;
        case 5: bl = st_wire_sample_body(body, "default", 1, good, 1); break;
        default: bl = 0; break;
        }
        claimed = (uint32_t)bl;
        size_t fl;
        if (w->kind == 1) {
            fl = st_wire_frame(frame, "STY1", 1, w->op, 0, 100 + (uint32_t)i, NULL, 0, 0);
            assert_int_equal(st_wire_send_all(fd, frame, fl), 0);
        } else if (w->kind == 2) {
            fl = st_wire_frame(frame, "STX1", 1, w->op, 0, 100 + (uint32_t)i, "xy", 2, 2);
            /* the server must have read the first 10 bytes on their own before the rest goes */
            stc_conn *sc = st_daemon_client(&D1, NULL);
            assert_non_null(sc);
            uint64_t in0 = st_conn_stat(sc, "bytes_in");
            assert_int_equal(st_wire_send_all(fd, frame, 10), 0);
            assert_int_equal(wait_bytes_in(sc, in0, 10), 0);
            stc_close(sc);
            assert_int_equal(st_wire_send_all(fd, frame + 10, fl - 10), 0);
        } else if (w->kind == 3) {
            /* claims a huge body and sends 64 KiB of it: the server must skip, not store */
            uint32_t huge = w->op == STP_OP_PING ? (100u << 20) : 65536;
            fl = st_wire_frame(frame, "STX1", 1, w->op, 0, 100 + (uint32_t)i, NULL, 0, huge);
            memset(frame + fl, 0xAB, 65536);
            assert_int_equal(st_wire_send_all(fd, frame, fl + 65536), 0);
            if (w->op == STP_OP_PING) {
                /* the rest of the 100 MiB would be skipped too; close instead of sending it */
            }
        } else {
            fl = st_wire_frame(frame, "STX1", w->version, w->op, w->flags, 100 + (uint32_t)i, body,
                           (uint32_t)bl, claimed);
            assert_int_equal(st_wire_send_all(fd, frame, fl), 0);
        }
        st_wire_reply r;
        if (w->status < 0) {
            assert_true(st_wire_peer_closed(fd, 5000));
        } else {
            int rc = st_wire_read_reply(fd, &r, 5000);
            if (rc != 0)
                fprintf(stderr, "row '%s': no reply\n", w->what);
            assert_int_equal(rc, 0);
            if ((int)r.status != w->status)
                fprintf(stderr, "row '%s': status %u, want %d (%.*s)\n", w->what, r.status,
                        w->status, (int)r.len, (const char *)r.body);
            assert_int_equal(r.status, w->status);
            assert_int_equal(r.reqid, 100 + (uint32_t)i);
            assert_true(r.flags & STP_F_REPLY);
            if (w->op == STP_OP_SAMPLE && w->status == STP_S_OK) {
                assert_int_equal(stp_rd32(r.body + 8), w->nbad);
                if (w->body == 3) {  /* the NaN query: status NONFINITE, the other OK */
                    uint32_t cnt = stp_rd32(r.body);
                    assert_int_equal(cnt, 2);
                    const uint8_t *stat = r.body + 12 + 2 * 4 * 4;
                    assert_int_equal(stat[0], ST_Q_NONFINITE);
                    assert_int_equal(stat[1], ST_Q_OK);
                }
            }
            /* the same connection still serves (except after a skipped 100 MiB body) */
            if (!(w->kind == 3 && w->op == STP_OP_PING)) {
                if (w->kind == 3) {
                    /* INFO claimed 64 KiB, all of it sent: it was skipped */
                }
                fl = st_wire_frame(frame, "STX1", 1, STP_OP_PING, 0, 999, "ok", 2, 2);
                assert_int_equal(st_wire_send_all(fd, frame, fl), 0);
                assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
                assert_int_equal(r.reqid, 999);
                assert_int_equal(r.status, 0);
            }
        }
        close(fd);
        /* another connection is served */
        stc_conn *c = st_daemon_client(&D1, NULL);
        assert_non_null(c);
        assert_int_equal(stc_ping(c), 0);
        stc_close(c);
    }
    free(frame);
}

/* ---- split reads --------------------------------------------------------------------------- */

/* Reads one reply frame whole (any body length) into buf (cap bytes). Its length, or 0. */
static size_t read_frame(int fd, uint8_t *buf, size_t cap)
{
    size_t got = 0, want = ST_WIRE_HEADER;
    while (got < want) {
        ssize_t r = recv(fd, buf + got, want - got, 0);
        if (r <= 0)
            return 0;
        got += (size_t)r;
        if (got == ST_WIRE_HEADER && want == ST_WIRE_HEADER) {
            want += stp_rd32(buf + 16);
            if (want > cap)
                return 0;
        }
    }
    return got;
}

/* A read of a big SAMPLE frame ends at the frame's end and what follows lands in a second
 * buffer (io.c, split reads), guessed from the last frame's length: pipelined SAMPLE frames
 * of different sizes and set names (so different pads), with PINGs between, sent whole,
 * trickled in pieces that end anywhere, or in groups after the last group's replies (so each
 * group's first read is split where the last frame's length says: at a frame's end, inside a
 * frame's body, inside its header), get byte for byte the replies each gets alone. */
static void split_reads_answer_every_pipeline_like_single_frames(void **state)
{
    (void)state;
    static const struct { const char *set; uint32_t n; int group; } shape[] = {
        {"default", 1024, 0},
        {"default", 2048, 1}, {"default", 1024, 1},              /* guess short: in a body */
        /* 10 bytes shorter than the 1024-query frame before: the guess ends in a header */
        {"xxxxxxxxxxxxxxxxxxxxxxxxx", 1023, 2}, {"default", 1024, 2},
        {"default", 700, 3}, {"", 0, 3}, {"default", 3000, 3},
        {"default", 3000, 4}, {"defaultx", 1024, 4}, {"abc", 800, 4}, {"default", 4096, 4},
    };
    enum { NF = sizeof shape / sizeof shape[0] };
    size_t cap = 64 + 34 + 32 + 28 * 4096;
    uint8_t *all = malloc(NF * cap), *body = malloc(cap), *got = malloc(cap);
    uint8_t *want[NF];
    size_t want_len[NF], off[NF + 1];
    float *q = malloc(sizeof(float) * 7 * 4096);
    assert_non_null(all);
    assert_non_null(body);
    assert_non_null(got);
    assert_non_null(q);
    for (uint32_t i = 0; i < 4096; i++) {
        float t = (float)i / 4096.0f;
        float qi[7] = {0, t, 1.0f - t * 0.5f, 0.01f, 0, 0, 0.01f};
        memcpy(q + 7 * i, qi, sizeof qi);
    }
    off[0] = 0;
    for (int i = 0; i < NF; i++) {
        size_t bl, fl;
        if (shape[i].n) {
            bl = st_wire_sample_body(body, shape[i].set, shape[i].n, q, shape[i].n);
            fl = st_wire_frame(all + off[i], "STX1", 1, STP_OP_SAMPLE, 0, 500 + (uint32_t)i, body,
                               (uint32_t)bl, (uint32_t)bl);
        } else {
            fl = st_wire_frame(all + off[i], "STX1", 1, STP_OP_PING, 0, 500 + (uint32_t)i, "pp",
                               2, 2);
        }
        off[i + 1] = off[i] + fl;
        /* the reference: the frame alone on a connection of its own */
        int fd = st_daemon_connect(&D1);
        assert_true(fd >= 0);
        assert_int_equal(st_wire_send_all(fd, all + off[i], fl), 0);
        want_len[i] = read_frame(fd, got, cap);
        assert_true(want_len[i] > 0);
        /* the set `default` samples (OK); the other names are unknown (an error reply) */
        int known = !shape[i].n || !strcmp(shape[i].set, "default");
        assert_int_equal(stp_rd16(got + 12) == STP_S_OK, known);
        want[i] = malloc(want_len[i]);
        assert_non_null(want[i]);
        memcpy(want[i], got, want_len[i]);
        close(fd);
    }
    assert_int_equal(off[4] - off[3], off[3] - off[2] - 10);
    /* whole, in groups, then in pieces of odd sizes with pauses (reads that end anywhere) */
    static const size_t piece[] = {0, 1, 7001, 40000, 16411};
    for (size_t p = 0; p < sizeof piece / sizeof piece[0]; p++) {
        int fd = st_daemon_connect(&D1);
        assert_true(fd >= 0);
        int next = 0;   /* the first reply not read */
        for (int i = 0; i < NF; i++) {
            if (piece[p] == 1 && (i == NF - 1 || shape[i + 1].group != shape[i].group)) {
                int g0 = next;
                assert_int_equal(st_wire_send_all(fd, all + off[g0], off[i + 1] - off[g0]), 0);
                for (; next <= i; next++) {
                    size_t n = read_frame(fd, got, cap);
                    assert_int_equal(n, want_len[next]);
                    assert_memory_equal(got, want[next], n);
                }
            }
        }
        if (!piece[p]) {
            assert_int_equal(st_wire_send_all(fd, all, off[NF]), 0);
        } else if (piece[p] > 1) {
            for (size_t o = 0; o < off[NF]; o += piece[p]) {
                size_t n = off[NF] - o < piece[p] ? off[NF] - o : piece[p];
                assert_int_equal(st_wire_send_all(fd, all + o, n), 0);
                usleep(2000);
            }
        }
        for (; next < NF; next++) {
            size_t n = read_frame(fd, got, cap);
            if (n != want_len[next] || memcmp(got, want[next], n) != 0)
                fprintf(stderr, "pieces of %zu: reply %d differs (%zu bytes, want %zu)\n",
                        piece[p], next, n, want_len[next]);
            assert_int_equal(n, want_len[next]);
            assert_memory_equal(got, want[next], n);
        }
        close(fd);
    }
    for (int i = 0; i < NF; i++)
        free(want[i]);
    free(all);
    free(body);
    free(got);
    free(q);
}

/* PROTOCOL.md 2.1: after a bad magic the replies already queued still go out, then the
 * connection ends. The daemon used to close the socket with the garbage that followed still
 * unread, which makes the kernel reset the connection and drop what of the replies it had
 * not sent yet. Here a SAMPLE whose reply (about 3 MB) outgrows the socket buffers is followed
 * by a bad magic and more garbage, sent before the client reads anything: the whole reply must
 * arrive, then the end of stream. */
static void a_bad_magic_after_a_big_reply_does_not_cut_it(void **state)
{
    (void)state;
    enum { NQ = 131072 };
    size_t flen;
    uint8_t *frame = st_default_sample_frame(NQ, 9, 5, &flen);
    assert_non_null(frame);
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    assert_int_equal(st_wire_send_all(fd, frame, flen), 0);
    static uint8_t junk[65536];
    memset(junk, 'x', sizeof junk);   /* "xxxx": not the magic */
    assert_int_equal(st_wire_send_all(fd, junk, sizeof junk), 0);
    st_sleep_ms(300);                 /* the daemon has answered and met the bad magic */
    (void)send(fd, junk, sizeof junk, MSG_NOSIGNAL | MSG_DONTWAIT); /* more, left unread */
    size_t cap = 64 + (size_t)NQ * 24, got = 0;
    uint8_t *reply = malloc(cap);
    assert_non_null(reply);
    for (;;) {
        ssize_t r = recv(fd, reply + got, cap - got, 0);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            fail_msg("after %zu bytes of the reply: %s", got, strerror(errno));
        if (r == 0)
            break;
        got += (size_t)r;
        assert_true(got < cap);
    }
    assert_true(got >= ST_WIRE_HEADER);
    assert_int_equal(stp_rd32(reply + 8), 5);                 /* the SAMPLE's reply */
    assert_int_equal(got, ST_WIRE_HEADER + stp_rd32(reply + 16)); /* whole, then the end */
    close(fd);
    free(reply);
    free(frame);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(malformed_frames_get_their_status),
        cmocka_unit_test(split_reads_answer_every_pipeline_like_single_frames),
        cmocka_unit_test(a_bad_magic_after_a_big_reply_does_not_cut_it),
    };
    static const char *const args[] = {"--heavy-batch", "2048", NULL};
    st_group_args = args;
    return cmocka_run_group_tests_name("server_frames", tests, st_group_setup,
                                       st_group_teardown);
}
