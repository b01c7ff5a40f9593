/* store/native/native_read.c - opens a native file as a set sampled from a read-only mapping
 * (format table and the checks made in native.h).
 *
 * Owns: st_native_open and st_native_open_fd (residency and release: native_resident.c). Order: the
 * header page is read with pread and checked (its CRC, magic, version, sizes, the section
 * table: page-aligned, inside the file, no overlap, the sizes the header implies) before the
 * file is mapped; then the small sections' CRCs, the face table and level offsets against the
 * canonical layout, the metadata and the extension record, each read through a bounded cursor.
 * Nothing in the file is used as an offset or a count before it is checked.
 */
#include "native.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "atlas.h"
#include "bc1_texel.h"
#include "crc32c.h"
#include "mesh.h"
#include "ptexres.h"

static uint32_t rd32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t rd64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }

static unsigned floor_log2(uint32_t x)
{
    unsigned l = 0;
    while (x >>= 1)
        l++;
    return l;
}

/* ---- a bounded cursor over one section ------------------------------------------------------ */

typedef struct cur {
    const uint8_t *p;
    size_t         n, at;
    int            bad;
} cur;

static const uint8_t *cur_take(cur *c, size_t n)
{
    if (c->bad || n > c->n - c->at) {
        c->bad = 1;
        return NULL;
    }
    const uint8_t *q = c->p + c->at;
    c->at += n;
    return q;
}
static uint32_t cur_u32(cur *c)
{
    const uint8_t *q = cur_take(c, 4);
    return q ? rd32(q) : 0;
}
static int cur_copy(cur *c, void *dst, size_t n)
{
    const uint8_t *q = cur_take(c, n);
    if (!q)
        return -1;
    if (n)
        memcpy(dst, q, n);
    return 0;
}
static void cur_pad4(cur *c) { cur_take(c, (4 - (c->at & 3)) & 3); }

/* n * k bytes, refusing an overflow or more than the section holds */
static int cur_array(cur *c, void *dst, size_t n, size_t k)
{
    if (k && n > (c->n - c->at) / k) {
        c->bad = 1;
        return -1;
    }
    return cur_copy(c, dst, n * k);
}

static size_t meta_type_size(unsigned type)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return type < 6 ? sz[type] : 0;
}

/* ---- sections ------------------------------------------------------------------------------ */

typedef struct sect {
    uint64_t off, size;
    uint32_t crc;
    int      present;
} sect;

static int check_meta(st_set *s, const uint8_t *p, size_t n, st_error *e)
{
    cur c = {p, n, 0, 0};
    uint32_t count = cur_u32(&c);
    for (uint32_t i = 0; !c.bad && i < count; i++) {
        uint32_t k = cur_u32(&c);
        const uint8_t *t = cur_take(&c, 4);
        uint32_t cnt = cur_u32(&c), d = cur_u32(&c);
        if (c.bad)
            break;
        unsigned type = t[0];
        size_t es = meta_type_size(type);
        if (!es || k < 1 || k > 4096 || (uint64_t)es * cnt != d)
            return st_fail(e, ST_EFORMAT, "native metadata entry %u: bad type, key or size", i);
        const uint8_t *key = cur_take(&c, k);
        const uint8_t *data = cur_take(&c, d);
        cur_pad4(&c);
        if (c.bad)
            break;
        if (key[k - 1] != 0 || memchr(key, 0, k) != key + k - 1)
            return st_fail(e, ST_EFORMAT, "native metadata entry %u: key is not a string", i);
        int rc = st_set_meta_add(s, (const char *)key, type, data, cnt, e);
        if (rc)
            return rc;
    }
    if (c.bad)
        return st_fail(e, ST_EFORMAT, "native metadata section is truncated");
    return ST_OK;
}

static int read_mesh_edges(cur *c, st_mesh_edge **out, uint32_t n, uint32_t nweld, uint32_t ntri)
{
    if (n > (c->n - c->at) / 20) {
        c->bad = 1;
        return -1;
    }
    *out = calloc(n ? n : 1, sizeof **out);
    if (!*out)
        return -2;
    for (uint32_t i = 0; i < n; i++) {
        st_mesh_edge *x = &(*out)[i];
        cur_copy(c, x->pos, 8);
        x->tri = cur_u32(c);
        const uint8_t *q = cur_take(c, 4);
        x->edge = q ? q[0] : 0;
        x->count = cur_u32(c);
        if (c->bad || x->pos[0] >= nweld || x->pos[1] >= nweld || x->tri >= ntri || x->edge > 2)
            return -1;
    }
    return 0;
}

static int check_atlas(st_set *s, const uint8_t *p, size_t n, st_error *e)
{
    cur c = {p, n, 0, 0};
    uint32_t parts = cur_u32(&c), mw = cur_u32(&c), mh = cur_u32(&c);
    st_atlas *a = st_atlas_new();
    if (!a)
        return st_fail(e, ST_ENOMEM, "out of memory for the atlas");
    st_mesh *m = NULL;
    int rc = ST_OK;
    cur_copy(&c, a->texture_name, sizeof a->texture_name);
    a->texture_name[sizeof a->texture_name - 1] = 0;
    if (c.bad || (parts & ~7u) || ((parts & 2) && !(parts & 1)) || ((parts & 4) && !(parts & 1)))
        goto bad;
    if (parts & 1) {
        uint32_t h[7];
        if (cur_array(&c, h, 7, 4))
            goto bad;
        uint32_t npos = h[0], nuv = h[1], ntri = h[2], nweld = h[3], nmat = h[6];
        size_t left = c.n - c.at;
        /* counts against the bytes that are there, before anything is allocated */
        if (nmat < 1 || nmat > ST_MESH_MAX_MATERIALS || nweld > npos || (npos && !nweld) ||
            ntri > left / 42 || npos > left / 12 || nuv > left / 8)
            goto bad;
        if ((rc = st_mesh_alloc(npos, nuv, ntri, &m, e)))
            goto fail;
        m->nweld = nweld;
        m->nfaces_src = h[4];
        m->ntri_nouv = h[5];
        st_material *mats = calloc(nmat, sizeof *mats);
        if (!mats) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for materials");
            goto fail;
        }
        free(m->mats);
        m->mats = mats;
        m->nmat = nmat;
        size_t t = ntri;
        if (cur_array(&c, m->pos, (size_t)npos * 3, 4) || cur_array(&c, m->uv, (size_t)nuv * 2, 4) ||
            cur_array(&c, m->tri_pos, t * 3, 4) || cur_array(&c, m->tri_uv, t * 3, 4) ||
            cur_array(&c, m->tri_weld, t * 3, 4) || cur_array(&c, m->tri_face, t, 4) ||
            cur_array(&c, m->tri_mat, t, 2))
            goto bad;
        cur_pad4(&c);
        for (uint32_t i = 0; i < nmat; i++) {
            if (cur_copy(&c, mats[i].name, sizeof mats[i].name) ||
                cur_copy(&c, mats[i].map_kd, sizeof mats[i].map_kd))
                goto bad;
            mats[i].name[sizeof mats[i].name - 1] = 0;
            mats[i].map_kd[sizeof mats[i].map_kd - 1] = 0;
        }
        for (size_t i = 0; i < t * 3; i++)
            if (m->tri_pos[i] >= npos || (m->tri_uv[i] != ST_MESH_NO_UV && m->tri_uv[i] >= nuv) ||
                (nweld && m->tri_weld[i] >= nweld))
                goto bad;
        for (size_t i = 0; i < t; i++)
            if (m->tri_mat[i] >= nmat)
                goto bad;
    }
    if (parts & 2) {
        uint32_t h[7];
        if (cur_array(&c, h, 7, 4))
            goto bad;
        st_seams *sm = calloc(1, sizeof *sm);
        if (!sm) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for seams");
            goto fail;
        }
        m->seams = sm;
        sm->nseams = h[0];
        sm->nboundary = h[1];
        sm->nnonmanifold = h[2];
        sm->nedges = h[3];
        sm->ncharts = h[4];
        sm->ndegenerate = h[5];
        sm->nuv_border = h[6];
        if (sm->nseams > (c.n - c.at) / 56)
            goto bad;
        sm->seams = calloc(sm->nseams ? sm->nseams : 1, sizeof *sm->seams);
        sm->tri_chart = calloc(m->ntri ? m->ntri : 1, sizeof *sm->tri_chart);
        if (!sm->seams || !sm->tri_chart) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for seams");
            goto fail;
        }
        for (uint32_t i = 0; i < sm->nseams; i++) {
            st_seam_edge *x = &sm->seams[i];
            cur_copy(&c, x->pos, 8);
            cur_copy(&c, x->tri, 8);
            cur_copy(&c, x->edge, 2);
            cur_copy(&c, x->winding, 2);
            const uint8_t *q = cur_take(&c, 4);
            x->mirrored = q ? q[0] : 0;
            cur_copy(&c, x->uv, 32);
            if (c.bad || x->pos[0] >= m->nweld || x->pos[1] >= m->nweld || x->tri[0] >= m->ntri ||
                x->tri[1] >= m->ntri || x->edge[0] > 2 || x->edge[1] > 2)
                goto bad;
        }
        int r1 = read_mesh_edges(&c, &sm->boundary, sm->nboundary, m->nweld, m->ntri);
        int r2 = r1 ? r1 : read_mesh_edges(&c, &sm->nonmanifold, sm->nnonmanifold, m->nweld, m->ntri);
        if (r1 == -2 || r2 == -2) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for seams");
            goto fail;
        }
        if (r1 || r2 || cur_array(&c, sm->tri_chart, m->ntri, 4))
            goto bad;
        for (uint32_t i = 0; i < m->ntri; i++)
            if (sm->tri_chart[i] >= sm->ncharts)
                goto bad;
    }
    if (parts & 4) {
        if (mw != s->faces[0].w || mh != s->faces[0].h)
            goto bad;
        size_t mn = (size_t)mw * mh;
        const uint8_t *q = cur_take(&c, mn);
        if (!q)
            goto bad;
        a->chart_mask = malloc(mn ? mn : 1);
        if (!a->chart_mask) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for the chart mask");
            goto fail;
        }
        memcpy(a->chart_mask, q, mn);
        a->mask_w = mw;
        a->mask_h = mh;
    }
    if (c.at != c.n)
        goto bad;
    a->mesh = m;
    /* the chart ids are not stored, nor made here: the first chart Discard / chart Traverse
     * sample rasterises them from the mesh (st_atlas_charts_pin), and the memory budget may
     * drop them again */
    st_set_ext x;
    st_atlas_ext(a, &x);
    st_set_ext_attach(s, &x);
    return ST_OK;
bad:
    rc = st_fail(e, ST_EFORMAT, "native atlas record is truncated or inconsistent");
fail:
    st_mesh_free(m);
    st_atlas_free(a);
    return rc;
}

static int check_ext(st_set *s, unsigned kind, const uint8_t *p, size_t n, st_error *e)
{
    switch (kind) {
    case ST_EXT_NONE:
        return n ? st_fail(e, ST_EFORMAT, "native extension section without a kind") : ST_OK;
    case ST_EXT_BC1: {
        if (s->info.kind != ST_KIND_BC1 || n != sizeof(st_bc1_ext))
            return st_fail(e, ST_EFORMAT, "native BC1 record: wrong size or set kind");
        st_bc1_ext *x = malloc(sizeof *x);
        if (!x)
            return st_fail(e, ST_ENOMEM, "out of memory");
        memcpy(x, p, sizeof *x);
        st_set_ext_attach(s, &(st_set_ext){.kind = ST_EXT_BC1, .data = x, .free = free});
        return ST_OK;
    }
    case ST_EXT_ATLAS:
        if (s->info.kind != ST_KIND_ATLAS)
            return st_fail(e, ST_EFORMAT, "native atlas record on a set that is no atlas");
        return check_atlas(s, p, n, e);
    case ST_EXT_PTEXRES: {
        uint32_t nf = s->info.nfaces;
        size_t base = (size_t)nf * (2 + st_texel_size(s));
        if (s->info.kind != ST_KIND_PERFACE || n < base)
            return st_fail(e, ST_EFORMAT, "native Ptex record: wrong size or set kind");
        st_ptexres_ctile *ct = NULL;
        uint32_t nct = 0;
        if (n > base) { /* the constant-tile list (docs/native.md) */
            const uint8_t *c = p + base;
            if (n - base < 4)
                return st_fail(e, ST_EFORMAT, "native Ptex record: truncated constant-tile list");
            memcpy(&nct, c, 4);
            if (nct == 0 || nct > (uint32_t)((n - base - 4) / 8) || n - base - 4 != (size_t)nct * 8)
                return st_fail(e, ST_EFORMAT, "native Ptex record: constant-tile list of %u "
                               "entries in %zu bytes", nct, n - base - 4);
            if (!(ct = malloc((size_t)nct * sizeof *ct)))
                return st_fail(e, ST_ENOMEM, "out of memory");
            for (uint32_t i = 0; i < nct; i++) {
                const uint8_t *x = c + 4 + (size_t)i * 8;
                memcpy(&ct[i].face, x, 4);
                ct[i].level = x[4], ct[i].tu = x[5], ct[i].tv = x[6], ct[i].pad = 0;
                /* a face of the set, a stored level, tiles no larger than the format allows,
                 * sorted by face then level without repeats (st_ptexres_set_ctiles' order) */
                if (ct[i].face >= nf || x[4] >= s->faces[ct[i].face].nlevels || x[5] > 15 ||
                    x[6] > 15 || x[7] ||
                    (i && (ct[i].face < ct[i - 1].face ||
                           (ct[i].face == ct[i - 1].face && ct[i].level <= ct[i - 1].level)))) {
                    free(ct);
                    return st_fail(e, ST_EFORMAT, "native Ptex record: constant-tile entry %u "
                                   "out of range or order", i);
                }
            }
        }
        /* flags and stored-level counts (copied); the constant values that follow are the
         * faces' last levels, which the table reads: the levels are never written */
        int rc = st_ptexres_attach_lazy(s, p, p + nf, 0, e);
        if (!rc && nct)
            rc = st_ptexres_set_ctiles(s, ct, nct, e);
        free(ct);
        return rc;
    }
    default:
        return st_fail(e, ST_EFORMAT, "native extension kind %u unknown", kind);
    }
}

/* The face table and level offsets against the layout st_set_create builds. */
static int check_faces(const st_set *s, uint64_t nlev, st_error *e)
{
    const st_set_info *in = &s->info;
    uint32_t n = in->nfaces;
    size_t ts = st_texel_size(s);
    uint64_t lvl = 0, off = 0;
    int bc1 = in->kind == ST_KIND_BC1;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        if (F->w < 1 || F->h < 1 || F->w > ST_MAX_DIM || F->h > ST_MAX_DIM)
            return st_fail(e, ST_EFORMAT, "native face %u: size %ux%u", f, F->w, F->h);
        if (in->kind != ST_KIND_ATLAS && !bc1 && ((F->w & (F->w - 1)) || (F->h & (F->h - 1))))
            return st_fail(e, ST_EFORMAT, "native face %u: size not a power of two", f);
        unsigned nl = floor_log2(F->w > F->h ? F->w : F->h) + 1;
        if (F->ulog2 != floor_log2(F->w) || F->vlog2 != floor_log2(F->h) || F->nlevels != nl ||
            (F->flags & ~(ST_FACE_CONSTANT | ST_FACE_SUBFACE)) || F->lvl != lvl)
            return st_fail(e, ST_EFORMAT, "native face %u: log2 sizes, levels, flags or level "
                           "index do not match its size", f);
        for (int k = 0; k < 4; k++) {
            if (F->adjface[k] < -1 || (F->adjface[k] >= 0 && (uint32_t)F->adjface[k] >= n) ||
                F->adjedge[k] > 3 || F->cornerface[k] < -1 ||
                (F->cornerface[k] >= 0 && (uint32_t)F->cornerface[k] >= n) ||
                F->cornercorner[k] > 3)
                return st_fail(e, ST_EFORMAT, "native face %u: adjacency out of range", f);
        }
        lvl += nl;
        if (lvl > nlev)
            return st_fail(e, ST_EFORMAT, "native face %u: more levels than the header has", f);
        for (unsigned l = 0; l < nl; l++) {
            if (s->level_off[F->lvl + l] != off)
                return st_fail(e, ST_EFORMAT, "native face %u level %u: offset %llu, layout "
                               "says %llu", f, l, (unsigned long long)s->level_off[F->lvl + l],
                               (unsigned long long)off);
            if (!(F->flags & ST_FACE_CONSTANT)) {
                uint64_t w = st_level_w(F, l), h = st_level_h(F, l);
                off += bc1 ? ((w + 3) / 4) * ((h + 3) / 4) * 8 : w * h * ts;
            }
        }
        if (F->flags & ST_FACE_CONSTANT)
            off += ts;
        if (off > s->texel_bytes)
            return st_fail(e, ST_EFORMAT, "native face %u: levels run past the texel arena", f);
    }
    if (lvl != nlev || off != s->texel_bytes)
        return st_fail(e, ST_EFORMAT, "native face table covers %llu levels and %llu bytes, the "
                       "header says %llu and %llu", (unsigned long long)lvl,
                       (unsigned long long)off, (unsigned long long)nlev,
                       (unsigned long long)s->texel_bytes);
    return st_set_check_adjacency(s, e) ? st_fail(e, ST_EFORMAT, "native adjacency: %s", e->msg)
                                        : ST_OK;
}

int st_native_open_fd(int fd, unsigned flags, st_native_source *src, st_set **out, st_error *e)
{
    *out = NULL;
    struct stat stt;
    uint8_t h[ST_NATIVE_PAGE];
    if (fstat(fd, &stt) != 0) {
        close(fd);
        return st_fail(e, ST_EIO, "fstat: %s", strerror(errno));
    }
    uint64_t fsize = (uint64_t)stt.st_size;
    if (fsize < ST_NATIVE_PAGE) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "native file truncated: %llu bytes, less than its header",
                       (unsigned long long)fsize);
    }
    ssize_t r = pread(fd, h, sizeof h, 0);
    if (r != (ssize_t)sizeof h) {
        close(fd);
        return st_fail(e, ST_EIO, "reading the native header: %s", r < 0 ? strerror(errno) : "short");
    }
    if (memcmp(h, ST_NATIVE_MAGIC, 8) != 0) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "not a native set file (bad magic)");
    }
    if (stu_crc32c(0, h, 4092) != rd32(h + 4092)) {
        close(fd);
        return st_fail(e, ST_ECORRUPT, "native header CRC-32C does not match");
    }
    if (rd32(h + 8) != ST_NATIVE_VERSION || rd32(h + 12) != ST_NATIVE_PAGE) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "native file version %u / page %u not supported",
                       rd32(h + 8), rd32(h + 12));
    }
    if (rd64(h + 16) != fsize) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "native file is %llu bytes, its header says %llu "
                       "(truncated or extended)", (unsigned long long)fsize,
                       (unsigned long long)rd64(h + 16));
    }
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = rd32(h + 32);
    info.nchan = h[36];
    info.dtype = h[37];
    info.alpha_chan = (int8_t)h[38];
    info.kind = h[39];
    info.colorspace = h[40];
    info.premultiplied = h[41];
    info.border_u = h[42];
    info.border_v = h[43];
    info.meshtype = h[44];
    info.edgefilter = h[46]; /* reserved (0, none) in files written before it */
    unsigned ext_kind = h[45];
    uint64_t nlev = rd64(h + 48), tbytes = rd64(h + 56);
    uint32_t nsec = rd32(h + 24);
    const char *why = NULL;
    if (info.nfaces < 1 || info.nfaces > ST_MAX_FACES)
        why = "face count";
    else if (info.nchan < 1 || info.nchan > ST_MAX_CHANNELS || !st_dtype_size(info.dtype))
        why = "channels or data type";
    else if (info.alpha_chan < -1 || info.alpha_chan >= (int)info.nchan)
        why = "alpha channel";
    else if (info.kind > ST_KIND_BC1 || (info.kind == ST_KIND_BC1 &&
             (info.dtype != ST_DT_U8 || info.nchan != 4)))
        why = "set kind";
    else if (info.colorspace > 1 || info.premultiplied > 1 || info.border_u > 2 ||
             info.border_v > 2 || info.meshtype > 1 || info.edgefilter > 1)
        why = "colour space, border, mesh type or edge filter mode";
    else if (nlev > (uint64_t)info.nfaces * ST_MAX_LEVELS || nlev < info.nfaces)
        why = "level count";
    else if (nsec < 3 || nsec > ST_NATIVE_MAX_SECTIONS)
        why = "section count";
    if (why) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "native header: bad %s", why);
    }
    sect sec[6];
    memset(sec, 0, sizeof sec);
    for (uint32_t i = 0; i < nsec; i++) {
        const uint8_t *t = h + 1024 + 32 * i;
        uint32_t id = rd32(t);
        uint64_t off = rd64(t + 8), size = rd64(t + 16);
        if (id < 1 || id > 5 || sec[id].present) {
            close(fd);
            return st_fail(e, ST_EFORMAT, "native section %u: id %u unknown or repeated", i, id);
        }
        uint64_t need = id == ST_NSEC_TEXELS ? ST_NATIVE_SLACK : 0;
        if (off % ST_NATIVE_PAGE || off < ST_NATIVE_PAGE || off > fsize ||
            size > fsize - off || need > fsize - off - size) {
            close(fd);
            return st_fail(e, ST_EFORMAT, "native section %u: offset %llu size %llu lies outside "
                           "the %llu-byte file", id, (unsigned long long)off,
                           (unsigned long long)size, (unsigned long long)fsize);
        }
        sec[id] = (sect){off, size, rd32(t + 24), 1};
    }
    for (int a = 1; a <= 5; a++)
        for (int b = a + 1; b <= 5; b++)
            if (sec[a].present && sec[b].present && sec[a].size && sec[b].size &&
                sec[a].off < sec[b].off + sec[b].size && sec[b].off < sec[a].off + sec[a].size) {
                close(fd);
                return st_fail(e, ST_EFORMAT, "native sections %d and %d overlap", a, b);
            }
    if (!sec[ST_NSEC_FACES].present || !sec[ST_NSEC_LEVELS].present || !sec[ST_NSEC_TEXELS].present ||
        sec[ST_NSEC_FACES].size != (uint64_t)info.nfaces * 64 || sec[ST_NSEC_LEVELS].size != nlev * 8 ||
        sec[ST_NSEC_TEXELS].size != tbytes) {
        close(fd);
        return st_fail(e, ST_EFORMAT, "native file: a required section is missing or its size "
                       "disagrees with the header");
    }
    if (fsize > SIZE_MAX) {
        close(fd);
        return st_fail(e, ST_ETOOBIG, "native file too large to map");
    }
    uint8_t *map = mmap(NULL, (size_t)fsize, PROT_READ, MAP_SHARED, fd, 0);
    if (map == MAP_FAILED) {
        close(fd);
        return st_fail(e, errno == ENOMEM ? ST_ENOMEM : ST_EIO, "mmap: %s", strerror(errno));
    }
    /* sampling reads a few pages of a set at random: without this a fault reads ahead whole
     * megabytes, and a released set (the memory budget) comes back whole at its next sample */
    madvise(map, (size_t)fsize, MADV_RANDOM);
    st_set *s = calloc(1, sizeof *s);
    if (!s) {
        munmap(map, (size_t)fsize);
        close(fd);
        return st_fail(e, ST_ENOMEM, "out of memory for the set header");
    }
    s->info = info;
    s->map = map;
    s->map_len = (size_t)fsize;
    s->map_fd = fd;
    s->faces = (st_face *)(void *)(map + sec[ST_NSEC_FACES].off);
    s->level_off = (uint64_t *)(void *)(map + sec[ST_NSEC_LEVELS].off);
    s->texels = map + sec[ST_NSEC_TEXELS].off;
    s->texel_bytes = (size_t)tbytes;
    int rc = ST_OK;
    static const char *const names[] = {"", "face table", "level offsets", "metadata",
                                        "extension", "texels"};
    for (int id = 1; id <= 5 && !rc; id++) {
        if (!sec[id].present || (id == ST_NSEC_TEXELS && !(flags & ST_NATIVE_VERIFY)))
            continue;
        if (stu_crc32c(0, map + sec[id].off, (size_t)sec[id].size) != sec[id].crc)
            rc = st_fail(e, ST_ECORRUPT, "native %s section fails its CRC-32C", names[id]);
    }
    if (!rc)
        rc = check_faces(s, nlev, e);
    if (!rc && sec[ST_NSEC_META].present)
        rc = check_meta(s, map + sec[ST_NSEC_META].off, (size_t)sec[ST_NSEC_META].size, e);
    if (!rc)
        rc = check_ext(s, ext_kind, sec[ST_NSEC_EXT].present ? map + sec[ST_NSEC_EXT].off : NULL,
                       sec[ST_NSEC_EXT].present ? (size_t)sec[ST_NSEC_EXT].size : 0, e);
    if (rc) {
        st_set_free(s);
        return rc;
    }
    if (src) {
        memset(src, 0, sizeof *src);
        src->bytes = rd64(h + 64);
        src->crc = rd32(h + 72);
        memcpy(src->name, h + 80, sizeof src->name - 1);
    }
    *out = s;
    return ST_OK;
}

int st_native_open(const char *path, unsigned flags, st_native_source *src, st_set **out,
                   st_error *e)
{
    *out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return st_fail(e, errno == ENOENT ? ST_ENOTFOUND : ST_EIO, "open %s: %s", path,
                       strerror(errno));
    return st_native_open_fd(fd, flags, src, out, e);
}
