/* store/image.h - 2D images read from and written to files, for importers and tools.
 *
 * Owns: st_image (one level, interleaved, rows top first), reading through OpenImageIO
 * (image_oiio.cpp: PNG, JPEG, TIFF, HDR, TGA, BMP, ... whatever the installed OIIO reads),
 * reading OpenEXR through its C API (exr.c, see exr.h), writing through OpenImageIO.
 * Does not own: texture sets (import.h turns images into sets), cube layouts (cube.h).
 *
 * Precision is kept: 8-bit -> ST_DT_U8, 16-bit -> ST_DT_U16, half -> ST_DT_HALF, 32-bit
 * float -> ST_DT_F32; other formats (int32, double, 10/12-bit packed) are converted to the
 * nearest of these (float for anything wider than 16 bits). More than 4 channels: the first
 * R,G,B,A by name (else the first 4). Colour space: "sRGB" for 8-bit files that OIIO reports
 * as sRGB (or unknown 8/16-bit PNG/JPEG/TIFF/BMP), linear for float/half and HDR/EXR.
 *
 * Caps: dimensions and bytes are checked against st_image_caps BEFORE any texel allocation.
 *
 * Ownership: st_image_read fills a caller-owned st_image whose `data` is malloc'ed; the caller
 * frees it with st_image_free (or free(img.data)). No globals, no OIIO in hot paths; OIIO is
 * only touched inside image_oiio.cpp.
 */
#ifndef ST_IMAGE_H
#define ST_IMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"

enum st_envmap { ST_ENVMAP_NONE = 0, ST_ENVMAP_LATLONG = 1, ST_ENVMAP_CUBE = 2 };

typedef struct st_image {
    uint32_t w, h;
    uint8_t  nchan;        /* 1..4 */
    uint8_t  dtype;        /* st_dtype (set.h) */
    uint8_t  colorspace;   /* st_colorspace */
    int8_t   alpha_chan;   /* -1 none */
    uint8_t  envmap;       /* st_envmap: from EXR's envmap attribute / OIIO's textureformat */
    uint8_t  nlevels_file; /* mip levels the file holds (information only; level 0 is read) */
    void    *data;         /* w*h*nchan*dtype_size bytes, rows top first, channels interleaved */
} st_image;

typedef struct st_image_caps {
    uint32_t max_dim;      /* per axis; 0 = 32768 (ST_MAX_DIM) */
    size_t   max_bytes;    /* decoded bytes; 0 = 2 GiB */
} st_image_caps;

/* Reads level 0 of the first subimage of any file OpenImageIO reads (EXR files are better
 * read with st_exr_read, which st_image_read_any picks by magic). ST_ENOTFOUND when the file
 * does not exist, ST_EFORMAT when no reader accepts it or it is truncated, ST_ETOOBIG over
 * the caps. */
int st_image_read(const char *path, const st_image_caps *caps, st_image *out, st_error *e);

/* Picks st_exr_read for files starting with the OpenEXR magic, st_image_read otherwise (and
 * for EXR files whose compression the OpenEXR 3.1 C API cannot decode, e.g. DWAB). */
int st_image_read_any(const char *path, const st_image_caps *caps, st_image *out, st_error *e);

/* Writes w x h x nchan texels of dtype (rows top first, interleaved) to path; the format
 * comes from the extension (.png for 8/16-bit, .exr for half/float, .tif, .hdr, .jpg...).
 * ST_EUNSUPPORTED when OIIO cannot write that format (e.g. .dds). */
int st_image_write(const char *path, uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                   const void *data, st_error *e);

/* Frees img->data and zeroes the struct; NULL accepted. */
void st_image_free(st_image *img);

/* Bytes of w*h*nchan texels of dtype, overflow- and cap-checked (0 on overflow / over cap). */
size_t st_image_bytes(uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                      const st_image_caps *caps);

#endif
