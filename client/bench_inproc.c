/* client/bench_inproc.c - the in-process baseline for SAMPLE throughput: st_sample_batch on
 * the default set (store/defaultset.h, the set seamtexd serves as "default"), with the same
 * query generator, batch size, mode and filter mix as the network run, on --threads threads.
 *
 * Owns: timing the baseline. Does not own: the sampler or the set.
 * The ratio network / in-process is what the "80 % of the in-process sampler" target means.
 */
#include "bench.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "defaultset.h"
#include "ptexfilter.h"
#include "sample.h"

typedef struct inproc_thread {
    const bench_cfg *cfg;
    const st_set *set;
    uint64_t seed;
    uint64_t t_measure, t_end;
    uint64_t queries;          /* answered in the measured window */
    uint64_t total;            /* answered, warm-up included */
    int failed;
} inproc_thread;

#define INPROC_POOL 16

static void *inproc_main(void *arg)
{
    inproc_thread *t = arg;
    const bench_cfg *cfg = t->cfg;
    size_t n = cfg->batch;
    st_query *q = malloc(INPROC_POOL * n * sizeof *q);
    float *out = malloc(n * t->set->info.nchan * sizeof *out);
    st_sample_opts opts[INPROC_POOL];
    if (!q || !out) {
        t->failed = 1;
        goto done;
    }
    uint64_t rng = stc_rng_seed(t->seed);
    for (unsigned i = 0; i < INPROC_POOL; i++) {
        bench_make_queries(q + i * n, n, t->set->info.nfaces, cfg->footprint, &rng);
        memset(&opts[i], 0, sizeof opts[i]);
        opts[i].mode = cfg->modes[stc_rng_next(&rng) % cfg->nmodes];
        opts[i].filter = cfg->filters[stc_rng_next(&rng) % cfg->nfilters];
    }
    for (unsigned i = 0;; i = (i + 1) % INPROC_POOL) {
        uint64_t t0 = bench_now_ns();
        if (t0 >= t->t_end)
            break;
        if (st_sample_batch(t->set, &opts[i], q + i * n, n, out, NULL, NULL) < 0) {
            t->failed = 1;
            break;
        }
        t->total += n;
        if (t0 >= t->t_measure && bench_now_ns() <= t->t_end)
            t->queries += n;
    }
done:
    free(q);
    free(out);
    return NULL;
}

static double cpu_seconds(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return 0;
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec +
           (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e6;
}

int bench_inproc_run(const bench_cfg *cfg, bench_inproc_result *res, char *msg, size_t ml)
{
    st_set *set = NULL;
    st_error e;
    st_error_clear(&e);
    if (st_default_set(&set, &e) != 0) {
        snprintf(msg, ml, "default set: %s", e.msg);
        return -1;
    }
    /* a Ptex-family filter needs the set's Ptex reductions, which a set that was not read
     * from a .ptx has only once prepared */
    for (unsigned i = 0; i < cfg->nfilters; i++) {
        if (cfg->filters[i] >= ST_FILTER_PTEX_POINT && st_ptexfilter_prepare(set, &e) != 0) {
            snprintf(msg, ml, "Ptex filters on the default set: %s", e.msg);
            st_set_free(set);
            return -1;
        }
    }
    unsigned nt = cfg->threads ? cfg->threads : 1;
    inproc_thread *ts = calloc(nt, sizeof *ts);
    pthread_t *tid = calloc(nt, sizeof *tid);
    if (!ts || !tid) {
        free(ts);
        free(tid);
        st_set_free(set);
        snprintf(msg, ml, "out of memory");
        return -1;
    }
    double cpu0 = cpu_seconds();
    uint64_t t0 = bench_now_ns();
    uint64_t tm = t0 + (uint64_t)(cfg->warmup_s * 1e9);
    uint64_t te = tm + (uint64_t)(cfg->duration_s * 1e9);
    unsigned started = 0;
    for (; started < nt; started++) {
        ts[started] = (inproc_thread){ .cfg = cfg, .set = set, .seed = cfg->seed * 7919u + started,
                                       .t_measure = tm, .t_end = te };
        if (pthread_create(&tid[started], NULL, inproc_main, &ts[started]) != 0)
            break;
    }
    uint64_t measured = 0, total = 0;
    int failed = started < nt;
    for (unsigned i = 0; i < started; i++) {
        pthread_join(tid[i], NULL);
        measured += ts[i].queries;
        total += ts[i].total;
        failed |= ts[i].failed;
    }
    res->qps = (double)measured / cfg->duration_s;
    res->queries_total = total;
    res->cpu_s = cpu_seconds() - cpu0;
    double per_cpu = res->cpu_s > 0 ? total / res->cpu_s : 0;
    if (!cfg->quiet)
        printf("seamtex-bench --inproc: st_sample_batch on the default set (%u faces), batch %u, "
               "%u threads: %.0f queries/s, %.0f queries per CPU-second\n", set->info.nfaces,
               cfg->batch, nt, res->qps, per_cpu);
    else
        printf("%.0f queries/s, %.0f per CPU-second\n", res->qps, per_cpu);
    free(ts);
    free(tid);
    st_set_free(set);
    if (failed) {
        snprintf(msg, ml, "in-process sampling failed (options refused or out of memory)");
        return -1;
    }
    return 0;
}
