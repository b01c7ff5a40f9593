/* tests/bench/bench_ptex.c - Ptex file import and Ptex-filter sampling throughput on every
 * shared .ptx file (SEAMTEX_DATA: every *.ptx under ptex-ref/ and ptx/, found by walking the
 * folders, so a file added there is covered).
 *
 * Import: each file imported --reps times (default 9) with st_ptex_read_file - the whole
 * import, file read included, file in the page cache - in a new process each time (this
 * binary again with --import-one: a fresh heap - the allocator started, nothing else - so
 * the arena's pages are faulted in, as on a daemon's first load and as Ptex's figures were
 * taken) and, before those, again in this process (warm heap; before any fork, whose
 * copy-on-write would make every page written again fault). Medians of wall and CPU time; MB/s and faces/s from the fresh CPU time (the 2-core
 * machine is shared, so wall time mostly measures the other jobs); bytes per level-0 texel
 * right after import; "table cpu": the first Ptex-filter call, which builds the resolution
 * table (ptexres.h). A file the importer refuses (a triangle mesh before it was supported)
 * is listed with the reason and left out of the sampling tables.
 *
 * Sampling: one thread, thread CPU time, batches of 4096 queries, each cell the median of
 * --reps-sample runs (default 3) of at least --min-ms (default 15) ms each. Per file, Ptex
 * filter, footprint (--fp, default 0.25,4,16 level-0 texels of the face queried: dudx =
 * fp / width, dvdy = fp / height, isotropic, axis-aligned) and query order (--order,
 * default both): "random" = uniform face and uv; "coherent" = the faces in turn, on each a
 * 16 x 16 raster of queries one footprint apart (steps capped at 1/16 of the face), like the
 * pixels of a render. Mode Traverse; --modes traverse,discard,clamp adds the others. --coverage
 * also asks for the coverage array (the kept weight over the kernel's: what a Discard user
 * reads; without it the filters skip computing it). One
 * untimed batch first builds the table. Tables in the shape of issue 17: file x filter,
 * M queries/s, one table per (mode, order, footprint).
 *
 * Query file (--queries FILE --ptx FILE): lines `faceid u v uw1 vw1 uw2 vw2 filter` as in
 * SEAMTEX_DATA/ptex-ref/ref_*.txt (anything after the filter name, such as "-> values", is
 * read as the expected values); times exactly those queries in Traverse (or --modes' first
 * mode): per filter, its lines in file order as one batch, repeated for at least --min-ms,
 * median of --reps-sample; prints M queries/s per filter and overall, and when the lines
 * carry values the share within the reference tolerance (1e-4, half an 8-bit step for u8).
 * --dump OUT writes every line's outputs (%.9g) in file order, to diff two builds or
 * another implementation. An outside Ptex harness that calls PtexFilter::eval on the same
 * lines, grouped the same way, gives the ratio to Ptex directly.
 *
 * Usage: bench_ptex [--json PATH] [--reps N] [--import-only | --sample-only]
 *                   [--files SUBSTR[,SUBSTR..]]   (=NAME: that file only) [--filters point,bilinear,..]
 *                   [--fp 0.25,4,16] [--order random|coherent|both]
 *                   [--modes traverse[,discard][,clamp]] [--coverage]
 *                   [--min-ms MS] [--reps-sample N]
 *                   [--batches N]   (exactly N timed batches per cell, one run: a fixed
 *                                    amount of work, for instruction counts under callgrind)
 *                   [--emit-queries DIR]   (write every cell's queries as query files
 *                                           DIR/<file>_<order>_fp<fp>.txt, one block of 4096
 *                                           lines per filter, and DIR/index.txt: "<query
 *                                           file> <.ptx under SEAMTEX_DATA> <its --files
 *                                           name>" per line; time
 *                                           nothing: for a comparison with another
 *                                           implementation through --queries on both sides)
 *        bench_ptex --queries REF.txt --ptx FILE.ptx [--dump OUT] [--json PATH] [...]
 * Filter options, for every query of the run (either form; defaults as Ptex's reference
 * generator): [--sharpness S] (the bicubic filter, 0..1, default 0: the B-spline) [--width W]
 * (footprint multiplier, default 0 = 1) [--blur B] (default 0) [--lerp] (Ptex's lerp: the
 * gaussian and bicubic family blend toward the next lower resolution; default off).
 * tests/bench/ptexcmp/ptexq takes the same options with the same meaning on Ptex's side.
 * To compare two builds, run their binaries alternately (A B A B) and take the medians. */
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
#include "../common/ptexref.h"
#include "../common/testdata.h"
#include "../common/benchstat.h"

#define MAXFILES 64
#define NFILT 8
#define MAXFP 8
enum { NQ = 4096, TILE = 16 };

/* thread CPU time: the machine is shared */
static double now(void) { return st_bench_clock(CLOCK_THREAD_CPUTIME_ID); }

#define fnames st_ptexref_filters   /* NFILT of them, in ST_FILTER_PTEX_POINT.. order */
static const char *mnames[3] = {"discard", "traverse", "clamp"}; /* st_mode order */
static const char *dtnames[4] = {"u8", "u16", "half", "f32"};     /* st_dtype order */

typedef struct opts {
    const char *json, *files, *queries, *ptx, *dump;
    const char *emit;            /* --emit-queries DIR: write the cells' queries, time nothing */
    int reps, reps_sample, import_only, sample_only, order_mask, mode_mask;
    int coverage;                /* --coverage: ask for the coverage array too (Discard's use) */
    long batches;                /* --batches: exactly this many timed batches, one run */
    unsigned filter_mask;
    float sharpness, width, blur; /* the filter options of every query (st_sample_opts) */
    int lerp;                     /* --lerp: st_sample_opts.lerp = 1 */
    double min_s;
    int nfp;
    float fp[MAXFP];
} opts;

/* ---- the shared files ------------------------------------------------------------------- */

typedef struct ptxfile {
    char rel[512];               /* path under the data folder */
    char name[64];               /* short unique name */
} ptxfile;

/* The file name without .ptx; folder/name when another file has the same name. */
static void name_files(ptxfile *fl, int n)
{
    for (int i = 0; i < n; i++) {
        const char *base = strrchr(fl[i].rel, '/') + 1;
        int dup = 0;
        for (int j = 0; j < n; j++)
            dup |= j != i && !strcmp(base, strrchr(fl[j].rel, '/') + 1);
        const char *p = base;
        if (dup) {
            p = base - 1;
            while (p > fl[i].rel && p[-1] != '/')
                p--;
        }
        snprintf(fl[i].name, sizeof fl[i].name, "%.*s", (int)(strlen(p) - 4), p);
    }
}

static int wanted(const opts *op, const char *name)
{
    if (!op->files)
        return 1;
    char buf[512];
    snprintf(buf, sizeof buf, "%s", op->files);
    for (char *t = strtok(buf, ","); t; t = strtok(NULL, ","))
        if (t[0] == '=' ? !strcmp(name, t + 1) : strstr(name, t) != NULL)
            return 1;
    return 0;
}

/* ---- import ----------------------------------------------------------------------------- */

/* --import-one PATH: one import in this (new) process; prints wall and CPU seconds. The
 * allocator's own start (glibc's heap set-up on the first malloc: ~0.1 ms of brk, getrandom
 * and a first page) happens before the clock, as it has in a C++ harness by main (Ptex's,
 * tests/bench/ptexcmp/ptexopen.cpp) and in a daemon long before its first import. */
static int import_one(const char *path)
{
    st_set *s = NULL;
    st_error e;
    {
        void *volatile warm = malloc(1); /* volatile: kept, not folded with the free */
        free(warm);
    }
    double w0 = st_bench_clock(CLOCK_MONOTONIC);
    double c0 = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID);
    int rc = st_ptex_read_file(path, 0, &s, &e);
    double w = st_bench_clock(CLOCK_MONOTONIC) - w0;
    double c = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID) - c0;
    if (rc) {
        fprintf(stderr, "%s: %s\n", path, e.msg);
        return 1;
    }
    printf("%.9f %.9f\n", w, c);
    st_set_free(s);
    return 0;
}

/* One import in a new process (this binary run again with --import-one). Process start-up
 * is not timed. Wall and CPU seconds. */
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

/* Imports one file reps times (fresh and warm) and prints its row; returns the last set
 * (NULL when the importer refuses the file: printed with the reason). */
static st_set *import_row(const opts *op, const char *path, const char *name, FILE *js,
                          int *jfirst)
{
    struct stat sb;
    if (stat(path, &sb))
        return NULL;
    double fwall[99], fcpu[99], wcpu[99];
    st_set *s = NULL;
    st_error e;
    /* the warm imports first: after a fork every page of this process is copy-on-write,
     * and the warm figure would pay a fault on each page it writes again */
    for (int r = 0; r < op->reps; r++) {
        double c0 = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID);
        if (st_ptex_read_file(path, 0, &s, &e)) {
            printf("%-22s refused: %s\n", name, e.msg);
            return NULL;
        }
        wcpu[r] = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID) - c0;
        if (r + 1 < op->reps)
            st_set_free(s);
    }
    for (int r = 0; r < op->reps && !op->sample_only; r++)
        if (import_fresh(path, &fwall[r], &fcpu[r])) {
            printf("%s: import in a child process failed\n", name);
            st_set_free(s);
            return NULL;
        }
    if (op->sample_only)
        return s;
    double fw = st_bench_median(fwall, op->reps), fc = st_bench_median(fcpu, op->reps);
    double wc = st_bench_median(wcpu, op->reps);
    double mb = (double)sb.st_size / 1e6, texels = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        texels += s->faces[f].flags & ST_FACE_CONSTANT ? 1.0
                                                       : (double)s->faces[f].w * s->faces[f].h;
    double bpt = (double)st_set_memory(s) / texels;
    /* the first Ptex-filter call builds the resolution table */
    st_query q0 = {.face = 0, .u = 0.5f, .v = 0.5f, .dudx = 0.01f, .dvdy = 0.01f};
    st_sample_opts o0 = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_PTEX_BILINEAR};
    float out0[4];
    double t0 = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID);
    st_ptexfilter_batch(s, &o0, &q0, 1, out0, NULL, NULL);
    double tb = st_bench_clock(CLOCK_PROCESS_CPUTIME_ID) - t0;
    char ty[16];
    snprintf(ty, sizeof ty, "%sx%u", dtnames[s->info.dtype & 3], s->info.nchan);
    printf("%-22s %-6s %6.2f %6u %9.2f %9.2f %9.2f %8.1f %10.0f %8.2f %9.2f\n", name, ty, mb,
           s->info.nfaces, fw * 1e3, fc * 1e3, wc * 1e3, mb / fc, s->info.nfaces / fc, bpt,
           tb * 1e3);
    if (js) {
        fprintf(js, "%s{\"file\":\"%s\",\"type\":\"%s\",\"mb\":%.4f,\"faces\":%u,"
                "\"fresh_wall_ms\":%.3f,\"fresh_cpu_ms\":%.3f,\"warm_cpu_ms\":%.3f,"
                "\"mb_per_s\":%.2f,\"faces_per_s\":%.0f,\"bytes_per_texel\":%.3f,"
                "\"table_cpu_ms\":%.3f}",
                *jfirst ? "" : ",", name, ty, mb, s->info.nfaces, fw * 1e3, fc * 1e3, wc * 1e3,
                mb / fc, s->info.nfaces / fc, bpt, tb * 1e3);
        *jfirst = 0;
    }
    return s;
}

/* ---- sampling --------------------------------------------------------------------------- */

static uint32_t rnd(uint32_t *x)
{
    *x = *x * 1664525u + 1013904223u;
    return *x >> 8;
}
static float rndf(uint32_t *x) { return (float)rnd(x) / 16777216.0f; }

/* NQ queries of footprint fp level-0 texels, random (coherent = 0) or face by face in 16 x 16
 * rasters one footprint apart (coherent = 1). */
static void make_queries(const st_set *s, float fp, int coherent, st_query *q)
{
    uint32_t x = 42, nf = s->info.nfaces, f = 0;
    for (int k = 0; k < NQ;) {
        if (!coherent) {
            f = rnd(&x) % nf;
            const st_face *F = &s->faces[f];
            q[k] = (st_query){.face = f, .u = rndf(&x), .v = rndf(&x),
                              .dudx = fp / (float)F->w, .dvdy = fp / (float)F->h};
            k++;
            continue;
        }
        const st_face *F = &s->faces[f];
        float du = fp / (float)F->w, dv = fp / (float)F->h;
        float su = du < 1.0f / TILE ? du : 1.0f / TILE, sv = dv < 1.0f / TILE ? dv : 1.0f / TILE;
        float u0 = rndf(&x) * (1.0f - TILE * su), v0 = rndf(&x) * (1.0f - TILE * sv);
        for (int j = 0; j < TILE && k < NQ; j++)
            for (int i = 0; i < TILE && k < NQ; i++, k++)
                q[k] = (st_query){.face = f, .u = u0 + ((float)i + 0.5f) * su,
                                  .v = v0 + ((float)j + 0.5f) * sv, .dudx = du, .dvdy = dv};
        f = (f + 1) % nf;
    }
}

/* M queries/s of n queries q with filter flt and mode m: median of reps runs of whole
 * batches lasting at least min_s each. */
static double time_batch(const opts *op, const st_set *s, int flt, int mode, const st_query *q,
                         size_t n, float *out)
{
    st_sample_opts o = {.mode = (uint8_t)mode, .filter = (uint8_t)(ST_FILTER_PTEX_POINT + flt),
                        .sharpness = op->sharpness, .width = op->width, .blur = op->blur,
                        .lerp = (uint8_t)op->lerp};
    static float covbuf[NQ];
    float *cov = op->coverage && n <= NQ ? covbuf : NULL;
    double t[99];
    long iters = 1;
    /* find a batch count that lasts min_s (the first, untimed call builds the table) */
    st_ptexfilter_batch(s, &o, q, n, out, cov, NULL);
    if (op->batches > 0) { /* a fixed amount of work, for instruction counts (callgrind) */
        double t0 = now();
        for (long k = 0; k < op->batches; k++)
            st_ptexfilter_batch(s, &o, q, n, out, cov, NULL);
        double d = now() - t0;
        return (double)n * (double)op->batches / (d > 0 ? d : 1e-9) / 1e6;
    }
    for (;;) {
        double t0 = now();
        for (long k = 0; k < iters; k++)
            st_ptexfilter_batch(s, &o, q, n, out, cov, NULL);
        double d = now() - t0;
        if (d >= op->min_s || iters > (1L << 30)) {
            t[0] = d;
            break;
        }
        iters = d <= 0 ? iters * 8 : (long)((double)iters * op->min_s * 1.2 / d) + 1;
    }
    for (int r = 1; r < op->reps_sample; r++) {
        double t0 = now();
        for (long k = 0; k < iters; k++)
            st_ptexfilter_batch(s, &o, q, n, out, cov, NULL);
        t[r] = now() - t0;
    }
    return (double)n * (double)iters / st_bench_median(t, op->reps_sample) / 1e6;
}

/* --emit-queries: the cell's queries for every filter asked, as query-file lines
 * (DIR/<file>_<order>_fp<fp>.txt), and the file's path and name in DIR/index.txt; 0 or -1 */
static int emit_cell(const opts *op, const ptxfile *pf, int ord, float fp, const st_query *q)
{
    char qf[256], path[1024];
    snprintf(qf, sizeof qf, "%s_%s_fp%g.txt", pf->name, ord ? "coherent" : "random",
             (double)fp);
    for (char *c = qf; *c; c++)
        if (*c == '/')
            *c = '-';                /* folder/name file names */
    snprintf(path, sizeof path, "%s/%s", op->emit, qf);
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    for (int flt = 0; flt < NFILT; flt++)
        if (op->filter_mask >> flt & 1)
            for (int k = 0; k < NQ; k++)
                fprintf(f, "%u %.9g %.9g %.9g 0 0 %.9g %s\n", q[k].face, (double)q[k].u,
                        (double)q[k].v, (double)q[k].dudx, (double)q[k].dvdy, fnames[flt]);
    int bad = ferror(f) | fclose(f);
    snprintf(path, sizeof path, "%s/index.txt", op->emit);
    FILE *ix = fopen(path, "a");
    if (!ix)
        return -1;
    fprintf(ix, "%s %s %s\n", qf, pf->rel, pf->name);
    bad |= ferror(ix) | fclose(ix);
    return bad ? -1 : 0;
}

static void sample_tables(const opts *op, ptxfile *fl, st_set **sets, int nfl, FILE *js)
{
    static st_query q[NQ];
    static float out[NQ * 4];
    int first = 1;
    for (int m = 0; m < 3; m++) {
        if (!(op->mode_mask >> m & 1))
            continue;
        for (int ord = 0; ord < 2; ord++) {
            if (!(op->order_mask >> ord & 1))
                continue;
            for (int fi = 0; fi < op->nfp; fi++) {
                printf("\nM queries/s, %s, %s order, footprint %g texels%s\n%-22s %-6s",
                       mnames[m], ord ? "coherent" : "random", (double)op->fp[fi],
                       op->coverage ? ", coverage asked" : "", "file", "type");
                for (int f = 0; f < NFILT; f++)
                    if (op->filter_mask >> f & 1)
                        printf(" %10s", fnames[f]);
                printf("\n");
                for (int i = 0; i < nfl; i++) {
                    st_set *s = sets[i];
                    if (!s)
                        continue;
                    char ty[16];
                    snprintf(ty, sizeof ty, "%sx%u", dtnames[s->info.dtype & 3], s->info.nchan);
                    printf("%-22s %-6s", fl[i].name, ty);
                    fflush(stdout);
                    make_queries(s, op->fp[fi], ord, q);
                    if (op->emit) {
                        int rc = m == 0 || !(op->mode_mask & ((1 << m) - 1))
                                     ? emit_cell(op, &fl[i], ord, op->fp[fi], q) : 0;
                        printf(" %s\n", rc ? "could not write its queries" : "queries written");
                        continue;
                    }
                    for (int f = 0; f < NFILT; f++) {
                        if (!(op->filter_mask >> f & 1))
                            continue;
                        double mq = time_batch(op, s, f, m, q, NQ, out);
                        printf(" %10.2f", mq);
                        fflush(stdout);
                        if (js) {
                            fprintf(js, "%s{\"file\":\"%s\",\"type\":\"%s\",\"filter\":\"%s\","
                                    "\"mode\":\"%s\",\"order\":\"%s\",\"footprint\":%g,"
                                    "\"coverage\":%s,\"mqps\":%.4f}",
                                    first ? "" : ",", fl[i].name, ty, fnames[f], mnames[m],
                                    ord ? "coherent" : "random", (double)op->fp[fi],
                                    op->coverage ? "true" : "false", mq);
                            first = 0;
                        }
                    }
                    printf("\n");
                }
            }
        }
    }
}

/* ---- query file ------------------------------------------------------------------------- */

typedef struct refline {
    st_query q;
    int filter, nref;            /* filter index; expected values given (0..4) */
    float ref[4];
} refline;

static int run_query_file(const opts *op, const char *dd)
{
    (void)dd;
    FILE *fp = fopen(op->queries, "r");
    if (!fp) {
        fprintf(stderr, "%s: cannot open\n", op->queries);
        return 1;
    }
    size_t cap = 1024, n = 0;
    refline *L = malloc(cap * sizeof *L);
    char line[1024];
    int lineno = 0;
    while (L && fgets(line, sizeof line, fp)) {
        lineno++;
        st_refline pl;
        int pr = st_refline_parse(line, &pl);
        if (pr == 0)
            continue;
        if (pr < 0) {
            fprintf(stderr, "%s:%d: expected `faceid u v uw1 vw1 uw2 vw2 filter`\n",
                    op->queries, lineno);
            fclose(fp);
            free(L);
            return 1;
        }
        refline r = {{pl.face, pl.u, pl.v, pl.dudx, pl.dvdx, pl.dudy, pl.dvdy}, pl.filter, pl.nref,
                     {pl.ref[0], pl.ref[1], pl.ref[2], pl.ref[3]}};
        if (n == cap) {
            refline *nl = realloc(L, 2 * cap * sizeof *L);
            if (!nl)
                break;
            L = nl;
            cap *= 2;
        }
        L[n++] = r;
    }
    fclose(fp);
    if (!L) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    st_set *s = NULL;
    st_error e;
    if (st_ptex_read_file(op->ptx, 0, &s, &e)) {
        fprintf(stderr, "%s: %s\n", op->ptx, e.msg);
        free(L);
        return 1;
    }
    unsigned nc = s->info.nchan;
    for (size_t i = 0; i < n; i++)
        if (L[i].q.face >= s->info.nfaces) {
            fprintf(stderr, "%s: query %zu names face %u of %u\n", op->queries, i + 1,
                    L[i].q.face, s->info.nfaces);
            st_set_free(s);
            free(L);
            return 1;
        }
    int mode = op->mode_mask & 2 ? ST_MODE_TRAVERSE : op->mode_mask & 1 ? ST_MODE_DISCARD
                                                                        : ST_MODE_CLAMP;
    st_query *q = malloc((n ? n : 1) * sizeof *q);
    float *out = malloc((n ? n : 1) * 4 * sizeof *out), *res = calloc((n ? n : 1) * 4, sizeof *res);
    size_t *idx = malloc((n ? n : 1) * sizeof *idx);
    if (!q || !out || !res || !idx) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    float tol = s->info.dtype == ST_DT_U8 ? 0.5f / 255.0f : 1e-4f;
    printf("%s on %s, %s, %zu queries; per filter its lines in file order as one batch, "
           "median of %d runs of >= %.0f ms (thread CPU time)\n",
           op->queries, op->ptx, mnames[mode], n, op->reps_sample, op->min_s * 1e3);
    if (op->sharpness > 0 || op->width > 0 || op->blur > 0 || op->lerp)
        printf("filter options: sharpness %g, width %g, blur %g%s\n", (double)op->sharpness,
               (double)(op->width > 0 ? op->width : 1.0f), (double)op->blur,
               op->lerp ? ", lerp" : "");
    printf("%-10s %8s %12s %10s %10s\n", "filter", "queries", "M queries/s", "ns/query",
           "match%");
    FILE *js = op->json ? fopen(op->json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"ptex_queries\",\"queries\":\"%s\",\"ptx\":\"%s\","
                "\"mode\":\"%s\",\"filters\":[", op->queries, op->ptx, mnames[mode]);
    double total_s = 0;
    size_t total_n = 0;
    int jfirst = 1;
    for (int f = 0; f < NFILT; f++) {
        size_t m = 0;
        for (size_t i = 0; i < n; i++)
            if (L[i].filter == f) {
                idx[m] = i;
                q[m++] = L[i].q;
            }
        if (!m)
            continue;
        double mq = time_batch(op, s, f, mode, q, m, out);
        size_t ok = 0, withref = 0;
        for (size_t k = 0; k < m; k++) {
            const refline *r = &L[idx[k]];
            memcpy(res + idx[k] * 4, out + k * nc, nc * sizeof *out);
            if (!r->nref)
                continue;
            withref++;
            int good = 1;
            for (int c = 0; c < r->nref && c < (int)nc; c++)
                good &= fabsf(out[k * nc + (unsigned)c] - r->ref[c]) <= tol;
            ok += (size_t)good;
        }
        total_s += (double)m / (mq * 1e6);
        total_n += m;
        char match[16] = "-";
        if (withref)
            snprintf(match, sizeof match, "%.2f", 100.0 * (double)ok / (double)withref);
        printf("%-10s %8zu %12.2f %10.1f %10s\n", fnames[f], m, mq, 1e3 / mq, match);
        if (js) {
            fprintf(js, "%s{\"filter\":\"%s\",\"queries\":%zu,\"mqps\":%.4f,\"matched\":%zu,"
                    "\"with_reference\":%zu}", jfirst ? "" : ",", fnames[f], m, mq, ok, withref);
            jfirst = 0;
        }
    }
    double all = total_n ? (double)total_n / total_s / 1e6 : 0;
    printf("%-10s %8zu %12.2f %10.1f\n", "all", total_n, all, total_n ? 1e3 / all : 0.0);
    if (js) {
        fprintf(js, "],\"all_mqps\":%.4f}\n", all);
        fclose(js);
    }
    int rc = 0;
    if (op->dump) {
        FILE *d = fopen(op->dump, "w");
        if (!d) {
            fprintf(stderr, "%s: cannot write\n", op->dump);
            rc = 1;
        } else {
            for (size_t i = 0; i < n; i++) {
                for (unsigned c = 0; c < nc; c++)
                    fprintf(d, "%s%.9g", c ? " " : "", (double)res[i * 4 + c]);
                fprintf(d, "\n");
            }
            rc = fclose(d) ? 1 : 0;
        }
    }
    free(q);
    free(out);
    free(res);
    free(idx);
    free(L);
    st_set_free(s);
    return rc;
}

/* ---- main ------------------------------------------------------------------------------- */

static int parse_list(const char *arg, const char *const *names, int nnames)
{
    char buf[256];
    snprintf(buf, sizeof buf, "%s", arg);
    int mask = 0;
    for (char *t = strtok(buf, ","); t; t = strtok(NULL, ",")) {
        int k = 0;
        while (k < nnames && strcmp(t, names[k]))
            k++;
        if (k == nnames)
            return -1;
        mask |= 1 << k;
    }
    return mask;
}

static int usage(void)
{
    fprintf(stderr, "usage: bench_ptex [--json PATH] [--reps N] [--import-only | --sample-only]"
            " [--files S,..] [--filters F,..] [--fp X,..] [--order random|coherent|both]"
            " [--modes M,..] [--coverage] [--min-ms MS] [--reps-sample N] [--batches N]"
            " [--emit-queries DIR]\n"
            "       bench_ptex --queries REF.txt --ptx FILE.ptx [--dump OUT] [--json PATH]\n"
            "       either form: [--sharpness S] [--width W] [--blur B] [--lerp]\n");
    return 2;
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--import-one"))
        return import_one(argv[2]);
    opts op = {.reps = 9, .reps_sample = 3, .order_mask = 3, .mode_mask = 1 << ST_MODE_TRAVERSE,
               .filter_mask = (1u << NFILT) - 1, .min_s = 0.015, .nfp = 3,
               .fp = {0.25f, 4.0f, 16.0f}};
    static const char *orders[3] = {"random", "coherent", "both"};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--import-only"))
            op.import_only = 1;
        else if (!strcmp(a, "--sample-only"))
            op.sample_only = 1;
        else if (!strcmp(a, "--coverage"))
            op.coverage = 1;
        else if (!strcmp(a, "--lerp"))
            op.lerp = 1;
        else if (!v)
            return usage();
        else if (!strcmp(a, "--json"))
            op.json = v, i++;
        else if (!strcmp(a, "--reps"))
            op.reps = atoi(v), i++;
        else if (!strcmp(a, "--batches"))
            op.batches = atol(v), i++;
        else if (!strcmp(a, "--reps-sample"))
            op.reps_sample = atoi(v), i++;
        else if (!strcmp(a, "--min-ms"))
            op.min_s = atof(v) / 1e3, i++;
        else if (!strcmp(a, "--files"))
            op.files = v, i++;
        else if (!strcmp(a, "--queries"))
            op.queries = v, i++;
        else if (!strcmp(a, "--ptx"))
            op.ptx = v, i++;
        else if (!strcmp(a, "--dump"))
            op.dump = v, i++;
        else if (!strcmp(a, "--sharpness"))
            op.sharpness = strtof(v, NULL), i++;
        else if (!strcmp(a, "--width"))
            op.width = strtof(v, NULL), i++;
        else if (!strcmp(a, "--blur"))
            op.blur = strtof(v, NULL), i++;
        else if (!strcmp(a, "--emit-queries"))
            op.emit = v, i++, op.sample_only = 1;
        else if (!strcmp(a, "--filters")) {
            int m = parse_list(v, fnames, NFILT);
            if (m <= 0)
                return usage();
            op.filter_mask = (unsigned)m, i++;
        } else if (!strcmp(a, "--modes")) {
            op.mode_mask = parse_list(v, mnames, 3), i++;
            if (op.mode_mask <= 0)
                return usage();
        } else if (!strcmp(a, "--order")) {
            int m = parse_list(v, orders, 3);
            if (m <= 0)
                return usage();
            op.order_mask = m & 4 ? 3 : m, i++;
        } else if (!strcmp(a, "--fp")) {
            char buf[256];
            snprintf(buf, sizeof buf, "%s", v);
            op.nfp = 0;
            for (char *t = strtok(buf, ","); t && op.nfp < MAXFP; t = strtok(NULL, ",")) {
                float x = strtof(t, NULL);
                if (!(x > 0 && x < 1e6f))
                    return usage();
                op.fp[op.nfp++] = x;
            }
            if (!op.nfp)
                return usage();
            i++;
        } else
            return usage();
    }
    if (op.reps < 1 || op.reps > 99)
        op.reps = 9;
    if (op.reps_sample < 1 || op.reps_sample > 99)
        op.reps_sample = 3;
    if (!(op.min_s > 0 && op.min_s < 60))
        op.min_s = 0.015;
    if (!(op.sharpness >= 0 && op.sharpness <= 1) || !(op.width >= 0 && op.width <= 1e4f) ||
        !(op.blur >= 0 && op.blur <= 1e4f))
        return usage();
    const char *dd = st_test_data_dir();
    if (op.queries || op.ptx) {
        if (!op.queries || !op.ptx)
            return usage();
        return run_query_file(&op, dd);
    }
    static ptxfile fl[MAXFILES];
    static char rel[MAXFILES][512];
    int nfl = st_test_ptx_files(rel, MAXFILES);
    if (!nfl) {
        printf("no .ptx files under %s (SEAMTEX_DATA)\n", dd);
        return 0;
    }
    for (int i = 0; i < nfl; i++)
        memcpy(fl[i].rel, rel[i], sizeof fl[i].rel);
    name_files(fl, nfl);
    FILE *js = op.json ? fopen(op.json, "w") : NULL;
    if (js)
        fprintf(js, "{\"bench\":\"ptex\",\"reps\":%d,\"import\":[", op.reps);
    if (!op.sample_only) {
        printf("import (st_ptex_read_file, file in the page cache), median of %d; \"fresh\": "
               "one import per new process (cold heap, allocator started),\n\"warm\": repeated in "
               "this process; "
               "MB/s and faces/s from fresh CPU time (the machine is shared)\n", op.reps);
        printf("%-22s %-6s %6s %6s %9s %9s %9s %8s %10s %8s %9s\n", "file", "type", "MB",
               "faces", "fresh ms", "fresh cpu", "warm cpu", "MB/s", "faces/s", "B/texel",
               "table cpu");
    }
    static st_set *sets[MAXFILES];
    int jfirst = 1;
    if (op.sample_only)
        op.reps = 1;
    for (int i = 0; i < nfl; i++) {
        if (!wanted(&op, fl[i].name))
            continue;
        char path[1024];
        if (snprintf(path, sizeof path, "%s/%s", dd, fl[i].rel) >= (int)sizeof path)
            continue;
        sets[i] = import_row(&op, path, fl[i].name, js, &jfirst);
        if (op.import_only) {
            st_set_free(sets[i]);
            sets[i] = NULL;
        }
    }
    if (js)
        fprintf(js, "],\"sample\":[");
    if (!op.import_only)
        sample_tables(&op, fl, sets, nfl, js);
    if (js) {
        fprintf(js, "]}\n");
        fclose(js);
    }
    for (int i = 0; i < nfl; i++)
        st_set_free(sets[i]);
    return 0;
}
