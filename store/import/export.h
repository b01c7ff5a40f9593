/* store/import/export.h - every kind of set out as a standard file that uploads back to an
 * equivalent set (FETCH, `seamtex fetch`).
 *
 * Owns: the table of which format fits which set kind, and the writers' dispatch:
 *
 *   set kind                 format  what is written                         uploads back as
 *   per-face (Ptex)          PTX     the set as .ptx (ptex/ptex_write.c)     the same set
 *   cube                     PTX     a Ptex environment cube (6 faces in     the same cube (its
 *                                    Ptex's env-cube layout), any texel type  layout is detected)
 *   cube, half or float      EXR     an OpenEXR cube (6 faces stacked        the same cube
 *                                    +X..-Z, envmap=cube)
 *   atlas, u8 or u16         PNG     the atlas image at its precision         an atlas image set
 *   atlas, half or float     EXR     the atlas image at its precision         an atlas image set
 *   atlas with a mesh        OBJ     the mesh: v, vt, f (triangles)           with texture=<the
 *                                                                              image set>: the atlas
 *   BC1                      DDS     the BC1 set (bc1/dds.c)                  the same BC1 set
 *
 * Alpha: an EXR carries the set's (grey + alpha as Y, A; no alpha: none); a PNG has no 2- or
 * 4-channel form without alpha, so such a u8 / u16 set without one comes back with its last
 * channel as alpha, and a premultiplied one (associated-alpha TIFF) comes back flagged straight.
 *
 * Does not own: the writers themselves (ptex/, bc1/dds.c, image_io.h). Images go through a
 * temp file in the caller's folder (OpenImageIO writes files), removed before returning; the
 * file must read back as the image (same size) before its bytes are handed out: OpenImageIO
 * 2.4 reports success for a file a full disk cut short (ST_EIO, "No space left on device").
 * Every format's bytes are a function of the set alone (no time stamp: image_io.h).
 *
 * Ownership: *buf is malloc'ed; the caller frees it.
 */
#ifndef ST_EXPORT_H
#define ST_EXPORT_H

#include <stddef.h>

#include "set.h"

typedef enum st_export_format {
    ST_EXPORT_PTX = 0,
    ST_EXPORT_DDS = 1,
    ST_EXPORT_EXR = 2,
    ST_EXPORT_PNG = 3,
    ST_EXPORT_OBJ = 4,
    ST_EXPORT_COUNT
} st_export_format;

/* Bit (1 << format) set for every format that fits s. */
unsigned st_export_formats(const st_set *s);

/* "ptx", "dds", "exr", "png", "obj"; NULL for an unknown format. */
const char *st_export_format_name(int format);

/* Serialises s in `format` into *buf (*len bytes). tmpdir (NULL: $TMPDIR or /tmp) is where
 * image writers put their temp file. ST_EUNSUPPORTED, naming the formats that fit, when the
 * format does not fit the set. */
int st_export_mem(const st_set *s, int format, const char *tmpdir, void **buf, size_t *len,
                  st_error *e);

#endif
