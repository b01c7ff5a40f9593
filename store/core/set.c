/* store/core/set.c - creation, validation, mip reduction and metadata of texture sets.
 *
 * Everything sized from outside (face count, face sizes, channel count) is checked with
 * overflow-safe arithmetic against caps before the single texel arena is allocated. The
 * adjacency walk that finds valences and diagonal faces is bounded (ST_WALK_MAX steps), so a
 * hostile adjacency table cannot loop.
 */
#include "set.h"
#include "loadpath.h"
#include "trilevel.h"
#include "bigalloc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#define ST_WALK_MAX 64

static int is_pow2(uint32_t x) { return x && !(x & (x - 1)); }

/* The arena's size for bytes of texels: 64-byte aligned, rounded up so that a 16-byte load
 * at the very end stays inside. */
static size_t arena_size(size_t bytes)
{
    return (bytes + 64 + 63) & ~(size_t)63;
}

/* The texel arena: 64-byte aligned, and from 2/3 MiB on on transparent huge pages
 * (util/bigalloc.h, a long-lived buffer; st_set_memory counts its whole huge pages). Every
 * importer writes its whole arena right away; with 4 KiB pages the page faults of a large
 * Ptex import cost more CPU than its decoding. alloc is a multiple of 64. */
STU_LOADPATH
static uint8_t *arena_alloc(size_t alloc)
{
    return stu_big_alloc(alloc, STU_BIG_KEEP);
}

static unsigned floor_log2(uint32_t x)
{
    unsigned l = 0;
    while (x >>= 1)
        l++;
    return l;
}

/* The face table (nfaces st_face, 64 bytes each) and right after it the level offsets
 * (nlev uint64_t): one block from util/bigalloc.c, so that from 16 KiB on its pages are
 * faulted in by one call (set_create writes all of it right away; teapot's 28 KiB of faces
 * and 14 KiB of offsets were 11 page faults, about 0.1 ms of a 3.6 ms fresh import). Freed
 * with free(s->faces). Its bytes for st_set_memory: face_block_bytes. A hostile face count
 * cannot make it populate more than about three times the descriptor array that its
 * caller already holds (at most 16 levels a face). */
static size_t face_block_bytes(size_t nfaces, size_t nlev)
{
    return stu_big_footprint(nfaces * sizeof(st_face) + nlev * sizeof(uint64_t), STU_BIG_KEEP);
}
STU_LOADPATH
static st_face *face_block(size_t nfaces, size_t nlev)
{
    return stu_big_alloc(nfaces * sizeof(st_face) + nlev * sizeof(uint64_t), STU_BIG_KEEP);
}

/* A level holds w*h texels, or for a BC1 set ceil(w/4)*ceil(h/4) blocks of 8 bytes. */
static size_t level_units(const st_set_info *info, const st_face *F, unsigned l)
{
    size_t w = st_level_w(F, l), h = st_level_h(F, l);
    if (info->kind == ST_KIND_BC1)
        return ((w + 3) / 4) * ((h + 3) / 4);
    return w * h;
}
static size_t level_unit_size(const st_set_info *info, size_t tsize)
{
    return info->kind == ST_KIND_BC1 ? 8 : tsize;
}

STU_LOADPATH
int st_set_check_adjacency(const st_set *s, st_error *e)
{
    uint32_t n = s->info.nfaces;
    int tri = s->info.meshtype == ST_MESH_TRIANGLE;
    if (s->info.meshtype > ST_MESH_TRIANGLE)
        return st_fail(e, ST_EINVAL, "mesh type %u is neither quad (0) nor triangle (1)",
                       s->info.meshtype);
    if (tri && s->info.kind != ST_KIND_PERFACE)
        return st_fail(e, ST_EINVAL, "only a per-face set can be a triangle mesh");
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        if (tri && (F->w != F->h || (F->flags & ST_FACE_SUBFACE) || F->adjface[3] != -1))
            return st_fail(e, ST_EADJ, "face %u: a triangle face is square (%ux%u), no subface, "
                           "with three edges (edge 3 must be -1)", f, F->w, F->h);
        for (int ed = 0; ed < 4; ed++) {
            int32_t g = F->adjface[ed];
            if (g < 0)
                continue;
            if ((uint32_t)g >= n)
                return st_fail(e, ST_EADJ, "face %u edge %d: neighbour %d out of range (%u faces)",
                               f, ed, g, n);
            unsigned ge = F->adjedge[ed];
            if (ge > (tri ? 2u : 3u))
                return st_fail(e, ST_EADJ, "face %u edge %d: neighbour edge id %u not in 0..%u",
                               f, ed, ge, tri ? 2u : 3u);
            const st_face *G = &s->faces[g];
            int fsub = (F->flags & ST_FACE_SUBFACE) != 0, gsub = (G->flags & ST_FACE_SUBFACE) != 0;
            if (fsub != gsub)
                continue; /* Ptex: a main face edge names one of the two subfaces along it */
            if (G->adjface[ge] != (int32_t)f || G->adjedge[ge] != ed)
                return st_fail(e, ST_EADJ,
                               "face %u edge %d -> face %d edge %u, but face %d edge %u -> "
                               "face %d edge %u (adjacency not symmetric)",
                               f, ed, g, ge, g, ge, G->adjface[ge], G->adjedge[ge]);
        }
    }
    return ST_OK;
}

/* Walks around the vertex at corner c of face f (Ptex order: cross edge c, then the edge
 * after the one we arrived on). Fills valence and, for a regular interior vertex, the
 * diagonal face and its corner. */
STU_LOADPATH
static void corner_walk(st_set *s, uint32_t f, unsigned c)
{
    /* a triangle has three edges: the next edge is (e + 1) % 3, the one before (e + 2) % 3 */
    unsigned ne_n = s->info.meshtype == ST_MESH_TRIANGLE ? 3u : 4u;
    st_face *F = &s->faces[f];
    int32_t af = (int32_t)f;
    unsigned ae = c;
    int32_t diag = -1;
    unsigned diag_corner = 0;
    unsigned count = 1;
    int boundary = 0;
    for (int i = 0; i < ST_WALK_MAX; i++) {
        const st_face *A = &s->faces[af];
        int32_t nf = A->adjface[ae];
        if (nf < 0) {
            boundary = 1;
            break;
        }
        unsigned ne = A->adjedge[ae];
        af = nf;
        ae = (ne + 1) % ne_n; /* the vertex is corner (ne+1) of the new face, where edge ne+1
                                 starts */
        if (af == (int32_t)f && ae == c)
            break;
        count++;
        if (count == 3) {
            diag = af;
            diag_corner = ae;
        }
    }
    if (boundary) {
        /* count the faces on the other side too, walking the other way */
        int32_t bf = (int32_t)f;
        unsigned be = (c + ne_n - 1) % ne_n; /* edge ending at the vertex */
        for (int i = 0; i < ST_WALK_MAX; i++) {
            const st_face *B = &s->faces[bf];
            int32_t nf = B->adjface[be];
            if (nf < 0)
                break;
            unsigned ne = B->adjedge[be];
            bf = nf;
            be = (ne + ne_n - 1) % ne_n;
            count++;
        }
        F->valence[c] = (uint8_t)((count > 127 ? 127 : count) | ST_VALENCE_BOUNDARY);
        F->cornerface[c] = -1;
        F->cornercorner[c] = 0;
        return;
    }
    F->valence[c] = (uint8_t)(count > 127 ? 127 : count);
    if (count == 4 && ne_n == 4 && !(F->flags & ST_FACE_SUBFACE)) {
        F->cornerface[c] = diag;
        F->cornercorner[c] = (uint8_t)diag_corner;
    } else {
        F->cornerface[c] = -1;
        F->cornercorner[c] = 0;
    }
}

STU_LOADPATH
static int set_create(const st_set_info *info, const st_face_desc *fd, size_t max_bytes,
                      int zero, st_set **out, st_error *e)
{
    *out = NULL;
    if (!max_bytes)
        max_bytes = ST_DEFAULT_MAX_BYTES;
    if (info->nchan < 1 || info->nchan > ST_MAX_CHANNELS)
        return st_fail(e, ST_EINVAL, "channel count %u not in 1..%u", info->nchan, ST_MAX_CHANNELS);
    size_t csize = st_dtype_size(info->dtype);
    if (!csize)
        return st_fail(e, ST_EINVAL, "data type %u unknown", info->dtype);
    if (info->nfaces < 1 || info->nfaces > ST_MAX_FACES)
        return st_fail(e, ST_ETOOBIG, "face count %u not in 1..%u", info->nfaces, ST_MAX_FACES);
    if (info->alpha_chan >= (int)info->nchan)
        return st_fail(e, ST_EINVAL, "alpha channel %d but only %u channels", info->alpha_chan,
                       info->nchan);
    size_t tsize = csize * info->nchan;
    if (info->kind == ST_KIND_BC1 && (info->dtype != ST_DT_U8 || info->nchan != 4))
        return st_fail(e, ST_EINVAL, "a BC1 set decodes to 4 channels of u8");

    st_set *s = calloc(1, sizeof *s);
    if (!s)
        return st_fail(e, ST_ENOMEM, "out of memory for the set header");
    s->info = *info;
    /* the face table and the level offsets: one block (face_block) */
    size_t nlev_all = 0;
    for (uint32_t f = 0; f < info->nfaces; f++)
        nlev_all += floor_log2(fd[f].w > fd[f].h ? fd[f].w : fd[f].h) + 1u;
    s->faces = face_block(info->nfaces, nlev_all);
    if (!s->faces) {
        free(s);
        return st_fail(e, ST_ENOMEM, "out of memory for %u faces", info->nfaces);
    }
    memset(s->faces, 0, (size_t)info->nfaces * sizeof *s->faces);

    /* sizes and level counts, with the arena size summed overflow-safe */
    size_t nlev_total = 0, bytes = 0;
    int rc = ST_OK;
    for (uint32_t f = 0; f < info->nfaces; f++) {
        const st_face_desc *d = &fd[f];
        st_face *F = &s->faces[f];
        if (d->w < 1 || d->h < 1 || d->w > ST_MAX_DIM || d->h > ST_MAX_DIM) {
            rc = st_fail(e, ST_ETOOBIG, "face %u: size %ux%u not in 1..%u", f, d->w, d->h,
                         ST_MAX_DIM);
            goto fail;
        }
        if (info->kind != ST_KIND_ATLAS && info->kind != ST_KIND_BC1 &&
            (!is_pow2(d->w) || !is_pow2(d->h))) {
            rc = st_fail(e, ST_EINVAL, "face %u: size %ux%u is not a power of two", f, d->w, d->h);
            goto fail;
        }
        F->w = d->w;
        F->h = d->h;
        F->ulog2 = (uint8_t)floor_log2(d->w);
        F->vlog2 = (uint8_t)floor_log2(d->h);
        F->nlevels = (uint8_t)(floor_log2(d->w > d->h ? d->w : d->h) + 1);
        F->flags = d->flags & (ST_FACE_CONSTANT | ST_FACE_SUBFACE);
        F->lvl = (uint32_t)nlev_total;
        nlev_total += F->nlevels;
        for (int ed = 0; ed < 4; ed++) {
            int32_t g = d->adjface[ed];
            if (g >= 0 && (d->adjedge[ed] < 0 || d->adjedge[ed] > 3)) {
                rc = st_fail(e, ST_EADJ, "face %u edge %d: neighbour edge id %d not in 0..3", f,
                             ed, d->adjedge[ed]);
                goto fail;
            }
            F->adjface[ed] = g < 0 ? -1 : g;
            F->adjedge[ed] = g < 0 ? 0 : (uint8_t)d->adjedge[ed];
        }
        size_t fb = 0;
        if (F->flags & ST_FACE_CONSTANT) {
            fb = tsize;
        } else {
            for (unsigned l = 0; l < F->nlevels; l++) {
                size_t lb;
                if (st_mul_size(level_units(info, F, l), level_unit_size(info, tsize), &lb) ||
                    st_add_size(fb, lb, &fb)) {
                    rc = st_fail(e, ST_ETOOBIG, "face %u: size overflows", f);
                    goto fail;
                }
            }
        }
        if (st_add_size(bytes, fb, &bytes) || bytes > max_bytes) {
            rc = st_fail(e, ST_ETOOBIG, "set needs more than %zu bytes of texels (at face %u)",
                         max_bytes, f);
            goto fail;
        }
    }
    if ((rc = st_set_check_adjacency(s, e)) != ST_OK)
        goto fail;

    s->level_off = (uint64_t *)(void *)(s->faces + info->nfaces); /* nlev_total == nlev_all */
    size_t alloc = arena_size(bytes);
    s->texels = arena_alloc(alloc);
    if (!s->texels) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of texels", bytes);
        goto fail;
    }
    if (zero)
        memset(s->texels, 0, alloc);
    else
        memset(s->texels + bytes, 0, alloc - bytes); /* the slack past the last texel */
    s->texel_bytes = bytes;
    size_t off = 0;
    for (uint32_t f = 0; f < info->nfaces; f++) {
        st_face *F = &s->faces[f];
        for (unsigned l = 0; l < F->nlevels; l++) {
            s->level_off[F->lvl + l] = off;
            if (!(F->flags & ST_FACE_CONSTANT))
                off += level_units(info, F, l) * level_unit_size(info, tsize);
        }
        if (F->flags & ST_FACE_CONSTANT)
            off += tsize;
    }
    for (uint32_t f = 0; f < info->nfaces; f++) {
        for (unsigned c = 0; c < (info->meshtype == ST_MESH_TRIANGLE ? 3u : 4u); c++)
            corner_walk(s, f, c);
        if (info->meshtype == ST_MESH_TRIANGLE) { /* no fourth corner */
            s->faces[f].valence[3] = 0;
            s->faces[f].cornerface[3] = -1;
            s->faces[f].cornercorner[3] = 0;
        }
    }
    *out = s;
    return ST_OK;
fail:
    st_set_free(s);
    return rc;
}

int st_set_create(const st_set_info *info, const st_face_desc *fd, size_t max_bytes,
                  st_set **out, st_error *e)
{
    return set_create(info, fd, max_bytes, 1, out, e);
}

STU_LOADPATH
int st_set_create_unzeroed(const st_set_info *info, const st_face_desc *fd, size_t max_bytes,
                           st_set **out, st_error *e)
{
    return set_create(info, fd, max_bytes, 0, out, e);
}

/* Frees the extension of s, whatever state its levels are in. */
static void ext_free(st_set *s)
{
    if (s->ext.data && s->ext.free)
        s->ext.free(s->ext.data);
    memset(&s->ext, 0, sizeof s->ext);
}

void st_set_free(st_set *s)
{
    if (!s)
        return;
    ext_free(s);
    for (uint32_t i = 0; i < s->nmeta; i++) {
        free(s->meta[i].key);
        free(s->meta[i].data);
    }
    free(s->meta);
    if (s->map) {
        munmap(s->map, s->map_len);
        close(s->map_fd);
    } else {
        free(s->texels);
        free(s->faces); /* and the level offsets after it (face_block) */
    }
    free(s);
}

/* Level l of face f from level l - 1: each texel the mean of the (up to 2 x 2) texels above
 * it. With labels (sid: one per texel of level l - 1, did: of level l) a texel labelled d != 0
 * takes the mean of those of its texels labelled d alone (d is one of theirs: see
 * st_set_build_mips_labelled); label 0, or no labels, the mean of all of them. */
static void reduce_level(const st_set *s, uint32_t f, unsigned l, const uint16_t *sid,
                         const uint16_t *did)
{
    const st_face *F = &s->faces[f];
    unsigned nc = s->info.nchan, dt = s->info.dtype;
    size_t ts = st_texel_size(s);
    uint32_t sw = st_level_w(F, l - 1), sh = st_level_h(F, l - 1);
    uint32_t dw = st_level_w(F, l), dh = st_level_h(F, l);
    const uint8_t *src = st_face_level(s, f, l - 1);
    uint8_t *dst = st_face_level(s, f, l);
    uint32_t xs = sw > 1 ? 2 : 1, ys = sh > 1 ? 2 : 1; /* per axis: stop at 1 */
    float norm = 1.0f / (float)(xs * ys);
    for (uint32_t y = 0; y < dh; y++) {
        for (uint32_t x = 0; x < dw; x++) {
            float acc[ST_MAX_CHANNELS] = {0};
            uint16_t d = did ? did[(size_t)y * dw + x] : 0;
            unsigned n = 0;
            for (uint32_t j = 0; j < ys; j++)
                for (uint32_t i = 0; i < xs; i++) {
                    size_t t = (size_t)(y * ys + j) * sw + (x * xs + i);
                    if (d && sid[t] != d)
                        continue;
                    const uint8_t *p = src + t * ts;
                    for (unsigned c = 0; c < nc; c++)
                        acc[c] += st_channel_get(dt, p, c);
                    n++;
                }
            float k = n == xs * ys ? norm : 1.0f / (float)(n ? n : 1);
            uint8_t *q = dst + ((size_t)y * dw + x) * ts;
            for (unsigned c = 0; c < nc; c++)
                st_channel_put(dt, q, c, acc[c] * k);
        }
    }
}

void st_set_build_mips_labelled(st_set *s, uint32_t f, const uint16_t *const *ids)
{
    if (s->info.kind == ST_KIND_BC1 || s->info.meshtype == ST_MESH_TRIANGLE ||
        f >= s->info.nfaces || (s->faces[f].flags & ST_FACE_CONSTANT))
        return;
    (void)st_set_levels(s, NULL);
    for (unsigned l = 1; l < s->faces[f].nlevels; l++)
        reduce_level(s, f, l, ids ? ids[l - 1] : NULL, ids ? ids[l] : NULL);
}

void st_set_build_mips(st_set *s, uint32_t f)
{
    if (s->info.kind == ST_KIND_BC1)
        return; /* BC1 levels are encoded from reduced uncompressed levels, see bc1.h */
    /* deferred levels are made first, so that they cannot overwrite these later (a failure
     * leaves nothing to make: every level below is written here) */
    (void)st_set_levels(s, NULL);
    uint32_t lo = f == UINT32_MAX ? 0 : f, hi = f == UINT32_MAX ? s->info.nfaces : f + 1;
    for (uint32_t i = lo; i < hi && i < s->info.nfaces; i++) {
        if (s->faces[i].flags & ST_FACE_CONSTANT)
            continue;
        for (unsigned l = 1; l < s->faces[i].nlevels; l++) {
            if (s->info.meshtype == ST_MESH_TRIANGLE) /* square faces, Ptex's triangle rule */
                st_tri_reduce(s->info.dtype, s->info.nchan, st_face_level(s, i, l - 1),
                              st_level_w(&s->faces[i], l - 1), st_face_level(s, i, l));
            else
                reduce_level(s, i, l, NULL, NULL);
        }
    }
}

int st_face_is_uniform(const st_set *s, uint32_t f)
{
    const st_face *F = &s->faces[f];
    if (F->flags & ST_FACE_CONSTANT)
        return 1;
    if (s->info.kind == ST_KIND_BC1)
        return 0;
    size_t ts = st_texel_size(s), n = (size_t)F->w * F->h;
    const uint8_t *p = st_face_level(s, f, 0);
    for (size_t i = 1; i < n; i++)
        if (memcmp(p, p + i * ts, ts))
            return 0;
    return 1;
}

static size_t meta_type_size(unsigned type)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return type < 6 ? sz[type] : 0;
}

STU_LOADPATH
int st_set_meta_add(st_set *s, const char *key, unsigned type, const void *data, uint32_t count,
                    st_error *e)
{
    size_t es = meta_type_size(type), bytes;
    if (!es)
        return st_fail(e, ST_EINVAL, "metadata '%s': type %u unknown", key, type);
    if (st_mul_size(es, count, &bytes) || bytes > ((size_t)1 << 30))
        return st_fail(e, ST_ETOOBIG, "metadata '%s': %u elements is too many", key, count);
    void *copy = malloc(bytes ? bytes : 1);
    if (!copy)
        return st_fail(e, ST_ENOMEM, "out of memory for metadata");
    if (bytes)
        memcpy(copy, data, bytes);
    for (uint32_t i = 0; i < s->nmeta; i++) {
        if (!strcmp(s->meta[i].key, key)) { /* a key holds one value: the last one set */
            free(s->meta[i].data);
            s->meta[i].data = copy;
            s->meta[i].type = (uint8_t)type;
            s->meta[i].count = count;
            return ST_OK;
        }
    }
    st_meta_entry *m = realloc(s->meta, (s->nmeta + 1) * sizeof *m);
    if (!m) {
        free(copy);
        return st_fail(e, ST_ENOMEM, "out of memory for metadata");
    }
    s->meta = m;
    st_meta_entry *ent = &m[s->nmeta];
    ent->key = strdup(key);
    if (!ent->key) {
        free(copy);
        return st_fail(e, ST_ENOMEM, "out of memory for metadata");
    }
    ent->data = copy;
    ent->type = (uint8_t)type;
    ent->count = count;
    s->nmeta++;
    return ST_OK;
}

const st_meta_entry *st_set_meta_find(const st_set *s, const char *key)
{
    for (uint32_t i = 0; i < s->nmeta; i++)
        if (!strcmp(s->meta[i].key, key))
            return &s->meta[i];
    return NULL;
}

/* Heap bytes of the set's metadata and extension. */
static size_t meta_ext_memory(const st_set *s)
{
    size_t m = 0;
    for (uint32_t i = 0; i < s->nmeta; i++)
        m += strlen(s->meta[i].key) + 1 + meta_type_size(s->meta[i].type) * s->meta[i].count;
    if (s->ext.data && s->ext.memory)
        m += s->ext.memory(s->ext.data);
    return m;
}

size_t st_set_memory(const st_set *s)
{
    /* an arena of its own: what it really holds (huge pages are allocated whole) */
    size_t tb = s->map ? s->texel_bytes
                       : stu_big_footprint(arena_size(s->texel_bytes), STU_BIG_KEEP);
    size_t nlev = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        nlev += s->faces[f].nlevels;
    size_t m = sizeof *s + tb;
    if (s->map) /* the face table and offsets are in the mapped file */
        m += (size_t)s->info.nfaces * sizeof(st_face) + nlev * sizeof(uint64_t);
    else /* one block from util/bigalloc.c, with its rounding */
        m += face_block_bytes(s->info.nfaces, nlev);
    return m + meta_ext_memory(s);
}

size_t st_set_heap_memory(const st_set *s)
{
    return s->map ? meta_ext_memory(s) : st_set_memory(s);
}

STU_LOADPATH
void st_set_ext_attach(st_set *s, const st_set_ext *x)
{
    /* the old extension may hold what the levels past level 0 are made from: make them now
     * (a set's levels never stay undefined once nothing can make them) */
    if (s->ext.levels && st_set_levels(s, NULL) != ST_OK)
        for (uint32_t f = 0; f < s->info.nfaces; f++) {
            const st_face *F = &s->faces[f];
            if (F->flags & ST_FACE_CONSTANT || F->nlevels < 2)
                continue;
            size_t a = s->level_off[F->lvl + 1];
            size_t b = f + 1 < s->info.nfaces ? s->level_off[s->faces[f + 1].lvl]
                                              : s->texel_bytes;
            memset(s->texels + a, 0, b - a);
        }
    ext_free(s);
    if (x)
        s->ext = *x;
}
