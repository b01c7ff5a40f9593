/* store/sample/sample_internal.h - what sample.c (query loop, fast in-face probes) and sample_tap.c
 * (taps outside the face: Discard, Clamp, Traverse across edges and corners) share. Not a
 * public header: nothing outside sample*.c includes it.
 */
#ifndef ST_SAMPLE_INTERNAL_H
#define ST_SAMPLE_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "bc1_texel.h"
#include "sample.h"

#define ST_AI static inline __attribute__((always_inline))

/* One level of one face, resolved once per probe. */
typedef struct st_view {
    const uint8_t *base;
    int32_t w, h;      /* level size in texels */
    size_t xs, ys;     /* bytes per texel step in x and in y; 0 for a constant face */
    uint32_t bw;       /* BC1: blocks per row; 0 when the level holds plain texels */
} st_view;

/* The query's footprint, for Traverse's choice of the neighbour's level. */
typedef struct st_fp {
    float dudx, dvdx, dudy, dvdy;
    float rho2;    /* max(|(dudx W0, dvdx H0)|, |(dudy W0, dvdy H0)|)^2 in the query's face */
    float lodadj;  /* min(lod, 0): how far below level 0 the footprint asked (magnification) */
    const st_chart_ids *ch; /* chart Discard / Traverse on an atlas: the set's ids, else unused */
    unsigned chart;         /* the query's chart id (chart + 1); 0: none, image Discard */
} st_fp;

/* Running sums of one query: sum(w T) per channel and sum(w). rot: quarter turns given to
 * channels 0-1 of each texel added, (x, y) -> (-y, x) per turn; 0 except while Traverse reads
 * a turned neighbour of a set in Ptex's tanvec edge filter mode (sample_tap.c). */
typedef struct st_acc {
    float c[ST_MAX_CHANNELS];
    float w;
    unsigned rot;
} st_acc;

ST_AI void st_view_init(st_view *v, const st_set *s, uint32_t f, unsigned level)
{
    const st_face *F = &s->faces[f];
    v->base = st_face_level(s, f, level);
    v->w = (int32_t)st_level_w(F, level);
    v->h = (int32_t)st_level_h(F, level);
    v->bw = 0;
    if (F->flags & ST_FACE_CONSTANT) {
        v->xs = v->ys = 0;
    } else if (s->info.kind == ST_KIND_BC1) {
        v->xs = v->ys = 0;
        v->bw = (uint32_t)(v->w + 3) / 4;
    } else {
        v->xs = st_texel_size(s);
        v->ys = v->xs * (size_t)v->w;
    }
}

/* floor() for |x| < 2^31 without a libm call (-O2 without SSE4.1 has no inline floorf). */
ST_AI int32_t st_ifloor(float x)
{
    int32_t i = (int32_t)x;
    return i - (x < (float)i);
}

/* Reads texel (i, j), inside the level, as floats (any dtype, BC1 decoded). */
void st_fetch_any(const st_set *s, const st_view *v, int32_t i, int32_t j, float out[4]);

/* A bilinear probe of face f at `level` whose four taps (i0 + {0,1}, j0 + {0,1}) are not all
 * inside the face; fx, fy are the bilinear fractions, pw the probe's weight. Applies the
 * mode's rule to every outside tap and adds to a. */
void st_probe_bilinear_edge(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                            unsigned level, const st_view *v, int32_t i0, int32_t j0, float fx,
                            float fy, float pw, st_acc *a);

/* Chart Discard and Traverse (an atlas, fp->chart != 0): a bilinear probe whose four taps are
 * not all inside the level and of the query's chart; taps outside the level or on a texel of
 * another chart (fp->ch at `level`) are dropped - in Traverse (mode) read from their linked
 * texel when they have one (st_chart_link_find) - the rest added. */
void st_probe_bilinear_chart(const st_set *s, unsigned mode, const st_fp *fp, unsigned level,
                             const st_view *v, int32_t i0, int32_t j0, float fx, float fy,
                             float pw, st_acc *a);
/* The tap (i, j) of a point probe that is not of the query's chart: chart Traverse reads its
 * linked texel, if any; otherwise dropped. */
void st_probe_point_chart(const st_set *s, unsigned mode, const st_fp *fp, unsigned level,
                          const st_view *v, int32_t i, int32_t j, float pw, st_acc *a);

/* The same for the one tap of a point probe. */
void st_probe_point_edge(const st_set *s, unsigned mode, const st_fp *fp, uint32_t f,
                         unsigned level, const st_view *v, int32_t i, int32_t j, float pw,
                         st_acc *a);

/* GL's *_MIPMAP_NEAREST: level 0 when lod <= 0.5, else ceil(lod + 0.5) - 1, clamped to
 * nl - 1. */
static inline unsigned st_nearest_level(float lod, unsigned nl)
{
    if (!(lod > 0.5f))
        return 0;
    float t = lod + 0.5f;
    int32_t L = (int32_t)t;
    L -= ((float)L == t);
    return (unsigned)L >= nl ? nl - 1 : (unsigned)L;
}

/* Clamp-to-edge lookup of face f at level (bilinear, or nearest when point) at (u, v),
 * weight pw; never leaves the face. */
void st_lookup_clamped(const st_set *s, uint32_t f, unsigned level, float u, float v,
                       int point, float pw, st_acc *a);

/* GL's level of detail of a footprint whose longer axis is sqrt(rho2) texels of level 0. */
ST_AI float st_lod_of_rho2(float rho2)
{
    return rho2 > 0.0f ? 0.5f * log2f(rho2) : -INFINITY;
}

/* The status of a query before it is sampled (st_qstatus): face in range, finite, inside the
 * coordinate and footprint caps. */
ST_AI int st_check_query(const st_set *s, const st_query *q)
{
    if (q->face >= s->info.nfaces)
        return ST_Q_BAD_FACE;
    /* x - x is NaN exactly when x is NaN or infinite */
    float z = (q->u - q->u) + (q->v - q->v) + (q->dudx - q->dudx) + (q->dvdx - q->dvdx) +
              (q->dudy - q->dudy) + (q->dvdy - q->dvdy);
    if (z != z)
        return ST_Q_NONFINITE;
    if (fabsf(q->u) > ST_MAX_COORD || fabsf(q->v) > ST_MAX_COORD ||
        fabsf(q->dudx) > ST_MAX_DERIV || fabsf(q->dvdx) > ST_MAX_DERIV ||
        fabsf(q->dudy) > ST_MAX_DERIV || fabsf(q->dvdy) > ST_MAX_DERIV)
        return ST_Q_BAD_FOOTPRINT;
    return ST_Q_OK;
}


/* The GPU-style filters on a triangle-mesh set (sample_tri.c); same contract as
 * st_sample_batch for filters 0..3 (options already checked). */
int st_sample_tri_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                        float *out, float *coverage, uint8_t *status);

#endif
