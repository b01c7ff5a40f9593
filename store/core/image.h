/* store/core/image.h - the 2D image type that importers fill and set builders read.
 *
 * Owns: st_image (one level, interleaved, rows top first), its caps and byte count, freeing it
 * (image.c). Does not own: reading and writing files (import/image_io.h: OpenImageIO for PNG,
 * JPEG, TIFF, HDR, TGA, BMP, ..., OpenEXR through its C API), texture sets (import.h turns
 * images into sets), cube layouts (kinds/cube.h).
 *
 * Precision is kept: 8-bit -> ST_DT_U8, 16-bit -> ST_DT_U16, half -> ST_DT_HALF, 32-bit
 * float -> ST_DT_F32; other formats (int32, double, 10/12-bit packed) are converted to the
 * nearest of these (float for anything wider than 16 bits); signed 8/16-bit data -> float
 * (-1..1, OpenImageIO's normalisation: u8/u16 would clamp the negative half to 0). More than 4 channels: the first
 * R,G,B,A by name (else the first 4). Colour space: "sRGB" for 8-bit files that OIIO reports
 * as sRGB (or unknown 8/16-bit PNG/JPEG/TIFF/BMP), linear for float/half and HDR/EXR.
 *
 * Caps: dimensions and bytes are checked against st_image_caps BEFORE any texel allocation.
 *
 * Ownership: st_image_read fills a caller-owned st_image whose `data` is malloc'ed; the caller
 * frees it with st_image_free (or free(img.data)). No globals, no OIIO in hot paths; OIIO is
 * only touched inside import/image_oiio.cpp.
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
    uint8_t  premultiplied; /* 1: colour is stored premultiplied by alpha_chan (EXR with alpha,
                              associated-alpha TIFF); texels are never converted */
    void    *data;         /* w*h*nchan*dtype_size bytes, rows top first, channels interleaved */
} st_image;

typedef struct st_image_caps {
    uint32_t max_dim;      /* per axis; 0 = 32768 (ST_MAX_DIM) */
    size_t   max_bytes;    /* decoded bytes; 0 = 2 GiB */
} st_image_caps;


/* Frees img->data and zeroes the struct; NULL accepted. */
void st_image_free(st_image *img);

/* Bytes of w*h*nchan texels of dtype, overflow- and cap-checked (0 on overflow / over cap). */
size_t st_image_bytes(uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                      const st_image_caps *caps);

#endif
