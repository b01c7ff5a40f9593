/* client/cli_json.c - the CLI's JSON writer (see cli_json.h). */
#include "cli_json.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Length of the valid UTF-8 sequence at s (1..4), 0 when the bytes there are not one
 * (a stray continuation byte, a truncated sequence, an overlong form, a surrogate, or a
 * code point above U+10FFFF). */
static int utf8_len(const unsigned char *s)
{
    unsigned c = s[0];
    int n;
    unsigned cp, min;
    if (c < 0x80)
        return 1;
    if (c >= 0xC2 && c <= 0xDF) { n = 2; cp = c & 0x1F; min = 0x80; }
    else if (c >= 0xE0 && c <= 0xEF) { n = 3; cp = c & 0x0F; min = 0x800; }
    else if (c >= 0xF0 && c <= 0xF4) { n = 4; cp = c & 0x07; min = 0x10000; }
    else return 0;
    for (int i = 1; i < n; i++) {
        if ((s[i] & 0xC0) != 0x80)       /* also stops at the NUL terminator */
            return 0;
        cp = (cp << 6) | (s[i] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
        return 0;
    return n;
}

void cli_json_write_string(FILE *f, const char *str)
{
    const unsigned char *s = (const unsigned char *)str;
    while (*s) {
        unsigned c = *s;
        if (c == '"' || c == '\\') {
            fputc('\\', f);
            fputc((int)c, f);
            s++;
        } else if (c < 0x20) {
            switch (c) {
            case '\n': fputs("\\n", f); break;
            case '\r': fputs("\\r", f); break;
            case '\t': fputs("\\t", f); break;
            case '\b': fputs("\\b", f); break;
            case '\f': fputs("\\f", f); break;
            default: fprintf(f, "\\u%04x", c); break;
            }
            s++;
        } else if (c < 0x80) {
            fputc((int)c, f);
            s++;
        } else {
            int n = utf8_len(s);
            if (n) {
                fwrite(s, 1, (size_t)n, f);
                s += n;
            } else {
                fputs("\\ufffd", f);      /* not UTF-8: the replacement character */
                s++;
            }
        }
    }
}

/* The comma, indentation and key before a value at the current level. */
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
        fputc('"', j->f);
        cli_json_write_string(j->f, key);
        fputs("\": ", j->f);
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
    fputc('"', j->f);
    cli_json_write_string(j->f, v);
    fputc('"', j->f);
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
