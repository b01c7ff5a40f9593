/* store/bc1_seam.c - the seam-aware BC1 endpoint solve (declared in seammask.h).
 *
 * Owns: st_bc1_seam_solve. Does not own: seam sample points and masking (seammask.c), the
 * block encoder (bc1_encode.c), sets (bc1_set.c).
 *
 * Unknowns: the two endpoints (8-bit scale, per channel) of every block that a seam tap
 * touches. With the selectors fixed, a decoded texel is (1 - t) E0 + t E1 with t in
 * {0, 1, 1/3, 2/3} (4-colour) or {0, 1, 1/2} (3-colour), so E = Ec + alpha Es is quadratic
 * in the endpoints; it is minimised per channel by Jacobi-preconditioned conjugate gradients
 * with the bounds 0..255 enforced by fixing the variables that leave the range and solving
 * again (the published tool clamped after the solve, which throws much of the gain away),
 * then rounded (not truncated) to 5/6 bits. The energy of every state is measured exactly
 * (truncating decoder) and the best state is kept.
 */
#include "bc1.h"
#include "bc1_texel.h"
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

/* Exact E over the touched blocks and all points. */
static double exact_energy(const solver *S)
{
    double ec = 0, es = 0;
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
    for (size_t p = 0; p < S->sys->npts; p++) {
        const tapref *r = &S->taps[8 * p];
        for (unsigned c = 0; c < 3; c++) {
            double v = 0;
            for (int k = 0; k < 8; k++)
                v += r[k].w * tap_value(S, &r[k], c);
            es += S->sys->pts[p].len * v * v;
        }
    }
    return ec + S->alpha * es;
}

/* y = H z over 2*nb unknowns (channel independent); fixed entries give 0. h holds each
 * block's data-term 2x2 matrix (a00, a01, a11), computed once per solve. */
static void matvec(const solver *S, const double *h, const double *z, double *y,
                   const uint8_t *fixed)
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
    if (fixed)
        for (uint32_t i = 0; i < 2 * S->nb; i++)
            if (fixed[i])
                y[i] = 0;
}

/* Solves channel c for z (warm start given), bounded to 0..255. */
static int solve_channel(const solver *S, unsigned c, double *z, double *wk, uint8_t *fixed,
                         const volatile int *cancel, st_error *e)
{
    uint32_t n = 2 * S->nb;
    double *rhs = wk, *r = wk + n, *zz = wk + 2 * n, *p = wk + 3 * n, *q = wk + 4 * n,
           *minv = wk + 5 * n, *h = wk + 6 * n;
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
        minv[i] = minv[i] > 1e-9 ? 1.0 / minv[i] : 0.0;
    memset(fixed, 0, n);
    for (int round = 0; round < 4; round++) {
        /* tiny ridge: an endpoint no texel uses (all weight on the other) stays put */
        matvec(S, h, z, q, round ? fixed : NULL);
        double rz = 0, bn = 0;
        for (uint32_t i = 0; i < n; i++) {
            double bi = fixed[i] ? 0 : rhs[i];
            r[i] = fixed[i] ? 0 : bi - q[i];
            bn += bi * bi;
            zz[i] = minv[i] * r[i];
            p[i] = zz[i];
            rz += r[i] * zz[i];
        }
        /* endpoints are rounded to 5/6 bits afterwards: 1e-8 of the right-hand side is
         * far below a quantisation step */
        double tol = 1e-8 * (bn > 1 ? bn : 1);
        for (int it = 0; it < 200; it++) {
            double rr = 0;
            for (uint32_t i = 0; i < n; i++)
                rr += r[i] * r[i];
            if (rr <= tol)
                break;
            if (cancel && *cancel)
                return st_fail(e, ST_ECANCELED, "seam-aware BC1 solve cancelled");
            matvec(S, h, p, q, fixed);
            double pq = 0;
            for (uint32_t i = 0; i < n; i++)
                pq += p[i] * q[i];
            if (!(pq > 0))
                break;
            double a = rz / pq, rz2 = 0;
            for (uint32_t i = 0; i < n; i++) {
                z[i] += a * p[i];
                r[i] -= a * q[i];
                zz[i] = minv[i] * r[i];
                rz2 += r[i] * zz[i];
            }
            double beta = rz2 / rz;
            rz = rz2;
            for (uint32_t i = 0; i < n; i++)
                p[i] = zz[i] + beta * p[i];
        }
        int changed = 0;
        for (uint32_t i = 0; i < n; i++)
            if (z[i] < 0 || z[i] > 255) {
                z[i] = z[i] < 0 ? 0 : 255;
                changed |= !fixed[i];
                fixed[i] = 1;
            }
        if (!changed)
            break;
    }
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

/* Seam energy of point p (exact decoder, every block as it is now). */
static double point_energy(const solver *S, size_t p)
{
    const tapref *r = &S->taps[8 * p];
    double v[3] = {0, 0, 0};
    for (int j = 0; j < 8; j++) {
        const uint8_t *px = r[j].blk < 0 ? S->target + r[j].tex * 4
                                         : S->dec + ((size_t)r[j].blk * 16 + r[j].pos) * 3;
        for (int c = 0; c < 3; c++)
            v[c] += r[j].w * px[c];
    }
    return S->sys->pts[p].len * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

static double texel_data(const solver *S, uint32_t b, int i)
{
    double d = S->d[16 * b + i];
    if (d == 0)
        return 0;
    const uint8_t *px = S->dec + ((size_t)b * 16 + i) * 3;
    const uint8_t *o = S->orig + S->sb[b].tex[i] * 4;
    double e = 0;
    for (int c = 0; c < 3; c++) {
        double dd = (double)px[c] - o[c];
        e += dd * dd;
    }
    return d * e;
}

/* Energy that block b's bits can change: its texels' data term plus the seam term of every
 * point that taps it (exact decoder, other blocks as they are). With texel >= 0, only what
 * texel `texel` of the block changes: its data term and the points that tap it. */
static double local_energy(const solver *S, uint32_t b, int texel)
{
    double ec = 0, es = 0;
    for (int i = 0; i < 16; i++)
        if (texel < 0 || i == texel)
            ec += texel_data(S, b, i);
    for (uint32_t k = S->bp_off[b]; k < S->bp_off[b + 1]; k++) {
        size_t p = S->bp[k];
        if (texel >= 0) {
            const tapref *r = &S->taps[8 * p];
            int hit = 0;
            for (int j = 0; j < 8 && !hit; j++)
                hit = r[j].blk == (int32_t)b && r[j].pos == texel;
            if (!hit)
                continue;
        }
        es += point_energy(S, p);
    }
    return ec + S->alpha * es;
}


/* Discrete descent on block b: every selector of every texel, then +-1 on each of the six
 * 565 components (keeping the block's mode), accepting what lowers local_energy. Returns 1
 * when something changed. */
static int local_search(const solver *S, uint32_t b)
{
    uint8_t *blk = blk_ptr(S, b);
    uint8_t *dc = S->dec + (size_t)b * 48;
    int changed = 0;
    uint16_t c0 = rd16(blk), c1 = rd16(blk + 2);
    int four = c0 > c1;
    int nsel = four ? 4 : 3;
    if (!four && c0 == c1)
        nsel = 1; /* a flat block: only selector 0 means anything */
    uint8_t pal[16];
    st_bc1_palette(c0, c1, ST_BC1_DEC_EXACT, pal);
    for (int i = 0; i < 16 && nsel > 1; i++) {
        if (S->d[16 * b + i] == 0)
            continue;
        uint32_t sel = (uint32_t)blk[4] | (uint32_t)blk[5] << 8 | (uint32_t)blk[6] << 16 |
                       (uint32_t)blk[7] << 24;
        uint32_t keep = sel;
        unsigned s0 = sel >> (2 * i) & 3u, sk = s0;
        double cur = local_energy(S, b, i);
        for (unsigned j = 0; j < (unsigned)nsel; j++) {
            if (j == s0)
                continue;
            memcpy(dc + 3 * i, pal + 4 * j, 3); /* only texel i changes */
            double en = local_energy(S, b, i);
            if (en < cur - 1e-9) {
                cur = en;
                keep = (sel & ~(3u << (2 * i))) | j << (2 * i);
                sk = j;
                changed = 1;
            }
        }
        memcpy(dc + 3 * i, pal + 4 * sk, 3);
        put_block(blk, c0, c1, keep);
    }
    static const int sh[3] = {11, 5, 0}, mx[3] = {31, 63, 31};
    double cur = local_energy(S, b, -1);
    for (int ep = 0; ep < 2; ep++)
        for (int k = 0; k < 3; k++)
            for (int dlt = -1; dlt <= 1; dlt += 2) {
                uint16_t cc[2] = {rd16(blk), rd16(blk + 2)};
                uint32_t sel = (uint32_t)blk[4] | (uint32_t)blk[5] << 8 |
                               (uint32_t)blk[6] << 16 | (uint32_t)blk[7] << 24;
                int q = (cc[ep] >> sh[k]) & mx[k];
                if (q + dlt < 0 || q + dlt > mx[k])
                    continue;
                uint16_t n0 = cc[0], n1 = cc[1];
                uint16_t *t = ep ? &n1 : &n0;
                *t = (uint16_t)((*t & ~(mx[k] << sh[k])) | ((q + dlt) << sh[k]));
                if (four ? n0 <= n1 : n0 > n1)
                    continue; /* would change the mode */
                uint8_t saved[48];
                memcpy(saved, dc, 48);
                put_block(blk, n0, n1, sel);
                refresh(S, b);
                double en = local_energy(S, b, -1);
                if (en < cur - 1e-9) {
                    cur = en;
                    changed = 1;
                } else {
                    put_block(blk, cc[0], cc[1], sel);
                    memcpy(dc, saved, 48);
                }
            }
    return changed;
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

int st_bc1_seam_solve(const st_seam_sys *sys, const uint8_t *orig, const uint8_t *target,
                      uint8_t *const *blocks, float alpha, float outside_weight, int iterations,
                      void (*progress)(void *arg, double fraction), void *progress_arg,
                      const volatile int *cancel, st_bc1_seam_stats *stats, st_error *e)
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
    uint8_t *saved = NULL, *fixed = NULL;
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
    fixed = malloc((size_t)(nb ? nb : 1) * 2);
    z = malloc((size_t)(nb ? nb : 1) * 2 * 3 * sizeof *z);
    wk = malloc((size_t)(nb ? nb : 1) * 15 * sizeof *wk); /* 6 vectors of 2nb + 3nb */
    if (!S.sb || !S.t || !S.d || !S.taps || !saved || !fixed || !z || !wk) {
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
        stats->e_before = best;
        stats->nblocks = nb;
    }
    for (uint32_t b = 0; b < nb; b++)
        memcpy(saved + 8 * b, blk_ptr(&S, b), 8);
    for (int it = 0; it < iterations; it++) {
        for (uint32_t b = 0; b < nb; b++) {
            block_weights(blk_ptr(&S, b), S.t + 16 * b);
            double en[2][3];
            block_endpoints(blk_ptr(&S, b), en);
            for (int c = 0; c < 3; c++) {
                z[(size_t)c * 2 * nb + 2 * b] = en[0][c];
                z[(size_t)c * 2 * nb + 2 * b + 1] = en[1][c];
            }
        }
        for (unsigned c = 0; c < 3; c++) {
            rc = solve_channel(&S, c, z + (size_t)c * 2 * nb, wk, fixed, cancel, e);
            if (rc)
                goto out;
        }
        for (uint32_t b = 0; b < nb; b++) {
            double e0[3], e1[3];
            for (int c = 0; c < 3; c++) {
                e0[c] = z[(size_t)c * 2 * nb + 2 * b];
                e1[c] = z[(size_t)c * 2 * nb + 2 * b + 1];
            }
            requantise(&S, b, e0, e1);
            refresh(&S, b);
        }
        for (int pass = 0; pass < 2; pass++) {
            int any = 0;
            for (uint32_t b = 0; b < nb; b++) {
                if (cancel && *cancel) {
                    rc = st_fail(e, ST_ECANCELED, "seam-aware BC1 solve cancelled");
                    goto out;
                }
                any |= local_search(&S, b);
                if (progress && (b & 1023) == 1023)
                    progress(progress_arg, ((double)it + (pass + (double)b / nb) / 2.0) / iterations);
            }
            if (!any)
                break;
        }
        double en = exact_energy(&S);
        if (progress)
            progress(progress_arg, (double)(it + 1) / iterations);
        if (stats)
            stats->iterations = it + 1;
        if (en < best) {
            best = en;
            for (uint32_t b = 0; b < nb; b++)
                memcpy(saved + 8 * b, blk_ptr(&S, b), 8);
        }
    }
    for (uint32_t b = 0; b < nb; b++)
        memcpy(blk_ptr(&S, b), saved + 8 * b, 8);
    if (stats)
        stats->e_after = best;
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
    free(fixed);
    free(z);
    free(wk);
    return rc;
}
