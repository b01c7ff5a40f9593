/* store/ptex/ptexres.h - every resolution of every face that Ptex's filter may ask for.
 *
 * Ptex picks the u and v resolution of a kernel independently, so it reads reductions such as
 * (ulog2-3, vlog2-1) that a set's level chain (both axes halved together) does not hold. The
 * Ptex reader makes them on demand from the stored reductions: a stored level when the
 * reduction is the same on both axes, the face's constant value for 1x1, and otherwise a
 * 2:1 reduction in u or v (alternating for square steps) of the next larger resolution, with
 * integer halving that truncates. This table holds all of them, built once when a set is
 * loaded, so that the filter reads plain memory and matches Ptex bit for bit.
 *
 * Owns: the table (a set extension, set->ext, freed with the set). Does not own: the set's
 * own levels (set.c), filtering (ptexfilter*.c).
 *
 * Cost: one pointer per (face, ulog2', vlog2') pair plus the texels of the pairs that are not
 * set levels: about 2.7x the size of level 0 on top of the set's own 4/3. A set opened from a
 * native file gets a lazy table instead: nothing until a Ptex filter samples it, dropped
 * again under a memory budget (st_ptexres_drop), counted by st_set_memory only while built.
 */
#ifndef ST_PTEXRES_H
#define ST_PTEXRES_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

#define ST_PTEXRES_MAGIC 0x50545852u /* "PTXR" */

typedef struct st_ptexres {
    uint32_t        magic;        /* ST_PTEXRES_MAGIC */
    uint32_t        nfaces;
    uint64_t       *base;         /* per face: index of its (0,0) entry in px */
    const uint8_t **px;           /* res (ru, rv) of face f: px[base[f] + ru * (vlog2+1) + rv];
                                     a constant face has one entry (its texel) */
    uint8_t        *ptxflags;     /* per face: Ptex FaceInfo flags (PTX_FLAG_*) */
    uint8_t        *nstored;      /* per face: set levels holding stored reductions (>= 1) */
    uint8_t        *arena;        /* texels of the entries that are not set levels */
    size_t          arena_bytes;
    size_t          bytes;        /* everything the table holds, counted by st_set_memory */
    /* A lazy table (st_ptexres_attach_lazy, native sets) is built on the first Ptex filter
     * call from the per-face inputs below (they live as long as the set: in its mapping) and
     * may be dropped again (st_ptexres_drop) and rebuilt on demand. Filters hold rw shared
     * while they read the table; build and drop hold it exclusive. Eager tables: built = 1
     * from the start, never dropped, no locking. */
    int             lazy;
    int             built;        /* atomic */
    const uint8_t  *in_const, *in_flags, *in_nstored;
    size_t          max_bytes;
    pthread_rwlock_t rw;
    uint64_t        nbuilds;      /* atomic: builds so far (1 for an eager table) */
} st_ptexres;

/* Builds the table for s and attaches it as the set's ST_EXT_PTEXRES extension, with the
 * Ptex filter family as its filter (s must have no extension yet). For face f:
 * constpx (may be NULL) gives its Ptex constant value (nfaces pixels; NULL = the face's
 * average computed as Ptex does), ptxflags (may be NULL) its Ptex flags, nstored (may be
 * NULL = every square level) the number of set levels that hold stored reductions (level 0
 * included; 1 = none). The set's levels that are not stored are then overwritten with the
 * values Ptex would serve for them, so that the set and the table agree. */
int st_ptexres_attach(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                      const uint8_t *nstored, size_t max_bytes, st_error *e);

/* Attaches a lazy table to s (ST_EXT_PTEXRES, s must have no extension yet): nothing is
 * built until a Ptex filter first samples s (or st_ptexres_ensure is called); the inputs are
 * as for st_ptexres_attach but all three are required and must outlive s (a native set's
 * mapping). The set's levels are NOT rewritten: s must already hold the values Ptex serves
 * for the levels it does not store (a native file is written from a set whose levels were
 * rewritten by st_ptexres_attach), so a read-only mapped set is never written. */
int st_ptexres_attach_lazy(st_set *s, const uint8_t *constpx, const uint8_t *ptxflags,
                           const uint8_t *nstored, size_t max_bytes, st_error *e);

/* The table of s when it is built, or NULL when s has none (or a lazy one not built yet). */
const st_ptexres *st_ptexres_get(const st_set *s);

/* Builds a lazy table now if needed; returns the table or NULL (no table, or the build
 * failed: out of memory / over max_bytes). */
const st_ptexres *st_ptexres_ensure(const st_set *s);

/* Frees a lazy table's built data when no filter is using it (it is rebuilt on the next Ptex
 * filter call); returns the bytes freed (0: nothing built, an eager table, or busy). */
size_t st_ptexres_drop(const st_set *s);

/* Bytes a built table holds beyond its small header (0 when not built or no table). */
size_t st_ptexres_built_bytes(const st_set *s);

/* Data of face f at resolution (ru, rv), 0 <= ru <= ulog2, 0 <= rv <= vlog2. */
static inline const uint8_t *st_ptexres_data(const st_ptexres *t, const st_set *s, uint32_t f,
                                             unsigned ru, unsigned rv)
{
    const st_face *F = &s->faces[f];
    if (F->flags & ST_FACE_CONSTANT)
        return t->px[t->base[f]];
    return t->px[t->base[f] + (size_t)ru * (F->vlog2 + 1u) + rv];
}

#endif
