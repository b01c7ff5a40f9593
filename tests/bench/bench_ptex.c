/* tests/bench/bench_ptex.c - Ptex file loading and Ptex-filter sampling throughput on real
 * files (SEAMTEX_DATA). Load: median of 5 reads from memory (the file is read once first),
 * reported per MB of file and per face. Sampling: one thread, batches of 4096 random queries
 * (uniform face, uv in [0,1], footprints of 1/512 .. 1/2 of a face, like the reference
 * queries), median of 5 runs, per Ptex filter in Traverse mode. Prints a table; --json PATH
 * writes the figures. The Ptex library reached about 16 M bilinear and 8 M gaussian
 * queries/s at best on a small cube on this machine. Times are the thread's CPU time (the
 * machine is shared by other jobs; wall time would measure their load, not this code). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ptex.h"
#include "ptexfilter.h"
#include "../common/testdata.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t); /* CPU time: the machine is shared */
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

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

static const char *files[] = {
    "ptex-ref/cube1_k6_u8.ptx",
    "ptex-ref/cube8_k7varrot_f32.ptx",
    "ptx/wdas-ptex-samples/teapot/teapot.ptx",
    "ptx/wdas-ptex-samples/holeycube/holeycube.ptx",
    "ptx/wdas-ptex-2009/cube/text/cube.ptx",
};
static const char *fnames[8] = {"point", "bilinear", "box", "gaussian", "bicubic", "bspline",
                                "catmullrom", "mitchell"};

int main(int argc, char **argv)
{
    const char *json = NULL;
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
    const char *dd = getenv("SEAMTEX_DATA");
    if (!dd || !*dd)
        dd = "../shared/data";
    FILE *js = json ? fopen(json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"ptex\",\"load\":[");
    printf("%-22s %8s %6s %10s %10s %10s\n", "file", "MB", "faces", "load ms", "ms/MB", "us/face");
    size_t nf = sizeof files / sizeof files[0];
    st_set *sets[8] = {0};
    for (size_t i = 0; i < nf; i++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dd, files[i]);
        size_t len;
        uint8_t *b = st_test_read_file(path, &len);
        if (!b) {
            printf("%-22s missing (SEAMTEX_DATA=%s)\n", files[i], dd);
            continue;
        }
        double t[5];
        for (int r = 0; r < 5; r++) {
            st_set *s;
            st_error e;
            double t0 = now();
            if (st_ptex_read_mem(b, len, 0, &s, &e)) {
                printf("%s: %s\n", files[i], e.msg);
                return 1;
            }
            t[r] = now() - t0;
            if (r == 4)
                sets[i] = s;
            else
                st_set_free(s);
        }
        double m = median(t, 5), mb = (double)len / 1e6;
        const char *base = strrchr(files[i], '/') + 1;
        printf("%-22s %8.2f %6u %10.2f %10.2f %10.1f\n", base, mb, sets[i]->info.nfaces, m * 1e3,
               m * 1e3 / mb, m * 1e6 / sets[i]->info.nfaces);
        if (js)
            fprintf(js, "%s{\"file\":\"%s\",\"mb\":%.3f,\"faces\":%u,\"load_ms\":%.3f,"
                    "\"ms_per_mb\":%.3f,\"us_per_face\":%.3f}", i ? "," : "", base, mb,
                    sets[i]->info.nfaces, m * 1e3, m * 1e3 / mb, m * 1e6 / sets[i]->info.nfaces);
        free(b);
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
    for (size_t i = 0; i < 3 && i < nf; i++) {
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
            int reps = 40;
            for (int r = 0; r < 5; r++) {
                double t0 = now();
                for (int k = 0; k < reps; k++)
                    st_ptexfilter_batch(s, &o, q, N, out, cov, st);
                t[r] = now() - t0;
            }
            double qps = (double)N * reps / median(t, 5) / 1e6;
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
    for (size_t i = 0; i < nf; i++)
        st_set_free(sets[i]);
    return 0;
}
