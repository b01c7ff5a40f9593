/* store/kinds/atlas.c - atlas sets: an image as face 0 of an ST_KIND_ATLAS set, its mesh and chart
 * mask in set->ext, and sampling by (u, v) in texture space.
 *
 * Owns: st_atlas_from_image, st_atlas_attach_mesh, st_atlas_get, st_atlas_free,
 * st_atlas_sample. Does not own: the filters (sample.c), seam finding (seams.c).
 *
 * The chart mask is rasterised once per mesh (texel centres inside a UV triangle, clipped to
 * the image, then dilated by one texel so bilinear taps at chart borders stay in), costing
 * w*h bytes. Chart-relative Discard with that mask (ST_ATLAS_CHART_DISCARD) is done here for
 * point and bilinear filters at level 0 (the mask exists for level 0 only); other filters fall
 * back to the sampler's Discard.
 *
 * The chart ids (st_atlas_build_chart_ids) are rasterised the same way, undilated, with the
 * mesh's chart of each triangle, and reduced level by level like the box mips (the majority
 * of the texels each level averages); the sampler's Discard reads them through
 * set->ext.charts (2 bytes per texel of every level, 8/3 bytes per level-0 texel). With ids,
 * st_atlas_attach_mesh rebuilds the image's levels >= 1 per chart (st_set_build_mips_labelled:
 * a chart's coarse texel averages that chart's texels alone, never the gutter or another
 * chart); without, they are the box means of the whole image.
 *
 * An atlas opened from a native file builds them on its first chart-mode sample instead
 * (st_atlas_charts_pin, atlas.h), and the memory budget may drop them again
 * (st_atlas_charts_drop); the native file stores the mesh and the mask, not the ids.
 */
#include "atlas.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

st_atlas *st_atlas_new(void)
{
    st_atlas *a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    /* the default attributes by the static initializers (what pthread_*_init(.., NULL) sets,
     * and no call that can fail) */
    a->charts_lock = (pthread_mutex_t)PTHREAD_MUTEX_INITIALIZER;
    a->charts_pin = (pthread_rwlock_t)PTHREAD_RWLOCK_INITIALIZER;
    atomic_init(&a->charts_built, 0);
    return a;
}

/* Frees the chart data (ids, links, triangle lists) and marks it not built. */
static void free_charts(st_atlas *a)
{
    atomic_store_explicit(&a->charts_built, 0, memory_order_release);
    __atomic_store_n(&a->charts_bytes, 0, __ATOMIC_RELAXED);
    st_atlas_free_links(a);
    st_atlas_free_locate(a);
    free(a->chart_id);
    a->chart_id = NULL;
    a->chart_id_bytes = 0;
    memset(&a->ids, 0, sizeof a->ids);
}

void st_atlas_free(void *p)
{
    st_atlas *a = p;
    if (!a)
        return;
    st_mesh_free(a->mesh);
    free(a->chart_mask);
    free_charts(a);
    pthread_mutex_destroy(&a->charts_lock);
    pthread_rwlock_destroy(&a->charts_pin);
    free(a);
}

const st_atlas *st_atlas_get(const st_set *s)
{
    if (!s || s->info.kind != ST_KIND_ATLAS)
        return NULL;
    return st_set_ext_get(s, ST_EXT_ATLAS);
}

static size_t atlas_memory(const void *p)
{
    const st_atlas *a = p;
    /* the chart data once built (a drop may zero it meanwhile) */
    return sizeof *a + st_mesh_memory(a->mesh) +
           (a->chart_mask ? (size_t)a->mask_w * a->mask_h : 0) +
           __atomic_load_n(&a->charts_bytes, __ATOMIC_RELAXED);
}

int st_atlas_charts_pin(const st_set *s, st_error *e)
{
    st_atlas *a = (st_atlas *)(uintptr_t)st_atlas_get(s);
    if (!a)
        return st_fail(e, ST_EINVAL, "not an atlas set");
    for (;;) {
        pthread_rwlock_rdlock(&a->charts_pin);
        if (atomic_load_explicit(&a->charts_built, memory_order_acquire))
            return ST_OK; /* a drop needs the exclusive side: the data stays until unpinned */
        pthread_rwlock_unlock(&a->charts_pin);
        int rc = ST_OK;
        pthread_mutex_lock(&a->charts_lock); /* (re)build once, then pin again */
        if (!atomic_load_explicit(&a->charts_built, memory_order_relaxed))
            rc = st_atlas_build_chart_ids(a, s, e);
        pthread_mutex_unlock(&a->charts_lock);
        if (rc)
            return rc;
    }
}

void st_atlas_charts_unpin(const st_set *s)
{
    st_atlas *a = (st_atlas *)(uintptr_t)st_atlas_get(s);
    if (a)
        pthread_rwlock_unlock(&a->charts_pin);
}

size_t st_atlas_charts_drop(const st_set *s)
{
    st_atlas *a = (st_atlas *)(uintptr_t)st_atlas_get(s);
    if (!a || !atomic_load_explicit(&a->charts_built, memory_order_acquire))
        return 0;
    if (pthread_rwlock_trywrlock(&a->charts_pin) != 0)
        return 0; /* a sampler is reading it: it is not cold */
    size_t freed = 0;
    pthread_mutex_lock(&a->charts_lock); /* no build in progress either */
    if (atomic_load_explicit(&a->charts_built, memory_order_relaxed)) {
        freed = __atomic_load_n(&a->charts_bytes, __ATOMIC_RELAXED);
        free_charts(a);
    }
    pthread_mutex_unlock(&a->charts_lock);
    pthread_rwlock_unlock(&a->charts_pin);
    return freed;
}

size_t st_atlas_charts_built_bytes(const st_set *s)
{
    const st_atlas *a = st_atlas_get(s);
    if (!a || !atomic_load_explicit(&((st_atlas *)(uintptr_t)a)->charts_built,
                                    memory_order_acquire))
        return 0;
    return __atomic_load_n(&a->charts_bytes, __ATOMIC_RELAXED);
}

void st_atlas_ext(st_atlas *a, st_set_ext *x)
{
    *x = (st_set_ext){.kind = ST_EXT_ATLAS, .data = a, .free = st_atlas_free,
                      .memory = atlas_memory, .charts = &a->ids,
                      .charts_pin = st_atlas_charts_pin,
                      .charts_unpin = st_atlas_charts_unpin};
}

/* Marks the texels whose centre lies in triangle abc (uv): mask[] = 1 when mask is not NULL;
 * ids[] = id when ids is not NULL and the texel has no id yet or a larger one (so where charts
 * overlap in uv, the lowest chart wins, whatever the triangle order). */
static void raster_tri(uint8_t *mask, uint16_t *ids, uint16_t id, uint32_t w, uint32_t h,
                       const float *a, const float *b, const float *c)
{
    /* texel space: x = u*w, y = v*h; texel (i, j) centre at (i+.5, j+.5) */
    double ax = a[0] * (double)w, ay = a[1] * (double)h, bx = b[0] * (double)w, by = b[1] * (double)h;
    double cx = c[0] * (double)w, cy = c[1] * (double)h;
    double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (area == 0 || !isfinite(area))
        return;
    /* the box is clipped to the image in double before it becomes an integer: Draco UVs are
     * any finite float, and (long) of 1e20 * w is undefined (on x86 LONG_MIN, which left a
     * triangle covering the whole image out of the mask) */
    double minx = fmax(floor(fmin(ax, fmin(bx, cx))), 0);
    double maxx = fmin(ceil(fmax(ax, fmax(bx, cx))), (double)w - 1);
    double miny = fmax(floor(fmin(ay, fmin(by, cy))), 0);
    double maxy = fmin(ceil(fmax(ay, fmax(by, cy))), (double)h - 1);
    if (minx > maxx || miny > maxy)
        return;
    long i0 = (long)minx, i1 = (long)maxx, j0 = (long)miny, j1 = (long)maxy;
    double sgn = area > 0 ? 1 : -1;
    for (long j = j0; j <= j1; j++)
        for (long i = i0; i <= i1; i++) {
            double px = i + 0.5, py = j + 0.5;
            double w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * sgn;
            double w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * sgn;
            double w2 = ((ax - px) * (by - py) - (ay - py) * (bx - px)) * sgn;
            if (w0 >= 0 && w1 >= 0 && w2 >= 0) {
                size_t k = (size_t)j * w + (size_t)i;
                if (mask)
                    mask[k] = 1;
                if (ids && (!ids[k] || id < ids[k]))
                    ids[k] = id;
            }
        }
}

/* Level l's id of a texel: the id most of its (up to 4) level l-1 texels with an id hold (the
 * texels the box mip averages, set.c's reduce_level), the lowest on a tie; 0 when none has. */
static void reduce_ids(const uint16_t *src, uint32_t sw, uint32_t sh, uint16_t *dst, uint32_t dw,
                       uint32_t dh)
{
    uint32_t xs = sw > 1 ? 2 : 1, ys = sh > 1 ? 2 : 1;
    for (uint32_t y = 0; y < dh; y++)
        for (uint32_t x = 0; x < dw; x++) {
            uint16_t c[4];
            unsigned n = 0;
            for (uint32_t j = 0; j < ys; j++)
                for (uint32_t i = 0; i < xs; i++) {
                    uint16_t v = src[(size_t)(y * ys + j) * sw + (x * xs + i)];
                    if (v)
                        c[n++] = v;
                }
            uint16_t best = 0;
            unsigned bestn = 0;
            for (unsigned k = 0; k < n; k++) {
                unsigned cnt = 0;
                for (unsigned m = 0; m < n; m++)
                    cnt += c[m] == c[k];
                if (cnt > bestn || (cnt == bestn && c[k] < best)) {
                    best = c[k];
                    bestn = cnt;
                }
            }
            dst[(size_t)y * dw + x] = best;
        }
}

/* Marks a's chart data built: what it holds, then the flag (release). */
static void charts_built(st_atlas *a)
{
    __atomic_store_n(&a->charts_bytes, a->chart_id_bytes + a->chart_link_bytes + a->loc.bytes,
                     __ATOMIC_RELAXED);
    atomic_store_explicit(&a->charts_built, 1, memory_order_release);
}

int st_atlas_build_chart_ids(st_atlas *a, const st_set *s, st_error *e)
{
    free_charts(a);
    const st_mesh *m = a->mesh;
    if (!m || !m->seams || !m->seams->tri_chart || m->seams->ncharts > 65534 || !s ||
        s->info.nfaces < 1) {
        charts_built(a); /* none to build */
        return ST_OK;    /* no ids: Discard takes the image as one face */
    }
    const st_face *F = &s->faces[0];
    unsigned nl = F->nlevels;
    size_t off[ST_MAX_LEVELS], total = 0;
    for (unsigned l = 0; l < nl; l++) {
        off[l] = total;
        total += (size_t)st_level_w(F, l) * st_level_h(F, l);
    }
    uint16_t *ids = calloc(total ? total : 1, sizeof *ids);
    if (!ids)
        return st_fail(e, ST_ENOMEM, "out of memory for the chart ids of a %ux%u atlas", F->w, F->h);
    for (uint32_t t = 0; t < m->ntri; t++) {
        const uint32_t *u = &m->tri_uv[(size_t)t * 3];
        uint32_t ch = m->seams->tri_chart[t];
        if (u[0] == ST_MESH_NO_UV || u[1] == ST_MESH_NO_UV || u[2] == ST_MESH_NO_UV ||
            ch >= m->seams->ncharts)
            continue;
        raster_tri(NULL, ids, (uint16_t)(ch + 1), F->w, F->h, &m->uv[(size_t)u[0] * 2],
                   &m->uv[(size_t)u[1] * 2], &m->uv[(size_t)u[2] * 2]);
    }
    for (unsigned l = 1; l < nl; l++)
        reduce_ids(ids + off[l - 1], st_level_w(F, l - 1), st_level_h(F, l - 1), ids + off[l],
                   st_level_w(F, l), st_level_h(F, l));
    a->chart_id = ids;
    a->chart_id_bytes = total * sizeof *ids;
    for (unsigned l = 0; l < nl; l++)
        a->ids.level[l] = ids + off[l];
    a->ids.nlevels = nl;
    int rc = st_atlas_build_links(a, s, e);
    if (rc == ST_OK)
        rc = st_atlas_build_locate(a, s, e);
    if (rc)   /* nothing half-built: no ids either, and not marked built */
        free_charts(a);
    else
        charts_built(a);
    return rc;
}

static int build_mask(st_atlas *a, const st_mesh *m, uint32_t w, uint32_t h, st_error *e)
{
    size_t n = (size_t)w * h;
    uint8_t *mask = calloc(n ? n : 1, 1);
    uint8_t *dil = calloc(n ? n : 1, 1);
    if (!mask || !dil) {
        free(mask);
        free(dil);
        return st_fail(e, ST_ENOMEM, "out of memory for a %ux%u chart mask", w, h);
    }
    for (uint32_t t = 0; t < m->ntri; t++) {
        const uint32_t *u = &m->tri_uv[(size_t)t * 3];
        if (u[0] == ST_MESH_NO_UV || u[1] == ST_MESH_NO_UV || u[2] == ST_MESH_NO_UV)
            continue;
        raster_tri(mask, NULL, 0, w, h, &m->uv[(size_t)u[0] * 2], &m->uv[(size_t)u[1] * 2],
                   &m->uv[(size_t)u[2] * 2]);
    }
    for (uint32_t j = 0; j < h; j++)
        for (uint32_t i = 0; i < w; i++) {
            uint8_t v = 0;
            for (int dj = -1; dj <= 1 && !v; dj++)
                for (int di = -1; di <= 1 && !v; di++) {
                    long x = (long)i + di, y = (long)j + dj;
                    if (x >= 0 && y >= 0 && x < (long)w && y < (long)h)
                        v = mask[(size_t)y * w + (size_t)x];
                }
            dil[(size_t)j * w + i] = v;
        }
    free(mask);
    free(a->chart_mask);
    a->chart_mask = dil;
    a->mask_w = w;
    a->mask_h = h;
    return ST_OK;
}

int st_atlas_attach_mesh(st_set *s, st_mesh *mesh, st_error *e)
{
    if (!s || s->info.kind != ST_KIND_ATLAS) {
        st_mesh_free(mesh);
        return st_fail(e, ST_EINVAL, "not an atlas set");
    }
    st_atlas *a = (st_atlas *)st_atlas_get(s);
    if (!a) {
        st_set_ext_attach(s, NULL);
        a = st_atlas_new();
        if (!a) {
            st_mesh_free(mesh);
            return st_fail(e, ST_ENOMEM, "out of memory for the atlas");
        }
        st_set_ext x;
        st_atlas_ext(a, &x);
        st_set_ext_attach(s, &x);
    }
    st_mesh_free(a->mesh);
    a->mesh = NULL;
    free(a->chart_mask);
    a->chart_mask = NULL;
    free_charts(a);
    if (!mesh) {
        charts_built(a); /* none */
        st_set_build_mips(s, 0); /* no charts: box means over the whole image */
        return ST_OK;
    }
    int rc = st_mesh_find_seams(mesh, e);
    if (rc == ST_OK)
        rc = build_mask(a, mesh, s->faces[0].w, s->faces[0].h, e);
    if (rc) {
        st_mesh_free(mesh);
        return rc;
    }
    a->mesh = mesh;
    if ((rc = st_atlas_build_chart_ids(a, s, e)) != ST_OK) {
        a->mesh = NULL;
        st_mesh_free(mesh);
        free(a->chart_mask);
        a->chart_mask = NULL;
        return rc;
    }
    /* per-chart mips: a coarse texel of a chart averages that chart's texels alone, never the
     * gutter's or another chart's (no ids: the box means of the whole image) */
    st_set_build_mips_labelled(s, 0, a->ids.nlevels ? a->ids.level : NULL);
    return ST_OK;
}

int st_atlas_from_image(const st_image *img, st_mesh *mesh, size_t max_bytes, st_set **out,
                        st_error *e)
{
    *out = NULL;
    if (!img || !img->data || img->nchan < 1 || img->nchan > 4 || !st_dtype_size(img->dtype)) {
        st_mesh_free(mesh);
        return st_fail(e, ST_EINVAL, "no image to make an atlas of");
    }
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 1;
    info.nchan = img->nchan;
    info.dtype = img->dtype;
    info.alpha_chan = img->alpha_chan;
    info.premultiplied = img->alpha_chan >= 0 && img->premultiplied;
    info.kind = ST_KIND_ATLAS;
    info.colorspace = img->colorspace;
    st_face_desc fd;
    memset(&fd, 0, sizeof fd);
    fd.w = img->w;
    fd.h = img->h;
    for (int k = 0; k < 4; k++)
        fd.adjface[k] = -1;
    int rc = st_set_create(&info, &fd, max_bytes, out, e);
    if (rc) {
        st_mesh_free(mesh);
        return rc;
    }
    st_set *s = *out;
    memcpy(st_face_level(s, 0, 0), img->data, (size_t)img->w * img->h * st_texel_size(s));
    if (!mesh)
        st_set_build_mips(s, 0); /* else st_atlas_attach_mesh builds them, per chart */
    st_atlas *a = st_atlas_new();
    if (!a) {
        st_set_free(s);
        *out = NULL;
        st_mesh_free(mesh);
        return st_fail(e, ST_ENOMEM, "out of memory for the atlas");
    }
    st_set_ext x;
    st_atlas_ext(a, &x);
    st_set_ext_attach(s, &x);
    if (mesh && (rc = st_atlas_attach_mesh(s, mesh, e)) != ST_OK) {
        st_set_free(s);
        *out = NULL;
        return rc;
    }
    return ST_OK;
}

static int mask_at(const st_atlas *a, long x, long y)
{
    if (x < 0 || y < 0 || x >= (long)a->mask_w || y >= (long)a->mask_h)
        return 0;
    return a->chart_mask[(size_t)y * a->mask_w + (size_t)x];
}

/* Chart-relative Discard for one query, point or bilinear at level 0. */
static void chart_sample(const st_set *s, const st_atlas *a, const st_sample_opts *o,
                         const st_query *q, float *out, float *cov, uint8_t *st)
{
    const st_face *F = &s->faces[0];
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    size_t ts = st_texel_size(s);
    const uint8_t *p = st_face_level(s, 0, 0);
    float acc[4] = {0, 0, 0, 0}, wsum = 0;
    if (o->filter == ST_FILTER_POINT) {
        long x = (long)floorf(q->u * (float)F->w), y = (long)floorf(q->v * (float)F->h);
        if (x >= 0 && y >= 0 && x < (long)F->w && y < (long)F->h && mask_at(a, x, y)) {
            for (unsigned c = 0; c < nc; c++)
                acc[c] = st_channel_get(dt, p + ((size_t)y * F->w + (size_t)x) * ts, c);
            wsum = 1;
        }
    } else {
        float fx = q->u * (float)F->w - 0.5f, fy = q->v * (float)F->h - 0.5f;
        long x0 = (long)floorf(fx), y0 = (long)floorf(fy);
        float ax = fx - (float)x0, ay = fy - (float)y0;
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) {
                long x = x0 + i, y = y0 + j;
                float w = (i ? ax : 1 - ax) * (j ? ay : 1 - ay);
                if (w <= 0 || x < 0 || y < 0 || x >= (long)F->w || y >= (long)F->h || !mask_at(a, x, y))
                    continue;
                for (unsigned c = 0; c < nc; c++)
                    acc[c] += w * st_channel_get(dt, p + ((size_t)y * F->w + (size_t)x) * ts, c);
                wsum += w;
            }
    }
    if (wsum > 0) {
        for (unsigned c = 0; c < nc; c++)
            out[c] = acc[c] / wsum;
        *cov = wsum;
        *st = ST_Q_OK;
    } else {
        for (unsigned c = 0; c < nc; c++)
            out[c] = NAN;
        *cov = 0;
        *st = ST_Q_ZERO_COVERAGE;
    }
}

int st_atlas_sample(const st_set *s, const st_sample_opts *o, unsigned flags, const st_query *q,
                    size_t n, float *out, float *coverage, uint8_t *status)
{
    if (!s || s->info.kind != ST_KIND_ATLAS || !o || !out)
        return ST_EINVAL;
    /* the modes as st_sample_batch (and so SAMPLE over the wire) takes them: face 0 has four
     * boundary edges, so Traverse drops the taps beyond the image border as at any boundary */
    st_sample_opts oo = *o;
    const st_atlas *a = st_atlas_get(s);
    int chart = (flags & ST_ATLAS_CHART_DISCARD) && oo.mode == ST_MODE_DISCARD && a &&
                a->chart_mask && (oo.filter == ST_FILTER_POINT || oo.filter == ST_FILTER_BILINEAR);
    enum { B = 128 };
    st_query fq[B];
    uint8_t st[B];
    float cv[B];
    int bad = 0;
    unsigned nc = s->info.nchan;
    for (size_t i0 = 0; i0 < n; i0 += B) {
        size_t m = n - i0 < B ? n - i0 : B;
        for (size_t k = 0; k < m; k++) {
            fq[k] = q[i0 + k];
            fq[k].face = 0;
        }
        if (chart) {
            for (size_t k = 0; k < m; k++) {
                const st_query *x = &fq[k];
                if (!isfinite(x->u) || !isfinite(x->v) || fabsf(x->u) > ST_MAX_COORD ||
                    fabsf(x->v) > ST_MAX_COORD) {
                    /* as st_sample_batch refuses them (and (long) of u * w stays defined) */
                    st[k] = isfinite(x->u) && isfinite(x->v) ? ST_Q_BAD_FOOTPRINT : ST_Q_NONFINITE;
                    cv[k] = 0;
                    for (unsigned c = 0; c < nc; c++)
                        out[(i0 + k) * nc + c] = NAN;
                    continue;
                }
                chart_sample(s, a, &oo, x, out + (i0 + k) * nc, &cv[k], &st[k]);
            }
        } else {
            int r = st_sample_batch(s, &oo, fq, m, out + i0 * nc, cv, st);
            if (r < 0)
                return r;
        }
        for (size_t k = 0; k < m; k++) {
            if (st[k] != ST_Q_OK)
                bad++;
            if (status)
                status[i0 + k] = st[k];
            if (coverage)
                coverage[i0 + k] = cv[k];
        }
    }
    return bad;
}
