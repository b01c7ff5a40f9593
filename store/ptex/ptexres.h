/* store/ptex/ptexres.h - every resolution of every face that Ptex's filter may ask for.
 *
 * Ptex picks the u and v resolution of a kernel independently, so it reads reductions such as
 * (ulog2-3, vlog2-1) that a set's level chain (both axes halved together) does not hold. The
 * Ptex reader makes them on demand from the stored reductions: a stored level when the
 * reduction is the same on both axes, the face's constant value for 1x1, and otherwise a
 * 2:1 reduction in u or v (alternating for square steps) of the next larger resolution, with
 * integer halving that truncates. This table points at all of them, so that the filter reads
 * plain memory and matches Ptex bit for bit.
 *
 * Two steps, so that an import pays only for the first:
 *   1. the set's own levels hold the values Ptex serves for them (st_ptexres_fill_levels: the
 *      levels a file did not store are made by the rules above, at import; a native set file
 *      keeps them as they are);
 *   2. the table of every (ru, rv) is built lazily, on the first Ptex-filter call on the set
 *      (st_ptexres_table, once, under a mutex; any number of threads may sample at once).
 *      Pairs that are set levels point into the set; the others get texels in one arena.
 * st_ptexres_attach_lazy hangs the (unbuilt) table on a set whose levels are already filled;
 * st_ptexres_attach does both steps' set-up for a set whose levels are not filled yet.
 *
 * Deferred levels (st_ptexres_attach_deferred, the Ptex reader's default): step 1 itself waits
 * for the first reader of a level past level 0. The record then holds what the reader kept
 * (the zipped stored reductions, the constant data) and the set's levels hook
 * (st_set_levels, set.h): one state for the whole set, `levels` 0 pending / 1 made /
 * 2 failed, read with acquire ordering; the first call inflates the stored reductions and
 * fills the rest under `levels_lock`, stores 1 with release and frees what it kept. A failure
 * (a corrupt deflate stream found late) stores 2 and its message, which every later call
 * returns. The table build (st_ptexres_table) makes the levels first.
 *
 * Owns: the table (a set extension, set->ext, freed with the set). Does not own: the set's
 * own levels (set.c), filtering (ptexfilter*.c).
 *
 * Cost: before the first Ptex-filter call, three bytes per face (Ptex flags, stored levels,
 * lane flags) and the deferred reductions' compressed bytes. After it: one pointer per
 * (face, ulog2', vlog2') pair plus the texels of the pairs that are not set levels (about 2.7x
 * level 0); st_set_memory counts it once built. A built table may be dropped again under a
 * memory budget (st_ptexres_drop, server/budget.c) and is rebuilt by the next Ptex filter
 * call: the filter reads the table pinned (st_ptexres_pin, a shared lock), the drop only
 * tries the exclusive lock and gives up when a filter holds it.
 */
#ifndef ST_PTEXRES_H
#define ST_PTEXRES_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

#define ST_PTEXRES_MAGIC 0x50545852u /* "PTXR" */

/* lanef bits set by the table's build (ptexres.c, zero_ring: what they check and why that
 * suffices). ZRING: a Traverse kernel of the face (a quad mesh) reaches only faces that are
 * constant with a texel of zero bytes, and its split never changes its weight. ZFACE: the
 * face itself is such a face (Clamp reads no other) */
#define ST_PTEXRES_ZRING 1u
#define ST_PTEXRES_ZFACE 2u

/* A stored face (level 0, or a stored square reduction `level`) of a .ptx file that is tiled
 * (tiles of 2^tu x 2^tv texels) with every tile a constant tile of one and the same value.
 * Ptex's reader serves a reduction it makes from such a face as a constant face once the
 * reduction fits in one tile (PtexReader::TiledFaceBase::reduce), which matters to the tanvec
 * edge filter mode: Ptex does not turn data it serves as constant (st_ptexres_served_const). */
typedef struct st_ptexres_ctile {
    uint32_t face;
    uint8_t  level, tu, tv, pad;
} st_ptexres_ctile;

typedef struct st_ptexres {
    uint32_t        magic;        /* ST_PTEXRES_MAGIC */
    uint32_t        nfaces;
    uint8_t        *ptxflags;     /* per face: Ptex FaceInfo flags (PTX_FLAG_*), then 3 zero
                                     bytes (ptexfilter_lanes.c reads 32 bits at a face) */
    uint8_t        *nstored;      /* per face: set levels that hold stored reductions (>= 1) */
    uint8_t        *lanef;        /* per face: ptxflags' PTX_FLAG_NBCONSTANT bit, bit 4 + e
                                     set when edge e is a mesh boundary (adjface < 0), and
                                     ST_PTEXRES_ZRING and _ZFACE (set by the table's build),
                                     then 3 zero bytes (the bilinear lanes read 32 bits at a
                                     face: one gather for both) */
    size_t          max_bytes;    /* cap on the arena */
    /* built by st_ptexres_table; read only once `built` is 1 (acquire) */
    atomic_int      built;
    pthread_mutex_t lock;         /* serialises the build (and the drop) */
    pthread_rwlock_t pin;         /* shared: a reader of the built table; exclusive: a drop */
    uint64_t       *base;         /* per face: index of its (0,0) entry in px */
    const uint8_t **px;           /* res (ru, rv) of face f: px[base[f] + ru * (vlog2+1) + rv];
                                     a constant face has one entry (its texel) */
    uint8_t        *arena;        /* texels of the entries that are not set levels */
    size_t          arena_bytes;
    size_t          bytes;        /* everything the table holds, counted by st_set_memory */
    /* the set's levels past level 0 (deferred by st_ptexres_attach_deferred; else always 1) */
    atomic_int      levels;       /* 0 pending, 1 made, 2 failed (levels_err says why) */
    pthread_mutex_t levels_lock;  /* serialises making them */
    struct st_ptexres_deferred *def; /* what makes them while pending, freed once made */
    size_t          def_bytes;    /* its memory, counted by st_set_memory (0 once freed) */
    st_error        levels_err;   /* the failure, read once `levels` is 2 (acquire) */
    st_ptexres_ctile *ctiles;     /* stored faces whose tiles are all one constant, sorted by
                                     face then level (st_ptexres_set_ctiles; kept by
                                     native set files, not by the .ptx writer) */
    uint32_t        nctiles;
} st_ptexres;

/* What a reader keeps to make a set's levels later (st_ptexres_attach_deferred). make inflates
 * the stored reductions into the set's levels (nothing else: the rest is filled from them by
 * st_ptexres_fill_levels with constpx afterwards); free releases data. */
typedef struct st_ptexres_deferred {
    int          (*make)(st_set *s, void *data, st_error *e);
    void         (*free)(void *data);
    void          *data;
    const uint8_t *constpx;       /* per face one texel (inside data): the 1x1 values */
    size_t         bytes;         /* data's memory, for st_set_memory */
} st_ptexres_deferred;

/* Overwrites face f's levels [nstored, nlevels) with the values Ptex serves for them (every
 * level when nstored is 1; the 1x1 level always gets the constant value): constpx (one texel;
 * NULL = the average of level 0 computed as Ptex does) for 1x1, else one or two 2:1
 * reductions of the level before. nstored counts level 0 (1 = no stored reductions); a face
 * whose Ptex flags say it has edits must pass 1. Constant faces are left alone. ST_ENOMEM
 * only for faces over 4 KiB of level-1 texels when a scratch row cannot be allocated. */
int st_ptexres_fill_levels(st_set *s, uint32_t f, unsigned nstored, const uint8_t *constpx,
                           st_error *e);

/* Attaches the table, unbuilt, as the set's ST_EXT_PTEXRES extension with the Ptex filter
 * family as its filter (s must have no extension yet). The set's levels must already hold
 * the values Ptex serves (st_ptexres_fill_levels, or a native set file that kept them).
 * ptxflags (may be NULL = from the face flags) and nstored (may be NULL = every square level)
 * are copied. max_bytes (0 = ST_DEFAULT_MAX_BYTES) caps the arena built later. Costs two
 * bytes per face until a Ptex filter first runs. */
int st_ptexres_attach_lazy(st_set *s, const uint8_t *ptxflags, const uint8_t *nstored,
                           size_t max_bytes, st_error *e);

/* Like st_ptexres_attach, but nothing past level 0 is made now: the set's levels hook makes
 * them on the first st_set_levels (d->make, then st_ptexres_fill_levels of every face from
 * d->constpx, ptxflags and nstored). *d is copied; d->data passes to the record in every case
 * (freed by d->free on failure too). Level 0 must be complete. */
int st_ptexres_attach_deferred(st_set *s, const st_ptexres_deferred *d, const uint8_t *ptxflags,
                               const uint8_t *nstored, size_t max_bytes, st_error *e);

/* For a set whose levels past level 0 are not Ptex's yet: fills them (st_ptexres_fill_levels
 * with constpx + f * texel size, or NULL) and attaches the table lazily. Arguments as above. */
int st_ptexres_attach(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                      const uint8_t *nstored, size_t max_bytes, st_error *e);

/* Records the stored faces of s (attached record) whose tiles are all one constant (a .ptx
 * reader's finding; c sorted by face then level, copied). ST_ENOMEM, ST_EINVAL (no record). */
int st_ptexres_set_ctiles(st_set *s, const st_ptexres_ctile *c, uint32_t n, st_error *e);

/* 1 when Ptex's reader serves quad face f (not constant) at resolution (ru, rv), 0 <= ru <=
 * ulog2, 0 <= rv <= vlog2, as a constant face: (0, 0), or a reduction it makes (not level 0,
 * not a stored square reduction of a face without edits) whose chain of 2:1 reductions (u or
 * v, the order of st_ptexres_fill_levels) starts at a stored face listed in t->ctiles and has
 * reached a resolution that fits in one of its tiles; else 0. */
int st_ptexres_served_const(const st_ptexres *t, const st_set *s, uint32_t f, int ru, int rv);

/* The built table of s: builds it on the first call (thread-safe; later calls are one atomic
 * load). NULL when s has no table (e NULL-safe) or the build failed (ST_ENOMEM or over
 * max_bytes, in e; a later call tries again). */
const st_ptexres *st_ptexres_table(const st_set *s, st_error *e);

/* The table record of s (built or not: test t->built, or call st_ptexres_table), or NULL
 * when s has none. */
const st_ptexres *st_ptexres_get(const st_set *s);

/* The built table of s, pinned: like st_ptexres_table, but st_ptexres_drop cannot free it
 * until st_ptexres_unpin(t). NULL (nothing pinned) as for st_ptexres_table. The Ptex filter
 * reads through this; other callers of st_ptexres_table must not race with a drop. */
const st_ptexres *st_ptexres_pin(const st_set *s, st_error *e);
void st_ptexres_unpin(const st_ptexres *t);

/* Frees the built data of the table of s when no reader has it pinned (it is rebuilt on the
 * next Ptex filter call); returns the bytes freed (0: no table, not built, or pinned). */
size_t st_ptexres_drop(const st_set *s);

/* Bytes the built table of s holds beyond its record (0: no table or not built). */
size_t st_ptexres_built_bytes(const st_set *s);

/* Data of face f at resolution (ru, rv), 0 <= ru <= ulog2, 0 <= rv <= vlog2, of a built
 * table (st_ptexres_table). */
static inline const uint8_t *st_ptexres_data(const st_ptexres *t, const st_set *s, uint32_t f,
                                             unsigned ru, unsigned rv)
{
    const st_face *F = &s->faces[f];
    if (F->flags & ST_FACE_CONSTANT)
        return t->px[t->base[f]];
    return t->px[t->base[f] + (size_t)ru * (F->vlog2 + 1u) + rv];
}

#endif
