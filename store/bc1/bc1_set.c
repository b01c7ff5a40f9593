/* store/bc1/bc1_set.c - re-encoding a stored set into an ST_KIND_BC1 set (bc1.h), with seam
 * masking and the seam-aware endpoint solve.
 *
 * Owns: st_bc1_compress_set, st_bc1_opts_default, the BC1 set's ext (st_bc1_ext). Does not
 * own: the block encoder (bc1_encode.c), the seam systems and solves (seammask.c,
 * bc1_seam.c), files (dds.c).
 *
 * Pipeline: level 0 of every face -> global RGBA8 (seammask.h layout) -> masking (optional)
 * -> RGBA8 mip chain per face by 2x2 box reduction of the (masked) level above -> every
 * level encoded, split into items of at most 16 block rows, run by worker threads that take
 * items from a shared counter -> seam-aware solve on level 0 (optional). The calling thread
 * works too and is the only one that reports progress; every worker checks `cancel` between
 * items.
 */
#include "bc1.h"
#include "seammask.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define ROWS_PER_ITEM 16 /* block rows */

void st_bc1_opts_default(st_bc1_opts *o)
{
    memset(o, 0, sizeof *o);
    o->level = ST_BC1_HQ;
    o->seam_mode = ST_BC1_SEAM_AWARE;
    o->alpha = 2.0f;
    o->seam_boost = 1.25f;
    o->seam_rms_goal = 1.1f;
    o->step = 0.5f;
    o->iterations = 3;
    o->threads = 0;
    o->max_bytes = 0;
}

typedef struct item {
    uint32_t face, level, by0, by1;
} item;

typedef struct pool {
    const st_set *out;
    const uint8_t *const *lv;     /* lv[face_level_index] RGBA8 of that level */
    const st_seam_sys *sys;
    const float *w0;              /* per global level-0 texel weight, or NULL */
    const item *items;
    size_t nitems;
    int level;
    const volatile int *cancel;
    atomic_size_t next;
    atomic_ullong done_texels;
    atomic_int stop;
} pool;

static void run_item(pool *P, const item *it)
{
    const st_face *F = &P->out->faces[it->face];
    uint32_t w = st_level_w(F, it->level), h = st_level_h(F, it->level);
    uint32_t bw = (w + 3) / 4;
    const uint8_t *img = P->lv[F->lvl + it->level];
    uint8_t *blocks = st_face_level(P->out, it->face, it->level);
    uint32_t y0 = it->by0 * 4, y1 = it->by1 * 4 < h ? it->by1 * 4 : h;
    const float *wt = P->w0 && it->level == 0 ? P->w0 + P->sys->base[it->face] + (size_t)y0 * w : NULL;
    st_bc1_encode_image_w(img + (size_t)y0 * w * 4, wt, w, y1 - y0, (size_t)w * 4, P->level, 1,
                          blocks + (size_t)it->by0 * bw * 8, NULL);
    atomic_fetch_add(&P->done_texels, (unsigned long long)w * (y1 - y0));
}

static void *worker(void *arg)
{
    pool *P = arg;
    for (;;) {
        if (atomic_load(&P->stop) || (P->cancel && __atomic_load_n(P->cancel, __ATOMIC_RELAXED)))
            break;
        size_t i = atomic_fetch_add(&P->next, 1);
        if (i >= P->nitems)
            break;
        run_item(P, &P->items[i]);
    }
    return NULL;
}

static void bc1_ext_free(void *p) { free(p); }
static size_t bc1_ext_memory(const void *p) { (void)p; return sizeof(st_bc1_ext); }

void st_bc1_ext_attach(st_set *s, st_bc1_ext *x)
{
    st_set_ext_attach(s, &(st_set_ext){.kind = ST_EXT_BC1, .data = x, .free = bc1_ext_free,
                                       .memory = bc1_ext_memory});
}

/* 2x2 box reduction of an RGBA8 level (an odd last row/column is dropped, as set.c does). */
static void reduce(const uint8_t *src, uint32_t sw, uint32_t sh, uint8_t *dst, uint32_t dw,
                   uint32_t dh)
{
    uint32_t xs = sw > 1 ? 2 : 1, ys = sh > 1 ? 2 : 1;
    unsigned n = xs * ys;
    for (uint32_t y = 0; y < dh; y++)
        for (uint32_t x = 0; x < dw; x++)
            for (int c = 0; c < 4; c++) {
                unsigned acc = 0;
                for (uint32_t j = 0; j < ys; j++)
                    for (uint32_t i = 0; i < xs; i++)
                        acc += src[(((size_t)(y * ys + j)) * sw + x * xs + i) * 4 + c];
                dst[((size_t)y * dw + x) * 4 + c] = (uint8_t)((acc + n / 2) / n);
            }
}

static void report(st_bc1_progress_fn fn, void *arg, double f)
{
    if (fn)
        fn(arg, f < 0 ? 0 : f > 1 ? 1 : f);
}

/* the seam-aware solve's 0..1 is this call's 0.85..0.99 */
typedef struct seam_prog {
    st_bc1_progress_fn fn;
    void *arg;
} seam_prog;

static void on_seam_progress(void *arg, double f)
{
    seam_prog *sp = arg;
    report(sp->fn, sp->arg, 0.85 + 0.14 * f);
}

int st_bc1_compress_set(const st_set *src, const st_bc1_opts *o, st_bc1_progress_fn progress,
                        void *progress_arg, const volatile int *cancel, st_set **out,
                        st_error *e)
{
    *out = NULL;
    st_bc1_opts opts;
    if (o)
        opts = *o;
    else
        st_bc1_opts_default(&opts);
    if (src->info.kind == ST_KIND_BC1)
        return st_fail(e, ST_EINVAL, "set is already BC1");
    if (src->info.meshtype == ST_MESH_TRIANGLE)
        return st_fail(e, ST_EUNSUPPORTED, "%s", ST_BC1_TRIANGLE_REFUSAL);
    if (opts.seam_mode < ST_BC1_SEAM_NONE || opts.seam_mode > ST_BC1_SEAM_AWARE)
        return st_fail(e, ST_EINVAL, "seam mode %d unknown", opts.seam_mode);
    if (!(opts.alpha >= 0) || opts.alpha > 1e6 || !(opts.seam_boost >= 0) || opts.seam_boost > 1e3 ||
        !(opts.seam_rms_goal >= 0) || opts.seam_rms_goal > 1e3)
        return st_fail(e, ST_EINVAL, "seam weight alpha must be in 0..1e6, seam_boost and "
                                     "seam_rms_goal in 0..1e3");
    report(progress, progress_arg, 0);

    int rc;
    st_seam_sys *sys = NULL;
    uint8_t *orig = NULL, *work = NULL, **lv = NULL, *lvmem = NULL, **blk0 = NULL;
    item *items = NULL;
    float *w0 = NULL;
    st_set *s = NULL;
    st_face_desc *fd = NULL;
    rc = st_seam_sys_build(src, opts.seam_mode == ST_BC1_SEAM_NONE ? 4.0f : opts.step, &sys, e);
    if (rc)
        goto out;
    rc = st_seam_gather_rgba8(src, sys, &orig, e);
    if (rc)
        goto out;
    size_t gbytes = (size_t)sys->ntexels * 4;
    work = malloc(gbytes ? gbytes : 4);
    if (!work) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %zu bytes", gbytes);
        goto out;
    }
    memcpy(work, orig, gbytes);
    int punch = 0;
    if (src->info.alpha_chan >= 0)
        for (uint64_t i = 0; i < sys->ntexels && !punch; i++)
            punch = work[4 * i + 3] < 128;
    if (opts.seam_mode != ST_BC1_SEAM_NONE) {
        rc = st_seam_mask_rgba8(sys, opts.alpha, 0, work, cancel, e);
        if (rc)
            goto out;
    }
    report(progress, progress_arg, 0.1);

    /* the output set */
    st_set_info info = src->info;
    info.kind = ST_KIND_BC1;
    info.nchan = 4;
    info.dtype = ST_DT_U8;
    info.alpha_chan = src->info.alpha_chan >= 0 ? 3 : -1;
    fd = calloc(info.nfaces, sizeof *fd);
    if (!fd) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for face descriptions");
        goto out;
    }
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &src->faces[f];
        fd[f].w = F->w;
        fd[f].h = F->h;
        fd[f].flags = F->flags;
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = F->adjface[k];
            fd[f].adjedge[k] = (int8_t)F->adjedge[k];
        }
    }
    rc = st_set_create(&info, fd, opts.max_bytes, &s, e);
    if (rc)
        goto out;
    for (uint32_t i = 0; i < src->nmeta; i++) {
        const st_meta_entry *m = &src->meta[i];
        rc = st_set_meta_add(s, m->key, m->type, m->data, m->count, e);
        if (rc)
            goto out;
    }
    st_bc1_ext *x = calloc(1, sizeof *x);
    if (!x) {
        rc = st_fail(e, ST_ENOMEM, "out of memory");
        goto out;
    }
    x->src_kind = src->info.kind;
    x->src_nchan = src->info.nchan;
    x->src_alpha = src->info.alpha_chan;
    x->punchthrough = (uint8_t)punch;
    x->level = (uint8_t)(opts.level == ST_BC1_FAST || opts.level == ST_BC1_BEST ? opts.level
                                                                              : ST_BC1_HQ);
    x->seam_mode = (uint8_t)opts.seam_mode;
    st_bc1_ext_attach(s, x);

    /* RGBA8 levels of every face: level 0 points into `work`, the others into lvmem */
    size_t nlv = 0, mipbytes = 0;
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        nlv = F->lvl + F->nlevels > nlv ? F->lvl + F->nlevels : nlv;
        if (F->flags & ST_FACE_CONSTANT)
            continue;
        for (unsigned l = 1; l < F->nlevels; l++)
            mipbytes += (size_t)st_level_w(F, l) * st_level_h(F, l) * 4;
    }
    lv = calloc(nlv ? nlv : 1, sizeof *lv);
    lvmem = malloc(mipbytes ? mipbytes : 4);
    blk0 = calloc(info.nfaces, sizeof *blk0);
    if (!lv || !lvmem || !blk0) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of mip levels", mipbytes);
        goto out;
    }
    size_t off = 0, nitems = 0;
    uint64_t total_texels = 0;
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        if (F->flags & ST_FACE_CONSTANT) {
            memcpy(st_face_level(s, f, 0), work + sys->base[f] * 4, 4);
            continue;
        }
        blk0[f] = st_face_level(s, f, 0);
        lv[F->lvl] = work + sys->base[f] * 4;
        for (unsigned l = 1; l < F->nlevels; l++) {
            lv[F->lvl + l] = lvmem + off;
            reduce(lv[F->lvl + l - 1], st_level_w(F, l - 1), st_level_h(F, l - 1), lvmem + off,
                   st_level_w(F, l), st_level_h(F, l));
            off += (size_t)st_level_w(F, l) * st_level_h(F, l) * 4;
        }
        for (unsigned l = 0; l < F->nlevels; l++) {
            uint32_t bh = (st_level_h(F, l) + 3) / 4;
            nitems += (bh + ROWS_PER_ITEM - 1) / ROWS_PER_ITEM;
            total_texels += (uint64_t)st_level_w(F, l) * st_level_h(F, l);
        }
        if (cancel && __atomic_load_n(cancel, __ATOMIC_RELAXED)) {
            rc = st_fail(e, ST_ECANCELED, "compression cancelled");
            goto out;
        }
    }
    items = malloc((nitems ? nitems : 1) * sizeof *items);
    if (!items) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %zu work items", nitems);
        goto out;
    }
    size_t ni = 0;
    for (uint32_t f = 0; f < info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        if (F->flags & ST_FACE_CONSTANT)
            continue;
        for (unsigned l = 0; l < F->nlevels; l++) {
            uint32_t bh = (st_level_h(F, l) + 3) / 4;
            for (uint32_t by = 0; by < bh; by += ROWS_PER_ITEM)
                items[ni++] = (item){f, l, by, by + ROWS_PER_ITEM < bh ? by + ROWS_PER_ITEM : bh};
        }
    }

    /* seam-aware atlas: texels outside every chart are weighted down (0.05) in the level-0
     * encode, so that they do not take precision from what is seen; the seam solve then
     * sets them for the seams */
    if (opts.seam_mode == ST_BC1_SEAM_AWARE && src->info.kind == ST_KIND_ATLAS) {
        w0 = malloc((size_t)sys->ntexels * sizeof *w0 + 1);
        if (!w0) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for texel weights");
            goto out;
        }
        for (uint64_t i = 0; i < sys->ntexels; i++)
            w0[i] = sys->inside[i] ? 1.0f : 0.05f;
    }
    pool P;
    P.out = s;
    P.sys = sys;
    P.w0 = w0;
    P.lv = (const uint8_t *const *)lv;
    P.items = items;
    P.nitems = ni;
    P.level = opts.level;
    P.cancel = cancel;
    atomic_init(&P.next, 0);
    atomic_init(&P.done_texels, 0);
    atomic_init(&P.stop, 0);
    int threads = opts.threads;
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)n : 1;
    }
    if (threads > 64)
        threads = 64;
    if ((size_t)threads > ni)
        threads = ni ? (int)ni : 1;
    pthread_t tid[64];
    int started = 0;
    for (int t = 1; t < threads; t++) {
        if (pthread_create(&tid[started], NULL, worker, &P) != 0)
            break;
        started++;
    }
    /* the calling thread works and reports */
    for (;;) {
        if (cancel && __atomic_load_n(cancel, __ATOMIC_RELAXED))
            break;
        size_t i = atomic_fetch_add(&P.next, 1);
        if (i >= P.nitems)
            break;
        run_item(&P, &P.items[i]);
        double frac = total_texels ? (double)atomic_load(&P.done_texels) / (double)total_texels : 1;
        report(progress, progress_arg, 0.1 + 0.75 * frac);
    }
    atomic_store(&P.stop, 1);
    for (int t = 0; t < started; t++)
        pthread_join(tid[t], NULL);
    if (cancel && __atomic_load_n(cancel, __ATOMIC_RELAXED)) {
        rc = st_fail(e, ST_ECANCELED, "compression cancelled");
        goto out;
    }
    report(progress, progress_arg, 0.85);

    if (opts.seam_mode == ST_BC1_SEAM_AWARE) {
        float boost = opts.seam_boost > 0 ? opts.seam_boost : 1.25f;
        seam_prog sp = {progress, progress_arg};
        double goal = opts.seam_rms_goal > 0 ? opts.seam_rms_goal * st_seam_rms_rgba8(sys, work) : 0;
        rc = st_bc1_seam_solve(sys, orig, work, blk0, opts.alpha * boost, 0, opts.iterations, goal,
                               on_seam_progress, &sp, cancel, NULL, e);
        if (rc)
            goto out;
    }
    report(progress, progress_arg, 1);
    *out = s;
    s = NULL;
out:
    st_set_free(s);
    st_seam_sys_free(sys);
    free(orig);
    free(work);
    free(lv);
    free(lvmem);
    free(blk0);
    free(items);
    free(w0);
    free(fd);
    return rc;
}
