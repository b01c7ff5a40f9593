/* store/ptex/ptexres.c - builds the table of every (ulog2', vlog2') resolution of every face, with
 * the Ptex reader's rules for the ones it makes on demand (see ptexres.h).
 *
 * Work: one pass decides, per face and resolution, where the data comes from (a set level, the
 * constant value, or a 2:1 reduction of a larger resolution) and sums the bytes; one
 * allocation; one pass from large to small resolutions fills the arena. Sizes were already
 * checked when the set was created; the arena is checked against max_bytes.
 */
#include "ptexres.h"
#include "ptexfilter.h"

#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "ptex_format.h"

/* The arena: large ones 2 MiB aligned and marked for transparent huge pages (the table is
 * written once, right away; 4 KiB page faults were a third of the load time). */
static uint8_t *arena_alloc(size_t bytes)
{
    size_t want = bytes + 64; /* slack: the filter loads 16 bytes per texel */
    const size_t huge = (size_t)2 << 20;
    if (want < 2 * huge)
        return malloc(want);
    size_t rounded = (want + huge - 1) & ~(huge - 1);
    uint8_t *p = aligned_alloc(huge, rounded);
#ifdef MADV_HUGEPAGE
    if (p)
        madvise(p, rounded, MADV_HUGEPAGE);
#endif
    return p;
}

static size_t ptexres_memory(const void *p)
{
    const st_ptexres *t = p;
    return __atomic_load_n(&t->built, __ATOMIC_ACQUIRE) ? t->bytes : sizeof *t;
}

/* Frees what a build made (the header stays). */
static void ptexres_clear(st_ptexres *t)
{
    free(t->base);
    free(t->px);
    free(t->ptxflags);
    free(t->nstored);
    free(t->arena);
    t->base = NULL;
    t->px = NULL;
    t->ptxflags = t->nstored = t->arena = NULL;
    t->arena_bytes = 0;
    t->bytes = 0;
}

static void ptexres_free(void *p)
{
    st_ptexres *t = p;
    if (!t)
        return;
    ptexres_clear(t);
    if (t->lazy)
        pthread_rwlock_destroy(&t->rw);
    free(t);
}

static st_ptexres *ptexres_of(const st_set *s)
{
    st_ptexres *t = st_set_ext_get(s, ST_EXT_PTEXRES);
    return t && t->magic == ST_PTEXRES_MAGIC ? t : NULL;
}

const st_ptexres *st_ptexres_get(const st_set *s)
{
    st_ptexres *t = ptexres_of(s);
    return t && __atomic_load_n(&t->built, __ATOMIC_ACQUIRE) ? t : NULL;
}

size_t st_ptexres_built_bytes(const st_set *s)
{
    const st_ptexres *t = st_ptexres_get(s);
    return t ? t->bytes - sizeof *t : 0;
}

/* Ptex's 2:1 reductions of interleaved texels: integers halve with truncation, half and float
 * take 0.5 * (a + b) in float (half rounds back to nearest even). One loop per dtype over
 * channel elements so that the compiler vectorises it. d[i] = reduce(a[i], b[i]), i < n. */
static void reduce_run(unsigned dt, const uint8_t *a, const uint8_t *b, uint8_t *d, size_t n,
                       size_t step)
{
    /* step: distance in elements between the two operands of a pair inside a (reduce in u
     * pairs neighbouring texels: a row is read as texel pairs) - 0 means a and b are rows */
    switch (dt) {
    case ST_DT_U8:
        for (size_t i = 0; i < n; i++)
            d[i] = (uint8_t)((a[i] + b[i]) >> 1);
        break;
    case ST_DT_U16: {
        const uint16_t *x = (const uint16_t *)(const void *)a, *y = (const uint16_t *)(const void *)b;
        uint16_t *z = (uint16_t *)(void *)d;
        for (size_t i = 0; i < n; i++)
            z[i] = (uint16_t)(((uint32_t)x[i] + y[i]) >> 1);
        break;
    }
    case ST_DT_HALF: {
        const uint16_t *x = (const uint16_t *)(const void *)a, *y = (const uint16_t *)(const void *)b;
        uint16_t *z = (uint16_t *)(void *)d;
        for (size_t i = 0; i < n; i++)
            z[i] = st_float_to_half(0.5f * (st_half_to_float(x[i]) + st_half_to_float(y[i])));
        break;
    }
    default: {
        const float *x = (const float *)(const void *)a, *y = (const float *)(const void *)b;
        float *z = (float *)(void *)d;
        for (size_t i = 0; i < n; i++)
            z[i] = 0.5f * (x[i] + y[i]);
        break;
    }
    }
    (void)step;
}

/* src is sw x sh; reduce u (dst sw/2 x sh) or v (dst sw x sh/2). */
static void reduce_axis(unsigned dt, unsigned nc, const uint8_t *src, uint32_t sw, uint32_t sh,
                        uint8_t *dst, int in_u)
{
    size_t cs = st_dtype_size(dt), ts = cs * nc;
    if (in_u && dt != ST_DT_HALF) {
        /* pairs of neighbouring texels, channel by channel */
        uint32_t dw = sw / 2;
        size_t n = (size_t)dw * sh;
        switch (dt) {
        case ST_DT_U8:
            for (size_t t = 0; t < n; t++)
                for (unsigned c = 0; c < nc; c++)
                    dst[t * nc + c] = (uint8_t)((src[2 * t * nc + c] + src[(2 * t + 1) * nc + c]) >> 1);
            break;
        case ST_DT_U16: {
            const uint16_t *x = (const uint16_t *)(const void *)src;
            uint16_t *z = (uint16_t *)(void *)dst;
            for (size_t t = 0; t < n; t++)
                for (unsigned c = 0; c < nc; c++)
                    z[t * nc + c] = (uint16_t)(((uint32_t)x[2 * t * nc + c] + x[(2 * t + 1) * nc + c]) >> 1);
            break;
        }
        default: {
            const float *x = (const float *)(const void *)src;
            float *z = (float *)(void *)dst;
            for (size_t t = 0; t < n; t++)
                for (unsigned c = 0; c < nc; c++)
                    z[t * nc + c] = 0.5f * (x[2 * t * nc + c] + x[(2 * t + 1) * nc + c]);
            break;
        }
        }
        (void)cs;
    } else if (in_u) {
        /* half: gather even and odd texels of each row, then one run */
        uint32_t dw = sw / 2;
        uint8_t ev[1024], od[1024];
        size_t chunk = sizeof ev / ts; /* texels per chunk */
        for (uint32_t y = 0; y < sh; y++) {
            const uint8_t *row = src + (size_t)y * sw * ts;
            uint8_t *drow = dst + (size_t)y * dw * ts;
            for (uint32_t x0 = 0; x0 < dw; x0 += (uint32_t)chunk) {
                uint32_t m = dw - x0 < chunk ? dw - x0 : (uint32_t)chunk;
                for (uint32_t x = 0; x < m; x++) {
                    memcpy(ev + x * ts, row + (size_t)(2 * (x0 + x)) * ts, ts);
                    memcpy(od + x * ts, row + (size_t)(2 * (x0 + x) + 1) * ts, ts);
                }
                reduce_run(dt, ev, od, drow + (size_t)x0 * ts, (size_t)m * nc, 0);
            }
        }
    } else {
        uint32_t dh = sh / 2;
        size_t rowb = (size_t)sw * ts;
        for (uint32_t y = 0; y < dh; y++)
            reduce_run(dt, src + (size_t)(2 * y) * rowb, src + (size_t)(2 * y + 1) * rowb,
                       dst + (size_t)y * rowb, (size_t)sw * nc, 0);
    }
}

/* Ptex's PtexUtils::average: float sum, scaled, converted with truncation for integers. */
static void average_px(unsigned dt, unsigned nc, const uint8_t *src, size_t n, uint8_t *dst)
{
    float acc[ST_MAX_CHANNELS] = {0};
    size_t ts = st_dtype_size(dt) * nc;
    for (size_t i = 0; i < n; i++)
        for (unsigned c = 0; c < nc; c++) {
            const uint8_t *p = src + i * ts;
            float v;
            switch (dt) {
            case ST_DT_U8: v = p[c]; break;
            case ST_DT_U16: { uint16_t x; memcpy(&x, p + 2 * c, 2); v = x; break; }
            case ST_DT_HALF: { uint16_t x; memcpy(&x, p + 2 * c, 2); v = st_half_to_float(x); break; }
            default: memcpy(&v, p + 4 * c, 4); break;
            }
            acc[c] += v;
        }
    float scale = 1.0f / (float)n;
    for (unsigned c = 0; c < nc; c++) {
        float v = acc[c] * scale;
        switch (dt) {
        case ST_DT_U8: dst[c] = (uint8_t)v; break;
        case ST_DT_U16: { uint16_t x = (uint16_t)v; memcpy(dst + 2 * c, &x, 2); break; }
        case ST_DT_HALF: { uint16_t x = st_float_to_half(v); memcpy(dst + 2 * c, &x, 2); break; }
        default: memcpy(dst + 4 * c, &v, 4); break;
        }
    }
}

/* Where the data of (ru, rv) comes from: >= 0 a set level, -1 the constant value, -2 reduce
 * in u from (ru+1, rv), -3 reduce in v from (ru, rv+1). */
static int source_of(unsigned U, unsigned V, unsigned ru, unsigned rv, unsigned nstored,
                     int hasedits)
{
    if (ru == 0 && rv == 0)
        return -1;
    unsigned redu = U - ru, redv = V - rv;
    if (redu == 0 && redv == 0)
        return 0;
    if (redu == redv && !hasedits && redu < nstored)
        return (int)redu;
    int blendu = redu == redv ? (int)(ru & 1) : redu > redv;
    return blendu ? -2 : -3;
}

/* Fills t (base, px, ptxflags, nstored, arena, bytes) for s. rewrite: overwrite the set's
 * levels that Ptex does not store with the values Ptex serves (a heap set being imported);
 * 0 for a set that already holds them (a mapped native set: never written). On failure t is
 * left cleared. */
static int ptexres_build(st_ptexres *t, const st_set *s, const uint8_t *constpx,
                         const uint8_t *ptxflags, const uint8_t *nstored, size_t max_bytes,
                         int rewrite, st_error *e)
{
    uint32_t n = s->info.nfaces;
    unsigned dt = s->info.dtype, nc = s->info.nchan;
    size_t ts = st_texel_size(s);
    t->base = malloc((size_t)n * sizeof *t->base);
    t->ptxflags = calloc(n, 1);
    t->nstored = calloc(n, 1);
    if (!t->base || !t->ptxflags || !t->nstored)
        goto nomem;
    size_t nent = 0, bytes = 0;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        t->base[f] = nent;
        t->ptxflags[f] = ptxflags ? ptxflags[f] : (uint8_t)((F->flags & ST_FACE_CONSTANT ?
                            PTX_FLAG_CONSTANT : 0) | (F->flags & ST_FACE_SUBFACE ? PTX_FLAG_SUBFACE : 0));
        if (F->flags & ST_FACE_CONSTANT) {
            nent++;
            continue;
        }
        unsigned U = F->ulog2, V = F->vlog2;
        unsigned ns = nstored ? nstored[f] : (U < V ? U : V) + 1u;
        t->nstored[f] = (uint8_t)ns;
        int he = (t->ptxflags[f] & PTX_FLAG_HASEDITS) != 0;
        nent += (size_t)(U + 1) * (V + 1);
        for (unsigned ru = 0; ru <= U; ru++)
            for (unsigned rv = 0; rv <= V; rv++)
                if (source_of(U, V, ru, rv, ns, he) < 0) {
                    bytes += ((size_t)1 << (ru + rv)) * ts;
                    if (bytes > max_bytes) {
                        ptexres_clear(t);
                        return st_fail(e, ST_ETOOBIG, "Ptex resolution table needs more than "
                                       "%zu bytes (at face %u)", max_bytes, f);
                    }
                }
    }
    t->px = malloc(nent * sizeof *t->px);
    t->arena = arena_alloc(bytes);
    t->arena_bytes = bytes;
    if (!t->px || !t->arena)
        goto nomem;
    size_t off = 0;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        const uint8_t **px = t->px + t->base[f];
        if (F->flags & ST_FACE_CONSTANT) {
            px[0] = st_face_level(s, f, 0);
            continue;
        }
        unsigned U = F->ulog2, V = F->vlog2;
        unsigned ns = t->nstored[f];
        int he = (t->ptxflags[f] & PTX_FLAG_HASEDITS) != 0;
        /* from the largest resolution sum down, so that sources exist */
        for (int sum = (int)(U + V); sum >= 0; sum--) {
            for (unsigned ru = 0; ru <= U; ru++) {
                int rvi = sum - (int)ru;
                if (rvi < 0 || rvi > (int)V)
                    continue;
                unsigned rv = (unsigned)rvi;
                int src = source_of(U, V, ru, rv, ns, he);
                size_t idx = (size_t)ru * (V + 1) + rv;
                if (src >= 0) {
                    px[idx] = st_face_level(s, f, (unsigned)src);
                    continue;
                }
                uint8_t *d = t->arena + off;
                off += ((size_t)1 << (ru + rv)) * ts;
                px[idx] = d;
                if (src == -1) {
                    if (constpx)
                        memcpy(d, constpx + (size_t)f * ts, ts);
                    else
                        average_px(dt, nc, st_face_level(s, f, 0), (size_t)F->w * F->h, d);
                } else if (src == -2) {
                    reduce_axis(dt, nc, px[(size_t)(ru + 1) * (V + 1) + rv], 1u << (ru + 1),
                                1u << rv, d, 1);
                } else {
                    reduce_axis(dt, nc, px[idx + 1], 1u << ru, 1u << (rv + 1), d, 0);
                }
            }
        }
        /* the set's levels that Ptex does not store: the values Ptex serves for them (a
         * mapped set already holds them: its file was written after this rewrite) */
        for (unsigned l = 1; rewrite && l < F->nlevels; l++) {
            unsigned ru = U > l ? U - l : 0, rv = V > l ? V - l : 0;
            const uint8_t *p = px[(size_t)ru * (V + 1) + rv];
            uint8_t *q = st_face_level(s, f, l);
            if (p != q)
                memcpy(q, p, ((size_t)1 << (ru + rv)) * ts);
        }
    }
    t->bytes = sizeof *t + (size_t)t->nfaces * (sizeof *t->base + 2) + nent * sizeof *t->px +
               t->arena_bytes;
    return ST_OK;
nomem:
    ptexres_clear(t);
    return st_fail(e, ST_ENOMEM, "out of memory for the Ptex resolution table");
}

int st_ptexres_attach(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                      const uint8_t *nstored, size_t max_bytes, st_error *e)
{
    if (s->ext.kind != ST_EXT_NONE)
        return st_fail(e, ST_EINVAL, "set already has an extension; cannot attach the Ptex table");
    if (s->map)
        return st_fail(e, ST_EINVAL, "a mapped set takes a lazy Ptex table");
    st_ptexres *t = calloc(1, sizeof *t);
    if (!t)
        return st_fail(e, ST_ENOMEM, "out of memory for the Ptex table");
    t->magic = ST_PTEXRES_MAGIC;
    t->nfaces = s->info.nfaces;
    int rc = ptexres_build(t, s, constpx, ptxflags, nstored,
                           max_bytes ? max_bytes : ST_DEFAULT_MAX_BYTES, 1, e);
    if (rc) {
        free(t);
        return rc;
    }
    t->built = 1;
    t->nbuilds = 1;
    /* the Ptex filter family registers itself with the sampler through the extension */
    st_set_ext_attach(s, &(st_set_ext){.kind = ST_EXT_PTEXRES, .data = t, .free = ptexres_free,
                                       .memory = ptexres_memory,
                                       .filter = st_ptexfilter_batch});
    return ST_OK;
}

/* ---- lazy tables (native sets) ------------------------------------------------------------- */

/* Builds t under the exclusive lock when it is not built. Caller holds nothing. */
static int lazy_build(st_ptexres *t, const st_set *s)
{
    if (__atomic_load_n(&t->built, __ATOMIC_ACQUIRE))
        return ST_OK;
    pthread_rwlock_wrlock(&t->rw);
    int rc = ST_OK;
    if (!t->built) {
        st_error e;
        st_error_clear(&e);
        rc = ptexres_build(t, s, t->in_const, t->in_flags, t->in_nstored, t->max_bytes, 0, &e);
        if (!rc) {
            __atomic_store_n(&t->built, 1, __ATOMIC_RELEASE);
            __atomic_add_fetch(&t->nbuilds, 1, __ATOMIC_RELAXED);
        }
    }
    pthread_rwlock_unlock(&t->rw);
    return rc;
}

/* The filter entry of a lazy table: build on first use, then filter under the shared lock
 * (a drop waits for no filter: it only tries the exclusive lock). */
static int lazy_filter(const st_set *s, const struct st_sample_opts *o, const struct st_query *q,
                       size_t n, float *out, float *coverage, uint8_t *status)
{
    st_ptexres *t = ptexres_of(s);
    if (!t)
        return ST_EUNSUPPORTED;
    for (;;) {
        int rc = lazy_build(t, s);
        if (rc)
            return rc;
        pthread_rwlock_rdlock(&t->rw);
        if (__atomic_load_n(&t->built, __ATOMIC_ACQUIRE))
            break;
        pthread_rwlock_unlock(&t->rw);  /* dropped in between: build again */
    }
    int rc = st_ptexfilter_batch(s, o, q, n, out, coverage, status);
    pthread_rwlock_unlock(&t->rw);
    return rc;
}

int st_ptexres_attach_lazy(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                           const uint8_t *nstored, size_t max_bytes, st_error *e)
{
    if (s->ext.kind != ST_EXT_NONE)
        return st_fail(e, ST_EINVAL, "set already has an extension; cannot attach the Ptex table");
    if (!constpx || !ptxflags || !nstored)
        return st_fail(e, ST_EINVAL, "a lazy Ptex table needs its per-face inputs");
    st_ptexres *t = calloc(1, sizeof *t);
    if (!t)
        return st_fail(e, ST_ENOMEM, "out of memory for the Ptex table");
    t->magic = ST_PTEXRES_MAGIC;
    t->nfaces = s->info.nfaces;
    t->lazy = 1;
    t->in_const = constpx;
    t->in_flags = ptxflags;
    t->in_nstored = nstored;
    t->max_bytes = max_bytes ? max_bytes : ST_DEFAULT_MAX_BYTES;
    pthread_rwlock_init(&t->rw, NULL);
    st_set_ext_attach(s, &(st_set_ext){.kind = ST_EXT_PTEXRES, .data = t, .free = ptexres_free,
                                       .memory = ptexres_memory, .filter = lazy_filter});
    return ST_OK;
}

const st_ptexres *st_ptexres_ensure(const st_set *s)
{
    st_ptexres *t = ptexres_of(s);
    if (!t)
        return NULL;
    if (t->lazy && lazy_build(t, s) != ST_OK)
        return NULL;
    return st_ptexres_get(s);
}

size_t st_ptexres_drop(const st_set *s)
{
    st_ptexres *t = ptexres_of(s);
    if (!t || !t->lazy || !__atomic_load_n(&t->built, __ATOMIC_ACQUIRE))
        return 0;
    if (pthread_rwlock_trywrlock(&t->rw) != 0)
        return 0;  /* a filter is reading it: it is not cold */
    size_t freed = 0;
    if (t->built) {
        freed = t->bytes - sizeof *t;
        __atomic_store_n(&t->built, 0, __ATOMIC_RELEASE);
        ptexres_clear(t);
    }
    pthread_rwlock_unlock(&t->rw);
    return freed;
}
