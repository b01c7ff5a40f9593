/* store/bc1/dds.c - DDS files of BC1 sets (bc1.h): writing and reading.
 *
 * Owns: the DDS container for BC1 (legacy DXT1 header, DX10 extension, cube maps, arrays,
 * mips) and seamtex's chunks after the image data. Does not own: encoding (bc1_encode.c),
 * sets (set.c).
 *
 * Every BC1 set that st_bc1_compress_set makes is written so that st_dds_read_* gives back
 * the same set: faces, sizes, flags (constant, subface), adjacency, every block, info
 * (colour space, border modes, alpha channel), the st_bc1_ext record and the metadata.
 * Other DDS readers see a valid texture (face 0, the cube or the array) and ignore the rest.
 *
 * File layout (little-endian):
 *   OFFSET SIZE DESCRIPTION
 *   0      4    "DDS "
 *   4      124  DDS_HEADER: size 124, flags, height, width, linear size (level-0 bytes),
 *               depth, mip count, 11 reserved, pixel format (32 bytes: size 32, flags
 *               DDPF_FOURCC, FourCC "DXT1" or "DX10", 5 unused), caps, caps2, caps3, caps4,
 *               reserved
 *   128    20   DX10 header when FourCC is "DX10": DXGI format (71 BC1_UNORM, 72 _SRGB),
 *               dimension 3 (2D), misc flags (4 = cube), array size, alpha mode
 *   ...         for each face (array element / cube face), every mip level, blocks row-major
 *   then seamtex's chunks, each opening with an 8-byte magic:
 *   "STSET001"  the set record (below); written first
 *   "STADJ001"  u32 nfaces, u8 source kind, 3 pad, then per face i32 adjface[4],
 *               u8 adjedge[4], u8 flags, 7 pad (28 bytes): adjacency of a per-face or cube
 *               set (also of a one-face per-face set)
 * Per-face sets whose faces differ in size (most Ptex files) are written as a plain DXT1
 * texture of face 0 (what any reader shows) followed by the "STFACES1" table (sizes and
 * adjacency of every face), faces 1.. with their levels (see write_mixed), then "STSET001".
 * Cube faces are written in set order (+X,-X,+Y,-Y,+Z,-Z, cube.h), each face image as stored
 * (rows top first). A constant face is written as uniform blocks (what other readers show);
 * its exact texel is in the set record, and seamtex reads it back as a constant face.
 *
 * Set record "STSET001" (size in the record; everything checked when read):
 *   OFFSET SIZE DESCRIPTION
 *    0     8    "STSET001"
 *    8     4    record size in bytes (from offset 0)
 *   12     4    nfaces (must match the file)
 *   16     1    colorspace 0..1       17  1  premultiplied 0..1
 *   18     1    border_u 0..2         19  1  border_v 0..2
 *   20     1    meshtype 0..1         21  1  alpha_chan (s8, -1 or 3)
 *   22     2    pad
 *   24     8    st_bc1_ext: src_kind 0..2, src_nchan 1..4, src_alpha (s8 -1..3),
 *               punchthrough 0..1, level 0..2, seam_mode 0..2, 2 pad
 *   32     4    nconst: constant faces       36  4  nmeta: metadata entries
 *   40          nconst x (u32 face id, strictly ascending; u8 rgba[4])
 *   ...         nmeta x (u8 keysize with the NUL, 2..255 | key | u8 type 0..5 | u32 count |
 *               count elements of the type's size), set order (repeats kept)
 *               except "seamtex:source_format": the importer sets it on every set it makes
 *               (import.c) to say how the set in memory was made; a .dds written here is a
 *               new source, which the importer would tag "dds" when it reads it back, so
 *               writing it would make a restarted daemon's .dds of a COMPRESS result differ
 *               from the one served before the restart (tests/unit/test_dds_reload.c). The
 *               Ptex writer leaves it out for the same reason (ptex_write.c).
 * Files without the record (older seamtex files, other tools) read as before: no constant
 * faces, alpha from the blocks, linear unless DX10 says sRGB, no metadata.
 */
#include "bc1.h"
#include "fileio.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DDSD_CAPS        0x1u
#define DDSD_HEIGHT      0x2u
#define DDSD_WIDTH       0x4u
#define DDSD_PIXELFORMAT 0x1000u
#define DDSD_MIPMAPCOUNT 0x20000u
#define DDSD_LINEARSIZE  0x80000u
#define DDPF_FOURCC      0x4u
#define DDSCAPS_COMPLEX  0x8u
#define DDSCAPS_TEXTURE  0x1000u
#define DDSCAPS_MIPMAP   0x400000u
#define DDSCAPS2_CUBE_ALL 0xFE00u
#define DXGI_BC1_TYPELESS 70u
#define DXGI_BC1_UNORM   71u
#define DXGI_BC1_SRGB    72u
#define TRAILER_MAGIC    "STADJ001"
#define TRAILER_FACE     28u
#define MIXED_MAGIC      "STFACES1"
#define MIXED_FACE       36u
#define SET_MAGIC        "STSET001"
#define SET_FIXED        40u
#define SET_CONST        8u

/* Cube adjacency of cube.h ("face:edge" across edges 0..3 of faces +X,-X,+Y,-Y,+Z,-Z). */
static const int8_t CUBE_ADJ[6][4][2] = {
    {{2, 1}, {4, 3}, {3, 1}, {5, 1}}, {{2, 3}, {5, 3}, {3, 3}, {4, 1}},
    {{4, 0}, {0, 0}, {5, 0}, {1, 0}}, {{5, 2}, {0, 2}, {4, 2}, {1, 2}},
    {{2, 0}, {1, 3}, {3, 2}, {0, 1}}, {{2, 2}, {0, 3}, {3, 0}, {1, 1}},
};

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static size_t level_bytes(uint32_t w, uint32_t h) { return (size_t)((w + 3) / 4) * ((h + 3) / 4) * 8; }

static unsigned full_levels(uint32_t w, uint32_t h)
{
    uint32_t m = w > h ? w : h;
    unsigned l = 1;
    while (m >>= 1)
        l++;
    return l;
}

/* Bytes of the first `levels` levels of a w x h face as blocks (w, h <= ST_MAX_DIM: no
 * overflow, at most ~1.5 GiB). */
static size_t chain_bytes(uint32_t w, uint32_t h, unsigned levels)
{
    size_t b = 0;
    for (unsigned l = 0; l < levels; l++) {
        uint32_t lw = w >> l ? w >> l : 1, lh = h >> l ? h >> l : 1;
        b += level_bytes(lw, lh);
    }
    return b;
}

/* Every level of face f as blocks (a constant face expanded to uniform blocks). */
static size_t face_chain_bytes(const st_face *F) { return chain_bytes(F->w, F->h, F->nlevels); }

static void put_face_chain(const st_set *s, uint32_t f, uint8_t *p)
{
    const st_face *F = &s->faces[f];
    uint8_t blk[8];
    if (F->flags & ST_FACE_CONSTANT) {
        uint8_t px[64];
        for (int t = 0; t < 16; t++)
            memcpy(px + 4 * t, st_face_level(s, f, 0), 4);
        st_bc1_encode_block(px, ST_BC1_HQ, blk);
    }
    for (unsigned l = 0; l < F->nlevels; l++) {
        size_t lb = level_bytes(st_level_w(F, l), st_level_h(F, l));
        if (F->flags & ST_FACE_CONSTANT) {
            for (size_t o = 0; o < lb; o += 8)
                memcpy(p + o, blk, 8);
        } else {
            memcpy(p, st_face_level(s, f, l), lb);
        }
        p += lb;
    }
}

static void put_header(uint8_t *b, uint32_t w, uint32_t h, unsigned nlevels, int cube, int dx10)
{
    memcpy(b, "DDS ", 4);
    uint8_t *hd = b + 4;
    put32(hd + 0, 124);
    put32(hd + 4, DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | DDSD_MIPMAPCOUNT |
                      DDSD_LINEARSIZE);
    put32(hd + 8, h);
    put32(hd + 12, w);
    put32(hd + 16, (uint32_t)level_bytes(w, h));
    put32(hd + 24, nlevels);
    put32(hd + 72, 32);
    put32(hd + 76, DDPF_FOURCC);
    memcpy(hd + 80, dx10 ? "DX10" : "DXT1", 4);
    put32(hd + 104, DDSCAPS_TEXTURE | (nlevels > 1 ? DDSCAPS_MIPMAP | DDSCAPS_COMPLEX : 0) |
                        (cube ? DDSCAPS_COMPLEX : 0));
    put32(hd + 108, cube ? DDSCAPS2_CUBE_ALL : 0);
}

static size_t meta_tsize(unsigned t)
{
    static const size_t sz[] = {1, 1, 2, 4, 4, 8};
    return t < 6 ? sz[t] : 0;
}

/* The importer's provenance entry (import.c), never written: see the top of this file. */
#define META_NOT_WRITTEN "seamtex:source_format"

static int meta_written(const st_meta_entry *m) { return strcmp(m->key, META_NOT_WRITTEN) != 0; }

/* ---- the set record: writing -------------------------------------------------------------- */

static int set_record_size(const st_set *s, size_t *out, st_error *e)
{
    size_t n = SET_FIXED;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        if (s->faces[f].flags & ST_FACE_CONSTANT)
            n += SET_CONST;
    for (uint32_t i = 0; i < s->nmeta; i++) {
        const st_meta_entry *m = &s->meta[i];
        if (!meta_written(m))
            continue;
        size_t ks = strlen(m->key) + 1, ts = meta_tsize(m->type), db;
        if (ks < 2 || ks > 255 || !ts)
            return st_fail(e, ST_EINVAL, "metadata '%.40s': key of 1..254 bytes and type 0..5 "
                           "needed for DDS", m->key);
        if (st_mul_size(ts, m->count, &db) || st_add_size(n, 1 + ks + 1 + 4 + db, &n))
            return st_fail(e, ST_ETOOBIG, "metadata '%.40s' too big", m->key);
    }
    if (n > UINT32_MAX)
        return st_fail(e, ST_ETOOBIG, "metadata of %zu bytes does not fit a DDS set record", n);
    *out = n;
    return ST_OK;
}

static void put_set_record(const st_set *s, uint8_t *p, size_t size)
{
    const st_bc1_ext *x = st_set_ext_get(s, ST_EXT_BC1);
    memcpy(p, SET_MAGIC, 8);
    put32(p + 8, (uint32_t)size);
    put32(p + 12, s->info.nfaces);
    p[16] = s->info.colorspace;
    p[17] = s->info.premultiplied;
    p[18] = s->info.border_u;
    p[19] = s->info.border_v;
    p[20] = s->info.meshtype;
    p[21] = (uint8_t)s->info.alpha_chan;
    p[24] = x ? x->src_kind : ST_KIND_PERFACE;
    p[25] = x ? x->src_nchan : 4;
    p[26] = (uint8_t)(x ? x->src_alpha : s->info.alpha_chan);
    p[27] = x ? x->punchthrough : 0;
    p[28] = x ? x->level : ST_BC1_HQ;
    p[29] = x ? x->seam_mode : ST_BC1_SEAM_NONE;
    uint32_t nconst = 0;
    uint8_t *q = p + SET_FIXED;
    for (uint32_t f = 0; f < s->info.nfaces; f++)
        if (s->faces[f].flags & ST_FACE_CONSTANT) {
            put32(q, f);
            memcpy(q + 4, st_face_level(s, f, 0), 4);
            q += SET_CONST;
            nconst++;
        }
    put32(p + 32, nconst);
    uint32_t nmeta = 0;
    for (uint32_t i = 0; i < s->nmeta; i++) {
        const st_meta_entry *m = &s->meta[i];
        if (!meta_written(m))
            continue;
        nmeta++;
        size_t ks = strlen(m->key) + 1, db = meta_tsize(m->type) * m->count;
        *q++ = (uint8_t)ks;
        memcpy(q, m->key, ks);
        q += ks;
        *q++ = m->type;
        put32(q, m->count);
        q += 4;
        if (db)
            memcpy(q, m->data, db);
        q += db;
    }
    put32(p + 36, nmeta);
}

/* Whether a one-face set needs the adjacency trailer (a per-face face with neighbours). */
static int needs_trailer(const st_set *s)
{
    if (s->info.nfaces > 1)
        return 1;
    const st_face *F = &s->faces[0];
    return F->adjface[0] >= 0 || F->adjface[1] >= 0 || F->adjface[2] >= 0 ||
           F->adjface[3] >= 0 || (F->flags & ST_FACE_SUBFACE);
}

/* Faces of several sizes (most Ptex files): a plain DXT1 texture of face 0 with its mips, so
 * that any DDS reader shows face 0, then the "STFACES1" table (u32 nfaces, u8 source kind, 3
 * pad, per face u32 w, u32 h, i32 adjface[4], u8 adjedge[4], u8 flags, 7 pad: 36 bytes), then
 * faces 1.. with every level, then the set record. */
static int write_mixed(const st_set *s, uint8_t **buf, size_t *len, st_error *e)
{
    const st_bc1_ext *x = st_set_ext_get(s, ST_EXT_BC1);
    uint32_t nf = s->info.nfaces;
    size_t total = 128, fb, rec;
    int rc = set_record_size(s, &rec, e);
    if (rc)
        return rc;
    for (uint32_t f = 0; f < nf; f++)
        if (st_add_size(total, face_chain_bytes(&s->faces[f]), &total))
            return st_fail(e, ST_ETOOBIG, "DDS size overflows");
    if (st_mul_size(nf, MIXED_FACE, &fb) || st_add_size(total, 16 + fb, &total) ||
        st_add_size(total, rec, &total))
        return st_fail(e, ST_ETOOBIG, "DDS size overflows");
    uint8_t *b = calloc(1, total);
    if (!b)
        return st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of DDS", total);
    put_header(b, s->faces[0].w, s->faces[0].h, s->faces[0].nlevels, 0, 0);
    uint8_t *p = b + 128;
    put_face_chain(s, 0, p);
    p += face_chain_bytes(&s->faces[0]);
    memcpy(p, MIXED_MAGIC, 8);
    put32(p + 8, nf);
    p[12] = x ? x->src_kind : ST_KIND_PERFACE;
    p += 16;
    for (uint32_t f = 0; f < nf; f++, p += MIXED_FACE) {
        const st_face *F = &s->faces[f];
        put32(p, F->w);
        put32(p + 4, F->h);
        for (int k = 0; k < 4; k++) {
            put32(p + 8 + 4 * k, (uint32_t)F->adjface[k]);
            p[24 + k] = F->adjedge[k];
        }
        p[28] = F->flags & ST_FACE_SUBFACE;
    }
    for (uint32_t f = 1; f < nf; f++) {
        put_face_chain(s, f, p);
        p += face_chain_bytes(&s->faces[f]);
    }
    put_set_record(s, p, rec);
    *buf = b;
    *len = total;
    return ST_OK;
}

int st_dds_write_mem(const st_set *s, uint8_t **buf, size_t *len, st_error *e)
{
    *buf = NULL;
    *len = 0;
    if (s->info.kind != ST_KIND_BC1 || s->info.nfaces < 1)
        return st_fail(e, ST_EINVAL, "only BC1 sets are written as DDS");
    const st_bc1_ext *x = st_set_ext_get(s, ST_EXT_BC1);
    uint32_t nf = s->info.nfaces;
    const st_face *F0 = &s->faces[0];
    for (uint32_t f = 1; f < nf; f++)
        if (s->faces[f].w != F0->w || s->faces[f].h != F0->h)
            return write_mixed(s, buf, len, e);
    int cube = x && x->src_kind == ST_KIND_CUBE && nf == 6 && F0->w == F0->h;
    int dx10 = !cube && nf > 1;
    int trailer = needs_trailer(s);
    size_t face_bytes = face_chain_bytes(F0), rec;
    int rc = set_record_size(s, &rec, e);
    if (rc)
        return rc;
    size_t total = 128 + (dx10 ? 20 : 0), data;
    if (st_mul_size(face_bytes, nf, &data) || st_add_size(total, data, &total))
        return st_fail(e, ST_ETOOBIG, "DDS size overflows");
    size_t rstart = total, tstart;
    if (st_add_size(total, rec, &total))
        return st_fail(e, ST_ETOOBIG, "DDS size overflows");
    tstart = total;
    if (trailer && st_add_size(total, 16 + (size_t)nf * TRAILER_FACE, &total))
        return st_fail(e, ST_ETOOBIG, "DDS size overflows");
    uint8_t *b = calloc(1, total);
    if (!b)
        return st_fail(e, ST_ENOMEM, "out of memory for %zu bytes of DDS", total);
    put_header(b, F0->w, F0->h, F0->nlevels, cube, dx10);
    uint8_t *p = b + 128;
    if (dx10) {
        put32(p, s->info.colorspace == ST_CS_SRGB ? DXGI_BC1_SRGB : DXGI_BC1_UNORM);
        put32(p + 4, 3);
        put32(p + 8, 0);
        put32(p + 12, nf);
        put32(p + 16, x && x->punchthrough ? 1 : 3);
        p += 20;
    }
    for (uint32_t f = 0; f < nf; f++, p += face_bytes)
        put_face_chain(s, f, p);
    put_set_record(s, b + rstart, rec);
    if (trailer) {
        p = b + tstart;
        memcpy(p, TRAILER_MAGIC, 8);
        put32(p + 8, nf);
        p[12] = x ? x->src_kind : ST_KIND_PERFACE;
        p += 16;
        for (uint32_t f = 0; f < nf; f++, p += TRAILER_FACE) {
            const st_face *F = &s->faces[f];
            for (int k = 0; k < 4; k++) {
                put32(p + 4 * k, (uint32_t)F->adjface[k]);
                p[16 + k] = F->adjedge[k];
            }
            p[20] = F->flags & ST_FACE_SUBFACE;
        }
    }
    *buf = b;
    *len = total;
    return ST_OK;
}

/* Written to path.tmp, fsynced and renamed over path, so that a reader (or a restart after a
 * crash) sees the old file or the new one, never a part. */
int st_dds_write_file(const st_set *s, const char *path, st_error *e)
{
    uint8_t *b;
    size_t n;
    int rc = st_dds_write_mem(s, &b, &n, e);
    if (rc)
        return rc;
    rc = st_file_write_atomic(path, b, n, e);
    free(b);
    return rc;
}

/* ---- reading ------------------------------------------------------------------------------ */


/* A checked set record (pointers into the caller's buffer). */
typedef struct set_rec {
    int            present;
    st_set_info    info;       /* colorspace .. alpha_chan */
    st_bc1_ext     ext;
    uint32_t       nconst, nmeta;
    const uint8_t *consts;     /* nconst x 8 bytes */
    const uint8_t *meta;       /* nmeta records */
} set_rec;

/* Checks the record at pos (which starts with SET_MAGIC) completely; *next is the offset
 * after it. */
static int parse_set_record(const uint8_t *buf, size_t len, size_t pos, uint32_t nf,
                            set_rec *r, size_t *next, st_error *e)
{
    if (len - pos < SET_FIXED)
        return st_fail(e, ST_EFORMAT, "DDS set record at offset %zu truncated", pos);
    const uint8_t *p = buf + pos;
    uint32_t size = get32(p + 8);
    if (size < SET_FIXED || size > len - pos)
        return st_fail(e, ST_EFORMAT, "DDS set record at offset %zu: size %u not in %u..%zu",
                       pos, size, SET_FIXED, len - pos);
    if (get32(p + 12) != nf)
        return st_fail(e, ST_EFORMAT, "DDS set record: %u faces, the file has %u",
                       get32(p + 12), nf);
    int8_t alpha = (int8_t)p[21], salpha = (int8_t)p[26];
    if (p[16] > ST_CS_SRGB || p[17] > 1 || p[18] > 2 || p[19] > 2 || p[20] > 1 ||
        (alpha != -1 && alpha != 3))
        return st_fail(e, ST_EFORMAT, "DDS set record: info field out of range");
    if (p[24] > ST_KIND_ATLAS || p[25] < 1 || p[25] > ST_MAX_CHANNELS || salpha < -1 ||
        salpha >= (int)p[25] || p[27] > 1 || p[28] > ST_BC1_BEST || p[29] > ST_BC1_SEAM_AWARE)
        return st_fail(e, ST_EFORMAT, "DDS set record: BC1 source field out of range");
    memset(r, 0, sizeof *r);
    r->present = 1;
    r->info.colorspace = p[16];
    r->info.premultiplied = p[17];
    r->info.border_u = p[18];
    r->info.border_v = p[19];
    r->info.meshtype = p[20];
    r->info.alpha_chan = alpha;
    r->ext.src_kind = p[24];
    r->ext.src_nchan = p[25];
    r->ext.src_alpha = salpha;
    r->ext.punchthrough = p[27];
    r->ext.level = p[28];
    r->ext.seam_mode = p[29];
    r->nconst = get32(p + 32);
    r->nmeta = get32(p + 36);
    size_t at = SET_FIXED;
    if (r->nconst > nf || r->nconst > (size - at) / SET_CONST)
        return st_fail(e, ST_EFORMAT, "DDS set record: %u constant faces (%u faces, %u bytes)",
                       r->nconst, nf, size);
    r->consts = p + at;
    for (uint32_t i = 0; i < r->nconst; i++) {
        uint32_t f = get32(p + at + (size_t)i * SET_CONST);
        if (f >= nf || (i && f <= get32(p + at + (size_t)(i - 1) * SET_CONST)))
            return st_fail(e, ST_EFORMAT, "DDS set record: constant face %u out of range or "
                           "order", f);
    }
    at += (size_t)r->nconst * SET_CONST;
    r->meta = p + at;
    for (uint32_t i = 0; i < r->nmeta; i++) {
        if (size - at < 2)
            return st_fail(e, ST_EFORMAT, "DDS set record: metadata %u truncated", i);
        size_t ks = p[at];
        if (ks < 2 || size - at - 1 < ks + 5)
            return st_fail(e, ST_EFORMAT, "DDS set record: metadata %u key of %zu bytes", i, ks);
        const uint8_t *key = p + at + 1;
        if (key[ks - 1] != 0 || memchr(key, 0, ks - 1))
            return st_fail(e, ST_EFORMAT, "DDS set record: metadata %u key not a string", i);
        unsigned type = key[ks];
        uint32_t count = get32(key + ks + 1);
        size_t ts = meta_tsize(type), db;
        if (!ts || st_mul_size(ts, count, &db) || db > size - at - 1 - ks - 5)
            return st_fail(e, ST_EFORMAT, "DDS set record: metadata '%s' type %u count %u "
                           "overruns the record", (const char *)key, type, count);
        at += 1 + ks + 5 + db;
    }
    if (at != size)
        return st_fail(e, ST_EFORMAT, "DDS set record: %u bytes declared, %zu used", size, at);
    *next = pos + size;
    return ST_OK;
}

/* Where face f's blocks are in the file and how many levels the file holds per face. */
typedef struct layout {
    const uint8_t *face0;      /* face 0's levels */
    const uint8_t *rest;       /* face 1's levels, the others follow */
    unsigned       mips;       /* levels per face in the file (0 = every level of the face) */
} layout;

/* Builds the set from face descriptions and the file's blocks; applies the set record. */
static int build_set(st_face_desc *fd, uint32_t nf, int srgb, uint8_t src_kind,
                     const set_rec *rec, const layout *lo, size_t max_bytes, st_set **out,
                     st_error *e)
{
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = nf;
    info.nchan = 4;
    info.dtype = ST_DT_U8;
    info.alpha_chan = 3;
    info.kind = ST_KIND_BC1;
    info.colorspace = srgb ? ST_CS_SRGB : ST_CS_LINEAR;
    if (rec->present) {
        info.colorspace = rec->info.colorspace;
        info.premultiplied = rec->info.premultiplied;
        info.border_u = rec->info.border_u;
        info.border_v = rec->info.border_v;
        info.meshtype = rec->info.meshtype;
        info.alpha_chan = rec->info.alpha_chan;
        for (uint32_t i = 0; i < rec->nconst; i++)
            fd[get32(rec->consts + (size_t)i * SET_CONST)].flags |= ST_FACE_CONSTANT;
    }
    st_set *s;
    int rc = st_set_create(&info, fd, max_bytes, &s, e); /* checks sizes, caps, adjacency */
    if (rc)
        return rc;
    st_bc1_ext *x = calloc(1, sizeof *x);
    if (!x) {
        st_set_free(s);
        return st_fail(e, ST_ENOMEM, "out of memory");
    }
    if (rec->present) {
        *x = rec->ext;
    } else {
        x->src_kind = src_kind;
        x->src_nchan = 4;
        x->src_alpha = 3;
        x->level = ST_BC1_HQ;
    }
    st_bc1_ext_attach(s, x);
    const uint8_t *src = lo->face0;
    int punch = 0;
    for (uint32_t f = 0; f < nf; f++) {
        const st_face *F = &s->faces[f];
        unsigned mips = lo->mips ? lo->mips : F->nlevels;
        if (f == 1)
            src = lo->rest;
        if (F->flags & ST_FACE_CONSTANT) { /* blocks in the file are for other readers */
            src += chain_bytes(F->w, F->h, mips);
            continue;
        }
        for (unsigned l = 0; l < mips; l++) {
            size_t lb = level_bytes(st_level_w(F, l), st_level_h(F, l));
            memcpy(st_face_level(s, f, l), src, lb);
            for (size_t o = 0; o < lb && !punch && !rec->present; o += 8) {
                const uint8_t *bk = src + o;
                if ((bk[0] | bk[1] << 8) <= (bk[2] | bk[3] << 8))
                    for (int t = 0; t < 16; t++)
                        punch |= ((bk[4 + t / 4] >> (2 * (t & 3))) & 3) == 3;
            }
            src += lb;
        }
        /* levels the file does not have: decode the last one, reduce, encode */
        for (unsigned l = mips; l < F->nlevels; l++) {
            uint32_t sw = st_level_w(F, l - 1), sh = st_level_h(F, l - 1);
            uint32_t dw = st_level_w(F, l), dh = st_level_h(F, l);
            uint8_t *a = malloc((size_t)sw * sh * 4), *b = malloc((size_t)dw * dh * 4);
            if (!a || !b) {
                free(a);
                free(b);
                st_set_free(s);
                return st_fail(e, ST_ENOMEM, "out of memory for a mip level");
            }
            st_bc1_decode_image(st_face_level(s, f, l - 1), sw, sh, ST_BC1_DEC_EXACT, a);
            uint32_t xs = sw > 1 ? 2 : 1, ys = sh > 1 ? 2 : 1;
            for (uint32_t y = 0; y < dh; y++)
                for (uint32_t xx = 0; xx < dw; xx++)
                    for (int c = 0; c < 4; c++) {
                        unsigned acc = 0;
                        for (uint32_t j = 0; j < ys; j++)
                            for (uint32_t i = 0; i < xs; i++)
                                acc += a[(((size_t)(y * ys + j)) * sw + xx * xs + i) * 4 + c];
                        b[((size_t)y * dw + xx) * 4 + c] = (uint8_t)((acc + xs * ys / 2) / (xs * ys));
                    }
            st_bc1_encode_image(b, dw, dh, (size_t)dw * 4, ST_BC1_FAST, 1, st_face_level(s, f, l),
                                NULL);
            free(a);
            free(b);
        }
    }
    if (rec->present) {
        for (uint32_t i = 0; i < rec->nconst; i++) {
            const uint8_t *c = rec->consts + (size_t)i * SET_CONST;
            memcpy(st_face_level(s, get32(c), 0), c + 4, 4);
        }
        const uint8_t *m = rec->meta;
        for (uint32_t i = 0; i < rec->nmeta; i++) {
            size_t ks = m[0];
            const char *key = (const char *)m + 1;
            unsigned type = m[1 + ks];
            uint32_t count = get32(m + 2 + ks);
            if ((rc = st_set_meta_add(s, key, type, m + 6 + ks, count, e))) {
                st_set_free(s);
                return rc;
            }
            m += 6 + ks + meta_tsize(type) * count;
        }
    } else {
        x->punchthrough = (uint8_t)punch;
        if (!punch)
            s->info.alpha_chan = -1;
    }
    *out = s;
    return ST_OK;
}

/* 2..7 trailing bytes that begin one of seamtex's chunk magics: a seamtex file cut inside
 * the magic (refused: reading on would drop the record or the trailer without a word). */
static int cut_chunk_magic(const uint8_t *p, size_t n)
{
    return n >= 2 && n < 8 && (!memcmp(p, SET_MAGIC, n) || !memcmp(p, TRAILER_MAGIC, n) ||
                               !memcmp(p, MIXED_MAGIC, n));
}

/* Reads the STFACES1 layout: the table is at offset `at`, just after face 0's levels (`mips`
 * of them, which must be all of face 0's levels). */
static int read_mixed(const uint8_t *buf, size_t len, size_t face0_off, size_t at,
                      unsigned mips, int srgb, size_t max_bytes, st_set **out, st_error *e)
{
    const uint8_t *p = buf + at;
    uint32_t nf = get32(p + 8);
    if (nf < 1 || nf > ST_MAX_FACES)
        return st_fail(e, ST_ETOOBIG, "DDS face table: %u faces not in 1..%u", nf, ST_MAX_FACES);
    size_t tb;
    if (st_mul_size(nf, MIXED_FACE, &tb) || tb > len - at - 16)
        return st_fail(e, ST_EFORMAT, "DDS face table of %u faces truncated", nf);
    uint8_t kind = p[12] <= ST_KIND_ATLAS ? p[12] : ST_KIND_PERFACE;
    const uint8_t *t = p + 16;
    uint32_t W = get32(buf + 16), H = get32(buf + 12);
    st_face_desc *fd = calloc(nf, sizeof *fd);
    if (!fd)
        return st_fail(e, ST_ENOMEM, "out of memory for %u faces", nf);
    size_t need = 0;
    int rc = ST_OK;
    for (uint32_t f = 0; f < nf && !rc; f++) {
        const uint8_t *q = t + (size_t)f * MIXED_FACE;
        fd[f].w = get32(q);
        fd[f].h = get32(q + 4);
        for (int k = 0; k < 4; k++) {
            int32_t a = (int32_t)get32(q + 8 + 4 * k);
            fd[f].adjface[k] = a < 0 ? -1 : a;
            fd[f].adjedge[k] = (int8_t)q[24 + k];
        }
        fd[f].flags = q[28] & ST_FACE_SUBFACE;
        if (fd[f].w < 1 || fd[f].h < 1 || fd[f].w > ST_MAX_DIM || fd[f].h > ST_MAX_DIM)
            rc = st_fail(e, ST_ETOOBIG, "DDS face table: face %u size %ux%u not in 1..%u", f,
                         fd[f].w, fd[f].h, ST_MAX_DIM);
        else if (f == 0 && (fd[0].w != W || fd[0].h != H ||
                            mips != full_levels(fd[0].w, fd[0].h)))
            rc = st_fail(e, ST_EFORMAT, "DDS face table: face 0 does not match the header");
        else if (f > 0 && st_add_size(need, chain_bytes(fd[f].w, fd[f].h,
                                                         full_levels(fd[f].w, fd[f].h)), &need))
            rc = st_fail(e, ST_EFORMAT, "DDS face sizes overflow");
    }
    /* every face's levels must be in the file, then nothing or the set record */
    size_t data = at + 16 + tb;
    if (!rc && need > len - data)
        rc = st_fail(e, ST_EFORMAT, "DDS data truncated: faces 1..%u need %zu bytes, file has %zu",
                     nf - 1, need, len - data);
    set_rec rec;
    memset(&rec, 0, sizeof rec);
    size_t end = data + need, next;
    if (!rc && end < len) {
        if (len - end < 8 || memcmp(buf + end, SET_MAGIC, 8))
            rc = st_fail(e, ST_EFORMAT, "DDS face table layout: %zu unknown bytes after the faces",
                         len - end);
        else if (!(rc = parse_set_record(buf, len, end, nf, &rec, &next, e)) && next != len)
            rc = st_fail(e, ST_EFORMAT, "DDS face table layout: %zu unknown bytes after the "
                         "set record", len - next);
    }
    if (!rc) {
        layout lo = {buf + face0_off, buf + data, 0};
        rc = build_set(fd, nf, srgb, kind, &rec, &lo, max_bytes, out, e);
    }
    free(fd);
    return rc;
}

int st_dds_read_mem(const uint8_t *buf, size_t len, size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    if (len < 128 || memcmp(buf, "DDS ", 4))
        return st_fail(e, ST_EFORMAT, "not a DDS file (no \"DDS \" magic or shorter than 128 bytes)");
    const uint8_t *h = buf + 4;
    if (get32(h) != 124 || get32(h + 72) != 32)
        return st_fail(e, ST_EFORMAT, "DDS header size %u / pixel format size %u (want 124 / 32)",
                       get32(h), get32(h + 72));
    uint32_t H = get32(h + 8), W = get32(h + 12), mips = get32(h + 24);
    if (W < 1 || H < 1 || W > ST_MAX_DIM || H > ST_MAX_DIM)
        return st_fail(e, ST_ETOOBIG, "DDS size %ux%u not in 1..%u", W, H, ST_MAX_DIM);
    if (!(get32(h + 76) & DDPF_FOURCC))
        return st_fail(e, ST_EUNSUPPORTED, "DDS pixel format is not compressed (no FourCC)");
    unsigned nfull = full_levels(W, H);
    if (mips == 0 || !(get32(h + 4) & DDSD_MIPMAPCOUNT))
        mips = 1;
    if (mips > nfull)
        return st_fail(e, ST_EFORMAT, "DDS claims %u mip levels, a %ux%u texture has at most %u",
                       mips, W, H, nfull);
    uint32_t caps2 = get32(h + 108);
    int dx10 = !memcmp(h + 80, "DX10", 4);
    /* a DX10 file says cube in its misc flags (as DirectXTex reads it); caps2 is then only a
     * hint: taking it would read a 72-face array as a cube of its first 6 faces */
    int cube = !dx10 && (caps2 & 0x200u) != 0;
    uint32_t nf = 1;
    size_t off = 128;
    int srgb = 0;
    if (dx10) {
        if (len < 148)
            return st_fail(e, ST_EFORMAT, "DDS DX10 header truncated");
        uint32_t fmt = get32(buf + 128), dim = get32(buf + 132), misc = get32(buf + 136),
                 arr = get32(buf + 140);
        if (fmt != DXGI_BC1_UNORM && fmt != DXGI_BC1_SRGB && fmt != DXGI_BC1_TYPELESS)
            return st_fail(e, ST_EUNSUPPORTED, "DDS DXGI format %u is not BC1 (70..72)", fmt);
        if (dim != 3)
            return st_fail(e, ST_EUNSUPPORTED, "DDS resource dimension %u is not 2D", dim);
        if (arr < 1 || arr > ST_MAX_FACES)
            return st_fail(e, ST_ETOOBIG, "DDS array size %u not in 1..%u", arr, ST_MAX_FACES);
        srgb = fmt == DXGI_BC1_SRGB;
        if (misc & 4u) {
            cube = 1;
            if (arr != 1)
                return st_fail(e, ST_EUNSUPPORTED, "DDS cube map arrays are not supported");
        }
        nf = arr;
        off = 148;
    } else if (memcmp(h + 80, "DXT1", 4)) {
        return st_fail(e, ST_EUNSUPPORTED, "DDS FourCC '%.4s' is not DXT1 or DX10", (const char *)h + 80);
    }
    if (cube) {
        if ((caps2 & DDSCAPS2_CUBE_ALL) != DDSCAPS2_CUBE_ALL && !dx10)
            return st_fail(e, ST_EUNSUPPORTED, "DDS cube map without all six faces");
        if (W != H)
            return st_fail(e, ST_EFORMAT, "DDS cube faces are %ux%u, not square", W, H);
        nf = 6;
    }
    size_t face_bytes = chain_bytes(W, H, mips);
    size_t need, end;
    if (st_mul_size(face_bytes, nf, &need) || st_add_size(need, off, &end) || end > len)
        return st_fail(e, ST_EFORMAT, "DDS data truncated: %u faces of %zu bytes need %zu bytes, file has %zu",
                       nf, face_bytes, need, len - off);
    /* faces of several sizes: face 0 is the texture, the table and the other faces follow */
    if (nf == 1 && !cube && len - end >= 16 && !memcmp(buf + end, MIXED_MAGIC, 8))
        return read_mixed(buf, len, off, end, mips, srgb, max_bytes, out, e);
    /* seamtex's chunks: the set record, the adjacency trailer (other bytes are ignored; a
     * chunk that is there but damaged or cut short is refused) */
    set_rec rec;
    memset(&rec, 0, sizeof rec);
    const uint8_t *tr = NULL;
    uint8_t src_kind = cube ? ST_KIND_CUBE : nf == 1 ? ST_KIND_ATLAS : ST_KIND_PERFACE;
    size_t pos = end;
    if (cut_chunk_magic(buf + pos, len - pos))
        return st_fail(e, ST_EFORMAT, "DDS truncated: %zu bytes of a seamtex chunk at offset %zu",
                       len - pos, pos);
    if (len - pos >= 8 && !memcmp(buf + pos, SET_MAGIC, 8)) {
        int rc = parse_set_record(buf, len, pos, nf, &rec, &pos, e);
        if (rc)
            return rc;
    }
    if (len - pos >= 8 && !memcmp(buf + pos, TRAILER_MAGIC, 8)) {
        /* the adjacency trailer is there: a damaged one is refused, not skipped (the set
         * would come back without its adjacency, every face edge a boundary) */
        if (len - pos < 16 || get32(buf + pos + 8) != nf || (len - pos - 16) / TRAILER_FACE < nf)
            return st_fail(e, ST_EFORMAT, "DDS adjacency trailer at offset %zu damaged: %zu bytes "
                           "for %u faces (the file has %u)", pos, len - pos,
                           len - pos >= 16 ? get32(buf + pos + 8) : 0, nf);
        tr = buf + pos + 16;
        if (buf[pos + 12] <= ST_KIND_ATLAS)
            src_kind = buf[pos + 12];
    } else if (len - pos >= 8 && !memcmp(buf + pos, MIXED_MAGIC, 8)) {
        return st_fail(e, ST_EFORMAT, "DDS face table at offset %zu truncated (%zu bytes)", pos,
                       len - pos);
    } else if (cut_chunk_magic(buf + pos, len - pos)) {
        return st_fail(e, ST_EFORMAT, "DDS truncated: %zu bytes of a seamtex chunk at offset %zu",
                       len - pos, pos);
    }
    st_face_desc *fd = calloc(nf, sizeof *fd);
    if (!fd)
        return st_fail(e, ST_ENOMEM, "out of memory for %u faces", nf);
    for (uint32_t f = 0; f < nf; f++) {
        fd[f].w = W;
        fd[f].h = H;
        for (int k = 0; k < 4; k++) {
            fd[f].adjface[k] = -1;
            fd[f].adjedge[k] = 0;
            if (tr) {
                int32_t a = (int32_t)get32(tr + (size_t)f * TRAILER_FACE + 4 * k);
                fd[f].adjface[k] = a < 0 ? -1 : a;
                fd[f].adjedge[k] = (int8_t)tr[(size_t)f * TRAILER_FACE + 16 + k];
            } else if (cube) {
                fd[f].adjface[k] = CUBE_ADJ[f][k][0];
                fd[f].adjedge[k] = CUBE_ADJ[f][k][1];
            }
        }
        if (tr)
            fd[f].flags = tr[(size_t)f * TRAILER_FACE + 20] & ST_FACE_SUBFACE;
    }
    layout lo = {buf + off, buf + off + face_bytes, mips};
    int rc = build_set(fd, nf, srgb, src_kind, &rec, &lo, max_bytes, out, e);
    free(fd);
    return rc;
}

int st_dds_read_file(const char *path, size_t max_bytes, st_set **out, st_error *e)
{
    *out = NULL;
    void *b;
    size_t n;
    int rc = st_file_read(path, (size_t)1 << 34, &b, &n, e);
    if (rc)
        return rc;
    rc = st_dds_read_mem(b, n, max_bytes, out, e);
    free(b);
    return rc;
}
