/* server/metrics_req.c - the request reader of the /metrics endpoint (metrics.h,
 * sts_metrics_judge): the HTTP/1.x request line and headers a scraper sends, judged byte by
 * byte as they arrive. Apart from metrics_http.c (sockets, thread) so that it can be fuzzed
 * alone (tests/fuzz/fuzz_metrics.c). The rules are listed in metrics_http.c's opening
 * comment. */
#include <string.h>

#include "metrics.h"

static int tchar(unsigned char c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           (c && strchr("!#$%&'*+-.^_`|~", c));
}

int sts_metrics_judge(const char *buf, size_t len, int *head)
{
    const char *nl = memchr(buf, '\n', len);
    size_t line = nl ? (size_t)(nl - buf) : len;
    for (size_t i = 0; i < line; i++) {
        unsigned char c = (unsigned char)buf[i];
        /* a CR only right before the LF, or as the last byte read so far: a read may stop
         * between the two (a valid request must not get 400 for where the reads fell) */
        if ((c < 0x20 && !(c == '\r' && i + 1 == line)) || c >= 0x7F)
            return 400;                      /* binary garbage: no need to wait */
    }
    if (!nl)
        return len >= STS_METRICS_MAX_REQUEST ? 414 : 0;
    if (line && buf[line - 1] == '\r')
        line--;
    /* METHOD SP TARGET SP HTTP/1.x */
    const char *sp1 = memchr(buf, ' ', line);
    const char *sp2 = sp1 ? memchr(sp1 + 1, ' ', line - (size_t)(sp1 + 1 - buf)) : NULL;
    if (!sp1 || !sp2 || sp1 == buf || sp2 == sp1 + 1)
        return 400;
    const char *ver = sp2 + 1;
    size_t vlen = line - (size_t)(ver - buf);
    if (vlen != 8 || (memcmp(ver, "HTTP/1.1", 8) && memcmp(ver, "HTTP/1.0", 8)))
        return 400;
    for (const char *p = buf; p < sp1; p++)
        if (!tchar((unsigned char)*p))
            return 400;
    /* headers: up to an empty line */
    const char *p = nl + 1, *end = buf + len;
    for (;;) {
        const char *e = memchr(p, '\n', (size_t)(end - p));
        size_t hl = e ? (size_t)(e - p) : (size_t)(end - p);
        for (size_t i = 0; i < hl; i++) {
            unsigned char c = (unsigned char)p[i];
            if ((c < 0x20 && c != '\t' && !(c == '\r' && i + 1 == hl)) || c == 0x7F)
                return 400;
        }
        if (!e)
            return len >= STS_METRICS_MAX_REQUEST ? 431 : 0;
        if (hl && p[hl - 1] == '\r')
            hl--;
        if (!hl)
            break;                             /* the empty line: the request is whole */
        const char *colon = memchr(p, ':', hl);
        if (p[0] == ' ' || p[0] == '\t' || !colon || colon == p)
            return 400;                        /* folded, or no "name:" */
        for (const char *q = p; q < colon; q++)
            if (!tchar((unsigned char)*q))
                return 400;
        p = e + 1;
    }
    size_t mlen = (size_t)(sp1 - buf);
    int get = mlen == 3 && !memcmp(buf, "GET", 3);
    *head = mlen == 4 && !memcmp(buf, "HEAD", 4);
    if (!get && !*head)
        return 405;
    size_t tlen = (size_t)(sp2 - sp1 - 1);
    const char *q = memchr(sp1 + 1, '?', tlen);
    if (q)
        tlen = (size_t)(q - sp1 - 1);
    if (tlen != 8 || memcmp(sp1 + 1, "/metrics", 8))
        return 404;
    return 200;
}
