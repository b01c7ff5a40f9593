/* tests/unit/test_json_log.c - JSON string escaping (util/json_str.c) and seamtexd's JSON log
 * lines (server/log.c sts_log_format_line), checked by parsing them back with json-c.
 *
 * Owns: these behaviours: every byte string becomes one valid JSON string literal that
 * decodes to the input with control characters and quotes intact and each byte of an invalid
 * UTF-8 sequence as U+FFFD; a cut never splits an escape; log lines are one object each with
 * time (RFC 3339 UTC, milliseconds), level, message and the fields; text lines keep their
 * format. No daemon.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "../common/json_line.h"
#include "json_str.h"
#include "log.h"

/* Escapes in (n bytes), parses {"k": <literal>} back and compares the decoded text. */
static void roundtrip(const char *in, size_t n, const char *want)
{
    char lit[1024], doc[1100];
    size_t need = stu_json_str(lit, sizeof lit, in, n);
    assert_true(need < sizeof lit);
    assert_int_equal(strlen(lit), need);
    assert_true(need <= 6 * n + 2);
    int m = snprintf(doc, sizeof doc, "{\"k\":%s}", lit);
    struct json_object *o = st_json_line(doc, (size_t)m);
    assert_non_null(o);
    assert_string_equal(st_json_str(o, "k"), want);
    json_object_put(o);
}

static void strings_escape_and_decode_back(void **state)
{
    (void)state;
    roundtrip("plain", 5, "plain");
    roundtrip("", 0, "");
    roundtrip("q\"b\\s/", 6, "q\"b\\s/");
    roundtrip("a\nb\rc\td\be\ff", 11, "a\nb\rc\td\be\ff");
    roundtrip("\x01\x1f\x7f", 3, "\x01\x1f\x7f");
    roundtrip("nul\0in", 6, "nul");   /* json-c's C string stops at the NUL it decoded */
    roundtrip("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80", 14, "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
    /* invalid UTF-8: each offending byte becomes U+FFFD */
#define R "\xef\xbf\xbd"
    roundtrip("\xff", 1, R);
    roundtrip("a\x80z", 3, "a" R "z");                 /* stray continuation byte */
    roundtrip("\xc0\xaf", 2, R R);                      /* overlong '/' */
    roundtrip("\xe0\x80\xaf", 3, R R R);                /* overlong, 3 bytes */
    roundtrip("\xed\xa0\x80", 3, R R R);                /* a UTF-16 surrogate */
    roundtrip("\xf4\x90\x80\x80", 4, R R R R);          /* past U+10FFFF */
    roundtrip("ok\xe2\x82", 4, "ok" R R);               /* truncated at the end */
    roundtrip("\xe2\x28\xa1", 3, R "(" R);              /* bad second byte */
#undef R
    /* the escaped form is plain ASCII except well-formed UTF-8 */
    char lit[64];
    stu_json_str(lit, sizeof lit, "\x01", 1);
    assert_string_equal(lit, "\"\\u0001\"");
}

static void a_cut_never_splits_an_escape(void **state)
{
    (void)state;
    const char *in = "ab\"\x01\xc3\xa9z";
    char full[64];
    size_t need = stu_json_str(full, sizeof full, in, strlen(in));
    for (size_t cap = 1; cap <= need; cap++) {
        char out[64];
        memset(out, 'X', sizeof out);
        assert_int_equal(stu_json_str(out, cap, in, strlen(in)), need);
        size_t got = strlen(out);
        assert_true(got < cap);
        assert_memory_equal(out, full, got);   /* a prefix of the whole literal ... */
        /* ... that ends between two pieces: never inside \", \u0001 or the 2-byte é */
        static const size_t cuts[] = {0, 1, 2, 3, 5, 11, 13, 14, 15};
        int ok = 0;
        for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++)
            ok |= got == cuts[i];
        assert_true(ok);
    }
}

static void json_lines_carry_time_level_message_and_fields(void **state)
{
    (void)state;
    char line[8192];
    size_t n = sts_log_format_line(STS_LOG_JSON, STS_WARN, 1764633600, 123456789,
                                   STS_FIELDS(STS_FS("set", "a\"b"), STS_FI("bytes", 12345),
                                              STS_FS("peer", NULL), STS_FI("neg", -7)),
                                   "upload of 'a\"b' refused:\n\x01 bad\xff", line, sizeof line);
    assert_int_equal(n, strlen(line));
    assert_true(n > 0 && line[n - 1] == '\n');
    assert_null(memchr(line, '\n', n - 1));   /* one line */
    struct json_object *o = st_json_line(line, n - 1);
    assert_non_null(o);
    assert_string_equal(st_json_str(o, "time"), "2025-12-02T00:00:00.123Z");
    assert_string_equal(st_json_str(o, "level"), "warn");
    assert_string_equal(st_json_str(o, "message"), "upload of 'a\"b' refused:\n\x01 bad\xef\xbf\xbd");
    assert_string_equal(st_json_str(o, "set"), "a\"b");
    assert_int_equal(st_json_int(o, "bytes"), 12345);
    assert_int_equal(st_json_int(o, "neg"), -7);
    struct json_object *v;
    assert_true(json_object_object_get_ex(o, "peer", &v) && v == NULL);   /* null */
    json_object_put(o);

    /* text lines: the format of before, fields not shown */
    n = sts_log_format_line(STS_LOG_TEXT, STS_INFO, 1764633600, 5000000,
                            STS_FIELDS(STS_FS("set", "x")), "hello", line, sizeof line);
    assert_string_equal(line, "2025-12-02T00:00:00.005Z INFO  hello\n");
}

static void long_lines_stay_valid_json(void **state)
{
    (void)state;
    /* a message of control characters grows 6x when escaped; a small buffer drops what does
     * not fit whole and still closes the object */
    char msg[1024];
    memset(msg, 1, sizeof msg - 1);
    msg[sizeof msg - 1] = 0;
    char big[3000];
    memset(big, 'v', sizeof big - 1);
    big[sizeof big - 1] = 0;
    for (size_t cap = 256; cap <= 8192; cap *= 2) {
        char line[8192];
        size_t n = sts_log_format_line(STS_LOG_JSON, STS_ERROR, 0, 0,
                                       STS_FIELDS(STS_FS("a", big), STS_FI("b", 1)), msg, line,
                                       cap);
        assert_true(n < cap);
        struct json_object *o = st_json_line(line, n - 1);
        assert_non_null(o);
        assert_string_equal(st_json_str(o, "level"), "error");
        assert_non_null(st_json_str(o, "message"));
        json_object_put(o);
    }
}

static void formats_parse(void **state)
{
    (void)state;
    assert_int_equal(sts_log_format_parse("text"), STS_LOG_TEXT);
    assert_int_equal(sts_log_format_parse("json"), STS_LOG_JSON);
    assert_int_equal(sts_log_format_parse("JSON"), -1);
    assert_int_equal(sts_log_format_parse(""), -1);
    assert_string_equal(sts_log_format_name(STS_LOG_JSON), "json");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(strings_escape_and_decode_back),
        cmocka_unit_test(a_cut_never_splits_an_escape),
        cmocka_unit_test(json_lines_carry_time_level_message_and_fields),
        cmocka_unit_test(long_lines_stay_valid_json),
        cmocka_unit_test(formats_parse),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
