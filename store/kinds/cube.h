/* store/kinds/cube.h - cube maps: 6-face sets with fixed adjacency, direction lookup, conversions
 * from strips, crosses, six images and lat-long images, and Castano's edge-fixup.
 *
 * Owns: the cube face order and frames, the adjacency table, direction <-> (face, u, v),
 * st_cube_sample_dir (a batch front end to st_sample_batch), building cube sets from images
 * (cube.c, cube_convert.c), baking and exporting edge-fixup faces. Does not own: filtering
 * (sample.h), file decoding (image.h, exr.h, ptex.h).
 *
 * Face order and frames (the OpenEXR envmap=cube convention, ImfEnvmap): face f holds the
 * direction seen when looking from the centre of the cube; the stored face image is the one
 * OpenEXR stacks in its vertical strip, rows top first. With s = 2u - 1 and t = 2v - 1
 * (u right, v down in the stored image, texel centres at (i + .5) / n):
 *
 *   face 0  +X   dir = ( 1, -t,  s)        face 3  -Y   dir = ( s, -1,  t)
 *   face 1  -X   dir = (-1, -t, -s)        face 4  +Z   dir = (-s, -t,  1)
 *   face 2  +Y   dir = ( s,  1, -t)        face 5  -Z   dir = ( s, -t, -1)
 *
 * Every face has du x dv pointing out of the cube, so the faces are consistently oriented
 * (Ptex: a shared edge runs in opposite directions in its two faces) and the sampler's
 * Traverse mode works across the 12 edges; each of the 8 corners has valence 3.
 * Adjacency (edge e: 0 v=0, 1 u=1, 2 v=1, 3 u=0; "face:edge" across it):
 *
 *   +X: 2:1 4:3 3:1 5:1    -X: 2:3 5:3 3:3 4:1    +Y: 4:0 0:0 5:0 1:0
 *   -Y: 5:2 0:2 4:2 1:2    +Z: 2:0 1:3 3:2 0:1    -Z: 2:2 0:3 3:0 1:1
 *
 * OpenEXR itself maps pixel centres 0 and n-1 to the face edges (+-1), i.e. its cube files
 * are "edge-fixup baked" in Castano's sense; seamtex uses texel centres ((i + .5) / n, the GPU
 * convention). Sampling an OpenEXR cube with ST_CUBE_LOOKUP_FIXUP reproduces OpenEXR's own
 * lookup; the plain lookup differs by at most half a texel at the face edges.
 *
 * Lat-long images follow OpenEXR too: column x <-> longitude atan2(dx, dz) = -2 pi (x/(W-1) - .5),
 * row y <-> latitude asin(dy) = -pi (y/(H-1) - .5): +Y at the top row, +Z in the middle column,
 * +X at a quarter of the width.
 *
 * Ownership: builders return a new set the caller frees with st_set_free. The sampler entry
 * point allocates nothing and may be called from many threads on the same set.
 */
#ifndef ST_CUBE_H
#define ST_CUBE_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "image.h"
#include "sample.h"
#include "set.h"

enum { ST_CUBE_PX = 0, ST_CUBE_NX = 1, ST_CUBE_PY = 2, ST_CUBE_NY = 3, ST_CUBE_PZ = 4,
       ST_CUBE_NZ = 5 };

/* Creates an empty (zeroed) cube set: 6 faces of n x n (n a power of two, 1..ST_MAX_DIM),
 * kind ST_KIND_CUBE, the adjacency above. info supplies nchan, dtype, colorspace, alpha. */
int st_cube_create(const st_set_info *info, uint32_t n, size_t max_bytes, st_set **out,
                   st_error *e);

/* Creates an empty 6-face set of n x n faces (n a power of two) of the given kind with the
 * given adjacency (neighbour face and edge across edge k of face f): the cube layout above,
 * or Ptex's environment-cube layout (st_cube_to_ptex_env). */
int st_cube_six_faces(const st_set_info *info, uint32_t n, unsigned kind,
                      const int32_t adjf[6][4], const int8_t adje[6][4], size_t max_bytes,
                      st_set **out, st_error *e);

/* Direction of face f at (u, v) (not normalised; the major component is +-1). */
void st_cube_face_dir(unsigned face, float u, float v, float dir[3]);

/* Face and (u, v) in [0,1]^2 of a direction. Returns the face 0..5, or -1 for a zero,
 * NaN or infinite direction. */
int st_cube_dir_to_face(const float dir[3], float *u, float *v);

/* Castano's edge-fixup of a direction for a face of n texels at level lod (0 = level 0):
 * the two components other than the major axis (ties: x, then y, the face rule) are scaled
 * by 1 - 2^lod / n ((n-1)/n at lod 0); at an exact tie (a cube edge or corner) the tied
 * component is scaled too, so the lookup lands where OpenEXR's does. */
void st_cube_fixup_dir(const float dir[3], float n, float lod, float out[3]);

enum st_cube_lookup {
    ST_CUBE_LOOKUP_PLAIN = 0,   /* texel-centre convention (GPU cube maps) */
    ST_CUBE_LOOKUP_FIXUP = 1    /* Castano's edge-fixup lookup, for faces baked with edge
                                   fixup (st_cube_bake_fixup, OpenEXR cube files); lod from
                                   the footprint (or 0 for point/bilinear) */
};

/* One direction query: dir (any length > 0) and a footprint given either as a cone angle
 * (full apex angle in radians, > 0) or, when cone == 0, as the direction derivatives
 * ddx and ddy (same units as dir; zero derivatives = a point lookup). A negative cone is
 * neither: its query gets ST_Q_BAD_FOOTPRINT. */
typedef struct st_cube_query {
    float dir[3];
    float cone;
    float ddx[3], ddy[3];
} st_cube_query;

/* Maps every query to (face, u, v, footprint) and samples with st_sample_batch in chunks
 * (no allocation). cube: any set st_cube_is_cube accepts, BC1 cubes included. Arguments and
 * results as st_sample_batch: out n * nchan floats, coverage and status (out required, the
 * other two may be NULL). A zero / non-finite direction gets ST_Q_NONFINITE, a negative cone
 * ST_Q_BAD_FOOTPRINT. Returns the
 * number of queries not ST_Q_OK, or a negative ST_E* code (nothing written). lookup is an
 * st_cube_lookup. Traverse mode gives seamless filtering across edges and corners; Clamp
 * shows the seams; Discard renormalises inside the face. */
int st_cube_sample_dir(const st_set *cube, const st_sample_opts *o, unsigned lookup,
                       const st_cube_query *q, size_t n, float *out, float *coverage,
                       uint8_t *status);

/* 1 when s can be sampled by direction: a cube set, or a BC1 set encoded from one (same
 * faces, frames and adjacency; bc1.h). */
int st_cube_is_cube(const st_set *s);

/* Converts direction queries to face queries (what st_cube_sample_dir does before sampling);
 * status gets ST_Q_NONFINITE for a bad direction or a non-finite cone / footprint,
 * ST_Q_BAD_FOOTPRINT for a negative cone (such a query is face 0, centre). */
void st_cube_queries(const st_set *cube, unsigned lookup, const st_cube_query *q, size_t n,
                     st_query *fq, uint8_t *status);

/* ---- building cube sets from images (cube_convert.c) ---------------------------------- */

typedef enum st_cube_layout {
    ST_CUBE_STRIP_V    = 0,  /* n x 6n, faces top to bottom in face order (OpenEXR envmap) */
    ST_CUBE_STRIP_H    = 1,  /* 6n x n, faces left to right in face order */
    ST_CUBE_CROSS_H    = 2,  /* 4n x 3n: row 1 = +X +Z -X -Z, +Y above and -Y below +Z */
    ST_CUBE_CROSS_V    = 3,  /* 3n x 4n: row 1 = +X +Z -X, +Y above +Z, -Y then -Z below */
    ST_CUBE_LATLONG    = 4   /* equirectangular, resampled */
} st_cube_layout;
/* In a cross, every face is placed (rotated by a multiple of 90 degrees) so that the image
 * is continuous across every internal edge of the cross when seen from inside the cube, with
 * +Y up around +Z; the exact placements are listed in docs/import.md. */

/* Face images given one per file / buffer, in face order +X -X +Y -Y +Z -Z: */
typedef enum st_cube_faces_conv {
    ST_CUBE_FACES_EXR  = 0,  /* each image is the OpenEXR face (as in the strip) */
    ST_CUBE_FACES_GL   = 1,  /* OpenGL / Direct3D cube map faces (GL spec major-axis table,
                                image row 0 = t 0); mirrored into seamtex's right-handed frame */
    ST_CUBE_FACES_GL_FLIPPED = 2  /* GL faces stored upside down (row 0 = t 1) */
} st_cube_faces_conv;

/* From one image in a layout. face_n: for ST_CUBE_LATLONG the face size wanted (power of two;
 * 0 = the power of two nearest to W/4); ignored otherwise (the layout gives n, which must be a
 * power of two). Mip levels are built by box reduction. */
int st_cube_from_image(const st_image *img, st_cube_layout layout, uint32_t face_n,
                       size_t max_bytes, st_set **out, st_error *e);

/* Guesses the layout of a single image from its aspect ratio and envmap tag: 1:6 strip_v,
 * 6:1 strip_h, 4:3 cross_h, 3:4 cross_v, 2:1 latlong; -1 when none fits. */
int st_cube_guess_layout(const st_image *img);

/* From six square images of the same size, dtype and channel count. conv outside
 * st_cube_faces_conv: ST_EINVAL. */
int st_cube_from_faces(const st_image faces[6], st_cube_faces_conv conv, size_t max_bytes,
                       st_set **out, st_error *e);

/* Builds a cube set from a per-face set of 6 faces read from a Ptex environment cube
 * (Ptex's envcube convention: face order and frames as ptex's envcube sample; faces are
 * remapped by direction to seamtex's frames). */
int st_cube_from_ptex_env(const st_set *ptex, size_t max_bytes, st_set **out, st_error *e);

/* 1 when s has 6 faces whose adjacency is exactly Ptex's environment-cube layout. */
int st_cube_is_ptex_env_layout(const st_set *s);

/* The inverse of st_cube_from_ptex_env: a 6-face per-face set in Ptex's env-cube layout and
 * frames, whose level-0 texels are the cube's own (exact copies), mips by box reduction,
 * metadata copied. Written with st_ptex_write_*, it imports back as the same cube. */
int st_cube_to_ptex_env(const st_set *cube, size_t max_bytes, st_set **out, st_error *e);

/* ---- Castano edge fixup ---------------------------------------------------------------- */

/* Bakes a new cube set whose level L texel x maps to s = 2x/(n_L - 1) - 1 (Castano's map_2,
 * per level), each texel sampled from `cube` with Traverse bilinear at that level. Sampling
 * the result with ST_CUBE_LOOKUP_FIXUP approximates sampling `cube` plainly. */
int st_cube_bake_fixup(const st_set *cube, size_t max_bytes, st_set **out, st_error *e);


/* Lays level `level` of a cube set out as one image in `layout` (strip or cross; not
 * latlong): exact texel copies; out->envmap is ST_ENVMAP_CUBE for the vertical strip (OpenEXR's
 * envmap=cube layout) and ST_ENVMAP_NONE for the others. out->data is malloc'ed; the caller
 * frees it with st_image_free. */
int st_cube_to_image(const st_set *cube, unsigned level, st_cube_layout layout, st_image *out,
                     st_error *e);

#endif
