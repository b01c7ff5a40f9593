/* tests/unit/test_cli_json_writer.c - the CLI's JSON writer (client/cli_json.c): every
 * document it writes parses (json-c, strict, UTF-8 validated) and reads back the same values:
 * hostile strings (quotes, backslashes, every control byte, multi-byte UTF-8, bytes that are
 * not UTF-8), integers at the ends of their ranges, doubles bit for bit, NaN as null; misuse
 * of the nesting is reported by cli_json_end.
 *
 * cli_json.c belongs to the CLI, not to a library, so it is compiled into this test directly
 * (as test_hist.c does with the load tester's files).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../client/cli_json.c"

/* A writer on a memory stream; finish() closes it and parses the text strictly. */
typedef struct doc {
    FILE  *f;
    char  *buf;
    size_t len;
    cli_json j;
} doc;

static void start(doc *d)
{
    d->buf = NULL;
    d->len = 0;
    d->f = open_memstream(&d->buf, &d->len);
    assert_non_null(d->f);
    cli_json_begin(&d->j, d->f);
}

/* cli_json_end's result in *end; the parsed document (NULL when it does not parse). */
static json_object *finish(doc *d, int *end)
{
    *end = cli_json_end(&d->j);
    fclose(d->f);
    json_tokener *tok = json_tokener_new();
    assert_non_null(tok);
    json_tokener_set_flags(tok, JSON_TOKENER_STRICT | JSON_TOKENER_VALIDATE_UTF8);
    json_object *o = json_tokener_parse_ex(tok, d->buf, (int)d->len);
    if (json_tokener_get_error(tok) != json_tokener_success ||
        strspn(d->buf + json_tokener_get_parse_end(tok), "\n") !=
            d->len - json_tokener_get_parse_end(tok)) {
        json_object_put(o);
        o = NULL;
    }
    json_tokener_free(tok);
    return o;
}

static const char *str_of(json_object *o, const char *key)
{
    json_object *v;
    assert_true(json_object_object_get_ex(o, key, &v));
    assert_true(json_object_is_type(v, json_type_string));
    return json_object_get_string(v);
}

static void strings_read_back_exactly(void **state)
{
    (void)state;
    char ctl[40];
    for (int i = 1; i < 32; i++)
        ctl[i - 1] = (char)i;
    ctl[31] = '\0';
    const char *cases[] = {
        "", "plain", "quote \" and backslash \\ and slash /", "\"\\\"\\", ctl,
        "tab\there\nnewline\r\b\f", "del \x7f kept",
        "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80",      /* e-acute, euro, an emoji */
        "seamtex: compress: NOT_FOUND: no set named 'x'",
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        doc d;
        start(&d);
        cli_json_object(&d.j, NULL);
        cli_json_str(&d.j, "s", cases[i]);
        cli_json_str(&d.j, cases[i], "as a key");
        cli_json_close(&d.j);
        int end;
        json_object *o = finish(&d, &end);
        assert_int_equal(end, 0);
        assert_non_null(o);
        assert_string_equal(str_of(o, "s"), cases[i]);
        assert_string_equal(str_of(o, cases[i]), "as a key");
        json_object_put(o);
        free(d.buf);
    }
}

static void bytes_that_are_not_utf8_become_replacement_characters(void **state)
{
    (void)state;
    static const struct { const char *in, *out; } cases[] = {
        { "a\x80z", "a\xef\xbf\xbdz" },                        /* a stray continuation byte */
        { "\xc0\xaf", "\xef\xbf\xbd\xef\xbf\xbd" },            /* overlong '/' */
        { "\xed\xa0\x80", "\xef\xbf\xbd\xef\xbf\xbd\xef\xbf\xbd" },  /* a UTF-16 surrogate */
        { "x\xe2\x82", "x\xef\xbf\xbd\xef\xbf\xbd" },          /* truncated at the end */
        { "\xf5\x80\x80\x80", "\xef\xbf\xbd\xef\xbf\xbd\xef\xbf\xbd\xef\xbf\xbd" }, /* > U+10FFFF */
        { "\xff ok \xc3\xa9", "\xef\xbf\xbd ok \xc3\xa9" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        doc d;
        start(&d);
        cli_json_array(&d.j, NULL);
        cli_json_str(&d.j, NULL, cases[i].in);
        cli_json_close(&d.j);
        int end;
        json_object *o = finish(&d, &end);
        assert_int_equal(end, 0);
        assert_non_null(o);
        assert_string_equal(json_object_get_string(json_object_array_get_idx(o, 0)),
                            cases[i].out);
        json_object_put(o);
        free(d.buf);
    }
}

static void integers_and_doubles_are_exact(void **state)
{
    (void)state;
    static const double dbl[] = { 0.0, 0.1, 1.0 / 3.0, -2.5, 1e300, 5e-324, 123456789.125,
                                  4294967296.5, 1.7976931348623157e308 };
    doc d;
    start(&d);
    cli_json_object(&d.j, NULL);
    cli_json_u64(&d.j, "umax", UINT64_MAX);
    cli_json_u64(&d.j, "u0", 0);
    cli_json_i64(&d.j, "imin", INT64_MIN);
    cli_json_i64(&d.j, "m1", -1);
    cli_json_double(&d.j, "nan", NAN);
    cli_json_double(&d.j, "inf", INFINITY);
    cli_json_bool(&d.j, "t", 1);
    cli_json_bool(&d.j, "f", 0);
    cli_json_str(&d.j, "null", NULL);
    cli_json_array(&d.j, "d");
    for (size_t i = 0; i < sizeof dbl / sizeof dbl[0]; i++)
        cli_json_double(&d.j, NULL, dbl[i]);
    cli_json_close(&d.j);
    cli_json_array(&d.j, "empty");
    cli_json_close(&d.j);
    cli_json_close(&d.j);
    int end;
    json_object *o = finish(&d, &end);
    assert_int_equal(end, 0);
    assert_non_null(o);
    json_object *v;
    assert_true(json_object_object_get_ex(o, "umax", &v));
    assert_true(json_object_get_uint64(v) == UINT64_MAX);
    assert_non_null(strstr(d.buf, "\"umax\": 18446744073709551615"));
    assert_true(json_object_object_get_ex(o, "imin", &v));
    assert_true(json_object_get_int64(v) == INT64_MIN);
    assert_true(json_object_object_get_ex(o, "m1", &v));
    assert_true(json_object_get_int64(v) == -1);
    assert_true(json_object_object_get_ex(o, "nan", &v));
    assert_null(v);                                   /* JSON null */
    assert_true(json_object_object_get_ex(o, "inf", &v));
    assert_null(v);
    assert_true(json_object_object_get_ex(o, "t", &v));
    assert_true(json_object_is_type(v, json_type_boolean) && json_object_get_boolean(v));
    assert_true(json_object_object_get_ex(o, "f", &v));
    assert_true(json_object_is_type(v, json_type_boolean) && !json_object_get_boolean(v));
    assert_true(json_object_object_get_ex(o, "null", &v));
    assert_null(v);
    assert_true(json_object_object_get_ex(o, "d", &v));
    assert_int_equal(json_object_array_length(v), sizeof dbl / sizeof dbl[0]);
    for (size_t i = 0; i < sizeof dbl / sizeof dbl[0]; i++) {
        double back = json_object_get_double(json_object_array_get_idx(v, i));
        assert_memory_equal(&back, &dbl[i], sizeof back);   /* bit for bit */
    }
    /* the shortest form that reads back: 0.1 is "0.1", not 0.10000000000000001 */
    assert_non_null(strstr(d.buf, "\n    0.1,"));
    assert_true(json_object_object_get_ex(o, "empty", &v));
    assert_int_equal(json_object_array_length(v), 0);
    json_object_put(o);
    free(d.buf);
}

static void misuse_is_reported(void **state)
{
    (void)state;
    int end;
    doc d;
    /* an object left open */
    start(&d);
    cli_json_object(&d.j, NULL);
    cli_json_u64(&d.j, "a", 1);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    /* two documents */
    start(&d);
    cli_json_u64(&d.j, NULL, 1);
    cli_json_u64(&d.j, NULL, 2);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    /* a value without a key in an object, one with a key in an array */
    start(&d);
    cli_json_object(&d.j, NULL);
    cli_json_u64(&d.j, NULL, 1);
    cli_json_close(&d.j);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    start(&d);
    cli_json_array(&d.j, NULL);
    cli_json_u64(&d.j, "k", 1);
    cli_json_close(&d.j);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    /* a close too many, and nesting past the limit */
    start(&d);
    cli_json_array(&d.j, NULL);
    cli_json_close(&d.j);
    cli_json_close(&d.j);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    start(&d);
    for (int i = 0; i <= CLI_JSON_DEPTH; i++)
        cli_json_array(&d.j, NULL);
    for (int i = 0; i <= CLI_JSON_DEPTH; i++)
        cli_json_close(&d.j);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
    /* nothing at all */
    start(&d);
    json_object_put(finish(&d, &end));
    assert_int_equal(end, -1);
    free(d.buf);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(strings_read_back_exactly),
        cmocka_unit_test(bytes_that_are_not_utf8_become_replacement_characters),
        cmocka_unit_test(integers_and_doubles_are_exact),
        cmocka_unit_test(misuse_is_reported),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
