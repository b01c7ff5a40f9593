/* tests/integration/test_protocol_rules.c - the rules PROTOCOL.md states for the corners an
 * outside client hit (issue 11), on the raw wire: which status wins when a SAMPLE count both
 * lies and exceeds max_batch, the ranges of sharpness / width / blur, SAMPLE flag bits 2-7
 * (bit 5, Ptex's lerp, reaching the sampler),
 * the values of queries that fail (BAD_FACE, NONFINITE, BAD_FOOTPRINT), HELLO with
 * min > max and a second HELLO, a chunk over max_chunk, another connection's upload id,
 * FETCH_READ with max_len 0; (pc32) a cube= upload option the file cannot take is INVALID at
 * COMMIT, while a data dir's set recorded with one before that check still loads.
 *
 * One daemon for the group (tests/common/daemon_fixture.h), --max-batch 4, on 127.0.0.1 port
 * 0, with its built-in set "default" (per-face, 384 faces, 4 channels u8). Frames are built
 * with protocol/'s encoders and read back here. Nothing here needs SEAMTEX_DATA.
 */
#include <math.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>
#include <zlib.h>

#include "../common/daemon_client.h"
#include "../common/wire.h"
#include "proto.h"
#include "sample.h"

#define D1 ST_GROUP
#define MAX_BATCH 4

/* ---- helpers --------------------------------------------------------------------------------- */

static int read_full(int fd, uint8_t *p, size_t n)
{
    size_t got = 0;
    while (got < n) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 10000) <= 0)
            return -1;
        ssize_t r = recv(fd, p + got, n - got, 0);
        if (r <= 0)
            return -1;
        got += (size_t)r;
    }
    return 0;
}

typedef struct reply {
    stp_header h;
    uint8_t   *body;   /* malloc'ed, h.body_len bytes (+1 for a NUL after messages) */
} reply;

/* Reads one reply frame of any size. */
static void read_reply(int fd, reply *r)
{
    uint8_t hdr[STP_HEADER_SIZE];
    assert_int_equal(read_full(fd, hdr, sizeof hdr), 0);
    int reason = 0;
    assert_int_equal(stp_parse_header(hdr, sizeof hdr, UINT32_MAX, &r->h, &reason), STP_OK);
    assert_true(r->h.flags & STP_F_REPLY);
    r->body = malloc((size_t)r->h.body_len + 1);
    assert_non_null(r->body);
    assert_int_equal(read_full(fd, r->body, r->h.body_len), 0);
    r->body[r->h.body_len] = 0;
}

/* Sends what b holds, frees it, reads the reply; checks its reqid and status. */
static void roundtrip(int fd, stp_buf *b, uint32_t reqid, int status, reply *r)
{
    assert_int_equal(b->err, 0);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(b), stp_buf_avail(b)), 0);
    stp_buf_free(b);
    stp_buf_init(b);
    read_reply(fd, r);
    assert_int_equal(r->h.reqid, reqid);
    if ((int)r->h.status != status)
        fail_msg("reqid %u: status %u, want %d (%s)", reqid, r->h.status, status,
                 r->h.status ? (const char *)r->body : "");
}

static void expect(int fd, stp_buf *b, uint32_t reqid, int status)
{
    reply r;
    roundtrip(fd, b, reqid, status, &r);
    free(r.body);
}

static stp_sample_req sample_req(const stp_query *q, uint32_t n)
{
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.p.name, sizeof rq.p.name, "default");
    rq.p.mode = STP_MODE_TRAVERSE;
    rq.p.filter = STP_FILTER_BILINEAR;
    rq.p.outfmt = STP_OUT_F32;
    rq.p.flags = STP_SF_COVERAGE | STP_SF_STATUS;
    rq.count = n;
    rq.queries = q;
    return rq;
}

static const stp_query GOOD = {3, 0.5f, 0.25f, 0, 0, 0, 0};

/* ---- tests ---------------------------------------------------------------------------------- */

/* PROTOCOL.md 4.4: the length check comes first: a count that lies is BAD_REQUEST even when
 * it is also over max_batch; an honest count over max_batch is TOO_LARGE. */
static void lying_count_over_max_batch_is_bad_request(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    stp_query q[MAX_BATCH + 1];
    for (int i = 0; i <= MAX_BATCH; i++)
        q[i] = GOOD;
    stp_buf b;
    stp_buf_init(&b);
    /* honest, over max_batch */
    stp_sample_req rq = sample_req(q, MAX_BATCH + 1);
    assert_int_equal(stp_enc_sample_req(&b, 1, 0, &rq), 0);
    expect(fd, &b, 1, STP_S_TOO_LARGE);
    /* count MAX_BATCH + 100 claimed, MAX_BATCH + 1 queries sent: lies and is over */
    assert_int_equal(stp_enc_sample_req(&b, 2, 0, &rq), 0);
    size_t cnt_at = STP_HEADER_SIZE + 2 + strlen("default") + 20;
    stp_wr32(b.data + b.start + cnt_at, MAX_BATCH + 100);
    expect(fd, &b, 2, STP_S_BAD_REQUEST);
    /* at max_batch: served */
    rq.count = MAX_BATCH;
    assert_int_equal(stp_enc_sample_req(&b, 3, 0, &rq), 0);
    expect(fd, &b, 3, STP_S_OK);
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.4: sharpness 0..1, width 0..1e4, blur 0..1e4, NaN never; INVALID otherwise,
 * whatever the filter. */
static void sharpness_width_blur_ranges(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    struct { unsigned filter; float s, w, b; int status; } rows[] = {
        {STP_FILTER_BILINEAR, 0, 0, 0, STP_S_OK},
        {STP_FILTER_BILINEAR, 1, 1e4f, 1e4f, STP_S_OK},
        {STP_FILTER_BILINEAR, -0.0f, 0.5f, 0.25f, STP_S_OK},
        {STP_FILTER_BILINEAR, NAN, 0, 0, STP_S_INVALID},
        {STP_FILTER_BILINEAR, 1.0001f, 0, 0, STP_S_INVALID},
        {STP_FILTER_BILINEAR, -0.5f, 0, 0, STP_S_INVALID},
        {STP_FILTER_POINT, 0, -1, 0, STP_S_INVALID},
        {STP_FILTER_TRILINEAR, 0, NAN, 0, STP_S_INVALID},
        {STP_FILTER_ANISO, 0, 2e4f, 0, STP_S_INVALID},
        {STP_FILTER_BILINEAR, 0, 0, INFINITY, STP_S_INVALID},
        {STP_FILTER_BILINEAR, 0, 0, -1e-3f, STP_S_INVALID},
        {STP_FILTER_PTEX_BICUBIC, 0.5f, 2, 0.01f, STP_S_OK},
        {STP_FILTER_PTEX_BICUBIC, 1.5f, 0, 0, STP_S_INVALID},
        {STP_FILTER_PTEX_GAUSSIAN, 0, 0, NAN, STP_S_INVALID},
    };
    stp_buf b;
    stp_buf_init(&b);
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        stp_sample_req rq = sample_req(&GOOD, 1);
        rq.p.filter = (uint8_t)rows[i].filter;
        rq.p.sharpness = rows[i].s;
        rq.p.width = rows[i].w;
        rq.p.blur = rows[i].b;
        assert_int_equal(stp_enc_sample_req(&b, 10 + (uint32_t)i, 0, &rq), 0);
        expect(fd, &b, 10 + (uint32_t)i, rows[i].status);
    }
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.4: each refused parameter gets a message naming it, prefixed once by the
 * opcode's name (the decoders' texts once carried it too: "SAMPLE: SAMPLE: ..."); 2.1: a NUL
 * byte in a str16 is BAD_REQUEST saying so, not "truncated body". */
static void error_messages_name_the_parameter_once(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    struct { int what; unsigned v; float f; const char *name; } rows[] = {
        {0, 3, 0, "mode"}, {1, 7, 0, "filter"}, {2, 2, 0, "zero_rule"},
        {3, 0, 1.5f, "sharpness"}, {4, 0, -1.0f, "width"}, {5, 0, NAN, "blur"},
        {6, 9, 0, "output format"}, {7, 17, 0, "max_aniso"},
    };
    stp_buf b;
    stp_buf_init(&b);
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        stp_sample_req rq = sample_req(&GOOD, 1);
        switch (rows[i].what) {
        case 0: rq.p.mode = (uint8_t)rows[i].v; break;
        case 1: rq.p.filter = (uint8_t)rows[i].v; break;
        case 2: rq.p.zero_rule = (uint8_t)rows[i].v; break;
        case 3: rq.p.sharpness = rows[i].f; break;
        case 4: rq.p.width = rows[i].f; break;
        case 5: rq.p.blur = rows[i].f; break;
        case 6: rq.p.outfmt = (uint8_t)rows[i].v; break;
        default: rq.p.max_aniso = (uint8_t)rows[i].v; break;
        }
        assert_int_equal(stp_enc_sample_req(&b, 40 + (uint32_t)i, 0, &rq), 0);
        reply r;
        roundtrip(fd, &b, 40 + (uint32_t)i, STP_S_INVALID, &r);
        const char *m = (const char *)r.body;
        if (strncmp(m, "SAMPLE: ", 8) || strstr(m + 8, "SAMPLE") || !strstr(m, rows[i].name))
            fail_msg("row %zu: \"%s\" should name %s once after \"SAMPLE: \"", i, m,
                     rows[i].name);
        free(r.body);
    }
    /* a lying count: the decoder's text, with one prefix */
    stp_sample_req rq = sample_req(&GOOD, 1);
    assert_int_equal(stp_enc_sample_req(&b, 60, 0, &rq), 0);
    stp_wr32(b.data + b.start + STP_HEADER_SIZE + 2 + strlen("default") + 20, 2);
    reply r;
    roundtrip(fd, &b, 60, STP_S_BAD_REQUEST, &r);
    assert_string_equal((const char *)r.body, "SAMPLE: count does not match the body length");
    free(r.body);
    /* INFO of a name with a NUL in it */
    static const uint8_t body[2 + 2 + 8] = {2, 0, 'p', 0}; /* "p\0", face_first, face_count */
    assert_int_equal(stp_enc_raw(&b, STP_OP_INFO, 0, 61, 0, 0, body, sizeof body), 0);
    roundtrip(fd, &b, 61, STP_S_BAD_REQUEST, &r);
    if (!strstr((const char *)r.body, "NUL") || strstr((const char *)r.body, "truncated"))
        fail_msg("INFO with a NUL in the name: \"%s\"", (const char *)r.body);
    free(r.body);
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.4: flag bits 6-7 are reserved: INVALID when set (libseamtex never sets them);
 * bit 4 (SHM) without its offsets and on a connection without a region is INVALID too. */
static void sample_flag_bits_4_to_7_are_invalid(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    for (unsigned bit = 4; bit < 8; bit++) {
        if (bit == 5)
            continue; /* lerp: sample_flag_bit_5_is_lerp */
        stp_sample_req rq = sample_req(&GOOD, 1);
        rq.p.flags = (uint8_t)(STP_SF_STATUS | 1u << bit);
        assert_int_equal(stp_enc_sample_req(&b, bit, 0, &rq), 0);
        expect(fd, &b, bit, STP_S_INVALID);
    }
    /* bits 2-3 choose the query layout (4.4.1): an f32-sized body with one of them set has
     * the wrong length, BAD_REQUEST; encoded in their layout they are OK */
    for (unsigned bit = 2; bit < 4; bit++) {
        stp_sample_req rq = sample_req(&GOOD, 1);
        assert_int_equal(stp_enc_sample_req(&b, 10 + bit, 0, &rq), 0);
        size_t flags_at = STP_HEADER_SIZE + 2 + strlen(rq.p.name) + 5;
        b.data[b.start + flags_at] |= (uint8_t)(1u << bit);
        expect(fd, &b, 10 + bit, STP_S_BAD_REQUEST);
        rq.p.flags |= (uint8_t)(1u << bit);
        assert_int_equal(stp_enc_sample_req(&b, 20 + bit, 0, &rq), 0);
        expect(fd, &b, 20 + bit, STP_S_OK);
    }
    stp_buf_free(&b);
    close(fd);
}

/* The values of a SAMPLE reply of n queries (f32, 4 channels: the set "default"). */
static void sample_values(int fd, stp_sample_req *rq, uint32_t reqid, float *v)
{
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(stp_enc_sample_req(&b, reqid, 0, rq), 0);
    reply r;
    roundtrip(fd, &b, reqid, STP_S_OK, &r);
    stp_sample_reply sr;
    assert_int_equal(stp_dec_sample_reply(r.body, r.h.body_len, &sr, NULL), 0);
    assert_int_equal(sr.count, rq->count);
    assert_int_equal(sr.nchan, 4);
    memcpy(v, sr.raw_values, (size_t)sr.count * 4 * sizeof(float)); /* LE f32 */
    free(r.body);
    stp_buf_free(&b);
}

/* PROTOCOL.md 4.4: flag bit 5 is Ptex's lerp: served (OK) and it reaches the sampler: a
 * gaussian / Mitchell query whose footprint lies between two levels changes, one on a level
 * does not, nor a box or bilinear query; SAMPLE_DIR refuses it (INVALID). */
static void sample_flag_bit_5_is_lerp(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    /* face 3 of "default"; footprints between levels (0.3, 0.7, 0.06 and 0.13 of the face)
     * and on levels (1/4, 1/2, 1/16, 1/8) */
    const stp_query between[4] = {{3, 0.43f, 0.37f, 0.3f, 0, 0, 0.3f},
                                  {3, 0.61f, 0.52f, 0.7f, 0, 0, 0.7f},
                                  {3, 0.27f, 0.71f, 0.06f, 0, 0, 0.06f},
                                  {3, 0.55f, 0.33f, 0.13f, 0, 0, 0.13f}};
    const stp_query level[4] = {{3, 0.43f, 0.37f, 0.25f, 0, 0, 0.25f},
                                {3, 0.61f, 0.52f, 0.5f, 0, 0, 0.5f},
                                {3, 0.27f, 0.71f, 0.0625f, 0, 0, 0.0625f},
                                {3, 0.55f, 0.33f, 0.125f, 0, 0, 0.125f}};
    static const uint8_t filters[4] = {STP_FILTER_PTEX_GAUSSIAN, STP_FILTER_PTEX_MITCHELL,
                                       STP_FILTER_PTEX_BOX, STP_FILTER_PTEX_BILINEAR};
    uint32_t id = 100;
    for (int fi = 0; fi < 4; fi++)
        for (int lv = 0; lv < 2; lv++) {
            float off[16], on[16];
            stp_sample_req rq = sample_req(lv ? level : between, 4);
            rq.p.filter = filters[fi];
            sample_values(fd, &rq, id++, off);
            rq.p.flags |= STP_SF_LERP;
            sample_values(fd, &rq, id++, on);
            int same = !memcmp(off, on, sizeof off);
            if (fi < 2 && !lv)
                assert_false(same); /* the width-4 filters between levels */
            else
                assert_true(same);
        }
    stp_buf b;
    stp_buf_init(&b);
    stp_dir_query dq = {{1, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    stp_sample_req rq = sample_req(NULL, 1);
    rq.queries = NULL;
    rq.dqueries = &dq;
    rq.p.flags = STP_SF_LERP;
    assert_int_equal(stp_enc_sample_dir_req(&b, id, 0, &rq), 0);
    expect(fd, &b, id, STP_S_INVALID);
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.6: a query whose status is not OK has NaN channels in f32 (0 in unorm) and
 * coverage 0; the reply is OK and nbad counts it. */
static void failed_queries_get_nan_and_zero_coverage(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    stp_query q[4] = {
        GOOD,
        {999999, 0.5f, 0.5f, 0, 0, 0, 0},       /* BAD_FACE */
        {3, NAN, 0.5f, 0, 0, 0, 0},             /* NONFINITE */
        {3, 0.5f, 0.5f, 2e4f, 0, 0, 0},         /* BAD_FOOTPRINT */
    };
    const uint8_t want[4] = {STP_Q_OK, STP_Q_BAD_FACE, STP_Q_NONFINITE, STP_Q_BAD_FOOTPRINT};
    stp_buf b;
    stp_buf_init(&b);
    for (unsigned fmt = 0; fmt < 3; fmt++) {
        for (unsigned filter = STP_FILTER_BILINEAR; filter <= STP_FILTER_PTEX_BILINEAR; filter += 8) {
            stp_sample_req rq = sample_req(q, 4);
            rq.p.outfmt = (uint8_t)fmt;
            rq.p.filter = (uint8_t)filter;
            assert_int_equal(stp_enc_sample_req(&b, 40 + fmt, 0, &rq), 0);
            reply r;
            roundtrip(fd, &b, 40 + fmt, STP_S_OK, &r);
            stp_sample_reply rp;
            assert_int_equal(stp_dec_sample_reply(r.body, r.h.body_len, &rp, NULL), 0);
            assert_int_equal(rp.count, 4);
            assert_int_equal(rp.nbad, 3);
            assert_memory_equal(rp.raw_status, want, 4);
            float cov[4];
            stp_sample_coverage(&rp, cov);
            assert_true(cov[0] == 1.0f);
            size_t esz = stp_outfmt_size(fmt);
            for (unsigned i = 1; i < 4; i++) {
                assert_true(cov[i] == 0.0f);
                for (unsigned ch = 0; ch < rp.nchan; ch++) {
                    const uint8_t *v = rp.raw_values + (i * rp.nchan + ch) * esz;
                    if (fmt == STP_OUT_F32)
                        assert_true(isnan(stp_u2f(stp_rd32(v))));
                    else
                        assert_int_equal(esz == 1 ? v[0] : stp_rd16(v), 0);
                }
            }
            free(r.body);
        }
    }
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.1: min_version > max_version is INVALID, a range without 1 BAD_VERSION, and a
 * second HELLO on a connection is answered as the first. */
static void hello_version_ranges_and_a_second_hello(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    struct { uint8_t lo, hi; int status; } rows[] = {
        {2, 1, STP_S_INVALID}, {1, 0, STP_S_INVALID}, {2, 3, STP_S_BAD_VERSION},
        {0, 0, STP_S_BAD_VERSION}, {1, 1, STP_S_OK}, {0, 9, STP_S_OK}, {1, 1, STP_S_OK},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        stp_hello_req h;
        memset(&h, 0, sizeof h);
        h.min_version = rows[i].lo;
        h.max_version = rows[i].hi;
        assert_int_equal(stp_enc_hello_req(&b, 60 + (uint32_t)i, 0, &h), 0);
        reply r;
        roundtrip(fd, &b, 60 + (uint32_t)i, rows[i].status, &r);
        if (rows[i].status == STP_S_OK) {
            stp_hello_reply hr;
            assert_int_equal(stp_dec_hello_reply(r.body, r.h.body_len, &hr, NULL), 0);
            assert_int_equal(hr.version, 1);
            assert_int_equal(hr.max_batch, MAX_BATCH);
            assert_int_equal(hr.max_chunk, STP_DEFAULT_MAX_CHUNK);
        }
        free(r.body);
    }
    stp_buf_free(&b);
    close(fd);
}

/* PROTOCOL.md 4.8: a chunk over max_chunk is TOO_LARGE (its body skipped, the upload and the
 * connection unchanged); another connection's upload id is NOT_FOUND. */
static void chunk_over_max_chunk_and_foreign_upload_ids(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1), fd2 = st_daemon_connect(&D1);
    assert_true(fd >= 0 && fd2 >= 0);
    stp_buf b;
    stp_buf_init(&b);
    stp_upload_begin ub;
    memset(&ub, 0, sizeof ub);
    snprintf(ub.name, sizeof ub.name, "protorules-up");
    ub.total_size = 2u * STP_DEFAULT_MAX_CHUNK;
    assert_int_equal(stp_enc_upload_begin(&b, 1, 0, &ub), 0);
    reply r;
    roundtrip(fd, &b, 1, STP_S_OK, &r);
    stp_upload_begin_reply br;
    assert_int_equal(stp_dec_upload_begin_reply(r.body, r.h.body_len, &br, NULL), 0);
    free(r.body);
    assert_int_equal(br.max_chunk, STP_DEFAULT_MAX_CHUNK);

    uint8_t *data = calloc(1, STP_DEFAULT_MAX_CHUNK + 1);
    assert_non_null(data);
    stp_upload_chunk ch = {br.upload_id, 0, STP_DEFAULT_MAX_CHUNK + 1, data};
    assert_int_equal(stp_enc_upload_chunk(&b, 2, 0, &ch), 0);
    expect(fd, &b, 2, STP_S_TOO_LARGE);
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_STATUS, 3, 0, br.upload_id), 0);
    roundtrip(fd, &b, 3, STP_S_OK, &r);
    stp_upload_progress pg;
    assert_int_equal(stp_dec_upload_progress(r.body, r.h.body_len, &pg, NULL), 0);
    free(r.body);
    assert_int_equal(pg.received, 0);
    /* exactly max_chunk is taken */
    ch.len = STP_DEFAULT_MAX_CHUNK;
    assert_int_equal(stp_enc_upload_chunk(&b, 4, 0, &ch), 0);
    expect(fd, &b, 4, STP_S_OK);

    /* the other connection cannot use the id */
    ch.offset = STP_DEFAULT_MAX_CHUNK;
    ch.len = 16;
    assert_int_equal(stp_enc_upload_chunk(&b, 5, 0, &ch), 0);
    expect(fd2, &b, 5, STP_S_NOT_FOUND);
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_STATUS, 6, 0, br.upload_id), 0);
    expect(fd2, &b, 6, STP_S_NOT_FOUND);
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_COMMIT, 7, 0, br.upload_id), 0);
    expect(fd2, &b, 7, STP_S_NOT_FOUND);
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_ABORT, 8, 0, br.upload_id), 0);
    expect(fd2, &b, 8, STP_S_NOT_FOUND);
    /* its owner still can */
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_ABORT, 9, 0, br.upload_id), 0);
    expect(fd, &b, 9, STP_S_OK);
    free(data);
    stp_buf_free(&b);
    close(fd);
    close(fd2);
}

/* PROTOCOL.md 4.10: max_len 0 reads as much as one reply holds (max_chunk); len 0 only at the
 * end of the file; an offset past it is INVALID. */
static void fetch_read_max_len_zero_reads_a_chunk(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    stp_fetch_open fo;
    memset(&fo, 0, sizeof fo);
    snprintf(fo.name, sizeof fo.name, "default");
    fo.format = STP_FETCH_PTX;
    assert_int_equal(stp_enc_fetch_open(&b, 1, 0, &fo), 0);
    reply r;
    roundtrip(fd, &b, 1, STP_S_OK, &r);
    stp_fetch_open_reply orp;
    assert_int_equal(stp_dec_fetch_open_reply(r.body, r.h.body_len, &orp, NULL), 0);
    free(r.body);
    assert_true(orp.total_size > 0);
    uint64_t want = orp.total_size < orp.max_chunk ? orp.total_size : orp.max_chunk;
    stp_fetch_read rd = {orp.fetch_id, 0, 0};
    assert_int_equal(stp_enc_fetch_read(&b, 2, 0, &rd), 0);
    roundtrip(fd, &b, 2, STP_S_OK, &r);
    stp_fetch_data d;
    assert_int_equal(stp_dec_fetch_data(r.body, r.h.body_len, &d, NULL), 0);
    assert_int_equal(d.offset, 0);
    assert_int_equal(d.len, want);
    free(r.body);
    rd.offset = orp.total_size;
    assert_int_equal(stp_enc_fetch_read(&b, 3, 0, &rd), 0);
    roundtrip(fd, &b, 3, STP_S_OK, &r);
    assert_int_equal(stp_dec_fetch_data(r.body, r.h.body_len, &d, NULL), 0);
    assert_int_equal(d.len, 0);
    free(r.body);
    rd.offset = orp.total_size + 1;
    assert_int_equal(stp_enc_fetch_read(&b, 4, 0, &rd), 0);
    expect(fd, &b, 4, STP_S_INVALID);
    stp_buf_free(&b);
    close(fd);
}

/* Uploads file (n bytes) as set name with options on connection fd, reqids from *reqid up;
 * checks the commit's status and, when OK, the set's kind (the first byte after the name). */
static void upload_with(int fd, uint32_t *reqid, const char *name, const char *options,
                        const uint8_t *file, size_t n, int status, int kind)
{
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(st_wire_upload_begin(&b, *reqid, name, "ptx", options, n,
                                          stp_crc32c(0, file, n), STP_UF_REPLACE),
                     0);
    reply r;
    roundtrip(fd, &b, (*reqid)++, STP_S_OK, &r);
    stp_upload_begin_reply br;
    assert_int_equal(stp_dec_upload_begin_reply(r.body, r.h.body_len, &br, NULL), 0);
    free(r.body);
    for (size_t off = 0; off < n;) {
        size_t len = n - off < br.max_chunk ? n - off : br.max_chunk;
        stp_upload_chunk ch = {br.upload_id, off, (uint32_t)len, file + off};
        assert_int_equal(stp_enc_upload_chunk(&b, *reqid, 0, &ch), 0);
        expect(fd, &b, (*reqid)++, STP_S_OK);
        off += len;
    }
    assert_int_equal(stp_enc_id_req(&b, STP_OP_UPLOAD_COMMIT, *reqid, 0, br.upload_id), 0);
    roundtrip(fd, &b, (*reqid)++, status, &r);
    if (status == STP_S_OK) {
        assert_true(r.h.body_len > 3);
        size_t nl = (size_t)r.body[0] | (size_t)r.body[1] << 8;
        assert_true(r.h.body_len > 2 + nl);
        assert_int_equal(r.body[2 + nl], kind);
    } else {
        assert_non_null(strstr((const char *)r.body, "cube="));
    }
    free(r.body);
    stp_buf_free(&b);
}

/* The built-in set "default" fetched as a Ptex file (384 faces: not an environment cube), on
 * connection fd with reqids from *reqid up; *n its bytes. */
static uint8_t *fetch_default_ptx(int fd, uint32_t *reqid, size_t *n)
{
    stp_buf b;
    stp_buf_init(&b);
    stp_fetch_open fo;
    memset(&fo, 0, sizeof fo);
    snprintf(fo.name, sizeof fo.name, "default");
    fo.format = STP_FETCH_PTX;
    assert_int_equal(stp_enc_fetch_open(&b, *reqid, 0, &fo), 0);
    reply r;
    roundtrip(fd, &b, (*reqid)++, STP_S_OK, &r);
    stp_fetch_open_reply orp;
    assert_int_equal(stp_dec_fetch_open_reply(r.body, r.h.body_len, &orp, NULL), 0);
    free(r.body);
    uint8_t *file = malloc(orp.total_size);
    assert_non_null(file);
    for (uint64_t off = 0; off < orp.total_size;) {
        stp_fetch_read rd = {orp.fetch_id, off, 0};
        assert_int_equal(stp_enc_fetch_read(&b, *reqid, 0, &rd), 0);
        roundtrip(fd, &b, (*reqid)++, STP_S_OK, &r);
        stp_fetch_data d;
        assert_int_equal(stp_dec_fetch_data(r.body, r.h.body_len, &d, NULL), 0);
        assert_true(d.len > 0 && d.offset == off);
        memcpy(file + off, d.data, d.len);
        off += d.len;
        free(r.body);
    }
    stp_buf_free(&b);
    *n = (size_t)orp.total_size;
    return file;
}

/* PROTOCOL.md 4.8 (pc32): a cube= conversion the file cannot take is INVALID at COMMIT, as it
 * is for an image and a BC1 DDS, never an OK with a set of another kind. */
static void cube_options_a_ptex_file_cannot_take_are_invalid(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    uint32_t reqid = 1;
    size_t n = 0;
    uint8_t *file = fetch_default_ptx(fd, &reqid, &n);
    upload_with(fd, &reqid, "protorules-ptx", "cube=strip_v", file, n, STP_S_INVALID, 0);
    upload_with(fd, &reqid, "protorules-ptx", "cube=latlong:64", file, n, STP_S_INVALID, 0);
    upload_with(fd, &reqid, "protorules-ptx", "cube=ptex", file, n, STP_S_INVALID, 0);
    upload_with(fd, &reqid, "protorules-ptx", "cube=auto", file, n, STP_S_OK, STP_KIND_PERFACE);
    upload_with(fd, &reqid, "protorules-ptx", "", file, n, STP_S_OK, STP_KIND_PERFACE);
    free(file);
    close(fd);
}

/* ... while a data dir's set recorded with such options before the check (its manifest says
 * cube=strip_v on a Ptex file; no native file, so the start rebuilds it from the source) still
 * loads, as the per-face set it was. */
static void recorded_cube_options_still_load(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    uint32_t reqid = 1;
    size_t n = 0;
    uint8_t *file = fetch_default_ptx(fd, &reqid, &n);
    close(fd);
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    char p[700];
    snprintf(p, sizeof p, "mkdir -p '%s/sets/old'", d.datadir);
    assert_int_equal(system(p), 0);
    snprintf(p, sizeof p, "%s/sets/old/source-1.ptx", d.datadir);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(file, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
    snprintf(p, sizeof p, "%s/sets/old/manifest", d.datadir);
    f = fopen(p, "wb");
    assert_non_null(f);
    fprintf(f, "seamtex-set 1\nname old\nsource source-1.ptx\nformat ptx\nbytes %zu\n"
            "crc32 %08lx\noptions cube=strip_v\nend\n", n, crc32(crc32(0L, Z_NULL, 0), file, (uInt)n));
    assert_int_equal(fclose(f), 0);
    free(file);
    static const char *const args[] = {"--no-default-set", NULL};
    assert_int_equal(st_daemon_start(&d, args), 0);
    fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    stp_info_req ir;
    memset(&ir, 0, sizeof ir);
    snprintf(ir.name, sizeof ir.name, "old");
    assert_int_equal(stp_enc_info_req(&b, 1, 0, &ir), 0);
    reply r;
    roundtrip(fd, &b, 1, STP_S_OK, &r);
    assert_true(r.h.body_len >= 8);
    assert_int_equal(r.body[0] | r.body[1] << 8, 384);   /* nfaces */
    assert_int_equal(r.body[7], STP_KIND_PERFACE);
    free(r.body);
    stp_buf_free(&b);
    close(fd);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lying_count_over_max_batch_is_bad_request),
        cmocka_unit_test(sharpness_width_blur_ranges),
        cmocka_unit_test(error_messages_name_the_parameter_once),
        cmocka_unit_test(sample_flag_bits_4_to_7_are_invalid),
        cmocka_unit_test(sample_flag_bit_5_is_lerp),
        cmocka_unit_test(failed_queries_get_nan_and_zero_coverage),
        cmocka_unit_test(hello_version_ranges_and_a_second_hello),
        cmocka_unit_test(chunk_over_max_chunk_and_foreign_upload_ids),
        cmocka_unit_test(fetch_read_max_len_zero_reads_a_chunk),
        cmocka_unit_test(cube_options_a_ptex_file_cannot_take_are_invalid),
        cmocka_unit_test(recorded_cube_options_still_load),
    };
    static const char *const args[] = {"--max-batch", "4", NULL};
    st_group_args = args;
    return cmocka_run_group_tests_name("protocol_rules", tests, st_group_setup,
                                       st_group_teardown);
}
