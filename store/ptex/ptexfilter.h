/* store/ptex/ptexfilter.h - Ptex's filter family (PtexFilter::eval of the Ptex library, v2.4)
 * on seamtex sets: point, bilinear, box, gaussian, bicubic (sharpness), B-spline,
 * Catmull-Rom, Mitchell, with Ptex's footprint, level selection, kernel splitting at face
 * edges, neighbour and corner handling (Traverse) or dropped overhang with renormalisation
 * (Discard). Clamp mode clamps the kernel into the face.
 *
 * Owns: the separable kernels and their application to faces. Does not own: the set
 * (set.h), the GPU-style filters and the batch entry point (sample.c dispatches filters >= 8
 * here).
 *
 * Threading: reads the set only; no globals; any number of threads at once. The one
 * exception to "reads only": the first call on a set builds its Ptex resolution table
 * (ptexres.h; once, under the table's mutex, other callers wait for it).
 */
#ifndef ST_PTEXFILTER_H
#define ST_PTEXFILTER_H

#include <stddef.h>
#include <stdint.h>

#include "sample.h"

/* Same contract as st_sample_batch (sample.h) for o->filter in ST_FILTER_PTEX_*: n queries,
 * out n * nchan floats, coverage and status n entries each (either may be NULL). Returns
 * the number of queries whose status is not ST_Q_OK, or a negative ST_E* code for invalid
 * options, or when the resolution table cannot be built (ST_ENOMEM, ST_ETOOBIG; nothing
 * written). */
int st_ptexfilter_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                        float *out, float *coverage, uint8_t *status);

/* Prepares what the Ptex filters read (every face at every (ulog2', vlog2') resolution, as the
 * Ptex reader serves them, ptexres.h) for a per-face set that was not read from a .ptx
 * (st_ptex_read_* does it already; then this does nothing). Without it the Ptex filters
 * return ST_EUNSUPPORTED. Call before the set is shared: it rewrites the set's levels past
 * the square reductions with Ptex's own u/v reductions and attaches set->ext; the table
 * itself is built by the first Ptex-filter call. */
int st_ptexfilter_prepare(st_set *s, st_error *e);

/* Bytes the Ptex resolution table of s holds (0 when it has none; a few per face until it is
 * built); st_set_memory includes them. */
size_t st_ptexfilter_memory(const st_set *s);

#endif
