/* tests/common/benchstat.c - benchmark clocks and order statistics (see benchstat.h). */
#include "benchstat.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

double st_bench_clock(clockid_t c)
{
    struct timespec ts;
    clock_gettime(c, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

double st_bench_now(void)
{
    return st_bench_clock(CLOCK_MONOTONIC);
}

int st_bench_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double st_bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, st_bench_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double st_bench_pct(double *v, int n, double p)
{
    qsort(v, (size_t)n, sizeof *v, st_bench_cmp_double);
    int k = (int)ceil(p * n) - 1;
    return v[k < 0 ? 0 : k >= n ? n - 1 : k];
}

int st_bench_args(int argc, char **argv, const char **json, int *reps, int reps_default)
{
    *json = NULL;
    *reps = reps_default;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            *json = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            *reps = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--json PATH] [--reps N]\n", argv[0]);
            return -1;
        }
    }
    if (*reps < 1 || *reps > 101)
        *reps = reps_default;
    return 0;
}
