/* store/service/registry.h - the named-set registry: the sets a daemon serves, by name.
 *
 * Owns: the name -> set table, reference counting of published sets, applying the set-name
 * rule to every name it publishes (st_name_check). Does not own: the rule itself (one
 * implementation, protocol/stp_name.h: header-only and libc-only, so the store links nothing
 * of protocol/), files (datadir.c), sockets, importing (import.c), sampling (sample.c).
 *
 * Threading: every function is thread-safe. A reader takes a reference with
 * st_registry_get and samples the set for as long as it holds it; an upload may meanwhile
 * replace the name or a DELETE remove it: the registry drops its own reference, and the set
 * is freed when the last reader releases its reference. Lookups take a mutex for a few
 * instructions (a hash probe and an atomic increment); no lock is held while sampling.
 *
 * Ownership: st_registry_put takes ownership of the set (also on failure: it is freed).
 * st_registry_get hands out a reference the caller must give back with st_setref_release.
 */
#ifndef ST_REGISTRY_H
#define ST_REGISTRY_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"
#include "stp_name.h"

#define ST_NAME_MAX STP_MAX_NAME  /* 255 bytes, not counting the NUL */

/* Returns 0 when the len bytes at name are a valid set name (stp_name.h: 1..255 bytes of
 * [A-Za-z0-9._-], not starting with '.', so never "." or ".." and never a hidden file), else
 * ST_EINVAL with a message saying why. */
int st_name_check(const char *name, size_t len, st_error *e);

/* What a reader gets: the set, its name and identity. Immutable while referenced. */
typedef struct st_setref {
    st_set   *set;
    char      name[ST_NAME_MAX + 1];
    uint64_t  gen;          /* registry-wide generation: a replaced name gets a new one */
    uint64_t  source_bytes; /* size of the source the set was imported from (0 unknown) */
    uint32_t  source_crc;   /* CRC-32 of that source (0 unknown) */
    char      format[16];   /* importer's name for the source ("ptx", "png", ...), may be "" */
    int64_t   created_ms;   /* wall clock when published, ms since the epoch */
    /* private */
    int       refs_;        /* atomic, see registry.c */
} st_setref;

/* Optional description stored beside a published set (all fields may be zero). */
typedef struct st_set_source {
    uint64_t bytes;
    uint32_t crc;
    const char *format;
} st_set_source;

typedef struct st_registry st_registry;

/* Creates an empty registry; NULL on allocation failure. Free with st_registry_free. */
st_registry *st_registry_create(void);

/* Drops the registry's references (sets still held by readers live on until released) and
 * frees the table. NULL is accepted. */
void st_registry_free(st_registry *r);

/* Publishes set under name, replacing any set of that name (whose reference is dropped).
 * *replaced (may be NULL) is set to 1 when a set was replaced. max_sets caps the number of
 * names (0 = no cap): a new name past it is ST_EBUSY. Takes ownership of set in every case. */
int st_registry_put(st_registry *r, const char *name, st_set *set, const st_set_source *src,
                    size_t max_sets, int *replaced, st_error *e);

/* Takes a reference to the set named name; ST_ENOTFOUND when there is none. */
int st_registry_get(st_registry *r, const char *name, st_setref **out, st_error *e);

/* Gives a reference back; frees the set when it was the last one. NULL is accepted. */
void st_setref_release(st_setref *ref);

/* Takes one more reference on a set the caller already holds. */
void st_setref_retain(st_setref *ref);

/* Removes name; ST_ENOTFOUND when absent. Readers holding it keep it until they release. */
int st_registry_remove(st_registry *r, const char *name, st_error *e);

/* Number of names. */
size_t st_registry_count(st_registry *r);

/* The generation the next set published will get: every set published after this call has a
 * gen >= the value returned, every set published before it a smaller one. */
uint64_t st_registry_next_gen(st_registry *r);

/* Takes references to up to max sets, sorted by name, into out[]; returns how many. The
 * caller releases each one. */
size_t st_registry_snapshot(st_registry *r, st_setref **out, size_t max);

/* Total bytes held by the registered sets (st_set_memory summed). */
uint64_t st_registry_memory(st_registry *r);

#endif
