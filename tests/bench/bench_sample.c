/* tests/bench/bench_sample.c - single-thread throughput of st_sample_batch: queries per second
 * for every mode x filter, on a cache-resident set, on a ~400 MB set and on an atlas set (the
 * shared duck: image + UV mesh, whose Discard is chart Discard), with random and with
 * coherent (scanline-ordered) queries, plus the Traverse / Discard cost ratio and a plain C
 * bilinear loop over one 2048^2 RGBA8 array as an in-process baseline.
 *
 * Usage: bench_sample [--json PATH] [--big-mb N] [--no-big] [--no-atlas] [--reps N] [--secs S]
 *
 * Footprints (level-0 texels of the query's face): point and bilinear 1 texel (level 0);
 * trilinear 1.5 texels (lod 0.58: two levels); aniso 8:1 (major 8 texels in a random
 * direction, minor 1 texel: 8 probes at level 0). Each figure is the median of --reps runs of
 * at least --secs seconds, batches of 4096 queries, one thread.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/cube_fixture.h"
#include "../common/testdata.h"
#include "import.h"
#include "quadmesh.h"
#include "sample.h"
#include "../common/benchstat.h"

#define NQ (1u << 19)
#define BATCH 4096

/* Rates use the thread's CPU time: the machine is shared, and time spent descheduled is not
 * the sampler's cost. */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* cheap deterministic texture for the big set: smooth ramps plus hashed noise */
static void bake_cheap(void *user, uint32_t face, float u, float v, const float P[3], float *out)
{
    (void)user;
    uint32_t h = st_quad_hash(face, (uint32_t)(u * 65536.0f) * 65537u + (uint32_t)(v * 65536.0f));
    out[0] = 0.5f + 0.4f * P[0];
    out[1] = 0.5f + 0.4f * P[1];
    out[2] = (float)(h & 255) / 255.0f;
    out[3] = 1.0f;
}

static st_set *build_set(unsigned n, unsigned log2size, st_quadmesh *mesh)
{
    if (st_quadmesh_cube(n, 1234, mesh, NULL))
        return NULL;
    st_quadmesh_opts o = {.nchan = 4, .dtype = ST_DT_U8, .has_alpha = 1,
                          .ulog2 = (uint8_t)log2size, .vlog2 = (uint8_t)log2size,
                          .bake = bake_cheap};
    st_set *s = NULL;
    st_error e;
    if (st_quadmesh_build(mesh, &o, &s, &e)) {
        fprintf(stderr, "build: %s\n", e.msg);
        return NULL;
    }
    return s;
}

typedef struct bench_ctx {
    st_query *q[4];    /* per filter footprint */
    float *out, *cov;
    uint8_t *st;
} bench_ctx;

static void footprint(st_query *q, unsigned filter, float W, float ang)
{
    float c = cosf(ang), s = sinf(ang);
    float major = filter == ST_FILTER_ANISO ? 8.0f : filter == ST_FILTER_TRILINEAR ? 1.5f : 1.0f;
    float minor = filter == ST_FILTER_ANISO ? 1.0f : major;
    q->dudx = major * c / W;
    q->dvdx = major * s / W;
    q->dudy = -minor * s / W;
    q->dvdy = minor * c / W;
}

static void make_queries(const st_set *s, int coherent, st_query *q[4])
{
    uint32_t rng = 99;
    uint32_t f = 0, i = 0, j = 0;
    for (uint32_t k = 0; k < NQ; k++) {
        st_query b;
        float W;
        if (coherent) {
            const st_face *F = &s->faces[f];
            W = (float)F->w;
            b.face = f;
            b.u = ((float)i + 0.3f) / W;
            b.v = ((float)j + 0.6f) / (float)F->h;
            if (++i == F->w) {
                i = 0;
                if (++j == F->h) {
                    j = 0;
                    f = (f + 1) % s->info.nfaces;
                }
            }
        } else {
            b.face = (uint32_t)(cf_rand(&rng) * s->info.nfaces) % s->info.nfaces;
            b.u = cf_rand(&rng);
            b.v = cf_rand(&rng);
            W = (float)s->faces[b.face].w;
        }
        float ang = coherent ? 0.3f : 6.2831853f * cf_rand(&rng);
        for (unsigned fl = 0; fl < 4; fl++) {
            q[fl][k] = b;
            footprint(&q[fl][k], fl, W, ang);
        }
    }
}

static double run_one(const st_set *s, const st_query *q, unsigned mode, unsigned filter,
                      double secs, bench_ctx *c)
{
    st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)filter, .max_aniso = 16};
    size_t done = 0, pos = 0;
    double t0 = cpu_now(), t;
    do {
        size_t n = BATCH;
        if (pos + n > NQ)
            pos = 0;
        st_sample_batch(s, &o, q + pos, n, c->out, c->cov, c->st);
        pos += n;
        done += n;
    } while ((t = cpu_now() - t0) < secs);
    return (double)done / t / 1e6;
}

/* Plain C bilinear over one 2048^2 RGBA8 array, clamp to edge: the floor of what any
 * per-query sampler can reach on this machine. */
static double run_plain(int coherent, int reps, double secs)
{
    enum { S = 2048 };
    uint8_t *img = malloc((size_t)S * S * 4);
    float *uv = malloc(NQ * 2 * sizeof *uv);
    float *out = malloc(BATCH * 4 * sizeof *out);
    uint32_t rng = 5;
    for (size_t i = 0; i < (size_t)S * S * 4; i++)
        img[i] = (uint8_t)(st_quad_hash(1, (uint32_t)i) & 255);
    for (uint32_t k = 0; k < NQ; k++) {
        if (coherent) {
            uv[2 * k] = ((float)(k % S) + 0.3f) / S;
            uv[2 * k + 1] = ((float)((k / S) % S) + 0.6f) / S;
        } else {
            uv[2 * k] = cf_rand(&rng);
            uv[2 * k + 1] = cf_rand(&rng);
        }
    }
    double r[16];
    float sink = 0;
    for (int rep = 0; rep < reps; rep++) {
        size_t done = 0, pos = 0;
        double t0 = cpu_now(), t;
        do {
            if (pos + BATCH > NQ)
                pos = 0;
            for (size_t k = 0; k < BATCH; k++) {
                float x = uv[2 * (pos + k)] * S - 0.5f, y = uv[2 * (pos + k) + 1] * S - 0.5f;
                int i0 = (int)floorf(x), j0 = (int)floorf(y);
                float fx = x - i0, fy = y - j0;
                int i1 = i0 + 1, j1 = j0 + 1;
                i0 = i0 < 0 ? 0 : i0 > S - 1 ? S - 1 : i0;
                i1 = i1 < 0 ? 0 : i1 > S - 1 ? S - 1 : i1;
                j0 = j0 < 0 ? 0 : j0 > S - 1 ? S - 1 : j0;
                j1 = j1 < 0 ? 0 : j1 > S - 1 ? S - 1 : j1;
                const uint8_t *p00 = img + ((size_t)j0 * S + i0) * 4,
                              *p10 = img + ((size_t)j0 * S + i1) * 4,
                              *p01 = img + ((size_t)j1 * S + i0) * 4,
                              *p11 = img + ((size_t)j1 * S + i1) * 4;
                for (int c = 0; c < 4; c++) {
                    float a = p00[c] + fx * (p10[c] - p00[c]);
                    float b = p01[c] + fx * (p11[c] - p01[c]);
                    out[4 * k + c] = (a + fy * (b - a)) * (1.0f / 255);
                }
            }
            sink += out[0];
            pos += BATCH;
            done += BATCH;
        } while ((t = cpu_now() - t0) < secs);
        r[rep] = (double)done / t / 1e6;
    }
    if (sink == 12345.0f)
        printf("#\n");
    free(img);
    free(uv);
    free(out);
    return st_bench_median(r, reps);
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    double big_mb = 400, secs = 0.08;
    int reps = 7, no_big = 0, no_atlas = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--big-mb") && i + 1 < argc)
            big_mb = atof(argv[++i]);
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--secs") && i + 1 < argc)
            secs = atof(argv[++i]);
        else if (!strcmp(argv[i], "--no-big"))
            no_big = 1;
        else if (!strcmp(argv[i], "--no-atlas"))
            no_atlas = 1;
        else {
            fprintf(stderr, "usage: %s [--json PATH] [--big-mb N] [--no-big] [--no-atlas] [--reps N] "
                            "[--secs S]\n", argv[0]);
            return 2;
        }
    }
    if (reps < 1 || reps > 15)
        reps = 3;

    bench_ctx c;
    for (int f = 0; f < 4; f++)
        c.q[f] = malloc(NQ * sizeof(st_query));
    c.out = malloc(BATCH * 4 * sizeof(float));
    c.cov = malloc(BATCH * sizeof(float));
    c.st = malloc(BATCH);

    /* (a) cache-resident: 6 faces of 64 x 64 RGBA8; (b) a cube of 256 x 256 RGBA8 faces,
     * subdivided until the texels reach about big_mb; (c) the duck atlas (SEAMTEX_DATA) */
    unsigned big_n = (unsigned)ceil(sqrt(big_mb * 1e6 / (6.0 * 65536 * 4 * 4.0 / 3)));
    struct { const char *name; unsigned n, lg; } sets[3] = {{"cache", 1, 6}, {"big", big_n, 8},
                                                            {"atlas", 0, 0}};
    const char *mname[3] = {"discard", "traverse", "clamp"};
    const char *fname[4] = {"point", "bilinear", "trilinear", "aniso8"};
    double res[3][2][3][4], best[3][2][3][4], rat[3][2][4];
    double setmb[3] = {0, 0, 0};
    memset(res, 0, sizeof res);
    memset(rat, 0, sizeof rat);
    memset(best, 0, sizeof best);

    char load[64] = "?";
    FILE *la = fopen("/proc/loadavg", "r");
    if (la) {
        if (!fgets(load, sizeof load, la))
            strcpy(load, "?");
        load[strcspn(load, "\n")] = 0;
        fclose(la);
    }
    printf("bench_sample: single thread, M queries per CPU-second (median of %d x %.2fs), RGBA8; "
           "load at start: %s\n", reps, secs, load);
    for (int si = 0; si < 3; si++) {
        if ((si == 1 && no_big) || (si == 2 && no_atlas))
            continue;
        st_quadmesh mesh;
        memset(&mesh, 0, sizeof mesh);
        double t0 = st_bench_now();
        st_set *s = NULL;
        if (si < 2) {
            s = build_set(sets[si].n, sets[si].lg, &mesh);
        } else {
            char obj[1024], png[1024];
            st_import_opts io;
            st_error e;
            st_import_opts_init(&io);
            io.texture_path = png;
            if (st_test_data_path(obj, sizeof obj, "meshes/duck/Duck.obj") ||
                st_test_data_path(png, sizeof png, "meshes/duck/DuckCM.png")) {
                printf("\nset atlas: no shared data (SEAMTEX_DATA), skipped\n");
                continue;
            }
            if (st_import_file(obj, &io, &s, &e) != 0)
                fprintf(stderr, "atlas: %s\n", e.msg);
        }
        if (!s) {
            fprintf(stderr, "could not build set %s\n", sets[si].name);
            return 1;
        }
        setmb[si] = (double)st_set_memory(s) / 1e6;
        printf("\nset %-5s: %u faces of %ux%u, %.1f MB (built in %.1fs)\n", sets[si].name,
               s->info.nfaces, s->faces[0].w, s->faces[0].h, setmb[si], st_bench_now() - t0);
        for (int ord = 0; ord < 2; ord++) {
            make_queries(s, ord, c.q);
            printf("  %-8s %-9s %9s %9s %9s %9s\n", ord ? "coherent" : "random", "",
                   fname[0], fname[1], fname[2], fname[3]);
            /* modes interleaved inside each repetition, so that a disturbance hits all
             * three; the ratio is the median of the per-repetition ratios */
            double ratio[4];
            for (unsigned f = 0; f < 4; f++) {
                double r[3][16], rr[16];
                for (int rep = 0; rep < reps; rep++) {
                    for (unsigned m = 0; m < 3; m++)
                        r[m][rep] = run_one(s, c.q[f], m, f, secs, &c);
                    rr[rep] = r[0][rep] / r[1][rep];
                }
                for (unsigned m = 0; m < 3; m++)
                    res[si][ord][m][f] = st_bench_median(r[m], reps); /* sorts r[m] */
                for (unsigned m = 0; m < 3; m++)
                    best[si][ord][m][f] = r[m][reps - 1];
                ratio[f] = rat[si][ord][f] = st_bench_median(rr, reps);
            }
            for (unsigned m = 0; m < 3; m++) {
                printf("  %-8s %-9s", "", mname[m]);
                for (unsigned f = 0; f < 4; f++)
                    printf(" %9.2f", res[si][ord][m][f]);
                printf("\n");
            }
            printf("  %-8s %-9s", "", "T/D cost");
            for (unsigned f = 0; f < 4; f++)
                printf(" %9.3f", ratio[f]);
            printf("\n");
            fflush(stdout);
        }
        st_set_free(s);
        if (si < 2)
            st_quadmesh_free(&mesh);
    }
    double plain[2];
    for (int ord = 0; ord < 2; ord++)
        plain[ord] = run_plain(ord, reps, secs);
    printf("\nbaseline: plain C bilinear loop, one 2048^2 RGBA8 array: random %.2f, coherent "
           "%.2f M/s\n", plain[0], plain[1]);
    printf("targets: discard bilinear random cache >= 30 M/s: %.2f; traverse/discard cost "
           "(bilinear, random, cache) <= 1.25: %.3f; aniso 8:1 >= 4 M/s: %.2f\n",
           res[0][0][0][1], rat[0][0][1], res[0][0][0][3]);

    if (json) {
        FILE *fp = fopen(json, "w");
        if (!fp) {
            perror(json);
            return 1;
        }
        fprintf(fp, "{\n  \"bench\": \"sample\",\n  \"unit\": \"M queries per second of thread CPU time, "
                    "single thread\",\n");
        fprintf(fp, "  \"loadavg_at_start\": \"%s\",\n", load);
        fprintf(fp, "  \"reps\": %d, \"secs_per_run\": %.2f, \"mqps\": \"median of the reps\", "
                    "\"best\": \"fastest rep\",\n", reps, secs);
        fprintf(fp, "  \"footprints\": {\"point\": \"1 texel\", \"bilinear\": \"1 texel\", "
                    "\"trilinear\": \"1.5 texels\", \"aniso8\": \"8 x 1 texels\"},\n");
        fprintf(fp, "  \"sets\": {\"cache\": %.2f, \"big\": %.2f, \"atlas\": %.2f},\n", setmb[0],
                setmb[1], setmb[2]);
        fprintf(fp, "  \"results\": [\n");
        int first = 1;
        for (int si = 0; si < 3; si++)
            for (int ord = 0; ord < 2; ord++)
                for (int m = 0; m < 3; m++)
                    for (int f = 0; f < 4; f++) {
                        if (res[si][ord][m][f] <= 0)
                            continue;
                        fprintf(fp, "%s    {\"set\": \"%s\", \"order\": \"%s\", \"mode\": \"%s\", "
                                    "\"filter\": \"%s\", \"mqps\": %.3f, \"best\": %.3f}",
                                first ? "" : ",\n", sets[si].name, ord ? "coherent" : "random",
                                mname[m], fname[f], res[si][ord][m][f], best[si][ord][m][f]);
                        first = 0;
                    }
        fprintf(fp, "\n  ],\n  \"traverse_over_discard_cost\": [\n");
        first = 1;
        for (int si = 0; si < 3; si++)
            for (int ord = 0; ord < 2; ord++)
                for (int f = 0; f < 4; f++) {
                    if (res[si][ord][1][f] <= 0)
                        continue;
                    fprintf(fp, "%s    {\"set\": \"%s\", \"order\": \"%s\", \"filter\": \"%s\", "
                                "\"ratio\": %.4f}",
                            first ? "" : ",\n", sets[si].name, ord ? "coherent" : "random",
                            fname[f], rat[si][ord][f]);
                    first = 0;
                }
        fprintf(fp, "\n  ],\n  \"baseline_plain_bilinear_2048_rgba8\": {\"random\": %.3f, "
                    "\"coherent\": %.3f}\n}\n", plain[0], plain[1]);
        fclose(fp);
    }
    for (int f = 0; f < 4; f++)
        free(c.q[f]);
    free(c.out);
    free(c.cov);
    free(c.st);
    return 0;
}
