/* tests/integration/test_log_json.c - seamtexd --log-format json: every line the daemon
 * writes is one JSON object with time, level and message, and the lines that have structured
 * fields carry them (server/log.c).
 *
 * Owns: this behaviour, end to end: a daemon started with --log-format json --log-level debug
 * serves an upload, a refused upload (a bad request: not a Ptex file), a delete, then stops;
 * every line of its stderr is parsed strictly with json-c (tests/common/json_line.h) and the
 * events are looked for with their fields. Also: --log-format takes only text or json.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/daemon_fixture.h"
#include "../common/json_line.h"
#include "../common/ptx_fixture.h"
#include "seamtex.h"

/* "2026-12-01T23:18:54.365Z" */
static int rfc3339_ms_utc(const char *t)
{
    static const char pat[] = "dddd-dd-ddTdd:dd:dd.dddZ";
    if (strlen(t) != sizeof pat - 1)
        return 0;
    for (size_t i = 0; pat[i]; i++)
        if (pat[i] == 'd' ? !(t[i] >= '0' && t[i] <= '9') : t[i] != pat[i])
            return 0;
    return 1;
}

static void every_line_is_a_json_object_with_fields(void **state)
{
    (void)state;
    static const char *const args[] = {"--log-format", "json", "--log-level", "debug", NULL};
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, args), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    size_t len;
    void *ptx = st_fixture_uniform_ptx(&len);
    assert_non_null(ptx);
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.hint = "ptx";
    stc_upload_result r;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "good", &o, &r), 0);
    static const char junk[] = "not a ptex file \x01\xff";
    assert_int_not_equal(stc_upload_buffer(c, junk, sizeof junk, "broken", &o, &r), 0);
    assert_int_equal(stc_delete(c, "good"), 0);
    stc_close(c);
    free(ptx);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);

    FILE *f = fopen(d.log, "r");
    assert_non_null(f);
    char line[16384];
    int lines = 0, serving = 0, refused = 0, created = 0, deleted = 0, stopped = 0;
    while (fgets(line, sizeof line, f)) {
        size_t n = strlen(line);
        assert_true(n > 0 && line[n - 1] == '\n');   /* whole lines only */
        struct json_object *j = st_json_line(line, n - 1);
        assert_non_null(j);
        lines++;
        const char *t = st_json_str(j, "time"), *lv = st_json_str(j, "level");
        assert_non_null(t);
        assert_true(rfc3339_ms_utc(t));
        assert_non_null(lv);
        assert_true(!strcmp(lv, "error") || !strcmp(lv, "warn") || !strcmp(lv, "info") ||
                    !strcmp(lv, "debug"));
        assert_non_null(st_json_str(j, "message"));
        const char *ev = st_json_str(j, "event");
        if (ev && !strcmp(ev, "serving")) {
            serving++;
            assert_int_equal(st_json_int(j, "port"), d.port);
        } else if (ev && !strcmp(ev, "upload_refused")) {
            refused++;
            assert_string_equal(lv, "warn");
            assert_string_equal(st_json_str(j, "set"), "broken");
            assert_string_equal(st_json_str(j, "stage"), "UPLOAD_COMMIT");
            assert_string_equal(st_json_str(j, "status"), "FORMAT");
            assert_non_null(st_json_str(j, "reason"));
            assert_int_equal(strncmp(st_json_str(j, "peer"), "127.0.0.1:", 10), 0);
        } else if (ev && !strcmp(ev, "set_created")) {
            created++;
            assert_string_equal(st_json_str(j, "set"), "good");
            assert_string_equal(st_json_str(j, "format"), "ptx");
            assert_int_equal(st_json_int(j, "bytes"), (int64_t)len);
            assert_int_equal(st_json_int(j, "faces"), 4);
        } else if (ev && !strcmp(ev, "set_deleted")) {
            deleted++;
            assert_string_equal(st_json_str(j, "set"), "good");
        } else if (ev && !strcmp(ev, "stopped")) {
            stopped++;
            assert_true(st_json_int(j, "requests") >= 5);
            assert_true(st_json_int(j, "errors") >= 1);
        }
        json_object_put(j);
    }
    fclose(f);
    assert_true(lines >= 6);
    assert_int_equal(serving, 1);
    assert_int_equal(refused, 1);
    assert_int_equal(created, 1);
    assert_int_equal(deleted, 1);
    assert_int_equal(stopped, 1);
    st_daemon_cleanup(&d);
}

static void log_format_takes_text_or_json_only(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    static const char *const bad[] = {"--log-format", "xml", NULL};
    assert_int_not_equal(st_daemon_start(&d, bad), 0);
    /* text stays the default and keeps its format: "<time> INFO  <message>" */
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);
    FILE *f = fopen(d.log, "r");
    assert_non_null(f);
    char line[4096];
    int info = 0;
    while (fgets(line, sizeof line, f))
        if (line[0] != '{' && strlen(line) > 30 && !strncmp(line + 24, " INFO  ", 7))
            info++;
    fclose(f);
    assert_true(info >= 1);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_line_is_a_json_object_with_fields),
        cmocka_unit_test(log_format_takes_text_or_json_only),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
