/* server/handles.h - one small table of handles, used for uploads, fetches and jobs.
 *
 * Owns: handle ids (1, 2, 3... per table, given on insert, never reused), lookup by id and
 * owner connection, the count of live records against a capacity, unlinking by a predicate
 * (expiry, a closing connection), and the table's mutex. Does not own: the records
 * themselves (each kind embeds an sts_handle as its FIRST member and is allocated and freed
 * by its owner: uploads.c, h_jobs.c), what a record means, when it expires.
 *
 * Locking: every *_locked function is called with t->mu held (sts_handles_lock); the others
 * take it themselves. A caller may walk t->list (newest first, through ->next) under the lock.
 * Ownership: a record inserted belongs to the table until it is unlinked; unlinking hands it
 * back to the caller, who frees it (outside the lock when freeing is slow).
 */
#ifndef STS_HANDLES_H
#define STS_HANDLES_H

#include <pthread.h>
#include <stdint.h>

/* Matches any owner in sts_handles_find_locked. */
#define STS_ANY_OWNER UINT64_MAX

typedef struct sts_handle {
    uint64_t           id;
    uint64_t           owner;  /* connection id that may use it; 0 = none (jobs, kept uploads) */
    uint8_t            live;   /* counted in sts_handles.live (against the capacity) */
    struct sts_handle *next;   /* the table's list, newest first */
} sts_handle;

typedef struct sts_handles {
    pthread_mutex_t mu;
    sts_handle     *list;
    uint32_t        live;      /* records whose `live` is set */
    uint64_t        next_id;   /* the last id given */
} sts_handles;

void sts_handles_init(sts_handles *t);
/* Destroys the mutex; the list must be empty (sts_handles_unlink_if with a predicate that
 * takes everything first). */
void sts_handles_destroy(sts_handles *t);
void sts_handles_lock(sts_handles *t);
void sts_handles_unlock(sts_handles *t);

/* Inserts h as live with the next id, unless `cap` records are live already: then -1 and
 * nothing changes (no id is used). */
int sts_handles_add_locked(sts_handles *t, sts_handle *h, uint64_t cap);
/* The record with this id and owner (STS_ANY_OWNER: any), or NULL. Still in the table. */
sts_handle *sts_handles_find_locked(sts_handles *t, uint64_t id, uint64_t owner);
/* Takes h out of the table (and out of the live count); the caller owns it again. */
void sts_handles_unlink_locked(sts_handles *t, sts_handle *h);
/* h stays in the table but no longer counts against the capacity (a finished job, a
 * committed upload kept for its reply). */
void sts_handles_retire_locked(sts_handles *t, sts_handle *h);

/* Unlinks every record `pick` returns non-zero for (called under the lock, in list order,
 * newest first; pick may change its record, e.g. a state) and returns them as a list through
 * ->next: the caller owns and frees them. */
sts_handle *sts_handles_unlink_if(sts_handles *t, int (*pick)(sts_handle *h, void *arg),
                                  void *arg);

#endif
