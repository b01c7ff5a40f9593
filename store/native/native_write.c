/* store/native/native_write.c - writes a set as a native file (format table in native.h).
 *
 * Owns: st_native_write_fd, st_native_write, st_native_size. The small sections (metadata, extension) are
 * serialised into a buffer first; the face table, level offsets and texel arena are written
 * straight from the set. Every section's CRC-32C (the texels' too) is computed before the
 * header is written, so the file is written front to back in one pass.
 */
#include "native.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "atlas.h"
#include "bc1_texel.h"
#include "crc32c.h"
#include "fdio.h"
#include "mesh.h"
#include "ptexres.h"

_Static_assert(sizeof(st_face) == 64, "st_face is 64 bytes on disk");
_Static_assert(sizeof(st_bc1_ext) == 8, "st_bc1_ext is 8 bytes on disk");

/* ---- a growable buffer for the small sections ----------------------------------------------- */

typedef struct nbuf {
    uint8_t *p;
    size_t   n, cap;
    int      oom;
} nbuf;

static void nb_put(nbuf *b, const void *p, size_t n)
{
    if (b->oom || !n)
        return;
    if (b->n + n > b->cap) {
        size_t c = b->cap ? b->cap : 256;
        while (c < b->n + n)
            c *= 2;
        uint8_t *q = realloc(b->p, c);
        if (!q) {
            b->oom = 1;
            return;
        }
        b->p = q;
        b->cap = c;
    }
    memcpy(b->p + b->n, p, n);
    b->n += n;
}
static void nb_u32(nbuf *b, uint32_t v) { nb_put(b, &v, 4); }
static void nb_u8(nbuf *b, uint8_t v) { nb_put(b, &v, 1); }
static void nb_zero(nbuf *b, size_t n)
{
    static const uint8_t z[64];
    while (n) {
        size_t k = n < sizeof z ? n : sizeof z;
        nb_put(b, z, k);
        n -= k;
    }
}
static void nb_pad4(nbuf *b) { nb_zero(b, (4 - (b->n & 3)) & 3); }

static size_t meta_type_size(unsigned type)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return type < 6 ? sz[type] : 0;
}

static void put_meta(nbuf *b, const st_set *s)
{
    nb_u32(b, s->nmeta);
    for (uint32_t i = 0; i < s->nmeta; i++) {
        const st_meta_entry *m = &s->meta[i];
        uint32_t k = (uint32_t)strlen(m->key) + 1;
        uint32_t d = (uint32_t)(meta_type_size(m->type) * m->count);
        nb_u32(b, k);
        nb_u8(b, m->type);
        nb_zero(b, 3);
        nb_u32(b, m->count);
        nb_u32(b, d);
        nb_put(b, m->key, k);
        nb_put(b, m->data, d);
        nb_pad4(b);
    }
}

static void put_mesh_edge(nbuf *b, const st_mesh_edge *x)
{
    nb_put(b, x->pos, 8);
    nb_u32(b, x->tri);
    nb_u8(b, x->edge);
    nb_zero(b, 3);
    nb_u32(b, x->count);
}

static void put_atlas(nbuf *b, const st_atlas *a)
{
    const st_mesh *m = a->mesh;
    const st_seams *sm = m ? m->seams : NULL;
    uint32_t parts = (m ? 1u : 0) | (sm ? 2u : 0) | (a->chart_mask ? 4u : 0);
    nb_u32(b, parts);
    nb_u32(b, a->chart_mask ? a->mask_w : 0);
    nb_u32(b, a->chart_mask ? a->mask_h : 0);
    char name[256];
    memset(name, 0, sizeof name);
    snprintf(name, sizeof name, "%s", a->texture_name);
    nb_put(b, name, sizeof name);
    if (m) {
        uint32_t hdr[7] = {m->npos, m->nuv, m->ntri, m->nweld, m->nfaces_src, m->ntri_nouv,
                           m->nmat};
        nb_put(b, hdr, sizeof hdr);
        size_t t = m->ntri;
        nb_put(b, m->pos, (size_t)m->npos * 3 * 4);
        nb_put(b, m->uv, (size_t)m->nuv * 2 * 4);
        nb_put(b, m->tri_pos, t * 3 * 4);
        nb_put(b, m->tri_uv, t * 3 * 4);
        if (m->tri_weld)
            nb_put(b, m->tri_weld, t * 3 * 4);
        else
            nb_zero(b, t * 3 * 4);
        if (m->tri_face)
            nb_put(b, m->tri_face, t * 4);
        else
            nb_zero(b, t * 4);
        nb_put(b, m->tri_mat, t * 2);
        nb_pad4(b);
        for (uint32_t i = 0; i < m->nmat; i++) {
            nb_put(b, m->mats[i].name, sizeof m->mats[i].name);
            nb_put(b, m->mats[i].map_kd, sizeof m->mats[i].map_kd);
        }
    }
    if (m && sm) {
        uint32_t hdr[7] = {sm->nseams, sm->nboundary, sm->nnonmanifold, sm->nedges, sm->ncharts,
                           sm->ndegenerate, sm->nuv_border};
        nb_put(b, hdr, sizeof hdr);
        for (uint32_t i = 0; i < sm->nseams; i++) {
            const st_seam_edge *x = &sm->seams[i];
            nb_put(b, x->pos, 8);
            nb_put(b, x->tri, 8);
            nb_put(b, x->edge, 2);
            nb_put(b, x->winding, 2);
            nb_u8(b, x->mirrored);
            nb_zero(b, 3);
            nb_put(b, x->uv, 32);
        }
        for (uint32_t i = 0; i < sm->nboundary; i++)
            put_mesh_edge(b, &sm->boundary[i]);
        for (uint32_t i = 0; i < sm->nnonmanifold; i++)
            put_mesh_edge(b, &sm->nonmanifold[i]);
        if (sm->tri_chart)
            nb_put(b, sm->tri_chart, (size_t)m->ntri * 4);
        else
            nb_zero(b, (size_t)m->ntri * 4);
    }
    if (a->chart_mask)
        nb_put(b, a->chart_mask, (size_t)a->mask_w * a->mask_h);
}

/* The Ptex inputs of the resolution table: flags, stored levels, constant value per face. */
static int put_ptex(nbuf *b, const st_set *s, st_error *e)
{
    const st_ptexres *t = st_ptexres_get(s); /* the record: the table need not be built */
    if (!t || !t->ptxflags || !t->nstored)
        return st_fail(e, ST_EINVAL, "Ptex resolution table not available to write");
    uint32_t n = s->info.nfaces;
    size_t ts = st_texel_size(s);
    nb_put(b, t->ptxflags, n);
    nb_put(b, t->nstored, n);
    /* the constant value: each face's last level holds it (st_ptexres_fill_levels); kept in
     * the file for format version 1, the reader takes it from the level */
    for (uint32_t f = 0; f < n; f++)
        nb_put(b, st_face_level(s, f, s->faces[f].nlevels - 1u), ts);
    /* the stored faces whose tiles are all one constant (ptexres.h), when there are any: u32
     * count, then 8 bytes each (u32 face, u8 level, u8 tu, u8 tv, u8 0) */
    if (t->nctiles) {
        uint8_t w[8];
        uint32_t c = t->nctiles;
        memcpy(w, &c, 4);
        nb_put(b, w, 4);
        for (uint32_t i = 0; i < c; i++) {
            const st_ptexres_ctile *x = &t->ctiles[i];
            memcpy(w, &x->face, 4);
            w[4] = x->level, w[5] = x->tu, w[6] = x->tv, w[7] = 0;
            nb_put(b, w, 8);
        }
    }
    return ST_OK;
}

/* ---- the file ----------------------------------------------------------------------------- */

typedef struct nsec {
    uint32_t       id;
    const uint8_t *p;
    uint64_t       size, off;
    uint32_t       crc;
} nsec;

static void wr32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); }
static void wr64(uint8_t *p, uint64_t v) { memcpy(p, &v, 8); }

static uint64_t page_up(uint64_t x)
{
    return (x + ST_NATIVE_PAGE - 1) & ~(uint64_t)(ST_NATIVE_PAGE - 1);
}

static int write_zeros(int fd, uint64_t n)
{
    static const uint8_t z[ST_NATIVE_PAGE];
    while (n) {
        size_t k = n < sizeof z ? (size_t)n : sizeof z;
        if (stu_write_all(fd, z, k) != 0)
            return -1;
        n -= k;
    }
    return 0;
}

/* A native file of s as it will be written: the small sections serialised (the caller frees
 * meta->p and ext->p, also on failure), the five sections placed (CRCs not computed yet), the
 * file's size. Builds every level first (a deferred Ptex import's, set.h). */
static int layout(const st_set *s, nbuf *meta, nbuf *ext, uint8_t *ext_kind, uint64_t *nlevp,
                  nsec sec[5], uint64_t *file_size, st_error *e)
{
    int rc = st_set_levels(s, e); /* every level is written: a deferred Ptex import's (set.h) */
    if (rc)
        return rc;
    uint64_t nlev = 0;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        nlev += s->faces[f].nlevels;
    put_meta(meta, s);
    *ext_kind = ST_EXT_NONE;
    if (st_set_ext_get(s, ST_EXT_BC1)) {
        *ext_kind = ST_EXT_BC1;
        nb_put(ext, st_set_ext_get(s, ST_EXT_BC1), sizeof(st_bc1_ext));
    } else if (st_set_ext_get(s, ST_EXT_ATLAS)) {
        *ext_kind = ST_EXT_ATLAS;
        put_atlas(ext, st_set_ext_get(s, ST_EXT_ATLAS));
    } else if (st_set_ext_get(s, ST_EXT_PTEXRES)) {
        *ext_kind = ST_EXT_PTEXRES;
        rc = put_ptex(ext, s, e);
    }
    if (!rc && (meta->oom || ext->oom))
        rc = st_fail(e, ST_ENOMEM, "out of memory serialising the native file");
    if (rc)
        return rc;
    nsec plan[5] = {
        {ST_NSEC_FACES, (const uint8_t *)s->faces, (uint64_t)s->info.nfaces * 64, 0, 0},
        {ST_NSEC_LEVELS, (const uint8_t *)s->level_off, nlev * 8, 0, 0},
        {ST_NSEC_META, meta->p, meta->n, 0, 0},
        {ST_NSEC_EXT, ext->p, ext->n, 0, 0},
        {ST_NSEC_TEXELS, s->texels, s->texel_bytes, 0, 0},
    };
    uint64_t off = ST_NATIVE_PAGE;
    for (int i = 0; i < 5; i++) {
        sec[i] = plan[i];
        sec[i].off = off;
        off = page_up(off + sec[i].size + (sec[i].id == ST_NSEC_TEXELS ? ST_NATIVE_SLACK : 0));
        if (off == sec[i].off)
            off += ST_NATIVE_PAGE; /* an empty section still owns its page */
    }
    *nlevp = nlev;
    *file_size = off;
    return ST_OK;
}

int st_native_size(const st_set *s, uint64_t *bytes, st_error *e)
{
    nbuf meta = {0}, ext = {0};
    uint8_t ext_kind;
    uint64_t nlev;
    nsec sec[5];
    int rc = layout(s, &meta, &ext, &ext_kind, &nlev, sec, bytes, e);
    free(meta.p);
    free(ext.p);
    return rc;
}

int st_native_write_fd(int fd, const st_set *s, const st_native_source *src, st_error *e)
{
    nbuf meta = {0}, ext = {0};
    uint8_t ext_kind;
    uint64_t nlev, file_size;
    nsec sec[5];
    int rc = layout(s, &meta, &ext, &ext_kind, &nlev, sec, &file_size, e);
    if (rc) {
        free(meta.p);
        free(ext.p);
        return rc;
    }
    for (int i = 0; i < 5; i++)
        sec[i].crc = stu_crc32c(0, sec[i].p, (size_t)sec[i].size);

    uint8_t h[ST_NATIVE_PAGE];
    memset(h, 0, sizeof h);
    memcpy(h, ST_NATIVE_MAGIC, 8);
    wr32(h + 8, ST_NATIVE_VERSION);
    wr32(h + 12, ST_NATIVE_PAGE);
    wr64(h + 16, file_size);
    wr32(h + 24, 5);
    wr32(h + 28, 0);
    wr32(h + 32, s->info.nfaces);
    h[36] = s->info.nchan;
    h[37] = s->info.dtype;
    h[38] = (uint8_t)s->info.alpha_chan;
    h[39] = s->info.kind;
    h[40] = s->info.colorspace;
    h[41] = s->info.premultiplied;
    h[42] = s->info.border_u;
    h[43] = s->info.border_v;
    h[44] = s->info.meshtype;
    h[45] = ext_kind;
    h[46] = s->info.edgefilter;
    wr64(h + 48, nlev);
    wr64(h + 56, s->texel_bytes);
    if (src) {
        wr64(h + 64, src->bytes);
        wr32(h + 72, src->crc);
        memcpy(h + 80, src->name, strnlen(src->name, sizeof src->name < 95 ? sizeof src->name : 95));
    }
    for (int i = 0; i < 5; i++) {
        uint8_t *t = h + 1024 + 32 * i;
        wr32(t, sec[i].id);
        wr64(t + 8, sec[i].off);
        wr64(t + 16, sec[i].size);
        wr32(t + 24, sec[i].crc);
    }
    wr32(h + 4092, stu_crc32c(0, h, 4092));

    int err = stu_write_all(fd, h, sizeof h);
    uint64_t pos = ST_NATIVE_PAGE;
    for (int i = 0; !err && i < 5; i++) {
        err = write_zeros(fd, sec[i].off - pos);
        if (!err && sec[i].size)
            err = stu_write_all(fd, sec[i].p, (size_t)sec[i].size);
        pos = sec[i].off + sec[i].size;
    }
    if (!err)
        err = write_zeros(fd, file_size - pos);
    int saved = errno;
    free(meta.p);
    free(ext.p);
    if (err)
        return st_fail(e, ST_EIO, "writing the native file: %s", strerror(saved));
    return ST_OK;
}

int st_native_write(const char *path, const st_set *s, const st_native_source *src,
                    st_error *e)
{
    char tmp[4096];
    if ((size_t)snprintf(tmp, sizeof tmp, "%s.tmp", path) >= sizeof tmp)
        return st_fail(e, ST_EINVAL, "path too long");
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0)
        return st_fail(e, ST_EIO, "create %s: %s", tmp, strerror(errno));
    int rc = st_native_write_fd(fd, s, src, e);
    if (!rc && fsync(fd) != 0)
        rc = st_fail(e, ST_EIO, "fsync %s: %s", tmp, strerror(errno));
    close(fd);
    if (!rc && rename(tmp, path) != 0)
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", tmp, path, strerror(errno));
    if (!rc && stu_fsync_parent(path) != 0)
        rc = st_fail(e, ST_EIO, "fsync the folder of %s: %s", path, strerror(errno));
    if (rc)
        unlink(tmp);
    return rc;
}
