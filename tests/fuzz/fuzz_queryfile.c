/* tests/fuzz/fuzz_queryfile.c - libFuzzer target for the CLI's query-file line parsers
 * (client/cli_parse.c: cli_query_line "face u v [dudx dvdx dudy dvdy]" and cli_dir_query_line
 * "x y z [ddx(3) ddy(3)]"), fed line by line as `seamtex sample --queries FILE` reads them.
 * Every line goes through both parsers. Invariants for a line that parses:
 *   - every value is within float's range, or a NaN / infinity the line spelled out;
 *   - parse(print(q)) == q bit for bit (NaNs compare as NaN), printed with %u and %.9g.
 * The CLI's sources are compiled into this target directly (the fuzz build links no client
 * objects). Seeds: tests/fuzz/seeds/fuzz_queryfile/. */
#include "../../client/cli_parse.c"

#include <stdio.h>

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int same(float a, float b)
{
    return (isnan(a) && isnan(b)) || !memcmp(&a, &b, sizeof a);
}

static void check_values(const float *v, int n)
{
    for (int i = 0; i < n; i++)
        CHECK(isnan(v[i]) || isinf(v[i]) || fabsf(v[i]) <= FLT_MAX);
}

static void one_line(const char *src, size_t n)
{
    char *line = malloc(n + 2), *copy = malloc(n + 2);
    CHECK(line && copy);
    memcpy(line, src, n);
    line[n] = '\n';          /* getline keeps the newline */
    line[n + 1] = 0;
    memcpy(copy, line, n + 2);

    stc_query q;
    int r = cli_query_line(line, &q);
    CHECK(r >= -1 && r <= 1);
    if (r == 1) {
        float v[6] = {q.u, q.v, q.dudx, q.dvdx, q.dudy, q.dvdy};
        check_values(v, 6);
        char out[256];
        snprintf(out, sizeof out, "%u %.9g %.9g %.9g %.9g %.9g %.9g\n", q.face, (double)q.u,
                 (double)q.v, (double)q.dudx, (double)q.dvdx, (double)q.dudy, (double)q.dvdy);
        stc_query b;
        CHECK(cli_query_line(out, &b) == 1);
        CHECK(b.face == q.face && same(b.u, q.u) && same(b.v, q.v) && same(b.dudx, q.dudx) &&
              same(b.dvdx, q.dvdx) && same(b.dudy, q.dudy) && same(b.dvdy, q.dvdy));
    }

    stc_dir_query d;
    r = cli_dir_query_line(copy, &d);
    CHECK(r >= -1 && r <= 1);
    if (r == 1) {
        float v[9];
        memcpy(v, d.dir, sizeof d.dir);
        memcpy(v + 3, d.ddx, sizeof d.ddx);
        memcpy(v + 6, d.ddy, sizeof d.ddy);
        check_values(v, 9);
        char out[400];
        int k = 0;
        for (int i = 0; i < 9; i++)
            k += snprintf(out + k, sizeof out - (size_t)k, "%.9g ", (double)v[i]);
        stc_dir_query b;
        CHECK(cli_dir_query_line(out, &b) == 1);
        float w[9];
        memcpy(w, b.dir, sizeof b.dir);
        memcpy(w + 3, b.ddx, sizeof b.ddx);
        memcpy(w + 6, b.ddy, sizeof b.ddy);
        for (int i = 0; i < 9; i++)
            CHECK(same(w[i], v[i]));
    }
    free(line);
    free(copy);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *p = (const char *)data, *end = p + size;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t n = nl ? (size_t)(nl - p) : (size_t)(end - p);
        one_line(p, n);
        p += n + (nl != NULL);
    }
    return 0;
}
