/* tests/bench/bench_native.c - native set files: hot sampling from a mapping vs the heap,
 * restart time with native files vs re-import, and out-of-core serving under a memory budget
 * beside OpenImageIO's TextureSystem.
 *
 * Usage: bench_native [--json PATH] [--only hot,restart,ooc] [--lib-mb N] [--ooc-mb N]
 *                     [--budget-mb N] [--secs S] [--rounds R] [--threads T] [--dir SCRATCH]
 *   Environment (make bench): SEAMTEX_BENCH_NATIVE_MB (default of --lib-mb, 512),
 *   SEAMTEX_BENCH_OOC_MB (--ooc-mb, default the whole library), SEAMTEX_BENCH_OOC_SECS
 *   (--secs, 24), SEAMTEX_BENCH_DIR (--dir, default $TMPDIR or /tmp),
 *   SEAMTEX_BENCH_TX_COMPRESSION (maketx --compression for OIIO's .tx files, default zip). The sizes:
 *   SEAMTEX_BENCH_NATIVE_MB=10240 SEAMTEX_BENCH_OOC_MB=8192 (docs/native.md "Measured").
 *   hot:     one Ptex set (shared cube8_k6_u8.ptx, else the in-process fixture) sampled in
 *            process from its heap copy (A) and from its mapped native file (B), same queries,
 *            alternating A B A B, 7 rounds per side; medians per filter.
 *   restart: a data dir of about --lib-mb MB of texels is generated under the scratch dir
 *            from the shared .ptx files and images (native_lib.c: copies of each, manifests
 *            written as the daemon writes them); seamtexd is started on it three times in one
 *            run: --native no (re-import of every source, as before native files), the first
 *            start with native files (the upgrade: import + write), and a start that maps
 *            them. Each: time from exec to the first served SAMPLE and to LIST showing every
 *            set. The page cache is warm (the machine is shared: it is not dropped).
 *   ooc:     the first sets of the library up to --ooc-mb (hard links, native files
 *            included) served under a budget of --budget-mb (default a quarter of the stored
 *            bytes) by seamtexd, by seamtex in process and by OIIO's TextureSystem on .tx
 *            copies, --threads threads each (default 2), the same Zipf(1.0) query stream,
 *            alternating in --rounds rounds (default 4) for --secs seconds per side
 *            (ooc_compare.c says exactly what each side does). The .tx files made by maketx
 *            are kept in SCRATCH/tx-cache for the next run.
 * The library, its subset and the .tx copies are deleted at the end. Machine load is printed
 * and stored in the JSON.
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
#include "native_lib.h"
#include "ooc_compare.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"

static char g_load[64];

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
            double t0 = nl_now_s();
            st_sample_batch(s, &o, q, F[k].n, out, NULL, stt);
            double t1 = nl_now_s();
            st_sample_batch(m, &o, q, F[k].n, out, NULL, stt);
            double t2 = nl_now_s();
            ta[round] = (t1 - t0) * 1e9 / (double)F[k].n;
            tb[round] = (t2 - t1) * 1e9 / (double)F[k].n;
        }
        res[*nres].filter = F[k].name;
        res[*nres].heap_ns = nl_median(ta, 7);
        res[*nres].map_ns = nl_median(tb, 7);
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

/* One bilinear query at the middle of face 0: the daemon serves the set. */
static int first_sample(stc_conn *c, const char *set)
{
    stc_query q = {0, 0.5f, 0.5f, 0.01f, 0, 0, 0.01f};
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = ST_MODE_TRAVERSE;
    o.filter = ST_FILTER_BILINEAR;
    o.outfmt = STC_OUT_F32;
    stc_sample_result r;
    return stc_sample(c, set, &o, &q, 1, &r);
}

typedef struct start_res {
    const char *what;
    double first_sample_s, all_listed_s;
    double load_s;   /* the daemon's own figure for loading the data dir (its log), 0 unknown */
} start_res;

/* Exec to serving (the port file) of a daemon on an empty data dir: the part of every start
 * that does not depend on the library (loading the shared libraries). Median of 3. */
static double empty_start_s(const char *scratch)
{
    char dir[700];
    snprintf(dir, sizeof dir, "%s/bench_native_empty_%d", scratch, (int)getpid());
    double t[3];
    int k = 0;
    for (int i = 0; i < 3; i++) {
        mkdir(dir, 0700);
        nl_daemon d;
        double t0 = nl_now_s();
        if (nl_daemon_start(&d, dir, NULL) != 0)
            break;
        stc_conn *c = nl_daemon_connect(&d, 600);
        if (c)
            t[k++] = nl_now_s() - t0;
        stc_close(c);
        nl_daemon_stop(&d);
    }
    char cmd[2200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s.port' '%s.log'", dir, dir, dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    double m = k ? nl_median(t, k) : 0;
    printf("restart %-28s serving %8.3f s (median of %d)\n", "empty data dir", m, k);
    return m;
}

static int timed_start(const char *dir, const char *const *extra, const nl_set *sets, int n,
                       start_res *r)
{
    nl_daemon d;
    double t0 = nl_now_s();
    if (nl_daemon_start(&d, dir, extra) != 0)
        return -1;
    stc_conn *c = nl_daemon_connect(&d, 3600);
    if (!c)
        return -1;
    while (first_sample(c, sets[0].name) != 0)
        usleep(1000);
    r->first_sample_s = nl_now_s() - t0;
    for (;;) {
        const stc_set_entry *e;
        size_t ne = 0;
        if (stc_list(c, &e, &ne) == 0 && (int)ne >= n)
            break;
        usleep(1000);
    }
    r->all_listed_s = nl_now_s() - t0;
    printf("restart %-28s first sample %8.3f s   every set listed %8.3f s\n", r->what,
           r->first_sample_s, r->all_listed_s);
    stc_close(c);
    nl_daemon_stop(&d);
    /* the daemon's own account of the start */
    FILE *lf = fopen(d.logfile, "r");
    char line[1024], last[1024] = "";
    while (lf && fgets(line, sizeof line, lf))
        if (strstr(line, "sets loaded") || strstr(line, "sets imported"))
            snprintf(last, sizeof last, "%s", line);
    if (lf)
        fclose(lf);
    printf("    daemon: %s", last[0] ? last : "(no load line)\n");
    /* the line ends "..., N ms" */
    char *ms = strstr(last, " ms");
    char *sp = ms;
    while (sp && sp > last && sp[-1] != ' ')
        sp--;
    r->load_s = ms ? atof(sp) / 1e3 : 0;
    return 0;
}

/* Removes a scratch dir with its .port and .log files beside it. */
static void rm_rf(const char *p)
{
    char cmd[2000];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s.port' '%s.log'", p, p, p);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", p);
}

static double env_num(const char *name, double dflt)
{
    const char *v = getenv(name);
    return v && *v ? atof(v) : dflt;
}

int main(int argc, char **argv)
{
    const char *json = NULL, *only = NULL;
    const char *tmp = getenv("TMPDIR") && *getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
    const char *scratch = getenv("SEAMTEX_BENCH_DIR") && *getenv("SEAMTEX_BENCH_DIR")
                              ? getenv("SEAMTEX_BENCH_DIR") : tmp;
    double lib_mb = env_num("SEAMTEX_BENCH_NATIVE_MB", 512);
    double ooc_mb = env_num("SEAMTEX_BENCH_OOC_MB", 0);
    double secs = env_num("SEAMTEX_BENCH_OOC_SECS", 24), budget_mb = 0;
    int rounds = 4, threads = 2;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (!strcmp(argv[i], "--lib-mb") && i + 1 < argc)
            lib_mb = atof(argv[++i]);
        else if (!strcmp(argv[i], "--ooc-mb") && i + 1 < argc)
            ooc_mb = atof(argv[++i]);
        else if (!strcmp(argv[i], "--budget-mb") && i + 1 < argc)
            budget_mb = atof(argv[++i]);
        else if (!strcmp(argv[i], "--secs") && i + 1 < argc)
            secs = atof(argv[++i]);
        else if (!strcmp(argv[i], "--rounds") && i + 1 < argc)
            rounds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--dir") && i + 1 < argc)
            scratch = argv[++i];
        else {
            fprintf(stderr, "usage: %s [--json PATH] [--only hot|restart|ooc] [--lib-mb N] "
                    "[--ooc-mb N] [--budget-mb N] [--secs S] [--rounds R] [--threads T] "
                    "[--dir SCRATCH]\n", argv[0]);
            return 2;
        }
    }
    /* --only takes one part or a comma-separated list of them */
    int do_hot = !only || strstr(only, "hot"), do_restart = !only || strstr(only, "restart");
    int do_ooc = !only || strstr(only, "ooc");
    if (lib_mb <= 0 || secs <= 0 || rounds < 1 || rounds > OOC_MAX_ROUNDS || threads < 1 ||
        threads > 16 || (!do_hot && !do_restart && !do_ooc)) {
        fprintf(stderr, "%s: bad option value (--only hot|restart|ooc, --rounds 1..%d, "
                "--threads 1..16)\n", argv[0], OOC_MAX_ROUNDS);
        return 2;
    }
    nl_read_load(g_load, sizeof g_load);
    printf("machine: %ld cores, load %s\n", sysconf(_SC_NPROCESSORS_ONLN), g_load);
    hot_res hot[4];
    int nhot = 0;
    if (do_hot && bench_hot(hot, &nhot) != 0)
        fprintf(stderr, "hot: failed\n");
    start_res st[3];
    double empty_s = 0;
    int nst = 0, nsets = 0, have_ooc = 0;
    ooc_res ooc;
    char dir[512] = "", sub[600] = "", txdir[600] = "", txcache[600] = "";
    if (do_restart || do_ooc) {
        mkdir(scratch, 0700);
        snprintf(dir, sizeof dir, "%s/bench_native_lib_%d", scratch, (int)getpid());
        nl_set *sets = NULL;
        double t0 = nl_now_s();
        nsets = nl_make_library(dir, do_restart ? lib_mb : (ooc_mb > 0 ? ooc_mb : lib_mb), &sets);
        printf("library written in %.1f s\n", nl_now_s() - t0);
        if (nsets <= 0) {
            fprintf(stderr, "restart/ooc: no shared data (SEAMTEX_DATA) or no space: skipped\n");
        } else {
            if (do_restart) {
                static const char *const nonative[] = {"--native", "no", NULL};
                st[0].what = "re-import (--native no)";
                st[1].what = "upgrade (import + write)";
                st[2].what = "native files (mmap)";
                if (timed_start(dir, nonative, sets, nsets, &st[0]) == 0 &&
                    timed_start(dir, NULL, sets, nsets, &st[1]) == 0 &&
                    timed_start(dir, NULL, sets, nsets, &st[2]) == 0)
                    nst = 3;
                empty_s = empty_start_s(scratch);
                if (nst == 3 && st[2].load_s > 0)
                    printf("restart: native start %.1fx faster than re-import to the first "
                           "sample, %.1fx to every set listed, %.0fx in the daemon's data-dir "
                           "load\n", st[0].first_sample_s / st[2].first_sample_s,
                           st[0].all_listed_s / st[2].all_listed_s, st[0].load_s / st[2].load_s);
            }
            if (do_ooc) {
                /* the out-of-core library: hard links to the first sets (native files
                 * included when the restart part wrote them) up to --ooc-mb */
                snprintf(sub, sizeof sub, "%s.ooc", dir);
                snprintf(txdir, sizeof txdir, "%s.tx", dir);
                snprintf(txcache, sizeof txcache, "%s/tx-cache", scratch);
                int n = nl_link_subset(dir, sets, nsets, ooc_mb, sub);
                ooc_cfg oc = {sub, txcache, txdir, sets, n, secs, rounds, threads,
                              (uint64_t)(budget_mb * 1048576.0),
                              getenv("SEAMTEX_BENCH_TX_COMPRESSION")};
                if (n > 0 && ooc_compare(&oc, &ooc) == 0)
                    have_ooc = 1;
                else
                    fprintf(stderr, "ooc: failed\n");
            }
        }
        free(sets);
        rm_rf(dir);
        if (sub[0])
            rm_rf(sub);
        if (txdir[0])
            rm_rf(txdir);
    }
    nl_read_load(g_load, sizeof g_load);
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
        fprintf(f, "],\n  \"restart\": {\"lib_mb\": %.0f, \"sets\": %d, \"empty_start_s\": %.4f",
                lib_mb, nsets, empty_s);
        for (int i = 0; i < nst; i++)
            fprintf(f, ", \"%s\": {\"first_sample_s\": %.4f, \"all_listed_s\": %.4f, "
                    "\"daemon_load_s\": %.4f}", i == 0 ? "reimport" : i == 1 ? "upgrade" : "native",
                    st[i].first_sample_s, st[i].all_listed_s, st[i].load_s);
        fprintf(f, "}");
        if (have_ooc) {
            fprintf(f, ",\n  \"ooc\": ");
            ooc_json(f, &ooc);
        }
        fprintf(f, "\n}\n");
        fclose(f);
    }
    return 0;
}
