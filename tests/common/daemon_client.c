/* tests/common/daemon_client.c - see daemon_client.h. */
#include "daemon_client.h"

#include <stdio.h>
#include <string.h>

#include "wait.h"

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
    return sc->last != UINT64_MAX && sc->last >= sc->value;
}

int st_wait_stat(const st_daemon *d, stc_conn *c, const char *key, st_stat_cmp cmp,
                 uint64_t value, int timeout_ms)
{
    stat_cond sc = {d, c, key, cmp, value, 0};
    if (st_wait_until(stat_holds, &sc, timeout_ms) == 0)
        return 0;
    fprintf(stderr, "st_wait_stat: %s is %llu after %d ms, want %s %llu\n", key,
            (unsigned long long)sc.last, timeout_ms, cmp == ST_STAT_EQ ? "==" : ">=",
            (unsigned long long)value);
    return -1;
}
