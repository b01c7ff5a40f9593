/* tests/integration/test_metrics.c - seamtexd --metrics-listen (server/metrics_http.c,
 * server/metrics_text.c): GET /metrics in the Prometheus text format, what it says, and what
 * it refuses.
 *
 * Owns: these behaviours: promtool (Debian's prometheus package) finds zero problems in a
 * scrape, and every STATS key has a typed family (no untyped fallback); scrapes taken while
 * clients sample show counters that never go back, and a scrape
 * after the load agrees with STATS key by key (one set of counters); every HTTP request other
 * than GET / HEAD /metrics gets its 4xx; hostile clients (a 10 MB header, a byte-a-moment
 * sender, binary garbage, a flood of connections) get a 4xx or a closed connection while the
 * data port keeps answering PING and SAMPLE and /metrics keeps answering scrapes; at the fd
 * limit a waiting scrape does not spin the metrics thread, and is answered once descriptors
 * are free. Each test
 * starts its own daemon on 127.0.0.1 port 0 with --metrics-listen 127.0.0.1:0 (the port is
 * read from STATS metrics_port). A missing /usr/bin/promtool fails the test.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <poll.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/daemon_fixture.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex.h"

#define PROMTOOL "/usr/bin/promtool"

extern char **environ;

static const char *const METRICS_ARGS[] = {"--metrics-listen", "127.0.0.1:0", NULL};

static int metrics_port(const st_daemon *d)
{
    uint64_t p = st_daemon_stat(d, "metrics_port");
    assert_true(p > 0 && p < 65536);
    return (int)p;
}

static int connect_port(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    assert_true(fd >= 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(connect(fd, (struct sockaddr *)&a, sizeof a), 0);
    return fd;
}

static int send_all(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n) {
        ssize_t w = send(fd, c, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        c += w;
        n -= (size_t)w;
    }
    return 0;
}

/* Reads until the server closes (or resets) the connection, at most 30 s; malloc'ed,
 * NUL-terminated; *len its length. */
static char *read_to_close(int fd, size_t *len)
{
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    assert_non_null(buf);
    int64_t end = st_now_ms() + 30000;
    for (;;) {
        int64_t left = end - st_now_ms();
        assert_true(left > 0);   /* the server must close within its deadline, far below this */
        if (!st_wait_readable(fd, (int)left))
            continue;
        if (n == cap) {
            cap *= 2;
            buf = realloc(buf, cap + 1);
            assert_non_null(buf);
        }
        ssize_t r = recv(fd, buf + n, cap - n, 0);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;   /* end of stream or a reset: both are a close */
        n += (size_t)r;
    }
    buf[n] = 0;
    *len = n;
    return buf;
}

/* One whole request on a fresh connection; returns the response (malloc'ed). */
static char *http(int port, const char *req, size_t *len)
{
    int fd = connect_port(port);
    assert_int_equal(send_all(fd, req, strlen(req)), 0);
    char *resp = read_to_close(fd, len);
    close(fd);
    return resp;
}

static int status_of(const char *resp)
{
    int st = 0;
    if (sscanf(resp, "HTTP/1.1 %d ", &st) != 1)
        return 0;
    return st;
}

/* GET /metrics: the body (malloc'ed), asserting a 200 with the text format's content type
 * and a Content-Length that matches. */
static char *scrape(int port)
{
    size_t len;
    char *resp = http(port, "GET /metrics HTTP/1.1\r\nHost: test\r\nAccept: text/plain\r\n\r\n",
                      &len);
    assert_int_equal(status_of(resp), 200);
    assert_non_null(strstr(resp, "\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\n"));
    char *body = strstr(resp, "\r\n\r\n");
    assert_non_null(body);
    body += 4;
    const char *cl = strstr(resp, "Content-Length: ");
    assert_non_null(cl);
    assert_int_equal(strtoull(cl + 16, NULL, 10), strlen(body));
    char *out = strdup(body);
    free(resp);
    return out;
}

/* ---- the exposition, parsed ---------------------------------------------------------------- */

typedef struct sample {
    char   series[1024];  /* name{labels} as written */
    char   family[128];   /* the family whose TYPE line covers it */
    char   type[16];
    double value;
} sample;

typedef struct expo {
    sample *s;
    size_t  n;
} expo;

static void parse(const char *text, expo *e)
{
    size_t cap = 256;
    e->s = malloc(cap * sizeof *e->s);
    e->n = 0;
    char fam[128] = "", type[16] = "";
    const char *p = text;
    while (*p) {
        const char *nl = strchr(p, '\n');
        assert_non_null(nl);   /* every line ends with a newline */
        char line[1024];
        size_t ll = (size_t)(nl - p);
        assert_true(ll < sizeof line);
        memcpy(line, p, ll);
        line[ll] = 0;
        p = nl + 1;
        if (!strncmp(line, "# TYPE ", 7)) {
            assert_int_equal(sscanf(line + 7, "%127s %15s", fam, type), 2);
            continue;
        }
        if (line[0] == '#' || !line[0])
            continue;
        char *sp = strrchr(line, ' ');
        assert_non_null(sp);
        *sp = 0;
        if (e->n == cap) {
            cap *= 2;
            e->s = realloc(e->s, cap * sizeof *e->s);
        }
        sample *s = &e->s[e->n++];
        snprintf(s->series, sizeof s->series, "%s", line);
        snprintf(s->family, sizeof s->family, "%s", fam);
        snprintf(s->type, sizeof s->type, "%s", type);
        s->value = strtod(sp + 1, NULL);
        /* every sample belongs to the family of the last TYPE line */
        assert_int_equal(strncmp(line, fam, strlen(fam)), 0);
    }
}

static const sample *find(const expo *e, const char *series)
{
    for (size_t i = 0; i < e->n; i++)
        if (!strcmp(e->s[i].series, series))
            return &e->s[i];
    return NULL;
}

static double value(const expo *e, const char *series)
{
    const sample *s = find(e, series);
    if (!s) {
        fprintf(stderr, "/metrics has no %s\n", series);
        fail();
    }
    return s->value;
}

/* ---- promtool ------------------------------------------------------------------------------ */

/* Runs `promtool check metrics` on text; returns its exit status, its output in out. */
static int promtool_check(const st_daemon *d, const char *text, char *out, size_t cap)
{
    if (access(PROMTOOL, X_OK) != 0) {
        fprintf(stderr, "%s is missing: install Debian's prometheus package "
                "(deploy/install-deps.sh)\n", PROMTOOL);
        fail();
    }
    char in_path[400], out_path[400];
    snprintf(in_path, sizeof in_path, "%s/metrics.txt", d->dir);
    snprintf(out_path, sizeof out_path, "%s/promtool.out", d->dir);
    FILE *f = fopen(in_path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, in_path, O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    char *argv[] = {"promtool", "check", "metrics", NULL};
    pid_t pid;
    assert_int_equal(posix_spawn(&pid, PROMTOOL, &fa, NULL, argv, environ), 0);
    posix_spawn_file_actions_destroy(&fa);
    int st;
    assert_int_equal(waitpid(pid, &st, 0), pid);
    f = fopen(out_path, "r");
    assert_non_null(f);
    size_t n = fread(out, 1, cap - 1, f);
    out[n] = 0;
    fclose(f);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

/* ---- traffic --------------------------------------------------------------------------------- */

static void sample_batch(stc_conn *c, unsigned mode, unsigned filter, size_t n)
{
    stc_query q[256];
    assert_true(n <= 256);
    for (size_t i = 0; i < n; i++)
        q[i] = (stc_query){(uint32_t)(i % 24), 0.1f + 0.003f * (float)i, 0.5f, 0.01f, 0, 0, 0.01f};
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = mode;
    o.filter = filter;
    stc_sample_result r;
    assert_int_equal(stc_sample(c, "default", &o, q, n, &r), 0);
    assert_int_equal(r.count, n);
}

/* promtool finds nothing to say about a scrape after varied traffic (errors included). */
static void promtool_finds_zero_problems(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, METRICS_ARGS), 0);
    int port = metrics_port(&d);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    sample_batch(c, 1, 1, 100);   /* traverse bilinear */
    sample_batch(c, 0, 2, 50);    /* discard trilinear */
    stc_info info;
    assert_int_not_equal(stc_info_get(c, "no-such-set", 0, 0, &info), 0);   /* an error */
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    char *text = scrape(port);
    char out[8192];
    int rc = promtool_check(&d, text, out, sizeof out);
    if (rc != 0 || out[0])
        fprintf(stderr, "promtool check metrics: exit %d:\n%s\n", rc, out);
    assert_int_equal(rc, 0);
    assert_string_equal(out, "");   /* not even a lint warning */
    expo e;
    parse(text, &e);
    assert_true(value(&e, "seamtex_build_info{version=\"0.1\",protocol=\"1\"}") == 1);
    assert_true(value(&e, "seamtex_queries_total{mode=\"traverse\",filter=\"bilinear\"}") == 100);
    assert_true(value(&e, "seamtex_queries_total{mode=\"discard\",filter=\"trilinear\"}") == 50);
    assert_true(value(&e, "seamtex_request_errors_total{opcode=\"info\"}") == 1);
    assert_true(value(&e, "seamtex_requests_total{opcode=\"sample\"}") == 2);
    assert_true(value(&e, "seamtex_request_duration_seconds_count{opcode=\"sample\"}") == 2);
    assert_true(value(&e, "seamtex_request_duration_seconds_bucket{opcode=\"sample\",le=\"+Inf\"}")
                == 2);
    free(e.s);
    free(text);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* No family of the scrape text is an untyped fallback (seamtex_stat_<key>: a STATS key
 * without a row in metrics_text.c), and promtool check metrics finds nothing. */
static void assert_typed_and_clean(const st_daemon *d, const char *text)
{
    if (strstr(text, " untyped\n") || strstr(text, "seamtex_stat_")) {
        fprintf(stderr, "an untyped fallback family in /metrics:\n%s\n", text);
        fail();
    }
    char out[8192];
    int rc = promtool_check(d, text, out, sizeof out);
    if (rc != 0 || out[0])
        fprintf(stderr, "promtool check metrics: exit %d:\n%s\n", rc, out);
    assert_int_equal(rc, 0);
    assert_string_equal(out, "");
}

/* STATS of c, then a scrape of d's metrics at port (checked as above) parsed into *e: nothing
 * but the scrape between the two. The caller asks for the port before c's connection is
 * counted (metrics_port opens a connection of its own: its close must not fall between). */
static void stats_and_scrape(const st_daemon *d, int port, stc_conn *c, const stc_stat **st,
                             size_t *n, expo *e)
{
    assert_int_equal(stc_stats(c, st, n), 0);
    char *text = scrape(port);
    assert_typed_and_clean(d, text);
    parse(text, e);
    free(text);
}

/* Every STATS key has a typed family: none falls back to seamtex_stat_<key> (untyped), the
 * fallback meant for a key added to STATS before metrics_text.c names it. io<i>_conns,
 * io<i>_accepted, io<i>_cpu (with --pin-io yes) and shm_overlap_copies used to. The per-thread
 * families carry thread="<i>" and agree with STATS; promtool stays silent. */
static void every_stats_key_has_a_typed_family(void **state)
{
    (void)state;
    static const char *const args[] = {"--metrics-listen", "127.0.0.1:0", "--io-threads", "2",
                                       "--pin-io", "yes", NULL};
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, args), 0);
    int port = metrics_port(&d);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_int_equal(st_wait_stat(&d, c, "conns_current", ST_STAT_EQ, 1, 60000), 0);
    const stc_stat *st;
    size_t n;
    expo e;
    stats_and_scrape(&d, port, c, &st, &n, &e);
    /* nothing but the scrape between STATS and it: the per-thread keys are the same */
    uint64_t conns = 0;
    for (unsigned i = 0; i < 2; i++) {
        static const char *const suf[3] = {"conns", "accepted", "cpu"};
        static const char *const fam[3] = {"seamtex_io_thread_connections",
                                           "seamtex_io_thread_accepted_total",
                                           "seamtex_io_thread_cpu"};
        for (int k = 0; k < 3; k++) {
            char key[32], series[96];
            snprintf(key, sizeof key, "io%u_%s", i, suf[k]);
            snprintf(series, sizeof series, "%s{thread=\"%u\"}", fam[k], i);
            const stc_stat *x = stc_stat_find(st, n, key);
            assert_non_null(x);
            assert_true(value(&e, series) == (double)x->u);
            const sample *sm = find(&e, series);
            assert_string_equal(sm->type, k == 1 ? "counter" : "gauge");
            if (k == 0)
                conns += x->u;
        }
    }
    assert_true((double)conns == value(&e, "seamtex_connections"));
    assert_true(value(&e, "seamtex_shm_overlap_copies_total") ==
                (double)stc_stat_find(st, n, "shm_overlap_copies")->u);
    assert_string_equal(find(&e, "seamtex_shm_overlap_copies_total")->type, "counter");
    free(e.s);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* A cluster node (etcd on loopback): its cluster_* STATS keys come out as typed families too
 * (they were untyped seamtex_stat_cluster_* fallbacks), promtool finds nothing, and each agrees
 * with STATS. */
static void a_cluster_nodes_keys_have_typed_families(void **state)
{
    (void)state;
    st_etcd etcd;
    assert_int_equal(st_etcd_start(&etcd, "/metrics"), 0);
    const char *args[] = {"--cluster", etcd.url, "--node-id", "m0", "--advertise", "127.0.0.1:0",
                          "--metrics-listen", "127.0.0.1:0", NULL};
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, args), 0);
    assert_int_equal(st_wait_stat(&d, NULL, "cluster_repair_passes", ST_STAT_GE, 1, 60000), 0);
    int port = metrics_port(&d);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    const stc_stat *st;
    size_t n;
    expo e;
    stats_and_scrape(&d, port, c, &st, &n, &e);
    assert_true(value(&e, "seamtex_cluster_members") == 1.0);
    assert_string_equal(find(&e, "seamtex_cluster_members")->type, "gauge");
    assert_true(value(&e, "seamtex_cluster_etcd_up") == 1.0);
    assert_true(value(&e, "seamtex_cluster_lease_grants_total") ==
                (double)stc_stat_find(st, n, "cluster_lease_grants")->u);
    assert_string_equal(find(&e, "seamtex_cluster_reads_unconfirmed_total")->type, "counter");
    free(e.s);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
    st_daemon_cleanup(&d);
    st_etcd_stop(&etcd);
}

/* ---- under load ---------------------------------------------------------------------------- */

typedef struct loader {
    const st_daemon *d;
    int              stop;      /* atomic */
    unsigned         mode;
    uint64_t         batches;
    int              failed;
} loader;

static void *load_main(void *arg)
{
    loader *l = arg;
    stc_conn *c = st_daemon_client(l->d, NULL);
    if (!c) {
        l->failed = 1;
        return NULL;
    }
    stc_query q[256];
    for (size_t i = 0; i < 256; i++)
        q[i] = (stc_query){(uint32_t)(i % 24), 0.25f, 0.003f * (float)i, 0.02f, 0, 0, 0.02f};
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = l->mode;
    o.filter = 1;
    while (!__atomic_load_n(&l->stop, __ATOMIC_RELAXED)) {
        stc_sample_result r;
        if (stc_sample(c, "default", &o, q, 256, &r) != 0 || stc_ping(c) != 0) {
            l->failed = 1;
            break;
        }
        l->batches++;
    }
    stc_close(c);
    return NULL;
}

static int counter_like(const sample *s)
{
    return !strcmp(s->type, "counter") || !strcmp(s->type, "histogram");
}

/* Scrapes while two clients sample: no counter ever goes back, the query counters grow; after
 * the load, a scrape agrees with STATS taken just before it on every shared counter. */
static void scrapes_under_load_are_monotonic_and_match_stats(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, METRICS_ARGS), 0);
    int port = metrics_port(&d);
    loader l[2] = {{&d, 0, 0, 0, 0}, {&d, 0, 1, 0, 0}};
    pthread_t th[2];
    for (int i = 0; i < 2; i++)
        assert_int_equal(pthread_create(&th[i], NULL, load_main, &l[i]), 0);
    /* the load is running once the daemon has answered some queries */
    assert_int_equal(st_wait_stat(&d, NULL, "queries", ST_STAT_GE, 2560, 60000), 0);
    expo prev = {0}, cur;
    int grew = 0;
    for (int k = 0; k < 8; k++) {
        char *text = scrape(port);
        parse(text, &cur);
        free(text);
        if (prev.s) {
            for (size_t i = 0; i < cur.n; i++) {
                if (!counter_like(&cur.s[i]))
                    continue;
                const sample *p = find(&prev, cur.s[i].series);
                assert_non_null(p);   /* the same series in every scrape */
                if (cur.s[i].value < p->value) {
                    fprintf(stderr, "%s went back: %.17g -> %.17g\n", cur.s[i].series, p->value,
                            cur.s[i].value);
                    fail();
                }
            }
            grew += value(&cur, "seamtex_requests_total{opcode=\"sample\"}") >
                    value(&prev, "seamtex_requests_total{opcode=\"sample\"}");
            free(prev.s);
        }
        prev = cur;
        /* the next scrape once at least one more batch was answered */
        uint64_t q = st_daemon_stat(&d, "queries");
        assert_int_equal(st_wait_stat(&d, NULL, "queries", ST_STAT_GE, q + 256, 60000), 0);
    }
    assert_true(grew > 0);
    for (int i = 0; i < 2; i++) {
        __atomic_store_n(&l[i].stop, 1, __ATOMIC_RELAXED);
        pthread_join(th[i], NULL);
        assert_false(l[i].failed);
    }
    free(prev.s);

    /* STATS, then a scrape: nothing but the scrape itself happens in between. The load
     * threads' connections close asynchronously in the daemon: first wait until this client's
     * is the only one left. */
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_int_equal(st_wait_stat(&d, c, "conns_current", ST_STAT_EQ, 1, 60000), 0);
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    char *text = scrape(port);
    expo e;
    parse(text, &e);
    free(text);
#define SAME(key, series) do { \
        const stc_stat *s_ = stc_stat_find(st, n, key); \
        assert_non_null(s_); \
        if ((double)s_->u != value(&e, series)) { \
            fprintf(stderr, "STATS %s = %llu, /metrics %s = %.17g\n", key, \
                    (unsigned long long)s_->u, series, value(&e, series)); \
            fail(); \
        } } while (0)
    SAME("conns_accepted", "seamtex_connections_accepted_total");
    SAME("conns_current", "seamtex_connections");
    SAME("requests", "seamtex_requests_dispatched_total");
    SAME("bytes_in", "seamtex_network_receive_bytes_total");
    SAME("inline_tasks", "seamtex_tasks_total{where=\"inline\"}");
    SAME("worker_tasks", "seamtex_tasks_total{where=\"worker\"}");
    SAME("query_errors", "seamtex_query_errors_total");
    SAME("sets", "seamtex_sets");
    SAME("set_memory", "seamtex_set_memory_bytes");
    SAME("stored_bytes", "seamtex_stored_bytes");
    SAME("resident_bytes", "seamtex_resident_bytes");
    SAME("uploads_committed", "seamtex_uploads_committed_total");
    SAME("jobs_started", "seamtex_jobs_started_total");
    SAME("conns_evicted", "seamtex_connections_evicted_total");
    SAME("queries_discard_bilinear", "seamtex_queries_total{mode=\"discard\",filter=\"bilinear\"}");
    SAME("queries_traverse_bilinear", "seamtex_queries_total{mode=\"traverse\",filter=\"bilinear\"}");
    SAME("metrics_scrapes", "seamtex_metrics_scrapes_total");
    /* the sum of the query family is STATS queries */
    double qsum = 0;
    for (size_t i = 0; i < e.n; i++)
        if (!strncmp(e.s[i].series, "seamtex_queries_total{", 22))
            qsum += e.s[i].value;
    assert_true(qsum == (double)stc_stat_find(st, n, "queries")->u);
    /* per opcode: requests, errors, histogram count, sum and buckets against op_<op>_* (not
     * STATS: the STATS request being answered is not in its own op_stats_* keys yet, but it
     * is in the scrape after it) */
    static const char *const ops[] = {"hello", "ping", "sample"};
    for (size_t k = 0; k < 3; k++) {
        char key[96], series[160];
        snprintf(key, sizeof key, "op_%s_requests", ops[k]);
        snprintf(series, sizeof series, "seamtex_requests_total{opcode=\"%s\"}", ops[k]);
        SAME(key, series);
        snprintf(series, sizeof series, "seamtex_request_duration_seconds_count{opcode=\"%s\"}",
                 ops[k]);
        SAME(key, series);
        snprintf(key, sizeof key, "op_%s_errors", ops[k]);
        snprintf(series, sizeof series, "seamtex_request_errors_total{opcode=\"%s\"}", ops[k]);
        SAME(key, series);
        snprintf(key, sizeof key, "op_%s_requests", ops[k]);
        if (stc_stat_find(st, n, key)->u == 0)
            continue;
        snprintf(key, sizeof key, "op_%s_sum_us", ops[k]);
        const stc_stat *sum = stc_stat_find(st, n, key);
        assert_non_null(sum);
        snprintf(series, sizeof series, "seamtex_request_duration_seconds_sum{opcode=\"%s\"}",
                 ops[k]);
        assert_true(value(&e, series) * 1e6 > (double)sum->u - 0.5 &&
                    value(&e, series) * 1e6 < (double)sum->u + 0.5);
        /* each STATS bucket op_<op>_lat_<lo>_<hi>us is the difference of two cumulative ones */
        char prefix[64];
        snprintf(prefix, sizeof prefix, "op_%s_lat_", ops[k]);
        for (size_t i = 0; i < n; i++) {
            unsigned long long lo, hi;
            if (strncmp(st[i].key, prefix, strlen(prefix)) ||
                sscanf(st[i].key + strlen(prefix), "%llu_%lluus", &lo, &hi) != 2)
                continue;
            char le_hi[64], le_lo[64];
            snprintf(le_hi, sizeof le_hi, "%llu.%06llu", hi / 1000000, hi % 1000000);
            snprintf(le_lo, sizeof le_lo, "%llu.%06llu", lo / 1000000, lo % 1000000);
            snprintf(series, sizeof series,
                     "seamtex_request_duration_seconds_bucket{opcode=\"%s\",le=\"%s\"}", ops[k],
                     le_hi);
            double upper = value(&e, series), lower = 0;
            if (lo) {
                snprintf(series, sizeof series,
                         "seamtex_request_duration_seconds_bucket{opcode=\"%s\",le=\"%s\"}",
                         ops[k], le_lo);
                lower = value(&e, series);
            }
            assert_true(upper - lower == (double)st[i].u);
        }
    }
#undef SAME
    free(e.s);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* ---- what is refused --------------------------------------------------------------------- */

static void expect_status(int port, const char *req, int want)
{
    size_t len;
    char *resp = http(port, req, &len);
    if (status_of(resp) != want)
        fprintf(stderr, "request %.60s...: wanted %d, got:\n%.300s\n", req, want, resp);
    assert_int_equal(status_of(resp), want);
    assert_non_null(strstr(resp, "\r\nConnection: close\r\n"));
    if (want == 405)
        assert_non_null(strstr(resp, "\r\nAllow: GET, HEAD\r\n"));
    free(resp);
}

/* A whole GET /metrics sent in pieces cut between each CR and its LF, with a pause after each
 * piece so that the endpoint reads them apart: still a 200 (the reader once answered 400 to
 * a CR that was the last byte read so far). */
static void crlf_split_by_reads_is_served(int port)
{
    static const char *const parts[] = {"GET /metrics HTTP/1.1\r", "\nHost: a\r", "\n\r",
                                        "\n"};
    int fd = connect_port(port);
    assert_true(fd >= 0);
    for (size_t i = 0; i < sizeof parts / sizeof parts[0]; i++) {
        assert_int_equal(send_all(fd, parts[i], strlen(parts[i])), 0);
        poll(NULL, 0, 150);
    }
    size_t len;
    char *resp = read_to_close(fd, &len);
    close(fd);
    assert_non_null(resp);
    if (status_of(resp) != 200)
        fprintf(stderr, "CRLF split by reads: got:\n%.300s\n", resp);
    assert_int_equal(status_of(resp), 200);
    free(resp);
}

/* The data port still answers PING and a SAMPLE batch. */
static void data_path_serves(const st_daemon *d)
{
    stc_conn *c = st_daemon_client(d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    sample_batch(c, 1, 1, 64);
    stc_close(c);
}

static void only_get_metrics_is_served(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, METRICS_ARGS), 0);
    int port = metrics_port(&d);
    expect_status(port, "GET / HTTP/1.1\r\n\r\n", 404);
    expect_status(port, "GET /metricsx HTTP/1.0\r\n\r\n", 404);
    expect_status(port, "GET /metrics?name[]=x HTTP/1.1\n\n", 200);   /* LF only, a query */
    crlf_split_by_reads_is_served(port);
    expect_status(port, "POST /metrics HTTP/1.1\r\nContent-Length: 0\r\n\r\n", 405);
    expect_status(port, "DELETE /metrics HTTP/1.1\r\n\r\n", 405);
    expect_status(port, "GET /metrics HTTP/2.0\r\n\r\n", 400);
    expect_status(port, "GET /metrics\r\n\r\n", 400);
    expect_status(port, "GET  /metrics HTTP/1.1\r\n\r\n", 400);
    expect_status(port, "GET /metrics HTTP/1.1\r\nno colon here\r\n\r\n", 400);
    expect_status(port, "GET /metrics HTTP/1.1\r\nX: a\r\n folded\r\n\r\n", 400);
    expect_status(port, "\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 400);   /* a TLS hello */
    /* HEAD: the headers of the 200, no body */
    size_t len;
    char *resp = http(port, "HEAD /metrics HTTP/1.1\r\n\r\n", &len);
    assert_int_equal(status_of(resp), 200);
    char *end = strstr(resp, "\r\n\r\n");
    assert_non_null(end);
    assert_int_equal((size_t)(end + 4 - resp), len);
    assert_true(strtoull(strstr(resp, "Content-Length: ") + 16, NULL, 10) > 1000);
    free(resp);
    /* 8 KiB bounds: a longer request line 414, longer headers 431 */
    size_t big = 9000;
    char *req = malloc(big + 64);
    assert_non_null(req);
    memcpy(req, "GET /", 5);
    memset(req + 5, 'a', big);
    strcpy(req + 5 + big, " HTTP/1.1\r\n\r\n");
    expect_status(port, req, 414);
    strcpy(req, "GET /metrics HTTP/1.1\r\nX-Big: ");
    size_t at = strlen(req);
    memset(req + at, 'b', big);
    strcpy(req + at + big, "\r\n\r\n");
    expect_status(port, req, 431);
    free(req);
    assert_int_equal(st_daemon_stat(&d, "metrics_refused"), 12);   /* the 12 refusals above */
    data_path_serves(&d);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* ---- hostile clients ------------------------------------------------------------------------ */

typedef struct trickler {
    int port;
    int closed;        /* the server closed the connection */
    int got_200;
    int64_t sent;
} trickler;

/* Sends a request one byte at a time, a pause between bytes (the slowness is what is under
 * test), never finishing its headers, until the server closes the connection. */
static void *trickle_main(void *arg)
{
    trickler *t = arg;
    int fd = connect_port(t->port);
    const char *head = "GET /metrics HTTP/1.1\r\nX-Slow: ";
    for (int64_t i = 0; i < 600 && !t->closed; i++) {   /* 600 x 100 ms: 60 s at most */
        char c = i < (int64_t)strlen(head) ? head[i] : 'a';
        if (send(fd, &c, 1, MSG_NOSIGNAL) != 1) {
            t->closed = 1;
            break;
        }
        t->sent++;
        if (st_wait_readable(fd, 100)) {
            char buf[512];
            ssize_t r = recv(fd, buf, sizeof buf - 1, 0);
            if (r > 0) {
                buf[r] = 0;
                t->got_200 |= status_of(buf) == 200;
            }
            if (r <= 0)
                t->closed = 1;
        }
    }
    close(fd);
    return NULL;
}

static void hostile_clients_do_not_harm_the_daemon(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, METRICS_ARGS), 0);
    int port = metrics_port(&d);

    /* a slow sender: closed at the deadline, while others are served meanwhile */
    trickler t = {port, 0, 0, 0};
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, trickle_main, &t), 0);
    free(scrape(port));
    data_path_serves(&d);
    pthread_join(th, NULL);
    assert_true(t.closed);
    assert_false(t.got_200);

    /* a 10 MB header: a 431 or a closed connection (the send fails once the server closes) */
    int fd = connect_port(port);
    struct timeval tv = {10, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    size_t total = 10u << 20, chunk = 64u << 10, sent = 0;
    char *junk = malloc(chunk);
    assert_non_null(junk);
    memset(junk, 'h', chunk);
    const char *head = "GET /metrics HTTP/1.1\r\nX-Huge: ";
    int ok = send_all(fd, head, strlen(head)) == 0;
    while (ok && sent < total) {
        ok = send_all(fd, junk, chunk) == 0;
        sent += ok ? chunk : 0;
    }
    free(junk);
    size_t len;
    char *resp = read_to_close(fd, &len);
    assert_true(len == 0 || status_of(resp) == 431);
    free(resp);
    close(fd);

    /* binary garbage */
    char garbage[4096];
    for (size_t i = 0; i < sizeof garbage; i++)
        garbage[i] = (char)((i * 2654435761u) >> 13);
    garbage[0] = 0;
    fd = connect_port(port);
    send_all(fd, garbage, sizeof garbage);
    resp = read_to_close(fd, &len);
    assert_true(len == 0 || status_of(resp) == 400);
    free(resp);
    close(fd);

    /* a flood of half-sent requests: the newest connection evicts the oldest, so a scrape
     * still gets through, and the data port is untouched */
    enum { FLOOD = 200 };
    int fds[FLOOD];
    for (int i = 0; i < FLOOD; i++) {
        fds[i] = connect_port(port);
        send_all(fds[i], "GET /metr", 9);
    }
    free(scrape(port));
    data_path_serves(&d);
    for (int i = 0; i < FLOOD; i++)
        close(fds[i]);

    /* still alive, still serving, and it says what it refused */
    free(scrape(port));
    data_path_serves(&d);
    assert_true(st_daemon_stat(&d, "metrics_refused") >= 3 + FLOOD - 16);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* The daemon at its fd limit while a scraper connects (dur28): accept4 fails with EMFILE and
 * the listener stays readable. Before, the metrics thread polled it again at once, logging
 * "metrics: accept: Too many open files" about a million times a second for as long as the
 * scraper waited. Now the listener sits out a second at a time with one warning per 10 s, the
 * data path serves on, and once descriptors are free the waiting scrape is answered. */
static void fd_shortage_does_not_spin_the_metrics_thread(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, METRICS_ARGS), 0);
    int port = metrics_port(&d);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    /* the limit just above the highest descriptor, then data connections until the holes
     * below it are taken (the first BUSY answer says so): not one descriptor is left */
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/fd", (int)d.pid);
    int maxfd = -1;
    DIR *dir = opendir(path);
    assert_non_null(dir);
    for (struct dirent *de; (de = readdir(dir));)
        if (de->d_name[0] != '.' && atoi(de->d_name) > maxfd)
            maxfd = atoi(de->d_name);
    closedir(dir);
    struct rlimit old, rl;
    assert_int_equal(prlimit(d.pid, RLIMIT_NOFILE, NULL, &old), 0);
    rl = old;
    rl.rlim_cur = (rlim_t)maxfd + 1;
    assert_int_equal(prlimit(d.pid, RLIMIT_NOFILE, &rl, NULL), 0);
    enum { FILL = 900 };
    static int fill[FILL];
    int nfill = 0, busy = 0;
    for (int i = 0; i < FILL && !busy; i++, nfill++) {
        fill[i] = st_daemon_connect(&d);
        assert_true(fill[i] >= 0);
        uint8_t frame[24] = {'S', 'T', 'X', '1', 1, 0x02, 0, 0, 1};   /* PING, reqid 1 */
        assert_int_equal(send_all(fill[i], frame, sizeof frame), 0);
        uint8_t reply[24];
        size_t got = 0;
        while (got < sizeof reply && st_wait_readable(fill[i], 10000)) {
            ssize_t r = recv(fill[i], reply + got, sizeof reply - got, 0);
            if (r <= 0)
                break;
            got += (size_t)r;
        }
        assert_int_equal(got, sizeof reply);   /* served, or BUSY when none was left */
        busy += reply[12] == 9;
    }
    printf("# highest fd %d, fd limit %d: data connection %d answered BUSY\n", maxfd,
           maxfd + 1, nfill);
    assert_true(busy > 0);
    int fd = connect_port(port);               /* completes in the kernel's backlog */
    const char *req = "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n";
    assert_int_equal(send_all(fd, req, strlen(req)), 0);
    assert_int_equal(st_wait_file_has(d.log, "metrics: accept:", 10000), 0);
    for (int i = 0; i < 50; i++)               /* the data path is served meanwhile */
        assert_int_equal(stc_ping(c), 0);
    int lines = st_daemon_log_count(&d, "metrics: accept:");
    printf("# 'metrics: accept:' warnings while the scrape waits: %d\n", lines);
    assert_true(lines >= 1 && lines <= 2);
    assert_int_equal(prlimit(d.pid, RLIMIT_NOFILE, &old, NULL), 0);
    size_t len;
    char *resp = read_to_close(fd, &len);      /* answered after the pause */
    assert_int_equal(status_of(resp), 200);
    free(resp);
    close(fd);
    for (int i = 0; i < nfill; i++)
        close(fill[i]);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}

/* --metrics-listen with a bare port means loopback; a bad address stops the start. */
static void bad_metrics_address_is_refused(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    static const char *const bad[] = {"--metrics-listen", "127.0.0.1:99999", NULL};
    assert_int_not_equal(st_daemon_start(&d, bad), 0);
    st_daemon_cleanup(&d);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(promtool_finds_zero_problems),
        cmocka_unit_test(every_stats_key_has_a_typed_family),
        cmocka_unit_test(a_cluster_nodes_keys_have_typed_families),
        cmocka_unit_test(scrapes_under_load_are_monotonic_and_match_stats),
        cmocka_unit_test(only_get_metrics_is_served),
        cmocka_unit_test(hostile_clients_do_not_harm_the_daemon),
        cmocka_unit_test(bad_metrics_address_is_refused),
        cmocka_unit_test(fd_shortage_does_not_spin_the_metrics_thread),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
