/* store/bc1/bc1_seam.c - the seam-aware BC1 endpoint solve (declared in seammask.h).
 *
 * Owns: st_bc1_seam_solve. Does not own: seam sample points and masking (seammask.c), the
 * CG iteration (cg.c: this file gives it the endpoint system), the block encoder
 * (bc1_encode.c), sets (bc1_set.c).
 *
 * Unknowns: the two endpoints (8-bit scale, per channel) of every block that a seam tap
 * touches. With the selectors fixed, a decoded texel is (1 - t) E0 + t E1 with t in
 * {0, 1, 1/3, 2/3} (4-colour) or {0, 1, 1/2} (3-colour), so E = Ec + alpha Es is quadratic
 * in the endpoints; it is minimised per channel by Jacobi-preconditioned conjugate gradients
 * with the bounds 0..255 enforced by fixing the variables that leave the range and solving
 * again (the published tool clamped after the solve, which throws much of the gain away),
 * then rounded (not truncated) to 5/6 bits. Then block-coordinate descent: with the other
 * blocks fixed, a block's share of E is a quadratic in its 16 decoded texels (bquad), so
 * candidate encodings of one block are compared exactly and cheaply; the block-level moves
 * change selectors and endpoints together, which the global solve cannot. The energy of
 * every state is measured exactly (truncating decoder) and the best state is kept. The seam
 * weight may be raised towards a seam RMS goal (st_bc1_seam_solve).
 */
#include "bc1.h"
#include "bc1_texel.h"
#include "cg.h"
#include "seammask.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct sblock {
    uint32_t face;
    uint32_t bi;          /* block index in the face */
    uint64_t tex[16];     /* global texel id of each of the 16 texels, UINT64_MAX = padding */
} sblock;

typedef struct tapref {
    int32_t  blk;         /* index into blocks, -1 = a constant texel */
    uint8_t  pos;         /* texel 0..15 in the block */
    float    w;           /* signed weight (side B negative) */
    uint64_t tex;         /* global texel id */
} tapref;

typedef struct solver {
    const st_seam_sys *sys;
    const uint8_t *orig, *target;
    uint8_t *const *blocks;
    float alpha, ow;
    sblock *sb;
    uint32_t nb;
    tapref *taps;         /* 8 per point */
    float *t;             /* nb*16 current weight of endpoint 1 per texel */
    float *d;             /* nb*16 data weight (0 for padding) */
    uint32_t *bp_off;     /* nb+1: points touching block b are bp[bp_off[b] .. bp_off[b+1]) */
    uint32_t *bp;
    uint8_t *dec;         /* nb*16*3: the exact decode of every variable block, kept current */
} solver;

/* Refreshes the decode cache of block b from its bytes. */
static void refresh(const solver *S, uint32_t b);

static uint64_t bkey(uint32_t f, uint32_t bi) { return (uint64_t)f << 32 | bi; }

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t face_of(const st_seam_sys *sys, uint64_t t)
{
    uint32_t lo = 0, hi = sys->nfaces;
    while (hi - lo > 1) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (sys->base[mid] <= t)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

static uint8_t *blk_ptr(const solver *S, uint32_t b)
{
    return S->blocks[S->sb[b].face] + (size_t)S->sb[b].bi * 8;
}

static uint16_t rd16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

static void put_block(uint8_t *blk, uint16_t c0, uint16_t c1, uint32_t sel)
{
    blk[0] = (uint8_t)c0;
    blk[1] = (uint8_t)(c0 >> 8);
    blk[2] = (uint8_t)c1;
    blk[3] = (uint8_t)(c1 >> 8);
    blk[4] = (uint8_t)sel;
    blk[5] = (uint8_t)(sel >> 8);
    blk[6] = (uint8_t)(sel >> 16);
    blk[7] = (uint8_t)(sel >> 24);
}


/* Weights of endpoint 1 per texel from the block's current selectors. */
static void block_weights(const uint8_t *blk, float t[16])
{
    int four = rd16(blk) > rd16(blk + 2);
    uint32_t sel = (uint32_t)blk[4] | (uint32_t)blk[5] << 8 | (uint32_t)blk[6] << 16 |
                   (uint32_t)blk[7] << 24;
    static const float w4[4] = {0, 1, 1.0f / 3, 2.0f / 3}, w3[4] = {0, 1, 0.5f, 0};
    for (int i = 0; i < 16; i++)
        t[i] = (four ? w4 : w3)[sel >> (2 * i) & 3];
}

/* Exact decoded value of a tap, channel c. */
static double tap_value(const solver *S, const tapref *r, unsigned c)
{
    if (r->blk < 0)
        return S->target[r->tex * 4 + c];
    return S->dec[((size_t)r->blk * 16 + r->pos) * 3 + c];
}

static void refresh(const solver *S, uint32_t b)
{
    uint8_t px[64];
    st_bc1_decode_block(blk_ptr(S, b), ST_BC1_DEC_EXACT, px);
    uint8_t *d = S->dec + (size_t)b * 48;
    for (int i = 0; i < 16; i++) {
        d[3 * i] = px[4 * i];
        d[3 * i + 1] = px[4 * i + 1];
        d[3 * i + 2] = px[4 * i + 2];
    }
}

/* Es of the current state: sum over the points of len * squared residual, RGB. */
static double seam_sum(const solver *S)
{
    double es = 0;
    for (size_t p = 0; p < S->sys->npts; p++) {
        const tapref *r = &S->taps[8 * p];
        for (unsigned c = 0; c < 3; c++) {
            double v = 0;
            for (int k = 0; k < 8; k++)
                v += r[k].w * tap_value(S, &r[k], c);
            es += S->sys->pts[p].len * v * v;
        }
    }
    return es;
}

/* Exact E over the touched blocks and all points. */
static double exact_energy(const solver *S)
{
    double ec = 0;
    for (uint32_t b = 0; b < S->nb; b++) {
        for (int i = 0; i < 16; i++) {
            if (S->d[16 * b + i] == 0)
                continue;
            const uint8_t *px = S->dec + ((size_t)b * 16 + i) * 3;
            const uint8_t *o = S->orig + S->sb[b].tex[i] * 4;
            for (int c = 0; c < 3; c++) {
                double dd = (double)px[c] - o[c];
                ec += S->d[16 * b + i] * dd * dd;
            }
        }
    }
    return ec + S->alpha * seam_sum(S);
}

/* y = H z over 2*nb unknowns (channel independent). h holds each block's data-term 2x2
 * matrix (a00, a01, a11), computed once per solve. */
static void matvec(const solver *S, const double *h, const double *z, double *y)
{
    for (uint32_t b = 0; b < S->nb; b++) {
        y[2 * b] = h[3 * b] * z[2 * b] + h[3 * b + 1] * z[2 * b + 1];
        y[2 * b + 1] = h[3 * b + 1] * z[2 * b] + h[3 * b + 2] * z[2 * b + 1];
    }
    for (size_t p = 0; p < S->sys->npts; p++) {
        const tapref *r = &S->taps[8 * p];
        double v = 0;
        for (int k = 0; k < 8; k++) {
            if (r[k].blk < 0)
                continue;
            double t = S->t[16 * r[k].blk + r[k].pos];
            v += r[k].w * ((1 - t) * z[2 * r[k].blk] + t * z[2 * r[k].blk + 1]);
        }
        v *= S->alpha * S->sys->pts[p].len;
        for (int k = 0; k < 8; k++) {
            if (r[k].blk < 0)
                continue;
            double t = S->t[16 * r[k].blk + r[k].pos];
            y[2 * r[k].blk] += r[k].w * (1 - t) * v;
            y[2 * r[k].blk + 1] += r[k].w * t * v;
        }
    }
}

/* matvec as the solver's callback (cg.h) */
typedef struct hmat {
    const solver *S;
    const double *h;
} hmat;

static void hmat_apply(void *ctx, const double *z, double *y)
{
    const hmat *m = ctx;
    matvec(m->S, m->h, z, y);
}

/* Solves channel c for z (warm start given), bounded to 0..255. */
static int solve_channel(const solver *S, unsigned c, double *z, double *wk, uint8_t *fixed,
                         const volatile int *cancel, st_error *e)
{
    uint32_t n = 2 * S->nb;
    /* wk: rhs, the solver's four vectors (r, z, p, q), minv, then h (3 per block) */
    double *rhs = wk, *r = wk + n, *minv = wk + 5 * n, *h = wk + 6 * n;
    for (uint32_t b = 0; b < S->nb; b++) {
        double a00 = 0, a01 = 0, a11 = 0;
        for (int i = 0; i < 16; i++) {
            double t = S->t[16 * b + i], s = 1 - t, d = S->d[16 * b + i];
            a00 += d * s * s;
            a01 += d * s * t;
            a11 += d * t * t;
        }
        h[3 * b] = a00;
        h[3 * b + 1] = a01;
        h[3 * b + 2] = a11;
    }
    /* right-hand side: data term minus the constant taps' seam contribution */
    for (uint32_t b = 0; b < S->nb; b++) {
        double r0 = 0, r1 = 0;
        for (int i = 0; i < 16; i++) {
            double d = S->d[16 * b + i];
            if (d == 0)
                continue;
            double t = S->t[16 * b + i], o = S->orig[S->sb[b].tex[i] * 4 + c];
            r0 += d * (1 - t) * o;
            r1 += d * t * o;
        }
        rhs[2 * b] = r0;
        rhs[2 * b + 1] = r1;
    }
    for (uint32_t i = 0; i < n; i++)
        minv[i] = 0;
    for (uint32_t b = 0; b < S->nb; b++)
        for (int i = 0; i < 16; i++) {
            double t = S->t[16 * b + i], d = S->d[16 * b + i];
            minv[2 * b] += d * (1 - t) * (1 - t);
            minv[2 * b + 1] += d * t * t;
        }
    for (size_t pt = 0; pt < S->sys->npts; pt++) {
        const tapref *rf = &S->taps[8 * pt];
        double cst = 0;
        for (int k = 0; k < 8; k++)
            if (rf[k].blk < 0)
                cst += rf[k].w * S->target[rf[k].tex * 4 + c];
        double al = S->alpha * S->sys->pts[pt].len;
        for (int k = 0; k < 8; k++) {
            if (rf[k].blk < 0)
                continue;
            double t = S->t[16 * rf[k].blk + rf[k].pos];
            rhs[2 * rf[k].blk] -= al * cst * rf[k].w * (1 - t);
            rhs[2 * rf[k].blk + 1] -= al * cst * rf[k].w * t;
            minv[2 * rf[k].blk] += al * rf[k].w * rf[k].w * (1 - t) * (1 - t);
            minv[2 * rf[k].blk + 1] += al * rf[k].w * rf[k].w * t * t;
        }
    }
    for (uint32_t i = 0; i < n; i++)
        minv[i] = minv[i] > 1e-9 ? 1.0 / minv[i] : 0.0; /* an endpoint no texel uses stays put */
    /* bounded to 0..255 by fixing what leaves the range (cg.h); endpoints are rounded to
     * 5/6 bits afterwards: 1e-8 of the right-hand side is far below a quantisation step */
    hmat m = {S, h};
    st_cg P = {.n = n, .matvec = hmat_apply, .ctx = &m, .minv = minv, .b = rhs, .lo = 0,
               .hi = 255, .rounds = 4, .tol = 1e-8, .maxit = 200, .cancel = cancel};
    if (st_cg_solve(&P, z, fixed, r))
        return st_fail(e, ST_ECANCELED, "seam-aware BC1 solve cancelled");
    return ST_OK;
}

/* Endpoints of a block on the 8-bit scale (expanded 565). */
static void block_endpoints(const uint8_t *blk, double e[2][3])
{
    uint8_t a[3], b[3];
    st_bc1_565_to_rgb8(rd16(blk), a);
    st_bc1_565_to_rgb8(rd16(blk + 2), b);
    for (int k = 0; k < 3; k++) {
        e[0][k] = a[k];
        e[1][k] = b[k];
    }
}

static int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

/* Writes the rounded endpoints, keeping the block's mode and its selectors (remapped when
 * the rounding flips the endpoint order); the local search re-selects by the energy
 * afterwards. (Re-selecting against the masked texels here instead measured about the same:
 * duck 38.01 dB / seam RMS 5.52 against 38.16 / 5.46 kept, nonquad 7.58 against 7.79.) */
static void requantise(const solver *S, uint32_t b, const double e0[3], const double e1[3])
{
    uint8_t *blk = blk_ptr(S, b);
    int four = rd16(blk) > rd16(blk + 2);
    int q0[3], q1[3];
    for (int k = 0; k < 3; k++) {
        double mx = k == 1 ? 63.0 : 31.0;
        q0[k] = clampi((int)floor(e0[k] * mx / 255.0 + 0.5), 0, (int)mx);
        q1[k] = clampi((int)floor(e1[k] * mx / 255.0 + 0.5), 0, (int)mx);
    }
    uint16_t c0 = (uint16_t)(q0[0] << 11 | q0[1] << 5 | q0[2]);
    uint16_t c1 = (uint16_t)(q1[0] << 11 | q1[1] << 5 | q1[2]);
    int swapped = 0;
    if (four ? c0 < c1 : c0 > c1) {
        uint16_t t = c0;
        c0 = c1;
        c1 = t;
        swapped = 1;
    }
    if (four && c0 == c1) {
        /* cannot stay in 4-colour mode: a flat block, selector 0 everywhere */
        put_block(blk, c0, c1, 0);
        return;
    }
    uint32_t sel = (uint32_t)blk[4] | (uint32_t)blk[5] << 8 | (uint32_t)blk[6] << 16 |
                   (uint32_t)blk[7] << 24;
    if (swapped) {
        uint32_t ns = 0;
        for (int i = 0; i < 16; i++) {
            unsigned v = sel >> (2 * i) & 3u;
            v = four ? v ^ 1u : v < 2 ? v ^ 1u : v; /* 0<->1, and 2<->3 in 4-colour mode */
            ns |= v << (2 * i);
        }
        sel = ns;
    }
    put_block(blk, c0, c1, sel);
}

static int has_transparent(const uint8_t *blk)
{
    if (rd16(blk) > rd16(blk + 2))
        return 0;
    uint32_t sel = (uint32_t)blk[4] | (uint32_t)blk[5] << 8 | (uint32_t)blk[6] << 16 |
                   (uint32_t)blk[7] << 24;
    for (int i = 0; i < 16; i++)
        if ((sel >> (2 * i) & 3) == 3)
            return 1;
    return 0;
}

/* ---- block-coordinate descent -------------------------------------------------------------
 * With every other block fixed, E is a quadratic in block b's 16 decoded texels, the same
 * matrix for the three channels: E = sum_c (x_c' H x_c - 2 g_c' x_c) + const. A sweep visits
 * every block, builds (H, g), and tries endpoint/selector candidates - the block as it is,
 * and the HQ encoding of the block's continuous optimum x* = H^-1 g weighted by diag(H) - each
 * polished by (endpoints solved for the selectors, every floor/ceil rounding per channel,
 * selectors re-chosen texel by texel on the quadratic), and keeps the lowest. E falls at every
 * accepted move, so sweeps never raise it. */
typedef struct bquad {
    double H[16][16];
    double g[3][16];
} bquad;

static void block_quad(const solver *S, uint32_t b, bquad *q)
{
    memset(q, 0, sizeof *q);
    for (int i = 0; i < 16; i++) {
        double d = S->d[16 * b + i];
        q->H[i][i] = d;
        if (d > 0)
            for (int c = 0; c < 3; c++)
                q->g[c][i] = d * S->orig[S->sb[b].tex[i] * 4 + c];
    }
    for (uint32_t k = S->bp_off[b]; k < S->bp_off[b + 1]; k++) {
        size_t p = S->bp[k];
        const tapref *r = &S->taps[8 * p];
        double a[16], cc[3] = {0, 0, 0};
        int idx[8], na = 0;
        for (int j = 0; j < 8; j++) {
            if (r[j].blk == (int32_t)b) {
                int pos = r[j].pos, seen = 0;
                for (int m = 0; m < na && !seen; m++)
                    seen = idx[m] == pos;
                if (!seen) {
                    idx[na++] = pos;
                    a[pos] = 0;
                }
                a[pos] += r[j].w;
            } else {
                for (int c = 0; c < 3; c++)
                    cc[c] += r[j].w * tap_value(S, &r[j], (unsigned)c);
            }
        }
        double al = S->alpha * S->sys->pts[p].len;
        for (int m = 0; m < na; m++) {
            int i = idx[m];
            for (int n = 0; n < na; n++)
                q->H[i][idx[n]] += al * a[i] * a[idx[n]];
            for (int c = 0; c < 3; c++)
                q->g[c][i] -= al * cc[c] * a[i];
        }
    }
    for (int i = 0; i < 16; i++)
        if (q->H[i][i] <= 0)
            q->H[i][i] = 1e-6; /* padding: no term; stays put */
}

/* sum_c x_c' H x_c - 2 g_c' x_c of decoded texels x (16 x 3 bytes). */
static double quad_value(const bquad *q, const uint8_t *x)
{
    double s = 0;
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < 16; i++) {
            double hx = 0;
            for (int j = 0; j < 16; j++)
                hx += q->H[i][j] * x[3 * j + c];
            s += x[3 * i + c] * (hx - 2 * q->g[c][i]);
        }
    return s;
}

/* x* = H^-1 g (Cholesky), clamped to 0..255, as RGBA8. */
static void quad_optimum(const bquad *q, const uint8_t *cur, uint8_t out[64])
{
    double L[16][16];
    int ok = 1;
    for (int i = 0; i < 16 && ok; i++)
        for (int j = 0; j <= i; j++) {
            double s = q->H[i][j];
            for (int k = 0; k < j; k++)
                s -= L[i][k] * L[j][k];
            if (i == j) {
                if (!(s > 1e-12)) {
                    ok = 0;
                    break;
                }
                L[i][i] = sqrt(s);
            } else {
                L[i][j] = s / L[j][j];
            }
        }
    for (int c = 0; c < 3; c++) {
        double y[16];
        for (int i = 0; i < 16; i++) {
            if (!ok) {
                y[i] = cur[3 * i + c];
                continue;
            }
            double s = q->g[c][i];
            for (int k = 0; k < i; k++)
                s -= L[i][k] * y[k];
            y[i] = s / L[i][i];
        }
        if (ok)
            for (int i = 15; i >= 0; i--) {
                double s = y[i];
                for (int k = i + 1; k < 16; k++)
                    s -= L[k][i] * y[k];
                y[i] = s / L[i][i];
            }
        for (int i = 0; i < 16; i++) {
            double v = y[i] < 0 ? 0 : y[i] > 255 ? 255 : y[i];
            out[4 * i + c] = (uint8_t)(v + 0.5);
        }
    }
    for (int i = 0; i < 16; i++)
        out[4 * i + 3] = 255;
}

static void decode3(const uint8_t blk[8], uint8_t x[48])
{
    uint8_t px[64];
    st_bc1_decode_block(blk, ST_BC1_DEC_EXACT, px);
    for (int i = 0; i < 16; i++)
        memcpy(x + 3 * i, px + 4 * i, 3);
}

static uint32_t rd_sel(const uint8_t *blk)
{
    return (uint32_t)blk[4] | (uint32_t)blk[5] << 8 | (uint32_t)blk[6] << 16 |
           (uint32_t)blk[7] << 24;
}

/* Channel k of a 565 value expanded to 8 bits. */
static int expand_q(int q, int k) { return k == 1 ? (q << 2) | (q >> 4) : (q << 3) | (q >> 2); }

/* Endpoints for the block's selectors: the 2x2 least-squares solve of the quadratic per
 * channel, then the best of the four floor/ceil roundings of each channel (channels are
 * independent, the exact decoder included); the mode is kept (endpoints swapped with the
 * selectors remapped when the rounding flips their order; a 4-colour block whose endpoints
 * meet becomes flat). */
static void refit_endpoints(const bquad *q, uint8_t blk[8])
{
    uint16_t c0 = rd16(blk), c1 = rd16(blk + 2);
    int four = c0 > c1;
    uint32_t sel = rd_sel(blk);
    if (!four && c0 == c1)
        return;
    static const int sh[3] = {11, 5, 0}, mx[3] = {31, 63, 31};
    int ti[16];
    double t[16];
    for (int i = 0; i < 16; i++) {
        ti[i] = (int)(sel >> (2 * i) & 3u);
        t[i] = four ? (double[4]){0, 1, 1.0 / 3, 2.0 / 3}[ti[i]] : (double[4]){0, 1, 0.5, 0}[ti[i]];
    }
    /* M = T' H T, T rows (1 - t_i, t_i) */
    double m00 = 0, m01 = 0, m11 = 0;
    for (int i = 0; i < 16; i++)
        for (int j = 0; j < 16; j++) {
            double h = q->H[i][j];
            m00 += (1 - t[i]) * h * (1 - t[j]);
            m01 += (1 - t[i]) * h * t[j];
            m11 += t[i] * h * t[j];
        }
    double det = m00 * m11 - m01 * m01;
    if (!(det > 1e-9 * (m00 * m11 + 1e-30)))
        return;
    int nq[2] = {0, 0};
    for (int k = 0; k < 3; k++) {
        double r0 = 0, r1 = 0;
        for (int i = 0; i < 16; i++) {
            r0 += (1 - t[i]) * q->g[k][i];
            r1 += t[i] * q->g[k][i];
        }
        double e0 = (m11 * r0 - m01 * r1) / det, e1 = (m00 * r1 - m01 * r0) / det;
        double s = mx[k] / 255.0;
        int f0 = (int)floor(e0 * s), f1 = (int)floor(e1 * s);
        double bestv = 1e300;
        int b0 = (c0 >> sh[k]) & mx[k], b1 = (c1 >> sh[k]) & mx[k];
        for (int a = 0; a < 2; a++)
            for (int bb = 0; bb < 2; bb++) {
                int q0 = clampi(f0 + a, 0, mx[k]), q1 = clampi(f1 + bb, 0, mx[k]);
                int v0 = expand_q(q0, k), v1 = expand_q(q1, k);
                int pal[4] = {v0, v1, four ? (2 * v0 + v1) / 3 : (v0 + v1) / 2,
                              four ? (v0 + 2 * v1) / 3 : 0};
                double x[16], val = 0;
                for (int i = 0; i < 16; i++)
                    x[i] = pal[ti[i]];
                for (int i = 0; i < 16; i++) {
                    double hx = 0;
                    for (int j = 0; j < 16; j++)
                        hx += q->H[i][j] * x[j];
                    val += x[i] * (hx - 2 * q->g[k][i]);
                }
                if (val < bestv) {
                    bestv = val;
                    b0 = q0;
                    b1 = q1;
                }
            }
        nq[0] |= b0 << sh[k];
        nq[1] |= b1 << sh[k];
    }
    uint16_t n0 = (uint16_t)nq[0], n1 = (uint16_t)nq[1];
    if (four && n0 == n1) {
        uint32_t ns = 0; /* all entries equal: selector 3 must not appear in 3-colour mode */
        for (int i = 0; i < 16; i++)
            ns |= (uint32_t)(ti[i] == 3 ? 2 : ti[i]) << (2 * i);
        put_block(blk, n0, n1, ns);
        return;
    }
    if (four ? n0 < n1 : n0 > n1) {
        uint32_t ns = 0;
        for (int i = 0; i < 16; i++) {
            unsigned v = (unsigned)ti[i];
            v = four ? v ^ 1u : v < 2 ? v ^ 1u : v;
            ns |= v << (2 * i);
        }
        put_block(blk, n1, n0, ns);
        return;
    }
    put_block(blk, n0, n1, sel);
}

/* Selectors re-chosen texel by texel (two passes) on the quadratic, endpoints fixed;
 * never selector 3 in 3-colour mode. */
static void reselect(const bquad *q, uint8_t blk[8], const float *dw)
{
    uint16_t c0 = rd16(blk), c1 = rd16(blk + 2);
    int four = c0 > c1;
    int nsel = four ? 4 : (c0 == c1 ? 1 : 3);
    if (nsel == 1)
        return;
    uint8_t pal[16], x[48];
    st_bc1_palette(c0, c1, ST_BC1_DEC_EXACT, pal);
    uint32_t sel = rd_sel(blk);
    decode3(blk, x);
    double gr[3][16]; /* (H x - g) per channel */
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < 16; i++) {
            double s = -q->g[c][i];
            for (int j = 0; j < 16; j++)
                s += q->H[i][j] * x[3 * j + c];
            gr[c][i] = s;
        }
    for (int pass = 0; pass < 2; pass++) {
        int moved = 0;
        for (int i = 0; i < 16; i++) {
            if (dw[i] == 0)
                continue;
            unsigned s0 = sel >> (2 * i) & 3u, bs = s0;
            double bestd = 0;
            for (unsigned j = 0; j < (unsigned)nsel; j++) {
                if (j == s0)
                    continue;
                double dq = 0;
                for (int c = 0; c < 3; c++) {
                    double dl = (double)pal[4 * j + c] - x[3 * i + c];
                    dq += 2 * dl * gr[c][i] + q->H[i][i] * dl * dl;
                }
                if (dq < bestd - 1e-9) {
                    bestd = dq;
                    bs = j;
                }
            }
            if (bs == s0)
                continue;
            for (int c = 0; c < 3; c++) {
                double dl = (double)pal[4 * bs + c] - x[3 * i + c];
                for (int j = 0; j < 16; j++)
                    gr[c][j] += q->H[j][i] * dl;
                x[3 * i + c] = pal[4 * bs + c];
            }
            sel = (sel & ~(3u << (2 * i))) | bs << (2 * i);
            moved = 1;
        }
        if (!moved)
            break;
    }
    put_block(blk, c0, c1, sel);
}

/* Polishes candidate blk in place (refit, reselect, twice) and returns its quadratic value. */
static double polish(const bquad *q, uint8_t blk[8], const float *dw)
{
    uint8_t x[48];
    for (int r = 0; r < 2; r++) {
        refit_endpoints(q, blk);
        reselect(q, blk, dw);
    }
    decode3(blk, x);
    return quad_value(q, x);
}

/* One block-coordinate step on block b; returns 1 when the block changed (E fell). */
static int bcd_block(const solver *S, uint32_t b)
{
    bquad q;
    block_quad(S, b, &q);
    uint8_t *blk = blk_ptr(S, b);
    const uint8_t *cur = S->dec + (size_t)b * 48;
    const float *dw = S->d + 16 * b;
    double e_cur = quad_value(&q, cur);
    uint8_t best[8], cand[8], xs[64];
    memcpy(best, blk, 8);
    double e_best = e_cur;
    memcpy(cand, blk, 8);
    double v = polish(&q, cand, dw);
    if (v < e_best - 1e-6) {
        e_best = v;
        memcpy(best, cand, 8);
    }
    quad_optimum(&q, cur, xs);
    float w[16];
    for (int i = 0; i < 16; i++)
        w[i] = dw[i] == 0 ? 0.0f : (float)q.H[i][i];
    st_bc1_encode_block_w(xs, w, ST_BC1_HQ, cand);
    v = polish(&q, cand, dw);
    if (v < e_best - 1e-6) {
        e_best = v;
        memcpy(best, cand, 8);
    }
    if (e_best < e_cur - 1e-6) {
        memcpy(blk, best, 8);
        refresh(S, b);
        return 1;
    }
    return 0;
}

/* Seam RMS per channel of the current state (exact decode), as st_seam_rms_rgba8. */
static double state_rms(const solver *S)
{
    double es = seam_sum(S);
    return S->sys->total_len > 0 ? sqrt(es / (3 * S->sys->total_len)) : 0;
}

static void put_all(const solver *S, const uint8_t *src)
{
    for (uint32_t b = 0; b < S->nb; b++) {
        memcpy(blk_ptr(S, b), src + 8 * b, 8);
        refresh(S, b);
    }
}

/* Scratch and callbacks of the rounds. */
typedef struct work {
    double *z, *wk;
    uint8_t *fixed, *saved;
    const volatile int *cancel;
    void (*progress)(void *arg, double fraction);
    void *progress_arg;
    double p0, pw;        /* this round's share of the progress range */
} work;

/* One round at S->alpha: the bounded endpoint solve with the selectors fixed, rounding, then
 * two block-coordinate sweeps; when the exact E ends below *best, the state is saved. */
static int run_round(const solver *S, work *W, double *best, st_error *e)
{
    uint32_t nb = S->nb;
    double *z = W->z;
    for (uint32_t b = 0; b < nb; b++) {
        block_weights(blk_ptr(S, b), S->t + 16 * b);
        double en[2][3];
        block_endpoints(blk_ptr(S, b), en);
        for (int c = 0; c < 3; c++) {
            z[(size_t)c * 2 * nb + 2 * b] = en[0][c];
            z[(size_t)c * 2 * nb + 2 * b + 1] = en[1][c];
        }
    }
    for (unsigned c = 0; c < 3; c++) {
        int rc = solve_channel(S, c, z + (size_t)c * 2 * nb, W->wk, W->fixed, W->cancel, e);
        if (rc)
            return rc;
    }
    for (uint32_t b = 0; b < nb; b++) {
        double e0[3], e1[3];
        for (int c = 0; c < 3; c++) {
            e0[c] = z[(size_t)c * 2 * nb + 2 * b];
            e1[c] = z[(size_t)c * 2 * nb + 2 * b + 1];
        }
        requantise(S, b, e0, e1);
        refresh(S, b);
    }
    for (int pass = 0; pass < 2; pass++) {
        int any = 0;
        for (uint32_t b = 0; b < nb; b++) {
            if (W->cancel && __atomic_load_n(W->cancel, __ATOMIC_RELAXED))
                return st_fail(e, ST_ECANCELED, "seam-aware BC1 solve cancelled");
            any |= bcd_block(S, b);
            if (W->progress && (b & 1023) == 1023)
                W->progress(W->progress_arg, W->p0 + W->pw * (pass + (double)b / nb) / 2.0);
        }
        if (!any)
            break;
    }
    double en = exact_energy(S);
    if (W->progress)
        W->progress(W->progress_arg, W->p0 + W->pw);
    if (en < *best) {
        *best = en;
        for (uint32_t b = 0; b < nb; b++)
            memcpy(W->saved + 8 * b, blk_ptr(S, b), 8);
    }
    return ST_OK;
}

int st_bc1_seam_solve(const st_seam_sys *sys, const uint8_t *orig, const uint8_t *target,
                      uint8_t *const *blocks, float alpha, float outside_weight, int iterations,
                      double rms_goal, void (*progress)(void *arg, double fraction),
                      void *progress_arg, const volatile int *cancel, st_bc1_seam_stats *stats,
                      st_error *e)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!sys->npts)
        return ST_OK;
    if (alpha <= 0)
        alpha = 2.0f;
    if (outside_weight <= 0)
        outside_weight = 0.01f;
    if (iterations <= 0)
        iterations = 3;
    if (iterations > 16)
        iterations = 16;
    solver S = {sys, orig, target, blocks, alpha, outside_weight, NULL, 0, NULL, NULL, NULL,
                NULL, NULL, NULL};
    int rc = ST_OK;
    uint64_t *keys = malloc((sys->nvars ? sys->nvars : 1) * sizeof *keys);
    uint8_t *saved = NULL, *fixed = NULL, *start = NULL, *back = NULL;
    double *z = NULL, *wk = NULL;
    if (!keys)
        return st_fail(e, ST_ENOMEM, "out of memory for seam blocks");
    /* touched blocks */
    uint32_t nk = 0;
    for (uint32_t i = 0; i < sys->nvars; i++) {
        uint64_t t = sys->vars[i];
        uint32_t f = face_of(sys, t);
        if (!blocks[f])
            continue;
        uint64_t local = t - sys->base[f];
        uint32_t x = (uint32_t)(local % sys->fw[f]), y = (uint32_t)(local / sys->fw[f]);
        uint32_t bw = (sys->fw[f] + 3) / 4;
        uint32_t bi = (y / 4) * bw + x / 4;
        if (has_transparent(blocks[f] + (size_t)bi * 8))
            continue;
        keys[nk++] = bkey(f, bi);
    }
    qsort(keys, nk, sizeof *keys, cmp_u64);
    uint32_t nb = 0;
    for (uint32_t i = 0; i < nk; i++)
        if (!nb || keys[nb - 1] != keys[i])
            keys[nb++] = keys[i];
    S.nb = nb;
    S.sb = malloc((nb ? nb : 1) * sizeof *S.sb);
    S.t = malloc((size_t)(nb ? nb : 1) * 16 * sizeof *S.t);
    S.d = malloc((size_t)(nb ? nb : 1) * 16 * sizeof *S.d);
    S.taps = malloc((sys->npts * 8) * sizeof *S.taps);
    saved = malloc((size_t)(nb ? nb : 1) * 8);
    start = malloc((size_t)(nb ? nb : 1) * 8);
    back = malloc((size_t)(nb ? nb : 1) * 8);
    fixed = malloc((size_t)(nb ? nb : 1) * 2);
    z = malloc((size_t)(nb ? nb : 1) * 2 * 3 * sizeof *z);
    wk = malloc((size_t)(nb ? nb : 1) * 15 * sizeof *wk); /* 6 vectors of 2nb + 3nb */
    if (!S.sb || !S.t || !S.d || !S.taps || !saved || !start || !back || !fixed || !z || !wk) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for %u seam blocks", nb);
        goto out;
    }
    for (uint32_t b = 0; b < nb; b++) {
        uint32_t f = (uint32_t)(keys[b] >> 32), bi = (uint32_t)keys[b];
        uint32_t bw = (sys->fw[f] + 3) / 4, bx = bi % bw, by = bi / bw;
        S.sb[b].face = f;
        S.sb[b].bi = bi;
        for (int i = 0; i < 16; i++) {
            uint32_t x = bx * 4 + (uint32_t)(i & 3), y = by * 4 + (uint32_t)(i >> 2);
            if (x < sys->fw[f] && y < sys->fh[f]) {
                uint64_t t = sys->base[f] + (uint64_t)y * sys->fw[f] + x;
                S.sb[b].tex[i] = t;
                S.d[16 * b + i] = sys->inside[t] ? 1.0f : outside_weight;
            } else {
                S.sb[b].tex[i] = UINT64_MAX;
                S.d[16 * b + i] = 0;
            }
        }
    }
    for (size_t p = 0; p < sys->npts; p++)
        for (int k = 0; k < 8; k++) {
            tapref *r = &S.taps[8 * p + k];
            uint32_t v = k < 4 ? sys->pts[p].va[k] : sys->pts[p].vb[k - 4];
            r->w = k < 4 ? sys->pts[p].wa[k] : -sys->pts[p].wb[k - 4];
            r->tex = sys->vars[v];
            r->blk = -1;
            r->pos = 0;
            uint32_t f = face_of(sys, r->tex);
            if (!blocks[f])
                continue;
            uint64_t local = r->tex - sys->base[f];
            uint32_t x = (uint32_t)(local % sys->fw[f]), y = (uint32_t)(local / sys->fw[f]);
            uint32_t bw = (sys->fw[f] + 3) / 4;
            uint64_t key = bkey(f, (y / 4) * bw + x / 4);
            uint32_t lo = 0, hi = nb;
            while (lo < hi) {
                uint32_t mid = lo + (hi - lo) / 2;
                if (keys[mid] < key)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            if (lo < nb && keys[lo] == key) {
                r->blk = (int32_t)lo;
                r->pos = (uint8_t)((y & 3) * 4 + (x & 3));
            }
            /* else: a transparent block, kept as it is: its texel is a constant; the
             * target value stands in for it (close to what it decodes to) */
        }
    /* points per block (CSR), each point once per block */
    S.bp_off = calloc((size_t)nb + 1, sizeof *S.bp_off);
    if (!S.bp_off) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for the seam point index");
        goto out;
    }
    for (int pass = 0; pass < 2; pass++) {
        for (size_t p = 0; p < sys->npts; p++) {
            int32_t seen[8];
            int ns = 0;
            for (int k = 0; k < 8; k++) {
                int32_t bk = S.taps[8 * p + k].blk;
                int dup = bk < 0;
                for (int j = 0; j < ns && !dup; j++)
                    dup = seen[j] == bk;
                if (dup)
                    continue;
                seen[ns++] = bk;
                if (pass == 0)
                    S.bp_off[bk + 1]++;
                else
                    S.bp[S.bp_off[bk]++] = (uint32_t)p;
            }
        }
        if (pass == 0) {
            for (uint32_t b = 0; b < nb; b++)
                S.bp_off[b + 1] += S.bp_off[b];
            S.bp = malloc(((size_t)S.bp_off[nb] ? S.bp_off[nb] : 1) * sizeof *S.bp);
            if (!S.bp) {
                rc = st_fail(e, ST_ENOMEM, "out of memory for the seam point index");
                goto out;
            }
        } else {
            /* the fill advanced each start to the next block's start: shift back */
            for (uint32_t b = nb; b > 0; b--)
                S.bp_off[b] = S.bp_off[b - 1];
            S.bp_off[0] = 0;
        }
    }
    S.dec = malloc((size_t)(nb ? nb : 1) * 48);
    if (!S.dec) {
        rc = st_fail(e, ST_ENOMEM, "out of memory for the decode cache");
        goto out;
    }
    for (uint32_t b = 0; b < nb; b++)
        refresh(&S, b);
    double best = exact_energy(&S);
    if (stats) {
        stats->nblocks = nb;
        stats->alpha = alpha;
    }
    for (uint32_t b = 0; b < nb; b++)
        memcpy(saved + 8 * b, blk_ptr(&S, b), 8);
    memcpy(start, saved, (size_t)nb * 8);
    work W = {z, wk, fixed, saved, cancel, progress, progress_arg, 0, 0};
    for (int it = 0; it < iterations; it++) {
        W.p0 = (rms_goal > 0 ? 0.7 : 1.0) * it / iterations;
        W.pw = (rms_goal > 0 ? 0.7 : 1.0) / iterations;
        if ((rc = run_round(&S, &W, &best, e)))
            goto out;
        if (stats)
            stats->iterations++;
    }
    put_all(&S, saved);
    /* while the seams are above the goal: alpha x SEAM_RAISE and one more round from the
     * best state so far, at most SEAM_RAISES times, stopping when two raises in a row
     * lowered the seam RMS by less than 2% each (the 8-bit floor; one alone may precede a
     * drop where many seam blocks snap together). When a raise overshoots the goal, one
     * round halfway back (alpha / sqrt(SEAM_RAISE)) from there is kept if its seams still
     * meet the goal: it gives back data error for the seam slack. */
    const float SEAM_RAISE = 1.2f;
    enum { SEAM_RAISES = 8 };
    double rms = rms_goal > 0 ? state_rms(&S) : 0, last_rms = rms;
    int stalls = 0, raised = 0;
    for (int level = 1; rms_goal > 0 && rms > rms_goal && level <= SEAM_RAISES; level++) {
        S.alpha *= SEAM_RAISE;
        best = exact_energy(&S);
        W.p0 = 0.7 + 0.3 * (level - 1) / (SEAM_RAISES + 1);
        W.pw = 0.3 / (SEAM_RAISES + 1);
        if ((rc = run_round(&S, &W, &best, e)))
            goto out;
        if (stats)
            stats->iterations++;
        put_all(&S, saved);
        raised = 1;
        rms = state_rms(&S);
        stalls = rms > 0.98 * last_rms ? stalls + 1 : 0;
        last_rms = rms;
        if (stalls >= 2)
            break;
    }
    if (raised && rms < 0.95 * rms_goal) {
        float keep_alpha = S.alpha;
        double keep_best = best;
        memcpy(back, saved, (size_t)nb * 8);
        S.alpha = (float)(S.alpha / sqrt(SEAM_RAISE));
        best = exact_energy(&S);
        W.p0 = 0.7 + 0.3 * SEAM_RAISES / (SEAM_RAISES + 1);
        W.pw = 0.3 / (SEAM_RAISES + 1);
        if ((rc = run_round(&S, &W, &best, e)))
            goto out;
        if (stats)
            stats->iterations++;
        put_all(&S, saved);
        if (state_rms(&S) > rms_goal) {
            S.alpha = keep_alpha;
            best = keep_best;
            memcpy(saved, back, (size_t)nb * 8);
            put_all(&S, saved);
        }
    }
    if (stats)
        stats->alpha = S.alpha;
    /* never worse than the start, at the alpha finally used */
    put_all(&S, start);
    double e0 = exact_energy(&S);
    if (e0 <= best) {
        best = e0;
        memcpy(saved, start, (size_t)nb * 8);
    }
    put_all(&S, saved);
    if (stats) {
        stats->e_before = e0;
        stats->e_after = best;
    }
    if (progress)
        progress(progress_arg, 1.0);
out:
    free(keys);
    free(S.sb);
    free(S.t);
    free(S.d);
    free(S.taps);
    free(S.bp_off);
    free(S.bp);
    free(S.dec);
    free(saved);
    free(start);
    free(back);
    free(fixed);
    free(z);
    free(wk);
    return rc;
}
