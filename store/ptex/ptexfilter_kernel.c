/* store/ptex/ptexfilter_kernel.c - building and transforming the separable kernels of Ptex's filter
 * family; see ptexfilter_kernel.h. The arithmetic is kept in float and in Ptex's order so that
 * results agree with the Ptex library to rounding.
 */
#include "ptexfilter_kernel.h"

#include <math.h>
#include <string.h>

#include "sample.h"

#define ffloor pk_floor
#define fceil pk_ceil

/* ---- kernel operations ------------------------------------------------------------------ */

/* dst's window (u, v, uw, vw) with the weights ku, kv moved to index 0. Element loops, not
 * memcpy: a few weights each, and a libc call per array cost more than the copy. Copying
 * forward to index 0 is safe even when ku or kv lie in dst's own buffers (src == dst). */
static void pk_set_part(pk *dst, const pk *src, int u, int v, int uw, int vw, const float *ku,
                        const float *kv)
{
    dst->ulog2 = src->ulog2;
    dst->vlog2 = src->vlog2;
    dst->u = u;
    dst->v = v;
    dst->uw = uw;
    dst->vw = vw;
    dst->ku0 = dst->kv0 = 0;
    dst->rot = 0;
    for (int i = 0; i < uw; i++)
        dst->kub[i] = ku[i];
    for (int i = 0; i < vw; i++)
        dst->kvb[i] = kv[i];
}

void pk_set(pk *dst, const pk *src)
{
    int rot = src->rot;
    pk_set_part(dst, src, src->u, src->v, src->uw, src->vw, src->kub + src->ku0,
                src->kvb + src->kv0);
    dst->rot = rot;
}

#define accumulate pk_accumulate

void pk_merge_l(pk *k, int black)
{
    int w = -k->u;
    float *ku = pk_ku(k);
    if (!black)
        ku[w] += accumulate(ku, w);
    k->ku0 += w;
    k->uw -= w;
    k->u = 0;
}

void pk_merge_r(pk *k, int black)
{
    int w = k->uw + k->u - (1 << k->ulog2);
    float *kp = pk_ku(k) + k->uw - w;
    if (!black)
        kp[-1] += accumulate(kp, w);
    k->uw -= w;
}

void pk_merge_b(pk *k, int black)
{
    int w = -k->v;
    float *kv = pk_kv(k);
    if (!black)
        kv[w] += accumulate(kv, w);
    k->kv0 += w;
    k->vw -= w;
    k->v = 0;
}

void pk_merge_t(pk *k, int black)
{
    int w = k->vw + k->v - (1 << k->vlog2);
    float *kp = pk_kv(k) + k->vw - w;
    if (!black)
        kp[-1] += accumulate(kp, w);
    k->vw -= w;
}

void pk_split_l(pk *k, pk *o)
{
    int w = -k->u;
    if (w < k->uw) {
        pk_set_part(o, k, (1 << k->ulog2) - w, k->v, w, k->vw, pk_ku(k), pk_kv(k));
        k->u = 0;
        k->uw -= w;
        k->ku0 += w;
    } else {
        pk_set(o, k);
        o->u += 1 << k->ulog2;
        k->u = 0;
        k->uw = 0;
    }
}

void pk_split_r(pk *k, pk *o)
{
    int w = k->u + k->uw - (1 << k->ulog2);
    if (w < k->uw) {
        pk_set_part(o, k, 0, k->v, w, k->vw, pk_ku(k) + k->uw - w, pk_kv(k));
        k->uw -= w;
    } else {
        pk_set(o, k);
        o->u -= 1 << k->ulog2;
        k->u = 0;
        k->uw = 0;
    }
}

void pk_split_b(pk *k, pk *o)
{
    int w = -k->v;
    if (w < k->vw) {
        pk_set_part(o, k, k->u, (1 << k->vlog2) - w, k->uw, w, pk_ku(k), pk_kv(k));
        k->v = 0;
        k->vw -= w;
        k->kv0 += w;
    } else {
        pk_set(o, k);
        o->v += 1 << k->vlog2;
        k->v = 0;
        k->vw = 0;
    }
}

void pk_split_t(pk *k, pk *o)
{
    int w = k->v + k->vw - (1 << k->vlog2);
    if (w < k->vw) {
        pk_set_part(o, k, k->u, 0, k->uw, w, pk_ku(k), pk_kv(k) + k->vw - w);
        k->vw -= w;
    } else {
        pk_set(o, k);
        o->v -= 1 << k->vlog2;
        k->v = 0;
        k->vw = 0;
    }
}

static void reverse(float *p, int n)
{
    for (int i = 0, j = n - 1; i < j; i++, j--) {
        float t = p[i];
        p[i] = p[j];
        p[j] = t;
    }
}

static void flip_u(pk *k)
{
    k->u = (1 << k->ulog2) - k->u - k->uw;
    reverse(pk_ku(k), k->uw);
}

static void flip_v(pk *k)
{
    k->v = (1 << k->vlog2) - k->v - k->vw;
    reverse(pk_kv(k), k->vw);
}

static void swap_uv(pk *k)
{
    int t;
    t = k->ulog2; k->ulog2 = k->vlog2; k->vlog2 = t;
    t = k->u; k->u = k->v; k->v = t;
    t = k->uw; k->uw = k->vw; k->vw = t;
    t = k->ku0; k->ku0 = k->kv0; k->kv0 = t;
    int n = k->ku0 + k->uw > k->kv0 + k->vw ? k->ku0 + k->uw : k->kv0 + k->vw;
    for (int i = 0; i < n; i++) {
        float x = k->kub[i];
        k->kub[i] = k->kvb[i];
        k->kvb[i] = x;
    }
}

void pk_rotate(pk *k, int rot)
{
    switch (rot & 3) {
    default: return;
    case 1: flip_u(k); swap_uv(k); break;
    case 2: flip_u(k); flip_v(k); break;
    case 3: flip_v(k); swap_uv(k); break;
    }
    k->rot = (k->rot + rot) & 3;
}

/* Moves the weights to the start of the buffer so that upres has room. */
static void pack(pk *k)
{
    if (k->ku0) {
        memmove(k->kub, k->kub + k->ku0, sizeof(float) * (size_t)k->uw);
        k->ku0 = 0;
    }
    if (k->kv0) {
        memmove(k->kvb, k->kvb + k->kv0, sizeof(float) * (size_t)k->vw);
        k->kv0 = 0;
    }
}

void pk_upres_u(pk *k)
{
    pack(k);
    if (2 * k->uw > PK_MAX)
        k->uw = PK_MAX / 2; /* cannot happen with Ptex's kernels (width <= 2 at res 0) */
    float *ku = k->kub;
    for (int i = k->uw - 1; i >= 0; i--)
        ku[2 * i] = ku[2 * i + 1] = ku[i] / 2;
    k->uw *= 2;
    k->u *= 2;
    k->ulog2++;
}

void pk_upres_v(pk *k)
{
    pack(k);
    if (2 * k->vw > PK_MAX)
        k->vw = PK_MAX / 2;
    float *kv = k->kvb;
    for (int i = k->vw - 1; i >= 0; i--)
        kv[2 * i] = kv[2 * i + 1] = kv[i] / 2;
    k->vw *= 2;
    k->v *= 2;
    k->vlog2++;
}

void pk_downres_u(pk *k)
{
    pk_downres_run(pk_ku(k), &k->u, &k->uw);
    k->ulog2--;
}

void pk_downres_v(pk *k)
{
    pk_downres_run(pk_kv(k), &k->v, &k->vw);
    k->vlog2--;
}

int pk_main_to_subface(pk *k, int eid)
{
    if (k->ulog2 == 0)
        pk_upres_u(k);
    if (k->vlog2 == 0)
        pk_upres_v(k);
    if (k->ulog2 > 0)
        k->ulog2--;
    if (k->vlog2 > 0)
        k->vlog2--;
    int primary = 0, resu = 1 << k->ulog2, resv = 1 << k->vlog2;
    switch (eid & 3) {
    case 0:
        primary = k->u < resu;
        k->v -= resv;
        if (!primary)
            k->u -= resu;
        break;
    case 1:
        primary = k->v < resv;
        if (!primary)
            k->v -= resv;
        break;
    case 2:
        primary = k->u >= resu;
        if (primary)
            k->u -= resu;
        break;
    case 3:
        primary = k->v >= resv;
        k->u -= resu;
        if (primary)
            k->v -= resv;
        break;
    }
    return primary;
}

void pk_subface_to_main(pk *k, int eid)
{
    switch (eid & 3) {
    case 0: k->v += 1 << k->vlog2; break;
    case 1: break;
    case 2: k->u += 1 << k->ulog2; break;
    case 3: k->u += 1 << k->ulog2; k->v += 1 << k->vlog2; break;
    }
    k->ulog2++;
    k->vlog2++;
}

float pk_make_symmetric(pk *k, float initial_weight)
{
    if (k->ulog2 > k->vlog2) {
        do pk_downres_u(k); while (k->ulog2 > k->vlog2);
    } else if (k->vlog2 > k->ulog2) {
        do pk_downres_v(k); while (k->vlog2 > k->ulog2);
    }
    k->uw = k->vw = k->uw < k->vw ? k->uw : k->vw;
    float *ku = pk_ku(k), *kv = pk_kv(k);
    float nw = 0;
    for (int i = 0; i < k->uw; i++) {
        float sum = ku[i] + kv[i];
        ku[i] = kv[i] = sum;
        nw += sum;
    }
    nw *= nw;
    float scale = nw == 0 ? 1.f : initial_weight / nw;
    if (scale < 1) {
        if (scale < -1) {
            for (int i = 0; i < k->uw; i++)
                ku[i] *= -1;
            nw = -nw;
        } else {
            for (int i = 0; i < k->uw; i++)
                ku[i] *= scale;
            nw = initial_weight;
        }
    }
    return nw;
}

/* ---- kernel construction ---------------------------------------------------------------- */

#define recip_pow2 pk_recip_pow2
#define res_from_width pk_res_from_width

void pk_params_init(pk_params *p, unsigned ftype, float sharpness, int avx2)
{
    p->ftype = ftype;
    p->avx2 = avx2;
    p->lerp = 0;
    float sh = sharpness;
    if (ftype == ST_FILTER_PTEX_BSPLINE)
        sh = 0.f;
    else if (ftype == ST_FILTER_PTEX_CATMULLROM)
        sh = 1.f;
    else if (ftype == ST_FILTER_PTEX_MITCHELL)
        sh = 2.f / 3.f;
    float B = 1.0f - sh;
    p->coeffs[0] = 1.5f - B;
    p->coeffs[1] = 1.5f * B - 2.5f;
    p->coeffs[2] = 1.0f - (float)(1.0 / 3.0) * B;
    p->coeffs[3] = (float)(1.0 / 3.0) * B - 0.5f;
    p->coeffs[4] = 2.5f - 1.5f * B;
    p->coeffs[5] = 2.0f * B - 4.0f;
    p->coeffs[6] = 2.0f - (float)(2.0 / 3.0) * B;
}

/* The kernel function at x1 + i * step, i < n: Ptex's gaussian exp(-2x^2) or the bicubic
 * family, four points at a time (w has room for n rounded up to 4).
 * exp is 2^(x log2 e) with a degree-6 polynomial on [-1/2, 1/2] (pk_exp2_4, shared with the
 * triangle filter's read sweeps): relative error about 2e-7,
 * against the ulp of the exp that Ptex calls. */
typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));

/* The kernel function at the four points xv (the gaussian by pk_exp2_4, the bicubic family's
 * two cubic pieces chosen by |x| < 1, < 2, else 0). */
static inline __attribute__((always_inline)) v4f kernel4(const pk_params *p, v4f xv)
{
    if (p->ftype == ST_FILTER_PTEX_GAUSSIAN)
        return pk_exp2_4(xv * xv * -2.0f * 1.44269504f);
    const float *c = p->coeffs;
    v4i xb;
    memcpy(&xb, &xv, 16);
    xb &= 0x7fffffff;
    v4f a, r;
    memcpy(&a, &xb, 16);
    v4f inner = (c[0] * a + c[1]) * a * a + c[2];
    v4f outer = ((c[3] * a + c[4]) * a + c[5]) * a + c[6];
    v4i m1 = a < 1.0f, m2 = a < 2.0f, ib, ob;
    memcpy(&ib, &inner, 16);
    memcpy(&ob, &outer, 16);
    v4i rb = (ib & m1) | (ob & ~m1 & m2);
    memcpy(&r, &rb, 16);
    return r;
}

static void kernel_eval(const pk_params *p, float x1, float step, float *w, int n)
{
    for (int i = 0; i < n; i += 4) {
        v4f iv = {(float)i, (float)(i + 1), (float)(i + 2), (float)(i + 3)};
        v4f r = kernel4(p, x1 + iv * step);
        memcpy(w + i, &r, sizeof r);
    }
}

/* The kernel function at the n points x[0 .. n) (n a multiple of 4, x and w with room for
 * them): kernel_eval's operations on given points. */
static void kernel_at(const pk_params *p, const float *x, float *w, int n)
{
    for (int i = 0; i < n; i += 4) {
        v4f xv;
        memcpy(&xv, x + i, 16);
        v4f r = kernel4(p, xv);
        memcpy(w + i, &r, sizeof r);
    }
}

void pk_width4_axis_lerp(const pk_params *p, int *kres, int *ku, int *kw, float *w, float u,
                         float uw, int fres)
{
    float lo = recip_pow2(fres), x1, step;
    float uwc = uw >= lo ? uw : lo;          /* pk_width4_axis' clamp to a texel */
    float lerp2 = 0.0f;
    int res = res_from_width(uwc);
    if (uwc < 1.0f) {
        float uwlo = 1.0f / (float)(1 << res); /* the width of the level picked */
        lerp2 = (uwc - uwlo) / uwlo;
    }
    if (!(lerp2 != 0.0f)) { /* on a level, a face or wider: the kernel without lerp */
        if (pk_width4_axis(kres, ku, kw, w, u, uw, fres, &x1, &step))
            kernel_eval(p, x1, step, w, *kw);
        return;
    }
    float lerp1 = 1.0f - lerp2;
    /* xa, xb: the pair's taps; xc: its middle (kernel points for k, Hermite points for h) */
    float xa[PK_MAX / 4 + 2] = {0}, xb[PK_MAX / 4 + 2] = {0}, xc[PK_MAX / 4 + 2] = {0};
    float ka[PK_MAX / 4 + 2], kb[PK_MAX / 4 + 2], kc[PK_MAX / 4 + 2]; /* pairs, room for 8 */
    int np;
    uw = uwc;
    if (uw >= .5f) { /* 2 texels, Hermite taps: kernel_s's [1/2, 1) branch blended */
        *kres = 1;
        float upix = u * 2.0f - 0.5f;
        *ku = pk_ifloor(u - .5f) * 2;
        *kw = 4;
        float x0 = (float)*ku - upix;
        float s = 1.0f / (uw * 1.5f + .5f);
        for (int i = 0; i < 4; i += 2) {
            float a = x0 + (float)i, b = a + 1.0f, m = (a + b) * 0.5f;
            float ha = pk_hermite_blur(a * s), hb = pk_hermite_blur(b * s);
            float hc = pk_hermite_blur(m * s);
            w[i] = ha * lerp1 + hc * lerp2;
            w[i + 1] = hb * lerp1 + hc * lerp2;
        }
        return;
    }
    if (uw >= .25f) { /* 4 texels: the kernel at texel steps, the middle by Hermite */
        *kres = 2;
        float upix = u * 4.0f - 0.5f;
        int u1 = pk_iceil(upix - 2), u2 = pk_iceil(upix + 2);
        u1 = u1 & ~1;
        u2 = (u2 + 1) & ~1;
        *ku = u1;
        *kw = u2 - u1;
        if (*kw > PK_MAX / 2)
            *kw = PK_MAX / 2;
        float x0 = (float)u1 - upix;
        float s = 1.0f / (uw + .75f);
        np = 0;
        for (int i = 0; i < *kw; i += 2, np++) {
            xa[np] = x0 + (float)i;
            xb[np] = xa[np] + 1.0f;
            xc[np] = (xa[np] + xb[np]) * 0.25f;
        }
        kernel_at(p, xa, ka, (np + 3) / 4 * 4);
        kernel_at(p, xb, kb, (np + 3) / 4 * 4);
        for (int j = 0; j < np; j++) {
            float hc = pk_hermite_blur(xc[j] * s);
            w[2 * j] = ka[j] * lerp1 + hc * lerp2;
            w[2 * j + 1] = kb[j] * lerp1 + hc * lerp2;
        }
        return;
    }
    *kres = res;
    int resu = 1 << res;
    float upix = u * (float)resu - 0.5f;
    float uwpix = uw * (float)resu;
    float dupix = 2.0f * uwpix;
    int u1 = pk_iceil(upix - dupix), u2 = pk_iceil(upix + dupix);
    u1 = u1 & ~1;
    u2 = (u2 + 1) & ~1;
    *ku = u1;
    *kw = u2 - u1;
    if (*kw > PK_MAX / 2)
        *kw = PK_MAX / 2; /* cannot happen: uwpix < 2 gives at most 10 */
    step = 1.0f / uwpix;
    x1 = ((float)u1 - upix) * step;
    np = 0;
    for (int i = 0; i < *kw; i += 2, np++) {
        xa[np] = x1 + (float)i * step;
        xb[np] = xa[np] + step;
        xc[np] = (xa[np] + xb[np]) * 0.5f;
    }
    kernel_at(p, xa, ka, (np + 3) / 4 * 4);
    kernel_at(p, xb, kb, (np + 3) / 4 * 4);
    kernel_at(p, xc, kc, (np + 3) / 4 * 4);
    for (int j = 0; j < np; j++) {
        w[2 * j] = ka[j] * lerp1 + kc[j] * lerp2;
        w[2 * j + 1] = kb[j] * lerp1 + kc[j] * lerp2;
    }
}

static void box_weights(float *k, int size, float f1, float f2)
{
    if (size == 1) {
        k[0] = f1 + f2 - 1.0f;
    } else {
        k[0] = f1;
        for (int i = 1; i < size - 1; i++)
            k[i] = 1.0f;
        k[size - 1] = f2;
    }
}

void pk_build(const pk_params *p, pk *k, float u, float v, float uw, float vw, int fulog2,
              int fvlog2)
{
    k->ku0 = k->kv0 = k->rot = 0;
    if (p->ftype == ST_FILTER_PTEX_BOX || p->ftype == ST_FILTER_PTEX_BILINEAR) {
        uw = uw < 1.0f ? uw : 1.0f;
        vw = vw < 1.0f ? vw : 1.0f;
        float lu = recip_pow2(fulog2), lv = recip_pow2(fvlog2);
        uw = uw > lu ? uw : lu;
        vw = vw > lv ? vw : lv;
        k->ulog2 = (uint8_t)res_from_width(uw);
        k->vlog2 = (uint8_t)res_from_width(vw);
        float ru = (float)(1 << k->ulog2), rv = (float)(1 << k->vlog2);
        if (p->ftype == ST_FILTER_PTEX_BILINEAR) {
            float upix = u * ru - 0.5f, vpix = v * rv - 0.5f;
            float uf = ffloor(upix), vf = ffloor(vpix);
            k->u = (int)uf;
            k->v = (int)vf;
            k->uw = k->vw = 2;
            float fu = upix - uf, fv = vpix - vf;
            k->kub[0] = 1.0f - fu;
            k->kub[1] = fu;
            k->kvb[0] = 1.0f - fv;
            k->kvb[1] = fv;
            return;
        }
        u *= ru;
        v *= rv;
        uw *= ru;
        vw *= rv;
        float u1 = u - 0.5f * uw, u2 = u + 0.5f * uw;
        float v1 = v - 0.5f * vw, v2 = v + 0.5f * vw;
        float u1f = ffloor(u1), u2c = fceil(u2), v1f = ffloor(v1), v2c = fceil(v2);
        k->u = (int)u1f;
        k->v = (int)v1f;
        k->uw = (int)u2c - k->u;
        k->vw = (int)v2c - k->v;
        if (k->uw < 1) k->uw = 1;
        if (k->vw < 1) k->vw = 1;
        if (k->uw > 3) k->uw = 3;
        if (k->vw > 3) k->vw = 3;
        box_weights(k->kub, k->uw, 1.0f - (u1 - u1f), 1.0f - (u2c - u2));
        box_weights(k->kvb, k->vw, 1.0f - (v1 - v1f), 1.0f - (v2c - v2));
        return;
    }
    if (p->lerp) {
        pk_width4_axis_lerp(p, &k->ulog2, &k->u, &k->uw, k->kub, u, uw, fulog2);
        pk_width4_axis_lerp(p, &k->vlog2, &k->v, &k->vw, k->kvb, v, vw, fvlog2);
        return;
    }
    float x1u = 0, su = 0, x1v = 0, sv = 0;
    int eu = pk_width4_axis(&k->ulog2, &k->u, &k->uw, k->kub, u, uw, fulog2, &x1u, &su);
    int ev = pk_width4_axis(&k->vlog2, &k->v, &k->vw, k->kvb, v, vw, fvlog2, &x1v, &sv);
    if (p->avx2) {
        if (eu && ev)
            pf_kernel_eval2_avx2(p, x1u, su, k->kub, k->uw, x1v, sv, k->kvb, k->vw);
        else if (eu) /* the other axis' width is 1/4 or more: its weights are written */
            pf_kernel_eval1_avx2(p, x1u, su, k->kub, k->uw);
        else if (ev)
            pf_kernel_eval1_avx2(p, x1v, sv, k->kvb, k->vw);
        return;
    }
    if (eu)
        kernel_eval(p, x1u, su, k->kub, k->uw);
    if (ev)
        kernel_eval(p, x1v, sv, k->kvb, k->vw);
}

void pk_kernel_eval(const pk_params *p, float x1, float step, float *w, int n)
{
    kernel_eval(p, x1, step, w, n);
}
