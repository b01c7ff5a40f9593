/* store/bc1/seammask.h - seams as sample points, and least-squares seam masking (after Sylvan
 * 2015 and the seam-aware DXT1 poster, in the shared papers folder beside the repository, ../shared/papers/).
 *
 * Owns: turning the seams of a set into sample-point pairs (st_seam_sys), the energy
 * E = Ec + alpha * Es and its minimisation over texels (masking), seam RMS measurement.
 * Does not own: finding atlas seams (mesh.h, st_mesh_find_seams), BC1 (bc1.h; the
 * seam-aware endpoint solve in bc1_seam.c reuses st_seam_sys).
 *
 * Texel layout of a system ("global" texels): level 0 of every face, face after face, rows
 * of u; face f starts at base[f] and is fw[f] x fh[f] (a constant face counts as 1 x 1).
 * Texel (i, j) of a face has its centre at ((i + .5) / w, (j + .5) / h) in face (u, v).
 *
 * Sample points: each seam is sampled at points `step` texels apart (default 0.5; the
 * seam's length in texels is the longer of its two sides) at the centres of equal segments;
 * each point has a weight = its segment's length in texels (the mean of both sides) and on
 * each side a bilinear combination of 4 texels.
 *   - atlas set: the seams of the atlas mesh (st_mesh_find_seams); bilinear taps with
 *     REPEAT addressing (the glTF default: UVs outside [0,1], e.g. the spider, wrap), only
 *     seams whose two triangles both have UVs; when the atlas names its texture and a
 *     material maps it, only triangles of such materials count (several textures per
 *     mesh, e.g. the milk truck). Texels inside charts: centres covered by one of those
 *     triangles, rasterised here WITHOUT the dilation of the atlas's own chart mask - the
 *     gutter texels next to a chart are exactly the ones masking must be free to move;
 *   - per-face and cube sets: every shared face edge (adjacency), once per pair; the point
 *     at parameter s along edge e of face f meets the point at 1 - s along the neighbour's
 *     edge (shared edges run in opposite directions); each side is evaluated AT the edge
 *     with clamp-to-face bilinear, i.e. the face's own edge texels interpolated along the
 *     edge. Matching those is what makes Discard sampling (which reads no neighbour) seamless
 *     under magnification. Every texel is "inside" (weight 1).
 *
 * Energy per channel (values on the 0..255 scale): Ec = sum_i d_i (x_i - x0_i)^2 with d_i = 1
 * inside charts and `outside_weight` (default 0.01) outside, Es = sum_p len_p (A_p x - B_p x)^2,
 * E = Ec + alpha * Es. Only texels that some tap touches can move; the rest keep x0.
 *
 * Ownership: st_seam_sys_build returns a system the caller frees with st_seam_sys_free
 * (NULL accepted). A built system is read-only: many threads may use it at once.
 */
#ifndef ST_SEAMMASK_H
#define ST_SEAMMASK_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

typedef struct st_seam_pt {
    uint32_t va[4], vb[4];     /* variable index (into sys->vars) of each tap, side A / B */
    float    wa[4], wb[4];     /* bilinear weights, each side sums to 1 */
    float    len;              /* segment length in texels */
    uint32_t seam;             /* index into sys->frames */
} st_seam_pt;

/* Where a seam lies on each side, for pictures (the report's stitched close-ups): side k is
 * on face face[k]; the seam runs from org[k] along tan[k] (texel units, both sides in the same
 * 3D direction) for len[k] texels; nrm[k] is the unit normal pointing into side k's chart or
 * face. Texel coordinates: x = u * w, y = v * h (texel centres at +.5). */
typedef struct st_seam_frame {
    uint32_t face[2];
    float    org[2][2], tan[2][2], nrm[2][2], len[2];
    uint8_t  wrap;             /* atlas: REPEAT addressing */
} st_seam_frame;

typedef struct st_seam_sys {
    uint32_t  nfaces;
    uint32_t *fw, *fh;         /* per face, level-0 size as held in the global layout */
    uint64_t *base;            /* nfaces + 1 texel offsets */
    uint64_t  ntexels;
    uint8_t  *inside;          /* ntexels: 1 inside a chart (data weight 1), 0 outside */
    st_seam_pt *pts;
    size_t    npts;
    uint64_t *vars;            /* nvars global texel ids touched by some tap, ascending */
    uint32_t  nvars;
    uint32_t  nseams;          /* seams (edge pairs) sampled = frames */
    st_seam_frame *frames;
    double    total_len;       /* sum of len over points */
} st_seam_sys;

/* Builds the sample points of `s` (atlas, per-face or cube; a set without seams gives a
 * system with npts = 0). step: spacing in texels (0 = 0.5, clamped to 0.05..4). */
int st_seam_sys_build(const st_set *s, float step, st_seam_sys **out, st_error *e);
void st_seam_sys_free(st_seam_sys *sys);

/* Level 0 of every face of s as global RGBA8 texels (4 bytes each; grey -> RGB, no alpha
 * channel -> 255, float/half clamped to 0..1). *out is malloc'ed, caller frees. */
int st_seam_gather_rgba8(const st_set *s, const st_seam_sys *sys, uint8_t **out, st_error *e);

/* Masking: minimises E over the touched texels of the RGB channels of `rgba` (global RGBA8,
 * modified in place: the solution is rounded to 8 bits). The solve respects 0..255: it runs
 * conjugate gradients (Jacobi-preconditioned, warm-started at the original texels; cg.h),
 * fixes the variables that left the range at the bound, and solves again. alpha <= 0 means 2,
 * outside_weight <= 0 means 0.01. cancel may be NULL. */
int st_seam_mask_rgba8(const st_seam_sys *sys, float alpha, float outside_weight,
                       uint8_t *rgba, const volatile int *cancel, st_error *e);

/* The same on float planes (plane[c][texel], 0..255 scale, c < nchan), not rounded. */
int st_seam_mask_planes(const st_seam_sys *sys, float alpha, float outside_weight,
                        unsigned nchan, float *const *planes, const volatile int *cancel,
                        st_error *e);

/* Seam RMS of global RGBA8 texels over the RGB channels: sqrt(sum_p len_p sum_c r_pc^2 /
 * (3 sum_p len_p)), r = side A - side B, 0..255 scale ("per channel"). 0 without points. */
double st_seam_rms_rgba8(const st_seam_sys *sys, const uint8_t *rgba);

/* PSNR (dB, RGB) between two global RGBA8 buffers over the texels inside charts (all texels
 * when inside is NULL), leaving out the texels transparent (alpha < 128) in both: BC1's
 * punch-through stores them as transparent black by design; 99 when identical. */
double st_seam_psnr_inside(const st_seam_sys *sys, const uint8_t *a, const uint8_t *b);

/* ---- seam-aware BC1 (bc1_seam.c) ----------------------------------------------------------
 * The blocks touched by a seam tap are the variables of E = Ec + alpha Es measured on their
 * exactly decoded texels (Ec against `orig`, Es over the seam points). Each round: with the
 * selectors fixed, one bounded least-squares solve of all their endpoints together, rounded
 * to RGB565; then block-coordinate descent (two sweeps): with the other blocks fixed a
 * block's share of E is a quadratic in its 16 texels; candidates (the block as it is, the HQ
 * encoding of that quadratic's optimum) are polished (endpoints solved for the selectors and
 * rounded floor/ceil per channel to the best, selectors re-chosen) and the lowest is kept
 * when it lowers E. `iterations` rounds (<= 0: 3). rms_goal > 0: while the result's seam
 * RMS (per channel, as st_seam_rms_rgba8) is above rms_goal, alpha is raised 1.2x and one
 * more round runs from there, at most 8 times, stopping early when two raises in a row
 * lowered the RMS by less than 2% each (st_bc1_compress_set passes 1.1 x the masked texture's RMS: BC1 should
 * not add much to the seams masking left). The state of lowest
 * exact energy at the alpha finally used is kept, never worse than the input blocks.
 * blocks[f] holds face f's level-0 blocks (ceil(fw/4) x ceil(fh/4), row-major) or NULL for
 * a face that is not block-coded (a constant face: its texel is taken from `target`).
 * Blocks using selector 3 in 3-colour mode (transparent texels) are left alone; opaque
 * blocks never get selector 3 in 3-colour mode. orig / target: global RGBA8
 * (st_seam_gather_rgba8 layout). stats (may be NULL) gets the energy before and after (at
 * the final alpha), that alpha and the number of blocks solved. progress (may be NULL) is
 * called from the calling thread with 0..1. */
typedef struct st_bc1_seam_stats {
    double   e_before, e_after;  /* E = Ec + alpha Es over the touched blocks, 0..255 scale */
    float    alpha;              /* the seam weight finally used */
    uint32_t nblocks;            /* blocks whose endpoints were variables */
    int      iterations;         /* rounds run */
} st_bc1_seam_stats;

int st_bc1_seam_solve(const st_seam_sys *sys, const uint8_t *orig, const uint8_t *target,
                      uint8_t *const *blocks, float alpha, float outside_weight, int iterations,
                      double rms_goal, void (*progress)(void *arg, double fraction),
                      void *progress_arg, const volatile int *cancel, st_bc1_seam_stats *stats,
                      st_error *e);

#endif
