/* store/service/defaultset.h - the built-in data set the daemon loads at start as set "default".
 *
 * Owns: its recipe. A cube subdivided 8 x 8 per side (384 quad faces, random frame rotations
 * so every edge rotation occurs), RGBA8, per-face sizes drawn in 16..64 per axis, baked from a
 * smooth procedural colour of the 3D position with a high-frequency stripe pattern on top (so
 * any seam shows), with mip chains, prepared for the Ptex filter family too (ptexfilter.h:
 * levels past the square reductions follow Ptex's u/v reductions). Deterministic: the same bytes on every run.
 * Does not own: the set layout (set.h), the mesh builder (quadmesh.h).
 */
#ifndef ST_DEFAULTSET_H
#define ST_DEFAULTSET_H

#include "set.h"

#define ST_DEFAULT_SET_N     8     /* subdivisions per cube side */
#define ST_DEFAULT_SET_SEED  20131u

/* The procedural colour at 3D point P (RGBA, 0..1); tests compare samples against it. */
void st_default_set_color(const float P[3], float rgba[4]);

/* Builds the default set; the caller owns *out (st_set_free). */
int st_default_set(st_set **out, st_error *e);

#endif
