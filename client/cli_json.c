/* client/cli_json.c - the CLI's JSON writer (see cli_json.h). */
#include "cli_json.h"

#include "json_str.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The quoted, escaped literal of str, through util/'s one JSON string escaper (invalid UTF-8
 * becomes U+FFFD, control characters are escaped). */
static void put_string(FILE *f, const char *str)
{
    size_t len = strlen(str);
    char stackbuf[512];
    size_t need = stu_json_str(stackbuf, sizeof stackbuf, str, len);
    if (need < sizeof stackbuf) {
        fwrite(stackbuf, 1, need, f);
        return;
    }
    char *buf = malloc(need + 1);
    if (!buf) {                       /* out of memory: a valid, empty literal */
        fputs("\"\"", f);
        return;
    }
    stu_json_str(buf, need + 1, str, len);
    fwrite(buf, 1, need, f);
    free(buf);
}

static void lead(cli_json *j, const char *key)
{
    if (j->depth > 0) {
        if (j->count[j->depth]++)
            fputc(',', j->f);
        fputc('\n', j->f);
        for (int i = 0; i < j->depth; i++)
            fputs("  ", j->f);
        if ((j->closer[j->depth] == '}') != (key != NULL))
            j->bad = 1;                   /* a key in an array, or none in an object */
    } else if (j->count[0]++ || key) {
        j->bad = 1;                       /* a second top-level value: not one document */
    }
    if (key) {
        put_string(j->f, key);
        fputs(": ", j->f);
    }
}

void cli_json_begin(cli_json *j, FILE *f)
{
    memset(j, 0, sizeof *j);
    j->f = f;
}

static void open_level(cli_json *j, const char *key, char open, char close)
{
    lead(j, key);
    fputc(open, j->f);
    if (j->depth == CLI_JSON_DEPTH) {
        j->bad = 1;
        return;
    }
    j->depth++;
    j->count[j->depth] = 0;
    j->closer[j->depth] = close;
}

void cli_json_object(cli_json *j, const char *key) { open_level(j, key, '{', '}'); }
void cli_json_array(cli_json *j, const char *key) { open_level(j, key, '[', ']'); }

void cli_json_close(cli_json *j)
{
    if (j->depth == 0) {
        j->bad = 1;
        return;
    }
    if (j->count[j->depth]) {
        fputc('\n', j->f);
        for (int i = 1; i < j->depth; i++)
            fputs("  ", j->f);
    }
    fputc(j->closer[j->depth], j->f);
    j->depth--;
}

void cli_json_str(cli_json *j, const char *key, const char *v)
{
    lead(j, key);
    if (!v) {
        fputs("null", j->f);
        return;
    }
    put_string(j->f, v);
}

void cli_json_u64(cli_json *j, const char *key, uint64_t v)
{
    lead(j, key);
    fprintf(j->f, "%llu", (unsigned long long)v);
}

void cli_json_i64(cli_json *j, const char *key, int64_t v)
{
    lead(j, key);
    fprintf(j->f, "%lld", (long long)v);
}

void cli_json_double(cli_json *j, const char *key, double v)
{
    lead(j, key);
    if (!isfinite(v)) {
        fputs("null", j->f);
        return;
    }
    /* the shortest of 15, 16, 17 significant digits that reads back to the same double */
    char buf[40];
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, sizeof buf, "%.*g", prec, v);
        if (strtod(buf, NULL) == v)
            break;
    }
    fputs(buf, j->f);
}

void cli_json_bool(cli_json *j, const char *key, int v)
{
    lead(j, key);
    fputs(v ? "true" : "false", j->f);
}

int cli_json_end(cli_json *j)
{
    fputc('\n', j->f);
    return j->bad || j->depth || j->count[0] != 1 || ferror(j->f) ? -1 : 0;
}
