/* store/import/exr.h - OpenEXR files through OpenEXR's C API (openexr.h, OpenEXR 3.1).
 *
 * Owns: reading one part of an EXR (scanline or tiled, one level or mip-mapped: level 0 is
 * read; half, float and uint channels) into an st_image, taking R,G,B,A by channel name: of
 * the default layer, else of the first layer with a "<layer>.R" channel; else X, Y, Z of a Y's layer that has an X (a vector, no alpha); else Y (or
 * "<layer>.Y") as one channel, two with the A (or "<layer>.A") beside it (alpha_chan 1); an A
 * with no R, G or B does not hide a Y or a chroma file; else up to 4 channels in file order. Does not own: other
 * formats.
 *
 * OpenEXR 3.1.5's C API decodes 4-channel half data to interleaved float with the channel
 * order reversed; this reader therefore always decodes each channel to its own plane and
 * interleaves itself.
 *
 * Output dtype: all selected channels half -> ST_DT_HALF, else ST_DT_F32 (uint -> float).
 * The envmap attribute sets img->envmap. Caps are checked before allocating texels; files are
 * checked for truncation by the library (errors become ST_EFORMAT).
 */
#ifndef ST_EXR_H
#define ST_EXR_H

#include "image.h"

int st_exr_read(const char *path, const st_image_caps *caps, st_image *out, st_error *e);

/* The same reader on a caller-owned buffer of len bytes (an OpenEXR memory stream: the C API's
 * custom read and size functions); name is used in messages only (NULL = "(memory)"). Same
 * results as st_exr_read on a file holding those bytes. */
int st_exr_read_mem(const void *buf, size_t len, const char *name, const st_image_caps *caps,
                    st_image *out, st_error *e);

/* 1 when the first 4 bytes are the OpenEXR magic 76 2f 31 01. */
int st_exr_is_magic(const void *buf, size_t len);

#endif
