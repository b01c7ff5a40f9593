/* tests/unit/test_proto.c - the wire protocol without sockets: header parser (need more / ok /
 * bad), the malformed-frame table at parser and decoder level, round trips of every body
 * encoder/decoder, lying inner counts, zero-length batches, NaN as data, CRC32C, stp_buf. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "err.h"
#include "proto.h"
#include "registry.h"
#include "sample.h"
#include "seamtex.h"

#include "crc32c.h"

/* Encodes into a fresh buffer, checks the frame header, returns the body. */
typedef struct frame {
    stp_buf b;
    stp_header h;
    const uint8_t *body;
} frame;

static void frame_parse(frame *f, uint8_t opcode, uint32_t reqid, int reply)
{
    int reason = -1;
    assert_int_equal(f->b.err, 0);
    assert_true(stp_buf_avail(&f->b) >= STP_HEADER_SIZE);
    assert_int_equal(stp_parse_header(stp_buf_head(&f->b), stp_buf_avail(&f->b), UINT32_MAX,
                                      &f->h, &reason), STP_OK);
    assert_int_equal(reason, STP_R_NONE);
    assert_int_equal(f->h.opcode, opcode);
    assert_int_equal(f->h.reqid, reqid);
    assert_int_equal(!!(f->h.flags & STP_F_REPLY), reply);
    assert_int_equal((size_t)f->h.body_len + STP_HEADER_SIZE, stp_buf_avail(&f->b));
    f->body = stp_buf_head(&f->b) + STP_HEADER_SIZE;
}

/* Every strict prefix of a valid body must be refused by dec (and never read past it:
 * each prefix is copied into an exact-size heap block so ASan sees overreads). */
typedef int (*dec_fn)(const uint8_t *body, size_t len, void *out, const char **why);

static void prefixes_refused(const uint8_t *body, size_t len, dec_fn dec, void *out)
{
    for (size_t n = 0; n < len; n++) {
        uint8_t *copy = malloc(n ? n : 1);
        const char *why = NULL;
        memcpy(copy, body, n);
        int s = dec(copy, n, out, &why);
        if (s == 0)
            fail_msg("prefix of %zu of %zu bytes accepted", n, len);
        assert_non_null(why);
        free(copy);
    }
    /* and one trailing byte too many */
    uint8_t *longer = malloc(len + 1);
    memcpy(longer, body, len);
    longer[len] = 0;
    const char *why = NULL;
    assert_int_equal(dec(longer, len + 1, out, &why), STP_S_BAD_REQUEST);
    free(longer);
}

/* Decoders adapted to dec_fn (calling through a cast pointer would be undefined). */
#define WRAP(name, type) \
    static int w_##name(const uint8_t *b, size_t n, void *o, const char **why) \
    { return stp_dec_##name(b, n, (type *)o, why); }
WRAP(hello_req, stp_hello_req)
WRAP(hello_reply, stp_hello_reply)
WRAP(list_reply, stp_list_reply)
WRAP(info_req, stp_info_req)
WRAP(info_reply, stp_info_reply)
WRAP(sample_reply, stp_sample_reply)
WRAP(stats_reply, stp_stats_reply)
WRAP(upload_begin, stp_upload_begin)
WRAP(upload_begin_reply, stp_upload_begin_reply)
WRAP(upload_chunk, stp_upload_chunk)
WRAP(upload_progress, stp_upload_progress)
WRAP(upload_done, stp_upload_done)
WRAP(compress_req, stp_compress_req)
WRAP(job_status, stp_job_status)
WRAP(fetch_open, stp_fetch_open)
WRAP(fetch_open_reply, stp_fetch_open_reply)
WRAP(fetch_read, stp_fetch_read)
WRAP(fetch_data, stp_fetch_data)
static int w_sample_req(const uint8_t *b, size_t n, void *o, const char **why)
{
    return stp_dec_sample_req(b, n, UINT32_MAX, (stp_sample_req *)o, why);
}
static int w_sample_dir_req(const uint8_t *b, size_t n, void *o, const char **why)
{
    return stp_dec_sample_dir_req(b, n, UINT32_MAX, (stp_sample_req *)o, why);
}
static int w_id(const uint8_t *b, size_t n, void *o, const char **why)
{
    return stp_dec_id_req(b, n, (uint64_t *)o, why);
}
static int w_name(const uint8_t *b, size_t n, void *o, const char **why)
{
    return stp_dec_name_req(b, n, (char *)o, why);
}

/* ---- header ---------------------------------------------------------------------------------- */

static void header_round_trips_little_endian(void **state)
{
    (void)state;
    uint8_t raw[STP_HEADER_SIZE];
    stp_header h = { STP_VERSION, STP_OP_SAMPLE, STP_F_REPLY, 0x11223344u, STP_S_NOT_FOUND,
                     0x0a0b0c0du, 1500 }, g;
    stp_write_header(raw, &h);
    static const uint8_t want[STP_HEADER_SIZE] = {
        0x53, 0x54, 0x58, 0x31, 1, 0x05, 0x01, 0x00, 0x44, 0x33, 0x22, 0x11, 0x05, 0x00,
        0x00, 0x00, 0x0d, 0x0c, 0x0b, 0x0a, 0xdc, 0x05, 0x00, 0x00 };
    assert_memory_equal(raw, want, sizeof want);
    int reason;
    assert_int_equal(stp_parse_header(raw, sizeof raw, UINT32_MAX, &g, &reason), STP_OK);
    assert_int_equal(g.reqid, h.reqid);
    assert_int_equal(g.body_len, h.body_len);
    assert_int_equal(g.status, h.status);
    assert_int_equal(g.timeout_ms, 1500);
}

static void header_needs_more_until_complete(void **state)
{
    (void)state;
    uint8_t raw[STP_HEADER_SIZE];
    stp_header h = { STP_VERSION, STP_OP_PING, 0, 7, 0, 2, 0 }, g;
    stp_write_header(raw, &h);
    for (size_t n = 0; n < STP_HEADER_SIZE; n++) {
        int reason = -1;
        assert_int_equal(stp_parse_header(raw, n, 100, &g, &reason), STP_NEED_MORE);
        assert_int_equal(reason, STP_R_NONE);
    }
    assert_int_equal(stp_parse_header(raw, STP_HEADER_SIZE, 100, &g, NULL), STP_OK);
}

static void bad_magic_is_fatal_as_soon_as_seen(void **state)
{
    (void)state;
    uint8_t raw[STP_HEADER_SIZE];
    stp_header h = { STP_VERSION, STP_OP_PING, 0, 7, 0, 0, 0 }, g;
    for (int pos = 0; pos < 4; pos++) {
        stp_write_header(raw, &h);
        raw[pos] ^= 0x20;
        int reason = 0;
        /* detected with only pos+1 bytes present */
        assert_int_equal(stp_parse_header(raw, (size_t)pos + 1, 100, &g, &reason), STP_BAD);
        assert_int_equal(reason, STP_R_BAD_MAGIC);
        assert_true(stp_reason_fatal(reason));
    }
    /* an HTTP request is a bad magic too */
    const char *http = "GET / HTTP/1.1\r\n\r\n";
    int reason = 0;
    assert_int_equal(stp_parse_header((const uint8_t *)http, strlen(http), 100, &g, &reason),
                     STP_BAD);
    assert_int_equal(reason, STP_R_BAD_MAGIC);
}

/* The malformed-frame table, parser level: each row with its defined outcome. */
static void malformed_frame_table_at_parser_level(void **state)
{
    (void)state;
    struct row {
        const char *what;
        int version, opcode;
        uint32_t body_len;
        size_t present;            /* header bytes given */
        int want, reason, status, fatal;
    } rows[] = {
        { "bad version",         2, STP_OP_PING, 0,    24, STP_BAD, STP_R_BAD_VERSION,
          STP_S_BAD_VERSION, 0 },
        { "version 0",           0, STP_OP_PING, 8,    24, STP_BAD, STP_R_BAD_VERSION,
          STP_S_BAD_VERSION, 0 },
        { "unknown opcode",      1, 0xEE,        0,    24, STP_OK,  STP_R_NONE, STP_S_OK, 0 },
        { "truncated header",    1, STP_OP_PING, 0,    23, STP_NEED_MORE, STP_R_NONE,
          STP_S_OK, 0 },
        { "body over the cap",   1, STP_OP_SAMPLE, 1025, 24, STP_BAD, STP_R_TOO_LARGE,
          STP_S_TOO_LARGE, 0 },
        { "body at the cap",     1, STP_OP_SAMPLE, 1024, 24, STP_OK, STP_R_NONE, STP_S_OK, 0 },
        { "4 GiB body",          1, STP_OP_UPLOAD_CHUNK, 0xFFFFFFFFu, 24, STP_BAD,
          STP_R_TOO_LARGE, STP_S_TOO_LARGE, 0 },
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        uint8_t raw[STP_HEADER_SIZE];
        stp_header h = { (uint8_t)rows[i].version, (uint8_t)rows[i].opcode, 0, 99, 0,
                         rows[i].body_len, 0 }, g;
        int reason = -1;
        stp_write_header(raw, &h);
        int r = stp_parse_header(raw, rows[i].present, 1024, &g, &reason);
        if (r != rows[i].want || reason != rows[i].reason)
            fail_msg("%s: got %d/%d", rows[i].what, r, reason);
        assert_int_equal(stp_reason_status(reason), rows[i].status);
        assert_int_equal(stp_reason_fatal(reason), rows[i].fatal);
        if (r != STP_NEED_MORE) {
            /* even refused headers tell what to skip and whom to answer */
            assert_int_equal(g.body_len, rows[i].body_len);
            assert_int_equal(g.reqid, 99);
        }
    }
    assert_null(stp_opcode_name(0xEE));
    assert_string_equal(stp_opcode_name(STP_OP_SAMPLE), "SAMPLE");
}

static void encode_sample(stp_buf *b, const char *name, uint32_t n, const stp_query *q);

/* The malformed-frame table, decoder level: a valid SAMPLE body (name "tex", 2 queries) and
 * variants of it, each with the status the server must answer. */
static void malformed_body_table_at_decoder_level(void **state)
{
    (void)state;
    enum { NAME = 2 + 3, PARAMS = 24, Q = STP_QUERY_SIZE, COUNT_AT = NAME + 20 };
    stp_query q[2] = { { 0, 0.5f, 0.5f, 0, 0, 0, 0 }, { 1, 0.25f, 0.75f, 0, 0, 0, 0 } };
    stp_buf b;
    stp_buf_init(&b);
    encode_sample(&b, "tex", 2, q);
    const uint8_t *valid = b.data + STP_HEADER_SIZE;
    size_t vlen = b.len - STP_HEADER_SIZE;
    assert_int_equal(vlen, NAME + PARAMS + 2 * Q);
    struct row {
        const char *what;
        int edit;            /* what to change */
        uint32_t value;
        int want;
    } rows[] = {
        { "valid",                              0, 0, 0 },
        { "count larger than the queries",      1, 3, STP_S_BAD_REQUEST },
        { "count smaller than the queries",     1, 1, STP_S_BAD_REQUEST },
        { "count whose *28 wraps 32 bits",      1, 0x09249249u, STP_S_BAD_REQUEST },
        { "count 2^32-1",                       1, 0xFFFFFFFFu, STP_S_BAD_REQUEST },
        { "name length past the end",           2, 0xFFFF, STP_S_BAD_REQUEST },
        { "name length 0 shifts every field",   2, 0, STP_S_BAD_REQUEST },
        { "name with a NUL byte",               3, 0, STP_S_BAD_REQUEST },
        { "one trailing byte",                  4, 1, STP_S_BAD_REQUEST },
        { "truncated inside the last query",    5, 3, STP_S_BAD_REQUEST },
        { "truncated inside the parameters",    5, 2 * Q + 10, STP_S_BAD_REQUEST },
        { "empty body",                         5, (uint32_t)vlen, STP_S_BAD_REQUEST },
        { "zero-length batch",                  6, 0, 0 },
        { "NaN and infinite query fields",      7, 0, 0 },
        { "count over max_batch (1)",           8, 0, STP_S_TOO_LARGE },
        { "unknown output format",              9, 7, STP_S_INVALID },
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        uint8_t *body = malloc(vlen + 1);
        size_t len = vlen;
        uint32_t max_batch = 100;
        memcpy(body, valid, vlen);
        switch (rows[i].edit) {
        case 1: stp_wr32(body + COUNT_AT, rows[i].value); break;
        case 2: stp_wr16(body, (uint16_t)rows[i].value); break;
        case 3: body[3] = 0; break;
        case 4: body[len++] = 0; break;
        case 5: len -= rows[i].value; break;
        case 6: stp_wr32(body + COUNT_AT, 0); len = NAME + PARAMS; break;
        case 7:
            stp_wr32(body + NAME + PARAMS + 4, stp_f2u(NAN));
            stp_wr32(body + NAME + PARAMS + Q + 12, stp_f2u(-INFINITY));
            break;
        case 8: max_batch = 1; break;
        case 9: body[NAME + 4] = (uint8_t)rows[i].value; break;
        default: break;
        }
        /* exact-size copy so that ASan sees any read past `len` */
        uint8_t *exact = malloc(len ? len : 1);
        memcpy(exact, body, len);
        stp_sample_req r;
        const char *why = NULL;
        int got = stp_dec_sample_req(exact, len, max_batch, &r, &why);
        if (got != rows[i].want)
            fail_msg("%s: status %d (%s), want %d", rows[i].what, got, why ? why : "",
                     rows[i].want);
        if (got != 0)
            assert_non_null(why);
        if (rows[i].edit == 7) {
            stp_query g;
            stp_sample_query(&r, 0, &g);
            assert_true(isnan(g.u));
            stp_sample_query(&r, 1, &g);
            assert_true(isinf(g.dudx) && g.dudx < 0);
        }
        free(exact);
        free(body);
    }
    /* other bodies: a chunk whose len lies, a HELLO with min > max, an id of 7 bytes, bytes
     * where the body must be empty */
    uint8_t chunk[20 + 4] = { 0 };
    stp_wr32(chunk + 16, 5);
    stp_upload_chunk ch;
    assert_int_equal(stp_dec_upload_chunk(chunk, sizeof chunk, &ch, NULL), STP_S_BAD_REQUEST);
    uint8_t hello[12] = { 2, 1 };
    stp_hello_req hr;
    assert_int_equal(stp_dec_hello_req(hello, sizeof hello, &hr, NULL), STP_S_INVALID);
    uint64_t id;
    assert_int_equal(stp_dec_id_req(chunk, 7, &id, NULL), STP_S_BAD_REQUEST);
    assert_int_equal(stp_dec_empty(chunk, 1, NULL), STP_S_BAD_REQUEST);
    assert_int_equal(stp_dec_empty(NULL, 0, NULL), 0);
    stp_buf_free(&b);
}

/* ---- bodies -------------------------------------------------------------------------------- */

static void hello_round_trips(void **state)
{
    (void)state;
    frame f;
    stp_hello_req rq = { 1, 1, STP_CAP_PIPELINE | STP_CAP_FETCH, "s3cret", "unit" }, rq2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_hello_req(&f.b, 5, 0, &rq), 0);
    frame_parse(&f, STP_OP_HELLO, 5, 0);
    assert_int_equal(stp_dec_hello_req(f.body, f.h.body_len, &rq2, NULL), 0);
    assert_string_equal(rq2.token, "s3cret");
    assert_string_equal(rq2.client_name, "unit");
    assert_int_equal(rq2.caps, rq.caps);
    prefixes_refused(f.body, f.h.body_len, w_hello_req, &rq2);

    stp_hello_reply rp = { 1, STP_CAP_AUTH, 1u << 20, 4096, 65536, 32, 1, "seamtexd" }, rp2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_hello_reply(&f.b, 5, &rp), 0);
    frame_parse(&f, STP_OP_HELLO, 5, 1);
    assert_int_equal(stp_dec_hello_reply(f.body, f.h.body_len, &rp2, NULL), 0);
    assert_int_equal(rp2.max_body, 1u << 20);
    assert_int_equal(rp2.max_batch, 4096);
    assert_int_equal(rp2.max_chunk, 65536);
    assert_int_equal(rp2.max_inflight, 32);
    assert_int_equal(rp2.authenticated, 1);
    assert_string_equal(rp2.server_name, "seamtexd");
    prefixes_refused(f.body, f.h.body_len, w_hello_reply, &rp2);
    stp_buf_free(&f.b);
}

static void list_round_trips_and_refuses_lying_count(void **state)
{
    (void)state;
    frame f;
    stp_list_entry e[2] = { { "ptex_a", 0, 3, 0, 12, 4096 }, { "cube.b", 1, 4, 3, 6, 1u << 30 } };
    stp_list_reply rp = { 7, 2, e, NULL, 0 }, rp2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_list_reply(&f.b, 9, &rp), 0);
    frame_parse(&f, STP_OP_LIST, 9, 1);
    assert_int_equal(stp_dec_list_reply(f.body, f.h.body_len, &rp2, NULL), 0);
    assert_int_equal(rp2.total, 7);
    assert_int_equal(rp2.count, 2);
    size_t pos = 0;
    stp_list_entry g;
    assert_true(stp_list_next(&rp2, &pos, &g));
    assert_string_equal(g.name, "ptex_a");
    assert_int_equal(g.nfaces, 12);
    assert_true(stp_list_next(&rp2, &pos, &g));
    assert_string_equal(g.name, "cube.b");
    assert_int_equal(g.memory, 1u << 30);
    assert_int_equal(g.dtype, 3);
    assert_false(stp_list_next(&rp2, &pos, &g));
    prefixes_refused(f.body, f.h.body_len, w_list_reply, &rp2);

    /* count says 3 with two entries, and a count of 2^32-1 */
    uint8_t *b = malloc(f.h.body_len);
    memcpy(b, f.body, f.h.body_len);
    stp_wr32(b + 4, 3);
    assert_int_equal(stp_dec_list_reply(b, f.h.body_len, &rp2, NULL), STP_S_BAD_REQUEST);
    stp_wr32(b + 4, 0xFFFFFFFFu);
    assert_int_equal(stp_dec_list_reply(b, f.h.body_len, &rp2, NULL), STP_S_BAD_REQUEST);
    free(b);

    stp_list_req lq = { 3, 10 }, lq2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_list_req(&f.b, 1, 0, &lq), 0);
    frame_parse(&f, STP_OP_LIST, 1, 0);
    assert_int_equal(stp_dec_list_req(f.body, f.h.body_len, &lq2, NULL), 0);
    assert_int_equal(lq2.first, 3);
    assert_int_equal(lq2.max, 10);
    assert_int_equal(stp_dec_list_req(NULL, 0, &lq2, NULL), 0);     /* empty = all */
    assert_int_equal(lq2.first, 0);
    assert_int_equal(stp_dec_list_req(f.body, 4, &lq2, NULL), STP_S_BAD_REQUEST);
    stp_buf_free(&f.b);
}

static void info_round_trips_with_face_records(void **state)
{
    (void)state;
    frame f;
    stp_info_req rq = { "set1", 2, 3 }, rq2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_info_req(&f.b, 2, 0, &rq), 0);
    frame_parse(&f, STP_OP_INFO, 2, 0);
    assert_int_equal(stp_dec_info_req(f.body, f.h.body_len, &rq2, NULL), 0);
    assert_string_equal(rq2.name, "set1");
    assert_int_equal(rq2.face_first, 2);
    assert_int_equal(rq2.face_count, 3);
    prefixes_refused(f.body, f.h.body_len, w_info_req, &rq2);

    stp_face_rec fr[2] = { { 64, 32, { 1, -1, 5, -1 }, { 3, 0, 2, 0 }, 1, 7 },
                           { 1, 1, { -1, -1, -1, 0 }, { 0, 0, 0, 1 }, 2, 1 } };
    stp_info_reply rp;
    memset(&rp, 0, sizeof rp);
    rp.nfaces = 10; rp.nchan = 4; rp.dtype = ST_DT_HALF; rp.alpha_chan = -1; rp.kind = 1;
    rp.memory = 123456789012ull; rp.max_w = 64; rp.min_w = 1; rp.irregular_corners = 8;
    rp.max_valence = 5; rp.face_first = 2; rp.nrec = 2; rp.faces = fr;
    stp_info_reply rp2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_info_reply(&f.b, 2, &rp), 0);
    frame_parse(&f, STP_OP_INFO, 2, 1);
    assert_int_equal(f.h.body_len, 80 + 2 * STP_FACE_REC_SIZE);
    assert_int_equal(stp_dec_info_reply(f.body, f.h.body_len, &rp2, NULL), 0);
    assert_int_equal(rp2.alpha_chan, -1);
    assert_int_equal(rp2.memory, 123456789012ull);
    assert_int_equal(rp2.irregular_corners, 8);
    assert_int_equal(rp2.nrec, 2);
    stp_face_rec g;
    stp_info_face(&rp2, 0, &g);
    assert_int_equal(g.w, 64);
    assert_int_equal(g.adjface[1], -1);
    assert_int_equal(g.adjface[2], 5);
    assert_int_equal(g.adjedge[0], 3);
    assert_int_equal(g.nlevels, 7);
    stp_info_face(&rp2, 1, &g);
    assert_int_equal(g.flags, 2);
    assert_int_equal(g.adjedge[3], 1);
    prefixes_refused(f.body, f.h.body_len, w_info_reply, &rp2);
    stp_buf_free(&f.b);
}

static void encode_sample(stp_buf *b, const char *name, uint32_t n, const stp_query *q)
{
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.p.name, sizeof rq.p.name, "%s", name);
    rq.p.mode = ST_MODE_TRAVERSE;
    rq.p.filter = ST_FILTER_PTEX_MITCHELL;
    rq.p.zero_rule = ST_ZERO_CLAMP;
    rq.p.max_aniso = 8;
    rq.p.outfmt = STP_OUT_UNORM16;
    rq.p.flags = STP_SF_COVERAGE | STP_SF_STATUS;
    rq.p.sharpness = 0.5f;
    rq.p.width = 2.0f;
    rq.count = n;
    rq.queries = q;
    assert_int_equal(stp_enc_sample_req(b, 77, 250, &rq), 0);
}

static void sample_request_round_trips_and_keeps_nan(void **state)
{
    (void)state;
    frame f;
    stp_query q[3] = { { 0, 0.25f, 0.75f, 0.01f, 0, 0, 0.01f },
                       { 5, NAN, 0.5f, INFINITY, -0.0f, 0, 0 },
                       { 0xFFFFFFFFu, -3.0f, 1e30f, 0, 0, 0, 0 } };
    stp_sample_req r;
    stp_buf_init(&f.b);
    encode_sample(&f.b, "tex", 3, q);
    frame_parse(&f, STP_OP_SAMPLE, 77, 0);
    assert_int_equal(f.h.timeout_ms, 250);
    assert_int_equal(f.h.body_len, 2 + 3 + 24 + 3 * STP_QUERY_SIZE);
    assert_int_equal(stp_dec_sample_req(f.body, f.h.body_len, 100, &r, NULL), 0);
    assert_string_equal(r.p.name, "tex");
    assert_int_equal(r.p.mode, ST_MODE_TRAVERSE);
    assert_int_equal(r.p.filter, ST_FILTER_PTEX_MITCHELL);
    assert_int_equal(r.p.zero_rule, ST_ZERO_CLAMP);
    assert_int_equal(r.p.max_aniso, 8);
    assert_int_equal(r.p.outfmt, STP_OUT_UNORM16);
    assert_true(r.p.sharpness == 0.5f && r.p.width == 2.0f && r.p.blur == 0.0f);
    assert_int_equal(r.count, 3);
    stp_query g;
    stp_sample_query(&r, 0, &g);
    assert_memory_equal(&g, &q[0], sizeof g);
    stp_sample_query(&r, 1, &g);
    assert_true(isnan(g.u));                       /* NaN is data for the decoder */
    assert_true(isinf(g.dudx));
    assert_true(signbit(g.dvdx));
    stp_sample_query(&r, 2, &g);
    assert_int_equal(g.face, 0xFFFFFFFFu);
    assert_true(g.v == 1e30f);
    prefixes_refused(f.body, f.h.body_len, w_sample_req, &r);
    stp_buf_free(&f.b);
}

static void sample_request_refuses_lying_counts(void **state)
{
    (void)state;
    stp_query q[2] = { { 0, 0.5f, 0.5f, 0, 0, 0, 0 }, { 1, 0.5f, 0.5f, 0, 0, 0, 0 } };
    stp_buf b;
    stp_header h;
    stp_sample_req r;
    const char *why;
    stp_buf_init(&b);
    encode_sample(&b, "tex", 2, q);
    assert_int_equal(stp_parse_header(stp_buf_head(&b), b.len, UINT32_MAX, &h, NULL), STP_OK);
    uint8_t *body = b.data + STP_HEADER_SIZE;
    size_t count_at = 2 + 3 + 20;
    uint32_t lies[] = { 1, 3, 1000, 0xFFFFFFFFu, 0x80000000u, 0x09249249u /* *28 wraps 32 bits */ };
    for (size_t i = 0; i < sizeof lies / sizeof lies[0]; i++) {
        stp_wr32(body + count_at, lies[i]);
        why = NULL;
        assert_int_equal(stp_dec_sample_req(body, h.body_len, UINT32_MAX, &r, &why),
                         STP_S_BAD_REQUEST);
        assert_non_null(strstr(why, "count"));
    }
    /* a name length that runs past the body */
    stp_wr32(body + count_at, 2);
    stp_wr16(body, 0xFFFF);
    assert_int_equal(stp_dec_sample_req(body, h.body_len, UINT32_MAX, &r, NULL),
                     STP_S_BAD_REQUEST);
    stp_wr16(body, 3);
    assert_int_equal(stp_dec_sample_req(body, h.body_len, UINT32_MAX, &r, NULL), 0);
    /* over max_batch: TOO_LARGE, after the length check */
    assert_int_equal(stp_dec_sample_req(body, h.body_len, 1, &r, &why), STP_S_TOO_LARGE);
    stp_buf_free(&b);
}

static void sample_request_refuses_bad_values(void **state)
{
    (void)state;
    stp_buf b;
    stp_sample_req r;
    stp_buf_init(&b);
    encode_sample(&b, "tex", 0, NULL);
    uint8_t *body = b.data + STP_HEADER_SIZE;
    size_t len = b.len - STP_HEADER_SIZE, p0 = 2 + 3;
    struct { size_t off; uint8_t v; int want; } rows[] = {
        { 4, 4, STP_S_INVALID },     /* outfmt 4 */
        { 4, 3, 0 },                 /* outfmt 3, f16 */
        { 3, 17, STP_S_INVALID },    /* max_aniso 17 */
        { 5, 16, STP_S_BAD_REQUEST },/* SHM (bit 4) without its 24 bytes of offsets */
        { 5, 32, 0 },                /* LERP (bit 5, since session 26) */
        { 5, 64, STP_S_INVALID },    /* unknown flag bit (bit 6) */
        { 5, 128, STP_S_INVALID },   /* unknown flag bit (bit 7) */
        { 5, 4 | 8, 0 },             /* UV16 | FACE16: no query, so the length still fits */
        { 3, 16, 0 },
        { 3, 0, 0 },
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        stp_buf_clear(&b);
        encode_sample(&b, "tex", 0, NULL);
        body = b.data + STP_HEADER_SIZE;
        body[p0 + rows[i].off] = rows[i].v;
        assert_int_equal(stp_dec_sample_req(body, len, 100, &r, NULL), rows[i].want);
    }
    stp_buf_free(&b);
}

/* PROTOCOL.md 4.12: a SAMPLE / SAMPLE_DIR with flag SHM carries three u64 offsets instead of
 * its queries; the reply is 16 bytes; ranges are checked without wrapping. */
static void shm_sample_request_round_trips_and_is_checked(void **state)
{
    (void)state;
    stp_buf b;
    stp_buf_init(&b);
    stp_sample_req r, d;
    memset(&r, 0, sizeof r);
    snprintf(r.p.name, sizeof r.p.name, "tex");
    r.p.mode = 1;
    r.p.filter = 1;
    r.p.flags = STP_SF_SHM | STP_SF_STATUS | STP_SF_UV16;
    r.count = 1000;
    r.shm.query_off = 4096;
    r.shm.reply_off = 0x123456789ull;
    r.shm.reply_cap = UINT64_MAX;
    for (int dir = 0; dir < 2; dir++) {
        stp_buf_clear(&b);
        r.p.flags = STP_SF_SHM | STP_SF_STATUS | (dir ? 0 : STP_SF_UV16);
        assert_int_equal(dir ? stp_enc_sample_dir_req(&b, 7, 0, &r)
                             : stp_enc_sample_req(&b, 7, 0, &r), 0);
        size_t len = b.len - STP_HEADER_SIZE;
        assert_int_equal(len, 2 + 3 + 24 + STP_SHM_REF_SIZE);   /* no queries in the body */
        const uint8_t *body = b.data + STP_HEADER_SIZE;
        assert_int_equal(dir ? stp_dec_sample_dir_req(body, len, 1u << 20, &d, NULL)
                             : stp_dec_sample_req(body, len, 1u << 20, &d, NULL), 0);
        assert_int_equal(d.count, 1000);
        assert_int_equal(d.p.flags, r.p.flags);
        assert_true(d.raw == NULL);
        assert_true(d.shm.query_off == 4096 && d.shm.reply_off == 0x123456789ull &&
                    d.shm.reply_cap == UINT64_MAX);
        assert_int_equal(stp_sample_peek_count(body, len), 1000);
        /* a byte more or less: BAD_REQUEST; count over max_batch: TOO_LARGE */
        assert_int_equal(stp_dec_sample_req(body, len - 1, 1u << 20, &d, NULL),
                         STP_S_BAD_REQUEST);
        assert_int_equal(stp_dec_sample_req(body, len, 999, &d, NULL), STP_S_TOO_LARGE);
    }
    /* the sizes both sides compute */
    assert_int_equal(stp_sample_query_bytes(STP_OP_SAMPLE, 0, 10), 280);
    assert_int_equal(stp_sample_query_bytes(STP_OP_SAMPLE, STP_SF_UV16 | STP_SF_FACE16, 10), 140);
    assert_int_equal(stp_sample_query_bytes(STP_OP_SAMPLE_DIR, 0, 10), 360);
    assert_int_equal(stp_sample_reply_bytes(10, 4, STP_OUT_F32, STP_SF_COVERAGE | STP_SF_STATUS),
                     12 + 10 * 21);
    assert_int_equal(stp_sample_reply_bytes(10, 3, STP_OUT_UNORM8, 0), 12 + 30);
    assert_int_equal(stp_sample_reply_bytes(10, 3, 9, 0), 0);
    /* ranges: inside, touching the end, past it, wrapping */
    assert_true(stp_shm_range_ok(100, 0, 100));
    assert_true(stp_shm_range_ok(100, 100, 0));
    assert_false(stp_shm_range_ok(100, 101, 0));
    assert_false(stp_shm_range_ok(100, 1, 100));
    assert_false(stp_shm_range_ok(100, UINT64_MAX, 2));
    assert_false(stp_shm_range_ok(100, 2, UINT64_MAX));
    /* the reply */
    stp_buf_clear(&b);
    stp_shm_reply rp = {64, 1000}, rp2;
    assert_int_equal(stp_enc_shm_reply(&b, STP_OP_SAMPLE, 7, &rp), 0);
    assert_int_equal(b.len, STP_HEADER_SIZE + STP_SHM_REPLY_SIZE);
    assert_int_equal(stp_dec_shm_reply(b.data + STP_HEADER_SIZE, 16, &rp2, NULL), 0);
    assert_true(rp2.offset == 64 && rp2.length == 1000);
    assert_int_equal(stp_dec_shm_reply(b.data + STP_HEADER_SIZE, 15, &rp2, NULL),
                     STP_S_BAD_REQUEST);
    stp_buf_free(&b);
}

static void zero_length_batch_is_valid(void **state)
{
    (void)state;
    stp_buf b;
    stp_sample_req r;
    stp_sample_reply rp, rp2;
    stp_buf_init(&b);
    encode_sample(&b, "tex", 0, NULL);
    assert_int_equal(stp_dec_sample_req(b.data + STP_HEADER_SIZE, b.len - STP_HEADER_SIZE, 0,
                                        &r, NULL), 0);
    assert_int_equal(r.count, 0);
    memset(&rp, 0, sizeof rp);
    rp.nchan = 3;
    rp.outfmt = STP_OUT_F32;
    rp.flags = STP_SF_COVERAGE | STP_SF_STATUS;
    stp_buf_clear(&b);
    assert_int_equal(stp_enc_sample_reply(&b, STP_OP_SAMPLE, 1, &rp), 0);
    assert_int_equal(b.len, STP_HEADER_SIZE + 12);
    assert_int_equal(stp_dec_sample_reply(b.data + STP_HEADER_SIZE, 12, &rp2, NULL), 0);
    assert_int_equal(rp2.count, 0);
    stp_buf_free(&b);
}

static void sample_dir_request_round_trips(void **state)
{
    (void)state;
    frame f;
    stp_dir_query q[2] = { { { 1, 0, 0 }, { 0, 0.01f, 0 }, { 0, 0, 0.01f } },
                           { { 0, NAN, -1 }, { 0.05f, 0, 0 }, { 0, 0, 0 } } };
    stp_sample_req rq, r;
    memset(&rq, 0, sizeof rq);
    strcpy(rq.p.name, "sky");
    rq.p.filter = ST_FILTER_TRILINEAR;
    rq.p.footprint = STP_FP_CONE;
    rq.count = 2;
    rq.dqueries = q;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_sample_dir_req(&f.b, 4, 0, &rq), 0);
    frame_parse(&f, STP_OP_SAMPLE_DIR, 4, 0);
    assert_int_equal(f.h.body_len, 2 + 3 + 24 + 2 * STP_DIR_QUERY_SIZE);
    assert_int_equal(stp_dec_sample_dir_req(f.body, f.h.body_len, 10, &r, NULL), 0);
    assert_int_equal(r.p.footprint, STP_FP_CONE);
    stp_dir_query g;
    stp_sample_dir_query(&r, 0, &g);
    assert_memory_equal(&g, &q[0], sizeof g);
    stp_sample_dir_query(&r, 1, &g);
    assert_true(isnan(g.dir[1]));
    assert_true(g.ddx[0] == 0.05f);
    prefixes_refused(f.body, f.h.body_len, w_sample_dir_req, &r);
    /* the 28-byte SAMPLE decoder refuses a 36-byte-per-query body */
    assert_int_equal(stp_dec_sample_req(f.body, f.h.body_len, 10, &r, NULL), STP_S_BAD_REQUEST);
    /* unknown footprint kind */
    uint8_t *body = (uint8_t *)f.body;
    body[2 + 3 + 6] = 2;
    assert_int_equal(stp_dec_sample_dir_req(f.body, f.h.body_len, 10, &r, NULL), STP_S_INVALID);
    stp_buf_free(&f.b);
}

static void sample_reply_converts_formats(void **state)
{
    (void)state;
    float vals[2 * 2] = { 0.5f, NAN, -1.0f, 2.0f };
    float cov[2] = { 1.0f, 0.25f };
    uint8_t st[2] = { ST_Q_OK, ST_Q_NONFINITE };
    for (unsigned fmt = 0; fmt < 3; fmt++) {
        frame f;
        stp_sample_reply rp = { 2, 2, (uint8_t)fmt, STP_SF_COVERAGE | STP_SF_STATUS, 1,
                                vals, cov, st, NULL, NULL, NULL }, rp2;
        stp_buf_init(&f.b);
        assert_int_equal(stp_enc_sample_reply(&f.b, STP_OP_SAMPLE, 3, &rp), 0);
        frame_parse(&f, STP_OP_SAMPLE, 3, 1);
        assert_int_equal(f.h.body_len, 12 + 4 * stp_outfmt_size(fmt) + 8 + 2);
        assert_int_equal(stp_dec_sample_reply(f.body, f.h.body_len, &rp2, NULL), 0);
        assert_int_equal(rp2.nbad, 1);
        float out[4], c2[2];
        stp_sample_values_f32(&rp2, out);
        stp_sample_coverage(&rp2, c2);
        assert_true(c2[0] == 1.0f && c2[1] == 0.25f);
        assert_memory_equal(rp2.raw_status, st, 2);
        if (fmt == STP_OUT_F32) {
            assert_true(out[0] == 0.5f && isnan(out[1]) && out[2] == -1.0f && out[3] == 2.0f);
            uint16_t u[4];
            assert_int_equal(stp_sample_values_u16(&rp2, u), -1);
        } else {
            uint16_t u[4];
            unsigned max = fmt == STP_OUT_UNORM8 ? 255 : 65535;
            assert_int_equal(stp_sample_values_u16(&rp2, u), 0);
            assert_int_equal(u[0], (max + 1) / 2);   /* 0.5 rounds up: 128 / 32768 */
            assert_int_equal(u[1], 0);               /* NaN -> 0 */
            assert_int_equal(u[2], 0);               /* clamped */
            assert_int_equal(u[3], max);
            assert_true(fabsf(out[0] - 0.5f) < 1.0f / max);
        }
        prefixes_refused(f.body, f.h.body_len, w_sample_reply, &rp2);
        stp_buf_free(&f.b);
    }
}

/* The exact unorm value of a float in [2^-20, 1]: floor(v * max + 1/2) in integers. v is
 * m * 2^-k with a 24-bit m and k <= 44, so 2 * m * max + 2^k < 2^63. */
static uint32_t unorm_ref(float v, uint32_t max)
{
    int e;
    float fr = frexpf(v, &e);                       /* v = fr * 2^e, fr in [0.5, 1) */
    uint64_t m = (uint64_t)ldexpf(fr, 24);          /* v = m * 2^(e - 24) */
    int k = 24 - e;                                 /* v = m / 2^k */
    assert_true(k >= 0 && k <= 44);
    return (uint32_t)((2 * m * max + ((uint64_t)1 << k)) >> (k + 1));
}

static uint32_t unorm_wire(float v, unsigned fmt)
{
    frame f;
    uint8_t st = 0;
    stp_sample_reply rp = { 1, 1, (uint8_t)fmt, 0, 0, &v, NULL, &st, NULL, NULL, NULL }, rp2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_sample_reply(&f.b, STP_OP_SAMPLE, 1, &rp), 0);
    frame_parse(&f, STP_OP_SAMPLE, 1, 1);
    assert_int_equal(stp_dec_sample_reply(f.body, f.h.body_len, &rp2, NULL), 0);
    uint16_t u = 0;
    assert_int_equal(stp_sample_values_u16(&rp2, &u), 0);
    stp_buf_free(&f.b);
    return u;
}

/* PROTOCOL.md 4.6: unorm = the integer nearest to clamp(v, 0, 1) * max, computed exactly,
 * ties up, NaN 0. Checked at the floats on both sides of every rounding boundary
 * (k + 1/2) / max of both formats, and at the special values. */
static void unorm_conversion_is_exact_at_every_boundary(void **state)
{
    (void)state;
    /* the value: binary32 arithmetic would give 140 */
    assert_int_equal(unorm_wire(0.54705882f, STP_OUT_UNORM8), 139);
    assert_int_equal(unorm_ref(0.54705882f, 255), 139);
    assert_int_equal(unorm_wire(0.5f, STP_OUT_UNORM8), 128);       /* the one tie: up */
    assert_int_equal(unorm_wire(0.5f, STP_OUT_UNORM16), 32768);
    const float special[] = {0.0f, -0.0f, -1.0f, 1.0f, 1.5f, INFINITY, -INFINITY, NAN,
                             1e-30f, 0x1p-149f, 0.99999994f};
    const uint32_t want8[] = {0, 0, 0, 255, 255, 255, 0, 0, 0, 0, 255};
    const uint32_t want16[] = {0, 0, 0, 65535, 65535, 65535, 0, 0, 0, 0, 65535};
    for (size_t i = 0; i < sizeof special / sizeof special[0]; i++) {
        assert_int_equal(unorm_wire(special[i], STP_OUT_UNORM8), want8[i]);
        assert_int_equal(unorm_wire(special[i], STP_OUT_UNORM16), want16[i]);
    }
    unsigned checked = 0;
    for (unsigned fmt = STP_OUT_UNORM8; fmt <= STP_OUT_UNORM16; fmt++) {
        uint32_t max = fmt == STP_OUT_UNORM8 ? 255 : 65535;
        /* 16-bit: every 7th boundary (and the ends) keeps the test under a second */
        uint32_t step = fmt == STP_OUT_UNORM8 ? 1 : 7;
        for (uint32_t k = 0; k < max; k += (k + step < max - 1 ? step : 1)) {
            float b = (float)(((double)k + 0.5) / max);
            float lo = nextafterf(b, 0.0f), hi = nextafterf(b, 2.0f);
            const float around[] = {nextafterf(lo, 0.0f), lo, b, hi, nextafterf(hi, 2.0f)};
            for (int j = 0; j < 5; j++) {
                float v = around[j];
                if (v < 0x1p-20f || v > 1.0f)
                    continue;
                uint32_t want = unorm_ref(v, max);
                if (unorm_wire(v, fmt) != want)
                    fail_msg("unorm%u of %.9g (0x%08x): %u, exact %u", fmt == 1 ? 8 : 16,
                             (double)v, stp_f2u(v), unorm_wire(v, fmt), want);
                checked++;
            }
        }
    }
    assert_true(checked > 40000);
}

static void stats_round_trip(void **state)
{
    (void)state;
    frame f;
    stp_stat st[3] = { { "requests_total", STP_STAT_U64, { .u = 1ull << 40 } },
                       { "latency_p99_ms", STP_STAT_F64, { .f = 0.125 } },
                       { "connections", STP_STAT_U64, { .u = 3 } } };
    stp_stats_reply rp = { 3, st, NULL, 0 }, rp2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_stats_reply(&f.b, 8, &rp), 0);
    frame_parse(&f, STP_OP_STATS, 8, 1);
    assert_int_equal(stp_dec_stats_reply(f.body, f.h.body_len, &rp2, NULL), 0);
    size_t pos = 0;
    stp_stat g;
    assert_true(stp_stats_next(&rp2, &pos, &g));
    assert_string_equal(g.key, "requests_total");
    assert_true(g.v.u == 1ull << 40);
    assert_true(stp_stats_next(&rp2, &pos, &g));
    assert_true(g.type == STP_STAT_F64 && g.v.f == 0.125);
    assert_true(stp_stats_next(&rp2, &pos, &g));
    assert_false(stp_stats_next(&rp2, &pos, &g));
    prefixes_refused(f.body, f.h.body_len, w_stats_reply, &rp2);
    /* an unknown value type is refused */
    uint8_t *body = (uint8_t *)f.body;
    body[4 + 2 + strlen("requests_total")] = 9;
    assert_int_equal(stp_dec_stats_reply(f.body, f.h.body_len, &rp2, NULL), STP_S_BAD_REQUEST);
    stp_buf_free(&f.b);
}

static void upload_bodies_round_trip(void **state)
{
    (void)state;
    frame f;
    stp_upload_begin bg, bg2;
    memset(&bg, 0, sizeof bg);
    strcpy(bg.name, "mesh1");
    strcpy(bg.hint, "obj");
    strcpy(bg.options, "texture=img1 cube=latlong:512");
    bg.total_size = 5ull << 32;
    bg.crc32c = 0xE3069283u;
    bg.flags = STP_UF_REPLACE;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_upload_begin(&f.b, 1, 0, &bg), 0);
    frame_parse(&f, STP_OP_UPLOAD_BEGIN, 1, 0);
    assert_int_equal(stp_dec_upload_begin(f.body, f.h.body_len, &bg2, NULL), 0);
    assert_string_equal(bg2.options, bg.options);
    assert_string_equal(bg2.hint, "obj");
    assert_true(bg2.total_size == bg.total_size && bg2.crc32c == bg.crc32c);
    prefixes_refused(f.body, f.h.body_len, w_upload_begin, &bg2);
    /* STAGE (a cluster node's push of a write not recorded yet) only with REPLICA */
    bg.flags = STP_UF_REPLICA | STP_UF_STAGE;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_begin(&f.b, 1, 0, &bg), 0);
    frame_parse(&f, STP_OP_UPLOAD_BEGIN, 1, 0);
    assert_int_equal(stp_dec_upload_begin(f.body, f.h.body_len, &bg2, NULL), 0);
    assert_int_equal(bg2.flags, STP_UF_REPLICA | STP_UF_STAGE);
    bg.flags = STP_UF_REPLACE | STP_UF_STAGE;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_begin(&f.b, 1, 0, &bg), 0);
    frame_parse(&f, STP_OP_UPLOAD_BEGIN, 1, 0);
    assert_int_equal(stp_dec_upload_begin(f.body, f.h.body_len, &bg2, NULL), STP_S_INVALID);
    /* REPLICA_PUBLISH: a name and a CRC-32; a bad name is INVALID, a short body refused */
    stp_buf rp;
    stp_buf_init(&rp);
    assert_int_equal(stp_put_replica_publish(&rp, "mesh1", 0xCBF43926u), 0);
    char rname[STP_MAX_NAME + 1];
    uint32_t rcrc = 0;
    assert_int_equal(stp_dec_replica_publish(stp_buf_head(&rp), stp_buf_avail(&rp), rname,
                                             &rcrc, NULL), 0);
    assert_string_equal(rname, "mesh1");
    assert_int_equal(rcrc, 0xCBF43926u);
    assert_int_not_equal(stp_dec_replica_publish(stp_buf_head(&rp), stp_buf_avail(&rp) - 1,
                                                 rname, &rcrc, NULL), 0);
    stp_buf_clear(&rp);
    assert_int_equal(stp_put_replica_publish(&rp, "../x", 1), 0);
    assert_int_equal(stp_dec_replica_publish(stp_buf_head(&rp), stp_buf_avail(&rp), rname,
                                             &rcrc, NULL), STP_S_INVALID);
    stp_buf_free(&rp);

    stp_upload_begin_reply br = { 42, 100, 65536 }, br2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_begin_reply(&f.b, 1, &br), 0);
    frame_parse(&f, STP_OP_UPLOAD_BEGIN, 1, 1);
    assert_int_equal(f.h.body_len, 20);
    assert_int_equal(stp_dec_upload_begin_reply(f.body, 20, &br2, NULL), 0);
    assert_true(br2.upload_id == 42 && br2.received == 100 && br2.max_chunk == 65536);
    prefixes_refused(f.body, f.h.body_len, w_upload_begin_reply, &br2);

    uint8_t data[300];
    for (int i = 0; i < 300; i++) data[i] = (uint8_t)(i * 7);
    stp_upload_chunk ch = { 42, 100, 300, data }, ch2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_chunk(&f.b, 2, 0, &ch), 0);
    frame_parse(&f, STP_OP_UPLOAD_CHUNK, 2, 0);
    assert_int_equal(stp_dec_upload_chunk(f.body, f.h.body_len, &ch2, NULL), 0);
    assert_true(ch2.upload_id == 42 && ch2.offset == 100 && ch2.len == 300);
    assert_memory_equal(ch2.data, data, 300);
    prefixes_refused(f.body, f.h.body_len, w_upload_chunk, &ch2);
    /* lying chunk length */
    uint8_t *body = (uint8_t *)f.body;
    stp_wr32(body + 16, 301);
    assert_int_equal(stp_dec_upload_chunk(f.body, f.h.body_len, &ch2, NULL), STP_S_BAD_REQUEST);
    stp_wr32(body + 16, 0xFFFFFFFFu);
    assert_int_equal(stp_dec_upload_chunk(f.body, f.h.body_len, &ch2, NULL), STP_S_BAD_REQUEST);

    stp_upload_progress pg = { 400, 1000 }, pg2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_progress(&f.b, STP_OP_UPLOAD_CHUNK, 2, &pg), 0);
    frame_parse(&f, STP_OP_UPLOAD_CHUNK, 2, 1);
    assert_int_equal(stp_dec_upload_progress(f.body, f.h.body_len, &pg2, NULL), 0);
    assert_true(pg2.received == 400 && pg2.total == 1000);
    prefixes_refused(f.body, f.h.body_len, w_upload_progress, &pg2);

    stp_upload_done dn = { "mesh1", 2, 4, 0, 1, 1u << 20 }, dn2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_upload_done(&f.b, 3, &dn), 0);
    frame_parse(&f, STP_OP_UPLOAD_COMMIT, 3, 1);
    assert_int_equal(stp_dec_upload_done(f.body, f.h.body_len, &dn2, NULL), 0);
    assert_string_equal(dn2.name, "mesh1");
    assert_true(dn2.kind == 2 && dn2.nchan == 4 && dn2.memory == 1u << 20);
    prefixes_refused(f.body, f.h.body_len, w_upload_done, &dn2);
    stp_buf_free(&f.b);
}

static void job_and_fetch_bodies_round_trip(void **state)
{
    (void)state;
    frame f;
    stp_compress_req cr = { "src", "dst", 5, STP_CF_SEAM_AWARE }, cr2;
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_compress_req(&f.b, 1, 0, &cr), 0);
    frame_parse(&f, STP_OP_COMPRESS, 1, 0);
    assert_int_equal(stp_dec_compress_req(f.body, f.h.body_len, &cr2, NULL), 0);
    assert_string_equal(cr2.target, "dst");
    assert_true(cr2.level == 5 && cr2.flags == STP_CF_SEAM_AWARE);
    prefixes_refused(f.body, f.h.body_len, w_compress_req, &cr2);
    ((uint8_t *)f.body)[f.h.body_len - 2] = 10;    /* level 10 */
    assert_int_equal(stp_dec_compress_req(f.body, f.h.body_len, &cr2, NULL), STP_S_INVALID);

    stp_job_status js, js2;
    memset(&js, 0, sizeof js);
    js.job_id = 9; js.state = STP_JOB_FAILED; js.progress = 0.75f; js.result = STP_S_NOMEM;
    strcpy(js.message, "ran out");
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_job_status(&f.b, STP_OP_JOB_STATUS, 2, &js), 0);
    frame_parse(&f, STP_OP_JOB_STATUS, 2, 1);
    assert_int_equal(stp_dec_job_status(f.body, f.h.body_len, &js2, NULL), 0);
    assert_true(js2.job_id == 9 && js2.state == STP_JOB_FAILED && js2.progress == 0.75f);
    assert_int_equal(js2.result, STP_S_NOMEM);
    assert_string_equal(js2.message, "ran out");
    prefixes_refused(f.body, f.h.body_len, w_job_status, &js2);

    stp_fetch_open fo = { "set9", STP_FETCH_DDS }, fo2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_fetch_open(&f.b, 3, 0, &fo), 0);
    frame_parse(&f, STP_OP_FETCH_OPEN, 3, 0);
    assert_int_equal(stp_dec_fetch_open(f.body, f.h.body_len, &fo2, NULL), 0);
    assert_true(fo2.format == STP_FETCH_DDS && strcmp(fo2.name, "set9") == 0);
    prefixes_refused(f.body, f.h.body_len, w_fetch_open, &fo2);
    /* every format of the list decodes; the next number is INVALID; names are extensions */
    for (unsigned fmt = 0; fmt <= STP_FETCH_OBJ + 1; fmt++) {
        const char *why = NULL;
        stp_fetch_open fx = { "set9", (uint8_t)fmt };
        stp_buf_clear(&f.b);
        assert_int_equal(stp_enc_fetch_open(&f.b, 4, 0, &fx), 0);
        frame_parse(&f, STP_OP_FETCH_OPEN, 4, 0);
        int st = stp_dec_fetch_open(f.body, f.h.body_len, &fo2, &why);
        assert_int_equal(st, fmt <= STP_FETCH_OBJ ? 0 : STP_S_INVALID);
        if (fmt <= STP_FETCH_OBJ)
            assert_int_equal(stp_fetch_format_parse(stp_fetch_format_name(fmt)), (int)fmt);
    }
    assert_int_equal(STP_FETCH_PTX, 0);
    assert_int_equal(STP_FETCH_DDS, 1);
    assert_int_equal(stp_fetch_format_parse("EXR"), STP_FETCH_EXR);
    assert_int_equal(stp_fetch_format_parse("png"), STP_FETCH_PNG);
    assert_int_equal(stp_fetch_format_parse("obj"), STP_FETCH_OBJ);
    assert_int_equal(stp_fetch_format_parse("tga"), -1);
    assert_int_equal(stp_fetch_format_parse(""), -1);
    assert_null(stp_fetch_format_name(5));

    stp_fetch_open_reply fr = { 5, 123456, 0xdeadbeef, 4096 }, fr2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_fetch_open_reply(&f.b, 3, &fr), 0);
    frame_parse(&f, STP_OP_FETCH_OPEN, 3, 1);
    assert_int_equal(stp_dec_fetch_open_reply(f.body, f.h.body_len, &fr2, NULL), 0);
    assert_true(fr2.fetch_id == 5 && fr2.total_size == 123456 && fr2.crc32c == 0xdeadbeef);
    prefixes_refused(f.body, f.h.body_len, w_fetch_open_reply, &fr2);

    stp_fetch_read rd = { 5, 4096, 4096 }, rd2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_fetch_read(&f.b, 4, 0, &rd), 0);
    frame_parse(&f, STP_OP_FETCH_READ, 4, 0);
    assert_int_equal(stp_dec_fetch_read(f.body, f.h.body_len, &rd2, NULL), 0);
    assert_true(rd2.offset == 4096 && rd2.max_len == 4096);
    prefixes_refused(f.body, f.h.body_len, w_fetch_read, &rd2);

    uint8_t data[5] = { 1, 2, 3, 4, 5 };
    stp_fetch_data fd = { 4096, 5, data }, fd2;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_fetch_data(&f.b, 4, &fd), 0);
    frame_parse(&f, STP_OP_FETCH_READ, 4, 1);
    assert_int_equal(stp_dec_fetch_data(f.body, f.h.body_len, &fd2, NULL), 0);
    assert_memory_equal(fd2.data, data, 5);
    prefixes_refused(f.body, f.h.body_len, w_fetch_data, &fd2);

    uint64_t id = 0;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_id_req(&f.b, STP_OP_JOB_CANCEL, 6, 0, 0x0102030405060708ull), 0);
    frame_parse(&f, STP_OP_JOB_CANCEL, 6, 0);
    assert_int_equal(stp_dec_id_req(f.body, f.h.body_len, &id, NULL), 0);
    assert_true(id == 0x0102030405060708ull);
    prefixes_refused(f.body, f.h.body_len, w_id, &id);

    char name[STP_MAX_NAME + 1];
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_name_req(&f.b, STP_OP_DELETE, 7, 0, "old_set"), 0);
    frame_parse(&f, STP_OP_DELETE, 7, 0);
    assert_int_equal(stp_dec_name_req(f.body, f.h.body_len, name, NULL), 0);
    assert_string_equal(name, "old_set");
    prefixes_refused(f.body, f.h.body_len, w_name, name);
    stp_buf_free(&f.b);
}

static void strings_with_nul_or_over_the_cap_are_refused(void **state)
{
    (void)state;
    char name[STP_MAX_NAME + 1];
    uint8_t body[2 + 300];
    stp_wr16(body, 3);
    memcpy(body + 2, "a\0b", 3);
    assert_int_equal(stp_dec_name_req(body, 5, name, NULL), STP_S_BAD_REQUEST);
    stp_wr16(body, 256);                    /* one over STP_MAX_NAME: a well-formed body */
    memset(body + 2, 'a', 256);             /* with a name the rule refuses */
    assert_int_equal(stp_dec_name_req(body, 258, name, NULL), STP_S_INVALID);
    stp_wr16(body, 255);
    assert_int_equal(stp_dec_name_req(body, 257, name, NULL), 0);
    assert_int_equal(strlen(name), 255);
}

static void error_frames_carry_a_bounded_message(void **state)
{
    (void)state;
    frame f;
    char msg[64], big[3000];
    stp_buf_init(&f.b);
    assert_int_equal(stp_enc_errorf(&f.b, STP_OP_INFO, 1, STP_S_NOT_FOUND, "no set %s", "x"), 0);
    frame_parse(&f, STP_OP_INFO, 1, 1);
    assert_int_equal(f.h.status, STP_S_NOT_FOUND);
    stp_dec_error(f.body, f.h.body_len, msg, sizeof msg);
    assert_string_equal(msg, "no set x");
    /* the PROTOCOL.md example, byte for byte */
    static const uint8_t want[] = { 0x53, 0x54, 0x58, 0x31, 1, 4, 1, 0, 1, 0, 0, 0, 5, 0, 0, 0,
                                    8, 0, 0, 0, 0, 0, 0, 0, 'n', 'o', ' ', 's', 'e', 't', ' ',
                                    'x' };
    assert_int_equal(f.b.len, sizeof want);
    assert_memory_equal(f.b.data, want, sizeof want);
    memset(big, 'm', sizeof big - 1);
    big[sizeof big - 1] = 0;
    stp_buf_clear(&f.b);
    assert_int_equal(stp_enc_error(&f.b, STP_OP_PING, 2, STP_S_INTERNAL, big), 0);
    frame_parse(&f, STP_OP_PING, 2, 1);
    assert_int_equal(f.h.body_len, STP_MAX_MSG);
    /* a NUL inside a message is shown as '?', a short buffer cuts */
    uint8_t odd[3] = { 'a', 0, 'b' };
    stp_dec_error(odd, 3, msg, sizeof msg);
    assert_string_equal(msg, "a?b");
    stp_dec_error(odd, 3, msg, 2);
    assert_string_equal(msg, "a");
    stp_buf_free(&f.b);
}

static void ping_example_matches_protocol_md(void **state)
{
    (void)state;
    stp_buf b;
    static const uint8_t want[] = { 0x53, 0x54, 0x58, 0x31, 1, 2, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0,
                                    2, 0, 0, 0, 0, 0, 0, 0, 'h', 'i' };
    stp_buf_init(&b);
    assert_int_equal(stp_enc_raw(&b, STP_OP_PING, 0, 7, 0, 0, "hi", 2), 0);
    assert_int_equal(b.len, sizeof want);
    assert_memory_equal(b.data, want, sizeof want);
    stp_buf_free(&b);
}

static void sample_example_matches_protocol_md(void **state)
{
    (void)state;
    static const uint8_t want_req[] = {
        0x53, 0x54, 0x58, 0x31, 1, 5, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0x39, 0, 0, 0, 0, 0, 0, 0,
        3, 0, 't', 'e', 'x', 1, 1, 0, 0, 1, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        1, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0x3f, 0, 0, 0x80, 0x3e, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 0, 0, 0, 0 };
    static const uint8_t want_rep[] = {
        0x53, 0x54, 0x58, 0x31, 1, 5, 1, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0x14, 0, 0, 0, 0, 0, 0, 0,
        1, 0, 0, 0, 3, 1, 3, 0, 0, 0, 0, 0, 0xff, 0x80, 0, 0, 0, 0x80, 0x3f, 0 };
    stp_buf b;
    stp_query q = { 3, 0.5f, 0.25f, 0, 0, 0, 0 };
    stp_sample_req r;
    memset(&r, 0, sizeof r);
    strcpy(r.p.name, "tex");
    r.p.mode = 1; r.p.filter = 1; r.p.outfmt = STP_OUT_UNORM8;
    r.p.flags = STP_SF_COVERAGE | STP_SF_STATUS;
    r.count = 1;
    r.queries = &q;
    stp_buf_init(&b);
    assert_int_equal(stp_enc_sample_req(&b, 2, 0, &r), 0);
    assert_int_equal(b.len, sizeof want_req);
    assert_memory_equal(b.data, want_req, sizeof want_req);
    float v[3] = { 1.0f, 0.5f, 0.0f }, cov = 1.0f;
    uint8_t st = 0;
    stp_sample_reply rp = { 1, 3, STP_OUT_UNORM8, 3, 0, v, &cov, &st, NULL, NULL, NULL };
    stp_buf_clear(&b);
    assert_int_equal(stp_enc_sample_reply(&b, STP_OP_SAMPLE, 2, &rp), 0);
    assert_int_equal(b.len, sizeof want_rep);
    assert_memory_equal(b.data, want_rep, sizeof want_rep);
    stp_buf_free(&b);
}

/* ---- buffer, crc, names, statuses --------------------------------------------------------- */

static void frames_survive_buffer_compaction(void **state)
{
    (void)state;
    stp_buf b;
    stp_header h;
    stp_buf_init(&b);
    /* fill, consume most of it, then write a frame large enough to force compaction */
    uint8_t junk[200] = { 0 };
    stp_put_bytes(&b, junk, sizeof junk);
    stp_buf_consume(&b, 190);
    size_t at = stp_frame_begin(&b, STP_OP_PING, 0, 1, 0, 0);
    uint8_t payload[1000];
    memset(payload, 0xab, sizeof payload);
    stp_put_bytes(&b, payload, sizeof payload);
    assert_int_equal(stp_frame_end(&b, at), 0);
    assert_int_equal(stp_buf_avail(&b), 10 + STP_HEADER_SIZE + 1000);
    assert_int_equal(stp_parse_header(stp_buf_head(&b) + 10, stp_buf_avail(&b) - 10, 4096, &h,
                                      NULL), STP_OK);
    assert_int_equal(h.body_len, 1000);
    stp_buf_free(&b);
}

static void crc32c_matches_check_value_and_both_paths_agree(void **state)
{
    (void)state;
    assert_int_equal(stp_crc32c(0, "123456789", 9), 0xE3069283u);
    assert_int_equal(stu_crc32c_sw(0, "123456789", 9), 0xE3069283u);
    assert_int_equal(stp_crc32c(0, "", 0), 0);
    uint8_t *d = malloc(10000);
    uint32_t x = 12345;
    for (int i = 0; i < 10000; i++) {
        x = x * 1103515245u + 12345u;
        d[i] = (uint8_t)(x >> 16);
    }
    for (size_t off = 0; off < 9; off++)
        for (size_t n = 0; n < 100; n += 7) {
            assert_int_equal(stp_crc32c(0, d + off, n * 13), stu_crc32c_sw(0, d + off, n * 13));
        }
    /* incremental equals one shot */
    uint32_t whole = stp_crc32c(0, d, 10000);
    uint32_t part = stp_crc32c(stp_crc32c(stp_crc32c(0, d, 3), d + 3, 4000), d + 4003, 5997);
    assert_int_equal(whole, part);
    free(d);
}

static void status_and_opcode_names_come_from_the_lists(void **state)
{
    (void)state;
    for (unsigned s = 0; s < STP_S_COUNT_; s++)
        assert_string_not_equal(stp_status_name(s), "?");
    assert_string_equal(stp_status_name(STP_S_COUNT_), "?");
    assert_string_equal(stp_status_name(STP_S_INVALID), "INVALID");
    assert_string_equal(stp_status_name(STP_S_UNKNOWN_OPCODE), "UNKNOWN_OPCODE");
    /* the client's enum is the server status, negated and offset */
    assert_int_equal(STC_ENOTFOUND, -(STC_SERVER_BASE + STP_S_NOT_FOUND));
    assert_int_equal(STC_ETOOLARGE, -(STC_SERVER_BASE + STP_S_TOO_LARGE));
    assert_int_equal(STC_EPERM, -(STC_SERVER_BASE + STP_S_PERM));
    assert_int_equal(STC_ESHUTDOWN, -(STC_SERVER_BASE + STP_S_SHUTDOWN));
    assert_int_equal(stc_server_status(STC_ECORRUPT), STP_S_CORRUPT);
    assert_string_equal(stc_strerror(STC_ENOTFOUND), "NOT_FOUND");
    assert_string_equal(stc_strerror(STC_ETIMEDOUT), "ETIMEDOUT");
    assert_string_equal(stc_strerror(STC_ECANCELED), "ECANCELED");
    assert_string_equal(stc_strerror(STC_OK), "OK");
    assert_string_equal(stc_strerror(-50), "?");   /* every unknown code (lib35) */
    /* opcodes: names, mutating flags as PROTOCOL.md section 4 lists them */
    static const struct { unsigned op; const char *name; int mut; } ops[] = {
        {0x01, "HELLO", 0}, {0x02, "PING", 0}, {0x03, "LIST", 0}, {0x04, "INFO", 0},
        {0x05, "SAMPLE", 0}, {0x06, "SAMPLE_DIR", 0}, {0x07, "STATS", 0},
        {0x10, "UPLOAD_BEGIN", 1}, {0x11, "UPLOAD_CHUNK", 1}, {0x12, "UPLOAD_COMMIT", 1},
        {0x13, "UPLOAD_ABORT", 1}, {0x14, "UPLOAD_STATUS", 0}, {0x15, "DELETE", 1},
        {0x20, "COMPRESS", 1}, {0x21, "JOB_STATUS", 0}, {0x22, "JOB_CANCEL", 1},
        {0x23, "FETCH_OPEN", 0}, {0x24, "FETCH_READ", 0}, {0x25, "FETCH_CLOSE", 0},
        {0x30, "CLUSTER", 0}, {0x31, "REPLICA_PUBLISH", 1}, {0x08, "SHM_ATTACH", 0},
    };
    unsigned named = 0;
    for (unsigned op = 0; op < 256; op++)
        named += stp_opcode_name(op) != NULL;
    assert_int_equal(named, sizeof ops / sizeof ops[0]);
    for (size_t i = 0; i < sizeof ops / sizeof ops[0]; i++) {
        assert_string_equal(stp_opcode_name(ops[i].op), ops[i].name);
        assert_int_equal(stp_opcode_mutating(ops[i].op), ops[i].mut);
    }
    assert_null(stp_opcode_name(0x09));
    assert_false(stp_opcode_mutating(0x99));
}

/* The protocol's value lists round-trip, and agree with the store's names and numbers (the
 * wire values ARE the store's; the daemon checks the numbers at compile time too). */
static void value_lists_round_trip_and_match_the_store(void **state)
{
    (void)state;
    unsigned nmodes = 0, nfilters = 0;
    for (unsigned v = 0; v < 256; v++) {
        const char *m = stp_mode_name(v), *f = stp_filter_name(v);
        if (m) {
            nmodes++;
            assert_int_equal(stp_mode_parse(m), (int)v);
            assert_string_equal(m, st_mode_name(v));
        } else {
            assert_null(st_mode_name(v));
        }
        if (f) {
            nfilters++;
            assert_int_equal(stp_filter_parse(f), (int)v);
            assert_string_equal(f, st_filter_name(v));
        } else {
            assert_null(st_filter_name(v));
        }
    }
    assert_int_equal(nmodes, 3);
    assert_int_equal(nfilters, 12);
    assert_int_equal(stp_mode_parse("traverse"), ST_MODE_TRAVERSE);
    assert_int_equal(stp_filter_parse("ptex-mitchell"), ST_FILTER_PTEX_MITCHELL);
    assert_int_equal(stp_filter_parse("ptex_bilinear"), ST_FILTER_PTEX_BILINEAR);
    assert_int_equal(stp_filter_parse("nope"), -1);
    assert_int_equal(stp_filter_parse(NULL), -1);
    assert_int_equal(stp_mode_parse(NULL), -1);
    assert_int_equal(stp_zero_rule_parse("clamp"), ST_ZERO_CLAMP);
    assert_int_equal(stp_zero_rule_parse("nan"), ST_ZERO_NAN);
    assert_int_equal(stp_zero_rule_parse("x"), -1);
    assert_int_equal(stp_outfmt_parse("unorm16"), STP_OUT_UNORM16);
    assert_string_equal(stp_outfmt_name(STP_OUT_UNORM8), "unorm8");
    assert_int_equal(stp_outfmt_size(STP_OUT_F32), 4);
    assert_int_equal(stp_outfmt_size(STP_OUT_UNORM16), 2);
    assert_int_equal(stp_outfmt_size(STP_OUT_F16), 2);
    assert_int_equal(stp_outfmt_size(4), 0);
    assert_string_equal(stp_qstatus_name(ST_Q_ZERO_COVERAGE), "ZERO_COVERAGE");
    assert_string_equal(stp_qstatus_name(ST_Q_OK), "OK");
    assert_string_equal(stp_qstatus_name(5), "?");
    assert_string_equal(stp_kind_name(ST_KIND_ATLAS), "atlas");
    assert_string_equal(stp_dtype_name(ST_DT_HALF), "half");
    assert_null(stp_kind_name(4));
}

/* The one set-name rule: 1..255 bytes of [A-Za-z0-9._-], the first not '.'. */
static void set_names_follow_one_rule(void **state)
{
    (void)state;
    static const struct { const char *name; int problem; } rows[] = {
        {"a", STP_NAME_OK}, {"Tex_01.ptx-v2", STP_NAME_OK}, {"x..y", STP_NAME_OK},
        {"a.", STP_NAME_OK}, {"-", STP_NAME_OK}, {"_", STP_NAME_OK},
        {"", STP_NAME_EMPTY}, {".", STP_NAME_DOT}, {"..", STP_NAME_DOT},
        {".hidden", STP_NAME_DOT}, {"../etc", STP_NAME_DOT}, {"a/b", STP_NAME_BAD_BYTE},
        {"/abs", STP_NAME_BAD_BYTE}, {"sp ace", STP_NAME_BAD_BYTE}, {"a\\b", STP_NAME_BAD_BYTE},
        {"caf\xc3\xa9", STP_NAME_BAD_BYTE}, {"\x80", STP_NAME_BAD_BYTE},
        {"tab\t", STP_NAME_BAD_BYTE}, {"a:b", STP_NAME_BAD_BYTE},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const char *n = rows[i].name;
        assert_int_equal(stp_name_check(n, strlen(n), NULL), rows[i].problem);
        assert_int_equal(stp_name_valid(n, strlen(n)), rows[i].problem == STP_NAME_OK);
        assert_int_equal(stp_name_valid_cstr(n), rows[i].problem == STP_NAME_OK);
        assert_true(stp_name_problem_text(rows[i].problem)[0] || rows[i].problem == 0);
    }
    size_t at = 99;
    assert_int_equal(stp_name_check("ab/c", 4, &at), STP_NAME_BAD_BYTE);
    assert_int_equal(at, 2);
    /* a NUL inside the length is a bad byte, not the end of the name */
    assert_int_equal(stp_name_check("a\0b", 3, &at), STP_NAME_BAD_BYTE);
    assert_int_equal(at, 1);
    assert_false(stp_name_valid(NULL, 0));
    assert_false(stp_name_valid_cstr(NULL));
    /* 255 bytes is the longest name, 256 is one too many */
    char longname[300];
    memset(longname, 'a', sizeof longname);
    assert_true(stp_name_valid(longname, 255));
    assert_int_equal(stp_name_check(longname, 256, NULL), STP_NAME_TOO_LONG);
    longname[255] = 0;
    assert_true(stp_name_valid_cstr(longname));
    longname[255] = 'a';
    longname[256] = 0;
    assert_false(stp_name_valid_cstr(longname));
    /* the registry applies the same rule and says INVALID (ST_EINVAL) */
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_name_check("a/b", 3, &e), ST_EINVAL);
    assert_non_null(strstr(e.msg, "0x2f"));
    longname[255] = 0;
    assert_int_equal(st_name_check(longname, 255, NULL), 0);
}

/* Request decoders hold every set name to the rule: a malformed name is INVALID (the body is
 * well-formed), a body cut short is still BAD_REQUEST. */
static void request_decoders_refuse_bad_names_as_invalid(void **state)
{
    (void)state;
    static const char *const bad[] = {"", "../x", "a/b", ".hidden", "/abs", "\x80\x81",
                                      "caf\xc3\xa9"};
    static const size_t badlen[] = {0, 4, 3, 7, 4, 2, 5};
    char big[300];
    memset(big, 'n', sizeof big);
    for (int k = 0; k < 9; k++) {
        const char *n = k < 7 ? bad[k] : big;
        size_t nl = k < 7 ? badlen[k] : k == 7 ? 256 : 255;
        int want = k == 8 ? 0 : STP_S_INVALID;
        uint8_t body[1200];
        size_t bl;
        const char *why = NULL;
        /* name body (DELETE) */
        body[0] = (uint8_t)nl; body[1] = (uint8_t)(nl >> 8);
        memcpy(body + 2, n, nl);
        bl = 2 + nl;
        char name[STP_MAX_NAME + 1];
        assert_int_equal(stp_dec_name_req(body, bl, name, &why), want);
        if (want)
            assert_non_null(strstr(why, "set name"));
        else
            assert_int_equal(strlen(name), 255);
        /* INFO */
        memset(body + bl, 0, 8);
        stp_info_req ir;
        assert_int_equal(stp_dec_info_req(body, bl + 8, &ir, &why), want);
        /* FETCH_OPEN */
        body[bl] = 0;
        stp_fetch_open fo;
        assert_int_equal(stp_dec_fetch_open(body, bl + 1, &fo, &why), want);
        /* COMPRESS: a bad source, then a bad target */
        stp_compress_req cr;
        uint8_t cb[600];
        cb[0] = (uint8_t)nl; cb[1] = (uint8_t)(nl >> 8);
        memcpy(cb + 2, n, nl);
        size_t cl = 2 + nl;
        cb[cl++] = 1; cb[cl++] = 0; cb[cl++] = 't';
        cb[cl++] = 0; cb[cl++] = 0;
        assert_int_equal(stp_dec_compress_req(cb, cl, &cr, &why), want);
        cb[0] = 1; cb[1] = 0; cb[2] = 's';
        cl = 3;
        cb[cl++] = (uint8_t)nl; cb[cl++] = (uint8_t)(nl >> 8);
        memcpy(cb + cl, n, nl);
        cl += nl;
        cb[cl++] = 0; cb[cl++] = 0;
        assert_int_equal(stp_dec_compress_req(cb, cl, &cr, &why), want);
        if (want)
            assert_non_null(strstr(why, "target name"));
        /* UPLOAD_BEGIN */
        stp_buf b;
        stp_buf_init(&b);
        stp_upload_begin ub;
        memset(&ub, 0, sizeof ub);
        strcpy(ub.name, "ok");
        assert_int_equal(stp_enc_upload_begin(&b, 1, 0, &ub), 0);
        /* swap the name "ok" (bytes 24+2..) for n */
        uint8_t ubody[1400];
        size_t ulen = stp_buf_avail(&b) - STP_HEADER_SIZE - 4;
        ubody[0] = (uint8_t)nl; ubody[1] = (uint8_t)(nl >> 8);
        memcpy(ubody + 2, n, nl);
        memcpy(ubody + 2 + nl, stp_buf_head(&b) + STP_HEADER_SIZE + 4, ulen);
        stp_upload_begin ubd;
        assert_int_equal(stp_dec_upload_begin(ubody, 2 + nl + ulen, &ubd, &why), want);
        /* SAMPLE with no queries */
        stp_buf_clear(&b);
        stp_sample_req sr;
        memset(&sr, 0, sizeof sr);
        strcpy(sr.p.name, "ok");
        assert_int_equal(stp_enc_sample_req(&b, 1, 0, &sr), 0);
        size_t slen = stp_buf_avail(&b) - STP_HEADER_SIZE - 4;
        memcpy(ubody + 2 + nl, stp_buf_head(&b) + STP_HEADER_SIZE + 4, slen);
        stp_sample_req srd;
        assert_int_equal(stp_dec_sample_req(ubody, 2 + nl + slen, 16, &srd, &why), want);
        assert_int_equal(stp_dec_sample_dir_req(ubody, 2 + nl + slen, 16, &srd, &why), want);
        stp_buf_free(&b);
    }
    /* a body cut inside the name is malformed, not an invalid name; so is a NUL byte in it,
     * as in every str16 (PROTOCOL.md 1) */
    uint8_t cut[4] = {9, 0, 'a', 'b'};
    char name[STP_MAX_NAME + 1];
    const char *why = NULL;
    assert_int_equal(stp_dec_name_req(cut, sizeof cut, name, &why), STP_S_BAD_REQUEST);
    uint8_t nul[5] = {3, 0, 'a', 0, 'b'};
    assert_int_equal(stp_dec_name_req(nul, sizeof nul, name, &why), STP_S_BAD_REQUEST);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(header_round_trips_little_endian),
        cmocka_unit_test(header_needs_more_until_complete),
        cmocka_unit_test(bad_magic_is_fatal_as_soon_as_seen),
        cmocka_unit_test(malformed_frame_table_at_parser_level),
        cmocka_unit_test(malformed_body_table_at_decoder_level),
        cmocka_unit_test(hello_round_trips),
        cmocka_unit_test(list_round_trips_and_refuses_lying_count),
        cmocka_unit_test(info_round_trips_with_face_records),
        cmocka_unit_test(sample_request_round_trips_and_keeps_nan),
        cmocka_unit_test(sample_request_refuses_lying_counts),
        cmocka_unit_test(shm_sample_request_round_trips_and_is_checked),
        cmocka_unit_test(sample_request_refuses_bad_values),
        cmocka_unit_test(zero_length_batch_is_valid),
        cmocka_unit_test(sample_dir_request_round_trips),
        cmocka_unit_test(sample_reply_converts_formats),
        cmocka_unit_test(stats_round_trip),
        cmocka_unit_test(upload_bodies_round_trip),
        cmocka_unit_test(job_and_fetch_bodies_round_trip),
        cmocka_unit_test(strings_with_nul_or_over_the_cap_are_refused),
        cmocka_unit_test(error_frames_carry_a_bounded_message),
        cmocka_unit_test(ping_example_matches_protocol_md),
        cmocka_unit_test(sample_example_matches_protocol_md),
        cmocka_unit_test(frames_survive_buffer_compaction),
        cmocka_unit_test(crc32c_matches_check_value_and_both_paths_agree),
        cmocka_unit_test(status_and_opcode_names_come_from_the_lists),
        cmocka_unit_test(value_lists_round_trip_and_match_the_store),
        cmocka_unit_test(set_names_follow_one_rule),
        cmocka_unit_test(unorm_conversion_is_exact_at_every_boundary),
        cmocka_unit_test(request_decoders_refuse_bad_names_as_invalid),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
