/* tests/unit/test_protodoc.c - PROTOCOL.md's tables that print the daemon's own numbers agree
 * with the code: the per-opcode table of section 2.2 (code, name, mutating, body cap, where it
 * runs) against sts_handler_find (server/dispatch.c), row by row and both ways (every opcode
 * the daemon serves has exactly one row, every row is an opcode it serves).
 *
 * Reads PROTOCOL.md from the working directory (tests/run.sh runs from the repository root)
 * or from $SEAMTEX_BUILD/.. . No daemon.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "dispatch.h"
#include "proto.h"

#define TABLE_MARK "<!-- opcode-caps-table"

static char *read_protocol_md(void)
{
    char path[4096];
    const char *b = getenv("SEAMTEX_BUILD");
    FILE *f = fopen("PROTOCOL.md", "rb");
    if (!f && b) {
        snprintf(path, sizeof path, "%s/../PROTOCOL.md", b);
        f = fopen(path, "rb");
    }
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        s = NULL;
    }
    if (s)
        s[n] = 0;
    fclose(f);
    return s;
}

/* Splits a table row "| a | b | ... |" into trimmed cells (in place); returns the count. */
static int cells(char *line, char *out[], int max)
{
    int n = 0;
    char *p = strchr(line, '|');
    while (p && n < max) {
        char *q = strchr(p + 1, '|');
        if (!q)
            break;
        *q = 0;
        char *a = p + 1, *z = q;
        while (*a == ' ')
            a++;
        while (z > a && z[-1] == ' ')
            z--;
        *z = 0;
        out[n++] = a;
        p = q;
    }
    return n;
}

static const char *runs_text(unsigned flags)
{
    return (flags & STS_H_HEAVY) ? "worker"
           : (flags & STS_H_SIZED) ? "worker over heavy-batch queries" : "inline";
}

static void caps_table_matches_dispatch(void **state)
{
    (void)state;
    char *doc = read_protocol_md();
    assert_non_null(doc);
    char *t = strstr(doc, TABLE_MARK);
    if (!t)
        fail_msg("PROTOCOL.md has no '%s' marker before the caps table", TABLE_MARK);
    int seen[256] = {0};
    int rows = 0;
    char *line = strchr(t, '\n');
    /* the table: from the first row that starts with '|' to the first line that does not */
    while (line && (line[1] != '|'))
        line = strchr(line + 1, '\n');
    while (line && line[1] == '|') {
        char *end = strchr(line + 1, '\n');
        if (end)
            *end = 0;
        char *c[8];
        int n = cells(line + 1, c, 8);
        line = end;
        if (n < 5 || strncmp(c[0], "0x", 2) != 0)
            continue;   /* the header and the alignment row */
        unsigned op = (unsigned)strtoul(c[0], NULL, 16);
        const sts_handler *hd = sts_handler_find(op);
        if (!hd)
            fail_msg("PROTOCOL.md 2.2 lists 0x%02x (%s), which the daemon does not serve", op, c[1]);
        if (seen[op]++)
            fail_msg("PROTOCOL.md 2.2 lists 0x%02x twice", op);
        rows++;
        if (strcmp(c[1], hd->name) != 0)
            fail_msg("0x%02x: PROTOCOL.md says %s, dispatch.c %s", op, c[1], hd->name);
        int mut = !strcmp(c[2], "yes");
        if (mut != ((hd->flags & STS_H_MUTATING) != 0) || (!mut && c[2][0]))
            fail_msg("%s: PROTOCOL.md's mutating column '%s' is wrong", hd->name, c[2]);
        if (hd->max_body == 0) {
            if (strcmp(c[3], "max_body"))
                fail_msg("%s: PROTOCOL.md's cap is '%s', dispatch.c has none (max_body)",
                         hd->name, c[3]);
        } else {
            char want[32];
            snprintf(want, sizeof want, "%u", hd->max_body);
            if (strcmp(c[3], want))
                fail_msg("%s: PROTOCOL.md's cap is '%s', dispatch.c's %s", hd->name, c[3], want);
        }
        if (strcmp(c[4], runs_text(hd->flags)))
            fail_msg("%s: PROTOCOL.md says it runs '%s', dispatch.c '%s'", hd->name, c[4],
                     runs_text(hd->flags));
    }
    for (unsigned op = 0; op < 256; op++)
        if (sts_handler_find(op) && !seen[op])
            fail_msg("PROTOCOL.md 2.2 has no row for 0x%02x %s", op, sts_handler_find(op)->name);
    assert_true(rows >= 19);
    free(doc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(caps_table_matches_dispatch),
    };
    return cmocka_run_group_tests_name("protodoc", tests, NULL, NULL);
}
