/* store/import/exr.c - OpenEXR reader on OpenEXR's C API (openexr.h, 3.1).
 *
 * Owns: st_exr_read, st_exr_is_magic. Reads part 0, level 0 (scanline or tiled, any level
 * mode), channels R,G,B,A by name (of the default layer, else of the first layer with a
 * "<layer>.R"; else X, Y, Z when the Y has an X beside it; else Y, with its A as a second
 * channel; else up to 4 channels in file order), half kept as half, float and uint as float. Does not own: other image formats (image_oiio.cpp).
 *
 * Why planes: OpenEXR 3.1.5's default unpacker mis-orders 4-channel half data decoded to
 * interleaved float (fixed upstream in 3.3). Each selected channel is therefore decoded into
 * its own plane with its own type, and interleaved here afterwards.
 *
 * Caps: the data window is checked against max_dim and max_bytes before any allocation; the
 * library's own limits catch absurd tile sizes and chunk tables.
 */
#include "exr.h"

#include <OpenEXR/openexr.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>

#include "set.h"

int st_exr_is_magic(const void *buf, size_t len)
{
    static const unsigned char m[4] = {0x76, 0x2f, 0x31, 0x01};
    return len >= 4 && !memcmp(buf, m, 4);
}

static void quiet_handler(exr_const_context_t c, exr_result_t code, const char *msg)
{
    (void)c;
    (void)code;
    (void)msg;
}

typedef struct exr_job {
    int32_t  x0, y0, w, h;        /* data window */
    int      nsel;
    int      chan_idx[4];         /* index in the channel list */
    unsigned out_dt;              /* ST_DT_HALF or ST_DT_F32 */
    size_t   cs;                  /* bytes per channel value */
    uint8_t *planes[4];           /* w*h values each */
} exr_job;

/* Decodes one chunk into the planes. */
static int decode_chunk(exr_context_t ctx, const exr_chunk_info_t *ci, int32_t px, int32_t py,
                        exr_decode_pipeline_t *dec, int *inited, exr_job *j)
{
    exr_result_t r;
    if (!*inited) {
        r = exr_decoding_initialize(ctx, 0, ci, dec);
        if (r != EXR_ERR_SUCCESS)
            return r;
        *inited = 1;
    } else {
        r = exr_decoding_update(ctx, 0, ci, dec);
        if (r != EXR_ERR_SUCCESS)
            return r;
    }
    if (px < 0 || py < 0 || ci->width < 0 || ci->height < 0 || px + ci->width > j->w ||
        py + ci->height > j->h)
        return EXR_ERR_CORRUPT_CHUNK;
    for (int c = 0; c < dec->channel_count; c++) {
        exr_coding_channel_info_t *ch = &dec->channels[c];
        ch->decode_to_ptr = NULL;
        for (int k = 0; k < j->nsel; k++) {
            if (j->chan_idx[k] != c)
                continue;
            if (ch->x_samples != 1 || ch->y_samples != 1)
                return EXR_ERR_FEATURE_NOT_IMPLEMENTED;
            ch->user_data_type = j->out_dt == ST_DT_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)j->cs;
            ch->user_pixel_stride = (int32_t)j->cs;
            ch->user_line_stride = (int32_t)(j->cs * (size_t)j->w);
            ch->decode_to_ptr = j->planes[k] + ((size_t)py * j->w + px) * j->cs;
        }
    }
    r = exr_decoding_choose_default_routines(ctx, 0, dec);
    if (r != EXR_ERR_SUCCESS)
        return r;
    return exr_decoding_run(ctx, 0, dec);
}

static int read_part(exr_context_t ctx, const char *path, exr_job *j, st_error *e)
{
    exr_storage_t st;
    if (exr_get_storage(ctx, 0, &st) != EXR_ERR_SUCCESS)
        return st_fail(e, ST_EFORMAT, "%s: no storage type", path);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int inited = 0, r = EXR_ERR_SUCCESS;
    if (st == EXR_STORAGE_SCANLINE) {
        int32_t spc = 0;
        if (exr_get_scanlines_per_chunk(ctx, 0, &spc) != EXR_ERR_SUCCESS || spc < 1)
            return st_fail(e, ST_EFORMAT, "%s: bad scanlines per chunk", path);
        for (int64_t y = j->y0; y < (int64_t)j->y0 + j->h && r == EXR_ERR_SUCCESS; y += spc) {
            exr_chunk_info_t ci;
            r = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci);
            if (r == EXR_ERR_SUCCESS)
                r = decode_chunk(ctx, &ci, 0, ci.start_y - j->y0, &dec, &inited, j);
        }
    } else if (st == EXR_STORAGE_TILED) {
        int32_t tw = 0, th = 0;
        if (exr_get_tile_sizes(ctx, 0, 0, 0, &tw, &th) != EXR_ERR_SUCCESS || tw < 1 || th < 1)
            return st_fail(e, ST_EFORMAT, "%s: bad tile size", path);
        int32_t ntx = (int32_t)(((int64_t)j->w + tw - 1) / tw);
        int32_t nty = (int32_t)(((int64_t)j->h + th - 1) / th);
        for (int32_t ty = 0; ty < nty && r == EXR_ERR_SUCCESS; ty++)
            for (int32_t tx = 0; tx < ntx && r == EXR_ERR_SUCCESS; tx++) {
                exr_chunk_info_t ci;
                r = exr_read_tile_chunk_info(ctx, 0, tx, ty, 0, 0, &ci);
                if (r == EXR_ERR_SUCCESS)
                    r = decode_chunk(ctx, &ci, tx * tw, ty * th, &dec, &inited, j);
            }
    } else {
        return st_fail(e, ST_EUNSUPPORTED, "%s: deep EXR data is not an image seamtex reads", path);
    }
    if (inited)
        exr_decoding_destroy(ctx, &dec);
    if (r != EXR_ERR_SUCCESS)
        return st_fail(e, r == EXR_ERR_FEATURE_NOT_IMPLEMENTED ? ST_EUNSUPPORTED : ST_EFORMAT,
                       "%s: decoding failed: %s", path, exr_get_error_code_as_string(r));
    return ST_OK;
}

/* The bytes of the file being read, for the ripmap check below: a file (path) or a buffer. */
typedef struct raw_src {
    const char    *path;          /* NULL: buf */
    const uint8_t *buf;
    uint64_t       size;
} raw_src;

static int raw_read(FILE *f, const raw_src *src, uint64_t off, void *dst, size_t n)
{
    if (off > src->size || n > src->size - off)
        return -1;
    if (!f) {
        memcpy(dst, src->buf + off, n);
        return 0;
    }
    return fseeko(f, (off_t)off, SEEK_SET) || fread(dst, 1, n, f) != n ? -1 : 0;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Moves *pos past one header (attributes, each name\0 type\0 int32 size value, ended by an
 * empty name). Returns 0, or -1 when the header does not end inside the file. */
static int skip_header(FILE *f, const raw_src *src, uint64_t *pos)
{
    uint8_t b[256];
    for (int attr = 0; attr <= 100000; attr++) {
        /* name, then type: NUL-terminated strings of at most 255 bytes */
        size_t strs[2] = {0, 0};
        for (int k = 0; k < 2; k++) {
            if (*pos >= src->size)
                return -1;
            size_t got = src->size - *pos < sizeof b ? (size_t)(src->size - *pos) : sizeof b;
            if (raw_read(f, src, *pos, b, got))
                return -1;
            uint8_t *z = memchr(b, 0, got);
            if (!z)
                return -1;
            strs[k] = (size_t)(z - b);
            *pos += strs[k] + 1;
            if (k == 0 && strs[0] == 0)
                return 0; /* end of the header */
        }
        if (raw_read(f, src, *pos, b, 4))
            return -1;
        *pos += 4 + (uint64_t)le32(b);
    }
    return -1;
}

/* A ripmap part 0: OpenEXR 3.1.5's C API maps the tiles of rip levels (x, y > 0) to the wrong
 * chunks (exr_read_tile_chunk_info on a valid file answers BAD_CHUNK_LEADER), so part 0's
 * chunks are checked from the file's own chunk offset tables (OpenEXR file layout): after the
 * magic and the version field come the headers - one, or in a multi-part file (version flag
 * bit 12) one per part followed by an empty header (a lone NUL) - then one offset table per
 * part in header order, each chunk_count uint64 offsets, part 0's first. Each of part 0's
 * offsets leads to a tile leader (in a multi-part file an int32 part number, which must be 0,
 * first; then int32 x, y, level x, level y, packed size) whose data must end inside the file.
 * Returns 0 when every chunk is inside. */
static int ripmap_chunks_inside(exr_context_t ctx, const raw_src *src)
{
    int32_t nchunks = 0;
    int nparts = 0;
    if (exr_get_chunk_count(ctx, 0, &nchunks) != EXR_ERR_SUCCESS || nchunks < 1 ||
        exr_get_count(ctx, &nparts) != EXR_ERR_SUCCESS || nparts < 1)
        return -1;
    FILE *f = NULL;
    if (src->path && !(f = fopen(src->path, "rb")))
        return -1;
    uint8_t b[24];
    int bad = raw_read(f, src, 4, b, 4);
    int multi = !bad && (le32(b) & 0x1000u) != 0;
    uint64_t pos = 8, all_chunks = 0;
    for (int p = 0; p < (multi ? nparts : 1) && !bad; p++) {
        int32_t n = 0;
        bad = skip_header(f, src, &pos) || exr_get_chunk_count(ctx, p, &n) != EXR_ERR_SUCCESS ||
              n < 0;
        all_chunks += (uint64_t)(n > 0 ? n : 0);
    }
    if (!bad && multi) /* the empty header that ends the list */
        bad = raw_read(f, src, pos++, b, 1) || b[0] != 0;
    size_t lead = multi ? 24 : 20; /* the leader, up to and with the packed size */
    uint64_t table_end = pos + 8 * all_chunks;
    for (int32_t i = 0; i < nchunks && !bad; i++) {
        uint8_t o[8];
        if (raw_read(f, src, pos + 8 * (uint64_t)i, o, 8)) {
            bad = 1;
            break;
        }
        uint64_t off = (uint64_t)le32(o) | (uint64_t)le32(o + 4) << 32;
        if (off < table_end || raw_read(f, src, off, b, lead) || (multi && le32(b) != 0) ||
            (int32_t)le32(b + lead - 4) < 0 || le32(b + lead - 4) > src->size - off - lead)
            bad = 1;
    }
    if (f)
        fclose(f);
    return bad ? -1 : 0;
}

/* Every chunk of every level of a tiled part must lie inside the file: only level 0 is
 * decoded, but a file cut inside its smaller levels is still a truncated file and is refused
 * (a scanline part has one level, all of whose chunks read_part decodes). */
static int tiled_chunks_inside(exr_context_t ctx, const char *path, const raw_src *src,
                               st_error *e)
{
    uint64_t fsize = src->size;
    exr_storage_t st;
    if (exr_get_storage(ctx, 0, &st) != EXR_ERR_SUCCESS || st != EXR_STORAGE_TILED)
        return ST_OK;
    uint32_t xs, ys;
    exr_tile_level_mode_t lm;
    exr_tile_round_mode_t rm;
    int32_t lx = 1, ly = 1;
    if (exr_get_tile_descriptor(ctx, 0, &xs, &ys, &lm, &rm) != EXR_ERR_SUCCESS ||
        exr_get_tile_levels(ctx, 0, &lx, &ly) != EXR_ERR_SUCCESS || lx < 1 || ly < 1 ||
        lx > 64 || ly > 64)
        return st_fail(e, ST_EFORMAT, "%s: bad tile description", path);
    if (lm == EXR_TILE_RIPMAP_LEVELS) {
        if (ripmap_chunks_inside(ctx, src))
            return st_fail(e, ST_EFORMAT, "%s: truncated or corrupt: a chunk of the ripmap is "
                           "not inside the file", path);
        ly = 1; /* the rip levels (x, 0) are still checked through the library below */
    }
    for (int32_t vy = 0; vy < ly; vy++)
        for (int32_t vx = 0; vx < lx; vx++) {
            if (lm != EXR_TILE_RIPMAP_LEVELS && vx != vy)
                continue;
            int32_t lw, lh, tw, th;
            if (exr_get_level_sizes(ctx, 0, vx, vy, &lw, &lh) != EXR_ERR_SUCCESS ||
                exr_get_tile_sizes(ctx, 0, vx, vy, &tw, &th) != EXR_ERR_SUCCESS || tw < 1 ||
                th < 1 || lw < 1 || lh < 1)
                return st_fail(e, ST_EFORMAT, "%s: bad level %d,%d", path, vx, vy);
            int32_t ntx = (lw + tw - 1) / tw, nty = (lh + th - 1) / th;
            for (int32_t ty = 0; ty < nty; ty++)
                for (int32_t tx = 0; tx < ntx; tx++) {
                    exr_chunk_info_t ci;
                    if (exr_read_tile_chunk_info(ctx, 0, tx, ty, vx, vy, &ci) != EXR_ERR_SUCCESS ||
                        ci.data_offset > fsize || ci.packed_size > fsize - ci.data_offset)
                        return st_fail(e, ST_EFORMAT,
                                       "%s: truncated or corrupt: tile %d,%d of level %d,%d is "
                                       "not inside the file", path, tx, ty, vx, vy);
                }
        }
    return ST_OK;
}

/* Reads part 0 of the file opened with init (the library's own file I/O, or a memory
 * stream); path names it in messages; src gives its bytes and size (the ripmap check reads the chunk table). */
static int read_with(const char *path, exr_context_initializer_t *init, const raw_src *src,
                     const st_image_caps *caps, st_image *out, st_error *e)
{
    memset(out, 0, sizeof *out);
    init->error_handler_fn = quiet_handler;
    exr_context_t ctx = NULL;
    exr_result_t r = exr_start_read(&ctx, path, init);
    if (r != EXR_ERR_SUCCESS) {
        exr_finish(&ctx);
        return st_fail(e, r == EXR_ERR_FILE_ACCESS ? ST_ENOTFOUND : ST_EFORMAT,
                       "%s: not a readable OpenEXR file: %s", path, exr_get_error_code_as_string(r));
    }
    int rc = ST_OK;
    exr_job j;
    memset(&j, 0, sizeof j);
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *chl = NULL;
    if (exr_get_data_window(ctx, 0, &dw) != EXR_ERR_SUCCESS ||
        exr_get_channels(ctx, 0, &chl) != EXR_ERR_SUCCESS || !chl || chl->num_channels < 1) {
        rc = st_fail(e, ST_EFORMAT, "%s: no data window or channels", path);
        goto done;
    }
    int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
    uint32_t maxdim = caps && caps->max_dim ? caps->max_dim : ST_MAX_DIM;
    if (w < 1 || h < 1) {
        rc = st_fail(e, ST_EFORMAT, "%s: empty data window", path);
        goto done;
    }
    if (w > maxdim || h > maxdim) {
        rc = st_fail(e, ST_ETOOBIG, "%s: %lldx%lld is over the %u per-axis cap", path,
                     (long long)w, (long long)h, maxdim);
        goto done;
    }
    j.x0 = dw.min.x;
    j.y0 = dw.min.y;
    j.w = (int32_t)w;
    j.h = (int32_t)h;
    /* channel selection by name (the list is sorted alphabetically): R,G,B,A of the default
     * layer, else of the first layer that has a ".R" (e.g. "diffuse.R"), else X,Y,Z of the
     * first Y's layer when it has an X, else Y (with its A) */
    static const char *rgba[4] = {"R", "G", "B", "A"};
    char layer[64] = "";
    int alpha = -1;
    for (int pass = 0; pass < 2 && j.nsel == 0; pass++) {
        if (pass == 1) {
            for (int c = 0; c < chl->num_channels && !layer[0]; c++) {
                const char *nm = chl->entries[c].name.str;
                size_t l = strlen(nm);
                if (l >= 3 && l - 2 < sizeof layer && !strcmp(nm + l - 2, ".R")) {
                    memcpy(layer, nm, l - 1); /* keeps the dot */
                    layer[l - 1] = 0;
                }
            }
            if (!layer[0])
                break;
        }
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < chl->num_channels; c++) {
                const char *nm = chl->entries[c].name.str;
                size_t ll = strlen(layer);
                if (!strncmp(nm, layer, ll) && !strcmp(nm + ll, rgba[k])) {
                    if (k == 3)
                        alpha = j.nsel;
                    j.chan_idx[j.nsel++] = c;
                }
            }
        /* an A without R, G or B is not a colour image: Y + A (a grey image with alpha) and
         * Y, RY, BY, A (luminance/chroma) are decided below; taking A alone would import a
         * YA file as its alpha and let a chroma file through as grey */
        if (j.nsel == 1 && alpha == 0) {
            j.nsel = 0;
            alpha = -1;
        }
    }
    if (j.nsel == 0) {
        /* Luminance/chroma images (OpenEXR's RgbaOutputFile with WRITE_YC: Y plus RY, BY,
         * the chroma usually subsampled 2x2) need OpenEXR's chroma reconstruction filter and
         * its Y/RY/BY -> RGB matrix; taking Y alone would silently turn a colour image grey,
         * so such a file is refused with a clear reason (a Y-only file is grey and is read). */
        for (int c = 0; c < chl->num_channels; c++) {
            const char *nm = chl->entries[c].name.str;
            size_t l = strlen(nm);
            if (!strcmp(nm, "RY") || !strcmp(nm, "BY") ||
                (l >= 3 && (!strcmp(nm + l - 3, ".RY") || !strcmp(nm + l - 3, ".BY")))) {
                /* EFORMAT, not EUNSUPPORTED: that one sends the file on to OIIO's reader */
                rc = st_fail(e, ST_EFORMAT,
                             "%s: a luminance/chroma (Y, RY, BY) OpenEXR image is not "
                             "supported; write it as R, G, B channels", path);
                goto done;
            }
        }
        int y = -1;
        for (int c = 0; c < chl->num_channels; c++) {
            const char *nm = chl->entries[c].name.str;
            size_t l = strlen(nm);
            if (y < 0 && (!strcmp(nm, "Y") || (l >= 2 && !strcmp(nm + l - 2, ".Y"))))
                y = c;
        }
        /* a Y beside an X of its layer is a vector's component (a position or normal map,
         * CIE XYZ), not luminance: the layer's X, Y and Z (if any) in that order, no alpha
         * (taking Y alone made a grey image of one component). A Z without an X is depth
         * beside a luminance Y and is left out. */
        int xyz[3] = {-1, y, -1};
        if (y >= 0) {
            const char *yn = chl->entries[y].name.str;
            size_t pl = strlen(yn) - 1;
            for (int c = 0; c < chl->num_channels; c++) {
                const char *nm = chl->entries[c].name.str;
                if (strlen(nm) == pl + 1 && !strncmp(nm, yn, pl) && (nm[pl] == 'X' || nm[pl] == 'Z'))
                    xyz[nm[pl] == 'X' ? 0 : 2] = c;
            }
        }
        if (xyz[0] >= 0) {
            for (int k = 0; k < 3; k++)
                if (xyz[k] >= 0)
                    j.chan_idx[j.nsel++] = xyz[k];
            y = -2; /* selected: no alpha, no file-order fallback */
        } else
            j.chan_idx[j.nsel++] = y >= 0 ? y : 0;
        if (y >= 0) {
            /* Y's alpha: "A" next to "Y", "<layer>.A" next to "<layer>.Y" */
            const char *yn = chl->entries[y].name.str;
            size_t pl = strlen(yn) - 1;
            for (int c = 0; c < chl->num_channels; c++) {
                const char *nm = chl->entries[c].name.str;
                if (strlen(nm) == pl + 1 && !strncmp(nm, yn, pl) && nm[pl] == 'A') {
                    alpha = 1;
                    j.chan_idx[j.nsel++] = c;
                    break;
                }
            }
        }
        if (y == -1 && chl->num_channels > 1) {
            /* no RGB(A)/Y names: take up to 4 channels in file order */
            j.nsel = 0;
            for (int c = 0; c < chl->num_channels && j.nsel < 4; c++)
                j.chan_idx[j.nsel++] = c;
        }
    }
    for (int k = 0; k < j.nsel; k++) {
        const exr_attr_chlist_entry_t *ce = &chl->entries[j.chan_idx[k]];
        if (ce->x_sampling != 1 || ce->y_sampling != 1) {
            rc = st_fail(e, ST_EUNSUPPORTED, "%s: channel %s is subsampled (%d x %d), which is "
                         "not read", path, ce->name.str, ce->x_sampling, ce->y_sampling);
            goto done;
        }
    }
    int allhalf = 1;
    for (int k = 0; k < j.nsel; k++)
        if (chl->entries[j.chan_idx[k]].pixel_type != EXR_PIXEL_HALF)
            allhalf = 0;
    j.out_dt = allhalf ? ST_DT_HALF : ST_DT_F32;
    j.cs = st_dtype_size(j.out_dt);
    size_t plane = st_image_bytes((uint32_t)w, (uint32_t)h, 1, j.out_dt, caps);
    size_t total = st_image_bytes((uint32_t)w, (uint32_t)h, (unsigned)j.nsel, j.out_dt, caps);
    if (!plane || !total || total > (caps && caps->max_bytes ? caps->max_bytes : (size_t)1 << 31) / 2) {
        rc = st_fail(e, ST_ETOOBIG, "%s: %lldx%lld x %d channels is over the byte cap", path,
                     (long long)w, (long long)h, j.nsel);
        goto done;
    }
    for (int k = 0; k < j.nsel; k++) {
        j.planes[k] = calloc(1, plane);
        if (!j.planes[k]) {
            rc = st_fail(e, ST_ENOMEM, "%s: out of memory for %zu bytes", path, plane);
            goto done;
        }
    }
    if ((rc = read_part(ctx, path, &j, e)) != ST_OK ||
        (rc = tiled_chunks_inside(ctx, path, src, e)) != ST_OK)
        goto done;
    uint8_t *data = malloc(total);
    if (!data) {
        rc = st_fail(e, ST_ENOMEM, "%s: out of memory for %zu bytes", path, total);
        goto done;
    }
    size_t npx = (size_t)w * (size_t)h;
    for (size_t p = 0; p < npx; p++)
        for (int k = 0; k < j.nsel; k++)
            memcpy(data + (p * j.nsel + k) * j.cs, j.planes[k] + p * j.cs, j.cs);
    out->w = (uint32_t)w;
    out->h = (uint32_t)h;
    out->nchan = (uint8_t)j.nsel;
    out->dtype = (uint8_t)j.out_dt;
    out->colorspace = ST_CS_LINEAR;
    out->alpha_chan = (int8_t)alpha;
    out->premultiplied = alpha >= 0; /* OpenEXR stores colour premultiplied by alpha */
    out->data = data;
    const exr_attribute_t *env = NULL;
    if (exr_get_attribute_by_name(ctx, 0, "envmap", &env) == EXR_ERR_SUCCESS && env &&
        env->type == EXR_ATTR_ENVMAP)
        out->envmap = env->uc == EXR_ENVMAP_CUBE ? ST_ENVMAP_CUBE : ST_ENVMAP_LATLONG;
    int32_t lx = 1, ly = 1;
    exr_storage_t st;
    if (exr_get_storage(ctx, 0, &st) == EXR_ERR_SUCCESS && st == EXR_STORAGE_TILED &&
        exr_get_tile_levels(ctx, 0, &lx, &ly) == EXR_ERR_SUCCESS)
        out->nlevels_file = (uint8_t)(lx > 0 && lx < 64 ? lx : 1);
    else
        out->nlevels_file = 1;
done:
    for (int k = 0; k < 4; k++)
        free(j.planes[k]);
    exr_finish(&ctx);
    return rc;
}

int st_exr_read(const char *path, const st_image_caps *caps, st_image *out, st_error *e)
{
    struct stat sb;
    if (stat(path, &sb) != 0) {
        memset(out, 0, sizeof *out);
        return st_fail(e, ST_ENOTFOUND, "%s: not a readable OpenEXR file: cannot stat", path);
    }
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    raw_src src = {path, NULL, (uint64_t)sb.st_size};
    return read_with(path, &init, &src, caps, out, e);
}

/* A memory stream for the OpenEXR C API: pread semantics on a caller-owned buffer. */
typedef struct mem_stream {
    const uint8_t *buf;
    size_t         len;
} mem_stream;

static int64_t mem_read(exr_const_context_t ctx, void *user, void *dst, uint64_t sz,
                        uint64_t off, exr_stream_error_func_ptr_t err)
{
    (void)ctx;
    (void)err;
    const mem_stream *m = user;
    if (off >= m->len)
        return 0;
    uint64_t n = m->len - off < sz ? m->len - off : sz;
    memcpy(dst, m->buf + off, (size_t)n);
    return (int64_t)n;
}

static int64_t mem_size(exr_const_context_t ctx, void *user)
{
    (void)ctx;
    return (int64_t)((const mem_stream *)user)->len;
}

int st_exr_read_mem(const void *buf, size_t len, const char *name, const st_image_caps *caps,
                    st_image *out, st_error *e)
{
    mem_stream m = {buf, len};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &m;
    init.read_fn = mem_read;
    init.size_fn = mem_size;
    raw_src src = {NULL, buf, (uint64_t)len};
    return read_with(name ? name : "(memory)", &init, &src, caps, out, e);
}
