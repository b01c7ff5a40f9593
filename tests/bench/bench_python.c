/* tests/bench/bench_python.c - a 10^6-query SAMPLE round trip from Python (the seamtex
 * module) against the same call from C (libseamtex's stc_sample), on one seamtexd over
 * loopback.
 *
 * Usage: bench_python [--json PATH] [--reps N] [--n QUERIES]
 *
 * Starts seamtexd (tests/common/daemon_fixture.h), writes n random bilinear Traverse queries
 * on the default set (face, u, v; no footprint) as raw arrays, and starts
 * `$PYTHON3 tests/bench/py_sample.py PORT DIR` (default /usr/bin/python3), which loads them
 * into numpy arrays and times Client.sample() of all n each time it is told "go". Both sides
 * make two untimed warm-up calls, then the runs alternate C, Python, Python, C, C, Python
 * ... (--reps each, default 7), so a change of the machine's load touches both alike and
 * neither always runs right after the other; the figures are the medians. Both ask for values, coverage and status (the Python call always does); the C
 * side leaves the result where libseamtex put it (owned by the connection), the Python side
 * packs its three arrays into stc_query records first and copies the result out into fresh
 * arrays: that is the overhead measured. Without a Python module (no python3-dev) it says so
 * and exits 0.
 */
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "daemon_fixture.h"
#include "seamtex.h"
#include "../common/benchstat.h"

extern char **environ;

static double cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double loadavg(void)
{
    double l = 0;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &l) != 1)
            l = 0;
        fclose(f);
    }
    return l;
}

static int write_raw(const char *dir, const char *name, const void *p, size_t bytes)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    size_t w = fwrite(p, 1, bytes, f);
    return fclose(f) == 0 && w == bytes ? 0 : -1;
}

int main(int argc, char **argv)
{
    const char *json = NULL;
    int reps = 7;
    size_t n = 1000000;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--n") && i + 1 < argc)
            n = (size_t)strtoull(argv[++i], NULL, 10);
        else {
            fprintf(stderr, "usage: bench_python [--json PATH] [--reps N] [--n QUERIES]\n");
            return 2;
        }
    }
    if (reps < 1 || reps > 100 || n < 1 || n > 100000000) {
        fprintf(stderr, "bench_python: --reps 1..100, --n 1..10^8\n");
        return 2;
    }
    const char *build = getenv("SEAMTEX_BUILD") ? getenv("SEAMTEX_BUILD") : "build";
    const char *python = getenv("PYTHON3") ? getenv("PYTHON3") : "/usr/bin/python3";
    char modpath[512];
    snprintf(modpath, sizeof modpath, "%s/python/seamtex/__init__.py", build);
    if (access(modpath, R_OK) != 0 || access(python, X_OK) != 0) {
        printf("bench_python: skipped: %s or %s is missing (make python; python3-dev)\n",
               modpath, python);
        return 0;
    }

    /* the queries: face, u, v from a fixed xorshift sequence */
    stc_query *q = calloc(n, sizeof *q);
    uint32_t *face = malloc(n * 4);
    float *u = malloc(n * 4), *v = malloc(n * 4);
    if (!q || !face || !u || !v)
        return 1;
    uint64_t s = 0x9E3779B97F4A7C15ull;
    for (size_t i = 0; i < n; i++) {
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        face[i] = (uint32_t)(s % 384);
        u[i] = (float)((s >> 16) & 0xFFFFFF) / 16777216.0f;
        v[i] = (float)((s >> 40) & 0xFFFFFF) / 16777216.0f;
        q[i].face = face[i], q[i].u = u[i], q[i].v = v[i];
    }

    st_daemon d;
    if (st_daemon_up(&d, NULL) != 0) {
        fprintf(stderr, "bench_python: seamtexd did not start\n");
        return 1;
    }
    int rc = 1;
    pid_t child = 0;
    FILE *to = NULL, *from = NULL;
    /* wall and client CPU seconds of each run, C and Python */
    double *tc = calloc((size_t)reps, sizeof *tc), *tp = calloc((size_t)reps, sizeof *tp);
    double *cc = calloc((size_t)reps, sizeof *cc), *cp = calloc((size_t)reps, sizeof *cp);
    /* the Python side's time outside stc_sample (packing, copying out, the interpreter) */
    double *po = calloc((size_t)reps, sizeof *po), pcall;
    double load0 = loadavg();
    int err = 0;
    stc_conn *c = stc_connect(d.host, (unsigned)d.port, 5000, &err);
    if (!c || !tc || !tp || !cc || !cp || !po) {
        fprintf(stderr, "bench_python: connect failed (%s)\n", stc_strerror(err));
        goto out;
    }
    stc_set_timeout(c, 120000);
    if (write_raw(d.dir, "face.u32", face, n * 4) || write_raw(d.dir, "u.f32", u, n * 4) ||
        write_raw(d.dir, "v.f32", v, n * 4)) {
        fprintf(stderr, "bench_python: cannot write the queries into %s\n", d.dir);
        goto out;
    }

    /* the Python side, on two pipes */
    int in_p[2], out_p[2];
    if (pipe(in_p) || pipe(out_p))
        goto out;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, in_p[0], 0);
    posix_spawn_file_actions_adddup2(&fa, out_p[1], 1);
    posix_spawn_file_actions_addclose(&fa, in_p[1]);
    posix_spawn_file_actions_addclose(&fa, out_p[0]);
    char port[16];
    snprintf(port, sizeof port, "%d", d.port);
    char *const pargv[] = {(char *)python, (char *)"tests/bench/py_sample.py", port, d.dir, NULL};
    if (posix_spawn(&child, python, &fa, NULL, pargv, environ) != 0) {
        fprintf(stderr, "bench_python: cannot start %s\n", python);
        child = 0;
        goto out;
    }
    posix_spawn_file_actions_destroy(&fa);
    close(in_p[0]);
    close(out_p[1]);
    to = fdopen(in_p[1], "w");
    from = fdopen(out_p[0], "r");
    char line[256];
    if (!to || !from || !fgets(line, sizeof line, from) || strncmp(line, "ready", 5) != 0) {
        fprintf(stderr, "bench_python: the Python side did not start\n");
        goto out;
    }

    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;                /* traverse */
    o.filter = 1;              /* bilinear */
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    stc_sample_result res;
    for (int w = 0; w < 2; w++)      /* warm-up: the library's buffers reach their size */
        if ((err = stc_sample(c, "default", &o, q, n, &res)) != 0) {
            fprintf(stderr, "bench_python: sample: %s %s\n", stc_strerror(err), stc_errmsg(c));
            goto out;
        }
    printf("bench_python: %zu-query SAMPLE round trips (bilinear traverse, default set), "
           "C and Python alternating, %d times each; load %.1f\n", n, reps, load0);
    for (int r = 0; r < reps; r++) {
        /* A B, then B A: neither side always runs right after the other */
        for (int side = 0; side < 2; side++) {
            if ((side == 0) == (r % 2 == 0)) {
                double t0 = st_bench_now(), c0 = cpu();
                if ((err = stc_sample(c, "default", &o, q, n, &res)) != 0 || res.count != n) {
                    fprintf(stderr, "bench_python: sample: %s %s\n", stc_strerror(err),
                            stc_errmsg(c));
                    goto out;
                }
                tc[r] = st_bench_now() - t0;
                cc[r] = cpu() - c0;
            } else {
                fputs("go\n", to);
                fflush(to);
                if (!fgets(line, sizeof line, from) ||
                    sscanf(line, "%lf %lf %lf %lf", &tp[r], &cp[r], &pcall, &po[r]) != 4) {
                    fprintf(stderr, "bench_python: the Python side stopped\n");
                    goto out;
                }
            }
        }
        printf("  run %d (%s first): C %.3f s (%.2f M queries/s, client CPU %.0f ms)   "
               "Python %.3f s (%.2f M queries/s, client CPU %.0f ms, outside stc_sample "
               "%.0f ms)\n", r + 1, r % 2 ? "Python" : "C", tc[r], n / tc[r] / 1e6,
               cc[r] * 1e3, tp[r], n / tp[r] / 1e6, cp[r] * 1e3, po[r] * 1e3);
        fflush(stdout);
    }
    double mc = st_bench_median(tc, reps), mp = st_bench_median(tp, reps), load1 = loadavg();
    double mcc = st_bench_median(cc, reps), mcp = st_bench_median(cp, reps);
    double mpo = st_bench_median(po, reps);
    printf("median: C %.3f s = %.2f M queries/s; Python %.3f s = %.2f M queries/s; "
           "Python/C throughput %.1f %%; client CPU per call C %.0f ms, Python %.0f ms; "
           "Python outside stc_sample %.0f ms; load %.1f -> %.1f\n", mc, n / mc / 1e6, mp,
           n / mp / 1e6, 100.0 * mc / mp, mcc * 1e3, mcp * 1e3, mpo * 1e3, load0, load1);
    if (json) {
        FILE *js = fopen(json, "w");
        if (js) {
            fprintf(js, "{\n  \"bench\": \"python\",\n  \"queries\": %zu,\n  \"reps\": %d,\n"
                        "  \"c_median_s\": %.6f,\n  \"python_median_s\": %.6f,\n"
                        "  \"c_queries_per_s\": %.0f,\n  \"python_queries_per_s\": %.0f,\n"
                        "  \"python_over_c\": %.4f,\n  \"c_client_cpu_s\": %.6f,\n"
                        "  \"python_client_cpu_s\": %.6f,\n  \"python_outside_stc_s\": %.6f,\n"
                        "  \"load_before\": %.2f,\n  \"load_after\": %.2f\n}\n",
                    n, reps, mc, mp, n / mc, n / mp, mc / mp, mcc, mcp, mpo, load0, load1);
            fclose(js);
        }
    }
    rc = 0;
out:
    if (to)
        fclose(to);               /* EOF: the Python side leaves its loop */
    if (from)
        fclose(from);
    if (child > 0)
        waitpid(child, NULL, 0);
    stc_close(c);
    st_daemon_down(&d, 20000);
    free(q), free(face), free(u), free(v), free(tc), free(tp), free(cc), free(cp), free(po);
    return rc;
}
