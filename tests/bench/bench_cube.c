/* tests/bench/bench_cube.c - direction-lookup throughput of cube maps: the direction -> (face,
 * uv, footprint) mapping alone, and st_cube_sample_dir in each mode (Discard, Traverse, Clamp)
 * with bilinear and trilinear filters, plain and with Castano's edge-fixup lookup.
 *
 * Usage: bench_cube [--json PATH] [--reps N] [--secs S]
 *
 * The cube is StageEnvLatLong.exr resampled to 6 x 256^2 RGB half faces (or, without the
 * shared data, a synthetic 6 x 256^2 cube). Queries: 2^16 random directions with a cone of
 * one level-0 texel (bilinear reads level 0-1; trilinear blends two levels). Each figure is
 * the median of --reps runs of at least --secs seconds of thread CPU time, batches of 4096.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cube.h"
#include "import.h"
#include "../common/benchstat.h"

#define NQ (1u << 16)
#define BATCH 4096

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static st_set *synthetic_cube(void)
{
    st_set_info in = {.nchan = 3, .dtype = ST_DT_HALF, .alpha_chan = -1};
    st_set *s = NULL;
    st_error e;
    if (st_cube_create(&in, 256, 0, &s, &e))
        return NULL;
    for (unsigned f = 0; f < 6; f++) {
        uint8_t *p = st_face_level(s, f, 0);
        for (uint32_t j = 0; j < 256; j++)
            for (uint32_t i = 0; i < 256; i++) {
                float d[3];
                st_cube_face_dir(f, (i + 0.5f) / 256, (j + 0.5f) / 256, d);
                for (unsigned c = 0; c < 3; c++)
                    st_channel_put(ST_DT_HALF, p + ((size_t)j * 256 + i) * 6, c, 0.5f + 0.4f * sinf(3 * d[c]));
            }
    }
    st_set_build_mips(s, UINT32_MAX);
    return s;
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int reps = 5;
    double secs = 0.2;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--secs") && i + 1 < argc)
            secs = atof(argv[++i]);
    }
    if (reps < 1 || reps > 50)
        reps = 5;
    const char *data = getenv("SEAMTEX_DATA");
    if (!data || !*data)
        data = "../shared/data";
    char path[2048];
    snprintf(path, sizeof path, "%s/env/StageEnvLatLong.exr", data);
    st_set *cube = NULL;
    const char *src = "StageEnvLatLong.exr -> 6 x 256^2 half";
    if (!access(path, R_OK)) {
        st_import_opts o;
        st_import_opts_init(&o);
        o.cube = ST_IMPORT_CUBE_LATLONG;
        o.face_size = 256;
        st_error e;
        if (st_import_file(path, &o, &cube, &e))
            fprintf(stderr, "%s: %s\n", path, e.msg);
    }
    if (!cube) {
        cube = synthetic_cube();
        src = "synthetic 6 x 256^2 half (no shared data)";
    }
    if (!cube)
        return 1;
    st_cube_query *q = calloc(NQ, sizeof *q);
    st_query *fq = calloc(BATCH, sizeof *fq);
    float *out = calloc((size_t)BATCH * 4, sizeof *out);
    uint8_t *st = calloc(BATCH, 1);
    if (!q || !fq || !out || !st)
        return 1;
    uint32_t seed = 99;
    for (uint32_t i = 0; i < NQ; i++) {
        for (int k = 0; k < 3; k++) {
            seed = seed * 1664525u + 1013904223u;
            q[i].dir[k] = (float)(seed >> 8) / (float)(1u << 24) * 2.0f - 1.0f;
        }
        q[i].cone = 2.0f / 256.0f;
    }
    struct { const char *name; int mode, filter, lookup, map_only; } C[] = {
        {"map dir -> face/uv/footprint only", 0, 0, 0, 1},
        {"map with fixup lookup only", 0, 0, 1, 1},
        {"discard bilinear", ST_MODE_DISCARD, ST_FILTER_BILINEAR, 0, 0},
        {"traverse bilinear", ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0},
        {"clamp bilinear", ST_MODE_CLAMP, ST_FILTER_BILINEAR, 0, 0},
        {"clamp bilinear + fixup lookup", ST_MODE_CLAMP, ST_FILTER_BILINEAR, 1, 0},
        {"discard trilinear", ST_MODE_DISCARD, ST_FILTER_TRILINEAR, 0, 0},
        {"traverse trilinear", ST_MODE_TRAVERSE, ST_FILTER_TRILINEAR, 0, 0},
        {"clamp trilinear", ST_MODE_CLAMP, ST_FILTER_TRILINEAR, 0, 0},
        {"clamp trilinear + fixup lookup", ST_MODE_CLAMP, ST_FILTER_TRILINEAR, 1, 0},
    };
    FILE *js = json ? fopen(json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"cube\",\"cube\":\"%s\",\"reps\":%d,\"results\":[", src, reps);
    printf("cube direction lookups on %s; one thread, median of %d x >= %.2f s CPU\n", src, reps, secs);
    printf("%-36s %14s %10s\n", "case", "Mlookups/s", "ns/lookup");
    for (size_t c = 0; c < sizeof C / sizeof C[0]; c++) {
        st_sample_opts o;
        memset(&o, 0, sizeof o);
        o.mode = (uint8_t)C[c].mode;
        o.filter = (uint8_t)C[c].filter;
        double rate[50];
        for (int r = 0; r < reps; r++) {
            double t0 = cpu_now(), t;
            size_t done = 0;
            do {
                for (uint32_t i = 0; i < NQ; i += BATCH) {
                    if (C[c].map_only)
                        st_cube_queries(cube, (unsigned)C[c].lookup, q + i, BATCH, fq, st);
                    else
                        st_cube_sample_dir(cube, &o, (unsigned)C[c].lookup, q + i, BATCH, out, NULL, st);
                }
                done += NQ;
                t = cpu_now() - t0;
            } while (t < secs);
            rate[r] = (double)done / t;
        }
        qsort(rate, (size_t)reps, sizeof(double), st_bench_cmp_double);
        double m = rate[reps / 2];
        printf("%-36s %14.2f %10.1f\n", C[c].name, m / 1e6, 1e9 / m);
        if (js)
            fprintf(js, "%s{\"case\":\"%s\",\"lookups_per_s\":%.0f}", c ? "," : "", C[c].name, m);
    }
    if (js) {
        fprintf(js, "]}\n");
        fclose(js);
    }
    free(q);
    free(fq);
    free(out);
    free(st);
    st_set_free(cube);
    return 0;
}
