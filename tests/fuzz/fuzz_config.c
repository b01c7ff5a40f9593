/* tests/fuzz/fuzz_config.c - libFuzzer target for seamtexd's config-file parser
 * (server/config.c, sts_config_read_mem: the parser behind sts_config_read_file). Any bytes
 * must give a config or an error message, never a crash. After a successful parse:
 *   - every string setting is NUL-terminated inside its buffer and holds no '#', newline or
 *     leading / trailing blank (the parser's own rules);
 *   - parse(serialise(c)) == c: every setting written back as "key = value" (with the same
 *     formatter the SIGHUP diff uses) and read into fresh defaults gives the same values;
 *   - sts_parse_listen on the listen value gives a port 0..65535 and a terminated host;
 *   - sts_config_check and sts_config_diff run (their results are not judged).
 * An error always comes with a message.
 *
 * The fuzz build links only the store and protocol objects, so the daemon's config and log
 * sources are compiled into this target directly. Seeds: tests/fuzz/seeds/fuzz_config/. */
#include "../../server/config.c"
#include "../../server/log.c"

#include <stdint.h>

/* an invariant: on failure, names it and stops (libFuzzer keeps the input) */
#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_str(const char *s, size_t cap)
{
    const char *nul = memchr(s, 0, cap);
    CHECK(nul != NULL);
    size_t n = (size_t)(nul - s);
    CHECK(!memchr(s, '#', n) && !memchr(s, '\n', n));
    CHECK(n == 0 || (!isspace((unsigned char)s[0]) && !isspace((unsigned char)s[n - 1])));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sts_config c;
    char err[512];
    sts_config_defaults(&c);
    err[0] = 0;
    if (sts_config_read_mem(&c, (const char *)data, size, "fuzz.conf", err, sizeof err)) {
        CHECK(err[0] != 0);
        return 0;
    }
    for (size_t i = 0; i < NOPTS; i++)
        if (OPTS[i].type == T_STR)
            check_str((const char *)&c + OPTS[i].off, OPTS[i].cap);

    /* serialise every setting and read it back */
    size_t cap = NOPTS * (LINE_MAX_BYTES + 8), len = 0;
    char *text = malloc(cap), val[LINE_MAX_BYTES];
    CHECK(text != NULL);
    for (size_t i = 0; i < NOPTS; i++) {
        if (OPTS[i].type == T_NOT)
            continue;
        fmt_val(&c, &OPTS[i], val, sizeof val);
        int n = snprintf(text + len, cap - len, "%s = %s\n", OPTS[i].name, val);
        CHECK(n > 0 && (size_t)n < cap - len);
        len += (size_t)n;
    }
    sts_config back;
    sts_config_defaults(&back);
    if (sts_config_read_mem(&back, text, len, "serialised", err, sizeof err)) {
        fprintf(stderr, "round trip refused: %s\n", err);
        __builtin_trap();
    }
    /* compared setting by setting: a string buffer keeps stale bytes after its NUL when a
     * longer value was overridden by a shorter one, which is not a difference */
    for (size_t i = 0; i < NOPTS; i++) {
        char a[LINE_MAX_BYTES], b[LINE_MAX_BYTES];
        fmt_val(&c, &OPTS[i], a, sizeof a);
        fmt_val(&back, &OPTS[i], b, sizeof b);
        if (strcmp(a, b)) {
            fprintf(stderr, "round trip changed %s: '%s' -> '%s'\n", OPTS[i].name, a, b);
            __builtin_trap();
        }
    }
    free(text);

    char host[128];
    int port = -1;
    if (sts_parse_listen(c.listen, host, sizeof host, &port) == 0) {
        CHECK(port >= 0 && port <= 65535);
        CHECK(memchr(host, 0, sizeof host) != NULL);
    }
    (void)sts_config_check(&c, err, sizeof err);
    sts_config d;
    sts_config_defaults(&d);
    char diff[8192];
    (void)sts_config_diff(&d, &c, diff, sizeof diff);
    return 0;
}
