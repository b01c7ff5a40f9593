/* store/ptex/ptexfilter_lanes.h - Ptex's bilinear filter on several queries at once, one query
 * per vector lane, and the checks and set-up of the box and width-4 filters' queries the same
 * way, and the box filter's 8-query in-face case that follows them (ptexfilter_simd.c's
 * pf_box8_select; private to ptexfilter*.c).
 *
 * A lane function takes a fixed number of queries (8 with AVX2, 4 with SSE2: its lane count)
 * and serves those whose bilinear needs no kernel: a valid query (face in range, every
 * derivative finite and within ST_MAX_DERIV) on a plain face (no constant neighbourhood,
 * neither constant nor a subface) with (u, v) in [0, 1), whose 2 x 2 texels at Ptex's
 * resolution lie inside the face with both fractions > 0 - what ptexfilter.c's per-query
 * bilinear_q serves without a kernel, with its operations in its order lane by lane, so the
 * outputs are bit for bit the same. The caller runs the per-query path for the others.
 *
 * Owns: nothing but the lane loops (ptexfilter_lanes.c). The context points into the set and
 * its built Ptex resolution table, which the caller keeps pinned.
 */
#ifndef ST_PTEXFILTER_LANES_H
#define ST_PTEXFILTER_LANES_H

#include <stddef.h>
#include <stdint.h>

#include "ptexfilter_kernel.h"
#include "sample.h"

typedef struct pf_lanes {
    const st_face *faces;        /* the set's faces */
    const uint8_t *lanef;        /* st_ptexres lanef (3 readable bytes after the last) */
    const uint64_t *base;        /* st_ptexres base */
    const uint8_t *const *px;    /* st_ptexres px */
    uint32_t nfaces;
    float width, blur;           /* the options' width (0 -> 1) and blur (0 -> 0) */
} pf_lanes;

/* The kernel set-up of the lanes handed over (pf_bilinear_lanes_fn's *edge): per lane the
 * resolution (ru, rv), the first texel (ui, vi) and the fractions (fu, fv) of the 2 x 2
 * texels, as ptexfilter.c's bilinear_kernel computes them; and two masks of those lanes (bit
 * j: lane j): open, the 2 x 2 texels overhang no mesh boundary edge of the face (ui < 0 past
 * edge 3, vi < 0 past edge 0, fu != 0 and ui + 2 > 2^ru past edge 1, fv != 0 and vi + 2 >
 * 2^rv past edge 2, each counting when that edge's adjface is < 0), and inside, they overhang
 * no edge (a texel centre). */
typedef struct pf_lanes_kern {
    int32_t ru[8], rv[8], ui[8], vi[8];
    float fu[8], fv[8];
    unsigned open, inside;
} pf_lanes_kern;

/* Runs blocks of `lanes` queries, q[0 .. lanes), q[lanes .. 2 lanes), ..., until a block is
 * not served whole or nblk (>= 1) blocks were: *whole = the number of blocks served whole
 * before the one it stopped at (nblk when all were; their outputs written, edge 0, the mask
 * returned all ones). What follows is about the block it stopped at (q, out below: that
 * block's, at q + *whole * lanes). Reads q[0 .. lanes); for every query it serves writes its
 * nc values to out (at q's place: out + j * nc for q[j]) and sets bit j of the returned mask. A valid query on a plain face
 * with (u, v) in [0, 1) whose 2 x 2 texels overhang the face or sit on a texel centre (a
 * fraction of 0) is not served but handed over: bit j of *edge set and its kernel set-up in
 * k (the caller's kernel path takes it from there without computing it again). The others'
 * outputs are left as they were or overwritten with anything: the caller writes them
 * afterwards. Reads texels up to 15 bytes past a 2 x 2 window's last texel (the arenas' 64
 * bytes of slack cover it). */
typedef unsigned (*pf_bilinear_lanes_fn)(const pf_lanes *c, const st_query *q, size_t nblk,
                                         float *out, pf_lanes_kern *k, unsigned *edge,
                                         size_t *whole);

/* The lane function for texels of type dt (st_dtype) with nc channels, its lane count in
 * *lanes: with maxlanes >= 8 the 8-lane one when the CPU has AVX2 + FMA + F16C
 * (pf_have_avx2), else (or with maxlanes 4: tests) the 4-lane SSE2 one; NULL when maxlanes
 * < 4, dt or nc is out of range, or the build has no SSE2. */
pf_bilinear_lanes_fn pf_bilinear_lanes_select(unsigned dt, unsigned nc, unsigned maxlanes,
                                              unsigned *lanes);

/* The box and width-4 filters (ptexfilter.c's kernel_run): the checks and the set-up of 8
 * queries at once, the per-query path's operations lane by lane (the kernel itself is built
 * and applied per query by the fused path, ptexfilter_simd.c). plain: the lanes whose query
 * passes the checks above (face in range, derivatives within ST_MAX_DERIV, NaN failing,
 * (u, v) in [0, 1), a plain face); fast: of those, the ones to offer the fused path (every
 * plain one for the box; for a width-4 filter those whose widths are not 1/4 or more - NaN
 * is offered - on a face of at least 8 x 8 texels: kernel_qi's test). For the plain lanes:
 * the face's row of the resolution table (px + base[f]), its log2 size, u, v and the widths
 * with width and blur applied (|du/dx| + |du/dy|, then * width + blur, as kernel_qi
 * computes them). */
typedef struct pf_klanes {
    const uint8_t *const *px[8];
    int32_t ulog2[8], vlog2[8];
    float u[8], v[8], bu[8], bv[8];
    unsigned plain, fast;
    unsigned nonb; /* the plain lanes whose face has no neighbour across any edge (lanef's
                      four boundary bits); for a width-4 filter, of those, the ones whose
                      widths are both 1/2 or more, or both in pf_q8's band */
    unsigned cst;  /* the lanes that pass the checks on a constant face (neither a subface
                      nor next to a constant face: open_face's), their set-up filled as a
                      plain lane's (px + base[f]: the face's one texel at px[base[f]]) */
} pf_klanes;
typedef void (*pf_kernel_lanes_fn)(const pf_lanes *c, const st_query *q, pf_klanes *k);

/* The function for filter ftype (st_filter: box, or a width-4 one), NULL without AVX2 + FMA
 * + F16C (pf_have_avx2) or SSE2 builds. */
pf_kernel_lanes_fn pf_kernel_lanes_select(unsigned ftype);

/* The box filter's in-face case of 8 queries at once (ptexfilter_simd.c, AVX2), after
 * klanes8 (k): pf_w4x8_fn's contract for the box (p unused): the lanes of k->fast whose box
 * kernel the fused path serves (no zero weight at an end, the window inside the face, total
 * weight > 0) written bit for bit as pf_fast_fn writes them and their mask returned; those
 * whose window overhangs the face handed over (*over, kout[lane], wout[lane] its pk_weight)
 * as pf_fast_fn hands them over; the others left to the per-query path. Any texel type, 1..4
 * channels; NULL without AVX2 + FMA + F16C (pf_have_avx2) or off x86. */
pf_w4x8_fn pf_box8_select(unsigned dt, unsigned nc);

/* The width-4 filters' kernels of a face or more along both axes (resolution 1 x 1:
 * ptexfilter.c's kernel_r0) on faces with no neighbour, 8 queries at once (ptexfilter_simd.c,
 * AVX2), after klanes8 (k): of the lanes of k->nonb whose widths are both 1 or more, those
 * whose kernel keeps a tap on the face's one texel along each axis and overhangs the face
 * (what kernel_r0 gives to pf_walk_kernel_r0's fold in Traverse and Clamp, to pf_walk_fold
 * in Discard) are served: each axis' 2 hermite taps (zeros stripped) folded as fold_r0 folds
 * them (blu, blv: black; discard: Discard's drop and weight, its coverage rule), the window
 * the small window of the face's one texel, the division kernel_walk_wr's; outputs written
 * at out + lane * nc, coverage at cov[lane], the mask returned (bit for bit the per-query
 * path's). The others (a tap past the face only, a kernel inside the face, Discard's zero
 * weight) are left to the per-query path, untouched. NULL without AVX2 + FMA + F16C. */
typedef unsigned (*pf_r0x8_fn)(int blu, int blv, int discard, const pf_klanes *k, float *out,
                               float *cov);
pf_r0x8_fn pf_r0x8_select(unsigned dt, unsigned nc);

/* The same for ptexfilter.c's kernel_iso's kernels of widths in [1/2, 1) along both axes
 * (resolution 2 x 2, 4 hermite taps an axis, zeros stripped) on faces of 2 x 2 texels or more
 * without neighbours: the lanes whose kernel keeps a tap on the face along each axis and
 * overhangs it served (the overhang folded, or dropped where black and in Discard; the
 * window on the face's level (1, 1)); NULL without AVX2 + FMA + F16C. */
pf_r0x8_fn pf_iso8_select(unsigned dt, unsigned nc);

/* The width-4 filters' kernels of widths in [1/4, 1/2) along both axes, counted after
 * pk_width4_axis' clamp of a width to a texel of the face (so also narrower ones on faces of
 * 4 texels): resolution 2 x 2, 4 or 6 taps an axis from texel -2 or 0 whose weights are
 * evaluated (pf_kernel_eval2_avx2's operations: build_w4's kernel bit for bit), on faces
 * without neighbours, 8 queries at a time up to the window: what ptexfilter.c's
 * kernel_declined_with does with them - pk_strip_zeros, pk_weight; inside the face apply's
 * window (Traverse and Clamp); else kernel_walk_wr's fold (pf_walk_fold: each overhang
 * folded onto the edge texel's weight, or dropped where black (blu, blv) and in Discard,
 * Discard's kept weight and coverage rule) and put_window's window choice. Per lane j
 * served: the window's first texel (u[j], v[j]) and taps (nu[j], nv[j]) on the face's
 * level (2, 2), its weights from wu[j] + u[j] and wv[j] + v[j], small bit j when the window
 * is the small window's (else the window loop's), the division's scale (1 / (weight x the
 * type's one value)) and the coverage. */
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
/* pk_width4_axis' clamp of a width, 8 lanes: bw clamped to a texel of a face of 2^lg texels
 * (NaN too: !(uw >= lo)). For the AVX2 functions of ptexfilter_lanes.c and _simd.c. */
__attribute__((target("avx2"), always_inline)) static inline __m256 pf_w4_clamp8(__m256 bw,
                                                                               __m256i lg)
{
    __m256 lo = _mm256_castsi256_ps(
        _mm256_slli_epi32(_mm256_sub_epi32(_mm256_set1_epi32(127), lg), 23));
    return _mm256_blendv_ps(lo, bw, _mm256_cmp_ps(bw, lo, _CMP_GE_OQ));
}
#endif

typedef struct pf_q8 {
    float wu[8][4], wv[8][4];
    int32_t u[8], v[8], nu[8], nv[8];
    float scale[8], cov[8];
    unsigned small;
} pf_q8;

/* Fills t for the lanes of m (of k->nonb; k: klanes8's set-up, p the filter) that it
 * serves and returns them; the others (widths outside the band, a kernel of zeros, a fold
 * that declines, Discard keeping no weight or, inside the face, not the whole of it) are
 * left to the per-query path. dt: st_dtype. NULL without AVX2 + FMA + F16C (pf_have_avx2)
 * or off x86. */
typedef unsigned (*pf_q8_fn)(const pk_params *p, const pf_klanes *k, unsigned m, int blu,
                             int blv, int discard, unsigned dt, pf_q8 *t);
pf_q8_fn pf_q8_select(void);

/* The width-4 filters' kernels whose widths, after pk_width4_axis' clamp of a width to a
 * texel of the face, are in [1/4, 1) along each axis (resolution 2 with 4 or 6 evaluated
 * taps from an even texel, or resolution 1 with 4 hermite taps), built 8 at a time for the
 * per-query path (ptexfilter.c's kernel_declined_with): of the lanes of m (plain lanes that
 * path would build, k: klanes8's set-up), those whose kernel keeps a tap on each axis and
 * overhangs the face get in kout[lane] the kernel pk_build_w4s + strip_w4 make (bit for
 * bit: the weights from index 0, ku0 and kv0 the first nonzero taps) and in wout[lane] the
 * weight pk_build_w4s returns; their mask is returned (kout and wout untouched in the other
 * lanes). Lanes whose widths as given are both 1 or more (kernel_r0's) are left; so are all
 * when under 4 of m remain (the per-query build is cheaper then). NULL without AVX2 + FMA + F16C or off x86. */
typedef unsigned (*pf_b8_fn)(const pk_params *p, const pf_klanes *k, unsigned m, pk *kout,
                             float *wout);
pf_b8_fn pf_b8_select(unsigned ftype);

/* The box's and the width-4 filters' kernels inside a constant face (ptexfilter.c's
 * const_inside), 8 at a time after klanes8 (k): of the lanes of m (of k->cst), those whose
 * kernel - the box's as pk_build makes it, or a width-4 filter's of a width under 1/4 once
 * clamped to a texel of the face, as build_w4 makes it (the resolution from the width, up to
 * 8 evaluated taps an axis) - keeps a tap on each axis, lies inside the face with its zero
 * end taps stripped (the box: with none at an end) and weighs in (0, +inf): its pk_weight in
 * w[lane], their mask returned (what every mode keeps whole: const_write's result). The
 * others are left to the per-query path. NULL without AVX2 + FMA + F16C or off x86. */
typedef unsigned (*pf_cst8_fn)(const pk_params *p, const pf_klanes *k, unsigned m, float *w);
pf_cst8_fn pf_cst8_select(unsigned ftype);

#endif
