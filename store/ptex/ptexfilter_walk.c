/* store/ptex/ptexfilter_walk.c - the Traverse split of a kernel that overhangs a plain face,
 * on pieces that point at their parent's weights, and Discard's and Clamp's merges of one;
 * see ptexfilter_walk.h.
 *
 * Each step names the pk operation (ptexfilter_kernel.c) and the walk function
 * (ptexfilter.c) it stands for; the float operations and their order are theirs: weights
 * are moved, reversed and swapped (no arithmetic), folds add the overhang's sum (summed in
 * order) to the edge weight, reductions add pairs, and each piece's window sum goes through
 * the same window loop, pieces in the walk's order. Corners of a vertex of valence other
 * than 3 or 4 go through the pk operations themselves on a pk copy (they are rare). A
 * piece's window goes through put (rotation 0 first), put_face (constant face, reductions
 * out of line in put_reduced, the guard) and put_window (the table and the window call).
 * pf_walk_fold is split_walk's Discard and Clamp on the same pieces: merges, one window; a
 * kernel at resolution 1 x 1 of at most 2 x 2 taps folds in fold_r0 (two taps an axis, the
 * face's one texel), which pf_walk_kernel_r0 (ptexfilter.c's kernel_r0) reaches at once;
 * it also sums such a kernel's one-texel pieces over a regular corner (lean_two's) or over a
 * boundary and one edge (lean_fold_one's) in one pf_small4 / pf_small2 call, and over a
 * corner without a cornerface (valence 3, or 5 and more: lean_two3's and walk_two's with
 * corner_other's) in r0_other, its one-texel pk operations written out; pf_walk_kernel sends
 * any kernel of that shape over such a corner there too (two_nocorner: the box's). pf_walk_fold8
 * is pf_walk_fold for a block's lanes in one call (ptexfilter.c's kernel_fold8).
 * The lean walks' constant-face instances (cst) sum a piece on a constant face in lean_const
 * (put_const without the reduction, the flips as reversed sums).
 */
#include "ptexfilter_walk.h"

#include "ptexres.h"

/* A piece of a kernel: along axis a (0 u, 1 v) its window [at[a], at[a] + n[a]) at
 * resolution 2^lg[a] and its weights k[a], which belong to the parent (or to a buffer of the
 * step that made them). */
typedef struct pw {
    int lg[2], at[2], n[2];
    const float *k[2];
} pw;

typedef struct pw_state {
    const pf_walk *w;
    pf_v4 acc;
    float weight;
} pw_state;

static inline int subface(const pf_walk *w, int f)
{
    return (w->faces[f].flags & ST_FACE_SUBFACE) != 0;
}

static inline void reversed(float *dst, const float *src, int n)
{
    for (int i = 0; i < n; i++)
        dst[i] = src[n - 1 - i];
}

/* downres of ptexfilter_kernel.c, repeated until the resolution is 2^lg: per step the
 * first weight kept alone when the start is odd, then pairs summed, a last single one kept;
 * from src into buf (in place after the first step: the write never passes the read).
 * t = {start, taps, log2 resolution}, updated. Returns buf. */
__attribute__((noinline)) static const float *shrink(float *buf, const float *src, int t[3],
                                                     int lg)
{
    do {
        float *d = buf;
        const float *r = src;
        int w = t[1];
        if (t[0] & 1) {
            *d++ = *r++;
            w--;
        }
        for (int i = w / 2; i > 0; i--) {
            *d++ = r[0] + r[1];
            r += 2;
        }
        if (w & 1)
            *d++ = *r++;
        t[0] /= 2;
        t[1] = (int)(d - buf);
        t[2]--;
        src = buf;
    } while (t[2] > lg);
    return buf;
}

/* The window (u, v, uw, vw) at resolution (ru, rv) with weights ku, kv on face af (F), at
 * the face's resolution or below it, inside it (put_face's checks made): summed into
 * s->acc. */
__attribute__((always_inline)) static inline void put_window(pw_state *s, int ru, int rv,
                                                             int u, int v, int uw, int vw,
                                                             const float *ku, const float *kv,
                                                             int af, const st_face *F)
{
    const pf_walk *w = s->w;
    int resu = 1 << ru;
    const uint8_t *d = w->px[w->base[af] + (size_t)ru * (F->vlog2 + 1u) + (size_t)rv];
    size_t rowb = (size_t)resu * w->ts;
    const uint8_t *base = d + ((size_t)v * (size_t)resu + (size_t)u) * w->ts;
    pf_window_fn fn = (((uint32_t)uw - 1u) | ((uint32_t)vw - 1u)) < 2u ? w->small : w->win;
    s->acc = fn(base, rowb, ku, uw, kv, vw, s->acc);
}

/* put_face for a face smaller than the window's resolution along an axis: the weights
 * reduced to the face's resolution as apply does, then the guard and the window. Out of
 * line (rare): its buffers stay out of the walks' frames. */
/* The window's weights along each axis where face F is coarser reduced to F's resolution as
 * apply does (into rbu, rbv), its start, width and resolution with them. */
__attribute__((always_inline)) static inline void reduce_to_face(const st_face *F, int *ru,
                                                                 int *rv, int *u, int *v,
                                                                 int *uw, int *vw,
                                                                 const float **ku,
                                                                 const float **kv, float *rbu,
                                                                 float *rbv)
{
    if (__builtin_expect(*ru > F->ulog2, 0)) {
        int t[3] = {*u, *uw, *ru};
        *ku = shrink(rbu, *ku, t, F->ulog2);
        *u = t[0], *uw = t[1], *ru = t[2];
    }
    if (__builtin_expect(*rv > F->vlog2, 0)) {
        int t[3] = {*v, *vw, *rv};
        *kv = shrink(rbv, *kv, t, F->vlog2);
        *v = t[0], *vw = t[1], *rv = t[2];
    }
}

__attribute__((noinline)) static void put_reduced(pw_state *s, int ru, int rv, int u, int v,
                                                  int uw, int vw, const float *ku,
                                                  const float *kv, int af)
{
    const st_face *F = &s->w->faces[af];
    float rbu[PK_MAX], rbv[PK_MAX];
    reduce_to_face(F, &ru, &rv, &u, &v, &uw, &vw, &ku, &kv, rbu, rbv);
    if (u < 0 || v < 0 || u + uw > (1 << ru) || v + vw > (1 << rv))
        return; /* outside the face: apply's guard against bad input */
    put_window(s, ru, rv, u, v, uw, vw, ku, kv, af, F);
}

/* apply of ptexfilter.c on constant face af (F) for the window (u, v, uw, vw) at resolution
 * (ru, rv) with weights ku, kv: the weights reduced to the face's resolution where it is
 * coarser, then the face's texel times their pk_weight added to s->acc (no window guard:
 * apply has none for a constant face). Out of line (a constant face is the rare case). */
__attribute__((noinline)) static void put_const(pw_state *s, int ru, int rv, int u, int v,
                                                int uw, int vw, const float *ku,
                                                const float *kv, int af, const st_face *F)
{
    const pf_walk *w = s->w;
    float rbu[PK_MAX], rbv[PK_MAX];
    reduce_to_face(F, &ru, &rv, &u, &v, &uw, &vw, &ku, &kv, rbu, rbv);
    float wt = pk_accumulate(ku, uw) * pk_accumulate(kv, vw);
    s->acc += w->texel(w->dt, w->nc, w->px[w->base[af]]) * wt;
}

/* apply_small / apply of ptexfilter.c for the window (u, v, uw, vw) at resolution
 * (ru, rv) with weights ku, kv on face af: reduced to the face's resolution when the face is
 * smaller (put_reduced, out of line), the window summed into s->acc; on a constant face
 * put_const. Returns 1 (the walk's pieces continue). Scalars, not a struct, so that they
 * stay in registers. */
__attribute__((always_inline)) static inline int put_face(pw_state *s, int ru, int rv, int u,
                                                          int v, int uw, int vw,
                                                          const float *ku, const float *kv,
                                                          int af)
{
    if (uw <= 0 || vw <= 0)
        return 1;
    const st_face *F = &s->w->faces[af];
    if (__builtin_expect(F->flags & ST_FACE_CONSTANT, 0)) {
        put_const(s, ru, rv, u, v, uw, vw, ku, kv, af, F);
        return 1;
    }
    if (__builtin_expect(ru > F->ulog2 || rv > F->vlog2, 0)) { /* a smaller face */
        put_reduced(s, ru, rv, u, v, uw, vw, ku, kv, af);
        return 1;
    }
    /* outside the face: apply's guard against bad input (u < 0 or u + uw > 2^ru, uw >= 1;
     * as bits: u and its last texel u + uw - 1 both below 2^ru, a negative u having its
     * top bit set as unsigned, ru <= 30) */
    if (((((uint32_t)u | ((uint32_t)u + (uint32_t)uw - 1u)) >> ru) |
         (((uint32_t)v | ((uint32_t)v + (uint32_t)vw - 1u)) >> rv)) != 0)
        return 1;
    put_window(s, ru, rv, u, v, uw, vw, ku, kv, af, F);
    return 1;
}

/* pk_rotate(k, rot) then put_face: the window flipped and its axes swapped as pk_rotate
 * does, the weights reversed into this frame's buffers. */
__attribute__((always_inline)) static inline int put(pw_state *s, const pw *p, int rot, int af)
{
    float tu[PK_MAX], tv[PK_MAX];
    /* the flipped starts, in the cases that flip (rot 0, the commonest, needs neither) */
#define PW_FU ((1 << p->lg[0]) - p->at[0] - p->n[0])
#define PW_FV ((1 << p->lg[1]) - p->at[1] - p->n[1])
    if (__builtin_expect(!(rot & 3), 1)) /* tested first: the switch's compares come after */
        return put_face(s, p->lg[0], p->lg[1], p->at[0], p->at[1], p->n[0], p->n[1], p->k[0],
                        p->k[1], af);
    switch (rot & 3) {
    case 1: /* flip_u, swap_uv */
        reversed(tv, p->k[0], p->n[0]);
        return put_face(s, p->lg[1], p->lg[0], p->at[1], PW_FU, p->n[1], p->n[0], p->k[1], tv,
                        af);
    case 2: /* flip_u, flip_v */
        reversed(tu, p->k[0], p->n[0]);
        reversed(tv, p->k[1], p->n[1]);
        return put_face(s, p->lg[0], p->lg[1], PW_FU, PW_FV, p->n[0], p->n[1], tu, tv, af);
    default: /* 3: flip_v, swap_uv */
        reversed(tu, p->k[1], p->n[1]);
        return put_face(s, p->lg[1], p->lg[0], PW_FV, p->at[0], p->n[1], p->n[0], tu, p->k[0],
                        af);
    }
#undef PW_FU
#undef PW_FV
}

/* ---- splits and folds (pk_split_*, pk_merge_*) along axis a ----------------------------- */

/* pk_split_r (a = 0) / pk_split_t (a = 1): the part past the high edge, moved to the far
 * side (at 0); the whole kernel when it lies past the edge. */
__attribute__((always_inline)) static inline pw split_hi(pw *k, int a)
{
    int res = 1 << k->lg[a], w = k->at[a] + k->n[a] - res;
    pw o = *k;
    if (w < k->n[a]) {
        o.at[a] = 0;
        o.n[a] = w;
        o.k[a] = k->k[a] + k->n[a] - w;
        k->n[a] -= w;
    } else {
        o.at[a] -= res;
        k->at[a] = 0;
        k->n[a] = 0;
    }
    return o;
}

/* pk_split_l (a = 0) / pk_split_b (a = 1): the part before the low edge. */
__attribute__((always_inline)) static inline pw split_lo(pw *k, int a)
{
    int res = 1 << k->lg[a], w = -k->at[a];
    pw o = *k;
    if (w < k->n[a]) {
        o.at[a] = res - w;
        o.n[a] = w;
        k->at[a] = 0;
        k->n[a] -= w;
        k->k[a] += w;
    } else {
        o.at[a] += res;
        k->at[a] = 0;
        k->n[a] = 0;
    }
    return o;
}

/* The weights *kp (n of them) copied into buf, for a fold that changes one. */
static float *own(float *buf, const float **kp, int n)
{
    for (int i = 0; i < n; i++)
        buf[i] = (*kp)[i];
    *kp = buf;
    return buf;
}

/* pk_merge_l / pk_merge_b: the weights before the low edge folded onto the first one inside
 * (dropped when black); an overhang as wide as the window leaves it empty. */
static void merge_lo(pw *k, int a, int black, float *buf)
{
    int w = -k->at[a];
    if (w < k->n[a] && !black) { /* black drops the overhang: the weights are not changed */
        float *kk = own(buf, &k->k[a], k->n[a]);
        kk[w] += pk_accumulate(kk, w);
    }
    k->k[a] += w;
    k->n[a] -= w;
    k->at[a] = 0;
}

/* pk_merge_r / pk_merge_t: the weights past the high edge folded onto the last one inside. */
static void merge_hi(pw *k, int a, int black, float *buf)
{
    int w = k->n[a] + k->at[a] - (1 << k->lg[a]);
    if (w < k->n[a] && !black) {
        float *kk = own(buf, &k->k[a], k->n[a]);
        float *kp = kk + k->n[a] - w;
        kp[-1] += pk_accumulate(kp, w);
    }
    k->n[a] -= w;
}

/* ---- edges and corners (across_small, corner_small, apply_to_corner) -------------------- */

__attribute__((always_inline)) static inline int edge(pw_state *s, pw ka, int f, int eid)
{
    const st_face *F = &s->w->faces[f];
    int af = F->adjface[eid];
    if (subface(s->w, af))
        return 0;
    return put(s, &ka, eid - F->adjedge[eid] + 2, af);
}

/* apply_to_corner for a vertex whose faces are not subfaces and whose valence is not 4
 * (corner() took the regular one): shared among the faces of a vertex of valence > 4 (the
 * kernel made symmetric with the pk operations), dropped (its weight removed) otherwise. */
__attribute__((noinline)) static int corner_other(pw_state *s, pw kc, int f, int eid)
{
    enum { MAXV = 10 };
    const st_face *faces = s->w->faces;
    int af = f, ae = eid, cface[MAXV], cedge[MAXV], ncorners = 0;
    for (int i = 0; i < MAXV; i++) {
        const st_face *A = &faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || (af == f && ae == eid)) {
            ncorners = i - 2;
            break;
        }
        if (subface(s->w, af))
            return 0;
        cface[i] = af;
        cedge[i] = ae;
    }
    if (ncorners == 1)
        return put(s, &kc, eid - cedge[1] + 2, cface[1]);
    if (ncorners > 1) {
        pk k;
        k.ulog2 = kc.lg[0], k.vlog2 = kc.lg[1], k.u = kc.at[0], k.v = kc.at[1];
        k.uw = kc.n[0], k.vw = kc.n[1], k.ku0 = k.kv0 = k.rot = 0;
        for (int i = 0; i < kc.n[0]; i++)
            k.kub[i] = kc.k[0][i];
        for (int i = 0; i < kc.n[1]; i++)
            k.kvb[i] = kc.k[1][i];
        pk_rotate(&k, eid + 2);
        float w0 = pk_weight(&k);
        float nw = pk_make_symmetric(&k, w0);
        pw ks = {{k.ulog2, k.vlog2}, {k.u, k.v}, {k.uw, k.vw}, {pk_ku(&k), pk_kv(&k)}};
        for (int i = 1; i <= ncorners; i++)
            if (!put(s, &ks, 2 - cedge[i] + 2, cface[i]))
                return 0;
        s->weight += nw * (float)ncorners - w0;
        return 1;
    }
    float wu = pk_accumulate(kc.k[0], kc.n[0]), wv = pk_accumulate(kc.k[1], kc.n[1]);
    s->weight -= wu * wv;
    return 1;
}

/* corner_small: the diagonal face of a regular vertex (4 steps around it back to the start),
 * the piece dropped at a vertex of valence 3 (3 steps), else corner_other. */
__attribute__((always_inline)) static inline int corner(pw_state *s, pw kc, int f, int eid)
{
    /* the four steps around the vertex written out (the loop's tests in its order: a step
     * that leaves the mesh, reaches a subface, or comes back to (f, eid) before the fourth,
     * or not at the fourth, goes to corner_other) */
    const st_face *faces = s->w->faces;
    const st_face *A = &faces[f];
    int a1 = A->adjface[eid];
    /* a regular vertex (the set's cornerface: the same four steps back to (f, eid), from the
     * adjacency, which does not change): its faces are f, a1, the diagonal face and f's
     * neighbour across the edge before eid; the loop's tests that remain are the subface
     * flags (f is not one), which may change after the set is made */
    int dg = A->cornerface[eid];
    if (__builtin_expect(dg >= 0, 1)) {
        if (subface(s->w, a1) || subface(s->w, dg) || subface(s->w, A->adjface[(eid + 3) & 3]))
            goto other;
        return put(s, &kc, eid - A->cornercorner[eid] + 2, dg);
    }
    /* a vertex of valence 3 inside the mesh (the set's valence: 3 steps back to (f, eid),
     * none before; its faces f, a1 and f's neighbour across the edge before eid): the
     * piece dropped, its weight removed, as below, when neither is a subface */
    if (A->valence[eid] == 3) {
        if (subface(s->w, a1) || subface(s->w, A->adjface[(eid + 3) & 3]))
            goto other;
        s->weight -= pk_accumulate(kc.k[0], kc.n[0]) * pk_accumulate(kc.k[1], kc.n[1]);
        return 1;
    }
    if (a1 < 0)
        goto other;
    int e1 = (A->adjedge[eid] + 1) % 4;
    if (subface(s->w, a1) || (a1 == f && e1 == eid))
        goto other;
    A = &faces[a1];
    int cf = A->adjface[e1];
    if (cf < 0)
        goto other;
    int ce = (A->adjedge[e1] + 1) % 4;
    if (subface(s->w, cf) || (cf == f && ce == eid))
        goto other;
    A = &faces[cf];
    int a3 = A->adjface[ce];
    if (a3 < 0)
        goto other;
    int e3 = (A->adjedge[ce] + 1) % 4;
    if (a3 == f && e3 == eid) {
        /* back at (f, eid) after 3 steps: valence 3, corner_other's ncorners 0 (its loop
         * stops there before any other test): the piece dropped, its weight removed */
        s->weight -= pk_accumulate(kc.k[0], kc.n[0]) * pk_accumulate(kc.k[1], kc.n[1]);
        return 1;
    }
    if (subface(s->w, a3))
        goto other;
    A = &faces[a3];
    int a4 = A->adjface[e3];
    if (a4 < 0)
        goto other;
    int e4 = (A->adjedge[e3] + 1) % 4;
    if (subface(s->w, a4) || !(a4 == f && e4 == eid))
        goto other;
    return put(s, &kc, eid - ce + 2, cf);
other:
    return corner_other(s, kc, f, eid);
}

/* ---- the walk (split_walk in Traverse at depth 0) ---------------------------------------- */

/* One side of split_walk: the part past the right edge (hi, edge 1, corners 2 above and 1
 * below) or the left edge (edge 3, corners 3 and 0) split off with its corners and sent
 * across, or folded back at a boundary. st, sb: the kernel overhangs the top, the bottom. */
__attribute__((always_inline)) static inline int side(pw_state *s, pw *k, int f, int hi, int st,
                                                      int sb, float *bk_u, float *ba)
{
    const st_face *F = &s->w->faces[f];
    int eid = hi ? 1 : 3, ct = hi ? 2 : 3, cb = hi ? 1 : 0;
    int bv = s->w->black_v;
    if (F->adjface[eid] < 0) {
        if (hi)
            merge_hi(k, 0, s->w->black_u, bk_u);
        else
            merge_lo(k, 0, s->w->black_u, bk_u);
        return 1;
    }
    pw ka = hi ? split_hi(k, 0) : split_lo(k, 0);
    if (st) {
        if (F->adjface[2] >= 0) {
            if (!corner(s, split_hi(&ka, 1), f, ct))
                return 0;
        } else
            merge_hi(&ka, 1, bv, ba);
    }
    if (sb) {
        if (F->adjface[0] >= 0) {
            if (!corner(s, split_lo(&ka, 1), f, cb))
                return 0;
        } else
            merge_lo(&ka, 1, bv, ba);
    }
    return edge(s, ka, f, eid);
}

/* The walk of a kernel that overhangs one edge only (eid) of f, to a neighbour there: the
 * piece past the edge sent across, then the rest (side() or the top / bottom split of
 * walk_all without corners), in a function of its own so that its frame is small (walk_all
 * keeps every side's state across its window calls). */
__attribute__((noinline)) static int walk_one(const pf_walk *w, const pk *k0, int f, int eid,
                                              pf_v4 *acc)
{
    pw_state s = {w, *acc, 0.0f};
    pw k = {{k0->ulog2, k0->vlog2}, {k0->u, k0->v}, {k0->uw, k0->vw},
            {k0->kub + k0->ku0, k0->kvb + k0->kv0}};
    pw ka;
    switch (eid) {
    case 0: ka = split_lo(&k, 1); break;
    case 1: ka = split_hi(&k, 0); break;
    case 2: ka = split_hi(&k, 1); break;
    default: ka = split_lo(&k, 0); break;
    }
    if (!edge(&s, ka, f, eid) || !put(&s, &k, 0, f))
        return 0;
    *acc = s.acc;
    return 1;
}

/* The corner between the overhung u edge (the high one when hu) and v edge (hv), as side()
 * numbers them: 2 (hu, hv), 1 (hu, low v), 3 (low u, hv), 0. */
static inline int corner_between(int hu, int hv)
{
    return hu ? 2 - !hv : 3 * !!hv;
}

/* The walk of a kernel that overhangs one u edge (the high one when hu, as split_hi; else
 * the low one) and one v edge (hv), each to a neighbour: walk_all's steps for that case in
 * its order (the side's corner piece, the side's edge piece, the v edge's piece, the rest on
 * f), in a function of its own with a small frame (no folds, one side, one corner). */
__attribute__((noinline)) static int walk_two(const pf_walk *w, const pk *k0, int f, int sides,
                                              pf_v4 *acc, float *weight)
{
    int hu = sides & 1, hv = sides >> 1; /* six arguments: the caller's call is a jump */
    pw_state s = {w, *acc, *weight};
    pw k = {{k0->ulog2, k0->vlog2}, {k0->u, k0->v}, {k0->uw, k0->vw},
            {k0->kub + k0->ku0, k0->kvb + k0->kv0}};
    pw ka = hu ? split_hi(&k, 0) : split_lo(&k, 0);
    pw kc = hv ? split_hi(&ka, 1) : split_lo(&ka, 1);
    int c = corner_between(hu, hv);
    if (!corner(&s, kc, f, c) || !edge(&s, ka, f, hu ? 1 : 3))
        return 0;
    pw kb = hv ? split_hi(&k, 1) : split_lo(&k, 1);
    if (!edge(&s, kb, f, hv ? 2 : 0) || !put(&s, &k, 0, f))
        return 0;
    *acc = s.acc;
    *weight = s.weight;
    return 1;
}

__attribute__((noinline)) static int walk_all(const pf_walk *w, const pk *k0, int f,
                                              pf_v4 *acc, float *weight)
{
    pw_state s = {w, *acc, *weight};
    const st_face *F = &w->faces[f];
    pw k = {{k0->ulog2, k0->vlog2}, {k0->u, k0->v}, {k0->uw, k0->vw},
            {k0->kub + k0->ku0, k0->kvb + k0->kv0}};
    float bk_u[PK_MAX], bk_v[PK_MAX], ba[PK_MAX]; /* k's folds, a side piece's fold */
    int resu = 1 << k.lg[0], resv = 1 << k.lg[1];
    int sr = k.at[0] + k.n[0] > resu, sl = k.at[0] < 0;
    int st = k.at[1] + k.n[1] > resv, sb = k.at[1] < 0;
    if (sr && !side(&s, &k, f, 1, st, sb, bk_u, ba))
        return 0;
    if (sl && !side(&s, &k, f, 0, st, sb, bk_u, ba))
        return 0;
    if (st) {
        if (F->adjface[2] >= 0) {
            if (!edge(&s, split_hi(&k, 1), f, 2))
                return 0;
        } else
            merge_hi(&k, 1, w->black_v, bk_v);
    }
    if (sb) {
        if (F->adjface[0] >= 0) {
            if (!edge(&s, split_lo(&k, 1), f, 0))
                return 0;
        } else
            merge_lo(&k, 1, w->black_v, bk_v);
    }
    if (!put(&s, &k, 0, f))
        return 0;
    *acc = s.acc;
    *weight = s.weight;
    return 1;
}

/* ---- lean walks: walk_one's and walk_two's common case, checked first -------------------- */

/* pk_accumulate of the n weights at p in reverse order (the sum of reversed()'s copy). */
static inline float sum_reversed(const float *p, int n)
{
    float r = 0;
    for (int i = n - 1; i >= 0; i--)
        r += p[i];
    return r;
}

/* lean_put's piece on constant face af (F): put_const without a reduction (0 when af is
 * smaller than the piece's resolution, as lean_put declines): the face's texel times the
 * piece's pk_weight in af's frame, where a flip reverses an axis' weights (so its sum runs
 * from the other end) and an odd rotation swaps the axes (the u sum, taken first, is then
 * the v weights'). s0, s1: pk_accumulate of k0 and k1 (the caller's, taken once for the
 * pieces that share them). */
__attribute__((always_inline)) static inline int lean_const(pw_state *s, int lg0, int lg1,
                                                            int n0, int n1, const float *k0,
                                                            const float *k1, float s0,
                                                            float s1, int rot, int af,
                                                            const st_face *F)
{
    rot &= 3;
    int odd = rot & 1;
    if ((odd ? lg1 : lg0) > F->ulog2 || (odd ? lg0 : lg1) > F->vlog2)
        return 0;
    /* rotation 1 and 2 flip u (k0 reversed), 2 and 3 flip v (k1 reversed) */
    float a = ((rot + 3) & 3) < 2 ? sum_reversed(k0, n0) : s0;
    float b = (rot & 2) ? sum_reversed(k1, n1) : s1;
    float wt = odd ? b * a : a * b;
    const pf_walk *w = s->w;
    s->acc += w->texel(w->dt, w->nc, w->px[w->base[af]]) * wt;
    return 1;
}

/* The piece (lg, at, n, weights per axis) of a lean walk rotated by rot into face af's
 * frame as put() rotates it (its reversed weights in tu, tv), then put_window: 0 when af is
 * smaller than the piece's resolution (a reduction: the caller takes the walk instead).
 * The checks put_face makes that the lean walks' entry made for every piece at once (no
 * empty piece, no constant face, the window inside the face: see lean_fits) are not
 * repeated. */
__attribute__((always_inline)) static inline int lean_put(pw_state *s, int lg0, int lg1,
                                                          int at0, int at1, int n0, int n1,
                                                          const float *k0, const float *k1,
                                                          int rot, int af, float *tu,
                                                          float *tv, int cst, float s0,
                                                          float s1)
{
    const st_face *F = &s->w->faces[af];
    if (cst && (F->flags & ST_FACE_CONSTANT))
        return lean_const(s, lg0, lg1, n0, n1, k0, k1, s0, s1, rot, af, F);
    int ru = lg0, rv = lg1, u = at0, v = at1, uw = n0, vw = n1;
    const float *ku = k0, *kv = k1;
    if (__builtin_expect(rot & 3, 0)) {
        int fu = (1 << lg0) - at0 - n0, fv = (1 << lg1) - at1 - n1;
        switch (rot & 3) {
        case 1: /* flip_u, swap_uv */
            reversed(tv, k0, n0);
            ru = lg1, rv = lg0, u = at1, v = fu, uw = n1, vw = n0, ku = k1, kv = tv;
            break;
        case 2: /* flip_u, flip_v */
            reversed(tu, k0, n0);
            reversed(tv, k1, n1);
            u = fu, v = fv, ku = tu, kv = tv;
            break;
        default: /* 3: flip_v, swap_uv */
            reversed(tu, k1, n1);
            ru = lg1, rv = lg0, u = fv, v = at0, uw = n1, vw = n0, ku = tu, kv = k0;
            break;
        }
    }
    if (ru > F->ulog2 || rv > F->vlog2)
        return 0;
    put_window(s, ru, rv, u, v, uw, vw, ku, kv, af, F);
    return 1;
}

/* pk_accumulate(p, n) of taps p in buffer b (a pk's kub or kvb): pk_accumulate4 (no loop)
 * for at most 4 taps (a corner's overhang) where 4 floats from p lie in the buffer. */
static inline float sum_in(const float *b, const float *p, int n)
{
    if (__builtin_expect((unsigned)(n - 1) < 4u && p - b <= PK_MAX - 4, 1))
        return pk_accumulate4(p, n);
    return pk_accumulate(p, n);
}

/* The lean walks' entry test of one overhung axis: the overhang w (> 0) narrower than the
 * kernel (n taps) and at most the resolution res wide. Then every piece of the split is
 * non-empty, and each lies inside [0, res) along the axis: the part past the edge is [0, w)
 * or [res - w, res) (its flip the other), the part left on f ends at the edge it overhung
 * and starts inside (the kernel overhangs one edge of the axis); along the other axis a
 * piece is that axis' part, inside as well. A neighbour at the piece's resolution or finer
 * (lean_put's test) then holds the window: put_face's guard would pass. */
static inline int lean_fits(int w, int n, int res)
{
    return w < n && w <= res;
}

/* walk_one for the common case: the neighbour af across eid neither a subface nor constant
 * (f plain), the overhang as lean_fits says, af at the piece's resolution or finer. The
 * same pieces, rotation, windows and order (the piece past the edge, then the rest on f).
 * Returns 1 with *acc updated; 0 (*acc untouched) when the case does not hold. */
__attribute__((always_inline)) static inline int lean_one_core(const pf_walk *w, int f,
                                                               int eid, int lg0, int lg1,
                                                               int at0, int at1, int n0,
                                                               int n1, const float *ku,
                                                               const float *kv, pf_v4 *acc,
                                                               int cst)
{
    const st_face *faces = w->faces, *F = &faces[f];
    int af = F->adjface[eid];
    unsigned fl = faces[af].flags | F->flags;
    if (cst ? (fl & (ST_FACE_SUBFACE | ST_FACE_CONSTANT)) != ST_FACE_CONSTANT
            : (fl & (ST_FACE_SUBFACE | ST_FACE_CONSTANT)) != 0)
        return 0;
    int a = eid & 1, res = 1 << (a ? lg0 : lg1);
    int at = a ? at0 : at1, n = a ? n0 : n1;
    int hi = eid == 1 || eid == 2, wd = hi ? at + n - res : -at;
    if (!lean_fits(wd, n, res) || lg0 > F->ulog2 || lg1 > F->vlog2)
        return 0;
    /* the part past the edge (split_hi / split_lo) and the rest on f */
    int pat = hi ? 0 : res - wd, rat = hi ? at : 0;
    const float *kk = a ? ku : kv, *kp = hi ? kk + n - wd : kk, *kr = hi ? kk : kk + wd;
    float tu[PK_MAX], tv[PK_MAX];
    pw_state s = {w, *acc, 0.0f};
    int rot = eid - F->adjedge[eid] + 2;
    /* with constant faces (cst) the sums lean_const takes: the other axis' weights, the
     * part past the edge and the rest */
    float so = cst ? pk_accumulate(a ? kv : ku, a ? n1 : n0) : 0.0f;
    float sp = cst ? pk_accumulate(kp, wd) : 0.0f, sr = cst ? pk_accumulate(kr, n - wd) : 0.0f;
    int ok = a ? lean_put(&s, lg0, lg1, pat, at1, wd, n1, kp, kv, rot, af, tu, tv, cst, sp, so)
               : lean_put(&s, lg0, lg1, at0, pat, n0, wd, ku, kp, rot, af, tu, tv, cst, so, sp);
    if (!ok)
        return 0;
    if (cst && (F->flags & ST_FACE_CONSTANT)) /* f at the kernel's resolution (tested) */
        lean_const(&s, lg0, lg1, a ? n - wd : n0, a ? n1 : n - wd, a ? kr : ku, a ? kv : kr,
                   a ? sr : so, a ? so : sr, 0, f, F);
    else if (a)
        put_window(&s, lg0, lg1, rat, at1, n - wd, n1, kr, kv, f, F);
    else
        put_window(&s, lg0, lg1, at0, rat, n0, n - wd, ku, kr, f, F);
    *acc = s.acc;
    return 1;
}

__attribute__((always_inline)) static inline int lean_one_case(const pf_walk *w,
                                                               const pk *k0, int f, int eid,
                                                               pf_v4 *acc)
{
    return lean_one_core(w, f, eid, k0->ulog2, k0->vlog2, k0->u, k0->v, k0->uw, k0->vw,
                         k0->kub + k0->ku0, k0->kvb + k0->kv0, acc, 0);
}

/* walk_two for the common case: the neighbours across the two overhung edges and the
 * diagonal face of a regular corner (the set's cornerface) neither subfaces nor constant
 * (f plain), both overhangs as lean_fits says, every face at its piece's resolution or
 * finer. The same pieces, rotations, windows and order (corner, the u edge's piece, the v
 * edge's piece, the rest on f); a regular corner leaves the weight alone. Returns 1 with
 * *acc updated; 0 (*acc untouched) when the case does not hold. */
__attribute__((always_inline)) static inline int lean_two_case(const pf_walk *w,
                                                               const pk *k0, int f, int hu,
                                                               int hv, pf_v4 *acc,
                                                               float *weight, int drop,
                                                               int cst)
{
    const st_face *faces = w->faces, *F = &faces[f];
    int eu = hu ? 1 : 3, ev = hv ? 2 : 0, c = corner_between(hu, hv);
    int au = F->adjface[eu], av = F->adjface[ev], dg = F->cornerface[c];
    if (drop) {
        /* corner()'s valence-3 case: no cornerface, valence 3, its faces au and av (the
         * neighbours across the corner's two edges) not subfaces (tested below) */
        if (dg >= 0 || F->valence[c] != 3)
            return 0;
        dg = f; /* no corner face: f's flags tested twice */
    }
    if (dg < 0)
        return 0;
    unsigned fl = (faces[au].flags | faces[av].flags | faces[dg].flags | F->flags) &
                  (ST_FACE_SUBFACE | ST_FACE_CONSTANT);
    if (cst ? fl != ST_FACE_CONSTANT : fl != 0)
        return 0;
    int lg0 = k0->ulog2, lg1 = k0->vlog2, at0 = k0->u, at1 = k0->v, n0 = k0->uw, n1 = k0->vw;
    const float *ku = k0->kub + k0->ku0, *kv = k0->kvb + k0->kv0;
    int res0 = 1 << lg0, res1 = 1 << lg1;
    int wu = hu ? at0 + n0 - res0 : -at0, wv = hv ? at1 + n1 - res1 : -at1;
    if (!lean_fits(wu, n0, res0) || !lean_fits(wv, n1, res1) || lg0 > F->ulog2 ||
        lg1 > F->vlog2)
        return 0;
    /* split_hi / split_lo on each axis: the part past the edge (p) and the rest on f (r) */
    int pu = hu ? 0 : res0 - wu, ru = hu ? at0 : 0;
    int pv = hv ? 0 : res1 - wv, rv = hv ? at1 : 0;
    const float *kpu = hu ? ku + n0 - wu : ku, *kru = hu ? ku : ku + wu;
    const float *kpv = hv ? kv + n1 - wv : kv, *krv = hv ? kv : kv + wv;
    float tu[PK_MAX], tv[PK_MAX];
    pw_state s = {w, *acc, 0.0f};
    /* with constant faces (cst) the sums lean_const takes, each once */
    float spu = cst ? pk_accumulate(kpu, wu) : 0.0f, sru = cst ? pk_accumulate(kru, n0 - wu) : 0.0f;
    float spv = cst ? pk_accumulate(kpv, wv) : 0.0f, srv = cst ? pk_accumulate(krv, n1 - wv) : 0.0f;
    int rc = drop ? 0 : c - F->cornercorner[c] + 2, ra = eu - F->adjedge[eu] + 2;
    int rb = ev - F->adjedge[ev] + 2;
    if (drop) {
        /* the corner piece (wu x wv taps past both edges) dropped, its weight removed, as
         * corner() does at a vertex of valence 3; then the two edge pieces and the rest,
         * walk_two's order */
        if (!lean_put(&s, lg0, lg1, pu, rv, wu, n1 - wv, kpu, krv, ra, au, tu, tv, cst, spu,
                      srv) ||
            !lean_put(&s, lg0, lg1, ru, pv, n0 - wu, wv, kru, kpv, rb, av, tu, tv, cst, sru, spv))
            return 0;
        if (cst && (F->flags & ST_FACE_CONSTANT))
            lean_const(&s, lg0, lg1, n0 - wu, n1 - wv, kru, krv, sru, srv, 0, f, F);
        else
            put_window(&s, lg0, lg1, ru, rv, n0 - wu, n1 - wv, kru, krv, f, F);
        *acc = s.acc;
        *weight -= sum_in(k0->kub, kpu, wu) * sum_in(k0->kvb, kpv, wv);
        return 1;
    }
    if (!cst && !(lg0 | lg1)) {
        /* a kernel at resolution 1 x 1: every piece one texel (lean_fits: each overhang one
         * texel, the rest one texel), at (0, 0) of table entry 0 in any frame (a flip of one
         * texel at resolution 1 is itself); a rotation reverses one weight (the same value)
         * and, when odd, swaps the axes: put_window's window and call, with the weights */
        const uint8_t *const *px = w->px;
        const uint64_t *bs = w->base;
        size_t ts = w->ts;
        pf_window_fn sm = w->small; /* 1 x 1 windows */
        pf_v4 a = *acc;
        a = sm(px[bs[dg]], ts, rc & 1 ? kpv : kpu, 1, rc & 1 ? kpu : kpv, 1, a);
        a = sm(px[bs[au]], ts, ra & 1 ? krv : kpu, 1, ra & 1 ? kpu : krv, 1, a);
        a = sm(px[bs[av]], ts, rb & 1 ? kpv : kru, 1, rb & 1 ? kru : kpv, 1, a);
        *acc = sm(px[bs[f]], ts, kru, 1, krv, 1, a);
        return 1;
    }
    if (!cst && !((rc | ra | rb) & 3)) { /* no piece rotated: lean_put's rotation 0 for each */
        const st_face *C = &faces[dg], *A = &faces[au], *B = &faces[av];
        if ((lg0 > C->ulog2) | (lg1 > C->vlog2) | (lg0 > A->ulog2) | (lg1 > A->vlog2) |
            (lg0 > B->ulog2) | (lg1 > B->vlog2))
            return 0;
        put_window(&s, lg0, lg1, pu, pv, wu, wv, kpu, kpv, dg, C);
        put_window(&s, lg0, lg1, pu, rv, wu, n1 - wv, kpu, krv, au, A);
        put_window(&s, lg0, lg1, ru, pv, n0 - wu, wv, kru, kpv, av, B);
    } else if (!lean_put(&s, lg0, lg1, pu, pv, wu, wv, kpu, kpv, rc, dg, tu, tv, cst, spu,
                         spv) ||
               !lean_put(&s, lg0, lg1, pu, rv, wu, n1 - wv, kpu, krv, ra, au, tu, tv, cst, spu,
                         srv) ||
               !lean_put(&s, lg0, lg1, ru, pv, n0 - wu, wv, kru, kpv, rb, av, tu, tv, cst, sru,
                         spv))
        return 0;
    if (cst && (F->flags & ST_FACE_CONSTANT))
        lean_const(&s, lg0, lg1, n0 - wu, n1 - wv, kru, krv, sru, srv, 0, f, F);
    else
        put_window(&s, lg0, lg1, ru, rv, n0 - wu, n1 - wv, kru, krv, f, F);
    *acc = s.acc;
    return 1;
}

/* pf_walk_kernel's one-edge and two-edge walks: the lean case, else walk_one / walk_two. */
__attribute__((noinline)) static int lean_one(const pf_walk *w, const pk *k0, int f, int eid,
                                              pf_v4 *acc)
{
    int ok; /* the edge a constant in each case: its selects folded */
    switch (eid) {
    case 0: ok = lean_one_case(w, k0, f, 0, acc); break;
    case 1: ok = lean_one_case(w, k0, f, 1, acc); break;
    case 2: ok = lean_one_case(w, k0, f, 2, acc); break;
    default: ok = lean_one_case(w, k0, f, 3, acc); break;
    }
    return ok || walk_one(w, k0, f, eid, acc);
}

/* lean_two_case with the sides as constants in each case (their selects folded), else
 * walk_two; drop: lean_two3's. */
__attribute__((always_inline)) static inline int lean_two_sides(const pf_walk *w, const pk *k0,
                                                                int f, int sides, pf_v4 *acc,
                                                                float *weight, int drop)
{
    int ok;
    switch (sides & 3) {
    case 0: ok = lean_two_case(w, k0, f, 0, 0, acc, weight, drop, 0); break;
    case 1: ok = lean_two_case(w, k0, f, 1, 0, acc, weight, drop, 0); break;
    case 2: ok = lean_two_case(w, k0, f, 0, 1, acc, weight, drop, 0); break;
    default: ok = lean_two_case(w, k0, f, 1, 1, acc, weight, drop, 0); break;
    }
    return ok || walk_two(w, k0, f, sides, acc, weight);
}

__attribute__((noinline)) static int lean_two(const pf_walk *w, const pk *k0, int f, int sides,
                                              pf_v4 *acc, float *weight)
{
    return lean_two_sides(w, k0, f, sides, acc, weight, 0);
}

/* lean_two where the corner between the two edges has no cornerface (a vertex of valence 3
 * is the common one: a cube's corners), its piece dropped as corner() drops it. */
__attribute__((noinline)) static int lean_two3(const pf_walk *w, const pk *k0, int f,
                                               int sides, pf_v4 *acc, float *weight)
{
    return lean_two_sides(w, k0, f, sides, acc, weight, 1);
}

/* lean_one / lean_two / lean_two3 for a constant face f (pf_walk_kernel_cst): the same lean
 * cases with the pieces on constant faces summed by lean_const (cst), the other faces'
 * windows as before, else walk_one / walk_two (drop: lean_two3's). Out of line and apart
 * from lean_one / lean_two: the plain faces' code stays as it was. */
__attribute__((noinline)) static int lean_one_k(const pf_walk *w, const pk *k0, int f, int eid,
                                                pf_v4 *acc)
{
    return lean_one_core(w, f, eid, k0->ulog2, k0->vlog2, k0->u, k0->v, k0->uw, k0->vw,
                         k0->kub + k0->ku0, k0->kvb + k0->kv0, acc, 1) ||
           walk_one(w, k0, f, eid, acc);
}

__attribute__((noinline)) static int lean_two_k(const pf_walk *w, const pk *k0, int f,
                                                int sides, pf_v4 *acc, float *weight, int drop)
{
    int hu = sides & 1, hv = sides >> 1 & 1, ok;
    if (drop)
        ok = lean_two_case(w, k0, f, hu, hv, acc, weight, 1, 1);
    else
        ok = lean_two_case(w, k0, f, hu, hv, acc, weight, 0, 1);
    return ok || walk_two(w, k0, f, sides, acc, weight);
}

static int walk_boundary(const pf_walk *w, pk *k0, int f, unsigned m, pf_v4 *acc,
                         float *weight);

/* walk_all for a kernel that overhangs one u edge (the high one when sides & 1) and one v
 * edge (sides & 2), one of them with a neighbour, the other at a mesh boundary: walk_all
 * folds the boundary axis (merge_hi / merge_lo with its border's black, on the kernel and,
 * when the u edge is the one with a neighbour, on its piece past that edge: the same
 * weights, the same sums) and sends the piece past the other edge across, then the rest on
 * f: the fold (pf_fold_axis, on a copy of that axis' weights) then lean_one's pieces. Falls
 * back to walk_boundary (nothing written) where lean_one declines or the overhang at the
 * boundary is as wide as the kernel. */
__attribute__((always_inline)) static inline int lean_fold_body(const pf_walk *w, pk *k0,
                                                                int f, int sides, unsigned m,
                                                                pf_v4 *acc, float *weight,
                                                                int cst)
{
    const int *adj = w->faces[f].adjface;
    int hu = sides & 1, hv = sides >> 1 & 1;
    int eu = hu ? 1 : 3, ev = hv ? 2 : 0;
    int lg0 = k0->ulog2, lg1 = k0->vlog2, at0 = k0->u, at1 = k0->v, n0 = k0->uw, n1 = k0->vw;
    const float *ku = k0->kub + k0->ku0, *kv = k0->kvb + k0->kv0;
    float fb[PK_MAX];
    float *fk = fb;
    int ok = 0;
    if (adj[eu] < 0) { /* the u edge at the boundary: u folded, the v edge's piece across */
        int ov = hu ? at0 + n0 - (1 << lg0) : -at0;
        if (ov < n0) {
            for (int i = 0; i < n0; i++)
                fb[i] = ku[i];
            pf_fold_axis(1 << lg0, &at0, &n0, &fk, w->black_u);
            ok = lean_one_core(w, f, ev, lg0, lg1, at0, at1, n0, n1, fk, kv, acc, cst);
        }
    } else { /* the v edge at the boundary: v folded, the u edge's piece across */
        int ov = hv ? at1 + n1 - (1 << lg1) : -at1;
        if (ov < n1) {
            for (int i = 0; i < n1; i++)
                fb[i] = kv[i];
            pf_fold_axis(1 << lg1, &at1, &n1, &fk, w->black_v);
            ok = lean_one_core(w, f, eu, lg0, lg1, at0, at1, n0, n1, ku, fk, acc, cst);
        }
    }
    return ok || walk_boundary(w, k0, f, m, acc, weight);
}

/* lean_fold_body on a plain face f, and on a constant one (lean_fold_k) */
__attribute__((noinline)) static int lean_fold_one(const pf_walk *w, pk *k0, int f, int sides,
                                                   unsigned m, pf_v4 *acc, float *weight)
{
    return lean_fold_body(w, k0, f, sides, m, acc, weight, 0);
}

__attribute__((noinline)) static int lean_fold_k(const pf_walk *w, pk *k0, int f, int sides,
                                                 unsigned m, pf_v4 *acc, float *weight)
{
    return lean_fold_body(w, k0, f, sides, m, acc, weight, 1);
}

/* The edge the kernel overhangs when it overhangs one only and f has a neighbour there,
 * else -1. */
static inline int one_edge(const pf_walk *w, const pk *k0, int f)
{
    int resu = 1 << k0->ulog2, resv = 1 << k0->vlog2;
    int sr = k0->u + k0->uw > resu, sl = k0->u < 0;
    int st = k0->v + k0->vw > resv, sb = k0->v < 0;
    if (sr + sl + st + sb != 1)
        return -1;
    int eid = sr ? 1 : sl ? 3 : st ? 2 : 0;
    return w->faces[f].adjface[eid] >= 0 ? eid : -1;
}

int pf_walk_traverse(const pf_walk *w, const pk *k0, int f, pf_v4 *acc, float *weight)
{
    int eid = one_edge(w, k0, f);
    if (eid >= 0)
        return walk_one(w, k0, f, eid, acc);
    return walk_all(w, k0, f, acc, weight);
}

/* ---- Discard and Clamp (split_walk's other modes at depth 0) ----------------------------- */

/* The fold of a kernel at resolution 1 x 1 of at most 2 x 2 taps (the width-4 filters' at a
 * footprint of a face or more; the test of fold() passed): along each axis one tap on the
 * face (u = 0, or -1 with 2 taps), one past its edge or none; the merges as fold's (blu,
 * blv: dropped), in pk_merge's order (the folded tap plus the overhang's sum, 0 + the one
 * tap: that tap, not zero), on copies (k's weights are not read after); the window the
 * face's one texel (table entry 0). Discard's weight (pk_weight of the kernel left) in
 * *weight when weight is not NULL. */
__attribute__((always_inline)) static inline void fold_r0(const pf_walk *w, const float *ku,
                                                          const float *kv, int u, int v,
                                                          int uw, int vw, int blu, int blv,
                                                          int f, pf_v4 *acc, float *weight)
{
    float a = ku[-u], b = kv[-v];
    if (uw == 2 && !blu)
        a = u ? ku[1] + ku[0] : ku[0] + ku[1];
    if (vw == 2 && !blv)
        b = v ? kv[1] + kv[0] : kv[0] + kv[1];
    if (weight)
        *weight = a * b;
    *acc = w->small(w->px[w->base[f]], w->ts, &a, 1, &b, 1, *acc);
}

/* pf_walk_fold on kernel k0's window and resolution with its weights ku, kv (k0's own, or
 * copies of them: the merges write into them), inline where the boundary walk and
 * pf_walk_fold8 take it */
__attribute__((always_inline)) static inline int fold_w(const pf_walk *w, const pk *k0,
                                                        float *ku, float *kv, int f,
                                                        int discard, pf_v4 *acc,
                                                        float *weight)
{
    const st_face *F = &w->faces[f];
    int cst = (F->flags & ST_FACE_CONSTANT) != 0;
    int ru = k0->ulog2, rv = k0->vlog2, resu = 1 << ru, resv = 1 << rv;
    int u = k0->u, v = k0->v, uw = k0->uw, vw = k0->vw;
    /* an overhang as wide as the window (a kernel past the face, which no query's kernel
     * is): pk_merge_* would write outside it, so the general walk takes it (u >= resu
     * implies the kernel overhangs the right edge, u + uw <= 0 the left: uw >= 1) */
    if ((u >= resu) | (u + uw <= 0) | (v >= resv) | (v + vw <= 0))
        return 0;
    int blu = discard || w->black_u, blv = discard || w->black_v;
    if (!(ru | rv) && uw <= 2 && vw <= 2 && !cst) {
        fold_r0(w, ku, kv, u, v, uw, vw, blu, blv, f, acc, discard ? weight : NULL);
        return 1;
    }
    /* pk_merge_r, _l, _t, _b in split_walk's order on the weights (in place, as they
     * do; Discard and a black border only move the window) */
    pf_fold_axis(resu, &u, &uw, &ku, blu);
    pf_fold_axis(resv, &v, &vw, &kv, blv);
    /* Discard's weight: pk_weight of the kernel left, taken before apply reduces it */
    if (discard)
        *weight = pk_accumulate(ku, uw) * pk_accumulate(kv, vw);
    pw_state s = {w, *acc, 0.0f};
    /* the window lies inside the face (the test above): put_face's guard cannot fire */
    if (__builtin_expect(cst, 0))
        put_const(&s, ru, rv, u, v, uw, vw, ku, kv, f, F);
    else if (__builtin_expect((ru > F->ulog2) | (rv > F->vlog2), 0))
        put_reduced(&s, ru, rv, u, v, uw, vw, ku, kv, f);
    else
        put_window(&s, ru, rv, u, v, uw, vw, ku, kv, f, F);
    *acc = s.acc;
    return 1;
}

/* pf_walk_fold, inline where the boundary walk takes it */
__attribute__((always_inline)) static inline int fold(const pf_walk *w, pk *k0, int f,
                                                      int discard, pf_v4 *acc, float *weight)
{
    return fold_w(w, k0, k0->kub + k0->ku0, k0->kvb + k0->kv0, f, discard, acc, weight);
}

int pf_walk_fold(const pf_walk *w, pk *k0, int f, int discard, pf_v4 *acc, float *weight)
{
    return fold(w, k0, f, discard, acc, weight);
}

unsigned pf_walk_fold8(const pf_walk *w, pk *ks, unsigned mask, const st_query *q,
                       pf_v4 *acc)
{
    unsigned done = 0;
    for (unsigned m = mask; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        if (fold(w, ks + j, (int)q[j].face, 0, &acc[j], NULL))
            done |= 1u << j;
    }
    return done;
}

/* ---- Traverse's entry (ptexfilter.c's walk() and kernel_walk_w) ------------------------ */

/* pf_walk_kernel's kernel of a face at a mesh boundary (not a one-edge walk): where no edge
 * the kernel overhangs has a neighbour, split_walk only merges (pk_merge_r, _l, _t, _b in
 * that order, black per border mode) and applies the rest on f, the weight untouched:
 * Clamp's fold with the border modes' black; else the whole walk (its folds copy the edge
 * weights). Out of line: pf_walk_kernel's frame stays that of its common cases. */
__attribute__((noinline)) static int walk_boundary(const pf_walk *w, pk *k0, int f,
                                                   unsigned m, pf_v4 *acc, float *weight)
{
    const int *adj = w->faces[f].adjface;
    /* the edges with a neighbour, as pf_walk_kernel's m numbers them */
    unsigned nb = (unsigned)(adj[1] >= 0) | (unsigned)(adj[3] >= 0) << 1 |
                  (unsigned)(adj[2] >= 0) << 2 | (unsigned)(adj[0] >= 0) << 3;
    if (!(m & nb))
        return fold(w, k0, f, 0, acc, weight);
    return walk_all(w, k0, f, acc, weight);
}

/* The edges kernel k0 overhangs: right 1, left 2, top 4, bottom 8; from them the one edge
 * (one_edge's test) or the one u edge and one v edge (walk_two's sides) it overhangs, else
 * -1: tables, not a switch: its jump table's indirect branch mispredicted (callgrind
 * --branch-sim: 0.5 more a query on envcube). */
static const signed char one_of[16] = {-1, 1, 3, -1, 2, -1, -1, -1, 0, -1, -1, -1, -1, -1,
                                       -1, -1};
static const signed char two_of[16] = {-1, -1, -1, -1, -1, 3, 2, -1, -1, 1, 0, -1, -1, -1,
                                       -1, -1};
static inline unsigned overhung(const pk *k0)
{
    int resu = 1 << k0->ulog2, resv = 1 << k0->vlog2;
    return (unsigned)(k0->u + k0->uw > resu) | (unsigned)(k0->u < 0) << 1 |
           (unsigned)(k0->v + k0->vw > resv) << 2 | (unsigned)(k0->v < 0) << 3;
}

static int r0_other(const pf_walk *w, int f, int c, int eu, int ev, const float *kpu,
                    const float *kru, const float *kpv, const float *krv, pf_v4 *acc,
                    float *weight);

/* pf_walk_kernel's kernel over one u and one v edge, both to neighbours, whose corner has no
 * cornerface: one of pf_walk_kernel_r0's shape (2 x 2 taps at resolution 1 x 1 from u, v in
 * {-1, 0}: the box at footprints of a face or more, whose kernels do not go through
 * kernel_r0) takes r0_other's one-texel pieces as pf_walk_kernel_r0 gives them (since
 * session 31: walk_two's pk copies and corner_other at a vertex of valence 5 and more were
 * about 1150 instructions a call on teapot's box at fp 16); else, or where r0_other
 * declines, lean_two3. */
__attribute__((noinline)) static int two_nocorner(const pf_walk *w, pk *k0, int f, int t,
                                                  pf_v4 *acc, float *weight)
{
    int u = k0->u, v = k0->v;
    if (!(k0->ulog2 | k0->vlog2) && k0->uw == 2 && k0->vw == 2 && (unsigned)(u + 1) < 2u &&
        (unsigned)(v + 1) < 2u) {
        int hu = u == 0, hv = v == 0, c = corner_between(hu, hv);
        const float *ku = k0->kub + k0->ku0, *kv = k0->kvb + k0->kv0;
        if (r0_other(w, f, c, hu ? 1 : 3, hv ? 2 : 0, ku + hu, ku + !hu, kv + hv, kv + !hv,
                     acc, weight))
            return 1;
    }
    return lean_two3(w, k0, f, t, acc, weight);
}

int pf_walk_kernel(const pf_walk *w, pk *k0, int f, pf_v4 *acc, float *weight)
{
    unsigned m = overhung(k0);
    const int *adj = w->faces[f].adjface;
    /* one edge or one u edge and one v edge, to neighbours (an overhung edge without one: f
     * is at a mesh boundary) */
    int e = one_of[m], t = two_of[m];
    if (e >= 0)
        return adj[e] >= 0 ? lean_one(w, k0, f, e, acc) : walk_boundary(w, k0, f, m, acc, weight);
    if (t >= 0) {
        int au = adj[t & 1 ? 1 : 3], av = adj[t & 2 ? 2 : 0];
        if ((au | av) < 0) /* one edge with a neighbour: lean_fold_one */
            return (au & av) < 0 ? walk_boundary(w, k0, f, m, acc, weight)
                                 : lean_fold_one(w, k0, f, t, m, acc, weight);
        /* the corner between the two edges (walk_two's c): lean_two where it is a regular
         * vertex, lean_two3 (a valence-3 corner's piece dropped) where it has no cornerface */
        return w->faces[f].cornerface[corner_between(t & 1, t >> 1)] >= 0
                   ? lean_two(w, k0, f, t, acc, weight)
                   : two_nocorner(w, k0, f, t, acc, weight);
    }
    if ((adj[0] | adj[1] | adj[2] | adj[3]) < 0)
        return walk_boundary(w, k0, f, m, acc, weight);
    return walk_all(w, k0, f, acc, weight);
}

/* pf_walk_kernel's one-edge and two-edge cases, to neighbours, and the two-edge case with
 * one neighbour, in their constant-face forms (lean_one_k, lean_two_k, lean_fold_k); the
 * rest (mesh boundaries without neighbours, walk_all) as pf_walk_kernel takes them. */
int pf_walk_kernel_cst(const pf_walk *w, pk *k0, int f, pf_v4 *acc, float *weight)
{
    unsigned m = overhung(k0);
    const int *adj = w->faces[f].adjface;
    int e = one_of[m], t = two_of[m];
    if (e >= 0 && adj[e] >= 0)
        return lean_one_k(w, k0, f, e, acc);
    if (t >= 0) {
        int au = adj[t & 1 ? 1 : 3], av = adj[t & 2 ? 2 : 0];
        if ((au | av) >= 0)
            return lean_two_k(w, k0, f, t, acc, weight,
                              w->faces[f].cornerface[corner_between(t & 1, t >> 1)] < 0);
        if ((au & av) >= 0)
            return lean_fold_k(w, k0, f, t, m, acc, weight);
    }
    return pf_walk_kernel(w, k0, f, acc, weight);
}

/* pf_walk_kernel_r0's kernel (2 x 2 taps at resolution 1 x 1) over corner c of plain face f
 * whose vertex has no cornerface (valence other than 4), both edges eu, ev to neighbours:
 * what lean_two3 (valence 3, the corner's piece dropped) or walk_two with corner() /
 * corner_other (the rest) does, written out for one-texel pieces, in walk_two's order: the
 * corner's piece (dropped, its weight removed, at valence 3 or when the ring walk comes back
 * or stops with no face between the two neighbours; with two or more, made symmetric with
 * pk_make_symmetric's operations and put on each, the weight adjusted as corner_other
 * adjusts it; with one, declined), the u edge's piece on au, the v edge's on av, the rest
 * on f. A rotation of a one-texel piece at resolution 1 reverses one weight (the
 * same value) and, when odd, swaps the axes. kp*, kr*: the parts past each edge and left on
 * f. Returns 0 (nothing written) when a face reached is a subface or constant: the general
 * walk then. */
__attribute__((noinline)) static int r0_other(const pf_walk *w, int f, int c, int eu, int ev,
                                              const float *kpu, const float *kru,
                                              const float *kpv, const float *krv, pf_v4 *acc,
                                              float *weight)
{
    enum { MAXV = 10 }; /* corner_other's */
    const st_face *faces = w->faces, *F = &faces[f];
    const unsigned sc = ST_FACE_SUBFACE | ST_FACE_CONSTANT;
    int au = F->adjface[eu], av = F->adjface[ev];
    if ((faces[au].flags | faces[av].flags | F->flags) & sc)
        return 0;
    int cface[MAXV], cedge[MAXV], ncorners = 0;
    if (F->valence[c] != 3) { /* corner(): valence 3 drops the piece at once */
        int af = f, ae = c;
        for (int i = 0; i < MAXV; i++) { /* corner_other's ring walk */
            const st_face *A = &faces[af];
            af = A->adjface[ae];
            ae = (A->adjedge[ae] + 1) % 4;
            if (af < 0 || (af == f && ae == c)) {
                ncorners = i - 2;
                break;
            }
            if (faces[af].flags & sc)
                return 0;
            cface[i] = af;
            cedge[i] = ae;
        }
    }
    /* one face between the neighbours without a cornerface: a ring open at a mesh
     * boundary past it (no shared file has one: left to the general walk, untested here) */
    if (ncorners == 1)
        return 0;
    const uint8_t *const *px = w->px;
    const uint64_t *bs = w->base;
    size_t ts = w->ts;
    pf_window_fn sm = w->small; /* 1 x 1 windows */
    pf_v4 a = *acc;
    float wt = *weight;
    if (ncorners > 1) {
        /* pk_rotate(k, c + 2), pk_weight, pk_make_symmetric on the one-texel piece */
        int r = c + 2;
        float k0 = r & 1 ? kpv[0] : kpu[0], k1 = r & 1 ? kpu[0] : kpv[0];
        float w0 = pk_accumulate(&k0, 1) * pk_accumulate(&k1, 1);
        float sum = k0 + k1, ku = sum, kv = sum, nw = 0;
        nw += sum;
        nw *= nw;
        float scale = nw == 0 ? 1.f : w0 / nw;
        if (scale < 1) {
            if (scale < -1) {
                ku *= -1;
                nw = -nw;
            } else {
                ku *= scale;
                nw = w0;
            }
        }
        for (int i = 1; i <= ncorners; i++) {
            int ri = 2 - cedge[i] + 2;
            a = sm(px[bs[cface[i]]], ts, ri & 1 ? &kv : &ku, 1, ri & 1 ? &ku : &kv, 1, a);
        }
        wt += nw * (float)ncorners - w0;
    } else {
        wt -= pk_accumulate(kpu, 1) * pk_accumulate(kpv, 1);
    }
    int ra = eu - F->adjedge[eu] + 2, rb = ev - F->adjedge[ev] + 2;
    a = sm(px[bs[au]], ts, ra & 1 ? krv : kpu, 1, ra & 1 ? kpu : krv, 1, a);
    a = sm(px[bs[av]], ts, rb & 1 ? kpv : kru, 1, rb & 1 ? kru : kpv, 1, a);
    *acc = sm(px[bs[f]], ts, kru, 1, krv, 1, a);
    *weight = wt;
    return 1;
}

int pf_walk_kernel_r0(const pf_walk *w, pk *k0, int f, pf_v4 *acc, float *weight)
{
    const st_face *faces = w->faces, *F = &faces[f];
    const int *adj = F->adjface;
    int u = k0->u, v = k0->v, uw = k0->uw, vw = k0->vw;
    /* 2 taps an axis at u, v in {-1, 0}: one u and one v edge overhung by a texel (the high
     * one at 0), what the dispatch below gives lean_two or lean_fold_one; their cases that
     * take it, here without their dispatch and frames, each window one texel at (0, 0) of
     * table entry 0 (a flip of one texel at resolution 1 is itself) summed in their order by
     * one pf_small4 / pf_small2 call: */
    if (__builtin_expect(w->small4 != NULL, 1) && uw == 2 && vw == 2 &&
        (unsigned)(u + 1) < 2u && (unsigned)(v + 1) < 2u) {
        int hu = u == 0, hv = v == 0, c = corner_between(hu, hv);
        int eu = hu ? 1 : 3, ev = hv ? 2 : 0, au = adj[eu], av = adj[ev];
        const uint8_t *const *px = w->px;
        const uint64_t *bs = w->base;
        const float *ku = k0->kub + k0->ku0, *kv = k0->kvb + k0->kv0;
        /* the parts past each edge (p) and left on f (r), as lean_two_case / lean_one_core
         * split them */
        const float *kpu = ku + hu, *kru = ku + !hu, *kpv = kv + hv, *krv = kv + !hv;
        const unsigned sc = ST_FACE_SUBFACE | ST_FACE_CONSTANT;
        if ((au | av) >= 0) {
            /* both edges to neighbours, their corner a regular vertex, no face a subface
             * or constant: lean_two_case's resolution-1 x 1 case (lean_fits: overhangs of
             * 1 < 2 taps, at most the resolution; no face coarser than 1 x 1): the corner's,
             * the u edge's, the v edge's and f's windows, the weight left alone */
            int dg = F->cornerface[c];
            if (dg >= 0 &&
                !((faces[au].flags | faces[av].flags | faces[dg].flags | F->flags) & sc)) {
                int rc = c - F->cornercorner[c] + 2, ra = eu - F->adjedge[eu] + 2;
                int rb = ev - F->adjedge[ev] + 2;
                pf_tex4 t = {{px[bs[dg]], px[bs[au]], px[bs[av]], px[bs[f]]},
                             {rc & 1 ? kpv : kpu, ra & 1 ? krv : kpu, rb & 1 ? kpv : kru, kru},
                             {rc & 1 ? kpu : kpv, ra & 1 ? kpu : krv, rb & 1 ? kru : kpv, krv}};
                *acc = w->small4(&t, w->ts, *acc);
                return 1;
            }
            /* no cornerface (valence 3, or 5 and more): lean_two3's / walk_two's pieces */
            if (dg < 0 && r0_other(w, f, c, eu, ev, kpu, kru, kpv, krv, acc, weight))
                return 1;
        } else if ((au & av) >= 0) {
            /* one edge to a neighbour an, the other at the mesh boundary, an and f neither
             * a subface nor constant: lean_fold_body's case (the overhang 1 < 2 taps): the
             * boundary axis folded (pf_fold_axis on a copy: one tap left), then lean_one_core
             * across the other edge: the piece past it on an (an odd rotation swaps the
             * axes' weights), the rest on f */
            int an = au >= 0 ? au : av;
            if (!((faces[an].flags | F->flags) & sc)) {
                float fb[2];
                float *fk = fb;
                int at, n = 2;
                pf_tex4 t;
                t.p[0] = px[bs[an]];
                t.p[1] = px[bs[f]];
                if (au < 0) { /* u folded, the v edge's piece on av */
                    fb[0] = ku[0], fb[1] = ku[1], at = u;
                    pf_fold_axis(1, &at, &n, &fk, w->black_u);
                    int rot = ev - F->adjedge[ev] + 2;
                    t.ku[0] = rot & 1 ? kpv : fk, t.kv[0] = rot & 1 ? fk : kpv;
                    t.ku[1] = fk, t.kv[1] = krv;
                } else { /* v folded, the u edge's piece on au */
                    fb[0] = kv[0], fb[1] = kv[1], at = v;
                    pf_fold_axis(1, &at, &n, &fk, w->black_v);
                    int rot = eu - F->adjedge[eu] + 2;
                    t.ku[0] = rot & 1 ? fk : kpu, t.kv[0] = rot & 1 ? kpu : fk;
                    t.ku[1] = kru, t.kv[1] = fk;
                }
                *acc = w->small2(&t, w->ts, *acc);
                return 1;
            }
        }
    }
    /* the overhung edges (a kernel at resolution 1 x 1: left u < 0, right u + uw > 1) and
     * whether each has a neighbour */
    int sl = u < 0, sr = u + uw > 1, sb = v < 0, st = v + vw > 1;
    int nl = adj[3] >= 0, nr = adj[1] >= 0, nb = adj[0] >= 0, nt = adj[2] >= 0;
    /* walk_boundary's fold: no overhung edge with a neighbour, f not constant, no overhang
     * as wide as the window */
    if (!((sl & nl) | (sr & nr) | (sb & nb) | (st & nt) | (F->flags & ST_FACE_CONSTANT) |
          (u >= 1) | (u + uw <= 0) | (v >= 1) | (v + vw <= 0))) {
        fold_r0(w, k0->kub + k0->ku0, k0->kvb + k0->kv0, u, v, uw, vw, w->black_u,
                w->black_v, f, acc, NULL);
        return 1;
    }
    /* pf_walk_kernel's dispatch with these sides: one u and one v edge overhung, each to a
     * neighbour: lean_two where their corner is a regular vertex, else lean_two3; one of
     * them to a neighbour: lean_fold_one; one edge overhung, to a neighbour: lean_one; the
     * rest through pf_walk_kernel */
    int hu = sl | sr, hv = sb | st;
    if (hu & hv) {
        int nu = sl ? nl : nr, nv = sb ? nb : nt;
        if (nu & nv)
            return F->cornerface[corner_between(sr, st)] >= 0
                       ? lean_two(w, k0, f, sr | st << 1, acc, weight)
                       : lean_two3(w, k0, f, sr | st << 1, acc, weight);
        if (nu | nv) /* with pf_walk_kernel's mask of the overhung edges */
            return lean_fold_one(w, k0, f, sr | st << 1,
                                 (unsigned)(sr | sl << 1 | st << 2 | sb << 3), acc, weight);
    } else if (hu | hv) {
        int e = sl ? 3 : sr ? 1 : sb ? 0 : 2;
        if (adj[e] >= 0)
            return lean_one(w, k0, f, e, acc);
    }
    return pf_walk_kernel(w, k0, f, acc, weight);
}
