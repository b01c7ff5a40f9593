/* tests/bench/bench_native.c - native set files: hot sampling from a mapping vs the heap,
 * restart time with native files vs re-import, and out-of-core serving under a memory budget.
 *
 * Usage: bench_native [--json PATH] [--only hot|restart|ooc] [--lib-mb N] [--secs S]
 *        (SEAMTEX_BENCH_NATIVE_MB sets the default of --lib-mb)
 *   hot:     one Ptex set (shared cube8_k6_u8.ptx, else the in-process fixture) sampled in
 *            process from its heap copy (A) and from its mapped native file (B), same queries,
 *            alternating A B A B, 7 rounds per side; medians per filter.
 *   restart: a data dir of about --lib-mb MB of texels (default 10240; the real benchmark) is
 *            generated under $TMPDIR from the shared .ptx files and images (copies of each,
 *            manifests written as the daemon writes them); seamtexd is started on it three
 *            times in one run: --native no (re-import of every source, as before native
 *            files), the first start with native files (the upgrade: import + write), and a
 *            start that maps them. Each: time from exec to the first served SAMPLE and to LIST
 *            showing every set. The page cache is warm (the machine is shared: it is not
 *            dropped).
 *   ooc:     the same library served with --memory-budget = library / 4; one client sends
 *            SAMPLE batches (256 bilinear queries, random faces and footprints) to sets drawn
 *            with Zipf(1.0) popularity for --secs seconds (default 20): throughput, p50/p99
 *            batch latency, resident bytes over time (STATS resident_bytes every 0.5 s) and the
 *            share of queries that hit a released (cold) set.
 * The library is deleted at the end. Machine load is printed and stored in the JSON.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "datadir.h"
#include "import.h"
#include "native.h"
#include "ptex.h"
#include "ptexfilter.h"
#include "sample.h"
#include "seamtex.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}
static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static char g_load[64];
static void read_load(void)
{
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (!fgets(g_load, sizeof g_load, f))
            g_load[0] = 0;
        fclose(f);
    }
    char *nl = strchr(g_load, '\n');
    if (nl)
        *nl = 0;
}

/* ---- hot: heap vs mapping ------------------------------------------------------------------ */

typedef struct hot_res {
    const char *filter;
    double heap_ns, map_ns;
} hot_res;

static int bench_hot(hot_res *res, int *nres)
{
    st_error e;
    st_set *s = NULL;
    char path[1024];
    if (st_test_data_path(path, sizeof path, "ptex-ref/cube8_k6_u8.ptx") == 0) {
        if (st_ptex_read_file(path, 0, &s, &e) != 0)
            return -1;
    } else {
        size_t len;
        void *b = st_fixture_default_ptx(&len, 1);
        int rc = st_ptex_read_mem(b, len, 0, &s, &e);
        free(b);
        if (rc)
            return -1;
    }
    char np[256];
    snprintf(np, sizeof np, "%s/bench_native_%d.native", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp",
             (int)getpid());
    if (st_native_write(np, s, NULL, &e) != 0)
        return -1;
    st_set *m = NULL;
    if (st_native_open(np, 0, NULL, &m, &e) != 0)
        return -1;
    unlink(np);
    const size_t n = 1 << 18;
    st_query *q = malloc(n * sizeof *q);
    float *out = malloc(n * 4 * sizeof(float));
    uint8_t *stt = malloc(n);
    uint32_t r = 7;
    for (size_t i = 0; i < n; i++) {
        r = r * 1664525u + 1013904223u;
        q[i].face = (r >> 8) % s->info.nfaces;
        r = r * 1664525u + 1013904223u;
        q[i].u = (float)(r >> 8) / 16777216.0f;
        r = r * 1664525u + 1013904223u;
        q[i].v = (float)(r >> 8) / 16777216.0f;
        float fp = (float)((r >> 4) & 15) * 0.004f;
        q[i].dudx = fp;
        q[i].dvdy = fp;
        q[i].dvdx = q[i].dudy = 0;
    }
    static const struct { const char *name; uint8_t f; size_t n; } F[] = {
        {"bilinear", ST_FILTER_BILINEAR, 1 << 18}, {"trilinear", ST_FILTER_TRILINEAR, 1 << 18},
        {"ptex-bicubic", ST_FILTER_PTEX_BICUBIC, 1 << 15}};
    *nres = 0;
    for (size_t k = 0; k < sizeof F / sizeof F[0]; k++) {
        st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = F[k].f, .max_aniso = 8};
        double ta[7], tb[7];
        st_sample_batch(s, &o, q, F[k].n, out, NULL, stt);  /* warm both */
        st_sample_batch(m, &o, q, F[k].n, out, NULL, stt);
        for (int round = 0; round < 7; round++) {
            double t0 = now_s();
            st_sample_batch(s, &o, q, F[k].n, out, NULL, stt);
            double t1 = now_s();
            st_sample_batch(m, &o, q, F[k].n, out, NULL, stt);
            double t2 = now_s();
            ta[round] = (t1 - t0) * 1e9 / (double)F[k].n;
            tb[round] = (t2 - t1) * 1e9 / (double)F[k].n;
        }
        res[*nres].filter = F[k].name;
        res[*nres].heap_ns = median(ta, 7);
        res[*nres].map_ns = median(tb, 7);
        printf("hot %-13s heap %7.1f ns/query  mapped %7.1f ns/query  (mapped/heap %.3f)\n",
               F[k].name, res[*nres].heap_ns, res[*nres].map_ns,
               res[*nres].map_ns / res[*nres].heap_ns);
        (*nres)++;
    }
    free(q);
    free(out);
    free(stt);
    st_set_free(m);
    st_set_free(s);
    return 0;
}

/* ---- the generated library ------------------------------------------------------------------ */

typedef struct libsrc {
    const char *rel, *ext;
    uint64_t    texel_bytes;   /* of the imported set */
    uint32_t    nfaces;
} libsrc;

static libsrc SRC[] = {
    {"ptex-ref/cube8_k7varrot_f32.ptx", "ptx", 0, 0},
    {"ptx/wdas-ptex-samples/holeycube/holeycube.ptx", "ptx", 0, 0},
    {"ptx/wdas-ptex-2009/cube/text/cube.ptx", "ptx", 0, 0},
    {"ptex-ref/cube8_k6_u8.ptx", "ptx", 0, 0},
    {"images/brick.png", "png", 0, 0},
    {"meshes/duck/DuckCM.png", "png", 0, 0},
};
#define NSRC (sizeof SRC / sizeof SRC[0])

typedef struct libset {
    char     name[32];
    uint32_t nfaces;
    double   pop;   /* Zipf weight */
} libset;

static int copy_file(const char *from, const char *to)
{
    size_t n;
    void *b = st_test_read_file(from, &n);
    if (!b)
        return -1;
    int fd = open(to, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    int ok = fd >= 0 && write(fd, b, n) == (ssize_t)n;
    if (fd >= 0)
        close(fd);
    free(b);
    return ok ? 0 : -1;
}

/* A sources-only data dir of about mb MB of texels. Returns the number of sets. */
static int make_library(const char *dir, double mb, libset **out)
{
    char p[900], q[1200];
    uint64_t total = 0, want = (uint64_t)(mb * 1048576.0);
    int have = 0;
    for (size_t i = 0; i < NSRC; i++) {
        if (st_test_data_path(p, sizeof p, SRC[i].rel) != 0 || access(p, R_OK) != 0)
            continue;
        st_import_opts o;
        st_import_opts_init(&o);
        st_set *s = NULL;
        st_error e;
        if (st_import_file(p, &o, &s, &e) != 0)
            continue;
        SRC[i].texel_bytes = s->texel_bytes;
        SRC[i].nfaces = s->info.nfaces;
        st_set_free(s);
        have++;
    }
    if (!have)
        return 0;
    snprintf(p, sizeof p, "%s/sets", dir);
    mkdir(dir, 0700);
    mkdir(p, 0700);
    int n = 0, cap = 0;
    libset *sets = NULL;
    for (size_t k = 0; total < want; k++) {
        libsrc *sr = &SRC[k % NSRC];
        if (!sr->texel_bytes)
            continue;
        if (n == cap) {
            cap = cap ? cap * 2 : 64;
            sets = realloc(sets, (size_t)cap * sizeof *sets);
        }
        libset *ls = &sets[n];
        snprintf(ls->name, sizeof ls->name, "lib%05d", n);
        ls->nfaces = sr->nfaces;
        snprintf(p, sizeof p, "%s/sets/%s", dir, ls->name);
        mkdir(p, 0700);
        char srcname[64];
        snprintf(srcname, sizeof srcname, "source-%05d.%s", n, sr->ext);
        snprintf(q, sizeof q, "%s/%s", p, srcname);
        char from[1024];
        st_test_data_path(from, sizeof from, sr->rel);
        if (copy_file(from, q) != 0)
            return -1;
        uint64_t bytes;
        uint32_t crc;
        st_error e;
        if (st_file_crc(q, &bytes, &crc, &e) != 0)
            return -1;
        snprintf(q, sizeof q, "%s/manifest", p);
        FILE *f = fopen(q, "w");
        fprintf(f, "seamtex-set 1\nname %s\nsource %s\nformat %s\nbytes %llu\ncrc32 %08x\n"
                "options\nend\n", ls->name, srcname, sr->ext, (unsigned long long)bytes, crc);
        fclose(f);
        total += sr->texel_bytes;
        n++;
    }
    *out = sets;
    printf("library: %d sets, %.0f MB of texels, in %s\n", n, (double)total / 1048576.0, dir);
    return n;
}

/* ---- the daemon ---------------------------------------------------------------------------- */

typedef struct daemon {
    pid_t pid;
    int   port;
    char  portfile[1100], logfile[1100];
} daemon_t;

static int daemon_start(daemon_t *d, const char *dir, const char *const *extra)
{
    const char *bdir = getenv("SEAMTEX_BUILD");
    char exe[1024];
    snprintf(exe, sizeof exe, "%s/seamtexd", bdir && *bdir ? bdir : "build");
    snprintf(d->portfile, sizeof d->portfile, "%s.port", dir);
    snprintf(d->logfile, sizeof d->logfile, "%s.log", dir);
    unlink(d->portfile);
    const char *argv[32];
    int ac = 0;
    argv[ac++] = exe;
    argv[ac++] = "--listen";
    argv[ac++] = "127.0.0.1:0";
    argv[ac++] = "--data-dir";
    argv[ac++] = dir;
    argv[ac++] = "--port-file";
    argv[ac++] = d->portfile;
    argv[ac++] = "--no-default-set";
    argv[ac++] = "--max-sets";
    argv[ac++] = "100000";
    for (int i = 0; extra && extra[i] && ac < 30; i++)
        argv[ac++] = extra[i];
    argv[ac] = NULL;
    d->pid = fork();
    if (d->pid == 0) {
        int fd = open(d->logfile, O_WRONLY | O_CREAT | O_APPEND, 0600);
        dup2(fd, 2);
        execv(exe, (char *const *)argv);
        _exit(127);
    }
    return d->pid > 0 ? 0 : -1;
}

static stc_conn *daemon_connect(daemon_t *d, double timeout_s)
{
    double t0 = now_s();
    while (now_s() - t0 < timeout_s) {
        FILE *f = fopen(d->portfile, "r");
        /* the port file is written when the daemon serves */
        if (f) {
            int port = 0;
            if (fscanf(f, "%d", &port) == 1 && port > 0) {
                fclose(f);
                d->port = port;
                int err;
                stc_conn *c = stc_connect("127.0.0.1", (unsigned)port, 60000, &err);
                if (c)
                    return c;
            } else {
                fclose(f);
            }
        }
        int st;
        if (waitpid(d->pid, &st, WNOHANG) == d->pid)
            return NULL;
        usleep(2000);
    }
    return NULL;
}

static void daemon_stop(daemon_t *d)
{
    kill(d->pid, SIGTERM);
    int st;
    waitpid(d->pid, &st, 0);
}

static int sample_one(stc_conn *c, const char *set, uint32_t nfaces, size_t n, uint32_t *rng,
                      double *lat_s)
{
    stc_query q[256];
    for (size_t i = 0; i < n; i++) {
        *rng = *rng * 1664525u + 1013904223u;
        q[i].face = (*rng >> 8) % nfaces;
        *rng = *rng * 1664525u + 1013904223u;
        q[i].u = (float)(*rng >> 8) / 16777216.0f;
        *rng = *rng * 1664525u + 1013904223u;
        q[i].v = (float)(*rng >> 8) / 16777216.0f;
        q[i].dudx = q[i].dvdy = (float)((*rng >> 4) & 15) * 0.003f;
        q[i].dvdx = q[i].dudy = 0;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    o.outfmt = STC_OUT_F32;
    stc_sample_result r;
    double t0 = now_s();
    int rc = stc_sample(c, set, &o, q, n, &r);
    if (lat_s)
        *lat_s = now_s() - t0;
    return rc;
}

typedef struct start_res {
    const char *what;
    double first_sample_s, all_listed_s;
} start_res;

static int timed_start(const char *dir, const char *const *extra, const libset *sets, int n,
                       start_res *r)
{
    daemon_t d;
    double t0 = now_s();
    if (daemon_start(&d, dir, extra) != 0)
        return -1;
    stc_conn *c = daemon_connect(&d, 3600);
    if (!c)
        return -1;
    uint32_t rng = 1;
    while (sample_one(c, sets[0].name, sets[0].nfaces, 16, &rng, NULL) != 0)
        usleep(1000);
    r->first_sample_s = now_s() - t0;
    for (;;) {
        const stc_set_entry *e;
        size_t ne = 0;
        if (stc_list(c, &e, &ne) == 0 && (int)ne >= n)
            break;
        usleep(1000);
    }
    r->all_listed_s = now_s() - t0;
    printf("restart %-28s first sample %8.3f s   every set listed %8.3f s\n", r->what,
           r->first_sample_s, r->all_listed_s);
    stc_close(c);
    daemon_stop(&d);
    /* the daemon's own account of the start */
    FILE *lf = fopen(d.logfile, "r");
    char line[1024], last[1024] = "";
    while (lf && fgets(line, sizeof line, lf))
        if (strstr(line, "sets loaded") || strstr(line, "sets imported"))
            snprintf(last, sizeof last, "%s", line);
    if (lf)
        fclose(lf);
    printf("    daemon: %s", last[0] ? last : "(no load line)\n");
    return 0;
}

/* ---- out of core ---------------------------------------------------------------------------- */

typedef struct ooc_res {
    double qps, p50_ms, p99_ms, cold_share, max_resident_mb, budget_mb, stored_mb;
    uint64_t releases, majflt;
    int nsamples;
    double resident_mb[128];
} ooc_res;

static uint64_t stat_of(stc_conn *c, const char *key)
{
    const stc_stat *s;
    size_t n;
    if (stc_stats(c, &s, &n) != 0)
        return UINT64_MAX;
    for (size_t i = 0; i < n; i++)
        if (!strcmp(s[i].key, key))
            return s[i].u;
    return UINT64_MAX;
}

static int bench_ooc(const char *dir, const libset *sets, int n, double secs, ooc_res *r)
{
    /* stored bytes first (no budget), then the budget = stored / 4 */
    daemon_t d;
    if (daemon_start(&d, dir, NULL) != 0)
        return -1;
    stc_conn *c = daemon_connect(&d, 3600);
    if (!c)
        return -1;
    uint64_t stored = stat_of(c, "stored_bytes");
    stc_close(c);
    daemon_stop(&d);
    uint64_t budget = stored / 4;
    char bs[32];
    snprintf(bs, sizeof bs, "%llu", (unsigned long long)budget);
    const char *const extra[] = {"--memory-budget", bs, NULL};
    if (daemon_start(&d, dir, extra) != 0)
        return -1;
    c = daemon_connect(&d, 3600);
    stc_conn *sc = c ? stc_connect("127.0.0.1", (unsigned)d.port, 60000, NULL) : NULL;
    if (!c || !sc)
        return -1;
    memset(r, 0, sizeof *r);
    r->budget_mb = (double)budget / 1048576.0;
    r->stored_mb = (double)stored / 1048576.0;
    double *cdf = malloc((size_t)n * sizeof *cdf), sum = 0;
    for (int i = 0; i < n; i++)
        cdf[i] = (sum += 1.0 / (double)(i + 1));   /* Zipf(1.0) */
    size_t cap = 1 << 20, nl = 0;
    double *lat = malloc(cap * sizeof *lat);
    uint64_t q0 = stat_of(sc, "cold_queries"), rel0 = stat_of(sc, "budget_releases");
    uint64_t mf0 = stat_of(sc, "major_faults");
    uint32_t rng = 99;
    double t0 = now_s(), next = t0;
    uint64_t queries = 0;
    while (now_s() - t0 < secs) {
        rng = rng * 1664525u + 1013904223u;
        double x = (double)(rng >> 8) / 16777216.0 * sum;
        int lo = 0, hi = n - 1;
        while (lo < hi) {
            int mid = (lo + hi) / 2;
            if (cdf[mid] < x)
                lo = mid + 1;
            else
                hi = mid;
        }
        /* popularity rank != name order: spread the popular ones over the library */
        int k = (int)(((uint64_t)lo * 2654435761u) % (uint64_t)n);
        double l;
        if (sample_one(c, sets[k].name, sets[k].nfaces, 256, &rng, &l) != 0)
            break;
        if (nl < cap)
            lat[nl++] = l;
        queries += 256;
        if (now_s() >= next && r->nsamples < 128) {
            uint64_t res = stat_of(sc, "resident_bytes");
            double mb = (double)res / 1048576.0;
            r->resident_mb[r->nsamples++] = mb;
            if (mb > r->max_resident_mb)
                r->max_resident_mb = mb;
            next += 0.5;
        }
    }
    double el = now_s() - t0;
    r->qps = (double)queries / el;
    qsort(lat, nl, sizeof *lat, cmp_d);
    r->p50_ms = nl ? lat[nl / 2] * 1e3 : 0;
    r->p99_ms = nl ? lat[(size_t)((double)nl * 0.99)] * 1e3 : 0;
    r->cold_share = queries ? (double)(stat_of(sc, "cold_queries") - q0) / (double)queries : 0;
    r->releases = stat_of(sc, "budget_releases") - rel0;
    r->majflt = stat_of(sc, "major_faults") - mf0;
    printf("ooc: %.0f MB stored, budget %.0f MB: %.0f queries/s, batch p50 %.2f ms p99 %.2f ms, "
           "cold share %.3f, releases %llu, major faults %llu, resident max %.0f MB\n",
           r->stored_mb, r->budget_mb, r->qps, r->p50_ms, r->p99_ms, r->cold_share,
           (unsigned long long)r->releases, (unsigned long long)r->majflt, r->max_resident_mb);
    printf("ooc resident MB every 0.5 s:");
    for (int i = 0; i < r->nsamples; i++)
        printf(" %.0f", r->resident_mb[i]);
    printf("\n");
    free(lat);
    free(cdf);
    stc_close(sc);
    stc_close(c);
    daemon_stop(&d);
    return 0;
}

int main(int argc, char **argv)
{
    const char *json = NULL, *only = NULL;
    double lib_mb = 10240, secs = 20;
    if (getenv("SEAMTEX_BENCH_NATIVE_MB"))   /* make bench on a small machine */
        lib_mb = atof(getenv("SEAMTEX_BENCH_NATIVE_MB"));
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (!strcmp(argv[i], "--lib-mb") && i + 1 < argc)
            lib_mb = atof(argv[++i]);
        else if (!strcmp(argv[i], "--secs") && i + 1 < argc)
            secs = atof(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--json PATH] [--only hot|restart|ooc] [--lib-mb N] "
                    "[--secs S]\n", argv[0]);
            return 2;
        }
    }
    read_load();
    printf("machine: %ld cores, load %s\n", sysconf(_SC_NPROCESSORS_ONLN), g_load);
    hot_res hot[4];
    int nhot = 0;
    if (!only || !strcmp(only, "hot"))
        if (bench_hot(hot, &nhot) != 0)
            fprintf(stderr, "hot: failed\n");
    start_res st[3];
    int nst = 0, nsets = 0;
    ooc_res ooc;
    int have_ooc = 0;
    char dir[512] = "";
    if (!only || !strcmp(only, "restart") || !strcmp(only, "ooc")) {
        const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
        snprintf(dir, sizeof dir, "%s/bench_native_lib_%d", tmp, (int)getpid());
        libset *sets = NULL;
        nsets = make_library(dir, lib_mb, &sets);
        if (nsets <= 0) {
            fprintf(stderr, "restart: no shared data (SEAMTEX_DATA): skipped\n");
        } else {
            static const char *const nonative[] = {"--native", "no", NULL};
            st[0].what = "re-import (--native no)";
            st[1].what = "upgrade (import + write)";
            st[2].what = "native files (mmap)";
            if (timed_start(dir, nonative, sets, nsets, &st[0]) == 0 &&
                timed_start(dir, NULL, sets, nsets, &st[1]) == 0 &&
                timed_start(dir, NULL, sets, nsets, &st[2]) == 0)
                nst = 3;
            if (nst == 3)
                printf("restart: native start %.1fx faster than re-import to the first sample, "
                       "%.1fx to every set listed\n", st[0].first_sample_s / st[2].first_sample_s,
                       st[0].all_listed_s / st[2].all_listed_s);
            if ((!only || !strcmp(only, "ooc")) && bench_ooc(dir, sets, nsets, secs, &ooc) == 0)
                have_ooc = 1;
        }
        free(sets);
        char cmd[600];
        snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s.port' '%s.log'", dir, dir, dir);
        if (dir[0] && system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", dir);
    }
    read_load();
    printf("load at the end: %s\n", g_load);
    if (json) {
        FILE *f = fopen(json, "w");
        if (!f) {
            perror(json);
            return 1;
        }
        fprintf(f, "{\n  \"load_end\": \"%s\",\n  \"hot\": [", g_load);
        for (int i = 0; i < nhot; i++)
            fprintf(f, "%s{\"filter\": \"%s\", \"heap_ns\": %.2f, \"mapped_ns\": %.2f}",
                    i ? ", " : "", hot[i].filter, hot[i].heap_ns, hot[i].map_ns);
        fprintf(f, "],\n  \"restart\": {\"lib_mb\": %.0f, \"sets\": %d", lib_mb, nsets);
        for (int i = 0; i < nst; i++)
            fprintf(f, ", \"%s\": {\"first_sample_s\": %.4f, \"all_listed_s\": %.4f}",
                    i == 0 ? "reimport" : i == 1 ? "upgrade" : "native", st[i].first_sample_s,
                    st[i].all_listed_s);
        fprintf(f, "}");
        if (have_ooc) {
            fprintf(f, ",\n  \"ooc\": {\"stored_mb\": %.1f, \"budget_mb\": %.1f, \"qps\": %.0f, "
                    "\"p50_ms\": %.3f, \"p99_ms\": %.3f, \"cold_share\": %.4f, \"releases\": %llu, "
                    "\"major_faults\": %llu, \"max_resident_mb\": %.1f, \"resident_mb\": [",
                    ooc.stored_mb, ooc.budget_mb, ooc.qps, ooc.p50_ms, ooc.p99_ms, ooc.cold_share,
                    (unsigned long long)ooc.releases, (unsigned long long)ooc.majflt,
                    ooc.max_resident_mb);
            for (int i = 0; i < ooc.nsamples; i++)
                fprintf(f, "%s%.1f", i ? ", " : "", ooc.resident_mb[i]);
            fprintf(f, "]}");
        }
        fprintf(f, "\n}\n");
        fclose(f);
    }
    return 0;
}
