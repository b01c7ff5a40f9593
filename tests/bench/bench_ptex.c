/* tests/bench/bench_ptex.c - Ptex file import and Ptex-filter sampling throughput on real
 * files (SEAMTEX_DATA).
 *
 * Import: every shared quad-mesh .ptx (ptex-ref/ and ptx/), each imported --reps times (default
 * 9) with st_ptex_read_file - the whole import, file read included, file in the page cache -
 * in a new process each time (this binary again with --import-one: a fresh heap, so the
 * arena's pages are faulted in, as on a daemon's first load and as Ptex's figures were taken)
 * and again in this process (warm heap: the allocator reuses freed pages). Medians of wall and CPU time; MB/s of file and faces/s
 * from the fresh CPU time (the 2-core machine is shared, so wall time mostly measures the
 * other jobs); the bytes the set holds per level-0 texel right after import (st_set_memory);
 * "table cpu": the first Ptex-filter call on the set, which builds the Ptex resolution table
 * (ptexres.h; built lazily since the import stopped building it). The Ptex library's own open + level-0 decode of every face (Ptex 2.4.3, fresh
 * process each, measured outside the project since Ptex is not in Debian and must not be
 * copied in; same kind of machine, not this run) took 54 ms for cube8_k7varrot_f32, 20 ms for
 * holeycube and 59 ms for the 2009 text cube.
 *
 * Sampling: one thread, batches of 4096 random queries (uniform face, uv in [0,1], footprints
 * of 1/512 .. 1/2 of a face, like the reference queries), median of 5 runs, per Ptex filter in
 * Traverse mode, for the first three files (one untimed batch first builds the table). The
 * Ptex library reached about 16 M bilinear and 8 M gaussian queries/s at best on a small cube
 * on this machine. Sampling times are the thread's CPU time (the machine is shared).
 *
 * Usage: bench_ptex [--json PATH] [--reps N] [--import-only]
 * To compare two builds, run their binaries alternately (A B A B) with --import-only. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "../common/testdata.h"

static double clock_s(clockid_t c)
{
    struct timespec t;
    clock_gettime(c, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
static double now(void) { return clock_s(CLOCK_THREAD_CPUTIME_ID); } /* the machine is shared */

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmpd);
    return v[n / 2];
}

/* the sampling table uses the first three */
static const char *files[] = {
    "ptex-ref/cube1_k6_u8.ptx",
    "ptex-ref/cube8_k7varrot_f32.ptx",
    "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
    "ptx/wdas-ptex-2009/cube/text/cube.ptx",
    "ptex-ref/cube8_k6_u8.ptx",
    "ptex-ref/cube8_k6_u8_rot.ptx",
    "ptx/wdas-ptex-samples/envcube/envcube.ptx",
    "ptx/wdas-ptex-2009/dispplane/rand/pPlane1.ptx",
    "ptx/wdas-ptex-2009/dispplane/rand_lo/pPlane1.ptx",
    "ptx/wdas-ptex-2009/dispplane/wave_lo/pPlane1.ptx",
    "ptx/wdas-ptex-2009/nonquad/test/pPlane1.ptx",
    "ptx/wdas-ptex-2009/nonquad/evblur/pPlane1.ptx",
    "ptx/wdas-ptex-2009/tri/uv.ptx",
    "ptx/wdas-ptex-2009/tri/quad.ptx",
    "ptx/wdas-ptex-2009/bordermodes/clamp.ptx",
};
#define NFILES (sizeof files / sizeof files[0])
static const char *fnames[8] = {"point", "bilinear", "box", "gaussian", "bicubic", "bspline",
                                "catmullrom", "mitchell"};

/* --import-one PATH: one import in this (new) process; prints wall and CPU seconds. */
static int import_one(const char *path)
{
    st_set *s = NULL;
    st_error e;
    double w0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
    int rc = st_ptex_read_file(path, 0, &s, &e);
    double w = clock_s(CLOCK_MONOTONIC) - w0, c = clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0;
    if (rc) {
        fprintf(stderr, "%s: %s\n", path, e.msg);
        return 1;
    }
    printf("%.9f %.9f\n", w, c);
    st_set_free(s);
    return 0;
}

/* One import in a new process (this binary run again with --import-one): a fresh heap, so
 * the arena's pages are faulted in, as on a daemon's first load and as Ptex's figures were
 * taken ("fresh process each"). Process start-up is not timed. Wall and CPU seconds. */
static int import_fresh(const char *path, double *wall, double *cpu)
{
    int fd[2];
    if (pipe(fd))
        return -1;
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        close(fd[0]);
        if (dup2(fd[1], 1) < 0)
            _exit(127);
        execl("/proc/self/exe", "bench_ptex", "--import-one", path, (char *)NULL);
        _exit(127);
    }
    close(fd[1]);
    char buf[128] = {0};
    ssize_t n = read(fd[0], buf, sizeof buf - 1);
    close(fd[0]);
    int st;
    waitpid(pid, &st, 0);
    if (n <= 0 || !WIFEXITED(st) || WEXITSTATUS(st) || sscanf(buf, "%lf %lf", wall, cpu) != 2)
        return -1;
    return 0;
}

/* A short unique name: the file name, or folder/file for the many pPlane1.ptx. */
static void short_name(const char *rel, char *buf, size_t cap)
{
    const char *base = strrchr(rel, '/') + 1;
    if (strcmp(base, "pPlane1.ptx")) {
        snprintf(buf, cap, "%s", base);
        return;
    }
    const char *p = base - 1;
    while (p > rel && p[-1] != '/')
        p--;
    snprintf(buf, cap, "%.*s/%s", (int)(base - p - 1), p, base);
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int reps = 9, import_only = 0;
    if (argc == 3 && !strcmp(argv[1], "--import-one"))
        return import_one(argv[2]);
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--import-only"))
            import_only = 1;
    }
    if (reps < 1 || reps > 99)
        reps = 9;
    const char *dd = getenv("SEAMTEX_DATA");
    if (!dd || !*dd)
        dd = "../shared/data";
    FILE *js = json ? fopen(json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"ptex\",\"reps\":%d,\"import\":[", reps);
    printf("import (st_ptex_read_file, file in the page cache), median of %d; \"fresh\": one "
           "import per new process (cold heap),\n\"warm\": repeated in this process; MB/s "
           "and faces/s from fresh CPU time (the machine is shared)\n", reps);
    printf("%-22s %6s %6s %9s %9s %9s %8s %10s %8s %9s\n", "file", "MB", "faces", "fresh ms",
           "fresh cpu", "warm cpu", "MB/s", "faces/s", "B/texel", "table cpu");
    st_set *sets[NFILES] = {0};
    int jfirst = 1;
    for (size_t i = 0; i < NFILES; i++) {
        char path[1024], name[64];
        snprintf(path, sizeof path, "%s/%s", dd, files[i]);
        short_name(files[i], name, sizeof name);
        struct stat sb;
        if (stat(path, &sb)) {
            printf("%-22s missing (SEAMTEX_DATA=%s)\n", name, dd);
            continue;
        }
        double fwall[99], fcpu[99], wcpu[99];
        st_set *s = NULL;
        for (int r = 0; r < reps; r++) {
            if (import_fresh(path, &fwall[r], &fcpu[r])) {
                printf("%s: import in a child process failed\n", name);
                return 1;
            }
            st_error e;
            double c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
            if (st_ptex_read_file(path, 0, &s, &e)) {
                printf("%s: %s\n", name, e.msg);
                return 1;
            }
            wcpu[r] = clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0;
            if (r + 1 < reps)
                st_set_free(s);
        }
        double fw = median(fwall, reps), fc = median(fcpu, reps), wc = median(wcpu, reps);
        double mb = (double)sb.st_size / 1e6, texels = 0;
        for (uint32_t f = 0; f < s->info.nfaces; f++)
            texels += s->faces[f].flags & ST_FACE_CONSTANT ? 1.0 : (double)s->faces[f].w * s->faces[f].h;
        double bpt = (double)st_set_memory(s) / texels;
        /* the first Ptex-filter call: builds the resolution table when the import did not */
        st_query q0 = {.face = 0, .u = 0.5f, .v = 0.5f, .dudx = 0.01f, .dvdy = 0.01f};
        st_sample_opts o0 = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BILINEAR};
        float out0[4];
        double t0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
        st_ptexfilter_batch(s, &o0, &q0, 1, out0, NULL, NULL);
        double tb = clock_s(CLOCK_PROCESS_CPUTIME_ID) - t0;
        printf("%-22s %6.2f %6u %9.2f %9.2f %9.2f %8.1f %10.0f %8.2f %9.2f\n", name, mb,
               s->info.nfaces, fw * 1e3, fc * 1e3, wc * 1e3, mb / fc, s->info.nfaces / fc, bpt,
               tb * 1e3);
        if (js) {
            fprintf(js, "%s{\"file\":\"%s\",\"mb\":%.4f,\"faces\":%u,\"fresh_wall_ms\":%.3f,"
                    "\"fresh_cpu_ms\":%.3f,\"warm_cpu_ms\":%.3f,\"mb_per_s\":%.2f,"
                    "\"faces_per_s\":%.0f,\"bytes_per_texel\":%.3f,\"table_cpu_ms\":%.3f}",
                    jfirst ? "" : ",", name, mb, s->info.nfaces, fw * 1e3, fc * 1e3, wc * 1e3,
                    mb / fc, s->info.nfaces / fc, bpt, tb * 1e3);
            jfirst = 0;
        }
        if (i < 3 && !import_only)
            sets[i] = s;
        else
            st_set_free(s);
    }
    if (import_only) {
        if (js) {
            fprintf(js, "]}\n");
            fclose(js);
        }
        return 0;
    }
    if (js)
        fprintf(js, "],\"sample\":[");
    enum { N = 4096 };
    static st_query q[N];
    static float out[N * 4], cov[N];
    static uint8_t st[N];
    printf("\n%-22s", "Mqueries/s (Traverse)");
    for (int f = 0; f < 8; f++)
        printf(" %10s", fnames[f]);
    printf("\n");
    int first = 1;
    for (size_t i = 0; i < 3; i++) {
        st_set *s = sets[i];
        if (!s)
            continue;
        uint32_t x = 42;
        for (int k = 0; k < N; k++) {
            x = x * 1664525u + 1013904223u;
            q[k].face = (x >> 8) % s->info.nfaces;
            x = x * 1664525u + 1013904223u;
            q[k].u = (float)(x >> 8) / 16777216.0f;
            x = x * 1664525u + 1013904223u;
            q[k].v = (float)(x >> 8) / 16777216.0f;
            x = x * 1664525u + 1013904223u;
            float w = powf(2.0f, -1.0f - 8.0f * (float)(x >> 8) / 16777216.0f);
            q[k].dudx = w;
            q[k].dvdx = 0;
            q[k].dudy = 0;
            q[k].dvdy = w * 0.8f;
        }
        const char *base = strrchr(files[i], '/') + 1;
        printf("%-22s", base);
        for (int f = 0; f < 8; f++) {
            st_sample_opts o = {.mode = ST_MODE_TRAVERSE, .filter = (uint8_t)(ST_FILTER_PTEX_POINT + f)};
            double t[5];
            int batches = 40;
            for (int r = 0; r < 5; r++) {
                double t0 = now();
                for (int k = 0; k < batches; k++)
                    st_ptexfilter_batch(s, &o, q, N, out, cov, st);
                t[r] = now() - t0;
            }
            double qps = (double)N * batches / median(t, 5) / 1e6;
            printf(" %10.2f", qps);
            if (js)
                fprintf(js, "%s{\"file\":\"%s\",\"filter\":\"%s\",\"mqps\":%.3f}", first ? "" : ",",
                        base, fnames[f], qps);
            first = 0;
        }
        printf("\n");
    }
    if (js) {
        fprintf(js, "]}\n");
        fclose(js);
    }
    for (size_t i = 0; i < NFILES; i++)
        st_set_free(sets[i]);
    return 0;
}
