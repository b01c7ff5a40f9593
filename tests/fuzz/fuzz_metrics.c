/* tests/fuzz/fuzz_metrics.c - libFuzzer target for the /metrics endpoint's request reader
 * (server/metrics_req.c, sts_metrics_judge): the bytes a scraper (or anyone reaching
 * --metrics-listen) sends, at most STS_METRICS_MAX_REQUEST of them (the endpoint's buffer).
 * The input is judged whole and at every prefix that ends after a '\n' or a '\r' (the ways
 * reads can cut it, a CRLF split between two reads included). Invariants:
 *   - the answer is 0 (wait for more) or one of 200 400 404 405 414 431; 0 only while the
 *     buffer is not full, 414 / 431 only once it is;
 *   - a prefix that got an answer gets the same answer with more bytes after it (the endpoint
 *     answers at the first read that decides, so a later byte must not change it);
 *   - 200 only for "GET /metrics" or "HEAD /metrics" (a query string allowed) and an HTTP/1.0
 *     or HTTP/1.1 version, with *head set exactly for HEAD.
 * The buffer is a heap copy of exactly the input's length, so a read past it is an ASan
 * report. Seeds: tests/fuzz/seeds/fuzz_metrics/. */
#include "../../server/metrics_req.c"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#define CHECK(c) do { if (!(c)) { fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, \
                                          __LINE__, #c); __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int judge_copy(const uint8_t *data, size_t len, int *head)
{
    char *buf = malloc(len ? len : 1);
    if (!buf)
        return -1;
    memcpy(buf, data, len);
    *head = -1;
    int st = sts_metrics_judge(buf, len, head);
    free(buf);
    return st;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t len = size < STS_METRICS_MAX_REQUEST ? size : STS_METRICS_MAX_REQUEST;
    int head;
    int st = judge_copy(data, len, &head);
    if (st < 0)
        return 0;
    CHECK(st == 0 || st == 200 || st == 400 || st == 404 || st == 405 || st == 414 ||
          st == 431);
    CHECK(st != 0 || len < STS_METRICS_MAX_REQUEST);
    CHECK((st != 414 && st != 431) || len == STS_METRICS_MAX_REQUEST);
    if (st == 200) {
        CHECK(head == 0 || head == 1);
        const char *m = head ? "HEAD /metrics" : "GET /metrics";
        size_t ml = strlen(m);
        CHECK(len > ml && !memcmp(data, m, ml) && (data[ml] == ' ' || data[ml] == '?'));
        const uint8_t *nl = memchr(data, '\n', len);
        CHECK(nl != NULL);
        size_t line = (size_t)(nl - data);
        if (line && data[line - 1] == '\r')
            line--;
        CHECK(line >= ml + 9 && (!memcmp(data + line - 8, "HTTP/1.1", 8) ||
                                 !memcmp(data + line - 8, "HTTP/1.0", 8)));
    }
    /* prefixes that end after a '\n' or a '\r' (a read can stop between the two), as a read
     * could have stopped there */
    int checked = 0;
    for (size_t i = 0; i < len && checked < 64; i++) {
        if ((data[i] != '\n' && data[i] != '\r') || i + 1 == len)
            continue;
        checked++;
        int h2, st2 = judge_copy(data, i + 1, &h2);
        CHECK(st2 != 414 && st2 != 431);
        if (st2 > 0) {
            CHECK(st2 == st);
            if (st2 == 200)
                CHECK(h2 == head);
            break;
        }
    }
    return 0;
}
