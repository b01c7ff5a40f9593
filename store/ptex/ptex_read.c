/* store/ptex/ptex_read.c - reads a Ptex file (layout in ptex_format.h) into a texture set.
 *
 * Owns: parsing and validation of .ptx bytes, block decoding (constant, zipped, diff-zipped,
 * tiled), edits and metadata. Does not own: the set layout (set.c), the inner unpacking loops
 * (ptex_unpack.c), the Ptex rules for the levels a file does not store and the
 * table of on-demand reductions that Ptex's filter reads (ptexres.c: attached here, the table
 * built later by the first Ptex-filter call). Stored quad faces that are tiled with every tile
 * a constant tile of one value are listed for it (st_ptexres_set_ctiles: Ptex serves some
 * reductions of those as constant faces, which its tanvec mode does not turn).
 *
 * Triangle meshes (mesh type 0) are read the same way: square faces (checked), three edges
 * (the fourth adjacency entry and the subface flag are ignored, as Ptex does), blocks in Ptex's
 * packed triangle layout (core/trilevel.h); their unstored levels get the triangle reduction.
 *
 * One pass, no extra copies: the set is created with its arena unzeroed, every block of every
 * level is inflated once - a one-channel block straight into its place in the arena, any other
 * into one reused scratch that stays in the cache - and unpacked into the arena; the levels the
 * file does not store are then made from the level before each. Everything the import writes
 * is written once. By default (not the _eager readers) only level 0 is inflated in that pass:
 * the stored reductions are checked and listed, and inflated - with the unstored levels made -
 * by the first st_set_levels (pend_make below, through ptexres.c's levels hook).
 *
 * Hostile input: the whole file is in memory; every section is located with overflow-checked
 * arithmetic and must lie inside the buffer; every count is capped before it sizes an
 * allocation (ST_MAX_FACES, ST_MAX_DIM, 16 levels, and a zip stream cannot inflate to more
 * than PTX_MAX_ZIP_RATIO times its size, so a declared size larger than that is refused before
 * allocating); every zlib stream must inflate to exactly its declared size, with a valid zlib
 * header and Adler-32; every byte of the unzeroed arena is written before the set is returned
 * (a failure frees it unread) - or, for levels past 0 of a deferred import, before
 * st_set_levels first returns ST_OK (no reader reads them until then). Errors name the
 * section, face, level or byte offset.
 */
#include "ptex.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <libdeflate.h>

#include "ptex_format.h"
#include "ptex_inflate.h"
#include "ptex_unpack.h"
#include "ptexres.h"
#include "fileio.h"
#include "bigalloc.h"
#include "loadpath.h"

#define PTX_MAX_LEVELS 16u

/* Streams that inflate to at most this many bytes go through ptex_inflate.h (no heap, no
 * per-stream table of 2^11 entries), larger ones through libdeflate (faster per byte). */
#ifndef PTX_SMALL_INFLATE
#define PTX_SMALL_INFLATE 16384u
#endif
#ifndef PTX_SMALL_DYN
#define PTX_SMALL_DYN 4u
#endif
#ifndef PTX_SMALL_DYN_BYTES
#define PTX_SMALL_DYN_BYTES 2048u
#endif
#ifndef PTX_SMALL_LEVEL0
#define PTX_SMALL_LEVEL0 131072u /* zipped bytes of level 0 (or of the deferred levels) */
#endif

typedef struct rd {
    const uint8_t *buf;         /* the bytes from file offset `origin` on */
    size_t len;                 /* the file's length (import) or the copy's (deferred) */
    uint64_t origin;            /* file offset of buf[0]: 0, or the first stored reduction's
                                   level when making deferred levels from their copy */
    int dry;                    /* check every block but inflate and write nothing (the
                                   stored reductions of a deferred import) */
    size_t max_bytes;
    unsigned dt, nc;
    int tri;                    /* a triangle mesh: square faces, three edges */
    size_t csize, psize;        /* bytes per channel, per pixel */
    st_error *e;
    struct libdeflate_decompressor *dd; /* made on the first stream it inflates, reused */
    unsigned ndyn;              /* streams of a dynamic-code first block seen so far */
    int dyn_all;                /* level 0 is small: all its streams through ptex_inflate.h */
    uint8_t *scratch;           /* planar blocks of several channels inflate here (reused) */
    size_t scratch_cap;
    int ctiled;                 /* decode_face's last face: tiled, every tile a constant tile
                                   of one value (tiles of 2^ct_tu x 2^ct_tv texels) */
    uint8_t ct_tu, ct_tv;
} rd;

/* Puts a prefix (printf-formatted) before e's message, keeping rc. Off the import's path and
 * its stack: the copy of the message is on this frame, not on the reader's (a deeper stack
 * reached a fresh page in a fresh process). */
__attribute__((noinline, cold, format(printf, 3, 4)))
static void err_prefix(st_error *e, int rc, const char *fmt, ...)
{
    if (!e)
        return;
    char pre[ST_ERRMSG_LEN], tmp[ST_ERRMSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(pre, sizeof pre, fmt, ap);
    va_end(ap);
    snprintf(tmp, sizeof tmp, "%s", e->msg);
    st_fail(e, rc, "%s%s", pre, tmp);
}

/* The reader's scratch of at least n bytes: grown, never shrunk, freed at the end. A planar
 * block is at most a tile or a face (the Ptex writer tiles faces over 64 KiB), so it stays
 * in the cache between the inflate and the interleave. The first block needing it is
 * usually the largest (level 0 comes first); its size rounded up to 4 KiB (to 64 bytes under
 * 4 KiB), from util/bigalloc.c so that its pages are faulted in by one call. */
STU_LOADPATH
static uint8_t *scratch(rd *r, size_t n)
{
    if (n > r->scratch_cap) {
        /* a small block's scratch stays small (a whole fresh page for a 48-byte block was a
         * page fault of a small file's import) */
        size_t cap = n < 4096 ? (n + 63) & ~(size_t)63 : (n + 4095) & ~(size_t)4095;
        uint8_t *p = stu_big_alloc(cap, STU_BIG_TEMP);
        if (!p)
            return NULL;
        free(r->scratch);
        r->scratch = p;
        r->scratch_cap = cap;
    }
    return r->scratch;
}

/* [off, off+n) inside the buffer? (off is a file offset) */
static int in_file(const rd *r, uint64_t off, uint64_t n)
{
    return off >= r->origin && off - r->origin <= r->len && n <= r->len - (off - r->origin);
}

/* The byte at file offset off (inside the buffer). */
static const uint8_t *at(const rd *r, uint64_t off)
{
    return r->buf + (off - r->origin);
}

static int zip_bound_ok(uint64_t zipsize, uint64_t memsize)
{
    return memsize <= zipsize * PTX_MAX_ZIP_RATIO + 64;
}

/* Why a zlib stream at p (zlen bytes) that libdeflate refused as bad data is bad, for the
 * message: the deflate data itself, a missing check value, or a check value that does not
 * match. Runs only on the failure path (inflates again, raw). */
static const char *zlib_bad_reason(rd *r, const uint8_t *p, uint64_t zlen, void *out,
                                   size_t outlen)
{
    size_t used = 0, got = 0;
    if (libdeflate_deflate_decompress_ex(r->dd, p + 2, zlen - 2, out, outlen, &used,
                                         &got) != LIBDEFLATE_SUCCESS)
        return "invalid or truncated deflate data";
    if (zlen - 2 - used < 4)
        return "truncated: no check value";
    const uint8_t *t = p + 2 + used;
    uint32_t want = (uint32_t)t[0] << 24 | (uint32_t)t[1] << 16 | (uint32_t)t[2] << 8 | t[3];
    if (libdeflate_adler32(1, out, got) != want)
        return "incorrect data check";
    return "invalid or truncated deflate data";
}

/* Inflates exactly outlen bytes from the zlib stream at [off, off+zlen), in one call by
 * libdeflate straight into out (whole-buffer, no window copy; it checks the stream's Adler-32
 * with its own vectorised Adler-32). The 2-byte zlib header is checked here first, for a
 * clear message. Like zlib, refuses a bad header, a preset dictionary, malformed or truncated
 * deflate data, a missing or wrong check value, and a stream that inflates to more or fewer
 * bytes than declared. */
static int zip_check(rd *r, uint64_t off, uint64_t zlen, size_t outlen, const char *what);

STU_LOADPATH
static int inflate_exact(rd *r, uint64_t off, uint64_t zlen, void *out, size_t outlen,
                         const char *what)
{
    int rc = zip_check(r, off, zlen, outlen, what);
    if (rc)
        return rc;
    const uint8_t *p = at(r, off);
    /* ptex_inflate.h: small streams of stored and fixed-code blocks; dynamic-code ones of a
     * small file (dyn_all), else the first few small ones (in a large file libdeflate, faster
     * a byte on large dynamic streams, is used anyway and its first use is paid once) */
    if (outlen <= PTX_SMALL_INFLATE &&
        (zlen < 3 || ((p[2] >> 1) & 3) != 2 ||
         r->dyn_all || (outlen <= PTX_SMALL_DYN_BYTES && r->ndyn++ < PTX_SMALL_DYN))) {
        size_t got = 0;
        const char *why = "";
        int ir = st_ptx_inflate(p, zlen, out, outlen, &got, &why);
        if (ir == ST_PTX_INFL_OVER)
            return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu inflates to more "
                           "than the declared %zu bytes", what, (unsigned long long)off, outlen);
        if (ir != ST_PTX_INFL_OK)
            return st_fail(r->e, ST_EFORMAT, "%s: bad zlib stream at offset %llu (%s)", what,
                           (unsigned long long)off, why);
        if (got != outlen)
            return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu inflates to %zu "
                           "bytes, declared %zu", what, (unsigned long long)off, got, outlen);
        return ST_OK;
    }
    if (!r->dd && !(r->dd = libdeflate_alloc_decompressor()))
        return st_fail(r->e, ST_ENOMEM, "out of memory for the inflater");
    size_t got = 0;
    enum libdeflate_result lr = libdeflate_zlib_decompress(r->dd, p, zlen, out, outlen, &got);
    if (lr == LIBDEFLATE_INSUFFICIENT_SPACE)
        return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu inflates to more "
                       "than the declared %zu bytes", what, (unsigned long long)off, outlen);
    if (lr != LIBDEFLATE_SUCCESS)
        return st_fail(r->e, ST_EFORMAT, "%s: bad zlib stream at offset %llu (%s)", what,
                       (unsigned long long)off, zlib_bad_reason(r, p, zlen, out, outlen));
    if (got != outlen)
        return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu inflates to %zu bytes, "
                       "declared %zu", what, (unsigned long long)off, got, outlen);
    return ST_OK;
}

/* Everything inflate_exact checks before inflating: the block inside the file, the zip-ratio
 * bound, the size cap and the 2-byte zlib header (so that only the deflate data and its
 * Adler-32 are left for the inflate). */
STU_LOADPATH
static int zip_check(rd *r, uint64_t off, uint64_t zlen, size_t outlen, const char *what)
{
    if (!in_file(r, off, zlen))
        return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu (%llu bytes) overruns "
                       "the file (%zu bytes)", what, (unsigned long long)off,
                       (unsigned long long)zlen, r->len);
    if (!zip_bound_ok(zlen, outlen))
        return st_fail(r->e, ST_EFORMAT, "%s: %llu zipped bytes cannot inflate to the declared "
                       "%zu bytes", what, (unsigned long long)zlen, outlen);
    if (outlen > UINT32_MAX)
        return st_fail(r->e, ST_ETOOBIG, "%s: block of %zu bytes is too large", what, outlen);
    if (zlen < 2)
        return st_fail(r->e, ST_EFORMAT, "%s: zip block at offset %llu is truncated "
                       "(inflated 0 of %zu bytes)", what, (unsigned long long)off, outlen);
    const uint8_t *p = at(r, off);
    unsigned cmf = p[0], flg = p[1];
    if ((cmf & 15) != 8 || (cmf >> 4) > 7 || (cmf * 256 + flg) % 31)
        return st_fail(r->e, ST_EFORMAT, "%s: bad zlib stream at offset %llu (incorrect "
                       "header)", what, (unsigned long long)off);
    if (flg & 0x20)
        return st_fail(r->e, ST_EFORMAT, "%s: bad zlib stream at offset %llu (needs a preset "
                       "dictionary)", what, (unsigned long long)off);
    return ST_OK;
}

STU_LOADPATH
static void fill_rect(const rd *r, const uint8_t *px, uint32_t w, uint32_t h, uint8_t *dst,
                      size_t stride)
{
    for (uint32_t x = 0; x < w; x++)
        memcpy(dst + x * r->psize, px, r->psize);
    for (uint32_t y = 1; y < h; y++)
        memcpy(dst + y * stride, dst, (size_t)w * r->psize);
}

/* One non-tiled block of encoding enc at [off, off+size) holding a w x h rectangle, written
 * interleaved into dst (row stride bytes). A one-channel block that fills its rows is
 * inflated straight into dst (planar is interleaved then) and difference-decoded there; any
 * other block inflates into the reader's scratch and is interleaved from it in one pass. */
STU_LOADPATH
static int decode_block(rd *r, unsigned enc, uint64_t off, uint64_t size, uint32_t w, uint32_t h,
                        uint8_t *dst, size_t stride, const char *what)
{
    if (!in_file(r, off, size))
        return st_fail(r->e, ST_EFORMAT, "%s: block at offset %llu (%llu bytes) overruns the "
                       "file", what, (unsigned long long)off, (unsigned long long)size);
    if (enc == PTX_ENC_CONSTANT) {
        if (size < r->psize)
            return st_fail(r->e, ST_EFORMAT, "%s: constant block of %llu bytes, a pixel is %zu",
                           what, (unsigned long long)size, r->psize);
        if (!r->dry)
            fill_rect(r, at(r, off), w, h, dst, stride);
        return ST_OK;
    }
    if (enc == PTX_ENC_DIFFZIPPED && r->dt != ST_DT_U8 && r->dt != ST_DT_U16)
        return st_fail(r->e, ST_EFORMAT, "%s: diff-zipped block for a float data type", what);
    size_t bytes = (size_t)w * h * r->psize;
    if (!zip_bound_ok(size, bytes))
        return st_fail(r->e, ST_EFORMAT, "%s: %llu zipped bytes cannot inflate to %zu", what,
                       (unsigned long long)size, bytes);
    int diff = enc == PTX_ENC_DIFFZIPPED, rc;
    if (r->dry)
        return zip_check(r, off, size, bytes, what);
    if (r->nc == 1 && stride == (size_t)w * r->psize) {
        if ((rc = inflate_exact(r, off, size, dst, bytes, what)) == ST_OK && diff)
            st_ptx_undiff(r->csize, dst, bytes);
        return rc;
    }
    uint8_t *tmp = scratch(r, bytes);
    if (!tmp)
        return st_fail(r->e, ST_ENOMEM, "%s: out of memory for %zu bytes", what, bytes);
    if ((rc = inflate_exact(r, off, size, tmp, bytes, what)) == ST_OK) {
        if (diff)
            st_ptx_undiff(r->csize, tmp, bytes); /* one run over all planes */
        st_ptx_planar_to_rows(r->csize, r->nc, tmp, w, h, dst, stride);
    }
    return rc;
}

/* Face data header at [off, off+size) for a face of resolution (ulog2, vlog2); may be tiled. */
STU_LOADPATH
static int decode_face(rd *r, uint32_t fdh, uint64_t off, uint64_t end, unsigned ulog2,
                       unsigned vlog2, uint8_t *dst, const char *what)
{
    unsigned enc = fdh >> 30;
    uint64_t size = fdh & 0x3fffffffu;
    uint32_t w = 1u << ulog2, h = 1u << vlog2;
    size_t stride = (size_t)w * r->psize;
    if (off > end || size > end - off)
        return st_fail(r->e, ST_EFORMAT, "%s: block at offset %llu (%llu bytes) overruns its "
                       "level (ends at %llu)", what, (unsigned long long)off,
                       (unsigned long long)size, (unsigned long long)end);
    r->ctiled = 0;
    if (enc != PTX_ENC_TILED)
        return decode_block(r, enc, off, size, w, h, dst, stride, what);
    if (size < 6 || !in_file(r, off, size))
        return st_fail(r->e, ST_EFORMAT, "%s: tiled block at offset %llu is too short", what,
                       (unsigned long long)off);
    int tu = (int8_t)*at(r, off), tv = (int8_t)*at(r, off + 1);
    uint32_t thsize = ptx_rd32(at(r, off + 2));
    if (tu < 0 || tv < 0 || (unsigned)tu > ulog2 || (unsigned)tv > vlog2)
        return st_fail(r->e, ST_EFORMAT, "%s: tile resolution %dx%d (log2) does not fit the face "
                       "%ux%u (log2)", what, tu, tv, ulog2, vlog2);
    uint32_t ntu = 1u << (ulog2 - (unsigned)tu), ntv = 1u << (vlog2 - (unsigned)tv);
    size_t ntiles = (size_t)ntu * ntv;
    if (thsize > size - 6)
        return st_fail(r->e, ST_EFORMAT, "%s: tile header of %u bytes overruns the block", what,
                       thsize);
    if (!zip_bound_ok(thsize, ntiles * 4))
        return st_fail(r->e, ST_EFORMAT, "%s: %u zipped bytes cannot hold %zu tile headers",
                       what, thsize, ntiles);
    uint8_t *th = malloc(ntiles * 4);
    if (!th)
        return st_fail(r->e, ST_ENOMEM, "%s: out of memory for %zu tile headers", what, ntiles);
    int rc = inflate_exact(r, off + 6, thsize, th, ntiles * 4, what);
    uint64_t pos = off + 6 + thsize, bend = off + size;
    uint32_t tw = 1u << tu, tht = 1u << tv;
    int ctiled = 1; /* every tile constant, of tile 0's value (Ptex serves reductions of such
                     * a face that fit in a tile as a constant face) */
    uint64_t c0 = pos;
    for (size_t i = 0; rc == ST_OK && i < ntiles; i++) {
        uint32_t tf = ptx_rd32(th + 4 * i);
        unsigned tenc = tf >> 30;
        uint64_t tsize = tf & 0x3fffffffu;
        if (tenc == PTX_ENC_TILED) {
            rc = st_fail(r->e, ST_EFORMAT, "%s: tile %zu is itself tiled", what, i);
            break;
        }
        if (tsize > bend - pos) {
            rc = st_fail(r->e, ST_EFORMAT, "%s: tile %zu (%llu bytes at offset %llu) overruns "
                         "the tiled block", what, i, (unsigned long long)tsize,
                         (unsigned long long)pos);
            break;
        }
        size_t tx = i % ntu, ty = i / ntu;
        uint8_t *d = r->dry ? dst : dst + ty * tht * stride + tx * tw * r->psize;
        rc = decode_block(r, tenc, pos, tsize, tw, tht, d, stride, what);
        if (rc == ST_OK && ctiled)
            ctiled = tenc == PTX_ENC_CONSTANT &&
                     (i == 0 ? (c0 = pos, 1) : !memcmp(at(r, pos), at(r, c0), r->psize));
        pos += tsize;
    }
    free(th);
    if (rc == ST_OK && ctiled) {
        r->ctiled = 1;
        r->ct_tu = (uint8_t)tu;
        r->ct_tv = (uint8_t)tv;
    }
    return rc;
}

/* Reads a level header: nf FaceDataHeaders (inflated into tmp, nf * 4 bytes) and the offsets
 * of their blocks. Messages name "level L header", formatted only on failure (the first
 * snprintf of a process faults in a few pages of libc's printf code). */
STU_LOADPATH
static int read_level_header(rd *r, uint64_t pos, uint64_t lsize, uint32_t hsize, uint32_t nf,
                             uint8_t *tmp, uint32_t *fdh, uint64_t *offs, unsigned level)
{
    if (hsize > lsize)
        return st_fail(r->e, ST_EFORMAT, "level %u header: %u bytes, larger than the level "
                       "(%llu)", level, hsize, (unsigned long long)lsize);
    if (!zip_bound_ok(hsize, (uint64_t)nf * 4))
        return st_fail(r->e, ST_EFORMAT, "level %u header: %u zipped bytes cannot hold %u face "
                       "headers", level, hsize, nf);
    int rc = inflate_exact(r, pos, hsize, tmp, (size_t)nf * 4, "");
    if (rc)
        err_prefix(r->e, rc, "level %u header", level);
    if (rc == ST_OK) {
        uint64_t o = pos + hsize, end = pos + lsize;
        for (uint32_t i = 0; i < nf; i++) {
            fdh[i] = ptx_rd32(tmp + 4 * i);
            offs[i] = o;
            o += fdh[i] & 0x3fffffffu;
            if (o > end) {
                rc = st_fail(r->e, ST_EFORMAT, "level %u: the blocks of its first %u faces "
                             "(%llu bytes) overrun the level (%llu bytes)", level, i + 1,
                             (unsigned long long)(o - pos), (unsigned long long)lsize);
                break;
            }
        }
    }
    return rc;
}

/* ---- deferred stored reductions ----------------------------------------------------------
 * A deferred import (the default) checks the stored reductions' blocks as it reads them (every
 * check of decode_face but the inflate: r->dry) and keeps what making them later needs: the
 * zipped blocks, where each (face, level) block lies, and the constant data. The blocks are
 * the file buffer itself when the reader owns it (st_ptex_read_file: it is kept instead of
 * freed, no copy and no fresh page to fault in), else a copy of the level data from level 1 on
 * (its level headers included: one memcpy). ptexres.c's levels hook calls pend_make once, on
 * the first st_set_levels. */
typedef struct pend_blk {
    uint32_t face;
    uint32_t fdh;               /* its FaceDataHeader */
    uint64_t off;               /* file offset of its block */
} pend_blk;

typedef struct pend {
    uint8_t *zip;               /* the file's bytes [origin, origin + zlen) */
    uint64_t origin;
    size_t zlen;
    size_t zbytes;              /* what zip holds in memory (a file buffer: its footprint) */
    size_t max_bytes;
    unsigned dt, nc, tri;
    pend_blk *blk;              /* in file order: level by level, rfaceid order inside */
    size_t nblk, cap;
    uint32_t first[PTX_MAX_LEVELS + 1]; /* blk[first[l], first[l+1]) are level l's (l >= 1) */
    uint64_t lend[PTX_MAX_LEVELS];      /* file offset where level l ends */
    unsigned nlevels;
    int dyn_all;                /* the stored reductions are small: all through ptex_inflate.h */
    uint8_t *constdata;         /* nfaces texels */
} pend;

STU_LOADPATH
static void pend_free(void *p)
{
    pend *d = p;
    if (!d)
        return;
    free(d->zip);
    free(d->blk);
    free(d->constdata);
    free(d);
}

STU_LOADPATH
static int pend_push(pend *d, uint32_t f, uint32_t fdh, uint64_t off)
{
    if (d->nblk == d->cap) {
        size_t nc = d->cap ? 2 * d->cap : 16; /* from 256 B: a small file's few blocks fit in
                                                 the heap page already in use */
        pend_blk *nb = realloc(d->blk, nc * sizeof *nb);
        if (!nb)
            return -1;
        d->blk = nb;
        d->cap = nc;
    }
    d->blk[d->nblk++] = (pend_blk){f, fdh, off};
    return 0;
}

/* The deferred levels' make (st_ptexres_deferred): inflates every kept block into its level,
 * with the import's own decoding and messages ("level L face F: ..." and the file offset). */
static int pend_make(st_set *s, void *p, st_error *e)
{
    pend *d = p;
    rd R = {.buf = d->zip, .len = d->zlen, .origin = d->origin, .max_bytes = d->max_bytes,
            .dt = d->dt, .nc = d->nc, .tri = (int)d->tri, .e = e, .dyn_all = d->dyn_all};
    rd *r = &R;
    r->csize = st_dtype_size(d->dt);
    r->psize = r->csize * d->nc;
    int rc = ST_OK;
    for (unsigned l = 1; rc == ST_OK && l < d->nlevels; l++)
        for (size_t i = d->first[l]; i < d->first[l + 1]; i++) {
            const pend_blk *k = &d->blk[i];
            const st_face *F = &s->faces[k->face];
            if ((rc = decode_face(r, k->fdh, k->off, d->lend[l], F->ulog2 - l, F->vlog2 - l,
                                  st_face_level(s, k->face, l), ""))) {
                err_prefix(e, rc, "level %u face %u", l, k->face);
                break;
            }
        }
    if (r->dd) /* none when every stream went through ptex_inflate.h: no call into libdeflate */
        libdeflate_free_decompressor(r->dd);
    free(r->scratch);
    return rc;
}

/* st_ptexres_ctile order: by face, then level */
static int ctile_cmp(const void *a, const void *b)
{
    const st_ptexres_ctile *x = a, *y = b;
    if (x->face != y->face)
        return x->face < y->face ? -1 : 1;
    return (x->level > y->level) - (x->level < y->level);
}

/* Parses metadata records (small or large-header form) from mem. */
typedef struct meta_ctx {
    st_set *s;
    uint64_t lmd_pos, lmd_end;   /* large metadata blocks */
} meta_ctx;

static size_t meta_tsize(unsigned t)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return t < 6 ? sz[t] : 0;
}

STU_LOADPATH
static int meta_put(rd *r, st_set *s, const char *key, unsigned type, const uint8_t *data,
                    uint32_t dsize)
{
    size_t ts = meta_tsize(type);
    if (!ts)
        return st_fail(r->e, ST_EFORMAT, "metadata '%s': type %u unknown", key, type);
    if (dsize % ts)
        return st_fail(r->e, ST_EFORMAT, "metadata '%s': %u bytes is not a whole number of "
                       "%zu-byte values", key, dsize, ts);
    uint8_t *copy = NULL;
    if (type == 0 && (dsize == 0 || data[dsize - 1] != 0)) {
        /* a string without its NUL: keep it, terminated */
        copy = malloc((size_t)dsize + 1);
        if (!copy)
            return st_fail(r->e, ST_ENOMEM, "out of memory for metadata");
        if (dsize)
            memcpy(copy, data, dsize);
        copy[dsize] = 0;
        data = copy;
        dsize++;
    }
    /* a later record with the same key (metadata edits) replaces the earlier one */
    for (uint32_t i = 0; i < s->nmeta; i++)
        if (!strcmp(s->meta[i].key, key)) {
            void *nd = malloc(dsize ? dsize : 1);
            if (!nd) {
                free(copy);
                return st_fail(r->e, ST_ENOMEM, "out of memory for metadata");
            }
            if (dsize)
                memcpy(nd, data, dsize);
            free(s->meta[i].data);
            s->meta[i].data = nd;
            s->meta[i].type = (uint8_t)type;
            s->meta[i].count = (uint32_t)(dsize / ts);
            free(copy);
            return ST_OK;
        }
    int rc = st_set_meta_add(s, key, type, data, (uint32_t)(dsize / ts), r->e);
    free(copy);
    return rc;
}

STU_LOADPATH
static int parse_meta(rd *r, meta_ctx *m, const uint8_t *p, size_t n, int large)
{
    size_t i = 0;
    while (i < n) {
        unsigned ks = p[i++];
        if (ks == 0 || ks > n - i)
            return st_fail(r->e, ST_EFORMAT, "metadata: key of %u bytes overruns the block", ks);
        char key[256];
        memcpy(key, p + i, ks);
        key[ks - 1] = 0;
        i += ks;
        size_t need = 1 + 4 + (large ? 4 : 0);
        if (need > n - i)
            return st_fail(r->e, ST_EFORMAT, "metadata '%s': record truncated", key);
        unsigned type = p[i];
        uint32_t dsize = ptx_rd32(p + i + 1);
        i += 5;
        if (!large) {
            if (dsize > n - i)
                return st_fail(r->e, ST_EFORMAT, "metadata '%s': %u bytes of data overrun the "
                               "block", key, dsize);
            int rc = meta_put(r, m->s, key, type, p + i, dsize);
            if (rc)
                return rc;
            i += dsize;
        } else {
            uint32_t zs = ptx_rd32(p + i);
            i += 4;
            if (zs > m->lmd_end - m->lmd_pos)
                return st_fail(r->e, ST_EFORMAT, "large metadata '%s': %u zipped bytes overrun "
                               "the large metadata section", key, zs);
            if (!zip_bound_ok(zs, dsize) || dsize > (1u << 30))
                return st_fail(r->e, ST_EFORMAT, "large metadata '%s': %u zipped bytes cannot "
                               "hold %u bytes", key, zs, dsize);
            uint8_t *d = malloc(dsize ? dsize : 1);
            if (!d)
                return st_fail(r->e, ST_ENOMEM, "out of memory for metadata '%s'", key);
            int rc = inflate_exact(r, m->lmd_pos, zs, d, dsize, "large metadata");
            if (rc == ST_OK)
                rc = meta_put(r, m->s, key, type, d, dsize);
            free(d);
            if (rc)
                return rc;
            m->lmd_pos += zs;
        }
    }
    return ST_OK;
}

STU_LOADPATH
static int read_meta_block(rd *r, meta_ctx *m, uint64_t pos, uint32_t zs, uint32_t ms, int large)
{
    if (!ms)
        return ST_OK;
    if (!in_file(r, pos, zs) || !zip_bound_ok(zs, ms))
        return st_fail(r->e, ST_EFORMAT, "%s: %u zipped bytes at offset %llu cannot hold %u "
                       "bytes inside the file", large ? "large metadata header" : "metadata", zs,
                       (unsigned long long)pos, ms);
    uint8_t *tmp = malloc(ms);
    if (!tmp)
        return st_fail(r->e, ST_ENOMEM, "out of memory for metadata");
    int rc = inflate_exact(r, pos, zs, tmp, ms, large ? "large metadata header" : "metadata");
    if (rc == ST_OK)
        rc = parse_meta(r, m, tmp, ms, large);
    free(tmp);
    return rc;
}

typedef struct face_edit {
    uint32_t faceid;
    uint32_t fdh;
    uint64_t pos;
} face_edit;

typedef struct meta_edit {
    uint64_t pos;
    uint32_t zs, ms;
} meta_edit;

STU_LOADPATH
static int check_faceinfo(rd *r, const ptx_faceinfo *fi, uint32_t f, uint32_t nfaces)
{
    if (fi->ulog2 < 0 || fi->vlog2 < 0 || fi->ulog2 > (int)ST_MAX_LOG2 || fi->vlog2 > (int)ST_MAX_LOG2)
        return st_fail(r->e, ST_EFORMAT, "face %u: resolution 2^%d x 2^%d not in 1..%u", f,
                       fi->ulog2, fi->vlog2, ST_MAX_DIM);
    if (r->tri && fi->ulog2 != fi->vlog2)
        return st_fail(r->e, ST_EFORMAT, "triangle face %u: resolution 2^%d x 2^%d (a triangle "
                       "face is square)", f, fi->ulog2, fi->vlog2);
    for (int ed = 0; ed < (r->tri ? 3 : 4); ed++) /* a triangle's fourth entry is unused */
        if (fi->adjfaces[ed] < -1 || (fi->adjfaces[ed] >= 0 && (uint32_t)fi->adjfaces[ed] >= nfaces))
            return st_fail(r->e, ST_EADJ, "face %u edge %d: neighbour %d out of range (%u faces)",
                           f, ed, fi->adjfaces[ed], nfaces);
    return ST_OK;
}

/* own: the caller's pointer to buf when the reader may keep buf (a buffer from
 * util/bigalloc.c, freed with free()): a deferred import with stored reductions takes it and
 * sets *own to NULL. */
STU_LOADPATH
static int read_mem(const void *buf, size_t len, size_t max_bytes, int eager, void **own,
                    st_set **out, st_error *e)
{
    *out = NULL;
    if (!max_bytes)
        max_bytes = ST_DEFAULT_MAX_BYTES;
    rd R = {.buf = buf, .len = len, .max_bytes = max_bytes, .e = e};
    rd *r = &R;
    const uint8_t *b = buf;
    int rc = ST_OK;
    st_set *s = NULL;
    ptx_faceinfo *fi = NULL;
    uint8_t *constdata = NULL, *ptxflags = NULL, *nstored = NULL;
    st_ptexres_ctile *ct = NULL; /* stored faces whose tiles are all one constant (quads) */
    size_t nct = 0, ctcap = 0;
    uint32_t *fdh = NULL;
    uint64_t *offs = NULL;
    uint32_t *faceids_r = NULL;
    face_edit *fedits = NULL;
    meta_edit *medits = NULL;
    size_t nfedits = 0, nmedits = 0;
    st_face_desc *fd = NULL;
    uint8_t *work = NULL, *lhtmp = NULL; /* the per-face tables' block; level headers' inflate */
    pend *pd = NULL;                     /* a deferred import's kept blocks */

    if (len < PTX_HEADER_SIZE)
        return st_fail(e, ST_EFORMAT, "file of %zu bytes is shorter than the Ptex header (64)", len);
    if (ptx_rd32(b) != PTX_MAGIC)
        return st_fail(e, ST_EFORMAT, "not a Ptex file (magic is not \"Ptex\")");
    uint32_t version = ptx_rd32(b + 4);
    if (version != 1)
        return st_fail(e, ST_EUNSUPPORTED, "Ptex file version %u (only version 1 exists)", version);
    uint32_t meshtype = ptx_rd32(b + 8), dtype = ptx_rd32(b + 12);
    int32_t alpha = (int32_t)ptx_rd32(b + 16);
    uint32_t nchan = ptx_rd16(b + 20), nlevels = ptx_rd16(b + 22), nfaces = ptx_rd32(b + 24);
    uint32_t exthsize = ptx_rd32(b + 28), fisize = ptx_rd32(b + 32), cdsize = ptx_rd32(b + 36);
    uint32_t lisize = ptx_rd32(b + 40);
    uint64_t ldsize = ptx_rd64(b + 48);
    uint32_t mdzip = ptx_rd32(b + 56), mdmem = ptx_rd32(b + 60);
    if (meshtype > 1)
        return st_fail(e, ST_EFORMAT, "mesh type %u is neither triangle (0) nor quad (1)", meshtype);
    if (dtype > 3)
        return st_fail(e, ST_EFORMAT, "data type %u not in 0..3", dtype);
    if (nchan < 1)
        return st_fail(e, ST_EFORMAT, "channel count is 0");
    if (nchan > ST_MAX_CHANNELS)
        return st_fail(e, ST_EUNSUPPORTED, "%u channels; a set holds at most %u", nchan,
                       ST_MAX_CHANNELS);
    if (nfaces < 1 || nfaces > ST_MAX_FACES)
        return st_fail(e, ST_ETOOBIG, "face count %u not in 1..%u", nfaces, ST_MAX_FACES);
    if (nlevels < 1 || nlevels > PTX_MAX_LEVELS)
        return st_fail(e, ST_EFORMAT, "level count %u not in 1..%u", nlevels, PTX_MAX_LEVELS);
    if (lisize < nlevels * PTX_LEVELINFO_SIZE)
        return st_fail(e, ST_EFORMAT, "level info of %u bytes is too small for %u levels",
                       lisize, nlevels);
    r->tri = meshtype == PTX_MESH_TRIANGLE;
    r->dt = dtype;
    r->nc = nchan;
    r->csize = st_dtype_size(dtype);
    r->psize = r->csize * nchan;

    /* extended header: missing fields are 0 */
    uint8_t ext[PTX_EXTHEADER_SIZE] = {0};
    if (!in_file(r, PTX_HEADER_SIZE, exthsize))
        return st_fail(e, ST_EFORMAT, "extended header of %u bytes overruns the file", exthsize);
    memcpy(ext, b + PTX_HEADER_SIZE, exthsize < PTX_EXTHEADER_SIZE ? exthsize : PTX_EXTHEADER_SIZE);
    unsigned bu = ptx_rd16(ext), bv = ptx_rd16(ext + 4);
    /* edge filter mode: Ptex's filters test for tanvec (1) only, any other value is none */
    unsigned efm = ptx_rd16(ext + 6) == 1 ? ST_EDGEFILTER_TANVEC : ST_EDGEFILTER_NONE;
    uint32_t lmdzip = ptx_rd32(ext + 8), lmdmem = ptx_rd32(ext + 12);
    uint64_t lmddata = ptx_rd64(ext + 16), editsize = ptx_rd64(ext + 24), editpos = ptx_rd64(ext + 32);
    if (bu > 2 || bv > 2)
        return st_fail(e, ST_EFORMAT, "border modes %u/%u not in 0..2", bu, bv);

    /* section offsets; everything must lie inside the file */
    uint64_t pos = PTX_HEADER_SIZE + (uint64_t)exthsize;
    uint64_t fipos = pos;    pos += fisize;
    uint64_t cdpos = pos;    pos += cdsize;
    uint64_t lipos = pos;    pos += lisize;
    uint64_t ldpos = pos;
    if (ldsize > len || pos > len - ldsize)
        return st_fail(e, ST_EFORMAT, "sections up to the level data (%llu + %llu bytes) overrun "
                       "the file (%zu bytes)", (unsigned long long)pos, (unsigned long long)ldsize, len);
    pos += ldsize;
    uint64_t mdpos = pos;    pos += mdzip;
    pos += 8;                /* compatibility barrier */
    uint64_t lmdhpos = pos;  pos += lmdzip;
    uint64_t lmdpos = pos;
    if (lmdmem && (pos > len || lmddata > len - pos))
        return st_fail(e, ST_EFORMAT, "large metadata (%llu bytes at offset %llu) overruns the "
                       "file", (unsigned long long)lmddata, (unsigned long long)pos);
    if (lmddata > len)
        lmddata = len; /* unused when lmdmem is 0; keeps the sums below from wrapping */
    pos += lmddata;

    /* a small level 0: every stream of the file through ptex_inflate.h, dynamic ones too,
     * from the face info on (on small streams it is the faster of the two since session 30,
     * and libdeflate's first use in a process - its code, its decompressor - costs 100-200
     * us); the level info lies inside the file (it ends where the level data starts) */
    r->dyn_all = ptx_rd64(b + lipos) <= PTX_SMALL_LEVEL0;

    /* face info */
    size_t fibytes = (size_t)nfaces * PTX_FACEINFO_SIZE;
    if (!zip_bound_ok(fisize, fibytes))
        return st_fail(e, ST_EFORMAT, "face info: %u zipped bytes cannot hold %u faces", fisize,
                       nfaces);
    uint8_t *fiz = malloc(fibytes);
    if (!fiz)
        return st_fail(e, ST_ENOMEM, "out of memory for %u faces", nfaces);
    rc = inflate_exact(r, fipos, fisize, fiz, fibytes, "face info");
    /* The import's per-face tables, in one block allocated once the face count is backed by
     * a face info that inflated to it: from 16 KiB on util/bigalloc.c faults its pages in by
     * one call (a fresh 4 KiB page first written from user space costs 10-25 us on the
     * project's VM; these tables are 100 bytes a face). */
    size_t nfc = nfaces, cdbytes = nfc * r->psize;
    size_t o_fi = nfc * sizeof *offs, o_fd = o_fi + nfc * sizeof *fi;
    size_t o_fdh = o_fd + nfc * sizeof *fd, o_ids = o_fdh + nfc * sizeof *fdh;
    size_t o_lh = o_ids + nfc * sizeof *faceids_r, o_cd = o_lh + nfc * 4;
    size_t o_flags = o_cd + cdbytes, o_nstored = o_flags + nfc, worksize = o_nstored + nfc;
    /* a constant data that cannot inflate to its size is refused right after the face
     * checks: its block is then left to malloc, not populated */
    int cd_ok = zip_bound_ok(cdsize, cdbytes);
    if (rc == ST_OK &&
        !(work = cd_ok ? stu_big_alloc(worksize, STU_BIG_TEMP) : malloc(worksize)))
        rc = st_fail(e, ST_ENOMEM, "out of memory for %u faces", nfaces);
    if (rc) {
        free(fiz);
        goto done;
    }
    offs = (uint64_t *)(void *)work;
    fi = (ptx_faceinfo *)(void *)(work + o_fi);
    fd = (st_face_desc *)(void *)(work + o_fd);
    fdh = (uint32_t *)(void *)(work + o_fdh);
    faceids_r = (uint32_t *)(void *)(work + o_ids);
    lhtmp = work + o_lh;
    constdata = work + o_cd;
    ptxflags = work + o_flags;
    nstored = work + o_nstored;
    for (uint32_t f = 0; rc == ST_OK && f < nfaces; f++) {
        ptx_faceinfo_decode(fiz + (size_t)f * PTX_FACEINFO_SIZE, &fi[f]);
        rc = check_faceinfo(r, &fi[f], f, nfaces);
    }
    free(fiz);
    if (rc)
        goto done;

    /* constant data */
    if (!cd_ok) {
        rc = st_fail(e, ST_EFORMAT, "constant data: %u zipped bytes cannot hold %zu", cdsize,
                     cdbytes);
        goto done;
    }
    if ((rc = inflate_exact(r, cdpos, cdsize, constdata, cdbytes, "constant data")))
        goto done;

    {
        /* rfaceid order: stable sort by min(ulog2, vlog2) descending, constant faces count 1
         * (counting sort keeps it stable). Made from the face info as stored, before the
         * edit records below replace it: the stored reductions are in that order (Ptex's
         * reader makes its rfaceids in readFaceInfo, before readEditData), so a face edit
         * that changes a face's size or makes it constant must not move the other faces'
         * reductions. */
        uint32_t cnt[ST_MAX_LOG2 + 2] = {0};
        for (uint32_t f = 0; f < nfaces; f++) {
            unsigned m = fi[f].flags & PTX_FLAG_CONSTANT ? 1u :
                         (unsigned)(fi[f].ulog2 < fi[f].vlog2 ? fi[f].ulog2 : fi[f].vlog2);
            cnt[m]++;
        }
        uint32_t start[ST_MAX_LOG2 + 2], acc = 0;
        for (int m = ST_MAX_LOG2 + 1; m >= 0; m--) {
            start[m] = acc;
            acc += cnt[m];
        }
        for (uint32_t f = 0; f < nfaces; f++) {
            unsigned m = fi[f].flags & PTX_FLAG_CONSTANT ? 1u :
                         (unsigned)(fi[f].ulog2 < fi[f].vlog2 ? fi[f].ulog2 : fi[f].vlog2);
            faceids_r[start[m]++] = f;
        }
    }
    /* edit records */
    {
        uint64_t ep = editpos > pos ? editpos : pos, eend;
        if (editpos > 0)
            eend = editpos + editsize < editpos ? UINT64_MAX : editpos + editsize;
        else
            eend = UINT64_MAX;
        if (eend > len)
            eend = len;
        while (ep < eend && eend - ep >= 5) {
            unsigned et = b[ep];
            uint32_t esz = ptx_rd32(b + ep + 1);
            if (!esz)
                break;
            uint64_t body = ep + 5;
            if (esz > len - body) {
                rc = st_fail(e, ST_EFORMAT, "edit record at offset %llu (%u bytes) overruns the "
                             "file", (unsigned long long)ep, esz);
                goto done;
            }
            if (et == PTX_EDIT_FACEDATA) {
                if (esz < PTX_EDIT_FACE_SIZE + r->psize) {
                    rc = st_fail(e, ST_EFORMAT, "face edit at offset %llu is too short",
                                 (unsigned long long)ep);
                    goto done;
                }
                uint32_t faceid = ptx_rd32(b + body);
                if (faceid >= nfaces) {
                    rc = st_fail(e, ST_EFORMAT, "face edit at offset %llu names face %u of %u",
                                 (unsigned long long)ep, faceid, nfaces);
                    goto done;
                }
                ptx_faceinfo nfi;
                ptx_faceinfo_decode(b + body + 4, &nfi);
                if ((rc = check_faceinfo(r, &nfi, faceid, nfaces)))
                    goto done;
                nfi.flags |= PTX_FLAG_HASEDITS;
                fi[faceid] = nfi;
                memcpy(constdata + (size_t)faceid * r->psize, b + body + PTX_EDIT_FACE_SIZE, r->psize);
                if (!(nfi.flags & PTX_FLAG_CONSTANT)) {
                    face_edit *ne = realloc(fedits, (nfedits + 1) * sizeof *ne);
                    if (!ne) {
                        rc = st_fail(e, ST_ENOMEM, "out of memory for edits");
                        goto done;
                    }
                    fedits = ne;
                    fedits[nfedits].faceid = faceid;
                    fedits[nfedits].fdh = ptx_rd32(b + body + 24);
                    fedits[nfedits].pos = body + PTX_EDIT_FACE_SIZE + r->psize;
                    if ((fedits[nfedits].fdh & 0x3fffffffu) > esz - PTX_EDIT_FACE_SIZE - r->psize) {
                        rc = st_fail(e, ST_EFORMAT, "face edit at offset %llu: block overruns "
                                     "the record", (unsigned long long)ep);
                        goto done;
                    }
                    nfedits++;
                }
            } else if (et == PTX_EDIT_METADATA) {
                if (esz < PTX_EDIT_META_SIZE) {
                    rc = st_fail(e, ST_EFORMAT, "metadata edit at offset %llu is too short",
                                 (unsigned long long)ep);
                    goto done;
                }
                meta_edit *nm = realloc(medits, (nmedits + 1) * sizeof *nm);
                if (!nm) {
                    rc = st_fail(e, ST_ENOMEM, "out of memory for edits");
                    goto done;
                }
                medits = nm;
                medits[nmedits].zs = ptx_rd32(b + body);
                medits[nmedits].ms = ptx_rd32(b + body + 4);
                medits[nmedits].pos = body + 8;
                if (medits[nmedits].zs > esz - 8) {
                    rc = st_fail(e, ST_EFORMAT, "metadata edit at offset %llu overruns its record",
                                 (unsigned long long)ep);
                    goto done;
                }
                nmedits++;
            } /* unknown record types are skipped, as Ptex does */
            ep = body + esz;
        }
    }

    /* the set (every field of fd[f] is set here) */
    for (uint32_t f = 0; f < nfaces; f++) {
        fd[f].w = 1u << fi[f].ulog2;
        fd[f].h = 1u << fi[f].vlog2;
        fd[f].flags = (uint8_t)((fi[f].flags & PTX_FLAG_CONSTANT ? ST_FACE_CONSTANT : 0) |
                                (fi[f].flags & PTX_FLAG_SUBFACE && !r->tri ? ST_FACE_SUBFACE : 0));
        for (int ed = 0; ed < 4; ed++) {
            fd[f].adjface[ed] = fi[f].adjfaces[ed];
            fd[f].adjedge[ed] = (int8_t)((fi[f].adjedges >> (2 * ed)) & 3);
        }
        if (r->tri) { /* Ptex ignores a triangle's fourth edge and subface flag */
            fd[f].adjface[3] = -1;
            fd[f].adjedge[3] = 0;
            fi[f].flags &= (uint8_t)~PTX_FLAG_SUBFACE;
        }
        ptxflags[f] = fi[f].flags;
        nstored[f] = 1;
    }
    st_set_info info = {
        .nfaces = nfaces, .nchan = (uint8_t)nchan, .dtype = (uint8_t)dtype,
        .alpha_chan = (int8_t)(alpha >= 0 && alpha < (int32_t)nchan ? alpha : -1),
        .kind = ST_KIND_PERFACE, .colorspace = ST_CS_LINEAR, .premultiplied = 0,
        .border_u = (uint8_t)bu, .border_v = (uint8_t)bv,
        .meshtype = (uint8_t)(r->tri ? ST_MESH_TRIANGLE : ST_MESH_QUAD),
        .edgefilter = (uint8_t)efm,
    };
    /* every byte of every level is written below: constant and 1x1 faces from the constant
     * data, level 0 of the others and their stored reductions decoded (a block must fill its
     * face exactly, tiles cover it), every other level made by st_ptexres_attach; any
     * failure frees the set unread */
    if ((rc = st_set_create_unzeroed(&info, fd, max_bytes, &s, e)))
        goto done;

    /* constant faces and 1x1 faces: the constant data */
    for (uint32_t f = 0; f < nfaces; f++)
        if ((s->faces[f].flags & ST_FACE_CONSTANT) || (fi[f].ulog2 == 0 && fi[f].vlog2 == 0))
            memcpy(st_face_level(s, f, 0), constdata + (size_t)f * r->psize, r->psize);

    if (!eager && !(pd = calloc(1, sizeof *pd))) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for the stored reductions");
        goto done;
    }
    uint64_t lpos = ldpos, lend_all = ldpos + ldsize;
    for (unsigned l = 0; l < nlevels; l++) {
        if (pd && l > 0) {
            pd->first[l] = (uint32_t)pd->nblk;
            if (l == 1)
                pd->origin = lpos;
        }
        r->dry = pd && l > 0; /* a deferred import checks the stored reductions only */
        const uint8_t *li = b + lipos + (size_t)l * PTX_LEVELINFO_SIZE;
        uint64_t lsize = ptx_rd64(li);
        uint32_t hsize = ptx_rd32(li + 8), nf = ptx_rd32(li + 12);
        if (lsize > lend_all - lpos) {
            rc = st_fail(e, ST_EFORMAT, "level %u: %llu bytes overrun the level data", l,
                         (unsigned long long)lsize);
            goto done;
        }
        if (nf > nfaces || (l == 0 && nf != nfaces)) {
            rc = st_fail(e, ST_EFORMAT, "level %u holds %u faces of %u", l, nf, nfaces);
            goto done;
        }
        if ((rc = read_level_header(r, lpos, lsize, hsize, nf, lhtmp, fdh, offs, l)))
            goto done;
        if (l == 0)
            for (size_t i = 0; i < nfedits; i++) {
                fdh[fedits[i].faceid] = fedits[i].fdh;
                offs[fedits[i].faceid] = fedits[i].pos;
            }
        for (uint32_t i = 0; i < nf; i++) {
            uint32_t f = l == 0 ? i : faceids_r[i];
            const st_face *F = &s->faces[f];
            if (F->flags & ST_FACE_CONSTANT)
                continue;
            if (l == 0 && fi[f].ulog2 == 0 && fi[f].vlog2 == 0)
                continue; /* Ptex serves a 1x1 face from the constant data */
            if (l > 0 && (fi[f].flags & PTX_FLAG_HASEDITS))
                continue; /* stored reductions of an edited face are stale */
            if (l > 0 && (l > F->ulog2 || l > F->vlog2)) {
                rc = st_fail(e, ST_EFORMAT, "level %u lists face %u whose resolution 2^%u x 2^%u "
                             "has no such reduction", l, f, F->ulog2, F->vlog2);
                goto done;
            }
            if (l > 0 && nstored[f] != l)
                continue; /* a gap: the level before was missing for this face */
            int edited = 0;
            for (size_t k = 0; l == 0 && k < nfedits; k++)
                edited |= fedits[k].faceid == f;
            uint64_t end = edited ? len : lpos + lsize;
            /* the message names "level L face F", formatted only on failure (a printf per
             * face was a few percent of importing a file of small faces) */
            if ((rc = decode_face(r, fdh[i], offs[i], end, F->ulog2 - l, F->vlog2 - l,
                                  r->dry ? NULL : st_face_level(s, f, l), ""))) {
                err_prefix(e, rc, "level %u face %u", l, f);
                goto done;
            }
            if (r->ctiled && !r->tri) {
                if (nct == ctcap) {
                    size_t nc = ctcap ? 2 * ctcap : 16;
                    st_ptexres_ctile *np = realloc(ct, nc * sizeof *np);
                    if (!np) {
                        rc = st_fail(e, ST_ENOMEM, "out of memory for the tiled faces");
                        goto done;
                    }
                    ct = np;
                    ctcap = nc;
                }
                ct[nct++] = (st_ptexres_ctile){.face = f, .level = (uint8_t)l, .tu = r->ct_tu,
                                               .tv = r->ct_tv};
            }
            if (r->dry && pend_push(pd, f, fdh[i], offs[i])) {
                rc = st_fail(e, ST_ENOMEM, "out of memory for the stored reductions");
                goto done;
            }
            if (l > 0)
                nstored[f] = (uint8_t)(l + 1);
        }
        lpos += lsize;
        if (pd && l > 0)
            pd->lend[l] = lpos;
    }
    r->dry = 0;
    if (pd) {
        pd->nlevels = nlevels;
        /* pd->origin: where level 1 starts (until the file buffer is kept below) */
        pd->dyn_all = nlevels > 1 && lpos - pd->origin <= PTX_SMALL_LEVEL0;
        pd->first[nlevels > 1 ? nlevels : 1] = (uint32_t)pd->nblk;
        /* the blocks, when one is kept: the file buffer itself, or a copy of the level data
         * from level 1 on */
        if (pd->nblk && own) {
            pd->zip = *own;
            *own = NULL;
            pd->origin = 0;
            pd->zlen = len;
            pd->zbytes = stu_big_footprint(len + 1, STU_BIG_TEMP); /* as util/fdio.c reads */
        } else if (pd->nblk) {
            pd->zlen = (size_t)(lpos - pd->origin);
            if (!(pd->zip = malloc(pd->zlen))) {
                rc = st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of stored reductions",
                             pd->zlen);
                goto done;
            }
            memcpy(pd->zip, b + pd->origin, pd->zlen);
            pd->zbytes = pd->zlen;
        }
        if (!(pd->constdata = malloc(cdbytes ? cdbytes : 1))) {
            rc = st_fail(e, ST_ENOMEM, "out of memory for the constant data");
            goto done;
        }
        memcpy(pd->constdata, constdata, cdbytes);
        pd->max_bytes = max_bytes;
        pd->dt = dtype;
        pd->nc = nchan;
        pd->tri = (unsigned)r->tri;
    }

    /* metadata: small, large, then edits in file order */
    {
        meta_ctx m = {.s = s, .lmd_pos = lmdpos, .lmd_end = lmdpos + lmddata};
        if (mdmem && (rc = read_meta_block(r, &m, mdpos, mdzip, mdmem, 0)))
            goto done;
        if (lmdmem && (rc = read_meta_block(r, &m, lmdhpos, lmdzip, lmdmem, 1)))
            goto done;
        for (size_t i = 0; i < nmedits; i++)
            if ((rc = read_meta_block(r, &m, medits[i].pos, medits[i].zs, medits[i].ms, 0)))
                goto done;
    }

    /* every other resolution, as Ptex serves it; also fills the set's unstored levels - now
     * (eager), or with the stored reductions on the first st_set_levels */
    if (pd) {
        st_ptexres_deferred d = {.make = pend_make, .free = pend_free, .data = pd,
                                 .constpx = pd->constdata,
                                 .bytes = sizeof *pd + pd->zbytes + pd->cap * sizeof *pd->blk +
                                          cdbytes};
        pd = NULL; /* the record owns it now, whatever happens */
        if ((rc = st_ptexres_attach_deferred(s, &d, ptxflags, nstored, max_bytes, e)))
            goto done;
    } else if ((rc = st_ptexres_attach(s, constdata, ptxflags, nstored, max_bytes, e))) {
        goto done;
    }
    if (nct) {
        qsort(ct, nct, sizeof *ct, ctile_cmp);
        if ((rc = st_ptexres_set_ctiles(s, ct, (uint32_t)nct, e)))
            goto done;
    }

done:
    free(ct);
    pend_free(pd);
    if (r->dd) /* none when every stream went through ptex_inflate.h: no call into libdeflate */
        libdeflate_free_decompressor(r->dd);
    free(r->scratch);
    free(work);
    free(fedits);
    free(medits);
    if (rc) {
        st_set_free(s);
        return rc;
    }
    *out = s;
    return ST_OK;
}

STU_LOADPATH
int st_ptex_read_mem(const void *buf, size_t len, size_t max_bytes, st_set **out, st_error *e)
{
    return read_mem(buf, len, max_bytes, 0, NULL, out, e);
}

int st_ptex_read_mem_eager(const void *buf, size_t len, size_t max_bytes, st_set **out,
                           st_error *e)
{
    return read_mem(buf, len, max_bytes, 1, NULL, out, e);
}

STU_LOADPATH
static int read_file(const char *path, size_t max_bytes, int eager, st_set **out, st_error *e)
{
    *out = NULL;
    void *buf;
    size_t len;
    int rc = st_file_read(path, (size_t)4 << 30, &buf, &len, e);
    if (rc)
        return rc;
    rc = read_mem(buf, len, max_bytes, eager, &buf, out, e); /* may keep buf (NULL then) */
    if (rc)
        err_prefix(e, rc, "%s: ", path);
    free(buf);
    return rc;
}

STU_LOADPATH
int st_ptex_read_file(const char *path, size_t max_bytes, st_set **out, st_error *e)
{
    return read_file(path, max_bytes, 0, out, e);
}

int st_ptex_read_file_eager(const char *path, size_t max_bytes, st_set **out, st_error *e)
{
    return read_file(path, max_bytes, 1, out, e);
}
