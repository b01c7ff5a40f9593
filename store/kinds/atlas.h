/* store/kinds/atlas.h - atlas sets: one texture (face 0, any w x h, with its mip chain) plus the mesh
 * that maps onto it, with the mesh's UV seams.
 *
 * Owns: st_atlas (the set's ext for ST_KIND_ATLAS), building an atlas set from an image and a
 * mesh, sampling by (u, v) in texture space, the chart mask (which texels some triangle
 * covers). Does not own: image decoding (image.h), mesh reading and seams (mesh.h), the
 * filters (sample.h).
 *
 * Texture space: u right, v down from the image's top row (mesh.h says how file UVs are
 * flipped into it). Sampling an atlas uses st_sample_batch on face 0, in every mode as
 * SAMPLE over the wire does: Clamp clamps taps into the image; face 0's four edges are
 * boundaries, so Traverse, having no neighbour to go to, drops the taps beyond the image
 * border and renormalises (coverage < 1 there), as Discard does; st_atlas_sample with
 * ST_ATLAS_CHART_DISCARD also discards taps on texels outside every chart (the chart mask),
 * renormalising. Discard without that flag is chart Discard (sample.c, docs/sampler.md): taps
 * on texels not of the query's chart are dropped, at every level, from the chart ids kept
 * here (set->ext.charts); Traverse is chart Traverse: such taps read the texel linked to them
 * across a UV seam (atlas_links.c), and are dropped where there is none.
 *
 * When the chart data is built (ids, links, triangle lists: st_atlas_build_chart_ids): at once
 * for an atlas made from an image and a mesh (its per-chart mips need the ids); for one opened
 * from a native file, lazily, by the first chart Discard / chart Traverse sample (the set
 * extension's charts_pin hook, which st_sample_batch calls once per batch in those modes: the
 * build runs once under charts_lock, the batch holds the shared side of charts_pin while it
 * reads). st_set_memory counts the data once built (charts_bytes); the memory budget may drop
 * it again (st_atlas_charts_drop: only with the exclusive side of charts_pin, tried, never
 * waited for, so never under a sampler), and the next chart-mode sample rebuilds it, the same
 * bytes (the ids are a function of the mesh and the face's size). Clamp, the plain modes of
 * other sets and st_atlas_sample's mask Discard never build it.
 *
 * Ownership: the atlas owns its mesh (freed by st_atlas_free, which is the set's ext_free).
 */
#ifndef ST_ATLAS_H
#define ST_ATLAS_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "image.h"
#include "mesh.h"
#include "sample.h"
#include "set.h"

/* The query chart's triangle lists (atlas_locate.c; what st_chart_ids' near_ and tri_ pointers
 * point to): bits 1 bit a level-0 texel, rank set bits before each 64-bit word, off / tri the
 * near texels' triangle lists, xy 6 doubles a triangle, id its chart + 1 (0: not listed). */
typedef struct st_atlas_locate {
    uint64_t *bits;
    uint32_t *rank, *off, *tri;
    double   *xy;
    uint16_t *id;
    size_t    bytes;
} st_atlas_locate;

typedef struct st_atlas {
    st_mesh  *mesh;        /* may be NULL: a plain image set */
    uint8_t  *chart_mask;  /* w*h bytes of level 0, 1 where a UV'd triangle covers the texel
                              centre (conservatively dilated by one texel), NULL when no mesh */
    uint32_t  mask_w, mask_h;
    uint16_t *chart_id;    /* chart id (chart + 1, 0 none) per texel of every level of face 0,
                              the levels one after another; NULL when no mesh or more than
                              65534 charts (docs/sampler.md, "Chart Discard") */
    size_t    chart_id_bytes;
    st_chart_link *chart_link; /* chart Traverse's links of every level (atlas_links.c), the
                              levels one after another; NULL when none */
    size_t    chart_link_bytes;
    st_atlas_locate loc;   /* the query chart's triangle lists (atlas_locate.c) */
    st_chart_ids ids;      /* chart_id's and chart_link's levels and loc, what set->ext.charts
                              points to; read only while pinned (st_atlas_charts_pin) */
    /* chart_id, chart_link, loc and ids are built (st_atlas_build_chart_ids): read once 1
     * (acquire); 0 until the first chart-mode sample of a native atlas and after a drop */
    atomic_int       charts_built;
    size_t           charts_bytes;   /* what they hold once built (atomic reads), else 0 */
    pthread_mutex_t  charts_lock;    /* serialises the build and the drop */
    pthread_rwlock_t charts_pin;     /* shared: a sampler reading them; exclusive: a drop */
    char      texture_name[256]; /* file the texture came from (information) */
} st_atlas;

/* A new empty atlas record (no mesh, nothing built), or NULL when out of memory. */
st_atlas *st_atlas_new(void);

/* Makes an ST_KIND_ATLAS set of the image (copied; level 0 = the image, mips by box
 * reduction). mesh (may be NULL) is taken over by the set (also on failure it is freed);
 * when not NULL its seams are found and a chart mask rasterised. */
int st_atlas_from_image(const st_image *img, st_mesh *mesh, size_t max_bytes, st_set **out,
                        st_error *e);

/* (Re)builds a's chart ids for face 0 of s from a->mesh (seams found), with the links and the
 * triangle lists, and marks them built (charts_built, charts_bytes): called when a mesh is
 * attached, and under charts_lock by the first chart-mode sample of an atlas opened from a
 * native file (the ids are not stored). The caller holds charts_lock, or the set is not
 * published yet. */
int st_atlas_build_chart_ids(st_atlas *a, const st_set *s, st_error *e);

/* How far past a seam side's UV edge (in texels of each level) chart Traverse links texels. */
#define ST_CHART_LINK_BAND 4

/* (Re)builds a's chart Traverse links from a->mesh's seams and a's chart ids (atlas_links.c;
 * called by st_atlas_build_chart_ids); ST_ENOMEM leaves none. */
int st_atlas_build_links(st_atlas *a, const st_set *s, st_error *e);
void st_atlas_free_links(st_atlas *a);

/* (Re)builds a's triangle lists for the query's chart at triangle resolution from a->mesh and
 * a's level-0 chart ids (atlas_locate.c; called by st_atlas_build_chart_ids); ST_ENOMEM leaves
 * none. A mesh whose lists would be too long gets none (ST_OK): the texel rule. */
int st_atlas_build_locate(st_atlas *a, const st_set *s, st_error *e);
void st_atlas_free_locate(st_atlas *a);

/* Attaches a mesh to an existing atlas set (replacing an old one); takes it over. */
int st_atlas_attach_mesh(st_set *s, st_mesh *mesh, st_error *e);

/* The set extension's charts_pin hook (set.h): builds a's chart data when it is not built
 * (once, under charts_lock) and holds the shared side of charts_pin, so that no drop frees it
 * until st_atlas_charts_unpin. ST_OK (pinned; the ids may still be none: no mesh, or more than
 * 65534 charts), or ST_ENOMEM from the build (nothing pinned; a later call tries again). */
int st_atlas_charts_pin(const st_set *s, st_error *e);
void st_atlas_charts_unpin(const st_set *s);

/* Frees the built chart data of atlas set s when no sampler has it pinned (the next chart-mode
 * sample rebuilds it); returns the bytes freed (0: not an atlas, not built, or pinned). */
size_t st_atlas_charts_drop(const st_set *s);

/* Bytes the built chart data of s holds (0: not an atlas or not built). */
size_t st_atlas_charts_built_bytes(const st_set *s);

/* The atlas of a set, NULL when the set is not an atlas or has no ext. */
const st_atlas *st_atlas_get(const st_set *s);

void st_atlas_free(void *atlas);
/* Fills x with the ST_EXT_ATLAS extension record of a (the set will own and free a). */
void st_atlas_ext(st_atlas *a, st_set_ext *x);

enum { ST_ATLAS_CHART_DISCARD = 0x100 };   /* extra bit in st_atlas_sample's flags */

/* Samples n (u, v) queries of texture space with footprint (face field ignored, set to 0).
 * mode / filter from o, every mode as st_sample_batch takes it (Traverse drops the taps
 * beyond the image border, see above). With flags & ST_ATLAS_CHART_DISCARD in Discard mode,
 * taps outside the chart mask are dropped too (point / bilinear filters; others fall back to
 * face Discard); |u|, |v| over ST_MAX_COORD are ST_Q_BAD_FOOTPRINT there as well. Results as
 * st_sample_batch. */
int st_atlas_sample(const st_set *s, const st_sample_opts *o, unsigned flags,
                    const st_query *q, size_t n, float *out, float *coverage, uint8_t *status);

#endif
