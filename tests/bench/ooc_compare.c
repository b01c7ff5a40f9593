/* tests/bench/ooc_compare.c - the out-of-core comparison of bench_native (ooc_compare.h).
 *
 * Three sides serve one library under the same memory budget, with the same query stream and
 * the same number of threads, alternating round by round (A B C, C B A, ...):
 *   daemon  seamtexd --memory-budget B on its own data dir (hard links to the same native
 *           files: each seamtex side counts only the pages mapped in its own process, so they
 *           may share the page cache, as OIIO's side shares it with its .tx files): each
 *           thread has its own connection and sends SAMPLE batches (traverse, bilinear, f32
 *           out) and waits for the reply.
 *   inproc  seamtex in this process: the daemon's own registry, data-dir load and budget
 *           thread (sts_server_init, sts_budget_start; no sockets are used), each batch as
 *           the SAMPLE handler runs it (registry get, budget touch, st_sample_batch).
 *   oiio    OpenImageIO's TextureSystem (oiio_texsys.cpp), max_memory_MB = B, one .tx file per
 *           set (a copy, so that no two sets share a file or the page cache), texture() per
 *           query with a resolved handle and per-thread info.
 * The .tx files: each source set's level-0 faces are packed into one image (shelf packing,
 * faces at their own resolution side by side, no gutter; a constant face as an 8 x 8 cell),
 * written with OIIO in the set's channel count and type, and converted by `maketx --oiio`
 * (64 x 64 tiles, zip unless SEAMTEX_BENCH_TX_COMPRESSION names another, box-filtered MIP
 * levels); made once per source and kept in txcache.
 * A query (face f, u, v, footprint d) becomes s = (x0 + u w) / W, t = (y0 + v h) / H with
 * dsdx = d w / W, dtdy = d h / H for f's cell (x0, y0, w, h) in the W x H image: the same
 * texels, the same footprint in texels. What each side computes: seamtex bilinear in the
 * nearest MIP level of the face, taps past a face edge read from the neighbour (traverse);
 * OIIO bilinear in one MIP level (MipModeOneLevel, InterpBilinear, anisotropic 1, clamp),
 * taps past a cell edge read the neighbouring cell of the atlas (no seam handling).
 */
#include "ooc_compare.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "budget.h"
#include "config.h"
#include "import.h"
#include "oiio_texsys.h"
#include "registry.h"
#include "sample.h"
#include "server.h"
#include "../common/testdata.h"

#define MAXT 16

/* ---- the .tx files ------------------------------------------------------------------------- */

typedef struct tx_layout {
    int       ok;
    uint32_t  W, H, n;
    unsigned  nchan;
    uint32_t *x0, *y0, *w, *h;
    char      path[1024];
} tx_layout;

static const st_set *g_sort_set;
static uint32_t cell_w(const st_face *f) { return (f->flags & ST_FACE_CONSTANT) && f->w > 8 ? 8 : f->w; }
static uint32_t cell_h(const st_face *f) { return (f->flags & ST_FACE_CONSTANT) && f->h > 8 ? 8 : f->h; }
static int cmp_face_h(const void *a, const void *b)
{
    const st_face *fa = &g_sort_set->faces[*(const uint32_t *)a];
    const st_face *fb = &g_sort_set->faces[*(const uint32_t *)b];
    uint32_t ha = cell_h(fa), hb = cell_h(fb);
    if (ha != hb)
        return ha > hb ? -1 : 1;
    return *(const uint32_t *)a < *(const uint32_t *)b ? -1 : 1;
}

/* The layout of source si's faces in its image, and (unless cached) the .tx file. */
static int build_tx(const char *cache, const char *comp, int si, tx_layout *L)
{
    char p[1024], err[512] = "";
    memset(L, 0, sizeof *L);
    if (st_test_data_path(p, sizeof p, nl_sources[si].rel) != 0)
        return -1;
    st_import_opts o;
    st_import_opts_init(&o);
    st_set *s = NULL;
    st_error e;
    if (st_import_file(p, &o, &s, &e) != 0) {
        fprintf(stderr, "ooc: %s: %s\n", p, e.msg);
        return -1;
    }
    uint32_t n = s->info.nfaces;
    uint32_t *order = malloc(n * sizeof *order);
    L->x0 = malloc(n * sizeof *L->x0);
    L->y0 = malloc(n * sizeof *L->y0);
    L->w = malloc(n * sizeof *L->w);
    L->h = malloc(n * sizeof *L->h);
    if (!order || !L->x0 || !L->y0 || !L->w || !L->h) {
        free(order);
        st_set_free(s);
        return -1;
    }
    double area = 0;
    uint32_t maxw = 0;
    for (uint32_t f = 0; f < n; f++) {
        order[f] = f;
        L->w[f] = cell_w(&s->faces[f]);
        L->h[f] = cell_h(&s->faces[f]);
        area += (double)L->w[f] * L->h[f];
        if (L->w[f] > maxw)
            maxw = L->w[f];
    }
    g_sort_set = s;
    qsort(order, n, sizeof *order, cmp_face_h);
    uint32_t W = (uint32_t)ceil(sqrt(area * 1.15) / 64.0) * 64;
    if (W < maxw)
        W = maxw;
    uint32_t x = 0, y = 0, shelf = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t f = order[i];
        if (x + L->w[f] > W) {
            y += shelf;
            x = 0;
            shelf = 0;
        }
        L->x0[f] = x;
        L->y0[f] = y;
        x += L->w[f];
        if (L->h[f] > shelf)
            shelf = L->h[f];
    }
    free(order);
    L->W = W;
    L->H = y + shelf;
    L->n = n;
    L->nchan = s->info.nchan;
    const char *base = strrchr(nl_sources[si].rel, '/');
    base = base ? base + 1 : nl_sources[si].rel;
    snprintf(L->path, sizeof L->path, "%s/src%d-%.*s-%s.tx", cache, si,
             (int)(strcspn(base, ".")), base, comp);
    if (access(L->path, R_OK) == 0) {
        st_set_free(s);
        L->ok = 1;
        return 0;
    }
    size_t ts = st_texel_size(s);
    uint8_t *img = calloc((size_t)L->W * L->H, ts);
    if (!img) {
        st_set_free(s);
        return -1;
    }
    for (uint32_t f = 0; f < n; f++) {
        const st_face *fc = &s->faces[f];
        const uint8_t *src = st_face_level(s, f, 0);
        int cst = (fc->flags & ST_FACE_CONSTANT) != 0;
        for (uint32_t j = 0; j < L->h[f]; j++)
            for (uint32_t i = 0; i < L->w[f]; i++)
                memcpy(img + (((size_t)(L->y0[f] + j) * L->W) + L->x0[f] + i) * ts,
                       cst ? src : src + ((size_t)j * fc->w + i) * ts, ts);
    }
    int isfloat = s->info.dtype == ST_DT_HALF || s->info.dtype == ST_DT_F32;
    char in[1100];
    snprintf(in, sizeof in, "%s.in.%s", L->path, isfloat ? "exr" : "tif");
    int rc = bto_write_image(in, L->W, L->H, L->nchan, s->info.dtype, img, err, sizeof err);
    free(img);
    st_set_free(s);
    if (rc != 0) {
        fprintf(stderr, "ooc: %s\n", err);
        return -1;
    }
    char cmd[2600];
    snprintf(cmd, sizeof cmd, "nice -n 5 maketx --oiio --compression '%s' --threads 1 -o '%s.part.tx' "
             "'%s' >/dev/null && mv '%s.part.tx' '%s'", comp, L->path, in, L->path, L->path);
    double t0 = nl_now_s();
    rc = system(cmd);
    unlink(in);
    if (rc != 0) {
        fprintf(stderr, "ooc: maketx failed for %s\n", in);
        return -1;
    }
    printf("ooc: %s -> %s (%u x %u, %u faces) by maketx in %.1f s\n", nl_sources[si].rel,
           L->path, L->W, L->H, n, nl_now_s() - t0);
    L->ok = 1;
    return 0;
}

static void layout_free(tx_layout *L)
{
    free(L->x0);
    free(L->y0);
    free(L->w);
    free(L->h);
}

/* ---- the sides ----------------------------------------------------------------------------- */

typedef struct runner runner;
typedef struct worker {
    runner   *R;
    int       tid;
    uint32_t  rng;
    double   *lat;
    size_t    nlat, cap;
    uint64_t  queries, failed;
    stc_conn *conn;
    void     *oth;
} worker;

struct runner {
    const ooc_cfg *c;
    int            side;
    double         deadline;
    sts_server    *srv;
    bto_ts        *ts;
    void         **handles;
    tx_layout     *lay;
    nl_zipf        z;
    worker         w[MAXT];
};

static void *worker_main(void *arg)
{
    worker *w = arg;
    runner *R = w->R;
    const ooc_cfg *c = R->c;
    static __thread nl_batch b;
    static __thread st_query q[NL_BATCH];
    static __thread stc_query cq[NL_BATCH];
    static __thread bto_query bq[NL_BATCH];
    static __thread float out[NL_BATCH * 4];
    static __thread uint8_t stt[NL_BATCH];
    st_sample_opts so = {.mode = ST_MODE_TRAVERSE, .filter = ST_FILTER_BILINEAR};
    stc_sample_opts co;
    memset(&co, 0, sizeof co);
    co.mode = ST_MODE_TRAVERSE;
    co.filter = ST_FILTER_BILINEAR;
    co.outfmt = STC_OUT_F32;
    while (nl_now_s() < R->deadline) {
        nl_next_batch(&R->z, c->sets, &w->rng, &b);
        const nl_set *set = &c->sets[b.set];
        double t0 = 0;
        int bad = 0;
        if (R->side == OOC_DAEMON) {
            for (int i = 0; i < NL_BATCH; i++)
                cq[i] = (stc_query){b.face[i], b.u[i], b.v[i], b.d[i], 0, 0, b.d[i]};
            stc_sample_result r;
            t0 = nl_now_s();
            bad = stc_sample(w->conn, set->name, &co, cq, NL_BATCH, &r) != 0;
        } else if (R->side == OOC_INPROC) {
            for (int i = 0; i < NL_BATCH; i++)
                q[i] = (st_query){b.face[i], b.u[i], b.v[i], b.d[i], 0, 0, b.d[i]};
            t0 = nl_now_s();
            st_setref *ref = NULL;
            if (st_registry_get(R->srv->reg, set->name, &ref, NULL) != 0) {
                bad = 1;
            } else {
                int cold = sts_budget_touch(R->srv, ref->set);
                int64_t c0 = cold ? sts_now_us() : 0;
                bad = st_sample_batch(ref->set, &so, q, NL_BATCH, out, NULL, stt) != 0;
                if (cold)
                    sts_budget_cold_done(R->srv, c0, NL_BATCH);
                st_setref_release(ref);
            }
        } else {
            const tx_layout *L = &R->lay[set->src];
            for (int i = 0; i < NL_BATCH; i++) {
                uint32_t f = b.face[i];
                float sw = (float)L->w[f] / (float)L->W, th = (float)L->h[f] / (float)L->H;
                bq[i] = (bto_query){((float)L->x0[f] + b.u[i] * (float)L->w[f]) / (float)L->W,
                                    ((float)L->y0[f] + b.v[i] * (float)L->h[f]) / (float)L->H,
                                    b.d[i] * sw, 0, 0, b.d[i] * th};
            }
            t0 = nl_now_s();
            bad = bto_sample(R->ts, w->oth, R->handles[b.set], bq, NL_BATCH, (int)L->nchan,
                             out) != 0;
        }
        double l = nl_now_s() - t0;
        if (bad) {
            w->failed++;
            if (R->side == OOC_DAEMON)
                break;   /* a lost connection: stop rather than spin */
            continue;
        }
        if (w->nlat == w->cap) {
            size_t nc = w->cap ? w->cap * 2 : 4096;
            double *nl = realloc(w->lat, nc * sizeof *nl);
            if (!nl)
                break;
            w->lat = nl;
            w->cap = nc;
        }
        w->lat[w->nlat++] = l;
        w->queries += NL_BATCH;
    }
    return NULL;
}

static long majflt_self(void)
{
    struct rusage ru;
    return getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_majflt : 0;
}

typedef struct side_ctx {
    runner     R;
    nl_daemon *d;
    stc_conn  *mon;     /* daemon: STATS */
    double     t_used;  /* seconds this side has run so far */
    uint64_t   base[4]; /* counters at the start of the side's first round */
} side_ctx;

static double resident_now(side_ctx *S, double *rss)
{
    *rss = 0;
    if (S->R.side == OOC_DAEMON) {
        *rss = (double)nl_proc_rss(S->d->pid) / 1048576.0;
        uint64_t r = nl_stat(S->mon, "resident_bytes");
        return r == UINT64_MAX ? 0 : (double)r / 1048576.0;
    }
    if (S->R.side == OOC_INPROC)
        return (double)__atomic_load_n(&S->R.srv->budget.resident, __ATOMIC_RELAXED) / 1048576.0;
    return (double)bto_stat(S->R.ts, "stat:cache_memory_used") / 1048576.0;
}

static void counters(side_ctx *S, uint64_t v[4])
{
    memset(v, 0, 4 * sizeof *v);
    if (S->R.side == OOC_DAEMON) {
        v[0] = nl_stat(S->mon, "cold_queries");
        v[1] = nl_stat(S->mon, "budget_releases");
        v[2] = nl_stat(S->mon, "major_faults");
    } else if (S->R.side == OOC_INPROC) {
        sts_budget *b = &S->R.srv->budget;
        v[0] = __atomic_load_n(&b->cold_queries, __ATOMIC_RELAXED);
        v[1] = __atomic_load_n(&b->releases, __ATOMIC_RELAXED);
        v[2] = (uint64_t)majflt_self();
    } else {
        v[0] = bto_stat(S->R.ts, "stat:tiles_created");
        v[1] = bto_stat(S->R.ts, "stat:bytes_read");
    }
}

/* One round of one side: threads sample until the deadline while this thread records the
 * resident memory every 0.5 s. Returns the round's queries per second. */
static double run_round(side_ctx *S, ooc_side *o, int round, double secs)
{
    runner *R = &S->R;
    int T = R->c->threads;
    uint64_t q0 = 0;
    for (int t = 0; t < T; t++) {
        q0 += R->w[t].queries;
        R->w[t].rng = 0x9e3779b9u * (uint32_t)(round * MAXT + t + 1);  /* same on every side */
    }
    pthread_t th[MAXT];
    double t0 = nl_now_s();
    R->deadline = t0 + secs;
    for (int t = 0; t < T; t++)
        pthread_create(&th[t], NULL, worker_main, &R->w[t]);
    for (double next = t0; nl_now_s() < R->deadline;) {
        if (nl_now_s() >= next && o->nres < OOC_MAX_RES) {
            double rss, mb = resident_now(S, &rss);
            o->res_t[o->nres] = S->t_used + (nl_now_s() - t0);
            o->res_mb[o->nres] = mb;
            o->rss_mb[o->nres++] = rss;
            if (mb > o->max_res_mb)
                o->max_res_mb = mb;
            next += 0.5;
        }
        usleep(20000);
    }
    for (int t = 0; t < T; t++)
        pthread_join(th[t], NULL);
    double el = nl_now_s() - t0;
    S->t_used += el;
    uint64_t q1 = 0;
    for (int t = 0; t < T; t++)
        q1 += R->w[t].queries;
    return (double)(q1 - q0) / el;
}

static void side_finish(side_ctx *S, ooc_side *o, int rounds)
{
    runner *R = &S->R;
    size_t nl = 0;
    for (int t = 0; t < R->c->threads; t++)
        nl += R->w[t].nlat;
    double *all = malloc((nl ? nl : 1) * sizeof *all);
    size_t k = 0;
    for (int t = 0; t < R->c->threads; t++) {
        if (all)
            memcpy(all + k, R->w[t].lat, R->w[t].nlat * sizeof *all);
        k += R->w[t].nlat;
        o->queries += R->w[t].queries;
        o->failed += R->w[t].failed;
        free(R->w[t].lat);
    }
    if (all && nl) {
        qsort(all, nl, sizeof *all, nl_cmp_double);
        o->p50_ms = all[nl / 2] * 1e3;
        o->p99_ms = all[(size_t)((double)nl * 0.99)] * 1e3;
    }
    free(all);
    double q[OOC_MAX_ROUNDS];
    memcpy(q, o->qps, sizeof q);
    o->qps_median = nl_median(q, rounds);
    uint64_t v[4];
    counters(S, v);
    if (R->side == OOC_OIIO) {
        o->tiles_created = v[0] - S->base[0];
        o->bytes_read = v[1] - S->base[1];
    } else {
        o->cold_share = o->queries ? (double)(v[0] - S->base[0]) / (double)o->queries : 0;
        o->releases = v[1] - S->base[1];
        o->majflt = v[2] - S->base[2];
    }
}

static const char *const side_names[OOC_NSIDES] = {"seamtexd", "seamtex-inproc", "oiio-texsys"};

int ooc_compare(const ooc_cfg *c, ooc_res *r)
{
    memset(r, 0, sizeof *r);
    r->sets = c->nsets;
    r->rounds = c->rounds < 1 ? 1 : c->rounds > OOC_MAX_ROUNDS ? OOC_MAX_ROUNDS : c->rounds;
    r->threads = c->threads < 1 ? 1 : c->threads > MAXT ? MAXT : c->threads;
    snprintf(r->tx_compression, sizeof r->tx_compression, "%s",
             c->tx_compression && *c->tx_compression ? c->tx_compression : "zip");
    if (strspn(r->tx_compression, "abcdefghijklmnopqrstuvwxyz0123456789:") !=
        strlen(r->tx_compression)) {
        fprintf(stderr, "ooc: bad .tx compression name\n");
        return -1;
    }
    ooc_cfg cc = *c;
    cc.threads = r->threads;
    int rc = -1;
    /* the .tx files: one per source (cached), one copy per set */
    tx_layout lay[16];
    memset(lay, 0, sizeof lay);
    mkdir(c->txcache, 0700);
    mkdir(c->txdir, 0700);
    for (size_t i = 0; i < nl_nsources && i < 16; i++)
        if (nl_sources[i].texel_bytes && build_tx(c->txcache, r->tx_compression, (int)i,
                                                  &lay[i]) != 0)
            goto out_lay;
    char **txpath = calloc((size_t)c->nsets, sizeof *txpath);
    if (!txpath)
        goto out_lay;
    uint64_t txbytes = 0;
    for (int k = 0; k < c->nsets; k++) {
        txpath[k] = malloc(1100);
        snprintf(txpath[k], 1100, "%s/%s.tx", c->txdir, c->sets[k].name);
        struct stat st;
        if (nl_copy_file(lay[c->sets[k].src].path, txpath[k]) != 0 || stat(txpath[k], &st) != 0) {
            fprintf(stderr, "ooc: cannot copy %s\n", txpath[k]);
            goto out_tx;
        }
        txbytes += (uint64_t)st.st_size;
    }
    r->tx_disk_mb = (double)txbytes / 1048576.0;

    /* seamtex in process: loads the data dir as the daemon does; the stored bytes set the
     * budget */
    static sts_server srv;
    sts_config cfg;
    sts_config_defaults(&cfg);
    snprintf(cfg.listen, sizeof cfg.listen, "127.0.0.1:0");
    snprintf(cfg.data_dir, sizeof cfg.data_dir, "%s", c->dir);
    cfg.default_set = 0;
    cfg.max_sets = 100000;
    cfg.log_level = STS_WARN;
    if (sts_server_init(&srv, &cfg) != 0) {
        fprintf(stderr, "ooc: in-process server did not start\n");
        goto out_tx;
    }
    uint64_t stored, resident;
    sts_budget_measure(&srv, &stored, &resident);
    uint64_t budget = c->budget ? c->budget : stored / 4;
    __atomic_store_n(&srv.cfg.memory_budget, budget, __ATOMIC_RELAXED);
    r->stored_mb = (double)stored / 1048576.0;
    r->budget_mb = (double)budget / 1048576.0;
    if (sts_budget_start(&srv) != 0)
        goto out_srv;
    printf("ooc: %d sets, %.0f MB stored, budget %.0f MB; OIIO: %.0f MB of .tx files (%s); "
           "%d threads per side, %d rounds of %.1f s\n", c->nsets, r->stored_mb, r->budget_mb,
           r->tx_disk_mb, r->tx_compression, r->threads, r->rounds, c->secs / r->rounds);

    /* the daemon, on its own data dir of hard links to the same files (its budget counts the
     * pages mapped in its process, not the page cache both sides share) */
    nl_daemon d;
    char bs[32], ddir[1100];
    snprintf(bs, sizeof bs, "%llu", (unsigned long long)budget);
    snprintf(ddir, sizeof ddir, "%s.d", c->dir);
    double tc = nl_now_s();
    if (nl_link_subset(c->dir, c->sets, c->nsets, 0, ddir) != c->nsets) {
        fprintf(stderr, "ooc: cannot link the library to %s\n", ddir);
        goto out_budget;
    }
    printf("ooc: the daemon's data dir linked in %.1f s\n", nl_now_s() - tc);
    const char *const extra[] = {"--memory-budget", bs, NULL};
    if (nl_daemon_start(&d, ddir, extra) != 0)
        goto out_ddir;
    stc_conn *mon = nl_daemon_connect(&d, 3600);
    if (!mon) {
        fprintf(stderr, "ooc: seamtexd did not start (log %s)\n", d.logfile);
        goto out_daemon;
    }
    /* OIIO */
    bto_ts *ts = bto_create(r->budget_mb, c->nsets + 16);
    void **handles = calloc((size_t)c->nsets, sizeof *handles);
    if (!ts || !handles)
        goto out_oiio;
    for (int k = 0; k < c->nsets; k++)
        if (!(handles[k] = bto_handle(ts, txpath[k]))) {
            fprintf(stderr, "ooc: OIIO cannot open %s\n", txpath[k]);
            goto out_oiio;
        }

    side_ctx S[OOC_NSIDES];
    memset(S, 0, sizeof S);
    for (int s = 0; s < OOC_NSIDES; s++) {
        runner *R = &S[s].R;
        R->c = &cc;
        R->side = s;
        R->srv = &srv;
        R->ts = ts;
        R->handles = handles;
        R->lay = lay;
        S[s].d = &d;
        S[s].mon = mon;
        r->side[s].name = side_names[s];
        if (nl_zipf_init(&R->z, c->nsets) != 0)
            goto out_sides;
        for (int t = 0; t < r->threads; t++) {
            R->w[t].R = R;
            R->w[t].tid = t;
            if (s == OOC_DAEMON &&
                !(R->w[t].conn = stc_connect("127.0.0.1", (unsigned)d.port, 60000, NULL)))
                goto out_sides;
            if (s == OOC_OIIO)
                R->w[t].oth = bto_thread(ts);
        }
        counters(&S[s], S[s].base);
    }
    double per = c->secs / r->rounds;
    double ratio_d[OOC_MAX_ROUNDS], ratio_i[OOC_MAX_ROUNDS];
    for (int round = 0; round < r->rounds; round++) {
        for (int k = 0; k < OOC_NSIDES; k++) {
            int s = round % 2 ? OOC_NSIDES - 1 - k : k;
            r->side[s].qps[round] = run_round(&S[s], &r->side[s], round, per);
        }
        ratio_d[round] = r->side[OOC_DAEMON].qps[round] / r->side[OOC_OIIO].qps[round];
        ratio_i[round] = r->side[OOC_INPROC].qps[round] / r->side[OOC_OIIO].qps[round];
        char load[64];
        nl_read_load(load, sizeof load);
        printf("ooc round %d: seamtexd %.0f  seamtex in-process %.0f  OIIO %.0f queries/s "
               "(load %.14s)\n", round + 1, r->side[OOC_DAEMON].qps[round],
               r->side[OOC_INPROC].qps[round], r->side[OOC_OIIO].qps[round], load);
    }
    for (int s = 0; s < OOC_NSIDES; s++) {
        ooc_side *o = &r->side[s];
        side_finish(&S[s], o, r->rounds);
        printf("ooc %-15s median %8.0f queries/s  batch p50 %7.2f ms  p99 %8.2f ms  resident max "
               "%6.0f MB", o->name, o->qps_median, o->p50_ms, o->p99_ms, o->max_res_mb);
        if (s == OOC_OIIO)
            printf("  tiles read %llu, %.0f MB read\n", (unsigned long long)o->tiles_created,
                   (double)o->bytes_read / 1048576.0);
        else
            printf("  cold share %.3f, releases %llu, major faults %llu\n", o->cold_share,
                   (unsigned long long)o->releases, (unsigned long long)o->majflt);
        if (o->failed)
            printf("ooc %s: %llu batches failed\n", o->name, (unsigned long long)o->failed);
    }
    r->ratio_daemon_oiio = nl_median(ratio_d, r->rounds);
    r->ratio_inproc_oiio = nl_median(ratio_i, r->rounds);
    printf("ooc: throughput vs OIIO (median of per-round ratios): seamtexd %.2fx, seamtex "
           "in-process %.2fx\n", r->ratio_daemon_oiio, r->ratio_inproc_oiio);
    for (int s = 0; s < OOC_NSIDES; s++) {
        printf("ooc %s resident MB every 0.5 s:", r->side[s].name);
        for (int i = 0; i < r->side[s].nres; i++)
            printf(" %.0f", r->side[s].res_mb[i]);
        printf("\n");
    }
    rc = 0;
out_sides:
    for (int s = 0; s < OOC_NSIDES; s++) {
        for (int t = 0; t < r->threads; t++) {
            stc_close(S[s].R.w[t].conn);
            bto_thread_free(ts, S[s].R.w[t].oth);
        }
        nl_zipf_free(&S[s].R.z);
    }
out_oiio:
    free(handles);
    bto_free(ts);
    stc_close(mon);
out_daemon:
    nl_daemon_stop(&d);
out_ddir: {
        char cmd[3500];
        snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s.port' '%s.log'", ddir, ddir, ddir);
        if (system(cmd) != 0)
            fprintf(stderr, "ooc: could not remove %s\n", ddir);
    }
out_budget:
    sts_budget_stop(&srv);
out_srv:
    sts_server_free(&srv);
out_tx:
    for (int k = 0; k < c->nsets; k++)
        free(txpath[k]);
    free(txpath);
out_lay:
    for (int i = 0; i < 16; i++)
        layout_free(&lay[i]);
    return rc;
}

void ooc_json(FILE *f, const ooc_res *r)
{
    fprintf(f, "{\"sets\": %d, \"stored_mb\": %.1f, \"budget_mb\": %.1f, \"tx_disk_mb\": %.1f, "
            "\"tx_compression\": \"%s\", \"rounds\": %d, \"threads\": %d, \"ratio_daemon_oiio\": %.3f, "
            "\"ratio_inproc_oiio\": %.3f", r->sets, r->stored_mb, r->budget_mb, r->tx_disk_mb,
            r->tx_compression, r->rounds, r->threads, r->ratio_daemon_oiio, r->ratio_inproc_oiio);
    for (int s = 0; s < OOC_NSIDES; s++) {
        const ooc_side *o = &r->side[s];
        if (!o->name)
            continue;
        fprintf(f, ",\n    \"%s\": {\"qps_median\": %.0f, \"p50_ms\": %.3f, \"p99_ms\": %.3f, "
                "\"queries\": %llu, \"failed_batches\": %llu, \"cold_share\": %.4f, "
                "\"releases\": %llu, \"major_faults\": %llu, \"tiles_read\": %llu, "
                "\"bytes_read\": %llu, \"max_resident_mb\": %.1f, \"qps_rounds\": [",
                o->name, o->qps_median, o->p50_ms, o->p99_ms, (unsigned long long)o->queries,
                (unsigned long long)o->failed, o->cold_share, (unsigned long long)o->releases,
                (unsigned long long)o->majflt, (unsigned long long)o->tiles_created,
                (unsigned long long)o->bytes_read, o->max_res_mb);
        for (int i = 0; i < r->rounds; i++)
            fprintf(f, "%s%.0f", i ? ", " : "", o->qps[i]);
        fprintf(f, "], \"resident_mb\": [");
        for (int i = 0; i < o->nres; i++)
            fprintf(f, "%s[%.1f, %.1f]", i ? ", " : "", o->res_t[i], o->res_mb[i]);
        fprintf(f, "]");
        if (s == OOC_DAEMON) {
            fprintf(f, ", \"vmrss_mb\": [");
            for (int i = 0; i < o->nres; i++)
                fprintf(f, "%s%.1f", i ? ", " : "", o->rss_mb[i]);
            fprintf(f, "]");
        }
        fprintf(f, "}");
    }
    fprintf(f, "}");
}
