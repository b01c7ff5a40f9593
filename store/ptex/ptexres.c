/* store/ptex/ptexres.c - the Ptex reader's rules for the resolutions it makes on demand (see
 * ptexres.h): filling a set's unstored levels with them at import, and the lazily built table
 * of every (ulog2', vlog2') resolution of every face.
 *
 * Levels (st_ptexres_fill_levels, at import): a set level L that the file did not store is
 * (U-L, V-L) while both axes still halve, which Ptex makes as a v reduction of a u reduction
 * of level L-1 (or u of v: the order alternates with the parity of U-L), and past the smaller
 * axis a single 2:1 reduction of level L-1 along the larger one; 1x1 is the constant value.
 * So filling a level reads only the level before it (plus one scratch of half its size).
 * A triangle set's faces are square and every level is the triangle reduction of the one
 * before (trilevel.h), as Ptex's reader makes them; its table is never built (the triangle
 * filter, ptextri_filter.c, reads only square resolutions: the set's levels).
 *
 * Table (st_ptexres_table, first Ptex-filter call): one pass decides, per face and
 * resolution, where the data comes from (a set level - which now holds exactly what Ptex
 * serves for it - or a 2:1 reduction of a larger resolution) and sums the bytes; one
 * allocation; one pass from large to small resolutions fills the arena. Built once under
 * the record's mutex; readers test `built` with acquire ordering, so a thread that sees 1
 * sees every pointer and texel. Sizes were already checked when the set was created; the
 * arena is checked against max_bytes. The build also sets the faces' zero bits in lanef
 * (zero_ring: constant faces of zero texels, and faces whose whole Traverse ring is such).
 */
#include "ptexres.h"
#include "loadpath.h"
#include "ptexfilter.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "ptex_format.h"
#include "trilevel.h"

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

/* The record (three bytes per face) always; what makes deferred levels while they are
 * pending; the table once it is built. */
static size_t ptexres_memory(const void *p)
{
    const st_ptexres *t = p;
    size_t m = sizeof *t + (size_t)t->nfaces * 3;
    m += __atomic_load_n(&t->def_bytes, __ATOMIC_RELAXED); /* 0 once made (or failed) */
    if (atomic_load_explicit(&((st_ptexres *)(uintptr_t)t)->built, memory_order_acquire))
        m += __atomic_load_n(&t->bytes, __ATOMIC_RELAXED); /* a drop may zero it meanwhile */
    return m;
}

/* Frees what made the deferred levels (under levels_lock, or with the record unshared). */
static void def_free(st_ptexres *t)
{
    if (!t->def)
        return;
    if (t->def->free)
        t->def->free(t->def->data);
    free(t->def);
    t->def = NULL;
    __atomic_store_n(&t->def_bytes, 0, __ATOMIC_RELAXED);
}

static void ptexres_free(void *p)
{
    st_ptexres *t = p;
    if (!t)
        return;
    pthread_mutex_destroy(&t->lock);
    pthread_mutex_destroy(&t->levels_lock);
    pthread_rwlock_destroy(&t->pin);
    def_free(t);
    free(t->base);
    free(t->px);
    free(t->ptxflags);
    free(t->nstored);
    free(t->lanef);
    free(t->arena);
    free(t->ctiles);
    free(t);
}

int st_ptexres_set_ctiles(st_set *s, const st_ptexres_ctile *c, uint32_t n, st_error *e)
{
    st_ptexres *t = (st_ptexres *)st_ptexres_get(s);
    if (!t)
        return st_fail(e, ST_EINVAL, "set has no Ptex table");
    st_ptexres_ctile *cp = NULL;
    if (n && !(cp = malloc((size_t)n * sizeof *cp)))
        return st_fail(e, ST_ENOMEM, "out of memory for %u constant-tile records", n);
    if (n)
        memcpy(cp, c, (size_t)n * sizeof *cp);
    free(t->ctiles);
    t->ctiles = cp;
    t->nctiles = n;
    return ST_OK;
}

/* The ctiles record of face f's stored level l, or NULL. */
static const st_ptexres_ctile *ctile_of(const st_ptexres *t, uint32_t f, unsigned l)
{
    uint32_t lo = 0, hi = t->nctiles;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        const st_ptexres_ctile *c = &t->ctiles[mid];
        if (c->face < f || (c->face == f && c->level < l))
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < t->nctiles && t->ctiles[lo].face == f && t->ctiles[lo].level == l
               ? &t->ctiles[lo] : NULL;
}

/* What Ptex's getData(f, (ru, rv)) returns: 0 packed data (or tiles not all one constant),
 * 1 a constant face, 2 tiles all one constant of 2^*tu x 2^*tv texels. */
static int served_kind(const st_ptexres *t, const st_set *s, uint32_t f, int ru, int rv, int *tu,
                       int *tv)
{
    const st_face *F = &s->faces[f];
    if (ru == 0 && rv == 0)
        return 1;
    int redu = (int)F->ulog2 - ru, redv = (int)F->vlog2 - rv;
    if ((redu == 0 && redv == 0) ||
        (redu == redv && !(t->ptxflags[f] & PTX_FLAG_HASEDITS) && redu < (int)t->nstored[f])) {
        const st_ptexres_ctile *c = ctile_of(t, f, (unsigned)redu);
        if (!c)
            return 0;
        *tu = c->tu;
        *tv = c->tv;
        return 2;
    }
    /* a reduction Ptex makes: of the next larger resolution in u or in v (PtexReader::getData) */
    int blendu = redu == redv ? (ru & 1) : redu > redv;
    int k = served_kind(t, s, f, ru + blendu, rv + !blendu, tu, tv);
    if (k != 2)
        return k;
    /* TiledFaceBase::reduce: the tile resolution kept but not over the new face's; one tile
     * left: a constant face (the tiles are all one constant), else tiled again */
    if (*tu > ru)
        *tu = ru;
    if (*tv > rv)
        *tv = rv;
    return *tu == ru && *tv == rv ? 1 : 2;
}

int st_ptexres_served_const(const st_ptexres *t, const st_set *s, uint32_t f, int ru, int rv)
{
    if (ru == 0 && rv == 0)
        return 1;
    if (!t->nctiles)
        return 0;
    int tu = 0, tv = 0;
    return served_kind(t, s, f, ru, rv, &tu, &tv) == 1;
}

const st_ptexres *st_ptexres_get(const st_set *s)
{
    const st_ptexres *t = st_set_ext_get(s, ST_EXT_PTEXRES);
    return t && t->magic == ST_PTEXRES_MAGIC ? t : NULL;
}

/* Ptex's 2:1 reductions of interleaved texels: integers halve with truncation, half and float
 * take 0.5 * (a + b) in float (half rounds back the way PtexHalf does, ties away from zero:
 * st_float_to_half_ptex). One loop per dtype over channel elements so that the compiler
 * vectorises it. d[i] = reduce(a[i], b[i]), i < n. */
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
            z[i] = st_float_to_half_ptex(0.5f * (st_half_to_float(x[i]) + st_half_to_float(y[i])));
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
        case ST_DT_HALF: { uint16_t x = st_float_to_half_ptex(v); memcpy(dst + 2 * c, &x, 2); break; }
        default: memcpy(dst + 4 * c, &v, 4); break;
        }
    }
}

/* Where the data of (ru, rv) comes from: >= 0 a set level, -1 the constant value, -2 reduce
 * in u from (ru+1, rv), -3 reduce in v from (ru, rv+1). The Ptex reader's rule: a stored
 * square reduction, else a 2:1 step along the axis reduced more (alternating on squares). */
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

/* The set level that holds (ru, rv) of a face of U x V (log2) once its levels are filled, or
 * -1: level L is (max(U-L, 0), max(V-L, 0)). The (0,0) entry is the last level. */
static int level_of(unsigned U, unsigned V, unsigned ru, unsigned rv)
{
    unsigned redu = U - ru, redv = V - rv;
    if (redu == redv)
        return (int)redu;
    if (rv == 0 && redu > redv)
        return (int)redu; /* past the v axis: (U-L, 0), L > V */
    if (ru == 0 && redv > redu)
        return (int)redv;
    return -1;
}

int st_ptexres_fill_levels(st_set *s, uint32_t f, unsigned nstored, const uint8_t *constpx,
                           st_error *e)
{
    const st_face *F = &s->faces[f];
    if (F->flags & ST_FACE_CONSTANT || F->nlevels <= 1)
        return ST_OK;
    unsigned dt = s->info.dtype, nc = s->info.nchan, U = F->ulog2, V = F->vlog2;
    size_t ts = st_texel_size(s);
    if (nstored < 1)
        nstored = 1;
    if (s->info.meshtype == ST_MESH_TRIANGLE) { /* square faces: Ptex's triangle reduction */
        for (unsigned l = nstored; l < F->nlevels; l++) {
            uint8_t *d = st_face_level(s, f, l);
            if (l == F->ulog2) {
                if (constpx)
                    memcpy(d, constpx, ts);
                else
                    average_px(dt, nc, st_face_level(s, f, 0), (size_t)F->w * F->h, d);
            } else {
                st_tri_reduce(dt, nc, st_face_level(s, f, l - 1), st_level_w(F, l - 1), d);
            }
        }
        return ST_OK;
    }
    /* scratch for the u- or v-reduced intermediate of a square step: half of level L-1 */
    uint8_t small[4096], *tmp = small;
    size_t need = 0;
    for (unsigned l = nstored; l < F->nlevels && l <= U && l <= V; l++) {
        need = ((size_t)1 << (U - l + V - l + 1)) * ts;
        break; /* the first unstored square step is the largest */
    }
    if (need > sizeof small && !(tmp = malloc(need)))
        return st_fail(e, ST_ENOMEM, "face %u: out of memory for %zu bytes of scratch", f, need);
    for (unsigned l = 1; l < F->nlevels; l++) {
        unsigned ru = U > l ? U - l : 0, rv = V > l ? V - l : 0;
        uint8_t *d = st_face_level(s, f, l);
        const uint8_t *p = st_face_level(s, f, l - 1);
        if (ru == 0 && rv == 0) {
            if (constpx)
                memcpy(d, constpx, ts);
            else
                average_px(dt, nc, st_face_level(s, f, 0), (size_t)F->w * F->h, d);
        } else if (l <= U && l <= V) {
            if (l < nstored)
                continue; /* stored square reduction */
            /* (ru, rv) from (ru+1, rv+1): source_of's alternation, two 2:1 steps */
            if (ru & 1) {
                reduce_axis(dt, nc, p, 1u << (ru + 1), 1u << (rv + 1), tmp, 0);
                reduce_axis(dt, nc, tmp, 1u << (ru + 1), 1u << rv, d, 1);
            } else {
                reduce_axis(dt, nc, p, 1u << (ru + 1), 1u << (rv + 1), tmp, 1);
                reduce_axis(dt, nc, tmp, 1u << ru, 1u << (rv + 1), d, 0);
            }
        } else if (U > V) {
            reduce_axis(dt, nc, p, 1u << (ru + 1), 1u, d, 1); /* (ru+1, 0) -> (ru, 0) */
        } else {
            reduce_axis(dt, nc, p, 1u, 1u << (rv + 1), d, 0); /* (0, rv+1) -> (0, rv) */
        }
    }
    if (tmp != small)
        free(tmp);
    return ST_OK;
}

/* Every face's levels past the stored ones, as Ptex serves them (st_ptexres_fill_levels). */
static int fill_all(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                    const uint8_t *nstored, st_error *e)
{
    size_t ts = st_texel_size(s);
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        const st_face *F = &s->faces[f];
        unsigned ns = nstored ? nstored[f] : (F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2) + 1u;
        if (ptxflags && (ptxflags[f] & PTX_FLAG_HASEDITS))
            ns = 1; /* an edited face's stored reductions are stale */
        int rc = st_ptexres_fill_levels(s, f, ns, constpx ? constpx + (size_t)f * ts : NULL, e);
        if (rc)
            return rc;
    }
    return ST_OK;
}

/* The set's levels hook (st_set_levels) of a record with deferred levels: one acquire load
 * once they are made; else the first caller makes them under levels_lock (the reader's
 * inflate, then the fill of the unstored levels), publishes 1 with release and frees what
 * made them. A failure other than ST_ENOMEM is final: 2 and its message for every caller. */
static int ptexres_levels(const st_set *s, st_error *e)
{
    st_ptexres *t = s->ext.data;
    int st = atomic_load_explicit(&t->levels, memory_order_acquire);
    if (st == 1)
        return ST_OK;
    if (st == 0) {
        pthread_mutex_lock(&t->levels_lock);
        st = atomic_load_explicit(&t->levels, memory_order_relaxed);
        if (st == 0) {
            st_set *w = (st_set *)(uintptr_t)s; /* the levels are written once, here */
            st_error le;
            st_error_clear(&le);
            int rc = t->def->make(w, t->def->data, &le);
            if (rc == ST_OK)
                rc = fill_all(w, t->def->constpx, t->ptxflags, t->nstored, &le);
            if (rc == ST_ENOMEM) { /* nothing is wrong with the file: a later call tries again */
                pthread_mutex_unlock(&t->levels_lock);
                return st_fail(e, rc, "%s", le.msg);
            }
            if (rc != ST_OK) {
                t->levels_err = le;
                t->levels_err.code = rc;
            }
            def_free(t);
            st = rc == ST_OK ? 1 : 2;
            atomic_store_explicit(&t->levels, st, memory_order_release);
        }
        pthread_mutex_unlock(&t->levels_lock);
        if (st == 1)
            return ST_OK;
    }
    return st_fail(e, t->levels_err.code, "%s", t->levels_err.msg);
}

STU_LOADPATH
static int attach_record(st_set *s, const uint8_t *ptxflags, const uint8_t *nstored,
                         size_t max_bytes, st_ptexres_deferred *def, st_error *e)
{
    if (s->ext.kind != ST_EXT_NONE)
        return st_fail(e, ST_EINVAL, "set already has an extension; cannot attach the Ptex table");
    uint32_t n = s->info.nfaces;
    st_ptexres *t = calloc(1, sizeof *t);
    if (!t)
        return st_fail(e, ST_ENOMEM, "out of memory for the Ptex table");
    t->magic = ST_PTEXRES_MAGIC;
    t->nfaces = n;
    t->max_bytes = max_bytes ? max_bytes : ST_DEFAULT_MAX_BYTES;
    t->ptxflags = calloc((size_t)n + 3, 1); /* + 3: the bilinear lanes read 32 bits at a face */
    t->nstored = malloc(n);
    t->lanef = calloc((size_t)n + 3, 1);
    if (!t->ptxflags || !t->nstored || !t->lanef) {
        free(t->ptxflags);
        free(t->nstored);
        free(t->lanef);
        free(t);
        return st_fail(e, ST_ENOMEM, "out of memory for the Ptex table");
    }
    /* the default attributes by the static initializers (what pthread_*_init(.., NULL) sets,
     * without calling into libc: in a fresh process those two calls - their code, their
     * binding and the default attribute read - were 20-40 us of a 200 us import) */
    t->lock = (pthread_mutex_t)PTHREAD_MUTEX_INITIALIZER;
    t->levels_lock = (pthread_mutex_t)PTHREAD_MUTEX_INITIALIZER;
    t->pin = (pthread_rwlock_t)PTHREAD_RWLOCK_INITIALIZER;
    atomic_init(&t->built, 0);
    atomic_init(&t->levels, def ? 0 : 1);
    t->def = def;
    t->def_bytes = def ? sizeof *def + def->bytes : 0;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        t->ptxflags[f] = ptxflags ? ptxflags[f] : (uint8_t)((F->flags & ST_FACE_CONSTANT ?
                            PTX_FLAG_CONSTANT : 0) | (F->flags & ST_FACE_SUBFACE ? PTX_FLAG_SUBFACE : 0));
        t->nstored[f] = nstored ? nstored[f] : (uint8_t)((F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2) + 1u);
        unsigned bnd = 0;
        for (unsigned eid = 0; eid < 4; eid++)
            bnd |= F->adjface[eid] < 0 ? 1u << (4 + eid) : 0u;
        t->lanef[f] = (uint8_t)((t->ptxflags[f] & PTX_FLAG_NBCONSTANT) | bnd);
    }
    /* the Ptex filter family registers itself with the sampler through the extension */
    /* the Ptex filter family registers itself with the sampler through the extension; a
     * record with deferred levels also hooks st_set_levels */
    st_set_ext_attach(s, &(st_set_ext){.kind = ST_EXT_PTEXRES, .data = t, .free = ptexres_free,
                                       .memory = ptexres_memory,
                                       .filter = st_ptexfilter_batch,
                                       .levels = def ? ptexres_levels : NULL});
    return ST_OK;
}

int st_ptexres_attach_lazy(st_set *s, const uint8_t *ptxflags, const uint8_t *nstored,
                           size_t max_bytes, st_error *e)
{
    return attach_record(s, ptxflags, nstored, max_bytes, NULL, e);
}

STU_LOADPATH
int st_ptexres_attach_deferred(st_set *s, const st_ptexres_deferred *d, const uint8_t *ptxflags,
                               const uint8_t *nstored, size_t max_bytes, st_error *e)
{
    st_ptexres_deferred *def = malloc(sizeof *def);
    if (!def) {
        if (d->free)
            d->free(d->data);
        return st_fail(e, ST_ENOMEM, "out of memory for the Ptex table");
    }
    *def = *d;
    int rc = attach_record(s, ptxflags, nstored, max_bytes, def, e);
    if (rc) {
        if (def->free)
            def->free(def->data);
        free(def);
    }
    return rc;
}

STU_LOADPATH
int st_ptexres_attach(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                      const uint8_t *nstored, size_t max_bytes, st_error *e)
{
    if (s->ext.kind != ST_EXT_NONE)
        return st_fail(e, ST_EINVAL, "set already has an extension; cannot attach the Ptex table");
    int rc = fill_all(s, constpx, ptxflags, nstored, e);
    return rc ? rc : st_ptexres_attach_lazy(s, ptxflags, nstored, max_bytes, e);
}

/* Face f is constant with a texel of ts zero bytes (px: the built table's entries). */
static int zero_face(const st_set *s, const uint64_t *base, const uint8_t *const *px, size_t ts,
                     int32_t f)
{
    if (f < 0)
        return 1; /* a mesh boundary: no face to read */
    const st_face *F = &s->faces[f];
    if ((F->flags & (ST_FACE_CONSTANT | ST_FACE_SUBFACE)) != ST_FACE_CONSTANT)
        return 0;
    const uint8_t *d = px[base[f]];
    for (size_t i = 0; i < ts; i++)
        if (d[i])
            return 0;
    return 1;
}

/* lanef's ST_PTEXRES_ZFACE bit of face f (ptexres.h): f constant, not a subface, with a
 * texel of zero bytes (zero_face). Its ST_PTEXRES_ZRING bit: f, each neighbour across an edge and
 * the diagonal face of each corner that has neighbours across both its edges are constant,
 * not subfaces, with a texel of zero bytes, and each such corner is a regular vertex (the set's cornerface). Those are
 * every face Ptex's Traverse split (splitAndApply) reaches from f: its pieces go across an
 * edge to the neighbour, or past a corner to the corner's faces, never further (no subface
 * to re-split on); and the split changes the kernel's weight only at a corner that is not
 * regular (applyToCorner: valence 2, 3 or 5+). So with the bit set every piece adds texel 0
 * times a weight to the sum, and the sum stays +0 whatever the weights are (finite ones: a
 * product with +-0 is +-0, and +0 + -0 is +0), and the division is by the kernel's whole
 * weight. Quad meshes only (never set on triangle meshes: ptextri_filter.c has its own
 * walk). */
static void zero_ring(st_ptexres *t, const st_set *s, const uint64_t *base,
                      const uint8_t *const *px)
{
    uint32_t n = s->info.nfaces;
    size_t ts = st_texel_size(s);
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        int ok = zero_face(s, base, px, ts, (int32_t)f);
        for (int e = 0; ok && e < 4; e++) {
            ok = zero_face(s, base, px, ts, F->adjface[e]);
            /* corner e lies between edges e and e - 1 */
            if (ok && F->adjface[e] >= 0 && F->adjface[(e + 3) & 3] >= 0)
                ok = F->cornerface[e] >= 0 && zero_face(s, base, px, ts, F->cornerface[e]);
        }
        int tri = s->info.meshtype == ST_MESH_TRIANGLE;
        unsigned bits = (ok && !tri ? ST_PTEXRES_ZRING : 0u) |
                        (!tri && zero_face(s, base, px, ts, (int32_t)f) ? ST_PTEXRES_ZFACE : 0u);
        t->lanef[f] = (uint8_t)((t->lanef[f] & ~(ST_PTEXRES_ZRING | ST_PTEXRES_ZFACE)) | bits);
    }
}

/* Builds px and the arena of t for s (t->lock held). */
static int build_table(st_ptexres *t, const st_set *s, st_error *e)
{
    uint32_t n = s->info.nfaces;
    unsigned dt = s->info.dtype, nc = s->info.nchan;
    size_t ts = st_texel_size(s), max_bytes = t->max_bytes;
    uint64_t *base = malloc((size_t)n * sizeof *base);
    const uint8_t **pxs = NULL;
    uint8_t *arena = NULL;
    if (!base)
        goto nomem;
    size_t nent = 0, bytes = 0;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        base[f] = nent;
        if (F->flags & ST_FACE_CONSTANT) {
            nent++;
            continue;
        }
        unsigned U = F->ulog2, V = F->vlog2;
        nent += (size_t)(U + 1) * (V + 1);
        for (unsigned ru = 0; ru <= U; ru++)
            for (unsigned rv = 0; rv <= V; rv++)
                if (level_of(U, V, ru, rv) < 0) {
                    bytes += ((size_t)1 << (ru + rv)) * ts;
                    if (bytes > max_bytes) {
                        free(base);
                        return st_fail(e, ST_ETOOBIG, "Ptex resolution table needs more than "
                                       "%zu bytes (at face %u)", max_bytes, f);
                    }
                }
    }
    pxs = malloc(nent * sizeof *pxs);
    arena = arena_alloc(bytes);
    if (!pxs || !arena)
        goto nomem;
    size_t off = 0;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        const uint8_t **px = pxs + base[f];
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
                size_t idx = (size_t)ru * (V + 1) + rv;
                int lvl = level_of(U, V, ru, rv);
                if (lvl >= 0) { /* the set level holds what Ptex serves here */
                    px[idx] = st_face_level(s, f, (unsigned)lvl);
                    continue;
                }
                int src = source_of(U, V, ru, rv, ns, he); /* -2 or -3 off the level chain */
                uint8_t *d = arena + off;
                off += ((size_t)1 << (ru + rv)) * ts;
                px[idx] = d;
                if (src == -2)
                    reduce_axis(dt, nc, px[(size_t)(ru + 1) * (V + 1) + rv], 1u << (ru + 1),
                                1u << rv, d, 1);
                else
                    reduce_axis(dt, nc, px[idx + 1], 1u << ru, 1u << (rv + 1), d, 0);
            }
        }
    }
    zero_ring(t, s, base, pxs);
    t->base = base;
    t->px = pxs;
    t->arena = arena;
    t->arena_bytes = bytes;
    __atomic_store_n(&t->bytes, (size_t)n * sizeof *base + nent * sizeof *pxs + bytes,
                     __ATOMIC_RELAXED);
    return ST_OK;
nomem:
    free(base);
    free(pxs);
    free(arena);
    return st_fail(e, ST_ENOMEM, "out of memory for the Ptex resolution table");
}

const st_ptexres *st_ptexres_table(const st_set *s, st_error *e)
{
    st_ptexres *t = st_set_ext_get(s, ST_EXT_PTEXRES);
    if (!t || t->magic != ST_PTEXRES_MAGIC) {
        st_fail(e, ST_EUNSUPPORTED, "set has no Ptex resolution table");
        return NULL;
    }
    if (atomic_load_explicit(&t->built, memory_order_acquire))
        return t;
    if (st_set_levels(s, e)) /* the table points into the set's levels */
        return NULL;
    pthread_mutex_lock(&t->lock);
    int rc = ST_OK;
    if (!atomic_load_explicit(&t->built, memory_order_relaxed)) {
        rc = build_table(t, s, e);
        if (rc == ST_OK)
            atomic_store_explicit(&t->built, 1, memory_order_release);
    }
    pthread_mutex_unlock(&t->lock);
    return rc == ST_OK ? t : NULL;
}

const st_ptexres *st_ptexres_pin(const st_set *s, st_error *e)
{
    st_ptexres *t = st_set_ext_get(s, ST_EXT_PTEXRES);
    if (!t || t->magic != ST_PTEXRES_MAGIC) {
        st_fail(e, ST_EUNSUPPORTED, "set has no Ptex resolution table");
        return NULL;
    }
    for (;;) {
        pthread_rwlock_rdlock(&t->pin);
        if (atomic_load_explicit(&t->built, memory_order_acquire))
            return t; /* a drop needs the exclusive lock: the table stays until unpinned */
        pthread_rwlock_unlock(&t->pin);
        if (!st_ptexres_table(s, e)) /* (re)build under the mutex, then pin again */
            return NULL;
    }
}

void st_ptexres_unpin(const st_ptexres *t)
{
    if (t)
        pthread_rwlock_unlock(&((st_ptexres *)(uintptr_t)t)->pin);
}

size_t st_ptexres_drop(const st_set *s)
{
    st_ptexres *t = (st_ptexres *)(uintptr_t)st_ptexres_get(s);
    if (!t || !atomic_load_explicit(&t->built, memory_order_acquire))
        return 0;
    if (pthread_rwlock_trywrlock(&t->pin) != 0)
        return 0; /* a filter is reading it: it is not cold */
    size_t freed = 0;
    pthread_mutex_lock(&t->lock); /* no build in progress either */
    if (atomic_load_explicit(&t->built, memory_order_relaxed)) {
        atomic_store_explicit(&t->built, 0, memory_order_release);
        freed = __atomic_load_n(&t->bytes, __ATOMIC_RELAXED);
        free(t->base);
        free(t->px);
        free(t->arena);
        t->base = NULL;
        t->px = NULL;
        t->arena = NULL;
        t->arena_bytes = 0;
        __atomic_store_n(&t->bytes, 0, __ATOMIC_RELAXED);
    }
    pthread_mutex_unlock(&t->lock);
    pthread_rwlock_unlock(&t->pin);
    return freed;
}

size_t st_ptexres_built_bytes(const st_set *s)
{
    const st_ptexres *t = st_ptexres_get(s);
    if (!t || !atomic_load_explicit(&((st_ptexres *)(uintptr_t)t)->built, memory_order_acquire))
        return 0;
    return __atomic_load_n(&t->bytes, __ATOMIC_RELAXED);
}
