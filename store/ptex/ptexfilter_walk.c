/* store/ptex/ptexfilter_walk.c - the Traverse split of a kernel that overhangs a plain face,
 * on pieces that point at their parent's weights; see ptexfilter_walk.h.
 *
 * Each step names the pk operation (ptexfilter_kernel.c) and the walk function
 * (ptexfilter.c) it stands for; the float operations and their order are theirs: weights
 * are moved, reversed and swapped (no arithmetic), folds add the overhang's sum (summed in
 * order) to the edge weight, reductions add pairs, and each piece's window sum goes through
 * the same window loop, pieces in the walk's order. Corners of a vertex of valence other
 * than 4 go through the pk operations themselves on a pk copy (they are rare).
 */
#include "ptexfilter_walk.h"

#include "ptexres.h"

/* A piece of a kernel: its window at resolution 2^ulog2 x 2^vlog2 and its weights, which
 * belong to the parent (or to a buffer of the step that made them). */
typedef struct pw {
    int ulog2, vlog2, u, v, uw, vw;
    const float *ku, *kv;
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

/* downres of ptexfilter_kernel.c from src into dst (dst == src allowed: dst never passes
 * src): the first weight kept alone when u is odd, then pairs summed, a last single one
 * kept. Returns the new width; *u halved. */
__attribute__((noinline)) static int reduce(float *dst, const float *src, int *u, int uw)
{
    float *d = dst;
    const float *s = src;
    int w = uw;
    if (*u & 1) {
        *d++ = *s++;
        w--;
    }
    for (int i = w / 2; i > 0; i--) {
        *d++ = s[0] + s[1];
        s += 2;
    }
    if (w & 1)
        *d++ = *s++;
    *u /= 2;
    return (int)(d - dst);
}

/* apply_small / apply of ptexfilter.c for the window (u, v, uw, vw) at resolution
 * (ru, rv) with weights ku, kv on face af: reduced to the face's resolution when the face is
 * smaller, the window summed into s->acc. 0: a constant face (declined). Scalars, not a
 * struct, so that they stay in registers. */
__attribute__((always_inline)) static inline int put_face(pw_state *s, int ru, int rv, int u,
                                                          int v, int uw, int vw,
                                                          const float *ku, const float *kv,
                                                          int af)
{
    if (uw <= 0 || vw <= 0)
        return 1;
    const pf_walk *w = s->w;
    const st_face *F = &w->faces[af];
    if (F->flags & ST_FACE_CONSTANT)
        return 0;
    float rbu[PK_MAX], rbv[PK_MAX];
    if (__builtin_expect(ru > F->ulog2, 0)) {
        int uu = u;
        const float *src = ku;
        do {
            uw = reduce(rbu, src, &uu, uw);
            src = rbu;
            ru--;
        } while (ru > F->ulog2);
        u = uu;
        ku = rbu;
    }
    if (__builtin_expect(rv > F->vlog2, 0)) {
        int vv = v;
        const float *src = kv;
        do {
            vw = reduce(rbv, src, &vv, vw);
            src = rbv;
            rv--;
        } while (rv > F->vlog2);
        v = vv;
        kv = rbv;
    }
    int resu = 1 << ru;
    if (u < 0 || v < 0 || u + uw > resu || v + vw > (1 << rv))
        return 1; /* outside the face: apply's guard against bad input */
    const uint8_t *d = w->px[w->base[af] + (size_t)ru * (F->vlog2 + 1u) + (size_t)rv];
    size_t rowb = (size_t)resu * w->ts;
    const uint8_t *base = d + ((size_t)v * (size_t)resu + (size_t)u) * w->ts;
    pf_window_fn fn = uw <= 2 && vw <= 2 ? w->small : w->win;
    s->acc = fn(base, rowb, ku, uw, kv, vw, s->acc);
    return 1;
}

/* pk_rotate(k, rot) then put_face: the window flipped and its axes swapped as pk_rotate
 * does, the weights reversed into this frame's buffers. */
__attribute__((always_inline)) static inline int put(pw_state *s, const pw *p, int rot, int af)
{
    float tu[PK_MAX], tv[PK_MAX];
    int resu = 1 << p->ulog2, resv = 1 << p->vlog2;
    switch (rot & 3) {
    case 1: /* flip_u, swap_uv */
        reversed(tv, p->ku, p->uw);
        return put_face(s, p->vlog2, p->ulog2, p->v, resu - p->u - p->uw, p->vw, p->uw, p->kv,
                        tv, af);
    case 2: /* flip_u, flip_v */
        reversed(tu, p->ku, p->uw);
        reversed(tv, p->kv, p->vw);
        return put_face(s, p->ulog2, p->vlog2, resu - p->u - p->uw, resv - p->v - p->vw,
                        p->uw, p->vw, tu, tv, af);
    case 3: /* flip_v, swap_uv */
        reversed(tu, p->kv, p->vw);
        return put_face(s, p->vlog2, p->ulog2, resv - p->v - p->vw, p->u, p->vw, p->uw, tu,
                        p->ku, af);
    default:
        return put_face(s, p->ulog2, p->vlog2, p->u, p->v, p->uw, p->vw, p->ku, p->kv, af);
    }
}

/* ---- splits and folds (pk_split_*, pk_merge_*) ------------------------------------------ */

__attribute__((always_inline)) static inline pw split_r(pw *k)
{
    int resu = 1 << k->ulog2, w = k->u + k->uw - resu;
    pw o = *k;
    if (w < k->uw) {
        o.u = 0;
        o.uw = w;
        o.ku = k->ku + k->uw - w;
        k->uw -= w;
    } else {
        o.u -= resu;
        k->u = 0;
        k->uw = 0;
    }
    return o;
}

__attribute__((always_inline)) static inline pw split_l(pw *k)
{
    int resu = 1 << k->ulog2, w = -k->u;
    pw o = *k;
    if (w < k->uw) {
        o.u = resu - w;
        o.uw = w;
        k->u = 0;
        k->uw -= w;
        k->ku += w;
    } else {
        o.u += resu;
        k->u = 0;
        k->uw = 0;
    }
    return o;
}

__attribute__((always_inline)) static inline pw split_t(pw *k)
{
    int resv = 1 << k->vlog2, w = k->v + k->vw - resv;
    pw o = *k;
    if (w < k->vw) {
        o.v = 0;
        o.vw = w;
        o.kv = k->kv + k->vw - w;
        k->vw -= w;
    } else {
        o.v -= resv;
        k->v = 0;
        k->vw = 0;
    }
    return o;
}

__attribute__((always_inline)) static inline pw split_b(pw *k)
{
    int resv = 1 << k->vlog2, w = -k->v;
    pw o = *k;
    if (w < k->vw) {
        o.v = resv - w;
        o.vw = w;
        k->v = 0;
        k->vw -= w;
        k->kv += w;
    } else {
        o.v += resv;
        k->v = 0;
        k->vw = 0;
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

/* pk_merge_l / _r (fold the columns past the edge onto the edge column, or drop them when
 * black): an overhang as wide as the window leaves it empty (nothing to fold onto). */
static void merge_l(pw *k, int black, float *buf)
{
    int w = -k->u;
    if (w < k->uw) {
        float *ku = own(buf, &k->ku, k->uw);
        if (!black)
            ku[w] += pk_accumulate(ku, w);
    }
    k->ku += w;
    k->uw -= w;
    k->u = 0;
}

static void merge_r(pw *k, int black, float *buf)
{
    int w = k->uw + k->u - (1 << k->ulog2);
    if (w < k->uw) {
        float *ku = own(buf, &k->ku, k->uw);
        float *kp = ku + k->uw - w;
        if (!black)
            kp[-1] += pk_accumulate(kp, w);
    }
    k->uw -= w;
}

static void merge_b(pw *k, int black, float *buf)
{
    int w = -k->v;
    if (w < k->vw) {
        float *kv = own(buf, &k->kv, k->vw);
        if (!black)
            kv[w] += pk_accumulate(kv, w);
    }
    k->kv += w;
    k->vw -= w;
    k->v = 0;
}

static void merge_t(pw *k, int black, float *buf)
{
    int w = k->vw + k->v - (1 << k->vlog2);
    if (w < k->vw) {
        float *kv = own(buf, &k->kv, k->vw);
        float *kp = kv + k->vw - w;
        if (!black)
            kp[-1] += pk_accumulate(kp, w);
    }
    k->vw -= w;
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
        k.ulog2 = kc.ulog2, k.vlog2 = kc.vlog2, k.u = kc.u, k.v = kc.v;
        k.uw = kc.uw, k.vw = kc.vw, k.ku0 = k.kv0 = k.rot = 0;
        for (int i = 0; i < kc.uw; i++)
            k.kub[i] = kc.ku[i];
        for (int i = 0; i < kc.vw; i++)
            k.kvb[i] = kc.kv[i];
        pk_rotate(&k, eid + 2);
        float w0 = pk_weight(&k);
        float nw = pk_make_symmetric(&k, w0);
        pw ks = {k.ulog2, k.vlog2, k.u, k.v, k.uw, k.vw, pk_ku(&k), pk_kv(&k)};
        for (int i = 1; i <= ncorners; i++)
            if (!put(s, &ks, 2 - cedge[i] + 2, cface[i]))
                return 0;
        s->weight += nw * (float)ncorners - w0;
        return 1;
    }
    float wu = pk_accumulate(kc.ku, kc.uw), wv = pk_accumulate(kc.kv, kc.vw);
    s->weight -= wu * wv;
    return 1;
}

/* corner_small: the diagonal face of a regular vertex (4 steps around it back to the start),
 * else corner_other. */
__attribute__((always_inline)) static inline int corner(pw_state *s, pw kc, int f, int eid)
{
    const st_face *faces = s->w->faces;
    int af = f, ae = eid, cf = -1, ce = 0;
    for (int i = 0; i < 4; i++) {
        const st_face *A = &faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || subface(s->w, af) || (af == f && ae == eid) != (i == 3))
            break;
        if (i == 1) {
            cf = af;
            ce = ae;
        }
        if (i == 3)
            return put(s, &kc, eid - ce + 2, cf);
    }
    return corner_other(s, kc, f, eid);
}

/* ---- the walk (split_walk in Traverse at depth 0) ---------------------------------------- */

int pf_walk_traverse(const pf_walk *w, const pk *k0, int f, pf_v4 *acc, float *weight)
{
    pw_state s = {w, *acc, *weight};
    const st_face *F = &w->faces[f];
    pw k = {k0->ulog2, k0->vlog2, k0->u, k0->v, k0->uw, k0->vw, k0->kub + k0->ku0,
            k0->kvb + k0->kv0};
    float bk_u[PK_MAX], bk_v[PK_MAX], ba[PK_MAX]; /* k's folds, a side piece's fold */
    int resu = 1 << k.ulog2, resv = 1 << k.vlog2;
    int sr = k.u + k.uw > resu, sl = k.u < 0;
    int st = k.v + k.vw > resv, sb = k.v < 0;
    int bu = w->black_u, bv = w->black_v;
    if (sr) {
        if (F->adjface[1] >= 0) {
            pw ka = split_r(&k);
            if (st) {
                if (F->adjface[2] >= 0) {
                    if (!corner(&s, split_t(&ka), f, 2))
                        return 0;
                } else
                    merge_t(&ka, bv, ba);
            }
            if (sb) {
                if (F->adjface[0] >= 0) {
                    if (!corner(&s, split_b(&ka), f, 1))
                        return 0;
                } else
                    merge_b(&ka, bv, ba);
            }
            if (!edge(&s, ka, f, 1))
                return 0;
        } else
            merge_r(&k, bu, bk_u);
    }
    if (sl) {
        if (F->adjface[3] >= 0) {
            pw ka = split_l(&k);
            if (st) {
                if (F->adjface[2] >= 0) {
                    if (!corner(&s, split_t(&ka), f, 3))
                        return 0;
                } else
                    merge_t(&ka, bv, ba);
            }
            if (sb) {
                if (F->adjface[0] >= 0) {
                    if (!corner(&s, split_b(&ka), f, 0))
                        return 0;
                } else
                    merge_b(&ka, bv, ba);
            }
            if (!edge(&s, ka, f, 3))
                return 0;
        } else
            merge_l(&k, bu, bk_u);
    }
    if (st) {
        if (F->adjface[2] >= 0) {
            if (!edge(&s, split_t(&k), f, 2))
                return 0;
        } else
            merge_t(&k, bv, bk_v);
    }
    if (sb) {
        if (F->adjface[0] >= 0) {
            if (!edge(&s, split_b(&k), f, 0))
                return 0;
        } else
            merge_b(&k, bv, bk_v);
    }
    if (!put(&s, &k, 0, f))
        return 0;
    *acc = s.acc;
    *weight = s.weight;
    return 1;
}
