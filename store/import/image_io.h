/* store/import/image_io.h - reading and writing 2D images through OpenImageIO and OpenEXR.
 *
 * Owns: st_image_read (OpenImageIO, image_oiio.cpp), st_image_read_any (picks OpenEXR's C API
 * for EXR files, exr.c), st_image_write. Does not own: the st_image type and its caps
 * (core/image.h), texture sets (import.h turns images into sets).
 *
 * Ownership: a read fills a caller-owned st_image whose data the caller frees with
 * st_image_free (core/image.h); a read that fails leaves it empty (data NULL).
 */
#ifndef ST_IMAGE_IO_H
#define ST_IMAGE_IO_H

#include "image.h"

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
 * A PNG or EXR is a function of the texels and the attributes given (an EXR's `capDate` is
 * written empty, not the wall clock OpenImageIO would stamp), so FETCH is byte-stable.
 * ST_EUNSUPPORTED when OIIO cannot write that format (e.g. .dds). */
int st_image_write(const char *path, uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                   const void *data, st_error *e);

/* As st_image_write (which takes the last of 2 or 4 channels as alpha), for a whole st_image:
 * also records its colour space (sRGB or linear), its envmap kind (an EXR cube strip gets
 * envmap=cube, so it reads back as a cube) and its alpha channel (none: none, except in a PNG,
 * which has no 2- or 4-channel form without alpha; an EXR of grey + alpha has channels Y, A). */
int st_image_write_img(const char *path, const st_image *img, st_error *e);

#endif
