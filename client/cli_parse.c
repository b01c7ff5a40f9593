/* client/cli_parse.c - the CLI's text parsers that take outside bytes: numbers of arguments
 * and the lines of a query file (`seamtex sample --queries FILE`).
 *
 * Owns: cli_parse_u32, cli_parse_float, cli_query_line, cli_dir_query_line. Does not own:
 * reading the file, the commands (cli_sample.c). No I/O and no connection here, so the fuzz
 * target tests/fuzz/fuzz_queryfile.c compiles this file alone.
 */
#include "cli.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int cli_parse_u32(const char *s, uint32_t *out)
{
    char *end;
    errno = 0;
    if (!s || *s == '-' || *s == '\0')
        return -1;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || *end || v > UINT32_MAX)
        return -1;
    *out = (uint32_t)v;
    return 0;
}

int cli_parse_float(const char *s, float *out)
{
    char *end;
    errno = 0;
    if (!s || *s == '\0')
        return -1;
    double v = strtod(s, &end);
    if (errno == ERANGE && fabs(v) > 1.0)
        return -1;
    if (*end)
        return -1;
    /* a finite value past float's range is refused like strtod's own overflow above
     * (converting it would be undefined behaviour); "nan" and "inf" stay accepted: the server
     * answers such a query with the NONFINITE status. Past FLT_MAX but below the midpoint
     * 2^128 - 2^103 rounds to FLT_MAX: that is how FLT_MAX is printed (%.8g "3.4028235e+38",
     * %.9g "3.40282347e+38", both a little above it) */
    if (isfinite(v) && fabs(v) > FLT_MAX) {
        if (fabs(v) >= 0x1.ffffffp127)
            return -1;
        v = v > 0 ? FLT_MAX : -FLT_MAX;
    }
    *out = (float)v;
    return 0;
}

int cli_query_line(char *line, stc_query *q)
{
    char *hash = strchr(line, '#');
    if (hash)
        *hash = '\0';
    char *tok[8];
    int n = 0;
    for (char *save = NULL, *t = strtok_r(line, " \t\r\n,", &save); t;
         t = strtok_r(NULL, " \t\r\n,", &save)) {
        if (n == 8)
            return -1;
        tok[n++] = t;
    }
    if (n == 0)
        return 0;
    if (n != 3 && n != 7)
        return -1;
    memset(q, 0, sizeof *q);
    float *f[6] = { &q->u, &q->v, &q->dudx, &q->dvdx, &q->dudy, &q->dvdy };
    if (cli_parse_u32(tok[0], &q->face))
        return -1;
    for (int i = 1; i < n; i++)
        if (cli_parse_float(tok[i], f[i - 1]))
            return -1;
    return 1;
}

int cli_dir_query_line(char *line, stc_dir_query *q)
{
    char *hash = strchr(line, '#');
    if (hash)
        *hash = '\0';
    float v[9] = { 0 };
    int n = 0;
    for (char *save = NULL, *t = strtok_r(line, " \t\r\n,", &save); t;
         t = strtok_r(NULL, " \t\r\n,", &save)) {
        if (n == 9 || cli_parse_float(t, &v[n]))
            return -1;
        n++;
    }
    if (n == 0)
        return 0;
    if (n != 3 && n != 9)
        return -1;
    memcpy(q->dir, v, sizeof q->dir);
    memcpy(q->ddx, v + 3, sizeof q->ddx);
    memcpy(q->ddy, v + 6, sizeof q->ddy);
    return 1;
}
