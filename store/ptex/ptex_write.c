/* store/ptex/ptex_write.c - writes a per-face set as a Ptex file (layout in ptex_format.h).
 *
 * Owns: encoding a set into .ptx bytes and writing them atomically. Does not own: reading
 * (ptex_read.c) or the set (set.c).
 *
 * What is written, following the Ptex library's own writer: header and 40-byte extended header
 * (minor version 4, border modes, editdatapos), zipped face info with the neighbourhood-constant
 * flag computed as Ptex does, zipped constant data (each face's 1x1 level), level 0 by face id
 * and the set's square reductions (levels 1..min(ulog2, vlog2), every face, rfaceid order),
 * each block planar and zipped (u8/u16 difference-coded), faces larger than 64 KiB tiled with
 * Ptex's tile size rule (uniform tiles stored as constant tiles), small metadata in one zip
 * block and entries over 1 KiB as large metadata. All levels of square faces are stored, so
 * reading the file gives the set back bit for bit; for non-square faces the levels past the
 * square reductions are re-derived by the reader with Ptex's rule (they round-trip exactly for
 * every set that the reader produced). A triangle-mesh set (st_meshtype) is written with mesh
 * type triangle: three edges per face (adjfaces[3] = -1, adjedges in bits 0..5), no subface
 * flags; its square faces' levels already hold the packed triangle layout and Ptex's triangle
 * reductions (core/trilevel.h), so every level is stored and comes back bit for bit.
 *
 * Metadata the writer leaves out or merges, so that write(read(write(s))) == write(s) and a
 * daemon's upload/fetch loop gives the same bytes every round:
 *   - "seamtex:source_format", which the importer appends to every set it makes (import.c):
 *     it says how the set in memory was made; a .ptx written here is a new source, and the
 *     importer would only re-add it ("ptex") to what it reads back;
 *   - a repeated key (st_set_meta_add appends): written once, at its first position with its
 *     last value - the rule the reader applies to repeated records and metadata edits.
 */
#include "ptex.h"
#include "fileio.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "ptex_format.h"

typedef struct wb {
    uint8_t *p;
    size_t len, cap;
    int oom;
} wb;

static int wb_reserve(wb *b, size_t n)
{
    if (b->oom)
        return -1;
    if (n <= b->cap - b->len)
        return 0;
    size_t nc = b->cap ? b->cap : 4096;
    while (nc - b->len < n) {
        if (nc > SIZE_MAX / 2) {
            b->oom = 1;
            return -1;
        }
        nc *= 2;
    }
    uint8_t *q = realloc(b->p, nc);
    if (!q) {
        b->oom = 1;
        return -1;
    }
    b->p = q;
    b->cap = nc;
    return 0;
}

static void wb_put(wb *b, const void *d, size_t n)
{
    if (wb_reserve(b, n))
        return;
    if (n)
        memcpy(b->p + b->len, d, n);
    b->len += n;
}

/* Appends one zlib stream of d; returns its size (0 and oom set on failure). */
static uint32_t wb_zip(wb *b, const void *d, size_t n)
{
    uLongf bound = compressBound((uLong)n);
    if (n > UINT32_MAX / 2 || wb_reserve(b, bound)) {
        b->oom = 1;
        return 0;
    }
    uLongf out = bound;
    if (compress2(b->p + b->len, &out, d, (uLong)n, Z_DEFAULT_COMPRESSION) != Z_OK) {
        b->oom = 1;
        return 0;
    }
    b->len += out;
    return (uint32_t)out;
}

typedef struct wctx {
    const st_set *s;
    size_t csize, psize;
    unsigned nc;
    uint8_t *tmp;                /* planar scratch, the size of the largest face */
} wctx;

static void deinterleave(const wctx *w, const uint8_t *src, size_t stride, uint32_t uw,
                         uint32_t vw, uint8_t *dst)
{
    size_t cs = w->csize, ps = w->psize;
    for (unsigned c = 0; c < w->nc; c++)
        for (uint32_t y = 0; y < vw; y++) {
            uint8_t *d = dst + (((size_t)c * vw + y) * uw) * cs;
            const uint8_t *sp = src + y * stride + c * cs;
            for (uint32_t x = 0; x < uw; x++)
                memcpy(d + x * cs, sp + x * ps, cs);
        }
}

static void encode_difference(unsigned dt, uint8_t *p, size_t bytes)
{
    if (dt == ST_DT_U8) {
        uint8_t prev = 0;
        for (size_t i = 0; i < bytes; i++) {
            uint8_t v = p[i];
            p[i] = (uint8_t)(v - prev);
            prev = v;
        }
    } else if (dt == ST_DT_U16) {
        uint16_t prev = 0;
        for (size_t i = 0; i + 1 < bytes; i += 2) {
            uint16_t v = ptx_rd16(p + i);
            ptx_wr16(p + i, (uint16_t)(v - prev));
            prev = v;
        }
    }
}

static int rect_uniform(const wctx *w, const uint8_t *src, size_t stride, uint32_t uw, uint32_t vw)
{
    for (uint32_t y = 0; y < vw; y++)
        for (uint32_t x = 0; x < uw; x++)
            if (memcmp(src, src + y * stride + x * w->psize, w->psize))
                return 0;
    return 1;
}

/* One zipped block of a uw x vw rectangle; returns its FaceDataHeader. */
static uint32_t put_block(wctx *w, wb *b, const uint8_t *src, size_t stride, uint32_t uw,
                          uint32_t vw)
{
    unsigned dt = w->s->info.dtype;
    size_t bytes = (size_t)uw * vw * w->psize;
    deinterleave(w, src, stride, uw, vw, w->tmp);
    int diff = dt == ST_DT_U8 || dt == ST_DT_U16;
    if (diff)
        encode_difference(dt, w->tmp, bytes);
    uint32_t z = wb_zip(b, w->tmp, bytes);
    return (z & 0x3fffffffu) | (uint32_t)(diff ? PTX_ENC_DIFFZIPPED : PTX_ENC_ZIPPED) << 30;
}

static unsigned floor_log2(size_t x)
{
    unsigned l = 0;
    while (x >>= 1)
        l++;
    return l;
}

/* A face's data at (ulog2, vlog2); tiled like Ptex when over PTX_TILE_SIZE bytes. */
static uint32_t put_face(wctx *w, wb *b, const uint8_t *src, unsigned ulog2, unsigned vlog2)
{
    uint32_t uw = 1u << ulog2, vw = 1u << vlog2;
    size_t stride = (size_t)uw * w->psize;
    size_t facesize = (size_t)uw * vw * w->psize;
    unsigned ntl = floor_log2(facesize / PTX_TILE_SIZE);
    if (facesize < PTX_TILE_SIZE || ntl == 0)
        return put_block(w, b, src, stride, uw, vw);
    int n = (int)(ulog2 + vlog2) - (int)ntl;
    int tu = (n + 1) / 2 < (int)ulog2 ? (n + 1) / 2 : (int)ulog2;
    int tv = n - tu < (int)vlog2 ? n - tu : (int)vlog2;
    uint32_t ntu = 1u << (ulog2 - (unsigned)tu), ntv = 1u << (vlog2 - (unsigned)tv);
    uint32_t tw = 1u << tu, th = 1u << tv;
    size_t ntiles = (size_t)ntu * ntv;
    uint8_t *hdr = malloc(ntiles * 4);
    wb tiles = {0};
    if (!hdr) {
        b->oom = 1;
        return 0;
    }
    for (uint32_t ty = 0; ty < ntv; ty++)
        for (uint32_t tx = 0; tx < ntu; tx++) {
            const uint8_t *p = src + (size_t)ty * th * stride + (size_t)tx * tw * w->psize;
            uint32_t fdh;
            if (rect_uniform(w, p, stride, tw, th)) {
                wb_put(&tiles, p, w->psize);
                fdh = (uint32_t)w->psize | (uint32_t)PTX_ENC_CONSTANT << 30;
            } else {
                fdh = put_block(w, &tiles, p, stride, tw, th);
            }
            ptx_wr32(hdr + 4 * ((size_t)ty * ntu + tx), fdh);
        }
    size_t start = b->len;
    uint8_t pre[6];
    pre[0] = (uint8_t)tu;
    pre[1] = (uint8_t)tv;
    wb_put(b, pre, 6);
    uint32_t hz = wb_zip(b, hdr, ntiles * 4);
    if (!b->oom)
        ptx_wr32(b->p + start + 2, hz);
    wb_put(b, tiles.p, tiles.len);
    if (tiles.oom)
        b->oom = 1;
    free(tiles.p);
    free(hdr);
    return (uint32_t)((b->len - start) & 0x3fffffffu) | (uint32_t)PTX_ENC_TILED << 30;
}

/* Ptex's neighbourhood-constant flag of a constant face: every face around each of its
 * vertices is constant with the same value. Vertices on a boundary clear it here. */
static int nb_constant(const st_set *s, uint32_t f, size_t ps)
{
    const st_face *F = &s->faces[f];
    const uint8_t *val = st_face_level(s, f, 0);
    int ne = s->info.meshtype == ST_MESH_TRIANGLE ? 3 : 4; /* edges (and corners) per face */
    for (int e = 0; e < ne; e++) {
        int prev_sub = (F->flags & ST_FACE_SUBFACE) != 0;
        int32_t prevf = (int32_t)f, af = F->adjface[e];
        int ae = F->adjedge[e], count = 0;
        while (af != (int32_t)f && af >= 0 && ++count < 10) {
            const st_face *A = &s->faces[af];
            if (!(A->flags & ST_FACE_CONSTANT) || memcmp(val, st_face_level(s, (uint32_t)af, 0), ps))
                return 0;
            int sub = (A->flags & ST_FACE_SUBFACE) != 0;
            if (prev_sub && !sub && A->adjface[ae] == prevf)
                break;
            prev_sub = sub;
            prevf = af;
            ae = (ae + 1) % ne;
            af = A->adjface[ae];
            ae = A->adjedge[ae];
        }
        if (af < 0)
            return 0; /* boundary vertex: left unflagged (Ptex may flag it; the filter then
                         computes the same constant the long way) */
    }
    return 1;
}

static size_t meta_tsize(unsigned t)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return t < 6 ? sz[t] : 0;
}

typedef struct meta_key {
    const char *key;
    uint32_t    idx;
} meta_key;

static int meta_key_cmp(const void *a, const void *b)
{
    const meta_key *x = a, *y = b;
    int c = strcmp(x->key, y->key);
    return c ? c : x->idx < y->idx ? -1 : x->idx > y->idx;
}

/* The importer's provenance entry, not written (see the top of this file). */
#define META_NOT_WRITTEN "seamtex:source_format"

/* Fills pick[i] for each metadata entry i: the entry whose value is written at position i
 * (the last entry with the same key) when i is the first entry with its key, else UINT32_MAX
 * (not written). O(n log n), so a set holding many entries costs little. */
static int meta_pick(const st_set *s, uint32_t *pick)
{
    uint32_t n = s->nmeta;
    meta_key *k = malloc((size_t)n * sizeof *k + 1);
    if (!k)
        return -1;
    for (uint32_t i = 0; i < n; i++) {
        k[i].key = s->meta[i].key;
        k[i].idx = i;
        pick[i] = UINT32_MAX;
    }
    qsort(k, n, sizeof *k, meta_key_cmp);
    for (uint32_t i = 0; i < n;) {
        uint32_t j = i;
        while (j + 1 < n && !strcmp(k[j + 1].key, k[i].key))
            j++;
        if (strcmp(k[i].key, META_NOT_WRITTEN))
            pick[k[i].idx] = k[j].idx;
        i = j + 1;
    }
    free(k);
    return 0;
}

int st_ptex_write_mem(const st_set *s, void **bufp, size_t *lenp, st_error *e)
{
    *bufp = NULL;
    *lenp = 0;
    if (s->info.kind != ST_KIND_PERFACE)
        return st_fail(e, ST_EUNSUPPORTED, "only per-face sets can be written as Ptex (kind %u)",
                       s->info.kind);
    int lrc = st_set_levels(s, e); /* the reductions written: a deferred Ptex import's (set.h) */
    if (lrc)
        return lrc;
    uint32_t n = s->info.nfaces;
    wctx w = {.s = s, .csize = st_dtype_size(s->info.dtype), .nc = s->info.nchan};
    w.psize = w.csize * w.nc;
    size_t maxface = 0;
    unsigned nlevels = 1;
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        size_t sz = (size_t)F->w * F->h * w.psize;
        if (sz > maxface)
            maxface = sz;
        unsigned m = F->flags & ST_FACE_CONSTANT ? 1u : (F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2);
        if (m + 1 > nlevels)
            nlevels = m + 1;
    }
    for (uint32_t i = 0; i < s->nmeta; i++) {
        size_t ksz = strlen(s->meta[i].key);
        if (ksz == 0 || ksz > 254)
            return st_fail(e, ST_EINVAL, "metadata key '%.40s' must have 1..254 bytes",
                           s->meta[i].key);
        if (!meta_tsize(s->meta[i].type) ||
            (uint64_t)s->meta[i].count * meta_tsize(s->meta[i].type) > (1u << 30))
            return st_fail(e, ST_EINVAL, "metadata '%s': bad type or size", s->meta[i].key);
    }
    w.tmp = malloc(maxface ? maxface : 1);
    uint8_t *fi = calloc(n, PTX_FACEINFO_SIZE);
    uint8_t *cd = malloc((size_t)n * w.psize);
    uint32_t *fdh = malloc((size_t)n * sizeof *fdh);
    uint32_t *faceids_r = malloc((size_t)n * sizeof *faceids_r);
    uint32_t *mpick = malloc((size_t)s->nmeta * sizeof *mpick + 1);
    wb out = {0}, faces = {0};
    int rc = ST_OK;
    if (!w.tmp || !fi || !cd || !fdh || !faceids_r || !mpick || meta_pick(s, mpick)) {
        rc = st_fail(e, ST_ENOMEM, "out of memory writing %u faces", n);
        goto done;
    }
    /* face info and constant data */
    for (uint32_t f = 0; f < n; f++) {
        const st_face *F = &s->faces[f];
        ptx_faceinfo x = {.ulog2 = (int8_t)F->ulog2, .vlog2 = (int8_t)F->vlog2};
        for (int ed = 0; ed < 4; ed++) {
            x.adjfaces[ed] = F->adjface[ed];
            x.adjedges |= (uint8_t)((F->adjface[ed] >= 0 ? F->adjedge[ed] & 3 : 0) << (2 * ed));
        }
        if (F->flags & ST_FACE_CONSTANT)
            x.flags |= PTX_FLAG_CONSTANT;
        if (F->flags & ST_FACE_SUBFACE)
            x.flags |= PTX_FLAG_SUBFACE;
        if ((F->flags & ST_FACE_CONSTANT) && nb_constant(s, f, w.psize))
            x.flags |= PTX_FLAG_NBCONSTANT;
        ptx_faceinfo_encode(fi + (size_t)f * PTX_FACEINFO_SIZE, &x);
        unsigned last = F->flags & ST_FACE_CONSTANT ? 0 : F->nlevels - 1u;
        memcpy(cd + (size_t)f * w.psize, st_face_level(s, f, last), w.psize);
    }
    /* rfaceid order (stable, min(ulog2, vlog2) descending, constant faces count 1) */
    {
        uint32_t cnt[ST_MAX_LOG2 + 2] = {0}, start[ST_MAX_LOG2 + 2], acc = 0;
        for (uint32_t f = 0; f < n; f++) {
            const st_face *F = &s->faces[f];
            cnt[F->flags & ST_FACE_CONSTANT ? 1 : (F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2)]++;
        }
        for (int m = ST_MAX_LOG2 + 1; m >= 0; m--) {
            start[m] = acc;
            acc += cnt[m];
        }
        for (uint32_t f = 0; f < n; f++) {
            const st_face *F = &s->faces[f];
            faceids_r[start[F->flags & ST_FACE_CONSTANT ? 1 :
                            (F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2)]++] = f;
        }
    }
    uint8_t hdr[PTX_HEADER_SIZE + PTX_EXTHEADER_SIZE] = {0};
    wb_put(&out, hdr, sizeof hdr);
    uint32_t fisize = wb_zip(&out, fi, (size_t)n * PTX_FACEINFO_SIZE);
    uint32_t cdsize = wb_zip(&out, cd, (size_t)n * w.psize);
    size_t lipos = out.len;
    uint8_t li[PTX_MAX_LEVELS_W * PTX_LEVELINFO_SIZE];
    memset(li, 0, sizeof li);
    wb_put(&out, li, (size_t)nlevels * PTX_LEVELINFO_SIZE);
    uint64_t ldsize = 0;
    for (unsigned l = 0; l < nlevels; l++) {
        uint32_t nf = 0;
        faces.len = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t f = l == 0 ? i : faceids_r[i];
            const st_face *F = &s->faces[f];
            unsigned m = F->flags & ST_FACE_CONSTANT ? 1u : (F->ulog2 < F->vlog2 ? F->ulog2 : F->vlog2);
            if (l > 0 && m < l)
                break; /* rfaceid order: no later face has this level */
            if (F->flags & ST_FACE_CONSTANT) {
                wb_put(&faces, st_face_level(s, f, 0), w.psize);
                fdh[nf++] = (uint32_t)w.psize | (uint32_t)PTX_ENC_CONSTANT << 30;
            } else {
                fdh[nf++] = put_face(&w, &faces, st_face_level(s, f, l), F->ulog2 - l, F->vlog2 - l);
            }
        }
        uint8_t *fh = malloc((size_t)nf * 4 + 1);
        if (!fh) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for a level header");
            goto done;
        }
        for (uint32_t i = 0; i < nf; i++)
            ptx_wr32(fh + 4 * i, fdh[i]);
        size_t lstart = out.len;
        uint32_t hsize = wb_zip(&out, fh, (size_t)nf * 4);
        free(fh);
        wb_put(&out, faces.p, faces.len);
        if (faces.oom)
            out.oom = 1;
        uint64_t lsize = out.len - lstart;
        if (!out.oom) {
            uint8_t *lp = out.p + lipos + (size_t)l * PTX_LEVELINFO_SIZE;
            ptx_wr64(lp, lsize);
            ptx_wr32(lp + 8, hsize);
            ptx_wr32(lp + 12, nf);
        }
        ldsize += lsize;
    }
    /* metadata: small entries in one block, large ones in their own blocks */
    uint32_t mdzip = 0, mdmem = 0, lmdzip = 0, lmdmem = 0;
    uint64_t lmddata = 0;
    {
        wb small = {0}, lhdr = {0}, ldata = {0};
        for (uint32_t i = 0; i < s->nmeta; i++) {
            if (mpick[i] == UINT32_MAX)
                continue; /* a repeated key: written once, at its first position */
            const st_meta_entry *m = &s->meta[mpick[i]];
            uint8_t ks = (uint8_t)(strlen(m->key) + 1), type = m->type;
            uint32_t ds = (uint32_t)(m->count * meta_tsize(m->type));
            uint8_t d4[4];
            ptx_wr32(d4, ds);
            wb *dst = ds > PTX_META_THRESHOLD ? &lhdr : &small;
            wb_put(dst, &ks, 1);
            wb_put(dst, m->key, ks);
            wb_put(dst, &type, 1);
            wb_put(dst, d4, 4);
            if (dst == &small) {
                wb_put(dst, m->data, ds);
            } else {
                uint32_t z = wb_zip(&ldata, m->data, ds);
                ptx_wr32(d4, z);
                wb_put(dst, d4, 4);
                lmddata += z;
            }
        }
        if (small.len) {
            mdmem = (uint32_t)small.len;
            mdzip = wb_zip(&out, small.p, small.len);
        }
        uint8_t barrier[8] = {0};
        wb_put(&out, barrier, 8);
        if (lhdr.len) {
            lmdmem = (uint32_t)lhdr.len;
            lmdzip = wb_zip(&out, lhdr.p, lhdr.len);
            wb_put(&out, ldata.p, ldata.len);
        }
        if (small.oom || lhdr.oom || ldata.oom)
            out.oom = 1;
        free(small.p);
        free(lhdr.p);
        free(ldata.p);
    }
    if (out.oom) {
        rc = st_fail(e, ST_ENOMEM, "out of memory encoding the Ptex file");
        goto done;
    }
    uint8_t *h = out.p;
    ptx_wr32(h, PTX_MAGIC);
    ptx_wr32(h + 4, 1);
    ptx_wr32(h + 8, s->info.meshtype == ST_MESH_TRIANGLE ? PTX_MESH_TRIANGLE : PTX_MESH_QUAD);
    ptx_wr32(h + 12, s->info.dtype);
    ptx_wr32(h + 16, (uint32_t)(int32_t)s->info.alpha_chan);
    ptx_wr16(h + 20, s->info.nchan);
    ptx_wr16(h + 22, (uint16_t)nlevels);
    ptx_wr32(h + 24, n);
    ptx_wr32(h + 28, PTX_EXTHEADER_SIZE);
    ptx_wr32(h + 32, fisize);
    ptx_wr32(h + 36, cdsize);
    ptx_wr32(h + 40, nlevels * PTX_LEVELINFO_SIZE);
    ptx_wr32(h + 44, 4);
    ptx_wr64(h + 48, ldsize);
    ptx_wr32(h + 56, mdzip);
    ptx_wr32(h + 60, mdmem);
    uint8_t *x = h + PTX_HEADER_SIZE;
    ptx_wr16(x, s->info.border_u);
    ptx_wr16(x + 4, s->info.border_v);
    ptx_wr16(x + 6, s->info.edgefilter == ST_EDGEFILTER_TANVEC);
    ptx_wr32(x + 8, lmdzip);
    ptx_wr32(x + 12, lmdmem);
    ptx_wr64(x + 16, lmddata);
    ptx_wr64(x + 24, 0);
    ptx_wr64(x + 32, out.len); /* edits would start here */
    *bufp = out.p;
    *lenp = out.len;
    out.p = NULL;
done:
    free(out.p);
    free(faces.p);
    free(w.tmp);
    free(fi);
    free(cd);
    free(fdh);
    free(faceids_r);
    free(mpick);
    return rc;
}

int st_ptex_write_file(const st_set *s, const char *path, st_error *e)
{
    void *buf;
    size_t len;
    int rc = st_ptex_write_mem(s, &buf, &len, e);
    if (rc)
        return rc;
    rc = st_file_write_atomic(path, buf, len, e);
    free(buf);
    return rc;
}
