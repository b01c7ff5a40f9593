/* store/ptex/ptexfilter.c - Ptex's filter family on seamtex sets (see ptexfilter.h): footprint,
 * kernel, and where its pieces land.
 *
 * Traverse follows Ptex's PtexSeparableFilter (v2.4) step for step: the kernel is split at
 * each face edge it overhangs; a piece crosses into the neighbour (rotated into its frame,
 * reduced to its resolution, adjusted between subfaces and main faces), the corner piece goes
 * to the diagonal face of a regular vertex, is made symmetric and shared among the faces of a
 * vertex of valence > 4, or is dropped (and its weight removed) at valence 3 and at
 * boundaries; at a boundary edge the overhang is folded back (clamp, periodic) or dropped
 * (black). The sum is divided by the kernel's weight. Discard drops every overhanging piece
 * and divides by the weight kept (coverage = kept / total); Clamp folds every overhang back.
 * In a set with Ptex's tanvec edge filter mode (info.edgefilter) Traverse turns channels 0-1
 * of each piece that reached a face turned against the query face back (apply, tanvec_add),
 * on the general path only: batch sends such sets there.
 *
 * Per batch (texel type, channel count, filter and options are the same for every query) one
 * query function is chosen: point and bilinear inside a face specialised per texel type and
 * channel count, box and width-4 kernels inside a face through the fused path of
 * ptexfilter_simd.c; everything else (edges, subfaces, constant faces, wide kernels) through
 * eval, the general path. Both ways do the same arithmetic in the same order. The point
 * filter and the box and width-4 filters also have their own batch loops (point_run,
 * kernel_run: the query checks and the query function inline, no call per query; kernel_run
 * takes the checks and set-up of 8 queries at once from ptexfilter_lanes.c's kernel lanes
 * with AVX2, then the fused path's common case of the whole block at once (ptexfilter_simd.c's
 * pf_w4x8_select for the width-4 filters, pf_box8_select for the box; kernels inside a
 * constant face through pf_cst8_select, and on faces without neighbours the folds of width-4
 * kernels of a quarter face or more through pf_r0x8_select, pf_iso8_select and
 * pf_q8_select; in blocks with under 3 fused-path lanes, the width-4 kernels that
 * kernel_declined_with would build one by one through pf_b8_select, handed to kernel_built),
 * and calls the fused path per query for the lanes left). A
 * bilinear 2 x 2 kernel that overhangs a plain face takes its own walk (bilinear_walk on
 * pk2 pieces; in Traverse over plain faces ptexfilter_simd.c's pf_edge2, the same walk in
 * registers). A query on a face that reads as zero in its mode (ptexres.h's zero bits: in
 * Traverse the face and every face its split reaches constant zero, in Clamp the face, in
 * Discard the face when no coverage is asked for and the kernel is the gaussian, the box or
 * bilinear) is +0 once its kernel's weight is known to be positive and finite (zero_ring_q),
 * without the walk.
 *
 * Data comes from the set's Ptex resolution table (ptexres.h), which a set read from a .ptx
 * has (st_ptexfilter_prepare attaches it to any per-face set); the first call on a set builds
 * the table (once, thread-safe), later calls only read it.
 */
#include "ptexfilter.h"

#include <math.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "ptex_format.h"
#include "ptexfilter_kernel.h"
#include "ptexfilter_lanes.h"
#include "ptexfilter_walk.h"
#include "ptexres.h"
#include "ptextri.h"

#define PF_MAX_DEPTH 8   /* subface re-splits; Ptex needs 2, a bad adjacency table might loop */

typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));

static inline v4f v4f_abs(v4f x)
{
    v4i b;
    memcpy(&b, &x, sizeof b);
    b &= 0x7fffffff;
    memcpy(&x, &b, sizeof x);
    return x;
}

enum { PF_U8, PF_F32, PF_OTHER };

/* One texel as 4 float lanes (raw values: u8 0..255, u16 0..65535). The u8, u16 and float
 * loads read 4 channels even for fewer: the set arena and the table arena end with slack, and
 * the extra lanes are never stored. */
static inline v4f load_u8(const uint8_t *p)
{
#ifdef __SSE2__
    uint32_t x;
    memcpy(&x, p, 4);
    __m128i z = _mm_setzero_si128();
    __m128i v = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128((int)x), z), z);
    return (v4f)_mm_cvtepi32_ps(v);
#else
    return (v4f){(float)p[0], (float)p[1], (float)p[2], (float)p[3]};
#endif
}
static inline v4f load_f32(const uint8_t *p)
{
    v4f v;
    memcpy(&v, p, sizeof v);
    return v;
}
static inline v4f load_u16(const uint8_t *p)
{
#ifdef __SSE2__
    __m128i v = _mm_loadl_epi64((const __m128i *)(const void *)p);
    return (v4f)_mm_cvtepi32_ps(_mm_unpacklo_epi16(v, _mm_setzero_si128()));
#else
    uint16_t x[4];
    memcpy(x, p, sizeof x);
    return (v4f){(float)x[0], (float)x[1], (float)x[2], (float)x[3]};
#endif
}

typedef struct pf {
    const st_set *s;
    const st_ptexres *t;
    unsigned nc, dt;
    size_t ts;               /* bytes per texel */
    int mode;                /* st_mode */
    int bu, bv;              /* border modes: 0 clamp, 1 black, 2 periodic */
    int kind;                /* PF_U8 (1..4 channels), PF_F32 (3..4 channels), PF_OTHER */
    pf_fast_fn fast;         /* the fused path of a kernel inside one face, or NULL */
    pf_window_fn win;        /* the window loop for the batch's type and channels, or NULL */
    pf_window_fn small;      /* windows of <= 2 x 2 texels (bilinear pieces), or NULL */
    pf_edge2_fn edge2;       /* a 2 x 2 kernel's Traverse walk, plain faces (AVX2), or NULL */
    pf_bilinear_half_fn bhalf; /* the in-face bilinear of half texels (F16C), or NULL */
    float width, blur;       /* the options' width (0 -> 1) and blur (0 -> 0) */
    float weight;
    v4f acc;                 /* the weighted sum, raw units */
    pf_walk walk;            /* what pf_walk_traverse reads (set when c->small is) */
    int iso;                 /* kernel_iso may run: both window loops (Discard: inside only) */
    int cst;                 /* eval's shortcuts for kernels inside a constant face
                              * (const_write): all paths but PF_PATH_GENERAL */
    pf_r0x8_fn r0x8;         /* kernel_r0's folds 8 at a time (set when c->small is), or NULL */
    pf_r0x8_fn iso8;         /* kernel_iso's, the same */
    pf_q8_fn q8;             /* kernel_q8's taps 8 at a time (set when c->iso8 is), or NULL */
    pf_cst8_fn cst8;         /* kernel_cst8's kernels 8 at a time (with c->cst), or NULL */
    pf_b8_fn b8;             /* kernel_declined_with's width-4 builds 8 at a time (with
                              * c->small), or NULL */
    int tanvec;              /* Ptex's tanvec edge filter mode in Traverse (the set's mode
                              * tanvec, 2+ channels): apply rotates channels 0-1 of each
                              * rotated piece (tanvec_add); the batch takes the general path */
    int zdis;                /* Discard reads a zero face as zero (zero_in_mode): the caller
                              * asks no coverage and the filter is the gaussian, the box or
                              * bilinear, whose weight kept in the face is positive */
} pf;

static float one_value(unsigned dt)
{
    return dt == ST_DT_U8 ? 255.0f : dt == ST_DT_U16 ? 65535.0f : 1.0f;
}

static inline float texel_raw(unsigned dt, const uint8_t *p, unsigned c)
{
    switch (dt) {
    case ST_DT_U8: return (float)p[c];
    case ST_DT_U16: { uint16_t x; memcpy(&x, p + 2 * c, 2); return (float)x; }
    case ST_DT_HALF: { uint16_t x; memcpy(&x, p + 2 * c, 2); return st_half_to_float(x); }
    default: { float x; memcpy(&x, p + 4 * c, 4); return x; }
    }
}

static inline v4f load_any(unsigned dt, unsigned nc, const uint8_t *p)
{
    v4f v = {0, 0, 0, 0};
    for (unsigned ch = 0; ch < nc; ch++)
        v[ch] = texel_raw(dt, p, ch);
    return v;
}

static pf_v4 walk_texel(unsigned dt, unsigned nc, const uint8_t *p);

static inline int is_subface(const pf *c, int f)
{
    return (c->s->faces[f].flags & ST_FACE_SUBFACE) != 0;
}

/* The window loop without AVX2 (the portable loops; pf_window_select gives NULL): returns
 * c->acc + the window's weighted sum. Kept out of apply so that its frame stays small. */
__attribute__((noinline)) static v4f apply_portable(const pf *c, const uint8_t *base, size_t rowb,
                                                   size_t ts, const float *ku, int uw,
                                                   const float *kv, int vw)
{
    unsigned nc = c->nc, dt = c->dt;
    v4f acc = c->acc;
    switch (c->kind) {
    case PF_U8:
        if (nc < 3) {
            /* 1 or 2 channels: a row of the window is uw * nc contiguous bytes; dot it with the
             * weights repeated per channel, 4 bytes at a time (lane l holds channel l % nc). The
             * last load may read up to 3 bytes past the row (weight 0; arenas end with slack). */
            int ne = uw * (int)nc, nv = (ne + 3) / 4;
            v4f wv[(PK_MAX * 4 + 3) / 4];
            float *we = (float *)wv;
            if (nc == 1) {
                for (int i = 0; i < uw; i++)
                    we[i] = ku[i];
            } else {
                for (int i = 0; i < uw; i++)
                    we[2 * i] = we[2 * i + 1] = ku[i];
            }
            for (int i = ne; i < nv * 4; i++)
                we[i] = 0.0f;
            for (int j = 0; j < vw; j++) {
                const uint8_t *p = base + j * rowb;
                v4f rs = load_u8(p) * wv[0];
                for (int b = 1; b < nv; b++)
                    rs += load_u8(p + 4 * b) * wv[b];
                v4f row = nc == 2 ? (v4f){rs[0] + rs[2], rs[1] + rs[3], 0, 0}
                                  : (v4f){(rs[0] + rs[1]) + (rs[2] + rs[3]), 0, 0, 0};
                acc += row * kv[j];
            }
            break;
        }
        for (int j = 0; j < vw; j++) {
            const uint8_t *p = base + j * rowb;
            v4f row = load_u8(p) * ku[0];
            for (int i = 1; i < uw; i++)
                row += load_u8(p + (size_t)i * ts) * ku[i];
            acc += row * kv[j];
        }
        break;
    case PF_F32:
        for (int j = 0; j < vw; j++) {
            const uint8_t *p = base + j * rowb;
            v4f row = load_f32(p) * ku[0];
            for (int i = 1; i < uw; i++)
                row += load_f32(p + (size_t)i * ts) * ku[i];
            acc += row * kv[j];
        }
        break;
    default:
        for (int j = 0; j < vw; j++) {
            const uint8_t *p = base + j * rowb;
            v4f row = load_any(dt, nc, p) * ku[0];
            for (int i = 1; i < uw; i++)
                row += load_any(dt, nc, p + (size_t)i * ts) * ku[i];
            acc += row * kv[j];
        }
        break;
    }
    return acc;
}

/* Ptex's tanvec edge filter mode: the sum r of a piece that reached its face turned by rot
 * quarter turns (pk's rot) added to acc with channels 0-1, a tangent-space vector, turned
 * back into the query face's frame: (x, y) -> (-y, x) per quarter turn; the other channels
 * added as they are. Ptex's order: the piece summed on its own from zero, then each channel
 * added to (or subtracted from) the result. */
static inline v4f tanvec_add(v4f acc, v4f r, int rot)
{
    switch (rot & 3) {
    case 1: acc[0] -= r[1]; acc[1] += r[0]; break;
    case 2: acc[0] -= r[0]; acc[1] -= r[1]; break;
    case 3: acc[0] += r[1]; acc[1] -= r[0]; break;
    default: acc[0] += r[0]; acc[1] += r[1]; break;
    }
    acc[2] += r[2];
    acc[3] += r[3];
    return acc;
}

/* Kernel applied to the data of face f at the kernel's resolution (reduced first when the
 * face is smaller). In the tanvec mode a piece turned against the query face (k->rot) is
 * summed apart and its channels 0-1 turned back (tanvec_add), except, as in Ptex, on data
 * Ptex serves as a constant: a constant face, any face at 1 x 1 (its constant value), and a
 * reduction Ptex makes from a tiled face whose tiles are all one constant once it fits in a
 * tile (st_ptexres_served_const). */
static void apply(pf *c, pk *k, int f)
{
    if (k->uw <= 0 || k->vw <= 0)
        return;
    const st_face *F = &c->s->faces[f];
    while (k->ulog2 > F->ulog2)
        pk_downres_u(k);
    while (k->vlog2 > F->vlog2)
        pk_downres_v(k);
    if (k->ulog2 < 0 || k->vlog2 < 0)
        return;
    const uint8_t *const *px = c->t->px + c->t->base[f];
    unsigned nc = c->nc, dt = c->dt;
    const float *ku = k->kub + k->ku0, *kv = k->kvb + k->kv0;
    if (F->flags & ST_FACE_CONSTANT) {
        const uint8_t *d = px[0];
        float w = pk_weight(k);
        c->acc += load_any(dt, nc, d) * w;
        return;
    }
    int resu = 1 << k->ulog2;
    /* the window must lie inside the face (it does for Ptex's kernels; guard bad input) */
    if (k->u < 0 || k->v < 0 || k->u + k->uw > resu || k->v + k->vw > (1 << k->vlog2))
        return;
    const uint8_t *d = px[(unsigned)k->ulog2 * (F->vlog2 + 1u) + (unsigned)k->vlog2];
    size_t ts = c->ts;
    const uint8_t *base = d + ((size_t)k->v * resu + k->u) * ts;
    size_t rowb = (size_t)resu * ts;
    if (__builtin_expect(c->tanvec, 0) && (k->rot & 3) &&
        !st_ptexres_served_const(c->t, c->s, (uint32_t)f, k->ulog2, k->vlog2)) {
        v4f acc = c->acc;
        c->acc = (v4f){0, 0, 0, 0};
        v4f r = c->win ? c->win(base, rowb, ku, k->uw, kv, k->vw, c->acc)
                       : apply_portable(c, base, rowb, ts, ku, k->uw, kv, k->vw);
        c->acc = tanvec_add(acc, r, k->rot);
        return;
    }
    if (c->win)
        c->acc = c->win(base, rowb, ku, k->uw, kv, k->vw, c->acc);
    else
        c->acc = apply_portable(c, base, rowb, ts, ku, k->uw, kv, k->vw);
}

static void split_apply(pf *c, pk *k, int f, int depth);

static void apply_across_edge(pf *c, pk *k, int f, int eid, int depth)
{
    const st_face *F = &c->s->faces[f];
    int af = F->adjface[eid], ae = F->adjedge[eid];
    int rot = eid - ae + 2;
    int fsub = is_subface(c, f), asub = is_subface(c, af);
    if (fsub != asub) {
        if (asub) {
            int primary = pk_main_to_subface(k, eid);
            if (!primary) {
                int neid = (ae + 3) % 4;
                const st_face *A = &c->s->faces[af];
                int naf = A->adjface[neid], nae = A->adjedge[neid];
                if (naf < 0)
                    return;
                af = naf;
                ae = nae;
                rot += neid - ae + 2;
            }
        } else {
            int primary = c->s->faces[af].adjface[ae] == f;
            pk_subface_to_main(k, eid - primary);
        }
    }
    pk_rotate(k, rot);
    if (is_subface(c, af))
        split_apply(c, k, af, depth + 1);
    else
        apply(c, k, af);
}

static void apply_to_corner_face(pf *c, pk *k, int f, int eid, int cf, int ceid, int depth)
{
    int fsub = is_subface(c, f), csub = is_subface(c, cf);
    if (fsub != csub) {
        if (csub)
            pk_main_to_subface(k, eid + 3);
        else
            pk_subface_to_main(k, eid + 3);
    }
    pk_rotate(k, eid - ceid + 2);
    if (csub)
        split_apply(c, k, cf, depth + 1);
    else
        apply(c, k, cf);
}

static void apply_to_corner(pf *c, pk *k, int f, int eid, int depth)
{
    enum { MAXV = 10 };
    int af = f, ae = eid;
    int prev_sub = is_subface(c, f);
    int cface[MAXV], cedge[MAXV];
    int ncorners = 0;
    for (int i = 0; i < MAXV; i++) {
        int prevf = af;
        const st_face *A = &c->s->faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || (af == f && ae == eid)) {
            ncorners = i - 2;
            break;
        }
        cface[i] = af;
        cedge[i] = ae;
        int sub = is_subface(c, af);
        if (prev_sub && !sub && c->s->faces[af].adjface[(ae + 3) % 4] == prevf) {
            int primary = i == 1;
            pk_subface_to_main(k, eid + primary * 2);
            pk_rotate(k, eid - ae + 3 - primary);
            split_apply(c, k, af, depth + 1);
            return;
        }
        prev_sub = sub;
    }
    if (ncorners == 1) {
        apply_to_corner_face(c, k, f, eid, cface[1], cedge[1], depth);
    } else if (ncorners > 1) {
        pk_rotate(k, eid + 2);
        float w0 = pk_weight(k);
        float nw = pk_make_symmetric(k, w0);
        for (int i = 1; i <= ncorners; i++) {
            pk kc;
            pk_set(&kc, k);
            apply_to_corner_face(c, &kc, f, 2, cface[i], cedge[i], depth);
        }
        c->weight += nw * (float)ncorners - w0;
    } else {
        c->weight -= pk_weight(k);
    }
}


/* Ptex's point filter: the level-0 texel under (u, v), clamped into the face. */
static void eval_point(pf *c, uint32_t f, float u, float v, float *out)
{
    const st_face *F = &c->s->faces[f];
    const uint8_t *d;
    int ui = 0, vi = 0;
    if (F->flags & ST_FACE_CONSTANT) {
        d = st_face_level(c->s, f, 0);
    } else {
        int resu = (int)F->w, resv = (int)F->h;
        float fu = u * (float)resu, fv = v * (float)resv;
        ui = fu >= (float)resu ? resu - 1 : fu <= 0 ? 0 : (int)fu;
        vi = fv >= (float)resv ? resv - 1 : fv <= 0 ? 0 : (int)fv;
        d = st_ptexres_data(c->t, c->s, f, F->ulog2, F->vlog2) +
            ((size_t)vi * (size_t)resu + (size_t)ui) * st_dtype_size(c->dt) * c->nc;
    }
    float inv = 1.0f / one_value(c->dt);
    for (unsigned ch = 0; ch < c->nc; ch++)
        out[ch] = c->dt == ST_DT_F32 || c->dt == ST_DT_HALF ? texel_raw(c->dt, d, ch)
                                                           : texel_raw(c->dt, d, ch) * inv;
}

__attribute__((always_inline)) static inline v4f load_dt(const uint8_t *p, unsigned DT, unsigned NC)
{
    switch (DT) {
    case ST_DT_U8: return load_u8(p);
    case ST_DT_U16: return load_u16(p);
    case ST_DT_F32: return load_f32(p);
    default: return pk_half4(p, NC); /* load_any's values without its per-channel switch */
    }
}

/* load_any for the walk (pf_walk's texel: a constant face's texel): load_dt's one vector
 * load of the type (load_any's values lane by lane; it reads past the texel, as
 * const_write's load does), the lanes from nc on cleared as load_any leaves them. */
static pf_v4 walk_texel(unsigned dt, unsigned nc, const uint8_t *p)
{
    static const pk_v4i keep[4] = {{-1, 0, 0, 0}, {-1, -1, 0, 0}, {-1, -1, -1, 0},
                                   {-1, -1, -1, -1}};
    v4f x;
    switch (dt) {
    case ST_DT_U8: x = load_u8(p); break;
    case ST_DT_U16: x = load_u16(p); break;
    case ST_DT_F32: x = load_f32(p); break;
    default: return pk_half4(p, nc); /* its lanes from nc on cleared */
    }
    pk_v4i b;
    memcpy(&b, &x, sizeof b);
    b &= keep[(nc - 1) & 3];
    memcpy(&x, &b, sizeof x);
    return x;
}

/* Ptex's bilinear kernel (pk_build's arithmetic in its order): resolution (ru, rv), first
 * texel (ui, vi) and fractions (fu, fv) of the 2 x 2 texels; weights 1 - fu, fu and 1 - fv,
 * fv. */
typedef struct pf_bil {
    int ru, rv, ui, vi;
    float fu, fv;
} pf_bil;

__attribute__((always_inline)) static inline pf_bil bilinear_kernel(const pf *c,
                                                                    const st_face *F, float u,
                                                                    float v, float uw, float vw)
{
    pf_bil b;
#ifdef __SSE2__
    /* both axes at once (lane 0 u, lane 1 v), the scalar code's operations lane by lane */
    const __m128 one = _mm_set1_ps(1.0f);
    const __m128i e127 = _mm_set1_epi32(127);
    __m128 w = _mm_setr_ps(uw, vw, 0.0f, 0.0f);
    w = _mm_add_ps(_mm_mul_ps(w, _mm_set1_ps(c->width)), _mm_set1_ps(c->blur));
    w = _mm_min_ps(w, one);                                     /* bu < 1 ? bu : 1 */
    __m128i lg = _mm_setr_epi32(F->ulog2, F->vlog2, 0, 0);
    __m128 lo = _mm_castsi128_ps(_mm_slli_epi32(_mm_sub_epi32(e127, lg), 23));
    w = _mm_max_ps(w, lo);                                      /* bu > lu ? bu : lu */
    __m128i r = _mm_sub_epi32(e127, _mm_and_si128(_mm_srli_epi32(_mm_castps_si128(w), 23),
                                                  _mm_set1_epi32(0xff)));
    __m128 rf = _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(r, e127), 23)); /* 2^res */
    __m128 pix = _mm_sub_ps(_mm_mul_ps(_mm_setr_ps(u, v, 0.0f, 0.0f), rf), _mm_set1_ps(0.5f));
    __m128 t = _mm_cvtepi32_ps(_mm_cvttps_epi32(pix));          /* pk_floor */
    __m128 fl = _mm_sub_ps(t, _mm_and_ps(_mm_cmpgt_ps(t, pix), one));
    __m128i fi = _mm_cvttps_epi32(fl);
    __m128 fr = _mm_sub_ps(pix, fl);
    b.ru = _mm_cvtsi128_si32(r);
    b.rv = _mm_cvtsi128_si32(_mm_shuffle_epi32(r, 1));
    b.ui = _mm_cvtsi128_si32(fi);
    b.vi = _mm_cvtsi128_si32(_mm_shuffle_epi32(fi, 1));
    b.fu = _mm_cvtss_f32(fr);
    b.fv = _mm_cvtss_f32(_mm_shuffle_ps(fr, fr, 1));
#else
    float bu = uw * c->width + c->blur, bv = vw * c->width + c->blur;
    bu = bu < 1.0f ? bu : 1.0f;
    bv = bv < 1.0f ? bv : 1.0f;
    float lu = pk_recip_pow2(F->ulog2), lv = pk_recip_pow2(F->vlog2);
    bu = bu > lu ? bu : lu;
    bv = bv > lv ? bv : lv;
    b.ru = pk_res_from_width(bu), b.rv = pk_res_from_width(bv);
    float upix = u * (float)(1 << b.ru) - 0.5f, vpix = v * (float)(1 << b.rv) - 0.5f;
    float uf = pk_floor(upix), vf = pk_floor(vpix);
    b.ui = (int)uf, b.vi = (int)vf;
    b.fu = upix - uf, b.fv = vpix - vf;
#endif
    return b;
}

/* The 2 x 2 texels lie inside the face with both fractions > 0 (then no kernel is needed). */
__attribute__((always_inline)) static inline int bilinear_fits(const pf_bil *b)
{
    return b->ui >= 0 && b->vi >= 0 && b->ui + 1 < (1 << b->ru) && b->vi + 1 < (1 << b->rv) &&
           b->fu > 0.0f && b->fv > 0.0f;
}

/* Writes Ptex's bilinear of the 2 x 2 texels of b inside face f (bilinear_fits(b)). */
__attribute__((always_inline)) static inline void bilinear_write(const pf *c, const st_face *F,
                                                                 uint32_t f, const pf_bil *b,
                                                                 float *out, unsigned DT,
                                                                 unsigned NC)
{
    int ru = b->ru, rv = b->rv, ui = b->ui, vi = b->vi;
    float fu = b->fu, fv = b->fv;
    const uint8_t *d = c->t->px[c->t->base[f] + (size_t)ru * (F->vlog2 + 1u) + (size_t)rv];
    size_t ts = st_dtype_size(DT) * NC, rowb = ts << ru;
    const uint8_t *p = d + (size_t)vi * rowb + (size_t)ui * ts;
    float ku0 = 1.0f - fu, kv0 = 1.0f - fv;
    v4f acc;
    if (DT == ST_DT_HALF && c->bhalf) {
        acc = c->bhalf(p, ts, rowb, ku0, fu, kv0, fv);
    } else {
        v4f r0 = load_dt(p, DT, NC) * ku0 + load_dt(p + ts, DT, NC) * fu;
        v4f r1 = load_dt(p + rowb, DT, NC) * ku0 + load_dt(p + rowb + ts, DT, NC) * fu;
        acc = r0 * kv0 + r1 * fv;
    }
    float scale = 1.0f / ((ku0 + fu) * (kv0 + fv) * one_value(DT));
    for (unsigned ch = 0; ch < NC; ch++)
        out[ch] = acc[ch] * scale;
}

/* ---- a bilinear kernel that overhangs its face (c->small set) ----------------------------
 * split_apply and apply for kernels of at most 2 x 2 texels: the same kernel operations in the
 * same order on the same weights, on pk2 pieces (a pk of at most 2 x 2 weights held at index
 * 0: no weight buffers to copy, no calls per operation), the pieces summed by c->small (bit
 * for bit pf_apply_avx2 on such windows) in the same order; what is left out is the general
 * path's overhead (eval's prologue, pk_build, the window loop's dispatch, pk's bookkeeping).
 * A corner of valence other than 4 without subfaces around it takes corner_other_small
 * (apply_to_corner's steps on the pk2). Anything rarer - a subface neighbour, a constant
 * face - goes to the general functions with the pk the general path would hold at that point, so
 * the results are those of eval bit for bit (test_ptexfilter_paths checks it on every shared
 * file). */

typedef struct pk2 {
    int ulog2, vlog2, u, v, uw, vw;  /* as pk's; uw, vw <= 2 */
    float ku[2], kv[2];              /* weights at index 0 (pk's ku0 = kv0 = 0) */
} pk2;

static void pk2_to_pk(pk *k, const pk2 *p)
{
    k->ulog2 = p->ulog2, k->vlog2 = p->vlog2, k->u = p->u, k->v = p->v;
    k->uw = p->uw, k->vw = p->vw;
    k->ku0 = k->kv0 = k->rot = 0;
    for (int i = 0; i < p->uw; i++)
        k->kub[i] = p->ku[i];
    for (int i = 0; i < p->vw; i++)
        k->kvb[i] = p->kv[i];
}

/* pk_accumulate for n <= 2 with no loop: the same additions in the same order (0 + w[0]
 * first), so the same bits. */
static inline float p2_sum(const float *w, int n)
{
    float r = n > 0 ? 0.0f + w[0] : 0.0f;
    return n > 1 ? r + w[1] : r;
}

static inline float p2_weight(const pk2 *p)
{
    return p2_sum(p->ku, p->uw) * p2_sum(p->kv, p->vw);
}

/* pk_merge_l / _r along one axis of a pk2 (x the first texel, n the width, w the weights,
 * res the size): the overhang folded onto the edge texel (unless black) and dropped. */
static inline void p2_merge_lo(int *x, int *n, float *w, int black)
{
    int o = -*x;
    if (!black)
        w[o] += p2_sum(w, o);
    for (int i = o; i < *n && i < 2; i++) /* i < 2: n <= 2 (lets the compiler unroll) */
        w[i - o] = w[i];
    *n -= o;
    *x = 0;
}
static inline void p2_merge_hi(int x, int *n, float *w, int res, int black)
{
    int o = *n + x - res;
    float *kp = w + *n - o;
    if (!black)
        kp[-1] += p2_sum(kp, o);
    *n -= o;
}
static inline void p2_merge_l(pk2 *p, int black) { p2_merge_lo(&p->u, &p->uw, p->ku, black); }
static inline void p2_merge_b(pk2 *p, int black) { p2_merge_lo(&p->v, &p->vw, p->kv, black); }
static inline void p2_merge_r(pk2 *p, int black)
{
    p2_merge_hi(p->u, &p->uw, p->ku, 1 << p->ulog2, black);
}
static inline void p2_merge_t(pk2 *p, int black)
{
    p2_merge_hi(p->v, &p->vw, p->kv, 1 << p->vlog2, black);
}

/* pk_split_l / _r along one axis: o (a copy of p) gets the part past the low / high edge,
 * p keeps the rest. */
static inline void p2_split_lo(int *x, int *n, float *w, int res, int *ox, int *on, float *ow)
{
    int o = -*x;
    if (o < *n) {
        *ox = res - o;
        *on = o;
        for (int i = 0; i < o && i < 2; i++)
            ow[i] = w[i];
        for (int i = o; i < *n && i < 2; i++)
            w[i - o] = w[i];
        *n -= o;
    } else {
        *ox += res;
        *n = 0;
    }
    *x = 0;
}
static inline void p2_split_hi(int *x, int *n, float *w, int res, int *ox, int *on, float *ow)
{
    int o = *x + *n - res;
    if (o < *n) {
        *ox = 0;
        *on = o;
        for (int i = 0; i < o && i < 2; i++)
            ow[i] = w[*n - o + i];
        *n -= o;
    } else {
        *ox -= res;
        *x = 0;
        *n = 0;
    }
}
static inline void p2_split_l(pk2 *p, pk2 *o)
{
    *o = *p;
    p2_split_lo(&p->u, &p->uw, p->ku, 1 << p->ulog2, &o->u, &o->uw, o->ku);
}
static inline void p2_split_r(pk2 *p, pk2 *o)
{
    *o = *p;
    p2_split_hi(&p->u, &p->uw, p->ku, 1 << p->ulog2, &o->u, &o->uw, o->ku);
}
static inline void p2_split_b(pk2 *p, pk2 *o)
{
    *o = *p;
    p2_split_lo(&p->v, &p->vw, p->kv, 1 << p->vlog2, &o->v, &o->vw, o->kv);
}
static inline void p2_split_t(pk2 *p, pk2 *o)
{
    *o = *p;
    p2_split_hi(&p->v, &p->vw, p->kv, 1 << p->vlog2, &o->v, &o->vw, o->kv);
}

/* pk_rotate: quarter turns (flip u then swap, flip both, flip v then swap). */
static inline void p2_flip(int *x, int n, float *w, int lg)
{
    *x = (1 << lg) - *x - n;
    if (n == 2) {
        float t = w[0];
        w[0] = w[1];
        w[1] = t;
    }
}
static inline void p2_rotate(pk2 *p, int rot)
{
    rot &= 3;
    if (rot == 0)
        return;
    if (rot != 3)
        p2_flip(&p->u, p->uw, p->ku, p->ulog2);
    if (rot != 1)
        p2_flip(&p->v, p->vw, p->kv, p->vlog2);
    if (rot != 2) {
        pk2 t = *p;
        p->ulog2 = t.vlog2, p->vlog2 = t.ulog2, p->u = t.v, p->v = t.u;
        p->uw = t.vw, p->vw = t.uw;
        p->ku[0] = t.kv[0], p->ku[1] = t.kv[1], p->kv[0] = t.ku[0], p->kv[1] = t.ku[1];
    }
}

/* pk_downres_run on at most 2 weights (n >= 1): a pair starting at an even texel is summed,
 * anything else kept. */
static inline void p2_downres(int *x, int *n, float *w)
{
    if (!(*x & 1) && *n == 2) {
        w[0] = w[0] + w[1];
        *n = 1;
    }
    *x /= 2;
}

/* A piece of at most 2 x 2 texels taken down to resolution 2^ul x 2^vl where it is finer:
 * p2_downres along u, then along v, a level at a time. */
__attribute__((always_inline)) static inline void p2_reduce_to(pk2 *k, int ul, int vl)
{
    while (k->ulog2 > ul) {
        p2_downres(&k->u, &k->uw, k->ku);
        k->ulog2--;
    }
    while (k->vlog2 > vl) {
        p2_downres(&k->v, &k->vw, k->kv);
        k->vlog2--;
    }
}

/* apply() for a piece of at most 2 x 2 texels. */
__attribute__((always_inline)) static inline void apply_small(pf *c, pk2 *k, int f)
{
    const st_face *F = &c->s->faces[f];
    if (k->uw <= 0 || k->vw <= 0)
        return;
    p2_reduce_to(k, F->ulog2, F->vlog2);
    if (__builtin_expect(F->flags & ST_FACE_CONSTANT, 0)) {
        /* apply's constant face: its texel times the weight left (no window guard) */
        c->acc += load_any(c->dt, c->nc, c->t->px[c->t->base[f]]) * p2_weight(k);
        return;
    }
    int resu = 1 << k->ulog2;
    if (k->u < 0 || k->v < 0 || k->u + k->uw > resu || k->v + k->vw > (1 << k->vlog2))
        return;
    const uint8_t *d = c->t->px[c->t->base[f] + (size_t)k->ulog2 * (F->vlog2 + 1u) +
                                (size_t)k->vlog2];
    size_t rowb = (size_t)resu * c->ts;
    const uint8_t *base = d + ((size_t)k->v * (size_t)resu + (size_t)k->u) * c->ts;
    c->acc = c->small(base, rowb, k->ku, k->uw, k->kv, k->vw, c->acc);
}

/* apply_across_edge when neither face is a subface (else the general one). */
static void across_small(pf *c, pk2 *k, int f, int eid)
{
    const st_face *F = &c->s->faces[f];
    int af = F->adjface[eid];
    if (is_subface(c, af)) {
        pk g;
        pk2_to_pk(&g, k);
        apply_across_edge(c, &g, f, eid, 0);
        return;
    }
    p2_rotate(k, eid - F->adjedge[eid] + 2);
    apply_small(c, k, af);
}

/* pk_make_symmetric on a pk2: the finer axis reduced (p2_downres: pk_downres_run's steps on
 * at most 2 weights), both cut to the shorter, each pair of weights summed into both, the
 * squared sum scaled down to the initial weight; its operations in its order. */
static inline float p2_make_symmetric(pk2 *k, float initial_weight)
{
    int m = k->ulog2 < k->vlog2 ? k->ulog2 : k->vlog2;
    p2_reduce_to(k, m, m);
    k->uw = k->vw = k->uw < k->vw ? k->uw : k->vw;
    float nw = 0;
    for (int i = 0; i < k->uw && i < 2; i++) {
        float sum = k->ku[i] + k->kv[i];
        k->ku[i] = k->kv[i] = sum;
        nw += sum;
    }
    nw *= nw;
    float scale = nw == 0 ? 1.f : initial_weight / nw;
    if (scale < 1) {
        if (scale < -1) {
            for (int i = 0; i < k->uw && i < 2; i++)
                k->ku[i] *= -1;
            nw = -nw;
        } else {
            for (int i = 0; i < k->uw && i < 2; i++)
                k->ku[i] *= scale;
            nw = initial_weight;
        }
    }
    return nw;
}

/* apply_to_corner at depth 0 on a pk2 when no face around the vertex is a subface (f is
 * not one: the pk2 walk's faces): its ring walk, and its steps - the piece made symmetric
 * and put on each face between the neighbours, the weight adjusted, or, with none, dropped,
 * its weight removed - with the pk2 operations (p2_rotate, p2_weight, p2_make_symmetric,
 * apply_small; apply_to_corner_face without subfaces is pk_rotate then apply). Returns 0
 * (nothing done) when a face of the ring is a subface, or with one face between the
 * neighbours (the ring open past it: corner_small takes the closed one). */
static int corner_other_small(pf *c, pk2 *k, int f, int eid)
{
    enum { MAXV = 10 }; /* apply_to_corner's */
    int af = f, ae = eid, cface[MAXV], cedge[MAXV], ncorners = 0;
    for (int i = 0; i < MAXV; i++) {
        const st_face *A = &c->s->faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || (af == f && ae == eid)) {
            ncorners = i - 2;
            break;
        }
        if (is_subface(c, af))
            return 0;
        cface[i] = af;
        cedge[i] = ae;
    }
    if (ncorners == 1) /* corner_small took the closed ring; an open one: untested here */
        return 0;
    if (ncorners > 1) {
        p2_rotate(k, eid + 2);
        float w0 = p2_weight(k);
        float nw = p2_make_symmetric(k, w0);
        for (int i = 1; i <= ncorners; i++) {
            pk2 kc = *k;
            p2_rotate(&kc, 2 - cedge[i] + 2);
            apply_small(c, &kc, cface[i]);
        }
        c->weight += nw * (float)ncorners - w0;
    } else {
        c->weight -= p2_weight(k);
    }
    return 1;
}

/* apply_to_corner when no face around the vertex is a subface: a regular vertex (valence 4:
 * one diagonal face) here, the others in corner_other_small; else the general one. */
static void corner_small(pf *c, pk2 *k, int f, int eid)
{
    int af = f, ae = eid, cf = -1, ce = 0;
    for (int i = 0; i < 4; i++) {
        const st_face *A = &c->s->faces[af];
        af = A->adjface[ae];
        ae = (A->adjedge[ae] + 1) % 4;
        if (af < 0 || is_subface(c, af) || (af == f && ae == eid) != (i == 3))
            break;
        if (i == 1) {
            cf = af;
            ce = ae;
        }
        if (i == 3) { /* back at (f, eid) after 4 steps: ncorners == 1 */
            p2_rotate(k, eid - ce + 2);
            apply_small(c, k, cf);
            return;
        }
    }
    if (corner_other_small(c, k, f, eid))
        return;
    pk g;
    pk2_to_pk(&g, k);
    apply_to_corner(c, &g, f, eid, 0);
}

/* The split of a kernel that overhangs face f, one walk for both kinds of kernel: the pieces
 * past an edge go to the neighbour (apply_across_edge), past a vertex to the faces around it
 * (apply_to_corner), past a border are merged back (Clamp) or dropped (Discard), and the rest
 * is applied on f. small (a constant where it is inlined) says which kernel the walk holds: a
 * pk (k; the general functions, split_apply) or a pk2 of at most 2 x 2 texels on a face that
 * is not a subface, at depth 0 (k2; the functions above, split_apply_small); the kernel
 * operations and their order are the same. */
#define W_MERGE(D, K, K2, BLACK) (small ? p2_merge_##D(K2, BLACK) : pk_merge_##D(K, BLACK))
#define W_SPLIT(D, K, K2, O, O2) (small ? p2_split_##D(K2, O2) : pk_split_##D(K, O))

__attribute__((always_inline)) static inline void leaf(pf *c, pk *k, pk2 *k2, int f, int small)
{
    if (small)
        apply_small(c, k2, f);
    else
        apply(c, k, f);
}

__attribute__((always_inline)) static inline void to_edge(pf *c, pk *k, pk2 *k2, int f, int eid,
                                                         int depth, int small)
{
    if (small)
        across_small(c, k2, f, eid);
    else
        apply_across_edge(c, k, f, eid, depth);
}

__attribute__((always_inline)) static inline void to_corner(pf *c, pk *k, pk2 *k2, int f,
                                                           int eid, int depth, int small)
{
    if (small)
        corner_small(c, k2, f, eid);
    else
        apply_to_corner(c, k, f, eid, depth);
}

__attribute__((always_inline)) static inline void split_walk(pf *c, pk *k, pk2 *k2, int f,
                                                            int depth, int small)
{
    const st_face *F = &c->s->faces[f];
    int u = small ? k2->u : k->u, v = small ? k2->v : k->v;
    int uw = small ? k2->uw : k->uw, vw = small ? k2->vw : k->vw;
    int resu = 1 << (small ? k2->ulog2 : k->ulog2), resv = 1 << (small ? k2->vlog2 : k->vlog2);
    int sr = u + uw > resu, sl = u < 0;
    int st = v + vw > resv, sb = v < 0;
    int bu = c->bu == 1, bv = c->bv == 1;
    if (c->mode != ST_MODE_TRAVERSE || depth > PF_MAX_DEPTH) {
        int drop = c->mode == ST_MODE_DISCARD;
        if (sr) W_MERGE(r, k, k2, drop || bu);
        if (sl) W_MERGE(l, k, k2, drop || bu);
        if (st) W_MERGE(t, k, k2, drop || bv);
        if (sb) W_MERGE(b, k, k2, drop || bv);
        if (drop)
            c->weight = small ? p2_weight(k2) : pk_weight(k);
        leaf(c, k, k2, f, small);
        return;
    }
    pk ka, kc;
    pk2 ka2, kc2;
    if (sr) {
        if (F->adjface[1] >= 0) {
            W_SPLIT(r, k, k2, &ka, &ka2);
            if (st) {
                if (F->adjface[2] >= 0) {
                    W_SPLIT(t, &ka, &ka2, &kc, &kc2);
                    to_corner(c, &kc, &kc2, f, 2, depth, small);
                } else
                    W_MERGE(t, &ka, &ka2, bv);
            }
            if (sb) {
                if (F->adjface[0] >= 0) {
                    W_SPLIT(b, &ka, &ka2, &kc, &kc2);
                    to_corner(c, &kc, &kc2, f, 1, depth, small);
                } else
                    W_MERGE(b, &ka, &ka2, bv);
            }
            to_edge(c, &ka, &ka2, f, 1, depth, small);
        } else
            W_MERGE(r, k, k2, bu);
    }
    if (sl) {
        if (F->adjface[3] >= 0) {
            W_SPLIT(l, k, k2, &ka, &ka2);
            if (st) {
                if (F->adjface[2] >= 0) {
                    W_SPLIT(t, &ka, &ka2, &kc, &kc2);
                    to_corner(c, &kc, &kc2, f, 3, depth, small);
                } else
                    W_MERGE(t, &ka, &ka2, bv);
            }
            if (sb) {
                if (F->adjface[0] >= 0) {
                    W_SPLIT(b, &ka, &ka2, &kc, &kc2);
                    to_corner(c, &kc, &kc2, f, 0, depth, small);
                } else
                    W_MERGE(b, &ka, &ka2, bv);
            }
            to_edge(c, &ka, &ka2, f, 3, depth, small);
        } else
            W_MERGE(l, k, k2, bu);
    }
    if (st) {
        if (F->adjface[2] >= 0) {
            W_SPLIT(t, k, k2, &ka, &ka2);
            to_edge(c, &ka, &ka2, f, 2, depth, small);
        } else
            W_MERGE(t, k, k2, bv);
    }
    if (sb) {
        if (F->adjface[0] >= 0) {
            W_SPLIT(b, k, k2, &ka, &ka2);
            to_edge(c, &ka, &ka2, f, 0, depth, small);
        } else
            W_MERGE(b, k, k2, bv);
    }
    leaf(c, k, k2, f, small);
}
#undef W_MERGE
#undef W_SPLIT

static void split_apply(pf *c, pk *k, int f, int depth)
{
    split_walk(c, k, NULL, f, depth, 0);
}

/* split_apply at depth 0 on face f (not a subface) for a kernel of at most 2 x 2 texels. */
__attribute__((always_inline)) static inline void split_apply_small(pf *c, pk2 *k, int f)
{
    split_walk(c, NULL, k, f, 0, 1);
}

/* One axis of a kernel at resolution 1 (the face's one texel) folded at the face's edges:
 * n (1 or 2) taps w from texel x (-1 or 0; one tap only at 0), the overhang's one tap merged
 * onto the tap on the texel as pk_merge_l / _r, p2_merge_lo / _hi and fold_r0 merge it (that
 * tap + the overhang's sum 0 + tap: the same bits, no weight being -0), or dropped (black).
 * Returns the weight on the texel. */
static inline float fold1_taps(int x, int n, const float *w, int black)
{
    return n < 2 || black ? w[-x] : w[-x] + w[1 + x];
}

/* One axis of bilinear_fold: the taps 1 - fr and fr from texel x of res (fr 0: the one tap 1
 * at x, inside), *s their p2_sum; the window left after split_walk's merge (p2_merge_lo /
 * _hi: the edge tap plus p2_sum of the overhang's one tap, that tap + 0 + it: the same bits
 * as the tap + it, no weight being -0; black: dropped): its first texel *at, *n taps in w,
 * *kept their p2_sum where a merge left one tap (Discard's weight), else *s. */
static inline void fold2_axis(int x, float fr, int res, int black, float *s, int *at, int *n,
                              float *w, float *kept)
{
    float t0 = 1.0f - fr;
    *at = x;
    w[0] = t0;
    if (fr == 0.0f) { /* one tap, inside: no merge */
        *s = *kept = 0.0f + t0;
        *n = 1;
        return;
    }
    *s = *kept = (0.0f + t0) + fr;
    *n = 1;
    if (x < 0) { /* the tap at -1 past the low edge */
        *at = 0;
        w[0] = black ? fr : fr + t0;
        *kept = w[0];
    } else if (x + 2 > res) { /* the tap at res past the high edge */
        w[0] = black ? t0 : t0 + fr;
        *kept = w[0];
    } else {
        w[1] = fr;
        *n = 2;
    }
}

/* fold2_axis at resolution 1 (the face's one texel: x -1 or 0), the weight on the texel
 * returned (written out: no window to describe). */
static inline float fold1_axis(int x, float fr, int black, float *s, float *kept)
{
    float t0 = 1.0f - fr;
    if (fr == 0.0f) { /* one tap, on the texel: no merge */
        *s = *kept = 0.0f + t0;
        return t0;
    }
    *s = (0.0f + t0) + fr; /* p2_sum */
    *kept = black ? (x < 0 ? fr : t0) : (x < 0 ? fr + t0 : t0 + fr);
    return *kept;
}

/* bilinear_walk's kernel on a face with no neighbour across any edge, where split_walk only
 * merges, in every mode (black: the border mode's, or Discard), then applies what is left
 * (apply_small's window, c->small, at most 2 x 2 texels): the same operations, without the
 * pk2. */
static int bilinear_fold(pf *c, int ru, int rv, int ui, int vi, float fu, float fv, uint32_t f,
                         float *out, float *cov)
{
    int dis = c->mode == ST_MODE_DISCARD;
    float su, sv, ku[2], kv[2], wu, wv;
    pf_v4 acc, zero = {0.0f, 0.0f, 0.0f, 0.0f};
    if (!(ru | rv)) { /* the face's one texel (a footprint of a face or more) */
        ku[0] = fold1_axis(ui, fu, dis || c->bu == 1, &su, &wu);
        kv[0] = fold1_axis(vi, fv, dis || c->bv == 1, &sv, &wv);
        acc = c->small(c->t->px[c->t->base[f]], c->ts, ku, 1, kv, 1, zero);
    } else {
        int u, v, nu, nv, resu = 1 << ru;
        fold2_axis(ui, fu, resu, dis || c->bu == 1, &su, &u, &nu, ku, &wu);
        fold2_axis(vi, fv, 1 << rv, dis || c->bv == 1, &sv, &v, &nv, kv, &wv);
        const uint8_t *d = c->t->px[c->t->base[f] +
                                    (size_t)ru * (c->s->faces[f].vlog2 + 1u) + (size_t)rv];
        acc = c->small(d + ((size_t)v * (size_t)resu + (size_t)u) * c->ts,
                       (size_t)resu * c->ts, ku, nu, kv, nv, zero);
    }
    float total = su * sv, w = total;
    *cov = 1.0f;
    if (dis) {
        w = wu * wv;
        float cv = total != 0.0f ? w / total : 0.0f;
        *cov = cv;
        if (!(w > 0.0f) || cv <= 0.0f)
            return 0;
    }
    float scale = 1.0f / (w * one_value(c->dt));
    for (unsigned ch = 0; ch < c->nc; ch++)
        out[ch] = acc[ch] * scale;
    return 1;
}

/* Face f reads as zero in c's mode: in Traverse its ring is all zero (ptexres.h's
 * ST_PTEXRES_ZRING: every face the split reaches is constant with a texel of zero bytes, no
 * corner changes the weight), in Clamp the face itself (ST_PTEXRES_ZFACE: Clamp folds the
 * kernel onto f at every edge and keeps its whole weight); in Discard the face itself too,
 * but only with c->zdis: Discard divides by the weight it keeps in f, which is positive for
 * those kernels (the tap of the texel holding (u, v), in f, weighs > 0: the gaussian's
 * within half a texel of the centre, the box's covering it, bilinear's >= 1/4), so its sum of
 * +0 pieces over it is +0 as well; without c->zdis the coverage (kept / total) is wanted, or a
 * kernel with negative taps might keep a weight <= 0 (the zero rule). */
static inline int zero_in_mode(const pf *c, int f)
{
    unsigned bit = c->mode == ST_MODE_TRAVERSE ? ST_PTEXRES_ZRING
                   : c->mode == ST_MODE_CLAMP || c->zdis ? ST_PTEXRES_ZFACE
                                                         : 0u;
    return (c->t->lanef[f] & bit) != 0;
}

/* A query on face f that reads as zero (zero_in_mode) with a kernel of weight w (its
 * pk_weight, zeros stripped, not empty) in (0, +inf): every path (const_write inside the
 * face, the walk or fold, or eval_kernel's split across it) sums +0 (each piece adds 0 times
 * a finite weight: +-0) and divides by w, so the result is +0 times 1 / (w one), written
 * here without the walk, coverage 1. 1 when written; else 0, nothing written. */
static inline int zero_ring_q(const pf *c, int f, float w, float *out)
{
    uint32_t wb;
    memcpy(&wb, &w, sizeof wb);
    if (!zero_in_mode(c, f) || wb - 1u >= 0x7f7fffffu)
        return 0;
    pf_put_scaled(out, (pf_v4){0.0f, 0.0f, 0.0f, 0.0f}, 1.0f / (w * one_value(c->dt)), c->nc);
    return 1;
}

/* eval's kernel path for the bilinear kernel of lane j of lk (its resolution, first texel and
 * fractions; a query of its own passes lane 0 of a local one: the lanes' hand-over passes
 * its set-up as it lies, with no copy) on face f (open_face: plain or constant) in every
 * mode, by the walk: the 2 x 2 texels overhang the face, or a fraction is 0 (a query on a
 * texel centre: the zero weight stripped as pk_strip_zeros does; 1 - fraction is never 0).
 * On a face with no neighbour across any edge the merges alone (bilinear_fold, which sums
 * f's window: callers do not pass a constant face without neighbours). Returns 0 (nothing
 * written) when Discard keeps no weight: eval then runs (its zero-coverage rule). */
static int bilinear_walk(pf *c, const pf_lanes_kern *lk, unsigned j, uint32_t f, float *out,
                         float *cov)
{
    int ru = lk->ru[j], rv = lk->rv[j], ui = lk->ui[j], vi = lk->vi[j];
    float fu = lk->fu[j], fv = lk->fv[j];
    if ((c->t->lanef[f] & 0xf0u) == 0xf0u) /* f not constant there: bilinear_q's test */
        return bilinear_fold(c, ru, rv, ui, vi, fu, fv, f, out, cov);
    pk2 k;
    k.ulog2 = ru, k.vlog2 = rv, k.u = ui, k.v = vi;
    k.uw = fu != 0.0f ? 2 : 1;
    k.vw = fv != 0.0f ? 2 : 1;
    k.ku[0] = 1.0f - fu, k.ku[1] = fu;
    k.kv[0] = 1.0f - fv, k.kv[1] = fv;
    c->acc = (v4f){0, 0, 0, 0};
    float su = p2_sum(k.ku, k.uw), sv = p2_sum(k.kv, k.vw);
    float total = su * sv;
    if (zero_ring_q(c, (int)f, total, out)) {
        *cov = 1.0f;
        return 1;
    }
    c->weight = total;
    if (c->mode == ST_MODE_DISCARD) {
        /* split_walk's Discard at depth 0 (the overhang dropped in the order r, l, t, b, the
         * weight left, the piece on f), with the sum of an axis kept when no merge touched
         * it: p2_weight's value, one sum fewer per unmerged axis */
        int sr = k.u + k.uw > 1 << ru, sl = k.u < 0, st = k.v + k.vw > 1 << rv, sb = k.v < 0;
        if (sr) {
            p2_merge_r(&k, 1);
            su = p2_sum(k.ku, k.uw);
        }
        if (sl) {
            p2_merge_l(&k, 1);
            su = p2_sum(k.ku, k.uw);
        }
        if (st) {
            p2_merge_t(&k, 1);
            sv = p2_sum(k.kv, k.vw);
        }
        if (sb) {
            p2_merge_b(&k, 1);
            sv = p2_sum(k.kv, k.vw);
        }
        float w = su * sv; /* c->weight, held where the call below cannot reach it */
        c->weight = w;
        apply_small(c, &k, (int)f);
        /* no clamp to 1 (eval_kernel's, for a dropped negative lobe): the weights here,
         * 1 - fu and fu with fu = upix - floor(upix) in [0, 1) (or NaN), are not negative,
         * so each axis sum left is at most its whole and w <= total: w / total <= 1 */
        float cv = total != 0.0f ? w / total : 0.0f;
        *cov = cv;
        if (!(w > 0.0f) || cv <= 0.0f)
            return 0;
    } else {
        split_apply_small(c, &k, (int)f);
        *cov = 1.0f;
    }
    float scale = 1.0f / (c->weight * one_value(c->dt));
    for (unsigned ch = 0; ch < c->nc; ch++)
        out[ch] = c->acc[ch] * scale;
    return 1;
}

/* b as lane 0 of lk (a query of its own on bilinear_walk) */
static inline void bil_lane0(pf_lanes_kern *lk, const pf_bil *b)
{
    lk->ru[0] = b->ru, lk->rv[0] = b->rv, lk->ui[0] = b->ui, lk->vi[0] = b->vi;
    lk->fu[0] = b->fu, lk->fv[0] = b->fv;
}

/* The 2 x 2 kernel of b on face f in Traverse over plain faces (e2: c->edge2 or NULL;
 * ptexfilter_simd.c: bilinear_walk's weights, walk, total and division, inline): 1 with out
 * written and *cov 1, 0 when there is none, the kernel overhangs a boundary edge, or it
 * declines (nothing written). In Discard and Clamp (trav 0) only a kernel inside the face (a
 * texel centre: a zero fraction), where every mode agrees (Discard keeps the whole weight,
 * coverage 1); one that overhangs goes to the walk's merges. */
__attribute__((always_inline)) static inline int bilinear_edge2(pf *c, pf_edge2_fn e2, int trav,
                                                                int ru, int rv, int ui, int vi,
                                                                float fu, float fv, uint32_t f,
                                                                float *out, float *cov)
{
    if (!e2)
        return 0;
    if (!trav && (ui < 0 || vi < 0 || (fu != 0.0f && ui + 2 > 1 << ru) ||
                  (fv != 0.0f && vi + 2 > 1 << rv)))
        return 0;
    /* a kernel past a mesh boundary edge goes to the walk (its folds) without the attempt
     * (pf_edge2 declines it too, after a call and its set-up) */
    const int *adj = c->s->faces[f].adjface;
    if ((ui < 0 && adj[3] < 0) || (vi < 0 && adj[0] < 0) ||
        (fu != 0.0f && ui + 2 > 1 << ru && adj[1] < 0) ||
        (fv != 0.0f && vi + 2 > 1 << rv && adj[2] < 0) ||
        !e2(&c->walk, (int)f, ru, rv, ui, vi, fu, fv, out))
        return 0;
    *cov = 1.0f;
    return 1;
}

/* The bilinear kernel b that overhangs face f (open_face, not constant) or sits on a texel
 * centre, in every mode: bilinear_edge2 (e2, trav as its), else bilinear_walk (its return
 * value). */
__attribute__((always_inline)) static inline int bilinear_edge_with(pf *c, pf_edge2_fn e2,
                                                                    int trav, pf_bil b,
                                                                    uint32_t f, float *out,
                                                                    float *cov)
{
    if (bilinear_edge2(c, e2, trav, b.ru, b.rv, b.ui, b.vi, b.fu, b.fv, f, out, cov))
        return 1;
    pf_lanes_kern lk;
    bil_lane0(&lk, &b);
    return bilinear_walk(c, &lk, 0, f, out, cov);
}

/* bilinear_edge_with for a query of its own (c's edge2 and mode) */
static int bilinear_edge(pf *c, pf_bil b, uint32_t f, float *out, float *cov)
{
    return bilinear_edge_with(c, c->edge2, c->mode == ST_MODE_TRAVERSE, b, f, out, cov);
}

/* The handed-over lanes whose kernel bilinear_edge2 would offer e2, from the lanes' masks:
 * in Traverse those past no mesh boundary edge, else those inside the face; none without e2. */
static inline unsigned lanes_e2m(pf_edge2_fn e2, int trav, const pf_lanes_kern *lk)
{
    return !e2 ? 0u : trav ? lk->open : lk->inside;
}

/* bilinear_edge_with for lane j of a block the lanes handed over, from their kernel set-up
 * lk: e2m (bit j) says whether bilinear_edge2 would attempt e2 (the lanes' open or inside
 * mask, chosen once per block by mode, 0 without e2), so its checks are not made again. */
__attribute__((always_inline)) static inline int bilinear_edge_lane(pf *c, pf_edge2_fn e2,
                                                                    unsigned e2m,
                                                                    const pf_lanes_kern *lk,
                                                                    unsigned j, uint32_t f,
                                                                    float *out, float *cov)
{
    if (e2m >> j & 1 &&
        e2(&c->walk, (int)f, lk->ru[j], lk->rv[j], lk->ui[j], lk->vi[j], lk->fu[j], lk->fv[j],
           out)) {
        *cov = 1.0f;
        return 1;
    }
    return bilinear_walk(c, lk, j, f, out, cov);
}

static int eval_kernel(pf *c, const pk_params *pp, const st_sample_opts *o, const st_query *q,
                       pk *k, float *out, float *cov);

/* eval_kernel on a kernel of weight w (its pk_weight) inside constant face f, at or under the
 * face's resolution: apply's sum (the face's texel times w, added to zero) divided by w and
 * the type's one value, in eval_kernel's operations; texels of type DT with NC channels
 * (constants where inlined). */
__attribute__((always_inline)) static inline void const_write_at(const uint8_t *texel, float w,
                                                                float *out, unsigned DT,
                                                                unsigned NC)
{
    v4f acc = (v4f){0, 0, 0, 0};
    acc += load_dt(texel, DT, NC) * w; /* load_any's values */
    float scale = 1.0f / (w * one_value(DT));
    pf_put_scaled(out, acc, scale, NC);
}
/* const_write_at of face f's texel */
__attribute__((always_inline)) static inline void const_write(const pf *c, uint32_t f, float w,
                                                             float *out, unsigned DT,
                                                             unsigned NC)
{
    const_write_at(c->t->px[c->t->base[f]], w, out, DT, NC);
}

/* 1 when eval_kernel keeps the whole weight w of a kernel that lies inside its face: in
 * every mode but Discard, and in Discard when w's bits are in (0, +inf) (positive, finite,
 * not NaN: the coverage w / w is 1 exactly). Then the result is apply's sum divided by w
 * with coverage 1, the same bits in every mode. */
static inline int keeps_whole(const pf *c, float w)
{
    uint32_t wb;
    memcpy(&wb, &w, sizeof wb);
    return c->mode != ST_MODE_DISCARD || wb - 1u < 0x7f7fffffu;
}

/* Kernel k (zeros stripped) lies inside its face at its own resolution: every tap on a
 * texel of the face, none to walk. */
static inline int pk_in_face(const pk *k)
{
    return k->u >= 0 && k->v >= 0 && k->u + k->uw <= (1 << k->ulog2) &&
           k->v + k->vw <= (1 << k->vlog2);
}

/* Kernel k (zeros stripped, not empty) of constant face F (f) when it lies inside the face
 * at or under its resolution and every mode keeps its whole weight (its pk_weight in (0,
 * +inf), or not Discard): eval_kernel's result written by const_write, 1; else 0, nothing
 * written (*cov is eval_kernel's 1 either way). */
static inline int const_inside(const pf *c, const pk *k, const st_face *F, uint32_t f,
                               float *out)
{
    if (!pk_in_face(k) || k->ulog2 > F->ulog2 || k->vlog2 > F->vlog2)
        return 0;
    float w = pk_weight(k);
    if (!keeps_whole(c, w))
        return 0;
    const_write(c, f, w, out, c->dt, c->nc);
    return 1;
}

static int eval(pf *c, const pk_params *pp, const st_sample_opts *o, const st_query *q,
                float *out, float *cov)
{
    uint32_t f = q->face;
    const st_face *F = &c->s->faces[f];
    float u = q->u, v = q->v;
    *cov = 1.0f;
    if (pp->ftype == ST_FILTER_PTEX_POINT) {
        eval_point(c, f, u, v, out);
        return ST_Q_OK;
    }
    if (c->t->ptxflags[f] & PTX_FLAG_NBCONSTANT) {
        const uint8_t *d = st_ptexres_data(c->t, c->s, f, 0, 0);
        for (unsigned ch = 0; ch < c->nc; ch++)
            out[ch] = st_channel_get(c->dt, d, ch);
        return ST_Q_OK;
    }
    float uw = fabsf(q->dudx) + fabsf(q->dudy), vw = fabsf(q->dvdx) + fabsf(q->dvdy);
    int black = 0;
    switch (c->bu) {
    case 0: u = u < 0.0f ? 0.0f : u > 1.0f ? 1.0f : u; break;
    case 2: u = u - floorf(u); break;
    default: if (u <= -1.0f || u >= 2.0f) black = 1; break;
    }
    switch (c->bv) {
    case 0: v = v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v; break;
    case 2: v = v - floorf(v); break;
    default: if (v <= -1.0f || v >= 2.0f) black = 1; break;
    }
    if (black) {
        for (unsigned ch = 0; ch < c->nc; ch++)
            out[ch] = 0.0f;
        return ST_Q_OK;
    }
    float width = o->width > 0 ? o->width : 1.0f, blur = o->blur > 0 ? o->blur : 0.0f;
    unsigned kind = F->flags & (ST_FACE_SUBFACE | ST_FACE_CONSTANT);
    if (pp->ftype == ST_FILTER_PTEX_BILINEAR && !kind) {
        pf_bil b = bilinear_kernel(c, F, u, v, uw, vw);
        if (bilinear_fits(&b)) { /* the common case without building a kernel */
            bilinear_write(c, F, f, &b, out, c->dt, c->nc);
            return ST_Q_OK;
        }
    }
    pk k;
    if (F->flags & ST_FACE_SUBFACE) {
        uw = uw * width + blur * 2.0f;
        vw = vw * width + blur * 2.0f;
        pk_build(pp, &k, u * .5f, v * .5f, uw * .5f, vw * .5f, F->ulog2 + 1, F->vlog2 + 1);
        if (k.ulog2 == 0)
            pk_upres_u(&k);
        if (k.vlog2 == 0)
            pk_upres_v(&k);
        k.ulog2--;
        k.vlog2--;
    } else {
        uw = uw * width + blur;
        vw = vw * width + blur;
        pk_build(pp, &k, u, v, uw, vw, F->ulog2, F->vlog2);
    }
    pk_strip_zeros(&k);
    c->acc = (v4f){0, 0, 0, 0};
    if (k.uw <= 0 || k.vw <= 0) {
        for (unsigned ch = 0; ch < c->nc; ch++)
            out[ch] = 0.0f;
        *cov = 0.0f;
        return ST_Q_OK;
    }
    if (kind == ST_FACE_CONSTANT && c->cst && const_inside(c, &k, F, f, out))
        return ST_Q_OK;
    return eval_kernel(c, pp, o, q, &k, out, cov);
}

/* pf_walk_kernel (ptexfilter_walk.c) on kernel k of face f: 1 when it took it (it declines
 * kernels that reach a subface; constant faces it takes since session 19). On a face at a
 * mesh boundary it folds (no overhung edge with a neighbour: pf_walk_fold's merges) or runs
 * the whole walk with its folds (since session 14); one that overhangs one edge only, into a
 * neighbour, walks in walk_one on any face. In Discard and Clamp pf_walk_fold: split_walk's
 * merges and the window on f. eval_kernel does not offer a subface. */
static int walk(pf *c, pk *k, int f)
{
    if (c->mode == ST_MODE_TRAVERSE)
        return pf_walk_kernel(&c->walk, k, f, &c->acc, &c->weight);
    return pf_walk_fold(&c->walk, k, f, c->mode == ST_MODE_DISCARD, &c->acc, &c->weight);
}

/* The rest of eval once the query's kernel k is built with its zeros stripped (uw, vw >= 1):
 * applied to the face or split across its edges, divided by the weight. */
static int eval_kernel(pf *c, const pk_params *pp, const st_sample_opts *o, const st_query *q,
                       pk *k, float *out, float *cov)
{
    int f = (int)q->face;
    *cov = 1.0f;
    c->acc = (v4f){0, 0, 0, 0};
    float total = pk_weight(k);
    c->weight = total;
    if (pk_in_face(k)) {
        apply(c, k, f); /* the kernel lies inside the face: every mode agrees */
        /* with a finite positive total (its bits in (0, +inf)), Discard keeps the whole
         * weight (apply leaves it): total / total is 1 exactly, the coverage already set */
        if (keeps_whole(c, total))
            goto divide;
    } else if (!(c->small && !(c->s->faces[f].flags & ST_FACE_SUBFACE) && walk(c, k, f)))
        /* on a face that is not a subface: the same walk on pieces without copies (walk
         * above: Traverse's splits, Discard's and Clamp's merges; pieces on constant faces
         * their texel times their weight); what it declines: the general walk */
        split_apply(c, k, f, 0);
    if (c->mode == ST_MODE_DISCARD) {
        /* the share of the kernel's weight kept; a sharpening kernel whose dropped lobe was
         * negative keeps more than its total, reported as 1 */
        *cov = total != 0.0f ? c->weight / total : 0.0f;
        if (*cov > 1.0f)
            *cov = 1.0f;
        if (!(c->weight > 0.0f) || *cov <= 0.0f) {
            *cov = 0.0f;
            if (o->zero_rule == ST_ZERO_CLAMP) {
                /* fold everything into the face instead */
                st_sample_opts o2 = *o;
                o2.mode = ST_MODE_CLAMP;
                pf c2 = *c;
                c2.mode = ST_MODE_CLAMP;
                float dummy;
                st_query q2 = *q;
                q2.u = q->u < 0 ? 0 : q->u > 1 ? 1 : q->u;
                q2.v = q->v < 0 ? 0 : q->v > 1 ? 1 : q->v;
                eval(&c2, pp, &o2, &q2, out, &dummy);
                return ST_Q_OK;
            }
            for (unsigned ch = 0; ch < c->nc; ch++)
                out[ch] = NAN;
            return ST_Q_ZERO_COVERAGE;
        }
    }
divide:;
    float scale = 1.0f / (c->weight * one_value(c->dt));
    for (unsigned ch = 0; ch < c->nc; ch++)
        out[ch] = c->acc[ch] * scale;
    return ST_Q_OK;
}

/* ---- one query, specialised per texel type and channel count ----------------------------
 * The batch picks one of these per call (texel type, channel count and filter are the same
 * for every query of a batch): the common cases with the type's loads and no per-texel
 * switch, everything else through eval (same arithmetic in the same order, so the results
 * are the same bit for bit whichever way a query goes). */
typedef int (*pf_query_fn)(pf *c, const pk_params *pp, const st_sample_opts *o,
                           const st_query *q, float *out, float *cov);

/* Ptex's point filter (eval_point) for type DT, NC channels. */
__attribute__((always_inline)) static inline int point_q(pf *c, const st_query *q, float *out, float *cov, unsigned DT,
                          unsigned NC)
{
    uint32_t f = q->face;
    const st_face *F = &c->s->faces[f];
    const uint8_t *d;
    *cov = 1.0f;
    if (F->flags & ST_FACE_CONSTANT) {
        d = st_face_level(c->s, f, 0);
    } else {
        int resu = (int)F->w, resv = (int)F->h;
        float fu = q->u * (float)resu, fv = q->v * (float)resv;
        int ui = fu >= (float)resu ? resu - 1 : fu <= 0 ? 0 : (int)fu;
        int vi = fv >= (float)resv ? resv - 1 : fv <= 0 ? 0 : (int)fv;
        d = c->t->px[c->t->base[f] + (size_t)F->ulog2 * (F->vlog2 + 1u) + F->vlog2] +
            ((size_t)vi * (size_t)resu + (size_t)ui) * (st_dtype_size(DT) * NC);
    }
    v4f x = load_dt(d, DT, NC);
    if (DT == ST_DT_F32 || DT == ST_DT_HALF) {
        for (unsigned ch = 0; ch < NC; ch++)
            out[ch] = x[ch];
    } else {
        float inv = 1.0f / one_value(DT);
        for (unsigned ch = 0; ch < NC; ch++)
            out[ch] = x[ch] * inv;
    }
    return ST_Q_OK;
}

/* The query's face when the filter may take a shortcut on it: no constant neighbourhood,
 * not a subface, (u, v) in [0, 1) (which every border mode leaves as it is); else NULL
 * (eval's general path). A face that is not constant as well is plain (the fused path's,
 * the lanes', the walks'); a constant one takes const_write's shortcuts. */
static inline const st_face *open_face(const pf *c, const st_query *q)
{
    uint32_t f = q->face;
    const st_face *F = &c->s->faces[f];
    if ((c->t->ptxflags[f] & PTX_FLAG_NBCONSTANT) || (F->flags & ST_FACE_SUBFACE) ||
        !(q->u >= 0.0f && q->u < 1.0f && q->v >= 0.0f && q->v < 1.0f))
        return NULL;
    return F;
}

/* Ptex's bilinear filter for type DT, NC channels: the no-kernel path inside the face (on a
 * constant face its texel times the weight), the 2 x 2 kernel's own path when it overhangs
 * (c->small), else eval. */
__attribute__((always_inline)) static inline int bilinear_q(pf *c, const pk_params *pp,
                                                            const st_sample_opts *o,
                                                            const st_query *q, float *out,
                                                            float *cov, unsigned DT,
                                                            unsigned NC)
{
    uint32_t f = q->face;
    const st_face *F = open_face(c, q);
    if (F) {
        pf_bil b = bilinear_kernel(c, F, q->u, q->v, fabsf(q->dudx) + fabsf(q->dudy),
                                   fabsf(q->dvdx) + fabsf(q->dvdy));
        if (!(F->flags & ST_FACE_CONSTANT)) {
            if (bilinear_fits(&b)) {
                bilinear_write(c, F, f, &b, out, DT, NC);
                *cov = 1.0f;
                return ST_Q_OK;
            }
            if (c->small && bilinear_edge(c, b, f, out, cov))
                return ST_Q_OK;
        } else {
            /* a constant face: the kernel (a zero fraction's tap stripped) inside it, its
             * texel times the kernel's pk_weight, (1 - fu + fu)(1 - fv + fv) (with fu 0 the
             * stripped axis' 0 + 1: the same 1); else the 2 x 2 kernel's walk as on a plain
             * face (not bilinear_edge2 nor, on a face without neighbours, bilinear_fold: both
             * read f's texels; eval's general walk takes those) */
            int uw = b.fu != 0.0f ? 2 : 1, vw = b.fv != 0.0f ? 2 : 1;
            if (b.ui >= 0 && b.vi >= 0 && b.ui + uw <= 1 << b.ru && b.vi + vw <= 1 << b.rv) {
                const_write(c, f, (1.0f - b.fu + b.fu) * (1.0f - b.fv + b.fv), out, DT, NC);
                *cov = 1.0f;
                return ST_Q_OK;
            }
            pf_lanes_kern lk;
            bil_lane0(&lk, &b);
            if (c->small && (c->t->lanef[f] & 0xf0u) != 0xf0u && /* not bilinear_fold's */
                bilinear_walk(c, &lk, 0, f, out, cov))
                return ST_Q_OK;
        }
    }
    return eval(c, pp, o, q, out, cov);
}

/* eval_kernel for kernel k (zeros stripped, overhanging, weight its pk_weight) of face f,
 * neither a subface nor constant, when the walk takes it (ptexfilter_walk.c): in Traverse
 * pf_walk_kernel (the pieces summed as split_walk sums them, the weight adjusted at corners
 * as it does), in Discard and Clamp pf_walk_fold (the overhang merged, the window on f; in
 * Discard the weight kept, with eval_kernel's coverage), divided by the weight, without
 * eval_kernel's frame and checks; 0 when it declines or Discard keeps no weight (nothing
 * written, k as it was: eval_kernel then runs, its zero-coverage rule included). Clamp
 * leaves k merged (split_walk's pk_merge_* would too; no caller reads it after). */
__attribute__((always_inline)) static inline int kernel_walk_wr(pf *c, pk *k, int f,
                                                                float weight, float *out,
                                                                float *cov, int r0)
{
    pf_v4 acc = {0.0f, 0.0f, 0.0f, 0.0f};
    float cv = 1.0f;
    if (c->mode == ST_MODE_TRAVERSE) {
        if (!(r0 ? pf_walk_kernel_r0 : pf_walk_kernel)(&c->walk, k, f, &acc, &weight))
            return 0;
    } else if (c->mode == ST_MODE_DISCARD) {
        float total = weight;
        if (!pf_walk_fold(&c->walk, k, f, 1, &acc, &weight))
            return 0;
        cv = total != 0.0f ? weight / total : 0.0f;
        if (cv > 1.0f)
            cv = 1.0f;
        if (!(weight > 0.0f) || cv <= 0.0f)
            return 0;
    } else if (!pf_walk_fold(&c->walk, k, f, 0, &acc, &weight))
        return 0;
    pf_put_scaled(out, acc, 1.0f / (weight * one_value(c->dt)), c->nc);
    *cov = cv;
    return 1;
}

/* kernel_walk_wr with pf_walk_kernel in Traverse (r0: pf_walk_kernel_r0, for kernel_r0's
 * kernels at resolution 1 x 1). */
__attribute__((always_inline)) static inline int kernel_walk_w(pf *c, pk *k, int f,
                                                               float weight, float *out,
                                                               float *cov)
{
    return kernel_walk_wr(c, k, f, weight, out, cov, 0);
}

/* kernel_walk_w with the kernel's weight pk_weight(k). */
__attribute__((always_inline)) static inline int kernel_walk(pf *c, pk *k, int f,
                                                             float *out, float *cov)
{
    return kernel_walk_w(c, k, f, pk_weight(k), out, cov);
}

/* pk_build for a width-4 filter (gaussian, bicubic family), inline: its width-4 branch with
 * the same pk_width4_axis and the same evaluations (pf_kernel_eval2_avx2 for both axes,
 * pf_kernel_eval1_avx2 for one, pk_kernel_eval without AVX2), so the same kernel bit for
 * bit, without the call and its filter-type tests. */
__attribute__((always_inline)) static inline void build_w4(const pk_params *p, pk *k, float u,
                                                           float v, float uw, float vw,
                                                           int fulog2, int fvlog2)
{
    k->ku0 = k->kv0 = k->rot = 0;
    float x1u = 0, su = 0, x1v = 0, sv = 0;
    int eu = pk_width4_axis(&k->ulog2, &k->u, &k->uw, k->kub, u, uw, fulog2, &x1u, &su);
    int ev = pk_width4_axis(&k->vlog2, &k->v, &k->vw, k->kvb, v, vw, fvlog2, &x1v, &sv);
    if (!p->avx2) {
        if (eu)
            pk_kernel_eval(p, x1u, su, k->kub, k->uw);
        if (ev)
            pk_kernel_eval(p, x1v, sv, k->kvb, k->vw);
    } else if (eu && ev)
        pf_kernel_eval2_avx2(p, x1u, su, k->kub, k->uw, x1v, sv, k->kvb, k->vw);
    else if (eu)
        pf_kernel_eval1_avx2(p, x1u, su, k->kub, k->uw);
    else if (ev)
        pf_kernel_eval1_avx2(p, x1v, sv, k->kvb, k->vw);
}

/* One axis of a width-4 kernel at resolution 2^0 (a width of a face or more, not NaN):
 * pk_width4_axis' last case (2 taps at u - 0.5 rounded down, the hermite weight and its
 * complement) with pk_strip_zeros' end taps removed (w0 is 0 only when w1 is 1, and the
 * other way round: one tap is left, written first, as at kub + ku0). Returns the axis'
 * pk_accumulate: (0 + w0) + w1, or 0 + the one tap. */
__attribute__((always_inline)) static inline float build_r0_axis(float u, int *ku, int *kw,
                                                                 float *w)
{
    float upix = u - .5f;
    float ui = pk_floor(upix);
    float w0 = pk_hermite_blur(upix - ui), w1 = 1 - w0;
    *ku = (int)ui;
    *kw = 2;
    w[0] = w0;
    w[1] = w1;
    if (__builtin_expect(w0 == 0, 0)) {
        *ku += 1;
        *kw = 1;
        w[0] = w1;
        return 0.0f + w1;
    }
    if (__builtin_expect(w1 == 0, 0)) {
        *kw = 1;
        return 0.0f + w0;
    }
    return (0.0f + w0) + w1;
}

/* pk_strip_zeros of a kernel pk_build_w4s (or build_w4) made: its common case without the
 * test that picks it, which such a kernel always passes (ku0 = kv0 = 0; along each axis 2 to
 * PK_MAX / 2 taps: 4 or 2 at resolutions 1 and 0, an even count of at least 2 at resolution
 * 2, and under a width of 1/4 the taps over 4 widths of at least a texel each, clamped to
 * PK_MAX / 2). */
__attribute__((always_inline)) static inline void strip_w4(pk *k)
{
    pk_strip_axis_m(&k->ku0, &k->u, &k->uw, pk_nonzero_mask24(k->kub, k->uw));
    pk_strip_axis_m(&k->kv0, &k->v, &k->vw, pk_nonzero_mask24(k->kvb, k->vw));
}

/* kernel_declined_with's steps for a width-4 kernel at resolution 1 x 1 (pk_width4_axis'
 * last case on both axes, stripped: 1 or 2 taps an axis). Out of line: kernel_run's batch
 * loop keeps its registers for the other kernels. */
__attribute__((noinline)) static int kernel_r0(pf *c, const pk_params *pp,
                                               const st_sample_opts *o, const st_query *q,
                                               float *out, float *cov)
{
    pk k;
    k.ulog2 = k.vlog2 = k.ku0 = k.kv0 = k.rot = 0;
    float wu = build_r0_axis(q->u, &k.u, &k.uw, k.kub);
    float wv = build_r0_axis(q->v, &k.v, &k.vw, k.kvb);
    if (k.u >= 0 && k.v >= 0 && k.u + k.uw <= 1 && k.v + k.vw <= 1) {
        if (keeps_whole(c, wu * wv)) {
            c->acc = (v4f){0, 0, 0, 0};
            apply(c, &k, (int)q->face);
            float scale = 1.0f / (wu * wv * one_value(c->dt));
            for (unsigned ch = 0; ch < c->nc; ch++)
                out[ch] = c->acc[ch] * scale;
            *cov = 1.0f;
            return ST_Q_OK;
        }
    } else if (c->small && kernel_walk_wr(c, &k, (int)q->face, wu * wv, out, cov, 1))
        return ST_Q_OK;
    return eval_kernel(c, pp, o, q, &k, out, cov);
}

/* One axis of kernel_iso's kernel (a width of half a face or more, not NaN): pk_width4_axis
 * (its last two cases: 4 hermite taps at resolution 2, or 2 at resolution 1) and
 * pk_strip_axis12, as build_w4 and pk_strip_zeros make it: resolution *lg, first texel *at,
 * *n taps from w + *k0. Returns their pk_accumulate. */
__attribute__((always_inline)) static inline float iso_axis(float u, float uw, int fres, int *lg,
                                                            int *at, int *n, int *k0, float *w)
{
    float x1, st;
    *k0 = 0;
    if (pk_width4_axis(lg, at, n, w, u, uw, fres, &x1, &st)) {
        *n = 0; /* a width under half the face (not for kernel_iso) */
        return 0.0f;
    }
    /* pk_accumulate of the taps left: at resolution 2 the 4 taps' sum from 0 in order, the
     * same bits (the stripped end taps are +0: a zero added to the sum leaves it, a run of
     * zeros before the first tap leaves 0; the weights are never -0) */
    float sum = *lg ? (((0.0f + w[0]) + w[1]) + w[2]) + w[3] : 0.0f;
    pk_strip_axis12(k0, at, n, w);
    return *lg ? sum : pk_accumulate(w + *k0, *n);
}

/* A width-4 kernel of half a face or more along both axes (bu, bv >= 1/2, not NaN) on plain
 * face q->face with no neighbour across any edge (c->iso): what kernel_declined_with (or
 * kernel_r0) does, without the pk and the walk's dispatch. The kernel as build_w4 /
 * build_r0_axis and pk_strip_zeros make it (1 to 4 taps an axis at resolution 2 or 1), its
 * weight pk_weight's; inside the face apply's window (c->win), in every mode that keeps the
 * whole weight (keeps_whole); else, in Traverse and Clamp, the walk of a face without
 * neighbours, which in both modes is pf_walk_fold's Clamp fold (fold(), fold_r0: the same
 * sums) and put_window's window choice. Returns the status, or -1 (nothing written) where
 * fold declines, Discard would drop taps or keep a part of the weight, or the kernel is
 * empty: the caller's path then. */
__attribute__((noinline)) static int kernel_iso(pf *c, const st_query *q, int ulog2, int vlog2,
                                                float bu, float bv, float *out, float *cov)
{
    /* pk_strip_axis12 reads 4 (12 for more taps: none here); a width of a face or more
     * writes 2 taps, and the lanes past them are loaded, then masked off: zeroed, so that
     * no indeterminate value is read (gcc -O1 cannot tell that n <= 4 keeps the loads of
     * lanes 4..11 from running) */
    float ku[12] = {0}, kv[12] = {0};
    int lu, lv, u, v, nu, nv, au, av;
    float su = iso_axis(q->u, bu, ulog2, &lu, &u, &nu, &au, ku);
    float sv = iso_axis(q->v, bv, vlog2, &lv, &v, &nv, &av, kv);
    if (nu <= 0 || nv <= 0)
        return -1;
    float *pu = ku + au, *pv = kv + av;
    float weight = su * sv; /* pk_weight */
    int resu = 1 << lu, resv = 1 << lv;
    pf_window_fn fn = c->win;
    if (!keeps_whole(c, weight))
        return -1;
    if ((u < 0) | (u + nu > resu) | (v < 0) | (v + nv > resv)) {
        if (c->mode == ST_MODE_DISCARD || (u >= resu) | (u + nu <= 0) | (v >= resv) |
                                              (v + nv <= 0))
            return -1; /* Discard's drop, or fold declines */
        pf_fold_axis(resu, &u, &nu, &pu, c->walk.black_u);
        pf_fold_axis(resv, &v, &nv, &pv, c->walk.black_v);
        if ((((uint32_t)nu - 1u) | ((uint32_t)nv - 1u)) < 2u)
            fn = c->small;
    }
    const uint8_t *d = c->t->px[c->t->base[q->face] + (size_t)lu * (vlog2 + 1u) + (size_t)lv];
    pf_v4 acc = fn(d + ((size_t)v * (size_t)resu + (size_t)u) * c->ts, (size_t)resu * c->ts, pu,
                   nu, pv, nv, (pf_v4){0.0f, 0.0f, 0.0f, 0.0f});
    float scale = 1.0f / (weight * one_value(c->dt));
    for (unsigned ch = 0; ch < c->nc; ch++)
        out[ch] = acc[ch] * scale;
    *cov = 1.0f;
    return ST_Q_OK;
}

/* kernel_q's query whose kernel the fused path does not take (a width-4 kernel of 1/4 face or
 * wider, a weight <= 0, no taps) on plain face F: eval's kernel path without its prologue,
 * which a plain face with (u, v) in [0, 1) passes through unchanged. The face and widths are
 * recomputed from q so that kernel_q keeps nothing live across the fused call (its spills
 * cost the in-face queries more than the recomputation costs the others). */
__attribute__((always_inline)) static inline int kernel_declined_with(pf *c,
                                                                      const pk_params *pp,
                                                                      const st_sample_opts *o,
                                                                      const st_query *q,
                                                                      int ulog2, int vlog2,
                                                                      float bu, float bv,
                                                                      float *out, float *cov)
{
    pk k;
    if (pp->ftype != ST_FILTER_PTEX_BOX) {
        if (bu >= 1.0f && bv >= 1.0f)
            return kernel_r0(c, pp, o, q, out, cov);
        /* half a face wide or more (not both a face: kernel_r0's), on a face without
         * neighbours (lanef's four boundary bits) */
        if (__builtin_expect(bu >= .5f && bv >= .5f && c->iso &&
                                 (c->t->lanef[q->face] & 0xf0u) == 0xf0u, 0)) {
            int r = kernel_iso(c, q, ulog2, vlog2, bu, bv, out, cov);
            if (r >= 0)
                return r;
        }
    }
    /* the width-4 kernel's pk_weight (after the strip) from its build, without pk_weight's
     * loops (pk_build_w4s) */
    float weight;
    if (pp->ftype != ST_FILTER_PTEX_BOX) {
        weight = pk_build_w4s(pp, &k, q->u, q->v, bu, bv, ulog2, vlog2);
        strip_w4(&k);
    } else {
        pk_build(pp, &k, q->u, q->v, bu, bv, ulog2, vlog2);
        pk_strip_zeros(&k);
        weight = pk_weight(&k); /* not read when the kernel is empty */
    }
    if (k.uw <= 0 || k.vw <= 0) {
        for (unsigned ch = 0; ch < c->nc; ch++)
            out[ch] = 0.0f;
        *cov = 0.0f;
        return ST_Q_OK;
    }
    if (pk_in_face(&k)) {
        if (keeps_whole(c, weight)) {
            /* inside the face: eval_kernel's apply and division (its Discard rules aside) */
            c->acc = (v4f){0, 0, 0, 0};
            apply(c, &k, (int)q->face);
            pf_put_scaled(out, c->acc, 1.0f / (weight * one_value(c->dt)), c->nc);
            *cov = 1.0f;
            return ST_Q_OK;
        }
    } else if (c->small && kernel_walk_w(c, &k, (int)q->face, weight, out, cov))
        return ST_Q_OK;
    return eval_kernel(c, pp, o, q, &k, out, cov);
}

/* kernel_declined_with with the face's size and the widths recomputed from q. */
__attribute__((always_inline)) static inline int kernel_declined(pf *c, const pk_params *pp,
                                                     const st_sample_opts *o, const st_query *q,
                                                     float *out, float *cov)
{
    const st_face *F = &c->s->faces[q->face];
    float uw = fabsf(q->dudx) + fabsf(q->dudy), vw = fabsf(q->dvdx) + fabsf(q->dvdy);
    return kernel_declined_with(c, pp, o, q, F->ulog2, F->vlog2, uw * c->width + c->blur,
                                vw * c->width + c->blur, out, cov);
}

/* kernel_qi's query on constant face F (neither a subface nor with a constant
 * neighbourhood, (u, v) in [0, 1), which every border mode leaves as it is): eval's kernel
 * path without its prologue, built as kernel_declined_with builds it, its pk_weight taken
 * once; a kernel inside the face, at or under its resolution, to const_write (const_inside's
 * test: the weight one that every mode keeps);
 * one that overhangs the face to the walk as kernel_declined_with sends a plain face's
 * (eval_kernel's walk and division without its frame: in Traverse pf_walk_kernel_cst, whose
 * lean cases take constant faces, in the other modes kernel_walk_w); any other, or what the
 * walk declines, to eval_kernel. */
__attribute__((noinline)) static int kernel_const(pf *c, const pk_params *pp,
                                                  const st_sample_opts *o, const st_query *q,
                                                  const st_face *F, float *out, float *cov)
{
    if ((pp->ftype == ST_FILTER_PTEX_GAUSSIAN || pp->ftype == ST_FILTER_PTEX_BOX) &&
        zero_in_mode(c, (int)q->face)) {
        /* zero_ring_q's result without the kernel: the kernel's weight is in (0, +inf) and
         * far from both ends for any width, so 1 / (w one) is positive and finite, and +0
         * times it is +0. The gaussian (u, v in [0, 1)): pk_width4_axis picks a step of at
         * most one texel on each axis, so some tap lies within half a texel of the centre,
         * weight exp(-2 x^2) >= exp(-1/2) (or, at widths of half a face and more, hermite
         * taps whose nearest weighs > 0.6, two that sum to 1), and no tap is negative, past
         * 1 or NaN; at most 16 taps an axis. The box: each axis' taps are the coverage of
         * texels of the level the width picks (the width clamped to [a texel of the face,
         * 1], NaN to 1), in [0, 1], summing to the width in that level's texels, 1 to 2;
         * at most 3 taps an axis */
        for (unsigned ch = 0; ch < c->nc; ch++)
            out[ch] = 0.0f;
        *cov = 1.0f;
        return ST_Q_OK;
    }
    float bu = (fabsf(q->dudx) + fabsf(q->dudy)) * c->width + c->blur;
    float bv = (fabsf(q->dvdx) + fabsf(q->dvdy)) * c->width + c->blur;
    pk k;
    if (pp->ftype != ST_FILTER_PTEX_BOX) {
        build_w4(pp, &k, q->u, q->v, bu, bv, F->ulog2, F->vlog2);
        strip_w4(&k);
    } else {
        pk_build(pp, &k, q->u, q->v, bu, bv, F->ulog2, F->vlog2);
        pk_strip_zeros(&k);
    }
    float w = pk_weight(&k); /* not read when the kernel is empty */
    if (k.uw <= 0 || k.vw <= 0)
        return eval(c, pp, o, q, out, cov);
    *cov = 1.0f;
    int f = (int)q->face;
    if (zero_ring_q(c, f, w, out))
        return ST_Q_OK;
    if (pk_in_face(&k)) {
        /* const_inside's test with this weight */
        if (k.ulog2 <= F->ulog2 && k.vlog2 <= F->vlog2 && keeps_whole(c, w)) {
            const_write(c, q->face, w, out, c->dt, c->nc);
            return ST_Q_OK;
        }
    } else if (c->small) {
        if (c->mode != ST_MODE_TRAVERSE) {
            if (kernel_walk_w(c, &k, f, w, out, cov))
                return ST_Q_OK;
        } else {
            /* kernel_walk_wr's Traverse with the constant face's walk */
            pf_v4 acc = {0.0f, 0.0f, 0.0f, 0.0f};
            if (pf_walk_kernel_cst(&c->walk, &k, f, &acc, &w)) {
                pf_put_scaled(out, acc, 1.0f / (w * one_value(c->dt)), c->nc);
                return ST_Q_OK;
            }
        }
    }
    c->acc = (v4f){0, 0, 0, 0};
    return eval_kernel(c, pp, o, q, &k, out, cov);
}

/* Box and width-4 filters: the fused path (ptexfilter_simd.c) when the kernel lies inside
 * the face (every mode agrees there), kernel_const on a constant face, else eval. Inlined
 * into kernel_run's batch loop; kernel_q is the per-query function of the same. */
__attribute__((always_inline)) static inline int kernel_qi(pf *c, const pk_params *pp,
                                                           const st_sample_opts *o,
                                                           const st_query *q, float *out,
                                                           float *cov)
{
    const st_face *F = open_face(c, q);
    if (!F)
        return eval(c, pp, o, q, out, cov);
    if (F->flags & ST_FACE_CONSTANT)
        return kernel_const(c, pp, o, q, F, out, cov);
    float uw = fabsf(q->dudx) + fabsf(q->dudy), vw = fabsf(q->dvdx) + fabsf(q->dvdy);
    float bu = uw * c->width + c->blur, bv = vw * c->width + c->blur;
    /* a width-4 kernel of 1/4 face or wider (the width clamped to a texel first, so any
     * width on a face of fewer than 8 texels along an axis) is one the fused path declines
     * (w4_axes' first test; NaN widths are offered, as before): not offered it */
    if (pp->ftype != ST_FILTER_PTEX_BOX &&
        (bu >= .25f || bv >= .25f || F->ulog2 < 3 || F->vlog2 < 3))
        return kernel_declined(c, pp, o, q, out, cov);
    pk k;
    int r = c->fast(pp, c->t->px + c->t->base[q->face], F->ulog2, F->vlog2, q->u, q->v, bu, bv,
                    out, &k);
    if (r == 1) {
        *cov = 1.0f;
        return ST_Q_OK;
    }
    if (r == 2) { /* built, stripped, overhangs the face: what eval would have built */
        if (c->small && kernel_walk(c, &k, (int)q->face, out, cov))
            return ST_Q_OK;
        return eval_kernel(c, pp, o, q, &k, out, cov);
    }
    return kernel_declined(c, pp, o, q, out, cov);
}

static int kernel_q(pf *c, const pk_params *pp, const st_sample_opts *o, const st_query *q,
                    float *out, float *cov)
{
    return kernel_qi(c, pp, o, q, out, cov);
}

#define PF_QFN(DT, NC)                                                                      \
    static int point_##DT##_##NC(pf *c, const pk_params *pp, const st_sample_opts *o,      \
                                 const st_query *q, float *out, float *cov)                \
    {                                                                                       \
        (void)pp; (void)o;                                                                  \
        return point_q(c, q, out, cov, DT, NC);                                             \
    }                                                                                       \
    static int bilinear_##DT##_##NC(pf *c, const pk_params *pp, const st_sample_opts *o,   \
                                    const st_query *q, float *out, float *cov)             \
    {                                                                                       \
        return bilinear_q(c, pp, o, q, out, cov, DT, NC);                                   \
    }
#define PF_QFN_NC(DT) PF_QFN(DT, 1) PF_QFN(DT, 2) PF_QFN(DT, 3) PF_QFN(DT, 4)
PF_QFN_NC(0)
PF_QFN_NC(1)
PF_QFN_NC(2)
PF_QFN_NC(3)

/* The query function of a batch (c->fast set already). */
static pf_query_fn query_fn(const pf *c, unsigned filter)
{
#define PF_ROW(F, DT) {F##_##DT##_1, F##_##DT##_2, F##_##DT##_3, F##_##DT##_4}
    static const pf_query_fn point[4][4] = {PF_ROW(point, 0), PF_ROW(point, 1),
                                            PF_ROW(point, 2), PF_ROW(point, 3)};
    static const pf_query_fn bilinear[4][4] = {PF_ROW(bilinear, 0), PF_ROW(bilinear, 1),
                                               PF_ROW(bilinear, 2), PF_ROW(bilinear, 3)};
#undef PF_ROW
    if (c->dt > 3 || c->nc < 1 || c->nc > 4)
        return eval;
    if (filter == ST_FILTER_PTEX_POINT)
        return point[c->dt][c->nc - 1];
    if (filter == ST_FILTER_PTEX_BILINEAR)
        return bilinear[c->dt][c->nc - 1];
    return c->fast ? kernel_q : eval;
}

/* The common case's checks of a query (one vector compare: |u|, |v| and the four derivatives
 * within the bound, NaN failing it, and the face in range): 1 when it passes them all. */
__attribute__((always_inline)) static inline int query_plain(const st_query *qi,
                                                             uint32_t nfaces)
{
    const v4f lima = {ST_MAX_COORD, ST_MAX_COORD, ST_MAX_DERIV, ST_MAX_DERIV};
    const v4f limb = {ST_MAX_DERIV, ST_MAX_DERIV, 1.0f, 1.0f};
    v4f a, b = {qi->dudy, qi->dvdy, 0.0f, 0.0f};
    memcpy(&a, &qi->u, sizeof a);
    v4i ok = (v4f_abs(a) <= lima) & (v4f_abs(b) <= limb);
#ifdef __SSE2__
    int all = _mm_movemask_ps((__m128)ok) == 15;
#else
    int all = ok[0] && ok[1] && ok[2] && ok[3];
#endif
    return qi->face < nfaces && all;
}

/* One query of a batch: query_plain's checks, then qfn; returns its status. */
static inline int one_query(pf *c, const pk_params *pp, const st_sample_opts *o,
                            pf_query_fn qfn, const st_query *qi, float *oi, float *cov)
{
    if (__builtin_expect(query_plain(qi, c->s->info.nfaces), 1))
        return qfn(c, pp, o, qi, oi, cov);
    int st;
    if (qi->face >= c->s->info.nfaces)
        st = ST_Q_BAD_FACE;
    else
        st = isfinite(qi->u) && isfinite(qi->v) && isfinite(qi->dudx) && isfinite(qi->dvdx) &&
                     isfinite(qi->dudy) && isfinite(qi->dvdy)
                 ? ST_Q_BAD_FOOTPRINT : ST_Q_NONFINITE;
    for (unsigned ch = 0; ch < c->nc; ch++)
        oi[ch] = NAN;
    *cov = 0.0f;
    return st;
}

/* The batch along path (pf_path): PF_PATH_BEST is st_ptexfilter_batch. */
/* Query i of a batch one by one: its values, coverage and status written; 1 when it failed. */
static inline int serve(pf *c, const pk_params *pp, const st_sample_opts *o, pf_query_fn qfn,
                        const st_query *q, size_t i, float *out, float *coverage,
                        uint8_t *status)
{
    float cov = 1.0f;
    int st = one_query(c, pp, o, qfn, q + i, out + i * c->nc, &cov);
    if (coverage)
        coverage[i] = cov;
    if (status)
        status[i] = (uint8_t)st;
    return st != ST_Q_OK;
}

/* The point filter's batch for type DT, NC channels: one_query's checks and point_q inline
 * per query (no call per query, coverage and status written directly); a query that fails
 * the checks goes through serve. Returns the number that failed. */
__attribute__((always_inline)) static inline int point_run(pf *c, const pk_params *pp,
                                                           const st_sample_opts *o,
                                                           pf_query_fn qfn,
                                                           const st_query *q, size_t n,
                                                           float *out, float *coverage,
                                                           uint8_t *status, unsigned DT,
                                                           unsigned NC)
{
    uint32_t nfaces = c->s->info.nfaces;
    int bad = 0;
    for (size_t i = 0; i < n; i++) {
        const st_query *qi = q + i;
        if (__builtin_expect(query_plain(qi, nfaces), 1)) {
            float cov;
            point_q(c, qi, out + i * NC, &cov, DT, NC);
            if (coverage)
                coverage[i] = 1.0f;
            if (status)
                status[i] = ST_Q_OK;
            continue;
        }
        bad += serve(c, pp, o, qfn, q, i, out, coverage, status); /* fails its checks */
    }
    return bad;
}

typedef int (*pf_point_run_fn)(pf *c, const pk_params *pp, const st_sample_opts *o,
                               pf_query_fn qfn, const st_query *q, size_t n, float *out,
                               float *coverage, uint8_t *status);
#define PF_PRUN(DT, NC)                                                                     \
    static int point_run_##DT##_##NC(pf *c, const pk_params *pp, const st_sample_opts *o,  \
                                     pf_query_fn qfn, const st_query *q, size_t n,         \
                                     float *out, float *coverage, uint8_t *status)         \
    {                                                                                       \
        return point_run(c, pp, o, qfn, q, n, out, coverage, status, DT, NC);               \
    }
#define PF_PRUN_NC(DT) PF_PRUN(DT, 1) PF_PRUN(DT, 2) PF_PRUN(DT, 3) PF_PRUN(DT, 4)
PF_PRUN_NC(0)
PF_PRUN_NC(1)
PF_PRUN_NC(2)
PF_PRUN_NC(3)

/* The point filter's batch loop for the batch's type and channel count, or NULL. */
static pf_point_run_fn point_run_select(unsigned dt, unsigned nc)
{
#define PF_ROW(DT) {point_run_##DT##_1, point_run_##DT##_2, point_run_##DT##_3, point_run_##DT##_4}
    static const pf_point_run_fn fns[4][4] = {PF_ROW(0), PF_ROW(1), PF_ROW(2), PF_ROW(3)};
#undef PF_ROW
    return dt > 3 || nc < 1 || nc > 4 ? NULL : fns[dt][nc - 1];
}

/* A kernel the fused path handed over (built, stripped, overhanging the face: what eval
 * would have built; weight its pk_weight): the shortcut walk of the mode, else eval_kernel.
 * Returns the status, *cov set. */
static inline int kernel_handed(pf *c, const pk_params *pp, const st_sample_opts *o,
                                const st_query *qi, pk *k, float weight, float *oi,
                                float *cov)
{
    if (c->small && kernel_walk_w(c, k, (int)qi->face, weight, oi, cov))
        return ST_Q_OK;
    return eval_kernel(c, pp, o, qi, k, oi, cov);
}

/* A kernel c->b8 built (kernel_declined_with's build and strip, not empty; weight the
 * weight its build returns), inside the face or not: kernel_declined_with's steps past its
 * build - inside the face apply's window and the division where every mode keeps the
 * weight, else kernel_handed's walk - else eval_kernel. Returns the status, *cov set. */
__attribute__((always_inline)) static inline int kernel_built(pf *c, const pk_params *pp,
                                                             const st_sample_opts *o,
                                                             const st_query *qi, pk *k,
                                                             float weight, float *oi,
                                                             float *cov)
{
    if (pk_in_face(k)) {
        if (keeps_whole(c, weight)) {
            c->acc = (v4f){0, 0, 0, 0};
            apply(c, k, (int)qi->face);
            pf_put_scaled(oi, c->acc, 1.0f / (weight * one_value(c->dt)), c->nc);
            *cov = 1.0f;
            return ST_Q_OK;
        }
    } else if (c->small && kernel_walk_w(c, k, (int)qi->face, weight, oi, cov))
        return ST_Q_OK;
    return eval_kernel(c, pp, o, qi, k, oi, cov);
}

/* kernel_qi's steps past its checks for a query that passed them (face f plain, (u, v) in
 * [0, 1)), the fused path offered (fast) or not (a width-4 kernel it declines): px the face's
 * row of the table, bu, bv the widths with width and blur applied. Returns the status,
 * *cov set. */
__attribute__((always_inline)) static inline int kernel_plain(pf *c, const pk_params *pp,
                                                              const st_sample_opts *o,
                                                              const st_query *qi, int fast,
                                                              const uint8_t *const *px,
                                                              int ulog2, int vlog2, float u,
                                                              float v, float bu, float bv,
                                                              float *oi, float *cov)
{
    *cov = 1.0f;
    if (!fast) /* not offered: the widths and size as computed (kernel_declined's) */
        return kernel_declined_with(c, pp, o, qi, ulog2, vlog2, bu, bv, oi, cov);
    pk k;
    int r = c->fast(pp, px, ulog2, vlog2, u, v, bu, bv, oi, &k);
    if (r == 1)
        return ST_Q_OK;
    if (r == 2) { /* built, stripped, overhangs the face: what eval would have built */
        if (c->small && kernel_walk(c, &k, (int)qi->face, oi, cov))
            return ST_Q_OK;
        return eval_kernel(c, pp, o, qi, &k, oi, cov);
    }
    return kernel_declined(c, pp, o, qi, oi, cov); /* declined: recomputed from qi */
}

/* Lane j of a block of kernel_run_with (query ii): its kernel handed over by the 8-query
 * fused path (handed: kh, its weight kwh) to kernel_handed, else serve for a query that
 * failed the lanes' checks, else kernel_plain; coverage and status written. Returns 1 when
 * it failed. */
__attribute__((always_inline)) static inline int kernel_lane(
    pf *c, const pk_params *pp, const st_sample_opts *o, pf_query_fn qfn, const st_query *q,
    size_t ii, const pf_klanes *k, unsigned j, int handed, pk *kh, float kwh, float *out,
    float *coverage, uint8_t *status, unsigned nc)
{
    float cov;
    int st;
    if (handed) {
        cov = 1.0f;
        st = kernel_handed(c, pp, o, q + ii, kh, kwh, out + ii * nc, &cov);
    } else if (k->cst >> j & 1) { /* checked, on a constant face open_face opens */
        cov = 1.0f;
        st = kernel_const(c, pp, o, q + ii, &c->s->faces[q[ii].face], out + ii * nc, &cov);
    } else if (!(k->plain >> j & 1))
        return serve(c, pp, o, qfn, q, ii, out, coverage, status);
    else
        st = kernel_plain(c, pp, o, q + ii, k->fast >> j & 1, k->px[j], k->ulog2[j],
                          k->vlog2[j], k->u[j], k->v[j], k->bu[j], k->bv[j],
                          out + ii * nc, &cov);
    if (coverage)
        coverage[ii] = cov;
    if (status)
        status[ii] = (uint8_t)st;
    return st != ST_Q_OK;
}

/* The lanes of k->nonb that c->r0x8 and c->iso8 serve (kernel_r0's and kernel_iso's kernels
 * folded on a face without neighbours), their coverage (when cov) and status (when st)
 * written: the mask. */
static unsigned kernel_r0x8(pf *c, const pf_klanes *k, float *out, float *cov, uint8_t *st)
{
    float cv[2][8];
    int dis = c->mode == ST_MODE_DISCARD;
    unsigned r0 = c->r0x8(c->walk.black_u, c->walk.black_v, dis, k, out, cv[0]), m = r0;
    if (k->nonb & ~r0)
        m |= c->iso8(c->walk.black_u, c->walk.black_v, dis, k, out, cv[1]);
    for (unsigned r = m; r; r &= r - 1) {
        unsigned j = (unsigned)__builtin_ctz(r);
        if (cov)
            cov[j] = cv[!(r0 >> j & 1)][j];
        if (st)
            st[j] = ST_Q_OK;
    }
    return m;
}

/* The lanes of mask (kernels handed over by the 8-query fused path, ks[j] with its
 * pk_weight kw[j], on faces without neighbours: k->nonb; q the block's queries): kernel_handed's
 * steps for them (kernel_walk_wr: in every mode pf_walk_fold's fold - at resolution 1 x 1
 * with at most 2 x 2 taps (the box's at a face or more) fold_r0's: fold1_taps, the one
 * texel through c->small; else pf_walk_fold itself on a copy of the kernel; Discard's
 * weight and coverage) and its division, at out + j * nc, coverage (when cov) and status
 * (when st) written. Returns the lanes served; the others (an overhang as wide as the
 * window, Discard keeping no weight) are left. */
__attribute__((noinline)) static unsigned kernel_fold8(pf *c, const pf_klanes *k, pk *ks,
                                                       const float *kw, unsigned mask,
                                                       const st_query *q, float *out,
                                                       float *cov, uint8_t *st)
{
    int dis = c->mode == ST_MODE_DISCARD;
    int blu = dis || c->walk.black_u, blv = dis || c->walk.black_v;
    float one = one_value(c->dt);
    unsigned done = 0, nc = c->nc;
    /* the lanes pf_walk_fold takes: in Traverse and Clamp every lane it folds is served,
     * so in one call, in place (a lane it declines keeps ks[j] as it was); Discard, which may
     * leave a folded lane to the per-query path, on a copy per lane */
    unsigned gen = 0, gok = 0;
    for (unsigned m = mask; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const pk *kj = ks + j;
        gen |= (unsigned)(((kj->ulog2 | kj->vlog2) | (kj->uw > 2) | (kj->vw > 2)) != 0) << j;
    }
    pf_v4 gacc[8];
    if (gen && !dis) {
        for (unsigned m = gen; m; m &= m - 1)
            gacc[__builtin_ctz(m)] = (pf_v4){0.0f, 0.0f, 0.0f, 0.0f};
        gok = pf_walk_fold8(&c->walk, ks, gen, q, gacc);
    }
    for (unsigned m = mask; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const pk *kj = ks + j;
        int u = kj->u, v = kj->v;
        float weight = kw[j], cv = 1.0f;
        pf_v4 acc = {0.0f, 0.0f, 0.0f, 0.0f};
        if (gen >> j & 1) {
            if (!dis) {
                if (!(gok >> j & 1))
                    continue;
                acc = gacc[j];
            } else {
                pk kc = *kj; /* pf_walk_fold folds in place; a lane it declines keeps ks[j] */
                if (!pf_walk_fold(&c->walk, &kc, (int)q[j].face, dis, &acc, &weight))
                    continue;
            }
        } else {
            if ((u >= 1) | (u + kj->uw <= 0) | (v >= 1) | (v + kj->vw <= 0))
                continue;
            float a = fold1_taps(u, kj->uw, kj->kub + kj->ku0, blu);
            float b = fold1_taps(v, kj->vw, kj->kvb + kj->kv0, blv);
            if (dis)
                weight = a * b;
            acc = c->small(k->px[j][0], c->ts, &a, 1, &b, 1, acc);
        }
        if (dis) {
            float total = kw[j];
            cv = total != 0.0f ? weight / total : 0.0f;
            if (cv > 1.0f)
                cv = 1.0f;
            if (!(weight > 0.0f) || cv <= 0.0f)
                continue;
        }
        pf_put_scaled(out + j * nc, acc, 1.0f / (weight * one), nc);
        if (cov)
            cov[j] = cv;
        if (st)
            st[j] = ST_Q_OK;
        done |= 1u << j;
    }
    return done;
}

/* The lanes of mask (of k->nonb) that c->q8 serves (both widths in pf_q8's band:
 * resolution 2 x 2, evaluated taps; everything up to the window 8 at a time), each lane's
 * window summed by the window loop put_window (or apply, inside the face) picks for it and
 * divided as kernel_walk_wr divides; coverage (when cov) and status (when st) written: the
 * mask. */
__attribute__((noinline)) static unsigned kernel_q8(pf *c, const pk_params *pp,
                                                    const pf_klanes *k, unsigned mask,
                                                    float *out, float *cov, uint8_t *st)
{
    pf_q8 t;
    unsigned done = c->q8(pp, k, mask, c->walk.black_u, c->walk.black_v,
                          c->mode == ST_MODE_DISCARD, c->dt, &t),
             nc = c->nc;
    for (unsigned m = done; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const uint8_t *d = k->px[j][2u * ((unsigned)k->vlog2[j] + 1u) + 2u]; /* level (2, 2) */
        int u = t.u[j], v = t.v[j];
        pf_v4 acc = (t.small >> j & 1 ? c->small : c->win)(
            d + ((size_t)v * 4u + (size_t)u) * c->ts, 4u * c->ts, t.wu[j] + u, t.nu[j],
            t.wv[j] + v, t.nv[j], (pf_v4){0.0f, 0.0f, 0.0f, 0.0f});
        pf_put_scaled(out + j * nc, acc, t.scale[j], nc);
        if (cov)
            cov[j] = t.cov[j];
        if (st)
            st[j] = ST_Q_OK;
    }
    return done;
}

/* The lanes of k->cst whose kernel c->cst8 finds inside their constant face (with a weight
 * in (0, +inf)): kernel_const's const_inside result, const_write's operations on the face's
 * texel, coverage (when cov) and status (when st) written: the mask. */
__attribute__((noinline)) static unsigned kernel_cst8(pf *c, const pk_params *pp,
                                                      const pf_klanes *k, float *out,
                                                      float *cov, uint8_t *st)
{
    float w[8];
    unsigned done = c->cst8(pp, k, k->cst, w), nc = c->nc;
    for (unsigned m = done; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        const_write_at(k->px[j][0], w[j], out + j * nc, c->dt, nc);
        if (cov)
            cov[j] = 1.0f;
        if (st)
            st[j] = ST_Q_OK;
    }
    return done;
}

/* A block of 8 queries from q + i (k: klanes8's) with lanes of k->nonb, for a width-4
 * filter: kernel_r0x8's lanes, kernel_q8's, then the others but skip (lanes served
 * already) one by one (kernel_lane; such blocks are mostly of one-face files, where the
 * 8-query fused path finds nothing). Out of line: kernel_run_with's loop keeps its
 * registers for the common blocks. Returns the number that failed. */
__attribute__((noinline)) static int kernel_block_nonb(pf *c, const pk_params *pp,
                                                       const st_sample_opts *o, pf_query_fn qfn,
                                                       const st_query *q, size_t i,
                                                       const pf_klanes *k, unsigned skip,
                                                       float *out, float *coverage,
                                                       uint8_t *status)
{
    unsigned nc = c->nc;
    unsigned r0 = kernel_r0x8(c, k, out + i * nc, coverage ? coverage + i : NULL,
                              status ? status + i : NULL);
    if (c->q8 && (k->nonb & ~r0))
        r0 |= kernel_q8(c, pp, k, k->nonb & ~r0, out + i * nc, coverage ? coverage + i : NULL,
                        status ? status + i : NULL);
    int bad = 0;
    for (unsigned m = ~(r0 | skip) & 0xffu; m; m &= m - 1) {
        unsigned j = (unsigned)__builtin_ctz(m);
        bad += kernel_lane(c, pp, o, qfn, q, i + j, k, j, 0, NULL, 0.0f, out, coverage, status,
                           nc);
    }
    return bad;
}

/* The fewest lanes of a block worth c->b8 (about 1100 instructions a block against about 240
 * a kernel built by kernel_declined_with: callgrind, teapot gaussian). */
enum { B8_MIN = 4 };

/* The batch of the box and width-4 filters with the fused path (qfn is kernel_q). Blocks of
 * 8 queries go through the kernel lanes (kl, ptexfilter_lanes.c, AVX2: one_query's and
 * open_face's checks and kernel_qi's widths and test, lane by lane), then (W8: w8, the box
 * and width-4 filters with AVX2) the fused path's common case of the block at once
 * (ptexfilter_simd.c's pf_box8_select and pf_w4x8_select: served, or its kernel handed
 * over to kernel_handed),
 * then per query the fused path (kernel_plain) for the lanes left; the rest one by one with the same checks in one vector compare
 * ((u, v) in [0, 1), the four derivatives within the bound, NaN failing it; the face in
 * range and plain: together they imply one_query's checks and open_face's) and kernel_qi's
 * widths from the same vector. A query that fails the checks goes through serve
 * (one_query, kernel_q: what it did before, in full). Coverage and status written directly.
 * Returns the number that failed. */
__attribute__((always_inline)) static inline int kernel_run_with(
    pf *c, const pk_params *pp, const st_sample_opts *o, pf_query_fn qfn, const st_query *q,
    size_t n, float *out, float *coverage, uint8_t *status, pf_kernel_lanes_fn kl,
    pf_w4x8_fn w8, const pf_lanes *lc, int W8)
{
    const uint32_t nfaces = c->s->info.nfaces;
    const st_face *faces = c->s->faces;
    const uint8_t *ptxflags = c->t->ptxflags;
    const uint8_t *const *px = c->t->px;
    const uint64_t *base = c->t->base;
    const unsigned nc = c->nc;
    const int w4 = pp->ftype != ST_FILTER_PTEX_BOX;
    const v4f width = {c->width, c->width, 0.0f, 0.0f}, blur = {c->blur, c->blur, 0.0f, 0.0f};
    const v4f zero = {0.0f, 0.0f, 0.0f, 0.0f}, one = {1.0f, 1.0f, 1.0f, 1.0f};
    const v4f lim = {ST_MAX_DERIV, ST_MAX_DERIV, ST_MAX_DERIV, ST_MAX_DERIV};
    int bad = 0;
    size_t i = 0;
    if (kl) {
        pk ks[8];
        float kw[8], kwb[8];
        for (; i + 8 <= n; i += 8) {
            pf_klanes k;
            kl(lc, q + i, &k);
            /* kernels inside constant faces, 8 at a time (cs: the lanes served) */
            unsigned cs = 0;
            if (__builtin_expect(k.cst != 0, 0) && c->cst8)
                cs = kernel_cst8(c, pp, &k, out + i * nc, coverage ? coverage + i : NULL,
                                 status ? status + i : NULL);
            /* the fused path's common case of the width-4 filters, 8 at a time:
             * done, or handed over (over: the kernels in ks, their weights in kw) */
            if (__builtin_expect(k.nonb != 0, 0) && c->r0x8) { /* width-4, no neighbours */
                bad += kernel_block_nonb(c, pp, o, qfn, q, i, &k, cs, out, coverage, status);
                continue;
            }
            unsigned done = 0, over = 0, f2 = k.fast & (k.fast - 1), r0 = cs;
            if (!W8 || !(f2 & (f2 - 1))) { /* under 3 lanes offered: one by one is less */
                /* the width-4 kernels of the lanes not offered to the fused path, which
                 * kernel_declined_with builds one by one, built 8 at a time where c->b8
                 * takes them (bl; ks, kwb) and given to kernel_built, coverage and status
                 * written; then the other lanes (each query on its own: any order) */
                unsigned bl = 0, nf = k.plain & ~(k.fast | k.cst | k.nonb | cs) & 0xffu;
                if (pf_bits_atleast(nf, B8_MIN) && c->b8)
                    bl = c->b8(pp, &k, nf, ks, kwb);
                for (unsigned m = bl; m; m &= m - 1) {
                    unsigned j = (unsigned)__builtin_ctz(m);
                    size_t ii = i + j;
                    float cov = 1.0f;
                    int st = kernel_built(c, pp, o, q + ii, &ks[j], kwb[j], out + ii * nc, &cov);
                    if (coverage)
                        coverage[ii] = cov;
                    if (status)
                        status[ii] = (uint8_t)st;
                    bad += st != ST_Q_OK;
                }
                for (unsigned m = ~(cs | bl) & 0xffu; m; m &= m - 1) {
                    unsigned j = (unsigned)__builtin_ctz(m);
                    bad += kernel_lane(c, pp, o, qfn, q, i + j, &k, j, 0, NULL, 0.0f, out,
                                       coverage, status, nc);
                }
                continue;
            }
            done = w8(pp, &k, out + i * nc, ks, kw, &over);
            if (over & k.nonb && c->small) { /* folds on faces without neighbours */
                unsigned fo = kernel_fold8(c, &k, ks, kw, over & k.nonb, q + i, out + i * nc,
                                           coverage ? coverage + i : NULL,
                                           status ? status + i : NULL);
                over &= ~fo;
                r0 |= fo;
            }
            if (done && (coverage || status)) { /* served: coverage 1, status OK */
                for (unsigned m = done; m; m &= m - 1) {
                    unsigned j = (unsigned)__builtin_ctz(m);
                    if (coverage)
                        coverage[i + j] = 1.0f;
                    if (status)
                        status[i + j] = ST_Q_OK;
                }
            }
            for (unsigned m = ~(done | r0) & 0xffu; m; m &= m - 1) {
                unsigned j = (unsigned)__builtin_ctz(m);
                bad += kernel_lane(c, pp, o, qfn, q, i + j, &k, j, over >> j & 1, &ks[j],
                                   kw[j], out, coverage, status, nc);
            }
        }
    }
    for (; i < n; i++) {
        const st_query *qi = q + i;
        v4f a, d; /* (u, v, dudx, dvdx), (dudx, dvdx, dudy, dvdy): inside the query */
        memcpy(&a, &qi->u, sizeof a);
        memcpy(&d, &qi->dudx, sizeof d);
        v4f ad = v4f_abs(d);
        v4i ok = (a >= zero) & (a < one), okd = ad <= lim;
        int m = (ok[0] & 1) | (ok[1] & 2) | (okd[0] & 4) | (okd[1] & 8) | (okd[2] & 16) |
                (okd[3] & 32);
        uint32_t f = qi->face;
        const st_face *F;
        if (m != 63 || f >= nfaces || (ptxflags[f] & PTX_FLAG_NBCONSTANT) ||
            ((F = &faces[f])->flags & (ST_FACE_SUBFACE | ST_FACE_CONSTANT))) {
            bad += serve(c, pp, o, qfn, q, i, out, coverage, status);
            continue;
        }
        v4f w = ad + (v4f){ad[2], ad[3], 0.0f, 0.0f}; /* |d.x| + |d.y| per axis */
        w = w * width + blur;
        float bu = w[0], bv = w[1], cov;
        /* kernel_qi: a width-4 kernel of 1/4 face or wider is one the fused path declines */
        int fast = !w4 || !(bu >= .25f || bv >= .25f || F->ulog2 < 3 || F->vlog2 < 3);
        int st = kernel_plain(c, pp, o, qi, fast, px + base[f], F->ulog2, F->vlog2, a[0], a[1],
                              bu, bv, out + i * nc, &cov);
        if (coverage)
            coverage[i] = cov;
        if (status)
            status[i] = (uint8_t)st;
        bad += st != ST_Q_OK;
    }
    return bad;
}

/* kernel_run_with, its block loop with the 8-query fused path (w8: the box's or the width-4
 * filters') or without it. */
static int kernel_run(pf *c, const pk_params *pp, const st_sample_opts *o, pf_query_fn qfn,
                      const st_query *q, size_t n, float *out, float *coverage,
                      uint8_t *status, pf_kernel_lanes_fn kl, pf_w4x8_fn w8,
                      const pf_lanes *lc)
{
    if (w8)
        return kernel_run_with(c, pp, o, qfn, q, n, out, coverage, status, kl, w8, lc, 1);
    return kernel_run_with(c, pp, o, qfn, q, n, out, coverage, status, kl, NULL, lc, 0);
}

static int batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                 float *out, float *coverage, uint8_t *status, int path)
{
    if (!s || !o || (!q && n) || (!out && n))
        return ST_EINVAL;
    if (o->filter < ST_FILTER_PTEX_POINT || o->filter > ST_FILTER_PTEX_MITCHELL)
        return ST_EINVAL;
    if (o->mode > ST_MODE_CLAMP)
        return ST_EINVAL;
    if (s->info.kind != ST_KIND_PERFACE)
        return ST_EUNSUPPORTED;
    if (!st_ptexres_get(s))
        return ST_EUNSUPPORTED;
    if (!(o->sharpness >= 0.0f && o->sharpness <= 1.0f) || !(o->width >= 0.0f) ||
        !(o->blur >= 0.0f) || o->width > ST_MAX_DERIV || o->blur > ST_MAX_DERIV)
        return ST_EINVAL;
    if (s->info.meshtype == ST_MESH_TRIANGLE) /* Ptex's point and triangle filters */
        return st_ptextri_batch(s, o, q, n, out, coverage, status);
    st_error be;
    /* built on the first call; pinned so that a budget drop leaves it alone during the batch */
    const st_ptexres *t = st_ptexres_pin(s, &be);
    if (!t)
        return be.code; /* ST_ENOMEM or ST_ETOOBIG; the next call tries again */
    /* Ptex's tanvec edge filter mode rotates what Traverse reads across rotated edges: only
     * the general path does (apply); Discard and Clamp read no neighbour */
    int tanvec = s->info.edgefilter == ST_EDGEFILTER_TANVEC && s->info.nchan >= 2 &&
                 o->mode == ST_MODE_TRAVERSE;
    if (tanvec)
        path = PF_PATH_GENERAL;
    /* Ptex's lerp (width-4 filters only): pk_build makes the blended kernels; no shortcut
     * builds them, so the batch takes the general path */
    int lerp = o->lerp && o->filter >= ST_FILTER_PTEX_GAUSSIAN;
    if (lerp)
        path = PF_PATH_GENERAL;
    int general = path == PF_PATH_GENERAL;
    int avx2 = pf_have_avx2();
    pk_params pp;
    pk_params_init(&pp, o->filter, o->sharpness, avx2);
    pp.lerp = lerp;
    pf c = {.s = s, .t = t, .nc = s->info.nchan, .dt = s->info.dtype, .mode = o->mode,
            .bu = s->info.border_u, .bv = s->info.border_v};
    c.kind = c.dt == ST_DT_U8 ? PF_U8 : c.dt == ST_DT_F32 && c.nc >= 3 ? PF_F32 : PF_OTHER;
    c.tanvec = tanvec;
    c.zdis = o->mode == ST_MODE_DISCARD && !coverage &&
             (o->filter == ST_FILTER_PTEX_GAUSSIAN || o->filter == ST_FILTER_PTEX_BOX ||
              o->filter == ST_FILTER_PTEX_BILINEAR);
    c.fast = general ? NULL : pf_fast_select(c.dt, c.nc, o->filter);
    c.win = pf_window_select(c.dt, c.nc);
    c.small = general ? NULL : pf_small_select(c.dt, c.nc);
    c.ts = st_dtype_size(c.dt) * c.nc;
    c.edge2 = general ? NULL : pf_edge2_select(c.dt, c.nc);
    if (!c.win)
        c.small = NULL, c.edge2 = NULL; /* the shortcut walks need both window loops */
    c.iso = c.small != NULL;
    c.cst = !general;
    int w4 = o->filter > ST_FILTER_PTEX_BOX; /* pf_klanes' nonb means another thing for the box */
    c.r0x8 = c.small && w4 ? pf_r0x8_select(c.dt, c.nc) : NULL;
    c.iso8 = c.small && w4 ? pf_iso8_select(c.dt, c.nc) : NULL;
    c.q8 = c.iso8 ? pf_q8_select() : NULL;
    c.b8 = c.small && w4 ? pf_b8_select(o->filter) : NULL;
    c.cst8 = c.cst && o->filter >= ST_FILTER_PTEX_BOX ? pf_cst8_select(o->filter) : NULL;
    c.walk = (pf_walk){.faces = s->faces, .px = t->px, .base = t->base, .ts = c.ts,
                       .black_u = c.bu == 1, .black_v = c.bv == 1, .win = c.win,
                       .small = c.small,
                       .small4 = c.small ? pf_small4_select(c.dt, c.nc) : NULL,
                       .small2 = c.small ? pf_small2_select(c.dt, c.nc) : NULL,
                       .texel = walk_texel, .dt = c.dt, .nc = c.nc};
    c.bhalf = pf_bilinear_half_select(); /* in eval's in-face bilinear too */
    c.width = o->width > 0 ? o->width : 1.0f;
    c.blur = o->blur > 0 ? o->blur : 0.0f;
    pf_query_fn qfn = general ? eval : query_fn(&c, o->filter);
    /* the bilinear of in-face queries several at a time (ptexfilter_lanes.c), the rest and
     * the tail one by one */
    unsigned nl = 0;
    pf_bilinear_lanes_fn lanes = NULL;
    if (o->filter == ST_FILTER_PTEX_BILINEAR && s->info.nfaces > 0 &&
        (path == PF_PATH_BEST || path == PF_PATH_LANES4))
        lanes = pf_bilinear_lanes_select(c.dt, c.nc, path == PF_PATH_BEST ? 8 : 4, &nl);
    pf_lanes lc = {.faces = s->faces, .lanef = t->lanef, .base = t->base, .px = t->px,
                   .nfaces = s->info.nfaces, .width = c.width, .blur = c.blur};
    if (o->filter == ST_FILTER_PTEX_POINT && !general && point_run_select(c.dt, c.nc)) {
        int bad = point_run_select(c.dt, c.nc)(&c, &pp, o, qfn, q, n, out, coverage, status);
        st_ptexres_unpin(t);
        return bad;
    }
    if (qfn == kernel_q && path == PF_PATH_BEST) {
        int bad = kernel_run(&c, &pp, o, qfn, q, n, out, coverage, status,
                             pf_kernel_lanes_select(o->filter),
                             o->filter == ST_FILTER_PTEX_BOX
                                 ? pf_box8_select(c.dt, c.nc)
                                 : pf_w4x8_select(c.dt, c.nc, o->filter),
                             &lc);
        st_ptexres_unpin(t);
        return bad;
    }
    pf_lanes_kern lk;
    pf_edge2_fn e2 = c.edge2;                  /* bilinear_edge2's, decided once */
    int trav = c.mode == ST_MODE_TRAVERSE;
    int bad = 0;
    unsigned nc = c.nc;
    for (size_t i = 0; i < n;) {
        /* a block of lanes, then [i, end) one by one but for those the lanes served (done)
         * and those whose kernel set-up they handed over (edge: the 2 x 2 kernel's own path
         * from there, when there is one); where the lanes take fewer than 2 of a block
         * (subfaces, constant faces, coordinates outside the face), the next 3 blocks go one
         * by one without them, so such runs pay for a quarter of the lane work that finds
         * nothing */
        unsigned done = 0, edge = 0;
        size_t end = n;
        if (lanes && i + nl <= n) {
            /* the lanes run block after block while each is served whole; coverage 1 and
             * ST_Q_OK for those, then the block they stopped at, if any, as below */
            size_t nblk = (n - i) / nl, whole;
            done = lanes(&lc, q + i, nblk, out + i * nc, &lk, &edge, &whole);
            if (whole) {
                size_t w = whole * nl;
                if (coverage)
                    for (size_t k = 0; k < w; k++)
                        coverage[i + k] = 1.0f;
                if (status)
                    memset(status + i, ST_Q_OK, w);
                i += w;
                if (whole == nblk)
                    continue;
            }
            if (!c.small)
                edge = 0;
            unsigned took = done | edge;
            end = i + ((took & (took - 1)) == 0 ? 4 * (size_t)nl : nl); /* fewer than 2 */
            end = end < n ? end : n;
        }
        if (!(done | edge)) /* no lane served one (or no lanes): the plain loop */
            for (; i < end; i++)
                bad += serve(&c, &pp, o, qfn, q, i, out, coverage, status);
        if (nl && end == i + nl) {
            /* a block of lanes that took 2 or more: coverage 1 and status ST_Q_OK for the
             * whole block (fixed-size copies), then the lanes not served one by one */
            static const float ones[8] = {1, 1, 1, 1, 1, 1, 1, 1};
            static const uint8_t oks[8] = {ST_Q_OK, ST_Q_OK, ST_Q_OK, ST_Q_OK,
                                           ST_Q_OK, ST_Q_OK, ST_Q_OK, ST_Q_OK};
            if (nl == 8) {
                if (coverage)
                    memcpy(coverage + i, ones, 8 * sizeof ones[0]);
                if (status)
                    memcpy(status + i, oks, 8);
            } else {
                if (coverage)
                    memcpy(coverage + i, ones, 4 * sizeof ones[0]);
                if (status)
                    memcpy(status + i, oks, 4);
            }
            unsigned e2m = edge ? lanes_e2m(e2, trav, &lk) : 0u;
            for (unsigned rest = ~done & ((1u << nl) - 1); rest; rest &= rest - 1) {
                unsigned j = (unsigned)__builtin_ctz(rest);
                size_t k = i + j;
                float cov;
                if (edge >> j & 1 &&
                    bilinear_edge_lane(&c, e2, e2m, &lk, j, q[k].face, out + k * nc, &cov)) {
                    if (coverage)
                        coverage[k] = cov; /* status ST_Q_OK already */
                    continue;
                }
                bad += serve(&c, &pp, o, qfn, q, k, out, coverage, status);
            }
            i = end;
            continue;
        }
        unsigned e2m = edge ? lanes_e2m(e2, trav, &lk) : 0u;
        for (unsigned j = 0; i < end; i++, j++) {
            if (!(done >> j & 1)) {
                float cov;
                if (edge >> j & 1 &&
                    bilinear_edge_lane(&c, e2, e2m, &lk, j, q[i].face, out + i * nc, &cov)) {
                    if (coverage)
                        coverage[i] = cov;
                    if (status)
                        status[i] = ST_Q_OK;
                    continue;
                }
                bad += serve(&c, &pp, o, qfn, q, i, out, coverage, status);
                continue;
            }
            if (coverage)
                coverage[i] = 1.0f;
            if (status)
                status[i] = ST_Q_OK;
        }
    }
    st_ptexres_unpin(t);
    return bad;
}

int st_ptexfilter_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                        float *out, float *coverage, uint8_t *status)
{
    int lrc = s ? st_set_levels(s, NULL) : ST_OK; /* a deferred Ptex import's levels (set.h) */
    return lrc ? lrc : batch(s, o, q, n, out, coverage, status, PF_PATH_BEST);
}

int pf_batch_path(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                  float *out, float *coverage, uint8_t *status, int path)
{
    int lrc = s ? st_set_levels(s, NULL) : ST_OK;
    return lrc ? lrc : batch(s, o, q, n, out, coverage, status, path);
}

int st_ptexfilter_prepare(st_set *s, st_error *e)
{
    if (st_ptexres_get(s))
        return st_set_levels(s, e); /* the table is built by the first Ptex filter call */
    if (s->info.kind != ST_KIND_PERFACE)
        return st_fail(e, ST_EUNSUPPORTED, "Ptex filters need a per-face set");
    return st_ptexres_attach(s, NULL, NULL, NULL, 0, e);
}

size_t st_ptexfilter_memory(const st_set *s)
{
    const st_ptexres *t = st_ptexres_get(s);
    return t && s->ext.memory ? s->ext.memory(t) : 0;
}
