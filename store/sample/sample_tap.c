/* store/sample/sample_tap.c - the sampler's slow path: probes with taps outside their face.
 *
 * Owns: the per-tap rules of the three modes (Discard drops the tap - on an atlas also a tap on
 * a texel of another chart than the query's (st_probe_bilinear_chart), Clamp clamps its index,
 * Traverse reads it from the neighbour across the edge or the diagonal face across the
 * corner - on an atlas a tap of another chart from the texel linked to it across a UV seam,
 * st_chart_link_find), the edge and corner uv mappings, the choice of the neighbour's level, the turn of
 * channels 0-1 of what Traverse reads in a turned neighbour of a set in Ptex's tanvec edge
 * filter mode (tanvec_rot), and the generic (any dtype, BC1) texel fetch. Does not own: option and query validation, level
 * selection, the in-face fast path (sample.c).
 *
 * Traverse has two paths: the general one maps each outside tap's centre in floats
 * (traverse_tap); the common case of a probe crossing one edge into a same-size level is done
 * in integers (traverse_edge_exact), bit-identical to the general path. Compiling with
 * -DST_EXACT_OK=0 turns the integer path off, to check that identity on any set.
 *
 * Every rule here is written out in docs/sampler.md.
 */
#include "sample_internal.h"
#include "trilevel.h"

#include <math.h>

#ifndef ST_EXACT_OK
#define ST_EXACT_OK 1
#endif

void st_fetch_any(const st_set *s, const st_view *v, int32_t i, int32_t j, float out[4])
{
    if (v->bw) {
        const uint8_t *blk = v->base + ((size_t)(j >> 2) * v->bw + (size_t)(i >> 2)) * 8;
        uint8_t rgba[4];
        st_bc1_texel(blk, (unsigned)i & 3u, (unsigned)j & 3u, rgba);
        for (int c = 0; c < 4; c++)
            out[c] = rgba[c] * (1.0f / 255.0f);
        return;
    }
    const uint8_t *p = v->base + (size_t)i * v->xs + (size_t)j * v->ys;
    unsigned nc = s->info.nchan;
    switch (s->info.dtype) { /* one switch per texel, not per channel */
    case ST_DT_U8:
        for (unsigned c = 0; c < nc; c++)
            out[c] = st_channel_get(ST_DT_U8, p, c);
        break;
    case ST_DT_U16:
        for (unsigned c = 0; c < nc; c++)
            out[c] = st_channel_get(ST_DT_U16, p, c);
        break;
    case ST_DT_HALF:
        for (unsigned c = 0; c < nc; c++)
            out[c] = st_channel_get(ST_DT_HALF, p, c);
        break;
    default:
        for (unsigned c = 0; c < nc; c++)
            out[c] = st_channel_get(ST_DT_F32, p, c);
        break;
    }
}

static void add_tap(const st_set *s, const st_view *v, int32_t i, int32_t j, float w, st_acc *a)
{
    float t[4];
    st_fetch_any(s, v, i, j, t);
    unsigned nc = s->info.nchan;
    if (a->rot) { /* a tangent-space vector read in a turned neighbour, into the query's frame */
        float x = t[0], y = t[1];
        switch (a->rot & 3u) {
        case 1:  t[0] = -y; t[1] = x;  break;
        case 2:  t[0] = -x; t[1] = -y; break;
        default: t[0] = y;  t[1] = -x; break;
        }
    }
    for (unsigned c = 0; c < nc; c++)
        a->c[c] += w * t[c];
    a->w += w;
}

static int32_t clampi(int32_t x, int32_t hi) { return x < 0 ? 0 : x > hi ? hi : x; }

void st_lookup_clamped(const st_set *s, uint32_t f, unsigned level, float u, float v,
                       int point, float pw, st_acc *a)
{
    st_view V;
    st_view_init(&V, s, f, level);
    if (point) {
        int32_t i = st_ifloor(u * (float)V.w), j = st_ifloor(v * (float)V.h);
        add_tap(s, &V, clampi(i, V.w - 1), clampi(j, V.h - 1), pw, a);
        return;
    }
    float x = u * (float)V.w - 0.5f, y = v * (float)V.h - 0.5f;
    int32_t i0 = st_ifloor(x), j0 = st_ifloor(y);
    float fx = x - (float)i0, fy = y - (float)j0;
    float w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    for (int k = 0; k < 4; k++) {
        if (w[k] == 0.0f)
            continue;
        int32_t i = clampi(i0 + (k & 1), V.w - 1), j = clampi(j0 + (k >> 1), V.h - 1);
        add_tap(s, &V, i, j, pw * w[k], a);
    }
}

/* Edge frame of edge e: s along the edge (in its direction), d the outward depth. */
static void edge_frame(unsigned e, float u, float v, float *s, float *d)
{
    switch (e) {
    case 0:  *s = u;        *d = -v;       break;
    case 1:  *s = v;        *d = u - 1.0f; break;
    case 2:  *s = 1.0f - u; *d = v - 1.0f; break;
    default: *s = 1.0f - v; *d = -u;       break;
    }
}
static void edge_frame_inv(unsigned e, float s, float d, float *u, float *v)
{
    switch (e) {
    case 0:  *u = s;        *v = -d;       break;
    case 1:  *u = 1.0f + d; *v = s;        break;
    case 2:  *u = 1.0f - s; *v = 1.0f + d; break;
    default: *u = -d;       *v = 1.0f - s; break;
    }
}
/* Corner frame of corner c: origin at the corner, X along edge c into the face, Y along edge
 * (c+3)%4 reversed, into the face. */
static void corner_frame(unsigned c, float u, float v, float *X, float *Y)
{
    switch (c) {
    case 0:  *X = u;        *Y = v;        break;
    case 1:  *X = v;        *Y = 1.0f - u; break;
    case 2:  *X = 1.0f - u; *Y = 1.0f - v; break;
    default: *X = 1.0f - v; *Y = u;        break;
    }
}
static void corner_frame_inv(unsigned c, float X, float Y, float *u, float *v)
{
    switch (c) {
    case 0:  *u = X;        *v = Y;        break;
    case 1:  *u = 1.0f - Y; *v = X;        break;
    case 2:  *u = 1.0f - X; *v = 1.0f - Y; break;
    default: *u = Y;        *v = 1.0f - X; break;
    }
}

/* Ptex's tanvec edge filter mode: in a per-face quad set whose mode is tanvec and which has 2+
 * channels, channels 0-1 are a vector in each face's (u, v) frame, and a texel Traverse reads
 * in a neighbour turned by rot quarter turns against the query face is turned back (as Ptex's
 * filters do). Across edge e of F to edge ge of G rot is (e - ge + 2) mod 4; across corner c
 * to the diagonal face's corner c', (c - c' + 2) mod 4 (both frames meet the shared edge or
 * corner with opposite orientation). Unlike Ptex's separable filters, a neighbour read at 1 x 1
 * is turned too: its one texel is a vector in its frame like any other. */
static unsigned tanvec_rot(const st_set *s, unsigned e, unsigned ge)
{
    if (s->info.edgefilter != ST_EDGEFILTER_TANVEC || s->info.nchan < 2 ||
        s->info.kind != ST_KIND_PERFACE || s->info.meshtype != ST_MESH_QUAD)
        return 0;
    return (e - ge + 2u) & 3u;
}

/* Level of neighbour G for a tap of a probe at `level` of the query's face: the footprint is
 * carried through the edge rotation (odd rotations swap u and v), measured in G's texels, and
 * the level shifts by the log2 ratio of the two measures: lod_G = level + log2(rho_G / rho_F) +
 * min(lod_F, 0), rounded as GL's nearest-mipmap rule. Equal sizes give level itself; a zero
 * footprint gives level 0. */
static unsigned neighbour_level(const st_fp *fp, unsigned level, const st_face *G, int swap)
{
    if (!(fp->rho2 > 0.0f))
        return 0;
    float W = (float)G->w, H = (float)G->h;
    float du1 = swap ? fp->dvdx : fp->dudx, dv1 = swap ? fp->dudx : fp->dvdx;
    float du2 = swap ? fp->dvdy : fp->dudy, dv2 = swap ? fp->dudy : fp->dvdy;
    float ax = du1 * W, ay = dv1 * H, bx = du2 * W, by = dv2 * H;
    float r1 = ax * ax + ay * ay, r2 = bx * bx + by * by, rg = r1 > r2 ? r1 : r2;
    float adj = fp->lodadj;
    if (adj != adj) { /* point and bilinear leave it to be derived here */
        adj = 0.5f * log2f(fp->rho2);
        adj = adj < 0.0f ? adj : 0.0f;
    }
    float lod = (float)level + adj + (rg == fp->rho2 ? 0.0f : 0.5f * log2f(rg / fp->rho2));
    return st_nearest_level(lod, G->nlevels);
}

/* Public helper (sample.h): the point (u, v) of face f, beyond or on edge `edge`, expressed
 * in the neighbour's uv. */
int st_uv_across_edge(const st_set *s, uint32_t f, unsigned edge, float u, float v,
                      uint32_t *g, float *gu, float *gv)
{
    if (f >= s->info.nfaces || edge > 3)
        return -1;
    const st_face *F = &s->faces[f];
    if (F->adjface[edge] < 0)
        return -1;
    if (s->info.meshtype == ST_MESH_TRIANGLE) { /* barycentric unfolding, trilevel.h */
        float p[3] = {u, v, 1.0f - u - v}, np[3];
        st_tri_across_edge(edge, F->adjedge[edge], p, np);
        *gu = np[0];
        *gv = np[1];
        *g = (uint32_t)F->adjface[edge];
        return 0;
    }
    float es, ed;
    edge_frame(edge, u, v, &es, &ed);
    edge_frame_inv(F->adjedge[edge], 1.0f - es, -ed, gu, gv);
    *g = (uint32_t)F->adjface[edge];
    return 0;
}

int st_uv_across_corner(const st_set *s, uint32_t f, unsigned corner, float u, float v,
                        uint32_t *g, float *gu, float *gv)
{
    if (f >= s->info.nfaces || corner > 3)
        return -1;
    const st_face *F = &s->faces[f];
    if (F->cornerface[corner] < 0)
        return -1;
    float X, Y;
    corner_frame(corner, u, v, &X, &Y);
    corner_frame_inv(F->cornercorner[corner], -X, -Y, gu, gv);
    *g = (uint32_t)F->cornerface[corner];
    return 0;
}

/* The read in neighbour G (level gl, at its uv (gu, gv)) for a tap Traverse sent there. A
 * bilinear tap of G that falls back across the shared edge `back` (and only that edge) is read
 * from the query's face f at the probe's level, clamped: when G is coarser than f, the point
 * lies between f's edge and G's first texel centre, and this keeps the interpolation between
 * true samples (second order) instead of G's clamped border (first order). At equal
 * resolution the point is a texel centre of G, those taps have weight 0 and nothing changes.
 * Every other tap outside G is clamped into G: no further traversal. */
static void neighbour_read(const st_set *s, uint32_t g, unsigned gl, float gu, float gv,
                           int point, float pw, st_acc *a, int back, uint32_t f, unsigned level)
{
    if (point || back < 0) {
        st_lookup_clamped(s, g, gl, gu, gv, point, pw, a);
        return;
    }
    st_view V;
    st_view_init(&V, s, g, gl);
    float x = gu * (float)V.w - 0.5f, y = gv * (float)V.h - 0.5f;
    int32_t i0 = st_ifloor(x), j0 = st_ifloor(y);
    float fx = x - (float)i0, fy = y - (float)j0;
    if (fx == 0.0f && fy == 0.0f && (uint32_t)i0 < (uint32_t)V.w && (uint32_t)j0 < (uint32_t)V.h) {
        add_tap(s, &V, i0, j0, pw, a); /* equal resolution: exactly a texel centre of G */
        return;
    }
    float w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    for (int k = 0; k < 4; k++) {
        if (w[k] == 0.0f)
            continue;
        int32_t i = i0 + (k & 1), j = j0 + (k >> 1);
        int iin = (uint32_t)i < (uint32_t)V.w, jin = (uint32_t)j < (uint32_t)V.h;
        int across = back == 0 ? (j < 0 && iin) : back == 1 ? (i >= V.w && jin)
                   : back == 2 ? (j >= V.h && iin) : (i < 0 && jin);
        uint32_t f2;
        float fu, fv;
        if (across && !st_uv_across_edge(s, g, (unsigned)back, ((float)i + 0.5f) / (float)V.w,
                                         ((float)j + 0.5f) / (float)V.h, &f2, &fu, &fv)) {
            unsigned rot = a->rot; /* f2 is the query's face: its own frame, nothing turned */
            a->rot = 0;
            st_lookup_clamped(s, f2, level < s->faces[f2].nlevels ? level : 0, fu, fv, 0,
                              pw * w[k], a);
            a->rot = rot;
            continue;
        }
        (void)f;
        add_tap(s, &V, clampi(i, V.w - 1), clampi(j, V.h - 1), pw * w[k], a);
    }
}

/* Traverse: tap (i, j) of face f at `level` lies outside the face. Its centre is mapped into
 * the neighbour (edge) or the diagonal face (corner, regular vertices only) and read there at
 * the neighbour's matching level (neighbour_level, neighbour_read).
 * A tap with no face to go to is dropped (its weight is not counted in the coverage). */
static void traverse_tap(const st_set *s, const st_fp *fp, uint32_t f, unsigned level,
                         const st_view *v, int32_t i, int32_t j, int point, float w, st_acc *a)
{
    const st_face *F = &s->faces[f];
    float uc = ((float)i + 0.5f) / (float)v->w, vc = ((float)j + 0.5f) / (float)v->h;
    int ou = i < 0 ? -1 : i >= v->w ? 1 : 0;
    int ov = j < 0 ? -1 : j >= v->h ? 1 : 0;
    uint32_t g;
    float gu, gv;
    int swap, back = -1;
    unsigned rot;
    if (ou && ov) {
        unsigned c = ov < 0 ? (ou < 0 ? 0u : 1u) : (ou > 0 ? 2u : 3u);
        if (st_uv_across_corner(s, f, c, uc, vc, &g, &gu, &gv))
            return;
        swap = (F->cornercorner[c] ^ c) & 1;
        rot = tanvec_rot(s, c, F->cornercorner[c]);
    } else {
        unsigned e = ov < 0 ? 0u : ou > 0 ? 1u : ov > 0 ? 2u : 3u;
        if (st_uv_across_edge(s, f, e, uc, vc, &g, &gu, &gv))
            return;
        swap = (F->adjedge[e] ^ e) & 1;
        back = F->adjedge[e];
        rot = tanvec_rot(s, e, F->adjedge[e]);
    }
    unsigned gl = neighbour_level(fp, level, &s->faces[g], swap);
    a->rot = rot;
    neighbour_read(s, g, gl, gu, gv, point, w, a, back, f, level);
    a->rot = 0;
}

static void outside_tap(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                        unsigned level,
                        const st_view *v, int32_t i, int32_t j, int point, float w, st_acc *a)
{
    if ((uint32_t)i < (uint32_t)v->w && (uint32_t)j < (uint32_t)v->h) {
        add_tap(s, v, i, j, w, a);
        return;
    }
    switch (mode) {
    case ST_MODE_CLAMP:
        add_tap(s, v, clampi(i, v->w - 1), clampi(j, v->h - 1), w, a);
        break;
    case ST_MODE_TRAVERSE:
        traverse_tap(s, fp, f, level, v, i, j, point, w, a);
        break;
    default: /* Discard: zero weight */
        break;
    }
}

/* Traverse's common case in integers: the probe's outside taps all lie across ONE edge e, the
 * neighbour G is read at a level of the same size along and across the edge. Then each tap
 * centre maps exactly onto a texel centre of G (what traverse_tap would compute in floats,
 * with the same weights in the same order, so the result is bit-identical): F's tap at
 * along-edge index a and depth k beyond the edge is G's texel at along index L-1-a, depth k
 * inside. Returns 0, having added nothing, when the case does not apply. */
static int traverse_edge_exact(const st_set *s, const st_fp *fp, uint32_t f, unsigned level,
                               const st_view *v, int32_t i0, int32_t j0, const float w[4],
                               float pw, st_acc *a)
{
    int uin = i0 >= 0 && i0 + 1 < v->w, vin = j0 >= 0 && j0 + 1 < v->h;
    unsigned e;
    if (vin && !uin)
        e = i0 < 0 ? 3u : 1u;
    else if (uin && !vin)
        e = j0 < 0 ? 0u : 2u;
    else
        return 0; /* a corner quadrant is involved */
    const st_face *F = &s->faces[f];
    if (F->adjface[e] < 0)
        return 0;
    uint32_t g = (uint32_t)F->adjface[e];
    unsigned ge = F->adjedge[e];
    const st_face *G = &s->faces[g];
    unsigned gl = neighbour_level(fp, level, G, (int)((ge ^ e) & 1));
    int32_t gw = (int32_t)st_level_w(G, gl), gh = (int32_t)st_level_h(G, gl);
    int32_t along = (e & 1) ? v->h : v->w, across = (e & 1) ? v->w : v->h;
    int32_t galong = (ge & 1) ? gh : gw, gacross = (ge & 1) ? gw : gh;
    if (galong != along || gacross != across)
        return 0;
    st_view GV;
    st_view_init(&GV, s, g, gl);
    for (int k = 0; k < 4; k++) {
        if (w[k] == 0.0f)
            continue;
        int32_t i = i0 + (k & 1), j = j0 + (k >> 1);
        if ((uint32_t)i < (uint32_t)v->w && (uint32_t)j < (uint32_t)v->h) {
            add_tap(s, v, i, j, pw * w[k], a);
            continue;
        }
        int32_t al, dp; /* along-edge index in F, depth beyond the edge (0 = first) */
        switch (e) {
        case 0:  al = i;             dp = -1 - j;      break;
        case 1:  al = j;             dp = i - v->w;    break;
        case 2:  al = v->w - 1 - i;  dp = j - v->h;    break;
        default: al = v->h - 1 - j;  dp = -1 - i;      break;
        }
        if (dp >= gacross) /* deeper than G: clamp in G, as the float path would */
            dp = gacross - 1;
        int32_t ga = along - 1 - al, gi, gj;
        switch (ge) {
        case 0:  gi = ga;          gj = dp;          break;
        case 1:  gi = gw - 1 - dp; gj = ga;          break;
        case 2:  gi = gw - 1 - ga; gj = gh - 1 - dp; break;
        default: gi = dp;          gj = gh - 1 - ga; break;
        }
        a->rot = tanvec_rot(s, e, ge);
        add_tap(s, &GV, gi, gj, pw * w[k], a);
        a->rot = 0;
    }
    return 1;
}

void st_probe_bilinear_edge(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                            unsigned level, const st_view *v, int32_t i0, int32_t j0, float fx,
                            float fy, float pw, st_acc *a)
{
    float w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    if (ST_EXACT_OK && mode == ST_MODE_TRAVERSE && traverse_edge_exact(s, fp, f, level, v, i0, j0, w, pw, a))
        return;
    for (int k = 0; k < 4; k++) {
        if (w[k] == 0.0f)
            continue; /* a zero-weight tap neither reads nor counts */
        outside_tap(s, mode, fp, f, level, v, i0 + (k & 1), j0 + (k >> 1), 0, pw * w[k], a);
    }
}

const st_chart_link *st_chart_link_find(const st_chart_ids *ch, unsigned level, uint32_t texel,
                                        unsigned chart)
{
    const st_chart_link *l = ch->link[level];
    size_t lo = 0, hi = ch->nlink[level];
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (l[mid].texel < texel || (l[mid].texel == texel && l[mid].chart < chart))
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < ch->nlink[level] && l[lo].texel == texel && l[lo].chart == chart)
        return &l[lo];
    return NULL;
}

/* A tap of texel (i, j) not of the query's chart: chart Traverse reads the other chart across
 * the seam at the point its link carries the texel's centre to (the same level) - bilinear
 * there over the 2 x 2 texels around the point that are of the other chart, their weights
 * renormalised (the texel under the point is one of them, with at least a quarter of the
 * weight), or that one texel for the point filter (bilinear 0) - and chart Discard, like
 * Traverse without a link, drops it. */
static void chart_tap(const st_set *s, unsigned mode, const st_fp *fp, unsigned level,
                      const st_view *v, int32_t i, int32_t j, float w, int bilinear, st_acc *a)
{
    if (mode != ST_MODE_TRAVERSE || (uint32_t)i >= (uint32_t)v->w || (uint32_t)j >= (uint32_t)v->h)
        return;
    const st_chart_link *l =
        st_chart_link_find(fp->ch, level, (uint32_t)j * (uint32_t)v->w + (uint32_t)i, fp->chart);
    if (!l)
        return;
    int32_t ti = (int32_t)(l->to % (uint32_t)v->w), tj = (int32_t)(l->to / (uint32_t)v->w);
    if (!bilinear) {
        add_tap(s, v, ti, tj, w, a);
        return;
    }
    /* the point, in texels of the level less half a texel: its 2 x 2 around it */
    float px = (float)ti + ((float)(l->frac & 255) + 0.5f) / 256.0f - 0.5f;
    float py = (float)tj + ((float)(l->frac >> 8) + 0.5f) / 256.0f - 0.5f;
    int32_t i0 = (int32_t)floorf(px), j0 = (int32_t)floorf(py);
    float fx = px - (float)i0, fy = py - (float)j0;
    float wk[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    const uint16_t *m = fp->ch->level[level];
    uint16_t other = m[l->to];
    int keep[4];
    float sum = 0;
    for (int k = 0; k < 4; k++) {
        int32_t x = i0 + (k & 1), y = j0 + (k >> 1);
        keep[k] = wk[k] > 0.0f && (uint32_t)x < (uint32_t)v->w && (uint32_t)y < (uint32_t)v->h &&
                  m[(size_t)y * (size_t)v->w + (size_t)x] == other;
        if (keep[k])
            sum += wk[k];
    }
    for (int k = 0; k < 4; k++)
        if (keep[k])
            add_tap(s, v, i0 + (k & 1), j0 + (k >> 1), w * (wk[k] / sum), a);
}

void st_probe_bilinear_chart(const st_set *s, unsigned mode, const st_fp *fp, unsigned level,
                             const st_view *v, int32_t i0, int32_t j0, float fx, float fy,
                             float pw, st_acc *a)
{
    float w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    const uint16_t *m = fp->ch->level[level];
    for (int k = 0; k < 4; k++) {
        int32_t i = i0 + (k & 1), j = j0 + (k >> 1);
        if (w[k] == 0.0f)
            continue; /* a zero-weight tap neither reads nor counts */
        if ((uint32_t)i < (uint32_t)v->w && (uint32_t)j < (uint32_t)v->h &&
            m[(size_t)j * (size_t)v->w + (size_t)i] == fp->chart)
            add_tap(s, v, i, j, pw * w[k], a);
        else /* beyond the image or not of the query's chart */
            chart_tap(s, mode, fp, level, v, i, j, pw * w[k], 1, a);
    }
}

void st_probe_point_chart(const st_set *s, unsigned mode, const st_fp *fp, unsigned level,
                          const st_view *v, int32_t i, int32_t j, float pw, st_acc *a)
{
    chart_tap(s, mode, fp, level, v, i, j, pw, 0, a);
}

void st_probe_point_edge(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                         unsigned level, const st_view *v, int32_t i, int32_t j, float pw,
                         st_acc *a)
{
    outside_tap(s, mode, fp, f, level, v, i, j, 1, pw, a);
}
