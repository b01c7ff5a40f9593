/* store/ptex/ptextri.h - Ptex's filters on triangle-mesh sets (Ptex meshtype triangle):
 * PtexPointFilterTri and PtexTriangleFilter of the Ptex library (v2.4), in Traverse, Discard
 * and Clamp.
 *
 * Ptex filters a triangle mesh with two filters only: `point` (the small triangle holding
 * (u, v), core/trilevel.h) and the triangle filter, which every other filter name maps to
 * (bilinear, box, gaussian, bicubic, bspline, catmullrom, mitchell all give its value): a
 * Gaussian over the footprint ellipse in the face's barycentric domain, eccentricity clamped
 * to 15, at least a texel wide, at the resolution of the ellipse's minor axis, split at the
 * face's edges (docs/ptex.md, "Triangle meshes").
 *
 * Owns: the triangle kernel and its pieces. Does not own: option checks shared with the quad
 * filters (st_ptexfilter_batch checks them and hands triangle sets here), the texel layout
 * and the point rule (core/trilevel.h), the set's levels (the reader fills them).
 *
 * Threading: reads the set only; no allocation, no globals.
 */
#ifndef ST_PTEXTRI_H
#define ST_PTEXTRI_H

#include <stddef.h>
#include <stdint.h>

#include "sample.h"

/* Same contract as st_ptexfilter_batch for a per-face set whose info.meshtype is
 * ST_MESH_TRIANGLE; o has been checked (filter in the Ptex family, mode, sharpness, width,
 * blur). Returns the number of queries whose status is not ST_Q_OK. */
int st_ptextri_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                     float *out, float *coverage, uint8_t *status);

/* st_ptextri_batch with every weight one libm expf a tap, as Ptex does (the outputs of the
 * builds before session 17): the read sweeps (Traverse, Discard's kept taps, Clamp's kernels
 * inside the face) instead of the polynomial exp four taps at a time, Clamp's folded sweeps
 * and Discard's whole-kernel weight (the coverage's denominator) instead of the recurrence
 * (the definition those approximate to about 1e-6 relatively; the point filter's values are
 * the same bits either way). For tests. */
int st_ptextri_batch_pertap(const st_set *s, const st_sample_opts *o, const st_query *q,
                            size_t n, float *out, float *coverage, uint8_t *status);

/* st_ptextri_batch with Clamp's fold sweeps and Discard's whole-kernel weight sweeps stepped
 * by recurrence through the general rows (row_clamp: row_same, row_step, row_band_t) instead
 * of the lean ones st_ptextri_batch runs: the same taps, texels, weights and order, so the
 * same bits in every output. Clamp's kernels at levels of 8 x 8 texels or more run the rows
 * a lane with the fold a lane (rows_apply_t, fold_idx8) in both builds alike. For tests. */
int st_ptextri_batch_general(const st_set *s, const st_sample_opts *o, const st_query *q,
                             size_t n, float *out, float *coverage, uint8_t *status);

/* st_ptextri_batch as a CPU without AVX2 runs it: the lean fold and whole-weight sweeps'
 * baseline instances, where st_ptextri_batch takes their AVX2 instances when the CPU has AVX2
 * (the same operations on the same values: the same bits in every output). For tests. */
int st_ptextri_batch_baseline(const st_set *s, const st_sample_opts *o, const st_query *q,
                              size_t n, float *out, float *coverage, uint8_t *status);

/* For tests: whether Clamp's walk of the band past the diagonal edge (row_band_t) reads the
 * texels fold_tap gives, tap by tap: the sums of row y's taps x in [xa, xb) of an R x R level
 * of one f32 channel (texels: R * R values), upright (odd 0) or inverted, with made-up weights
 * (stepped by recurrence, or per-tap expf of a made-up Q), walked and folded, are the same
 * bits. The taps must be ones the fold reads past the diagonal: upright y >= 0, x >= 0,
 * x + y >= R; inverted y <= R - 1, x <= R - 1, x + y <= R - 1. */
int st_ptextri_band_check(int R, int odd, int y, int xa, int xb, const float *texels,
                          int recurrence);

/* For tests: whether Clamp's fold a lane (fold_idx8, which the lean and general builds' fold
 * sweeps at levels of 8 x 8 texels or more run, eight rows at a time) gives every tap the
 * texel fold_tap gives it: lanes L = 0..7 are rows y0 + L of an R x R level (R a power of two
 * up to 2^15), upright where bit L of upmask is set, else inverted, starting at tap x0 - L and
 * stepped over nx taps as the sweeps step them. Returns the number of taps whose texel
 * differs (-1: R or nx out of range). */
int st_ptextri_fold_check(int R, int y0, int x0, int nx, unsigned upmask);

#endif
