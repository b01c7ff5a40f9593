/* client/bench_main.c - seamtex-bench, the load tester: arguments, connections, threads,
 * the report and its JSON.
 *
 * Owns: the command line, splitting connections and the rate across threads, merging the
 * threads' histograms, printing percentiles, writing JSON. Does not own: the event loop
 * (bench_loop.c), frames (bench_wire.c), the in-process baseline (bench_inproc.c).
 *
 * What the counts mean: over the network, -c is the number of connections, -T the number of
 * threads they are shared by (at most one per connection), -P the requests outstanding per
 * connection; with --inproc there are no connections and -T is the number of sampling threads.
 *
 * Always bounded: it stops after --duration seconds (plus warm-up and at most 2 s of drain)
 * or --requests requests, whichever comes first, and only talks to loopback addresses.
 */
#include "bench.h"

#include <errno.h>
#include <getopt.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include "proto.h"
#include "unixaddr.h"

static const double PCTS[] = { 50, 90, 99, 99.9, 99.99 };
#define NPCTS (sizeof PCTS / sizeof PCTS[0])

static void usage(FILE *f)
{
    fprintf(f,
"usage: seamtex-bench [options]\n"
"Load tester for seamtexd (loopback only). Closed loop by default (capacity); --rate gives\n"
"an open loop (latency at a fixed rate, measured from each request's intended send time).\n"
"\n"
"  -h, --host HOST        server address, loopback only (127.0.0.1), or unix:/path (a\n"
"                         daemon's Unix socket; -p unused)\n"
"  -p, --port PORT        server port (7450)\n"
"  -t, --token TOKEN      access token, if the server wants one\n"
"  -o, --op OP            ping | sample | sample-dir (cube maps: -s a cube set) (ping)\n"
"      --proto P          seamtex | memcached | redis (seamtex): load another server with its\n"
"                         cheapest no-op, the same way as a seamtexd PING, for comparison:\n"
"                         memcached \"version\", Redis PING; -o ping only\n"
"  -c, --conns N          connections in all (1)\n"
"  -T, --threads N        client threads; over the network they share the connections, each\n"
"                         thread driving conns/threads of them in its own epoll loop, so N is\n"
"                         at most -c (more is cut to -c, with a note); --inproc: the\n"
"                         number of sampling threads, each calling st_sample_batch (1)\n"
"  -P, --pipeline N       closed loop: requests outstanding on each connection (1), so\n"
"                         c x P in flight in all; open loop: cap on outstanding per\n"
"                         connection (1024)\n"
"  -r, --rate R           open loop at R requests/s over all connections\n"
"      --arrival KIND     uniform | poisson (uniform)\n"
"  -d, --duration S       measured seconds (5)\n"
"  -w, --warmup S         seconds before the measurement, not recorded (1)\n"
"  -n, --requests N       stop after N requests in all (0 = no cap)\n"
"      --timeout S        a reply later than S seconds counts as a timeout (5)\n"
"      --spin-us N        open loop: poll rather than sleep within N us of a due send, as a\n"
"                         timed sleep wakes ~60 us late here (100; 0 = always sleep)\n"
"      --seed N           seed of the arrivals and queries (1)\n"
"  -s, --set NAME         set to sample (default)\n"
"      --cluster SEEDS    HOST:PORT,... or etcd://HOST:PORT/PREFIX of a seamtex cluster:\n"
"                         -o sample through libseamtex's stc_cluster, -P requests pipelined\n"
"                         per handle (routed to each set's owner, several nodes at once),\n"
"                         one handle and thread per connection (-c); -s a,b,c cycles sets\n"
"      --blocking         with --cluster: one stc_cluster_sample at a time (no pipelining)\n"
"      --lib              -o sample through libseamtex on a direct connection to -h/-p with\n"
"                         the same loop as --cluster (the baseline of its routing overhead)\n"
"  -b, --batch N          queries per SAMPLE request (4096)\n"
"  -m, --mode LIST        comma list of discard,traverse,clamp picked at random (traverse)\n"
"  -f, --filter LIST      comma list of filters picked at random (bilinear)\n"
"      --footprint F      |du/dx| = |dv/dy| of every query (0.001); sample-dir: cone angle\n"
"      --compact          SAMPLE with compact queries (PROTOCOL.md 4.4.1): u, v as u16,\n"
"                         derivatives as f16, faces as u16 when the set has <= 65536\n"
"      --outfmt FMT       reply values: f32 | f16 | unorm8 | unorm16 (f32)\n"
"      --shm              SAMPLE on a unix: address through a shared-memory region per\n"
"                         connection (PROTOCOL.md 4.12): the pool's queries are written\n"
"                         into it once, each request names them and a reply room of its\n"
"                         own, the daemon samples in place, frames stay small\n"
"      --shm-copy         --shm, and each request's queries are copied into a room of its\n"
"                         own first (a client that builds its queries elsewhere)\n"
"      --lowat K          closed-loop SAMPLE: a connection's thread is woken when K whole\n"
"                         replies are in its socket (SO_RCVLOWAT; TCP honours it), not at\n"
"                         each reply's first bytes: fewer wake-ups of the client and fewer\n"
"                         preemptions of the daemon (default: -P / 2, at least 1; 0 = off)\n"
"      --inproc           no server: st_sample_batch on the default set, same queries\n"
"      --idle N           open N connections, PING each once, hold them --hold seconds\n"
"      --hold S           (10)\n"
"  -j, --json PATH        write the results as JSON\n"
"  -q, --quiet            print only the summary line\n"
"      --help\n");
}

static int parse_double(const char *s, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !(v >= lo && v <= hi))
        return -1;
    *out = v;
    return 0;
}

static int parse_uint(const char *s, unsigned long long lo, unsigned long long hi,
                      unsigned long long *out)
{
    char *end;
    errno = 0;
    if (*s == '-')
        return -1;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return -1;
    *out = v;
    return 0;
}

/* "a,b,c" -> codes through parse(); -1 on an unknown name or too many. */
static int parse_list(const char *s, int (*parse)(const char *), uint8_t *out, unsigned *n)
{
    char buf[256];
    if (strlen(s) >= sizeof buf)
        return -1;
    strcpy(buf, s);
    *n = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        int v = parse(tok);
        if (v < 0 || *n >= BENCH_MAX_MIX)
            return -1;
        out[(*n)++] = (uint8_t)v;
    }
    return *n ? 0 : -1;
}

static double loadavg1(void)
{
    double l = -1;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &l) != 1)
            l = -1;
        fclose(f);
    }
    return l;
}

/* This process's CPU (every thread, user + system) and context switches at one instant. */
typedef struct cpu_mark {
    double   cpu_s;
    uint64_t vcsw, ivcsw;
    uint64_t t0, t1;       /* CLOCK_MONOTONIC ns: when it was read (a window: its edges) */
} cpu_mark;

static void json_hist(FILE *f, const char *name, const stc_hist *h)
{
    fprintf(f, "  \"%s_us\": {", name);
    for (size_t i = 0; i < NPCTS; i++)
        fprintf(f, "\"p%g\": %.1f, ", PCTS[i], stc_hist_percentile(h, PCTS[i]) / 1e3);
    fprintf(f, "\"max\": %.1f, \"mean\": %.1f}", h->max / 1e3, stc_hist_mean(h) / 1e3);
}

static int write_json(const bench_cfg *cfg, const bench_result *r, double secs,
                      double load0, double load1, double inproc_qps, const cpu_mark *win,
                      double cpu_total_s)
{
    FILE *f = fopen(cfg->json_path, "w");
    if (!f) {
        fprintf(stderr, "seamtex-bench: %s: %s\n", cfg->json_path, strerror(errno));
        return -1;
    }
    fprintf(f, "{\n  \"tool\": \"seamtex-bench\",\n  \"proto\": \"%s\",\n",
            bench_proto_name(cfg->proto));
    fprintf(f, "  \"op\": \"%s\",\n  \"loop\": \"%s\",\n", bench_op_name(cfg->op),
            cfg->open_loop ? "open" : "closed");
    if (cfg->open_loop)
        fprintf(f, "  \"arrival\": \"%s\",\n  \"target_rate\": %.1f,\n",
                cfg->arrival == STC_ARRIVAL_POISSON ? "poisson" : "uniform", cfg->rate);
    fprintf(f, "  \"conns\": %u,\n  \"threads\": %u,\n  \"pipeline\": %u,\n", cfg->conns,
            cfg->threads, cfg->pipeline);
    if (bench_op_samples(cfg->op)) {
        fprintf(f, "  \"set\": \"%s\",\n  \"batch\": %u,\n  \"modes\": [", cfg->set, cfg->batch);
        for (unsigned i = 0; i < cfg->nmodes; i++)
            fprintf(f, "%s\"%s\"", i ? ", " : "", stp_mode_name(cfg->modes[i]));
        fprintf(f, "],\n  \"filters\": [");
        for (unsigned i = 0; i < cfg->nfilters; i++)
            fprintf(f, "%s\"%s\"", i ? ", " : "", stp_filter_name(cfg->filters[i]));
        fprintf(f, "],\n  \"queries\": \"%s\",\n  \"outfmt\": \"%s\",\n  \"shm\": %s,\n"
                "  \"shm_copy\": %s,\n", cfg->compact ? "compact" : "f32",
                stp_outfmt_name(cfg->outfmt), cfg->shm ? "true" : "false",
                cfg->shm_copy ? "true" : "false");
        fprintf(f, "  \"queries_per_s\": %.1f,\n", secs > 0 ? r->queries / secs : 0.0);
        if (inproc_qps > 0)
            fprintf(f, "  \"inproc_queries_per_s\": %.1f,\n", inproc_qps);
    }
    fprintf(f, "  \"duration_s\": %.3f,\n  \"warmup_s\": %.3f,\n  \"seed\": %llu,\n", secs,
            cfg->warmup_s, (unsigned long long)cfg->seed);
    fprintf(f, "  \"achieved_rate\": %.1f,\n", secs > 0 ? r->measured / secs : 0.0);
    fprintf(f, "  \"sent\": %llu,\n  \"completed\": %llu,\n  \"measured\": %llu,\n",
            (unsigned long long)r->sent, (unsigned long long)r->completed,
            (unsigned long long)r->measured);
    fprintf(f, "  \"errors\": %llu,\n  \"timeouts\": %llu,\n  \"conn_errors\": %llu,\n"
               "  \"late_sends\": %llu,\n  \"unsent\": %llu,\n",
            (unsigned long long)r->errors, (unsigned long long)r->timeouts,
            (unsigned long long)r->conn_errors, (unsigned long long)r->late_sends,
            (unsigned long long)r->unsent);
    fprintf(f, "  \"bytes_out\": %llu,\n  \"bytes_in\": %llu,\n",
            (unsigned long long)r->bytes_out, (unsigned long long)r->bytes_in);
    /* the load tester's own cost: its CPU over the measured window (from the warm-up's end to
     * t_end, or to the last thread's end under -n) against the requests and queries recorded
     * in it, so start-up, connecting, the pools and --shm's region are not in it; and over
     * the whole process for comparison with figures taken from outside */
    fprintf(f, "  \"cpu_s\": %.4f,\n  \"cpu_window_s\": %.4f,\n"
               "  \"vcsw_window\": %llu,\n  \"ivcsw_window\": %llu,\n"
               "  \"window_start_ns\": %llu,\n  \"window_end_ns\": %llu,\n",
            cpu_total_s, win->cpu_s, (unsigned long long)win->vcsw,
            (unsigned long long)win->ivcsw, (unsigned long long)win->t0,
            (unsigned long long)win->t1);
    if (bench_op_samples(cfg->op))
        fprintf(f, "  \"queries_measured\": %llu,\n", (unsigned long long)r->queries);
    if (cfg->cluster || cfg->lib)
        fprintf(f, "  \"client\": \"%s\",\n  \"failovers\": %llu,\n  \"moved\": %llu,\n",
                cfg->lib ? "lib" : cfg->blocking ? "cluster-blocking" : "cluster-pipelined",
                (unsigned long long)r->failovers, (unsigned long long)r->moved);
    json_hist(f, "corrected", &r->corrected);
    fprintf(f, ",\n");
    json_hist(f, "service", &r->service);
    fprintf(f, ",\n  \"loadavg_before\": %.2f,\n  \"loadavg_after\": %.2f\n}\n", load0, load1);
    int bad = ferror(f);
    if (fclose(f) != 0 || bad) {
        fprintf(stderr, "seamtex-bench: writing %s failed\n", cfg->json_path);
        return -1;
    }
    return 0;
}

static void print_hist(const char *name, const stc_hist *h)
{
    printf("  %-9s", name);
    for (size_t i = 0; i < NPCTS; i++)
        printf(" p%-5g %8.1f", PCTS[i], stc_hist_percentile(h, PCTS[i]) / 1e3);
    printf("  max %8.1f us\n", h->max / 1e3);
}

/* The threads that have returned, so that main's waits for the measured window's edges end
 * early when a request cap (-n) ends the run first. Owned by main; each thread holds a
 * pointer to it in its thread_arg. */
typedef struct done_gate {
    pthread_mutex_t mu;
    pthread_cond_t  cv; /* on CLOCK_MONOTONIC */
    unsigned        n;
} done_gate;

typedef struct thread_arg {
    bench_thread *th;
    done_gate    *gate;
} thread_arg;

static void *thread_main(void *arg)
{
    thread_arg *a = arg;
    bench_thread *th = a->th;
    if (th->cfg->cluster || th->cfg->lib)
        bench_lib_run(th);
    else
        bench_loop_run(th);
    pthread_mutex_lock(&a->gate->mu);
    a->gate->n++;
    pthread_cond_signal(&a->gate->cv);
    pthread_mutex_unlock(&a->gate->mu);
    return NULL;
}

static cpu_mark cpu_now(void)
{
    struct rusage ru;
    cpu_mark m = { 0, 0, 0, bench_now_ns(), 0 };
    if (getrusage(RUSAGE_SELF, &ru) == 0) {
        m.cpu_s = (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec / 1e6 +
                  (double)ru.ru_stime.tv_sec + ru.ru_stime.tv_usec / 1e6;
        m.vcsw = (uint64_t)ru.ru_nvcsw;
        m.ivcsw = (uint64_t)ru.ru_nivcsw;
    }
    return m;
}

/* Sleeps until `deadline` (CLOCK_MONOTONIC ns) or until n threads have returned. */
static void wait_edge(done_gate *g, uint64_t deadline, unsigned n)
{
    struct timespec ts = { (time_t)(deadline / 1000000000ull), (long)(deadline % 1000000000ull) };
    pthread_mutex_lock(&g->mu);
    while (g->n < n && bench_now_ns() < deadline)
        if (pthread_cond_timedwait(&g->cv, &g->mu, &ts) == ETIMEDOUT)
            break;
    pthread_mutex_unlock(&g->mu);
}

static void close_all(int *fds, unsigned n)
{
    for (unsigned i = 0; i < n; i++)
        if (fds[i] >= 0)
            close(fds[i]);
}

/* --idle: many connections that do nothing, to measure what they cost the server. */
static int run_idle(const bench_cfg *cfg)
{
    int *fds = malloc(cfg->idle * sizeof *fds);
    if (!fds)
        return 1;
    char msg[256];
    unsigned n = 0;
    for (; n < cfg->idle; n++) {
        fds[n] = bench_wire_connect(cfg, msg, sizeof msg);
        if (fds[n] < 0) {
            fprintf(stderr, "seamtex-bench: connection %u: %s\n", n, msg);
            break;
        }
    }
    printf("idle: %u connections open\n", n);
    fflush(stdout);
    if (n == cfg->idle) {
        struct timespec ts = { (time_t)cfg->hold_s,
                               (long)((cfg->hold_s - (double)(time_t)cfg->hold_s) * 1e9) };
        while (nanosleep(&ts, &ts) < 0 && errno == EINTR)
            ;
    }
    close_all(fds, n);
    free(fds);
    return n == cfg->idle ? 0 : 3;
}

int main(int argc, char **argv)
{
    bench_cfg cfg = {
        .host = "127.0.0.1", .port = "7450", .set = "default", .op = BENCH_OP_PING,
        .arrival = STC_ARRIVAL_UNIFORM, .duration_s = 5, .warmup_s = 1, .timeout_s = 5,
        .seed = 1, .conns = 1, .threads = 1, .pipeline = 0, .batch = 4096,
        .footprint = 0.001f, .hold_s = 10, .spin_us = 100, .lowat = -1,
    };
    int inproc = 0;
    enum { O_ARRIVAL = 256, O_TIMEOUT, O_SPIN, O_SEED, O_FOOTPRINT, O_INPROC, O_IDLE, O_HOLD, O_HELP,
           O_PROTO, O_COMPACT, O_OUTFMT, O_CLUSTER, O_BLOCKING, O_LIB, O_SHM, O_SHM_COPY,
           O_LOWAT };
    static const struct option opts[] = {
        { "host", required_argument, 0, 'h' },     { "port", required_argument, 0, 'p' },
        { "token", required_argument, 0, 't' },    { "op", required_argument, 0, 'o' },
        { "conns", required_argument, 0, 'c' },    { "threads", required_argument, 0, 'T' },
        { "pipeline", required_argument, 0, 'P' }, { "rate", required_argument, 0, 'r' },
        { "arrival", required_argument, 0, O_ARRIVAL },
        { "duration", required_argument, 0, 'd' }, { "warmup", required_argument, 0, 'w' },
        { "requests", required_argument, 0, 'n' },
        { "timeout", required_argument, 0, O_TIMEOUT },
        { "spin-us", required_argument, 0, O_SPIN },
        { "seed", required_argument, 0, O_SEED },  { "set", required_argument, 0, 's' },
        { "batch", required_argument, 0, 'b' },    { "mode", required_argument, 0, 'm' },
        { "filter", required_argument, 0, 'f' },
        { "footprint", required_argument, 0, O_FOOTPRINT },
        { "inproc", no_argument, 0, O_INPROC },    { "idle", required_argument, 0, O_IDLE },
        { "hold", required_argument, 0, O_HOLD },  { "json", required_argument, 0, 'j' },
        { "quiet", no_argument, 0, 'q' },          { "help", no_argument, 0, O_HELP },
        { "proto", required_argument, 0, O_PROTO },
        { "compact", no_argument, 0, O_COMPACT },  { "outfmt", required_argument, 0, O_OUTFMT },
        { "cluster", required_argument, 0, O_CLUSTER },
        { "blocking", no_argument, 0, O_BLOCKING }, { "lib", no_argument, 0, O_LIB },
        { "shm", no_argument, 0, O_SHM },
        { "shm-copy", no_argument, 0, O_SHM_COPY },
        { "lowat", required_argument, 0, O_LOWAT },
        { 0, 0, 0, 0 }
    };
    cfg.modes[0] = STP_MODE_TRAVERSE;
    cfg.nmodes = 1;
    cfg.filters[0] = STP_FILTER_BILINEAR;
    cfg.nfilters = 1;
    int ch;
    unsigned long long u;
    double d;
    while ((ch = getopt_long(argc, argv, "h:p:t:o:c:T:P:r:d:w:n:s:b:m:f:j:q", opts, NULL)) != -1) {
        int bad = 0;
        switch (ch) {
        case 'h': cfg.host = optarg; break;
        case O_CLUSTER: cfg.cluster = optarg; break;
        case O_BLOCKING: cfg.blocking = 1; break;
        case O_LIB: cfg.lib = 1; break;
        case 'p': cfg.port = optarg; bad = parse_uint(optarg, 1, 65535, &u); break;
        case 't': cfg.token = optarg; break;
        case 'o':
            if (!strcmp(optarg, "ping")) cfg.op = BENCH_OP_PING;
            else if (!strcmp(optarg, "sample")) cfg.op = BENCH_OP_SAMPLE;
            else if (!strcmp(optarg, "sample-dir")) cfg.op = BENCH_OP_SAMPLE_DIR;
            else bad = 1;
            break;
        case O_PROTO:
            if (!strcmp(optarg, "seamtex")) cfg.proto = BENCH_PROTO_SEAMTEX;
            else if (!strcmp(optarg, "memcached")) cfg.proto = BENCH_PROTO_MEMCACHED;
            else if (!strcmp(optarg, "redis")) cfg.proto = BENCH_PROTO_REDIS;
            else bad = 1;
            break;
        case 'c': bad = parse_uint(optarg, 1, BENCH_MAX_CONNS, &u); cfg.conns = (unsigned)u; break;
        case 'T': bad = parse_uint(optarg, 1, BENCH_MAX_THREADS, &u); cfg.threads = (unsigned)u; break;
        case 'P': bad = parse_uint(optarg, 1, BENCH_MAX_PIPELINE, &u); cfg.pipeline = (unsigned)u; break;
        case 'r': bad = parse_double(optarg, 0.001, 1e8, &cfg.rate); cfg.open_loop = 1; break;
        case O_ARRIVAL:
            if (!strcmp(optarg, "uniform")) cfg.arrival = STC_ARRIVAL_UNIFORM;
            else if (!strcmp(optarg, "poisson")) cfg.arrival = STC_ARRIVAL_POISSON;
            else bad = 1;
            break;
        case 'd': bad = parse_double(optarg, 0.01, 3600, &cfg.duration_s); break;
        case 'w': bad = parse_double(optarg, 0, 600, &cfg.warmup_s); break;
        case 'n': bad = parse_uint(optarg, 0, 1ull << 40, &u); cfg.max_requests = u; break;
        case O_TIMEOUT: bad = parse_double(optarg, 0.001, 600, &cfg.timeout_s); break;
        case O_SPIN: bad = parse_uint(optarg, 0, 100000, &u); cfg.spin_us = (unsigned)u; break;
        case O_SEED: bad = parse_uint(optarg, 0, UINT64_MAX, &u); cfg.seed = u; break;
        case 's': cfg.set = optarg; break;
        case 'b': bad = parse_uint(optarg, 1, BENCH_MAX_BATCH, &u); cfg.batch = (unsigned)u; break;
        case 'm': bad = parse_list(optarg, stp_mode_parse, cfg.modes, &cfg.nmodes); break;
        case 'f': bad = parse_list(optarg, stp_filter_parse, cfg.filters, &cfg.nfilters); break;
        case O_FOOTPRINT:
            bad = parse_double(optarg, 0, 100, &d);
            cfg.footprint = (float)d;
            break;
        case O_INPROC: inproc = 1; break;
        case O_COMPACT: cfg.compact = 1; break;
        case O_SHM: cfg.shm = 1; break;
        case O_SHM_COPY: cfg.shm = cfg.shm_copy = 1; break;
        case O_LOWAT: bad = parse_uint(optarg, 0, BENCH_MAX_PIPELINE, &u); cfg.lowat = (int)u; break;
        case O_OUTFMT: {
            int f = stp_outfmt_parse(optarg);
            bad = f < 0;
            cfg.outfmt = bad ? 0 : (uint8_t)f;
            break;
        }
        case O_IDLE: bad = parse_uint(optarg, 1, BENCH_MAX_CONNS, &u); cfg.idle = (unsigned)u; break;
        case O_HOLD: bad = parse_double(optarg, 0, 3600, &cfg.hold_s); break;
        case 'j': cfg.json_path = optarg; break;
        case 'q': cfg.quiet = 1; break;
        case O_HELP: usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
        if (bad) {   /* named as given: -c, or --proto for an option without a letter */
            char name[40] = "--";
            if (ch < 256)
                snprintf(name, sizeof name, "-%c", ch);
            for (const struct option *o = opts; ch >= 256 && o->name; o++)
                if (o->val == ch)
                    snprintf(name, sizeof name, "--%s", o->name);
            fprintf(stderr, "seamtex-bench: bad value for %s: '%s'\n", name, optarg ? optarg : "");
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "seamtex-bench: unexpected argument '%s'\n", argv[optind]);
        usage(stderr);
        return 2;
    }
    if (cfg.proto != BENCH_PROTO_SEAMTEX && (inproc || cfg.op != BENCH_OP_PING)) {
        fprintf(stderr, "seamtex-bench: --proto %s loads only its no-op: -o ping, no --inproc\n",
                bench_proto_name(cfg.proto));
        return 2;
    }
    int libmode = cfg.cluster || cfg.lib;   /* bench_cluster.c: one handle per thread */
    if (libmode && (cfg.op != BENCH_OP_SAMPLE || cfg.open_loop || inproc || cfg.idle ||
                    cfg.proto != BENCH_PROTO_SEAMTEX || (cfg.cluster && cfg.lib) ||
                    cfg.conns > BENCH_MAX_THREADS)) {
        fprintf(stderr, "seamtex-bench: --cluster / --lib load -o sample in a closed loop, one "
                "thread per connection (-c at most %d), not with --lib and --cluster both\n",
                BENCH_MAX_THREADS);
        return 2;
    }
    if (cfg.shm && (cfg.op != BENCH_OP_SAMPLE && cfg.op != BENCH_OP_SAMPLE_DIR)) {
        fprintf(stderr, "seamtex-bench: --shm samples (-o sample or sample-dir)\n");
        return 2;
    }
    if (cfg.shm && (libmode || inproc || !cfg.host || !stu_is_unix_addr(cfg.host))) {
        fprintf(stderr, "seamtex-bench: --shm needs a unix: address (-h unix:PATH), not --lib, "
                "--cluster or --inproc\n");
        return 2;
    }
    if (cfg.blocking && !cfg.cluster) {
        fprintf(stderr, "seamtex-bench: --blocking goes with --cluster\n");
        return 2;
    }
    if (libmode)
        cfg.threads = cfg.conns;
    /* over the network a thread drives whole connections; --inproc has none and keeps -T */
    if (!inproc && !cfg.idle && cfg.threads > cfg.conns) {
        fprintf(stderr, "seamtex-bench: note: -T %u cut to %u, one thread per connection at "
                "most (-c %u)\n", cfg.threads, cfg.conns, cfg.conns);
        cfg.threads = cfg.conns;
    }
    if (cfg.pipeline == 0)
        cfg.pipeline = cfg.open_loop ? 1024 : 1;
    signal(SIGPIPE, SIG_IGN);

    double load0 = loadavg1();
    if (inproc) {
        bench_inproc_result ir = { 0, 0, 0 };
        char msg[256];
        cfg.op = BENCH_OP_SAMPLE;
        if (bench_inproc_run(&cfg, &ir, msg, sizeof msg) < 0) {
            fprintf(stderr, "seamtex-bench: %s\n", msg);
            return 1;
        }
        if (cfg.json_path) {
            FILE *f = fopen(cfg.json_path, "w");
            int bad = !f;
            if (f) {
                bad = fprintf(f, "{\n  \"tool\": \"seamtex-bench\",\n  \"op\": \"inproc\",\n"
                                 "  \"batch\": %u,\n  \"threads\": %u,\n"
                                 "  \"queries_per_s\": %.1f,\n  \"queries_total\": %llu,\n"
                                 "  \"cpu_s\": %.3f,\n  \"queries_per_cpu_s\": %.1f,\n"
                                 "  \"loadavg_before\": %.2f,\n  \"loadavg_after\": %.2f\n}\n",
                              cfg.batch, cfg.threads, ir.qps,
                              (unsigned long long)ir.queries_total, ir.cpu_s,
                              ir.cpu_s > 0 ? ir.queries_total / ir.cpu_s : 0.0, load0,
                              loadavg1()) < 0;
                bad |= fclose(f) != 0;
            }
            if (bad) {
                fprintf(stderr, "seamtex-bench: cannot write %s\n", cfg.json_path);
                return 1;
            }
        }
        return 0;
    }
    if (cfg.idle) {
        struct rlimit rl;
        if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < cfg.idle + 64) {
            rl.rlim_cur = rl.rlim_max < cfg.idle + 64 ? rl.rlim_max : cfg.idle + 64;
            setrlimit(RLIMIT_NOFILE, &rl);
        }
        return run_idle(&cfg);
    }

    /* connect everything first, so the measurement does not include connection setup */
    char msg[256];
    int *fds = malloc(cfg.conns * sizeof *fds);
    uint8_t **shm = cfg.shm ? calloc(cfg.conns, sizeof *shm) : NULL;
    size_t shm_size = 0;
    bench_thread *ths = calloc(cfg.threads, sizeof *ths);
    bench_result *res = calloc(cfg.threads + 1, sizeof *res);
    pthread_t *tids = calloc(cfg.threads, sizeof *tids);
    thread_arg *targs = calloc(cfg.threads, sizeof *targs);
    done_gate gate = { .n = 0 };
    unsigned nfds = 0;
    int rc = 0;
    if (!fds || !ths || !res || !tids || !targs) {
        fprintf(stderr, "seamtex-bench: out of memory\n");
        rc = 1;
        goto done;
    }
    for (; !libmode && nfds < cfg.conns; nfds++) {
        fds[nfds] = bench_wire_connect(&cfg, msg, sizeof msg);
        if (fds[nfds] < 0) {
            fprintf(stderr, "seamtex-bench: connection %u: %s\n", nfds, msg);
            rc = 3;
            goto done;
        }
    }
    if (!libmode && bench_op_samples(cfg.op) &&
        bench_wire_set_info(&cfg, fds[0], msg, sizeof msg) < 0) {
        fprintf(stderr, "seamtex-bench: %s\n", msg);
        rc = 1;
        goto done;
    }
    for (unsigned i = 0; cfg.shm && i < nfds; i++) {
        if (!shm || bench_wire_shm_attach(&cfg, fds[i], &shm[i], &shm_size, msg,
                                          sizeof msg) < 0) {
            fprintf(stderr, "seamtex-bench: connection %u: %s\n", i, shm ? msg : "out of memory");
            rc = 1;
            goto done;
        }
    }

    uint64_t t0 = bench_now_ns() + 20000000ull;    /* 20 ms for the threads to start */
    uint64_t t_measure = t0 + (uint64_t)(cfg.warmup_s * 1e9);
    uint64_t t_end = t_measure + (uint64_t)(cfg.duration_s * 1e9);
    unsigned first = 0;
    for (unsigned t = 0; t < cfg.threads; t++) {
        bench_thread *th = &ths[t];
        th->cfg = &cfg;
        th->index = t;
        th->conn_first = first;
        th->conn_count = cfg.conns / cfg.threads + (t < cfg.conns % cfg.threads);
        first += th->conn_count;
        th->fds = fds + th->conn_first;
        th->shm = shm ? shm + th->conn_first : NULL;
        th->shm_slot = cfg.shm ? bench_wire_shm_slot(&cfg) : 0;
        if (cfg.max_requests)
            th->max_requests = cfg.max_requests / cfg.threads +
                               (t < cfg.max_requests % cfg.threads);
        th->t_start = t0;
        th->t_measure = t_measure;
        th->t_end = t_end;
        th->res = &res[t];
        stc_hist_reset(&th->res->corrected);
        stc_hist_reset(&th->res->service);
        th->wire = libmode ? NULL : bench_wire_new(&cfg, cfg.seed * 7919u + t, msg, sizeof msg);
        if (!libmode && !th->wire) {
            fprintf(stderr, "seamtex-bench: %s\n", msg);
            rc = 1;
            goto done;
        }
        th->shm_qroom = cfg.shm ? bench_wire_shm_qroom(&cfg) : 0;
        th->shm_qarea = th->shm_qroom * (cfg.shm ? bench_wire_shm_qrooms(&cfg) : 0);
        for (unsigned i = 0; th->shm && !cfg.shm_copy && i < th->conn_count; i++)  /* once */
            bench_wire_shm_place(th->wire, th->shm[i], th->shm_qroom);
    }
    if (!cfg.quiet)
        printf("seamtex-bench: %s%s%s, %s loop, %u conns, %u threads, pipeline %u%s, %.1f s "
               "(+%.1f s warm-up)\n", cfg.proto ? bench_proto_name(cfg.proto) : "",
               cfg.proto ? " " : "", bench_op_name(cfg.op), cfg.open_loop ? "open" : "closed",
               cfg.conns, cfg.threads, cfg.pipeline,
               bench_op_samples(cfg.op) ? ", batches" : "", cfg.duration_s, cfg.warmup_s);
    if (!cfg.quiet && (cfg.cluster || cfg.lib))
        printf("  through libseamtex: %s\n", cfg.lib ? "direct stc_conn, pipelined"
               : cfg.blocking ? "stc_cluster, blocking" : "stc_cluster, pipelined");
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_mutex_init(&gate.mu, NULL);
    pthread_cond_init(&gate.cv, &ca);
    pthread_condattr_destroy(&ca);
    unsigned started = 0;
    for (; started < cfg.threads; started++) {
        targs[started] = (thread_arg){ &ths[started], &gate };
        if (pthread_create(&tids[started], NULL, thread_main, &targs[started]) != 0) {
            fprintf(stderr, "seamtex-bench: cannot start thread %u\n", started);
            rc = 1;
            break;
        }
    }
    /* the measured window's CPU: read at its edges by this thread, which sleeps between */
    wait_edge(&gate, t_measure, started);
    cpu_mark w0 = cpu_now();
    wait_edge(&gate, t_end, started);
    cpu_mark w1 = cpu_now();
    cpu_mark win = { w1.cpu_s - w0.cpu_s, w1.vcsw - w0.vcsw, w1.ivcsw - w0.ivcsw, w0.t0, w1.t0 };
    for (unsigned t = 0; t < started; t++)
        pthread_join(tids[t], NULL);
    pthread_cond_destroy(&gate.cv);
    pthread_mutex_destroy(&gate.mu);
    double cpu_total = cpu_now().cpu_s;

    bench_result *all = &res[cfg.threads];
    stc_hist_reset(&all->corrected);
    stc_hist_reset(&all->service);
    for (unsigned t = 0; t < cfg.threads; t++) {
        bench_result *r = &res[t];
        if (ths[t].err[0]) {
            fprintf(stderr, "seamtex-bench: %s\n", ths[t].err);
            rc = ths[t].no_conn ? 3 : rc == 3 ? 3 : 1;   /* seamtex-bench(1) EXIT STATUS */
        }
        stc_hist_merge(&all->corrected, &r->corrected);
        stc_hist_merge(&all->service, &r->service);
        all->sent += r->sent;
        all->completed += r->completed;
        all->measured += r->measured;
        all->errors += r->errors;
        all->timeouts += r->timeouts;
        all->conn_errors += r->conn_errors;
        all->late_sends += r->late_sends;
        all->unsent += r->unsent;
        all->queries += r->queries;
        all->bytes_out += r->bytes_out;
        all->bytes_in += r->bytes_in;
        all->failovers += r->failovers;
        all->moved += r->moved;
    }

    /* the measured window; with a request cap the run may end before t_end */
    double secs = cfg.duration_s;
    uint64_t t_last = 0;
    for (unsigned t = 0; t < cfg.threads; t++)
        if (res[t].t_last > t_last)
            t_last = res[t].t_last;
    if (cfg.max_requests && t_last > t_measure && (t_last - t_measure) / 1e9 < secs)
        secs = (t_last - t_measure) / 1e9;
    double load1 = loadavg1();
    double rate = secs > 0 ? all->measured / secs : 0;
    if (!cfg.quiet) {
        if (cfg.open_loop)
            printf("  target %.0f req/s (%s), achieved %.0f req/s\n", cfg.rate,
                   cfg.arrival == STC_ARRIVAL_POISSON ? "poisson" : "uniform", rate);
        else
            printf("  throughput %.0f req/s\n", rate);
        if (bench_op_samples(cfg.op))
            printf("  %.0f queries/s (batch %u)\n", all->queries / secs, cfg.batch);
        printf("  sent %llu, completed %llu, measured %llu, errors %llu, timeouts %llu, "
               "conn errors %llu, late sends %llu\n",
               (unsigned long long)all->sent, (unsigned long long)all->completed,
               (unsigned long long)all->measured, (unsigned long long)all->errors,
               (unsigned long long)all->timeouts, (unsigned long long)all->conn_errors,
               (unsigned long long)all->late_sends);
        if (all->unsent)
            printf("  WARNING: %llu requests were due but never sent (connections full: "
                   "raise --pipeline or --conns); the rate was not held\n",
                   (unsigned long long)all->unsent);
        printf("  latency (us):\n");
        print_hist("corrected", &all->corrected);
        print_hist("service", &all->service);
        printf("  load average %.2f -> %.2f\n", load0, load1);
    } else {
        printf("%.0f req/s p50 %.1f us p99 %.1f us max %.1f us errors %llu timeouts %llu\n",
               rate, stc_hist_percentile(&all->corrected, 50) / 1e3,
               stc_hist_percentile(&all->corrected, 99) / 1e3, all->corrected.max / 1e3,
               (unsigned long long)all->errors, (unsigned long long)all->timeouts);
    }
    if (cfg.json_path && write_json(&cfg, all, secs, load0, load1, 0, &win, cpu_total) < 0)
        rc = 1;
    if (all->measured == 0) {
        fprintf(stderr, "seamtex-bench: no reply was measured\n");
        rc = rc ? rc : 1;
    }
done:
    if (fds)
        close_all(fds, nfds);
    for (unsigned t = 0; ths && t < cfg.threads; t++)
        bench_wire_free(ths[t].wire);
    for (unsigned i = 0; shm && i < cfg.conns; i++)
        if (shm[i])
            munmap(shm[i], shm_size);
    free(shm);
    free(fds);
    free(ths);
    free(res);
    free(tids);
    free(targs);
    return rc;
}
