/* tests/integration/test_names.c - the set-name rule end to end, against a real seamtexd.
 *
 * The rule (PROTOCOL.md section 1, protocol/stp_name.h): a set name is 1..255 bytes, each in
 * [A-Za-z0-9._-], the first not '.'. Every request that carries a name (INFO, SAMPLE,
 * SAMPLE_DIR, UPLOAD_BEGIN, DELETE, COMPRESS source and target, FETCH_OPEN) answers INVALID
 * for any other name, with a message saying what is wrong; a name is never PERM (that status
 * is for the token only) and never cut short. The longest legal name works everywhere: upload,
 * INFO, LIST, SAMPLE, FETCH, COMPRESS to a 255-byte target, restart (reloaded from the data
 * dir), DELETE.
 *
 * Bodies over an opcode's body cap are refused with TOO_LARGE before they are read: with a
 * name of 256..~500 bytes every request here is INVALID; a name long enough to push the body
 * over the cap (e.g. 600 bytes in INFO, cap 512) is TOO_LARGE.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_fixture.h"
#include "defaultset.h"
#include "ptex.h"
#include "seamtex.h"

static st_daemon D;

static int setup(void **state)
{
    (void)state;
    if (st_daemon_init(&D) != 0 || st_daemon_start(&D, NULL) != 0)
        return -1;
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    st_daemon_stop(&D, 10000);
    st_daemon_cleanup(&D);
    return 0;
}

static stc_conn *conn(void)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 60000;
    int err = 0;
    char msg[256] = "";
    stc_conn *c = stc_connect_opts(D.host, (unsigned)D.port, &o, &err, msg, sizeof msg);
    if (!c)
        fprintf(stderr, "connect: %s %s\n", stc_strerror(err), msg);
    return c;
}

/* The built-in set as a .ptx in memory (malloc'ed). */
static void *default_ptx(size_t *len)
{
    st_set *s = NULL;
    st_error e;
    void *buf = NULL;
    if (st_default_set(&s, &e) != 0)
        return NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0)
        buf = NULL;
    st_set_free(s);
    return buf;
}

/* A name of n bytes: c repeated, then a tail that makes it unique. */
static void long_name(char *out, size_t n, char c)
{
    memset(out, c, n);
    out[n] = 0;
    out[n - 1] = 'z';
}

static int listed(stc_conn *c, const char *name)
{
    const stc_set_entry *sets = NULL;
    size_t n = 0;
    assert_int_equal(stc_list(c, &sets, &n), 0);
    for (size_t i = 0; i < n; i++)
        if (!strcmp(sets[i].name, name))
            return 1;
    return 0;
}

/* A 255-byte name (the longest) is a set like any other, across a restart and a delete. */
static void a_255_byte_name_works_end_to_end(void **state)
{
    (void)state;
    char name[256], target[256], path[600];
    long_name(name, 255, 'n');
    long_name(target, 255, 't');
    size_t len = 0;
    void *ptx = default_ptx(&len);
    assert_non_null(ptx);
    stc_conn *c = conn();
    assert_non_null(c);

    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    int rc = stc_upload_buffer(c, ptx, len, name, &uo, &ur);
    if (rc)
        fprintf(stderr, "upload: %s: %s\n", stc_strerror(rc), stc_errmsg(c));
    assert_int_equal(rc, 0);
    assert_string_equal(ur.name, name);          /* not cut to 64 bytes */
    assert_true(listed(c, name));
    stc_info info;
    assert_int_equal(stc_info_get(c, name, 0, 1, &info), 0);
    assert_int_equal(info.nfaces, ur.nfaces);

    stc_sample_opts so;
    memset(&so, 0, sizeof so);
    so.mode = 1;
    so.filter = 1;
    so.want = STC_WANT_STATUS;
    stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    stc_sample_result res;
    assert_int_equal(stc_sample(c, name, &so, &q, 1, &res), 0);
    assert_int_equal(res.nbad, 0);

    snprintf(path, sizeof path, "%s/fetched.ptx", D.dir);
    assert_int_equal(stc_fetch_file(c, name, STC_FETCH_PTX, path, NULL, NULL), 0);
    assert_int_equal(access(path, F_OK), 0);
    unlink(path);

    uint64_t job = 0;
    stc_job js;
    assert_int_equal(stc_compress(c, name, target, 0, STC_COMPRESS_SEAM_AWARE, &job), 0);
    rc = stc_job_wait(c, job, 300000, &js) /* a hang guard, not a speed check */;
    if (rc)
        fprintf(stderr, "compress: %s: %s\n", stc_strerror(rc), js.message);
    assert_int_equal(rc, 0);
    assert_int_equal(js.state, STC_JOB_DONE);
    assert_true(listed(c, target));
    stc_close(c);

    /* restart on the same data dir: both come back from disk under their full names */
    assert_int_equal(st_daemon_stop(&D, 10000), 0);
    assert_int_equal(st_daemon_start(&D, NULL), 0);
    c = conn();
    assert_non_null(c);
    assert_true(listed(c, name));
    assert_true(listed(c, target));
    assert_int_equal(stc_info_get(c, target, 0, 0, &info), 0);
    assert_int_equal(stc_delete(c, name), 0);
    assert_int_equal(stc_delete(c, target), 0);
    assert_false(listed(c, name));
    assert_int_equal(stc_delete(c, name), STC_ENOTFOUND);
    stc_close(c);

    /* and the deletes were durable */
    assert_int_equal(st_daemon_stop(&D, 10000), 0);
    assert_int_equal(st_daemon_start(&D, NULL), 0);
    c = conn();
    assert_non_null(c);
    assert_false(listed(c, name));
    assert_false(listed(c, target));
    stc_close(c);
    free(ptx);
}

/* ---- raw requests with bad names ------------------------------------------------------------ */

typedef struct body {
    uint8_t b[2048];
    size_t  n;
} body;

static void put(body *x, const void *p, size_t n)
{
    assert_true(x->n + n <= sizeof x->b);
    memcpy(x->b + x->n, p, n);
    x->n += n;
}
static void put_u8(body *x, uint8_t v) { put(x, &v, 1); }
static void put_zeros(body *x, size_t n)
{
    static const uint8_t z[64];
    put(x, z, n);
}
static void put_str(body *x, const char *s, size_t n)
{
    uint8_t l[2] = {(uint8_t)n, (uint8_t)(n >> 8)};
    put(x, l, 2);
    put(x, s, n);
}

enum { R_INFO, R_DELETE, R_FETCH, R_COMPRESS_SRC, R_COMPRESS_DST, R_UPLOAD, R_SAMPLE,
       R_SAMPLE_DIR, R_COUNT };
static const char *const R_NAME[R_COUNT] = {"INFO", "DELETE", "FETCH_OPEN", "COMPRESS source",
                                            "COMPRESS target", "UPLOAD_BEGIN", "SAMPLE",
                                            "SAMPLE_DIR"};

/* Builds request r with name (n bytes) in its name field; returns the opcode. */
static unsigned build(int r, const char *name, size_t n, body *x)
{
    x->n = 0;
    switch (r) {
    case R_INFO:
        put_str(x, name, n);
        put_zeros(x, 8);
        return 0x04;
    case R_DELETE:
        put_str(x, name, n);
        return 0x15;
    case R_FETCH:
        put_str(x, name, n);
        put_u8(x, 0);
        return 0x23;
    case R_COMPRESS_SRC:
    case R_COMPRESS_DST:
        if (r == R_COMPRESS_SRC) {
            put_str(x, name, n);
            put_str(x, "fresh-target", 12);
        } else {
            put_str(x, "default", 7);
            put_str(x, name, n);
        }
        put_u8(x, 0);
        put_u8(x, 0);
        return 0x20;
    case R_UPLOAD:
        put_str(x, name, n);
        put_str(x, "ptx", 3);
        put_zeros(x, 8);        /* total_size */
        put_zeros(x, 4);        /* crc32c */
        put_zeros(x, 4);        /* flags */
        put_str(x, "", 0);      /* options */
        return 0x10;
    case R_SAMPLE:
    case R_SAMPLE_DIR:
        put_str(x, name, n);
        put_zeros(x, 24);       /* mode 0, filter 0, ..., count 0 */
        return r == R_SAMPLE ? 0x05 : 0x06;
    }
    return 0;
}

/* Sends one raw request and returns its reply's status (an stc code); msg gets the message. */
static int send_raw(stc_conn *c, unsigned op, const body *x, char *msg, size_t cap)
{
    uint32_t id = 0;
    stc_reply rp;
    assert_int_equal(stc_append_raw(c, op, x->b, x->n, &id), 0);
    assert_int_equal(stc_flush(c), 0);
    assert_int_equal(stc_get_reply(c, 20000, &rp), 0);
    assert_int_equal(rp.reqid, id);
    snprintf(msg, cap, "%s", rp.errmsg ? rp.errmsg : "");
    return rp.status;
}

/* Every name-carrying request answers INVALID, naming the fault, for every malformed name. */
static void malformed_names_are_invalid_in_every_request(void **state)
{
    (void)state;
    char n256[257], n600[601];
    long_name(n256, 256, 'a');
    long_name(n600, 600, 'a');
    static const struct { const char *name; size_t len; const char *says; } bad[] = {
        {"", 0, "empty"},
        {"../x", 4, "start with '.'"},
        {"a/b", 3, "A-Z a-z 0-9 . _ -"},
        {"/abs", 4, "A-Z a-z 0-9 . _ -"},
        {".hidden", 7, "start with '.'"},
        {"\x80\x81\xfe", 3, "A-Z a-z 0-9 . _ -"},
        {"caf\xc3\xa9", 5, "A-Z a-z 0-9 . _ -"},
        {"sp ace", 6, "A-Z a-z 0-9 . _ -"},
        {NULL, 256, "longer than 255 bytes"},
    };
    stc_conn *c = conn();
    assert_non_null(c);
    char msg[1100];
    body x;
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *name = bad[i].name ? bad[i].name : n256;
        for (int r = 0; r < R_COUNT; r++) {
            unsigned op = build(r, name, bad[i].len, &x);
            int st = send_raw(c, op, &x, msg, sizeof msg);
            if (st != STC_EINVALID || !strstr(msg, bad[i].says))
                fprintf(stderr, "%s with name #%zu: %s '%s'\n", R_NAME[r], i, stc_strerror(st),
                        msg);
            assert_int_equal(st, STC_EINVALID);
            assert_non_null(strstr(msg, bad[i].says));
            assert_non_null(strstr(msg, r == R_COMPRESS_DST ? "target name" : "set name"));
        }
    }
    /* a name that takes the body over its opcode's cap: TOO_LARGE, before any decoding */
    unsigned op = build(R_INFO, n600, 600, &x);
    assert_int_equal(send_raw(c, op, &x, msg, sizeof msg), STC_ETOOLARGE);
    /* the connection is fine after all that, and nothing was created */
    assert_int_equal(stc_ping(c), 0);
    assert_false(listed(c, "fresh-target"));
    stc_close(c);
}

/* Names just inside the rule pass the name check (and then meet the usual answers). */
static void names_inside_the_rule_reach_the_handler(void **state)
{
    (void)state;
    char n255[256];
    long_name(n255, 255, 'q');
    static const char *const ok[] = {"a", "x..y", "A-b_c.9", "trailing.", "-dash", "_u"};
    stc_conn *c = conn();
    assert_non_null(c);
    char msg[1100];
    body x;
    for (size_t i = 0; i <= sizeof ok / sizeof ok[0]; i++) {
        const char *name = i < sizeof ok / sizeof ok[0] ? ok[i] : n255;
        unsigned op = build(R_INFO, name, strlen(name), &x);
        assert_int_equal(send_raw(c, op, &x, msg, sizeof msg), STC_ENOTFOUND);
        op = build(R_DELETE, name, strlen(name), &x);
        assert_int_equal(send_raw(c, op, &x, msg, sizeof msg), STC_ENOTFOUND);
        op = build(R_FETCH, name, strlen(name), &x);
        assert_int_equal(send_raw(c, op, &x, msg, sizeof msg), STC_ENOTFOUND);
    }
    stc_close(c);
}

/* libseamtex applies the same rule before sending anything. */
static void the_client_library_refuses_bad_names_locally(void **state)
{
    (void)state;
    char n256[257];
    long_name(n256, 256, 'a');
    stc_conn *c = conn();
    assert_non_null(c);
    stc_info info;
    assert_int_equal(stc_info_get(c, "../x", 0, 0, &info), STC_EINVAL);
    assert_int_equal(stc_info_get(c, n256, 0, 0, &info), STC_EINVAL);
    assert_int_equal(stc_delete(c, ".hidden"), STC_EINVAL);
    assert_int_equal(stc_upload_buffer(c, "x", 1, "a/b", NULL, NULL), STC_EINVAL);
    uint64_t job = 0;
    assert_int_equal(stc_compress(c, "default", "", 0, 0, &job), STC_EINVAL);
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(malformed_names_are_invalid_in_every_request),
        cmocka_unit_test(names_inside_the_rule_reach_the_handler),
        cmocka_unit_test(the_client_library_refuses_bad_names_locally),
        cmocka_unit_test(a_255_byte_name_works_end_to_end),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
