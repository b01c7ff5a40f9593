/* tests/common/daemon_client.c - see daemon_client.h. */
#include "daemon_client.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wait.h"
#include "wire.h"
#include "proto.h"

stc_conn *st_daemon_client(const st_daemon *d, const char *token)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 60000;
    o.token = token;
    int err = 0;
    char msg[256] = "";
    stc_conn *c = stc_connect_opts(d->host, (unsigned)d->port, &o, &err, msg, sizeof msg);
    if (!c)
        fprintf(stderr, "connect: %s %s\n", stc_strerror(err), msg);
    return c;
}

uint64_t st_conn_stat(stc_conn *c, const char *key)
{
    const stc_stat *st;
    size_t n;
    if (!c || stc_stats(c, &st, &n) != 0)
        return UINT64_MAX;
    const stc_stat *s = stc_stat_find(st, n, key);
    return s ? s->u : UINT64_MAX;
}

uint64_t st_daemon_stat(const st_daemon *d, const char *key)
{
    stc_conn *c = st_daemon_client(d, NULL);
    if (!c)
        return UINT64_MAX;
    uint64_t v = st_conn_stat(c, key);
    stc_close(c);
    return v;
}

typedef struct stat_cond {
    const st_daemon *d;
    stc_conn *c;
    const char *key;
    st_stat_cmp cmp;
    uint64_t value, last;
} stat_cond;

static int stat_holds(void *arg)
{
    stat_cond *sc = arg;
    sc->last = sc->c ? st_conn_stat(sc->c, sc->key) : st_daemon_stat(sc->d, sc->key);
    if (sc->cmp == ST_STAT_EQ)
        return sc->last == sc->value;
    if (sc->cmp == ST_STAT_LE)
        return sc->last <= sc->value;
    return sc->last != UINT64_MAX && sc->last >= sc->value;
}

int st_wait_stat(const st_daemon *d, stc_conn *c, const char *key, st_stat_cmp cmp,
                 uint64_t value, int timeout_ms)
{
    stat_cond sc = {d, c, key, cmp, value, 0};
    if (st_wait_until(stat_holds, &sc, timeout_ms) == 0)
        return 0;
    fprintf(stderr, "st_wait_stat: %s is %llu after %d ms, want %s %llu\n", key,
            (unsigned long long)sc.last, timeout_ms, cmp == ST_STAT_EQ ? "==" : cmp == ST_STAT_LE ? "<=" : ">=",
            (unsigned long long)value);
    return -1;
}

uint32_t st_rng_next(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

stc_query *st_default_set_queries(size_t n, uint32_t seed)
{
    stc_query *q = calloc(n ? n : 1, sizeof *q);
    if (!q)
        return NULL;
    for (size_t i = 0; i < n; i++) {
        q[i].face = st_rng_next(&seed) % 390;
        q[i].u = (float)(st_rng_next(&seed) % 1000001) / 1e6f;
        q[i].v = (float)(st_rng_next(&seed) % 1000001) / 1e6f;
        float fp = (float)pow(10.0, -(double)(st_rng_next(&seed) % 5) - 0.3);
        q[i].dudx = fp;
        q[i].dvdy = fp * 0.7f;
        q[i].dvdx = (i % 3) ? 0.0f : fp * 0.3f;
        q[i].dudy = (i % 97) ? 0.0f : NAN;
    }
    return q;
}

uint8_t *st_default_sample_frame(size_t n, uint32_t seed, uint32_t reqid, size_t *len)
{
    stc_query *q = st_default_set_queries(n, seed);
    float *q7 = malloc((n ? n : 1) * 7 * sizeof *q7);
    uint8_t *body = malloc(64 + n * 28), *frame = malloc(128 + n * 28);
    if (q && q7 && body && frame) {
        for (size_t i = 0; i < n; i++) {
            float *p = q7 + i * 7;
            p[0] = (float)q[i].face, p[1] = q[i].u, p[2] = q[i].v, p[3] = q[i].dudx;
            p[4] = q[i].dvdx, p[5] = q[i].dudy, p[6] = q[i].dvdy;
        }
        size_t blen = st_wire_sample_body(body, "default", (uint32_t)n, q7, (uint32_t)n);
        *len = st_wire_frame(frame, "STX1", 1, STP_OP_SAMPLE, 0, reqid, body, (uint32_t)blen,
                             (uint32_t)blen);
    } else {
        free(frame);
        frame = NULL;
    }
    free(q);
    free(q7);
    free(body);
    return frame;
}
