/* store/ptex/ptexfilter_walk.h - the Traverse split of a kernel that overhangs a plain face,
 * for the common neighbourhood, and Discard's and Clamp's merges of one (pf_walk_fold)
 * (private to ptexfilter*.c).
 *
 * ptexfilter.c's split walk (split_walk with its shortcuts for faces that are not subfaces)
 * splits the kernel into pk copies, rotates each into its neighbour's frame and applies it.
 * pf_walk_traverse does the same splits, rotations, folds at boundary edges, reductions to a
 * smaller neighbour's resolution, corners (regular, shared among the faces of a vertex of
 * valence > 4, or dropped) and window sums, in the same order with the same float
 * operations, on pieces that point at their parent's weights (a piece copies weights only
 * when it reverses, folds or reduces them), in one function with the pieces in registers, so
 * the results are the walk's bit for bit at a fraction of its bookkeeping. It declines what
 * it does not take: a subface among the faces the kernel reaches, or a constant face where
 * its lean cases and folds would sum a window (a piece on a constant face is its texel times
 * the piece's weight, as apply sums it, since session 19); the caller then runs the general
 * walk from the start (nothing it wrote counts). A kernel that
 * overhangs one edge only (80% of the walks of the teapot's box at 4 texels) takes a
 * function of its own with the two pieces (walk_one: a small frame, where the whole walk
 * keeps every side's state across its window calls); one that overhangs one u edge and one
 * v edge, each to a neighbour (most of the teapot's kernels at 16 texels), takes walk_two
 * (the same steps, one side, one corner). A regular corner's diagonal face is the set's
 * cornerface and a corner of valence 3 is read from its valence (the adjacency does not
 * change; the subface flags, which may, are tested at run time). pf_walk_kernel is what the
 * filter calls: those walks on any face, the fold where no overhung edge has a neighbour,
 * the whole walk otherwise. walk_one and walk_two are preceded by lean_one / lean_two (since
 * session 16): their common case (plain faces, overhangs narrower than the kernel and at
 * most a face wide, no reduction) checked once for all pieces, then the same windows in the
 * same order without put_face's per-piece checks; a 1 x 1 kernel's pieces one texel each.
 * Since session 19 two more: lean_two3, a two-edge kernel whose corner has no cornerface
 * and valence 3 (a cube's corners: the corner piece dropped, its weight removed, as
 * corner() does, then lean_two's other pieces), and lean_fold_one, a two-edge kernel one of
 * whose edges is at a mesh boundary (that axis folded on a copy of its weights as walk_all
 * folds it, then lean_one's two pieces across the other edge). Since session 21 the lean
 * cases also have constant-face instances (lean_one_k, lean_two_k, lean_fold_k: a piece on a
 * constant face is its texel times the piece's weight in that face's frame, lean_const),
 * which pf_walk_kernel_cst takes for a kernel of a constant face.
 *
 * pf_edge2_select (declared here, implemented in ptexfilter_simd.c with the window code it
 * inlines) is the same walk for the bilinear's 2 x 2 kernel alone, with its pieces in
 * registers and its windows summed inline.
 *
 * Owns: nothing but the walk. Does not own: the kernel (ptexfilter_kernel.h), the window
 * loops (ptexfilter_simd.c), eval_kernel's weight and division (ptexfilter.c).
 */
#ifndef ST_PTEXFILTER_WALK_H
#define ST_PTEXFILTER_WALK_H

#include <stddef.h>
#include <stdint.h>

#include "ptexfilter_kernel.h"
#include "set.h"

/* What the walk reads, set once per batch (all borrowed). */
typedef struct pf_walk {
    const st_face *faces;        /* the set's faces */
    const uint8_t *const *px;    /* the resolution table (st_ptexres px) */
    const uint64_t *base;        /* its per-face index (st_ptexres base) */
    size_t ts;                   /* bytes per texel */
    int black_u, black_v;        /* border mode black in u / v: a fold drops the overhang */
    pf_window_fn win;            /* the window loop (pf_window_select), not NULL */
    pf_window_fn small;          /* windows of <= 2 x 2 texels (pf_small_select), not NULL */
    pf_small4_fn small4;         /* four 1 x 1 windows (pf_small4_select), or NULL */
    pf_small4_fn small2;         /* two (pf_small2_select), NULL when small4 is */
    /* a constant face's texel at p as 4 float lanes, nc of them set (ptexfilter.c's
     * load_any for the set's type dt) */
    pf_v4 (*texel)(unsigned dt, unsigned nc, const uint8_t *p);
    unsigned dt, nc;
} pf_walk;

/* The Traverse split of kernel k (weights not empty, zeros stripped) built for face f (not a
 * subface), which it overhangs: every piece's window sum added to *acc in the walk's order,
 * and *weight (the kernel's total weight on entry) adjusted for the corners as the walk does.
 * Returns 1; 0 when it declines (*acc and *weight untouched). k is not modified. */
int pf_walk_traverse(const pf_walk *w, const pk *k, int f, pf_v4 *acc, float *weight);

/* What ptexfilter.c's walk() and kernel_walk_w call in Traverse: a kernel that overhangs
 * one edge of f only, into a neighbour there, takes the one-edge walk (walk_one), one that
 * overhangs one u and one v edge, into neighbours there, walk_two; one of a
 * face at a mesh boundary none of whose overhung edges has a neighbour takes pf_walk_fold
 * with the border modes' black (split_walk then only merges: k's weights may be left merged
 * in place when it returns 1, as pk_merge_* would leave them, or not: no caller reads them
 * after); any other the whole walk
 * (pf_walk_traverse's, folds at boundary edges included). Returns 0 (nothing written, k as
 * it was) when the walk or the fold declines. */
int pf_walk_kernel(const pf_walk *w, pk *k, int f, pf_v4 *acc, float *weight);

/* pf_walk_kernel for a kernel of a constant face f (ptexfilter.c's kernel_const), with the
 * same results: its lean cases also take constant faces (a piece on one is the face's
 * texel times the piece's weight in that face's frame, as put_const sums it), apart from
 * pf_walk_kernel's so that a plain face's walk does not test for them (since session 21). */
int pf_walk_kernel_cst(const pf_walk *w, pk *k, int f, pf_v4 *acc, float *weight);

/* pf_walk_kernel for a kernel at resolution 1 x 1 of at most 2 x 2 taps, at or inside the
 * face (u, v >= -1; ptexfilter.c's kernel_r0), with the same results: a face at a mesh
 * boundary none of whose overhung edges has a neighbour takes the fold's one texel at once
 * (walk_boundary's fold), a kernel over one u and one v edge with neighbours lean_two or
 * walk_two, over one edge with a neighbour lean_one, without pf_walk_kernel's dispatch (since
 * session 17); any other pf_walk_kernel. Since session 24 a kernel of 2 x 2 taps over one u
 * and one v edge takes lean_two's (a regular corner) and lean_fold_one's (one edge at the
 * mesh boundary) one-texel windows itself, summed by one w->small4 / w->small2 call. */
int pf_walk_kernel_r0(const pf_walk *w, pk *k0, int f, pf_v4 *acc, float *weight);

/* One axis of pf_walk_fold's merges (pk_merge_r then _l, or _t then _b): the taps past the
 * high edge of a window of res texels, then those before the low edge, folded onto the edge
 * tap (pk_accumulate's sum added to it) or, black, dropped; *w (n taps from texel *at) moved
 * past the taps dropped at the low end, *n and *at updated. The window overlaps the face
 * (*at < res, *at + *n > 0). */
static inline void pf_fold_axis(int res, int *at, int *n, float **w, int black)
{
    float *k = *w;
    if (*at + *n > res) {
        int m = *at + *n - res;
        if (!black)
            k[*n - m - 1] += pk_accumulate(k + *n - m, m);
        *n -= m;
    }
    if (*at < 0) {
        int m = -*at;
        if (!black)
            k[m] += pk_accumulate(k, m);
        *w = k + m;
        *n -= m;
        *at = 0;
    }
}

/* split_walk's Discard (discard 1) or Clamp (0) of kernel k (weights not empty, zeros
 * stripped) built for face f (not a subface), which it overhangs: the overhang past each edge
 * merged as pk_merge_r, _l, _t, _b do, in that order (dropped in Discard and at a black
 * border; else folded onto the edge weight, in k's weights, or in copies for a kernel at
 * resolution 1 x 1 of at most 2 x 2 taps: k's weights are not read after),
 * then the window on f summed into *acc; in Discard *weight becomes the weight kept
 * (pk_weight of the merged kernel, whose weights it leaves as they were), in Clamp it is
 * left alone (the kernel's total); on a constant f the face's texel times the merged
 * kernel's weight, as apply sums it. Returns 1; 0 when it declines, before any change: an
 * overhang as wide as the window. */
int pf_walk_fold(const pf_walk *w, pk *k, int f, int discard, pf_v4 *acc, float *weight);

/* Clamp's pf_walk_fold (Traverse's at a mesh boundary without neighbours: the same merges)
 * for the lanes of mask, in one call: bit j the kernel ks[j] of face q[j].face, folded in
 * place as pf_walk_fold folds it, its sum added to acc[j]. Returns the lanes folded; a lane
 * it declines keeps its kernel and acc[j] as they were (pf_walk_fold declines before any
 * change). For ptexfilter.c's kernel_fold8, which serves every lane folded (Discard, which
 * may not, takes pf_walk_fold on a copy). */
unsigned pf_walk_fold8(const pf_walk *w, pk *ks, unsigned mask, const st_query *q,
                       pf_v4 *acc);

/* The Traverse filter of a bilinear 2 x 2 kernel (ptexfilter.c's bilinear_walk: first texel
 * (u, v) at resolution (ulog2, vlog2), fractions fu, fv: weights 1 - fu, fu and 1 - fv, fv,
 * a zero fraction's tap left out) that overhangs face f (plain), for the common
 * neighbourhood: a neighbour across every edge it overhangs, each of them (and the diagonal
 * face of a regular corner) neither a subface nor constant. ptexfilter_simd.c (AVX2, one
 * function per texel type and channel count): the walk's splits, rotations, reductions and
 * window sums (pf_small_select's code) in its order, inline, then its division by the
 * kernel's total weight (which regular corners keep) and the type's one value, so out is
 * bilinear_walk's bit for bit. Returns 1 with out's nc values written, 0 when it declines
 * (nothing written: the caller runs the walk). */
typedef int (*pf_edge2_fn)(const pf_walk *w, int f, int ulog2, int vlog2, int u, int v,
                           float fu, float fv, float *out);
/* The function for texels of type dt with nc channels, NULL without AVX2. */
pf_edge2_fn pf_edge2_select(unsigned dt, unsigned nc);

#endif
