/* store/import/import.h - the import dispatcher: a file on disk -> a texture set.
 *
 * Owns: format detection (magic first, extension second), caps, and the choice of reader:
 *   - Ptex .ptx (magic "Ptex")                      -> per-face set (ptex.h); an environment
 *     cube (.penv, a 6-face .ptx whose adjacency is Ptex's env-cube layout, or any 6-face file
 *     with ST_IMPORT_CUBE_PTEX) -> cube set
 *   - OpenEXR (magic 76 2f 31 01)                    -> exr.h (OIIO for DWAA/DWAB, which the
 *     OpenEXR 3.1 C API does not decode); envmap=cube -> cube set,
 *     envmap=latlong -> atlas set unless a cube conversion is asked for
 *   - PNG, JPEG, TIFF, HDR, TGA, BMP, ... (OIIO)     -> atlas set (one face, any w x h)
 *   - OBJ (.obj) / Draco (.drc, magic "DRACO")      -> a mesh, paired with o->texture to give
 *     an atlas set; without a texture: the mesh's first map_Kd (OBJ) is loaded when found,
 *     else ST_EINVAL ("a mesh needs a texture"). A mesh without UVs: ST_ENOUV.
 *   - DDS (magic "DDS ", BC1/DXT1 only)             -> a BC1 set (bc1.h: st_dds_read_file), with
 *     its adjacency, faces and cube layout when seamtex wrote it; other DDS formats are refused
 *   - cube conversions (o->cube): six files, strips, crosses, lat-long -> cube set.
 * Does not own: the readers themselves, the set layout, the registry or the data dir.
 *
 * Caps: max_bytes bounds the file size read and the set's texel arena; max_dim bounds each
 * image axis. Both are checked before texel memory is allocated.
 *
 * Ownership: *out is a new set the caller frees with st_set_free. No globals; any thread may
 * import (OpenImageIO is thread-safe for separate files).
 */
#ifndef ST_IMPORT_H
#define ST_IMPORT_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

typedef enum st_import_format {
    ST_FMT_AUTO  = 0,
    ST_FMT_PTEX  = 1,
    ST_FMT_EXR   = 2,
    ST_FMT_IMAGE = 3,   /* anything OpenImageIO reads */
    ST_FMT_OBJ   = 4,
    ST_FMT_DRACO = 5,
    ST_FMT_DDS   = 6    /* BC1 (DXT1) DDS, as dds.c reads it (bc1.h) */
} st_import_format;

typedef enum st_import_cube {
    ST_IMPORT_CUBE_NONE    = 0,  /* keep the file as it is (EXR envmap=cube still -> cube) */
    ST_IMPORT_CUBE_AUTO    = 1,  /* an image whose aspect ratio fits a layout becomes a cube */
    ST_IMPORT_CUBE_STRIP_V = 2,
    ST_IMPORT_CUBE_STRIP_H = 3,
    ST_IMPORT_CUBE_CROSS_H = 4,
    ST_IMPORT_CUBE_CROSS_V = 5,
    ST_IMPORT_CUBE_LATLONG = 6,  /* resampled to face_size */
    ST_IMPORT_CUBE_SIX     = 7,  /* path is a pattern containing "%s", replaced by
                                    +x -x +y -y +z -z (or face_names) */
    ST_IMPORT_CUBE_PTEX    = 8   /* a 6-face Ptex file is an environment cube */
} st_import_cube;

typedef enum st_import_cs {
    ST_IMPORT_CS_AUTO   = 0,     /* from the file (see image.h) */
    ST_IMPORT_CS_LINEAR = 1,
    ST_IMPORT_CS_SRGB   = 2
} st_import_cs;

typedef struct st_import_opts {
    uint8_t  format;            /* st_import_format, ST_FMT_AUTO = detect */
    uint8_t  cube;              /* st_import_cube */
    uint8_t  six_conv;          /* st_cube_faces_conv for ST_IMPORT_CUBE_SIX */
    uint8_t  colorspace;        /* st_import_cs */
    uint32_t face_size;         /* lat-long -> cube face size (power of two), 0 = auto */
    const char *face_names[6];  /* for ST_IMPORT_CUBE_SIX; NULL entries = "+x" ... "-z" */
    const st_set *texture;      /* an atlas set to pair a mesh with (copied), may be NULL */
    const char *texture_path;   /* or an image file to pair a mesh with, may be NULL */
    size_t   max_bytes;         /* cap on input file bytes and set texels; 0 = default */
    uint32_t max_dim;           /* cap per image axis; 0 = ST_MAX_DIM */
    uint8_t  no_side_files;     /* 1: open no file the input names (an OBJ's mtllib / map_Kd);
                                   the daemon's uploads, whose folder holds other clients'
                                   uploads: a mesh there pairs only with texture= */
    uint8_t  cube_lenient;      /* 1: a cube kind a Ptex file or a mesh cannot take is ignored
                                   (the file imported as without it), as before session 32;
                                   0 (default): ST_EINVAL. For files recorded with their options
                                   before the check (a data dir's manifests) */
} st_import_opts;

/* Fills o with defaults (everything auto / zero). */
void st_import_opts_init(st_import_opts *o);

/* The upload options string (PROTOCOL.md, "Upload options"), parsed strictly:
 *   options   = "" | option *(" " option)          one space between options, none around
 *   option    = "cube=" kind [":" size] | "colorspace=" ("auto" | "srgb" | "linear")
 *             | "texture=" name
 *   kind      = "none" | "auto" | "strip_v" | "strip_h" | "cross_h" | "cross_v" | "latlong"
 *             | "ptex"
 *   size      = a power of two 1..32768 in decimal, no sign or leading zero (latlong only)
 * Each key at most once. Fills o->cube, o->face_size, o->colorspace; copies the texture set's
 * name (1..255 bytes, checked by the caller against the set-name rule) into texture (cap
 * bytes, "" when absent). ST_EINVAL with a message naming the option at fault; o is changed
 * only on success. */
int st_import_opts_parse(const char *text, st_import_opts *o, char *texture, size_t cap,
                         st_error *e);

/* Detects the format of a buffer (first bytes) and, as a fallback, the file name's extension.
 * Returns an st_import_format, ST_FMT_AUTO when unknown. */
int st_import_detect(const void *head, size_t len, const char *name);

/* Imports the file at path (o may be NULL = defaults). */
int st_import_file(const char *path, const st_import_opts *o, st_set **out, st_error *e);

/* Names for logs and the protocol ("ptex", "exr", "image", "obj", "draco"). */
const char *st_import_format_name(int fmt);

#endif
