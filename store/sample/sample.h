/* store/sample/sample.h - filtered sampling of texture sets: Discard, Traverse and Clamp modes with
 * GPU-style filters (point, bilinear, trilinear, anisotropic) and, from ptexfilter.c, the Ptex
 * filter family. The exact footprint, level and corner rules are written in docs/sampler.md.
 *
 * A query names a face and a point (u, v) in that face's [0,1]^2 with the footprint vectors
 * (du/dx, dv/dx) and (du/dy, dv/dy), in face uv units. A batch shares one st_sample_opts.
 * Output per query: nchan floats and the coverage (the sum of the filter weights that fell on
 * texels that were used: Toth's denominator; 1 in Clamp mode and for interior queries).
 *
 * Threading: st_sample_batch reads the set only; any number of threads may call it at once
 * on the same set. No allocation, no globals; output goes to caller-owned buffers.
 */
#ifndef ST_SAMPLE_H
#define ST_SAMPLE_H

#include <stddef.h>
#include <stdint.h>

#include "set.h"

typedef enum st_mode {
    ST_MODE_DISCARD  = 0,  /* Toth 2013: taps outside the face get zero weight, renormalise */
    ST_MODE_TRAVERSE = 1,  /* Ptex / McDonald 2013: taps outside are read from the neighbour */
    ST_MODE_CLAMP    = 2   /* clamp-to-edge per face: the baseline that shows seams */
} st_mode;

typedef enum st_filter {
    ST_FILTER_POINT       = 0,  /* nearest texel of the nearest level */
    ST_FILTER_BILINEAR    = 1,  /* bilinear in the nearest level */
    ST_FILTER_TRILINEAR   = 2,  /* bilinear in two levels, lerped */
    ST_FILTER_ANISO       = 3,  /* up to max_aniso trilinear probes along the major axis */
    /* Ptex's filter family (ptexfilter.c), Ptex's own footprint and kernel rules */
    ST_FILTER_PTEX_POINT      = 8,
    ST_FILTER_PTEX_BILINEAR   = 9,
    ST_FILTER_PTEX_BOX        = 10,
    ST_FILTER_PTEX_GAUSSIAN   = 11,
    ST_FILTER_PTEX_BICUBIC    = 12,  /* sharpness from opts (0 = B-spline, 1 = Catmull-Rom) */
    ST_FILTER_PTEX_BSPLINE    = 13,
    ST_FILTER_PTEX_CATMULLROM = 14,
    ST_FILTER_PTEX_MITCHELL   = 15
} st_filter;

typedef enum st_zero_rule {
    ST_ZERO_NAN   = 0,  /* every tap discarded: coverage 0, channels NaN, status ZERO_COVERAGE */
    ST_ZERO_CLAMP = 1   /* every tap discarded: clamp the centre into the face, bilinear lookup
                           at the footprint's level (Toth's CLAMP_IF_ZERO_COVERAGE); coverage 0 */
} st_zero_rule;

typedef struct st_query {
    uint32_t face;
    float u, v;
    float dudx, dvdx, dudy, dvdy;
} st_query;

typedef struct st_sample_opts {
    uint8_t mode;        /* st_mode */
    uint8_t filter;      /* st_filter */
    uint8_t zero_rule;   /* st_zero_rule */
    uint8_t max_aniso;   /* 1..16 probes for ST_FILTER_ANISO; 0 means 16 */
    float   sharpness;   /* Ptex bicubic sharpness, 0..1 */
    float   width;       /* Ptex filter width multiplier; 0 means 1 */
    float   blur;        /* Ptex blur; 0 = none */
    uint8_t lerp;        /* Ptex's lerp option: 1 blends the gaussian and bicubic-family
                            kernels toward the next lower resolution (PtexWidth4Filter);
                            0 = off; ignored by every other filter, as in Ptex */
} st_sample_opts;

/* Per-query status. */
enum st_qstatus {
    ST_Q_OK            = 0,
    ST_Q_BAD_FACE      = 1,  /* face index out of range */
    ST_Q_NONFINITE     = 2,  /* NaN or infinite coordinate or derivative */
    ST_Q_BAD_FOOTPRINT = 3,  /* a derivative beyond ST_MAX_DERIV, or |u|,|v| beyond ST_MAX_COORD */
    ST_Q_ZERO_COVERAGE = 4   /* Discard with ST_ZERO_NAN and every tap outside the face */
};

#define ST_MAX_COORD 1.0e4f  /* |u|, |v| above this are refused, not sampled */
#define ST_MAX_DERIV 1.0e4f  /* footprint components above this are refused */

/* A link of chart Traverse: the texel of level L whose index (row * width + column) is
 * `texel`, seen from chart `chart` (id, as in st_chart_ids), reads the same level at the point
 * the seam's unfolding maps the texel centre to (docs/sampler.md, "Chart Traverse"): `to` is
 * the texel under that point, `frac` where in it the point lies, in 256ths of a texel (bits
 * 0-7 along u, 8-15 along v). */
typedef struct st_chart_link {
    uint32_t texel, to;
    uint16_t chart, frac;
} st_chart_link;

/* Chart ids of an atlas set's face 0 at every level, for chart Discard and chart Traverse
 * (docs/sampler.md, "Chart Discard", "Chart Traverse"; built by kinds/atlas.c and reached
 * through set->ext.charts). level[L] holds st_level_w x st_level_h ids of level L, row by row:
 * 0 for a texel of no chart, else the chart's index (mesh.h) + 1. nlevels 0: no ids (Discard
 * takes the image as one face). link[L]: nlink[L] links of level L sorted by (texel, chart),
 * at most one per pair (may be none). */
typedef struct st_chart_ids {
    unsigned nlevels;
    const uint16_t *level[ST_MAX_LEVELS];
    const st_chart_link *link[ST_MAX_LEVELS];
    size_t nlink[ST_MAX_LEVELS];
    /* The query's chart at triangle resolution (kinds/atlas_locate.c; docs/sampler.md, "Chart
     * Discard"): near_bits has a bit per level-0 texel (row by row, 64 to a word), set where a
     * UV triangle of a chart other than the texel's id reaches the texel's square (and may own
     * a point of it); near_rank[w] counts the bits set before word w; the r-th near texel's
     * triangles are near_tri[near_off[r] .. near_off[r + 1]), by chart, lowest first; triangle
     * t is counter-clockwise at tri_xy[6 t ..] in level-0 texel space (x = u W, y = v H), of
     * chart tri_id[t] - 1. near_bits NULL: none (the texel rule). */
    const uint64_t *near_bits;
    const uint32_t *near_rank, *near_off, *near_tri;
    const double *tri_xy;
    const uint16_t *tri_id;
} st_chart_ids;

/* Bit k of a bitmap of 64-bit words, and its rank: the bits set before it, rank[w] counting
 * those of the words before word w (st_chart_ids' near_bits and near_rank). */
static inline int st_bit_get(const uint64_t *bits, size_t k)
{
    return (int)(bits[k >> 6] >> (k & 63) & 1);
}
static inline size_t st_bit_rank(const uint64_t *bits, const uint32_t *rank, size_t k)
{
    uint64_t below = bits[k >> 6] & ((UINT64_C(1) << (k & 63)) - 1);
    return rank[k >> 6] + (size_t)__builtin_popcountll(below);
}

/* The link of texel index `texel` of level L seen from chart `chart` under chart Traverse, or
 * NULL when there is none (the tap is dropped, as by Discard). */
const st_chart_link *st_chart_link_find(const st_chart_ids *ch, unsigned level, uint32_t texel,
                                        unsigned chart);

/* Samples n queries. out receives n * nchan floats (NaN for a query whose status is not OK),
 * coverage n floats and status n bytes (either may be NULL). Returns the number of queries
 * whose status is not ST_Q_OK, or a negative ST_E* code for invalid options (nothing written).
 * A Ptex-family filter on a set of another kind than per-face is ST_EUNSUPPORTED. On a
 * triangle-mesh set (info.meshtype ST_MESH_TRIANGLE) bilinear, trilinear and aniso are
 * ST_EUNSUPPORTED; point reads the small triangle holding (u, v) (sample_tri.c). A chart Discard
 * or chart Traverse batch on an atlas whose chart data is not built builds it first
 * (set->ext.charts_pin: an atlas opened from a native file, or one the memory budget dropped);
 * should that fail, ST_ENOMEM (nothing written). */
int st_sample_batch(const st_set *s, const st_sample_opts *o, const st_query *q, size_t n,
                    float *out, float *coverage, uint8_t *status);

/* The point (u, v) of face f (on or beyond edge `edge`) in the uv of the neighbour across that
 * edge, through the edge rotation (the mapping Traverse uses; docs/sampler.md); on a
 * triangle-mesh set the barycentric unfolding across the edge (core/trilevel.h).
 * Returns 0 and fills g, gu, gv, or -1 when the edge is a boundary or f/edge is out of range. */
int st_uv_across_edge(const st_set *s, uint32_t f, unsigned edge, float u, float v,
                      uint32_t *g, float *gu, float *gv);
/* The same across corner `corner` into the diagonal face of a regular (valence 4, interior)
 * vertex; -1 at irregular or boundary vertices. */
int st_uv_across_corner(const st_set *s, uint32_t f, unsigned corner, float u, float v,
                        uint32_t *g, float *gu, float *gv);

/* Names for the protocol, CLI and reports ("discard", "bilinear", ...); NULL when unknown. */
const char *st_mode_name(unsigned mode);
const char *st_filter_name(unsigned filter);
/* Parses a name back; returns -1 when unknown. */
int st_mode_parse(const char *name);
int st_filter_parse(const char *name);

#endif
